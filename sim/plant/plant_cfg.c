/*
 * plant_cfg: the plant's line-oriented config format (README.md beside this
 * file), its defaults, checks and seeded perturbation.
 */
#include "plant/plant.h"
#include "simrand.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int plant_cfg_defaults(plant_cfg_t *cfg)
{
    uint8_t i;
    if (cfg == NULL) {
        return PLANT_E_ARG;
    }
    memset(cfg, 0, sizeof *cfg);
    strcpy(cfg->name, "plant");
    cfg->ei_Nm2 = 2.945e-3;
    cfg->nm_per_tick = 6136.0;
    cfg->magnet_moment_Am2 = 0.0389;
    cfg->magnet_offset_mm = 2.0;
    cfg->gravity_dir[2] = -1.0;
    cfg->noise_uT = 0.4;
    cfg->servo_tau_ms = 4.0;
    cfg->travel_limit_factor = 1.5;
    cfg->travel_limit_margin_um = 300.0;
    for (i = 0; i < PLANT_MAX_TENDONS; i++) {
        plant_tendon_cfg_t *t = &cfg->tendon[i];
        t->radius_mm = 4.5;
        t->segment = 1;
        t->servo_id = (uint8_t)(i + 1u);
        t->pull_dir = 1;
        t->sensor = -1;
        t->ea_N = 3000.0;
        t->free_len_mm = 300.0;
        t->slack_um = 1000.0;
    }
    for (i = 0; i < PLANT_MAX_SENSORS; i++) {
        cfg->sensor[i].mux_channel = i;
        cfg->sensor[i].i2c_addr = 0x69;
        cfg->sensor[i].rot[0] = cfg->sensor[i].rot[4] = cfg->sensor[i].rot[8] = 1.0;
    }
    return 0;
}

int plant_cfg_check(const plant_cfg_t *cfg)
{
    uint8_t i;
    if (cfg == NULL) {
        return PLANT_E_ARG;
    }
    if (cfg->n_segments == 0u || cfg->n_tendons == 0u || cfg->n_sensors == 0u ||
        cfg->ei_Nm2 <= 0.0 || cfg->nm_per_tick <= 0.0 || cfg->n_grid < 2u ||
        cfg->servo_tau_ms <= 0.0 || cfg->noise_uT < 0.0) {
        return PLANT_E_RANGE;
    }
    for (i = 0; i < cfg->n_segments; i++) {
        if (cfg->seg_len_mm[i] <= 0.0) {
            return PLANT_E_RANGE;
        }
    }
    for (i = 1; i < cfg->n_grid; i++) {
        if (cfg->grid_mN[i] <= cfg->grid_mN[i - 1u]) {
            return PLANT_E_RANGE;
        }
    }
    if (cfg->default_mN < cfg->grid_mN[0] || cfg->default_mN > cfg->grid_mN[cfg->n_grid - 1u]) {
        return PLANT_E_RANGE;
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        const plant_tendon_cfg_t *t = &cfg->tendon[i];
        if (t->segment < 1u || t->segment > cfg->n_segments || t->ea_N <= 0.0 ||
            t->free_len_mm <= 0.0 || t->radius_mm <= 0.0 ||
            (t->pull_dir != 1 && t->pull_dir != -1) || t->sensor >= (int)cfg->n_sensors ||
            t->friction_mu < 0.0 || t->friction_mu >= 0.5 || t->friction_mN < 0.0 ||
            t->backlash_um < 0.0) {
            return PLANT_E_RANGE;
        }
    }
    return 0;
}

/* Parses up to max numbers separated by blanks; returns how many, or -1 when
 * something else is on the line. */
static int parse_numbers(const char *s, double *out, int max)
{
    int n = 0;
    while (*s != '\0') {
        char *end;
        double v;
        while (isspace((unsigned char)*s)) {
            s++;
        }
        if (*s == '\0') {
            break;
        }
        if (n == max) {
            return -1;
        }
        v = strtod(s, &end);
        if (end == s || !isfinite(v)) {
            return -1;
        }
        out[n++] = v;
        s = end;
    }
    return n;
}

typedef struct {
    const char *key;
    size_t offset;
    int count; /* numbers expected; negative: a list up to -count */
    char kind; /* 'd' double, '8' uint8, 'i' int8, 'w' uint16 */
} plant_key_t;

#define PK(key, type, field, count, kind)                                                          \
    {                                                                                              \
        key, offsetof(type, field), count, kind                                                    \
    }

