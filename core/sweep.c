/* sweep.c -- the global step (Eq. 6) of a step, and the one place that chooses how
 * it runs.
 *
 * The choice, per cloth and per step:
 *   wavefront  fixed counts of plain or over-relaxed red-black sweeps on lattices,
 *              without contacts: temporally blocked, the mesh streamed once for all
 *              iterations (lattice.h; bitwise the result of the plain loop)
 *   lattice    a regular grid: the stencil sweeps of lattice.h
 *   ELL        other meshes: the ELLPACK rows of ell.h
 *   CSR        the generic rows (global.c): the reference, and what the Chebyshev
 *              stash and meshes without another layout use
 *   direct     one exact solve per cloth (direct.h)
 * and, for the iterative solvers, when the iterations of a global step stop (the
 * iteration mode: a fixed count, a tolerance, a time budget, the target strain). */
#include "sweep.h"

#include <math.h>
#include <string.h>

#include "collide.h"
#include "contact_step.h"
#include "direct.h"
#include "ell.h"
#include "global.h"
#include "lattice.h"
#include "report.h"
#include "target.h"

/* The layout a sweep of cloth c runs on, for Gauss-Seidel by color (the Chebyshev
 * stash exists only on the CSR rows) or for Jacobi and serial Gauss-Seidel (the
 * lattice's versions need its CSR ordering). */
typedef enum rbc_layout { RBC_LAYOUT_CSR, RBC_LAYOUT_LATTICE, RBC_LAYOUT_ELL } rbc_layout;

static rbc_layout color_sweep_layout(const rbc_cloth_state *c, rbc_gs_variant v) {
    if (v == RBC_GS_STASH) return RBC_LAYOUT_CSR;
    return c->lattice ? RBC_LAYOUT_LATTICE : c->ell ? RBC_LAYOUT_ELL : RBC_LAYOUT_CSR;
}

static rbc_layout row_sweep_layout(const rbc_cloth_state *c) {
    return c->lattice && c->lattice->csr_order ? RBC_LAYOUT_LATTICE : RBC_LAYOUT_CSR;
}

/* packed: the ELL layout's p4 holds p (ell_pack_all ran, and only packed sweeps
 * wrote p since), so its sweeps may read it. */
static void gs_color(rbc_cloth_state *c, uint32_t color, rbc_gs_variant v, float omega,
                     int packed, uint32_t tid, uint32_t nt) {
    if (color >= c->topo.ncolors) return;
    switch (color_sweep_layout(c, v)) {
    case RBC_LAYOUT_LATTICE:
        rbc_lattice_sweep(c->lattice, c, color, v == RBC_GS_SOR ? omega : 0.0f, tid, nt);
        break;
    case RBC_LAYOUT_ELL:
        if (packed)
            rbc_ell_sweep_packed(c->ell, c, color, v == RBC_GS_SOR ? omega : 0.0f, tid, nt);
        else
            rbc_ell_sweep(c->ell, c, color, v == RBC_GS_SOR ? omega : 0.0f, tid, nt);
        break;
    case RBC_LAYOUT_CSR:
        rbc_csr_gs_color(c, color, v, omega, tid, nt);
        break;
    }
}

void rbc_global_gs_color(rbc_cloth_state *c, uint32_t color, rbc_gs_variant v, float omega,
                         uint32_t tid, uint32_t nt) {
    gs_color(c, color, v, omega, 0, tid, nt);
}

void rbc_global_jacobi(rbc_cloth_state *c, float *const src[3], float *const dst[3],
                       int chebyshev, float omega, uint32_t tid, uint32_t nt) {
    /* A lattice: the same sums in the same order over rows, vectorized (lattice.h);
     * bitwise the CSR rows' result, whatever the split of the rows over threads. */
    if (row_sweep_layout(c) == RBC_LAYOUT_LATTICE)
        rbc_lattice_jacobi(c->lattice, c, src, dst, chebyshev, omega, tid, nt);
    else
        rbc_csr_jacobi(c, src, dst, chebyshev, omega, tid, nt);
}

