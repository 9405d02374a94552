/*
 * bench: the virtual bench. The unmodified firmware ELF runs on simavr
 * (ATmega2560, 16 MHz) and this host program wires simulated hardware to its
 * pins: the console on UART0, the servo bus on UART1 (half-duplex, direction
 * pin PE4), the sensors on the TWI, the button (PE5), the LED (PB7), the
 * EEPROM and the watchdog. The device models (sim/devices) and the robot
 * plant (sim/plant) are portable C shared with the unit tests; this program
 * only moves bytes and pin levels between them and the simulated MCU.
 *
 * Every part below keeps its state in the one bench_t; nothing is global
 * except the pointer the signal handler uses.
 */
#ifndef HALLHOME_BENCH_H
#define HALLHOME_BENCH_H

#include <regex.h>
#include <stdint.h>
#include <stdio.h>

#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>

#include "devices/icm20948_model.h"
#include "devices/tca9548a_model.h"
#include "devices/xl430_model.h"
#include "plant/plant.h"

#define BENCH_F_CPU       16000000u
#define BENCH_EEPROM_SIZE 4096u
#define BENCH_MAX_SERVOS  PLANT_MAX_TENDONS
#define BENCH_MAX_SENSORS PLANT_MAX_SENSORS
#define BENCH_MAX_EVENTS  1024u
#define BENCH_MAX_PATTERN 8u
#define BENCH_LED_LOG     4096u
#define BENCH_LINE_MAX    512u
#define BENCH_G           9.80665 /* standard gravity, m/s^2: grams to newtons */

/* ATmega2560 I/O addresses (data space) the bench touches directly
 * (datasheet 2549Q, "Register Summary"). */
#define BENCH_MCUSR    0x54u
#define BENCH_PIND     0x29u
#define BENCH_DDRD     0x2Au
#define BENCH_PINE     0x2Cu
#define BENCH_EECR     0x3Fu
#define BENCH_GPIOR0   0x3Eu
#define BENCH_GPIOR1   0x4Au
#define BENCH_TWSR     0xB9u
#define BENCH_TWCR     0xBCu
#define BENCH_UCSR0B   0xC1u
#define BENCH_UCSR1A   0xC8u
#define BENCH_UCSR1B   0xC9u
#define BENCH_UBRR1L   0xCCu
#define BENCH_UDR1     0xCEu
#define BENCH_RAMSTART 0x200u
#define BENCH_RAMEND   0x21FFu

/* Process exit codes (docs/bench.md). */
enum {
    BENCH_EXIT_OK = 0,      /* --until matched, or the run ended as asked */
    BENCH_EXIT_FAIL = 1,    /* a --fail-on pattern matched or the final check failed */
    BENCH_EXIT_USAGE = 2,   /* bad option, scenario, ELF or plant config */
    BENCH_EXIT_TIMEOUT = 3, /* the time limit passed before --until matched */
    BENCH_EXIT_CRASHED = 4, /* the firmware stopped (cli+sleep, crash) before --until */
    BENCH_EXIT_SIGNAL = 5   /* interrupted (SIGINT/SIGTERM) */
};

/* Timed scenario events (sim/README.md lists the script syntax). */
typedef enum {
    EV_PRESS,          /* button down; arg0 = hold ms (0 = until release) */
    EV_RELEASE,        /* button up */
    EV_SEND,           /* console line (text), CR LF appended */
    EV_SEND_RAW,       /* console bytes (text) as given */
    EV_POWER_CYCLE,    /* power off and on: EEPROM kept, servos lose multi-turn */
    EV_POWER_LOSS,     /* stop the run here, EEPROM saved as it is */
    EV_WDT_RESET,      /* a watchdog reset (MCUSR = WDRF, SRAM kept) */
    EV_EXT_RESET,      /* reset pin pulse (MCUSR = EXTRF), e.g. a serial DTR */
    EV_SENSOR_UNPLUG,  /* sensor arg0 stops acknowledging */
    EV_SENSOR_PLUG,    /* sensor arg0 is back (powered up fresh) */
    EV_MUX_UNPLUG,     /* the TCA9548A stops acknowledging */
    EV_MUX_PLUG,       /* ... and comes back */
    EV_I2C_STUCK,      /* a slave holds SDA low; arg0 = SCL clocks it needs to let go */
    EV_SERVO_SILENT,   /* servo of tendon arg0 stops answering */
    EV_SERVO_ANSWER,   /* ... and answers again */
    EV_SERVO_HWERR,    /* servo of tendon arg0 raises hardware error bits arg1 */
    EV_BUS_NOISE,      /* corrupt bytes on the servo bus with probability farg */
    EV_MAGNET_REMOVE,  /* the tip magnet falls off */
    EV_MAGNET_RESTORE, /* ... and is put back */
    EV_FIELD,          /* extra field farg3[0..2] uT at sensor arg0 (ambient change) */
    EV_SATURATE,       /* 6 mT at sensor arg0 */
    EV_TENDON_EA,      /* tendon arg0's axial stiffness E*A times farg[0] */
    EV_WEIGHT,         /* farg[0] grams hung on tendon arg0 at the spool side (0 = off) */
    EV_QUIT            /* end the run (exit code as if the time limit passed) */
} bench_ev_kind_t;

