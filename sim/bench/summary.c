/*
 * hh_bench's run summary (--summary): the JSON file written at exit
 * (docs/bench.md describes its members).
 */
#include <stdio.h>

#include "bench.h"

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

void bench_write_summary(bench_t *b, double wall, double cpu)
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