static const plant_key_t plant_top_keys[] = {
    PK("backbone_ei_Nm2", plant_cfg_t, ei_Nm2, 1, 'd'),
    PK("nm_per_tick", plant_cfg_t, nm_per_tick, 1, 'd'),
    PK("magnet_moment_Am2", plant_cfg_t, magnet_moment_Am2, 1, 'd'),
    PK("magnet_offset_mm", plant_cfg_t, magnet_offset_mm, 1, 'd'),
    PK("tip_mass_g", plant_cfg_t, tip_mass_g, 1, 'd'),
    PK("gravity_dir", plant_cfg_t, gravity_dir, 3, 'd'),
    PK("noise_uT", plant_cfg_t, noise_uT, 1, 'd'),
    PK("servo_tau_ms", plant_cfg_t, servo_tau_ms, 1, 'd'),
    PK("travel_limit_factor", plant_cfg_t, travel_limit_factor, 1, 'd'),
    PK("travel_limit_margin_um", plant_cfg_t, travel_limit_margin_um, 1, 'd'),
    PK("travel_limit_um", plant_cfg_t, travel_limit_um, 1, 'd'),
    PK("default_mN", plant_cfg_t, default_mN, 1, 'w'),
};

static const plant_key_t plant_tendon_keys[] = {
    PK("angle_deg", plant_tendon_cfg_t, angle_deg, 1, 'd'),
    PK("radius_mm", plant_tendon_cfg_t, radius_mm, 1, 'd'),
    PK("segment", plant_tendon_cfg_t, segment, 1, '8'),
    PK("servo_id", plant_tendon_cfg_t, servo_id, 1, '8'),
    PK("pull_dir", plant_tendon_cfg_t, pull_dir, 1, 'i'),
    PK("sensor", plant_tendon_cfg_t, sensor, 1, 'i'),
    PK("ea_N", plant_tendon_cfg_t, ea_N, 1, 'd'),
    PK("free_len_mm", plant_tendon_cfg_t, free_len_mm, 1, 'd'),
    PK("slack_um", plant_tendon_cfg_t, slack_um, 1, 'd'),
    PK("friction_mN", plant_tendon_cfg_t, friction_mN, 1, 'd'),
    PK("friction_mu", plant_tendon_cfg_t, friction_mu, 1, 'd'),
    PK("backlash_um", plant_tendon_cfg_t, backlash_um, 1, 'd'),
    PK("nm_per_tick", plant_tendon_cfg_t, nm_per_tick, 1, 'd'),
};

static const plant_key_t plant_sensor_keys[] = {
    PK("pos_mm", plant_sensor_cfg_t, pos_mm, 3, 'd'),
    PK("ambient_uT", plant_sensor_cfg_t, ambient_uT, 3, 'd'),
    PK("rot", plant_sensor_cfg_t, rot, 9, 'd'),
    PK("mux", plant_sensor_cfg_t, mux_channel, 1, '8'),
    PK("addr", plant_sensor_cfg_t, i2c_addr, 1, '8'),
};

/* Stores the numbers of one key into the struct at base. */
static int store_key(const plant_key_t *k, void *base, const double *v, int n)
{
    int i;
    unsigned char *p = (unsigned char *)base + k->offset;
    if (n != k->count) {
        return PLANT_E_SYNTAX;
    }
    for (i = 0; i < n; i++) {
        switch (k->kind) {
        case 'd':
            ((double *)(void *)p)[i] = v[i];
            break;
        case '8':
            if (v[i] < 0.0 || v[i] > 255.0 || v[i] != floor(v[i])) {
                return PLANT_E_RANGE;
            }
            p[i] = (uint8_t)v[i];
            break;
        case 'i':
            if (v[i] < -128.0 || v[i] > 127.0 || v[i] != floor(v[i])) {
                return PLANT_E_RANGE;
            }
            ((int8_t *)(void *)p)[i] = (int8_t)v[i];
            break;
        default: /* 'w' */
            if (v[i] < 0.0 || v[i] > 65535.0 || v[i] != floor(v[i])) {
                return PLANT_E_RANGE;
            }
            ((uint16_t *)(void *)p)[i] = (uint16_t)v[i];
            break;
        }
    }
    return 0;
}

static const plant_key_t *find_key(const plant_key_t *keys, size_t n, const char *name)
{
    size_t i;
    for (i = 0; i < n; i++) {
        if (strcmp(keys[i].key, name) == 0) {
            return &keys[i];
        }
    }
    return NULL;
}

