/* backend_step.c -- the substeps of a step on a backend (backend.h): Algorithm 1 as a
 * sequence of kernel launches, written once for every backend.
 *
 * rbc_solver_step (step.c) does the serial work around it on the host for every
 * backend alike (substeps, weights, SOR's omega and Chebyshev's rho, pins' paths,
 * the strain warning, stats); between steps the host's x and q are the state, so a
 * failed step leaves them as they were and every host call that reads or writes the
 * state works unchanged. */
#include "backend_step.h"

#include <stdio.h>
#include <string.h>

#include "energy.h"
#include "energy_guard.h"
#include "global.h"
#include "kernels/pd_kernels.h"
#include "report.h"
#include "stage.h"
#include "strain.h"
#include "sweep.h"
#include "target.h"

static int32_t refuse(const char *backend, const char *what, char *err, size_t errlen) {
    return rbc_fail(err, errlen, RBC_ERR_UNSUPPORTED,
                    "the %s backend does not run %s yet; nothing was run elsewhere", backend,
                    what);
}

/* The first setting a backend does not run, or NULL. */
static const char *settings_refused(const rbc_solver_settings *st) {
    const char *what = NULL;
    if (st->kind == RBC_SOLVER_GAUSS_SEIDEL)
        what = "the serial Gauss-Seidel solver (RBC_SOLVER_GAUSS_SEIDEL has no parallel "
               "form; use rbgs or multicolor)";
    else if (st->kind == RBC_SOLVER_DIRECT)
        what = "the direct solver (RBC_SOLVER_DIRECT)";
    return what;
}

int32_t rbc_backend_settings_check(const rbc_solver_settings *st, const char *backend,
                                   char *err, size_t errlen) {
    const char *what = settings_refused(st);
    return what ? refuse(backend, what, err, errlen) : RBC_OK;
}

/* The first collider a backend does not run, or NULL: the analytic shapes run
 * (collide_kernels.h); the triangle mesh's BVH queries are the CPU's (shapes.c). */
static const char *colliders_refused(const rbc_solver *s) {
    for (uint32_t k = 0; k < s->collider_count; ++k)
        if (s->colliders[k].shape == RBC_SHAPE_TRIANGLE_MESH)
            return "the triangle mesh collider (RBC_SHAPE_TRIANGLE_MESH; planes, spheres, "
                   "capsules and boxes run)";
    return NULL;
}

