#include "icm20948/icm_set.h"

#include <stddef.h>
#include <string.h>

#include "icm20948/icm20948_reg.h"

/* icm_set_take() measured smaller on the AVR as a call than inlined. */
#if defined(__GNUC__)
#define ICM_SET_NOINLINE __attribute__((noinline))
#else
#define ICM_SET_NOINLINE
#endif

/* Functions that measured smaller on the AVR as calls than inlined into their
 * callers (a slot's init start, the count of sampling sensors). */
#if defined(__GNUC__)
#define ICM_NOINLINE __attribute__((noinline))
#else
#define ICM_NOINLINE
#endif

/* The bus the set's sensors are set up on (icm20948.h, ICM_BUS_FIXED). */
#if ICM_BUS_FIXED
#define ICM_SET_BUS(set) NULL
#else
#define ICM_SET_BUS(set) ((set)->bus)
#endif

int8_t icm_set_setup(icm_set_t *set, const icm_bus_t *bus, uint8_t mux_addr, icm_set_slot_t *slots,
                     uint8_t cap)
{
    if (set == NULL || (bus == NULL && !ICM_BUS_FIXED) || slots == NULL || cap == 0u ||
        cap > ICM_SET_MAX) {
        return ICM_E_ARG;
    }
    memset(set, 0, sizeof(*set));
#if !ICM_BUS_FIXED
    set->bus = bus;
#endif
    set->slot = slots;
    set->cap = cap;
    set->period_us = ICM_SET_PERIOD_US_DEFAULT;
    set->active = ICM_SET_NONE;
    if (mux_addr != ICM_NO_MUX) {
        if (tca_setup(&set->mux, bus, mux_addr) != 0) {
            return ICM_E_ARG;
        }
        set->has_mux = 1;
    }
    return 0;
}

int8_t icm_set_add(icm_set_t *set, uint8_t channel, uint8_t addr)
{
    uint8_t i;
    icm_set_slot_t *s;
    if (set == NULL || set->begun || set->n >= set->cap) {
        return ICM_E_ARG;
    }
    for (i = 0; i < set->n; i++) {
        if (set->slot[i].dev.channel == channel && set->slot[i].dev.addr == addr) {
            return ICM_E_ARG;
        }
    }
    s = &set->slot[set->n];
    memset(s, 0, sizeof(*s));
    if (icm_setup(&s->dev, ICM_SET_BUS(set), set->has_mux ? &set->mux : NULL, channel, addr) != 0) {
        return ICM_E_ARG;
    }
    return (int8_t)set->n++;
}

int8_t icm_set_period_us(icm_set_t *set, uint32_t period_us)
{
    if (set == NULL || period_us < 1000u || period_us > 100000u) {
        return ICM_E_ARG;
    }
    set->period_us = period_us;
    return 0;
}

int8_t icm_set_stale_limit_us(icm_set_t *set, uint32_t stale_us)
{
    uint8_t i;
    if (set == NULL || stale_us == 0u) {
        return ICM_E_ARG;
    }
    for (i = 0; i < set->n; i++) {
        (void)icm_set_stale_us(&set->slot[i].dev, stale_us);
    }
    return 0;
}

ICM_NOINLINE static void icm_set_start_init(icm_set_slot_t *s, uint32_t now_us)
{
    (void)icm_init_start(&s->dev, now_us);
    s->state = ICM_SET_S_INIT;
    s->consec_err = 0;
    s->fresh = 0;
    s->rate_dhz = 0;
    icm_clock_reset(&s->clk); /* the AK09916 restarts on its own clock */
}

int8_t icm_set_begin(icm_set_t *set, uint32_t now_us)
{
    uint8_t i;
    if (set == NULL || set->n == 0u) {
        return ICM_E_ARG;
    }
    if (set->has_mux) {
        tca_invalidate(&set->mux);
    }
    for (i = 0; i < set->n; i++) {
        icm_set_start_init(&set->slot[i], now_us);
    }
    set->begun = 1;
    set->cursor = 0;
    set->active = ICM_SET_NONE;
    return 0;
}

void icm_set_retry(icm_set_t *set, uint32_t now_us)
{
    uint8_t i;
    if (set->has_mux) {
        tca_invalidate(&set->mux); /* the mux may have been unplugged too */
    }
    for (i = 0; i < set->n; i++) {
        icm_set_slot_t *s = &set->slot[i];
        if (s->state == ICM_SET_S_FAIL) {
            s->due_us = now_us;
        }
        /* an init already under way (its periodic retry) is waited for too:
         * taken as settled, it was named missing in its reset wait and the
         * press refused, the sensor found 80 ms later (chaos seed 3195) */
        s->retry = (uint8_t)(s->state != ICM_SET_S_RUN);
    }
}

static uint8_t icm_set_due(uint32_t now_us, uint32_t due_us)
{
    return (uint8_t)((int32_t)(now_us - due_us) >= 0);
}

