"""The chaos suite's short fixed set (`make chaos-test`, part of `make test`)
and the checks of the harness itself.

The fixed set runs a few seeded schedules end to end on the virtual bench
and fails on any invariant violation (docs/chaos.md). Seeds in KNOWN_FAILING
fail on firmware faults not fixed yet: they still run and their violations
are reported (pytest -rx shows them), marked expected failures, not
skipped; a seed that passes passes (and should then leave the list).
"""

import subprocess

import pytest

from . import check as chk
from . import robots as rb
from . import runner
from . import schedule as sc

# Small robots (each schedule about 10-40 s wall); together they hit the
# recovery, release and bounded-pull invariants.
FIXED = [3, 5, 9, 10, 187,
         # a run after a servo timeout brings the servos up again first (a servo silent
         # past its Bus Watchdog refused every goal: the next run stalled)
         1029,
         1021]
# seed: what fails on the firmware of this commit (docs/chaos.md). Seeds 3, 5,
# 9, 10 and 187 were here (tendons pulled to 1.4-4x their target): the slack a
# calibrated tendon keeps was too small for the other tendons' pulls, which
# took it up and made it an antagonist; with the margin at least the tendon's
# own travel (docs/homing.md, "Release decision") they pass.
KNOWN_FAILING = {
    1021: "12-tendon robot c2s12t4k77d98: while tendon 4 is pulled, tendon 5 (not yet "
          "calibrated in that run) carries 1452 mN, 1.81x its target (1100 mN allowed): it "
          "was not slack enough for tendon 4's pull, in the run after an external reset and "
          "a field-rate fault",
}


@pytest.fixture(scope="module")
def pool():
    if not runner.BENCH.exists():
        pytest.fail(f"{runner.BENCH} missing: run `make sim-build`")
    return rb.pool()


@pytest.mark.parametrize("seed", FIXED)
def test_schedule(seed, pool):
    r = runner.run_one(seed, pool)
    msgs = [f"{k}: {m}" for k, v in r["violations"].items() for m in v]
    if msgs and seed in KNOWN_FAILING:
        # runs in full and reports what it measured; passes once fixed
        pytest.xfail(f"{KNOWN_FAILING[seed]} | measured: " + "; ".join(msgs))
    assert not msgs, (f"seed {seed} [{r['robot']}], faults "
                      + ", ".join(f"{t}@{p}" for t, p in r["faults"])
                      + f"; replay: {runner.replay_line(seed)}\n  " + "\n  ".join(msgs))


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
