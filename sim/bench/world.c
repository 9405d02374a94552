/*
 * world: the robot plant (sim/plant) behind the servo and sensor models.
 *
 * Once per simulated millisecond every XL430 model advances its profile, the
 * plant takes the servos' physical shaft angles as its motor angles, finds
 * its equilibrium when a motor moved, and each ICM-20948 model receives the
 * true field at its sensor (the model adds its own noise, 0.15 uT
 * quantization, saturation and data-ready timing). The servos' Present Load
 * follows the spool tension (an estimate, as on the real XL430).
 *
 * The start is a seeded random slack state: each tendon's shaft powers up
 * between the given slack margins before its true engagement.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <string.h>

#include "bench.h"

#define WORLD_TICK_US 1000u
/* XL430-W250-T stall torque at 12 V (e-manual): 1.5 N m; spool radius 4 mm. */
#define WORLD_STALL_NM 1.5
#define WORLD_SPOOL_M  0.004

static double world_rand01(uint64_t *s)
{
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

int world_init(bench_t *b)
{
    bench_bus_t *s = &b->bus;
    bench_twi_t *t = &b->twi;
    plant_cfg_t cfg;
    int line = 0;
    int rc;
    if (b->plant_path == NULL) {
        return 0;
    }
    rc = plant_cfg_load(&cfg, b->plant_path, &line);
    if (rc == 0) {
        rc = plant_cfg_check(&cfg);
    }
    if (rc != 0) {
        fprintf(stderr, "hh_bench: plant config %s: error %d at line %d\n", b->plant_path, rc,
                line);
        return -1;
    }
    if (plant_cfg_perturb_stiffness(&cfg, b->seed, b->perturb,
                                    b->perturb_stiffness < 0.0 ? b->perturb
                                                               : b->perturb_stiffness) != 0 ||
        plant_init(&b->plant, &cfg, b->seed) != 0) {
        fprintf(stderr, "hh_bench: plant config %s refused\n", b->plant_path);
        return -1;
    }
    b->have_plant = 1;
    if (b->have_straight != 0 && b->have_straight != cfg.n_tendons) {
        fprintf(stderr, "hh_bench: --straight-um has %u values for %u tendons\n", b->have_straight,
                cfg.n_tendons);
        return -1;
    }
    b->target_mN = b->tension_N > 0.0 ? (int32_t)lround(b->tension_N * 1000.0) : cfg.default_mN;
    uint64_t rng = 0x243F6A8885A308D3ull ^ ((uint64_t)b->seed * 0x9E3779B97F4A7C15ull);
    if (rng == 0) {
        rng = 1;
    }
    s->n_servos = cfg.n_tendons;
    for (uint8_t i = 0; i < cfg.n_tendons; i++) {
        xl430_config xc;
        double eng = 0.0;
        if (plant_true_engagement(&b->plant.cfg, i, &eng) != 0) {
            fprintf(stderr, "hh_bench: tendon %u has no engagement point\n", i);
            return -1;
        }
        double mm = b->start_slack_min_mm +
                    (b->start_slack_max_mm - b->start_slack_min_mm) * world_rand01(&rng);
        double slack_ticks = mm * 1e6 / cfg.nm_per_tick;
        b->eng_ticks[i] = eng;
        xl430_config_default(&xc, cfg.tendon[i].servo_id);
        xc.bits_per_byte = 11; /* simavr's frame */
        xc.baud_index = b->servo_baud_index;
        xc.shaft_ticks = eng - (double)cfg.tendon[i].pull_dir * slack_ticks;
        xl430_init(&s->servo[i], &xc, 0);
        xl430_set_sensed(&s->servo[i], 0, 120, 32);
        plant_set_motor(&b->plant, i, xc.shaft_ticks);
        b->moved_from[i] = xc.shaft_ticks;
    }
    plant_solve(&b->plant);
    t->n_icm = cfg.n_sensors;
    for (uint8_t k = 0; k < cfg.n_sensors; k++) {
        icmm_t *m = &t->icm[k];
        icmm_init(m, cfg.sensor[k].i2c_addr, b->seed + 101u * k);
        icmm_set_noise(m, (uint32_t)lround(cfg.noise_uT * 100.0), b->seed + 7u * k + 1u);
        if (tcam_attach(&t->mux, cfg.sensor[k].mux_channel, icmm_slave(m)) != 0) {
            fprintf(stderr, "hh_bench: sensor %u: mux channel %u refused\n", k,
                    cfg.sensor[k].mux_channel);
            return -1;
        }
    }
    b->next_world_us = 0;
    truth_init(b);
    world_tick(b, 0);
    return 0;
}

void world_tick(bench_t *b, uint64_t now)
{
    bench_bus_t *s = &b->bus;
    uint8_t moved = 0;
    if (!b->have_plant) {
        return;
    }
    for (uint8_t i = 0; i < s->n_servos; i++) {
        xl430_step(&s->servo[i], (uint32_t)now);
        double sh = xl430_shaft_ticks(&s->servo[i]);
        if (fabs(sh - b->moved_from[i]) >= 1.0) {
            b->moved_from[i] = sh;
            b->last_move_us[i] = now;
        }
        if (fabs(sh - plant_motor_ticks(&b->plant, i)) > 1e-3) {
            plant_set_motor(&b->plant, i, sh);
            moved = 1;
        }
    }
    if (moved) {
        plant_solve(&b->plant);
        for (uint8_t i = 0; i < s->n_servos; i++) {
            double take = (plant_motor_ticks(&b->plant, i) - b->eng_ticks[i]) *
                          (double)b->plant.cfg.tendon[i].pull_dir;
            if (b->plant.tension_N[i] > b->max_tension_N[i]) {
                b->max_tension_N[i] = b->plant.tension_N[i];
            }
            if (take > b->max_take_up_ticks[i]) {
                b->max_take_up_ticks[i] = take;
            }
        }
        for (uint8_t i = 0; i < s->n_servos; i++) {
            double load = b->plant.tension_N[i] * WORLD_SPOOL_M / WORLD_STALL_NM * 1000.0;
            xl430_set_sensed(&s->servo[i], (int16_t)lround(load > 1000.0 ? 1000.0 : load), 120, 32);
        }
    }
    if (b->fault_at_us != 0 && !b->fault_seen) {
        b->fault_seen = 1;
        for (uint8_t i = 0; i < s->n_servos; i++) {
            if (b->plant.tension_N[i] > b->fault_tension_N) {
                b->fault_tension_N = b->plant.tension_N[i];
            }
        }
    }
    if (b->fault_at_us != 0 && b->released_at_us == 0) {
        uint8_t slack = 1;
        for (uint8_t i = 0; i < s->n_servos; i++) {
            if (b->plant.tension_N[i] >= 0.001) {
                slack = 0;
            }
        }
        if (slack) {
            b->released_at_us = now;
        }
    }
    for (uint8_t k = 0; k < b->twi.n_icm; k++) {
        double f[3];
        plant_field_sensor(&b->plant, k, f);
        icmm_set_field_cuT(&b->twi.icm[k], (int32_t)lround(f[0] * 100.0),
                           (int32_t)lround(f[1] * 100.0), (int32_t)lround(f[2] * 100.0));
    }
    truth_tick(b, now);
    twi_bench_advance(b, now);
    b->next_world_us = now + WORLD_TICK_US;
}

void world_power_cycle(bench_t *b, uint64_t now)
{
    /* the homes were reported in the encoders' old frames: keep them in the
     * shaft's, which the power cycle does not change */
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        if ((b->truth.home_known >> i) & 1u) {
            b->truth.home_shaft[i] = world_home_shaft(b, i);
            b->truth.home_shaft_known |= (uint16_t)(1u << i);
        }
    }
    b->truth.home_known = 0;
    bus_power_cycle(b, now);
    twi_bench_power_cycle(b);
}

