"""The generator refuses designs the firmware cannot use (hallhome.usable):
one small robot that passes, and one variant per rule that breaks it. Each
refusal must name the file, the key and the limit; `--force` writes the
table anyway; `hallhome check` fails on the rules that need no model."""

import json
import re

import pytest
from click.testing import CliRunner

from hallhome.cli import main
from hallhome.paths import LIB_DIR
from hallhome.robot import load_robot
from hallhome.tablegen import generate
from hallhome.usable import (FirmwareLimitError, UnusableRobot, firmware_limits, header_constants,
                             robot_refusals, summarise)

# One segment, three tendons, three sensors on a ring 20 mm out and 15 mm
# above the tip: every target is about 180 sigma of the noise at 0.6 N.
BASE = """description = "one segment, three tendons: test fixture"

[[segments]]
length_mm = 60.0
disks = 4
youngs_modulus_GPa = 60.0
poisson_ratio = 0.33
outer_radius_mm = 0.5
density_kg_m3 = 6450.0
disk_mass_g = 0.2

[[tendons]]
segment = 1
routing_radius_mm = 4.5
routing_angle_deg = 0.0
servo_id = 1
pull_dir = 1
spool_radius_mm = 4.0
ticks_per_rev = 4096
stiffness_EA_N = 2000.0
free_length_mm = 150.0

[[tendons]]
segment = 1
routing_radius_mm = 4.5
routing_angle_deg = 120.0
servo_id = 2
pull_dir = 1
spool_radius_mm = 4.0
ticks_per_rev = 4096
stiffness_EA_N = 2000.0
free_length_mm = 150.0

[[tendons]]
segment = 1
routing_radius_mm = 4.5
routing_angle_deg = 240.0
servo_id = 3
pull_dir = 1
spool_radius_mm = 4.0
ticks_per_rev = 4096
stiffness_EA_N = 2000.0
free_length_mm = 150.0

[magnet]
shape = "cylinder"
diameter_mm = 3.5
length_mm = 3.0
polarization_T = [0.0, 0.0, 1.3]
offset_mm = [0.0, 0.0, 2.5]

[[sensors]]
position_mm = [20.0, 0.0, 75.0]
rotation_deg = [180.0, 0.0, 0.0]
mux_channel = 0
i2c_address = 0x69

[[sensors]]
position_mm = [-10.0, 17.32, 75.0]
mux_channel = 1
i2c_address = 0x69

[[sensors]]
position_mm = [-10.0, -17.32, 75.0]
mux_channel = 2
i2c_address = 0x69

[sensing]
noise_uT = 0.6

[gravity]
direction = [0.0, 0.0, -1.0]

[calibration]
tension_grid_N = [0.3, 0.6, 1.0]
default_tension_N = 0.6
travel_limit_mm = 2.5
"""

SENSOR_2 = "[-10.0, 17.32, 75.0]"


def write(tmp_path, name="base", *edits, extra=""):
    text = BASE
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    p = tmp_path / f"{name}.toml"
    p.write_text(text + extra)
    return p


def sensor(x, y, z, ch):
    return (f"\n[[sensors]]\nposition_mm = [{x}, {y}, {z}]\nmux_channel = {ch}\n"
            f"i2c_address = 0x69\n")


def tables(*args):
    return CliRunner().invoke(main, ["tables", *map(str, args)])


def refused(path):
    with pytest.raises(UnusableRobot) as exc:
        generate(path, path.parent / "out")
    assert not (path.parent / "out" / f"{path.stem}.c").exists()
    return exc.value.problems


def test_the_base_robot_is_usable_and_the_summary_gives_snr(tmp_path):
    p = write(tmp_path)
    res = tables("--out-dir", tmp_path / "out", p)
    assert res.exit_code == 0, res.output
    assert "tendon  servo  sensor  target at 0.6 N  SNR" in res.output
    rows = [ln.split() for ln in res.output.splitlines() if re.match(r"^\s+\d+\s+\d+\s+\d", ln)]
    assert [r[:3] for r in rows] == [["0", "1", "0"], ["1", "2", "1"], ["2", "3", "2"]]
    twin = json.loads((tmp_path / "out" / "base.json").read_text())
    for r, t in zip(rows, twin["human"]["tendons"]):
        target = float(r[3])
        assert target == pytest.approx(t["target_uT"][1], abs=0.05)  # 0.6 N is grid point 1
        assert float(r[5]) == pytest.approx(target / 0.6, abs=0.6)


