/* lattice.c -- the lattice fast path of the Gauss-Seidel sweep; see lattice.h. */
#include "lattice.h"

#include <math.h>
#include <string.h>

#include "cpu/pool.h"
#include "report.h"
#include "simd.h"
#include "cloth_state.h"
#include "kernels/lattice_kernels.h"

/* Inlined into its callers (with constant flags where they pass them) (GCC and Clang,
 * MSVC's __forceinline; elsewhere an ordinary inline, the same arithmetic). */
#if defined(__GNUC__) || defined(__clang__)
#define RBC_ALWAYS_INLINE static inline __attribute__((always_inline))
#elif defined(_MSC_VER)
#define RBC_ALWAYS_INLINE static __forceinline
#else
#define RBC_ALWAYS_INLINE static inline
#endif

/* RBC_VECTOR_EXT: kernels/lattice_kernels.h. */

/* The wavefront's progress counters: an acquire load and a release store of an aligned
 * uint32_t. GCC and Clang: their builtins. MSVC on x86 and x64: the hardware orders
 * loads as acquires and stores as releases (TSO) and an aligned 32-bit volatile access
 * is one instruction, so only the compiler must be kept from moving other accesses
 * across it (_ReadWriteBarrier). MSVC on ARM64: a full barrier (DMB ISH) after the
 * load and before the store, as MSVC's own <atomic> did there; volatile itself orders
 * nothing under ARM64's default /volatile:iso. (Neither MSVC branch is compiled
 * here: README.md, "Windows".) */
#if defined(__GNUC__) || defined(__clang__)
#define RBC_LOAD_ACQUIRE(p) __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define RBC_STORE_RELEASE(p, v) __atomic_store_n((p), (v), __ATOMIC_RELEASE)
#elif defined(_MSC_VER) && (defined(_M_X64) || defined(_M_IX86))
#include <intrin.h>
static __forceinline uint32_t rbc_load_acquire(volatile uint32_t *p) {
    uint32_t v = *p;
    _ReadWriteBarrier();
    return v;
}
static __forceinline void rbc_store_release(volatile uint32_t *p, uint32_t v) {
    _ReadWriteBarrier();
    *p = v;
}
#define RBC_LOAD_ACQUIRE(p) rbc_load_acquire(p)
#define RBC_STORE_RELEASE(p, v) rbc_store_release((p), (v))
#elif defined(_MSC_VER) && defined(_M_ARM64)
#include <intrin.h>
static __forceinline uint32_t rbc_load_acquire(volatile uint32_t *p) {
    uint32_t v = (uint32_t)__iso_volatile_load32((const volatile __int32 *)p);
    __dmb(0xB); /* _ARM64_BARRIER_ISH */
    return v;
}
static __forceinline void rbc_store_release(volatile uint32_t *p, uint32_t v) {
    __dmb(0xB);
    __iso_volatile_store32((volatile __int32 *)p, (__int32)v);
}
#define RBC_LOAD_ACQUIRE(p) rbc_load_acquire(p)
#define RBC_STORE_RELEASE(p, v) rbc_store_release((p), (v))
#else
#error "lattice.c: no acquire load / release store for this compiler"
#endif

/* First column of color c in row j, and the number of such columns. */
static uint32_t first_col(const rbc_lattice *g, uint32_t c, uint32_t j) {
    return (c + j + g->c0) & 1u;
}
static uint32_t row_count(const rbc_lattice *g, uint32_t c, uint32_t j) {
    uint32_t f = first_col(g, c, j);
    return f < g->nx ? (g->nx - f + 1) / 2 : 0;
}

void rbc_lattice_free(rbc_lattice *g, const rbc_allocator *a) {
    if (!g) return;
    size_t n = (size_t)g->nx * g->ny;
    rbc_mem_free(a, g->row_first[0], sizeof(uint32_t) * (g->ny + 1));
    rbc_mem_free(a, g->row_first[1], sizeof(uint32_t) * (g->ny + 1));
    rbc_mem_free(a, g->kl, sizeof(float) * n);
    rbc_mem_free(a, g->kr, sizeof(float) * n);
    rbc_mem_free(a, g->kd, sizeof(float) * n);
    rbc_mem_free(a, g->ku, sizeof(float) * n);
    rbc_mem_free(a, g->ll, sizeof(float) * n);
    rbc_mem_free(a, g->lr, sizeof(float) * n);
    rbc_mem_free(a, g->ld, sizeof(float) * n);
    rbc_mem_free(a, g->lu, sizeof(float) * n);
    rbc_mem_free(a, g->zeros, sizeof(float) * (g->nx / 2 + 2));
    rbc_mem_free(a, g->nzeros, sizeof(float) * (g->nx / 2 + 2));
    rbc_mem_free(a, g, sizeof *g);
}

