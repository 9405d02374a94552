"""Identify the robot as built from a survey (docs/identify.md).

The fit adjusts the robot description until the host's model reproduces the
survey: for every tendon pulled alone, the field change at every sensor
against the spool's take-up; for every weight record, the field change a
known force caused. Parameters (each with its nominal value from the TOML
and a prior spread that keeps ill-determined directions near the
description):

- ``magnet_J``: |polarization| of the tip magnet, T (its direction stays
  the TOML's);
- ``length_<j>``: length of segment j, mm;
- ``radius``: routing radius of every tendon (one common factor), mm, and,
  with weight records, ``EA<i>``: each pulled tendon's axial stiffness, N;
  or, when every pulled tendon has a weight record of its own,
  ``radius<i>`` and ``EA<i>``: each tendon's routing radius (mm) and axial
  stiffness. A tendon's take-up per bend is its radius plus its stretch,
  and the survey alone cannot tell one from the other (docs/identify.md,
  "What one weight per segment cannot tell"); its own weight tells how far
  a known force bends the robot through it. Without one, its EA takes up
  its take-up and its radius stays the common one;
- ``angle<i>``: routing angle of each pulled tendon, degrees: the plane it
  bends the robot in;
- ``sensor<k>_<x|y|z>``: sensor k's position, mm (its rotation stays);
- ``engage<i>``: take-up from the pull's first step to the tendon's
  engagement, um (no prior: the slack at the start is unknown);
- ``EI_<j>``: bending stiffness of segment j, mN m^2, only with weight
  records (or ``stiffness=True``); without them it stays nominal;
- ``friction``: the tendons' friction force (``friction_mN`` of every
  tendon), mN, only when a tendon carries weights of two masses
  (``measures_friction``). A hung weight reaches the tendon's end as
  m g (1 - mu) - f0 (``Robot.tip_tension``): one mass gives the stiffness
  with the description's friction folded in, two tell the offset f0 from
  the slope (mu stays the description's: it scales like the stiffness).

The model is the host's constant-curvature model, with gravity's moment in
the pulled tendon's bending plane (``cc_single``), and field model: cheap
enough for finite-difference Jacobians, and within some 15 um of the
Cosserat model the tables use on straight-routed robots. The magnet
field change is compared, so ambient fields cancel. ``scipy.optimize.
least_squares`` minimises the residuals (field / ``sigma_uT``) plus the
priors; the 1-sigma uncertainties come from the Jacobian at the solution,
scaled up by the reduced chi-square when the model does not explain the
data to the noise. A fit that does not converge, lands on a bound or
outside the plausible range of a parameter, or leaves residuals far above
the signal is refused with the reason (``FitResult.refused``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import least_squares

from hallhome.field import field_at_sensors
from hallhome.identify_data import IdentifyError, Survey
from hallhome.model import CosseratModel, ModelError, solve_many
from hallhome.robot import Robot
from hallhome.tablegen import MODEL_STEPS

TENSION_GRID = np.linspace(0.0, 3.0, 16)  # N: the model's sweep per tendon


@dataclass(frozen=True)
class Param:
    """One fitted quantity in display units: nominal value, prior 1-sigma
    (None: no prior), plausible range (the fit is refused outside it)."""

    name: str
    unit: str
    nominal: float
    prior: float | None
    lo: float
    hi: float
    scale: float  # optimiser unit: value = nominal + scale * z


@dataclass
class FitResult:
    params: list[Param]
    values: np.ndarray
    sigmas: np.ndarray
    robot: Robot  # the identified description (SI)
    rms_uT: float
    signal_uT: float  # rms of the measured field changes
    tendon_rms_uT: dict[int, float]
    weight_rms_uT: list[float]
    chi2_red: float
    n_data: int
    converged: bool
    message: str
    refused: str | None
    stiffness: bool
    # per tendon (take-up (n,), measured and modelled field changes (n, n_s, 3), engagement)
    curves: dict = dataclasses.field(default_factory=dict)
    # per held pull: (tendon, held tendon, measured and modelled engagement shift, um)
    held_shifts_um: list = dataclasses.field(default_factory=list)

    def value(self, name: str) -> float:
        return float(self.values[[p.name for p in self.params].index(name)])

    def table(self) -> list[dict]:
        """Fitted against nominal, one row per parameter."""
        rows = []
        for p, v, s in zip(self.params, self.values, self.sigmas):
            constrained = p.prior is None or s < 0.5 * p.prior
            rows.append({"name": p.name, "unit": p.unit, "nominal": p.nominal, "value": float(v),
                         "sigma": float(s), "from_data": bool(constrained)})
        return rows


def weighs_every_tendon(survey: Survey) -> bool:
    """True when every pulled tendon has a weight record of its own: the fit
    then gives each tendon its own routing radius and axial stiffness."""
    return bool(survey.weights) and ({w.tendon for w in survey.weights}
                                     >= {p.tendon for p in survey.pulls})


# A held pull's engagement shift: the 1-sigma of the kink's difference (two
# kinks of about a fifth of a tick, 1.2 um, each on the bench) and of the
# model's path, um.
SHIFT_SIGMA_UM = 2.0


# A tendon's routing angle: prior 1-sigma and plausible range about the
# description's, degrees (a routing hole drilled a millimetre off at a 4.5 mm
# radius turns it by some 13 degrees: beyond that it is another robot).
ANGLE_PRIOR_DEG = 2.0
ANGLE_RANGE_DEG = 10.0


# A tendon's axial stiffness: prior 1-sigma, relative to the description's.
# The fitted EA is effective: it carries the error of the free length (and, on
# a tendon without a weight of its own, of the routing radius) as well.
EA_PRIOR = 0.2


# Two masses on one tendon tell the friction when the heavier is at least
# this many times the lighter (closer masses leave it to the noise).
FRICTION_MASS_RATIO = 1.5


# A fitted friction this far below zero (mN), and beyond 3 sigma, is refused;
# closer to zero it is a frictionless robot seen through the noise.
FRICTION_SLACK_MN = 2.0


def measures_friction(survey: Survey) -> bool:
    """True when some tendon carries weight records of two masses at least
    FRICTION_MASS_RATIO apart: the fit then finds the tendon friction."""
    masses: dict[int, list[float]] = {}
    for w in survey.weights:
        masses.setdefault(w.tendon, []).append(w.mass)
    return any(max(m) >= FRICTION_MASS_RATIO * min(m) for m in masses.values())


def fit_params(robot: Robot, survey: Survey, stiffness: bool | None = None,
               mechanics: bool = True, per_tendon: bool | None = None,
               friction: bool | None = None) -> list[Param]:
    """The parameters ``fit`` fits (same defaults)."""
    if stiffness is None:
        stiffness = bool(survey.weights)
    if per_tendon is None:
        per_tendon = weighs_every_tendon(survey)
    if friction is None:
        friction = measures_friction(survey)
    return _params(robot, survey, stiffness, mechanics, per_tendon, friction)


def _params(robot: Robot, survey: Survey, stiffness: bool, mechanics: bool,
            per_tendon_radius: bool = False, friction: bool = False) -> list[Param]:
    out = []
    J = float(np.linalg.norm(robot.magnet.polarization))
    out.append(Param("magnet_J", "T", J, 0.15 * J, 0.5 * J, 1.5 * J, 0.05 * J))
    for j, s in enumerate(robot.segments if mechanics else ()):
        L = s.length * 1e3
        out.append(Param(f"length_{j + 1}", "mm", L, 0.05 * L, 0.8 * L, 1.2 * L, 0.01 * L))
    r = float(np.mean([t.routing_radius for t in robot.tendons])) * 1e3
    # a tendon gets its own radius from its own weight or its held pull; the
    # others share one. Each pulled tendon's stretch (EA) comes with its own
    # radius, or with the weights: a tendon's take-up per bend is its radius
    # plus its stretch, and without its own weight or held pull only the sum
    # is seen (docs/identify.md, "What one weight per segment cannot tell").
    # Left at the description's, a tendon whose free length or EA differs
    # pulled the magnet, the lengths and the sensors to make up its take-up
    # (bench robots at 10 %: magnet 6 % rms off, lengths 3 mm; with it 1.4 %
    # and 1 mm)
    pulled = [p.tendon for p in survey.pulls]
    own = set(pulled) if per_tendon_radius else {h.tendon for h in survey.held}
    if mechanics and not set(pulled) <= own:
        out.append(Param("radius", "mm", r, 0.05 * r, 0.7 * r, 1.3 * r, 0.01 * r))
    for i in pulled if mechanics else ():
        if i in own:
            ri = robot.tendons[i].routing_radius * 1e3
            out.append(Param(f"radius{i}", "mm", ri, 0.05 * ri, 0.7 * ri, 1.3 * ri, 0.01 * ri))
        if stiffness or i in own:
            ea = robot.tendons[i].stiffness_ea
            out.append(Param(f"EA{i}", "N", ea, EA_PRIOR * ea, 0.5 * ea, 2.0 * ea, 0.05 * ea))
    if mechanics:
        # the plane a tendon bends the robot in: the field's direction at
        # every sensor tells it, and at an off-plane sensor a tenth of a
        # degree moves a target by a few mN (bench robots at 10 %: +-0.5 deg)
        for p in survey.pulls:
            a0 = float(np.degrees(robot.tendons[p.tendon].routing_angle))
            out.append(Param(f"angle{p.tendon}", "deg", a0, ANGLE_PRIOR_DEG, a0 - ANGLE_RANGE_DEG,
                             a0 + ANGLE_RANGE_DEG, 0.05))
    for k, s in enumerate(robot.sensors):
        for a, ax in enumerate("xyz"):
            q = s.position[a] * 1e3
            out.append(Param(f"sensor{k}_{ax}", "mm", q, 1.0, q - 5.0, q + 5.0, 0.2))
    for p in survey.pulls:
        e0 = _engagement_guess(p, robot.noise) * 1e6
        out.append(Param(f"engage{p.tendon}", "um", e0, None, -1e3, p.take_up[-1] * 1e6, 50.0))
    if stiffness:
        for j, s in enumerate(robot.segments):
            ei = s.bending_stiffness * 1e3
            out.append(Param(f"EI_{j + 1}", "mN m^2", ei, 0.3 * ei, 0.25 * ei, 4.0 * ei,
                             0.05 * ei))
    if friction:
        # no prior: the two masses decide. Below zero it is not physical, but
        # a bound at 0 would start a frictionless description on its edge:
        # the range goes below and a fit that ends there is refused (_refusal)
        f0 = float(np.mean([t.friction_N or 0.0 for t in robot.tendons])) * 1e3
        out.append(Param("friction", "mN", f0, None, -50.0, 500.0, 5.0))
    return out


def _engagement_guess(pull, noise: float) -> float:
    """Take-up where the field change first exceeds 10 sigma of the noise."""
    mag = np.max(np.linalg.norm(pull.delta, axis=-1), axis=-1)
    above = np.nonzero(mag > 10 * noise)[0]
    return float(pull.take_up[max(above[0] - 1, 0)]) if len(above) else 0.0


def apply(robot: Robot, params: list[Param], values) -> Robot:
    """``robot`` with the fitted values in place (SI units)."""
    v = {p.name: float(x) for p, x in zip(params, values)}
    segs = []
    for j, s in enumerate(robot.segments):
        e = s.youngs_modulus
        if f"EI_{j + 1}" in v:
            e = v[f"EI_{j + 1}"] * 1e-3 / s.second_moment
        segs.append(dataclasses.replace(s, length=v.get(f"length_{j + 1}", s.length * 1e3) * 1e-3,
                                        youngs_modulus=e))
    r_nom = float(np.mean([t.routing_radius for t in robot.tendons]))
    f = v["radius"] * 1e-3 / r_nom if "radius" in v else 1.0
    tendons = [dataclasses.replace(t, routing_radius=v[f"radius{i}"] * 1e-3 if f"radius{i}" in v
                                   else t.routing_radius * f,
                                   stiffness_ea=v.get(f"EA{i}", t.stiffness_ea),
                                   routing_angle=np.radians(v[f"angle{i}"]) if f"angle{i}" in v
                                   else t.routing_angle,
                                   friction_N=v["friction"] * 1e-3 if "friction" in v
                                   else t.friction_N)
               for i, t in enumerate(robot.tendons)]
    J = np.array(robot.magnet.polarization)
    magnet = dataclasses.replace(robot.magnet,
                                 polarization=tuple(J / np.linalg.norm(J) * v["magnet_J"]))
    sensors = [dataclasses.replace(s, position=tuple(v[f"sensor{k}_{a}"] * 1e-3 for a in "xyz"))
               for k, s in enumerate(robot.sensors)]
    return dataclasses.replace(robot, segments=tuple(segs), tendons=tuple(tendons),
                               magnet=magnet, sensors=tuple(sensors))


GRAVITY_POINTS = 8  # mass points per segment for gravity's moment (midpoint rule)
GRAVITY_ROUNDS = 4  # fixed-point rounds of gravity and the pose it bends


def _plane_gravity(robot: Robot, i: int, kap_t: np.ndarray) -> np.ndarray:
    """Segment curvatures (n, n_seg), 1/m, of tendon ``i``'s bending plane:
    the tendon's kap_t plus gravity's, from the weight distal of each point
    of the pose (each segment's mass spread over GRAVITY_POINTS points, the
    magnet at its centre) times its lever, averaged over the segment, over
    EI; fixed-point rounds with the pose. Gravity's component across the
    plane is left out (a robot lying across the bend twists out of it)."""
    t = robot.tendons[i]
    segs = robot.segments
    g = np.zeros(3) if robot.gravity is None else np.asarray(robot.gravity, float)
    g_lat = g[0] * np.cos(t.routing_angle) + g[1] * np.sin(t.routing_angle)
    g_ax = g[2]
    masses = np.concatenate([[sg.linear_density * sg.length / GRAVITY_POINTS] * GRAVITY_POINTS
                             for sg in segs] + [[robot.magnet.mass]])
    if not masses.any() or (g_lat == 0.0 and g_ax == 0.0):
        return kap_t
    u = (np.arange(GRAVITY_POINTS) + 0.5) / GRAVITY_POINTS
    kap = kap_t.copy()
    n = kap.shape[0]
    ei = np.array([sg.bending_stiffness for sg in segs])
    # per segment the arc lengths of its mass points and of its end (a column)
    arcs = [np.append(sg.length * u, sg.length)[:, None] for sg in segs]
    off = robot.magnet.offset[2]
    beyond = np.triu(np.ones((len(masses), len(masses)), bool), 1)[:, :, None]
    m_beyond = masses[None, :, None]
    for _ in range(GRAVITY_ROUNDS):
        xs, zs = [], []
        x0, z0, phi = np.zeros(n), np.zeros(n), np.zeros(n)
        for k, sg in enumerate(segs):
            # the points along segment k, all at once: (GRAVITY_POINTS + 1, n)
            kk = kap[:, k]
            bent = kk != 0
            th = kk * arcs[k]
            with np.errstate(invalid="ignore", divide="ignore"):
                lx = np.where(bent, (1.0 - np.cos(th)) / np.where(bent, kk, 1.0), 0.0)
                lz = np.where(bent, np.sin(th) / np.where(bent, kk, 1.0), arcs[k])
            cp, sp = np.cos(phi), np.sin(phi)
            x = x0 + lx * cp + lz * sp
            z = z0 - lx * sp + lz * cp
            xs.append(x[:-1])
            zs.append(z[:-1])
            x0, z0, phi = x[-1], z[-1], phi + kk * sg.length
        xs.append((x0 + off * np.sin(phi))[None])
        zs.append((z0 + off * np.cos(phi))[None])
        X, Z = np.concatenate(xs), np.concatenate(zs)  # (points, n)
        # moment about each point of the weight beyond it: r x F, the
        # component that bends towards +lateral: (r_ax F_lat - r_lat F_ax)
        rx = X[None, :, :] - X[:, None, :]
        rz = Z[None, :, :] - Z[:, None, :]
        mom = np.sum(np.where(beyond, m_beyond * (rz * g_lat - rx * g_ax), 0.0),
                     axis=1)  # (points, n)
        grav = mom[:-1].reshape(len(segs), GRAVITY_POINTS, n).mean(axis=1).T / ei[None, :]
        kap = kap_t + grav
    return kap


def cc_single(robot: Robot, i: int, tensions, gravity: bool = True
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tendon ``i`` pulled alone: the host's constant-curvature model
    (``ConstantCurvatureModel``, straight routing) in closed form, vectorised
    over ``tensions`` (N), with gravity's moment in the tendon's bending plane
    (``_plane_gravity``; ``gravity=False``: the model itself). Returns tip
    positions (n, 3) m, tip rotations (n, 3, 3) and the take-up (n,) m (path
    shortening plus stretch). tests/host/test_identify.py checks it against
    the model itself and the Cosserat model."""
    t = robot.tendons[i]
    T = np.asarray(tensions, float)
    n = len(T)
    c, s = np.cos(t.routing_angle), np.sin(t.routing_angle)
    K = np.array([[0.0, 0.0, c], [0.0, 0.0, s], [-c, -s, 0.0]])  # [axis]x
    R = np.tile(np.eye(3), (n, 1, 1))
    p = np.zeros((n, 3))
    path = np.zeros(n)
    kap_t = np.array([T * t.routing_radius / seg.bending_stiffness if k < t.segment
                      else np.zeros(n) for k, seg in enumerate(robot.segments)]).T
    kaps = _plane_gravity(robot, i, kap_t) if gravity else kap_t
    for k, seg in enumerate(robot.segments):
        kap = kaps[:, k]
        th = kap * seg.length
        if k < t.segment:
            path += seg.length * (1.0 - kap * t.routing_radius)
        with np.errstate(invalid="ignore", divide="ignore"):
            lx = np.where(kap != 0, (1.0 - np.cos(th)) / np.where(kap != 0, kap, 1.0), 0.0)
            lz = np.where(kap != 0, np.sin(th) / np.where(kap != 0, kap, 1.0), seg.length)
        local_p = lx[:, None] * np.array([c, s, 0.0]) + lz[:, None] * np.array([0.0, 0.0, 1.0])
        st, ct = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
        local_R = np.eye(3) + st * K + (1.0 - ct) * (K @ K)
        p = p + np.einsum("nij,nj->ni", R, local_p)
        R = R @ local_R
    straight = robot.segment_end(t.segment)
    take = (straight - path) + T * (path + t.free_length) / t.stiffness_ea
    return p, R, take


