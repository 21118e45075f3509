/* global.c -- the global step's iterative solvers on the generic CSR rows of the
 * topology (global.h); sweep.c chooses when the lattice or ELLPACK layouts run
 * instead. */
#include "global.h"

#include <math.h>
#include <string.h>

#include "kernels/pd_kernels.h"
#include "report.h"


void rbc_global_rhs(rbc_cloth_state *c, uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    uint32_t b, e;
    rbc_split(t->n, tid, nt, &b, &e);
    for (uint32_t i = b; i < e; ++i)
        rbc_k_rhs(i, t->adj_start, t->adj_k, c->dx, c->dy, c->dz, c->w, c->y[0], c->y[1],
                  c->y[2], c->bx, c->by, c->bz);
}

void rbc_csr_gs_color(rbc_cloth_state *c, uint32_t color, rbc_gs_variant v, float omega,
                      uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    if (color >= t->ncolors) return;
    uint32_t c0 = t->color_start[color], count = t->color_start[color + 1] - c0;
    uint32_t b, e;
    rbc_split(count, tid, nt, &b, &e);
    /* Local copies: stores to p must not force reloads of these pointers. */
    const uint32_t *restrict adj_start = t->adj_start, *restrict adj_nbr = t->adj_nbr;
    const float *restrict adj_k = t->adj_k, *restrict bx = c->bx, *restrict by = c->by,
                          *restrict bz = c->bz, *restrict inv_denom = c->inv_denom;
    const uint8_t *restrict pinned = c->pinned;
    float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
    float *sx = c->alt[0], *sy = c->alt[1], *sz = c->alt[2];
    /* rbc_gs_variant numbers the kernel's variants (asserted below). */
    for (uint32_t i = c0 + b; i < c0 + e; ++i)
        rbc_k_gs(i, (int)v, omega, adj_start, adj_nbr, adj_k, bx, by, bz, inv_denom, pinned, px,
                 py, pz, sx, sy, sz);
}

_Static_assert(RBC_GS_PLAIN == RBC_K_GS_PLAIN && RBC_GS_SOR == RBC_K_GS_SOR &&
                   RBC_GS_STASH == RBC_K_GS_STASH,
               "rbc_gs_variant numbers the kernel's variants");

void rbc_global_chebyshev_blend(rbc_cloth_state *c, float omega, uint32_t tid, uint32_t nt) {
    uint32_t b, e;
    rbc_split(c->topo.n, tid, nt, &b, &e);
    for (int a = 0; a < 3; ++a)
        for (uint32_t i = b; i < e; ++i)
            rbc_k_cheb_blend(i, omega, c->pinned, c->p[a], c->prev[a], c->alt[a]);
}

void rbc_csr_jacobi(rbc_cloth_state *c, float *const src[3], float *const dst[3], int chebyshev,
                    float omega, uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    uint32_t b, e;
    rbc_split(t->n, tid, nt, &b, &e);
    const uint8_t *pinned = c->pinned;
    const float *sx = src[0], *sy = src[1], *sz = src[2];
    float *ox = dst[0], *oy = dst[1], *oz = dst[2];
    float *qx = c->prev[0], *qy = c->prev[1], *qz = c->prev[2];
    for (uint32_t i = b; i < e; ++i)
        rbc_k_jacobi(i, chebyshev, omega, t->adj_start, t->adj_nbr, t->adj_k, c->bx, c->by, c->bz,
                     c->inv_denom, pinned, sx, sy, sz, ox, oy, oz, qx, qy, qz);
}

void rbc_csr_gs_serial(rbc_cloth_state *c) {
    const rbc_topology *t = &c->topo;
    for (uint32_t v = 0; v < t->n; ++v) {
        uint32_t i = t->to_internal[v];
        if (c->pinned[i]) continue;
        float gx, gy, gz;
        rbc_k_eq6b(i, t->adj_start, t->adj_nbr, t->adj_k, c->bx, c->by, c->bz, c->inv_denom,
                   c->p[0], c->p[1], c->p[2], &gx, &gy, &gz);
        c->p[0][i] = gx;
        c->p[1][i] = gy;
        c->p[2][i] = gz;
    }
}