int rbc_lattice_detect(const rbc_topology *t, const rbc_allocator *a, rbc_lattice **out) {
    *out = NULL;
    const uint32_t n = t->n;
    if (t->ncolors != 2 || n < 2) return 0;
    /* nx from host vertex 0: its neighbours are 1 and nx (or only 1: one row). */
    uint32_t i0 = t->to_internal[0], nx = 0;
    for (uint32_t k = t->adj_start[i0]; k < t->adj_start[i0 + 1]; ++k) {
        uint32_t u = t->to_host[t->adj_nbr[k]];
        if (u > nx) nx = u;
    }
    if (nx == 1) nx = n;
    if (nx < 2 || n % nx) return 0;
    uint32_t ny = n / nx;
    rbc_lattice g;
    memset(&g, 0, sizeof g);
    g.nx = nx;
    g.ny = ny;
    g.c0 = i0 < t->color_start[1] ? 0u : 1u;
    /* The coloring and the internal order must be the lattice's. */
    for (uint32_t c = 0; c < 2; ++c) {
        uint32_t total = 0;
        for (uint32_t j = 0; j < ny; ++j) total += row_count(&g, c, j);
        if (total != t->color_start[c + 1] - t->color_start[c]) return 0;
    }
    for (uint32_t v = 0; v < n; ++v) {
        uint32_t col = v % nx, row = v / nx, c = (col + row + g.c0) & 1u;
        uint32_t i = t->to_internal[v];
        if (i < t->color_start[c] || i >= t->color_start[c + 1]) return 0;
    }
    rbc_lattice *h = rbc_mem_alloc(a, sizeof *h);
    if (!h) return -1;
    *h = g;
    h->row_first[0] = rbc_mem_alloc(a, sizeof(uint32_t) * (ny + 1));
    h->row_first[1] = rbc_mem_alloc(a, sizeof(uint32_t) * (ny + 1));
    h->kl = rbc_mem_alloc(a, sizeof(float) * n);
    h->kr = rbc_mem_alloc(a, sizeof(float) * n);
    h->kd = rbc_mem_alloc(a, sizeof(float) * n);
    h->ku = rbc_mem_alloc(a, sizeof(float) * n);
    h->ll = rbc_mem_alloc(a, sizeof(float) * n);
    h->lr = rbc_mem_alloc(a, sizeof(float) * n);
    h->ld = rbc_mem_alloc(a, sizeof(float) * n);
    h->lu = rbc_mem_alloc(a, sizeof(float) * n);
    h->zeros = rbc_mem_alloc(a, sizeof(float) * (nx / 2 + 2)); /* zero-filled */
    h->nzeros = rbc_mem_alloc(a, sizeof(float) * (nx / 2 + 2));
    if (!h->row_first[0] || !h->row_first[1] || !h->kl || !h->kr || !h->kd || !h->ku ||
        !h->ll || !h->lr || !h->ld || !h->lu || !h->zeros || !h->nzeros) {
        rbc_lattice_free(h, a);
        return -1;
    }
    for (uint32_t m = 0; m < nx / 2 + 2; ++m) h->nzeros[m] = -0.0f;
    h->bytes = sizeof *h + 2 * sizeof(uint32_t) * (ny + 1) + 8 * sizeof(float) * (size_t)n +
               2 * sizeof(float) * (nx / 2 + 2);
    for (uint32_t c = 0; c < 2; ++c) {
        uint32_t at = t->color_start[c];
        for (uint32_t j = 0; j < ny; ++j) {
            h->row_first[c][j] = at;
            at += row_count(h, c, j);
        }
        h->row_first[c][ny] = at;
    }
    /* Every particle where the stencil says ... */
    for (uint32_t v = 0; v < n; ++v) {
        uint32_t col = v % nx, row = v / nx, c = (col + row + h->c0) & 1u;
        if (t->to_internal[v] != h->row_first[c][row] + (col - first_col(h, c, row)) / 2)
            goto not_grid;
    }
    /* ... and every spring a stencil direction: (v, v + 1) in a row or (v, v + nx).
     * Springs are unique (topology.c), so each direction is set at most once; the
     * rest length is the spring's own. */
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t ia = t->sa[k], ib = t->sb[k];
        uint32_t va = t->to_host[ia], vb = t->to_host[ib];
        if (va > vb) {
            uint32_t tmp = va;
            va = vb, vb = tmp;
            tmp = ia, ia = ib, ib = tmp;
        }
        float sk = t->stiff[k], L = t->rest_len[k];
        if (vb == va + 1 && va % nx + 1 < nx) {
            h->kr[ia] = sk, h->lr[ia] = L; /* ib is ia's right neighbour */
            h->kl[ib] = sk, h->ll[ib] = L;
        } else if (vb == va + nx) {
            h->ku[ia] = sk, h->lu[ia] = L;
            h->kd[ib] = sk, h->ld[ib] = L;
        } else {
            goto not_grid;
        }
    }
    /* Every lattice edge a spring, and the CSR rows in the stencil's order (lattice.h,
     * csr_order): topology.c sorts springs by host (lower, upper) vertex, which gives
     * each row down, left, right, up; checked rather than assumed, because the
     * Jacobi and serial Gauss-Seidel paths promise the CSR rows' result bitwise. */
    int full = 1;
    for (uint32_t v = 0; v < n && full; ++v) {
        const uint32_t col = v % nx, row = v / nx, i = t->to_internal[v];
        const int has[4] = {row > 0, col > 0, col + 1 < nx, row + 1 < ny};
        const float ks[4] = {h->kd[i], h->kl[i], h->kr[i], h->ku[i]};
        int last = -1, count = 0;
        for (uint32_t s = t->adj_start[i]; s < t->adj_start[i + 1]; ++s, ++count) {
            const uint32_t u = t->to_host[t->adj_nbr[s]];
            const int d = u + nx == v ? 0 : u + 1 == v ? 1 : u == v + 1 ? 2 : u == v + nx ? 3 : 4;
            if (d == 4 || d <= last || !has[d] || t->adj_k[s] != ks[d]) full = 0;
            last = d;
        }
        full &= count == has[0] + has[1] + has[2] + has[3];
    }
    h->csr_order = (uint32_t)full;
    /* One stiffness for every spring, and a spring on every lattice edge: the sweep
     * broadcasts it (with an edge missing, the broadcast would add its spring). */
    int uniform = full && t->ns > 0;
    for (uint32_t k = 0; k < t->ns && uniform; ++k) uniform = t->stiff[k] == t->stiff[0];
    h->k_uniform = uniform ? t->stiff[0] : 0.0f;
    *out = h;
    return 1;
