/* Unit tests of lib/console: line assembly, validation, dispatch, the
 * one-reply guarantee, reports and number formatting. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "con_fake.h"
#include "console/console.h"

typedef struct {
    int calls[CON_CMD_COUNT];
    int total;
    uint8_t last_cmd;
    con_args_t last;
    char s0[CON_LINE_MAX + 1];
    int8_t result;           /* what every handler returns */
    uint8_t report;          /* emit a report before returning */
    uint8_t complete_inside; /* call con_complete() from inside the handler */
    int8_t inner_rc;         /* what that call returned */
} app_t;

static con_fake_t fake;
static con_t con;
static con_rt_t rt;
static app_t app;
static uint16_t clock_ms; /* advances 1 ms per poll */

static int8_t record(uint8_t cmd, con_t *c, const con_args_t *a, void *ctx)
{
    app_t *p = (app_t *)ctx;
    p->calls[cmd]++;
    p->total++;
    p->last_cmd = cmd;
    p->last = *a;
    p->s0[0] = '\0';
    if (a->s[0] != NULL) {
        snprintf(p->s0, sizeof(p->s0), "%s", a->s[0]);
    }
    if (p->report) {
        con_report_begin(c, "rep");
        con_report_int(c, "cmd", cmd);
        con_report_end(c);
    }
    if (p->complete_inside) {
        p->inner_rc = con_complete(c, 0);
    }
    return p->result;
}

