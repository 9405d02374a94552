/* Fixtures for the homing and plant tests (hom_fixture.h). */
#include "hom_fixture.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *hom_fix_path(const char *rel, char *buf, size_t n)
{
    const char *self = __FILE__;
    const char *cut = strstr(self, "tests/unit/support/");
    size_t root = cut != NULL ? (size_t)(cut - self) : 0u;
    if (root + strlen(rel) + 1u > n) {
        buf[0] = '\0';
        return buf;
    }
    memcpy(buf, self, root);
    strcpy(buf + root, rel);
    return buf;
}

int hom_fix_load(const char *name, plant_cfg_t *cfg, tbl_wide_t *t)
{
    char rel[128];
    char path[512];
    int line = 0;
    int rc;
    if (snprintf(rel, sizeof rel, "sim/plant/configs/%s", name) >= (int)sizeof rel) {
        return PLANT_E_ARG;
    }
    rc = plant_cfg_load(cfg, hom_fix_path(rel, path, sizeof path), &line);
    if (rc != 0) {
        fprintf(stderr, "hom_fixture: %s: error %d at line %d\n", path, rc, line);
        return rc;
    }
    if (t != NULL) {
        rc = plant_make_table(cfg, t);
    }
    return rc;
}

int hom_fix_paper(plant_cfg_t *cfg, tbl_wide_t *t)
{
    return hom_fix_load("paper_2seg_near.cfg", cfg, t);
}

int hom_fix_paper_desc(plant_cfg_t *cfg, tbl_wide_t *t)
{
    return hom_fix_load("paper_2seg.cfg", cfg, t);
}

int hom_fix_count_events(const plant_run_result_t *r, uint8_t type)
{
    int n = 0;
    uint16_t i;
    for (i = 0; i < r->n_events; i++) {
        if (r->events[i].type == type) {
            n++;
        }
    }
    return n;
}

plant_cfg_t hom_fix_cfg;
tbl_wide_t hom_fix_tab;

int hom_fix_setup_paper(void **state)
{
    (void)state;
    return hom_fix_paper(&hom_fix_cfg, &hom_fix_tab);
}

int hom_fix_setup_paper_desc(void **state)
{
    (void)state;
    return hom_fix_paper_desc(&hom_fix_cfg, &hom_fix_tab);
}

const hom_event_t *hom_fix_find_event(const plant_run_result_t *r, uint8_t type)
{
    uint16_t i;
    for (i = 0; i < r->n_events; i++) {
        if (r->events[i].type == type) {
            return &r->events[i];
        }
    }
    return NULL;
}

const tbl_table_t *hom_fix_pack(const tbl_wide_t *w)
{
    static const tbl_wide_t *owner[8];
    static tbl_buf_t buf[8];
    unsigned k;
    for (k = 0; k < 8u && owner[k] != NULL && owner[k] != w; k++) {
    }
    if (k == 8u || tbl_pack(w, &buf[k]) != 0) {
        fprintf(stderr, "hom_fixture: table %p does not pack\n", (const void *)w);
        abort();
    }
    owner[k] = w;
    return tbl_buf_table(&buf[k]);
}
