/*
 * homing, preflight, the release of every tendon, the slack check and baseline, and the release
 * check after each home (see hom_priv.h, homing.h and docs/homing.md).
 */
#include "homing/hom_priv.h"

#include <string.h>

/* Where a run releases tendon i to before its slack check: the margin
 * before its engagement window (quick mode: before the engagement the stored
 * home implies). The slack check's further steps count from here, not from
 * where the tendon stands, so runs after stops do not pay out more. */
HOM_NOINLINE static int32_t release_base(const hom_t *h, uint8_t i)
{
    const hom_tendon_t *t = &h->tendon[i];
    if (h->mode == HOM_MODE_QUICK) {
        return hom_beyond(t, t->est_home, -((int32_t)t->travel_ticks + t->margin_ticks));
    }
    return hom_beyond(t, t->eng_lo, -t->margin_ticks);
}

/* Tendon i's engagement window changed: the app keeps it (hom_window()). */
HOM_NOINLINE static void win_changed(hom_t *h, uint8_t i)
{
    h->win_changed |= hom_bit(i);
}

/* Preflight: every device must answer within preflight_ms; each one that does
 * not, or reports an error, is named before the refusal. */
void hom_do_preflight(hom_t *h, const hom_in_t *in)
{
    uint8_t i;
    int missing = 0;
    int all = 1;
    if (!h->pf_started) {
        h->pf_started = 1;
        h->t_phase = h->now_ms;
        h->t_start = h->now_ms;
        hom_push_event(h, HOM_EV_START, h->mode, 0, h->tension_mN, 0);
        hom_phase_event(h, HOM_PH_PREFLIGHT, 0);
        /* h->seen: none yet, as hom_start() cleared it */
        h->pf_missing = 0xFFFFu; /* none has answered yet */
    }
    if (!hom_load_step(h)) {
        all = 0; /* the table's part of the set-up first */
    }
    for (i = 0; i < h->n_sensors; i++) {
        uint8_t st = in->sensor[i].status;
        if (st == HOM_SENS_NEW) {
            h->seen[i] |= 1u;
            memcpy(h->sensor[i].last, in->sensor[i].b_cuT, sizeof h->sensor[i].last);
            h->sensor[i].have_last = 1;
        } else if (st == HOM_SENS_ERROR || st == HOM_SENS_OVERFLOW || st == HOM_SENS_ABSENT) {
            h->seen[i] |= (uint8_t)(st == HOM_SENS_ABSENT ? 2u : 4u);
        }
        if (h->seen[i] != 1u) {
            all = 0; /* not sampled yet, or an error reported earlier */
        }
    }
    for (i = 0; i < h->n_tendons; i++) {
        const hom_servo_in_t *s = &in->servo[i];
        if (s->status == HOM_SERVO_OK && s->hw_error == 0u) {
            h->tendon[i].servo_ok_ms = (uint16_t)h->now_ms;
            h->tendon[i].present = s->pos;
            h->pf_missing &= (uint16_t)~hom_bit(i);
        } else if (s->status == HOM_SERVO_OK || s->status == HOM_SERVO_ABSENT) {
            h->pf_missing |= hom_bit(i); /* faulty: hardware error or absent */
        }
        if (hom_has(h->pf_missing, i)) {
            all = 0;
        }
    }
    if (all) {
        for (i = 0; i < h->n_sensors; i++) {
            h->sensor[i].last_ms = (uint16_t)h->now_ms;
        }
        hom_phase_event(h, HOM_PH_RELEASE, 0);
        for (i = 0; i < h->n_tendons; i++) {
            hom_tendon_t *t = &h->tendon[i];
            int32_t g;
            t->est_home = hom_unwrap_home(t->est_home, t->present);
            if (h->mode == HOM_MODE_DRY) {
                continue;
            }
            if (!hom_has(h->win_known, i)) {
                /* Nothing known this power cycle (the window is kept across
                 * resets, not power-ups): the engagement may lie up to the
                 * release that frees a tendon left at the top of the grid
                 * behind the present position, or ahead of it by what a
                 * run cut by the power-up released (and the start slack the
                 * search covers). A stored home tells more: the engagement
                 * lies near it less the travel, and no release goes beyond
                 * the release before that (every power-up's first run paid
                 * out a release more: chaos seed 1034). */
                int32_t p = t->present;
                int32_t r = t->release_ticks;
                int32_t e = hom_beyond(t, t->est_home, -t->travel_ticks); /* with a stored home */
                if (t->have_home) {
                    if (hom_further_back(t, e, p) == p) {
                        p = e;
                    }
                    r = 0;
                }
                hom_window_around(t->dir, r, (int32_t)t->release_ticks - t->margin_ticks, p,
                                  &t->eng_lo, &t->eng_hi);
                if (h->mode == HOM_MODE_QUICK) {
                    t->eng_hi = e;
                    t->eng_lo = e;
                }
                h->win_known |= hom_bit(i);
                win_changed(h, i);
            }
            g = release_base(h, i);
            hom_release_to(h, i, g);
        }
        /* a dry run moves nothing: straight to the baseline average */
        hom_enter(h, h->mode == HOM_MODE_DRY ? ST_SLACK_AVG : ST_RELEASE_ALL);
        h->steps = 0;
        return;
    }
    if (hom_phase_ms(h) < h->cfg.preflight_ms) {
        return;
    }
    for (i = 0; i < h->n_sensors; i++) {
        if (h->seen[i] != 1u) {
            int32_t why = (h->seen[i] & 2u) ? 1 : ((h->seen[i] & 4u) ? 3 : 2);
            hom_push_event(h, HOM_EV_MISSING, HOM_DEV_SENSOR, i, why, 0);
            missing++;
        }
    }
    for (i = 0; i < h->n_tendons; i++) {
        if (hom_has(h->pf_missing, i)) {
            const hom_servo_in_t *s = &in->servo[i];
            int32_t why = s->status == HOM_SERVO_ABSENT ? 1 : (s->hw_error != 0u ? 4 : 2);
            hom_push_event(h, HOM_EV_MISSING, HOM_DEV_SERVO, i, why, s->hw_error);
            missing++;
        }
    }
    hom_fail(h, HOM_F_PREFLIGHT, HOM_DEV_NONE, 0, missing);
}

