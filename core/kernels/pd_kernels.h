/* pd_kernels.h -- the per-particle and per-spring bodies of Algorithm 1 of the
 * paper (Projective Dynamics with a Red-Black Gauss-Seidel global step), shared by
 * every backend. Positions are structure-of-arrays floats in metres, indexed by
 * internal (color-contiguous) particle index. */
#ifndef RBC_PD_KERNELS_H
#define RBC_PD_KERNELS_H
#include <math.h>
#include <stdint.h>

#include "rbc_hd.h"

/* Alg. 2, Verlet integration with damping, for particle i:
 *   y = x + (1 - c h)(x - x_prev) + h^2 g
 * i.e. p(t+h) = 2p(t) - p(t-h) + h^2 f_ext with f_ext = g - c v as an acceleration
 * and v = (x - x_prev)/h. `keep` = 1 - c h (clamped to [0, 1] by the caller), `g_h2` =
 * h^2 g. y is the inertial target of Eq. 6; the global iterations start from p = y. */
RBC_HD void rbc_k_predict(uint32_t i, const float *xx, const float *xy, const float *xz,
                          const float *qx, const float *qy, const float *qz, float *yx, float *yy,
                          float *yz, float *px, float *py, float *pz, float keep, float gx_h2,
                          float gy_h2, float gz_h2) {
    float nx = xx[i] + keep * (xx[i] - qx[i]) + gx_h2;
    float ny = xy[i] + keep * (xy[i] - qy[i]) + gy_h2;
    float nz = xz[i] + keep * (xz[i] - qz[i]) + gz_h2;
    yx[i] = nx;
    yy[i] = ny;
    yz[i] = nz;
    px[i] = nx;
    py[i] = ny;
    pz[i] = nz;
}

/* Alg. 3, the local step for spring s joining a and b:
 *   d_ab = L (p_a - p_b) / |p_a - p_b|
 * written into a's half-edge slot (a's target is p_b + d_ab) and, negated, into b's
 * (b's target is p_a - d_ab). A spring of (near) zero current length keeps its rest
 * direction u, so d never becomes 0/0. */
RBC_HD void rbc_k_local(uint32_t s, const uint32_t *sa, const uint32_t *sb, const float *rest,
                        const float *ux, const float *uy, const float *uz, const uint32_t *he_a,
                        const uint32_t *he_b, const float *px, const float *py, const float *pz,
                        float *dx, float *dy, float *dz) {
    uint32_t a = sa[s], b = sb[s];
    float ex = px[a] - px[b], ey = py[a] - py[b], ez = pz[a] - pz[b];
    float len2 = ex * ex + ey * ey + ez * ez;
    float L = rest[s];
    float ox, oy, oz;
    if (len2 > 1e-24f) { /* |e| > 1e-12 m */
        float f = L / sqrtf(len2);
        ox = ex * f;
        oy = ey * f;
        oz = ez * f;
    } else {
        ox = L * ux[s];
        oy = L * uy[s];
        oz = L * uz[s];
    }
    uint32_t ka = he_a[s], kb = he_b[s];
    dx[ka] = ox;
    dy[ka] = oy;
    dz[ka] = oz;
    dx[kb] = -ox;
    dy[kb] = -oy;
    dz[kb] = -oz;
}

/* Eq. 6 for particle i, reading the neighbours from (px, py, pz):
 *   g_i = (m_i/h^2 y_i + sum_j s_ij (p_j + d_ij)) / (m_i/h^2 + sum_j s_ij)
 * w[i] = m_i/h^2 (kg/s^2), inv_denom[i] = 1/(w_i + sum_j s_ij). Gauss-Seidel writes g_i
 * back into the same arrays (red-black ordering makes a color's updates independent),
 * Jacobi into another iterate. */
RBC_HD void rbc_k_eq6(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                      const float *adj_k, const float *dx, const float *dy, const float *dz,
                      const float *w, const float *inv_denom, const float *yx, const float *yy,
                      const float *yz, const float *px, const float *py, const float *pz,
                      float *gx, float *gy, float *gz) {
    float wi = w[i];
    float sx = wi * yx[i], sy = wi * yy[i], sz = wi * yz[i];
    for (uint32_t k = adj_start[i]; k < adj_start[i + 1]; ++k) {
        uint32_t j = adj_nbr[k];
        float kk = adj_k[k];
        sx += kk * (px[j] + dx[k]);
        sy += kk * (py[j] + dy[k]);
        sz += kk * (pz[j] + dz[k]);
    }
    float r = inv_denom[i];
    *gx = sx * r;
    *gy = sy * r;
    *gz = sz * r;
}

