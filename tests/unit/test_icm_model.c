/*
 * The register-level ICM-20948/AK09916 model itself, through the byte-level
 * bus: the behaviour the driver tests and the virtual bench rely on.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "devices/icm20948_model.h"
#include "icm20948/icm20948_reg.h"
#include "icm_fake_bus.h"

typedef struct {
    icmm_t m;
    icm_fake_bus_t fb;
} rig_t;

static void rig(rig_t *r)
{
    icmm_init(&r->m, 0x68, 42);
    icm_fake_bus_setup(&r->fb, icmm_slave(&r->m));
}

static int8_t wr(rig_t *r, uint8_t reg, uint8_t v)
{
    uint8_t b[2] = {reg, v};
    return r->fb.bus.write(r->fb.bus.ctx, 0x68, b, 2);
}

static uint8_t rd(rig_t *r, uint8_t reg)
{
    uint8_t v = 0;
    assert_int_equal(r->fb.bus.write_read(r->fb.bus.ctx, 0x68, &reg, 1, &v, 1), 0);
    return v;
}

static void bank(rig_t *r, uint8_t b)
{
    assert_int_equal(wr(r, ICM_REG_BANK_SEL, (uint8_t)(b << 4)), 0);
}

/* One SLV4 transfer with the AK09916, waiting for SLV4_DONE; returns the
 * status byte. */
static uint8_t slv4(rig_t *r, uint8_t read, uint8_t reg, uint8_t val, uint8_t *di)
{
    uint8_t st = 0;
    int i;
    bank(r, 3);
    assert_int_equal(wr(r, ICM_REG_I2C_SLV4_ADDR, (uint8_t)(0x0C | (read ? 0x80 : 0))), 0);
    assert_int_equal(wr(r, ICM_REG_I2C_SLV4_REG, reg), 0);
    assert_int_equal(wr(r, ICM_REG_I2C_SLV4_DO, val), 0);
    assert_int_equal(wr(r, ICM_REG_I2C_SLV4_CTRL, 0x80), 0);
    bank(r, 0);
    for (i = 0; i < 20 && !(st & ICM_REG_MST_SLV4_DONE); i++) {
        icm_fake_bus_sleep_us(&r->fb, 50);
        st = rd(r, ICM_REG_I2C_MST_STATUS);
    }
    if (di != NULL) {
        bank(r, 3);
        *di = rd(r, ICM_REG_I2C_SLV4_DI);
        bank(r, 0);
    }
    return st;
}

static void wake_master(rig_t *r)
{
    assert_int_equal(wr(r, ICM_REG_PWR_MGMT_1, 0x01), 0);
    assert_int_equal(wr(r, ICM_REG_USER_CTRL, ICM_REG_USER_I2C_MST_EN), 0);
    icm_fake_bus_sleep_us(&r->fb, 1000);
}

static void test_address_who_am_i_and_banks(void **state)
{
    rig_t r;
    uint8_t v;
    (void)state;
    rig(&r);
    /* wrong address: NACK */
    assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x69, &v, 0), ICM_BUS_E_ADDR_NACK);
    assert_int_equal(rd(&r, ICM_REG_WHO_AM_I), 0xEA);
    assert_int_equal(rd(&r, ICM_REG_PWR_MGMT_1), 0x41); /* reset value: asleep */
    assert_int_equal(rd(&r, ICM_REG_LP_CONFIG), 0x40);
    /* bank 3 register 0x01 is I2C_MST_CTRL, bank 0 0x01 is something else */
    bank(&r, 3);
    assert_int_equal(wr(&r, ICM_REG_I2C_MST_CTRL, 0x17), 0);
    assert_int_equal(rd(&r, ICM_REG_BANK_SEL), 0x30);
    assert_int_equal(rd(&r, ICM_REG_I2C_MST_CTRL), 0x17);
    bank(&r, 0);
    assert_int_equal(rd(&r, 0x01), 0x00);
    /* WHO_AM_I is read-only */
    assert_int_equal(wr(&r, ICM_REG_WHO_AM_I, 0x00), 0);
    assert_int_equal(rd(&r, ICM_REG_WHO_AM_I), 0xEA);
    /* burst write auto-increments */
    {
        uint8_t b[4] = {ICM_REG_I2C_SLV0_ADDR, 0x8C, 0x10, 0x89};
        bank(&r, 3);
        assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x68, b, 4), 0);
        assert_int_equal(icmm_peek(&r.m, 3, ICM_REG_I2C_SLV0_REG), 0x10);
        assert_int_equal(icmm_peek(&r.m, 3, ICM_REG_I2C_SLV0_CTRL), 0x89);
    }
}

