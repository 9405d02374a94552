/*
 * hh_mc: benchmark studies on the native closed loop (lib/homing + sim/plant,
 * no AVR) that hh_closedloop does not cover: per-run parameter values for the
 * robustness Monte Carlo, one-at-a-time parameter sweeps, and an ambient field
 * that differs between table generation and calibration.
 *
 *   hh_mc CONFIG mc      [-n runs] [-s seed] [-p frac] [-t mN]
 *   hh_mc CONFIG oat     [-p frac] [-k steps] [-s seed] [-t mN]
 *   hh_mc CONFIG ambient [-a "uT uT ..."] [-d directions] [-s seed] [-t mN]
 *   hh_mc CONFIG cal     [-g] [-n runs] [-s seed] [-p frac] [-t mN] [-m full|quick]
 *   hh_mc CONFIG targets [-t mN]
 *
 * The table comes from the nominal plant (plant_make_table: the targets the
 * model-free workflow records with weights on the true robot), as in
 * hh_closedloop; with -g it is the generated table the firmware links
 * (lookup_tables/generated/<robot>.c from the host model, built in with
 * -DHH_ROBOT=<robot>): the model-based workflow. The robot a run calibrates
 * differs from the nominal plant as each study says. Output: header lines
 * `cols,<kind>,<name>,...` naming the columns, then one `<kind>,...` CSV line
 * per result (bench/native.py parses both).
 *
 * mc: the robot is plant_cfg_perturb(nominal, seed + run, frac); one line per
 *   tendon with the tension error and the deviation of every parameter that
 *   tendon depends on (relative for scale factors, absolute for angles,
 *   slack and sensor positions), so the error can be regressed on them.
 * oat: one parameter group at a time moved over [-frac, +frac] (the same
 *   scale plant_cfg_perturb uses for that group), every tendon at once.
 * cal: repeated calibrations of the plant (perturbed with seed + run and
 *   frac when frac > 0) from random slack; quick mode re-homes after a
 *   simulated power cycle as hh_closedloop does. One line per tendon home.
 * targets: per tendon the plant table's and the generated table's target
 *   |dB| and expected travel at the tension, side by side, and the tension
 *   where the noise-free plant meets the generated target (model error).
 * ambient: the calibration sees every sensor's ambient field changed by the
 *   same vector (magnitude from -a, seeded random directions). Per tendon:
 *   the field-change mode through the closed loop (homing core), and both
 *   modes with an ideal detector (noise-free quasi-static pull of the plant,
 *   sub-tick crossing of the target): the field-change mode compares
 *   |B - B0| with the table's target, the paper's absolute mode compares
 *   |B - A_table| (the ambient the table was generated with removed) with
 *   the table's |B(p_T)|. The absolute mode also runs through the homing
 *   core (hom_cmd_t.ambient_cuT): one capture run before the change stores
 *   its ambient offsets, every changed-ambient run reuses them.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plant/closedloop.h"
#include "simrand.h"

typedef struct {
    const char *path;
    const char *study;
    unsigned runs;
    unsigned seed;
    double frac;
    unsigned tension;
    unsigned steps;
    unsigned dirs;
    double amb[32];
    unsigned n_amb;
    int generated;
    int quick;
} opts_t;

static plant_cfg_t nominal;
static tbl_wide_t table;    /* natural units */
static tbl_buf_t table_buf; /* `table` packed, as the homing reads it */

/* `table` packed (again: callers may have changed it). */
static const tbl_table_t *packed(void)
{
    if (tbl_pack(&table, &table_buf) != 0) {
        fprintf(stderr, "hh_mc: the table does not fit the stored format\n");
        exit(1);
    }
    return tbl_buf_table(&table_buf);
}

#ifdef HH_ROBOT
#define HH_CAT2(a, b) a##b
#define HH_CAT(a, b)  HH_CAT2(a, b)
extern const tbl_table_t HH_CAT(tbl_table_, HH_ROBOT);

/* The generated table in natural units. */
static void generated_table(tbl_wide_t *w)
{
    tbl_src_t g = {&HH_CAT(tbl_table_, HH_ROBOT), tbl_copy_ram};
    if (tbl_unpack(&g, w) != 0) {
        fprintf(stderr, "hh_mc: the generated table fails its check\n");
        exit(1);
    }
}
#endif