/* The plant's true tension (mN) of tendon i pulled alone to its
 * single-tendon home (the calibration's definition, what it is judged by). */
static double true_tension_mN(const bench_t *b, uint8_t i)
{
    return plant_tension_at(&b->plant.cfg, i, world_home_shaft(b, i)) * 1000.0;
}

static int within_tol(const bench_t *b, double t_mN, double tol_pct)
{
    return fabs(t_mN - (double)b->target_mN) <= tol_pct * 0.01 * (double)b->target_mN;
}

int world_check_tension(bench_t *b, double tol_pct, char *reason, size_t n)
{
    char list[64] = "";
    size_t len = 0;
    int failed = 0;
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        if (within_tol(b, true_tension_mN(b, i), tol_pct)) {
            continue;
        }
        if (len < sizeof list) {
            len += (size_t)snprintf(list + len, sizeof list - len, "%s%u", failed ? ", " : "", i);
        }
        failed++;
    }
    if (failed > 0) {
        snprintf(reason, n, "true tension outside %g %% of the %d mN target at the home of %s %s",
                 tol_pct, (int)b->target_mN, failed > 1 ? "tendons" : "tendon", list);
    }
    return failed;
}

double world_home_shaft(const bench_t *b, uint8_t i)
{
    const xl430 *m = &b->bus.servo[i];
    int32_t home;
    if (!((b->truth.home_known >> i) & 1u) && ((b->truth.home_shaft_known >> i) & 1u)) {
        return b->truth.home_shaft[i]; /* reported before a power cycle */
    }
    home = (b->truth.home_known >> i) & 1u ? b->truth.home_ticks[i]
                                           : (int32_t)xl430_get(m, DXL_XL430_GOAL_POSITION_ADDR, 4);
    /* the shaft plus the way from the encoder's position to the home (the
     * encoder's frame differs from the shaft's after a power cycle) */
    return xl430_shaft_ticks(m) + (double)(home - xl430_present_position(m));
}

