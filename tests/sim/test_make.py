"""Builds that cannot lie: every robot builds in build/fw/<robot>/ with its
own ELF and HEX, switching ROBOT= rebuilds what depends on it, a robot
without a table cannot be flashed, and unknown robots are named.

Robots are generated into a temporary ROBOTS_DIR / TABLES_DIR (copies of
paper_2seg under other names); their build directories are removed after.
"""

import os
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
HALLHOME = ROOT / ".venv" / "bin" / "hallhome"
PAPER = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"

# `make sim` and the files it keeps under build/ are shared: the tests that
# run it for real take turns (fresh_seed holds conftest.py's make_sim_lock);
# the others run `make -n`, fail before building, or build robots of their own.


def make(*args, check=None):
    r = subprocess.run(["make", "--no-print-directory", *map(str, args)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    r.out = r.stdout + r.stderr
    if check is not None:
        assert r.returncode == check, r.out
    return r


def fw_path(robot, *extra):
    r = make("-s", "fw-path", f"ROBOT={robot}", *extra, check=0)
    return r.stdout


def flash_image(hex_path: Path) -> bytes:
    """The flash content of an Intel HEX file (data records in file order)."""
    data = bytearray()
    for line in hex_path.read_text().splitlines():
        if line.startswith(":") and line[7:9] == "00":
            data += bytes.fromhex(line[9:9 + 2 * int(line[1:3], 16)])
    return bytes(data)


def name_in_flash(hex_path: Path, name: str) -> bool:
    """The table's name field: the robot name NUL-padded to TBL_NAME_LEN."""
    return name.encode() + b"\0" * (16 - len(name)) in flash_image(hex_path)


def test_fw_path_is_one_line_per_robot():
    assert fw_path("paper_2seg") == "build/fw/paper_2seg/hallhome-paper_2seg.elf\n"
    assert fw_path("trio_3seg") == "build/fw/trio_3seg/hallhome-trio_3seg.elf\n"
    assert make("fw-path", check=0).stdout == "build/fw/paper_2seg/hallhome-paper_2seg.elf\n"


def test_each_robot_compiles_into_its_own_directory_and_flashes_its_own_hex():
    r = make("-n", "-B", "firmware", "ROBOT=trio_3seg", check=0)
    main = [ln for ln in r.stdout.splitlines() if "firmware/main.c" in ln]
    assert len(main) == 1
    assert "-DHH_ROBOT=trio_3seg" in main[0]
    assert "-o build/fw/trio_3seg/avr/firmware/main.o" in main[0]
    assert "build/fw/trio_3seg/avr/table_trio_3seg.o" in r.stdout
    assert "paper_2seg" not in r.stdout
    r = make("-n", "flash", "ROBOT=trio_3seg", "PORT=/dev/null", check=0)
    assert "flash:w:build/fw/trio_3seg/hallhome-trio_3seg.hex:i" in r.stdout
    assert "paper_2seg" not in r.stdout
    r = make("-n", "size", "ROBOT=trio_3seg", check=0)
    assert "scripts/size.sh build/fw/trio_3seg/hallhome-trio_3seg.elf" in r.stdout


def test_unknown_robot_is_named_with_the_list_of_robots(tmp_path):
    for goal in ("sim", "firmware", "flash"):
        r = make(goal, "ROBOT=nosuch")
        assert r.returncode == 2, r.out
        assert "no robot 'nosuch'" in r.out and "No rule to make target" not in r.out
        assert "robots in lookup_tables/robots: paper_2seg trio_3seg" in r.out
    (tmp_path / "only_me.toml").write_text(PAPER.read_text())
    r = make("sim", "ROBOT=nosuch", f"ROBOTS_DIR={tmp_path}")
    assert r.returncode == 2 and f"robots in {tmp_path}: only_me" in r.out


def test_sim_refuses_a_robot_the_plant_cannot_model_before_building():
    r = make("sim", "ROBOT=trio_3seg")
    assert r.returncode == 2, r.out
    assert "supports straight tendon routing" in r.out
    assert "trio_3seg.toml: tendons[8].twist_deg_per_mm" in r.out
    assert "avr-gcc" not in r.out and "Traceback" not in r.out


@pytest.fixture
def robots(tmp_path):
    """Two copies of paper_2seg, mkbot_a (with a table) and mkbot_b (none
    yet), in a temporary ROBOTS_DIR / TABLES_DIR."""
    rd, td = tmp_path / "robots", tmp_path / "tables"
    rd.mkdir()
    names = ("mkbot_a", "mkbot_b")
    for n in names:
        (rd / f"{n}.toml").write_text(PAPER.read_text())
    subprocess.run([HALLHOME, "tables", "--quiet", "--out-dir", td, rd / "mkbot_a.toml"],
                   check=True)
    yield rd, td, (f"ROBOTS_DIR={rd}", f"TABLES_DIR={td}")
    for n in names:
        shutil.rmtree(ROOT / "build" / "fw" / n, ignore_errors=True)


@pytest.mark.slow(15)
def test_switching_robots_builds_each_with_its_own_table(robots):
    rd, td, dirs = robots
    elf_a = ROOT / fw_path("mkbot_a", *dirs).strip()
    hex_a, hex_b = elf_a.with_suffix(".hex"), ROOT / fw_path("mkbot_b", *dirs).strip()
    hex_b = hex_b.with_suffix(".hex")
    r = make("firmware", "ROBOT=mkbot_a", *dirs, check=0)
    assert f"robot mkbot_a, table {td}/mkbot_a.c" in r.out
    assert name_in_flash(hex_a, "mkbot_a")
    stamp = os.stat(elf_a).st_mtime_ns

    # a robot without a table builds, says so, and cannot be flashed
    r = make("firmware", "ROBOT=mkbot_b", *dirs, check=0)
    assert "NO TABLE" in r.out
    assert not name_in_flash(hex_b, "mkbot_a") and not name_in_flash(hex_b, "mkbot_b")
    r = make("flash", "ROBOT=mkbot_b", "PORT=/dev/null", *dirs)
    assert r.returncode == 2 and "has no table" in r.out and "avrdude" not in r.out
    assert os.stat(elf_a).st_mtime_ns == stamp  # the other robot's image untouched

    # back to mkbot_a: nothing to do
    r = make("firmware", "ROBOT=mkbot_a", *dirs, check=0)
    assert "avr-gcc" not in r.out and os.stat(elf_a).st_mtime_ns == stamp

    # mkbot_b's table appears after its objects were built: relinked with it
    subprocess.run([HALLHOME, "tables", "--quiet", "--out-dir", td, rd / "mkbot_b.toml"],
                   check=True)
    r = make("firmware", "ROBOT=mkbot_b", *dirs, check=0)
    assert f"table {td}/mkbot_b.c" in r.out and name_in_flash(hex_b, "mkbot_b")
    assert make("-n", "flash", "ROBOT=mkbot_b", "PORT=/dev/null", *dirs,
                check=0).stdout.count("avrdude") == 1

    # and a table that disappears relinks without it
    (td / "mkbot_a.c").unlink()
    r = make("firmware", "ROBOT=mkbot_a", *dirs, check=0)
    assert "NO TABLE" in r.out and not name_in_flash(hex_a, "mkbot_a")
    assert re.search(r"avr-gcc .* -o \S*hallhome-mkbot_a\.elf", r.out)

def test_sim_refuses_a_seed_or_tension_that_is_not_a_number():
    for var, bad, says in (("SEED", "N", "SEED takes a whole number, not 'N'"),
                           ("SEED", "-3", "SEED takes a whole number"),
                           ("TENSION", "1,2", "TENSION takes newtons")):
        r = make("sim", f"{var}={bad}", *(["SEED=3"] if var != "SEED" else []))
        assert r.returncode == 2 and says in r.out, r.out[-2000:]
        assert "+ build/sim/hh_bench" not in r.out and "[1/5]" not in r.out  # nothing ran



# --- make sim: identification before the calibration ------------------------------------

def _sim_files(tag):
    d = ROOT / "build" / "sim" / "identify" / f"paper_2seg-{tag}"
    return d, [ROOT / "build" / "sim" / "eeprom" / f"{r}-{tag}.eeprom"
               for r in ("paper_2seg", "paper_2seg_id")]


@pytest.fixture
def fresh_seed(make_sim_lock):
    """SEED=3 under its own perturbation tag (PERTURB=0.05, hh_bench's
    default: the same robot), so the identification and the EEPROM images
    are this test's own; removed after."""
    d, images = _sim_files("3-p0.05")

    def clean():
        shutil.rmtree(d, ignore_errors=True)
        for p in images:
            p.unlink(missing_ok=True)
    clean()
    yield d
    clean()


@pytest.mark.slow(40)
def test_sim_identifies_the_robot_then_calibrates_with_its_table(fresh_seed):
    r = make("sim", "SEED=3", "PERTURB=0.05")
    assert r.returncode == 0, r.out[-3000:]
    steps = [f"make sim: [{k}/5] " for k in range(1, 6)]
    pos = [r.out.find(s) for s in steps]
    assert all(p >= 0 for p in pos) and pos == sorted(pos), r.out[-3000:]
    assert "IDENTIFY=1 PERTURB=0.05" in r.out
    assert "fit done in" in r.out and "residual per weight" in r.out
    assert "[5/5] calibration with the paper_2seg_id table" in r.out
    assert re.search(r"<ready table=paper_2seg_id ", r.out)
    assert "--perturb 0.05" in r.out and "--eeprom build/sim/eeprom/paper_2seg_id-3-p0.05" in r.out
    assert re.search(r"^\s+5\s+6\s+\d+ .* pass$", r.stdout, re.M)
    d = fresh_seed
    for f in ("survey.json", "paper_2seg_id.toml", "fit.txt", "tables/paper_2seg_id.c",
              "plots/identify_residuals.png"):
        assert (d / f).exists(), f
    # the pulls are the firmware's own `survey`, the weights the bench's
    sv = json.loads((d / "survey.json").read_text())
    assert sv["source"] == "board survey, bench weights" and len(sv["weights"]) == 2
    # generated files go under build/, never into lookup_tables/
    assert not (ROOT / "lookup_tables" / "robots" / "paper_2seg_id.toml").exists()
    assert not (ROOT / "lookup_tables" / "generated" / "paper_2seg_id.c").exists()
    # the same robot again: survey and fit are kept, the firmware is up to date
    r = make("sim", "SEED=3", "PERTURB=0.05")
    assert r.returncode == 0, r.out[-3000:]
    assert "(kept: this robot was surveyed before)" in r.out
    assert "(kept from an earlier run of this robot" in r.out
    assert "avr-gcc" not in r.out


def test_sim_without_identification_and_fault_scenarios_use_the_nominal_table(fresh_seed):
    r = make("sim", "SEED=3", "PERTURB=0.05", "IDENTIFY=0")
    assert r.returncode == 0, r.out[-3000:]
    assert "IDENTIFY=0" in r.out and "[1/5]" not in r.out
    assert re.search(r"<ready table=paper_2seg ", r.out)
    assert not fresh_seed.exists()
    r = make("-n", "sim", "SEED=3", "FAULT=sensor_unplug", check=0)
    assert "sh sim/identify.sh" not in r.out and "IDENTIFY=0" in r.out
    r = make("-n", "sim", "SEED=3", "FAULT=sensor_unplug", "IDENTIFY=1", check=0)
    assert "sh sim/identify.sh" in r.out
    assert not fresh_seed.exists()  # a dry run runs nothing


@pytest.mark.slow(12)
def test_sim_calibrates_with_the_nominal_table_when_the_fit_is_refused(fresh_seed, tmp_path):
    """A fit refused (here by a stand-in for the venv's python that refuses
    every fit) is reported and the nominal table calibrates."""
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\n"
                    "case \"$*\" in *'identify fit'*) echo 'refused: for the test' >&2; "
                    "exit 1;; esac\n"
                    f"exec {ROOT / '.venv' / 'bin' / 'python'} \"$@\"\n")
    fake.chmod(0o755)
    r = make("sim", "SEED=3", "PERTURB=0.05", f"PY={fake}")
    assert r.returncode == 0, r.out[-3000:]
    assert "refused: for the test" in r.out
    assert "identification refused (reason above): calibrating with the nominal table" in r.out
    assert "[3/5]" not in r.out and "[4/5]" not in r.out
    assert "[5/5] calibration with the paper_2seg table" in r.out
    assert re.search(r"<ready table=paper_2seg ", r.out)
