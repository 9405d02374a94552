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
ROBOT_TOML  := lookup_tables/robots/$(ROBOT).toml
SIM_PLANT   := $(if $(wildcard $(ROBOT_TOML)),$(SIM_DIR)/plant/$(ROBOT).cfg,sim/plant/configs/$(ROBOT).cfg)
# One EEPROM image per robot and seed: the same SEED again is the same robot
# after a power cycle (stored homes: the firmware re-homes quickly), a new
# seed is a new robot with an erased EEPROM.
SIM_STATE    = $(SIM_DIR)/eeprom/$(ROBOT)-$(SEED).eeprom
SIM_UNTIL   ?= ^<done mode=(full|quick)
SIM_FAIL    ?= ^<fault
SIM_TOL     ?= 10
SIM_ARGS    ?=
SIM_SCN     := sim/bench/scenarios/$(FAULT).scn

.PHONY: sim-build sim sim-test
EXTRA_HELP += "make sim [ROBOT= TENSION= SEED= FAULT= INTERACTIVE=1]   firmware on the virtual bench" \
	"make sim-test   virtual bench tests"

sim-build: $(BENCH) $(TESTFW_ELFS)

$(SIM_DIR)/obj/%.o: %.c | $(STAMP)
	@mkdir -p $(@D)
	$(BENCH_CC) $(BENCH_CFLAGS) $$(pkg-config --cflags simavr) -c $< -o $@

$(BENCH): $(BENCH_OBJS)
	$(BENCH_CC) $^ -o $@ $$(pkg-config --libs simavr) -lelf -lm

$(SIM_DIR)/testfw/%.elf: sim/bench/testfw/%.c $(TESTFW_DRIVERS) $(AVR_DIR)/version.h | $(STAMP)
	@mkdir -p $(@D)
	$(AVR_CC) -mmcu=$(MCU) -DF_CPU=$(F_CPU) -std=c99 -Os -g -Wall -Wextra -Werror \
		-Ilib -Ifirmware -I$(AVR_DIR) $< $(TESTFW_DRIVERS) -o $@

$(SIM_DIR)/plant/%.cfg: lookup_tables/robots/%.toml $(wildcard host_tools/hallhome/*.py) | $(STAMP)
	@mkdir -p $(@D)
	$(PY) -c "import sys; from hallhome.robot import load_robot; \
		from hallhome.plantcfg import write_plant_config; \
		write_plant_config(load_robot(sys.argv[1]), sys.argv[2])" $< $@

sim: $(BENCH) firmware $(SIM_PLANT)
	@test -f $(SIM_PLANT) || { echo "make sim: no plant config $(SIM_PLANT)"; exit 2; }
	@test -z "$(FAULT)" || test -f $(SIM_SCN) || { echo "make sim: no scenario $(SIM_SCN); known:"; \
		ls sim/bench/scenarios | sed 's/\.scn$$//; s/^/  /'; exit 2; }
	@mkdir -p $(SIM_DIR)/eeprom
	@echo "make sim: ROBOT=$(ROBOT) SEED=$(SEED) TENSION=$(or $(TENSION),default) FAULT=$(or $(FAULT),none)"
	$(BENCH) $(FW_ELF) --plant $(SIM_PLANT) --seed $(SEED) --eeprom $(SIM_STATE) \
		--summary $(SIM_DIR)/summary.json --timestamps --table --linger 3s \
		$(if $(TENSION),--tension $(TENSION) --at "0.3s send set cal_tension $(shell awk 'BEGIN{printf "%d", $(TENSION)*1000}')") \
		$(if $(INTERACTIVE),--interactive --realtime --pty-link $(SIM_DIR)/console --control -, \
			--limit $(SIM_LIMIT) --at "1s press 100" \
			$(if $(FAULT),--scenario $(SIM_SCN), \
				--until '$(SIM_UNTIL)' --fail-on '$(SIM_FAIL)' --check-tension $(SIM_TOL))) \
		$(SIM_ARGS)

sim-test: $(BENCH) $(TESTFW_ELFS) firmware
	$(VENV)/bin/pytest -q tests/sim

TEST_TARGETS += sim-test

-include $(BENCH_OBJS:.o=.d)
