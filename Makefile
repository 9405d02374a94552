# hallhome: build, flash, test. `make help` lists the targets.
#
# Everything installs itself: the first target that needs a tool runs
# scripts/bootstrap.sh once (stamp file), so `make test` and `make sim` work on
# a fresh Debian machine with no earlier step.

ROBOT    ?= paper_2seg
BUILD    := build
VENV     := .venv
PY       := $(VENV)/bin/python
STAMP    := $(BUILD)/.bootstrap.stamp
JOBS     ?= $(shell nproc 2>/dev/null || echo 2)

# --- firmware (ATmega2560, avr-gcc, no Arduino core) -------------------------
# Each robot builds in its own directory, build/fw/<robot>/, with the ELF and
# HEX named after it: switching ROBOT= never reuses another robot's objects
# (firmware/main.c names the table through -DHH_ROBOT) and never flashes
# another robot's image. ROBOTS_DIR and TABLES_DIR may be set on the command
# line to build a robot kept elsewhere (e.g. a generated one under build/).
ROBOTS_DIR ?= lookup_tables/robots
TABLES_DIR ?= lookup_tables/generated
MCU      := atmega2560
F_CPU    := 16000000UL
AVR_CC   := avr-gcc
AVR_OBJCOPY := avr-objcopy
AVR_SIZE := avr-size
FW_DIR   := $(BUILD)/fw/$(ROBOT)
AVR_DIR  := $(FW_DIR)/avr
FW_ELF   := $(FW_DIR)/hallhome-$(ROBOT).elf
FW_HEX   := $(FW_DIR)/hallhome-$(ROBOT).hex
FW_MAP   := $(FW_DIR)/hallhome-$(ROBOT).map
# version.h is the same for every robot (and the bench's test programs).
FW_GEN_DIR := $(BUILD)/fw/include
VERSION_H := $(FW_GEN_DIR)/version.h

VERSION_BASE := $(shell cat VERSION)
GIT_REV  := $(shell git describe --always --dirty --abbrev=7 2>/dev/null)
FW_VERSION := $(VERSION_BASE)$(if $(GIT_REV),+g$(GIT_REV))

