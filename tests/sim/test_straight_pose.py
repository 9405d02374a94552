"""Straight-pose homes on the firmware (docs/homing.md, "Straight-pose
homes"): the final move, `home` and a power cycle's quick re-home go to the
straight-pose homes with `home_pose` 1 (the default) and to the
single-tendon homes with `home_pose` 0; both homes are reported and kept."""

import json
import re
import subprocess
from pathlib import Path

import pytest

import needs

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
RESULT = re.compile(r"<result tendon=(\d+) id=\d+ home=(-?\d+) straight=(-?\d+) ")
HOME = re.compile(r"<home tendon=(\d+) home=(-?\d+) straight=(-?\d+) rest=-?\d+ usable=1 now=(-?\d+)>")


def bench(tmp_path, *args, name="s"):
    summ = tmp_path / f"{name}.json"
    r = subprocess.run([BENCH, FW, "--plant", PLANT, "--seed", "5", "--perturb", "0",
                        "--summary", summ, *map(str, args)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr
    return r.stdout, json.loads(summ.read_text())


def goals(summary):
    return {t["tendon"]: t["goal_ticks"] for t in summary["tendons"]}


@pytest.fixture(scope="module", autouse=True)
def built():
    needs.built(BENCH, FW)


def test_final_move_and_home_go_to_the_chosen_homes(tmp_path):
    # calibrate, release, `home`: every goal is the reported straight-pose home
    out, s = bench(tmp_path, "--limit", "30s", "--at", "1s press 100",
                   "--at", "12s send release", "--at", "14s send home", "--at", "16s send status",
                   "--until", "^<home tendon=5 ", "--linger", "200ms")
    res = {int(t): (int(h), int(st)) for t, h, st in RESULT.findall(out)}
    assert sorted(res) == list(range(6))
    assert goals(s) == {i: st for i, (h, st) in res.items()}
    for i, (h, st) in res.items():
        # paid out on the release side: the segment-2 tendons about twice as far
        assert (20 < h - st < 80) if i < 3 else (60 < h - st < 130), (i, h, st)
    stored = {int(t): (int(h), int(st)) for t, h, st, _ in HOME.findall(out)}
    assert stored == res  # status lists both homes as the run reported them
    assert all(abs(t["tension_now_mN"] - 800.0) < 150.0 for t in s["tendons"]), s["tendons"]
    assert s["final_pose"]["tip_dev_mm"] < 0.5

    # home_pose 0: the final move and `home` go to the single-tendon homes,
    # and the robot holds several times the target
    out, s = bench(tmp_path, "--limit", "30s", "--at", "0.3s send set home_pose 0",
                   "--at", "1s press 100", "--at", "12s send release", "--at", "14s send home",
                   "--at", "16s send status", "--until", "^<home tendon=5 ", "--linger", "200ms",
                   name="single")
    res0 = {int(t): (int(h), int(st)) for t, h, st in RESULT.findall(out)}
    assert goals(s) == {i: h for i, (h, st) in res0.items()}
    assert all(t["tension_now_mN"] > 2000.0 for t in s["tendons"]), s["tendons"]
    assert all(abs(res0[i][0] - res[i][0]) <= 3 for i in res)  # the same homes measured


def test_quick_rehome_after_a_power_cycle_lands_on_the_same_straight_homes(tmp_path):
    img = tmp_path / "ee.img"
    args = ["--eeprom", img, "--limit", "40s", "--at", "1s press 100",
            "--until", "^<done mode=(full|quick)", "--linger", "500ms"]
    out1, s1 = bench(tmp_path, *args, name="full")
    assert "<done mode=full" in out1
    out2, s2 = bench(tmp_path, *args, name="quick")
    assert "<done mode=quick" in out2
    # the shaft positions (the plant's frame: the encoders lost their turns)
    # after both final moves, and the straight-pose tensions there
    for a, b in zip(s1["tendons"], s2["tendons"]):
        assert abs(a["shaft_ticks"] - b["shaft_ticks"]) <= 3, (a, b)
        assert abs(b["tension_now_mN"] - 800.0) < 150.0, b
