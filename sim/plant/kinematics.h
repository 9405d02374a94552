/*
 * kinematics: the plant's piecewise constant-curvature geometry (arcs, the
 * tip frame) and the moment that gravity exerts on the bent robot. Private to
 * sim/plant (plant.c's statics use it); the units are SI.
 */
#ifndef HALLHOME_PLANT_KINEMATICS_H
#define HALLHOME_PLANT_KINEMATICS_H

#include "plant/plant.h"

#define PLANT_G 9.80665 /* standard gravity, m/s^2 */

/* Mass points per segment for the gravity moment (midpoint rule). */
#define PLANT_GRAVITY_POINTS 8u

/* plant_solve's fixed point of gravity and pose: at most this many rounds,
 * until gravity's curvature moves by less than the tolerance (1/m). */
#define PLANT_GRAVITY_ROUNDS 30u
#define PLANT_GRAVITY_TOL    1e-7

/* Constant-curvature arc of length len (m) with curvature vector k (1/m) in
 * its base frame: bending towards k. Writes the end frame's rotation and
 * position relative to the base. */
void plant_arc(const double k[2], double len, double rot[3][3], double pos[3]);

/* out = a b (out may alias a or b). */
void plant_mat_mul(double out[3][3], double a[3][3], double b[3][3]);

/* The tip pose (p->tip) from the segment curvatures p->curv. */
void plant_forward_kinematics(plant_t *p);

/* Bending stiffness of segment j: its own when given, else the backbone's. */
double plant_seg_ei(const plant_cfg_t *c, uint8_t j);

/* Nonzero when the config has a mass for gravity to act on. */
int plant_has_gravity(const plant_cfg_t *c);

/* Gravity's curvature of each segment (1/m, segment base frame) for the pose
 * the curvatures curv give: the weight of everything distal of a point of the
 * segment (the segment's own mass and the segments beyond it, spread along
 * their arcs, and the tip mass at the magnet's centre) times its lever from
 * that point, averaged over the segment, over EI. On an upright robot it
 * vanishes when the robot is straight and bends it further when bent; on a
 * robot lying sideways the straight robot already sags. */
void plant_gravity_curv(const plant_cfg_t *c, double curv[][2], double gk[][2]);

#endif
