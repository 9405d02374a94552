/*
 * app_priv: what the rooms of lib/app share, and nothing outside lib/app
 * includes. Each room is one file that owns one part of app_t (app.h):
 *
 *   app.c         the superloop (app_poll) and the small helpers every room uses
 *   app_boot.c    app_init, the table, device bring-up and <ready>        (app_t.boot)
 *   app_bus.c     the servo-bus scheduler: one transaction at a time      (app_t.bus)
 *   app_sense.c   the sensor set and its samples for the homing           (app_t.sense)
 *   app_run.c     runs (cal, rehome), app moves (home, release), aborts   (app_t.run)
 *   app_win.c     the engagement windows that bound every release: kept
 *                 in .noinit across resets, in EEPROM across power cycles (io->win)
 *   app_learn.c   learn, forget and the learned-target table copy         (app_t.learn)
 *   app_rec.c     the EEPROM records: homes, rest positions, history,
 *                 settings, written one byte per pass while idle          (app_t.rec)
 *   app_cmd.c     the console: its poll, the command handlers, listings   (app_t.cmd)
 *   app_report.c  report lines and the flash words they use
 *   app_panel.c   button and LED                                          (app_t.panel)
 *
 * A room writes its own sub-struct; the others read it, or call the room's
 * functions declared here. The shared storage app_t.u belongs to one
 * activity at a time (app.h).
 *
 * Functions here follow the app's convention: 0 done, negative error (a
 * CON_E_* code), positive in progress, unless they say otherwise.
 */
#ifndef HALLHOME_APP_PRIV_H
#define HALLHOME_APP_PRIV_H

#include <stddef.h>

#include "app/app.h"

/* Flash is the scarce resource on the AVR: most tasks called from one place
 * stay functions of their own (APP_NOINLINE) rather than being merged into
 * their caller, which costs more code (-0.8 KB measured); the ones left
 * without it (the bus poll, button and LED, the bring-up's start and finish,
 * the table load, the home recovery, the event report, the window take-over,
 * the end of a run: 0.6 KB together; the listing's line, the hex printer,
 * the kept windows' moving flag, the run's homing start: 174 B together;
 * the rest positions' poll, the windows' recovery and record: 42 B)
 * each measured smaller without it, and every one kept APP_NOINLINE measured
 * larger without it. The firmware is linked as one LTO
 * unit, so functions shared between the rooms cost no more than the static
 * functions of one file did. */
#if defined(__GNUC__)
#define APP_NOINLINE __attribute__((noinline))
#else
#define APP_NOINLINE
#endif

/* The board's functions (app.h, APP_BOARD_FIXED); APP_HAS_RX_LOST(a) and
 * APP_HAS_STACK_FREE(a): the board counts lost console bytes, knows its
 * least free stack; APP_WIN(a): the kept windows (app_io_t.win). */
#if APP_BOARD_FIXED
#define APP_NOW_MS(a)              ((void)(a), app_board_now_ms())
#define APP_NOW_US(a)              ((void)(a), app_board_now_us())
#define APP_BUTTON(a)              app_board_button()
#define APP_LED(a, on)             app_board_led(on)
#define APP_WDT_KICK(a)            app_board_wdt_kick()
#define APP_HAS_RX_LOST(a)         1
#define APP_RX_LOST(a)             app_board_rx_lost()
#define APP_HAS_STACK_FREE(a)      1
#define APP_STACK_FREE(a)          app_board_stack_free()
#define APP_CON_COPY(a, d, s, n)   app_board_con_copy(d, s, n)
#define APP_TABLE_COPY(a, d, s, n) app_board_table_copy(d, s, n)
#define APP_WIN(a)                 ((void)(a), &app_board_win)
#else
#define APP_NOW_MS(a)              (a)->io->board->now_ms((a)->io->board->ctx)
#define APP_NOW_US(a)              (a)->io->board->now_us((a)->io->board->ctx)
#define APP_BUTTON(a)              (a)->io->board->button((a)->io->board->ctx)
#define APP_LED(a, on)             (a)->io->board->led((a)->io->board->ctx, on)
#define APP_WDT_KICK(a)            (a)->io->board->wdt_kick((a)->io->board->ctx)
#define APP_HAS_RX_LOST(a)         ((a)->io->board->rx_lost != NULL)
#define APP_RX_LOST(a)             (a)->io->board->rx_lost((a)->io->board->ctx)
#define APP_HAS_STACK_FREE(a)      ((a)->io->stack_free != NULL)
#define APP_STACK_FREE(a)          (a)->io->stack_free()
#define APP_CON_COPY(a, d, s, n)   (a)->io->con_copy(d, s, n)
#define APP_TABLE_COPY(a, d, s, n) (a)->io->table_copy(d, s, n)
#define APP_WIN(a)                 (a)->io->win
#endif