static void usage(void)
{
    fprintf(stderr,
            "usage: hh_mc CONFIG mc|oat|ambient|cal|targets [-g] [-n runs] [-s seed] [-p frac]\n"
            "             [-t mN] [-k steps] [-a \"uT ...\"] [-d directions] [-m full|quick]\n");
}

static double rel(double actual, double nom)
{
    return nom != 0.0 ? actual / nom - 1.0 : 0.0;
}

/* Relative change of segment j's bending stiffness (its own EI when the
 * config gives one, else the backbone's). */
static double seg_ei_rel(const plant_cfg_t *actual, unsigned j)
{
    if (j >= nominal.n_segments) {
        return 0.0;
    }
    if (nominal.seg_ei_Nm2[j] > 0.0) {
        return rel(actual->seg_ei_Nm2[j], nominal.seg_ei_Nm2[j]);
    }
    return rel(actual->ei_Nm2, nominal.ei_Nm2);
}

/* A full calibration of `actual` with the nominal table, delta mode. */
static void run_setup(plant_run_cfg_t *rc, const plant_cfg_t *actual, unsigned tension,
                      uint32_t seed)
{
    plant_run_defaults(rc, actual, packed());
    rc->seed = seed;
    rc->cmd.mode = HOM_MODE_FULL;
    rc->cmd.tension_mN = (uint16_t)tension;
}

/* One closed-loop calibration of `actual` with the nominal table. */
static int run_one(const plant_cfg_t *actual, unsigned tension, uint32_t seed,
                   plant_run_result_t *res)
{
    plant_run_cfg_t rc;
    run_setup(&rc, actual, tension, seed);
    return plant_run(&rc, res);
}

static int study_mc(const opts_t *o)
{
    static plant_cfg_t actual;
    static plant_run_result_t res;
    unsigned r;
    printf(
        "cols,mc,run,tendon,segment,rc,tension_N,err_N,err_ticks,sim_ms,seg1_ei,seg2_ei,moment,"
        "seg1_len,seg2_len,angle_deg,radius,ea,free_len,slack_um,friction_f0,friction_mu,backlash,"
        "sensor_dx_mm,sensor_dy_mm,sensor_dz_mm,sensor_dr_mm\n");
    for (r = 0; r < o->runs; r++) {
        unsigned i;
        int prc;
        actual = nominal;
        (void)plant_cfg_perturb(&actual, o->seed + r, o->frac);
        prc = run_one(&actual, o->tension, o->seed * 7919u + r, &res);
        for (i = 0; i < nominal.n_tendons; i++) {
            const plant_tendon_cfg_t *n = &nominal.tendon[i];
            const plant_tendon_cfg_t *a = &actual.tendon[i];
            const double *pn = nominal.sensor[table.tendons[i].sensor].pos_mm;
            const double *pa = actual.sensor[table.tendons[i].sensor].pos_mm;
            double rn = hypot(pn[0], pn[1]);
            double dr = rn > 0.0 ? ((pa[0] - pn[0]) * pn[0] + (pa[1] - pn[1]) * pn[1]) / rn : 0.0;
            int ok = prc == 0 && res.rc == 0 && res.have_home[i];
            printf("mc,%u,%u,%u,%d,%.5f,%.5f,%.3f,%u,%.5f,%.5f,%.5f,%.5f,%.5f,%.4f,%.5f,%.5f,%.5f,"
                   "%.2f,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%.4f\n",
                   r, i, n->segment, prc != 0 ? prc : res.rc, ok ? res.tension_at_home_N[i] : NAN,
                   ok ? res.tension_at_home_N[i] - o->tension * 1e-3 : NAN,
                   ok ? res.err_ticks[i] : NAN, (unsigned)res.end_ms, seg_ei_rel(&actual, 0),
                   seg_ei_rel(&actual, 1), rel(actual.magnet_moment_Am2, nominal.magnet_moment_Am2),
                   rel(actual.seg_len_mm[0], nominal.seg_len_mm[0]),
                   nominal.n_segments > 1 ? rel(actual.seg_len_mm[1], nominal.seg_len_mm[1]) : 0.0,
                   a->angle_deg - n->angle_deg, rel(a->radius_mm, n->radius_mm),
                   rel(a->ea_N, n->ea_N), rel(a->free_len_mm, n->free_len_mm),
                   a->slack_um - n->slack_um, rel(a->friction_mN, n->friction_mN),
                   rel(a->friction_mu, n->friction_mu), rel(a->backlash_um, n->backlash_um),
                   pa[0] - pn[0], pa[1] - pn[1], pa[2] - pn[2], dr);
        }
    }
    return 0;
}