ROBOT_NAMES := $(sort $(basename $(notdir $(wildcard $(ROBOTS_DIR)/*.toml))))
TABLE_SRC := $(wildcard $(TABLES_DIR)/$(ROBOT).c)
TABLE_OBJ := $(if $(TABLE_SRC),$(AVR_DIR)/table_$(ROBOT).o)
# A robot is known when it has a description or a table (learned tables,
# <robot>_learned.c, have no TOML of their own).
ROBOT_KNOWN := $(or $(wildcard $(ROBOTS_DIR)/$(ROBOT).toml),$(TABLE_SRC))
FW_SRCS  := $(wildcard firmware/*.c) $(wildcard lib/*/*.c)
FW_OBJS  := $(patsubst %.c,$(AVR_DIR)/%.o,$(FW_SRCS)) $(TABLE_OBJ)
# Interprocedural passes that clone functions for constant arguments or
# split their parameters grow the AVR image; one LTO partition lets the
# linker see every caller (measured: -0.4 KB). Hoisting loop invariants and
# partial redundancy elimination keep values in registers that an 8-bit core
# must save and reload; argument space reserved once per function instead of
# pushed per call; wide types not split into bytes early (measured together:
# -0.6 KB). Forward propagation, the dominator optimizations and
# reassociation of the tree passes combine 32-bit expressions into forms an
# 8-bit core evaluates with more instructions (measured together: -0.9 KB).
# Branches kept as branches rather than turned into selects of 32-bit values
# (measured: -76 B). Whole-program points-to analysis and the priority
# register allocator (measured together: -0.2 KB). Loops not rewritten around
# a computed trip count (measured: -50 B). Enumerations in one byte where
# their values fit (no enum is stored in EEPROM or shared with the host;
# measured: -60 B). A function's registers saved at its entry, not on the
# paths that need them (measured: -30 B).
AVR_SIZE_OPT := -fno-tree-loop-ivcanon -fno-ipa-sra -fno-ipa-cp-clone -flto-partition=none \
	-fno-move-loop-invariants -fno-tree-pre -fno-split-wide-types -maccumulate-args \
	-fno-tree-forwprop -fno-tree-dominator-opts -fno-tree-reassoc -fno-ssa-phiopt \
	-fipa-pta -fira-algorithm=priority -fshort-enums -fno-shrink-wrap
# The libraries sized to what the firmware uses (each knob is described where
# it is defined): 4 data bytes per servo reply, the most the firmware reads (a
# Present Position; a ping returns 3), not the default 8 (48 bytes of RAM for
# 12 servos); homing events without their step time, which no report prints
# (48 bytes); no servo-bus counters, which no report prints either (24 bytes
# and the code that counts), nor the sensors' sample counters that no report
# prints (32 bytes); no settings' help texts, which no reply prints (about 300
# bytes of flash). The board has one servo bus, one console, one EEPROM and
# one I2C bus: the modules call its functions directly (firmware/uart1.c,
# main.c, eeprom_port.c, twi.c), not through the function pointers in which
# the native tests pass their fakes (measured together: 806 bytes of flash,
# 54 of RAM); the app calls the board's clock, button, LED, watchdog and
# counters the same way (firmware/main.c; 366 bytes of flash, 16 of RAM) and
# keeps its engagement windows at a fixed address (app_board_win; 210 bytes).
# The app runs every command itself: the console has no handler table (130
# bytes of flash, 6 of RAM).
# A firmware built for one robot keeps per-tendon state (the homing's, the
# app's servo bus, windows and frames, the servo master's replies) for its
# table's tendons only, the count in the table's TBL_LAYOUT, not for the
# format's 12; a table with more is refused as one with too many sensors is.
# The same for sensors, when the table has fewer than the 4 a firmware keeps
# state for (HOM_MAX_SENSORS; a table with more is refused).
TABLE_TENDONS := $(if $(TABLE_SRC),$(shell sed -n 's/^TBL_LAYOUT.\([0-9]*\).*/\1/p' $(TABLE_SRC)))
TABLE_SENSORS := $(if $(TABLE_SRC),$(shell sed -n 's/^TBL_LAYOUT.[0-9]*, *\([0-9]*\).*/\1/p' $(TABLE_SRC)))
AVR_ROBOT_CFG := $(if $(TABLE_TENDONS),-DHOM_MAX_TENDONS=$(TABLE_TENDONS)u -DDXL_MAX_IDS=$(TABLE_TENDONS)u) \
	$(if $(filter 1 2 3,$(TABLE_SENSORS)),-DHOM_MAX_SENSORS=$(TABLE_SENSORS)u)
AVR_LIB_CFG := $(AVR_ROBOT_CFG) -DDXL_PORT_FIXED=1 -DCON_IO_FIXED=1 -DSTORE_EE_FIXED=1 -DICM_BUS_FIXED=1 -DAPP_BOARD_FIXED=1 -DCON_HANDLERS=0 -DDXL_REPLY_DATA=4u -DHOM_EV_TIME=0 -DDXL_STATS=0 -DICM_STATS=0 -DSTORE_SETTING_HELP=0
AVR_CFLAGS := $(AVR_LIB_CFG) -mmcu=$(MCU) -DF_CPU=$(F_CPU) -std=c99 -Os -g -Wall -Wextra -Werror -pedantic \
	-Wshadow -Wstrict-prototypes -Wmissing-prototypes -ffunction-sections -fdata-sections \
	-mcall-prologues -mstrict-X -fno-inline-small-functions $(AVR_SIZE_OPT) -flto -mrelax -Ilib -Ifirmware -I$(FW_GEN_DIR) -DTBL_FLASH=__attribute__\(\(__progmem__\)\) \
	-DHH_ROBOT=$(ROBOT) -DAPP_ROOM_MARK_ADDR=0x4A -MMD -MP
# The link's LTO output puts each function in a section of its own, and the
# linker places them sorted by name: the functions of a module (hom_, app_,
# dxl_, con_, tbl_) then lie together, within reach of the 2-byte relative
# calls and jumps that -mrelax turns the 4-byte ones into (measured: -162 B;
# in the one section the LTO output had, they lay in the compiler's order).
# Most calls and jumps between functions still spanned more than the 4 KB
# that rcall and rjmp reach: firmware/link_order.txt (scripts/link_order.py
# writes it from a linked firmware) places the functions first, in an order
# that brings the most call and jump sites within reach, in the toolchain's
# own linker script for the MCU; what it does not name (a function added
# since) follows, sorted by name (measured: -906 B on either robot).
FW_LDSCRIPT := $(FW_DIR)/link.x
AVR_LDFLAGS := -mmcu=$(MCU) -Os -mcall-prologues -mstrict-X -fno-inline-small-functions $(AVR_SIZE_OPT) -flto -mrelax -ffunction-sections -Wl,--sort-section=name -Wl,--gc-sections -Wl,-Map,$(FW_MAP) -Wl,-T,$(FW_LDSCRIPT)

# Shell lines that stop a target for an unknown robot or a missing table.
NO_ROBOT = { echo "make $(or $(MAKECMDGOALS),firmware): no robot '$(ROBOT)': neither $(ROBOTS_DIR)/$(ROBOT).toml nor $(TABLES_DIR)/$(ROBOT).c exists"; \
	echo "robots in $(ROBOTS_DIR): $(or $(ROBOT_NAMES),none)"; exit 2; }
NO_TABLE = { echo "make $(or $(MAKECMDGOALS),flash): robot '$(ROBOT)' has no table $(TABLES_DIR)/$(ROBOT).c: its firmware would boot with table=none and refuse to calibrate"; \
	echo "generate it first: $(VENV)/bin/hallhome tables $(ROBOTS_DIR)/$(ROBOT).toml --out-dir $(TABLES_DIR)"; exit 2; }

.PHONY: all firmware size flash fw-path help bootstrap test native-build unit avr-lib fuzz fuzz-smoke host-test pytest-suites lint \
	format clean robot-unknown table-missing
all: firmware

help:
	@echo "make firmware   build $(FW_HEX) (ROBOT=$(ROBOT); robots: $(ROBOT_NAMES))"
	@echo "make fw-path    print the firmware ELF path of ROBOT"
	@echo "make size       flash / static RAM use, fails above the budget in scripts/size.sh"
	@echo "make flash PORT=/dev/ttyACM0   upload with avrdude (Arduino bootloader; needs ROBOT's table)"
	@echo "make test       every test suite (installs what it needs first)"
	@echo "make unit | host-test | fuzz-smoke | lint   one suite"
	@echo "make fuzz       longer libFuzzer runs (FUZZ_SECONDS=$(FUZZ_SECONDS))"
	@echo "make format     clang-format every C file in place"
	@printf "%s\n" $(EXTRA_HELP)

$(STAMP): scripts/bootstrap.sh scripts/apt-packages.txt host_tools/pyproject.toml
	@mkdir -p $(BUILD)
	bash scripts/bootstrap.sh
	@touch $@

bootstrap: $(STAMP)

firmware: $(if $(ROBOT_KNOWN),$(FW_HEX),robot-unknown)

fw-path:
	@echo $(FW_ELF)

robot-unknown:
	@$(NO_ROBOT)

table-missing:
	@$(NO_TABLE)

$(VERSION_H): FORCE | $(STAMP)
	@mkdir -p $(@D)
	@printf '/* generated by the Makefile */\n#define HH_VERSION "%s"\n' "$(FW_VERSION)" > $@.tmp
	@cmp -s $@.tmp $@ && rm $@.tmp || mv $@.tmp $@

# What the ELF is linked from, rewritten only when it changes: a table that
# appears or disappears relinks the ELF even when no object is newer.
$(FW_DIR)/objects.txt: FORCE
	@mkdir -p $(@D)
	@echo "$(FW_OBJS)" > $@.tmp
	@cmp -s $@.tmp $@ && rm $@.tmp || mv $@.tmp $@

# The compile and link flags, rewritten only when they change: a knob of
# AVR_LIB_CFG changes struct layouts, so every object is built again with it.
$(FW_DIR)/flags.txt: FORCE
	@mkdir -p $(@D)
	@echo "$(AVR_CFLAGS) | $(AVR_LDFLAGS)" > $@.tmp
	@cmp -s $@.tmp $@ && rm $@.tmp || mv $@.tmp $@

$(AVR_DIR)/%.o: %.c $(VERSION_H) $(FW_DIR)/flags.txt | $(STAMP)
	@mkdir -p $(@D)
	$(AVR_CC) $(AVR_CFLAGS) -c $< -o $@

ifneq ($(TABLE_OBJ),)
$(TABLE_OBJ): $(TABLE_SRC) $(VERSION_H) $(FW_DIR)/flags.txt | $(STAMP)
	@mkdir -p $(@D)
	$(AVR_CC) $(AVR_CFLAGS) -c $< -o $@
endif

$(FW_ELF): $(FW_OBJS) $(FW_DIR)/objects.txt $(FW_DIR)/flags.txt $(FW_LDSCRIPT)
	$(AVR_CC) $(AVR_LDFLAGS) $(FW_OBJS) -o $@

# The default script of the MCU's emulation with the sections of
# firmware/link_order.txt placed before the rest of .text.* (a script without
# that line fails the build rather than losing the order).
$(FW_LDSCRIPT): firmware/link_order.txt | $(STAMP)
	@mkdir -p $(@D)
	avr-ld --verbose -m$$($(AVR_CC) -mmcu=$(MCU) -print-multi-directory) | awk -v order=$< \
		'/^=====/ { inside = !inside; next } !inside { next } \
		/^ *\*\(\.text\.\*\)$$/ { while ((getline p < order) > 0) if (p !~ /^#/ && p != "") print "    *(" p ")"; done = 1 } \
		{ print } END { if (!done) exit 1 }' > $@.tmp && mv $@.tmp $@

$(FW_HEX): $(FW_ELF)
	$(AVR_OBJCOPY) -O ihex -R .eeprom $< $@
	@echo "built $@ ($(FW_VERSION), robot $(ROBOT), $(if $(TABLE_SRC),table $(TABLE_SRC),NO TABLE: the board boots with table=none and refuses to calibrate))"

# Every lib/ module compiled for the AVR with warnings as errors, linked in or not.
avr-lib: $(patsubst %.c,$(AVR_DIR)/%.o,$(wildcard lib/*/*.c))
	@echo "avr-lib: $(words $^) lib/ sources compiled for $(MCU) with -Werror"

size: $(if $(ROBOT_KNOWN),$(FW_ELF),robot-unknown)
	@bash scripts/size.sh $(FW_ELF)

# Flashing needs the robot's table: an image without one cannot calibrate.
flash: $(if $(ROBOT_KNOWN),$(if $(TABLE_SRC),$(FW_HEX),table-missing),robot-unknown)
	@if [ -z "$(PORT)" ]; then \
		echo "make flash: set PORT to the Mega's serial port, e.g. make flash PORT=/dev/ttyACM0"; \
		echo "candidate ports:"; \
		ls /dev/serial/by-id/* /dev/ttyACM* /dev/ttyUSB* 2>/dev/null | sed 's/^/  /' || true; \
		exit 2; fi
	avrdude -p $(MCU) -c wiring -P $(PORT) -b 115200 -D -U flash:w:$(FW_HEX):i

# --- native tests (CMake + ctest + cmocka, ASan + UBSan) ---------------------
NATIVE := $(BUILD)/native
native-build: $(STAMP)
	cmake -S . -B $(NATIVE) -DCMAKE_BUILD_TYPE=Debug >/dev/null
	cmake --build $(NATIVE) -j$(JOBS)

unit: native-build
	cd $(NATIVE) && ctest --output-on-failure -j$(JOBS)

# --- fuzzing (clang + libFuzzer) ----------------------------------------------
FUZZ_DIR := $(BUILD)/fuzz
FUZZ_SECONDS ?= 300
FUZZ_SMOKE_RUNS ?= 20000
fuzz-build: $(STAMP)
	CC=clang cmake -S . -B $(FUZZ_DIR) -DHH_FUZZ=ON >/dev/null
	cmake --build $(FUZZ_DIR) -j$(JOBS)

fuzz-smoke: fuzz-build
	@bash scripts/fuzz.sh $(FUZZ_DIR) -runs=$(FUZZ_SMOKE_RUNS)

fuzz: fuzz-build
	@bash scripts/fuzz.sh $(FUZZ_DIR) -max_total_time=$(FUZZ_SECONDS)

# --- host tests (pytest in the project venv) ---------------------------------
# A worker per core; idle workers steal queued tests (tests/conftest.py orders
# the long ones first).
PYTEST_ARGS := -q -n $(JOBS) --dist worksteal -rxX
host-test: $(STAMP) native-build
	$(VENV)/bin/pytest $(PYTEST_ARGS) tests/host

# make test runs the pytest suites in one session (no worker waits at the end
# of one suite while the other finishes it); mk/*.mk add theirs and what they
# need built.
PYTEST_SUITES := tests/host
PYTEST_DEPS   := native-build

# --- lint -----------------------------------------------------------------------
C_FILES = $(shell git ls-files -co --exclude-standard -- '*.c' '*.h' | grep -v '^lookup_tables/generated/')
lint: $(STAMP)
	clang-format --dry-run --Werror $(C_FILES)
	cppcheck --quiet --error-exitcode=1 --std=c99 --enable=warning,portability,performance \
		--inline-suppr --suppress=missingIncludeSystem -Ilib -Ifirmware lib firmware
	@echo "lint: clang-format and cppcheck clean ($(words $(C_FILES)) files)"

format:
	clang-format -i $(C_FILES)

# make test runs the short suites side by side first (make -j$(JOBS) -O:
# each target's output in one piece; they share no build directory), then
# TEST_TARGETS one after the other. Later parts of the project append to
# both in mk/*.mk, and their pytest suites to PYTEST_SUITES.
TEST_SIDE_BY_SIDE := unit avr-lib firmware size fuzz-smoke lint
TEST_TARGETS :=
-include $(sort $(wildcard mk/*.mk))
TEST_TARGETS += pytest-suites

pytest-suites: $(STAMP) $(PYTEST_DEPS)
	$(VENV)/bin/pytest $(PYTEST_ARGS) --durations=20 $(PYTEST_SUITES)

test: $(STAMP)
	@echo "=== make -j$(JOBS) $(TEST_SIDE_BY_SIDE)"
	@$(MAKE) --no-print-directory -j$(JOBS) -O $(TEST_SIDE_BY_SIDE)
	@set -e; for t in $(TEST_TARGETS); do echo "=== make $$t"; $(MAKE) --no-print-directory $$t; done
	@echo "=== make test: all suites passed ($(TEST_SIDE_BY_SIDE) $(TEST_TARGETS))"

clean:
	rm -rf $(BUILD)

FORCE:

-include $(FW_OBJS:.o=.d)
