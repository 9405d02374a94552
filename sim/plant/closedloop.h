/*
 * closedloop: the homing state machine (lib/homing) driving the plant model
 * (plant.h) through the plant's simple servos, natively, with no AVR. Used by
 * the unit tests and by build/native/hh_closedloop for benchmarks.
 *
 * Time runs in 1 ms steps: the servos move, the plant finds its equilibrium,
 * each sensor delivers a sample every 10 ms (100 Hz, staggered), every servo
 * reports its present position every step (a 1 ms bus cycle; pos_period_ms
 * sets a slower one), hom_step()
 * runs and its changed goals go to the servos. Faults can be injected at a
 * chosen time. Ground truth (true homes, tensions, travel) comes back in the
 * result.
 */
#ifndef HALLHOME_CLOSEDLOOP_H
#define HALLHOME_CLOSEDLOOP_H

#include <stdint.h>

#include "homing/homing.h"
#include "plant/plant.h"

#define PLANT_RUN_MAX_EVENTS 96u

/* Injected faults. */
typedef enum {
    PLANT_FI_NONE = 0,
    PLANT_FI_SENSOR_SILENT,  /* sensor `index` stops delivering samples at fault_ms */
    PLANT_FI_SENSOR_ERROR,   /* sensor `index` reports read errors from fault_ms */
    PLANT_FI_SENSOR_ABSENT,  /* sensor `index` not found at the probe */
    PLANT_FI_SATURATE,       /* a 6 mT field appears at sensor `index` at fault_ms */
    PLANT_FI_FIELD_JUMP,     /* a step appears at sensor `index` at fault_ms: jump_uT, or
                                3 mT along x when jump_uT is all zero */
    PLANT_FI_SERVO_SILENT,   /* servo of tendon `index` stops answering at fault_ms */
    PLANT_FI_SERVO_HWERR,    /* servo of tendon `index` reports overload at fault_ms */
    PLANT_FI_SERVO_ABSENT,   /* servo of tendon `index` not found at the probe */
    PLANT_FI_MAGNET_MISSING, /* no magnet on the tip */
    PLANT_FI_MAGNET_REMOVED, /* the magnet taken off the tip at fault_ms */
    PLANT_FI_FIELD_STUCK,    /* from fault_ms, once sensor `index`'s field has changed by
                                fall_at_uT since the run's start, it stays at that field
                                (the magnet come off the tip and left where it was) */
    PLANT_FI_FIELD_FALL,     /* from fault_ms, once sensor `index`'s field has changed by
                                fall_at_uT since the run's start, a field appears there
                                that cancels half of that change (an ambient change against
                                the tendon's field), and stays */
    PLANT_FI_ABORT           /* hom_abort() at fault_ms (button, '!') */
} plant_fault_t;

typedef struct {
    const plant_cfg_t *plant;  /* the robot (possibly perturbed) */
    const tbl_table_t *table;  /* the table the homing uses (host memory) */
    const hom_config_t *hom;   /* NULL = hom_config_default() */
    hom_cmd_t cmd;             /* mode, tension, stored homes */
    uint32_t seed;             /* sensor noise and random start */
    double start_min_um;       /* random start: motor take-up relative to the true */
    double start_max_um;       /*   engagement, uniform in [min, max] (< 0: slack) */
    const double *start_ticks; /* explicit start motor positions (plant frame) or NULL */
    int32_t frame_offset;      /* encoder frame: reported ticks = plant ticks - offset */
    plant_fault_t fault;
    uint8_t fault_index;
    uint32_t fault_ms;
    uint32_t max_ms;       /* give up after this simulated time (0 = 60 s) */
    uint32_t clock0_ms;    /* the homing's clock at the start: now_ms = clock0_ms + the
                              simulated time (a clock that wraps during the run) */
    double fall_at_uT;     /* PLANT_FI_FIELD_FALL, _STUCK: the change that sets it off */
    double jump_uT[3];     /* PLANT_FI_FIELD_JUMP: the step (world frame); 0: 3 mT x */
    uint8_t pos_period_ms; /* positions read every this many ms (0, 1: every step; a
                              12-servo bus reads them every 5-7 ms), no reply between */
    uint8_t goal_lag_ms;   /* goal writes reach the servos this much later (a slow main
                              loop and a busy bus: up to 20 ms on 12 servos), < 32 */
    uint8_t sample_lag_ms; /* sensor samples reach the homing this much later (the
                              AK09916's period, the ICM-20948 master's poll, a slow main
                              loop), < 20 */
    uint16_t mst_us;       /* nonzero: the firmware's sensor path instead of sample_lag_ms:
                              the ICM-20948 master copies the latest sample every mst_us
                              (7300 on the board), the host reads every read_us (5000
                              when 0) up to read_jitter_us late, and each sample's age
                              comes from the sensor clock (icm_clock.h) */
    uint16_t read_us;
    uint16_t read_jitter_us;
    uint8_t age_mode;           /* 0: ages as the firmware has them (the clock's, or sample_lag_ms);
                                   1: the true ages; 2: every age 0 (a homing that ignores them) */
    double ambient_shift_uT[3]; /* added to every sensor's ambient field (world frame) for
                                   this run: the bench moved or iron came near since the
                                   absolute mode's ambient capture (cmd.ambient_cuT) */
} plant_run_cfg_t;