/* Moves one parameter group of cfg by x on plant_cfg_perturb's scale. */
static int apply_group(plant_cfg_t *cfg, const char *g, double x)
{
    unsigned i;
    if (strcmp(g, "ei") == 0) {
        cfg->ei_Nm2 *= 1.0 + x;
        for (i = 0; i < cfg->n_segments; i++) {
            cfg->seg_ei_Nm2[i] *= 1.0 + x;
        }
        return 0;
    }
    if (strcmp(g, "moment") == 0) {
        cfg->magnet_moment_Am2 *= 1.0 + x;
        return 0;
    }
    if (strcmp(g, "seg_len") == 0) {
        for (i = 0; i < cfg->n_segments; i++) {
            cfg->seg_len_mm[i] *= 1.0 + 0.2 * x;
        }
        return 0;
    }
    if (strcmp(g, "sensor_z") == 0 || strcmp(g, "sensor_r") == 0) {
        for (i = 0; i < cfg->n_sensors; i++) {
            double *p = cfg->sensor[i].pos_mm;
            double r = hypot(p[0], p[1]);
            if (g[7] == 'z') {
                p[2] += x; /* 1 mm per unit, as plant_cfg_perturb */
            } else if (r > 0.0) {
                p[0] += x * p[0] / r;
                p[1] += x * p[1] / r;
            }
        }
        return 0;
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        plant_tendon_cfg_t *t = &cfg->tendon[i];
        if (strcmp(g, "angle") == 0) {
            t->angle_deg += 5.0 * x;
        } else if (strcmp(g, "radius") == 0) {
            t->radius_mm *= 1.0 + 0.2 * x;
        } else if (strcmp(g, "ea") == 0) {
            t->ea_N *= 1.0 + x;
        } else if (strcmp(g, "free_len") == 0) {
            t->free_len_mm *= 1.0 + x;
        } else if (strcmp(g, "slack") == 0) {
            t->slack_um += 500.0 * x;
        } else if (strcmp(g, "friction_f0") == 0) {
            t->friction_mN *= 1.0 + x;
        } else if (strcmp(g, "friction_mu") == 0) {
            t->friction_mu *= 1.0 + x;
        } else if (strcmp(g, "backlash") == 0) {
            t->backlash_um *= 1.0 + x;
        } else {
            return -1;
        }
    }
    return 0;
}

static const char *const groups[] = {
    "ei",    "moment",      "seg_len",     "angle",    "radius",   "ea",      "free_len",
    "slack", "friction_f0", "friction_mu", "backlash", "sensor_z", "sensor_r"};

static int study_oat(const opts_t *o)
{
    static plant_cfg_t actual;
    static plant_run_result_t res;
    unsigned g, k, i;
    unsigned steps = o->steps < 2u ? 2u : o->steps;
    printf("cols,oat,group,x,tendon,segment,rc,tension_N,err_N\n");
    for (g = 0; g < sizeof groups / sizeof groups[0]; g++) {
        for (k = 0; k < steps; k++) {
            double x = -o->frac + 2.0 * o->frac * k / (steps - 1u);
            int prc;
            actual = nominal;
            (void)apply_group(&actual, groups[g], x);
            prc = run_one(&actual, o->tension, o->seed * 7919u + k, &res);
            for (i = 0; i < nominal.n_tendons; i++) {
                int ok = prc == 0 && res.rc == 0 && res.have_home[i];
                printf("oat,%s,%.4f,%u,%u,%d,%.5f,%.5f\n", groups[g], x, i,
                       nominal.tendon[i].segment, prc != 0 ? prc : res.rc,
                       ok ? res.tension_at_home_N[i] : NAN,
                       ok ? res.tension_at_home_N[i] - o->tension * 1e-3 : NAN);
            }
        }
    }
    return 0;
}

