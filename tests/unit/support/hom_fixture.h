/* Fixtures for the homing, plant and app tests: the paper robot's plant
 * configs from sim/plant/configs/ and a table computed from the nominal plant,
 * so "lands within one tick of the true home" compares like with like. */
#ifndef HALLHOME_HOM_FIXTURE_H
#define HALLHOME_HOM_FIXTURE_H

#include "plant/closedloop.h"

/* Path of a file under the repository root (from this file's location), in
 * buf of size n. Returns buf. */
const char *hom_fix_path(const char *rel, char *buf, size_t n);

/* Loads sim/plant/configs/<name> into *cfg and, when t is not NULL, fills *t
 * with plant_make_table(). Returns 0 or the plant error. */
int hom_fix_load(const char *name, plant_cfg_t *cfg, tbl_wide_t *t);

/* hom_fix_load("paper_2seg_near.cfg"): the paper robot with the sensors close
 * to the magnet (a strong field; grid 250..1500 mN, 800 mN at index 4). */
int hom_fix_paper(plant_cfg_t *cfg, tbl_wide_t *t);

/* hom_fix_load("paper_2seg.cfg"): the paper robot as its description has it
 * (written by hallhome.plantcfg; sensors on a 22 mm ring, a weak field). */
int hom_fix_paper_desc(plant_cfg_t *cfg, tbl_wide_t *t);

/* The robot of a test group that runs one robot throughout: its plant and
 * table, loaded by the group's setup (cmocka group setups, `state` unused):
 * hom_fix_setup_paper() with hom_fix_paper(), hom_fix_setup_paper_desc()
 * with hom_fix_paper_desc(). */
extern plant_cfg_t hom_fix_cfg;
extern tbl_wide_t hom_fix_tab;
int hom_fix_setup_paper(void **state);
int hom_fix_setup_paper_desc(void **state);

/* w packed into the stored layout, for tbl_src_t.table / plant_run_defaults().
 * Each wide table (by address, up to 8) has its own buffer, repacked on every
 * call, so a test edits its wide table and packs again. Fails the test when w
 * does not pack. */
const tbl_table_t *hom_fix_pack(const tbl_wide_t *w);

/* Number of events of the given HOM_EV_* type a closed-loop run recorded. */
int hom_fix_count_events(const plant_run_result_t *r, uint8_t type);

/* The first event of the given HOM_EV_* type a closed-loop run recorded, or
 * NULL. */
const hom_event_t *hom_fix_find_event(const plant_run_result_t *r, uint8_t type);

#endif /* HALLHOME_HOM_FIXTURE_H */
