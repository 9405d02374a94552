/*
 * hh_bench's command line: the usage text, the defaults and the options
 * (docs/bench.md is the reference).
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"

/* ---- command line ------------------------------------------------------------------ */

/* A whole number in [0, max] written in full (decimal, or 0x hex); 0 when
 * it is one, else a message naming the option and -1. */
static int whole(const char *opt, const char *v, unsigned long long max, unsigned long long *out)
{
    char *end = NULL;
    errno = 0;
    unsigned long long n = strtoull(v, &end, 0);
    if (end == v || *end != '\0' || v[0] == '-' || errno != 0 || n > max) {
        fprintf(stderr, "hh_bench: %s takes a whole number 0-%llu, not '%s'\n", opt, max, v);
        return -1;
    }
    *out = n;
    return 0;
}

/* A fraction in [0, 1) written in full; 0 when it is one, else -1. */
static int fraction(const char *opt, const char *v, double *out)
{
    char *end = NULL;
    double x = strtod(v, &end);
    if (end == v || *end != '\0' || !(x >= 0.0 && x < 1.0)) {
        fprintf(stderr, "hh_bench: %s takes a fraction in [0, 1), not '%s'\n", opt, v);
        return -1;
    }
    *out = x;
    return 0;
}

static void usage(FILE *f)
{
    fprintf(
        f,
        "usage: hh_bench [options] FIRMWARE.elf\n"
        "  --limit TIME          stop after this simulated time (e.g. 30s, 500ms)\n"
        "  --until REGEX         end with exit 0 when a console line matches (repeatable)\n"
        "  --linger TIME         after --until matched, run on this long (--fail-on stays)\n"
        "  --fail-on REGEX       end with exit 1 when a console line matches (repeatable)\n"
        "  --at 'TIME EVENT ...' a timed event (repeatable); --scenario FILE: a script of them\n"
        "  --input FILE          console input queued at power-up; --stdin: forward stdin\n"
        "  --control FILE|-      untimed event lines, each run when read (a FIFO, stdin)\n"
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
        "  --servo-baud N        servos' Baud Rate field at power-up (0-7; 3 = 1 Mbps)\n"
        "  --slack MIN:MAX       start slack before engagement in mm (0.3:2)\n"
        "  --survey FILE         write the identification survey of the plant (JSON) and exit\n"
        "  --survey-travel MM    survey pull past the detected engagement (default: the travel\n"
        "                        the unperturbed robot needs for the top grid tension)\n"
        "  --survey-weight G[,G2]  survey: hang G grams on one tendon per segment (0: none);\n"
        "                        G,G2: each mass in turn (the fit then finds the friction)\n"
        "  --survey-weight-all   survey: the weight on every tendon in turn\n"
        "  --survey-held         survey: every tendon pulled again while a tendon of its\n"
        "                        segment holds a bend (its radius, docs/identify.md)\n"
        "  --tension N           calibration tension for the truth table (default: each run's\n"
        "                        own, from its <progress state=start tension_mN=>)\n"
        "  --table               print the per-tendon table at exit\n"
        "  --straight-um U0,U1.. per tendon, um to pay out from its home to its straight-pose\n"
        "                        home: the table adds the tensions of that pose (computed)\n"
        "  --loop-table          print main-loop pass times by phase at exit (mean, p99, worst)\n"
        "  --loop-profile FILE   the program counter every 16 cycles of each phase's worst pass,\n"
        "                        as JSON at exit (python -m bench.profile ELF FILE names them)\n"
        "  --check-tension PCT   exit 1 unless every tendon's true tension at home is within "
        "PCT%%\n"
        "  --trace-bus           every servo-bus byte and direction change on stderr\n"
        "the reference, with the events and the summary: docs/bench.md\n"
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

int bench_options(bench_t *b, bench_cli_t *cli, int argc, char **argv)
{
    cli->check_pct = -1.0;
    cli->table = 0;
    cli->use_stdin = 0;
    cli->loop_table = 0;
    cli->loop_profile = NULL;

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
            cli->use_stdin = 1;
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
            unsigned long long n;
            if (whole(a, v, UINT64_MAX, &n) != 0) {
                return BENCH_EXIT_USAGE;
            }
            b->eewrite_stop = n;
        } else if (strcmp(a, "--summary") == 0) {
            NEEDV();
            b->summary_path = v;
        } else if (strcmp(a, "--plant") == 0) {
            NEEDV();
            b->plant_path = v;
        } else if (strcmp(a, "--seed") == 0) {
            NEEDV();
            unsigned long long n;
            if (whole(a, v, UINT32_MAX, &n) != 0) {
                return BENCH_EXIT_USAGE;
            }
            b->seed = (uint32_t)n;
        } else if (strcmp(a, "--perturb") == 0) {
            NEEDV();
            if (fraction(a, v, &b->perturb) != 0) {
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--perturb-stiffness") == 0) {
            NEEDV();
            if (fraction(a, v, &b->perturb_stiffness) != 0) {
                return BENCH_EXIT_USAGE;
            }
        } else if (strcmp(a, "--servo-baud") == 0) {
            NEEDV();
            unsigned long long n;
            if (whole(a, v, 7, &n) != 0) { /* the control table's Baud Rate values */
                return BENCH_EXIT_USAGE;
            }
            b->servo_baud_index = (uint8_t)n;
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
        } else if (strcmp(a, "--survey-held") == 0) {
            b->survey_held = 1;
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
            cli->table = 1;
        } else if (strcmp(a, "--loop-table") == 0) {
            cli->loop_table = 1;
        } else if (strcmp(a, "--loop-profile") == 0) {
            NEEDV();
            cli->loop_profile = v;
        } else if (strcmp(a, "--check-tension") == 0) {
            NEEDV();
            cli->check_pct = strtod(v, NULL);
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
    return -1;
}