not_grid:
    rbc_lattice_free(h, a);
    return 0;
}

#if RBC_VECTOR_EXT
/* 1 if none of the n pin flags at pin is set. */
static inline int row_free(const uint8_t *pin, uint32_t n) {
    uint64_t any = 0;
    uint32_t m = 0;
    for (; m + 8 <= n; m += 8) {
        uint64_t w;
        memcpy(&w, pin + m, 8);
        any |= w;
    }
    for (; m < n; ++m) any |= pin[m];
    return any == 0;
}
#endif /* RBC_VECTOR_EXT */

/* The cloth's arrays for rbc_k_lat_edge. */
static inline rbc_k_lat_gs_arrays gs_edge_arrays(const rbc_cloth_state *c) {
    const rbc_k_lat_gs_arrays A = {c->pinned, c->inv_denom, {c->bx, c->by, c->bz},
                                   {c->p[0], c->p[1], c->p[2]}};
    return A;
}

/* One row of one color: the Gauss-Seidel update of its particles. */
RBC_ALWAYS_INLINE void grid_row(const rbc_lattice *g, rbc_cloth_state *c,
                                const rbc_k_lat_gs_arrays *A, uint32_t color, uint32_t j,
                                float omega) {
    const uint32_t nx = g->nx, ny = g->ny, o = 1u - color;
    float *const *P = c->p;
    const uint32_t s0 = g->row_first[color][j], cnt = g->row_first[color][j + 1] - s0;
    if (!cnt) return;
    const uint32_t f = first_col(g, color, j), ro = g->row_first[o][j];
    const float *dn[3], *up[3];
    for (int a = 0; a < 3; ++a) {
        dn[a] = j > 0 ? P[a] + g->row_first[o][j - 1] : g->zeros;
        up[a] = j + 1 < ny ? P[a] + g->row_first[o][j + 1] : g->zeros;
    }
    /* m in [lo, hi): both horizontal neighbours exist: column f + 2m >= 1 and
     * f + 2m + 1 <= nx - 1. */
    uint32_t lo = f == 0 ? 1u : 0u;
    uint32_t hi = nx >= 2 + f ? (nx - 2 - f) / 2 + 1 : 0u;
    if (hi > cnt) hi = cnt;
    if (lo > hi) lo = hi;
    /* The common case, a row with one stiffness and no pinned particle, in one vector
     * loop over the whole row, its edge particles included. The loop reads the left
     * neighbour of column 0 at ro + f - 1 and the right one of column nx - 1 at
     * ro + f + cnt - 1 (then masks them): in bounds unless this is the other color's
     * first or the last row, which take the path below. */
#if RBC_VECTOR_EXT
    if (g->k_uniform != 0.0f && cnt >= 8 && lo + (cnt - hi) <= 2 && ro + f >= 1 &&
        ro + f + cnt <= g->row_first[1][ny] && row_free(c->pinned + s0, cnt)) {
        const float *B[3] = {c->bx, c->by, c->bz};
        for (int a = 0; a < 3; ++a)
            rbc_k_lat_row_free(cnt, P[a] + s0, P[a] + ro + f - 1, P[a] + ro + f, dn[a], up[a],
                               B[a] + s0, c->inv_denom + s0, g->k_uniform, omega, lo == 1,
                               hi < cnt);
        return;
    }
#endif
    for (uint32_t m = 0; m < lo; ++m) { /* column 0: the right neighbour only (if any) */
        const uint32_t i = s0 + m;
        const int has_r = f + 2 * m + 1 < nx;
        rbc_k_lat_edge(A, i, has_r ? ro + f + m : i, has_r ? g->kr[i] : 0.0f, g->kd[i], g->ku[i],
                       dn, up, m, omega);
    }
    if (hi > lo && g->k_uniform != 0.0f) {
        const uint32_t i = s0 + lo, li = ro + f - 1 + lo, ri = ro + f + lo;
        const float *B[3] = {c->bx, c->by, c->bz};
        for (int a = 0; a < 3; ++a)
            rbc_k_lat_row_axis(hi - lo, P[a] + i, P[a] + li, P[a] + ri, dn[a] + lo, up[a] + lo,
                               B[a] + i, c->inv_denom + i, c->pinned + i, omega, g->k_uniform);
    } else if (hi > lo) {
        const uint32_t i = s0 + lo, li = ro + f - 1 + lo, ri = ro + f + lo;
        rbc_k_lat_row(hi - lo, P[0] + i, P[1] + i, P[2] + i, P[0] + li, P[1] + li, P[2] + li,
                      P[0] + ri, P[1] + ri, P[2] + ri, dn[0] + lo, dn[1] + lo, dn[2] + lo,
                      up[0] + lo, up[1] + lo, up[2] + lo, g->kl + i, g->kr + i, g->kd + i,
                      g->ku + i, c->bx + i, c->by + i, c->bz + i, c->inv_denom + i,
                      c->pinned + i, omega, g->k_uniform);
    }
    for (uint32_t m = hi; m < cnt; ++m) { /* column nx - 1: the left neighbour only */
        const uint32_t i = s0 + m;
        const int has_l = f + 2 * m >= 1;
        rbc_k_lat_edge(A, i, has_l ? ro + f + m - 1 : i, has_l ? g->kl[i] : 0.0f, g->kd[i],
                       g->ku[i], dn, up, m, omega);
    }
}

