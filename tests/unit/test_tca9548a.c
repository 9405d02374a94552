/*
 * tca9548a: the mux driver's channel cache and errors, and the mux model's
 * routing (including why unused channels must be off).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "devices/icm20948_model.h"
#include "devices/tca9548a_model.h"
#include "icm20948/icm20948_reg.h"
#include "icm20948/tca9548a.h"
#include "icm_fake_bus.h"

typedef struct {
    tcam_t mm;
    icmm_t a, b;
    icm_fake_bus_t fb;
    tca_t mux;
} rig_t;

static void rig_setup(rig_t *r)
{
    tcam_init(&r->mm, 0x70);
    icmm_init(&r->a, 0x69, 1);
    icmm_init(&r->b, 0x69, 2);
    r->a.who_am_i = 0xEA;
    r->b.who_am_i = 0x3C; /* differs in bits 7, 6, 1 */
    assert_int_equal(tcam_attach(&r->mm, 0, icmm_slave(&r->a)), 0);
    assert_int_equal(tcam_attach(&r->mm, 6, icmm_slave(&r->b)), 0);
    icm_fake_bus_setup(&r->fb, tcam_slave(&r->mm));
    assert_int_equal(tca_setup(&r->mux, &r->fb.bus, 0x70), 0);
}

static uint8_t read_who(rig_t *r, int8_t *rc)
{
    uint8_t reg = ICM_REG_WHO_AM_I;
    uint8_t v = 0;
    *rc = r->fb.bus.write_read(r->fb.bus.ctx, 0x69, &reg, 1, &v, 1);
    return v;
}

static void test_args(void **state)
{
    rig_t r;
    (void)state;
    rig_setup(&r);
    assert_int_equal(tca_setup(NULL, &r.fb.bus, 0x70), TCA_E_ARG);
    assert_int_equal(tca_setup(&r.mux, NULL, 0x70), TCA_E_ARG);
    assert_int_equal(tca_setup(&r.mux, &r.fb.bus, 0x6F), TCA_E_ARG);
    assert_int_equal(tca_setup(&r.mux, &r.fb.bus, 0x78), TCA_E_ARG);
    assert_int_equal(tca_setup(&r.mux, &r.fb.bus, 0x77), 0);
    assert_int_equal(tca_select(&r.mux, 8), TCA_E_ARG);
    assert_int_equal(tca_select(NULL, 0), TCA_E_ARG);
    assert_int_equal(tca_disable_all(NULL), TCA_E_ARG);
    assert_int_equal(r.fb.transfers, 0);
}

static void test_select_caches_and_isolates(void **state)
{
    rig_t r;
    int8_t rc;
    (void)state;
    rig_setup(&r);
    /* power-on: all channels off, nobody answers at 0x69 */
    (void)read_who(&r, &rc);
    assert_int_equal(rc, ICM_BUS_E_ADDR_NACK);
    assert_int_equal(tca_select(&r.mux, 0), 0);
    assert_int_equal(r.mm.ctrl, 0x01);
    assert_int_equal(read_who(&r, &rc), 0xEA);
    assert_int_equal(rc, 0);
    /* same channel again: no bus traffic */
    assert_int_equal(tca_select(&r.mux, 0), 0);
    assert_int_equal(r.mux.writes, 1);
    assert_int_equal(r.mm.ctrl_writes, 1);
    /* another channel: only that one is on */
    assert_int_equal(tca_select(&r.mux, 6), 0);
    assert_int_equal(r.mm.ctrl, 0x40);
    assert_int_equal(read_who(&r, &rc), 0x3C);
    assert_int_equal(tca_disable_all(&r.mux), 0);
    assert_int_equal(r.mm.ctrl, 0);
    (void)read_who(&r, &rc);
    assert_int_equal(rc, ICM_BUS_E_ADDR_NACK);
    /* after disable_all the cache knows channel 6 is off */
    assert_int_equal(tca_select(&r.mux, 6), 0);
    assert_int_equal(r.mux.writes, 4);
}

static void test_two_channels_on_collide(void **state)
{
    rig_t r;
    int8_t rc;
    uint8_t both = 0x41;
    (void)state;
    rig_setup(&r);
    /* what the driver never does: two channels with the same address on */
    assert_int_equal(r.fb.bus.write(r.fb.bus.ctx, 0x70, &both, 1), 0);
    /* open-drain wired AND of 0xEA and 0x3C */
    assert_int_equal(read_who(&r, &rc), 0xEA & 0x3C);
}

static void test_errors_invalidate_cache(void **state)
{
    rig_t r;
    (void)state;
    rig_setup(&r);
    r.mm.present = 0;
    assert_int_equal(tca_select(&r.mux, 0), TCA_E_ABSENT);
    assert_false(r.mux.valid);
    r.mm.present = 1;
    r.fb.nack_at_byte = 1;
    assert_int_equal(tca_select(&r.mux, 0), TCA_E_NACK);
    r.fb.timeouts = 1;
    assert_int_equal(tca_select(&r.mux, 0), TCA_E_TIMEOUT);
    r.fb.stuck_sda = 1;
    assert_int_equal(tca_select(&r.mux, 0), TCA_E_BUS);
    r.fb.stuck_sda = 0;
    assert_int_equal(r.mux.errors, 4);
    assert_int_equal(tca_select(&r.mux, 0), 0);
    assert_true(r.mux.valid);
    assert_int_equal(r.mm.ctrl, 0x01);
    /* invalidation forces a rewrite even for the same channel */
    tca_invalidate(&r.mux);
    assert_int_equal(tca_select(&r.mux, 0), 0);
    assert_int_equal(r.mm.ctrl_writes, 2);
}

static void test_model_control_readback(void **state)
{
    rig_t r;
    uint8_t v = 0;
    (void)state;
    rig_setup(&r);
    assert_int_equal(tca_select(&r.mux, 3), 0);
    assert_int_equal(r.fb.bus.write_read(r.fb.bus.ctx, 0x70, NULL, 0, &v, 1), 0);
    assert_int_equal(v, 0x08);
    assert_int_equal(tcam_attach(&r.mm, 8, icmm_slave(&r.a)), -1);
    assert_int_equal(tcam_attach(&r.mm, 0, icmm_slave(&r.b)), 0);
    assert_int_equal(tcam_attach(&r.mm, 0, icmm_slave(&r.b)), -1); /* full */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_args),
        cmocka_unit_test(test_select_caches_and_isolates),
        cmocka_unit_test(test_two_channels_on_collide),
        cmocka_unit_test(test_errors_invalidate_cache),
        cmocka_unit_test(test_model_control_readback),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
