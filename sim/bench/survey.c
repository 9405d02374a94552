/*
 * survey: the identification survey of the bench's robot, written as JSON
 * for `hallhome identify fit` (docs/identify.md).
 *
 * The bench plays the board's part on the plant directly (the board's own
 * `survey` is run through the firmware instead, hallhome.op_survey; the held
 * pulls the board cannot run yet): every tendon in turn, the others left at their start
 * positions (slack), is pulled from its start in small encoder steps until
 * it has gone a set travel past the point where the field starts to change;
 * at every step the record holds what the firmware would see: the servo's
 * encoder position in ticks and each sensor's averaged reading in cuT, in the
 * sensor's own frame (noise, 0.15 uT quantisation and the ambient field
 * included). Optional weights: with every servo slack, a known mass hangs on
 * one tendon per segment (--survey-weight) or on every tendon in turn
 * (--survey-weight-all) and the field before and after is recorded; with two
 * masses (--survey-weight G,G2) each is hung in turn. Optional held pulls
 * (--survey-held): every tendon pulled again while another of its segment
 * holds a bend, which moves its engagement by its routing radius times the
 * bend.
 * The plant's truth (perturbed parameters, true engagements, the true |dB|
 * per grid tension) goes into a separate "truth" object, for evaluating a
 * fit, never for making one.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "bench.h"

#define SURVEY_STEP_TICKS   4u    /* one step: about 25 um of take-up on a 4 mm spool */
#define SURVEY_SAMPLES      4u    /* readings averaged per step and sensor */
#define SURVEY_BASE_SAMPLES 16u   /* readings averaged for a baseline */
#define SURVEY_ENGAGE_UT    3.0   /* field change that marks the engagement: ~10 sigma of a step */
#define SURVEY_MAX_STEPS    4000u /* 100 mm: a pull that never engages is given up */
#define SURVEY_RELEASE_MM   3.0   /* the other tendons' release before a pull */
#define SURVEY_HELD_BACK_MM 1.5   /* a held pull's start before the pull's alone */

/* Averaged reading of every sensor, cuT in the sensor frame. */
static void read_avg(plant_t *p, unsigned n, double out[][3])
{
    for (uint8_t k = 0; k < p->cfg.n_sensors; k++) {
        double sum[3] = {0, 0, 0};
        for (unsigned s = 0; s < n; s++) {
            int32_t r[3];
            (void)plant_read_sensor(p, k, r);
            for (int a = 0; a < 3; a++) {
                sum[a] += (double)r[a];
            }
        }
        for (int a = 0; a < 3; a++) {
            out[k][a] = sum[a] / (double)n;
        }
    }
}

static void put_fields(FILE *f, uint8_t n, double v[][3])
{
    fputc('[', f);
    for (uint8_t k = 0; k < n; k++) {
        fprintf(f, "%s[%.1f,%.1f,%.1f]", k ? "," : "", v[k][0], v[k][1], v[k][2]);
    }
    fputc(']', f);
}

/* A plant with tendon `keep` where the bench started it and every other
 * tendon released SURVEY_RELEASE_MM further: bending away from a tendon
 * lengthens its path, and a tendon left with little slack would engage and
 * hold the robot back during another's pull (the firmware releases the others
 * before it pulls one the same way). */
static int start_plant(const bench_t *b, plant_t *p, uint32_t seed, uint8_t keep)
{
    const plant_cfg_t *c = &b->plant.cfg;
    if (plant_init(p, c, seed) != 0) {
        return -1;
    }
    for (uint8_t m = 0; m < c->n_tendons; m++) {
        double release = m == keep ? 0.0 : SURVEY_RELEASE_MM * 1e6 / plant_nm_per_tick(c, m);
        (void)plant_set_motor(p, m, b->moved_from[m] - (double)c->tendon[m].pull_dir * release);
    }
    return plant_solve(p);
}

/* The pull's bound past the detected engagement, ticks: --survey-travel when
 * given, else the travel the robot's description (the plant config before
 * its perturbation) expects at the top grid tension, as the firmware would
 * take it from its table's travel_um. */
