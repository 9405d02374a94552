/*
 * app_panel: the button (debounced; a short press starts a run, a long press
 * aborts) and the LED patterns (app.h, APP_LED_*).
 */
#include "app/app_priv.h"

void app_panel_button(app_t *a, uint16_t t)
{
    uint8_t b = APP_BUTTON(a);
    uint8_t raw = b & 1u;
    b ^= raw; /* the count */
    if (b != a->panel.presses && !a->panel.state) {
        /* the board counted a press (it settles in 8 ms, before the
         * debounce below): the release the debounce saw, or one it missed
         * (it came and went within one long pass: a status burst at rest
         * writes for 100 ms, chaos seeds 2035 and 2083), which starts a run */
        a->panel.presses = b;
        if (a->panel.owed) {
            a->panel.owed = 0;
        } else {
            app_run_press(a);
        }
    }
    if (raw != a->panel.raw) {
        a->panel.raw = raw;
        a->panel.t_change = t;
    }
    if ((uint16_t)(t - a->panel.t_change) >= APP_DEBOUNCE_MS && a->panel.state != a->panel.raw) {
        a->panel.state = a->panel.raw;
        if (a->panel.state) {
            a->panel.t_down = t;
            a->panel.long_done = 0;
        } else {
            a->panel.owed = 1;
            if (!a->panel.long_done) {
                app_run_press(a);
            }
        }
    }
    if (a->panel.state && !a->panel.long_done &&
        (uint16_t)(t - a->panel.t_down) >= APP_LONG_PRESS_MS) {
        a->panel.long_done = 1;
        app_abort(a);
    }
}

void app_panel_led(app_t *a, uint32_t t)
{
    /* one 32-bit division a pass: the phase p in the pattern's period
     * ((t / 100) & 1 is p >= 100 of t % 200, and so on) */
    uint8_t pat = app_led_pattern(a);
    uint8_t on;
    uint16_t p = (uint16_t)(t % (pat == APP_LED_BOOT    ? 200u
                                 : pat == APP_LED_RUN   ? 250u
                                 : pat == APP_LED_FAULT ? 1000u
                                                        : 2000u));
    switch (pat) {
    case APP_LED_BOOT:
        on = (uint8_t)(p >= 100u);
        break;
    case APP_LED_RUN:
        on = (uint8_t)(p >= 125u);
        break;
    case APP_LED_DONE:
        on = 1;
        break;
    case APP_LED_FAULT: /* 50 ms on, 50 off, three times */
        on = (uint8_t)(p < 300u && ((p / 50u) & 1u) == 0u);
        break;
    default:
        on = (uint8_t)(p < 50u || (a->boot.offer_quick && p >= 200u && p < 250u));
        break;
    }
    if (on != a->panel.led_on || a->loops == 0u) {
        a->panel.led_on = on;
        APP_LED(a, on);
    }
}

uint8_t app_led_pattern(const app_t *app)
{
    switch (app->state) {
    case APP_ST_BOOT:
        return APP_LED_BOOT;
    case APP_ST_CAL:
    case APP_ST_MOVE:
    case APP_ST_LEARN:
        return APP_LED_RUN;
    case APP_ST_FAULT:
        return APP_LED_FAULT;
    default:
        return app->panel.led == APP_LED_DONE || app->panel.led == APP_LED_FAULT ? app->panel.led
                                                                                 : APP_LED_IDLE;
    }
}
