"""Survey records for `hallhome identify` (docs/identify.md): reading them and
making synthetic ones.

A survey file is JSON (``"format": "hallhome-survey"``), as the virtual bench
writes it (``hh_bench --survey``) and as the firmware will stream it: what
the board sees, nothing more. Per tendon, pulled alone with the others
slack, a baseline field and a list of steps ``[ticks, [[bx, by, bz] per
sensor]]``: the servo's encoder position and each sensor's reading in its
own frame, in cuT (10 nT; the firmware's unit). Optional weight records:
``{"tendon", "mass_g", "baseline_cuT", "field_cuT"}`` with every servo slack.
An optional ``"truth"`` object (the bench plant's true parameters) is kept
for evaluation and never used by the fit.

Here the records become SI: take-up past the pull's first step (m, from the
robot description's spool and pull direction) and the field change from the
baseline (T), so the earth's field and nearby iron cancel as they do in the
firmware's delta mode.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from hallhome.field import field_at_sensors
from hallhome.model import CosseratModel
from hallhome.robot import Robot

CUT = 1e-8  # one cuT in tesla
G = 9.80665  # standard gravity, m/s^2: the mass of a weight record to newtons


class IdentifyError(ValueError):
    """A survey or fit refused; the message gives the reason."""


@dataclass(frozen=True)
class Pull:
    """One tendon pulled alone: ``take_up`` (n,) m past the first step,
    ``delta`` (n, n_sensors, 3) T, the field change from the baseline in
    each sensor's frame."""

    tendon: int
    take_up: np.ndarray
    delta: np.ndarray


@dataclass(frozen=True)
class WeightRecord:
    """A known mass (kg) hung on ``tendon`` with every servo slack; ``delta``
    (n_sensors, 3) T, the field change it caused."""

    tendon: int
    mass: float
    delta: np.ndarray

    @property
    def force(self) -> float:
        """m g, N."""
        return self.mass * G


@dataclass(frozen=True)
class HeldPull:
    """``tendon`` pulled from slack again while tendon ``hold`` stands
    ``hold_take_up`` (m) past the first step of its own pull: ``shift`` (m of
    the tendon's take-up), how far the bend moved its engagement from its
    pull alone (both found by ``engagement_ticks``); ``hold_delta``
    (n_sensors, 3) T, the field of the bend against the baseline of the hold
    tendon's pull."""

    tendon: int
    hold: int
    hold_take_up: float
    shift: float
    hold_delta: np.ndarray


@dataclass(frozen=True)
class Survey:
    pulls: tuple[Pull, ...]
    weights: tuple[WeightRecord, ...]
    truth: dict | None
    source: str
    meta: dict
    held: tuple[HeldPull, ...] = ()


# The engagement's kink: the field change is fitted as zero before it and a
# quadratic in the take-up past it, over the steps up to KINK_SPAN_TICKS past
# the first step beyond 10 sigma of the noise; the kink is searched within
# KINK_SEARCH_TICKS of that step, to KINK_RES_TICKS.
KINK_SPAN_TICKS = 40.0
KINK_SEARCH_TICKS = 12.0
KINK_RES_TICKS = 0.05
KINK_SLACK_STEPS = 4  # steps before the field leaves the noise: the pull began slack
SCAN_SLACK_STEPS = 2  # the same of a board's scan (2-tick steps, its first point slack)

# A held pull needs a hold that bends the robot across the pulled tendon
# (|sin| of the angle between their routing angles at least HELD_MIN_SIN):
# a hold in its own plane leaves the robot no freedom as it engages, the
# field barely changes and the kink is lost (bench robots with four tendons
# at 90 degrees: targets 4 times worse). And along it (|cos| at least
# HELD_MIN_COS): the shift is the radius times the bend along the tendon.
HELD_MIN_SIN = 0.5
HELD_MIN_COS = 0.25


def held_pairs(robot: Robot) -> list[tuple[int, int]]:
    """The held pulls a survey runs, ``(tendon, hold)``: every tendon with a
    tendon of its segment that may hold it (HELD_MIN_SIN), the one along it
    most (the largest |cos|, above HELD_MIN_COS; the first of equals), as
    ``hh_bench --survey-held`` chooses."""
    pairs = []
    for i, t in enumerate(robot.tendons):
        best, hold = HELD_MIN_COS, None
        for m, a in enumerate(robot.tendons):
            d = a.routing_angle - t.routing_angle
            if m != i and a.segment == t.segment and abs(math.sin(d)) >= HELD_MIN_SIN \
                    and abs(math.cos(d)) > best + 1e-9:
                best, hold = abs(math.cos(d)), m
        if hold is not None:
            pairs.append((i, hold))
    return pairs


