/*
 * hh_bench: runs the firmware ELF on simavr with the simulated board around
 * it. Command line, run loop, resets, EEPROM image and the run summary;
 * docs/bench.md is the reference for options, events, output and exit codes.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <avr_eeprom.h>
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

/* ---- pins, EEPROM, resets ------------------------------------------------------ */

static void led_pin(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    (void)irq;
    uint8_t on = value ? 1u : 0u;
    if (on == b->led_on && b->led_changes > 0) {
        return;
    }
    b->led_on = on;
    b->led_changes++;
    if (b->n_led < BENCH_LED_LOG) {
        b->led[b->n_led].t_us = bench_now_us(b);
        b->led[b->n_led].on = on;
        b->n_led++;
    }
}

static void eecr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    bench_t *b = param;
    (void)avr;
    (void)addr;
    if (v & 0x02u) { /* EEPE: simavr has written the byte */
        b->ee_writes++;
        if (b->eewrite_stop != 0 && b->ee_writes >= b->eewrite_stop) {
            bench_finish(b, BENCH_EXIT_OK, "power-loss after EEPROM write");
        }
    }
}

static void reset_hook(avr_io_t *io)
{
    bench_t *b = ((bench_reset_io_t *)(void *)io)->b;
    b->reset_seen = 1;
}

static void ee_get(bench_t *b, uint8_t *img)
{
    avr_eeprom_desc_t d = {img, 0, BENCH_EEPROM_SIZE};
    avr_ioctl(b->avr, AVR_IOCTL_EEPROM_GET, &d); /* returns -1 even on success */
}

static void ee_set(bench_t *b, uint8_t *img)
{
    avr_eeprom_desc_t d = {img, 0, BENCH_EEPROM_SIZE};
    avr_ioctl(b->avr, AVR_IOCTL_EEPROM_SET, &d);
}

static int ee_load(bench_t *b)
{
    FILE *f;
    memset(b->ee_image, 0xFF, sizeof b->ee_image);
    if (b->eeprom_path == NULL) {
        return 0;
    }
    f = fopen(b->eeprom_path, "rb");
    if (f == NULL) {
        if (errno == ENOENT) {
            ee_set(b, b->ee_image); /* a new board: erased */
            return 0;
        }
        perror(b->eeprom_path);
        return -1;
    }
    size_t n = fread(b->ee_image, 1, sizeof b->ee_image, f);
    fclose(f);
    if (n != sizeof b->ee_image) {
        fprintf(stderr, "hh_bench: %s: %zu bytes, expected %u\n", b->eeprom_path, n,
                BENCH_EEPROM_SIZE);
        return -1;
    }
    ee_set(b, b->ee_image);
    return 0;
}

static int ee_save(bench_t *b)
{
    char tmp[4096];
    FILE *f;
    if (b->eeprom_path == NULL) {
        return 0;
    }
    ee_get(b, b->ee_image);
    snprintf(tmp, sizeof tmp, "%s.tmp", b->eeprom_path);
    f = fopen(tmp, "wb");
    if (f == NULL || fwrite(b->ee_image, 1, sizeof b->ee_image, f) != sizeof b->ee_image) {
        perror(tmp);
        if (f) {
            fclose(f);
        }
        return -1;
    }
    if (fclose(f) != 0 || rename(tmp, b->eeprom_path) != 0) {
        perror(b->eeprom_path);
        return -1;
    }
    return 0;
}

/* The reset cleared the PIN registers, but a pin IRQ keeps its last level
 * and simavr 1.6 filters a raise to the same level: raising the button's PE5
 * high again after a reset left PINE5 reading 0, a button held down from the
 * reset on (the firmware took it for a long press 2 s later), and PD2/PD3,
 * PE6/PE7 low (INT2/3/6/7 polled every cycle). Write the levels the board
 * holds on its inputs into the registers. */
static void held_levels(bench_t *b)
{
    uint8_t *pine = &b->avr->data[BENCH_PINE];
    uint8_t *pind = &b->avr->data[BENCH_PIND];
    *pine = (uint8_t)((*pine & (uint8_t)~b->ext_e_mask) | b->ext_e_value);
    *pind = (uint8_t)((*pind & (uint8_t)~b->twi.ext_d_mask) | b->twi.ext_d_value);
    bus_pin_high(b);
}

/* After any reset (ours or the firmware's watchdog): simavr dropped every
 * host timer and cleared the I/O registers; put back what the board's
 * hardware holds there. */