/* --survey-weight G[,G2]: masses hung in turn on each weighted tendon; two
 * masses let the fit tell the tendon friction from the stiffness. */
#define BENCH_SURVEY_MASSES 2

typedef struct {
    uint64_t at_us;
    bench_ev_kind_t kind;
    int32_t arg0, arg1;
    double farg[3];
    char text[128];
} bench_event_t;

typedef struct {
    uint64_t t_us;
    uint8_t on;
} bench_led_t;

typedef struct bench_t bench_t;

/* A console-line pattern of --until / --fail-on, or of a scenario's `until`
 * and `fail-on` lines, active in a window of simulated time. */
typedef struct {
    regex_t re;
    uint64_t from_us, to_us; /* active in [from, to) */
    char text[128];
} bench_pattern_t;

/* ---- UART1 half-duplex servo bus (bus.c) ---------------------------------- */

#define BUS_HIST 16u

typedef struct {
    uint64_t start_us, end_us;
    int8_t src; /* -1 = MCU, else servo index */
} bus_window_t;

typedef struct {
    avr_irq_t *rx_irq; /* UART1 INPUT */
    uint8_t dir_tx;    /* PE4 level: 1 = MCU drives the bus */
    uint8_t xoff;      /* simavr's RX FIFO is full */
    uint32_t byte_us;  /* 11 bit times at the MCU's rate (11 us at 1 Mbps) */
    uint32_t mcu_baud; /* UART1's rate at the last MCU byte */
    /* MCU bytes in flight: delivered to the servos at the end of their frame */
    uint8_t mcu_q[256];
    uint64_t mcu_start[256];
    uint64_t mcu_out[256]; /* when simavr gave the byte (its UDR1 write) */
    uint8_t mcu_head, mcu_tail;
    uint64_t mcu_busy_until; /* end of the last MCU frame on the wire */
    /* bytes waiting for room in simavr's RX FIFO */
    uint8_t rx_q[256];
    uint8_t rx_head, rx_tail;
    bus_window_t hist[BUS_HIST];
    uint8_t hist_pos;
    double noise_rate;
    uint64_t rng;
    /* servants */
    xl430 servo[BENCH_MAX_SERVOS];
    uint8_t n_servos;
    uint8_t silent[BENCH_MAX_SERVOS];
    /* counters */
    uint64_t mcu_bytes;        /* bytes the MCU put on the bus */
    uint64_t mcu_bytes_no_dir; /* bytes written with the direction pin in receive */
    uint64_t truncated;        /* frames cut by turning the direction round too early */
    uint64_t servo_bytes;      /* bytes the servos put on the bus */
    uint64_t delivered_rx;     /* bytes raised into UART1 RX */
    uint64_t lost_rx_disabled; /* servo bytes that arrived while RXEN1 = 0 or dir = TX */
    uint64_t collisions;       /* frames that overlapped another frame */
    uint64_t corrupted;        /* bytes corrupted (collision, truncation, noise) */
    uint64_t noise_hits;       /* of which by injected noise */
    uint64_t xoff_events;
    uint64_t baud_mismatch; /* bytes a receiver at another rate could not decode */
    uint8_t trace;          /* --trace bus: every byte and direction change on stderr */
} bench_bus_t;

