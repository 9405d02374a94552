/*
 * Fast sync read (lib/dxl/dxl_fast.c): the request bytes, the view of the
 * combined reply, and the master fed hand-made replies (good, reordered,
 * corrupted, cut off by a silent servo, wrong IDs, servo errors) and then
 * the next transaction, which must not suffer from what came before.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "dxl/dxl.h"
#include "dxl/dxl_xl430_reg.h"
#include "dxl_fakebus.h"

#define REPLY_CAP 160u

/* A fast sync read reply as a chain of servos sends it: header and LEN from
 * the first, per servo ERR ID DATA(n) and the running CRC, the last CRC being
 * the packet's. A byte flipped on the wire (flip_at >= 0, XOR 0x10) is flipped
 * after its sender computed its CRC, and every later servo computes its CRC
 * over it as received. Returns the length. */
static uint16_t make_chain(uint8_t *out, const uint8_t *ids, const uint8_t *errs,
                           const uint32_t *values, uint8_t count, uint8_t n, int32_t flip_at)
{
    uint16_t field = (uint16_t)(1u + count * (n + 4u));
    const uint8_t hdr[8] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, (uint8_t)field, (uint8_t)(field >> 8),
                            0x55};
    memcpy(out, hdr, 8);
    uint16_t pos = 8;
    for (uint8_t i = 0; i < count; i++) {
        out[pos++] = errs != NULL ? errs[i] : 0u;
        out[pos++] = ids[i];
        dxl_put_le(out + pos, values[i], n);
        pos = (uint16_t)(pos + n);
        uint16_t crc = dxl_crc16(0, out, pos);
        out[pos++] = (uint8_t)crc;
        out[pos++] = (uint8_t)(crc >> 8);
        if (flip_at >= 0 && flip_at < (int32_t)pos) {
            out[flip_at] ^= 0x10;
            flip_at = -1;
        }
    }
    return pos;
}

static uint16_t make_reply(uint8_t *out, const uint8_t *ids, const uint8_t *errs,
                           const uint32_t *values, uint8_t count, uint8_t n)
{
    return make_chain(out, ids, errs, values, count, n, -1);
}

/* Feeds bytes to a raw-mode parser; returns the last result and counts the
 * complete packets in *packets. */
static int8_t feed(dxl_parser *p, const uint8_t *b, uint16_t n, uint8_t *packets)
{
    int8_t rc = 1;
    for (uint16_t i = 0; i < n; i++) {
        rc = dxl_parser_feed(p, b[i]);
        if (rc == 0 && packets != NULL) {
            (*packets)++;
        }
    }
    return rc;
}

static void test_request_is_sync_read_with_instruction_0x8a(void **state)
{
    (void)state;
    uint8_t fast[32];
    uint8_t plain[32];
    uint16_t fast_len = 0;
    uint16_t plain_len = 0;
    const uint8_t ids[2] = {3, 7};
    assert_int_equal(dxl_build_fast_sync_read(fast, sizeof fast, 132, 4, ids, 2, &fast_len), 0);
    assert_int_equal(dxl_build_sync_read(plain, sizeof plain, 132, 4, ids, 2, &plain_len), 0);
    /* FF FF FD 00 FE 09 00 8A 84 00 04 00 03 07 CRC_L CRC_H */
    const uint8_t head[14] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00,
                              0x8A, 0x84, 0x00, 0x04, 0x00, 0x03, 0x07};
    assert_int_equal(fast_len, 16);
    assert_memory_equal(fast, head, 14);
    uint16_t crc = dxl_crc16(0, fast, 14);
    assert_int_equal(fast[14], (uint8_t)crc);
    assert_int_equal(fast[15], (uint8_t)(crc >> 8));
    assert_int_equal(plain_len, fast_len);
    assert_int_equal(plain[7], 0x82);
    assert_memory_equal(plain + 8, fast + 8, 6);
    /* the same argument checks as the plain sync read */
    const uint8_t bad[1] = {253};
    assert_int_equal(dxl_build_fast_sync_read(fast, sizeof fast, 132, 4, bad, 1, &fast_len),
                     -DXL_E_ARG);
    assert_int_equal(fast_len, 0);
    assert_int_equal(dxl_build_fast_sync_read(fast, sizeof fast, 132, 0, ids, 2, &fast_len),
                     -DXL_E_ARG);
    assert_int_equal(dxl_build_fast_sync_read(fast, sizeof fast, 132, 4, ids, 0, &fast_len),
                     -DXL_E_ARG);
    assert_int_equal(dxl_build_fast_sync_read(fast, 15, 132, 4, ids, 2, &fast_len), -DXL_E_NOSPACE);
}

