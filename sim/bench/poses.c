/*
 * poses: the final pose's truth and the straight pose computed from the
 * firmware's homes (docs/homing.md, "Straight-pose homes").
 *
 * Today the final move takes every tendon to its single-tendon home: the
 * robot straightens and the tensions rise far above the target. Until the
 * firmware moves to straight-pose homes itself, the bench computes that pose
 * from the homes it measured: each home minus the host's shift
 * (`python -m hallhome.straight ROBOT.toml -t T --list`), every tendon moved
 * there together from slack on a copy of the plant's description.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "plant/pose.h"

int poses_parse(bench_t *b, const char *list)
{
    const char *s = list;
    uint8_t n = 0;
    while (*s != '\0') {
        char *end;
        if (n == BENCH_MAX_SERVOS) {
            return -1;
        }
        b->straight_um[n] = strtod(s, &end);
        if (end == s || (*end != ',' && *end != '\0') || !isfinite(b->straight_um[n])) {
            return -1;
        }
        n++;
        s = *end == ',' ? end + 1 : end;
    }
    b->have_straight = n;
    return n > 0 ? 0 : -1;
}

int poses_report(bench_t *b, bench_pose_t *now, bench_pose_t *straight)
{
    const plant_cfg_t *cfg = &b->plant.cfg;
    double tip[3];
    double d2 = 0.0;
    double goal[PLANT_MAX_TENDONS];
    plant_pose_result_t r;
    memset(now, 0, sizeof *now);
    memset(straight, 0, sizeof *straight);
    if (!b->have_plant || plant_straight_tip(cfg, tip) != 0) {
        return -1;
    }
    for (int a = 0; a < 3; a++) {
        d2 += (b->plant.tip.pos_mm[a] - tip[a]) * (b->plant.tip.pos_mm[a] - tip[a]);
    }
    now->tip_dev_mm = sqrt(d2);
    for (uint8_t i = 0; i < cfg->n_tendons; i++) {
        now->tension_N[i] = b->plant.tension_N[i];
    }
    if (b->have_straight != cfg->n_tendons) {
        return 0;
    }
    for (uint8_t i = 0; i < cfg->n_tendons; i++) {
        goal[i] = world_home_shaft(b, i) - (double)cfg->tendon[i].pull_dir * b->straight_um[i] *
                                               1000.0 / plant_nm_per_tick(cfg, i);
    }
    if (plant_pose_ramp(cfg, goal, &r) != 0) {
        return -1;
    }
    straight->tip_dev_mm = r.tip_dev_mm;
    for (uint8_t i = 0; i < cfg->n_tendons; i++) {
        straight->tension_N[i] = r.tension_N[i];
    }
    return 1;
}