/* A failed run is re-initialised at once: the usual causes (the sensor
 * reset itself, its AK09916 stopped, the cable glitched) clear with an init,
 * and an absent sensor then backs off to the retry period. */
static void icm_set_read_error(icm_set_slot_t *s, int8_t rc, uint32_t now_us)
{
    s->last_err = rc;
    s->consec_err++;
    if (rc == ICM_E_ABSENT || rc == ICM_E_STALE || s->consec_err >= ICM_SET_MAX_ERRORS) {
        s->reinits++;
        icm_set_start_init(s, now_us);
    }
}

static void icm_set_fetch(icm_set_slot_t *s, uint32_t now_us)
{
    icm_sample_t smp;
    int8_t rc = icm_read_fetch(&s->dev, now_us, &smp);
    if (rc != 0) {
        icm_set_read_error(s, rc, now_us);
        return;
    }
    s->consec_err = 0;
    if (smp.flags & ICM_SAMPLE_NEW) {
        smp.t_us = icm_clock_seen(&s->clk, now_us);
#if ICM_STATS
        if (s->fresh) {
            s->missed++;
        }
#endif
        s->last = smp;
        s->fresh = 1;
        s->win_new++;
    }
    if ((uint32_t)(now_us - s->win_from_us) >= ICM_SET_RATE_WINDOW_US) {
        uint32_t ms = (uint32_t)(now_us - s->win_from_us) / 1000u;
        s->rate_dhz = (uint16_t)(((uint32_t)s->win_new * 10000u) / ms);
        s->win_new = 0;
        s->win_from_us = now_us;
    }
}

static void icm_set_init_step(icm_set_slot_t *s, uint32_t now_us)
{
    int8_t rc = icm_init_poll(&s->dev, now_us);
    if (rc <= 0) {
        s->retry = 0;
    }
    if (rc == 0) {
        s->state = ICM_SET_S_RUN;
        s->last_err = 0;
        s->due_us = now_us;
        s->win_from_us = now_us;
        s->win_new = 0;
        s->rate_dhz = 0;
    } else if (rc < 0) {
        s->state = ICM_SET_S_FAIL;
        s->last_err = rc;
        s->due_us = now_us + ICM_SET_RETRY_US;
    }
}

int8_t icm_set_poll(icm_set_t *set, uint32_t now_us)
{
    uint8_t k;
    if (set == NULL) {
        return ICM_E_ARG;
    }
    if (!set->begun) {
        return ICM_E_STATE;
    }
    if (set->active != ICM_SET_NONE) {
        icm_set_fetch(&set->slot[set->active], now_us);
        set->active = ICM_SET_NONE;
        return 0;
    }
    for (k = 0; k < set->n; k++) {
        uint8_t i = (uint8_t)((set->cursor + k) % set->n);
        icm_set_slot_t *s = &set->slot[i];
        if (s->state == ICM_SET_S_INIT) {
            icm_set_init_step(s, now_us);
        } else if (s->state == ICM_SET_S_RUN && icm_set_due(now_us, s->due_us)) {
            int8_t rc = icm_read_start(&s->dev, now_us);
            s->due_us += set->period_us;
            if (icm_set_due(now_us, s->due_us)) {
                s->due_us = now_us + set->period_us; /* fell behind: do not burst */
            }
            if (rc == 0) {
                set->active = i;
            } else {
                icm_set_read_error(s, rc, now_us);
            }
        } else if (s->state == ICM_SET_S_FAIL && icm_set_due(now_us, s->due_us)) {
            s->reinits++;
            icm_set_start_init(s, now_us);
        } else {
            continue;
        }
        set->cursor = (uint8_t)((i + 1u) % set->n);
        return 0;
    }
    return 0;
}

ICM_NOINLINE uint8_t icm_set_ready_count(const icm_set_t *set)
{
    uint8_t i, n = 0;
    if (set == NULL) {
        return 0;
    }
    for (i = 0; i < set->n; i++) {
        n = (uint8_t)(n + (set->slot[i].state == ICM_SET_S_RUN));
    }
    return n;
}

uint8_t icm_set_settled(const icm_set_t *set)
{
    uint8_t i;
    if (set == NULL || !set->begun) {
        return 0;
    }
    for (i = 0; i < set->n; i++) {
        if ((set->slot[i].state == ICM_SET_S_INIT && set->slot[i].reinits == 0u) ||
            set->slot[i].retry) {
            return 0;
        }
    }
    return 1;
}

ICM_SET_NOINLINE int8_t icm_set_take(icm_set_t *set, uint8_t idx, icm_sample_t *out)
{
    icm_set_slot_t *s;
    if (set == NULL || out == NULL || idx >= set->n) {
        return ICM_E_ARG;
    }
    s = &set->slot[idx];
    if (s->state != ICM_SET_S_RUN) {
        return s->last_err != 0 ? s->last_err : ICM_E_STATE;
    }
    if (!s->fresh) {
        return 0;
    }
    *out = s->last;
    s->fresh = 0;
    return 1;
}

