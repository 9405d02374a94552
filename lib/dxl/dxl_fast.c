/*
 * Fast sync read (instruction 0x8A): the request, the view of its combined
 * reply and the master's handler for it. Kept apart from the plain status
 * packets of dxl.c so that a firmware that never asks for it does not carry
 * it (the master reaches dxl_fast_on_status only through m->on_status).
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

/* Each block settles the reply of the ID it names, in whatever order (as
 * ROBOTIS's SDK reads them); a block of an ID not asked is counted as a
 * wrong ID and the others still count. */
static void dxl_fast_on_status(dxl_master *m, const dxl_status *st)
{
    dxl_fast_block b;
    for (uint8_t i = 0; i < m->n_reply; i++) {
        if (dxl_fast_block_at(st, m->n, m->n_reply, i, &b) != 0) {
            dxl_malformed(m);
            return;
        }
        dxl_reply *r = dxl_claim(m, b.id);
        if (r != NULL) {
            dxl_settle(m, r, b.err, b.data, m->n);
        }
    }
}

int8_t dxl_fast_sync_read(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids,
                          uint8_t count)
{
    int8_t rc = dxl_group_read(m, DXL_INST_FAST_SYNC_READ, addr, n, ids, count);
    if (rc > 0) {
        m->on_status = dxl_fast_on_status;
    }
    return rc;
}
