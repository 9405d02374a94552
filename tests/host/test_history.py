"""`hallhome history` and `export` against a scripted board: whole turns
unwrapped, creep per tension, runs dated from the host's run log."""

import json

from click.testing import CliRunner
from fakeboard import FakeBoard, use

from hallhome import op_history, runlog
from hallhome.cli import main

TID = "0x1115c2f1"
HIST = [  # newest first, as the board sends it
    f"<hist age=0 count=5 table_id={TID} tension_mN=800 homes=4335,4322,-3772>",
    f"<hist age=1 count=4 table_id={TID} tension_mN=700 homes=4300,4310,310?>",
    f"<hist age=2 count=3 table_id={TID} tension_mN=800 homes=4331,4321,-3774>",  # after a power cycle
    f"<hist age=3 count=2 table_id={TID} tension_mN=700 homes=4296,4309,300>",
    f"<hist age=4 count=1 table_id={TID} tension_mN=800 homes=4327,4320,323>",
]


def test_unwrap_removes_whole_turns_only():
    assert op_history.TICKS_PER_TURN == 4096
    assert op_history.unwrap([323, -3774, -3772]) == [323, 322, 324]
    assert op_history.unwrap([100, None, 100 + 2 * 4096 + 5]) == [100, None, 105]
    assert op_history.unwrap([10, 30, 2000]) == [10, 30, 2000]  # within half a turn: kept


def test_creep_groups_by_tension():
    rows = [{"count": c, "tension_mN": t, "homes": h} for c, t, h in
            [(1, 800, [4327, 323]), (2, 700, [4296, 300]), (3, 800, [4331, -3774]), (5, 800, [4335, -3772])]]
    g = op_history.creep(rows, 2)
    assert list(g) == [700, 800]
    assert g[800]["counts"] == [1, 3, 5] and g[700]["counts"] == [2]
    assert g[800]["tendons"][0]["drift"] == 8 and g[800]["tendons"][1]["drift"] == 1
    assert g[700]["tendons"][0]["drift"] is None


def test_runlog_round_trip(tmp_path, monkeypatch):
    p = tmp_path / "runs.jsonl"
    monkeypatch.setenv("HALLHOME_RUNS", str(p))
    runlog.record(TID, 3, 800, "full", when=1000.0)
    runlog.record("0x1115C2F1", 3, 800, "full", when=2000.0)  # the same run again: latest wins
    with open(p, "a") as f:
        f.write('{"table_id": "0x1115c2f1", "cou')  # cut by a crash
    log = runlog.load()
    assert runlog.when(log, TID, 3) == 2000.0 and runlog.when(log, TID, 4) is None
    monkeypatch.setenv("HALLHOME_RUNS", "")
    runlog.record(TID, 9, 800, "full")
    assert runlog.load() == {}


def test_history_command(monkeypatch, tmp_path):
    monkeypatch.setenv("HALLHOME_RUNS", str(tmp_path / "runs.jsonl"))
    runlog.record(TID, 5, 800, "full", when=1764000000.0)
    b = FakeBoard({"history": HIST, "status": ["<status state=idle saving=0>"]})
    use(monkeypatch, b, op_history)
    r = CliRunner().invoke(main, ["history", "--no-plot"])
    assert r.exit_code == 0, r.output
    assert "drift at 0.700 N over 2 runs (ticks, whole turns removed): tendon 0: +4, tendon 1: +1" in r.output
    assert "drift at 0.800 N over 3 runs (ticks, whole turns removed): tendon 0: +8, tendon 1: +2, " \
           "tendon 2: +1" in r.output
    assert "2025-11-" in r.output  # run 5 dated; the others "-"
    r = CliRunner().invoke(main, ["history", "--json"])
    d = json.loads(r.stdout)
    assert [x["count"] for x in d["runs"]] == [1, 2, 3, 4, 5]
    assert d["runs"][3]["homes"] == [4300, 4310, None] and d["runs"][0]["time"] is None
    c800 = [c for c in d["creep"] if c["tension_mN"] == 800][0]
    assert c800["tendons"][2]["homes_unwrapped"] == [323, 322, 324]
    png = tmp_path / "h.png"
    r = CliRunner().invoke(main, ["history", "--plot", str(png)])
    assert r.exit_code == 0 and png.read_bytes()[:4] == b"\x89PNG"


def test_export_json_flag(monkeypatch):
    b = FakeBoard({"version": [f"<version name=hallhome version=0.1.0 table=paper_2seg table_id={TID} "
                               "tendons=1 sensors=1>"],
                   "status": ["<status state=idle tension_mN=800 count=2>",
                              "<home tendon=0 home=4327 straight=4280 rest=4000 usable=1 now=8423>"],
                   "table": ["<table name=paper_2seg table_id=0x1115c2f1 tendons=1>",
                             "<tendon tendon=0 id=1 sensor=0 target_cuT=1>"]})
    use(monkeypatch, b, op_history)
    r = CliRunner().invoke(main, ["export", "--json"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["tendons"] == [{"tendon": 0, "servo_id": 1, "home_ticks": 4327, "home_now_ticks": 8423,
                             "straight_ticks": 4280, "straight_now_ticks": 8376,
                             "rest_ticks": 4000, "usable": True}]