/* Room marker for the virtual bench (sim/bench/looptime.c): app_poll() writes
 * a zero to the byte at APP_ROOM_MARK_ADDR before each room's call, and the
 * bench, which counts the writes of a pass, tells which room a long pass
 * spent its time in. The AVR build points it at GPIOR1, a general purpose
 * register nothing else uses (one OUT of the zero register, 2 bytes per
 * marker); other builds leave it out. */
#ifdef APP_ROOM_MARK_ADDR
#define APP_ROOM_MARK() (*(volatile uint8_t *)(APP_ROOM_MARK_ADDR) = 0u)
#else
#define APP_ROOM_MARK() ((void)0)
#endif

/* Report kinds, keys and words, each once in console-flash memory (program
 * memory on the AVR, where CON_FLASH is __progmem__): app_w_<id>. W(id) is
 * the word "id" itself; WS(id, text) any other text. The *_words entries are
 * space-separated lists read by app_rep_word(). */
#define APP_WORDS(W, WS)                                                                           \
    WS(mode_words, "full quick single dry survey")                                                 \
    WS(target_words, "delta abs")                                                                  \
    WS(fault_words, HOM_FAULT_WORDS)                                                               \
    W(target)                                                                                      \
    WS(state_words, "boot idle cal move learn fault")                                              \
    WS(dev_words, "none sensor servo tendon")                                                      \
    WS(phase_words, "- preflight release baseline tendon final hold")                              \
    W(reason)                                                                                      \
    W(dev)                                                                                         \
    W(index)                                                                                       \
    W(name)                                                                                        \
    W(hallhome)                                                                                    \
    W(board)                                                                                       \
    W(reset)                                                                                       \
    W(missing)                                                                                     \
    W(sensor)                                                                                      \
    W(ch)                                                                                          \
    W(addr)                                                                                        \
    W(servo)                                                                                       \
    W(hw_error)                                                                                    \
    W(found)                                                                                       \
    W(model)                                                                                       \
    W(fw)                                                                                          \
    W(cal_pos)                                                                                     \
    W(ready)                                                                                       \
    W(table_id)                                                                                    \
    W(none)                                                                                        \
    W(sensors_expected)                                                                            \
    W(servos_expected)                                                                             \
    W(moved)                                                                                       \
    W(stored)                                                                                      \
    W(count)                                                                                       \
    W(other_table)                                                                                 \
    W(progress)                                                                                    \
    W(state)                                                                                       \
    W(start)                                                                                       \
    W(mode)                                                                                        \
    W(tension_mN)                                                                                  \
    W(why)                                                                                         \
    W(bits)                                                                                        \
    W(engaged)                                                                                     \
    W(result)                                                                                      \
    W(home_um)                                                                                     \
    W(straight)                                                                                    \
    W(target_uT)                                                                                   \
    W(travel_um)                                                                                   \
    W(time_ms)                                                                                     \
    W(code)                                                                                        \
    W(detail)                                                                                      \
    W(done)                                                                                        \
    W(servo_stall)                                                                                 \
    W(baseline)                                                                                    \
    W(learned)                                                                                     \
    W(eeprom)                                                                                      \
    W(refused)                                                                                     \
    W(tendons)                                                                                     \
    W(homes_now)                                                                                   \
    W(saving)                                                                                      \
    W(loop_max_us)                                                                                 \
    W(stack_free)                                                                                  \
    W(loops)                                                                                       \
    W(rest)                                                                                        \
    W(usable)                                                                                      \
    W(ok)                                                                                          \
    W(who)                                                                                         \
    W(mag)                                                                                         \
    W(rate_Hz)                                                                                     \
    W(bx_uT)                                                                                       \
    W(by_uT)                                                                                       \
    W(bz_uT)                                                                                       \
    W(ovf)                                                                                         \
    W(last_err)                                                                                    \
    W(reinits)                                                                                     \
    W(grid_mN)                                                                                     \
    W(default_mN)                                                                                  \
    W(noise_cuT)                                                                                   \
    W(dir)                                                                                         \
    W(segment)                                                                                     \
    W(limit_um)                                                                                    \
    W(target_cuT)                                                                                  \
    W(hist)                                                                                        \
    W(age)                                                                                         \
    W(value)                                                                                       \
    W(unit)                                                                                        \
    W(min)                                                                                         \
    W(max)                                                                                         \
    W(default)                                                                                     \
    W(overrun)                                                                                     \
    W(bytes)                                                                                       \
    W(total)                                                                                       \
    W(dropped)                                                                                     \
    W(reports)                                                                                     \
    W(not_released)                                                                                \
    W(servo_error)                                                                                 \
    W(sv)                                                                                          \
    W(b)

