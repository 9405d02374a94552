/*
 * plant: statics, kinematics, magnet field and sensors of the robot model
 * (see plant.h for the model).
 */
#include "plant/plant.h"
#include "plant/kinematics.h"
#include "simrand.h"

#include <math.h>
#include <string.h>

#define PLANT_PI      3.14159265358979323846
#define PLANT_MU0_4PI 1e-7

/* ---- tendon geometry ------------------------------------------------------- */

static void tendon_dir(const plant_cfg_t *c, uint8_t i, double d[2])
{
    double a = c->tendon[i].angle_deg * PLANT_PI / 180.0;
    d[0] = cos(a);
    d[1] = sin(a);
}

/* Path compliance between tendons i and m: how far tendon i's path shortens
 * per newton at the tip of tendon m (m/N), from the segments both span:
 * bending, and the backbone's compression when its EA is given. */
static double compliance(const plant_cfg_t *c, uint8_t i, uint8_t m)
{
    double di[2];
    double dm[2];
    double len = 0.0;
    double axial = 0.0;
    uint8_t j;
    uint8_t top =
        c->tendon[i].segment < c->tendon[m].segment ? c->tendon[i].segment : c->tendon[m].segment;
    tendon_dir(c, i, di);
    tendon_dir(c, m, dm);
    for (j = 0; j < top; j++) {
        len += c->seg_len_mm[j] * 1e-3 / plant_seg_ei(c, j);
        /* every tendon through segment j compresses it, shortening every path */
        if (c->seg_ea_N[j] > 0.0) {
            axial += c->seg_len_mm[j] * 1e-3 / c->seg_ea_N[j];
        }
    }
    return len * c->tendon[i].radius_mm * 1e-3 * c->tendon[m].radius_mm * 1e-3 *
               (di[0] * dm[0] + di[1] * dm[1]) +
           axial;
}

double plant_path_compliance(const plant_cfg_t *cfg, uint8_t i, uint8_t m)
{
    if (cfg == NULL || i >= cfg->n_tendons || m >= cfg->n_tendons) {
        return 0.0;
    }
    return compliance(cfg, i, m);
}

/* ---- statics --------------------------------------------------------------- */

/* Tendon i's tensions given its elongation budget e (m: spool take-up minus
 * slack minus the path shortening caused by the other tendons and gravity),
 * its own path compliance cii, stiffness k and friction; prev is the tip-side
 * tension of the previous equilibrium (the friction play's memory). */
static void tendon_solve(const plant_tendon_cfg_t *t, double e, double cii, double k, double prev,
                         double *ts, double *tt)
{
    double mu = t->friction_mu;
    double f0 = t->friction_mN * 1e-3;
    double T;
    if (e <= 0.0) {
        *ts = 0.0;
        *tt = 0.0;
        return;
    }
    /* stuck: the tip keeps its tension */
    T = k * (e - cii * prev);
    if (T < 0.0) {
        T = 0.0;
    }
    if (prev >= T * (1.0 - mu) - f0 && prev <= T * (1.0 + mu) + f0 && T > 0.0) {
        *ts = T;
        *tt = prev;
        return;
    }
    if (prev < T * (1.0 - mu) - f0) { /* pulling: friction opposes, tip lags */
        T = k * (e + cii * f0) / (1.0 + k * cii * (1.0 - mu));
        *ts = T;
        *tt = T * (1.0 - mu) - f0 > 0.0 ? T * (1.0 - mu) - f0 : 0.0;
        return;
    }
    /* releasing: friction holds tension at the tip */
    T = k * (e - cii * f0) / (1.0 + k * cii * (1.0 + mu));
    if (T > 0.0) {
        *ts = T;
        *tt = T * (1.0 + mu) + f0;
        return;
    }
    *ts = 0.0;
    *tt = e / cii;
    if (*tt > f0) {
        *tt = f0;
    }
    if (*tt > prev) {
        *tt = prev;
    }
}

