/*
 * app: the hallhome product on one board. Press the button, every tendon is
 * homed, the result is stored and reported.
 *
 * The application wires the portable modules together and runs them from a
 * superloop: app_poll() is called as often as possible and each call does
 * one bounded step of every task, in this order:
 *   1. watchdog kick, realtime stop (`!`) and button (debounced: a short
 *      press calibrates, or quick re-homes when that is offered after a power
 *      cycle; a press held for APP_LONG_PRESS_MS aborts and releases);
 *   2. sensors: one icm_set_poll() step, new samples taken;
 *   3. servos: one dxl_poll(); when the bus is free, the next transaction
 *      (torque, then goals, then hardware-error or position sync reads);
 *   4. homing: hom_step() on the newest samples and positions, its goals
 *      queued for the bus, its events turned into console reports;
 *      app-driven moves (`home`, `release`) and `learn` captures;
 *   5. console: con_poll() (commands are handled by the app_* handlers);
 *   6. store: one EEPROM byte per call, only while no motion runs;
 *   7. LED pattern, and the loop time (the longest is shown by `status`).
 *
 * Boot: app_init() prints `<boot ...>`, loads settings, homes and learned
 * targets and checks the table; the first app_poll() calls bring the servo bus
 * up (ping, extended-position mode) and the sensors (WHO_AM_I, AK09916) and,
 * once every device answered or APP_PREFLIGHT_MS passed, report each missing
 * device and `<ready ...>`. Stored homes of this table are recovered into the
 * servos' new frame (store_recover_position); when that works for every
 * tendon a quick re-home is offered (`rehome=1`).
 *
 * The app never includes firmware headers: the board is reached through
 * app_board_t, and every bus through the modules' own port interfaces, so the
 * same code runs natively in tests against the device models.
 *
 * Report formats and the learn procedure: docs/app.md.
 *
 * Error convention: 0 = done, negative = APP_E_* or a console CON_E_* code,
 * positive = in progress.
 */
#ifndef HALLHOME_APP_H
#define HALLHOME_APP_H

#include <stddef.h>
#include <stdint.h>

#include "console/console.h"
#include "dxl/dxl.h"
#include "homing/homing.h"
#include "icm20948/icm_set.h"
#include "store/store.h"
#include "table/table.h"

/* Sensor slots the app reserves (77 bytes each in the firmware): as many as a
 * run can use; a table with more sensors is refused at boot with "no valid
 * lookup table". */
#define APP_MAX_SENSORS HOM_MAX_SENSORS
/* Tendons the app keeps state for (sized to the robot's table in a firmware
 * built for one, HOM_MAX_TENDONS); a table with more is refused at boot the
 * same way. */
#define APP_MAX_TENDONS HOM_MAX_TENDONS

#define APP_DEBOUNCE_MS     30u    /* the button level must hold this long */
#define APP_LONG_PRESS_MS   2000u  /* held this long: abort and release */
#define APP_PREFLIGHT_MS    3000u  /* boot: longest wait for every device */
#define APP_MOVE_TIMEOUT_MS 10000u /* `home` / `release` moves */
#define APP_MOVE_TOL_TICKS  3      /* a move has arrived within this */
#define APP_LEARN_SAMPLES   16u    /* samples averaged by `learn` and the baseline */
#define APP_HWERR_EVERY     8u     /* read Hardware Error Status every n-th cycle */
#define APP_SERVO_REBOOT_MS 600u   /* wait after `reboot` before the bus is brought up */
#define APP_REBOOT_TRIES    3u     /* reboots of a servo in hardware error before it is named */
#define APP_REBOOT_WAIT     64u    /* bus transactions a reboot waits at most for the other goals */
/* After a reset that cut a run: how long the bring-up waits for the early
 * release (v_release, about 3100 ticks/s) to slacken the tendons; a tendon
 * 150 ticks past engagement is slack after 50 ms, one in the final move
 * (its straight-pose goal, the profile's acceleration) took longer, and the
 * bring-up's torque cycle stopped it taut until the full release after the
 * bring-up: 171-380 ms (chaos seeds 8153, 7421). */
