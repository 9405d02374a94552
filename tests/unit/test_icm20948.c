/*
 * icm20948 driver against the register-level ICM-20948/AK09916 model and the
 * TCA9548A model, through the byte-level fake bus.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "devices/icm20948_model.h"
#include "devices/tca9548a_model.h"
#include "icm20948/icm20948.h"
#include "icm20948/icm20948_reg.h"
#include "icm20948/tca9548a.h"
#include "icm_fake_bus.h"

typedef struct {
    icmm_t icm;
    icm_fake_bus_t fb;
    icm_dev_t dev;
} direct_t;

static void direct_setup(direct_t *d)
{
    icmm_init(&d->icm, 0x69, 1234);
    icm_fake_bus_setup(&d->fb, icmm_slave(&d->icm));
    assert_int_equal(icm_setup(&d->dev, &d->fb.bus, NULL, ICM_NO_MUX, 0x69), 0);
}

/* Runs init to its end, polling every 100 us of simulated time. */
static int8_t run_init(icm_dev_t *dev, icm_fake_bus_t *fb, uint32_t *polls)
{
    uint32_t n = 0;
    int8_t rc;
    assert_int_equal(icm_init_start(dev, icm_fake_bus_now_us(fb)), 0);
    do {
        rc = icm_init_poll(dev, icm_fake_bus_now_us(fb));
        icm_fake_bus_sleep_us(fb, 100);
        n++;
    } while (rc == ICM_BUSY && n < 5000u);
    if (polls != NULL) {
        *polls = n;
    }
    return rc;
}

static int8_t read_once(icm_dev_t *dev, icm_fake_bus_t *fb, icm_sample_t *s)
{
    int8_t rc = icm_read_start(dev, icm_fake_bus_now_us(fb));
    if (rc != 0) {
        return rc;
    }
    return icm_read_fetch(dev, icm_fake_bus_now_us(fb), s);
}

/* Reads every 5 ms until a new sample arrives (at most 50 ms). */
static int8_t read_new(icm_dev_t *dev, icm_fake_bus_t *fb, icm_sample_t *s)
{
    int i;
    for (i = 0; i < 10; i++) {
        int8_t rc;
        icm_fake_bus_sleep_us(fb, 5000);
        rc = read_once(dev, fb, s);
        if (rc != 0 || (s->flags & ICM_SAMPLE_NEW)) {
            return rc;
        }
    }
    return 99;
}

static void test_setup_rejects_bad_args(void **state)
{
    icm_dev_t dev;
    icm_bus_t bus = {0};
    tca_t mux;
    (void)state;
    assert_int_equal(icm_setup(&dev, NULL, NULL, ICM_NO_MUX, 0x69), ICM_E_ARG);
    assert_int_equal(icm_setup(&dev, &bus, NULL, ICM_NO_MUX, 0x69), ICM_E_ARG);
    assert_int_equal(icm_init_poll(NULL, 0), ICM_E_ARG);
    direct_t d;
    direct_setup(&d);
    assert_int_equal(icm_setup(&dev, &d.fb.bus, NULL, ICM_NO_MUX, 0x6A), ICM_E_ARG);
    assert_int_equal(icm_setup(&dev, &d.fb.bus, NULL, 3, 0x69), ICM_E_ARG);
    assert_int_equal(tca_setup(&mux, &d.fb.bus, 0x70), 0);
    assert_int_equal(icm_setup(&dev, &d.fb.bus, &mux, 8, 0x69), ICM_E_ARG);
    assert_int_equal(icm_setup(&dev, &d.fb.bus, &mux, 7, 0x68), 0);
    assert_int_equal(icm_set_stale_us(&dev, 0), ICM_E_ARG);
    /* reading before init is a state error, not a bus access */
    icm_sample_t s;
    assert_int_equal(icm_read_start(&d.dev, 0), ICM_E_STATE);
    assert_int_equal(icm_read_fetch(&d.dev, 0, &s), ICM_E_STATE);
    assert_int_equal(icm_init_poll(&d.dev, 0), ICM_E_STATE);
    assert_int_equal(d.fb.transfers, 0);
}

