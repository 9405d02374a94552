"""The benchmark run: `python -m bench.run --out bench/results` (make bench) or
`--reduced --out build/bench-check` (make bench-check). Collects every figure
into results.json, draws the PNGs and writes report.md (docs/benchmarks.md).
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Dict, List

import hallhome  # noqa: F401  (before numpy: it sets one BLAS thread)
import numpy as np

from . import native, plots, report, simavr, stats, straight_fw


def log(msg: str) -> None:
    print(f"bench: {msg}", flush=True)


def _acc_dict(rows) -> Dict:
    a = stats.accuracy(rows)
    return {
        "cells": [{"target_N": t, "segment": s, "mean_N": m, "sd_N": sd, "n": n}
                  for (t, s), (m, sd, n) in a["cells"].items()],
        "segments": [{"segment": s, "mean_N": m, "sd_N": sd, "n": n}
                     for s, (m, sd, n) in a["segments"].items()],
        "all": dict(zip(("mean_N", "sd_N", "n"), a["all"])),
    }


def _repeat_dict(homes: Dict[int, List[float]], mm_per_tick: float) -> Dict:
    r = stats.repeatability(homes, mm_per_tick)
    return {"per_tendon_mm": {str(k): v for k, v in r["per_tendon_mm"].items()},
            "avg_mm": r["avg_mm"], "n": {str(k): v for k, v in r["n"].items()},
            "max_spread_ticks": r["max_spread_ticks"]}


# ---- native loop ---------------------------------------------------------------------

def _run_ms(homes: List[Dict]) -> List[float]:
    """Simulated time of each run of one runner invocation (rows per home)."""
    per = {}
    for h in homes:
        per[h["run"]] = h["sim_ms"]
    return [per[k] for k in sorted(per)]


def _closedloop_rows(a, runs: int, tension: int, seed: int, mode: str = "full") -> List[Dict]:
    """Plant table (model-free targets): the project's hh_closedloop."""
    out = native.closedloop(a.closedloop, a.config, runs, tension, seed, mode=mode)
    return out["homes"]


def _generated_rows(a, runs: int, tension: int, seed: int, mode: str = "full") -> List[Dict]:
    """Generated table (the firmware's, model-based): hh_mc cal -g."""
    out = native.mc(a.mc, a.config, "cal", ["-g", "-n", str(runs), "-p", "0", "-t", str(tension),
                                             "-s", str(seed), "-m", mode])
    return [r for r in out.get("cal", [])]


NATIVE_SOURCES = (("native", "plant table", _closedloop_rows),
                  ("native_gen", "generated table", _generated_rows))


def native_items(a, res: Dict, cfg: Dict) -> None:
    mm_tick = cfg["nm_per_tick"] * 1e-6
    seg = cfg["segment"]
    n_rep = 3 if a.reduced else 10
    n_acc = 2 if a.reduced else 5
    n_q = 2 if a.reduced else 10
    res["repeat"]["runs"] = n_rep
    for key, label, rows_of in NATIVE_SOURCES:
        log(f"native loop, {label}: repeatability, {n_rep} calibrations at 800 mN")
        try:
            homes_rows = rows_of(a, n_rep, 800, a.seed)
        except (OSError, RuntimeError) as e:
            why = f"the runner failed: {e}"
            log(f"native loop, {label}: {why}")
            for k in ("repeat", "accuracy", "time"):
                res[k][key] = {"not_measured": why}
            continue
        homes: Dict[int, List[float]] = {}
        for h in homes_rows:
            homes.setdefault(int(h["tendon"]), []).append(h["home_ticks"])
        rep = _repeat_dict(homes, mm_tick)
        errs = stats.clean(h["err_ticks"] for h in homes_rows)
        rep["max_abs_err_ticks"] = max(abs(e) for e in errs) if errs else None
        rep["mean_err_ticks"] = stats.mean_sd(errs)[0] if errs else None
        rep["runs"] = n_rep
        res["repeat"][key] = rep

        log(f"native loop, {label}: tension accuracy, {n_acc} calibrations at 500 / 800 / 1000 mN")
        rows = []
        runs_ms = _run_ms(homes_rows)
        for t in (500, 800, 1000):
            r = rows_of(a, n_acc, t, a.seed + t)
            for h in r:
                i = int(h["tendon"])
                rows.append((t / 1000.0, seg[i] if i < len(seg) else 1, h["tension_N"]))
            runs_ms += _run_ms(r)
        res["accuracy"][key] = _acc_dict(rows)

        log(f"native loop, {label}: {n_q} quick re-homes")
        q_ms = _run_ms(rows_of(a, n_q, 800, a.seed + 77, mode="quick"))
        res["time"][key] = {
            "full_s": stats.mean_sd(runs_ms)[0] / 1000.0, "full_max_s": max(runs_ms) / 1000.0,
            "n_full": len(runs_ms), "quick_s": stats.mean_sd(q_ms)[0] / 1000.0 if q_ms else None,
            "quick_max_s": max(q_ms) / 1000.0 if q_ms else None, "n_quick": len(q_ms)}


