/*
 * The DYNAMIXEL Protocol 2.0 master: the transaction engine (an attempt
 * sent, its replies taken byte by byte and settled per servo, retries,
 * deadlines, the results read back) and the requests that start a
 * transaction, one per instruction. The bring-up is in dxl_bringup.c
 * (dxl_priv.h lists the files).
 */
#include "dxl/dxl.h"

#include <stddef.h>

#include "dxl/dxl_priv.h"

enum { DXL_PH_IDLE, DXL_PH_SEND, DXL_PH_WAIT_TX, DXL_PH_RECV };

#define DXL_PENDING    1 /* reply[].result while the reply is awaited */
#define DXL_READ_CHUNK 12u
/* chunks per poll: bounds the time one poll takes (the 256-byte receive
 * buffer holds the rest of a long reply). A reply byte costs the AVR about
 * 12 us to take; 24 bytes a poll take the 16-byte reply of one servo at
 * once and leave the pass that takes the last bytes of six servos' reply
 * (56) room to settle them and send the next request (dxl_launch()): three
 * chunks of 16 made the fine approach's worst pass 4.05 ms, and its mean
 * 1.60 ms (1.46 ms now). */
#define DXL_READ_ROUNDS 2u
/* chunks drained before an attempt: 48 bytes of late replies, as before */
#define DXL_DRAIN_ROUNDS 4u

static uint8_t dxl_time_reached(uint32_t now, uint32_t t)
{
    return (int32_t)(now - t) >= 0;
}

static uint32_t dxl_now(const dxl_master *m)
{
    return DXL_PORT_NOW_US(m);
}

void dxl_config_default(dxl_config *cfg, uint32_t baud, uint8_t bits_per_byte)
{
    cfg->retries = 2;
    cfg->byte_us = (uint16_t)((1000000UL * bits_per_byte + baud - 1u) / baud);
    cfg->timeout_us = 1500;
    cfg->tx_slack_us = 2000;
}

void dxl_master_init(dxl_master *m, const dxl_port *port, const dxl_config *cfg)
{
#if DXL_PORT_FIXED
    (void)port;
#else
    m->port = *port;
#endif
    m->cfg = *cfg;
    dxl_parser_init(&m->parser, m->rx, DXL_RX_CAP);
#if DXL_STATS
    m->stats = (dxl_master_stats){0, 0, 0, 0, 0, 0};
#endif
    m->n_reply = 0;
    m->expect = 0;
    m->got = 0;
    m->phase = DXL_PH_IDLE;
    m->result = 0;
}

uint8_t dxl_busy(const dxl_master *m)
{
    return m->phase != DXL_PH_IDLE;
}

/* Late replies to an abandoned request would otherwise be taken for the
 * answer to the next one. */
static void dxl_drain(dxl_master *m)
{
    uint8_t chunk[DXL_READ_CHUNK];
    for (uint8_t round = 0; round < DXL_DRAIN_ROUNDS; round++) {
        uint16_t got = DXL_PORT_READ(m, chunk, DXL_READ_CHUNK);
        if (got == 0) {
            break;
        }
        DXL_COUNT(m->stats.stale = (uint16_t)(m->stats.stale + got));
    }
}

static void dxl_begin_attempt(dxl_master *m)
{
    dxl_drain(m);
    dxl_parser_reset(&m->parser);
    uint8_t fast = m->inst == DXL_INST_FAST_SYNC_READ;
    dxl_parser_set_raw(&m->parser, fast);
    m->parser.block = fast ? (uint16_t)(m->n + 4u) : 0u;
    m->attempt_err = 0;
    uint8_t got = 0;
    for (uint8_t i = 0; i < m->n_reply; i++) {
        if (m->reply[i].result != DXL_PENDING) {
            got++;
        }
    }
    m->got = got;
    m->tx_sent = 0;
    DXL_COUNT(m->stats.requests++);
    DXL_PORT_SET_DIR(m, DXL_DIR_TX);
    m->phase = DXL_PH_SEND;
}