RBC_VECTOR_CLONES
void rbc_lattice_sweep(const rbc_lattice *g, rbc_cloth_state *c, uint32_t color, float omega,
                    uint32_t tid, uint32_t nt) {
    uint32_t j0, j1;
    rbc_split(g->ny, tid, nt, &j0, &j1);
    const rbc_k_lat_gs_arrays A = gs_edge_arrays(c);
    for (uint32_t j = j0; j < j1; ++j) grid_row(g, c, &A, color, j, omega);
}

RBC_VECTOR_CLONES
void rbc_lattice_wavefront(const rbc_lattice *g, rbc_cloth_state *c, uint32_t iterations, float omega,
                        volatile uint32_t *progress, size_t stride, uint32_t tid, uint32_t nt) {
    const uint32_t ny = g->ny;
    /* Sweep u (iteration u / 2, color u % 2) updates row w - u at step w. Threads
     * split the 2 * iterations sweeps, not the iterations: 11 iterations give two
     * threads 11 sweeps each instead of 6 and 5 iterations. */
    uint32_t u0, u1;
    rbc_split(2 * iterations, tid, nt, &u0, &u1);
    const uint32_t steps = ny + 2 * iterations; /* last: black row ny-1 of the last one */
    const rbc_k_lat_gs_arrays A = gs_edge_arrays(c);
    volatile uint32_t *mine = progress + stride * tid;
    volatile uint32_t *before = tid ? progress + stride * (tid - 1) : NULL;
    for (uint32_t w = 0; w < steps; ++w) {
        /* Sweep u0 at step w reads rows of sweep u0 - 1 that the previous thread
         * writes at steps <= w. */
        if (before) {
            uint32_t spins = 0;
            while (RBC_LOAD_ACQUIRE(before) <= w) rbc_pool_spin(&spins);
        }
        for (uint32_t u = u0; u < u1; ++u) {
            int64_t r = (int64_t)w - (int64_t)u;
            if (r >= 0 && r < (int64_t)ny) grid_row(g, c, &A, u & 1u, (uint32_t)r, omega);
        }
        RBC_STORE_RELEASE(mine, w + 1);
    }
}