static void test_blocks_of_a_reply(void **state)
{
    (void)state;
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {3, 7, 1};
    const uint8_t errs[3] = {0x00, 0x80, 0x07};
    const uint32_t values[3] = {0x000000A6u, 0xFFFFFD00u, 0x01020304u};
    uint16_t len = make_reply(reply, ids, errs, values, 3, 4);
    assert_int_equal(len, 8u + 3u * 8u);
    uint8_t buf[64];
    dxl_parser p;
    dxl_parser_init(&p, buf, sizeof buf);
    dxl_parser_set_raw(&p, 1);
    uint8_t packets = 0;
    assert_int_equal(feed(&p, reply, len, &packets), 0);
    assert_int_equal(packets, 1);
    dxl_status st;
    assert_int_equal(dxl_parser_status(&p, &st), 0);
    dxl_fast_block b;
    for (uint8_t i = 0; i < 3; i++) {
        assert_int_equal(dxl_fast_block_at(&st, 4, 3, i, &b), 0);
        assert_int_equal(b.id, ids[i]);
        assert_int_equal(b.err, errs[i]);
        assert_int_equal(dxl_get_le(b.data, 4), values[i]);
    }
    /* the view refuses what does not match the request */
    assert_int_equal(dxl_fast_block_at(&st, 4, 3, 3, &b), -DXL_E_MALFORMED);
    assert_int_equal(dxl_fast_block_at(&st, 4, 2, 0, &b), -DXL_E_MALFORMED);
    assert_int_equal(dxl_fast_block_at(&st, 4, 4, 0, &b), -DXL_E_MALFORMED);
    assert_int_equal(dxl_fast_block_at(&st, 2, 3, 0, &b), -DXL_E_MALFORMED);
    st.id = 3; /* a plain status packet of one servo is not a fast reply */
    assert_int_equal(dxl_fast_block_at(&st, 4, 3, 0, &b), -DXL_E_MALFORMED);
}

/* Data holding FF FF FD is sent as is: raw mode takes it, and the normal
 * (unstuffing) mode would read the next byte as a new header. */
static void test_unstuffed_data_in_raw_mode(void **state)
{
    (void)state;
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[2] = {1, 2};
    const uint32_t values[2] = {0x00FDFFFFu, 0xFDFFFF00u};
    uint16_t len = make_reply(reply, ids, NULL, values, 2, 4);
    uint8_t buf[64];
    dxl_parser p;
    dxl_parser_init(&p, buf, sizeof buf);
    dxl_parser_set_raw(&p, 1);
    assert_int_equal(feed(&p, reply, len, NULL), 0);
    dxl_status st;
    dxl_fast_block b;
    assert_int_equal(dxl_parser_status(&p, &st), 0);
    assert_int_equal(dxl_fast_block_at(&st, 4, 2, 1, &b), 0);
    assert_int_equal(dxl_get_le(b.data, 4), values[1]);
    dxl_parser_set_raw(&p, 0);
    assert_true(feed(&p, reply, len, NULL) != 0);
    assert_true(p.stats.truncated >= 1u);
}

/* A flipped bit anywhere costs the packet (one CRC covers all blocks); a
 * packet right after it is still found and parsed. */