class _Model:
    """Tip poses per tendon over TENSION_GRID, cached on the parameters the
    mechanics depend on (the field and engagement parameters reuse them)."""

    def __init__(self, robot: Robot, survey: Survey):
        self.robot, self.survey = robot, survey
        self.key = None
        self.wcache: dict = {}  # weight record poses, by what they depend on
        self.pcache: dict = {}  # each pull's poses, by what they depend on
        self.fcache = None  # the last field: (poses, magnet and sensors, field)
        self.scache: dict = {}  # each pull's field curve, by its exact values

    def _weight_loads(self, r: Robot) -> list:
        """(tendon, force) of each Cosserat pose the weight records need: the
        unloaded robot (tendon None) and each record's. A weight hung from
        slack reaches the tendon's end through its friction as a
        calibration's pull does (Robot.tip_tension)."""
        return [(None, 0.0)] + [(w.tendon, r.tip_tension(r.tendons[w.tendon], w.force))
                                for w in self.survey.weights]

    @staticmethod
    def _weight_key(r: Robot, mech: tuple, tendon: int | None, force: float) -> tuple:
        """What a weight pose depends on: the segments and that tendon's
        radius and angle (a tendon's stiffness, or another tendon's geometry,
        leaves it as it is)."""
        return (mech, tendon, force,
                None if tendon is None else (r.tendons[tendon].routing_radius,
                                             r.tendons[tendon].routing_angle))

    @staticmethod
    def _weight_problem(r: Robot, tendon: int | None, force: float):
        """The Cosserat model and tensions of a weight pose."""
        tau = np.zeros(len(r.tendons))
        if tendon is not None:
            tau[tendon] = force
        return CosseratModel(r, steps_per_segment=MODEL_STEPS), tau

    def _weight_pose(self, r: Robot, mech: tuple, tendon: int | None, force: float):
        """Tip pose of the Cosserat model with ``force`` on ``tendon`` (None:
        no load), cached (``_weight_key``)."""
        key = self._weight_key(r, mech, tendon, force)
        hit = self.wcache.get(key)
        if hit is None:
            if len(self.wcache) > 4096:
                self.wcache.clear()
            cos, tau = self._weight_problem(r, tendon, force)
            # no warm start: the finite differences of the Jacobian need the
            # same solution for the same parameters, to the last digit
            sol = cos.solve(tau)
            hit = self.wcache[key] = (sol.tip_position[None], sol.tip_rotation[None])
        return hit

    def prepare(self, robots: list[Robot]):
        """Solve the weight poses ``poses`` will need for ``robots`` (the
        columns of a finite-difference Jacobian) and has not cached, all at
        once: ``solve_many`` gives the same solutions as one by one, and
        shoots the columns that differ in one parameter in lockstep."""
        jobs: dict = {}
        for r in robots if self.survey.weights else ():
            mech = self._mechanics(r)[:2]
            for tendon, force in self._weight_loads(r):
                key = self._weight_key(r, mech, tendon, force)
                if key not in self.wcache and key not in jobs:
                    jobs[key] = self._weight_problem(r, tendon, force)
        if len(jobs) < 2:
            return
        try:
            sols = solve_many([m for m, _ in jobs.values()], [tau for _, tau in jobs.values()])
        except (ModelError, ValueError, np.linalg.LinAlgError):
            return  # each column meets it on its own, as without this
        if len(self.wcache) + len(jobs) > 4096:
            self.wcache.clear()
        for key, sol in zip(jobs, sols):
            self.wcache[key] = (sol.tip_position[None], sol.tip_rotation[None])

    def _pull(self, r: Robot, mech: tuple, tendon: int, tensions):
        """cc_single of one tendon, cached on the segments and that
        tendon's own parameters: a finite difference in another tendon's
        angle or radius leaves it as it is."""
        t = r.tendons[tendon]
        key = (mech, tendon, tuple(tensions), t.routing_radius, t.routing_angle, t.stiffness_ea,
               t.friction_N)
        hit = self.pcache.get(key)
        if hit is None:
            if len(self.pcache) > 4096:
                self.pcache.clear()
            hit = self.pcache[key] = cc_single(r, tendon, tensions)
        return hit

    @staticmethod
    def _mechanics(r: Robot) -> tuple:
        """The parameters the poses depend on; the segments' first."""
        segs, tds = r.segments, r.tendons
        return (tuple(s.length for s in segs), tuple(s.youngs_modulus for s in segs),
                tuple(t.routing_radius for t in tds), tuple(t.stiffness_ea for t in tds),
                tuple(t.friction_N for t in tds), tuple(t.routing_angle for t in tds))

    def poses(self, r: Robot):
        key = self._mechanics(r)
        if key != self.key:
            pos, rot, take = [], [], []
            mech = key[:2]
            for p in self.survey.pulls:
                a, b, c = self._pull(r, mech, p.tendon, TENSION_GRID)
                pos.append(a)
                rot.append(b)
                take.append(c)
            a, b, _ = self._pull(r, mech, 0, [0.0])
            pos.append(a)
            rot.append(b)
            if self.survey.weights:
                # the weights fix the stiffness, so they get the model the
                # tables are generated with (Cosserat, gravity: an upright
                # robot's own weight adds to its bending)
                for tendon, force in self._weight_loads(r):
                    a, b = self._weight_pose(r, mech, tendon, force)
                    pos.append(a)
                    rot.append(b)
            self.cached = (np.concatenate(pos), np.concatenate(rot), np.concatenate(take))
            self.key = key
        return self.cached

    def _field(self, r: Robot, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """field_at_sensors at the poses, reused while they (the same cached
        arrays) and the magnet and sensors stay: a finite difference in an
        engagement leaves the field as it was. (Only the whole call is
        reused: magpylib's elliptic integrals iterate until every pose in
        the call has converged, so a pose's field depends on the others.)"""
        key = repr((r.magnet, r.sensors))  # repr: exact floats, -0.0 apart from 0.0
        hit = self.fcache
        if hit is None or hit[0] is not pos or hit[1] is not rot or hit[2] != key:
            hit = self.fcache = (pos, rot, key, field_at_sensors(r, pos, rot))
        return hit[3]

    def _spline(self, n: int, take: np.ndarray, field: np.ndarray) -> CubicSpline:
        """Pull n's field curve against its take-up, cached on their exact
        values: a finite difference in an engagement, or in another
        tendon, often leaves it as it was."""
        key = (n, take.tobytes(), field.tobytes())
        hit = self.scache.get(key)
        if hit is None:
            if len(self.scache) > 256:
                self.scache.clear()
            hit = self.scache[key] = CubicSpline(take, field, axis=0)
        return hit

    def predict(self, r: Robot, engage: dict[int, float]):
        """Predicted field changes: a list per pull (n, n_s, 3) and an array
        of the weight records (n_w, n_s, 3), tesla; and the held pulls'
        (``_held()``)."""
        pos, rot, take = self.poses(r)
        B = self._field(r, pos, rot)
        ng = len(TENSION_GRID)
        npull = len(self.survey.pulls) * ng
        b0 = B[npull]
        out, curves = [], {}
        for n, p in enumerate(self.survey.pulls):
            tg = take[n * ng:(n + 1) * ng]
            spline = self._spline(n, tg, B[n * ng:(n + 1) * ng] - b0[None])
            curves[p.tendon] = (tg, spline)
            x = p.take_up - engage[p.tendon]
            pred = np.zeros_like(p.delta)
            on = x > 0
            if np.any(on):
                pred[on] = spline(x[on])
            out.append(pred)
        wpred = B[npull + 2:] - B[npull + 1][None] if self.survey.weights else B[:0]
        return out, wpred, self._held(r, engage, curves)

    def _held(self, r: Robot, engage: dict[int, float], curves: dict):
        """Each held pull's engagement shift (m) and the field of its bend
        (n_s, 3) T: the held tendon's pull at its take-up (``curves``: each
        pull's take-up over TENSION_GRID and its field curve), and the pulled
        tendon's path shortened by that pose's curvature (segments it runs
        through, along its direction) times its radius."""
        shifts, fields = [], []
        for h in self.survey.held:
            tg, field = curves[h.hold]
            x = h.hold_take_up - engage[h.hold]
            fields.append(field(x))
            T = float(np.interp(x, tg, TENSION_GRID))
            ta, tb = r.tendons[h.hold], r.tendons[h.tendon]
            kap_t = np.array([[T * ta.routing_radius / sg.bending_stiffness if k < ta.segment
                               else 0.0 for k, sg in enumerate(r.segments)],
                              [0.0] * len(r.segments)])
            kap = _plane_gravity(r, h.hold, kap_t)
            along = np.cos(ta.routing_angle - tb.routing_angle)
            shifts.append(sum(sg.length * tb.routing_radius * along * (kap[0, k] - kap[1, k])
                              for k, sg in enumerate(r.segments) if k < tb.segment))
        return np.array(shifts), fields


def fit(robot: Robot, survey: Survey, *, sigma_uT: float = 1.0,
        stiffness: bool | None = None, mechanics: bool = True, max_nfev: int | None = None,
        progress=None, per_tendon: bool | None = None,
        friction: bool | None = None) -> FitResult:
    """Fits ``robot`` to ``survey`` (see the module docstring). ``stiffness``
    (default: when the survey has weight records) adds the segments' EI;
    ``per_tendon`` (default: when every pulled tendon has a weight record)
    fits each tendon's routing radius and axial stiffness instead of one
    common radius (with the stiffness but not ``per_tendon``: the common
    radius and each tendon's axial stiffness); ``friction`` (default: when
    a tendon carries two masses, ``measures_friction``) fits the tendons'
    friction force.
    ``max_nfev``: model evaluations before the fit gives up (default 200 per
    parameter; a fit that runs out is refused as not converged).
    ``progress(nfev, rms_uT)`` is called after every model evaluation."""
    twisted = [t.index for t in robot.tendons if t.twist != 0.0]
    if twisted:
        raise IdentifyError(f"tendons {twisted} have helical routing: the fit models straight "
                            "routing only")
    if stiffness is None:
        stiffness = bool(survey.weights)
    params = fit_params(robot, survey, stiffness, mechanics, per_tendon, friction)
    names = [p.name for p in params]
    model = _Model(robot, survey)
    sigma = sigma_uT * 1e-6
    lo = np.array([(p.lo - p.nominal) / p.scale for p in params])
    hi = np.array([(p.hi - p.nominal) / p.scale for p in params])
    n_prior = sum(p.prior is not None for p in params)

    def values(z):
        return np.array([p.nominal + p.scale * zz for p, zz in zip(params, z)])

    def unpack(z):
        v = values(z)
        r = apply(robot, params, v)
        engage = {p.tendon: v[names.index(f"engage{p.tendon}")] * 1e-6 for p in survey.pulls}
        return r, engage

    nfev = [0]

    def resid(z):
        r, engage = unpack(z)
        preds, wpred, (hshift, hfield) = model.predict(r, engage)
        parts = [((pr - p.delta) / sigma).ravel() for pr, p in zip(preds, survey.pulls)]
        parts += [((wp - w.delta) / sigma).ravel() for wp, w in zip(wpred, survey.weights)]
        parts += [((hf - h.hold_delta) / sigma).ravel() for hf, h in zip(hfield, survey.held)]
        if survey.held:
            parts.append((hshift - np.array([h.shift for h in survey.held]))
                         / (SHIFT_SIGMA_UM * 1e-6))
        if progress is not None:
            nfev[0] += 1
            data = np.concatenate(parts)
            progress(nfev[0], float(np.sqrt(np.mean(data ** 2))) * sigma_uT)
        v = values(z)
        parts.append(np.array([(v[k] - p.nominal) / p.prior for k, p in enumerate(params)
                               if p.prior is not None]))
        return np.concatenate(parts)

    def columns(fun, zs):
        """least_squares' map over the columns of a finite-difference
        Jacobian: their Cosserat solves first, together (_Model.prepare),
        then each column as ever."""
        zs = list(zs)
        model.prepare([unpack(z)[0] for z in zs])
        return map(fun, zs)

    z0 = np.clip(np.zeros(len(params)), lo + 1e-9, hi - 1e-9)
    try:
        sol = least_squares(resid, z0, bounds=(lo, hi), x_scale=1.0, method="trf",
                            max_nfev=max_nfev or 200 * len(params), workers=columns)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise IdentifyError(f"the fit failed: {exc}") from None
    v = values(sol.x)
    r_fit, engage = unpack(sol.x)
    res = sol.fun[:len(sol.fun) - n_prior]
    n_data = len(res)
    chi2 = float(np.sum(res ** 2) / max(n_data - len(params), 1))
    try:
        cov_z = np.linalg.inv(sol.jac.T @ sol.jac) * max(chi2, 1.0)
        sig = np.sqrt(np.clip(np.diag(cov_z), 0, None)) * np.array([p.scale for p in params])
    except np.linalg.LinAlgError:
        sig = np.full(len(params), np.inf)
    preds, wpred, (hshift, _) = model.predict(r_fit, engage)
    per_tendon, curves = {}, {}
    for pr, p in zip(preds, survey.pulls):
        per_tendon[p.tendon] = float(np.sqrt(np.mean((pr - p.delta) ** 2)) * 1e6)
        curves[p.tendon] = (p.take_up, p.delta, pr, engage[p.tendon])
    wrms = [float(np.sqrt(np.mean((wp - w.delta) ** 2)) * 1e6)
            for wp, w in zip(wpred, survey.weights)]
    # the field's residuals (the engagement shifts, in their own unit, last)
    rms = float(np.sqrt(np.mean(res[:n_data - len(survey.held)] ** 2)) * sigma_uT)
    data = np.concatenate([p.delta.ravel() for p in survey.pulls] +
                          [w.delta.ravel() for w in survey.weights])
    signal = float(np.sqrt(np.mean(data ** 2)) * 1e6)
    out = FitResult(params, v, sig, r_fit, rms, signal, per_tendon, wrms, chi2, n_data,
                    bool(sol.success), sol.message, None, stiffness, curves,
                    [(h.tendon, h.hold, h.shift * 1e6, float(m) * 1e6)
                     for h, m in zip(survey.held, hshift)])
    out.refused = _refusal(out, sol, lo, hi)
    return out


def _refusal(res: FitResult, sol, lo, hi) -> str | None:
    """The reason to refuse a fit, or None."""
    if not sol.success or sol.status <= 0:
        return f"the fit did not converge ({sol.message})"
    fit_note = (f" (residual {res.rms_uT:.1f} uT rms against {res.signal_uT:.1f} uT of "
                "signal)")
    for p, v, sd in zip(res.params, res.values, res.sigmas):
        if p.name == "friction" and v < -max(3.0 * sd if np.isfinite(sd) else 0.0,
                                             FRICTION_SLACK_MN):
            return (f"friction = {v:.1f} +- {sd:.1f} mN: below zero, the two masses disagree "
                    "with the model; fit with one mass (--no-friction: the description's "
                    "friction)" + fit_note)
    for p, z, v, a, b in zip(res.params, sol.x, res.values, lo, hi):
        if ((p.prior is not None or p.name == "friction")
                and min(z - a, b - z) < 1e-3 * (b - a)):
            return (f"{p.name} = {v:.4g} {p.unit} reached the edge of its plausible range "
                    f"{p.lo:.4g}..{p.hi:.4g} {p.unit} (nominal {p.nominal:.4g}): the "
                    "description does not fit this robot" + fit_note)
    for p, v in zip(res.params, res.values):
        if p.name.startswith("engage") and not p.lo < v < p.hi:
            return f"{p.name}: no engagement inside the pull ({v:.0f} um)"
    if not np.all(np.isfinite(res.sigmas)):
        return "the parameters are not determined by these data (singular Jacobian)"
    if res.rms_uT > max(0.1 * res.signal_uT, 5.0):
        return (f"the model does not explain the data: residual {res.rms_uT:.1f} uT rms "
                f"against {res.signal_uT:.1f} uT of signal")
    return None
