/*
 * homing: the tension calibration as a non-blocking state machine.
 *
 * Pure logic: it never calls a driver. Each main-loop pass the application
 * fills a hom_in_t (time, every sensor's newest raw sample, every servo's
 * present position and health), calls hom_step(), writes the goals the
 * returned hom_out_t marks as changed to the servos, and drains events with
 * hom_event_pop() for the console. The same code runs on the AVR, in native
 * tests against the plant model and in the virtual bench.
 *
 * Field interface (decided here): the application passes RAW 3-axis samples
 * per sensor in cuT (int32, one AK09916 LSB = 15 cuT) with a status saying
 * whether the sample is new. The machine captures its own straight-pose
 * baseline B0 (the two agreeing averages of the slack check, every tendon
 * slack) and computes |B - B0| with 32-bit integer arithmetic.
 *
 * Sequence (full calibration; docs/homing.md has the state diagram):
 *   1. preflight: every servo and sensor of the table must answer and be
 *      healthy before any motion; otherwise one HOM_EV_MISSING per faulty
 *      device, then HOM_F_PREFLIGHT, and nothing moves.
 *   2. release every tendon, then confirm slack: release further in steps
 *      until no sensor's field changes (bounded, HOM_F_SLACK).
 *   3. capture each sensor's baseline B0 (and check the magnet is there when
 *      the table predicts its straight-pose field: HOM_F_MAGNET_MISSING).
 *   4. per tendon, the others slack: fast take-up until |B - B0| on its
 *      selected sensor rises above the engagement threshold; moderate speed
 *      to a fraction of the expected travel; fine steps that stop, settle,
 *      average (more samples near the target, as the noise requires), and
 *      use the table's curve, then the locally measured slope, to predict
 *      the target; always moving in the pull direction so backlash and
 *      friction sit on the same side every time; the home is the crossing of
 *      a least-squares line through the points near the target (sub-tick,
 *      then rounded); release the tendon. A wide overshoot backs off behind
 *      the engagement and comes again.
 *   5. move every tendon to its home together, profile velocities scaled by
 *      distance so they arrive together; HOM_EV_DONE.
 * Modes: HOM_MODE_FULL; HOM_MODE_QUICK after a power cycle, from stored homes
 * (stored homes moved into the new encoder frame, whole turns being lost;
 * small release; fast take-up to just short of the stored home);
 * HOM_MODE_SINGLE (one tendon); HOM_MODE_DRY (preflight, baseline, targets
 * reported, no motion).
 * Target modes (hom_cmd_t.ambient_cuT): delta, |B - B0| against the table's
 * target_cuT (default); absolute, the paper's |B - A| against abs_target_cuT
 * with a caller-stored ambient offset A (docs/homing.md, "Target modes").
 *
 * Release (decided here): a release is a position move of the servo to a
 * point a known slack margin beyond the tendon's engagement in the release
 * direction, at the release velocity, torque kept on: the tendon is slack,
 * the shaft stays where it was put, and the next take-up starts from a known
 * place. Torque off would also slacken the tendon on an XL430, but leaves the
 * spool free to drift.
 *
 * Safety: a travel limit counted from engagement (a target predicted or a
 * goal beyond it is refused; being beyond it aborts), a time limit per tendon, a field-rate check
 * and sensor saturation abort, as do a sensor that stops answering and a servo that times out or
 * reports a hardware error. Every abort (hom_abort() or a fault) writes release goals for every
 * tendon in the very step call that detects it, so the application sends them within one main-loop
 * pass.
 *
 * Return convention: hom_step() returns HOM_RUNNING (positive) while a
 * calibration runs, 0 when idle or finished, and -(hom_fault_t) once a run
 * has ended in a fault (until the next hom_start()). hom_start() returns 0 or
 * a negative HOM_E_* code.
 *
 * Integer arithmetic only (the AVR has no FPU); per step the work is bounded
 * by the number of tendons and sensors; no 64-bit type anywhere. One 32-bit
 * integer square root per new sample of the selected sensor, a few 32-bit
 * multiply-divides per fine point. The table must stay readable (and its
 * copy function valid) until the run ends: the magnet check, the start of
 * each tendon and the fine approach read it.
 */
#ifndef HALLHOME_HOMING_H
#define HALLHOME_HOMING_H

#include <stdint.h>

#include "dxl/dxl_xl430_reg.h"
#include "table/table.h"

#define HOM_RUNNING 1
#define HOM_EV_CAP  12u /* event queue capacity */
/* Events carry the time of their step (hom_event_t.t_ms) unless this is 0:
 * the firmware, whose reports do not print it, keeps 4 bytes per queued
 * event (48 bytes of RAM) by building with -DHOM_EV_TIME=0. */
