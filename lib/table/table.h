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
 *   field           cuT  (centi-microtesla, 10 nT; one AK09916 LSB is 15 cuT);
 *                   stored in LSB, returned by the accessors in cuT
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
#define TBL_FORMAT_VERSION 3u

/* Largest counts a table may have (the accessors' RAM copies are sized to
 * them); a table itself is sized to its robot (TBL_LAYOUT). */
#define TBL_MAX_GRID    12u /* tension grid points per tendon */
#define TBL_MAX_TENDONS 12u
#define TBL_MAX_SENSORS 8u
#define TBL_NAME_LEN    16u /* robot name, NUL-terminated */

#define TBL_NO_MUX 0xFFu /* sensor wired directly, no TCA9548A channel */

/* Field unit of the stored table: one AK09916 LSB, 0.15 uT = 15 cuT, the
 * resolution the sensor reports in. Every stored field (targets, straight-pose
 * field) is an integer number of LSB; the accessors return cuT. */
#define TBL_CUT_PER_LSB 15u

/* Calibration target mode the table was generated for (both sets of targets
 * are always present; the mode is the default the firmware starts in). */
#define TBL_MODE_DELTA    0u /* |B - B0| against |B(p_T) - B(p_0)| (default) */
#define TBL_MODE_ABSOLUTE 1u /* the paper's |B| against an absolute target */

/* ---- the stored table (flash) -------------------------------------------------
 *
 * A table is a tbl_head_t followed by arrays sized to the robot's own counts
 * (NT tendons, NS sensors, NG grid points), in the order TBL_LAYOUT declares.
 * Every member after the header is made of 1- and 2-byte integers and the
 * header is 36 bytes, so the layout has no padding on any compiler: the byte
 * offsets are the TBL_OFF_* sums below, which the accessors use and every
 * generated source checks at compile time (TBL_LAYOUT_CHECK).
 *
 * Stored units (smallest integer that holds the robot's values; the generator
 * refuses a value that does not fit, naming robot, key and limit):
 *   field           LSB of TBL_CUT_PER_LSB cuT, uint16 (|B| targets) / int16
 *   length          um, uint16 (travel, travel limit) / int16 (straight shift)
 *   spool           nm per encoder tick, uint16
 */
typedef struct {
    uint32_t magic;          /* TBL_MAGIC */
    uint16_t format_version; /* TBL_FORMAT_VERSION */
    uint16_t size;           /* bytes of the whole table, TBL_SIZE(n_tendons, n_sensors, n_grid) */
    uint32_t
        table_id; /* CRC-32 of the table's bytes with table_id 0: identifies the robot + model */
    char name[TBL_NAME_LEN];
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    uint8_t mode;        /* TBL_MODE_* */
    uint16_t default_mN; /* default calibration tension, inside the grid */
    uint16_t noise_cuT;  /* expected sensor noise (1 sigma) the table assumed */
} tbl_head_t;

typedef struct {
    uint8_t mux_channel;       /* 0..7, or TBL_NO_MUX */
    uint8_t i2c_addr;          /* 7-bit ICM-20948 address, 0x68 or 0x69 */
    int16_t b_straight_lsb[3]; /* predicted magnet field at the straight pose, sensor frame */
} tbl_sensor_rec_t;

typedef struct {
    uint8_t servo_id;     /* DYNAMIXEL ID */
    int8_t pull_dir;      /* +1: increasing position ticks shortens the tendon; -1: decreasing */
    uint8_t segment;      /* 1-based segment where the tendon ends */
    uint8_t sensor;       /* index of the selected sensor in the table's sensors */
    uint16_t nm_per_tick; /* tendon take-up per encoder tick (spool radius * 2 pi / ticks) */
    uint16_t travel_limit_um; /* safety: never pull further than this past engagement */
} tbl_tendon_rec_t;

/* The whole table for NT tendons, NS sensors and NG grid points. Declared
 * here once; each generated source expands it with its robot's counts, which
 * completes the type tbl_table_t in that source only (everywhere else a table
 * is reached through a tbl_src_t and the TBL_OFF_* offsets).
 *   grid_mN        tension grid, strictly increasing, NG >= 2
 *   target_lsb     |B(p_T) - B(p_0)| on the tendon's sensor, per grid tension
 *   abs_target_lsb |B(p_T)| (magnet only), per grid tension
 *   travel_um      expected take-up from engagement, per grid tension
 *   straight_um    take-up to pay out from the single-tendon home (this tendon
 *                  pulled alone to the grid tension) to the straight-pose home
 *                  (every tendon at that tension together, the robot straight):
 *                  the path shortening of the bent pose minus the backbone's
 *                  compression under every tendon (docs/homing.md,
 *                  "Straight-pose homes"); negative: take up more */