static void test_corruption_then_next_packet(void **state)
{
    (void)state;
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[2] = {1, 2};
    const uint32_t values[2] = {100, 200};
    uint16_t len = make_reply(reply, ids, NULL, values, 2, 4);
    uint8_t buf[64];
    dxl_parser p;
    dxl_parser_init(&p, buf, sizeof buf);
    dxl_parser_set_raw(&p, 1);
    for (uint16_t at = 7; at < len; at++) {
        uint8_t bad[REPLY_CAP];
        memcpy(bad, reply, len);
        bad[at] ^= 0x10;
        dxl_parser_reset(&p);
        uint16_t crc_before = p.stats.crc;
        uint8_t packets = 0;
        assert_int_equal(feed(&p, bad, len, &packets), -DXL_E_CRC);
        assert_int_equal(packets, 0);
        assert_int_equal(p.stats.crc, crc_before + 1u);
        dxl_parser_reset(&p);
        packets = 0;
        assert_int_equal(feed(&p, reply, len, &packets), 0);
        assert_int_equal(packets, 1);
    }
    /* without a reset in between: the good packet after a bad one */
    uint8_t two[2 * REPLY_CAP];
    memcpy(two, reply, len);
    two[12] ^= 0x01;
    memcpy(two + len, reply, len);
    dxl_parser_reset(&p);
    uint8_t packets = 0;
    assert_int_equal(feed(&p, two, (uint16_t)(2u * len), &packets), 0);
    assert_int_equal(packets, 1);
}

/* ---- the master, fed hand-made replies on a bus without servos ---------- */

typedef struct {
    dxl_fakebus bus;
    dxl_master m;
    dxl_port port;
} rig;

static rig R;

static void rig_init(uint8_t retries)
{
    dxl_fakebus_init(&R.bus, 1000000, 10);
    dxl_fakebus_port(&R.bus, &R.port);
    dxl_config cfg;
    dxl_config_default(&cfg, 1000000, 10);
    cfg.retries = retries;
    dxl_master_init(&R.m, &R.port, &cfg);
}

/* Starts a fast sync read of Present Position, lets the request leave, then
 * puts `reply` on the wire and runs the master to its end. */
static int8_t ask(const uint8_t *ids, uint8_t count, const uint8_t *reply, uint16_t len)
{
    assert_int_equal(dxl_fast_sync_read(&R.m, DXL_XL430_PRESENT_POSITION_ADDR, 4, ids, count), 1);
    for (uint16_t us = 0; us < 400u; us++) {
        dxl_fakebus_advance(&R.bus, 1);
        (void)dxl_poll(&R.m);
    }
    if (len > 0) {
        dxl_fakebus_inject(&R.bus, reply, len);
    }
    return dxl_fakebus_run(&R.bus, &R.m, 100000);
}

static void test_master_settles_every_block(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {4, 2, 9};
    const uint32_t values[3] = {4000, (uint32_t)-20, 123456};
    uint16_t len = make_reply(reply, ids, NULL, values, 3, 4);
    assert_int_equal(ask(ids, 3, reply, len), 0);
    for (uint8_t i = 0; i < 3; i++) {
        const dxl_reply *r = dxl_reply_for(&R.m, ids[i]);
        assert_non_null(r);
        assert_int_equal(r->result, 0);
        assert_int_equal(dxl_reply_value(r, 4), (int32_t)values[i]);
    }
    /* blocks in another order still land by ID, as the SDK reads them */
    const uint8_t swapped[3] = {9, 4, 2};
    const uint32_t sv[3] = {9, 4, 2};
    len = make_reply(reply, swapped, NULL, sv, 3, 4);
    assert_int_equal(ask(ids, 3, reply, len), 0);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 9), 4), 9);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 2), 4), 2);
}

static void test_master_error_and_alert_per_servo(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {1, 2, 3};
    const uint8_t errs[3] = {0x00, 0x80, 0x07};
    const uint32_t values[3] = {10, 20, 0};
    uint16_t len = make_reply(reply, ids, errs, values, 3, 4);
    assert_int_equal(ask(ids, 3, reply, len), -DXL_E_ALERT);
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, 0);
    assert_int_equal(dxl_reply_for(&R.m, 2)->result, -DXL_E_ALERT);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 2), 4), 20); /* data still valid */
    assert_int_equal(dxl_reply_for(&R.m, 3)->result, -DXL_E_SERVO);
    assert_int_equal(dxl_reply_for(&R.m, 3)->err, 0x07);
    assert_int_equal(R.m.stats.retries, 0); /* a servo error is an answer */
}

