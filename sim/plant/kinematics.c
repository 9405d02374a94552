/*
 * kinematics: arcs, the tip frame and gravity's moment on the bent robot
 * (see kinematics.h).
 */
#include "plant/kinematics.h"

#include <math.h>
#include <string.h>

void plant_mat_mul(double out[3][3], double a[3][3], double b[3][3])
{
    double r[3][3];
    int i;
    int j;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    memcpy(out, r, sizeof r);
}

void plant_arc(const double k[2], double len, double rot[3][3], double pos[3])
{
    double kap = sqrt(k[0] * k[0] + k[1] * k[1]);
    double th = kap * len;
    double c = kap > 0.0 ? k[0] / kap : 1.0;
    double s = kap > 0.0 ? k[1] / kap : 0.0;
    double ct = cos(th);
    double st = sin(th);
    double r;
    double z;
    /* rotation by th about the axis (-s, c, 0) */
    double ax[3];
    double v = 1.0 - ct;
    int i;
    int j;
    if (th < 1e-6) {
        r = kap * len * len / 2.0;
        z = len;
    } else {
        r = (1.0 - ct) / kap;
        z = st / kap;
    }
    pos[0] = r * c;
    pos[1] = r * s;
    pos[2] = z;
    ax[0] = -s;
    ax[1] = c;
    ax[2] = 0.0;
    for (i = 0; i < 3; i++) {
        for (j = 0; j < 3; j++) {
            rot[i][j] = v * ax[i] * ax[j] + (i == j ? ct : 0.0);
        }
    }
    rot[0][1] -= st * ax[2];
    rot[0][2] += st * ax[1];
    rot[1][0] += st * ax[2];
    rot[1][2] -= st * ax[0];
    rot[2][0] -= st * ax[1];
    rot[2][1] += st * ax[0];
}

/* p = base + R d */
static void place(const double base[3], double rot[3][3], const double d[3], double p[3])
{
    int a;
    for (a = 0; a < 3; a++) {
        p[a] = base[a] + rot[a][0] * d[0] + rot[a][1] * d[1] + rot[a][2] * d[2];
    }
}

void plant_forward_kinematics(plant_t *p)
{
    double rot[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    double pos[3] = {0, 0, 0};
    uint8_t j;
    int a;
    for (j = 0; j < p->cfg.n_segments; j++) {
        double r[3][3];
        double d[3];
        plant_arc(p->curv[j], p->cfg.seg_len_mm[j] * 1e-3, r, d);
        place(pos, rot, d, pos);
        plant_mat_mul(rot, rot, r);
    }
    for (a = 0; a < 3; a++) {
        p->tip.pos_mm[a] = pos[a] * 1e3;
    }
    memcpy(p->tip.rot, rot, sizeof rot);
}

double plant_seg_ei(const plant_cfg_t *c, uint8_t j)
{
    return c->seg_ei_Nm2[j] > 0.0 ? c->seg_ei_Nm2[j] : c->ei_Nm2;
}

int plant_has_gravity(const plant_cfg_t *c)
{
    uint8_t j;
    if (c->tip_mass_g > 0.0) {
        return 1;
    }
    for (j = 0; j < c->n_segments; j++) {
        if (c->seg_mass_g[j] > 0.0) {
            return 1;
        }
    }
    return 0;
}

#define GRAV_MAX_POINTS (PLANT_MAX_SEGMENTS * PLANT_GRAVITY_POINTS + 1u)

void plant_gravity_curv(const plant_cfg_t *c, double curv[][2], double gk[][2])
{
    double pt[GRAV_MAX_POINTS][3]; /* mass points, world frame, in arc order */
    double wt[GRAV_MAX_POINTS];    /* their weights, N */
    double base_rot[PLANT_MAX_SEGMENTS][3][3];
    double rot[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    double pos[3] = {0, 0, 0};
    double mag[3] = {0, 0, 0};
    uint8_t n = 0;
    uint8_t j;
    uint8_t q;
    uint8_t e;
    uint8_t m;

    for (j = 0; j < c->n_segments; j++) {
        double len = c->seg_len_mm[j] * 1e-3;
        double r[3][3];
        double d[3];
        memcpy(base_rot[j], rot, sizeof rot);
        for (q = 0; q < PLANT_GRAVITY_POINTS; q++) {
            plant_arc(curv[j], len * (q + 0.5) / PLANT_GRAVITY_POINTS, r, d);
            place(pos, rot, d, pt[n]);
            wt[n++] = c->seg_mass_g[j] * 1e-3 * PLANT_G / PLANT_GRAVITY_POINTS;
        }
        plant_arc(curv[j], len, r, d);
        place(pos, rot, d, pos);
        plant_mat_mul(rot, rot, r);
    }
    mag[2] = c->magnet_offset_mm * 1e-3;
    place(pos, rot, mag, pt[n]);
    wt[n++] = c->tip_mass_g * 1e-3 * PLANT_G;

    for (j = 0; j < c->n_segments; j++) {
        double sum[2] = {0.0, 0.0};
        for (q = 0; q < PLANT_GRAVITY_POINTS; q++) {
            double mw[3] = {0.0, 0.0, 0.0}; /* moment about this point, world frame */
            double mb[2];
            int a;
            e = (uint8_t)(j * PLANT_GRAVITY_POINTS + q);
            for (m = (uint8_t)(e + 1u); m < n; m++) {
                double l[3];
                double f[3];
                for (a = 0; a < 3; a++) {
                    l[a] = pt[m][a] - pt[e][a];
                    f[a] = wt[m] * c->gravity_dir[a];
                }
                mw[0] += l[1] * f[2] - l[2] * f[1];
                mw[1] += l[2] * f[0] - l[0] * f[2];
                mw[2] += l[0] * f[1] - l[1] * f[0];
            }
            /* into the segment's base frame (R^T m) */
            for (a = 0; a < 2; a++) {
                mb[a] = base_rot[j][0][a] * mw[0] + base_rot[j][1][a] * mw[1] +
                        base_rot[j][2][a] * mw[2];
            }
            /* a moment about +y bends towards +x: curvature (m_y, -m_x) / EI */
            sum[0] += mb[1];
            sum[1] -= mb[0];
        }
        gk[j][0] = sum[0] / (PLANT_GRAVITY_POINTS * plant_seg_ei(c, j));
        gk[j][1] = sum[1] / (PLANT_GRAVITY_POINTS * plant_seg_ei(c, j));
    }
}
