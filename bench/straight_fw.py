"""Straight-pose homes measured on the firmware (make bench, section 8):
calibrations of the real ELF on the simavr bench at 0.3, 0.8 and 1.5 N, on
the nominal robot and on robots perturbed by ±5 %, with the final move to the
straight-pose homes (the default, `home_pose` 1). Per tendon, from the
bench's summary:

  alone     the tendon pulled alone to the single-tendon home it reported
            (the calibration's own error, the paper's figure);
  straight  the plant after the final move: every tendon at its
            straight-pose home together (what the user gets);
  paper     every tendon at its single-tendon home together, computed on the
            same plant from the same homes (`--straight-um` of zeros): the
            final pose under the paper's definition of a home.

The tip's distance from the all-slack pose is taken after the final move.
The table shifts come from the nominal description on every plant, so the
perturbed rows show what a robot that differs from its description gets.
"""

from __future__ import annotations

from typing import Dict, List

from . import native, simavr, stats

TENSIONS_MN = (300, 800, 1500)
TOL_N = 0.05
TIP_TOL_MM = 0.5
PERTURBED = "±5 %"


def _case_rows(run: Dict, target_N: float) -> Dict:
    s = run["summary"]
    tend = s.get("tendons", [])
    return {
        "alone": [t["tension_at_home_mN"] / 1000.0 - target_N for t in tend],
        "straight": [t["tension_now_mN"] / 1000.0 - target_N for t in tend],
        "paper": [t["tension_straight_mN"] / 1000.0 - target_N for t in tend
                  if t.get("tension_straight_mN", -1.0) >= 0.0],
        "tip_mm": s.get("final_pose", {}).get("tip_dev_mm"),
        "reported": all(t.get("home_reported") for t in tend),
    }


def measure(a, res: Dict, workdir: str, n_tendons: int, nominal_seeds: int,
            perturbed_seeds: int, log=print, label: str = "nominal") -> None:
    """Runs the calibrations (a: bench.run's arguments) and stores
    res["straight"]: one row per plant kind and tension; the nominal rows
    are named label and judged against the goal, the perturbed ones reported."""
    zeros = ",".join("0" for _ in range(n_tendons))
    jobs = []
    for t in TENSIONS_MN:
        for kind, n, frac in ((label, nominal_seeds, 0.0), (PERTURBED, perturbed_seeds, 0.05)):
            for k in range(n):
                jobs.append(dict(hh_bench=a.hh_bench, elf=a.elf, plant=a.config,
                                 seed=a.seed + 7000 + 10 * k + t, tension_mN=t, workdir=workdir,
                                 limit_s=a.sim_limit, perturb=frac,
                                 extra_args=["--straight-um", zeros], kind=kind))
    log(f"simavr bench: {len(jobs)} calibrations with the final move to the straight-pose homes")
    kinds = [j.pop("kind") for j in jobs]
    runs = simavr.batch(jobs, a.jobs)
    rows: List[Dict] = []
    for kind in (label, PERTURBED):
        for t in TENSIONS_MN:
            sel = [r for r, k in zip(runs, kinds) if k == kind and r["tension_mN"] == t]
            ok = [r for r in sel if r.get("ok")]
            cases = [_case_rows(r, t / 1000.0) for r in ok]
            row = {"kind": kind, "tension_mN": t, "runs": len(sel), "failed": len(sel) - len(ok),
                   "errors": [str(r.get("error"))[:160] for r in sel if not r.get("ok")][:2],
                   "unreported": sum(1 for c in cases if not c["reported"])}
            for key in ("alone", "straight", "paper"):
                v = [e for c in cases for e in c[key]]
                if v:
                    m, sd = stats.mean_sd(v)
                    row[key] = {"n": len(v), "mean_N": m, "sd_N": sd,
                                "min_N": min(v), "max_N": max(v),
                                "max_abs_N": max(abs(e) for e in v)}
            tips = [c["tip_mm"] for c in cases if c["tip_mm"] is not None]
            row["tip_max_mm"] = max(tips) if tips else None
            if "straight" in row:
                row["goal_met"] = (row["straight"]["max_abs_N"] <= TOL_N
                                   and row["tip_max_mm"] is not None
                                   and row["tip_max_mm"] <= TIP_TOL_MM)
            rows.append(row)
    res["straight"] = {"rows": rows, "tol_N": TOL_N, "tip_tol_mm": TIP_TOL_MM,
                       "nominal_seeds": nominal_seeds, "perturbed_seeds": perturbed_seeds}


def _range(d: Dict | None) -> str:
    if not d:
        return "n/a"
    return f"{d['mean_N']:+.3f} ({d['min_N']:+.3f} to {d['max_N']:+.3f})"