static void test_init_configures_device(void **state)
{
    direct_t d;
    uint32_t polls;
    (void)state;
    direct_setup(&d);
    d.icm.regs[0][ICM_REG_USER_CTRL] = 0; /* power-on */
    assert_int_equal(run_init(&d.dev, &d.fb, &polls), 0);
    assert_true(icm_ready(&d.dev));
    assert_int_equal(d.dev.who_am_i, 0xEA);
    assert_int_equal(d.dev.mag_id, 0x09);
    /* reset once, awake with auto clock, master on, AK in 100 Hz mode */
    assert_int_equal(d.icm.resets, 1);
    assert_int_equal(icmm_peek(&d.icm, 0, ICM_REG_PWR_MGMT_1), ICM_REG_PWR_CLKSEL_AUTO);
    assert_int_equal(icmm_peek(&d.icm, 0, ICM_REG_USER_CTRL), ICM_REG_USER_I2C_MST_EN);
    assert_true(d.icm.mst_resets >= 1);
    assert_int_equal(d.icm.ak.mode, AK_REG_MODE_CONT_100HZ);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_MST_CTRL), 0x17);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_SLV0_ADDR), 0x8C);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_SLV0_REG), AK_REG_ST1);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_SLV0_CTRL), 0x89);
    assert_int_equal(d.dev.mag_company, 0x48);
    /* gyro and accelerometer off, master at 1.1 kHz / 2^3 with the shadow
     * delay, its clock set before it was enabled */
    assert_int_equal(icmm_peek(&d.icm, 0, ICM_REG_PWR_MGMT_2), 0x3F);
    assert_int_equal(icmm_peek(&d.icm, 0, ICM_REG_LP_CONFIG), ICM_REG_LP_I2C_MST_CYCLE);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_MST_ODR_CONFIG), 3);
    assert_int_equal(icmm_peek(&d.icm, 3, ICM_REG_I2C_MST_DELAY_CTRL), ICM_REG_DELAY_ES_SHADOW);
    assert_int_equal(d.icm.mst_ctrl_live_writes, 0);
    /* the master now polls the AK09916 at about 137 Hz, not 1.1 kHz */
    {
        uint32_t before = d.icm.slv0_reads;
        icm_fake_bus_sleep_us(&d.fb, 1000000);
        assert_in_range(d.icm.slv0_reads - before, 130, 145);
    }
    /* ends in bank 0, and the cache agrees with the device */
    assert_int_equal(d.icm.bank, 0);
    assert_int_equal(d.dev.bank, 0);
    /* the init waits (reset 100 ms) were honoured by polling, not blocking */
    assert_true(polls > 100u);
    assert_true(icm_fake_bus_now_us(&d.fb) >= ICM_RESET_WAIT_US);
}

static void test_bank_cache_avoids_redundant_selects(void **state)
{
    direct_t d;
    icm_sample_t s;
    uint32_t before;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icm_fake_bus_sleep_us(&d.fb, 20000);
    before = d.fb.transfers;
    assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    /* bank already 0: the read is one transfer */
    assert_int_equal(d.fb.transfers - before, 1);
    /* someone switched the bank behind the driver's back is not modelled;
     * after a failed transfer the cache is dropped and the bank rewritten */
    d.fb.timeouts = 1;
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_TIMEOUT);
    assert_int_equal(d.dev.bank, 0xFF);
}

static void test_sample_values_and_flags(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    /* 30.00 uT, -45.15 uT, 0.15 uT: 200, -301, 1 counts */
    icmm_set_field_cuT(&d.icm, 3000, -4515, 15);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    assert_true(s.flags & ICM_SAMPLE_NEW);
    assert_false(s.flags & ICM_SAMPLE_OVERFLOW);
    assert_int_equal(s.raw[0], 200);
    assert_int_equal(s.raw[1], -301);
    assert_int_equal(s.raw[2], 1);
    /* read again at once: same snapshot, a repeat */
    assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    assert_false(s.flags & ICM_SAMPLE_NEW);
    assert_int_equal(s.raw[1], -301);
    /* a new field shows up within one AK period as a new sample */
    icmm_set_field_cuT(&d.icm, -3000, 0, 32752 * 15);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    assert_int_equal(s.raw[0], -200);
    assert_int_equal(s.raw[2], 32752);
    assert_false(s.flags & ICM_SAMPLE_OVERFLOW);
}