#define CON_CMD(id, name, synopsis, help)                                                          \
    static int8_t h_##id(con_t *c, const con_args_t *a, void *ctx)                                 \
    {                                                                                              \
        return record(CON_CMD_##id, c, a, ctx);                                                    \
    }
#include "console/con_commands.def"
#undef CON_CMD

static con_handler_fn handlers[CON_CMD_COUNT] = {
#define CON_CMD(id, name, synopsis, help) h_##id,
#include "console/con_commands.def"
#undef CON_CMD
};

static int setup(void **state)
{
    (void)state;
    memset(&app, 0, sizeof(app));
    memset(&rt, 0, sizeof(rt));
    con_fake_init(&fake);
    for (int i = 0; i < CON_CMD_COUNT; i++) {
        handlers[i] = NULL;
    }
#define CON_CMD(id, name, synopsis, help) handlers[CON_CMD_##id] = h_##id;
#include "console/con_commands.def"
#undef CON_CMD
    assert_int_equal(con_init(&con, &fake.io, handlers, &app, con_fake_copy, &rt), 0);
    return 0;
}

/* Feeds input, polls until everything is read and nothing is pending (or
 * a command stays pending), and returns the output written meanwhile. */
static const char *run_bytes(const void *in, size_t n)
{
    size_t start = fake.out_taken;
    int i;
    con_fake_feed(&fake, in, n);
    for (i = 0; i < 100000; i++) {
        int8_t rc = con_poll(&con, clock_ms++);
        if (con_pending(&con)) {
            break;
        }
        if (rc == 0 && con_fake_unread(&fake) == 0u) {
            break;
        }
    }
    fake.out_taken = fake.out_len;
    return fake.out + start;
}

static const char *run(const char *in)
{
    return run_bytes(in, strlen(in));
}

/* ---- dispatch ---------------------------------------------------- */

static void test_every_command_dispatches(void **state)
{
    char name[16];
    char line[32];
    uint8_t i;
    (void)state;
    for (i = 0; i < CON_CMD_COUNT; i++) {
        assert_true(con_cmd_name(&con, i, name, sizeof(name)) > 0);
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
        assert_string_equal(run(line), "ok\r\n");
        assert_int_equal(app.calls[i], 1);
        assert_int_equal(app.last_cmd, i);
    }
    assert_int_equal(app.total, CON_CMD_COUNT - 1);
}

static void test_arguments_parsed(void **state)
{
    (void)state;
    assert_string_equal(run("cal 0.8 3\n"), "ok\r\n");
    assert_int_equal(app.last.given, 3);
    assert_int_equal(app.last.v[0], 800);
    assert_int_equal(app.last.v[1], 3);
    assert_string_equal(app.last.s[0], "0.8");
    assert_string_equal(run("cal\n"), "ok\r\n");
    assert_int_equal(app.last.given, 0);
    assert_int_equal(app.last.v[0], 0);
    assert_null(app.last.s[0]);
    assert_string_equal(run("cal 2\n"), "ok\r\n");
    assert_int_equal(app.last.given, 1);
    assert_int_equal(app.last.v[0], 2000);
    assert_string_equal(run("cal .05\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 50);
    assert_string_equal(run("cal 10\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 10000);
    assert_string_equal(run("cal 0.01 0\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 10);
    assert_string_equal(run("learn 11 1.250\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 11);
    assert_int_equal(app.last.v[1], 1250);
    assert_string_equal(run("servos\n"), "ok\r\n");
    assert_int_equal(app.last.given, 0);
    assert_string_equal(run("servos scan\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 0);
    assert_string_equal(run("servos pos\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 1);
    assert_string_equal(run("servos err\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 2);
    assert_string_equal(run("get\n"), "ok\r\n");
    assert_int_equal(app.last.given, 0);
    assert_string_equal(run("get cal_tension\n"), "ok\r\n");
    assert_string_equal(app.s0, "cal_tension");
    assert_string_equal(run("set Filter_K -5\n"), "ok\r\n");
    assert_string_equal(app.s0, "Filter_K"); /* setting names are passed as typed */
    assert_int_equal(app.last.v[1], -5);
    assert_string_equal(run("set x 2147483647\n"), "ok\r\n");
    assert_int_equal(app.last.v[1], 2147483647);
    assert_string_equal(run("set x -2147483647\n"), "ok\r\n");
    assert_int_equal(app.last.v[1], -2147483647);
    assert_string_equal(run("reboot 252\n"), "ok\r\n");
    assert_int_equal(app.last.v[0], 252);
    assert_string_equal(run("reboot 0\n"), "ok\r\n");
    /* case-insensitive command names, extra spaces and tabs */
    assert_string_equal(run("  CAL\t 1.5   4  \n"), "ok\r\n");
    assert_int_equal(app.last_cmd, CON_CMD_CAL);
    assert_int_equal(app.last.v[0], 1500);
    assert_int_equal(app.last.v[1], 4);
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
        const char *out = run(cases[i].line);
        if (strcmp(out, cases[i].reply) != 0) {
            fail_msg("line %s got %s want %s", cases[i].line, out, cases[i].reply);
        }
        assert_int_equal(app.total, 0);
    }
}

static void test_handler_results(void **state)
{
    (void)state;
    app.result = CON_E_BUSY;
    assert_string_equal(run("home\n"), "error:9 busy\r\n");
    app.result = CON_E_MOVED;
    assert_string_equal(run("rehome\n"),
                        "error:22 spool turned while powered off: full calibration needed\r\n");
    app.result = -77; /* not a declared code */
    assert_string_equal(run("home\n"), "error:24 internal error\r\n");
    app.result = CON_E_NOT_PENDING;
    assert_string_equal(run("home\n"), "error:24 internal error\r\n");
    app.result = 0;
    app.report = 1;
    assert_string_equal(run("status\n"), "<rep cmd=2>\r\nok\r\n");
    handlers[CON_CMD_TABLE] = NULL;
    assert_string_equal(run("table\n"), "error:10 not available in this firmware\r\n");
}

static void test_pending_defers_input(void **state)
{
    (void)state;
    app.result = CON_PENDING;
    assert_string_equal(run("servos scan\nstatus\n"), "");
    assert_true(con_pending(&con));
    assert_int_equal(app.total, 1);
    /* the next line stays unread however long the command takes */
    for (int i = 0; i < 50; i++) {
        assert_int_equal(con_poll(&con, clock_ms++), 1);
    }
    assert_int_equal(con_fake_unread(&fake), strlen("status\n"));
    assert_int_equal(app.total, 1);
    /* reports while pending are fine; the args stay valid */
    assert_int_equal(app.last.v[0], 0);
    con_report_begin(&con, "servo");
    con_report_int(&con, "id", 3);
    con_report_end(&con);
    app.result = 0;
    assert_int_equal(con_complete(&con, CON_E_SERVO_FAULT), 0);
    assert_false(con_pending(&con));
    /* a second completion writes nothing */
    assert_int_equal(con_complete(&con, 0), CON_E_NOT_PENDING);
    assert_string_equal(run(""), "<servo id=3>\r\nerror:14 servo missing or faulty\r\nok\r\n");
    assert_int_equal(app.calls[CON_CMD_STATUS], 1);
    /* completion with no command pending or with a non-final result */
    assert_int_equal(con_complete(&con, 0), CON_E_NOT_PENDING);
    app.result = CON_PENDING;
    assert_string_equal(run("servos\n"), "");
    assert_int_equal(con_complete(&con, 1), CON_E_NOT_PENDING);
    assert_true(con_pending(&con));
    assert_int_equal(con_complete(&con, 0), 0);
    assert_string_equal(run(""), "ok\r\n");
}

/* Without a handler table the application runs each validated line
 * itself: con_call() names it until con_called() takes the result, which
 * gets the reply a handler's would; nothing more is read meanwhile and bad
 * lines never reach the application. */
static void test_application_runs_commands(void **state)
{
    int i;
    (void)state;
    assert_int_equal(con_init(&con, &fake.io, NULL, NULL, con_fake_copy, &rt), 0);
    assert_int_equal(con_call(&con), -1);
    assert_int_equal(con_called(&con, 0), CON_E_NOT_PENDING);
    con_fake_feed(&fake, "cal 0.5\nstatus\n", 15);
    assert_int_equal(con_poll(&con, clock_ms++), 1);
    assert_int_equal(con_call(&con), CON_CMD_CAL);
    assert_int_equal(con.args.given, 1);
    assert_int_equal(con.args.v[0], 500);
    for (i = 0; i < 10; i++) {
        assert_int_equal(con_poll(&con, clock_ms++), 1);
    }
    assert_int_equal(con_fake_unread(&fake), strlen("status\n"));
    assert_int_equal(fake.out_len, 0u);
    /* reports of the command come before its reply */
    con_report_begin(&con, "rep");
    con_report_int(&con, "cmd", CON_CMD_CAL);
    con_report_end(&con);
    assert_int_equal(con_called(&con, 0), 0);
    assert_int_equal(con_call(&con), -1);
    assert_string_equal(run(""), "<rep cmd=5>\r\nok\r\n");
    assert_int_equal(con_poll(&con, clock_ms++), 1);
    assert_int_equal(con_call(&con), CON_CMD_STATUS);
    assert_int_equal(con_called(&con, CON_PENDING), 0);
    assert_true(con_pending(&con));
    assert_int_equal(con_complete(&con, CON_E_BUSY), 0);
    assert_int_equal(con_call(&con), -1);
    assert_true(strncmp(run(""), "error:", 6) == 0);
    assert_true(strncmp(run("servos bogus\n"), "error:", 6) == 0);
    assert_int_equal(con_call(&con), -1);
    assert_true(strncmp(run("help\n"), "<help cmd=help", 14) == 0);
    assert_int_equal(con_call(&con), -1);
}

static void test_pending_deadline(void **state)
{
    int i;
    (void)state;
    clock_ms = 65000; /* the deadline works across the clock's wrap */
    app.result = CON_PENDING;
    assert_string_equal(run("servos scan\nstatus\n"), "");
    assert_true(con_pending(&con));
    for (i = 1; i < (int)CON_PENDING_MS; i++) {
        assert_int_equal(con_poll(&con, (uint16_t)(65000 + i)), 1);
    }
    assert_string_equal(fake.out + fake.out_taken, "");
    assert_int_equal(con_poll(&con, (uint16_t)(65000 + CON_PENDING_MS)), 0);
    assert_false(con_pending(&con));
    assert_string_equal(fake.out + fake.out_taken, "error:21 timed out\r\n");
    fake.out_taken = fake.out_len;
    /* the late completion writes nothing; the next line runs */
    assert_int_equal(con_complete(&con, 0), CON_E_NOT_PENDING);
    app.result = 0;
    clock_ms = 100;
    assert_string_equal(run(""), "ok\r\n");
    assert_int_equal(app.calls[CON_CMD_STATUS], 1);
    /* a shorter deadline, and none at all */
    con_set_timeout(&con, 5);
    app.result = CON_PENDING;
    assert_string_equal(run("home\n"), "");
    for (i = 0; i < 4; i++) {
        assert_int_equal(con_poll(&con, (uint16_t)(clock_ms + i)), 1);
    }
    assert_int_equal(con_poll(&con, (uint16_t)(clock_ms + 5)), 0);
    assert_string_equal(run(""), "error:21 timed out\r\n");
    con_set_timeout(&con, 0);
    assert_string_equal(run("home\n"), "");
    assert_int_equal(con_poll(&con, (uint16_t)(clock_ms + 60000)), 1);
    assert_int_equal(con_complete(&con, 0), 0);
    assert_string_equal(run(""), "ok\r\n");
}

static void test_complete_inside_handler_is_refused(void **state)
{
    (void)state;
    app.complete_inside = 1;
    assert_string_equal(run("home\n"), "ok\r\n");
    assert_int_equal(app.inner_rc, CON_E_NOT_PENDING);
    app.result = CON_PENDING;
    assert_string_equal(run("home\n"), "");
    assert_int_equal(app.inner_rc, CON_E_NOT_PENDING);
    assert_true(con_pending(&con));
    assert_int_equal(con_complete(&con, CON_E_ABORTED), 0);
    assert_string_equal(run(""), "error:20 aborted\r\n");
}

/* ---- line assembly ----------------------------------------------- */

static void test_terminators_and_empty_lines(void **state)
{
    (void)state;
    assert_string_equal(run("status\r"), "ok\r\n");
    assert_string_equal(run("status\r\n"), "ok\r\n");
    assert_string_equal(run("status\n"), "ok\r\n");
    assert_int_equal(app.total, 3);
    /* CR then LF in a later read is still one terminator */
    assert_string_equal(run("status\r"), "ok\r\n");
    assert_string_equal(run("\nstatus\n"), "ok\r\n");
    assert_int_equal(app.total, 5);
    /* empty lines get ok (host sync) and call nothing */
    assert_string_equal(run("\n"), "ok\r\n");
    assert_string_equal(run("\r\n"), "ok\r\n");
    assert_string_equal(run("\n\n"), "ok\r\nok\r\n");
    assert_string_equal(run("\r\r"), "ok\r\nok\r\n");
    assert_string_equal(run("\n"), ""); /* the LF of the last CR's CRLF */
    assert_string_equal(run("   \t \n"), "ok\r\n");
    assert_string_equal(run("\n\r"), "ok\r\nok\r\n");
    assert_int_equal(app.total, 5);
    /* no terminator yet: no reply */
    assert_string_equal(run("stat"), "");
    assert_string_equal(run("us\n"), "ok\r\n");
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
    assert_string_equal(run(line), "ok\r\n");
    assert_int_equal(app.total, 1);
    /* one more: one error, nothing run */
    line[CON_LINE_MAX] = ' ';
    line[CON_LINE_MAX + 1] = '\n';
    line[CON_LINE_MAX + 2] = '\0';
    assert_string_equal(run(line), "error:6 line too long\r\n");
    assert_int_equal(app.total, 1);
    /* very long: still one error, then the console is back to normal */
    memset(line, 'x', sizeof(line));
    line[sizeof(line) - 2] = '\n';
    line[sizeof(line) - 1] = '\0';
    assert_string_equal(run(line), "error:6 line too long\r\n");
    /* backspace cannot shorten a discarded line */
    memset(line, 'a', 60);
    memset(line + 60, '\b', 30);
    memcpy(line + 90, "\n", 2);
    assert_string_equal(run(line), "error:6 line too long\r\n");
    assert_string_equal(run("status\n"), "ok\r\n");
    assert_int_equal(app.total, 2);
}

static void test_bad_bytes(void **state)
{
    static const uint8_t nul[] = {'s', 't', 'a', 0, 't', 'u', 's', '\n'};
    static const uint8_t high[] = {'s', 't', 0xC3, 0xA4, 't', 'u', 's', '\n'};
    static const uint8_t ctrl[] = {'s', 't', 'a', 0x1B, 't', 'u', 's', '\n'};
    static const uint8_t ff[] = {0xFF, '\n', 's', 't', 'a', 't', 'u', 's', '\n'};
    (void)state;
    assert_string_equal(run_bytes(nul, sizeof(nul)), "error:7 bad character in line\r\n");
    assert_string_equal(run_bytes(high, sizeof(high)), "error:7 bad character in line\r\n");
    assert_string_equal(run_bytes(ctrl, sizeof(ctrl)), "error:7 bad character in line\r\n");
    assert_string_equal(run_bytes(ff, sizeof(ff)), "error:7 bad character in line\r\nok\r\n");
    assert_int_equal(app.total, 1);
    /* a bad byte in an overlong line: the length error wins, once */
    {
        uint8_t buf[80];
        memset(buf, 'a', sizeof(buf));
        buf[3] = 0;
        buf[79] = '\n';
        assert_string_equal(run_bytes(buf, sizeof(buf)), "error:6 line too long\r\n");
    }
}

static void test_backspace(void **state)
{
    (void)state;
    assert_string_equal(run("statx\bus\n"), "ok\r\n");
    assert_int_equal(app.calls[CON_CMD_STATUS], 1);
    assert_string_equal(run("homx\x7f"
                            "e\n"),
                        "ok\r\n");
    assert_int_equal(app.calls[CON_CMD_HOME], 1);
    assert_string_equal(run("\b\b\bstatus\n"), "ok\r\n"); /* nothing to erase: harmless */
    assert_int_equal(app.calls[CON_CMD_STATUS], 2);
}

static void test_realtime_stop(void **state)
{
    (void)state;
    assert_int_equal(con_rt_take(&rt), 0);
    assert_string_equal(run("sta!tus\n"), "ok\r\n"); /* taken out, the line still counts */
    assert_int_equal(app.calls[CON_CMD_STATUS], 1);
    assert_int_equal(con_rt_take(&rt), 1);
    assert_int_equal(con_rt_take(&rt), 0);
    assert_string_equal(run("!"), ""); /* a lone ! is no line */
    assert_int_equal(con_rt_take(&rt), 1);
    assert_string_equal(run("!!!\n"), "ok\r\n"); /* !!! then an empty line */
    assert_int_equal(con_rt_take(&rt), 1);
    assert_int_equal(con_rt_take(&rt), 0);
    /* the interrupt hook */
    assert_int_equal(con_rt_byte(&rt, 'a'), 0);
    assert_int_equal(con_rt_byte(&rt, '\n'), 0);
    assert_int_equal(con_rt_take(&rt), 0);
    assert_int_equal(con_rt_byte(&rt, '!'), 1);
    assert_int_equal(con_rt_take(&rt), 1);
    /* the counter wraps without losing the event */
    rt.count = 255;
    rt.seen = 255;
    assert_int_equal(con_rt_byte(&rt, '!'), 1);
    assert_int_equal(con_rt_take(&rt), 1);
    /* while a command is pending the hook still sees the stop */
    app.result = CON_PENDING;
    assert_string_equal(run("cal\n"), "");
    assert_int_equal(con_rt_byte(&rt, '!'), 1);
    assert_int_equal(con_rt_take(&rt), 1);
    assert_int_equal(con_complete(&con, CON_E_ABORTED), 0);
    assert_string_equal(run(""), "error:20 aborted\r\n");
    /* a console without a realtime state still drops the ! */
    assert_int_equal(con_init(&con, &fake.io, handlers, &app, con_fake_copy, NULL), 0);
    app.result = 0;
    assert_string_equal(run("stat!us\n"), "ok\r\n");
}

/* ---- help -------------------------------------------------------- */

static void test_help_generated(void **state)
{
    char line[200];
    char name[16];
    int n = 0;
    (void)state;
    con_fake_puts(&fake, "help\nstatus\n");
    /* one help line per poll; the next command waits */
    for (int i = 0; i < 1000 && con_fake_unread(&fake) > 0u; i++) {
        (void)con_poll(&con, clock_ms++);
        if (app.total == 0) {
            assert_true(fake.out_len < 200u * (size_t)(i + 1));
        }
    }
    while (con_poll(&con, clock_ms++) != 0) {
    }
    while (con_fake_line(&fake, line, sizeof(line))) {
        if (n < CON_CMD_COUNT) {
            assert_true(con_cmd_name(&con, (uint8_t)n, name, sizeof(name)) > 0);
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
    assert_int_equal(app.calls[CON_CMD_HELP], 0); /* built in */
    assert_int_equal(app.calls[CON_CMD_STATUS], 1);
}

static void test_cmd_name(void **state)
{
    char buf[8];
    (void)state;
    assert_int_equal(con_cmd_name(&con, CON_CMD_VERSION, buf, sizeof(buf)), 7);
    assert_string_equal(buf, "version");
    assert_int_equal(con_cmd_name(&con, CON_CMD_VERSION, buf, 4), 7);
    assert_string_equal(buf, "ver");
    assert_int_equal(con_cmd_name(&con, CON_CMD_COUNT, buf, sizeof(buf)), CON_E_INTERNAL);
    assert_int_equal(con_cmd_name(&con, 0, buf, 0), CON_E_INTERNAL);
}

/* ---- reports and numbers ----------------------------------------- */

static void test_reports(void **state)
{
    char line[128];
    (void)state;
    con_report_begin(&con, "cal");
    con_report_int(&con, "t", 3);
    con_report_int(&con, "pos", -123456);
    con_report_fixed(&con, "N", 800, 3);
    con_report_fixed(&con, "d", -5, 1);
    con_report_str(&con, "name", "paper_2seg");
    con_report_str(&con, "msg", "two words");
    con_report_str(&con, "e", "");
    con_report_flash(&con, "f", "a=b");
    con_report_end(&con);
    assert_int_equal(con_fake_line(&fake, line, sizeof(line)), 1);
    assert_string_equal(line, "<cal t=3 pos=-123456 N=0.800 d=-0.5 name=paper_2seg "
                              "msg=\"two words\" e=\"\" f=\"a=b\">");
    assert_int_equal(con_fake_line(&fake, line, sizeof(line)), 0);
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
        setup(NULL);
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
        con_fake_feed(&fake, in, n);
        for (i = 0; i < 200000; i++) {
            int8_t rc = con_poll(&con, clock_ms++);
            if (con_pending(&con) && rng() % 4u == 0u) {
                int8_t r = (rng() & 1u) ? 0 : CON_E_TIMEOUT;
                assert_int_equal(con_complete(&con, r), 0);
            }
            app.result =
                (int8_t)((rng() % 3u == 0u) ? CON_PENDING : ((rng() & 1u) ? 0 : CON_E_BUSY));
            if (rc == 0 && con_fake_unread(&fake) == 0u && !con_pending(&con)) {
                break;
            }
        }
        assert_int_equal(count_replies(fake.out), lines);
        assert_int_equal(fake.overflow, 0);
    }
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
    g_fake_write = fake.io.write;
    fake.io.write = checked_write;
    fake.io.room = fake_room;
    con_set_realtime(&con, 1);
}

static void test_realtime_drops_reports_without_room(void **state)
{
    (void)state;
    realtime_setup(10);
    assert_int_equal(con_report_fits(&con), 0); /* what a caller that must not lose it asks */
    con_report_begin(&con, "progress");
    con_report_int(&con, "tendon", 3);
    con_report_end(&con);
    assert_int_equal(fake.out_len, 0u);
    assert_int_equal(con_dropped(&con), 1u);
    g_room = 255;
    assert_int_equal(con_report_fits(&con), 1);
    con_report_begin(&con, "progress");
    con_report_int(&con, "tendon", 3);
    con_report_end(&con);
    assert_string_equal(fake.out, "<progress tendon=3>\r\n");
    assert_int_equal(con_dropped(&con), 1u);
    assert_int_equal(g_over, 0u);
}

/* Realtime: a line is taken only when the longest output and the reserve
 * fit, so a command's report is not dropped (a `version` taken just after a
 * reset's <ready> and <released> came back with its `ok` alone). */
static void test_realtime_command_output_leaves_reserve(void **state)
{
    (void)state;
    realtime_setup(CON_RESERVE + 10u); /* the reply fits, a report plus reserve not */
    app.report = 1;
    assert_string_equal(run("version\n"), ""); /* waits unread */
    assert_int_equal(app.total, 0);
    g_room = 255;
    assert_string_equal(run(""), "<rep cmd=1>\r\nok\r\n");
    assert_int_equal(con_dropped(&con), 0u);
    assert_int_equal(g_over, 0u);
}

static void test_realtime_reply_waits_for_room(void **state)
{
    int i;
    (void)state;
    realtime_setup(0);
    con_fake_puts(&fake, "version\nversion\n");
    for (i = 0; i < 50; i++) {
        assert_int_equal(con_poll(&con, clock_ms++), 0); /* no room: reads nothing */
    }
    assert_int_equal(fake.out_len, 0u);
    assert_int_equal(app.total, 0);
    g_room = 255;
    assert_string_equal(run(""), "ok\r\n"); /* the next waits for the ring to drain */
    assert_int_equal(app.total, 1);
    g_room = 255;
    assert_string_equal(run(""), "ok\r\n");
    assert_int_equal(app.total, 2);
    assert_int_equal(g_over, 0u);
}

static void test_realtime_help_waits_line_by_line(void **state)
{
    char line[256];
    int i, n = 0;
    (void)state;
    realtime_setup(CON_OUT_MAX + CON_RESERVE - 1u);
    con_fake_puts(&fake, "help\n");
    for (i = 0; i < 50; i++) {
        (void)con_poll(&con, clock_ms++);
    }
    assert_int_equal(fake.out_len, 0u);
    for (i = 0; i < 1000 && n <= CON_CMD_COUNT; i++) {
        g_room = 255;
        (void)con_poll(&con, clock_ms++);
        while (con_fake_line(&fake, line, sizeof line)) {
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
    app.report = 1;
    for (i = 0; i < 300; i++) {
        if (i % 3 == 0 && sent < 60) {
            con_fake_puts(&fake, (i % 2) ? "version\n" : "status\n");
            sent++;
        }
        x = x * 1103515245u + 12345u;
        g_room = (uint16_t)((x >> 16) % 256u);
        (void)con_poll(&con, clock_ms++);
    }
    for (i = 0; i < 5000 && replies < sent; i++) {
        g_room = 255;
        (void)con_poll(&con, clock_ms++);
        while (con_fake_line(&fake, line, sizeof line)) {
            if (strcmp(line, "ok") == 0) {
                replies++;
            } else {
                assert_true(line[0] == '<' && line[strlen(line) - 1] == '>');
            }
        }
        if (con_fake_unread(&fake) == 0u && replies == sent) {
            break;
        }
    }
    while (con_fake_line(&fake, line, sizeof line)) {
        replies += strcmp(line, "ok") == 0;
    }
    assert_int_equal(replies, sent);
    assert_int_equal(g_over, 0u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_every_command_dispatches, setup),
        cmocka_unit_test_setup(test_application_runs_commands, setup),
        cmocka_unit_test_setup(test_arguments_parsed, setup),
        cmocka_unit_test_setup(test_bad_arguments_change_nothing, setup),
        cmocka_unit_test_setup(test_handler_results, setup),
        cmocka_unit_test_setup(test_pending_defers_input, setup),
        cmocka_unit_test_setup(test_pending_deadline, setup),
        cmocka_unit_test_setup(test_complete_inside_handler_is_refused, setup),
        cmocka_unit_test_setup(test_terminators_and_empty_lines, setup),
        cmocka_unit_test_setup(test_overlong_line, setup),
        cmocka_unit_test_setup(test_bad_bytes, setup),
        cmocka_unit_test_setup(test_backspace, setup),
        cmocka_unit_test_setup(test_realtime_stop, setup),
        cmocka_unit_test_setup(test_help_generated, setup),
        cmocka_unit_test_setup(test_cmd_name, setup),
        cmocka_unit_test_setup(test_reports, setup),
        cmocka_unit_test_setup(test_format_fixed, setup),
        cmocka_unit_test_setup(test_parse_fixed, setup),
        cmocka_unit_test_setup(test_one_reply_per_line_random, setup),
        cmocka_unit_test_setup(test_realtime_drops_reports_without_room, setup),
        cmocka_unit_test_setup(test_realtime_command_output_leaves_reserve, setup),
        cmocka_unit_test_setup(test_realtime_reply_waits_for_room, setup),
        cmocka_unit_test_setup(test_realtime_help_waits_line_by_line, setup),
        cmocka_unit_test_setup(test_realtime_random_room_one_reply_per_line, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
