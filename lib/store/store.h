/*
 * store: hallhome's persistent records in the ATmega2560's 4 KB EEPROM.
 *
 * What is kept: the settings (versioned, ranges checked, defaults restored
 * when invalid), the homes of the last calibration (multi-turn tick count,
 * single-turn remainder and the rest position the servo was left at, with the
 * tension, calibration count and table_id), the engagement windows a power
 * cycle would otherwise forget (each tendon's window relative to the servo's
 * single-turn position when it was saved), learned (model-free) targets per
 * tendon in the shape of the table's stored target row (uint16 LSB per grid
 * point, TBL_CUT_PER_LSB cuT each), and a ring of the last
 * STORE_HIST_N calibrations so tendon creep can be followed.
 *
 * Power-loss guarantee: settings, homes, windows and each tendon's learned targets are
 * kept in two slots (A and B). A slot holds
 *
 *     kind u8 | version u8 | seq u16 | body | crc u16      (little-endian)
 *
 * with a CRC-16/CCITT-FALSE over kind..body. A save always overwrites the
 * slot that does NOT hold the newest valid copy, so a power loss at any byte
 * leaves the newest valid copy untouched. It first sets the slot's kind byte
 * to STORE_KIND_NONE, then writes version, sequence, body and CRC, and the
 * kind byte last: a torn slot is invalid by its kind, not only (with
 * probability 1 - 2^-16) by its CRC. A load takes the valid slot with the newer sequence number
 * (serial arithmetic, so the counter may wrap). History entries are single-slot records in a ring:
 * a save overwrites the oldest entry only, so a cut write loses at most the entry it was replacing,
 * never the newest one.
 *
 * EEPROM access goes through store_eeprom_t (read byte, read block, ready,
 * write byte), so the AVR adapter (firmware/eeprom_port.c) is thin and the
 * tests use a RAM fake that can cut the power at any byte.
 *
 * Saves are non-blocking: store_save_*() only prepares a save; store_poll()
 * writes at most one byte per call, when the EEPROM is ready and the caller
 * says the robot is idle (writes only when idle; a save started before a
 * calibration simply pauses). Loads read synchronously: EEPROM reads take no
 * time and every record is at most STORE_SLOT_MAX bytes. A load during a save
 * is allowed and returns the previous copy (the slot being written is not
 * valid yet); on the AVR its first read may wait for the byte write in flight
 * (at most 3.4 ms).
 *
 * Error convention: 0 = done, negative = STORE_E_*, positive = in progress.
 *
 * EEPROM layout (bytes, 4096 in all; STORE_ADDR_* below are the source):
 *
 *   0x000  settings slot A      128 bytes (4 + 4*STORE_SETTING_COUNT + 2 used)
 *   0x080  settings slot B      128
 *   0x100  homes slot A         192 (4 + 184 + 2 used)
 *   0x1C0  homes slot B         192
 *   0x280  learned targets      24 slots of 64: tendon t at 0x280 + 128*t
 *                               (A) and +64 (B); 4 + 32 + 2 used
 *   0x880  history ring         STORE_HIST_N = 24 entries of 72 (4 + 64 + 2 used)
 *   0xF40  windows slot A       96 (4 + 80 + 2 used)
 *   0xFA0  windows slot B       96
 */
#ifndef HALLHOME_STORE_H
#define HALLHOME_STORE_H

#include <stddef.h>
#include <stdint.h>

#include "table/table.h"

/* Storage class of the settings declaration: program memory on the AVR
 * (the firmware build defines TBL_FLASH as __progmem__), plain const memory
 * on the host. Read it only through the copy function given to store_init. */
#ifndef STORE_FLASH
#ifdef TBL_FLASH
#define STORE_FLASH TBL_FLASH
#else
#define STORE_FLASH
#endif
#endif

/* 1: the settings' help texts are kept (store_setting_text() which 2); 0: not
 * (the firmware, which prints none: about 300 bytes of flash). The host tools
 * read them from store_settings.def itself. */
#ifndef STORE_SETTING_HELP
#define STORE_SETTING_HELP 1
#endif

