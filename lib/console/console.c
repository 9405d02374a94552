#include "console/console.h"

#include <string.h>

#define ST_READ    0u /* assembling a line */
#define ST_CALL    1u /* inside a handler */
#define ST_PENDING 2u /* handler accepted, waiting for con_complete() */
#define ST_HELP    3u /* writing the help listing */
#define ST_HELD    4u /* a final reply waits for room (realtime mode) */

#define F_OVER 0x01u /* line overflowed: discard to its end */
#define F_BAD  0x02u /* line holds a control or non-ASCII byte */
#define F_CR   0x04u /* last terminator was CR: a following LF is part of it */

#define CON_POLL_BYTES 16u
#define CON_SYN_MAX    64u /* longest synopsis (checked by the unit tests) */
#define CON_MAG_MAX    2147483647UL

/* Functions that measured smaller on the AVR as calls than inlined into the
 * line handling (argument checks, a handler's result). */
#if defined(__GNUC__)
#define CON_NOINLINE __attribute__((noinline))
#else
#define CON_NOINLINE
#endif

/* name, synopsis and help of every command, NUL-separated, in enum order:
 * one flash string instead of 3 * N pointers. */
static const char con_cmd_text[] CON_FLASH =
#define CON_CMD(id, name, synopsis, help) name "\0" synopsis "\0" help "\0"
#include "console/con_commands.def"
#undef CON_CMD
    ;

static const uint8_t con_err_codes[] CON_FLASH = {
#define CON_ERR(code, id, text) (code),
#include "console/con_errors.def"
#undef CON_ERR
};

static const char con_err_text[] CON_FLASH =
#define CON_ERR(code, id, text) text "\0"
#include "console/con_errors.def"
#undef CON_ERR
    ;

/* Fixed output text, kept in flash (a string literal would cost AVR RAM). */
static const char s_ok[] CON_FLASH = "ok\r\n";
static const char s_error[] CON_FLASH = "error:";
static const char s_crlf[] CON_FLASH = "\r\n";
static const char s_rep_end[] CON_FLASH = ">\r\n";
static const char s_help_cmd[] CON_FLASH = "<help cmd=";
static const char s_help_args[] CON_FLASH = " args=\"";
static const char s_help_text[] CON_FLASH = "\" text=\"";
static const char s_help_end[] CON_FLASH = "\">\r\n";

/* ---- flash access ------------------------------------------------ */

/* One byte of a flash string. The scans below read them one at a time
 * (command lookup, synopsis, error text: about 1 KB per line): an inline
 * LPM on the AVR, not a call through copy per byte (11 ms per line). */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define CON_FLASH_BYTE(p) ((char)pgm_read_byte(p))
#else
#define CON_FLASH_BYTE(p) (*(p))
#endif

static char fl_char(const con_t *c, const char *p)
{
    (void)c;
    return CON_FLASH_BYTE(p);
}

/* Pointer past the next n NUL-terminated strings at p. */
static const char *fl_skip(const con_t *c, const char *p, uint16_t n)
{
    while (n > 0u) {
        if (fl_char(c, p++) == '\0') {
            n--;
        }
    }
    return p;
}

/* ---- output ------------------------------------------------------ */

/* In realtime mode output is assembled a line at a time in obuf (see
 * con_set_realtime()); otherwise it is written at once. */
static void out(con_t *c, const char *s, uint8_t n)
{
    if (!c->realtime) {
        if (n > 0u) {
            c->io->write(c->io->ctx, s, n); /* may wait: nothing moves */
        }
        return;
    }
    if (c->olen > CON_OUT_MAX || (uint16_t)c->olen + n > CON_OUT_MAX) {
        c->olen = CON_OUT_MAX + 1u; /* too long: never written in part */
        return;
    }
    memcpy(&c->obuf[c->olen], s, n);
    c->olen = (uint8_t)(c->olen + n);
}

/* Writes the assembled line when it may be written now, keeping `reserve`
 * bytes of room free in realtime mode. Returns 1 when written (or dropped for
 * length), 0 when it must wait; the buffer is empty afterwards either way. */
