"""The benchmark report builder (bench/stats.py, bench/report.py, the parsers
of bench/native.py and bench/simavr.py) on known inputs."""
import math
import os
import sys

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from bench import native, report, simavr, stats  # noqa: E402


def test_mean_sd_is_the_sample_sd():
    m, sd = stats.mean_sd([1.0, 2.0, 3.0, 4.0])
    assert m == pytest.approx(2.5)
    assert sd == pytest.approx(math.sqrt(5.0 / 3.0))
    assert stats.mean_sd([7.0]) == (7.0, 0.0)
    m, sd = stats.mean_sd([])
    assert math.isnan(m) and sd == 0.0
    assert stats.mean_sd([1.0, float("nan"), 3.0, None]) == (2.0, pytest.approx(math.sqrt(2.0)))


def test_repeatability_table_one():
    # tendon 0 always on the same tick, tendon 1 alternating one tick apart
    homes = {0: [100] * 10, 1: [200, 201] * 5}
    r = stats.repeatability(homes, 0.0061)
    assert r["per_tendon_mm"][0] == 0.0
    sd1 = stats.mean_sd([200, 201] * 5)[1]
    assert r["per_tendon_mm"][1] == pytest.approx(sd1 * 0.0061)
    assert r["avg_mm"] == pytest.approx(sd1 * 0.0061 / 2)
    assert r["n"] == {0: 10, 1: 10}
    assert r["max_spread_ticks"] == 1


def test_accuracy_per_cell_segment_and_overall():
    rows = [(0.5, 1, 0.51), (0.5, 1, 0.53), (0.5, 2, 0.49), (0.8, 2, 0.80), (0.8, 1, float("nan"))]
    a = stats.accuracy(rows)
    m, sd, n = a["cells"][(0.5, 1)]
    assert (m, n) == (pytest.approx(0.02), 2)
    assert sd == pytest.approx(math.sqrt(2) * 0.01)
    assert a["segments"][2][:1] == (pytest.approx(-0.005),)
    m, sd, n = a["all"]
    assert n == 4
    assert m == pytest.approx((0.01 + 0.03 - 0.01 + 0.0) / 4)


def test_sensitivity_ranks_the_driving_parameter_first():
    rng = __import__("numpy").random.default_rng(3)
    x1 = rng.uniform(-1, 1, 400)
    x2 = rng.uniform(-1, 1, 400)
    x3 = rng.uniform(-1, 1, 400)
    y = 0.1 * x2 + 0.01 * x1 + 0.0001 * rng.normal(size=400)
    r = stats.sensitivity({"a": x1, "b": x2, "c": x3, "flat": [0.0] * 400}, y)
    assert [d["name"] for d in r][:2] == ["b", "a"]
    assert "flat" not in [d["name"] for d in r]
    assert r[0]["r2"] == pytest.approx(1.0, abs=1e-3)
    assert sum(d["share"] for d in r) == pytest.approx(r[0]["r2"])


def test_oat_slopes():
    rows = [("g", -0.05, -0.01), ("g", 0.0, 0.0), ("g", 0.05, 0.01), ("h", -0.05, 0.0),
            ("h", 0.05, 0.0)]
    r = stats.oat_slopes(rows)
    assert r[0]["group"] == "g"
    assert r[0]["slope_N"] == pytest.approx(0.2)
    assert r[0]["range_N"] == pytest.approx(0.02)
    assert r[1]["range_N"] == 0.0


def test_goal_status():
    assert stats.goal(0.005, 0.0061) == "met"
    assert stats.goal(0.007, 0.0061) == "missed"
    assert stats.goal(-0.03, 0.02, "abs") == "missed"
    assert stats.goal(-0.01, 0.02, "abs") == "met"
    assert stats.goal(None, 1.0) == "not measured"
    assert stats.goal(float("nan"), 1.0) == "not measured"


