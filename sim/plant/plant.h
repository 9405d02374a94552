/*
 * plant: a portable physics model of a tendon-driven continuum robot with a
 * magnet at its tip and magnetometers around it, for closed-loop tests of the
 * homing state machine and for benchmarks.
 *
 * Deliberately different from the host tool's Cosserat model, so that the
 * model error a real robot brings is present in simulation too:
 *   - piecewise constant curvature: segment j bends with the moment of every
 *     tendon that ends at or beyond it (tendons coupled across segments),
 *     curvature = sum(T_tip * r * direction) / EI (EI per segment), plus
 *     gravity's: the moment of the weight distal of each point of the bent
 *     robot (segment masses spread along the arcs, a tip mass), averaged over
 *     the segment, solved as a fixed point with the pose;
 *   - tendon path shortening r * (direction . curvature) * L per segment,
 *     plus the backbone's axial compression L * (sum of the tip tensions of
 *     the tendons through the segment) / EA when a segment's EA is given;
 *   - tendon elasticity k = EA / L_free and slack (no compression);
 *   - friction along the tendon path as a play operator between spool-side
 *     and tip-side tension (dead band f0 + mu * T: hysteresis);
 *   - spool backlash as a play operator between motor and spool;
 *   - a point dipole magnet following the tip frame, an ambient field per
 *     sensor, each sensor reading in its own frame, Gaussian noise, 0.15 uT
 *     quantisation, the AK09916's +-4912 uT range with an overflow flag;
 *   - a simple servo (first-order position response with the profile velocity
 *     as a speed limit and encoder quantisation), kept apart in plant_servo_*
 *     so the virtual bench can drive the plant from its XL430 model instead.
 * Statics are quasi-static: each plant_solve() finds the equilibrium for the
 * current motor angles by projected Gauss-Seidel over the tendons.
 *
 * Units inside the model are SI (double); the interfaces speak the firmware's
 * units: encoder ticks, cuT (10 nT), mN, um.
 *
 * Configuration is a line-oriented text file (sim/plant/README.md), parsed
 * without malloc into a plant_cfg_t with the fixed maxima of lib/table.
 *
 * Error convention: 0 = done, negative = PLANT_E_*.
 */
#ifndef HALLHOME_PLANT_H
#define HALLHOME_PLANT_H

#include <stddef.h>
#include <stdint.h>

#include "table/table.h"
#include "table/table_pack.h"

#define PLANT_MAX_SEGMENTS 4u
#define PLANT_MAX_TENDONS  TBL_MAX_TENDONS
#define PLANT_MAX_SENSORS  TBL_MAX_SENSORS

/* AK09916: 0.15 uT per LSB = 15 cuT, +-32752 LSB (+-4912 uT). */
#define PLANT_LSB_CUT 15
#define PLANT_LSB_MAX 32752

/* XL430 profile velocity unit 0.229 rpm at 4096 ticks/rev = 15.633 ticks/s. */
#define PLANT_TPS_PER_VEL_UNIT (0.229 * 4096.0 / 60.0)

enum {
    PLANT_E_ARG = -1,    /* NULL pointer or index out of range */
    PLANT_E_IO = -2,     /* config file cannot be opened or read */
    PLANT_E_SYNTAX = -3, /* a line is not `key = value...` or a number does not parse */
    PLANT_E_KEY = -4,    /* unknown key */
    PLANT_E_RANGE = -5,  /* a value or index outside its limits, or the config incomplete */
    PLANT_E_SOLVE = -6   /* a search (true home, engagement) found no solution */
};

