/* direct.c -- the exact global step: A p = b of Eq. 6 (see direct.h) by CHOLMOD.
 *
 *   create   number the free particles; assemble the lower triangle of A in double
 *            (CSC, one column per free particle); analyse (fill-reducing ordering and
 *            symbolic factor); factorise numerically (simplicial LL'); drop A and
 *            CHOLMOD's scratch.
 *   solve    assemble b in double, in particle order, stored permuted with xyz
 *            interleaved; forward and back substitution with L (three right-hand
 *            sides in one pass over L, two-column chains of L together); round x
 *            to float into p.
 *
 * The substitutions are ours, over the documented simplicial layout of
 * cholmod_factor (column j in i/x[p[j] .. p[j]+nz[j]), diagonal first), rather than
 * cholmod_solve2, which reallocates its workspace on every call with 3 right-hand
 * sides. Simplicial LL' with AMD ordering, fixed: the solve runs every nonlinear
 * iteration and the factorisation only when h, pins or topology change, so the solve
 * decides; METIS would terminate the process when out of memory; a pivot <= 0 stops
 * LL' with CHOLMOD_NOT_POSDEF. The measurements behind each choice are in
 * docs/design/solvers.md ("The direct solver").
 *
 * Memory: every CHOLMOD call here (start, allocate_sparse, analyze, factorize,
 * free_sparse, free_work, free_factor, finish) runs inside an rbc_cholmod_enter
 * scope with the cloth's allocator (create and destroy below), so CHOLMOD's blocks
 * come from the world's hooks (cholmod_alloc.h). A hook that returns NULL makes the
 * CHOLMOD call fail with CHOLMOD_OUT_OF_MEMORY: create reports RBC_ERR_OUT_OF_MEMORY
 * (cholmod_fail), frees what it had and leaves *out NULL, and the caller keeps the
 * cloth's previous factor (sweep.c).
 */
#include "report.h"
#include "direct.h"
#include "../abi/rbcloth.h"

#if RBC_WITH_CHOLMOD
#include "cholmod_alloc.h"
#include "cholmod_load.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>

struct rbc_direct {
    const rbc_cholmod_api *api; /* CHOLMOD, loaded (cholmod_load.h) */
    rbc_allocator alloc;
    uint32_t n;                 /* particles */
    uint32_t nf;                /* free particles = order of A */
    int32_t *free_idx;          /* [n] column of A for particle i, or -1 if pinned */
    uint32_t *free_of;          /* [nf] particle of column f */
    uint32_t *pos;              /* [nf] row of P A P^T that column f of A becomes */
    double *v;                  /* [3 nf] b, then x, in permuted order, xyz interleaved */
    double *inv_diag;           /* [nf] 1 / L_jj (a division costs ~10 multiplies) */
    uint8_t *chain;             /* [nf] 1: column j+1 of L is column j's pattern less
                                   row j+1 (a 2-column supernode, solved together) */
    size_t own_bytes;           /* held through alloc */
    int started;                /* cm is initialised (nf > 0) */
    cholmod_common cm;
    cholmod_factor *L;          /* simplicial LL' of P A P^T */
    size_t cholmod_bytes;       /* CHOLMOD's memory in use after create */
};


void rbc_direct_destroy(rbc_direct *d) {
    if (!d) return;
    rbc_allocator a = d->alloc; /* d is freed below: the scope uses a copy */
    if (d->started) {
        const rbc_allocator *prev = rbc_cholmod_enter(&a);
        d->api->free_factor(&d->L, &d->cm);
        d->api->finish(&d->cm);
        rbc_cholmod_leave(prev);
    }
    rbc_mem_free(&a, d->free_idx, rbc_mul_size(d->n, sizeof(int32_t)));
    rbc_mem_free(&a, d->free_of, rbc_mul_size(d->nf, sizeof(uint32_t)));
    rbc_mem_free(&a, d->pos, rbc_mul_size(d->nf, sizeof(uint32_t)));
    rbc_mem_free(&a, d->v, rbc_mul_size(3 * (size_t)d->nf, sizeof(double)));
    rbc_mem_free(&a, d->inv_diag, rbc_mul_size(d->nf, sizeof(double)));
    rbc_mem_free(&a, d->chain, d->nf);
    rbc_mem_free(&a, d, sizeof *d);
}

