/*
 * dxl_proto: CRC, packet builders and the byte-at-a-time parser, checked
 * against the packet examples of the ROBOTIS e-manual Protocol 2.0 page and
 * against corrupted input.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "dxl/dxl_proto.h"

/* e-manual Protocol 2.0, examples of each instruction and its status packet. */
static const uint8_t PING_1[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E};
static const uint8_t PING_1_REPLY[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00,
                                       0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D};
static const uint8_t PING_ALL[] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0x31, 0x42};
static const uint8_t READ_1[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00,
                                 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15};
static const uint8_t READ_1_REPLY[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55,
                                       0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0};
static const uint8_t WRITE_1[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03,
                                  0x74, 0x00, 0x00, 0x02, 0x00, 0x00, 0xCA, 0x89};
static const uint8_t WRITE_1_REPLY[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04,
                                        0x00, 0x55, 0x00, 0xA1, 0x0C};
static const uint8_t SYNC_READ[] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82,
                                    0x84, 0x00, 0x04, 0x00, 0x01, 0x02, 0xCE, 0xFA};
static const uint8_t SYNC_READ_REPLY_2[] = {0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x08, 0x00, 0x55,
                                            0x00, 0x1F, 0x08, 0x00, 0x00, 0xBA, 0xBE};
static const uint8_t SYNC_WRITE[] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83,
                                     0x74, 0x00, 0x04, 0x00, 0x01, 0x96, 0x00, 0x00,
                                     0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87};

typedef struct {
    dxl_parser p;
    uint8_t buf[64];
} parse_fixture;

static void fixture_init(parse_fixture *f)
{
    dxl_parser_init(&f->p, f->buf, sizeof f->buf);
}

/* Feeds bytes; returns how many packets completed and keeps the last status. */
static int feed_all(parse_fixture *f, const uint8_t *b, size_t n, dxl_status *last, int *errors)
{
    int packets = 0;
    for (size_t i = 0; i < n; i++) {
        int8_t rc = dxl_parser_feed(&f->p, b[i]);
        if (rc == 0) {
            packets++;
            if (last != NULL) {
                assert_int_equal(dxl_parser_status(&f->p, last), 0);
            }
        } else if (rc < 0 && errors != NULL) {
            (*errors)++;
        }
    }
    return packets;
}

static void test_crc_of_every_example(void **state)
{
    (void)state;
    const uint8_t *pk[] = {
        PING_1,        PING_1_REPLY, PING_ALL,          READ_1,    READ_1_REPLY, WRITE_1,
        WRITE_1_REPLY, SYNC_READ,    SYNC_READ_REPLY_2, SYNC_WRITE};
    const size_t len[] = {sizeof PING_1,        sizeof PING_1_REPLY, sizeof PING_ALL,
                          sizeof READ_1,        sizeof READ_1_REPLY, sizeof WRITE_1,
                          sizeof WRITE_1_REPLY, sizeof SYNC_READ,    sizeof SYNC_READ_REPLY_2,
                          sizeof SYNC_WRITE};
    for (size_t i = 0; i < sizeof len / sizeof len[0]; i++) {
        uint16_t crc = dxl_crc16(0, pk[i], (uint16_t)(len[i] - 2u));
        assert_int_equal(crc & 0xFF, pk[i][len[i] - 2u]);
        assert_int_equal(crc >> 8, pk[i][len[i] - 1u]);
    }
    /* byte-wise and block-wise agree */
    uint16_t crc = 0;
    for (size_t i = 0; i < sizeof SYNC_WRITE - 2u; i++) {
        crc = dxl_crc16_byte(crc, SYNC_WRITE[i]);
    }
    assert_int_equal(crc, 0x8782);
}

