/*
 * table_pack: builds a table in RAM from natural units, for code that makes
 * tables at run time instead of compiling a generated one (the plant model of
 * the simulator and the tests). The firmware never packs: its table comes from
 * `hallhome tables` (host_tools/hallhome/tablegen.py), which applies the same
 * rounding and the same range checks.
 *
 * Error convention: 0 = done, negative = TBL_E_* code (table.h).
 */
#ifndef HALLHOME_TABLE_PACK_H
#define HALLHOME_TABLE_PACK_H

#include <stdint.h>

#include "table/table.h"

/* A whole table in natural units, every array at its TBL_MAX_* size; only the
 * first n_* entries are packed. magic and format_version are packed as given
 * (a test may set wrong ones on purpose). */
typedef struct {
    uint32_t magic;          /* TBL_MAGIC */
    uint16_t format_version; /* TBL_FORMAT_VERSION */
    uint32_t table_id;
    char name[TBL_NAME_LEN];
    uint8_t n_tendons;
    uint8_t n_sensors;
    uint8_t n_grid;
    uint8_t mode;
    uint16_t grid_mN[TBL_MAX_GRID];
    uint16_t default_mN;
    uint16_t noise_cuT;
    tbl_sensor_t sensors[TBL_MAX_SENSORS];
    tbl_tendon_t tendons[TBL_MAX_TENDONS];
} tbl_wide_t;

/* Room for the largest table, aligned like the header. */
typedef union {
    tbl_head_t head;
    uint8_t bytes[TBL_SIZE_MAX];
} tbl_buf_t;

/* The packed table in buf, as the accessors take it (tbl_src_t.table). */
static inline const tbl_table_t *tbl_buf_table(const tbl_buf_t *buf)
{
    return (const tbl_table_t *)(const void *)buf;
}

/* Packs w into buf: fields rounded to the nearest LSB, lengths and the spool
 * factor stored as they are. Returns 0; TBL_E_ARG (NULL, or counts above the
 * TBL_MAX_* maxima); TBL_E_RANGE (a value that does not fit its stored type:
 * a field above TBL_FIELD_CUT_MAX or outside int16 LSB, a length or spool
 * factor above 65535). buf is fully written (zero-filled past the table). */
int tbl_pack(const tbl_wide_t *w, tbl_buf_t *buf);

/* Reads the table at src back into natural units (every field through the
 * accessors, so fields come back as whole LSB in cuT). Returns 0, or the
 * tbl_check() error (w is then untouched). */
int tbl_unpack(const tbl_src_t *src, tbl_wide_t *w);

#endif /* HALLHOME_TABLE_PACK_H */