/* Per tendon: the firmware's single-tendon home (encoder frame), its
 * take-up past the true engagement, the plant's truth there and, with a
 * tolerance (tol_pct >= 0), whether its true tension is within it. */
void world_report(bench_t *b, FILE *json, FILE *table, double tol_pct)
{
    const plant_cfg_t *cfg = &b->plant.cfg;
    bench_pose_t now;
    bench_pose_t straight;
    int have_straight;
    if (!b->have_plant) {
        if (json) {
            fprintf(json, "  \"tendons\": []");
        }
        return;
    }
    have_straight = poses_report(b, &now, &straight) == 1;
    if (table) {
        fprintf(table,
                "\ntendon  id  home_ticks  home_mm  true_home  err_ticks  T_home_mN  target_mN  "
                "err_mN   err_%%  T_final_mN  T_straight_mN  result\n");
    }
    if (json) {
        fprintf(json,
                "  \"fault\": {\"t_s\": %.6f, \"max_tension_mN\": %.1f, "
                "\"released_after_ms\": %.3f},\n",
                (double)b->fault_at_us * 1e-6, b->fault_tension_N * 1000.0,
                b->fault_at_us && b->released_at_us >= b->fault_at_us
                    ? (double)(b->released_at_us - b->fault_at_us) * 1e-3
                    : -1.0);
        fprintf(json,
                "  \"final_pose\": {\"tip_dev_mm\": %.4f},\n"
                "  \"straight_pose\": {\"computed\": %s, \"tip_dev_mm\": %.4f},\n",
                now.tip_dev_mm, have_straight ? "true" : "false",
                have_straight ? straight.tip_dev_mm : -1.0);
        fprintf(json, "  \"target_mN\": %d,\n  \"tendons\": [", (int)b->target_mN);
    }
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        const xl430 *m = &b->bus.servo[i];
        double shaft = world_home_shaft(b, i); /* the single-tendon home */
        double eng = 0.0, home = NAN;
        (void)plant_true_engagement(cfg, i, &eng);
        (void)plant_true_home(cfg, i, (uint16_t)b->target_mN, &home);
        double t_home = true_tension_mN(b, i);
        /* the take-up past the true engagement at the home (the table) and
         * where the shaft stands now (the summary: slack after a release) */
        double mm_tick = (double)cfg->tendon[i].pull_dir * cfg->nm_per_tick / 1e6;
        double take_mm = (shaft - eng) * mm_tick;
        double take_now_mm = (xl430_shaft_ticks(m) - eng) * mm_tick;
        int32_t goal = (int32_t)xl430_get(m, DXL_XL430_GOAL_POSITION_ADDR, 4);
        int32_t present = xl430_present_position(m);
        int32_t home_enc = (int32_t)lround(shaft - xl430_shaft_ticks(m)) + present;
        double err_mN = t_home - (double)b->target_mN;
        if (table) {
            char st[16] = "-";
            if (have_straight) {
                snprintf(st, sizeof st, "%.1f", straight.tension_N[i] * 1000.0);
            }
            fprintf(table,
                    "%6u %3u %11d %8.3f %10.1f %10.1f %10.1f %10d %8.1f %7.1f %11.1f %14s  %6s\n",
                    i, m->cfg.id, (int)home_enc, take_mm, home, shaft - home, t_home,
                    (int)b->target_mN, err_mN, 100.0 * err_mN / (double)b->target_mN,
                    now.tension_N[i] * 1000.0, st,
                    tol_pct < 0.0 ? "-" : (within_tol(b, t_home, tol_pct) ? "pass" : "FAIL"));
        }
        if (json) {
            fprintf(
                json,
                "%s\n    {\"tendon\": %u, \"id\": %u, \"pull_dir\": %d, \"goal_ticks\": %d, "
                "\"present_ticks\": %d, "
                "\"home_ticks\": %d, \"home_reported\": %s, \"home_shaft_ticks\": %.2f, "
                "\"torque\": %u, \"hw_error\": %u, \"shaft_ticks\": %.2f, \"take_up_mm\": %.4f, "
                "\"true_engagement_ticks\": %.2f, \"true_home_ticks\": %.2f, \"err_ticks\": %.2f, "
                "\"tension_at_home_mN\": %.1f, \"tension_now_mN\": %.1f, \"err_mN\": %.1f, "
                "\"max_tension_mN\": %.1f, \"max_take_up_mm\": %.4f, \"last_move_s\": %.6f, "
                "\"tension_straight_mN\": %.1f}",
                i ? "," : "", i, m->cfg.id, (int)cfg->tendon[i].pull_dir, (int)goal, (int)present,
                (int)home_enc,
                ((b->truth.home_known | b->truth.home_shaft_known) >> i) & 1u ? "true" : "false",
                shaft, (unsigned)xl430_get(m, DXL_XL430_TORQUE_ENABLE_ADDR, 1),
                (unsigned)xl430_get(m, DXL_XL430_HW_ERROR_ADDR, 1), xl430_shaft_ticks(m),
                take_now_mm, eng, isnan(home) ? -1.0 : home, isnan(home) ? 0.0 : shaft - home,
                t_home, b->plant.tension_N[i] * 1000.0, err_mN, b->max_tension_N[i] * 1000.0,
                b->max_take_up_ticks[i] * cfg->nm_per_tick / 1e6, (double)b->last_move_us[i] * 1e-6,
                have_straight ? straight.tension_N[i] * 1000.0 : -1.0);
        }
    }
    if (json) {
        fprintf(json, "\n  ]");
    }
    if (table) {
        fprintf(table,
                "T_home: the tendon alone at its single-tendon home (others slack), the "
                "calibration's definition; result judges it\n"
                "T_final: the plant now, every tendon where the final move took it (home_pose 1: "
                "its straight-pose home; 0: its single-tendon home), tip %.3f mm from straight\n",
                now.tip_dev_mm);
        if (have_straight) {
            fprintf(table,
                    "T_straight: every tendon at its single-tendon home minus the host's "
                    "straight-pose shift together (computed on the plant from these homes, tip "
                    "%.3f mm from straight)\n",
                    straight.tip_dev_mm);
        } else {
            fprintf(table, "T_straight: - (no straight-pose shifts given: --straight-um)\n");
        }
    }
}
