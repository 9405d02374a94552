/*
 * app: the superloop that turns the rooms into the product (app.h), and the
 * small helpers every room uses (app_priv.h). Each pass runs one bounded step
 * of every room, in the order app.h lists.
 */
#include <string.h>

#include "app/app_priv.h"

uint32_t app_now_ms(const app_t *a)
{
    return APP_NOW_MS(a);
}

uint32_t app_now_us(const app_t *a)
{
    return APP_NOW_US(a);
}

APP_NOINLINE uint16_t app_bit16(uint8_t i)
{
    return (uint16_t)(1u << i);
}

/* Bit i of m (one routine: a variable shift is a loop on the AVR). */
APP_NOINLINE uint8_t app_has(uint16_t m, uint8_t i)
{
    return (uint8_t)((m >> i) & 1u);
}

APP_NOINLINE uint16_t app_all_mask(const app_t *a)
{
    return (uint16_t)((1u << a->info.n_tendons) - 1u);
}

uint8_t app_idle_state(const app_t *a)
{
    return (uint8_t)(a->state == APP_ST_IDLE || a->state == APP_ST_FAULT);
}

int8_t app_poll(app_t *app)
{
    app_t *a = app;
    hom_in_t in;
    uint32_t t0 = app_now_us(a), t = app_now_ms(a), dt;
    uint8_t st = a->state; /* a run started in this pass steps from the next */
    APP_WDT_KICK(a);
    if (con_rt_take(a->io->rt)) {
        app_abort(a);
    }
    /* one APP_ROOM_MARK() before each room, unconditionally: the bench
     * names the rooms by their order (sim/bench/looptime.c) */
    APP_ROOM_MARK();
    app_panel_button(a, (uint16_t)t);
    memset(&in, 0, sizeof in);
    APP_ROOM_MARK();
    app_sense_poll(a, &in, t0);
    APP_ROOM_MARK();
    if (a->state == APP_ST_BOOT) {
        app_boot_poll(a);
    }
    APP_ROOM_MARK();
    app_bus_poll(a);
    APP_ROOM_MARK();
    app_run_poll(a);
    APP_ROOM_MARK();
    switch (a->state) {
    case APP_ST_CAL:
        if (st == APP_ST_CAL) {
            app_run_step(a, &in);
        }
        break;
    case APP_ST_MOVE:
        app_run_move_step(a);
        break;
    case APP_ST_LEARN:
        app_learn_step(a, &in);
        break;
    default:
        break;
    }
    APP_ROOM_MARK();
    app_cmd_poll(a);
    APP_ROOM_MARK();
    app_rec_rest_poll(a);
    APP_ROOM_MARK();
    app_rec_poll(a);
    APP_ROOM_MARK();
    app_panel_led(a, t);
    APP_ROOM_MARK();
    a->loops++;
    dt = app_now_us(a) - t0;
    if (dt > a->loop_max_us) {
        a->loop_max_us = dt;
    }
    return (int8_t)a->state;
}