#ifndef HOM_EV_TIME
#define HOM_EV_TIME 1
#endif
/* Sensors a run can use (the table format allows TBL_MAX_SENSORS): state is
 * kept per sensor, and the firmware's RAM is sized for this many (4, or a
 * robot's table's fewer: the Makefile passes -DHOM_MAX_SENSORS=n). A table
 * with more is refused by hom_start() (HOM_E_TABLE). */
#ifndef HOM_MAX_SENSORS
#define HOM_MAX_SENSORS 4u
#endif
/* Tendons a run can use: the table format allows TBL_MAX_TENDONS, and state
 * is kept per tendon. A firmware built for one robot sizes it to that robot's
 * table (-DHOM_MAX_TENDONS=n; the Makefile reads n from the table). A table
 * with more is refused by hom_start() (HOM_E_TABLE). */
#ifndef HOM_MAX_TENDONS
#define HOM_MAX_TENDONS TBL_MAX_TENDONS
#endif
#define HOM_WAY_PTS   4u /* floors of the field kept on a pull's way out (hom_approach.c) */
#define HOM_WAY_SHIFT 4u /* kept in units of 16 cuT: up to 10.4 mT */

/* hom_start() errors (numbered apart from the -(hom_fault_t) that hom_step()
 * returns, so the two never collide) */
enum {
    HOM_E_ARG = -101,     /* NULL pointer, unknown mode, tendon index beyond the table */
    HOM_E_TABLE = -102,   /* the table fails tbl_check(), or has more than HOM_MAX_SENSORS or
                             HOM_MAX_TENDONS */
    HOM_E_TENSION = -103, /* tension outside the table's grid */
    HOM_E_BUSY = -104,    /* a calibration is running: abort it first */
    HOM_E_HOMES = -105    /* quick re-home without a stored home for every tendon */
};

typedef enum {
    HOM_MODE_FULL = 0,
    HOM_MODE_QUICK = 1,
    HOM_MODE_SINGLE = 2,
    HOM_MODE_DRY = 3
} hom_mode_t;

/* Why a run ended in a fault, declared once: the enum (HOM_F_<ID>), the
 * console words hom_fault_name() returns, and HOM_FAULT_WORDS (the words in
 * enum order separated by spaces, which the firmware keeps in flash) all
 * come from this list. */
#define HOM_FAULTS(X)                                                                              \
    X(NONE, "none")                                                                                \
    X(ABORTED, "aborted")               /* hom_abort(): button long press, '!' */                  \
    X(PREFLIGHT, "preflight")           /* devices missing or faulty before motion */              \
    X(SENSOR_TIMEOUT, "sensor_timeout") /* a sensor gave no sample for sensor_timeout_ms */        \
    X(SENSOR_ERROR, "sensor_error")     /* a sensor reported read errors 3 times in a row */       \
    X(SATURATED, "saturated")           /* a sensor overflowed (HOFL) or read beyond sat_cuT */    \
    X(FIELD_RATE, "field_rate")         /* a field jumped more than rate_limit_cuT per sample */   \
    X(SERVO_TIMEOUT, "servo_timeout")   /* a servo did not answer for servo_timeout_ms */          \
    X(SERVO_ERROR, "servo_error")       /* a servo reported a hardware error */                    \
    X(SERVO_STALL, "servo_stall")       /* a servo did not reach its goal in time */               \
    X(TRAVEL_LIMIT, "travel_limit")     /* the target lies beyond the travel limit */              \
    X(NO_ENGAGEMENT, "no_engagement")   /* no field change within the take-up search */            \
    X(NO_PROGRESS, "no_progress")       /* the field does not rise towards the target */           \
    X(TENDON_TIMEOUT, "tendon_timeout") /* one tendon took longer than tendon_timeout_ms */        \
    X(SLACK, "slack")                   /* the field kept changing while releasing */              \
    X(MAGNET_MISSING, "magnet_missing") /* baseline far below the straight-pose prediction */      \
    X(FIELD_STEP, "field_step")         /* released after its home, the tendon did not bring the   \
                                           field back to the baseline: a magnet, sensor or iron    \
                                           moved (the home is not recorded) */

typedef enum {
#define HOM_FAULT_ENUM(id, word) HOM_F_##id,
    HOM_FAULTS(HOM_FAULT_ENUM)
#undef HOM_FAULT_ENUM
        HOM_F_COUNT
} hom_fault_t;

#define HOM_FAULT_WORD(id, word) word " "
#define HOM_FAULT_WORDS          HOM_FAULTS(HOM_FAULT_WORD)

/* Device kinds named in events. */
enum { HOM_DEV_NONE = 0, HOM_DEV_SENSOR = 1, HOM_DEV_SERVO = 2, HOM_DEV_TENDON = 3 };

/* Phases reported by HOM_EV_PHASE (code). */
enum {
    HOM_PH_PREFLIGHT = 1,
    HOM_PH_RELEASE,
    HOM_PH_BASELINE,
    HOM_PH_TENDON, /* index = tendon */
    HOM_PH_FINAL,
    HOM_PH_HOLD /* held pull: index = the held tendon, a = where it stands (ticks) */
};

