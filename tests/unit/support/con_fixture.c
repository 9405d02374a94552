/* Fixtures for the console tests (con_fixture.h). */
#include "con_fixture.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

con_fake_t g_serial;
con_t g_con;
con_rt_t g_rt;
con_fix_app_t g_app;
uint16_t g_clock_ms;

static int8_t record(uint8_t cmd, con_t *c, const con_args_t *a, void *ctx)
{
    con_fix_app_t *p = (con_fix_app_t *)ctx;
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

con_handler_fn g_handlers[CON_CMD_COUNT] = {
#define CON_CMD(id, name, synopsis, help) h_##id,
#include "console/con_commands.def"
#undef CON_CMD
};

int con_fix_setup(void **state)
{
    (void)state;
    memset(&g_app, 0, sizeof(g_app));
    memset(&g_rt, 0, sizeof(g_rt));
    con_fake_init(&g_serial);
    for (int i = 0; i < CON_CMD_COUNT; i++) {
        g_handlers[i] = NULL;
    }
#define CON_CMD(id, name, synopsis, help) g_handlers[CON_CMD_##id] = h_##id;
#include "console/con_commands.def"
#undef CON_CMD
    assert_int_equal(con_init(&g_con, &g_serial.io, g_handlers, &g_app, con_fake_copy, &g_rt), 0);
    return 0;
}

const char *con_fix_run_bytes(const void *in, size_t n)
{
    size_t start = g_serial.out_taken;
    int i;
    con_fake_feed(&g_serial, in, n);
    for (i = 0; i < 100000; i++) {
        int8_t rc = con_poll(&g_con, g_clock_ms++);
        if (con_pending(&g_con)) {
            break;
        }
        if (rc == 0 && con_fake_unread(&g_serial) == 0u) {
            break;
        }
    }
    g_serial.out_taken = g_serial.out_len;
    return g_serial.out + start;
}

const char *con_fix_run(const char *in)
{
    return con_fix_run_bytes(in, strlen(in));
}
