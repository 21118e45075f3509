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

/* Eq. 6, one Gauss-Seidel update of free particle i, reading its neighbors' current
 * positions (the other color, already updated this sweep or not yet: red-black
 * ordering makes both Gauss-Seidel):
 *   p_i = (m_i/h^2 y_i + sum_j s_ij (p_j + d_ij)) / (m_i/h^2 + sum_j s_ij)
 * w[i] = m_i/h^2 (kg/s^2), inv_denom[i] = 1/(w_i + sum_j s_ij). */
RBC_HD void rbc_k_global(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                         const float *adj_k, const float *dx, const float *dy, const float *dz,
                         const float *w, const float *inv_denom, const float *yx,
                         const float *yy, const float *yz, float *px, float *py, float *pz) {
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
    px[i] = sx * r;
    py[i] = sy * r;
    pz[i] = sz * r;
}
#endif
