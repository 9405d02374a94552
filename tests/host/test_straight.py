"""Straight-pose homes (hallhome.straight): the host's shifts against known
answers, and the proof on the plant (build/native/hh_straight): homes minus
the shifts leave every tendon near the target with the robot straight."""

import dataclasses
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hallhome.model import CosseratModel
from hallhome.paths import ROBOTS_DIR
from hallhome.plantcfg import write_plant_config
from hallhome.robot import load_robot
from hallhome.straight import (MODEL_STEPS, main, straight_pose, straight_shift_um,
                               straight_um_table, tolerance_ticks)
from hallhome.tablegen import compute

from test_model import tiny_robot_toml

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROBOTS_DIR / "paper_2seg.toml"
HH_STRAIGHT = ROOT / "build" / "native" / "hh_straight"


@pytest.fixture(scope="module")
def paper():
    return load_robot(PAPER)


@pytest.fixture(scope="module")
def paper_shifts(paper):
    return straight_shift_um(paper, paper.tension_grid)


def tiny(tmp_path, **kw):
    p = tmp_path / "tiny.toml"
    p.write_text(tiny_robot_toml(**kw))
    return load_robot(p)


def test_shape_and_reference_numbers(paper, paper_shifts):
    grid = np.array(paper.tension_grid)
    assert paper_shifts.shape == (6, len(grid))
    # device facts: about 37 um of path per 0.1 N for a tendon ending at
    # segment 1, 73 um at segment 2 (bending; compression takes a few um off),
    # per 0.1 N at the tendon's end: the spool's tension less the friction
    tip = np.array([paper.tip_tension(paper.tendons[0], t) for t in grid])
    assert np.all(tip < grid) and np.all(tip > 0.95 * grid - 0.011)
    per = paper_shifts / tip * 0.1
    assert np.all((per[:3] > 35.5) & (per[:3] < 37.5)), per[:3]
    assert np.all((per[3:] > 71.0) & (per[3:] < 74.0)), per[3:]


def test_symmetric_tendons_get_the_same_shift(paper_shifts):
    # three tendons 120 deg apart per segment, gravity along the backbone
    for seg in (paper_shifts[:3], paper_shifts[3:]):
        assert np.ptp(seg, axis=0).max() < 1e-3


def test_opposite_tendons_without_gravity(tmp_path):
    r = tiny(tmp_path, tendons=((1, 5.0, 0.0, 0.0), (1, 5.0, 180.0, 0.0)))
    s = straight_shift_um(r, [0.5, 1.0])
    assert abs(s[0, 0] - s[1, 0]) < 1e-6 and abs(s[0, 1] - s[1, 1]) < 1e-6
    assert s[0, 0] > 0


def test_monotone_in_tension(paper_shifts):
    assert np.all(np.diff(paper_shifts, axis=1) > 0)


def test_compression_term_is_the_backbone_under_every_tension(paper):
    p = straight_pose(paper, 0.8)
    # segment 1 carries all six tendons, segment 2 three
    ea = [s.axial_stiffness for s in paper.segments]
    length = [s.length for s in paper.segments]
    tip = paper.tip_tension(paper.tendons[0], 0.8)  # what reaches the robot
    assert tip == pytest.approx(0.8 * 0.98 - 0.010)
    seg1 = length[0] * 6 * tip / ea[0]
    seg2 = seg1 + length[1] * 3 * tip / ea[1]
    assert p.all_um[:3] == pytest.approx(seg1 * 1e6, rel=0.02)
    assert p.all_um[3:] == pytest.approx(seg2 * 1e6, rel=0.02)
    assert np.allclose(p.shift_um, p.single_um - p.all_um)
    assert p.tip_deviation_mm < 0.05  # balanced: every tendon at T keeps it straight


def test_shift_does_not_depend_on_tendon_stiffness(paper, paper_shifts):
    stiff = dataclasses.replace(paper, tendons=tuple(
        dataclasses.replace(t, stiffness_ea=t.stiffness_ea * 3.0) for t in paper.tendons))
    assert np.allclose(straight_shift_um(stiff, paper.tension_grid), paper_shifts, atol=1e-9)


def test_an_unbalanced_robot_is_not_straight_and_needs_no_shift(tmp_path):
    # one tendon: pulled alone or "all together" is the same pose
    r = tiny(tmp_path)
    p = straight_pose(r, 0.5)
    assert abs(p.shift_um[0]) < 1e-9
    assert p.tip_deviation_mm > 0.5


def test_int16_table_form(paper, paper_shifts):
    t = straight_um_table(paper, paper.tension_grid)
    assert t.dtype == np.int16 and np.array_equal(t, np.rint(paper_shifts))
    # about 730 um per newton at segment 2: 60 N would need 44 mm
    with pytest.raises(ValueError, match="tendon 3 at 60 N"):
        straight_um_table(paper, [0.8, 60.0])


def test_bad_tension_refused(paper):
    with pytest.raises(ValueError):
        straight_pose(paper, 0.0)
    with pytest.raises(ValueError):
        straight_shift_um(paper, [0.8, -0.1])