int8_t icm_set_diag(const icm_set_t *set, uint8_t idx, icm_diag_t *d)
{
    const icm_set_slot_t *s;
    uint8_t i;
    if (set == NULL || d == NULL || idx >= set->n) {
        return ICM_E_ARG;
    }
    s = &set->slot[idx];
    memset(d, 0, sizeof(*d));
    d->state = s->state;
    d->channel = s->dev.channel;
    d->addr = s->dev.addr;
    d->who_am_i = s->dev.who_am_i;
    d->present = (uint8_t)(s->dev.who_am_i == ICM_REG_WHO_AM_I_V);
    d->mag_ready = (uint8_t)(s->state == ICM_SET_S_RUN);
    d->mag_id = s->dev.mag_id;
    d->last_err = s->last_err;
    d->rate_dhz = s->rate_dhz;
    for (i = 0; i < 3u; i++) {
        d->field_cuT[i] = (int32_t)s->last.raw[i] * AK_REG_LSB_CUT;
    }
#if ICM_STATS
    d->samples = s->dev.new_count;
    d->overrun_count = s->dev.overrun_count;
#endif
    d->overflow_count = s->dev.overflow_count;
    d->error_count = s->dev.error_count;
    d->reinits = s->reinits;
    return 0;
}

typedef struct {
    char *p;
    uint16_t len;
} icm_out_t;

static void icm_put(icm_out_t *o, const char *s)
{
    while (*s != '\0') {
        o->p[o->len++] = *s++;
    }
}

static void icm_put_u(icm_out_t *o, uint32_t v, uint8_t min_digits)
{
    char tmp[10];
    uint8_t n = 0;
    do {
        tmp[n++] = (char)('0' + (v % 10u));
        v /= 10u;
    } while (v != 0u || n < min_digits);
    while (n > 0u) {
        o->p[o->len++] = tmp[--n];
    }
}

static void icm_put_i(icm_out_t *o, int32_t v)
{
    if (v < 0) {
        icm_put(o, "-");
        icm_put_u(o, (uint32_t)(-(v + 1)) + 1u, 1);
    } else {
        icm_put_u(o, (uint32_t)v, 1);
    }
}

/* Fixed point with `dec` decimals: the value is in units of 10^-dec. */
static void icm_put_fix(icm_out_t *o, int32_t v, uint32_t scale, uint8_t dec)
{
    uint32_t a;
    if (v < 0) {
        icm_put(o, "-");
        a = (uint32_t)(-(v + 1)) + 1u;
    } else {
        a = (uint32_t)v;
    }
    icm_put_u(o, a / scale, 1);
    icm_put(o, ".");
    icm_put_u(o, a % scale, dec);
}

static void icm_put_hex8(icm_out_t *o, uint8_t v)
{
    static const char hex[] = "0123456789ABCDEF";
    char s[5] = {'0', 'x', hex[v >> 4], hex[v & 15u], '\0'};
    icm_put(o, s);
}

int16_t icm_diag_format(const icm_diag_t *d, char *buf, uint16_t cap)
{
    static const char *const names[] = {"idle", "init", "run", "fail"};
    icm_out_t o;
    if (d == NULL || buf == NULL || cap < ICM_DIAG_LINE_MAX) {
        return ICM_E_ARG;
    }
    o.p = buf;
    o.len = 0;
    icm_put(&o, "ch=");
    if (d->channel == ICM_NO_MUX) {
        icm_put(&o, "-");
    } else {
        icm_put_u(&o, d->channel, 1);
    }
    icm_put(&o, " addr=");
    icm_put_hex8(&o, d->addr);
    icm_put(&o, " state=");
    icm_put(&o, names[d->state & 3u]);
    icm_put(&o, " who=");
    icm_put_hex8(&o, d->who_am_i);
    icm_put(&o, " mag=");
    icm_put_u(&o, d->mag_ready, 1);
    icm_put(&o, " rate=");
    icm_put_fix(&o, d->rate_dhz, 10u, 1);
    icm_put(&o, " bx=");
    icm_put_fix(&o, d->field_cuT[0], 100u, 2);
    icm_put(&o, " by=");
    icm_put_fix(&o, d->field_cuT[1], 100u, 2);
    icm_put(&o, " bz=");
    icm_put_fix(&o, d->field_cuT[2], 100u, 2);
    icm_put(&o, " ovf=");
    icm_put_u(&o, d->overflow_count, 1);
    icm_put(&o, " dor=");
    icm_put_u(&o, d->overrun_count, 1);
    icm_put(&o, " err=");
    icm_put_u(&o, d->error_count, 1);
    icm_put(&o, " last=");
    icm_put_i(&o, d->last_err);
    buf[o.len] = '\0';
    return (int16_t)o.len;
}
