import subprocess
import sys

import pytest

from click.testing import CliRunner

from hallhome import __version__
from hallhome.cli import main
from hallhome.paths import PROJECT_ROOT


def test_version_matches_version_file():
    expected = (PROJECT_ROOT / "VERSION").read_text().strip()
    result = CliRunner().invoke(main, ["--version"])
    assert result.exit_code == 0
    assert result.output.strip() == f"hallhome, version {expected}"
    assert __version__ == expected


def test_help_lists_purpose():
    result = CliRunner().invoke(main, ["--help"])
    assert result.exit_code == 0
    assert "tension calibration" in result.output


def test_unknown_subcommand_fails_with_message():
    result = CliRunner().invoke(main, ["no-such-command"])
    assert result.exit_code == 2
    assert "No such command" in result.output


def test_console_script_runs_as_module():
    out = subprocess.run([sys.executable, "-m", "hallhome", "--version"],
                         capture_output=True, text=True, check=True)
    assert "hallhome, version" in out.stdout


# --- characterize ----------------------------------------------------------------------

def _magnet_csv(tmp_path, robot_path, polarization, axis="equatorial"):
    """Fields the robot's own magnet model gives at |J| = polarization."""
    import numpy as np

    from hallhome.field import field_magnitude_at
    from hallhome.robot import Magnet, load_robot
    m = load_robot(robot_path).magnet
    j = np.array(m.polarization, float)
    m2 = Magnet(m.shape, m.dimensions, tuple(j / np.linalg.norm(j) * polarization), m.offset,
                m.rotation, m.mass)
    d_cm = np.linspace(1.0, 4.0, 10)
    b_uT = field_magnitude_at(m2, d_cm * 1e-2, axis) * 1e6
    p = tmp_path / "meas.csv"
    p.write_text("distance_cm,field_uT\n" + "".join(f"{d:.3f},{b:.4f}\n" for d, b in zip(d_cm, b_uT)))
    return p


def test_characterize_writes_the_fit_into_the_toml(tmp_path):
    import shutil

    from hallhome.paths import ROBOTS_DIR
    from hallhome.robot import load_robot
    toml = tmp_path / "paper_2seg.toml"
    shutil.copy(ROBOTS_DIR / "paper_2seg.toml", toml)
    data = _magnet_csv(tmp_path, toml, 1.1)
    png = tmp_path / "fit.png"
    r = CliRunner().invoke(main, ["characterize", str(data), "--robot", str(toml), "--write",
                                  "--plot", str(png)])
    assert r.exit_code == 0, r.output
    import re
    m = re.search(r"wrote polarization_T = \[(\S+), (\S+), (\S+)\]", r.output)
    assert m, r.output
    assert [abs(float(v)) for v in m.groups()[:2]] == [0.0, 0.0]
    assert float(m.group(3)) == pytest.approx(1.1, abs=0.002)
    assert load_robot(toml).magnet.polarization[2] == pytest.approx(1.1, abs=0.002)
    text = toml.read_text()
    assert "# Magnet:" in text and "offset_mm = [0.0, 0.0, 2.5]" in text  # the rest kept
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_characterize_fails_and_writes_nothing_when_the_model_contradicts(tmp_path):
    import shutil

    from hallhome.paths import ROBOTS_DIR, TABLES_DIR
    toml = tmp_path / "paper_2seg.toml"
    shutil.copy(ROBOTS_DIR / "paper_2seg.toml", toml)
    before = toml.read_text()
    r = CliRunner().invoke(main, ["characterize", str(TABLES_DIR / "examples" / "paper_fig1_synthetic.csv"),
                                  "--robot", str(toml), "--write", "--plot", str(tmp_path / "f.png")])
    assert r.exit_code == 1
    assert "does not explain these data" in r.output and "nothing written" in r.output
    assert toml.read_text() == before
    r = CliRunner().invoke(main, ["characterize", str(TABLES_DIR / "examples" / "paper_fig1_synthetic.csv"),
                                  "--write"])
    assert r.exit_code == 2 and "--write needs --robot" in r.output


def test_readme_lists_every_command():
    text = (PROJECT_ROOT / "README.md").read_text()
    for name in main.commands:
        assert f"`hallhome {name}" in text, name