typedef struct {
    int rc;        /* final hom_step() result: 0 done, -(hom_fault_t) */
    uint8_t fault; /* hom_fault_t */
    uint8_t fault_index;
    uint8_t fault_dev;
    uint8_t n_tendons;
    uint32_t end_ms;     /* simulated time at done or fault */
    uint32_t release_ms; /* after a fault: time until every tendon is slack (0 = none needed
                            or not reached within 300 ms: see released) */
    uint8_t released;    /* after a fault: every spool tension fell below 1 mN */
    uint8_t have_home[TBL_MAX_TENDONS];
    int32_t home[TBL_MAX_TENDONS];                 /* homes in the homing's (encoder) frame */
    double home_plant[TBL_MAX_TENDONS];            /* the same in the plant frame */
    double true_home[TBL_MAX_TENDONS];             /* plant frame, for the requested tension */
    double err_ticks[TBL_MAX_TENDONS];             /* home_plant - true_home */
    double tension_at_home_N[TBL_MAX_TENDONS];     /* single-tendon tension at the home */
    double final_tension_N[TBL_MAX_TENDONS];       /* spool tensions at the end (all at home) */
    double max_past_engage_ticks[TBL_MAX_TENDONS]; /* deepest pull past the detected engagement */
    double max_tension_N[TBL_MAX_TENDONS];         /* highest spool tension during the run */
    double max_pull_N[TBL_MAX_TENDONS];            /* highest spool tension while the tendon was
                                                      the one pulled and had no home yet: the
                                                      bounded pull (docs/homing.md) */
    double max_behind_ticks[TBL_MAX_TENDONS];      /* deepest a fine point of the tendon was
                                                      taken behind the furthest its servo
                                                      had been since it was last slack: the
                                                      spool's backlash and the path's friction
                                                      hold the field of the further place */
    int32_t limit_ticks[TBL_MAX_TENDONS];          /* the homing's travel limit */
    double engage_err_ticks[TBL_MAX_TENDONS];      /* the last engagement the homing recorded,
                                                      against where the tendon's tension reached
                                                      the threshold's share of the target (pull
                                                      sense: > 0 late); NAN if none */
    double tip_mm[3];                              /* tip at the end */
    uint16_t win_kept; /* bit i: from the first tendon's pull on, the run gave tendon i's
                          window to keep (hom_win_take_changed()) */
    uint16_t n_events;
    hom_event_t events[PLANT_RUN_MAX_EVENTS];
} plant_run_result_t;

/* Sets a run config to nominal: no fault, full mode at the table's default
 * tension, random start between 2 mm slack and 0.3 mm taut, frame offset 0. */
void plant_run_defaults(plant_run_cfg_t *rc, const plant_cfg_t *plant, const tbl_table_t *table);

/* Run `run` of the bounded-pull scan series s0 (tests/tools/bound_scan.c,
 * test_homing_bound.c): the plant's seed and the bus timing from the run
 * number, and with `step` an ambient field step (up to 30 uT per axis) on a
 * random one of n_sensors at a random moment of a run of n_tendons. */
void plant_run_scan(plant_run_cfg_t *rc, uint32_t s0, unsigned run, uint8_t n_sensors,
                    uint8_t n_tendons, int step);

/* Runs one calibration in closed loop. Returns 0 when the run finished (done
 * or fault: see res->rc), PLANT_E_ARG for a NULL or inconsistent argument
 * (table and plant tendon counts differ), PLANT_E_RANGE when hom_start()
 * refused (res->rc holds its HOM_E_* code), PLANT_E_SOLVE when the run did
 * not end within max_ms. */
int plant_run(const plant_run_cfg_t *rc, plant_run_result_t *res);

#endif /* HALLHOME_CLOSEDLOOP_H */