/* Handles `tendon.<i|*>.<field>` and `sensor.<k>.<field>`. */
static int parse_indexed(plant_cfg_t *cfg, const char *key, const double *v, int n)
{
    int is_tendon = strncmp(key, "tendon.", 7) == 0;
    const char *rest = key + (is_tendon ? 7 : 7);
    const char *dot;
    unsigned long idx = 0;
    int all = 0;
    const plant_key_t *k;
    unsigned max = is_tendon ? PLANT_MAX_TENDONS : PLANT_MAX_SENSORS;
    int rc;

    if (rest[0] == '*' && rest[1] == '.') {
        all = 1;
        dot = rest + 1;
    } else {
        char *end;
        if (!isdigit((unsigned char)rest[0])) {
            return PLANT_E_KEY;
        }
        idx = strtoul(rest, &end, 10);
        if (*end != '.') {
            return PLANT_E_KEY;
        }
        dot = end;
        if (idx >= max) {
            return PLANT_E_RANGE;
        }
    }
    if (is_tendon) {
        k = find_key(plant_tendon_keys, sizeof plant_tendon_keys / sizeof plant_tendon_keys[0],
                     dot + 1);
    } else {
        k = find_key(plant_sensor_keys, sizeof plant_sensor_keys / sizeof plant_sensor_keys[0],
                     dot + 1);
    }
    if (k == NULL) {
        return PLANT_E_KEY;
    }
    if (all) {
        unsigned i;
        if (!is_tendon) {
            return PLANT_E_KEY;
        }
        for (i = 0; i < max; i++) {
            rc = store_key(k, &cfg->tendon[i], v, n);
            if (rc != 0) {
                return rc;
            }
        }
        return 0;
    }
    if (is_tendon) {
        rc = store_key(k, &cfg->tendon[idx], v, n);
        if (rc == 0 && idx + 1u > cfg->n_tendons) {
            cfg->n_tendons = (uint8_t)(idx + 1u);
        }
    } else {
        rc = store_key(k, &cfg->sensor[idx], v, n);
        if (rc == 0 && idx + 1u > cfg->n_sensors) {
            cfg->n_sensors = (uint8_t)(idx + 1u);
        }
    }
    return rc;
}

static int parse_line(plant_cfg_t *cfg, char *line)
{
    char *eq;
    char *key;
    char *val;
    char *end;
    double v[TBL_MAX_GRID];
    int n;
    int i;
    const plant_key_t *k;

    eq = strchr(line, '=');
    if (eq == NULL) {
        return PLANT_E_SYNTAX;
    }
    *eq = '\0';
    key = line;
    while (isspace((unsigned char)*key)) {
        key++;
    }
    end = eq;
    while (end > key && isspace((unsigned char)end[-1])) {
        end--;
    }
    *end = '\0';
    val = eq + 1;
    while (isspace((unsigned char)*val)) {
        val++;
    }
    end = val + strlen(val);
    while (end > val && isspace((unsigned char)end[-1])) {
        end--;
    }
    *end = '\0';
    if (*key == '\0') {
        return PLANT_E_SYNTAX;
    }
    if (strcmp(key, "name") == 0) {
        if (strlen(val) >= TBL_NAME_LEN || *val == '\0') {
            return PLANT_E_RANGE;
        }
        strcpy(cfg->name, val);
        return 0;
    }
    n = parse_numbers(val, v, (int)TBL_MAX_GRID);
    if (n <= 0) {
        return PLANT_E_SYNTAX;
    }
    if (strcmp(key, "segment_len_mm") == 0) {
        if (n > (int)PLANT_MAX_SEGMENTS) {
            return PLANT_E_RANGE;
        }
        for (i = 0; i < n; i++) {
            cfg->seg_len_mm[i] = v[i];
        }
        cfg->n_segments = (uint8_t)n;
        return 0;
    }
    {
        /* per-segment lists: key, field, the lowest value allowed (and whether it is) */
        static const struct {
            const char *key;
            size_t offset;
            int zero_ok;
        } lists[] = {
            {"segment_ei_Nm2", offsetof(plant_cfg_t, seg_ei_Nm2), 0},
            {"segment_ea_N", offsetof(plant_cfg_t, seg_ea_N), 1},
            {"segment_mass_g", offsetof(plant_cfg_t, seg_mass_g), 1},
        };
        size_t l;
        for (l = 0; l < sizeof lists / sizeof lists[0]; l++) {
            double *dst = (double *)(void *)((unsigned char *)cfg + lists[l].offset);
            if (strcmp(key, lists[l].key) != 0) {
                continue;
            }
            if (n > (int)PLANT_MAX_SEGMENTS) {
                return PLANT_E_RANGE;
            }
            for (i = 0; i < n; i++) {
                if (v[i] < 0.0 || (v[i] == 0.0 && !lists[l].zero_ok)) {
                    return PLANT_E_RANGE;
                }
                dst[i] = v[i];
            }
            return 0;
        }
    }
    if (strcmp(key, "grid_mN") == 0) {
        for (i = 0; i < n; i++) {
            if (v[i] <= 0.0 || v[i] > 65535.0) {
                return PLANT_E_RANGE;
            }
            cfg->grid_mN[i] = (uint16_t)v[i];
        }
        cfg->n_grid = (uint8_t)n;
        return 0;
    }
    if (strncmp(key, "tendon.", 7) == 0 || strncmp(key, "sensor.", 7) == 0) {
        return parse_indexed(cfg, key, v, n);
    }
    k = find_key(plant_top_keys, sizeof plant_top_keys / sizeof plant_top_keys[0], key);
    if (k == NULL) {
        return PLANT_E_KEY;
    }
    return store_key(k, cfg, v, n);
}

