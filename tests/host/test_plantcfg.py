"""Plant configs from robot descriptions: the values the C plant reads, seeded
perturbation, refusals, and a closed-loop run of the C homing against the
written config (build/native/hh_closedloop, built by `make unit`)."""

import math
import re
import subprocess

import pytest

from hallhome.paths import PROJECT_ROOT, ROBOTS_DIR
from hallhome.plantcfg import PlantConfigError, plant_lines, write_plant_config
from hallhome.robot import load_robot

PAPER = ROBOTS_DIR / "paper_2seg.toml"
TOOL = PROJECT_ROOT / "build" / "native" / "hh_closedloop"


def parse(lines):
    out = {}
    for line in lines:
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        key, _, value = line.partition("=")
        out[key.strip()] = value.strip()
    return out


def nums(s):
    return [float(x) for x in s.split()]


def test_paper_values():
    r = load_robot(PAPER)
    kv = parse(plant_lines(r))
    assert kv["name"] == "paper_2seg"
    assert nums(kv["segment_len_mm"]) == pytest.approx([53.0, 53.0])
    assert nums(kv["segment_ei_Nm2"]) == pytest.approx([2.945e-3, 2.945e-3], rel=1e-3)
    assert float(kv["nm_per_tick"]) == pytest.approx(6135.9, abs=0.1)
    # m = J V / mu0 for the 3.5 x 3 mm, 1.3 T cylinder
    v = math.pi * 1.75e-3**2 * 3e-3
    assert float(kv["magnet_moment_Am2"]) == pytest.approx(1.3 * v / (4e-7 * math.pi))
    assert float(kv["magnet_offset_mm"]) == pytest.approx(2.5)
    # gravity as the host's model has it: backbone and six 0.2 g disks spread
    # along each segment, the magnet at its centre
    rod = math.pi * 0.5e-3**2 * 53e-3 * 6450.0 * 1e3
    assert nums(kv["segment_mass_g"]) == pytest.approx([rod + 1.2, rod + 1.2])
    assert float(kv["tip_mass_g"]) == pytest.approx(r.magnet.mass * 1e3)
    assert [int(x) for x in kv["grid_mN"].split()][0] == 200
    assert kv["default_mN"] == "800"
    assert float(kv["travel_limit_um"]) == pytest.approx(2500.0)
    assert float(kv["noise_uT"]) == pytest.approx(0.6)
    tendons = {int(m.group(1)) for k in kv if (m := re.match(r"tendon\.(\d+)\.", k))}
    sensors = {int(m.group(1)) for k in kv if (m := re.match(r"sensor\.(\d+)\.", k))}
    assert tendons == set(range(6)) and sensors == set(range(3))
    assert kv["tendon.3.segment"] == "2"
    # the plant stretches the free length only: path inside the robot added
    assert float(kv["tendon.3.free_len_mm"]) == pytest.approx(150.0 + 106.0)
    assert float(kv["tendon.0.free_len_mm"]) == pytest.approx(150.0 + 53.0)
    assert nums(kv["sensor.1.pos_mm"]) == pytest.approx([-11.0, 19.0526, 122.0])
    rot = nums(kv["sensor.0.rot"])  # 180 deg about x
    assert rot == pytest.approx([1, 0, 0, 0, -1, 0, 0, 0, -1], abs=1e-9)
    assert kv["sensor.2.addr"] == "0x69"


def test_perturbation_is_seeded():
    r = load_robot(PAPER)
    nominal = plant_lines(r, seed=5, perturb=0.0)
    assert nominal[2:] == plant_lines(r, seed=9, perturb=0.0)[2:]  # no perturbation: seed unused
    a = plant_lines(r, seed=5, perturb=0.05)
    assert a == plant_lines(r, seed=5, perturb=0.05)
    assert a != plant_lines(r, seed=6, perturb=0.05)
    ka, kn = parse(a), parse(nominal)
    ratio = float(ka["tendon.2.ea_N"]) / float(kn["tendon.2.ea_N"])
    assert ratio != 1.0 and abs(ratio - 1.0) <= 0.05
    for i in range(3):
        d = [x - y for x, y in zip(nums(ka[f"sensor.{i}.pos_mm"]), nums(kn[f"sensor.{i}.pos_mm"]))]
        assert max(abs(x) for x in d) <= 0.05
    with pytest.raises(PlantConfigError):
        plant_lines(r, perturb=-0.1)


def test_twisted_routing_refused():
    r = load_robot(ROBOTS_DIR / "trio_3seg.toml")
    if all(t.twist == 0.0 for t in r.tendons):
        pytest.skip("trio_3seg has no twisted tendon any more")
    with pytest.raises(PlantConfigError, match="twist"):
        plant_lines(r)


def run_tool(*args):
    if not TOOL.exists():
        pytest.fail(f"{TOOL} is missing: run `make unit` first (it builds hh_closedloop)")
    p = subprocess.run([str(TOOL), *map(str, args)], capture_output=True, text=True, timeout=300)
    summary = [line for line in p.stdout.splitlines() if line.startswith("summary,")]
    if not summary:
        return p, {}
    return p, dict(kv.split("=") for kv in summary[0].split(",")[1:])


def test_closed_loop_on_written_config(tmp_path):
    cfg = write_plant_config(load_robot(PAPER), tmp_path / "paper.cfg")
    p, s = run_tool(cfg, "-n", "2", "-s", "3", "-q")
    assert p.returncode == 0 and s, p.stdout + p.stderr
    assert s["faults"] == "0"
    # the table comes from this very plant: within a tick of the true home
    assert float(s["max_abs_err_ticks"]) <= 1.0
    homes = [line.split(",") for line in p.stdout.splitlines() if line.startswith("home,")]
    assert len(homes) == 12


def test_closed_loop_generated_table_model_error(tmp_path):
    """The host's Cosserat table against the PCC plant of the same robot:
    repeatable, with a tension error that stays small (model error)."""
    cfg = write_plant_config(load_robot(PAPER), tmp_path / "paper.cfg")
    p, s = run_tool(cfg, "-g", "paper_2seg", "-n", "2", "-s", "4", "-q")
    assert p.returncode == 0 and s, p.stdout + p.stderr
    assert s["faults"] == "0"
    assert abs(float(s["tension_err_mean_N"])) < 0.1


def test_plant_config_command_writes_the_same_file_as_the_function(tmp_path):
    from click.testing import CliRunner

    from hallhome.cli import main
    from hallhome.paths import ROBOTS_DIR
    from hallhome.plantcfg import write_plant_config
    from hallhome.robot import load_robot

    toml = ROBOTS_DIR / "paper_2seg.toml"
    out = tmp_path / "cli.cfg"
    result = CliRunner().invoke(main, ["plant-config", str(toml), str(out), "--seed", "7",
                                       "--perturb", "0.05"])
    assert result.exit_code == 0, result.output
    ref = write_plant_config(load_robot(toml), tmp_path / "ref.cfg", seed=7, perturb=0.05)
    assert out.read_text() == ref.read_text()


def test_plant_config_command_refuses_a_robot_the_plant_cannot_model(tmp_path):
    from click.testing import CliRunner

    from hallhome.cli import main
    from hallhome.paths import ROBOTS_DIR

    result = CliRunner().invoke(main, ["plant-config", str(ROBOTS_DIR / "trio_3seg.toml"),
                                       str(tmp_path / "x.cfg")])
    assert result.exit_code == 1
    assert "trio_3seg.toml" in result.output and not (tmp_path / "x.cfg").exists()
