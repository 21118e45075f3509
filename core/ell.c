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