/* Event types. Fields: index = tendon, sensor or servo (tendon index) as the
 * type says; a and b carry numbers. */
enum {
    HOM_EV_START = 1, /* code = mode, a = tension mN */
    HOM_EV_PHASE,     /* code = HOM_PH_*, index = tendon for HOM_PH_TENDON */
    HOM_EV_MISSING,   /* code = HOM_DEV_*, index = sensor or tendon, a = 1 absent / 2 no
                         answer / 3 error or overflow / 4 servo hardware error, b = error bits */
    HOM_EV_ENGAGED,   /* index = tendon, a = engagement position (ticks) */
    HOM_EV_HOME,      /* index = tendon, a = home (ticks), b = interpolated home in 1/256 tick
                         minus a * 256 (sub-tick residue) */
    HOM_EV_TARGET,    /* dry run: index = tendon, a = target cuT, b = travel um */
    HOM_EV_DONE,      /* a = run time ms */
    HOM_EV_FAULT,     /* code = hom_fault_t, index = device index, a = HOM_DEV_*, b = detail */
    HOM_EV_RELEASED   /* release goals sent to every tendon after a fault, a = fault */
};

typedef struct {
#if HOM_EV_TIME
    uint32_t t_ms;
#endif
    uint8_t type;
    uint8_t code;
    uint8_t index;
    int32_t a;
    int32_t b;
} hom_event_t;

/* Sensor status for one step. */
enum {
    HOM_SENS_NONE = 0, /* no new sample since the last step */
    HOM_SENS_NEW,      /* b_cuT holds a new sample */
    HOM_SENS_ERROR,    /* the read failed (no answer, bus error) */
    HOM_SENS_OVERFLOW, /* new sample with the HOFL flag: saturated */
    HOM_SENS_ABSENT    /* not found by the application's probe (WHO_AM_I) */
};

/* Servo status for one step. */
enum {
    HOM_SERVO_OK = 0,  /* answered this step; pos and hw_error are fresh */
    HOM_SERVO_NOREPLY, /* no answer this step */
    HOM_SERVO_ABSENT   /* not found by the application's probe (ping) */
};

typedef struct {
    uint8_t status;   /* HOM_SENS_* */
    int32_t b_cuT[3]; /* raw field, cuT, sensor frame */
    uint8_t age_q;    /* how long before this step it was measured, quarter ms (icm_clock.h) */
} hom_sensor_in_t;

typedef struct {
    uint8_t status;   /* HOM_SERVO_* */
    uint8_t hw_error; /* XL430 Hardware Error Status (address 70); nonzero = fault */
    int32_t pos;      /* Present Position, ticks */
} hom_servo_in_t;

/* Inputs of one step, indexed like the table's tendons and sensors. */
typedef struct {
    hom_sensor_in_t sensor[HOM_MAX_SENSORS];
    hom_servo_in_t servo[HOM_MAX_TENDONS];
    uint32_t now_ms; /* last: each servo's fields stay within the first 64 bytes, which the
                        AVR reaches through the struct's pointer with one instruction a byte */
} hom_in_t;

/* Outputs: the commanded state of every tendon's servo. The application
 * writes goal, profile velocity, the profile acceleration and torque of
 * tendon i when bit i of `changed` is set (it may write all of them every
 * step). */
typedef struct {
    int32_t goal[HOM_MAX_TENDONS]; /* Goal Position, ticks */
    uint16_t vel[HOM_MAX_TENDONS]; /* Profile Velocity, 0.229 rpm units */
    uint16_t acc; /* Profile Acceleration of every move of the run (hom_config_t.acc),
                     214.577 rev/min^2 units */
    uint8_t torque[HOM_MAX_TENDONS]; /* Torque Enable */
    uint16_t changed;                /* bit i: tendon i changed in this step */
} hom_out_t;

/* Tunables. hom_config_default() explains the defaults (docs/homing.md). */
#define HOM_SLACK_MARGIN_UM 600u /* hom_config_t.slack_margin_um by default */
/* hom_config_t.initial_release_um by default: from the table */
#define HOM_INITIAL_RELEASE_UM 0u
/* hom_config_t.v_release and v_final by default: the servo's top speed */
#define HOM_V_TOP DXL_XL430_VELOCITY_LIMIT_DEFAULT
/* hom_config_t.acc by default: the servo's maximum (the app's own moves use
 * it and HOM_V_TOP without a hom_config_t) */
