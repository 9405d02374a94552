/*
 * homing: the calibration state machine (see homing.h and docs/homing.md).
 */
#include "homing/homing.h"

#include <stddef.h>
#include <string.h>

enum {
    ST_IDLE = 0,
    ST_PREFLIGHT,
    ST_RELEASE_ALL, /* moving every tendon to its release goal */
    ST_SLACK_AVG,   /* settle, then average every sensor */
    ST_TENDON_START,
    ST_TAKEUP,   /* fast (then moderate) search for engagement */
    ST_MODERATE, /* engagement to near the target */
    ST_FINE_MOVE,
    ST_FINE_AVG,
    ST_BACKOFF, /* overshot on the first fine point: back to slack, re-approach */
    ST_TENDON_RELEASE,
    ST_FINAL,
    ST_DONE,
    ST_FAULT
};

static int move_done(hom_t *h, int arrived, uint8_t dev, uint8_t index);

/* Functions that measured smaller on the AVR as calls than inlined (each
 * inlined copy of 32- and 64-bit arithmetic costs more than the call). */
#if defined(__GNUC__)
#define HOM_NOINLINE __attribute__((noinline))
#else
#define HOM_NOINLINE
#endif

#define HOM_MAX_AVG             32u
#define HOM_QUICK_STOP_PERMILLE 975u /* quick leg: stop when the field is this close */
#define HOM_DROOP_TICKS         8    /* a servo stopped this close counts as arrived ... */
#define HOM_STILL_MS            100u /* ... after this long without motion */
#define HOM_FIT_POINTS          4u   /* near points kept for the final fit (hom_t.pts) */

void hom_config_default(hom_config_t *cfg)
{
    /* Speeds in XL430 units (0.229 rpm = 15.63 ticks/s = 96 um/s on a
     * 6.1 um tick). Fast take-up: 120 units = 11.5 mm/s, 19 ticks between two
     * 100 Hz samples, only while the tendon is slack. Moderate: 40 units,
     * 6 ticks per sample, so stopping at 80 % of the target leaves margin for
     * a sample of latency. Fine steps are short moves, speed hardly matters.
     * Release: 200 units = 3.1 ticks/ms, a 1 mm release in 52 ms (< 100 ms). */
    memset(cfg, 0, sizeof *cfg);
    cfg->v_fast = 120;
    cfg->v_moderate = 40;
    cfg->v_fine = 60;
    cfg->v_release = 200;
    cfg->v_final = 120;
    cfg->acc = 0;
    cfg->slack_margin_um = 600; /* > the path shortening another tendon causes at 1 N */
    cfg->slack_step_um = 300;
    cfg->slack_max_steps = 6;
    cfg->baseline_samples = 16;
    cfg->avg_samples = 2;
    cfg->fine_max_steps = 16;
    cfg->near_permille = 800;
    cfg->settle_ms = 20;
    cfg->preflight_ms = 200;
    cfg->sensor_timeout_ms = 100;
    cfg->servo_timeout_ms = 50;
    cfg->move_timeout_ms = 3000;
    cfg->tendon_timeout_ms = 4000;
    cfg->engage_min_cuT = 300;
    cfg->rate_limit_cuT = 250000; /* 2.5 mT per sample: 3x the fastest take-up seen */
    cfg->sat_cuT = 490000;        /* 4900 uT of the AK09916's 4912 uT */
    cfg->max_takeup_um = 4000;
    cfg->initial_release_um = 0;
}

void hom_init(hom_t *h, const hom_config_t *cfg)
{
    memset(h, 0, sizeof *h);
    if (cfg != NULL) {
        h->cfg = *cfg;
    } else {
        hom_config_default(&h->cfg);
    }
    h->state = ST_IDLE;
}

/* 32-bit arithmetic only (64-bit code is large and slow on the AVR): each
 * axis is scaled down by the smallest power of two that keeps the sum of
 * three squares within 32 bits (|axis| <= 37837, exact below 378 uT per
 * axis; short by less than three scaled units of at most 16 cuT at the
 * AK09916's full range), the
 * root is built bit by bit (floor), then scaled back. */