/* Tendon i held by a hanging force w at the spool side: the spool-side
 * tension is w whatever the path does (the mass moves), and the tip-side
 * tension is the friction play's state pushed into [w (1 - mu) - f0,
 * w (1 + mu) + f0]: hung from slack the tip sees w (1 - mu) - f0. */
static void weight_solve(const plant_tendon_cfg_t *t, double w, double prev, double *ts, double *tt)
{
    double mu = t->friction_mu;
    double f0 = t->friction_mN * 1e-3;
    double lo = w * (1.0 - mu) - f0;
    double hi = w * (1.0 + mu) + f0;
    *ts = w;
    *tt = prev < lo ? lo : (prev > hi ? hi : prev);
    if (*tt < 0.0) {
        *tt = 0.0;
    }
}

static void backlash_update(plant_t *p, uint8_t i)
{
    double half = 0.5 * p->cfg.tendon[i].backlash_um;
    if (p->motor_um[i] - half > p->spool_um[i]) {
        p->spool_um[i] = p->motor_um[i] - half;
    } else if (p->motor_um[i] + half < p->spool_um[i]) {
        p->spool_um[i] = p->motor_um[i] + half;
    }
}

/* Path shortening of every tendon by the gravity curvature gk. */
static void gravity_shortening(const plant_cfg_t *c, double gk[][2], double gshort[])
{
    uint8_t i;
    uint8_t j;
    for (i = 0; i < c->n_tendons; i++) {
        double d[2];
        tendon_dir(c, i, d);
        gshort[i] = 0.0;
        for (j = 0; j < c->tendon[i].segment; j++) {
            gshort[i] += c->seg_len_mm[j] * 1e-3 * c->tendon[i].radius_mm * 1e-3 *
                         (d[0] * gk[j][0] + d[1] * gk[j][1]);
        }
    }
}

/* Projected Gauss-Seidel over the tendons: each tendon in turn given the
 * others' tip tensions; the system matrix I + kC is symmetric positive
 * definite up to scaling, so the sweeps converge. Returns the sweeps. */
static uint32_t tension_sweeps(plant_t *p, const double prev[], double cmat[][PLANT_MAX_TENDONS],
                               const double gshort[])
{
    const plant_cfg_t *c = &p->cfg;
    uint32_t it;
    uint8_t i;
    uint8_t m;
    for (it = 0; it < 400u; it++) {
        double change = 0.0;
        for (i = 0; i < c->n_tendons; i++) {
            const plant_tendon_cfg_t *t = &c->tendon[i];
            double k = t->ea_N / (t->free_len_mm * 1e-3);
            double e = (p->spool_um[i] - t->slack_um) * 1e-6 - gshort[i];
            double ts;
            double tt;
            for (m = 0; m < c->n_tendons; m++) {
                if (m != i) {
                    e -= cmat[i][m] * p->tip_tension_N[m];
                }
            }
            tendon_solve(t, e, cmat[i][i], k, prev[i], &ts, &tt);
            if (p->weight_N[i] > ts) {
                weight_solve(t, p->weight_N[i], prev[i], &ts, &tt);
            }
            change += fabs(tt - p->tip_tension_N[i]) + fabs(ts - p->tension_N[i]);
            p->tension_N[i] = ts;
            p->tip_tension_N[i] = tt;
        }
        if (change < 1e-9) {
            break;
        }
    }
    return it + 1u;
}

/* Segment curvatures: gravity's gk plus every tendon's moment. */
static void curvatures(plant_t *p, double gk[][2])
{
    const plant_cfg_t *c = &p->cfg;
    uint8_t i;
    uint8_t j;
    for (j = 0; j < c->n_segments; j++) {
        p->curv[j][0] = gk[j][0];
        p->curv[j][1] = gk[j][1];
    }
    for (i = 0; i < c->n_tendons; i++) {
        double d[2];
        double mom = p->tip_tension_N[i] * c->tendon[i].radius_mm * 1e-3;
        tendon_dir(c, i, d);
        for (j = 0; j < c->tendon[i].segment; j++) {
            p->curv[j][0] += mom * d[0] / plant_seg_ei(c, j);
            p->curv[j][1] += mom * d[1] / plant_seg_ei(c, j);
        }
    }
}

