/*
 * The console's command table (con_commands.def): command lookup, argument
 * checks against the synopses, number parsing, command names and the help
 * listing. con_priv.h lists the console's files.
 */
#include <stddef.h>
#include <string.h>

#include "console/con_priv.h"

#define CON_SYN_MAX 64u /* longest synopsis (checked by the unit tests) */
#define CON_MAG_MAX 2147483647UL

/* One byte of a flash string (CON_FLASH_BYTE; con_out.c has the same
 * function: con_priv.h says why). */
static char con_fl_char(const con_t *c, const char *p)
{
    (void)c;
    return CON_FLASH_BYTE(p);
}

/* name, synopsis and help of every command, NUL-separated, in enum order:
 * one flash string instead of 3 * N pointers (console.h). */
const char con_cmd_text[] CON_FLASH =
#define CON_CMD(id, name, synopsis, help) name "\0" synopsis "\0" help "\0"
#include "console/con_commands.def"
#undef CON_CMD
    ;

/* Where each command's name starts in con_cmd_text: the lookup of a line's
 * command and its synopsis read only what they need. Skipping every earlier
 * command's help text, a byte at a time, cost about 1 ms of each command
 * line on the AVR (an unknown command 1.15 ms, `get cal_tension` 2.4 ms). */
static const uint16_t con_cmd_at[CON_CMD_COUNT] CON_FLASH = {
#define CON_CMD(id, name, synopsis, help) (uint16_t) offsetof(con_cmd_layout_t, n_##id),
#include "console/con_commands.def"
#undef CON_CMD
};

/* Command cmd's entry (its name; the synopsis and help follow). */
static const char *cmd_entry(uint8_t cmd)
{
    return con_cmd_text + CON_FLASH_U16(&con_cmd_at[cmd]);
}

static const char s_help_cmd[] CON_FLASH = "<help cmd=";
static const char s_help_args[] CON_FLASH = " args=\"";
static const char s_help_text[] CON_FLASH = "\" text=\"";
static const char s_help_end[] CON_FLASH = "\">\r\n";

/* ---- numbers ----------------------------------------------------- */

