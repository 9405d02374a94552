/* Unit tests of lib/console's output: the generated help listing, command
 * names, reports, number formatting, and realtime mode, where output never
 * waits for room in the transmit ring. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "con_fake.h"
#include "con_fixture.h"
#include "console/console.h"

/* ---- help -------------------------------------------------------- */

static void test_help_generated(void **state)
{
    char line[200];
    char name[16];
    int n = 0;
    (void)state;
    con_fake_puts(&g_serial, "help\nstatus\n");
    /* one help line per poll; the next command waits */
    for (int i = 0; i < 1000 && con_fake_unread(&g_serial) > 0u; i++) {
        (void)con_poll(&g_con, g_clock_ms++);
        if (g_app.total == 0) {
            assert_true(g_serial.out_len < 200u * (size_t)(i + 1));
        }
    }
    while (con_poll(&g_con, g_clock_ms++) != 0) {
    }
    while (con_fake_line(&g_serial, line, sizeof(line))) {
        if (n < CON_CMD_COUNT) {
            assert_true(con_cmd_name(&g_con, (uint8_t)n, name, sizeof(name)) > 0);
            char want[40];
            snprintf(want, sizeof(want), "<help cmd=%s args=\"", name);
            assert_memory_equal(line, want, strlen(want));
            assert_true(line[strlen(line) - 1] == '>');
            if (n == CON_CMD_CAL) {
                assert_string_equal(line, "<help cmd=cal args=\"[tension_N] [tendon]\" "
                                          "text=\"calibrate every tendon, or one, at a "
                                          "tension in N (default: setting cal_tension)\">");
            }
            if (n == CON_CMD_SERVOS) {
                assert_non_null(strstr(line, "args=\"[scan|pos|err]\""));
            }
            if (n == CON_CMD_LEARN) {
                assert_non_null(strstr(line, "args=\"<tendon> <tension_N> [dB_uT]\""));
            }
            if (n == CON_CMD_HELP) {
                assert_non_null(strstr(line, "args=\"\""));
            }
        } else if (n == CON_CMD_COUNT) {
            assert_string_equal(line, "ok");
        } else {
            assert_string_equal(line, "ok"); /* status, after help finished */
        }
        n++;
    }
    assert_int_equal(n, CON_CMD_COUNT + 2);
    assert_int_equal(g_app.calls[CON_CMD_HELP], 0); /* built in */
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 1);
}

static void test_cmd_name(void **state)
{
    char buf[8];
    (void)state;
    assert_int_equal(con_cmd_name(&g_con, CON_CMD_VERSION, buf, sizeof(buf)), 7);
    assert_string_equal(buf, "version");
    assert_int_equal(con_cmd_name(&g_con, CON_CMD_VERSION, buf, 4), 7);
    assert_string_equal(buf, "ver");
    assert_int_equal(con_cmd_name(&g_con, CON_CMD_COUNT, buf, sizeof(buf)), CON_E_INTERNAL);
    assert_int_equal(con_cmd_name(&g_con, 0, buf, 0), CON_E_INTERNAL);
}

/* ---- reports and numbers ----------------------------------------- */

static void test_reports(void **state)
{
    char line[128];
    (void)state;
    con_report_begin(&g_con, "cal");
    con_report_int(&g_con, "t", 3);
    con_report_int(&g_con, "pos", -123456);
    con_report_fixed(&g_con, "N", 800, 3);
    con_report_fixed(&g_con, "d", -5, 1);
    con_report_str(&g_con, "name", "paper_2seg");
    con_report_str(&g_con, "msg", "two words");
    con_report_str(&g_con, "e", "");
    con_report_flash(&g_con, "f", "a=b");
    con_report_end(&g_con);
    assert_int_equal(con_fake_line(&g_serial, line, sizeof(line)), 1);
    assert_string_equal(line, "<cal t=3 pos=-123456 N=0.800 d=-0.5 name=paper_2seg "
                              "msg=\"two words\" e=\"\" f=\"a=b\">");
    assert_int_equal(con_fake_line(&g_serial, line, sizeof(line)), 0);
}

/* Lists as the `table`, `history` and survey lines write them: the same
 * bytes as a comma list built first and written with con_report_str(). */
