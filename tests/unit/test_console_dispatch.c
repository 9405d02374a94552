/* Unit tests of lib/console's dispatch: every command reaches its handler or
 * the application, handler results become replies, pending commands and
 * their deadline, and one final reply per line under random input. */
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

/* ---- dispatch ---------------------------------------------------- */

static void test_every_command_dispatches(void **state)
{
    char name[16];
    char line[32];
    uint8_t i;
    (void)state;
    for (i = 0; i < CON_CMD_COUNT; i++) {
        assert_true(con_cmd_name(&g_con, i, name, sizeof(name)) > 0);
        if (i == CON_CMD_HELP) {
            continue;
        }
        /* required arguments filled with a valid value */
        if (i == CON_CMD_LEARN) {
            snprintf(line, sizeof(line), "%s 2 0.5\n", name);
        } else if (i == CON_CMD_SET) {
            snprintf(line, sizeof(line), "%s filter_k 4\n", name);
        } else if (i == CON_CMD_REBOOT || i == CON_CMD_FORGET) {
            snprintf(line, sizeof(line), "%s 3\n", name);
        } else {
            snprintf(line, sizeof(line), "%s\n", name);
        }
        assert_string_equal(con_fix_run(line), "ok\r\n");
        assert_int_equal(g_app.calls[i], 1);
        assert_int_equal(g_app.last_cmd, i);
    }
    assert_int_equal(g_app.total, CON_CMD_COUNT - 1);
}

static void test_handler_results(void **state)
{
    (void)state;
    g_app.result = CON_E_BUSY;
    assert_string_equal(con_fix_run("home\n"), "error:9 busy\r\n");
    g_app.result = CON_E_MOVED;
    assert_string_equal(con_fix_run("rehome\n"),
                        "error:22 spool turned while powered off: full calibration needed\r\n");
    g_app.result = -77; /* not a declared code */
    assert_string_equal(con_fix_run("home\n"), "error:24 internal error\r\n");
    g_app.result = CON_E_NOT_PENDING;
    assert_string_equal(con_fix_run("home\n"), "error:24 internal error\r\n");
    g_app.result = 0;
    g_app.report = 1;
    assert_string_equal(con_fix_run("status\n"), "<rep cmd=2>\r\nok\r\n");
    g_handlers[CON_CMD_TABLE] = NULL;
    assert_string_equal(con_fix_run("table\n"), "error:10 not available in this firmware\r\n");
}

/* Every declared code replies with its own text (the reply finds the text
 * by the code's place in con_errors.def); the codes beyond the last, and
 * the most negative, reply as internal errors. */
static void test_every_error_code_has_its_text(void **state)
{
    static const struct {
        int8_t rc;
        const char *reply;
    } want[] = {
#define CON_ERR(code, id, text) {CON_E_##id, "error:" #code " " text "\r\n"},
#include "console/con_errors.def"
#undef CON_ERR
        {CON_E_BAD_HOLD - 1, "error:24 internal error\r\n"}, /* the last declared, minus 1 */
        {-128, "error:24 internal error\r\n"},
    };
    size_t i;
    (void)state;
    for (i = 0; i < sizeof want / sizeof want[0]; i++) {
        g_app.result = want[i].rc;
        assert_string_equal(con_fix_run("home\n"), want[i].reply);
    }
}

static void test_pending_defers_input(void **state)
{
    (void)state;
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("servos scan\nstatus\n"), "");
    assert_true(con_pending(&g_con));
    assert_int_equal(g_app.total, 1);
    /* the next line stays unread however long the command takes */
    for (int i = 0; i < 50; i++) {
        assert_int_equal(con_poll(&g_con, g_clock_ms++), 1);
    }
    assert_int_equal(con_fake_unread(&g_serial), strlen("status\n"));
    assert_int_equal(g_app.total, 1);
    /* reports while pending are fine; the args stay valid */
    assert_int_equal(g_app.last.v[0], 0);
    con_report_begin(&g_con, "servo");
    con_report_int(&g_con, "id", 3);
    con_report_end(&g_con);
    g_app.result = 0;
    assert_int_equal(con_complete(&g_con, CON_E_SERVO_FAULT), 0);
    assert_false(con_pending(&g_con));
    /* a second completion writes nothing */
    assert_int_equal(con_complete(&g_con, 0), CON_E_NOT_PENDING);
    assert_string_equal(con_fix_run(""),
                        "<servo id=3>\r\nerror:14 servo missing or faulty\r\nok\r\n");
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 1);
    /* completion with no command pending or with a non-final result */
    assert_int_equal(con_complete(&g_con, 0), CON_E_NOT_PENDING);
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("servos\n"), "");
    assert_int_equal(con_complete(&g_con, 1), CON_E_NOT_PENDING);
    assert_true(con_pending(&g_con));
    assert_int_equal(con_complete(&g_con, 0), 0);
    assert_string_equal(con_fix_run(""), "ok\r\n");
}

