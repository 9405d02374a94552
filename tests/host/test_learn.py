"""`hallhome learn`, `learned` and `forget`: the fit onto the grid, the
plausibility checks and the dialogue against a scripted board whose field
changes as the operator hangs weights (the virtual bench has no weights;
tests/sim/test_operator_bench.py runs the dialogue on the firmware)."""

import json

import pytest
from click.testing import CliRunner
from fakeboard import FakeBoard, use

from hallhome import learnfit, op_common, op_learn, protocol
from hallhome.cli import main

GRID = [200, 500, 800, 1100]
MODEL = [10.0, 30.0, 50.0, 70.0]  # uT at the grid


# --- the arithmetic ----------------------------------------------------------------

def test_isotonic_pools_violators():
    assert learnfit.isotonic([1, 3, 2, 4]) == [1, 2.5, 2.5, 4]
    assert learnfit.isotonic([5, 4, 3]) == [4, 4, 4]
    assert learnfit.isotonic([1, 2, 3]) == [1, 2, 3]
    assert learnfit.isotonic([1, 4, 1], [1, 1, 2]) == [1, 2, 2]


def test_fit_to_grid_interpolates_inside_the_learned_span():
    fit = learnfit.fit_to_grid([(490, 30.0), (980, 49.0)], GRID)
    assert fit[0] is None and fit[3] is None
    assert fit[1] == pytest.approx(30 + 10 / 490 * 19)
    assert fit[2] == pytest.approx(30 + 310 / 490 * 19)
    # a point within the tolerance of a grid tension covers it
    assert learnfit.fit_to_grid([(795, 40.0)], GRID, 1.0) == [None, None, 40.0, None]
    assert learnfit.fit_to_grid([(795, 40.0)], GRID, 0.5) == [None] * 4
    # non-decreasing whatever the noise
    fit = learnfit.fit_to_grid([(200, 12.0), (500, 11.0), (800, 50.0), (1100, 70.0)], GRID)
    assert fit == [11.5, 11.5, 50.0, 70.0]
    assert learnfit.fit_to_grid([], GRID) == [None] * 4


def test_export_targets_grow_strictly():
    assert op_learn.strictly_growing([None, 100, 100, 120, 110, 130]) == (
        [None, 100, None, 120, None, 130], 2)


def test_export_file_compiles(monkeypatch, tmp_path):
    """A session's file goes through the table generator's own checks."""
    from hallhome.paths import ROBOTS_DIR
    from hallhome.robot import load_robot
    from hallhome.tablegen import apply_learned, build_table, compute, load_learned, parse_table_header
    robot = load_robot(ROBOTS_DIR / "paper_2seg.toml")
    spec = parse_table_header()
    table = build_table(compute(robot), spec)
    grid = table["grid_mN"]
    info = op_learn.TableInfo("paper_2seg", f"0x{table['table_id']:08x}", grid, 800, 0.6, 6, {0: 0})
    got = [{"tendon": 0, "tension_mN": 490, "dB_uT": 41.0, "stored_on_board": False},
           {"tendon": 0, "tension_mN": 800, "dB_uT": 99.0, "stored_on_board": True, "grid_mN": 800,
            "board_dB_uT": 99.5},
           {"tendon": 0, "tension_mN": 981, "dB_uT": 120.0, "stored_on_board": False}]
    doc, notes = op_learn.export_doc(info, got, {}, 1.0)
    assert notes == []
    vals = doc["tendons"][0]["target_cuT"]
    assert vals[grid.index(800)] == 9950  # the board's own value
    p = tmp_path / "learned_paper_2seg.json"
    p.write_text(json.dumps(doc))
    applied = apply_learned(table, spec, robot, [load_learned(p)])
    # stored in the table's unit: 9950 cuT is 663.3 LSB of 15 cuT, kept as 663
    assert applied.table["tendons"][0]["target_lsb"][grid.index(800)] == 663


def test_nearest_grid():
    assert learnfit.nearest_grid(804, GRID, 1.0) == 800
    assert learnfit.nearest_grid(490, GRID, 1.0) is None


