"""The chaos suite's short fixed set (`make chaos-test`, part of `make test`)
and the checks of the harness itself.

The fixed set runs a few seeded schedules end to end on the virtual bench
and fails on any invariant violation (docs/chaos.md). Seeds in KNOWN_FAILING
fail on firmware faults not fixed yet: they still run and their violations
are reported (pytest -rx shows them), marked expected failures, not
skipped; a seed that passes passes (and should then leave the list).
"""

import json
import os
import re
import subprocess

import pytest

from . import bustrace as bt
from . import check as chk
from . import robots as rb
from . import runner
from . import schedule as sc

# One schedule per firmware fault the suite found (each schedule about 10-40 s
# wall); `make chaos-regress` runs every seed of tests/chaos/regression_seeds.txt,
# these and the ones left out of this set for `make test`'s time: 3 and 187
# (the slack margin, as 5, 9 and 10 here), 4093 and 5038 (power cycles after a
# release, as 3049). Small robots first; together they hit the recovery,
# release and bounded-pull invariants.
FIXED = [5, 9, 10,
         # a run after a servo timeout brings the servos up again first (a servo silent
         # past its Bus Watchdog refused every goal: the next run stalled)
         1029,
         # 12 tendons: a tendon not slack enough for its neighbour's pull (passes since
         # the slack margin grows with the tension)
         1021,
         # a press 0.4 s after a sensor is plugged back (the bring-up tries it at once)
         1009,
         # a servo silent while idle: its Bus Watchdog cleared once it answers again
         1016,
         # a start line completing a line an overrun cut; a calibration's end is its
         # done or fault, not the release after a servo's reboot
         1027,
         # 12 tendons under bus noise: a lost sync write left a take-up running on
         # (1.52x); every new goal now goes out twice
         2010,
         # a press during a 100 ms burst of `status` output at rest (the tick's press count)
         2035,
         # 24 Bus Watchdog writes in a row after a servo's reboot: servo_timeout
         2049,
         # release, power cycle, release, fault: two releases before a tendon's search
         2065,
         # an early release whose last byte the bench cut; a `!` during `servos` (on
         # another build with a servo's torque off in that bring-up)
         2090,
         # a servo cut off the bus in a take-up (the take-up's goal is a lease)
         3008,
         # an early release after a watchdog reset, under bus noise (sent twice); on
         # another build a servo reboot whose reply noise cut (the bus comes up again)
         3037,
         # watchdogs a 100 ms `status` burst at rest let expire (cleared by broadcast)
         3079,
         # a press while a sensor's periodic retry is in its reset wait
         3195,
         # a servo rebooted while its shaft crossed a turn: its window a turn off
         5015,
         # power cycles that cut runs after their release, before a tendon's take-up
         # (the windows of a power cycle's first run go to the EEPROM before it moves)
         3049,
         # a tendon 50 x softer than its table: released back to where its take-up began
         4039,
         # a reset-pin reset while a run's <done> was still in the output ring
         7071,
         # a watchdog reset in the final move: the early release's wait before the bring-up
         8153,
         # the magnet removed in a tendon's fine approach: the field falls while it pulls
         8390,
         # servo 1 silent in a take-up under bus noise: servo 8 was named (a group read's
         # first silent servo silences the rest; it now goes last)
         2004,
         # a tendon 50 x softer than its table stretched to a 2.5 mm travel limit: slack
         # 105 ms after the fault (the pull now stops at what the servo unwinds in 85 ms)
         11282,
         # the magnet removed at 93 % of the target field: 1-tick fine steps the field did
         # not follow went on to 1.53 x the target
         16518,
         # a servo silent in a take-up, then a field_step stop 110 ms later: its tendon
         # stayed at 0.4 N for 460 ms and the release report did not name it
         17518,
         # a clean calibration of a 12-tendon robot ended in a false field_step after the
         # approach sent a servo back from 218 to 196 (a fall is now judged against the
         # field on the way out where the servo stands)
         17633,
         # a clean calibration of a 12-tendon robot after a watchdog reset in the slack
         # check ended in travel_limit (a stop sent the servo back through the spool's
         # backlash; a stop now allows for the servo's run until the goal lands)
         18451,
         # the last tendon's <result> waited behind a `help` listing and went out after
         # the final move had raised every tendon to the straight pose (1.39 x): the
         # bench now closes the windows at the final move it sees on the bus
         18834,
         # a clean calibration of a 4-tendon robot ended in no_progress (known failing,
         # below)
         19418,
         # an ambient step in a take-up on a 1-sensor robot pulled to 1.45 x: the
         # engagement had been recorded 20 ticks late (a sample judged up to 16 ms after
         # it was measured); now taken where the servo was when it was measured, and the
         # bounded pull's limit holds the first pull
         19346,
         # clean calibrations of 9- and 12-tendon robots ended in travel_limit: their
         # segment-3 tendons travel 1.25 x the table's; a search again now goes to the
         # table's own limit
         20462, 20598]