def test_limits_are_read_from_the_firmware_headers(tmp_path):
    lim = firmware_limits()
    hom = header_constants(LIB_DIR / "homing" / "homing.h")
    tbl = header_constants(LIB_DIR / "table" / "table.h")
    assert lim.sensors.value == min(hom["HOM_MAX_SENSORS"], tbl["TBL_MAX_SENSORS"])
    assert lim.tendons.value == tbl["TBL_MAX_TENDONS"]
    assert lim.name_chars.value == tbl["TBL_NAME_LEN"] - 1
    # a different header gives a different limit: nothing is restated in Python
    for sub in ("homing", "table"):
        (tmp_path / sub).mkdir()
        text = (LIB_DIR / sub / f"{sub}.h").read_text()
        text = text.replace("#define HOM_MAX_SENSORS 4u", "#define HOM_MAX_SENSORS 2u")
        (tmp_path / sub / f"{sub}.h").write_text(text)
    small = firmware_limits(tmp_path)
    assert small.sensors.value == 2 and small.sensors.source.startswith("HOM_MAX_SENSORS in ")
    (tmp_path / "homing" / "homing.h").write_text("/* no limits here */\n")
    with pytest.raises(FirmwareLimitError, match="HOM_MAX_SENSORS"):
        firmware_limits(tmp_path)


def test_a_saturating_sensor_is_refused(tmp_path):
    p = write(tmp_path, "sat", (SENSOR_2, "[0.0, 0.0, 70.0]"))
    problems = refused(p)
    assert any(m.startswith("sat.toml: sensors[2].position_mm: the sensor saturates: ")
               and "above the AK09916's 4912 uT full scale" in m for m in problems), problems


def test_a_sensor_inside_the_robot_is_refused(tmp_path):
    p = write(tmp_path, "inside", (SENSOR_2, "[2.0, 0.0, 30.0]"))
    problems = refused(p)
    assert any(m.startswith("inside.toml: sensors[2].position_mm: the sensor is inside the "
                            "robot in the straight pose: 2.0 mm from the backbone")
               and "radius of 4.5 mm" in m for m in problems), problems


def test_a_sensor_within_the_bending_envelope_is_refused(tmp_path):
    # 6.5 mm beside the straight robot, but tendon 0 bends the tip 2.8 mm toward it
    p = write(tmp_path, "bend", (SENSOR_2, "[6.5, 0.0, 58.0]"))
    problems = refused(p)
    assert any(m.startswith("bend.toml: sensors[2].position_mm: the sensor is within the "
                            "robot's bending envelope (tendon 0 alone at ") for m in problems), \
        problems
    assert not any("straight pose: " in m for m in problems)


def test_more_sensors_than_the_firmware_supports_is_refused_before_the_model(tmp_path):
    p = write(tmp_path, "five", extra=sensor(0, 20, 75, 3) + sensor(0, -20, 75, 4))
    problems = refused(p)
    assert problems == ["five.toml: sensors: 5 sensors, the firmware supports at most 4 "
                        "(HOM_MAX_SENSORS in lib/homing/homing.h)"]
    four = write(tmp_path, "four", extra=sensor(0, 20, 75, 3))
    assert robot_refusals(load_robot(four), firmware_limits()) == []


def test_more_tendons_than_the_firmware_supports_is_refused(tmp_path):
    extra = "".join(f"\n[[tendons]]\nsegment = 1\nrouting_radius_mm = 4.5\n"
                    f"routing_angle_deg = {10 * k}.0\nservo_id = {10 + k}\npull_dir = 1\n"
                    f"spool_radius_mm = 4.0\nticks_per_rev = 4096\nstiffness_EA_N = 2000.0\n"
                    f"free_length_mm = 150.0\n" for k in range(10))
    p = write(tmp_path, "many", extra=extra)
    assert refused(p) == ["many.toml: tendons: 13 tendons, the firmware supports at most 12 "
                          "(TBL_MAX_TENDONS in lib/table/table.h)"]