#define HOM_ACC_DEFAULT 0u
/* Every stop releases every tendon within 100 ms (docs/app.md), and a tendon
 * is slack only once its spool is back at its engagement: so no tendon is
 * pulled further past its (detected) engagement than HOM_V_TOP unwinds in
 * HOM_RELEASE_REACH_MS, whatever the table's travel limit. The other 15 ms
 * cover the pass that sees the stop, the goals' sync write and an
 * engagement detected a few ticks late. 265 units x 0.229 rpm x 4096 ticks
 * per turn = 4.14 ticks per ms: 352 ticks, 2.16 mm at 6136 nm/tick. The
 * host's table generator reads this figure (hallhome/usable.py), so it is a
 * number here; homing.c checks it against the speed and the time. */
#define HOM_RELEASE_REACH_MS    85L
#define HOM_RELEASE_REACH_TICKS 352L

/* The bounded pull (docs/homing.md): a tendon's true tension stays below
 * 1.25 x the run's tension + HOM_BOUND_MN before its home is recorded.
 * Besides the field's own checks, the homing never pulls further past the
 * engagement than the table's travel at that tension. */
#define HOM_BOUND_MN 100u
/* The table's travel is taken a sixteenth short: a robot may be
 * stiffer than its table says. The bench's plant is 2-4 % stiffer than the
 * host's model of the chaos pool's robots at that travel, and the path's
 * friction adds about 2 % while pulling; at the full travel an ambient step
 * took chaos seeds 13456, 19952 and 19346 to 1.39-1.45 x at 0.8 N. */
#define HOM_BOUND_SHORT 16u
/* Held pull (hom_cmd_t.hold): the bend of the held tendon moves the pulled
 * tendon's engagement earlier (by its routing radius times the bend), so
 * every tendon but the held one starts this much further back. */
#define HOM_HELD_BACK_UM 1500u
/* Held pull: the pulled tendon's engagement is crossed twice, alone and
 * held, each in the same steps (a scan): from HOM_SCAN_BACK ticks behind the
 * engagement its take-up detected (HOM_SCAN_BACK_HELD held), HOM_SCAN_STEP
 * ticks a step (twice that while the field is flat), each point standing for
 * HOM_SCAN_SAMPLES samples of its sensor (streamed: the host averages them),
 * to HOM_SCAN_AHEAD past the first point whose field reached the engagement
 * threshold (HOM_SCAN_POINTS points at most): the engagement is then found
 * within a fraction of a tick, as the bench's stepped pulls find it (single
 * samples at the survey's speed moved it by a tick run to run). Both
 * crossings come from slack, on the pulling side of the spool's backlash and
 * the path's friction, so what they leave in the kink cancels in the shift.
 * The scan ends early once its field reaches half the target: the held
 * tendon carries the pulled one's pull. */
#define HOM_SCAN_BACK      32
#define HOM_SCAN_BACK_HELD 56
#define HOM_SCAN_AHEAD     24
#define HOM_SCAN_STEP      2
#define HOM_SCAN_SAMPLES   8u
#define HOM_SCAN_POINTS    56u

typedef struct {
    uint16_t v_fast;             /* take-up before engagement, 0.229 rpm units */
    uint16_t v_moderate;         /* engagement to near the target */
    uint16_t v_fine;             /* fine steps */
    uint16_t v_release;          /* releases and aborts */
    uint16_t v_final;            /* final move to the homes (the longest move) */
    uint16_t acc;                /* profile acceleration for every move (0 = the servo's maximum) */
    uint16_t slack_margin_um;    /* release this far beyond engagement */
    uint16_t slack_step_um;      /* slack check: further release per step */
    uint8_t slack_max_steps;     /* slack check: steps before HOM_F_SLACK */
    uint8_t baseline_samples;    /* per slack-check average, B0 takes two (1..32, else 32) */
    uint8_t avg_samples;         /* per fine point, more near the target (1..16, else 16) */
    uint8_t fine_max_steps;      /* fine points before HOM_F_NO_PROGRESS */
    uint8_t takeup_per_tick;     /* take-up speed per tick of expected travel (at most v_fast) */
    uint16_t near_permille;      /* moderate approach stops at this fraction of the target */
    uint16_t settle_ms;          /* wait after a fine move before sampling */
    uint16_t preflight_ms;       /* time for every device to answer */
    uint16_t sensor_timeout_ms;  /* no sample for this long: HOM_F_SENSOR_TIMEOUT */
    uint16_t servo_timeout_ms;   /* no answer for this long: HOM_F_SERVO_TIMEOUT */
    uint16_t move_timeout_ms;    /* a release / final move longer than this: HOM_F_SERVO_STALL */
    uint16_t tendon_timeout_ms;  /* one tendon longer than this (twice, once it backed off to
                                    slack): HOM_F_TENDON_TIMEOUT */
    uint32_t engage_min_cuT;     /* engagement threshold floor (raised to 8x table noise, at most
                                    a quarter of the smallest target) */
    uint32_t rate_limit_cuT;     /* largest plausible change of one axis between two samples */
    uint32_t sat_cuT;            /* an axis at or beyond this reads as saturated */
    uint32_t max_takeup_um;      /* engagement search: the most slack a tendon may start with (the
                                    search adds what the run itself released) */
    uint32_t initial_release_um; /* first release when positions are unknown (0 = from table) */
    uint8_t straight;            /* final move to the straight-pose homes (1), or to the
                                    single-tendon homes (0, the paper's definition) */
} hom_config_t;