#define APP_EARLY_RELEASE_MS 120u
/* The early release's velocity and goal writes, each sent this many times
 * in turn: a sync write has no reply, and at 1e-3 bus noise one copy of 8
 * servos' goals is lost about once in 20 (chaos seeds 3037: one lost, a
 * tendon taut 308 ms; 21316: two lost, 384 ms). */
#define APP_EARLY_COPIES 3u
#define APP_EARLY_SENT   (2u * APP_EARLY_COPIES + 1u) /* reset_release: all sent, waiting */
#define APP_EARLY_DONE   (APP_EARLY_SENT + 1u)
#define APP_BUS_WATCHDOG                                                                           \
    10u                           /* XL430 Bus Watchdog, 20 ms units: servos stop 200 ms           \
                                       after the last instruction (board hung or reset) */
#define APP_GOAL_REFRESH_EVERY 4u /* send goals not reached again every n-th cycle */
/* A position read that missed a servo (a corrupted reply) is followed by up to
 * this many position reads in a row, ahead of the hardware-error reads and
 * goal refreshes, so one servo's position never goes stale for the homing's
 * servo timeout because of two unlucky bytes; a servo that stays silent still
 * times out, and the other transactions resume. */
#define APP_POS_RETRIES 3u
/* Position reads of the pulled tendon's servo alone between two reads of
 * every servo during a run's take-up and approach (app_bus.c: focus()). */
#define APP_FOCUS_READS 2u
/* A servo whose position has not been read for this long is a fault. The
 * firmware reads positions every 5-13 ms (a pass of the loop took up to about
 * 13 ms when this was chosen, 4 ms now), so 50 ms left room for only four reads,
 * and two corrupted replies in a row at a byte error rate of 1e-3 could end
 * a healthy run; 120 ms is still well inside the servos' own 200 ms bus
 * watchdog. */
#define APP_SERVO_TIMEOUT_MS 120u
/* A servo that has not answered a position read for this long when a stop is
 * reported may not hear the release either (a loose cable: it still runs to
 * its last goal): the report names it. Longer than two reads lost to bus
 * noise on 12 servos (positions every 7-18 ms). */
#define APP_SERVO_SILENT_MS 40u

enum {
    APP_E_ARG = -1 /* NULL pointer or missing interface in app_init() */
};

/* App states (also `state=` in status reports). */
enum {
    APP_ST_BOOT = 0, /* bus bring-up and sensor init */
    APP_ST_IDLE,     /* nothing moves */
    APP_ST_CAL,      /* the homing state machine runs */
    APP_ST_MOVE,     /* an app-driven move (`home`, `release`) */
    APP_ST_LEARN,    /* `learn` or a baseline capture averages samples */
    APP_ST_FAULT     /* the last run ended in a fault; idle otherwise */
};

/* LED patterns (app_led_pattern()). */
enum {
    APP_LED_BOOT = 0, /* fast blink 5 Hz */
    APP_LED_IDLE,     /* 50 ms blip every 2 s (two blips: quick re-home offered) */
    APP_LED_RUN,      /* 4 Hz blink while anything moves */
    APP_LED_DONE,     /* steady on after a successful run */
    APP_LED_FAULT     /* 10 Hz blink, three flashes then a pause, until the next action */
};

/* Engagement windows of every tendon (hom_window()), kept across runs and
 * across resets that keep the servos powered (watchdog, reset pin): the
 * board places it in memory the C start-up leaves alone (.noinit on the AVR)
 * and clears it after a power-up. app_init() keeps it only when the magic,
 * the table and the CRC check. With it, the release after any stop goes no
 * further than the slack margin before each tendon's window, so repeated
 * stops and resets never pay out tendon without bound (docs/app.md). */
