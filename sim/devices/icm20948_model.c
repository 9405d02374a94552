#include "devices/icm20948_model.h"

#include <string.h>

#include "icm20948/icm20948_reg.h"

#define ICMM_NEVER UINT64_MAX

static uint32_t akm_period_us(uint8_t mode)
{
    switch (mode) {
    case AK_REG_MODE_CONT_10HZ:
        return 100000u;
    case AK_REG_MODE_CONT_20HZ:
        return 50000u;
    case AK_REG_MODE_CONT_50HZ:
        return 20000u;
    case AK_REG_MODE_CONT_100HZ:
        return AK_REG_PERIOD_100HZ_US;
    default:
        return 0;
    }
}

static void akm_reset(akm_t *ak)
{
    ak->mode = AK_REG_MODE_POWER_DOWN;
    ak->st1 = 0;
    ak->st2 = 0;
    memset(ak->data, 0, sizeof(ak->data));
    ak->locked = 0;
    ak->pend_valid = 0;
    ak->next_meas_us = ICMM_NEVER;
}

static uint32_t akm_rand(akm_t *ak)
{
    uint32_t x = ak->rng;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    ak->rng = x;
    return x;
}

/* Irwin-Hall: the sum of 12 uniform 16-bit values has a standard deviation
 * of 65536 counts, close enough to Gaussian for sensor noise. */
static int32_t akm_noise(akm_t *ak)
{
    int64_t s = 0;
    int i;
    if (ak->noise_cuT == 0u) {
        return 0;
    }
    for (i = 0; i < 12; i++) {
        s += (int64_t)(akm_rand(ak) & 0xFFFFu);
    }
    s = 2 * s - 12 * 65535;
    return (int32_t)((s * (int64_t)ak->noise_cuT) / (2 * 65536));
}

int16_t akm_quantize(int32_t cuT, uint8_t *sat)
{
    int32_t q;
    if (cuT >= 0) {
        q = (cuT + AK_REG_LSB_CUT / 2) / AK_REG_LSB_CUT;
    } else {
        q = -((-cuT + AK_REG_LSB_CUT / 2) / AK_REG_LSB_CUT);
    }
    if (q > AK_REG_RAW_MAX) {
        *sat = 1;
        q = AK_REG_RAW_MAX;
    } else if (q < -AK_REG_RAW_MAX) {
        *sat = 1;
        q = -AK_REG_RAW_MAX;
    }
    return (int16_t)q;
}

static void akm_measure(akm_t *ak, uint64_t t)
{
    uint8_t d[6];
    uint8_t sat = 0;
    uint8_t st2;
    int i;
    for (i = 0; i < 3; i++) {
        int16_t q = akm_quantize(ak->field_cuT[i] + akm_noise(ak), &sat);
        d[2 * i] = (uint8_t)((uint16_t)q & 0xFFu);
        d[2 * i + 1] = (uint8_t)((uint16_t)q >> 8);
    }
    st2 = sat ? AK_REG_ST2_HOFL : 0u;
    ak->samples++;
    if (ak->locked) {
        if (ak->pend_valid) {
            ak->st1 |= AK_REG_ST1_DOR;
        }
        memcpy(ak->pend_data, d, 6);
        ak->pend_st2 = st2;
        ak->pend_valid = 1;
    } else {
        if (ak->st1 & AK_REG_ST1_DRDY) {
            ak->st1 |= AK_REG_ST1_DOR;
        }
        memcpy(ak->data, d, 6);
        ak->st2 = st2;
        ak->st1 |= AK_REG_ST1_DRDY;
    }
    if (ak->mode == AK_REG_MODE_SINGLE) {
        ak->mode = AK_REG_MODE_POWER_DOWN;
        ak->next_meas_us = ICMM_NEVER;
    } else {
        ak->next_meas_us = t + akm_period_us(ak->mode);
    }
}

static uint8_t akm_acks(const icmm_t *m, uint8_t addr7)
{
    return (uint8_t)(m->ak.present && addr7 == AK_REG_ADDR && m->now_us >= m->ak.reset_until_us);
}

