"""Can the firmware use this robot? The design checks behind `hallhome tables`
(which refuses a design that fails one, unless ``--force``) and `hallhome
check` (the checks that need no model).

Every refusal names the file, the key and the limit, e.g. ``big.toml:
sensors: 5 sensors, the firmware supports at most 4 (HOM_MAX_SENSORS in
lib/homing/homing.h)``. The firmware's limits are read from its C declarations
(``firmware_limits``), never restated here:

- more sensors than a run can use (HOM_MAX_SENSORS, lib/homing/homing.h;
  a table with more boots as ``table=none``) or the table holds
  (TBL_MAX_SENSORS), more tendons than TBL_MAX_TENDONS, a robot name longer
  than TBL_NAME_LEN - 1 characters (lib/table/table.h);
- values implausible for their unit (``Robot.doubts``, e.g. a length in
  metres under a ``_mm`` key);
- with the model's results: a sensor axis beyond the AK09916's full scale at
  the straight pose or any grid pose; a sensor inside the robot or within the
  volume it sweeps during calibration; a target below ``NOISE_FACTOR`` times
  the sensing noise at any grid tension.
"""

from __future__ import annotations

import math
import re
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hallhome.paths import LIB_DIR, PROJECT_ROOT
from hallhome.robot import SENSOR_SATURATION_T, Robot

if TYPE_CHECKING:  # tablegen imports this module
    from hallhome.tablegen import RobotResult

NOISE_FACTOR = 10.0  # a target must exceed this many sigma of sensing noise


class FirmwareLimitError(RuntimeError):
    """A firmware header no longer declares a limit the checks need."""


class UnusableRobot(RuntimeError):
    """The firmware cannot use this design; ``problems`` lists every reason."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


@dataclass(frozen=True)
class Limit:
    value: int
    source: str  # e.g. "APP_MAX_SENSORS in lib/app/app.h"


@dataclass(frozen=True)
class FirmwareLimits:
    sensors: Limit
    tendons: Limit
    name_chars: Limit
    reach_ticks: Limit  # the furthest the firmware pulls a tendon past its engagement


def header_constants(path: Path) -> dict[str, int]:
    """Integer ``#define NAME value`` constants of a C header (comments
    stripped; u/U/l/L suffixes allowed)."""
    text = Path(path).read_text(encoding="utf-8")
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    return {name: int(value, 0) for name, value in
            re.findall(r"#define\s+(\w+)\s+(0[xX][0-9A-Fa-f]+|\d+)[uUlL]*\s*$", text, flags=re.M)}


def firmware_limits(lib_dir: Path = LIB_DIR) -> FirmwareLimits:
    """The limits the firmware built from ``lib_dir`` puts on a robot."""
    headers = {"table": lib_dir / "table" / "table.h", "homing": lib_dir / "homing" / "homing.h"}
    consts: dict[str, tuple[int, str]] = {}
    for h in headers.values():
        try:
            rel = h.relative_to(PROJECT_ROOT).as_posix()
        except ValueError:
            rel = str(h)
        for name, v in header_constants(h).items():
            consts[name] = (v, rel)

    def get(name: str) -> Limit:
        if name not in consts:
            raise FirmwareLimitError(f"{name} is not defined in {', '.join(map(str, headers.values()))}")
        v, where = consts[name]
        return Limit(v, f"{name} in {where}")

    sensors = min(get("HOM_MAX_SENSORS"), get("TBL_MAX_SENSORS"), key=lambda lim: lim.value)
    name = get("TBL_NAME_LEN")
    return FirmwareLimits(sensors=sensors, tendons=get("TBL_MAX_TENDONS"),
                          name_chars=Limit(name.value - 1, f"{name.source}, with the NUL"),
                          reach_ticks=get("HOM_RELEASE_REACH_TICKS"))


def travel_limit(robot: Robot, i: int, limits: FirmwareLimits) -> tuple[float, str]:
    """Tendon i's travel limit past engagement as the firmware applies it, m,
    and where it comes from: the description's ``travel_limit_mm``, or less,
    the travel the servo unwinds within the release bound at its top speed
    (HOM_RELEASE_REACH_TICKS; docs/app.md, release)."""
    reach = limits.reach_ticks.value * robot.tendons[i].metres_per_tick
    if reach < robot.travel_limit:
        return reach, (f"{reach * 1e3:.3f} mm, the travel the servo unwinds within the release "
                       f"bound ({limits.reach_ticks.source}), below travel_limit_mm = "
                       f"{robot.travel_limit * 1e3:.3f}")
    return robot.travel_limit, f"travel_limit_mm = {robot.travel_limit * 1e3:.3f}"


def tendon_key(robot: Robot, i: int) -> str:
    """The TOML key of tendon i (0-based) and the firmware's name for it."""
    t = robot.tendons[i]
    return f"tendons[{i + 1}] (tendon {i}, servo {t.servo_id})"


