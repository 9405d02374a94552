"""Markdown report of a benchmark run (bench/results/report.md) and its check.

build_report() turns the results dictionary that bench/run.py collects into
Markdown; check_report() verifies that a report has every section and that
its figures parse as numbers (the reduced pipeline check, `make bench-check`).
"""
from __future__ import annotations

import math
import os
import re
from typing import Dict, List, Optional

import numpy as np

from . import stats, straight_fw
from .stats import GOALS, PAPER

# Where a figure comes from: key in the results, label in the report.
SOURCES = [
    ("native", "native loop, plant table"),
    ("native_gen", "native loop, generated table"),
    ("simavr", "simavr bench, generated table"),
]

SECTIONS = [
    "## 1. Repeatability",
    "## 2. Tension accuracy",
    "## 3. Time per calibration",
    "## 4. Robustness",
    "## 5. Absolute-magnitude mode vs field-change mode",
    "## 6. Firmware resources",
    "## Goals",
    "## 7. Identification of the robot as built",
    "## 8. Straight-pose homes",
]


def fmt(v, digits: int = 4, unit: str = "") -> str:
    """A number for the report, or 'n/a' when not measured."""
    if v is None:
        return "n/a"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(f):
        return "n/a"
    return f"{f:.{digits}f}{(' ' + unit) if unit else ''}"


