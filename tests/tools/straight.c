/*
 * hh_straight: the proof of straight-pose homes on the plant, before any
 * firmware (docs/homing.md, "Straight-pose homes").
 *
 *   hh_straight CONFIG -t mN --shift-um U0,U1,... [-s seed] [-p perturb]
 *               [--homes H0,H1,... | --targets-cuT C0,C1,... --sensors K0,K1,...]
 *               [--tol mN]
 *
 * Takes each tendon's single-tendon home: the plant's true one (the spool
 * tension at the target), or the firmware's measured ones with --homes
 * (plant frame ticks), or with --targets-cuT where a calibration against a
 * table's field targets lands, noise-free (plant_field_home: the target
 * |dB| of each tendon on its selected sensor); then it pays out the
 * given shift (um of take-up, the host's straight_shift_um() at this
 * tension), moves every tendon there together (plant_pose_ramp) and reports
 * the tensions and the tip's deviation from straight; beside it the same for
 * every tendon at its single-tendon home (today's final pose) and the plant's
 * own straight-pose homes (plant_straight_homes) for the error in ticks. The
 * plant is perturbed with seed and perturb as hh_closedloop and hh_bench do.
 *
 * CSV lines: `tendon,i,segment,single_ticks,straight_ticks,true_straight_ticks,
 * err_ticks,tol_ticks,plant_shift_um,host_shift_um,T_single_final_N,T_straight_N,T_alone_N`
 * (tol_ticks: the ticks of its own spool that move a tendon's tension by the
 * tolerance in the true straight pose, the others held; T_alone_N: the
 * tendon's tension alone at its single-tendon home, the calibration's own
 * error before any straight-pose shift); one
 * `pose,tip_single_mm,tip_straight_mm,tip_true_mm,worst_err_N` line.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plant/pose.h"

static void usage(void)
{
    fprintf(stderr, "usage: hh_straight CONFIG -t mN --shift-um U0,U1,... [-s seed] [-p perturb]"
                    " [--homes H0,H1,... | --targets-cuT C0,C1,... --sensors K0,K1,...]"
                    " [--tol mN]\n");
}

/* Comma-separated numbers into v[]; returns how many, or -1. */
static int parse_list(const char *s, double v[], int max)
{
    int n = 0;
    while (*s != '\0') {
        char *end;
        if (n == max) {
            return -1;
        }
        v[n++] = strtod(s, &end);
        if (end == s) {
            return -1;
        }
        s = *end == ',' ? end + 1 : end;
        if (*end != ',' && *end != '\0') {
            return -1;
        }
    }
    return n;
}