typedef struct {
    int8_t dir;          /* table pull_dir */
    uint8_t sensor;      /* selected sensor */
    uint8_t engaged;     /* engage is valid */
    uint8_t have_home;   /* home is valid (this run or stored, for the final move) */
    uint8_t retries;     /* re-approaches after overshooting the target */
    int8_t abs_sign;     /* absolute mode: +1 when |B| rises towards the target, -1 falls */
    uint32_t target_cuT; /* |B - B0| target at the requested tension; absolute mode:
                            ||B_magnet(p_T)| - |b_straight|| (see hom_cmd_t) */
    /* the take-up figures in ticks, at most INT16_MAX (load_tendon()); each
     * is widened to 32 bits before arithmetic that could leave 16 */
    int16_t travel_ticks; /* expected take-up from engagement */
    int16_t limit_ticks;  /* travel limit from engagement (at most HOM_RELEASE_REACH_TICKS) */
    int16_t margin_ticks; /* slack margin */
    uint16_t nm_per_tick; /* table spool factor (the table's own width) */
    int32_t engage;       /* engagement position, ticks */
    int32_t home;         /* home, ticks */
    int32_t est_home;     /* quick mode: stored home in this power cycle's frame */
    int32_t eng_lo;       /* engagement window (see hom_cmd_t.win_*): lowest and highest */
    int32_t eng_hi;       /* position, in the pull direction, the engagement may lie at */
    /* the servo's state and commands, here rather than in arrays of hom_t
     * (hom_step() copies the commands into its hom_out_t): reached through
     * the tendon's pointer, each field takes one instruction a byte on the
     * AVR (the first 64 bytes of a struct; the fields after moved_ms are
     * seldom used) */
    int32_t present; /* Present Position, ticks */
    int32_t goal;    /* Goal Position last commanded, ticks */
    uint16_t vel;    /* its Profile Velocity, 0.229 rpm units */
    /* ms, low 16 bits, compared as 16-bit differences (hom_since16()) */
    uint16_t servo_ok_ms;   /* its last answer (checked every step against servo_timeout_ms) */
    uint16_t moved_ms;      /* last goal written or change of the present position (kept at
                               most HOM_STILL_CAP_MS old) */
    uint8_t torque;         /* Torque Enable */
    uint16_t release_ticks; /* the release that frees this tendon of unknown state */
    int16_t to_straight;    /* the table's straight-pose shift at the run's tension as a
                               position change, ticks rounded to nearest ... */
    int8_t straight_frac;   /* ... and what the rounding left (1/256 tick, -128..127) */
    int8_t home_frac;       /* what rounding a measured home left (1/256 tick) */
} hom_tendon_t;

typedef struct {
    int32_t b0[3];    /* straight-pose baseline, cuT (the slack check: its previous average) */
    int32_t last[3];  /* newest sample */
    int32_t acc[3];   /* running sum for averages */
    uint16_t last_ms; /* time of the newest sample, ms (low 16 bits: hom_check_sensors()
                         compares it every step, a 16-bit difference) */
    uint8_t n_acc;    /* samples in acc */
    uint8_t have_last;
    uint8_t err_run; /* consecutive read errors */
    uint32_t p0;     /* absolute mode: the table's straight-pose |B| */
} hom_sensor_t;

/* Caller-owned state. Read-only for the application except through the
 * functions below; tendon[i].home / have_home hold the results. The fields
 * used in every step come first: the AVR reaches the first 64 bytes of a
 * struct without address arithmetic. */
