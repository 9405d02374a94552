/*
 * con_priv: what the files of lib/console share and nothing else. Users of
 * the console include console.h only.
 *
 *   con_out.c    output buffering, the final reply, reports,
 *                con_format_fixed(), con_fl_skip()
 *   con_parse.c  the command table: lookup, argument checks against the
 *                synopses, con_parse_fixed(), con_cmd_name(), help listing
 *   console.c    line assembly, execution, pending commands, realtime bytes,
 *                the public entry points
 *
 * The firmware is linked as one LTO unit, and the compiler's inlining,
 * register allocation and function order follow how the sources are laid out
 * (the order of the files, where a helper is defined): the files are named
 * so that they link in the order console.c once had its parts, and the one
 * small helper two of them use, con_fl_char(), is a static function of each,
 * as it was of console.c. The image keeps its code and layout, and the main
 * loop's passes their timing, to which the bench's fault scenarios are
 * sensitive (measured: a first split, whose functions kept their code but
 * not their order, moved the timing enough to fail three of them).
 */
#ifndef HALLHOME_CON_PRIV_H
#define HALLHOME_CON_PRIV_H

#include "console/console.h"

#define CON_ST_READ    0u /* assembling a line */
#define CON_ST_CALL    1u /* inside a handler */
#define CON_ST_PENDING 2u /* handler accepted, waiting for con_complete() */
#define CON_ST_HELP    3u /* writing the help listing */
#define CON_ST_HELD    4u /* a final reply waits for room (realtime mode) */

/* Functions that measured smaller on the AVR as calls than inlined into the
 * line handling (argument checks, a handler's result). */
#if defined(__GNUC__)
#define CON_NOINLINE __attribute__((noinline))
#else
#define CON_NOINLINE
#endif

/* ---- flash access ------------------------------------------------ */

/* One byte of a flash string (con_fl_char() in con_out.c and con_parse.c).
 * The scans read them one at a time (command lookup, synopsis, error text:
 * about 1 KB per line): an inline LPM on the AVR, not a call through copy
 * per byte (11 ms per line). */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define CON_FLASH_BYTE(p) ((char)pgm_read_byte(p))
#define CON_FLASH_U16(p)  ((uint16_t)pgm_read_word(p))
#else
#define CON_FLASH_BYTE(p) (*(p))
#define CON_FLASH_U16(p)  (*(p))
#endif

/* The console's byte I/O (console.h, CON_IO_FIXED); CON_HAS_ROOM(c): it
 * has a room() function. */
#if CON_IO_FIXED
#define CON_IO_READ(c)          ((void)(c), con_io_read())
#define CON_IO_WRITE(c, buf, n) ((void)(c), con_io_write(buf, n))
#define CON_IO_ROOM(c)          ((void)(c), con_io_room())
#define CON_HAS_ROOM(c)         ((void)(c), 1)
#else
#define CON_IO_READ(c)          (c)->io->read((c)->io->ctx)
#define CON_IO_WRITE(c, buf, n) (c)->io->write((c)->io->ctx, buf, n)
#define CON_IO_ROOM(c)          (c)->io->room((c)->io->ctx)
#define CON_HAS_ROOM(c)         ((c)->io->room != NULL)
#endif

/* Pointer past the next n NUL-terminated strings at p (con_out.c). */
const char *con_fl_skip(const con_t *c, const char *p, uint16_t n);

/* ---- output (con_out.c) ------------------------------------------ */

/* Appends n bytes to the line being assembled (realtime mode), or writes
 * them at once (see con_set_realtime()). */
void con_out(con_t *c, const char *s, uint8_t n);
void con_out_ch(con_t *c, char ch);
void con_out_ram(con_t *c, const char *s);
/* A flash string, in small chunks (no read past its NUL). */
void con_out_flash(con_t *c, const char *p);

/* Writes the assembled line when it may be written now, keeping `reserve`
 * bytes of room free in realtime mode. Returns 1 when written (or dropped for
 * length), 0 when it must wait; the line is gone afterwards either way. */
uint8_t con_flush(con_t *c, uint16_t reserve);

/* The one place a final reply (`ok` for rc >= 0, else `error:...`) is
 * written; in realtime mode without room it is held (CON_ST_HELD) and
 * written by a later con_poll(). */
void con_reply(con_t *c, int8_t rc);

/* ---- the command table (con_parse.c) ----------------------------- */

/* The command named tok (lower case), or CON_E_UNKNOWN_COMMAND. */
int8_t con_find_cmd(const con_t *c, const char *tok);

/* Checks every argument against the synopsis and fills c->args; the first
 * failure decides the error. */
int8_t con_check_args(con_t *c, uint8_t cmd, char **tok, uint8_t ntok);

/* Starts the help listing (CON_ST_HELP) at the first command. */
void con_help_start(con_t *c);

/* Writes the help line of the next command. Returns 1 when written, 0 when
 * it must wait for room (realtime mode). */
uint8_t con_help_line(con_t *c);

#endif /* HALLHOME_CON_PRIV_H */