# seed: what fails on the firmware of this commit (docs/chaos-rounds.md). Seeds 3, 5,
# 9, 10 and 187 were here (tendons pulled to 1.4-4x their target): the slack a
# calibrated tendon keeps was too small for the other tendons' pulls, which
# took it up and made it an antagonist; with the margin at least the tendon's
# own travel (docs/homing.md, "Release decision") they pass.
# (1021 was here: tendon 5 of the 12-tendon robot carried 1.81x its target while
# tendon 4 was pulled, on one build; it passes on every build since the slack
# margin's change, seeds 1000-1039 run three times.)
# (3049 was here: three power cycles, each cutting a run after its release,
# paid tendons 9-11 out three releases, 13 mm, and the search ended in
# no_engagement; the windows now survive a power cycle in EEPROM.)
# (17633 was here: a false field_step after the approach sent tendon 7 back
# from 218 to 196; the field-fall check now compares like with like.)
# (18451 was here: a moderate approach read at 209 while its servo ran on to
# 217 was stopped at 211, back through the spool's backlash; the fine points
# read a flat field and put the target beyond the travel limit. A stop now
# allows for the servo's run until the goal lands, and an engaged tendon is
# only pulled further: test_homing_runon.c.)
KNOWN_FAILING: dict[int, str] = {
    19418: "a clean calibration ended in no_progress on tendon 3 (35 uT target) of "
           "c1s4t2k04561: fine steps of 4-8 ticks crossed the target wider than the 3-tick "
           "bracket four times (back-offs); passes on ff7d839 by timing (docs/chaos-rounds.md)",
}


@pytest.fixture(scope="module")
def pool():
    if not runner.BENCH.exists():
        pytest.fail(f"{runner.BENCH} missing: run `make sim-build`")
    return rb.pool()


# seconds a seed takes on an idle machine, for those over about 15 s: the long
# ones start first (tests/conftest.py)
SLOW_SEEDS = {2035: 45, 20462: 32, 3049: 25, 5015: 22, 8390: 21, 20598: 20, 17518: 19, 5: 18,
              2010: 18}


@pytest.mark.parametrize("seed", [pytest.param(s, marks=pytest.mark.slow(SLOW_SEEDS[s]))
                                  if s in SLOW_SEEDS else s for s in FIXED])
def test_schedule(seed, pool):
    """One seed of the fixed set on the bench (make chaos-test runs the
    suite in one worker per core, pytest -n)."""
    r = runner.run_one(seed, pool)
    msgs = [f"{k}: {m}" for k, v in r["violations"].items() for m in v]
    if msgs and seed in KNOWN_FAILING:
        # runs in full and reports what it measured; passes once fixed
        pytest.xfail(f"{KNOWN_FAILING[seed]} | measured: " + "; ".join(msgs))
    assert not msgs, (f"seed {seed} [{r['robot']}], faults "
                      + ", ".join(f"{t}@{p}" for t, p in r["faults"])
                      + f"; replay: {runner.replay_line(seed)}\n  " + "\n  ".join(msgs))


class _Plain:
    """What _reference_run takes of a schedule: a bench seed, bus noise."""

    def __init__(self, bench_seed: int, base_noise: float):
        self.bench_seed, self.base_noise = bench_seed, base_noise