/* ------------------------------------------------------------------------- */
/* Jacobi and serial Gauss-Seidel on the lattice                             */
/* ------------------------------------------------------------------------- */



/* The variants, each a loop with no branch inside (clones for AVX2 and AVX-512 picked
 * at load time, simd.h): uniform stiffness or arrays, Chebyshev or plain. */
RBC_VECTOR_CLONES
static void jacobi_axis(uint32_t count, float *restrict o, float *restrict q,
                        const float *restrict s, const float *restrict l, const float *restrict r,
                        const float *restrict d, const float *restrict u, const float *restrict b,
                        const float *restrict inv, const uint8_t *restrict pin,
                        const float *restrict kl, const float *restrict kr,
                        const float *restrict kd, const float *restrict ku, float kuni,
                        float omega, int cheb) {
#define RBC_JAC(UNI, CHEB)                                                                \
    rbc_k_lat_jacobi_row(count, o, q, s, l, r, d, u, b, inv, pin, kl, kr, kd, ku, kuni, omega,  \
                         UNI, CHEB)
    if (kuni != 0.0f) {
        if (cheb) RBC_JAC(1, 1);
        else RBC_JAC(1, 0);
    } else if (cheb) {
        RBC_JAC(0, 1);
    } else {
        RBC_JAC(0, 0);
    }
#undef RBC_JAC
}


/* One row of one color of a Jacobi iteration. */
static void jacobi_row(const rbc_lattice *g, rbc_cloth_state *c,
                       const rbc_k_lat_jacobi_arrays *A, float *const S[3], float *const D[3],
                       uint32_t color, uint32_t j, int cheb, float omega) {
    const uint32_t nx = g->nx, ny = g->ny, o = 1u - color;
    const uint32_t s0 = g->row_first[color][j], cnt = g->row_first[color][j + 1] - s0;
    if (!cnt) return;
    const uint32_t f = first_col(g, color, j), ro = g->row_first[o][j];
    const int has_d = j > 0, has_u = j + 1 < ny;
    /* The other color's particles in the rows below and above: same first column. */
    const uint32_t rd = has_d ? g->row_first[o][j - 1] : 0;
    const uint32_t ru = has_u ? g->row_first[o][j + 1] : 0;
    uint32_t lo = f == 0 ? 1u : 0u;
    uint32_t hi = nx >= 2 + f ? (nx - 2 - f) / 2 + 1 : 0u;
    if (hi > cnt) hi = cnt;
    if (lo > hi) lo = hi;
    /* Column 0 (m < lo) and nx - 1 (m >= hi) one by one, the interior as rows. */
    for (uint32_t m = 0; m < lo; ++m)
        rbc_k_lat_jacobi_edge(A, S, D, s0 + m, rd + m, 0, ro + f + m, ru + m, has_d, 0, 1, has_u,
                              cheb, omega);
    for (uint32_t m = hi; m < cnt; ++m)
        rbc_k_lat_jacobi_edge(A, S, D, s0 + m, rd + m, ro + f + m - 1, 0, ru + m, has_d, 1, 0,
                              has_u, cheb, omega);
    if (hi > lo) {
        const uint32_t i = s0 + lo, li = ro + f - 1 + lo, ri = ro + f + lo;
        const float *B[3] = {c->bx, c->by, c->bz};
        for (int a = 0; a < 3; ++a)
            jacobi_axis(hi - lo, D[a] + i, cheb ? c->prev[a] + i : NULL, S[a] + i, S[a] + li,
                        S[a] + ri, has_d ? S[a] + rd + lo : g->nzeros + lo,
                        has_u ? S[a] + ru + lo : g->nzeros + lo, B[a] + i, c->inv_denom + i,
                        c->pinned + i, g->kl + i, g->kr + i, g->kd + i, g->ku + i, g->k_uniform,
                        omega, cheb);
    }
}

void rbc_lattice_jacobi(const rbc_lattice *g, rbc_cloth_state *c, float *const src[3],
                     float *const dst[3], int chebyshev, float omega, uint32_t tid, uint32_t nt) {
    uint32_t j0, j1;
    rbc_split(g->ny, tid, nt, &j0, &j1);
    const rbc_k_lat_jacobi_arrays A = {g->kd, g->kl, g->kr, g->ku, c->inv_denom,
                                       {c->bx, c->by, c->bz}, c->pinned,
                                       {c->prev[0], c->prev[1], c->prev[2]}};
    for (uint32_t j = j0; j < j1; ++j)
        for (uint32_t color = 0; color < 2; ++color)
            jacobi_row(g, c, &A, src, dst, color, j, chebyshev, omega);
}