def engagement_ticks(ticks: np.ndarray, delta: np.ndarray, noise: float, *,
                     offset: bool = False, slack_steps: int = KINK_SLACK_STEPS) -> float | None:
    """Where a pull's field starts to change, in its encoder ticks (signed as
    the ticks go): the least-squares kink of a hinge, zero before it and a
    quadratic after, fitted to every sensor axis at once. None when the field
    never leaves 10 sigma of ``noise`` (T); IdentifyError when it leaves it
    within ``slack_steps`` steps (no slack seen before the kink). With
    ``offset`` the hinge has a constant of its own (a baseline taken from a
    few steps, the board's scans: ``op_survey.scan_of``)."""
    t = np.abs(ticks - ticks[0])
    y = delta.reshape(len(t), -1)
    above = np.nonzero(np.max(np.linalg.norm(delta, axis=-1), axis=-1) > 10 * noise)[0]
    if not len(above):
        return None
    if above[0] < slack_steps:
        raise IdentifyError("the field changes from its first steps: the pull started "
                            "engaged (start it further back)")
    guess = t[above[0] - 1]
    sel = t <= guess + KINK_SPAN_TICKS
    ts, ys = t[sel], y[sel]

    def sse(e):
        x = np.clip(ts - e, 0.0, None)
        a = np.stack([np.ones_like(x), x, x * x] if offset else [x, x * x], 1)
        coef = np.linalg.lstsq(a, ys, rcond=None)[0]
        return float(np.sum((ys - a @ coef) ** 2))

    grid = np.arange(guess - KINK_SEARCH_TICKS, guess + KINK_SEARCH_TICKS, KINK_RES_TICKS)
    e = float(grid[int(np.argmin([sse(g) for g in grid]))])
    return float(ticks[0] + np.sign(ticks[-1] - ticks[0]) * e)


def _fields(value, n_sensors: int, where: str) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.shape != (n_sensors, 3) or not np.all(np.isfinite(a)):
        raise IdentifyError(f"{where}: expected {n_sensors} sensors x 3 finite values")
    return a


def _base_name(name: str) -> str:
    """A robot's name without the ``_id`` of an identified description."""
    return name[:-3] if name.endswith("_id") else name


def survey_from_dict(d: dict, robot: Robot, any_robot: bool = False) -> Survey:
    """Validates a survey object against ``robot`` and converts it to SI.
    Raises IdentifyError naming the first problem. A survey that names
    another robot (``"robot"``, the board's table name; ``<name>_id`` counts
    as ``<name>``) is refused unless ``any_robot``."""
    if not isinstance(d, dict) or d.get("format") != "hallhome-survey":
        raise IdentifyError('not a survey: expected "format": "hallhome-survey"')
    if d.get("field_unit", "cuT") != "cuT":
        raise IdentifyError(f"field_unit {d.get('field_unit')!r}: expected cuT")
    name = d.get("robot")
    if (not any_robot and isinstance(name, str) and name
            and _base_name(name) != _base_name(robot.name)):
        raise IdentifyError(f"the survey is of robot {name!r}, the description is "
                            f"{robot.name!r}: a survey from another robot? (fit it anyway "
                            "with --any-robot)")
    ns, nt = len(robot.sensors), len(robot.tendons)
    pulls, seen, first, parsed = [], set(), {}, {}
    for n, p in enumerate(d.get("pulls") or []):
        where = f"pulls[{n}]"
        i = p.get("tendon") if isinstance(p, dict) else None
        if not isinstance(i, int) or not 0 <= i < nt or i in seen:
            raise IdentifyError(f"{where}: tendon must be a new index 0..{nt - 1}")
        seen.add(i)
        ticks, delta, base = _pull_arrays(p, ns, where)
        parsed[i] = (ticks, delta, base)  # for the held pulls
        t = robot.tendons[i]
        take_up = (ticks - ticks[0]) * t.pull_dir * t.metres_per_tick
        if np.any(np.diff(take_up) <= 0):
            raise IdentifyError(f"{where}: the steps do not pull (take-up must grow; pull_dir "
                                f"{t.pull_dir:+d} in the robot description)")
        if np.max(np.linalg.norm(delta[-1], axis=-1)) < 20 * robot.noise:
            raise IdentifyError(f"{where}: tendon {i} never changed the field beyond the noise "
                                "(magnet missing, tendon not engaged, wrong robot?)")
        pulls.append(Pull(i, take_up, delta))
        first[i] = float(ticks[0])
    if not pulls:
        raise IdentifyError("no pulls in the survey")
    weights = []
    for n, w in enumerate(d.get("weights") or []):
        where = f"weights[{n}]"
        i, m = w.get("tendon"), w.get("mass_g")
        if not isinstance(i, int) or not 0 <= i < nt:
            raise IdentifyError(f"{where}: tendon must be 0..{nt - 1}")
        if not isinstance(m, (int, float)) or not 0 < m <= 10000:
            raise IdentifyError(f"{where}: mass_g must be in (0, 10000]")
        delta = (_fields(w.get("field_cuT"), ns, where) -
                 _fields(w.get("baseline_cuT"), ns, where)) * CUT
        weights.append(WeightRecord(i, m * 1e-3, delta))
    meta = {k: d[k] for k in ("robot", "seed", "perturb", "source") if k in d}
    meta["first_ticks"] = first
    held = tuple(_held(h, n, parsed, robot) for n, h in enumerate(d.get("held") or []))
    return Survey(tuple(pulls), tuple(weights), d.get("truth"), d.get("source", "?"), meta,
                  held)


