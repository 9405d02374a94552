"""Straight-pose homes: where every tendon must be for the robot to stand
straight with every tendon at the target tension at once.

A calibration measures each tendon's *single-tendon home*: the spool position
where that tendon, pulled with every other tendon slack, reaches the target
tension T (the paper's definition). Pulled alone, the tendon bends the robot
and its path inside the robot shortens by d_i(T e_i). When every tendon then
goes to its single-tendon home, the robot straightens, that shortening is
given back and turns into stretch: on paper_2seg at 0.8 N the tendons end at
3.7-5.4 N.

The straight-pose home of tendon i is the spool position where, with every
tendon pulled to T together, its tension is T. Both homes are at the same
tension, so the elastic stretch T (path + free length) / EA is the same in
both (up to T * (difference of path) / EA, below 0.1 um on the reference
robots) and cancels: the difference of the two homes is purely geometric,

    shift_i(T) = d_i(T e_i) - d_i(T 1)                         (1)

where d_i(tau) is the path shortening of tendon i (against the unloaded
straight robot) under the tension vector tau, from the Cosserat rod model
(``CosseratModel.solve(...).displacements``). The straight-pose home is the
measured single-tendon home minus shift_i(T) of take-up: the tendon pays out
shift_i(T) from its single-tendon home. Nothing in (1) depends on the
tendon's axial stiffness EA, which no user knows well.

The two terms are the two corrections of the method the design started
from: d_i(T e_i) is the geometric path shortening of the pose the field
measured at the single-tendon home (the bending, about 37 um per 0.1 N for a
tendon ending at segment 1 of the reference robot, 73 um for segment 2);
d_i(T 1) is what the path changes when all tendons pull at once. On a robot
whose tendons balance (their offsets sum to zero over every segment) the
moments cancel, the backbone stays straight and d_i(T 1) is the backbone's
axial compression under the sum of the tensions (plus the small effect of
gravity): it shortens every path, so the straight home needs *more* take-up
by that much. The Cosserat model has shear and extension, so both terms come
from one model without special cases, and an unbalanced robot (a segment
with one tendon, gravity across) gets the pose of every tendon at T, which
is then not straight: ``tip_deviation_mm`` says by how much.

T in (1) is what bends the robot: the tension at the tendon's end, which the
path's friction leaves of the spool's T (``Robot.tip_tension``; every home
is approached pulling from slack, the single-tendon one and the final move's
alike), so both poses are solved at it.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass

import numpy as np

from hallhome.model import CosseratModel
from hallhome.robot import Robot, RobotError, load_robot

# The table generator's integration grid (tablegen.MODEL_STEPS): the same
# model resolution as the targets the shifts go with.
MODEL_STEPS = 8


@dataclass(frozen=True)
class StraightPose:
    """The model's figures at one tension T, per tendon (SI units unless the
    name says otherwise): ``single_um`` d_i(T e_i), ``all_um`` d_i(T 1),
    ``shift_um`` their difference (1), ``tip_deviation_mm`` the tip's distance
    with every tendon at T from the tip with every tendon slack."""

    tension_N: float
    single_um: np.ndarray
    all_um: np.ndarray
    shift_um: np.ndarray
    tip_deviation_mm: float


def _model(robot: Robot, model: CosseratModel | None) -> CosseratModel:
    return model if model is not None else CosseratModel(robot, steps_per_segment=MODEL_STEPS)


def straight_pose(robot: Robot, tension_N: float,
                  model: CosseratModel | None = None) -> StraightPose:
    """The terms of (1) at one tension (n_tendons + 2 Cosserat solves)."""
    m = _model(robot, model)
    n = len(robot.tendons)
    if not tension_N > 0.0:
        raise ValueError(f"tension: expected > 0 N, got {tension_N!r}")
    slack = m.solve(np.zeros(n))
    tip = robot.tip_tensions(np.full(n, float(tension_N)))
    together = m.solve(tip, base_moment_guess=slack.base_moment)
    single = np.empty(n)
    for i in range(n):
        tau = np.zeros(n)
        tau[i] = tip[i]
        single[i] = m.solve(tau, base_moment_guess=slack.base_moment).displacements[i]
    all_d = together.displacements
    dev = float(np.linalg.norm(together.tip_position - slack.tip_position)) * 1e3
    return StraightPose(float(tension_N), single * 1e6, all_d * 1e6, (single - all_d) * 1e6, dev)


def straight_shift_um(robot: Robot, grid_N, model: CosseratModel | None = None,
                      single_um: np.ndarray | None = None) -> np.ndarray:
    """Per tendon and grid tension, the take-up (um) to pay out from the
    single-tendon home to reach the straight-pose home: float array of shape
    (n_tendons, len(grid_N)), shift_i(T) of (1) (module docstring). Positive
    means the straight-pose home is on the release side of the single one.
    ``single_um``, (n_tendons, len(grid_N)): d_i(T e_i) already solved (the
    table generator's sweep), so that only the poses of every tendon at T
    are solved here."""
    m = _model(robot, model)
    grid = [float(t) for t in np.atleast_1d(grid_N)]
    n = len(robot.tendons)
    out = np.empty((n, len(grid)))
    if single_um is None:
        for g, t in enumerate(grid):
            out[:, g] = straight_pose(robot, t, m).shift_um
        return out
    slack = m.solve(np.zeros(n))
    for g, t in enumerate(grid):
        together = m.solve(robot.tip_tensions(np.full(n, t)), base_moment_guess=slack.base_moment)
        out[:, g] = np.asarray(single_um)[:, g] - together.displacements * 1e6
    return out


INT16_MAX = 32767


def straight_um_table(robot: Robot, grid_N, model: CosseratModel | None = None,
                      single_um: np.ndarray | None = None) -> np.ndarray:
    """``straight_shift_um`` rounded to whole um as the table's signed int16
    ``straight_um`` carries it (int array, same shape); ValueError naming the
    tendon and tension when a shift does not fit."""
    shifts = straight_shift_um(robot, grid_N, model, single_um)
    out = np.rint(shifts).astype(np.int64)
    bad = np.argwhere(np.abs(out) > INT16_MAX)
    if bad.size:
        i, g = (int(x) for x in bad[0])
        raise ValueError(f"{robot.name}: tendon {i} at {float(np.atleast_1d(grid_N)[g]):g} N: "
                         f"straight shift {shifts[i, g]:.0f} um outside int16")
    return out.astype(np.int16)


def straight_compliance(robot: Robot, tension_N: float, model: CosseratModel | None = None,
                        step_N: float = 0.02) -> np.ndarray:
    """A = d(take-up)/d(tension) at the pose of every tendon at T, m/N,
    (n, n): diag((path + free) / EA) plus the path's response dd/dtau
    (central differences of the Cosserat model around T 1). Depends on EA."""
    m = _model(robot, model)
    n = len(robot.tendons)
    base = np.full(n, float(tension_N))
    a = np.empty((n, n))
    for k in range(n):
        up = base.copy()
        dn = base.copy()
        up[k] += step_N
        dn[k] -= step_N
        a[:, k] = (m.solve(up).take_up - m.solve(dn).take_up) / (2.0 * step_N)
    return a


def straight_stiffness_N_per_m(robot: Robot, tension_N: float,
                               model: CosseratModel | None = None,
                               common: bool = False) -> np.ndarray:
    """Tension gained per metre of take-up in the straight pose, per tendon:
    with common=False dT_i/du_i with the other spools held still
    ([A^-1]_ii, A from ``straight_compliance``); with common=True the gain of
    each tendon when every spool takes up the same length (A^-1 1), the mode a
    systematic error of every home excites. The second is stiffer: the
    tendons cancel each other's bending, only stretch and compression
    remain."""
    inv = np.linalg.inv(straight_compliance(robot, tension_N, model))
    return inv.sum(axis=1) if common else np.diag(inv)


def tolerance_ticks(robot: Robot, tension_N: float, tol_N: float = 0.05,
                    model: CosseratModel | None = None, common: bool = False) -> np.ndarray:
    """Per tendon, how many encoder ticks of its own spool move its tension
    in the straight pose by tol_N (the others held; with common=True every
    spool by as many ticks): the encoder floor of a tension tolerance."""
    k = straight_stiffness_N_per_m(robot, tension_N, model, common)
    mpt = np.array([t.metres_per_tick for t in robot.tendons])
    return tol_N / k / mpt


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m hallhome.straight",
        description="Straight-pose shifts of a robot: per tendon, the take-up (um) to pay out "
                    "from its single-tendon home (pulled alone) to its straight-pose home "
                    "(every tendon at the tension together). Method: docs/homing.md, "
                    "'Straight-pose homes'.")
    ap.add_argument("robot", help="robot description (TOML)")
    ap.add_argument("--tension", "-t", type=float, action="append",
                    help="tension in N (repeatable; default: the robot's grid)")
    ap.add_argument("--list", action="store_true",
                    help="print only the shifts at the first tension (default: the robot's "
                         "default tension), comma-separated (the form hh_bench --straight-um "
                         "takes)")
    ap.add_argument("--tolerance", type=float, metavar="N",
                    help="also print the encoder ticks that move a tendon's tension by N "
                         "in the straight pose")
    args = ap.parse_args(argv)
    try:
        robot = load_robot(args.robot)
    except (OSError, RobotError) as e:
        print(f"hallhome.straight: {e}", file=sys.stderr)
        return 2
    grid = args.tension or ([robot.default_tension] if args.list else list(robot.tension_grid))
    if any(not t > 0.0 for t in grid):
        print("hallhome.straight: tensions must be > 0 N", file=sys.stderr)
        return 2
    model = _model(robot, None)
    if args.list:
        print(",".join(f"{v:.1f}" for v in straight_pose(robot, grid[0], model).shift_um))
        return 0
    print(f"{robot.name}: shift (um) from the single-tendon home to the straight-pose home")
    print("T_N      " + " ".join(f"{'t' + str(i):>7}" for i in range(len(robot.tendons)))
          + "   tip_dev_mm")
    for t in grid:
        p = straight_pose(robot, t, model)
        print(f"{t:<8.3f} " + " ".join(f"{v:7.1f}" for v in p.shift_um)
              + f"   {p.tip_deviation_mm:.4f}")
        if args.tolerance:
            tk = tolerance_ticks(robot, t, args.tolerance, model)
            tc = tolerance_ticks(robot, t, args.tolerance, model, common=True)
            print(f"  +-{args.tolerance:g} N, one tendon (ticks):  "
                  + " ".join(f"{v:7.2f}" for v in tk))
            print(f"  +-{args.tolerance:g} N, all together (ticks): "
                  + " ".join(f"{v:7.2f}" for v in tc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
