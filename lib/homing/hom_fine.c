/*
 * homing, the fine approach to the target (table curve, measured slope, averaged points), the
 * least-squares home and the final move (see hom_priv.h, homing.h and docs/homing.md).
 */
#include "homing/hom_priv.h"

#include <stddef.h>
#include <string.h>

/* The table's local slope of |dB| over travel around the tension (a 100 mN
 * window clipped to the grid), cuT per tick with 8 fractional bits: the
 * first fine step's estimate before two points of its own exist. */
HOM_NOINLINE int32_t hom_table_slope(const hom_t *h, uint8_t i)
{
    const tbl_src_t *table = &h->table;
    uint32_t nm_per_tick = h->tendon[i].nm_per_tick;
    tbl_info_t info;
    tbl_point_t lo;
    tbl_point_t hi;
    uint16_t t = h->tension_mN;
    uint16_t t0;
    uint16_t t1;
    int32_t dticks;
    int32_t s;
    uint16_t g0;
    uint16_t g1;
    (void)tbl_info(table, &info);
    g0 = tbl_grid_mN(table, 0);
    g1 = tbl_grid_mN(table, (uint8_t)(info.n_grid - 1u));
    t0 = (uint16_t)(t >= g0 + 50u ? t - 50u : g0);
    t1 = (uint16_t)(t + 50u <= g1 ? t + 50u : g1);
    hom_work_point(h, i, t0, &lo);
    hom_work_point(h, i, t1, &hi);
    dticks = hom_um_ticks((int32_t)hi.travel_um - (int32_t)lo.travel_um, nm_per_tick);
    if (dticks <= 0 || hi.target_cuT <= lo.target_cuT) {
        dticks = hom_um_ticks((int32_t)hi.travel_um, nm_per_tick);
        s = dticks > 0 ? hom_muldiv((int32_t)hi.target_cuT, 256, dticks) : 256;
    } else {
        s = hom_muldiv((int32_t)(hi.target_cuT - lo.target_cuT), 256, dticks);
    }
    return s < 1 ? 1 : s;
}

/* Distance of tendon i to its goal in the final move: its home (measured or
 * stored), else where it was sent last. */
HOM_NOINLINE static int32_t final_dist(const hom_t *h, uint8_t i, int32_t *goal)
{
    const hom_tendon_t *t = &h->tendon[i];
    int32_t d;
    *goal = t->have_home == 1u ? t->home : (t->have_home == 2u ? t->est_home : t->goal);
    if (t->have_home != 0u && h->cfg.straight != 0u) {
        *goal += hom_straight_ticks(t);
    }
    d = *goal - t->present;
    return (int32_t)hom_abs32(d);
}

HOM_NOINLINE void hom_begin_final(hom_t *h)
{
    uint8_t i;
    int32_t dmax = 1;
    int32_t g;
    hom_phase_event(h, HOM_PH_FINAL, 0);
    for (i = 0; i < h->n_tendons; i++) {
        int32_t d = final_dist(h, i, &g);
        if (d > dmax) {
            dmax = d;
        }
    }
    /* the same profile shape for all, velocities in proportion to distance,
     * so every tendon arrives at the same moment */
    for (i = 0; i < h->n_tendons && !h->survey; i++) {
        if (h->tendon[i].have_home != 0u) {
            uint32_t d = (uint32_t)final_dist(h, i, &g);
            uint32_t v = ((uint32_t)h->cfg.v_final * d + (uint32_t)dmax - 1u) / (uint32_t)dmax;
            hom_set_goal(h, i, g, (uint16_t)(v == 0u ? 1u : v));
        }
    }
    hom_enter(h, ST_FINAL);
}

/* Samples to average at a point near the target: enough that the noise of
 * the average (table noise per axis / sqrt n) is at most a seventh of the
 * field change of one tick (a fifth in quick mode: about half the samples,
 * docs/homing.md "Calibration time"); at least 4 and twice avg_samples, at
 * most HOM_MAX_AVG.
 * A weak field (sensors far from the magnet, a high tension where |dB|
 * flattens) needs many; a strong one needs the minimum. */
