# The randomized fault suite (docs/chaos.md): seeded schedules of faults,
# aborts, resets and console traffic on random robots, every invariant of the
# calibration checked against the bench's ground truth after each one.
#
#   make chaos [N=50] [SEED0=1] [JOBS=]   N schedules, summary, failing seeds
#   make chaos-replay SEED=123            one schedule, console shown
#   make chaos-regress                    the seeds in tests/chaos/regression_seeds.txt
#   make chaos-test                       the short fixed set (part of make test)
#
# Robots are built once into build/chaos/robots/ (cached by content).

N     ?= 50
SEED0 ?= 1
CHAOS_FIXED := tests/chaos/test_chaos.py
# mk/sim.mk (read after this file) builds the bench
CHAOS_BENCH := $(BUILD)/sim/hh_bench

.PHONY: chaos chaos-replay chaos-regress chaos-test
EXTRA_HELP += "make chaos [N= SEED0=]   randomized fault suite; chaos-replay SEED=, chaos-regress"

chaos: $(CHAOS_BENCH) | $(STAMP)
	$(PY) -m tests.chaos run -n $(N) --seed0 $(SEED0) --jobs $(JOBS)

chaos-replay: $(CHAOS_BENCH) | $(STAMP)
	$(PY) -m tests.chaos replay $(SEED)

chaos-regress: $(CHAOS_BENCH) | $(STAMP)
	$(PY) -m tests.chaos seeds tests/chaos/regression_seeds.txt --jobs $(JOBS)

chaos-test: $(CHAOS_BENCH) | $(STAMP)
	$(VENV)/bin/pytest $(PYTEST_ARGS) $(CHAOS_FIXED)

PYTEST_SUITES += $(CHAOS_FIXED)
PYTEST_DEPS   += $(CHAOS_BENCH)
