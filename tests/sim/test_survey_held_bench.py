"""The board's held pulls on the virtual bench (`survey T H`, docs/identify.md
"Held pulls on the board"), sent as `hallhome identify survey` sends them
(hallhome.survey_bench) to the robot whose held tendon once went over the
bounded pull: paper_2seg at +-10 %, stiffness +-25 %, seed 8. Each run
completes with its hold reported and nothing stored; every tendon's true
tension stays within the survey's bounded pull, 1.25 x 1.5 N + 0.1 N, the
held ones included; each scan alone finds its tendon's engagement where the
plant has it; the held scan finds it moved by the bend. Two held runs, about
20 s simulated."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

import needs

from hallhome import survey_bench
from hallhome.identify_data import SCAN_SLACK_STEPS, engagement_ticks
from hallhome.op_survey import SurveyView, held_of, parse_report
from hallhome.robot import load_robot

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
TOML = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"
OPTS = ["--plant", str(PLANT), "--seed", "8", "--perturb", "0.1", "--perturb-stiffness", "0.25"]
RUNS = [(0, 1), (1, 0)]
BOUND_MN = 1.25 * 1500 + 100


# the module's bench run, shared by its tests (tests/conftest.py)
pytestmark = pytest.mark.slow(15)


@pytest.fixture(scope="module")
def held(tmp_path_factory):
    needs.built(BENCH, FW)
    d = tmp_path_factory.mktemp("held")
    log, summary = d / "board.txt", d / "summary.json"
    done = survey_bench.run([str(BENCH), str(FW), *OPTS, "--summary", str(summary)],
                            [f"survey {t} {h}" for t, h in RUNS], log)
    assert done == len(RUNS), log.read_text()[-3000:]
    text = log.read_text()
    runs = text.split("<progress state=start")[1:]
    views = []
    for run in runs:
        v = SurveyView(6, None, 3)
        for line in run.splitlines():
            r = parse_report(line)
            if r is not None:
                v.feed(r)
        views.append(v)
    return {"log": text, "runs": runs, "views": views,
            "summary": json.loads(summary.read_text())}


def test_held_runs_complete_report_the_hold_and_store_nothing(held):
    log = held["log"]
    assert "<fault" not in log and "<result" not in log
    holds = re.findall(r"<progress state=hold tendon=(\d+) id=\d+ pos=(-?\d+)>", log)
    assert [int(h) for h, _ in holds] == [h for _, h in RUNS]
    dones = re.findall(r"<done mode=survey [^>]*>", log)
    assert len(dones) == len(RUNS)
    # five eighths of the top grid tension, nothing counted
    assert all("tension_mN=937" in x and "count=0" in x for x in dones)


def test_every_tendon_stays_within_the_bounded_pull(held):
    peaks = held["summary"]["truth"]["run_peaks_mN"]
    assert len(peaks) == len(RUNS)
    for (t, h), run in zip(RUNS, peaks):
        print(f"survey {t} {h}: held tendon {run[h]:.0f} mN, pulled {run[t]:.0f} mN")
        assert max(run) <= BOUND_MN, run


def test_scans_find_the_engagement_and_its_shift(held):
    robot = load_robot(TOML)
    truth = {t["tendon"]: t["true_engagement_ticks"] for t in held["summary"]["tendons"]}

    def kink(steps, base):
        t = np.array([s[0] for s in steps], float)
        f = np.array([s[1] for s in steps], float)
        return engagement_ticks(t, (f - np.array(base)[None]) * 1e-8, robot.noise, offset=True,
                                slack_steps=SCAN_SLACK_STEPS)

    for (t, h), v in zip(RUNS, held["views"]):
        rec = held_of(v, {t: 1})
        assert (rec["tendon"], rec["hold_tendon"]) == (t, h)
        # standing points: several samples each, 2-4 ticks apart
        assert len(rec["free_steps"]) >= 12 and len(rec["steps"]) >= 12
        free = kink(rec["free_steps"], rec["free_baseline_cuT"])
        bent = kink(rec["steps"], rec["baseline_cuT"])
        print(f"survey {t} {h}: engagement alone {free:.2f} (plant {truth[t]:.2f}), "
              f"held {bent:.2f}")
        assert abs(free - truth[t]) <= 1.0
        # the bend moves the engagement back by 25-40 ticks on segment 1
        assert 20.0 <= free - bent <= 45.0