static void test_master_wrong_id_and_wrong_length(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[2] = {1, 2};
    const uint8_t answered[2] = {1, 5};
    const uint32_t values[2] = {10, 50};
    uint16_t len = make_reply(reply, answered, NULL, values, 2, 4);
    assert_int_equal(ask(ids, 2, reply, len), -DXL_E_WRONG_ID);
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, 0);
    assert_int_equal(dxl_reply_for(&R.m, 2)->result, -DXL_E_WRONG_ID);
    assert_int_equal(R.m.stats.wrong_id, 1);
    /* blocks of 2 bytes for a request of 4: malformed, nothing settled */
    len = make_reply(reply, ids, NULL, values, 2, 2);
    assert_int_equal(ask(ids, 2, reply, len), -DXL_E_MALFORMED);
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, -DXL_E_MALFORMED);
    assert_int_equal(dxl_reply_for(&R.m, 2)->result, -DXL_E_MALFORMED);
    assert_int_equal(R.m.stats.malformed, 1);
}

/* A silent servo breaks the chain: header and the blocks before it, then
 * nothing. Every servo times out; the next request is answered normally. */
static void test_master_broken_chain_then_next_request(void **state)
{
    (void)state;
    rig_init(1);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {1, 2, 3};
    const uint32_t values[3] = {10, 20, 30};
    uint16_t len = make_reply(reply, ids, NULL, values, 3, 4);
    uint16_t cut = (uint16_t)(8u + 8u); /* header and servo 1's block; 2 is silent */
    assert_int_equal(ask(ids, 3, reply, cut), -DXL_E_TIMEOUT);
    /* servo 1's block checks out on its own CRC: kept, as a sync read would */
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, 0);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 1), 4), 10);
    assert_int_equal(dxl_reply_for(&R.m, 2)->result, -DXL_E_TIMEOUT);
    assert_int_equal(dxl_reply_for(&R.m, 3)->result, -DXL_E_TIMEOUT);
    assert_int_equal(R.m.stats.retries, 1);
    /* the rest of the broken reply arrives late: drained as stale, then the
     * next request gets its own reply */
    dxl_fakebus_inject(&R.bus, reply + cut, (uint16_t)(len - cut));
    assert_int_equal(ask(ids, 3, reply, len), 0);
    assert_true(R.m.stats.stale >= (uint16_t)(len - cut));
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 3), 4), 30);
    /* a plain read after the fast one parses stuffed status packets again */
    uint8_t st[16];
    uint16_t st_len = 0;
    const uint8_t data[4] = {0xFF, 0xFF, 0xFD, 0x00};
    assert_int_equal(dxl_build_status(st, sizeof st, 1, 0, data, 4, &st_len), 0);
    assert_int_equal(dxl_read(&R.m, 1, DXL_XL430_PRESENT_POSITION_ADDR, 4), 1);
    for (uint16_t us = 0; us < 400u; us++) {
        dxl_fakebus_advance(&R.bus, 1);
        (void)dxl_poll(&R.m);
    }
    dxl_fakebus_inject(&R.bus, st, st_len);
    assert_int_equal(dxl_fakebus_run(&R.bus, &R.m, 100000), 0);
    assert_int_equal(dxl_get_le(dxl_reply_for(&R.m, 1)->data, 4), 0x00FDFFFFu);
}

/* Feeds `len` bytes of a reply to a raw parser checking blocks of `per`
 * bytes; returns blk_ok and stores blk_n. */
static uint16_t blocks_ok(const uint8_t *bytes, uint16_t len, uint16_t per, uint8_t *n)
{
    uint8_t buf[REPLY_CAP];
    dxl_parser p;
    dxl_parser_init(&p, buf, sizeof buf);
    dxl_parser_set_raw(&p, 1);
    p.block = per;
    (void)feed(&p, bytes, len, NULL);
    *n = p.blk_n;
    return p.blk_ok;
}

/* Block CRC fields, checked by the parser as they arrive: a cut keeps the
 * blocks whose CRC field arrived; a byte flipped on the wire spoils only its
 * own block, whose sender computed the CRC before the flip (the later
 * servos compute theirs over it as received); the last block's field is the
 * packet CRC, not counted here. */
