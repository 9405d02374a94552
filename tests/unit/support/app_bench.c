/* Native board for lib/app (app_bench.h). */
#include "app_bench.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dxl/dxl_proto.h"
#include "dxl/dxl_xl430_reg.h"
#include "hom_fixture.h"
#include "simrand.h"

/* tbl_copy_fn carries no context: the bench in use (one at a time). */
static app_bench_t *g_bench;

void app_bench_copy_learned(void *dst, const void *src, size_t n)
{
    app_table_copy(&g_bench->app, dst, src, n);
}

static app_bench_t *of_bus(void *ctx)
{
    return (app_bench_t *)(void *)((char *)ctx - offsetof(app_bench_t, bus));
}

static uint32_t port_now(void *ctx)
{
    return (uint32_t)of_bus(ctx)->now_us;
}

static uint32_t b_now_ms(void *ctx)
{
    return (uint32_t)(((app_bench_t *)ctx)->now_us / 1000u);
}

static uint32_t b_now_us(void *ctx)
{
    return (uint32_t)((app_bench_t *)ctx)->now_us;
}

static uint8_t b_button(void *ctx)
{
    return ((app_bench_t *)ctx)->button;
}

static void b_led(void *ctx, uint8_t on)
{
    app_bench_t *b = ctx;
    if (on != b->led) {
        b->led_changes++;
    }
    b->led = on;
}

static void b_kick(void *ctx)
{
    ((app_bench_t *)ctx)->kicks++;
}

static void b_reboot(void *ctx)
{
    ((app_bench_t *)ctx)->reboots++;
}

/* Flips one bit of byte with probability b->noise. */
static uint8_t noisy(app_bench_t *b, uint8_t byte)
{
    uint64_t x;
    if (b->noise <= 0.0) {
        return byte;
    }
    x = simrand_next(&b->noise_seed);
    if ((double)(x >> 11) * (1.0 / 9007199254740992.0) < b->noise) {
        b->noise_hits++;
        return (uint8_t)(byte ^ (1u << (uint8_t)(x & 7u)));
    }
    return byte;
}

/* A sync write from address addr (below 256) reaches the servos with a bit
 * of its CRC flipped while *left copies are still to be lost. */
static void lose_sync_write(uint8_t *left, uint8_t addr, uint8_t *buf, uint16_t n)
{
    if (*left != 0u && n > 9u && buf[7] == DXL_INST_SYNC_WRITE && buf[8] == addr && buf[9] == 0u) {
        (*left)--;
        buf[n - 1u] ^= 0x01u;
    }
}

static uint16_t noisy_write(void *ctx, const uint8_t *data, uint16_t n)
{
    app_bench_t *b = of_bus(ctx);
    uint8_t buf[DXL_TX_CAP];
    uint16_t i;
    if (n > sizeof buf) {
        n = sizeof buf;
    }
    for (i = 0; i < n; i++) {
        buf[i] = noisy(b, data[i]);
    }
    lose_sync_write(&b->lose_goal_writes, DXL_XL430_PROFILE_ACCELERATION_ADDR, buf, n);
    lose_sync_write(&b->lose_position_writes, DXL_XL430_GOAL_POSITION_ADDR, buf, n);
    return b->bus_port.write(ctx, buf, n);
}

static uint16_t noisy_read(void *ctx, uint8_t *out, uint16_t cap)
{
    app_bench_t *b = of_bus(ctx);
    uint16_t i, n = b->bus_port.read(ctx, out, cap);
    for (i = 0; i < n; i++) {
        out[i] = noisy(b, out[i]);
    }
    return n;
}

static void bench_copy(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}

/* Motors follow the servo shafts (or the weight), then the field at every
 * sensor goes to its ICM model. */
static void plant_update(app_bench_t *b)
{
    uint8_t i, k;
    for (i = 0; i < b->cfg.n_tendons; i++) {
        double m = xl430_shaft_ticks(&b->servo[i]) - b->shaft0[i];
        if (b->weight_on && i == b->weight_tendon) {
            m = b->weight_ticks;
        }
        (void)plant_set_motor(&b->plant, i, m);
    }
    (void)plant_solve(&b->plant);
    for (k = 0; k < b->cfg.n_sensors; k++) {
        double f[3];
        plant_field_true(&b->plant, k, f);
        icmm_set_field_cuT(&b->icm[k], (int32_t)(f[0] * 100.0), (int32_t)(f[1] * 100.0),
                           (int32_t)(f[2] * 100.0));
    }
}

static void app_start(app_bench_t *b, uint8_t with_table)
{
    memset(&b->io, 0, sizeof b->io);
    b->board.ctx = b;
    b->board.now_ms = b_now_ms;
    b->board.now_us = b_now_us;
    b->board.button = b_button;
    b->board.led = b_led;
    b->board.wdt_kick = b_kick;
    b->board.reboot = b_reboot;
    b->io.board = &b->board;
    dxl_fakebus_port(&b->bus, &b->bus_port);
    b->io.servo_port = b->bus_port;
    b->io.servo_port.write = noisy_write;
    b->io.servo_port.read = noisy_read;
    b->io.servo_port.now_us = port_now;
    b->io.servo_bits = 10;
    b->io.sensor_bus = &b->i2c.bus;
    b->io.mux_addr = 0x70;
    b->io.eeprom = &b->ee.ee;
    b->io.store_copy = bench_copy;
    b->io.console = &b->con.io;
    b->io.con_copy = bench_copy;
    b->io.rt = &b->rt;
    b->io.table = with_table ? tbl_buf_table(&b->table_buf) : NULL;
    b->io.table_copy = bench_copy;
    b->io.table_copy_learned = app_bench_copy_learned;
    b->io.version_f = "0.0.0-test";
    b->io.board_f = "native bench";
    b->io.reset_f = "power";
    b->io.win = &b->win;
    b->io.release_at_boot = b->wdt_reset;
    b->wdt_reset = 0;
    memset(&b->rt, 0, sizeof b->rt);
    g_bench = b;
    (void)app_init(&b->app, &b->io);
}