static void test_build_emanual_instructions(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint16_t len;
    assert_int_equal(dxl_build_ping(buf, sizeof buf, 1, &len), 0);
    assert_int_equal(len, sizeof PING_1);
    assert_memory_equal(buf, PING_1, len);

    assert_int_equal(dxl_build_ping(buf, sizeof buf, DXL_BROADCAST_ID, &len), 0);
    assert_memory_equal(buf, PING_ALL, sizeof PING_ALL);

    assert_int_equal(dxl_build_read(buf, sizeof buf, 1, 132, 4, &len), 0);
    assert_int_equal(len, sizeof READ_1);
    assert_memory_equal(buf, READ_1, len);

    const uint8_t goal[4] = {0x00, 0x02, 0x00, 0x00};
    assert_int_equal(dxl_build_write(buf, sizeof buf, 1, 116, goal, 4, &len), 0);
    assert_int_equal(len, sizeof WRITE_1);
    assert_memory_equal(buf, WRITE_1, len);

    const uint8_t ids[2] = {1, 2};
    assert_int_equal(dxl_build_sync_read(buf, sizeof buf, 132, 4, ids, 2, &len), 0);
    assert_int_equal(len, sizeof SYNC_READ);
    assert_memory_equal(buf, SYNC_READ, len);

    const uint8_t data[8] = {0x96, 0, 0, 0, 0xAA, 0, 0, 0};
    assert_int_equal(dxl_build_sync_write(buf, sizeof buf, 116, 4, ids, data, 2, &len), 0);
    assert_int_equal(len, sizeof SYNC_WRITE);
    assert_memory_equal(buf, SYNC_WRITE, len);
}

static void test_build_emanual_status(void **state)
{
    (void)state;
    uint8_t buf[32];
    uint16_t len;
    const uint8_t info[3] = {0x06, 0x04, 0x26};
    assert_int_equal(dxl_build_status(buf, sizeof buf, 1, 0, info, 3, &len), 0);
    assert_memory_equal(buf, PING_1_REPLY, sizeof PING_1_REPLY);
    const uint8_t pos[4] = {0xA6, 0, 0, 0};
    assert_int_equal(dxl_build_status(buf, sizeof buf, 1, 0, pos, 4, &len), 0);
    assert_int_equal(len, sizeof READ_1_REPLY);
    assert_memory_equal(buf, READ_1_REPLY, len);
    assert_int_equal(dxl_build_status(buf, sizeof buf, 1, 0, NULL, 0, &len), 0);
    assert_memory_equal(buf, WRITE_1_REPLY, sizeof WRITE_1_REPLY);
}

static void test_parse_emanual_status(void **state)
{
    (void)state;
    parse_fixture f;
    fixture_init(&f);
    dxl_status st;
    assert_int_equal(feed_all(&f, PING_1_REPLY, sizeof PING_1_REPLY, &st, NULL), 1);
    assert_int_equal(st.id, 1);
    assert_int_equal(st.err, 0);
    assert_int_equal(st.n, 3);
    assert_int_equal(dxl_get_le(st.params, 2), 1030);
    assert_int_equal(st.params[2], 38);

    assert_int_equal(feed_all(&f, READ_1_REPLY, sizeof READ_1_REPLY, &st, NULL), 1);
    assert_int_equal(dxl_get_le(st.params, 4), 166);
    assert_int_equal(feed_all(&f, SYNC_READ_REPLY_2, sizeof SYNC_READ_REPLY_2, &st, NULL), 1);
    assert_int_equal(st.id, 2);
    assert_int_equal(dxl_get_le(st.params, 4), 2079);
    assert_int_equal(feed_all(&f, WRITE_1_REPLY, sizeof WRITE_1_REPLY, &st, NULL), 1);
    assert_int_equal(st.n, 0);
    assert_int_equal(f.p.stats.packets, 4);
    assert_int_equal(f.p.stats.garbage, 0);

    /* an instruction packet is a valid frame but not a status */
    assert_int_equal(feed_all(&f, READ_1, sizeof READ_1, NULL, NULL), 1);
    assert_int_equal(dxl_parser_status(&f.p, &st), -DXL_E_MALFORMED);
    assert_int_equal(f.p.buf[0], DXL_INST_READ);
}

