/*
 * truth: the plant's ground truth behind the firmware's invariants, measured
 * on the bench rather than guessed from the console (docs/chaos.md has the
 * definitions; tests/chaos checks them):
 *
 * - peak tension per tendon before its home is recorded: inside a window
 *   that opens once the tendon is slack (below 1 mN) after a run's
 *   `<progress state=start` (the tension it was left with by the last
 *   calibration's final move is not this run's pull) and closes at that
 *   tendon's `<result tendon=i`, at the final move (every tendon, each slack
 *   since the start, sent past its engagement: final_move_sent()) or at the
 *   run's end (`<done`, `<fault`, `<released`, a reset);
 * - every stop (a `!` reaching UART0, a `<fault` or `<released` line, a
 *   reset) and the first tick after it with each tendon, then every tendon,
 *   below 1 mN;
 * - the tension while a baseline is taken (from `<progress state=baseline`
 *   to the next progress report);
 * - slack: the deepest slack before the true engagement, at a run's start
 *   and at any time, and the total spool motion in the release direction;
 * - console lines (terminators reaching UART0) against final replies (`ok`,
 *   `error:`), in order, with the lines a reset or an overrun report cut off;
 * - resets the script did not inject;
 * - the longest servo-bus silence while a run is active.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>

#include "bench.h"

static double take_up_ticks(const bench_t *b, uint8_t i)
{
    return (plant_motor_ticks(&b->plant, i) - b->eng_ticks[i]) *
           (double)b->plant.cfg.tendon[i].pull_dir;
}

static double max_tension(const bench_t *b)
{
    double m = 0.0;
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        if (b->plant.tension_N[i] > m) {
            m = b->plant.tension_N[i];
        }
    }
    return m;
}

/* Every tendon's goal lies past its true engagement: the firmware has sent
 * its final move (or `home`), which it does only once every home of the run
 * is recorded. Seen on the bus, not on the console: a `<result` line can
 * wait behind other output (a `help` listing) and go out after the final
 * move has raised the tensions to the homes' pose (chaos seed 18834: the
 * straight pose's 1.39 x, 6 ms before the last tendon's result). */
static int final_move_sent(const bench_t *b)
{
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        const xl430 *m = &b->bus.servo[i];
        int32_t goal = (int32_t)xl430_get(m, DXL_XL430_GOAL_POSITION_ADDR, 4);
        double g = (double)(goal - xl430_present_position(m)) + xl430_shaft_ticks(m);
        if ((g - b->eng_ticks[i]) * (double)b->plant.cfg.tendon[i].pull_dir <= 0.0) {
            return 0;
        }
    }
    return 1;
}

void truth_init(bench_t *b)
{
    bench_truth_t *t = &b->truth;
    for (uint8_t i = 0; i < b->bus.n_servos; i++) {
        t->last_shaft[i] = plant_motor_ticks(&b->plant, i);
    }
}

static void add_stop(bench_t *b, truth_stop_kind_t kind)
{
    bench_truth_t *t = &b->truth;
    if (!b->have_plant) {
        return;
    }
    if (t->n_stops >= TRUTH_MAX_STOPS) {
        t->stops_dropped++;
        return;
    }
    truth_stop_t *s = &t->stop[t->n_stops++];
    memset(s, 0, sizeof *s);
    s->t_us = bench_now_us(b);
    s->kind = (uint8_t)kind;
    s->tension_N = max_tension(b);
}

static void end_run(bench_truth_t *t)
{
    t->run_active = 0;
    t->in_baseline = 0;
}

/* Replies come in the order of the lines, so a line lost silently leaves the
 * newest line without a reply once the traffic pauses: a line waiting
 * longer than the grace was never answered. Its wait starts when it was
 * sent or when the reply before it came, whichever is later: the lines
 * queued behind a flood of long replies are served one after the other
 * (chaos seed 22844: 21 `help` lines sent within 0.2 s in a calibration,
 * the last one answered 3.5 s later, in order). At a reset the lines sent
 * within the grace were cut off. */
