"""The bench's side of identification (docs/identify.md): the `weight` event
(a known mass on a tendon at the spool side) and the `--survey` dump."""

import json
import math
import re
import subprocess
from pathlib import Path

import pytest

import needs

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
G = 9.80665


@pytest.fixture(scope="module", autouse=True)
def built():
    needs.built(BENCH, FW)


def run(tmp_path, *args):
    summary = tmp_path / "summary.json"
    proc = subprocess.run([str(BENCH), str(FW), "--summary", str(summary), *map(str, args)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    data = json.loads(summary.read_text()) if summary.exists() else None
    return proc, data


def sensor_fields(out):
    """{index: (bx, by, bz)} of every `<sensor ...>` report, in order of arrival."""
    reports = []
    for line in out.splitlines():
        m = re.search(r"<sensor index=(\d+) .*bx_uT=(\S+) by_uT=(\S+) bz_uT=(\S+)", line)
        if m:
            reports.append((int(m[1]), tuple(float(m[k]) for k in (2, 3, 4))))
    return reports


def test_weight_hangs_m_g_on_the_tendon_and_bends_the_robot(tmp_path):
    proc, s = run(tmp_path, "--plant", PLANT, "--limit", "2s", "--at", "1.0s send sensors",
                  "--at", "1.3s weight 3 80", "--at", "1.7s send sensors")
    assert proc.returncode == 0, proc.stderr
    tensions = [t["tension_now_mN"] for t in s["tendons"]]
    assert tensions[3] == pytest.approx(80e-3 * G * 1e3, abs=0.2)
    assert all(t == 0.0 for i, t in enumerate(tensions) if i != 3)
    assert s["tendons"][3]["max_tension_mN"] >= tensions[3]
    reports = sensor_fields(proc.stdout)
    assert len(reports) == 6
    before, after = dict(reports[:3]), dict(reports[3:])
    # the tip bends towards tendon 3 (0 deg, over sensor 0): sensor 0's field changes by
    # hundreds of uT, far beyond the noise, as with a servo pulling 0.78 N
    change = math.dist(before[0], after[0])
    assert change > 100.0


def test_weight_taken_off_lets_the_robot_go_straight(tmp_path):
    proc, s = run(tmp_path, "--plant", PLANT, "--limit", "2s", "--at", "1.0s send sensors",
                  "--at", "1.2s weight 3 80", "--at", "1.5s weight 3 0",
                  "--at", "1.8s send sensors")
    assert proc.returncode == 0, proc.stderr
    assert s["tendons"][3]["tension_now_mN"] == 0.0
    assert s["tendons"][3]["max_tension_mN"] == pytest.approx(784.5, abs=0.5)
    reports = sensor_fields(proc.stdout)
    before, after = dict(reports[:3]), dict(reports[3:])
    # the friction play may hold a few mN at the tip: a few uT at most, not hundreds
    assert math.dist(before[0], after[0]) < 10.0


@pytest.mark.parametrize("event", ["weight 0 -5", "weight 0", "weight 0 20000", "weight x 10"])
def test_bad_weight_events_are_usage_errors(tmp_path, event):
    proc, _ = run(tmp_path, "--plant", PLANT, "--limit", "1s", "--at", f"0.5s {event}")
    assert proc.returncode == 2, proc.stderr


def test_weight_on_a_missing_tendon_is_named_and_changes_nothing(tmp_path):
    proc, s = run(tmp_path, "--plant", PLANT, "--limit", "1s", "--at", "0.5s weight 9 50")
    assert proc.returncode == 0
    assert "no tendon 9" in proc.stderr
    assert all(t["tension_now_mN"] == 0.0 for t in s["tendons"])


def survey(tmp_path, *args, name="survey.json"):
    out = tmp_path / name
    proc = subprocess.run([str(BENCH), str(FW), "--plant", str(PLANT), "--survey", str(out),
                           *map(str, args)], capture_output=True, text=True, timeout=120, cwd=ROOT)
    return proc, out


def test_survey_records_what_the_firmware_sees(tmp_path):
    proc, out = survey(tmp_path, "--seed", 4, "--survey-weight", 80)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    assert d["format"] == "hallhome-survey" and d["field_unit"] == "cuT"
    assert [p["tendon"] for p in d["pulls"]] == list(range(6))
    for p in d["pulls"]:
        ticks = [s[0] for s in p["steps"]]
        assert all(isinstance(t, int) for t in ticks)
        assert all(b - a == d["step_ticks"] for a, b in zip(ticks, ticks[1:]))  # pull_dir +1
        first, last = p["steps"][0][1], p["steps"][-1][1]
        assert len(first) == 3 and all(len(v) == 3 for v in first)
        # slack at the start (the baseline's field), pulled at the end (a large change)
        assert math.dist(first[0], p["baseline_cuT"][0]) < 300  # 3 uT in cuT
        assert max(math.dist(a, b) for a, b in zip(last, p["baseline_cuT"])) > 5000
        # the safe bound: about the top grid tension (1.5 N), not beyond 2 N
        assert 1200 < p["max_tension_mN"] < 2000
    assert [w["tendon"] for w in d["weights"]] == [0, 3]
    for w in d["weights"]:
        assert w["mass_g"] == 80
        assert max(math.dist(a, b) for a, b in zip(w["field_cuT"], w["baseline_cuT"])) > 5000
    truth = d["truth"]
    assert len(truth["tendons"]) == 6 and len(truth["segment_len_mm"]) == 2
    assert len(truth["tendons"][0]["dB_uT"]) == len(truth["grid_mN"])


def test_survey_is_reproducible_and_follows_the_seed(tmp_path):
    _, a = survey(tmp_path, "--seed", 5, name="a.json")
    _, b = survey(tmp_path, "--seed", 5, name="b.json")
    _, c = survey(tmp_path, "--seed", 6, name="c.json")
    assert a.read_text() == b.read_text()
    assert json.loads(a.read_text())["truth"] != json.loads(c.read_text())["truth"]


def test_survey_needs_a_plant_and_a_writable_file(tmp_path):
    proc = subprocess.run([str(BENCH), str(FW), "--survey", str(tmp_path / "x.json")],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 2 and "--survey needs --plant" in proc.stderr
    proc, _ = survey(tmp_path / "missing" / "dir")
    assert proc.returncode == 2
    proc = subprocess.run([str(BENCH), str(FW), "--plant", str(PLANT), "--survey-travel", "0",
                           "--survey", str(tmp_path / "y.json")],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 2


@pytest.mark.slow(7)
def test_fit_of_a_bench_survey_beats_the_nominal_targets(tmp_path):
    """The plant is not the host's model (constant curvature with friction,
    a point dipole, backlash): the fit must still converge, stay near the
    truth and give better targets than the nominal description."""
    import numpy as np

    from hallhome.identify import fit
    from hallhome.identify_data import load_survey
    from hallhome.identify_eval import tension_errors, truth_values
    from hallhome.robot import load_robot

    proc, out = survey(tmp_path, "--seed", 3, "--survey-weight", 80)
    assert proc.returncode == 0, proc.stderr
    robot = load_robot(ROOT / "lookup_tables" / "robots" / "paper_2seg.toml")
    sv = load_survey(out, robot)
    res = fit(robot, sv)
    assert res.refused is None, res.refused
    truth = truth_values(robot, sv)
    assert res.value("magnet_J") == pytest.approx(truth["magnet_J"], rel=0.03)
    for i in range(6):
        assert res.value(f"engage{i}") == pytest.approx(truth[f"engage{i}"], abs=20.0)
    nominal = np.abs(tension_errors(robot, sv.truth))
    identified = np.abs(tension_errors(res.robot, sv.truth))
    assert identified.max() < 0.03 and identified.max() < nominal.max()
    assert identified.mean() < 0.5 * nominal.mean()


def test_stiffness_spread_moves_the_backbone_alone(tmp_path):
    """--perturb-stiffness scales the backbone's EI deviations (same draws),
    everything else stays the robot of --perturb."""
    _, a = survey(tmp_path, "--seed", 9, name="a.json")
    _, b = survey(tmp_path, "--seed", 9, "--perturb-stiffness", 0.25, name="b.json")
    _, c = survey(tmp_path, "--seed", 9, "--perturb-stiffness", 0.05, name="c.json")
    ta, tb = json.loads(a.read_text())["truth"], json.loads(b.read_text())["truth"]
    da, dc = json.loads(a.read_text()), json.loads(c.read_text())
    assert da == dc  # the same spread given twice: the same robot, the same survey
    nominal_ei = 2.9452431e-3  # the TOML's: 60 GPa, 1 mm rod
    for ea, eb in zip(ta["segment_ei_Nm2"], tb["segment_ei_Nm2"]):
        assert (eb / nominal_ei - 1) == pytest.approx(5 * (ea / nominal_ei - 1), abs=1e-4)
    assert ta["segment_len_mm"] == tb["segment_len_mm"]
    assert ta["magnet_moment_Am2"] == tb["magnet_moment_Am2"]
    assert [t["radius_mm"] for t in ta["tendons"]] == [t["radius_mm"] for t in tb["tendons"]]
    assert json.loads(b.read_text())["perturb_stiffness"] == 0.25
    for bad in ("1", "-0.1", "x"):
        proc, _ = survey(tmp_path, "--perturb-stiffness", bad, name="bad.json")
        assert proc.returncode == 2 and "--perturb-stiffness" in proc.stderr


def test_survey_weight_on_every_tendon(tmp_path):
    """--survey-weight-all: one record per tendon; those of each segment's
    first tendon are the records without it."""
    _, one = survey(tmp_path, "--seed", 4, "--survey-weight", 80, name="one.json")
    _, every = survey(tmp_path, "--seed", 4, "--survey-weight", 80, "--survey-weight-all",
                      name="every.json")
    w1, wa = json.loads(one.read_text())["weights"], json.loads(every.read_text())["weights"]
    assert [w["tendon"] for w in wa] == list(range(6))
    assert [w for w in wa if w["tendon"] in (0, 3)] == w1
    for w in wa:
        assert max(math.dist(a, b) for a, b in zip(w["field_cuT"], w["baseline_cuT"])) > 5000


@pytest.mark.slow(7)
def test_two_masses_per_segment_and_the_friction_they_give(tmp_path):
    """--survey-weight G,G2: each mass in turn on the same tendons, the first
    mass's records as with G alone; the fit finds the plant's friction from
    them, starting from a description that says there is none."""
    import dataclasses

    from hallhome.identify import fit
    from hallhome.identify_data import load_survey
    from hallhome.robot import load_robot

    _, one = survey(tmp_path, "--seed", 6, "--perturb", 0.05, "--survey-weight", 80,
                    name="one.json")
    _, two = survey(tmp_path, "--seed", 6, "--perturb", 0.05, "--survey-weight", "80,160",
                    name="two.json")
    w1, w2 = json.loads(one.read_text())["weights"], json.loads(two.read_text())["weights"]
    assert [(w["tendon"], w["mass_g"]) for w in w2] == [(0, 80.0), (0, 160.0), (3, 80.0),
                                                        (3, 160.0)]
    assert [w for w in w2 if w["mass_g"] == 80.0] == w1
    robot = load_robot(ROOT / "lookup_tables" / "robots" / "paper_2seg.toml")
    none = dataclasses.replace(robot, tendons=tuple(
        dataclasses.replace(t, friction_N=0.0) for t in robot.tendons))
    sv = load_survey(two, none)
    res = fit(none, sv)
    assert res.refused is None
    true = sum(t["friction_mN"] for t in sv.truth["tendons"]) / len(sv.truth["tendons"])
    assert res.value("friction") == pytest.approx(true, abs=3.0)
    for bad in ("80,", "80,160,240", "x", "-5", "80,,160"):
        proc, _ = survey(tmp_path, "--survey-weight", bad, name="bad.json")
        assert proc.returncode == 2 and "--survey-weight takes" in proc.stderr, bad


@pytest.mark.slow(15)
def test_held_pulls_give_each_tendons_radius(tmp_path):
    """--survey-held: every tendon pulled again from further back while the
    tendon of its segment 120 degrees off holds the bend of the top grid
    tension. On a robot built to 10 %, its stiffness to 25 % (seed 1: a
    tendon's radius 2.6 % off its weighted neighbour's), one weight per
    segment leaves a tendon 0.04 N off at 1.5 N: the survey cannot tell its
    radius from its stretch. With the held pulls, whose engagements the bend
    moved by their radius times the bend, every target is within 0.015 N."""
    import dataclasses

    import numpy as np

    from hallhome.identify import fit
    from hallhome.identify_data import load_survey
    from hallhome.identify_eval import per_segment, tension_errors
    from hallhome.robot import load_robot

    proc, out = survey(tmp_path, "--seed", 1, "--perturb", 0.1, "--perturb-stiffness", 0.25,
                       "--survey-weight", 80, "--survey-held")
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    seg = [0, 0, 0, 1, 1, 1]
    assert sorted(h["tendon"] for h in d["held"]) == list(range(6))
    for h in d["held"]:
        a, i = h["hold_tendon"], h["tendon"]
        assert a != i and seg[a] == seg[i]
        # the hold's tension stays within the bounded pull's 1.25 x 1.5 N + 0.1 N
        assert 1400 < h["hold_tension_mN"] < 1975
        free = next(p for p in d["pulls"] if p["tendon"] == i)
        assert h["steps"][0][0] < free["steps"][0][0]  # started further back
    robot = load_robot(ROOT / "lookup_tables" / "robots" / "paper_2seg.toml")
    sv = per_segment(robot, load_survey(out, robot))
    without = fit(robot, dataclasses.replace(sv, held=()))
    held = fit(robot, sv)
    assert without.refused is None and held.refused is None, (without.refused, held.refused)
    assert "radius" in [p.name for p in without.params]
    assert {f"radius{i}" for i in range(6)} <= {p.name for p in held.params}
    e_without = np.abs(tension_errors(without.robot, sv.truth)).max()
    e_held = np.abs(tension_errors(held.robot, sv.truth)).max()
    assert e_without > 0.03 and e_held < 0.015, (e_without, e_held)
    for i, t in enumerate(sv.truth["tendons"]):
        assert held.value(f"radius{i}") == pytest.approx(t["radius_mm"], rel=0.015)


def test_held_pulls_only_where_a_hold_bends_the_robot_across_the_tendon(tmp_path):
    """A 12-tendon robot of the chaos pool: segment 1 has three tendons at
    120 degrees (each held by one of the others), segment 2 four at 90
    degrees (a neighbour bends nothing along the tendon, the antagonist
    nothing across it: no held pull), segment 3 five at 72 degrees (each held
    by one 144 degrees off, the larger |cos| of the two allowed)."""
    out = tmp_path / "pool.json"
    proc = subprocess.run([str(BENCH), str(FW), "--plant",
                           str(ROOT / "sim" / "plant" / "configs" / "c3s12t3k9ccfb.cfg"),
                           "--seed", "2", "--survey", str(out), "--survey-weight", "80",
                           "--survey-held"], capture_output=True, text=True, timeout=300,
                          cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(out.read_text())
    angle = {i: t["angle_deg"] for i, t in enumerate(d["truth"]["tendons"])}
    held = {h["tendon"]: h["hold_tendon"] for h in d["held"]}
    assert sorted(held) == [0, 1, 2, 7, 8, 9, 10, 11]
    for i, a in held.items():
        off = abs((angle[a] - angle[i] + 180.0) % 360.0 - 180.0)
        assert off == pytest.approx(120.0 if i < 3 else 144.0, abs=6.0), (i, a, off)
        assert began_slack(d, i)


def began_slack(d, i):
    """The held pull of tendon i began slack: its first steps read its
    baseline."""
    h = next(x for x in d["held"] if x["tendon"] == i)
    return all(math.dist(a, b) < 300 for a, b in zip(h["steps"][0][1], h["baseline_cuT"]))