int32_t rbc_backend_scene_check(const rbc_solver *s, const char *backend, char *err,
                                size_t errlen) {
    const char *what = settings_refused(&s->settings);
    if (!what) what = colliders_refused(s);
    if (what)
        ;
    else if (s->callback)
        what = "the host collision callback (rbc_collision_fn)";
    else if (s->contact_fn)
        what = "the host contact callback (rbc_contact_fn)";
    else if (s->wind_drag != 0.0f || s->wind_lift != 0.0f)
        what = "wind";
    else if (rbc_guard_on(s) && s->collider_count)
        what = "the energy guard with colliders (their work is not summed on a backend yet; "
               "set energy_guard to RBC_ENERGY_GUARD_OFF)";
    for (uint32_t k = 0; !what && k < s->cloth_count; ++k) {
        const rbc_cloth_state *c = s->cloths[k];
        if (c->collision_flags && c->thickness > 0.0f)
            what = "cloth contact (collision flags)";
        else if (c->tear_strain > 0.0f)
            what = "tearing (tear_strain)";
        else if (c->att.count)
            what = "attachments to colliders";
        else if (c->torn)
            what = "cut or torn springs (the backend's copy of the topology is not updated)";
    }
    return what ? refuse(backend, what, err, errlen) : RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* A cloth's copy on the backend                                              */
/* ------------------------------------------------------------------------- */

static void *dalloc(const rbc_backend_handle *bk, size_t bytes, int *ok) {
    void *p = *ok ? bk->ops->alloc(bk->be, bytes ? bytes : 1) : NULL;
    if (!p) *ok = 0;
    return p;
}

void rbc_backend_cloth_free(const rbc_backend_handle *bk, const rbc_allocator *al, rbc_cloth_state *c) {
    rbc_dcloth *d = c->dev;
    if (!d) return;
    void *const ptrs[] = {d->adj_start, d->adj_nbr, d->adj_k, d->sa, d->sb, d->he_a, d->he_b,
                          d->rest, d->ux, d->uy, d->uz, d->w, d->inv_denom, d->pinned,
                          d->pin_idx, d->pin_start, d->pin_target, d->bad,
                          d->sums, d->strain_blk, d->e_blk, d->stiff, d->pin_springs,
                          d->cols, d->mass, d->ksum, d->ncon, d->ct};
    for (size_t k = 0; k < sizeof ptrs / sizeof ptrs[0]; ++k)
        if (ptrs[k]) bk->ops->release(bk->be, ptrs[k]);
    float **sets[] = {d->x, d->q, d->p, d->y, d->d, d->b, d->alt, d->prev};
    for (size_t k = 0; k < sizeof sets / sizeof sets[0]; ++k)
        for (int a = 0; a < 3; ++a)
            if (sets[k][a]) bk->ops->release(bk->be, sets[k][a]);
    memset(d, 0, sizeof *d);
    c->dev = NULL;
    rbc_mem_free(al, d, sizeof *d);
}

static int32_t up(const rbc_backend_handle *bk, void *dst, const void *src, size_t bytes) {
    return bk->ops->upload(bk->be, dst, src, bytes);
}

/* The cloth's topology on the backend (once; pins are uploaded every step). */
static int32_t cloth_create(const rbc_backend_handle *bk, rbc_solver *s, rbc_cloth_state *c, char *err,
                            size_t errlen) {
    const rbc_topology *t = &c->topo;
    rbc_dcloth *d = rbc_mem_alloc(&s->alloc, sizeof *d);
    if (!d) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory (host)");
    memset(d, 0, sizeof *d);
    c->dev = d;
    d->n = t->n;
    d->ns = t->ns;
    d->ncolors = t->ncolors;
    memcpy(d->color_start, t->color_start, sizeof d->color_start);
    const size_t n = t->n, ns = t->ns, nf = n * sizeof(float), nh = 2 * ns;
    int ok = 1;
    d->adj_start = dalloc(bk, (n + 1) * sizeof(uint32_t), &ok);
    d->adj_nbr = dalloc(bk, nh * sizeof(uint32_t), &ok);
    d->adj_k = dalloc(bk, nh * sizeof(float), &ok);
    d->sa = dalloc(bk, ns * sizeof(uint32_t), &ok);
    d->sb = dalloc(bk, ns * sizeof(uint32_t), &ok);
    d->he_a = dalloc(bk, ns * sizeof(uint32_t), &ok);
    d->he_b = dalloc(bk, ns * sizeof(uint32_t), &ok);
    d->rest = dalloc(bk, ns * sizeof(float), &ok);
    d->ux = dalloc(bk, ns * sizeof(float), &ok);
    d->uy = dalloc(bk, ns * sizeof(float), &ok);
    d->uz = dalloc(bk, ns * sizeof(float), &ok);
    d->w = dalloc(bk, nf, &ok);
    d->inv_denom = dalloc(bk, nf, &ok);
    d->pinned = dalloc(bk, n, &ok);
    d->bad = dalloc(bk, 4 * sizeof(int32_t), &ok);
    d->strain_blocks = (t->ns + RBC_STRAIN_BLOCK - 1u) / RBC_STRAIN_BLOCK;
    d->energy_blocks = rbc_energy_blocks_of(t->n);
    d->sums = dalloc(bk, 3 * sizeof(double), &ok);
    d->strain_blk = dalloc(bk, 2 * (size_t)d->strain_blocks * sizeof(double), &ok);
    d->e_blk = dalloc(bk, (size_t)RBC_EPB * d->energy_blocks * sizeof(double), &ok);
    d->stiff = dalloc(bk, ns * sizeof(float), &ok);
    d->mass = dalloc(bk, nf, &ok);
    d->ksum = dalloc(bk, nf, &ok);
    for (int a = 0; a < 3; ++a) {
        d->x[a] = dalloc(bk, nf, &ok);
        d->q[a] = dalloc(bk, nf, &ok);
        d->p[a] = dalloc(bk, nf, &ok);
        d->y[a] = dalloc(bk, nf, &ok);
        d->b[a] = dalloc(bk, nf, &ok);
        d->d[a] = dalloc(bk, nh * sizeof(float), &ok);
        d->alt[a] = dalloc(bk, nf, &ok);
        d->prev[a] = dalloc(bk, nf, &ok);
    }
    if (!ok) {
        rbc_backend_cloth_free(bk, &s->alloc, c);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                        "cloth 0x%08x: out of %s memory for %u particles and %u springs "
                        "(%s)",
                        c->public_id, bk->ops->name, t->n, t->ns, bk->ops->last_error(bk->be));
    }
    int32_t rc = RBC_OK;
    if (rc == RBC_OK) rc = up(bk, d->adj_start, t->adj_start, (n + 1) * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->adj_nbr, t->adj_nbr, nh * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->adj_k, t->adj_k, nh * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->sa, t->sa, ns * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->sb, t->sb, ns * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->he_a, t->he_a, ns * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->he_b, t->he_b, ns * sizeof(uint32_t));
    if (rc == RBC_OK) rc = up(bk, d->rest, t->rest_len, ns * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->ux, t->ux, ns * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->uy, t->uy, ns * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->uz, t->uz, ns * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->mass, t->mass, nf);
    if (rc == RBC_OK) rc = up(bk, d->stiff, t->stiff, ns * sizeof(float));
    if (rc == RBC_OK) rc = up(bk, d->ksum, t->ksum, nf);
    if (rc != RBC_OK) {
        rbc_fail(err, errlen, rc, "cloth 0x%08x: upload to the %s backend failed: %s",
                 c->public_id, bk->ops->name, bk->ops->last_error(bk->be));
        rbc_backend_cloth_free(bk, &s->alloc, c);
    }
    return rc;
}

