#include "dxl/dxl_proto.h"

#include <stddef.h>

#include "dxl/dxl_priv.h"

/* Polynomial 0x8005 a byte at a time without a table: for x = top byte ^
 * byte, the table entry is (x << 1) ^ (x << 2), with 0x8003 added when x has
 * odd parity (the reduction by z^16 = z^15 + z^2 + 1, bit by bit). No flash
 * lookups and no 16-bit shifts by 4, which the AVR does one bit at a time:
 * the parser and the packet writer run it on every bus byte. */
uint16_t dxl_crc16_byte(uint16_t crc, uint8_t byte)
{
    uint8_t x = (uint8_t)((crc >> 8) ^ byte);
    uint8_t p = (uint8_t)(x ^ (x >> 4));
    uint16_t t = (uint16_t)((uint16_t)x << 1);
    p ^= (uint8_t)(p >> 2);
    p ^= (uint8_t)(p >> 1);
    t ^= (uint16_t)(t << 1);
    if (p & 1u) {
        t ^= 0x8003u;
    }
    return (uint16_t)((crc << 8) ^ t);
}

uint16_t dxl_crc16(uint16_t crc, const uint8_t *data, uint16_t n)
{
    for (uint16_t i = 0; i < n; i++) {
        crc = dxl_crc16_byte(crc, data[i]);
    }
    return crc;
}

uint32_t dxl_get_le(const uint8_t *p, uint8_t size)
{
    uint32_t v = 0;
    for (uint8_t i = size; i > 0; i--) {
        v = (v << 8) | p[i - 1u];
    }
    return v;
}

void dxl_put_le(uint8_t *p, uint32_t value, uint8_t size)
{
    for (uint8_t i = 0; i < size; i++, value >>= 8) {
        p[i] = (uint8_t)value;
    }
}

/* --- writer ------------------------------------------------------------------ */

/* The header every packet starts with, FF FF FD 00 (the writer puts it, the
 * parser looks for it), then the writer's placeholders for ID and LEN. */
static const uint8_t dxl_header[7] DXL_FLASH = {0xFF, 0xFF, 0xFD, 0x00, 0x00, 0x00, 0x00};

static void dxl_writer_raw(dxl_writer *w, uint8_t byte)
{
    if (w->pos < w->cap) {
        w->buf[w->pos++] = byte;
    } else {
        w->overflow = 1;
    }
}

void dxl_writer_begin(dxl_writer *w, uint8_t *buf, uint16_t cap, uint8_t id, uint8_t inst)
{
    w->buf = buf;
    w->cap = cap;
    w->pos = 0;
    w->overflow = 0;
    /* header, ID and LEN (filled in by dxl_writer_end()) */
    for (uint8_t i = 0; i < 7u; i++) {
        dxl_writer_raw(w, i == 4u ? id : DXL_FLASH_BYTE(&dxl_header[i]));
    }
    w->run = 0;
    dxl_writer_put(w, inst);
}

/* The pattern is matched on the bytes as given (an inserted FD never starts
 * a new match), which is how the e-manual and ROBOTIS's SDK define it. */
void dxl_writer_put(dxl_writer *w, uint8_t byte)
{
    dxl_writer_raw(w, byte);
    if (byte == 0xFF) {
        w->run = (uint8_t)(w->run < 2u ? w->run + 1u : 2u);
    } else if (byte == 0xFD && w->run == 2u) {
        dxl_writer_raw(w, 0xFD);
        w->run = 0;
    } else {
        w->run = 0;
    }
}

void dxl_writer_put_le(dxl_writer *w, uint32_t value, uint8_t size)
{
    for (uint8_t i = 0; i < size; i++, value >>= 8) {
        dxl_writer_put(w, (uint8_t)value);
    }
}

int8_t dxl_writer_end(dxl_writer *w, uint16_t *len)
{
    uint8_t *buf = w->buf;
    uint16_t pos = w->pos;
    *len = 0;
    if (w->overflow || pos + 2u > w->cap) {
        w->overflow = 1;
        return -DXL_E_NOSPACE;
    }
    uint16_t field = (uint16_t)(pos - 7u + 2u);
    buf[5] = (uint8_t)field;
    buf[6] = (uint8_t)(field >> 8);
    uint16_t crc = dxl_crc16(0, buf, pos);
    buf[pos] = (uint8_t)crc;
    buf[pos + 1u] = (uint8_t)(crc >> 8);
    w->pos = (uint16_t)(pos + 2u);
    *len = w->pos;
    return 0;
}

