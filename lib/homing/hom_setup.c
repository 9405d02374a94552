/*
 * hom_setup: a run's set-up (see hom_priv.h and docs/homing.md): hom_start()
 * checks the command against the table and clears the state, the preflight
 * loads each sensor's and tendon's part from the table one per step
 * (hom_load_step(), load_tendon(): target, take-up travel, travel limit,
 * slack margin, release and straight-pose shift in encoder ticks), and a
 * tendon's fresh engagement window from the table alone
 * (hom_fresh_window(), for a window the app cannot trust).
 */
#include "homing/hom_priv.h"

#include <stddef.h>
#include <string.h>

/* hom_um_to_ticks() for the tendon state's 16-bit take-up figures: at most
 * INT16_MAX, eight turns of an XL430, far beyond HOM_RELEASE_REACH_TICKS (a
 * table's grid reaches it only with a spool of under 2 nm a tick). */
HOM_NOINLINE static int16_t hom_ticks16(uint32_t um, uint32_t nm_per_tick)
{
    int32_t ticks = hom_um_to_ticks(um, nm_per_tick);
    return ticks > INT16_MAX ? INT16_MAX : (int16_t)ticks;
}

int32_t hom_straight_q8(const hom_tendon_t *t, int16_t straight_um)
{
    return -hom_pull(t, hom_muldiv(straight_um, 256000, (int32_t)t->nm_per_tick));
}

/* The slack kept beyond engagement at tension_mN for a tendon whose travel
 * there is travel_um (load_tendon() says why). */
HOM_NOINLINE static uint32_t margin_um(uint16_t slack_margin_um, uint16_t tension_mN,
                                       uint32_t travel_um)
{
    uint32_t r = slack_margin_um;
    if (tension_mN > 1000u) {
        r = r * tension_mN / 1000u;
    }
    if (travel_um + slack_margin_um / 4u > r) {
        r = travel_um + slack_margin_um / 4u;
    }
    return r;
}

/* The first release when positions are unknown, for a tendon whose travel at
 * the top of its grid is top_um (load_tendon() says why); the
 * configuration's initial_release_um and slack_margin_um. */
HOM_NOINLINE static uint32_t release_um(uint32_t initial_um, uint16_t slack_margin_um,
                                        uint32_t top_um)
{
    if (initial_um != 0u) {
        return initial_um;
    }
    return top_um + top_um / 2u + slack_margin_um;
}

/* Tendon i's row for the run at its tension: what hom_start() left for the
 * preflight (the cmd fields are set). tbl_target() cannot fail here:
 * hom_start() checked the tendon count and the tension's range. */
