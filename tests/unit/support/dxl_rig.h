/*
 * dxl_rig: a DYNAMIXEL master on a simulated bus with XL430 models, the
 * bench of the master's and the bring-up's unit tests.
 */
#ifndef HALLHOME_DXL_RIG_H
#define HALLHOME_DXL_RIG_H

#include <stdint.h>

#include "dxl_fakebus.h"

#define DXL_RIG_SERVOS 6u
#define DXL_RIG_RUN_US 200000u /* dxl_rig_run()'s limit */

typedef struct {
    dxl_fakebus bus;
    xl430 servo[DXL_RIG_SERVOS];
    dxl_master m;
    dxl_port port;
} dxl_rig;

/* Servos 1..count at 1 Mbps, several turns in, factory return delay unless
 * `delay` is given; the master on the bus with its defaults. */
void dxl_rig_init(dxl_rig *r, uint8_t count, uint8_t delay);

/* The bus run until the master's transaction ends (dxl_fakebus_run()), at
 * most DXL_RIG_RUN_US. */
int8_t dxl_rig_run(dxl_rig *r);

#endif
