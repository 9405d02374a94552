/*
 * The console's output: lines assembled and written (realtime mode: whole or
 * not at all), the final reply of every line, the report lines and the
 * fixed-point numbers they print. con_priv.h lists the console's files.
 */
#include <string.h>

#include "console/con_priv.h"

/* The codes of con_errors.def run 1, 2, 3, ... in its order, so a code's
 * text is the code's place there: checked here at compile time. */
enum {
#define CON_ERR(code, id, text) CON_ERR_AT_##id,
#include "console/con_errors.def"
#undef CON_ERR
    CON_ERR_COUNT
};
#define CON_ERR(code, id, text)                                                                    \
    typedef char con_err_in_order_##id[(code) == CON_ERR_AT_##id + 1 ? 1 : -1];
#include "console/con_errors.def"
#undef CON_ERR

/* console.h */
const char con_err_text[] CON_FLASH =
#define CON_ERR(code, id, text) text "\0"
#include "console/con_errors.def"
#undef CON_ERR
    ;

/* Fixed output text, kept in flash (a string literal would cost AVR RAM). */
static const char s_ok[] CON_FLASH = "ok\r\n";
static const char s_error[] CON_FLASH = "error:";
static const char s_crlf[] CON_FLASH = "\r\n";
static const char s_rep_end[] CON_FLASH = ">\r\n";

/* ---- flash access ------------------------------------------------ */

/* One byte of a flash string (CON_FLASH_BYTE; con_parse.c has the same
 * function: con_priv.h says why). */
static char con_fl_char(const con_t *c, const char *p)
{
    (void)c;
    return CON_FLASH_BYTE(p);
}

/* Pointer past the next n NUL-terminated strings at p. */
const char *con_fl_skip(const con_t *c, const char *p, uint16_t n)
{
    while (n > 0u) {
        if (con_fl_char(c, p++) == '\0') {
            n--;
        }
    }
    return p;
}

/* ---- output ------------------------------------------------------ */

/* A line that found no room in the output ring while it was assembled
 * (con_t.olen); CON_OUT_MAX + 1: one too long. */
#define OUT_NO_ROOM (CON_OUT_MAX + 2u)

/* In realtime mode output is assembled a line at a time (see
 * con_set_realtime()), in obuf or, with CON_IO_FIXED, in the output ring
 * behind the bytes queued (con_io_stage()); otherwise it is written at once.
 * In the ring, a part that does not fit the room there now drops the line,
 * which in obuf would be dropped at its end unless the room grew meanwhile. */
void con_out(con_t *c, const char *s, uint8_t n)
{
    if (!c->realtime) {
        if (n > 0u) {
            CON_IO_WRITE(c, s, n); /* may wait: nothing moves */
        }
        return;
    }
    if (c->olen > CON_OUT_MAX) {
        return; /* too long or no room: never written in part */
    }
    if ((uint16_t)c->olen + n > CON_OUT_MAX) {
        c->olen = CON_OUT_MAX + 1u;
        return;
    }
#if CON_IO_FIXED
    if (con_io_room() < (uint16_t)c->olen + n) {
        c->olen = OUT_NO_ROOM;
        return;
    }
    con_io_stage(c->olen, s, n);
#else
    memcpy(&c->obuf[c->olen], s, n);
#endif
    c->olen = (uint8_t)(c->olen + n);
}

/* Writes the assembled line when it may be written now, keeping `reserve`
 * bytes of room free in realtime mode. Returns 1 when written (or dropped for
 * length), 0 when it must wait; the line is gone afterwards either way. */
uint8_t con_flush(con_t *c, uint16_t reserve)
{
    uint8_t n = c->olen;
    c->olen = 0;
    if (n == CON_OUT_MAX + 1u) {
        c->dropped++;
        return 1;
    }
    if (n == OUT_NO_ROOM ||
        (c->realtime && CON_HAS_ROOM(c) && CON_IO_ROOM(c) < (uint16_t)(n + reserve))) {
        return 0;
    }
    if (n > 0u) {
#if CON_IO_FIXED
        con_io_commit(n);
#else
        CON_IO_WRITE(c, c->obuf, n);
#endif
    }
    return 1;
}

void con_out_ch(con_t *c, char ch)
{
    con_out(c, &ch, 1);
}

/* Writes a RAM (flash 0) or flash (flash 1) string in small chunks (no read
 * past its NUL): one routine for both. */
static void out_str(con_t *c, const char *p, uint8_t flash)
{
    char buf[16];
    uint8_t n = 0;
    char ch;
    while ((ch = flash ? con_fl_char(c, p) : *p) != '\0') {
        p++;
        buf[n++] = ch;
        if (n == sizeof(buf)) {
            con_out(c, buf, n);
            n = 0;
        }
    }
    con_out(c, buf, n);
}

void con_out_ram(con_t *c, const char *s)
{
    out_str(c, s, 0);
}

void con_out_flash(con_t *c, const char *p)
{
    out_str(c, p, 1);
}

static uint8_t needs_quotes(const con_t *c, const char *s, uint8_t flash)
{
    char ch = flash ? con_fl_char(c, s) : *s;
    if (ch == '\0') {
        return 1;
    }
    while (ch != '\0') {
        if (ch == ' ' || ch == '>' || ch == '=') {
            return 1;
        }
        s++;
        ch = flash ? con_fl_char(c, s) : *s;
    }
    return 0;
}