static uint8_t near_samples(const hom_t *h, int32_t s_q8)
{
    int32_t div = h->mode == HOM_MODE_QUICK ? HOM_NEAR_DIV_QUICK : HOM_NEAR_DIV;
    int32_t q = ((int32_t)h->noise_cuT * div * 256 + s_q8 - 1) / s_q8; /* ceil(div noise / slope) */
    int32_t n = q > 6 ? (int32_t)HOM_MAX_AVG : q * q;
    int32_t lo = 2 * (int32_t)h->cfg.avg_samples;
    if (lo < 4) {
        lo = 4; /* at least 4 near the target, whatever a far point takes */
    }
    if (n < lo) {
        n = lo;
    }
    return (uint8_t)(n > (int32_t)HOM_MAX_AVG ? (int32_t)HOM_MAX_AVG : n);
}

/* Keeps a point averaged near the target for the final fit (the newest
 * HOM_FIT_POINTS). */
static void keep_point(hom_t *h, int32_t p, uint32_t b, uint8_t n)
{
    uint8_t k;
    if (h->n_pts == HOM_FIT_POINTS) {
        for (k = 1; k < HOM_FIT_POINTS; k++) {
            h->pts[k - 1u] = h->pts[k];
        }
        h->n_pts--;
    }
    h->pts[h->n_pts].p = p;
    h->pts[h->n_pts].b = b;
    h->pts[h->n_pts].n = n;
    h->n_pts++;
}

/* The home from a weighted least-squares line through the near points within
 * 4 ticks of p (weights: samples averaged): every sample taken near the
 * target counts, not only the last two points', which matters where one
 * tick is worth little more than the sensor noise. Returns the fitted
 * crossing in 1/256 tick, or `fallback` when fewer than two positions, a
 * non-rising line, or a crossing more than a tick outside the points.
 * 32-bit arithmetic: the crossing does not change when every y is scaled by
 * the same factor, so sums of y beyond what the products below hold in 32
 * bits (|sy| >= 2^21: points 164 uT or more from the target on average) are
 * halved together until they fit; below that the result is exact. */
static int32_t fit_or(const hom_t *h, int32_t p, int32_t fallback)
{
    const hom_tendon_t *t = hom_cur(h);
    /* at most 4 points of at most 32 samples with |x| <= 4: the sums without
     * y fit 16 bits (|sx| <= 512, sxx <= 2048, d < 2^18); with |y| < 2^20
     * the others fit 32; |sy| < 2^21 and |sxy| < 2^23 keep each product of
     * snum below 2^30 */
    int16_t sn = 0;
    int16_t sx = 0;
    int16_t sxx = 0;
    int32_t sy = 0;
    int32_t sxy = 0;
    int32_t d;
    int32_t snum;
    int32_t x_q8;
    int16_t lo = 0;
    int16_t hi = 0;
    uint8_t k;
    for (k = 0; k < h->n_pts; k++) {
        int32_t x = hom_ahead(t, h->pts[k].p, p); /* pull-direction ticks from p */
        int32_t y = (int32_t)h->pts[k].b - (int32_t)t->target_cuT;
        int16_t n = h->pts[k].n;
        int16_t nx;
        if (hom_abs32(x) > 4u || hom_abs32(y) >= (1uL << 20)) {
            continue;
        }
        nx = (int16_t)(n * x);
        lo = x < lo ? (int16_t)x : lo;
        hi = x > hi ? (int16_t)x : hi;
        sn = (int16_t)(sn + n);
        sx = (int16_t)(sx + nx);
        sxx = (int16_t)(sxx + nx * x);
        sy += n * y;
        sxy += nx * y;
    }
    while (hom_abs32(sy) >= (1uL << 21) || hom_abs32(sxy) >= (1uL << 23)) {
        sy /= 2;
        sxy /= 2;
    }
    d = (int32_t)sn * sxx - (int32_t)sx * sx;
    snum = (int32_t)sn * sxy - (int32_t)sx * sy;
    if (hi == lo || d <= 0 || snum <= 0) {
        return fallback;
    }
    /* y = a + s x with s = snum / d; the crossing y = 0 lies at
     * x = (sx - sy d / snum) / sn. A quotient beyond 2^20 puts the crossing
     * far outside the points (|sx * 256| <= 2^17, sn * 5 * 256 < 2^18). */
    x_q8 = hom_muldiv(sy, d * 256, snum);
    if (hom_abs32(x_q8) > (1uL << 20)) {
        return fallback;
    }
    x_q8 = ((int32_t)sx * 256 - x_q8) / sn;
    if (x_q8 < (lo - 1) * 256 || x_q8 > (hi + 1) * 256) {
        return fallback;
    }
    return hom_beyond(t, p * 256, x_q8);
}

