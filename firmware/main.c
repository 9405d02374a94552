/*
 * hallhome firmware entry point: board bring-up, boot banner, superloop.
 */
#include <avr/interrupt.h>
#include <avr/pgmspace.h>

#include "board.h"
#include "reset.h"
#include "tick.h"
#include "uart0.h"
#include "version.h"

static void banner(void)
{
    uart0_puts_P(PSTR("<boot name=hallhome version=" HH_VERSION " board="));
    uart0_puts_P(PSTR(BOARD_NAME));
    uart0_puts_P(PSTR(" reset="));
    uart0_puts_P(reset_cause_P());
    uart0_puts_P(PSTR(">\r\n"));
}

int main(void)
{
    tick_init();
    uart0_init(BOARD_CONSOLE_BAUD);
    sei();
    banner();
    for (;;) {
    }
}
