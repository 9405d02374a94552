/*
 * app_bus: the servo-bus room. One DYNAMIXEL transaction at a time, chosen
 * each pass in this order: a requested reboot (after the goals queued before
 * it), the Bus Watchdog writes of a bring-up, torque changes, queued goals,
 * then the cycle of position sync reads with a hardware-error read every
 * APP_HWERR_EVERY-th cycle and a goal refresh every APP_GOAL_REFRESH_EVERY-th.
 * The replies become bus.present / bus.hw_err for the other rooms.
 */

#include "app/app_priv.h"
#include "dxl/dxl_xl430_reg.h"

#define GOALS_PER_TXN 6u /* 12-byte entries of one sync write that fit DXL_TX_CAP */

uint32_t app_bus_baud(const app_t *app)
{
    return (uint32_t)app->rec.set.v[STORE_SET_BUS_BAUD];
}

/* The tendons the next group read asks: the pulled tendon alone, or all.
 * While a run takes a tendon up or approaches its home only that servo
 * moves, and the homing steps on its position. The reply of every servo
 * (56 bytes for six) cost about 1.3 ms of CPU a read and came every 4.3 ms
 * in the fine approach; read alone (16 bytes) it comes every pass (1.7 ms).
 * Every APP_FOCUS_READS + 1-th read still asks every servo, and so do the
 * reads after a read that missed a servo, before a hardware-error read and
 * while the pulled servo is silent: the other servos' positions, alert
 * bits and silence come from those, every 7 ms in the fine approach and
 * 12 ms in the take-up (18 ms at most), inside the 40 ms silence check and
 * the 120 ms servo timeout. */
static uint16_t focus(app_t *a)
{
    uint8_t i;
    if (a->state == APP_ST_CAL && (a->bus.hwerr_due | a->bus.pos_force) == 0u &&
        a->bus.focus < APP_FOCUS_READS && hom_pulling(&a->u.hom, &i) &&
        app_has((uint16_t)(a->bus.absent | a->bus.missed), i) == 0u) {
        a->bus.focus++;
        return app_bit16(i);
    }
    a->bus.focus = 0;
    return UINT16_MAX;
}

/* The IDs of a group read: the servos in `missed` go last. In a
 * Sync Read each servo answers after the status of the one before it, in a
 * Fast Sync Read it appends to it: one silent servo silences the ones after
 * it in the list. First in the list, it silenced every servo, every position
 * went stale at once and the servo timeout named one of the others (chaos
 * seed 2004: servo 1 silent at 818 mN, servo 8 named, so servo 1's tendon
 * was not reported as not released). Last, the others answer and only its
 * own position goes stale. The missed go in index order one cycle and in
 * reverse the next: always in index order, a silent servo ahead of one
 * missed to bus noise kept it silent and stale, and it was named in the
 * silent one's place (chaos seed 1029). */
static uint8_t present_ids(app_t *a, uint8_t *ids, uint16_t *mask)
{
    uint8_t i, j, pass, n = 0;
    uint16_t only = focus(a);
    *mask = 0;
    for (pass = 0; pass < 2u; pass++) {
        for (j = 0; j < a->info.n_tendons; j++) {
            /* the missed in index order one cycle, in reverse the next */
            i = (pass != 0u && (a->bus.cycle & 1u)) ? (uint8_t)(a->info.n_tendons - 1u - j) : j;
            if (app_has(only, i) && app_has(a->bus.absent, i) == 0u &&
                app_has(a->bus.missed, i) == pass) {
                ids[n++] = a->bus.ids[i];
                *mask |= app_bit16(i);
            }
        }
    }
    return n;
}

APP_NOINLINE static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