#define APP_W_DECL(id)        extern const char app_w_##id[];
#define APP_WS_DECL(id, text) extern const char app_w_##id[];
APP_WORDS(APP_W_DECL, APP_WS_DECL)
#undef APP_W_DECL
#undef APP_WS_DECL

/* The words that are command names, or end a command name, a help or an
 * error text, are the console's (console.h). */
#define app_w_version CON_CMD_NAME_F(VERSION)
#define app_w_status  CON_CMD_NAME_F(STATUS)
#define app_w_sensors CON_CMD_NAME_F(SENSORS)
#define app_w_servos  CON_CMD_NAME_F(SERVOS)
#define app_w_rehome  CON_CMD_NAME_F(REHOME)
#define app_w_release CON_CMD_NAME_F(RELEASE)
#define app_w_boot    (CON_CMD_NAME_F(REBOOT) + 2)
#define app_w_p       (CON_CMD_NAME_F(HELP) + 3)
#define app_w_homes   CON_CMD_HELP_TAIL_F(REHOME, "homes")
#define app_w_dB_uT   CON_CMD_HELP_TAIL_F(LEARN, "dB_uT")
#define app_w_aborted CON_ERR_TAIL_F(ABORTED, "aborted")
#define app_w_setting CON_ERR_TAIL_F(UNKNOWN_SETTING, "setting")
#define app_w_grid    CON_ERR_TAIL_F(TENSION_RANGE, "grid")

/* A word that ends another word is that word's tail, with no flash of its
 * own (a word costs its length and the NUL). */
#define app_w_fault    (app_w_default + 2)
#define app_w_error    (app_w_servo_error + 6)
#define app_w_err      (app_w_last_err + 5)
#define app_w_id       (app_w_table_id + 6)
#define app_w_pos      (app_w_cal_pos + 4)
#define app_w_table    (app_w_other_table + 6)
#define app_w_home     (app_w_hallhome + 4)
#define app_w_released (app_w_not_released + 4)
#define app_w_now      (app_w_homes_now + 6)
#define app_w_t        (app_w_start + 4)
#define app_w_tendon   (app_w_dev_words + 18) /* "none sensor servo tendon" */

/* ---- app.c: helpers of every room ------------------------------------------ */

uint32_t app_now_ms(const app_t *a);
uint32_t app_now_us(const app_t *a);
/* 1 << i and bit i of m (one routine each: a variable shift is a loop on the AVR) */
uint16_t app_bit16(uint8_t i);
uint8_t app_has(uint16_t m, uint8_t i);
/* every tendon of the table */
uint16_t app_all_mask(const app_t *a);
/* nothing moves, nothing is captured (APP_ST_IDLE or APP_ST_FAULT) */
uint8_t app_idle_state(const app_t *a);
/* app_boot.c: entry g of the table's tension grid, mN (0 beyond it, or
 * without a table), and 1 when mN lies within the grid; read from the
 * table, which app_t does not copy (tbl_info_t) */