HOM_NOINLINE static void load_tendon(hom_t *h, uint8_t i)
{
    struct {
        tbl_point_t pt;
        tbl_tendon_head_t row;
        uint32_t top;
    } r;
    hom_tendon_t *t = &h->tendon[i];
    int32_t q8;
    (void)tbl_tendon_head(&h->table, i, &r.row);
    (void)tbl_entry(&h->table, i, TBL_ROW_TRAVEL, TBL_GRID_TOP, &r.top);
    (void)tbl_target(&h->table, i, h->tension_mN, &r.pt);
    t->dir = r.row.pull_dir < 0 ? -1 : 1;
    t->nm_per_tick = r.row.nm_per_tick;
    t->sensor = r.row.sensor;
    t->travel_ticks = hom_ticks16(r.pt.travel_um, r.row.nm_per_tick);
    /* The slack kept beyond engagement must exceed the path lengthening the
     * other tendons' pulls cause on this one: slack_margin_um covers it at
     * 1 N on the reference robot and grows with the tension above that
     * (linear statics; at 1.5 N a distal pull took up 0.6 mm of slack on
     * the opposite proximal tendon and made it carry 0.29 N). On any robot
     * a pull at the run's tension lengthens a tendon opposite it by about
     * the geometric take-up of that tendon's own pull (same moment, same
     * segments): its travel at the tension, plus a quarter of the margin
     * for a late engagement. */
    t->margin_ticks = hom_ticks16(margin_um(h->cfg.slack_margin_um, h->tension_mN, r.pt.travel_um) +
                                      (h->hold != 0u ? HOM_HELD_BACK_UM : 0u),
                                  r.row.nm_per_tick);
    q8 = hom_straight_q8(t, r.pt.straight_um);
    t->to_straight = (int16_t)hom_floor_div256(q8);
    t->straight_frac = (int8_t)(q8 - (int32_t)t->to_straight * 256);
    /* the engagement threshold is at most a quarter of every delta target */
    if (r.pt.target_cuT / 4u < h->engage_cuT) {
        h->engage_cuT = r.pt.target_cuT / 4u;
    }
    /* The bounded pull (docs/homing.md): no further past the engagement
     * than where the tension could pass 1.25 x the run's + HOM_BOUND_MN on
     * the robot the table describes, the travel taken in proportion to the
     * tension and a HOM_BOUND_SHORT-th short. The engagement is where the
     * field crossed the threshold (engagement_at(), hom_approach.c), where
     * the tendon may already carry the threshold's share of the target (its
     * field's): that much less.
     * The field decides where a tendon stops; this bounds what a field that
     * lies can ask (an ambient step against the tendon's own field, chaos
     * seeds 13456, 19346 and 19952: 1.39-2.10 x the target) on a first
     * pull. A target beyond it is looked at again (hom_over_limit()). */
    q8 = hom_muldiv((int32_t)(r.pt.travel_um - r.pt.travel_um / HOM_BOUND_SHORT),
                    h->tension_mN + h->tension_mN / 4u + HOM_BOUND_MN -
                        hom_muldiv(h->tension_mN, (int32_t)h->engage_cuT, (int32_t)r.pt.target_cuT),
                    h->tension_mN);
    t->limit_ticks = (int16_t)hom_limit_ticks(&r.row, q8);
    /* absolute mode: the engagement threshold stays the delta mode's; the
     * target becomes the distance of |B_magnet(p_T)| from |b_straight| */
    t->target_cuT = hom_work_target(h, t->sensor, r.pt.target_cuT, r.pt.abs_target_cuT);
    if (h->amb != NULL) {
        t->abs_sign = r.pt.abs_target_cuT < h->sensor[t->sensor].p0 ? -1 : 1;
    }
    /* The initial release must free the tendon left anywhere up to the top
     * of its grid: one and a half times its travel there plus the margin
     * (each tendon its own, as the app's releases: the largest of them,
     * robot-wide, paid out 6.6 mm on a 3-segment robot's short tendons). */
    t->release_ticks = (uint16_t)hom_um_to_ticks(
        release_um(h->cfg.initial_release_um, h->cfg.slack_margin_um, r.top), r.row.nm_per_tick);
}

/* A travel limit past the engagement for a pull of at most um on the
 * tendon of table row `row`: never beyond the table's travel_limit_um nor
 * HOM_RELEASE_REACH_TICKS (docs/homing.md, the safety table). */
HOM_NOINLINE int32_t hom_limit_ticks(const tbl_tendon_head_t *row, int32_t um)
{
    int32_t ticks;
    if (um > (int32_t)row->travel_limit_um) {
        um = (int32_t)row->travel_limit_um;
    }
    ticks = hom_um_ticks(um, row->nm_per_tick);
    return ticks > HOM_RELEASE_REACH_TICKS ? HOM_RELEASE_REACH_TICKS : ticks;
}

