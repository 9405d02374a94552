"""Lookup-table generator: robot TOML -> lookup_tables/generated/<robot>.c
and its JSON twin <robot>.json (docs/tables.md); with learned targets
exported by `hallhome learn`, <robot>_learned.c and .json instead.

The C layout is declared once, in lib/table/table.h. The generator parses
that header for the constants (TBL_MAGIC, TBL_MAX_*, ...) and the struct
fields, fills every field by name and refuses to write a table when the
header has a field it does not know. The output is deterministic: the same
robot gives the same bytes on every run (no time stamps, no absolute paths,
fixed rounding).

This module runs the steps (generate) and names the generator's API; each
step lives in its own module:

- tablegen_spec: the C contract parsed from table.h (TableSpec, TableError);
- tablegen_compute: the model sweep and the sensor selection (compute);
- tablegen_table: the integer table, its checks and its bytes (build_table);
- tablegen_learned: learned-target files and their merge (apply_learned);
- tablegen_render: the C source and the JSON twin (render_c, render_json).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from hallhome.robot import Robot, load_robot
from hallhome.tablegen_compute import (MODEL_STEPS, RISE_MARGIN, SENSITIVITY_STEP_N, RobotResult,
                                       TendonResult, _pick, compute)
from hallhome.tablegen_learned import (LEARNED_FORMAT, LEARNED_FORMAT_VERSION, LEARNED_SUFFIX,
                                       LearnedApplied, LearnedFile, apply_learned, load_learned)
from hallhome.tablegen_render import render_c, render_json
from hallhome.tablegen_spec import (TABLE_HEADER, CField, TableError, TableSpec,
                                    parse_table_header)
from hallhome.tablegen_table import (build_table, canonical_bytes, check_table, table_size,
                                     target_cuT)
from hallhome.usable import UnusableRobot, check_limits, firmware_limits, robot_refusals

__all__ = [
    "LEARNED_FORMAT", "LEARNED_FORMAT_VERSION", "LEARNED_SUFFIX", "MODEL_STEPS", "RISE_MARGIN",
    "SENSITIVITY_STEP_N", "TABLE_HEADER", "CField", "Generated", "LearnedApplied",
    "LearnedFile", "RobotResult", "TableError", "TableSpec", "TendonResult", "UnusableRobot",
    "apply_learned", "build_table", "canonical_bytes", "check_table", "compute",
    "generate", "load_learned", "parse_table_header", "render_c", "render_json",
    "table_size", "target_cuT",
    "_pick",  # the tests check its tie-breaking
]


@dataclass
class Generated:
    robot: Robot
    result: RobotResult
    table: dict
    c_path: Path
    json_path: Path
    learned: LearnedApplied | None = None


def generate(robot_path: str | Path, out_dir: str | Path, progress=None,
             steps: int = MODEL_STEPS, learned: Sequence[str | Path] = (),
             force: bool = False) -> Generated:
    """Load, compute and write <out_dir>/<robot>.c and .json. Files are only
    rewritten when their content changes. With ``learned`` files (exported by
    `hallhome learn`, applied in order) the learned targets replace the
    model's and the files are <robot>_learned.c and .json instead.

    Raises ``UnusableRobot`` listing every reason the firmware cannot use the
    design (hallhome.usable); with ``force`` they become warnings instead
    (limits of the table format itself still raise ``TableError``)."""
    spec = parse_table_header()
    limits = firmware_limits()
    files = [load_learned(p) for p in learned]  # format errors before the model runs
    robot = load_robot(robot_path)
    early = robot_refusals(robot, limits)
    if early and not force:
        raise UnusableRobot(early)  # before the model runs: counts, name, units
    res = compute(robot, steps=steps, progress=progress)
    refusals = check_limits(robot, res, limits)
    if refusals and not force:
        raise UnusableRobot(refusals)
    res.warnings = [f"forced: {r}" for r in refusals] + res.warnings
    table = build_table(res, spec)
    applied = None
    if files:
        applied = apply_learned(table, spec, robot, files)
        table = applied.table
        res.warnings = res.warnings + applied.warnings
    name = robot.name if applied is None else applied.name
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    c_path, json_path = out / f"{name}.c", out / f"{name}.json"
    _write_if_changed(c_path, render_c(table, spec, robot, applied))
    _write_if_changed(json_path, render_json(res, table, spec, applied))
    return Generated(robot, res, table, c_path, json_path, applied)


def _write_if_changed(path: Path, text: str) -> None:
    if path.exists() and path.read_text(encoding="utf-8") == text:
        return
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text, encoding="utf-8", newline="\n")
    tmp.replace(path)

