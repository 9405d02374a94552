"""Targets identified from the board's survey with held pulls (`survey`, then
`survey T H`, run by the firmware on the virtual bench) and one weight per
segment hung by the bench, scored against the plant's truth
(docs/identify.md, "Held pulls on the board"). `make bench` runs it as part
of section 7 (bench/run.py, `board_item`); on its own:

    .venv/bin/python bench/held_board.py SEED [SEED ...] [--perturb 0.1]
        [--perturb-stiffness 0.25] [--jobs 2] [--out FILE.json] [--keep DIR]

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
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, List, Optional

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Rig:
    """What a board run needs: the bench, the firmware, the plant, the table's
    description."""
    bench: Path = ROOT / "build" / "sim" / "hh_bench"
    fw: Path = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
    plant: Path = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
    toml: Path = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"


def one(seed: int, perturb: float, stiff: float, tmp: Path, keep: Optional[Path] = None,
        rig: Rig = Rig()) -> dict:
    """One seeded robot: the board's survey and held pulls, the bench's weight
    records, the fit, and its targets' errors on the plant."""
    from hallhome import op_survey, survey_bench
    from hallhome.identify import fit
    from hallhome.identify_data import load_survey
    from hallhome.identify_eval import per_segment, tension_errors
    from hallhome.robot import load_robot

    robot = load_robot(rig.toml)
    opts = ["--plant", str(rig.plant), "--seed", str(seed), "--perturb", str(perturb),
            "--perturb-stiffness", str(stiff)]
    bench_json, log, out = tmp / "bench.json", tmp / "board.txt", tmp / "survey.json"
    subprocess.run([str(rig.bench), str(rig.fw), *opts, "--survey", str(bench_json),
                    "--survey-weight", "80"], check=True, capture_output=True)
    cmds = survey_bench.commands(str(rig.toml), True)
    summary = tmp / "summary.json"
    done = survey_bench.run([str(rig.bench), str(rig.fw), *opts, "--summary", str(summary)],
                            cmds, log)
    text = log.read_text()
    times = [int(m) for m in re.findall(r"<done mode=survey [^>]*time_ms=(\d+)", text)]
    if op_survey.main([str(log), str(bench_json), str(out)]) != 0:
        return {"seed": seed, "runs_done": done, "runs": len(cmds), "held": 0,
                "refused": "the board's runs gave no survey file"}
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
    if res.refused:
        # the user keeps the nominal targets (as section 7's other rows score it)
        rec["errors"] = tension_errors(robot, truth).tolist()
        rec["nominal_targets"] = True
    else:
        rec["errors"] = tension_errors(res.robot, truth).tolist()
        rec["held_shifts_um"] = [list(map(float, x[2:])) for x in res.held_shifts_um]
        rec["radius_err_pct"] = [
            100 * (res.value(f"radius{i}") / t["radius_mm"] - 1)
            for i, t in enumerate(truth["tendons"])] if "radius0" in [p.name for p in res.params] else None
    return rec


def _one_in_tmp(seed: int, perturb: float, stiff: float, keep: Optional[str], rig: Rig) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        return one(seed, perturb, stiff, Path(tmp), Path(keep) if keep else None, rig)


def study(seeds: List[int], perturb: float, stiff: float, jobs: int = 1,
          keep: Optional[str] = None, rig: Rig = Rig(),
          log: Callable[[dict], None] = lambda r: None) -> List[dict]:
    """``one`` per seed, ``jobs`` at once; ``log`` gets each record as it
    comes, the list comes back in the order of ``seeds``."""
    from hallhome.jobs import map_jobs

    return map_jobs(_one_in_tmp, [(s, perturb, stiff, keep, rig) for s in seeds], jobs,
                    lambda i, rec: log(rec))


def summary(recs: List[dict], perturb: float, stiff: float) -> Dict:
    """The set's figures, as section 7 of the report shows them: the error
    per test tension (a robot whose fit was refused with the nominal
    targets, as the user would keep them; one whose runs gave no survey
    file counted apart), the highest true tensions and the runs' times."""
    from hallhome.identify_eval import error_summary

    ok = [r for r in recs if "errors" in r]

    def span(key):
        """min and max of a figure over the records, a list per record or one"""
        v = [x for r in recs for x in (r.get(key) if isinstance(r.get(key), list)
                                       else [r.get(key)]) if x is not None]
        return {"min": min(v), "max": max(v)} if v else None

    def top(key):
        return (span(key) or {}).get("max")

    return {"seeds": [r["seed"] for r in recs], "perturb": perturb, "perturb_stiffness": stiff,
            "errors": error_summary([np.array(r["errors"]) for r in ok]) if ok else None,
            "refused": [{"seed": r["seed"], "why": r["refused"]} for r in recs if r.get("refused")],
            "runs_short": [r["seed"] for r in recs if r.get("runs_done") != r.get("runs")],
            "hold_peak_mN": top("hold_peaks_mN"), "pulled_peak_mN": top("pulled_peaks_mN"),
            "survey_peak_mN": top("survey_peak_mN"),
            "survey_alone_s": span("survey_alone_s"), "held_s": span("held_s"),
            "survey_s": span("survey_s"), "fit_s": span("fit_s")}


def print_record(r: dict) -> None:
    e = np.array(r.get("errors", [[np.nan]]))
    print(f"seed {r['seed']}: runs {r.get('runs_done')}/{r.get('runs')} held {r.get('held')} "
          f"survey {r.get('survey_s', float('nan')):.1f} s, fit {r.get('fit_s', float('nan')):.0f} s, "
          f"refused {r.get('refused')!r}; error mean {np.nanmean(e):+.4f} "
          f"sd {np.nanstd(e, ddof=1) if e.size > 1 else 0.0:.4f} "
          f"worst {np.nanmax(np.abs(e)):.4f} N; radius % "
          f"{np.round(r.get('radius_err_pct') or [], 2).tolist()}; "
          f"held tendons' peak {r.get('hold_peak_mN')} mN (per run "
          f"{r.get('hold_peaks_mN')}), pulled {r.get('pulled_peaks_mN')}, "
          f"survey alone {r.get('survey_peak_mN')} mN", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seeds", type=int, nargs="+")
    ap.add_argument("--perturb", type=float, default=0.1)
    ap.add_argument("--perturb-stiffness", type=float, default=0.25)
    ap.add_argument("--jobs", type=int, default=1, help="seeds at once")
    ap.add_argument("--out", default=None, help="every seed's record, as JSON")
    ap.add_argument("--keep", default=None, help="directory for each seed's survey, log and "
                    "bench summary")
    a = ap.parse_args()
    recs = study(a.seeds, a.perturb, a.perturb_stiffness, a.jobs, a.keep, log=print_record)
    if a.out:
        Path(a.out).write_text(json.dumps(recs, indent=1))
    s = summary(recs, a.perturb, a.perturb_stiffness)
    if s["errors"]:
        for k, v in s["errors"].items():
            print(f"{k if k == 'all' else k + ' N'}: n={v['n']} mean {v['mean']:+.4f} "
                  f"sd {v['sd']:.4f} worst {v['worst']:.4f} N")
    print(f"refused {len(s['refused'])}, runs short {s['runs_short']}; highest true tension: "
          f"held {s['hold_peak_mN']} mN, pulled {s['pulled_peak_mN']} mN, "
          f"survey alone {s['survey_peak_mN']} mN")
    return 0


if __name__ == "__main__":
    sys.exit(main())