static void after_reset(bench_t *b)
{
    uint64_t now = bench_now_us(b);
    b->resets++;
    if (b->n_reset_log < BENCH_RESET_LOG) {
        b->reset_log[b->n_reset_log].t_us = now;
        b->reset_log[b->n_reset_log].mcusr = b->avr->data[BENCH_MCUSR];
        b->n_reset_log++;
    }
    if (b->avr->data[BENCH_MCUSR] & 0x08u) {
        b->wdt_resets++;
    }
    truth_reset(b, b->avr->data[BENCH_MCUSR]);
    loop_reset(b);
    b->timer_at = 0;
    b->bus.dir_tx = 0;
    b->bus.mcu_head = b->bus.mcu_tail = 0;
    b->bus.xoff = 0;
    b->con.xoff = 0;
    led_pin(NULL, 0, b);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 4), 0);
    bus_pin_high(b);
    bench_button(b, b->button_down);
    if (b->button_down) {
        b->presses--; /* re-applied, not pressed again */
    }
    twi_bench_advance(b, now);
    b->twi.cur = -1;
    b->twi.addr_phase = 0;
    twi_bench_lines(b);
    held_levels(b);
    bench_rearm(b);
}

static uint64_t sram_rng(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

static void do_reset(bench_t *b, uint8_t kind)
{
    uint64_t now = bench_now_us(b);
    ee_get(b, b->ee_image);
    avr_reset(b->avr);
    ee_set(b, b->ee_image);
    b->reset_seen = 0;
    if (kind == EV_POWER_CYCLE) {
        /* SRAM content is undefined after power-up: no .noinit survives */
        uint64_t s =
            0x2545F4914F6CDD1Dull ^ (b->power_cycles + 1u) * 0x9E3779B97F4A7C15ull ^ b->seed;
        for (unsigned a = BENCH_RAMSTART; a <= BENCH_RAMEND; a++) {
            b->avr->data[a] = (uint8_t)sram_rng(&s);
        }
        b->avr->data[BENCH_MCUSR] = 0x01u; /* PORF */
        b->power_cycles++;
        world_power_cycle(b, now);
    } else if (kind == EV_WDT_RESET) {
        b->avr->data[BENCH_MCUSR] = 0x08u; /* WDRF */
    } else {
        b->avr->data[BENCH_MCUSR] = 0x02u; /* EXTRF */
    }
    after_reset(b);
}

/* ---- summary --------------------------------------------------------------------- */

static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') {
            fprintf(f, "\\%c", c);
        } else if (c < 0x20 || c >= 0x7F) {
            fprintf(f, "\\u%04x", c);
        } else {
            fputc(c, f);
        }
    }
    fputc('"', f);
}

static const char *cause_name(uint8_t mcusr)
{
    if (mcusr & 0x08u) {
        return "watchdog";
    }
    if (mcusr & 0x04u) {
        return "brown-out";
    }
    if (mcusr & 0x01u) {
        return "power";
    }
    if (mcusr & 0x02u) {
        return "external";
    }
    return "software";
}

