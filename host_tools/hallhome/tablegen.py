"""Lookup-table generator: robot TOML -> lookup_tables/generated/<robot>.c
and its JSON twin <robot>.json (docs/tables.md); with learned targets
exported by `hallhome learn`, <robot>_learned.c and .json instead.

The C layout is declared once, in lib/table/table.h. This module parses that
header for the constants (TBL_MAGIC, TBL_MAX_*, ...) and the struct fields,
fills every field by name and refuses to write a table when the header has a
field it does not know. The output is deterministic: the same robot gives the
same bytes on every run (no time stamps, no absolute paths, fixed rounding).
"""

from __future__ import annotations

import json
import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from hallhome.field import field_at_sensors, magnet_poses
from hallhome.model import CosseratModel, Solution
from hallhome.paths import LIB_DIR, PROJECT_ROOT, ROBOTS_DIR
from hallhome.robot import Robot, load_robot
from hallhome.straight import straight_um_table
from hallhome.usable import UnusableRobot, check_limits, firmware_limits, robot_refusals

TABLE_HEADER = LIB_DIR / "table" / "table.h"
SENSITIVITY_STEP_N = 0.01  # central difference for d|dB|/dT at the default tension
# |dB| must rise up to the top of the grid plus this part of its last interval
RISE_MARGIN = 0.25
MODEL_STEPS = 8  # integration steps per segment (docs/model.md: < 1 um at the tip)

_CTYPES = {"uint8_t": ("B", 0, 0xFF), "int8_t": ("b", -0x80, 0x7F),
           "uint16_t": ("H", 0, 0xFFFF), "int16_t": ("h", -0x8000, 0x7FFF),
           "uint32_t": ("I", 0, 0xFFFFFFFF), "int32_t": ("i", -0x80000000, 0x7FFFFFFF),
           "char": ("c", 0, 0x7F)}


class TableError(RuntimeError):
    """The table cannot be generated (message names the robot and the cause)."""


# --- the C contract ---------------------------------------------------------------

@dataclass(frozen=True)
class CField:
    ctype: str
    name: str
    count: int | None  # array length, None for a scalar
    dims: tuple[str, ...] = ()  # TBL_LAYOUT members: the count parameters (NT, NS, NG)


@dataclass(frozen=True)
class TableSpec:
    """What lib/table/table.h declares: integer constants, struct fields and
    the stored layout (TBL_LAYOUT's members, sized by the robot's counts)."""

    constants: dict[str, int]
    structs: dict[str, tuple[CField, ...]]
    layout: tuple[CField, ...] = ()
    layout_params: tuple[str, str, str] = ("NT", "NS", "NG")

    def __getitem__(self, name: str) -> int:
        return self.constants[name]


def parse_table_header(path: Path = TABLE_HEADER) -> TableSpec:
    """Parse the #define constants and the typedef'd structs of table.h."""
    text = path.read_text(encoding="utf-8")
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    consts: dict[str, int] = {}
    for name, value in re.findall(r"#define\s+(TBL_\w+)\s+(0[xX][0-9A-Fa-f]+|\d+)[uUlL]*\b",
                                  text):
        consts[name] = int(value, 0)
    structs: dict[str, tuple[CField, ...]] = {}
    for body, sname in re.findall(r"typedef\s+struct\s*\{(.*?)\}\s*(\w+)\s*;", text, flags=re.S):
        fields = []
        for decl in body.split(";"):
            decl = " ".join(decl.split())
            if not decl:
                continue
            m = re.fullmatch(r"(?:const\s+)?(\w+)\s+(\w+)(?:\s*\[\s*(\w+)\s*\])?", decl)
            if m is None:
                fields = None  # pointers, function types: not table data
                break
            ctype, name, dim = m.groups()
            count = None if dim is None else (consts[dim] if dim in consts else int(dim, 0))
            fields.append(CField(ctype, name, count))
        if fields is not None:
            structs[sname] = tuple(fields)
    for needed in ("TBL_MAGIC", "TBL_FORMAT_VERSION", "TBL_MAX_GRID", "TBL_MAX_TENDONS",
                   "TBL_MAX_SENSORS", "TBL_NAME_LEN", "TBL_NO_MUX", "TBL_MODE_DELTA",
                   "TBL_MODE_ABSOLUTE", "TBL_CUT_PER_LSB"):
        if needed not in consts:
            raise TableError(f"{path}: constant {needed} not found")
    m = re.search(r"#define\s+TBL_LAYOUT\(\s*(\w+)\s*,\s*(\w+)\s*,\s*(\w+)\s*\)\s*\\\s*"
                  r"struct\s+tbl_table\s*\{(.*?)\}", text, flags=re.S)
    if m is None:
        raise TableError(f"{path}: macro TBL_LAYOUT(NT, NS, NG) not found")
    params = m.group(1, 2, 3)
    layout = []
    for decl in m.group(4).replace("\\", " ").split(";"):
        decl = " ".join(decl.split())
        if not decl:
            continue
        fm = re.fullmatch(r"(\w+)\s+(\w+)((?:\s*\[\s*\w+\s*\])*)", decl)
        if fm is None:
            raise TableError(f"{path}: TBL_LAYOUT member {decl!r} not understood")
        dims = tuple(re.findall(r"\w+", fm.group(3)))
        if any(d not in params for d in dims):
            raise TableError(f"{path}: TBL_LAYOUT member {decl!r}: sizes must be {params}")
        layout.append(CField(fm.group(1), fm.group(2), None, dims))
    if not layout or layout[0].ctype not in structs or layout[0].dims:
        raise TableError(f"{path}: TBL_LAYOUT must start with the header struct")
    return TableSpec(consts, structs, tuple(layout), params)