int hom_fresh_window(const tbl_src_t *table, uint8_t i, uint16_t tension_mN, int32_t p, int32_t *lo,
                     int32_t *hi)
{
    tbl_tendon_head_t row;
    tbl_point_t pt;
    uint32_t top;
    int32_t r, m;
    if (tbl_tendon_head(table, i, &row) != 0 ||
        tbl_entry(table, i, TBL_ROW_TRAVEL, TBL_GRID_TOP, &top) != 0 ||
        tbl_target(table, i, tension_mN, &pt) != 0) {
        return HOM_E_ARG;
    }
    r = hom_um_to_ticks(release_um(HOM_INITIAL_RELEASE_UM, HOM_SLACK_MARGIN_UM, top),
                        row.nm_per_tick);
    m = hom_um_to_ticks(margin_um(HOM_SLACK_MARGIN_UM, tension_mN, pt.travel_um), row.nm_per_tick);
    hom_window_around(row.pull_dir < 0 ? -1 : 1, r, r - m, p, lo, hi);
    return 0;
}

/* One piece of the run's set-up per preflight step: the table work of a
 * tendon (several divisions per grid value) costs about a millisecond on the
 * AVR, too much for twelve tendons in one pass of the main loop. Absolute
 * mode first each sensor's straight-pose |b|, then each tendon's row.
 * Returns 1 once everything is loaded. */
int hom_load_step(hom_t *h)
{
    uint8_t k = (uint8_t)(h->pf_started - 1u);
    uint8_t ns = h->amb != NULL ? h->n_sensors : 0u;
    if (k < ns) {
        tbl_sensor_t sn;
        (void)tbl_sensor(&h->table, k, &sn);
        h->sensor[k].p0 = hom_norm3(sn.b_straight_cuT);
    } else if (k < ns + h->n_tendons) {
        load_tendon(h, (uint8_t)(k - ns));
    } else {
        return 1;
    }
    h->pf_started++;
    return 0;
}

HOM_NOINLINE int hom_start(hom_t *h, const tbl_src_t *table, const hom_cmd_t *cmd)
{
    tbl_info_t info;
    uint16_t tension;
    uint8_t i;

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
    if (info.n_sensors > HOM_MAX_SENSORS || info.n_tendons > HOM_MAX_TENDONS) {
        return HOM_E_TABLE;
    }
    if (cmd->mode == HOM_MODE_SINGLE && cmd->tendon >= info.n_tendons) {
        return HOM_E_ARG;
    }
    if (cmd->hold != 0u && (!cmd->survey || cmd->mode != HOM_MODE_SINGLE ||
                            cmd->hold > info.n_tendons || cmd->hold - 1u == cmd->tendon)) {
        return HOM_E_ARG;
    }
    if (cmd->mode == HOM_MODE_QUICK &&
        (cmd->stored_mask & (hom_bit(info.n_tendons) - 1u)) != (hom_bit(info.n_tendons) - 1u)) {
        return HOM_E_HOMES;
    }
    tension = cmd->tension_mN != 0u ? cmd->tension_mN : info.default_mN;
    if (tension < tbl_grid_mN(table, 0) ||
        tension > tbl_grid_mN(table, (uint8_t)(info.n_grid - 1u))) {
        return HOM_E_TENSION;
    }
    /* a fresh run: what hom_init() clears, except the config; the table's
     * part of each tendon follows in the preflight (hom_load_step()) */
    memset(h, 0, offsetof(hom_t, cfg));
    memset(&h->table, 0, sizeof *h - offsetof(hom_t, table));
    for (i = 0; i < info.n_tendons; i++) {
        hom_tendon_t *t = &h->tendon[i];
        if (hom_has(cmd->stored_mask, i)) {
            t->est_home = cmd->stored_home[i]; /* unwrapped once positions are known */
            t->have_home = 2;                  /* 2: stored, not yet measured */
        }
        if (hom_has(cmd->win_mask, i)) {
            t->eng_lo = cmd->win_lo[i];
            t->eng_hi = cmd->win_hi[i];
        }
    }
    h->win_known = (uint16_t)(cmd->win_mask & (hom_bit(info.n_tendons) - 1u));
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
    h->amb = cmd->ambient_cuT;
    h->amb_capture = cmd->ambient_capture;
    h->survey = cmd->survey;
    h->hold = cmd->hold;
    h->state = ST_PREFLIGHT; /* held, t_phase and fault (HOM_F_NONE) are 0 */
    return 0;
}