static double survey_bound(const bench_t *b, uint8_t i)
{
    static plant_cfg_t nominal;
    const plant_cfg_t *c = &b->plant.cfg;
    double eng;
    double top;
    int line = 0;
    if (b->survey_travel_mm > 0.0) {
        return b->survey_travel_mm * 1e6 / plant_nm_per_tick(c, i);
    }
    if (plant_cfg_load(&nominal, b->plant_path, &line) != 0 ||
        plant_true_engagement(&nominal, i, &eng) != 0 ||
        plant_true_home(&nominal, i, nominal.grid_mN[nominal.n_grid - 1u], &top) != 0) {
        return 1e6 / plant_nm_per_tick(c, i); /* 1 mm */
    }
    return fabs(top - eng) * plant_nm_per_tick(&nominal, i) / plant_nm_per_tick(c, i);
}

/* Tendon i pulled from its start in steps, the others released, up to the
 * bound past its engagement; with hold < n_tendons (a held pull), tendon
 * `hold` stands at motor position hold_ticks first, bending the robot, and
 * the pull goes a quarter of the bound (the engagement is what counts, and
 * the held tendon's tension rises with it). `sep` goes before the record. */
static int survey_pull(const bench_t *b, FILE *f, uint8_t i, const char *sep, uint8_t hold,
                       double hold_ticks)
{
    static plant_t p;
    double base[PLANT_MAX_SENSORS][3];
    double cur[PLANT_MAX_SENSORS][3];
    const plant_cfg_t *c = &b->plant.cfg;
    double dir = (double)c->tendon[i].pull_dir;
    double start = floor(b->moved_from[i] + 0.5);
    double travel_ticks = survey_bound(b, i);
    uint8_t held = hold < c->n_tendons;
    long engaged_at = -1;
    if (start_plant(b, &p, b->seed * 31u + i + (held ? 7919u * (hold + 1u) : 0u), i) != 0) {
        return -1;
    }
    if (held) {
        /* a hold on the far side lengthens the pulled tendon's path, and
         * it would engage short of its start: it starts SURVEY_HELD_BACK_MM
         * further back */
        start -= dir * floor(SURVEY_HELD_BACK_MM * 1e6 / plant_nm_per_tick(c, i));
        (void)plant_set_motor(&p, i, start);
        (void)plant_set_motor(&p, hold, hold_ticks);
        (void)plant_solve(&p);
        travel_ticks *= 0.25;
    }
    read_avg(&p, SURVEY_BASE_SAMPLES, base);
    fprintf(f, "%s\n  {\"tendon\": %u, ", sep, i);
    if (held) {
        fprintf(f, "\"hold_tendon\": %u, \"hold_ticks\": %.0f, ", hold, hold_ticks);
    }
    fprintf(f, "\"baseline_cuT\": ");
    put_fields(f, c->n_sensors, base);
    fprintf(f, ", \"steps\": [");
    for (unsigned s = 0; s < SURVEY_MAX_STEPS; s++) {
        double ticks = start + dir * (double)(s * SURVEY_STEP_TICKS);
        double dmax = 0.0;
        (void)plant_set_motor(&p, i, ticks);
        (void)plant_solve(&p);
        read_avg(&p, SURVEY_SAMPLES, cur);
        fprintf(f, "%s\n    [%ld, ", s ? "," : "", (long)ticks);
        put_fields(f, c->n_sensors, cur);
        fputc(']', f);
        for (uint8_t k = 0; k < c->n_sensors; k++) {
            double d = 0.0;
            for (int a = 0; a < 3; a++) {
                d += (cur[k][a] - base[k][a]) * (cur[k][a] - base[k][a]);
            }
            d = sqrt(d) * 0.01;
            dmax = d > dmax ? d : dmax;
        }
        if (engaged_at < 0 && dmax > SURVEY_ENGAGE_UT) {
            engaged_at = (long)s;
        }
        if (engaged_at >= 0 && (double)((long)s - engaged_at) * SURVEY_STEP_TICKS >= travel_ticks) {
            break;
        }
    }
    fprintf(f, "],\n   \"max_tension_mN\": %.1f", p.tension_N[i] * 1e3);
    if (held) {
        fprintf(f, ", \"hold_tension_mN\": %.1f", p.tension_N[hold] * 1e3);
    }
    fputc('}', f);
    return engaged_at >= 0 ? 0 : -1;
}