/* The constant part of Eq. 6's numerator for particle i, for the linear iterations
 * of one non-linear iteration (y and d change only between them):
 *   b_i = m_i/h^2 y_i + sum_j s_ij d_ij
 * so that a sweep reads one vector per particle instead of d per neighbour. */
RBC_HD void rbc_k_rhs(uint32_t i, const uint32_t *adj_start, const float *adj_k,
                      const float *dx, const float *dy, const float *dz, const float *w,
                      const float *yx, const float *yy, const float *yz, float *bx, float *by,
                      float *bz) {
    float wi = w[i];
    float sx = wi * yx[i], sy = wi * yy[i], sz = wi * yz[i];
    for (uint32_t k = adj_start[i]; k < adj_start[i + 1]; ++k) {
        float kk = adj_k[k];
        sx += kk * dx[k];
        sy += kk * dy[k];
        sz += kk * dz[k];
    }
    bx[i] = sx;
    by[i] = sy;
    bz[i] = sz;
}

/* Eq. 6 for particle i from its precomputed b_i (rbc_k_rhs), reading the neighbours
 * from (px, py, pz): g_i = (b_i + sum_j s_ij p_j) / (m_i/h^2 + sum_j s_ij). */
RBC_HD void rbc_k_eq6b(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                       const float *adj_k, const float *bx, const float *by, const float *bz,
                       const float *inv_denom, const float *px, const float *py,
                       const float *pz, float *gx, float *gy, float *gz) {
    float sx = bx[i], sy = by[i], sz = bz[i];
    for (uint32_t k = adj_start[i]; k < adj_start[i + 1]; ++k) {
        uint32_t j = adj_nbr[k];
        float kk = adj_k[k];
        sx += kk * px[j];
        sy += kk * py[j];
        sz += kk * pz[j];
    }
    float r = inv_denom[i];
    *gx = sx * r;
    *gy = sy * r;
    *gz = sz * r;
}

/* One Gauss-Seidel update of free particle i in place (Eq. 6). */
RBC_HD void rbc_k_global(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                         const float *adj_k, const float *dx, const float *dy, const float *dz,
                         const float *w, const float *inv_denom, const float *yx,
                         const float *yy, const float *yz, float *px, float *py, float *pz) {
    float gx, gy, gz;
    rbc_k_eq6(i, adj_start, adj_nbr, adj_k, dx, dy, dz, w, inv_denom, yx, yy, yz, px, py, pz,
              &gx, &gy, &gz);
    px[i] = gx;
    py[i] = gy;
    pz[i] = gz;
}

/* Residual and right-hand side of free particle i's row of the global system (from
 * b_i of rbc_k_rhs)
 *   (w_i + sum_j s_ij) p_i - sum_{j free} s_ij p_j = w_i y_i + sum_j s_ij d_ij + sum_{j pinned} s_ij p_j
 * as squared norms: *r2 += |b_i - (A p)_i|^2, *b2 += |b_i|^2 (double accumulators). */
RBC_HD void rbc_k_residual(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                           const float *adj_k, const float *b_x, const float *b_y,
                           const float *b_z, const float *inv_denom, const float *px,
                           const float *py, const float *pz, const uint8_t *pinned, double *r2,
                           double *b2) {
    /* b (rbc_k_rhs) holds m_i/h^2 y_i + sum_j s_ij d_ij; the pinned neighbours' terms
     * join it on the right-hand side. */
    double bx = b_x[i], by = b_y[i], bz = b_z[i];
    double ax = px[i] / (double)inv_denom[i], ay = py[i] / (double)inv_denom[i],
           az = pz[i] / (double)inv_denom[i];
    for (uint32_t k = adj_start[i]; k < adj_start[i + 1]; ++k) {
        uint32_t j = adj_nbr[k];
        double kk = adj_k[k];
        if (pinned[j]) {
            bx += kk * px[j];
            by += kk * py[j];
            bz += kk * pz[j];
        } else {
            ax -= kk * px[j];
            ay -= kk * py[j];
            az -= kk * pz[j];
        }
    }
    double rx = bx - ax, ry = by - ay, rz = bz - az;
    *r2 += rx * rx + ry * ry + rz * rz;
    *b2 += bx * bx + by * by + bz * bz;
}
/* The Gauss-Seidel variants of one color's update (Eq. 6 in place): plain, over-relaxed
 * (SOR: p += omega (g - p)), or plain with the old value kept in s for Chebyshev's
 * blend after the sweeps. */
#define RBC_K_GS_PLAIN 0
#define RBC_K_GS_SOR 1
#define RBC_K_GS_STASH 2