uint16_t app_grid_mN(const app_t *a, uint8_t g);
uint8_t app_in_grid(const app_t *a, uint16_t mN);

/* ---- app_report.c: report lines -------------------------------------------- */

void app_rep_begin(app_t *a, const char *kind);
void app_rep_int(app_t *a, const char *key, int32_t v);
void app_rep_u8(app_t *a, const char *key, uint8_t v);
void app_rep_u16(app_t *a, const char *key, uint16_t v);
/* tendon=i id=<its servo's ID> */
void app_rep_tendon(app_t *a, uint8_t i);
void app_rep_end(app_t *a);
/* not_released=<ID> index=<i-1> for servo i-1 when i > 0, else for a servo
 * silent since before the stop (app_bus_silent()), else nothing */
void app_rep_not_released(app_t *a, uint8_t i);
/* key=0x%08x (table_id) without a printf */
void app_rep_hex(app_t *a, const char *key, uint32_t v);
/* key=<word i of the flash list words_f> ("?" past its end) */
static inline void app_rep_word(app_t *a, const char *key, const char *words_f, uint8_t i)
{
    con_report_word(&a->cmd.con, key, words_f, i);
}
/* A report field read from a struct: its key (a flash word), where it lies
 * and how it prints. Reports that print struct members list them in flash
 * (APP_FIELD) and print them with one app_rep_fields() call instead of one
 * call per field (a call site costs 16-20 bytes of AVR code, an entry 5). */
typedef struct {
    const char *key;
    uint16_t off; /* offsetof() in the struct */
    uint8_t fmt;  /* size in bytes (1, 2, 4) | APP_F_* */
} app_field_t;
#define APP_F_U    0x00u /* unsigned integer */
#define APP_F_S    0x08u /* signed integer */
#define APP_F_DEC1 0x10u /* one decimal (v / 10) */
#define APP_F_DEC2 0x20u /* two decimals (v / 100) */
#define APP_F_HEX  0x40u /* 0x%08x */
#define APP_FIELD(key, type, member, f)                                                            \
    {                                                                                              \
        app_w_##key, (uint16_t)offsetof(type, member),                                             \
            (uint8_t)(sizeof(((type *)0)->member) | (f))                                           \
    }
/* Prints the n fields f (in flash) of the struct at base. */
void app_rep_fields(app_t *a, const void *base, const app_field_t *f, uint8_t n);
#define APP_REP_FIELDS(a, base, f)                                                                 \
    app_rep_fields((a), (base), (f), (uint8_t)(sizeof(f) / sizeof((f)[0])))
/* table_id (hex), tendons, sensors of a tbl_info_t; [0] alone: table_id */
extern const app_field_t app_info_fields[3];
/* name=hallhome version=... board=... of <boot> and <version> */
void app_rep_ident(app_t *a);
/* table=<name> and the first n of app_info_fields, or table=none without a table */
void app_rep_table(app_t *a, uint8_t n);
/* key=<the table's name>, read from the table (tbl_name()) */
void app_rep_name(app_t *a, const char *key);
/* A fault the app itself detects (moves, learn, EEPROM), in the same shape as
 * the homing's: reason word, console error code, device, index. */
void app_rep_fault(app_t *a, const char *reason_f, int8_t err, uint8_t dev, uint8_t index);
/* One <missing ...> per sensor not sampling and per servo absent or in
 * hardware error. Returns CON_E_SENSOR_FAULT when a sensor is missing, else
 * CON_E_SERVO_FAULT when a servo is, else 0. */
int8_t app_rep_missing(app_t *a);
/* One <servo ...> per tendon (with_model: model and firmware of the bring-up). */
/* One `<servo ...>` line: what the bus knows of tendon i's servo. */
void app_rep_servo(app_t *a, uint8_t i, uint8_t with_model);
/* A homing event as a console report. */
void app_rep_event(app_t *a, const hom_event_t *ev);

/* ---- app_boot.c: bring-up ------------------------------------------------- */

/* One step of the bring-up (state APP_ST_BOOT): servos pinged and set up,
 * sensors started, then `<missing ...>` and `<ready ...>`. */
