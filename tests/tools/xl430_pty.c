/*
 * xl430_pty: servo models (sim/devices/xl430_model.h) on a pseudo-terminal,
 * so that a foreign Protocol 2.0 master (ROBOTIS's Python DynamixelSDK in
 * tests/host/test_dxl_conformance.py) can drive them like servos on a U2D2.
 *
 *   hh_xl430_pty [--boot-ms N] [--return-delay N] ID [ID...]
 *
 * Prints "pty: PATH" on standard output once the models run, then serves
 * until standard input closes. The models run on the real monotonic clock at
 * 1 Mbps with 10 bits per byte (the pty itself does not pace bytes); every
 * byte one servo sends is seen by the others, as on a shared bus.
 */
#define _POSIX_C_SOURCE 200809L
#define _XOPEN_SOURCE   600
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "devices/xl430_model.h"

#define PTY_MAX_SERVOS 8

static uint32_t now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u);
}

static int open_pty(void)
{
    int fd = posix_openpt(O_RDWR | O_NOCTTY);
    if (fd < 0 || grantpt(fd) != 0 || unlockpt(fd) != 0) {
        perror("hh_xl430_pty: pty");
        return -1;
    }
    const char *name = ptsname(fd);
    if (name == NULL) {
        perror("hh_xl430_pty: ptsname");
        return -1;
    }
    /* raw on the servo side, like a USB serial adapter; the slave stays
     * open so that the master side never reads EOF between clients */
    int sfd = open(name, O_RDWR | O_NOCTTY);
    struct termios tio;
    if (sfd < 0 || tcgetattr(sfd, &tio) != 0) {
        perror("hh_xl430_pty: slave");
        return -1;
    }
    tio.c_iflag &= (tcflag_t) ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
    tio.c_oflag &= (tcflag_t)~OPOST;
    tio.c_lflag &= (tcflag_t) ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    tio.c_cflag &= (tcflag_t) ~(CSIZE | PARENB);
    tio.c_cflag |= CS8;
    tcsetattr(sfd, TCSANOW, &tio);
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    printf("pty: %s\n", name);
    fflush(stdout);
    return fd;
}

/* Sends every reply byte that is due and shows it to the other servos. */
static void pump(int fd, xl430 *s, int n, uint32_t t)
{
    for (int k = 0; k < n; k++) {
        uint8_t byte;
        uint32_t due;
        xl430_step(&s[k], t);
        while (xl430_tx_peek(&s[k], &byte, &due) && (int32_t)(t - due) >= 0) {
            xl430_tx_pop(&s[k]);
            if (write(fd, &byte, 1) != 1) {
                perror("hh_xl430_pty: write");
            }
            for (int j = 0; j < n; j++) {
                if (j != k) {
                    xl430_rx(&s[j], byte, due);
                }
            }
        }
    }
}

int main(int argc, char **argv)
{
    static xl430 servo[PTY_MAX_SERVOS];
    uint32_t boot_ms = 100;
    unsigned delay = 0;
    int n = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--boot-ms") == 0 && i + 1 < argc) {
            boot_ms = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--return-delay") == 0 && i + 1 < argc) {
            delay = (unsigned)strtoul(argv[++i], NULL, 10);
        } else if (n < PTY_MAX_SERVOS) {
            xl430_config c;
            xl430_config_default(&c, (uint8_t)strtoul(argv[i], NULL, 10));
            c.return_delay = (uint8_t)delay;
            c.boot_us = boot_ms * 1000u;
            xl430_init(&servo[n++], &c, now_us());
        }
    }
    if (n == 0) {
        fprintf(stderr, "usage: hh_xl430_pty [--boot-ms N] [--return-delay N] ID [ID...]\n");
        return 2;
    }
    int fd = open_pty();
    if (fd < 0) {
        return 1;
    }
    for (;;) {
        struct pollfd p[2] = {{fd, POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
        if (poll(p, 2, 1) < 0) {
            perror("hh_xl430_pty: poll");
            return 1;
        }
        if (p[1].revents != 0) {
            char junk[64];
            if (read(STDIN_FILENO, junk, sizeof junk) <= 0) {
                return 0; /* the test is over */
            }
        }
        uint8_t buf[256];
        ssize_t got = read(fd, buf, sizeof buf);
        uint32_t t = now_us();
        for (ssize_t i = 0; i < got; i++) {
            for (int k = 0; k < n; k++) {
                xl430_rx(&servo[k], buf[i], t);
            }
        }
        pump(fd, servo, n, t);
    }
}
