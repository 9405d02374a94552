/*
 * hom_priv: what the files of the homing module share and nobody else may
 * use (the public API is homing.h). The state machine is split by phase,
 * one room per concern.
 *
 * - homing.c: the public API (step, events, results) and the helpers
 *   every phase uses: goals, arrival, averages, norms, 32-bit muldiv.
 * - hom_setup.c: a run's set-up: hom_start(), each sensor's and tendon's
 *   part of the table loaded in the preflight, fresh engagement windows.
 * - hom_fault.c: faults: ending a run with every tendon released, the
 *   health checks of sensors and servos each step, fault names.
 * - hom_slack.c: preflight, the release of every tendon, the slack check
 *   and baseline, and the release check after each home.
 * - hom_approach.c: one tendon's take-up to engagement and the moderate
 *   approach, the travel limit, the per-step dispatch of a tendon.
 * - hom_fine.c: the fine approach to the target (table curve, measured
 *   slope, averaged points), the least-squares home and the final move.
 *
 * Everything declared here is internal: names carry the hom_ prefix only to
 * keep the firmware's global namespace clean.
 */
#ifndef HALLHOME_HOM_PRIV_H
#define HALLHOME_HOM_PRIV_H

#include <stdint.h>

#include "homing/homing.h"

enum {
    ST_IDLE = 0,
    ST_PREFLIGHT,
    ST_RELEASE_ALL, /* moving every tendon to its release goal */
    ST_SLACK_AVG,   /* settle, then average every sensor */
    ST_TENDON_START,
    ST_TAKEUP,   /* fast (then moderate) search for engagement */
    ST_MODERATE, /* engagement to near the target */
    ST_FINE_MOVE,
    ST_FINE_AVG,
    ST_BACKOFF, /* overshot on the first fine point: back to slack, re-approach */
    ST_TENDON_RELEASE,
    ST_FINAL,
    ST_DONE,
    ST_FAULT
};

/* Functions that measured smaller on the AVR as calls than inlined (each
 * inlined copy of 32-bit arithmetic costs more than the call). The health
 * checks, the fit, the straight-pose shift, the table set-up step, the
 * release check and the near-target test measured smaller without it, and
 * have no HOM_NOINLINE. */
#if defined(__GNUC__)
#define HOM_NOINLINE __attribute__((noinline))
#else
#define HOM_NOINLINE
#endif

#define HOM_MAX_AVG 32u
/* a near point averages until its noise is at most 1/HOM_NEAR_DIV of one
 * tick's field change (hom_fine.c, near_samples()); a quick re-home trades
 * some of that for time, 1/HOM_NEAR_DIV_QUICK: about half the samples, its
 * homes as close to the target tension on the bench (docs/homing.md,
 * "Calibration time") */
#define HOM_NEAR_DIV            7
#define HOM_NEAR_DIV_QUICK      5
#define HOM_QUICK_STOP_PERMILLE 975u /* quick leg: stop when the field is this close */
#define HOM_MAX_RETRIES                                                                            \
    3u                        /* back-offs of one tendon before HOM_F_NO_PROGRESS:                 \
                                 a take-up that ran on, then two overshoots */
#define HOM_RUN_ON_TICKS 1    /* a servo standing further past its goal ran on */
#define HOM_DROOP_TICKS  8    /* a servo stopped this close counts as arrived ... */
#define HOM_STILL_MS     100u /* ... after this long without motion */
/* a servo's moved_ms is kept at most this old (hom_check_servos()): every
 * use compares hom_still_ms() with far less, and its 16-bit difference
 * never wraps */
#define HOM_STILL_CAP_MS 30000u
#define HOM_SAMPLE_AGE_MS                                                                          \
    20u /* a sample reaches the homing up to 16 ms after it was measured (docs/homing.md,          \
           "Engagement"): a servo standing this long stood when every later one was taken */
#define HOM_FIT_POINTS 4u /* near points kept for the final fit (hom_t.pts) */
#define HOM_FLAT_TICKS                                                                                 \
    12                  /* fine: the least pull the field may stay flat over before it no longer       \
                           follows the tendon: a point after the servo ran past its goal and came back \
                           reads flat through the spool's backlash (5 ticks on the bench) and the      \
                           friction band: 10 ticks measured at the lowest grid tension */
#define HOM_FLAT_STEP 4 /* fine: the longest step while the field is flat */

/* ---- homing.c: API and shared helpers ---- */
void hom_push_event(hom_t *h, uint8_t type, uint8_t code, uint8_t index, int32_t a, int32_t b);
/* HOM_EV_PHASE code (HOM_PH_*) for index */
void hom_phase_event(hom_t *h, uint8_t code, uint8_t index);
void hom_done(hom_t *h);
int32_t hom_muldiv(int32_t a, int32_t b, int32_t c);
/* |v| as unsigned: INT32_MIN gives 2^31, no overflow */
uint32_t hom_abs32(int32_t v);
/* um on a spool of nm_per_tick as ticks, truncated towards zero */
int32_t hom_um_ticks(int32_t um, uint32_t nm_per_tick);
/* a * permille / 1000, truncated towards zero */
int32_t hom_per_mille(int32_t a, int32_t permille);
int32_t hom_um_to_ticks(uint32_t um, uint32_t nm_per_tick);
void hom_over_limit(hom_t *h, int32_t d);
int32_t hom_curve_um256(const hom_t *h, uint32_t b, uint8_t work);
int32_t hom_unwrap_home(int32_t stored, int32_t present);
uint32_t hom_work_target(const hom_t *h, uint8_t k, uint32_t d, uint32_t abs_t);
void hom_work_point(const hom_t *h, uint8_t i, uint16_t mN, tbl_point_t *pt);
int32_t hom_pull(const hom_tendon_t *t, int32_t d);
/* the position d ticks past p in t's pull direction: p + hom_pull(t, d) */
int32_t hom_beyond(const hom_tendon_t *t, int32_t p, int32_t d);
/* how far x lies past `from` in t's pull direction: hom_pull(t, x - from) */
int32_t hom_ahead(const hom_tendon_t *t, int32_t x, int32_t from);
/* The engagement window around p: ahead ticks ahead of it in the pull
 * direction dir, behind ticks behind it. */