static uint8_t flush(con_t *c, uint16_t reserve)
{
    uint8_t n = c->olen;
    c->olen = 0;
    if (n > CON_OUT_MAX) {
        c->dropped++;
        return 1;
    }
    if (c->realtime && c->io->room != NULL && c->io->room(c->io->ctx) < (uint16_t)(n + reserve)) {
        return 0;
    }
    if (n > 0u) {
        c->io->write(c->io->ctx, c->obuf, n);
    }
    return 1;
}

static void out_ch(con_t *c, char ch)
{
    out(c, &ch, 1);
}

static void out_ram(con_t *c, const char *s)
{
    size_t n = strlen(s);
    while (n > 0u) {
        uint8_t k = (n > 255u) ? 255u : (uint8_t)n;
        out(c, s, k);
        s += k;
        n -= k;
    }
}

/* Writes a flash string in small chunks (no read past its NUL). */
static void out_flash(con_t *c, const char *p)
{
    char buf[16];
    uint8_t n = 0;
    char ch;
    while ((ch = fl_char(c, p++)) != '\0') {
        buf[n++] = ch;
        if (n == sizeof(buf)) {
            out(c, buf, n);
            n = 0;
        }
    }
    out(c, buf, n);
}

static uint8_t needs_quotes(const con_t *c, const char *s, uint8_t flash)
{
    char ch = flash ? fl_char(c, s) : *s;
    if (ch == '\0') {
        return 1;
    }
    while (ch != '\0') {
        if (ch == ' ' || ch == '>' || ch == '=') {
            return 1;
        }
        s++;
        ch = flash ? fl_char(c, s) : *s;
    }
    return 0;
}

static void out_key(con_t *c, const char *key)
{
    out_ch(c, ' ');
    out_flash(c, key);
    out_ch(c, '=');
}

int8_t con_format_fixed(char *buf, uint8_t cap, int32_t v, uint8_t decimals)
{
    uint32_t pw[10];
    uint32_t m, p;
    uint8_t n = 1, nd, i, len, k = 0;
    if (decimals > 9u) {
        decimals = 9u;
    }
    m = (v < 0) ? (uint32_t)0 - (uint32_t)v : (uint32_t)v;
    /* the powers of ten up to m's leading digit only (a report is mostly
     * short numbers), then the digits by subtraction: no divide on the AVR */
    pw[0] = 1u;
    while (n < 10u) {
        p = pw[n - 1u] * 10u; /* at most 10^9: no overflow */
        if (p > m) {
            break;
        }
        pw[n++] = p;
    }
    nd = n > decimals ? n : (uint8_t)(decimals + 1u);
    len = (uint8_t)(nd + (v < 0 ? 1u : 0u) + (decimals ? 1u : 0u));
    if (cap <= len) {
        if (cap > 0u) {
            buf[0] = '\0';
        }
        return -1;
    }
    if (v < 0) {
        buf[k++] = '-';
    }
    for (i = nd; i-- > 0u;) {
        char d = '0';
        if (i < n) {
            while (m >= pw[i]) {
                m -= pw[i];
                d++;
            }
        }
        if (decimals != 0u && i == (uint8_t)(decimals - 1u)) {
            buf[k++] = '.';
        }
        buf[k++] = d;
    }
    buf[k] = '\0';
    return (int8_t)k;
}

static void out_fixed(con_t *c, int32_t v, uint8_t decimals)
{
    char buf[13];
    int8_t n = con_format_fixed(buf, sizeof(buf), v, decimals);
    out(c, buf, (uint8_t)n);
}

/* The one place a final reply is written; in realtime mode without room it
 * is held (ST_HELD) and written by a later con_poll(). */
