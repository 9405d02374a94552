/*
 * closedloop: homing state machine + plant + simple servos (closedloop.h).
 */
#include "plant/closedloop.h"

#include "icm20948/icm_clock.h"
#include "homing/hom_priv.h" /* the state, to measure where fine points are taken */
#include "simrand.h"

#include <math.h>
#include <string.h>

void plant_run_defaults(plant_run_cfg_t *rc, const plant_cfg_t *plant, const tbl_table_t *table)
{
    memset(rc, 0, sizeof *rc);
    rc->plant = plant;
    rc->table = table;
    rc->cmd.mode = HOM_MODE_FULL;
    rc->start_min_um = -2000.0;
    rc->start_max_um = 300.0;
}

/* A uniform draw in [0, 1) from a linear congruence (the scan that found
 * the bounded pull's cases drew its steps so). */
static double scan_draw(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return (double)(*s >> 8) / 16777216.0;
}

void plant_run_scan(plant_run_cfg_t *rc, uint32_t s0, unsigned run, uint8_t n_sensors,
                    uint8_t n_tendons, int step)
{
    uint32_t rs = s0 * 7919u + run * 104729u + 1u;
    uint8_t a;
    rc->seed = s0 + 500u + run;
    rc->pos_period_ms = (uint8_t)(6u + run % 13u);
    rc->goal_lag_ms = (uint8_t)(2u + run % 11u);
    rc->sample_lag_ms = (uint8_t)(run % 13u);
    if (!step) {
        return;
    }
    rc->fault = PLANT_FI_FIELD_JUMP;
    rc->fault_index = (uint8_t)(scan_draw(&rs) * n_sensors);
    rc->fault_ms = (uint32_t)(300.0 + scan_draw(&rs) * 1300.0 * n_tendons);
    for (a = 0; a < 3u; a++) {
        rc->jump_uT[a] = round((scan_draw(&rs) * 60.0 - 30.0) * 10.0) / 10.0;
    }
    if (rc->jump_uT[0] == 0.0) {
        rc->jump_uT[0] = 0.1; /* all zero would be the plant's 3 mT default */
    }
}

static void fill_ground_truth(const plant_run_cfg_t *rc, const plant_t *p, const hom_t *h,
                              plant_run_result_t *res)
{
    uint8_t i;
    uint16_t tension = h->tension_mN;
    for (i = 0; i < res->n_tendons; i++) {
        res->final_tension_N[i] = p->tension_N[i];
        res->limit_ticks[i] = h->tendon[i].limit_ticks;
        if (plant_true_home(rc->plant, i, tension, &res->true_home[i]) != 0) {
            res->true_home[i] = NAN;
        }
        if (h->tendon[i].have_home == 1u) {
            res->have_home[i] = 1;
            res->home[i] = h->tendon[i].home;
            res->home_plant[i] = (double)h->tendon[i].home + (double)rc->frame_offset;
            res->err_ticks[i] = res->home_plant[i] - res->true_home[i];
            res->tension_at_home_N[i] = plant_tension_at(rc->plant, i, res->home_plant[i]);
        }
    }
    memcpy(res->tip_mm, p->tip.pos_mm, sizeof res->tip_mm);
}

#define CL_MAX_LAG 32u