def test_targets_below_ten_sigma_of_the_noise_are_refused(tmp_path):
    p = write(tmp_path, "noisy", ("noise_uT = 0.6", "noise_uT = 15.0"))
    problems = refused(p)
    assert len(problems) == 3
    assert problems[0].startswith("noisy.toml: tendons[1] (tendon 0, servo 1): target ")
    assert "below 10 x the sensing noise (150.00 uT, sensing.noise_uT = 15)" in problems[0]


@pytest.mark.parametrize("edit, key, hint", [
    (("length_mm = 60.0", "length_mm = 0.06"), "segments[1].length_mm: 0.06", "a value in m?"),
    (("youngs_modulus_GPa = 60.0", "youngs_modulus_GPa = 60e9"),
     "segments[1].youngs_modulus_GPa: 60000000000.0", "a value in Pa?"),
    (("spool_radius_mm = 4.0", "spool_radius_mm = 0.004"), "tendons[1].spool_radius_mm: 0.004",
     "a value in m?"),
    (("diameter_mm = 3.5", "diameter_mm = 3500.0"), "magnet.diameter_mm: 3500.0",
     "a value in um?"),
])
def test_implausible_units_are_refused_and_named(tmp_path, edit, key, hint):
    p = write(tmp_path, "units", edit)
    problems = refused(p)
    assert len(problems) == 1 and problems[0].startswith(f"units.toml: {key} is implausible")
    assert hint in problems[0]
    res = CliRunner().invoke(main, ["check", str(p)])
    assert res.exit_code == 1 and key in res.output


def test_a_name_longer_than_the_firmware_holds_fails_check_and_tables(tmp_path):
    p = write(tmp_path, "a_very_long_robot_name")
    res = CliRunner().invoke(main, ["check", str(p)])
    assert res.exit_code == 1
    assert ("a_very_long_robot_name.toml: file name: robot name 'a_very_long_robot_name' has 22 "
            "characters, the firmware holds at most 15 (TBL_NAME_LEN in lib/table/table.h")\
        in res.output
    res = tables("--out-dir", tmp_path / "out", p)
    assert res.exit_code == 1 and "has 22 characters" in res.output
    ok = CliRunner().invoke(main, ["check", str(write(tmp_path))])
    assert ok.exit_code == 0, ok.output


def test_cli_names_file_key_and_limit_and_force_writes_anyway(tmp_path):
    p = write(tmp_path, "noisy", ("noise_uT = 0.6", "noise_uT = 15.0"))
    res = tables("--out-dir", tmp_path / "out", p)
    assert res.exit_code == 1
    assert "the firmware cannot use this design (3 problem(s)); nothing written" in res.output
    assert "sensing.noise_uT = 15" in res.output
    assert not (tmp_path / "out" / "noisy.c").exists()
    res = tables("--force", "--out-dir", tmp_path / "out", p)
    assert res.exit_code == 0, res.output
    twin = json.loads((tmp_path / "out" / "noisy.json").read_text())
    assert sum(w.startswith("forced: noisy.toml: tendons[") for w in twin["warnings"]) == 3


def test_warnings_are_summarised_not_listed(tmp_path):
    msgs = [f"tendon {i} (servo {i + 1}, segment 1): expected travel {0.1 * i:.3f} mm at 1.5 N "
            f"exceeds the travel limit 0.050 mm" for i in range(6)]
    msgs += ["sensor 2 something else entirely"]
    out = summarise(msgs)
    assert len(out) == 2
    assert out[0].startswith("6 x (tendons 0, 1, 2, 3, 4, 5), e.g. tendon 0 (servo 1")
    assert out[1] == msgs[-1]
    # through the command: one line per kind however many tendons warn
    p = write(tmp_path, "short", ("travel_limit_mm = 2.5", "travel_limit_mm = 0.4"))
    res = tables("--out-dir", tmp_path / "out", p)
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.splitlines() if "warning:" in ln]
    assert len(lines) == 1 and lines[0].lstrip().startswith("warning: 3 x (tendons 0, 1, 2)")
    assert "3 warning(s), all listed in" in res.output