static void survey_weights(const bench_t *b, FILE *f)
{
    static plant_t p;
    double base[PLANT_MAX_SENSORS][3];
    double cur[PLANT_MAX_SENSORS][3];
    const plant_cfg_t *c = &b->plant.cfg;
    int first = 1;
    /* one record per segment and mass, on its first tendon, or with
     * --survey-weight-all one per tendon and mass; a segment's first tendon
     * gets the same noise either way, so the records of one are those of the
     * other on those tendons; each mass is hung from slack */
    for (uint8_t i = 0; i < c->n_tendons; i++) {
        uint8_t j = c->tendon[i].segment;
        uint8_t m;
        for (m = 0; m < i && c->tendon[m].segment != j; m++) {
        }
        if (m < i && !b->survey_weight_all) {
            continue;
        }
        for (uint8_t k = 0; k < b->survey_n_weights; k++) {
            double g = b->survey_weight_g[k];
            if (!(g > 0.0) ||
                start_plant(b, &p, b->seed * 57u + (m < i ? 100u + i : j) + 1000u * k, i) != 0) {
                continue;
            }
            read_avg(&p, SURVEY_BASE_SAMPLES, base);
            (void)plant_set_weight(&p, i, g * 1e-3 * BENCH_G);
            (void)plant_solve(&p);
            read_avg(&p, SURVEY_BASE_SAMPLES, cur);
            fprintf(f,
                    "%s\n  {\"tendon\": %u, \"mass_g\": %.3f, \"baseline_cuT\": ", first ? "" : ",",
                    i, g);
            put_fields(f, c->n_sensors, base);
            fprintf(f, ", \"field_cuT\": ");
            put_fields(f, c->n_sensors, cur);
            fputc('}', f);
            first = 0;
        }
    }
}

/* Held pulls (--survey-held): every tendon pulled from slack while a
 * tendon of its segment stands where it reaches the top grid tension alone.
 * The bend moves the pulled tendon's engagement by its path's change, which
 * its routing radius sets and its stretch does not (docs/identify.md). The
 * hold moves it most along the pulled tendon (the largest |cos| of the angle
 * between them), among the tendons that also bend the robot across it (|sin|
 * at least the fit's HELD_MIN_SIN, host_tools/hallhome/identify_data.py): a
 * hold in the pulled tendon's own plane leaves the robot no freedom as the
 * tendon engages, its field barely changes, and the kink is lost (4 tendons
 * at 90 degrees, antagonist pairs: no held pull). */
#define HELD_MIN_SIN 0.5
#define HELD_MIN_COS 0.25

static int survey_held(const bench_t *b, FILE *f)
{
    const plant_cfg_t *c = &b->plant.cfg;
    const char *sep = "";
    int rc = 0;
    for (uint8_t i = 0; i < c->n_tendons; i++) {
        uint8_t hold = 0xFFu;
        double best = HELD_MIN_COS;
        double home;
        for (uint8_t m = 0; m < c->n_tendons; m++) {
            double a = (c->tendon[m].angle_deg - c->tendon[i].angle_deg) *
                       (3.14159265358979323846 / 180.0);
            if (m != i && c->tendon[m].segment == c->tendon[i].segment &&
                fabs(sin(a)) >= HELD_MIN_SIN && fabs(cos(a)) > best + 1e-9) {
                best = fabs(cos(a));
                hold = m;
            }
        }
        if (hold == 0xFFu || plant_true_home(c, hold, c->grid_mN[c->n_grid - 1u], &home) != 0) {
            continue;
        }
        if (survey_pull(b, f, i, sep, hold, floor(home + 0.5)) != 0) {
            fprintf(stderr, "hh_bench: survey: tendon %u never moved the field, %u held\n", i,
                    hold);
            rc = -1;
        }
        sep = ",";
    }
    return rc;
}

/* The plant's truth: parameters and, per tendon, the true engagement and the
 * noise-free |B - B0| at every sensor for each grid tension (the single-tendon
 * pull of the calibration's definition). */