def test_check_reading_refusals():
    ok = dict(noise_uT=0.6, grid_mN=GRID, model_uT=MODEL)
    assert learnfit.check_reading(800, 49.0, [], **ok) is None
    assert "only 0.90 uT" in learnfit.check_reading(800, 0.9, [], **ok)
    assert learnfit.check_reading(800, 0.9, [], min_field=0.5, **dict(ok, model_uT=None)) is None
    why = learnfit.check_reading(800, 40.0, [(500, 45.0)], **ok)
    assert "does not rise with tension: 45.00 uT was learned at 0.500 N" in why
    assert learnfit.check_reading(800, 44.0, [(500, 45.0)], **dict(ok, model_uT=None)) is None  # noise
    why = learnfit.check_reading(800, 150.0, [], **ok)
    assert "+200 % from the model's 50.00 uT" in why and "--no-model" in why
    assert learnfit.check_reading(800, 150.0, [], **dict(ok, model_uT=None)) is None
    assert "outside the table's grid, 0.2..1.1 N" in learnfit.check_reading(1500, 90.0, [], **ok)


def test_parse_load():
    assert op_learn.parse_load("81.6") == (pytest.approx(0.80022, abs=1e-5), 81.6)
    assert op_learn.parse_load("50 g")[1] == 50
    assert op_learn.parse_load("0.75N") == (0.75, None)
    for bad in ("abc", "-5", "0", "nan", "N"):
        with pytest.raises(ValueError) as e:
            op_learn.parse_load(bad)
        assert "neither a mass in grams" in str(e.value) and "convert" not in str(e.value)


# --- the dialogue ----------------------------------------------------------------------

class LearnBoard(FakeBoard):
    """Two tendons on sensors 0 and 1; `hang(t, dB)` puts a weight on
    tendon t that changes its sensor's field by dB uT."""

    B0 = {0: (100.0, 0.0, -50.0), 1: (-50.0, 80.0, -50.0)}

    def __init__(self):
        super().__init__()
        self.field = dict(self.B0)
        self.learned = {}  # (tendon, grid index) -> cuT
        self.answers.update({"table": self.table, "sensors": self.sensors, "release": self.release,
                             "status": ["<status state=idle saving=0 count=0>"], "learn": self.learn})

    def hang(self, t, dB, reads=None):
        """With `reads`, the weight comes off after that many `sensors` reads."""
        bx, by, bz = self.B0[t]
        self.field[t] = (bx + dB, by, bz)
        self.off = (t, reads)

    def table(self, line):
        rows = []
        for t in (0, 1):
            vals = [f"{self.learned[(t, g)]}*" if (t, g) in self.learned else str(int(MODEL[g] * 100))
                    for g in range(len(GRID))]
            rows.append(f"<tendon tendon={t} id={t + 1} dir=1 segment=1 sensor={t} limit_um=2500 "
                        f"target_cuT={','.join(vals)}>")
        return [f"<table name=paper_2seg table_id=0x1115c2f1 tendons=2 sensors=2 "
                f"grid_mN={','.join(map(str, GRID))} default_mN=800 noise_cuT=60>"] + rows

    def sensors(self, line):
        t, reads = getattr(self, "off", (None, None))
        if reads is not None:
            if reads == 0:
                self.field[t] = self.B0[t]
            self.off = (t, reads - 1)
        return [f"<sensor index={k} ch={k} addr=105 ok=1 rate_Hz=86.0 bx_uT={b[0]:.2f} by_uT={b[1]:.2f} "
                f"bz_uT={b[2]:.2f} ovf=0 err=0>" for k, b in sorted(self.field.items())]

    def release(self, line):
        self.events.append("<done mode=release time_ms=900 baseline=1>")
        return []

    def learn(self, line):
        _, t, n = line.split()
        t, g = int(t), GRID.index(protocol.parse_fixed(n, 3))
        dB = self.field[t][0] - self.B0[t][0]
        self.learned[(t, g)] = int(round(dB * 100))
        return [f"<learned tendon={t} tension_mN={GRID[g]} grid={g} sensor={t} dB_uT={dB:.2f}>"]


def dialogue(monkeypatch, board, steps):
    """Runs the prompts: each step is (answer, action before answering)."""
    steps = list(steps)
    asked = []

    def ask(text, default=""):
        asked.append(text)
        if not steps:
            raise AssertionError(f"unexpected prompt {text!r}")
        answer, action = steps.pop(0)
        if action:
            action()
        if isinstance(answer, BaseException):
            raise answer
        return answer or default
    monkeypatch.setattr(op_learn, "ask", ask)
    use(monkeypatch, board, op_learn)
    return asked