static void test_overflow_sets_hofl(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icmm_set_field_cuT(&d.icm, 500000, 0, -600000); /* 5000 uT, -6000 uT */
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    assert_true(s.flags & ICM_SAMPLE_OVERFLOW);
    assert_true(s.st2 & AK_REG_ST2_HOFL);
    assert_int_equal(s.raw[0], 32752);
    assert_int_equal(s.raw[2], -32752);
    assert_int_equal(d.dev.overflow_count, 1);
    /* back in range: HOFL clears */
    icmm_set_field_cuT(&d.icm, 100, 0, 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    assert_false(s.flags & ICM_SAMPLE_OVERFLOW);
    assert_int_equal(d.dev.overflow_count, 1);
}

static void test_rate_every_sample_caught_at_5ms(void **state)
{
    direct_t d;
    icm_sample_t s;
    int i;
    uint32_t t0;
    (void)state;
    direct_setup(&d);
    icmm_set_noise(&d.icm, 60, 77); /* 0.6 uT rms: no two samples alike */
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icm_fake_bus_sleep_us(&d.fb, 20000);
    assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    t0 = d.icm.ak.samples;
    uint32_t n0 = d.dev.new_count;
    for (i = 0; i < 200; i++) { /* one second */
        icm_fake_bus_sleep_us(&d.fb, 5000 - d.fb.last_transfer_ns / 1000u);
        assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    }
    /* the AK produced ~100 samples; the driver saw each one as new once */
    uint32_t produced = d.icm.ak.samples - t0;
    uint32_t seen = d.dev.new_count - n0;
    assert_in_range(produced, 99, 101);
    assert_in_range(seen, produced - 1u, produced + 1u);
    assert_int_equal(d.dev.overrun_count, 0);
}

static void test_read_wire_time(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icm_fake_bus_sleep_us(&d.fb, 20000);
    assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    /* START addr+W, reg, rSTART addr+R, 9 data bytes, STOP: 12 bytes of 9
     * bits + 2 starts + stop = 111 bits = 277.5 us at 400 kHz */
    assert_int_equal(d.fb.last_transfer_ns, 277500);
}

static void test_absent_sensor(void **state)
{
    direct_t d;
    (void)state;
    direct_setup(&d);
    d.icm.present = 0;
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_ABSENT);
    assert_false(icm_ready(&d.dev));
    assert_int_equal(d.dev.err, ICM_E_ABSENT);
    assert_int_equal(d.dev.who_am_i, 0);
}

static void test_wrong_who_am_i(void **state)
{
    direct_t d;
    (void)state;
    direct_setup(&d);
    d.icm.who_am_i = 0x71; /* an MPU-9250 at the same address */
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_WHOAMI);
    assert_int_equal(d.dev.who_am_i, 0x71);
    assert_int_equal(d.icm.resets, 0); /* never reset a device we do not know */
}

static void test_mag_absent_after_retries(void **state)
{
    direct_t d;
    (void)state;
    direct_setup(&d);
    d.icm.ak.present = 0;
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_MAG_ABSENT);
    assert_int_equal(d.dev.tries, ICM_MAG_TRIES);
    /* one master reset at setup, then one between every two tries */
    assert_int_equal(d.icm.mst_resets, 1u + (ICM_MAG_TRIES - 1u));
}

static void test_mag_wrong_id(void **state)
{
    direct_t d;
    (void)state;
    direct_setup(&d);
    d.icm.ak.wia2 = 0x05;
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_MAG_ID);
    assert_int_equal(d.dev.mag_id, 0x05);
    assert_int_equal(d.dev.tries, ICM_MAG_TRIES);
    /* another company's chip with the same device ID is refused too */
    direct_setup(&d);
    d.icm.ak.wia1 = 0x47;
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_MAG_ID);
    assert_int_equal(d.dev.mag_company, 0x47);
    assert_int_equal(d.dev.mag_id, 0); /* WIA2 never reached */
    assert_int_equal(d.dev.tries, ICM_MAG_TRIES);
}