@pytest.mark.slow(16)
@pytest.mark.parametrize("tendons,sensors", [(10, 2), (11, 4)])
def test_ten_and_eleven_tendons_calibrate_within_the_bounds(tendons, sensors):
    """The pool has robots of 9 and 12 tendons, none of 10 or 11: a robot
    of 10 tendons once faulted `servo_timeout` on index 9 after every press,
    one of 11 reported servo 10 missing although `servos pos` found it
    (issue 13, reproduction 3). On a 3-segment robot of each, under 1e-3
    bus noise: the press right after <ready> completes, every tendon is
    homed within 15 % of the target, and none is pulled past the bound."""
    robot = rb.build(rb.make_robot(900 + tendons, segments=3, tendons=tendons,
                                   sensors=sensors))
    rundir = runner.RUNS / f"tendons{tendons}"
    rundir.mkdir(parents=True, exist_ok=True)
    ref = runner._reference_run(robot, _Plain(tendons, 1e-3), rundir, "clean", 1)
    assert ref is not None, f"no bench summary in {rundir}"
    assert ref["end"].startswith("<done mode=full"), ref["end"]
    summary = json.loads((rundir / "clean-summary.json").read_text())
    target = summary["target_mN"]
    bound = chk.PULL_FACTOR * target + chk.PULL_OFFSET_MN
    assert len(summary["tendons"]) == tendons
    for t in summary["tendons"]:
        assert t["home_reported"], t
        assert abs(t["tension_at_home_mN"] - target) <= 0.15 * target, t
    for t in summary["truth"]["tendons"]:
        assert t["peak_before_home_mN"] <= bound, (t, bound)


# ---- the harness: schedules, robots, checks -----------------------------------

def test_schedule_is_deterministic(pool):
    a, ra = sc.generate(42, pool)
    b, rb_ = sc.generate(42, pool)
    c, _ = sc.generate(43, pool)
    assert a.script() == b.script() and ra.name == rb_.name
    assert a.script() != c.script()


def test_schedules_cover_every_fault_and_phase(pool):
    faults, phases, robots = set(), set(), set()
    for s in range(1, 200):
        sch, r = sc.generate(s, pool)
        faults.update(k for k, _ in sch.faults)
        phases.update(p for _, p in sch.faults)
        robots.add(r.name)
        assert sch.clean_steps, "every schedule ends with a clean calibration"
        assert all(len(ln) < 256 for ln in sch.lines), "the bench reads 255-character lines"
    assert faults == set(sc.FAULTS)
    assert phases == set(sc.PHASES)
    assert robots == {r.name for r in pool}


def test_pool_spans_the_robot_space(pool):
    assert {r.segments for r in pool} == {1, 2, 3}
    assert min(r.tendons for r in pool) == 3 and max(r.tendons for r in pool) == rb.MAX_TENDONS
    assert {r.sensors for r in pool} == {1, 2, 3, 4}


def _summary(**truth):
    base = {"runs": 1, "baselines": 1, "baselines_taut": 0, "baseline_max_mN": 0.0,
            "console": {"lines_sent": 2, "replies": 2, "unanswered": 0, "extra_replies": 0},
            "resets": {"total": 1, "injected": 1}, "max_bus_gap_ms": 10.0, "max_bus_gap_at_s": 1.0,
            "tendons": [{"tendon": 0, "peak_before_home_mN": 830.0, "peak_at_s": 2.0,
                         "max_slack_mm": 1.0, "max_start_slack_mm": 1.0, "paid_out_mm": 2.0}],
            "stops": []}
    base.update(truth)
    return {"exit_code": 0, "target_mN": 800, "steps": {"count": 2, "log": [[1.0, 0]]},
            "truth": base, "tendons": [{"tendon": 0, "tension_at_home_mN": 820.0}]}


CLEAN = """[  1.100000] <progress state=start mode=full tension_mN=800>
[  3.000000] <result tendon=0 id=1 home=4300 home_um=1>
[  3.500000] <done mode=full target=delta time_ms=2400 tension_mN=800 count=1>
[  6.000000] <boot name=hallhome reset=power>
[  6.100000] <ready table=x homes=stored count=1 rehome=1>
[  6.300000] <hist age=0 count=1 table_id=0x1 tension_mN=800 homes=4300>
"""


class _Sch:
    clean_steps = [0]


def test_check_passes_a_clean_run():
    v = chk.check(_Sch(), _summary(), CLEAN)
    assert v.violations == {}
    assert v.figures["peak_ratio"] == pytest.approx(830 / 800)