/* The home is found: the fit through the near points of p, or `fallback`
 * (1/256 tick); the tendon goes back to slack, and the home is recorded and
 * reported once the field has come back to the baseline there
 * (hom_release_check()). */
HOM_NOINLINE void hom_finish_tendon(hom_t *h, int32_t p, int32_t fallback)
{
    hom_tendon_t *t = hom_cur(h);
    int32_t home_q8;
    if (h->hold != 0u) {
        hom_held_next(h);
        return;
    }
    home_q8 = fit_or(h, p, fallback);
    t->home = hom_floor_div256(home_q8);
    t->home_frac = (int8_t)(home_q8 - t->home * 256);
    h->retake = 0; /* the next tendon's take-up at its own speed */
    h->home_dB = hom_delta_of(h, t->sensor, h->sensor[t->sensor].last);
    hom_release_slack(h, h->cur, 0);
    hom_enter(h, ST_TENDON_RELEASE);
}

/* The current tendon's travel past its engagement where the table's
 * field-travel curve reaches b (the grid inverted, the engagement at the
 * origin), um x 256; -1 past the grid. The curve is of the working targets
 * (work 1: absolute mode's, hom_work_target()) or of the delta targets. */
HOM_NOINLINE int32_t hom_curve_um256(const hom_t *h, uint32_t b, uint8_t work)
{
    /* the delta targets in one read (the learned ones among them: one
     * look at the record), the rest entry by entry where needed */
    uint32_t tgt[TBL_MAX_GRID];
    const hom_tendon_t *t = hom_cur(h);
    uint32_t x0 = 0;
    uint32_t y0 = 0;
    int n = tbl_row(&h->table, h->cur, TBL_ROW_TARGET, tgt);
    uint8_t g;
    for (g = 0; (int)g < n; g++) {
        uint32_t x1 = 0;
        uint32_t y1 = tgt[g];
        if (work && h->amb != NULL) { /* delta mode works with the delta targets */
            uint32_t abs_t = 0;
            (void)tbl_entry(&h->table, h->cur, TBL_ROW_ABS, g, &abs_t);
            y1 = hom_work_target(h, t->sensor, y1, abs_t);
        }
        if (b < y1 && y1 > y0) {
            (void)tbl_entry(&h->table, h->cur, TBL_ROW_TRAVEL, g, &x1);
            if (g != 0u) {
                (void)tbl_entry(&h->table, h->cur, TBL_ROW_TRAVEL, (uint8_t)(g - 1u), &x0);
            }
            return (int32_t)x0 * 256 +
                   hom_muldiv((int32_t)(b - y0), (int32_t)(x1 - x0) * 256, (int32_t)(y1 - y0));
        }
        y0 = y1;
    }
    return -1;
}

/* Distance from field b to the target along the table's curve, 1/256
 * tick; 0 when the table cannot say. The field is not linear in travel (it
 * flattens as the tip moves away), so from a point well short of the
 * target this beats any one slope. */