/* The tendon is back at slack after its home: every tendon slack, the
 * robot straight, so its selected sensor must read the baseline again
 * (within the engagement threshold, averaged). A field that stays changed
 * means something moved that no tendon moves (a magnet, a sensor, iron
 * nearby) and the home measured against it is wrong: HOM_F_FIELD_STEP, the
 * home is not recorded. Otherwise the home is recorded and reported.
 * A held pull (hom_held_next()) waits here with the pulled tendon's sensor:
 * in phase 1 the pulled tendon is back at slack, checked the same way, and
 * the held tendon's pull begins; in phase 2 the held tendon stands, and its
 * bend's field (baseline_samples averaged) becomes the reference the
 * pulled tendon's engagement is found against: not a baseline (no tendon
 * is slack-checked under it, and the app keeps no baseline of a held run).
 * HOM_PH_HOLD names the held tendon and where it stands. */
void hom_release_check(hom_t *h)
{
    hom_tendon_t *t = hom_cur(h);
    uint8_t k = h->tendon[h->hold != 0u ? h->single : h->cur].sensor;
    int32_t avg[3];
    uint32_t d;
    if (h->settled >= 3u) {
        /* two steps after the home's: the next tendon's set-up (its table
         * slope, its goal) shares a main-loop pass neither with the app's
         * keeping of the window (a CRC, the home's step) nor with the
         * <result> report (the step after): together 4.1-4.6 ms */
        if (h->settled++ == 4u) {
            hom_begin_tendon(h, hom_next_tendon(h, (uint8_t)(h->cur + 1u)));
        }
        return;
    }
    if (!h->settled) {
        if (hom_move_done(h, hom_reached(h, h->cur), HOM_DEV_SERVO, h->cur)) {
            h->settled = 1;
            h->t_phase = h->now_ms;
        }
        return;
    }
    if (h->settled == 1u) {
        if (hom_phase_ms(h) >= h->cfg.settle_ms) {
            hom_start_avg(h);
            h->settled = 2;
        }
        return;
    }
    if (h->sensor[k].n_acc < (h->held == 2u ? h->cfg.baseline_samples : h->cfg.avg_samples)) {
        return;
    }
    hom_avg_of(h, k, avg);
    if (h->held == 2u) {
        hom_avg_of(h, k, h->sensor[k].b0);
        hom_push_event(h, HOM_EV_PHASE, HOM_PH_HOLD, h->cur, t->present, 0);
        h->held = 3;
        hom_begin_tendon(h, h->single);
        return;
    }
    d = hom_delta_of(h, k, avg);
    if (d > h->engage_cuT) {
        hom_fail(h, HOM_F_FIELD_STEP, HOM_DEV_SENSOR, k, (int32_t)d);
        return;
    }
    if (h->held == 1u) {
        hom_begin_tendon(h, (uint8_t)(h->hold - 1u));
        return;
    }
    t->have_home = 1;
    /* the window its engagement narrowed is kept from now on: an engagement
     * that a field step faked in the take-up (the field changed after half
     * the margin was taken up) ends without a home, and kept, its window
     * left every later search short of the true engagement (chaos seed
     * 10103: no_engagement in every calibration after it) */
    win_changed(h, h->cur);
    d = hom_since(h, h->t_tendon); /* the tendon's time, saturated at 16 bits */
    h->tendon_ms = (uint16_t)(d > 0xFFFFu ? 0xFFFFu : d);
    /* the home's sub-tick residue, -128..127 (1/256 tick; the home is
     * rounded to the nearest tick) */
    hom_push_event(h, HOM_EV_HOME, 0, h->cur, t->home, t->home_frac);
    h->settled = 3;
}

