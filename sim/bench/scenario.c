/*
 * scenario: timed events of a bench run, from --at options and script files
 * (one event per line: `<time> <event> [args]`, `#` starts a comment; times
 * like 1.5s, 250ms, 800us or a bare number of seconds). sim/README.md lists
 * the events.
 */
#define _POSIX_C_SOURCE 200809L
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#include <avr_ioport.h>
#include <sim_io.h>

#include "bench.h"

int scen_parse_time(const char *s, uint64_t *us)
{
    char *end;
    double v = strtod(s, &end);
    double mul = 1e6;
    if (end == s || v < 0) {
        return -1;
    }
    if (strcmp(end, "us") == 0) {
        mul = 1.0;
    } else if (strcmp(end, "ms") == 0) {
        mul = 1e3;
    } else if (strcmp(end, "s") == 0 || *end == '\0') {
        mul = 1e6;
    } else if (strcmp(end, "min") == 0) {
        mul = 60e6;
    } else {
        return -1;
    }
    *us = (uint64_t)(v * mul + 0.5);
    return 0;
}

static const struct {
    const char *name;
    bench_ev_kind_t kind;
    uint8_t nargs; /* required integer/float args */
} scen_names[] = {
    {"press", EV_PRESS, 0},
    {"longpress", EV_PRESS, 0},
    {"release", EV_RELEASE, 0},
    {"send", EV_SEND, 0},
    {"raw", EV_SEND_RAW, 0},
    {"power-cycle", EV_POWER_CYCLE, 0},
    {"power-loss", EV_POWER_LOSS, 0},
    {"wdt-reset", EV_WDT_RESET, 0},
    {"ext-reset", EV_EXT_RESET, 0},
    {"sensor-unplug", EV_SENSOR_UNPLUG, 1},
    {"sensor-plug", EV_SENSOR_PLUG, 1},
    {"mux-unplug", EV_MUX_UNPLUG, 0},
    {"mux-plug", EV_MUX_PLUG, 0},
    {"i2c-stuck", EV_I2C_STUCK, 0},
    {"servo-silent", EV_SERVO_SILENT, 1},
    {"servo-answer", EV_SERVO_ANSWER, 1},
    {"servo-hwerr", EV_SERVO_HWERR, 1},
    {"bus-noise", EV_BUS_NOISE, 1},
    {"magnet-remove", EV_MAGNET_REMOVE, 0},
    {"magnet-restore", EV_MAGNET_RESTORE, 0},
    {"field", EV_FIELD, 4},
    {"saturate", EV_SATURATE, 1},
    {"tendon-stiffness", EV_TENDON_EA, 2},
    {"weight", EV_WEIGHT, 2},
    {"quit", EV_QUIT, 0},
};

/* C-style escapes in raw text: \r \n \t \\ \xHH. */
static void unescape(char *s)
{
    char *o = s;
    while (*s) {
        if (*s == '\\' && s[1]) {
            s++;
            switch (*s) {
            case 'r':
                *o++ = '\r';
                s++;
                break;
            case 'n':
                *o++ = '\n';
                s++;
                break;
            case 't':
                *o++ = '\t';
                s++;
                break;
            case 'x': {
                char hex[3] = {s[1], s[1] ? s[2] : '\0', '\0'};
                *o++ = (char)strtol(hex, NULL, 16);
                s += 1 + strlen(hex);
                break;
            }
            default:
                *o++ = *s++;
                break;
            }
        } else {
            *o++ = *s++;
        }
    }
    *o = '\0';
}

/* "[FROM[-TO]] until|fail-on REGEX": the scenario's expected outcome, matched
 * against console lines from FROM (default 0) until TO (default the end).
 * Returns 1 when the line is one. */
static int scen_pattern_line(bench_t *b, const char *line, int *rc)
{
    uint64_t from = 0, to = UINT64_MAX;
    const char *p = line;
    while (*p == ' ' || *p == '\t') {
        p++;
    }
    if (*p >= '0' && *p <= '9') {
        char tbuf[48];
        size_t n = strcspn(p, " \t");
        if (n >= sizeof tbuf) {
            return 0;
        }
        memcpy(tbuf, p, n);
        tbuf[n] = '\0';
        char *dash = strchr(tbuf, '-');
        if (dash != NULL) {
            *dash = '\0';
            if (scen_parse_time(dash + 1, &to) != 0) {
                return 0;
            }
        }
        if (scen_parse_time(tbuf, &from) != 0) {
            return 0;
        }
        p += n;
        while (*p == ' ' || *p == '\t') {
            p++;
        }
    }
    uint8_t fail;
    if (strncmp(p, "until ", 6) == 0) {
        fail = 0;
        p += 6;
    } else if (strncmp(p, "fail-on ", 8) == 0) {
        fail = 1;
        p += 8;
    } else {
        return 0;
    }
    char re[200];
    size_t n = strcspn(p, "\r\n");
    if (n >= sizeof re) {
        *rc = -1;
        return 1;
    }
    memcpy(re, p, n);
    re[n] = '\0';
    *rc = bench_add_pattern(b, fail, re, from, to);
    return 1;
}

