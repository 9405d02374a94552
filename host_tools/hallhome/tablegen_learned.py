"""Learned targets: reading the files `hallhome learn` exports
(format in docs/operator.md) and compiling their targets into the model's
table in place of the model's.
"""

from __future__ import annotations

import json
import re
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from hallhome.paths import ROBOTS_DIR
from hallhome.robot import Robot
from hallhome.tablegen_compute import _tendon_name
from hallhome.tablegen_render import _relpath
from hallhome.tablegen_spec import TableError, TableSpec
from hallhome.tablegen_table import canonical_bytes, check_table

LEARNED_FORMAT = "hallhome-learned"
LEARNED_FORMAT_VERSION = 1
LEARNED_SUFFIX = "_learned"  # <robot>_learned.c defines tbl_table_<robot>_learned
_HEX_ID = re.compile(r"0[xX][0-9A-Fa-f]{1,8}")


@dataclass(frozen=True)
class LearnedFile:
    """One validated learned-targets file (format in docs/operator.md)."""

    path: Path
    source: str  # the path as written into the outputs (project-relative or bare name)
    robot: str
    table_id: int  # the table the board ran while learning
    grid_mN: tuple[int, ...]
    targets: dict[int, tuple[int | None, ...]]  # tendon -> per grid_mN entry, None = not learned
    samples: tuple[dict, ...]

    @property
    def count(self) -> int:
        return sum(v is not None for row in self.targets.values() for v in row)


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def load_learned(path: str | Path) -> LearnedFile:
    """Read and check a `hallhome learn` export on its own (the checks that
    need the table are in apply_learned). Raises TableError naming the file
    and the problem."""
    path = Path(path)
    where = path.name

    def fail(msg: str):
        raise TableError(f"learned targets {where}: {msg}")

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        fail(f"cannot read the file ({exc})")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        fail(f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})")
    if not isinstance(doc, dict):
        fail("expected a JSON object at the top level")

    def need(obj: dict, key: str, ctx: str = ""):
        if key not in obj:
            fail(f"missing field '{ctx}{key}'")
        return obj[key]

    if need(doc, "format") != LEARNED_FORMAT:
        fail(f"format is {doc['format']!r}, expected {LEARNED_FORMAT!r} "
             f"(the file `hallhome learn` writes)")
    version = need(doc, "format_version")
    if version != LEARNED_FORMAT_VERSION:
        fail(f"format_version {version!r} is not supported (this generator reads "
             f"{LEARNED_FORMAT_VERSION})")
    robot = need(doc, "robot")
    if not isinstance(robot, str) or not robot:
        fail(f"robot must be a non-empty string, got {robot!r}")
    tid = need(doc, "table_id")
    if not isinstance(tid, str) or not _HEX_ID.fullmatch(tid):
        fail(f"table_id must be a hex string like \"0x1115c2f1\", got {tid!r}")
    grid = need(doc, "grid_mN")
    if (not isinstance(grid, list) or len(grid) < 1
            or not all(_is_int(g) and 0 < g <= 0xFFFF for g in grid)):
        fail(f"grid_mN must be a list of tensions in mN (integers 1..65535), got {grid!r}")
    if any(b <= a for a, b in zip(grid, grid[1:])):
        fail(f"grid_mN is not strictly increasing: {grid}")
    rows = need(doc, "tendons")
    if not isinstance(rows, list):
        fail(f"tendons must be a list, got {type(rows).__name__}")
    targets: dict[int, tuple[int | None, ...]] = {}
    for k, row in enumerate(rows):
        ctx = f"tendons[{k}]."
        if not isinstance(row, dict):
            fail(f"tendons[{k}] must be an object")
        t = need(row, "tendon", ctx)
        if not _is_int(t) or t < 0:
            fail(f"{ctx}tendon must be a tendon index (integer >= 0), got {t!r}")
        vals = need(row, "target_cuT", ctx)
        if not isinstance(vals, list) or len(vals) != len(grid):
            fail(f"{ctx}target_cuT must be a list with one entry per grid_mN tension "
                 f"({len(grid)}), got {vals!r}")
        for g, v in zip(grid, vals):
            if v is not None and not (_is_int(v) and 0 <= v <= 0xFFFFFFFF):
                fail(f"{ctx}target_cuT at {g} mN must be null or an integer in cuT "
                     f"(0..4294967295), got {v!r}")
        if t in targets:
            fail(f"tendon {t} appears twice in tendons")
        targets[t] = tuple(vals)
    samples = doc.get("samples", [])
    if not isinstance(samples, list):
        fail(f"samples must be a list, got {type(samples).__name__}")
    for k, smp in enumerate(samples):
        ctx = f"samples[{k}]."
        if not isinstance(smp, dict):
            fail(f"samples[{k}] must be an object")
        for key in ("tendon", "tension_mN"):
            v = need(smp, key, ctx)
            if not _is_int(v) or v < 0:
                fail(f"{ctx}{key} must be an integer >= 0, got {v!r}")
    return LearnedFile(path, _relpath(path), robot, int(tid, 16), tuple(grid), targets,
                       tuple(samples))