typedef struct {
    uint16_t magic; /* APP_WIN_MAGIC */
    uint16_t mask;  /* bit i: lo[i], hi[i] valid */
    uint32_t table_id;
    int32_t lo[APP_MAX_TENDONS];
    int32_t hi[APP_MAX_TENDONS];
    uint16_t crc;   /* store_crc16() of everything before it */
    uint8_t moving; /* a run or move was under way: a reset then releases at boot. Outside
                       the CRC: one byte, written in one store, and a reset between it and
                       a CRC update cost every window (chaos seed 8153: a watchdog as a
                       run's end cleared it, no early release, 172 ms taut) */
} app_win_t;

#define APP_WIN_MAGIC   0x5748u
#define APP_RECOVER_NEW 0xFFu

/* The board as the app sees it. Every function must return at once. */
typedef struct {
    void *ctx;
    uint32_t (*now_ms)(void *ctx); /* free-running milliseconds */
    uint32_t (*now_us)(void *ctx); /* free-running microseconds (may wrap) */
    /* bit 0: the button is pressed (raw level); bits 1-7: presses the board
     * counted itself (settled, modulo 128), or 0 when it counts none */
    uint8_t (*button)(void *ctx);
    void (*led)(void *ctx, uint8_t on);
    void (*wdt_kick)(void *ctx);
    void (*reboot)(void *ctx);      /* resets the board (NULL: not available) */
    uint16_t (*rx_lost)(void *ctx); /* console bytes lost to a full receive buffer, since boot
                                       (NULL: not counted) */
} app_board_t;

/* A firmware for one board builds with -DAPP_BOARD_FIXED=1: the app then
 * calls the board's functions below (the app_board_t contracts without ctx,
 * none of them optional, app_io_t.stack_free, and the app's own reads through
 * app_io_t.con_copy and .table_copy; reboot, which the app never calls, has
 * none) directly, and app_io_t.board and .stack_free are not read (measured: 366 bytes less
 * AVR code, 16 bytes less RAM). The default, 0, takes them
 * from app_io_t, where the native tests and benchmarks put their fakes. */
#ifndef APP_BOARD_FIXED
#define APP_BOARD_FIXED 0
#endif
uint32_t app_board_now_ms(void);
uint32_t app_board_now_us(void);
uint8_t app_board_button(void);
void app_board_led(uint8_t on);
void app_board_wdt_kick(void);
uint16_t app_board_rx_lost(void);
uint16_t app_board_stack_free(void);
void app_board_con_copy(void *dst, const void *src, size_t n);
void app_board_table_copy(void *dst, const void *src, size_t n);
/* The kept windows (app_io_t.win, not read): the board's copy at a fixed
 * address, so that no access goes through a pointer and none checks for
 * NULL (measured: 210 bytes less AVR code). */
extern app_win_t app_board_win;

/* Everything the app is wired to (the caller keeps it for the app's life). Strings marked _f are
 * read through con_copy (flash on the AVR). */
typedef struct app_io_s {
    const app_board_t *board;
    dxl_port servo_port; /* half-duplex servo bus */
    uint8_t servo_bits;  /* bits per byte on the wire (10; 11 in simavr) */
    const icm_bus_t *sensor_bus;
    uint8_t mux_addr; /* TCA9548A address, or ICM_NO_MUX */
    const store_eeprom_t *eeprom;
    store_copy_fn store_copy; /* reads the settings declaration */
    const con_io_t *console;
    con_copy_fn con_copy;     /* reads console declarations and report keys */
    con_rt_t *rt;             /* shared with the RX interrupt's hook */
    const tbl_table_t *table; /* the compiled table, or NULL when none was built */
    tbl_copy_fn table_copy;   /* plain copy from table memory */
    /* Copy that also applies learned targets: a function of the tbl_copy_fn
     * type that calls app_table_copy() on this app (tbl_copy_fn carries no
     * context, so the owner of the app instance binds it). NULL: learned
     * targets are stored but not used. */
    tbl_copy_fn table_copy_learned;
    app_win_t *win; /* engagement windows (see app_win_t); NULL: none kept */
    /* Least free stack there has been since boot, bytes (the board paints the
     * stack at boot); NULL: not known (`status` then omits stack_free). */
    uint16_t (*stack_free)(void);
    const char *version_f; /* firmware version */
    const char *board_f;   /* board name */
    const char *reset_f;   /* reset cause word */
    /* The reset left the servos powered with the firmware out of control (a
     * watchdog reset): every tendon is released at boot, as after a reset
     * that cut a run, whatever the robot was doing (docs/app.md, "Recovery"). */
    uint8_t release_at_boot;
} app_io_t;

