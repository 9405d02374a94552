# Benchmarks (docs/benchmarks.md): the paper's figures on the native closed loop
# and on the simavr bench, with plots, in bench/results/report.md.
#
#   make bench         full run (under 15 minutes): bench/results/report.md + PNGs
#   make bench-check   reduced run into build/bench-check: checks the pipeline
#                      produces every section with numbers, not that goals are met
#
# Variables: BENCH_ARGS (extra bench/run.py options, e.g. --no-simavr --jobs 1),
# BENCH_PLANT (plant config; default the one `make sim` uses, $(SIM_PLANT) of
# mk/sim.mk: written from the robot TOML when there is one). Both the native
# loop and the simavr bench run that robot.
# hh_bench itself is built by mk/sim.mk (`make sim-build`).

BENCH_BUILD   := $(BUILD)/bench
BENCH_CL      := $(BENCH_BUILD)/hh_closedloop
BENCH_MC      := $(BENCH_BUILD)/hh_mc_$(ROBOT)
BENCH_RESULTS := bench/results
BENCH_CHECK_DIR := $(BUILD)/bench-check
BENCH_ARGS    ?=
BENCH_PLANT    = $(or $(SIM_PLANT),sim/plant/configs/$(ROBOT).cfg)
# The native runners built with optimisation (the CMake build carries the
# sanitizers, 7x slower): the homing core and the plant, no AVR.
BENCH_NATIVE_SRCS = $(wildcard sim/plant/*.c) $(wildcard lib/homing/*.c) lib/table/table.c lib/table/table_pack.c \
	lib/icm20948/icm_clock.c
BENCH_NATIVE_CFLAGS := -std=c99 -O2 -Wall -Wextra -pedantic -Ilib -Isim

.PHONY: bench bench-check bench-tools

# hh_closedloop links every generated table, as the CMake build does (its -g).
$(BENCH_CL): tests/tools/closedloop.c $(BENCH_NATIVE_SRCS) $(wildcard $(TABLES_DIR)/*.c) $(wildcard sim/plant/*.h lib/homing/*.h lib/table/*.h lib/icm20948/icm_clock.h) | $(STAMP)
	@mkdir -p $(@D)
	$(CC) $(BENCH_NATIVE_CFLAGS) -o $@ tests/tools/closedloop.c $(BENCH_NATIVE_SRCS) \
		$(wildcard $(TABLES_DIR)/*.c) -lm

# hh_mc links the generated table of $(ROBOT) too (-g: the model-based workflow).
BENCH_GEN_TABLE := $(wildcard $(TABLES_DIR)/$(ROBOT).c)

$(BENCH_MC): bench/hh_mc.c $(BENCH_NATIVE_SRCS) $(BENCH_GEN_TABLE) $(wildcard sim/plant/*.h lib/homing/*.h lib/table/*.h lib/icm20948/icm_clock.h) | $(STAMP)
	@mkdir -p $(@D)
	$(CC) $(BENCH_NATIVE_CFLAGS) -Werror $(if $(BENCH_GEN_TABLE),-DHH_ROBOT=$(ROBOT)) -o $@ \
		bench/hh_mc.c $(BENCH_GEN_TABLE) $(BENCH_NATIVE_SRCS) -lm

bench-tools: $(BENCH_CL) $(BENCH_MC)

# The firmware, the bench and hh_dxl_bench are built first but do not stop the
# run when they fail to build (a part in progress elsewhere in the tree): the
# report then says what could not be measured, or which firmware it ran.
BENCH_SOFT_DEPS = @for t in firmware $(BUILD)/sim/hh_bench native-build $(BENCH_PLANT); do \
		$(MAKE) --no-print-directory $$t >$(BENCH_BUILD)/build-$$(basename $$t).log 2>&1 || \
		echo "bench: 'make $$t' failed (see $(BENCH_BUILD)/build-$$(basename $$t).log); measuring what is there"; \
	done

bench: bench-tools
	$(BENCH_SOFT_DEPS)
	@echo "make bench: full run on $(BENCH_PLANT), progress below"
	$(PY) -m bench.run --out $(BENCH_RESULTS) --config $(BENCH_PLANT) --robot $(ROBOT_TOML) --closedloop $(BENCH_CL) \
		--mc $(BENCH_MC) --hh-bench $(BUILD)/sim/hh_bench --elf $(FW_ELF) \
		--dxl-bench $(BUILD)/native/hh_dxl_bench $(BENCH_ARGS)
	@echo "make bench: report in $(BENCH_RESULTS)/report.md"

bench-check: bench-tools
	$(BENCH_SOFT_DEPS)
	@rm -rf $(BENCH_CHECK_DIR)
	$(PY) -m bench.run --reduced --out $(BENCH_CHECK_DIR) --config $(BENCH_PLANT) --robot $(ROBOT_TOML) \
		--closedloop $(BENCH_CL) --mc $(BENCH_MC) --hh-bench $(BUILD)/sim/hh_bench \
		--elf $(FW_ELF) --dxl-bench $(BUILD)/native/hh_dxl_bench --sim-limit 40 $(BENCH_ARGS)
	$(PY) -c "import sys; from bench.report import check_report; \
		p = check_report('$(BENCH_CHECK_DIR)/report.md'); [print('bench-check:', x) for x in p]; sys.exit(1 if p else 0)"
	@echo "bench-check: report with every section and its figures in $(BENCH_CHECK_DIR)/report.md"

TEST_TARGETS += bench-check
EXTRA_HELP += "make bench      benchmarks vs the paper: bench/results/report.md (BENCH_ARGS=)" \
	"make bench-check   reduced benchmark run: the report pipeline works"
