"""PNG plots of the benchmark report, each measured figure beside the paper's."""
from __future__ import annotations

import os
from typing import Dict, List, Optional

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .report import ID_SHORT, SOURCES, id_set_label  # noqa: E402
from .stats import PAPER  # noqa: E402


def _save(fig, outdir: str, name: str) -> str:
    path = os.path.join(outdir, name)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return name


def repeatability(res: Dict, outdir: str) -> str:
    """Table I as bars: SD of each tendon's home, paper (manual, automated) and
    ours (native loop, simavr bench when measured), log scale."""
    fig, ax = plt.subplots(figsize=(8, 4.2))
    labels = [f"S{s + 1}T{t + 1}" for s in range(2) for t in range(3)] + ["avg"]
    x = np.arange(len(labels))
    series = [
        ("paper manual", sum(PAPER["repeat_manual_mm"], []) + [PAPER["repeat_manual_avg_mm"]]),
        ("paper automated", sum(PAPER["repeat_auto_mm"], []) + [PAPER["repeat_auto_avg_mm"]]),
    ]
    for src, lab in SOURCES:
        r = res.get(src)
        if r and "per_tendon_mm" in r:
            per = [r["per_tendon_mm"].get(str(i), r["per_tendon_mm"].get(i, np.nan)) for i in range(6)]
            series.append((f"hallhome, {lab}", per + [r["avg_mm"]]))
    w = 0.8 / len(series)
    floor = 1e-4  # an SD of 0 (every home on the same tick) drawn at the floor
    for k, (name, vals) in enumerate(series):
        v = np.array([max(float(a), floor) if np.isfinite(a) else np.nan for a in vals])
        ax.bar(x + (k - (len(series) - 1) / 2) * w, v, w, label=name)
    ax.axhline(PAPER["tick_mm"], color="k", ls="--", lw=1, label="one encoder tick (goal)")
    ax.set_yscale("log")
    ax.set_ylim(floor / 2, 1000)
    ax.set_xticks(x)
    ax.set_xticklabels(labels)
    ax.set_ylabel("SD of home position (mm)")
    ax.set_title(f"Repeatability of tendon homes, {res.get('runs', 10)} calibrations at 0.8 N "
                 "(an SD of 0 drawn at 1e-4)")
    ax.legend(fontsize=7, ncol=3, loc="upper center")
    return _save(fig, outdir, "repeatability.png")


def accuracy(acc: Dict, outdir: str) -> str:
    """Mean tension error +- SD per target and segment, with the paper's
    overall (0.06 +- 0.20) N band."""
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.axhspan(PAPER["tension_err_mean_N"] - PAPER["tension_err_sd_N"],
               PAPER["tension_err_mean_N"] + PAPER["tension_err_sd_N"], color="0.85",
               label="paper: 0.06 ± 0.20 N")
    ax.axhline(PAPER["tension_err_mean_N"], color="0.5", lw=1)
    ax.axhspan(-0.02, 0.02, color="tab:green", alpha=0.15, label="goal: mean within ±0.02 N")
    markers = {"native": "o", "native_gen": "^", "simavr": "s"}
    offs = {"native": -0.02, "native_gen": 0.0, "simavr": 0.02}
    for src, lab in SOURCES:
        a = acc.get(src)
        if not a or "cells" not in a:
            continue
        for c in a["cells"]:
            seg = c["segment"]
            ax.errorbar(c["target_N"] + offs[src] + (seg - 1.5) * 0.008, c["mean_N"],
                        yerr=c["sd_N"], fmt=markers[src],
                        color="tab:blue" if seg == 1 else "tab:orange", capsize=3,
                        label=f"{lab}, segment {seg}")
    h, l = ax.get_legend_handles_labels()
    uniq = dict(zip(l, h))
    ax.legend(uniq.values(), uniq.keys(), fontsize=8)
    ax.set_xlabel("target tension (N)")
    ax.set_ylabel("true tension at home − target (N)")
    ax.set_title("Tension accuracy, 5 calibrations per target")
    return _save(fig, outdir, "accuracy.png")


