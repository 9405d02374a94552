import subprocess
import sys

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
