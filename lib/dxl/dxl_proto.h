/*
 * dxl_proto: the DYNAMIXEL Protocol 2.0 codec. No I/O: it turns requests
 * into bytes in a caller-supplied buffer and turns received bytes, one at a
 * time, into packets. Both the master (dxl.h) and the servo model in sim/
 * use it.
 *
 * Packet layout (ROBOTIS e-manual, Protocol 2.0, "Instruction Packet" and
 * "Status Packet"):
 *
 *   FF FF FD 00 ID LEN_L LEN_H INST PARAM... CRC_L CRC_H
 *
 * LEN counts INST, the parameters and the CRC, after byte stuffing; a status
 * packet has INST 0x55 followed by the error byte. Byte stuffing (e-manual,
 * "Byte Stuffing"): wherever FF FF FD occurs in INST and the parameters, an
 * extra FD is sent after it. The CRC (e-manual, "CRC"; polynomial 0x8005,
 * initial value 0, no reflection) covers every byte sent from the first FF up
 * to the last parameter, stuffing included.
 *
 * Error convention: 0 = done, negative = -DXL_E_* (enum dxl_err below),
 * positive = still in progress.
 */
#ifndef HALLHOME_DXL_PROTO_H
#define HALLHOME_DXL_PROTO_H

#include <stdint.h>

/* Error codes of the whole dxl module; functions return their negation. */
enum dxl_err {
    DXL_OK = 0,
    DXL_E_ARG = 1,       /* argument out of range (ID, count, length) */
    DXL_E_NOSPACE = 2,   /* caller buffer too small for the packet */
    DXL_E_GUARD = 3,     /* factory reset asked without DXL_FACTORY_RESET_GUARD */
    DXL_E_CRC = 4,       /* received CRC does not match */
    DXL_E_LENGTH = 5,    /* LEN field below the minimum or beyond any buffer */
    DXL_E_OVERFLOW = 6,  /* packet body larger than the parser buffer */
    DXL_E_TRUNCATED = 7, /* a new header began before the packet ended */
    DXL_E_MALFORMED = 8, /* valid frame, wrong content (not a status, bad size) */
    DXL_E_TIMEOUT = 9,   /* no (complete) reply before the deadline */
    DXL_E_WRONG_ID = 10, /* only replies from other IDs arrived */
    DXL_E_SERVO = 11,    /* servo error number (error byte bits 6:0) nonzero */
    DXL_E_ALERT = 12,    /* alert bit set: the servo has a hardware error */
    DXL_E_BUSY = 13,     /* a transaction is already running */
    DXL_E_PORT = 14,     /* the port did not finish sending before its deadline */
    DXL_E_MISSING = 15,  /* bring-up: at least one ID did not answer */
    DXL_E_HW_ERROR = 16  /* bring-up: hardware error status nonzero */
};

/* Instructions (e-manual, "Instruction Details"). */
#define DXL_INST_PING           0x01u
#define DXL_INST_READ           0x02u
#define DXL_INST_WRITE          0x03u
#define DXL_INST_REG_WRITE      0x04u
#define DXL_INST_ACTION         0x05u
#define DXL_INST_FACTORY_RESET  0x06u
#define DXL_INST_REBOOT         0x08u
#define DXL_INST_CLEAR          0x10u
#define DXL_INST_STATUS         0x55u
#define DXL_INST_SYNC_READ      0x82u
#define DXL_INST_SYNC_WRITE     0x83u
#define DXL_INST_FAST_SYNC_READ 0x8Au
#define DXL_INST_BULK_READ      0x92u
#define DXL_INST_BULK_WRITE     0x93u

#define DXL_BROADCAST_ID 0xFEu
#define DXL_MAX_ID       0xFCu /* 252 */

/* Status error byte (e-manual, "Status Packet", Error field). */
#define DXL_ERR_ALERT       0x80u
#define DXL_ERR_NUMBER_MASK 0x7Fu
#define DXL_ERR_RESULT_FAIL 0x01u
#define DXL_ERR_INSTRUCTION 0x02u
#define DXL_ERR_CRC         0x03u
#define DXL_ERR_DATA_RANGE  0x04u
#define DXL_ERR_DATA_LENGTH 0x05u
#define DXL_ERR_DATA_LIMIT  0x06u
#define DXL_ERR_ACCESS      0x07u