/* The arrays of the serial sweep, loaded once: the stores to p cannot make the
 * compiler reload them. */
typedef struct gs_arrays {
    float *px, *py, *pz;
    const float *bx, *by, *bz, *inv, *kd, *kl, *kr, *ku;
    const uint8_t *pin;
    float kuni;
} gs_arrays;

/* One update of the serial sweep, in place, particle i with its neighbours at dn, rt,
 * up (read where the flag says it exists) and the left one's new value carried in L:
 * rbc_k_eq6b's sum in the CSR row's order (down, left, right, up). The left neighbour
 * was updated just before; carrying its value keeps serial Gauss-Seidel's dependency
 * chain in registers instead of a store and a reload. */
RBC_ALWAYS_INLINE void gs_update(const gs_arrays *A, uint32_t i, uint32_t dn, uint32_t rt,
                                 uint32_t up, int has_d, int has_l, int has_r, int has_u,
                                 const int uni, float L[3]) {
    if (A->pin[i]) {
        L[0] = A->px[i], L[1] = A->py[i], L[2] = A->pz[i];
        return;
    }
    const float kd = uni ? A->kuni : A->kd[i], kl = uni ? A->kuni : A->kl[i],
                kr = uni ? A->kuni : A->kr[i], ku = uni ? A->kuni : A->ku[i];
    float *const P[3] = {A->px, A->py, A->pz};
    const float bv[3] = {A->bx[i], A->by[i], A->bz[i]}, inv = A->inv[i];
    for (int a = 0; a < 3; ++a) {
        float acc = bv[a];
        if (has_d) acc += kd * P[a][dn];
        if (has_l) acc += kl * L[a];
        if (has_r) acc += kr * P[a][rt];
        if (has_u) acc += ku * P[a][up];
        L[a] = acc * inv;
        P[a][i] = L[a];
    }
}

/* Row j of the serial sweep in the stencil: column 2m + e is the particle of parity e
 * (e = 0: the color of column 0) at row[e] + m, its neighbours below and above the
 * other color's particles at dn[e] + m and up[e] + m (same column), its right one at
 * row[1 - e] + m + e. L: the left neighbour's new value. */
typedef struct gs_row {
    uint32_t row[2], dn[2], up[2];
    int has_d, has_u;
    float L[3];
} gs_row;

static gs_row gs_row_at(const rbc_lattice *g, uint32_t j) {
    const uint32_t cA = (j + g->c0) & 1u, cB = 1u - cA; /* first_col(g, cA, j) == 0 */
    gs_row r;
    r.has_d = j > 0;
    r.has_u = j + 1 < g->ny;
    r.row[0] = g->row_first[cA][j];
    r.row[1] = g->row_first[cB][j];
    r.dn[0] = r.has_d ? g->row_first[cB][j - 1] : 0;
    r.dn[1] = r.has_d ? g->row_first[cA][j - 1] : 0;
    r.up[0] = r.has_u ? g->row_first[cB][j + 1] : 0;
    r.up[1] = r.has_u ? g->row_first[cA][j + 1] : 0;
    r.L[0] = r.L[1] = r.L[2] = 0.0f;
    return r;
}

/* Column col of row r, any column (flags at run time). */
RBC_ALWAYS_INLINE void gs_col(const gs_arrays *A, uint32_t nx, gs_row *r, uint32_t col,
                              const int uni) {
    const uint32_t e = col & 1u, m = col >> 1;
    gs_update(A, r->row[e] + m, r->dn[e] + m, r->row[1u - e] + m + e, r->up[e] + m, r->has_d,
              col > 0, col + 1 < nx, r->has_u, uni, r->L);
}

/* Column 2m + E of row r, an interior one of a row with rows below and above. */
#define RBC_GS_INNER(R, M, E)                                                             \
    gs_update(A, R.row[E] + (M), R.dn[E] + (M), R.row[1 - (E)] + (M) + (E), R.up[E] + (M), 1, \
              1, 1, 1, uni, R.L)

/* Rows j and j + 1 together, the upper one a column behind: (col, j + 1) is updated
 * after (col, j) and before (col + 1, j + 1), (col, j) before (col, j + 1), so every
 * update reads exactly the values it reads in host order (new below and to the left,
 * old above and to the right): the result is bitwise host order's, and the two rows'
 * chains through their left neighbours run side by side. Step c updates (c, j) and
 * (c - 1, j + 1); steps 2 .. nx - 2 of rows with neighbours above and below take the
 * branch-free path, two steps (an even and an odd column) per turn. */
