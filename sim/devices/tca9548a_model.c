#include "devices/tca9548a_model.h"

#include <string.h>

void tcam_init(tcam_t *m, uint8_t addr)
{
    memset(m, 0, sizeof(*m));
    m->addr = addr;
    m->present = 1;
}

int tcam_attach(tcam_t *m, uint8_t channel, simi2c_slave_t slave)
{
    if (channel >= TCAM_CHANNELS || m->n_down[channel] >= TCAM_PER_CHANNEL) {
        return -1;
    }
    m->down[channel][m->n_down[channel]++] = slave;
    return 0;
}

/* Enabled channels are wired straight through: every slave on them sees the
 * START, and the bus is a wired AND of the slaves that acknowledged. */
static uint8_t tcam_start(void *ctx, uint8_t addr_byte)
{
    tcam_t *m = ctx;
    uint8_t ack = 0;
    uint8_t ch, i;
    m->target = 0;
    m->reading = (uint8_t)(addr_byte & 1u);
    memset(m->acked, 0, sizeof(m->acked));
    if (m->present && (addr_byte >> 1) == m->addr) {
        m->target = 1;
        return 1;
    }
    for (ch = 0; ch < TCAM_CHANNELS; ch++) {
        if (!(m->ctrl & (1u << ch))) {
            continue;
        }
        for (i = 0; i < m->n_down[ch]; i++) {
            simi2c_slave_t *s = &m->down[ch][i];
            if (s->start(s->ctx, addr_byte)) {
                m->acked[ch] |= (uint8_t)(1u << i);
                ack = 1;
            }
        }
    }
    if (ack) {
        m->target = 2;
    }
    return ack;
}

static uint8_t tcam_write(void *ctx, uint8_t byte)
{
    tcam_t *m = ctx;
    uint8_t ack = 0;
    uint8_t ch, i;
    if (m->target == 1) {
        m->ctrl = byte;
        m->ctrl_writes++;
        return 1;
    }
    if (m->target != 2) {
        return 0;
    }
    for (ch = 0; ch < TCAM_CHANNELS; ch++) {
        for (i = 0; i < m->n_down[ch]; i++) {
            if (m->acked[ch] & (1u << i)) {
                simi2c_slave_t *s = &m->down[ch][i];
                ack = (uint8_t)(ack | s->write(s->ctx, byte));
            }
        }
    }
    return ack;
}

static uint8_t tcam_read(void *ctx, uint8_t master_ack)
{
    tcam_t *m = ctx;
    uint8_t v = 0xFFu;
    uint8_t ch, i;
    if (m->target == 1) {
        return m->ctrl;
    }
    if (m->target != 2) {
        return 0xFFu;
    }
    for (ch = 0; ch < TCAM_CHANNELS; ch++) {
        for (i = 0; i < m->n_down[ch]; i++) {
            if (m->acked[ch] & (1u << i)) {
                simi2c_slave_t *s = &m->down[ch][i];
                v &= s->read(s->ctx, master_ack);
            }
        }
    }
    return v;
}

/* STOP reaches every slave on an enabled channel, as on the wire. */
static void tcam_stop(void *ctx)
{
    tcam_t *m = ctx;
    uint8_t ch, i;
    for (ch = 0; ch < TCAM_CHANNELS; ch++) {
        if (!(m->ctrl & (1u << ch)) && !m->acked[ch]) {
            continue;
        }
        for (i = 0; i < m->n_down[ch]; i++) {
            simi2c_slave_t *s = &m->down[ch][i];
            s->stop(s->ctx);
        }
    }
    m->target = 0;
    memset(m->acked, 0, sizeof(m->acked));
}

static void tcam_advance(void *ctx, uint64_t now_us)
{
    tcam_t *m = ctx;
    uint8_t ch, i;
    for (ch = 0; ch < TCAM_CHANNELS; ch++) {
        for (i = 0; i < m->n_down[ch]; i++) {
            simi2c_slave_t *s = &m->down[ch][i];
            if (s->advance != NULL) {
                s->advance(s->ctx, now_us);
            }
        }
    }
}

simi2c_slave_t tcam_slave(tcam_t *m)
{
    simi2c_slave_t s;
    s.ctx = m;
    s.start = tcam_start;
    s.write = tcam_write;
    s.read = tcam_read;
    s.stop = tcam_stop;
    s.advance = tcam_advance;
    return s;
}
