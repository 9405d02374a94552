/*
 * console: hallhome's line console (UART0, 115200 8N1), protocol side only.
 *
 * The protocol (docs/console.md is the reference):
 *   - a command is one line of printable ASCII ended by CR, LF or CRLF (one
 *     terminator); every line gets exactly one final reply, `ok` or
 *     `error:<code> <text>` (codes in con_errors.def);
 *   - an empty line (or only spaces) gets `ok`, so a host can synchronise;
 *   - the whole line is read, tokenised and checked against the command's
 *     synopsis (con_commands.def) before its handler runs: an unknown
 *     command, bad number, out-of-range value, missing or extra argument,
 *     a line longer than CON_LINE_MAX (discarded up to its end, one error) or
 *     a line with a control or non-ASCII byte (NUL included) gets its error
 *     and changes nothing;
 *   - backspace (0x08) and DEL (0x7F) erase the previous character, TAB is a
 *     space;
 *   - asynchronous reports are whole lines `<kind key=value ...>`; a value
 *     with spaces is double-quoted;
 *   - `!` is a realtime stop: it is taken out of the byte stream wherever it
 *     appears (mid-line too; the rest of the line still counts) and only
 *     raises a flag. The UART RX interrupt calls con_rt_byte() for every byte
 *     so the stop is seen on receipt even while the console is not reading.
 *
 * What this module does not do: any behaviour. The application supplies one
 * handler per command (a table indexed by con_cmd_t) and performs the
 * command; the module depends on no other hallhome module. An application
 * may instead run the commands itself (no table: con_init() with handlers
 * NULL): a validated line then waits in con_call() until the application
 * hands its handler's result to con_called(), with the same contract.
 *
 * Handlers and the one-reply guarantee. A handler returns
 *   0            done: the console replies `ok`;
 *   CON_E_*      failed: the console replies `error:<code> <text>`;
 *   CON_PENDING  accepted but not finished (e.g. needs bus time): no reply
 *                yet; the console reads no further input until the
 *                application calls con_complete() once with the result, or
 *                until the pending deadline (con_set_timeout(), default
 *                CON_PENDING_MS) passes: then the console itself replies
 *                `error:21 timed out` and a late con_complete() is refused
 *                with CON_E_NOT_PENDING, so the line still gets one reply.
 * A handler may emit reports (con_report_*) before it returns or while
 * pending; it never writes `ok`/`error` itself. Commands that start long
 * work (cal) reply `ok` when accepted and report progress and results later.
 * The built-in `help` is emitted one line per con_poll() call, then `ok`.
 *
 * Flash strings: the declarations (command names, synopses, help, error
 * texts) and every `kind` and `key` argument of the report functions are
 * read through the copy function given to con_init() (memcpy on the host,
 * memcpy_P on the AVR, where CON_FLASH places the declarations in program
 * memory and the application passes PSTR("...") keys).
 *
 * Wiring on the board (the application does this, e.g. in firmware/main.c):
 *
 *     static con_rt_t con_rt;
 *     static uint8_t con_rt_hook(uint8_t b) { return con_rt_byte(&con_rt, b); }
 *     ...
 *     uart0_set_rt_hook(con_rt_hook);
 *     con_init(&con, &io, handlers, &app, copy_P, &con_rt);  // io wraps uart0_read/_write
 *     for (;;) { con_poll(&con, tick_ms()); if (con_rt_take(&con_rt)) abort_all(); ... }
 *
 * Error convention: 0 = done, negative = CON_E_*, positive = in progress.
 */
#ifndef HALLHOME_CONSOLE_H
#define HALLHOME_CONSOLE_H

#include <stddef.h>
#include <stdint.h>

#ifndef CON_FLASH
#ifdef TBL_FLASH
#define CON_FLASH TBL_FLASH
#else
#define CON_FLASH
#endif
#endif

/* Commands, in con_commands.def order. */
typedef enum {
#define CON_CMD(id, name, synopsis, help) CON_CMD_##id,
#include "console/con_commands.def"
#undef CON_CMD
    CON_CMD_COUNT
} con_cmd_t;

/* name, synopsis and help of every command, NUL-separated, in enum order
 * (con_parse.c), and the same strings as members of a struct (of chars: no
 * padding), so that offsetof() says at compile time where each command's
 * entry starts. CON_CMD_NAME_F(id): command id's name as a flash string, for
 * a report that prints the same word (kept once). */
