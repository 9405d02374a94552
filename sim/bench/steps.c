/*
 * steps: a chain of events triggered by the firmware's own console lines, so
 * a script can hit a phase of a calibration (the baseline, the third
 * tendon's fine approach, the EEPROM save) whatever time the earlier phases
 * took. Script and --at lines:
 *
 *     step [on REGEX | taut T:MN] [within TIME] [+DELAY] EVENT [ARGS]
 *
 * The steps run in order. A step waits for a console line matching REGEX
 * (POSIX extended, no spaces: write `.` or `[^0-9]` for them) that comes
 * after the line the previous step matched (or after the previous event,
 * when that step had no pattern or gave up); its event then runs DELAY
 * after that line, and never before the previous step's event. Without `on`
 * the event runs DELAY after the previous one. `within` bounds the wait,
 * counted from the previous event: when no line matched in that time the
 * event runs anyway (counted as timed out), so a stuck firmware does not
 * stop the rest of the script. `taut T:MN` waits instead until tendon T's
 * true tension (the plant's, at the spool) reaches MN millinewtons: a fault
 * meant for a taut tendon then hits one, whatever the firmware's timing
 * (150 ms after an engagement a take-up that ran on may be back at slack).
 * EVENT is any timed event (docs/bench.md) or `nop`.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <string.h>

#include "bench.h"

int steps_add(bench_t *b, const char *spec)
{
    bench_steps_t *c = &b->steps;
    char buf[256];
    char *save = NULL;
    size_t len = strcspn(spec, "\r\n");
    if (c->n >= STEPS_MAX || len >= sizeof buf) {
        return -1;
    }
    bench_step_t *s = &c->step[c->n];
    memset(s, 0, sizeof *s);
    memcpy(buf, spec, len);
    buf[len] = '\0';
    char *p = buf;
    for (;;) {
        while (*p == ' ' || *p == '\t') {
            p++;
        }
        char *end = p + strcspn(p, " \t");
        char word[128];
        size_t wl = (size_t)(end - p);
        if (wl == 0 || wl >= sizeof word) {
            return -1;
        }
        memcpy(word, p, wl);
        word[wl] = '\0';
        if (strcmp(word, "taut") == 0) {
            char *v = end + strspn(end, " \t");
            char *vend = v + strcspn(v, " \t");
            unsigned tendon;
            double mn;
            int used = 0;
            if (s->has_re || s->has_taut || sscanf(v, "%u:%lf%n", &tendon, &mn, &used) != 2 ||
                v + used != vend || tendon >= PLANT_MAX_TENDONS || mn <= 0.0) {
                return -1;
            }
            s->has_taut = 1;
            s->taut_tendon = (uint8_t)tendon;
            s->taut_N = mn * 1e-3;
            p = vend;
        } else if (strcmp(word, "on") == 0 || strcmp(word, "within") == 0) {
            char *v = end + strspn(end, " \t");
            char *vend = v + strcspn(v, " \t");
            size_t vl = (size_t)(vend - v);
            if (vl == 0 || vl >= sizeof s->pattern) {
                return -1;
            }
            char val[96];
            memcpy(val, v, vl);
            val[vl] = '\0';
            if (word[0] == 'o') {
                if (s->has_re || s->has_taut ||
                    regcomp(&s->re, val, REG_EXTENDED | REG_NOSUB) != 0) {
                    return -1;
                }
                s->has_re = 1;
                memcpy(s->pattern, val, vl + 1);
            } else if (scen_parse_time(val, &s->within_us) != 0) {
                return -1;
            }
            p = vend;
        } else if (word[0] == '+') {
            if (scen_parse_time(word + 1, &s->delay_us) != 0) {
                return -1;
            }
            p = end;
        } else {
            break; /* the event */
        }
    }
    if (strlen(p) >= sizeof s->event) {
        return -1;
    }
    strcpy(s->event, p);
    /* check the event now: a bad one is a usage error, not a surprise later */
    if (strncmp(s->event, "nop", 3) != 0) {
        uint16_t before = b->n_ev;
        char probe[256];
        snprintf(probe, sizeof probe, "0 %s", s->event);
        if (strncmp(s->event, "step", 4) == 0 || scen_add_spec(b, probe) != 0 ||
            b->n_ev != before + 1u) {
            if (b->n_ev != before) {
                b->n_ev = before;
            }
            return -1;
        }
        b->n_ev = before; /* parsed only */
    }
    c->n++;
    (void)save;
    return 0;
}

/* The current step matched (or gave up waiting) at at_us: its event runs
 * DELAY later, never before the previous step's event. */
static void fire(bench_t *b, uint64_t at_us, uint8_t timed_out)
{
    bench_steps_t *c = &b->steps;
    bench_step_t *s = &c->step[c->cur];
    uint64_t t = at_us + s->delay_us;
    if (t < c->last_fire_us) {
        t = c->last_fire_us;
    }
    if (strncmp(s->event, "nop", 3) != 0 && scen_add_at(b, t, s->event) != 0) {
        fprintf(stderr, "hh_bench: step %u: event table full\n", c->cur);
    }
    c->fired_us[c->cur] = t;
    c->timed_out[c->cur] = timed_out;
    c->n_timed_out = (uint16_t)(c->n_timed_out + timed_out);
    c->cur++;
    /* the next step sees the lines after this match (those during this
     * step's delay too: a run that ends before the event is not missed) */
    c->armed_us = (s->has_re || s->has_taut) && !timed_out ? at_us : t;
    c->last_fire_us = t;
}

/* Steps without a pattern, and timed-out waits, fire here. */
void steps_poll(bench_t *b, uint64_t now)
{
    bench_steps_t *c = &b->steps;
    while (c->cur < c->n) {
        bench_step_t *s = &c->step[c->cur];
        /* a tension counts from the previous step's event on */
        if (s->has_taut && now >= c->armed_us && now >= c->last_fire_us &&
            s->taut_tendon < b->plant.cfg.n_tendons &&
            b->plant.tension_N[s->taut_tendon] >= s->taut_N) {
            fire(b, now, 0);
        } else if (!s->has_re && !s->has_taut) {
            fire(b, c->last_fire_us, 0);
        } else if (s->within_us != 0 && now >= c->last_fire_us + s->within_us) {
            fire(b, now, 1);
        } else {
            break;
        }
    }
}

void steps_line(bench_t *b, const char *line)
{
    bench_steps_t *c = &b->steps;
    uint64_t now = bench_now_us(b);
    if (c->cur >= c->n || now < c->armed_us) {
        return;
    }
    bench_step_t *s = &c->step[c->cur];
    if (s->has_re && regexec(&s->re, line, 0, NULL, 0) == 0) {
        fire(b, now, 0);
        steps_poll(b, now);
    }
}

void steps_report(bench_t *b, FILE *json)
{
    const bench_steps_t *c = &b->steps;
    fprintf(json, "  \"steps\": {\"count\": %u, \"fired\": %u, \"timed_out\": %u, \"log\": [", c->n,
            c->cur, c->n_timed_out);
    for (uint16_t i = 0; i < c->cur; i++) {
        fprintf(json, "%s[%.6f, %u]", i ? ", " : "", (double)c->fired_us[i] * 1e-6,
                c->timed_out[i]);
    }
    fprintf(json, "]},\n");
}