@pytest.mark.parametrize("truth, inv", [
    ({"tendons": [{"tendon": 0, "peak_before_home_mN": 1101.0, "peak_at_s": 2.0, "max_slack_mm": 1,
                   "max_start_slack_mm": 1, "paid_out_mm": 1}]}, "bounded_pull"),
    ({"tendons": [{"tendon": 0, "peak_before_home_mN": 800.0, "peak_at_s": 2.0, "max_slack_mm": 9,
                   "max_start_slack_mm": 7.5, "paid_out_mm": 9}]}, "recovery"),
    ({"stops": [{"kind": "bang", "t_s": 2.0, "tension_mN": 800, "released_after_ms": 130.0,
                 "tendon_ms": [130.0]}]}, "release"),
    ({"stops": [{"kind": "watchdog", "t_s": 2.0, "tension_mN": 800, "released_after_ms": -1,
                 "tendon_ms": [-1]}]}, "release"),
    ({"baselines_taut": 1, "baseline_max_mN": 40.0}, "release"),
    ({"console": {"lines_sent": 200, "replies": 22, "unanswered": 178, "extra_replies": 0}},
     "replies"),
    ({"max_bus_gap_ms": 250.0}, "timing"),
    ({"resets": {"total": 2, "injected": 1}}, "resets"),
])
def test_check_finds_each_violation(truth, inv):
    v = chk.check(_Sch(), _summary(**truth), CLEAN)
    assert list(v.violations) == [inv], v.violations


def test_check_finds_a_failed_recovery_and_bad_records():
    failed = CLEAN.replace("<done mode=full target=delta time_ms=2400 tension_mN=800 count=1>",
                           "<fault reason=no_engagement code=11 dev=tendon index=0>")
    assert "recovery" in chk.check(_Sch(), _summary(), failed).violations
    lost = CLEAN.replace("homes=stored count=1", "homes=none count=0")
    assert "eeprom" in chk.check(_Sch(), _summary(), lost).violations
    moved = CLEAN.replace("homes=4300", "homes=4290")
    assert "eeprom" in chk.check(_Sch(), _summary(), moved).violations
    off = _summary()
    off["tendons"][0]["tension_at_home_mN"] = 1000.0
    assert "accuracy" in chk.check(_Sch(), off, CLEAN).violations


def test_accuracy_is_judged_against_a_first_or_a_repeat_undisturbed_calibration():
    """A final calibration outside 15 % passes when an undisturbed one of
    the same robot and seed lands within 5 % of target of it: the first of
    a boot, or one after it in the same boot (seed 13335: the first homed a
    tendon 4 ticks early, every later one where the disturbed run did)."""
    off = _summary()
    off["tendons"][0]["tension_at_home_mN"] = 933.0
    done = "<done mode=full target=delta time_ms=2400 tension_mN=800 count=1>"
    first = {"end": done, "tendons": [{"tendon": 0, "tension_at_home_mN": 874.0}]}
    repeat = {"end": done.replace("count=1", "count=2"),
              "tendons": [{"tendon": 0, "tension_at_home_mN": 927.0}]}
    assert "accuracy" in chk.check(_Sch(), off, CLEAN, dict(first)).violations
    assert "accuracy" in chk.check(_Sch(), off, CLEAN, dict(first, repeat=None)).violations
    assert chk.check(_Sch(), off, CLEAN, dict(first, repeat=repeat)).violations == {}
    failed = dict(repeat, end="<fault reason=slack code=14 dev=tendon index=0>")
    assert "accuracy" in chk.check(_Sch(), off, CLEAN, dict(first, repeat=failed)).violations


def test_a_history_line_cut_by_the_end_is_not_a_record():
    """The bench's end cuts a background `history` reply mid-line (seed
    12302: "stored homes 221, calibrated 221,224,224,223"): only whole
    lines count; a whole one that differs still is a violation."""
    cut = CLEAN + "[  9.000000] <hist age=0 count=1 table_id=0x1 tension_mN=800 homes=43"
    assert chk.check(_Sch(), _summary(), cut).violations == {}
    moved = CLEAN + "[  9.000000] <hist age=0 count=1 table_id=0x1 tension_mN=800 homes=4290>\n"
    assert list(chk.check(_Sch(), _summary(), moved).violations) == ["eeprom"]