RBC_ALWAYS_INLINE void gs_two_rows(const gs_arrays *A, const rbc_lattice *g, uint32_t j,
                                   const int uni) {
    const uint32_t nx = g->nx;
    gs_row a = gs_row_at(g, j), b = gs_row_at(g, j + 1);
    gs_col(A, nx, &a, 0, uni);
    uint32_t c = 1;
    if (a.has_d && b.has_u) {
        gs_col(A, nx, &a, 1, uni);
        gs_col(A, nx, &b, 0, uni);
        for (c = 2; c + 2 < nx; c += 2) { /* steps c and c + 1, both <= nx - 2 */
            const uint32_t m = c >> 1;
            RBC_GS_INNER(a, m, 0);
            RBC_GS_INNER(b, m - 1, 1);
            RBC_GS_INNER(a, m, 1);
            RBC_GS_INNER(b, m, 0);
        }
    }
    for (; c < nx; ++c) {
        gs_col(A, nx, &a, c, uni);
        gs_col(A, nx, &b, c - 1, uni);
    }
    gs_col(A, nx, &b, nx - 1, uni);
}
#undef RBC_GS_INNER

RBC_ALWAYS_INLINE void gs_serial(const rbc_lattice *g, rbc_cloth_state *c, const int uni) {
    const gs_arrays A = {c->p[0], c->p[1], c->p[2], c->bx, c->by, c->bz, c->inv_denom,
                         g->kd, g->kl, g->kr, g->ku, c->pinned, g->k_uniform};
    uint32_t j = 0;
    for (; j + 1 < g->ny; j += 2) gs_two_rows(&A, g, j, uni);
    if (j < g->ny) {
        gs_row a = gs_row_at(g, j);
        for (uint32_t col = 0; col < g->nx; ++col) gs_col(&A, g->nx, &a, col, uni);
    }
}

void rbc_lattice_gs_serial(const rbc_lattice *g, rbc_cloth_state *c) {
    if (g->k_uniform != 0.0f) gs_serial(g, c, 1);
    else gs_serial(g, c, 0);
}

/* ------------------------------------------------------------------------- */
/* Local step + right-hand side                                              */
/* ------------------------------------------------------------------------- */

/* One direction's d_ij, exactly as rbc_k_local computes it from i's side. */
static void spring_target(const rbc_topology *t, float *const P[3], uint32_t i, uint32_t j,
                          float L, float out[3]) {
    float ex = P[0][i] - P[0][j], ey = P[1][i] - P[1][j], ez = P[2][i] - P[2][j];
    float len2 = ex * ex + ey * ey + ez * ez;
    if (len2 > 1e-24f) {
        float f = L / sqrtf(len2);
        out[0] = ex * f;
        out[1] = ey * f;
        out[2] = ez * f;
        return;
    }
    double rx = (double)t->rest_x[i] - t->rest_x[j], ry = (double)t->rest_y[i] - t->rest_y[j],
           rz = (double)t->rest_z[i] - t->rest_z[j];
    double len = sqrt(rx * rx + ry * ry + rz * rz);
    float ux = len > 0.0 ? (float)(rx / len) : 0.0f, uy = len > 0.0 ? (float)(ry / len) : 0.0f,
          uz = len > 0.0 ? (float)(rz / len) : 0.0f;
    out[0] = L * ux;
    out[1] = L * uy;
    out[2] = L * uz;
}

/* b of one particle, scalar, any position in the lattice. */
static void rhs_particle(const rbc_lattice *g, rbc_cloth_state *c, uint32_t color, uint32_t j,
                         uint32_t m) {
    const rbc_topology *t = &c->topo;
    const uint32_t o = 1u - color, f = first_col(g, color, j), col = f + 2 * m;
    const uint32_t i = g->row_first[color][j] + m, ro = g->row_first[o][j];
    float *const *P = c->p;
    float wi = c->w[i];
    float sx = wi * c->y[0][i], sy = wi * c->y[1][i], sz = wi * c->y[2][i];
    uint32_t nb[4];
    float ks[4] = {g->kl[i], g->kr[i], g->kd[i], g->ku[i]};
    float Ls[4] = {g->ll[i], g->lr[i], g->ld[i], g->lu[i]};
    int has[4] = {col > 0, col + 1 < g->nx, j > 0, j + 1 < g->ny};
    nb[0] = has[0] ? ro + f + m - 1 : 0;
    nb[1] = has[1] ? ro + f + m : 0;
    nb[2] = has[2] ? g->row_first[o][j - 1] + m : 0;
    nb[3] = has[3] ? g->row_first[o][j + 1] + m : 0;
    for (int d = 0; d < 4; ++d) {
        if (!has[d] || ks[d] == 0.0f) continue;
        float dv[3];
        spring_target(t, P, i, nb[d], Ls[d], dv);
        sx += ks[d] * dv[0];
        sy += ks[d] * dv[1];
        sz += ks[d] * dv[2];
    }
    c->bx[i] = sx;
    c->by[i] = sy;
    c->bz[i] = sz;
}