/* The application's state, one sub-struct per room of lib/app (each written
 * by its own file, docs/architecture.md). Caller-owned; read-only outside
 * lib/app. The small fields of each room come first: the AVR reaches the
 * first 64 bytes of a struct with one instruction. */

/* app_boot.c: bring-up of the devices and the boot reports. */
typedef struct {
    uint8_t step;        /* 0 start, 1 bring-up, 2 positions and Bus Watchdog, 3 ready */
    uint8_t con_wait;    /* a pending command is answered when the bring-up is done */
    uint8_t n_servos;    /* servos found by the last bring-up */
    uint8_t n_sensors;   /* sensors sampling after the last bring-up */
    uint8_t recovered;   /* every stored home was recovered at boot, none stored since */
    uint8_t offer_quick; /* recovered, at cal_tension: a press re-homes quickly (app_boot_offer) */
    int8_t recover_rc;   /* worst store_recover_position() result at boot */
    uint32_t t_start;    /* start of the bring-up (or of the wait after a servo reboot) */
} app_boot_t;

/* app_bus.c: the servo bus, one transaction at a time. */
typedef struct {
    uint8_t txn; /* transaction in flight */
    uint8_t cycle;
    uint8_t hwerr_due;
    uint8_t pos_force;  /* the next cycle reads positions (a servo was missed) */
    uint8_t pos_streak; /* position reads in a row that missed a servo */
    uint8_t wdog_step;  /* Bus Watchdog writes left after a bring-up (two per servo) */
    uint8_t wdog_gap;   /* 1: a position read comes before the next Bus Watchdog write */
    uint8_t focus;      /* reads of the pulled tendon alone since the last read of all */
    uint8_t wdog_bcast; /* broadcast Bus Watchdog writes left: 2 clear, 1 arm */
    uint8_t reboot_id;
    uint8_t reboot_req;   /* a reboot of reboot_id waits: bus transactions left at most (0: none) */
    uint8_t reboot_tries; /* reboots of reboot_id that left it in error or silent */
    uint16_t absent;      /* bit i: tendon i's servo did not answer the bring-up */
    uint16_t fresh;       /* bit i: a position arrived since the last homing step */
    uint16_t missed;      /* bit i: servo i silenced the group reads: it goes last in them */
    uint16_t seen;        /* bit i: a position has arrived since boot */
    uint16_t goal_due;    /* bit i: goal/velocity of tendon i to send */
    uint16_t goal_again;  /* bit i: a new goal of tendon i, to send once more */
    uint16_t torque_due;  /* bit i: torque of tendon i to send */
    uint16_t torque_on; /* bit i: torque on sent since tendon i's goal (hom_goal()) became valid */
    uint16_t txn_mask;  /* tendons of the transaction in flight */
    uint16_t acc;       /* profile acceleration of every goal */
    uint16_t t_all_ok;  /* ms (low 16 bits): the last position read every servo answered */
    uint8_t ids[APP_MAX_TENDONS];
    uint8_t hw_err[APP_MAX_TENDONS];
    int32_t present[APP_MAX_TENDONS];
    dxl_master dxl;
} app_bus_t;

