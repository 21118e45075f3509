/* ell_kernels.h -- the ELLPACK Gauss-Seidel update (Eq. 6 from b, as rbc_k_gs's
 * plain and SOR variants; the layout is ell.h's), shared by the CPU sweep (ell.c) and
 * a device kernel. Slot j of lane m of a chunk of len particles sits at
 * [offset + j * len + m]; padding slots have stiffness 0. */
#ifndef RBC_ELL_KERNELS_H
#define RBC_ELL_KERNELS_H
#include <stddef.h>
#include <stdint.h>

#include "rbc_hd.h"

enum { RBC_ELL_CHUNK = 64 }; /* 8 vectors of AVX2: a degree group of a window fills few chunks only partly */

/* Lanes [0, n) of a chunk (n <= RBC_ELL_CHUNK, slot stride `stride`, the chunk's
 * width slots each): accumulate slot by slot, then write p = g (omega == 0) or
 * p += omega (g - p); pinned lanes keep p. The host calls it for a whole chunk
 * (n = stride = len), so the slot loop's lanes are vector gathers; a device thread
 * calls it for one lane (n = 1, the pointers at that lane). Either way a particle's
 * sum is b + s_0 p_0 + s_1 p_1 + ... in slot order, so both round alike. The gathers
 * read only other colors (padding included), the stores come after them. */
RBC_HD_INLINE void rbc_k_ell_lanes(uint32_t n, uint32_t width, size_t stride,
                                   const uint32_t *RBC_RESTRICT nbr,
                                   const float *RBC_RESTRICT kk, const float *RBC_RESTRICT px,
                                   const float *RBC_RESTRICT py, const float *RBC_RESTRICT pz,
                                   const float *RBC_RESTRICT bx, const float *RBC_RESTRICT by,
                                   const float *RBC_RESTRICT bz, const float *RBC_RESTRICT inv,
                                   const uint8_t *RBC_RESTRICT pin, float *RBC_RESTRICT ox,
                                   float *RBC_RESTRICT oy, float *RBC_RESTRICT oz,
                                   float omega) {
    float ax[RBC_ELL_CHUNK], ay[RBC_ELL_CHUNK], az[RBC_ELL_CHUNK];
    for (uint32_t m = 0; m < n; ++m) {
        ax[m] = bx[m];
        ay[m] = by[m];
        az[m] = bz[m];
    }
    for (uint32_t j = 0; j < width; ++j) {
        const uint32_t *RBC_RESTRICT nj = nbr + j * stride;
        const float *RBC_RESTRICT kj = kk + j * stride;
        for (uint32_t m = 0; m < n; ++m) {
            uint32_t q = nj[m];
            float k = kj[m];
            ax[m] += k * px[q];
            ay[m] += k * py[q];
            az[m] += k * pz[q];
        }
    }
    if (omega == 0.0f) {
        for (uint32_t m = 0; m < n; ++m) {
            float r = inv[m];
            ox[m] = rbc_keep_if(pin[m], ox[m], ax[m] * r);
            oy[m] = rbc_keep_if(pin[m], oy[m], ay[m] * r);
            oz[m] = rbc_keep_if(pin[m], oz[m], az[m] * r);
        }
    } else {
        for (uint32_t m = 0; m < n; ++m) {
            float r = inv[m], x = ox[m], y = oy[m], z = oz[m];
            ox[m] = rbc_keep_if(pin[m], x, x + omega * (ax[m] * r - x));
            oy[m] = rbc_keep_if(pin[m], y, y + omega * (ay[m] * r - y));
            oz[m] = rbc_keep_if(pin[m], z, z + omega * (az[m] * r - z));
        }
    }
}

/* Particle t of a color of count particles, one lane of its chunk t / RBC_ELL_CHUNK:
 * what one device thread does. width and offset point at the color's first chunk,
 * b, inv, pin and o at its first particle; nbr and kk are the whole slot arrays. */
RBC_HD void rbc_k_ell_one(uint32_t t, uint32_t count, const uint32_t *width,
                          const size_t *offset, const uint32_t *nbr, const float *kk,
                          const float *px, const float *py, const float *pz, const float *bx,
                          const float *by, const float *bz, const float *inv,
                          const uint8_t *pin, float *ox, float *oy, float *oz, float omega) {
    const uint32_t ch = t / RBC_ELL_CHUNK, m = t % RBC_ELL_CHUNK;
    const uint32_t rest = count - ch * RBC_ELL_CHUNK;
    const uint32_t len = rest < RBC_ELL_CHUNK ? rest : RBC_ELL_CHUNK;
    const size_t at = offset[ch] + m;
    rbc_k_ell_lanes(1, width[ch], len, nbr + at, kk + at, px, py, pz, bx + t, by + t, bz + t,
                    inv + t, pin + t, ox + t, oy + t, oz + t, omega);
}
#endif
