# Lookup tables: $(ROBOTS_DIR)/*.toml -> $(TABLES_DIR)/*.{c,json} (defaults
# lookup_tables/robots and lookup_tables/generated) by `hallhome tables`
# (host_tools/hallhome/tablegen.py).

ROBOT_TOMLS := $(sort $(wildcard $(ROBOTS_DIR)/*.toml))
TABLES_CHECK_DIR := $(BUILD)/tables-check

.PHONY: tables tables-check

tables: $(STAMP)
	$(VENV)/bin/hallhome tables --quiet --out-dir $(TABLES_DIR) $(ROBOT_TOMLS)
	@echo "tables: regenerated $(words $(ROBOT_TOMLS)) robot(s) into $(TABLES_DIR)"

# Regenerates every table into a scratch directory and compares it with the
# committed files: fails when a TOML, the model or table.h changed without
# `make tables`. Learned tables (<robot>_learned.*, written with --learned from
# measurements on a board) have no TOML of their own and are left out.
tables-check: $(STAMP)
	@rm -rf $(TABLES_CHECK_DIR) && mkdir -p $(TABLES_CHECK_DIR)
	@$(VENV)/bin/hallhome tables --quiet --out-dir $(TABLES_CHECK_DIR) $(ROBOT_TOMLS)
	@status=0; \
	for f in $(TABLES_CHECK_DIR)/*; do \
		g=$(TABLES_DIR)/$$(basename $$f); \
		if ! cmp -s $$f $$g; then \
			echo "tables-check: $$g is out of date (or missing); run 'make tables' and commit it:"; \
			diff -u $$g $$f 2>&1 | head -20; status=1; \
		fi; \
	done; \
	for g in $(TABLES_DIR)/*.c $(TABLES_DIR)/*.json; do \
		[ -e "$$g" ] || continue; \
		case $$g in *_learned.c|*_learned.json) continue;; esac; \
		if [ ! -e $(TABLES_CHECK_DIR)/$$(basename $$g) ]; then \
			echo "tables-check: $$g has no robot TOML in $(ROBOTS_DIR)"; status=1; \
		fi; \
	done; \
	if [ $$status -ne 0 ]; then exit 1; fi
	@echo "tables-check: $(words $(ROBOT_TOMLS)) generated table(s) up to date"

TEST_SIDE_BY_SIDE += tables-check
EXTRA_HELP += "make tables     regenerate lookup_tables/generated from the robot TOMLs"
EXTRA_HELP += "make tables-check   fail when the committed tables are out of date"