# --- computation --------------------------------------------------------------------

@dataclass
class TendonResult:
    """Model results of one tendon swept over the tension grid (SI units)."""

    solutions: list[Solution]  # one per grid tension
    field: np.ndarray  # (n_grid, n_sensors, 3) magnet field in sensor frames, T
    delta: np.ndarray  # (n_grid, n_sensors) |B(p_T) - B(p_0)|, T
    sensitivity: np.ndarray  # (n_sensors,) d|dB|/dT at the default tension, T/N
    geometric: np.ndarray  # (n_grid,) path shortening from engagement, m
    stretch: np.ndarray  # (n_grid,) elastic stretch, m
    selected: int  # sensor with the largest sensitivity among those rising over the grid
    closest: int  # sensor closest to the magnet at the default tension
    closest_distance: float  # m
    rises_to: np.ndarray  # (n_sensors,) tension up to which |dB| keeps rising, N

    @property
    def travel(self) -> np.ndarray:
        return self.geometric + self.stretch


@dataclass
class RobotResult:
    robot: Robot
    straight: Solution
    b_straight: np.ndarray  # (n_sensors, 3), T, sensor frames
    tendons: list[TendonResult]
    warnings: list[str] = field(default_factory=list)
    # (n_tendons, n_grid) take-up from the single-tendon to the straight-pose
    # home, um (hallhome.straight)
    straight_um: np.ndarray | None = None


def _pick(values: np.ndarray, largest: bool) -> int:
    """Index of the largest (smallest) value; near-ties (1e-9 relative) go to
    the lowest index so symmetric layouts pick the same sensor everywhere."""
    v = np.asarray(values, float)
    best = v.max() if largest else v.min()
    tol = 1e-9 * max(abs(best), 1e-30)  # float noise only; real asymmetries count
    return int(np.nonzero(np.abs(v - best) <= tol)[0][0])


def _fine_tensions(grid: np.ndarray) -> np.ndarray:
    """The grid, the midpoint of each interval, and the top plus
    RISE_MARGIN of its last interval: where |dB| must keep rising."""
    mids = 0.5 * (grid[1:] + grid[:-1])
    past = grid[-1] + RISE_MARGIN * (grid[-1] - grid[-2])
    return np.sort(np.concatenate([grid, mids, [past]]))


