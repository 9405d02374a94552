/*
 * homing, one tendon's take-up to engagement and the moderate approach, the travel limit, the
 * per-step dispatch of a tendon (see hom_priv.h, homing.h and docs/homing.md).
 */
#include "homing/hom_priv.h"

#include <stddef.h>

/* Where the take-up search for engagement ends: the most slack a tendon may
 * have started with past the high end of its engagement window (what every
 * earlier release paid out lies behind it), at least two ticks on. */
HOM_NOINLINE static int32_t search_goal(const hom_t *h, uint8_t i)
{
    const hom_tendon_t *t = &h->tendon[i];
    int32_t g = hom_beyond(t, t->eng_hi, hom_um_ticks_cur(h, i, h->cfg.max_takeup_um));
    return hom_further_back(t, g, hom_beyond(t, t->present, 2)) == g ? hom_beyond(t, t->present, 2)
                                                                     : g;
}

/* The take-up's goal: at most a lease of 30 ms of motion at its speed
 * ahead of the position last read, never past the search's end. A servo
 * cut off the bus runs on to the last goal it took until its Bus Watchdog
 * stops it 200 ms later: with the search's end as its goal, a take-up at
 * 1400 ticks/s that lost its servo on engagement pulled to 3.7 times the
 * target (chaos seed 3008). The lease is about the tendon's travel at the
 * run's tension (the speed is tied to it, hom_begin_tendon()), renewed when
 * half of it is left. */
static int32_t lease_ticks(uint16_t v)
{
    return 8 + (int32_t)((v * 15u) >> 5); /* 0.229 rpm units: 15.6 ticks/s each */
}

HOM_NOINLINE static void lease(hom_t *h, uint16_t v)
{
    const hom_tendon_t *t = hom_cur(h);
    int32_t g = hom_beyond(t, t->present, lease_ticks(v));
    if (hom_ahead(t, g, h->search_end) > 0) {
        g = h->search_end;
    }
    hom_set_goal(h, h->cur, g, v);
}

HOM_NOINLINE void hom_begin_tendon(hom_t *h, uint8_t i)
{
    hom_tendon_t *t;
    int32_t g;
    uint16_t v;
    h->settled = 0; /* the waits of the slack check and release check are over */
    if (i >= h->n_tendons) {
        hom_begin_final(h);
        return;
    }
    t = &h->tendon[i];
    /* Take-up speed: v_fast at most, and takeup_per_tick units per
     * tick of the tendon's expected travel at this tension. Engagement shows
     * at the next 100 Hz sample and the moderate speed takes over a sample
     * later, so the distance run past engagement grows with the speed: tied
     * to the travel it stays the same share of it (a third per sample at
     * most) whatever the tension, short of the moderate stop at 0.8 of it.
     * A short travel (proximal, low tension) goes slower, a long one faster
     * than one fixed speed would. */
    v = (uint16_t)((uint16_t)t->travel_ticks * h->cfg.takeup_per_tick);
    if (v > h->cfg.v_fast) {
        v = h->cfg.v_fast;
    }
    if (h->retake != 0u) {
        /* hom_over_limit(): a sample's run, a thirteenth of the travel */
        v = (uint16_t)((uint16_t)t->travel_ticks / 2u + 1u);
    }
    h->cur = i;
    h->t_tendon = h->now_ms;
    hom_pull_afresh(h);
    h->near = 0;
    h->steps = 0;
    h->slope_q8 = hom_table_slope(h, i);
    h->slope_min_q8 = (h->slope_q8 >> 1) + 1; /* at least 1: a divisor */
    h->pos_at_sample = t->present;
    if (h->retake == 0u) {
        /* a fault's release goes back at least here: a tendon far softer
         * than its table is taut where a search again starts */
        h->takeup_from = t->present;
    }
    h->takeup_at = t->present;
    t->engaged = 0;
    t->retries = 0;
    hom_phase_event(h, HOM_PH_TENDON, i);
    h->quick_leg = 0;
    if (h->mode == HOM_MODE_QUICK) {
        /* straight to just short of the stored home: a tenth of the expected
         * travel (at least 3 ticks) leaves room for the fine steps */
        int32_t guard = t->travel_ticks / 10;
        if (guard < 3) {
            guard = 3;
        }
        g = hom_beyond(t, t->est_home, -guard);
        if (hom_ahead(t, g, t->present) > 0) {
            h->quick_leg = 1;
            hom_set_goal(h, i, g, v);
            h->state = ST_TAKEUP;
            return;
        }
    }
    h->search_end = search_goal(h, i);
    lease(h, h->mode == HOM_MODE_QUICK ? h->cfg.v_moderate : v);
    h->state = ST_TAKEUP;
}

