/*
 * app_steps: the steps the lib/app tests share (boot, a command and its
 * reply, a press) on the bench of app_bench.h.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "app_steps.h"

app_bench_t g_b;
char g_line[APP_STEPS_LINE];

void boot(app_bench_t *b, uint8_t with_table)
{
    assert_int_equal(app_bench_init(b, with_table), 0);
    assert_true(app_bench_wait_line(b, "<boot ", g_line, sizeof g_line, 10));
    assert_non_null(strstr(g_line, "name=hallhome"));
    assert_non_null(strstr(g_line, "board=\"native bench\""));
    assert_true(app_bench_wait_line(b, "<ready ", g_line, sizeof g_line, 4000));
}

/* Waits for the final reply of a command line. */
void reply(app_bench_t *b, const char *expect, uint32_t ms)
{
    uint64_t end = b->now_us + (uint64_t)ms * 1000u;
    for (;;) {
        while (con_fake_line(&b->con, g_line, sizeof g_line)) {
            if (g_line[0] != '<') {
                assert_string_equal(g_line, expect);
                return;
            }
        }
        assert_true(b->now_us < end);
        app_bench_step(b);
    }
}

void cmd(app_bench_t *b, const char *line, const char *expect)
{
    app_bench_send(b, line);
    reply(b, expect, 4000);
}

void press(app_bench_t *b, uint32_t ms)
{
    b->button = 1;
    app_bench_run_ms(b, ms);
    b->button = 0;
    app_bench_run_ms(b, 50);
}