def cell(text) -> str:
    """Text safe inside a Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _src_note(r: Optional[Dict]) -> str:
    if not r:
        return "not measured"
    if r.get("not_measured"):
        return cell(f"not measured: {r['not_measured']}")
    return ""


def _per(r: Dict, i: int):
    per = r.get("per_tendon_mm", {})
    return per.get(str(i), per.get(i))


def _measured(r: Optional[Dict]) -> bool:
    return bool(r) and not r.get("not_measured")


def section_repeat(res: Dict) -> List[str]:
    rep = res.get("repeat", {})
    out = [SECTIONS[0] + " (paper Table I)", ""]
    out.append(
        f"{rep.get('runs', 10)} automated calibrations at 0.8 N from random initial slack "
        "(native loop: each tendon starts between 2 mm slack and 0.3 mm taut of its "
        "engagement; simavr bench: between 2 and 0.3 mm slack, hh_bench's default), nominal "
        "robot; standard "
        "deviation of each tendon's home position (spool travel), in mm. One encoder tick is "
        f"{fmt(res.get('meta', {}).get('mm_per_tick'), 5)} mm.")
    out.append("")
    out.append("| segment | tendon | paper manual (mm) | paper automated (mm) | "
               + " | ".join(f"{lab} (mm)" for _, lab in SOURCES) + " |")
    out.append("| --- | --- | --- | --- | " + " | ".join("---" for _ in SOURCES) + " |")
    for sg in range(2):
        for t in range(3):
            i = 3 * sg + t
            cells = [fmt(_per(rep[k], i)) if _measured(rep.get(k)) else "n/a" for k, _ in SOURCES]
            out.append(f"| {sg + 1} | {t + 1} | {PAPER['repeat_manual_mm'][sg][t]:.3f} | "
                       f"{PAPER['repeat_auto_mm'][sg][t]:.4f} | " + " | ".join(cells) + " |")
    cells = [fmt(rep[k].get("avg_mm")) if _measured(rep.get(k)) else "n/a" for k, _ in SOURCES]
    out.append(f"| average | | {PAPER['repeat_manual_avg_mm']:.3f} | "
               f"{PAPER['repeat_auto_avg_mm']:.4f} | " + " | ".join(cells) + " |")
    out.append("")
    for k, lab in SOURCES:
        r = rep.get(k)
        if _measured(r):
            extra = (f"; largest distance from the true home {fmt(r.get('max_abs_err_ticks'), 2)} "
                     "tick") if r.get("max_abs_err_ticks") is not None else ""
            out.append(f"- {lab}: {r.get('runs', 'n/a')} calibrations, largest spread of one "
                       f"tendon's homes {fmt(r.get('max_spread_ticks'), 0)} tick(s){extra}.")
        else:
            out.append(f"- {lab}: {_src_note(r)}")
    out += ["", "![repeatability](repeatability.png)", ""]
    return out


def section_accuracy(res: Dict) -> List[str]:
    acc = res.get("accuracy", {})
    out = [SECTIONS[1], ""]
    out.append("Targets 0.5, 0.8 and 1.0 N, 5 calibrations each, nominal robot; the plant's "
               "true spool-side tension at each home (pulled alone from slack: the "
               "calibration's definition) minus the target. Paper: (0.06 ± 0.20) N over all "
               "tests, measured with load cells (±0.15 N).")
    out.append("")
    out.append("| source | target (N) | segment | tendon homes | mean error (N) | SD (N) |")
    out.append("| --- | --- | --- | --- | --- | --- |")
    for src, lab in SOURCES:
        a = acc.get(src) or {}
        if a.get("not_measured") or not a:
            out.append(f"| {lab} | - | - | 0 | {_src_note(a)} | |")
            continue
        for c in a["cells"]:
            out.append(f"| {lab} | {c['target_N']:.1f} | {c['segment']} | {c['n']} | "
                       f"{c['mean_N']:+.4f} | {c['sd_N']:.4f} |")
        for sg in a["segments"]:
            out.append(f"| {lab} | all | {sg['segment']} | {sg['n']} | {sg['mean_N']:+.4f} | "
                       f"{sg['sd_N']:.4f} |")
        al = a["all"]
        out.append(f"| **{lab}** | **all** | **both** | {al['n']} | **{al['mean_N']:+.4f}** | "
                   f"**{al['sd_N']:.4f}** |")
    out.append(f"| paper | all | both | 30 | +{PAPER['tension_err_mean_N']:.2f} | "
               f"{PAPER['tension_err_sd_N']:.2f} |")
    out.append("")
    diag = acc.get("table_diag") or {}
    if diag.get("rows"):
        out.append("What the generated table alone does (native, noise-free plant pulled "
                   "quasi-statically until the table's target is met, sub-tick): the tension "
                   "error before any homing, bus or firmware effect. The plant table's target "
                   "is shown beside it" + (
                       " (its own sensor choice differs for tendon(s) "
                       + ", ".join(sorted({str(r["tendon"]) for r in diag["rows"]
                                           if r["gen_sensor"] != r["plant_sensor"]}))
                       + ")." if any(r["gen_sensor"] != r["plant_sensor"] for r in diag["rows"])
                       else ", same sensors."))
        out.append("")
        out.append("| target (N) | segment | tendons | generated: target (µT) | plant table: "
                   "target (µT) | error at the generated target (N) |")
        out.append("| --- | --- | --- | --- | --- | --- |")
        groups: Dict = {}
        for r in diag["rows"]:
            groups.setdefault((r["target_N"], r["segment"]), []).append(r)
        for (t, sg), rs in sorted(groups.items()):
            errs = [r["ideal_err_N"] for r in rs if r["ideal_err_N"] is not None]
            gt = sorted({fmt(r["gen_target_uT"], 1) for r in rs})
            pt = sorted({fmt(r["plant_target_uT"], 1) for r in rs})
            err = (fmt(min(errs), 4) if errs and abs(max(errs) - min(errs)) < 5e-5
                   else (f"{fmt(min(errs), 4)} .. {fmt(max(errs), 4)}" if errs else "n/a"))
            out.append(f"| {t:.1f} | {sg} | {', '.join(str(r['tendon']) for r in rs)} | "
                       f"{' / '.join(gt)} | {' / '.join(pt)} | {err} |")
        out.append("")
    elif diag.get("not_measured"):
        out += [f"- generated-table diagnosis: not measured: {diag['not_measured']}", ""]
    out += ["![accuracy](accuracy.png)", ""]
    return out


def section_time(res: Dict) -> List[str]:
    tm = res.get("time", {})
    out = [SECTIONS[2], ""]
    out.append("Simulated time of a full 6-tendon calibration (start to done) and of a quick "
               "re-home after a power cycle (robot left at its homes, encoders off by whole "
               f"turns). Paper: about {PAPER['cal_time_s']:.0f} s per calibration. The native "
               "loop assumes a servo answer every 1 ms and a first-order servo; the simavr bench "
               "runs the firmware's own bus schedule at 1 Mbps against the XL430 model.")
    out.append("")
    out.append("| source | full: mean (s) | full: max (s) | runs | quick re-home: mean (s) | runs |")
    out.append("| --- | --- | --- | --- | --- | --- |")
    notes = []
    for k, lab in SOURCES:
        t = tm.get(k)
        if _measured(t):
            out.append(f"| {lab} | {fmt(t.get('full_s'), 2)} | {fmt(t.get('full_max_s'), 2)} | "
                       f"{t.get('n_full', 0)} | {fmt(t.get('quick_s'), 2)} | {t.get('n_quick', 0)} |")
            if t.get("quick_max_s") is not None and t.get("n_quick", 0) > 1:
                notes.append(f"- quick re-home, {lab}: slowest {fmt(t['quick_max_s'], 2)} s of "
                             f"{t['n_quick']}")
            if t.get("quick_note"):
                notes.append(f"- quick re-home, {lab}: {t['quick_note']}")
            ph = t.get("phases")
            if ph:
                notes.append(
                    f"- where the time goes, {lab} (mean over {ph['runs']} runs): start to the "
                    f"first tendon (preflight, release, slack check, baseline) "
                    f"{fmt(ph['prep_s'], 2)} s; one tendon from its start to its home "
                    f"{fmt(ph['tendon_s'], 2)} s (slowest {fmt(ph['tendon_max_s'], 2)} s): "
                    f"take-up to engagement {fmt(ph.get('takeup_s'), 2)} s, engagement to home "
                    f"(moderate and fine approach) {fmt(ph.get('fine_s'), 2)} s; final move to "
                    f"the homes {fmt(ph['final_s'], 2)} s; the rest is the releases between "
                    "tendons.")
        else:
            out.append(f"| {lab} | {_src_note(t)} | | 0 | | 0 |")
    out.append(f"| paper | {PAPER['cal_time_s']:.0f} | | | | |")
    out += [""] + notes + (["" ] if notes else []) + ["![timing](timing.png)", ""]
    return out


def section_robust(res: Dict) -> List[str]:
    rob = res.get("robust", {})
    out = [SECTIONS[3] + " (Monte Carlo)", ""]
    out.append(
        f"{rob.get('runs', 0)} seeded robots from `plant_cfg_perturb` at ±"
        f"{100 * rob.get('frac', 0):.0f} % (stiffness, free lengths, friction, backlash, "
        "magnet moment ±frac; segment lengths and radii ±frac/5; tendon angles ±5°·frac; "
        "sensor positions ±1 mm·frac; slack ±500 µm·frac), each calibrated once at "
        f"{rob.get('tension_mN', 800)} mN by the homing core. Table `plant`: the nominal "
        "robot's own targets, so the error is what the parameter deviations alone do; table "
        "`generated`: the firmware's table from the host model, its model error added. "
        "Native loop (hh_mc, bench/hh_mc.c): homing core + plant, no simavr; the row "
        "`generated, simavr bench` is a check of a few perturbed robots (hh_bench --perturb, "
        "the same perturbation) calibrated by the firmware. The histogram and the ranking use "
        "the ±5 % plant-table runs.")
    out.append("")
    out.append("| perturbation | table | runs | tendon homes | faults | mean error (N) | SD (N) | "
               "5th pct (N) | 95th pct (N) | max abs (N) |")
    out.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for lvl in rob.get("levels", []):
        out.append(f"| ±{100 * lvl['frac']:.0f} % | {lvl.get('table', 'plant')} | {lvl['runs']} | "
                   f"{lvl['n']} | "
                   f"{lvl['faults']} | {lvl['mean_N']:+.4f} | {lvl['sd_N']:.4f} | "
                   f"{lvl['p5_N']:+.4f} | {lvl['p95_N']:+.4f} | {lvl['max_abs_N']:.4f} |")
    out.append(f"| paper (real robot) | model | | 30 | | +{PAPER['tension_err_mean_N']:.2f} | "
               f"{PAPER['tension_err_sd_N']:.2f} | | | |")
    out.append("")
    rank = rob.get("ranking", [])
    if rank:
        out.append(f"Which parameter drives the error (±{100 * rob.get('frac', 0):.0f} % runs): "
                   "joint linear fit of the tension error on every parameter deviation of "
                   f"the tendon (standardized), R² = {rank[0]['r2']:.2f}; share = the part of "
                   "the error variance each one explains.")
        out.append("")
        out.append("| rank | parameter | share of variance | correlation | standardized coefficient |")
        out.append("| --- | --- | --- | --- | --- |")
        for k, d in enumerate(rank[:10]):
            out.append(f"| {k + 1} | {d['name']} | {d['share']:.3f} | {d['corr']:+.3f} | "
                       f"{d['beta']:+.3f} |")
        out.append("")
    oat = rob.get("oat", [])
    if oat:
        out.append("One parameter group at a time over ±frac (every tendon or sensor moved "
                   "together; closed loop): range of the mean tension error over the sweep.")
        out.append("")
        out.append("| group | error range (N) | slope (N per unit deviation) |")
        out.append("| --- | --- | --- |")
        for d in oat:
            out.append(f"| {d['group']} | {d['range_N']:.4f} | {d['slope_N']:+.4f} |")
        out.append("")
    out += ["![robustness histogram](robustness_hist.png)", "",
            "![robustness sensitivity](robustness_sensitivity.png)", ""]
    return out


def section_ambient(res: Dict) -> List[str]:
    amb = res.get("ambient", {})
    out = [SECTIONS[4], ""]
    out.append(
        "The table is generated with the configured ambient field; the calibration then sees "
        "every sensor's ambient changed by the same vector (seeded random directions, "
        f"{amb.get('dirs', 0)} per magnitude; a re-oriented robot or moved iron), nominal "
        f"robot, {amb.get('tension_mN', 800)} mN. Field-change mode: |B − B0| against the "
        "table's |B(p_T) − B(p_0)|. Paper's absolute mode: |B − A_table| (the ambient seen at "
        "table generation removed) against the table's |B(p_T)|, pulling until the reading "
        "crosses the target in the direction the table predicts (|B| of the magnet can fall "
        "with the pull, as the tip turns the dipole away).")
    out.append("")
    if amb.get("abs_mode_note"):
        out.append(f"- {amb['abs_mode_note']}")
        out.append("")
    out.append("| ambient change (µT) | mode | tendon homes | failed | mean error (N) | "
               "RMS (N) | max abs (N) |")
    out.append("| --- | --- | --- | --- | --- | --- | --- |")
    for mode in ("abs_loop", "abs_ideal", "delta_loop", "delta_ideal"):
        for r in amb.get("modes", {}).get(mode, []):
            failed = f"{r['failed']} ({r['why']})" if r.get("failed") and r.get("why") else r["failed"]
            out.append(f"| {r['dA_uT']:g} | {mode} | {r['n']} | {failed} | "
                       f"{fmt(r['mean_N'])} | {fmt(r['rms_N'])} | {fmt(r['max_abs_N'])} |")
    bench = amb.get("bench")
    if bench:
        out += ["", "The firmware on the simavr bench, both modes (`set target_mode`): a first "
                "calibration (the absolute mode captures its ambient offsets there), every "
                "sensor's ambient changed by the same vector, a second calibration; the true "
                "tensions at the second run's homes (generated table, so the table's own bias "
                "is in every row; change 0 is the control):", "",
                "| mode | ambient change (µT) | result | mean error (N) | max abs error (N) | "
                "largest home shift from the unchanged delta run (ticks) |",
                "| --- | --- | --- | --- | --- | --- |"]
        for b in bench:
            mode = b.get("mode", "field change")
            if b.get("ok"):
                out.append(f"| {mode} | {b['dA_uT']:g} | done | {fmt(b['mean_N'])} | "
                           f"{fmt(b['max_abs_N'])} | {fmt(b.get('max_home_shift_ticks'), 0)} |")
            else:
                out.append(f"| {mode} | {b['dA_uT']:g} | failed: {cell(b.get('error'))} | | | |")
    out += ["", "`abs_ideal` / `delta_ideal`: noise-free quasi-static pull of the plant, "
            "sub-tick crossing (isolates the ambient effect); `abs_loop` / `delta_loop`: the "
            "homing core in the closed loop (noise, encoder ticks). Errors are over the homes "
            "found; a failed "
            "home is one the mode never reached within the travel limit (`target_not_reached`, "
            "a travel-limit fault in practice) or a run the homing core ended with a fault "
            "(`magnet_missing`: its magnet check compares the absolute |B0| with the table's "
            "straight-pose prediction, so a large ambient change can trip it).", "",
            "![ambient](ambient.png)", ""]
    return out


def section_resources(res: Dict) -> List[str]:
    r = res.get("resources", {})
    out = [SECTIONS[5], ""]
    out.append("| figure | value | source |")
    out.append("| --- | --- | --- |")
    def budget(v, cap):
        if v is None:
            return ""
        return "within" if v <= cap else "**over**"

    out.append(f"| flash | {fmt(r.get('flash_bytes'), 0, 'bytes')} "
               f"({fmt(r.get('flash_pct'), 1)} % of 256 KB; {budget(r.get('flash_bytes'), 65536)} "
               f"the 64 KB budget) | {cell(r.get('size_src', 'n/a'))} |")
    out.append(f"| static RAM | {fmt(r.get('ram_bytes'), 0, 'bytes')} "
               f"({fmt(r.get('ram_pct'), 1)} % of 8 KB; {budget(r.get('ram_bytes'), 4096)} "
               f"the 4 KB budget) | {cell(r.get('size_src', 'n/a'))} |")
    out.append(f"| worst main-loop time | {fmt(r.get('loop_max_us'), 0, 'µs')} | "
               f"{cell(r.get('loop_src', 'not measured'))} |")
    bus = r.get("bus", {})
    out.append(f"| servo bus cycle, sync write 6 + sync read 6 | "
               f"{fmt(bus.get('sync_wire_ms'), 3, 'ms')} on the wire, "
               f"{fmt(bus.get('sync_simavr_ms'), 3, 'ms')} on simavr (11 bit/byte) | "
               "build/native/hh_dxl_bench (simulated bus, 1 Mbps, return delay 0) |")
    out.append(f"| servo bus cycle, with fast sync read | {fmt(bus.get('fast_sync_wire_ms'), 3, 'ms')} "
               f"on the wire, {fmt(bus.get('fast_sync_simavr_ms'), 3, 'ms')} on simavr | "
               "build/native/hh_dxl_bench |")
    bb = r.get("bench_bus") or {}
    if bb.get("median_ms") is not None:
        out.append(f"| servo position-read period on the bench (firmware's bus cycle) | median "
                   f"{fmt(bb['median_ms'], 2, 'ms')}, 95th pct {fmt(bb['p95_ms'], 2, 'ms')}, max "
                   f"{fmt(bb['max_ms'], 2, 'ms')} ({bb['reads']} (fast) sync reads of Present Position "
                   f"in {fmt(bb['window_s'], 1, 's')}) | simavr bench, `--trace-bus` during a "
                   "calibration |")
        fine = (bb.get("by_phase") or {}).get("engaged")
        if fine:
            miss = fine["median_ms"] - FEEDBACK_GOAL_MS
            goal = ("met" if miss <= 0 else f"missed by {fmt(miss, 2, 'ms')}")
            out.append(f"| position feedback in the fine approach (`engaged`) | median "
                       f"{fmt(fine['median_ms'], 2, 'ms')}, 95th pct {fmt(fine['p95_ms'], 2, 'ms')}, "
                       f"max {fmt(fine['max_ms'], 2, 'ms')} ({fine['reads']} reads; goal at most "
                       f"{FEEDBACK_GOAL_MS:g} ms: {goal}); the take-up (`tendon`): median "
                       f"{fmt((bb['by_phase'].get('tendon') or {}).get('median_ms'), 2, 'ms')} | "
                       "the same run, each read filed under the phase the last report named |")
    else:
        out.append(f"| servo position-read period on the bench | "
                   f"not measured: {cell(bb.get('error', 'no simavr bench run'))} | simavr bench |")
    tx = r.get("servo_tx_hz")
    out.append(f"| servo transactions per servo on the bench | {fmt(tx, 0, 'per s')}"
               f"{f' (one every {1000.0 / tx:.2f} ms)' if tx else ''} | "
               f"{cell(r.get('bench_src', 'not measured'))} |")
    rates = r.get("sensor_rate_hz")
    out.append(f"| sensor sample rate achieved | "
               f"{', '.join(fmt(x, 1) for x in rates) + ' Hz' if rates else 'n/a'} | "
               f"{cell(r.get('bench_src', 'not measured'))} |")
    out.append("")
    out += loop_phase_table(r)
    if r.get("notes"):
        out += [f"- {n}" for n in r["notes"]] + [""]
    return out


def loop_phase_table(r: Dict) -> List[str]:
    """Main-loop pass times per calibration phase against the 4 ms goal."""
    rows = r.get("loop_phases")
    if not rows:
        return [f"Main-loop pass by phase: not measured "
                f"({cell(r.get('loop_phases_src', 'no simavr bench run'))}).", ""]
    limit = GOALS["loop_worst_us"]
    out = [f"Main-loop pass by phase ({cell(r.get('loop_phases_src', ''))}; goal: worst pass "
           f"at most {limit / 1000:g} ms in every phase):", "",
           "| phase | passes | mean | p99 (worst run) | worst | goal |",
           "| --- | --- | --- | --- | --- | --- |"]
    for p in rows:
        out.append(f"| {p['name']} | {p['passes']} | {fmt(p['mean_us'], 0, 'µs')} | "
                   f"{fmt(p['p99_us'], 0, 'µs')} | {fmt(p['max_us'], 0, 'µs')} | "
                   f"{'met' if p['max_us'] <= limit else 'missed'} |")
    return out + [""]


# Issue 14: a position read at least every 2 ms during the fine approach.
FEEDBACK_GOAL_MS = 2.0

ID_MODES = (("nominal", "nominal TOML (today)"), ("survey", "survey only (no weights)"),
            ("weights", "survey + one weight per segment"),
            ("tendons", "survey + one weight per tendon"),
            ("friction", "survey + two masses per segment (friction fitted)"),
            ("held", "survey + one weight per segment + held pulls (the bench's stepped "
                     "pulls)"))
ID_SHORT = {"survey": "survey only", "weights": "one weight per segment",
            "tendons": "one weight per tendon", "friction": "two masses per segment",
            "held": "one weight per segment and held pulls"}


def id_set_label(st: Dict) -> str:
    """The robots of an identification set, as the report and plot name them."""
    lab = f"±{100 * st['perturb']:g} %"
    if abs(st.get("perturb_stiffness", st["perturb"]) - st["perturb"]) > 1e-12:
        lab += f", stiffness ±{100 * st['perturb_stiffness']:g} %"
    fr = st.get("description_friction_mN")
    if fr is not None:
        lab += (", description without friction" if fr == 0
                else f", description friction {fr:g} mN")
    return lab


def section_identify(res: Dict) -> List[str]:
    idf = res.get("identify") or {}
    g = stats.ID_GOALS
    out = [SECTIONS[7], ""]
    out.append(
        "Issue 17: accuracy on the robot as built. Seeded robots perturbed by `hh_bench "
        "--perturb` (every parameter, as section 4) and `--perturb-stiffness` (the backbone's "
        "EI and EA alone); for each, `hh_bench --survey --survey-weight-all` records what "
        "the board would see (every tendon pulled alone from slack, encoder and field at "
        f"each step, and a {fmt(idf.get('weight_g'), 0)} g weight on every tendon in turn), "
        "`hallhome identify fit` fits the description to it (without the "
        "weights; with one per segment, the records of each segment's first tendon, which "
        "are those of a survey with one weight per segment; with one per tendon; with a "
        "second mass, twice the first, on each segment's first tendon, which lets the fit "
        "find the tendon friction; with one per segment and the held pulls, `--survey-held`: "
        "every tendon pulled again while another tendon of its segment holds a bend, whose "
        "engagement's move gives its routing radius; here the bench's stepped pulls, the "
        "board's own `survey T H` in the last rows) "
        "and the "
        "table generator makes the targets of each description (hallhome.identify_eval, "
        "docs/identify.md). Error = the tension at which the true robot (the plant's "
        "noise-free single-tendon pull, the calibration's definition) shows the target, "
        "minus the target: what a homing that lands exactly on the target leaves; every "
        "tendon of every robot counts. A refused fit keeps the nominal targets, as the user "
        f"would. Goals: mean within ±{g['mean_abs_N']} N, SD ≤ {g['sd_N']} N, worst |error| "
        f"≤ {g['worst_N']} N.")
    if idf.get("reused_from"):
        src = idf["reused_from"]
        out.append(f"Measured by the run of {src.get('git')} ({src.get('date')}), taken over "
                   "with `--identify-from` (this section depends on the host tools and the "
                   "plant, not the firmware).")
    out.append("")
    if not idf or idf.get("not_measured"):
        out.append(f"| robots | targets from | tension (N) | mean (N) | SD (N) | worst (N) | "
                   "goals |")
        out.append("| --- | --- | --- | --- | --- | --- | --- |")
        out.append(f"| - | - | - | n/a | n/a | n/a | {cell(_src_note(idf))} |")
        out.append("")
        return out
    out.append("| robots | targets from | tension (N) | mean (N) | SD (N) | worst \\|error\\| (N) "
               "| goals: mean / SD / worst |")
    out.append("| --- | --- | --- | --- | --- | --- | --- |")
    for st in idf.get("sets", []):
        lab = f"{len(st['seeds'])} x {id_set_label(st)}"
        for mode, mlab in ID_MODES:
            if mode not in st:
                continue
            out += error_rows(lab, mlab, st[mode])
    out += board_rows(res.get("identify_board") or {})
    out.append("")
    for st in idf.get("sets", []):
        ref = st.get("refused", {})
        fs = st.get("fit_s") or {}
        counts = ", ".join(f"{ID_SHORT[m]} {ref[m]}" for m, _ in ID_MODES[1:] if m in ref)
        out.append(f"- {len(st['seeds'])} robots at {id_set_label(st)} (seeds "
                   f"{st['seeds'][0]}-{st['seeds'][-1]}): fits refused: {counts}; a fit took "
                   f"{fmt(fs.get('mean'), 1)} s on average, {fmt(fs.get('max'), 1)} s at most.")
        for r in st.get("refusals", [])[:5]:
            out.append(f"  - refused, {cell(r)}")
    out.append(f"- Measured in {fmt(idf.get('wall_s'), 0)} s (wall).")
    out += board_notes(res.get("identify_board") or {})
    out += [""] + [f"- {n}" for n in identify_notes(idf)]
    out += ["", "![identification](identify.png)", ""]
    return out


BOARD_LABEL = ("the board's `survey` and `survey T H` + one weight per segment "
               "(bench/held_board.py)")


def error_rows(robots: str, targets: str, errs: Dict) -> List[str]:
    """Section 7's rows of one set and description: per test tension and all
    three, the mean, SD and worst |error| against the goals."""
    out = []
    for t in ("0.3", "0.8", "1.5", "all"):
        r = errs[t]
        out.append(f"| {robots} | {targets} | {t if t != 'all' else 'all three'} | "
                   f"{r['mean']:+.4f} | {r['sd']:.4f} | {r['worst']:.4f} | "
                   f"{' / '.join(stats.id_goal_cells(r))} |")
    return out


def board_rows(b: Dict) -> List[str]:
    """Section 7's rows of the board's own survey and held pulls."""
    if not b or b.get("not_measured") or not b.get("errors"):
        why = b.get("not_measured") or ("no robot's runs gave a survey file" if b
                                        else "not measured")
        return [f"| - | {BOARD_LABEL} | - | n/a | n/a | n/a | {cell(why)} |"]
    return error_rows(f"{len(b['seeds'])} x {id_set_label(b)}, firmware", BOARD_LABEL,
                      b["errors"])


def board_notes(b: Dict) -> List[str]:
    """What the board's runs of section 7 took: the highest true tensions
    against the bounded pull, the runs' times, the fits refused."""
    if not b or b.get("not_measured"):
        return []

    def rng(k, unit="s", d=1):
        v = b.get(k) or {}
        return f"{fmt(v.get('min'), d)}-{fmt(v.get('max'), d)} {unit}"

    bound = b.get("bound_mN")
    peaks = [b.get("survey_peak_mN"), b.get("hold_peak_mN"), b.get("pulled_peak_mN")]
    over = bound is not None and any(p is not None and p > bound for p in peaks)
    ref = b.get("refused") or []
    return [
        f"- The board's survey and held pulls, {len(b['seeds'])} robots at {id_set_label(b)} "
        f"(seeds {b['seeds'][0]}-{b['seeds'][-1]}, the firmware on the bench): the highest true "
        f"tension of any tendon in the survey alone {fmt(peaks[0], 0)} mN, of a held tendon "
        f"{fmt(peaks[1], 0)} mN, of a pulled tendon in a held run {fmt(peaks[2], 0)} mN, "
        f"against the bounded pull's {fmt(bound, 0)} mN"
        + (" (**over it**)" if over else " (within it)")
        + f"; the survey alone took {rng('survey_alone_s')}, each held run {rng('held_s')}, "
        f"a fit {rng('fit_s', d=0)}; fits refused (scored with the nominal targets): {len(ref)}"
        + (" (" + "; ".join(f"seed {r['seed']}: {cell(r['why'])}" for r in ref[:5]) + ")"
           if ref else "")
        + (f"; runs that did not end in `<done>`: seeds {b['runs_short']}"
           if b.get("runs_short") else "")
        + f"; measured in {fmt(b.get('wall_s'), 0)} s (wall)."]


