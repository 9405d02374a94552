/*
 * looptime: the duration of every main-loop pass of the firmware, in CPU
 * cycles, sorted by calibration phase.
 *
 * The firmware writes GPIOR0 once per pass (firmware/main.c); the bench
 * timestamps each write with simavr's cycle count, so a pass is the cycles
 * between two writes, interrupts included, exact to the cycle and free of
 * any effect on the firmware's timing beyond the one OUT instruction. The
 * phase is the one the firmware's last report line named: `<boot`, `<ready`
 * and `<done` (idle), `<progress state=NAME` and `<fault`. A line reaches the
 * bench a little after the pass that printed it, so the pass that changes
 * phase counts in the old one. A reset ends the pass in flight uncounted.
 *
 * Attribution: app_poll() also writes GPIOR1 before each room's call
 * (APP_ROOM_MARK, lib/app/app_priv.h), always the same sequence, so the n-th
 * GPIOR1 write of a pass starts room n (room 0: from the pass marker to the
 * first room marker). Per phase the table gives each room's longest share of
 * a single pass and the rooms' shares of the phase's worst pass.
 *
 * Profile (--loop-profile FILE): the program counter every LOOP_PROF_EVERY
 * cycles of every pass, with the room it fell in; the samples of each
 * phase's worst pass are kept and written as JSON at exit, for
 * `python -m bench.profile` to name the functions the pass spent its time in.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"

/* Closes the room in progress at cycle now. */
static void loop_room_end(bench_loop_t *l, uint64_t now)
{
    uint8_t r = l->room < LOOP_ROOMS ? l->room : (uint8_t)(LOOP_ROOMS - 1u);
    if (l->room_start != 0 && now > l->room_start) {
        l->pass_room[r] += now - l->room_start;
    }
    l->room_start = now;
}

static void loop_room_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    bench_loop_t *l = &((bench_t *)param)->loop;
    (void)addr;
    (void)v;
    loop_room_end(l, avr->cycle);
    if (l->room < 255u) {
        l->room++;
    }
    if (l->room + 1u > l->rooms_used) {
        l->rooms_used = (uint8_t)(l->room + 1u < LOOP_ROOMS ? l->room + 1u : LOOP_ROOMS);
    }
}

static void loop_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    bench_t *b = param;
    bench_loop_t *l = &b->loop;
    (void)addr;
    (void)v;
    uint64_t now = avr->cycle;
    loop_room_end(l, now);
    if (l->last_cycle != 0 && now > l->last_cycle) {
        loop_phase_t *p = &l->phase[l->cur];
        uint64_t c = now - l->last_cycle;
        uint64_t bin = c / LOOP_BIN_CYCLES;
        p->hist[bin < LOOP_BINS ? bin : LOOP_BINS - 1u]++;
        p->passes++;
        p->sum += c;
        if (c > p->max) {
            p->max = c;
            p->max_at_us = bench_now_us(b);
            memcpy(p->worst_room, l->pass_room, sizeof p->worst_room);
            if (l->pc != NULL && (p->worst_pc != NULL ||
                                  (p->worst_pc = malloc(LOOP_PCS * sizeof *p->worst_pc)) != NULL)) {
                memcpy(p->worst_pc, l->pc, l->n_pc * sizeof *l->pc);
                p->n_worst_pc = l->n_pc;
            }
        }
        for (uint8_t r = 0; r < LOOP_ROOMS; r++) {
            if (l->pass_room[r] > p->room_max[r]) {
                p->room_max[r] = l->pass_room[r];
            }
        }
    }
    memset(l->pass_room, 0, sizeof l->pass_room);
    l->room = 0;
    l->last_cycle = now;
    l->n_pc = 0;
}

static uint8_t loop_phase_index(bench_loop_t *l, const char *name, size_t len)
{
    if (len >= sizeof l->phase[0].name) {
        len = sizeof l->phase[0].name - 1u;
    }
    for (uint8_t i = 0; i < l->n_phases; i++) {
        if (strlen(l->phase[i].name) == len && memcmp(l->phase[i].name, name, len) == 0) {
            return i;
        }
    }
    if (l->n_phases >= LOOP_PHASES) {
        return (uint8_t)(LOOP_PHASES - 1u); /* the last one collects the rest */
    }
    loop_phase_t *p = &l->phase[l->n_phases];
    memcpy(p->name, name, len);
    p->name[len] = '\0';
    return l->n_phases++;
}

