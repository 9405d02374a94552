/*
 * hh_bench: runs the firmware ELF on simavr with the simulated board around
 * it. The simulator's set-up, the service timer and the run loop, the
 * console lines' checks (--until, --fail-on) and the end of the run; the
 * command line is in options.c, the LED pin, EEPROM image and resets in
 * board.c, the run summary in summary.c. docs/bench.md is the reference for
 * options, events, output and exit codes.
 */
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <stdarg.h>
#include <string.h>
#include <time.h>

#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_elf.h>
#include <sim_io.h>

#include "bench.h"

bench_t *bench_signal_target;
static volatile sig_atomic_t bench_signalled;
static bench_t bench; /* large (device models): kept out of the stack */

static double wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void on_signal(int sig)
{
    (void)sig;
    bench_signalled = 1;
}

/* The default callback sleeps in wall time; a sleeping firmware must not
 * hold the simulation back (pacing, when asked for, is done in the loop). */
static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr;
    (void)how_long;
}

void bench_finish(bench_t *b, int code, const char *reason)
{
    if (b->stop) {
        return;
    }
    b->stop = 1;
    b->exit_code = code;
    b->reason = reason;
}

void bench_console_line(bench_t *b, const char *line)
{
    if (b->con.echo) {
        if (b->con.timestamps) {
            double t = (double)bench_now_us(b) * 1e-6;
            printf("[%10.6f] %s\n", t, line);
        } else {
            printf("%s\n", line);
        }
        fflush(stdout);
    }
    truth_line(b, line);
    steps_line(b, line);
    loop_line(b, line);
    if (b->fault_at_us == 0 && strncmp(line, "<fault", 6) == 0) {
        b->fault_at_us = bench_now_us(b);
        b->released_at_us = 0;
    }
    if (b->stop) {
        return;
    }
    uint64_t now = bench_now_us(b);
    for (uint8_t i = 0; i < b->n_fail; i++) {
        if (now >= b->fail[i].from_us && now < b->fail[i].to_us &&
            regexec(&b->fail[i].re, line, 0, NULL, 0) == 0) {
            snprintf(b->until_line, sizeof b->until_line, "%s", line);
            b->until_at_us = bench_now_us(b);
            snprintf(b->reason_buf, sizeof b->reason_buf, "fail-on matched: %s", b->fail[i].text);
            bench_finish(b, BENCH_EXIT_FAIL, b->reason_buf);
            return;
        }
    }
    for (uint8_t i = 0; i < b->n_until && b->linger_end_us == 0; i++) {
        if (now >= b->until[i].from_us && now < b->until[i].to_us &&
            regexec(&b->until[i].re, line, 0, NULL, 0) == 0) {
            snprintf(b->until_line, sizeof b->until_line, "%s", line);
            b->until_at_us = bench_now_us(b);
            if (b->linger_us == 0) {
                bench_finish(b, BENCH_EXIT_OK, "until matched");
            } else {
                b->linger_end_us = b->until_at_us + b->linger_us; /* let saves finish */
            }
            return;
        }
    }
}

/* simavr's messages (load report, warnings) go to stderr: standard output
 * carries only the console. */
static void bench_logger(avr_t *avr, const int level, const char *format, va_list ap)
{
    if (avr == NULL || level <= avr->log) {
        vfprintf(stderr, format, ap);
    }
}

/* ---- the one service timer: bus bytes, world ticks, scenario events --------- */

static uint64_t next_event_us(bench_t *b)
{
    uint64_t next = bus_next_us(b);
    uint64_t cand[3] = {b->have_plant ? b->next_world_us : 0,
                        b->next_ev < b->n_ev ? b->ev[b->next_ev].at_us : 0, b->button_release_us};
    if (b->next_ev < b->n_ev && cand[1] == 0) {
        cand[1] = 1; /* an event at t = 0 runs right away */
    }
    for (int i = 0; i < 3; i++) {
        if (cand[i] != 0 && (next == 0 || cand[i] < next)) {
            next = cand[i];
        }
    }
    return next;
}

static avr_cycle_count_t service(avr_t *avr, avr_cycle_count_t when, void *param)
{
    bench_t *b = param;
    uint64_t now = when / (BENCH_F_CPU / 1000000u);
    (void)avr;
    b->in_service = 1;
    bus_service(b, now);
    if (b->have_plant && b->next_world_us <= now) {
        world_tick(b, now);
    }
    if (!b->pending_reset) {
        scen_run_due(b, now);
    }
    bus_service(b, now);
    b->in_service = 0;
    uint64_t next = next_event_us(b);
    if (next == 0 || b->pending_reset) {
        b->timer_at = 0;
        return 0;
    }
    if (next <= now) {
        next = now + 1u;
    }
    b->timer_at = next;
    return (avr_cycle_count_t)next * (BENCH_F_CPU / 1000000u);
}