def identify_notes(idf: Dict) -> List[str]:
    """Where the fit with weights meets or misses the goals, worded from the
    figures."""
    notes = []
    for st in idf.get("sets", []):
        nom = st["nominal"]["all"]
        for mode in ("weights", "tendons", "friction", "held"):
            lab = ID_SHORT[mode]
            if mode not in st:
                continue
            w = st[mode]["all"]
            cells = stats.id_goal_cells(w)
            missed = [f"{name} ({c})" for name, c in zip(("mean", "SD", "worst"), cells)
                      if c != "met"]
            worst_t = max(("0.3", "0.8", "1.5"), key=lambda t: st[mode][t]["worst"])
            notes.append(
                f"{id_set_label(st)}, {lab}: {w['mean']:+.4f} ± {w['sd']:.4f} N, worst "
                f"{w['worst']:.4f} N (at {worst_t} N) against {nom['mean']:+.4f} ± "
                f"{nom['sd']:.4f} N, worst {nom['worst']:.4f} N with the nominal targets; "
                + ("every goal met." if not missed else "missed: " + ", ".join(missed) + "."))
    for st in idf.get("sets", []):
        if "weights" not in st:
            continue
        trend = ", ".join(f"{st['weights'][t]['mean']:+.4f} N at {t} N" for t in ("0.3", "0.8", "1.5"))
        line = (f"{id_set_label(st)}: the mean error with one weight per segment by "
                f"tension ({trend})")
        if "tendons" in st:
            line += (f", and with one per tendon ({st['tendons']['0.3']['mean']:+.4f} N at 0.3 N, "
                     f"{st['tendons']['1.5']['mean']:+.4f} N at 1.5 N); the SD at 1.5 N is "
                     f"{st['weights']['1.5']['sd']:.4f} N with one weight per segment, "
                     f"{st['tendons']['1.5']['sd']:.4f} N with one per tendon")
        notes.append(line + ".")
    why = []
    g = idf.get("weight_g")
    for st in idf.get("sets", []):
        if "weights" not in st or not g:
            continue
        trend = st["weights"]["1.5"]["mean"] - st["weights"]["0.3"]["mean"]
        fr = st.get("description_friction_mN")
        line = (f"at {id_set_label(st)} the mean error with one weight per segment moves by "
                f"{trend:+.4f} N from 0.3 to 1.5 N: "
                + ("the description has no tendon friction (the plant's tip gets T (1 - mu) - "
                   "f0 of a spool tension T, sim/plant), so the stiffness a weight gives (at "
                   f"m g = {g * 9.80665e-3:.2f} N) is an effective one, exact at that tension "
                   "only" if fr == 0 else
                   "the targets carry the description's tendon friction (T (1 - mu) - f0 at "
                   "the tip of a spool tension T), which the plant has within the set's "
                   "spread"))
        if "friction" in st:
            f = st.get("parameter_rms_error", {}).get("friction", {}).get("friction")
            t2 = st["friction"]["1.5"]["mean"] - st["friction"]["0.3"]["mean"]
            line += (f"; with two masses per segment the fit finds the friction"
                     + (f" (rms {f:.2f} mN from the plant's)" if f is not None else "")
                     + f" and the trend is {t2:+.4f} N")
        why.append(line)
    corr = [(st, radius_correlation(st)) for st in idf.get("sets", [])]
    corr = [(st, c) for st, c in corr if c is not None]
    if corr:
        why.append(
            "with one weight per segment the spread comes from the tendons without a weight: "
            "each tendon's routing radius differs from the weighted one's, and a tendon's "
            "survey cannot tell its radius from its stretch (free length over EA), so the "
            "fit keeps one radius for all; a tendon's error at 1.5 N correlates with its "
            "true radius over the weighted tendon's ("
            + ", ".join(f"r = {c:+.2f} at {id_set_label(st)}" for st, c in corr)
            + "). A weight on every tendon lets the fit take each tendon's radius and "
            "stretch")
    ref = [(st, st.get("refused", {}).get("survey", 0)) for st in idf.get("sets", [])]
    worse = [st for st in idf.get("sets", []) if st.get("survey")
             and abs(st["survey"]["all"]["mean"]) > abs(st["nominal"]["all"]["mean"])]
    if worse:
        why.append(
            "without weights the stiffness stays nominal: the geometry fit removes errors "
            "that partly cancelled the stiffness's, so the mean gets worse than the nominal "
            "description's (" + ", ".join(
                f"{st['survey']['all']['mean']:+.4f} against {st['nominal']['all']['mean']:+.4f} N "
                f"at {id_set_label(st)}" for st in worse) + ")")
    for st, n in ref:
        if n:
            why.append(f"{n} of {len(st['seeds'])} survey-only fits at {id_set_label(st)} "
                       "were refused (see above) and scored with the nominal targets")
    if why:
        notes.append("Why: " + "; ".join(f"({k + 1}) {w}" for k, w in enumerate(why)) + ".")
    return notes