/* What changes between steps: the state, pins and (with h) the weights. */
static int32_t cloth_upload(const rbc_backend_handle *bk, rbc_cloth_state *c, float h, int guard,
                            char *err, size_t errlen) {
    rbc_dcloth *d = c->dev;
    const size_t nf = (size_t)d->n * sizeof(float);
    int32_t rc = RBC_OK;
    if (c->pin_count > d->pin_cap) {
        if (d->pin_idx) bk->ops->release(bk->be, d->pin_idx);
        if (d->pin_start) bk->ops->release(bk->be, d->pin_start);
        if (d->pin_target) bk->ops->release(bk->be, d->pin_target);
        int ok = 1;
        d->pin_idx = dalloc(bk, c->pin_count * sizeof(uint32_t), &ok);
        d->pin_start = dalloc(bk, 3 * c->pin_count * sizeof(float), &ok);
        d->pin_target = dalloc(bk, 3 * c->pin_count * sizeof(float), &ok);
        d->pin_cap = ok ? c->pin_count : 0;
        if (!ok)
            return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                            "cloth 0x%08x: out of %s memory for %u pins (%s)", c->public_id,
                            bk->ops->name, c->pin_count, bk->ops->last_error(bk->be));
    }
    d->pin_count = c->pin_count;
    if (c->pin_count) {
        rc = up(bk, d->pin_idx, c->pin_idx, c->pin_count * sizeof(uint32_t));
        if (rc == RBC_OK) rc = up(bk, d->pin_start, c->pin_start, 3 * c->pin_count * sizeof(float));
        if (rc == RBC_OK)
            rc = up(bk, d->pin_target, c->pin_target, 3 * c->pin_count * sizeof(float));
    }
    if (rc == RBC_OK) rc = up(bk, d->pinned, c->pinned, d->n);
    /* The energy guard: the springs the pins' work is summed over (they change with
     * the pins), and the budget the device adds that work to, substep by substep in
     * the pool's order. */
    d->pin_spring_count = 0;
    if (rc == RBC_OK && guard && c->pin_spring_count) {
        if (c->pin_spring_count > d->pin_spring_cap) {
            if (d->pin_springs) bk->ops->release(bk->be, d->pin_springs);
            int ok = 1;
            d->pin_springs = dalloc(bk, c->pin_spring_count * sizeof(uint32_t), &ok);
            d->pin_spring_cap = ok ? c->pin_spring_count : 0;
            if (!ok)
                return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                                "cloth 0x%08x: out of %s memory for %u springs at pins (%s)",
                                c->public_id, bk->ops->name, c->pin_spring_count,
                                bk->ops->last_error(bk->be));
        }
        rc = up(bk, d->pin_springs, c->pin_springs, c->pin_spring_count * sizeof(uint32_t));
        d->pin_spring_count = c->pin_spring_count;
    }
    if (rc == RBC_OK && guard) {
        const double sums[3] = {0.0, 0.0, c->guard.step_budget};
        rc = up(bk, d->sums, sums, sizeof sums);
    }
    /* The weights change only with h here: masses and stiffness change only by
     * tearing and cuts, which the scene check refuses (their topology would need a
     * new upload too). */
    if (rc == RBC_OK && d->h != h) {
        rc = up(bk, d->w, c->w, nf);
        if (rc == RBC_OK) rc = up(bk, d->inv_denom, c->inv_denom, nf);
        d->h = rc == RBC_OK ? h : 0.0f;
    }
    for (int a = 0; rc == RBC_OK && a < 3; ++a) {
        rc = up(bk, d->x[a], c->x[a], nf);
        if (rc == RBC_OK) rc = up(bk, d->q[a], c->q[a], nf);
    }
    static const int32_t zero[4] = {0, 0, 0, 0};
    if (rc == RBC_OK) rc = up(bk, d->bad, zero, sizeof zero);
    if (rc != RBC_OK)
        return rbc_fail(err, errlen, rc, "cloth 0x%08x: upload to the %s backend failed: %s",
                        c->public_id, bk->ops->name, bk->ops->last_error(bk->be));
    return RBC_OK;
}

/* The world's colliders for cloth c's copy (each cloth holds its own: a few hundred
 * bytes, freed with it), and room for its contacts: min(colliders, RBC_KC_SLOTS)
 * slots per particle, since a particle has at most one contact per collider. */