static void slack_done(hom_t *h)
{
    uint8_t k;
    uint8_t i;
    if (h->mode != HOM_MODE_DRY && h->steps > 1u) {
        /* the slack check had to release further: the engagement lies
         * behind the window, which now starts a margin past the confirmed
         * slack (later releases go no further than here) */
        for (i = 0; i < h->n_tendons; i++) {
            hom_tendon_t *t = &h->tendon[i];
            int32_t lo = hom_beyond(t, t->present, t->margin_ticks);
            if (hom_further_back(t, lo, t->eng_lo) == lo) {
                t->eng_lo = lo;
                win_changed(h, i);
            }
        }
    }
    for (k = 0; k < h->n_sensors; k++) {
        tbl_sensor_t s;
        uint32_t pred;
        (void)tbl_sensor(&h->table, k, &s);
        pred = hom_norm3(s.b_straight_cuT); /* the table's straight-pose |B| */
        if (h->amb_capture) {
            int a;
            for (a = 0; a < 3; a++) {
                h->amb[k][a] = h->sensor[k].b0[a] - s.b_straight_cuT[a];
            }
        }
        if (pred >= 10000u && hom_norm3(h->sensor[k].b0) < pred / 2u) {
            hom_fail(h, HOM_F_MAGNET_MISSING, HOM_DEV_SENSOR, k,
                     (int32_t)hom_norm3(h->sensor[k].b0));
            return;
        }
    }
    hom_phase_event(h, HOM_PH_BASELINE, 0);
    if (h->mode == HOM_MODE_DRY) {
        for (i = 0; i < h->n_tendons; i++) {
            hom_push_event(
                h, HOM_EV_TARGET, 0, i, (int32_t)h->tendon[i].target_cuT,
                hom_per_mille(h->tendon[i].travel_ticks, (int32_t)h->tendon[i].nm_per_tick));
        }
        hom_done(h);
        return;
    }
    h->settled = 3; /* the next step begins the first tendon */
}