void bus_init(bench_t *b);
void bus_attach_irqs(bench_t *b);
/* Next cycle the bus needs service at (0 = nothing pending). */
uint64_t bus_next_us(bench_t *b);
/* Does everything due at or before now_us. */
void bus_service(bench_t *b, uint64_t now_us);
void bus_power_cycle(bench_t *b, uint64_t now_us);
void bus_pin_high(bench_t *b);

/* ---- TWI (i2c.c) ------------------------------------------------------------ */

typedef struct {
    avr_irq_t *in_irq;
    uint8_t addr_phase; /* a write address byte was sent: fix its status code */
    int8_t cur;         /* index of the addressed top-level slave, -1 none */
    uint8_t cur_addr;
    simi2c_slave_t top[2];
    uint8_t top_addr[2];
    uint8_t n_top;
    tcam_t mux;
    icmm_t icm[BENCH_MAX_SENSORS];
    uint8_t n_icm;
    uint8_t icm_present[BENCH_MAX_SENSORS];
    /* stuck bus */
    uint8_t stuck;
    int32_t stuck_clocks; /* SCL rising edges still needed */
    uint8_t scl_low;
    uint8_t ext_d_mask, ext_d_value;
    /* counters */
    uint64_t starts, addr_acks, addr_nacks, writes, reads, stops;
    uint64_t stuck_refused; /* bus operations refused while SDA was held low */
    uint64_t stuck_events, scl_clocks, recoveries;
    uint64_t status_fixes;
} bench_twi_t;

void twi_bench_init(bench_t *b, uint32_t seed);
void twi_bench_attach(bench_t *b);
void twi_bench_advance(bench_t *b, uint64_t now_us);
void twi_bench_power_cycle(bench_t *b);
void twi_bench_stick(bench_t *b, int32_t clocks);
/* Applies the SCL/SDA (and idle RXD1/TXD1) levels the bus pull-ups give. */
void twi_bench_lines(bench_t *b);

/* ---- console (console.c) ---------------------------------------------------- */

typedef struct {
    avr_irq_t *rx_irq;
    uint8_t xoff;
    uint8_t *in; /* bytes waiting to go into UART0 RX */
    size_t in_len, in_cap, in_pos;
    char line[BENCH_LINE_MAX];
    size_t line_len;
    int pty_fd; /* master side in interactive mode, else -1 */
    int stdin_fd;
    int control_fd; /* --control: event lines run when read (-1 = none) */
    char ctl_line[256];
    size_t ctl_len;
    uint8_t timestamps;
    uint8_t echo; /* stream console lines to stdout */
    uint64_t bytes_out, bytes_in, lines;
} bench_con_t;

void con_bench_attach(bench_t *b);
void con_bench_queue(bench_t *b, const char *data, size_t n);
void con_bench_pump(bench_t *b);
int con_bench_open_pty(bench_t *b, const char *link);
void con_bench_poll_fds(bench_t *b);
void con_bench_poll_control(bench_t *b);
void con_bench_flush(bench_t *b);

/* ---- ground truth of the invariants (truth.c, docs/chaos.md) --------------- */

#define TRUTH_MAX_STOPS   64u
#define TRUTH_MAX_PENDING 512u  /* console lines awaiting their final reply */
#define TRUTH_SLACK_N     0.001 /* a tendon below 1 mN is released */
/* A line sent this long before a reset (or the end of the run) may still be
 * waiting for a held reply (the console's 3 s deadline): not counted lost. */
#define TRUTH_REPLY_GRACE_US 3500000u

typedef enum {
    TRUTH_STOP_BANG,     /* a `!` byte reached UART0 */
    TRUTH_STOP_FAULT,    /* a `<fault` console line */
    TRUTH_STOP_RELEASED, /* a `<released` console line */
    TRUTH_STOP_WATCHDOG, /* a watchdog reset (injected or the firmware's own) */
    TRUTH_STOP_EXTERNAL, /* a reset-pin reset */
    TRUTH_STOP_POWER     /* a power cycle */
} truth_stop_kind_t;

typedef struct {
    uint64_t t_us;
    uint8_t kind;                        /* truth_stop_kind_t */
    double tension_N;                    /* highest tendon tension at the stop */
    uint64_t all_us;                     /* first tick with every tendon released (0 = not yet) */
    uint64_t slack_us[BENCH_MAX_SERVOS]; /* per tendon, first tick below 1 mN */
} truth_stop_t;