typedef struct {
    double angle_deg;   /* position around the backbone, body frame */
    double radius_mm;   /* routing radius */
    uint8_t segment;    /* 1-based segment where the tendon ends */
    uint8_t servo_id;   /* DYNAMIXEL ID written to the table */
    int8_t pull_dir;    /* +1: increasing ticks shortens the tendon */
    int8_t sensor;      /* table's selected sensor, -1 = choose the most sensitive */
    double ea_N;        /* tendon axial stiffness E*A */
    double free_len_mm; /* free length between spool and tip */
    double slack_um;    /* slack at motor tick 0 (tendon taut when take-up exceeds it) */
    double friction_mN; /* dead band f0 of the friction play operator */
    double friction_mu; /* tension-proportional part of the dead band */
    double backlash_um; /* spool backlash (full play) */
    double nm_per_tick; /* this tendon's spool factor, when > 0 (else the robot's) */
} plant_tendon_cfg_t;

typedef struct {
    double pos_mm[3];     /* world frame: base at origin, robot along +z */
    double ambient_uT[3]; /* ambient field (earth, iron) at the sensor, world frame */
    double rot[9];        /* sensor axes in the world frame, row-major R: reading = R^T b */
    uint8_t mux_channel;
    uint8_t i2c_addr;
} plant_sensor_cfg_t;

typedef struct {
    char name[TBL_NAME_LEN];
    uint8_t n_segments;
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    double seg_len_mm[PLANT_MAX_SEGMENTS];
    double ei_Nm2;                         /* backbone bending stiffness */
    double seg_ei_Nm2[PLANT_MAX_SEGMENTS]; /* per segment, when > 0 (else ei_Nm2) */
    double seg_ea_N[PLANT_MAX_SEGMENTS];   /* backbone axial stiffness, 0 = inextensible */
    double seg_mass_g[PLANT_MAX_SEGMENTS]; /* gravity: mass spread along the segment */
    double nm_per_tick;                    /* spool take-up per encoder tick */
    double magnet_moment_Am2;   /* dipole moment along the tip's z axis (0 = magnet missing) */
    double magnet_offset_mm;    /* magnet centre beyond the tip along tip z */
    double tip_mass_g;          /* gravity: lumped mass at the magnet's centre */
    double gravity_dir[3];      /* unit vector of gravity in the world frame */
    double noise_uT;            /* sensor noise, 1 sigma per axis */
    double servo_tau_ms;        /* first-order servo time constant */
    double travel_limit_factor; /* table travel limit = factor * travel at the top grid tension */
    double travel_limit_margin_um; /* ... plus this margin */
    double travel_limit_um;        /* if > 0: the table's travel limit, as given */
    uint16_t grid_mN[TBL_MAX_GRID];
    uint16_t default_mN;
    plant_tendon_cfg_t tendon[PLANT_MAX_TENDONS];
    plant_sensor_cfg_t sensor[PLANT_MAX_SENSORS];
} plant_cfg_t;

/* Ground truth of the tip. */
typedef struct {
    double pos_mm[3];
    double rot[3][3]; /* tip frame axes (columns) in the world frame */
} plant_pose_t;

typedef struct {
    plant_cfg_t cfg;
    uint64_t rng;                            /* noise generator state */
    double motor_um[PLANT_MAX_TENDONS];      /* motor take-up (pull positive) */
    double spool_um[PLANT_MAX_TENDONS];      /* spool take-up after backlash */
    double tension_N[PLANT_MAX_TENDONS];     /* spool-side tension (ground truth) */
    double tip_tension_N[PLANT_MAX_TENDONS]; /* tension delivered at the tip */
    double curv[PLANT_MAX_SEGMENTS][2];      /* curvature vector per segment, 1/m */
    plant_pose_t tip;
    double extra_uT[PLANT_MAX_SENSORS][3]; /* injected disturbance per sensor */
    double weight_N[PLANT_MAX_TENDONS];    /* known force hung on the tendon, spool side */
    uint32_t iterations;                   /* Gauss-Seidel sweeps of the last solve */
} plant_t;

/* Fills *cfg with the built-in defaults (a robot with no tendons, segments or
 * sensors: the file must add them). Returns 0 or PLANT_E_ARG. */
int plant_cfg_defaults(plant_cfg_t *cfg);