static void survey_truth(const bench_t *b, FILE *f)
{
    static plant_t p;
    const plant_cfg_t *c = &b->plant.cfg;
    double b0[PLANT_MAX_SENSORS][3];
    fprintf(f, "{\"magnet_moment_Am2\": %.9g, \"magnet_offset_mm\": %.6g, \"tip_mass_g\": %.6g",
            c->magnet_moment_Am2, c->magnet_offset_mm, c->tip_mass_g);
    fprintf(f, ",\n  \"segment_len_mm\": [");
    for (uint8_t j = 0; j < c->n_segments; j++) {
        fprintf(f, "%s%.6g", j ? ", " : "", c->seg_len_mm[j]);
    }
    fprintf(f, "],\n  \"segment_ei_Nm2\": [");
    for (uint8_t j = 0; j < c->n_segments; j++) {
        fprintf(f, "%s%.6g", j ? ", " : "", c->seg_ei_Nm2[j] > 0.0 ? c->seg_ei_Nm2[j] : c->ei_Nm2);
    }
    fprintf(f, "],\n  \"grid_mN\": [");
    for (uint8_t g = 0; g < c->n_grid; g++) {
        fprintf(f, "%s%u", g ? ", " : "", c->grid_mN[g]);
    }
    fprintf(f, "],\n  \"sensors\": [");
    for (uint8_t k = 0; k < c->n_sensors; k++) {
        const double *q = c->sensor[k].pos_mm;
        fprintf(f, "%s{\"pos_mm\": [%.6g, %.6g, %.6g]}", k ? ", " : "", q[0], q[1], q[2]);
    }
    fprintf(f, "],\n  \"tendons\": [");
    (void)plant_pull_alone(c, 0,
                           (double)c->tendon[0].pull_dir * (c->tendon[0].slack_um - 20000.0) /
                               (plant_nm_per_tick(c, 0) * 1e-3),
                           &p);
    for (uint8_t k = 0; k < c->n_sensors; k++) {
        plant_field_true(&p, k, b0[k]);
    }
    for (uint8_t i = 0; i < c->n_tendons; i++) {
        const plant_tendon_cfg_t *t = &c->tendon[i];
        fprintf(f,
                "%s\n   {\"angle_deg\": %.6g, \"radius_mm\": %.6g, \"ea_N\": %.6g, "
                "\"free_len_mm\": %.6g, \"friction_mN\": %.6g, \"friction_mu\": %.6g, "
                "\"backlash_um\": %.6g, \"nm_per_tick\": %.6g, \"engagement_ticks\": %.3f,\n"
                "    \"dB_uT\": [",
                i ? "," : "", t->angle_deg, t->radius_mm, t->ea_N, t->free_len_mm, t->friction_mN,
                t->friction_mu, t->backlash_um, plant_nm_per_tick(c, i), b->eng_ticks[i]);
        for (uint8_t g = 0; g < c->n_grid; g++) {
            double home;
            fprintf(f, "%s[", g ? ", " : "");
            if (plant_true_home(c, i, c->grid_mN[g], &home) == 0 &&
                plant_pull_alone(c, i, home, &p) == 0) {
                for (uint8_t k = 0; k < c->n_sensors; k++) {
                    double w[3];
                    double s = 0.0;
                    plant_field_true(&p, k, w);
                    for (int a = 0; a < 3; a++) {
                        s += (w[a] - b0[k][a]) * (w[a] - b0[k][a]);
                    }
                    fprintf(f, "%s%.4f", k ? ", " : "", sqrt(s));
                }
            }
            fputc(']', f);
        }
        fprintf(f, "]}");
    }
    fprintf(f, "]}");
}

int survey_write(bench_t *b, const char *path)
{
    FILE *f;
    int rc = 0;
    if (!b->have_plant) {
        fprintf(stderr, "hh_bench: --survey needs --plant\n");
        return -1;
    }
    f = fopen(path, "w");
    if (f == NULL) {
        perror(path);
        return -1;
    }
    fprintf(f,
            "{\"format\": \"hallhome-survey\", \"version\": 1, \"source\": \"hh_bench\",\n"
            " \"robot\": \"%s\", \"seed\": %u, \"perturb\": %.6g, \"perturb_stiffness\": %.6g,\n"
            " \"field_unit\": \"cuT\", \"step_ticks\": %u,\n \"pulls\": [",
            b->plant.cfg.name, b->seed, b->perturb,
            b->perturb_stiffness < 0.0 ? b->perturb : b->perturb_stiffness, SURVEY_STEP_TICKS);
    for (uint8_t i = 0; i < b->plant.cfg.n_tendons; i++) {
        if (survey_pull(b, f, i, i ? "," : "", 0xFFu, 0.0) != 0) {
            fprintf(stderr, "hh_bench: survey: tendon %u never moved the field\n", i);
            rc = -1;
        }
    }
    fprintf(f, "],\n \"weights\": [");
    survey_weights(b, f);
    if (b->survey_held) {
        fprintf(f, "],\n \"held\": [");
        if (survey_held(b, f) != 0) {
            rc = -1;
        }
    }
    fprintf(f, "],\n \"truth\": ");
    survey_truth(b, f);
    fprintf(f, "}\n");
    if (fclose(f) != 0) {
        perror(path);
        rc = -1;
    }
    return rc;
}