static void test_report_lists(void **state)
{
    static const int32_t v[3] = {300, -1048575, 0};
    char line[128];
    uint8_t i;
    (void)state;
    con_report_begin(&g_con, "hist");
    con_report_list(&g_con, "homes", 3);
    for (i = 0; i < 3u; i++) {
        con_report_item(&g_con, v[i], i == 1u ? '?' : '\0', i == 0u);
    }
    con_report_list(&g_con, "none", 0);
    con_report_list(&g_con, "one", 1);
    con_report_item(&g_con, 7, '*', 1);
    con_report_end(&g_con);
    assert_int_equal(con_fake_line(&g_serial, line, sizeof(line)), 1);
    assert_string_equal(line, "<hist homes=300,-1048575?,0 none=\"\" one=7*>");
}

static void test_format_fixed(void **state)
{
    char b[13];
    (void)state;
    assert_int_equal(con_format_fixed(b, sizeof(b), 0, 0), 1);
    assert_string_equal(b, "0");
    assert_int_equal(con_format_fixed(b, sizeof(b), 0, 3), 5);
    assert_string_equal(b, "0.000");
    assert_int_equal(con_format_fixed(b, sizeof(b), 7, 3), 5);
    assert_string_equal(b, "0.007");
    assert_int_equal(con_format_fixed(b, sizeof(b), -7, 3), 6);
    assert_string_equal(b, "-0.007");
    assert_int_equal(con_format_fixed(b, sizeof(b), 1234567, 2), 8);
    assert_string_equal(b, "12345.67");
    assert_int_equal(con_format_fixed(b, sizeof(b), 2147483647, 0), 10);
    assert_string_equal(b, "2147483647");
    assert_int_equal(con_format_fixed(b, sizeof(b), -2147483647 - 1, 0), 11);
    assert_string_equal(b, "-2147483648");
    assert_int_equal(con_format_fixed(b, sizeof(b), -2147483647 - 1, 9), 13 - 1);
    assert_string_equal(b, "-2.147483648");
    assert_int_equal(con_format_fixed(b, sizeof(b), 5, 12), 11); /* 9 decimals at most */
    assert_string_equal(b, "0.000000005");
    assert_int_equal(con_format_fixed(b, sizeof(b), 100, 0), 3);
    assert_string_equal(b, "100");
    assert_int_equal(con_format_fixed(b, 4, 100, 0), 3);
    assert_int_equal(con_format_fixed(b, 3, 100, 0), -1);
    assert_string_equal(b, "");
    assert_int_equal(con_format_fixed(b, 0, 100, 0), -1);
}

/* ---- realtime mode: output never waits ------------------------------- */

static uint16_t g_room;
static uint32_t g_over; /* writes larger than the room offered */

static uint16_t fake_room(void *ctx)
{
    (void)ctx;
    return g_room;
}

static void (*g_fake_write)(void *ctx, const char *buf, uint8_t n);

static void checked_write(void *ctx, const char *buf, uint8_t n)
{
    if (n > g_room) {
        g_over++;
    }
    g_room = (uint16_t)(g_room - (n > g_room ? g_room : n));
    g_fake_write(ctx, buf, n);
}

static void realtime_setup(uint16_t room)
{
    g_room = room;
    g_over = 0;
    g_fake_write = g_serial.io.write;
    g_serial.io.write = checked_write;
    g_serial.io.room = fake_room;
    con_set_realtime(&g_con, 1);
}

static void test_realtime_drops_reports_without_room(void **state)
{
    (void)state;
    realtime_setup(10);
    assert_int_equal(con_report_fits(&g_con), 0); /* what a caller that must not lose it asks */
    con_report_begin(&g_con, "progress");
    con_report_int(&g_con, "tendon", 3);
    con_report_end(&g_con);
    assert_int_equal(g_serial.out_len, 0u);
    assert_int_equal(con_dropped(&g_con), 1u);
    g_room = 255;
    assert_int_equal(con_report_fits(&g_con), 1);
    con_report_begin(&g_con, "progress");
    con_report_int(&g_con, "tendon", 3);
    con_report_end(&g_con);
    assert_string_equal(g_serial.out, "<progress tendon=3>\r\n");
    assert_int_equal(con_dropped(&g_con), 1u);
    assert_int_equal(g_over, 0u);
}

/* Realtime: a line is taken only when the longest output and the reserve
 * fit, so a command's report is not dropped (a `version` taken just after a
 * reset's <ready> and <released> came back with its `ok` alone). */