static void dxl_finish(dxl_master *m, int8_t err)
{
    int8_t result = 0;
    for (uint8_t i = 0; i < m->n_reply; i++) {
        if (m->reply[i].result == DXL_PENDING) {
            m->reply[i].result = err;
            m->reply[i].len = 0;
        }
        if (result == 0) {
            result = m->reply[i].result;
        }
    }
    m->result = m->n_reply == 0 ? err : result;
    m->phase = DXL_PH_IDLE;
    DXL_PORT_SET_DIR(m, DXL_DIR_RX);
}

static void dxl_end_attempt(dxl_master *m, int8_t err)
{
    if (err == -DXL_E_TIMEOUT) {
        DXL_COUNT(m->stats.timeouts++);
        if (m->attempt_err != 0) {
            err = m->attempt_err;
        }
    }
    if (m->attempt < m->cfg.retries) {
        m->attempt++;
        DXL_COUNT(m->stats.retries++);
        dxl_begin_attempt(m);
        return;
    }
    dxl_finish(m, err);
}

void dxl_note(dxl_master *m, int8_t err)
{
    if (m->attempt_err == 0) {
        m->attempt_err = err;
    }
}

static dxl_reply *dxl_pending_for(dxl_master *m, uint8_t id)
{
    dxl_reply *r = m->reply;
    for (uint8_t i = 0; i < m->n_reply; i++, r++) {
        if (r->id == id && r->result == DXL_PENDING) {
            return r;
        }
    }
    return NULL;
}

dxl_reply *dxl_claim(dxl_master *m, uint8_t id)
{
    dxl_reply *r = dxl_pending_for(m, id);
    if (r == NULL && dxl_reply_for(m, id) == NULL) {
        /* answered already is fine: a retried group request asks everyone again */
        DXL_COUNT(m->stats.wrong_id++);
        dxl_note(m, -DXL_E_WRONG_ID);
    }
    return r;
}

void dxl_malformed(dxl_master *m)
{
    DXL_COUNT(m->stats.malformed++);
    dxl_note(m, -DXL_E_MALFORMED);
}

/* The error number makes the data meaningless; the alert bit alone only says
 * that Hardware Error Status is nonzero, the data is still the servo's. */
DXL_NOINLINE void dxl_settle(dxl_master *m, dxl_reply *r, uint8_t err, const uint8_t *data,
                             uint8_t n)
{
    r->err = err;
    r->len = n;
    for (uint8_t i = 0; i < n; i++) {
        r->data[i] = data[i];
    }
    if ((uint8_t)(err & DXL_ERR_NUMBER_MASK) != 0) {
        r->result = -DXL_E_SERVO;
    } else if ((err & DXL_ERR_ALERT) != 0) {
        r->result = -DXL_E_ALERT;
    } else {
        r->result = 0;
    }
    m->got++;
}

static void dxl_on_packet(dxl_master *m)
{
    dxl_status st;
    if (dxl_parser_status(&m->parser, &st) != 0) {
        return; /* an instruction packet (our own echo on an unbuffered bus) */
    }
    if (m->inst == DXL_INST_FAST_SYNC_READ) {
        dxl_fast_on_status(m, &st);
        return;
    }
    dxl_reply *r = dxl_claim(m, st.id);
    if (r == NULL) {
        return;
    }
    uint16_t want = r->len;
    if (st.n != want && !((st.err & DXL_ERR_NUMBER_MASK) != 0 && st.n == 0)) {
        dxl_malformed(m);
        return;
    }
    dxl_settle(m, r, st.err, st.params, (uint8_t)st.n); /* r->len or 0 */
}

static uint16_t dxl_reply_bytes(const dxl_master *m)
{
    if (m->inst == DXL_INST_FAST_SYNC_READ) {
        return (uint16_t)(8u + m->n_reply * (m->n + 4u));
    }
    uint16_t most = 0;
    for (uint8_t i = 0; i < m->n_reply; i++) {
        most = (uint16_t)(most + 11u + m->reply[i].len);
    }
    return most;
}