/* --- builders ------------------------------------------------------------------ */

static int8_t dxl_check_unicast(uint8_t id, uint16_t *len)
{
    *len = 0;
    return id > DXL_MAX_ID ? -DXL_E_ARG : 0;
}

static int8_t dxl_check_any(uint8_t id, uint16_t *len)
{
    *len = 0;
    return (id > DXL_MAX_ID && id != DXL_BROADCAST_ID) ? -DXL_E_ARG : 0;
}

static int8_t dxl_build_simple(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t inst, uint16_t *len)
{
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, inst);
    return dxl_writer_end(&w, len);
}

int8_t dxl_build_ping(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len)
{
    int8_t rc = dxl_check_any(id, len);
    return rc != 0 ? rc : dxl_build_simple(buf, cap, id, DXL_INST_PING, len);
}

int8_t dxl_build_read(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr, uint16_t n,
                      uint16_t *len)
{
    int8_t rc = dxl_check_unicast(id, len);
    if (rc != 0 || n == 0) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, DXL_INST_READ);
    dxl_writer_put_le(&w, addr, 2);
    dxl_writer_put_le(&w, n, 2);
    return dxl_writer_end(&w, len);
}

static int8_t dxl_build_write_inst(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t inst,
                                   uint16_t addr, const uint8_t *data, uint16_t n, uint16_t *len)
{
    int8_t rc = dxl_check_any(id, len);
    if (rc != 0 || n == 0 || data == NULL) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, inst);
    dxl_writer_put_le(&w, addr, 2);
    for (uint16_t i = 0; i < n; i++) {
        dxl_writer_put(&w, data[i]);
    }
    return dxl_writer_end(&w, len);
}

int8_t dxl_build_write(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr, const uint8_t *data,
                       uint16_t n, uint16_t *len)
{
    return dxl_build_write_inst(buf, cap, id, DXL_INST_WRITE, addr, data, n, len);
}

int8_t dxl_build_reg_write(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr,
                           const uint8_t *data, uint16_t n, uint16_t *len)
{
    return dxl_build_write_inst(buf, cap, id, DXL_INST_REG_WRITE, addr, data, n, len);
}

int8_t dxl_build_action(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len)
{
    int8_t rc = dxl_check_any(id, len);
    return rc != 0 ? rc : dxl_build_simple(buf, cap, id, DXL_INST_ACTION, len);
}

int8_t dxl_build_reboot(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len)
{
    int8_t rc = dxl_check_any(id, len);
    return rc != 0 ? rc : dxl_build_simple(buf, cap, id, DXL_INST_REBOOT, len);
}

int8_t dxl_build_factory_reset(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t mode, uint32_t guard,
                               uint16_t *len)
{
    int8_t rc = dxl_check_any(id, len);
    if (guard != DXL_FACTORY_RESET_GUARD) {
        return -DXL_E_GUARD;
    }
    if (rc != 0 || (mode != DXL_RESET_ALL && mode != DXL_RESET_KEEP_ID &&
                    mode != DXL_RESET_KEEP_ID_AND_BAUD)) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, DXL_INST_FACTORY_RESET);
    dxl_writer_put(&w, mode);
    return dxl_writer_end(&w, len);
}

int8_t dxl_build_clear_multiturn(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len)
{
    static const uint8_t key[4] = {0x44, 0x58, 0x4C, 0x22}; /* e-manual, "Clear" */
    int8_t rc = dxl_check_any(id, len);
    if (rc != 0) {
        return rc;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, DXL_INST_CLEAR);
    dxl_writer_put(&w, DXL_CLEAR_MULTITURN);
    for (uint8_t i = 0; i < 4u; i++) {
        dxl_writer_put(&w, key[i]);
    }
    return dxl_writer_end(&w, len);
}

static int8_t dxl_check_ids(const uint8_t *ids, uint8_t count)
{
    if (ids == NULL || count == 0) {
        return -DXL_E_ARG;
    }
    for (uint8_t i = 0; i < count; i++) {
        if (ids[i] > DXL_MAX_ID) {
            return -DXL_E_ARG;
        }
    }
    return 0;
}