def robot_refusals(robot: Robot, limits: FirmwareLimits) -> list[str]:
    """The refusals that need no model: unit doubts, counts, the name."""
    f = robot.path.name
    out = list(robot.doubts)
    if len(robot.name) > limits.name_chars.value:
        out.append(f"{f}: file name: robot name {robot.name!r} has {len(robot.name)} characters, "
                   f"the firmware holds at most {limits.name_chars.value} "
                   f"({limits.name_chars.source})")
    for what, n, lim in (("sensors", len(robot.sensors), limits.sensors),
                         ("tendons", len(robot.tendons), limits.tendons)):
        if n > lim.value:
            out.append(f"{f}: {what}: {n} {what}, the firmware supports at most {lim.value} "
                       f"({lim.source})")
    return out


def robot_radius(robot: Robot) -> float:
    """The robot's radius around its backbone, m: the disks reach at least
    to the largest tendon routing radius."""
    return max(t.routing_radius for t in robot.tendons)


def magnet_radius(robot: Robot) -> float:
    """Radius of the sphere around the magnet's centre that holds it, m."""
    m = robot.magnet
    if m.shape == "cylinder":
        return math.hypot(m.dimensions[0] / 2.0, m.dimensions[1] / 2.0)
    if m.shape == "cuboid":
        return float(np.linalg.norm(m.dimensions)) / 2.0
    return m.dimensions[0] / 2.0


def _polyline_distance(points: np.ndarray, p: np.ndarray) -> float:
    """Shortest distance from p to the polyline through ``points`` (n, 3)."""
    a, b = points[:-1], points[1:]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab),
                                                                1e-30), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))


def _poses(res: RobotResult):
    """(what, tension or None, Solution) for the straight pose and every grid pose."""
    yield "the straight pose", None, res.straight
    for i, tr in enumerate(res.tendons):
        for T, sol in zip(res.robot.tension_grid, tr.solutions):
            yield f"tendon {i} alone at {T:g} N", T, sol