/* "<time> <event> [args]" */
static int scen_add_line(bench_t *b, const char *line)
{
    int prc = 0;
    if (strncmp(line, "step ", 5) == 0) {
        return steps_add(b, line + 5);
    }
    if (line[0] != '#' && scen_pattern_line(b, line, &prc)) {
        return prc;
    }
    char buf[256];
    char *save = NULL;
    size_t len = strlen(line);
    if (len >= sizeof buf) {
        return -1;
    }
    memcpy(buf, line, len + 1);
    char *hash = strchr(buf, '#');
    if (hash != NULL && strncmp(buf, "send", 4) != 0) {
        *hash = '\0';
    }
    char *tok = strtok_r(buf, " \t\r\n", &save);
    if (tok == NULL) {
        return 1; /* blank */
    }
    if (b->n_ev >= BENCH_MAX_EVENTS) {
        return -1;
    }
    bench_event_t *e = &b->ev[b->n_ev];
    memset(e, 0, sizeof *e);
    if (scen_parse_time(tok, &e->at_us) != 0) {
        return -1;
    }
    char *name = strtok_r(NULL, " \t\r\n", &save);
    if (name == NULL) {
        return -1;
    }
    size_t k;
    for (k = 0; k < sizeof scen_names / sizeof scen_names[0]; k++) {
        if (strcmp(name, scen_names[k].name) == 0) {
            break;
        }
    }
    if (k == sizeof scen_names / sizeof scen_names[0]) {
        return -1;
    }
    e->kind = scen_names[k].kind;
    if (e->kind == EV_SEND || e->kind == EV_SEND_RAW) {
        char *rest = save != NULL ? save : (char *)"";
        while (*rest == ' ' || *rest == '\t') {
            rest++;
        }
        size_t n = strcspn(rest, "\r\n");
        if (n >= sizeof e->text) {
            return -1;
        }
        memcpy(e->text, rest, n);
        e->text[n] = '\0';
        if (e->kind == EV_SEND_RAW) {
            unescape(e->text);
        }
        b->n_ev++;
        return 0;
    }
    double v[4] = {0, 0, 0, 0};
    uint8_t n = 0;
    while (n < 4 && (tok = strtok_r(NULL, " \t\r\n", &save)) != NULL) {
        char *end;
        v[n] = strtod(tok, &end);
        if (end == tok || *end != '\0') {
            return -1;
        }
        n++;
    }
    if (n < scen_names[k].nargs) {
        return -1;
    }
    e->arg0 = (int32_t)v[0];
    e->arg1 = (int32_t)v[1];
    switch (e->kind) {
    case EV_PRESS:
        if (strcmp(name, "longpress") == 0) {
            e->arg0 = n > 0 ? (int32_t)v[0] : 2500;
        } else {
            e->arg0 = n > 0 ? (int32_t)v[0] : 150;
        }
        break;
    case EV_I2C_STUCK:
        e->arg0 = n > 0 ? (int32_t)v[0] : 3;
        break;
    case EV_SERVO_HWERR:
        e->arg1 = n > 1 ? (int32_t)v[1] : 0x20; /* overload */
        break;
    case EV_BUS_NOISE:
        e->farg[0] = v[0];
        if (v[0] < 0.0 || v[0] > 1.0) {
            return -1;
        }
        break;
    case EV_TENDON_EA:
        e->farg[0] = v[1];
        if (!(v[1] > 0.0 && v[1] <= 100.0)) {
            return -1;
        }
        break;
    case EV_WEIGHT:
        /* grams; 0 takes the weight off; 10 kg is far beyond any tendon */
        e->farg[0] = v[1];
        if (!(v[1] >= 0.0 && v[1] <= 10000.0)) {
            return -1;
        }
        break;
    case EV_FIELD:
        e->farg[0] = v[1];
        e->farg[1] = v[2];
        e->farg[2] = v[3];
        break;
    default:
        break;
    }
    b->n_ev++;
    return 0;
}