static void write_summary(bench_t *b, double wall, double cpu)
{
    FILE *f = fopen(b->summary_path, "w");
    double sim = (double)bench_now_us(b) * 1e-6;
    const bench_bus_t *s = &b->bus;
    const bench_twi_t *t = &b->twi;
    if (f == NULL) {
        perror(b->summary_path);
        return;
    }
    fprintf(f, "{\n  \"elf\": ");
    json_str(f, b->elf_path);
    fprintf(f, ",\n  \"exit_code\": %d,\n  \"reason\": ", b->exit_code);
    json_str(f, b->reason ? b->reason : "");
    fprintf(f,
            ",\n  \"sim_s\": %.6f,\n  \"wall_s\": %.3f,\n  \"speed\": %.2f,\n  \"cpu_s\": %.3f,\n"
            "  \"speed_cpu\": %.2f,\n  \"cycles\": %llu,\n",
            sim, wall, wall > 0 ? sim / wall : 0.0, cpu, cpu > 0 ? sim / cpu : 0.0,
            (unsigned long long)b->avr->cycle);
    fprintf(f, "  \"uart_timing_fixes\": %llu,\n", (unsigned long long)b->uart_fixes);
    fprintf(f, "  \"seed\": %u,\n  \"until\": {\"matched\": %s, \"t_s\": %.6f, \"line\": ", b->seed,
            b->until_line[0] ? "true" : "false", (double)b->until_at_us * 1e-6);
    json_str(f, b->until_line);
    fprintf(f, "},\n  \"cal_time_s\": %.6f,\n",
            b->cal_start_us && b->until_at_us > b->cal_start_us
                ? (double)(b->until_at_us - b->cal_start_us) * 1e-6
                : 0.0);
    fprintf(f,
            "  \"console\": {\"bytes_out\": %llu, \"bytes_in\": %llu, \"input_pending\": %llu, "
            "\"lines\": %llu},\n",
            (unsigned long long)b->con.bytes_out, (unsigned long long)b->con.bytes_in,
            (unsigned long long)(b->con.in_len - b->con.in_pos), (unsigned long long)b->con.lines);
    fprintf(f, "  \"led\": {\"on\": %u, \"changes\": %llu, \"log\": [", b->led_on,
            (unsigned long long)b->led_changes);
    for (uint32_t i = 0; i < b->n_led; i++) {
        fprintf(f, "%s[%.6f, %u]", i ? ", " : "", (double)b->led[i].t_us * 1e-6, b->led[i].on);
    }
    fprintf(f, "]},\n  \"button\": {\"presses\": %llu, \"down\": %u},\n",
            (unsigned long long)b->presses, b->button_down);
    fprintf(
        f, "  \"resets\": {\"count\": %llu, \"watchdog\": %llu, \"power_cycles\": %llu, \"log\": [",
        (unsigned long long)b->resets, (unsigned long long)b->wdt_resets,
        (unsigned long long)b->power_cycles);
    for (uint32_t i = 0; i < b->n_reset_log; i++) {
        fprintf(f, "%s{\"t_s\": %.6f, \"cause\": \"%s\"}", i ? ", " : "",
                (double)b->reset_log[i].t_us * 1e-6, cause_name(b->reset_log[i].mcusr));
    }
    fprintf(f, "]},\n  \"eeprom\": {\"path\": ");
    json_str(f, b->eeprom_path ? b->eeprom_path : "");
    fprintf(f, ", \"writes\": %llu},\n", (unsigned long long)b->ee_writes);
    fprintf(
        f,
        "  \"bus\": {\"mcu_bytes\": %llu, \"mcu_bytes_no_dir\": %llu, \"truncated\": %llu, "
        "\"servo_bytes\": %llu, \"rx_delivered\": %llu, \"rx_lost\": %llu, \"collisions\": %llu, "
        "\"corrupted\": %llu, \"noise_hits\": %llu, \"xoff\": %llu, \"baud_mismatch\": %llu, "
        "\"noise_rate\": %g, \"servos\": [",
        (unsigned long long)s->mcu_bytes, (unsigned long long)s->mcu_bytes_no_dir,
        (unsigned long long)s->truncated, (unsigned long long)s->servo_bytes,
        (unsigned long long)s->delivered_rx, (unsigned long long)s->lost_rx_disabled,
        (unsigned long long)s->collisions, (unsigned long long)s->corrupted,
        (unsigned long long)s->noise_hits, (unsigned long long)s->xoff_events,
        (unsigned long long)s->baud_mismatch, s->noise_rate);
    for (uint8_t i = 0; i < s->n_servos; i++) {
        fprintf(f, "%s{\"id\": %u, \"instructions\": %u, \"replies\": %u, \"silent\": %u}",
                i ? ", " : "", s->servo[i].cfg.id, s->servo[i].instructions, s->servo[i].replies,
                s->silent[i]);
    }
    fprintf(f,
            "]},\n  \"twi\": {\"starts\": %llu, \"addr_acks\": %llu, \"addr_nacks\": %llu, "
            "\"writes\": %llu, "
            "\"reads\": %llu, \"stops\": %llu, \"status_fixes\": %llu, \"stuck\": %u, "
            "\"stuck_events\": %llu, \"stuck_refused\": %llu, \"scl_clocks\": %llu, "
            "\"recoveries\": %llu, \"mux_ctrl_writes\": %u, \"sensors\": [",
            (unsigned long long)t->starts, (unsigned long long)t->addr_acks,
            (unsigned long long)t->addr_nacks, (unsigned long long)t->writes,
            (unsigned long long)t->reads, (unsigned long long)t->stops,
            (unsigned long long)t->status_fixes, t->stuck, (unsigned long long)t->stuck_events,
            (unsigned long long)t->stuck_refused, (unsigned long long)t->scl_clocks,
            (unsigned long long)t->recoveries, t->mux.ctrl_writes);
    for (uint8_t k = 0; k < t->n_icm; k++) {
        fprintf(f, "%s{\"present\": %u, \"samples\": %u, \"ext_reads\": %u, \"resets\": %u}",
                k ? ", " : "", t->icm[k].present, t->icm[k].ak.samples, t->icm[k].ext_reads,
                t->icm[k].resets);
    }
    fprintf(f, "]},\n");
    loop_report(b, f, NULL);
    truth_report(b, f);
    world_report(b, f, NULL, -1.0);
    fprintf(f, "\n}\n");
    fclose(f);
}