def radius_correlation(st: Dict) -> Optional[float]:
    """Correlation over every tendon of every robot of the set between the
    error at 1.5 N with one weight per segment and the tendon's true routing
    radius over its segment's weighted tendon's; None without the data."""
    radii, wt = st.get("radius_mm"), st.get("weighted_tendon")
    err = (st.get("errors") or {}).get("weights")
    if not radii or not wt or not err:
        return None
    x, y = [], []
    for r, e in zip(radii, err):
        for i, w in enumerate(wt):
            x.append(r[i] / r[w])
            y.append(e[i][2])
    if len(x) < 3 or np.std(x) == 0 or np.std(y) == 0:
        return None
    return float(np.corrcoef(x, y)[0, 1])


def goals_table(res: Dict) -> List[Dict]:
    """Each goal with the figure it is judged on: the simavr bench when it was
    measured there, otherwise the native loop (said so)."""
    rep, acc, tm = res.get("repeat", {}), res.get("accuracy", {}), res.get("time", {})

    def pick(d: Dict, key):
        for k, lab in (("simavr", "simavr bench"),
                       ("native_gen", "native loop, generated table (simavr bench not measured)"),
                       ("native", "native loop, plant table (simavr bench not measured)")):
            r = d.get(k)
            if _measured(r) and key(r) is not None:
                return key(r), lab
        return None, "not measured"

    g = []
    v, s = pick(rep, lambda r: r.get("avg_mm"))
    g.append({"goal": "repeatability (average SD of homes)", "limit": f"≤ {GOALS['repeat_avg_mm']} mm",
              "value": fmt(v, 4, "mm"), "source": s,
              "status": stats.goal(v, GOALS["repeat_avg_mm"])})
    v, s = pick(tm, lambda r: r.get("full_max_s"))
    g.append({"goal": "full 6-tendon calibration time (slowest run)",
              "limit": f"≤ {GOALS['cal_time_s']:g} s", "value": fmt(v, 2, "s"), "source": s,
              "status": stats.goal(v, GOALS["cal_time_s"])})
    v, s = pick(acc, lambda r: r.get("all", {}).get("mean_N"))
    g.append({"goal": "mean tension error", "limit": f"within ±{GOALS['tension_err_mean_abs_N']} N",
              "value": fmt(v, 4, "N"), "source": s,
              "status": stats.goal(v, GOALS["tension_err_mean_abs_N"], "abs")})
    v, s = pick(acc, lambda r: r.get("all", {}).get("sd_N"))
    g.append({"goal": "tension error SD", "limit": f"≤ {GOALS['tension_err_sd_N']} N",
              "value": fmt(v, 4, "N"), "source": s,
              "status": stats.goal(v, GOALS["tension_err_sd_N"])})
    return g