def table_diag_item(a, res: Dict) -> None:
    """Where the noise-free plant meets the generated table's targets: the
    tension error the table alone imposes, before any homing or firmware."""
    rows = []
    for t in (500, 800, 1000):
        try:
            out = native.mc(a.mc, a.config, "targets", ["-t", str(t)])
        except (OSError, RuntimeError) as e:
            res["accuracy"]["table_diag"] = {"not_measured": str(e)}
            return
        for r in out.get("tgt", []):
            tn = r.get("gen_ideal_tension_N")
            rows.append({"target_N": t / 1000.0, "tendon": int(r["tendon"]),
                         "segment": int(r["segment"]), "gen_sensor": int(r["gen_sensor"]),
                         "gen_target_uT": r["gen_target_uT"],
                         "plant_sensor": int(r["plant_sensor"]),
                         "plant_target_uT": r["plant_target_uT"],
                         "ideal_err_N": (tn - t / 1000.0) if isinstance(tn, float) else None})
    res["accuracy"]["table_diag"] = {"rows": rows}


def robust_item(a, res: Dict) -> None:
    runs = 10 if a.reduced else a.mc_runs
    fracs = [0.05] if a.reduced else [0.02, 0.05, 0.10]
    main_frac = 0.05
    rob = {"runs": runs, "frac": main_frac, "tension_mN": 800, "levels": []}
    plan = [(f, "plant") for f in fracs] + ([] if a.reduced else [(main_frac, "generated")])
    for frac, table in plan:
        log(f"native loop: Monte Carlo, {runs} perturbed robots at ±{100 * frac:.0f} %, "
            f"{table} table")
        try:
            out = native.mc(a.mc, a.config, "mc", (["-g"] if table == "generated" else []) + [
                "-n", str(runs), "-p", str(frac), "-s", str(a.seed + 1000), "-t", "800"])
        except (OSError, RuntimeError) as e:
            log(f"native loop: Monte Carlo failed: {e}")
            continue
        rows = out.get("mc", [])
        errs = [r["err_N"] for r in rows]
        ok = stats.clean(errs)
        faults = len({r["run"] for r in rows if r["rc"] != 0})
        m, sd = stats.mean_sd(ok)
        rob["levels"].append({
            "frac": frac, "table": table, "runs": runs, "n": len(ok), "faults": faults,
            "mean_N": m, "sd_N": sd,
            "p5_N": stats.percentile(ok, 5), "p95_N": stats.percentile(ok, 95),
            "max_abs_N": max((abs(e) for e in ok), default=float("nan"))})
        if frac == main_frac and table == "plant":
            rob["err_N"] = [e if math.isfinite(e) else None for e in errs]
            names = ["seg1_ei", "seg2_ei", "moment", "seg1_len", "seg2_len", "angle_deg", "radius", "ea",
                     "free_len", "slack_um", "friction_f0", "friction_mu", "backlash",
                     "sensor_dx_mm", "sensor_dy_mm", "sensor_dz_mm", "sensor_dr_mm"]
            feats = {n: [r[n] for r in rows] for n in names if rows and n in rows[0]}
            rob["ranking"] = stats.sensitivity(feats, errs)
    log("native loop: one-at-a-time parameter sweeps")
    out = native.mc(a.mc, a.config, "oat", ["-p", str(main_frac), "-k", "2" if a.reduced else "7",
                                             "-s", str(a.seed), "-t", "800"])
    rob["oat"] = stats.oat_slopes((r["group"], r["x"], r["err_N"]) for r in out.get("oat", []))
    res["robust"] = rob


def _count(words) -> str:
    c: Dict[str, int] = {}
    for w in words:
        c[w] = c.get(w, 0) + 1
    return ", ".join(f"{k} x{v}" for k, v in sorted(c.items()))