/* ---- command line ------------------------------------------------------------------ */

static void usage(FILE *f)
{
    fprintf(
        f,
        "usage: hh_bench [options] FIRMWARE.elf\n"
        "  --limit TIME          stop after this simulated time (e.g. 30s, 500ms)\n"
        "  --until REGEX         end with exit 0 when a console line matches (repeatable)\n"
        "  --fail-on REGEX       end with exit 1 when a console line matches (repeatable)\n"
        "  --at 'TIME EVENT ...' a timed event (repeatable); --scenario FILE: a script of them\n"
        "  --input FILE          console input queued at power-up; --stdin: forward stdin\n"
        "  --interactive         console on a pty (path printed; --pty-link PATH adds a symlink)\n"
        "  --realtime            pace simulated time to the wall clock\n"
        "  --timestamps          prefix console lines with the simulated time; --quiet: no "
        "console\n"
        "  --eeprom FILE         EEPROM image (4096 bytes), loaded if it exists, saved at exit\n"
        "  --power-loss-after-eewrites N  stop right after the Nth EEPROM byte write\n"
        "  --summary FILE        JSON summary at exit\n"
        "  --plant FILE          robot plant config (sim/plant); servos and sensors from it\n"
        "  --seed N              seed of the perturbation, the start state and all noise\n"
        "  --perturb FRAC        relative perturbation of the robot's parameters (0.05)\n"
        "  --perturb-stiffness FRAC  the backbone's stiffness (EI, EA) by FRAC instead\n"
        "  --slack MIN:MAX       start slack before engagement in mm (0.3:2)\n"
        "  --survey FILE         write the identification survey of the plant (JSON) and exit\n"
        "  --survey-travel MM    survey pull past the detected engagement (default: the travel\n"
        "                        the unperturbed robot needs for the top grid tension)\n"
        "  --survey-weight G[,G2]  survey: hang G grams on one tendon per segment (0: none);\n"
        "                        G,G2: each mass in turn (the fit then finds the friction)\n"
        "  --survey-weight-all   survey: the weight on every tendon in turn\n"
        "  --tension N           calibration tension for the truth table (plant default)\n"
        "  --table               print the per-tendon table at exit\n"
        "  --straight-um U0,U1.. per tendon, um to pay out from its home to its straight-pose\n"
        "                        home: the table adds the tensions of that pose (computed)\n"
        "  --loop-table          print main-loop pass times by phase at exit (mean, p99, worst)\n"
        "  --check-tension PCT   exit 1 unless every tendon's true tension at home is within "
        "PCT%%\n"
        "exit: 0 ok, 1 fail-on/check, 2 usage, 3 time limit before --until, 4 firmware stopped, "
        "5 signal\n");
}

int bench_add_pattern(bench_t *b, uint8_t fail, const char *re, uint64_t from_us, uint64_t to_us)
{
    bench_pattern_t *tab = fail ? b->fail : b->until;
    uint8_t *n = fail ? &b->n_fail : &b->n_until;
    if (*n >= BENCH_MAX_PATTERN || regcomp(&tab[*n].re, re, REG_EXTENDED | REG_NOSUB) != 0) {
        fprintf(stderr, "hh_bench: bad or too many patterns: %s\n", re);
        return -1;
    }
    tab[*n].from_us = from_us;
    tab[*n].to_us = to_us;
    snprintf(tab[*n].text, sizeof tab[*n].text, "%s", re);
    (*n)++;
    return 0;
}

