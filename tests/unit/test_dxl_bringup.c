/*
 * dxl bring-up against XL430 models on a simulated bus (configuration,
 * EEPROM writes only where needed, missing IDs, other models, hardware
 * errors), and the XL430 model on its own (multi-turn, Bus Watchdog, status
 * return level, duplicate IDs).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "dxl/dxl.h"
#include "dxl/dxl_xl430_reg.h"
#include "dxl_rig.h"

#define N_SERVOS DXL_RIG_SERVOS

static dxl_rig R;

static int8_t run(void)
{
    return dxl_rig_run(&R);
}

/* --- bring-up -------------------------------------------------------------------- */

static dxl_bringup B;

static dxl_bringup_config bu_config(void)
{
    dxl_bringup_config c = {20, 100, 0, 30000};
    return c;
}

static void test_bringup_configures_every_servo(void **state)
{
    (void)state;
    dxl_rig_init(&R, N_SERVOS, 250);
    const uint8_t ids[N_SERVOS] = {1, 2, 3, 4, 5, 6};
    dxl_bringup_config c = bu_config();
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, N_SERVOS, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), 0);
    assert_int_equal(B.n_missing, 0);
    assert_int_equal(B.n_wrong_model, 0);
    for (uint8_t i = 0; i < N_SERVOS; i++) {
        const xl430 *s = &R.servo[i];
        assert_int_equal(B.servo[i].present, 1);
        assert_int_equal(B.servo[i].model, 1060);
        assert_int_equal(B.servo[i].model_ok, 1);
        assert_int_equal(B.servo[i].position, 100 * (i + 1));
        assert_int_equal(xl430_get(s, DXL_XL430_RETURN_DELAY_ADDR, 1), 0);
        assert_int_equal(xl430_get(s, DXL_XL430_OPERATING_MODE_ADDR, 1), 4);
        assert_int_equal(xl430_get(s, DXL_XL430_TORQUE_ENABLE_ADDR, 1), 1);
        assert_int_equal(xl430_get(s, DXL_XL430_PROFILE_ACCELERATION_ADDR, 4), 20);
        assert_int_equal(xl430_get(s, DXL_XL430_PROFILE_VELOCITY_ADDR, 4), 100);
        /* factory return delay 250 and position mode: both rewritten once */
        assert_int_equal(B.servo[i].return_delay, 250);
        assert_int_equal(B.servo[i].mode, DXL_XL430_MODE_POSITION);
        assert_int_equal(B.servo[i].eeprom_writes, 2);
        assert_int_equal(s->eeprom_writes, 2);
    }
    assert_int_equal(R.bus.collisions, 0);
    assert_int_equal(dxl_bringup_poll(&B), 0);
}

/* The next boot finds the EEPROM fields set and writes none of them; a servo
 * with only one field off gets only that one. */
static void test_bringup_skips_eeprom_writes_already_done(void **state)
{
    (void)state;
    dxl_rig_init(&R, 3, 250);
    const uint8_t ids[3] = {1, 2, 3};
    dxl_bringup_config c = bu_config();
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 3, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), 0);
    for (uint8_t i = 0; i < 3; i++) {
        assert_int_equal(R.servo[i].eeprom_writes, 2);
        xl430_power_cycle(&R.servo[i], R.bus.now);
    }
    /* servo 3 was switched back to position mode by someone else */
    R.servo[2].ct[DXL_XL430_OPERATING_MODE_ADDR] = DXL_XL430_MODE_POSITION;
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 3, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), 0);
    for (uint8_t i = 0; i < 3; i++) {
        const xl430 *s = &R.servo[i];
        assert_int_equal(B.servo[i].return_delay, 0);
        assert_int_equal(xl430_get(s, DXL_XL430_OPERATING_MODE_ADDR, 1), DXL_XL430_MODE_EXTENDED);
        assert_int_equal(xl430_get(s, DXL_XL430_TORQUE_ENABLE_ADDR, 1), 1);
        assert_int_equal(xl430_get(s, DXL_XL430_PROFILE_VELOCITY_ADDR, 4), 100);
    }
    assert_int_equal(B.servo[0].eeprom_writes, 0);
    assert_int_equal(B.servo[1].eeprom_writes, 0);
    assert_int_equal(B.servo[2].eeprom_writes, 1);
    assert_int_equal(R.servo[0].eeprom_writes, 2);
    assert_int_equal(R.servo[1].eeprom_writes, 2);
    assert_int_equal(R.servo[2].eeprom_writes, 3);
}

