/* ell.c -- the ELLPACK Gauss-Seidel sweep; see ell.h. */
#include "ell.h"

#include <string.h>

#include "report.h"
#include "simd.h"
#include "cloth_state.h"

void rbc_ell_free(rbc_ell *e, const rbc_allocator *a) {
    if (!e) return;
    rbc_mem_free(a, e->nbr, rbc_mul_size(e->slots, sizeof(uint32_t)));
    rbc_mem_free(a, e->k, rbc_mul_size(e->slots, sizeof(float)));
    rbc_mem_free(a, e->width, rbc_mul_size(e->nchunks, sizeof(uint32_t)));
    rbc_mem_free(a, e->offset, rbc_mul_size((size_t)e->nchunks + 1, sizeof(size_t)));
    rbc_mem_free(a, e->p4, rbc_mul_size(e->n4, 4 * sizeof(float)));
    rbc_mem_free(a, e, sizeof *e);
}

/* Chunk ch of color c: its first internal particle and its length. */
static uint32_t chunk_first(const rbc_ell *e, const rbc_topology *t, uint32_t c, uint32_t ch) {
    return t->color_start[c] + (ch - e->chunk_start[c]) * RBC_ELL_CHUNK;
}
static uint32_t chunk_len(const rbc_ell *e, const rbc_topology *t, uint32_t c, uint32_t ch) {
    uint32_t f = chunk_first(e, t, c, ch), end = t->color_start[c + 1];
    return end - f < RBC_ELL_CHUNK ? end - f : RBC_ELL_CHUNK;
}

/* The stiffness slot that mirrors internal particle i's j-th CSR slot. */
static float *ell_slot_k(rbc_ell *e, const rbc_topology *t, uint32_t i, uint32_t j) {
    uint32_t c = 0;
    while (c + 1 < t->ncolors && i >= t->color_start[c + 1]) ++c;
    const uint32_t m = i - t->color_start[c], ch = e->chunk_start[c] + m / RBC_ELL_CHUNK;
    return &e->k[e->offset[ch] + (size_t)j * chunk_len(e, t, c, ch) + m % RBC_ELL_CHUNK];
}

void rbc_ell_break_spring(rbc_ell *e, const rbc_topology *t, uint32_t sp) {
    uint32_t a = t->sa[sp], b = t->sb[sp];
    *ell_slot_k(e, t, a, t->he_a[sp] - t->adj_start[a]) = 0.0f;
    *ell_slot_k(e, t, b, t->he_b[sp] - t->adj_start[b]) = 0.0f;
}

