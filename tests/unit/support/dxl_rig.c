/* dxl_rig: see dxl_rig.h. */
#include "dxl_rig.h"

void dxl_rig_init(dxl_rig *r, uint8_t count, uint8_t delay)
{
    dxl_fakebus_init(&r->bus, 1000000, 10);
    for (uint8_t i = 0; i < count; i++) {
        xl430_config c;
        xl430_config_default(&c, (uint8_t)(i + 1u));
        c.return_delay = delay;
        c.boot_us = 20000;
        c.shaft_ticks = 4096.0 * (i + 2) + 100.0 * (i + 1); /* several turns in */
        xl430_init(&r->servo[i], &c, 0);
        dxl_fakebus_add(&r->bus, &r->servo[i]);
    }
    dxl_fakebus_port(&r->bus, &r->port);
    dxl_config cfg;
    dxl_config_default(&cfg, 1000000, 10);
    dxl_master_init(&r->m, &r->port, &cfg);
}

int8_t dxl_rig_run(dxl_rig *r)
{
    return dxl_fakebus_run(&r->bus, &r->m, DXL_RIG_RUN_US);
}