#define TRUTH_MAX_RUNS 16u

typedef struct {
    /* calibration runs: a window per tendon from its first slack reading
     * after the run's start report to its `<result tendon=i` (or the run's
     * end) */
    uint8_t run_active;
    uint32_t runs;
    uint16_t homed_mask;
    uint16_t open_mask; /* tendons slack since the run's start: window open */
    /* the newest single-tendon home the firmware reported per tendon
     * (`<result ... home=`), encoder frame; a power cycle forgets them */
    uint16_t home_known;
    int32_t home_ticks[BENCH_MAX_SERVOS];
    /* the same homes in the shaft's frame, kept over a power cycle */
    uint16_t home_shaft_known;
    double home_shaft[BENCH_MAX_SERVOS];
    double peak_N[BENCH_MAX_SERVOS]; /* highest tension inside the windows */
    uint64_t peak_us[BENCH_MAX_SERVOS];
    /* the highest tension of every tendon in each of the first runs, from
     * its start report to its end, whatever its windows (a held pull's hold,
     * docs/identify.md) */
    double run_peak_N[TRUTH_MAX_RUNS][BENCH_MAX_SERVOS];
    double slack_ticks[BENCH_MAX_SERVOS];       /* deepest slack before the true engagement */
    double start_slack_ticks[BENCH_MAX_SERVOS]; /* deepest slack at a run's start */
    double paid_out_ticks[BENCH_MAX_SERVOS];    /* total motion in the release direction */
    double last_shaft[BENCH_MAX_SERVOS];
    /* baselines: the highest tension between a baseline report and the
     * next progress report */
    uint8_t in_baseline;
    uint32_t baselines, baselines_taut;
    double baseline_max_N;
    /* stops and their releases */
    truth_stop_t stop[TRUTH_MAX_STOPS];
    uint32_t n_stops, stops_dropped;
    /* console accounting */
    uint64_t pending_us[TRUTH_MAX_PENDING];
    uint32_t pend_head, pend_n;
    uint64_t last_reply_us; /* the newest final reply: the line after it is served from then */
    uint8_t last_in;
    uint64_t lines_sent, replies, extra_replies, lost_at_reset, unanswered, excused_overrun;
    uint64_t first_unanswered_us; /* when the first line never answered was sent */
    uint64_t overrun_reports, bangs;
    uint32_t overrun_budget; /* lines an overrun may have cost, not yet seen unanswered */
    /* resets */
    uint64_t injected_resets, resets;
    /* motion loop: the longest servo-bus silence while a run is active */
    uint64_t last_bus_us, max_bus_gap_us, max_bus_gap_at_us;
} bench_truth_t;

/* ---- step chains (steps.c): events triggered by console lines or tension - */

#define STEPS_MAX 160u

typedef struct {
    regex_t re;
    uint8_t has_re;
    uint8_t has_taut; /* waits for a tendon's true tension instead of a line */
    uint8_t taut_tendon;
    double taut_N;
    uint64_t within_us; /* give up waiting after this long (0 = never) */
    uint64_t delay_us;  /* the event runs this long after the match */
    char event[200];    /* "EVENT ARGS", or "nop" */
    char pattern[96];
} bench_step_t;

typedef struct {
    bench_step_t step[STEPS_MAX];
    uint16_t n, cur;
    uint64_t armed_us;     /* the current step sees console lines from here */
    uint64_t last_fire_us; /* the previous step's event time */
    uint64_t fired_us[STEPS_MAX];
    uint8_t timed_out[STEPS_MAX];
    uint16_t n_timed_out;
} bench_steps_t;

/* ---- main-loop pass times (looptime.c) ----------------------------------------- */

#define LOOP_PHASES     16u
#define LOOP_BIN_CYCLES 16u    /* 1 us */
#define LOOP_BINS       50000u /* 50 ms; longer passes land in the last bin */
/* Room markers: app_poll() writes GPIOR1 before each room's call
 * (APP_ROOM_MARK in lib/app/app_priv.h); the n-th write of a pass starts
 * room n, room 0 is the pass's start up to the first marker. */
#define LOOP_ROOMS 12u
/* --loop-profile: the program counter sampled every LOOP_PROF_EVERY cycles
 * of a pass, kept for the worst pass of each phase (room << 24 | PC, the
 * PC a byte address); a pass of up to 32 ms at 16 MHz */