/* The shared row body (kernels/lattice_kernels.h), cloned for AVX2 and AVX-512. */
RBC_VECTOR_CLONES
static int rhs_interior(uint32_t count, const float *restrict px, const float *restrict py,
                        const float *restrict pz, const float *restrict lx,
                        const float *restrict ly, const float *restrict lz,
                        const float *restrict rx, const float *restrict ry,
                        const float *restrict rz, const float *restrict dx,
                        const float *restrict dy, const float *restrict dz,
                        const float *restrict ux, const float *restrict uy,
                        const float *restrict uz, const float *restrict kl,
                        const float *restrict kr, const float *restrict kd,
                        const float *restrict ku, const float *restrict ll,
                        const float *restrict lr, const float *restrict ld,
                        const float *restrict lu, const float *restrict w, const float *restrict yx,
                        const float *restrict yy, const float *restrict yz, float *restrict bx,
                        float *restrict by, float *restrict bz, float kuni) {
    return rbc_k_lat_rhs_row(count, px, py, pz, lx, ly, lz, rx, ry, rz, dx, dy, dz, ux, uy, uz, kl,
                             kr, kd, ku, ll, lr, ld, lu, w, yx, yy, yz, bx, by, bz, kuni);
}

void rbc_lattice_rhs(const rbc_lattice *g, rbc_cloth_state *c, uint32_t tid, uint32_t nt) {
    const uint32_t nx = g->nx, ny = g->ny;
    uint32_t j0, j1;
    rbc_split(ny, tid, nt, &j0, &j1);
    float *const *P = c->p;
    for (uint32_t color = 0; color < 2; ++color) {
        const uint32_t o = 1u - color;
        for (uint32_t j = j0; j < j1; ++j) {
            const uint32_t s0 = g->row_first[color][j], cnt = g->row_first[color][j + 1] - s0;
            if (!cnt) continue;
            const uint32_t f = first_col(g, color, j), ro = g->row_first[o][j];
            uint32_t lo = f == 0 ? 1u : 0u;
            uint32_t hi = nx >= 2 + f ? (nx - 2 - f) / 2 + 1 : 0u;
            if (hi > cnt) hi = cnt;
            if (lo > hi) lo = hi;
            for (uint32_t m = 0; m < lo; ++m) rhs_particle(g, c, color, j, m);
            if (hi > lo) {
                const float *dn[3], *up[3];
                for (int a = 0; a < 3; ++a) {
                    dn[a] = j > 0 ? P[a] + g->row_first[o][j - 1] : g->zeros;
                    up[a] = j + 1 < ny ? P[a] + g->row_first[o][j + 1] : g->zeros;
                }
                const uint32_t i = s0 + lo, li = ro + f - 1 + lo, ri = ro + f + lo;
                int bad = rhs_interior(hi - lo, P[0] + i, P[1] + i, P[2] + i, P[0] + li, P[1] + li,
                                       P[2] + li, P[0] + ri, P[1] + ri, P[2] + ri, dn[0] + lo,
                                       dn[1] + lo, dn[2] + lo, up[0] + lo, up[1] + lo,
                                       up[2] + lo, g->kl + i, g->kr + i, g->kd + i, g->ku + i,
                                       g->ll + i, g->lr + i, g->ld + i, g->lu + i, c->w + i,
                                       c->y[0] + i, c->y[1] + i, c->y[2] + i, c->bx + i,
                                       c->by + i, c->bz + i, g->k_uniform);
                if (bad)
                    for (uint32_t m = lo; m < hi; ++m) rhs_particle(g, c, color, j, m);
            }
            for (uint32_t m = hi; m < cnt; ++m) rhs_particle(g, c, color, j, m);
        }
    }
}

/* Zero the stiffness from i toward j (its left/right/down/up neighbour). */
static void grid_zero(rbc_lattice *g, const rbc_topology *t, uint32_t i, uint32_t j) {
    uint32_t hi = t->to_host[i], hj = t->to_host[j];
    uint32_t nx = g->nx;
    if (hj + 1 == hi && hi % nx != 0) g->kl[i] = 0.0f;
    else if (hi + 1 == hj && hj % nx != 0) g->kr[i] = 0.0f;
    else if (hj + nx == hi) g->kd[i] = 0.0f;
    else if (hi + nx == hj) g->ku[i] = 0.0f;
}

void rbc_lattice_break_spring(rbc_lattice *g, const rbc_topology *t, uint32_t sp) {
    grid_zero(g, t, t->sa[sp], t->sb[sp]);
    grid_zero(g, t, t->sb[sp], t->sa[sp]);
    g->k_uniform = 0.0f;
}