void app_boot_poll(app_t *a);
/* The bring-up's entry for servo id, or NULL (valid until the shared storage
 * is reused by a run or a record). */
const dxl_servo_info *app_boot_servo_info(const app_t *a, uint8_t id);
/* Brings the bus up again (`servos` scan, or after a servo reboot); the
 * pending console line is answered with the servo lines once it is done. */
void app_boot_again(app_t *a);
/* A run stored new homes: nothing was recovered, no quick re-home offered. */
void app_boot_homes_new(app_t *a);
/* The button's quick re-home is offered while the recovered homes were
 * calibrated at cal_tension: a press always works at cal_tension, and a
 * press after `set cal_tension` to another tension calibrates in full at it
 * (`rehome` still re-homes at the homes' tension). */
void app_boot_offer(app_t *a);

/* ---- app_bus.c: the servo bus ------------------------------------------------ */

/* Bus transactions (app_bus_t.txn). */
enum {
    APP_TX_NONE = 0,
    APP_TX_POS,
    APP_TX_HWERR,
    APP_TX_GOAL,
    APP_TX_TORQUE,
    APP_TX_REBOOT,
    APP_TX_WDOG
};

/* One step of the bus: the reply of the transaction in flight taken, the next
 * one started (torque, Bus Watchdog, goals, hardware-error or position reads). */
void app_bus_poll(app_t *a);
/* Queues a goal for tendon i (torque on first when it is off). */
void app_bus_goal(app_t *a, uint8_t i, int32_t goal, uint16_t vel, uint16_t acc);
/* Reboots servo id once the goals queued before it are out; the bus is then
 * brought up again and the pending console line answered. */
void app_bus_reboot(app_t *a, uint8_t id);
/* Writes the queued goals at once, outside the scheduler (which sends them
 * again later): what 0 their Profile Velocity, 1 their Goal Position, one
 * sync write each (all twelve fit one packet; the scheduler's 12-byte
 * entries do not). For the bring-up's first moments. Returns 1 when the
 * write went out. */
uint8_t app_bus_goals_now(app_t *a, uint8_t what);
/* A bring-up takes the bus: the transaction in flight is dropped, no servo
 * is absent yet and no goal of the old frames is sent again. */
void app_bus_stop(app_t *a);
/* The bring-up is over: its servos, positions and hardware errors taken (the
 * others marked absent), nothing queued, the Bus Watchdog writes due.
 * Returns the number of servos found. */
uint8_t app_bus_found(app_t *a);
/* A run starts from cleared goals: none is refreshed until set again. */
void app_bus_goals_cleared(app_t *a);
/* The first servo that has been silent in the position reads for
 * APP_SERVO_SILENT_MS or more, as its index + 1; 0: none. */
uint8_t app_bus_silent(const app_t *a);
/* Positions read before now are not news for the next step. */
void app_bus_positions_stale(app_t *a);
/* Every servo's input of a homing step (status, hardware error, position);
 * the positions then count as taken. */
void app_bus_inputs(app_t *a, hom_in_t *in);
/* Queues what a homing step changed: goals, velocities, torque. */
void app_bus_take(app_t *a, const hom_out_t *out);

/* ---- app_sense.c: the sensors ---------------------------------------------- */

/* One step of the sensor set (now_us: the pass's start), and this pass's
 * samples into in->sensor[] for the homing and `learn`. */
void app_sense_poll(app_t *a, hom_in_t *in, uint32_t now_us);
/* Sets the sensors of the table up and starts them (once; nothing when the
 * set already runs). */
void app_sense_start(app_t *a);
/* The bring-up is over: the error counts so far are taken as seen. Returns
 * the number of sensors sampling. */
uint8_t app_sense_settled(app_t *a);

/* ---- app_run.c: runs, moves and the kept windows ----------------------------- */

/* App-driven moves (app_run_t.move_kind). */
enum { APP_MOVE_HOME = 1, APP_MOVE_RELEASE = 2 };