def section(res: Dict, title: str) -> List[str]:
    st = res.get("straight")
    out = [title, ""]
    if not st:
        out += [f"not measured: {res.get('meta', {}).get('simavr_status', 'no simavr runs')}", ""]
        return out
    out += [
        "The firmware on the simavr bench, final move to the straight-pose homes (`home_pose` 1, "
        "the default; method in docs/homing.md, \"Straight-pose homes\"). Tension errors in N, "
        "mean (lowest to highest) over every tendon of every run: **alone**, the tendon pulled "
        "alone to its single-tendon home (the calibration's own error); **straight pose**, the "
        "plant after the final move, every tendon at its straight-pose home; **paper's "
        "definition**, every tendon at its single-tendon home together (computed on the same "
        "plant from the same homes). The plants compress the backbone; the shifts come from the "
        f"nominal description. {st['nominal_seeds']} nominal and {st['perturbed_seeds']} "
        f"perturbed robots per tension; goal: straight pose within ±{st['tol_N']:g} N and tip "
        f"within {st['tip_tol_mm']:g} mm of straight.", "",
        "| robot | T (N) | runs (failed) | alone | straight pose | worst \\|error\\| straight "
        "| tip from straight, worst (mm) | paper's definition | goal |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in st["rows"]:
        if r["runs"] == 0:
            continue
        failed = f"{r['runs']} ({r['failed']})"
        worst = f"{r['straight']['max_abs_N']:.3f}" if r.get("straight") else "n/a"
        tip = f"{r['tip_max_mm']:.3f}" if r.get("tip_max_mm") is not None else "n/a"
        goal = ("met" if r.get("goal_met") else "missed") if r["kind"] != PERTURBED else "report"
        out.append(f"| {r['kind']} | {r['tension_mN'] / 1000:g} | {failed} | {_range(r.get('alone'))} "
                   f"| {_range(r.get('straight'))} | {worst} | {tip} | "
                   f"{_range(r.get('paper'))} | {goal} |")
    errs = [e for r in st["rows"] for e in r.get("errors", [])]
    if errs:
        out += ["", "Failed runs: " + "; ".join(errs[:3])]
    if any(r.get("unreported") for r in st["rows"]):
        out += ["", "Some runs' homes were not reported by the firmware: those tendons are "
                "judged at the servo's goal."]
    out.append("")
    return out


def _measure_pool(a, res: Dict, work: str) -> None:
    """Every robot of the chaos pool with friction declared: its table, plant
    and firmware built as the suite builds them, nominal plants only."""
    import types

    from tests.chaos import robots as rb
    rows: List[Dict] = []
    st: Dict = {}
    for r in rb.pool(friction=True):
        print(f"building {r.describe()}", flush=True)
        rb.build(r)
        sub: Dict = {}
        args = types.SimpleNamespace(**{**vars(a), "config": str(r.plant), "elf": str(r.elf)})
        measure(args, sub, work, r.tendons, a.nominal, 0, label=r.describe())
        st = sub["straight"]
        rows += [x for x in st["rows"] if x["runs"]]
    res["straight"] = {**st, "rows": rows}


def main(argv=None) -> int:
    """`python -m bench.straight_fw`: section 8 alone (the rest of `make
    bench` takes a quarter of an hour), written as markdown."""
    import argparse
    import os
    import shutil
    import types

    p = argparse.ArgumentParser(description=main.__doc__)
    p.add_argument("--hh-bench", default="build/sim/hh_bench")
    p.add_argument("--elf", default="build/fw/paper_2seg/hallhome-paper_2seg.elf")
    p.add_argument("--config", default="build/sim/plant/paper_2seg.cfg")
    p.add_argument("--nominal", type=int, default=3, help="nominal robots per tension")
    p.add_argument("--perturbed", type=int, default=5, help="±5 %% robots per tension")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--sim-limit", type=float, default=60.0)
    p.add_argument("--pool", action="store_true",
                   help="instead of --config: the chaos suite's eight random robots (1-3 "
                   "segments, 3-12 tendons, 1-4 sensors), their descriptions declaring the "
                   "plant's friction, --nominal plants each, built as the suite builds them")
    p.add_argument("--out", default=None, help="markdown file (default: standard output)")
    a = p.parse_args(argv)
    work = simavr.scratch_dir(os.path.join("build", "bench", "straight_fw"))
    res: Dict = {}
    try:
        if a.pool:
            _measure_pool(a, res, work)
        else:
            n = len(native.read_cfg(a.config)["segment"])
            measure(types.SimpleNamespace(**vars(a)), res, work, n, a.nominal, a.perturbed)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    text = "\n".join(section(res, "## Straight-pose homes on the firmware")) + "\n"
    if a.out:
        on = "the chaos pool (--pool)" if a.pool else f"`{a.config}`"
        with open(a.out, "w") as fh:
            fh.write(f"Generated by `python -m bench.straight_fw` on {on}.\n\n" + text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