/* Reading HXL..TMPS clears DRDY/DOR and holds the data registers; reading
 * ST2 ends the read cycle and releases a sample that completed meanwhile. */
static uint8_t akm_read(akm_t *ak, uint8_t reg)
{
    uint8_t v;
    switch (reg) {
    case AK_REG_WIA1:
        return ak->wia1;
    case AK_REG_WIA2:
        return ak->wia2;
    case AK_REG_ST1:
        return ak->st1;
    case AK_REG_ST2:
        v = ak->st2;
        ak->locked = 0;
        ak->st1 &= (uint8_t) ~(AK_REG_ST1_DRDY | AK_REG_ST1_DOR);
        if (ak->pend_valid) {
            memcpy(ak->data, ak->pend_data, 6);
            ak->st2 = ak->pend_st2;
            ak->st1 |= AK_REG_ST1_DRDY;
            ak->pend_valid = 0;
        }
        return v;
    case AK_REG_CNTL2:
        return ak->mode;
    default:
        break;
    }
    if (reg >= AK_REG_HXL && reg <= AK_REG_TMPS) {
        ak->locked = 1;
        ak->st1 &= (uint8_t) ~(AK_REG_ST1_DRDY | AK_REG_ST1_DOR);
        return reg == AK_REG_TMPS ? 0u : ak->data[reg - AK_REG_HXL];
    }
    return 0;
}

static void akm_write(akm_t *ak, uint64_t now, uint8_t reg, uint8_t v)
{
    if (reg == AK_REG_CNTL2) {
        ak->mode = (uint8_t)(v & 0x1Fu);
        if (ak->mode == AK_REG_MODE_SINGLE) {
            ak->next_meas_us = now + 8000u;
        } else if (akm_period_us(ak->mode) != 0u) {
            ak->next_meas_us = now + akm_period_us(ak->mode);
        } else {
            ak->next_meas_us = ICMM_NEVER;
        }
    } else if (reg == AK_REG_CNTL3 && (v & AK_REG_CNTL3_SRST)) {
        akm_reset(ak);
        ak->reset_until_us = now + AKM_SRST_US;
    }
}

static void icmm_reset_regs(icmm_t *m)
{
    memset(m->regs, 0, sizeof(m->regs));
    m->regs[0][ICM_REG_PWR_MGMT_1] = ICM_REG_PWR_RESET_VALUE;
    m->regs[0][ICM_REG_LP_CONFIG] = ICM_REG_LP_I2C_MST_CYCLE;
    m->bank = 0;
    m->slv4_pending = 0;
    m->mst_hung = 0;
}

void icmm_init(icmm_t *m, uint8_t addr, uint32_t seed)
{
    memset(m, 0, sizeof(*m));
    m->addr = addr;
    m->present = 1;
    m->who_am_i = ICM_REG_WHO_AM_I_V;
    icmm_reset_regs(m);
    m->next_mst_us = ICMM_NEVER;
    m->ak.present = 1;
    m->ak.wia1 = AK_REG_WIA1_V;
    m->ak.wia2 = AK_REG_WIA2_V;
    m->ak.rng = seed ? seed : 1u;
    akm_reset(&m->ak);
}

void icmm_set_field_cuT(icmm_t *m, int32_t x, int32_t y, int32_t z)
{
    m->ak.field_cuT[0] = x;
    m->ak.field_cuT[1] = y;
    m->ak.field_cuT[2] = z;
}

void icmm_set_noise(icmm_t *m, uint32_t sigma_cuT, uint32_t seed)
{
    m->ak.noise_cuT = sigma_cuT;
    m->ak.rng = seed ? seed : 1u;
}

static uint8_t icmm_mst_active(const icmm_t *m)
{
    return (uint8_t)((m->regs[0][ICM_REG_USER_CTRL] & ICM_REG_USER_I2C_MST_EN) &&
                     !(m->regs[0][ICM_REG_PWR_MGMT_1] & ICM_REG_PWR_SLEEP) &&
                     m->now_us >= m->reset_until_us && !m->mst_hung);
}