static void dxl_recv(dxl_master *m)
{
    uint8_t chunk[DXL_READ_CHUNK];
    uint8_t fast = m->inst == DXL_INST_FAST_SYNC_READ;
    for (uint8_t round = 0; round < DXL_READ_ROUNDS && m->got < m->expect; round++) {
        uint16_t n = DXL_PORT_READ(m, chunk, DXL_READ_CHUNK);
        if (n == 0) {
            break;
        }
        m->heard_by = dxl_now(m) + m->cfg.timeout_us;
        for (uint16_t i = 0; i < n; i++) {
            int8_t rc = dxl_parser_feed(&m->parser, chunk[i]);
            if (rc == 0) {
                dxl_on_packet(m);
                if (fast && m->got < m->expect && m->attempt_err != 0) {
                    /* the one combined reply is in, with bad blocks: retry now */
                    dxl_end_attempt(m, m->attempt_err);
                    return;
                }
            } else if (rc < 0) {
                dxl_note(m, rc == -DXL_E_CRC ? -DXL_E_CRC : -DXL_E_MALFORMED);
                if (fast) {
                    dxl_fast_on_status(m, NULL); /* keep the blocks that check out */
                }
                if (m->got >= m->expect) {
                    dxl_finish(m, 0);
                    return;
                }
                if (m->expect == 1u || fast) {
                    /* the one reply is spoilt and the bus is free: retry now */
                    dxl_end_attempt(m, m->attempt_err);
                    return;
                }
            }
        }
    }
    /* A request that no servo heard (a byte corrupted on the way) gets no
     * reply at all, and a reply whose header or length byte was corrupted
     * leaves the parser waiting for bytes that never come: waiting out the
     * whole allowance of a sync read of every servo (18 ms for twelve) held
     * the goals a pull needed (chaos seeds 1024, 2042: tendons taken up
     * 22-29 ms too long, 1.48-1.98 x their target). The line quiet for
     * timeout_us ends the attempt. */
    if (m->got >= m->expect) {
        dxl_finish(m, 0);
    } else if (dxl_time_reached(dxl_now(m), m->deadline) ||
               dxl_time_reached(dxl_now(m), m->heard_by)) {
        if (fast) {
            dxl_fast_on_status(m, NULL);
        }
        if (m->got >= m->expect) {
            dxl_finish(m, 0);
        } else {
            dxl_end_attempt(m, -DXL_E_TIMEOUT);
        }
    }
}

/* Queues what the port takes of the request; once all of it is queued the
 * port must finish sending it in time. */
static void dxl_send(dxl_master *m)
{
    uint16_t len = m->tx_len;
    uint16_t sent = m->tx_sent;
    sent = (uint16_t)(sent + DXL_PORT_WRITE(m, m->tx + sent, (uint16_t)(len - sent)));
    m->tx_sent = sent;
    if (sent >= len) {
        m->deadline = dxl_now(m) + (uint32_t)len * m->cfg.byte_us + m->cfg.tx_slack_us;
        m->phase = DXL_PH_WAIT_TX;
    }
}

int8_t dxl_poll(dxl_master *m)
{
    uint8_t phase = m->phase;
    if (phase == DXL_PH_SEND) {
        dxl_send(m); /* still sending after it: phase SEND or WAIT_TX */
    } else if (phase == DXL_PH_WAIT_TX) {
        if (!DXL_PORT_TX_DONE(m)) {
            if (dxl_time_reached(dxl_now(m), m->deadline)) {
                dxl_finish(m, -DXL_E_PORT);
            }
        } else if (m->expect == 0) {
            dxl_finish(m, 0);
        } else {
            uint32_t allow = (uint32_t)m->expect * m->cfg.timeout_us +
                             (uint32_t)dxl_reply_bytes(m) * m->cfg.byte_us;
            uint32_t now = dxl_now(m);
            m->deadline = now + allow;
            m->heard_by = now + m->cfg.timeout_us;
            m->phase = DXL_PH_RECV;
            dxl_recv(m);
        }
    } else if (phase == DXL_PH_RECV) {
        dxl_recv(m);
    }
    return m->phase == DXL_PH_IDLE ? m->result : 1;
}

