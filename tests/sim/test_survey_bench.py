"""The identification survey on the board (`survey`, docs/identify.md
"Survey on the board") on the virtual bench: what it streams, that it
stores nothing and ends released, that a stop during it is recovered from,
and `hallhome identify survey` end to end with `hallhome identify fit`."""

import json
import math
import os
import re
import subprocess
import time
from pathlib import Path

import pytest

import needs

from hallhome.identify_data import load_survey
from hallhome.op_survey import from_log, parse_report, parse_sample
from hallhome.paths import LIB_DIR
from hallhome.protocol import c_define
from hallhome.robot import load_robot

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "build" / "sim" / "hh_bench"
FW = ROOT / "build" / "fw" / "paper_2seg" / "hallhome-paper_2seg.elf"
PLANT = ROOT / "sim" / "plant" / "configs" / "paper_2seg.cfg"
TOML = ROOT / "lookup_tables" / "robots" / "paper_2seg.toml"
HALLHOME = ROOT / ".venv" / "bin" / "hallhome"
TOP_MN = 1500  # paper_2seg's top grid tension
# the survey's tension, every tendon's target: a share of the top (app_priv.h)
SURVEY_MN = TOP_MN * c_define(LIB_DIR / "app" / "app_priv.h", "APP_SURVEY_EIGHTHS") // 8
BOUND_MN = 1.25 * TOP_MN + c_define(LIB_DIR / "homing" / "homing.h", "HOM_BOUND_MN")


@pytest.fixture(scope="module", autouse=True)
def built():
    needs.built(BENCH, FW)


def run(tmp_path, *args):
    summary = tmp_path / "summary.json"
    proc = subprocess.run([str(BENCH), str(FW), "--plant", str(PLANT), "--seed", "7",
                           "--summary", str(summary), *map(str, args)],
                          capture_output=True, text=True, timeout=180, cwd=ROOT)
    return proc, json.loads(summary.read_text())


def samples(out):
    """(tendon, ticks, [[x, y, z] per sensor]) of every <sv> line."""
    got = []
    for line in out.splitlines():
        rep = parse_report(line)
        if rep is not None and rep.kind == "sv":
            t, smp = parse_sample(rep, 3)
            got.append((t, smp.ticks, smp.b))
    return got


def test_survey_streams_every_tendon_stores_nothing_and_ends_released(tmp_path):
    proc, s = run(tmp_path, "--limit", "30s", "--at", "1s send survey",
                  "--at", "step on ^<done.mode=survey +300ms send history",
                  "--at", "step +300ms power-cycle", "--at", "step on ^<ready +100ms send history")
    out = proc.stdout
    assert proc.returncode == 0, proc.stderr
    assert "<done mode=survey" in out and "<fault" not in out
    assert re.search(rf"<progress state=start mode=full tension_mN={SURVEY_MN}\b", out)
    got = samples(out)
    for i in range(6):
        mine = [g for g in got if g[0] == i]
        # a fit needs 8; how many lines a pull gets depends on where its
        # take-up handed over to the survey's approach: 39-96 for tendon 1
        # of this seed over builds of the same logic whose code layout
        # differs (the passes' timing moves), at the top grid tension; 35-63
        # per tendon at the survey's three quarters of it
        assert len(mine) >= 24, f"tendon {i}: {len(mine)} samples"
        ticks = [g[1] for g in mine]
        assert ticks[-1] - ticks[0] > 100  # from slack through the engagement
        # the pulled tendon moves the field of its segment far beyond the noise
        first, last = mine[0][2], mine[-1][2]
        assert max(math.dist(a, b) for a, b in zip(first, last)) > 3000  # cuT
    # bounded pull at the top grid tension, and every tendon slack at the end
    for t in s["tendons"]:
        assert t["max_tension_mN"] <= BOUND_MN, t
        assert t["tension_now_mN"] < 1.0, t
    # nothing stored: no history entry, no homes after a power cycle
    boots = [ln for ln in out.splitlines() if ln.startswith("<ready ")]
    assert len(boots) == 2 and all("homes=none" in b for b in boots), boots
    assert "<hist " not in out