def test_parse_closedloop_output():
    text = ("home,0,1,270,270.394,-0.394,0.7970,-0.0030,4549,none\n"
            "summary,runs=1,faults=0,max_abs_err_ticks=0.606,mean_sim_ms=4554\n")
    out = native.parse_closedloop(text)
    assert out["homes"][0]["tendon"] == 1
    assert out["homes"][0]["tension_N"] == pytest.approx(0.797)
    assert out["summary"]["mean_sim_ms"] == 4554


def test_parse_cols_output():
    text = "cols,amb,dA_uT,mode,err_N\namb,50.00,abs_ideal,0.0123\namb,0,delta_loop,nan\n"
    rows = native.parse_cols(text)["amb"]
    assert rows[0] == {"dA_uT": 50.0, "mode": "abs_ideal", "err_N": pytest.approx(0.0123)}
    assert math.isnan(rows[1]["err_N"])


def test_parse_bench_console():
    text = ("Loaded 80250 .text\n"
            "[  2.463825] <result tendon=0 id=1 home=4324 home_um=26532 dB_uT=106.91>\n"
            "[  8.600157] <done mode=full time_ms=7972 tension_mN=800 count=1>\n"
            "[  8.7] ok\n")
    lines = simavr.parse_console(text)
    assert len(lines) == 3
    assert lines[0]["rep"]["_kind"] == "result" and lines[0]["rep"]["home"] == "4324"
    assert lines[1]["t"] == pytest.approx(8.600157)
    assert lines[1]["rep"]["time_ms"] == "7972"
    assert lines[2]["rep"] == {}


def test_read_cfg(tmp_path):
    p = tmp_path / "r.cfg"
    p.write_text("nm_per_tick = 6000\ntendon.*.segment = 1\ntendon.0.angle_deg = 0\n"
                 "tendon.1.segment = 2 # distal\n")
    c = native.read_cfg(str(p))
    assert c["nm_per_tick"] == 6000.0
    assert c["segment"] == [1, 2]