static void test_master_hang_recovered_by_retry(void **state)
{
    direct_t d;
    (void)state;
    direct_setup(&d);
    d.icm.mst_hang_tries = 2; /* the first two SLV4 transfers hang the master */
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(d.dev.tries, 2);
    assert_int_equal(d.icm.mst_resets, 3);
    assert_int_equal(d.icm.ak.mode, AK_REG_MODE_CONT_100HZ);
}

static void test_nack_mid_transfer(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icm_fake_bus_sleep_us(&d.fb, 20000);
    d.fb.nack_at_byte = 1; /* the register byte */
    memset(&s, 0x5A, sizeof(s));
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_NACK);
    assert_int_equal(s.raw[0], 0x5A5A); /* untouched */
    assert_true(icm_ready(&d.dev));     /* a glitch: the next read works */
    assert_int_equal(d.dev.error_count, 1);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    /* NACK during init, in the middle of the reset write */
    direct_setup(&d);
    assert_int_equal(icm_init_start(&d.dev, 0), 0);
    assert_int_equal(icm_init_poll(&d.dev, 0), ICM_BUSY); /* bank 0 */
    assert_int_equal(icm_init_poll(&d.dev, 0), ICM_BUSY); /* WHO_AM_I */
    d.fb.nack_at_byte = 2;
    assert_int_equal(icm_init_poll(&d.dev, 0), ICM_E_NACK);
    /* and a fresh init then succeeds */
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
}

static void test_stuck_bus_recovered(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    icm_fake_bus_sleep_us(&d.fb, 20000);
    d.fb.stuck_sda = 1;
    d.fb.stuck_recoverable = 1;
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_BUS);
    assert_int_equal(d.fb.recoveries, 1);
    assert_int_equal(d.fb.stuck_sda, 0);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    /* a bus that stays stuck keeps failing, with a recovery per failure */
    d.fb.stuck_sda = 1;
    d.fb.stuck_recoverable = 0;
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_BUS);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), ICM_E_BUS);
    assert_int_equal(d.fb.recoveries, 3);
}

static void test_stale_data(void **state)
{
    direct_t d;
    icm_sample_t s;
    int8_t rc = 0;
    int i;
    (void)state;
    direct_setup(&d);
    icmm_set_noise(&d.icm, 60, 5);
    assert_int_equal(icm_set_stale_us(&d.dev, 30000), 0);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    /* the AK stops measuring (e.g. it reset itself): the snapshot freezes */
    d.icm.ak.mode = AK_REG_MODE_POWER_DOWN;
    d.icm.ak.next_meas_us = UINT64_MAX;
    for (i = 0; i < 20 && rc == 0; i++) {
        icm_fake_bus_sleep_us(&d.fb, 5000);
        rc = read_once(&d.dev, &d.fb, &s);
    }
    assert_int_equal(rc, ICM_E_STALE);
    assert_in_range(i, 6, 8); /* 30 ms after the last new sample */
    assert_false(s.flags & ICM_SAMPLE_NEW);
    assert_true(icm_ready(&d.dev)); /* the caller decides */
    assert_int_equal(d.dev.err, ICM_E_STALE);
}

static void test_sensor_disappears_after_init(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    d.icm.present = 0;
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_ABSENT);
    assert_false(icm_ready(&d.dev));
    assert_int_equal(read_once(&d.dev, &d.fb, &s), ICM_E_STATE);
    d.icm.present = 1;
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
}

static void test_magnetometer_disappears_goes_stale(void **state)
{
    direct_t d;
    icm_sample_t s;
    int8_t rc = 0;
    int i;
    (void)state;
    direct_setup(&d);
    icmm_set_noise(&d.icm, 60, 9);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    d.icm.ak.present = 0; /* SLV0 NACKs, EXT_SLV_SENS_DATA freezes */
    for (i = 0; i < 30 && rc == 0; i++) {
        icm_fake_bus_sleep_us(&d.fb, 5000);
        rc = read_once(&d.dev, &d.fb, &s);
    }
    assert_int_equal(rc, ICM_E_STALE);
    assert_true(icmm_peek(&d.icm, 0, ICM_REG_I2C_MST_STATUS) & ICM_REG_MST_SLV0_NACK);
}