/* A mode of app_run_request() with this bit set is an identification
 * survey (`survey`): every tendon, or one, pulled alone to the top grid
 * tension as a calibration pulls, its samples streamed as <sv> lines, and
 * nothing kept (docs/identify.md, "Survey on the board"). */
#define APP_RUN_SURVEY 0x80u
/* app_run_t.mode of a survey: its word in app_w_mode_words */
#define APP_MODE_SURVEY 4u
/* Survey: one <sv> line per this many samples of the pulled tendon's sensor
 * (100 Hz): four sensors' lines at 50 Hz take half of the console's 115200
 * baud, leaving room for the run's own reports. */
#define APP_SURVEY_EVERY 2u
/* Survey: the approach from engagement (hom_config_t.v_moderate) at 10
 * units, 156 ticks/s: 1.6 ticks between two samples of a sensor, so the
 * position a line pairs with a sample lags it by well under a tick. */
#define APP_SURVEY_V 10u
/* Survey (`survey`): the run's tension, every tendon's target, is this many
 * eighths of the table's top grid tension (at least the lowest grid
 * tension). The survey runs on a robot not yet identified, and the field
 * says where its bend is, not its tension: pulled to the top target,
 * paper_2seg at +-10 %, stiffness +-25 % (seeds 8 and 18) took a tendon to
 * 2.10 and 2.15 N, 1.43 x the top, against the bounded pull's
 * 1.25 x 1.5 N + 0.1 N = 1.975 N. */
#define APP_SURVEY_EIGHTHS 6u
/* Held pull (`survey T H`, docs/identify.md): the run's tension, the held
 * tendon's target, is this many eighths of the table's top grid tension.
 * The pulled tendon's pull raises the held tendon's tension: held at the
 * top target, paper_2seg at +-10 %, stiffness +-25 % (seed 8) stood at
 * 1.97 N before that rise and reached 2.35 N against the bounded pull's
 * 1.25 x 1.5 N + 0.1 N = 1.975 N. */
#define APP_HOLD_EIGHTHS 5u

/* Starts a homing run. Returns 0 or a CON_E_* code (nothing moves then), or
 * CON_PENDING when an EEPROM write must finish first
 * (the pending console line is answered when the run starts). */
int8_t app_run_request(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon);
/* A short press: the run the board offers (quick re-home or full), deferred
 * while the bring-up or an EEPROM write finishes; a refusal is reported. */
void app_run_press(app_t *a);
/* Each pass before the steps: deferred run requests and owed releases. */
void app_run_poll(app_t *a);
/* After the bring-up that follows a servo's reboot: 0 when that servo is up
 * and clear of errors (or none was rebooted), CON_PENDING when it is
 * rebooted again (a stop's release is owed to it), else CON_E_SERVO_FAULT,
 * with <fault reason=not_released> when its release was owed. */
int8_t app_run_rebooted(app_t *a);
/* 0 when a run or move may start: the bring-up is over, a table is loaded
 * and no device is missing (each missing one reported); else CON_E_*. */
int8_t app_run_check(app_t *a);
/* One step of a run (state APP_ST_CAL) on this pass's samples. */
void app_run_step(app_t *a, hom_in_t *in);
/* Starts an app move (APP_MOVE_*) whose goals are queued. */
void app_run_move(app_t *a, uint8_t kind);
/* One step of an app move (state APP_ST_MOVE). */
void app_run_move_step(app_t *a);
/* Queues the release goals of every tendon that answered (never a pull; a
 * tendon without a window gets one). Returns nonzero when any was queued. */
uint8_t app_run_release_goals(app_t *a);
/* After a reset that cut a run: the release goals of the tendons whose
 * engagement window survived, before the bring-up (which switches torque
 * off and on, and a servo takes its present position as goal then): steps 1
 * and 3 write the release velocity, steps 2 and 4 the goals. 1 when sent. */
uint8_t app_run_early_release(app_t *a, uint8_t step);
/* The target mode changed: the next absolute run captures the ambient again. */
void app_run_ambient_reset(app_t *a);

/* ---- app_win.c: engagement windows -------------------------------------------- */

/* um of tendon travel in encoder ticks at npt nm per tick (rounded). */
int32_t app_um_ticks(uint32_t npt, uint32_t um);
/* Engagement windows kept across resets (app_win_t): checked at boot, set
 * (keep 0: forgotten) per tendon. */