/* Parses config text (NUL-terminated) over the current contents of *cfg (call
 * plant_cfg_defaults() first). Returns 0, PLANT_E_ARG, PLANT_E_SYNTAX,
 * PLANT_E_KEY or PLANT_E_RANGE; *err_line (may be NULL) gets the 1-based line
 * of the error. */
int plant_cfg_parse(plant_cfg_t *cfg, const char *text, int *err_line);

/* Loads a config file: defaults, then the file (at most 16 KB). Returns as
 * plant_cfg_parse(), or PLANT_E_IO. */
int plant_cfg_load(plant_cfg_t *cfg, const char *path, int *err_line);

/* Checks completeness: at least one segment, tendon and sensor, every
 * tendon's segment and sensor index valid, positive stiffnesses, grid strictly
 * increasing with default inside. Returns 0 or PLANT_E_RANGE. */
int plant_cfg_check(const plant_cfg_t *cfg);

/* Seeded perturbation of the physical parameters, as a real robot differs from
 * its description: every stiffness, length, radius, friction, backlash and the
 * magnet moment is multiplied by (1 + frac * u), u uniform in [-1, 1]; tendon
 * angles move by frac * 5 deg * u, sensor positions by frac * 1 mm * u per axis,
 * slack by frac * 500 um * u. frac = 0 leaves cfg unchanged. Returns 0 or
 * PLANT_E_ARG. */
int plant_cfg_perturb(plant_cfg_t *cfg, uint32_t seed, double frac);

/* The same with the backbone's stiffness (bending EI and axial EA of every
 * segment: the rod's modulus) perturbed by `stiff` instead of frac, e.g. a
 * NiTi rod whose modulus is known to +-25 % on a robot built to +-10 %. The
 * random draws are those of plant_cfg_perturb(), so stiff = frac gives the
 * same robot. Returns 0 or PLANT_E_ARG. */
int plant_cfg_perturb_stiffness(plant_cfg_t *cfg, uint32_t seed, double frac, double stiff);

/* Starts a plant: copies cfg, seeds the noise, puts every motor at tick 0
 * with the spool against the release side of its backlash, solves. Returns 0,
 * PLANT_E_ARG or PLANT_E_RANGE (cfg fails plant_cfg_check()). */
int plant_init(plant_t *p, const plant_cfg_t *cfg, uint32_t seed);

/* Tendon i's take-up per encoder tick, nm (its own or the robot's). */
double plant_nm_per_tick(const plant_cfg_t *cfg, uint8_t i);

/* Sets tendon i's motor angle in (fractional) encoder ticks; takes effect at
 * the next plant_solve(). Returns 0 or PLANT_E_ARG. */
int plant_set_motor(plant_t *p, uint8_t i, double ticks);

/* Hangs a known force (newtons, m g of a mass) on tendon i at the spool side,
 * as the model-free procedure hangs a weight on a slack servo's tendon; 0
 * takes it off. While the servo's own pull is weaker, the spool-side tension
 * is the force and the tip receives it through the friction play (pulling:
 * force (1 - mu) - f0); a servo pulling harder takes over. Takes effect at
 * the next plant_solve(). Returns 0 or PLANT_E_ARG (index, negative or not
 * finite force). */
int plant_set_weight(plant_t *p, uint8_t i, double newtons);

/* Motor angle of tendon i in ticks (the inverse of plant_set_motor). */
double plant_motor_ticks(const plant_t *p, uint8_t i);

/* Finds the static equilibrium for the current motor angles (backlash and
 * friction keep their history between calls). Returns 0 or PLANT_E_ARG. */
int plant_solve(plant_t *p);

/* Noise-free field at sensor k from the last solve (ambient + magnet +
 * injected disturbance), in uT, world frame (plant_read_sensor() turns it
 * into the sensor frame). */
void plant_field_true(const plant_t *p, uint8_t k, double b_uT[3]);

/* The same in the sensor's own frame (its TOML rotation), as the chip's
 * registers give it: what the bench's AK09916 models are fed. */
void plant_field_sensor(const plant_t *p, uint8_t k, double b_uT[3]);

