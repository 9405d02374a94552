#include "con_fake.h"

#include <string.h>

static int16_t fake_read(void *ctx)
{
    con_fake_t *f = (con_fake_t *)ctx;
    if (f->in_pos >= f->in_len) {
        return -1;
    }
    return f->in[f->in_pos++];
}

static void fake_write(void *ctx, const char *buf, uint8_t n)
{
    con_fake_t *f = (con_fake_t *)ctx;
    uint8_t i;
    for (i = 0; i < n; i++) {
        if (f->out_len < CON_FAKE_OUT_MAX) {
            f->out[f->out_len++] = buf[i];
        } else {
            f->overflow++;
        }
    }
    f->out[f->out_len] = '\0';
}

static uint16_t fake_room(void *ctx)
{
    return ((con_fake_t *)ctx)->room;
}

void con_fake_set_room(con_fake_t *f, int32_t room)
{
    f->room = (uint16_t)(room < 0 ? 0 : room);
    f->io.room = room < 0 ? NULL : fake_room;
}

void con_fake_init(con_fake_t *f)
{
    memset(f, 0, sizeof(*f));
    f->io.ctx = f;
    f->io.read = fake_read;
    f->io.write = fake_write;
}

void con_fake_feed(con_fake_t *f, const void *bytes, size_t n)
{
    const uint8_t *b = (const uint8_t *)bytes;
    while (n-- > 0u && f->in_len < CON_FAKE_IN_MAX) {
        f->in[f->in_len++] = *b++;
    }
}

void con_fake_puts(con_fake_t *f, const char *s)
{
    con_fake_feed(f, s, strlen(s));
}

size_t con_fake_unread(const con_fake_t *f)
{
    return f->in_len - f->in_pos;
}

int con_fake_line(con_fake_t *f, char *buf, size_t cap)
{
    const char *start = f->out + f->out_taken;
    const char *end = strstr(start, "\r\n");
    size_t n;
    if (end == NULL || cap == 0u) {
        return 0;
    }
    n = (size_t)(end - start);
    if (n >= cap) {
        n = cap - 1u;
    }
    memcpy(buf, start, n);
    buf[n] = '\0';
    f->out_taken = (size_t)(end - f->out) + 2u;
    return 1;
}

void con_fake_clear(con_fake_t *f)
{
    f->out_taken = f->out_len;
}

void con_fake_copy(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}