APP_NOINLINE static void servo_done(app_t *a)
{
    uint8_t i;
    uint16_t got = 0, lost, first, keep = 0;
    if (a->bus.txn == APP_TX_POS || a->bus.txn == APP_TX_HWERR) {
        for (i = 0; i < a->info.n_tendons; i++) {
            const dxl_reply *r;
            if (app_has(a->bus.txn_mask, i) == 0u) {
                continue;
            }
            r = dxl_reply_for(&a->bus.dxl, a->bus.ids[i]);
            if (r == NULL || (r->result != 0 && r->result != -DXL_E_ALERT)) {
                continue;
            }
            if (a->bus.txn == APP_TX_POS && r->len >= 4u) {
                a->bus.present[i] = dxl_reply_value(r, 4);
                got |= app_bit16(i);
            } else if (a->bus.txn == APP_TX_HWERR && r->len >= 1u) {
                a->bus.hw_err[i] = r->data[0];
                got |= app_bit16(i);
            }
            if (r->result == -DXL_E_ALERT && a->bus.txn == APP_TX_POS) {
                a->bus.hwerr_due = 1;
            }
        }
        /* The first servo of the list that did not answer silenced the ones
         * after it: it goes last in the next group read, and so does every
         * servo that went last and is still silent. A read of one servo
         * (focus()) says nothing of the others. */
        if (a->bus.focus != 0u) {
            keep = (uint16_t)~a->bus.txn_mask;
        }
        lost = (uint16_t)(a->bus.txn_mask & ~got);
        first = (uint16_t)(lost & ~a->bus.missed);
        a->bus.missed =
            (uint16_t)((a->bus.missed & (lost | keep)) | (first & (uint16_t)(0u - first)));
        if (a->bus.txn == APP_TX_POS) {
            a->bus.fresh |= got;
            a->bus.seen |= got;
        }
        if (a->bus.txn == APP_TX_POS && a->bus.focus == 0u) {
            if (got == a->bus.txn_mask) {
                uint16_t now = (uint16_t)app_now_ms(a);
                a->bus.pos_streak = 0;
                /* A servo silent this long (a loose cable) may have missed
                 * every instruction past its Bus Watchdog: it then refuses
                 * every goal, a release too, until the watchdog is cleared
                 * (chaos seed 1016: silent 0.25 s while idle, the next run's
                 * release stalled and the fault's release was refused).
                 * Clear and arm them all again, as after a bring-up. */
                if ((uint16_t)(now - a->bus.t_all_ok) > APP_SERVO_TIMEOUT_MS) {
                    a->bus.wdog_step = (uint8_t)(2u * a->info.n_tendons);
                    a->bus.wdog_bcast = 2;
                }
                a->bus.t_all_ok = now;
            } else if (a->bus.pos_streak < APP_POS_RETRIES) {
                a->bus.pos_streak++;
                a->bus.pos_force = 1;
            }
        }
    } else if (a->bus.txn == APP_TX_REBOOT) {
        /* The servo lost its multi-turn count: bring the bus up again and
         * recover the homes as after a power cycle (its window moves by the
         * turns lost: app_bus_found()). A reboot whose reply was lost or
         * cut by bus noise may have been carried out all the same, with
         * the servo's torque off: the bus comes up again then too, and the
         * bring-up's end judges the servo (app_run_rebooted()). Chaos seed
         * 3037: the reply's length byte flipped, the two retries found the
         * servo booting, and the runs that followed pulled against a tendon
         * whose servo never took its release. */
        app_boot_again(a);
    }
    a->bus.txn = APP_TX_NONE;
}

/* Tendons whose servo stands more than a tick from the goal last sent. A
 * sync write carries no reply: a servo that missed one to a corrupted byte
 * keeps its old goal, so these goals go out again every few cycles. A servo
 * that is really stuck stays where it is and the homing's stall check still
 * sees it; a servo on its way gets the goal it already has. A servo waiting
 * for its reboot (torque off) is left out. */
static uint16_t off_goal(const app_t *a)
{
    uint8_t i = a->info.n_tendons;
    uint16_t m = 0;
    while (i-- > 0u) {
        m = (uint16_t)(m << 1);
        if ((a->bus.reboot_req == 0u || a->bus.ids[i] != a->bus.reboot_id) &&
            (uint32_t)(a->bus.present[i] - hom_goal(&a->u.hom, i)) + 1u > 2u) {
            m |= 1u;
        }
    }
    return m & a->bus.torque_on;
}

