/*
 * The console's line handling: bytes assembled into lines, each line
 * executed (its handler called, or held for con_call()), pending commands
 * and their deadline, the help listing paced by con_poll(), realtime `!`
 * bytes. con_priv.h lists the console's files.
 */
#include "console/console.h"

#include <string.h>

#include "console/con_priv.h"

#define F_OVER 0x01u /* line overflowed: discard to its end */
#define F_BAD  0x02u /* line holds a control or non-ASCII byte */
#define F_CR   0x04u /* last terminator was CR: a following LF is part of it */

#define CON_POLL_BYTES 16u

/* ---- line handling ----------------------------------------------- */

/* The console has a handler table (console.h, CON_HANDLERS). */
#if CON_HANDLERS
#define CON_TABLE(c) ((c)->handlers != NULL)
#else
#define CON_TABLE(c) 0
#endif

/* A handler's result: the final reply now, or the command pending. */
CON_NOINLINE static void end_call(con_t *c, int8_t rc)
{
    if (rc > 0) {
        c->state = CON_ST_PENDING;
        c->t_pending = c->now;
        return;
    }
    c->state = CON_ST_READ;
    con_reply(c, rc);
}

static void execute(con_t *c)
{
    char *tok[CON_MAX_ARGS + 2];
    char *p = c->line;
    uint8_t ntok = 0, j;
    int8_t cmd, rc;
#if CON_HANDLERS
    con_handler_fn h;
#endif
    for (;;) {
        while (*p == ' ') {
            *p++ = '\0';
        }
        if (*p == '\0') {
            break;
        }
        if (ntok < (uint8_t)(sizeof(tok) / sizeof(tok[0]))) {
            tok[ntok++] = p;
        } else {
            ntok = (uint8_t)(CON_MAX_ARGS + 2u); /* more than any synopsis takes */
        }
        while (*p != ' ' && *p != '\0') {
            p++;
        }
    }
    if (ntok == 0u) {
        con_reply(c, 0); /* empty line: `ok`, so a host can synchronise */
        return;
    }
    for (j = 0; tok[0][j] != '\0'; j++) {
        if (tok[0][j] >= 'A' && tok[0][j] <= 'Z') {
            tok[0][j] = (char)(tok[0][j] - 'A' + 'a');
        }
    }
    cmd = con_find_cmd(c, tok[0]);
    if (cmd < 0) {
        con_reply(c, cmd);
        return;
    }
    rc = con_check_args(c, (uint8_t)cmd, tok + 1, (uint8_t)(ntok - 1u));
    if (rc < 0) {
        con_reply(c, rc);
        return;
    }
    if (cmd == CON_CMD_HELP) {
        con_help_start(c);
        return;
    }
    if (!CON_TABLE(c)) {
        c->state = CON_ST_CALL; /* the application runs it: con_call() */
        c->call = (uint8_t)cmd;
        return;
    }
#if CON_HANDLERS
    c->copy(&h, &c->handlers[cmd], sizeof(h));
    if (h == NULL) {
        con_reply(c, CON_E_NOT_AVAILABLE);
        return;
    }
    c->state = CON_ST_CALL;
    end_call(c, h(c, &c->args, c->app));
#endif
}

static void end_line(con_t *c)
{
    uint8_t fl = c->flags;
    c->line[c->len] = '\0';
    c->len = 0;
    c->flags = (uint8_t)(c->flags & F_CR);
    if (fl & F_OVER) {
        con_reply(c, CON_E_LINE_TOO_LONG);
    } else if (fl & F_BAD) {
        con_reply(c, CON_E_BAD_CHAR);
    } else {
        execute(c);
    }
}

/* Returns 1 when b ended a line (its reply is written or pending). */
static uint8_t take_byte(con_t *c, uint8_t b)
{
    if (c->flags & F_CR) {
        c->flags = (uint8_t)(c->flags & ~F_CR);
        if (b == '\n') {
            return 0; /* second half of CRLF */
        }
    }
    if (b == '!') {
        if (c->rt != NULL) {
            c->rt->count++;
        }
        return 0;
    }
    if (b == '\r' || b == '\n') {
        if (b == '\r') {
            c->flags |= F_CR;
        }
        end_line(c);
        return 1;
    }
    if (b == 0x08u || b == 0x7Fu) {
        if (c->len > 0u && !(c->flags & F_OVER)) {
            c->len--;
        }
        return 0;
    }
    if (b == '\t') {
        b = ' ';
    }
    if (b < 0x20u || b > 0x7Eu) {
        c->flags |= F_BAD;
        return 0;
    }
    if (c->len < CON_LINE_MAX) {
        c->line[c->len++] = (char)b;
    } else {
        c->flags |= F_OVER;
    }
    return 0;
}