/* The target of the current tendon lies d ticks past its engagement,
 * beyond its limit. That limit is the bounded pull's at first (load_tendon(),
 * homing.c), and three things put a target beyond it: a field that lies
 * (an ambient step against the tendon's own field), an engagement recorded
 * early (up to a sample's run short of the real one), or a robot softer
 * than its table (the host's model put the travel of some chaos robots'
 * tendons 25 % short). So, once a tendon, it goes back to slack, where a
 * lie that is still there shows before the engagement (HOM_F_FIELD_STEP),
 * and searches for its engagement again, at half a unit of speed per tick
 * of travel (a sample's run is a thirteenth of it); that second pull goes
 * to the table's own limit (ST_BACKOFF in hom_do_tendon()), and beyond it
 * the run ends in HOM_F_TRAVEL_LIMIT. */
HOM_NOINLINE void hom_over_limit(hom_t *h, int32_t d)
{
    if (h->retake == 0u) {
        h->retake = 1;
        hom_back_off(h);
        return;
    }
    hom_fail_tendon(h, HOM_F_TRAVEL_LIMIT, d);
}

/* Faults when position x of the engaged tendon lies beyond its travel limit
 * past engagement. Returns 1 if it did. */
HOM_NOINLINE static int beyond_limit(hom_t *h, int32_t x)
{
    const hom_tendon_t *t = hom_cur(h);
    int32_t d;
    if (!t->engaged || h->retake == 1u) {
        return 0; /* hom_over_limit() backs off from beyond it */
    }
    d = hom_ahead(t, x, t->engage);
    if (d > t->limit_ticks) {
        hom_over_limit(h, d);
        return 1;
    }
    return 0;
}

/* A goal in the pull direction, refused beyond the travel limit. */
HOM_NOINLINE int hom_pull_to(hom_t *h, int32_t g, uint16_t v)
{
    if (beyond_limit(h, g)) {
        return -1;
    }
    hom_set_goal(h, h->cur, g, v);
    return 0;
}

/* How far the current servo may have run, in the pull direction, by the
 * time a goal decided now reaches it: since its position was last read
 * (7-18 ms with 12 servos on the bus) and until the next bus cycle carries
 * the goal (taken as long as the last gap between two reads), at its
 * profile velocity, 1/64 tick per ms per 0.229 rpm unit, at most 60 ms. An
 * upper bound, as the servo never runs faster than its profile. Only for a
 * servo moving in the pull direction. */
HOM_NOINLINE static int16_t run_on(const hom_t *h)
{
    const hom_tendon_t *t = hom_cur(h);
    uint16_t since = hom_since16(h, t->servo_ok_ms);
    since += h->read_gap_ms;
    if (since > 60u) {
        since = 60u;
    }
    return (int16_t)((uint16_t)(since * t->vel) >> 6);
}

