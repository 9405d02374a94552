/* Fixtures for the homing and plant tests: the paper robot's plant config from
 * sim/plant/configs/ and a table computed from the nominal plant, so "lands
 * within one tick of the true home" compares like with like. */
#ifndef HALLHOME_HOM_FIXTURE_H
#define HALLHOME_HOM_FIXTURE_H

#include "plant/closedloop.h"

/* Path of a file under the repository root (from this file's location), in
 * buf of size n. Returns buf. */
const char *hom_fix_path(const char *rel, char *buf, size_t n);

/* Loads sim/plant/configs/paper_2seg.cfg into *cfg and, when t is not NULL,
 * fills *t with plant_make_table(). Returns 0 or the plant error. */
int hom_fix_paper(plant_cfg_t *cfg, tbl_table_t *t);

#endif /* HALLHOME_HOM_FIXTURE_H */