#define LOOP_PROF_EVERY 16u
#define LOOP_PCS        32768u

typedef struct {
    char name[16];
    uint64_t passes;
    uint64_t sum; /* cycles */
    uint64_t max; /* cycles */
    uint64_t max_at_us;
    uint64_t room_max[LOOP_ROOMS];   /* each room's longest share of one pass, cycles */
    uint64_t worst_room[LOOP_ROOMS]; /* the rooms' shares of the worst pass, cycles */
    uint32_t hist[LOOP_BINS];
    uint32_t *worst_pc; /* --loop-profile: the worst pass's samples (malloc'd) */
    uint32_t n_worst_pc;
} loop_phase_t;

typedef struct {
    loop_phase_t phase[LOOP_PHASES];
    uint8_t n_phases;
    uint8_t cur;
    uint64_t last_cycle; /* the last pass marker (0: none since reset) */
    uint64_t room_start; /* the last room marker (or pass marker) */
    uint8_t room;        /* room markers seen in this pass */
    uint8_t rooms_used;  /* the most room markers seen in any pass, + 1 */
    uint64_t pass_room[LOOP_ROOMS];
    uint32_t *pc; /* --loop-profile: this pass's samples (NULL: off) */
    uint32_t n_pc;
    uint64_t prof_next; /* the cycle of the next sample */
} bench_loop_t;

/* ---- the bench ---------------------------------------------------------------- */

#define BENCH_RESET_LOG 32u

typedef struct {
    uint64_t t_us;
    uint8_t mcusr;
} bench_reset_t;

typedef struct {
    avr_io_t io; /* first: simavr hands back this pointer */
    bench_t *b;
} bench_reset_io_t;

struct bench_t {
    avr_t *avr;
    bench_reset_io_t reset_io;
    bench_reset_t reset_log[BENCH_RESET_LOG];
    uint32_t n_reset_log;
    uint8_t in_service;
    uint8_t interactive;
    const char *pty_link;
    const char *input_path;
    /* options */
    const char *elf_path;
    const char *eeprom_path;
    const char *summary_path;
    const char *plant_path;
    const char *table_path;  /* --table: per-tendon table on stdout at exit */
    const char *survey_path; /* --survey: write the identification survey, then exit */
    double survey_travel_mm; /* survey pull past the detected engagement */
    double survey_weight_g[BENCH_SURVEY_MASSES]; /* masses hung in turn on one tendon per
                                                  * segment (0 = none) */
    uint8_t survey_n_weights;                    /* how many of them are given */
    uint8_t survey_weight_all;                   /* --survey-weight-all: on every tendon instead */
    uint8_t survey_held; /* --survey-held: each tendon pulled again, another one held */
    uint64_t limit_us;   /* 0 = none */
    uint32_t seed;
    double perturb;
    double perturb_stiffness; /* backbone EI and EA spread; < 0: perturb's */
    uint8_t servo_baud_index; /* Baud Rate field the servos power up with (3 = 1 Mbps) */
    double tension_N;
    double straight_um[BENCH_MAX_SERVOS]; /* --straight-um: shift to the straight-pose home */
    uint8_t have_straight;
    double start_slack_min_mm, start_slack_max_mm;
    uint8_t realtime;
    uint8_t quiet_stats;
    bench_pattern_t until[BENCH_MAX_PATTERN];
    uint8_t n_until;
    bench_pattern_t fail[BENCH_MAX_PATTERN];
    uint8_t n_fail;
    uint64_t linger_us;     /* run on this long after --until matched */
    uint64_t linger_end_us; /* set when it matched (0 = not yet) */
    uint64_t eewrite_stop;  /* stop after this many EEPROM byte writes (0 = never) */
    /* state */
    bench_con_t con;
    bench_bus_t bus;
    bench_twi_t twi;
    plant_t plant;
    uint8_t have_plant;
    double eng_ticks[BENCH_MAX_SERVOS];         /* true engagement per tendon */
    double max_tension_N[BENCH_MAX_SERVOS];     /* highest spool tension of the run */
    double max_take_up_ticks[BENCH_MAX_SERVOS]; /* deepest pull past the true engagement */
    double moved_from[BENCH_MAX_SERVOS];        /* shaft where it last moved a whole tick */
    uint64_t last_move_us[BENCH_MAX_SERVOS];    /* when (0 = never since power-up) */
    uint64_t fault_at_us;                       /* first `<fault` console line (0 = none) */
    uint64_t released_at_us; /* first time after it with every tendon below 1 mN */
    double fault_tension_N;  /* highest spool tension at the first tick after it */
    uint8_t fault_seen;      /* fault_tension_N taken */
    int32_t target_mN;
    uint8_t magnet_removed;
    double magnet_moment_Am2; /* the moment magnet-restore puts back */
    bench_event_t ev[BENCH_MAX_EVENTS];
    uint16_t n_ev, next_ev;
    uint64_t cal_start_us; /* first button press or cal command */
    uint64_t until_at_us;
    char until_line[BENCH_LINE_MAX];
    bench_led_t led[BENCH_LED_LOG];
    uint32_t n_led;
    uint64_t led_changes;
    uint8_t led_on;
    uint8_t ext_e_mask, ext_e_value;
    uint8_t button_down;
    uint64_t button_release_us; /* pending release of a timed press (0 = none) */
    uint64_t presses;
    uint64_t ee_writes;
    uint8_t ee_image[BENCH_EEPROM_SIZE];
    uint8_t pending_reset; /* 0 none, else an EV_* reset kind to perform */
    uint8_t reset_seen;
    uint64_t resets, wdt_resets, power_cycles;
    uint64_t uart_fixes; /* UART frame times corrected (U2X set after UBRR) */
    uint64_t next_world_us;
    uint64_t timer_at; /* absolute us of the armed service timer */
    bench_truth_t truth;
    bench_steps_t steps;
    bench_loop_t loop;
    /* end of run */
    int stop;
    int exit_code;
    const char *reason;
    char reason_buf[160];
    double wall_start;
};

