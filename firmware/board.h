/*
 * board.h: the one place that names the Arduino Mega 2560's pins and clocks
 * for hallhome. Change wiring here only; every driver reads these macros.
 *
 * Arduino pin numbers are given beside each port bit for readers with a Mega
 * pinout card.
 */
#ifndef HALLHOME_BOARD_H
#define HALLHOME_BOARD_H

#define BOARD_NAME "Arduino Mega 2560"

/* Console: UART0 (USB), 115200 8N1. U2X, UBRR 16 gives +2.1 % (the rate the
 * Arduino bootloader and every Mega sketch use). */
#define BOARD_CONSOLE_BAUD 115200UL

/* Servo bus: UART1, TX1 = PD3 (pin 18), RX1 = PD2 (pin 19), through a
 * 74LVC2G241-style buffer; its direction pin is high to transmit. */
#define BOARD_DXL_BAUD     1000000UL
#define BOARD_DXL_DIR_DDR  DDRE
#define BOARD_DXL_DIR_PORT PORTE
#define BOARD_DXL_DIR_BIT  PE4 /* pin 2 */

/* Sensors: TWI, SDA = PD1 (pin 20), SCL = PD0 (pin 21), 400 kHz, behind a
 * TCA9548A at 0x70. */
#define BOARD_TWI_HZ      400000UL
#define BOARD_TWI_PORT    PORTD
#define BOARD_TWI_DDR     DDRD
#define BOARD_TWI_PIN     PIND
#define BOARD_TWI_SDA_BIT PD1
#define BOARD_TWI_SCL_BIT PD0
#define BOARD_MUX_ADDR    0x70

/* Button: momentary switch to GND, internal pull-up, PE5 (pin 3). The 1 ms
 * tick samples it every 4 ms too (board_io.c): a press is counted once the
 * pin has read up for 8 samples in a row after 8 down. */
#define BOARD_BTN_DDR  DDRE
#define BOARD_BTN_PORT PORTE
#define BOARD_BTN_PIN  PINE
#define BOARD_BTN_BIT  PE5

/* Status LED: PB7 (pin 13, the Mega's on-board LED). */
#define BOARD_LED_DDR  DDRB
#define BOARD_LED_PORT PORTB
#define BOARD_LED_BIT  PB7

#endif /* HALLHOME_BOARD_H */