static void reply(con_t *c, int8_t rc)
{
    const char *text = con_err_text;
    uint8_t i, code;
    c->olen = 0;
    if (rc >= 0) {
        out_flash(c, s_ok);
        if (!flush(c, 0)) {
            c->held_rc = rc;
            c->state = ST_HELD;
        }
        return;
    }
    for (i = 0;; i++) {
        if (i == sizeof(con_err_codes)) {
            rc = CON_E_INTERNAL; /* not a declared code: say so, once */
            i = 0;
            text = con_err_text;
        }
        c->copy(&code, &con_err_codes[i], 1);
        if (code == (uint8_t)-rc) {
            break;
        }
        text = fl_skip(c, text, 1);
    }
    out_flash(c, s_error);
    out_fixed(c, -(int32_t)rc, 0);
    out_ch(c, ' ');
    out_flash(c, text);
    out_flash(c, s_crlf);
    if (!flush(c, 0)) {
        c->held_rc = rc;
        c->state = ST_HELD;
    }
}

/* ---- reports ----------------------------------------------------- */

uint8_t con_report_fits(const con_t *con)
{
    return (uint8_t)(!con->realtime || con->io->room == NULL ||
                     con->io->room(con->io->ctx) >= CON_OUT_MAX + CON_RESERVE);
}

void con_report_begin(con_t *con, const char *kind)
{
    con->olen = 0;
    con->mute = 0;
    if (con->realtime && con->io->room != NULL &&
        con->io->room(con->io->ctx) <
            (con->state == ST_CALL ? CON_OUT_MAX + CON_RESERVE : CON_MIN_ROOM)) {
        con->mute = 1; /* dropped: assembling it would only cost time */
        return;
    }
    out_ch(con, '<');
    out_flash(con, kind);
}

void con_report_int(con_t *con, const char *key, int32_t v)
{
    if (con->mute) {
        return;
    }
    out_key(con, key);
    out_fixed(con, v, 0);
}

void con_report_fixed(con_t *con, const char *key, int32_t v, uint8_t decimals)
{
    if (con->mute) {
        return;
    }
    out_key(con, key);
    out_fixed(con, v, decimals);
}

void con_report_str(con_t *con, const char *key, const char *s)
{
    uint8_t q;
    if (con->mute) {
        return;
    }
    q = needs_quotes(con, s, 0);
    out_key(con, key);
    if (q) {
        out_ch(con, '"');
    }
    out_ram(con, s);
    if (q) {
        out_ch(con, '"');
    }
}

void con_report_flash(con_t *con, const char *key, const char *s)
{
    uint8_t q;
    if (con->mute) {
        return;
    }
    q = needs_quotes(con, s, 1);
    out_key(con, key);
    if (q) {
        out_ch(con, '"');
    }
    out_flash(con, s);
    if (q) {
        out_ch(con, '"');
    }
}

void con_report_end(con_t *con)
{
    if (con->mute) {
        con->mute = 0;
        con->dropped++;
        return;
    }
    out_flash(con, s_rep_end);
    if (!flush(con, con->state == ST_CALL ? CON_RESERVE : 0u)) {
        con->dropped++;
    }
}

/* ---- numbers ----------------------------------------------------- */

int8_t con_parse_fixed(const char *text, uint8_t len, uint8_t decimals, int32_t *v)
{
    uint32_t m = 0;
    uint8_t i = 0, neg = 0, ndig = 0, nfrac = 0, point = 0;
    if (len > 0u && (text[0] == '-' || text[0] == '+')) {
        neg = (text[0] == '-');
        i = 1;
    }
    for (; i < len; i++) {
        char ch = text[i];
        if (ch == '.' && !point) {
            point = 1;
            continue;
        }
        if (ch < '0' || ch > '9') {
            return CON_E_BAD_NUMBER;
        }
        if (point && ++nfrac > decimals) {
            return CON_E_BAD_NUMBER; /* more precision than the unit holds */
        }
        if (m > CON_MAG_MAX / 10u || (m == CON_MAG_MAX / 10u && ch > '7')) {
            return CON_E_BAD_NUMBER; /* above 2147483647 */
        }
        m = m * 10u + (uint32_t)(ch - '0');
        ndig++;
    }
    if (ndig == 0u) {
        return CON_E_BAD_NUMBER;
    }
    for (; nfrac < decimals; nfrac++) {
        if (m > CON_MAG_MAX / 10u) {
            return CON_E_BAD_NUMBER;
        }
        m *= 10u;
    }
    *v = neg ? -(int32_t)m : (int32_t)m;
    return 0;
}