def ambient_item(a, res: Dict) -> None:
    mags = "0 50" if a.reduced else "0 10 25 50 100 200"
    dirs = 1 if a.reduced else 8
    log(f"native loop: ambient change {mags} uT, {dirs} directions, both modes")
    out = native.mc(a.mc, a.config, "ambient", ["-a", mags, "-d", str(dirs), "-s", str(a.seed),
                                                 "-t", "800"])
    modes: Dict[str, List[Dict]] = {}
    by: Dict = {}
    for r in out.get("amb", []):
        by.setdefault((r["mode"], r["dA_uT"]), []).append(r)
    for (mode, mag), rows in sorted(by.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        e = stats.clean(r["err_N"] for r in rows if r["rc"] == 0)
        m, _ = stats.mean_sd(e)
        modes.setdefault(mode, []).append({
            "dA_uT": mag, "n": len(rows), "failed": sum(1 for r in rows if r["rc"] != 0),
            "why": _count(str(r.get("why", "")) for r in rows if r["rc"] != 0),
            "mean_N": m, "rms_N": math.sqrt(sum(x * x for x in e) / len(e)) if e else float("nan"),
            "max_abs_N": max((abs(x) for x in e), default=float("nan"))})
    res["ambient"] = {
        "modes": modes, "dirs": dirs, "tension_mN": 800,
        "abs_mode_note": (
            "Both modes run through the homing core in the closed loop (`abs_loop`, "
            "`delta_loop`; the absolute mode captures its ambient offsets A = B0 − b_straight "
            "in one run before the change and reuses them, hom_cmd_t.ambient_cuT) and as "
            "ideal detectors on the noise-free plant (`abs_ideal` with A = the ambient the "
            "table was made with, `delta_ideal`). The firmware runs both on the simavr bench "
            "(below).")}


# ---- firmware and simavr bench -------------------------------------------------------

def size_item(a, res: Dict) -> None:
    r = res["resources"]
    if not a.elf or not os.path.exists(a.elf):
        r["size_src"] = f"not measured: no firmware ELF at {a.elf}"
        return
    try:
        out = subprocess.run(["avr-size", "-A", a.elf], capture_output=True, text=True,
                             check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        r["size_src"] = f"not measured: avr-size failed ({e})"
        return
    sec = {}
    for line in out.splitlines():
        f = line.split()
        if len(f) >= 2 and f[0].startswith(".") and f[1].isdigit():
            sec[f[0]] = int(f[1])
    flash = sec.get(".text", 0) + sec.get(".data", 0)
    ram = sec.get(".data", 0) + sec.get(".bss", 0) + sec.get(".noinit", 0)
    r.update({"flash_bytes": flash, "ram_bytes": ram, "flash_pct": 100.0 * flash / 262144,
              "ram_pct": 100.0 * ram / 8192,
              "size_src": f"avr-size -A {a.elf} (as scripts/size.sh)"})


def simavr_items(a, res: Dict, cfg: Dict, workdir: str) -> None:
    mm_tick = cfg["nm_per_tick"] * 1e-6
    seg = cfg["segment"]
    why = None
    if a.no_simavr:
        why = "skipped (--no-simavr)"
    elif not (a.hh_bench and os.path.exists(a.hh_bench)):
        why = f"no bench binary at {a.hh_bench}"
    elif not (a.elf and os.path.exists(a.elf)):
        why = f"no firmware ELF at {a.elf}"
    probe = None
    if why is None:
        log("simavr bench: probe calibration (seed 1, 800 mN)")
        probe = simavr.calibration(a.hh_bench, a.elf, a.config, a.seed, 800, workdir,
                                   limit_s=a.sim_limit)
        boot = [l["rep"] for l in probe.get("lines", []) if l["rep"].get("_kind") == "boot"]
        if boot:
            res["meta"]["firmware"] = boot[0].get("version")
        if not probe["ok"]:
            why = f"the firmware does not complete a calibration on the bench ({probe.get('error')})"
    if why is not None:
        log(f"simavr bench: {why}")
        nm = {"not_measured": why}
        for k in ("repeat", "accuracy", "time"):
            res[k]["simavr"] = dict(nm)
        res["meta"]["simavr_status"] = f"not measured: {why}"
        res["resources"]["loop_src"] = f"not measured: {why}"
        res["resources"]["bench_src"] = f"not measured: {why}"
        if probe and probe.get("summary"):
            _bench_rates(res, probe, note="from a run that did not complete a calibration")
        return

    n_rep = 2 if a.reduced else 10
    n_acc = 1 if a.reduced else 5
    jobs = [dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config, seed=a.seed + k, tension_mN=800,
                 workdir=workdir, limit_s=a.sim_limit) for k in range(1, n_rep)]
    for t in (500, 1000):
        jobs += [dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config, seed=a.seed + 100 * k + t,
                      tension_mN=t, workdir=workdir, limit_s=a.sim_limit) for k in range(n_acc)]
    log(f"simavr bench: {len(jobs)} more calibrations, {a.jobs} at a time")
    t0 = time.time()

    def progress(k, r):
        log(f"simavr bench: calibration {k + 1}/{len(jobs)} "
            f"({jobs[k]['tension_mN']} mN, seed {jobs[k]['seed']}): "
            f"{'done in %.2f s simulated' % r['cal_s'] if r.get('ok') else 'FAILED ' + str(r.get('error'))}"
            f" [{time.time() - t0:.0f} s]")

    runs = [probe] + simavr.batch(jobs, a.jobs, progress)
    ok800 = [r for r in runs if r.get("ok") and r["tension_mN"] == 800]
    failed = [r for r in runs if not r.get("ok")]
    homes: Dict[int, List[float]] = {}
    for r in ok800:
        for i, h in r["homes"].items():
            homes.setdefault(i, []).append(h)
    rep = _repeat_dict(homes, mm_tick)
    errs = stats.clean(e for r in ok800 for e in r["shaft_err_ticks"].values())
    rep["max_abs_err_ticks"] = max(abs(e) for e in errs) if errs else None
    rep["mean_err_ticks"] = stats.mean_sd(errs)[0] if errs else None
    rep["runs"] = len(ok800)
    rep["failed"] = len([r for r in failed if r["tension_mN"] == 800])
    res["repeat"]["simavr"] = rep
    rows = []
    for r in runs:
        if not r.get("ok"):
            continue
        if r["tension_mN"] == 800 and r not in ok800[:n_acc]:
            continue
        for i, tn in r["tension_N"].items():
            rows.append((r["tension_mN"] / 1000.0, seg[i] if i < len(seg) else 1, tn))
    res["accuracy"]["simavr"] = _acc_dict(rows)
    cal = [r["cal_s"] for r in runs if r.get("ok") and r.get("cal_s") is not None]
    tm = {"full_s": stats.mean_sd(cal)[0] if cal else None, "full_max_s": max(cal) if cal else None,
          "n_full": len(cal), "n_quick": 0, "failed": len(failed)}
    ph = [r["phases"] for r in runs if r.get("ok") and r.get("phases")]
    if ph:
        tm["phases"] = {
            "prep_s": stats.mean_sd(p["prep_s"] for p in ph)[0],
            "tendon_s": stats.mean_sd(x for p in ph for x in p["tendon_s"])[0],
            "tendon_max_s": max((x for p in ph for x in p["tendon_s"]), default=None),
            "takeup_s": stats.mean_sd(x for p in ph for x in p.get("takeup_s", []))[0],
            "fine_s": stats.mean_sd(x for p in ph for x in p.get("fine_s", []))[0],
            "final_s": stats.mean_sd(p["final_s"] for p in ph)[0], "runs": len(ph)}
    res["time"]["simavr"] = tm
    res["meta"]["simavr_status"] = (
        f"{len(runs) - len(failed)} of {len(runs)} calibrations completed"
        + (f"; failed: {'; '.join(str(r.get('error')) for r in failed[:3])}" if failed else ""))

    res["resources"]["loop_phases"] = stats.loop_phases(
        r["summary"].get("loop", {}).get("phases", []) for r in runs
        if r.get("ok") and r.get("summary"))
    res["resources"]["loop_phases_src"] = (
        f"simavr bench: every main-loop pass of {len(runs) - len(failed)} calibrations "
        "(boot, idle, calibration), timed by the cycle counter (`hh_bench --loop-table`)")

    straight_fw.measure(a, res, workdir, len(seg), nominal_seeds=1 if a.reduced else 3,
                        perturbed_seeds=0 if a.reduced else 5, log=log)

    log("simavr bench: traced run for the servo bus cycle")
    res["resources"]["bench_bus"] = simavr.bus_cycle(a.hh_bench, a.elf, a.config, workdir)
    if a.reduced:
        tm["quick_note"] = "not measured in the reduced check"
        res["resources"]["loop_src"] = "not measured in the reduced check"
        _bench_rates(res, probe)
        return
    bench_ambient(a, res, cfg, workdir, probe)
    bench_perturbed(a, res, workdir)
    # every 800 mN calibration (10): a quick re-home's time moves by up to
    # 0.15 s with how its fine points fall (a back-off, one more near point),
    # and the mean of three moved by 0.1 s from one set of seeds to the next
    base = [r for r in ok800 if r.get("done_t")]
    log(f"simavr bench: {len(base)} x (the same calibration, status, power cycle, quick re-home)")
    qjobs = [dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config, seed=r["seed"], tension_mN=800,
                  done_t=r["done_t"], workdir=workdir, limit_s=r["done_t"] + a.sim_limit)
             for r in base]
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        qs = list(ex.map(lambda j: simavr.rehome_and_status(**j), qjobs))
    quick = [q["quick_s"] for q in qs if q.get("quick_s") is not None]
    if quick:
        tm["quick_s"] = stats.mean_sd(quick)[0]
        tm["quick_max_s"] = max(quick)
        tm["n_quick"] = len(quick)
        ph = [q["phantom"][0] for q in qs if q.get("phantom")]
        if ph:
            tm["quick_note"] = (
                f"in {len(ph)} of {len(qs)} runs the firmware reported `{ph[0]}` about 2 s "
                "after the power cycle, with no button event scheduled (a long press seen at "
                "power-up), so the tendons were released from their homes before the quick "
                "re-home started; the time includes taking them up again")
    else:
        tm["quick_note"] = "not measured: " + "; ".join(
            str(q.get("error", "no quick done report")) for q in qs[:2])
    r = res["resources"]
    loops = [q["loop_max_us"] for q in qs if q.get("loop_max_us") is not None]
    if loops:
        r["loop_max_us"] = max(loops)
        r["loop_src"] = (f"simavr bench: `status` loop_max_us right after a full calibration "
                         f"(worst pass since boot), worst of {len(loops)} runs")
    else:
        r["loop_src"] = "not measured: no status report after the calibration"
    _bench_rates(res, probe)