void app_win_check(app_t *a);
void app_win_set(app_t *a, uint8_t i, int32_t lo, int32_t hi, uint8_t keep);
/* Notes in the kept copy whether anything moves (a reset then releases). */
void app_win_moving(app_t *a, uint8_t on);
/* Takes the windows the run changed into the kept copy. */
void app_win_take(app_t *a);
/* Tendon i's slack margin (ticks, signed by its pull direction: the release
 * goes that far before its window) and, in *span, the span of a fresh window
 * either side of where it stands: one and a half times its top-grid travel. */
int32_t app_win_margin(const app_t *a, uint8_t i, int32_t *span);
/* Tendon i's window with nothing known this power cycle (no kept window, no
 * stored home): the homing's own for a run at tension_mN, around where the
 * tendon stands (docs/app.md, "Recovery"). Returns its bound on the slack
 * side. */
int32_t app_win_fresh(app_t *a, uint8_t i, uint16_t tension_mN);
/* Before a run at tension_mN: every tendon that answered and has neither a
 * window nor a stored home gets a fresh one (one tendon a call), then the
 * windows are queued for the EEPROM (APP_SAVE_WIN), so a power cut in the
 * run does not cost a release more. Nonzero while windows are being set or
 * their save is queued or under way: the run waits. */
uint8_t app_win_before_run(app_t *a, uint16_t tension_mN);
/* Queues the record of the kept windows for the EEPROM (APP_SAVE_WIN). */
void app_win_persist(app_t *a);
/* That record, relative to where each servo stands now: built when its save
 * starts (app_rec_poll()). */
void app_win_record(app_t *a, store_win_t *r);
/* After a bring-up: windows saved in EEPROM go to the tendons that have no
 * window (a power-up clears them) and no stored home (recovered or not). */
void app_win_recover(app_t *a);

/* ---- app_learn.c: learn and forget -------------------------------------------- */

#define APP_LEARN_BASELINE 0xFFu /* learn.tendon: capturing the straight-pose baseline */

/* Starts averaging samples for tendon (or APP_LEARN_BASELINE). */
void app_learn_begin(app_t *a, uint8_t tendon);
/* One step of a capture (state APP_ST_LEARN) on this pass's samples. */
void app_learn_step(app_t *a, const hom_in_t *in);
/* `learn`: starts averaging tendon's sensor for grid point grid. Returns
 * CON_PENDING (answered when done) or CON_E_SENSOR_FAULT. */
int8_t app_learn_start(app_t *a, uint8_t tendon, uint8_t grid);
/* `forget`: erases the learned records of the tendons in mask that have one.
 * Returns CON_PENDING (answered once written) or 0 when none has. */
int8_t app_learn_forget(app_t *a, uint16_t mask);
/* `forget`, called by app_rec_poll() while the EEPROM and the record
 * storage are free: the next tendon's empty learned record is queued. */
void app_learn_forget_next(app_t *a);
/* `learn T N DB`: installs v (cuT) as tendon's learned target at grid point grid
 * when plausible (as `learn` checks it), and saves it. Returns CON_PENDING
 * (answered once written: app_learn_installed()) or CON_E_IMPLAUSIBLE. */
int8_t app_learn_install(app_t *a, uint8_t tendon, uint8_t grid, uint32_t v);
/* The learned record just written was an install's: returns 1 once. */
uint8_t app_learn_installed(app_t *a);
/* The learned record just written was the last one of a `forget`: returns 1
 * (once) so that its console line is answered. */
uint8_t app_learn_forgotten(app_t *a);
/* A run or a bring-up takes the storage of the straight-pose baseline. */
void app_learn_drop_baseline(app_t *a);
/* The learned record in u.idle goes to the EEPROM now: a record with
 * targets marks its tendon as learned. */
void app_learn_saving(app_t *a);
/* A run ended well: its straight-pose baseline becomes the learn baseline
 * (copied out of the homing's storage into u.idle.b0). */
void app_learn_keep_baseline(app_t *a);