size_t rbc_direct_bytes(const rbc_direct *d) { return d ? d->own_bytes + d->cholmod_bytes : 0; }

/* A CHOLMOD failure (status < 0, or the not-positive-definite warning) as an
 * rbc_result with a message. */
static int32_t cholmod_fail(rbc_direct *d, const rbc_topology *t, const char *stage, float h,
                            char *err, size_t errlen) {
    int s = d->cm.status;
    if (s == CHOLMOD_OUT_OF_MEMORY)
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                    "direct solver: out of memory in %s (%u free particles)", stage, d->nf);
    if (s == CHOLMOD_TOO_LARGE)
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                    "direct solver: the Cholesky factor of %u free particles exceeds CHOLMOD's "
                    "32-bit index range (%s)",
                    d->nf, stage);
    if (s == CHOLMOD_NOT_POSDEF && d->L && d->L->minor < d->nf) {
        /* L->minor is a column of the permuted matrix; Perm maps it back to ours. */
        size_t col = d->L->minor;
        const int *perm = d->L->Perm;
        uint32_t f = perm ? (uint32_t)perm[col] : (uint32_t)col;
        uint32_t i = d->free_of[f];
        return rbc_fail(err, errlen, RBC_ERR_UNSTABLE,
                    "direct solver: the global matrix is not positive definite at vertex %u "
                    "(h = %g s, m/h^2 = %g kg/s^2, sum of stiffness %g N/m)",
                    t->to_host[i], (double)h, (double)rbc_direct_weight(t->mass[i], h),
                    (double)t->ksum[i]);
    }
    return rbc_fail(err, errlen, RBC_ERR_UNSTABLE, "direct solver: CHOLMOD status %d in %s", s,
                stage);
}

/* Sort rows[0..len) ascending, carrying vals (a column has a handful of entries). */
static void sort_column(int *rows, double *vals, size_t len) {
    for (size_t a = 1; a < len; ++a) {
        int r = rows[a];
        double v = vals[a];
        size_t b = a;
        for (; b > 0 && rows[b - 1] > r; --b) {
            rows[b] = rows[b - 1];
            vals[b] = vals[b - 1];
        }
        rows[b] = r;
        vals[b] = v;
    }
}

static int32_t direct_create(rbc_direct **out, const rbc_topology *t, const uint8_t *pinned,
                             float h, const rbc_allocator *a, char *err, size_t errlen);

int32_t rbc_direct_create(rbc_direct **out, const rbc_topology *t, const uint8_t *pinned,
                          float h, const rbc_allocator *a, char *err, size_t errlen) {
    /* Every CHOLMOD call of create, its failure paths' destroy included, allocates
     * through a (see the top of this file). */
    *out = NULL;
    if (!rbc_cholmod_get(err, errlen)) return RBC_ERR_BACKEND_UNAVAILABLE; /* loads it */
    const rbc_allocator *prev = rbc_cholmod_enter(a);
    int32_t rc = direct_create(out, t, pinned, h, a, err, errlen);
    rbc_cholmod_leave(prev);
    return rc;
}