void rbc_global_residual(const rbc_cloth_state *c, uint32_t color_end, uint32_t tid,
                         uint32_t nt, double *r2, double *b2) {
    const rbc_topology *t = &c->topo;
    if (color_end > t->ncolors) color_end = t->ncolors;
    uint32_t b, e;
    rbc_split(t->color_start[color_end], tid, nt, &b, &e);
    double r = 0.0, bb = 0.0;
    for (uint32_t i = b; i < e; ++i) {
        if (c->pinned[i]) continue;
        rbc_k_residual(i, t->adj_start, t->adj_nbr, t->adj_k, c->bx, c->by, c->bz,
                       c->inv_denom, c->p[0], c->p[1], c->p[2], c->pinned, &r, &bb);
    }
    *r2 += r;
    *b2 += bb;
}

float rbc_chebyshev_omega(uint32_t k, uint32_t delay, float rho) {
    if (k < delay) return 1.0f;
    float r2 = rho * rho;
    float omega = 2.0f / (2.0f - r2);
    for (uint32_t j = delay + 1; j <= k; ++j) omega = 4.0f / (4.0f - r2 * omega);
    return omega;
}

/* Power iteration on the Jacobi iteration matrix J = D^-1 N of the free particles'
 * system (the same matrix for x, y and z): e <- J e. J is similar to the symmetric
 * D^-1/2 N D^-1/2, so in the D-weighted norm |e|_D^2 = sum_i D_i e_i^2 the one-step
 * ratio |J e|_D / |e|_D approaches rho_J from below (an underestimate is the safe side
 * for Chebyshev weights and SOR's omega). Its spectrum is symmetric for a bipartite
 * graph (+-rho), so the norm ratio, not a Rayleigh quotient, is the estimate. */
float rbc_global_spectral_radius(rbc_cloth_state *c, float h) {
    if (c->rho_est > 0.0f && c->h_rho == h) return c->rho_est;
    for (int k = 0; k < RBC_RHO_CACHE; ++k)
        if (c->rho_cache_h[k] == h && h > 0.0f) {
            c->rho_est = c->rho_cache_v[k];
            c->h_rho = h;
            return c->rho_est;
        }
    const rbc_topology *t = &c->topo;
    /* e and its image live in the Jacobi scratch (alt) when present, else in y's x
     * and y components: the estimate runs before a step, which rewrites y anyway
     * (the residual in stats, which reads y, is marked stale meanwhile). */
    float *e = c->alt[0] ? c->alt[0] : c->y[0];
    float *f = c->alt[1] ? c->alt[1] : c->y[1];
    if (!c->alt[0]) c->system_valid = 0;
    uint32_t seed = 0x9E3779B9u;
    for (uint32_t i = 0; i < t->n; ++i) {
        seed = seed * 1664525u + 1013904223u;
        e[i] = c->pinned[i] ? 0.0f : 0.5f + (float)(seed >> 8) / 16777216.0f;
    }
    double ratio = 0.0;
    for (int it = 0; it < 150; ++it) {
        double n_e = 0.0, n_f = 0.0;
        for (uint32_t i = 0; i < t->n; ++i) {
            if (c->pinned[i]) {
                f[i] = 0.0f;
                continue;
            }
            float acc = 0.0f;
            for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; ++k)
                acc += t->adj_k[k] * e[t->adj_nbr[k]];
            f[i] = acc * c->inv_denom[i];
            double Dii = 1.0 / c->inv_denom[i];
            n_e += Dii * e[i] * e[i];
            n_f += Dii * f[i] * f[i];
        }
        ratio = n_e > 0.0 ? sqrt(n_f / n_e) : 0.0;
        /* Renormalise to keep the floats in range. */
        float scale = n_f > 0.0 ? (float)(1.0 / sqrt(n_f)) : 0.0f;
        for (uint32_t i = 0; i < t->n; ++i) e[i] = f[i] * scale;
    }
    float rho = (float)ratio;
    if (!(rho > 0.0f)) rho = 0.0f;
    if (rho >= 1.0f) rho = 0.9999f; /* D^-1 N of an SPD, diagonally dominant A: < 1 */
    c->rho_est = rho;
    c->h_rho = h;
    c->rho_cache_h[c->rho_cache_next] = h;
    c->rho_cache_v[c->rho_cache_next] = rho;
    c->rho_cache_next = (c->rho_cache_next + 1) % RBC_RHO_CACHE;
    return rho;
}