@pytest.mark.slow(25)
@pytest.mark.parametrize("seed", [8, 18])
def test_a_survey_of_a_robot_stiffer_than_its_table_stays_within_the_bound(tmp_path, seed):
    """The survey runs before the robot is identified, and the field tells its
    bend, not its tension: pulled to the top grid target, these robots (every
    parameter within 10 % of the table, the backbone's stiffness within 25 %)
    took a tendon to 2.10 and 2.15 N against the bound's 1.975 N. The survey's
    tension is now a share of the top (APP_SURVEY_EIGHTHS)."""
    summary = tmp_path / "summary.json"
    proc = subprocess.run([str(BENCH), str(FW), "--plant", str(PLANT), "--seed", str(seed),
                           "--perturb", "0.1", "--perturb-stiffness", "0.25",
                           "--summary", str(summary), "--limit", "60s", "--at", "1s send survey",
                           "--until", "^<done mode=survey|^<fault"],
                          capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert "<done mode=survey" in proc.stdout and "<fault" not in proc.stdout
    tendons = json.loads(summary.read_text())["tendons"]
    assert len(tendons) == 6
    peak = max(t["max_tension_mN"] for t in tendons)
    assert peak <= BOUND_MN, (peak, BOUND_MN)
    assert peak >= 0.9 * SURVEY_MN  # it did pull to the survey's tension


def test_a_stop_during_the_survey_releases_and_the_next_press_calibrates(tmp_path):
    proc, s = run(tmp_path, "--limit", "40s", "--at", "1s send survey",
                  "--at", "step on ^<progress.state=engaged.tendon=2[^0-9] +200ms raw !",
                  "--at", "step on ^<released +500ms send survey 4",
                  "--at", "step on ^<done.mode=survey +300ms press",
                  "--until", "^<done mode=full")
    out = proc.stdout
    assert proc.returncode == 0, out[-2000:]
    assert re.search(r"<released", out)
    assert [ln for ln in out.splitlines() if ln.startswith("<done mode=survey")]
    # the single-tendon survey pulled tendon 4 only
    after = out[out.index("<released"):out.index("<done mode=survey")]
    assert {g[0] for g in samples(after)} == {4}
    assert "<done mode=full" in out


def test_survey_refuses_a_tendon_the_table_lacks(tmp_path):
    proc, _ = run(tmp_path, "--limit", "2s", "--at", "1s send survey 9", "--at", "1.2s send survey x")
    assert "error:15" in proc.stdout  # BAD_TENDON
    assert "error:2" in proc.stdout   # BAD_NUMBER
    assert "<sv " not in proc.stdout


def test_hallhome_identify_survey_end_to_end(tmp_path):
    """The host tool against the board on a pty, then the fit of its file."""
    pty = tmp_path / "console"
    log = open(tmp_path / "bench.log", "w")
    bench = subprocess.Popen([str(BENCH), str(FW), "--plant", str(PLANT), "--seed", "7",
                              "--eeprom", str(tmp_path / "ee.bin"), "--interactive", "--realtime",
                              "--pty-link", str(pty)], stdout=log, stderr=subprocess.STDOUT,
                             cwd=ROOT)
    try:
        deadline = time.monotonic() + 15
        while "<ready " not in (tmp_path / "bench.log").read_text(errors="replace"):
            assert time.monotonic() < deadline, "the bench did not come up"
            time.sleep(0.1)
        out = tmp_path / "survey.json"
        # the pulls alone (the held pulls: test_survey_held_bench.py)
        r = subprocess.run([str(HALLHOME), "identify", "survey", "--port", str(pty), "--out",
                            str(out), "--json", "--no-held"], capture_output=True, text=True,
                           timeout=120,
                           cwd=ROOT, env=dict(os.environ, COLUMNS="200"))
        assert r.returncode == 0, r.stdout + r.stderr
        summary = json.loads(r.stdout)
        assert [p["tendon"] for p in summary["pulls"]] == list(range(6))
        # a pull's steps scale with its travel: the segment-1 tendons travel
        # half as far as the segment-2 ones (22-28 steps against 44-50 at
        # the survey's tension on an idle machine). The bench runs in real
        # time here, so a loaded machine moves single pulls (30 and 37
        # steps in one `make test`): the segments' means are compared.
        steps = [p["steps"] for p in summary["pulls"]]
        assert min(steps) >= 20, summary["pulls"]
        assert sum(steps[3:]) >= 1.4 * sum(steps[:3]), summary["pulls"]
        # every pull of the robot its table describes reaches the top target
        assert all(p["reached"] >= 0.97 for p in summary["pulls"]), summary["pulls"]
    finally:
        bench.terminate()
        bench.wait(10)
    doc = json.loads(out.read_text())
    assert doc["format"] == "hallhome-survey" and doc["robot"] == "paper_2seg"
    survey = load_survey(out, load_robot(TOML))  # what `identify fit` reads
    assert [p.tendon for p in survey.pulls] == list(range(6))


def board_survey(tmp_path, seed):
    """The survey file the host tool makes of a scripted bench run's <sv> lines."""
    proc = subprocess.run([str(BENCH), str(FW), "--plant", str(PLANT), "--seed", str(seed),
                           "--limit", "60s", "--at", "1s send survey",
                           "--until", "^<done mode=survey|^<fault"],
                          capture_output=True, text=True, timeout=180, cwd=ROOT)
    doc = from_log(proc.stdout.splitlines(), "paper_2seg", 6, 3)  # refuses an unfinished one
    path = tmp_path / f"survey{seed}.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("seed", [2, 8])
def test_a_board_survey_identifies_the_geometry(tmp_path, seed):
    """Seeded, deterministic: the fit of the board's survey of the bench robot
    (perturbed by 5 %) is accepted, its residual near the single-sample noise,
    the geometry within the spread measured on seeds 1-10 (docs/identify.md:
    the magnet's strength and the routing radius trade against each other).
    Seeds 2 and 8 landed in the wrong valley before the top of each pull was
    left out. The residual moves with the run's timing: seed 8 left 0.9 uT
    in one build and 1.59 uT in a build whose version string differs."""
    fit = subprocess.run([str(HALLHOME), "identify", "fit", str(TOML),
                          str(board_survey(tmp_path, seed)), "--no-write", "--json"],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert fit.returncode == 0, fit.stdout + fit.stderr
    res = json.loads(fit.stdout)
    assert not res.get("refused"), res["refused"]
    assert res["rms_uT"] < 2.0, res["rms_uT"]
    val = {p["name"]: p["value"] for p in res["parameters"]}
    assert val["magnet_J"] == pytest.approx(1.3, rel=0.15)
    assert val["radius"] == pytest.approx(4.5, rel=0.1)
    assert val["length_1"] + val["length_2"] == pytest.approx(106.0, rel=0.03)
