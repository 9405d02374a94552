"""Static models of a tendon-driven continuum robot.

``CosseratModel``: the Cosserat rod with general tendon routing of Rucker &
Webster (IEEE T-RO 27(6), 2011), with shear and extension, optional gravity
and elastic tendons. ``ConstantCurvatureModel``: the piecewise constant
curvature model beside it. Both return a ``Solution``. docs/model.md gives the
equations, the frames and the validation.

Formulation used here (equivalent to Rucker & Webster's eq. (9)-(14)): cut
the robot at arc length s and take the distal part, backbone and tendons
together. Its balance gives the total internal force N(s) = n + sum tau_i t_i
and moment M(s) = m + sum (R r_i) x tau_i t_i as the external load on the
distal part, so N(s) = g (mass distal of s) is known in closed form and
M' = -p' x N. In the body frame the constitutive law then fixes the strains
(u, v) locally:

    Kbt u + sum tau_i r_i x t_i = R^T M,   Kse (v - e3) + sum tau_i t_i = R^T N,
    t_i = q_i / |q_i|,  q_i = v + u x r_i + r_i',

solved per integration stage by Newton's method (its Jacobian holds Rucker &
Webster's A, B, G, H matrices). The base moment M(0) is unknown: shooting
finds it with scipy.optimize.root so that M(L) equals the moment of the
magnet's weight about the tip. Without gravity M vanishes identically and the
first shot already meets the boundary condition.

Speed: numpy's cost here is per call, not per number, so the integration
carries a shot's finite-difference neighbours, and with ``solve_many``
other models of the same structure, as one batch. Every number comes out as
for its problem alone, to the last bit: elementwise the same operations in
the same order, each small matrix product and solve the same BLAS/LAPACK
call (numpy makes one per matrix), and each problem's iterations stop on
its own test (tests/host/test_model_speed_equivalence.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from hallhome.robot import Robot

E3 = np.array([0.0, 0.0, 1.0])


class ModelError(RuntimeError):
    """The shooting method did not converge (message says where)."""


@dataclass(frozen=True)
class Solution:
    """One static equilibrium.

    ``s`` (n,) arc lengths of the recorded frames, m; ``positions`` (n, 3)
    backbone points in the base frame, m; ``rotations`` (n, 3, 3) backbone
    frames (columns: body x, y, z in base coordinates). ``tensions`` (N) the
    load; ``path_lengths`` each tendon's path length inside the robot, m;
    ``displacements`` each tendon's geometric path shortening against the
    unloaded straight robot, m (positive = shorter); ``stretches`` each
    tendon's elastic elongation T (path + free length) / EA, m, so that
    ``take_up`` = displacements + stretches is the spool travel from the
    unloaded straight robot to this load; ``base_moment`` the
    shooting unknown M(0), N m; ``residual`` the tip boundary error, N m;
    ``iterations`` the number of shots.
    """

    s: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    tensions: np.ndarray
    path_lengths: np.ndarray
    displacements: np.ndarray
    base_moment: np.ndarray
    residual: float
    iterations: int
    stretches: np.ndarray

    @property
    def take_up(self) -> np.ndarray:
        """Geometric shortening plus elastic stretch per tendon, m."""
        return self.displacements + self.stretches

    @property
    def tip_position(self) -> np.ndarray:
        """Tip position in the base frame, m."""
        return self.positions[-1]

    @property
    def tip_rotation(self) -> np.ndarray:
        """Tip frame orientation, 3x3."""
        return self.rotations[-1]


_EYE3 = np.eye(3)
# Cyclic shifts of a vector's components: a x b = a[_P1] b[_P2] - a[_P2] b[_P1],
# component by component the products and differences written out.
_P1 = np.array([1, 2, 0])
_P2 = np.array([2, 0, 1])
# The skew matrix of w, flattened, taken from (w0, w1, w2, 0) (the zero makes
# its diagonal an exact +0.0): which component, and its sign.
_SKEW_OF = np.array([3, 2, 1, 2, 3, 0, 1, 0, 3])
_SKEW_SIGN = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])
_E6 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # (u, v) of the straight, unstretched rod


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (broadcasting); faster than np.cross
    for the small arrays used here."""
    return _cross_shifted(a, b.take(_P2, -1), b.take(_P1, -1))