int scen_load_file(bench_t *b, const char *path)
{
    FILE *f = fopen(path, "r");
    char line[256];
    int no = 0;
    if (f == NULL) {
        perror(path);
        return -1;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        no++;
        if (scen_add_line(b, line) < 0) {
            fprintf(stderr, "%s:%d: bad scenario line: %s", path, no, line);
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    return 0;
}

/* --at "TIME EVENT ARGS" (a ':' may separate the time: 2s:press). */
int scen_add_spec(bench_t *b, const char *spec)
{
    char buf[256];
    size_t n = strlen(spec);
    if (n >= sizeof buf) {
        return -1;
    }
    memcpy(buf, spec, n + 1);
    char *colon = strchr(buf, ':');
    char *space = strchr(buf, ' ');
    if (colon != NULL && (space == NULL || colon < space)) {
        *colon = ' ';
    }
    return scen_add_line(b, buf) == 0 ? 0 : -1;
}

/* A control line ("EVENT ARGS", or an until/fail-on line) to run now: the
 * event is placed after every event already due. Returns 0 or -1. */
int scen_add_now(bench_t *b, const char *line)
{
    return scen_add_at(b, bench_now_us(b), line);
}

/* The same at a later time (a step of a chain, steps.c): placed after every
 * event due at or before it. */
int scen_add_at(bench_t *b, uint64_t at_us, const char *line)
{
    char buf[256];
    uint64_t now = bench_now_us(b) > at_us ? bench_now_us(b) : at_us;
    int n = snprintf(buf, sizeof buf, "0 %s", line);
    uint16_t before = b->n_ev;
    if (n < 0 || (size_t)n >= sizeof buf || scen_add_line(b, buf) < 0) {
        return -1;
    }
    if (b->n_ev == before) {
        return 0; /* a pattern line, or blank */
    }
    bench_event_t e = b->ev[b->n_ev - 1];
    e.at_us = now;
    uint16_t j = (uint16_t)(b->n_ev - 1u);
    while (j > b->next_ev && b->ev[j - 1].at_us > now) {
        b->ev[j] = b->ev[j - 1];
        j--;
    }
    b->ev[j] = e;
    bench_rearm(b);
    return 0;
}

static int ev_cmp(const void *a, const void *c)
{
    const bench_event_t *x = a, *y = c;
    return x->at_us < y->at_us ? -1 : x->at_us > y->at_us ? 1 : 0;
}

void scen_sort(bench_t *b)
{
    /* insertion sort keeps the file order of equal times */
    for (uint16_t i = 1; i < b->n_ev; i++) {
        bench_event_t e = b->ev[i];
        uint16_t j = i;
        while (j > 0 && ev_cmp(&b->ev[j - 1], &e) > 0) {
            b->ev[j] = b->ev[j - 1];
            j--;
        }
        b->ev[j] = e;
    }
}

static void sensor_present(bench_t *b, int32_t k, uint8_t on)
{
    if (k < 0 || k >= b->twi.n_icm) {
        fprintf(stderr, "hh_bench: no sensor %d\n", (int)k);
        return;
    }
    icmm_t *m = &b->twi.icm[k];
    if (on && !m->present) {
        uint32_t noise = m->ak.noise_cuT;
        icmm_init(m, m->addr, b->seed + 101u * (uint32_t)k + 13u);
        icmm_set_noise(m, noise, b->seed + 7u * (uint32_t)k + 5u);
        icmm_advance(m, bench_now_us(b));
    }
    m->present = on;
    m->ak.present = on;
}

void scen_run_due(bench_t *b, uint64_t now)
{
    if (b->button_release_us != 0 && b->button_release_us <= now) {
        b->button_release_us = 0;
        bench_button(b, 0);
    }
    steps_poll(b, now);
    while (b->next_ev < b->n_ev && b->ev[b->next_ev].at_us <= now) {
        bench_event_t *e = &b->ev[b->next_ev++];
        switch (e->kind) {
        case EV_PRESS:
            bench_button(b, 1);
            if (b->cal_start_us == 0) {
                b->cal_start_us = now;
            }
            b->button_release_us = e->arg0 > 0 ? now + (uint64_t)e->arg0 * 1000u : 0;
            break;
        case EV_RELEASE:
            bench_button(b, 0);
            break;
        case EV_SEND:
            con_bench_queue(b, e->text, strlen(e->text));
            con_bench_queue(b, "\r\n", 2);
            if (b->cal_start_us == 0 && strncmp(e->text, "cal", 3) == 0) {
                b->cal_start_us = now;
            }
            break;
        case EV_SEND_RAW:
            con_bench_queue(b, e->text, strlen(e->text));
            break;
        case EV_POWER_CYCLE:
        case EV_WDT_RESET:
        case EV_EXT_RESET:
            b->pending_reset = (uint8_t)e->kind;
            b->truth.injected_resets++;
            return; /* the main loop resets; later events wait for it */
        case EV_POWER_LOSS:
            bench_finish(b, BENCH_EXIT_OK, "power-loss");
            return;
        case EV_SENSOR_UNPLUG:
            sensor_present(b, e->arg0, 0);
            break;
        case EV_SENSOR_PLUG:
            sensor_present(b, e->arg0, 1);
            break;
        case EV_MUX_UNPLUG:
            b->twi.mux.present = 0;
            break;
        case EV_MUX_PLUG:
            b->twi.mux.present = 1;
            b->twi.mux.ctrl = 0;
            break;
        case EV_I2C_STUCK:
            twi_bench_stick(b, e->arg0);
            break;
        case EV_SERVO_SILENT:
        case EV_SERVO_ANSWER:
        case EV_SERVO_HWERR:
            if (e->arg0 < 0 || e->arg0 >= b->bus.n_servos) {
                fprintf(stderr, "hh_bench: no servo for tendon %d\n", (int)e->arg0);
                break;
            }
            if (e->kind == EV_SERVO_HWERR) {
                xl430_inject_hw_error(&b->bus.servo[e->arg0], (uint8_t)e->arg1);
            } else {
                b->bus.silent[e->arg0] = (uint8_t)(e->kind == EV_SERVO_SILENT);
            }
            break;
        case EV_BUS_NOISE:
            b->bus.noise_rate = e->farg[0];
            break;
        case EV_MAGNET_REMOVE:
            if (b->have_plant && !b->magnet_removed) {
                b->magnet_moment_Am2 = b->plant.cfg.magnet_moment_Am2;
                b->plant.cfg.magnet_moment_Am2 = 0.0;
            }
            b->magnet_removed = 1;
            break;
        case EV_MAGNET_RESTORE:
            if (b->have_plant && b->magnet_removed) {
                b->plant.cfg.magnet_moment_Am2 = b->magnet_moment_Am2;
            }
            b->magnet_removed = 0;
            break;
        case EV_FIELD:
        case EV_SATURATE:
            if (!b->have_plant || e->arg0 < 0 || e->arg0 >= b->plant.cfg.n_sensors) {
                fprintf(stderr, "hh_bench: no sensor %d in the plant\n", (int)e->arg0);
                break;
            }
            if (e->kind == EV_SATURATE) {
                b->plant.extra_uT[e->arg0][0] = 6000.0;
            } else {
                for (int a = 0; a < 3; a++) {
                    b->plant.extra_uT[e->arg0][a] = e->farg[a];
                }
            }
            break;
        case EV_TENDON_EA:
            /* a more elastic tendon (a spring in line, a stretched or
             * creeping tendon): the same tension takes more spool travel */
            if (!b->have_plant || e->arg0 < 0 || e->arg0 >= b->plant.cfg.n_tendons) {
                fprintf(stderr, "hh_bench: no tendon %d in the plant\n", (int)e->arg0);
                break;
            }
            b->plant.cfg.tendon[e->arg0].ea_N *= e->farg[0];
            (void)plant_solve(&b->plant);
            break;
        case EV_WEIGHT:
            /* a known mass on the tendon at the spool side, its servo slack:
             * the model-free procedure's hanging weight */
            if (!b->have_plant || e->arg0 < 0 || e->arg0 >= b->plant.cfg.n_tendons) {
                fprintf(stderr, "hh_bench: no tendon %d in the plant\n", (int)e->arg0);
                break;
            }
            (void)plant_set_weight(&b->plant, (uint8_t)e->arg0, e->farg[0] * 1e-3 * BENCH_G);
            (void)plant_solve(&b->plant);
            for (uint8_t i = 0; i < b->plant.cfg.n_tendons; i++) {
                if (b->plant.tension_N[i] > b->max_tension_N[i]) {
                    b->max_tension_N[i] = b->plant.tension_N[i];
                }
            }
            break;
        case EV_QUIT:
            bench_finish(b, b->n_until ? BENCH_EXIT_TIMEOUT : BENCH_EXIT_OK, "quit");
            return;
        }
    }
}

/* PE5: switch to ground with the pull-up; the bench drives the pin level.
 * PE6/PE7 are unconnected; they read high here because simavr 1.6 polls
 * INT6/INT7 every cycle while their pins read low (a fifty-fold slowdown). */
void bench_button(bench_t *b, uint8_t down)
{
    avr_ioport_external_t ext;
    b->button_down = down;
    if (down) {
        b->presses++;
    }
    b->ext_e_mask = 0xE0u;
    b->ext_e_value = down ? 0xC0u : 0xE0u;
    ext.name = 'E';
    ext.mask = b->ext_e_mask;
    ext.value = b->ext_e_value;
    avr_ioctl(b->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('E'), &ext);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 5), down ? 0u : 1u);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 6), 1);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 7), 1);
}
