/* lattice_kernels.h -- the row bodies of the lattice fast path (lattice.h): Eq. 6
 * from b for a run of one color's particles in a row (Gauss-Seidel plain or SOR, and
 * Jacobi plain or Chebyshev), its scalar edge particles, and the fused local step +
 * right-hand side of a row's interior. Shared by the CPU's sweeps (lattice.c, which
 * keeps the scheduling: row bounds, the variants' dispatch, threads and the
 * wavefront) and device kernels. The arguments are a row's runs: the particles at
 * m, their left and right neighbours (the other color's run, one column apart), the
 * rows below and above (the other color, same column; a row of zeros beyond the
 * edges). */
#ifndef RBC_LATTICE_KERNELS_H
#define RBC_LATTICE_KERNELS_H
#include <math.h>
#include <stdint.h>

#include "rbc_hd.h"

/* The uniform free row's vector loop (rbc_k_lat_row_free) is written in GCC's vector
 * extension, which GCC and Clang have (clang-cl too) and MSVC's cl has not: there
 * (and wherever RBC_NO_VECTOR_EXT is defined, which is how GCC builds and tests this
 * path: core_lattice_fallback) such a row takes the path of every other row, the
 * scalar edges and rbc_k_lat_row_axis's loop, which sums the same terms in another
 * order. Nor under nvcc: the vector row is the CPU's alone, and a device runs the
 * scalar bodies. */
#if (defined(__GNUC__) || defined(__clang__)) && !defined(RBC_NO_VECTOR_EXT) && \
    !defined(__CUDACC__)
#define RBC_VECTOR_EXT 1
#else
#define RBC_VECTOR_EXT 0
#endif

/* The interior of a row: every particle has its left and right neighbour. The row
 * bodies are inlined into lattice.c's sweeps, which are cloned for AVX2 and AVX-512
 * and picked at load time (simd.h; the default is SSE2): one dispatch per sweep
 * instead of three indirect calls per row of 50 particles, whose set-up was a fifth
 * of the sweep's time at 10K. */

/* The three coordinates in one loop: the stiffnesses, b's row and the pins are read
 * once per particle. */
RBC_HD_INLINE void rbc_k_lat_row(uint32_t count, float *RBC_RESTRICT px, float *RBC_RESTRICT py,
                                 float *RBC_RESTRICT pz, const float *RBC_RESTRICT lx,
                                 const float *RBC_RESTRICT ly, const float *RBC_RESTRICT lz,
                                 const float *RBC_RESTRICT rx, const float *RBC_RESTRICT ry,
                                 const float *RBC_RESTRICT rz, const float *RBC_RESTRICT dx,
                                 const float *RBC_RESTRICT dy, const float *RBC_RESTRICT dz,
                                 const float *RBC_RESTRICT ux, const float *RBC_RESTRICT uy,
                                 const float *RBC_RESTRICT uz, const float *RBC_RESTRICT kl,
                                 const float *RBC_RESTRICT kr, const float *RBC_RESTRICT kd,
                                 const float *RBC_RESTRICT ku, const float *RBC_RESTRICT bx,
                                 const float *RBC_RESTRICT by, const float *RBC_RESTRICT bz,
                                 const float *RBC_RESTRICT inv, const uint8_t *RBC_RESTRICT pin,
                                 float omega, float kuni) {
    /* kuni != 0: every spring of the lattice has stiffness kuni (missing ones read a
     * zero row or are edge particles): the same arithmetic with a broadcast constant
     * instead of four streams of stiffness. */
#define RBC_ROW_BODY(LOADK, RELAX)                                                       \
    for (uint32_t m = 0; m < count; ++m) {                                               \
        LOADK                                                                            \
        float r = inv[m];                                                                \
        float gx = (bx[m] + a * lx[m] + b * rx[m] + c * dx[m] + d * ux[m]) * r;          \
        float gy = (by[m] + a * ly[m] + b * ry[m] + c * dy[m] + d * uy[m]) * r;          \
        float gz = (bz[m] + a * lz[m] + b * rz[m] + c * dz[m] + d * uz[m]) * r;          \
        float ox = px[m], oy = py[m], oz = pz[m];                                        \
        RELAX                                                                            \
        px[m] = rbc_keep_if(pin[m], ox, gx);                                                 \
        py[m] = rbc_keep_if(pin[m], oy, gy);                                                 \
        pz[m] = rbc_keep_if(pin[m], oz, gz);                                                 \
    }
#define RBC_K_ARRAYS float a = kl[m], b = kr[m], c = kd[m], d = ku[m];
#define RBC_K_UNIFORM float a = kuni, b = kuni, c = kuni, d = kuni;
#define RBC_SOR gx = ox + omega * (gx - ox); gy = oy + omega * (gy - oy); gz = oz + omega * (gz - oz);
    if (kuni != 0.0f) {
        if (omega == 0.0f) {
            RBC_ROW_BODY(RBC_K_UNIFORM, )
        } else {
            RBC_ROW_BODY(RBC_K_UNIFORM, RBC_SOR)
        }
    } else if (omega == 0.0f) {
        RBC_ROW_BODY(RBC_K_ARRAYS, )
    } else {
        RBC_ROW_BODY(RBC_K_ARRAYS, RBC_SOR)
    }
#undef RBC_K_ARRAYS
#undef RBC_K_UNIFORM
#undef RBC_SOR
#undef RBC_ROW_BODY
}