void hom_window_around(int8_t dir, int32_t ahead, int32_t behind, int32_t p, int32_t *lo,
                       int32_t *hi);
uint32_t hom_since(const hom_t *h, uint32_t t);
/* ms since a 16-bit stamp (the low 16 bits of now_ms when it was taken) */
uint16_t hom_since16(const hom_t *h, uint16_t t);
void hom_set_goal(hom_t *h, uint8_t i, int32_t goal, uint16_t vel);
/* tendon i's goal g at v_release, or where it stands if that is further back */
void hom_release_to(hom_t *h, uint8_t i, int32_t g);
/* tendon i's goal at v_release: the slack margin >> shift behind its engagement */
void hom_release_slack(hom_t *h, uint8_t i, uint8_t shift);
int hom_reached(const hom_t *h, uint8_t i);
void hom_start_avg(hom_t *h);
void hom_avg_of(const hom_t *h, uint8_t k, int32_t out[3]);
uint32_t hom_delta_of(const hom_t *h, uint8_t k, const int32_t b[3]);
uint32_t hom_meas_of(const hom_t *h, uint8_t k, const int32_t b[3]);
int32_t hom_floor_div256(int32_t q8);
/* Straight-pose home minus home of tendon t, ticks (hom_to_straight()). */
int16_t hom_straight_ticks(const hom_tendon_t *t);
int32_t hom_further_back(const hom_tendon_t *t, int32_t g, int32_t x);
int32_t hom_um_ticks_cur(const hom_t *h, uint8_t i, uint32_t um);
uint8_t hom_next_tendon(const hom_t *h, uint8_t from);
int hom_move_done(hom_t *h, int arrived, uint8_t dev, uint8_t index);
uint16_t hom_bit(uint8_t i);
uint8_t hom_has(uint16_t m, uint8_t i);
/* the tendon being calibrated */
hom_tendon_t *hom_cur(const hom_t *h);
/* ms since tendon i's goal was last set or its servo last moved */
uint32_t hom_still_ms(const hom_t *h, uint8_t i);
/* ms since the current state was entered (hom_enter()) */
uint32_t hom_phase_ms(const hom_t *h);
/* Enters state (ST_*) now: the phase's waits and timeouts count from this
 * step, and its steps (hom_t.settled) start again. */
void hom_enter(hom_t *h, uint8_t state);

/* ---- hom_setup.c: a run's set-up from the table ---- */
/* One piece of the run's table set-up (preflight); 1 once all is loaded. */
int hom_load_step(hom_t *h);
/* A travel limit past the engagement for a pull of at most um (hom_setup.c
 * says which bounds apply). */
int32_t hom_limit_ticks(const tbl_tendon_head_t *row, int32_t um);
/* The table's straight-pose shift (um of take-up paid out) as a position
 * change of tendon t, 1/256 tick in the tick frame. */
int32_t hom_straight_q8(const hom_tendon_t *t, int16_t straight_um);

/* ---- hom_fault.c: faults and health checks ---- */
void hom_fail(hom_t *h, hom_fault_t f, uint8_t dev, uint8_t index, int32_t detail);
void hom_fail_tendon(hom_t *h, hom_fault_t f, int32_t detail);
void hom_finish_tendon(hom_t *h, int32_t p, int32_t fallback);
int hom_check_sensors(hom_t *h, const hom_in_t *in);
int hom_check_servos(hom_t *h, const hom_in_t *in);

/* ---- hom_slack.c: preflight, release, slack check, baseline ---- */
void hom_do_preflight(hom_t *h, const hom_in_t *in);
void hom_release_check(hom_t *h);
void hom_do_slack_avg(hom_t *h);
/* Held pull (hom_cmd_t.hold): a scan or the held tendon's pull has ended;
 * on to the next phase (hom_t.held). */
void hom_held_next(hom_t *h);

/* ---- hom_approach.c: take-up and approach ---- */
void hom_begin_tendon(hom_t *h, uint8_t i);
int hom_pull_to(hom_t *h, int32_t g, uint16_t v);
void hom_do_tendon(hom_t *h, const hom_in_t *in);

/* ---- hom_fine.c: fine approach, fit, final move ---- */
int32_t hom_table_slope(const hom_t *h, uint8_t i);
void hom_begin_final(hom_t *h);
void hom_fine_point(hom_t *h);
/* Back behind the engagement, a quarter of the slack margin (the bounded
 * pull's retake: the whole margin, to slack); the approach comes again to
 * h->mod_goal from there, on the pulling side of the path's friction and the
 * spool's backlash. */
void hom_back_off(hom_t *h);
void hom_pull_afresh(hom_t *h);

#endif /* HALLHOME_HOM_PRIV_H */
