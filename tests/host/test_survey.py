"""`hallhome identify survey`'s host side (hallhome.op_survey): the board's
<sv> lines into survey pulls, the weights dialogue, refusals."""

import json

import pytest

from hallhome import protocol
from hallhome.client import Report
from hallhome.op_survey import (BOUND_SHARE, Sample, SurveyError, SurveyView, parse_sample,
                                pull_of, reached, record_weights, survey_doc, weight_tendons)


def sv(t, p, *vals):
    return Report("sv", {"t": t, "p": p, "b": ",".join(map(str, vals))},
                  f"<sv t={t} p={p} b={','.join(map(str, vals))}>")


def test_parse_sample_splits_sensors_and_refuses_a_short_line():
    t, s = parse_sample(sv(2, 4100, 1, 2, 3, 4, 5, 6), 2)
    assert t == 2 and s.ticks == 4100 and s.b == [[1, 2, 3], [4, 5, 6]]
    with pytest.raises(ValueError):
        parse_sample(sv(2, 4100, 1, 2, 3, 4, 5), 2)
    with pytest.raises(ValueError):
        parse_sample(Report("sv", {"t": "x", "p": 1, "b": "1,2,3"}, "<sv>"), 1)


def ramp(start, stop, step, dirn=1, engaged_at=None):
    """Samples of one sensor: flat (100, 0, 0) before engaged_at, rising after."""
    out = []
    for p in range(start, stop, step * dirn):
        rise = max(0, dirn * (p - engaged_at)) if engaged_at is not None else 0
        out.append(Sample(p, [[100 + 10 * rise, 0, 0]]))
    return out


def test_pull_averages_repeats_keeps_growth_and_takes_the_baseline_from_slack():
    s = ramp(1000, 1100, 4, engaged_at=1040)
    s += [Sample(1096, [[700, 0, 0]]), Sample(1096, [[720, 0, 0]])]  # fine samples at one spot
    s += [Sample(1080, [[500, 0, 0]])]  # a re-approach goes back first: dropped
    s += [Sample(1104, [[740, 0, 0]])]
    p = pull_of(0, s, 1044, 1, keep=1.0)
    ticks = [st[0] for st in p["steps"]]
    assert ticks == sorted(set(ticks)) and 1080 not in ticks[ticks.index(1096):]
    at = dict((st[0], st[1]) for st in p["steps"])
    assert at[1096][0][0] == pytest.approx((660 + 700 + 720) / 3, abs=0.1)
    assert p["baseline_cuT"] == [[100.0, 0.0, 0.0]]  # only samples 8+ ticks short of 1044
    assert p["samples"] == len(s)


def test_the_baseline_leaves_out_a_back_off_past_slack_positions():
    """Bench seed 5 at ±10 %, stiffness ±25 % (tendon 1, sensor 0's x axis, cuT):
    the take-up ran on past its engagement (163) to 247 and backed off to 136
    with the field still high from the pull; the sample at 155 passed for
    slack and moved the baseline by 6 uT, and the fit went to a magnet of half
    the nominal strength (refused)."""
    slack = [Sample(p, [[26150 + (p % 3) * 30, -200, 7530]]) for p in range(-213, 163, 25)]
    run_on = [Sample(199, [[23490, -195, 8250]]), Sample(208, [[17310, -150, 9375]]),
              Sample(231, [[13620, -60, 9600]]), Sample(247, [[11940, -165, 9615]]),
              Sample(234, [[11415, -45, 9510]])]
    back = [Sample(155, [[13965, -105, 9585]]), Sample(136, [[26115, -165, 7530]]),
            Sample(139, [[26235, -240, 7500]])]
    approach = [Sample(p, [[26100 - 300 * (p - 163), -200, 7600]]) for p in range(142, 260, 3)]
    p = pull_of(1, slack + run_on + back + approach, 163, 1)
    quiet = [s for s in slack if 163 - s.ticks >= 8]  # BASE_GUARD_TICKS
    want = [round(sum(s.b[0][a] for s in quiet) / len(quiet), 1) for a in range(3)]
    assert p["baseline_cuT"] == [want]
    # each sample before the run-on counts, none after
    assert abs(p["baseline_cuT"][0][0] - 26180) < 40


def test_pull_in_the_negative_direction():
    s = ramp(5000, 4900, 4, dirn=-1, engaged_at=4960)
    p = pull_of(3, s, 4956, -1, keep=1.0)
    ticks = [st[0] for st in p["steps"]]
    assert ticks == sorted(ticks, reverse=True) and len(ticks) == len(s)