static void test_device_reset(void **state)
{
    rig_t r;
    int8_t rc;
    uint8_t reg = ICM_REG_WHO_AM_I, v;
    (void)state;
    rig(&r);
    wake_master(&r);
    bank(&r, 3);
    assert_int_equal(wr(&r, ICM_REG_I2C_MST_CTRL, 0x17), 0);
    bank(&r, 0);
    assert_int_equal(wr(&r, ICM_REG_PWR_MGMT_1, ICM_REG_PWR_DEVICE_RST), 0);
    /* resetting: no ACK */
    rc = r.fb.bus.write_read(r.fb.bus.ctx, 0x68, &reg, 1, &v, 1);
    assert_int_equal(rc, ICM_BUS_E_ADDR_NACK);
    icm_fake_bus_sleep_us(&r.fb, ICMM_RESET_US);
    /* back: registers at reset values, bank 0, asleep */
    assert_int_equal(rd(&r, ICM_REG_PWR_MGMT_1), 0x41);
    assert_int_equal(rd(&r, ICM_REG_USER_CTRL), 0);
    assert_int_equal(rd(&r, ICM_REG_BANK_SEL), 0);
    assert_int_equal(icmm_peek(&r.m, 3, ICM_REG_I2C_MST_CTRL), 0);
    assert_int_equal(r.m.resets, 1);
}

static void test_slv4_and_status_clear_on_read(void **state)
{
    rig_t r;
    uint8_t di = 0;
    uint8_t st;
    (void)state;
    rig(&r);
    /* master not enabled: SLV4 never completes */
    st = slv4(&r, 1, AK_REG_WIA2, 0, NULL);
    assert_false(st & ICM_REG_MST_SLV4_DONE);
    wake_master(&r);
    assert_int_equal(wr(&r, ICM_REG_USER_CTRL, 0x22), 0); /* reset the stuck transfer */
    st = slv4(&r, 1, AK_REG_WIA2, 0, &di);
    assert_int_equal(st, ICM_REG_MST_SLV4_DONE);
    assert_int_equal(di, 0x09);
    assert_int_equal(rd(&r, ICM_REG_I2C_MST_STATUS), 0); /* cleared by the read */
    assert_int_equal(icmm_peek(&r.m, 3, ICM_REG_I2C_SLV4_CTRL) & 0x80, 0);
    slv4(&r, 1, AK_REG_WIA1, 0, &di);
    assert_int_equal(di, 0x48);
    /* AK absent: NACK flagged with DONE */
    r.m.ak.present = 0;
    st = slv4(&r, 1, AK_REG_WIA2, 0, NULL);
    assert_int_equal(st, ICM_REG_MST_SLV4_DONE | ICM_REG_MST_SLV4_NACK);
}

static void test_master_hang_until_reset(void **state)
{
    rig_t r;
    (void)state;
    rig(&r);
    wake_master(&r);
    r.m.mst_hang_tries = 1;
    assert_false(slv4(&r, 1, AK_REG_WIA2, 0, NULL) & ICM_REG_MST_SLV4_DONE);
    assert_false(slv4(&r, 1, AK_REG_WIA2, 0, NULL) & ICM_REG_MST_SLV4_DONE); /* still hung */
    assert_int_equal(wr(&r, ICM_REG_USER_CTRL, 0x22), 0);
    assert_true(slv4(&r, 1, AK_REG_WIA2, 0, NULL) & ICM_REG_MST_SLV4_DONE);
}