void dxl_abort(dxl_master *m)
{
    if (m->phase != DXL_PH_IDLE) {
#if DXL_PORT_FIXED
        /* The board's port sends straight from m->tx: the next request is
         * built there only once the bytes under way have left (at most
         * DXL_TX_CAP of them, 1 ms at 1 Mbps; the deadline bounds it). */
        while (m->phase == DXL_PH_WAIT_TX && !DXL_PORT_TX_DONE(m) &&
               !dxl_time_reached(dxl_now(m), m->deadline)) {
        }
#endif
        dxl_finish(m, -DXL_E_TIMEOUT);
    }
}

const dxl_reply *dxl_reply_for(const dxl_master *m, uint8_t id)
{
    const dxl_reply *r = m->reply;
    for (uint8_t i = 0; i < m->n_reply; i++, r++) {
        if (r->id == id) {
            return r;
        }
    }
    return NULL;
}

DXL_NOINLINE int32_t dxl_reply_value(const dxl_reply *r, uint8_t size)
{
    if (r == NULL || r->len < size || (size != 1u && size != 2u && size != 4u)) {
        return 0;
    }
    uint32_t v = dxl_get_le(r->data, size);
    if (size == 1u) {
        return (int8_t)v;
    }
    if (size == 2u) {
        return (int16_t)v;
    }
    return (int32_t)v;
}

/* --- starting transactions --------------------------------------------------------- */

DXL_NOINLINE static int8_t dxl_prepare(dxl_master *m, uint8_t inst, uint16_t addr, uint16_t n)
{
    if (m->phase != DXL_PH_IDLE) {
        return -DXL_E_BUSY;
    }
    m->inst = inst;
    m->addr = addr;
    m->n = n;
    m->n_reply = 0;
    m->expect = 0;
    m->attempt = 0;
    return 0;
}

DXL_NOINLINE static void dxl_expect(dxl_master *m, uint8_t id, uint16_t n)
{
    dxl_reply *r = &m->reply[m->n_reply++];
    r->id = id;
    r->result = DXL_PENDING;
    r->err = 0;
    r->len = (uint8_t)n;
    m->expect++;
}

static int8_t dxl_launch(dxl_master *m, int8_t built)
{
    if (built != 0) {
        m->n_reply = 0;
        m->expect = 0;
        return built;
    }
    dxl_begin_attempt(m);
    /* The request goes out now, not at the next poll: the main loop polls
     * once a pass (1.4 ms on the AVR), and a read took three passes (send,
     * turn round, receive). Sent at its start, a short read is back by the
     * next pass. A retry still waits for the next poll: the spoilt reply
     * before it may not have ended. */
    dxl_send(m);
    return 1;
}

/* A unicast request expects one status packet carrying `n` data bytes; a
 * broadcast one expects nothing. */
static int8_t dxl_simple(dxl_master *m, uint8_t id, uint16_t n, int8_t built)
{
    if (built == 0 && id != DXL_BROADCAST_ID) {
        dxl_expect(m, id, n);
    }
    return dxl_launch(m, built);
}

/* Builds and starts the request of dxl_single() or dxl_group(), which
 * checked its arguments: instruction m->inst to `id`; then `addr`, except in
 * a ping or reboot; then `n`, except in a write. Then its blocks: a single
 * request has one, a group request one per servo of ids[0..count), which
 * starts with the servo's ID. A write's block carries the next `n` bytes of
 * data; each block but a sync write's and a broadcast's expects a reply of
 * `want` data bytes. One writer sequence for every request the firmware
 * sends. */
