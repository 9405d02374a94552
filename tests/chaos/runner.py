"""Runs chaos schedules on the virtual bench and reports (docs/chaos.md).

    python -m tests.chaos run [-n N] [--seed0 S] [--jobs J]   N schedules
    python -m tests.chaos replay SEED                         one, console shown
    python -m tests.chaos seeds FILE                          the seeds listed in FILE
    python -m tests.chaos recheck [-n N] [--seed0 S]          the checks again on earlier runs
    python -m tests.chaos trace SEED TENDON --to S [--from S] a replayed schedule's bus, one
                                                              tendon's goals and positions

Each schedule's files go to build/chaos/runs/<seed>/: the script
(schedule.scn), the console log, the bench summary and the verdict. Seeds
that fail are added to tests/chaos/regression_seeds.txt.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from . import bustrace as bt
from . import check as chk
from . import robots as rb
from . import schedule as sc

ROOT = rb.ROOT
BENCH = ROOT / "build" / "sim" / "hh_bench"
RUNS = rb.BUILD / "runs"
REGRESSION = Path(__file__).with_name("regression_seeds.txt")


def bench_cmd(sch, robot, rundir: Path) -> list[str]:
    return [str(BENCH), str(robot.elf), "--plant", str(robot.plant), "--seed", str(sch.bench_seed),
            "--eeprom", str(rundir / "eeprom.bin"), "--timestamps", "--summary",
            str(rundir / "summary.json"), "--limit", f"{sch.limit_s:.0f}s",
            "--scenario", str(rundir / "schedule.scn")]


def run_one(seed: int, pool: list, echo: bool = False) -> dict:
    sch, robot = sc.generate(seed, pool)
    rb.build(robot)
    rundir = RUNS / str(seed)
    rundir.mkdir(parents=True, exist_ok=True)
    for stale in ("eeprom.bin", "summary.json"):
        (rundir / stale).unlink(missing_ok=True)
    (rundir / "schedule.scn").write_text(sch.script())
    cmd = bench_cmd(sch, robot, rundir)
    (rundir / "command.txt").write_text(shlex.join(cmd) + "\n")
    t0 = time.time()
    p = None
    for _ in range(2):  # once more when something outside killed the bench
        for stale in ("eeprom.bin", "summary.json"):
            (rundir / stale).unlink(missing_ok=True)
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        if p.returncode != 5:
            break
    (rundir / "console.txt").write_text(p.stdout)
    (rundir / "stderr.txt").write_text(p.stderr)
    (rundir / "wall_s.txt").write_text(f"{time.time() - t0:.3f}\n")
    if echo:
        sys.stdout.write(p.stdout)
    return judge(seed, pool)


def _reference_run(robot, sch, rundir: Path, name: str, presses: int) -> dict | None:
    """One undisturbed bench run of the schedule's robot: presses
    calibrations in one boot, each once the last has ended. What the
    summary holds is the last calibration's; None when there is none."""
    lines = [f"0 bus-noise {sch.base_noise}"] if sch.base_noise else []
    lines.append("step on ^<ready within 18s +0.3s press 100")
    lines += ["step on ^<(done|fault|released) within 18s +0.5s press 100"] * (presses - 1)
    scn = rundir / f"{name}.scn"
    scn.write_text("\n".join(lines) + "\n")
    summ = rundir / f"{name}-summary.json"
    summ.unlink(missing_ok=True)
    ends_re = "^<(done|fault|released)"
    cmd = [str(BENCH), str(robot.elf), "--plant", str(robot.plant), "--seed", str(sch.bench_seed),
           "--timestamps", "--summary", str(summ),
           "--limit", f"{presses * (10 + 3 * robot.tendons)}s", "--scenario", str(scn)]
    if presses == 1:
        cmd += ["--until", ends_re]
    else:  # the last calibration's end; the bench's --until takes the first
        cmd += ["--until", f"count={presses}>"]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    try:
        summary = json.loads(summ.read_text())
    except (OSError, ValueError):
        return None
    ends = [ln.split("] ", 1)[-1] for ln in p.stdout.splitlines()
            if "<done" in ln or "<fault" in ln or "<released" in ln]
    return {"end": ends[-1] if ends else "", "tendons": summary.get("tendons", [])}