extern bench_t *bench_signal_target;

static inline uint64_t bench_now_us(const bench_t *b)
{
    return b->avr->cycle / (BENCH_F_CPU / 1000000u);
}

/* main.c: the run loop */
void bench_finish(bench_t *b, int code, const char *reason);
void bench_console_line(bench_t *b, const char *line);
void bench_rearm(bench_t *b);

/* options.c: the command line. What the end of the run reads of it and
 * bench_t does not hold. */
typedef struct {
    double check_pct;         /* --check-tension PCT; < 0: no check */
    uint8_t table;            /* --table */
    uint8_t use_stdin;        /* --stdin */
    uint8_t loop_table;       /* --loop-table */
    const char *loop_profile; /* --loop-profile FILE */
} bench_cli_t;
/* Sets the defaults of b and cli, then the options of argv. Returns -1 to
 * run, else the exit code: BENCH_EXIT_OK after --help (usage on stdout),
 * BENCH_EXIT_USAGE after a bad or missing argument (the reason on stderr). */
int bench_options(bench_t *b, bench_cli_t *cli, int argc, char **argv);
/* Adds an --until (fail = 0) or --fail-on (fail = 1) pattern. Returns 0, or
 * -1 when the expression does not compile or the table is full. */
int bench_add_pattern(bench_t *b, uint8_t fail, const char *re, uint64_t from_us, uint64_t to_us);

/* board.c: the LED pin, the EEPROM image and resets. led_pin is the notify
 * hook of PB7, eecr_write the write hook of EECR (counts EEPROM writes,
 * --power-loss-after-eewrites), reset_hook the io reset hook (notes the
 * reset for the run loop). ee_load reads --eeprom into the EEPROM (erased
 * when the file does not exist) and ee_save writes it back: 0 or -1.
 * after_reset puts back what the board holds after any reset; do_reset
 * performs a reset of kind EV_POWER_CYCLE, EV_WDT_RESET or else external. */
void bench_led_pin(avr_irq_t *irq, uint32_t value, void *param);
void bench_eecr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param);
void bench_reset_hook(avr_io_t *io);
int bench_ee_load(bench_t *b);
int bench_ee_save(bench_t *b);
void bench_after_reset(bench_t *b);
void bench_do_reset(bench_t *b, uint8_t kind);

/* summary.c: writes the JSON summary to b->summary_path (wall and cpu: the
 * run's seconds of wall and CPU time). */
void bench_write_summary(bench_t *b, double wall, double cpu);