int app_bench_init(app_bench_t *b, uint8_t with_table)
{
    uint8_t i, k;
    int rc;
    memset(b, 0, sizeof *b);
    b->loop_us = APP_BENCH_LOOP_US;
    b->noise_seed = 0x9E3779B97F4A7C15ull;
    rc = hom_fix_paper(&b->cfg, &b->table);
    if (rc != 0) {
        return rc;
    }
    rc = tbl_pack(&b->table, &b->table_buf);
    if (rc != 0) {
        return rc;
    }
    rc = plant_init(&b->plant, &b->cfg, 7u);
    if (rc != 0) {
        return rc;
    }
    dxl_fakebus_init(&b->bus, 1000000u, 10);
    for (i = 0; i < b->cfg.n_tendons; i++) {
        xl430_config xc;
        xl430_config_default(&xc, b->table.tendons[i].servo_id);
        xl430_init(&b->servo[i], &xc, 0);
        dxl_fakebus_add(&b->bus, &b->servo[i]);
        b->servo_attached[i] = 1;
        b->shaft0[i] = 0.0;
    }
    tcam_init(&b->mux, 0x70);
    for (k = 0; k < b->cfg.n_sensors; k++) {
        icmm_init(&b->icm[k], b->table.sensors[k].i2c_addr, 100u + k);
        icmm_set_noise(&b->icm[k], (uint32_t)(b->cfg.noise_uT * 100.0), 200u + k);
        (void)tcam_attach(&b->mux, b->table.sensors[k].mux_channel, icmm_slave(&b->icm[k]));
    }
    icm_fake_bus_setup(&b->i2c, tcam_slave(&b->mux));
    store_fake_init(&b->ee, 0xFF);
    b->ee.busy_polls = 2;
    con_fake_init(&b->con);
    plant_update(b);
    app_start(b, with_table);
    return 0;
}

void app_bench_restart(app_bench_t *b, uint8_t power_cycle)
{
    uint8_t i;
    if (power_cycle) {
        for (i = 0; i < b->bus.n; i++) {
            xl430_power_cycle(b->bus.servo[i], b->bus.now);
        }
        memset(&b->win, 0, sizeof b->win); /* RAM the board keeps only across resets */
    }
    store_fake_power_on(&b->ee);
    app_start(b, b->io.table != NULL);
}

void app_bench_step(app_bench_t *b)
{
    uint64_t i2c_us;
    uint32_t ms;
    uint32_t bus_now = b->bus.now;
    if ((uint32_t)b->now_us > bus_now) {
        dxl_fakebus_advance(&b->bus, (uint32_t)b->now_us - bus_now);
    }
    ms = (uint32_t)(b->now_us / 1000u);
    if (ms != b->last_plant_ms) {
        b->last_plant_ms = ms;
        plant_update(b);
    }
    i2c_us = b->i2c.now_ns / 1000u;
    if (i2c_us < b->now_us) {
        icm_fake_bus_sleep_us(&b->i2c, (uint32_t)(b->now_us - i2c_us));
    }
    (void)app_poll(&b->app);
    i2c_us = b->i2c.now_ns / 1000u;
    b->now_us += b->loop_us;
    if (i2c_us > b->now_us) {
        b->now_us = i2c_us;
    }
}

void app_bench_run_ms(app_bench_t *b, uint32_t ms)
{
    uint64_t end = b->now_us + (uint64_t)ms * 1000u;
    while (b->now_us < end) {
        app_bench_step(b);
    }
}

int app_bench_wait_line(app_bench_t *b, const char *prefix, char *line, size_t cap, uint32_t ms)
{
    uint64_t end = b->now_us + (uint64_t)ms * 1000u;
    size_t n = strlen(prefix);
    for (;;) {
        while (con_fake_line(&b->con, line, cap)) {
            if (getenv("APP_BENCH_TRACE") != NULL) {
                fprintf(stderr, "%10.3f %s\n", (double)b->now_us / 1000.0, line);
            }
            if (strncmp(line, prefix, n) == 0) {
                return 1;
            }
        }
        if (b->now_us >= end) {
            return 0;
        }
        app_bench_step(b);
    }
}

void app_bench_send(app_bench_t *b, const char *line)
{
    con_fake_puts(&b->con, line);
    con_fake_puts(&b->con, "\r\n");
}

double app_bench_tension(const app_bench_t *b, uint8_t i)
{
    return b->plant.tension_N[i];
}

long app_bench_field(const char *line, const char *key, long def)
{
    char pat[40];
    const char *p;
    snprintf(pat, sizeof pat, " %s=", key);
    p = strstr(line, pat);
    if (p == NULL) {
        return def;
    }
    return strtol(p + strlen(pat), NULL, 0);
}
