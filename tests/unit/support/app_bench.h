/*
 * app_bench: a native board for lib/app. The real modules run against the
 * device models: XL430 servos on the simulated DYNAMIXEL bus (dxl_fakebus),
 * ICM-20948s behind a TCA9548A on the simulated I2C bus (icm_fake_bus), a RAM
 * EEPROM (store_fake), a byte console (con_fake), and the robot plant
 * (sim/plant) that turns the servo shafts into tip motion and field.
 *
 * Time: one bench clock in microseconds. Each app_bench_step() charges one
 * main-loop pass (loop_us, APP_BENCH_LOOP_US by default, plus the I2C wire
 * time the pass used),
 * brings the servo bus and the plant to that time and runs app_poll().
 */
#ifndef HALLHOME_APP_BENCH_H
#define HALLHOME_APP_BENCH_H

#include <stdint.h>

#include "app/app.h"
#include "con_fake.h"
#include "devices/icm20948_model.h"
#include "devices/tca9548a_model.h"
#include "devices/xl430_model.h"
#include "dxl_fakebus.h"
#include "icm_fake_bus.h"
#include "plant/plant.h"
#include "store_fake.h"

#ifndef APP_BENCH_LOOP_US
#define APP_BENCH_LOOP_US 150u
#endif /* cost charged per main-loop pass */

typedef struct {
    /* devices */
    dxl_fakebus bus;
    xl430 servo[TBL_MAX_TENDONS];
    uint8_t servo_attached[TBL_MAX_TENDONS];
    tcam_t mux;
    icmm_t icm[TBL_MAX_SENSORS];
    icm_fake_bus_t i2c;
    store_fake_t ee;
    con_fake_t con;
    con_rt_t rt;
    /* robot */
    plant_cfg_t cfg;
    tbl_wide_t table;    /* the robot's table in natural units */
    tbl_buf_t table_buf; /* the same packed: what the app reads */
    plant_t plant;
    uint8_t weight_on; /* a weight pulls tendon weight_tendon to weight_ticks */
    uint8_t weight_tendon;
    double weight_ticks;
    double shaft0[TBL_MAX_TENDONS]; /* shaft angle at the plant's motor tick 0 */
    /* board */
    uint64_t now_us;
    uint32_t loop_us; /* cost of one pass (the AVR needs about 2 ms) */
    uint32_t last_plant_ms;
    uint8_t button;
    uint8_t led;
    uint32_t led_changes;
    uint32_t kicks;
    uint32_t reboots;
    /* servo bus noise: each byte the master sends or receives has one bit
     * flipped with probability noise (a seeded generator) */
    double noise;
    uint64_t noise_seed;
    uint32_t noise_hits;
    dxl_port bus_port; /* the fake bus's own port, under the noise */
    /* the next lose_goal_writes sync writes of goals (profile, velocity and
     * position from Profile Acceleration on) reach the servos with a bit of
     * their CRC flipped: every servo drops them */
    uint8_t lose_goal_writes;
    /* the same for the next lose_position_writes sync writes of Goal Position
     * alone (the early release after a reset) */
    uint8_t lose_position_writes;
    /* the app */
    app_board_t board;
    con_io_t con_io;
    app_win_t win;     /* the board's kept engagement windows */
    uint8_t wdt_reset; /* the next app_bench_restart() is a watchdog reset (io.release_at_boot) */
    app_io_t io;
    app_t app;
} app_bench_t;

/* Loads the paper robot and its plant-made table, wires everything, powers
 * the devices up and calls app_init(). table 0: no table (io.table NULL).
 * Returns 0 or a negative error. */
int app_bench_init(app_bench_t *b, uint8_t with_table);

/* The board restarts (watchdog, reset button): app_init() again with the
 * same devices, EEPROM and robot. power_cycle also power cycles the servos
 * (multi-turn counts lost). */
void app_bench_restart(app_bench_t *b, uint8_t power_cycle);

/* One main-loop pass. */
void app_bench_step(app_bench_t *b);

/* Runs passes for ms of bench time. */
void app_bench_run_ms(app_bench_t *b, uint32_t ms);

/* Runs until an output line starting with prefix appears (copied into line,
 * capacity cap) or ms passed. Lines before it are dropped. Returns 1 when
 * found. */
int app_bench_wait_line(app_bench_t *b, const char *prefix, char *line, size_t cap, uint32_t ms);

/* Sends a console line (CR LF appended). */
void app_bench_send(app_bench_t *b, const char *line);

/* Spool tension of tendon i in newtons (ground truth). */
double app_bench_tension(const app_bench_t *b, uint8_t i);

/* Integer value of key=... in a report line, or def when absent. */
long app_bench_field(const char *line, const char *key, long def);

/* tbl_copy_fn for the bench's app instance (learned targets applied). */
void app_bench_copy_learned(void *dst, const void *src, size_t n);

#endif /* HALLHOME_APP_BENCH_H */