/* One coordinate of a row's interior with the uniform stiffness kuni: eight streams,
 * few enough to stay in registers (the three-coordinate loop spills on AVX2). */
RBC_HD_INLINE void rbc_k_lat_row_axis(uint32_t count, float *RBC_RESTRICT p,
                                      const float *RBC_RESTRICT l, const float *RBC_RESTRICT r,
                                      const float *RBC_RESTRICT d, const float *RBC_RESTRICT u,
                                      const float *RBC_RESTRICT b, const float *RBC_RESTRICT inv,
                                      const uint8_t *RBC_RESTRICT pin, float omega, float kuni) {
    if (omega == 0.0f) {
        for (uint32_t m = 0; m < count; ++m) {
            float gv = (b[m] + kuni * l[m] + kuni * r[m] + kuni * d[m] + kuni * u[m]) * inv[m];
            p[m] = rbc_keep_if(pin[m], p[m], gv);
        }
    } else {
        for (uint32_t m = 0; m < count; ++m) {
            float gv = (b[m] + kuni * l[m] + kuni * r[m] + kuni * d[m] + kuni * u[m]) * inv[m];
            float o = p[m];
            p[m] = rbc_keep_if(pin[m], o, o + omega * (gv - o));
        }
    }
}

/* The arrays a Gauss-Seidel edge particle reads and writes, behind one pointer: read
 * where used, they need no registers across the sweep (as rbc_k_lat_jacobi_arrays). */
typedef struct rbc_k_lat_gs_arrays {
    const uint8_t *pinned;
    const float *inv_denom;
    const float *b[3];
    float *p[3];
} rbc_k_lat_gs_arrays;

/* A row's edge particle, scalar: its one horizontal neighbour at index ih (stiffness
 * kh), the vertical ones at m of the rows below and above (zeros beyond the edges).
 * Straight-line code: the edges are 2 of every row's particles, a sixth of the sweep's
 * time at 10K before this was tightened. */
RBC_HD void rbc_k_lat_edge(const rbc_k_lat_gs_arrays *A, uint32_t i, uint32_t ih, float kh,
                           float kd, float ku, const float *const dn[3], const float *const up[3],
                           uint32_t m, float omega) {
    if (A->pinned[i]) return;
    float *px = A->p[0], *py = A->p[1], *pz = A->p[2];
    const float r = A->inv_denom[i];
    float gx = (A->b[0][i] + kh * px[ih] + kd * dn[0][m] + ku * up[0][m]) * r;
    float gy = (A->b[1][i] + kh * py[ih] + kd * dn[1][m] + ku * up[1][m]) * r;
    float gz = (A->b[2][i] + kh * pz[ih] + kd * dn[2][m] + ku * up[2][m]) * r;
    if (omega != 0.0f) {
        gx = px[i] + omega * (gx - px[i]);
        gy = py[i] + omega * (gy - py[i]);
        gz = pz[i] + omega * (gz - pz[i]);
    }
    px[i] = gx, py[i] = gy, pz[i] = gz;
}