/* ---- public ------------------------------------------------------ */

int8_t con_init(con_t *con, const con_io_t *io, const con_handler_fn *handlers, void *app,
                con_copy_fn copy, con_rt_t *rt)
{
    memset(con, 0, sizeof(*con));
#if CON_IO_FIXED
    (void)io;
#else
    con->io = io;
#endif
#if CON_HANDLERS
    con->handlers = handlers;
    con->app = app;
    con->copy = copy;
#else
    (void)handlers;
    (void)app;
    (void)copy;
#endif
    con->rt = rt;
    con->state = CON_ST_READ;
    con->pending_ms = CON_PENDING_MS;
    return 0;
}

void con_set_timeout(con_t *con, uint16_t ms)
{
    con->pending_ms = ms;
}

int8_t con_poll(con_t *con, uint16_t now_ms)
{
    uint8_t n;
    con->now = now_ms;
    if (con->state == CON_ST_PENDING) {
        if (con->pending_ms == 0u || (uint16_t)(now_ms - con->t_pending) < con->pending_ms) {
            return 1;
        }
        /* the application lost the command: the line still gets its reply */
        con->state = CON_ST_READ;
        con_reply(con, CON_E_TIMEOUT);
        return 0;
    }
    if (con->state == CON_ST_CALL) {
        return 1;
    }
    if (con->state == CON_ST_HELD) {
        con->state = CON_ST_READ;
        con_reply(con, con->held_rc);
        return con->state == CON_ST_READ ? 0 : 1;
    }
    if (con->state == CON_ST_HELP) {
        if (con->help_i < CON_CMD_COUNT) {
            /* a line is assembled only when the longest fits, so a full
             * ring costs no work per pass and no pass waits for the UART */
            if (con_line_fits(con)) {
                con->help_i = (uint8_t)(con->help_i + con_help_line(con));
            }
            return 1;
        }
        con->state = CON_ST_READ;
        con_reply(con, 0);
        return 0;
    }
    if (con->realtime &&
        ((uint16_t)(now_ms - con->t_line) < CON_RT_LINE_MS || !con_report_fits(con))) {
        /* realtime: one line per CON_RT_LINE_MS, and only when its output
         * fits (a `version` taken just after a reset's <ready> and
         * <released> lost its report); the rest waits in the ring */
        return 0;
    }
    for (n = 0; n < CON_POLL_BYTES; n++) {
        int16_t b = CON_IO_READ(con);
        if (b < 0) {
            break;
        }
        if (take_byte(con, (uint8_t)b)) {
            con->t_line = now_ms;
            break;
        }
    }
    return (con->state == CON_ST_READ) ? 0 : 1;
}

void con_set_realtime(con_t *con, uint8_t on)
{
    con->realtime = on;
}

uint16_t con_dropped(const con_t *con)
{
    return con->dropped;
}

int8_t con_complete(con_t *con, int8_t rc)
{
    if (con->state != CON_ST_PENDING || rc > 0) {
        return CON_E_NOT_PENDING;
    }
    con->state = CON_ST_READ;
    con_reply(con, rc);
    return 0;
}

uint8_t con_pending(const con_t *con)
{
    return con->state == CON_ST_PENDING;
}

int8_t con_call(const con_t *con)
{
    return (con->state == CON_ST_CALL && !CON_TABLE(con)) ? (int8_t)con->call : -1;
}

int8_t con_called(con_t *con, int8_t rc)
{
    if (con_call(con) < 0) {
        return CON_E_NOT_PENDING;
    }
    end_call(con, rc);
    return 0;
}

uint8_t con_rt_byte(con_rt_t *rt, uint8_t byte)
{
    if (byte != '!') {
        return 0;
    }
    rt->count++;
    return 1;
}

uint8_t con_rt_take(con_rt_t *rt)
{
    uint8_t now = rt->count;
    if (now == rt->seen) {
        return 0;
    }
    rt->seen = now;
    return 1;
}