def reference(seed: int, pool: list) -> dict | None:
    """Undisturbed calibrations of the schedule's robot with its bench seed
    and base bus noise: a press once the board is ready, nothing else
    ("tendons"), and a second run with two presses in one boot, the second
    once the first has ended ("repeat": a calibration after an earlier one
    of the same boot; on a robot whose field rises slowly at the home the
    two differ by a few ticks, seed 13335). What they achieve is what
    recovery must restore (docs/chaos.md). Kept in the run's folder with
    the firmware's hash, so a rebuilt firmware runs them again."""
    sch, robot = sc.generate(seed, pool)
    rundir = RUNS / str(seed)
    elf_hash = hashlib.sha1(Path(robot.elf).read_bytes()).hexdigest()[:12]
    path = rundir / "reference.json"
    if path.exists():
        try:
            ref = json.loads(path.read_text())
            if ref.get("elf_hash") == elf_hash and "repeat" in ref:
                return ref
        except ValueError:
            pass
    first = _reference_run(robot, sch, rundir, "reference", 1)
    if first is None:
        return None
    ref = {"elf_hash": elf_hash, **first, "repeat": _reference_run(robot, sch, rundir,
                                                                    "reference-repeat", 2)}
    path.write_text(json.dumps(ref, indent=1) + "\n")
    return ref


def judge(seed: int, pool: list) -> dict:
    """The verdict on a schedule run earlier, from its files (the checks may
    have changed since)."""
    sch, robot = sc.generate(seed, pool)
    rundir = RUNS / str(seed)
    out = (rundir / "console.txt").read_text()
    try:
        summary = json.loads((rundir / "summary.json").read_text())
    except (OSError, ValueError):
        err = (rundir / "stderr.txt").read_text() if (rundir / "stderr.txt").exists() else ""
        summary = {"exit_code": 2, "reason": "no summary: " + err[-300:]}
    try:
        wall = float((rundir / "wall_s.txt").read_text())
    except (OSError, ValueError):
        wall = 0.0
    verdict = chk.check(sch, summary, out)
    if any(k in verdict.violations for k in chk.NEEDS_REFERENCE):
        verdict = chk.check(sch, summary, out, reference(seed, pool))
    res = {"seed": seed, "robot": robot.describe(), "faults": sch.faults,
           "violations": verdict.violations, "figures": verdict.figures, "wall_s": wall,
           "sim_s": summary.get("sim_s", 0.0), "cpu_s": summary.get("cpu_s", 0.0), "timed_out_steps": summary.get("steps", {}).get(
               "timed_out", 0)}
    (rundir / "verdict.json").write_text(json.dumps(res, indent=1) + "\n")
    return res


def replay_line(seed: int) -> str:
    return f"make chaos-replay SEED={seed}"


def one_line(r: dict) -> str:
    inv = ", ".join(f"{k}: {v[0]}" + (f" (+{len(v) - 1})" if len(v) > 1 else "")
                    for k, v in r["violations"].items())
    return f"seed {r['seed']} [{r['robot']}] {inv}"


WORST = [("peak_ratio", "worst peak tension before home / target", "{:.2f}x (bound 1.25x + 0.1 N)"),
         ("release_ms", "worst release after a stop", "{:.1f} ms (bound 100 ms)"),
         ("baseline_max_mN", "highest tension during a baseline", "{:.1f} mN"),
         ("bus_gap_ms", "longest servo-bus silence in a run", "{:.1f} ms (bound 50 ms)"),
         ("max_start_slack_mm", "deepest slack at a run's start", "{:.2f} mm (bound per tendon: "
          f"the {chk.max_takeup_mm():.1f} mm search past its window, two releases and the margin)"),
         ("max_paid_out_mm", "most tendon paid out in one schedule", "{:.1f} mm"),
         ("final_err_pct", "worst final tension error", "{:.1f} % (bound 15 %, or 5 % of an "
          "undisturbed calibration's)"),
         ("final_vs_reference_pct", "worst final tension against an undisturbed calibration",
          "{:.1f} % of target")]