typedef struct {
    uint8_t state;
    uint8_t mode;
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t single; /* HOM_MODE_SINGLE: the tendon */
    uint8_t cur;    /* tendon being calibrated */
    uint8_t moved;  /* motion has been commanded in this run */
    uint8_t abort_req;
    uint8_t fault; /* hom_fault_t of the last run */
    uint8_t fault_index;
    uint8_t fault_dev;
    uint8_t steps;       /* slack-check steps or fine points so far */
    uint8_t settled;     /* slack average: settle time over, averaging; after a home: the
                            steps until the next tendon begins (3, 4) */
    uint8_t pf_started;  /* preflight: first step seen, t_phase valid; then 1 + the
                            sensors and tendons of the table loaded (hom_load_step()) */
    uint8_t quick_leg;   /* quick mode: fast leg to just before the expected engagement */
    uint8_t near;        /* fine: the next point is within a few ticks of the target */
    uint8_t n_near;      /* fine: samples to average at a near point */
    uint8_t retake;      /* the current tendon reached its bounded pull's limit: 1 backing off
                            to search its engagement again, 2 searching slowly (hom_over_limit()) */
    uint8_t b_low;       /* pull: samples in a row below the field's floor by more than the
                            tolerance */
    uint8_t read_gap_ms; /* the current servo's last gap between two position reads */
    uint8_t ev_head;
    uint8_t ev_count;
    uint8_t ev_dropped;
    /* a pull's state that starts afresh with it (hom_pull_afresh() clears it
     * at once: keep it together, have_prev first, ref_b last) */
    uint8_t have_prev; /* fine: a previous point below the target exists */
    uint8_t n_pts;     /* fine: near points kept */
    uint8_t far;       /* fine: the last point put the target beyond the travel limit */
    uint8_t n_way;     /* pull: floors kept in way_q/way_b since the engagement or the last
                          back-off */
    uint32_t b_pend;   /* pull: the last sample since the last position read, judged there */
    uint32_t ref_b; /* fine: the |dB| of the point ref_p: the last one the field rose enough to */
    uint16_t win_changed;  /* bit i: tendon i's engagement window changed (hom_window()) */
    uint16_t win_known;    /* bit i: tendon i's window is set */
    uint32_t now_ms;       /* time of the current step */
    uint32_t t_phase;      /* start of the current wait */
    uint32_t t_tendon;     /* start of the current tendon */
    int32_t pos_at_sample; /* active tendon's position when its last sample below the
                              engagement threshold was measured */
    int32_t takeup_from;   /* active tendon's position when its take-up began */
    int32_t takeup_at;     /* ... and when this take-up began (a search again's own) */
    uint32_t home_dB;      /* active tendon: |B - B0| of its selected sensor (cuT) when its home
                              was found (for the HOM_EV_HOME report) */
    uint16_t tendon_ms;    /* the last tendon's time from its start to its recorded home
                              (at most 65535) */
    int32_t p_prev;        /* fine: previous point (position, |dB|) */
    uint32_t b_prev;
    int16_t way_q[HOM_WAY_PTS];  /* pull: the way out, furthest last: ticks past the engagement
                                    of a position read further than any before, */
    uint16_t way_b[HOM_WAY_PTS]; /*   and the |dB| (cuT >> HOM_WAY_SHIFT) of the sample judged
                                    there, a floor for the field from there on */
    int32_t ref_p;        /* fine: the point the field's rise is measured from (its |dB|: ref_b) */
    int32_t mod_goal;     /* re-approach: moderate goal after an overshoot */
    int32_t p_far;        /* the furthest position read in this pull */
    int32_t search_end;   /* take-up: where the search for engagement ends */
    int32_t slope_q8;     /* fine: current slope estimate, cuT per tick * 256 */
    int32_t slope_min_q8; /* fine: half the table's slope, the floor of every estimate */
    uint32_t engage_cuT;  /* engagement threshold */
    uint16_t tension_mN;
    uint16_t noise_cuT;
    uint32_t t_start; /* run start */
    hom_config_t cfg;
    tbl_src_t table;     /* the run's table: it must stay readable until the run ends */
    int32_t (*amb)[3];   /* absolute mode: the caller's ambient offsets (NULL: delta mode) */
    uint8_t amb_capture; /* absolute mode: this run captures them at its baseline */
    uint8_t survey;      /* hom_cmd_t.survey: no final move */
    uint8_t hold;        /* hom_cmd_t.hold: the held tendon + 1, 0 without a held pull */
    uint8_t held;        /* held pull's phase: 0 the pulled tendon's scan alone, 1 its return
                            to slack and the held tendon's pull, 2 the hold, 3 the held scan,
                            4 the release */
    struct {
        int32_t p;                 /* position, ticks */
        uint32_t b;                /* averaged |B - B0|, cuT */
        uint8_t n;                 /* samples averaged */
    } pts[4];                      /* fine: near points for the final fit */
    uint8_t seen[HOM_MAX_SENSORS]; /* preflight: sample received */
    uint16_t pf_missing;           /* preflight: bit i, tendon i's servo has not answered yet,
                                      answered with a hardware error, or is absent */
    hom_tendon_t tendon[HOM_MAX_TENDONS];
    hom_sensor_t sensor[HOM_MAX_SENSORS];
    uint16_t changed; /* hom_out_t.changed of this step */
    hom_event_t ev[HOM_EV_CAP];
} hom_t;