#if RBC_VECTOR_EXT
/* Eight lanes of GCC's vector extension: ymm registers in the AVX2 and AVX-512
 * clones, two xmm in the SSE2 one. Unaligned loads and stores through memcpy. The
 * helpers are always inlined into the cloned sweeps, so no vector crosses a call. */
typedef float rbc_v8 __attribute__((vector_size(32)));
/* GCC warns of the vector return's ABI at the end of the translation unit, so this
 * stays off for the rest of it (nothing here passes a vector across a call). */
#pragma GCC diagnostic ignored "-Wpsabi"
RBC_HD_INLINE rbc_v8 rbc_ld8(const float *p) {
    rbc_v8 v;
    memcpy(&v, p, sizeof v);
    return v;
}
RBC_HD_INLINE void rbc_st8(float *p, rbc_v8 v) { memcpy(p, &v, sizeof v); }

typedef int32_t rbc_m8 __attribute__((vector_size(32)));

/* Eight particles from m of rbc_k_lat_row_free; keep_l and keep_r: all ones, or zero in
 * the lane of an edge particle, whose missing horizontal neighbour then reads +0. */
RBC_HD_INLINE rbc_v8 rbc_k_lat_free8(uint32_t m, const float *p, const float *l, const float *r,
                                     const float *d, const float *u, const float *b,
                                     const float *inv, rbc_v8 kv, float omega, rbc_m8 keep_l,
                                     rbc_m8 keep_r) {
    rbc_v8 lv = (rbc_v8)((rbc_m8)rbc_ld8(l + m) & keep_l);
    rbc_v8 rv = (rbc_v8)((rbc_m8)rbc_ld8(r + m) & keep_r);
    rbc_v8 s = (lv + rv) + (rbc_ld8(d + m) + rbc_ld8(u + m));
    rbc_v8 g = (rbc_ld8(b + m) + kv * s) * rbc_ld8(inv + m);
    if (omega == 0.0f) return g;
    rbc_v8 o = rbc_ld8(p + m);
    return o + omega * (g - o);
}

/* One coordinate of a whole row, edges included, with the uniform stiffness k and no
 * pin: g = (b + k ((l + r) + (d + u))) / denominator, and p = g, or p += omega (g - p)
 * (SOR). count >= 8. An edge particle (column 0 when left_edge, at m = 0; column
 * nx - 1 when right_edge, at m = count - 1) reads its missing neighbour as 0 (it was
 * read from the next row or the one before and masked away), so the same formula
 * gives its Eq. 6 with one horizontal spring. The last eight particles are computed
 * first and stored last: the loop's last vector overlaps them when count is not a
 * multiple of 8, and both computed the overlap from the same old values (a color's
 * particles read only the other color, b, the denominator and their own old
 * position), so both wrote the same. */
RBC_HD_INLINE void rbc_k_lat_row_free(uint32_t count, float *RBC_RESTRICT p, const float *l,
                                      const float *r, const float *d, const float *u,
                                      const float *b, const float *inv, float k, float omega,
                                      int left_edge, int right_edge) {
    const rbc_v8 kv = {k, k, k, k, k, k, k, k};
    const rbc_m8 all = {-1, -1, -1, -1, -1, -1, -1, -1};
    rbc_m8 first = all, last = all;
    first[0] = left_edge ? 0 : -1;
    last[7] = right_edge ? 0 : -1;
    const uint32_t t = count - 8;
    const rbc_v8 tail = rbc_k_lat_free8(t, p, l, r, d, u, b, inv, kv, omega, t ? all : first, last);
    if (t) rbc_st8(p, rbc_k_lat_free8(0, p, l, r, d, u, b, inv, kv, omega, first, all));
    for (uint32_t m = 8; m < t; m += 8)
        rbc_st8(p + m, rbc_k_lat_free8(m, p, l, r, d, u, b, inv, kv, omega, all, all));
    rbc_st8(p + t, tail);
}
#endif /* RBC_VECTOR_EXT */