int plant_solve(plant_t *p)
{
    const plant_cfg_t *c;
    double prev[PLANT_MAX_TENDONS];
    double cmat[PLANT_MAX_TENDONS][PLANT_MAX_TENDONS];
    double gshort[PLANT_MAX_TENDONS];
    double gk[PLANT_MAX_SEGMENTS][2];
    double next[PLANT_MAX_SEGMENTS][2];
    int grav;
    uint8_t i;
    uint8_t m;
    uint8_t j;
    uint8_t round;

    if (p == NULL) {
        return PLANT_E_ARG;
    }
    c = &p->cfg;
    grav = plant_has_gravity(c);
    memset(gk, 0, sizeof gk);
    if (grav) {
        plant_gravity_curv(c, p->curv, gk); /* from the last pose */
    }
    for (i = 0; i < c->n_tendons; i++) {
        backlash_update(p, i);
        prev[i] = p->tip_tension_N[i];
        for (m = 0; m < c->n_tendons; m++) {
            cmat[i][m] = compliance(c, i, m);
        }
    }
    /* gravity's moment depends on the pose it bends: fixed-point rounds
     * until its curvature moves less than PLANT_GRAVITY_TOL */
    p->iterations = 0u;
    for (round = 0u;; round++) {
        double delta = 0.0;
        gravity_shortening(c, gk, gshort);
        p->iterations += tension_sweeps(p, prev, cmat, gshort);
        curvatures(p, gk);
        if (!grav || round + 1u >= PLANT_GRAVITY_ROUNDS) {
            break;
        }
        plant_gravity_curv(c, p->curv, next);
        for (j = 0; j < c->n_segments; j++) {
            delta = fmax(delta, fabs(next[j][0] - gk[j][0]) + fabs(next[j][1] - gk[j][1]));
        }
        memcpy(gk, next, sizeof gk);
        if (delta < PLANT_GRAVITY_TOL) {
            break;
        }
    }
    plant_forward_kinematics(p);
    return 0;
}

/* ---- field and sensors ----------------------------------------------------- */

void plant_dipole_uT(const plant_cfg_t *cfg, const plant_pose_t *tip, const double q_mm[3],
                     double b_uT[3])
{
    double m[3];
    double r[3];
    double d2 = 0.0;
    double d;
    double mr = 0.0;
    int a;
    for (a = 0; a < 3; a++) {
        double mag = (tip->pos_mm[a] + tip->rot[a][2] * cfg->magnet_offset_mm) * 1e-3;
        m[a] = tip->rot[a][2] * cfg->magnet_moment_Am2;
        r[a] = q_mm[a] * 1e-3 - mag;
        d2 += r[a] * r[a];
    }
    d = sqrt(d2);
    if (d < 1e-4) {
        d = 1e-4;
    }
    for (a = 0; a < 3; a++) {
        r[a] /= d;
        mr += m[a] * r[a];
    }
    for (a = 0; a < 3; a++) {
        b_uT[a] = PLANT_MU0_4PI * (3.0 * mr * r[a] - m[a]) / (d * d * d) * 1e6;
    }
}

void plant_field_true(const plant_t *p, uint8_t k, double b_uT[3])
{
    int a;
    if (p == NULL || k >= p->cfg.n_sensors) {
        b_uT[0] = b_uT[1] = b_uT[2] = 0.0;
        return;
    }
    plant_dipole_uT(&p->cfg, &p->tip, p->cfg.sensor[k].pos_mm, b_uT);
    for (a = 0; a < 3; a++) {
        b_uT[a] += p->cfg.sensor[k].ambient_uT[a] + p->extra_uT[k][a];
    }
}

static double plant_gauss(plant_t *p)
{
    double u1 = ((double)(simrand_next(&p->rng) >> 11) + 0.5) / 9007199254740992.0;
    double u2 = simrand_unit(&p->rng);
    return sqrt(-2.0 * log(u1)) * cos(2.0 * PLANT_PI * u2);
}