HOM_NOINLINE static void begin_moderate(hom_t *h)
{
    hom_tendon_t *t = hom_cur(h);
    int32_t g;
    int32_t d;
    if (t->retries != 0u) {
        g = h->mod_goal;
    } else {
        g = hom_beyond(t, t->engage, hom_per_mille(t->travel_ticks, h->cfg.near_permille));
    }
    if (hom_ahead(t, g, t->engage) > t->limit_ticks) {
        g = hom_beyond(t, t->engage, t->limit_ticks);
    }
    /* the servo ran on since its position was read (chaos seed 12141: a
     * take-up 5 ticks past the goal set here read short of it; the return
     * through the spool's backlash left the field flat, and the fine points
     * predicted the target beyond the travel limit) */
    d = hom_ahead(t, g, t->present);
    if (t->retries == 0u) {
        /* from the take-up, still running; a re-approach starts from slack,
         * where the servo stands (taken as run on at the back-off's speed
         * it went to 2 ticks from there, and its fine points met a flat
         * field up to the travel limit: chaos seed 17633 on another build) */
        d -= run_on(h);
    }
    if (t->retries == 0u && d < 2 + (int32_t)(t->vel >> 2)) {
        /* the take-up has run on to where the approach starts (a short
         * travel, a low tension; it may be its speed over 16 ms, a quarter
         * tick per 0.229 rpm unit, beyond the last position read): stopping
         * it there would bring the servo back through the spool's backlash
         * and the path's friction, and every point after would read the
         * field of a position further on. Back behind the engagement
         * (hom_back_off()), and up to g again */
        t->retries = 1u;
        h->mod_goal = g;
        hom_back_off(h);
        return;
    }
    if (d < 2) {
        g = hom_beyond(t, t->present, 2);
    }
    if (hom_pull_to(h, g, h->cfg.v_moderate) == 0) {
        h->state = ST_MODERATE;
        h->p_far = t->present;
    }
}

/* The field b has come within permille of the target. */
static int near_target(const hom_tendon_t *t, uint32_t b, uint16_t permille)
{
    return (int32_t)b >= hom_per_mille((int32_t)t->target_cuT, permille);
}

/* An engaged tendon is only pulled further (a back-off starts afresh), so
 * the field it moves may not fall below what it was where the servo stands:
 * the field rises with the pull, and on a way back the path's friction and
 * the spool's backlash hold it higher still. Each sample is judged at the
 * next position read (with 12 servos positions come every 7-18 ms), and a
 * sample judged at a read further than any before was taken at that
 * position or short of it: it is a floor for the field there and beyond,
 * and the homing keeps the last HOM_WAY_PTS of them (the way out). Two
 * samples in a row more than an eighth (and eight times the noise) below
 * the highest floor at or short of their read: the field no longer follows
 * the tendon (the magnet moved or gone, an ambient field changed, a sensor
 * knocked), and steps that chase the target would pull on to the travel
 * limit (chaos seed 8390: the magnet removed after the first fine point,
 * 4.9 x the target).
 * A servo that comes back (a take-up run past its goal, chaos seeds 3049,
 * 2010, 12091; a fine point that returns, 16831 and 17633: from 218 to 196)
 * is judged against the field on the way out at where it stands, like with
 * like: not against a sample taken on the way back, further out than the
 * read that judged it. Behind every floor kept, nothing is judged until the
 * servo comes forward again.
 * Called every step: b is a fresh sample's |dB| (0: none), p the position,
 * fresh_p whether it was read this step. Returns 1 when the run ended in
 * HOM_F_FIELD_STEP. */