static void test_verified_blocks(void **state)
{
    (void)state;
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {1, 2, 3};
    const uint32_t values[3] = {10, 20, 30};
    uint16_t len = make_reply(reply, ids, NULL, values, 3, 4);
    uint8_t n = 0;
    assert_int_equal(blocks_ok(reply, len, 8, &n), 0x3);
    assert_int_equal(n, 2);
    for (uint16_t cut = 0; cut < len; cut++) {
        uint16_t whole = cut < 8u ? 0u : (uint16_t)((cut - 8u) / 8u);
        if (whole > 2u) {
            whole = 2u;
        }
        assert_int_equal(blocks_ok(reply, cut, 8, &n), (1u << whole) - 1u);
        assert_int_equal(n, whole);
    }
    for (uint16_t at = 8; at < (uint16_t)(len - 8u); at++) {
        uint8_t bad[REPLY_CAP];
        make_chain(bad, ids, NULL, values, 3, 4, at);
        uint16_t block = (uint16_t)((at - 8u) / 8u);
        assert_int_equal(blocks_ok(bad, len, 8, &n), 0x3u & ~(1u << block));
        assert_int_equal(n, 2);
    }
    /* no block size set: nothing checked */
    assert_int_equal(blocks_ok(reply, len, 0, &n), 0);
    assert_int_equal(n, 0);
}

/* A byte of servo 1's data flipped on the wire: the last servo's packet CRC
 * covers it as received and passes, servo 1's own CRC field does not. Its
 * data is refused; the others are kept. */
static void test_master_wire_flip_passing_the_packet_crc(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {1, 2, 3};
    const uint32_t values[3] = {10, 20, 30};
    uint16_t len = make_chain(reply, ids, NULL, values, 3, 4, 8 + 2 + 3); /* value byte 3 */
    uint16_t crc = dxl_crc16(0, reply, (uint16_t)(len - 2u));
    assert_int_equal(reply[len - 2u] | reply[len - 1u] << 8, crc); /* the packet CRC passes */
    assert_int_equal(ask(ids, 3, reply, len), -DXL_E_CRC);
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, -DXL_E_CRC);
    assert_int_equal(dxl_reply_for(&R.m, 1)->len, 0);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 2), 4), 20);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 3), 4), 30);
    assert_int_equal(R.m.stats.retries, 0);
}

/* A flipped byte in the last block: the blocks before it are kept, the
 * last servo gets the CRC error. */
static void test_master_corrupt_last_block_keeps_the_others(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[3] = {1, 2, 3};
    const uint32_t values[3] = {10, 20, 30};
    uint16_t len = make_reply(reply, ids, NULL, values, 3, 4);
    reply[8u + 16u + 3u] ^= 0x01; /* servo 3's data */
    assert_int_equal(ask(ids, 3, reply, len), -DXL_E_CRC);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 1), 4), 10);
    assert_int_equal(dxl_reply_value(dxl_reply_for(&R.m, 2), 4), 20);
    assert_int_equal(dxl_reply_for(&R.m, 3)->result, -DXL_E_CRC);
}

/* A flipped byte in the first block costs every servo's answer. */
static void test_master_corrupt_reply_is_lost_whole(void **state)
{
    (void)state;
    rig_init(0);
    uint8_t reply[REPLY_CAP];
    const uint8_t ids[2] = {1, 2};
    const uint32_t values[2] = {10, 20};
    uint16_t len = make_reply(reply, ids, NULL, values, 2, 4);
    reply[10] ^= 0x40;
    assert_int_equal(ask(ids, 2, reply, len), -DXL_E_CRC);
    assert_int_equal(dxl_reply_for(&R.m, 1)->result, -DXL_E_CRC);
    assert_int_equal(dxl_reply_for(&R.m, 2)->result, -DXL_E_CRC);
    assert_int_equal(dxl_reply_for(&R.m, 2)->len, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_request_is_sync_read_with_instruction_0x8a),
        cmocka_unit_test(test_blocks_of_a_reply),
        cmocka_unit_test(test_unstuffed_data_in_raw_mode),
        cmocka_unit_test(test_corruption_then_next_packet),
        cmocka_unit_test(test_master_settles_every_block),
        cmocka_unit_test(test_master_error_and_alert_per_servo),
        cmocka_unit_test(test_master_wrong_id_and_wrong_length),
        cmocka_unit_test(test_master_broken_chain_then_next_request),
        cmocka_unit_test(test_verified_blocks),
        cmocka_unit_test(test_master_wire_flip_passing_the_packet_crc),
        cmocka_unit_test(test_master_corrupt_last_block_keeps_the_others),
        cmocka_unit_test(test_master_corrupt_reply_is_lost_whole),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
