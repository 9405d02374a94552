# Virtual bench: the firmware ELF on simavr with simulated servos, sensors and
# robot (sim/README.md, docs/bench.md).
#
#   make sim        full calibration run of $(ROBOT) (see sim/README.md for
#                   what the current firmware gets through)
#   make sim-test   builds the bench and its test firmware, runs the pytest suite
#
# Variables of `make sim`: ROBOT, TENSION (N), SEED, FAULT (scenario name in
# sim/bench/scenarios), INTERACTIVE=1 (console on a pty), SIM_LIMIT, SIM_ARGS.

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
TESTFW_DRIVERS := firmware/tick.c firmware/uart0.c firmware/uart1.c firmware/twi.c firmware/reset.c

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
SIM_STATE    = $(SIM_DIR)/eeprom/$(ROBOT)-$(SEED).eeprom
SIM_UNTIL   ?= ^<done mode=(full|quick)
SIM_FAIL    ?= ^<fault
SIM_TOL     ?= 10
SIM_ARGS    ?=
SIM_SCN     := sim/bench/scenarios/$(FAULT).scn

.PHONY: sim-build sim sim-test sim-no-robot
EXTRA_HELP += "make sim [ROBOT= TENSION= SEED= FAULT= INTERACTIVE=1]   firmware on the virtual bench" \
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
	@test -f $(SIM_PLANT) || { echo "make sim: no plant config $(SIM_PLANT)"; exit 2; }
	@test -z "$(FAULT)" || test -f $(SIM_SCN) || { echo "make sim: no scenario $(SIM_SCN); known:"; \
		ls sim/bench/scenarios | sed 's/\.scn$$//; s/^/  /'; exit 2; }
	@mkdir -p $(SIM_DIR)/eeprom
	@echo "make sim: ROBOT=$(ROBOT) SEED=$(SEED) TENSION=$(or $(TENSION),default) FAULT=$(or $(FAULT),none)"
	@# the straight-pose shifts of the robot description (T_straight in the table)
	S=$$($(if $(wildcard $(ROBOT_TOML)),$(PY) -m hallhome.straight $(ROBOT_TOML) --list $(if $(TENSION),-t $(TENSION)),true) || true); \
	$(BENCH) $(FW_ELF) --plant $(SIM_PLANT) --seed $(SEED) --eeprom $(SIM_STATE) \
		--summary $(SIM_DIR)/summary.json --timestamps --table --linger 3s \
		$(if $(TENSION),--tension $(TENSION) --at "0.3s send set cal_tension $(shell awk 'BEGIN{printf "%d", $(TENSION)*1000}')") \
		$(if $(INTERACTIVE),--interactive --realtime --pty-link $(SIM_DIR)/console --control -, \
			--limit $(SIM_LIMIT) --at "1s press 100" \
			$(if $(FAULT),--scenario $(SIM_SCN), \
				--until '$(SIM_UNTIL)' --fail-on '$(SIM_FAIL)' --check-tension $(SIM_TOL))) \
		$${S:+--straight-um $$S} $(SIM_ARGS)

# The suites run the default robot's firmware (paper_2seg), whatever ROBOT is.
SIM_TEST_ROBOT := paper_2seg
sim-test: $(BENCH) $(TESTFW_ELFS)
	@$(MAKE) --no-print-directory firmware ROBOT=$(SIM_TEST_ROBOT)
	$(VENV)/bin/pytest -q tests/sim

TEST_TARGETS += sim-test

-include $(BENCH_OBJS:.o=.d)
