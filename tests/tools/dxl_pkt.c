/*
 * dxl_pkt: builds and parses Protocol 2.0 packets with lib/dxl, one command
 * per input line, one output line per command, so that a host test can hold
 * the C codec against another implementation (ROBOTIS's Python SDK).
 *
 * Commands (numbers decimal, byte strings as contiguous hex, "-" for none):
 *   ping ID | read ID ADDR LEN | write ID ADDR HEX | regwrite ID ADDR HEX
 *   action ID | reboot ID | clear ID | factory ID MODE
 *   syncread ADDR LEN ID,ID.. | fastsyncread ADDR LEN ID,ID..
 *   syncwrite ADDR LEN ID,ID.. HEX | bulkread ID:ADDR:LEN ..
 *   bulkwrite ID:ADDR:HEX .. | status ID ERR HEX | parse HEX
 * Output: the packet as hex, or "error N" (N the negative dxl code); parse
 * prints one item per packet or error, separated by spaces:
 *   status:ID:ERR:HEX, inst:ID:INST:HEX or err:N.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dxl/dxl_proto.h"

#define PKT_CAP 1100u

static int hex_decode(const char *s, uint8_t *out, size_t cap)
{
    if (strcmp(s, "-") == 0) {
        return 0;
    }
    size_t n = strlen(s);
    if (n % 2u != 0 || n / 2u > cap) {
        return -1;
    }
    for (size_t i = 0; i < n / 2u; i++) {
        unsigned v;
        if (sscanf(s + 2u * i, "%2x", &v) != 1) {
            return -1;
        }
        out[i] = (uint8_t)v;
    }
    return (int)(n / 2u);
}

static void hex_print(const uint8_t *b, size_t n)
{
    if (n == 0) {
        fputs("-", stdout);
    }
    for (size_t i = 0; i < n; i++) {
        printf("%02x", b[i]);
    }
}

static int id_list(char *s, uint8_t *ids, int cap)
{
    int n = 0;
    for (char *tok = strtok(s, ","); tok != NULL && n < cap; tok = strtok(NULL, ",")) {
        ids[n++] = (uint8_t)strtoul(tok, NULL, 10);
    }
    return n;
}

static void do_parse(const char *hex)
{
    static uint8_t in[PKT_CAP * 2u];
    uint8_t body[PKT_CAP];
    int n = hex_decode(hex, in, sizeof in);
    if (n < 0) {
        puts("error bad-hex");
        return;
    }
    dxl_parser p;
    dxl_parser_init(&p, body, sizeof body);
    int items = 0;
    for (int i = 0; i < n; i++) {
        int8_t rc = dxl_parser_feed(&p, in[i]);
        if (rc == 1) {
            continue;
        }
        if (items++ > 0) {
            fputs(" ", stdout);
        }
        if (rc < 0) {
            printf("err:%d", rc);
            continue;
        }
        dxl_status st;
        if (dxl_parser_status(&p, &st) == 0) {
            printf("status:%u:%u:", st.id, st.err);
            hex_print(st.params, st.n);
        } else {
            printf("inst:%u:%u:", p.id, p.buf[0]);
            hex_print(p.buf + 1, (size_t)(p.body_len - 1u));
        }
    }
    if (items == 0) {
        fputs("none", stdout);
    }
    fputs("\n", stdout);
}

static int8_t do_line(char *line, uint8_t *pkt, uint16_t *len)
{
    static uint8_t data[PKT_CAP];
    char *argv[64];
    int argc = 0;
    for (char *tok = strtok(line, " \t\r\n"); tok != NULL && argc < 64;
         tok = strtok(NULL, " \t\r\n")) {
        argv[argc++] = tok;
    }
    if (argc == 0) {
        return 1;
    }
    const char *cmd = argv[0];
    unsigned long a1 = argc > 1 ? strtoul(argv[1], NULL, 10) : 0;
    unsigned long a2 = argc > 2 ? strtoul(argv[2], NULL, 10) : 0;
    if (strcmp(cmd, "parse") == 0 && argc == 2) {
        do_parse(argv[1]);
        return 1;
    }
    if (strcmp(cmd, "ping") == 0 && argc == 2) {
        return dxl_build_ping(pkt, PKT_CAP, (uint8_t)a1, len);
    }
    if (strcmp(cmd, "read") == 0 && argc == 4) {
        return dxl_build_read(pkt, PKT_CAP, (uint8_t)a1, (uint16_t)a2,
                              (uint16_t)strtoul(argv[3], NULL, 10), len);
    }
    if ((strcmp(cmd, "write") == 0 || strcmp(cmd, "regwrite") == 0) && argc == 4) {
        int n = hex_decode(argv[3], data, sizeof data);
        if (n < 0) {
            return -DXL_E_ARG;
        }
        return cmd[0] == 'w' ? dxl_build_write(pkt, PKT_CAP, (uint8_t)a1, (uint16_t)a2, data,
                                               (uint16_t)n, len)
                             : dxl_build_reg_write(pkt, PKT_CAP, (uint8_t)a1, (uint16_t)a2, data,
                                                   (uint16_t)n, len);
    }
    if (strcmp(cmd, "action") == 0 && argc == 2) {
        return dxl_build_action(pkt, PKT_CAP, (uint8_t)a1, len);
    }
    if (strcmp(cmd, "reboot") == 0 && argc == 2) {
        return dxl_build_reboot(pkt, PKT_CAP, (uint8_t)a1, len);
    }
    if (strcmp(cmd, "clear") == 0 && argc == 2) {
        return dxl_build_clear_multiturn(pkt, PKT_CAP, (uint8_t)a1, len);
    }
    if (strcmp(cmd, "factory") == 0 && argc == 3) {
        return dxl_build_factory_reset(pkt, PKT_CAP, (uint8_t)a1, (uint8_t)a2,
                                       DXL_FACTORY_RESET_GUARD, len);
    }
    if ((strcmp(cmd, "syncread") == 0 || strcmp(cmd, "fastsyncread") == 0) && argc == 4) {
        uint8_t ids[253];
        int n = id_list(argv[3], ids, 253);
        return cmd[0] == 's' ? dxl_build_sync_read(pkt, PKT_CAP, (uint16_t)a1, (uint16_t)a2, ids,
                                                   (uint8_t)n, len)
                             : dxl_build_fast_sync_read(pkt, PKT_CAP, (uint16_t)a1, (uint16_t)a2,
                                                        ids, (uint8_t)n, len);
    }
    if (strcmp(cmd, "syncwrite") == 0 && argc == 5) {
        uint8_t ids[253];
        int n = id_list(argv[3], ids, 253);
        int d = hex_decode(argv[4], data, sizeof data);
        if (d < 0 || d != n * (int)a2) {
            return -DXL_E_ARG;
        }
        return dxl_build_sync_write(pkt, PKT_CAP, (uint16_t)a1, (uint16_t)a2, ids, data, (uint8_t)n,
                                    len);
    }
    if ((strcmp(cmd, "bulkread") == 0 || strcmp(cmd, "bulkwrite") == 0) && argc >= 2) {
        dxl_bulk_item items[32];
        static uint8_t blobs[32][PKT_CAP / 32u];
        int count = 0;
        for (int i = 1; i < argc && count < 32; i++, count++) {
            char *id = strtok(argv[i], ":");
            char *addr = strtok(NULL, ":");
            char *rest = strtok(NULL, ":");
            if (id == NULL || addr == NULL || rest == NULL) {
                return -DXL_E_ARG;
            }
            items[count].id = (uint8_t)strtoul(id, NULL, 10);
            items[count].addr = (uint16_t)strtoul(addr, NULL, 10);
            items[count].data = NULL;
            if (cmd[4] == 'r') {
                items[count].n = (uint16_t)strtoul(rest, NULL, 10);
            } else {
                int n = hex_decode(rest, blobs[count], sizeof blobs[count]);
                if (n < 0) {
                    return -DXL_E_ARG;
                }
                items[count].n = (uint16_t)n;
                items[count].data = blobs[count];
            }
        }
        return cmd[4] == 'r' ? dxl_build_bulk_read(pkt, PKT_CAP, items, (uint8_t)count, len)
                             : dxl_build_bulk_write(pkt, PKT_CAP, items, (uint8_t)count, len);
    }
    if (strcmp(cmd, "status") == 0 && argc == 4) {
        int n = hex_decode(argv[3], data, sizeof data);
        if (n < 0) {
            return -DXL_E_ARG;
        }
        return dxl_build_status(pkt, PKT_CAP, (uint8_t)a1, (uint8_t)a2, data, (uint16_t)n, len);
    }
    return -DXL_E_ARG;
}

int main(void)
{
    static char line[8192];
    static uint8_t pkt[PKT_CAP];
    while (fgets(line, sizeof line, stdin) != NULL) {
        uint16_t len = 0;
        int8_t rc = do_line(line, pkt, &len);
        if (rc == 1) {
            fflush(stdout);
            continue;
        }
        if (rc < 0) {
            printf("error %d\n", rc);
        } else {
            hex_print(pkt, len);
            fputs("\n", stdout);
        }
        fflush(stdout);
    }
    return 0;
}