int rbc_ell_build(const rbc_topology *t, const rbc_allocator *a, rbc_ell **out) {
    *out = NULL;
    if (t->ncolors < 2) return 0;
    rbc_ell h;
    memset(&h, 0, sizeof h);
    h.ncolors = t->ncolors;
    for (uint32_t c = 0; c < t->ncolors; ++c) {
        uint32_t cnt = t->color_start[c + 1] - t->color_start[c];
        h.chunk_start[c + 1] = h.chunk_start[c] + (cnt + RBC_ELL_CHUNK - 1) / RBC_ELL_CHUNK;
    }
    h.nchunks = h.chunk_start[t->ncolors];
    rbc_ell *e = rbc_mem_alloc(a, sizeof *e);
    if (!e) return -1;
    *e = h;
    e->width = rbc_mem_alloc(a, rbc_mul_size(h.nchunks, sizeof(uint32_t)));
    e->offset = rbc_mem_alloc(a, rbc_mul_size((size_t)h.nchunks + 1, sizeof(size_t)));
    if (!e->width || !e->offset) {
        rbc_ell_free(e, a);
        return -1;
    }
    size_t slots = 0, used = 2 * (size_t)t->ns;
    for (uint32_t c = 0; c < t->ncolors; ++c)
        for (uint32_t ch = h.chunk_start[c]; ch < h.chunk_start[c + 1]; ++ch) {
            const uint32_t f = chunk_first(e, t, c, ch), len = chunk_len(e, t, c, ch);
            uint32_t w = 0;
            for (uint32_t i = f; i < f + len; ++i) {
                uint32_t d = t->adj_start[i + 1] - t->adj_start[i];
                if (d > w) w = d;
            }
            e->width[ch] = w;
            e->offset[ch] = slots;
            slots += (size_t)w * len;
        }
    e->offset[h.nchunks] = slots;
    if (slots > 2 * used + 64) { /* a few hubs: padding would cost more */
        rbc_ell_free(e, a);
        return 0;
    }
    e->slots = slots;
    e->nbr = rbc_mem_alloc(a, rbc_mul_size(slots, sizeof(uint32_t)));
    e->k = rbc_mem_alloc(a, rbc_mul_size(slots, sizeof(float))); /* zero-filled */
    if (!e->nbr || !e->k) {
        rbc_ell_free(e, a);
        return -1;
    }
    e->bytes = sizeof *e + slots * (sizeof(uint32_t) + sizeof(float)) +
               h.nchunks * (sizeof(uint32_t) + sizeof(size_t)) + sizeof(size_t);
    for (uint32_t c = 0; c < t->ncolors; ++c) {
        /* Padding reads a particle of another color (never written in this sweep). */
        const uint32_t pad = c == 0 ? t->color_start[1] : 0;
        for (uint32_t ch = h.chunk_start[c]; ch < h.chunk_start[c + 1]; ++ch) {
            const uint32_t f = chunk_first(e, t, c, ch), len = chunk_len(e, t, c, ch);
            uint32_t *nb = e->nbr + e->offset[ch];
            float *kk = e->k + e->offset[ch];
            for (uint32_t m = 0; m < len; ++m) {
                uint32_t i = f + m, j = 0;
                for (uint32_t s = t->adj_start[i]; s < t->adj_start[i + 1]; ++s, ++j) {
                    nb[(size_t)j * len + m] = t->adj_nbr[s];
                    kk[(size_t)j * len + m] = t->adj_k[s];
                }
                for (; j < e->width[ch]; ++j) nb[(size_t)j * len + m] = pad;
            }
        }
    }
    /* The packed positions (rbc_ell_pack), 16 bytes a particle. */
    e->n4 = t->n;
    e->p4 = rbc_mem_alloc(a, rbc_mul_size(t->n, 4 * sizeof(float)));
    if (!e->p4) {
        rbc_ell_free(e, a);
        return -1;
    }
    e->bytes += (size_t)t->n * 4 * sizeof(float);
    *out = e;
    return 1;
}

/* The shared body (kernels/ell_kernels.h) over a whole chunk, cloned here for AVX2 and
 * AVX-512 (simd.h): it is inlined into each clone, whose gathers it vectorizes. */
RBC_VECTOR_CLONES
static void ell_chunk(uint32_t len, uint32_t width, size_t stride, const uint32_t *restrict nbr,
                      const float *restrict kk, const float *restrict px,
                      const float *restrict py, const float *restrict pz,
                      const float *restrict bx, const float *restrict by,
                      const float *restrict bz, const float *restrict inv,
                      const uint8_t *restrict pin, float *restrict ox, float *restrict oy,
                      float *restrict oz, float omega) {
    rbc_k_ell_lanes(len, width, stride, nbr, kk, px, py, pz, bx, by, bz, inv, pin, ox, oy, oz,
                    omega);
}

void rbc_ell_sweep(const rbc_ell *e, rbc_cloth_state *c, uint32_t color, float omega,
                   uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    const uint32_t c0 = e->chunk_start[color];
    uint32_t b, en;
    rbc_split(e->chunk_start[color + 1] - c0, tid, nt, &b, &en);
    for (uint32_t ch = c0 + b; ch < c0 + en; ++ch) {
        const uint32_t len = chunk_len(e, t, color, ch), i = chunk_first(e, t, color, ch);
        /* The gathers read p through a const pointer of the whole array; the stores
         * go through ox/oy/oz at this chunk's range, after every gather of the chunk. */
        ell_chunk(len, e->width[ch], len, e->nbr + e->offset[ch], e->k + e->offset[ch], c->p[0],
                  c->p[1], c->p[2], c->bx + i, c->by + i, c->bz + i, c->inv_denom + i,
                  c->pinned + i, c->p[0] + i, c->p[1] + i, c->p[2] + i, omega);
    }
}

void rbc_ell_pack(rbc_ell *e, const rbc_cloth_state *c, uint32_t tid, uint32_t nt) {
    uint32_t b, en;
    rbc_split(c->topo.n, tid, nt, &b, &en);
    const float *restrict px = c->p[0], *restrict py = c->p[1], *restrict pz = c->p[2];
    float *restrict q = e->p4;
    for (uint32_t i = b; i < en; ++i) {
        q[4 * (size_t)i] = px[i];
        q[4 * (size_t)i + 1] = py[i];
        q[4 * (size_t)i + 2] = pz[i];
        q[4 * (size_t)i + 3] = 0.0f;
    }
}