void rbc_global_gs_serial(rbc_cloth_state *c) {
    /* A lattice: the same updates in the same order, the neighbours found by the
     * stencil instead of index arrays (lattice.h); bitwise the CSR rows' result. */
    if (row_sweep_layout(c) == RBC_LAYOUT_LATTICE)
        rbc_lattice_gs_serial(c->lattice, c);
    else
        rbc_csr_gs_serial(c);
}

float rbc_solver_sor_omega(const rbc_solver *s, rbc_cloth_state *c, float h) {
    if (s->settings.omega > 0.0f) return s->settings.omega;
    /* Optimal SOR for a consistently ordered matrix (red-black): Young's formula. */
    float rho = rbc_global_spectral_radius(c, h);
    return 2.0f / (1.0f + sqrtf(1.0f - rho * rho));
}

static int is_jacobi(rbc_solver_kind k) {
    return k == RBC_SOLVER_JACOBI || k == RBC_SOLVER_JACOBI_CHEBYSHEV;
}

/* Serial, before the step's threads start: what the selected solver needs for this
 * substep length (SOR's omega and Chebyshev's rho from the spectral radius, the
 * direct solver's factorisation: each changes only with h, the pins or the
 * topology), and whether fixed counts may run as the wavefront. */
int32_t rbc_sweep_prepare(step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    /* The color sweeps of these solvers leave each color's values as they are until its
     * next sweep (Chebyshev blends after the sweeps; the others have no colors): their
     * collider contacts and friction are solved per color. */
    ctx->color_pass = st->kind == RBC_SOLVER_RBGS || st->kind == RBC_SOLVER_RBGS_SOR ||
                      st->kind == RBC_SOLVER_MULTICOLOR_GS;
    ctx->wavefront = ctx->color_pass && !ctx->cc_active;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->topo.ncolors > ctx->ncolors) ctx->ncolors = c->topo.ncolors;
        ctx->wavefront = ctx->wavefront && c->lattice != NULL;
        uint32_t ki = rbc_step_slot(k);
        if (st->kind == RBC_SOLVER_RBGS_SOR) ctx->sor_omega[ki] = rbc_solver_sor_omega(s, c, ctx->h);
        if (st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV || st->kind == RBC_SOLVER_RBGS_CHEBYSHEV) {
            /* rho_J, given or estimated. Gauss-Seidel's radius is rho_J^2 for a
             * consistently ordered (two color) matrix; used with more colors too. */
            float rho = st->rho > 0.0f ? st->rho : rbc_global_spectral_radius(c, ctx->h);
            if (st->kind == RBC_SOLVER_RBGS_CHEBYSHEV) rho = rho * rho;
            ctx->cheb_rho[ki] = rho;
        }
        if (st->kind == RBC_SOLVER_DIRECT &&
            (!c->direct || c->h_direct != ctx->h || c->direct_dirty)) {
            rbc_direct *d = NULL;
            int32_t rc = rbc_direct_create(&d, &c->topo, c->pinned, ctx->h, &s->alloc, ctx->err,
                                           ctx->errlen);
            if (rc != RBC_OK) return rc;
            rbc_direct_destroy(c->direct);
            c->direct = d;
            c->h_direct = ctx->h;
            c->direct_dirty = 0;
        }
    }
    return RBC_OK;
}

/* One linear iteration of a Jacobi solver over every cloth. Even k reads p and
 * writes alt, odd k the reverse; the global step swaps the buffers afterwards when
 * the count is odd. */
static void jacobi_iteration(step_ctx *ctx, uint32_t k, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    int cheb = st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        float *const *src = (k & 1) ? c->alt : c->p;
        float *const *dst = (k & 1) ? c->p : c->alt;
        float omega = cheb ? rbc_chebyshev_omega(k, st->chebyshev_delay, ctx->cheb_rho[rbc_step_slot(q)])
                           : 1.0f;
        rbc_global_jacobi(c, src, dst, cheb, omega, tid, nt);
    }
    rbc_pool_barrier(s->pool);
}