APP_NOINLINE static void servo_next(app_t *a)
{
    uint8_t ids[APP_MAX_TENDONS];
    uint8_t data[GOALS_PER_TXN * 12u];
    uint8_t i, n = 0, txn, v, pos_only, wdog, id;
    uint16_t mask, addr;
    if (a->bus.reboot_req != 0u &&
        (a->bus.goal_due | a->bus.goal_again | a->bus.torque_due) == 0u &&
        (--a->bus.reboot_req == 0u || off_goal(a) == 0u)) {
        /* once every other tendon stands at its goal (a release), or after
         * APP_REBOOT_WAIT transactions: the bring-up that follows a reboot
         * owns the bus for 0.9 s and forgets the goals still queued. Chaos
         * seed 15309: the first copy of six release goals was lost to bus
         * noise, the reboot went before the second, and five tendons stayed
         * at 2 N for 940 ms. Both copies lost, the refresh of goals not
         * reached sends them again before the reboot goes. */
        a->bus.reboot_req = 0;
        if (dxl_reboot(&a->bus.dxl, a->bus.reboot_id) > 0) {
            a->bus.txn = APP_TX_REBOOT;
        } else {
            (void)con_complete(&a->cmd.con, CON_E_INTERNAL); /* a `reboot` waiting, if any */
        }
        return;
    }
    wdog = (uint8_t)(a->bus.wdog_step != 0u && !a->bus.wdog_gap);
    if (a->bus.wdog_bcast != 0u || wdog || a->bus.torque_due != 0u) {
        txn = APP_TX_WDOG;
        addr = DXL_XL430_BUS_WATCHDOG_ADDR;
        if (a->bus.wdog_bcast != 0u) {
            /* every watchdog cleared and armed at once, by two broadcast
             * writes, before the writes one by one that confirm it: cleared
             * one by one, twelve servos took 130 ms to take the release
             * goals a 100 ms `status` burst at rest had let expire (chaos
             * seed 3079) */
            v = --a->bus.wdog_bcast != 0u ? 0u : APP_BUS_WATCHDOG;
            id = DXL_BROADCAST_ID;
        } else if (wdog) {
            /* two writes per servo, from the last: 0 clears an expired
             * watchdog (the servo refuses goals until then), then the
             * period arms it. A position read between two writes: 24
             * writes in a row kept a run's positions away for 121 ms, a
             * servo_timeout (chaos seed 2049) */
            a->bus.wdog_gap = 1;
            v = a->bus.wdog_step--;
            i = (uint8_t)((v - 1u) >> 1);
            if (app_has(a->bus.absent, i)) {
                return;
            }
            v = (v & 1u) ? APP_BUS_WATCHDOG : 0u;
            id = a->bus.ids[i];
        } else {
            for (i = 0; app_has(a->bus.torque_due, i) == 0u; i++) {
            }
            a->bus.torque_due &= (uint16_t)~app_bit16(i);
            v = app_has(a->bus.torque_on, i);
            id = a->bus.ids[i];
            addr = DXL_XL430_TORQUE_ENABLE_ADDR;
            txn = APP_TX_TORQUE;
        }
        if (dxl_write_value(&a->bus.dxl, id, addr, v, 1) > 0) {
            a->bus.txn = txn;
        }
        return;
    }
    if (a->bus.goal_due == 0u && a->bus.goal_again != 0u) {
        /* a new goal goes out twice: a sync write has no reply, and one
         * lost to a corrupted byte left a take-up running until the next
         * refresh, 25 ms later on 12 servos (chaos seed 2010: 1.12 N for
         * 0.8 N). At 1e-3 bus noise both copies are lost about once in
         * 1500 goals; the refresh of goals not reached catches those. */
        a->bus.goal_due = a->bus.goal_again;
        a->bus.goal_again = 0;
    }
    if (a->bus.goal_due == 0u) {
        a->bus.wdog_gap = 0;
        n = present_ids(a, ids, &mask);
        if (n == 0u) {
            return;
        }
        a->bus.txn_mask = mask;
        /* even before a forced position read or a hardware-error read: a
         * lost goal is worse than a late position. The error reads that
         * every position read of a servo in alert asks for took every
         * other cycle, always those of the refresh: both copies of five
         * release goals lost, and no refresh for 990 ms (chaos seed 21268).
         * A read of the pulled servo alone is no cycle: the refreshes and
         * error reads keep their pace in reads of every servo. */
        /* a read of the pulled servo alone (focus), or one forced after a
         * read that missed a servo, reads positions, not hardware errors */
        pos_only = a->bus.focus;
        if (pos_only == 0u &&
            (uint8_t)(++a->bus.cycle % APP_GOAL_REFRESH_EVERY) == APP_GOAL_REFRESH_EVERY / 2u) {
            a->bus.goal_due = off_goal(a); /* this cycle refreshes goals instead */
        }
        if (a->bus.goal_due == 0u) { /* otherwise the reads wait for the next cycle */
            pos_only |= a->bus.pos_force;
            addr = DXL_XL430_HW_ERROR_ADDR;
            v = 1;
            txn = APP_TX_HWERR;
            if (a->bus.hwerr_due || (!pos_only && (a->bus.cycle % APP_HWERR_EVERY) == 0u)) {
                a->bus.hwerr_due = 0;
            } else {
                a->bus.pos_force = 0;
                addr = DXL_XL430_PRESENT_POSITION_ADDR;
                v = 4;
                txn = APP_TX_POS;
            }
            if (dxl_fast_sync_read(&a->bus.dxl, addr, v, ids, n) > 0) {
                a->bus.txn = txn;
            }
            return;
        }
        n = 0;
    }
    for (i = 0; i < a->info.n_tendons && n < GOALS_PER_TXN; i++) {
        uint8_t *p = &data[n * 12u];
        if (app_has(a->bus.goal_due, i) == 0u) {
            continue;
        }
        a->bus.goal_due &= (uint16_t)~app_bit16(i);
        if (app_has(a->bus.absent, i)) {
            continue;
        }
        ids[n++] = a->bus.ids[i];
        put32(p, a->bus.acc);
        put32(p + 4, hom_goal_vel(&a->u.hom, i));
        put32(p + 8, (uint32_t)hom_goal(&a->u.hom, i));
    }
    if (n > 0u &&
        dxl_sync_write(&a->bus.dxl, DXL_XL430_PROFILE_ACCELERATION_ADDR, 12u, ids, data, n) > 0) {
        a->bus.txn = APP_TX_GOAL;
    }
}