int8_t dxl_build_group_read(uint8_t *buf, uint16_t cap, uint8_t inst, uint16_t addr, uint16_t n,
                            const uint8_t *ids, uint8_t count, uint16_t *len)
{
    *len = 0;
    if (n == 0 || dxl_check_ids(ids, count) != 0) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, DXL_BROADCAST_ID, inst);
    dxl_writer_put_le(&w, addr, 2);
    dxl_writer_put_le(&w, n, 2);
    for (uint8_t i = 0; i < count; i++) {
        dxl_writer_put(&w, ids[i]);
    }
    return dxl_writer_end(&w, len);
}

int8_t dxl_build_sync_read(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                           const uint8_t *ids, uint8_t count, uint16_t *len)
{
    return dxl_build_group_read(buf, cap, DXL_INST_SYNC_READ, addr, n, ids, count, len);
}

int8_t dxl_build_sync_write(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                            const uint8_t *ids, const uint8_t *data, uint8_t count, uint16_t *len)
{
    *len = 0;
    if (n == 0 || data == NULL || dxl_check_ids(ids, count) != 0) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, DXL_BROADCAST_ID, DXL_INST_SYNC_WRITE);
    dxl_writer_put_le(&w, addr, 2);
    dxl_writer_put_le(&w, n, 2);
    for (uint8_t i = 0; i < count; i++) {
        dxl_writer_put(&w, ids[i]);
        for (uint16_t k = 0; k < n; k++) {
            dxl_writer_put(&w, data[(uint16_t)(i * n + k)]);
        }
    }
    return dxl_writer_end(&w, len);
}

static int8_t dxl_build_bulk(uint8_t *buf, uint16_t cap, uint8_t inst, const dxl_bulk_item *items,
                             uint8_t count, uint16_t *len)
{
    *len = 0;
    if (items == NULL || count == 0) {
        return -DXL_E_ARG;
    }
    for (uint8_t i = 0; i < count; i++) {
        if (items[i].id > DXL_MAX_ID || items[i].n == 0 ||
            (inst == DXL_INST_BULK_WRITE && items[i].data == NULL)) {
            return -DXL_E_ARG;
        }
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, DXL_BROADCAST_ID, inst);
    for (uint8_t i = 0; i < count; i++) {
        dxl_writer_put(&w, items[i].id);
        dxl_writer_put_le(&w, items[i].addr, 2);
        dxl_writer_put_le(&w, items[i].n, 2);
        if (inst == DXL_INST_BULK_WRITE) {
            for (uint16_t k = 0; k < items[i].n; k++) {
                dxl_writer_put(&w, items[i].data[k]);
            }
        }
    }
    return dxl_writer_end(&w, len);
}

int8_t dxl_build_bulk_read(uint8_t *buf, uint16_t cap, const dxl_bulk_item *items, uint8_t count,
                           uint16_t *len)
{
    return dxl_build_bulk(buf, cap, DXL_INST_BULK_READ, items, count, len);
}

int8_t dxl_build_bulk_write(uint8_t *buf, uint16_t cap, const dxl_bulk_item *items, uint8_t count,
                            uint16_t *len)
{
    return dxl_build_bulk(buf, cap, DXL_INST_BULK_WRITE, items, count, len);
}

int8_t dxl_build_status(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t err, const uint8_t *params,
                        uint16_t n, uint16_t *len)
{
    *len = 0;
    if (id > DXL_BROADCAST_ID || (n > 0 && params == NULL)) {
        return -DXL_E_ARG;
    }
    dxl_writer w;
    dxl_writer_begin(&w, buf, cap, id, DXL_INST_STATUS);
    dxl_writer_put(&w, err);
    for (uint16_t i = 0; i < n; i++) {
        dxl_writer_put(&w, params[i]);
    }
    return dxl_writer_end(&w, len);
}

/* --- parser ---------------------------------------------------------------------- */

enum {
    DXL_PS_H1,
    DXL_PS_H2,
    DXL_PS_H3,
    DXL_PS_RSRV,
    DXL_PS_ID,
    DXL_PS_LEN_L,
    DXL_PS_LEN_H,
    DXL_PS_BODY,
    DXL_PS_CRC_L,
    DXL_PS_CRC_H
};