/* Without a handler table the application runs each validated line
 * itself: con_call() names it until con_called() takes the result, which
 * gets the reply a handler's would; nothing more is read meanwhile and bad
 * lines never reach the application. */
static void test_application_runs_commands(void **state)
{
    int i;
    (void)state;
    assert_int_equal(con_init(&g_con, &g_serial.io, NULL, NULL, con_fake_copy, &g_rt), 0);
    assert_int_equal(con_call(&g_con), -1);
    assert_int_equal(con_called(&g_con, 0), CON_E_NOT_PENDING);
    con_fake_feed(&g_serial, "cal 0.5\nstatus\n", 15);
    assert_int_equal(con_poll(&g_con, g_clock_ms++), 1);
    assert_int_equal(con_call(&g_con), CON_CMD_CAL);
    assert_int_equal(g_con.args.given, 1);
    assert_int_equal(g_con.args.v[0], 500);
    for (i = 0; i < 10; i++) {
        assert_int_equal(con_poll(&g_con, g_clock_ms++), 1);
    }
    assert_int_equal(con_fake_unread(&g_serial), strlen("status\n"));
    assert_int_equal(g_serial.out_len, 0u);
    /* reports of the command come before its reply */
    con_report_begin(&g_con, "rep");
    con_report_int(&g_con, "cmd", CON_CMD_CAL);
    con_report_end(&g_con);
    assert_int_equal(con_called(&g_con, 0), 0);
    assert_int_equal(con_call(&g_con), -1);
    assert_string_equal(con_fix_run(""), "<rep cmd=5>\r\nok\r\n");
    assert_int_equal(con_poll(&g_con, g_clock_ms++), 1);
    assert_int_equal(con_call(&g_con), CON_CMD_STATUS);
    assert_int_equal(con_called(&g_con, CON_PENDING), 0);
    assert_true(con_pending(&g_con));
    assert_int_equal(con_complete(&g_con, CON_E_BUSY), 0);
    assert_int_equal(con_call(&g_con), -1);
    assert_true(strncmp(con_fix_run(""), "error:", 6) == 0);
    assert_true(strncmp(con_fix_run("servos bogus\n"), "error:", 6) == 0);
    assert_int_equal(con_call(&g_con), -1);
    assert_true(strncmp(con_fix_run("help\n"), "<help cmd=help", 14) == 0);
    assert_int_equal(con_call(&g_con), -1);
}

static void test_pending_deadline(void **state)
{
    int i;
    (void)state;
    g_clock_ms = 65000; /* the deadline works across the clock's wrap */
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("servos scan\nstatus\n"), "");
    assert_true(con_pending(&g_con));
    for (i = 1; i < (int)CON_PENDING_MS; i++) {
        assert_int_equal(con_poll(&g_con, (uint16_t)(65000 + i)), 1);
    }
    assert_string_equal(g_serial.out + g_serial.out_taken, "");
    assert_int_equal(con_poll(&g_con, (uint16_t)(65000 + CON_PENDING_MS)), 0);
    assert_false(con_pending(&g_con));
    assert_string_equal(g_serial.out + g_serial.out_taken, "error:21 timed out\r\n");
    g_serial.out_taken = g_serial.out_len;
    /* the late completion writes nothing; the next line runs */
    assert_int_equal(con_complete(&g_con, 0), CON_E_NOT_PENDING);
    g_app.result = 0;
    g_clock_ms = 100;
    assert_string_equal(con_fix_run(""), "ok\r\n");
    assert_int_equal(g_app.calls[CON_CMD_STATUS], 1);
    /* a shorter deadline, and none at all */
    con_set_timeout(&g_con, 5);
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("home\n"), "");
    for (i = 0; i < 4; i++) {
        assert_int_equal(con_poll(&g_con, (uint16_t)(g_clock_ms + i)), 1);
    }
    assert_int_equal(con_poll(&g_con, (uint16_t)(g_clock_ms + 5)), 0);
    assert_string_equal(con_fix_run(""), "error:21 timed out\r\n");
    con_set_timeout(&g_con, 0);
    assert_string_equal(con_fix_run("home\n"), "");
    assert_int_equal(con_poll(&g_con, (uint16_t)(g_clock_ms + 60000)), 1);
    assert_int_equal(con_complete(&g_con, 0), 0);
    assert_string_equal(con_fix_run(""), "ok\r\n");
}

