# Virtual bench: the firmware ELF on simavr with simulated servos, sensors and
# robot (sim/README.md, docs/bench.md).
#
#   make sim        full calibration run of $(ROBOT) (see sim/README.md for
#                   what the current firmware gets through)
#   make sim-test   builds the bench and its test firmware, runs the pytest suite
#
# Variables of `make sim`: ROBOT, TENSION (N), SEED, FAULT (scenario name in
# sim/bench/scenarios), INTERACTIVE=1 (console on a pty), IDENTIFY=0 (skip the
# identification: calibrate with the nominal table), PERTURB and
# PERTURB_STIFFNESS (the robot's spread, hh_bench --perturb and
# --perturb-stiffness), SIM_LIMIT, SIM_ARGS.

SIM_DIR     := $(BUILD)/sim
BENCH       := $(SIM_DIR)/hh_bench
BENCH_CC    ?= gcc
BENCH_CFLAGS := -std=c99 -O2 -g -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes \
	-Wmissing-prototypes -Ilib -Isim -Isim/bench -MMD -MP
BENCH_SRCS  := $(wildcard sim/bench/*.c) $(wildcard sim/devices/*.c) \
	$(filter-out sim/plant/closedloop.c,$(wildcard sim/plant/*.c)) \
	lib/dxl/dxl_proto.c lib/table/table.c
BENCH_OBJS  := $(patsubst %.c,$(SIM_DIR)/obj/%.o,$(BENCH_SRCS))

# Test fixtures: small AVR programs that exercise the bench's peripherals
# through the real board-support drivers before the application uses them.
TESTFW_SRCS := $(wildcard sim/bench/testfw/*.c)
TESTFW_ELFS := $(patsubst sim/bench/testfw/%.c,$(SIM_DIR)/testfw/%.elf,$(TESTFW_SRCS))
TESTFW_DRIVERS := firmware/tick.c firmware/board_io.c firmware/uart0.c firmware/uart1.c firmware/twi.c firmware/reset.c

ifeq ($(origin SEED),undefined)
SEED        := $(shell od -An -N4 -tu4 /dev/urandom | tr -d ' ')
endif
TENSION     ?=
FAULT       ?=
SIM_LIMIT   ?= 120s
# The plant is written from the robot TOML (host_tools/hallhome/plantcfg.py,
# nominal values: the bench perturbs them with SEED); a hand-written
# sim/plant/configs/$(ROBOT).cfg is used only for a robot without a TOML.
# Writing it fails, naming the TOML key, for a robot the plant cannot model
# (helical routing, an off-axis magnet): before anything is built.
ROBOT_TOML  := $(ROBOTS_DIR)/$(ROBOT).toml
SIM_HAND_CFG := sim/plant/configs/$(ROBOT).cfg
SIM_PLANT   := $(if $(wildcard $(ROBOT_TOML)),$(SIM_DIR)/plant/$(ROBOT).cfg,$(SIM_HAND_CFG))
SIM_ROBOT_KNOWN := $(or $(wildcard $(ROBOT_TOML)),$(wildcard $(SIM_HAND_CFG)))
# One EEPROM image per robot and seed: the same SEED again is the same robot
# after a power cycle (stored homes: the firmware re-homes quickly), a new
# seed is a new robot with an erased EEPROM.
SIM_STATE    = $(SIM_DIR)/eeprom/$(ROBOT)-$(SEED)$(SIM_PERTURB_TAG).eeprom
SIM_UNTIL   ?= ^<done mode=(full|quick)
SIM_FAIL    ?= ^<fault
SIM_TOL     ?= 10
SIM_ARGS    ?=
SIM_SCN     := sim/bench/scenarios/$(FAULT).scn
# The robot's spread (hh_bench's defaults when empty: 0.05, stiffness the same).
PERTURB     ?=
PERTURB_STIFFNESS ?=
SIM_PERTURB := $(if $(PERTURB),--perturb $(PERTURB)) \
	$(if $(PERTURB_STIFFNESS),--perturb-stiffness $(PERTURB_STIFFNESS))
SIM_PERTURB_TAG := $(if $(PERTURB),-p$(PERTURB))$(if $(PERTURB_STIFFNESS),-s$(PERTURB_STIFFNESS))

# Identification (docs/identify.md, sim/identify.sh): before the calibration,
# the bench surveys its perturbed robot, `hallhome identify fit` fits the
# description to it, the table of the identified TOML is generated and its
# firmware built (ROBOT=<robot>_id, build/fw/<robot>_id), and that firmware
# calibrates. On by default, except for fault scenarios (FAULT=), which test
# the reactions to faults with the nominal table; IDENTIFY=0 skips it. Every
# file goes under build/sim/identify: $(ROBOT)-$(SEED)/ per robot (survey,
# fit output, plots, identified TOML, its table), tables/ for the firmware
# build. A refused fit is reported and the nominal table calibrates.
ifeq ($(origin IDENTIFY),undefined)
IDENTIFY    := $(if $(FAULT),0,1)
endif
SIM_ID_ON   := $(and $(filter 1,$(IDENTIFY)),$(wildcard $(ROBOT_TOML)))
SIM_ID_NAME := $(ROBOT)_id
SIM_ID_DIR   = $(SIM_DIR)/identify/$(ROBOT)-$(SEED)$(SIM_PERTURB_TAG)$(if $(SIM_ID_WEIGHT_ALL),-wall)
SIM_ID_TOML  = $(SIM_ID_DIR)/$(SIM_ID_NAME).toml
SIM_ID_TABLES := $(SIM_DIR)/identify/tables
SIM_ID_ELF  := $(BUILD)/fw/$(SIM_ID_NAME)/hallhome-$(SIM_ID_NAME).elf
SIM_ID_STATE = $(SIM_DIR)/eeprom/$(SIM_ID_NAME)-$(SEED)$(SIM_PERTURB_TAG).eeprom
SIM_ID_WEIGHT ?= 80
# SIM_ID_WEIGHT_ALL=1: the weight on every tendon in turn instead of one per
# segment (the fit then gives each tendon its own radius and stretch)
SIM_ID_WEIGHT_ALL ?=

.PHONY: sim-build sim sim-test sim-no-robot
EXTRA_HELP += "make sim [ROBOT= TENSION= SEED= FAULT= INTERACTIVE=1 IDENTIFY=0]   firmware on the virtual bench" \
	"make sim-test   virtual bench tests"

sim-build: $(BENCH) $(TESTFW_ELFS)

$(SIM_DIR)/obj/%.o: %.c | $(STAMP)
	@mkdir -p $(@D)
	$(BENCH_CC) $(BENCH_CFLAGS) $$(pkg-config --cflags simavr) -c $< -o $@

$(BENCH): $(BENCH_OBJS)
	$(BENCH_CC) $^ -o $@ $$(pkg-config --libs simavr) -lelf -lm

$(SIM_DIR)/testfw/%.elf: sim/bench/testfw/%.c $(TESTFW_DRIVERS) $(VERSION_H) | $(STAMP)
	@mkdir -p $(@D)
	$(AVR_CC) -mmcu=$(MCU) -DF_CPU=$(F_CPU) -std=c99 -Os -g -Wall -Wextra -Werror \
		-Ilib -Ifirmware -I$(FW_GEN_DIR) $< $(TESTFW_DRIVERS) -o $@

$(SIM_DIR)/plant/%.cfg: $(ROBOTS_DIR)/%.toml $(wildcard host_tools/hallhome/*.py) | $(STAMP)
	@mkdir -p $(@D)
	@$(PY) -m hallhome.plantcfg $< $@

sim-no-robot:
	@echo "make sim: no robot '$(ROBOT)': no $(ROBOT_TOML) (and no hand-written $(SIM_HAND_CFG))"
	@echo "robots in $(ROBOTS_DIR): $(or $(ROBOT_NAMES),none)"
	@exit 2

# The plant config first: a robot the bench cannot model stops here.
sim: $(if $(SIM_ROBOT_KNOWN),$(SIM_PLANT) $(BENCH) firmware,sim-no-robot)
	@echo "$(SEED)" | grep -Eq '^[0-9]{1,10}$$' || { echo "make sim: SEED takes a whole number, not '$(SEED)'"; exit 2; }
	@test -z "$(TENSION)" || echo "$(TENSION)" | grep -Eq '^[0-9]*\.?[0-9]+$$' || \
		{ echo "make sim: TENSION takes newtons (for example TENSION=1.2), not '$(TENSION)'"; exit 2; }
	@test -f $(SIM_PLANT) || { echo "make sim: no plant config $(SIM_PLANT)"; exit 2; }
	@test -z "$(FAULT)" || test -f $(SIM_SCN) || { echo "make sim: no scenario $(SIM_SCN); known:"; \
		ls sim/bench/scenarios | sed 's/\.scn$$//; s/^/  /'; exit 2; }
	@mkdir -p $(SIM_DIR)/eeprom
	@echo "make sim: ROBOT=$(ROBOT) SEED=$(SEED) TENSION=$(or $(TENSION),cal_tension) FAULT=$(or $(FAULT),none) IDENTIFY=$(if $(SIM_ID_ON),1,0)$(if $(SIM_PERTURB_TAG), PERTURB=$(or $(PERTURB),0.05) PERTURB_STIFFNESS=$(or $(PERTURB_STIFFNESS),$(PERTURB),0.05))"
	@# identification first (sim/identify.sh): its firmware, description and
	@# EEPROM image replace the nominal ones unless the fit was refused (exit 3).
	@# The script runs make itself: a $$(MAKE) on this line would make
	@# `make -n sim` run it.
	@# the straight-pose shifts of the robot description (T_straight in the
	@# table); the bench's command line is shown (set -x) as it runs
	@ELF=$(FW_ELF); TOML=$(ROBOT_TOML); STATE=$(SIM_STATE); \
	$(if $(SIM_ID_ON),rc=0; BENCH=$(BENCH) FW_ELF=$(FW_ELF) PY=$(PY) WEIGHT_G=$(SIM_ID_WEIGHT) \
		sh sim/identify.sh $(ROBOT_TOML) $(SIM_PLANT) $(SEED) $(SIM_ID_DIR) \
		$(SIM_ID_TABLES) $(SIM_PERTURB) $(if $(SIM_ID_WEIGHT_ALL),--survey-weight-all) || rc=$$?; \
	if [ $$rc -eq 0 ]; then ELF=$(SIM_ID_ELF); TOML=$(SIM_ID_TOML); STATE=$(SIM_ID_STATE); \
	elif [ $$rc -ne 3 ]; then exit $$rc; fi; \
	echo "make sim: [5/5] calibration with the $$(basename $$TOML .toml) table ($$ELF)";) \
	S=$$($(if $(wildcard $(ROBOT_TOML)),$(PY) -m hallhome.straight $$TOML --list $(if $(TENSION),-t $(TENSION)),true) || true); \
	set -x; $(BENCH) $$ELF --plant $(SIM_PLANT) --seed $(SEED) $(SIM_PERTURB) --eeprom $$STATE \
		--summary $(SIM_DIR)/summary.json --timestamps --table --linger 3s \
		$(if $(TENSION),--tension $(TENSION) --at "0.3s send set cal_tension $(shell awk 'BEGIN{printf "%d", $(TENSION)*1000}')") \
		$(if $(INTERACTIVE),--interactive --realtime --pty-link $(SIM_DIR)/console --control -, \
			--limit $(SIM_LIMIT) --at "1s press 100" \
			$(if $(FAULT),--scenario $(SIM_SCN), \
				--until '$(SIM_UNTIL)' --fail-on '$(SIM_FAIL)' --check-tension $(SIM_TOL))) \
		$${S:+--straight-um $$S} $(SIM_ARGS)

# The suites run the default robot's firmware (paper_2seg), whatever ROBOT is.
SIM_TEST_ROBOT := paper_2seg
.PHONY: sim-test-firmware
sim-test-firmware:
	@$(MAKE) --no-print-directory firmware ROBOT=$(SIM_TEST_ROBOT)

sim-test: $(BENCH) $(TESTFW_ELFS) sim-test-firmware
	$(VENV)/bin/pytest $(PYTEST_ARGS) tests/sim

PYTEST_SUITES += tests/sim
PYTEST_DEPS   += $(BENCH) $(TESTFW_ELFS) sim-test-firmware

-include $(BENCH_OBJS:.o=.d)