int main(int argc, char **argv)
{
    plant_cfg_t cfg;
    plant_pose_result_t single_pose;
    plant_pose_result_t straight_pose;
    plant_pose_result_t true_pose;
    double shift[PLANT_MAX_TENDONS];
    double homes[PLANT_MAX_TENDONS];
    double used[PLANT_MAX_TENDONS];
    double truth[PLANT_MAX_TENDONS];
    double targets[PLANT_MAX_TENDONS];
    double sensors[PLANT_MAX_TENDONS];
    int n_targets = -1;
    int n_sensors = -1;
    double tol_mN = 50.0;
    double perturb = 0.0;
    double worst = 0.0;
    unsigned long seed = 1;
    int n_shift = -1;
    int n_homes = -1;
    int tension = 0;
    int line = 0;
    int a;
    uint8_t i;

    if (argc < 2) {
        usage();
        return 2;
    }
    for (a = 2; a < argc; a++) {
        const char *v = a + 1 < argc ? argv[a + 1] : NULL;
        if (v == NULL) {
            usage();
            return 2;
        }
        if (strcmp(argv[a], "-t") == 0) {
            tension = atoi(v);
        } else if (strcmp(argv[a], "-s") == 0) {
            seed = strtoul(v, NULL, 0);
        } else if (strcmp(argv[a], "-p") == 0) {
            perturb = strtod(v, NULL);
        } else if (strcmp(argv[a], "--tol") == 0) {
            tol_mN = strtod(v, NULL);
        } else if (strcmp(argv[a], "--shift-um") == 0) {
            n_shift = parse_list(v, shift, PLANT_MAX_TENDONS);
        } else if (strcmp(argv[a], "--targets-cuT") == 0) {
            n_targets = parse_list(v, targets, PLANT_MAX_TENDONS);
        } else if (strcmp(argv[a], "--sensors") == 0) {
            n_sensors = parse_list(v, sensors, PLANT_MAX_TENDONS);
        } else if (strcmp(argv[a], "--homes") == 0) {
            n_homes = parse_list(v, homes, PLANT_MAX_TENDONS);
        } else {
            usage();
            return 2;
        }
        a++;
    }
    if (plant_cfg_load(&cfg, argv[1], &line) != 0 || plant_cfg_check(&cfg) != 0) {
        fprintf(stderr, "hh_straight: %s: bad plant config (line %d)\n", argv[1], line);
        return 2;
    }
    if (tension <= 0 || tension > 60000 || n_shift != (int)cfg.n_tendons ||
        (n_homes >= 0 && n_homes != (int)cfg.n_tendons) ||
        (n_targets >= 0 && (n_targets != (int)cfg.n_tendons || n_sensors != n_targets)) ||
        plant_cfg_perturb(&cfg, (uint32_t)seed, perturb) != 0) {
        fprintf(stderr,
                "hh_straight: need -t mN > 0 and one shift (and home, or target and sensor) per "
                "tendon (%u)\n",
                cfg.n_tendons);
        return 2;
    }
    for (i = 0; i < cfg.n_tendons; i++) {
        if (n_targets >= 0) {
            if (sensors[i] < 0.0 || sensors[i] >= (double)cfg.n_sensors ||
                plant_field_home(&cfg, i, (uint8_t)sensors[i], targets[i], &homes[i]) != 0) {
                fprintf(stderr, "hh_straight: tendon %u: field target not reached\n", i);
                return 1;
            }
        } else if (n_homes < 0 && plant_true_home(&cfg, i, (uint16_t)tension, &homes[i]) != 0) {
            fprintf(stderr, "hh_straight: tendon %u: no single-tendon home\n", i);
            return 1;
        }
        used[i] = homes[i] -
                  (double)cfg.tendon[i].pull_dir * shift[i] / (plant_nm_per_tick(&cfg, i) * 1e-3);
    }
    if (plant_straight_homes(&cfg, (uint16_t)tension, truth) != 0) {
        fprintf(stderr, "hh_straight: the plant's straight-pose homes did not converge\n");
        return 1;
    }
    if (plant_pose_ramp(&cfg, homes, &single_pose) != 0 ||
        plant_pose_ramp(&cfg, used, &straight_pose) != 0 ||
        plant_pose_ramp(&cfg, truth, &true_pose) != 0) {
        return 1;
    }
    for (i = 0; i < cfg.n_tendons; i++) {
        plant_pose_result_t nudged;
        double moved[PLANT_MAX_TENDONS];
        double dir = (double)cfg.tendon[i].pull_dir;
        double err = straight_pose.tension_N[i] - tension * 1e-3;
        memcpy(moved, truth, sizeof moved);
        moved[i] += dir; /* one tick further in the pull direction */
        if (plant_pose_ramp(&cfg, moved, &nudged) != 0) {
            return 1;
        }
        if (fabs(err) > fabs(worst)) {
            worst = err;
        }
        printf("tendon,%u,%u,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f,%.1f,%.4f,%.4f,%.4f\n", i,
               cfg.tendon[i].segment, homes[i], used[i], truth[i], (used[i] - truth[i]) * dir,
               tol_mN * 1e-3 / (nudged.tension_N[i] - true_pose.tension_N[i]),
               (homes[i] - truth[i]) * dir * plant_nm_per_tick(&cfg, i) * 1e-3, shift[i],
               single_pose.tension_N[i], straight_pose.tension_N[i],
               plant_tension_at(&cfg, i, homes[i]));
    }
    printf("pose,%.4f,%.4f,%.4f,%.4f\n", single_pose.tip_dev_mm, straight_pose.tip_dev_mm,
           true_pose.tip_dev_mm, worst);
    return 0;
}