/* rbc_k_ell_lanes over a chunk with the neighbours read from p4, each lane's sums
 * in rbc_k_ell_lanes's order and operations, so bitwise its result. The chunk's new
 * values go to its range of p (ox, oy, oz) and of p4 (o4); all reads are of other
 * colors. ell_lanes_packed is the plain form: one lane at a time (the tail of a
 * color's last chunk, and compilers without the vector extension). */
static inline void ell_lanes_packed(uint32_t m0, uint32_t len, uint32_t width,
                                    const uint32_t *restrict nbr, const float *restrict kk,
                                    const float *restrict p4, const float *restrict bx,
                                    const float *restrict by, const float *restrict bz,
                                    const float *restrict inv, const uint8_t *restrict pin,
                                    float *restrict ox, float *restrict oy,
                                    float *restrict oz, float *restrict o4, float omega) {
    for (uint32_t m = m0; m < len; ++m) {
        float a[3] = {bx[m], by[m], bz[m]}, o[3] = {ox[m], oy[m], oz[m]};
        for (uint32_t j = 0; j < width; ++j) {
            const size_t s = (size_t)j * len + m;
            for (int l = 0; l < 3; ++l) a[l] += kk[s] * p4[4 * (size_t)nbr[s] + l];
        }
        for (int l = 0; l < 3; ++l) {
            float g = a[l] * inv[m];
            if (omega != 0.0f) g = o[l] + omega * (g - o[l]);
            o4[4 * (size_t)m + l] = rbc_keep_if(pin[m], o[l], g);
        }
        ox[m] = o4[4 * (size_t)m];
        oy[m] = o4[4 * (size_t)m + 1];
        oz[m] = o4[4 * (size_t)m + 2];
    }
}

#if defined(__has_builtin)
#if __has_builtin(__builtin_shufflevector) && !defined(RBC_NO_VECTOR_EXT)
#define ELL_PACKED_V8 1
#endif
#endif

#ifdef ELL_PACKED_V8
/* Eight lanes at a time in GCC's and Clang's vector extension (ymm in the AVX2 and
 * AVX-512 clones): per slot, the 8 neighbours' xyzw are 8 16-byte loads paired into
 * 4 vectors {P(m+r) | P(m+r+4)} and transposed into x, y and z by 6 shuffles (the
 * 4x4 transpose of each half), where the SoA layout needs 24 scalar loads merged
 * lane by lane. The results go back to p4 by the inverse transpose. */
typedef float ell_v4 __attribute__((vector_size(16)));
typedef float ell_v8 __attribute__((vector_size(32)));
typedef int32_t ell_m8 __attribute__((vector_size(32)));
#pragma GCC diagnostic ignored "-Wpsabi" /* no vector crosses a call: all inlined */
static inline ell_v4 ell_ld4(const float *p) {
    ell_v4 v;
    memcpy(&v, p, sizeof v);
    return v;
}
static inline ell_v8 ell_ld8(const float *p) {
    ell_v8 v;
    memcpy(&v, p, sizeof v);
    return v;
}
static inline ell_v8 ell_pair(const float *lo, const float *hi) {
    return __builtin_shufflevector(ell_ld4(lo), ell_ld4(hi), 0, 1, 2, 3, 4, 5, 6, 7);
}
#define ELL_LO(a, b) __builtin_shufflevector(a, b, 0, 8, 1, 9, 4, 12, 5, 13)   /* unpcklps */
#define ELL_HI(a, b) __builtin_shufflevector(a, b, 2, 10, 3, 11, 6, 14, 7, 15) /* unpckhps */
#define ELL_LH(a, b) __builtin_shufflevector(a, b, 0, 1, 8, 9, 4, 5, 12, 13)   /* movlhps */
#define ELL_HL(a, b) __builtin_shufflevector(a, b, 2, 3, 10, 11, 6, 7, 14, 15) /* movhlps */

#endif