/* app_run.c: runs, app moves, aborts and the releases that follow. */
typedef struct {
    uint8_t move_kind;
    uint8_t mode;       /* hom_mode_t of the run, or APP_MODE_SURVEY */
    uint8_t abs;        /* the run compares |B - A| with the absolute targets (target_mode 1) */
    uint8_t amb_ok;     /* amb[] holds this power cycle's ambient capture */
    uint8_t last_fault; /* hom_fault_t of the last run */
    uint8_t req_start;  /* a run requested while an EEPROM save finishes */
    uint8_t req_con;    /* the request came from a pending `cal` / `rehome` (0: a press, whose
                           mode is the offer when it starts) */
    uint8_t req_mode;
    uint8_t req_tendon;
    uint8_t auto_release;  /* ID of a servo in hardware error: reboot it, then release */
    uint8_t abort_owed;    /* a stop came after the run's end, before its report: release then */
    uint8_t done_out;      /* the end of a run or move is noted in the kept windows once its
                              <done> has left the board (a reset before that releases) */
    uint8_t reset_release; /* a reset cut a run or move: 1 owed, up to APP_EARLY_SENT early
                              release under way, APP_EARLY_DONE released early or nothing to
                              (app_boot_poll) */
    uint8_t recover_left;  /* device bring-ups left before the pending request is refused
                              (APP_RECOVER_NEW: a new request, not counted yet) */
    uint8_t bring_up;      /* the last run ended in a servo timeout or stall: the next run
                              brings the devices up again first (their Bus Watchdogs) */
    uint8_t survey_n;      /* survey: selected-sensor samples since the last <sv> line */
    uint8_t hold;          /* survey: the held tendon + 1 of a held pull (hom_cmd_t.hold), 0 */
    uint16_t mask;         /* tendons calibrated by this run */
    uint16_t tension;
    uint16_t req_tension;
    uint32_t t_start;
    uint32_t t_move;
    /* absolute target mode: each sensor's ambient offset A (cuT, sensor
     * frame), captured by the first absolute calibration of the power cycle
     * (or the first after `set target_mode`), RAM only (docs/app.md) */
    int32_t amb[APP_MAX_SENSORS][3];
} app_run_t;

/* app_learn.c: `learn`, the baseline capture and `forget`. */
typedef struct {
    uint8_t tendon; /* tendon being learned, or the baseline capture */
    uint8_t sensor;
    uint8_t grid;
    uint8_t n;          /* samples averaged so far (the fewest of any sensor) */
    uint8_t have_b0;    /* u.idle.b0 holds the straight-pose baseline */
    uint8_t forgetting; /* a `forget` waits for its records to be written */
    uint8_t installing; /* `learn T N DB` waits for its record to be written */
    uint16_t mask;      /* bit t: tendon t has a learned record for this table */
    uint16_t forget;    /* bit t: `forget` still has to erase tendon t's record */
    uint32_t t_start;
} app_learn_t;

/* app_rec.c: the EEPROM records and the homes of this power cycle. */
typedef struct {
    uint8_t save_due;                /* records waiting for the EEPROM */
    uint8_t win_fresh;               /* a run's fresh windows set, their record not yet queued */
    uint8_t win_loop;                /* low byte of loops when the last fresh window was set */
    uint8_t save_now;                /* the record being written */
    uint8_t rest_due;                /* rest positions to record once the servos have stopped */
    int8_t homes_rc;                 /* store_homes_load() result */
    uint16_t home_now;               /* bit i: homes.t[i] usable in this power cycle */
    uint16_t t_rest;                 /* 16-bit ms, compared as a 16-bit difference */
    int32_t offset[APP_MAX_TENDONS]; /* calibration frame = present frame + offset */
    store_t store;
    store_settings_t set;
    store_homes_t homes;
} app_rec_t;

/* app_panel.c: button and LED. */
typedef struct {
    uint8_t raw; /* button level, undebounced */
    uint8_t state;
    uint8_t long_done;
    uint8_t led; /* APP_LED_* last set by a room (app_led_pattern() has the rest) */
    uint8_t led_on;
    uint8_t presses;   /* the board's press count last seen (bits 1-7) */
    uint8_t owed;      /* 1: the debounce saw a release the board's count has not shown yet */
    uint16_t t_change; /* 16-bit ms, compared as 16-bit differences */
    uint16_t t_down;
} app_panel_t;