def _rises_to(fine: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Per sensor: the highest tension of fine up to which |dB| (rows of
    delta, one per tension) rises strictly from the lowest."""
    out = np.empty(delta.shape[1])
    for k in range(delta.shape[1]):
        falls = np.nonzero(np.diff(delta[:, k]) <= 0)[0]
        out[k] = fine[falls[0]] if len(falls) else fine[-1]
    return out


def _select(sens: np.ndarray, rises_to: np.ndarray, top: float) -> int:
    """The sensor a tendon's targets use: the most sensitive at the default
    tension among those whose |dB| rises past the top of the grid; when none
    does, the one that rises furthest (then the most sensitive of those)."""
    ok = rises_to > top
    if not ok.any():
        ok = rises_to >= rises_to.max()
    return _pick(np.where(ok, sens, -np.inf), True)


def compute(robot: Robot, steps: int = MODEL_STEPS, progress=None) -> RobotResult:
    """Sweep every tendon alone over the tension grid with the Cosserat model
    and the field model. ``progress(n)`` is called after each tendon."""
    model = CosseratModel(robot, steps_per_segment=steps)
    nt = len(robot.tendons)
    straight = model.solve(np.zeros(nt))
    b0 = field_at_sensors(robot, straight.tip_position, straight.tip_rotation)[0]
    grid = np.array(robot.tension_grid)
    td = robot.default_tension
    sensor_pos = np.array([s.position for s in robot.sensors])
    out = RobotResult(robot, straight, b0, [])
    fine = _fine_tensions(grid)
    on_grid = np.isin(fine, grid)
    for i, tendon in enumerate(robot.tendons):
        fsols = []
        guess = None
        # the grid's tensions are the spool's (what the servo holds); the
        # robot bends under what friction lets through to the tendon's end.
        # Between the grid's tensions and a little past the top, the field
        # must keep rising: a magnet that passes a sensor makes |dB| peak,
        # and a pull stops at the target's first crossing
        for T in fine:
            tau = np.zeros(nt)
            tau[i] = robot.tip_tension(tendon, T)
            sol = model.solve(tau, base_moment_guess=guess)
            guess = sol.base_moment
            fsols.append(sol)
        sols = [sl for sl, g in zip(fsols, on_grid) if g]
        extra = []
        for T in (td - SENSITIVITY_STEP_N, td + SENSITIVITY_STEP_N):
            tau = np.zeros(nt)
            tau[i] = robot.tip_tension(tendon, T)
            extra.append(model.solve(tau, base_moment_guess=guess))
        allsol = fsols + extra
        B = field_at_sensors(robot, np.array([s.tip_position for s in allsol]),
                             np.array([s.tip_rotation for s in allsol]))
        delta_all = np.linalg.norm(B - b0[None], axis=-1)
        sens = (delta_all[-1] - delta_all[-2]) / (2 * SENSITIVITY_STEP_N)
        rises_to = _rises_to(fine, delta_all[:-2])
        B = B[:-2][on_grid]
        delta = delta_all[:-2][on_grid]
        # the magnet at the default tension, for the paper's closest-sensor rule
        tau = np.zeros(nt)
        tau[i] = robot.tip_tension(tendon, td)
        dsol = model.solve(tau, base_moment_guess=guess)
        mpos, _ = magnet_poses(robot, dsol.tip_position, dsol.tip_rotation)
        dist = np.linalg.norm(sensor_pos - mpos[0], axis=1)
        geometric = np.array([straight.path_lengths[i] - s.path_lengths[i] for s in sols])
        stretch = np.array([robot.tendon_stretch(tendon, T, s.path_lengths[i])
                            for T, s in zip(grid, sols)])
        out.tendons.append(TendonResult(sols, B, delta, sens, geometric, stretch,
                                        _select(sens, rises_to, grid[-1]), _pick(dist, False),
                                        float(dist[_pick(dist, False)]), rises_to))
        if progress is not None:
            progress(i + 1)
    single_um = np.array([[s.displacements[i] * 1e6 for s in tr.solutions]
                          for i, tr in enumerate(out.tendons)])
    try:
        out.straight_um = straight_um_table(robot, grid, model, single_um)
    except ValueError as e:
        raise TableError(f"{robot.path.name}: {e}") from None
    out.warnings = _warnings(out)
    return out


def _tendon_name(robot: Robot, i: int) -> str:
    t = robot.tendons[i]
    return f"tendon {i} (servo {t.servo_id}, segment {t.segment})"


def _warnings(res: RobotResult) -> list[str]:
    robot = res.robot
    w = []
    for i, tr in enumerate(res.tendons):
        name = _tendon_name(robot, i)
        sel = tr.selected
        if tr.rises_to[sel] <= robot.tension_grid[-1]:
            w.append(f"{name}: no sensor's field keeps rising up to "
                     f"{robot.tension_grid[-1]:g} N (the magnet passes a sensor); on sensor "
                     f"{sel} it stops rising at {tr.rises_to[sel]:g} N, and a calibration "
                     f"above that lands early, short of its tension")
        elif sel != _pick(tr.sensitivity, True):
            best = _pick(tr.sensitivity, True)
            w.append(f"{name}: sensor {best} is the most sensitive "
                     f"({tr.sensitivity[best] * 1e6:.1f} uT/N) but its field stops rising at "
                     f"{tr.rises_to[best]:g} N; using sensor {sel} "
                     f"({tr.sensitivity[sel] * 1e6:.1f} uT/N)")
        if tr.selected != tr.closest and sel == _pick(tr.sensitivity, True):
            w.append(f"{name}: sensor {tr.selected} has the largest sensitivity "
                     f"({tr.sensitivity[tr.selected] * 1e6:.1f} uT/N), the closest sensor "
                     f"{tr.closest} has {tr.sensitivity[tr.closest] * 1e6:.1f} uT/N; "
                     f"using sensor {tr.selected}")
        steps = np.diff(tr.delta[:, sel])
        if np.any(steps <= 0):
            k = int(np.nonzero(steps <= 0)[0][0])
            w.append(f"{name}: target on sensor {sel} does not grow between "
                     f"{robot.tension_grid[k]:g} N and {robot.tension_grid[k + 1]:g} N")
        abs_t = np.linalg.norm(tr.field[:, sel], axis=-1)
        if robot.mode == "absolute" and np.any(np.diff(abs_t) <= 0):
            k = int(np.nonzero(np.diff(abs_t) <= 0)[0][0])
            w.append(f"{name}: absolute target on sensor {sel} does not grow between "
                     f"{robot.tension_grid[k]:g} N and {robot.tension_grid[k + 1]:g} N")
        for T, tv in zip(robot.tension_grid, tr.travel):
            if tv > robot.travel_limit:
                w.append(f"{name}: expected travel {tv * 1e3:.3f} mm at {T:g} N exceeds the "
                         f"travel limit {robot.travel_limit * 1e3:.3f} mm")
                break
    # Saturation and targets lost in the noise are refusals (hallhome.usable).
    return w


# --- integer table ------------------------------------------------------------------

def _cuT(x: float) -> int:
    return int(round(x * 1e8))  # T -> centi-microtesla (10 nT)


def _lsb(x: float, spec: TableSpec) -> int:
    """T -> the table's field unit (TBL_CUT_PER_LSB cuT), nearest integer."""
    return int(round(x * 1e8 / spec["TBL_CUT_PER_LSB"]))


def _um(x: float) -> int:
    return int(round(x * 1e6))


def build_table(res: RobotResult, spec: TableSpec) -> dict:
    """The table content as a nested dict keyed by table.h field names, with
    integer values in the stored units: the header's fields at the top level,
    ``grid_mN``, ``sensors`` and ``tendons`` (each tendon with its per-grid
    rows). Raises TableError naming the robot, the key and the limit when a
    value does not fit its stored type (nothing is clipped)."""
    robot = res.robot
    c = spec.constants
    nt, ns, ng = len(robot.tendons), len(robot.sensors), len(robot.tension_grid)
    limits = [("tendons", nt, "TBL_MAX_TENDONS"), ("sensors", ns, "TBL_MAX_SENSORS"),
              ("tension grid points", ng, "TBL_MAX_GRID")]
    for what, n, cname in limits:
        if n > c[cname]:
            raise TableError(f"{robot.path.name}: {n} {what}, the table holds at most "
                             f"{c[cname]} ({cname} in lib/table/table.h)")
    if len(robot.name) >= c["TBL_NAME_LEN"]:
        raise TableError(f"{robot.path.name}: robot name {robot.name!r} is longer than "
                         f"{c['TBL_NAME_LEN'] - 1} characters (TBL_NAME_LEN)")
    grid_mN = [int(round(T * 1e3)) for T in robot.tension_grid]
    if any(b <= a for a, b in zip(grid_mN, grid_mN[1:])):
        raise TableError(f"{robot.path.name}: tension grid is not strictly increasing in mN: "
                         f"{grid_mN}")
    default_mN = int(round(robot.default_tension * 1e3))
    for i, tr in enumerate(res.tendons):
        t_def = float(np.interp(robot.default_tension, robot.tension_grid, tr.travel))
        if t_def > robot.travel_limit:
            raise TableError(f"{robot.path.name}: {_tendon_name(robot, i)}: expected travel "
                             f"{t_def * 1e3:.3f} mm at the default tension exceeds "
                             f"travel_limit_mm = {robot.travel_limit * 1e3:.3f}")
    sensors = []
    for s, b in zip(robot.sensors, res.b_straight):
        sensors.append({"mux_channel": c["TBL_NO_MUX"] if s.mux_channel is None
                        else s.mux_channel,
                        "i2c_addr": s.i2c_address,
                        "b_straight_lsb": [_lsb(x, spec) for x in b]})
    tendons = []
    for i, (t, tr) in enumerate(zip(robot.tendons, res.tendons)):
        sel = tr.selected
        tendons.append({
            "servo_id": t.servo_id,
            "pull_dir": t.pull_dir,
            "segment": t.segment,
            "sensor": sel,
            "nm_per_tick": int(round(t.metres_per_tick * 1e9)),
            "travel_limit_um": _um(robot.travel_limit),
            "target_lsb": [_lsb(x, spec) for x in tr.delta[:, sel]],
            "abs_target_lsb": [_lsb(x, spec) for x in np.linalg.norm(tr.field[:, sel], axis=-1)],
            "travel_um": [_um(x) for x in tr.travel],
            "straight_um": [int(x) for x in res.straight_um[i]],
        })
    table = {
        "magic": c["TBL_MAGIC"],
        "format_version": c["TBL_FORMAT_VERSION"],
        "size": table_size(spec, nt, ns, ng),
        "table_id": 0,
        "name": robot.name,
        "n_tendons": nt,
        "n_sensors": ns,
        "n_grid": ng,
        "mode": c["TBL_MODE_DELTA"] if robot.mode == "delta" else c["TBL_MODE_ABSOLUTE"],
        "default_mN": default_mN,
        "noise_cuT": _cuT(robot.noise),
        "grid_mN": grid_mN,
        "sensors": sensors,
        "tendons": tendons,
    }
    check_table(table, spec, robot.path.name)
    table["table_id"] = zlib.crc32(canonical_bytes(table, spec))
    return table


def _ctype_size(spec: TableSpec, ctype: str) -> int:
    if ctype in spec.structs:
        return sum((f.count or 1) * _ctype_size(spec, f.ctype) for f in spec.structs[ctype])
    return 1 if ctype == "char" else struct.calcsize("<" + _CTYPES[ctype][0])


def table_size(spec: TableSpec, nt: int, ns: int, ng: int) -> int:
    """Bytes of the stored table for these counts (TBL_SIZE in table.h)."""
    n = dict(zip(spec.layout_params, (nt, ns, ng)))
    total = 0
    for f in spec.layout:
        count = 1
        for d in f.dims:
            count *= n[d]
        total += count * _ctype_size(spec, f.ctype)
    return total


def _layout_items(table: dict, spec: TableSpec):
    """(member, value) in TBL_LAYOUT order: the header struct as the table's
    top-level fields, 1-dimensional members as top-level keys (a list of
    dicts for a struct type), [NT][NG] rows from each tendon's dict."""
    nt_param = spec.layout_params[0]
    for k, f in enumerate(spec.layout):
        if k == 0:
            yield f, {g.name: table[g.name] for g in spec.structs[f.ctype]}
        elif len(f.dims) == 2 and f.dims[0] == nt_param:
            yield f, [td[f.name] for td in table["tendons"]]
        elif f.name == "tendons":
            rec = spec.structs[f.ctype]
            yield f, [{g.name: td[g.name] for g in rec} for td in table["tendons"]]
        else:
            yield f, table[f.name]


def _unit_note(key: str, ctype: str, lo: int, hi: int, spec: TableSpec) -> str:
    cut = spec["TBL_CUT_PER_LSB"]
    if key.split("[")[0].endswith("_lsb") or "_lsb[" in key:
        return (f"{lo}..{hi} LSB = {lo * cut / 100:g}..{hi * cut / 100:g} uT "
                f"(TBL_CUT_PER_LSB = {cut} cuT)")
    if "_um" in key:
        return f"{lo}..{hi} um = {lo / 1000:g}..{hi / 1000:g} mm"
    return f"{lo}..{hi}"


def check_table(table: dict, spec: TableSpec, where: str) -> None:
    """Every header field filled, nothing else, the counts matching the
    arrays, every integer within its stored C type. Raises TableError naming
    ``where`` (the robot's file), the key and the limit."""
    def fail(msg):
        raise TableError(f"{where}: {msg}")

    def fields_of(value: dict, names: list[str], ctx: str):
        if set(value) != set(names):
            missing = sorted(set(names) - set(value))
            extra = sorted(set(value) - set(names))
            fail(f"lib/table/table.h {ctx}: generator and header disagree (header fields not "
                 f"filled: {missing}, unknown to header: {extra})")

    def scalar(key: str, ctype: str, v):
        if ctype in spec.structs:
            for g in spec.structs[ctype]:
                field(f"{key}.{g.name}", g, v[g.name])
            return
        _, lo, hi = _CTYPES[ctype]
        if not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
            fail(f"{key} = {v} does not fit the table's {ctype} "
                 f"({_unit_note(key, ctype, lo, hi, spec)}; lib/table/table.h)")

    def field(key: str, f: CField, v):
        if f.ctype == "char":
            if not isinstance(v, str) or len(v) >= f.count:
                fail(f"{key}: string {v!r} longer than {f.count - 1} characters")
            return
        if f.count is None:
            scalar(key, f.ctype, v)
            return
        if len(v) != f.count:
            fail(f"{key}: {len(v)} entries, the header declares {f.count}")
        for k, x in enumerate(v):
            scalar(f"{key}[{k}]", f.ctype, x)

    head = spec.layout[0]
    rec = spec.structs[spec.layout[[f.name for f in spec.layout].index("tendons")].ctype]
    rows = [f.name for f in spec.layout if len(f.dims) == 2]
    top = ([g.name for g in spec.structs[head.ctype]] +
           [f.name for f in spec.layout[1:] if len(f.dims) == 1])
    fields_of(table, top, "table")
    counts = dict(zip(spec.layout_params, (table["n_tendons"], table["n_sensors"],
                                           table["n_grid"])))
    for k, td in enumerate(table["tendons"]):
        fields_of(td, [g.name for g in rec] + rows, f"tendons[{k}]")
    if table["size"] != table_size(spec, *counts.values()):
        fail(f"size {table['size']} is not the layout's {table_size(spec, *counts.values())}")
    for f, v in _layout_items(table, spec):
        if not f.dims:
            for g in spec.structs[f.ctype]:
                field(g.name, g, v[g.name])
            continue
        if len(v) != counts[f.dims[0]]:
            fail(f"{f.name}: {len(v)} entries for {f.dims[0]} = {counts[f.dims[0]]}")
        for i, x in enumerate(v):
            if len(f.dims) == 2:
                if len(x) != counts[f.dims[1]]:
                    fail(f"tendons[{i}].{f.name}: {len(x)} entries for {f.dims[1]} = "
                         f"{counts[f.dims[1]]}")
                for g, y in enumerate(x):
                    scalar(f"tendons[{i}].{f.name}[{g}]", f.ctype, y)
            else:
                scalar(f"{f.name}[{i}]", f.ctype, x)


def _pack(spec: TableSpec, ctype: str, v, out: bytearray, count: int | None = None) -> None:
    if ctype == "char":
        raw = v.encode("ascii")
        out += raw + b"\0" * (count - len(raw))
        return
    if count is not None:
        for x in v:
            _pack(spec, ctype, x, out)
        return
    if ctype in spec.structs:
        for g in spec.structs[ctype]:
            _pack(spec, g.ctype, v[g.name], out, g.count)
        return
    out += struct.pack("<" + _CTYPES[ctype][0], int(v))


def canonical_bytes(table: dict, spec: TableSpec) -> bytes:
    """The bytes the table_id CRC-32 covers: the stored table exactly as the
    AVR holds it (TBL_LAYOUT order, little-endian, no padding), with
    table_id itself as 0."""
    out = bytearray()
    for f, v in _layout_items(table, spec):
        if not f.dims:
            v = dict(v, table_id=0)
            _pack(spec, f.ctype, v, out)
        elif len(f.dims) == 2:
            for row in v:
                _pack(spec, f.ctype, row, out, len(row))
        else:
            _pack(spec, f.ctype, v, out, len(v))
    if len(out) != table["size"]:
        raise TableError(f"table {table['name']}: {len(out)} bytes packed, size says "
                         f"{table['size']}")
    return bytes(out)


def target_cuT(table: dict, tendon: int, spec: TableSpec | None = None) -> list[int]:
    """Tendon ``tendon``'s targets in cuT, as the firmware reads them."""
    spec = spec or parse_table_header()
    return [v * spec["TBL_CUT_PER_LSB"] for v in table["tendons"][tendon]["target_lsb"]]


# --- learned targets (`hallhome learn` exports) ------------------------------------

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


# --- rendering ----------------------------------------------------------------------

_SYMBOLS = {("tbl_head_t", "magic"): "TBL_MAGIC",
            ("tbl_head_t", "format_version"): "TBL_FORMAT_VERSION"}


def _c_int(ctype: str, v: int) -> str:
    if ctype.startswith("u"):
        return f"{v}u" if v <= 0xFFFF else f"{v}UL"
    return str(v) if -0x8000 < v <= 0x7FFF else f"{v}L"


def _c_value(spec: TableSpec, sname: str, f: CField, v, indent: str) -> str:
    c = spec.constants
    sym = _SYMBOLS.get((sname, f.name))
    if sym is not None and c[sym] == v:
        return sym
    if sname == "tbl_head_t" and f.name == "table_id":
        return f"0x{v:08X}UL"
    if sname == "tbl_head_t" and f.name == "mode":
        return "TBL_MODE_DELTA" if v == c["TBL_MODE_DELTA"] else "TBL_MODE_ABSOLUTE"
    if sname == "tbl_sensor_rec_t" and f.name == "mux_channel" and v == c["TBL_NO_MUX"]:
        return "TBL_NO_MUX"
    if sname == "tbl_sensor_rec_t" and f.name == "i2c_addr":
        return f"0x{v:02X}u"
    if f.ctype == "char":
        return json.dumps(v)
    if f.ctype in spec.structs:
        inner = indent + "    "
        if f.count is None:
            return _c_struct(spec, f.ctype, v, inner)
        parts = [f"{inner}[{k}] = {_c_struct(spec, f.ctype, x, inner)}" for k, x in enumerate(v)]
        return "{\n" + ",\n".join(parts) + f",\n{indent}}}"
    if f.count is not None:
        return "{" + ", ".join(_c_int(f.ctype, x) for x in v) + "}"
    return _c_int(f.ctype, v)


def _c_struct(spec: TableSpec, sname: str, value: dict, indent: str) -> str:
    inner = indent + "    "
    lines = [f"{inner}.{f.name} = {_c_value(spec, sname, f, value[f.name], inner)},"
             for f in spec.structs[sname]]
    return "{\n" + "\n".join(lines) + f"\n{indent}}}"


def _c_layout(spec: TableSpec, table: dict) -> str:
    """The initializer of the whole table, one designated member per line
    group, in TBL_LAYOUT order; [NT][NG] rows one tendon per line."""
    ind = "    "
    parts = []
    for f, v in _layout_items(table, spec):
        if not f.dims:
            parts.append(f"{ind}.{f.name} = {_c_struct(spec, f.ctype, v, ind)},")
        elif len(f.dims) == 2:
            rows = [f"{ind * 2}{{{', '.join(_c_int(f.ctype, x) for x in row)}}}, /* tendon {i} */"
                    for i, row in enumerate(v)]
            parts.append(f"{ind}.{f.name} = {{\n" + "\n".join(rows) + f"\n{ind}}},")
        else:
            fake = CField(f.ctype, f.name, len(v))
            parts.append(f"{ind}.{f.name} = {_c_value(spec, 'tbl_table_t', fake, v, ind)},")
    return "{\n" + "\n".join(parts) + "\n}"


def render_c(table: dict, spec: TableSpec, robot: Robot,
             learned: LearnedApplied | None = None) -> str:
    """The generated C source defining tbl_table_<robot> (with learned
    targets: tbl_table_<robot>_learned)."""
    src = _relpath(robot.path)
    var = f"tbl_table_{robot.name}" if learned is None else f"tbl_table_{learned.name}"
    counts = f"{table['n_tendons']}, {table['n_sensors']}, {table['n_grid']}"
    head = f"/* generated by hallhome tables, do not edit: {src} */\n"
    if learned is not None:
        head = (f"/* generated by hallhome tables, do not edit: {src}\n"
                f" * learned targets from {', '.join(f.source for f in learned.files)}\n"
                f" * over the model table 0x{learned.model_table_id:08X}; learned grid points "
                f"(tendon: mN): {learned.summary()} */\n")
    return (head +
            f"#include \"table/table.h\"\n\n"
            f"/* {table['n_tendons']} tendons, {table['n_sensors']} sensors, {table['n_grid']} "
            f"grid points: {table['size']} bytes */\n"
            f"TBL_LAYOUT({counts});\n"
            f"TBL_LAYOUT_CHECK({counts});\n\n"
            f"extern const tbl_table_t {var} TBL_FLASH;\n\n"
            f"const tbl_table_t {var} TBL_FLASH = {_c_layout(spec, table)};\n")


def _relpath(p: Path) -> str:
    try:
        return p.resolve().relative_to(PROJECT_ROOT).as_posix()
    except ValueError:
        return p.name


def _r(x, nd):
    """Round for the JSON twin; -0.0 becomes 0.0 so output is stable."""
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_r(y, nd) for y in x]
    v = round(float(x), nd)
    return 0.0 if v == 0 else v