/* ---- commands ---------------------------------------------------- */

int8_t con_cmd_name(const con_t *con, uint8_t cmd, char *buf, uint8_t cap)
{
    const char *p;
    uint8_t n = 0;
    char ch;
    if (cmd >= CON_CMD_COUNT || cap == 0u) {
        return CON_E_INTERNAL;
    }
    p = fl_skip(con, con_cmd_text, (uint16_t)(3u * cmd));
    while ((ch = fl_char(con, p++)) != '\0') {
        if (n + 1u < cap) {
            buf[n] = ch;
        }
        n++;
    }
    buf[(n < cap) ? n : (uint8_t)(cap - 1u)] = '\0';
    return (int8_t)n;
}

static int8_t find_cmd(const con_t *c, const char *tok)
{
    const char *p = con_cmd_text;
    uint8_t i, j;
    for (i = 0; i < CON_CMD_COUNT; i++) {
        for (j = 0;; j++) {
            char ch = fl_char(c, p + j);
            if (ch != tok[j]) {
                break;
            }
            if (ch == '\0') {
                return (int8_t)i;
            }
        }
        p = fl_skip(c, p, 3);
    }
    return CON_E_UNKNOWN_COMMAND;
}

/* Copies the synopsis of cmd into syn (CON_SYN_MAX, truncated). */
/* The synopsis at p (flash) into syn. */
static void get_synopsis_at(const con_t *c, const char *p, char *syn)
{
    uint8_t n = 0;
    char ch;
    while ((ch = fl_char(c, p++)) != '\0' && n + 1u < CON_SYN_MAX) {
        syn[n++] = ch;
    }
    syn[n] = '\0';
}

static void get_synopsis(const con_t *c, uint8_t cmd, char *syn)
{
    get_synopsis_at(c, fl_skip(c, con_cmd_text, (uint16_t)(3u * cmd + 1u)), syn);
}

/* One argument spec of a synopsis, split in place. */
typedef struct {
    char open;          /* '<' required, '[' optional */
    char type;          /* i, d, w, s */
    const char *name;   /* NUL-terminated */
    const char *params; /* NUL-terminated, "" when none */
} con_spec_t;

/* Splits the spec starting at *q (spaces skipped) and advances *q past it.
 * Returns 0, or 1 at the end of the synopsis. */
static uint8_t next_spec(char **q, con_spec_t *sp)
{
    char *p = *q, *colon;
    while (*p == ' ') {
        p++;
    }
    if (*p == '\0') {
        return 1;
    }
    sp->open = *p++;
    sp->name = p;
    while (*p != '\0' && *p != '>' && *p != ']') {
        p++;
    }
    if (*p != '\0') {
        *p++ = '\0';
    }
    *q = p;
    colon = strchr(sp->name, ':');
    sp->type = 's';
    sp->params = sp->name + strlen(sp->name); /* "" */
    if (colon != NULL) {
        *colon = '\0';
        sp->type = colon[1];
        if (colon[1] != '\0' && colon[2] == ':') {
            sp->params = colon + 3;
        }
    }
    return 0;
}

static int8_t check_number(const char *tok, const con_spec_t *sp, int32_t *v)
{
    uint8_t dec = (sp->type == 'd') ? 3u : 0u;
    int32_t lo = -(int32_t)CON_MAG_MAX, hi = (int32_t)CON_MAG_MAX;
    const char *sep = strchr(sp->params, ':');
    if (con_parse_fixed(tok, (uint8_t)strlen(tok), dec, v) < 0) {
        return CON_E_BAD_NUMBER;
    }
    if (sep != NULL) {
        (void)con_parse_fixed(sp->params, (uint8_t)(sep - sp->params), dec, &lo);
        (void)con_parse_fixed(sep + 1, (uint8_t)strlen(sep + 1), dec, &hi);
    }
    return (*v < lo || *v > hi) ? CON_E_OUT_OF_RANGE : 0;
}

