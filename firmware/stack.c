#include "stack.h"

#include <avr/io.h>

/* End of the static data: the linker script places the heap after .noinit. */
extern uint8_t __heap_start;

/* Runs in .init3 (after .init2 set the stack pointer and cleared r1, before
 * .data and .bss are initialised): naked, it has no frame of its own, and the
 * stack holds nothing yet, so every byte up to SP can be painted. */
void stack_paint(void) __attribute__((naked, used, section(".init3")));
void stack_paint(void)
{
    uint8_t *p = &__heap_start;
    while (p < (uint8_t *)SP) {
        *p++ = STACK_PAINT;
    }
}

uint16_t stack_free_min(void)
{
    const uint8_t *p = &__heap_start;
    const uint8_t *sp = (const uint8_t *)SP;
    while (p < sp && *p == STACK_PAINT) {
        p++;
    }
    return (uint16_t)(p - &__heap_start);
}