static void test_complete_inside_handler_is_refused(void **state)
{
    (void)state;
    g_app.complete_inside = 1;
    assert_string_equal(con_fix_run("home\n"), "ok\r\n");
    assert_int_equal(g_app.inner_rc, CON_E_NOT_PENDING);
    g_app.result = CON_PENDING;
    assert_string_equal(con_fix_run("home\n"), "");
    assert_int_equal(g_app.inner_rc, CON_E_NOT_PENDING);
    assert_true(con_pending(&g_con));
    assert_int_equal(con_complete(&g_con, CON_E_ABORTED), 0);
    assert_string_equal(con_fix_run(""), "error:20 aborted\r\n");
}

/* ---- one final reply per line, under random input and handler outcomes --- */

static uint32_t rng_state = 12345u;
static uint32_t rng(void)
{
    rng_state = rng_state * 1103515245u + 12345u;
    return rng_state >> 16;
}

static int count_replies(const char *out)
{
    int n = 0;
    const char *p = out;
    while ((p = strstr(p, "\r\n")) != NULL) {
        const char *start = p;
        while (start > out && start[-1] != '\n') {
            start--;
        }
        if (strncmp(start, "ok\r\n", 4) == 0 || strncmp(start, "error:", 6) == 0) {
            n++;
        }
        p += 2;
    }
    return n;
}

static void test_one_reply_per_line_random(void **state)
{
    static const char *words[] = {"status", "cal",    "0.8", "12",   "learn", "x",  "!",
                                  "help",   "servos", "pos", "-3",   "set",   " ",  "\t",
                                  "\b",     "\r",     "\n",  "\r\n", "\xff",  "get"};
    int round;
    (void)state;
    for (round = 0; round < 300; round++) {
        uint8_t in[400];
        size_t n = 0;
        int lines = 0, last_cr = 0, i;
        con_fix_setup(NULL);
        while (n < 300) {
            const char *w = words[rng() % (sizeof(words) / sizeof(words[0]))];
            size_t k = strlen(w);
            memcpy(in + n, w, k);
            n += k;
        }
        in[n++] = '\n';
        for (i = 0; i < (int)n; i++) {
            if (in[i] == '\r' || (in[i] == '\n' && !last_cr)) {
                lines++;
            }
            last_cr = in[i] == '\r';
        }
        con_fake_feed(&g_serial, in, n);
        for (i = 0; i < 200000; i++) {
            int8_t rc = con_poll(&g_con, g_clock_ms++);
            if (con_pending(&g_con) && rng() % 4u == 0u) {
                int8_t r = (rng() & 1u) ? 0 : CON_E_TIMEOUT;
                assert_int_equal(con_complete(&g_con, r), 0);
            }
            g_app.result =
                (int8_t)((rng() % 3u == 0u) ? CON_PENDING : ((rng() & 1u) ? 0 : CON_E_BUSY));
            if (rc == 0 && con_fake_unread(&g_serial) == 0u && !con_pending(&g_con)) {
                break;
            }
        }
        assert_int_equal(count_replies(g_serial.out), lines);
        assert_int_equal(g_serial.overflow, 0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_every_command_dispatches, con_fix_setup),
        cmocka_unit_test_setup(test_application_runs_commands, con_fix_setup),
        cmocka_unit_test_setup(test_handler_results, con_fix_setup),
        cmocka_unit_test_setup(test_every_error_code_has_its_text, con_fix_setup),
        cmocka_unit_test_setup(test_pending_defers_input, con_fix_setup),
        cmocka_unit_test_setup(test_pending_deadline, con_fix_setup),
        cmocka_unit_test_setup(test_complete_inside_handler_is_refused, con_fix_setup),
        cmocka_unit_test_setup(test_one_reply_per_line_random, con_fix_setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