def bench_perturbed(a, res: Dict, workdir: str, frac: float = 0.05, n: int = 6) -> None:
    """A few calibrations of perturbed robots (hh_bench --perturb, its own
    seeded plant_cfg_perturb) by the firmware: a check of the native Monte
    Carlo's generated-table level on the real firmware."""
    if a.reduced or "robust" not in res:
        return
    log(f"simavr bench: {n} calibrations of robots perturbed by ±{100 * frac:.0f} %")
    jobs = [dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config, seed=a.seed + 5000 + k,
                 tension_mN=800, workdir=workdir, limit_s=a.sim_limit, perturb=frac)
            for k in range(n)]
    runs = simavr.batch(jobs, a.jobs)
    ok = [r for r in runs if r.get("ok")]
    errs = [t - 0.8 for r in ok for t in r["tension_N"].values()]
    if not errs:
        return
    m, sd = stats.mean_sd(errs)
    res["robust"]["levels"].append({
        "frac": frac, "table": "generated, simavr bench", "runs": n, "n": len(errs),
        "faults": n - len(ok), "mean_N": m, "sd_N": sd, "p5_N": stats.percentile(errs, 5),
        "p95_N": stats.percentile(errs, 95), "max_abs_N": max(abs(e) for e in errs)})


def bench_ambient(a, res: Dict, cfg: Dict, workdir: str, base: Dict) -> None:
    """Both target modes through the firmware: `set target_mode`, a first
    calibration (the absolute mode captures its ambient offsets there), every
    sensor's ambient changed by the same vector, a second calibration; the
    true tensions at the second run's homes. Change 0 is the control."""
    import random
    rng = random.Random(a.seed * 7 + 3)
    vecs = {}
    for mag in (0.0, 50.0, 100.0):
        v = [rng.gauss(0, 1) for _ in range(3)]
        n = math.sqrt(sum(x * x for x in v)) or 1.0
        vecs[mag] = [mag * x / n for x in v]
    t_change, t_second = base["done_t"] + 3.0, base["done_t"] + 4.0
    jobs, keys = [], []
    for mode in (0, 1):
        for mag, v in vecs.items():
            ev = [f"0.4s send set target_mode {mode}"]
            ev += [f"{t_change:.3f}s field {k} {v[0]:.2f} {v[1]:.2f} {v[2]:.2f}"
                   for k in range(cfg["n_sensors"]) if mag > 0]
            ev += [f"{t_second:.3f}s send cal"]
            jobs.append(dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config, seed=a.seed,
                             tension_mN=800, workdir=workdir, limit_s=t_second + a.sim_limit,
                             extra_events=ev, until=r"^<done .*count=2"))
            keys.append((mode, mag, v))
    log(f"simavr bench: {len(jobs)} runs of two calibrations with the ambient changed between")
    runs = simavr.batch(jobs, a.jobs)
    out = []
    for (mode, mag, v), r in zip(keys, runs):
        row = {"mode": "absolute" if mode else "field change", "dA_uT": mag, "vector_uT": v,
               "ok": r.get("ok", False)}
        if r.get("ok"):
            errs = [t - 0.8 for t in r["tension_N"].values()]
            row["mean_N"] = stats.mean_sd(errs)[0]
            row["max_abs_N"] = max(abs(e) for e in errs)
            d = [r["homes"][i] - base["homes"][i] for i in r["homes"] if i in base["homes"]]
            row["max_home_shift_ticks"] = max(abs(x) for x in d) if d else None
        else:
            row["error"] = r.get("error")
        out.append(row)
    res["ambient"]["bench"] = out