/* Factory reset parameter (e-manual, "Factory Reset"). */
#define DXL_RESET_ALL              0xFFu
#define DXL_RESET_KEEP_ID          0x01u
#define DXL_RESET_KEEP_ID_AND_BAUD 0x02u
/* The value the guard argument of a factory reset must carry ("RSET"). */
#define DXL_FACTORY_RESET_GUARD 0x52534554UL

/* Clear instruction, multi-turn option and its fixed key (e-manual, "Clear"). */
#define DXL_CLEAR_MULTITURN 0x01u

/* CRC of the header FF FF FD 00, where every packet's CRC starts. */
#define DXL_CRC_HEADER 0x0E28u

/* Bytes of a packet without parameters: header 4, ID, LEN 2, INST, CRC 2. */
#define DXL_PACKET_OVERHEAD 10u

/* CRC-16 over `n` bytes continuing from `crc` (start with 0). Returns the
 * updated CRC. Never fails. */
uint16_t dxl_crc16(uint16_t crc, const uint8_t *data, uint16_t n);

/* One byte of the CRC; same as dxl_crc16() with n = 1. */
uint16_t dxl_crc16_byte(uint16_t crc, uint8_t byte);

/* --- instruction packet builder ---------------------------------------------
 * A writer assembles one packet in a caller buffer: begin, put parameters,
 * end. Stuffing is applied as bytes are put; LEN and CRC are filled in by
 * dxl_writer_end(). Putting past the capacity is remembered, not written. */
typedef struct {
    uint8_t *buf;
    uint16_t cap;
    uint16_t pos;
    uint8_t run;      /* FF FF pattern progress for stuffing */
    uint8_t overflow; /* nonzero once a byte did not fit */
} dxl_writer;

/* Starts a packet for `id` with instruction `inst` in buf[0..cap). Never fails
 * (a too-small buffer is reported by dxl_writer_end()). */
void dxl_writer_begin(dxl_writer *w, uint8_t *buf, uint16_t cap, uint8_t id, uint8_t inst);

/* Appends one parameter byte (stuffed when needed). */
void dxl_writer_put(dxl_writer *w, uint8_t byte);

/* Appends `size` (1, 2 or 4) bytes of `value`, little-endian. */
void dxl_writer_put_le(dxl_writer *w, uint32_t value, uint8_t size);

/* Finishes the packet: writes LEN and CRC. Stores the total packet length in
 * *len. Returns 0, or -DXL_E_NOSPACE when the packet did not fit in cap (then
 * *len is 0). */
int8_t dxl_writer_end(dxl_writer *w, uint16_t *len);

/* Builders for every instruction. Each writes a complete packet into
 * buf[0..cap) and its length into *len. Each returns 0, -DXL_E_NOSPACE when
 * cap is too small, or -DXL_E_ARG when an argument is out of range (IDs above
 * 252 where a single servo is meant; zero counts; data lengths of 0). */
int8_t dxl_build_ping(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len);
int8_t dxl_build_read(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr, uint16_t n,
                      uint16_t *len);
/* Write and reg write: `n` data bytes from `data` to `addr`. `id` may be broadcast. */
int8_t dxl_build_write(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr, const uint8_t *data,
                       uint16_t n, uint16_t *len);
int8_t dxl_build_reg_write(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t addr,
                           const uint8_t *data, uint16_t n, uint16_t *len);
/* Action, reboot: `id` may be broadcast. */
int8_t dxl_build_action(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len);
int8_t dxl_build_reboot(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len);
/* Factory reset: `mode` is DXL_RESET_*; `guard` must be DXL_FACTORY_RESET_GUARD,
 * otherwise -DXL_E_GUARD and nothing is written. Also -DXL_E_ARG for an
 * unknown mode. */
int8_t dxl_build_factory_reset(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t mode, uint32_t guard,
                               uint16_t *len);