def test_homes_unread_are_excused_only_after_a_reported_overrun():
    """Every `history` asked for lost to a console overrun the firmware
    reported (seed 21148: the schedule's own flood took the line's end):
    the homes are not read, not wrong. Without such a report an answer
    missing is still a violation."""
    unread = "".join(ln + "\n" for ln in CLEAN.splitlines() if "<hist age=0" not in ln)
    assert unread != CLEAN
    v = chk.check(_Sch(), _summary(), unread)
    assert list(v.violations) == ["eeprom"], v.violations
    reported = unread + "[  9.500000] <overrun bytes=12 total=12>\n"
    v = chk.check(_Sch(), _summary(), reported)
    assert v.violations == {} and v.figures.get("eeprom_homes_unread") == 1, v.violations


def test_a_refused_press_at_rest_is_not_a_stop():
    """A press the board refuses while idle (a sensor missing) moves and
    stops nothing: the robot stays at its homes, as the last calibration
    left it (chaos seed 1018: counted as a stop never released). Any other
    fault report still is a stop."""
    held = {"stops": [{"kind": "fault", "t_s": 4.0, "tension_mN": 900.0, "released_after_ms": -1,
                       "tendon_ms": [-1]}]}
    refused = CLEAN + "[  4.000000] <fault reason=refused error=13 dev=none index=0>\n"
    v = chk.check(_Sch(), _summary(**held), refused)
    assert v.violations == {}, v.violations
    other = CLEAN + "[  4.000000] <fault reason=sensor_error code=4 dev=sensor index=0>\n"
    assert list(chk.check(_Sch(), _summary(**held), other).violations) == ["release"]


def test_a_press_during_a_run_is_answered_by_that_run():
    """A press kept over a release started a run 0.27 s before the final
    press, which the board ignores while a run goes (seed 8387: the checker
    took a background `cal 99`'s error:3 for the final press's answer)."""
    console = [(8.317, "<progress state=start mode=full tension_mN=800>"),
               (8.664, "error:3 argument out of range"),
               (12.0, "<done mode=full target=delta time_ms=1 tension_mN=800 count=1>")]
    a = chk.first_attempt(chk.runs(console), console, 8.59)
    assert a is not None and a["end"].startswith("<done mode=full"), a
    # a run that ended before the press does not answer it
    assert chk.first_attempt(chk.runs(console), console, 12.5) is None


class _SchCut:
    """A clean `cal` (step 1) sent 2.6 s after an overrun cut a long line;
    the final calibration (step 2) 7 s later."""
    clean_steps = [1, 2]
    lines = ["step on ^<ready within 16s +0.5s nop", "step +0.5s send cal",
             "step on ^<fault within 16s +7s press 100",
             "5.078s raw " + "x" * 90 + "\\r\\n", "8.000s send history"]


def test_a_start_line_that_completes_a_line_cut_by_an_overrun_is_excused():
    """36 bytes lost and reported (`<overrun>`), among them a long line's
    line end: the `cal` sent next completes that line and is answered
    `error:6 line too long` (chaos seed 1027). The clean calibration was
    never asked for: excused, not a failed recovery. A `cal` refused with a
    line end sent between the overrun and it is still a violation."""
    later = re.sub(r"\[\s*([0-9.]+)\]", lambda m: f"[{float(m.group(1)) + 14.0:10.6f}]", CLEAN)
    out = ("[  5.091000] <overrun bytes=36 total=36>\n"
           "[  7.800137] error:6 line too long\n") + later
    summ = _summary()
    summ["steps"] = {"count": 3, "log": [[1.0, 0], [7.79, 0], [15.0, 0]]}
    v = chk.check(_SchCut(), summ, out)
    assert "recovery" not in v.violations and v.figures.get("starts_cut_by_overrun") == 1
    assert chk.line_ends_sent(_SchCut(), summ["steps"]["log"]) == [5.078, 7.79, 8.0]
    no_report = out.replace("[  5.091000] <overrun bytes=36 total=36>\n", "")
    assert "recovery" in chk.check(_SchCut(), summ, no_report).violations
    _SchCut.lines = _SchCut.lines + ["6.000s raw help\\r\\nhelp\\n"]
    try:
        assert "recovery" in chk.check(_SchCut(), summ, out).violations
    finally:
        _SchCut.lines = _SchCut.lines[:-1]


