/* Unit tests of lib/console built as the firmware builds it (CON_IO_FIXED 1,
 * no handler table): a realtime line is assembled in the output ring itself,
 * behind the bytes queued there (con_io_stage(), con_io_commit()), and
 * committed whole or not at all. The console's sources are compiled into
 * this test with those settings; a fake 256-byte ring stands for UART0's. */
#define CON_IO_FIXED 1
#define CON_HANDLERS 0

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "console/con_out.c"
#define con_fl_char con_fl_char_parse /* a static function of each file */
#include "console/con_parse.c"
#undef con_fl_char
#include "console/console.c"

/* ---- the fake ring (firmware/uart0.c's indices) -------------------- */

static uint8_t ring[256];
static uint8_t head, tail;
static char sent[1024]; /* what left the ring, in order */
static size_t n_sent;
static const char *input = "";

int16_t con_io_read(void)
{
    return *input != '\0' ? (int16_t)(uint8_t)*input++ : -1;
}

void con_io_write(const char *buf, uint8_t n)
{
    while (n-- > 0u) {
        assert_true((uint8_t)(head + 1u) != tail); /* the tests never wait */
        ring[head++] = (uint8_t)*buf++;
    }
}

uint16_t con_io_room(void)
{
    return (uint16_t)((uint8_t)(tail - head - 1u));
}

void con_io_stage(uint8_t off, const char *buf, uint8_t n)
{
    assert_true((uint16_t)off + n <= con_io_room()); /* never over bytes queued */
    while (n-- > 0u) {
        ring[(uint8_t)(head + off++)] = (uint8_t)*buf++;
    }
}

void con_io_commit(uint8_t n)
{
    assert_true(n <= con_io_room());
    head = (uint8_t)(head + n);
}

/* The UART sends n queued bytes. */
static void drain(size_t n)
{
    while (n-- > 0u && tail != head) {
        assert_true(n_sent < sizeof sent - 1u);
        sent[n_sent++] = (char)ring[tail++];
    }
    sent[n_sent] = '\0';
}

/* Queues filler bytes ('.') so that `room` bytes stay free. */
static void fill_to_room(uint16_t room)
{
    while (con_io_room() > room) {
        ring[head++] = '.';
    }
}

static con_t con;
static con_rt_t rt;

static int setup(void **state)
{
    (void)state;
    memset(ring, 0, sizeof ring);
    head = tail = 37; /* anywhere in the ring: lines wrap around its end */
    n_sent = 0;
    sent[0] = '\0';
    input = "";
    assert_int_equal(con_init(&con, NULL, NULL, NULL, NULL, &rt), 0);
    return 0;
}

static void report(uint8_t fields)
{
    uint8_t i;
    con_report_begin(&con, "rep");
    for (i = 0; i < fields; i++) {
        con_report_int(&con, "value", 1000000 + i);
    }
    con_report_end(&con);
}

/* ---- tests --------------------------------------------------------- */

static void test_realtime_line_is_staged_then_committed_whole(void **state)
{
    (void)state;
    con_set_realtime(&con, 1);
    ring[head++] = 'A'; /* a byte queued before the line */
    con_report_begin(&con, "rep");
    con_report_int(&con, "a", 1);
    assert_int_equal(con_io_room(), 254u); /* staged, not queued */
    drain(10);
    assert_string_equal(sent, "A");
    con_report_fixed(&con, "b", -25, 1);
    con_report_end(&con);
    drain(100);
    assert_string_equal(sent, "A<rep a=1 b=-2.5>\r\n");
    assert_int_equal(con_dropped(&con), 0u);
}

static void test_realtime_line_without_room_is_dropped_whole(void **state)
{
    (void)state;
    con_set_realtime(&con, 1);
    fill_to_room(CON_MIN_ROOM); /* begins, but five fields do not fit */
    report(5);
    assert_int_equal(con_io_room(), CON_MIN_ROOM); /* nothing queued */
    assert_int_equal(con_dropped(&con), 1u);
    drain(300);
    assert_int_equal(strspn(sent, "."), n_sent); /* the queued bytes intact */
    report(1);                                   /* the next fits */
    drain(300);
    assert_string_equal(strchr(sent, '<'), "<rep value=1000000>\r\n");
    assert_int_equal(con_dropped(&con), 1u);
}

static void test_realtime_reply_waits_for_room_and_comes_whole(void **state)
{
    int8_t cmd;
    (void)state;
    input = "version\n";
    (void)con_poll(&con, 0);
    cmd = con_call(&con);
    assert_int_equal(cmd, CON_CMD_VERSION);
    con_set_realtime(&con, 1);
    fill_to_room(2); /* "ok\r\n" does not fit */
    assert_int_equal(con_called(&con, 0), 0);
    assert_int_equal(con_io_room(), 2u);
    assert_int_equal(con_poll(&con, 1), 1); /* held */
    drain(10);
    assert_int_equal(con_poll(&con, 2), 0); /* written */
    drain(300);
    assert_string_equal(strchr(sent, 'o'), "ok\r\n");
}

static void test_too_long_line_is_dropped_and_counted(void **state)
{
    (void)state;
    con_set_realtime(&con, 1);
    report(14); /* 14 fields of 14 bytes: over CON_OUT_MAX */
    assert_int_equal(con_io_room(), 255u);
    assert_int_equal(con_dropped(&con), 1u);
}

static void test_not_realtime_writes_at_once(void **state)
{
    (void)state;
    con_set_realtime(&con, 0);
    con_report_begin(&con, "rep");
    assert_int_equal(con_io_room(), 255u - 4u); /* "<rep" queued already */
    con_report_end(&con);
    drain(100);
    assert_string_equal(sent, "<rep>\r\n");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_realtime_line_is_staged_then_committed_whole, setup),
        cmocka_unit_test_setup(test_realtime_line_without_room_is_dropped_whole, setup),
        cmocka_unit_test_setup(test_realtime_reply_waits_for_room_and_comes_whole, setup),
        cmocka_unit_test_setup(test_too_long_line_is_dropped_and_counted, setup),
        cmocka_unit_test_setup(test_not_realtime_writes_at_once, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