static int32_t colliders_upload(const rbc_backend_handle *bk, rbc_solver *s, rbc_cloth_state *c,
                                char *err, size_t errlen) {
    rbc_dcloth *d = c->dev;
    const uint32_t nc = s->collider_count;
    const uint32_t slots = nc < RBC_KC_SLOTS ? nc : RBC_KC_SLOTS;
    d->ncols = 0;
    d->slots = 0;
    if (!nc) return RBC_OK;
    int ok = 1;
    if (nc > d->cols_cap) {
        if (d->cols) bk->ops->release(bk->be, d->cols);
        d->cols = dalloc(bk, nc * sizeof(rbc_dcollider), &ok);
        d->cols_cap = ok ? nc : 0;
    }
    if (ok && slots > d->slots_cap) {
        if (d->ct) bk->ops->release(bk->be, d->ct);
        if (d->ncon) bk->ops->release(bk->be, d->ncon);
        d->ct = dalloc(bk, (size_t)RBC_KC_FIELDS * slots * d->n * sizeof(float), &ok);
        d->ncon = dalloc(bk, (size_t)d->n * sizeof(uint32_t), &ok);
        d->slots_cap = ok ? slots : 0;
    }
    if (!ok)
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                        "cloth 0x%08x: out of %s memory for %u colliders' contacts (%s)",
                        c->public_id, bk->ops->name, nc, bk->ops->last_error(bk->be));
    rbc_dcollider *h = rbc_mem_alloc(&s->alloc, nc * sizeof *h);
    if (!h) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory (host)");
    memset(h, 0, nc * sizeof *h);
    for (uint32_t k = 0; k < nc; ++k) {
        const rbc_collider_state *col = &s->colliders[k];
        h[k].shape = (int32_t)col->shape;
        h[k].radius = col->radius;
        h[k].thickness = col->thickness;
        h[k].friction = col->friction;
        memcpy(h[k].he, col->half_extents, sizeof h[k].he);
        memcpy(h[k].lo, col->lo, sizeof h[k].lo);
        memcpy(h[k].hi, col->hi, sizeof h[k].hi);
        memcpy(h[k].last_position, col->last_position, sizeof h[k].last_position);
        memcpy(h[k].last_rotation, col->last_rotation, sizeof h[k].last_rotation);
        memcpy(h[k].position, col->position, sizeof h[k].position);
        memcpy(h[k].rotation, col->rotation, sizeof h[k].rotation);
    }
    /* The upload has the source staged when it returns (backend.h), so h may go. */
    int32_t rc = up(bk, d->cols, h, nc * sizeof *h);
    rbc_mem_free(&s->alloc, h, nc * sizeof *h);
    if (rc != RBC_OK)
        return rbc_fail(err, errlen, rc, "cloth 0x%08x: upload to the %s backend failed: %s",
                        c->public_id, bk->ops->name, bk->ops->last_error(bk->be));
    d->ncols = nc;
    d->slots = slots;
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* The schedule                                                               */
/* ------------------------------------------------------------------------- */

/* Stage by stage over every cloth, in the pool's order (step.c, sweep.c): what the
 * modes decide on (the residual and strain summed over all cloths) then reads the
 * same iterates the pool's checks read. */

static int32_t launch(const rbc_backend_handle *bk, rbc_kernel k, rbc_kargs *a, uint32_t first,
                      uint32_t count) {
    a->first = first;
    a->count = count;
    return bk->ops->launch(bk->be, k, a);
}

/* The collider contacts' projection (collide.h) over particles [first, first +
 * count) of P: after a Jacobi or Chebyshev iteration the whole iterate (h = 0), after
 * a color's sweep with color passes that color with its friction (h > 0), as
 * sweep.c's color_iteration and iteration_pass. */
static int32_t contacts_project(const rbc_backend_handle *bk, rbc_dcloth *d, uint32_t first,
                                uint32_t count, float *const P[3], float h) {
    if (!d->ncols) return RBC_OK;
    rbc_kargs a = {.c = d, .h = h};
    for (int ax = 0; ax < 3; ++ax) a.dst[ax] = P[ax];
    return launch(bk, RBC_KERNEL_COLLIDE_PROJECT, &a, first, count);
}

static rbc_dcloth *dev(const rbc_solver *s, uint32_t k) { return s->cloths[k]->dev; }

static int is_jacobi(rbc_solver_kind kind) {
    return kind == RBC_SOLVER_JACOBI || kind == RBC_SOLVER_JACOBI_CHEBYSHEV;
}

/* Linear iteration k of the selected solver on every cloth, with the contacts'
 * projections that join it (each touches only its own particle, so the cloths'
 * order does not matter). */