def test_a_calibration_ends_only_with_its_done_or_fault():
    """The chain waits for a calibration's end with RUN_END: the reports of
    a release the board makes on its own after a stop are not one (seed
    1027: a `<done mode=release>` after a servo's reboot ended the wait for
    the final calibration, and the power cycle cut it)."""
    assert " " not in sc.RUN_END  # the bench reads a step's pattern up to a space
    end = re.compile(sc.RUN_END)
    for ln in ["<done mode=full target=delta time_ms=1 tension_mN=800 count=1>",
               "<done mode=quick target=delta>", "<done mode=single target=delta>",
               "<fault reason=aborted code=1 dev=none index=0 detail=0>",
               "<fault reason=refused error=13 dev=none index=0>"]:
        assert end.search(ln), ln
    for ln in ["<done mode=release time_ms=453 baseline=1>", "<done mode=home time_ms=9>",
               "<released reason=servo_error id=2>", "<released reason=reset>"]:
        assert not end.search(ln), ln


def test_the_eeprom_save_phase_opens_at_a_calibrations_done_only():
    """Seed 17064: the phase's `^<done` matched the `<done mode=release>` of a
    servo's reboot, so the magnet came off inside the next calibration,
    which the checker then judged as the undisturbed final one."""
    regex = sc.PHASES["eeprom_save"][0]
    assert " " not in regex
    save = re.compile(regex)
    for ln in ["<done mode=full target=delta time_ms=1 tension_mN=800 count=1>",
               "<done mode=quick target=delta>", "<done mode=single target=delta>"]:
        assert save.search(ln), ln
    for ln in ["<done mode=release time_ms=453 baseline=1>", "<done mode=home time_ms=9>"]:
        assert not save.search(ln), ln


def test_a_power_cycle_that_cuts_a_result_line_ends_its_run():
    """A reset cuts a report mid-line and the boot report ends that line: the
    run ends there even when the cut line is a <result> (seed 9140: the
    next calibration's check took the run as still going, "did not end")."""
    out = "\n".join([
        "[  8.715491] <progress state=start mode=full tension_mN=800>",
        "[  9.571681] <result tendon=0 id=1 home=4320 straight=4272 target=delta>",
        "[  9.990896] <result tendon=1 id=2 home=4321 straight=4274 target=d"
        "<boot name=hallhome version=0.1.0 board=\"Arduino Mega 2560\" reset=power>",
        "[ 10.198859] <ready table=x homes=stored count=1 rehome=1>",
    ])
    (a,) = chk.runs(chk.parse_console(out))
    assert a["end_t"] == pytest.approx(9.990896) and "<boot name=" in a["end"]
    assert a["results"] == {0: 4320}


def test_a_reset_pin_reset_at_rest_is_not_a_stop():
    """A reset from the reset pin (a host opening the port) after a
    calibration's <done> leaves the robot at its homes, as docs/app.md has
    it (seeds 2004, 2025: counted as a stop never released). One that cuts
    a run or a release is a stop."""
    held = {"stops": [{"kind": "external", "t_s": 4.0, "tension_mN": 1150.0,
                       "released_after_ms": 1500.0, "tendon_ms": [1500.0]}]}
    assert chk.check(_Sch(), _summary(**held), CLEAN).violations == {}
    cut = {"stops": [dict(held["stops"][0], t_s=2.0)]}  # inside the run (1.1-3.5 s)
    assert list(chk.check(_Sch(), _summary(**cut), CLEAN).violations) == ["release"]
    moving = CLEAN + ("[  3.900000] <released reason=aborted>\n"
                      "[  4.500000] <done mode=release time_ms=450 baseline=1>\n")
    assert list(chk.check(_Sch(), _summary(**held), moving).violations) == ["release"]
    after_fault = CLEAN + ("[  3.800000] <fault reason=sensor_error code=4 dev=sensor index=0>\n"
                           "[  3.810000] <released reason=sensor_error>\n")
    assert chk.check(_Sch(), _summary(**held), after_fault).violations == {}


