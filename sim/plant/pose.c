/*
 * pose: every tendon at a given motor position at once (see pose.h).
 */
#include "plant/pose.h"

#include <math.h>
#include <string.h>

/* Motor ticks of tendon i at a take-up of take_um (pull direction). */
static double take_to_ticks(const plant_cfg_t *cfg, uint8_t i, double take_um)
{
    return (double)cfg->tendon[i].pull_dir * take_um / (plant_nm_per_tick(cfg, i) * 1e-3);
}

static double ticks_to_take(const plant_cfg_t *cfg, uint8_t i, double ticks)
{
    return (double)cfg->tendon[i].pull_dir * ticks * plant_nm_per_tick(cfg, i) * 1e-3;
}

int plant_straight_tip(const plant_cfg_t *cfg, double pos_mm[3])
{
    plant_t p;
    uint8_t i;
    if (cfg == NULL || pos_mm == NULL) {
        return PLANT_E_ARG;
    }
    if (plant_init(&p, cfg, 0) != 0) {
        return PLANT_E_RANGE;
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        (void)plant_set_motor(&p, i, take_to_ticks(cfg, i, cfg->tendon[i].slack_um - 20000.0));
    }
    (void)plant_solve(&p);
    memcpy(pos_mm, p.tip.pos_mm, sizeof p.tip.pos_mm);
    return 0;
}

int plant_pose_ramp(const plant_cfg_t *cfg, const double ticks[], plant_pose_result_t *out)
{
    plant_t p;
    double from[PLANT_MAX_TENDONS];
    double straight[3];
    double d2 = 0.0;
    uint32_t s;
    uint8_t i;
    int a;
    if (cfg == NULL || ticks == NULL || out == NULL) {
        return PLANT_E_ARG;
    }
    if (plant_straight_tip(cfg, straight) != 0 || plant_init(&p, cfg, 0) != 0) {
        return PLANT_E_RANGE;
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        from[i] = take_to_ticks(cfg, i, cfg->tendon[i].slack_um - PLANT_POSE_RELEASE_UM);
        (void)plant_set_motor(&p, i, from[i]);
    }
    (void)plant_solve(&p);
    for (s = 1; s <= PLANT_POSE_STEPS; s++) {
        double f = (double)s / (double)PLANT_POSE_STEPS;
        for (i = 0; i < cfg->n_tendons; i++) {
            (void)plant_set_motor(&p, i, from[i] + f * (ticks[i] - from[i]));
        }
        (void)plant_solve(&p);
    }
    memset(out, 0, sizeof *out);
    for (i = 0; i < cfg->n_tendons; i++) {
        out->tension_N[i] = p.tension_N[i];
        out->tip_tension_N[i] = p.tip_tension_N[i];
    }
    for (a = 0; a < 3; a++) {
        out->tip_pos_mm[a] = p.tip.pos_mm[a];
        d2 += (p.tip.pos_mm[a] - straight[a]) * (p.tip.pos_mm[a] - straight[a]);
    }
    out->tip_dev_mm = sqrt(d2);
    return 0;
}

int plant_straight_homes(const plant_cfg_t *cfg, uint16_t tension_mN, double ticks[])
{
    plant_pose_result_t r;
    double target = (double)tension_mN * 1e-3;
    uint8_t i;
    uint8_t m;
    int it;
    if (cfg == NULL || ticks == NULL || tension_mN == 0u || plant_cfg_check(cfg) != 0) {
        return PLANT_E_ARG;
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        double single;
        if (plant_true_home(cfg, i, tension_mN, &single) != 0) {
            return PLANT_E_SOLVE;
        }
        ticks[i] = take_to_ticks(cfg, i,
                                 ticks_to_take(cfg, i, single) -
                                     plant_path_compliance(cfg, i, i) * target * 1e6);
    }
    for (it = 0; it < 40; it++) {
        double worst = 0.0;
        double dT[PLANT_MAX_TENDONS];
        if (plant_pose_ramp(cfg, ticks, &r) != 0) {
            return PLANT_E_ARG;
        }
        for (i = 0; i < cfg->n_tendons; i++) {
            dT[i] = target - r.tension_N[i];
            if (fabs(dT[i]) > worst) {
                worst = fabs(dT[i]);
            }
        }
        if (worst < 1e-4) {
            return 0;
        }
        /* du = K^-1 dT + C dT: the frictionless statics T = K (u - s - C T) */
        for (i = 0; i < cfg->n_tendons; i++) {
            const plant_tendon_cfg_t *t = &cfg->tendon[i];
            double du = dT[i] * t->free_len_mm * 1e-3 / t->ea_N;
            for (m = 0; m < cfg->n_tendons; m++) {
                du += plant_path_compliance(cfg, i, m) * dT[m];
            }
            ticks[i] = take_to_ticks(cfg, i, ticks_to_take(cfg, i, ticks[i]) + du * 1e6);
        }
    }
    return PLANT_E_SOLVE;
}

/* |B - b0| (cuT) at sensor k with tendon i alone at take-up take_um. */
static double field_change(const plant_cfg_t *cfg, uint8_t i, uint8_t k, const double b0[3],
                           double take_um)
{
    plant_t p;
    double b[3];
    double s = 0.0;
    uint8_t m;
    int a;
    (void)plant_init(&p, cfg, 0);
    for (m = 0; m < cfg->n_tendons; m++) {
        (void)plant_set_motor(&p, m, take_to_ticks(cfg, m, cfg->tendon[m].slack_um - 20000.0));
    }
    (void)plant_solve(&p);
    (void)plant_set_motor(&p, i, take_to_ticks(cfg, i, take_um));
    (void)plant_solve(&p);
    plant_field_true(&p, k, b);
    for (a = 0; a < 3; a++) {
        s += (b[a] - b0[a]) * (b[a] - b0[a]);
    }
    return sqrt(s) * 100.0;
}

int plant_field_home(const plant_cfg_t *cfg, uint8_t i, uint8_t k, double target_cuT, double *ticks)
{
    plant_t p;
    double b0[3];
    double lo;
    double hi;
    uint8_t m;
    int n;
    if (cfg == NULL || ticks == NULL || plant_cfg_check(cfg) != 0 || i >= cfg->n_tendons ||
        k >= cfg->n_sensors || !(target_cuT > 0.0)) {
        return PLANT_E_ARG;
    }
    (void)plant_init(&p, cfg, 0);
    for (m = 0; m < cfg->n_tendons; m++) {
        (void)plant_set_motor(&p, m, take_to_ticks(cfg, m, cfg->tendon[m].slack_um - 20000.0));
    }
    (void)plant_solve(&p);
    plant_field_true(&p, k, b0);
    lo = cfg->tendon[i].slack_um - 5000.0;
    hi = cfg->tendon[i].slack_um;
    for (n = 0; n < 40 && field_change(cfg, i, k, b0, hi) <= target_cuT; n++) {
        hi += 1000.0;
    }
    if (n == 40 || field_change(cfg, i, k, b0, lo) > target_cuT) {
        return PLANT_E_SOLVE;
    }
    for (n = 0; n < 50; n++) {
        double mid = 0.5 * (lo + hi);
        if (field_change(cfg, i, k, b0, mid) > target_cuT) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    *ticks = take_to_ticks(cfg, i, 0.5 * (lo + hi));
    return 0;
}