/* One Gauss-Seidel update of particle i of a color (pinned particles stay). */
RBC_HD void rbc_k_gs(uint32_t i, int variant, float omega, const uint32_t *adj_start,
                     const uint32_t *adj_nbr, const float *adj_k, const float *bx,
                     const float *by, const float *bz, const float *inv_denom,
                     const uint8_t *pinned, float *px, float *py, float *pz, float *sx,
                     float *sy, float *sz) {
    if (pinned[i]) return;
    float gx, gy, gz;
    rbc_k_eq6b(i, adj_start, adj_nbr, adj_k, bx, by, bz, inv_denom, px, py, pz, &gx, &gy, &gz);
    if (variant == RBC_K_GS_PLAIN) {
        px[i] = gx;
        py[i] = gy;
        pz[i] = gz;
    } else if (variant == RBC_K_GS_SOR) {
        px[i] += omega * (gx - px[i]);
        py[i] += omega * (gy - py[i]);
        pz[i] += omega * (gz - pz[i]);
    } else {
        sx[i] = px[i];
        sy[i] = py[i];
        sz[i] = pz[i];
        px[i] = gx;
        py[i] = gy;
        pz[i] = gz;
    }
}

/* One Jacobi update of particle i from iterate s into o (pinned particles are copied).
 * Chebyshev: o = omega (g - q) + q with q = p^(k-1), and q becomes s. */
RBC_HD void rbc_k_jacobi(uint32_t i, int chebyshev, float omega, const uint32_t *adj_start,
                         const uint32_t *adj_nbr, const float *adj_k, const float *bx,
                         const float *by, const float *bz, const float *inv_denom,
                         const uint8_t *pinned, const float *sx, const float *sy,
                         const float *sz, float *ox, float *oy, float *oz, float *qx,
                         float *qy, float *qz) {
    if (pinned[i]) {
        ox[i] = sx[i];
        oy[i] = sy[i];
        oz[i] = sz[i];
        return;
    }
    float gx, gy, gz;
    rbc_k_eq6b(i, adj_start, adj_nbr, adj_k, bx, by, bz, inv_denom, sx, sy, sz, &gx, &gy, &gz);
    if (chebyshev) {
        ox[i] = omega * (gx - qx[i]) + qx[i];
        oy[i] = omega * (gy - qy[i]) + qy[i];
        oz[i] = omega * (gz - qz[i]) + qz[i];
        qx[i] = sx[i];
        qy[i] = sy[i];
        qz[i] = sz[i];
    } else {
        ox[i] = gx;
        oy[i] = gy;
        oz[i] = gz;
    }
}

/* Chebyshev's blend after a Gauss-Seidel iteration, one coordinate of particle i:
 * p = omega (p - q) + q with q = p^(k-1), and q becomes the stashed old value. */
RBC_HD void rbc_k_cheb_blend(uint32_t i, float omega, const uint8_t *pinned, float *p, float *q,
                             const float *old) {
    if (pinned[i]) return;
    p[i] = omega * (p[i] - q[i]) + q[i];
    q[i] = old[i];
}

/* Pin m on its path from where it was at the step's start to its target, reached at
 * the step's last substep (f = (substep + 1) / substeps). */
RBC_HD void rbc_k_pin(uint32_t m, const uint32_t *pin_idx, const float *pin_start,
                      const float *pin_target, float f, int last, float *px, float *py,
                      float *pz) {
    uint32_t i = pin_idx[m];
    float *p[3] = {px, py, pz};
    for (int a = 0; a < 3; ++a) {
        float st = pin_start[3 * m + a], tg = pin_target[3 * m + a];
        p[a][i] = last ? tg : st + (tg - st) * f;
    }
}

/* Whether particle i's position is finite (x - x is 0 exactly then, NaN otherwise). */
RBC_HD int rbc_k_finite(uint32_t i, const float *px, const float *py, const float *pz) {
    return (px[i] - px[i]) + (py[i] - py[i]) + (pz[i] - pz[i]) == 0.0f;
}
/* Whether spring s is within the blow-up bound: |p_a - p_b| <= max(stretch L_s, floor)
 * (a NaN compares true here: the finiteness check names it). */
RBC_HD int rbc_k_spring_ok(uint32_t s, const uint32_t *sa, const uint32_t *sb, const float *rest,
                           float stretch, float floor_len, const float *px, const float *py,
                           const float *pz) {
    uint32_t i = sa[s], j = sb[s];
    float ex = px[i] - px[j], ey = py[i] - py[j], ez = pz[i] - pz[j];
    float lim = stretch * rest[s];
    if (lim < floor_len) lim = floor_len;
    return !(ex * ex + ey * ey + ez * ez > lim * lim);
}
#endif
