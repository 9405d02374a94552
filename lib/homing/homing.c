/*
 * homing, the public API (step, events, results) and the helpers every phase uses: goals,
 * arrival, averages, norms, 32-bit muldiv (see hom_priv.h, homing.h and docs/homing.md; a run's
 * set-up, hom_start() included, is in hom_setup.c).
 */
#include "homing/hom_priv.h"

#include <stddef.h>
#include <string.h>

/* The defaults live in flash on the AVR (TBL_FLASH is __progmem__ there):
 * one copy instead of 30 stores. */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define HOM_COPY_DEFAULTS memcpy_P
#else
#define HOM_COPY_DEFAULTS memcpy
#endif

/* Speeds in XL430 units (0.229 rpm = 15.63 ticks/s = 96 um/s on a 6.1 um
 * tick). Take-up: twice the tendon's expected travel in ticks
 * (hom_begin_tendon()), at most v_fast, only while the tendon is slack; the
 * firmware's cap (setting approach_fast) is 90 units = 14 ticks per 100 Hz
 * sample: 120 gave homes up to 30 ticks off on the distal tendons of
 * paper_2seg at 1.5 N on the bench. Moderate: 60 units, 9 ticks per sample,
 * so stopping at 80 % of the target leaves margin for a sample of latency.
 * Fine steps are short moves, speed hardly matters. Release and final move:
 * 265 units (the XL430 Velocity Limit) = 4.1 ticks/ms, a 1 mm release in
 * 40 ms; no tendon is pulled further than it unwinds in 85 ms
 * (HOM_RELEASE_REACH_TICKS), a tendon as elastic as a spring in line (the
 * out_of_reach scenario) included. Settle: 10 ms after a fine step (5 ms
 * standing still); 20 ms gave the same homes on the bench and cost 10 ms a
 * point. */
/* HOM_RELEASE_REACH_TICKS is what HOM_V_TOP unwinds in HOM_RELEASE_REACH_MS
 * (0.229 rpm x 4096 ticks per turn / 60000 ms = 229 x 64 / 937500 ticks per
 * ms and unit): the build fails when one changes without the other. */
typedef char
    hom_reach_matches_the_speed[(HOM_RELEASE_REACH_TICKS ==
                                 (long)HOM_V_TOP * 229L * 64L * HOM_RELEASE_REACH_MS / 937500L)
                                    ? 1
                                    : -1];

static const hom_config_t TBL_FLASH hom_defaults = {
    .v_fast = 120,
    .v_moderate = 60,
    .v_fine = 60,
    .v_release = HOM_V_TOP,
    .v_final = HOM_V_TOP,
    .acc = HOM_ACC_DEFAULT,
    .slack_margin_um = HOM_SLACK_MARGIN_UM, /* > the path shortening another tendon causes at
                                             * 1 N; load_tendon() raises it with the tension
                                             * and the tendon's own travel */
    .slack_step_um = 300,
    .slack_max_steps = 6,
    .baseline_samples = 16,
    .avg_samples = 1,
    .fine_max_steps = 16,
    .takeup_per_tick = 2,
    .near_permille = 800,
    .settle_ms = 10,
    .preflight_ms = 200,
    .sensor_timeout_ms = 100,
    .servo_timeout_ms = 50,
    .move_timeout_ms = 3000,
    .tendon_timeout_ms = 4000,
    .engage_min_cuT = 300,
    .rate_limit_cuT = 250000, /* 2.5 mT per sample: 3x the fastest take-up seen */
    .sat_cuT = 490000,        /* 4900 uT of the AK09916's 4912 uT */
    .max_takeup_um = 4000,
    .initial_release_um = HOM_INITIAL_RELEASE_UM,
    .straight = 1,
};

void hom_config_default(hom_config_t *cfg)
{
    HOM_COPY_DEFAULTS(cfg, &hom_defaults, sizeof *cfg);
}

void hom_init(hom_t *h, const hom_config_t *cfg)
{
    memset(h, 0, sizeof *h);
    if (cfg != NULL) {
        h->cfg = *cfg;
    } else {
        hom_config_default(&h->cfg);
    }
    h->state = ST_IDLE;
}