#define TBL_LAYOUT(NT, NS, NG)                                                                     \
    struct tbl_table {                                                                             \
        tbl_head_t head;                                                                           \
        uint16_t grid_mN[NG];                                                                      \
        tbl_sensor_rec_t sensors[NS];                                                              \
        tbl_tendon_rec_t tendons[NT];                                                              \
        uint16_t target_lsb[NT][NG];                                                               \
        uint16_t abs_target_lsb[NT][NG];                                                           \
        uint16_t travel_um[NT][NG];                                                                \
        int16_t straight_um[NT][NG];                                                               \
    }

/* A table in table memory. Incomplete on purpose: its size is the robot's. */
typedef struct tbl_table tbl_table_t;

/* Byte offsets of the layout's members, from the counts. The per-grid arrays
 * are TBL_ROWS rows of NG entries per tendon, in the order of TBL_ROW_*. */
#define TBL_ROW_TARGET   0u
#define TBL_ROW_ABS      1u
#define TBL_ROW_TRAVEL   2u
#define TBL_ROW_STRAIGHT 3u
#define TBL_ROWS         4u

#define TBL_OFF_GRID            ((uint16_t)sizeof(tbl_head_t))
#define TBL_OFF_SENSORS(ng)     (TBL_OFF_GRID + 2u * (ng))
#define TBL_OFF_TENDONS(ns, ng) (TBL_OFF_SENSORS(ng) + (ns) * (uint16_t)sizeof(tbl_sensor_rec_t))
#define TBL_OFF_ROWS(nt, ns, ng)                                                                   \
    (TBL_OFF_TENDONS(ns, ng) + (nt) * (uint16_t)sizeof(tbl_tendon_rec_t))
#define TBL_OFF_ROW(nt, ns, ng, row) (TBL_OFF_ROWS(nt, ns, ng) + (row)*2u * (nt) * (ng))
#define TBL_SIZE(nt, ns, ng)         TBL_OFF_ROW(nt, ns, ng, TBL_ROWS)
#define TBL_SIZE_MAX                 TBL_SIZE(TBL_MAX_TENDONS, TBL_MAX_SENSORS, TBL_MAX_GRID)

/* Compile-time proof, in a generated source after TBL_LAYOUT(NT, NS, NG), that
 * the compiler laid the table out as the offsets say (C99 has no
 * _Static_assert: a negative array size fails the build). */
#define TBL_LAYOUT_CHECK(NT, NS, NG)                                                               \
    typedef char tbl_layout_ok_t                                                                   \
        [(sizeof(tbl_head_t) == 36u && sizeof(tbl_sensor_rec_t) == 8u &&                           \
          sizeof(tbl_tendon_rec_t) == 8u && offsetof(struct tbl_table, grid_mN) == TBL_OFF_GRID && \
          offsetof(struct tbl_table, sensors) == TBL_OFF_SENSORS(NG) &&                            \
          offsetof(struct tbl_table, tendons) == TBL_OFF_TENDONS(NS, NG) &&                        \
          offsetof(struct tbl_table, target_lsb) == TBL_OFF_ROW(NT, NS, NG, TBL_ROW_TARGET) &&     \
          offsetof(struct tbl_table, abs_target_lsb) == TBL_OFF_ROW(NT, NS, NG, TBL_ROW_ABS) &&    \
          offsetof(struct tbl_table, travel_um) == TBL_OFF_ROW(NT, NS, NG, TBL_ROW_TRAVEL) &&      \
          offsetof(struct tbl_table, straight_um) == TBL_OFF_ROW(NT, NS, NG, TBL_ROW_STRAIGHT) &&  \
          offsetof(struct tbl_table, straight_um) + sizeof(int16_t) * (NT) * (NG) ==               \
              TBL_SIZE(NT, NS, NG))                                                                \
             ? 1                                                                                   \
             : -1]

/* ---- the table as the firmware reads it (RAM, natural units) ------------------ */

/* One sensor, decoded by tbl_sensor(). */
typedef struct {
    uint8_t mux_channel;       /* 0..7, or TBL_NO_MUX */
    uint8_t i2c_addr;          /* 7-bit ICM-20948 address */
    int32_t b_straight_cuT[3]; /* predicted magnet field at the straight pose, sensor frame */
} tbl_sensor_t;

/* The fixed part of a tendon row, declared once: the first fields of
 * tbl_tendon_t and the whole of tbl_tendon_head_t (the same initial
 * sequence, so one is copied into the other as bytes). */
#define TBL_TENDON_HEAD_FIELDS                                                                     \
    uint8_t servo_id;                                                                              \
    int8_t pull_dir;                                                                               \
    uint8_t segment;                                                                               \
    uint8_t sensor;                                                                                \
    uint32_t nm_per_tick;                                                                          \
    uint32_t travel_limit_um;

/* One tendon row, decoded by tbl_tendon(); entries from n_grid on are 0. */
typedef struct {
    TBL_TENDON_HEAD_FIELDS
    uint32_t target_cuT[TBL_MAX_GRID];     /* |B(p_T) - B(p_0)| per grid tension */
    uint32_t abs_target_cuT[TBL_MAX_GRID]; /* |B(p_T)| (magnet only) per grid tension */
    uint32_t travel_um[TBL_MAX_GRID];      /* expected take-up from engagement per grid tension */
    int16_t straight_um[TBL_MAX_GRID];     /* single-tendon home to straight-pose home */
} tbl_tendon_t;