int plant_cfg_parse(plant_cfg_t *cfg, const char *text, int *err_line)
{
    int line_no = 0;
    if (cfg == NULL || text == NULL) {
        return PLANT_E_ARG;
    }
    while (*text != '\0') {
        char line[256];
        size_t len = strcspn(text, "\n");
        char *hash;
        char *s;
        int rc;
        line_no++;
        if (len >= sizeof line) {
            if (err_line != NULL) {
                *err_line = line_no;
            }
            return PLANT_E_SYNTAX;
        }
        memcpy(line, text, len);
        line[len] = '\0';
        text += len;
        if (*text == '\n') {
            text++;
        }
        hash = strchr(line, '#');
        if (hash != NULL) {
            *hash = '\0';
        }
        s = line;
        while (isspace((unsigned char)*s)) {
            s++;
        }
        if (*s == '\0') {
            continue;
        }
        rc = parse_line(cfg, s);
        if (rc != 0) {
            if (err_line != NULL) {
                *err_line = line_no;
            }
            return rc;
        }
    }
    return 0;
}

int plant_cfg_load(plant_cfg_t *cfg, const char *path, int *err_line)
{
    char buf[16384];
    size_t n;
    FILE *f;
    if (cfg == NULL || path == NULL) {
        return PLANT_E_ARG;
    }
    f = fopen(path, "r");
    if (f == NULL) {
        return PLANT_E_IO;
    }
    n = fread(buf, 1, sizeof buf - 1u, f);
    if (ferror(f) || !feof(f)) {
        fclose(f);
        return PLANT_E_IO;
    }
    fclose(f);
    buf[n] = '\0';
    (void)plant_cfg_defaults(cfg);
    return plant_cfg_parse(cfg, buf, err_line);
}

static double perturb_u(uint64_t *s)
{
    return 2.0 * simrand_unit(s) - 1.0; /* [-1, 1) */
}

int plant_cfg_perturb(plant_cfg_t *cfg, uint32_t seed, double frac)
{
    return plant_cfg_perturb_stiffness(cfg, seed, frac, frac);
}

int plant_cfg_perturb_stiffness(plant_cfg_t *cfg, uint32_t seed, double frac, double stiff)
{
    uint64_t s = 0x5EEDull ^ ((uint64_t)seed << 17);
    uint8_t i;
    int a;
    if (cfg == NULL) {
        return PLANT_E_ARG;
    }
    if (frac == 0.0 && stiff == 0.0) {
        return 0;
    }
    cfg->ei_Nm2 *= 1.0 + stiff * perturb_u(&s);
    for (i = 0; i < cfg->n_segments; i++) {
        cfg->seg_ei_Nm2[i] *= 1.0 + stiff * perturb_u(&s);
    }
    cfg->magnet_moment_Am2 *= 1.0 + frac * perturb_u(&s);
    for (i = 0; i < cfg->n_segments; i++) {
        cfg->seg_len_mm[i] *= 1.0 + 0.2 * frac * perturb_u(&s);
    }
    for (i = 0; i < cfg->n_tendons; i++) {
        plant_tendon_cfg_t *t = &cfg->tendon[i];
        t->angle_deg += 5.0 * frac * perturb_u(&s);
        t->radius_mm *= 1.0 + 0.2 * frac * perturb_u(&s);
        t->ea_N *= 1.0 + frac * perturb_u(&s);
        t->free_len_mm *= 1.0 + frac * perturb_u(&s);
        t->slack_um += 500.0 * frac * perturb_u(&s);
        t->friction_mN *= 1.0 + frac * perturb_u(&s);
        t->friction_mu *= 1.0 + frac * perturb_u(&s);
        t->backlash_um *= 1.0 + frac * perturb_u(&s);
    }
    for (i = 0; i < cfg->n_sensors; i++) {
        for (a = 0; a < 3; a++) {
            cfg->sensor[i].pos_mm[a] += frac * perturb_u(&s);
        }
    }
    /* drawn last, so the draws above stay what they were before the key */
    for (i = 0; i < cfg->n_segments; i++) {
        cfg->seg_ea_N[i] *= 1.0 + stiff * perturb_u(&s);
    }
    return 0;
}