void loop_init(bench_t *b)
{
    bench_loop_t *l = &b->loop;
    l->n_phases = 0;
    l->cur = loop_phase_index(l, "boot", 4);
    l->last_cycle = 0;
    l->room_start = 0;
    l->room = 0;
    l->rooms_used = 0;
    memset(l->pass_room, 0, sizeof l->pass_room);
    avr_register_io_write(b->avr, BENCH_GPIOR0, loop_write, b);
    avr_register_io_write(b->avr, BENCH_GPIOR1, loop_room_write, b);
}

void loop_reset(bench_t *b)
{
    b->loop.last_cycle = 0;
    b->loop.room_start = 0;
    b->loop.room = 0;
    memset(b->loop.pass_room, 0, sizeof b->loop.pass_room);
    b->loop.cur = loop_phase_index(&b->loop, "boot", 4);
}

void loop_line(bench_t *b, const char *line)
{
    bench_loop_t *l = &b->loop;
    static const char progress[] = "<progress state=";
    if (strncmp(line, progress, sizeof progress - 1u) == 0) {
        const char *name = line + sizeof progress - 1u;
        l->cur = loop_phase_index(l, name, strcspn(name, " >"));
    } else if (strncmp(line, "<ready", 6) == 0 || strncmp(line, "<done", 5) == 0) {
        l->cur = loop_phase_index(l, "idle", 4);
    } else if (strncmp(line, "<fault", 6) == 0) {
        l->cur = loop_phase_index(l, "fault", 5);
    } else if (strncmp(line, "<boot", 5) == 0) {
        l->cur = loop_phase_index(l, "boot", 4);
    }
}

static double loop_us(uint64_t cycles)
{
    return (double)cycles / (double)(BENCH_F_CPU / 1000000u);
}

/* The 99th percentile, to one histogram bin (LOOP_BIN_CYCLES), upper edge. */
static uint64_t loop_p99(const loop_phase_t *p)
{
    uint64_t want = p->passes - p->passes / 100u;
    uint64_t seen = 0;
    for (uint32_t i = 0; i < LOOP_BINS; i++) {
        seen += p->hist[i];
        if (seen >= want) {
            uint64_t edge = (uint64_t)(i + 1u) * LOOP_BIN_CYCLES;
            return edge < p->max ? edge : p->max;
        }
    }
    return p->max;
}

/* The rooms in the order app_poll() marks them (lib/app/app.c). */
static const char *const loop_room_names[LOOP_ROOMS] = {"pre",  "panel",    "sense", "boot",
                                                        "bus",  "run_poll", "step",  "cmd",
                                                        "rest", "rec",      "led",   "post"};

static void loop_room_table(const bench_loop_t *l, FILE *table)
{
    fprintf(table, "\nroom share of a pass, us: longest in any pass / in the phase's worst pass\n");
    fprintf(table, "%-10s", "phase");
    for (uint8_t r = 0; r < l->rooms_used; r++) {
        fprintf(table, " %13s", loop_room_names[r]);
    }
    fprintf(table, "\n");
    for (uint8_t i = 0; i < l->n_phases; i++) {
        const loop_phase_t *p = &l->phase[i];
        if (p->passes == 0) {
            continue;
        }
        fprintf(table, "%-10s", p->name);
        for (uint8_t r = 0; r < l->rooms_used; r++) {
            fprintf(table, " %6.0f/%6.0f", loop_us(p->room_max[r]), loop_us(p->worst_room[r]));
        }
        fprintf(table, "\n");
    }
}