static void test_ak_drdy_dor_and_st2_release(void **state)
{
    rig_t r;
    uint8_t v = 0;
    (void)state;
    rig(&r);
    wake_master(&r);
    icmm_set_field_cuT(&r.m, 150, -300, 450); /* 10, -20, 30 counts */
    slv4(&r, 0, AK_REG_CNTL2, AK_REG_MODE_CONT_100HZ, NULL);
    slv4(&r, 1, AK_REG_ST1, 0, &v);
    assert_int_equal(v, 0); /* nothing measured yet */
    icm_fake_bus_sleep_us(&r.fb, 10000);
    slv4(&r, 1, AK_REG_ST1, 0, &v);
    assert_int_equal(v, AK_REG_ST1_DRDY);
    /* another period unread: DOR */
    icm_fake_bus_sleep_us(&r.fb, 10000);
    slv4(&r, 1, AK_REG_ST1, 0, &v);
    assert_int_equal(v, AK_REG_ST1_DRDY | AK_REG_ST1_DOR);
    /* reading a data register clears both and holds the data */
    slv4(&r, 1, AK_REG_HXL, 0, &v);
    assert_int_equal(v, 10);
    slv4(&r, 1, AK_REG_ST1, 0, &v);
    assert_int_equal(v, 0);
    /* a sample completing while held waits for the ST2 read */
    icmm_set_field_cuT(&r.m, 1500, 0, 0);
    icm_fake_bus_sleep_us(&r.fb, 10000);
    slv4(&r, 1, AK_REG_HXL, 0, &v);
    assert_int_equal(v, 10); /* old sample still */
    slv4(&r, 1, AK_REG_ST2, 0, &v);
    assert_int_equal(v, 0);
    slv4(&r, 1, AK_REG_ST1, 0, &v);
    assert_int_equal(v, AK_REG_ST1_DRDY); /* released by the ST2 read */
    slv4(&r, 1, AK_REG_HXL, 0, &v);
    assert_int_equal(v, 100);
    /* soft reset: power-down, data cleared */
    slv4(&r, 0, AK_REG_CNTL3, AK_REG_CNTL3_SRST, NULL);
    icm_fake_bus_sleep_us(&r.fb, AKM_SRST_US);
    slv4(&r, 1, AK_REG_CNTL2, 0, &v);
    assert_int_equal(v, 0);
}

static void test_slv0_snapshot_and_hofl(void **state)
{
    rig_t r;
    uint8_t b[9];
    uint8_t reg = ICM_REG_EXT_SLV_SENS_DATA_00;
    uint8_t slv0[4] = {ICM_REG_I2C_SLV0_ADDR, 0x8C, AK_REG_ST1, 0x89};
    (void)state;
    rig(&r);
    wake_master(&r);
    slv4(&r, 0, AK_REG_CNTL2, AK_REG_MODE_CONT_100HZ, NULL);
    bank(&r, 3);
    assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x68, slv0, 4), 0);
    bank(&r, 0);
    /* beyond full scale on X: saturated counts and HOFL */
    icmm_set_field_cuT(&r.m, 500000, -15, 0);
    icm_fake_bus_sleep_us(&r.fb, 11000); /* sample at 10 ms, then one master read */
    assert_int_equal(r.fb.bus.write_read(r.fb.bus.ctx, 0x68, &reg, 1, b, 9), 0);
    assert_int_equal(b[1] | (b[2] << 8), 0x7FF0); /* 32752 */
    assert_int_equal((int16_t)(b[3] | (b[4] << 8)), -1);
    assert_int_equal(b[8], AK_REG_ST2_HOFL);
    assert_true(r.m.slv0_reads >= 10u); /* 1.1 kHz master */
    /* quantization: nearest count, half away from zero */
    {
        uint8_t sat = 0;
        assert_int_equal(akm_quantize(7, &sat), 0);
        assert_int_equal(akm_quantize(8, &sat), 1);
        assert_int_equal(akm_quantize(-8, &sat), -1);
        assert_int_equal(akm_quantize(491280, &sat), 32752);
        assert_int_equal(sat, 0);
        assert_int_equal(akm_quantize(491288, &sat), 32752);
        assert_int_equal(sat, 1);
    }
}

