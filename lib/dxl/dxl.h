/*
 * dxl: non-blocking DYNAMIXEL Protocol 2.0 master for XL430-W250-T servos,
 * over an abstract half-duplex port, plus the bus bring-up sequence.
 *
 * Use: fill a dxl_port, dxl_master_init(), start one transaction (dxl_ping,
 * dxl_read, dxl_sync_read, ...), then call dxl_poll() from the main loop
 * until it stops returning a positive value. Each transaction sends its
 * request, waits for the port to finish sending, collects the status
 * packet(s) against a deadline and retries on timeout or CRC error up to
 * cfg.retries times. The outcome of every servo involved is in m->reply[].
 *
 * The packet codec is in dxl_proto.h, the XL430 control table in
 * dxl_xl430_reg.h.
 *
 * Error convention: 0 = done, negative = -DXL_E_* (dxl_proto.h),
 * positive = still in progress. Time is a free-running uint32_t microsecond
 * count; all comparisons survive its wrap.
 */
#ifndef HALLHOME_DXL_H
#define HALLHOME_DXL_H

#include <stdint.h>

#include "dxl/dxl_proto.h"

/* Servos one transaction can address. */
#ifndef DXL_MAX_IDS
#define DXL_MAX_IDS 12u
#endif
/* Data bytes kept per reply (a read or sync read of more is refused). */
#ifndef DXL_REPLY_DATA
#define DXL_REPLY_DATA 8u
#endif
/* Request buffer: a sync write of 4 bytes to 12 servos needs 74 bytes. */
#ifndef DXL_TX_CAP
#define DXL_TX_CAP 96u
#endif
/* Reply body buffer (INST and the parameters the parser keeps): a fast
 * sync read of 4 bytes from N servos keeps 8 N - 1 (each servo's ERR, ID,
 * data and CRC, less the last CRC, which is the packet's), a single status
 * its data and two bytes. A longer packet (none answers the master's
 * requests) is refused as DXL_E_OVERFLOW. */
#ifndef DXL_RX_CAP
#define DXL_RX_CAP (DXL_MAX_IDS * 8u > DXL_REPLY_DATA + 2u ? DXL_MAX_IDS * 8u : DXL_REPLY_DATA + 2u)
#endif

#define DXL_DIR_RX 0u
#define DXL_DIR_TX 1u

/* The half-duplex port. The master calls set_dir(DXL_DIR_TX) before writing
 * a request; the port itself returns the bus to receive once the last stop
 * bit has left (never earlier: that truncates the byte) and then reports
 * tx_done. All functions must return at once. */
typedef struct {
    void *ctx;
    /* Queues up to n bytes for sending; returns how many were taken (0..n).
     * The board's port (DXL_PORT_FIXED) may send straight from data: the
     * master leaves its request unchanged until tx_done (dxl_abort() waits
     * for it). */
    uint16_t (*write)(void *ctx, const uint8_t *data, uint16_t n);
    /* Copies up to cap received bytes into out; returns how many (0 when none). */
    uint16_t (*read)(void *ctx, uint8_t *out, uint16_t cap);
    /* Drives the bus direction pin (DXL_DIR_TX or DXL_DIR_RX). */
    void (*set_dir)(void *ctx, uint8_t dir);
    /* Nonzero when every queued byte has left and the bus is back in receive. */
    uint8_t (*tx_done)(void *ctx);
    /* Monotonic microsecond clock. */
    uint32_t (*now_us)(void *ctx);
} dxl_port;

/* A firmware with one servo bus builds with -DDXL_PORT_FIXED=1: the master
 * then calls the board's port functions below (the dxl_port contracts
 * without ctx) directly, not through a dxl_port, which it neither keeps nor
 * reads (measured: 254 bytes less AVR code, 12 bytes less RAM). The default, 0, keeps a dxl_port
 * per master, which the native tests fill with their fakes. */
#ifndef DXL_PORT_FIXED
#define DXL_PORT_FIXED 0
#endif
#if DXL_PORT_FIXED
uint16_t dxl_port_write(const uint8_t *data, uint16_t n);
uint16_t dxl_port_read(uint8_t *out, uint16_t cap);
void dxl_port_set_dir(uint8_t dir);
uint8_t dxl_port_tx_done(void);
uint32_t dxl_port_now_us(void);
#endif

typedef struct {
    uint8_t retries;      /* extra attempts after a timeout or CRC error */
    uint16_t byte_us;     /* time of one byte on the wire, rounded up */
    uint16_t timeout_us;  /* allowance per expected reply beyond its bytes
                             (return delay, servo latency, port latency); an
                             attempt whose line stays quiet that long (no
                             first byte after the request, no next byte in a
                             reply) gets nothing more and ends there */
    uint16_t tx_slack_us; /* allowance for the port to finish sending */
} dxl_config;