int main(int argc, char **argv)
{
    bench_t *b = &bench;
    elf_firmware_t fw;
    double check_pct = -1.0;
    uint8_t table = 0, use_stdin = 0, loop_table = 0;

    b->seed = 1;
    b->perturb = 0.05;
    b->perturb_stiffness = -1.0;
    b->servo_baud_index = 3;
    b->start_slack_min_mm = 0.3;
    b->start_slack_max_mm = 2.0;
    b->con.echo = 1;
    b->con.pty_fd = -1;
    b->con.stdin_fd = -1;
    b->con.control_fd = -1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
#define NEEDV()                                                                                    \
    do {                                                                                           \
        if (v == NULL) {                                                                           \
            fprintf(stderr, "hh_bench: %s needs a value\n", a);                                    \
            return BENCH_EXIT_USAGE;                                                               \
        }                                                                                          \
        i++;                                                                                       \
    } while (0)
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--limit") == 0) {
            NEEDV();
            if (scen_parse_time(v, &b->limit_us) != 0) {
                fprintf(stderr, "hh_bench: bad time %s\n", v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--until") == 0) {
            NEEDV();
            if (bench_add_pattern(b, 0, v, 0, UINT64_MAX) != 0) {
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--linger") == 0) {
            NEEDV();
            if (scen_parse_time(v, &b->linger_us) != 0) {
                fprintf(stderr, "hh_bench: bad time %s\n", v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--fail-on") == 0) {
            NEEDV();
            if (bench_add_pattern(b, 1, v, 0, UINT64_MAX) != 0) {
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--at") == 0) {
            NEEDV();
            if (scen_add_spec(b, v) != 0) {
                fprintf(stderr, "hh_bench: bad event: %s\n", v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--scenario") == 0) {
            NEEDV();
            if (scen_load_file(b, v) != 0) {
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--input") == 0) {
            NEEDV();
            b->input_path = v;
        } else if (strcmp(a, "--stdin") == 0) {
            use_stdin = 1;
        } else if (strcmp(a, "--control") == 0) {
            NEEDV();
            b->con.control_fd = strcmp(v, "-") == 0 ? 0 : open(v, O_RDONLY | O_NONBLOCK);
            if (b->con.control_fd < 0) {
                perror(v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--interactive") == 0) {
            b->interactive = 1;
        } else if (strcmp(a, "--pty-link") == 0) {
            NEEDV();
            b->pty_link = v;
        } else if (strcmp(a, "--realtime") == 0) {
            b->realtime = 1;
        } else if (strcmp(a, "--timestamps") == 0) {
            b->con.timestamps = 1;
        } else if (strcmp(a, "--quiet") == 0) {
            b->con.echo = 0;
        } else if (strcmp(a, "--eeprom") == 0) {
            NEEDV();
            b->eeprom_path = v;
        } else if (strcmp(a, "--power-loss-after-eewrites") == 0) {
            NEEDV();
            b->eewrite_stop = strtoull(v, NULL, 10);
        } else if (strcmp(a, "--summary") == 0) {
            NEEDV();
            b->summary_path = v;
        } else if (strcmp(a, "--plant") == 0) {
            NEEDV();
            b->plant_path = v;
        } else if (strcmp(a, "--seed") == 0) {
            NEEDV();
            b->seed = (uint32_t)strtoul(v, NULL, 0);
        } else if (strcmp(a, "--perturb") == 0) {
            NEEDV();
            b->perturb = strtod(v, NULL);
        } else if (strcmp(a, "--perturb-stiffness") == 0) {
            char *end = NULL;
            NEEDV();
            b->perturb_stiffness = strtod(v, &end);
            if (end == v || *end != '\0' ||
                !(b->perturb_stiffness >= 0.0 && b->perturb_stiffness < 1.0)) {
                fprintf(stderr, "hh_bench: --perturb-stiffness takes a fraction in [0, 1)\n");
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--servo-baud") == 0) {
            NEEDV();
            b->servo_baud_index = (uint8_t)strtoul(v, NULL, 10);
            if (b->servo_baud_index > 7) {
                fprintf(stderr, "hh_bench: --servo-baud takes the control table value 0-7\n");
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--slack") == 0) {
            NEEDV();
            if (sscanf(v, "%lf:%lf", &b->start_slack_min_mm, &b->start_slack_max_mm) != 2 ||
                b->start_slack_min_mm < 0 || b->start_slack_max_mm < b->start_slack_min_mm) {
                fprintf(stderr, "hh_bench: bad --slack %s\n", v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--survey") == 0) {
            NEEDV();
            b->survey_path = v;
        } else if (strcmp(a, "--survey-travel") == 0) {
            NEEDV();
            b->survey_travel_mm = strtod(v, NULL);
            if (!(b->survey_travel_mm > 0.0 && b->survey_travel_mm <= 10.0)) {
                fprintf(stderr, "hh_bench: --survey-travel takes 0 < mm <= 10\n");
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--survey-weight-all") == 0) {
            b->survey_weight_all = 1;
        } else if (strcmp(a, "--survey-weight") == 0) {
            const char *q;
            char *end;
            NEEDV();
            b->survey_n_weights = 0;
            for (q = v;; q = end + 1) {
                double g = strtod(q, &end);
                if (end == q || !(g >= 0.0 && g <= 10000.0) || (*end != '\0' && *end != ',') ||
                    b->survey_n_weights == BENCH_SURVEY_MASSES) {
                    fprintf(stderr, "hh_bench: --survey-weight takes G or G,G2: grams, 0..10000\n");
                    return BENCH_EXIT_USAGE;
                }
                b->survey_weight_g[b->survey_n_weights++] = g;
                if (*end == '\0') {
                    break;
                }
            }
        } else if (strcmp(a, "--tension") == 0) {
            NEEDV();
            b->tension_N = strtod(v, NULL);
        } else if (strcmp(a, "--straight-um") == 0) {
            NEEDV();
            if (poses_parse(b, v) != 0) {
                fprintf(stderr, "hh_bench: bad --straight-um %s\n", v);
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--trace-bus") == 0) {
            b->bus.trace = 1;
        } else if (strcmp(a, "--table") == 0) {
            table = 1;
        } else if (strcmp(a, "--loop-table") == 0) {
            loop_table = 1;
        } else if (strcmp(a, "--check-tension") == 0) {
            NEEDV();
            check_pct = strtod(v, NULL);
        } else if (a[0] == '-') {
            fprintf(stderr, "hh_bench: unknown option %s\n", a);
            usage(stderr);
            return BENCH_EXIT_USAGE;
        } else {
            b->elf_path = a;
        }
#undef NEEDV
    }
    if (b->elf_path == NULL) {
        usage(stderr);
        return BENCH_EXIT_USAGE;
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
    b->reset_io.io.reset = reset_hook;
    avr_register_io(b->avr, &b->reset_io.io);

    con_bench_attach(b);
    bus_init(b);
    bus_attach_irqs(b);
    twi_bench_init(b, b->seed);
    avr_irq_register_notify(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('B'), 7), led_pin, b);
    avr_register_io_write(b->avr, BENCH_EECR, eecr_write, b);
    loop_init(b);
    if (ee_load(b) != 0 || world_init(b) != 0) {
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
    if (use_stdin) {
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
            after_reset(b);
        }
        if (b->pending_reset) {
            uint8_t k = b->pending_reset;
            b->pending_reset = 0;
            do_reset(b, k);
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

    if (check_pct >= 0.0 && b->have_plant && b->exit_code == BENCH_EXIT_OK &&
        world_check_tension(b, check_pct, b->reason_buf, sizeof b->reason_buf) > 0) {
        b->reason = b->reason_buf;
        b->exit_code = BENCH_EXIT_FAIL;
    }
    if (ee_save(b) != 0 && b->exit_code == BENCH_EXIT_OK) {
        b->exit_code = BENCH_EXIT_FAIL;
    }
    /* A run cut short (signal, time limit before --until, firmware stop) has
     * no homes to judge: a table of it would only show -100 % errors. */
    if (table && (b->exit_code == BENCH_EXIT_SIGNAL || b->exit_code == BENCH_EXIT_TIMEOUT ||
                  b->exit_code == BENCH_EXIT_CRASHED)) {
        printf("\nno table: the run ended before the calibration did (%s)\n",
               b->reason ? b->reason : "stopped");
    } else if (table) {
        world_report(b, NULL, stdout, check_pct);
        if (b->cal_start_us != 0 && b->until_at_us > b->cal_start_us) {
            printf("calibration time %.3f s simulated\n",
                   (double)(b->until_at_us - b->cal_start_us) * 1e-6);
        }
    }
    if (loop_table) {
        loop_report(b, NULL, stdout);
    }
    if (b->summary_path != NULL) {
        write_summary(b, wall, cpu);
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