enum {
    STORE_E_BUSY = -1,        /* a save is already in progress */
    STORE_E_EMPTY = -2,       /* no valid copy of the record (never saved, or both slots bad) */
    STORE_E_OTHER_TABLE = -3, /* record is valid but was made for another table_id */
    STORE_E_ARG = -4,         /* argument out of range (index, id, tendon, length) */
    STORE_E_RANGE = -5,       /* setting value outside its declared min..max */
    STORE_E_NAME = -6,        /* no setting of that name */
    STORE_E_VERIFY = -7,      /* read-back after a save did not match: EEPROM worn or cut */
    STORE_E_DEFAULTS = -8,    /* settings were missing/invalid: defaults restored */
    STORE_E_MOVED = -9,       /* spool turned while powered off: multi-turn position lost */
    STORE_E_IDLE = -10        /* store_poll() with no save started */
};

#define STORE_EEPROM_SIZE    4096u
#define STORE_MAX_TENDONS    TBL_MAX_TENDONS
#define STORE_TICKS_PER_TURN 4096L /* XL430 encoder ticks per revolution */
#define STORE_HIST_N         24u   /* history ring entries (>= 16 required) */

/* Record kinds (first byte of a slot) and their body format versions. */
#define STORE_KIND_SETTINGS    0x53u /* 'S' */
#define STORE_KIND_HOMES       0x48u /* 'H' */
#define STORE_KIND_LEARNED     0x4Cu /* 'L' */
#define STORE_KIND_HIST        0x52u /* 'R' */
#define STORE_KIND_WIN         0x57u /* 'W' */
#define STORE_KIND_NONE        0x00u /* slot being rewritten */
#define STORE_SETTINGS_VERSION 3u    /* raise when store_settings.def changes meaning/order */
#define STORE_HOMES_VERSION    2u
#define STORE_LEARNED_VERSION  2u /* 2: targets uint16 in table LSB (1: uint32 cuT) */
#define STORE_HIST_VERSION     1u
#define STORE_WIN_VERSION      1u

#define STORE_HDR_LEN 4u /* kind, version, seq (2) */
#define STORE_CRC_LEN 2u

/* ---- EEPROM interface ------------------------------------------------------ */

/* The EEPROM as the store sees it. ctx is passed back to every function.
 * write_byte() is only called when ready() returned nonzero, and must only
 * start the write (the AVR takes 3.4 ms per byte); ready() reports when the
 * next write may start. Reads are only called when ready() is nonzero or no
 * write was started since. */
typedef struct {
    void *ctx;
    uint8_t (*read_byte)(void *ctx, uint16_t addr);
    void (*read_block)(void *ctx, void *dst, uint16_t addr, uint16_t n);
    uint8_t (*ready)(void *ctx);
    void (*write_byte)(void *ctx, uint16_t addr, uint8_t value);
} store_eeprom_t;

/* A firmware with one EEPROM builds with -DSTORE_EE_FIXED=1: the store then
 * calls the board's functions below (the store_eeprom_t contracts without
 * ctx; defined by the board only when it builds so) directly, and the
 * store_eeprom_t given to store_init() is neither kept nor read (measured: 142 bytes less AVR
 * code). The default, 0, takes a store_eeprom_t per store, which the native tests fill with their
 * fakes. */
#ifndef STORE_EE_FIXED
#define STORE_EE_FIXED 0
#endif
uint8_t store_ee_read_byte(uint16_t addr);
void store_ee_read_block(void *dst, uint16_t addr, uint16_t n);
uint8_t store_ee_ready(void);
void store_ee_write_byte(uint16_t addr, uint8_t value);

/* ---- settings (declared once in store_settings.def) ------------------------- */

#define STORE_T_U8  0u
#define STORE_T_U16 1u
#define STORE_T_U32 2u
#define STORE_T_I32 3u

typedef enum {
#define STORE_SETTING(id, name, type, min, max, def, unit, help) STORE_SET_##id,
#include "store/store_settings.def"
#undef STORE_SETTING
    STORE_SETTING_COUNT
} store_setting_id_t;