void bench_rearm(bench_t *b)
{
    if (b->in_service) {
        return;
    }
    uint64_t now = bench_now_us(b);
    uint64_t next = next_event_us(b);
    if (next == 0 || (b->timer_at != 0 && b->timer_at <= next)) {
        return;
    }
    if (next <= now) {
        next = now + 1u;
    }
    avr_cycle_timer_cancel(b->avr, service, b);
    avr_cycle_timer_register(b->avr, (next - now) * (BENCH_F_CPU / 1000000u), service, b);
    b->timer_at = next;
}

/* simavr computes a UART's frame time when UBRR is written, reading U2X at
 * that moment; a firmware that sets U2X after UBRR (as the datasheet's
 * examples and uart0_init() do) would get frames twice as long as on the
 * board: the console at half its rate. The bench keeps each UART's frame at
 * 11 bit times of the rate UBRR and U2X select now. */
static void uart_timing_fix(bench_t *b)
{
    for (avr_io_t *io = b->avr->io_port; io != NULL; io = io->next) {
        if (io->kind == NULL || strcmp(io->kind, "uart") != 0) {
            continue;
        }
        avr_uart_t *u = (avr_uart_t *)(void *)io;
        uint32_t ubrr =
            avr_regbit_get(b->avr, u->ubrrl) | (uint32_t)avr_regbit_get(b->avr, u->ubrrh) << 8;
        avr_cycle_count_t want = (avr_cycle_count_t)(ubrr + 1u) * 8u * 11u;
        if (!avr_regbit_get(b->avr, u->u2x)) {
            want *= 2u;
        }
        if (u->cycles_per_byte != 0 && u->cycles_per_byte != want) {
            u->cycles_per_byte = want;
            b->uart_fixes++;
        }
    }
}

