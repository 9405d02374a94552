/*
 * libFuzzer target for the console: arbitrary bytes on the line, handlers
 * that succeed, fail, answer with undeclared codes or stay pending for a
 * while. Checks the protocol's promises: exactly one final reply per input
 * line, every output line is `ok`, `error:<code> <text>` or `<...>`, and
 * handlers only ever see arguments inside their declared ranges.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "console/console.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define LINE_MAX_OUT 512u

typedef struct {
    const uint8_t *in;
    size_t len, pos;
    char line[LINE_MAX_OUT]; /* output line being written */
    size_t line_len;
    int replies;
    const uint8_t *script; /* handler behaviour, taken from the input too */
    size_t script_len, script_pos;
} fz_t;

static fz_t fz;

static int16_t fz_read(void *ctx)
{
    fz_t *f = (fz_t *)ctx;
    return (f->pos < f->len) ? (int16_t)f->in[f->pos++] : -1;
}

/* Checks each output line as it completes and counts the final replies. */
static void fz_line(fz_t *f)
{
    const char *l = f->line;
    size_t n = f->line_len;
    if (n == 2u && memcmp(l, "ok", 2) == 0) {
        f->replies++;
    } else if (n > 8u && memcmp(l, "error:", 6) == 0 && l[6] >= '1' && l[6] <= '9') {
        f->replies++;
    } else if (!(n >= 2u && l[0] == '<' && l[n - 1u] == '>')) {
        abort();
    }
    f->line_len = 0;
}

static void fz_write(void *ctx, const char *buf, uint8_t n)
{
    fz_t *f = (fz_t *)ctx;
    uint8_t i;
    for (i = 0; i < n; i++) {
        if (buf[i] == '\n') {
            if (f->line_len == 0u || f->line[f->line_len - 1u] != '\r') {
                abort(); /* lines end in CRLF */
            }
            f->line_len--;
            fz_line(f);
            continue;
        }
        if (f->line_len >= LINE_MAX_OUT) {
            abort(); /* output lines are bounded */
        }
        f->line[f->line_len++] = buf[i];
    }
}

static void fz_copy(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}

static uint8_t script_byte(void)
{
    if (fz.script_len == 0u) {
        return 0;
    }
    return fz.script[fz.script_pos++ % fz.script_len];
}

static void in_range(const con_args_t *a, uint8_t arg, int32_t lo, int32_t hi, int required)
{
    if (!(a->given & (1u << arg))) {
        if (required) {
            abort();
        }
        return;
    }
    if (a->v[arg] < lo || a->v[arg] > hi || a->s[arg] == NULL) {
        abort();
    }
}

static int8_t handler(con_t *c, const con_args_t *a, void *app)
{
    uint8_t cmd = (uint8_t)(uintptr_t)app;
    uint8_t s = script_byte();
    (void)cmd;
    in_range(a, 0, -2147483647, 2147483647, 0);
    if (s & 0x80u) {
        con_report_begin(c, "fz");
        con_report_int(c, "a", a->v[0]);
        con_report_fixed(c, "b", a->v[1], (uint8_t)(s & 0x0Fu));
        con_report_end(c);
    }
    switch (s & 0x03u) {
    case 0:
        return 0;
    case 1:
        return CON_PENDING;
    case 2:
        return (int8_t)(-(int8_t)(s >> 2) - 1); /* declared or not */
    default:
        return CON_E_BUSY;
    }
}

static int8_t h_cal(con_t *c, const con_args_t *a, void *app)
{
    in_range(a, 0, 10, 10000, 0);
    in_range(a, 1, 0, 11, 0);
    return handler(c, a, app);
}

static int8_t h_learn(con_t *c, const con_args_t *a, void *app)
{
    in_range(a, 0, 0, 11, 1);
    in_range(a, 1, 10, 10000, 1);
    return handler(c, a, app);
}

static int8_t h_reboot(con_t *c, const con_args_t *a, void *app)
{
    in_range(a, 0, 0, 252, 1);
    return handler(c, a, app);
}

static int8_t h_servos(con_t *c, const con_args_t *a, void *app)
{
    in_range(a, 0, 0, 2, 0);
    return handler(c, a, app);
}

static int8_t h_set(con_t *c, const con_args_t *a, void *app)
{
    in_range(a, 0, 0, 0, 1); /* a word: v stays 0 */
    in_range(a, 1, -2147483647, 2147483647, 1);
    return handler(c, a, app);
}

/* Counts lines the way the protocol defines them: CR, LF or CRLF. */
static int count_lines(const uint8_t *in, size_t n)
{
    int lines = 0, last_cr = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        if (in[i] == '\r' || (in[i] == '\n' && !last_cr)) {
            lines++;
        }
        last_cr = in[i] == '\r';
    }
    return lines;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static con_handler_fn handlers[CON_CMD_COUNT];
    con_io_t io = {&fz, fz_read, fz_write, NULL};
    con_rt_t rt = {0, 0};
    con_t con;
    size_t split;
    uint8_t pending_polls = 0;
    uint16_t now = 0;
    uint8_t i;
    if (size < 1u) {
        return 0;
    }
    /* the first byte says how much of the tail is the handler script */
    split = (size_t)data[0] % 16u;
    if (split > size - 1u) {
        split = size - 1u;
    }
    memset(&fz, 0, sizeof(fz));
    fz.script = data + 1;
    fz.script_len = split;
    fz.in = data + 1 + split;
    fz.len = size - 1u - split;
    for (i = 0; i < CON_CMD_COUNT; i++) {
        handlers[i] = (i % 7u == 6u) ? NULL : handler;
    }
    handlers[CON_CMD_CAL] = h_cal;
    handlers[CON_CMD_LEARN] = h_learn;
    handlers[CON_CMD_REBOOT] = h_reboot;
    handlers[CON_CMD_SERVOS] = h_servos;
    handlers[CON_CMD_SET] = h_set;
    con_init(&con, &io, handlers, (void *)(uintptr_t)0, fz_copy, &rt);
    con_set_timeout(&con, (uint16_t)(data[0] >> 4)); /* 0 (none) .. 15 ms: deadlines fire too */
    /* every pending command is completed within 8 polls, so this ends */
    for (;;) {
        int8_t rc = con_poll(&con, now++);
        if (con_pending(&con)) {
            if ((script_byte() & 1u) || ++pending_polls >= 8u) {
                pending_polls = 0;
                if (con_complete(&con, (int8_t)(0 - (int)(script_byte() & 0x3Fu))) != 0) {
                    abort();
                }
                if (con_complete(&con, 0) != CON_E_NOT_PENDING) {
                    abort();
                }
            }
        } else if (rc == 0 && fz.pos == fz.len) {
            break;
        }
    }
    if (fz.line_len != 0u || fz.replies != count_lines(fz.in, fz.len)) {
        abort();
    }
    return 0;
}