extern const char con_cmd_text[];
typedef struct {
#define CON_CMD(id, name, synopsis, help)                                                          \
    char n_##id[sizeof(name)];                                                                     \
    char s_##id[sizeof(synopsis)];                                                                 \
    char h_##id[sizeof(help)];
#include "console/con_commands.def"
#undef CON_CMD
} con_cmd_layout_t;
#define CON_CMD_NAME_F(id) (con_cmd_text + offsetof(con_cmd_layout_t, n_##id))
/* The last `word` (a string literal) of command id's help text. */
#define CON_CMD_HELP_TAIL_F(id, word)                                                              \
    (con_cmd_text + offsetof(con_cmd_layout_t, h_##id) + sizeof(((con_cmd_layout_t *)0)->h_##id) - \
     sizeof(word))

/* Errors: CON_E_<ID> = -code of con_errors.def; these go on the wire. */
enum {
#define CON_ERR(code, id, text) CON_E_##id = -(code),
#include "console/con_errors.def"
#undef CON_ERR
    /* API misuse, never sent: con_complete() with no command pending, or a
     * non-final result. */
    CON_E_NOT_PENDING = -100
};

/* The error texts, NUL-separated, in con_errors.def order (con_out.c), laid
 * out as con_cmd_text is. CON_ERR_TAIL_F(id, word): the last `word` (a
 * string literal) of error id's text, for a report that prints it. */
extern const char con_err_text[];
typedef struct {
#define CON_ERR(code, id, text) char t_##id[sizeof(text)];
#include "console/con_errors.def"
#undef CON_ERR
} con_err_layout_t;
#define CON_ERR_TAIL_F(id, word)                                                                   \
    (con_err_text + offsetof(con_err_layout_t, t_##id) + sizeof(((con_err_layout_t *)0)->t_##id) - \
     sizeof(word))

#define CON_PENDING    1     /* handler result: reply comes later via con_complete() */
#define CON_LINE_MAX   48    /* characters in a command line, terminator excluded */
#define CON_MAX_ARGS   3     /* arguments after the command name */
#define CON_PENDING_MS 3000u /* default deadline of a pending command */
#define CON_RT_LINE_MS 25u   /* realtime mode: at most one command line per this many ms */
#define CON_MIN_ROOM   48u   /* realtime mode: a run report starts only with this much room */
#define CON_OUT_MAX    190u  /* realtime mode: longest line, CRLF included (longer: dropped) */
#define CON_RESERVE                                                                                \
    64u /* realtime mode: room command output leaves for run reports;                              \
           CON_OUT_MAX + CON_RESERVE must fit the output ring (255) */

typedef void (*con_copy_fn)(void *dst, const void *src, size_t n);

/* Byte I/O. read() returns the next received byte (0..255) or -1 when none
 * is waiting; write() queues n bytes for transmission (it may wait for room).
 * room() (optional, NULL: unbounded) returns how many bytes write() takes
 * now without waiting: in realtime mode (con_set_realtime()) the console
 * never writes more than that, so it never waits on the line. */
typedef struct {
    void *ctx;
    int16_t (*read)(void *ctx);
    void (*write)(void *ctx, const char *buf, uint8_t n);
    uint16_t (*room)(void *ctx);
} con_io_t;

/* A firmware with one console builds with -DCON_IO_FIXED=1: the console then
 * calls the board's functions below (the con_io_t contracts without ctx;
 * room() is not optional) directly, and the io given to con_init() is
 * neither kept nor read (measured: 144 bytes less AVR code). The default, 0, takes a con_io_t per
 * console, which the native tests fill with their fakes. */
#ifndef CON_IO_FIXED
#define CON_IO_FIXED 0
#endif
#if CON_IO_FIXED
int16_t con_io_read(void);
void con_io_write(const char *buf, uint8_t n);
uint16_t con_io_room(void);
/* Realtime mode assembles a line in the output ring itself, behind the bytes
 * queued: con_io_stage() puts n bytes at offset off there (the console keeps
 * off + n within con_io_room()), con_io_commit() queues the first n of them.
 * Staged bytes that are not committed are overwritten by the next line. */
void con_io_stage(uint8_t off, const char *buf, uint8_t n);
void con_io_commit(uint8_t n);
#endif

/* Realtime stop state, shared by the RX interrupt and the main loop. The
 * interrupt only increments `count`, the main loop only writes `seen`, so no
 * locking is needed. */
typedef struct {
    volatile uint8_t count;
    uint8_t seen;
} con_rt_t;

/* Validated arguments of the current line. Argument a (0-based, in synopsis
 * order) was given when bit a of `given` is set; v[a] is its value (integer,
 * thousandths for decimals, word index for choices); s[a] points to its text
 * (NUL-terminated, inside the console's line buffer, valid until the final
 * reply). Absent arguments have v = 0, s = NULL. */
typedef struct {
    int32_t v[CON_MAX_ARGS];
    const char *s[CON_MAX_ARGS];
    uint8_t given;
} con_args_t;

struct con_s;

/* An application that runs every command itself (con_call()) builds with
 * -DCON_HANDLERS=0: the console then has no handler table, and con_init()
 * ignores its handlers, app and copy arguments (pass NULL). The firmware
 * builds so (measured: 130 bytes less AVR code, 6 bytes less RAM); the
 * default, 1, keeps the table the native tests and tools use. */
#ifndef CON_HANDLERS
#define CON_HANDLERS 1
#endif

/* Command handler: see the file comment for the result contract. */
typedef int8_t (*con_handler_fn)(struct con_s *con, const con_args_t *args, void *app);

/* Caller-owned console state (95 bytes on the AVR with CON_IO_FIXED). Treat as opaque. */
typedef struct con_s {
#if !CON_IO_FIXED
    const con_io_t *io;
#endif
#if CON_HANDLERS
    const con_handler_fn *handlers; /* CON_CMD_COUNT entries, read via copy; NULL entry:
                                       error:NOT_AVAILABLE; NULL: con_call() */
    void *app;                      /* passed to every handler */
    con_copy_fn copy;
#endif
    con_rt_t *rt;
    con_args_t args;
    char line[CON_LINE_MAX + 1];
    uint16_t now;        /* ms, from the last con_poll() */
    uint16_t t_pending;  /* ms when the pending command was accepted */
    uint16_t pending_ms; /* deadline of a pending command; 0 = none */
    uint16_t t_line;     /* ms when the last line was read */
    uint8_t len;
    uint8_t flags;
    uint8_t state; /* reading, pending, help, reply held */
    uint8_t help_i;
    uint8_t call;     /* the command con_call() returns */
    uint8_t realtime; /* con_set_realtime() */
    int8_t held_rc;   /* final reply waiting for room */
    uint8_t olen;     /* bytes of the line assembled; CON_OUT_MAX + 1 when it overflowed,
                         CON_OUT_MAX + 2 when the output ring had no room for it */
    uint8_t mute;     /* the report being assembled is dropped already (no room) */
    uint16_t dropped; /* report lines dropped (con_dropped()) */
#if !CON_IO_FIXED
    char obuf[CON_OUT_MAX]; /* the line assembled (CON_IO_FIXED: in the output ring) */
#endif
} con_t;

/* Binds the console. handlers must hold CON_CMD_COUNT entries (the HELP
 * entry is not used: help is built in), or be NULL: the application runs
 * the commands (con_call()); with CON_HANDLERS 0 the application always
 * does. rt may be shared with the RX interrupt's hook. Returns 0. */
int8_t con_init(con_t *con, const con_io_t *io, const con_handler_fn *handlers, void *app,
                con_copy_fn copy, con_rt_t *rt);

/* Main-loop step at time now_ms (a free-running millisecond clock; only
 * differences are used, so it may wrap): reads and handles up to 16 input
 * bytes (stopping at the first completed line), or emits one help line.
 * Reads nothing while a command is pending; a pending command older than
 * the deadline is answered `error:21 timed out`. Returns 0 when waiting for
 * input, 1 while a command is pending or help is being written. */
int8_t con_poll(con_t *con, uint16_t now_ms);

/* Sets the deadline of pending commands in ms (1..65535; 0 = wait forever,
 * only for tests). con_init() sets CON_PENDING_MS. */
void con_set_timeout(con_t *con, uint16_t ms);

/* Realtime mode (on while anything moves): output never waits. Every line
 * is assembled first and written whole only when io->room() has space for
 * it (with CON_IO_FIXED it is assembled in the output ring, behind the bytes
 * queued, and a part that finds no room there drops it): a report line that
 * does not fit is dropped and counted
 * (con_dropped()); command output (a handler's reports, help lines) also
 * leaves CON_RESERVE bytes free for the run's own reports, help waits for
 * room line by line, and a final reply waits (no input is read meanwhile).
 * Command lines are read at most one per CON_RT_LINE_MS, and only when
 * CON_OUT_MAX + CON_RESERVE bytes are free (con_report_fits()), so a burst of
 * commands cannot take the loop's time from the motion (the rest waits in the
 * receive buffer: the streaming rule still holds). A report that cannot fit
 * is known at con_report_begin() (command output
 * needs CON_OUT_MAX + CON_RESERVE free, a run report CON_MIN_ROOM): it is
 * dropped there and its fields cost nothing. A line longer than CON_OUT_MAX
 * is dropped. Off: output is written at once
 * and write() may wait. */
void con_set_realtime(con_t *con, uint8_t on);

/* Report lines dropped in realtime mode since con_init() (wraps at 65536). */
uint16_t con_dropped(const con_t *con);

/* Finishes the pending command with result rc (0 -> `ok`, CON_E_* ->
 * `error:...`; any other negative value -> error:INTERNAL). Returns 0, or
 * CON_E_NOT_PENDING (nothing written) when no command is pending or rc is
 * positive. */
int8_t con_complete(con_t *con, int8_t rc);

/* Nonzero while a command waits for con_complete(). */
uint8_t con_pending(const con_t *con);

/* Without a handler table (con_init() with handlers NULL): the command
 * (con_cmd_t) of a validated line waiting for the application to run it, or
 * -1. Its arguments are in con->args. The console reads nothing more until
 * con_called() takes the result. Call it after each con_poll(). */
int8_t con_call(const con_t *con);

/* Hands the result of the command con_call() returned to the console, as a
 * handler's return value (0, CON_E_* or CON_PENDING: see the file comment).
 * Returns 0, or CON_E_NOT_PENDING (nothing written) when no command waits. */
int8_t con_called(con_t *con, int8_t rc);

/* RX-interrupt hook: counts `!` and returns 1 (byte consumed); returns 0 for
 * every other byte. Wrap it in a function of the uart0 hook type. */
uint8_t con_rt_byte(con_rt_t *rt, uint8_t byte);

/* Returns 1 once per burst of `!` received since the last call, else 0. */
uint8_t con_rt_take(con_rt_t *rt);

/* Reports: con_report_begin() writes `<kind`, each field ` key=value`,
 * con_report_end() writes `>` and CRLF. kind and key are flash strings.
 * con_report_fixed() prints v / 10^decimals with exactly `decimals`
 * fractional digits (800, 3 -> 0.800; -5, 1 -> -0.5); decimals above 9 are
 * taken as 9. con_report_str() writes a RAM string, in double quotes when it
 * is empty or holds a space, '>' or '='; con_report_flash() the same for a
 * flash string. Keys and values must not contain '"', CR or LF (the host
 * parser could not split them); kind and keys are single words. */
void con_report_begin(con_t *con, const char *kind);
/* 1 when a report of any length begun now would be written (realtime mode:
 * room for the longest line and the reserve of command replies), 0 when it
 * might be dropped: a caller whose report must not be lost waits for it. */
uint8_t con_report_fits(const con_t *con);
/* 1 when the longest line (and in realtime mode the reserve) fits the
 * output ring now, in either mode: a listing writes its next line only then,
 * so no pass waits for the UART (docs/console.md). */
uint8_t con_line_fits(const con_t *con);
/* 1 when the output ring is (all but) empty: what was written has left. */
uint8_t con_out_drained(const con_t *con);
void con_report_int(con_t *con, const char *key, int32_t v);
void con_report_fixed(con_t *con, const char *key, int32_t v, uint8_t decimals);
void con_report_str(con_t *con, const char *key, const char *s);
void con_report_flash(con_t *con, const char *key, const char *s);
/* key=v1,v2,... written as it goes: con_report_list() writes the key (and
 * "" when n, the count of items that follow, is 0), con_report_item() each
 * value, with a ',' before it unless first, and mark after it unless '\0'. */
void con_report_list(con_t *con, const char *key, uint8_t n);
void con_report_item(con_t *con, int32_t v, char mark, uint8_t first);
/* key=<word i of the space-separated flash list words> ("?" past its end). */
void con_report_word(con_t *con, const char *key, const char *words, uint8_t i);
void con_report_end(con_t *con);

/* Formats v / 10^decimals into buf (capacity cap, NUL-terminated; 13 bytes
 * hold any value). Returns the length, or -1 (buf = "") when cap is too
 * small. Used by the report functions; exposed for handlers and tests. */
int8_t con_format_fixed(char *buf, uint8_t cap, int32_t v, uint8_t decimals);

/* Parses text (len characters) as a number with up to `decimals` fractional
 * digits into *v scaled by 10^decimals ("0.8", 3 -> 800; "-12", 0 -> -12).
 * Grammar: [+-] digits [. digits] with at least one digit; magnitude at
 * most 2147483647 after scaling. Returns 0, or CON_E_BAD_NUMBER (*v
 * untouched). */
int8_t con_parse_fixed(const char *text, uint8_t len, uint8_t decimals, int32_t *v);

/* Copies the name of command cmd into buf (capacity cap, truncated,
 * NUL-terminated). Returns the name's length, or CON_E_INTERNAL for a bad
 * cmd or cap 0. */
int8_t con_cmd_name(const con_t *con, uint8_t cmd, char *buf, uint8_t cap);

#endif /* HALLHOME_CONSOLE_H */