static int32_t direct_create(rbc_direct **out, const rbc_topology *t, const uint8_t *pinned,
                             float h, const rbc_allocator *a, char *err, size_t errlen) {
    *out = NULL;
    const rbc_cholmod_api *api = rbc_cholmod_get(err, errlen);
    if (!(isfinite(h) && h > 0.0f && isfinite(1.0f / (h * h))))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "direct solver: h = %g s; it must be finite and > 0 with 1/h^2 finite",
                    (double)h);
    const uint32_t n = t->n;
    uint32_t nf = 0;
    for (uint32_t i = 0; i < n; ++i) nf += pinned[i] ? 0u : 1u;
    if (nf > (uint32_t)INT32_MAX)
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                    "direct solver: %u free particles exceed CHOLMOD's 32-bit indices", nf);

    rbc_direct *d = rbc_mem_alloc(a, sizeof *d);
    if (!d) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "direct solver: out of memory");
    d->api = api;
    d->alloc = *a;
    d->n = n;
    d->nf = nf;
    d->free_idx = rbc_mem_alloc(a, rbc_mul_size(n, sizeof(int32_t)));
    d->free_of = rbc_mem_alloc(a, rbc_mul_size(nf, sizeof(uint32_t)));
    d->pos = rbc_mem_alloc(a, rbc_mul_size(nf, sizeof(uint32_t)));
    d->v = rbc_mem_alloc(a, rbc_mul_size(3 * (size_t)nf, sizeof(double)));
    d->inv_diag = rbc_mem_alloc(a, rbc_mul_size(nf, sizeof(double)));
    d->chain = rbc_mem_alloc(a, nf);
    d->own_bytes = sizeof *d + rbc_mul_size(n, sizeof(int32_t)) +
                   2 * rbc_mul_size(nf, sizeof(uint32_t)) +
                   rbc_mul_size(4 * (size_t)nf, sizeof(double)) + nf;
    if (!d->free_idx || !d->free_of || !d->pos || !d->v || !d->inv_diag || !d->chain) {
        rbc_direct_destroy(d);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                    "direct solver: out of memory for %u particles", n);
    }
    for (uint32_t i = 0, f = 0; i < n; ++i) {
        if (pinned[i]) {
            d->free_idx[i] = -1;
        } else {
            d->free_idx[i] = (int32_t)f;
            d->free_of[f++] = i;
        }
    }
    if (nf == 0) { /* everything pinned: nothing to factor, nothing to solve */
        *out = d;
        return RBC_OK;
    }

    d->api->start(&d->cm);
    d->started = 1;
    d->cm.print = 0;             /* never print (also silences cholmod_error) */
    d->cm.error_handler = NULL;  /* failures are read from cm.status */
    d->cm.supernodal = CHOLMOD_SIMPLICIAL; /* see the top of this file */
    d->cm.nmethods = 1;
    d->cm.method[0].ordering = CHOLMOD_AMD;
    d->cm.postorder = 1;
    d->cm.final_ll = 1;          /* LL': a pivot <= 0 is reported, not factored */

    /* Lower triangle of A (stype -1, the form CHOLMOD's simplicial factorisation
     * permutes with one transpose instead of two), column f = free particle
     * free_of[f]: the diagonal m_i/h^2 + sum_j s_ij (all springs, pinned neighbours
     * included), then -s_ij for the free neighbours with a larger column. */
    size_t nnz = nf;
    for (uint32_t f = 0; f < nf; ++f) {
        uint32_t i = d->free_of[f];
        for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; ++k) {
            int32_t g = d->free_idx[t->adj_nbr[k]];
            nnz += (g >= 0 && (uint32_t)g > f) ? 1u : 0u;
        }
    }
    cholmod_sparse *A = d->api->allocate_sparse(nf, nf, nnz, 1, 1, -1, CHOLMOD_REAL, &d->cm);
    if (!A) {
        int32_t rc = cholmod_fail(d, t, "assembly", h, err, errlen);
        rbc_direct_destroy(d);
        return rc;
    }
    int *Ap = A->p, *Ai = A->i;
    double *Ax = A->x;
    size_t q = 0;
    for (uint32_t f = 0; f < nf; ++f) {
        uint32_t i = d->free_of[f];
        Ap[f] = (int)q;
        size_t diag = q++;
        double sum = (double)rbc_direct_weight(t->mass[i], h);
        for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; ++k) {
            double s = (double)t->adj_k[k];
            sum += s;
            int32_t g = d->free_idx[t->adj_nbr[k]];
            if (g >= 0 && (uint32_t)g > f) {
                Ai[q] = g;
                Ax[q] = -s;
                ++q;
            }
        }
        if (!isfinite(sum)) {
            d->api->free_sparse(&A, &d->cm);
            int32_t rc = rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                              "direct solver: vertex %u: m/h^2 + sum of stiffness = %g is not "
                              "finite (m = %g kg, h = %g s)",
                              t->to_host[i], sum, (double)t->mass[i], (double)h);
            rbc_direct_destroy(d);
            return rc;
        }
        Ai[diag] = (int)f;
        Ax[diag] = sum;
        /* Springs are unique (topology.c), so a column has no duplicate row. */
        sort_column(Ai + diag + 1, Ax + diag + 1, q - diag - 1);
    }
    Ap[nf] = (int)q;

    d->L = d->api->analyze(A, &d->cm);
    int ok = d->L != NULL && d->cm.status == CHOLMOD_OK;
    if (ok) ok = d->api->factorize(A, d->L, &d->cm) && d->cm.status == CHOLMOD_OK;
    d->api->free_sparse(&A, &d->cm);
    if (!ok) {
        int32_t rc = cholmod_fail(d, t, d->L ? "factorisation" : "analysis", h, err, errlen);
        rbc_direct_destroy(d);
        return rc;
    }

    /* The layout the substitutions rely on (documented for simplicial LL'; checked
     * so that a CHOLMOD that changed it fails here, not with wrong positions). */
    const cholmod_factor *L = d->L;
    const int *Lp = L->p, *Li = L->i, *Lnz = L->nz, *perm = L->Perm;
    const double *Lx = L->x;
    int layout = !L->is_super && L->is_ll && L->xtype == CHOLMOD_REAL &&
                 L->itype == CHOLMOD_INT && L->dtype == CHOLMOD_DOUBLE && L->n == nf && Lp &&
                 Li && Lnz && Lx && perm;
    for (uint32_t j = 0; layout && j < nf; ++j) {
        layout = Lnz[j] >= 1 && Li[Lp[j]] == (int)j && Lx[Lp[j]] > 0.0 && perm[j] >= 0 &&
                 (uint32_t)perm[j] < nf;
        if (!layout) break;
        d->pos[perm[j]] = j;
        d->inv_diag[j] = 1.0 / Lx[Lp[j]];
    }
    for (uint32_t j = 0; layout && j + 1 < nf; ++j) {
        int q0 = Lp[j], len = Lnz[j], q1 = Lp[j + 1];
        int is_chain = len >= 2 && Li[q0 + 1] == (int)(j + 1) && Lnz[j + 1] == len - 1;
        for (int e = 2; is_chain && e < len; ++e) is_chain = Li[q0 + e] == Li[q1 + e - 1];
        d->chain[j] = (uint8_t)is_chain;
    }
    if (!layout) {
        rbc_direct_destroy(d);
        return rbc_fail(err, errlen, RBC_ERR_UNSTABLE,
                    "direct solver: CHOLMOD returned a factor of an unexpected layout");
    }
    /* Analysis/factorisation scratch (Flag, Head, Iwork) is not used by the solve. */
    d->api->free_work(&d->cm);
    d->cholmod_bytes = d->cm.memory_inuse;
    *out = d;
    return RBC_OK;
}