@dataclass
class LearnedApplied:
    """The model's table with learned targets compiled in."""

    name: str  # <robot>_learned: the file stem and the C symbol's suffix
    table: dict  # as build_table's, learned target_lsb in place, table_id recomputed
    model_table_id: int
    files: list[LearnedFile]
    mask: list[list[bool]]  # [tendon][grid point]: target learned
    warnings: list[str]

    def summary(self) -> str:
        grid = self.table["grid_mN"]
        parts = [f"{t}: " + ",".join(str(g) for g, m in zip(grid, row) if m)
                 for t, row in enumerate(self.mask) if any(row)]
        return "; ".join(parts)


def apply_learned(table: dict, spec: TableSpec, robot: Robot,
                  files: Sequence[LearnedFile]) -> LearnedApplied:
    """Replace the model's targets by the learned targets of ``files`` (cuT,
    rounded to the table's LSB like the board stores them),
    applied in order: the first must have been learned on the model's table
    (same table_id), each later one on the table the earlier ones give (the
    firmware built from it). A later file's entry replaces an earlier one.
    Raises TableError on any mismatch; returns warnings for grid points left
    to the model and for targets that do not grow across the grid."""
    if not files:
        raise TableError("no learned targets file given")
    name = robot.name + LEARNED_SUFFIX
    if (ROBOTS_DIR / f"{name}.toml").exists():
        raise TableError(f"{robot.path.name}: a robot named {name!r} exists in "
                         f"lookup_tables/robots; its table and this learned table would "
                         f"share a name")
    grid = list(table["grid_mN"])
    cut = spec["TBL_CUT_PER_LSB"]
    nt = table["n_tendons"]
    model_id = table["table_id"]
    cur = json.loads(json.dumps(table))  # deep copy, plain data
    mask = [[False] * len(grid) for _ in range(nt)]
    origin: dict[tuple[int, int], str] = {}
    grid_txt = ", ".join(map(str, grid))
    for lf in files:
        where = f"learned targets {lf.path.name}"
        if lf.robot != robot.name:
            raise TableError(f"{where}: learned on robot {lf.robot!r}, but "
                             f"{robot.path.name} describes {robot.name!r}")
        for g in lf.grid_mN:
            if g not in grid:
                raise TableError(f"{where}: tension {g} mN is not on the table's grid "
                                 f"({grid_txt} mN)")
        for k, smp in enumerate(lf.samples):
            if smp["tension_mN"] not in grid:
                raise TableError(f"{where}: samples[{k}]: tension {smp['tension_mN']} mN is "
                                 f"not on the table's grid ({grid_txt} mN)")
            if smp["tendon"] >= nt:
                raise TableError(f"{where}: samples[{k}]: tendon {smp['tendon']} out of range "
                                 f"({robot.name} has tendons 0..{nt - 1})")
        for t in lf.targets:
            if t >= nt:
                raise TableError(f"{where}: tendon {t} out of range ({robot.name} has "
                                 f"tendons 0..{nt - 1})")
        if lf.table_id != cur["table_id"]:
            first = lf is files[0]
            on = ("the model's table" if first else
                  "the table the learned files before it give")
            raise TableError(
                f"{where}: learned on table 0x{lf.table_id:08X}, but {on} is "
                f"0x{cur['table_id']:08X}. Learned targets are only valid for the table the "
                f"board ran while learning (same TOML, model and sensor selection). "
                + ("A file learned on a firmware with a learned table needs the learned "
                   "files that built that table before it (--learned in order)."
                   if first else "Give the files in the order their tables were built."))
        for t, row in lf.targets.items():
            for g, v in zip(lf.grid_mN, row):
                if v is None:
                    continue
                gi = grid.index(g)
                if v > 0xFFFF * cut:
                    raise TableError(
                        f"{where}: tendon {t} at {g} mN: target {v} cuT ({v / 100:g} uT) does "
                        f"not fit the table's uint16_t field: at most 65535 LSB = "
                        f"{0xFFFF * cut / 100:g} uT (TBL_CUT_PER_LSB = {cut} cuT, "
                        f"lib/table/table.h)")
                cur["tendons"][t]["target_lsb"][gi] = (v + cut // 2) // cut
                mask[t][gi] = True
                origin[(t, gi)] = lf.path.name
        cur["table_id"] = 0
        check_table(cur, spec, robot.path.name)
        cur["table_id"] = zlib.crc32(canonical_bytes(cur, spec))
    if not any(any(row) for row in mask):
        raise TableError(f"learned targets {', '.join(f.path.name for f in files)}: no learned "
                         f"target at all (every target_cuT entry is null)")
    warnings = []
    for t in range(nt):
        name_t = _tendon_name(robot, t)
        vals = [v * cut for v in cur["tendons"][t]["target_lsb"]]
        pts = [(gi, vals[gi]) for gi in range(len(grid)) if mask[t][gi]]
        for (ga, va), (gb, vb) in zip(pts, pts[1:]):
            if vb <= va:
                raise TableError(
                    f"learned targets: {name_t}: learned target does not grow between "
                    f"{grid[ga]} mN ({va} cuT, {origin[(t, ga)]}) and {grid[gb]} mN "
                    f"({vb} cuT, {origin[(t, gb)]}): the targets must increase with the "
                    f"tension (a mass hung on the wrong tendon, or a moved sensor?)")
        left = [g for g, m in zip(grid, mask[t]) if not m]
        if len(left) == len(grid):
            warnings.append(f"{name_t}: no learned target; all {len(grid)} grid tensions keep "
                            f"the model's target")
        elif left:
            warnings.append(f"{name_t}: {len(left)} of {len(grid)} grid tensions keep the "
                            f"model's target ({', '.join(f'{g / 1e3:g}' for g in left)} N)")
        if pts and left:
            for k in range(len(grid) - 1):
                if vals[k + 1] <= vals[k]:
                    src = ["model" if not mask[t][i] else "learned" for i in (k, k + 1)]
                    warnings.append(f"{name_t}: target does not grow between {grid[k]} mN "
                                    f"({src[0]}, {vals[k]} cuT) and {grid[k + 1]} mN "
                                    f"({src[1]}, {vals[k + 1]} cuT); learn the neighbouring "
                                    f"grid points too")
                    break
    if robot.mode == "absolute":
        warnings.append("the table's mode is absolute: learned targets replace the delta "
                        "targets (target_lsb) only, abs_target_lsb stays the model's")
    return LearnedApplied(name, cur, model_id, list(files), mask, warnings)