/* A servo that answers the configuration read with too few bytes stops the
 * bring-up instead of being configured from garbage. */
static void test_bringup_read_error_stops(void **state)
{
    (void)state;
    dxl_rig_init(&R, 1, 0);
    const uint8_t ids[1] = {1};
    dxl_bringup_config c = bu_config();
    R.servo[0].ct[DXL_XL430_STATUS_RETURN_LEVEL_ADDR] = 0; /* answers ping only */
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 1, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), -DXL_E_TIMEOUT);
    assert_int_equal(R.servo[0].eeprom_writes, 0);
}

static void test_bringup_reports_missing_ids_by_number(void **state)
{
    (void)state;
    dxl_rig_init(&R, 4, 0);
    const uint8_t ids[6] = {1, 7, 2, 3, 4, 12};
    dxl_bringup_config c = bu_config();
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 6, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), -DXL_E_MISSING);
    assert_int_equal(B.n_missing, 2);
    assert_int_equal(B.missing[0], 7);
    assert_int_equal(B.missing[1], 12);
    /* nothing was configured before every servo was found */
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_TORQUE_ENABLE_ADDR, 1), 0);
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_RETURN_DELAY_ADDR, 1), 0);
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_OPERATING_MODE_ADDR, 1), 3);
}

static void test_bringup_warns_on_other_model(void **state)
{
    (void)state;
    dxl_rig_init(&R, 2, 0);
    R.servo[1].ct[0] = 0x2E; /* 1070: XL430-W250 is 1060 */
    R.servo[1].ct[1] = 0x04;
    const uint8_t ids[2] = {1, 2};
    dxl_bringup_config c = bu_config();
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 2, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), 0);
    assert_int_equal(B.servo[1].model, 1070);
    assert_int_equal(B.servo[1].model_ok, 0);
    assert_int_equal(B.n_wrong_model, 1);
}

static void test_bringup_hw_error_without_and_with_reboot(void **state)
{
    (void)state;
    dxl_rig_init(&R, 3, 0);
    xl430_inject_hw_error(&R.servo[1], DXL_XL430_HW_ERR_OVERHEATING);
    const uint8_t ids[3] = {1, 2, 3};
    dxl_bringup_config c = bu_config();
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 3, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), -DXL_E_HW_ERROR);
    assert_int_equal(B.servo[1].alert, 1);
    assert_int_equal(B.servo[1].hw_error, DXL_XL430_HW_ERR_OVERHEATING);
    assert_int_equal(B.servo[1].rebooted, 0);
    assert_int_equal(xl430_get(&R.servo[1], DXL_XL430_HW_ERROR_ADDR, 1),
                     DXL_XL430_HW_ERR_OVERHEATING);

    c.reboot_on_hw_error = 1;
    assert_int_equal(dxl_bringup_start(&B, &R.m, ids, 3, &c), 1);
    assert_int_equal(dxl_fakebus_run_bringup(&R.bus, &B, 2000000), 0);
    assert_int_equal(B.servo[1].rebooted, 1);
    assert_int_equal(B.servo[1].hw_error, 0);
    assert_int_equal(B.servo[0].rebooted, 0);
    assert_int_equal(xl430_get(&R.servo[1], DXL_XL430_TORQUE_ENABLE_ADDR, 1), 1);
    assert_int_equal(B.servo[1].position, 200);
}

static void test_bringup_arguments(void **state)
{
    (void)state;
    dxl_rig_init(&R, 1, 0);
    dxl_bringup_config c = bu_config();
    const uint8_t bad[2] = {1, 0xFE};
    assert_int_equal(dxl_bringup_start(&B, &R.m, bad, 2, &c), -DXL_E_ARG);
    assert_int_equal(dxl_bringup_start(&B, &R.m, bad, 0, &c), -DXL_E_ARG);
    assert_int_equal(dxl_ping(&R.m, 1), 1);
    assert_int_equal(dxl_bringup_start(&B, &R.m, bad, 1, &c), -DXL_E_BUSY);
}

/* --- the model on its own ------------------------------------------------------------ */