def _cross_shifted(a: np.ndarray, b2: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """a x b from b's cyclic shifts b2 = b[..., (2, 0, 1)] and b1 = b[..., (1, 2, 0)],
    precomputed where b is constant."""
    return a.take(_P1, -1) * b2 - a.take(_P2, -1) * b1


def _skew(w: np.ndarray) -> np.ndarray:
    """Batched cross-product matrices: (..., 3) -> (..., 3, 3)."""
    w0 = np.concatenate([w, np.zeros(w.shape[:-1] + (1,))], -1)
    return (w0.take(_SKEW_OF, -1) * _SKEW_SIGN).reshape(w.shape[:-1] + (3, 3))


def _exp_coeffs(w: np.ndarray):
    """a, b, c (B,1,1) of exp([w]) = I + a W + b W^2 and of its integral over
    the step V = I + b W + c W^2, for rotation vectors w (B,3) (series below
    1e-4 rad)."""
    th2 = np.einsum("bi,bi->b", w, w)
    th = np.sqrt(th2)
    small = th < 1e-4
    # each element as the np.where form gives it; the form itself only when
    # both kinds are there (it computes both)
    n_small = np.count_nonzero(small)
    if n_small == len(th):  # e.g. a straight robot: the series alone
        a, b, c = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0
    elif n_small == 0:
        sn, cs = np.sin(th), np.cos(th)
        th_2 = th * th
        a, b, c = sn / th, (1.0 - cs) / th_2, (th - sn) / (th_2 * th)
    else:
        ths = np.where(small, 1.0, th)
        sn, cs = np.sin(ths), np.cos(ths)
        a = np.where(small, 1.0 - th2 / 6.0, sn / ths)
        b = np.where(small, 0.5 - th2 / 24.0, (1.0 - cs) / (ths * ths))
        c = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ths - sn) / (ths * ths * ths))
    return a[:, None, None], b[:, None, None], c[:, None, None]


def _exp_se3(w: np.ndarray):
    """The rotation exp([w]) and V (both (..., 3, 3)) of the SE(3) exponential
    for rotation vectors w (..., 3): a step with constant strains (u, v) over h
    turns the frame by exp([u h]) and moves the point by R V v h."""
    shape = w.shape[:-1] + (3, 3)
    w = w.reshape(-1, 3)
    a, b, c = _exp_coeffs(w)
    W = _skew(w)
    W2 = W @ W
    return (_EYE3 + a * W + b * W2).reshape(shape), (_EYE3 + b * W + c * W2).reshape(shape)


def _se3_step(R: np.ndarray, p: np.ndarray, u: np.ndarray, v: np.ndarray, h: float):
    """Advance frames (B,3,3) and points (B,3) by h with constant strains
    (u, v): the exact SE(3) exponential."""
    E, V = _exp_se3(u * h)
    dp = (V @ (v * h)[..., None])[..., 0]
    return R @ E, p + (R @ dp[..., None])[..., 0]


@dataclass(frozen=True)
class _SegmentPlan:
    """One segment of a ``_Shots`` plan. The arrays carry the problems on an
    axis P and, beside it, a unit axis where the state carries each
    problem's shots; the per-step ones have the steps first."""

    active: np.ndarray  # (n_a,) tendons passing through
    n: int  # number of loaded tendons
    h: np.ndarray  # (P, 1, 1) step length
    hs: np.ndarray  # (2, P, 1, 1) half and whole step
    s_end: np.ndarray  # (P, steps) arc length at each step's end
    r1: np.ndarray  # (steps, P, 1, n, 3) loaded offsets r at the midpoints, shifted (1, 2, 0) ...
    r2: np.ndarray  # ... and (2, 0, 1), for r x . and . x r
    rp: np.ndarray  # (steps, P, 1, n, 3) r'
    S: np.ndarray  # (steps, P, 1, n, 3, 3) [r]x
    r_act: np.ndarray  # (steps, P, 1, n_a, 3) offsets of all passing tendons
    rp_act: np.ndarray
    N0: np.ndarray | None  # (steps, 2, P, 1, 3) N at the step start, shifted as r1, r2
    Nm: np.ndarray | None  # (steps, P, 1, 1, 3) N at the midpoint (None: no gravity) ...
    Nm12: np.ndarray | None  # ... and shifted as r1, r2: (steps, 2, P, 1, 3)
    kbt: np.ndarray  # (P, 1, 3)
    kse: np.ndarray  # (P, 1, 3)
    kd: np.ndarray  # (P, 1, 6) (kbt, kse)
    scale: np.ndarray  # (P, 1, 6) Newton unknowns' scale
    sc2: np.ndarray  # (P, 1, 6, 6)
    D: np.ndarray  # (P, 1, 6, 6) diag(kbt, kse)
    tol_w: np.ndarray  # (P, 1, 6) (L, L, L, 1, 1, 1): Newton's step is small when |dx| tol_w is
    tau3: np.ndarray  # (P, 1, n, 1) the loaded tendons' tensions
    tau4: np.ndarray  # (P, 1, n, 1, 1)


