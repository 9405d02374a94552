/*
 * dxl_priv: what the files of the master share and nothing else. Users of
 * the master include dxl.h only.
 *
 *   dxl.c          the transaction engine (attempts, replies settled per
 *                  servo, retries, deadlines, dxl_poll(), the results) and
 *                  the requests that start a transaction (dxl_ping() ...
 *                  dxl_bulk_write())
 *   dxl_bringup.c  the servo bring-up (dxl_bringup_start/_poll)
 *   dxl_fast.c     fast sync read: request, view of its combined reply, the
 *                  master's handler for it
 *
 * dxl.c and dxl_bringup.c each define the small dxl_time_reached() as a
 * static function of their own, where dxl.c had it: as a static inline of
 * this header, it changed the order of the firmware's functions (one LTO
 * unit) and with it the main loop's timing, to which the bench's fault
 * scenarios are sensitive (measured). The requests stay in dxl.c for the
 * same reason: in a file of their own, linked after dxl_bringup.c,
 * dxl_write_value() was inlined into its callers (80 bytes less flash, but
 * other code).
 */
#ifndef HALLHOME_DXL_PRIV_H
#define HALLHOME_DXL_PRIV_H

#include "dxl/dxl.h"

/* Constant tables live in program memory on the AVR, where a const array
 * would otherwise be copied to RAM at start-up; reading them takes
 * pgm_read_byte/_word (avr-libc), the one AVR header lib/dxl needs. */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define DXL_FLASH            PROGMEM
#define DXL_FLASH_BYTE(addr) pgm_read_byte(addr)
#define DXL_FLASH_WORD(addr) pgm_read_word(addr)
#else
#define DXL_FLASH
#define DXL_FLASH_BYTE(addr) (*(addr))
#define DXL_FLASH_WORD(addr) (*(addr))
#endif

/* Functions that measured smaller on the AVR as calls than inlined into their
 * callers (the packet set-up, the reply bookkeeping, the parser's reset and
 * rescan, the bring-up's end). */
#if defined(__GNUC__)
#define DXL_NOINLINE __attribute__((noinline))
#else
#define DXL_NOINLINE
#endif

/* The port's functions, called on master m (dxl.h, DXL_PORT_FIXED). */
#if DXL_PORT_FIXED
#define DXL_PORT_WRITE(m, data, n) ((void)(m), dxl_port_write(data, n))
#define DXL_PORT_READ(m, out, cap) ((void)(m), dxl_port_read(out, cap))
#define DXL_PORT_SET_DIR(m, dir)   ((void)(m), dxl_port_set_dir(dir))
#define DXL_PORT_TX_DONE(m)        ((void)(m), dxl_port_tx_done())
#define DXL_PORT_NOW_US(m)         ((void)(m), dxl_port_now_us())
#else
#define DXL_PORT_WRITE(m, data, n) (m)->port.write((m)->port.ctx, data, n)
#define DXL_PORT_READ(m, out, cap) (m)->port.read((m)->port.ctx, out, cap)
#define DXL_PORT_SET_DIR(m, dir)   (m)->port.set_dir((m)->port.ctx, dir)
#define DXL_PORT_TX_DONE(m)        (m)->port.tx_done((m)->port.ctx)
#define DXL_PORT_NOW_US(m)         (m)->port.now_us((m)->port.ctx)
#endif

/* Starts a sync read or fast sync read (`inst`); same returns as
 * dxl_sync_read(). */
int8_t dxl_group_read(dxl_master *m, uint8_t inst, uint16_t addr, uint16_t n, const uint8_t *ids,
                      uint8_t count);

/* The pending reply entry of `id`, or NULL: an ID never asked is counted and
 * noted as -DXL_E_WRONG_ID; an ID already answered is ignored. */
dxl_reply *dxl_claim(dxl_master *m, uint8_t id);

/* Stores a servo's answer in `r` and sets its result from the error byte. */
void dxl_settle(dxl_master *m, dxl_reply *r, uint8_t err, const uint8_t *data, uint8_t n);

/* Notes the first transport error of the attempt (kept as its result). */
void dxl_note(dxl_master *m, int8_t err);

/* Counts and notes a valid frame with the wrong content (-DXL_E_MALFORMED). */
void dxl_malformed(dxl_master *m);

/* The reply handler of a fast sync read (m->inst), whose answer is one
 * packet of blocks rather than one status packet per servo. Called with st
 * NULL when an attempt ends on a corrupted packet or its deadline, to take
 * what can be trusted of a partial one. */
void dxl_fast_on_status(dxl_master *m, const dxl_status *st);

#endif /* HALLHOME_DXL_PRIV_H */