/* World-frame field into sensor k's frame: R^T b. */
static void to_sensor(const plant_cfg_t *c, uint8_t k, const double w[3], double s[3])
{
    const double *r = c->sensor[k].rot;
    int a;
    for (a = 0; a < 3; a++) {
        s[a] = r[0 * 3 + a] * w[0] + r[1 * 3 + a] * w[1] + r[2 * 3 + a] * w[2];
    }
}

void plant_field_sensor(const plant_t *p, uint8_t k, double b_uT[3])
{
    double w[3];
    plant_field_true(p, k, w);
    to_sensor(&p->cfg, k, w, b_uT);
}

int plant_read_sensor(plant_t *p, uint8_t k, int32_t out_cuT[3])
{
    double w[3];
    double b[3];
    int a;
    int ovf = 0;
    if (p == NULL || out_cuT == NULL || k >= p->cfg.n_sensors) {
        return PLANT_E_ARG;
    }
    plant_field_true(p, k, w);
    to_sensor(&p->cfg, k, w, b);
    for (a = 0; a < 3; a++) {
        double lsb = floor((b[a] + p->cfg.noise_uT * plant_gauss(p)) / 0.15 + 0.5);
        if (lsb > PLANT_LSB_MAX) {
            lsb = PLANT_LSB_MAX;
            ovf = 1;
        } else if (lsb < -PLANT_LSB_MAX) {
            lsb = -PLANT_LSB_MAX;
            ovf = 1;
        }
        out_cuT[a] = (int32_t)lsb * PLANT_LSB_CUT;
    }
    return ovf;
}

/* ---- set-up and motors ----------------------------------------------------- */

double plant_nm_per_tick(const plant_cfg_t *cfg, uint8_t i)
{
    return cfg->tendon[i].nm_per_tick > 0.0 ? cfg->tendon[i].nm_per_tick : cfg->nm_per_tick;
}

int plant_init(plant_t *p, const plant_cfg_t *cfg, uint32_t seed)
{
    uint8_t i;
    if (p == NULL || cfg == NULL) {
        return PLANT_E_ARG;
    }
    if (plant_cfg_check(cfg) != 0) {
        return PLANT_E_RANGE;
    }
    memset(p, 0, sizeof *p);
    p->cfg = *cfg;
    p->rng = 0xC0FFEEull ^ ((uint64_t)seed << 20) ^ seed;
    for (i = 0; i < cfg->n_tendons; i++) {
        p->spool_um[i] = 0.5 * cfg->tendon[i].backlash_um; /* against the release side */
    }
    return plant_solve(p);
}

int plant_set_motor(plant_t *p, uint8_t i, double ticks)
{
    if (p == NULL || i >= p->cfg.n_tendons) {
        return PLANT_E_ARG;
    }
    p->motor_um[i] =
        (double)p->cfg.tendon[i].pull_dir * ticks * plant_nm_per_tick(&p->cfg, i) * 1e-3;
    return 0;
}

int plant_set_weight(plant_t *p, uint8_t i, double newtons)
{
    if (p == NULL || i >= p->cfg.n_tendons || !(newtons >= 0.0) || isinf(newtons)) {
        return PLANT_E_ARG;
    }
    p->weight_N[i] = newtons;
    return 0;
}

double plant_motor_ticks(const plant_t *p, uint8_t i)
{
    if (p == NULL || i >= p->cfg.n_tendons) {
        return 0.0;
    }
    return p->motor_um[i] / (plant_nm_per_tick(&p->cfg, i) * 1e-3) *
           (double)p->cfg.tendon[i].pull_dir;
}

/* ---- ground truth searches -------------------------------------------------- */

/* Tendon i pulled from deep slack to `ticks`, the others far slack; returns
 * the spool-side (tip when tip != 0) tension. */