class CosseratModel:
    """Cosserat-rod statics of ``robot`` (see the module docstring).

    ``steps_per_segment`` sets the integration grid (second-order Lie-group
    midpoint rule; docs/model.md shows its convergence); segments with
    helical routing get more steps, at most HELIX_STEP_RAD of turn per
    step. ``gravity=False`` ignores the robot's gravity entry.
    """

    def __init__(self, robot: Robot, steps_per_segment: int = 12, gravity: bool = True):
        self.robot = robot
        self.steps = int(steps_per_segment)
        self.g = np.array(robot.gravity) if gravity and robot.gravity is not None else None
        self.segs = robot.segments
        self.L = robot.length
        self.seg_start = np.cumsum([0.0] + [s.length for s in self.segs])
        self.kse = [np.array([s.shear_stiffness, s.shear_stiffness, s.axial_stiffness])
                    for s in self.segs]
        self.kbt = [np.array([s.bending_stiffness, s.bending_stiffness, s.torsional_stiffness])
                    for s in self.segs]
        td = robot.tendons
        self.n_t = len(td)
        self.rho = np.array([t.routing_radius for t in td])
        self.ang = np.array([t.routing_angle for t in td])
        self.twist = np.array([t.twist for t in td])
        self.t_seg = np.array([t.segment for t in td])
        mag = robot.magnet
        self.m_tip = mag.mass
        self.tip_offset = np.array(mag.offset)
        # Mass distal of each segment start (kg), for N(s) = g * W(s).
        lam = [s.linear_density for s in self.segs]
        self.lam = np.array(lam)
        tail = np.cumsum([0.0] + [lam[k] * self.segs[k].length for k in
                                  range(len(self.segs) - 1, -1, -1)])[::-1]
        self.mass_after = tail + self.m_tip  # index k: mass distal of seg_start[k]
        self.straight_lengths = np.array(
            [robot.segment_end(t.segment) * math.hypot(1.0, t.routing_radius * t.twist)
             for t in td])
        # Helical routing turns the tendon offsets within a step; keep that
        # below HELIX_STEP_RAD per step so helices converge like straight routing.
        self.seg_steps = []
        for k, seg in enumerate(self.segs):
            tw = [abs(t.twist) for t in td if t.segment >= k + 1] or [0.0]
            turn = max(tw) * seg.length
            self.seg_steps.append(max(self.steps, math.ceil(turn / HELIX_STEP_RAD)))
        ei = min(s.bending_stiffness for s in self.segs)
        self.m_scale = ei / self.L

    # --- pieces -----------------------------------------------------------------
    def _weight(self, k: int, s):
        """Mass distal of arc length(s) s inside segment k (kg)."""
        return self.mass_after[k + 1] + self.lam[k] * (self.seg_start[k + 1] - s)

    def _routing(self, idx: np.ndarray, s):
        """Offsets r (n,3) and their derivatives r' (n,3) of tendons idx at s;
        for arc lengths s (m,): (m, n, 3) each."""
        a = self.ang[idx] + self.twist[idx] * np.asarray(s)[..., None]
        ca, sa = np.cos(a), np.sin(a)
        rho = self.rho[idx]
        z = np.zeros_like(a)
        r = np.stack([rho * ca, rho * sa, z], -1)
        rp = np.stack([-rho * self.twist[idx] * sa, rho * self.twist[idx] * ca, z], -1)
        return r, rp

    def _loads(self, tensions: np.ndarray):
        """Per segment the tendons passing through and the loaded ones."""
        for k in range(len(self.segs)):
            active = np.nonzero(self.t_seg >= k + 1)[0]
            yield active, active[tensions[active] > 0.0]

    def _segment(self, k: int, active: np.ndarray, loaded: np.ndarray,
                 tensions: np.ndarray) -> dict:
        """Segment k's share of the plan of one problem (``_SegmentPlan``
        without the problem and shot axes): loaded tendons' routing at every
        step midpoint, all passing tendons' routing (for path lengths), N(s)
        and the Newton constants."""
        seg = self.segs[k]
        n_steps = self.seg_steps[k]
        h = seg.length / n_steps
        sm = self.seg_start[k] + (np.arange(n_steps) + 0.5) * h
        r, rp = self._routing(loaded, sm)
        ra, rpa = self._routing(active, sm)
        kse, kbt = self.kse[k], self.kbt[k]
        scale = np.concatenate([1.0 / np.sqrt(kbt), 1.0 / np.sqrt(kse)])
        out = dict(h=h, s_end=sm + 0.5 * h, r1=r.take(_P1, -1), r2=r.take(_P2, -1), rp=rp,
                   S=_skew(r), r_act=ra, rp_act=rpa, kbt=kbt, kse=kse, scale=scale,
                   sc2=scale[:, None] * scale[None, :], kd=np.concatenate([kbt, kse]),
                   D=np.diag(np.concatenate([kbt, kse])),
                   tol_w=np.array([self.L] * 3 + [1.0] * 3), tau=tensions[loaded])
        if self.g is not None:
            N0 = self.g * self._weight(k, sm - 0.5 * h)[:, None]
            Nm = self.g * self._weight(k, sm)[:, None]
            out.update(N0=np.stack([N0.take(_P1, -1), N0.take(_P2, -1)], 1), Nm=Nm,
                       Nm12=np.stack([Nm.take(_P1, -1), Nm.take(_P2, -1)], 1))
        return out

    def _straight_moment(self) -> np.ndarray:
        """Moment of the weights about the base for the straight robot: the
        first guess of the shooting unknown M(0)."""
        lever = sum(lam * (b * b - a * a) / 2.0 for lam, a, b in
                    zip(self.lam, self.seg_start[:-1], self.seg_start[1:]))
        lever += self.m_tip * (self.L + self.tip_offset[2])
        return np.cross(E3, self.g) * lever

    def _tensions(self, tensions) -> np.ndarray:
        """``tensions`` as an array, checked (see ``solve``)."""
        tau = np.asarray(tensions, dtype=float)
        if tau.shape != (self.n_t,) or np.any(tau < 0) or not np.all(np.isfinite(tau)):
            raise ValueError(f"tensions: expected {self.n_t} finite values >= 0 N, "
                             f"got {tensions!r}")
        return tau

    def _structure(self, tau: np.ndarray) -> tuple:
        """What models solved together in one ``_Shots`` must share."""
        return (self.g is None, self.n_t, tuple(self.seg_steps),
                tuple((tuple(a), tuple(b)) for a, b in self._loads(tau)))

    # --- public -----------------------------------------------------------------
    def solve(self, tensions, base_moment_guess=None) -> Solution:
        """Equilibrium under ``tensions`` (N, one per tendon, >= 0).

        ``base_moment_guess`` (N m, 3-vector) warm-starts the shooting, e.g.
        from a neighbouring tension. Raises ``ModelError`` when shooting does
        not converge and ``ValueError`` on a bad tension vector.
        """
        tau = self._tensions(tensions)
        x = np.zeros(3)
        if self.g is not None:
            guess = (self._straight_moment() if base_moment_guess is None
                     else np.asarray(base_moment_guess, float))
            x = guess / self.m_scale
        shots = _Shots([self], [tau])
        x, f, lengths, rec, n = _problem(_shooting(shots, x[None]), 0)
        if np.abs(f).max() >= _SHOOT_TOL:
            # scipy's hybrid Powell solver takes over from the chord steps

            def shoot(z, jac):
                nonlocal n
                n += 1
                f, J, lengths, rec = shots.shoot(z[None], jac)
                return f[0], None if J is None else J[0], lengths[0], [r[0] for r in rec]

            sol = optimize.root(lambda z: shoot(z, True)[:2], x, jac=True, method="hybr",
                                options={"xtol": 1e-13})
            x = sol.x
            f, _, lengths, rec = shoot(x, False)
            if np.abs(f).max() >= _SHOOT_TOL * 100:
                raise ModelError(f"{self.robot.name}: shooting did not converge at tensions "
                                 f"{tau.tolist()} N (tip moment error {np.abs(f).max():.3g} "
                                 f"of EI/L): {sol.message}")
        return self._solution(tau, x, f, lengths, rec, n)

    def _solution(self, tau, x, f, lengths, rec, shots: int) -> Solution:
        s, pos, rot = rec
        return Solution(s=s, positions=pos, rotations=rot, tensions=tau,
                        path_lengths=lengths, displacements=self.straight_lengths - lengths,
                        base_moment=x * self.m_scale,
                        residual=float(np.abs(f).max() * self.m_scale), iterations=shots,
                        stretches=self._stretches(tau, lengths))

    def _stretches(self, tau: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        return np.array([self.robot.tendon_stretch(t, T, ln)
                         for t, T, ln in zip(self.robot.tendons, tau, lengths)])


def solve_many(models: list[CosseratModel], tensions: list) -> list[Solution]:
    """``models[i].solve(tensions[i])`` for every i, the same solutions to
    the last bit, faster: problems of equal structure (the same steps and
    loaded tendons per segment, e.g. one robot and its neighbours in a
    finite-difference Jacobian) are shot in lockstep, which costs little
    more than one of them alone."""
    taus = [m._tensions(t) for m, t in zip(models, tensions)]
    groups: dict[tuple, list[int]] = {}
    for i, (m, tau) in enumerate(zip(models, taus)):
        groups.setdefault(m._structure(tau), []).append(i)
    out: list = [None] * len(models)
    for idx in groups.values():
        ms = [models[i] for i in idx]
        x = np.array([m._straight_moment() / m.m_scale if m.g is not None else np.zeros(3)
                      for m in ms])
        shot = _shooting(_Shots(ms, [taus[i] for i in idx]), x)
        for k, (i, m) in enumerate(zip(idx, ms)):
            x, f, lengths, rec, n = _problem(shot, k)
            if np.abs(f).max() >= _SHOOT_TOL:
                out[i] = m.solve(taus[i])  # hybrid Powell's turn: as solve() does
            else:
                out[i] = m._solution(taus[i], x, f, lengths, rec, n)
    return out


def _shooting(shots: _Shots, x: np.ndarray):
    """Shooting on the base moments x (P,3) (units of each model's m_scale):
    one shot with a finite-difference Jacobian (batched), then chord steps
    reusing it. Returns per problem x, the residual, path lengths, recorded
    frames ((s, positions, rotations)) and the number of shots; a residual
    still at _SHOOT_TOL or above calls for scipy's hybrid Powell solver."""
    f, J, lengths, rec = shots.shoot(x, shots.gravity)
    n = np.ones(len(x), int)
    for _ in range(_CHORD_STEPS):
        todo = ~(np.abs(f).max(1) < _SHOOT_TOL)
        if not todo.any():
            break
        x = x.copy()
        for p in np.nonzero(todo)[0]:
            x[p] = x[p] - np.linalg.solve(J[p], f[p])
        n += todo
        # the others keep their last shot (a first shot's Newton iterations
        # ran with its finite-difference neighbours: shot alone it differs)
        f_new, _, l_new, rec_new = shots.shoot(x, False)
        f = np.where(todo[:, None], f_new, f)
        lengths = np.where(todo[:, None], l_new, lengths)
        rec = [np.where(todo.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)
               for a, b in zip(rec_new, rec)]
    return x, f, lengths, rec, n


def _problem(shot: tuple, k: int) -> tuple:
    """Problem k's x, residual, path lengths, frames and shots of a
    ``_shooting`` result."""
    x, f, lengths, rec, n = shot
    return x[k], f[k], lengths[k], [r[k] for r in rec], int(n[k])


class _Shots:
    """Shots of P problems at once: ``models`` (of equal ``_structure``)
    under ``taus``. The state carries the problems on its first axis and
    each problem's shots on its second; every number is computed as for the
    problem alone."""

    def __init__(self, models: list[CosseratModel], taus: list[np.ndarray]):
        m0 = models[0]
        self.gravity = m0.g is not None
        self.n_t = m0.n_t
        self.m_scale = np.array([m.m_scale for m in models])[:, None, None]
        if self.gravity:
            self.tip = np.array([m.tip_offset for m in models])[:, None, :, None]
            self.tip_force = np.array([m.g * m.m_tip for m in models])[:, None]
        self.segs = []
        loads = list(m0._loads(taus[0]))
        for k, (active, loaded) in enumerate(loads):
            parts = [m._segment(k, active, loaded, tau) for m, tau in zip(models, taus)]

            def stack(key, axis=0):
                if len(parts) == 1:  # one problem: a view does
                    return parts[0][key][(slice(None),) * axis + (None,)]
                return np.stack([part[key] for part in parts], axis)

            h = np.array([part["h"] for part in parts])
            tau = stack("tau")
            grav = {}
            if self.gravity:
                grav = dict(N0=stack("N0", 2)[:, :, :, None], Nm=stack("Nm", 1)[:, :, None, None],
                            Nm12=stack("Nm12", 2)[:, :, :, None])
            self.segs.append(_SegmentPlan(
                active=active, n=len(loaded), h=h[:, None, None],
                hs=np.array([0.5 * h, h])[:, :, None, None], s_end=stack("s_end"),
                r1=stack("r1", 1)[:, :, None], r2=stack("r2", 1)[:, :, None],
                rp=stack("rp", 1)[:, :, None], S=stack("S", 1)[:, :, None],
                r_act=stack("r_act", 1)[:, :, None], rp_act=stack("rp_act", 1)[:, :, None],
                N0=grav.get("N0"), Nm=grav.get("Nm"), Nm12=grav.get("Nm12"),
                kbt=stack("kbt")[:, None], kse=stack("kse")[:, None], kd=stack("kd")[:, None],
                scale=stack("scale")[:, None], sc2=stack("sc2")[:, None],
                D=stack("D")[:, None], tol_w=stack("tol_w")[:, None],
                tau3=tau[:, None, :, None], tau4=tau[:, None, :, None, None]))

    def shoot(self, xs: np.ndarray, jac: bool):
        """One shot of every problem from the base moments xs (P,3), units
        of m_scale, with its finite-difference neighbours if jac: the tip
        residuals (P,3), their Jacobians (P,3,3) (None without jac), path
        lengths (P, n_t) and the recorded frames."""
        batch = (np.concatenate([xs[:, None], xs[:, None] + _FD_STEP * _EYE3], 1) if jac
                 else xs[:, None])
        res, lengths, rec = self._integrate(batch * self.m_scale)
        res = res / self.m_scale
        J = ((res[:, 1:] - res[:, :1]) / _FD_STEP).transpose(0, 2, 1) if jac else None
        return res[:, 0], J, lengths[:, 0], rec

    def _strains(self, seg: _SegmentPlan, j: int, R, M, u, v):
        """Solve the local constitutive + tendon equations at step j of
        ``seg`` for (u, v) (P, B, 3), by Newton's method from the guess
        (u, v); a problem's shots iterate together."""
        mb = (M[..., None, :] @ R)[..., 0, :]  # R^T M
        nb = (seg.Nm[j] @ R)[..., 0, :] if seg.Nm is not None else np.zeros_like(mb)
        if seg.n == 0:
            return mb / seg.kbt, E3 + nb / seg.kse
        mnb = np.concatenate([mb, nb], -1)
        r1, r2, rp, S = seg.r1[j], seg.r2[j], seg.rp[j], seg.S[j]
        P, B, n = u.shape[0], u.shape[1], seg.n
        x = np.concatenate([u, v], -1)
        # Per tendon tP = tau (I - t t^T) / |q| and S tP, side by side; the
        # Jacobian's blocks J[..., a, :, b, :] are [[-S tP S, S tP], [-tP S, tP]]
        # summed over the tendons (Jt indexes them [a, ..., b, :]).
        X = np.empty((2, P, B, n, 3, 3))
        Jb = np.empty((P, B, 2, 3, 2, 3))
        Jt = Jb.transpose(2, 0, 1, 3, 4, 5)
        J = Jb.reshape(P, B, 6, 6)
        going = np.ones(P, bool)
        for _ in range(12):
            q = x[..., None, 3:] + _cross_shifted(x[..., None, :3], r2, r1) + rp
            nq = np.sqrt(np.einsum("...i,...i->...", q, q))
            t = q / nq[..., None]
            tt = seg.tau3 * t
            # per tendon the moment r x tau t and the force tau t
            G = np.concatenate([r1 * tt.take(_P2, -1) - r2 * tt.take(_P1, -1), tt], -1)
            G = G[:, :, 0] if n == 1 else G.sum(2)
            F = (seg.kd * (x - _E6) + G - mnb) * seg.scale
            np.divide(seg.tau4 * (_EYE3 - t[..., :, None] * t[..., None, :]),
                      nq[..., None, None], out=X[1])
            np.matmul(S, X[1], out=X[0])
            if n == 1:
                Jt[..., 1, :] = X[:, :, :, 0]
                np.matmul(X[:, :, :, 0], S[:, :, 0], out=Jt[..., 0, :])
            else:
                Jt[..., 1, :] = X.sum(3)
                Jt[..., 0, :] = (X @ S).sum(3)
            np.negative(Jt[..., 0, :], out=Jt[..., 0, :])
            np.add(J, seg.D, out=J)
            np.multiply(J, seg.sc2, out=J)
            dx = np.linalg.solve(J, F[..., None])[..., 0] * seg.scale
            # a problem whose step was small (|du| L and |dv| below 1e-13)
            # stays where that step left it
            x = x - dx if P == 1 else np.where(going[:, None, None], x - dx, x)
            going &= ~((np.abs(dx) * seg.tol_w).max((1, 2)) < 1e-13)
            if not going.any():
                break
        return x[..., :3].copy(), x[..., 3:].copy()

    def _integrate(self, M0: np.ndarray):
        """Shots from the base moments M0 (P, B, 3): returns the tip boundary
        residuals (P, B, 3), tendon path lengths (P, B, n_t) and the frames
        of each problem's first shot: arc lengths (P, n), points (P, n, 3)
        and rotations (P, n, 3, 3).

        Lie-group midpoint rule: the strains are solved once per step, at the
        step's midpoint, whose state is predicted with the previous strains
        (an O(h^2) prediction keeps the rule second order)."""
        P, B = M0.shape[:2]
        R = np.broadcast_to(_EYE3, (P, B, 3, 3)).copy()
        p = np.zeros((P, B, 3))
        M = M0.copy()
        u = np.zeros((P, B, 3))
        v = np.broadcast_to(E3, (P, B, 3)).copy()
        lengths = np.zeros((P, B, self.n_t))
        rec_p, rec_R = [p[:, 0]], [R[:, 0]]  # never written in place below
        for seg in self.segs:
            steps = seg.s_end.shape[1]
            us, vs = np.empty((steps, P, B, 3)), np.empty((steps, P, B, 3))
            Eh = None  # exp([u h/2]) of the current u, once known
            for j in range(steps):
                if self.gravity:
                    if Eh is None:
                        Eh = _exp_se3(u * seg.hs[0])[0]
                    Rh = R @ Eh
                    Mh = M - seg.hs[0] * _cross_shifted((R @ v[..., None])[..., 0],
                                                        seg.N0[j, 1], seg.N0[j, 0])
                else:
                    Rh, Mh = R, M  # strains do not depend on the pose without loads
                u, v = self._strains(seg, j, Rh, Mh, u, v)
                if self.gravity:
                    # the half step (the midpoint's frame, and the next step's
                    # prediction) and the whole step in one batch
                    E, V = _exp_se3(u * seg.hs)
                    RE = R @ E
                    M = M - seg.h * _cross_shifted((RE[0] @ v[..., None])[..., 0],
                                                   seg.Nm12[j, 1], seg.Nm12[j, 0])
                    Eh, R_next, V = E[0], RE[1], V[1]
                else:
                    E, V = _exp_se3(u * seg.h)
                    R_next = R @ E
                dp = (V @ (v * seg.h)[..., None])[..., 0]
                p = p + (R @ dp[..., None])[..., 0]
                R = R_next
                us[j], vs[j] = u, v
                rec_p.append(p[:, 0])
                rec_R.append(R[:, 0])
            # path lengths: |q| of every passing tendon at every step midpoint
            q = vs[..., None, :] + _cross(us[..., None, :], seg.r_act) + seg.rp_act
            dl = seg.h * np.sqrt(np.einsum("...i,...i->...", q, q))
            acc = lengths[..., seg.active]
            for x in dl:  # step by step, as the sum runs along the robot
                acc = acc + x
            lengths[..., seg.active] = acc
        # Tip boundary: M(L) equals the moment of the magnet's weight about the tip.
        if self.gravity:
            res = M - _cross((R @ self.tip)[..., 0], self.tip_force)
        else:
            res = M.copy()
        s = np.concatenate([np.zeros((P, 1))] + [seg.s_end for seg in self.segs], 1)
        return res, lengths, (s, np.stack(rec_p, 1), np.stack(rec_R, 1))


HELIX_STEP_RAD = math.radians(2.0)
_FD_STEP = 1e-6
_SHOOT_TOL = 1e-10
_CHORD_STEPS = 6


class ConstantCurvatureModel:
    """Piecewise constant curvature with the tendon moments of each segment.

    Each segment bends with the constant curvature u = Kbt^-1 sum tau_i e3 x
    r_i over the tendons passing through it (routing averaged over the
    segment), as an inextensible arc. Gravity is ignored. Tendon path length
    in a segment is L (1 + (u x r_i) . e3), exact for parallel routing.
    """

    def __init__(self, robot: Robot, samples_per_segment: int = 12):
        self.robot = robot
        self.samples = samples_per_segment
        self.cos = CosseratModel(robot, steps_per_segment=1, gravity=False)

    def solve(self, tensions) -> Solution:
        """Equilibrium under ``tensions`` (N); see ``CosseratModel.solve``."""
        tau = np.asarray(tensions, dtype=float)
        if tau.shape != (self.cos.n_t,) or np.any(tau < 0):
            raise ValueError(f"tensions: expected {self.cos.n_t} values >= 0 N, got {tensions!r}")
        R = np.eye(3)[None]
        p = np.zeros((1, 3))
        lengths = np.zeros(self.cos.n_t)
        ss, ps, rs = [0.0], [p[0].copy()], [R[0].copy()]
        for k, seg in enumerate(self.robot.segments):
            active = np.nonzero(self.cos.t_seg >= k + 1)[0]
            # Routing averaged over the segment (exact for straight routing).
            sq = np.linspace(self.cos.seg_start[k], self.cos.seg_start[k + 1], 33)
            r = np.mean([self.cos._routing(active, x)[0] for x in sq], axis=0)
            moment = (tau[active][:, None] * np.cross(E3, r)).sum(0)
            u = moment / self.cos.kbt[k]
            u[2] = 0.0
            lengths[active] += seg.length * (1.0 + np.cross(u, r)[:, 2])
            h = seg.length / self.samples
            for _ in range(self.samples):
                R, p = _se3_step(R, p, u[None], E3[None], h)
                ss.append(ss[-1] + h)
                ps.append(p[0].copy())
                rs.append(R[0].copy())
        return Solution(s=np.array(ss), positions=np.array(ps), rotations=np.array(rs),
                        tensions=tau, path_lengths=lengths,
                        displacements=self.cos.straight_lengths - lengths,
                        base_moment=np.zeros(3), residual=0.0, iterations=0,
                        stretches=self.cos._stretches(tau, lengths))
