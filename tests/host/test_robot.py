"""Robot TOML loader: the shipped robots load, every error case names the
file, the key and what was expected."""

import math
import re

import pytest

from hallhome.paths import ROBOTS_DIR
from hallhome.robot import RobotError, load_robot, robot_files

PAPER = ROBOTS_DIR / "paper_2seg.toml"


def test_shipped_robots_load():
    names = [p.stem for p in robot_files()]
    assert "paper_2seg" in names and "trio_3seg" in names
    for p in robot_files():
        r = load_robot(p)
        assert r.name == p.stem


def test_paper_robot_in_si_units():
    r = load_robot(PAPER)
    assert len(r.segments) == 2 and len(r.tendons) == 6 and len(r.sensors) == 3
    assert r.length == pytest.approx(0.106)
    # device-facts reference: 1 mm NiTi, E 60 GPa -> EI = 2.945e-3 N m^2
    assert r.segments[0].bending_stiffness == pytest.approx(2.945e-3, rel=1e-3)
    # the paper's 0.0061 mm per tick
    assert r.tendons[0].metres_per_tick * 1e3 == pytest.approx(0.0061, abs=5e-5)
    assert r.tendons[0].routing_radius == pytest.approx(4.5e-3)
    assert r.tendons[3].routing_angle == pytest.approx(0.0)
    assert r.magnet.dimensions[0] == pytest.approx(3.5e-3)
    assert r.gravity == pytest.approx((0.0, 0.0, -9.80665))
    assert r.default_tension == 0.8 and r.tension_grid[0] == 0.2
    assert r.noise == pytest.approx(0.6e-6)
    assert r.sensors[0].mux_channel == 0 and r.sensors[0].i2c_address == 0x69


def test_trio_robot_has_four_tendon_segment_and_direct_sensor():
    r = load_robot(ROBOTS_DIR / "trio_3seg.toml")
    per_seg = [sum(t.segment == k for t in r.tendons) for k in (1, 2, 3)]
    assert per_seg == [4, 3, 3]
    assert r.tendons[7].twist == pytest.approx(math.radians(0.5) * 1e3)
    assert r.sensors[3].mux_channel is None
    assert r.magnet.shape == "sphere"


def _variant(tmp_path, pattern, repl, count=1, name="paper_2seg.toml"):
    text = PAPER.read_text()
    new, n = re.subn(pattern, repl, text, count=count, flags=re.M)
    assert n >= 1, pattern
    path = tmp_path / name
    path.write_text(new)
    return path