/* The outcome for one servo of the last transaction. */
typedef struct {
    uint8_t id;
    int8_t result; /* 0, or -DXL_E_TIMEOUT, _CRC, _MALFORMED, _WRONG_ID,
                      _SERVO (data not valid), _ALERT (data valid) */
    uint8_t err;   /* error byte as received */
    uint8_t len;   /* data bytes in data[] */
    uint8_t data[DXL_REPLY_DATA];
} dxl_reply;

typedef struct {
    uint16_t requests;  /* packets sent, retries included */
    uint16_t retries;   /* attempts repeated */
    uint16_t timeouts;  /* attempts that ended on the deadline */
    uint16_t wrong_id;  /* valid status packets from IDs not asked */
    uint16_t malformed; /* valid frames with wrong content */
    uint16_t stale;     /* bytes found waiting before a request (late replies) */
} dxl_master_stats;

typedef struct dxl_master dxl_master;

struct dxl_master {
#if !DXL_PORT_FIXED
    dxl_port port;
#endif
    dxl_config cfg;
    /* the transaction's state before the buffers: within the first 64
     * bytes, which the AVR reaches through the master's pointer with one
     * instruction a byte */
    uint8_t n_reply; /* entries in reply[] for this transaction */
    uint8_t expect;  /* replies the transaction waits for (0: none) */
    uint8_t got;     /* replies settled in this attempt */
    uint8_t phase;
    uint8_t inst;
    uint8_t attempt;
    int8_t attempt_err; /* first transport error seen in this attempt */
    int8_t result;      /* outcome once the transaction is over */
    uint16_t addr;
    uint16_t n; /* data bytes per reply */
    uint16_t tx_len;
    uint16_t tx_sent;
    uint32_t deadline;
    uint32_t heard_by; /* the next reply byte is due by then (see timeout_us) */
    dxl_parser parser;
    dxl_reply reply[DXL_MAX_IDS];
    uint8_t tx[DXL_TX_CAP];
    uint8_t rx[DXL_RX_CAP];
#if DXL_STATS
    dxl_master_stats stats;
#endif
};

/* Defaults for `baud` with `bits_per_byte` (10 on real hardware): 2 retries,
 * byte time rounded up, 1500 us reply allowance (covers the XL430's factory
 * return delay of 500 us), 2000 us send slack. */
void dxl_config_default(dxl_config *cfg, uint32_t baud, uint8_t bits_per_byte);

/* Sets up the master on `port` with `cfg` (both copied; `port` unused with
 * DXL_PORT_FIXED). Never fails. */
void dxl_master_init(dxl_master *m, const dxl_port *port, const dxl_config *cfg);

/* Transactions. Each returns 1 when started (then call dxl_poll()),
 * -DXL_E_BUSY when one is still running, -DXL_E_ARG for bad IDs, counts or
 * lengths (more than DXL_MAX_IDS servos, more than DXL_REPLY_DATA bytes to
 * read), or -DXL_E_NOSPACE when the request does not fit DXL_TX_CAP. Requests
 * to the broadcast ID and sync/bulk writes expect no reply. */
/* Ping one servo (not broadcast); reply data: model number (2 bytes), firmware. */
int8_t dxl_ping(dxl_master *m, uint8_t id);
/* Read n bytes at addr of one servo (not broadcast). */
int8_t dxl_read(dxl_master *m, uint8_t id, uint16_t addr, uint16_t n);
/* Write n bytes to addr; reply without data (none for broadcast). */
int8_t dxl_write(dxl_master *m, uint8_t id, uint16_t addr, const uint8_t *data, uint16_t n);
/* Write of a 1, 2 or 4 byte value, little-endian (other sizes: -DXL_E_ARG). */
int8_t dxl_write_value(dxl_master *m, uint8_t id, uint16_t addr, uint32_t value, uint8_t size);
/* Write held back until an action instruction. */
int8_t dxl_reg_write(dxl_master *m, uint8_t id, uint16_t addr, const uint8_t *data, uint16_t n);
/* Execute registered writes (broadcast allowed). */
int8_t dxl_action(dxl_master *m, uint8_t id);
/* Restart the servo; it answers first, then is away for its boot time. */
int8_t dxl_reboot(dxl_master *m, uint8_t id);
/* Needs guard == DXL_FACTORY_RESET_GUARD, else -DXL_E_GUARD and nothing is
 * sent; mode is DXL_RESET_*. */
int8_t dxl_factory_reset(dxl_master *m, uint8_t id, uint8_t mode, uint32_t guard);
/* Reset the multi-turn count (Present Position back within one turn). */
int8_t dxl_clear_multiturn(dxl_master *m, uint8_t id);
/* Read n bytes at addr from each of ids[0..count): one status packet each, in
 * list order. */
int8_t dxl_sync_read(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids, uint8_t count);
/* Fast sync read (dxl_fast.c): the same request and results as
 * dxl_sync_read(), answered by one combined status packet (needs servo
 * firmware that has the instruction, dxl_proto.h describes the packet); any
 * corruption or a silent servo costs the whole reply. */