/* app_sense.c: the sensor set. */
typedef struct {
    uint8_t err[APP_MAX_SENSORS]; /* error counts (low byte) already passed to the homing */
    icm_set_t set;
    icm_set_slot_t slot[APP_MAX_SENSORS];
} app_sense_t;

/* app_cmd.c: the console. */
typedef struct {
    uint16_t rx_lost; /* console bytes lost, last reported */
    uint16_t dropped; /* reports dropped, last reported */
    uint8_t list;     /* APP_LIST_*: a listing being written, one line a pass */
    uint8_t list_i;   /* its next item */
    uint8_t list_arg; /* servos: with model and firmware; history: entries */
    con_t con;
} app_cmd_t;

/* The order of the members is the AVR's: the first 64 bytes of app_t are
 * reached with one instruction, so the rooms with small, often used fields
 * come first (this order measured 0.1 KB smaller than the others tried). */
typedef struct {
    /* shared by every room: written by app_poll() and the room that changes
     * the activity (state), and by app_boot.c (the table) */
    uint8_t state;
    uint8_t table_ok;
    const struct app_io_s *io;
    app_panel_t panel;
    app_boot_t boot;
    app_learn_t learn;
    app_rec_t rec;
    app_bus_t bus;
    app_run_t run;
    uint32_t loop_max_us;
    uint32_t loops;
    tbl_src_t tab;  /* plain */
    tbl_src_t htab; /* learned targets applied */
    tbl_info_t info;
    app_cmd_t cmd;
    app_sense_t sense;
    /* Storage used by one activity at a time (RAM is the scarce resource):
     *  hom    calibration runs (app_run.c); its goals (hom_goal()) also hold
     *         the goals of app moves (home, release) while no run is active;
     *  bring  boot, `servos scan` and `reboot` (app_boot.c);
     *  idle   between runs (app_learn.c, app_rec.c): the sample sums of
     *         `learn` and the baseline capture, the straight-pose baseline
     *         (learn.have_b0) and the history or learned record being saved.
     *         It overlaps only the homing's first bytes (never its tendons,
     *         sensors or outputs); runs and bring-ups wait until its record
     *         is written, and clear learn.have_b0. */
    union {
        hom_t hom;
        dxl_bringup bring;
        struct {
            uint8_t cnt[APP_MAX_SENSORS];
            int32_t acc[APP_MAX_SENSORS][3];
            int32_t b0[APP_MAX_SENSORS][3];
            union {
                store_hist_t hist;
                store_learned_t learned;
                store_win_t win;
            } rec; /* kept until store_poll() is done */
        } idle;
    } u;
} app_t;

/* u.idle must stay clear of the homing's tendon results and outputs. */
typedef char app_idle_fits_t[(sizeof(((app_t *)0)->u.idle) <= offsetof(hom_t, tendon)) ? 1 : -1];

/* Binds the app to its board and ports, initialises every module, reads the
 * settings, homes and learned targets, checks the table and prints the
 * `<boot ...>` line. io is kept by reference. Nothing moves. Returns 0 or APP_E_ARG. */
int8_t app_init(app_t *app, const app_io_t *io);

/* The settings' bus rate (the board configures its servo UART with it before
 * the first app_poll()). */
uint32_t app_bus_baud(const app_t *app);

/* One pass of the superloop (see the file comment). Returns the app state
 * (APP_ST_*). Never blocks beyond one bus transfer and the console's output. */
int8_t app_poll(app_t *app);

/* Aborts whatever moves and releases every tendon (button long press, `!`).
 * Reports `<released ...>` once the release goals are sent. */
void app_abort(app_t *app);

/* The tbl_copy_fn body that applies learned targets: copies n bytes of the
 * table at src into dst with io.table_copy, then overwrites the parts that
 * fall inside a tendon's target_cuT[] with the learned entries stored in
 * EEPROM for this table. */
void app_table_copy(app_t *app, void *dst, const void *src, size_t n);

/* Current LED pattern (APP_LED_*). */
uint8_t app_led_pattern(const app_t *app);

#endif /* HALLHOME_APP_H */