/* Averages every sensor after a settle time; compares with the previous
 * average; releases further until nothing changes. */
HOM_NOINLINE void hom_do_slack_avg(hom_t *h)
{
    int32_t avg[HOM_MAX_SENSORS][3];
    uint8_t k;
    uint8_t i;
    uint32_t worst = 0;
    int done;
    if (h->settled == 3u) {
        /* the baseline is taken (slack_done()): the first tendon begins in
         * a step of its own, its table work apart from the averages' */
        hom_begin_tendon(h, hom_next_tendon(h, 0));
        return;
    }
    if (!h->settled) {
        if (hom_phase_ms(h) < h->cfg.settle_ms) {
            return;
        }
        hom_start_avg(h);
        h->settled = 1;
        return;
    }
    for (k = 0; k < h->n_sensors; k++) {
        if (h->sensor[k].n_acc < h->cfg.baseline_samples) {
            return;
        }
    }
    h->settled = 0;
    /* until the slack is confirmed, b0 holds the previous average; each
     * average is computed once (three 32-bit divisions per sensor) */
    for (k = 0; k < h->n_sensors; k++) {
        uint32_t n;
        hom_avg_of(h, k, avg[k]);
        n = hom_delta_of(h, k, avg[k]); /* |avg - b0|, b0 the previous average */
        if (n > worst) {
            worst = n;
        }
    }
    done = h->mode == HOM_MODE_DRY || (h->steps > 0u && worst <= h->engage_cuT);
    for (k = 0; k < h->n_sensors; k++) {
        int a;
        for (a = 0; a < 3; a++) {
            /* the baseline when this average confirms the slack: both
             * averages then saw the same straight pose, so it takes both */
            int32_t *b0 = &h->sensor[k].b0[a];
            *b0 = done && h->steps > 0u ? avg[k][a] - (avg[k][a] - *b0) / 2 : avg[k][a];
        }
    }
    if (done) {
        slack_done(h);
        return;
    }
    if (h->steps >= h->cfg.slack_max_steps) {
        hom_fail(h, HOM_F_SLACK, HOM_DEV_NONE, 0, (int32_t)worst);
        return;
    }
    h->steps++;
    for (i = 0; i < h->n_tendons; i++) {
        hom_tendon_t *t = &h->tendon[i];
        int32_t g = release_base(h, i) -
                    hom_pull(t, h->steps * hom_um_ticks_cur(h, i, h->cfg.slack_step_um));
        hom_release_to(h, i, g);
    }
    hom_enter(h, ST_RELEASE_ALL);
}

/* Held pull (hom_cmd_t.hold): one of its pulls has ended (a scan, the held
 * tendon's pull at its target or, as any survey pull, at its bound). After
 * the pulled tendon's scan alone it goes back to slack and the held
 * tendon's pull follows (phase 1); after the held tendon's, that tendon
 * stays where it is and bends the robot (phase 2); both wait in
 * ST_TENDON_RELEASE (hom_release_check()). After the held scan both go back
 * to slack, behind their engagements, and the run ends as a survey does.
 * None records a home. */
void hom_held_next(hom_t *h)
{
    uint8_t held = ++h->held;
    h->retake = 0; /* the next take-up at its own speed, its limit checked */
    if (held != 2u) {
        hom_release_slack(h, h->cur, 0);
    }
    if (held <= 2u) {
        hom_enter(h, ST_TENDON_RELEASE);
        return;
    }
    hom_release_slack(h, (uint8_t)(h->hold - 1u), 0);
    hom_begin_final(h);
}