static void settle_pending(bench_truth_t *t, uint64_t now, uint8_t at_reset)
{
    while (t->pend_n > 0) {
        uint64_t sent = t->pending_us[t->pend_head];
        uint64_t from = t->last_reply_us > sent ? t->last_reply_us : sent;
        if (from + TRUTH_REPLY_GRACE_US < now && t->overrun_budget > 0) {
            t->overrun_budget--; /* one of the lines an overrun report owned up to */
            t->excused_overrun++;
        } else if (from + TRUTH_REPLY_GRACE_US < now) {
            if (t->unanswered++ == 0) {
                t->first_unanswered_us = sent;
            }
        } else if (at_reset) {
            t->lost_at_reset++;
        } else {
            break; /* still within its deadline at the end of the run */
        }
        t->pend_head = (t->pend_head + 1u) % TRUTH_MAX_PENDING;
        t->pend_n--;
    }
}

void truth_tick(bench_t *b, uint64_t now)
{
    bench_truth_t *t = &b->truth;
    uint8_t n = b->bus.n_servos;
    for (uint8_t i = 0; i < n; i++) {
        double tension = b->plant.tension_N[i];
        double take = take_up_ticks(b, i);
        double shaft = plant_motor_ticks(&b->plant, i);
        double back = (t->last_shaft[i] - shaft) * (double)b->plant.cfg.tendon[i].pull_dir;
        if (back > 0.0) {
            t->paid_out_ticks[i] += back;
        }
        t->last_shaft[i] = shaft;
        if (-take > t->slack_ticks[i]) {
            t->slack_ticks[i] = -take;
        }
        if (t->run_active && tension < TRUTH_SLACK_N) {
            t->open_mask |= (uint16_t)(1u << i); /* this run's pull starts from slack */
        }
        if (t->run_active && (t->open_mask & ~t->homed_mask & (1u << i)) &&
            tension > t->peak_N[i]) {
            t->peak_N[i] = tension;
            t->peak_us[i] = now;
        }
        if (t->run_active && t->runs <= TRUTH_MAX_RUNS &&
            tension > t->run_peak_N[t->runs - 1u][i]) {
            t->run_peak_N[t->runs - 1u][i] = tension;
        }
        if (t->in_baseline && tension > t->baseline_max_N) {
            t->baseline_max_N = tension;
        }
    }
    if (b->have_plant && t->run_active && n > 1u && t->open_mask == (uint16_t)((1u << n) - 1u) &&
        t->homed_mask != t->open_mask && final_move_sent(b)) {
        /* every tendon was slack in this run and is now sent past its
         * engagement at once: every home is recorded */
        t->homed_mask = t->open_mask;
    }
    /* a line left without its reply for longer than any held reply takes */
    settle_pending(t, now, 0);
    for (uint32_t k = 0; k < t->n_stops; k++) {
        truth_stop_t *s = &t->stop[k];
        if (s->all_us != 0) {
            continue;
        }
        uint8_t all = 1;
        for (uint8_t i = 0; i < n; i++) {
            if (b->plant.tension_N[i] < TRUTH_SLACK_N) {
                if (s->slack_us[i] == 0) {
                    s->slack_us[i] = now > s->t_us ? now : s->t_us + 1u;
                }
            } else {
                all = 0;
            }
        }
        if (all) {
            s->all_us = now > s->t_us ? now : s->t_us + 1u;
        }
    }
}

static int field_int(const char *line, const char *key, int *v)
{
    const char *p = strstr(line, key);
    if (p == NULL) {
        return -1;
    }
    *v = atoi(p + strlen(key));
    return 0;
}