void rbc_direct_solve(rbc_direct *d, const rbc_topology *t, const uint8_t *pinned, const float *w,
                      const float *const y[3], const float *dx, const float *dy, const float *dz,
                      float *const p[3]) {
    (void)pinned; /* the factor's own pin set (free_idx) decides; see direct.h */
    const uint32_t nf = d->nf;
    if (nf == 0) return;
    const uint32_t *restrict adj_start = t->adj_start, *restrict adj_nbr = t->adj_nbr;
    const float *restrict adj_k = t->adj_k;
    const int32_t *restrict free_idx = d->free_idx;
    const uint32_t *restrict free_of = d->free_of, *restrict pos = d->pos;
    const float *px = p[0], *py = p[1], *pz = p[2];
    double *restrict v = d->v;

    /* v = P b, b_i = w_i y_i + sum_j s_ij d_ij + sum_{j pinned} s_ij p_j (double).
     * In particle order: the topology streams, only the stores into v scatter. */
    for (uint32_t f = 0; f < nf; ++f) {
        uint32_t i = free_of[f];
        size_t k = pos[f];
        double wi = (double)w[i];
        double sx = wi * y[0][i], sy = wi * y[1][i], sz = wi * y[2][i];
        for (uint32_t e = adj_start[i]; e < adj_start[i + 1]; ++e) {
            double s = (double)adj_k[e];
            uint32_t j = adj_nbr[e];
            double ex = dx[e], ey = dy[e], ez = dz[e];
            if (free_idx[j] < 0) {
                ex += px[j];
                ey += py[j];
                ez += pz[j];
            }
            sx += s * ex;
            sy += s * ey;
            sz += s * ez;
        }
        v[3 * k] = sx;
        v[3 * k + 1] = sy;
        v[3 * k + 2] = sz;
    }

    /* L z = v (column-oriented), then L^T x = z (row-oriented over the columns). Two
     * columns j, j+1 of one chain (chain[j]) share their rows below j+1: doing them
     * together reads and writes those rows of v once instead of twice. */
    const cholmod_factor *L = d->L;
    const int *restrict Lp = L->p, *restrict Li = L->i, *restrict Lnz = L->nz;
    const double *restrict Lx = L->x, *restrict inv_diag = d->inv_diag;
    const uint8_t *restrict chain = d->chain;
    for (uint32_t j = 0; j < nf;) {
        int q0 = Lp[j], q1 = q0 + Lnz[j];
        double *vj = v + 3 * (size_t)j;
        double r_jj = inv_diag[j];
        double zx = vj[0] * r_jj, zy = vj[1] * r_jj, zz = vj[2] * r_jj;
        vj[0] = zx;
        vj[1] = zy;
        vj[2] = zz;
        if (chain[j]) {
            double l = Lx[q0 + 1];
            double *vk = vj + 3;
            double r_kk = inv_diag[j + 1];
            double wx = (vk[0] - l * zx) * r_kk, wy = (vk[1] - l * zy) * r_kk,
                   wz = (vk[2] - l * zz) * r_kk;
            vk[0] = wx;
            vk[1] = wy;
            vk[2] = wz;
            /* lk[q]: the entry of column j+1 in the row of Lx[q] of column j */
            const double *restrict lk = Lx + (Lp[j + 1] - 1 - q0);
            for (int q = q0 + 2; q < q1; ++q) {
                double a = Lx[q], b = lk[q];
                double *r = v + 3 * (size_t)Li[q];
                r[0] -= a * zx + b * wx;
                r[1] -= a * zy + b * wy;
                r[2] -= a * zz + b * wz;
            }
            j += 2;
        } else {
            for (int q = q0 + 1; q < q1; ++q) {
                double l = Lx[q];
                double *r = v + 3 * (size_t)Li[q];
                r[0] -= l * zx;
                r[1] -= l * zy;
                r[2] -= l * zz;
            }
            j += 1;
        }
    }
    for (uint32_t j = nf; j-- > 0;) {
        if (j > 0 && chain[j - 1]) { /* columns j - 1 and j */
            uint32_t i0 = j - 1;
            int q0 = Lp[i0], q1 = q0 + Lnz[i0];
            const double *restrict lk = Lx + (Lp[j] - 1 - q0);
            double *vi = v + 3 * (size_t)i0, *vk = vi + 3;
            double sx = vi[0], sy = vi[1], sz = vi[2];
            double tx = vk[0], ty = vk[1], tz = vk[2];
            for (int q = q0 + 2; q < q1; ++q) {
                double a = Lx[q], b = lk[q];
                const double *r = v + 3 * (size_t)Li[q];
                sx -= a * r[0];
                sy -= a * r[1];
                sz -= a * r[2];
                tx -= b * r[0];
                ty -= b * r[1];
                tz -= b * r[2];
            }
            double r_kk = inv_diag[j], r_ii = inv_diag[i0], l = Lx[q0 + 1];
            tx *= r_kk;
            ty *= r_kk;
            tz *= r_kk;
            vk[0] = tx;
            vk[1] = ty;
            vk[2] = tz;
            vi[0] = (sx - l * tx) * r_ii;
            vi[1] = (sy - l * ty) * r_ii;
            vi[2] = (sz - l * tz) * r_ii;
            j = i0;
            continue;
        }
        int q0 = Lp[j], q1 = q0 + Lnz[j];
        double sx = v[3 * (size_t)j], sy = v[3 * (size_t)j + 1], sz = v[3 * (size_t)j + 2];
        for (int q = q0 + 1; q < q1; ++q) {
            double l = Lx[q];
            const double *r = v + 3 * (size_t)Li[q];
            sx -= l * r[0];
            sy -= l * r[1];
            sz -= l * r[2];
        }
        double r_jj = inv_diag[j];
        v[3 * (size_t)j] = sx * r_jj;
        v[3 * (size_t)j + 1] = sy * r_jj;
        v[3 * (size_t)j + 2] = sz * r_jj;
    }

    /* p = P^T x, rounded to float. */
    float *qx = p[0], *qy = p[1], *qz = p[2];
    for (uint32_t f = 0; f < nf; ++f) {
        uint32_t i = free_of[f];
        size_t k = pos[f];
        qx[i] = (float)v[3 * k];
        qy[i] = (float)v[3 * k + 1];
        qz[i] = (float)v[3 * k + 2];
    }
}