static int32_t linear_iteration(const rbc_backend_handle *bk, const step_ctx *ctx, uint32_t k) {
    const rbc_solver *s = ctx->s;
    const rbc_solver_kind kind = s->settings.kind;
    int32_t rc = RBC_OK;
    if (is_jacobi(kind)) {
        for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
            rbc_dcloth *d = dev(s, q);
            rbc_kargs a = {.c = d, .variant = kind == RBC_SOLVER_JACOBI_CHEBYSHEV};
            a.omega = a.variant ? rbc_chebyshev_omega(k, s->settings.chebyshev_delay,
                                                      ctx->cheb_rho[rbc_step_slot(q)])
                                : 1.0f;
            for (int ax = 0; ax < 3; ++ax) { /* even k reads p and writes alt */
                a.src[ax] = (k & 1) ? d->alt[ax] : d->p[ax];
                a.dst[ax] = (k & 1) ? d->p[ax] : d->alt[ax];
            }
            rc = launch(bk, RBC_KERNEL_JACOBI, &a, 0, d->n);
            if (rc == RBC_OK) rc = contacts_project(bk, d, 0, d->n, a.dst, 0.0f);
        }
        return rc;
    }
    const int variant = kind == RBC_SOLVER_RBGS_SOR         ? RBC_K_GS_SOR
                        : kind == RBC_SOLVER_RBGS_CHEBYSHEV ? RBC_K_GS_STASH
                                                            : RBC_K_GS_PLAIN;
    for (uint32_t color = 0; rc == RBC_OK && color < ctx->ncolors; ++color)
        for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
            rbc_dcloth *d = dev(s, q);
            if (color >= d->ncolors) continue;
            rbc_kargs a = {.c = d, .variant = variant, .omega = ctx->sor_omega[rbc_step_slot(q)]};
            const uint32_t c0 = d->color_start[color], nc = d->color_start[color + 1] - c0;
            rc = launch(bk, RBC_KERNEL_GS, &a, c0, nc);
            if (rc == RBC_OK && ctx->color_pass) rc = contacts_project(bk, d, c0, nc, d->p, ctx->h);
        }
    for (uint32_t q = 0; rc == RBC_OK && variant == RBC_K_GS_STASH && q < s->cloth_count; ++q) {
        rbc_kargs bl = {.c = dev(s, q)};
        bl.omega = rbc_chebyshev_omega(k, s->settings.chebyshev_delay,
                                       ctx->cheb_rho[rbc_step_slot(q)]);
        rc = launch(bk, RBC_KERNEL_CHEB_BLEND, &bl, 0, bl.c->n);
    }
    for (uint32_t q = 0; rc == RBC_OK && !ctx->color_pass && q < s->cloth_count; ++q)
        rc = contacts_project(bk, dev(s, q), 0, dev(s, q)->n, dev(s, q)->p, 0.0f);
    return rc;
}

static int32_t readback(const rbc_backend_handle *bk, void *dst, const void *src, size_t bytes) {
    return bk->ops->download(bk->be, dst, src, bytes);
}

/* RBC_ITERATE_TOLERANCE after iteration k: the relative residual of every cloth's
 * rows (sweep.c's tolerance_check: the same rows, the same p). */
static int32_t tolerance_check(const rbc_backend_handle *bk, step_ctx *ctx, uint32_t k,
                               uint32_t limit) {
    rbc_solver *s = ctx->s;
    static const double zero[2] = {0.0, 0.0};
    int32_t rc = RBC_OK;
    for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
        rbc_dcloth *d = dev(s, q);
        rc = up(bk, d->sums, zero, sizeof zero);
        rbc_kargs a = {.c = d};
        const uint32_t end = rbc_sweep_residual_colors(s->settings.kind, d->ncolors);
        if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_RESIDUAL, &a, 0, d->color_start[end]);
    }
    double R = 0.0, B = 0.0;
    for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
        double rb[2];
        rc = readback(bk, rb, dev(s, q)->sums, sizeof rb);
        R += rb[0];
        B += rb[1];
    }
    const double tol = s->settings.tolerance;
    ctx->stop = k >= limit || R <= tol * tol * B;
    return rc;
}

/* RBC_ITERATE_TARGET's check after iteration k: every cloth's strain blocks of the
 * latest iterate into the host's blocks, then target.c decides. */
static int32_t target_check(const rbc_backend_handle *bk, step_ctx *ctx, uint32_t k,
                            uint32_t limit, int alt) {
    rbc_solver *s = ctx->s;
    int32_t rc = RBC_OK;
    for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
        rbc_dcloth *d = dev(s, q);
        rbc_kargs a = {.c = d};
        for (int ax = 0; ax < 3; ++ax) a.pos[ax] = alt ? d->alt[ax] : d->p[ax];
        rc = launch(bk, RBC_KERNEL_STRAIN, &a, 0, d->strain_blocks);
    }
    for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q)
        rc = readback(bk, s->cloths[q]->strain_blk, dev(s, q)->strain_blk,
                      2 * (size_t)dev(s, q)->strain_blocks * sizeof(double));
    if (rc == RBC_OK) rbc_target_decide(ctx, k, limit);
    return rc;
}

