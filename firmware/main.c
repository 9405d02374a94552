/*
 * hallhome firmware entry point: board bring-up, then the application's
 * superloop (lib/app). Everything that decides anything is in lib/app; this
 * file only binds the board's drivers to the app's interfaces.
 */
#include <avr/interrupt.h>
#include <avr/pgmspace.h>
#include <string.h>

#include "app/app.h"
#include "board.h"
#include "board_io.h"
#include "eeprom_port.h"
#include "reset.h"
#include "tick.h"
#include "twi.h"
#include "stack.h"
#include "uart0.h"
#include "uart1.h"
#include "version.h"

/* The generated table of ROBOT= (lookup_tables/generated/<robot>.c). A weak
 * reference: when no table was generated the address is NULL and the app
 * reports "no valid lookup table" instead of calibrating with a made-up one. */
#define HH_CAT2(a, b) a##b
#define HH_CAT(a, b)  HH_CAT2(a, b)
#define HH_TABLE      HH_CAT(tbl_table_, HH_ROBOT)
extern const tbl_table_t HH_TABLE __attribute__((weak));

#define STR2(x) #x
#define STR(x)  STR2(x)

static app_t app;
static con_rt_t con_rt;
/* Kept across watchdog and reset-pin resets (the servos keep their positions
 * then); cleared after a power-up, when SRAM holds noise. */
app_win_t app_board_win __attribute__((section(".noinit")));

static uint8_t rt_hook(uint8_t b)
{
    return con_rt_byte(&con_rt, b);
}

static void copy_P(void *dst, const void *src, size_t n)
{
    memcpy_P(dst, src, n);
}

/* tbl_copy_fn has no context: bind the learned-target copy to the one app. */
static void copy_learned(void *dst, const void *src, size_t n)
{
    app_table_copy(&app, dst, src, n);
}

#if CON_IO_FIXED
/* The console's byte I/O (lib/console/console.h, CON_IO_FIXED). */
int16_t con_io_read(void)
{
    return uart0_read();
}

void con_io_write(const char *buf, uint8_t n)
{
    uint8_t i;
    for (i = 0; i < n; i++) {
        uart0_write((uint8_t)buf[i]);
    }
}

uint16_t con_io_room(void)
{
    return uart0_tx_room();
}

void con_io_stage(uint8_t off, const char *buf, uint8_t n)
{
    uart0_tx_stage(off, (const uint8_t *)buf, n);
}

void con_io_commit(uint8_t n)
{
    uart0_tx_commit(n);
}
#else
static int16_t c_read(void *ctx)
{
    (void)ctx;
    return uart0_read();
}

static void c_write(void *ctx, const char *buf, uint8_t n)
{
    uint8_t i;
    (void)ctx;
    for (i = 0; i < n; i++) {
        uart0_write((uint8_t)buf[i]);
    }
}

static uint16_t c_room(void *ctx)
{
    (void)ctx;
    return uart0_tx_room();
}

static const con_io_t con_io = {NULL, c_read, c_write, c_room};
#endif

#if APP_BOARD_FIXED
/* The board as the app sees it (lib/app/app.h, APP_BOARD_FIXED). */
uint32_t app_board_now_ms(void)
{
    return tick_ms();
}

uint32_t app_board_now_us(void)
{
    return tick_us();
}

uint8_t app_board_button(void)
{
    return board_io_button();
}

void app_board_led(uint8_t on)
{
    board_io_led(on);
}

void app_board_wdt_kick(void)
{
    board_io_wdt_kick();
}

uint16_t app_board_rx_lost(void)
{
    return uart0_rx_overruns();
}

uint16_t app_board_stack_free(void)
{
    return stack_free_min();
}

void app_board_con_copy(void *dst, const void *src, size_t n)
{
    memcpy_P(dst, src, n);
}

void app_board_table_copy(void *dst, const void *src, size_t n)
{
    memcpy_P(dst, src, n);
}
#else
static uint32_t b_now_ms(void *ctx)
{
    (void)ctx;
    return tick_ms();
}

static uint32_t b_now_us(void *ctx)
{
    (void)ctx;
    return tick_us();
}

static uint8_t b_button(void *ctx)
{
    (void)ctx;
    return board_io_button();
}

static void b_led(void *ctx, uint8_t on)
{
    (void)ctx;
    board_io_led(on);
}

static void b_kick(void *ctx)
{
    (void)ctx;
    board_io_wdt_kick();
}

static void b_reboot(void *ctx)
{
    (void)ctx;
    uart0_flush();
    board_io_reboot();
}

static uint16_t b_rx_lost(void *ctx)
{
    (void)ctx;
    return uart0_rx_overruns();
}

static const app_board_t board = {NULL,  b_now_ms, b_now_us, b_button,
                                  b_led, b_kick,   b_reboot, b_rx_lost};
#endif

int main(void)
{
    app_io_t io;
    tick_init();
    uart0_init(BOARD_CONSOLE_BAUD);
    uart0_set_rt_hook(rt_hook);
    twi_init();
    board_io_init();
    sei();

    memset(&io, 0, sizeof io);
#if !APP_BOARD_FIXED
    io.board = &board;
    io.stack_free = stack_free_min;
#endif
#if !DXL_PORT_FIXED
    io.servo_port = uart1_port();
#endif
    io.servo_bits = 10;
#if !ICM_BUS_FIXED
    io.sensor_bus = twi_bus();
#endif
    io.mux_addr = BOARD_MUX_ADDR;
#if !STORE_EE_FIXED
    io.eeprom = &eeprom_port;
#endif
    io.store_copy = copy_P;
#if !CON_IO_FIXED
    io.console = &con_io;
#endif
    io.con_copy = copy_P;
    io.rt = &con_rt;
    io.table = &HH_TABLE;
    io.table_copy = copy_P;
    io.table_copy_learned = copy_learned;
    io.version_f = PSTR(HH_VERSION);
    io.board_f = PSTR(BOARD_NAME);
    io.reset_f = reset_cause_P();
    io.release_at_boot = (reset_flags() & RESET_WATCHDOG) != 0u;
    if (reset_flags() & (RESET_POWER | RESET_BROWNOUT)) {
        memset(&app_board_win, 0, sizeof app_board_win);
    }
#if !APP_BOARD_FIXED
    io.win = &app_board_win; /* else the app uses app_board_win itself */
#endif
    (void)app_init(&app, &io);
    uart1_init(app_bus_baud(&app));
    board_io_wdt_start();
    for (;;) {
        /* pass marker: the virtual bench times each pass by this write
         * (sim/bench/looptime.c); one OUT instruction on the chip */
        GPIOR0 = 0;
        (void)app_poll(&app);
        stack_sweep();
    }
}
