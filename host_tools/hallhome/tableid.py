"""Which lookup table the host expects the board to run.

The board reports the `table_id` (CRC-32 of the canonical table, docs/tables.md)
of the table compiled into its firmware. The host computes the same id from a
robot TOML with the table generator itself (hallhome.tablegen), so the two
are compared, not restated: `hallhome status` warns and `hallhome calibrate`
refuses when they differ.

Without a TOML the expected robot is the project's default, the `ROBOT ?=`
line of the Makefile (what `make firmware` builds).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

from hallhome.paths import PROJECT_ROOT, ROBOTS_DIR

MAKEFILE = PROJECT_ROOT / "Makefile"


class TableIdError(RuntimeError):
    """The expected table could not be computed (bad TOML, learned file)."""


@dataclass(frozen=True)
class Expected:
    name: str        # the table's name as the board reports it
    table_id: int
    source: str      # what it was computed from, for messages

    @property
    def id_text(self) -> str:
        return f"0x{self.table_id:08x}"


def default_robot() -> Path:
    """The robot TOML `make firmware` builds when no ROBOT is given."""
    m = re.search(r"^ROBOT\s*\?=\s*(\S+)", MAKEFILE.read_text(encoding="utf-8"), re.M)
    if not m:
        raise TableIdError(f"no `ROBOT ?=` default in {MAKEFILE}")
    return ROBOTS_DIR / f"{m.group(1)}.toml"


def expected_table(robot: Optional[str | Path] = None, learned: Sequence[str | Path] = ()) -> Expected:
    """The table (name, id) the generator builds from `robot` (default: the
    project's default robot), with `learned` files applied as
    `hallhome tables --learned` does."""
    from hallhome.robot import RobotError, load_robot
    from hallhome.tablegen import (TableError, apply_learned, build_table, compute, load_learned,
                                   parse_table_header)

    path = Path(robot) if robot else default_robot()
    try:
        spec = parse_table_header()
        files = [load_learned(p) for p in learned]
        r = load_robot(path)
        table = build_table(compute(r), spec)
        name = r.name
        if files:
            applied = apply_learned(table, spec, r, files)
            table, name = applied.table, applied.name
    except RobotError as e:
        raise TableIdError(f"invalid robot description {path}:\n{e}") from None
    except (TableError, OSError) as e:
        raise TableIdError(str(e)) from None
    src = path.name + "".join(f" + {Path(p).name}" for p in learned)
    return Expected(name, int(table["table_id"]), src)


def parse_id(value) -> Optional[int]:
    """A board's `table_id=0x...` field as an int (None when absent or not hex)."""
    if isinstance(value, int):
        return value
    try:
        return int(str(value), 16)
    except (TypeError, ValueError):
        return None


def mismatch(expected: Expected, board_name, board_id) -> Optional[str]:
    """None when the board runs the expected table, else one sentence that
    says what differs and what to do."""
    bid = parse_id(board_id)
    if board_name == expected.name and bid == expected.table_id:
        return None
    board = f"{board_name} 0x{bid:08x}" if bid is not None else f"{board_name or 'none'} (no table id)"
    return (f"the board runs table {board}, but {expected.source} gives {expected.name} "
            f"{expected.id_text}: flash the firmware built from that TOML "
            f"(`make flash ROBOT={expected.name}`), or name the board's robot with --robot")
