"""`hallhome identify install`: the targets of an identified robot onto the
board as learned targets, without a reflash (docs/identify.md, "Install").

The board keeps its compiled table for everything but the targets: the
identified description must select the same sensor for every tendon and use
the same tension grid, otherwise the table itself has to be flashed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Tuple

import click
from rich.markup import escape

from hallhome import protocol
from hallhome.client import BoardError, Client, HallhomeError, LocalError
from hallhome.op_common import (cmd, err, fixed3, int_list, json_option,
                                operator_command, out, port_options, print_json, session,
                                wait_saved)
from hallhome.op_learn import TableInfo, read_table


@dataclass
class Plan:
    """What `install` sends: per tendon, (grid mN, target uT) in rising
    tension, and the reasons it cannot (empty when it can)."""

    targets: Dict[int, List[Tuple[int, float]]]
    refusals: List[str]


def plan(table: dict, board: TableInfo, robot_name: str, force: bool = False) -> Plan:
    """The identified table (tablegen.build_table's dict) against the board's
    table report."""
    refusals = []
    if robot_name not in (board.robot, board.robot + "_id") and not force:
        refusals.append(f"the board runs the table of {board.robot!r}, this description is "
                        f"{robot_name!r} (--force installs anyway)")
    if table["n_tendons"] != board.n:
        refusals.append(f"{table['n_tendons']} tendons here, {board.n} in the board's table")
    if list(table["grid_mN"]) != list(board.grid):
        refusals.append(f"tension grid {list(table['grid_mN'])} mN here, {list(board.grid)} mN "
                        "in the board's table (learned targets sit on the board's grid)")
    targets: Dict[int, List[Tuple[int, float]]] = {}
    from hallhome.tablegen import parse_table_header
    cut = parse_table_header()["TBL_CUT_PER_LSB"]  # the table stores whole LSB
    for i, t in enumerate(table["tendons"]):
        if i < board.n and board.sensor.get(i) != t["sensor"]:
            refusals.append(f"tendon {i}: the identified robot selects sensor {t['sensor']}, the "
                            f"board's table sensor {board.sensor.get(i)} (the targets are that "
                            "sensor's field)")
        targets[i] = [(g, v * cut / 100.0) for g, v in zip(table["grid_mN"], t["target_lsb"])]
    return Plan(targets, refusals)


def _verify(c: Client, p: Plan) -> List[str]:
    """Entries the board's table does not show as learned with the value sent."""
    _, rows = read_table(c)
    info = {int(r.get("tendon")): r for r in rows}
    bad = []
    for t, pts in p.targets.items():
        vals = int_list(info[t].get("target_cuT")) if t in info else []
        for k, (g, uT) in enumerate(pts):
            if k >= len(vals) or vals[k] != (round(uT * 100), "*"):
                bad.append(f"tendon {t} at {g / 1000:.3f} N")
    return bad


@click.command("install")
@click.argument("robot", type=click.Path(exists=True, dir_okay=False))
@click.option("--dry-run", is_flag=True, help="Compute the targets and check them against the "
              "board's table; send nothing.")
@click.option("--force", is_flag=True, help="Install although the board's table names another "
              "robot (the counts, grid and sensors must still match).")
@json_option
@port_options
@operator_command
def install_cmd(robot, dry_run, force, as_json, port, timeout) -> None:
    """Install an identified robot's targets on the board, without a reflash.

    ROBOT is the identified description (ROBOT_id.toml from `hallhome
    identify fit`).

    The targets are computed from ROBOT as `hallhome tables` would (a few
    seconds), the board's learned targets are forgotten, and every tendon's
    target at every grid tension is written as a learned target (`learn T N
    DB` console command; EEPROM, with a CRC and the table identity, as `learn`
    stores them). `table` then marks every target with `*`, `status` shows
    `learned=` for every tendon; `hallhome forget all` returns to the
    compiled targets. Refused, with the reason, when ROBOT selects another
    sensor for a tendon or has another tension grid than the board's table:
    flash the identified table instead (`hallhome tables ROBOT` and
    `make flash`)."""
    from hallhome import tablegen
    from hallhome.robot import RobotError, load_robot
    from hallhome.usable import check_limits, firmware_limits, robot_refusals

    try:
        desc = load_robot(robot)
    except RobotError as e:
        raise HallhomeError(f"{robot}: {e}") from None
    if "dB_uT" not in [a.name for a in protocol.COMMANDS_BY_NAME["learn"].args]:
        raise HallhomeError("the firmware declarations (lib/console/con_commands.def) have no "
                            "`learn T N DB` (install a given target)")
    if not as_json:
        err().print(f"computing the targets of {escape(desc.name)} "
                    f"({len(desc.tendons)} tendons x {len(desc.tension_grid)} tensions) ...")
    limits = firmware_limits()
    refused = robot_refusals(desc, limits)
    if not refused:
        res = tablegen.compute(desc)
        refused = check_limits(desc, res, limits)
    if refused:
        raise HallhomeError(f"{robot}: the firmware cannot use these targets:\n  "
                            + "\n  ".join(map(str, refused)))
    table = tablegen.build_table(res, tablegen.parse_table_header())
    with session(port, timeout) as c:
        head, rows = read_table(c)
        board = TableInfo.from_board(head, rows)
        p = plan(table, board, desc.name, force)
        if p.refusals:
            raise HallhomeError("cannot install these targets on this board:\n  "
                                + "\n  ".join(p.refusals))
        sent = 0
        if not dry_run:
            wait_saved(c, 20.0)
            try:
                c.command(cmd("forget", "all"))
            except (BoardError, LocalError) as e:
                raise HallhomeError(f"`forget all` refused: {e}") from None
            for t, pts in sorted(p.targets.items()):
                for g, uT in pts:
                    wait_saved(c, 20.0)
                    try:
                        c.command(cmd("learn", t, fixed3(g / 1000.0), f"{uT:.2f}"),
                                  timeout=max(timeout, 10.0))
                    except (BoardError, LocalError) as e:
                        raise HallhomeError(
                            f"tendon {t} at {g / 1000:.3f} N ({uT:.2f} uT) refused: {e}; "
                            f"{sent} target(s) installed so far (`hallhome forget all` removes "
                            "them)") from None
                    sent += 1
                if not as_json:
                    err().print(f"tendon {t}: {len(pts)} targets installed")
            wait_saved(c, 20.0)
            bad = _verify(c, p)
            if bad:
                raise HallhomeError("installed target(s) not in the board's table: "
                                    + ", ".join(bad))
    doc = {"robot": desc.name, "board_table": board.robot, "board_table_id": board.table_id,
           "dry_run": dry_run, "installed": sent,
           "targets_uT": {str(t): [uT for _, uT in pts] for t, pts in p.targets.items()},
           "grid_mN": board.grid}
    if as_json:
        print_json(doc)
        return
    if dry_run:
        out().print(f"dry run: {sum(len(v) for v in p.targets.values())} targets of "
                    f"{escape(desc.name)} fit the board's table {escape(board.robot)} "
                    f"{board.table_id}; nothing sent")
    else:
        out().print(f"installed {sent} targets of {escape(desc.name)} on the board (table "
                    f"{escape(board.robot)} {board.table_id}); `table` marks them with *, "
                    "`hallhome forget all` returns to the compiled targets")
