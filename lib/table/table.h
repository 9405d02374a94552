/*
 * table: the calibration lookup table, generated offline by `hallhome tables`
 * from a robot description and compiled into the firmware (flash on the AVR).
 *
 * This header is the single declaration of the table format. The host
 * generator (host_tools/hallhome/tablegen.py) reads the constants below from
 * this file and writes a C source that defines one `tbl_table_t`; it never
 * restates the layout by hand.
 *
 * Units (integers only, so the AVR never needs floating point to use a table):
 *   tension         mN   (millinewton)
 *   field           cuT  (centi-microtesla, 10 nT; one AK09916 LSB is 15 cuT)
 *   length          um   (micrometre)
 *   spool           nm per encoder tick
 *
 * Error convention: 0 = done, negative = TBL_E_* code.
 *
 * Reading: the table lives in memory the caller may not be able to address
 * directly (AVR program memory). Every accessor takes a tbl_src_t whose copy
 * function moves bytes from the table into RAM: memcpy on the host, memcpy_P
 * on the AVR.
 */
#ifndef HALLHOME_TABLE_H
#define HALLHOME_TABLE_H

#include <stddef.h>
#include <stdint.h>

/* Storage class of a generated table: program memory on the AVR (the firmware
 * build defines it), plain const memory on the host. */
#ifndef TBL_FLASH
#define TBL_FLASH
#endif

#define TBL_MAGIC          0x544C4848UL /* "HHLT" little-endian */
#define TBL_FORMAT_VERSION 2u

#define TBL_MAX_GRID    12u /* tension grid points per tendon */
#define TBL_MAX_TENDONS 12u
#define TBL_MAX_SENSORS 8u
#define TBL_NAME_LEN    16u /* robot name, NUL-terminated */

#define TBL_NO_MUX 0xFFu /* sensor wired directly, no TCA9548A channel */

/* Calibration target mode the table was generated for (both sets of targets
 * are always present; the mode is the default the firmware starts in). */
#define TBL_MODE_DELTA    0u /* |B - B0| against |B(p_T) - B(p_0)| (default) */
#define TBL_MODE_ABSOLUTE 1u /* the paper's |B| against an absolute target */

typedef struct {
    uint8_t mux_channel;       /* 0..7, or TBL_NO_MUX */
    uint8_t i2c_addr;          /* 7-bit ICM-20948 address, 0x68 or 0x69 */
    int32_t b_straight_cuT[3]; /* predicted magnet field at the straight pose, sensor frame */
} tbl_sensor_t;

typedef struct {
    uint8_t servo_id;     /* DYNAMIXEL ID */
    int8_t pull_dir;      /* +1: increasing position ticks shortens the tendon; -1: decreasing */
    uint8_t segment;      /* 1-based segment where the tendon ends */
    uint8_t sensor;       /* index of the selected sensor in tbl_table_t.sensors */
    uint32_t nm_per_tick; /* tendon take-up per encoder tick (spool radius * 2 pi / ticks) */
    uint32_t travel_limit_um;          /* safety: never pull further than this past engagement */
    uint32_t target_cuT[TBL_MAX_GRID]; /* |B(p_T) - B(p_0)| per grid tension */
    uint32_t abs_target_cuT[TBL_MAX_GRID]; /* |B(p_T)| (magnet only) per grid tension */
    uint32_t travel_um[TBL_MAX_GRID];      /* expected take-up from engagement per grid tension */
    /* take-up to pay out from the single-tendon home (this tendon pulled
     * alone to the grid tension) to the straight-pose home (every tendon at
     * that tension together, the robot straight): the path shortening of the
     * bent pose minus the backbone's compression under every tendon
     * (docs/homing.md, "Straight-pose homes"); negative: take up more */
    int16_t straight_um[TBL_MAX_GRID];
} tbl_tendon_t;

typedef struct {
    uint32_t magic;          /* TBL_MAGIC */
    uint16_t format_version; /* TBL_FORMAT_VERSION */
    uint16_t reserved;       /* 0 */
    uint32_t
        table_id; /* CRC-32 of the generator's canonical content: identifies the robot + model */
    char name[TBL_NAME_LEN];
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    uint8_t mode;                   /* TBL_MODE_* */
    uint16_t grid_mN[TBL_MAX_GRID]; /* strictly increasing, n_grid >= 2 used entries */
    uint16_t default_mN;            /* default calibration tension, inside the grid */
    uint16_t noise_cuT;             /* expected sensor noise (1 sigma) the table assumed */
    tbl_sensor_t sensors[TBL_MAX_SENSORS];
    tbl_tendon_t tendons[TBL_MAX_TENDONS];
} tbl_table_t;

