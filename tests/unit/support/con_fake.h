/*
 * con_fake: byte I/O for the console unit tests and the fuzz target. Input
 * is a byte buffer the console reads one byte at a time; output is captured
 * in a buffer and can be taken line by line.
 */
#ifndef HALLHOME_CON_FAKE_H
#define HALLHOME_CON_FAKE_H

#include <stddef.h>
#include <stdint.h>

#include "console/console.h"

#define CON_FAKE_IN_MAX  4096u
#define CON_FAKE_OUT_MAX 65536u

typedef struct {
    uint8_t in[CON_FAKE_IN_MAX];
    size_t in_len, in_pos;
    char out[CON_FAKE_OUT_MAX + 1];
    size_t out_len, out_taken;
    uint32_t overflow; /* output bytes lost because the buffer was full */
    uint16_t room;     /* what io.room reports, once con_fake_set_room() installed it */
    con_io_t io;
} con_fake_t;

void con_fake_init(con_fake_t *f);

/* Gives the console a transmit-ring room of `room` bytes (a UART still
 * sending); room < 0 takes the room function away again (none: the
 * console's writes never wait). */
void con_fake_set_room(con_fake_t *f, int32_t room);

/* Appends n input bytes (dropped beyond CON_FAKE_IN_MAX). */
void con_fake_feed(con_fake_t *f, const void *bytes, size_t n);

/* Appends a NUL-terminated string as input. */
void con_fake_puts(con_fake_t *f, const char *s);

/* Bytes of input not yet read by the console. */
size_t con_fake_unread(const con_fake_t *f);

/* Copies the next complete output line (without CRLF) into buf (capacity
 * cap) and returns 1, or returns 0 when no complete line is waiting. */
int con_fake_line(con_fake_t *f, char *buf, size_t cap);

/* Drops all output not taken yet. */
void con_fake_clear(con_fake_t *f);

/* memcpy with the con_copy_fn signature. */
void con_fake_copy(void *dst, const void *src, size_t n);

#endif /* HALLHOME_CON_FAKE_H */