/* Start request. */
typedef struct {
    hom_mode_t mode;
    uint16_t tension_mN;  /* 0 = the table's default */
    uint8_t tendon;       /* HOM_MODE_SINGLE: the tendon to calibrate */
    uint16_t stored_mask; /* bit i: stored_home[i] is valid */
    uint16_t win_mask;    /* bit i: win_lo[i] and win_hi[i] are valid (below) */
    uint8_t ambient_capture;
    /* Identification survey (docs/identify.md): the run pulls every tendon
     * as a calibration does, but ends with each released (its release check)
     * instead of a final move to the homes. */
    uint8_t survey;
    /* Held pull (survey, HOM_MODE_SINGLE; docs/identify.md): tendon hold - 1
     * (0: none; another tendon, of the pulled one's segment for the fit to
     * use it: hom_start() refuses only the pulled tendon itself or one
     * beyond the table, HOM_E_ARG). The pulled tendon's
     * engagement is scanned (HOM_SCAN_*) and it goes back to slack; tendon
     * hold - 1 is pulled alone to its target at the run's tension and held
     * there; the field averaged then is the reference of the pulled
     * tendon's engagement (in b0 for the rest of the run: never a baseline
     * to keep); the pulled tendon, started HOM_HELD_BACK_UM further back
     * than in a calibration (as every tendon but the held one), is scanned
     * again; then both are released. No home is recorded and no window
     * learns an engagement. */
    uint8_t hold;
    /* Target mode. NULL: delta mode (|B - B0| against target_cuT). Otherwise the
     * paper's absolute mode: ambient_cuT[k] is sensor k's ambient offset A (cuT,
     * sensor frame, one row per table sensor, caller-owned and valid until the run
     * ends) and the selected sensor's |B - A| is compared with abs_target_cuT.
     * With ambient_capture set, the run first writes A = B0 - b_straight_cuT for
     * every sensor from its own baseline; otherwise it uses the stored A. */
    int32_t (*ambient_cuT)[3];
    /* the small fields above, the arrays behind them: the AVR reaches the
     * first 64 bytes of a struct with one instruction a byte */
    int32_t stored_home[HOM_MAX_TENDONS]; /* homes from the last run (EEPROM), previous frame */
    /* Engagement windows from earlier runs of this power cycle (hom_window()):
     * bit i of win_mask says tendon i's engagement lies between win_lo[i]
     * and win_hi[i] (ticks, this power cycle's frame, low and high in the
     * pull direction). A run releases a tendon only to the slack margin
     * before win_lo and searches for its engagement up to max_takeup_um past
     * win_hi, so repeated stops never pay out more tendon. A tendon without
     * a window gets one at the start of the run: win_lo the release that
     * frees a tendon left anywhere up to the top of the grid, win_hi where it
     * stands (quick mode: the stored home minus the expected travel). */
    int32_t win_lo[HOM_MAX_TENDONS];
    int32_t win_hi[HOM_MAX_TENDONS];
} hom_cmd_t;

/* Fills *cfg with the defaults: speeds designed for a 6.1 um tick, a sensor
 * at 100 Hz and a 1-2 ms bus cycle (docs/homing.md). */
void hom_config_default(hom_config_t *cfg);

/* Initialises *h idle with the given config (NULL = defaults), no homes. */
void hom_init(hom_t *h, const hom_config_t *cfg);
/* Sets the configuration for the next hom_start() and makes h startable
 * without clearing the rest, which hom_start() clears itself (hom_init()
 * clears it twice: about 1.4 KB of stores on the AVR). */
void hom_config_set(hom_t *h, const hom_config_t *cfg);
/* hom_config_set() of the defaults, in place: returns h's configuration
 * for the caller's changes before hom_start() (no copy on the stack). */
hom_config_t *hom_config_reset(hom_t *h);

/* Starts a run: validates the table, interpolates every tendon's target at
 * the tension (the table stays in use during the run: keep it and its
 * copy function valid until the run ends), resets the events and results of the previous run
 * (stored homes from cmd are kept for the final move and quick mode). Returns 0, HOM_E_ARG,
 * HOM_E_TABLE, HOM_E_TENSION, HOM_E_BUSY or HOM_E_HOMES. Nothing moves until
 * hom_step(). */
int hom_start(hom_t *h, const tbl_src_t *table, const hom_cmd_t *cmd);

/* Requests an abort: the next hom_step() ends the run with HOM_F_ABORTED and
 * releases every tendon. Returns 1 when taken, 0 when no run goes on (idle,
 * or the run has ended: done or fault). */
int hom_abort(hom_t *h);

/* Runs the machine once on the inputs; writes the commanded servo state to
 * *out (the `changed` bits say what to send). Returns HOM_RUNNING, 0 (idle or
 * done), -(hom_fault_t) after a fault, or HOM_E_ARG for a NULL argument.
 * Bounded work, never waits. */
int hom_step(hom_t *h, const hom_in_t *in, hom_out_t *out);

/* Takes the oldest event into *ev. Returns 1 when one was taken, 0 when the
 * queue is empty. Events beyond HOM_EV_CAP are dropped and counted in
 * h->ev_dropped (the fault itself stays readable in h->fault). */
int hom_event_pop(hom_t *h, hom_event_t *ev);
/* Events waiting in the queue. */
uint8_t hom_event_count(const hom_t *h);

/* Console word of a fault reason ("aborted", "travel_limit", ...); "unknown"
 * for values outside the enum. */