static int8_t dxl_request(dxl_master *m, uint8_t id, uint16_t addr, uint16_t n, const uint8_t *data,
                          const uint8_t *ids, uint8_t count, uint16_t want)
{
    uint8_t inst = m->inst;
    uint8_t write = inst == DXL_INST_WRITE || inst == DXL_INST_SYNC_WRITE;
    dxl_writer w;
    dxl_writer_begin(&w, m->tx, DXL_TX_CAP, id, inst);
    if (inst != DXL_INST_PING && inst != DXL_INST_REBOOT) {
        dxl_writer_put_le(&w, addr, 2);
        if (inst != DXL_INST_WRITE) {
            dxl_writer_put_le(&w, n, 2);
        }
    }
    uint8_t blocks = count != 0u ? count : 1u;
    for (uint8_t i = 0; i < blocks; i++) {
        if (count != 0u) {
            id = ids[i];
            if (id > DXL_MAX_ID) {
                return dxl_launch(m, -DXL_E_ARG); /* drops the replies expected so far */
            }
            dxl_writer_put(&w, id);
        }
        if (write) {
            for (uint16_t k = 0; k < n; k++) {
                dxl_writer_put(&w, *data++);
            }
        }
        if (inst != DXL_INST_SYNC_WRITE && id != DXL_BROADCAST_ID) {
            dxl_expect(m, id, want);
        }
    }
    return dxl_launch(m, dxl_writer_end(&w, &m->tx_len));
}

/* Ping, read, write and reboot of one servo (write and reboot also to the
 * broadcast ID): one copy of the checks for the four transactions bring-up
 * and the app use, instead of one per instruction. A read sends `addr` and
 * `n`, a write `addr` and data[0..n); `want` is the reply's data length. */
static int8_t dxl_single(dxl_master *m, uint8_t inst, uint8_t id, uint16_t addr,
                         const uint8_t *data, uint16_t n, uint16_t want)
{
    int8_t rc = dxl_prepare(m, inst, addr, want);
    if (rc != 0) {
        return rc;
    }
    uint8_t any_id = inst == DXL_INST_WRITE || inst == DXL_INST_REBOOT;
    if ((id > DXL_MAX_ID && !(any_id && id == DXL_BROADCAST_ID)) || want > DXL_REPLY_DATA ||
        (inst == DXL_INST_READ && n == 0) || (inst == DXL_INST_WRITE && (n == 0 || data == NULL))) {
        return -DXL_E_ARG;
    }
    return dxl_request(m, id, addr, n, data, NULL, 0, want);
}

int8_t dxl_ping(dxl_master *m, uint8_t id)
{
    return dxl_single(m, DXL_INST_PING, id, 0, NULL, 0, 3);
}

int8_t dxl_read(dxl_master *m, uint8_t id, uint16_t addr, uint16_t n)
{
    return dxl_single(m, DXL_INST_READ, id, addr, NULL, n, n);
}

int8_t dxl_write(dxl_master *m, uint8_t id, uint16_t addr, const uint8_t *data, uint16_t n)
{
    return dxl_single(m, DXL_INST_WRITE, id, addr, data, n, 0);
}

int8_t dxl_write_value(dxl_master *m, uint8_t id, uint16_t addr, uint32_t value, uint8_t size)
{
    uint8_t data[4];
    if (size != 1u && size != 2u && size != 4u) {
        return -DXL_E_ARG;
    }
    dxl_put_le(data, value, size);
    return dxl_write(m, id, addr, data, size);
}

int8_t dxl_reg_write(dxl_master *m, uint8_t id, uint16_t addr, const uint8_t *data, uint16_t n)
{
    int8_t rc = dxl_prepare(m, DXL_INST_REG_WRITE, addr, 0);
    if (rc != 0) {
        return rc;
    }
    return dxl_simple(m, id, 0,
                      dxl_build_reg_write(m->tx, DXL_TX_CAP, id, addr, data, n, &m->tx_len));
}

int8_t dxl_action(dxl_master *m, uint8_t id)
{
    int8_t rc = dxl_prepare(m, DXL_INST_ACTION, 0, 0);
    if (rc != 0) {
        return rc;
    }
    return dxl_simple(m, id, 0, dxl_build_action(m->tx, DXL_TX_CAP, id, &m->tx_len));
}