uint8_t app_bus_goals_now(app_t *a, uint8_t what)
{
    uint8_t ids[APP_MAX_TENDONS];
    uint8_t data[APP_MAX_TENDONS * 4u];
    uint8_t i, n = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        if (app_has(a->bus.goal_due, i)) {
            put32(&data[n * 4u],
                  what != 0u ? (uint32_t)hom_goal(&a->u.hom, i) : hom_goal_vel(&a->u.hom, i));
            ids[n++] = a->bus.ids[i];
        }
    }
    return (uint8_t)(n > 0u && dxl_sync_write(&a->bus.dxl,
                                              what != 0u ? DXL_XL430_GOAL_POSITION_ADDR
                                                         : DXL_XL430_PROFILE_VELOCITY_ADDR,
                                              4u, ids, data, n) > 0);
}

APP_NOINLINE void app_bus_reboot(app_t *a, uint8_t id)
{
    a->bus.reboot_id = id;
    a->bus.reboot_req = APP_REBOOT_WAIT;
}

void app_bus_poll(app_t *a)
{
    if (a->state == APP_ST_BOOT && a->boot.step != 2u) {
        return; /* the bring-up owns the bus */
    }
    if (dxl_busy(&a->bus.dxl)) {
        int8_t rc = dxl_poll(&a->bus.dxl);
        if (rc > 0) {
            return;
        }
        servo_done(a);
    } else if (a->bus.txn != APP_TX_NONE) {
        (void)dxl_poll(&a->bus.dxl);
        servo_done(a);
    }
    if (a->state != APP_ST_BOOT || a->boot.step == 2u) {
        servo_next(a);
    }
}