HOM_NOINLINE static int32_t table_remaining_q8(const hom_t *h, uint32_t b)
{
    const hom_tendon_t *t = hom_cur(h);
    int32_t travel_b = hom_curve_um256(h, b, 1u);
    int32_t travel_t;
    if (travel_b < 0) {
        return 0;
    }
    travel_t =
        hom_per_mille((int32_t)t->travel_ticks * 256, (int32_t)t->nm_per_tick); /* um * 256 */
    if (travel_t <= travel_b) {
        return 0;
    }
    return hom_um_ticks(travel_t - travel_b, t->nm_per_tick);
}

/* A pull starts afresh: no fine points, no floors of the field on its way
 * out, no reference for its rise (one routine for hom_begin_tendon() and
 * hom_back_off()). */
HOM_NOINLINE void hom_pull_afresh(hom_t *h)
{
    /* have_prev, n_pts, far, n_way (the field falls with the release: no
     * floors of the way out), b_pend and ref_b, together in hom_t: one
     * clear instead of a store each */
    memset(&h->have_prev, 0, offsetof(hom_t, ref_b) + sizeof h->ref_b - offsetof(hom_t, have_prev));
}

/* A quarter of the margin is 24 ticks or more (the margin is at least
 * 600 um): behind an engagement recorded up to 16 ticks late, the spool's
 * backlash (5 ticks) and the friction band included, so the pull that comes
 * again is on its pulling branch well before the approach's start (0.8 of
 * the travel past the engagement). The whole margin, as before, cost a
 * re-approach of some 100 ticks more at the moderate speed: about 0.1 s per
 * back-off, which half the proximal tendons of paper_2seg make at 0.8 N
 * (every take-up that ran on to the approach's start). The retake after the
 * bounded pull's limit searches for its engagement again and must start
 * slack, a whole margin short of it (its field-step check counts half the
 * margin from its start). */
void hom_back_off(hom_t *h)
{
    hom_pull_afresh(h);
    hom_release_slack(h, h->cur, h->retake == 1u ? 0 : 2);
    h->state = ST_BACKOFF;
}

/* The field must rise as the tendon is pulled, checked at every fine
 * point. Measured from the last point it rose enough to (an eighth of what
 * the table's slope says), a pull of a sixth of the tendon's travel (at
 * least HOM_FLAT_TICKS) with less rise, four times the noise allowed, ends
 * the run in HOM_F_NO_PROGRESS (a point within the noise allowance of the
 * rise moved the reference too: chaos seed 16518, the field flat at 93 % of
 * the target, 1-tick steps each moved it, 1.53 x the target): the
 * field no longer follows the tendon (chaos seed 9145: the magnet removed
 * left the field flat just below the target, and fine steps of 2 ticks
 * went on 35 points, to 1.64 x the target, before HOM_F_NO_PROGRESS; a
 * tendon far softer than its table, or a target beyond what the robot
 * gives, end here too, before the travel limit). Returns 1 when the run
 * ended, 2 while the field is flat so far (the next fine step is then at
 * most HOM_FLAT_STEP). */
HOM_NOINLINE static int not_following(hom_t *h, const hom_tendon_t *t, int32_t p, uint32_t b)
{
    int32_t d = hom_ahead(t, p, h->ref_p);
    int32_t rise = (int32_t)b + 4 * (int32_t)h->noise_cuT - (int32_t)h->ref_b;
    int32_t span = (int32_t)((uint32_t)t->travel_ticks / 6u); /* travel > 0 */
    if (span < HOM_FLAT_TICKS) {
        span = HOM_FLAT_TICKS;
    }
    /* from a point whose field is a quarter of the target or more (ref_b
     * 0: none yet): just past the engagement the field rises far slower
     * than the table's slope at the target (chaos seed 2010: no_progress 30
     * ms after an engagement), and after a take-up that ran on the detected
     * engagement is early and the re-approach's first points still slack. d * slope_min_q8
     * fits 32 bits while d (within the travel limit) times the slope stays
     * below 2^31 / 256 cuT: 500 ticks at 160 uT a tick, far beyond any
     * table; past it the check errs to no check (a negative product) or to
     * a run ended early */
    uint32_t low = t->target_cuT / 4u; /* the curve's toe: the field rises slowly first */
    if (low < h->engage_cuT) {
        low = h->engage_cuT;
    }
    if (h->ref_b == 0u || b < low ||
        (d > 0 && (int32_t)b - (int32_t)h->ref_b >= ((d * h->slope_min_q8) >> 10))) {
        h->ref_p = p;
        h->ref_b = b < low ? 0u : b;
        return 0;
    }
    if (d < span) {
        return d > 0 ? 2 : 0;
    }
    hom_fail_tendon(h, HOM_F_NO_PROGRESS, rise);
    return 1;
}

