/*
 * homing, faults: ending a run with every tendon released, the health checks of sensors and servos
 * each step, fault names (see hom_priv.h, homing.h and docs/homing.md).
 */
#include "homing/hom_priv.h"

#include <string.h>

const char *hom_fault_name(int fault)
{
#define HOM_FAULT_NAME(id, word) word,
    static const char *const names[HOM_F_COUNT] = {HOM_FAULTS(HOM_FAULT_NAME)};
#undef HOM_FAULT_NAME
    if (fault < 0 || fault >= (int)HOM_F_COUNT) {
        return "unknown";
    }
    return names[fault];
}

/* Ends the run in a fault: the release goals go out in this very step. A
 * tendon that engaged goes back to the margin beyond its engagement; any
 * other goes back the margin from where it is (or keeps a release already
 * under way if that is further). The tendon being pulled goes back at
 * least to where its take-up began, where it was slack: a tendon far softer
 * than its table carries tension long before its field shows the
 * engagement, and the margin before that late engagement left it taut 1.7 s
 * (chaos seed 4039, `out_of_reach`, 216 mN). Nothing moves if nothing had
 * moved. */
HOM_NOINLINE void hom_fail(hom_t *h, hom_fault_t f, uint8_t dev, uint8_t index, int32_t detail)
{
    uint8_t i;
    h->fault = (uint8_t)f;
    h->fault_dev = dev;
    h->fault_index = index;
    hom_push_event(h, HOM_EV_FAULT, (uint8_t)f, index, dev, detail);
    if (h->moved) {
        for (i = 0; i < h->n_tendons; i++) {
            const hom_tendon_t *t = &h->tendon[i];
            /* the slack margin before the engagement window (this run's
             * engagement when it engaged: the window is narrowed to it), a
             * release already going further, and never a pull */
            int32_t g = hom_beyond(t, t->eng_lo, -t->margin_ticks);
            g = hom_further_back(t, g, t->goal);
            if (i == h->cur && h->state >= ST_TAKEUP && h->state <= ST_BACKOFF) {
                g = hom_further_back(t, g, h->takeup_from);
            }
            hom_release_to(h, i, g);
        }
        hom_push_event(h, HOM_EV_RELEASED, 0, 0, (int32_t)f, 0);
    }
    h->state = ST_FAULT;
}

/* hom_fail() naming the tendon being calibrated. A survey's pull that
 * reached its bound (its travel limit, a field that no longer rises with
 * it, its time) ends there instead: the tendon is released and checked as
 * after a home, and the survey goes on with the next tendon. What it
 * streamed up to there is its pull (docs/identify.md); on a robot that
 * differs from its table the bound comes before the top of the grid. A
 * tendon that never engaged still ends the survey. */
HOM_NOINLINE void hom_fail_tendon(hom_t *h, hom_fault_t f, int32_t detail)
{
    if (h->survey && f != HOM_F_NO_ENGAGEMENT) {
        int32_t p = hom_cur(h)->present;
        hom_finish_tendon(h, p, p * 256);
        return;
    }
    hom_fail(h, f, HOM_DEV_TENDON, h->cur, detail);
}

/* Sensor bookkeeping and health checks of one step. Returns 1 if it failed. */
int hom_check_sensors(hom_t *h, const hom_in_t *in)
{
    uint8_t k;
    int a;
    hom_fault_t f;
    int32_t detail;
    for (k = 0; k < h->n_sensors; k++) {
        const hom_sensor_in_t *s = &in->sensor[k];
        hom_sensor_t *st = &h->sensor[k];
        f = HOM_F_SATURATED;
        detail = 0;
        if (s->status == HOM_SENS_OVERFLOW) {
            goto fault;
        }
        if (s->status == HOM_SENS_ERROR || s->status == HOM_SENS_ABSENT) {
            f = HOM_F_SENSOR_ERROR;
            detail = s->status;
            if (++st->err_run >= 3u) {
                goto fault;
            }
        } else if (s->status == HOM_SENS_NEW) {
            st->err_run = 0;
            for (a = 0; a < 3; a++) {
                int32_t v = s->b_cuT[a];
                detail = v;
                if (hom_abs32(v) >= h->cfg.sat_cuT) {
                    goto fault;
                }
                if (st->have_last) {
                    detail = v - st->last[a];
                    if (hom_abs32(detail) > h->cfg.rate_limit_cuT) {
                        f = HOM_F_FIELD_RATE;
                        goto fault;
                    }
                }
            }
            memcpy(st->last, s->b_cuT, sizeof st->last);
            st->have_last = 1;
            st->last_ms = (uint16_t)h->now_ms;
            if (st->n_acc < HOM_MAX_AVG) {
                for (a = 0; a < 3; a++) {
                    st->acc[a] += s->b_cuT[a];
                }
                st->n_acc++;
            }
        }
        /* every step: the gap passes sensor_timeout_ms (16 bits) before
         * its 16-bit difference could wrap */
        detail = hom_since16(h, st->last_ms);
        if ((uint16_t)detail > h->cfg.sensor_timeout_ms) {
            f = HOM_F_SENSOR_TIMEOUT;
            goto fault;
        }
    }
    return 0;
fault: /* one exit for every fault: the call is set up once */
    hom_fail(h, f, HOM_DEV_SENSOR, k, detail);
    return 1;
}

int hom_check_servos(hom_t *h, const hom_in_t *in)
{
    uint8_t i;
    for (i = 0; i < h->n_tendons; i++) {
        const hom_servo_in_t *s = &in->servo[i];
        if (s->status == HOM_SERVO_OK) {
            if (s->hw_error != 0u) {
                hom_fail(h, HOM_F_SERVO_ERROR, HOM_DEV_SERVO, i, s->hw_error);
                return 1;
            }
            if (s->pos != h->tendon[i].present) {
                h->tendon[i].moved_ms = (uint16_t)h->now_ms;
            } else if (hom_since16(h, h->tendon[i].moved_ms) > HOM_STILL_CAP_MS) {
                /* standing long: the stamp ages no further, so that its
                 * 16-bit difference never wraps */
                h->tendon[i].moved_ms = (uint16_t)(h->now_ms - HOM_STILL_CAP_MS);
            }
            h->tendon[i].present = s->pos;
            if (i == h->cur) {
                uint16_t gap = hom_since16(h, h->tendon[i].servo_ok_ms);
                h->read_gap_ms = (uint8_t)(gap > 40u ? 40u : gap);
            }
            h->tendon[i].servo_ok_ms = (uint16_t)h->now_ms;
        } else if (hom_since16(h, h->tendon[i].servo_ok_ms) > h->cfg.servo_timeout_ms) {
            /* checked every step: the gap passes the 16-bit timeout before
             * its 16-bit difference could wrap */
            hom_fail(h, HOM_F_SERVO_TIMEOUT, HOM_DEV_SERVO, i,
                     hom_since16(h, h->tendon[i].servo_ok_ms));
            return 1;
        }
    }
    return 0;
}
