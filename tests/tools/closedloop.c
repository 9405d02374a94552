/*
 * hh_closedloop: runs calibrations of the homing state machine against the
 * plant model and prints per-tendon results and machine-readable CSV lines.
 *
 *   hh_closedloop CONFIG [-t mN] [-s seed] [-p perturb] [-n runs]
 *                 [-m full|quick|single|dry] [-i tendon] [-f fault:index:ms]
 *                 [-g generated_table] [-a delta|abs] [--ambient-shift uT[,uT,uT]] [-q]
 *
 * -f injects a fault (plant_fault_t number, see sim/plant/closedloop.h) into
 * every run; the summary then reports the slowest release to slack.
 * The table comes from the nominal plant (plant_make_table), or with
 * -g paper_2seg from the generated table linked into the program
 * (lookup_tables/generated: the host's Cosserat model against this plant,
 * model error included); each run
 * uses the
 * plant perturbed with seed+run and `perturb` (0 = nominal), so model error is
 * real when perturb > 0. Quick mode first runs a full calibration, then power
 * cycles (the encoder loses whole turns) with the robot left at its homes and
 * re-homes from the stored homes.
 *
 * -a abs runs the absolute target mode (docs/homing.md): each run is preceded by
 * a capture run (same robot, ambient unchanged) that stores the ambient offsets,
 * then the measured run reuses them. --ambient-shift adds a field (world frame;
 * one number: along x) to every sensor's ambient for the measured run, after the
 * capture. The summary line then ends with target_mode=...,ambient_shift_uT=...
 * (fields appended; without these options the output is unchanged).
 *
 * CSV lines: `home,run,tendon,home_ticks,true_home_ticks,err_ticks,tension_N,
 * tension_err_N,sim_ms,fault`; without -q also `event,run,t_ms,type,code,index,
 * a,b` (homing.h documents the fields); one `summary,key=value,...` line.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "plant/closedloop.h"

/* The default robot's generated table (linked through hh_lib). */
extern const tbl_table_t tbl_table_paper_2seg;

static const tbl_table_t *generated(const char *name)
{
    if (strcmp(name, "paper_2seg") == 0) {
        return &tbl_table_paper_2seg;
    }
    return NULL;
}

static void usage(void)
{
    fprintf(stderr,
            "usage: hh_closedloop CONFIG [-t mN] [-s seed] [-p perturb] [-n runs]\n"
            "                     [-m full|quick|single|dry] [-i tendon] [-f fault:index:ms]"
            " [-g table] [-a delta|abs] [--ambient-shift uT[,uT,uT]] [-q]\n");
}

static const char *event_name(uint8_t type)
{
    static const char *const names[] = {"?",    "start",  "phase", "missing", "engaged",
                                        "home", "target", "done",  "fault",   "released"};
    return type < sizeof names / sizeof names[0] ? names[type] : "?";
}

