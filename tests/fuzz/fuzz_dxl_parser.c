/*
 * libFuzzer target: arbitrary bytes into the Protocol 2.0 parser (every
 * buffer size, stuffed and raw mode) and, as the bus reply, into the master
 * running a read, a sync read and a fast sync read. ASan catches any read or
 * write outside the buffers.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "dxl/dxl.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

typedef struct {
    const uint8_t *data;
    size_t size;
    size_t pos;
    uint32_t now;
} fuzz_port;

static uint16_t fz_write(void *ctx, const uint8_t *d, uint16_t n)
{
    (void)ctx;
    (void)d;
    return n;
}

static uint16_t fz_read(void *ctx, uint8_t *out, uint16_t cap)
{
    fuzz_port *p = ctx;
    uint16_t n = 0;
    /* hand out the input in uneven pieces */
    uint16_t want = (uint16_t)(1u + (p->now % 7u));
    while (n < cap && n < want && p->pos < p->size) {
        out[n++] = p->data[p->pos++];
    }
    return n;
}

static void fz_dir(void *ctx, uint8_t dir)
{
    (void)ctx;
    (void)dir;
}

static uint8_t fz_done(void *ctx)
{
    (void)ctx;
    return 1;
}

static uint32_t fz_now(void *ctx)
{
    fuzz_port *p = ctx;
    p->now += 37u;
    return p->now;
}

static void run_master(const uint8_t *data, size_t size, uint8_t which)
{
    fuzz_port fp = {data, size, 0, 0};
    dxl_port port = {&fp, fz_write, fz_read, fz_dir, fz_done, fz_now};
    dxl_config cfg;
    dxl_config_default(&cfg, 1000000, 10);
    dxl_master m;
    dxl_master_init(&m, &port, &cfg);
    const uint8_t ids[4] = {1, 2, 3, 4};
    switch (which % 4u) {
    case 0:
        (void)dxl_read(&m, 1, 132, 4);
        break;
    case 1:
        (void)dxl_sync_read(&m, 132, 4, ids, 4);
        break;
    case 2:
        (void)dxl_fast_sync_read(&m, 132, 4, ids, 4);
        break;
    default:
        (void)dxl_ping(&m, 2);
        break;
    }
    for (int i = 0; i < 10000 && dxl_poll(&m) > 0; i++) {
    }
    for (uint8_t i = 0; i < m.n_reply; i++) {
        volatile int32_t v = dxl_reply_value(&m.reply[i], 4);
        (void)v;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2) {
        return 0;
    }
    uint8_t buf[96];
    uint16_t cap = (uint16_t)(1u + data[0] % sizeof buf);
    dxl_parser p;
    dxl_parser_init(&p, buf, cap);
    dxl_parser_set_raw(&p, data[1] & 1u);
    uint32_t sum = 0;
    for (size_t i = 2; i < size; i++) {
        int8_t rc = dxl_parser_feed(&p, data[i]);
        if (rc == 0) {
            dxl_status st;
            if (dxl_parser_status(&p, &st) == 0) {
                for (uint16_t k = 0; k < st.n; k++) {
                    sum += st.params[k];
                }
            }
            sum += p.buf[0];
        }
    }
    volatile uint32_t sink = sum;
    (void)sink;
    run_master(data + 2, size - 2, data[1] >> 1);
    return 0;
}