static int8_t check_word(const char *tok, const char *choices, int32_t *v)
{
    size_t n = strlen(tok);
    int32_t idx = 0;
    const char *p = choices;
    for (;;) {
        const char *end = strchr(p, '|');
        size_t len = (end != NULL) ? (size_t)(end - p) : strlen(p);
        if (len == n && memcmp(p, tok, n) == 0) {
            *v = idx;
            return 0;
        }
        if (end == NULL) {
            return CON_E_BAD_WORD;
        }
        p = end + 1;
        idx++;
    }
}

/* Checks every argument against the synopsis and fills c->args; the first
 * failure decides the error. */
CON_NOINLINE static int8_t check_args(con_t *c, uint8_t cmd, char **tok, uint8_t ntok)
{
    char syn[CON_SYN_MAX];
    char *q = syn;
    con_spec_t sp;
    uint8_t a;
    int8_t rc;
    get_synopsis(c, cmd, syn);
    memset(&c->args, 0, sizeof(c->args));
    for (a = 0; a < CON_MAX_ARGS && next_spec(&q, &sp) == 0; a++) {
        if (a >= ntok) {
            if (sp.open == '<') {
                return CON_E_MISSING_ARG;
            }
            continue;
        }
        rc = 0;
        if (sp.type == 'i' || sp.type == 'd') {
            rc = check_number(tok[a], &sp, &c->args.v[a]);
        } else if (sp.type == 'w') {
            rc = check_word(tok[a], sp.params, &c->args.v[a]);
        }
        if (rc < 0) {
            return rc;
        }
        c->args.s[a] = tok[a];
        c->args.given = (uint8_t)(c->args.given | (1u << a));
    }
    return (ntok > a) ? CON_E_TOO_MANY_ARGS : 0;
}

/* ---- help -------------------------------------------------------- */

/* Writes `<help cmd=NAME args="..." text="...">` for command i, the args
 * shown as names (choices for words) in their brackets. Returns 0 when it
 * must wait for room (realtime mode). */
/* No line is read while the help listing is written: line[] keeps the flash
 * address of the next command's text, so each help line starts there instead
 * of skipping every earlier command's text again (which took 14 ms for the
 * last line on the AVR, one flash byte at a time). */
static const char *help_pos(const con_t *c)
{
    const char *p;
    memcpy(&p, c->line, sizeof p);
    return p;
}

static void help_set(con_t *c, const char *p)
{
    memcpy(c->line, &p, sizeof p);
}

static uint8_t help_line(con_t *c)
{
    char syn[CON_SYN_MAX];
    char *q = syn;
    con_spec_t sp;
    uint8_t first = 1;
    const char *p = help_pos(c);
    const char *syn_f = fl_skip(c, p, 1);
    c->olen = 0;
    out_flash(c, s_help_cmd);
    out_flash(c, p);
    out_flash(c, s_help_args);
    get_synopsis_at(c, syn_f, syn);
    while (next_spec(&q, &sp) == 0) {
        if (!first) {
            out_ch(c, ' ');
        }
        first = 0;
        out(c, &sp.open, 1);
        out_ram(c, sp.type == 'w' ? sp.params : sp.name);
        out_ch(c, sp.open == '<' ? '>' : ']');
    }
    p = fl_skip(c, syn_f, 1);
    out_flash(c, s_help_text);
    out_flash(c, p);
    out_flash(c, s_help_end);
    if (!flush(c, CON_RESERVE)) {
        return 0;
    }
    help_set(c, fl_skip(c, p, 1));
    return 1;
}

/* ---- line handling ----------------------------------------------- */