static double norm3(const double v[3])
{
    return sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Ideal detectors: pulls tendon i of `actual` from slack (every other tendon
 * slack) in small steps, noise-free, and finds where |B - B0| reaches the
 * table's field-change target and where |B - a_tab| reaches its absolute
 * target (a_tab: the ambient at table generation). Writes the motor positions
 * (NAN when not reached before the table's travel limit). */
static void ideal_detect(const plant_cfg_t *actual, unsigned i, unsigned tension, double *x_delta,
                         double *x_abs)
{
    static plant_t p;
    tbl_src_t src = {packed(), tbl_copy_ram};
    tbl_point_t pt;
    double eng[TBL_MAX_TENDONS];
    double b0[3], b[3], d[3];
    double prev_x = 0.0, prev_qd = 0.0, prev_qa = 0.0;
    double step = 0.1;
    double tpu = plant_nm_per_tick(actual, (uint8_t)i) * 1e-3; /* um per tick */
    double span = (table.tendons[i].travel_limit_um + 2000.0) / tpu;
    double tgt_d, tgt_a;
    double sgn;
    int8_t dir = actual->tendon[i].pull_dir;
    unsigned k = table.tendons[i].sensor;
    unsigned j;
    double s;
    int first = 1;
    *x_delta = NAN;
    *x_abs = NAN;
    if (tbl_target(&src, (uint8_t)i, (uint16_t)tension, &pt) != 0 ||
        plant_init(&p, actual, 1u) != 0) {
        return;
    }
    tgt_d = pt.target_cuT * 0.01; /* uT */
    tgt_a = pt.abs_target_cuT * 0.01;
    {
        /* |B| of the magnet falls with the pull on some tendons (the tip
         * turns the dipole away): the absolute mode then pulls until the
         * reading falls to the target. The table's straight-pose prediction
         * tells which way. */
        const int32_t *bs = table.sensors[k].b_straight_cuT;
        double straight =
            0.01 * sqrt((double)bs[0] * bs[0] + (double)bs[1] * bs[1] + (double)bs[2] * bs[2]);
        sgn = tgt_a >= straight ? 1.0 : -1.0;
    }
    for (j = 0; j < actual->n_tendons; j++) {
        if (plant_true_engagement(actual, (uint8_t)j, &eng[j]) != 0) {
            return;
        }
        (void)plant_set_motor(&p, (uint8_t)j, eng[j] - actual->tendon[j].pull_dir * 1000.0 / tpu);
    }
    (void)plant_solve(&p);
    plant_field_true(&p, (uint8_t)k, b0);
    for (s = -200.0 / tpu; s <= span; s += step) {
        double x = eng[i] + dir * s;
        double qd, qa;
        unsigned a;
        (void)plant_set_motor(&p, (uint8_t)i, x);
        (void)plant_solve(&p);
        plant_field_true(&p, (uint8_t)k, b);
        for (a = 0; a < 3u; a++) {
            d[a] = b[a] - b0[a];
        }
        qd = norm3(d);
        for (a = 0; a < 3u; a++) {
            d[a] = b[a] - nominal.sensor[k].ambient_uT[a];
        }
        qa = norm3(d);
        if (first) {
            /* a shifted ambient can put the absolute reading past its target
             * while the tendon is still slack: the pull stops at once */
            if (sgn * (qa - tgt_a) >= 0.0) {
                *x_abs = x;
            }
        } else {
            if (isnan(*x_delta) && prev_qd < tgt_d && qd >= tgt_d) {
                *x_delta = prev_x + (x - prev_x) * (tgt_d - prev_qd) / (qd - prev_qd);
            }
            if (isnan(*x_abs) && sgn * (prev_qa - tgt_a) < 0.0 && sgn * (qa - tgt_a) >= 0.0) {
                *x_abs = prev_x + (x - prev_x) * (tgt_a - prev_qa) / (qa - prev_qa);
            }
        }
        if (!isnan(*x_delta) && !isnan(*x_abs)) {
            break;
        }
        prev_x = x;
        prev_qd = qd;
        prev_qa = qa;
        first = 0;
    }
}

static double gauss(uint64_t *s)
{
    double u1 = ((double)(simrand_next(s) >> 11) + 1.0) / 9007199254740993.0;
    double u2 = simrand_unit(s);
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

static int32_t amb_cuT[HOM_MAX_SENSORS][3]; /* absolute mode: captured ambient offsets */

/* The homing core's absolute mode: one capture run on the robot as the table
 * knows it (its baseline stores A = B0 - b_straight per sensor), once per
 * study, as an operator would before the ambient changed. Returns 0 when the
 * offsets were captured. */
static int capture_ambient(const opts_t *o)
{
    static plant_run_result_t res;
    plant_run_cfg_t rc;
    run_setup(&rc, &nominal, o->tension, o->seed * 7919u + 424243u);
    rc.cmd.ambient_cuT = amb_cuT;
    rc.cmd.ambient_capture = 1;
    return plant_run(&rc, &res) == 0 && res.rc == 0 ? 0 : -1;
}

/* A calibration of `actual` in the absolute mode with the captured offsets. */
static int run_abs(const plant_cfg_t *actual, unsigned tension, uint32_t seed,
                   plant_run_result_t *res)
{
    plant_run_cfg_t rc;
    run_setup(&rc, actual, tension, seed);
    rc.cmd.ambient_cuT = amb_cuT;
    rc.cmd.ambient_capture = 0;
    return plant_run(&rc, res);
}

static int study_ambient(const opts_t *o)
{
    static plant_cfg_t actual;
    static plant_run_result_t res;
    uint64_t rng = 0xA3B1E47ull ^ ((uint64_t)o->seed << 20);
    unsigned m, dd, i, k;
    int have_abs = capture_ambient(o) == 0;
    printf("cols,amb,dA_uT,dir,dx_uT,dy_uT,dz_uT,tendon,segment,mode,rc,tension_N,err_N,why\n");
    for (m = 0; m < o->n_amb; m++) {
        unsigned ndirs = o->amb[m] == 0.0 ? 1u : o->dirs;
        for (dd = 0; dd < ndirs; dd++) {
            double v[3];
            double n;
            int prc;
            do {
                v[0] = gauss(&rng);
                v[1] = gauss(&rng);
                v[2] = gauss(&rng);
                n = norm3(v);
            } while (n < 1e-9);
            for (k = 0; k < 3u; k++) {
                v[k] *= o->amb[m] / n;
            }
            actual = nominal;
            for (k = 0; k < actual.n_sensors; k++) {
                actual.sensor[k].ambient_uT[0] += v[0];
                actual.sensor[k].ambient_uT[1] += v[1];
                actual.sensor[k].ambient_uT[2] += v[2];
            }
            if (have_abs) {
                static plant_run_result_t ra;
                int arc = run_abs(&actual, o->tension, o->seed * 7919u + m * 131u + dd, &ra);
                for (i = 0; i < nominal.n_tendons; i++) {
                    int ok = arc == 0 && ra.rc == 0 && ra.have_home[i];
                    printf("amb,%.2f,%u,%.3f,%.3f,%.3f,%u,%u,abs_loop,%d,%.5f,%.5f,%s\n", o->amb[m],
                           dd, v[0], v[1], v[2], i, nominal.tendon[i].segment,
                           arc != 0 ? arc : ra.rc, ok ? ra.tension_at_home_N[i] : NAN,
                           ok ? ra.tension_at_home_N[i] - o->tension * 1e-3 : NAN,
                           arc != 0 ? "run_error" : hom_fault_name(ra.fault));
                }
            }
            prc = run_one(&actual, o->tension, o->seed * 7919u + m * 131u + dd, &res);
            for (i = 0; i < nominal.n_tendons; i++) {
                double xd, xa, td, ta;
                int ok = prc == 0 && res.rc == 0 && res.have_home[i];
                printf("amb,%.2f,%u,%.3f,%.3f,%.3f,%u,%u,delta_loop,%d,%.5f,%.5f,%s\n", o->amb[m],
                       dd, v[0], v[1], v[2], i, nominal.tendon[i].segment, prc != 0 ? prc : res.rc,
                       ok ? res.tension_at_home_N[i] : NAN,
                       ok ? res.tension_at_home_N[i] - o->tension * 1e-3 : NAN,
                       prc != 0 ? "run_error" : hom_fault_name(res.fault));
                ideal_detect(&actual, i, o->tension, &xd, &xa);
                td = isnan(xd) ? NAN : plant_tension_at(&actual, (uint8_t)i, xd);
                ta = isnan(xa) ? NAN : plant_tension_at(&actual, (uint8_t)i, xa);
                printf("amb,%.2f,%u,%.3f,%.3f,%.3f,%u,%u,delta_ideal,%d,%.5f,%.5f,%s\n", o->amb[m],
                       dd, v[0], v[1], v[2], i, nominal.tendon[i].segment, isnan(xd) ? 1 : 0, td,
                       td - o->tension * 1e-3, isnan(xd) ? "target_not_reached" : "none");
                printf("amb,%.2f,%u,%.3f,%.3f,%.3f,%u,%u,abs_ideal,%d,%.5f,%.5f,%s\n", o->amb[m],
                       dd, v[0], v[1], v[2], i, nominal.tendon[i].segment, isnan(xa) ? 1 : 0, ta,
                       ta - o->tension * 1e-3, isnan(xa) ? "target_not_reached" : "none");
            }
        }
    }
    return 0;
}

static int study_cal(const opts_t *o)
{
    static plant_cfg_t actual;
    static plant_run_result_t res;
    plant_run_cfg_t rc;
    unsigned r, i;
    printf("cols,cal,run,tendon,segment,rc,home_ticks,true_home_ticks,err_ticks,tension_N,err_N,"
           "sim_ms,why\n");
    for (r = 0; r < o->runs; r++) {
        int prc;
        actual = nominal;
        (void)plant_cfg_perturb(&actual, o->seed + r, o->frac);
        run_setup(&rc, &actual, o->tension, o->seed * 7919u + r);
        prc = plant_run(&rc, &res);
        if (o->quick && prc == 0 && res.rc == 0) {
            static double start[TBL_MAX_TENDONS];
            rc.cmd.mode = HOM_MODE_QUICK;
            rc.cmd.stored_mask = 0;
            for (i = 0; i < res.n_tendons; i++) {
                rc.cmd.stored_home[i] = res.home[i];
                rc.cmd.stored_mask |= (uint16_t)(1u << i);
                start[i] = res.home_plant[i];
            }
            rc.start_ticks = start;
            rc.frame_offset = 4096 * (int32_t)(1 + r % 3);
            rc.seed += 1000003u;
            prc = plant_run(&rc, &res);
        }
        for (i = 0; i < nominal.n_tendons; i++) {
            int ok = prc == 0 && res.rc == 0 && res.have_home[i];
            printf("cal,%u,%u,%u,%d,%.0f,%.3f,%.3f,%.5f,%.5f,%u,%s\n", r, i,
                   nominal.tendon[i].segment, prc != 0 ? prc : res.rc, ok ? res.home_plant[i] : NAN,
                   res.true_home[i], ok ? res.err_ticks[i] : NAN,
                   ok ? res.tension_at_home_N[i] : NAN,
                   ok ? res.tension_at_home_N[i] - o->tension * 1e-3 : NAN, (unsigned)res.end_ms,
                   prc != 0 ? "run_error" : hom_fault_name(res.fault));
        }
    }
    return 0;
}

static int study_targets(const opts_t *o)
{
    tbl_src_t sp = {packed(), tbl_copy_ram};
    unsigned i;
    static tbl_wide_t own;
    own = table;
    printf("cols,tgt,tendon,segment,plant_sensor,plant_target_uT,plant_travel_um,gen_sensor,"
           "gen_target_uT,gen_travel_um,gen_ideal_tension_N\n");
    for (i = 0; i < table.n_tendons; i++) {
        tbl_point_t a, b;
        int ga = tbl_target(&sp, (uint8_t)i, (uint16_t)o->tension, &a);
        int gb = -1;
        int gs = -1;
        double tn = NAN;
#ifdef HH_ROBOT
        tbl_src_t sg = {&HH_CAT(tbl_table_, HH_ROBOT), tbl_copy_ram};
        double xd, xa;
        gb = tbl_target(&sg, (uint8_t)i, (uint16_t)o->tension, &b);
        {
            tbl_tendon_t row;
            (void)tbl_tendon(&sg, (uint8_t)i, &row);
            gs = row.sensor;
        }
        /* where the noise-free plant meets the generated target, sub-tick */
        generated_table(&table);
        ideal_detect(&nominal, i, o->tension, &xd, &xa);
        table = own;
        sp.table = packed();
        tn = isnan(xd) ? NAN : plant_tension_at(&nominal, (uint8_t)i, xd);
#else
        memset(&b, 0, sizeof b);
#endif
        printf("tgt,%u,%u,%u,%.2f,%.0f,%d,%.2f,%.0f,%.5f\n", i, nominal.tendon[i].segment,
               table.tendons[i].sensor, ga == 0 ? a.target_cuT * 0.01 : NAN,
               ga == 0 ? (double)a.travel_um : NAN, gs, gb == 0 ? b.target_cuT * 0.01 : NAN,
               gb == 0 ? (double)b.travel_um : NAN, tn);
    }
    return 0;
}

int main(int argc, char **argv)
{
    opts_t o;
    int err_line = 0;
    int a;
    memset(&o, 0, sizeof o);
    o.runs = 200;
    o.seed = 1;
    o.frac = 0.05;
    o.steps = 5;
    o.dirs = 8;
    if (argc < 3) {
        usage();
        return 2;
    }
    o.path = argv[1];
    o.study = argv[2];
    for (a = 3; a < argc; a += 2) {
        const char *v = argv[a + 1 < argc ? a + 1 : a];
        if (strcmp(argv[a], "-g") == 0) {
            o.generated = 1;
            a--; /* a flag: no value */
            continue;
        }
        if (a + 1 >= argc) {
            break;
        }
        if (strcmp(argv[a], "-m") == 0) {
            o.quick = strcmp(v, "quick") == 0;
        } else if (strcmp(argv[a], "-n") == 0) {
            o.runs = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-s") == 0) {
            o.seed = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-p") == 0) {
            o.frac = strtod(v, NULL);
        } else if (strcmp(argv[a], "-t") == 0) {
            o.tension = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-k") == 0) {
            o.steps = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-d") == 0) {
            o.dirs = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-a") == 0) {
            char *end;
            const char *q = v;
            o.n_amb = 0;
            while (o.n_amb < 32u) {
                double x = strtod(q, &end);
                if (end == q) {
                    break;
                }
                o.amb[o.n_amb++] = x;
                q = end;
            }
        } else {
            usage();
            return 2;
        }
    }
    if (a != argc) {
        usage();
        return 2;
    }
    if (o.n_amb == 0u) {
        static const double def[] = {0.0, 5.0, 10.0, 20.0, 35.0, 50.0};
        memcpy(o.amb, def, sizeof def);
        o.n_amb = sizeof def / sizeof def[0];
    }
    if (plant_cfg_load(&nominal, o.path, &err_line) != 0 || plant_cfg_check(&nominal) != 0) {
        fprintf(stderr, "hh_mc: %s: bad config (line %d)\n", o.path, err_line);
        return 1;
    }
    if (o.generated) {
#ifdef HH_ROBOT
        generated_table(&table);
        if (table.n_tendons != nominal.n_tendons || table.n_sensors != nominal.n_sensors) {
            fprintf(stderr, "hh_mc: the generated table does not fit %s\n", o.path);
            return 1;
        }
#else
        fprintf(stderr, "hh_mc: built without a generated table (-DHH_ROBOT)\n");
        return 2;
#endif
    } else if (plant_make_table(&nominal, &table) != 0) {
        fprintf(stderr, "hh_mc: cannot build the table from %s\n", o.path);
        return 1;
    }
    if (o.tension == 0u) {
        o.tension = table.default_mN;
    }
    if (strcmp(o.study, "mc") == 0) {
        return study_mc(&o);
    }
    if (strcmp(o.study, "oat") == 0) {
        return study_oat(&o);
    }
    if (strcmp(o.study, "ambient") == 0) {
        return study_ambient(&o);
    }
    if (strcmp(o.study, "cal") == 0) {
        return study_cal(&o);
    }
    if (strcmp(o.study, "targets") == 0) {
        return study_targets(&o);
    }
    usage();
    return 2;
}