uint32_t hom_norm3(const int32_t v[3])
{
    uint32_t m[3];
    uint32_t top = 0;
    uint32_t s;
    uint32_t r = 0;
    uint32_t bit = (uint32_t)1 << 30;
    uint8_t sh = 0;
    uint8_t a;
    for (a = 0; a < 3u; a++) {
        m[a] = v[a] < 0 ? (uint32_t)0 - (uint32_t)v[a] : (uint32_t)v[a];
        top |= m[a];
    }
    while ((top >> sh) > 37837u) {
        sh++;
    }
    s = 0;
    for (a = 0; a < 3u; a++) {
        uint32_t x = m[a] >> sh;
        s += x * x;
    }
    while (bit > s) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (s >= r + bit) {
            s -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r << sh;
}

const char *hom_fault_name(int fault)
{
#define HOM_FAULT_NAME(id, word) word,
    static const char *const names[HOM_F_COUNT] = {HOM_FAULTS(HOM_FAULT_NAME)};
#undef HOM_FAULT_NAME
    if (fault < 0 || fault >= (int)HOM_F_COUNT) {
        return "unknown";
    }
    return names[fault];
}

HOM_NOINLINE static void push_event(hom_t *h, uint8_t type, uint8_t code, uint8_t index, int32_t a,
                                    int32_t b)
{
    hom_event_t *e;
    if (h->ev_count >= HOM_EV_CAP) {
        if (h->ev_dropped < 255u) {
            h->ev_dropped++;
        }
        return;
    }
    e = &h->ev[(h->ev_head + h->ev_count) % HOM_EV_CAP];
    e->t_ms = h->now_ms;
    e->type = type;
    e->code = code;
    e->index = index;
    e->a = a;
    e->b = b;
    h->ev_count++;
}

int hom_event_pop(hom_t *h, hom_event_t *ev)
{
    if (h == NULL || ev == NULL || h->ev_count == 0u) {
        return 0;
    }
    *ev = h->ev[h->ev_head];
    h->ev_head = (uint8_t)((h->ev_head + 1u) % HOM_EV_CAP);
    h->ev_count--;
    return 1;
}

int hom_window(const hom_t *h, uint8_t i, int32_t *lo, int32_t *hi)
{
    if (h == NULL || lo == NULL || hi == NULL || i >= h->n_tendons || !((h->win_known >> i) & 1u)) {
        return HOM_E_ARG;
    }
    *lo = h->tendon[i].eng_lo;
    *hi = h->tendon[i].eng_hi;
    return 0;
}

int hom_home(const hom_t *h, uint8_t i, int32_t *ticks)
{
    if (h == NULL || ticks == NULL || i >= h->n_tendons || !h->tendon[i].have_home) {
        return HOM_E_ARG;
    }
    *ticks = h->tendon[i].home;
    return 0;
}

/* a * b / c truncated towards zero and saturated to int32, in 32-bit
 * arithmetic only (64-bit expressions cost hundreds of bytes of code per use
 * on the AVR, and a library 64-bit division is slow): the quotient and the
 * remainder of |a| * |b| / |c| are built one bit of |a| at a time (double,
 * then add |b| / |c| and |b| % |c| for a set bit), the remainder staying below
 * |c| <= 2^31 so nothing overflows. Exactly the result a 64-bit a * b / c
 * gives. c must not be 0. */
HOM_NOINLINE static int32_t muldiv(int32_t a, int32_t b, int32_t c)
{
    uint32_t ua = a < 0 ? (uint32_t)0 - (uint32_t)a : (uint32_t)a;
    uint32_t ub = b < 0 ? (uint32_t)0 - (uint32_t)b : (uint32_t)b;
    uint32_t uc = c < 0 ? (uint32_t)0 - (uint32_t)c : (uint32_t)c;
    uint32_t bq = ub / uc;
    uint32_t br = ub % uc;
    uint32_t q = 0;
    uint32_t r = 0;
    uint8_t k;
    for (k = 0; k < 32u; k++) {
        if (q >= 0x80000000u) {
            q = 0xFFFFFFFFu; /* beyond 32 bits: saturated below */
            break;
        }
        q <<= 1;
        r <<= 1;
        if (r >= uc) {
            r -= uc;
            q++;
        }
        if (ua & 0x80000000u) {
            uint32_t t = q + bq;
            if (t < q) {
                q = 0xFFFFFFFFu;
                break;
            }
            q = t;
            r += br;
            if (r >= uc) {
                r -= uc;
                if (q == 0xFFFFFFFFu) {
                    break;
                }
                q++;
            }
        }
        ua <<= 1;
    }
    if ((a < 0) ^ (b < 0) ^ (c < 0)) {
        return q >= 0x80000000u ? INT32_MIN : -(int32_t)q;
    }
    return q > (uint32_t)INT32_MAX ? INT32_MAX : (int32_t)q;
}

/* um to ticks, rounded up so margins are never smaller than asked */
HOM_NOINLINE static int32_t um_to_ticks(uint32_t um, uint32_t nm_per_tick)
{
    return muldiv((int32_t)um, 1000, (int32_t)nm_per_tick) + 1;
}

/* A stored home moved into this power cycle's frame: the XL430 keeps the angle
 * within one turn but not the turn count, and the spool does not turn half a
 * revolution while unpowered. */
static int32_t unwrap_home(int32_t stored, int32_t present)
{
    int32_t d = (int32_t)((uint32_t)(stored - present) & 4095u);
    if (d >= 2048) {
        d -= 4096;
    }
    return present + d;
}

/* The quantity the approach drives towards a tendon's target: delta mode the
 * table's |B(p_T) - B(p_0)| as it is; absolute mode the table's |B_magnet(p_T)|
 * as a distance from the straight-pose |b_straight| of the tendon's sensor. */
HOM_NOINLINE static uint32_t work_target(const hom_t *h, uint8_t k, uint32_t d, uint32_t abs_t)
{
    int32_t r;
    if (h->amb == NULL) {
        return d;
    }
    r = (int32_t)abs_t - (int32_t)h->sensor[k].p0;
    return (uint32_t)(r < 0 ? -r : r);
}

/* Tendon i's table point at mN with target_cuT replaced by the approach
 * quantity's target (work_target). */
HOM_NOINLINE static void work_point(const hom_t *h, uint8_t i, uint16_t mN, tbl_point_t *pt)
{
    (void)tbl_target(&h->table, i, mN, pt);
    pt->target_cuT = work_target(h, h->tendon[i].sensor, pt->target_cuT, pt->abs_target_cuT);
}

/* The table's local slope of |dB| over travel around the tension (a 100 mN
 * window clipped to the grid), cuT per tick with 8 fractional bits: the
 * first fine step's estimate before two points of its own exist. */
HOM_NOINLINE static int32_t table_slope(const hom_t *h, uint8_t i)
{
    const tbl_src_t *table = &h->table;
    uint32_t nm_per_tick = h->tendon[i].nm_per_tick;
    tbl_info_t info;
    tbl_point_t lo;
    tbl_point_t hi;
    uint16_t t = h->tension_mN;
    uint16_t t0;
    uint16_t t1;
    int32_t dticks;
    int32_t s;
    (void)tbl_info(table, &info);
    t0 = (uint16_t)(t >= info.grid_mN[0] + 50u ? t - 50u : info.grid_mN[0]);
    t1 = (uint16_t)(t + 50u <= info.grid_mN[info.n_grid - 1u] ? t + 50u
                                                              : info.grid_mN[info.n_grid - 1u]);
    work_point(h, i, t0, &lo);
    work_point(h, i, t1, &hi);
    dticks = muldiv((int32_t)hi.travel_um - (int32_t)lo.travel_um, 1000, (int32_t)nm_per_tick);
    if (dticks <= 0 || hi.target_cuT <= lo.target_cuT) {
        dticks = muldiv((int32_t)hi.travel_um, 1000, (int32_t)nm_per_tick);
        s = dticks > 0 ? muldiv((int32_t)hi.target_cuT, 256, dticks) : 256;
    } else {
        s = muldiv((int32_t)(hi.target_cuT - lo.target_cuT), 256, dticks);
    }
    return s < 1 ? 1 : s;
}

/* Loads tendon i's row for a run at the tension; raises *rel_um to the
 * release that frees it. Returns 0, or -1 when the table has no target. */
HOM_NOINLINE static int load_tendon(hom_t *h, const tbl_src_t *table, const hom_cmd_t *cmd,
                                    uint8_t i, const tbl_info_t *info, uint16_t tension,
                                    uint32_t *rel_um)
{
    tbl_tendon_t row;
    tbl_point_t pt;
    hom_tendon_t *t = &h->tendon[i];
    uint32_t r;
    (void)tbl_tendon(table, i, &row);
    if (tbl_target(table, i, tension, &pt) != 0) {
        return -1;
    }
    memset(t, 0, sizeof *t);
    t->dir = row.pull_dir < 0 ? -1 : 1;
    t->nm_per_tick = row.nm_per_tick;
    t->sensor = row.sensor;
    t->target_cuT = pt.target_cuT;
    t->travel_ticks = um_to_ticks(pt.travel_um, row.nm_per_tick);
    t->margin_ticks = um_to_ticks(h->cfg.slack_margin_um, row.nm_per_tick);
    t->limit_ticks = muldiv((int32_t)row.travel_limit_um, 1000, (int32_t)row.nm_per_tick);
    if ((cmd->stored_mask >> i) & 1u) {
        t->est_home = cmd->stored_home[i]; /* unwrapped once positions are known */
        t->have_home = 2;                  /* 2: stored, not yet measured */
    }
    if ((cmd->win_mask >> i) & 1u) {
        t->eng_lo = cmd->win_lo[i];
        t->eng_hi = cmd->win_hi[i];
    }
    /* The initial release must free a tendon left anywhere up to the top of
     * the grid: one and a half times that travel plus the margin. */
    r = row.travel_um[info->n_grid - 1u];
    r = r + r / 2u + h->cfg.slack_margin_um;
    if (r > *rel_um) {
        *rel_um = r;
    }
    return 0;
}

int hom_start(hom_t *h, const tbl_src_t *table, const hom_cmd_t *cmd)
{
    tbl_info_t info;
    uint16_t tension;
    uint8_t i;
    uint32_t rel_um = 0;

    if (h == NULL || table == NULL || cmd == NULL || (unsigned)cmd->mode > HOM_MODE_DRY) {
        return HOM_E_ARG;
    }
    if (h->state != ST_IDLE && h->state != ST_DONE && h->state != ST_FAULT) {
        return HOM_E_BUSY;
    }
    if (tbl_check(table) != 0) {
        return HOM_E_TABLE;
    }
    (void)tbl_info(table, &info);
    if (info.n_sensors > HOM_MAX_SENSORS) {
        return HOM_E_TABLE;
    }
    if (cmd->mode == HOM_MODE_SINGLE && cmd->tendon >= info.n_tendons) {
        return HOM_E_ARG;
    }
    if (cmd->mode == HOM_MODE_QUICK &&
        (cmd->stored_mask & ((1u << info.n_tendons) - 1u)) != ((1u << info.n_tendons) - 1u)) {
        return HOM_E_HOMES;
    }
    tension = cmd->tension_mN != 0u ? cmd->tension_mN : info.default_mN;
    if (tension < info.grid_mN[0] || tension > info.grid_mN[info.n_grid - 1u]) {
        return HOM_E_TENSION;
    }
    for (i = 0; i < info.n_tendons; i++) {
        if (load_tendon(h, table, cmd, i, &info, tension, &rel_um) != 0) {
            return HOM_E_TENSION;
        }
    }
    /* a fresh run: what hom_init() clears, except the config and the tendons
     * just loaded */
    memset(h, 0, offsetof(hom_t, cfg));
    memset(&h->table, 0, offsetof(hom_t, tendon) - offsetof(hom_t, table));
    memset(h->sensor, 0, sizeof *h - offsetof(hom_t, sensor));
    if (h->cfg.initial_release_um != 0u) {
        rel_um = h->cfg.initial_release_um;
    }
    h->release_um = rel_um;
    h->win_known = (uint16_t)(cmd->win_mask & ((1u << info.n_tendons) - 1u));
    h->table = *table;
    /* averages beyond the accumulator's reach would never complete */
    if (h->cfg.baseline_samples == 0u || h->cfg.baseline_samples > HOM_MAX_AVG) {
        h->cfg.baseline_samples = HOM_MAX_AVG;
    }
    if (h->cfg.avg_samples == 0u || h->cfg.avg_samples > HOM_MAX_AVG / 2u) {
        h->cfg.avg_samples = HOM_MAX_AVG / 2u;
    }
    h->mode = (uint8_t)cmd->mode;
    h->single = cmd->tendon;
    h->n_tendons = info.n_tendons;
    h->n_sensors = info.n_sensors;
    h->tension_mN = tension;
    h->noise_cuT = info.noise_cuT;
    h->engage_cuT = h->cfg.engage_min_cuT;
    if (8u * (uint32_t)info.noise_cuT > h->engage_cuT) {
        h->engage_cuT = 8u * (uint32_t)info.noise_cuT;
    }
    for (i = 0; i < info.n_tendons; i++) {
        if (h->tendon[i].target_cuT / 4u < h->engage_cuT) {
            h->engage_cuT = h->tendon[i].target_cuT / 4u;
        }
    }
    h->amb = cmd->ambient_cuT;
    h->amb_capture = cmd->ambient_capture;
    for (i = 0; h->amb != NULL && i < info.n_sensors; i++) {
        tbl_sensor_t sn;
        (void)tbl_sensor(table, i, &sn);
        h->sensor[i].p0 = hom_norm3(sn.b_straight_cuT);
    }
    /* absolute mode: the engagement threshold stays the delta mode's; the
     * targets become distances of |B_magnet(p_T)| from |b_straight| */
    for (i = 0; h->amb != NULL && i < info.n_tendons; i++) {
        hom_tendon_t *t = &h->tendon[i];
        tbl_point_t pt;
        work_point(h, i, tension, &pt);
        t->abs_sign = pt.abs_target_cuT < h->sensor[t->sensor].p0 ? -1 : 1;
        t->target_cuT = pt.target_cuT;
    }
    h->state = ST_PREFLIGHT;
    h->t_phase = 0;
    h->fault = HOM_F_NONE;
    return 0;
}

void hom_abort(hom_t *h)
{
    if (h != NULL && h->state != ST_IDLE && h->state != ST_DONE && h->state != ST_FAULT) {
        h->abort_req = 1;
    }
}

/* ---- helpers ------------------------------------------------------------------ */

/* d ticks in the tendon's pull direction (dir is +1 or -1). */
HOM_NOINLINE static int32_t pull(const hom_tendon_t *t, int32_t d)
{
    return t->dir < 0 ? -d : d;
}

HOM_NOINLINE static int32_t slack_goal(const hom_tendon_t *t)
{
    return t->engage - pull(t, t->margin_ticks);
}

/* Milliseconds from t to the current step. */
HOM_NOINLINE static uint32_t since(const hom_t *h, uint32_t t)
{
    return (uint32_t)(h->now_ms - t);
}

HOM_NOINLINE static void set_goal(hom_t *h, uint8_t i, int32_t goal, uint16_t vel)
{
    h->moved_ms[i] = h->now_ms;
    h->out.goal[i] = goal;
    h->out.vel[i] = vel;
    h->out.acc[i] = h->cfg.acc;
    h->out.torque[i] = 1;
    h->out.changed |= (uint16_t)(1u << i);
    h->moved = 1;
}

/* At the goal: within a tick, or stopped short by a few ticks for
 * HOM_STILL_MS since both the command and the last motion (a position
 * controller without integral action droops under the tendon's load). */
HOM_NOINLINE static int reached(const hom_t *h, uint8_t i)
{
    int32_t d = h->present[i] - h->out.goal[i];
    if (d >= -1 && d <= 1) {
        return 1;
    }
    return d >= -HOM_DROOP_TICKS && d <= HOM_DROOP_TICKS &&
           since(h, h->moved_ms[i]) >= HOM_STILL_MS;
}

/* Every tendon whose goal was set in this run has reached it. */
HOM_NOINLINE static int all_reached(const hom_t *h)
{
    uint8_t i;
    for (i = 0; i < h->n_tendons; i++) {
        if (!reached(h, i)) {
            return 0;
        }
    }
    return 1;
}

HOM_NOINLINE static void start_avg(hom_t *h)
{
    uint8_t k;
    for (k = 0; k < h->n_sensors; k++) {
        memset(h->sensor[k].acc, 0, sizeof h->sensor[k].acc);
        h->sensor[k].n_acc = 0;
    }
}

HOM_NOINLINE static void avg_of(const hom_t *h, uint8_t k, int32_t out[3])
{
    int a;
    int32_t n = h->sensor[k].n_acc ? h->sensor[k].n_acc : 1;
    for (a = 0; a < 3; a++) {
        int32_t s = h->sensor[k].acc[a];
        out[a] = (s >= 0 ? s + n / 2 : s - n / 2) / n;
    }
}

/* |b - r| */
HOM_NOINLINE static uint32_t diff_norm(const int32_t b[3], const int32_t r[3])
{
    int32_t d[3];
    int a;
    for (a = 0; a < 3; a++) {
        d[a] = b[a] - r[a];
    }
    return hom_norm3(d);
}

static uint32_t delta_of(const hom_t *h, uint8_t k, const int32_t b[3])
{
    return diff_norm(b, h->sensor[k].b0);
}

/* The approach quantity of sensor k at field b: delta mode |b - B0|;
 * absolute mode the selected tendon's signed distance of |b - A| from the
 * straight-pose |b_straight| (0 below it), so that it rises from about 0 at
 * engagement to target_cuT exactly where |b - A| meets the absolute target. */
HOM_NOINLINE static uint32_t meas_of(const hom_t *h, uint8_t k, const int32_t b[3])
{
    int32_t m;
    if (h->amb == NULL) {
        return delta_of(h, k, b);
    }
    m = (int32_t)diff_norm(b, h->amb[k]) - (int32_t)h->sensor[k].p0;
    if (h->tendon[h->cur].abs_sign < 0) {
        m = -m;
    }
    return m < 0 ? 0u : (uint32_t)m;
}

static int32_t floor_div256(int32_t q8)
{
    return q8 >= 0 ? (q8 + 128) / 256 : -((-q8 + 127) / 256);
}

/* Of two goals, the one further in the release direction. */
HOM_NOINLINE static int32_t further_back(const hom_tendon_t *t, int32_t g, int32_t x)
{
    return pull(t, x - g) < 0 ? x : g;
}

/* Ends the run in a fault: the release goals go out in this very step. A
 * tendon that engaged goes back to the margin beyond its engagement; any
 * other goes back the margin from where it is (or keeps a release already
 * under way if that is further). Nothing moves if nothing had moved. */
HOM_NOINLINE static void fail(hom_t *h, hom_fault_t f, uint8_t dev, uint8_t index, int32_t detail)
{
    uint8_t i;
    h->fault = (uint8_t)f;
    h->fault_dev = dev;
    h->fault_index = index;
    push_event(h, HOM_EV_FAULT, (uint8_t)f, index, dev, detail);
    if (h->moved) {
        for (i = 0; i < h->n_tendons; i++) {
            const hom_tendon_t *t = &h->tendon[i];
            /* the slack margin before the engagement window (this run's
             * engagement when it engaged: the window is narrowed to it), a
             * release already going further, and never a pull */
            int32_t g = t->eng_lo - pull(t, t->margin_ticks);
            g = further_back(t, g, h->out.goal[i]);
            set_goal(h, i, further_back(t, h->present[i], g), h->cfg.v_release);
        }
        push_event(h, HOM_EV_RELEASED, 0, 0, (int32_t)f, 0);
    }
    h->state = ST_FAULT;
}

/* fail() naming the tendon being calibrated. */
HOM_NOINLINE static void fail_tendon(hom_t *h, hom_fault_t f, int32_t detail)
{
    fail(h, f, HOM_DEV_TENDON, h->cur, detail);
}

/* Sensor bookkeeping and health checks of one step. Returns 1 if it failed. */
HOM_NOINLINE static int check_sensors(hom_t *h, const hom_in_t *in)
{
    uint8_t k;
    int a;
    for (k = 0; k < h->n_sensors; k++) {
        const hom_sensor_in_t *s = &in->sensor[k];
        hom_sensor_t *st = &h->sensor[k];
        if (s->status == HOM_SENS_OVERFLOW) {
            fail(h, HOM_F_SATURATED, HOM_DEV_SENSOR, k, 0);
            return 1;
        }
        if (s->status == HOM_SENS_ERROR || s->status == HOM_SENS_ABSENT) {
            if (++st->err_run >= 3u) {
                fail(h, HOM_F_SENSOR_ERROR, HOM_DEV_SENSOR, k, s->status);
                return 1;
            }
        } else if (s->status == HOM_SENS_NEW) {
            st->err_run = 0;
            for (a = 0; a < 3; a++) {
                int32_t v = s->b_cuT[a];
                if (v >= (int32_t)h->cfg.sat_cuT || v <= -(int32_t)h->cfg.sat_cuT) {
                    fail(h, HOM_F_SATURATED, HOM_DEV_SENSOR, k, v);
                    return 1;
                }
                if (st->have_last) {
                    int32_t d = v - st->last[a];
                    if (d > (int32_t)h->cfg.rate_limit_cuT || d < -(int32_t)h->cfg.rate_limit_cuT) {
                        fail(h, HOM_F_FIELD_RATE, HOM_DEV_SENSOR, k, d);
                        return 1;
                    }
                }
            }
            memcpy(st->last, s->b_cuT, sizeof st->last);
            st->have_last = 1;
            st->last_ms = h->now_ms;
            if (st->n_acc < HOM_MAX_AVG) {
                for (a = 0; a < 3; a++) {
                    st->acc[a] += s->b_cuT[a];
                }
                st->n_acc++;
            }
        }
        if (since(h, st->last_ms) > h->cfg.sensor_timeout_ms) {
            fail(h, HOM_F_SENSOR_TIMEOUT, HOM_DEV_SENSOR, k, (int32_t)since(h, st->last_ms));
            return 1;
        }
    }
    return 0;
}

HOM_NOINLINE static int check_servos(hom_t *h, const hom_in_t *in)
{
    uint8_t i;
    for (i = 0; i < h->n_tendons; i++) {
        const hom_servo_in_t *s = &in->servo[i];
        if (s->status == HOM_SERVO_OK) {
            if (s->hw_error != 0u) {
                fail(h, HOM_F_SERVO_ERROR, HOM_DEV_SERVO, i, s->hw_error);
                return 1;
            }
            if (s->pos != h->present[i]) {
                h->moved_ms[i] = h->now_ms;
            }
            h->present[i] = s->pos;
            h->servo_ok_ms[i] = h->now_ms;
        } else if (since(h, h->servo_ok_ms[i]) > h->cfg.servo_timeout_ms) {
            fail(h, HOM_F_SERVO_TIMEOUT, HOM_DEV_SERVO, i, (int32_t)since(h, h->servo_ok_ms[i]));
            return 1;
        }
    }
    return 0;
}

/* ---- phases ------------------------------------------------------------------- */

/* Where a run releases tendon i to before its slack check: the margin
 * before its engagement window (quick mode: before the engagement the stored
 * home implies). The slack check's further steps count from here, not from
 * where the tendon stands, so runs after stops do not pay out more. */
HOM_NOINLINE static int32_t release_base(const hom_t *h, uint8_t i)
{
    const hom_tendon_t *t = &h->tendon[i];
    if (h->mode == HOM_MODE_QUICK) {
        return t->est_home - pull(t, t->travel_ticks + t->margin_ticks);
    }
    return t->eng_lo - pull(t, t->margin_ticks);
}

/* Preflight: every device must answer within preflight_ms; each one that does
 * not, or reports an error, is named before the refusal. */
static void do_preflight(hom_t *h, const hom_in_t *in)
{
    uint8_t i;
    int missing = 0;
    int all = 1;
    if (!h->pf_started) {
        h->pf_started = 1;
        h->t_phase = h->now_ms;
        h->t_start = h->now_ms;
        push_event(h, HOM_EV_START, h->mode, 0, h->tension_mN, 0);
        push_event(h, HOM_EV_PHASE, HOM_PH_PREFLIGHT, 0, 0, 0);
        memset(h->seen, 0, sizeof h->seen);
        for (i = 0; i < h->n_tendons; i++) {
            h->servo_ok_ms[i] = 0xFFFFFFFFu; /* not yet answered */
        }
    }
    for (i = 0; i < h->n_sensors; i++) {
        uint8_t st = in->sensor[i].status;
        if (st == HOM_SENS_NEW) {
            h->seen[i] |= 1u;
            memcpy(h->sensor[i].last, in->sensor[i].b_cuT, sizeof h->sensor[i].last);
            h->sensor[i].have_last = 1;
        } else if (st == HOM_SENS_ERROR || st == HOM_SENS_OVERFLOW || st == HOM_SENS_ABSENT) {
            h->seen[i] |= (uint8_t)(st == HOM_SENS_ABSENT ? 2u : 4u);
        }
        if (h->seen[i] != 1u) {
            all = 0; /* not sampled yet, or an error reported earlier */
        }
    }
    for (i = 0; i < h->n_tendons; i++) {
        const hom_servo_in_t *s = &in->servo[i];
        if (s->status == HOM_SERVO_OK && s->hw_error == 0u) {
            h->servo_ok_ms[i] = h->now_ms;
            h->present[i] = s->pos;
        } else if (s->status == HOM_SERVO_OK || s->status == HOM_SERVO_ABSENT) {
            h->servo_ok_ms[i] = 0xFFFFFFFEu; /* faulty: hardware error or absent */
        }
        if (h->servo_ok_ms[i] >= 0xFFFFFFFEu) {
            all = 0;
        }
    }
    if (all) {
        for (i = 0; i < h->n_sensors; i++) {
            h->sensor[i].last_ms = h->now_ms;
        }
        push_event(h, HOM_EV_PHASE, HOM_PH_RELEASE, 0, 0, 0);
        for (i = 0; i < h->n_tendons; i++) {
            hom_tendon_t *t = &h->tendon[i];
            int32_t g;
            t->est_home = unwrap_home(t->est_home, h->present[i]);
            if (h->mode == HOM_MODE_DRY) {
                continue;
            }
            if (!((h->win_known >> i) & 1u)) {
                /* nothing known: the engagement may lie up to the release
                 * that frees a tendon left at the top of the grid behind the
                 * present position, or (slack) ahead of it */
                t->eng_hi = h->present[i];
                t->eng_lo = h->present[i] -
                            pull(t, um_to_ticks(h->release_um, t->nm_per_tick) - t->margin_ticks);
                if (h->mode == HOM_MODE_QUICK) {
                    t->eng_hi = t->est_home - pull(t, t->travel_ticks);
                    t->eng_lo = t->eng_hi;
                }
                h->win_known |= (uint16_t)(1u << i);
                h->win_changed |= (uint16_t)(1u << i);
            }
            g = release_base(h, i);
            set_goal(h, i, further_back(t, h->present[i], g), h->cfg.v_release);
        }
        /* a dry run moves nothing: straight to the baseline average */
        h->state = h->mode == HOM_MODE_DRY ? ST_SLACK_AVG : ST_RELEASE_ALL;
        h->t_phase = h->now_ms;
        h->steps = 0;
        return;
    }
    if (since(h, h->t_phase) < h->cfg.preflight_ms) {
        return;
    }
    for (i = 0; i < h->n_sensors; i++) {
        if (h->seen[i] != 1u) {
            int32_t why = (h->seen[i] & 2u) ? 1 : ((h->seen[i] & 4u) ? 3 : 2);
            push_event(h, HOM_EV_MISSING, HOM_DEV_SENSOR, i, why, 0);
            missing++;
        }
    }
    for (i = 0; i < h->n_tendons; i++) {
        if (h->servo_ok_ms[i] >= 0xFFFFFFFEu) {
            const hom_servo_in_t *s = &in->servo[i];
            int32_t why = s->status == HOM_SERVO_ABSENT ? 1 : (s->hw_error != 0u ? 4 : 2);
            push_event(h, HOM_EV_MISSING, HOM_DEV_SERVO, i, why, s->hw_error);
            missing++;
        }
    }
    fail(h, HOM_F_PREFLIGHT, HOM_DEV_NONE, 0, missing);
}

static int32_t um_ticks_cur(const hom_t *h, uint8_t i, uint32_t um)
{
    return um_to_ticks(um, h->tendon[i].nm_per_tick);
}

/* The next tendon to calibrate at or after `from`, or n_tendons when none. */
static uint8_t next_tendon(const hom_t *h, uint8_t from)
{
    if (h->mode == HOM_MODE_SINGLE) {
        return from <= h->single ? h->single : h->n_tendons;
    }
    return from;
}

/* Where the take-up search for engagement ends: the most slack a tendon may
 * have started with past the high end of its engagement window (what every
 * earlier release paid out lies behind it), at least two ticks on. */
HOM_NOINLINE static int32_t search_goal(const hom_t *h, uint8_t i)
{
    const hom_tendon_t *t = &h->tendon[i];
    int32_t g = t->eng_hi + pull(t, um_ticks_cur(h, i, h->cfg.max_takeup_um));
    return further_back(t, g, h->present[i] + pull(t, 2)) == g ? h->present[i] + pull(t, 2) : g;
}

/* Distance of tendon i to its goal in the final move: its home (measured or
 * stored), else where it was sent last. */
HOM_NOINLINE static int32_t final_dist(const hom_t *h, uint8_t i, int32_t *goal)
{
    const hom_tendon_t *t = &h->tendon[i];
    int32_t d;
    *goal = t->have_home == 1u ? t->home : (t->have_home == 2u ? t->est_home : h->out.goal[i]);
    d = *goal - h->present[i];
    return d < 0 ? -d : d;
}

HOM_NOINLINE static void begin_final(hom_t *h)
{
    uint8_t i;
    int32_t dmax = 1;
    int32_t g;
    push_event(h, HOM_EV_PHASE, HOM_PH_FINAL, 0, 0, 0);
    for (i = 0; i < h->n_tendons; i++) {
        int32_t d = final_dist(h, i, &g);
        if (d > dmax) {
            dmax = d;
        }
    }
    /* the same profile shape for all, velocities in proportion to distance,
     * so every tendon arrives at the same moment */
    for (i = 0; i < h->n_tendons; i++) {
        if (h->tendon[i].have_home != 0u) {
            uint32_t d = (uint32_t)final_dist(h, i, &g);
            uint32_t v = ((uint32_t)h->cfg.v_final * d + (uint32_t)dmax - 1u) / (uint32_t)dmax;
            set_goal(h, i, g, (uint16_t)(v == 0u ? 1u : v));
        }
    }
    h->state = ST_FINAL;
    h->t_phase = h->now_ms;
}

HOM_NOINLINE static void begin_tendon(hom_t *h, uint8_t i)
{
    hom_tendon_t *t;
    int32_t g;
    if (i >= h->n_tendons) {
        begin_final(h);
        return;
    }
    t = &h->tendon[i];
    h->cur = i;
    h->t_tendon = h->now_ms;
    h->have_prev = 0;
    h->near = 0;
    h->n_pts = 0;
    h->steps = 0;
    h->slope_q8 = table_slope(h, i);
    h->pos_at_sample = h->present[i];
    t->engaged = 0;
    t->retries = 0;
    push_event(h, HOM_EV_PHASE, HOM_PH_TENDON, i, 0, 0);
    h->quick_leg = 0;
    if (h->mode == HOM_MODE_QUICK) {
        /* straight to just short of the stored home: a tenth of the expected
         * travel (at least 3 ticks) leaves room for the fine steps */
        int32_t guard = t->travel_ticks / 10 < 3 ? 3 : t->travel_ticks / 10;
        g = t->est_home - pull(t, guard);
        if (pull(t, g - h->present[i]) > 0) {
            h->quick_leg = 1;
            set_goal(h, i, g, h->cfg.v_fast);
            h->state = ST_TAKEUP;
            return;
        }
    }
    set_goal(h, i, search_goal(h, i),
             h->mode == HOM_MODE_QUICK ? h->cfg.v_moderate : h->cfg.v_fast);
    h->state = ST_TAKEUP;
}

/* Faults when position x of the engaged tendon lies beyond its travel limit
 * past engagement. Returns 1 if it did. */
HOM_NOINLINE static int beyond_limit(hom_t *h, int32_t x)
{
    const hom_tendon_t *t = &h->tendon[h->cur];
    int32_t d;
    if (!t->engaged) {
        return 0;
    }
    d = pull(t, x - t->engage);
    if (d > t->limit_ticks) {
        fail_tendon(h, HOM_F_TRAVEL_LIMIT, d);
        return 1;
    }
    return 0;
}

/* A goal in the pull direction, refused beyond the travel limit. */
HOM_NOINLINE static int pull_to(hom_t *h, int32_t g, uint16_t v)
{
    if (beyond_limit(h, g)) {
        return -1;
    }
    set_goal(h, h->cur, g, v);
    return 0;
}

HOM_NOINLINE static void begin_moderate(hom_t *h)
{
    hom_tendon_t *t = &h->tendon[h->cur];
    int32_t g;
    if (t->retries != 0u) {
        g = h->mod_goal;
    } else {
        g = t->engage + pull(t, muldiv(t->travel_ticks, h->cfg.near_permille, 1000));
    }
    if (pull(t, g - t->engage) > t->limit_ticks) {
        g = t->engage + pull(t, t->limit_ticks);
    }
    if (pull(t, g - h->present[h->cur]) < 2) {
        g = h->present[h->cur] + pull(t, 2);
    }
    if (pull_to(h, g, h->cfg.v_moderate) == 0) {
        h->state = ST_MODERATE;
    }
}

HOM_NOINLINE static void begin_fine_move(hom_t *h)
{
    h->state = ST_FINE_MOVE;
    h->t_phase = h->now_ms;
}

/* Samples to average at a point near the target: enough that the noise of
 * the average (table noise per axis / sqrt n) is at most a seventh of the
 * field change of one tick; at least twice avg_samples, at most HOM_MAX_AVG.
 * A weak field (sensors far from the magnet, a high tension where |dB|
 * flattens) needs many; a strong one needs the minimum. */
HOM_NOINLINE static uint8_t near_samples(const hom_t *h, int32_t s_q8)
{
    int32_t q = ((int32_t)h->noise_cuT * 7 * 256 + s_q8 - 1) / s_q8; /* ceil(7 noise / slope) */
    int32_t n = q > 6 ? (int32_t)HOM_MAX_AVG : q * q;
    int32_t lo = 2 * (int32_t)h->cfg.avg_samples;
    if (n < lo) {
        n = lo;
    }
    return (uint8_t)(n > (int32_t)HOM_MAX_AVG ? (int32_t)HOM_MAX_AVG : n);
}

/* Keeps a point averaged near the target for the final fit (the newest
 * HOM_FIT_POINTS). */
static void keep_point(hom_t *h, int32_t p, uint32_t b, uint8_t n)
{
    uint8_t k;
    if (h->n_pts == HOM_FIT_POINTS) {
        for (k = 1; k < HOM_FIT_POINTS; k++) {
            h->pts[k - 1u] = h->pts[k];
        }
        h->n_pts--;
    }
    h->pts[h->n_pts].p = p;
    h->pts[h->n_pts].b = b;
    h->pts[h->n_pts].n = n;
    h->n_pts++;
}

/* The home from a weighted least-squares line through the near points within
 * 4 ticks of p (weights: samples averaged): every sample taken near the
 * target counts, not only the last two points', which matters where one
 * tick is worth little more than the sensor noise. Returns the fitted
 * crossing in 1/256 tick, or `fallback` when fewer than two positions, a
 * non-rising line, or a crossing more than a tick outside the points.
 * 32-bit arithmetic: the crossing does not change when every y is scaled by
 * the same factor, so sums of y beyond what the products below hold in 32
 * bits (|sy| >= 2^21: points 164 uT or more from the target on average) are
 * halved together until they fit; below that the result is exact. */
HOM_NOINLINE static int32_t fit_or(const hom_t *h, int32_t p, int32_t fallback)
{
    const hom_tendon_t *t = &h->tendon[h->cur];
    /* at most 4 points of at most 32 samples with |x| <= 4: the sums without
     * y fit 16 bits (|sx| <= 512, sxx <= 2048, d < 2^18); with |y| < 2^20
     * the others fit 32; |sy| < 2^21 and |sxy| < 2^23 keep each product of
     * snum below 2^30 */
    int16_t sn = 0;
    int16_t sx = 0;
    int16_t sxx = 0;
    int32_t sy = 0;
    int32_t sxy = 0;
    int32_t d;
    int32_t snum;
    int32_t x_q8;
    int16_t lo = 0;
    int16_t hi = 0;
    uint8_t k;
    for (k = 0; k < h->n_pts; k++) {
        int32_t x = pull(t, h->pts[k].p - p); /* pull-direction ticks from p */
        int32_t y = (int32_t)h->pts[k].b - (int32_t)t->target_cuT;
        int16_t n = h->pts[k].n;
        int16_t nx;
        if (x < -4 || x > 4 || y >= (1L << 20) || y <= -(1L << 20)) {
            continue;
        }
        nx = (int16_t)(n * x);
        lo = x < lo ? (int16_t)x : lo;
        hi = x > hi ? (int16_t)x : hi;
        sn = (int16_t)(sn + n);
        sx = (int16_t)(sx + nx);
        sxx = (int16_t)(sxx + nx * x);
        sy += n * y;
        sxy += nx * y;
    }
    while (sy >= (1L << 21) || sy <= -(1L << 21) || sxy >= (1L << 23) || sxy <= -(1L << 23)) {
        sy /= 2;
        sxy /= 2;
    }
    d = (int32_t)sn * sxx - (int32_t)sx * sx;
    snum = (int32_t)sn * sxy - (int32_t)sx * sy;
    if (hi == lo || d <= 0 || snum <= 0) {
        return fallback;
    }
    /* y = a + s x with s = snum / d; the crossing y = 0 lies at
     * x = (sx - sy d / snum) / sn. A quotient beyond 2^20 puts the crossing
     * far outside the points (|sx * 256| <= 2^17, sn * 5 * 256 < 2^18). */
    x_q8 = muldiv(sy, d * 256, snum);
    if (x_q8 > (1L << 20) || x_q8 < -(1L << 20)) {
        return fallback;
    }
    x_q8 = ((int32_t)sx * 256 - x_q8) / sn;
    if (x_q8 < (lo - 1) * 256 || x_q8 > (hi + 1) * 256) {
        return fallback;
    }
    return p * 256 + pull(t, x_q8);
}

/* The home is found: the fit through the near points of p, or `fallback`
 * (1/256 tick); the tendon goes back to slack, and the home is recorded and
 * reported once the field has come back to the baseline there
 * (release_check()). */
HOM_NOINLINE static void finish_tendon(hom_t *h, int32_t p, int32_t fallback)
{
    hom_tendon_t *t = &h->tendon[h->cur];
    int32_t home_q8 = fit_or(h, p, fallback);
    t->home = floor_div256(home_q8);
    h->home_res = home_q8 - t->home * 256;
    h->home_dB = delta_of(h, t->sensor, h->sensor[t->sensor].last);
    set_goal(h, h->cur, slack_goal(t), h->cfg.v_release);
    h->state = ST_TENDON_RELEASE;
    h->settled = 0;
    h->t_phase = h->now_ms;
}

/* The tendon is back at slack after its home: every tendon slack, the
 * robot straight, so its selected sensor must read the baseline again
 * (within the engagement threshold, averaged). A field that stays changed
 * means something moved that no tendon moves (a magnet, a sensor, iron
 * nearby) and the home measured against it is wrong: HOM_F_FIELD_STEP, the
 * home is not recorded. Otherwise the home is recorded and reported. */
HOM_NOINLINE static void release_check(hom_t *h)
{
    hom_tendon_t *t = &h->tendon[h->cur];
    int32_t avg[3];
    uint32_t d;
    if (!h->settled) {
        if (move_done(h, reached(h, h->cur), HOM_DEV_SERVO, h->cur)) {
            h->settled = 1;
            h->t_phase = h->now_ms;
        }
        return;
    }
    if (h->settled == 1u) {
        if (since(h, h->t_phase) >= h->cfg.settle_ms) {
            start_avg(h);
            h->settled = 2;
        }
        return;
    }
    if (h->sensor[t->sensor].n_acc < h->cfg.avg_samples) {
        return;
    }
    avg_of(h, t->sensor, avg);
    d = delta_of(h, t->sensor, avg);
    if (d > h->engage_cuT) {
        fail(h, HOM_F_FIELD_STEP, HOM_DEV_SENSOR, t->sensor, (int32_t)d);
        return;
    }
    t->have_home = 1;
    h->tendon_ms = since(h, h->t_tendon);
    push_event(h, HOM_EV_HOME, 0, h->cur, t->home, h->home_res);
    h->settled = 0;
    begin_tendon(h, next_tendon(h, (uint8_t)(h->cur + 1u)));
}

/* Remaining travel from a field b to the target along the table's own
 * field-travel curve (inverse interpolation over the grid, engagement as the
 * origin), 1/256 tick; 0 when the table cannot say. The field is not linear
 * in travel (it flattens as the tip moves away), so from a point well short of
 * the target this beats any one slope. */
HOM_NOINLINE static int32_t table_remaining_q8(const hom_t *h, uint32_t b)
{
    tbl_tendon_t row;
    tbl_info_t info;
    const hom_tendon_t *t = &h->tendon[h->cur];
    uint32_t x0 = 0;
    uint32_t y0 = 0;
    int32_t travel_b = -1;
    int32_t travel_t;
    uint8_t g;
    if (tbl_tendon(&h->table, h->cur, &row) != 0 || tbl_info(&h->table, &info) != 0) {
        return 0;
    }
    for (g = 0; g < info.n_grid && travel_b < 0; g++) {
        uint32_t x1 = row.travel_um[g];
        uint32_t y1 = work_target(h, t->sensor, row.target_cuT[g], row.abs_target_cuT[g]);
        if (b < y1 && y1 > y0) {
            travel_b = (int32_t)x0 * 256 +
                       muldiv((int32_t)(b - y0), (int32_t)(x1 - x0) * 256, (int32_t)(y1 - y0));
        }
        x0 = x1;
        y0 = y1;
    }
    if (travel_b < 0) {
        return 0;
    }
    travel_t = muldiv(t->travel_ticks * 256, (int32_t)t->nm_per_tick, 1000); /* um * 256 */
    if (travel_t <= travel_b) {
        return 0;
    }
    return muldiv(travel_t - travel_b, 1000, (int32_t)t->nm_per_tick);
}

/* One averaged fine point at the present position. Finishes by interpolation
 * when the target is bracketed by two points at most 3 ticks apart, or by
 * extrapolation with the local slope when it is less than half a tick away
 * and the point was averaged with the doubled sample count (a slope measured
 * over a wider step overstates the local one, so longer extrapolations are
 * replaced by a one-tick step and a bracket). Otherwise it steps towards the
 * target: the whole predicted distance when it is 3 ticks or less (rounded
 * down, at least one), three quarters of it beyond, so the approach stays on
 * the slack side of the target. A wide overshoot backs off to slack and comes
 * again to the last point known to be short of it. */
static void fine_point(hom_t *h)
{
    hom_tendon_t *t = &h->tendon[h->cur];
    int32_t avg[3];
    int32_t p = h->present[h->cur];
    uint32_t b;
    int32_t s_q8;
    int32_t r_q8;
    int32_t step;
    int32_t room;
    int32_t dp;

    avg_of(h, t->sensor, avg);
    b = meas_of(h, t->sensor, avg);
    dp = h->have_prev ? pull(t, p - h->p_prev) : 0;
    if (h->near) {
        keep_point(h, p, b, h->sensor[t->sensor].n_acc);
    }
    if (b >= t->target_cuT) {
        if (h->have_prev && dp == 0) {
            /* the same position averaged again h->now_ms reads at or past the
             * target: the target is here, within the noise */
            finish_tendon(h, p, p * 256);
            return;
        }
        if (h->have_prev && b > h->b_prev && dp >= 1 && dp <= 3) {
            int32_t f = muldiv((int32_t)(t->target_cuT - h->b_prev), (p - h->p_prev) * 256,
                               (int32_t)(b - h->b_prev));
            finish_tendon(h, p, h->p_prev * 256 + f);
            return;
        }
        if (++t->retries > 2u) {
            fail_tendon(h, HOM_F_NO_PROGRESS, (int32_t)b);
            return;
        }
        if (h->have_prev) {
            /* the secant across the crossing is the slope to come back with */
            if (dp > 0 && b > h->b_prev) {
                h->slope_q8 = muldiv((int32_t)(b - h->b_prev), 256, dp);
            }
            h->mod_goal = h->p_prev;
        } else {
            /* scale the travel by how far the field overshot (the take-up can
             * cross a low target within one sample), then keep a margin */
            h->mod_goal =
                t->engage + muldiv(muldiv(p - t->engage, (int32_t)t->target_cuT, (int32_t)b),
                                   h->cfg.near_permille, 1000);
        }
        h->have_prev = 0;
        h->n_pts = 0;
        set_goal(h, h->cur, slack_goal(t), h->cfg.v_release);
        h->state = ST_BACKOFF;
        return;
    }
    /* a slope measured over 3 ticks or more replaces the estimate; one over
     * fewer ticks is too noisy and the last good one is kept */
    if (h->have_prev && dp >= 3 && b > h->b_prev) {
        h->slope_q8 = muldiv((int32_t)(b - h->b_prev), 256, dp);
    }
    s_q8 = h->slope_q8;
    if (s_q8 < 1) {
        s_q8 = 1;
    }
    r_q8 = muldiv((int32_t)(t->target_cuT - b), 65536, s_q8);
    if (!h->have_prev && t->retries == 0u) {
        /* first point: the table's own curve says how far the target is */
        int32_t rt = table_remaining_q8(h, b);
        if (rt > 0) {
            r_q8 = rt;
        }
    }
    if (r_q8 < 128 && h->near) {
        finish_tendon(h, p, p * 256 + pull(t, (int32_t)r_q8));
        return;
    }
    room = (t->limit_ticks - pull(t, p - t->engage)) * 256;
    if (r_q8 > room) {
        /* the target lies beyond the travel limit: unreachable, stop here */
        fail_tendon(h, HOM_F_TRAVEL_LIMIT, pull(t, p - t->engage) + r_q8 / 256);
        return;
    }
    if (++h->steps > h->cfg.fine_max_steps) {
        fail_tendon(h, HOM_F_NO_PROGRESS, (int32_t)b);
        return;
    }
    step = r_q8 <= 3 * 256 ? r_q8 >> 8 : (r_q8 / 4 * 3) >> 8;
    if (r_q8 >= 128 && step < 1) {
        step = 1; /* half a tick or more: bracket it rather than extrapolate */
    }
    h->near = (uint8_t)(r_q8 <= 4 * 256);
    h->n_near = near_samples(h, s_q8);
    if (step > t->limit_ticks + 1) {
        step = t->limit_ticks + 1; /* refused below as beyond the limit */
    }
    h->p_prev = p;
    h->b_prev = b;
    h->have_prev = 1;
    if (pull_to(h, p + pull(t, (int32_t)step), h->cfg.v_fine) == 0) {
        begin_fine_move(h);
    }
}

static void slack_done(hom_t *h)
{
    uint8_t k;
    uint8_t i;
    if (h->mode != HOM_MODE_DRY && h->steps > 1u) {
        /* the slack check had to release further: the engagement lies
         * behind the window, which now starts a margin past the confirmed
         * slack (later releases go no further than here) */
        for (i = 0; i < h->n_tendons; i++) {
            hom_tendon_t *t = &h->tendon[i];
            int32_t lo = h->present[i] + pull(t, t->margin_ticks);
            if (further_back(t, lo, t->eng_lo) == lo) {
                t->eng_lo = lo;
                h->win_changed |= (uint16_t)(1u << i);
            }
        }
    }
    for (k = 0; k < h->n_sensors; k++) {
        tbl_sensor_t s;
        uint32_t pred;
        (void)tbl_sensor(&h->table, k, &s);
        pred = hom_norm3(s.b_straight_cuT); /* the table's straight-pose |B| */
        if (h->amb_capture) {
            int a;
            for (a = 0; a < 3; a++) {
                h->amb[k][a] = h->sensor[k].b0[a] - s.b_straight_cuT[a];
            }
        }
        if (pred >= 10000u && hom_norm3(h->sensor[k].b0) < pred / 2u) {
            fail(h, HOM_F_MAGNET_MISSING, HOM_DEV_SENSOR, k, (int32_t)hom_norm3(h->sensor[k].b0));
            return;
        }
    }
    push_event(h, HOM_EV_PHASE, HOM_PH_BASELINE, 0, 0, 0);
    if (h->mode == HOM_MODE_DRY) {
        for (i = 0; i < h->n_tendons; i++) {
            push_event(h, HOM_EV_TARGET, 0, i, (int32_t)h->tendon[i].target_cuT,
                       muldiv(h->tendon[i].travel_ticks, (int32_t)h->tendon[i].nm_per_tick, 1000));
        }
        push_event(h, HOM_EV_DONE, 0, 0, (int32_t)since(h, h->t_start), 0);
        h->state = ST_DONE;
        return;
    }
    begin_tendon(h, next_tendon(h, 0));
}

/* Averages every sensor after a settle time; compares with the previous
 * average; releases further until nothing changes. */
HOM_NOINLINE static void do_slack_avg(hom_t *h)
{
    uint8_t k;
    uint8_t i;
    uint32_t worst = 0;
    int done;
    if (!h->settled) {
        if (since(h, h->t_phase) < h->cfg.settle_ms) {
            return;
        }
        start_avg(h);
        h->settled = 1;
        return;
    }
    for (k = 0; k < h->n_sensors; k++) {
        if (h->sensor[k].n_acc < h->cfg.baseline_samples) {
            return;
        }
    }
    h->settled = 0;
    /* until the slack is confirmed, b0 holds the previous average */
    for (k = 0; k < h->n_sensors; k++) {
        int32_t avg[3];
        int32_t d[3];
        uint32_t n;
        int a;
        avg_of(h, k, avg);
        for (a = 0; a < 3; a++) {
            d[a] = avg[a] - h->sensor[k].b0[a];
        }
        n = hom_norm3(d);
        if (n > worst) {
            worst = n;
        }
    }
    done = h->mode == HOM_MODE_DRY || (h->steps > 0u && worst <= h->engage_cuT);
    for (k = 0; k < h->n_sensors; k++) {
        int32_t avg[3];
        int a;
        avg_of(h, k, avg);
        for (a = 0; a < 3; a++) {
            /* the baseline when this average confirms the slack: both
             * averages then saw the same straight pose, so it takes both */
            int32_t *b0 = &h->sensor[k].b0[a];
            *b0 = done && h->steps > 0u ? avg[a] - (avg[a] - *b0) / 2 : avg[a];
        }
    }
    if (done) {
        slack_done(h);
        return;
    }
    if (h->steps >= h->cfg.slack_max_steps) {
        fail(h, HOM_F_SLACK, HOM_DEV_NONE, 0, (int32_t)worst);
        return;
    }
    h->steps++;
    for (i = 0; i < h->n_tendons; i++) {
        hom_tendon_t *t = &h->tendon[i];
        int32_t g =
            release_base(h, i) - pull(t, h->steps * um_ticks_cur(h, i, h->cfg.slack_step_um));
        set_goal(h, i, further_back(t, h->present[i], g), h->cfg.v_release);
    }
    h->state = ST_RELEASE_ALL;
    h->t_phase = h->now_ms;
}

/* The field b has come within permille of the target. */
HOM_NOINLINE static int near_target(const hom_tendon_t *t, uint32_t b, uint16_t permille)
{
    return (int32_t)b >= muldiv((int32_t)t->target_cuT, permille, 1000);
}

/* Close to the target while moving: stop two ticks on from the present
 * position p (unless the goal is nearer) and go on with fine points. */
HOM_NOINLINE static void stop_short(hom_t *h, int32_t p)
{
    const hom_tendon_t *t = &h->tendon[h->cur];
    uint8_t state = h->state;
    int32_t g = p + pull(t, 2);
    if (pull(t, h->out.goal[h->cur] - g) > 0) {
        (void)pull_to(h, g, h->cfg.v_moderate);
    }
    if (h->state == state) {
        begin_fine_move(h);
    }
}

HOM_NOINLINE static void do_tendon(hom_t *h, const hom_in_t *in)
{
    hom_tendon_t *t = &h->tendon[h->cur];
    uint8_t sel = t->sensor;
    int fresh = in->sensor[sel].status == HOM_SENS_NEW;
    uint32_t b = fresh ? delta_of(h, sel, in->sensor[sel].b_cuT) : 0u;
    /* delta mode: the approach quantity is |B - B0| itself, one norm */
    uint32_t m = fresh && h->amb != NULL ? meas_of(h, sel, in->sensor[sel].b_cuT) : b;
    int32_t p = h->present[h->cur];

    if (since(h, h->t_tendon) > h->cfg.tendon_timeout_ms) {
        fail_tendon(h, HOM_F_TENDON_TIMEOUT, (int32_t)since(h, h->t_tendon));
        return;
    }
    if (beyond_limit(h, p)) {
        return;
    }
    if (t->engaged && pull(t, p - h->out.goal[h->cur]) > HOM_DROOP_TICKS &&
        since(h, h->moved_ms[h->cur]) >= 10u) {
        /* pulling past the goal last sent: the servo missed that goal (a
         * sync write gets no status) and still runs to an older one; send
         * it again, every 10 ms until it takes */
        set_goal(h, h->cur, h->out.goal[h->cur], h->out.vel[h->cur]);
    }
    switch (h->state) {
    case ST_TAKEUP:
        if (fresh && !t->engaged && b >= h->engage_cuT) {
            t->engaged = 1;
            t->engage = h->pos_at_sample; /* the last position seen slack */
            t->eng_lo = t->engage;
            t->eng_hi = t->engage;
            h->win_changed |= (uint16_t)(1u << h->cur);
            push_event(h, HOM_EV_ENGAGED, 0, h->cur, t->engage, (int32_t)b);
            if (!h->quick_leg) {
                begin_moderate(h);
                break;
            }
        }
        if (fresh && !t->engaged) {
            h->pos_at_sample = p;
        }
        if (h->quick_leg && t->engaged && fresh && near_target(t, m, HOM_QUICK_STOP_PERMILLE)) {
            stop_short(h, p); /* the stored home is further than the field says */
        } else if (reached(h, h->cur)) {
            if (h->quick_leg && t->engaged) {
                begin_fine_move(h);
            } else if (h->quick_leg) {
                /* no engagement where the stored home put it: search as usual */
                h->quick_leg = 0;
                set_goal(h, h->cur, search_goal(h, h->cur), h->cfg.v_moderate);
            } else {
                fail_tendon(h, HOM_F_NO_ENGAGEMENT, pull(t, p - h->pos_at_sample));
            }
        }
        break;
    case ST_MODERATE:
        /* a re-approach goes to a point measured short of the target: only
         * the target itself stops it early */
        if (fresh && near_target(t, m, t->retries != 0u ? 1000u : h->cfg.near_permille)) {
            stop_short(h, p);
        } else if (reached(h, h->cur)) {
            begin_fine_move(h);
        }
        break;
    case ST_FINE_MOVE: {
        int32_t err = p - h->out.goal[h->cur];
        if (since(h, h->t_phase) >= h->cfg.settle_ms &&
            since(h, h->moved_ms[h->cur]) >= h->cfg.settle_ms / 2u &&
            ((err >= -1 && err <= 1) || reached(h, h->cur))) {
            start_avg(h);
            h->state = ST_FINE_AVG;
        } else if (since(h, h->t_phase) > h->cfg.move_timeout_ms) {
            fail(h, HOM_F_SERVO_STALL, HOM_DEV_SERVO, h->cur, err);
        }
        break;
    }
    case ST_FINE_AVG:
        /* points within a few ticks of the target decide the home: more samples */
        if (h->sensor[sel].n_acc >= (h->near ? h->n_near : h->cfg.avg_samples)) {
            fine_point(h);
        }
        break;
    case ST_BACKOFF:
        if (reached(h, h->cur)) {
            begin_moderate(h);
        }
        break;
    default:
        break;
    }
}

/* A release or final move: 1 when it has arrived; one that takes longer
 * than move_timeout_ms ends the run (HOM_F_SERVO_STALL). */
HOM_NOINLINE static int move_done(hom_t *h, int arrived, uint8_t dev, uint8_t index)
{
    if (!arrived && since(h, h->t_phase) > h->cfg.move_timeout_ms) {
        fail(h, HOM_F_SERVO_STALL, dev, index, 0);
    }
    return arrived;
}

int hom_step(hom_t *h, const hom_in_t *in, hom_out_t *out)
{
    uint8_t i;
    if (h == NULL || in == NULL || out == NULL) {
        return HOM_E_ARG;
    }
    h->now_ms = in->now_ms;
    h->out.changed = 0;
    if (h->state == ST_IDLE || h->state == ST_DONE || h->state == ST_FAULT) {
        *out = h->out;
        return h->state == ST_FAULT ? -(int)h->fault : 0;
    }
    if (h->abort_req) {
        h->abort_req = 0;
        for (i = 0; i < h->n_tendons; i++) {
            if (in->servo[i].status == HOM_SERVO_OK) {
                h->present[i] = in->servo[i].pos;
            }
        }
        fail(h, HOM_F_ABORTED, HOM_DEV_NONE, 0, 0);
    } else if (h->state == ST_PREFLIGHT) {
        do_preflight(h, in);
    } else {
        if (check_servos(h, in) == 0 && check_sensors(h, in) == 0) {
            switch (h->state) {
            case ST_RELEASE_ALL:
                if (move_done(h, all_reached(h), HOM_DEV_NONE, 0)) {
                    h->state = ST_SLACK_AVG;
                    h->settled = 0;
                    h->t_phase = h->now_ms;
                }
                break;
            case ST_SLACK_AVG:
                do_slack_avg(h);
                break;
            case ST_TENDON_RELEASE:
                release_check(h);
                break;
            case ST_FINAL:
                if (move_done(h, all_reached(h), HOM_DEV_NONE, 0)) {
                    push_event(h, HOM_EV_DONE, 0, 0, (int32_t)since(h, h->t_start), 0);
                    h->state = ST_DONE;
                }
                break;
            default:
                do_tendon(h, in);
                break;
            }
        }
    }
    *out = h->out;
    if (h->state == ST_FAULT) {
        return -(int)h->fault;
    }
    return h->state == ST_DONE ? 0 : HOM_RUNNING;
}