@pytest.mark.slow(18)
def test_short_travel_homes_are_not_early(pool):
    """At 0.3 N a tendon of the 12-tendon robot travels some 19 ticks from
    engagement to home, and the take-up had run most of it before the field
    showed the engagement (the bus cycle of 12 servos): the servo came back
    through the spool's backlash, the points after it read the field of a
    position further on, and homes came at 0.23-0.26 N. The approach now
    backs off to slack and comes up again (docs/homing.md, "Fine
    approach"). Seeds that showed it; the description leaves out the
    plant's friction, so a home reads some 17 mN high, never low."""
    import json
    r = rb.build(next(x for x in pool if x.segments == 2 and x.tendons == 12))
    for seed in (7307, 7317, 7327):
        summ = rb.BUILD / f"short_travel_{seed}.json"
        p = subprocess.run(
            [str(runner.BENCH), str(r.elf), "--plant", str(r.plant), "--seed", str(seed),
             "--perturb", "0", "--summary", str(summ), "--limit", "60s", "--quiet",
             "--until", "^<done mode=full", "--fail-on", "^<fault",
             "--at", "0.3s send set cal_tension 300", "--at", "0.6s send cal"],
            capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr[-400:]
        homes = [t["tension_at_home_mN"] for t in json.loads(summ.read_text())["tendons"]]
        assert min(homes) >= 280.0, f"seed {seed}: {homes}"


@pytest.mark.slow(38)
def test_surveys_of_the_three_segment_robots_complete(pool):
    """An identification survey pulls every tendon to the top of its grid
    (1.5 N). The segment-3 tendons of the pool's 3-segment robots travel up
    to 25 % further than their tables say, and a pull reached its bound
    (travel_limit, no_progress, tendon_timeout) before its target: 10 of 12
    surveys (these 4 robots, 3 seeds) ended in a fault. Such a pull now ends
    there and the survey goes on (docs/identify.md); a `status` and `table`
    go first, as `hallhome identify survey` sends them."""
    from concurrent.futures import ThreadPoolExecutor
    robots = [rb.build(r) for r in pool if r.segments == 3]
    assert len(robots) >= 3

    def survey(job):
        r, seed = job
        p = subprocess.run(
            [str(runner.BENCH), str(r.elf), "--plant", str(r.plant), "--seed", str(seed),
             "--limit", "120s", "--at", "0.5s send status", "--at", "0.55s send table",
             "--at", "0.9s send survey", "--until", "^<done mode=survey|^<fault"],
            capture_output=True, text=True, timeout=600)
        ends = [ln for ln in p.stdout.splitlines() if "<done" in ln or "<fault" in ln]
        return f"{r.name} seed {seed}: {ends[-1] if ends else p.stderr[-200:]}"

    jobs = [(r, seed) for r in robots for seed in (1, 2)]
    with ThreadPoolExecutor(max_workers=max(1, min(4, os.cpu_count() or 2))) as ex:
        ends = list(ex.map(survey, jobs))
    assert all("<done mode=survey" in e for e in ends), "\n".join(ends)


def _bus_lines(src: str, data: list[int], t_us: int) -> list[str]:
    who = "mcu" if src == "mcu" else f"servo {src}"
    return [f"bus {t_us + 11 * i:8d} us {who} {b:02X} start {t_us + 11 * i}"
            for i, b in enumerate(data)]


def test_bustrace_reads_a_servos_goal_and_position():
    def le(v):
        return list((v & 0xFFFFFFFF).to_bytes(4, "little"))
    write = [0x6C, 0x00, 0x0C, 0x00] + [1] + le(0) + le(90) + le(-154) + [2] + le(0) + le(60) + le(217)
    read = [0x84, 0x00, 0x04, 0x00, 1, 2]
    lines = (_bus_lines("mcu", [0xFF, 0xFF, 0xFD, 0x00, 0xFE, len(write) + 3, 0, 0x83] + write
                        + [0, 0], 1000)
             + _bus_lines("mcu", [0xFF, 0xFF, 0xFD, 0x00, 0xFE, len(read) + 3, 0, 0x8A] + read
                          + [0, 0], 2000)
             + _bus_lines("0", [0xFF, 0xFF, 0xFD, 0x00, 0xFE, 19, 0, 0x55, 0, 1] + le(209)
                          + [0, 0], 3000)
             + _bus_lines("1", [0x80, 2] + le(-211) + [0, 0], 3200)
             + _bus_lines("mcu", [0xFF], 4000))
    ev = bt.decode(lines, 1, 2)
    assert [(e.kind, e.addr, e.values, e.error) for e in ev] == [
        ("write", 108, [0, 60, 217], 0), ("read", 132, [-211], 0x80)]
    assert bt.describe(ev[0]) == "goal 217 at 60 units"
    assert bt.describe(ev[1]) == "position -211 (error 0x80)"
    first = bt.decode(lines, 0, 1)
    assert [(e.kind, e.values) for e in first] == [("write", [0, 90, -154]), ("read", [209])]