def test_tolerance_in_ticks(paper):
    m = CosseratModel(paper, MODEL_STEPS)
    one = tolerance_ticks(paper, 0.8, 0.05, m)
    common = tolerance_ticks(paper, 0.8, 0.05, m, common=True)
    # every tendon moving together: stretch and compression only, so close to
    # the tendon's own EA / (free + path) estimate; one tendon alone also bends
    # the robot (softer, more ticks)
    for i, t in enumerate(paper.tendons):
        k = t.stiffness_ea / (t.free_length + paper.segment_end(t.segment))
        stretch_only = 0.05 / k / t.metres_per_tick
        assert stretch_only < common[i] < 1.2 * stretch_only
        assert one[i] > 1.5 * common[i]
    assert one[0] == pytest.approx(1.69, abs=0.05) and one[3] == pytest.approx(2.43, abs=0.05)


def test_cli(capsys, tmp_path):
    assert main([str(PAPER), "--list"]) == 0
    vals = [float(v) for v in capsys.readouterr().out.strip().split(",")]
    assert len(vals) == 6 and vals[0] == pytest.approx(282.1, abs=0.5)
    assert main([str(PAPER), "-t", "0.3", "--tolerance", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "0.300" in out and "one tendon" in out and "all together" in out
    assert main([str(tmp_path / "none.toml")]) == 2
    assert main([str(PAPER), "-t", "0"]) == 2


# --- the proof on the plant ---------------------------------------------------------------

def hh_straight(*args):
    if not HH_STRAIGHT.exists():
        pytest.skip("build/native/hh_straight not built (make native-build)")
    return subprocess.run([str(HH_STRAIGHT), *map(str, args)], capture_output=True, text=True,
                          timeout=120)


def parse(out):
    rows = [ln.split(",") for ln in out.splitlines() if ln.startswith("tendon,")]
    pose = [ln.split(",") for ln in out.splitlines() if ln.startswith("pose,")][0]
    return ({k: np.array([float(r[c]) for r in rows]) for k, c in
             (("T_single", 10), ("T_straight", 11), ("T_alone", 12), ("err_ticks", 6))},
            [float(x) for x in pose[1:]])


@pytest.fixture(scope="module")
def paper_plant(tmp_path_factory, paper):
    return write_plant_config(paper, tmp_path_factory.mktemp("plant") / "paper.cfg",
                              compression=True)


@pytest.fixture(scope="module")
def paper_targets(paper):
    res = compute(paper)
    g = list(paper.tension_grid).index(0.8)
    return ([tr.delta[g, tr.selected] * 1e8 for tr in res.tendons],
            [tr.selected for tr in res.tendons])


def test_plant_field_homes_minus_shifts_are_straight_at_the_target(paper, paper_plant,
                                                                   paper_targets):
    shifts = straight_pose(paper, 0.8).shift_um
    targets, sensors = paper_targets
    r = hh_straight(paper_plant, "-t", 800, "--shift-um", ",".join(map(str, shifts)),
                    "--targets-cuT", ",".join(f"{t:.1f}" for t in targets),
                    "--sensors", ",".join(map(str, sensors)))
    assert r.returncode == 0, r.stderr
    t, (tip_single, tip_straight, tip_true, _) = parse(r.stdout)
    # today's final pose: every tendon at its single-tendon home, 4-7x the target
    assert np.all(t["T_single"] > 3.0)
    # the straight pose keeps what the calibration measured alone (its own
    # model and friction error) within 0.03 N, the tip within 0.5 mm
    assert np.all(np.abs(t["T_straight"] - t["T_alone"]) < 0.03), t
    assert np.all(np.abs(t["T_straight"] - 0.8) < 0.08), t
    assert tip_straight < 0.5 and tip_true < 0.01
    assert np.all(np.abs(t["err_ticks"]) < 2.0)


def test_plant_without_shifts_is_today_and_bad_input_is_refused(paper_plant):
    r = hh_straight(paper_plant, "-t", 800, "--shift-um", "0,0,0,0,0,0")
    assert r.returncode == 0, r.stderr
    t, _ = parse(r.stdout)
    assert np.allclose(t["T_straight"], t["T_single"], atol=1e-4)
    assert hh_straight(paper_plant, "-t", 800, "--shift-um", "1,2,3").returncode == 2
    assert hh_straight(paper_plant, "-t", 0, "--shift-um", "0,0,0,0,0,0").returncode == 2
    assert hh_straight(paper_plant, "-t", 800, "--shift-um", "0,0,0,0,0,0", "--targets-cuT",
                       "1,1,1,1,1,1").returncode == 2  # targets without sensors
    assert hh_straight(paper_plant, "-t", 800, "--shift-um", "0,0,0,0,0,0", "--targets-cuT",
                       "9e9,1,1,1,1,1", "--sensors", "0,0,0,0,0,0").returncode == 1
    assert math.isfinite(t["T_alone"][0])