static uint32_t icmm_mst_period(const icmm_t *m)
{
    uint8_t pwr2 = m->regs[0][ICM_REG_PWR_MGMT_2];
    if ((pwr2 & ICM_REG_PWR2_GYRO_OFF) != ICM_REG_PWR2_GYRO_OFF) {
        return ICMM_MST_PERIOD_US;
    }
    if ((pwr2 & ICM_REG_PWR2_ACCEL_OFF) != ICM_REG_PWR2_ACCEL_OFF) {
        return ICMM_ACC_PERIOD_US;
    }
    if (m->regs[0][ICM_REG_LP_CONFIG] & ICM_REG_LP_I2C_MST_CYCLE) {
        return ICMM_MST_PERIOD_US << (m->regs[3][ICM_REG_I2C_MST_ODR_CONFIG] & 0x0Fu);
    }
    return ICMM_MST_PERIOD_US;
}

/* Moves the bytes of the SLV0 read in flight that have arrived by t into
 * EXT_SLV_SENS_DATA: one by one, or all at the end with DELAY_ES_SHADOW. */
static void icmm_ext_commit(icmm_t *m, uint64_t t)
{
    uint8_t shadow = (uint8_t)(m->regs[3][ICM_REG_I2C_MST_DELAY_CTRL] & ICM_REG_DELAY_ES_SHADOW);
    uint8_t total = (uint8_t)(m->ext_done + m->ext_n);
    while (m->ext_n > 0u) {
        uint8_t upto = shadow ? total : (uint8_t)(m->ext_done + 1u);
        if (t < m->ext_t0_us + (uint64_t)(ICMM_SLV0_LEAD + upto) * ICMM_AUX_BYTE_US) {
            return;
        }
        while (m->ext_done < upto) {
            m->regs[0][ICM_REG_EXT_SLV_SENS_DATA_00 + m->ext_done] = m->ext_new[m->ext_done];
            m->ext_done++;
            m->ext_n--;
        }
    }
}

static void icmm_slv0(icmm_t *m)
{
    uint8_t addr = m->regs[3][ICM_REG_I2C_SLV0_ADDR];
    uint8_t reg = m->regs[3][ICM_REG_I2C_SLV0_REG];
    uint8_t ctrl = m->regs[3][ICM_REG_I2C_SLV0_CTRL];
    uint8_t n = (uint8_t)(ctrl & ICM_REG_SLV_CTRL_LENG);
    uint8_t i;
    if (!(ctrl & ICM_REG_SLV_CTRL_EN)) {
        return;
    }
    m->slv0_reads++;
    if (!akm_acks(m, (uint8_t)(addr & 0x7Fu))) {
        m->regs[0][ICM_REG_I2C_MST_STATUS] |= ICM_REG_MST_SLV0_NACK;
        return;
    }
    if (addr & ICM_REG_SLV_ADDR_READ) {
        icmm_ext_commit(m, ICMM_NEVER - 1u); /* the previous read has long ended */
        for (i = 0; i < n && i < ICM_REG_EXT_SLV_SENS_LEN; i++) {
            m->ext_new[i] = akm_read(&m->ak, (uint8_t)(reg + i));
        }
        m->ext_n = i;
        m->ext_done = 0;
        m->ext_t0_us = m->now_us;
        icmm_ext_commit(m, m->now_us);
    } else {
        akm_write(&m->ak, m->now_us, reg, m->regs[3][ICM_REG_I2C_SLV0_DO]);
    }
}