/* Clear the multi-turn count (Present Position back within one turn). */
int8_t dxl_build_clear_multiturn(uint8_t *buf, uint16_t cap, uint8_t id, uint16_t *len);
/* Sync read (dxl_proto.c) / fast sync read (dxl_fast.c) of `n` bytes at
 * `addr` from `count` servos; dxl_build_group_read() builds either, `inst`
 * being DXL_INST_SYNC_READ or DXL_INST_FAST_SYNC_READ (the two differ only in
 * the instruction byte). */
int8_t dxl_build_group_read(uint8_t *buf, uint16_t cap, uint8_t inst, uint16_t addr, uint16_t n,
                            const uint8_t *ids, uint8_t count, uint16_t *len);
int8_t dxl_build_sync_read(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                           const uint8_t *ids, uint8_t count, uint16_t *len);
int8_t dxl_build_fast_sync_read(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                                const uint8_t *ids, uint8_t count, uint16_t *len);
/* Sync write: servo ids[i] gets data[i*n .. i*n+n). */
int8_t dxl_build_sync_write(uint8_t *buf, uint16_t cap, uint16_t addr, uint16_t n,
                            const uint8_t *ids, const uint8_t *data, uint8_t count, uint16_t *len);

/* One servo's part of a bulk read or bulk write (data unused for reads). */
typedef struct {
    uint8_t id;
    uint16_t addr;
    uint16_t n;
    const uint8_t *data;
} dxl_bulk_item;

int8_t dxl_build_bulk_read(uint8_t *buf, uint16_t cap, const dxl_bulk_item *items, uint8_t count,
                           uint16_t *len);
int8_t dxl_build_bulk_write(uint8_t *buf, uint16_t cap, const dxl_bulk_item *items, uint8_t count,
                            uint16_t *len);

/* Builds a status packet (INST 0x55, then `err`, then `n` parameters): what a
 * servo sends. Used by the servo model and by tests. Returns 0,
 * -DXL_E_NOSPACE or -DXL_E_ARG (id above 253). */
int8_t dxl_build_status(uint8_t *buf, uint16_t cap, uint8_t id, uint8_t err, const uint8_t *params,
                        uint16_t n, uint16_t *len);

/* The counters of the parser and the master (dxl_parser.stats,
 * dxl_master.stats) are kept unless this is 0: the firmware, which reports
 * none of them, builds with -DDXL_STATS=0 (24 bytes of RAM and the code that
 * counts). */
#ifndef DXL_STATS
#define DXL_STATS 1
#endif
#if DXL_STATS
#define DXL_COUNT(x) ((void)(x))
#else
#define DXL_COUNT(x) ((void)0)
#endif

/* --- packet parser ------------------------------------------------------------
 * Fed one byte at a time. Finds the header (skipping anything before it),
 * checks the reserved byte, LEN and CRC, removes stuffing and stores INST and
 * the parameters in the caller's buffer. A header inside a packet (FF FF FD
 * not followed by the stuffing FD) ends that packet as truncated and starts
 * the new one, so a cut-off reply never swallows the next packet; when the
 * cut falls so close to the end that the new header overlaps the CRC, the
 * CRC error is reported and the last raw bytes are searched again for it. */
typedef struct {
    uint16_t garbage;   /* bytes skipped while looking for a header */
    uint16_t crc;       /* packets dropped for a CRC mismatch */
    uint16_t length;    /* packets dropped for an impossible LEN */
    uint16_t overflow;  /* packets dropped because the body did not fit */
    uint16_t truncated; /* packets cut short by a new header */
    uint16_t packets;   /* packets accepted */
} dxl_parse_stats;

typedef struct {
    uint8_t *buf; /* INST then parameters, unstuffed */
    uint16_t cap;
    uint16_t body_len; /* bytes in buf once a packet is complete */
    uint16_t remaining;
    uint16_t crc;
    uint16_t rx_crc;
    uint8_t id;
    uint8_t state;
    uint8_t run;     /* FF FF FD pattern progress inside the body */
    uint8_t raw;     /* nonzero: no unstuffing (fast sync read replies) */
    uint8_t tail[4]; /* last raw body bytes, searched again after a CRC error */
    uint8_t tail_n;
    /* Fast sync read replies (raw mode): with `block` set to n + 4, the
     * running CRC at the end of each block's data is compared with the
     * block's CRC field as the bytes arrive; bit i of blk_ok is set when
     * block i matched, blk_n counts the blocks whose CRC field has arrived
     * (the last block's field is the packet CRC, checked as usual). */
    uint16_t block;
    uint16_t blk_pos;
    uint16_t blk_crc;
    uint16_t blk_ok;
    uint8_t blk_n;
#if DXL_STATS
    dxl_parse_stats stats;
#endif
} dxl_parser;