int8_t dxl_reboot(dxl_master *m, uint8_t id)
{
    return dxl_single(m, DXL_INST_REBOOT, id, 0, NULL, 0, 0);
}

int8_t dxl_factory_reset(dxl_master *m, uint8_t id, uint8_t mode, uint32_t guard)
{
    int8_t rc = dxl_prepare(m, DXL_INST_FACTORY_RESET, 0, 0);
    if (rc != 0) {
        return rc;
    }
    return dxl_simple(m, id, 0,
                      dxl_build_factory_reset(m->tx, DXL_TX_CAP, id, mode, guard, &m->tx_len));
}

int8_t dxl_clear_multiturn(dxl_master *m, uint8_t id)
{
    int8_t rc = dxl_prepare(m, DXL_INST_CLEAR, 0, 0);
    if (rc != 0) {
        return rc;
    }
    return dxl_simple(m, id, 0, dxl_build_clear_multiturn(m->tx, DXL_TX_CAP, id, &m->tx_len));
}

/* Sync read, fast sync read and sync write: one broadcast request naming
 * `addr`, `n` and every servo of ids[0..count), each ID followed by its `n`
 * bytes of `data` in a write; a read expects one reply of `n` data bytes
 * from each. Checked here and built by dxl_request(), not by the codec's
 * builders (which the tests and the servo model use). */
static int8_t dxl_group(dxl_master *m, uint8_t inst, uint16_t addr, uint16_t n, const uint8_t *ids,
                        const uint8_t *data, uint8_t count)
{
    int8_t rc = dxl_prepare(m, inst, addr, n);
    if (rc != 0) {
        return rc;
    }
    if (ids == NULL || count == 0 || n == 0) {
        return -DXL_E_ARG;
    }
    /* a write needs its data, a read room for its replies */
    if (inst == DXL_INST_SYNC_WRITE ? data == NULL : (count > DXL_MAX_IDS || n > DXL_REPLY_DATA)) {
        return -DXL_E_ARG;
    }
    return dxl_request(m, DXL_BROADCAST_ID, addr, n, data, ids, count, n);
}

int8_t dxl_group_read(dxl_master *m, uint8_t inst, uint16_t addr, uint16_t n, const uint8_t *ids,
                      uint8_t count)
{
    return dxl_group(m, inst, addr, n, ids, NULL, count);
}

int8_t dxl_sync_read(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids, uint8_t count)
{
    return dxl_group_read(m, DXL_INST_SYNC_READ, addr, n, ids, count);
}

int8_t dxl_sync_write(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids,
                      const uint8_t *data, uint8_t count)
{
    return dxl_group(m, DXL_INST_SYNC_WRITE, addr, n, ids, data, count);
}

int8_t dxl_bulk_read(dxl_master *m, const dxl_bulk_item *items, uint8_t count)
{
    int8_t rc = dxl_prepare(m, DXL_INST_BULK_READ, 0, 0);
    if (rc != 0) {
        return rc;
    }
    if (items == NULL || count == 0 || count > DXL_MAX_IDS) {
        return -DXL_E_ARG;
    }
    for (uint8_t i = 0; i < count; i++) {
        if (items[i].n > DXL_REPLY_DATA) {
            return -DXL_E_ARG;
        }
    }
    int8_t built = dxl_build_bulk_read(m->tx, DXL_TX_CAP, items, count, &m->tx_len);
    if (built == 0) {
        for (uint8_t i = 0; i < count; i++) {
            dxl_expect(m, items[i].id, items[i].n);
        }
    }
    return dxl_launch(m, built);
}

int8_t dxl_bulk_write(dxl_master *m, const dxl_bulk_item *items, uint8_t count)
{
    int8_t rc = dxl_prepare(m, DXL_INST_BULK_WRITE, 0, 0);
    if (rc != 0) {
        return rc;
    }
    return dxl_launch(m, dxl_build_bulk_write(m->tx, DXL_TX_CAP, items, count, &m->tx_len));
}