int rbc_direct_available(char *err, size_t errlen) { return rbc_cholmod_get(err, errlen) != NULL; }

#else /* !RBC_WITH_CHOLMOD: a build without the direct solver (Windows, or chosen) */

#include "report.h"

struct rbc_direct {
    int unused;
};

static const char no_cholmod[] =
    "RBC_SOLVER_DIRECT is not in this build of rbcloth (configured without CHOLMOD, "
    "RBC_WITH_CHOLMOD=OFF); every other solver is";

int rbc_direct_available(char *err, size_t errlen) {
    rbc_fail(err, errlen, RBC_ERR_BACKEND_UNAVAILABLE, "%s", no_cholmod);
    return 0;
}

int32_t rbc_direct_create(rbc_direct **out, const rbc_topology *t, const uint8_t *pinned,
                          float h, const rbc_allocator *a, char *err, size_t errlen) {
    (void)t, (void)pinned, (void)h, (void)a;
    *out = NULL;
    return rbc_fail(err, errlen, RBC_ERR_BACKEND_UNAVAILABLE, "%s", no_cholmod);
}

/* Unreachable: no rbc_direct is ever made. */
void rbc_direct_solve(rbc_direct *d, const rbc_topology *t, const uint8_t *pinned, const float *w,
                      const float *const y[3], const float *dx, const float *dy, const float *dz,
                      float *const p[3]) {
    (void)d, (void)t, (void)pinned, (void)w, (void)y, (void)dx, (void)dy, (void)dz, (void)p;
}

void rbc_direct_destroy(rbc_direct *d) { (void)d; }

size_t rbc_direct_bytes(const rbc_direct *d) {
    (void)d;
    return 0;
}
#endif