def result_refusals(res: RobotResult) -> list[str]:
    """The refusals that need the model's results: saturation, sensors in the
    robot's way, targets lost in the noise."""
    from hallhome.field import magnet_poses

    robot = res.robot
    f = robot.path.name
    out = []
    # saturation: the worst axis of each sensor over every pose
    poses = [("the straight pose", None, res.b_straight[None])]
    poses += [(f"tendon {i} alone", robot.tension_grid, tr.field)
              for i, tr in enumerate(res.tendons)]
    for s in range(len(robot.sensors)):
        worst = max(((float(np.abs(B[k, s]).max()), what, None if grid is None else grid[k])
                     for what, grid, B in poses for k in range(B.shape[0])), key=lambda w: w[0])
        if worst[0] > SENSOR_SATURATION_T:
            at = "" if worst[2] is None else f" at {worst[2]:g} N"
            out.append(f"{f}: sensors[{s + 1}].position_mm: the sensor saturates: "
                       f"{worst[0] * 1e6:.0f} uT on one axis for {worst[1]}{at}, above the "
                       f"AK09916's {SENSOR_SATURATION_T * 1e6:.0f} uT full scale; move it "
                       f"further from the magnet")
    # clearance: the backbone thickened by the robot's radius, and the magnet
    r_robot, r_mag = robot_radius(robot), magnet_radius(robot)
    for s, sensor in enumerate(robot.sensors):
        p = np.asarray(sensor.position)
        for what, T, sol in _poses(res):
            d_bb = _polyline_distance(sol.positions, p)
            mpos, _ = magnet_poses(robot, sol.positions[-1], sol.rotations[-1])
            d_mag = float(np.linalg.norm(mpos[0] - p))
            hit = None
            if d_bb < r_robot:
                hit = (f"{d_bb * 1e3:.1f} mm from the backbone, inside the robot's radius of "
                       f"{r_robot * 1e3:.1f} mm (largest routing_radius_mm)")
            elif d_mag < r_mag:
                hit = (f"{d_mag * 1e3:.1f} mm from the magnet's centre, inside the magnet "
                       f"({r_mag * 1e3:.1f} mm)")
            if hit is not None:
                where = ("inside the robot in the straight pose" if T is None else
                         f"within the robot's bending envelope ({what})")
                out.append(f"{f}: sensors[{s + 1}].position_mm: the sensor is {where}: {hit}")
                break
    # signal: every grid target above NOISE_FACTOR sigma of the sensing noise
    floor = NOISE_FACTOR * robot.noise
    for i, tr in enumerate(res.tendons):
        d = tr.delta[:, tr.selected]
        low = [k for k in range(len(d)) if d[k] < floor]
        if low:
            k = low[0]
            out.append(f"{f}: {tendon_key(robot, i)}: target {d[k] * 1e6:.2f} uT at "
                       f"{robot.tension_grid[k]:g} N on sensor {tr.selected} is below "
                       f"{NOISE_FACTOR:g} x the sensing noise ({floor * 1e6:.2f} uT, "
                       f"sensing.noise_uT = {robot.noise * 1e6:g}); {len(low)} of {len(d)} grid "
                       f"tensions are: move the sensors closer or raise "
                       f"calibration.tension_grid_N")
    return out


def check_limits(robot: Robot, res: RobotResult | None, limits: FirmwareLimits) -> list[str]:
    """Every refusal of ``robot`` (and of its model results when given)."""
    out = robot_refusals(robot, limits)
    if res is not None:
        out += result_refusals(res)
    return out


# --- reporting ------------------------------------------------------------------------

_TENDON_PREFIX = re.compile(r"^tendon (\d+) \(servo \d+, segment \d+\): ")


def summarise(messages: list[str], shown: int = 1) -> list[str]:
    """Group messages that differ only in their numbers: one line per kind,
    with the count, the tendons concerned and ``shown`` example(s)."""
    groups: OrderedDict[str, list[tuple[str | None, str]]] = OrderedDict()
    for m in messages:
        mt = _TENDON_PREFIX.match(m)
        tendon, body = (mt.group(1), m[mt.end():]) if mt else (None, m)
        key = re.sub(r"[-+]?\d+(\.\d+)?([eE][-+]?\d+)?", "#", body)
        groups.setdefault(key, []).append((tendon, m))
    out = []
    for items in groups.values():
        if len(items) == 1:
            out.append(items[0][1])
            continue
        tendons = sorted({int(t) for t, _ in items if t is not None})
        who = f" (tendons {', '.join(map(str, tendons))})" if tendons else ""
        out.append(f"{len(items)} x{who}, e.g. " + "; ".join(m for _, m in items[:shown]))
    return out


def tendon_summary(res: RobotResult) -> list[str]:
    """Per tendon: the selected sensor, the target at the default tension and
    its signal-to-noise ratio (target over the 1-sigma sensing noise)."""
    robot = res.robot
    td = robot.default_tension
    lines = [f"  tendon  servo  sensor  target at {td:g} N  SNR"]
    for i, tr in enumerate(res.tendons):
        target = float(np.interp(td, robot.tension_grid, tr.delta[:, tr.selected]))
        lines.append(f"  {i:6d}  {robot.tendons[i].servo_id:5d}  {tr.selected:6d}  "
                     f"{target * 1e6:10.1f} uT  {target / robot.noise:5.0f}")
    return lines