def test_pull_refusals_name_the_tendon():
    with pytest.raises(SurveyError, match="tendon 1: no survey samples"):
        pull_of(1, [], 100, 1)
    with pytest.raises(SurveyError, match="reported no engagement"):
        pull_of(1, ramp(0, 100, 4), None, 1)
    with pytest.raises(SurveyError, match="slack sample"):
        pull_of(1, ramp(40, 100, 4, engaged_at=40), 44, 1)  # started at engagement
    with pytest.raises(SurveyError, match="distinct positions"):
        pull_of(1, ramp(0, 24, 4, engaged_at=12), 16, 1)


def test_view_collects_samples_engagement_and_counts_bad_lines():
    v = SurveyView(2, None, 1)
    v.feed(Report("progress", {"state": "engaged", "tendon": 1, "pos": 4200}, ""))
    v.feed(sv(1, 4210, 5, 6, 7))
    v.feed(sv(1, 4214, 5, 6))  # cut short
    v.feed(Report("dropped", {"reports": 3}, ""))
    v.feed(Report("done", {"mode": "full"}, ""))
    assert v.engaged == {1: 4200} and len(v.samples[1]) == 1 and v.bad == 1 and v.dropped == 3
    assert not v.ok  # a calibration's done is not a survey's
    v.done = Report("done", {"mode": "survey"}, "")
    assert v.ok


def test_a_pull_that_ended_at_its_bound_is_told_by_its_result():
    v = SurveyView(4, None, 1)
    for line in ("<result tendon=0 id=1 home=4400 dB_uT=1068.40 target_uT=1068.75>",
                 "<result tendon=1 id=2 home=4380 dB_uT=812.00 target_uT=1068.75>",
                 "<result tendon=3 id=4 home=4380 dB_uT=812.00 target_uT=0.00>"):
        msg = protocol.parse_line(line)  # as the client reads the board: decimals as text
        v.feed(Report(msg["kind"], msg["fields"], line))
    assert reached(v, 0) == pytest.approx(1.0, abs=1e-3) and reached(v, 0) >= BOUND_SHARE
    assert reached(v, 1) == pytest.approx(0.760, abs=1e-3) and reached(v, 1) < BOUND_SHARE
    assert reached(v, 2) is None  # no result (yet)
    assert reached(v, 3) is None  # no target to compare with


def test_survey_doc_has_the_fit_format_and_every_tendon():
    v = SurveyView(2, None, 1)
    for t in (0, 1):
        v.samples[t] = ramp(1000, 1100, 4, engaged_at=1040)
        v.engaged[t] = 1044
    doc = survey_doc("r", "0x1", v, {0: 1, 1: 1}, [])
    assert doc["format"] == "hallhome-survey" and doc["version"] == 1
    assert [p["tendon"] for p in doc["pulls"]] == [0, 1] and "weights" not in doc
    v.samples.pop(1)
    with pytest.raises(SurveyError, match="tendon 1"):
        survey_doc("r", "0x1", v, {}, [])