def report(results: list[dict], wall: float, jobs: int) -> int:
    faults = Counter(k for r in results for k, _ in r["faults"])
    phases = Counter(p for r in results for _, p in r["faults"])
    by_inv = Counter(k for r in results for k in r["violations"])
    failing = [r for r in results if r["violations"]]
    sim = sum(r["sim_s"] for r in results)
    print(f"\n=== chaos: {len(results)} schedules, {sum(faults.values())} faults injected, "
          f"{sum(len(v) for r in results for v in r['violations'].values())} invariant "
          f"violations in {len(failing)} schedules")
    cpu = sum(r.get("cpu_s", 0.0) for r in results)
    if jobs:
        print(f"time: {wall:.0f} s wall with {jobs} jobs ({wall / max(1, len(results)):.1f} s "
              "per schedule)")
    print(f"simulated {sim:.0f} s, bench CPU time {cpu:.0f} s ({cpu / max(1, len(results)):.1f} s "
          "per schedule)")
    print("faults by type:  " + ", ".join(f"{k} {v}" for k, v in sorted(faults.items())))
    print("faults by phase: " + ", ".join(f"{k} {v}" for k, v in sorted(phases.items())))
    print("schedules violating each invariant: " + (", ".join(
        f"{k} {v}" for k, v in sorted(by_inv.items())) or "none"))
    for key, text, fmt in WORST:
        vals = [r["figures"][key] for r in results if key in r["figures"]]
        if vals:
            worst = max(vals)
            # 1e9: a tendon that never read slack again
            print(f"  {text}: " + (fmt.format(worst) if worst < 1e9 else
                                   "never: a tendon stayed taut" + fmt[fmt.index(" ("):]))
    sent = sum(r["figures"].get("lines_sent", 0) for r in results)
    rep = sum(r["figures"].get("replies", 0) for r in results)
    print(f"  console: {sent:.0f} lines sent, {rep:.0f} final replies")
    beyond = [r["seed"] for r in results if r["figures"].get("beyond_table")]
    if beyond:
        print(f"  {len(beyond)} schedules on a robot and seed where an undisturbed calibration "
              "ends in the same fault (robot beyond its table): seeds "
              + ", ".join(map(str, beyond)))
    stalled = sum(1 for r in results if r["timed_out_steps"])
    if stalled:
        print(f"  {stalled} schedules waited out a step (a phase that never came)")
    if failing:
        print("\nfailing schedules (replay with the command shown):")
        for r in failing:
            print(f"  {one_line(r)}\n      {replay_line(r['seed'])}")
        old = set(load_seeds(REGRESSION)) if REGRESSION.exists() else set()
        new = [r["seed"] for r in failing if r["seed"] not in old]
        if new:
            with open(REGRESSION, "a") as f:
                for s in new:
                    f.write(f"{s}\n")
            print(f"{len(new)} new failing seed(s) added to {REGRESSION.relative_to(ROOT)}")
    return 1 if failing else 0


def load_seeds(path: Path) -> list[int]:
    return [int(ln.split("#")[0]) for ln in path.read_text().splitlines()
            if ln.split("#")[0].strip()]


def run_many(seeds: list[int], jobs: int, quiet: bool = False) -> list[dict]:
    pool = rb.pool()
    results = []
    with ThreadPoolExecutor(max_workers=jobs) as ex:
        futures = [ex.submit(run_one, s, pool) for s in seeds]
        for n, fut in enumerate(as_completed(futures), 1):
            r = fut.result()
            results.append(r)
            if not quiet:
                state = "ok" if not r["violations"] else "FAIL " + ",".join(r["violations"])
                print(f"[{n}/{len(seeds)}] seed {r['seed']}: {state} ({r['sim_s']:.0f} s sim, "
                      f"{r['wall_s']:.0f} s wall)", flush=True)
    return sorted(results, key=lambda r: r["seed"])