/* Queues a goal for tendon i. */
APP_NOINLINE void app_bus_goal(app_t *a, uint8_t i, int32_t goal, uint16_t vel, uint16_t acc)
{
    hom_idle_goal(&a->u.hom, i, goal, vel);
    a->bus.acc = acc;
    a->bus.goal_due |= app_bit16(i);
    if (app_has(a->bus.torque_on, i) == 0u) {
        a->bus.torque_on |= app_bit16(i);
        a->bus.torque_due |= app_bit16(i);
    }
}

void app_bus_stop(app_t *a)
{
    dxl_abort(&a->bus.dxl);
    a->bus.txn = APP_TX_NONE;
    a->bus.absent = 0;
    a->bus.goal_again = 0;
    a->bus.torque_on = 0; /* goals of the old frames must never be sent again */
}

APP_NOINLINE uint8_t app_bus_found(app_t *a)
{
    uint8_t i, n = 0;
    a->bus.seen = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        const dxl_servo_info *s = app_boot_servo_info(a, a->bus.ids[i]);
        if (app_has(a->bus.absent, i) == 0u && s != NULL && s->present) {
            n++;
            a->bus.hw_err[i] = s->hw_error;
            if (a->u.bring.result == 0) {
                app_win_t *w = APP_WIN(a);
                if (a->bus.ids[i] == a->bus.reboot_id && w != NULL) {
                    /* A rebooted servo restarts in the turn its shaft stands
                     * in (0..4095), the spool where it was: its engagement
                     * window moves by the whole turns between the position
                     * read before and the one read now (forgotten, it cost
                     * a release: chaos seed 2017). Taken from the position
                     * before the reboot alone, a shaft that crossed a turn
                     * while the reboot went out put the window a turn off
                     * and released 27 mm (seed 5015). */
                    int32_t d = (s->position - a->bus.present[i] + 2048) & ~(int32_t)4095;
                    app_win_set(a, i, w->lo[i] + d, w->hi[i] + d, app_has(w->mask, i));
                }
                a->bus.present[i] = s->position;
                a->bus.seen |= app_bit16(i);
            }
        } else {
            a->bus.absent |= app_bit16(i);
        }
    }
    a->bus.goal_due = 0;
    a->bus.goal_again = 0;
    a->bus.torque_due = 0;
    a->bus.wdog_step = (uint8_t)(2u * a->info.n_tendons);
    /* every servo found has just answered: the silence check starts now,
     * or the first read after a long bring-up rewrites every watchdog again */
    a->bus.t_all_ok = (uint16_t)app_now_ms(a);
    return n;
}

uint8_t app_bus_silent(const app_t *a)
{
    uint8_t i;
    if ((uint16_t)((uint16_t)app_now_ms(a) - a->bus.t_all_ok) < APP_SERVO_SILENT_MS) {
        return 0;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        if (app_has(a->bus.missed, i)) {
            return (uint8_t)(i + 1u);
        }
    }
    return 0;
}

void app_bus_goals_cleared(app_t *a)
{
    a->bus.torque_on = 0; /* nothing to refresh until a goal is set */
}

void app_bus_positions_stale(app_t *a)
{
    a->bus.fresh = 0;
}

void app_bus_inputs(app_t *a, hom_in_t *in)
{
    uint8_t i;
    for (i = 0; i < a->info.n_tendons; i++) {
        hom_servo_in_t *s = &in->servo[i];
        if (app_has(a->bus.absent, i)) {
            s->status = HOM_SERVO_ABSENT;
        } else {
            s->status = app_has(a->bus.fresh, i) ? HOM_SERVO_OK : HOM_SERVO_NOREPLY;
        }
        s->hw_error = a->bus.hw_err[i];
        s->pos = a->bus.present[i];
    }
    a->bus.fresh = 0;
}

APP_NOINLINE void app_bus_take(app_t *a, const hom_out_t *out)
{
    uint8_t i;
    if (out->changed != 0u) { /* the homing's tendons: the table's */
        a->bus.acc = out->acc;
        a->bus.goal_due |= out->changed;
        a->bus.goal_again |= out->changed;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        if (app_has(out->changed, i) &&
            (out->torque[i] != 0u) != (app_has(a->bus.torque_on, i) != 0u)) {
            a->bus.torque_on ^= app_bit16(i);
            a->bus.torque_due |= app_bit16(i);
        }
    }
}