def _bench_rates(res: Dict, run: Dict, note: str = "") -> None:
    s = run.get("summary") or {}
    sim_s = s.get("sim_s") or 0.0
    r = res["resources"]
    if sim_s <= 0:
        return
    sens = s.get("twi", {}).get("sensors", [])
    r["sensor_rate_hz"] = [k.get("samples", 0) / sim_s for k in sens]
    servos = s.get("bus", {}).get("servos", [])
    if servos:
        r["servo_tx_hz"] = sum(x.get("instructions", 0) for x in servos) / len(servos) / sim_s
    r["bench_src"] = (f"simavr bench summary: counts / simulated time of a whole calibration run "
                      f"({sim_s:.1f} s including boot{', ' + note if note else ''})")


# ---- identification ------------------------------------------------------------------

# (label key, perturbation, stiffness spread or None, seeds in a full run, fits,
#  the description's friction in mN or None for the TOML's)
ID_FITS = ("survey", "weights", "tendons", "friction", "held")
ID_SETS = (
    ("5", 0.05, None, 20, ID_FITS, None),
    ("10s25", 0.10, 0.25, 20, ID_FITS, None),
    ("5nf", 0.05, None, 20, ("weights", "friction"), 0.0),
)


def _counter(label: str, total: int):
    """A progress logger: each call logs the next of `total` with the time
    since it was made."""
    t0, count = time.time(), [0]

    def step(msg: str) -> None:
        count[0] += 1
        log(f"{label} {count[0]}/{total}: {msg} [{time.time() - t0:.0f} s]")
    return step