static double pull_from_slack(const plant_cfg_t *cfg, uint8_t i, double ticks, int tip, plant_t *p)
{
    uint8_t m;
    if (plant_init(p, cfg, 0) != 0) {
        return -1.0;
    }
    for (m = 0; m < cfg->n_tendons; m++) {
        /* the others 20 mm slack; this one starts just slack then jumps */
        double slack_ticks =
            (cfg->tendon[m].slack_um - 20000.0) / (plant_nm_per_tick(cfg, m) * 1e-3);
        (void)plant_set_motor(p, m, (double)cfg->tendon[m].pull_dir * slack_ticks);
    }
    (void)plant_solve(p);
    (void)plant_set_motor(p, i, ticks);
    (void)plant_solve(p);
    return tip ? p->tip_tension_N[i] : p->tension_N[i];
}

int plant_pull_alone(const plant_cfg_t *cfg, uint8_t i, double ticks, plant_t *p)
{
    if (cfg == NULL || p == NULL || i >= cfg->n_tendons) {
        return PLANT_E_ARG;
    }
    return pull_from_slack(cfg, i, ticks, 0, p) < 0.0 ? PLANT_E_ARG : 0;
}

double plant_tension_at(const plant_cfg_t *cfg, uint8_t i, double ticks)
{
    plant_t p;
    if (cfg == NULL || i >= cfg->n_tendons) {
        return 0.0;
    }
    return pull_from_slack(cfg, i, ticks, 0, &p);
}

/* Bisection on the pull position (in pull-direction ticks) for the point where
 * the chosen tension first exceeds level. */