def timing(tm: Dict, outdir: str) -> str:
    fig, ax = plt.subplots(figsize=(8, 3.8))
    names = ["paper (full)"]
    vals = [PAPER["cal_time_s"]]
    for src, lab in SOURCES:
        t = tm.get(src) or {}
        if t.get("full_s") is not None:
            names.append(f"{lab}: full")
            vals.append(t["full_s"])
        if t.get("quick_s") is not None:
            names.append(f"{lab}: quick re-home")
            vals.append(t["quick_s"])
    ax.barh(names, vals, color=["0.6"] + ["tab:blue"] * (len(vals) - 1))
    ax.axvline(12.0, color="tab:green", ls="--", label="goal: 12 s")
    for k, v in enumerate(vals):
        ax.text(v, k, f" {v:.1f} s", va="center", fontsize=8)
    ax.set_xlabel("time per calibration, 6 tendons (s)")
    ax.legend(fontsize=8)
    return _save(fig, outdir, "timing.png")


def robustness(rob: Dict, outdir: str) -> List[str]:
    err = np.array([e for e in rob.get("err_N", []) if e is not None and np.isfinite(e)])
    fig, ax = plt.subplots(figsize=(7, 4))
    if err.size:
        ax.hist(err, bins=40, color="tab:blue", alpha=0.8, label="hallhome, native loop")
    ax.axvspan(PAPER["tension_err_mean_N"] - PAPER["tension_err_sd_N"],
               PAPER["tension_err_mean_N"] + PAPER["tension_err_sd_N"], color="0.85", zorder=0,
               label="paper: 0.06 ± 0.20 N")
    ax.set_xlabel("true tension at home − target (N)")
    ax.set_ylabel("tendon homes")
    ax.set_title(f"Tension error over {rob.get('runs', 0)} perturbed robots "
                 f"(±{100 * rob.get('frac', 0):.0f} %), {rob.get('tension_mN', 0)} mN")
    ax.legend(fontsize=8)
    names = [_save(fig, outdir, "robustness_hist.png")]

    rank = rob.get("ranking", [])
    oat = rob.get("oat", [])
    fig, axs = plt.subplots(1, 2, figsize=(11, 4.2))
    if rank:
        r = rank[:12][::-1]
        axs[0].barh([d["name"] for d in r], [d["share"] for d in r], color="tab:purple")
        axs[0].set_xlabel("share of error variance (joint linear fit)")
        axs[0].set_title(f"Monte Carlo sensitivity (R² = {rank[0]['r2']:.2f})")
    for d in oat[:6]:
        axs[1].plot(d["x"], d["mean_err_N"], marker="o", label=d["group"])
    axs[1].set_xlabel("parameter deviation (plant_cfg_perturb units)")
    axs[1].set_ylabel("mean tension error (N)")
    axs[1].set_title("One at a time (six largest)")
    axs[1].legend(fontsize=7)
    names.append(_save(fig, outdir, "robustness_sensitivity.png"))
    return names