void dxl_parser_init(dxl_parser *p, uint8_t *buf, uint16_t cap)
{
    p->buf = buf;
    p->cap = cap;
    p->raw = 0;
    p->block = 0;
#if DXL_STATS
    p->stats = (dxl_parse_stats){0, 0, 0, 0, 0, 0};
#endif
    dxl_parser_reset(p);
}

DXL_NOINLINE void dxl_parser_reset(dxl_parser *p)
{
    p->state = DXL_PS_H1;
    p->body_len = 0;
    p->blk_ok = 0;
    p->blk_n = 0;
    p->remaining = 0;
    p->run = 0;
}

void dxl_parser_set_raw(dxl_parser *p, uint8_t raw)
{
    p->raw = raw;
}

static void dxl_parser_header_seen(dxl_parser *p)
{
    p->crc = DXL_CRC_HEADER;
    p->state = DXL_PS_ID;
}

/* FF FF FD inside a body must be followed by the stuffing FD; anything else
 * is the start of another packet, so the current one was cut short. */
static int8_t dxl_parser_body(dxl_parser *p, uint8_t byte)
{
    if (!p->raw && p->run == 3u) {
        p->run = 0;
        if (byte != 0xFD) {
            DXL_COUNT(p->stats.truncated++);
            if (byte == 0x00) {
                dxl_parser_header_seen(p);
            } else {
                DXL_COUNT(p->stats.garbage = (uint16_t)(p->stats.garbage + 1u));
                p->state = byte == 0xFF ? DXL_PS_H2 : DXL_PS_H1;
            }
            return -DXL_E_TRUNCATED;
        }
    } else {
        uint8_t run = p->run;
        if (byte == 0xFF) {
            run = (uint8_t)(run < 2u ? run + 1u : 2u);
        } else if (byte == 0xFD && run == 2u) {
            run = 3;
        } else {
            run = 0;
        }
        p->run = run;
        uint16_t len = p->body_len;
        if (len >= p->cap) {
            DXL_COUNT(p->stats.overflow++);
            p->state = DXL_PS_H1;
            return -DXL_E_OVERFLOW;
        }
        p->buf[len] = byte;
        p->body_len = (uint16_t)(len + 1u);
        uint16_t block = p->block;
        if (block != 0) {
            /* blk_pos starts at 0xFFFF for INST, then counts within a block */
            uint16_t k = p->blk_pos++;
            if (k == (uint16_t)(block - 2u)) {
                p->blk_crc = p->crc; /* CRC up to the end of the block's data */
            } else if (k == (uint16_t)(block - 1u)) {
                if ((uint16_t)(p->buf[len - 1u] | (uint16_t)byte << 8) == p->blk_crc &&
                    p->blk_n < 16u) {
                    p->blk_ok |= (uint16_t)(1u << p->blk_n);
                }
                p->blk_n++;
                p->blk_pos = 0;
            }
        }
    }
    p->crc = dxl_crc16_byte(p->crc, byte);
    p->tail[0] = p->tail[1];
    p->tail[1] = p->tail[2];
    p->tail[2] = p->tail[3];
    p->tail[3] = byte;
    if (p->tail_n < 4u) {
        p->tail_n++;
    }
    if (--p->remaining == 0) {
        p->state = DXL_PS_CRC_L;
    }
    return 1;
}

/* A packet cut short near its end leaves the next header in the last body
 * bytes and the CRC field: look for it there. At most six bytes are fed
 * again and a packet is at least ten, so this never recurses further; nor
 * do they get past its LEN, so the tail they are fed from stays as it is.
 * The bytes were already counted as part of the bad packet, not as garbage. */
DXL_NOINLINE static void dxl_parser_rescan(dxl_parser *p)
{
    uint16_t crc = p->rx_crc;
#if DXL_STATS
    uint16_t garbage = p->stats.garbage;
#endif
    p->state = DXL_PS_H1;
    for (uint8_t i = (uint8_t)(4u - p->tail_n); i < 4u; i++) {
        (void)dxl_parser_feed(p, p->tail[i]);
    }
    (void)dxl_parser_feed(p, (uint8_t)crc);
    (void)dxl_parser_feed(p, (uint8_t)(crc >> 8));
#if DXL_STATS
    p->stats.garbage = garbage;
#endif
}