static int search_pull(const plant_cfg_t *cfg, uint8_t i, double level, int tip, double *ticks)
{
    plant_t p;
    double dir;
    double lo;
    double hi;
    int n;
    if (cfg == NULL || ticks == NULL || i >= cfg->n_tendons || plant_cfg_check(cfg) != 0) {
        return PLANT_E_ARG;
    }
    dir = (double)cfg->tendon[i].pull_dir;
    lo = (cfg->tendon[i].slack_um - 5000.0) / (plant_nm_per_tick(cfg, i) * 1e-3);
    hi = lo + 1000.0;
    for (n = 0; n < 40 && pull_from_slack(cfg, i, dir * hi, tip, &p) <= level; n++) {
        hi += 1000.0;
    }
    if (n == 40 || pull_from_slack(cfg, i, dir * lo, tip, &p) > level) {
        return PLANT_E_SOLVE;
    }
    for (n = 0; n < 60; n++) {
        double mid = 0.5 * (lo + hi);
        if (pull_from_slack(cfg, i, dir * mid, tip, &p) > level) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    *ticks = dir * 0.5 * (lo + hi);
    return 0;
}

int plant_true_home(const plant_cfg_t *cfg, uint8_t i, uint16_t tension_mN, double *ticks)
{
    if (tension_mN == 0u) {
        return PLANT_E_ARG;
    }
    return search_pull(cfg, i, tension_mN * 1e-3, 0, ticks);
}

int plant_true_engagement(const plant_cfg_t *cfg, uint8_t i, double *ticks)
{
    return search_pull(cfg, i, 1e-9, 1, ticks);
}

/* ---- table ------------------------------------------------------------------ */

static uint32_t fnv_update(uint32_t h, const void *data, size_t n)
{
    const unsigned char *b = (const unsigned char *)data;
    size_t k;
    for (k = 0; k < n; k++) {
        h = (h ^ b[k]) * 16777619u;
    }
    return h;
}

static uint32_t round_u32(double v)
{
    return v <= 0.0 ? 0u : (uint32_t)(v + 0.5);
}

/* A field in cuT rounded to the table's stored unit (whole LSB), so the wide
 * table and its packed form hold the same values. */
static uint32_t round_field(double cuT)
{
    return round_u32(cuT / (double)TBL_CUT_PER_LSB) * TBL_CUT_PER_LSB;
}

/* |B - B0| and |B| of the magnet alone (cuT) at every sensor with tendon i
 * pulled alone to motor position x, into column g of dt and ab. */
static void field_delta(const plant_cfg_t *cfg, uint8_t i, double x, double b0[][3], plant_t *p,
                        double dt[][TBL_MAX_GRID], double ab[][TBL_MAX_GRID], uint8_t g)
{
    uint8_t k;
    int a;
    (void)pull_from_slack(cfg, i, x, 0, p);
    for (k = 0; k < cfg->n_sensors; k++) {
        double b[3];
        double bm[3];
        double s = 0.0;
        double sm = 0.0;
        plant_field_true(p, k, b);
        plant_dipole_uT(cfg, &p->tip, cfg->sensor[k].pos_mm, bm);
        for (a = 0; a < 3; a++) {
            s += (b[a] - b0[k][a]) * (b[a] - b0[k][a]);
            sm += bm[a] * bm[a];
        }
        dt[k][g] = sqrt(s) * 100.0;
        ab[k][g] = sqrt(sm) * 100.0;
    }
}

int plant_make_table(const plant_cfg_t *cfg, tbl_wide_t *t)
{
    plant_t p;
    double b0[PLANT_MAX_SENSORS][3];
    uint8_t i;
    uint8_t k;
    uint8_t g;
    int a;

    if (cfg == NULL || t == NULL) {
        return PLANT_E_ARG;
    }
    if (plant_cfg_check(cfg) != 0) {
        return PLANT_E_RANGE;
    }
    memset(t, 0, sizeof *t);
    t->magic = TBL_MAGIC;
    t->format_version = TBL_FORMAT_VERSION;
    memcpy(t->name, cfg->name, TBL_NAME_LEN);
    t->name[TBL_NAME_LEN - 1u] = '\0';
    t->n_tendons = cfg->n_tendons;
    t->n_sensors = cfg->n_sensors;
    t->n_grid = cfg->n_grid;
    t->mode = TBL_MODE_DELTA;
    memcpy(t->grid_mN, cfg->grid_mN, sizeof t->grid_mN);
    t->default_mN = cfg->default_mN;
    t->noise_cuT = (uint16_t)round_u32(cfg->noise_uT * 100.0);

    /* straight pose: every tendon far slack */
    (void)pull_from_slack(cfg, 0,
                          (double)cfg->tendon[0].pull_dir * (cfg->tendon[0].slack_um - 20000.0) /
                              (plant_nm_per_tick(cfg, 0) * 1e-3),
                          0, &p);
    for (k = 0; k < cfg->n_sensors; k++) {
        double bw[3];
        double bm[3];
        plant_field_true(&p, k, b0[k]);
        plant_dipole_uT(cfg, &p.tip, cfg->sensor[k].pos_mm, bw);
        to_sensor(cfg, k, bw, bm);
        t->sensors[k].mux_channel = cfg->sensor[k].mux_channel;
        t->sensors[k].i2c_addr = cfg->sensor[k].i2c_addr;
        for (a = 0; a < 3; a++) {
            t->sensors[k].b_straight_cuT[a] =
                (int32_t)floor(bm[a] * 100.0 / TBL_CUT_PER_LSB + 0.5) * (int32_t)TBL_CUT_PER_LSB;
        }
    }

    for (i = 0; i < cfg->n_tendons; i++) {
        const plant_tendon_cfg_t *tc = &cfg->tendon[i];
        tbl_tendon_t *row = &t->tendons[i];
        double eng;
        double dtarget[PLANT_MAX_SENSORS][TBL_MAX_GRID];
        double abst[PLANT_MAX_SENSORS][TBL_MAX_GRID];
        double travel[TBL_MAX_GRID];
        double home[TBL_MAX_GRID];
        int rising[PLANT_MAX_SENSORS];
        int best = -1;
        double best_val = 0.0;
        int rc = plant_true_engagement(cfg, i, &eng);
        if (rc != 0) {
            return rc;
        }
        row->servo_id = tc->servo_id;
        row->pull_dir = tc->pull_dir;
        row->segment = tc->segment;
        row->nm_per_tick = round_u32(plant_nm_per_tick(cfg, i));
        for (g = 0; g < cfg->n_grid; g++) {
            rc = plant_true_home(cfg, i, cfg->grid_mN[g], &home[g]);
            if (rc != 0) {
                return rc;
            }
            travel[g] = (home[g] - eng) * (double)tc->pull_dir * plant_nm_per_tick(cfg, i) * 1e-3;
            field_delta(cfg, i, home[g], b0, &p, dtarget, abst, g);
        }
        /* the field must keep rising between the grid's homes and a little
         * past the top (a magnet that passes a sensor makes |dB| peak, and a
         * pull stops at the target's first crossing): midpoints, then the
         * top plus a quarter of its last interval */
        for (k = 0; k < cfg->n_sensors; k++) {
            rising[k] = 1;
        }
        for (g = 1; g <= cfg->n_grid; g++) {
            double mid[PLANT_MAX_SENSORS][TBL_MAX_GRID];
            double unused[PLANT_MAX_SENSORS][TBL_MAX_GRID];
            uint8_t top = (uint8_t)(cfg->n_grid - 1u);
            double x = g < cfg->n_grid ? 0.5 * (home[g - 1u] + home[g])
                                       : home[top] + 0.25 * (home[top] - home[top - 1u]);
            field_delta(cfg, i, x, b0, &p, mid, unused, 0);
            for (k = 0; k < cfg->n_sensors; k++) {
                if (mid[k][0] <= dtarget[k][g - 1u] ||
                    (g < cfg->n_grid && dtarget[k][g] <= mid[k][0])) {
                    rising[k] = 0;
                }
            }
        }
        for (k = 0; k < cfg->n_sensors; k++) {
            if (rising[k] && dtarget[k][0] > best_val) {
                best_val = dtarget[k][0];
                best = k;
            }
        }
        if (tc->sensor >= 0) {
            best = tc->sensor;
        }
        if (best < 0) {
            return PLANT_E_SOLVE;
        }
        row->sensor = (uint8_t)best;
        for (g = 0; g < cfg->n_grid; g++) {
            row->target_cuT[g] = round_field(dtarget[best][g]);
            row->abs_target_cuT[g] = round_field(abst[best][g]);
            row->travel_um[g] = round_u32(travel[g]);
        }
        row->travel_limit_um = round_u32(travel[cfg->n_grid - 1u] * cfg->travel_limit_factor +
                                         cfg->travel_limit_margin_um);
        if (cfg->travel_limit_um > 0.0) {
            row->travel_limit_um = round_u32(cfg->travel_limit_um);
        }
    }
    t->table_id = fnv_update(2166136261u, t->tendons, sizeof t->tendons);
    return 0;
}

/* ---- simple servo ----------------------------------------------------------- */

void plant_servo_init(plant_servo_t *s, double pos, double tau_ms)
{
    s->pos = pos;
    s->goal = (int32_t)floor(pos + 0.5);
    s->vel_units = 0;
    s->tau_ms = tau_ms;
    s->torque = 1;
}

void plant_servo_step(plant_servo_t *s, double dt_ms)
{
    double vmax;
    double v;
    if (!s->torque) {
        return;
    }
    vmax = (double)(s->vel_units == 0u ? 265u : s->vel_units) * PLANT_TPS_PER_VEL_UNIT * 1e-3;
    v = ((double)s->goal - s->pos) / s->tau_ms; /* ticks per ms */
    if (v > vmax) {
        v = vmax;
    } else if (v < -vmax) {
        v = -vmax;
    }
    /* an exact first-order step when not speed-limited, so large dt stays stable */
    if (fabs(v) < vmax) {
        s->pos = (double)s->goal + (s->pos - (double)s->goal) * exp(-dt_ms / s->tau_ms);
    } else {
        s->pos += v * dt_ms;
    }
}

int32_t plant_servo_present(const plant_servo_t *s)
{
    return (int32_t)floor(s->pos + 0.5);
}