#define STORE_SETTING_MAX 24u /* room reserved in the layout */

/* Every setting as a signed 32-bit integer in its declared unit. */
typedef struct {
    int32_t v[STORE_SETTING_COUNT];
} store_settings_t;

/* Numbers of one setting's declaration. */
typedef struct {
    int32_t min, max, def;
    uint8_t type; /* STORE_T_* */
} store_setting_info_t;

/* ---- homes ----------------------------------------------------------------- */

/* One tendon's home. Ticks are XL430 Present Position in extended position
 * mode, in the frame the servo had when the calibration ran. The *_turn
 * fields are the same positions modulo 4096 (0..4095): what the servo
 * reports after a power cycle, when its multi-turn count is lost. rest_ticks
 * is where the servo was left (slack) after the calibration or the last
 * release; store_recover_position() uses it to find the multi-turn position
 * again after power-up. */
typedef struct {
    int32_t home_ticks;
    int32_t rest_ticks;
    uint16_t home_turn;
    uint16_t rest_turn;
} store_home_t;

typedef struct {
    uint32_t table_id;  /* tbl_table_t.table_id the homes were made with */
    uint32_t cal_count; /* calibrations run so far, this one included */
    uint16_t tension_mN;
    uint16_t valid_mask; /* bit t set: tendon t has a home */
    uint8_t n_tendons;
    uint8_t reserved[3]; /* 0 */
    store_home_t t[STORE_MAX_TENDONS];
    /* straight-pose home minus home_ticks, per tendon (ticks): the final
     * move's goal with `home_pose` 1 (docs/homing.md, "Straight-pose homes") */
    int16_t to_straight[STORE_MAX_TENDONS];
} store_homes_t;

/* ---- learned targets --------------------------------------------------------- */

/* Model-free targets of one tendon, in the shape and unit of the table's
 * stored target row (tbl_target_row()): entry g is the target at the table's
 * grid tension g, in LSB of TBL_CUT_PER_LSB cuT (tbl_lsb_of_cuT()). grid_mask
 * bit g set means entry g was learned; the others fall back to the compiled
 * table. */
typedef struct {
    uint32_t table_id;
    uint8_t tendon;
    uint8_t n_grid;
    uint16_t grid_mask;
    uint16_t target_lsb[TBL_MAX_GRID];
} store_learned_t;

/* ---- history ------------------------------------------------------------------ */

/* One calibration in the ring. cal_count is the time stamp (the board has no
 * clock); home_ticks are in the frame of that calibration. */
typedef struct {
    uint32_t cal_count;
    uint32_t table_id;
    uint16_t tension_mN;
    uint16_t valid_mask;
    uint8_t n_tendons;
    uint8_t reserved[3];
    int32_t home_ticks[STORE_MAX_TENDONS];
} store_hist_t;

/* ---- engagement windows ------------------------------------------------------ */

/* One tendon's engagement window (docs/app.md, "Recovery"), kept for a power
 * cycle: the servo's Present Position modulo 4096 when it was saved (a
 * power-up keeps the single-turn angle and loses the turns) and the window's
 * bounds relative to that position. */
typedef struct {
    uint16_t at_turn;
    int16_t lo;
    int16_t hi;
} store_win_tendon_t;

typedef struct {
    uint32_t table_id;
    uint16_t mask; /* bit t set: t[t] holds a window */
    uint8_t n_tendons;
    uint8_t reserved; /* 0 */
    store_win_tendon_t t[STORE_MAX_TENDONS];
} store_win_t;

/* ---- layout ------------------------------------------------------------------- */

#define STORE_SLOT_LEN(body) (STORE_HDR_LEN + (body) + STORE_CRC_LEN)