/* One linear iteration of Gauss-Seidel by color (RBGS, multicolor, SOR, Chebyshev);
 * packed as gs_color's. */
static void color_iteration(step_ctx *ctx, uint32_t k, int packed, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    rbc_pool *pool = s->pool;
    const rbc_solver_settings *st = &s->settings;
    rbc_gs_variant v = st->kind == RBC_SOLVER_RBGS_SOR         ? RBC_GS_SOR
                       : st->kind == RBC_SOLVER_RBGS_CHEBYSHEV ? RBC_GS_STASH
                                                               : RBC_GS_PLAIN;
    for (uint32_t color = 0; color < ctx->ncolors; ++color) {
        for (uint32_t q = 0; q < s->cloth_count; ++q)
            gs_color(s->cloths[q], color, v, ctx->sor_omega[rbc_step_slot(q)], packed, tid, nt);
        rbc_pool_barrier(pool);
        /* Collider contacts join particles of one color (each touches only its own
         * particle), so they are solved right after that color's sweep, before the
         * next color reads it: a particle's push and its friction then come from
         * the one Gauss-Seidel value it was just given (collide.h). */
        if (ctx->color_pass && (ctx->any_contacts || ctx->host_contacts)) {
            if (ctx->any_contacts) rbc_collide_project_color(s, &s->contacts[tid], color, ctx->h);
            if (tid == 0 && ctx->host_contacts)
                rbc_collide_project_color(s, &s->host_contacts, color, ctx->h);
            rbc_pool_barrier(pool);
        }
    }
    if (v == RBC_GS_STASH) {
        for (uint32_t q = 0; q < s->cloth_count; ++q)
            rbc_global_chebyshev_blend(
                s->cloths[q],
                rbc_chebyshev_omega(k, st->chebyshev_delay, ctx->cheb_rho[rbc_step_slot(q)]), tid,
                nt);
        rbc_pool_barrier(pool);
    }
}

/* One linear iteration of the selected iterative solver over every cloth, with the
 * barriers it needs; k is the iteration's index in this non-linear iteration. */
static void linear_iteration(step_ctx *ctx, uint32_t k, int packed, uint32_t tid,
                             uint32_t nt) {
    rbc_solver *s = ctx->s;
    switch (s->settings.kind) {
    case RBC_SOLVER_JACOBI:
    case RBC_SOLVER_JACOBI_CHEBYSHEV:
        jacobi_iteration(ctx, k, tid, nt);
        break;
    case RBC_SOLVER_GAUSS_SEIDEL:
        if (tid == 0)
            for (uint32_t q = 0; q < s->cloth_count; ++q) rbc_global_gs_serial(s->cloths[q]);
        rbc_pool_barrier(s->pool);
        break;
    default:
        color_iteration(ctx, k, packed, tid, nt);
        break;
    }
}

/* count iterations of every cloth as the lattice wavefront (a pipeline of the
 * threads, one cloth after the other). */
static void wavefront(step_ctx *ctx, uint32_t count, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        float omega =
            s->settings.kind == RBC_SOLVER_RBGS_SOR ? ctx->sor_omega[rbc_step_slot(q)] : 0.0f;
        ctx->progress[16 * tid] = 0;
        rbc_pool_barrier(s->pool);
        rbc_lattice_wavefront(c->lattice, c, count, omega, ctx->progress, 16, tid, nt);
        rbc_pool_barrier(s->pool);
    }
}

uint32_t rbc_sweep_residual_colors(rbc_solver_kind kind, uint32_t ncolors) {
    return !is_jacobi(kind) && ncolors > 1 && kind != RBC_SOLVER_GAUSS_SEIDEL ? ncolors - 1
                                                                              : ncolors;
}

/* RBC_ITERATE_TOLERANCE: stop at the relative residual, checked over all colors but
 * the last one a Gauss-Seidel sweep just solved exactly (its rows have zero residual
 * up to rounding). */