/* Prepares a parser that stores packet bodies in buf[0..cap). Statistics start at 0. */
void dxl_parser_init(dxl_parser *p, uint8_t *buf, uint16_t cap);

/* Drops any partial packet (statistics are kept) and returns to header search. */
void dxl_parser_reset(dxl_parser *p);

/* Selects raw mode (nonzero: bytes are taken as sent, no unstuffing and no
 * header detection inside the body) for packets whose senders do not stuff,
 * i.e. the combined fast sync read reply. Takes effect at the next packet. */
void dxl_parser_set_raw(dxl_parser *p, uint8_t raw);

/* Feeds one received byte. Returns 1 while more bytes are needed, 0 when a
 * complete packet with a good CRC is in the parser (read it with the
 * accessors below before feeding the next byte), or a negative error for a
 * packet just dropped: -DXL_E_CRC, -DXL_E_LENGTH, -DXL_E_OVERFLOW,
 * -DXL_E_TRUNCATED. After an error the parser is already looking for the next
 * header; each error is also counted in stats. */
int8_t dxl_parser_feed(dxl_parser *p, uint8_t byte);

/* A parsed status packet, pointing into the parser buffer. */
typedef struct {
    uint8_t id;
    uint8_t err;
    const uint8_t *params;
    uint16_t n;
} dxl_status;

/* Views the packet just completed as a status packet. Returns 0, or
 * -DXL_E_MALFORMED when it is not a status packet (INST not 0x55 or no error
 * byte). */
int8_t dxl_parser_status(const dxl_parser *p, dxl_status *st);

/* --- fast sync read reply (dxl_fast.c) --------------------------------------------
 * One status packet from ID 0xFE carries every servo's answer (e-manual,
 * Protocol 2.0, "Fast Sync Read"): after INST 0x55 come, per servo in the
 * request's ID order, a block of ERR, ID, the `n` data bytes and a 2-byte CRC
 * field; the last block's CRC field is the packet's own CRC. The first
 * servo sends the header, each one appends its block, the last one the CRC;
 * nobody stuffs (parse it in raw mode, dxl_parser_set_raw()). ROBOTIS's SDK
 * checks only the packet CRC; the master checks every block's own CRC field
 * as well (see dxl_fast.c for why). A servo that does not answer breaks the
 * chain: the packet never completes. Each block's CRC field holds the CRC of
 * the packet from its first FF to the end of that block's data (the last
 * one is thus the packet CRC), so each block can be checked on its own: the
 * parser does it as the bytes arrive (dxl_parser.block, blk_ok). */
typedef struct {
    uint8_t err;
    uint8_t id;
    const uint8_t *data; /* `n` bytes, pointing into the parser buffer */
} dxl_fast_block;

/* Views block `i` (0-based) of a fast sync read reply `st` (from
 * dxl_parser_status()) that answers a request for `n` bytes from `count`
 * servos. Returns 0, or -DXL_E_MALFORMED when `st` is not such a reply (not
 * from the broadcast ID, or its length is not exactly `count` blocks) or
 * i >= count. */
int8_t dxl_fast_block_at(const dxl_status *st, uint16_t n, uint8_t count, uint8_t i,
                         dxl_fast_block *b);

/* Little-endian value of `size` (1, 2 or 4) bytes at p. */
uint32_t dxl_get_le(const uint8_t *p, uint8_t size);

/* Writes `value` as `size` (1, 2 or 4) little-endian bytes at p. */
void dxl_put_le(uint8_t *p, uint32_t value, uint8_t size);

#endif /* HALLHOME_DXL_PROTO_H */