/* The global step of one non-linear iteration (segment of nsegments) on every
 * cloth: iterate until the mode says stop, as sweep.c's global_step plans it. */
static int32_t global_step(const rbc_backend_handle *bk, step_ctx *ctx, uint32_t segment,
                           uint32_t nsegments) {
    rbc_solver *s = ctx->s;
    const rbc_solver_settings *st = &s->settings;
    const int jac = is_jacobi(st->kind);
    int32_t rc = RBC_OK;
    if (st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV || st->kind == RBC_SOLVER_RBGS_CHEBYSHEV)
        for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
            rbc_dcloth *d = dev(s, q);
            rbc_kargs a = {.c = d};
            for (int ax = 0; ax < 3; ++ax) {
                a.src[ax] = d->p[ax];
                a.dst[ax] = d->prev[ax];
            }
            rc = launch(bk, RBC_KERNEL_COPY, &a, 0, d->n);
        }
    const rbc_sweep_plan pl = rbc_sweep_plan_global(ctx, segment, nsegments);
    const double deadline = ctx->start_ms + (double)st->budget_ms * (segment + 1) / nsegments;
    uint32_t k = 0;
    while (rc == RBC_OK) {
        const double t0 = rbc_now_ms();
        rc = linear_iteration(bk, ctx, k);
        k++;
        if (rc != RBC_OK) break;
        if (pl.fixed) {
            if (k >= pl.limit) break;
            continue;
        }
        if (st->mode == RBC_ITERATE_TARGET) {
            if (k < pl.first && k < pl.limit) continue;
            rc = target_check(bk, ctx, k, pl.limit, jac && (k & 1));
        } else if (st->mode == RBC_ITERATE_TOLERANCE) {
            rc = tolerance_check(bk, ctx, k, pl.limit);
        } else {
            /* The budget: an iteration's time is what the device took for it, so wait
             * for it (a sync per iteration: this mode pays a launch's latency). */
            rc = bk->ops->sync(bk->be);
            const double t1 = rbc_now_ms();
            ctx->stop = k >= pl.limit || t1 + (t1 - t0) > deadline;
        }
        if (ctx->stop) break;
    }
    ctx->linear_done += k;
    if (jac && (k & 1)) /* the last iteration wrote alt: make it p */
        for (uint32_t q = 0; q < s->cloth_count; ++q)
            for (int ax = 0; ax < 3; ++ax) {
                rbc_dcloth *d = dev(s, q);
                float *tmp = d->p[ax];
                d->p[ax] = d->alt[ax];
                d->alt[ax] = tmp;
            }
    return rc;
}

/* The substep's collider contacts (contact_step.c's detect stage): the frames, the
 * contacts of every particle's motion from x to its prediction, and the solve's start
 * moved onto them (with friction when the color passes solve the contacts). */
static int32_t contacts_detect(const rbc_backend_handle *bk, const step_ctx *ctx,
                               const rbc_cloth_state *c, rbc_dcloth *d, uint32_t sub) {
    if (!d->ncols) return RBC_OK;
    rbc_kargs a = {.c = d, .h = ctx->h, .thick = c->thickness, .mu = c->friction,
                   .margin = 0.5f * c->mean_rest};
    a.f0 = (float)sub / (float)ctx->substeps;
    a.f = (float)(sub + 1) / (float)ctx->substeps;
    a.last = sub + 1 == ctx->substeps;
    int32_t rc = launch(bk, RBC_KERNEL_COLLIDE_FRAMES, &a, 0, d->ncols);
    if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_COLLIDE_DETECT, &a, 0, d->n);
    if (rc == RBC_OK) rc = contacts_project(bk, d, 0, d->n, d->p, ctx->color_pass ? ctx->h : 0.0f);
    return rc;
}

/* After the solve (contact_step.c's friction stage): the normal forces and friction
 * where the color passes did not apply it, then the safety pass. The colliders' work
 * is the energy guard's, which backends refuse. */
static int32_t contacts_finish(const rbc_backend_handle *bk, const step_ctx *ctx,
                               const rbc_cloth_state *c, rbc_dcloth *d) {
    if (!d->ncols) return RBC_OK;
    rbc_kargs a = {.c = d, .h = ctx->h, .thick = c->thickness, .margin = 0.5f * c->mean_rest};
    int32_t rc = RBC_OK;
    if (!ctx->color_pass) {
        rc = launch(bk, RBC_KERNEL_COLLIDE_NORMAL, &a, 0, d->n);
        if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_COLLIDE_FINISH, &a, 0, d->n);
    }
    if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_COLLIDE_POST, &a, 0, d->n);
    return rc;
}

/* Every substep of every cloth; the state comes back to the host only if all are
 * finite. */
