/*
 * console: UART0 of the simulated board. Output is cut into lines and
 * streamed to standard output (optionally prefixed with the simulated time)
 * and matched against the run's --until / --fail-on patterns; in interactive
 * mode the raw bytes also go to a pty that host tools open like the board's
 * USB serial port. Input (script, stdin, pty, scenario `send`) is queued and
 * raised into UART0 RX under simavr's XON/XOFF flow control.
 */
#define _POSIX_C_SOURCE 200809L
#define _XOPEN_SOURCE   600
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include <avr_uart.h>
#include <sim_io.h>

#include "bench.h"

static void con_out_byte(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_con_t *c = &b->con;
    char ch = (char)value;
    (void)irq;
    c->bytes_out++;
    if (c->pty_fd >= 0) {
        ssize_t w = write(c->pty_fd, &ch, 1);
        (void)w; /* no reader yet: the byte is lost, as on a closed port */
    }
    if (ch == '\r') {
        return;
    }
    if (ch == '\n' || c->line_len + 1u >= sizeof c->line) {
        c->line[c->line_len] = '\0';
        c->line_len = 0;
        c->lines++;
        bench_console_line(b, c->line);
        return;
    }
    c->line[c->line_len++] = ch;
}

static void con_xon(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    (void)irq;
    (void)value;
    b->con.xoff = 0;
    if (b->con.in_pos < b->con.in_len) {
        con_bench_pump(b);
    }
}

static void con_xoff(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    (void)irq;
    (void)value;
    b->con.xoff = 1;
}

void con_bench_attach(bench_t *b)
{
    avr_t *avr = b->avr;
    b->con.rx_irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            con_out_byte, b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            con_xon, b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            con_xoff, b);
}

void con_bench_queue(bench_t *b, const char *data, size_t n)
{
    bench_con_t *c = &b->con;
    if (c->in_pos == c->in_len) {
        c->in_pos = c->in_len = 0;
    }
    if (c->in_len + n > c->in_cap) {
        size_t cap = c->in_cap ? c->in_cap : 256u;
        while (cap < c->in_len + n) {
            cap *= 2u;
        }
        uint8_t *p = realloc(c->in, cap);
        if (p == NULL) {
            fprintf(stderr, "hh_bench: out of memory for console input\n");
            exit(BENCH_EXIT_USAGE);
        }
        c->in = p;
        c->in_cap = cap;
    }
    memcpy(c->in + c->in_len, data, n);
    c->in_len += n;
    con_bench_pump(b);
}

/* Raises queued bytes while simavr's RX FIFO has room and the firmware's
 * receiver is on (simavr drops bytes that arrive while RXEN0 = 0; a script
 * waits for the firmware instead). The UART paces them into UDR0. */
void con_bench_pump(bench_t *b)
{
    bench_con_t *c = &b->con;
    if (!(b->avr->data[BENCH_UCSR0B] & 0x10u)) {
        return;
    }
    while (!c->xoff && c->in_pos < c->in_len) {
        c->bytes_in++;
        truth_con_in(b, c->in[c->in_pos]);
        avr_raise_irq(c->rx_irq, c->in[c->in_pos++]);
    }
}

int con_bench_open_pty(bench_t *b, const char *link)
{
    int fd = posix_openpt(O_RDWR | O_NOCTTY);
    if (fd < 0 || grantpt(fd) != 0 || unlockpt(fd) != 0) {
        perror("hh_bench: pty");
        return -1;
    }
    const char *name = ptsname(fd);
    struct termios tio;
    if (name == NULL) {
        perror("hh_bench: ptsname");
        return -1;
    }
    /* raw on the board's side, like a USB serial adapter */
    int sfd = open(name, O_RDWR | O_NOCTTY);
    if (sfd >= 0) {
        if (tcgetattr(sfd, &tio) == 0) {
            tio.c_iflag &=
                (tcflag_t) ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
            tio.c_oflag &= (tcflag_t)~OPOST;
            tio.c_lflag &= (tcflag_t) ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
            tio.c_cflag &= (tcflag_t) ~(CSIZE | PARENB);
            tio.c_cflag |= CS8;
            tcsetattr(sfd, TCSANOW, &tio);
        }
        close(sfd);
    }
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    b->con.pty_fd = fd;
    if (link != NULL) {
        unlink(link);
        if (symlink(name, link) != 0) {
            perror("hh_bench: pty link");
        }
    }
    fprintf(stderr, "hh_bench: console pty %s%s%s\n", name, link ? " link " : "", link ? link : "");
    printf("console pty: %s\n", name);
    fflush(stdout);
    return 0;
}

/* Reads what the pty client or stdin typed (non-blocking). */
void con_bench_poll_fds(bench_t *b)
{
    bench_con_t *c = &b->con;
    char buf[256];
    if (c->pty_fd >= 0) {
        ssize_t n = read(c->pty_fd, buf, sizeof buf);
        if (n > 0) {
            con_bench_queue(b, buf, (size_t)n);
        }
    }
    if (c->stdin_fd >= 0) {
        struct pollfd p = {c->stdin_fd, POLLIN, 0};
        if (poll(&p, 1, 0) == 1) {
            ssize_t n = read(c->stdin_fd, buf, sizeof buf);
            if (n > 0) {
                con_bench_queue(b, buf, (size_t)n);
            } else if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
                c->stdin_fd = -1; /* end of input: keep running */
            }
        }
    }
}

/* --control: "EVENT ARGS" lines (press, sensor-unplug 1, ...) from a file,
 * FIFO or standard input, each run at the simulated time it is read. */
void con_bench_poll_control(bench_t *b)
{
    bench_con_t *c = &b->con;
    char buf[128];
    if (c->control_fd < 0) {
        return;
    }
    struct pollfd p = {c->control_fd, POLLIN, 0};
    if (poll(&p, 1, 0) != 1) {
        return;
    }
    ssize_t n = read(c->control_fd, buf, sizeof buf);
    if (n <= 0) {
        if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
            c->control_fd = -1;
        }
        return;
    }
    for (ssize_t i = 0; i < n; i++) {
        char ch = buf[i];
        if (ch == '\n' || ch == '\r') {
            c->ctl_line[c->ctl_len] = '\0';
            if (c->ctl_len > 0 && scen_add_now(b, c->ctl_line) != 0) {
                fprintf(stderr, "hh_bench: bad control line: %s\n", c->ctl_line);
            }
            c->ctl_len = 0;
        } else if (c->ctl_len + 1u < sizeof c->ctl_line) {
            c->ctl_line[c->ctl_len++] = ch;
        }
    }
}

/* A partial last line (no newline yet) is shown at the end of the run. */
void con_bench_flush(bench_t *b)
{
    bench_con_t *c = &b->con;
    if (c->line_len > 0) {
        c->line[c->line_len] = '\0';
        c->line_len = 0;
        bench_console_line(b, c->line);
    }
}
