"""The arithmetic of `hallhome learn`, apart from the board: is a reading
plausible, and which targets on the table's grid do the learned points give.

A learned point is (tension in mN, field change |B - B0| in uT) for one
tendon, at any tension a known mass or force gives. The table needs targets
at its grid tensions, growing with tension (the firmware interpolates over
the grid), so the points are fitted with a non-decreasing curve (isotonic
regression) and read off at the grid tensions they span.
"""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

Point = Tuple[float, float]  # (tension mN, |dB| uT)

NO_WEIGHT_SIGMAS = 3.0    # a change below this many noise sigmas: no weight hangs
RISE_SIGMAS = 3.0         # a fall larger than this between tensions is not noise
MODEL_TOLERANCE = 0.5     # largest relative distance from the model's target


def isotonic(ys: Sequence[float], ws: Optional[Sequence[float]] = None) -> List[float]:
    """Least-squares non-decreasing fit of ys in their order (pool adjacent
    violators)."""
    blocks: List[List[float]] = []  # [mean, weight, count]
    for i, y in enumerate(ys):
        blocks.append([float(y), float(ws[i]) if ws else 1.0, 1])
        while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
            m2, w2, n2 = blocks.pop()
            m1, w1, n1 = blocks.pop()
            blocks.append([(m1 * w1 + m2 * w2) / (w1 + w2), w1 + w2, n1 + n2])
    out: List[float] = []
    for m, _, n in blocks:
        out += [m] * n
    return out


def fit_to_grid(points: Sequence[Point], grid_mN: Sequence[int], tol_pct: float = 1.0
                ) -> List[Optional[float]]:
    """Targets (uT) at the grid tensions from learned points: the
    non-decreasing fit, interpolated linearly between the learned tensions.
    A grid tension outside the learned span (widened by tol_pct) gets None:
    the compiled target stays there."""
    if not points:
        return [None] * len(grid_mN)
    by_t: dict = {}
    for t, v in points:
        by_t.setdefault(float(t), []).append(float(v))
    ts = sorted(by_t)
    ys = isotonic([sum(by_t[t]) / len(by_t[t]) for t in ts], [len(by_t[t]) for t in ts])
    lo, hi = ts[0] * (1 - tol_pct / 100), ts[-1] * (1 + tol_pct / 100)
    out: List[Optional[float]] = []
    for g in grid_mN:
        if not lo <= g <= hi:
            out.append(None)
        elif g <= ts[0]:
            out.append(ys[0])
        elif g >= ts[-1]:
            out.append(ys[-1])
        else:
            i = next(k for k in range(1, len(ts)) if ts[k] >= g)
            f = (g - ts[i - 1]) / (ts[i] - ts[i - 1])
            out.append(ys[i - 1] + f * (ys[i] - ys[i - 1]))
    return out


def interp(grid_mN: Sequence[int], values: Sequence[float], t_mN: float) -> float:
    """Linear interpolation over the grid, clamped at its ends."""
    if t_mN <= grid_mN[0]:
        return values[0]
    if t_mN >= grid_mN[-1]:
        return values[-1]
    i = next(k for k in range(1, len(grid_mN)) if grid_mN[k] >= t_mN)
    f = (t_mN - grid_mN[i - 1]) / (grid_mN[i] - grid_mN[i - 1])
    return values[i - 1] + f * (values[i] - values[i - 1])


def nearest_grid(t_mN: float, grid_mN: Sequence[int], tol_pct: float) -> Optional[int]:
    """The grid tension within tol_pct of t_mN, or None."""
    g = min(grid_mN, key=lambda x: abs(x - t_mN))
    return g if abs(t_mN - g) <= g * tol_pct / 100 else None


def check_reading(t_mN: float, dB: float, earlier: Sequence[Point], noise_uT: float,
                  grid_mN: Sequence[int], model_uT: Optional[Sequence[float]] = None,
                  min_field: Optional[float] = None, tol_pct: float = 1.0,
                  model_tolerance: float = MODEL_TOLERANCE) -> Optional[str]:
    """Why a reading is implausible, or None. `earlier`: this tendon's points
    so far; `model_uT`: the table's targets at the grid (None: no model
    check); `min_field`: the smallest change that shows a weight (default
    NO_WEIGHT_SIGMAS noise sigmas)."""
    lo, hi = grid_mN[0] * (1 - tol_pct / 100), grid_mN[-1] * (1 + tol_pct / 100)
    if not lo <= t_mN <= hi:
        return (f"{t_mN / 1000:.3f} N is outside the table's grid, {grid_mN[0] / 1000:g}.."
                f"{grid_mN[-1] / 1000:g} N: learned targets are fitted onto the grid")
    floor = NO_WEIGHT_SIGMAS * noise_uT if min_field is None else min_field
    if dB < floor:
        return (f"the field changed by only {dB:.2f} uT (less than {floor:.2f} uT, "
                f"{NO_WEIGHT_SIGMAS:g} noise sigmas): is the weight hanging, and free?")
    margin = RISE_SIGMAS * noise_uT
    for t, v in earlier:
        if (t < t_mN and v > dB + margin) or (t > t_mN and v < dB - margin):
            return (f"{dB:.2f} uT at {t_mN / 1000:.3f} N does not rise with tension: "
                    f"{v:.2f} uT was learned at {t / 1000:.3f} N (check the mass, and that "
                    "nothing touches the robot)")
    if model_uT is not None:
        m = interp(grid_mN, model_uT, t_mN)
        if m > 0 and abs(dB - m) / m > model_tolerance:
            return (f"{dB:.2f} uT is {100 * (dB - m) / m:+.0f} % from the model's {m:.2f} uT at "
                    f"{t_mN / 1000:.3f} N (more than {100 * model_tolerance:.0f} %): wrong tendon or "
                    "mass? --no-model accepts readings far from the model")
    return None