def _inputs_missing(a, bench_use: str = "", elf_use: str = "") -> "str | None":
    """Why section 7 cannot be measured (a bench, firmware or description
    missing), or None."""
    if not (a.hh_bench and os.path.exists(a.hh_bench)):
        return f"no bench binary at {a.hh_bench}{bench_use}"
    if not (a.elf and os.path.exists(a.elf)):
        return f"no firmware ELF at {a.elf}{elf_use}"
    if not (a.robot and os.path.exists(a.robot)):
        return f"no robot description at {a.robot}"
    return None


def identify_item(a, res: Dict) -> None:
    """Section 7: the robot as built identified from a bench survey
    (hallhome.identify_eval): seeded perturbed robots, targets from the
    nominal TOML, from the survey-only fit and from the fit with one weight
    per segment, scored by their tension errors on the true robot."""
    why = _inputs_missing(a, " (it writes the surveys)",
                          " (hh_bench needs one, the survey does not run it)")
    if why:
        log(f"identification: {why}")
        res["identify"] = {"not_measured": why}
        return
    try:
        from hallhome.identify_eval import studies
    except ImportError as e:
        res["identify"] = {"not_measured": f"hallhome.identify_eval: {e}"}
        return
    n = a.id_seeds if a.id_seeds is not None else (1 if a.reduced else None)
    sets = [{"key": k, "perturb": p, "perturb_stiffness": ps, "modes": list(modes),
             "description_friction_mN": fr, "seeds": list(range(1, (n or full) + 1))}
            for k, p, ps, full, modes, fr in ID_SETS]
    if a.reduced:
        # the pipeline once (a survey, the fit with one weight per segment, its
        # targets and their errors): the other fits are the host and sim
        # suites' (tests/host/test_identify.py, tests/sim/test_identify_bench.py)
        sets = [dict(sets[0], modes=["weights"])]
    total = sum(len(st["seeds"]) for st in sets)
    log(f"identification: {total} seeded robots (a survey, two to four fits and tables each), "
        f"{a.jobs} at a time; a fit takes 5-60 s")
    t0 = time.time()
    progress = _counter("identification", total)
    out = studies(Path(a.robot), sets, a.id_weight_g, Path(a.hh_bench), Path(a.elf),
                  Path(a.config), log=progress, jobs=max(1, a.jobs))
    for st, o in zip(sets, out):
        o["key"] = st["key"]
    res["identify"] = {"sets": out, "weight_g": a.id_weight_g, "goals": stats.ID_GOALS,
                       "wall_s": time.time() - t0, "robot": a.robot}


# The board's own survey and held pulls (bench/held_board.py): (perturbation,
# stiffness spread, seeds in a full run)
BOARD_SET = (0.10, 0.25, 20)


def board_item(a, res: Dict) -> None:
    """Section 7, the board's part: the firmware's `survey` and `survey T H`
    runs on seeded robots of the set above, one weight per segment hung by the
    bench, the fit and its targets' errors, and the highest true tensions of
    those runs (bench/held_board.py)."""
    from . import held_board

    perturb, stiff, full = BOARD_SET
    n = a.board_seeds if a.board_seeds is not None else (0 if a.reduced else full)
    why = "skipped (--reduced or --board-seeds 0)" if n <= 0 else _inputs_missing(a)
    if why:
        log(f"the board's survey and held pulls: {why}")
        res["identify_board"] = {"not_measured": why}
        return
    seeds = list(range(1, n + 1))
    log(f"the board's survey and held pulls: {n} seeded robots at ±{100 * perturb:g} %, "
        f"stiffness ±{100 * stiff:g} % ({a.jobs} at a time; 30-60 s each)")
    t0 = time.time()
    step = _counter("board identification", n)

    def progress(r):
        e = np.array(r.get("errors", [[np.nan]]))
        step(f"seed {r['seed']}, runs {r.get('runs_done')}/{r.get('runs')}, worst |error| "
             f"{np.nanmax(np.abs(e)):.4f} N"
             + (f", refused: {r['refused']}" if r.get("refused") else ""))

    rig = held_board.Rig(bench=Path(a.hh_bench), fw=Path(a.elf), plant=Path(a.config),
                         toml=Path(a.robot))
    recs = held_board.study(seeds, perturb, stiff, jobs=max(1, a.jobs), rig=rig, log=progress)
    from hallhome.paths import LIB_DIR
    from hallhome.protocol import c_define
    from hallhome.robot import load_robot

    top_mN = 1000 * load_robot(a.robot).tension_grid[-1]
    # the bounded pull at the survey's top tension (design.md, docs/homing.md)
    bound_mN = 1.25 * top_mN + c_define(LIB_DIR / "homing" / "homing.h", "HOM_BOUND_MN")
    res["identify_board"] = dict(held_board.summary(recs, perturb, stiff),
                                 bound_mN=bound_mN, wall_s=time.time() - t0, records=recs)


# ---- main ----------------------------------------------------------------------------