/* One coordinate of a row's interior (both horizontal neighbours exist): the Jacobi
 * update in the CSR row's order, b + s_d d + s_l l + s_r r + s_u u, each term rounded
 * as rbc_k_eq6b rounds it. A row beyond the edge is g->nzeros: s * (-0) = -0 for any
 * s >= 0 (kuni > 0, or the array's 0), and x + (-0) == x for every float x, +0 and
 * NaN included (round to nearest, the default), so the missing term changes nothing
 * (+0 would turn a -0 sum into +0).
 * Stiffness kuni when uniform, else the per-direction arrays; q (prev) only with
 * cheb. */
RBC_HD_INLINE void rbc_k_lat_jacobi_row(uint32_t count, float *RBC_RESTRICT o,
                                        float *RBC_RESTRICT q, const float *RBC_RESTRICT s,
                                        const float *RBC_RESTRICT l, const float *RBC_RESTRICT r,
                                        const float *RBC_RESTRICT d, const float *RBC_RESTRICT u,
                                        const float *RBC_RESTRICT b, const float *RBC_RESTRICT inv,
                                        const uint8_t *RBC_RESTRICT pin,
                                        const float *RBC_RESTRICT kl, const float *RBC_RESTRICT kr,
                                        const float *RBC_RESTRICT kd, const float *RBC_RESTRICT ku,
                                        float kuni, float omega, const int uni, const int cheb) {
    for (uint32_t m = 0; m < count; ++m) {
        float acc = b[m];
        acc += (uni ? kuni : kd[m]) * d[m];
        acc += (uni ? kuni : kl[m]) * l[m];
        acc += (uni ? kuni : kr[m]) * r[m];
        acc += (uni ? kuni : ku[m]) * u[m];
        float gv = acc * inv[m];
        if (cheb) {
            gv = omega * (gv - q[m]) + q[m];
            q[m] = rbc_keep_if(pin[m], q[m], s[m]);
        }
        o[m] = rbc_keep_if(pin[m], s[m], gv); /* pinned: dst = src */
    }
}

/* The arrays a Jacobi edge particle reads besides src and dst, behind one pointer:
 * read where used, they need no registers across a row (passed one by one, they
 * spilled: 1.5% more instructions in the lattice Jacobi). */
typedef struct rbc_k_lat_jacobi_arrays {
    const float *kd, *kl, *kr, *ku, *inv_denom;
    const float *b[3];
    const uint8_t *pinned;
    float *prev[3];
} rbc_k_lat_jacobi_arrays;

/* A Jacobi particle of column 0 (has_l 0) or nx - 1 (has_r 0), scalar: rbc_k_eq6b's
 * sum over its existing neighbours (down, left, right, up at dn, lt, rt, up) of src S,
 * written to dst D as rbc_global_jacobi writes it (A->prev with cheb). */
RBC_HD_INLINE void rbc_k_lat_jacobi_edge(const rbc_k_lat_jacobi_arrays *A, float *const S[3],
                                         float *const D[3], uint32_t i, uint32_t dn,
                                         uint32_t lt, uint32_t rt, uint32_t up, int has_d,
                                         const int has_l, const int has_r, int has_u, int cheb,
                                         float omega) {
    if (A->pinned[i]) {
        for (int a = 0; a < 3; ++a) D[a][i] = S[a][i];
        return;
    }
    const float kd = A->kd[i], kl = A->kl[i], kr = A->kr[i], ku = A->ku[i];
    for (int a = 0; a < 3; ++a) {
        const float *p = S[a];
        float acc = A->b[a][i];
        if (has_d) acc += kd * p[dn];
        if (has_l) acc += kl * p[lt];
        if (has_r) acc += kr * p[rt];
        if (has_u) acc += ku * p[up];
        float gv = acc * A->inv_denom[i];
        if (cheb) {
            float *q = A->prev[a];
            D[a][i] = omega * (gv - q[i]) + q[i];
            q[i] = p[i];
        } else {
            D[a][i] = gv;
        }
    }
}

