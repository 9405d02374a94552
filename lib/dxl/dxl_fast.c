/*
 * Fast sync read (instruction 0x8A): the request, the view of its combined
 * reply and the master's handler for it. Kept apart from the plain status
 * packets of dxl.c.
 */
#include <stddef.h>

#include "dxl/dxl_priv.h"
#include "dxl/dxl_proto.h"

int8_t dxl_build_fast_sync_read(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                                const uint8_t *ids, uint8_t count, uint16_t *len)
{
    return dxl_build_group_read(buf, cap, DXL_INST_FAST_SYNC_READ, addr, n, ids, count, len);
}

/* The parser took INST 0x55 and the first block's ERR for the status
 * packet's INST and error byte, and the last block's CRC field for the
 * packet CRC: the blocks start one byte before st->params, and st->n plus
 * those three bytes must be exactly `count` blocks of ERR ID DATA CRC. */
int8_t dxl_fast_block_at(const dxl_status *st, uint16_t n, uint8_t count, uint8_t i,
                         dxl_fast_block *b)
{
    uint16_t per = (uint16_t)(n + 4u);
    if (st->id != DXL_BROADCAST_ID || i >= count || (uint32_t)st->n + 3u != (uint32_t)count * per) {
        return -DXL_E_MALFORMED;
    }
    const uint8_t *p = st->params - 1 + (uint16_t)(i * per);
    b->err = p[0];
    b->id = p[1];
    b->data = p + 2;
    return 0;
}

/* Settles the blocks of `mask` from the reply body in the parser buffer;
 * notes a CRC error when a block it holds did not check out. A block of an
 * ID not asked is counted as a wrong ID (dxl_claim); blocks land by the ID
 * they name, in whatever order. */
static void dxl_fast_take(dxl_master *m, uint16_t mask, uint8_t blocks)
{
    const uint8_t *b = m->parser.buf + 1;
    for (uint8_t i = 0; i < blocks; i++, b += m->n + 4u, mask >>= 1) {
        if ((mask & 1u) == 0) { /* bit i of the caller's mask */
            dxl_note(m, -DXL_E_CRC);
            continue;
        }
        dxl_reply *r = dxl_claim(m, b[1]);
        if (r != NULL) {
            dxl_settle(m, r, b[0], b + 2, (uint8_t)m->n); /* m->n: at most DXL_REPLY_DATA */
        }
    }
}

/* A complete reply (st) passed the packet CRC, which is the last block's
 * own check; every other block must also match its own CRC field: the last
 * servo computes the packet CRC over the bytes as it received them, so a
 * byte of an earlier block flipped on the wire would pass the packet CRC.
 * With st NULL (the attempt ended on a spoilt or cut-short reply) the blocks
 * that check out one by one are kept: only the servos from a silent one or
 * a flipped byte on are asked again, as with a plain sync read. */
void dxl_fast_on_status(dxl_master *m, const dxl_status *st)
{
    const dxl_parser *p = &m->parser; /* blk_ok: blocks checked on arrival */
    uint8_t count = m->n_reply;
    uint16_t mask = 0;
    uint8_t blocks = 0;
    if (p->id == DXL_BROADCAST_ID) {
        mask = p->blk_ok;
        blocks = p->blk_n < count ? p->blk_n : count;
    }
    if (st != NULL) {
        /* dxl_fast_block_at()'s check of the whole reply, in 16 bits: m->n
         * and count are within DXL_REPLY_DATA and DXL_MAX_IDS here */
        if (st->id != DXL_BROADCAST_ID || st->n + 3u != (uint16_t)(count * (m->n + 4u))) {
            dxl_malformed(m);
            return;
        }
        mask |= (uint16_t)(1u << (count - 1u));
        blocks = count;
    }
    dxl_fast_take(m, mask, blocks);
}

int8_t dxl_fast_sync_read(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids,
                          uint8_t count)
{
    return dxl_group_read(m, DXL_INST_FAST_SYNC_READ, addr, n, ids, count);
}