int plant_run(const plant_run_cfg_t *rc, plant_run_result_t *res)
{
    plant_t plant;
    plant_cfg_t pcfg;
    plant_servo_t servo[TBL_MAX_TENDONS];
    double last_motor[TBL_MAX_TENDONS];
    hom_t h;
    hom_in_t in;
    hom_out_t out;
    hom_out_t line[CL_MAX_LAG]; /* goal writes on their way to the servos */
    /* samples on their way to the homing: a sensor samples every 10 ms and a
     * lag is below 20 ms, so two at most per sensor */
    hom_sensor_in_t held[HOM_MAX_SENSORS][2];
    uint32_t held_at[HOM_MAX_SENSORS][2] = {{0}};
    /* the firmware's sensor path (rc->mst_us): the samples measured, the
     * master's copy and the host's reads */
    hom_sensor_in_t ring[HOM_MAX_SENSORS][4];
    uint32_t ring_ms[HOM_MAX_SENSORS][4];
    uint32_t n_meas[HOM_MAX_SENSORS] = {0};
    uint32_t reg[HOM_MAX_SENSORS] = {0};  /* samples up to the one in the master's copy */
    uint32_t seen[HOM_MAX_SENSORS] = {0}; /* samples up to the last one read */
    uint64_t next_copy_us[HOM_MAX_SENSORS];
    uint64_t read_due_us[HOM_MAX_SENSORS];
    uint64_t read_at_us[HOM_MAX_SENSORS];
    icm_clock_t clk[HOM_MAX_SENSORS];
    uint32_t read_us = rc != NULL && rc->read_us != 0u ? rc->read_us : 5000u;
    const hom_out_t *o = &out;
    uint32_t lag = rc->goal_lag_ms < CL_MAX_LAG ? rc->goal_lag_ms : CL_MAX_LAG - 1u;
    tbl_src_t src;
    uint64_t rng;
    uint32_t t;
    uint32_t t_fault = 0;
    uint32_t max_ms;
    uint8_t i;
    uint8_t k;
    int ended = 0;
    int step_rc = HOM_RUNNING;
    int32_t engage[TBL_MAX_TENDONS];
    double b_start[3] = {0.0, 0.0, 0.0};
    double b_stuck[3] = {0.0, 0.0, 0.0};
    uint8_t fall_set = 0;
    uint8_t pulling = 0; /* a tendon's pull has begun */
    uint16_t win;
    uint8_t engaged[TBL_MAX_TENDONS];
    int8_t pull_dir[TBL_MAX_TENDONS];
    double far[TBL_MAX_TENDONS]; /* furthest motor position (pull sense) since last slack */
    double avg_behind = 0.0;     /* the current tendon's motor behind it, the step before */
    uint8_t avg_state = 0;       /* the homing's state the step before, */
    int32_t pt_p = 0;            /*   and its last fine point */
    uint32_t pt_b = 0;
    tbl_info_t info;

    src.table = rc != NULL ? rc->table : NULL;
    src.copy = tbl_copy_ram;
    if (rc == NULL || res == NULL || rc->plant == NULL || tbl_info(&src, &info) != 0 ||
        rc->plant->n_tendons != info.n_tendons || rc->plant->n_sensors != info.n_sensors ||
        info.n_tendons > TBL_MAX_TENDONS) {
        return PLANT_E_ARG;
    }
    for (i = 0; i < info.n_tendons; i++) {
        tbl_tendon_t row;
        (void)tbl_tendon(&src, i, &row);
        pull_dir[i] = row.pull_dir;
    }
    memset(res, 0, sizeof *res);
    res->n_tendons = rc->plant->n_tendons;
    pcfg = *rc->plant;
    if (rc->fault == PLANT_FI_MAGNET_MISSING) {
        pcfg.magnet_moment_Am2 = 0.0;
    }
    for (k = 0; k < pcfg.n_sensors; k++) {
        int ax;
        for (ax = 0; ax < 3; ax++) {
            pcfg.sensor[k].ambient_uT[ax] += rc->ambient_shift_uT[ax];
        }
    }
    if (plant_init(&plant, &pcfg, rc->seed) != 0) {
        return PLANT_E_ARG;
    }
    rng = 0xABCDEF01ull ^ ((uint64_t)rc->seed << 24);
    for (i = 0; i < res->n_tendons; i++) {
        double start;
        if (rc->start_ticks != NULL) {
            start = rc->start_ticks[i];
        } else {
            double eng;
            double um =
                rc->start_min_um + (rc->start_max_um - rc->start_min_um) * simrand_unit(&rng);
            if (plant_true_engagement(rc->plant, i, &eng) != 0) {
                return PLANT_E_ARG;
            }
            start = eng + (double)rc->plant->tendon[i].pull_dir * um /
                              (plant_nm_per_tick(rc->plant, i) * 1e-3);
            start = floor(start + 0.5);
        }
        plant_servo_init(&servo[i], start, pcfg.servo_tau_ms);
        (void)plant_set_motor(&plant, i, start);
        last_motor[i] = start;
        engaged[i] = 0;
        far[i] = -1e18;
        engage[i] = 0;
    }
    (void)plant_solve(&plant);
    if ((rc->fault == PLANT_FI_FIELD_FALL || rc->fault == PLANT_FI_FIELD_STUCK) &&
        rc->fault_index < pcfg.n_sensors) {
        plant_field_true(&plant, rc->fault_index, b_start);
    }

    hom_init(&h, rc->hom);
    step_rc = hom_start(&h, &src, &rc->cmd);
    if (step_rc != 0) {
        res->rc = step_rc;
        return PLANT_E_RANGE;
    }
    memset(&in, 0, sizeof in);
    max_ms = rc->max_ms != 0u ? rc->max_ms : 60000u;
    for (k = 0; k < HOM_MAX_SENSORS; k++) {
        /* the master's and the reads' phases: drawn per run */
        next_copy_us[k] = 1000u + simrand_next(&rng) % (rc->mst_us != 0u ? rc->mst_us : 1u);
        read_due_us[k] = 1000u + simrand_next(&rng) % read_us;
        read_at_us[k] = read_due_us[k];
        icm_clock_reset(&clk[k]);
    }

    for (t = 1; t <= max_ms; t++) {
        int moved = 0;
        int faulting = rc->fault != PLANT_FI_NONE && t >= rc->fault_ms;
        hom_event_t ev;

        for (i = 0; i < res->n_tendons; i++) {
            plant_servo_step(&servo[i], 1.0);
            if (servo[i].pos != last_motor[i]) {
                (void)plant_set_motor(&plant, i, servo[i].pos);
                last_motor[i] = servo[i].pos;
                moved = 1;
            }
        }
        if (faulting && (rc->fault == PLANT_FI_SATURATE || rc->fault == PLANT_FI_FIELD_JUMP)) {
            if (rc->fault == PLANT_FI_SATURATE) {
                plant.extra_uT[rc->fault_index][2] = 6000.0;
            } else if (rc->jump_uT[0] == 0.0 && rc->jump_uT[1] == 0.0 && rc->jump_uT[2] == 0.0) {
                plant.extra_uT[rc->fault_index][0] = 3000.0;
            } else {
                memcpy(plant.extra_uT[rc->fault_index], rc->jump_uT, sizeof rc->jump_uT);
            }
        }
        if (faulting && (rc->fault == PLANT_FI_FIELD_FALL || rc->fault == PLANT_FI_FIELD_STUCK) &&
            rc->fault_index < pcfg.n_sensors) {
            double b_now[3], d2 = 0.0;
            double *x = plant.extra_uT[rc->fault_index];
            int ax;
            if (moved) {
                (void)plant_solve(&plant);
            }
            plant_field_true(&plant, rc->fault_index, b_now);
            for (ax = 0; ax < 3; ax++) {
                b_now[ax] -= x[ax]; /* the robot's own field */
                d2 += (b_now[ax] - b_start[ax]) * (b_now[ax] - b_start[ax]);
            }
            if (!fall_set && d2 >= rc->fall_at_uT * rc->fall_at_uT) {
                fall_set = 1;
                for (ax = 0; ax < 3; ax++) {
                    b_stuck[ax] = b_now[ax];
                    x[ax] = -0.5 * (b_now[ax] - b_start[ax]);
                }
            }
            for (ax = 0; fall_set && rc->fault == PLANT_FI_FIELD_STUCK && ax < 3; ax++) {
                x[ax] = b_stuck[ax] - b_now[ax]; /* it reads the field it stuck at */
            }
        }
        if (faulting && rc->fault == PLANT_FI_MAGNET_REMOVED &&
            plant.cfg.magnet_moment_Am2 != 0.0) {
            plant.cfg.magnet_moment_Am2 = 0.0;
            moved = 1;
        }
        if (moved) {
            (void)plant_solve(&plant);
        }
        in.now_ms = rc->clock0_ms + t;
        for (k = 0; k < HOM_MAX_SENSORS; k++) {
            hom_sensor_in_t *s = &in.sensor[k];
            s->status = HOM_SENS_NONE;
            if (k >= plant.cfg.n_sensors || (t + 3u * k) % 10u != 0u) {
                continue;
            }
            if (rc->fault_index == k && ((rc->fault == PLANT_FI_SENSOR_SILENT && faulting) ||
                                         rc->fault == PLANT_FI_SENSOR_ABSENT)) {
                s->status = rc->fault == PLANT_FI_SENSOR_ABSENT ? HOM_SENS_ABSENT : HOM_SENS_NONE;
                continue;
            }
            if (rc->fault == PLANT_FI_SENSOR_ERROR && faulting && rc->fault_index == k) {
                s->status = HOM_SENS_ERROR;
                continue;
            }
            s->status =
                plant_read_sensor(&plant, k, s->b_cuT) == 1 ? HOM_SENS_OVERFLOW : HOM_SENS_NEW;
            s->age_q = (uint8_t)(rc->age_mode == 2u ? 0u : 4u * rc->sample_lag_ms);
            if (rc->mst_us != 0u) {
                /* measured now: the master copies it, a read finds it */
                ring[k][n_meas[k] % 4u] = *s;
                ring_ms[k][n_meas[k] % 4u] = t;
                n_meas[k]++;
                s->status = HOM_SENS_NONE;
            } else if (rc->sample_lag_ms != 0u) {
                /* read now, handed over sample_lag_ms later, in the slot
                 * whose sample has been handed over already */
                unsigned q = held_at[k][0] >= t ? 1u : 0u;
                held[k][q] = *s;
                held_at[k][q] = t + (rc->sample_lag_ms < 20u ? rc->sample_lag_ms : 19u);
                s->status = HOM_SENS_NONE;
            }
        }
        for (k = 0; k < HOM_MAX_SENSORS && rc->mst_us != 0u; k++) {
            uint64_t now_us = (uint64_t)t * 1000u;
            while (next_copy_us[k] <= now_us) {
                /* the latest sample measured by then (at most 3 ms back:
                 * this step's measurement, if any, is at now_us) */
                uint32_t m = n_meas[k];
                while (m > reg[k] &&
                       (uint64_t)ring_ms[k][(m - 1u) % 4u] * 1000u > next_copy_us[k]) {
                    m--;
                }
                reg[k] = m;
                next_copy_us[k] += rc->mst_us;
            }
            if (read_at_us[k] <= now_us) {
                if (reg[k] > seen[k]) {
                    uint32_t idx = (reg[k] - 1u) % 4u;
                    uint32_t meas_us = ring_ms[k][idx] * 1000u;
                    uint32_t est = icm_clock_seen(&clk[k], (uint32_t)now_us);
                    uint32_t age = rc->age_mode == 1u   ? (uint32_t)now_us - meas_us
                                   : rc->age_mode == 2u ? 0u
                                                        : (uint32_t)now_us - est;
                    in.sensor[k] = ring[k][idx];
                    in.sensor[k].age_q = (uint8_t)(age / 250u > 255u ? 255u : age / 250u);
                    seen[k] = reg[k];
                }
                read_due_us[k] += read_us;
                if (read_due_us[k] <= now_us) {
                    read_due_us[k] = now_us + read_us;
                }
                read_at_us[k] =
                    read_due_us[k] + (rc->read_jitter_us != 0u
                                          ? simrand_next(&rng) % (rc->read_jitter_us + 1u)
                                          : 0u);
            }
        }
        for (k = 0; k < HOM_MAX_SENSORS && rc->sample_lag_ms != 0u && rc->mst_us == 0u; k++) {
            unsigned q;
            for (q = 0; q < 2u; q++) {
                if (held_at[k][q] == t) {
                    in.sensor[k] = held[k][q];
                }
            }
        }
        for (i = 0; i < TBL_MAX_TENDONS; i++) {
            hom_servo_in_t *s = &in.servo[i];
            s->status = HOM_SERVO_OK;
            s->hw_error = 0;
            if (i >= res->n_tendons) {
                continue;
            }
            if (rc->pos_period_ms > 1u && t % rc->pos_period_ms != 0u) {
                s->status = HOM_SERVO_NOREPLY; /* not read in this step's bus cycle */
                continue;
            }
            s->pos = plant_servo_present(&servo[i]) - rc->frame_offset;
            if (rc->fault_index == i) {
                if (rc->fault == PLANT_FI_SERVO_ABSENT) {
                    s->status = HOM_SERVO_ABSENT;
                } else if (rc->fault == PLANT_FI_SERVO_SILENT && faulting) {
                    s->status = HOM_SERVO_NOREPLY;
                } else if (rc->fault == PLANT_FI_SERVO_HWERR && faulting) {
                    s->hw_error = 0x20; /* overload */
                }
            }
        }
        if (rc->fault == PLANT_FI_ABORT && t == rc->fault_ms) {
            hom_abort(&h);
        }
        out.changed = 0;
        if (!ended) {
            step_rc = hom_step(&h, &in, &out);
            win = hom_win_take_changed(&h);
            res->win_kept |= pulling ? win : 0u;
        }
        if (lag != 0u) {
            /* the writes reach the servos lag ms later, in order (those of
             * the run's last steps too) */
            line[t % CL_MAX_LAG] = out;
            out.changed = 0;
            o = t > lag ? &line[(t - lag) % CL_MAX_LAG] : &out;
        }
        for (i = 0; i < res->n_tendons; i++) {
            if ((o->changed >> i) & 1u) {
                /* a servo that stopped answering still obeys broadcast
                 * writes in this model only if it is alive: the silent one
                 * keeps its last goal */
                if (!(rc->fault == PLANT_FI_SERVO_SILENT && faulting && rc->fault_index == i)) {
                    servo[i].goal = o->goal[i] + rc->frame_offset;
                    servo[i].vel_units = o->vel[i];
                    servo[i].torque = o->torque[i];
                }
            }
        }
        if (!ended) {
            while (hom_event_pop(&h, &ev)) {
                if (ev.type == HOM_EV_PHASE && ev.code == HOM_PH_TENDON) {
                    pulling = 1;
                }
                if (ev.type == HOM_EV_ENGAGED && ev.index < TBL_MAX_TENDONS) {
                    engaged[ev.index] = 1;
                    engage[ev.index] = ev.a;
                }
                if (res->n_events < PLANT_RUN_MAX_EVENTS) {
                    res->events[res->n_events++] = ev;
                }
            }
        }
        for (i = 0; i < res->n_tendons; i++) {
            if (plant.tension_N[i] > res->max_tension_N[i]) {
                res->max_tension_N[i] = plant.tension_N[i];
            }
            if (h.cur == i && pulling && h.state != ST_FINAL && h.tendon[i].have_home != 1u &&
                plant.tension_N[i] > res->max_pull_N[i]) {
                res->max_pull_N[i] = plant.tension_N[i];
            }
            {
                double m = (double)pull_dir[i] * (double)plant_servo_present(&servo[i]);
                if (plant.tension_N[i] < 1e-3 || m > far[i]) {
                    far[i] = m;
                }
                if (h.cur == i && avg_state == ST_FINE_AVG &&
                    (h.p_prev != pt_p || h.b_prev != pt_b) &&
                    avg_behind > res->max_behind_ticks[i]) {
                    /* a point taken: where the servo stood while it was averaged */
                    res->max_behind_ticks[i] = avg_behind;
                }
                if (h.cur == i) {
                    avg_behind = far[i] - m;
                }
            }
            if (engaged[i]) {
                double past = (double)pull_dir[i] * ((double)in.servo[i].pos - (double)engage[i]);
                if (past > res->max_past_engage_ticks[i]) {
                    res->max_past_engage_ticks[i] = past;
                }
            }
        }
        avg_state = h.state;
        pt_p = h.p_prev;
        pt_b = h.b_prev;
        if (!ended && step_rc <= 0) {
            ended = 1;
            res->end_ms = t;
            t_fault = t;
            if (step_rc == 0) {
                break;
            }
        }
        if (ended) {
            int all_slack = 1;
            for (i = 0; i < res->n_tendons; i++) {
                if (plant.tension_N[i] >= 1e-3) {
                    all_slack = 0;
                }
            }
            if (all_slack && !res->released) {
                res->released = 1;
                res->release_ms = t - t_fault;
            }
            if (t - t_fault >= 300u) {
                break;
            }
        }
    }
    for (i = 0; i < res->n_tendons; i++) {
        /* where the tension reached the threshold's share of the target */
        double thr;
        uint32_t mN =
            h.tendon[i].target_cuT != 0u
                ? (uint32_t)((uint64_t)h.tension_mN * h.engage_cuT / h.tendon[i].target_cuT)
                : 0u;
        res->engage_err_ticks[i] = NAN;
        if (engaged[i] && mN >= 1u && plant_true_home(rc->plant, i, (uint16_t)mN, &thr) == 0) {
            res->engage_err_ticks[i] =
                (double)pull_dir[i] * ((double)engage[i] + (double)rc->frame_offset - thr);
        }
    }
    res->rc = step_rc;
    res->fault = h.fault;
    res->fault_index = h.fault_index;
    res->fault_dev = h.fault_dev;
    fill_ground_truth(rc, &plant, &h, res);
    if (!ended) {
        return PLANT_E_SOLVE;
    }
    return 0;
}