/* The interior of a row (left and right neighbours exist; rows beyond the edges read
 * zeros with stiffness 0 and rest length 0). Returns nonzero if some spring was
 * (near) zero length: the caller redoes the row in scalar with the rest-direction
 * fallback. With uni, the one stiffness kuni of every lattice spring instead of the
 * four stiffness streams (16 of the pass's ~84 bytes per particle, which is bound by
 * memory bandwidth at 1M particles): a missing neighbour's rest length 0 makes its
 * term k (e * 0) = 0 either way. */
RBC_HD_INLINE int rbc_k_lat_rhs_row(uint32_t count, const float *RBC_RESTRICT px,
                                    const float *RBC_RESTRICT py, const float *RBC_RESTRICT pz,
                                    const float *RBC_RESTRICT lx, const float *RBC_RESTRICT ly,
                                    const float *RBC_RESTRICT lz, const float *RBC_RESTRICT rx,
                                    const float *RBC_RESTRICT ry, const float *RBC_RESTRICT rz,
                                    const float *RBC_RESTRICT dx, const float *RBC_RESTRICT dy,
                                    const float *RBC_RESTRICT dz, const float *RBC_RESTRICT ux,
                                    const float *RBC_RESTRICT uy, const float *RBC_RESTRICT uz,
                                    const float *RBC_RESTRICT kl, const float *RBC_RESTRICT kr,
                                    const float *RBC_RESTRICT kd, const float *RBC_RESTRICT ku,
                                    const float *RBC_RESTRICT ll, const float *RBC_RESTRICT lr,
                                    const float *RBC_RESTRICT ld, const float *RBC_RESTRICT lu,
                                    const float *RBC_RESTRICT w, const float *RBC_RESTRICT yx,
                                    const float *RBC_RESTRICT yy, const float *RBC_RESTRICT yz,
                                    float *RBC_RESTRICT bx, float *RBC_RESTRICT by,
                                    float *RBC_RESTRICT bz, float kuni) {
    int bad = 0;
    /* KL..KU: the four stiffnesses of particle m (the streams, or kuni four times). */
#define RBC_DIR(NX, NY, NZ, KK, L)                                                         \
        {                                                                                  \
            float ex = x - NX[m], ey = y - NY[m], ez = z - NZ[m];                          \
            float len2 = ex * ex + ey * ey + ez * ez;                                      \
            bad |= len2 <= 1e-24f;                                                         \
            float fl = L[m] / sqrtf(len2), kk = KK;                                        \
            sx += kk * (ex * fl);                                                          \
            sy += kk * (ey * fl);                                                          \
            sz += kk * (ez * fl);                                                          \
        }
#define RBC_RHS_LOOP(KL, KR, KD, KU)                                                       \
    for (uint32_t m = 0; m < count; ++m) {                                                 \
        float x = px[m], y = py[m], z = pz[m], wi = w[m];                                  \
        float sx = wi * yx[m], sy = wi * yy[m], sz = wi * yz[m];                           \
        RBC_DIR(lx, ly, lz, KL, ll)                                                        \
        RBC_DIR(rx, ry, rz, KR, lr)                                                        \
        RBC_DIR(dx, dy, dz, KD, ld)                                                        \
        RBC_DIR(ux, uy, uz, KU, lu)                                                        \
        bx[m] = sx;                                                                        \
        by[m] = sy;                                                                        \
        bz[m] = sz;                                                                        \
    }
    if (kuni != 0.0f) {
        RBC_RHS_LOOP(kuni, kuni, kuni, kuni)
    } else {
        RBC_RHS_LOOP(kl[m], kr[m], kd[m], ku[m])
    }
#undef RBC_RHS_LOOP
#undef RBC_DIR
    return bad;
}
#endif
