"""The integer table: a computed robot in the stored units and types of
lib/table/table.h, checked against the header, and its bytes exactly as
the AVR holds them (the table_id CRC-32 covers those).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from hallhome.tablegen_compute import RobotResult, _tendon_name
from hallhome.tablegen_spec import _CTYPES, CField, TableError, TableSpec, parse_table_header
from hallhome.usable import firmware_limits, travel_limit

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
    limits = firmware_limits()
    for i, tr in enumerate(res.tendons):
        t_def = float(np.interp(robot.default_tension, robot.tension_grid, tr.travel))
        limit, source = travel_limit(robot, i, limits)
        if t_def > limit:
            raise TableError(f"{robot.path.name}: {_tendon_name(robot, i)}: expected travel "
                             f"{t_def * 1e3:.3f} mm at the default tension exceeds {source}")
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