static void out_key(con_t *c, const char *key)
{
    con_out_ch(c, ' ');
    con_out_flash(c, key);
    con_out_ch(c, '=');
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
    con_out(c, buf, (uint8_t)n);
}

/* The one place a final reply is written; in realtime mode without room it
 * is held (CON_ST_HELD) and written by a later con_poll(). */
void con_reply(con_t *c, int8_t rc)
{
    c->olen = 0;
    if (rc >= 0) {
        con_out_flash(c, s_ok);
        if (!con_flush(c, 0)) {
            c->held_rc = rc;
            c->state = CON_ST_HELD;
        }
        return;
    }
    if (rc < -CON_ERR_COUNT) {
        rc = CON_E_INTERNAL; /* not a declared code: say so, once */
    }
    con_out_flash(c, s_error);
    out_fixed(c, -(int32_t)rc, 0);
    con_out_ch(c, ' ');
    con_out_flash(c, con_fl_skip(c, con_err_text, (uint16_t)(-rc - 1)));
    con_out_flash(c, s_crlf);
    if (!con_flush(c, 0)) {
        c->held_rc = rc;
        c->state = CON_ST_HELD;
    }
}

/* ---- reports ----------------------------------------------------- */

/* 1 when the output ring has room for n bytes (always, without a room
 * function: writes then never wait). */
CON_NOINLINE static uint8_t has_room(const con_t *con, uint16_t n)
{
    return (uint8_t)(!CON_HAS_ROOM(con) || CON_IO_ROOM(con) >= n);
}

CON_NOINLINE uint8_t con_report_fits(const con_t *con)
{
    return (uint8_t)(!con->realtime || has_room(con, CON_OUT_MAX + CON_RESERVE));
}

uint8_t con_out_drained(const con_t *con)
{
    return has_room(con, CON_OUT_MAX + CON_RESERVE);
}

CON_NOINLINE uint8_t con_line_fits(const con_t *con)
{
    return has_room(con, CON_OUT_MAX + (con->realtime ? CON_RESERVE : 0u));
}

void con_report_begin(con_t *con, const char *kind)
{
    con->olen = 0;
    con->mute = 0;
    if (con->realtime && CON_HAS_ROOM(con) &&
        CON_IO_ROOM(con) < (con->state == CON_ST_CALL ? CON_OUT_MAX + CON_RESERVE : CON_MIN_ROOM)) {
        con->mute = 1; /* dropped: assembling it would only cost time */
        return;
    }
    con_out_ch(con, '<');
    con_out_flash(con, kind);
}

CON_NOINLINE void con_report_int(con_t *con, const char *key, int32_t v)
{
    con_report_fixed(con, key, v, 0);
}

void con_report_fixed(con_t *con, const char *key, int32_t v, uint8_t decimals)
{
    if (con->mute) {
        return;
    }
    out_key(con, key);
    out_fixed(con, v, decimals);
}

/* con_report_str() (flash 0) and con_report_flash() (flash 1) */
CON_NOINLINE static void report_text(con_t *con, const char *key, const char *s, uint8_t flash)
{
    uint8_t q;
    if (con->mute) {
        return;
    }
    q = needs_quotes(con, s, flash);
    out_key(con, key);
    if (q) {
        con_out_ch(con, '"');
    }
    out_str(con, s, flash);
    if (q) {
        con_out_ch(con, '"');
    }
}

void con_report_str(con_t *con, const char *key, const char *s)
{
    report_text(con, key, s, 0);
}

void con_report_flash(con_t *con, const char *key, const char *s)
{
    report_text(con, key, s, 1);
}

void con_report_list(con_t *con, const char *key, uint8_t n)
{
    if (con->mute) {
        return;
    }
    out_key(con, key);
    if (n == 0u) {
        con_out_ch(con, '"'); /* "", as con_report_str() writes an empty text */
        con_out_ch(con, '"');
    }
}

void con_report_item(con_t *con, int32_t v, char mark, uint8_t first)
{
    if (con->mute) {
        return;
    }
    if (!first) {
        con_out_ch(con, ',');
    }
    out_fixed(con, v, 0);
    if (mark != '\0') {
        con_out_ch(con, mark);
    }
}

void con_report_word(con_t *con, const char *key, const char *words, uint8_t i)
{
    /* read here a byte at a time with LPM: through the copy function (a call
     * per byte) the fault word of a `status` took 1 ms */
    char buf[16], ch;
    uint8_t n = 0;
    if (con->mute) {
        return;
    }
    for (;; words++) {
        ch = con_fl_char(con, words);
        if (ch == '\0' || ch == ' ') {
            if (i == 0u || ch == '\0') {
                break;
            }
            i--;
        } else if (i == 0u && n < sizeof buf - 1u) {
            buf[n++] = ch;
        }
    }
    if (i != 0u || n == 0u) {
        buf[n++] = '?';
    }
    buf[n] = '\0';
    con_report_str(con, key, buf);
}

void con_report_end(con_t *con)
{
    if (con->mute) {
        con->mute = 0;
        con->dropped++;
        return;
    }
    con_out_flash(con, s_rep_end);
    if (!con_flush(con, con->state == CON_ST_CALL ? CON_RESERVE : 0u)) {
        con->dropped++;
    }
}