/* scenario.c */
int scen_parse_time(const char *s, uint64_t *us);
int scen_load_file(bench_t *b, const char *path);
int scen_add_spec(bench_t *b, const char *spec);
void scen_sort(bench_t *b);
int scen_add_now(bench_t *b, const char *line);
void scen_run_due(bench_t *b, uint64_t now_us);
/* Drives the button pin: down = 1 pulls PE5 low. */
void bench_button(bench_t *b, uint8_t down);

/* world.c: the plant and the models behind the pins */
/* survey.c: the identification survey of the bench's robot (docs/identify.md):
 * each tendon pulled alone, encoder ticks and sensor readings as the firmware
 * sees them, optional hanging weights, and the plant's truth apart. Returns 0
 * or -1 (file, plant). */
int survey_write(bench_t *b, const char *path);

int world_init(bench_t *b);
void world_tick(bench_t *b, uint64_t now_us);
void world_power_cycle(bench_t *b, uint64_t now_us);
/* Writes the per-tendon truth as JSON members to json and/or as the table of
 * `make sim` to table (a result column: pass/FAIL against tol_pct % of the
 * target, or "-" when tol_pct < 0). */
void world_report(bench_t *b, FILE *json, FILE *table, double tol_pct);
/* Counts the tendons whose true tension is outside tol_pct % of the target;
 * when any is, writes a reason naming every one of them into reason[n]. */
int world_check_tension(bench_t *b, double tol_pct, char *reason, size_t n);

/* poses.c: the final pose's truth and the straight pose computed from the
 * homes (docs/homing.md, "Straight-pose homes") */
typedef struct {
    double tip_dev_mm;                  /* tip distance from straight */
    double tension_N[BENCH_MAX_SERVOS]; /* spool-side tension */
} bench_pose_t;
/* The plant as it stands now (after the final move: every tendon at its
 * straight-pose home, or at its single-tendon home with `home_pose` 0) into
 * *now; with --straight-um, every tendon at its single-tendon home
 * (world_home_shaft) minus its shift, reached together from slack
 * (plant_pose_ramp), into *straight. Returns 1 when *straight was computed,
 * 0 when not (no shifts), negative on a plant error. */
int poses_report(bench_t *b, bench_pose_t *now, bench_pose_t *straight);
/* Tendon i's single-tendon home in the plant's shaft frame: the home the
 * firmware reported (before a power cycle too), or, with none reported in
 * this bench run, the servo's goal. */
double world_home_shaft(const bench_t *b, uint8_t i);
/* Parses --straight-um: comma-separated um, one per tendon of the plant
 * (checked at the report). Returns 0 or -1. */
int poses_parse(bench_t *b, const char *list);

/* truth.c: the invariants' measurements (docs/chaos.md) */
void truth_init(bench_t *b);
void truth_tick(bench_t *b, uint64_t now_us);
void truth_line(bench_t *b, const char *line);
void truth_con_in(bench_t *b, uint8_t byte);
void truth_bus_byte(bench_t *b, uint64_t now_us);
void truth_reset(bench_t *b, uint8_t mcusr);
void truth_report(bench_t *b, FILE *json);

/* Main-loop pass times by phase (looptime.c): init hooks the firmware's
 * GPIOR0 pass marker; line follows the phase from console lines; reset drops
 * the pass in flight; report writes JSON members and/or the table. */
void loop_init(bench_t *b);
void loop_reset(bench_t *b);
void loop_line(bench_t *b, const char *line);
void loop_report(bench_t *b, FILE *json, FILE *table);
/* --loop-profile: sampling on (before the run); a sample when due (after
 * each instruction); the worst pass of each phase's samples, as JSON. */
int loop_profile_on(bench_t *b);
void loop_profile_sample(bench_t *b);
int loop_profile_write(const bench_t *b, const char *path);

/* steps.c: `step [on REGEX] [within TIME] [+DELAY] EVENT ARGS` script lines */
int steps_add(bench_t *b, const char *spec);
void steps_line(bench_t *b, const char *line);
void steps_poll(bench_t *b, uint64_t now_us);
void steps_report(bench_t *b, FILE *json);
/* Places the event line "EVENT ARGS" at at_us (not before now). */
int scen_add_at(bench_t *b, uint64_t at_us, const char *line);

#endif /* HALLHOME_BENCH_H */