ERROR_CASES = [
    # (pattern, replacement, expected message fragment)
    (r"^disks = 6$", "disks = 6\ncolour = \"red\"",
     "paper_2seg.toml: segments[1].colour: unknown key"),
    (r"^description = .*$", "description = \"x\"\nwheels = 4",
     "paper_2seg.toml: wheels: unknown key"),
    (r"^length_mm = 53.0\n", "",
     "paper_2seg.toml: segments[1].length_mm: expected a positive length in mm (missing)"),
    (r"^length_mm = 53.0$", "length_mm = -53.0",
     "paper_2seg.toml: segments[1].length_mm: expected a positive length in mm, got -53.0"),
    (r"^outer_radius_mm = 0.5$", "outer_radius_mm = 0.0",
     "segments[1].outer_radius_mm: expected a positive radius in mm, got 0.0"),
    (r"^inner_radius_mm = 0.0$", "inner_radius_mm = 0.7",
     "segments[1].inner_radius_mm: expected a radius in mm below outer_radius_mm (0.5), got 0.7"),
    (r"^poisson_ratio = 0.33$", "poisson_ratio = 0.7",
     "segments[1].poisson_ratio: expected a Poisson ratio in 0..0.5, got 0.7"),
    (r"^segment = 1$", "segment = 3",
     "paper_2seg.toml: tendons[1].segment: expected the number of an existing segment, 1..2, "
     "got 3"),
    (r"^servo_id = 2$", "servo_id = 1",
     "paper_2seg.toml: tendons[2].servo_id: expected a servo ID not used by another tendon "
     "(tendons[1] already uses it), got 1"),
    (r"^pull_dir = 1$", "pull_dir = 0",
     "tendons[1].pull_dir: expected +1 (increasing ticks shortens the tendon) or -1, got 0"),
    (r"^pull_dir = 1\n", "", "tendons[1].pull_dir: expected +1 or -1 (missing)"),
    (r"^spool_radius_mm = 4.0$", "spool_radius_mm = -4.0",
     "tendons[1].spool_radius_mm: expected a positive radius in mm, got -4.0"),
    (r"^stiffness_EA_N = 2000.0$", "stiffness_EA_N = \"stiff\"",
     "tendons[1].stiffness_EA_N: expected a positive axial stiffness EA in N, got 'stiff'"),
    (r"^free_length_mm = 150.0$", "free_length_mm = -1.0",
     "tendons[1].free_length_mm: expected a length >= 0 in mm, got -1.0"),
    (r"^mux_channel = 1$", "mux_channel = 0",
     "paper_2seg.toml: sensors[2].mux_channel: expected a mux channel no other sensor uses "
     "(sensors[1] is already on mux channel 0), got 0"),
    (r"^mux_channel = 2$", "mux_channel = 8",
     "sensors[3].mux_channel: expected a TCA9548A channel 0..7 or \"none\", got 8"),
    (r"^i2c_address = 0x69$", "i2c_address = 0x0C",
     "sensors[1].i2c_address: expected an ICM-20948 address, 0x68 or 0x69, got 12"),
    (r"^position_mm = \[22.0, 0.0, 122.0\]$", "position_mm = [22.0, 0.0]",
     "sensors[1].position_mm: expected [x, y, z] in mm in the base frame, got [22.0, 0.0]"),
    (r"^shape = \"cylinder\"$", "shape = \"torus\"",
     "magnet.shape: expected \"cylinder\", \"cuboid\" or \"sphere\", got 'torus'"),
    (r"^polarization_T = .*$", "polarization_T = [0.0, 0.0, 0.0]",
     "magnet.polarization_T: expected [Jx, Jy, Jz] in tesla, magnet frame, |J| < 2 T, got"),
    (r"^direction = \[0.0, 0.0, -1.0\]$", "direction = \"down\"",
     "gravity.direction: expected [x, y, z] (not all zero) or \"none\", got 'down'"),
    (r"^tension_grid_N = .*$", "tension_grid_N = [0.5, 0.4, 0.8]",
     "calibration.tension_grid_N: expected at least 2 strictly increasing tensions in N"),
    (r"^default_tension_N = 0.8$", "default_tension_N = 2.0",
     "calibration.default_tension_N: expected a tension in N inside the grid [0.2, 1.5], "
     "got 2.0"),
    (r"^travel_limit_mm = 2.5$", "travel_limit_mm = -1",
     "calibration.travel_limit_mm: expected a positive travel in mm, got -1"),
    (r"^mode = \"delta\"$", "mode = \"sometimes\"",
     "calibration.mode: expected \"delta\" or \"absolute\", got 'sometimes'"),
    (r"^\[sensing\]\nnoise_uT = 0.6$", "[sensing]\nnoise_uT = -0.6",
     "sensing.noise_uT: expected a positive 1-sigma noise in uT, at most 100, got -0.6"),
    (r"^\[gravity\]\ndirection = .*$", "",
     "paper_2seg.toml: gravity: expected a [gravity] table with direction"),
]


@pytest.mark.parametrize("pattern,repl,message", ERROR_CASES,
                         ids=[c[2].split(": ")[1] if ": " in c[2] else c[2]
                              for c in ERROR_CASES])
def test_error_names_file_key_and_expectation(tmp_path, pattern, repl, message):
    path = _variant(tmp_path, pattern, repl)
    with pytest.raises(RobotError) as exc:
        load_robot(path)
    assert message in str(exc.value), str(exc.value)


def test_every_problem_is_reported(tmp_path):
    text = PAPER.read_text().replace("length_mm = 53.0", "length_mm = -1.0")
    text = text.replace("servo_id = 6", "servo_id = 5")
    path = tmp_path / "paper_2seg.toml"
    path.write_text(text)
    with pytest.raises(RobotError) as exc:
        load_robot(path)
    probs = exc.value.problems
    assert sum("length_mm" in p for p in probs) == 2
    assert any("tendons[6].servo_id" in p for p in probs)


def test_invalid_toml_and_bad_name(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("[[segments]\nlength_mm = 1")
    with pytest.raises(RobotError, match=r"broken.toml: not valid TOML"):
        load_robot(bad)
    named = tmp_path / "2-bad name.toml"
    named.write_text(PAPER.read_text())
    with pytest.raises(RobotError, match=r"file name: expected a C identifier"):
        load_robot(named)
    with pytest.raises(FileNotFoundError):
        load_robot(tmp_path / "missing.toml")


def test_gravity_none_and_direct_sensors(tmp_path):
    text = PAPER.read_text().replace("direction = [0.0, 0.0, -1.0]", 'direction = "none"')
    text = text.replace("mux_channel = 0\n", 'mux_channel = "none"\n')
    path = tmp_path / "paper_2seg.toml"
    path.write_text(text)
    r = load_robot(path)
    assert r.gravity is None and r.sensors[0].mux_channel is None
    # two direct sensors on one address collide
    text2 = text.replace("mux_channel = 1\n", 'mux_channel = "none"\n')
    path.write_text(text2)
    with pytest.raises(RobotError, match=r"sensors\[2\].mux_channel: .*direct bus at address "
                                         r"0x69"):
        load_robot(path)