int8_t dxl_fast_sync_read(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids,
                          uint8_t count);
/* Write n bytes at addr of each servo: ids[i] gets data[i*n .. i*n+n). No reply. */
int8_t dxl_sync_write(dxl_master *m, uint16_t addr, uint16_t n, const uint8_t *ids,
                      const uint8_t *data, uint8_t count);
/* Read items[i].n bytes at items[i].addr of servo items[i].id, in list order. */
int8_t dxl_bulk_read(dxl_master *m, const dxl_bulk_item *items, uint8_t count);
/* Write items[i].data to each servo's own address. No reply. */
int8_t dxl_bulk_write(dxl_master *m, const dxl_bulk_item *items, uint8_t count);

/* Advances the running transaction. Returns 1 while it runs; 0 when it is
 * over and every reply is good; otherwise the first failing reply's result
 * (-DXL_E_TIMEOUT, -DXL_E_CRC, -DXL_E_MALFORMED, -DXL_E_WRONG_ID,
 * -DXL_E_SERVO, -DXL_E_ALERT) or -DXL_E_PORT when the port did not finish
 * sending. With no transaction started it returns the last outcome (0
 * initially). */
int8_t dxl_poll(dxl_master *m);

/* Nonzero while a transaction runs. */
uint8_t dxl_busy(const dxl_master *m);

/* Abandons the running transaction (the bus goes back to receive); its
 * pending replies get -DXL_E_TIMEOUT. With DXL_PORT_FIXED it first waits
 * until a request being sent has left, within its send deadline. Never
 * fails. */
void dxl_abort(dxl_master *m);

/* The reply entry for `id` in the last transaction, or NULL. */
const dxl_reply *dxl_reply_for(const dxl_master *m, uint8_t id);

/* The first `size` (1, 2 or 4) data bytes of a reply as a sign-extended value
 * (Present Position and Homing Offset are signed). Returns 0 when the reply
 * holds fewer bytes. */
int32_t dxl_reply_value(const dxl_reply *r, uint8_t size);

/* --- bring-up ------------------------------------------------------------------
 * For a list of IDs: ping all (missing IDs are listed), check the model
 * number (others are flagged, not refused), read the hardware error status of
 * servos whose alert bit is set and reboot them only when asked; then, per
 * servo, one read of Return Delay Time..Operating Mode, torque off, Return
 * Delay 0 and Operating Mode 4 (extended position) each written only when the
 * servo holds another value (EEPROM area: every write wears it), profile
 * acceleration and velocity, torque on; finally one sync read of all present
 * positions. A servo already configured gets no EEPROM write. */
typedef struct {
    uint32_t profile_acceleration; /* 214.577 rev/min^2 units */
    uint32_t profile_velocity;     /* 0.229 rpm units */
    uint8_t reboot_on_hw_error;    /* nonzero: reboot servos with a hardware error */
    uint32_t reboot_wait_us;       /* time a rebooting servo needs before it answers */
} dxl_bringup_config;

typedef struct {
    uint8_t id;
    uint8_t present;  /* answered the ping */
    uint8_t alert;    /* the ping reply had the alert bit set */
    uint8_t model_ok; /* model number is DXL_XL430_MODEL_NUMBER */
    uint8_t firmware;
    uint16_t model;
    uint8_t hw_error; /* Hardware Error Status last read (0 when none) */
    uint8_t rebooted;
    int32_t position;      /* Present Position after bring-up */
    uint8_t return_delay;  /* Return Delay Time as read before configuration */
    uint8_t mode;          /* Operating Mode as read before configuration */
    uint8_t eeprom_writes; /* EEPROM-area writes this bring-up made (0..2) */
} dxl_servo_info;

typedef struct {
    dxl_master *m;
    dxl_bringup_config cfg;
    dxl_servo_info servo[DXL_MAX_IDS];
    uint8_t n;
    uint8_t missing[DXL_MAX_IDS]; /* IDs that did not answer, in list order */
    uint8_t n_missing;
    uint8_t n_wrong_model; /* servos whose model number is not 1060 */
    uint8_t step;
    uint8_t index;
    uint8_t sub;
    int8_t result;
    uint32_t wait_until;
} dxl_bringup;

/* Starts bring-up of ids[0..count) on master m (which must be idle). Returns
 * 1, -DXL_E_ARG (count 0 or above DXL_MAX_IDS, an ID above 252) or
 * -DXL_E_BUSY. */
int8_t dxl_bringup_start(dxl_bringup *b, dxl_master *m, const uint8_t *ids, uint8_t count,
                         const dxl_bringup_config *cfg);

/* Advances bring-up. Returns 1 while running, 0 when every servo is set up and
 * its position read, -DXL_E_MISSING (see missing[]), -DXL_E_HW_ERROR (a
 * servo's hw_error is nonzero and reboot was not asked or did not clear it),
 * or the transport error of a configuration step. */
int8_t dxl_bringup_poll(dxl_bringup *b);

#endif /* HALLHOME_DXL_H */
