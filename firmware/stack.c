#include "stack.h"

#include <stddef.h>

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

static const uint8_t *sweep_at; /* the sweep's next byte (NULL: from the start) */
static uint16_t swept;          /* 1 + the free bytes of the last complete sweep */

/* Scans painted bytes from p upwards, at most to end: where it stopped. */
static const uint8_t *painted_up_to(const uint8_t *p, const uint8_t *end)
{
    const uint8_t *sp = (const uint8_t *)SP;
    if (end > sp) {
        end = sp;
    }
    while (p < end && *p == STACK_PAINT) {
        p++;
    }
    return p;
}

void stack_sweep(void)
{
    const uint8_t *p = sweep_at != NULL ? sweep_at : &__heap_start;
    const uint8_t *q = painted_up_to(p, p + STACK_SWEEP_BYTES);
    if (q == p + STACK_SWEEP_BYTES && q < (const uint8_t *)SP) {
        sweep_at = q; /* all painted so far: on with the next pass */
        return;
    }
    swept = (uint16_t)(q - &__heap_start + 1);
    sweep_at = NULL;
}

uint16_t stack_free_min(void)
{
    if (swept == 0u) {
        return (uint16_t)(painted_up_to(&__heap_start, (const uint8_t *)SP) - &__heap_start);
    }
    return (uint16_t)(swept - 1u);
}