/* Header search: states H1..RSRV are the number of header bytes matched.
 * On a mismatch the search goes on from the longest header prefix that ends
 * the bytes seen (only FF can start one: FF FF FF keeps two, FF FF FD FF one)
 * and every byte left behind counts as garbage. */
static void dxl_parser_hunt(dxl_parser *p, uint8_t byte)
{
    uint8_t k = p->state;
    if (byte == DXL_FLASH_BYTE(&dxl_header[k])) {
        if (k == DXL_PS_RSRV) {
            dxl_parser_header_seen(p);
        } else {
            p->state = (uint8_t)(k + 1u);
        }
        return;
    }
    uint8_t next = byte != 0xFF ? DXL_PS_H1 : (k == DXL_PS_H3 ? DXL_PS_H3 : DXL_PS_H2);
    DXL_COUNT(p->stats.garbage = (uint16_t)(p->stats.garbage + k + 1u - next));
    p->state = next;
}

int8_t dxl_parser_feed(dxl_parser *p, uint8_t byte)
{
    uint8_t state = p->state;
    if (state < DXL_PS_ID) {
        dxl_parser_hunt(p, byte);
        return 1;
    }
    if (state == DXL_PS_BODY) {
        return dxl_parser_body(p, byte);
    }
    if (state == DXL_PS_ID || state == DXL_PS_LEN_L) {
        if (state == DXL_PS_LEN_L) {
            p->remaining = byte;
        } else if (byte == 0xFF) {
            DXL_COUNT(p->stats.garbage = (uint16_t)(p->stats.garbage + 4u));
            p->state = DXL_PS_H2;
            return 1;
        } else {
            p->id = byte;
        }
        p->crc = dxl_crc16_byte(p->crc, byte);
        p->state = (uint8_t)(state + 1u); /* on to LEN_L, LEN_H */
        return 1;
    }
    if (state == DXL_PS_LEN_H) {
        uint16_t field = (uint16_t)(p->remaining | ((uint16_t)byte << 8));
        /* Stuffing adds at most one byte per three, so a raw body longer than
         * 4/3 of the buffer cannot fit once unstuffed. */
        uint16_t third = (uint16_t)(p->cap / 3u);
        uint16_t room = (uint16_t)(UINT16_MAX - third);
        uint16_t most = p->cap < room ? (uint16_t)(p->cap + third + 1u) : UINT16_MAX; /* any LEN */
        if (field < 3u || (uint16_t)(field - 2u) > most) {
            DXL_COUNT(p->stats.length++);
            p->state = DXL_PS_H1;
            return -DXL_E_LENGTH;
        }
        p->crc = dxl_crc16_byte(p->crc, byte);
        p->remaining = (uint16_t)(field - 2u);
        p->body_len = 0;
        p->run = 0;
        p->tail_n = 0;
        p->blk_pos = UINT16_MAX;
        p->blk_ok = 0;
        p->blk_n = 0;
        p->state = DXL_PS_BODY;
        return 1;
    }
    if (state == DXL_PS_CRC_L) {
        p->rx_crc = byte;
        p->state = DXL_PS_CRC_H;
        return 1;
    }
    if (state == DXL_PS_CRC_H) {
        p->rx_crc = (uint16_t)(p->rx_crc | ((uint16_t)byte << 8));
        p->state = DXL_PS_H1;
        if (p->rx_crc != p->crc) {
            DXL_COUNT(p->stats.crc++);
            dxl_parser_rescan(p);
            return -DXL_E_CRC;
        }
        DXL_COUNT(p->stats.packets++);
        return 0;
    }
    dxl_parser_reset(p);
    return 1;
}

int8_t dxl_parser_status(const dxl_parser *p, dxl_status *st)
{
    if (p->body_len < 2u || p->buf[0] != DXL_INST_STATUS) {
        return -DXL_E_MALFORMED;
    }
    st->id = p->id;
    st->err = p->buf[1];
    st->params = p->buf + 2;
    st->n = (uint16_t)(p->body_len - 2u);
    return 0;
}
