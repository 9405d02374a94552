/* Unit tests of lib/console's input: line assembly (terminators, overlong
 * lines, bad bytes, backspace, the realtime stop) and the validation of
 * arguments and numbers before anything runs. */
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

/* ---- arguments --------------------------------------------------- */

static void test_arguments_parsed(void **state)
{
    (void)state;
    assert_string_equal(con_fix_run("cal 0.8 3\n"), "ok\r\n");
    assert_int_equal(g_app.last.given, 3);
    assert_int_equal(g_app.last.v[0], 800);
    assert_int_equal(g_app.last.v[1], 3);
    assert_string_equal(g_app.last.s[0], "0.8");
    assert_string_equal(con_fix_run("cal\n"), "ok\r\n");
    assert_int_equal(g_app.last.given, 0);
    assert_int_equal(g_app.last.v[0], 0);
    assert_null(g_app.last.s[0]);
    assert_string_equal(con_fix_run("cal 2\n"), "ok\r\n");
    assert_int_equal(g_app.last.given, 1);
    assert_int_equal(g_app.last.v[0], 2000);
    assert_string_equal(con_fix_run("cal .05\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 50);
    assert_string_equal(con_fix_run("cal 10\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 10000);
    assert_string_equal(con_fix_run("cal 0.01 0\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 10);
    assert_string_equal(con_fix_run("learn 11 1.250\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 11);
    assert_int_equal(g_app.last.v[1], 1250);
    assert_string_equal(con_fix_run("servos\n"), "ok\r\n");
    assert_int_equal(g_app.last.given, 0);
    assert_string_equal(con_fix_run("servos scan\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 0);
    assert_string_equal(con_fix_run("servos pos\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 1);
    assert_string_equal(con_fix_run("servos err\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 2);
    assert_string_equal(con_fix_run("get\n"), "ok\r\n");
    assert_int_equal(g_app.last.given, 0);
    assert_string_equal(con_fix_run("get cal_tension\n"), "ok\r\n");
    assert_string_equal(g_app.s0, "cal_tension");
    assert_string_equal(con_fix_run("set Filter_K -5\n"), "ok\r\n");
    assert_string_equal(g_app.s0, "Filter_K"); /* setting names are passed as typed */
    assert_int_equal(g_app.last.v[1], -5);
    assert_string_equal(con_fix_run("set x 2147483647\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[1], 2147483647);
    assert_string_equal(con_fix_run("set x -2147483647\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[1], -2147483647);
    assert_string_equal(con_fix_run("reboot 252\n"), "ok\r\n");
    assert_int_equal(g_app.last.v[0], 252);
    assert_string_equal(con_fix_run("reboot 0\n"), "ok\r\n");
    /* case-insensitive command names, extra spaces and tabs */
    assert_string_equal(con_fix_run("  CAL\t 1.5   4  \n"), "ok\r\n");
    assert_int_equal(g_app.last_cmd, CON_CMD_CAL);
    assert_int_equal(g_app.last.v[0], 1500);
    assert_int_equal(g_app.last.v[1], 4);
}

typedef struct {
    const char *line;
    const char *reply;
} bad_case_t;

static void test_bad_arguments_change_nothing(void **state)
{
    static const bad_case_t cases[] = {
        {"help 1\n", "error:5 too many arguments\r\n"},
        {"version x\n", "error:5 too many arguments\r\n"},
        {"status 1\n", "error:5 too many arguments\r\n"},
        {"sensors all\n", "error:5 too many arguments\r\n"},
        {"servos foo\n", "error:8 unknown choice\r\n"},
        {"servos SCAN\n", "error:8 unknown choice\r\n"},
        {"servos scan pos\n", "error:5 too many arguments\r\n"},
        {"servos 1\n", "error:8 unknown choice\r\n"},
        {"cal 0.001\n", "error:3 argument out of range\r\n"},
        {"cal 0\n", "error:3 argument out of range\r\n"},
        {"cal -1\n", "error:3 argument out of range\r\n"},
        {"cal 10.001\n", "error:3 argument out of range\r\n"},
        {"cal 0.8x\n", "error:2 bad number\r\n"},
        {"cal 1.2345\n", "error:2 bad number\r\n"},
        {"cal 1..2\n", "error:2 bad number\r\n"},
        {"cal .\n", "error:2 bad number\r\n"},
        {"cal -\n", "error:2 bad number\r\n"},
        {"cal 99999999999\n", "error:2 bad number\r\n"},
        {"cal 2147483.648\n", "error:2 bad number\r\n"},
        {"cal 1 12\n", "error:3 argument out of range\r\n"},
        {"cal 1 -1\n", "error:3 argument out of range\r\n"},
        {"cal 1 1.5\n", "error:2 bad number\r\n"},
        {"cal 1 2 3\n", "error:5 too many arguments\r\n"},
        {"cal x 99\n", "error:2 bad number\r\n"}, /* the first bad argument decides */
        {"rehome now\n", "error:5 too many arguments\r\n"},
        {"home 1\n", "error:5 too many arguments\r\n"},
        {"release 1\n", "error:5 too many arguments\r\n"},
        {"learn\n", "error:4 missing argument\r\n"},
        {"learn 1\n", "error:4 missing argument\r\n"},
        {"learn a 1\n", "error:2 bad number\r\n"},
        {"learn 12 1\n", "error:3 argument out of range\r\n"},
        {"learn 1 0\n", "error:3 argument out of range\r\n"},
        {"learn 1 1 1 1\n", "error:5 too many arguments\r\n"},
        {"learn 1 1 0\n", "error:3 argument out of range\r\n"},
        {"learn 1 1 4913\n", "error:3 argument out of range\r\n"},
        {"learn 1 1 1 1 1 1 1\n", "error:5 too many arguments\r\n"},
        {"table x\n", "error:5 too many arguments\r\n"},
        {"history 3\n", "error:5 too many arguments\r\n"},
        {"get a b\n", "error:5 too many arguments\r\n"},
        {"set\n", "error:4 missing argument\r\n"},
        {"set filter_k\n", "error:4 missing argument\r\n"},
        {"set filter_k y\n", "error:2 bad number\r\n"},
        {"set filter_k 4.5\n", "error:2 bad number\r\n"},
        {"set filter_k 2147483648\n", "error:2 bad number\r\n"},
        {"set filter_k 1 2\n", "error:5 too many arguments\r\n"},
        {"save now\n", "error:5 too many arguments\r\n"},
        {"reboot\n", "error:4 missing argument\r\n"},
        {"reboot 253\n", "error:3 argument out of range\r\n"},
        {"reboot -1\n", "error:3 argument out of range\r\n"},
        {"reboot 1.5\n", "error:2 bad number\r\n"},
        {"reboot 0x10\n", "error:2 bad number\r\n"},
        {"calibrate\n", "error:1 unknown command\r\n"},
        {"ca\n", "error:1 unknown command\r\n"},
        {"x\n", "error:1 unknown command\r\n"},
        {"0.8\n", "error:1 unknown command\r\n"},
        {"helpx\n", "error:1 unknown command\r\n"},
    };
    size_t i;
    (void)state;
    for (i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
        const char *out = con_fix_run(cases[i].line);
        if (strcmp(out, cases[i].reply) != 0) {
            fail_msg("line %s got %s want %s", cases[i].line, out, cases[i].reply);
        }
        assert_int_equal(g_app.total, 0);
    }
}

/* ---- line assembly ----------------------------------------------- */

static void test_terminators_and_empty_lines(void **state)
{
    (void)state;
    assert_string_equal(con_fix_run("status\r"), "ok\r\n");
    assert_string_equal(con_fix_run("status\r\n"), "ok\r\n");
    assert_string_equal(con_fix_run("status\n"), "ok\r\n");
    assert_int_equal(g_app.total, 3);
    /* CR then LF in a later read is still one terminator */
    assert_string_equal(con_fix_run("status\r"), "ok\r\n");
    assert_string_equal(con_fix_run("\nstatus\n"), "ok\r\n");
    assert_int_equal(g_app.total, 5);
    /* empty lines get ok (host sync) and call nothing */
    assert_string_equal(con_fix_run("\n"), "ok\r\n");
    assert_string_equal(con_fix_run("\r\n"), "ok\r\n");
    assert_string_equal(con_fix_run("\n\n"), "ok\r\nok\r\n");
    assert_string_equal(con_fix_run("\r\r"), "ok\r\nok\r\n");
    assert_string_equal(con_fix_run("\n"), ""); /* the LF of the last CR's CRLF */
    assert_string_equal(con_fix_run("   \t \n"), "ok\r\n");
    assert_string_equal(con_fix_run("\n\r"), "ok\r\nok\r\n");
    assert_int_equal(g_app.total, 5);
    /* no terminator yet: no reply */
    assert_string_equal(con_fix_run("stat"), "");
    assert_string_equal(con_fix_run("us\n"), "ok\r\n");
}

static void test_overlong_line(void **state)
{
    char line[300];
    (void)state;
    /* exactly CON_LINE_MAX characters is fine */
    memset(line, ' ', sizeof(line));
    memcpy(line, "status", 6);
    line[CON_LINE_MAX] = '\n';
    line[CON_LINE_MAX + 1] = '\0';
    assert_string_equal(con_fix_run(line), "ok\r\n");
    assert_int_equal(g_app.total, 1);
    /* one more: one error, nothing run */
    line[CON_LINE_MAX] = ' ';
    line[CON_LINE_MAX + 1] = '\n';
    line[CON_LINE_MAX + 2] = '\0';
    assert_string_equal(con_fix_run(line), "error:6 line too long\r\n");
    assert_int_equal(g_app.total, 1);
    /* very long: still one error, then the console is back to normal */
    memset(line, 'x', sizeof(line));
    line[sizeof(line) - 2] = '\n';
    line[sizeof(line) - 1] = '\0';
    assert_string_equal(con_fix_run(line), "error:6 line too long\r\n");
    /* backspace cannot shorten a discarded line */
    memset(line, 'a', 60);
    memset(line + 60, '\b', 30);
    memcpy(line + 90, "\n", 2);
    assert_string_equal(con_fix_run(line), "error:6 line too long\r\n");
    assert_string_equal(con_fix_run("status\n"), "ok\r\n");
    assert_int_equal(g_app.total, 2);
}

static void test_bad_bytes(void **state)
{
    static const uint8_t nul[] = {'s', 't', 'a', 0, 't', 'u', 's', '\n'};
    static const uint8_t high[] = {'s', 't', 0xC3, 0xA4, 't', 'u', 's', '\n'};
    static const uint8_t ctrl[] = {'s', 't', 'a', 0x1B, 't', 'u', 's', '\n'};
    static const uint8_t ff[] = {0xFF, '\n', 's', 't', 'a', 't', 'u', 's', '\n'};
    (void)state;
    assert_string_equal(con_fix_run_bytes(nul, sizeof(nul)), "error:7 bad character in line\r\n");
    assert_string_equal(con_fix_run_bytes(high, sizeof(high)), "error:7 bad character in line\r\n");
    assert_string_equal(con_fix_run_bytes(ctrl, sizeof(ctrl)), "error:7 bad character in line\r\n");
    assert_string_equal(con_fix_run_bytes(ff, sizeof(ff)),
                        "error:7 bad character in line\r\nok\r\n");
    assert_int_equal(g_app.total, 1);
    /* a bad byte in an overlong line: the length error wins, once */
    {
        uint8_t buf[80];
        memset(buf, 'a', sizeof(buf));
        buf[3] = 0;
        buf[79] = '\n';
        assert_string_equal(con_fix_run_bytes(buf, sizeof(buf)), "error:6 line too long\r\n");
    }
}

static void test_backspace(void **state)
{
    (void)state;
    assert_string_equal(con_fix_run("statx\bus\n"), "ok\r\n");
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 1);
    assert_string_equal(con_fix_run("homx\x7f"
                                    "e\n"),
                        "ok\r\n");
    assert_int_equal(g_app.calls[CON_CMD_HOME], 1);
    assert_string_equal(con_fix_run("\b\b\bstatus\n"), "ok\r\n"); /* nothing to erase: harmless */
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 2);
}

static void test_realtime_stop(void **state)
{
    (void)state;
    assert_int_equal(con_rt_take(&g_rt), 0);
    assert_string_equal(con_fix_run("sta!tus\n"), "ok\r\n"); /* taken out, the line still counts */
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 1);
    assert_int_equal(con_rt_take(&g_rt), 1);
    assert_int_equal(con_rt_take(&g_rt), 0);
    assert_string_equal(con_fix_run("!"), ""); /* a lone ! is no line */
    assert_int_equal(con_rt_take(&g_rt), 1);
    assert_string_equal(con_fix_run("!!!\n"), "ok\r\n"); /* !!! then an empty line */
    assert_int_equal(con_rt_take(&g_rt), 1);
    assert_int_equal(con_rt_take(&g_rt), 0);
    /* the interrupt hook */
    assert_int_equal(con_rt_byte(&g_rt, 'a'), 0);
    assert_int_equal(con_rt_byte(&g_rt, '\n'), 0);
    assert_int_equal(con_rt_take(&g_rt), 0);
    assert_int_equal(con_rt_byte(&g_rt, '!'), 1);
    assert_int_equal(con_rt_take(&g_rt), 1);
    /* the counter wraps without losing the event */
    g_rt.count = 255;
    g_rt.seen = 255;
    assert_int_equal(con_rt_byte(&g_rt, '!'), 1);
    assert_int_equal(con_rt_take(&g_rt), 1);
    /* while a command is pending the hook still sees the stop */
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("cal\n"), "");
    assert_int_equal(con_rt_byte(&g_rt, '!'), 1);
    assert_int_equal(con_rt_take(&g_rt), 1);
    assert_int_equal(con_complete(&g_con, CON_E_ABORTED), 0);
    assert_string_equal(con_fix_run(""), "error:20 aborted\r\n");
    /* a console without a realtime state still drops the ! */
    assert_int_equal(con_init(&g_con, &g_serial.io, g_handlers, &g_app, con_fake_copy, NULL), 0);
    g_app.result = 0;
    assert_string_equal(con_fix_run("stat!us\n"), "ok\r\n");
}

/* ---- numbers ----------------------------------------------------- */

static void test_parse_fixed(void **state)
{
    int32_t v = 99;
    (void)state;
    assert_int_equal(con_parse_fixed("0.8", 3, 3, &v), 0);
    assert_int_equal(v, 800);
    assert_int_equal(con_parse_fixed("12", 2, 0, &v), 0);
    assert_int_equal(v, 12);
    assert_int_equal(con_parse_fixed("-12", 3, 0, &v), 0);
    assert_int_equal(v, -12);
    assert_int_equal(con_parse_fixed("+1.", 3, 3, &v), 0);
    assert_int_equal(v, 1000);
    assert_int_equal(con_parse_fixed(".125", 4, 3, &v), 0);
    assert_int_equal(v, 125);
    assert_int_equal(con_parse_fixed("2147483.647", 11, 3, &v), 0);
    assert_int_equal(v, 2147483647);
    assert_int_equal(con_parse_fixed("0.8xyz", 3, 3, &v), 0); /* only len characters */
    assert_int_equal(v, 800);
    v = 99;
    assert_int_equal(con_parse_fixed("2147483.648", 11, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("2147483648", 10, 0, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("2147484", 7, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("1.5", 3, 0, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("1.0001", 6, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("", 0, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("-", 1, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("+.", 2, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("1e3", 3, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("--1", 3, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed("1.2.3", 5, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(con_parse_fixed(" 1", 2, 3, &v), CON_E_BAD_NUMBER);
    assert_int_equal(v, 99);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_arguments_parsed, con_fix_setup),
        cmocka_unit_test_setup(test_bad_arguments_change_nothing, con_fix_setup),
        cmocka_unit_test_setup(test_terminators_and_empty_lines, con_fix_setup),
        cmocka_unit_test_setup(test_overlong_line, con_fix_setup),
        cmocka_unit_test_setup(test_bad_bytes, con_fix_setup),
        cmocka_unit_test_setup(test_backspace, con_fix_setup),
        cmocka_unit_test_setup(test_realtime_stop, con_fix_setup),
        cmocka_unit_test_setup(test_parse_fixed, con_fix_setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
