"""Computation of a robot's targets: every tendon swept alone over the
tension grid with the Cosserat model and the field model, the sensor each
tendon's targets use, and the warnings about the result (SI units
throughout; hallhome.tablegen_table turns them into the stored integers).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hallhome.field import field_at_sensors, magnet_poses
from hallhome.model import CosseratModel, Solution
from hallhome.robot import Robot
from hallhome.straight import straight_um_table
from hallhome.tablegen_spec import TableError
from hallhome.usable import firmware_limits, travel_limit

SENSITIVITY_STEP_N = 0.01  # central difference for d|dB|/dT at the default tension
# |dB| must rise up to the top of the grid plus this part of its last interval
RISE_MARGIN = 0.25
MODEL_STEPS = 8  # integration steps per segment (docs/model.md: < 1 um at the tip)


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
    limits = firmware_limits()
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
        limit, source = travel_limit(robot, i, limits)
        for T, tv in zip(robot.tension_grid, tr.travel):
            if tv > limit:
                w.append(f"{name}: expected travel {tv * 1e3:.3f} mm at {T:g} N exceeds {source}: "
                         f"a calibration at {T:g} N or more stops with travel_limit")
                break
    # Saturation and targets lost in the noise are refusals (hallhome.usable).
    return w