/* A handler's result: the final reply now, or the command pending. */
CON_NOINLINE static void end_call(con_t *c, int8_t rc)
{
    if (rc > 0) {
        c->state = ST_PENDING;
        c->t_pending = c->now;
        return;
    }
    c->state = ST_READ;
    reply(c, rc);
}

static void execute(con_t *c)
{
    char *tok[CON_MAX_ARGS + 2];
    char *p = c->line;
    uint8_t ntok = 0, j;
    int8_t cmd, rc;
    con_handler_fn h;
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
        reply(c, 0); /* empty line: `ok`, so a host can synchronise */
        return;
    }
    for (j = 0; tok[0][j] != '\0'; j++) {
        if (tok[0][j] >= 'A' && tok[0][j] <= 'Z') {
            tok[0][j] = (char)(tok[0][j] - 'A' + 'a');
        }
    }
    cmd = find_cmd(c, tok[0]);
    if (cmd < 0) {
        reply(c, cmd);
        return;
    }
    rc = check_args(c, (uint8_t)cmd, tok + 1, (uint8_t)(ntok - 1u));
    if (rc < 0) {
        reply(c, rc);
        return;
    }
    if (cmd == CON_CMD_HELP) {
        c->state = ST_HELP;
        c->help_i = 0;
        help_set(c, con_cmd_text);
        return;
    }
    if (c->handlers == NULL) {
        c->state = ST_CALL; /* the application runs it: con_call() */
        c->call = (uint8_t)cmd;
        return;
    }
    c->copy(&h, &c->handlers[cmd], sizeof(h));
    if (h == NULL) {
        reply(c, CON_E_NOT_AVAILABLE);
        return;
    }
    c->state = ST_CALL;
    end_call(c, h(c, &c->args, c->app));
}

static void end_line(con_t *c)
{
    uint8_t fl = c->flags;
    c->line[c->len] = '\0';
    c->len = 0;
    c->flags = (uint8_t)(c->flags & F_CR);
    if (fl & F_OVER) {
        reply(c, CON_E_LINE_TOO_LONG);
    } else if (fl & F_BAD) {
        reply(c, CON_E_BAD_CHAR);
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
    con->io = io;
    con->handlers = handlers;
    con->app = app;
    con->copy = copy;
    con->rt = rt;
    con->state = ST_READ;
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
    if (con->state == ST_PENDING) {
        if (con->pending_ms == 0u || (uint16_t)(now_ms - con->t_pending) < con->pending_ms) {
            return 1;
        }
        /* the application lost the command: the line still gets its reply */
        con->state = ST_READ;
        reply(con, CON_E_TIMEOUT);
        return 0;
    }
    if (con->state == ST_CALL) {
        return 1;
    }
    if (con->state == ST_HELD) {
        con->state = ST_READ;
        reply(con, con->held_rc);
        return con->state == ST_READ ? 0 : 1;
    }
    if (con->state == ST_HELP) {
        if (con->help_i < CON_CMD_COUNT) {
            /* realtime: a line is assembled only when the longest fits, so
             * a full ring costs no work per pass */
            if (!con->realtime || con->io->room == NULL ||
                con->io->room(con->io->ctx) >= CON_OUT_MAX + CON_RESERVE) {
                con->help_i = (uint8_t)(con->help_i + help_line(con));
            }
            return 1;
        }
        con->state = ST_READ;
        reply(con, 0);
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
        int16_t b = con->io->read(con->io->ctx);
        if (b < 0) {
            break;
        }
        if (take_byte(con, (uint8_t)b)) {
            con->t_line = now_ms;
            break;
        }
    }
    return (con->state == ST_READ) ? 0 : 1;
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
    if (con->state != ST_PENDING || rc > 0) {
        return CON_E_NOT_PENDING;
    }
    con->state = ST_READ;
    reply(con, rc);
    return 0;
}

uint8_t con_pending(const con_t *con)
{
    return con->state == ST_PENDING;
}

int8_t con_call(const con_t *con)
{
    return (con->state == ST_CALL && con->handlers == NULL) ? (int8_t)con->call : -1;
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