def ambient(amb: Dict, outdir: str) -> str:
    fig, ax = plt.subplots(figsize=(11, 4.2))
    styles = {"abs_loop": ("tab:orange", "absolute |B−A| (paper), homing core (closed loop)"),
              "abs_ideal": ("tab:red", "absolute |B−A| (paper), ideal detector"),
              "delta_ideal": ("tab:blue", "field change |B−B0|, ideal detector"),
              "delta_loop": ("tab:green", "field change |B−B0|, homing core (closed loop)")}
    for mode, (color, label) in styles.items():
        rows = amb.get("modes", {}).get(mode)
        if not rows:
            continue
        x = [r["dA_uT"] for r in rows]
        ax.plot(x, [r["rms_N"] for r in rows], marker="o", color=color, label=label + ", RMS")
        ax.plot(x, [r["max_abs_N"] for r in rows], ls=":", color=color, label=label + ", max")
        for r in rows:
            if r.get("failed"):
                y = r["rms_N"] if r["rms_N"] is not None and np.isfinite(r["rms_N"]) else 3.0
                ax.annotate(f"{r['failed']}/{r['n']} failed", (r["dA_uT"], y),
                            textcoords="offset points", xytext=(-60, 6), fontsize=7, color=color)
    ax.axhline(PAPER["tension_err_sd_N"], color="0.6", ls="--", lw=1, label="paper SD 0.20 N")
    ax.set_yscale("symlog", linthresh=0.01)
    ax.set_ylim(0, 10)
    ax.set_xlabel("ambient field change between table and calibration (µT)")
    ax.set_ylabel("|tension error| (N), linear below 0.01")
    ax.set_title("Ambient change: absolute mode vs field-change mode (failed homes not in RMS)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(fig, outdir, "ambient.png")


def _board_errors(board: Optional[Dict], st: Dict) -> Optional[np.ndarray]:
    """The board's survey and held pulls' errors (robots, tendons, tensions)
    when they were measured on robots of set st's spread."""
    if not board or board.get("not_measured") or not board.get("records"):
        return None
    same = all(abs((board.get(k) or 0.0) - (st.get(k) if st.get(k) is not None
                                            else st.get("perturb", 0.0))) < 1e-9
               for k in ("perturb", "perturb_stiffness"))
    rows = [r["errors"] for r in board["records"] if "errors" in r]
    return np.array(rows) if same and rows else None


def identify(idf: Dict, outdir: str, board: Optional[Dict] = None) -> str:
    """Tension error of every tendon of every identified robot, per set,
    tension and description (nominal, survey only, with weights; the board's
    own survey and held pulls beside the set of their spread), against the
    worst-error goal."""
    sets = idf.get("sets", []) if idf and not idf.get("not_measured") else []
    n = max(len(sets), 1)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 4.2), squeeze=False, sharey=True)
    modes = (("nominal", "nominal TOML"),) + tuple(ID_SHORT.items())
    tensions = (0.3, 0.8, 1.5)
    for ax, st in zip(axes[0], sets):
        shown = [(lab, np.array(st["errors"][key]))  # (robots, tendons, tensions)
                 for key, lab in modes if key in st.get("errors", {})]
        eb = _board_errors(board, st)
        if eb is not None:
            shown.append(("the board's survey and held pulls", eb))
        width = 0.8 / max(len(shown), 1)
        for m, (lab, e) in enumerate(shown):
            off = (m - (len(shown) - 1) / 2) * width
            for n_t, t in enumerate(tensions):
                v = e[:, :, n_t].ravel()
                x = n_t + off + np.linspace(-0.3, 0.3, v.size) * width
                ax.plot(x, v, ".", ms=3, color=f"C{m}", label=lab if n_t == 0 else None)
                ax.plot([n_t + off - 0.4 * width, n_t + off + 0.4 * width],
                        [v.mean()] * 2, color=f"C{m}", lw=2)
        goal = idf.get("goals", {}).get("worst_N", 0.04)
        ax.axhspan(-goal, goal, color="0.85", zorder=0, label=f"worst-error goal ±{goal} N")
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set_xticks(range(len(tensions)))
        ax.set_xticklabels([f"{t} N" for t in tensions])
        ax.set_title(f"{len(st['seeds'])} robots at {id_set_label(st)}", fontsize=9)
        ax.set_xlabel("tension (bars: mean)")
        if eb is not None:  # a description the first panel's legend lacks
            ax.legend(fontsize=7, loc="lower left")
    if not sets:
        axes[0][0].text(0.5, 0.5, "not measured", ha="center", transform=axes[0][0].transAxes)
    axes[0][0].set_ylabel("true tension - target (N)")
    axes[0][0].legend(fontsize=7, loc="lower left")
    return _save(fig, outdir, "identify.png")