void truth_line(bench_t *b, const char *line)
{
    bench_truth_t *t = &b->truth;
    uint64_t now = bench_now_us(b);
    if ((strcmp(line, "ok") == 0 || strncmp(line, "error:", 6) == 0) &&
        strstr(line, "<boot name=") == NULL) {
        /* a reply a reset cut, completed by the boot report ("error:7 b<boot
         * name=..."), was counted with its line among those the reset lost
         * (chaos seed 3107): not a reply as well */
        t->replies++;
        t->last_reply_us = now;
        if (t->pend_n > 0) {
            t->pend_head = (t->pend_head + 1u) % TRUTH_MAX_PENDING;
            t->pend_n--;
        } else {
            t->extra_replies++;
        }
        return;
    }
    if (strstr(line, "overrun") != NULL) {
        /* Any of the lines waiting now may be the ones the firmware dropped,
         * but the others still get their replies, in order: the queue stays,
         * and up to that many lines may later go unanswered, excused. A lost
         * line shifts the replies onto the lines after it, so the one left
         * over is the newest, whichever line was actually lost. */
        t->overrun_reports++;
        t->overrun_budget += t->pend_n;
    }
    if (strncmp(line, "<progress", 9) == 0) {
        t->in_baseline = 0;
        if (strstr(line, "state=start") != NULL) {
            int mN;
            /* the run is judged at the tension it calibrates at: without
             * --tension that is the board's own (its cal_tension, or the
             * stored homes' in a quick re-home), which an earlier run may
             * have changed in the EEPROM image */
            if (field_int(line, "tension_mN=", &mN) == 0 && mN > 0) {
                if (b->tension_N <= 0.0) {
                    b->target_mN = mN;
                } else if (mN != b->target_mN) {
                    fprintf(stderr,
                            "hh_bench: the run calibrates at %d mN, not at --tension's %d\n", mN,
                            (int)b->target_mN);
                }
            }
            t->run_active = 1;
            t->homed_mask = 0;
            t->open_mask = 0;
            t->runs++;
            for (uint8_t i = 0; i < b->bus.n_servos && b->have_plant; i++) {
                double slack = -take_up_ticks(b, i);
                if (slack > t->start_slack_ticks[i]) {
                    t->start_slack_ticks[i] = slack;
                }
            }
        } else if (strstr(line, "state=baseline") != NULL) {
            double m = max_tension(b);
            t->in_baseline = 1;
            t->baselines++;
            if (m >= TRUTH_SLACK_N) {
                t->baselines_taut++;
            }
            if (m > t->baseline_max_N) {
                t->baseline_max_N = m;
            }
        }
    } else if (strncmp(line, "<result ", 8) == 0) {
        int i;
        int h;
        if (field_int(line, "tendon=", &i) == 0 && i >= 0 && i < (int)BENCH_MAX_SERVOS) {
            t->homed_mask |= (uint16_t)(1u << i);
            if (field_int(line, " home=", &h) == 0) {
                t->home_ticks[i] = h;
                t->home_known |= (uint16_t)(1u << i);
                t->home_shaft_known &= (uint16_t) ~(1u << i);
            }
        }
    } else if (strncmp(line, "<fault", 6) == 0) {
        add_stop(b, TRUTH_STOP_FAULT);
        end_run(t);
    } else if (strncmp(line, "<released", 9) == 0) {
        add_stop(b, TRUTH_STOP_RELEASED);
        end_run(t);
    } else if (strncmp(line, "<done", 5) == 0) {
        end_run(t);
    }
    (void)now;
}

/* A line ends at CR, or at LF unless right after a CR (docs/console.md). */
void truth_con_in(bench_t *b, uint8_t byte)
{
    bench_truth_t *t = &b->truth;
    if (byte == '!') {
        t->bangs++;
        add_stop(b, TRUTH_STOP_BANG);
    } else if (byte == '\r' || (byte == '\n' && t->last_in != '\r')) {
        t->lines_sent++;
        if (t->pend_n < TRUTH_MAX_PENDING) {
            t->pending_us[(t->pend_head + t->pend_n) % TRUTH_MAX_PENDING] = bench_now_us(b);
            t->pend_n++;
        }
    }
    if (byte != '!') {
        t->last_in = byte;
    }
}

void truth_bus_byte(bench_t *b, uint64_t now)
{
    bench_truth_t *t = &b->truth;
    if (t->run_active && t->last_bus_us != 0 && now - t->last_bus_us > t->max_bus_gap_us) {
        t->max_bus_gap_us = now - t->last_bus_us;
        t->max_bus_gap_at_us = now;
    }
    t->last_bus_us = now;
}

void truth_reset(bench_t *b, uint8_t mcusr)
{
    bench_truth_t *t = &b->truth;
    t->resets++;
    settle_pending(t, bench_now_us(b), 1);
    t->last_in = 0;
    t->last_bus_us = 0;
    end_run(t);
    add_stop(b, (mcusr & 0x08u)   ? TRUTH_STOP_WATCHDOG
                : (mcusr & 0x01u) ? TRUTH_STOP_POWER
                                  : TRUTH_STOP_EXTERNAL);
}

