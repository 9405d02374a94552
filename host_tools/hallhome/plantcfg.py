"""Plant configs for the C robot model (sim/plant) from a robot description.

``write_plant_config(robot, path, seed=None, perturb=0.0)`` writes the
line-oriented ``key = value`` file that ``plant_cfg_load()`` parses
(sim/plant/README.md describes every key). The plant is a piecewise constant
curvature model, deliberately different from the host's Cosserat model, so a
closed-loop run with a generated table against this plant carries real model
error.

What the robot TOML does not describe is set from keyword arguments: initial
slack, friction along the tendon path (where a tendon's description has no
``friction_mN``/``friction_mu``; an argument given overrides the TOML),
spool backlash, ambient field, the simple servo's time constant. With ``perturb > 0`` the physical values are
perturbed with a seeded generator the same way ``plant_cfg_perturb()`` does in
C (every stiffness (each segment's EI, and EA with ``compression``), free length, friction, backlash and the magnet moment
times ``1 + perturb * u``, radii and segment lengths ``1 + 0.2 perturb u``,
angles ``+- 5 deg * perturb``, sensor positions ``+- 1 mm * perturb``, slack
``+- 500 um * perturb``; ``u`` uniform in [-1, 1]), so the file describes "the
real robot" while the table describes the nominal one.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hallhome.robot import Robot

MU0 = 4e-7 * math.pi
TBL_NO_MUX = 0xFF
EARTH_FIELD_UT = (18.0, 2.0, -44.0)  # a typical ambient, world frame


class PlantConfigError(ValueError):
    """The robot uses a feature the plant model does not have."""


def _fmt(x: float) -> str:
    return f"{x:.9g}"


def _vec(v) -> str:
    return " ".join(_fmt(float(x)) for x in v)


# The bench's tendon friction where a description says nothing of it: a
# play of 10 mN plus 2 % of the tension (braid through printed disk holes).
FRICTION_MN = 10.0
FRICTION_MU = 0.02


def _given_or(given: float | None, described: float | None, default: float) -> float:
    """An argument given, else the description's value, else the bench's."""
    if given is not None:
        return given
    return default if described is None else described


def plant_lines(robot: Robot, seed: int | None = None, perturb: float = 0.0, *,
                slack_um: float = 1000.0, friction_mN: float | None = None,
                friction_mu: float | None = None,
                backlash_um: float = 30.0, ambient_uT=EARTH_FIELD_UT,
                servo_tau_ms: float = 4.0, compression: bool = True) -> list[str]:
    """The plant config as a list of lines (see ``write_plant_config``)."""
    if perturb < 0.0:
        raise PlantConfigError(f"perturb: expected >= 0, got {perturb}")
    rng = np.random.default_rng(seed)

    def u() -> float:
        return float(rng.uniform(-1.0, 1.0)) if perturb > 0.0 else 0.0

    eis = [s.bending_stiffness for s in robot.segments]
    problems = plant_problems(robot)
    if problems:
        raise PlantConfigError("; ".join(problems))
    m = robot.magnet
    pol = np.asarray(m.rotation, dtype=float) @ np.asarray(m.polarization, dtype=float)
    moment = float(pol[2]) * m.volume / MU0
    # the host's model spreads the backbone and disks along each segment and
    # hangs the magnet at its centre: so does the plant
    seg_mass_g = [s.linear_density * s.length * 1e3 for s in robot.segments]

    lines = [
        f"# plant config written by hallhome from {robot.path.name}",
        f"# seed = {seed}, perturb = {perturb}",
        f"name = {robot.name}",
        "segment_len_mm = " + " ".join(
            _fmt(s.length * 1e3 * (1.0 + 0.2 * perturb * u())) for s in robot.segments),
        f"backbone_ei_Nm2 = {_fmt(eis[0])}",
        "segment_ei_Nm2 = " + " ".join(_fmt(e * (1.0 + perturb * u())) for e in eis),
        f"nm_per_tick = {_fmt(robot.tendons[0].metres_per_tick * 1e9)}",
        f"magnet_moment_Am2 = {_fmt(moment * (1.0 + perturb * u()))}",
        f"magnet_offset_mm = {_fmt(m.offset[2] * 1e3)}",
    ]
    if robot.gravity is not None and any(robot.gravity):
        g = np.asarray(robot.gravity, dtype=float)
        lines += [f"tip_mass_g = {_fmt(m.mass * 1e3)}",
                  "segment_mass_g = " + " ".join(_fmt(x) for x in seg_mass_g),
                  f"gravity_dir = {_vec(g / np.linalg.norm(g))}"]
    else:
        lines += ["tip_mass_g = 0"]
    lines += [
        f"noise_uT = {_fmt(robot.noise * 1e6)}",
        f"servo_tau_ms = {_fmt(servo_tau_ms)}",
        "grid_mN = " + " ".join(str(round(t * 1e3)) for t in robot.tension_grid),
        f"default_mN = {round(robot.default_tension * 1e3)}",
        f"travel_limit_um = {_fmt(robot.travel_limit * 1e6)}",
    ]
    for t in robot.tendons:
        # the plant stretches the free length only: add the path inside the robot
        free = t.free_length + robot.segment_end(t.segment)
        f0_mN = _given_or(friction_mN, None if t.friction_N is None else t.friction_N * 1e3,
                          FRICTION_MN)
        mu = _given_or(friction_mu, t.friction_mu, FRICTION_MU)
        p = f"tendon.{t.index}."
        lines += [
            p + f"angle_deg = {_fmt(math.degrees(t.routing_angle) + 5.0 * perturb * u())}",
            p + f"radius_mm = {_fmt(t.routing_radius * 1e3 * (1.0 + 0.2 * perturb * u()))}",
            p + f"segment = {t.segment}",
            p + f"servo_id = {t.servo_id}",
            p + f"pull_dir = {t.pull_dir}",
            p + f"nm_per_tick = {_fmt(t.metres_per_tick * 1e9)}",
            p + f"ea_N = {_fmt(t.stiffness_ea * (1.0 + perturb * u()))}",
            p + f"free_len_mm = {_fmt(free * 1e3 * (1.0 + perturb * u()))}",
            p + f"slack_um = {_fmt(slack_um + 500.0 * perturb * u())}",
            p + f"friction_mN = {_fmt(f0_mN * (1.0 + perturb * u()))}",
            p + f"friction_mu = {_fmt(mu * (1.0 + perturb * u()))}",
            p + f"backlash_um = {_fmt(backlash_um * (1.0 + perturb * u()))}",
        ]
    for s in robot.sensors:
        p = f"sensor.{s.index}."
        pos = [x * 1e3 + perturb * u() for x in s.position]
        r = np.asarray(s.rotation, dtype=float)
        lines += [
            p + f"pos_mm = {_vec(pos)}",
            p + f"rot = {_vec(r.reshape(9))}",
            p + f"ambient_uT = {_vec(ambient_uT)}",
            p + f"mux = {TBL_NO_MUX if s.mux_channel is None else s.mux_channel}",
            p + f"addr = {s.i2c_address:#04x}",
        ]
    if compression:
        # drawn last, so the draws above stay what they were without this key
        ei_at = next(k for k, ln in enumerate(lines) if ln.startswith("segment_ei_Nm2")) + 1
        lines.insert(ei_at, "segment_ea_N = " + " ".join(
            _fmt(s.axial_stiffness * (1.0 + perturb * u())) for s in robot.segments))
    return lines


def plant_problems(robot: Robot) -> list[str]:
    """What the plant cannot model in ``robot``, each naming the TOML key
    (1-based indices as in the file): more than 4 segments, helical routing
    (the plant routes every tendon straight along the backbone), a magnet off
    the tip axis or magnetised across it. Empty when the plant can run it."""
    f = robot.path.name
    out = []
    if len(robot.segments) > 4:
        out.append(f"{f}: segments: the bench plant has at most 4 segments, got "
                   f"{len(robot.segments)}")
    for t in robot.tendons:
        if t.twist != 0.0:
            out.append(f"{f}: tendons[{t.index + 1}].twist_deg_per_mm: the bench plant supports "
                       f"straight routing only, got {math.degrees(t.twist) * 1e-3:g}")
    m = robot.magnet
    pol = np.asarray(m.rotation, dtype=float) @ np.asarray(m.polarization, dtype=float)
    if abs(pol[0]) > 1e-9 or abs(pol[1]) > 1e-9:
        out.append(f"{f}: magnet.polarization_T: the bench plant's dipole points along the tip "
                   f"axis, got {list(m.polarization)} (rotation_deg applied: "
                   f"{[round(float(x), 6) for x in pol]})")
    if abs(m.offset[0]) > 1e-12 or abs(m.offset[1]) > 1e-12:
        out.append(f"{f}: magnet.offset_mm: the bench plant's dipole sits on the tip axis, got "
                   f"{[x * 1e3 for x in m.offset]}")
    return out


def write_plant_config(robot: Robot, path: str | Path, seed: int | None = None,
                       perturb: float = 0.0, **kwargs) -> Path:
    """Write the plant config of ``robot`` to ``path`` and return the path.

    ``seed`` and ``perturb`` (a fraction, 0 = the nominal robot) perturb the
    physical parameters reproducibly; other keyword arguments
    (``slack_um``, ``friction_mN``, ``friction_mu``, ``backlash_um``,
    ``ambient_uT``, ``servo_tau_ms``) set what the robot TOML does not
    describe; ``compression`` (default on) writes the backbone's axial
    stiffness (``segment_ea_N``): the plant compresses the backbone under
    the tendons as a real rod does, which decides the tensions of the
    straight pose once every tendon is home (docs/homing.md, "Straight-pose
    homes"); ``compression=False`` leaves it rigid along its axis. Raises
    ``PlantConfigError`` for robots the plant cannot model
    (``plant_problems``).
    """
    path = Path(path)
    path.write_text("\n".join(plant_lines(robot, seed, perturb, **kwargs)) + "\n",
                    encoding="ascii")
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m hallhome.plantcfg ROBOT.toml OUT.cfg``: the nominal plant
    config `make sim` runs. Exits 2 with every problem named when the robot
    is invalid or the plant cannot model it."""
    import sys

    from hallhome.robot import RobotError, load_robot

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python -m hallhome.plantcfg ROBOT.toml OUT.cfg", file=sys.stderr)
        return 2
    try:
        robot = load_robot(args[0])
    except RobotError as exc:
        print(f"invalid robot description:\n{exc}", file=sys.stderr)
        return 2
    problems = plant_problems(robot)
    if problems:
        print(f"{robot.name} cannot run on the virtual bench: its plant model (sim/plant) "
              f"supports straight tendon routing and an axial magnet on the tip axis only:",
              file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 2
    write_plant_config(robot, args[1])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