HOM_NOINLINE static int field_fell(hom_t *h, const hom_tendon_t *t, uint32_t b, int32_t p,
                                   uint8_t fresh_p)
{
    uint32_t floor_b = 0;
    int16_t q;
    uint8_t i;
    uint8_t n = h->n_way;
    if (b != 0u) {
        h->b_pend = b; /* judged at the next position read */
    }
    if (!fresh_p) {
        return 0;
    }
    b = h->b_pend;
    h->b_pend = 0;
    if (b == 0u) {
        return 0; /* no sample since the last read */
    }
    q = (int16_t)hom_ahead(t, p, t->engage);
    for (i = 0; i < n; i++) {
        uint32_t f = (uint32_t)h->way_b[i] << HOM_WAY_SHIFT;
        if (h->way_q[i] <= q && f > floor_b) {
            floor_b = f;
        }
    }
    if (b + floor_b / 8u + 8u * (uint32_t)h->noise_cuT < floor_b) {
        if (++h->b_low < 2u) {
            return 0;
        }
        hom_fail(h, HOM_F_FIELD_STEP, HOM_DEV_SENSOR, t->sensor, (int32_t)(floor_b - b));
        return 1;
    }
    h->b_low = 0;
    if (n == 0u || q > h->way_q[n - 1u]) {
        if (n == HOM_WAY_PTS) {
            n--; /* the oldest goes */
            for (i = 0; i < n; i++) {
                h->way_q[i] = h->way_q[i + 1u];
                h->way_b[i] = h->way_b[i + 1u];
            }
        }
        h->way_q[n] = q;
        b >>= HOM_WAY_SHIFT; /* rounded down: still a floor */
        h->way_b[n] = (uint16_t)(b > 0xFFFFu ? 0xFFFFu : b);
        h->n_way = (uint8_t)(n + 1u);
    }
    return 0;
}

/* Close to the target while moving: stop two ticks on from where the servo
 * may have run since its position p was read (unless the goal is nearer)
 * and go on with fine points. A stop at p itself sent a servo that had run
 * on back through the spool's backlash: the spool stayed, the field of the
 * next points was flat, and the fine points put the target beyond the
 * travel limit (chaos seed 18451: a moderate approach to 217 read at 209,
 * stopped at 211). */
HOM_NOINLINE static void stop_short(hom_t *h, int32_t p)
{
    const hom_tendon_t *t = hom_cur(h);
    uint8_t state = h->state;
    int32_t g = hom_beyond(t, p, 2 + run_on(h));
    if (hom_ahead(t, t->goal, g) > 0) {
        (void)hom_pull_to(h, g, h->cfg.v_moderate);
    }
    if (h->state == state) {
        hom_enter(h, ST_FINE_MOVE);
    }
}

/* Where the current servo was when a sample age_q quarter milliseconds old
 * was measured: back from the last position read along its profile
 * velocity (1/256 tick per quarter millisecond per 0.229 rpm unit), by the
 * time between the two, never behind where the take-up began. Still
 * accelerating it was further back: the engagement comes out early, the
 * side a bound is safe on. The sample's age is the sensor clock's estimate
 * (icm_clock.h); a sample read up to 16 ms after it was measured put a
 * take-up's engagement 20 ticks late (chaos seed 19346). */
HOM_NOINLINE static int32_t pos_measured(const hom_t *h, uint8_t age_q)
{
    const hom_tendon_t *t = hom_cur(h);
    int32_t q = (int32_t)age_q - 4 * (int32_t)hom_since16(h, t->servo_ok_ms);
    int32_t p = t->present;
    if (q > 0) {
        p -= hom_pull(t, (int32_t)(((uint32_t)q * t->vel) >> 8));
    }
    return hom_ahead(t, p, h->takeup_at) < 0 ? h->takeup_at : p;
}

/* The engagement a take-up's first sample over the threshold (b, measured
 * at pm) shows: where the field crossed the threshold, by the table's curve
 * between the threshold and b, and between where the last sample below it
 * and this one were measured. */
HOM_NOINLINE static int32_t engagement_at(const hom_t *h, int32_t pm, uint32_t b)
{
    const hom_tendon_t *t = hom_cur(h);
    int32_t d = hom_curve_um256(h, b, 0u);
    int32_t d0 = hom_curve_um256(h, h->engage_cuT, 0u);
    int32_t e = h->pos_at_sample; /* past the table's grid */
    if (d >= 0 && d0 >= 0) {
        e = hom_beyond(t, pm,
                       d > d0 ? -hom_muldiv(d - d0, 1000, 256 * (int32_t)t->nm_per_tick) : 0);
    }
    if (hom_ahead(t, e, h->pos_at_sample) < 0) {
        e = h->pos_at_sample;
    }
    return e;
}

