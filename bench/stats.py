"""Statistics of the benchmark report, free of I/O so they can be tested on
known inputs (tests/host/test_bench_report.py).

Conventions: standard deviations are sample standard deviations (n - 1), as
the paper's Table I; a statistic over fewer than two values is 0 for the SD
and NaN for the mean of nothing.
"""
from __future__ import annotations

import math
from typing import Dict, Iterable, List, Mapping, Sequence, Tuple

import numpy as np

# The paper (reference/tension-calibration-paper.txt), for the comparison columns.
PAPER = {
    "repeat_manual_mm": [[1.941, 2.503, 0.991], [3.121, 2.856, 2.424]],
    "repeat_auto_mm": [[0.0248, 0.0189, 0.0099], [0.0089, 0.0066, 0.0726]],
    "repeat_manual_avg_mm": 2.408,
    "repeat_auto_avg_mm": 0.0328,
    "tension_err_mean_N": 0.06,
    "tension_err_sd_N": 0.20,
    "cal_time_s": 52.0,
    "tick_mm": 0.0061,
}

# The goals on the bench at nominal parameters.
GOALS = {
    "repeat_avg_mm": 0.0061,  # at most one encoder tick
    "cal_time_s": 12.0,  # a full 6-tendon calibration
    "tension_err_mean_abs_N": 0.02,  # mean error within +-0.02 N
    "tension_err_sd_N": 0.03,  # standard deviation at most 0.03 N
    "loop_worst_us": 4000.0,  # worst main-loop pass, in every phase
}


# The identification's goals (issue 17): tension error of the targets made
# from the identified description, over every tendon of every seeded robot
# at 0.3, 0.8 and 1.5 N (docs/identify.md).
ID_GOALS = {
    "mean_abs_N": 0.01,  # mean within +-0.01 N
    "sd_N": 0.015,  # standard deviation at most 0.015 N
    "worst_N": 0.04,  # worst |error| at most 0.04 N
}


def id_goal_cells(st: Mapping) -> List[str]:
    """'met' or 'missed by X N' for the mean, SD and worst |error| of one row
    of the identification study (a dict with mean, sd, worst)."""
    out = []
    for value, limit in ((abs(st["mean"]), ID_GOALS["mean_abs_N"]), (st["sd"], ID_GOALS["sd_N"]),
                         (st["worst"], ID_GOALS["worst_N"])):
        if value is None or not math.isfinite(float(value)):
            out.append("not measured")
        elif value <= limit:
            out.append("met")
        else:
            out.append(f"missed by {value - limit:.4f} N")
    return out


def clean(values: Iterable[float]) -> List[float]:
    """The finite values, as floats."""
    out = []
    for v in values:
        try:
            f = float(v)
        except (TypeError, ValueError):
            continue
        if math.isfinite(f):
            out.append(f)
    return out


def mean_sd(values: Iterable[float]) -> Tuple[float, float]:
    """Mean and sample standard deviation of the finite values."""
    v = clean(values)
    if not v:
        return float("nan"), 0.0
    m = sum(v) / len(v)
    if len(v) < 2:
        return m, 0.0
    var = sum((x - m) ** 2 for x in v) / (len(v) - 1)
    return m, math.sqrt(max(var, 0.0))


def repeatability(homes_ticks: Mapping[int, Sequence[float]], mm_per_tick: float) -> Dict:
    """Table I: standard deviation of each tendon's home over repeated
    calibrations, in mm, and their average.

    homes_ticks: tendon -> homes in one fixed frame (ticks). Returns
    {"per_tendon_mm": {tendon: sd}, "avg_mm": mean of the SDs, "n": {tendon:
    count}, "max_spread_ticks": largest max-min over tendons}.
    """
    per = {}
    n = {}
    spread = 0.0
    for t in sorted(homes_ticks):
        v = clean(homes_ticks[t])
        n[t] = len(v)
        per[t] = mean_sd(v)[1] * mm_per_tick
        if v:
            spread = max(spread, max(v) - min(v))
    avg = sum(per.values()) / len(per) if per else float("nan")
    return {"per_tendon_mm": per, "avg_mm": avg, "n": n, "max_spread_ticks": spread}


def accuracy(rows: Iterable[Tuple[float, int, float]]) -> Dict:
    """Tension accuracy from (target_N, segment, true_tension_N) rows: mean
    error +- SD per target and segment, per segment, and over everything."""
    by_key: Dict[Tuple[float, int], List[float]] = {}
    by_seg: Dict[int, List[float]] = {}
    by_target: Dict[float, List[float]] = {}
    every: List[float] = []
    for target, seg, tension in rows:
        if not math.isfinite(float(tension)):
            continue
        e = float(tension) - float(target)
        by_key.setdefault((float(target), int(seg)), []).append(e)
        by_seg.setdefault(int(seg), []).append(e)
        by_target.setdefault(float(target), []).append(e)
        every.append(e)
    return {
        "cells": {k: mean_sd(v) + (len(v),) for k, v in sorted(by_key.items())},
        "segments": {k: mean_sd(v) + (len(v),) for k, v in sorted(by_seg.items())},
        "targets": {k: mean_sd(v) + (len(v),) for k, v in sorted(by_target.items())},
        "all": mean_sd(every) + (len(every),),
    }


