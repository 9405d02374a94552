"""The per-tendon table `make sim` prints (hh_bench --table): a result column
against the tolerance (judged at the single-tendon home the firmware
reported), every failing tendon named with the tolerance, the tensions after
the final move (by default to the straight-pose homes; with `home_pose` 0 to
the single-tendon homes) and of the straight pose computed from the homes
with --straight-um, with the tip's deviation from straight, and no table at
all for a run cut short."""

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
ROW = re.compile(r"^\s+\d+\s+\d+\s+-?\d+\s")


def bench(*args):
    r = subprocess.run([BENCH, FW, "--plant", PLANT, "--seed", "3", "--table", *map(str, args)],
                       capture_output=True, text=True, timeout=60)
    rows = [ln.split() for ln in r.stdout.splitlines() if ROW.match(ln)]
    return r, rows


def test_every_failing_tendon_is_named_with_the_tolerance():
    # 10 ms in, every tendon is still slack: all six fail
    r, rows = bench("--limit", "10ms", "--check-tension", "10")
    assert r.returncode == 1
    assert ("true tension outside 10 % of the 800 mN target at the home of tendons "
            "0, 1, 2, 3, 4, 5") in r.stderr
    assert len(rows) == 6 and all(row[-1] == "FAIL" for row in rows)
    header = [ln for ln in r.stdout.splitlines() if ln.startswith("tendon  id")]
    assert len(header) == 1 and header[0].split()[-1] == "result"


# hallhome.straight's shifts of paper_2seg at 0.8 N, as `make sim` passes them
# (python -m hallhome.straight lookup_tables/robots/paper_2seg.toml --list)
SHIFTS = subprocess.run(
    [str(ROOT / ".venv" / "bin" / "python"), "-m", "hallhome.straight",
     str(ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"), "--list"],
    capture_output=True, text=True, timeout=120, check=True, cwd=ROOT).stdout.strip()


def columns(r, rows, *names):
    header = [ln.split() for ln in r.stdout.splitlines() if ln.startswith("tendon  id")][0]
    return [[float(row[header.index(n)]) for row in rows] for n in names]


def test_passing_tendons_say_pass_and_without_a_tolerance_a_dash():
    r, rows = bench("--limit", "20s", "--at", "1s press 100", "--until", "^<done mode=full",
                    "--linger", "0", "--check-tension", "10", "--straight-um", SHIFTS)
    assert r.returncode == 0, r.stderr
    assert len(rows) == 6 and all(row[-1] == "pass" for row in rows)
    home, final, straight = columns(r, rows, "home_ticks", "T_final_mN", "T_straight_mN")
    # the final move went to the straight-pose homes: near the 800 mN target
    # (this plant is seed 3's, 5 % off the description the shifts come from:
    # 640-680 mN on the builds so far, and a home a tick apart moves the
    # straight pose's tensions by 15-30 mN), as the same shifts computed on
    # the plant from the reported homes
    assert all(abs(t - 800.0) < 200.0 for t in final), final
    assert all(abs(t - 800.0) < 200.0 for t in straight), straight
    assert all(abs(a - b) < 60.0 for a, b in zip(final, straight)), (final, straight)
    tips = re.findall(r"tip (\d+\.\d+) mm from straight", r.stdout)
    assert len(tips) == 2 and float(tips[0]) < 0.5 and float(tips[1]) < 0.5
    assert "T_home: the tendon alone at its single-tendon home" in r.stdout
    # the home column is the single-tendon home the firmware reported
    reported = [int(m) for m in re.findall(r"<result tendon=\d+ id=\d+ home=(-?\d+) ", r.stdout)]
    assert reported == home

    # home_pose 0: the paper's definition, every tendon at its single-tendon
    # home together, the robot straightened with several times the tension
    r, rows = bench("--limit", "20s", "--at", "0.3s send set home_pose 0", "--at", "1s press 100",
                    "--until", "^<done mode=full", "--linger", "0", "--check-tension", "10")
    assert r.returncode == 0, r.stderr
    assert len(rows) == 6 and all(row[-1] == "pass" for row in rows)
    home0, final0 = columns(r, rows, "home_ticks", "T_final_mN")
    assert all(3000.0 < t < 6500.0 for t in final0), final0
    assert all(abs(a - b) <= 3 for a, b in zip(home0, home)), (home0, home)  # same homes
    r, rows = bench("--limit", "10ms")
    assert r.returncode == 0 and len(rows) == 6 and all(row[-1] == "-" for row in rows)
    assert all(row[-2] == "-" for row in rows)  # no shifts: no straight pose
    assert "no straight-pose shifts given" in r.stdout
    r, _ = bench("--limit", "10ms", "--straight-um", "1,2,x")
    assert r.returncode == 2 and "bad --straight-um" in r.stderr
    r, _ = bench("--limit", "10ms", "--straight-um", "1,2,3")
    assert r.returncode == 2 and "has 3 values for 6 tendons" in r.stderr


def test_a_run_cut_short_prints_no_table():
    r, rows = bench("--limit", "50ms", "--until", "^<never", "--check-tension", "10")
    assert r.returncode == 3  # time limit before --until
    assert rows == [] and "-100.0" not in r.stdout
    assert "no table: the run ended before the calibration did (time limit)" in r.stdout