/* The current tendon's travel limit without the bounded pull's. */
HOM_NOINLINE static int32_t table_limit(const hom_t *h)
{
    tbl_tendon_head_t row;
    (void)tbl_tendon_head(&h->table, h->cur, &row);
    return hom_limit_ticks(&row, INT32_MAX);
}

/* A held pull's scan of the pulled tendon's engagement (HOM_SCAN_*,
 * hom_cmd_t.hold): 1 while it runs. */
static int scanning(const hom_t *h)
{
    return h->hold != 0u && h->cur == h->single;
}

/* Back to g (ST_BACKOFF, where the servo comes to a stand), from where the
 * scan's points go forward (h->steps counts them). g lies within
 * HOM_SCAN_BACK_HELD of the engagement, and the take-up began at least half
 * a margin (HOM_HELD_BACK_UM of it) short of that: never behind it. */
HOM_NOINLINE static void scan_from(hom_t *h, int32_t g)
{
    hom_pull_afresh(h);
    h->steps = 0;
    h->near = 0;
    hom_set_goal(h, h->cur, g, h->cfg.v_moderate);
    h->state = ST_BACKOFF;
}

/* A scan point is averaged: the next one, or the scan's end (HOM_SCAN_AHEAD
 * past the first point whose field reached the engagement threshold, the
 * field at half the target, or HOM_SCAN_POINTS points). The first point's
 * field is the scan's reference (its sensor's b0): the held tendon's path
 * friction keeps the pose that the take-up past the engagement left. Points
 * go HOM_SCAN_STEP ticks a step, twice that while the field stays within a
 * quarter of the engagement threshold of the first point's (the steps that
 * find where the slack ends). Each point has the tendon's time bound of its
 * own: the scan is bounded by its points. */
HOM_NOINLINE static void scan_next(hom_t *h)
{
    hom_tendon_t *t = hom_cur(h);
    int32_t *ref = h->sensor[t->sensor].b0;
    int32_t avg[3];
    uint32_t d;
    int32_t step = HOM_SCAN_STEP;
    if (h->steps == 0u) {
        hom_avg_of(h, t->sensor, ref);
        hom_pull_afresh(h); /* no floor of the field (field_fell()) from another reference */
    }
    hom_avg_of(h, t->sensor, avg);
    d = hom_delta_of(h, t->sensor, avg);
    h->t_tendon = h->now_ms;
    h->steps++;
    if (d < h->engage_cuT / 4u) {
        step = 2 * HOM_SCAN_STEP;
    }
    if (!h->near && d >= h->engage_cuT) {
        h->near = 1; /* the engagement as this scan's points find it */
        t->engage = t->goal;
    }
    if ((h->near && hom_ahead(t, t->goal, t->engage) >= HOM_SCAN_AHEAD) ||
        d >= t->target_cuT / 2u || h->steps >= HOM_SCAN_POINTS) {
        hom_held_next(h);
        return;
    }
    if (hom_pull_to(h, hom_beyond(t, t->goal, step), h->cfg.v_moderate) == 0) {
        hom_enter(h, ST_FINE_MOVE);
    }
}