#define STORE_ADDR_SETTINGS   0x000u
#define STORE_SETTINGS_STRIDE 0x080u
#define STORE_ADDR_HOMES      0x100u
#define STORE_HOMES_STRIDE    0x0C0u
#define STORE_ADDR_LEARNED    0x280u
#define STORE_LEARNED_STRIDE  0x040u /* slot A of tendon t: base + 2*t*stride */
#define STORE_ADDR_HIST       0x880u
#define STORE_HIST_STRIDE     0x048u
#define STORE_ADDR_WIN        (STORE_ADDR_HIST + STORE_HIST_N * STORE_HIST_STRIDE) /* 0xF40 */
#define STORE_WIN_STRIDE      0x060u
#define STORE_ADDR_END        (STORE_ADDR_WIN + 2u * STORE_WIN_STRIDE) /* 0x1000 */
#define STORE_SLOT_MAX        STORE_SLOT_LEN(sizeof(store_homes_t))

/* ---- state --------------------------------------------------------------------- */

typedef void (*store_copy_fn)(void *dst, const void *src, size_t n);

/* Caller-owned store state (21 bytes on the AVR with STORE_EE_FIXED). Treat as opaque. */
typedef struct {
#if !STORE_EE_FIXED
    const store_eeprom_t *ee;
#endif
    store_copy_fn copy;  /* reads the settings declaration (memcpy / memcpy_P) */
    const uint8_t *body; /* body of the record being saved (caller keeps it until done) */
    uint16_t addr;       /* slot being written */
    uint16_t len;        /* body length */
    uint16_t pos;        /* next byte of the slot to write */
    uint16_t crc;        /* CRC of bytes 0..pos-1 */
    uint16_t hist_seq;   /* seq of the newest history entry */
    uint8_t hdr[STORE_HDR_LEN];
    uint8_t hist_head; /* index of the newest history entry, or 0xFF when empty */
    uint8_t hist_slot; /* ring index of the history entry being saved */
    uint8_t state;
} store_t;

/* ---- functions ------------------------------------------------------------------ */

/* Binds the store to an EEPROM and the settings-declaration copy function
 * and scans the history ring for its newest entry. Returns 0. */
int8_t store_init(store_t *st, const store_eeprom_t *ee, store_copy_fn copy);

/* CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection) of n bytes
 * continuing from crc; start with 0xFFFF. Check value of "123456789": 0x29B1. */
uint16_t store_crc16(uint16_t crc, const void *data, size_t n);

/* Advances the save in progress by at most one byte write. may_write = 0
 * holds the save (robot not idle). Returns 1 while in progress, 0 when the
 * record is written and read back, STORE_E_VERIFY when the read-back failed
 * (the older copy is still valid), STORE_E_IDLE when no save was started. */
int8_t store_poll(store_t *st, uint8_t may_write);

/* Nonzero while a save is in progress. */
uint8_t store_busy(const store_t *st);

/* Settings. store_settings_defaults() fills every declared default.
 * store_settings_load() fills s from EEPROM and returns 0; when the record is
 * missing, bad or of another STORE_SETTINGS_VERSION it fills the defaults and
 * returns STORE_E_DEFAULTS; a single out-of-range value is replaced by its
 * default (also STORE_E_DEFAULTS). s is always usable afterwards.
 * store_save_settings() starts saving s (s must stay unchanged until
 * store_poll() returns 0): 1 started, STORE_E_BUSY. */
void store_settings_defaults(const store_t *st, store_settings_t *s);
int8_t store_settings_load(store_t *st, store_settings_t *s);
int8_t store_save_settings(store_t *st, const store_settings_t *s);

/* Sets setting id to value after checking its range: 0, STORE_E_ARG (id),
 * STORE_E_RANGE (value; s unchanged). */
int8_t store_setting_set(const store_t *st, store_settings_t *s, uint8_t id, int32_t value);

/* Declaration of setting id: 0 with *info filled, STORE_E_ARG. */
int8_t store_setting_info(const store_t *st, uint8_t id, store_setting_info_t *info);

/* Copies the NUL-terminated name (which = 0), unit (1) or help text (2, with
 * STORE_SETTING_HELP) of setting id into buf of capacity cap (truncated to
 * cap - 1 characters). Returns the full length of the text, or STORE_E_ARG
 * (id, which or cap 0). */
int16_t store_setting_text(const store_t *st, uint8_t id, uint8_t which, char *buf, uint8_t cap);