static const char *const stop_names[] = {"bang",     "fault",    "released",
                                         "watchdog", "external", "power"};

void truth_report(bench_t *b, FILE *f)
{
    bench_truth_t *t = &b->truth;
    const plant_cfg_t *cfg = &b->plant.cfg;
    uint64_t now = bench_now_us(b);
    double mm = cfg->nm_per_tick / 1e6;
    settle_pending(t, now, 0);
    steps_report(b, f);
    fprintf(f,
            "  \"truth\": {\"runs\": %u, \"baselines\": %u, \"baselines_taut\": %u, "
            "\"baseline_max_mN\": %.1f,\n",
            t->runs, t->baselines, t->baselines_taut, t->baseline_max_N * 1000.0);
    fprintf(f,
            "    \"console\": {\"lines_sent\": %llu, \"replies\": %llu, \"extra_replies\": %llu, "
            "\"unanswered\": %llu, \"first_unanswered_s\": %.6f, \"pending\": %u, "
            "\"lost_at_reset\": %llu, "
            "\"overrun_reports\": %llu, \"excused_overrun\": %llu, \"bangs\": %llu},\n",
            (unsigned long long)t->lines_sent, (unsigned long long)t->replies,
            (unsigned long long)t->extra_replies, (unsigned long long)t->unanswered,
            (double)t->first_unanswered_us * 1e-6, t->pend_n, (unsigned long long)t->lost_at_reset,
            (unsigned long long)t->overrun_reports, (unsigned long long)t->excused_overrun,
            (unsigned long long)t->bangs);
    fprintf(f,
            "    \"resets\": {\"total\": %llu, \"injected\": %llu},\n"
            "    \"max_bus_gap_ms\": %.3f, \"max_bus_gap_at_s\": %.6f,\n",
            (unsigned long long)t->resets, (unsigned long long)t->injected_resets,
            (double)t->max_bus_gap_us * 1e-3, (double)t->max_bus_gap_at_us * 1e-6);
    fprintf(f, "    \"tendons\": [");
    for (uint8_t i = 0; i < b->bus.n_servos && b->have_plant; i++) {
        fprintf(f,
                "%s\n      {\"tendon\": %u, \"peak_before_home_mN\": %.1f, \"peak_at_s\": %.6f, "
                "\"max_slack_mm\": %.4f, \"max_start_slack_mm\": %.4f, \"paid_out_mm\": %.4f}",
                i ? "," : "", i, t->peak_N[i] * 1000.0, (double)t->peak_us[i] * 1e-6,
                t->slack_ticks[i] * mm, t->start_slack_ticks[i] * mm, t->paid_out_ticks[i] * mm);
    }
    fprintf(f, "\n    ],\n    \"run_peaks_mN\": [");
    for (uint32_t r = 0; r < t->runs && r < TRUTH_MAX_RUNS && b->have_plant; r++) {
        fprintf(f, "%s[", r ? ", " : "");
        for (uint8_t i = 0; i < b->bus.n_servos; i++) {
            fprintf(f, "%s%.1f", i ? ", " : "", t->run_peak_N[r][i] * 1000.0);
        }
        fprintf(f, "]");
    }
    fprintf(f, "],\n    \"stops_dropped\": %u,\n    \"stops\": [", t->stops_dropped);
    for (uint32_t k = 0; k < t->n_stops; k++) {
        const truth_stop_t *s = &t->stop[k];
        fprintf(f, "%s\n      {\"kind\": \"%s\", \"t_s\": %.6f, \"tension_mN\": %.1f, ",
                k ? "," : "", stop_names[s->kind], (double)s->t_us * 1e-6, s->tension_N * 1000.0);
        fprintf(f, "\"released_after_ms\": %.3f, \"tendon_ms\": [",
                s->all_us ? (double)(s->all_us - s->t_us) * 1e-3 : -1.0);
        for (uint8_t i = 0; i < b->bus.n_servos; i++) {
            fprintf(f, "%s%.3f", i ? ", " : "",
                    s->slack_us[i] ? (double)(s->slack_us[i] - s->t_us) * 1e-3 : -1.0);
        }
        fprintf(f, "]}");
    }
    fprintf(f, "\n    ]\n  },\n");
}