def _results():
    per = {str(i): 0.001 * i for i in range(6)}
    acc = {"cells": [{"target_N": 0.5, "segment": 1, "mean_N": 0.01, "sd_N": 0.002, "n": 5}],
           "segments": [{"segment": 1, "mean_N": 0.01, "sd_N": 0.002, "n": 5}],
           "all": {"mean_N": 0.01, "sd_N": 0.002, "n": 5}}
    return {
        "meta": {"date": "d", "git": "g", "config": "c", "reduced": True, "mm_per_tick": 0.0061},
        "repeat": {"runs": 10, "native": {"per_tendon_mm": per, "avg_mm": 0.0025,
                                          "max_spread_ticks": 1, "max_abs_err_ticks": 0.6},
                   "simavr": {"not_measured": "bench off"}},
        "accuracy": {"native": acc, "simavr": {"not_measured": "bench off"},
                     "table_diag": {"rows": [
                         {"target_N": 0.8, "tendon": t, "segment": 1 + t // 2, "gen_sensor": 0,
                          "plant_sensor": t, "gen_target_uT": 100.0, "plant_target_uT": 110.0,
                          "ideal_err_N": 0.04 + 0.001 * (t // 2)} for t in range(4)]}},
        "time": {"native": {"full_s": 4.5, "full_max_s": 13.0, "n_full": 3, "quick_s": 2.0,
                            "n_quick": 1}, "simavr": {"not_measured": "bench off"}},
        "robust": {"runs": 3, "frac": 0.05, "tension_mN": 800,
                   "levels": [{"frac": 0.05, "runs": 3, "n": 18, "faults": 0, "mean_N": 0.01,
                               "sd_N": 0.05, "p5_N": -0.1, "p95_N": 0.1, "max_abs_N": 0.2}],
                   "ranking": [{"name": "moment", "share": 0.5, "corr": -0.7, "beta": -0.7,
                                "r2": 0.6}],
                   "oat": [{"group": "moment", "range_N": 0.08, "slope_N": -0.8, "x": [-0.05, 0.05],
                            "mean_err_N": [0.04, -0.04]}], "err_N": [0.01, -0.02, None]},
        "straight": {"nominal_seeds": 1, "perturbed_seeds": 0, "tol_N": 0.05, "tip_tol_mm": 0.5,
                     "rows": [{"kind": "nominal", "tension_mN": 800, "runs": 1, "failed": 0,
                               "errors": [], "unreported": 0, "tip_max_mm": 0.01,
                               "goal_met": False,
                               **{k: {"n": 6, "mean_N": m, "sd_N": 0.01, "min_N": m - 0.02,
                                      "max_N": m + 0.02, "max_abs_N": m + 0.02}
                                  for k, m in (("alone", 0.04), ("straight", 0.05),
                                               ("paper", 3.5))}}]},
        "ambient": {"dirs": 1, "tension_mN": 800,
                    "bench": [{"mode": "absolute", "dA_uT": 50.0, "ok": True, "mean_N": 0.04,
                               "max_abs_N": 0.045, "max_home_shift_ticks": 1.0},
                              {"mode": "field change", "dA_uT": 100.0, "ok": False,
                               "error": "exit 1"}],
                    "modes": {
            "abs_ideal": [{"dA_uT": 50, "n": 6, "failed": 0, "mean_N": 0.1, "rms_N": 0.2,
                           "max_abs_N": 0.4}]}},
        "resources": {"flash_bytes": 80000, "ram_bytes": 4000, "flash_pct": 30.5, "ram_pct": 48.8,
                      "bus": {"sync_wire_ms": 1.54}, "sensor_rate_hz": [99.0]},
        "identify": {"weight_g": 80.0, "goals": stats.ID_GOALS, "wall_s": 12.0,
                     "sets": [_id_set(0.05, 0.05), _id_set(0.10, 0.25),
                              _id_set(0.05, 0.05, description_friction=0.0)]},
    }


def _id_set(perturb, stiffness, description_friction=None):
    """An identification set of two robots with two tendons, errors made up:
    nominal +0.05 N off, survey only +0.03 N, with weights 0.0 +- 0.005 N
    except one tendon 0.05 N off at 1.5 N. With ``description_friction``: a
    description with that friction, fitted with one weight and with two
    masses per segment (+0.002 N everywhere, the friction 0.5 mN off)."""
    err = {"nominal": [[[0.05] * 3] * 2] * 2, "survey": [[[0.03] * 3] * 2] * 2,
           "weights": [[[0.005, -0.005, 0.0], [-0.005, 0.005, 0.05]],
                       [[0.005, -0.005, 0.0], [-0.005, 0.005, 0.0]]],
           "tendons": [[[0.001, -0.001, 0.0]] * 2] * 2}
    extra = {}
    if description_friction is not None:
        err = {"nominal": err["nominal"], "weights": err["weights"],
               "friction": [[[0.002] * 3] * 2] * 2}
        extra = {"description_friction_mN": description_friction,
                 "parameter_rms_error": {"friction": {"friction": 0.5}},
                 "refused": {"weights": 0, "friction": 0}, "refusals": []}
    import numpy as np

    def summary(e):
        e = np.array(e)
        rows = {f"{t:g}": e[:, :, n] for n, t in enumerate((0.3, 0.8, 1.5))}
        rows["all"] = e
        return {k: {"mean": float(v.mean()), "sd": float(v.std(ddof=1)),
                    "worst": float(np.abs(v).max()), "n": v.size} for k, v in rows.items()}

    return {"seeds": [1, 2], "perturb": perturb, "perturb_stiffness": stiffness,
            "radius_mm": [[4.5, 4.6], [4.5, 4.4]], "weighted_tendon": [0, 0],
            "refused": {"survey": 1, "weights": 0, "tendons": 0},
            "refusals": ["seed 2 survey: length_1 = 42.4 mm reached the edge"],
            "fit_s": {"mean": 9.0, "max": 14.0}, "errors": err,
            **{m: summary(e) for m, e in err.items()}, **extra}


def test_goals_fall_back_to_the_native_loop_and_say_so():
    g = report.goals_table(_results())
    assert [x["status"] for x in g] == ["met", "missed", "met", "met"]
    assert all("native loop" in x["source"] for x in g)
    r = _results()
    r["time"]["simavr"] = {"full_s": 8.0, "full_max_s": 9.0, "n_full": 2}
    g = report.goals_table(r)
    assert g[1]["status"] == "met" and g[1]["source"] == "simavr bench"


def test_report_has_every_section_and_passes_the_check(tmp_path):
    text = report.build_report(_results())
    for head in report.SECTIONS:
        assert head in text
    assert "not measured: bench off" in text
    path = tmp_path / "report.md"
    path.write_text(text)
    problems = report.check_report(str(path))
    # no PNGs were drawn here: only the images are missing
    assert problems and all("image" in p for p in problems)
    for name in ("repeatability", "accuracy", "timing", "robustness_hist",
                 "robustness_sensitivity", "ambient", "identify"):
        (tmp_path / f"{name}.png").write_bytes(b"")
    assert report.check_report(str(path)) == []


def test_check_finds_a_missing_section(tmp_path):
    text = report.build_report(_results()).replace(report.SECTIONS[4], "## 5. Something else")
    path = tmp_path / "report.md"
    path.write_text(text)
    assert any("missing section" in p for p in report.check_report(str(path)))


def test_table_diagnosis_groups_tendons_by_segment():
    text = report.build_report(_results())
    assert "| 0.8 | 1 | 0, 1 | 100.0 | 110.0 | 0.0400 |" in text
    assert "| 0.8 | 2 | 2, 3 | 100.0 | 110.0 | 0.0410 |" in text
    assert "differs for tendon(s) 1, 2, 3" in text


def test_bench_ambient_rows():
    text = report.build_report(_results())
    assert "| absolute | 50 | done | 0.0400 | 0.0450 | 1 |" in text
    assert "| field change | 100 | failed: exit 1 |" in text


def test_parse_bus_packets_from_a_trace():
    # sync read of Present Position (addr 132, 4 bytes) of IDs 1 and 2, then a
    # servo reply byte and a write of goal position 512 to ID 1 (device-facts)
    sync_read = "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA".split()
    write = "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89".split()
    lines = [f"bus {1000 + 11 * k} us mcu {b} start {1000 + 11 * k} dir 1"
             for k, b in enumerate(sync_read)]
    lines.append("bus 1300 us servo 0 FF start 1290")
    lines += [f"bus {5000 + 11 * k} us mcu {b} start {5000 + 11 * k} dir 1"
              for k, b in enumerate(write)]
    pk = simavr.parse_bus_packets("\n".join(lines))
    assert [(p["t_us"], p["id"], p["inst"], p["addr"]) for p in pk] == [
        (1000, 0xFE, 0x82, 132), (5000, 1, 0x03, 116)]


def test_not_measured_reasons_do_not_break_tables():
    r = _results()
    r["accuracy"]["simavr"] = {"not_measured": "exit 1; last reports: <a> | <b>"}
    text = report.build_report(r)
    row = [l for l in text.splitlines() if "exit 1; last reports" in l][0]
    assert row.count(" | ") == 5  # six cells: the reason's bar is escaped
    assert "<a> \\| <b>" in row


def test_goals_show_the_previous_run():
    r = _results()
    r["previous"] = {"date": "d0", "git": "abc", "firmware": "0.1",
                     "goals": {"full 6-tendon calibration time (slowest run)": "9.00 s (simavr bench)"}}
    text = report.build_report(r)
    row = [l for l in text.splitlines() if l.startswith("| full 6-tendon")][0]
    assert row.endswith("| 9.00 s (simavr bench) |")
    assert "Previous run: d0, commit abc, firmware 0.1." in text


def test_loop_phases_merge_runs_and_report_the_goal():
    run_a = [{"name": "idle", "passes": 3, "mean_us": 1000.0, "p99_us": 1500.0, "max_us": 1600.0},
             {"name": "engaged", "passes": 1, "mean_us": 5000.0, "p99_us": 5000.0,
              "max_us": 5000.0}]
    run_b = [{"name": "idle", "passes": 1, "mean_us": 2000.0, "p99_us": 2100.0, "max_us": 2100.0},
             {"name": "empty", "passes": 0, "mean_us": 0.0, "p99_us": 0.0, "max_us": 0.0}]
    rows = stats.loop_phases([run_a, run_b, None])
    assert [r["name"] for r in rows] == ["idle", "engaged"]
    idle = rows[0]
    assert idle["passes"] == 4 and idle["runs"] == 2
    assert idle["mean_us"] == pytest.approx(1250.0)
    assert idle["p99_us"] == 2100.0 and idle["max_us"] == 2100.0
    table = "\n".join(report.loop_phase_table({"loop_phases": rows, "loop_phases_src": "x"}))
    assert "| idle | 4 |" in table and "met |" in table
    assert "| engaged | 1 |" in table and "missed |" in table
    assert "not measured" in "\n".join(report.loop_phase_table({}))


def test_identification_goals_say_by_how_much_they_are_missed():
    assert stats.id_goal_cells({"mean": -0.008, "sd": 0.015, "worst": 0.04}) == \
        ["met", "met", "met"]
    assert stats.id_goal_cells({"mean": -0.012, "sd": 0.02, "worst": 0.0626}) == \
        ["missed by 0.0020 N", "missed by 0.0050 N", "missed by 0.0226 N"]
    assert stats.id_goal_cells({"mean": float("nan"), "sd": 0.0, "worst": 0.0})[0] == \
        "not measured"


def test_identification_section_rows_and_notes():
    text = report.build_report(_results())
    sec = text[text.index(report.SECTIONS[7]):]
    rows = [l for l in sec.splitlines() if l.startswith("| 2 x ")]
    # sets x descriptions x (three tensions and all); the third set: two fits
    assert len(rows) == 2 * 4 * 4 + 3 * 4
    assert "| 2 x ±5 % | nominal TOML (today) | 0.3 | +0.0500 | 0.0000 | 0.0500 | " \
        "missed by 0.0400 N / met / missed by 0.0100 N |" in rows
    assert "| 2 x ±10 %, stiffness ±25 % | survey + one weight per segment | 1.5 | +0.0125 | " \
        "0.0250 | 0.0500 | missed by 0.0025 N / missed by 0.0100 N / missed by 0.0100 N |" in rows
    assert ("fits refused: survey only 1, one weight per segment 0, one weight per tendon 0"
            in sec)
    assert "±5 %, one weight per tendon: +0.0000 ± 0.0009 N, worst 0.0010 N (at 0.3 N)" in sec
    assert "every goal met." in sec
    # the error at 1.5 N (0.05 N on the tendon routed further out than the weighted
    # one) against the radius ratio: worked out by hand, r = 0.816
    assert report.radius_correlation(_id_set(0.05, 0.05)) == pytest.approx(0.816, abs=1e-3)
    assert "r = +0.82 at ±5 %" in sec and "1 of 2 survey-only fits at ±5 %" in sec
    # the friction: the description's (perturbed) in the first sets; none in
    # the third, where two masses find it
    assert "at ±5 % the mean error with one weight per segment moves by +0.0125 N" in sec
    assert "which the plant has within the set's spread" in sec
    assert "fits refused: one weight per segment 0, two masses per segment 0" in sec
    assert ("| 2 x ±5 %, description without friction | survey + two masses per segment "
            "(friction fitted) | all three | +0.0020 | 0.0000 | 0.0020 | met / met / met |" in rows)
    assert "has no tendon friction" in sec and "(at m g = 0.78 N) is an effective one" in sec
    assert "the fit finds the friction (rms 0.50 mN from the plant's) and the trend is +0.0000 N" \
        in sec
    assert "±5 %, description without friction, two masses per segment: +0.0020" in sec
    assert "seed 2 survey: length_1" in sec
    assert "worst 0.0500 N (at 1.5 N)" in sec and "missed: SD (missed by 0.0001 N), worst (missed by 0.0100 N)" in sec


def test_identification_taken_from_an_earlier_run_says_which():
    r = _results()
    text = report.build_report(r)
    assert "--identify-from" not in text
    r["identify"]["reused_from"] = {"git": "abc1234", "date": "2026-11-26 20:56 UTC"}
    sec = report.build_report(r)
    sec = sec[sec.index(report.SECTIONS[7]):]
    assert "Measured by the run of abc1234 (2026-11-26 20:56 UTC)" in sec
    assert "| 2 x ±5 % | nominal TOML (today) | 0.3 |" in sec


def test_identification_not_measured_fails_the_check(tmp_path):
    r = _results()
    r["identify"] = {"not_measured": "no bench binary"}
    path = tmp_path / "report.md"
    path.write_text(report.build_report(r))
    problems = report.check_report(str(path))
    assert any(report.SECTIONS[7] in p and "no numeric" in p for p in problems)


def test_position_feedback_of_the_fine_approach_against_its_goal():
    """The fine approach's position-read period (issue 14: every 2 ms at
    most) gets its own row with the goal, met or missed by how much."""
    res = _results()
    res["resources"]["bench_bus"] = {
        "reads": 900, "median_ms": 4.5, "p95_ms": 11.0, "max_ms": 17.0, "window_s": 5.6,
        "by_phase": {"engaged": {"reads": 480, "median_ms": 4.36, "p95_ms": 9.3, "max_ms": 14.4},
                     "tendon": {"reads": 360, "median_ms": 6.45, "p95_ms": 11.4, "max_ms": 17.1}}}
    text = "\n".join(report.section_resources(res))
    row = next(line for line in text.splitlines() if "fine approach (`engaged`)" in line)
    assert "median 4.36 ms" in row and "missed by 2.36 ms" in row and "median 6.45 ms" in row
    res["resources"]["bench_bus"]["by_phase"]["engaged"]["median_ms"] = 1.8
    text = "\n".join(report.section_resources(res))
    assert "at most 2 ms: met" in text
    del res["resources"]["bench_bus"]["by_phase"]
    assert "fine approach (`engaged`)" not in "\n".join(report.section_resources(res))


def test_the_goal_note_on_position_reads_says_met_or_missed():
    from bench import run

    res = _results()
    res["resources"]["bus"] = {"sync_simavr_ms": 1.69}
    res["resources"]["bench_bus"] = {"median_ms": 4.5,
                                     "by_phase": {"engaged": {"median_ms": 4.36}}}
    note = next(n for n in run.goal_notes(res) if "reads the servo positions" in n)
    assert "every 4.50 ms (median)" in note and "every 4.36 ms (median), against issue 14's " \
        "2 ms: missed." in note
    res["resources"]["bench_bus"]["by_phase"]["engaged"]["median_ms"] = 1.61
    note = next(n for n in run.goal_notes(res) if "reads the servo positions" in n)
    assert note.endswith("against issue 14's 2 ms: met.")
    del res["resources"]["bench_bus"]["by_phase"]
    note = next(n for n in run.goal_notes(res) if "reads the servo positions" in n)
    assert "fine approach" not in note


def _board_records():
    # two robots whose fits were accepted (errors: 6 tendons x 3 tensions) and
    # one refused; seed 2's held run went over the bound
    def rec(seed, err, hold, pulled, survey):
        return {"seed": seed, "runs_done": 7, "runs": 7, "held": 6, "refused": None,
                "errors": [[err, 2 * err, 3 * err]] * 6, "hold_peak_mN": hold,
                "hold_peaks_mN": [hold, hold - 10], "pulled_peaks_mN": [pulled, pulled - 5],
                "survey_peak_mN": survey, "survey_alone_s": 9.0 + seed, "held_s": [8.0, 11.5],
                "survey_s": 60.0 + seed, "fit_s": 30.0 * seed}
    return [rec(1, 0.001, 1200.0, 600.0, 1500.0), rec(2, -0.003, 2000.0, 700.0, 1600.0),
            {"seed": 3, "runs_done": 6, "runs": 7, "held": 0, "refused": "no survey file"}]


def test_board_study_summary_counts_refusals_and_peaks():
    from bench import held_board

    s = held_board.summary(_board_records(), 0.1, 0.25)
    assert s["seeds"] == [1, 2, 3]
    assert s["errors"]["all"]["n"] == 36  # the refused robot keeps no targets here
    assert s["errors"]["1.5"]["mean"] == pytest.approx(3 * (0.001 - 0.003) / 2)
    assert s["errors"]["0.3"]["worst"] == pytest.approx(0.003)
    assert s["refused"] == [{"seed": 3, "why": "no survey file"}]
    assert s["runs_short"] == [3]
    assert (s["hold_peak_mN"], s["pulled_peak_mN"], s["survey_peak_mN"]) == (2000.0, 700.0, 1600.0)
    assert s["held_s"] == {"min": 8.0, "max": 11.5} and s["fit_s"] == {"min": 30.0, "max": 60.0}


def test_board_rows_and_notes_in_section_7():
    from bench import held_board

    r = _results()
    r["identify_board"] = dict(held_board.summary(_board_records(), 0.1, 0.25), bound_mN=1975.0,
                               wall_s=600.0)
    sec = report.build_report(r)
    sec = sec[sec.index(report.SECTIONS[7]):]
    rows = [l for l in sec.splitlines() if "`survey T H` + one weight" in l]
    assert len(rows) == 4
    assert rows[-1].startswith("| 3 x ±10 %, stiffness ±25 %, firmware | ")
    assert "| 1.5 | -0.0030 | " in rows[2]
    assert "of a held tendon 2000 mN" in sec and "against the bounded pull's 1975 mN (**over it**)" in sec
    assert "fits refused (scored with the nominal targets): 1 (seed 3: no survey file)" in sec
    assert "did not end in `<done>`: seeds [3]" in sec
    r["identify_board"]["hold_peak_mN"] = 1500.0
    assert "(within it)" in report.build_report(r)
    r["identify_board"] = {"not_measured": "skipped (--reduced or --board-seeds 0)"}
    sec = report.build_report(r)
    assert "| - | the board's `survey` and `survey T H`" in sec and "--board-seeds 0" in sec


def test_the_identification_plot_puts_the_board_beside_the_set_of_its_spread(tmp_path):
    from bench import held_board, plots

    board = dict(held_board.summary(_board_records(), 0.1, 0.25), records=_board_records())
    ten = {"perturb": 0.1, "perturb_stiffness": 0.25}
    five = {"perturb": 0.05, "perturb_stiffness": None}
    e = plots._board_errors(board, ten)
    assert e.shape == (2, 6, 3)  # the robots whose errors are known
    assert plots._board_errors(board, five) is None
    assert plots._board_errors({"not_measured": "skipped"}, ten) is None
    r = _results()
    assert os.path.exists(os.path.join(tmp_path, plots.identify(r["identify"], str(tmp_path),
                                                                board)))


def test_the_board_item_says_why_it_was_not_measured(tmp_path):
    from types import SimpleNamespace

    from bench import run

    elf = tmp_path / "fw.elf"
    elf.write_text("")
    a = SimpleNamespace(board_seeds=None, reduced=True, hh_bench=str(tmp_path / "none"),
                        elf=str(elf), robot=str(elf), jobs=1, config="x")
    res = {}
    run.board_item(a, res)
    assert res["identify_board"] == {"not_measured": "skipped (--reduced or --board-seeds 0)"}
    a.reduced, a.board_seeds = False, 3
    run.board_item(a, res)
    assert res["identify_board"]["not_measured"] == f"no bench binary at {tmp_path / 'none'}"
    a.hh_bench, a.elf = str(elf), str(tmp_path / "gone.elf")
    run.board_item(a, res)
    assert res["identify_board"]["not_measured"].startswith("no firmware ELF at ")