HOM_NOINLINE void hom_do_tendon(hom_t *h, const hom_in_t *in)
{
    const uint8_t cur = h->cur; /* the tendon stays the same through the step */
    hom_tendon_t *t = hom_cur(h);
    uint8_t sel = t->sensor;
    const hom_sensor_in_t *si = &in->sensor[sel];
    int fresh = si->status == HOM_SENS_NEW;
    uint32_t b = fresh ? hom_delta_of(h, sel, si->b_cuT) : 0u;
    /* delta mode: the approach quantity is |B - B0| itself, one norm */
    uint32_t m = fresh && h->amb != NULL ? hom_meas_of(h, sel, si->b_cuT) : b;
    int32_t p = t->present;

    /* a back-off to slack starts the approach again (at 1.5 N on the bench
     * robot's segment 2: 1.9 s, then 2.1 s more): twice the time for a
     * tendon that backed off */
    if (hom_since(h, h->t_tendon) > ((uint32_t)h->cfg.tendon_timeout_ms << (t->retries != 0u))) {
        hom_fail_tendon(h, HOM_F_TENDON_TIMEOUT, (int32_t)hom_since(h, h->t_tendon));
        return;
    }
    if (beyond_limit(h, p)) {
        return;
    }
    if (t->engaged) {
        /* a servo standing further than its goal: backing off, it missed
         * the goal (a sync write gets no status) and still runs to an older
         * one; send it again, every 10 ms until it takes. Pulling, it ran
         * on before a stop reached it (a goal a bus cycle late, a stale
         * read) or missed the goal and ran to an older one. Sent back, it
         * would leave the spool where it was (the backlash, the path's
         * friction) and every point after would read the field of the place
         * further on: the goal goes up to the furthest read instead, and a
         * point being averaged is taken again there. An engaged tendon is
         * only pulled further (a back-off starts afresh) */
        int32_t g = t->goal;
        int32_t past = HOM_DROOP_TICKS;
        uint8_t back = 0;
        if (h->state != ST_BACKOFF) {
            if (hom_ahead(t, p, h->p_far) > 0) {
                h->p_far = p;
            }
            back = hom_ahead(t, h->p_far, p) > 0; /* already on its way back */
            p = h->p_far;
            past = HOM_RUN_ON_TICKS;
        }
        if (hom_ahead(t, p, g) > past && (back || hom_still_ms(h, cur) >= 10u)) {
            hom_set_goal(h, cur, h->state != ST_BACKOFF ? p : g, t->vel);
            if (h->state == ST_FINE_AVG) {
                hom_enter(h, ST_FINE_MOVE);
            }
        }
        p = t->present;
        if (h->state != ST_BACKOFF &&
            field_fell(h, t, b, p, (uint8_t)(in->servo[cur].status == HOM_SERVO_OK))) {
            return;
        }
    }
    switch (h->state) {
    case ST_TAKEUP:
        if (fresh && !t->engaged) {
            if (b < h->engage_cuT) {
                h->pos_at_sample = pos_measured(h, si->age_q); /* the last position seen slack */
            } else if (hom_ahead(t, p, h->takeup_at) < t->margin_ticks >> 1) {
                /* the field changed before the tendon could have engaged: it
                 * was released a whole margin short of its engagement, and has
                 * taken up less than half of it. Something no tendon moves
                 * changed the field (a magnet, iron, a sensor knocked): taken
                 * for an engagement it would narrow the tendon's window to the
                 * wrong place and leave the next runs searching short of it */
                hom_fail(h, HOM_F_FIELD_STEP, HOM_DEV_SENSOR, sel, (int32_t)b);
                return;
            } else {
                t->engaged = 1;
                t->engage = engagement_at(h, pos_measured(h, si->age_q), b);
                /* the window narrows here for this run's releases; the app
                 * keeps it (win_changed) once the home is recorded */
                t->eng_lo = t->engage;
                t->eng_hi = t->engage;
                hom_push_event(h, HOM_EV_ENGAGED, 0, cur, t->engage, (int32_t)b);
                h->p_far = p;
                if (scanning(h)) {
                    /* a held pull's scan, from behind the engagement: a held
                     * take-up's field, weak at its sensor (the hold bends the
                     * robot off that sensor's best direction), put it up to 30
                     * ticks late, and a scan that starts past it reads the
                     * field its spool's backlash and path friction hold */
                    scan_from(h, hom_beyond(t, t->engage,
                                            -(h->held != 0u ? HOM_SCAN_BACK_HELD : HOM_SCAN_BACK)));
                    break;
                }
                if (!h->quick_leg) {
                    begin_moderate(h);
                    break;
                }
            }
        }
        if (!h->quick_leg && !t->engaged && t->goal != h->search_end &&
            hom_ahead(t, t->goal, p) <= lease_ticks(t->vel) >> 1) {
            lease(h, t->vel); /* half of the lease left: renew it */
            break;
        }
        if (h->quick_leg && t->engaged && fresh && near_target(t, m, HOM_QUICK_STOP_PERMILLE)) {
            stop_short(h, p); /* the stored home is further than the field says */
        } else if (hom_reached(h, cur)) {
            if (h->quick_leg && t->engaged) {
                hom_enter(h, ST_FINE_MOVE);
            } else if (h->quick_leg) {
                /* no engagement where the stored home put it: search as usual */
                h->quick_leg = 0;
                h->search_end = search_goal(h, cur);
                lease(h, h->cfg.v_moderate);
            } else {
                hom_fail_tendon(h, HOM_F_NO_ENGAGEMENT, hom_ahead(t, p, h->pos_at_sample));
            }
        }
        break;
    case ST_MODERATE:
        /* a re-approach goes to a point measured short of the target: only
         * the target itself stops it early */
        if (fresh && near_target(t, m, t->retries != 0u ? 1000u : h->cfg.near_permille)) {
            stop_short(h, p);
        } else if (hom_reached(h, cur)) {
            hom_enter(h, ST_FINE_MOVE);
        }
        break;
    case ST_FINE_MOVE: {
        int32_t err = p - t->goal;
        /* at the goal (hom_reached(): within a tick, or a droop of a few
         * standing still) and settled; a scan's point averages samples
         * measured there only: standing longer than a sample takes to reach
         * the homing */
        if (hom_phase_ms(h) >= h->cfg.settle_ms &&
            hom_still_ms(h, cur) >= (scanning(h) ? HOM_SAMPLE_AGE_MS : h->cfg.settle_ms / 2u) &&
            hom_reached(h, cur)) {
            hom_start_avg(h);
            h->state = ST_FINE_AVG;
        } else if (hom_phase_ms(h) > h->cfg.move_timeout_ms) {
            hom_fail(h, HOM_F_SERVO_STALL, HOM_DEV_SERVO, cur, err);
        }
        break;
    }
    case ST_FINE_AVG:
        if (scanning(h)) {
            if (h->sensor[sel].n_acc >= HOM_SCAN_SAMPLES) {
                scan_next(h);
            }
            break;
        }
        /* points within a few ticks of the target decide the home: more samples */
        if (h->sensor[sel].n_acc >= (h->near ? h->n_near : h->cfg.avg_samples)) {
            hom_fine_point(h);
        }
        break;
    case ST_BACKOFF:
        /* back where the back-off went, and standing there for longer than
         * a sample takes to reach the homing (up to 16 ms): a sample
         * measured on the way back, judged at a read on the way forward
         * again, would set a floor for the field that the pull ahead falls
         * below (a false HOM_F_FIELD_STEP; test_short_back_off_is_no_fall) */
        if (!hom_reached(h, cur) || hom_still_ms(h, cur) < HOM_SAMPLE_AGE_MS) {
            break;
        }
        if (h->retake == 1u) {
            /* back at slack: a field that lied (an ambient step, still
             * there) shows now, before the engagement (HOM_F_FIELD_STEP);
             * a field that did not says the robot is softer than its
             * table (chaos seeds 20462, 20598: segment-3 tendons 1.25 x
             * the table's travel), and the second pull goes to the table's
             * own limit */
            h->retake = 2;
            t->limit_ticks = (int16_t)table_limit(h);
            hom_begin_tendon(h, cur);
        } else if (scanning(h)) {
            h->p_far = t->present; /* the scan's points go forward from here */
            hom_enter(h, ST_FINE_MOVE);
        } else {
            begin_moderate(h);
        }
        break;
    default:
        break;
    }
}