int8_t con_parse_fixed(const char *text, uint8_t len, uint8_t decimals, int32_t *v)
{
    uint32_t m = 0;
    uint8_t i = 0, neg = 0, ndig = 0, nfrac = 0, point = 0;
    char ch;
    if (len > 0u && (text[0] == '-' || text[0] == '+')) {
        neg = (text[0] == '-');
        i = 1;
    }
    /* the digits of text, then '0's for the fractional digits it left out:
     * one path appends every digit and checks it against 2147483647 */
    for (;;) {
        if (i < len) {
            ch = text[i++];
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
            ndig++;
        } else if (ndig == 0u) {
            return CON_E_BAD_NUMBER;
        } else if (nfrac < decimals) {
            ch = '0';
            nfrac++;
        } else {
            break;
        }
        if (m > CON_MAG_MAX / 10u || (m == CON_MAG_MAX / 10u && ch > '7')) {
            return CON_E_BAD_NUMBER; /* above 2147483647 */
        }
        m = m * 10u + (uint32_t)(ch - '0');
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
    p = cmd_entry(cmd);
    while ((ch = con_fl_char(con, p++)) != '\0') {
        if (n + 1u < cap) {
            buf[n] = ch;
        }
        n++;
    }
    buf[(n < cap) ? n : (uint8_t)(cap - 1u)] = '\0';
    return (int8_t)n;
}

int8_t con_find_cmd(const con_t *c, const char *tok)
{
    uint8_t i, j;
    for (i = 0; i < CON_CMD_COUNT; i++) {
        const char *p = cmd_entry(i);
        for (j = 0;; j++) {
            char ch = con_fl_char(c, p + j);
            if (ch != tok[j]) {
                break;
            }
            if (ch == '\0') {
                return (int8_t)i;
            }
        }
    }
    return CON_E_UNKNOWN_COMMAND;
}

/* Copies the synopsis of cmd into syn (CON_SYN_MAX, truncated). */
/* The synopsis at p (flash) into syn. */
static void get_synopsis_at(const con_t *c, const char *p, char *syn)
{
    uint8_t n = 0;
    char ch;
    while ((ch = con_fl_char(c, p++)) != '\0' && n + 1u < CON_SYN_MAX) {
        syn[n++] = ch;
    }
    syn[n] = '\0';
}

static void get_synopsis(const con_t *c, uint8_t cmd, char *syn)
{
    get_synopsis_at(c, con_fl_skip(c, cmd_entry(cmd), 1), syn);
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
    uint8_t idx = 0; /* a synopsis lists a few choices */
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

/* con_check_args() on the synopsis syn (its caller's frame holds it: the
 * AVR reaches the first 64 bytes of a frame with one instruction a byte,
 * and the compiler put the spec and the spills behind it). */
CON_NOINLINE static int8_t check_args(con_t *c, char *syn, char **tok, uint8_t ntok)
{
    struct {
        char *q;
        con_spec_t sp;
    } l;
    uint8_t a;
    int8_t rc;
    l.q = syn;
    memset(&c->args, 0, sizeof(c->args));
    for (a = 0; a < CON_MAX_ARGS && next_spec(&l.q, &l.sp) == 0; a++) {
        if (a >= ntok) {
            if (l.sp.open == '<') {
                return CON_E_MISSING_ARG;
            }
            continue;
        }
        rc = 0;
        if (l.sp.type == 'i' || l.sp.type == 'd') {
            rc = check_number(tok[a], &l.sp, &c->args.v[a]);
        } else if (l.sp.type == 'w') {
            rc = check_word(tok[a], l.sp.params, &c->args.v[a]);
        }
        if (rc < 0) {
            return rc;
        }
        c->args.s[a] = tok[a];
        c->args.given = (uint8_t)(c->args.given | (1u << a));
    }
    return (ntok > a) ? CON_E_TOO_MANY_ARGS : 0;
}

/* Checks every argument against the synopsis and fills c->args; the first
 * failure decides the error. */
int8_t con_check_args(con_t *c, uint8_t cmd, char **tok, uint8_t ntok)
{
    char syn[CON_SYN_MAX];
    get_synopsis(c, cmd, syn);
    return check_args(c, syn, tok, ntok);
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

void con_help_start(con_t *c)
{
    c->state = CON_ST_HELP;
    c->help_i = 0;
    help_set(c, con_cmd_text);
}

uint8_t con_help_line(con_t *c)
{
    /* one local, the synopsis last: the AVR reaches the first 64 bytes of
     * a frame with one instruction a byte */
    struct {
        char *q;
        con_spec_t sp;
        char syn[CON_SYN_MAX];
    } l;
    uint8_t first = 1;
    const char *p = help_pos(c);
    const char *syn_f = con_fl_skip(c, p, 1);
    c->olen = 0;
    con_out_flash(c, s_help_cmd);
    con_out_flash(c, p);
    con_out_flash(c, s_help_args);
    get_synopsis_at(c, syn_f, l.syn);
    l.q = l.syn;
    while (next_spec(&l.q, &l.sp) == 0) {
        if (!first) {
            con_out_ch(c, ' ');
        }
        first = 0;
        con_out(c, &l.sp.open, 1);
        con_out_ram(c, l.sp.type == 'w' ? l.sp.params : l.sp.name);
        con_out_ch(c, l.sp.open == '<' ? '>' : ']');
    }
    p = con_fl_skip(c, syn_f, 1);
    con_out_flash(c, s_help_text);
    con_out_flash(c, p);
    con_out_flash(c, s_help_end);
    if (!con_flush(c, CON_RESERVE)) {
        return 0;
    }
    help_set(c, con_fl_skip(c, p, 1));
    return 1;
}