def trace(seed: int, tendon: int, t0: float, t1: float) -> int:
    """Runs the seed's bench command again up to t1 with --trace-bus and
    prints, from t0 on, the console and tendon's goals and positions."""
    rundir = RUNS / str(seed)
    cmdfile = rundir / "command.txt"
    if not cmdfile.exists():
        print(f"{cmdfile} missing: run `python -m tests.chaos replay {seed}` first",
              file=sys.stderr)
        return 2
    if t1 <= t0:
        print(f"--to {t1} is not after --from {t0}", file=sys.stderr)
        return 2
    cmd = shlex.split(cmdfile.read_text())
    plant = Path(cmd[cmd.index("--plant") + 1])
    ids = {}
    for ln in plant.read_text().splitlines():
        m = re.match(r"tendon\.(\d+)\.servo_id\s*=\s*(\d+)", ln.strip())
        if m:
            ids[int(m.group(1))] = int(m.group(2))
    if tendon not in ids:
        print(f"tendon {tendon}: the robot has tendons 0-{len(ids) - 1}", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        # a fresh EEPROM and summary, as the schedule's own run began
        for opt, name in (("--eeprom", "eeprom.bin"), ("--summary", "summary.json"),
                          ("--limit", None)):
            i = cmd.index(opt)
            cmd[i + 1] = f"{t1:.3f}s" if name is None else str(Path(tmp) / name)
        p = subprocess.run(cmd + ["--trace-bus"], capture_output=True, text=True, cwd=ROOT)
    trace_lines = p.stderr.splitlines()
    rows = [(e.t_s, (e.kind, e.addr), bt.describe(e))
            for e in bt.decode(trace_lines, tendon, ids[tendon])]
    rows += [(t, None, "console " + text) for t, text in chk.parse_console(p.stdout)]
    rows += [(t, None, text) for t, text in bt.noise(trace_lines)]
    last: dict = {}
    for t, key, text in sorted(rows, key=lambda r: r[0]):
        # a goal sent again each cycle, a position read unchanged: shown once
        if t0 <= t <= t1 and (key is None or last.get(key) != text):
            print(f"{t:10.5f}  {text}")
        if key is not None:
            last[key] = text
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.chaos", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("run", help="N schedules from seed0 on")
    a.add_argument("-n", type=int, default=20)
    a.add_argument("--seed0", type=int, default=1)
    a.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    b = sub.add_parser("replay", help="one schedule, console shown")
    b.add_argument("seed", type=int)
    d = sub.add_parser("recheck", help="check N earlier runs again (no bench run)")
    d.add_argument("-n", type=int, default=20)
    d.add_argument("--seed0", type=int, default=1)
    e = sub.add_parser("trace", help="one tendon's goals and positions on the bus, with the "
                       "console, in a window of a replayed schedule")
    e.add_argument("seed", type=int)
    e.add_argument("tendon", type=int)
    e.add_argument("--from", dest="t0", type=float, default=0.0, metavar="S",
                   help="window start, simulated seconds")
    e.add_argument("--to", dest="t1", type=float, required=True, metavar="S",
                   help="window end (the bench stops there)")
    c = sub.add_parser("seeds", help="the seeds listed in a file")
    c.add_argument("file", type=Path)
    c.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    args = ap.parse_args(argv)
    if not BENCH.exists():
        print(f"{BENCH} missing: run `make sim-build` first", file=sys.stderr)
        return 2
    t0 = time.time()
    if args.cmd == "replay":
        r = run_one(args.seed, rb.pool(), echo=True)
        rundir = RUNS / str(args.seed)
        print(f"\nschedule {rundir / 'schedule.scn'}; bench command in {rundir / 'command.txt'}")
        print("faults: " + ", ".join(f"{k}@{p}" for k, p in r["faults"]))
        print(one_line(r) if r["violations"] else f"seed {args.seed}: every invariant holds")
        for k, msgs in r["violations"].items():
            for m in msgs:
                print(f"  {k}: {m}")
        return 1 if r["violations"] else 0
    if args.cmd == "trace":
        return trace(args.seed, args.tendon, args.t0, args.t1)
    if args.cmd == "recheck":
        pool = rb.pool()
        seeds = [s for s in range(args.seed0, args.seed0 + args.n)
                 if (RUNS / str(s) / "console.txt").exists()]
        return report([judge(s, pool) for s in seeds], 0.0, 0)
    seeds = (list(range(args.seed0, args.seed0 + args.n)) if args.cmd == "run"
             else load_seeds(args.file))
    results = run_many(seeds, args.jobs)
    return report(results, time.time() - t0, args.jobs)