def section_goals(res: Dict) -> List[str]:
    out = [SECTIONS[6] + " (bench, nominal parameters)", ""]
    prev = res.get("previous") or {}
    pg = prev.get("goals") or {}
    out.append("| goal | limit | measured | source | status |"
               + (" previous run |" if pg else ""))
    out.append("| --- | --- | --- | --- | --- |" + (" --- |" if pg else ""))
    for g in goals_table(res):
        out.append(f"| {g['goal']} | {g['limit']} | {g['value']} | {g['source']} | "
                   f"**{g['status']}** |" + (f" {cell(pg.get(g['goal'], 'n/a'))} |" if pg else ""))
    out.append("")
    if pg:
        out.append(f"Previous run: {prev.get('date', 'n/a')}, commit {prev.get('git', 'n/a')}, "
                   f"firmware {prev.get('firmware', 'n/a')}.")
        out.append("")
    for n in res.get("goal_notes", []):
        out.append(f"- {n}")
    out.append("")
    return out


def build_report(res: Dict) -> str:
    m = res.get("meta", {})
    out = ["# hallhome benchmark report", ""]
    out.append(f"Generated by `make bench` (bench/run.py) on {m.get('date', 'n/a')}, "
               f"commit {m.get('git', 'n/a')}, robot config `{m.get('config', 'n/a')}`, "
               f"{'REDUCED pipeline check' if m.get('reduced') else 'full run'} in "
               f"{fmt(m.get('wall_s'), 0)} s. Every figure says where it was measured: the "
               "**native loop** (homing core + plant model, tests/tools/closedloop.c and "
               "bench/hh_mc.c, no AVR) or the **simavr bench** (the firmware ELF on simavr "
               "with simulated servos, sensors and the plant, sim/bench). "
               "The paper's figures come from reference/tension-calibration-paper.txt.")
    out.append("")
    sb = m.get("simavr_status")
    if sb:
        fw = f" (firmware {m['firmware']}, {m.get('elf', 'n/a')})" if m.get("firmware") else ""
        out.append(f"simavr bench{fw}: {sb}")
        out.append("")
    for part in (section_goals, section_repeat, section_accuracy, section_time, section_robust,
                 section_ambient, section_resources, section_identify):
        out += part(res)
    out += straight_fw.section(res, SECTIONS[8])
    return "\n".join(out).rstrip() + "\n"