void hom_config_set(hom_t *h, const hom_config_t *cfg)
{
    h->cfg = *cfg;
    h->state = ST_IDLE;
}

hom_config_t *hom_config_reset(hom_t *h)
{
    hom_config_default(&h->cfg);
    h->state = ST_IDLE;
    return &h->cfg;
}

/* |v| as an unsigned number, INT32_MIN's 2^31 included: one routine for
 * every magnitude and two-sided bound of the module (a 32-bit negation and
 * compare written out costs more than the call) */
HOM_NOINLINE uint32_t hom_abs32(int32_t v)
{
    return v < 0 ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
}

/* 32-bit arithmetic only (64-bit code is large and slow on the AVR): each
 * axis is scaled down by the smallest power of two that keeps the sum of
 * three squares within 32 bits (|axis| <= 37837, exact below 378 uT per
 * axis; short by less than three scaled units of at most 16 cuT at the
 * AK09916's full range), the
 * root is built bit by bit (floor), then scaled back. */
uint32_t hom_norm3(const int32_t v[3])
{
    uint32_t m[3];
    uint32_t top = 0;
    uint32_t s;
    uint32_t r = 0;
    uint32_t bit = (uint32_t)1 << 30;
    uint8_t sh = 0;
    uint8_t a;
    for (a = 0; a < 3u; a++) {
        m[a] = hom_abs32(v[a]);
        top |= m[a];
    }
    while ((top >> sh) > 37837u) {
        sh++;
    }
    s = 0;
    for (a = 0; a < 3u; a++) {
        uint32_t x = m[a] >> sh;
        s += x * x;
    }
    while (bit > s) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (s >= r + bit) {
            s -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r << sh;
}

HOM_NOINLINE void hom_push_event(hom_t *h, uint8_t type, uint8_t code, uint8_t index, int32_t a,
                                 int32_t b)
{
    hom_event_t *e;
    if (h->ev_count >= HOM_EV_CAP) {
        if (h->ev_dropped < 255u) {
            h->ev_dropped++;
        }
        return;
    }
    e = &h->ev[(h->ev_head + h->ev_count) % HOM_EV_CAP];
#if HOM_EV_TIME
    e->t_ms = h->now_ms;
#endif
    e->type = type;
    e->code = code;
    e->index = index;
    e->a = a;
    e->b = b;
    h->ev_count++;
}

HOM_NOINLINE void hom_phase_event(hom_t *h, uint8_t code, uint8_t index)
{
    hom_push_event(h, HOM_EV_PHASE, code, index, 0, 0);
}

/* The run is over: HOM_EV_DONE with its time. */
HOM_NOINLINE void hom_done(hom_t *h)
{
    hom_push_event(h, HOM_EV_DONE, 0, 0, (int32_t)hom_since(h, h->t_start), 0);
    h->state = ST_DONE;
}

int hom_event_pop(hom_t *h, hom_event_t *ev)
{
    if (h == NULL || ev == NULL || h->ev_count == 0u) {
        return 0;
    }
    *ev = h->ev[h->ev_head];
    h->ev_head = (uint8_t)((h->ev_head + 1u) % HOM_EV_CAP);
    h->ev_count--;
    return 1;
}

uint8_t hom_event_count(const hom_t *h)
{
    return h->ev_count;
}

int hom_window(const hom_t *h, uint8_t i, int32_t *lo, int32_t *hi)
{
    if (h == NULL || lo == NULL || hi == NULL || i >= h->n_tendons || !hom_has(h->win_known, i)) {
        return HOM_E_ARG;
    }
    *lo = h->tendon[i].eng_lo;
    *hi = h->tendon[i].eng_hi;
    return 0;
}

int hom_home(const hom_t *h, uint8_t i, int32_t *ticks)
{
    if (h == NULL || ticks == NULL || i >= h->n_tendons || !h->tendon[i].have_home) {
        return HOM_E_ARG;
    }
    *ticks = h->tendon[i].home;
    return 0;
}

int16_t hom_to_straight(const hom_t *h, uint8_t i)
{
    return h != NULL && i < h->n_tendons ? hom_straight_ticks(&h->tendon[i]) : 0;
}

/* a * b / c truncated towards zero and saturated to int32, in 32-bit
 * arithmetic only (64-bit expressions cost hundreds of bytes of code per use
 * on the AVR, and a library 64-bit division is slow): the quotient and the
 * remainder of |a| * |b| / |c| are built one bit of |a| at a time (double,
 * then add |b| / |c| and |b| % |c| for a set bit), the remainder staying below
 * |c| <= 2^31 so nothing overflows. Exactly the result a 64-bit a * b / c
 * gives. c must not be 0. */
HOM_NOINLINE int32_t hom_muldiv(int32_t a, int32_t b, int32_t c)
{
    uint32_t ua = hom_abs32(a);
    uint32_t ub = hom_abs32(b);
    uint32_t uc = hom_abs32(c);
    uint32_t bq;
    uint32_t br;
    uint32_t q = 0;
    uint32_t r = 0;
    uint8_t k;
    /* every caller passes c != 0 (a spool factor tbl_check() refused at 0, a
     * count or slope it has checked positive) */
    if (((ua | ub) >> 16) == 0u) {
        /* both below 2^16: the product fits, one division (the common case:
         * micrometres times 1000, cuT times 256) */
        q = ua * ub / uc; /* cppcheck-suppress zerodivcond */
        goto sign;
    }
    bq = ub / uc; /* cppcheck-suppress zerodivcond */
    br = ub % uc; /* cppcheck-suppress zerodivcond */
    /* the leading zero bits of |a| double nothing: start at its top bit */
    for (k = 0; k < 32u && (ua & 0x80000000u) == 0u; k++) {
        ua <<= 1;
    }
    for (; k < 32u; k++) {
        if (q >= 0x80000000u) {
            q = 0xFFFFFFFFu; /* beyond 32 bits: saturated below */
            break;
        }
        q <<= 1;
        r <<= 1;
        if (r >= uc) {
            r -= uc;
            q++;
        }
        if (ua & 0x80000000u) {
            uint32_t t = q + bq;
            if (t < q) {
                q = 0xFFFFFFFFu;
                break;
            }
            q = t;
            r += br;
            if (r >= uc) {
                r -= uc;
                if (q == 0xFFFFFFFFu) {
                    break;
                }
                q++;
            }
        }
        ua <<= 1;
    }
sign:
    if ((a < 0) ^ (b < 0) ^ (c < 0)) {
        return q >= 0x80000000u ? INT32_MIN : -(int32_t)q;
    }
    return q > (uint32_t)INT32_MAX ? INT32_MAX : (int32_t)q;
}

/* um on a spool of nm_per_tick as ticks, truncated towards zero */
HOM_NOINLINE int32_t hom_um_ticks(int32_t um, uint32_t nm_per_tick)
{
    return hom_muldiv(um, 1000, (int32_t)nm_per_tick);
}

/* a * permille / 1000, truncated towards zero */
HOM_NOINLINE int32_t hom_per_mille(int32_t a, int32_t permille)
{
    return hom_muldiv(a, permille, 1000);
}

/* um to ticks, rounded up so margins are never smaller than asked */
HOM_NOINLINE int32_t hom_um_to_ticks(uint32_t um, uint32_t nm_per_tick)
{
    return hom_um_ticks((int32_t)um, nm_per_tick) + 1;
}

/* A measured home and its shift are rounded once, together, from both
 * sub-tick parts (home + to_straight + the rounded sum of what rounding each
 * left): one rounding, not two. A stored home has only the shift's. */
HOM_NOINLINE int16_t hom_straight_ticks(const hom_tendon_t *t)
{
    return (int16_t)(t->to_straight + (t->have_home == 1u ? hom_floor_div256((int32_t)t->home_frac +
                                                                             t->straight_frac)
                                                          : 0));
}

/* A stored home moved into this power cycle's frame: the XL430 keeps the angle
 * within one turn but not the turn count, and the spool does not turn half a
 * revolution while unpowered. */
int32_t hom_unwrap_home(int32_t stored, int32_t present)
{
    int32_t d = (int32_t)((uint32_t)(stored - present) & 4095u);
    if (d >= 2048) {
        d -= 4096;
    }
    return present + d;
}

/* The quantity the approach drives towards a tendon's target: delta mode the
 * table's |B(p_T) - B(p_0)| as it is; absolute mode the table's |B_magnet(p_T)|
 * as a distance from the straight-pose |b_straight| of the tendon's sensor. */
HOM_NOINLINE uint32_t hom_work_target(const hom_t *h, uint8_t k, uint32_t d, uint32_t abs_t)
{
    int32_t r;
    if (h->amb == NULL) {
        return d;
    }
    r = (int32_t)abs_t - (int32_t)h->sensor[k].p0;
    return hom_abs32(r);
}

/* Tendon i's table point at mN with target_cuT replaced by the approach
 * quantity's target (work_target). */
HOM_NOINLINE void hom_work_point(const hom_t *h, uint8_t i, uint16_t mN, tbl_point_t *pt)
{
    (void)tbl_target(&h->table, i, mN, pt);
    pt->target_cuT = hom_work_target(h, h->tendon[i].sensor, pt->target_cuT, pt->abs_target_cuT);
}

void hom_window_around(int8_t dir, int32_t ahead, int32_t behind, int32_t p, int32_t *lo,
                       int32_t *hi)
{
    /* dir is -1 or 1: a negation, not a 32-bit multiply */
    if (dir < 0) {
        ahead = -ahead;
        behind = -behind;
    }
    *hi = p + ahead;
    *lo = p - behind;
}

int hom_abort(hom_t *h)
{
    if (h != NULL && h->state != ST_IDLE && h->state != ST_DONE && h->state != ST_FAULT) {
        h->abort_req = 1;
        return 1;
    }
    return 0;
}

/* d ticks in the tendon's pull direction (dir is +1 or -1). */
HOM_NOINLINE int32_t hom_pull(const hom_tendon_t *t, int32_t d)
{
    return t->dir < 0 ? -d : d;
}

/* The position d ticks past p in tendon t's pull direction (d < 0: behind
 * it). */
HOM_NOINLINE int32_t hom_beyond(const hom_tendon_t *t, int32_t p, int32_t d)
{
    return p + hom_pull(t, d);
}

/* How far x lies past `from` in tendon t's pull direction, ticks. */
HOM_NOINLINE int32_t hom_ahead(const hom_tendon_t *t, int32_t x, int32_t from)
{
    return hom_pull(t, x - from);
}

/* Milliseconds from t to the current step. */
HOM_NOINLINE uint32_t hom_since(const hom_t *h, uint32_t t)
{
    return (uint32_t)(h->now_ms - t);
}

/* 1 << i and bit i of m: one routine each (a variable shift is a loop on
 * the AVR) */
HOM_NOINLINE uint16_t hom_bit(uint8_t i)
{
    return (uint16_t)(1u << i);
}

HOM_NOINLINE uint8_t hom_has(uint16_t m, uint8_t i)
{
    return (uint8_t)((m >> i) & 1u);
}

/* As strchr() does, a const run in, a writable tendon out: one routine for
 * the readers and the writers. */
HOM_NOINLINE hom_tendon_t *hom_cur(const hom_t *h)
{
    return (hom_tendon_t *)&h->tendon[h->cur];
}

HOM_NOINLINE uint16_t hom_since16(const hom_t *h, uint16_t t)
{
    return (uint16_t)((uint16_t)h->now_ms - t);
}

HOM_NOINLINE uint32_t hom_still_ms(const hom_t *h, uint8_t i)
{
    return hom_since16(h, h->tendon[i].moved_ms);
}

HOM_NOINLINE uint32_t hom_phase_ms(const hom_t *h)
{
    return hom_since(h, h->t_phase);
}

HOM_NOINLINE void hom_enter(hom_t *h, uint8_t state)
{
    h->state = state;
    h->t_phase = h->now_ms;
    h->settled = 0;
}

HOM_NOINLINE void hom_set_goal(hom_t *h, uint8_t i, int32_t goal, uint16_t vel)
{
    h->tendon[i].moved_ms = (uint16_t)h->now_ms;
    hom_tendon_t *t = &h->tendon[i];
    t->goal = goal;
    t->vel = vel;
    t->torque = 1;
    h->changed |= hom_bit(i);
    h->moved = 1;
}

/* Tendon i released at the release speed to the slack margin shifted right
 * by `shift` behind its engagement: 0 the release after a home (slack), 2 a
 * back-off (hom_back_off()). */
HOM_NOINLINE void hom_release_slack(hom_t *h, uint8_t i, uint8_t shift)
{
    const hom_tendon_t *t = &h->tendon[i];
    hom_set_goal(h, i, hom_beyond(t, t->engage, -(t->margin_ticks >> shift)), h->cfg.v_release);
}

/* Tendon i released to g at the release speed, or only to where it stands
 * when that is further back already (a release never pulls). */
HOM_NOINLINE void hom_release_to(hom_t *h, uint8_t i, int32_t g)
{
    const hom_tendon_t *t = &h->tendon[i];
    hom_set_goal(h, i, hom_further_back(t, t->present, g), h->cfg.v_release);
}

/* At the goal: within a tick, or stopped short by a few ticks for
 * HOM_STILL_MS since both the command and the last motion (a position
 * controller without integral action droops under the tendon's load). */
HOM_NOINLINE int hom_reached(const hom_t *h, uint8_t i)
{
    const hom_tendon_t *t = &h->tendon[i];
    int32_t d = t->present - t->goal;
    if (d >= -1 && d <= 1) {
        return 1;
    }
    return d >= -HOM_DROOP_TICKS && d <= HOM_DROOP_TICKS && hom_still_ms(h, i) >= HOM_STILL_MS;
}

/* Every tendon whose goal was set in this run has reached it. */
HOM_NOINLINE static int all_reached(const hom_t *h)
{
    uint8_t i;
    for (i = 0; i < h->n_tendons; i++) {
        if (!hom_reached(h, i)) {
            return 0;
        }
    }
    return 1;
}

HOM_NOINLINE void hom_start_avg(hom_t *h)
{
    uint8_t k;
    for (k = 0; k < h->n_sensors; k++) {
        memset(h->sensor[k].acc, 0, sizeof h->sensor[k].acc);
        h->sensor[k].n_acc = 0;
    }
}

HOM_NOINLINE void hom_avg_of(const hom_t *h, uint8_t k, int32_t out[3])
{
    int a;
    int32_t n = h->sensor[k].n_acc ? h->sensor[k].n_acc : 1;
    for (a = 0; a < 3; a++) {
        int32_t s = h->sensor[k].acc[a];
        out[a] = (s >= 0 ? s + (n >> 1) : s - (n >> 1)) / n; /* n > 0 */
    }
}

/* |b - r| */
HOM_NOINLINE static uint32_t diff_norm(const int32_t b[3], const int32_t r[3])
{
    int32_t d[3];
    int a;
    for (a = 0; a < 3; a++) {
        d[a] = b[a] - r[a];
    }
    return hom_norm3(d);
}

HOM_NOINLINE uint32_t hom_delta_of(const hom_t *h, uint8_t k, const int32_t b[3])
{
    return diff_norm(b, h->sensor[k].b0);
}

/* The approach quantity of sensor k at field b: delta mode |b - B0|;
 * absolute mode the selected tendon's signed distance of |b - A| from the
 * straight-pose |b_straight| (0 below it), so that it rises from about 0 at
 * engagement to target_cuT exactly where |b - A| meets the absolute target. */
HOM_NOINLINE uint32_t hom_meas_of(const hom_t *h, uint8_t k, const int32_t b[3])
{
    int32_t m;
    if (h->amb == NULL) {
        return hom_delta_of(h, k, b);
    }
    m = (int32_t)diff_norm(b, h->amb[k]) - (int32_t)h->sensor[k].p0;
    if (h->tendon[h->cur].abs_sign < 0) {
        m = -m;
    }
    return m < 0 ? 0u : (uint32_t)m;
}

/* q8 / 256 rounded to nearest, halves up (the remainder is -128..127): the
 * floor of (q8 + 128) / 256, an arithmetic shift in avr-gcc, GCC and Clang
 * (each documents >> of a negative value as one). */
HOM_NOINLINE int32_t hom_floor_div256(int32_t q8)
{
    return (q8 + 128) >> 8;
}

/* Of two goals, the one further in the release direction. */
HOM_NOINLINE int32_t hom_further_back(const hom_tendon_t *t, int32_t g, int32_t x)
{
    return hom_ahead(t, x, g) < 0 ? x : g;
}

uint8_t hom_pulling(const hom_t *h, uint8_t *tendon)
{
    *tendon = h->cur;
    if (h->state < ST_TAKEUP || h->state > ST_BACKOFF) {
        return 0;
    }
    return (uint8_t)(h->hold == 0u || (h->state == ST_FINE_AVG && h->cur == h->single) ? 1u : 2u);
}

int32_t hom_um_ticks_cur(const hom_t *h, uint8_t i, uint32_t um)
{
    return hom_um_to_ticks(um, h->tendon[i].nm_per_tick);
}

/* The next tendon to calibrate at or after `from`, or n_tendons when none. */
uint8_t hom_next_tendon(const hom_t *h, uint8_t from)
{
    if (h->mode == HOM_MODE_SINGLE) {
        return from <= h->single ? h->single : h->n_tendons;
    }
    return from;
}

/* A release or final move: 1 when it has arrived; one that takes longer
 * than move_timeout_ms ends the run (HOM_F_SERVO_STALL). */
HOM_NOINLINE int hom_move_done(hom_t *h, int arrived, uint8_t dev, uint8_t index)
{
    if (!arrived && hom_phase_ms(h) > h->cfg.move_timeout_ms) {
        hom_fail(h, HOM_F_SERVO_STALL, dev, index, 0);
    }
    return arrived;
}

/* The commanded state of every tendon's servo into *out. */
HOM_NOINLINE static void put_out(const hom_t *h, hom_out_t *out)
{
    uint8_t i;
    for (i = 0; i < HOM_MAX_TENDONS; i++) {
        const hom_tendon_t *t = &h->tendon[i];
        out->goal[i] = t->goal;
        out->vel[i] = t->vel;
        out->torque[i] = t->torque;
    }
    out->acc = h->cfg.acc;
    out->changed = h->changed;
}

HOM_NOINLINE int hom_step(hom_t *h, const hom_in_t *in, hom_out_t *out)
{
    uint8_t i;
    if (h == NULL || in == NULL || out == NULL) {
        return HOM_E_ARG;
    }
    h->now_ms = in->now_ms;
    h->changed = 0;
    if (h->state == ST_IDLE || h->state == ST_DONE || h->state == ST_FAULT) {
        put_out(h, out);
        return h->state == ST_FAULT ? -(int)h->fault : 0;
    }
    if (h->abort_req) {
        h->abort_req = 0;
        for (i = 0; i < h->n_tendons; i++) {
            if (in->servo[i].status == HOM_SERVO_OK) {
                h->tendon[i].present = in->servo[i].pos;
            }
        }
        hom_fail(h, HOM_F_ABORTED, HOM_DEV_NONE, 0, 0);
    } else if (h->state == ST_PREFLIGHT) {
        hom_do_preflight(h, in);
    } else {
        if (hom_check_servos(h, in) == 0 && hom_check_sensors(h, in) == 0) {
            switch (h->state) {
            case ST_RELEASE_ALL:
            case ST_FINAL:
                /* every tendon's move: the release before the slack check,
                 * or the final move before the run's end */
                if (!hom_move_done(h, all_reached(h), HOM_DEV_NONE, 0)) {
                    break;
                }
                if (h->state == ST_FINAL) {
                    hom_done(h);
                } else {
                    hom_enter(h, ST_SLACK_AVG);
                }
                break;
            case ST_SLACK_AVG:
                hom_do_slack_avg(h);
                break;
            case ST_TENDON_RELEASE:
                hom_release_check(h);
                break;
            default:
                hom_do_tendon(h, in);
                break;
            }
        }
    }
    put_out(h, out);
    if (h->state == ST_FAULT) {
        return -(int)h->fault;
    }
    return h->state == ST_DONE ? 0 : HOM_RUNNING;
}