/* The fixed part of a tendon row (tbl_tendon()'s first fields), decoded by
 * tbl_tendon_head(): 12 bytes where the firmware needs no grid values. */
typedef struct {
    TBL_TENDON_HEAD_FIELDS
} tbl_tendon_head_t;

/* tbl_entry()'s grid index of a tendon's last grid point. */
#define TBL_GRID_TOP 0xFFu

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

/* The table-wide facts the firmware keeps, copied into RAM by tbl_info();
 * the name and the tension grid are read where they are needed
 * (tbl_name(), tbl_grid_mN()): 40 bytes of RAM less. */
typedef struct {
    uint32_t table_id;
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    uint8_t mode;
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

/* Copies the robot's name (NUL-terminated, at most TBL_NAME_LEN - 1
 * characters) into name. Does not validate. Returns 0 or TBL_E_ARG. */
int tbl_name(const tbl_src_t *src, char name[TBL_NAME_LEN]);

/* Entry g of the tension grid, mN: 0 beyond n_grid (or with a NULL
 * argument). Does not validate. */
uint16_t tbl_grid_mN(const tbl_src_t *src, uint8_t g);

/* Copies tendon row i (0-based) into *out. Returns 0, TBL_E_ARG (NULL argument
 * or i >= n_tendons). */
int tbl_tendon(const tbl_src_t *src, uint8_t i, tbl_tendon_t *out);

/* Copies the fixed part of tendon row i into *out, as tbl_tendon() would.
 * Returns 0, TBL_E_ARG (NULL argument or i >= n_tendons). */
int tbl_tendon_head(const tbl_src_t *src, uint8_t i, tbl_tendon_head_t *out);

/* Entry g (or TBL_GRID_TOP: the last) of grid row `row` of tendon i, as
 * tbl_tendon() widens it: TBL_ROW_TARGET and TBL_ROW_ABS in cuT,
 * TBL_ROW_TRAVEL in um. Returns 0, TBL_E_ARG (NULL argument, i >= n_tendons,
 * another row or g beyond the grid). */
int tbl_entry(const tbl_src_t *src, uint8_t i, uint8_t row, uint8_t g, uint32_t *out);

/* Grid row `row` of tendon i into out[0..n_grid-1], widened as by
 * tbl_entry() (one read through the copy function; later entries are left
 * as they were). Returns n_grid, or TBL_E_ARG (NULL argument, i >=
 * n_tendons or another row). */
int tbl_row(const tbl_src_t *src, uint8_t i, uint8_t row, uint32_t out[TBL_MAX_GRID]);

/* Copies sensor i (0-based) into *out. Returns 0, TBL_E_ARG (NULL argument or
 * i >= n_sensors). */
int tbl_sensor(const tbl_src_t *src, uint8_t i, tbl_sensor_t *out);

/* Linear interpolation of one tendon's target, absolute target, expected
 * travel and straight-pose shift at tension_mN, integer arithmetic only (rounded to nearest). A
 * tension exactly on a grid point returns that point's values. Returns 0, TBL_E_ARG (NULL argument
 * or tendon >= n_tendons) or TBL_E_RANGE (tension outside the grid; *out is left unchanged). */
int tbl_target(const tbl_src_t *src, uint8_t tendon, uint16_t tension_mN, tbl_point_t *out);

/* Address in table memory of tendon `tendon`'s stored target row: n_grid
 * uint16_t entries in LSB (TBL_CUT_PER_LSB cuT each), for a copy function
 * that substitutes learned targets where a read covers them. info is the
 * table's tbl_info(); the address is computed, never dereferenced. Returns NULL
 * when table or info is NULL or tendon >= info->n_tendons. */
const void *tbl_target_row(const tbl_table_t *table, const tbl_info_t *info, uint8_t tendon);

/* Largest field value a table (and a learned target) can hold, cuT. */
#define TBL_FIELD_CUT_MAX (0xFFFFUL * TBL_CUT_PER_LSB)

/* A field value in cuT rounded to the nearest stored LSB; cuT must not
 * exceed TBL_FIELD_CUT_MAX (the caller refuses larger values). */
uint16_t tbl_lsb_of_cuT(uint32_t cuT);

/* The same interpolation over arrays already in RAM (learned targets kept in
 * EEPROM have the table's shape): y[] sampled at grid[] (n points, strictly
 * increasing). Writes the value at x to *y_out. Returns 0, TBL_E_ARG (NULL or
 * n < 2) or TBL_E_RANGE (x outside the grid). */
int tbl_interp(const uint16_t *grid, const uint32_t *y, uint8_t n, uint16_t x, uint32_t *y_out);

#endif /* HALLHOME_TABLE_H */