NUM = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def check_report(path: str) -> List[str]:
    """Problems with a report: a missing section, a section without numbers, a
    referenced image that is not there, a goal without a status. Empty when
    the report is complete."""
    problems = []
    try:
        text = open(path).read()
    except OSError as e:
        return [f"cannot read {path}: {e}"]
    outdir = os.path.dirname(path)
    for k, head in enumerate(SECTIONS):
        i = text.find(head)
        if i < 0:
            problems.append(f"missing section {head!r}")
            continue
        nxt = min([j for j in (text.find("\n## ", i + 1),) if j > 0] or [len(text)])
        body = text[i + len(head):nxt]
        nums = []
        for line in body.splitlines():
            if line.startswith("|") and not line.startswith("| ---"):
                cells = [c.strip(" *") for c in line.strip("|").split("|")]
                for c in cells[1:]:
                    m = NUM.match(c.lstrip("±≤ "))
                    if m:
                        nums.append(float(m.group(0)))
        if not nums:
            problems.append(f"section {head!r} has no numeric figures")
        for img in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", body):
            if not os.path.exists(os.path.join(outdir, img)):
                problems.append(f"section {head!r}: image {img} missing")
    goals = text[text.find(SECTIONS[6]):] if SECTIONS[6] in text else ""
    st = re.findall(r"\*\*(met|missed|not measured)\*\*", goals)
    if len(st) < 4:
        problems.append(f"goals: {len(st)} statuses, expected 4")
    return problems
