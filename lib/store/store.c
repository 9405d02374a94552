#include "store/store.h"

#include <string.h>

#define ST_IDLE   0u
#define ST_WRITE  1u
#define ST_VERIFY 2u

/* Writes skipped because the EEPROM already holds the byte cost nothing, so
 * one poll may pass this many of them before returning. */
#define STORE_SKIP_BUDGET 32u

#define STORE_NO_HEAD 0xFFu

/* Functions that measured smaller on the AVR as calls than inlined into their
 * callers (a record's write set-up, the history slots' checks, a home's
 * entry, a position's recovery, a learned record's address). */
#if defined(__GNUC__)
#define STORE_NOINLINE __attribute__((noinline))
#else
#define STORE_NOINLINE
#endif

/* ---- layout checks (compile time; C99 has no _Static_assert) ----- */

#define STORE_ASSERT(name, cond) typedef char store_assert_##name[(cond) ? 1 : -1]

STORE_ASSERT(homes_size, sizeof(store_homes_t) == 184u);
STORE_ASSERT(learned_size, sizeof(store_learned_t) == 32u);
STORE_ASSERT(hist_size, sizeof(store_hist_t) == 64u);
STORE_ASSERT(win_size, sizeof(store_win_t) == 80u);
STORE_ASSERT(settings_fit, STORE_SETTING_COUNT <= STORE_SETTING_MAX &&
                               STORE_SLOT_LEN(4u * STORE_SETTING_MAX) <= STORE_SETTINGS_STRIDE);
STORE_ASSERT(homes_fit, STORE_SLOT_LEN(sizeof(store_homes_t)) <= STORE_HOMES_STRIDE);
STORE_ASSERT(learned_fit, STORE_SLOT_LEN(sizeof(store_learned_t)) <= STORE_LEARNED_STRIDE);
STORE_ASSERT(hist_fit, STORE_SLOT_LEN(sizeof(store_hist_t)) <= STORE_HIST_STRIDE);
STORE_ASSERT(win_fit, STORE_SLOT_LEN(sizeof(store_win_t)) <= STORE_WIN_STRIDE);
STORE_ASSERT(order1, STORE_ADDR_SETTINGS + 2u * STORE_SETTINGS_STRIDE <= STORE_ADDR_HOMES);
STORE_ASSERT(order2, STORE_ADDR_HOMES + 2u * STORE_HOMES_STRIDE <= STORE_ADDR_LEARNED);
STORE_ASSERT(order3,
             STORE_ADDR_LEARNED + 2u * STORE_MAX_TENDONS * STORE_LEARNED_STRIDE <= STORE_ADDR_HIST);
STORE_ASSERT(order4, STORE_ADDR_END <= STORE_EEPROM_SIZE);
STORE_ASSERT(hist_min, STORE_HIST_N >= 16u && STORE_HIST_N < STORE_NO_HEAD && STORE_HIST_N <= 127u);
STORE_ASSERT(table_id_first, offsetof(store_homes_t, table_id) == 0u &&
                                 offsetof(store_win_t, table_id) == 0u &&
                                 offsetof(store_learned_t, table_id) == 0u);
STORE_ASSERT(tendon_mask, STORE_MAX_TENDONS <= 16u && TBL_MAX_GRID <= 16u);

/* ---- settings declaration ---------------------------------------- */

#define STORE_TMIN_U8  0
#define STORE_TMAX_U8  255
#define STORE_TMIN_U16 0
#define STORE_TMAX_U16 65535L
#define STORE_TMIN_U32 0
#define STORE_TMAX_U32 2147483647L /* stored as int32_t */
#define STORE_TMIN_I32 (-2147483647L - 1)
#define STORE_TMAX_I32 2147483647L

/* Every declared range must fit its type and hold its default. */
#define STORE_SETTING(id, name, type, min, max, def, unit, help)                                   \
    STORE_ASSERT(decl_##id, (min) >= STORE_TMIN_##type && (max) <= STORE_TMAX_##type &&            \
                                (min) <= (def) && (def) <= (max));
#include "store/store_settings.def"
#undef STORE_SETTING