int main(int argc, char **argv)
{
    bench_t *b = &bench;
    elf_firmware_t fw;
    bench_cli_t cli;
    int opt_rc = bench_options(b, &cli, argc, argv);
    if (opt_rc >= 0) {
        return opt_rc; /* --help, or a bad command line */
    }

    avr_global_logger_set(bench_logger);
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(b->elf_path, &fw) != 0) {
        fprintf(stderr, "hh_bench: cannot read %s\n", b->elf_path);
        return BENCH_EXIT_USAGE;
    }
    fw.frequency = BENCH_F_CPU;
    snprintf(fw.mmcu, sizeof fw.mmcu, "%s", "atmega2560");
    b->avr = avr_make_mcu_by_name("atmega2560");
    if (b->avr == NULL) {
        fprintf(stderr, "hh_bench: simavr has no atmega2560\n");
        return BENCH_EXIT_USAGE;
    }
    avr_init(b->avr);
    b->avr->log = LOG_WARNING;
    avr_load_firmware(b->avr, &fw);
    b->avr->frequency = BENCH_F_CPU;
    b->avr->sleep = no_sleep;
    for (char u = '0'; u <= '3'; u++) {
        uint32_t flags = 0;
        avr_ioctl(b->avr, AVR_IOCTL_UART_SET_FLAGS(u), &flags);
    }

    b->reset_io.b = b;
    b->reset_io.io.kind = "hh_bench";
    b->reset_io.io.reset = bench_reset_hook;
    avr_register_io(b->avr, &b->reset_io.io);

    con_bench_attach(b);
    bus_init(b);
    bus_attach_irqs(b);
    twi_bench_init(b, b->seed);
    avr_irq_register_notify(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 7), bench_led_pin,
                            b);
    avr_register_io_write(b->avr, BENCH_EECR, bench_eecr_write, b);
    loop_init(b);
    if (cli.loop_profile != NULL && loop_profile_on(b) != 0) {
        fprintf(stderr, "hh_bench: no memory for --loop-profile\n");
        return BENCH_EXIT_USAGE;
    }
    if (bench_ee_load(b) != 0 || world_init(b) != 0) {
        return BENCH_EXIT_USAGE;
    }
    if (b->survey_path != NULL) {
        /* the survey needs the plant as the run would start it, nothing more */
        int rc = survey_write(b, b->survey_path);
        fprintf(stderr, "hh_bench: survey %s %s\n", b->survey_path, rc == 0 ? "written" : "failed");
        return rc == 0 ? BENCH_EXIT_OK : BENCH_EXIT_USAGE;
    }
    twi_bench_attach(b);
    b->avr->data[BENCH_MCUSR] = 0x01u; /* PORF: this run is a power-up */
    bench_button(b, 0);
    scen_sort(b);
    if (b->interactive && con_bench_open_pty(b, b->pty_link) != 0) {
        return BENCH_EXIT_USAGE;
    }
    if (cli.use_stdin) {
        b->con.stdin_fd = 0;
    }
    if (b->input_path != NULL) {
        FILE *f = fopen(b->input_path, "rb");
        char buf[1024];
        size_t n;
        if (f == NULL) {
            perror(b->input_path);
            return BENCH_EXIT_USAGE;
        }
        while ((n = fread(buf, 1, sizeof buf, f)) > 0) {
            con_bench_queue(b, buf, n);
        }
        fclose(f);
    }
    bench_rearm(b);

    bench_signal_target = b;
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGPIPE, SIG_IGN);

    b->wall_start = wall_now();
    double cpu_start = cpu_now();
    uint64_t limit_cycles = b->limit_us * (BENCH_F_CPU / 1000000u);
    uint32_t spin = 0;
    while (!b->stop) {
        int st = avr_run(b->avr);
        if (b->loop.pc != NULL) {
            loop_profile_sample(b);
        }
        if (st == cpu_Done || st == cpu_Crashed) {
            snprintf(b->reason_buf, sizeof b->reason_buf, "firmware %s",
                     st == cpu_Done ? "stopped (sleep with interrupts off)" : "crashed");
            bench_finish(b, b->n_until ? BENCH_EXIT_CRASHED : BENCH_EXIT_OK, b->reason_buf);
            if (b->n_until == 0 && st == cpu_Crashed) {
                b->exit_code = BENCH_EXIT_CRASHED;
            }
            break;
        }
        if (b->reset_seen) {
            b->reset_seen = 0;
            bench_after_reset(b);
        }
        if (b->pending_reset) {
            uint8_t k = b->pending_reset;
            b->pending_reset = 0;
            bench_do_reset(b, k);
        }
        if (b->linger_end_us != 0 && bench_now_us(b) >= b->linger_end_us) {
            bench_finish(b, BENCH_EXIT_OK, "until matched");
        }
        if (limit_cycles != 0 && b->avr->cycle >= limit_cycles) {
            bench_finish(b,
                         b->n_until && b->linger_end_us == 0 ? BENCH_EXIT_TIMEOUT : BENCH_EXIT_OK,
                         b->linger_end_us != 0 ? "until matched" : "time limit");
        }
        if ((++spin & 0x3FFu) == 0) {
            uart_timing_fix(b);
        }
        if ((spin & 0x3FFFu) == 0) {
            if (bench_signalled) {
                bench_finish(b, BENCH_EXIT_SIGNAL, "signal");
            }
            con_bench_poll_fds(b);
            con_bench_poll_control(b);
            con_bench_pump(b);
            if (b->realtime) {
                double ahead = (double)bench_now_us(b) * 1e-6 - (wall_now() - b->wall_start);
                if (ahead > 0.002) {
                    struct timespec ts = {0, (long)((ahead > 0.05 ? 0.05 : ahead) * 1e9)};
                    nanosleep(&ts, NULL);
                }
            }
        }
    }
    double wall = wall_now() - b->wall_start;
    double cpu = cpu_now() - cpu_start;
    con_bench_flush(b);

    if (cli.check_pct >= 0.0 && b->have_plant && b->exit_code == BENCH_EXIT_OK &&
        world_check_tension(b, cli.check_pct, b->reason_buf, sizeof b->reason_buf) > 0) {
        b->reason = b->reason_buf;
        b->exit_code = BENCH_EXIT_FAIL;
    }
    if (bench_ee_save(b) != 0 && b->exit_code == BENCH_EXIT_OK) {
        b->exit_code = BENCH_EXIT_FAIL;
    }
    /* A run cut short (signal, time limit before --until, firmware stop) has
     * no homes to judge: a table of it would only show -100 % errors. */
    if (cli.table && (b->exit_code == BENCH_EXIT_SIGNAL || b->exit_code == BENCH_EXIT_TIMEOUT ||
                      b->exit_code == BENCH_EXIT_CRASHED)) {
        printf("\nno table: the run ended before the calibration did (%s)\n",
               b->reason ? b->reason : "stopped");
    } else if (cli.table) {
        world_report(b, NULL, stdout, cli.check_pct);
        if (b->cal_start_us != 0 && b->until_at_us > b->cal_start_us) {
            printf("calibration time %.3f s simulated\n",
                   (double)(b->until_at_us - b->cal_start_us) * 1e-6);
        }
    }
    if (cli.loop_table) {
        loop_report(b, NULL, stdout);
    }
    if (cli.loop_profile != NULL && loop_profile_write(b, cli.loop_profile) != 0) {
        fprintf(stderr, "hh_bench: cannot write %s\n", cli.loop_profile);
    }
    if (b->summary_path != NULL) {
        bench_write_summary(b, wall, cpu);
    }
    fflush(stdout); /* the table before the verdict on stderr */
    fprintf(
        stderr,
        "hh_bench: %s after %.3f s simulated in %.3f s wall (%.1fx; %.1fx of CPU time), exit %d\n",
        b->reason ? b->reason : "stopped", (double)bench_now_us(b) * 1e-6, wall,
        wall > 0 ? (double)bench_now_us(b) * 1e-6 / wall : 0.0,
        cpu > 0 ? (double)bench_now_us(b) * 1e-6 / cpu : 0.0, b->exit_code);
    return b->exit_code;
}