static void icmm_slv4(icmm_t *m)
{
    uint8_t addr = m->regs[3][ICM_REG_I2C_SLV4_ADDR];
    uint8_t reg = m->regs[3][ICM_REG_I2C_SLV4_REG];
    m->slv4_pending = 0;
    m->regs[3][ICM_REG_I2C_SLV4_CTRL] &= (uint8_t)~ICM_REG_SLV_CTRL_EN;
    if (!akm_acks(m, (uint8_t)(addr & 0x7Fu))) {
        m->regs[0][ICM_REG_I2C_MST_STATUS] |= ICM_REG_MST_SLV4_NACK | ICM_REG_MST_SLV4_DONE;
        return;
    }
    if (addr & ICM_REG_SLV_ADDR_READ) {
        m->regs[3][ICM_REG_I2C_SLV4_DI] = akm_read(&m->ak, reg);
    } else {
        akm_write(&m->ak, m->now_us, reg, m->regs[3][ICM_REG_I2C_SLV4_DO]);
    }
    m->regs[0][ICM_REG_I2C_MST_STATUS] |= ICM_REG_MST_SLV4_DONE;
}

void icmm_advance(icmm_t *m, uint64_t now_us)
{
    for (;;) {
        uint64_t t = ICMM_NEVER;
        int which = 0;
        uint8_t active = icmm_mst_active(m);
        if (m->ak.next_meas_us < t) {
            t = m->ak.next_meas_us;
            which = 1;
        }
        if (active && m->next_mst_us < t) {
            t = m->next_mst_us;
            which = 2;
        }
        if (active && m->slv4_pending && m->slv4_at_us < t) {
            t = m->slv4_at_us;
            which = 3;
        }
        if (which == 0 || t > now_us) {
            break;
        }
        if (t > m->now_us) {
            m->now_us = t;
        }
        icmm_ext_commit(m, t);
        if (which == 1) {
            akm_measure(&m->ak, t);
        } else if (which == 2) {
            icmm_slv0(m);
            m->next_mst_us = t + icmm_mst_period(m);
        } else {
            icmm_slv4(m);
        }
    }
    if (now_us > m->now_us) {
        m->now_us = now_us;
    }
    icmm_ext_commit(m, m->now_us);
    if (!icmm_mst_active(m)) {
        m->next_mst_us = m->now_us + icmm_mst_period(m);
    }
}

uint8_t icmm_peek(const icmm_t *m, uint8_t bank, uint8_t reg)
{
    if (reg == ICM_REG_BANK_SEL) {
        return (uint8_t)(m->bank << ICM_REG_BANK_SHIFT);
    }
    if (bank == 0u && reg == ICM_REG_WHO_AM_I) {
        return m->who_am_i;
    }
    return m->regs[bank & 3u][reg & 0x7Fu];
}

static uint8_t icmm_is_ext(uint8_t bank, uint8_t reg)
{
    return (uint8_t)(bank == 0u && reg >= ICM_REG_EXT_SLV_SENS_DATA_00 &&
                     reg < ICM_REG_EXT_SLV_SENS_DATA_00 + ICM_REG_EXT_SLV_SENS_LEN);
}

static void icmm_reg_write(icmm_t *m, uint8_t reg, uint8_t v)
{
    uint8_t b = m->bank;
    if (reg == ICM_REG_BANK_SEL) {
        m->bank = (uint8_t)((v & ICM_REG_BANK_MASK) >> ICM_REG_BANK_SHIFT);
        return;
    }
    if (b == 0u) {
        switch (reg) {
        case ICM_REG_WHO_AM_I:
        case ICM_REG_I2C_MST_STATUS:
            return;
        case ICM_REG_PWR_MGMT_1:
            if (v & ICM_REG_PWR_DEVICE_RST) {
                icmm_reset_regs(m);
                m->reset_until_us = m->now_us + ICMM_RESET_US;
                m->resets++;
                return;
            }
            break;
        case ICM_REG_USER_CTRL:
            if (v & ICM_REG_USER_I2C_MST_RST) {
                m->slv4_pending = 0;
                m->mst_hung = 0;
                m->mst_resets++;
                m->regs[3][ICM_REG_I2C_SLV4_CTRL] &= (uint8_t)~ICM_REG_SLV_CTRL_EN;
                v &= (uint8_t)~ICM_REG_USER_I2C_MST_RST;
            }
            break;
        default:
            if (icmm_is_ext(0, reg)) {
                return;
            }
            break;
        }
    } else if (b == 3u) {
        if (reg == ICM_REG_I2C_SLV4_DI) {
            return;
        }
        if (reg == ICM_REG_I2C_MST_CTRL &&
            (m->regs[0][ICM_REG_USER_CTRL] & ICM_REG_USER_I2C_MST_EN)) {
            m->mst_ctrl_live_writes++;
        }
        if (reg == ICM_REG_I2C_SLV4_CTRL && (v & ICM_REG_SLV_CTRL_EN)) {
            m->slv4_pending = 1;
            m->slv4_at_us = m->now_us + ICMM_SLV4_US;
            if (m->mst_hang_tries > 0u) {
                m->mst_hang_tries--;
                m->mst_hung = 1;
            }
        }
    }
    m->regs[b][reg] = v;
}