/* Copies n bytes from table memory at src into RAM at dst. */
typedef void (*tbl_copy_fn)(void *dst, const void *src, size_t n);

typedef struct {
    const tbl_table_t *table; /* address in table memory (flash on the AVR) */
    tbl_copy_fn copy;         /* memcpy on the host, memcpy_P on the AVR */
} tbl_src_t;

/* ---- accessors (table.c) --------------------------------------------------- */

/* Error codes of the accessors (negative; 0 = done). */
enum {
    TBL_E_ARG = -1,     /* NULL pointer, or an index beyond n_tendons / n_sensors */
    TBL_E_MAGIC = -2,   /* magic is not TBL_MAGIC: not a table, or wrong memory */
    TBL_E_VERSION = -3, /* format_version is not TBL_FORMAT_VERSION */
    TBL_E_FORMAT = -4,  /* counts beyond the TBL_MAX_* maxima, n_grid < 2, grid not strictly
                           increasing, default outside the grid, or a tendon's sensor index
                           beyond n_sensors */
    TBL_E_RANGE = -5    /* tension outside [grid_mN[0], grid_mN[n_grid-1]] */
};

/* The table-wide facts the firmware needs, copied into RAM by tbl_info(). */
typedef struct {
    uint32_t table_id;
    char name[TBL_NAME_LEN];
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    uint8_t mode;
    uint16_t grid_mN[TBL_MAX_GRID];
    uint16_t default_mN;
    uint16_t noise_cuT;
} tbl_info_t;

/* One tendon's targets interpolated at a requested tension. */
typedef struct {
    uint16_t tension_mN;
    uint32_t target_cuT;     /* |B(p_T) - B(p_0)| at the tension */
    uint32_t abs_target_cuT; /* |B(p_T)| at the tension */
    uint32_t travel_um;      /* expected take-up from engagement */
    int16_t straight_um;     /* single-tendon home to straight-pose home, um of take-up paid out */
} tbl_point_t;

/* Copy function for tables in ordinary memory (host, or RAM on the AVR):
 * memcpy with the tbl_copy_fn signature. */
void tbl_copy_ram(void *dst, const void *src, size_t n);

/* Checks magic, format version and the internal consistency of the table at
 * src (counts within the maxima, n_grid >= 2, strictly increasing grid, default
 * inside it, every tendon's sensor index < n_sensors, nm_per_tick > 0).
 * Returns 0, TBL_E_ARG (src, its table or its copy function NULL), TBL_E_MAGIC,
 * TBL_E_VERSION or TBL_E_FORMAT. */
int tbl_check(const tbl_src_t *src);

/* Copies the table-wide facts into *info. Does not validate: call tbl_check()
 * first. Returns 0 or TBL_E_ARG (NULL argument). */
int tbl_info(const tbl_src_t *src, tbl_info_t *info);

/* Copies tendon row i (0-based) into *out. Returns 0, TBL_E_ARG (NULL argument
 * or i >= n_tendons). */
int tbl_tendon(const tbl_src_t *src, uint8_t i, tbl_tendon_t *out);

/* Copies sensor i (0-based) into *out. Returns 0, TBL_E_ARG (NULL argument or
 * i >= n_sensors). */
int tbl_sensor(const tbl_src_t *src, uint8_t i, tbl_sensor_t *out);

/* Linear interpolation of one tendon's target, absolute target, expected
 * travel and straight-pose shift at tension_mN, integer arithmetic only (rounded to nearest). A
 * tension exactly on a grid point returns that point's values. Returns 0, TBL_E_ARG (NULL argument
 * or tendon >= n_tendons) or TBL_E_RANGE (tension outside the grid; *out is left unchanged). */
int tbl_target(const tbl_src_t *src, uint8_t tendon, uint16_t tension_mN, tbl_point_t *out);

/* The same interpolation over arrays already in RAM (learned targets kept in
 * EEPROM have the table's shape): y[] sampled at grid[] (n points, strictly
 * increasing). Writes the value at x to *y_out. Returns 0, TBL_E_ARG (NULL or
 * n < 2) or TBL_E_RANGE (x outside the grid). */
int tbl_interp(const uint16_t *grid, const uint32_t *y, uint8_t n, uint16_t x, uint32_t *y_out);

#endif /* HALLHOME_TABLE_H */