static void test_model_multiturn_lost_at_power_cycle(void **state)
{
    (void)state;
    dxl_rig_init(&R, 1, 0);
    xl430 *s = &R.servo[0];
    assert_int_equal(xl430_present_position(s), 100);
    s->ct[DXL_XL430_OPERATING_MODE_ADDR] = DXL_XL430_MODE_EXTENDED;
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_TORQUE_ENABLE_ADDR, 1, 1), 1);
    assert_int_equal(run(), 0);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_GOAL_POSITION_ADDR, 100 + 3 * 4096, 4), 1);
    assert_int_equal(run(), 0);
    dxl_fakebus_advance(&R.bus, 3000000);
    assert_int_equal(xl430_present_position(s), 100 + 3 * 4096);
    xl430_power_cycle(s, R.bus.now);
    assert_int_equal(xl430_present_position(s), 100);
    assert_true(xl430_shaft_ticks(s) == 4096.0 * 5 + 100.0);
    assert_int_equal(xl430_get(s, DXL_XL430_TORQUE_ENABLE_ADDR, 1), 0);
}

static void test_model_bus_watchdog(void **state)
{
    (void)state;
    dxl_rig_init(&R, 1, 0);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_TORQUE_ENABLE_ADDR, 1, 1), 1);
    assert_int_equal(run(), 0);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_BUS_WATCHDOG_ADDR, 5, 1), 1); /* 100 ms */
    assert_int_equal(run(), 0);
    dxl_fakebus_advance(&R.bus, 90000);
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_BUS_WATCHDOG_ADDR, 1), 5);
    dxl_fakebus_advance(&R.bus, 20000);
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_BUS_WATCHDOG_ADDR, 1), 0xFF);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_GOAL_POSITION_ADDR, 300, 4), 1);
    assert_int_equal(run(), -DXL_E_SERVO);
    assert_int_equal(dxl_reply_for(&R.m, 1)->err, DXL_ERR_DATA_RANGE);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_BUS_WATCHDOG_ADDR, 0, 1), 1);
    assert_int_equal(run(), 0);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_GOAL_POSITION_ADDR, 300, 4), 1);
    assert_int_equal(run(), 0);
}

static void test_model_status_return_level(void **state)
{
    (void)state;
    dxl_rig_init(&R, 1, 0);
    R.m.cfg.retries = 0;
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_STATUS_RETURN_LEVEL_ADDR, 1, 1), 1);
    assert_int_equal(run(), 0); /* the reply to this write still follows level 2 */
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_LED_ADDR, 1, 1), 1);
    assert_int_equal(run(), -DXL_E_TIMEOUT);
    assert_int_equal(xl430_get(&R.servo[0], DXL_XL430_LED_ADDR, 1), 1);
    assert_int_equal(dxl_read(&R.m, 1, DXL_XL430_LED_ADDR, 1), 1);
    assert_int_equal(run(), 0);
    assert_int_equal(dxl_write_value(&R.m, 1, DXL_XL430_STATUS_RETURN_LEVEL_ADDR, 0, 1), 1);
    assert_int_equal(run(), -DXL_E_TIMEOUT);
    assert_int_equal(dxl_read(&R.m, 1, DXL_XL430_LED_ADDR, 1), 1);
    assert_int_equal(run(), -DXL_E_TIMEOUT);
    assert_int_equal(dxl_ping(&R.m, 1), 1);
    assert_int_equal(run(), 0);
}

static void test_model_reports_collisions_of_duplicate_ids(void **state)
{
    (void)state;
    dxl_rig_init(&R, 2, 0);
    R.servo[1].ct[DXL_XL430_ID_ADDR] = 1; /* two servos answer to ID 1 */
    assert_int_equal(xl430_transmitting(&R.servo[0], R.bus.now), 0);
    R.m.cfg.retries = 0;
    assert_int_equal(dxl_ping(&R.m, 1), 1);
    dxl_fakebus_run(&R.bus, &R.m, 160); /* request sent, replies starting */
    assert_int_equal(xl430_transmitting(&R.servo[0], R.bus.now + 20u), 1);
    assert_int_equal(xl430_transmitting(&R.servo[1], R.bus.now + 20u), 1);
    run();
    assert_true(R.bus.collisions > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bringup_configures_every_servo),
        cmocka_unit_test(test_bringup_skips_eeprom_writes_already_done),
        cmocka_unit_test(test_bringup_read_error_stops),
        cmocka_unit_test(test_bringup_reports_missing_ids_by_number),
        cmocka_unit_test(test_bringup_warns_on_other_model),
        cmocka_unit_test(test_bringup_hw_error_without_and_with_reboot),
        cmocka_unit_test(test_bringup_arguments),
        cmocka_unit_test(test_model_multiturn_lost_at_power_cycle),
        cmocka_unit_test(test_model_bus_watchdog),
        cmocka_unit_test(test_model_status_return_level),
        cmocka_unit_test(test_model_reports_collisions_of_duplicate_ids),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