def test_learn_any_masses_fitted_onto_the_grid(monkeypatch, tmp_path):
    b = LearnBoard()
    out = tmp_path / "l.json"
    dialogue(monkeypatch, b, [
        ("", None),                           # robot straight: baseline
        ("50", lambda: b.hang(0, 29.0)),      # 0.490 N, between grid tensions
        ("100", lambda: b.hang(0, 48.0, reads=2)),  # 0.981 N; then taken off
    ])
    r = CliRunner().invoke(main, ["learn", "-k", "0", "-m", "50", "-m", "100", "--out", str(out),
                                  "--samples", "2"])
    assert r.exit_code == 0, r.output
    assert "between grid tensions: fitted onto the grid" in r.output
    doc = json.loads(out.read_text())
    fit = learnfit.fit_to_grid([(490, 29.0), (981, 48.0)], GRID)
    assert doc["tendons"] == [{"tendon": 0, "target_cuT": [None if v is None else round(v * 100)
                                                            for v in fit]}]
    assert doc["tendons"][0]["target_cuT"][1] is not None and doc["tendons"][0]["target_cuT"][2] is not None
    assert [s["mass_g"] for s in doc["points"]] == [50, 100]
    assert doc["samples"] == []  # the format's samples sit on the grid: none here
    assert not any(x.startswith("learn") for x in b.sent)  # nothing on the grid: board untouched
    from hallhome.tablegen import load_learned
    assert load_learned(out).targets[0] == tuple(doc["tendons"][0]["target_cuT"])


def test_learn_refuses_implausible_readings_and_stores_grid_loads(monkeypatch, tmp_path):
    b = LearnBoard()
    out = tmp_path / "l.json"
    asked = dialogue(monkeypatch, b, [
        ("", None),
        ("abc", None),                         # not a mass
        ("81.6", None),                        # nothing hangs yet
        ("81.6", lambda: b.hang(0, 150.0)),    # far from the model
        ("81.6", lambda: b.hang(0, 49.0)),     # plausible, a grid tension: stored on the board
        ("0.5N", lambda: b.hang(0, 60.0)),     # lower tension, more field: not rising
        ("0.5N", lambda: b.hang(0, 30.0, reads=2)),
    ])
    r = CliRunner().invoke(main, ["learn", "-k", "0", "-m", "81.6", "-F", "0.5", "--out", str(out),
                                  "--samples", "2"])
    assert r.exit_code == 0, r.output
    assert "'abc' is neither a mass in grams" in r.output
    assert "the field changed by only 0.00 uT" in r.output
    assert "from the model's" in r.output and "does not rise with tension" in r.output
    assert "learn 0 0.800" in b.sent and b.learned == {(0, 2): 4900, (0, 1): 3000}
    assert len(asked) == 7
    doc = json.loads(out.read_text())
    assert [(s["tension_mN"], s["dB_uT"], s["stored_on_board"]) for s in doc["points"]] == [
        (800, 49.0, True), (500, 30.0, True)]
    assert [s["tension_mN"] for s in doc["samples"]] == [800, 500]
    assert doc["tendons"][0]["target_cuT"] == [None, 3000, 4900, None]


def test_learn_waits_for_the_baseline_after_the_weight_is_removed(monkeypatch, tmp_path):
    b = LearnBoard()
    out = tmp_path / "l.json"
    monkeypatch.setattr(op_learn, "SETTLE_WAIT", 0.2)
    asked = dialogue(monkeypatch, b, [
        ("", None),
        ("81.6", lambda: b.hang(0, 49.0)),
        ("", None),                             # still hanging after the wait: wait again
        ("", lambda: b.hang(0, 0.0)),           # removed now
    ])
    r = CliRunner().invoke(main, ["learn", "-k", "0", "-m", "81.6", "--out", str(out), "--samples", "2"])
    assert r.exit_code == 0, r.output
    assert "waiting for the field at sensor 0 to return to its baseline" in r.output
    assert "still 49.00 uT from its baseline" in asked[2]
    doc = json.loads(out.read_text())
    assert doc["tendons"][0]["target_cuT"] == [None, None, 4900, None]
    assert doc["samples"][0]["stored_on_board"] and doc["samples"][0]["board_dB_uT"] == 49.0
    assert "1 load(s) learned, 1 stored on the board" in r.output