void loop_report(bench_t *b, FILE *json, FILE *table)
{
    const bench_loop_t *l = &b->loop;
    if (json != NULL) {
        fprintf(json, "  \"loop\": {\"bin_us\": %.3f, \"phases\": [", loop_us(LOOP_BIN_CYCLES));
    }
    if (table != NULL) {
        fprintf(table, "\nmain-loop pass by phase (cycles between GPIOR0 writes, 16 MHz)\n");
        fprintf(table, "%-10s %8s %9s %9s %9s %10s\n", "phase", "passes", "mean_us", "p99_us",
                "worst_us", "worst_at_s");
    }
    uint8_t first = 1;
    for (uint8_t i = 0; i < l->n_phases; i++) {
        const loop_phase_t *p = &l->phase[i];
        if (p->passes == 0) {
            continue;
        }
        double mean = loop_us(p->sum) / (double)p->passes;
        if (json != NULL) {
            fprintf(json,
                    "%s{\"name\": \"%s\", \"passes\": %llu, \"mean_us\": %.1f, \"p99_us\": %.1f, "
                    "\"max_us\": %.1f, \"max_at_s\": %.6f}",
                    first ? "" : ", ", p->name, (unsigned long long)p->passes, mean,
                    loop_us(loop_p99(p)), loop_us(p->max), (double)p->max_at_us * 1e-6);
        }
        if (table != NULL) {
            fprintf(table, "%-10s %8llu %9.1f %9.1f %9.1f %10.3f\n", p->name,
                    (unsigned long long)p->passes, mean, loop_us(loop_p99(p)), loop_us(p->max),
                    (double)p->max_at_us * 1e-6);
        }
        first = 0;
    }
    if (json != NULL) {
        fprintf(json, "]},\n");
    }
    if (table != NULL && l->rooms_used > 1u) {
        loop_room_table(l, table);
    }
}

int loop_profile_on(bench_t *b)
{
    b->loop.pc = malloc(LOOP_PCS * sizeof *b->loop.pc);
    b->loop.n_pc = 0;
    b->loop.prof_next = 0;
    return b->loop.pc != NULL ? 0 : -1;
}

void loop_profile_sample(bench_t *b)
{
    bench_loop_t *l = &b->loop;
    uint64_t now = b->avr->cycle;
    if (now < l->prof_next) {
        return;
    }
    if (l->prof_next == 0) {
        l->prof_next = now;
    }
    /* one sample per period elapsed, on a fixed grid of cycles (an
     * instruction takes 1-5 cycles, a sleep many periods): the samples
     * then count the pass's cycles */
    uint32_t room = l->room < LOOP_ROOMS ? l->room : LOOP_ROOMS - 1u;
    while (l->prof_next <= now) {
        l->prof_next += LOOP_PROF_EVERY;
        if (l->last_cycle != 0 && l->n_pc < LOOP_PCS) {
            l->pc[l->n_pc++] = room << 24 | (b->avr->pc & 0xFFFFFFu);
        }
    }
}

int loop_profile_write(const bench_t *b, const char *path)
{
    const bench_loop_t *l = &b->loop;
    FILE *f = fopen(path, "w");
    if (f == NULL) {
        return -1;
    }
    fprintf(f, "{\"every_cycles\": %u, \"f_cpu\": %lu, \"rooms\": [", LOOP_PROF_EVERY,
            (unsigned long)BENCH_F_CPU);
    for (uint8_t r = 0; r < LOOP_ROOMS; r++) {
        fprintf(f, "%s\"%s\"", r ? ", " : "", loop_room_names[r]);
    }
    fprintf(f, "],\n \"phases\": [");
    uint8_t first = 1;
    for (uint8_t i = 0; i < l->n_phases; i++) {
        const loop_phase_t *p = &l->phase[i];
        if (p->passes == 0) {
            continue;
        }
        fprintf(f, "%s\n  {\"name\": \"%s\", \"max_us\": %.1f, \"max_at_s\": %.6f, \"samples\": [",
                first ? "" : ",", p->name, loop_us(p->max), (double)p->max_at_us * 1e-6);
        for (uint32_t k = 0; k < p->n_worst_pc; k++) {
            fprintf(f, "%s%u", k ? "," : "", p->worst_pc[k]);
        }
        fprintf(f, "]}");
        first = 0;
    }
    fprintf(f, "\n]}\n");
    return fclose(f) == 0 ? 0 : -1;
}