static void test_stuffing_inserted_and_removed(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint16_t len;
    /* goal position bytes FF FF FD 00 need one stuffing byte */
    const uint8_t v[4] = {0xFF, 0xFF, 0xFD, 0x00};
    assert_int_equal(dxl_build_write(buf, sizeof buf, 1, 116, v, 4, &len), 0);
    assert_int_equal(len, sizeof WRITE_1 + 1u);
    const uint8_t expect_body[] = {0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00};
    assert_int_equal(buf[5], 0x0A); /* LEN counts the stuffing byte */
    assert_memory_equal(buf + 7, expect_body, sizeof expect_body);
    assert_int_equal(dxl_crc16(0, buf, (uint16_t)(len - 2u)), dxl_get_le(buf + len - 2, 2));

    /* two patterns back to back, and FF FF FF FD */
    const uint8_t w[7] = {0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFF, 0xFD};
    assert_int_equal(dxl_build_status(buf, sizeof buf, 3, 0, w, 7, &len), 0);
    assert_int_equal(len, 11u + 7u + 2u);

    parse_fixture f;
    fixture_init(&f);
    dxl_status st;
    assert_int_equal(feed_all(&f, buf, len, &st, NULL), 1);
    assert_int_equal(st.n, 7);
    assert_memory_equal(st.params, w, 7);

    /* a value that ends in FF FF and an FD that is the last data byte */
    const uint8_t x[3] = {0xFF, 0xFF, 0xFD};
    assert_int_equal(dxl_build_status(buf, sizeof buf, 4, 0, x, 3, &len), 0);
    assert_int_equal(feed_all(&f, buf, len, &st, NULL), 1);
    assert_int_equal(st.n, 3);
    assert_memory_equal(st.params, x, 3);
}

static void test_stuffing_split_across_reads(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint16_t len;
    const uint8_t v[6] = {0x10, 0xFF, 0xFF, 0xFD, 0x20, 0x30};
    assert_int_equal(dxl_build_status(buf, sizeof buf, 9, 0, v, 6, &len), 0);
    for (uint16_t cut = 1; cut < len; cut++) {
        parse_fixture f;
        fixture_init(&f);
        dxl_status st;
        int n = feed_all(&f, buf, cut, NULL, NULL);
        n += feed_all(&f, buf + cut, (size_t)(len - cut), &st, NULL);
        assert_int_equal(n, 1);
        assert_int_equal(st.n, 6);
        assert_memory_equal(st.params, v, 6);
    }
}

static void test_garbage_before_header_and_back_to_back(void **state)
{
    (void)state;
    uint8_t stream[128];
    size_t n = 0;
    const uint8_t junk[] = {0x00, 0xFF, 0x13, 0xFF, 0xFF, 0x00, 0xFF, 0xFF, 0xFD, 0x05, 0xFF};
    memcpy(stream, junk, sizeof junk);
    n += sizeof junk;
    memcpy(stream + n, READ_1_REPLY, sizeof READ_1_REPLY);
    n += sizeof READ_1_REPLY;
    memcpy(stream + n, SYNC_READ_REPLY_2, sizeof SYNC_READ_REPLY_2);
    n += sizeof SYNC_READ_REPLY_2;
    parse_fixture f;
    fixture_init(&f);
    dxl_status st;
    int errors = 0;
    assert_int_equal(feed_all(&f, stream, n, &st, &errors), 2);
    assert_int_equal(errors, 0);
    assert_int_equal(st.id, 2);
    /* all eleven junk bytes: 00, FF 13, FF FF 00, FF FF FD 05 and the FF
     * that made FF FF FF FD with the real header */
    assert_int_equal(f.p.stats.garbage, 11);
    /* header with an extra FF in front */
    const uint8_t ff = 0xFF;
    assert_int_equal(feed_all(&f, &ff, 1, NULL, NULL), 0);
    assert_int_equal(feed_all(&f, PING_1_REPLY, sizeof PING_1_REPLY, &st, NULL), 1);
    assert_int_equal(st.id, 1);
}