def test_weight_tendons_first_of_each_segment_or_all():
    rows = [Report("tendon", {"tendon": i, "segment": 1 + i // 3}, "") for i in range(6)]
    assert weight_tendons(rows, "segment") == [0, 3]
    assert weight_tendons(rows, "all") == list(range(6))


class FakeBoard:
    """Answers `sensors` with the field of whatever weight hangs now."""

    def __init__(self):
        self.hung = False
        self.reads = 0

    def command(self, line, timeout=None):
        assert line == "sensors"
        self.reads += 1
        b = (150.0, 0.5, -2.0) if self.hung else (100.0, 0.5, -2.0)

        class R:
            def of(_, kind):
                return [Report("sensor", {"index": 0, "ok": 1, "bx_uT": b[0], "by_uT": b[1],
                                          "bz_uT": b[2]}, "")]
        return R()


def test_record_weights_reads_before_and_with_the_mass():
    board, asked = FakeBoard(), []

    def wait(msg):
        asked.append(msg)
        board.hung = msg.startswith("hang")

    recs = record_weights(board, [0, 3], [80.0], 4, 1, wait)
    assert [r["tendon"] for r in recs] == [0, 3]
    assert recs[0]["baseline_cuT"] == [[10000.0, 50.0, -200.0]]
    assert recs[0]["field_cuT"] == [[15000.0, 50.0, -200.0]]
    assert len(asked) == 4 and "tendon 3" in asked[2] and board.reads == 16


def test_two_masses_are_hung_in_turn_on_each_tendon():
    board, asked = FakeBoard(), []

    def wait(msg):
        asked.append(msg)
        board.hung = msg.startswith("hang")

    recs = record_weights(board, [0, 3], [40.0, 120.0], 4, 1, wait)
    assert [(r["tendon"], r["mass_g"]) for r in recs] == [(0, 40.0), (0, 120.0), (3, 40.0),
                                                          (3, 120.0)]
    assert [m.split(",")[0] for m in asked if m.startswith("hang")] == [
        "hang 40 g on tendon 0", "hang 120 g on tendon 0", "hang 40 g on tendon 3",
        "hang 120 g on tendon 3"]
    assert board.reads == 32


def test_record_weights_refuses_a_missing_sensor():
    with pytest.raises(SurveyError, match="1 sensor"):
        record_weights(FakeBoard(), [0], [80.0], 4, 2, lambda m: None)


def test_samples_taken_at_take_up_speed_near_the_engagement_are_left_out():
    # flat at 19 ticks a sample, then the approach at 3 ticks a sample from 1100
    s = [Sample(p, [[100, 0, 0]]) for p in range(900, 1080, 19)]
    s += [Sample(1081, [[400, 0, 0]])]  # at speed past the true engagement: lagging field
    s += [Sample(p, [[100 + 10 * (p - 1060), 0, 0]]) for p in range(1084, 1160, 3)]
    p = pull_of(0, s, 1090, 1)
    ticks = [st[0] for st in p["steps"]]
    assert 1081 not in ticks and 1084 in ticks and 900 in ticks  # flat part kept


def test_the_top_of_the_range_past_the_engagement_is_left_out():
    s = ramp(1000, 1201, 4, engaged_at=1040)  # engaged 1044, top 1200
    p = pull_of(0, s, 1044, 1)  # KEEP_RANGE 0.85: up to 1044 + 0.85 * 156 = 1176.6
    ticks = [st[0] for st in p["steps"]]
    assert max(ticks) == 1176 and 1000 in ticks
    s = ramp(5000, 4799, 4, dirn=-1, engaged_at=4960)  # negative pull: 4956 down to 4800
    ticks = [st[0] for st in pull_of(0, s, 4956, -1)["steps"]]
    assert min(ticks) == 4824  # 4956 - 0.85 * 156 = 4823.4


def test_a_console_log_becomes_a_survey_with_the_bench_weights(tmp_path):
    from hallhome.op_survey import from_log, main, parse_report
    lines = ["[  1.0] <progress state=start mode=full tension_mN=1500>"]
    for t in (0, 1):
        lines.append(f"[  2.0] <progress state=engaged tendon={t} pos=1044>")
        lines += [f"[  2.1] <sv t={t} p={p} b={100 + 10 * max(0, p - 1040)},0,0>"
                  for p in range(1000, 1100, 4)]
    lines.append("[  9.0] <done mode=survey target=delta time_ms=8000 tension_mN=1500 count=0>")
    assert parse_report(lines[-1]).get("mode") == "survey" and parse_report("ok") is None
    doc = from_log(lines, "r", 2, 1)
    assert [p["tendon"] for p in doc["pulls"]] == [0, 1]
    log, bench, out = tmp_path / "log.txt", tmp_path / "bench.json", tmp_path / "s.json"
    log.write_text("\n".join(lines))
    bench.write_text(json.dumps({"robot": "r", "pulls": [{"baseline_cuT": [[0, 0, 0]]}] * 2,
                                 "weights": [{"tendon": 0, "mass_g": 80}], "truth": {"x": 1}}))
    assert main([str(log), str(bench), str(out)]) == 0
    got = json.loads(out.read_text())
    assert got["weights"] == [{"tendon": 0, "mass_g": 80}] and got["truth"] == {"x": 1}
    assert got["source"] == "board survey, bench weights"
    # a survey the board did not finish is refused, nothing written
    log.write_text("\n".join(lines[:-1] + ["<fault reason=aborted code=20 dev=none index=0>"]))
    out.unlink()
    assert main([str(log), str(bench), str(out)]) == 1 and not out.exists()


def test_a_second_mass_too_light_or_alone_is_refused_before_the_board():
    from click.testing import CliRunner

    from hallhome.cli import main

    for args in (["--weight-g", "80", "--weight2-g", "100"], ["--weight2-g", "120"]):
        r = CliRunner().invoke(main, ["identify", "survey", "--port", "/dev/null-none", *args])
        assert r.exit_code == 2 and "--weight2-g" in r.output and "1.5 times" in r.output, r.output


# --- held pulls (`survey T H`) -------------------------------------------------------

def scan_lines(t, kink, start, stop, step=2, per=4, restart_from=None):
    """A scan's <sv> lines (one sensor): `per` samples at each point from
    start to stop, flat (100, 0, 0) before the kink and rising after; with
    restart_from, a first point there (engaged, its field held up) before
    the scan starts again at start."""
    pts = ([restart_from] if restart_from is not None else []) + list(range(start, stop, step))
    return [f"<sv t={t} p={p} b={100 + 100 * max(0, p - kink) + k % 2},0,0>"
            for p in pts for k in range(per)]


def held_lines(t, h, free_kink=1040, held_kink=1020, hold_pos=1300, restart=False):
    """A `survey T H` run's console lines: tendon t's scan alone, h's pull
    (not streamed), the hold, t's scan held."""
    return (["<progress state=start mode=single tension_mN=937>",
             f"<progress state=engaged tendon={t} pos={free_kink + 6}>"]
            + scan_lines(t, free_kink, free_kink - 30, free_kink + 30)
            + [f"<progress state=engaged tendon={h} pos=1030>",
               f"<progress state=hold tendon={h} id={h + 1} pos={hold_pos}>",
               f"<progress state=engaged tendon={t} pos={held_kink + 20}>"]
            + scan_lines(t, held_kink, held_kink - 30, held_kink + 30,
                         restart_from=held_kink + 4 if restart else None)
            + ["<done mode=survey target=delta time_ms=9000 tension_mN=937 count=0>"])


def pull_lines(t, engaged=1040, start=1000, stop=1100):
    """A survey run's console lines for one pulled tendon: flat then rising."""
    lines = ["<progress state=start mode=full tension_mN=1500>",
             f"<progress state=engaged tendon={t} pos={engaged + 4}>"]
    lines += [f"<sv t={t} p={p} b={100 + 10 * max(0, p - engaged)},0,0>"
              for p in range(start, stop, 4)]
    return lines + ["<done mode=survey target=delta time_ms=4000 tension_mN=1500 count=0>"]


def test_held_records_from_a_log_of_several_runs(capsys):
    from hallhome.op_survey import from_log

    lines = pull_lines(0)[:-1] + pull_lines(1)[1:]  # the survey of both
    lines += held_lines(1, 0, restart=True)
    lines += held_lines(0, 1)[:-1] + ["<fault reason=aborted code=1 dev=none index=0>"]
    doc = from_log(lines, "r", 2, 1)
    assert [p["tendon"] for p in doc["pulls"]] == [0, 1]
    assert len(doc["held"]) == 1  # the aborted one left out, named
    h = doc["held"][0]
    assert (h["tendon"], h["hold_tendon"], h["hold_ticks"]) == (1, 0, 1300)
    # each scan: its points averaged, the first point its baseline; the held
    # scan from where it started again (the engaged first point dropped)
    assert [s[0] for s in h["free_steps"]][:2] == [1010, 1012]
    assert [s[0] for s in h["steps"]][:2] == [990, 992]
    assert h["baseline_cuT"] == [[100.5, 0.0, 0.0]]
    assert h["free_baseline_cuT"] == [[100.5, 0.0, 0.0]]
    assert h["steps"][-1][1] == [[100.5 + 100 * 28, 0.0, 0.0]]
    assert "held pull left out (tendon 1 held)" in capsys.readouterr().err


def test_held_record_kinks_give_the_shift_between_the_two_scans():
    """The fit's loader: the shift between the two scans' kinks, not against
    the pull alone's (whose kink lies elsewhere here)."""
    from hallhome.identify_data import _held, _pull_arrays
    from hallhome.op_survey import SurveyView, held_of, parse_report
    from hallhome.paths import ROBOTS_DIR
    from hallhome.robot import load_robot

    robot = load_robot(ROBOTS_DIR / "paper_2seg.toml")
    ns = len(robot.sensors)
    v = SurveyView(6, None, ns)
    for line in held_lines(1, 0, 1040, 1020):
        r = parse_report(line.replace(",0,0>", ",0,0" + ",0,0,0" * (ns - 1) + ">"))
        if r is not None:
            v.feed(r)
    rec = held_of(v, {1: 1})
    pull = {"baseline_cuT": [[0, 0, 0]] * ns,
            "steps": [[900 + 10 * k, [[0, 0, 0]] * ns] for k in range(8)]
            + [[980 + 10 * k, [[2000 * (k + 1), 0, 0]] * ns] for k in range(4)]}
    parsed = {i: _pull_arrays(pull, ns, "p") for i in (0, 1)}
    held = _held(rec, 0, parsed, robot)
    m = robot.tendons[1].metres_per_tick
    assert held.shift == pytest.approx(-20 * m, abs=0.3 * m)
    assert held.hold_take_up == pytest.approx((1300 - 900) * robot.tendons[0].metres_per_tick)


def test_held_of_refuses_a_run_without_a_hold():
    from hallhome.op_survey import held_of

    v = SurveyView(2, 1, 1)
    for line in pull_lines(1):
        v.feed(protocol_report(line))
    with pytest.raises(SurveyError, match="not a held pull"):
        held_of(v, {1: 1})
    v = SurveyView(2, 1, 1)  # a hold, but no scan before it
    for line in held_lines(1, 0):
        if "state=hold" in line or "<sv" not in line:
            v.feed(protocol_report(line))
    with pytest.raises(SurveyError, match="no scan of the pulled tendon"):
        held_of(v, {1: 1})


def protocol_report(line):
    from hallhome.op_survey import parse_report
    return parse_report(line)


def test_held_pairs_follow_the_bench_rule():
    from hallhome.identify_data import held_pairs
    from hallhome.paths import ROBOTS_DIR
    from hallhome.robot import load_robot

    # three tendons 120 degrees apart per segment: the first of each pair
    assert held_pairs(load_robot(ROBOTS_DIR / "paper_2seg.toml")) == [
        (0, 1), (1, 0), (2, 0), (3, 4), (4, 3), (5, 3)]


def scripted_survey_board(n=6, refuse_held=None):
    """A board whose `survey` and `survey T H` stream ramps (one sensor)."""
    from fakeboard import FakeBoard

    b = FakeBoard()
    rows = [f"<tendon tendon={t} id={t + 1} dir=1 segment={1 + t // 3} sensor=0>"
            for t in range(n)]
    b.answers["table"] = [f"<table name=paper_2seg table_id=0x1 tendons={n} sensors=1>"] + rows

    def survey(line):
        args = [int(x) for x in line.split()[1:]]
        if len(args) == 2 and refuse_held:
            return refuse_held
        if len(args) == 2:
            t, h = args
            lines = held_lines(t, h, hold_pos=1300 + h)
        else:
            lines = ["<progress state=start mode=full tension_mN=1500>"]
            for t in range(n):
                lines += pull_lines(t)[1:-1]
            lines.append("<done mode=survey target=delta time_ms=28000 tension_mN=1500 "
                         "count=0>")
        b.events.extend(lines)
        return []
    b.answers["survey"] = survey
    return b


def run_survey(monkeypatch, tmp_path, board, *args):
    from click.testing import CliRunner

    from fakeboard import use
    from hallhome import op_survey
    from hallhome.cli import main

    use(monkeypatch, board, op_survey)
    out = tmp_path / "s.json"
    r = CliRunner().invoke(main, ["identify", "survey", "--port", "fake", "--out", str(out),
                                  *args])
    return r, out


def test_identify_survey_runs_the_held_pulls_after_the_pulls_alone(monkeypatch, tmp_path):
    b = scripted_survey_board()
    r, out = run_survey(monkeypatch, tmp_path, b)
    assert r.exit_code == 0, r.output
    assert b.sent == ["table", "survey", "survey 0 1", "survey 1 0", "survey 2 0", "survey 3 4",
                      "survey 4 3", "survey 5 3"]
    doc = json.loads(out.read_text())
    assert len(doc["pulls"]) == 6
    assert [(h["tendon"], h["hold_tendon"], h["hold_ticks"]) for h in doc["held"]] == [
        (0, 1, 1301), (1, 0, 1300), (2, 0, 1300), (3, 4, 1304), (4, 3, 1303), (5, 3, 1303)]
    assert "held pull 6 of 6" in r.output and "6 held pulls" in r.output
    # --no-held: the pulls alone only
    b = scripted_survey_board()
    r, out = run_survey(monkeypatch, tmp_path, b, "--no-held")
    assert r.exit_code == 0 and b.sent == ["table", "survey"]
    assert "held" not in json.loads(out.read_text())


def test_identify_survey_without_held_pulls_on_an_older_firmware(monkeypatch, tmp_path):
    b = scripted_survey_board(refuse_held="error:5 too many arguments")
    b.check = False  # the host's declaration has the argument; this board's has not
    r, out = run_survey(monkeypatch, tmp_path, b)
    assert r.exit_code == 0, r.output
    assert b.sent == ["table", "survey", "survey 0 1"]
    assert "runs no held pulls" in r.output and "held" not in json.loads(out.read_text())


def test_identify_survey_help_documents_the_held_pulls():
    from click.testing import CliRunner

    from hallhome.cli import main

    r = CliRunner().invoke(main, ["identify", "survey", "--help"])
    assert r.exit_code == 0
    assert "--no-held" in r.output and "Held pulls" in r.output and "--robot" in r.output