/* Back-to-back burst reads across many master updates (X = Y = Z here):
 * with DELAY_ES_SHADOW every block is one sample; without it a read that
 * starts while the SLV0 bytes arrive sees half old and half new. */
static int burst_reads(uint8_t delay_ctrl, int *torn)
{
    rig_t r;
    uint8_t b[9];
    uint8_t reg = ICM_REG_EXT_SLV_SENS_DATA_00;
    uint8_t slv0[4] = {ICM_REG_I2C_SLV0_ADDR, 0x8C, AK_REG_ST1, 0x89};
    uint8_t dly[2] = {ICM_REG_I2C_MST_DELAY_CTRL, delay_ctrl};
    int i, changes = 0;
    int16_t prev = 0;
    rig(&r);
    wake_master(&r);
    slv4(&r, 0, AK_REG_CNTL2, AK_REG_MODE_CONT_100HZ, NULL);
    bank(&r, 3);
    assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x68, slv0, 4), 0);
    assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x68, dly, 2), 0);
    bank(&r, 0);
    *torn = 0;
    for (i = 0; i < 1000; i++) {
        int32_t k = (int32_t)(icm_fake_bus_now_us(&r.fb) / 10000u) * 150;
        int16_t x, y, z;
        icmm_set_field_cuT(&r.m, k, k, k);
        assert_int_equal(r.fb.bus.write_read(r.fb.bus.ctx, 0x68, &reg, 1, b, 9), 0);
        x = (int16_t)(b[1] | (b[2] << 8));
        y = (int16_t)(b[3] | (b[4] << 8));
        z = (int16_t)(b[5] | (b[6] << 8));
        *torn += (x != y || x != z);
        changes += (x != prev);
        prev = x;
    }
    /* the model also counts tears that only touch ST1 or ST2 */
    assert_true((uint32_t)*torn <= r.m.torn_reads);
    assert_true(*torn > 0 || r.m.torn_reads == 0);
    return changes;
}

static void test_burst_read_is_one_sample(void **state)
{
    int torn;
    (void)state;
    assert_true(burst_reads(ICM_REG_DELAY_ES_SHADOW, &torn) > 20); /* data did change */
    assert_int_equal(torn, 0);
    assert_true(burst_reads(0, &torn) > 20);
    assert_true(torn > 0);
}

static void test_noise_is_seeded_and_sized(void **state)
{
    rig_t a, b;
    int i;
    int64_t s = 0, s2 = 0;
    (void)state;
    rig(&a);
    rig(&b);
    icmm_set_noise(&a.m, 300, 7);
    icmm_set_noise(&b.m, 300, 7);
    a.m.ak.mode = b.m.ak.mode = AK_REG_MODE_CONT_100HZ;
    a.m.ak.next_meas_us = b.m.ak.next_meas_us = 10000;
    for (i = 0; i < 1000; i++) {
        int16_t x;
        icmm_advance(&a.m, (uint64_t)(i + 1) * 10000u);
        icmm_advance(&b.m, (uint64_t)(i + 1) * 10000u);
        assert_memory_equal(a.m.ak.data, b.m.ak.data, 6); /* same seed, same noise */
        x = (int16_t)(a.m.ak.data[0] | (a.m.ak.data[1] << 8));
        s += x;
        s2 += (int64_t)x * x;
    }
    assert_int_equal(a.m.ak.samples, 1000);
    /* sigma 300 cuT = 20 counts: variance ~400 counts^2, mean ~0 */
    assert_in_range(s / 1000 + 5, 3, 7);
    assert_in_range(s2 / 1000, 340, 460);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_address_who_am_i_and_banks),
        cmocka_unit_test(test_device_reset),
        cmocka_unit_test(test_slv4_and_status_clear_on_read),
        cmocka_unit_test(test_master_hang_until_reset),
        cmocka_unit_test(test_ak_drdy_dor_and_st2_release),
        cmocka_unit_test(test_slv0_snapshot_and_hofl),
        cmocka_unit_test(test_burst_read_is_one_sample),
        cmocka_unit_test(test_noise_is_seeded_and_sized),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