static void tolerance_check(step_ctx *ctx, uint32_t k, uint32_t limit, uint32_t tid,
                            uint32_t nt) {
    rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    double r2 = 0.0, b2 = 0.0;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        const rbc_cloth_state *c = s->cloths[q];
        rbc_global_residual(c, rbc_sweep_residual_colors(st->kind, c->topo.ncolors), tid, nt,
                            &r2, &b2);
    }
    ctx->part[tid].r2 = r2;
    ctx->part[tid].b2 = b2;
    rbc_pool_barrier(s->pool);
    if (tid == 0) {
        double R = 0.0, B = 0.0;
        for (uint32_t th = 0; th < nt; ++th) {
            R += ctx->part[th].r2;
            B += ctx->part[th].b2;
        }
        double tol = st->tolerance;
        ctx->stop = k >= limit || R <= tol * tol * B;
    }
}

rbc_sweep_plan rbc_sweep_plan_global(const step_ctx *ctx, uint32_t segment, uint32_t nsegments) {
    const rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    rbc_sweep_plan pl;
    /* RBC_ITERATE_TARGET: every global step of a step but its last runs the count
     * the last one of the previous step needed (a fixed count, so the wavefront
     * serves it); the last one checks the strain from a quarter below that count on,
     * every iteration, up to max_linear_iterations. Checking where the step ends is
     * what decides; a check costs several lattice sweeps, so only ~2 per step. */
    const int tgt = st->mode == RBC_ITERATE_TARGET;
    pl.target_check = tgt && segment + 1 == nsegments;
    pl.fixed = st->mode == RBC_ITERATE_FIXED || (tgt && !pl.target_check);
    pl.limit = st->mode == RBC_ITERATE_FIXED ? s->linear_iterations
               : pl.fixed                    ? ctx->tgt_iters
                                             : st->max_linear_iterations;
    /* The first check a quarter (at least one) below last step's count: the count
     * comes down quickly when the cloth settles, and a step that needs the full
     * count pays a check or two more. */
    pl.first = 0;
    if (pl.target_check) {
        uint32_t n = ctx->tgt_iters, less = n / 4 > 1 ? n / 4 : 1;
        pl.first = n > less ? n - less : 1;
    }
    /* The wavefront does the same updates with the same inputs as the loop (bitwise
     * its result); contacts of this substep join the sweeps, so not with them. */
    int wave_ok = ctx->wavefront && !ctx->any_contacts && !ctx->host_contacts;
    pl.wave = wave_ok && pl.fixed;
    /* The target's checked global step: the iterations before its first check too. */
    pl.pre = pl.target_check && wave_ok ? pl.first - 1 : 0;
    return pl;
}

/* The last iteration wrote alt (Jacobi, odd count): make it p. */
static void jacobi_swap_back(step_ctx *ctx, uint32_t tid) {
    rbc_solver *s = ctx->s;
    if (tid == 0)
        for (uint32_t q = 0; q < s->cloth_count; ++q)
            for (int a = 0; a < 3; ++a) {
                rbc_cloth_state *c = s->cloths[q];
                float *tmp = c->p[a];
                c->p[a] = c->alt[a];
                c->alt[a] = tmp;
            }
    rbc_pool_barrier(s->pool);
}

/* Contacts join the solve after every linear iteration: cloth contact costs several
 * sweeps a pass, but a pass every third iteration left four stacked layers 2-3 mm
 * deeper than their 2 mm thickness and let them pass through each other sooner
 * (docs/design/cloth-contact.md). Collider and host contacts are projected here
 * unless the color sweeps did (color_pass). */
static unsigned iteration_pass(const step_ctx *ctx, uint32_t k) {
    const int jac = is_jacobi(ctx->s->settings.kind);
    return (jac && !(k & 1) ? RBC_PASS_ALT : 0u) | RBC_PASS_CLOTH |
           (!ctx->color_pass ? RBC_PASS_COLLIDERS : 0u);
}

/* Whether this global step's ELL sweeps read the packed positions (ell.h): only the
 * color sweeps write p between its iterations, i.e. no contacts of any kind are
 * projected between them, and not the Chebyshev stash (CSR rows). Then p is packed
 * once here, for every ELL cloth, before the first iteration. */