static void test_bad_crc_counted_then_recovers(void **state)
{
    (void)state;
    uint8_t bad[sizeof READ_1_REPLY];
    memcpy(bad, READ_1_REPLY, sizeof bad);
    bad[9] ^= 0x01;
    parse_fixture f;
    fixture_init(&f);
    int errors = 0;
    dxl_status st;
    assert_int_equal(feed_all(&f, bad, sizeof bad, NULL, &errors), 0);
    assert_int_equal(errors, 1);
    assert_int_equal(f.p.stats.crc, 1);
    /* last byte reports the error itself */
    fixture_init(&f);
    for (size_t i = 0; i + 1 < sizeof bad; i++) {
        assert_int_equal(dxl_parser_feed(&f.p, bad[i]), 1);
    }
    assert_int_equal(dxl_parser_feed(&f.p, bad[sizeof bad - 1]), -DXL_E_CRC);
    assert_int_equal(feed_all(&f, READ_1_REPLY, sizeof READ_1_REPLY, &st, NULL), 1);
    assert_int_equal(dxl_get_le(st.params, 4), 166);
}

static void test_wrong_length_rejected(void **state)
{
    (void)state;
    parse_fixture f;
    fixture_init(&f);
    /* LEN 2 is below the minimum (INST + CRC) */
    const uint8_t shortlen[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x02, 0x00};
    int errors = 0;
    feed_all(&f, shortlen, sizeof shortlen, NULL, &errors);
    assert_int_equal(errors, 1);
    assert_int_equal(f.p.stats.length, 1);
    /* LEN larger than the buffer could ever hold */
    const uint8_t huge[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x00, 0x40};
    errors = 0;
    feed_all(&f, huge, sizeof huge, NULL, &errors);
    assert_int_equal(errors, 1);
    assert_int_equal(f.p.stats.length, 2);
    /* LEN two too large: the CRC field lands on the next header, which the
     * rescan after the CRC error still finds */
    uint8_t stream[64];
    memcpy(stream, WRITE_1_REPLY, sizeof WRITE_1_REPLY);
    stream[5] = 0x06;
    memcpy(stream + sizeof WRITE_1_REPLY, READ_1_REPLY, sizeof READ_1_REPLY);
    dxl_status st;
    errors = 0;
    assert_int_equal(feed_all(&f, stream, sizeof WRITE_1_REPLY + sizeof READ_1_REPLY, &st, &errors),
                     1);
    assert_int_equal(errors, 1);
    assert_int_equal(f.p.stats.crc, 1);
    assert_int_equal(dxl_get_le(st.params, 4), 166);
}

static void test_truncated_packet_then_next(void **state)
{
    (void)state;
    /* cut READ_1_REPLY after every possible byte count and follow it with a
     * good packet: the good one is always found, the cut one always counted */
    for (size_t cut = 8; cut < sizeof READ_1_REPLY; cut++) {
        uint8_t stream[64];
        memcpy(stream, READ_1_REPLY, cut);
        memcpy(stream + cut, SYNC_READ_REPLY_2, sizeof SYNC_READ_REPLY_2);
        parse_fixture f;
        fixture_init(&f);
        dxl_status st;
        int errors = 0;
        assert_int_equal(feed_all(&f, stream, cut + sizeof SYNC_READ_REPLY_2, &st, &errors), 1);
        assert_int_equal(errors, 1);
        assert_int_equal(f.p.stats.truncated + f.p.stats.crc, 1);
        assert_int_equal(st.id, 2);
        assert_int_equal(dxl_get_le(st.params, 4), 2079);
    }
    /* early cut: detected inside the body as truncation */
    parse_fixture f;
    fixture_init(&f);
    uint8_t stream[64];
    memcpy(stream, READ_1_REPLY, 9);
    memcpy(stream + 9, SYNC_READ_REPLY_2, sizeof SYNC_READ_REPLY_2);
    int errors = 0;
    feed_all(&f, stream, 9 + sizeof SYNC_READ_REPLY_2, NULL, &errors);
    assert_int_equal(f.p.stats.truncated, 1);
    assert_int_equal(f.p.stats.packets, 1);
}