def _pull_arrays(p: dict, ns: int, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ticks (n,), field change from the baseline (n, ns, 3) T and the
    baseline (ns, 3) cuT of a pull record (a pull alone or a held pull)."""
    b = p.get("baseline_cuT")
    if isinstance(b, list) and len(b) != ns:
        raise IdentifyError(f"{where}: {len(b)} sensors, the description has {ns}: a "
                            "survey from another robot?")
    base = _fields(b, ns, f"{where}.baseline_cuT")
    steps = p.get("steps") or []
    if len(steps) < 8:
        raise IdentifyError(f"{where}: {len(steps)} steps, at least 8 needed")
    ticks = np.array([s[0] for s in steps], dtype=float)
    field = np.array([_fields(s[1], ns, f"{where}.steps[{k}]") for k, s in enumerate(steps)])
    return ticks, (field - base[None]) * CUT, base


def _held(h: dict, n: int, parsed: dict, robot: Robot) -> HeldPull:
    """A held pull record (see HeldPull), checked against the pulls alone of
    its tendon and of the held one (``parsed``: _pull_arrays() of each pull
    alone, by tendon)."""
    where = f"held[{n}]"
    ns, nt = len(robot.sensors), len(robot.tendons)
    i, a = (h.get("tendon"), h.get("hold_tendon")) if isinstance(h, dict) else (None, None)
    if not isinstance(i, int) or not isinstance(a, int) or not (0 <= i < nt and 0 <= a < nt) \
            or i == a:
        raise IdentifyError(f"{where}: tendon and hold_tendon must be two indices 0..{nt - 1}")
    if i not in parsed or a not in parsed:
        raise IdentifyError(f"{where}: tendons {i} and {a} need their pulls alone too")
    if not isinstance(h.get("hold_ticks"), (int, float)):
        raise IdentifyError(f"{where}: hold_ticks must be a number")
    t, ta = robot.tendons[i], robot.tendons[a]
    da = ta.routing_angle - t.routing_angle
    if ta.segment != t.segment or abs(math.sin(da)) < HELD_MIN_SIN \
            or abs(math.cos(da)) < HELD_MIN_COS:
        raise IdentifyError(f"{where}: tendon {a} cannot hold tendon {i}'s pull: it must be of "
                            f"its segment, {math.degrees(math.asin(HELD_MIN_SIN)):.0f}-"
                            f"{math.degrees(math.acos(HELD_MIN_COS)):.0f} degrees from it or "
                            "as far from its opposite (docs/identify.md)")
    ticks, delta, base = _pull_arrays(h, ns, where)
    fticks, fdelta, _ = parsed[i]
    kink = {}
    if "free_steps" in h:
        # the board's held run scans the engagement alone too, in the same
        # steps as the held one: the shift between two crossings made alike,
        # each scan's baseline its first point (docs/identify.md)
        fticks, fdelta, _ = _pull_arrays({"baseline_cuT": h.get("free_baseline_cuT"),
                                          "steps": h["free_steps"]}, ns, f"{where}.free")
        kink = {"offset": True, "slack_steps": SCAN_SLACK_STEPS}
    aticks, _, abase = parsed[a]
    try:
        e_held = engagement_ticks(ticks, delta, robot.noise, **kink)
        e_free = engagement_ticks(fticks, fdelta, robot.noise, **kink)
    except IdentifyError as exc:
        raise IdentifyError(f"{where}: tendon {i}: {exc}") from None
    if e_held is None or e_free is None:
        raise IdentifyError(f"{where}: tendon {i} never changed the field beyond the noise")
    hold_take = (float(h["hold_ticks"]) - aticks[0]) * ta.pull_dir * ta.metres_per_tick
    shift = (e_held - e_free) * t.pull_dir * t.metres_per_tick
    return HeldPull(i, a, hold_take, shift, (base - abase) * CUT)


def load_survey(path: str | Path, robot: Robot, any_robot: bool = False) -> Survey:
    """Reads a survey JSON file (see the module docstring and
    ``survey_from_dict``)."""
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise IdentifyError(f"{path}: {exc}") from None
    try:
        return survey_from_dict(d, robot, any_robot)
    except IdentifyError as exc:
        raise IdentifyError(f"{path}: {exc}") from None


def synthetic_survey(robot: Robot, *, seed: int = 1, noise_uT: float = 0.3,
                     top_tension: float = 1.5, step_ticks: int = 4, slack_mm: float = 0.5,
                     weights: tuple[tuple[int, float], ...] = (),
                     ambient_uT=(18.0, 2.0, -44.0)) -> dict:
    """A survey of ``robot`` made by the host's Cosserat model, in the file
    format (the pulls without gravity, as the fit models them; the weights
    with it): each tendon starts ``slack_mm`` (varied by up to 50 %
    with the seed) before engagement and is pulled to ``top_tension``;
    readings carry Gaussian noise ``noise_uT`` per axis, an ambient field and
    the 0.15 uT quantisation. ``weights``: (tendon, grams) records."""
    rng = np.random.default_rng(seed)
    model = CosseratModel(robot, steps_per_segment=8, gravity=False)
    nt = len(robot.tendons)
    straight = model.solve(np.zeros(nt))
    b0 = field_at_sensors(robot, straight.tip_position, straight.tip_rotation)[0]
    amb = np.array([np.array(s.rotation).T @ np.array(ambient_uT) * 1e-6 for s in robot.sensors])

    def reading(b):
        v = (b + amb) / 1e-6 + rng.normal(0.0, noise_uT, b.shape)
        return (np.round(v / 0.15) * 15).tolist()  # cuT, whole LSBs

    pulls = []
    for i, t in enumerate(robot.tendons):
        grid = np.linspace(0.0, top_tension * 1.05, 25)
        sols = []
        for T in grid:
            tau = np.zeros(nt)
            tau[i] = robot.tip_tension(t, T)
            sols.append(model.solve(tau))
        take = np.array([s.take_up[i] for s in sols])
        B = field_at_sensors(robot, np.array([s.tip_position for s in sols]),
                             np.array([s.tip_rotation for s in sols]))
        spline = CubicSpline(take, B, axis=0)
        slack = slack_mm * 1e-3 * (1.0 + 0.5 * rng.uniform(-1, 1))
        mpt = t.metres_per_tick
        start = int(rng.integers(-5000, 5000))
        n_steps = int(math.ceil((slack + take[-1]) / (step_ticks * mpt)))
        steps = []
        for k in range(n_steps + 1):
            x = k * step_ticks * mpt - slack
            b = b0 if x <= 0 else spline(x)
            steps.append([start + t.pull_dir * k * step_ticks, reading(b)])
        pulls.append({"tendon": i, "baseline_cuT": reading(b0), "steps": steps,
                      "engagement_um": round((slack / mpt) * mpt * 1e6, 3)})
    wrec = []
    heavy = CosseratModel(robot, steps_per_segment=8)  # a hung weight: gravity too
    s0 = heavy.solve(np.zeros(nt))
    w0 = field_at_sensors(robot, s0.tip_position, s0.tip_rotation)[0]
    for i, grams in weights:
        tau = np.zeros(nt)
        tau[i] = robot.tip_tension(robot.tendons[i], grams * 1e-3 * G)
        s = heavy.solve(tau)
        b = field_at_sensors(robot, s.tip_position, s.tip_rotation)[0]
        wrec.append({"tendon": i, "mass_g": grams, "baseline_cuT": reading(w0),
                     "field_cuT": reading(b)})
    return {"format": "hallhome-survey", "version": 1, "source": "synthetic (host model)",
            "robot": robot.name, "seed": seed, "field_unit": "cuT", "step_ticks": step_ticks,
            "pulls": pulls, "weights": wrec}