static const store_setting_info_t store_decl[STORE_SETTING_COUNT] STORE_FLASH = {
#define STORE_SETTING(id, name, type, min, max, def, unit, help)                                   \
    {(int32_t)(min), (int32_t)(max), (int32_t)(def), STORE_T_##type},
#include "store/store_settings.def"
#undef STORE_SETTING
};

/* name, unit and help of every setting, in declaration order, NUL-separated:
 * one flash string instead of 3 * N pointers. */
#if STORE_SETTING_HELP
#define STORE_HELP_TEXT(help)       help "\0"
#define STORE_HELP_MEMBER(id, help) char h_##id[sizeof(help)];
#define STORE_TEXTS                 3u
#else
#define STORE_HELP_TEXT(help)
#define STORE_HELP_MEMBER(id, help)
#define STORE_TEXTS 2u
#endif
static const char store_text[] STORE_FLASH =
#define STORE_SETTING(id, name, type, min, max, def, unit, help)                                   \
    name "\0" unit "\0" STORE_HELP_TEXT(help)
#include "store/store_settings.def"
#undef STORE_SETTING
    ;

/* The same strings as members of a struct (of chars: no padding): offsetof()
 * says at compile time where each setting's texts start in store_text. */
typedef struct {
#define STORE_SETTING(id, name, type, min, max, def, unit, help)                                   \
    char n_##id[sizeof(name)];                                                                     \
    char u_##id[sizeof(unit)];                                                                     \
    STORE_HELP_MEMBER(id, help)
#include "store/store_settings.def"
#undef STORE_SETTING
} store_text_layout_t;

static const uint16_t store_text_at[STORE_SETTING_COUNT] STORE_FLASH = {
#define STORE_SETTING(id, name, type, min, max, def, unit, help)                                   \
    (uint16_t) offsetof(store_text_layout_t, n_##id),
#include "store/store_settings.def"
#undef STORE_SETTING
};

/* ---- CRC --------------------------------------------------------- */

/* CRC-16/CCITT (0x1021) a byte at a time without a table: the eight shifts
 * of the bitwise form reduce to x = top byte ^ b, x ^= x >> 4 and three
 * shifted copies of x (about 8x faster on the AVR, where the bitwise loop
 * cost half a millisecond per 100-byte record or window check). */
static uint16_t crc_byte(uint16_t crc, uint8_t b)
{
    uint8_t x = (uint8_t)((crc >> 8) ^ b);
    x ^= (uint8_t)(x >> 4);
    return (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
}

uint16_t store_crc16(uint16_t crc, const void *data, size_t n)
{
    const uint8_t *p = (const uint8_t *)data;
    while (n--) {
        crc = crc_byte(crc, *p++);
    }
    return crc;
}

/* ---- slots ------------------------------------------------------- */

/* The EEPROM's functions, called for store st (store.h, STORE_EE_FIXED). */
#if STORE_EE_FIXED
#define EE_READ_BYTE(st, addr)          ((void)(st), store_ee_read_byte(addr))
#define EE_READ_BLOCK(st, dst, addr, n) ((void)(st), store_ee_read_block(dst, addr, n))
#define EE_READY(st)                    ((void)(st), store_ee_ready())
#define EE_WRITE_BYTE(st, addr, v)      ((void)(st), store_ee_write_byte(addr, v))
#else
#define EE_READ_BYTE(st, addr)          (st)->ee->read_byte((st)->ee->ctx, addr)
#define EE_READ_BLOCK(st, dst, addr, n) (st)->ee->read_block((st)->ee->ctx, dst, addr, n)
#define EE_READY(st)                    (st)->ee->ready((st)->ee->ctx)
#define EE_WRITE_BYTE(st, addr, v)      (st)->ee->write_byte((st)->ee->ctx, addr, v)
#endif

/* An EEPROM byte, and a little-endian word: one call through the port's
 * function pointer here instead of one at every read. */
STORE_NOINLINE static uint8_t ee_byte(const store_t *st, uint16_t addr)
{
    return EE_READ_BYTE(st, addr);
}

STORE_NOINLINE static uint16_t ee_word(const store_t *st, uint16_t addr)
{
    uint16_t lo = ee_byte(st, addr);
    return (uint16_t)(lo | ((uint16_t)ee_byte(st, (uint16_t)(addr + 1u)) << 8));
}

/* A slot is valid when kind and version match and the CRC over header and
 * body agrees; its sequence number goes to *seq. */
static uint8_t slot_valid(const store_t *st, uint16_t addr, uint8_t kind, uint8_t ver, uint16_t len,
                          uint16_t *seq)
{
    uint16_t crc = 0xFFFFu;
    uint16_t i;
    if (ee_byte(st, addr) != kind || ee_byte(st, (uint16_t)(addr + 1u)) != ver) {
        return 0;
    }
    for (i = 0; i < STORE_HDR_LEN + len; i++) {
        crc = crc_byte(crc, ee_byte(st, (uint16_t)(addr + i)));
    }
    if (ee_word(st, (uint16_t)(addr + i)) != crc) {
        return 0;
    }
    *seq = ee_word(st, (uint16_t)(addr + 2u));
    return 1;
}

/* a is newer than b in serial-number arithmetic (the counter wraps). */
static uint8_t seq_newer(uint16_t a, uint16_t b)
{
    return (int16_t)(uint16_t)(a - b) > 0;
}

/* Index of the newest valid slot of the n at base, base + stride, ... (the
 * first of slots with the same sequence number), or -1 when none is valid;
 * its sequence number goes to *seq, which is left alone when none is. */
static int8_t slot_newest(const store_t *st, uint16_t base, uint16_t stride, uint8_t n,
                          uint8_t kind, uint8_t ver, uint16_t len, uint16_t *seq)
{
    int8_t newest = -1;
    uint8_t i;
    uint16_t s;
    for (i = 0; i < n; i++) {
        if (slot_valid(st, (uint16_t)(base + i * stride), kind, ver, len, &s) &&
            (newest < 0 || seq_newer(s, *seq))) {
            newest = (int8_t)i;
            *seq = s;
        }
    }
    return newest;
}

/* Index (0 = A at base, 1 = B at base + stride) of the newest valid copy of a
 * two-slot record (A when both have the same sequence number), or -1; its
 * sequence number goes to *seq. */
static int8_t pair_pick(const store_t *st, uint16_t base, uint16_t stride, uint8_t kind,
                        uint8_t ver, uint16_t len, uint16_t *seq)
{
    return slot_newest(st, base, stride, 2u, kind, ver, len, seq);
}

static int8_t pair_load(store_t *st, uint16_t base, uint16_t stride, uint8_t kind, uint8_t ver,
                        void *body, uint16_t len)
{
    uint16_t seq;
    int8_t which = pair_pick(st, base, stride, kind, ver, len, &seq);
    if (which < 0) {
        return STORE_E_EMPTY;
    }
    EE_READ_BLOCK(st, body, (uint16_t)(base + (which ? stride : 0u) + STORE_HDR_LEN), len);
    return 0;
}

/* pair_load() of a record whose body starts with the table_id it was made
 * for: STORE_E_OTHER_TABLE (body filled) when that is not table_id. */
static int8_t pair_load_table(store_t *st, uint16_t base, uint16_t stride, uint8_t kind,
                              uint8_t ver, void *body, uint16_t len, uint32_t table_id)
{
    uint32_t id;
    int8_t rc = pair_load(st, base, stride, kind, ver, body, len);
    if (rc == 0) {
        memcpy(&id, body, sizeof id);
        if (id != table_id) {
            rc = STORE_E_OTHER_TABLE;
        }
    }
    return rc;
}

STORE_NOINLINE static int8_t save_begin(store_t *st, uint16_t addr, uint8_t kind, uint8_t ver,
                                        uint16_t seq, const void *body, uint16_t len)
{
    st->addr = addr;
    st->len = len;
    st->body = (const uint8_t *)body;
    st->pos = 0;
    st->crc = crc_byte(0xFFFFu, kind); /* the kind byte is written last but checked first */
    st->hdr[0] = kind;
    st->hdr[1] = ver;
    st->hdr[2] = (uint8_t)seq;
    st->hdr[3] = (uint8_t)(seq >> 8);
    st->state = ST_WRITE;
    return 1;
}

/* Saves a two-slot record into the slot that does not hold the newest valid
 * copy, so that copy survives whatever happens to this write. */
static int8_t pair_save(store_t *st, uint16_t base, uint16_t stride, uint8_t kind, uint8_t ver,
                        const void *body, uint16_t len)
{
    uint16_t seq = 0;
    int8_t which;
    if (st->state != ST_IDLE) {
        return STORE_E_BUSY;
    }
    which = pair_pick(st, base, stride, kind, ver, len, &seq);
    return save_begin(st, (uint16_t)(base + (which == 0 ? stride : 0u)), kind, ver,
                      (uint16_t)(seq + 1u), body, len);
}

STORE_NOINLINE static uint8_t hist_slot_valid(const store_t *st, uint8_t i, uint16_t *seq)
{
    return slot_valid(st, (uint16_t)(STORE_ADDR_HIST + i * STORE_HIST_STRIDE), STORE_KIND_HIST,
                      STORE_HIST_VERSION, (uint16_t)sizeof(store_hist_t), seq);
}

static void hist_scan(store_t *st)
{
    int8_t head = slot_newest(st, STORE_ADDR_HIST, STORE_HIST_STRIDE, STORE_HIST_N, STORE_KIND_HIST,
                              STORE_HIST_VERSION, (uint16_t)sizeof(store_hist_t), &st->hist_seq);
    st->hist_head = head < 0 ? STORE_NO_HEAD : (uint8_t)head;
}

/* ---- public ------------------------------------------------------ */

int8_t store_init(store_t *st, const store_eeprom_t *ee, store_copy_fn copy)
{
    memset(st, 0, sizeof(*st));
#if STORE_EE_FIXED
    (void)ee;
#else
    st->ee = ee;
#endif
    st->copy = copy;
    st->state = ST_IDLE;
    hist_scan(st);
    return 0;
}

uint8_t store_busy(const store_t *st)
{
    return st->state != ST_IDLE;
}

int8_t store_poll(store_t *st, uint8_t may_write)
{
    uint16_t total = (uint16_t)(STORE_HDR_LEN + st->len + STORE_CRC_LEN);
    uint16_t seq, i;
    uint8_t n, b, ok;
    if (st->state == ST_IDLE) {
        return STORE_E_IDLE;
    }
    if (!may_write || !EE_READY(st)) {
        return 1;
    }
    if (st->state == ST_WRITE) {
        /* Step 0 marks the slot invalid (kind byte 0x00) unless it already is,
         * steps 1..total-1 write version, sequence, body and CRC, step total
         * writes the kind byte: until that last byte the slot is invalid
         * whatever its CRC says, so a torn slot is never taken for a record. */
        for (n = 0; n < STORE_SKIP_BUDGET && st->pos <= total; n++) {
            uint16_t a = (uint16_t)(st->addr + st->pos);
            if (st->pos == 0u) {
                b = ee_byte(st, a);
                if (b == st->hdr[0]) {
                    b = STORE_KIND_NONE; /* still looks like a record of this kind */
                }
            } else if (st->pos == total) {
                a = st->addr;
                b = st->hdr[0];
            } else if (st->pos < STORE_HDR_LEN + st->len) {
                /* version, sequence and body, into the CRC */
                b = st->pos < STORE_HDR_LEN ? st->hdr[st->pos] : st->body[st->pos - STORE_HDR_LEN];
                st->crc = crc_byte(st->crc, b);
            } else {
                /* the CRC after the body, little-endian */
                b = st->pos == STORE_HDR_LEN + st->len ? (uint8_t)st->crc : (uint8_t)(st->crc >> 8);
            }
            st->pos++;
            if (ee_byte(st, a) != b) {
                EE_WRITE_BYTE(st, a, b);
                return 1;
            }
        }
        if (st->pos > total) {
            st->state = ST_VERIFY;
        }
        return 1;
    }
    /* ST_VERIFY: the last write has finished; read the whole slot back. */
    st->state = ST_IDLE;
    ok = slot_valid(st, st->addr, st->hdr[0], st->hdr[1], st->len, &seq) &&
         seq == (uint16_t)(st->hdr[2] | ((uint16_t)st->hdr[3] << 8));
    for (i = 0; ok && i < st->len; i++) {
        ok = ee_byte(st, (uint16_t)(st->addr + STORE_HDR_LEN + i)) == st->body[i];
    }
    if (!ok) {
        return STORE_E_VERIFY;
    }
    if (st->hdr[0] == STORE_KIND_HIST) {
        st->hist_head = st->hist_slot;
        st->hist_seq = seq;
    }
    return 0;
}

/* ---- settings ---------------------------------------------------- */

int8_t store_setting_info(const store_t *st, uint8_t id, store_setting_info_t *info)
{
    if (id >= STORE_SETTING_COUNT) {
        return STORE_E_ARG;
    }
    st->copy(info, &store_decl[id], sizeof(*info));
    return 0;
}

void store_settings_defaults(const store_t *st, store_settings_t *s)
{
    store_setting_info_t info;
    uint8_t i;
    for (i = 0; i < STORE_SETTING_COUNT; i++) {
        (void)store_setting_info(st, i, &info);
        s->v[i] = info.def;
    }
}

int8_t store_setting_set(const store_t *st, store_settings_t *s, uint8_t id, int32_t value)
{
    store_setting_info_t info;
    if (store_setting_info(st, id, &info) < 0) {
        return STORE_E_ARG;
    }
    if (value < info.min || value > info.max) {
        return STORE_E_RANGE;
    }
    s->v[id] = value;
    return 0;
}

int8_t store_settings_load(store_t *st, store_settings_t *s)
{
    store_setting_info_t info;
    int8_t rc;
    uint8_t i, lost;
    rc = pair_load(st, STORE_ADDR_SETTINGS, STORE_SETTINGS_STRIDE, STORE_KIND_SETTINGS,
                   STORE_SETTINGS_VERSION, s, (uint16_t)sizeof(*s));
    /* no valid record: every default, in the one loop that also puts back
     * the default of a stored value out of its range */
    lost = rc < 0;
    for (i = 0; i < STORE_SETTING_COUNT; i++) {
        (void)store_setting_info(st, i, &info);
        if (lost || s->v[i] < info.min || s->v[i] > info.max) {
            s->v[i] = info.def;
            rc = STORE_E_DEFAULTS;
        }
    }
    return rc;
}

int8_t store_save_settings(store_t *st, const store_settings_t *s)
{
    return pair_save(st, STORE_ADDR_SETTINGS, STORE_SETTINGS_STRIDE, STORE_KIND_SETTINGS,
                     STORE_SETTINGS_VERSION, s, (uint16_t)sizeof(*s));
}

int16_t store_setting_text(const store_t *st, uint8_t id, uint8_t which, char *buf, uint8_t cap)
{
    /* read from flash a byte a call from where the setting's own texts
     * start (walking there from the first setting's took 3 ms for the last
     * one, and `get` held a pass 4.6 ms) */
    uint16_t at, n = 0;
    uint8_t skip = which;
    const char *p;
    char c;
    if (id >= STORE_SETTING_COUNT || which >= STORE_TEXTS || cap == 0u) {
        return STORE_E_ARG;
    }
    st->copy(&at, &store_text_at[id], sizeof at);
    for (p = &store_text[at];; p++) {
        st->copy(&c, p, 1);
        if (skip > 0u) {
            /* walk past `which` NUL-terminated strings */
            skip = (uint8_t)(skip - (c == '\0'));
            continue;
        }
        if (c == '\0') {
            break;
        }
        if (n + 1u < cap) {
            buf[n] = c;
        }
        n++;
    }
    buf[(n < cap) ? n : (uint16_t)(cap - 1u)] = '\0';
    return (int16_t)n;
}

int8_t store_setting_find(const store_t *st, const char *name, uint8_t len)
{
    char buf[24];
    uint8_t i;
    int16_t n;
    for (i = 0; i < STORE_SETTING_COUNT; i++) {
        n = store_setting_text(st, i, 0, buf, sizeof(buf));
        if (n == (int16_t)len && len < sizeof(buf) && memcmp(buf, name, len) == 0) {
            return (int8_t)i;
        }
    }
    return STORE_E_NAME;
}

/* ---- homes ------------------------------------------------------- */

static uint16_t turn_of(int32_t ticks)
{
    /* floor modulo 4096, also for negative positions */
    return (uint16_t)((uint32_t)ticks & (uint32_t)(STORE_TICKS_PER_TURN - 1));
}

STORE_NOINLINE void store_home_set(store_home_t *e, int32_t home_ticks, int32_t rest_ticks)
{
    e->home_ticks = home_ticks;
    e->rest_ticks = rest_ticks;
    e->home_turn = turn_of(home_ticks);
    e->rest_turn = turn_of(rest_ticks);
}

int8_t store_homes_load(store_t *st, uint32_t table_id, store_homes_t *h)
{
    return pair_load_table(st, STORE_ADDR_HOMES, STORE_HOMES_STRIDE, STORE_KIND_HOMES,
                           STORE_HOMES_VERSION, h, (uint16_t)sizeof(*h), table_id);
}

int8_t store_save_homes(store_t *st, const store_homes_t *h)
{
    if (h->n_tendons > STORE_MAX_TENDONS) {
        return STORE_E_ARG;
    }
    return pair_save(st, STORE_ADDR_HOMES, STORE_HOMES_STRIDE, STORE_KIND_HOMES,
                     STORE_HOMES_VERSION, h, (uint16_t)sizeof(*h));
}

STORE_NOINLINE int8_t store_recover_position(const store_home_t *e, int32_t present, uint16_t tol,
                                             int32_t *pos)
{
    int16_t d;
    if (tol >= (uint16_t)(STORE_TICKS_PER_TURN / 2) || e->home_turn != turn_of(e->home_ticks) ||
        e->rest_turn != turn_of(e->rest_ticks)) {
        return STORE_E_ARG;
    }
    d = (int16_t)turn_of((int32_t)turn_of(present) - (int32_t)e->rest_turn);
    if (d >= (int16_t)(STORE_TICKS_PER_TURN / 2)) {
        d = (int16_t)(d - (int16_t)STORE_TICKS_PER_TURN);
    }
    if (d > (int16_t)tol || d < -(int16_t)tol) {
        return STORE_E_MOVED;
    }
    *pos = e->rest_ticks + d;
    return 0;
}

/* ---- windows ----------------------------------------------------- */

int8_t store_win_load(store_t *st, uint32_t table_id, store_win_t *w)
{
    return pair_load_table(st, STORE_ADDR_WIN, STORE_WIN_STRIDE, STORE_KIND_WIN, STORE_WIN_VERSION,
                           w, (uint16_t)sizeof(*w), table_id);
}

int8_t store_save_win(store_t *st, const store_win_t *w)
{
    if (w->n_tendons > STORE_MAX_TENDONS) {
        return STORE_E_ARG;
    }
    return pair_save(st, STORE_ADDR_WIN, STORE_WIN_STRIDE, STORE_KIND_WIN, STORE_WIN_VERSION, w,
                     (uint16_t)sizeof(*w));
}

int8_t store_win_recover(const store_win_tendon_t *e, int32_t present, uint16_t below,
                         uint16_t above, int32_t *lo, int32_t *hi)
{
    /* x: where the spool stands relative to the saved position, known
     * modulo a turn; taken in [min - below, that + 4095] (a tendon pulled
     * towards lower ticks has its bounds the other way round) */
    int32_t x0 = (e->lo < e->hi ? e->lo : e->hi) - (int32_t)below;
    int32_t x1 = (e->lo < e->hi ? e->hi : e->lo) + (int32_t)above;
    int32_t x;
    if (x1 - x0 >= (int32_t)STORE_TICKS_PER_TURN) {
        return STORE_E_ARG;
    }
    x = x0 + (int32_t)turn_of(present - (int32_t)e->at_turn - x0);
    if (x > x1) {
        return STORE_E_MOVED;
    }
    *lo = present - x + e->lo;
    *hi = present - x + e->hi;
    return 0;
}

/* ---- learned ----------------------------------------------------- */

STORE_NOINLINE static uint16_t learned_base(uint8_t tendon)
{
    return (uint16_t)(STORE_ADDR_LEARNED + 2u * tendon * STORE_LEARNED_STRIDE);
}

int8_t store_learned_load(store_t *st, uint8_t tendon, uint32_t table_id, store_learned_t *l)
{
    store_learned_t tmp;
    int8_t rc;
    if (tendon >= STORE_MAX_TENDONS) {
        return STORE_E_ARG;
    }
    rc = pair_load_table(st, learned_base(tendon), STORE_LEARNED_STRIDE, STORE_KIND_LEARNED,
                         STORE_LEARNED_VERSION, &tmp, (uint16_t)sizeof(tmp), table_id);
    if (rc == STORE_E_EMPTY) {
        return rc;
    }
    if (tmp.tendon != tendon || tmp.n_grid > TBL_MAX_GRID) {
        return STORE_E_EMPTY; /* valid CRC but not this tendon's record: never trust it */
    }
    *l = tmp;
    return rc; /* 0, or STORE_E_OTHER_TABLE */
}

int8_t store_save_learned(store_t *st, const store_learned_t *l)
{
    if (l->tendon >= STORE_MAX_TENDONS || l->n_grid > TBL_MAX_GRID) {
        return STORE_E_ARG;
    }
    return pair_save(st, learned_base(l->tendon), STORE_LEARNED_STRIDE, STORE_KIND_LEARNED,
                     STORE_LEARNED_VERSION, l, (uint16_t)sizeof(*l));
}

/* ---- history ----------------------------------------------------- */

int8_t store_hist_get(store_t *st, uint8_t age, store_hist_t *e)
{
    uint8_t i;
    uint16_t seq;
    if (age >= STORE_HIST_N) {
        return STORE_E_ARG;
    }
    if (st->hist_head == STORE_NO_HEAD) {
        return STORE_E_EMPTY;
    }
    i = (st->hist_head >= age) ? (uint8_t)(st->hist_head - age)
                               : (uint8_t)(st->hist_head + STORE_HIST_N - age);
    /* An entry lost to a cut write breaks the chain: older ones are still
     * there but the sequence check keeps the answer honest. */
    if (!hist_slot_valid(st, i, &seq) || seq != (uint16_t)(st->hist_seq - age)) {
        return STORE_E_EMPTY;
    }
    EE_READ_BLOCK(st, e, (uint16_t)(STORE_ADDR_HIST + i * STORE_HIST_STRIDE + STORE_HDR_LEN),
                  (uint16_t)sizeof(*e));
    return 0;
}

STORE_NOINLINE uint8_t store_hist_count(store_t *st)
{
    store_hist_t e;
    uint8_t n = 0;
    while (n < STORE_HIST_N && store_hist_get(st, n, &e) == 0) {
        n++;
    }
    return n;
}

int8_t store_save_hist(store_t *st, const store_hist_t *e)
{
    uint8_t i;
    uint16_t seq;
    if (st->state != ST_IDLE) {
        return STORE_E_BUSY;
    }
    if (e->n_tendons > STORE_MAX_TENDONS) {
        return STORE_E_ARG;
    }
    /* the slot after the newest entry, or slot 0 of an empty ring */
    i = 0;
    seq = 1u;
    if (st->hist_head != STORE_NO_HEAD) {
        i = (uint8_t)(st->hist_head + 1u);
        if (i >= STORE_HIST_N) {
            i = 0;
        }
        seq = (uint16_t)(st->hist_seq + 1u);
    }
    st->hist_slot = i;
    return save_begin(st, (uint16_t)(STORE_ADDR_HIST + i * STORE_HIST_STRIDE), STORE_KIND_HIST,
                      STORE_HIST_VERSION, seq, e, (uint16_t)sizeof(*e));
}