/* One averaged fine point at the present position. Finishes by interpolation
 * when the target is bracketed by two points at most 3 ticks apart, or by
 * extrapolation with the local slope when it is less than half a tick away
 * and the point was averaged with the doubled sample count (a slope measured
 * over a wider step overstates the local one, so longer extrapolations are
 * replaced by a one-tick step and a bracket). Otherwise it steps towards the
 * target: the whole predicted distance when it is 3 ticks or less (rounded
 * down, at least one), three quarters of it beyond, so the approach stays on
 * the slack side of the target. A wide overshoot backs off behind the
 * engagement and comes again to the last point known to be short of it. */
void hom_fine_point(hom_t *h)
{
    hom_tendon_t *t = hom_cur(h);
    int32_t avg[3];
    int32_t p = t->present;
    uint32_t b;
    int32_t s_q8;
    int32_t r_q8;
    int32_t step;
    int32_t room;
    int32_t dp;
    uint8_t flat;

    hom_avg_of(h, t->sensor, avg);
    b = hom_meas_of(h, t->sensor, avg);
    dp = h->have_prev ? hom_ahead(t, p, h->p_prev) : 0; /* 0 without a previous point */
    if (h->near) {
        keep_point(h, p, b, h->sensor[t->sensor].n_acc);
    }
    if (b >= t->target_cuT) {
        if (h->have_prev && dp == 0) {
            /* the same position averaged again h->now_ms reads at or past the
             * target: the target is here, within the noise */
            hom_finish_tendon(h, p, p * 256);
            return;
        }
        if (dp >= 1 && dp <= 3 && b > h->b_prev) {
            int32_t f = hom_muldiv((int32_t)(t->target_cuT - h->b_prev), (p - h->p_prev) * 256,
                                   (int32_t)(b - h->b_prev));
            hom_finish_tendon(h, p, h->p_prev * 256 + f);
            return;
        }
        if ((b - t->target_cuT) * 512u < (uint32_t)h->slope_min_q8) {
            /* over by less than half a tick at the floor slope (half the
             * table's, which a field rising ever faster past a wide step
             * beats): the home is extrapolated back to the target below,
             * with the points' own slope. A back-off from a step that landed
             * on the target cost a segment-2 tendon at 1.5 N 2.1 s, and the
             * tendon its timeout (seed 7 of the bench robot). */
            h->near = 1;
        } else {
            if (++t->retries > HOM_MAX_RETRIES) {
                hom_fail_tendon(h, HOM_F_NO_PROGRESS, (int32_t)b);
                return;
            }
            if (h->have_prev) {
                /* the secant across the crossing is the slope to come back with */
                if (dp > 0 && b > h->b_prev) {
                    h->slope_q8 = hom_muldiv((int32_t)(b - h->b_prev), 256, dp);
                }
                h->mod_goal = h->p_prev;
            } else {
                /* scale the travel by how far the field overshot (the take-up can
                 * cross a low target within one sample), then keep a margin */
                h->mod_goal =
                    t->engage +
                    hom_per_mille(hom_muldiv(p - t->engage, (int32_t)t->target_cuT, (int32_t)b),
                                  h->cfg.near_permille);
            }
            hom_back_off(h);
            return;
        }
    }
    flat = (uint8_t)not_following(h, t, p, b);
    if (flat == 1u) {
        return;
    }
    /* a slope measured over 3 ticks or more replaces the estimate; one over
     * fewer ticks is too noisy and the last good one is kept */
    if (dp >= 3 && b > h->b_prev) {
        h->slope_q8 = hom_muldiv((int32_t)(b - h->b_prev), 256, dp);
    }
    s_q8 = h->slope_q8 | 1; /* | 1: never a zero divisor (1/256 cuT per tick) */
    r_q8 = hom_muldiv((int32_t)(t->target_cuT - b), 65536, s_q8);
    if (!h->have_prev && t->retries == 0u) {
        /* first point: the table's own curve says how far the target is */
        int32_t rt = table_remaining_q8(h, b);
        if (rt > 0) {
            r_q8 = rt;
        }
    }
    if (r_q8 < 128 && h->near) {
        hom_finish_tendon(h, p, hom_beyond(t, p * 256, (int32_t)r_q8));
        return;
    }
    room = (t->limit_ticks - hom_ahead(t, p, t->engage)) * 256;
    if (r_q8 > room) {
        /* the target lies beyond the travel limit: unreachable, stop here,
         * once two points in a row say so. One point averaged from samples
         * that lagged its move (a main-loop pass stretched by console
         * output) can read almost no rise: its step goes by the table's
         * slope instead, within the room left: twice the floor, the table's
         * slope within 2/256 cuT a tick (hom_begin_tendon()), read again
         * it cost this pass two table interpolations (1.2 ms of a 4.0 ms
         * pass on the bench). */
        if (h->far) {
            hom_over_limit(h, hom_ahead(t, p, t->engage) + r_q8 / 256);
            return;
        }
        h->far = 1;
        r_q8 = hom_muldiv((int32_t)(t->target_cuT - b), 65536, 2 * h->slope_min_q8);
        if (r_q8 > room) {
            r_q8 = room;
        }
    } else {
        h->far = 0;
        if (s_q8 < h->slope_min_q8) {
            /* A measured slope may read far too low: a point taken where the
             * servo had run past and come back sits on the release branch of
             * the friction hysteresis, high for its position, and the next
             * secant is nearly flat. Its step would be many times the travel
             * (a 76-tick step pulled a 0.3 N tendon to 4.2 x its target). The
             * step goes by no less than half the table's slope, so no step
             * is more than twice what the table predicts. The test above
             * keeps the measured slope: a field that really is flat still
             * ends at the travel limit as before. */
            r_q8 = hom_muldiv((int32_t)(t->target_cuT - b), 65536, h->slope_min_q8);
            if (r_q8 < 128 && h->near) {
                /* by that slope the target is within half a tick: a step
                 * of 0 sent the servo where it stood, point after point,
                 * until the tendon's timeout (chaos seed 13376: a slope
                 * measured across the spool's backlash, 3 cuT per tick) */
                hom_finish_tendon(h, p, hom_beyond(t, p * 256, (int32_t)r_q8));
                return;
            }
        }
    }
    if (++h->steps > h->cfg.fine_max_steps) {
        hom_fail_tendon(h, HOM_F_NO_PROGRESS, (int32_t)b);
        return;
    }
    step = r_q8 <= 3 * 256 ? r_q8 >> 8 : (r_q8 / 4 * 3) >> 8;
    if (r_q8 >= 128 && step < 1) {
        step = 1; /* half a tick or more: bracket it rather than extrapolate */
    }
    h->near = (uint8_t)(r_q8 <= 4 * 256);
    h->n_near = near_samples(h, s_q8); /* as measured: a flat slope asks for many */
    if (flat && step > HOM_FLAT_STEP) {
        step = HOM_FLAT_STEP; /* a field that stopped following: pull on slowly */
    }
    if (step > t->limit_ticks + 1) {
        step = t->limit_ticks + 1; /* refused below as beyond the limit */
    }
    h->p_prev = p;
    h->b_prev = b;
    h->have_prev = 1;
    if (hom_pull_to(h, hom_beyond(t, p, (int32_t)step), h->cfg.v_fine) == 0) {
        hom_enter(h, ST_FINE_MOVE);
    }
}