/* Magnet-only field at world point q (mm) for a given tip pose, in uT. */
void plant_dipole_uT(const plant_cfg_t *cfg, const plant_pose_t *tip, const double q_mm[3],
                     double b_uT[3]);

/* One magnetometer reading of sensor k as the AK09916 delivers it: the field
 * in the sensor's frame plus Gaussian noise, quantised to 15 cuT, clipped at
 * the range. Writes cuT to out[3]. Returns 0, 1 when the reading overflowed (HOFL set),
 * PLANT_E_ARG. */
int plant_read_sensor(plant_t *p, uint8_t k, int32_t out_cuT[3]);

/* Tendon i's spool-side tension after a quasi-static pull from slack to motor
 * position `ticks` with every other tendon slack: the calibration's definition
 * of the tension at a home. Returns the tension in newtons. */
double plant_tension_at(const plant_cfg_t *cfg, uint8_t i, double ticks);

/* Puts *p in the calibration's single-tendon state: a fresh plant of cfg with
 * every other tendon far slack and tendon i pulled from slack to motor
 * position `ticks` (a far-slack `ticks` gives the straight pose). Returns 0 or
 * PLANT_E_ARG. */
int plant_pull_alone(const plant_cfg_t *cfg, uint8_t i, double ticks, plant_t *p);

/* The true home: the fractional motor position where tendon i, pulled from
 * slack with the others slack, reaches tension_mN at the spool. Returns 0,
 * PLANT_E_ARG or PLANT_E_SOLVE. */
int plant_true_home(const plant_cfg_t *cfg, uint8_t i, uint16_t tension_mN, double *ticks);

/* The true engagement: the motor position where tendon i, pulled from slack
 * with the others slack, starts to move the tip (tip-side tension > 0).
 * Returns 0, PLANT_E_ARG or PLANT_E_SOLVE. */
int plant_true_engagement(const plant_cfg_t *cfg, uint8_t i, double *ticks);

/* Path compliance of the plant: how far tendon i's path shortens per newton
 * of tip-side tension in tendon m (m/N), from the segments both span; the
 * diagonal is a tendon's own bending shortening (sim/plant/pose.h uses it).
 * 0 for an index out of range. */
double plant_path_compliance(const plant_cfg_t *cfg, uint8_t i, uint8_t m);

/* The model-free analogue of the host's table generator, the plant playing the
 * part of hanging weights: for every tendon and grid tension, pulls the plant
 * (noise-free) to the true home and records |B - B0| at every sensor, the
 * travel from engagement and |B| of the magnet alone; selects per tendon the
 * sensor with the largest change that rises over the whole grid (or the one
 * the config names). Fills *t completely (magic, version, counts, limits);
 * fields are whole LSB (TBL_CUT_PER_LSB), so tbl_pack() stores them as they are.
 * Returns 0, PLANT_E_ARG, PLANT_E_RANGE or PLANT_E_SOLVE. */
int plant_make_table(const plant_cfg_t *cfg, tbl_wide_t *t);

/* ---- simple servo, separate from the plant ---------------------------------- */

typedef struct {
    double pos;         /* shaft angle, ticks (continuous) */
    int32_t goal;       /* goal position, ticks */
    uint32_t vel_units; /* profile velocity, 0.229 rpm units (0 = the XL430's maximum) */
    double tau_ms;      /* first-order time constant */
    uint8_t torque;     /* 1 = holding / moving; 0 = free (the shaft stays put) */
} plant_servo_t;

/* Initialises a servo at shaft angle pos with torque on and goal = pos. */
void plant_servo_init(plant_servo_t *s, double pos, double tau_ms);

/* Advances the servo by dt_ms: first-order approach to the goal, the speed
 * clipped at the profile velocity. */
void plant_servo_step(plant_servo_t *s, double dt_ms);

/* Present position as the encoder reports it (rounded to a tick). */
int32_t plant_servo_present(const plant_servo_t *s);

#endif /* HALLHOME_PLANT_H */