const char *hom_fault_name(int fault);

/* 1 and *tendon while a tendon is taken up or approaches its target (the
 * stretch an identification survey records), 0 otherwise; 2 and *tendon
 * in a held pull's run (hom_cmd_t.hold) but where the pulled tendon stands
 * at a point of a scan, whose samples alone the survey keeps. */
uint8_t hom_pulling(const hom_t *h, uint8_t *tendon);

/* Tendon i's home from the last run. Returns 0 and writes *ticks, or
 * HOM_E_ARG when i is out of range or has no home. */
int hom_home(const hom_t *h, uint8_t i, int32_t *ticks);

/* Tendon i's straight-pose home minus its home, ticks (docs/homing.md,
 * "Straight-pose homes"): where the final move takes it with cfg.straight.
 * 0 when i is out of range. */
int16_t hom_to_straight(const hom_t *h, uint8_t i);

/* The engagement window a run gives tendon i of table at tension_mN when
 * nothing is known of it this power cycle (no window, no stored home),
 * standing at p: from one initial release behind p, less the slack margin,
 * to one initial release ahead (docs/homing.md, "Release decision"). The app
 * takes it before the run starts, to save it for a power cycle, with the
 * default configuration's margin and release (HOM_SLACK_MARGIN_UM,
 * HOM_INITIAL_RELEASE_UM). 0, or HOM_E_ARG when the table has no such tendon
 * or tension. */
int hom_fresh_window(const tbl_src_t *table, uint8_t i, uint16_t tension_mN, int32_t p, int32_t *lo,
                     int32_t *hi);

/* Tendon i's engagement window as the last run left it: the run's own
 * engagement when it engaged (low = high), otherwise the window it started
 * with. Returns 0 and writes *lo and *hi, or HOM_E_ARG when i is out of range
 * or has no window. h->win_changed has bit i set when it changed since the
 * caller last cleared the bit. */
int hom_window(const hom_t *h, uint8_t i, int32_t *lo, int32_t *hi);

/* |v| for a 3-axis integer vector (64-bit integer square root). */
uint32_t hom_norm3(const int32_t v[3]);

/* ---- accessors for the application -------------------------------------------
 * What the application reads of a run (and the goal slots it borrows between
 * runs), so that it never depends on the layout of hom_t. Static inline: each
 * is one load or store on the AVR. i must be below HOM_MAX_TENDONS, k below
 * HOM_MAX_SENSORS; none checks it. */

/* Goal Position and Profile Velocity last commanded for tendon i. */
static inline int32_t hom_goal(const hom_t *h, uint8_t i)
{
    return h->tendon[i].goal;
}

static inline uint16_t hom_goal_vel(const hom_t *h, uint8_t i)
{
    return h->tendon[i].vel;
}

/* Sets tendon i's commanded goal and velocity. Only while no run is active:
 * the application keeps the goals of its own moves (home, release) in the
 * machine's output, which the next hom_init() clears. */
static inline void hom_idle_goal(hom_t *h, uint8_t i, int32_t goal, uint16_t vel)
{
    h->tendon[i].goal = goal;
    h->tendon[i].vel = vel;
}

/* Tendons whose engagement window changed since the last call (hom_window()),
 * as a bit mask; the bits are cleared. */
static inline uint16_t hom_win_take_changed(hom_t *h)
{
    uint16_t m = h->win_changed;
    h->win_changed = 0;
    return m;
}

/* The fault of the last run (hom_fault_t) and the tendon or sensor it names. */
static inline uint8_t hom_fault(const hom_t *h)
{
    return h->fault;
}

static inline uint8_t hom_fault_index(const hom_t *h)
{
    return h->fault_index;
}

/* Tendon i's per-run state (target, engagement, spool factor, direction). */
static inline const hom_tendon_t *hom_tendon(const hom_t *h, uint8_t i)
{
    return &h->tendon[i];
}

/* For the HOM_EV_HOME report of the newest home: its |B - B0| (cuT) and the
 * tendon's time from its start to that home (ms). */
static inline uint32_t hom_home_dB(const hom_t *h)
{
    return h->home_dB;
}

static inline uint16_t hom_tendon_ms(const hom_t *h)
{
    return h->tendon_ms;
}

/* Sensor k's straight-pose baseline B0 of the last run (cuT, sensor frame). */
static inline const int32_t *hom_baseline(const hom_t *h, uint8_t k)
{
    return h->sensor[k].b0;
}

/* Sensor k's newest raw sample (cuT, sensor frame). */
static inline const int32_t *hom_last(const hom_t *h, uint8_t k)
{
    return h->sensor[k].last;
}

/* Nonzero when the last run captured the ambient offsets (absolute mode). */
static inline uint8_t hom_amb_captured(const hom_t *h)
{
    return h->amb_capture;
}

#endif /* HALLHOME_HOMING_H */