def sensitivity(features: Mapping[str, Sequence[float]], y: Sequence[float]) -> List[Dict]:
    """Which parameter drives the error: per feature the Pearson correlation
    with y, the standardized coefficient of a joint least-squares fit, and the
    share of y's variance that the feature explains in that fit
    (coefficient x covariance / variance, which sums to R^2). Features with
    no spread are left out. Sorted by share, largest first; every entry also
    carries "r2" of the joint fit."""
    yv = np.asarray(y, dtype=float)
    keep = np.isfinite(yv)
    names = []
    cols = []
    for name, col in features.items():
        c = np.asarray(col, dtype=float)
        keep &= np.isfinite(c)
        names.append(name)
        cols.append(c)
    if not names or keep.sum() < 3:
        return []
    yv = yv[keep]
    used = []
    xs = []
    for name, c in zip(names, cols):
        c = c[keep]
        if np.std(c) > 0.0:
            used.append(name)
            xs.append((c - c.mean()) / c.std())
    if not used or np.std(yv) == 0.0:
        return [
            {"name": n, "corr": 0.0, "beta": 0.0, "share": 0.0, "r2": 0.0} for n in used
        ]
    X = np.column_stack(xs)
    ys = (yv - yv.mean()) / yv.std()
    beta, *_ = np.linalg.lstsq(X, ys, rcond=None)
    corr = np.array([float(np.corrcoef(X[:, j], ys)[0, 1]) for j in range(X.shape[1])])
    share = beta * corr  # standardized: cov(x_j, y) = corr_j
    r2 = float(share.sum())
    out = [
        {"name": n, "corr": float(c), "beta": float(b), "share": float(s), "r2": r2}
        for n, c, b, s in zip(used, corr, beta, share)
    ]
    out.sort(key=lambda d: -abs(d["share"]))
    return out


def oat_slopes(rows: Iterable[Tuple[str, float, float]]) -> List[Dict]:
    """One-at-a-time sweeps: per group the least-squares slope of the mean
    tension error (N) against the group's deviation x, and the error range
    over the sweep. rows: (group, x, err_N). Sorted by |range|, largest first."""
    groups: Dict[str, Dict[float, List[float]]] = {}
    for g, x, e in rows:
        if math.isfinite(float(e)):
            groups.setdefault(g, {}).setdefault(float(x), []).append(float(e))
    out = []
    for g, pts in groups.items():
        xs = np.array(sorted(pts))
        ms = np.array([np.mean(pts[x]) for x in xs])
        slope = float(np.polyfit(xs, ms, 1)[0]) if len(xs) >= 2 and np.ptp(xs) > 0 else 0.0
        out.append(
            {
                "group": g,
                "slope_N": slope,
                "range_N": float(ms.max() - ms.min()) if len(ms) else 0.0,
                "x": xs.tolist(),
                "mean_err_N": ms.tolist(),
            }
        )
    out.sort(key=lambda d: -abs(d["range_N"]))
    return out


def percentile(values: Iterable[float], q: float) -> float:
    v = clean(values)
    return float(np.percentile(v, q)) if v else float("nan")


def goal(value: float, limit: float, kind: str = "max") -> str:
    """'met' / 'missed' / 'not measured': kind 'max' means value <= limit,
    'abs' means |value| <= limit."""
    if value is None or not math.isfinite(float(value)):
        return "not measured"
    v = abs(float(value)) if kind == "abs" else float(value)
    return "met" if v <= limit else "missed"


def loop_phases(runs: Iterable[Mapping]) -> List[Dict]:
    """Merges the per-phase main-loop pass statistics of several bench runs
    (each the ``loop.phases`` list of an hh_bench summary) into one row per
    phase, in order of first appearance: passes summed, mean weighted by
    passes, p99 the highest of the runs' p99 (a pooled percentile would need
    the histograms), worst the highest pass of all."""
    rows: Dict[str, Dict] = {}
    for phases in runs:
        for p in phases or []:
            n = int(p.get("passes", 0))
            if n <= 0:
                continue
            r = rows.setdefault(p["name"], {"name": p["name"], "passes": 0, "_sum": 0.0,
                                            "p99_us": 0.0, "max_us": 0.0, "runs": 0})
            r["passes"] += n
            r["_sum"] += float(p["mean_us"]) * n
            r["p99_us"] = max(r["p99_us"], float(p["p99_us"]))
            r["max_us"] = max(r["max_us"], float(p["max_us"]))
            r["runs"] += 1
    out = []
    for r in rows.values():
        r["mean_us"] = r.pop("_sum") / r["passes"]
        out.append(r)
    return out