def test_learn_new_baseline_on_request(monkeypatch, tmp_path):
    b = LearnBoard()
    monkeypatch.setattr(op_learn, "SETTLE_WAIT", 0.1)
    dialogue(monkeypatch, b, [("", None), ("81.6", lambda: b.hang(0, 49.0)), ("b", None)])
    r = CliRunner().invoke(main, ["learn", "-k", "0", "-m", "81.6", "--out", str(tmp_path / "x.json"),
                                  "--samples", "2"])
    assert r.exit_code == 0, r.output
    assert b.sent.count("release") == 2


def test_learn_ctrl_c_exits_130(monkeypatch, tmp_path):
    b = LearnBoard()
    dialogue(monkeypatch, b, [("", None), (KeyboardInterrupt(), None)])
    r = CliRunner().invoke(main, ["learn", "-k", "0", "--out", str(tmp_path / "x.json")])
    assert r.exit_code == 130 and "interrupted" in r.output


def test_learn_ctrl_c_through_click_prompt_exits_130(monkeypatch, tmp_path):
    import click

    def prompt(*a, **k):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise click.exceptions.Abort() from None
    monkeypatch.setattr(click, "prompt", prompt)
    use(monkeypatch, LearnBoard(), op_learn)
    r = CliRunner().invoke(main, ["learn", "-k", "0", "--out", str(tmp_path / "x.json")])
    assert r.exit_code == 130


def test_learn_tendon_beyond_the_table(monkeypatch, tmp_path):
    use(monkeypatch, LearnBoard(), op_learn)
    r = CliRunner().invoke(main, ["learn", "-k", "5", "--out", str(tmp_path / "x.json")])
    assert r.exit_code == 2 and "the table has 2 tendons (0..1)" in r.output


# --- learned, forget -------------------------------------------------------------------

def declare(monkeypatch, name, synopsis, help_="x"):
    c = protocol.Command(name.upper(), name, synopsis, help_, protocol.parse_synopsis(synopsis))
    monkeypatch.setitem(protocol.COMMANDS_BY_NAME, name, c)


def test_learned_from_table_marks_when_the_firmware_has_no_learned_command(monkeypatch):
    b = LearnBoard()
    b.learned[(1, 3)] = 7123
    monkeypatch.delitem(protocol.COMMANDS_BY_NAME, "learned", raising=False)
    use(monkeypatch, b, op_learn)
    r = CliRunner().invoke(main, ["learned", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["learned"] == [{"tendon": 1, "grid": 3, "tension_N": 1.1,
                                                "target_uT": 71.23}]


def test_learned_and_forget_on_a_firmware_that_has_them(monkeypatch):
    declare(monkeypatch, "learned", "")
    declare(monkeypatch, "forget", "<tendon:s>")
    b = LearnBoard()
    b.learned[(0, 2)] = 4900

    def learned(line):
        return [f"<learned tendon={t} grid={g} target_cuT={v}>" for (t, g), v in sorted(b.learned.items())]

    def forget(line):
        arg = line.split()[1]
        if arg != "all" and int(arg) >= 2:
            return "error:15 no such tendon"
        for k in list(b.learned):
            if arg == "all" or k[0] == int(arg):
                del b.learned[k]
        return []
    b.answers.update(learned=learned, forget=forget)
    use(monkeypatch, b, op_learn)
    r = CliRunner().invoke(main, ["learned"])
    assert r.exit_code == 0 and "learned targets" in r.output and "49.00" in r.output
    assert "learned" in b.sent
    r = CliRunner().invoke(main, ["forget", "0"])
    assert r.exit_code == 0, r.output
    assert "forget 0" in b.sent and b.learned == {}
    assert "0 learned target(s) left" in r.output
    r = CliRunner().invoke(main, ["forget", "1"])
    assert r.exit_code == 0
    r = CliRunner().invoke(main, ["forget", "4"])
    assert r.exit_code == 1 and "BAD_TENDON" in r.output
    r = CliRunner().invoke(main, ["forget", "x"])
    assert r.exit_code == 2 and "neither a tendon (0..11) nor `all`" in r.output
    r = CliRunner().invoke(main, ["forget", "12"])
    assert r.exit_code == 2 and "12 is not in 0..11" in r.output


def test_forget_on_a_firmware_without_it(monkeypatch):
    declare(monkeypatch, "forget", "<tendon:s>")
    b = LearnBoard()
    b.answers["forget"] = "error:1 unknown command"
    use(monkeypatch, b, op_learn)
    r = CliRunner().invoke(main, ["forget", "all"])
    assert r.exit_code == 1 and "the board's firmware has no `forget` command" in r.output
