/* hh_bound_scan CFG RUNS PERTURB TENSION_MN [STEP]: the bounded pull in the
 * native closed loop. RUNS calibrations of the plant CFG (perturbed by the
 * fraction PERTURB from the table computed from it), each with its own bus
 * timing (positions every 6-18 ms, goals 2-12 ms late, samples 0-12 ms
 * late) and, with STEP 1 (the default), an ambient step of up to 30 uT per
 * axis on a random sensor at a random moment. Prints each run over 1.25 x
 * the tension + 0.1 N (max_pull_N) and each fault of an undisturbed run,
 * then one summary line: runs, faults, the worst pull, the mean time, and
 * how late the engagements were recorded (ticks past where the tension
 * reached the threshold's share of the target; < 0 early).
 * Environment: S0 picks another series (default 1000); MST_US (with READ_US,
 * default 5000, and JIT_US, default 2000) takes the samples through the
 * firmware's sensor path (ICM-20948 master copies, host reads) instead of a
 * fixed lag; AGE 1 gives the homing the samples' true ages, 2 none. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "plant/closedloop.h"
#include "table/table.h"
#include "table/table_pack.h"

static plant_cfg_t g_nom;
static plant_cfg_t g_cfg;
static tbl_wide_t g_w;
static tbl_buf_t g_buf;
static plant_run_result_t g_res;

int main(int argc, char **argv)
{
    unsigned n, run, t_mN, n_over = 0, n_fault = 0;
    unsigned s0 = getenv("S0") != NULL ? (unsigned)atoi(getenv("S0")) : 1000u;
    double pert, bound, worst = 0.0, t_sum = 0.0;
    int line = 0, step;
    unsigned mst = getenv("MST_US") != NULL ? (unsigned)atoi(getenv("MST_US")) : 0u;
    unsigned rd = getenv("READ_US") != NULL ? (unsigned)atoi(getenv("READ_US")) : 5000u;
    unsigned jit = getenv("JIT_US") != NULL ? (unsigned)atoi(getenv("JIT_US")) : 2000u;
    unsigned age = getenv("AGE") != NULL ? (unsigned)atoi(getenv("AGE")) : 0u;
    double e_late = -1e9, e_early = 1e9, e_sum = 0.0;
    unsigned e_n = 0;
    if (argc < 5) {
        fprintf(stderr, "usage: hh_bound_scan CFG RUNS PERTURB TENSION_MN [STEP]\n");
        return 2;
    }
    n = (unsigned)atoi(argv[2]);
    pert = atof(argv[3]);
    t_mN = (unsigned)atoi(argv[4]);
    step = argc > 5 ? atoi(argv[5]) : 1;
    bound = 1.25 * t_mN / 1000.0 + 0.1;
    if (plant_cfg_load(&g_nom, argv[1], &line) != 0) {
        fprintf(stderr, "%s: line %d\n", argv[1], line);
        return 1;
    }
    if (plant_make_table(&g_nom, &g_w) != 0 || tbl_pack(&g_w, &g_buf) != 0) {
        fprintf(stderr, "%s: no table\n", argv[1]);
        return 1;
    }
    for (run = 0; run < n; run++) {
        plant_run_cfg_t rc;
        double r = 0.0;
        uint8_t i;
        g_cfg = g_nom;
        plant_cfg_perturb(&g_cfg, s0 + run, pert);
        plant_run_defaults(&rc, &g_cfg, tbl_buf_table(&g_buf));
        plant_run_scan(&rc, s0, run, g_nom.n_sensors, g_nom.n_tendons, step);
        rc.mst_us = (uint16_t)mst;
        rc.read_us = (uint16_t)rd;
        rc.read_jitter_us = (uint16_t)jit;
        rc.age_mode = (uint8_t)age;
        rc.cmd.tension_mN = (uint16_t)t_mN;
        if (plant_run(&rc, &g_res) != 0) {
            printf("run %u: the plant did not solve\n", run);
            continue;
        }
        for (i = 0; i < g_res.n_tendons; i++) {
            double e = g_res.engage_err_ticks[i];
            r = g_res.max_pull_N[i] > r ? g_res.max_pull_N[i] : r;
            if (!isnan(e)) {
                e_late = e > e_late ? e : e_late;
                e_early = e < e_early ? e : e_early;
                e_sum += e;
                e_n++;
            }
        }
        worst = r > worst ? r : worst;
        t_sum += g_res.end_ms;
        n_fault += g_res.rc != 0;
        if (g_res.rc != 0 && !step) {
            printf("run %u: undisturbed, fault %u on %u\n", run, g_res.fault, g_res.fault_index);
        }
        if (r > bound) {
            n_over++;
            printf("run %u: %.3f N (%.2f x), fault %u\n", run, r, r * 1000.0 / t_mN, g_res.fault);
        }
    }
    printf("runs %u over the bound %u faults %u worst pull %.3f N (%.2f x, bound %.3f N) mean "
           "%.0f ms\n",
           n, n_over, n_fault, worst, worst * 1000.0 / t_mN, bound, n != 0u ? t_sum / n : 0.0);
    printf("engagements %u recorded late by %.1f to %.1f ticks, mean %.1f\n", e_n, e_early, e_late,
           e_n != 0u ? e_sum / e_n : 0.0);
    return 0;
}