def _slope(x, y, at: float) -> float:
    """dy/dx of sampled data at ``at`` (central differences on the grid)."""
    return float(np.interp(at, x, np.gradient(np.asarray(y), np.asarray(x))))


def render_json(res: RobotResult, table: dict, spec: TableSpec,
                learned: LearnedApplied | None = None) -> str:
    """The JSON twin (format in docs/tables.md)."""
    robot = res.robot
    grid = list(robot.tension_grid)
    sensor_pos = np.array([s.position for s in robot.sensors])
    tendons = []
    for t, tr in zip(robot.tendons, res.tendons):
        mpos, _ = magnet_poses(robot, np.array([s.tip_position for s in tr.solutions]),
                               np.array([s.tip_rotation for s in tr.solutions]))
        tendons.append({
            "index": t.index,
            "servo_id": t.servo_id,
            "segment": t.segment,
            "selected_sensor": tr.selected,
            "closest_sensor": tr.closest,
            "selection_differs": tr.selected != tr.closest,
            "sensitivity_uT_per_N": _r(tr.sensitivity * 1e6, 3),
            "closest_distance_mm": _r(tr.closest_distance * 1e3, 4),
            "target_uT": _r(tr.delta[:, tr.selected] * 1e6, 3),
            "delta_uT_all_sensors": _r(tr.delta * 1e6, 3),
            "abs_target_uT": _r(np.linalg.norm(tr.field[:, tr.selected], axis=-1) * 1e6, 3),
            "travel_mm": _r(tr.travel * 1e3, 5),
            "geometric_mm": _r(tr.geometric * 1e3, 5),
            "stretch_mm": _r(tr.stretch * 1e3, 5),
            "tip_mm": _r(np.array([s.tip_position for s in tr.solutions]) * 1e3, 4),
            "magnet_mm": _r(mpos * 1e3, 4),
            "distance_to_sensors_mm": _r(np.linalg.norm(mpos[:, None] - sensor_pos[None],
                                                         axis=-1) * 1e3, 4),
            "nm_per_tick": table["tendons"][t.index]["nm_per_tick"],
            # tension resolution at the default tension: sensor noise over the
            # selected sensor's sensitivity, and one encoder tick over the
            # take-up slope dtravel/dT
            "noise_resolution_N": _r(robot.noise / tr.sensitivity[tr.selected], 5),
            "tick_resolution_N": _r(t.metres_per_tick / _slope(grid, tr.travel,
                                                                robot.default_tension), 5),
        })
        if learned is not None:
            h = tendons[-1]
            h["model_target_uT"] = h["target_uT"]
            h["target_uT"] = _r(np.array(target_cuT(table, t.index, spec)) / 100.0, 3)
            h["learned"] = list(learned.mask[t.index])
    doc = {
        "format": "hallhome-table",
        "format_version": spec["TBL_FORMAT_VERSION"],
        "generated_by": "hallhome tables",
        "source": _relpath(robot.path),
        "robot": robot.name,
        "table_id": f"0x{table['table_id']:08X}",
        "table": table,
        "human": {
            "grid_N": _r(grid, 4),
            "default_N": _r(robot.default_tension, 4),
            "noise_uT": _r(robot.noise * 1e6, 3),
            "travel_limit_mm": _r(robot.travel_limit * 1e3, 4),
            "mode": robot.mode,
            "straight_tip_mm": _r(res.straight.tip_position * 1e3, 4),
            "sensors": [{"index": s.index, "position_mm": _r(np.array(s.position) * 1e3, 4),
                         "mux_channel": s.mux_channel, "i2c_address": s.i2c_address,
                         "b_straight_uT": _r(b * 1e6, 3)}
                        for s, b in zip(robot.sensors, res.b_straight)],
            "tendons": tendons,
        },
        "selection_report": [
            {"tendon": k, "selected": tr.selected, "closest": tr.closest,
             "differs": tr.selected != tr.closest} for k, tr in enumerate(res.tendons)],
        "warnings": res.warnings,
    }
    if learned is not None:
        doc["learned"] = {
            "symbol": f"tbl_table_{learned.name}",
            "model_table_id": f"0x{learned.model_table_id:08X}",
            "files": [{"file": f.source, "table_id": f"0x{f.table_id:08X}",
                       "targets": f.count} for f in learned.files],
            "targets": sum(f.count for f in learned.files),
        }
    text = json.dumps(doc, indent=1, ensure_ascii=True)
    # Keep innermost arrays of numbers on one line: the twin stays readable.
    text = re.sub(r"\[\s*([-0-9.eE,\s]+?)\s*\]",
                  lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]", text)
    return text + "\n"


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

