/*
 * pose: the plant with every tendon at a given motor position at once, the
 * ground truth behind straight-pose homes (docs/homing.md, "Straight-pose
 * homes").
 *
 * A calibration's final move takes every tendon from slack to its home
 * together, each servo's velocity scaled by its distance so that all arrive
 * at once; plant_pose_ramp() does the same, quasi-statically, so the
 * friction play and the backlash end in the state the move leaves them in.
 * plant_straight_homes() finds the motor positions where, reached that way,
 * every tendon's spool-side tension is the target: the homes a straight-pose
 * calibration should land on.
 *
 * Error convention: 0 = done, negative = PLANT_E_*.
 */
#ifndef HALLHOME_PLANT_POSE_H
#define HALLHOME_PLANT_POSE_H

#include "plant/plant.h"

/* Linear steps of plant_pose_ramp()'s move. */
#define PLANT_POSE_STEPS 200u
/* Where the move starts: this far short of each tendon's slack (the
 * calibration's release margin, 600 um past engagement). */
#define PLANT_POSE_RELEASE_UM 600.0

typedef struct {
    double tension_N[PLANT_MAX_TENDONS];     /* spool-side tension */
    double tip_tension_N[PLANT_MAX_TENDONS]; /* delivered at the tip (friction) */
    double tip_pos_mm[3];                    /* tip position, world frame */
    double tip_dev_mm; /* tip distance from the straight pose (every tendon slack) */
} plant_pose_result_t;

/* The tip with every tendon far slack (gravity applied): the straight pose
 * the deviation is measured from. Returns 0, PLANT_E_ARG or PLANT_E_RANGE. */
int plant_straight_tip(const plant_cfg_t *cfg, double pos_mm[3]);

/* Every tendon from PLANT_POSE_RELEASE_UM short of its slack to motor
 * position ticks[i] (fractional encoder ticks, the plant frame) together in
 * PLANT_POSE_STEPS linear steps; *out gets the equilibrium at the end.
 * Returns 0, PLANT_E_ARG or PLANT_E_RANGE. */
int plant_pose_ramp(const plant_cfg_t *cfg, const double ticks[], plant_pose_result_t *out);

/* The true straight-pose homes at tension_mN: motor positions (ticks[i]) at
 * which plant_pose_ramp() leaves every spool-side tension within 0.1 mN of the
 * target. Newton iterations with the plant's own Jacobian of the frictionless
 * statics (I + K C) from the single-tendon homes minus each tendon's own
 * bending shortening. Returns 0, PLANT_E_ARG, PLANT_E_SOLVE (a single-tendon
 * home not found, or no convergence in 40 iterations; ticks[] then holds the
 * last iterate). */
int plant_straight_homes(const plant_cfg_t *cfg, uint16_t tension_mN, double ticks[]);

/* The home a field-target calibration measures, noise-free: the motor
 * position where tendon i, pulled from slack with the others slack, brings
 * |B - B0| at sensor k (B0: every tendon slack) to target_cuT, i.e. where the
 * table's target for a tension meets the plant. Returns 0, PLANT_E_ARG or
 * PLANT_E_SOLVE (the field never reaches the target within 40 mm). */
int plant_field_home(const plant_cfg_t *cfg, uint8_t i, uint8_t k, double target_cuT,
                     double *ticks);

#endif /* HALLHOME_PLANT_POSE_H */