static int ell_pack_all(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    const rbc_solver_kind kind = s->settings.kind;
    if (!ctx->color_pass || kind == RBC_SOLVER_RBGS_CHEBYSHEV || ctx->cc_active ||
        ctx->any_contacts || ctx->host_contacts)
        return 0;
    int any = 0;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        if (c->lattice || !c->ell) continue;
        rbc_ell_pack(c->ell, c, tid, nt);
        any = 1;
    }
    if (any) rbc_pool_barrier(s->pool);
    return any;
}

/* The global step of one non-linear iteration: iterate until the mode says stop. */
static void global_step(step_ctx *ctx, uint32_t segment, uint32_t nsegments, uint32_t tid,
                        uint32_t nt) {
    rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    if (st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV || st->kind == RBC_SOLVER_RBGS_CHEBYSHEV) {
        /* p^(k-1) starts as the initial guess: the first (unaccelerated) iteration
         * does not read it. */
        for (uint32_t q = 0; q < s->cloth_count; ++q) {
            rbc_cloth_state *c = s->cloths[q];
            uint32_t b, e;
            rbc_split(c->topo.n, tid, nt, &b, &e);
            for (int a = 0; a < 3; ++a)
                memcpy(c->prev[a] + b, c->p[a] + b, (size_t)(e - b) * sizeof(float));
        }
        rbc_pool_barrier(s->pool);
    }
    const rbc_sweep_plan pl = rbc_sweep_plan_global(ctx, segment, nsegments);
    if (pl.wave || pl.pre) wavefront(ctx, pl.wave ? pl.limit : pl.pre, tid, nt);
    if (pl.wave) {
        if (tid == 0) ctx->linear_done += pl.limit;
        return;
    }
    double deadline = ctx->start_ms + (double)st->budget_ms * (segment + 1) / nsegments;
    const int packed = ell_pack_all(ctx, tid, nt);
    uint32_t k = pl.pre;
    for (;;) {
        double t0 = tid == 0 ? rbc_now_ms() : 0.0;
        linear_iteration(ctx, k, packed, tid, nt);
        rbc_step_project_contacts(ctx, iteration_pass(ctx, k), tid, nt);
        k++;
        if (pl.fixed) {
            if (k >= pl.limit) break;
            continue;
        }
        if (st->mode == RBC_ITERATE_TARGET) {
            if (k < pl.first && k < pl.limit) continue;
            rbc_target_check(ctx, k, pl.limit, is_jacobi(st->kind) && (k & 1), tid, nt);
        } else if (st->mode == RBC_ITERATE_TOLERANCE) {
            tolerance_check(ctx, k, pl.limit, tid, nt);
        } else if (tid == 0) { /* budget: stop when another iteration would pass the deadline */
            double t1 = rbc_now_ms();
            ctx->stop = k >= pl.limit || t1 + (t1 - t0) > deadline;
        }
        rbc_pool_barrier(s->pool);
        if (ctx->stop) break;
    }
    if (tid == 0) ctx->linear_done += k;
    if (is_jacobi(st->kind) && (k & 1)) jacobi_swap_back(ctx, tid);
}

void rbc_stage_global(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    if (s->settings.kind != RBC_SOLVER_DIRECT) {
        global_step(ctx, at->sub * s->nonlinear_iterations + at->nl,
                    ctx->substeps * s->nonlinear_iterations, at->tid, at->nt);
        return;
    }
    /* One exact solve per cloth; cloths are spread over the threads. */
    for (uint32_t q = at->tid; q < s->cloth_count; q += at->nt) {
        rbc_cloth_state *c = s->cloths[q];
        rbc_direct_solve(c->direct, &c->topo, c->pinned, c->w, (const float *const *)c->y, c->dx,
                         c->dy, c->dz, c->p);
    }
    rbc_pool_barrier(s->pool);
    rbc_step_project_contacts(ctx, RBC_PASS_CLOTH | RBC_PASS_COLLIDERS, at->tid, at->nt);
    if (at->tid == 0) ctx->linear_done += 1;
}