static void test_overrun_flag_from_dor(void **state)
{
    direct_t d;
    icm_sample_t s;
    (void)state;
    direct_setup(&d);
    icmm_set_noise(&d.icm, 60, 11);
    assert_int_equal(run_init(&d.dev, &d.fb, NULL), 0);
    assert_int_equal(read_new(&d.dev, &d.fb, &s), 0);
    /* stop the master for 25 ms: the AK overwrites unread samples */
    d.icm.regs[3][ICM_REG_I2C_SLV0_CTRL] &= (uint8_t)~ICM_REG_SLV_CTRL_EN;
    icm_fake_bus_sleep_us(&d.fb, 25000);
    d.icm.regs[3][ICM_REG_I2C_SLV0_CTRL] |= ICM_REG_SLV_CTRL_EN;
    icm_fake_bus_sleep_us(&d.fb, 8000); /* one master period at 137.5 Hz */
    assert_int_equal(read_once(&d.dev, &d.fb, &s), 0);
    assert_true(s.flags & ICM_SAMPLE_NEW);
    assert_true(s.flags & ICM_SAMPLE_OVERRUN);
    assert_int_equal(d.dev.overrun_count, 1);
}

static void test_behind_mux(void **state)
{
    tcam_t mm;
    icmm_t a, b;
    icm_fake_bus_t fb;
    tca_t mux;
    icm_dev_t da, db;
    icm_sample_t s;
    (void)state;
    tcam_init(&mm, 0x70);
    icmm_init(&a, 0x69, 1);
    icmm_init(&b, 0x69, 2); /* same address, other channel */
    icmm_set_field_cuT(&a, 1500, 0, 0);
    icmm_set_field_cuT(&b, -1500, 0, 0);
    assert_int_equal(tcam_attach(&mm, 2, icmm_slave(&a)), 0);
    assert_int_equal(tcam_attach(&mm, 5, icmm_slave(&b)), 0);
    icm_fake_bus_setup(&fb, tcam_slave(&mm));
    assert_int_equal(tca_setup(&mux, &fb.bus, 0x70), 0);
    assert_int_equal(icm_setup(&da, &fb.bus, &mux, 2, 0x69), 0);
    assert_int_equal(icm_setup(&db, &fb.bus, &mux, 5, 0x69), 0);
    assert_int_equal(run_init(&da, &fb, NULL), 0);
    assert_int_equal(run_init(&db, &fb, NULL), 0);
    assert_int_equal(a.resets, 1);
    assert_int_equal(b.resets, 1);
    assert_int_equal(read_new(&da, &fb, &s), 0);
    assert_int_equal(s.raw[0], 100);
    assert_int_equal(mm.ctrl, 1u << 2);
    assert_int_equal(read_new(&db, &fb, &s), 0);
    assert_int_equal(s.raw[0], -100);
    assert_int_equal(mm.ctrl, 1u << 5);
    /* mux missing: the read reports the mux, not the sensor */
    mm.present = 0;
    assert_int_equal(read_once(&da, &fb, &s), ICM_E_MUX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_setup_rejects_bad_args),
        cmocka_unit_test(test_init_configures_device),
        cmocka_unit_test(test_bank_cache_avoids_redundant_selects),
        cmocka_unit_test(test_sample_values_and_flags),
        cmocka_unit_test(test_overflow_sets_hofl),
        cmocka_unit_test(test_rate_every_sample_caught_at_5ms),
        cmocka_unit_test(test_read_wire_time),
        cmocka_unit_test(test_absent_sensor),
        cmocka_unit_test(test_wrong_who_am_i),
        cmocka_unit_test(test_mag_absent_after_retries),
        cmocka_unit_test(test_mag_wrong_id),
        cmocka_unit_test(test_master_hang_recovered_by_retry),
        cmocka_unit_test(test_nack_mid_transfer),
        cmocka_unit_test(test_stuck_bus_recovered),
        cmocka_unit_test(test_stale_data),
        cmocka_unit_test(test_sensor_disappears_after_init),
        cmocka_unit_test(test_magnetometer_disappears_goes_stale),
        cmocka_unit_test(test_overrun_flag_from_dor),
        cmocka_unit_test(test_behind_mux),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
