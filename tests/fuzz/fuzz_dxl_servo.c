/*
 * libFuzzer target: arbitrary bus bytes into the XL430 servo model (every
 * instruction, address and length the bytes happen to form), with time
 * advancing between bytes, its replies drained as a bus would.
 */
#include <stddef.h>
#include <stdint.h>

#include "devices/xl430_model.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) {
        return 0;
    }
    xl430 m;
    xl430_config cfg;
    xl430_config_default(&cfg, (uint8_t)(data[0] & 0x0Fu));
    cfg.return_delay = 0;
    cfg.boot_us = 2000;
    xl430_init(&m, &cfg, 0);
    uint32_t t = 0;
    for (size_t i = 1; i < size; i++) {
        t += 10u + (data[i] & 0x40u);
        xl430_rx(&m, data[i], t);
        uint8_t byte;
        uint32_t due;
        while (xl430_tx_peek(&m, &byte, &due)) {
            xl430_tx_pop(&m);
            if ((int32_t)(due - t) > 0) {
                t = due;
            }
        }
    }
    xl430_step(&m, t + 100000u);
    volatile int32_t pos = xl430_present_position(&m);
    (void)pos;
    return 0;
}
