/*
 * app_sense: the sensor room. The table's ICM-20948s in one icm_set (polled
 * by app_poll() every pass), and their samples handed to the homing and to
 * `learn` in cuT with a status (new, overflow, error, absent).
 */

#include "app/app_priv.h"

/* The sensor set of the table, once: its slots, one sensor per table entry
 * (mux channel and address), started at once (reads begin with the next
 * icm_set_poll()). A later bring-up (a press that found a sensor missing,
 * `servos`, a reboot) tries the failed sensors again at once: one plugged
 * back since its last attempt would otherwise wait up to a second for its
 * retry, and the press was refused with the sensor present (chaos seeds
 * 1009, 1036). */
void app_sense_start(app_t *a)
{
    uint8_t k;
    if (a->sense.set.n != 0u) {
        icm_set_retry(&a->sense.set, app_now_us(a));
        return;
    }
    (void)icm_set_setup(&a->sense.set, a->io->sensor_bus, a->io->mux_addr, a->sense.slot,
                        APP_MAX_SENSORS);
    for (k = 0; k < a->info.n_sensors; k++) {
        tbl_sensor_t s;
        (void)tbl_sensor(&a->tab, k, &s);
        (void)icm_set_add(&a->sense.set, a->io->mux_addr == ICM_NO_MUX ? ICM_NO_MUX : s.mux_channel,
                          s.i2c_addr);
    }
    (void)icm_set_begin(&a->sense.set, app_now_us(a));
}

/* Errors counted during the bring-up are not news for the homing. */
uint8_t app_sense_settled(app_t *a)
{
    uint8_t k;
    for (k = 0; k < a->info.n_sensors; k++) {
        icm_diag_t d;
        (void)icm_set_diag(&a->sense.set, k, &d);
        a->sense.err[k] = (uint8_t)d.error_count;
    }
    return icm_set_ready_count(&a->sense.set);
}

APP_NOINLINE void app_sense_poll(app_t *a, hom_in_t *in, uint32_t now_us)
{
    uint8_t k;
    if (a->sense.set.n == 0u) {
        return; /* not set up yet (no table, or before the bring-up) */
    }
    (void)icm_set_poll(&a->sense.set, now_us);
    for (k = 0; k < a->info.n_sensors; k++) {
        icm_sample_t s;
        hom_sensor_in_t *o = &in->sensor[k];
        int8_t rc = icm_set_take(&a->sense.set, k, &s);
        icm_diag_t d;
        (void)icm_set_diag(&a->sense.set, k, &d);
        if (rc == 1) {
            uint8_t ax;
            o->status = (s.flags & ICM_SAMPLE_OVERFLOW) ? HOM_SENS_OVERFLOW : HOM_SENS_NEW;
            /* quarter milliseconds: x 131 / 32768 is / 250.1 */
            uint32_t age = ((uint32_t)(now_us - s.t_us) * 131u) >> 15;
            for (ax = 0; ax < 3u; ax++) {
                o->b_cuT[ax] = (int32_t)s.raw[ax] * 15;
            }
            o->age_q = (uint8_t)(age > 0xFFu ? 0xFFu : age);
        } else if (d.state == ICM_SET_S_FAIL && !d.present) {
            o->status = HOM_SENS_ABSENT;
        } else if ((uint8_t)d.error_count != a->sense.err[k]) {
            o->status = HOM_SENS_ERROR;
        } else {
            o->status = HOM_SENS_NONE;
        }
        a->sense.err[k] = (uint8_t)d.error_count;
    }
}