#ifdef ELL_PACKED_V8
RBC_VECTOR_CLONES
#endif
static void ell_chunk_packed(uint32_t len, uint32_t width, const uint32_t *restrict nbr,
                             const float *restrict kk, const float *restrict p4,
                             const float *restrict bx, const float *restrict by,
                             const float *restrict bz, const float *restrict inv,
                             const uint8_t *restrict pin, float *restrict ox,
                             float *restrict oy, float *restrict oz, float *restrict o4,
                             float omega) {
    uint32_t m = 0;
#ifdef ELL_PACKED_V8
    for (; m + 8 <= len; m += 8) {
        ell_v8 ax = ell_ld8(bx + m), ay = ell_ld8(by + m), az = ell_ld8(bz + m);
        for (uint32_t j = 0; j < width; ++j) {
            const uint32_t *restrict q = nbr + (size_t)j * len + m;
            const ell_v8 r0 = ell_pair(p4 + 4 * (size_t)q[0], p4 + 4 * (size_t)q[4]);
            const ell_v8 r1 = ell_pair(p4 + 4 * (size_t)q[1], p4 + 4 * (size_t)q[5]);
            const ell_v8 r2 = ell_pair(p4 + 4 * (size_t)q[2], p4 + 4 * (size_t)q[6]);
            const ell_v8 r3 = ell_pair(p4 + 4 * (size_t)q[3], p4 + 4 * (size_t)q[7]);
            const ell_v8 t0 = ELL_LO(r0, r1), t1 = ELL_LO(r2, r3);
            const ell_v8 t2 = ELL_HI(r0, r1), t3 = ELL_HI(r2, r3);
            const ell_v8 k = ell_ld8(kk + (size_t)j * len + m);
            ax += k * ELL_LH(t0, t1);
            ay += k * ELL_HL(t0, t1);
            az += k * ELL_LH(t2, t3);
        }
        const ell_v8 r = ell_ld8(inv + m);
        const ell_v8 x = ell_ld8(ox + m), y = ell_ld8(oy + m), z = ell_ld8(oz + m);
        ell_v8 gx = ax * r, gy = ay * r, gz = az * r;
        if (omega != 0.0f) {
            gx = x + omega * (gx - x);
            gy = y + omega * (gy - y);
            gz = z + omega * (gz - z);
        }
        ell_m8 keep;
        for (int l = 0; l < 8; ++l) keep[l] = -(int32_t)(pin[m + l] != 0);
        gx = (ell_v8)(((ell_m8)x & keep) | ((ell_m8)gx & ~keep));
        gy = (ell_v8)(((ell_m8)y & keep) | ((ell_m8)gy & ~keep));
        gz = (ell_v8)(((ell_m8)z & keep) | ((ell_m8)gz & ~keep));
        memcpy(ox + m, &gx, sizeof gx);
        memcpy(oy + m, &gy, sizeof gy);
        memcpy(oz + m, &gz, sizeof gz);
        /* Back to xyzw: u = {P(m+r) | P(m+r+4)}. */
        const ell_v8 w = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
        const ell_v8 s0 = ELL_LO(gx, gy), s1 = ELL_LO(gz, w);
        const ell_v8 s2 = ELL_HI(gx, gy), s3 = ELL_HI(gz, w);
        const ell_v8 u[4] = {ELL_LH(s0, s1), ELL_HL(s0, s1), ELL_LH(s2, s3), ELL_HL(s2, s3)};
        float *restrict d = o4 + 4 * (size_t)m;
        for (int l = 0; l < 4; ++l) {
            const ell_v4 lo = __builtin_shufflevector(u[l], u[l], 0, 1, 2, 3);
            const ell_v4 hi = __builtin_shufflevector(u[l], u[l], 4, 5, 6, 7);
            memcpy(d + 4 * l, &lo, sizeof lo);
            memcpy(d + 16 + 4 * l, &hi, sizeof hi);
        }
    }
#endif
    ell_lanes_packed(m, len, width, nbr, kk, p4, bx, by, bz, inv, pin, ox, oy, oz, o4, omega);
}

void rbc_ell_sweep_packed(rbc_ell *e, rbc_cloth_state *c, uint32_t color, float omega,
                          uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    const uint32_t c0 = e->chunk_start[color];
    uint32_t b, en;
    rbc_split(e->chunk_start[color + 1] - c0, tid, nt, &b, &en);
    for (uint32_t ch = c0 + b; ch < c0 + en; ++ch) {
        const uint32_t len = chunk_len(e, t, color, ch), i = chunk_first(e, t, color, ch);
        ell_chunk_packed(len, e->width[ch], e->nbr + e->offset[ch], e->k + e->offset[ch], e->p4,
                         c->bx + i, c->by + i, c->bz + i, c->inv_denom + i, c->pinned + i,
                         c->p[0] + i, c->p[1] + i, c->p[2] + i, e->p4 + 4 * (size_t)i, omega);
    }
}