/* Id of the setting called name (len characters, not NUL-terminated), or
 * STORE_E_NAME. */
int8_t store_setting_find(const store_t *st, const char *name, uint8_t len);

/* Homes. store_homes_load() fills h with the newest valid copy: 0, or
 * STORE_E_EMPTY (h untouched), or STORE_E_OTHER_TABLE (h filled, but made for
 * another table than table_id: do not drive to these homes).
 * store_save_homes(): 1 started, STORE_E_BUSY, STORE_E_ARG (n_tendons too
 * large). Before saving, store_home_set() fills one tendon's entry with the
 * turn remainders computed, so the fields always agree. */
int8_t store_homes_load(store_t *st, uint32_t table_id, store_homes_t *h);
int8_t store_save_homes(store_t *st, const store_homes_t *h);
void store_home_set(store_home_t *e, int32_t home_ticks, int32_t rest_ticks);

/* Recovers the multi-turn position after a power cycle. present is the
 * XL430's Present Position read at power-up (within one turn; reduced modulo
 * 4096 here). Assumption: nothing turned the spool by more than tol ticks
 * (< 2048, half a turn) since the rest position was saved; the tendon rests
 * slack there. The position in the calibration's frame is then
 * rest_ticks + (present - rest_turn), the difference taken on the circle.
 * Returns 0 with *pos set; STORE_E_MOVED when the circular difference exceeds
 * tol (the spool was turned: re-home from scratch); STORE_E_ARG when the
 * entry is inconsistent (turn fields disagree with the tick counts) or tol
 * >= 2048. The app then uses offset = *pos - present to map stored homes
 * into the servo's new frame: home_now = home_ticks - offset. */
int8_t store_recover_position(const store_home_t *e, int32_t present, uint16_t tol, int32_t *pos);

/* Engagement windows. store_win_load(): 0, STORE_E_EMPTY, STORE_E_OTHER_TABLE
 * (w filled, other table). store_save_win(): 1 started, STORE_E_BUSY,
 * STORE_E_ARG (n_tendons too large).
 * store_win_recover() finds tendon e's window in the servo's frame after a
 * power-up: present is its Present Position then. Assumption: since the
 * save, the spool stood between below ticks under the window's lower bound
 * and above ticks over its upper bound (in ticks; e->lo is the bound on the
 * slack side and may be the upper one), a span under one turn. Returns 0
 * with *lo, *hi set (same order as e's); STORE_E_MOVED when present lies
 * outside that span (the spool was turned: the window is not used);
 * STORE_E_ARG when the span is a turn or more. */
int8_t store_win_load(store_t *st, uint32_t table_id, store_win_t *w);
int8_t store_save_win(store_t *st, const store_win_t *w);
int8_t store_win_recover(const store_win_tendon_t *e, int32_t present, uint16_t below,
                         uint16_t above, int32_t *lo, int32_t *hi);

/* Learned targets of tendon l->tendon. load: 0, STORE_E_EMPTY, STORE_E_ARG
 * (tendon), STORE_E_OTHER_TABLE (l filled, other table). save: 1 started,
 * STORE_E_BUSY, STORE_E_ARG (tendon or n_grid). */
int8_t store_learned_load(store_t *st, uint8_t tendon, uint32_t table_id, store_learned_t *l);
int8_t store_save_learned(store_t *st, const store_learned_t *l);

/* History. store_hist_count() returns how many consecutive entries, newest
 * first, are readable (0..STORE_HIST_N). store_hist_get() reads the entry
 * `age` calibrations back (0 = newest): 0, STORE_E_EMPTY (no such entry or it
 * was lost), STORE_E_ARG (age >= STORE_HIST_N). store_save_hist() appends e,
 * overwriting the oldest entry: 1 started, STORE_E_BUSY, STORE_E_ARG. */
uint8_t store_hist_count(store_t *st);
int8_t store_hist_get(store_t *st, uint8_t age, store_hist_t *e);
int8_t store_save_hist(store_t *st, const store_hist_t *e);

#endif /* HALLHOME_STORE_H */
