/* measure_kernels.h -- per-element bodies of the measurements a step decides on:
 * the target mode's strain, the energy guard's energies and the pins' work, and the
 * guard's velocity scaling. Each backend sums them its own way (strain.c and
 * energy.c in fixed blocks, reassociated into vector lanes; the CUDA backend one
 * thread per block in order), so the sums agree to rounding, and each backend's sum
 * is the same for any thread count. */
#ifndef RBC_MEASURE_KERNELS_H
#define RBC_MEASURE_KERNELS_H
#include <math.h>
#include <stdint.h>

#include "rbc_hd.h"

/* Spring k's relative strain |p_a - p_b| / L - 1 in float, 0 for a spring that does
 * not count (live = 0: broken, or L = 0). strain.c gives its error bound. */
RBC_HD float rbc_k_rel_strain_f(float ex, float ey, float ez, float L, int live) {
    return live ? sqrtf(ex * ex + ey * ey + ez * ez) / L - 1.0f : 0.0f;
}

/* Particle i's terms of the energy guard's sums (energy.h), from position pos and
 * previous position prev, w = m/h^2, g gravity: kinetic w |v h|^2 (v h = pos - prev),
 * gravitational -m g . x (in double: it is large against the energies that move),
 * and the tolerance's m |x|_1, m |v h|_1 and w; pinned particles count 0. */
RBC_HD void rbc_k_energy_terms(uint32_t i, const float *X, const float *Y, const float *Z,
                               const float *QX, const float *QY, const float *QZ,
                               const float *W, const float *M, const uint8_t *pin, float gxf,
                               float gyf, float gzf, double *ke, double *ug, double *mag,
                               double *md, double *wsum) {
    float f = (float)(1 - (int)pin[i]);
    float vx = X[i] - QX[i], vy = Y[i] - QY[i], vz = Z[i] - QZ[i];
    float w = f * W[i], m = f * M[i];
    *ke += (double)(w * (vx * vx + vy * vy + vz * vz));
    *ug -= (double)m * ((double)gxf * X[i] + (double)gyf * Y[i] + (double)gzf * Z[i]);
    *mag += (double)(m * (fabsf(X[i]) + fabsf(Y[i]) + fabsf(Z[i])));
    *md += (double)(m * (fabsf(vx) + fabsf(vy) + fabsf(vz)));
    *wsum += (double)w;
}

/* Spring k's energy s/2 (|x_a - x_b| - L)^2 with each end at `after` if pinned, else
 * at `before` (the pins' work: after minus before). */
RBC_HD double rbc_k_spring_energy_at(uint32_t k, const uint32_t *sa, const uint32_t *sb,
                                     const float *rest, const float *stiff,
                                     const uint8_t *pinned, const float *bx, const float *by,
                                     const float *bz, const float *ax, const float *ay,
                                     const float *az) {
    uint32_t a = sa[k], b = sb[k];
    const float *pax = pinned[a] ? ax : bx, *pay = pinned[a] ? ay : by, *paz = pinned[a] ? az : bz;
    const float *pbx = pinned[b] ? ax : bx, *pby = pinned[b] ? ay : by, *pbz = pinned[b] ? az : bz;
    double ex = (double)pax[a] - pbx[b], ey = (double)pay[a] - pby[b],
           ez = (double)paz[a] - pbz[b];
    double v = sqrt(ex * ex + ey * ey + ez * ez) - rest[k];
    return 0.5 * stiff[k] * v * v;
}

/* The energy guard's clamp of free particle i: its previous position moves so that
 * the velocity is scaled by f and the position kept, prev = pos - f (pos - prev). */
RBC_HD void rbc_k_guard_scale(uint32_t i, float f, const uint8_t *pinned, const float *pos,
                              float *prev) {
    if (!pinned[i]) prev[i] = pos[i] - f * (pos[i] - prev[i]);
}
#endif
