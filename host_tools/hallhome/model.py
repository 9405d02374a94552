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


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (broadcasting); faster than np.cross
    for the small arrays used here."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], -1)


def _skew(w: np.ndarray) -> np.ndarray:
    """Batched cross-product matrices: (..., 3) -> (..., 3, 3)."""
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def _exp_coeffs(w: np.ndarray):
    th2 = np.einsum("bi,bi->b", w, w)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    sn, cs = np.sin(ths), np.cos(ths)
    a = np.where(small, 1.0 - th2 / 6.0, sn / ths)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - cs) / (ths * ths))
    c = np.where(small, 1.0 / 6.0 - th2 / 120.0, (ths - sn) / (ths * ths * ths))
    return a[:, None, None], b[:, None, None], c[:, None, None]


def _rot_step(R: np.ndarray, u: np.ndarray, h: float) -> np.ndarray:
    """Rotate frames (B,3,3) by the constant curvature u over h."""
    w = u * h
    a, b, _ = _exp_coeffs(w)
    W = _skew(w)
    return R @ (_EYE3 + a * W + b * (W @ W))


def _se3_step(R: np.ndarray, p: np.ndarray, u: np.ndarray, v: np.ndarray, h: float):
    """Advance frames (B,3,3) and points (B,3) by h with constant strains
    (u, v): the exact SE(3) exponential."""
    w = u * h
    a, b, c = _exp_coeffs(w)
    W = _skew(w)
    W2 = W @ W
    E = _EYE3 + a * W + b * W2
    V = _EYE3 + b * W + c * W2
    dp = (V @ (v * h)[..., None])[..., 0]
    return R @ E, p + (R @ dp[..., None])[..., 0]


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
    def _weight(self, k: int, s: float) -> float:
        """Mass distal of arc length s inside segment k (kg)."""
        return self.mass_after[k + 1] + self.lam[k] * (self.seg_start[k + 1] - s)

    def _routing(self, idx: np.ndarray, s: float):
        """Offsets r (n,3) and their derivatives r' (n,3) of tendons idx at s."""
        a = self.ang[idx] + self.twist[idx] * s
        ca, sa = np.cos(a), np.sin(a)
        rho = self.rho[idx]
        z = np.zeros_like(a)
        r = np.stack([rho * ca, rho * sa, z], -1)
        rp = np.stack([-rho * self.twist[idx] * sa, rho * self.twist[idx] * ca, z], -1)
        return r, rp

    def _strains(self, R, M, Nw, r, rp, S, tau, kse, kbt, u, v):
        """Solve the local constitutive + tendon equations for (u, v), batched
        over B shots, by Newton's method from the guess (u, v)."""
        mb = (M[:, None, :] @ R)[:, 0]  # R^T M
        nb = (Nw @ R) if Nw is not None else np.zeros_like(mb)
        if tau.size == 0:
            return mb / kbt, E3 + nb / kse
        scale = np.concatenate([1.0 / np.sqrt(kbt), 1.0 / np.sqrt(kse)])
        sc2 = scale[:, None] * scale[None, :]
        dk = np.concatenate([kbt, kse])
        tau4 = tau[None, :, None, None]
        for _ in range(12):
            q = v[:, None, :] + _cross(u[:, None, :], r) + rp
            nq = np.sqrt(np.einsum("bni,bni->bn", q, q))
            t = q / nq[..., None]
            tt = tau[None, :, None] * t
            f1 = kbt * u + _cross(r, tt).sum(1) - mb
            f2 = kse * (v - E3) + tt.sum(1) - nb
            tP = tau4 * (_EYE3 - t[..., :, None] * t[..., None, :]) / nq[..., None, None]
            sp = S @ tP
            J = np.empty((u.shape[0], 6, 6))
            J[:, :3, :3] = -(sp @ S).sum(1)
            J[:, :3, 3:] = sp.sum(1)
            J[:, 3:, :3] = -(tP @ S).sum(1)
            J[:, 3:, 3:] = tP.sum(1)
            J = (J + np.diag(dk)) * sc2
            F = np.concatenate([f1, f2], -1) * scale
            dx = np.linalg.solve(J, F[..., None])[..., 0] * scale
            u = u - dx[:, :3]
            v = v - dx[:, 3:]
            if (np.abs(dx[:, :3]).max() * self.L < 1e-13 and np.abs(dx[:, 3:]).max() < 1e-13):
                break
        return u, v

    def _plan(self, tensions: np.ndarray):
        """Per segment: loaded tendons, their tensions and routing at every
        step midpoint, and all passing tendons' routing (for path lengths)."""
        plan = []
        for k, seg in enumerate(self.segs):
            active = np.nonzero(self.t_seg >= k + 1)[0]
            loaded = active[tensions[active] > 0.0]
            n_steps = self.seg_steps[k]
            h = seg.length / n_steps
            stages = []
            for j in range(n_steps):
                sm = self.seg_start[k] + (j + 0.5) * h
                r, rp = self._routing(loaded, sm)
                ra, rpa = self._routing(active, sm)
                N0 = None if self.g is None else self.g * self._weight(k, sm - 0.5 * h)
                Nm = None if self.g is None else self.g * self._weight(k, sm)
                stages.append((sm, r[None], rp[None], _skew(r)[None], ra[None], rpa[None], N0, Nm))
            plan.append((active, tensions[loaded], h, stages))
        return plan

    def _integrate(self, plan, M0: np.ndarray, record: bool = False):
        """One shot from the base moments M0 (B,3): returns the tip boundary
        residuals (B,3), tendon path lengths (B, n_t) and, if record, the
        frames of shot 0.

        Lie-group midpoint rule: the strains are solved once per step, at the
        step's midpoint, whose state is predicted with the previous strains
        (an O(h^2) prediction keeps the rule second order)."""
        B = M0.shape[0]
        R = np.broadcast_to(_EYE3, (B, 3, 3)).copy()
        p = np.zeros((B, 3))
        M = M0.copy()
        u = np.zeros((B, 3))
        v = np.broadcast_to(E3, (B, 3)).copy()
        lengths = np.zeros((B, self.n_t))
        rec_s, rec_p, rec_R = [0.0], [p[0].copy()], [R[0].copy()]
        for k, (active, tau, h, stages) in enumerate(plan):
            kse, kbt = self.kse[k], self.kbt[k]
            for sm, r, rp, S, ra, rpa, N0, Nm in stages:
                if self.g is None:
                    Rh, Mh = R, M  # strains do not depend on the pose without loads
                else:
                    Rh = _rot_step(R, u, 0.5 * h)
                    Mh = M - 0.5 * h * _cross((R @ v[..., None])[..., 0], N0)
                u, v = self._strains(Rh, Mh, Nm, r, rp, S, tau, kse, kbt, u, v)
                if self.g is not None:
                    Rh = _rot_step(R, u, 0.5 * h)
                    M = M - h * _cross((Rh @ v[..., None])[..., 0], Nm)
                q = v[:, None, :] + _cross(u[:, None, :], ra) + rpa
                lengths[:, active] += h * np.sqrt(np.einsum("bni,bni->bn", q, q))
                R, p = _se3_step(R, p, u, v, h)
                if record:
                    rec_s.append(sm + 0.5 * h)
                    rec_p.append(p[0].copy())
                    rec_R.append(R[0].copy())
        # Tip boundary: M(L) equals the moment of the magnet's weight about the tip.
        if self.g is not None:
            res = M - _cross((R @ self.tip_offset), self.g * self.m_tip)
        else:
            res = M.copy()
        rec = (np.array(rec_s), np.array(rec_p), np.array(rec_R)) if record else None
        return res, lengths, rec

    def _straight_moment(self) -> np.ndarray:
        """Moment of the weights about the base for the straight robot: the
        first guess of the shooting unknown M(0)."""
        lever = sum(lam * (b * b - a * a) / 2.0 for lam, a, b in
                    zip(self.lam, self.seg_start[:-1], self.seg_start[1:]))
        lever += self.m_tip * (self.L + self.tip_offset[2])
        return np.cross(E3, self.g) * lever

    # --- public -----------------------------------------------------------------
    def solve(self, tensions, base_moment_guess=None) -> Solution:
        """Equilibrium under ``tensions`` (N, one per tendon, >= 0).

        ``base_moment_guess`` (N m, 3-vector) warm-starts the shooting, e.g.
        from a neighbouring tension. Raises ``ModelError`` when shooting does
        not converge and ``ValueError`` on a bad tension vector.
        """
        tau = np.asarray(tensions, dtype=float)
        if tau.shape != (self.n_t,) or np.any(tau < 0) or not np.all(np.isfinite(tau)):
            raise ValueError(f"tensions: expected {self.n_t} finite values >= 0 N, "
                             f"got {tensions!r}")
        plan = self._plan(tau)
        x = np.zeros(3)
        if self.g is not None:
            guess = (self._straight_moment() if base_moment_guess is None
                     else np.asarray(base_moment_guess, float))
            x = guess / self.m_scale
        shots = 0

        def shoot(xs, jac):
            nonlocal shots
            shots += 1
            batch = np.vstack([xs, xs + _FD_STEP * _EYE3]) if jac else xs[None]
            res, lengths, rec = self._integrate(plan, batch * self.m_scale, record=True)
            res = res / self.m_scale
            J = ((res[1:] - res[0]) / _FD_STEP).T if jac else None
            return res[0], J, lengths[0], rec

        # Shooting on the base moment: one shot with a finite-difference
        # Jacobian (batched), then chord steps reusing it; scipy's hybrid
        # Powell solver takes over if the chord steps stall.
        f, J, lengths, rec = shoot(x, self.g is not None)
        for _ in range(_CHORD_STEPS):
            if np.abs(f).max() < _SHOOT_TOL:
                break
            x = x - np.linalg.solve(J, f)
            f, _, lengths, rec = shoot(x, False)
        if np.abs(f).max() >= _SHOOT_TOL:
            sol = optimize.root(lambda z: shoot(z, True)[:2], x, jac=True, method="hybr",
                                options={"xtol": 1e-13})
            x = sol.x
            f, _, lengths, rec = shoot(x, False)
            if np.abs(f).max() >= _SHOOT_TOL * 100:
                raise ModelError(f"{self.robot.name}: shooting did not converge at tensions "
                                 f"{tau.tolist()} N (tip moment error {np.abs(f).max():.3g} "
                                 f"of EI/L): {sol.message}")
        s, pos, rot = rec
        return Solution(s=s, positions=pos, rotations=rot, tensions=tau,
                        path_lengths=lengths, displacements=self.straight_lengths - lengths,
                        base_moment=x * self.m_scale,
                        residual=float(np.abs(f).max() * self.m_scale), iterations=shots,
                        stretches=self._stretches(tau, lengths))

    def _stretches(self, tau: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        return np.array([self.robot.tendon_stretch(t, T, ln)
                         for t, T, ln in zip(self.robot.tendons, tau, lengths)])


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
