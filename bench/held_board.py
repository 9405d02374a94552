"""Targets identified from the board's survey with held pulls (`survey`, then
`survey T H`, run by the firmware on the virtual bench) and one weight per
segment hung by the bench, scored against the plant's truth
(docs/identify.md, "Held pulls on the board").

    .venv/bin/python bench/held_board.py SEED [SEED ...] [--perturb 0.1]
        [--perturb-stiffness 0.25] [--out FILE.json] [--keep DIR]

Per seed: the tension error of every tendon's targets at 0.3, 0.8 and
1.5 N, each tendon's fitted routing radius against the plant's, the highest
true tension of the held and of the pulled tendon in each held run (the
bench's run_peaks_mN) and of any tendon in the survey alone, and the runs'
times on the board.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
TOML = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"


def one(seed: int, perturb: float, stiff: float, tmp: Path, keep: Path | None = None) -> dict:
    from hallhome import op_survey, survey_bench
    from hallhome.identify import fit
    from hallhome.identify_data import load_survey
    from hallhome.identify_eval import per_segment, tension_errors
    from hallhome.robot import load_robot

    robot = load_robot(TOML)
    opts = ["--plant", str(PLANT), "--seed", str(seed), "--perturb", str(perturb),
            "--perturb-stiffness", str(stiff)]
    bench_json, log, out = tmp / "bench.json", tmp / "board.txt", tmp / "survey.json"
    subprocess.run([str(BENCH), str(FW), *opts, "--survey", str(bench_json),
                    "--survey-weight", "80"], check=True, capture_output=True)
    cmds = survey_bench.commands(str(TOML), True)
    summary = tmp / "summary.json"
    done = survey_bench.run([str(BENCH), str(FW), *opts, "--summary", str(summary)], cmds, log)
    text = log.read_text()
    times = [int(m) for m in re.findall(r"<done mode=survey [^>]*time_ms=(\d+)", text)]
    assert op_survey.main([str(log), str(bench_json), str(out)]) == 0
    sv = per_segment(robot, load_survey(out, robot))
    t0 = time.monotonic()
    res = fit(robot, sv)
    fit_s = time.monotonic() - t0
    truth = sv.truth
    rec = {"seed": seed, "runs_done": done, "runs": len(cmds), "held": len(sv.held),
           "survey_s": sum(times) / 1e3, "survey_alone_s": times[0] / 1e3 if times else None,
           "held_s": [t / 1e3 for t in times[1:]], "fit_s": fit_s, "refused": res.refused}
    try:
        runs = json.loads(summary.read_text())["truth"]["run_peaks_mN"]
        pairs = [tuple(map(int, c.split()[1:])) for c in cmds[1:]]
        # each held run's highest true tension of its held and its pulled tendon
        rec["hold_peaks_mN"] = [runs[k][h] for k, (_, h) in enumerate(pairs, 1)]
        rec["pulled_peaks_mN"] = [runs[k][t] for k, (t, _) in enumerate(pairs, 1)]
        rec["hold_peak_mN"] = max(rec["hold_peaks_mN"])
        rec["survey_peak_mN"] = max(runs[0])
    except (OSError, KeyError, ValueError, IndexError) as e:
        rec["hold_peak_mN"] = None
        rec["summary_error"] = str(e)
    if keep is not None:
        keep.mkdir(parents=True, exist_ok=True)
        for f in (out, log, summary):
            (keep / f"seed{seed}_{f.name}").write_bytes(f.read_bytes())
    if not res.refused:
        rec["errors"] = tension_errors(res.robot, truth).tolist()
        rec["held_shifts_um"] = [list(map(float, x[2:])) for x in res.held_shifts_um]
        rec["radius_err_pct"] = [
            100 * (res.value(f"radius{i}") / t["radius_mm"] - 1)
            for i, t in enumerate(truth["tendons"])] if "radius0" in [p.name for p in res.params] else None
    return rec


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("seeds", type=int, nargs="+")
    ap.add_argument("--perturb", type=float, default=0.1)
    ap.add_argument("--perturb-stiffness", type=float, default=0.25)
    ap.add_argument("--out", default=None)
    ap.add_argument("--keep", default=None, help="directory for each seed's survey, log and "
                    "bench summary")
    a = ap.parse_args()
    recs = []
    for s in a.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            r = one(s, a.perturb, a.perturb_stiffness, Path(tmp),
                    Path(a.keep) if a.keep else None)
        recs.append(r)
        e = np.array(r.get("errors", [[np.nan]]))
        print(f"seed {s}: runs {r['runs_done']}/{r['runs']} held {r['held']} "
              f"survey {r['survey_s']:.1f} s, fit {r['fit_s']:.0f} s, refused {r['refused']!r}; "
              f"error mean {np.nanmean(e):+.4f} sd {np.nanstd(e, ddof=1):.4f} "
              f"worst {np.nanmax(np.abs(e)):.4f} N; radius % "
              f"{np.round(r.get('radius_err_pct') or [], 2).tolist()}; "
              f"held tendons' peak {r.get('hold_peak_mN')} mN (per run "
              f"{r.get('hold_peaks_mN')}), pulled {r.get('pulled_peaks_mN')}, "
              f"survey alone {r.get('survey_peak_mN')} mN", flush=True)
        if a.out:
            Path(a.out).write_text(json.dumps(recs, indent=1))
    e = np.array([r["errors"] for r in recs if "errors" in r])
    if e.size:
        print(f"all: n={e.size} mean {e.mean():+.4f} sd {e.std(ddof=1):.4f} "
              f"worst {np.abs(e).max():.4f} N")
        for n, T in enumerate((0.3, 0.8, 1.5)):
            v = e[:, :, n]
            print(f"  {T} N: mean {v.mean():+.4f} sd {v.std(ddof=1):.4f} "
                  f"worst {np.abs(v).max():.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