static void test_overflow_of_small_buffer(void **state)
{
    (void)state;
    dxl_parser p;
    uint8_t small[4];
    dxl_parser_init(&p, small, sizeof small);
    int errors = 0;
    for (size_t i = 0; i < sizeof READ_1_REPLY; i++) {
        int8_t rc = dxl_parser_feed(&p, READ_1_REPLY[i]);
        if (rc < 0) {
            assert_int_equal(rc, -DXL_E_OVERFLOW);
            errors++;
        }
    }
    assert_int_equal(errors, 1);
    assert_int_equal(p.stats.overflow, 1);
    /* a packet that fits still parses */
    dxl_status st;
    int ok = 0;
    for (size_t i = 0; i < sizeof WRITE_1_REPLY; i++) {
        if (dxl_parser_feed(&p, WRITE_1_REPLY[i]) == 0) {
            ok++;
            assert_int_equal(dxl_parser_status(&p, &st), 0);
        }
    }
    assert_int_equal(ok, 1);
}

static void test_builder_capacity_and_arguments(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint16_t len = 99;
    assert_int_equal(dxl_build_ping(buf, 9, 1, &len), -DXL_E_NOSPACE);
    assert_int_equal(len, 0);
    assert_int_equal(dxl_build_ping(buf, 10, 1, &len), 0);
    assert_int_equal(dxl_build_read(buf, sizeof buf, DXL_BROADCAST_ID, 0, 1, &len), -DXL_E_ARG);
    assert_int_equal(dxl_build_read(buf, sizeof buf, 1, 0, 0, &len), -DXL_E_ARG);
    assert_int_equal(dxl_build_ping(buf, sizeof buf, 0xFD, &len), -DXL_E_ARG);
    const uint8_t ids[2] = {1, 253};
    assert_int_equal(dxl_build_sync_read(buf, sizeof buf, 132, 4, ids, 2, &len), -DXL_E_ARG);
    assert_int_equal(dxl_build_sync_read(buf, sizeof buf, 132, 4, ids, 0, &len), -DXL_E_ARG);
    /* stuffing that pushes the packet past the capacity is caught */
    const uint8_t v[4] = {0xFF, 0xFF, 0xFD, 0x00};
    assert_int_equal(dxl_build_write(buf, 16, 1, 116, v, 4, &len), -DXL_E_NOSPACE);
    assert_int_equal(dxl_build_write(buf, 17, 1, 116, v, 4, &len), 0);
}

static void test_factory_reset_needs_guard(void **state)
{
    (void)state;
    uint8_t buf[32];
    memset(buf, 0xAA, sizeof buf);
    uint16_t len;
    assert_int_equal(dxl_build_factory_reset(buf, sizeof buf, 1, DXL_RESET_ALL, 0, &len),
                     -DXL_E_GUARD);
    assert_int_equal(buf[0], 0xAA);
    assert_int_equal(len, 0);
    assert_int_equal(
        dxl_build_factory_reset(buf, sizeof buf, 1, 0x05, DXL_FACTORY_RESET_GUARD, &len),
        -DXL_E_ARG);
    assert_int_equal(dxl_build_factory_reset(buf, sizeof buf, 1, DXL_RESET_KEEP_ID,
                                             DXL_FACTORY_RESET_GUARD, &len),
                     0);
    const uint8_t expect[] = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x06, 0x01};
    assert_memory_equal(buf, expect, sizeof expect);
    assert_int_equal(len, 11);
}

