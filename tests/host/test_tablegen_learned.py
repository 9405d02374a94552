"""Learned targets compiled into a table: `hallhome tables ROBOT.toml
--learned learned_<robot>.json` (docs/tables.md, "Learned targets").

The learned files are written by `hallhome learn` itself, against a stand-in
board that answers the console commands the dialogue sends with the
firmware's report lines, so the tests read exactly what the operator tool
exports."""

import contextlib
import json
import shutil
import subprocess
import zlib

import pytest
from click.testing import CliRunner

from hallhome import op_learn, protocol
from hallhome.cli import main
from hallhome.client import Reply, Report
from hallhome.paths import LIB_DIR, ROBOTS_DIR
from hallhome.robot import load_robot
from hallhome.tablegen import (TableError, apply_learned, build_table, canonical_bytes, compute,
                               load_learned, parse_table_header)

SPEC = parse_table_header()
PAPER = ROBOTS_DIR / "paper_2seg.toml"
LEARN_SCALE = 1.08  # the stand-in robot's field change is 8 % above the model's
CUT = SPEC["TBL_CUT_PER_LSB"]


def _cuT(d: dict) -> list:
    """A tendon's targets as the firmware reads them (cuT)."""
    return [v * CUT for v in d["target_lsb"]]


def _q(cuT: int) -> int:
    """A measured target as the board stores it: the nearest whole LSB, in cuT."""
    return (cuT + CUT // 2) // CUT * CUT


# --- a board that answers `hallhome learn` ---------------------------------------------

def _report(line: str) -> Report:
    msg = protocol.parse_line(line)
    assert msg["type"] == "report", line
    return Report(msg["kind"], msg["fields"], line)


class LearnBoard:
    """Answers status, table, release and learn like the firmware (docs/app.md)
    for a compiled table given as build_table's dict. A learned target is the
    compiled one times LEARN_SCALE (what hanging the weight would measure)."""

    def __init__(self, table: dict):
        self.table = table
        self.learned = {}  # (tendon, grid index) -> cuT
        self.events = []
        self.motion = None
        self.garbled = 0

    def _table_lines(self):
        t = self.table
        yield (f"<table name={t['name']} table_id=0x{t['table_id']:08x} tendons={t['n_tendons']} "
               f"sensors={t['n_sensors']} grid_mN={','.join(map(str, t['grid_mN']))} "
               f"default_mN={t['default_mN']} noise_cuT={t['noise_cuT']}>")
        for k, d in enumerate(t["tendons"]):
            vals = [f"{self.learned[(k, g)]}*" if (k, g) in self.learned else str(v)
                    for g, v in enumerate(_cuT(d))]
            yield (f"<tendon tendon={k} id={d['servo_id']} dir={d['pull_dir']:+d} "
                   f"segment={d['segment']} sensor={d['sensor']} limit_um={d['travel_limit_um']} "
                   f"target_cuT={','.join(vals)}>")

    def command(self, line, timeout=None):
        words = line.split()
        if words[0] == "status":
            lines = ["<status state=idle table=x sensors=3 servos=6 saving=0 baseline=1>"]
        elif words[0] == "table":
            lines = list(self._table_lines())
        elif words[0] == "sensors":  # a still field: `learn` below says what hangs
            lines = [f"<sensor index={k} ch={k} addr=105 ok=1 bx_uT=100.00 by_uT=0.00 bz_uT=-50.00>"
                     for k in range(self.table["n_sensors"])]
        elif words[0] == "release":
            lines = []
            self.events.append(_report("<done mode=release time_ms=900 baseline=1>"))
        elif words[0] == "learn":
            t, mN = int(words[1]), round(float(words[2]) * 1000)
            g = self.table["grid_mN"].index(mN)
            d = self.table["tendons"][t]
            self.learned[(t, g)] = _q(round(_cuT(d)[g] * LEARN_SCALE))
            uT = self.learned[(t, g)] / 100  # the firmware reports what it stored
            lines = [f"<learned tendon={t} tension_mN={mN} grid={g} sensor={d['sensor']} "
                     f"dB_uT={uT:.2f}>"]
        else:
            raise AssertionError(f"unexpected command {line!r}")
        return Reply(line, [_report(x) for x in lines])

    def event(self, timeout):
        return self.events.pop(0) if self.events else None


def run_learn(monkeypatch, table, out, tendons, masses=()):
    """`hallhome learn` against a LearnBoard for ``table``; every mass as asked."""
    board = LearnBoard(table)

    @contextlib.contextmanager
    def session(port, timeout):
        yield board
    monkeypatch.setattr(op_learn, "session", session)
    # the stand-in's field does not move: accept it, the board's `learn` gives the values
    args = ["learn", "--out", str(out), "--min-field", "0", "--no-model"]
    for t in tendons:
        args += ["--tendon", str(t)]
    for m in masses:
        args += ["--mass", str(m)]
    n = len(tendons) * (len(masses) or 3)
    r = CliRunner().invoke(main, args, input="\n" * (1 + n))
    assert r.exit_code == 0, r.output
    return board


# --- fixtures: the model table once, one export --------------------------------------

@pytest.fixture(scope="module")
def model():
    robot = load_robot(PAPER)
    res = compute(robot)
    return robot, build_table(res, SPEC)


@pytest.fixture(scope="module")
def exported(model, tmp_path_factory):
    """learned_paper_2seg.json from `hallhome learn --tendon 0 --tendon 3`
    (default masses: 0.7, 0.8 and 0.9 N)."""
    mp = pytest.MonkeyPatch()
    path = tmp_path_factory.mktemp("learn") / "learned_paper_2seg.json"
    try:
        run_learn(mp, model[1], path, [0, 3])
    finally:
        mp.undo()
    return path


@pytest.fixture(scope="module")
def generated(exported, tmp_path_factory):
    out = tmp_path_factory.mktemp("gen")
    r = CliRunner().invoke(main, ["tables", str(PAPER), "--learned", str(exported),
                                  "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    return out, r.output


def write_doc(tmp_path, doc, name="learned.json"):
    p = tmp_path / name
    p.write_text(json.dumps(doc, indent=1) + "\n" if not isinstance(doc, str) else doc)
    return p


def mutated(exported, tmp_path, change):
    doc = json.loads(exported.read_text())
    change(doc)
    return write_doc(tmp_path, doc)


# --- round trip ----------------------------------------------------------------------

def test_export_has_the_documented_shape(exported, model):
    doc = json.loads(exported.read_text())
    assert doc["format"] == "hallhome-learned" and doc["format_version"] == 1
    assert doc["robot"] == "paper_2seg"
    assert doc["table_id"] == f"0x{model[1]['table_id']:08x}"
    assert [t["tendon"] for t in doc["tendons"]] == [0, 3]
    lf = load_learned(exported)
    assert lf.count == 6 and lf.table_id == model[1]["table_id"]


def test_round_trip_replaces_exactly_the_learned_targets(generated, exported, model):
    out, output = generated
    robot, table = model
    assert sorted(p.name for p in out.iterdir()) == ["paper_2seg_learned.c",
                                                     "paper_2seg_learned.json"]
    twin = json.loads((out / "paper_2seg_learned.json").read_text())
    t = twin["table"]
    grid = t["grid_mN"]
    learned_at = {grid.index(g) for g in (700, 800, 900)}
    for k, (d, m) in enumerate(zip(t["tendons"], table["tendons"])):
        h = twin["human"]["tendons"][k]
        for g in range(len(grid)):
            if k in (0, 3) and g in learned_at:
                assert _cuT(d)[g] == _q(round(_cuT(m)[g] * LEARN_SCALE))
                assert h["learned"][g] is True
            else:
                assert d["target_lsb"][g] == m["target_lsb"][g]
                assert h["learned"][g] is False
        assert d["abs_target_lsb"] == m["abs_target_lsb"] and d["travel_um"] == m["travel_um"]
        assert h["target_uT"] == [v / 100 for v in _cuT(d)]
        # the model's float against its stored value: within half an LSB (0.075 uT)
        assert h["model_target_uT"][0] == pytest.approx(_cuT(m)[0] / 100, abs=0.076)
    # a new table: its own id, the CRC of its content; the name stays the robot's
    assert t["name"] == "paper_2seg"
    assert t["table_id"] != table["table_id"]
    assert zlib.crc32(canonical_bytes(t, SPEC)) == t["table_id"]
    assert twin["table_id"] == f"0x{t['table_id']:08X}"
    assert twin["learned"] == {
        "symbol": "tbl_table_paper_2seg_learned",
        "model_table_id": f"0x{table['table_id']:08X}",
        "files": [{"file": "learned_paper_2seg.json", "table_id": f"0x{table['table_id']:08X}",
                   "targets": 6}],
        "targets": 6}
    # grid points left to the model are reported, and kept in the twin
    assert "tendon 0 (servo 1, segment 1): 9 of 12 grid tensions keep the model's target" \
        in " ".join(output.split())
    assert any(w.startswith("tendon 1 (servo 2, segment 1): no learned target")
               for w in twin["warnings"])
    assert f"6 learned target(s) over the model table 0x{table['table_id']:08X}" in output


def _c_program(symbol):
    return f"""#include <stdio.h>
#include "table/table.h"
extern const tbl_table_t {symbol};
int main(void) {{
    tbl_src_t src = {{&{symbol}, tbl_copy_ram}};
    tbl_info_t info;
    char name[TBL_NAME_LEN];
    tbl_point_t p;
    unsigned k, g;
    if (tbl_check(&src) != 0 || tbl_info(&src, &info) != 0 || tbl_name(&src, name) != 0) return 1;
    printf("%s %lu\\n", name, (unsigned long)info.table_id);
    for (k = 0; k < info.n_tendons; k++) {{
        for (g = 0; g < info.n_grid; g++) {{
            if (tbl_target(&src, (uint8_t)k, tbl_grid_mN(&src, (uint8_t)g), &p) != 0) return 2;
            printf("%lu ", (unsigned long)p.target_cuT);
        }}
        if (tbl_target(&src, (uint8_t)k, 750u, &p) != 0) return 3;
        printf("%lu\\n", (unsigned long)p.target_cuT);
    }}
    return 0;
}}
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_learned_table_compiles_and_reads_back_through_the_accessors(generated, tmp_path):
    out, _ = generated
    cfile = out / "paper_2seg_learned.c"
    twin = json.loads((out / "paper_2seg_learned.json").read_text())["table"]
    src = tmp_path / "prog.c"
    src.write_text(_c_program("tbl_table_paper_2seg_learned"))
    exe = tmp_path / "prog"
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                    f"-I{LIB_DIR}", str(src), str(cfile), str(LIB_DIR / "table" / "table.c"),
                    "-o", str(exe)], check=True)
    lines = subprocess.run([str(exe)], capture_output=True, text=True,
                           check=True).stdout.splitlines()
    assert lines[0].split() == ["paper_2seg", str(twin["table_id"])]
    g700, g800 = twin["grid_mN"].index(700), twin["grid_mN"].index(800)
    for line, d in zip(lines[1:], twin["tendons"]):
        v = [int(x) for x in line.split()]
        assert v[:-1] == _cuT(d)
        # 750 mN interpolates between the two learned points (half rounds up)
        a, b = _cuT(d)[g700], _cuT(d)[g800]
        assert v[-1] == a + (b - a + 1) // 2
    assert len(lines) == 1 + twin["n_tendons"]


@pytest.mark.skipif(shutil.which("avr-gcc") is None, reason="avr-gcc not installed")
def test_learned_table_compiles_for_the_avr(generated, tmp_path):
    out, _ = generated
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-std=c99", "-Wall", "-Wextra", "-Werror",
                    "-pedantic", "-DTBL_FLASH=__attribute__((__progmem__))", f"-I{LIB_DIR}",
                    "-c", str(out / "paper_2seg_learned.c"), "-o", str(tmp_path / "t.o")],
                   check=True)


def test_output_is_deterministic_and_leaves_the_model_table_alone(generated, exported,
                                                                  tmp_path):
    out, _ = generated
    # the same inputs from another place give the same bytes
    copy = tmp_path / "elsewhere" / "learned_paper_2seg.json"
    copy.parent.mkdir()
    copy.write_bytes(exported.read_bytes())
    dest = tmp_path / "out"
    dest.mkdir()
    sentinel = b"/* the model-based table */\n"
    (dest / "paper_2seg.c").write_bytes(sentinel)
    r = CliRunner().invoke(main, ["tables", "-q", str(PAPER), "--learned", str(copy),
                                  "--out-dir", str(dest)])
    assert r.exit_code == 0, r.output
    for ext in ("c", "json"):
        assert (dest / f"paper_2seg_learned.{ext}").read_bytes() == \
            (out / f"paper_2seg_learned.{ext}").read_bytes()
    assert (dest / "paper_2seg.c").read_bytes() == sentinel
    assert not (dest / "paper_2seg.json").exists()
    text = (dest / "paper_2seg_learned.c").read_text()
    assert text.count("const tbl_table_t tbl_table_paper_2seg_learned TBL_FLASH = {") == 1
    assert "learned targets from learned_paper_2seg.json" in text
    assert "(tendon: mN): 0: 700,800,900; 3: 700,800,900 */" in text


def test_a_file_learned_on_a_learned_table_chains_after_its_own(model, exported, tmp_path,
                                                                monkeypatch):
    robot, table = model
    first = apply_learned(table, SPEC, robot, [load_learned(exported)])
    # the board now runs the learned table and learns more points on tendon 5
    second = tmp_path / "learned_again.json"
    run_learn(monkeypatch, first.table, second, [5], masses=[102.0])
    doc = json.loads(second.read_text())
    assert doc["table_id"] == f"0x{first.table['table_id']:08x}"
    assert [t["tendon"] for t in doc["tendons"]] == [5]
    both = apply_learned(table, SPEC, robot, [load_learned(exported), load_learned(second)])
    g = table["grid_mN"].index(1000)
    assert both.mask[5][g] and sum(map(sum, both.mask)) == 7
    assert _cuT(both.table["tendons"][5])[g] == \
        _q(round(_cuT(table["tendons"][5])[g] * LEARN_SCALE))
    assert both.table["tendons"][0] == first.table["tendons"][0]
    with pytest.raises(TableError, match=r"learned on table 0x[0-9A-F]{8}, but the model's table "
                                         r"is 0x[0-9A-F]{8}.*learned files that built that table"):
        apply_learned(table, SPEC, robot, [load_learned(second)])
    # out of order, the first file already fails; the same file twice fails on the second
    with pytest.raises(TableError, match=r"learned_again.json: learned on table"):
        apply_learned(table, SPEC, robot, [load_learned(second), load_learned(exported)])
    ids = (table["table_id"], first.table["table_id"])
    with pytest.raises(TableError, match=rf"learned_paper_2seg.json: learned on table "
                                         rf"0x{ids[0]:08X}, but the table the learned "
                                         rf"files before it give is 0x{ids[1]:08X}"):
        apply_learned(table, SPEC, robot, [load_learned(exported), load_learned(exported)])


def test_warns_when_a_learned_point_meets_a_lower_model_point(model, exported, tmp_path):
    robot, table = model
    g900 = table["grid_mN"].index(900)
    above = _cuT(table["tendons"][0])[g900 + 1] + 50

    def change(doc):
        doc["tendons"][0]["target_cuT"][g900] = above
    app = apply_learned(table, SPEC, robot, [load_learned(mutated(exported, tmp_path, change))])
    assert any(w.startswith("tendon 0 (servo 1, segment 1): target does not grow between 900 mN "
                            f"(learned, {_q(above)} cuT) and 1000 mN (model") for w in app.warnings)
    clean = apply_learned(table, SPEC, robot, [load_learned(exported)])
    assert not any("does not grow" in w for w in clean.warnings)


# --- errors ----------------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("{\"format\": ", r"not valid JSON \(line 1, column 12"),
    ("[1, 2]", r"expected a JSON object at the top level"),
    ("{\"format\": \"hallhome-table\"}", r"format is 'hallhome-table', expected "
                                         r"'hallhome-learned'"),
])
def test_malformed_files(tmp_path, text, message):
    with pytest.raises(TableError, match=r"learned targets learned.json: " + message):
        load_learned(write_doc(tmp_path, text))


@pytest.mark.parametrize("key", ["format", "format_version", "robot", "table_id", "grid_mN",
                                 "tendons"])
def test_missing_top_level_field(exported, tmp_path, key):
    with pytest.raises(TableError, match=rf"missing field '{key}'"):
        load_learned(mutated(exported, tmp_path, lambda d: d.pop(key)))


@pytest.mark.parametrize("where, key", [("tendons", "tendon"), ("tendons", "target_cuT"),
                                        ("samples", "tension_mN"), ("samples", "tendon")])
def test_missing_nested_field(exported, tmp_path, where, key):
    with pytest.raises(TableError, match=rf"missing field '{where}\[0\]\.{key}'"):
        load_learned(mutated(exported, tmp_path, lambda d: d[where][0].pop(key)))


@pytest.mark.parametrize("change, message", [
    (lambda d: d.update(format_version=2), r"format_version 2 is not supported"),
    (lambda d: d.update(table_id=0x1115C2F1), r"table_id must be a hex string"),
    (lambda d: d.update(table_id="paper"), r"table_id must be a hex string"),
    (lambda d: d.update(robot=""), r"robot must be a non-empty string"),
    (lambda d: d.update(grid_mN="200,300"), r"grid_mN must be a list of tensions"),
    (lambda d: d["grid_mN"].reverse(), r"grid_mN is not strictly increasing"),
    (lambda d: d.update(tendons={}), r"tendons must be a list"),
    (lambda d: d["tendons"][0]["target_cuT"].pop(), r"tendons\[0\]\.target_cuT must be a list "
                                                    r"with one entry per grid_mN tension \(12\)"),
    (lambda d: d["tendons"][0]["target_cuT"].__setitem__(6, 106.5),
     r"tendons\[0\]\.target_cuT at 800 mN must be null or an integer in cuT"),
    (lambda d: d["tendons"][0]["target_cuT"].__setitem__(6, -3),
     r"tendons\[0\]\.target_cuT at 800 mN must be null or an integer"),
    (lambda d: d["tendons"][0].update(tendon=-1), r"tendons\[0\]\.tendon must be a tendon index"),
    (lambda d: d["tendons"][1].update(tendon=0), r"tendon 0 appears twice"),
    (lambda d: d.update(samples=None), r"samples must be a list"),
])
def test_invalid_fields(exported, tmp_path, change, message):
    with pytest.raises(TableError, match=r"learned targets learned.json: " + message):
        load_learned(mutated(exported, tmp_path, change))


def _apply(model, path):
    robot, table = model
    return apply_learned(table, SPEC, robot, [load_learned(path)])


def test_wrong_robot(model, exported, tmp_path):
    with pytest.raises(TableError, match=r"learned on robot 'trio_3seg', but paper_2seg.toml "
                                         r"describes 'paper_2seg'"):
        _apply(model, mutated(exported, tmp_path, lambda d: d.update(robot="trio_3seg")))


def test_table_id_mismatch(model, exported, tmp_path):
    with pytest.raises(TableError, match=r"learned on table 0x0BADC0DE, but the model's table is "
                                         rf"0x{model[1]['table_id']:08X}\. Learned targets are "
                                         r"only valid for the table the board ran"):
        _apply(model, mutated(exported, tmp_path, lambda d: d.update(table_id="0x0badc0de")))


def test_tendon_out_of_range(model, exported, tmp_path):
    with pytest.raises(TableError, match=r"tendon 6 out of range \(paper_2seg has tendons 0..5\)"):
        _apply(model, mutated(exported, tmp_path, lambda d: d["tendons"][1].update(tendon=6)))
    with pytest.raises(TableError, match=r"samples\[0\]: tendon 9 out of range"):
        _apply(model, mutated(exported, tmp_path, lambda d: d["samples"][0].update(tendon=9)))


def test_tension_not_on_the_grid(model, exported, tmp_path):
    def change(doc):
        doc["grid_mN"][6] = 850
    with pytest.raises(TableError, match=r"tension 850 mN is not on the table's grid "
                                         r"\(200, 300, .*, 1500 mN\)"):
        _apply(model, mutated(exported, tmp_path, change))
    with pytest.raises(TableError, match=r"samples\[1\]: tension 810 mN is not on the table's"):
        _apply(model, mutated(exported, tmp_path,
                              lambda d: d["samples"][1].update(tension_mN=810)))


def test_a_subset_of_the_grid_maps_by_tension(model, exported, tmp_path):
    def change(doc):
        keep = [i for i, v in enumerate(doc["tendons"][0]["target_cuT"]) if v is not None]
        doc["grid_mN"] = [doc["grid_mN"][i] for i in keep]
        for row in doc["tendons"]:
            row["target_cuT"] = [row["target_cuT"][i] for i in keep]
    full = _apply(model, exported)
    assert _apply(model, mutated(exported, tmp_path, change)).table == full.table


def test_learned_targets_must_grow_with_the_tension(model, exported, tmp_path):
    def change(doc):
        row = doc["tendons"][1]["target_cuT"]  # tendon 3
        row[6], row[7] = row[7], row[6]
    with pytest.raises(TableError, match=r"tendon 3 \(servo 4, segment 2\): learned target does "
                                         r"not grow between 800 mN \(\d+ cuT, learned.json\) and "
                                         r"900 mN"):
        _apply(model, mutated(exported, tmp_path, change))
    with pytest.raises(TableError, match=r"learned target does not grow between 700 mN"):
        _apply(model, mutated(exported, tmp_path, lambda d: d["tendons"][0]["target_cuT"]
                              .__setitem__(6, d["tendons"][0]["target_cuT"][5])))


def test_a_file_without_any_learned_target(model, exported, tmp_path):
    def change(doc):
        for row in doc["tendons"]:
            row["target_cuT"] = [None] * len(row["target_cuT"])
    with pytest.raises(TableError, match=r"no learned target at all"):
        _apply(model, mutated(exported, tmp_path, change))


def test_cli_reports_errors_and_writes_nothing(exported, tmp_path):
    out = tmp_path / "out"
    bad = write_doc(tmp_path, "{\"format\": ")
    r = CliRunner().invoke(main, ["tables", str(PAPER), "--learned", str(bad),
                                  "--out-dir", str(out)])
    assert r.exit_code == 1
    assert "Error: learned targets learned.json: not valid JSON (line 1, column 12" in r.output
    assert not out.exists()
    r = CliRunner().invoke(main, ["tables", str(PAPER), str(ROBOTS_DIR / "trio_3seg.toml"),
                                  "--learned", str(exported), "--out-dir", str(out)])
    assert r.exit_code == 2 and "--learned applies to exactly one robot TOML" in r.output
    r = CliRunner().invoke(main, ["tables", "--help"])
    assert "--learned" in r.output and "tbl_table_<robot>_learned" in r.output