static uint8_t icmm_reg_read(icmm_t *m, uint8_t reg)
{
    uint8_t v = icmm_is_ext(m->bank, reg) ? m->ext_view[reg - ICM_REG_EXT_SLV_SENS_DATA_00]
                                          : icmm_peek(m, m->bank, reg);
    if (m->bank == 0u && reg == ICM_REG_I2C_MST_STATUS) {
        m->regs[0][ICM_REG_I2C_MST_STATUS] = 0;
    }
    return v;
}

static uint8_t icmm_start(void *ctx, uint8_t addr_byte)
{
    icmm_t *m = ctx;
    m->selected = 0;
    if (!m->present || (addr_byte >> 1) != m->addr || m->now_us < m->reset_until_us) {
        return 0;
    }
    m->selected = 1;
    m->reading = (uint8_t)(addr_byte & 1u);
    m->nread = 0;
    if (!m->reading) {
        m->have_ptr = 0;
    } else {
        memcpy(m->ext_view, &m->regs[0][ICM_REG_EXT_SLV_SENS_DATA_00], sizeof(m->ext_view));
        if (m->ext_n > 0u && m->ext_done > 0u &&
            memcmp(&m->ext_new[m->ext_done],
                   &m->regs[0][ICM_REG_EXT_SLV_SENS_DATA_00 + m->ext_done], m->ext_n) != 0) {
            m->torn_reads++;
        }
    }
    return 1;
}

static uint8_t icmm_write(void *ctx, uint8_t byte)
{
    icmm_t *m = ctx;
    if (!m->selected || m->reading) {
        return 0;
    }
    if (!m->have_ptr) {
        m->ptr = (uint8_t)(byte & 0x7Fu);
        m->have_ptr = 1;
        return 1;
    }
    icmm_reg_write(m, m->ptr, byte);
    m->ptr = (uint8_t)((m->ptr + 1u) & 0x7Fu);
    return 1;
}

static uint8_t icmm_read(void *ctx, uint8_t master_ack)
{
    icmm_t *m = ctx;
    uint8_t v;
    (void)master_ack;
    if (!m->selected || !m->reading) {
        return 0xFFu;
    }
    if (m->nread == 0u && m->bank == 0u && m->ptr == ICM_REG_EXT_SLV_SENS_DATA_00) {
        m->ext_reads++;
    }
    m->nread++;
    v = icmm_reg_read(m, m->ptr);
    m->ptr = (uint8_t)((m->ptr + 1u) & 0x7Fu);
    return v;
}

static void icmm_stop(void *ctx)
{
    icmm_t *m = ctx;
    m->selected = 0;
}

static void icmm_advance_cb(void *ctx, uint64_t now_us)
{
    icmm_advance(ctx, now_us);
}

simi2c_slave_t icmm_slave(icmm_t *m)
{
    simi2c_slave_t s;
    s.ctx = m;
    s.start = icmm_start;
    s.write = icmm_write;
    s.read = icmm_read;
    s.stop = icmm_stop;
    s.advance = icmm_advance_cb;
    return s;
}