static void test_other_instructions_layout(void **state)
{
    (void)state;
    uint8_t buf[64];
    uint16_t len;
    assert_int_equal(dxl_build_clear_multiturn(buf, sizeof buf, 2, &len), 0);
    const uint8_t clear[] = {0x08, 0x00, 0x10, 0x01, 0x44, 0x58, 0x4C, 0x22};
    assert_memory_equal(buf + 5, clear, sizeof clear);
    assert_int_equal(dxl_build_reboot(buf, sizeof buf, 2, &len), 0);
    assert_int_equal(buf[7], DXL_INST_REBOOT);
    assert_int_equal(len, 10);
    assert_int_equal(dxl_build_action(buf, sizeof buf, DXL_BROADCAST_ID, &len), 0);
    assert_int_equal(buf[7], DXL_INST_ACTION);
    const uint8_t d[2] = {0x34, 0x12};
    assert_int_equal(dxl_build_reg_write(buf, sizeof buf, 3, 104, d, 2, &len), 0);
    assert_int_equal(buf[7], DXL_INST_REG_WRITE);
    const dxl_bulk_item items[2] = {{1, 132, 4, NULL}, {7, 146, 1, NULL}};
    assert_int_equal(dxl_build_bulk_read(buf, sizeof buf, items, 2, &len), 0);
    const uint8_t bulk[] = {0x92, 0x01, 0x84, 0x00, 0x04, 0x00, 0x07, 0x92, 0x00, 0x01, 0x00};
    assert_memory_equal(buf + 7, bulk, sizeof bulk);
    assert_int_equal(dxl_build_bulk_write(buf, sizeof buf, items, 2, &len), -DXL_E_ARG);
    const uint8_t ids[3] = {4, 5, 6};
    assert_int_equal(dxl_build_fast_sync_read(buf, sizeof buf, 132, 4, ids, 3, &len), 0);
    assert_int_equal(buf[7], DXL_INST_FAST_SYNC_READ);
    assert_int_equal(len, 17);
}

static void test_raw_mode_keeps_bytes_as_sent(void **state)
{
    (void)state;
    /* a fast sync read reply whose data holds FF FF FD 00 unstuffed */
    uint8_t pkt[32] = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x00, 0x00,
                       0x55, 0x00, 0x01, 0xFF, 0xFF, 0xFD, 0x00};
    uint16_t n = 14;
    pkt[5] = (uint8_t)(n - 7u + 2u);
    uint16_t crc = dxl_crc16(0, pkt, n);
    pkt[n++] = (uint8_t)crc;
    pkt[n++] = (uint8_t)(crc >> 8);
    parse_fixture f;
    fixture_init(&f);
    dxl_parser_set_raw(&f.p, 1);
    dxl_status st;
    assert_int_equal(feed_all(&f, pkt, n, &st, NULL), 1);
    assert_int_equal(st.id, DXL_BROADCAST_ID);
    assert_int_equal(st.n, 5);
    const uint8_t expect[5] = {0x01, 0xFF, 0xFF, 0xFD, 0x00};
    assert_memory_equal(st.params, expect, 5);
    /* the same bytes in stuffed mode look like a header inside the body */
    dxl_parser_set_raw(&f.p, 0);
    int errors = 0;
    assert_int_equal(feed_all(&f, pkt, n, NULL, &errors), 0);
    assert_true(errors >= 1);
    assert_int_equal(f.p.stats.truncated, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_of_every_example),
        cmocka_unit_test(test_build_emanual_instructions),
        cmocka_unit_test(test_build_emanual_status),
        cmocka_unit_test(test_parse_emanual_status),
        cmocka_unit_test(test_stuffing_inserted_and_removed),
        cmocka_unit_test(test_stuffing_split_across_reads),
        cmocka_unit_test(test_garbage_before_header_and_back_to_back),
        cmocka_unit_test(test_bad_crc_counted_then_recovers),
        cmocka_unit_test(test_wrong_length_rejected),
        cmocka_unit_test(test_truncated_packet_then_next),
        cmocka_unit_test(test_overflow_of_small_buffer),
        cmocka_unit_test(test_builder_capacity_and_arguments),
        cmocka_unit_test(test_factory_reset_needs_guard),
        cmocka_unit_test(test_other_instructions_layout),
        cmocka_unit_test(test_raw_mode_keeps_bytes_as_sent),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