static void test_realtime_command_output_leaves_reserve(void **state)
{
    (void)state;
    realtime_setup(CON_RESERVE + 10u); /* the reply fits, a report plus reserve not */
    g_app.report = 1;
    assert_string_equal(con_fix_run("version\n"), ""); /* waits unread */
    assert_int_equal(g_app.total, 0);
    g_room = 255;
    assert_string_equal(con_fix_run(""), "<rep cmd=1>\r\nok\r\n");
    assert_int_equal(con_dropped(&g_con), 0u);
    assert_int_equal(g_over, 0u);
}

static void test_realtime_reply_waits_for_room(void **state)
{
    int i;
    (void)state;
    realtime_setup(0);
    con_fake_puts(&g_serial, "version\nversion\n");
    for (i = 0; i < 50; i++) {
        assert_int_equal(con_poll(&g_con, g_clock_ms++), 0); /* no room: reads nothing */
    }
    assert_int_equal(g_serial.out_len, 0u);
    assert_int_equal(g_app.total, 0);
    g_room = 255;
    assert_string_equal(con_fix_run(""), "ok\r\n"); /* the next waits for the ring to drain */
    assert_int_equal(g_app.total, 1);
    g_room = 255;
    assert_string_equal(con_fix_run(""), "ok\r\n");
    assert_int_equal(g_app.total, 2);
    assert_int_equal(g_over, 0u);
}

static void test_realtime_help_waits_line_by_line(void **state)
{
    char line[256];
    int i, n = 0;
    (void)state;
    realtime_setup(CON_OUT_MAX + CON_RESERVE - 1u);
    con_fake_puts(&g_serial, "help\n");
    for (i = 0; i < 50; i++) {
        (void)con_poll(&g_con, g_clock_ms++);
    }
    assert_int_equal(g_serial.out_len, 0u);
    for (i = 0; i < 1000 && n <= CON_CMD_COUNT; i++) {
        g_room = 255;
        (void)con_poll(&g_con, g_clock_ms++);
        while (con_fake_line(&g_serial, line, sizeof line)) {
            n++;
        }
    }
    assert_int_equal(n, CON_CMD_COUNT + 1); /* every help line, then ok */
    assert_string_equal(line, "ok");
    assert_int_equal(g_over, 0u);
}

/* Seeded random room: every line still gets exactly one final reply, no
 * write ever exceeds the room offered, and nothing is written in part. */
static void test_realtime_random_room_one_reply_per_line(void **state)
{
    char line[256];
    uint32_t x = 777u;
    int i, replies = 0, sent = 0;
    (void)state;
    realtime_setup(0);
    g_app.report = 1;
    for (i = 0; i < 300; i++) {
        if (i % 3 == 0 && sent < 60) {
            con_fake_puts(&g_serial, (i % 2) ? "version\n" : "status\n");
            sent++;
        }
        x = x * 1103515245u + 12345u;
        g_room = (uint16_t)((x >> 16) % 256u);
        (void)con_poll(&g_con, g_clock_ms++);
    }
    for (i = 0; i < 5000 && replies < sent; i++) {
        g_room = 255;
        (void)con_poll(&g_con, g_clock_ms++);
        while (con_fake_line(&g_serial, line, sizeof line)) {
            if (strcmp(line, "ok") == 0) {
                replies++;
            } else {
                assert_true(line[0] == '<' && line[strlen(line) - 1] == '>');
            }
        }
        if (con_fake_unread(&g_serial) == 0u && replies == sent) {
            break;
        }
    }
    while (con_fake_line(&g_serial, line, sizeof line)) {
        replies += strcmp(line, "ok") == 0;
    }
    assert_int_equal(replies, sent);
    assert_int_equal(g_over, 0u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_help_generated, con_fix_setup),
        cmocka_unit_test_setup(test_cmd_name, con_fix_setup),
        cmocka_unit_test_setup(test_reports, con_fix_setup),
        cmocka_unit_test_setup(test_report_lists, con_fix_setup),
        cmocka_unit_test_setup(test_format_fixed, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_drops_reports_without_room, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_command_output_leaves_reserve, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_reply_waits_for_room, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_help_waits_line_by_line, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_random_room_one_reply_per_line, con_fix_setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