def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--out", default="bench/results")
    p.add_argument("--reduced", action="store_true", help="a couple of runs per item")
    p.add_argument("--config", default="sim/plant/configs/paper_2seg.cfg")
    p.add_argument("--closedloop", default="build/bench/hh_closedloop")
    p.add_argument("--mc", default="build/bench/hh_mc")
    p.add_argument("--hh-bench", default="build/sim/hh_bench")
    p.add_argument("--elf", default="build/fw/paper_2seg/hallhome-paper_2seg.elf")
    p.add_argument("--dxl-bench", default="build/native/hh_dxl_bench")
    p.add_argument("--no-simavr", action="store_true")
    p.add_argument("--jobs", type=int, default=2, help="simavr runs at once")
    p.add_argument("--sim-limit", type=float, default=60.0, help="simulated s per calibration")
    p.add_argument("--mc-runs", type=int, default=500)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--robot", default="lookup_tables/robots/paper_2seg.toml",
                   help="robot description the identification fits (section 7)")
    p.add_argument("--id-seeds", type=int, default=None,
                   help="robots per identification set (default 20, reduced 1)")
    p.add_argument("--id-weight-g", type=float, default=80.0,
                   help="the survey's weight per segment (g)")
    p.add_argument("--no-identify", action="store_true", help="skip section 7")
    p.add_argument("--board-seeds", type=int, default=None,
                   help="robots of section 7's board survey and held pulls, which run the "
                   "firmware (default 20, reduced 0; --identify-from does not reuse them)")
    p.add_argument("--identify-from", default=None, metavar="RESULTS_JSON",
                   help="section 7 from an earlier run's results.json instead of measuring it "
                   "again (it depends on the host tools and the plant, not the firmware); "
                   "the report names that run")
    a = p.parse_args(argv)
    t0 = time.time()
    os.makedirs(a.out, exist_ok=True)
    previous = load_previous(os.path.join(a.out, "results.json"))
    cfg = native.read_cfg(a.config)
    try:
        git = subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=7"],
                             capture_output=True, text=True).stdout.strip()
    except OSError:
        git = "n/a"
    res: Dict = {
        "meta": {"date": datetime.datetime.utcnow().strftime("%Y-%m-%d %H:%M UTC"),
                 "git": git or "n/a", "config": a.config, "reduced": a.reduced, "elf": a.elf,
                 "mm_per_tick": cfg["nm_per_tick"] * 1e-6},
        "repeat": {}, "accuracy": {}, "time": {}, "resources": {}, "goal_notes": [],
    }
    native_items(a, res, cfg)
    table_diag_item(a, res)
    robust_item(a, res)
    ambient_item(a, res)
    size_item(a, res)
    if a.no_identify:
        res["identify"] = {"not_measured": "skipped (--no-identify)"}
    elif a.identify_from:
        with open(a.identify_from) as fh:
            earlier = json.load(fh)
        res["identify"] = dict(earlier.get("identify") or {"not_measured": "none in the file"})
        # the run that measured it (a results.json that took it over names that one)
        res["identify"].setdefault(
            "reused_from", {k: earlier.get("meta", {}).get(k) for k in ("git", "date")})
    else:
        identify_item(a, res)
    if a.no_identify:
        res["identify_board"] = {"not_measured": "skipped (--no-identify)"}
    else:
        board_item(a, res)
    res["resources"]["bus"] = native.dxl_bench(a.dxl_bench if os.path.exists(a.dxl_bench) else None)
    work = simavr.scratch_dir(os.path.join("build", "bench", "simavr"))
    try:
        simavr_items(a, res, cfg, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    res["goal_notes"] = goal_notes(res)
    if previous:
        res["previous"] = previous
    res["meta"]["wall_s"] = time.time() - t0
    log("drawing plots")
    plots.repeatability(res["repeat"], a.out)
    plots.accuracy(res["accuracy"], a.out)
    plots.timing(res["time"], a.out)
    plots.robustness(res["robust"], a.out)
    plots.ambient(res["ambient"], a.out)
    plots.identify(res.get("identify", {}), a.out, res.get("identify_board"))
    text = report.build_report(res)
    path = os.path.join(a.out, "report.md")
    with open(path, "w") as fh:
        fh.write(text)
    with open(os.path.join(a.out, "results.json"), "w") as fh:
        json.dump(res, fh, indent=1, default=float, allow_nan=True)
    for g in report.goals_table(res):
        log(f"goal {g['goal']}: {g['value']} ({g['limit']}) {g['status']} [{g['source']}]")
    log(f"wrote {path} in {time.time() - t0:.0f} s")
    problems = report.check_report(path)
    for pr in problems:
        log(f"report problem: {pr}")
    return 1 if problems else 0


def load_previous(path: str) -> Dict:
    """The goal figures of the run whose results are about to be replaced, for
    the report's comparison column (empty when there is none)."""
    try:
        with open(path) as fh:
            old = json.load(fh)
    except (OSError, ValueError):
        return {}
    m = old.get("meta", {})
    return {"date": m.get("date"), "git": m.get("git"), "firmware": m.get("firmware"),
            "goals": {g["goal"]: g["value"] + (f" ({g['source'].split(' (')[0]})")
                      for g in report.goals_table(old)}}


def goal_notes(res: Dict) -> List[str]:
    """Why a goal is met or missed, worded from the figures themselves."""
    notes = []
    tick = res["meta"]["mm_per_tick"]
    acc = res.get("accuracy", {})
    rep = res.get("repeat", {})

    def measured(d, k):
        r = d.get(k)
        return r if (r and not r.get("not_measured")) else None

    notes.append(
        f"One encoder tick is {tick * 1000:.2f} µm of tendon, worth roughly 8-17 mN of tension "
        "on this robot (device-facts): homes are whole ticks, so half a tick's worth is the "
        "floor of the tension error whatever the sensors do.")
    gen, plant = measured(acc, "native_gen"), measured(acc, "native")
    sim = measured(acc, "simavr")
    judged = sim or gen
    if judged and gen and plant:
        m = judged["all"]["mean_N"]
        verdict = "misses" if abs(m) > stats.GOALS["tension_err_mean_abs_N"] else "meets"
        rg = measured(rep, "native_gen") or {}
        rp = measured(rep, "native") or {}
        notes.append(
            f"Tension accuracy {verdict} the ±{stats.GOALS['tension_err_mean_abs_N']} N mean "
            f"goal with the generated table ({m:+.4f} N "
            f"{'on the simavr bench' if sim else 'in the native loop'}). The same homing core "
            f"in the native loop gives {gen['all']['mean_N']:+.4f} N with the generated table "
            f"(homes {fmt_t(rg.get('mean_err_ticks'))} ticks from the true home on average) and "
            f"{plant['all']['mean_N']:+.4f} N with targets recorded on the plant itself "
            f"({fmt_t(rp.get('mean_err_ticks'))} ticks), and the noise-free plant pulled to the "
            "generated targets already lands that far off (section 2): the bias is the "
            "generated table's model error (host Cosserat model against the plant's "
            "constant-curvature robot), not the firmware. Targets learned on the robot (the "
            "model-free workflow, `learn`; the plant table is its noise-free ideal) remove it; "
            "the bench has no way to hang a known weight on a tendon yet, so that path is "
            "measured in the native loop only.")
    rob = res.get("robust", {})
    lv = {round(l["frac"], 3): l for l in rob.get("levels", []) if l.get("table", "plant") == "plant"}
    if 0.05 in lv:
        l = lv[0.05]
        top = ", ".join(d["name"] for d in rob.get("ranking", [])[:3]) or "n/a"
        notes.append(
            f"With ±5 % parameter error against the table the tension error is "
            f"{l['mean_N']:+.3f} ± {l['sd_N']:.3f} N (largest drivers: {top}): the table's "
            "match to the robot, not the homing, sets the accuracy, as in the paper's "
            "(0.06 ± 0.20) N.")
    ts = (res.get("time", {}).get("simavr") or {})
    tn = (res.get("time", {}).get("native_gen") or {})
    if ts.get("full_s") and tn.get("full_s"):
        notes.append(
            f"A calibration takes {ts['full_s']:.1f} s on the simavr bench against "
            f"{tn['full_s']:.1f} s in the native loop, which assumes a servo answer every 1 ms "
            "and a first-order servo; the bench runs the firmware's bus schedule against the "
            "XL430 model.")
    r = res.get("resources", {})
    if r.get("flash_bytes") and r["flash_bytes"] > 65536:
        notes.append(f"Flash ({r['flash_bytes']} bytes) is over the project's 64 KB budget "
                     "(scripts/size.sh); the chip has 256 KB.")
    if r.get("ram_bytes") and r["ram_bytes"] > 4096:
        notes.append(f"Static RAM ({r['ram_bytes']} bytes) is over the project's 4 KB budget "
                     "(half the chip, the rest kept for the stack).")
    bb, bus = r.get("bench_bus") or {}, r.get("bus") or {}
    if bb.get("median_ms") and bus.get("sync_simavr_ms"):
        fine = ((bb.get("by_phase") or {}).get("engaged") or {}).get("median_ms")
        notes.append(
            f"The firmware reads the servo positions every {bb['median_ms']:.2f} ms (median) on "
            f"the bench, against {bus['sync_simavr_ms']:.2f} ms for a sync write plus sync read "
            "on the same simulated bus (hh_dxl_bench) and the native loop's 1 ms: a "
            "transaction advances one step per main-loop pass (docs/benchmarks.md item 6)"
            + (f"; in the fine approach every {fine:.2f} ms (median), against issue 14's "
               f"{report.FEEDBACK_GOAL_MS:g} ms: "
               + ("met" if fine <= report.FEEDBACK_GOAL_MS else "missed")
               if fine is not None else "") + ".")
    if r.get("loop_max_us") and r["loop_max_us"] > 10000:
        notes.append(f"The worst main-loop pass ({r['loop_max_us'] / 1000:.1f} ms) is longer "
                     "than a sensor period (10 ms at 100 Hz).")
    return notes


def fmt_t(v) -> str:
    return "n/a" if v is None else f"{v:+.1f}"


if __name__ == "__main__":
    sys.exit(main())