/* ---- app_rec.c: EEPROM records and homes ---------------------------------------- */

/* Records waiting for the EEPROM (rec.save_due, rec.save_now). */
enum {
    APP_SAVE_HOMES = 1,
    APP_SAVE_HIST = 2,
    APP_SAVE_LEARNED = 4,
    APP_SAVE_SETTINGS = 8,
    APP_SAVE_WIN = 16
};

/* Queues records (APP_SAVE_*) for the EEPROM. */
void app_rec_queue(app_t *a, uint8_t what);
/* Record `what` (one APP_SAVE_*) is queued or being written. */
uint8_t app_rec_saving(const app_t *a, uint8_t what);
/* A history or learned record waits in u.idle: the homing and the bring-up
 * must not reuse that storage until it is written. */
uint8_t app_rec_busy(const app_t *a);
/* One EEPROM step (one byte while nothing moves), the queued records started
 * in turn, and `save` / `forget` answered when theirs is written. */
void app_rec_poll(app_t *a);
/* Records the rest positions once the servos have stopped after a release
 * or a fault. */
void app_rec_rest_poll(app_t *a);
/* Maps the stored homes into this power cycle's servo frames (rec.home_now).
 * Returns 0, or the first store_recover_position() error of a tendon. */
int8_t app_rec_recover(app_t *a);
/* Tendon i's stored home in this power cycle's frame (valid with home_now). */
int32_t app_rec_home(const app_t *a, uint8_t i);
/* Where `home` takes tendon i: its stored home, or its straight-pose home
 * with the `home_pose` setting 1, in this power cycle's frame. */
int32_t app_rec_goal(const app_t *a, uint8_t i);
/* 0 when every tendon has a stored home usable in this power cycle, else
 * CON_E_NOT_HOMED or CON_E_MOVED (a spool turned while powered off). */
int8_t app_rec_usable(const app_t *a);
/* Rest positions: recorded REST_DELAY_MS after t (due 1), or not (due 0). */
void app_rec_rest_at(app_t *a, uint8_t due, uint32_t t);
/* A run ended well: the homes of the tendons in mask taken from the homing
 * (calibration frame = this power cycle's frame, offsets 0), counted at
 * tension. Before the homing's storage is reused. */
void app_rec_take_homes(app_t *a, uint16_t mask, uint16_t tension);
/* ... then the history record of the run, and both records queued. */
void app_rec_save_run(app_t *a);

/* ---- app_cmd.c: the console ----------------------------------------------------- */

/* The console's step: realtime mode while anything moves, lost bytes and
 * dropped reports reported, a listing's next line, one byte or line handled. */
void app_cmd_poll(app_t *a);

/* Listings (app_cmd_t.list): written one line a pass, when the console's
 * output has room for it, and answered `ok` after the last. */
enum {
    APP_LIST_NONE = 0,
    APP_LIST_HOMES,   /* `status`: a <home> line per stored home */
    APP_LIST_SENSORS, /* `sensors` */
    APP_LIST_SERVOS,  /* `servos`: list_arg 1 with model and firmware (after a bring-up) */
    APP_LIST_TENDONS, /* `table`: a <tendon> line per tendon */
    APP_LIST_HISTORY, /* `history`: list_arg entries */
    APP_LIST_SETTINGS /* `get` */
};
/* Starts a listing; the pending console line is answered at its end.
 * Returns CON_PENDING. */
int8_t app_cmd_list(app_t *a, uint8_t list, uint8_t arg);

/* ---- app_panel.c: button and LED ------------------------------------------ */

/* Debounces the button (t: 16-bit ms): a short press calls app_run_press(), a
 * press held for APP_LONG_PRESS_MS calls app_abort(). */
void app_panel_button(app_t *a, uint16_t t);
/* Drives the LED with app_led_pattern() at time t (ms). */
void app_panel_led(app_t *a, uint32_t t);
/* The pattern a room asks for (APP_LED_*); app_led_pattern() shows it while
 * the state allows. */
static inline void app_panel_set(app_t *a, uint8_t pattern)
{
    a->panel.led = pattern;
}

#endif /* HALLHOME_APP_PRIV_H */