static int parse_mode(const char *s, hom_mode_t *m)
{
    if (strcmp(s, "full") == 0) {
        *m = HOM_MODE_FULL;
    } else if (strcmp(s, "quick") == 0) {
        *m = HOM_MODE_QUICK;
    } else if (strcmp(s, "single") == 0) {
        *m = HOM_MODE_SINGLE;
    } else if (strcmp(s, "dry") == 0) {
        *m = HOM_MODE_DRY;
    } else {
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    static plant_cfg_t nominal;
    static plant_cfg_t actual;
    static tbl_wide_t table; /* natural units */
    static tbl_buf_t packed; /* the same as the homing reads it */
    static plant_run_result_t res;
    static plant_run_result_t first;
    plant_run_cfg_t rc;
    const char *path;
    unsigned tension = 0;
    unsigned seed = 1;
    double perturb = 0.0;
    unsigned runs = 1;
    unsigned tendon = 0;
    int quiet = 0;
    hom_mode_t mode = HOM_MODE_FULL;
    unsigned fault = 0;
    unsigned fault_index = 0;
    unsigned fault_ms = 0;
    unsigned max_release_ms = 0;
    const char *gen = NULL;
    int err_line = 0;
    int a;
    unsigned r;
    double sum_e = 0.0;
    double sum_e2 = 0.0;
    double max_abs_ticks = 0.0;
    double sum_ms = 0.0;
    double home_sum[TBL_MAX_TENDONS] = {0};
    double home_sum2[TBL_MAX_TENDONS] = {0};
    unsigned n_home[TBL_MAX_TENDONS] = {0};
    unsigned n_tension = 0;
    unsigned faults = 0;
    clock_t c0;
    double wall;
    int abs_mode = 0;
    int new_opts = 0;
    double shift[3] = {0.0, 0.0, 0.0};
    static int32_t amb[HOM_MAX_SENSORS][3];

    if (argc < 2) {
        usage();
        return 2;
    }
    path = argv[1];
    for (a = 2; a < argc; a++) {
        const char *v = a + 1 < argc ? argv[a + 1] : NULL;
        if (strcmp(argv[a], "-q") == 0) {
            quiet = 1;
            continue;
        }
        if (v == NULL) {
            usage();
            return 2;
        }
        if (strcmp(argv[a], "-t") == 0) {
            tension = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-s") == 0) {
            seed = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-p") == 0) {
            perturb = strtod(v, NULL);
        } else if (strcmp(argv[a], "-n") == 0) {
            runs = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-i") == 0) {
            tendon = (unsigned)strtoul(v, NULL, 10);
        } else if (strcmp(argv[a], "-g") == 0) {
            gen = v;
        } else if (strcmp(argv[a], "-a") == 0) {
            if (strcmp(v, "abs") != 0 && strcmp(v, "delta") != 0) {
                usage();
                return 2;
            }
            abs_mode = strcmp(v, "abs") == 0;
            new_opts = 1;
        } else if (strcmp(argv[a], "--ambient-shift") == 0) {
            if (sscanf(v, "%lf,%lf,%lf", &shift[0], &shift[1], &shift[2]) < 1) {
                usage();
                return 2;
            }
            new_opts = 1;
        } else if (strcmp(argv[a], "-f") == 0) {
            if (sscanf(v, "%u:%u:%u", &fault, &fault_index, &fault_ms) != 3) {
                usage();
                return 2;
            }
        } else if (strcmp(argv[a], "-m") == 0) {
            if (parse_mode(v, &mode) != 0) {
                usage();
                return 2;
            }
        } else {
            usage();
            return 2;
        }
        a++;
    }
    if (plant_cfg_load(&nominal, path, &err_line) != 0 || plant_cfg_check(&nominal) != 0) {
        fprintf(stderr, "hh_closedloop: %s: bad config (line %d)\n", path, err_line);
        return 1;
    }
    if (gen != NULL) {
        const tbl_table_t *g = generated(gen);
        if (g == NULL) {
            fprintf(stderr, "hh_closedloop: generated table %s not linked\n", gen);
            return 1;
        }
        tbl_src_t gs;
        gs.table = g;
        gs.copy = tbl_copy_ram;
        if (tbl_unpack(&gs, &table) != 0) {
            fprintf(stderr, "hh_closedloop: generated table %s fails its check\n", gen);
            return 1;
        }
    } else if (plant_make_table(&nominal, &table) != 0) {
        fprintf(stderr, "hh_closedloop: cannot build the table from %s\n", path);
        return 1;
    }
    if (tension == 0u) {
        tension = table.default_mN;
    }
    if (tbl_pack(&table, &packed) != 0) {
        fprintf(stderr, "hh_closedloop: the table does not fit the stored format\n");
        return 1;
    }
    c0 = clock();
    for (r = 0; r < runs; r++) {
        unsigned i;
        actual = nominal;
        (void)plant_cfg_perturb(&actual, seed + r, perturb);
        plant_run_defaults(&rc, &actual, tbl_buf_table(&packed));
        rc.seed = seed * 7919u + r;
        rc.cmd.mode = mode == HOM_MODE_QUICK ? HOM_MODE_FULL : mode;
        rc.cmd.tension_mN = (uint16_t)tension;
        rc.cmd.tendon = (uint8_t)tendon;
        rc.fault = (plant_fault_t)fault;
        rc.fault_index = (uint8_t)fault_index;
        rc.fault_ms = fault_ms;
        if (abs_mode) {
            /* the capture run: the ambient as it was when the offsets were taken */
            plant_run_cfg_t cap = rc;
            cap.cmd.mode = HOM_MODE_FULL;
            cap.cmd.ambient_cuT = amb;
            cap.cmd.ambient_capture = 1;
            cap.fault = PLANT_FI_NONE;
            cap.seed += 500009u;
            if (plant_run(&cap, &res) != 0 || res.rc != 0) {
                fprintf(stderr, "hh_closedloop: ambient capture run %u failed (rc %d)\n", r,
                        res.rc);
                return 1;
            }
            rc.cmd.ambient_cuT = amb;
        }
        memcpy(rc.ambient_shift_uT, shift, sizeof shift);
        if (plant_run(&rc, &res) != 0) {
            fprintf(stderr, "hh_closedloop: run %u did not finish (rc %d)\n", r, res.rc);
            return 1;
        }
        if (mode == HOM_MODE_QUICK && res.rc == 0) {
            static double start[TBL_MAX_TENDONS];
            first = res;
            rc.cmd.mode = HOM_MODE_QUICK;
            rc.cmd.stored_mask = 0;
            for (i = 0; i < first.n_tendons; i++) {
                rc.cmd.stored_home[i] = first.home[i];
                rc.cmd.stored_mask |= (uint16_t)(1u << i);
                start[i] = first.home_plant[i];
            }
            rc.start_ticks = start;
            rc.frame_offset = 4096 * (int32_t)(1 + r % 3);
            rc.seed += 1000003u;
            if (plant_run(&rc, &res) != 0) {
                fprintf(stderr, "hh_closedloop: quick run %u did not finish\n", r);
                return 1;
            }
        }
        if (res.rc != 0) {
            int sent = 0;
            unsigned e;
            for (e = 0; e < res.n_events; e++) {
                sent |= res.events[e].type == HOM_EV_RELEASED;
            }
            faults++;
            /* a fault before any motion (preflight) commands nothing */
            if (sent && (res.release_ms > max_release_ms || !res.released)) {
                max_release_ms = res.released ? res.release_ms : 9999u;
            }
        }
        sum_ms += res.end_ms;
        if (!quiet) {
            printf("run %u: %s in %u ms simulated\n", r,
                   res.rc == 0 ? "done" : hom_fault_name(res.fault), (unsigned)res.end_ms);
            printf("  tendon  home   true_home  err_ticks  tension_N  final_N\n");
        }
        for (i = 0; i < res.n_tendons; i++) {
            double te;
            if (!res.have_home[i]) {
                continue;
            }
            te = res.tension_at_home_N[i] - tension * 1e-3;
            if (!quiet) {
                printf("  %6u %6ld %10.2f %10.2f %10.4f %8.3f\n", i, (long)res.home[i],
                       res.true_home[i], res.err_ticks[i], res.tension_at_home_N[i],
                       res.final_tension_N[i]);
            }
            printf("home,%u,%u,%.0f,%.3f,%.3f,%.4f,%.4f,%u,%s\n", r, i, res.home_plant[i],
                   res.true_home[i], res.err_ticks[i], res.tension_at_home_N[i], te,
                   (unsigned)res.end_ms, hom_fault_name(res.fault));
            if (fabs(res.err_ticks[i]) > max_abs_ticks) {
                max_abs_ticks = fabs(res.err_ticks[i]);
            }
            sum_e += te;
            sum_e2 += te * te;
            n_tension++;
            home_sum[i] += res.err_ticks[i];
            home_sum2[i] += res.err_ticks[i] * res.err_ticks[i];
            n_home[i]++;
        }
        if (!quiet) {
            unsigned e;
            for (e = 0; e < res.n_events; e++) {
                const hom_event_t *ev = &res.events[e];
                printf("event,%u,%lu,%s,%u,%u,%ld,%ld\n", r, (unsigned long)ev->t_ms,
                       event_name(ev->type), ev->code, ev->index, (long)ev->a, (long)ev->b);
            }
        }
    }
    wall = (double)(clock() - c0) / CLOCKS_PER_SEC;
    {
        double mean = n_tension ? sum_e / n_tension : 0.0;
        double var = n_tension > 1 ? (sum_e2 - n_tension * mean * mean) / (n_tension - 1) : 0.0;
        double sd = var > 0.0 ? sqrt(var) : 0.0;
        double sd_ticks = 0.0;
        unsigned i;
        unsigned n_sd = 0;
        for (i = 0; i < TBL_MAX_TENDONS; i++) {
            if (n_home[i] > 1u) {
                double m = home_sum[i] / n_home[i];
                double v = (home_sum2[i] - n_home[i] * m * m) / (n_home[i] - 1u);
                sd_ticks += sqrt(v > 0.0 ? v : 0.0);
                n_sd++;
            }
        }
        sd_ticks = n_sd ? sd_ticks / n_sd : 0.0;
        printf("summary,runs=%u,faults=%u,tension_mN=%u,perturb=%.3f,max_abs_err_ticks=%.3f,"
               "mean_home_sd_ticks=%.3f,mean_home_sd_um=%.4f,tension_err_mean_N=%.4f,"
               "tension_err_sd_N=%.4f,mean_sim_ms=%.0f,wall_s=%.3f,runs_per_min=%.0f,"
               "max_release_ms=%u",
               runs, faults, tension, perturb, max_abs_ticks, sd_ticks,
               sd_ticks * nominal.nm_per_tick * 1e-3, mean, sd, runs ? sum_ms / runs : 0.0, wall,
               wall > 0.0 ? runs * 60.0 / wall : 0.0, max_release_ms);
        if (new_opts) {
            printf(",target_mode=%s,ambient_shift_uT=%.3f:%.3f:%.3f", abs_mode ? "abs" : "delta",
                   shift[0], shift[1], shift[2]);
        }
        printf("\n");
    }
    return (faults == 0u || fault != 0u) ? 0 : 3;
}