static int32_t substeps(const rbc_backend_handle *bk, step_ctx *ctx, int guard) {
    rbc_solver *s = ctx->s;
    const float h = ctx->h, h2 = h * h;
    const uint32_t nseg = ctx->substeps * s->nonlinear_iterations;
    int32_t rc = RBC_OK;
    for (uint32_t sub = 0; rc == RBC_OK && sub < ctx->substeps; ++sub) {
        const int last = sub + 1 == ctx->substeps;
        for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
            rbc_cloth_state *c = s->cloths[q];
            rbc_dcloth *d = c->dev;
            float keep = 1.0f - c->damping * h;
            if (keep < 0.0f) keep = 0.0f; /* as stage_integrate */
            rbc_kargs a = {.c = d, .keep = keep};
            for (int ax = 0; ax < 3; ++ax) a.g_h2[ax] = s->gravity[ax] * h2;
            rc = launch(bk, RBC_KERNEL_PREDICT, &a, 0, d->n);
            a.f = (float)(sub + 1) / (float)ctx->substeps;
            a.last = last;
            if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_PINS, &a, 0, d->pin_count);
            if (rc == RBC_OK && d->pin_spring_count) { /* the pins moved from x to p */
                for (int ax = 0; ax < 3; ++ax) {
                    a.pos[ax] = d->p[ax];
                    a.prev[ax] = d->x[ax];
                }
                rc = launch(bk, RBC_KERNEL_PIN_WORK, &a, 0, 1);
            }
            if (rc == RBC_OK) rc = contacts_detect(bk, ctx, c, d, sub);
        }
        for (uint32_t nl = 0; rc == RBC_OK && nl < s->nonlinear_iterations; ++nl) {
            for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
                rbc_kargs a = {.c = dev(s, q)};
                rc = launch(bk, RBC_KERNEL_LOCAL, &a, 0, a.c->ns);
                if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_RHS, &a, 0, a.c->n);
            }
            if (rc == RBC_OK) rc = global_step(bk, ctx, sub * s->nonlinear_iterations + nl, nseg);
        }
        for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
            rbc_dcloth *d = dev(s, q);
            rbc_kargs a = {.c = d};
            rc = contacts_finish(bk, ctx, s->cloths[q], d);
            /* Non-finite values stay so in later substeps (every kernel reads them),
             * so the check's verdict is read once, after the last. */
            if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_CHECK, &a, 0, d->n);
            if (rc == RBC_OK && last && rbc_step_can_run_away(s->settings.kind)) {
                a.stretch = RBC_BLOWUP_STRETCH;
                a.floor_len = RBC_BLOWUP_STRETCH * s->cloths[q]->mean_rest;
                rc = launch(bk, RBC_KERNEL_SPRINGS, &a, 0, d->ns);
            }
            if (rc == RBC_OK && last && guard) { /* the guard's energy of p against x */
                for (int ax = 0; ax < 3; ++ax) {
                    a.pos[ax] = d->p[ax];
                    a.prev[ax] = d->x[ax];
                    a.g[ax] = s->gravity[ax];
                }
                rc = launch(bk, RBC_KERNEL_ENERGY, &a, 0, d->energy_blocks);
            }
            for (int ax = 0; ax < 3; ++ax) { /* commit: q <- x <- p */
                float *old_q = d->q[ax];
                d->q[ax] = d->x[ax];
                d->x[ax] = d->p[ax];
                d->p[ax] = old_q;
            }
        }
    }
    return rc;
}

/* A failure the checks found on cloth k: the message, as step.c words it. */
static int32_t report_bad(step_ctx *ctx, uint32_t k, const int32_t bad[4]) {
    const rbc_cloth_state *c = ctx->s->cloths[k];
    const rbc_topology *t = &c->topo;
    if (bad[2]) /* first: the contacts it dropped made the rest of the step wrong */
        return rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSUPPORTED,
                        "cloth 0x%08x: vertex %u touched more than %u colliders in one "
                        "substep, more than the backend's %u contact slots per particle; "
                        "the world was restored to its state before the step (fewer "
                        "overlapping colliders, or a world without a backend)",
                        c->public_id, t->to_host[bad[2] - 1], (unsigned)RBC_KC_SLOTS,
                        (unsigned)RBC_KC_SLOTS);
    if (bad[0]) {
        uint32_t i = (uint32_t)bad[0] - 1;
        return rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                        "cloth 0x%08x: vertex %u became non-finite within the step's %u "
                        "substeps (h = %g s, stiffness*h^2/mass up to %g); the world was "
                        "restored to its state before the step",
                        c->public_id, t->to_host[i], ctx->substeps, (double)ctx->h,
                        (double)(t->ksum[i] / c->w[i]));
    }
    uint32_t sp = (uint32_t)bad[1] - 1;
    return rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                    "cloth 0x%08x: the spring between vertices %u and %u was stretched past "
                    "%g times its rest length at the step's last substep: the global solver "
                    "diverged (more iterations, more substeps, or rbgs keep it stable); the "
                    "world was restored to its state before the step",
                    c->public_id, t->to_host[t->sa[sp]], t->to_host[t->sb[sp]],
                    (double)RBC_BLOWUP_STRETCH);
}

