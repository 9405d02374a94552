#include "icm20948/tca9548a.h"

#include <stddef.h>

int8_t tca_setup(tca_t *mux, const icm_bus_t *bus, uint8_t addr)
{
    if (mux == NULL || ICM_BUS_BAD(bus, 0) || addr < 0x70u || addr > 0x77u) {
        return TCA_E_ARG;
    }
#if !ICM_BUS_FIXED
    mux->bus = bus;
#endif
    mux->addr = addr;
    mux->ctrl = 0;
    mux->valid = 0;
    mux->writes = 0;
    mux->errors = 0;
    return 0;
}

static int8_t tca_write_ctrl(tca_t *mux, uint8_t ctrl)
{
    int8_t rc = ICM_BUS_WRITE(mux->bus, mux->addr, &ctrl, 1);
    mux->writes++;
    if (rc != ICM_BUS_OK) {
        mux->valid = 0;
        mux->errors++;
        return icm_bus_error(rc);
    }
    mux->ctrl = ctrl;
    mux->valid = 1;
    return 0;
}

int8_t tca_select(tca_t *mux, uint8_t channel)
{
    uint8_t ctrl;
    if (mux == NULL || channel >= TCA_CHANNELS) {
        return TCA_E_ARG;
    }
    ctrl = (uint8_t)(1u << channel);
    if (mux->valid && mux->ctrl == ctrl) {
        return 0;
    }
    return tca_write_ctrl(mux, ctrl);
}

int8_t tca_disable_all(tca_t *mux)
{
    if (mux == NULL) {
        return TCA_E_ARG;
    }
    return tca_write_ctrl(mux, 0);
}

void tca_invalidate(tca_t *mux)
{
    if (mux != NULL) {
        mux->valid = 0;
    }
}