/* The energy guard's decision (energy_guard.c) from the device's sums: each cloth's
 * budget with the pins' work, and its energy blocks at the last substep. */
static int32_t guard_decide(const rbc_backend_handle *bk, step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    int32_t rc = RBC_OK;
    for (uint32_t q = 0; rc == RBC_OK && q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        double sums[3];
        rc = readback(bk, sums, c->dev->sums, sizeof sums);
        if (rc == RBC_OK) c->guard.step_budget = sums[2];
        if (rc == RBC_OK)
            rc = readback(bk, c->e_blk, c->dev->e_blk,
                          (size_t)RBC_EPB * c->dev->energy_blocks * sizeof(double));
    }
    if (rc != RBC_OK) return rc;
    ctx->result = RBC_OK;
    rbc_guard_decide(ctx); /* the failure mode's verdict goes into ctx->result */
    return RBC_OK;
}

void rbc_backend_run(const rbc_backend_handle *bk, step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    const char *name = bk->ops->name;
    const int guard = rbc_guard_on(s);
    int32_t rc = RBC_OK;
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (!c->dev) rc = cloth_create(bk, s, c, ctx->err, ctx->errlen);
        if (rc == RBC_OK) rc = cloth_upload(bk, c, ctx->h, guard, ctx->err, ctx->errlen);
        if (rc == RBC_OK) rc = colliders_upload(bk, s, c, ctx->err, ctx->errlen);
    }
    /* A fixed count reads nothing back within the step: the backend may record the
     * step's launches and run them as one (a CUDA graph). The other modes decide on
     * readbacks between iterations. */
    const int record = bk->ops->step_begin && s->settings.mode == RBC_ITERATE_FIXED;
    if (rc == RBC_OK && record && (rc = bk->ops->step_begin(bk->be)) != RBC_OK)
        rbc_fail(ctx->err, ctx->errlen, rc, "the %s backend could not start a step: %s", name,
                 bk->ops->last_error(bk->be));
    else if (rc == RBC_OK) {
        rc = substeps(bk, ctx, guard);
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "a launch or readback on the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
        const int32_t re = record ? bk->ops->step_end(bk->be) : RBC_OK;
        if (rc == RBC_OK && (rc = re) != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "the %s backend's recorded step failed: %s",
                     name, bk->ops->last_error(bk->be));
    }
    if (rc == RBC_OK && (rc = bk->ops->sync(bk->be)) != RBC_OK)
        rbc_fail(ctx->err, ctx->errlen, rc, "the %s backend's step failed: %s", name,
                 bk->ops->last_error(bk->be));
    /* The verdicts first: the host's state changes only when every cloth passed. */
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        int32_t bad[4];
        rc = readback(bk, bad, s->cloths[k]->dev->bad, sizeof bad);
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "readback from the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
        else if (bad[0] || bad[1] || bad[2])
            rc = report_bad(ctx, k, bad);
        else /* the stats' collider contacts, as the pool's detect stage counts them */
            s->last_contacts += (uint32_t)bad[3];
    }
    if (rc == RBC_OK && guard) {
        rc = guard_decide(bk, ctx);
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "readback from the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
        else
            rc = ctx->result;
    }
    /* Readback of x and q into the host's arrays; a failure half-way is the snapshot's
     * to undo (rbc_solver_step restores it on any failed step). */
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const size_t nf = (size_t)c->topo.n * sizeof(float);
        for (int a = 0; rc == RBC_OK && a < 3; ++a) {
            rc = readback(bk, c->x[a], c->dev->x[a], nf);
            if (rc == RBC_OK) rc = readback(bk, c->q[a], c->dev->q[a], nf);
        }
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "readback from the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
    }
    /* The guard's clamp, on the committed state the host now holds (the device's
     * copy is uploaded again next step). */
    if (rc == RBC_OK && guard && ctx->clamp) rbc_guard_apply_committed(s);
    ctx->result = rc;
}

void rbc_solver_set_backend(rbc_solver *s, const rbc_backend_handle *bk) {
    if (bk && bk->ops == s->backend.ops && bk->be == s->backend.be) return; /* already */
    if (s->backend.ops) {
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            rbc_backend_cloth_free(&s->backend, &s->alloc, s->cloths[k]);
        s->backend.ops->close(s->backend.be);
    }
    s->backend.ops = bk ? bk->ops : NULL;
    s->backend.be = bk ? bk->be : NULL;
}

void rbc_solver_release_backend_copy(rbc_solver *s, rbc_cloth_state *c) {
    rbc_backend_cloth_free(&s->backend, &s->alloc, c);
}
