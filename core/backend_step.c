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

#include "global.h"
#include "kernels/pd_kernels.h"
#include "report.h"
#include "stage.h"

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
    else if (st->mode != RBC_ITERATE_FIXED)
        what = "an iteration mode other than RBC_ITERATE_FIXED (tolerance, budget and target "
               "need the residual or strain on the device)";
    else if (st->energy_guard != RBC_ENERGY_GUARD_OFF)
        what = "the energy guard (set the solver's energy_guard to RBC_ENERGY_GUARD_OFF)";
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
                          d->pin_idx, d->pin_start, d->pin_target, d->bad, d->cols, d->mass,
                          d->ksum, d->ncon, d->ct};
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
    if (rc == RBC_OK) rc = up(bk, d->ksum, t->ksum, nf);
    if (rc != RBC_OK) {
        rbc_fail(err, errlen, rc, "cloth 0x%08x: upload to the %s backend failed: %s",
                 c->public_id, bk->ops->name, bk->ops->last_error(bk->be));
        rbc_backend_cloth_free(bk, &s->alloc, c);
    }
    return rc;
}

/* What changes between steps: the state, pins and (with h) the weights. */
static int32_t cloth_upload(const rbc_backend_handle *bk, rbc_cloth_state *c, float h, char *err,
                            size_t errlen) {
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
                            "cloth 0x%08x: out of %s memory for %u pins", c->public_id,
                            bk->ops->name, c->pin_count);
    }
    d->pin_count = c->pin_count;
    if (c->pin_count) {
        rc = up(bk, d->pin_idx, c->pin_idx, c->pin_count * sizeof(uint32_t));
        if (rc == RBC_OK) rc = up(bk, d->pin_start, c->pin_start, 3 * c->pin_count * sizeof(float));
        if (rc == RBC_OK)
            rc = up(bk, d->pin_target, c->pin_target, 3 * c->pin_count * sizeof(float));
    }
    if (rc == RBC_OK) rc = up(bk, d->pinned, c->pinned, d->n);
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
                        "cloth 0x%08x: out of %s memory for %u colliders' contacts",
                        c->public_id, bk->ops->name, nc);
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

/* One global step of cloth c (linear iterations of the selected solver). */
static int32_t global_step(const rbc_backend_handle *bk, const step_ctx *ctx, uint32_t slot,
                           rbc_dcloth *d) {
    const rbc_solver *s = ctx->s;
    const rbc_solver_kind kind = s->settings.kind;
    const uint32_t count = s->linear_iterations;
    rbc_kargs a = {.c = d};
    int32_t rc = RBC_OK;
    const int cheb = kind == RBC_SOLVER_JACOBI_CHEBYSHEV || kind == RBC_SOLVER_RBGS_CHEBYSHEV;
    if (cheb) {
        for (int ax = 0; ax < 3; ++ax) {
            a.src[ax] = d->p[ax];
            a.dst[ax] = d->prev[ax];
        }
        rc = launch(bk, RBC_KERNEL_COPY, &a, 0, d->n);
    }
    if (kind == RBC_SOLVER_JACOBI || kind == RBC_SOLVER_JACOBI_CHEBYSHEV) {
        a.variant = kind == RBC_SOLVER_JACOBI_CHEBYSHEV;
        for (uint32_t k = 0; rc == RBC_OK && k < count; ++k) {
            a.omega = a.variant ? rbc_chebyshev_omega(k, s->settings.chebyshev_delay,
                                                      ctx->cheb_rho[slot])
                                : 1.0f;
            for (int ax = 0; ax < 3; ++ax) {
                a.src[ax] = (k & 1) ? d->alt[ax] : d->p[ax];
                a.dst[ax] = (k & 1) ? d->p[ax] : d->alt[ax];
            }
            rc = launch(bk, RBC_KERNEL_JACOBI, &a, 0, d->n);
            if (rc == RBC_OK) rc = contacts_project(bk, d, 0, d->n, a.dst, 0.0f);
        }
        if (count & 1) /* the last iteration wrote alt: make it p */
            for (int ax = 0; ax < 3; ++ax) {
                float *tmp = d->p[ax];
                d->p[ax] = d->alt[ax];
                d->alt[ax] = tmp;
            }
        return rc;
    }
    a.variant = kind == RBC_SOLVER_RBGS_SOR         ? RBC_K_GS_SOR
                : kind == RBC_SOLVER_RBGS_CHEBYSHEV ? RBC_K_GS_STASH
                                                    : RBC_K_GS_PLAIN;
    a.omega = ctx->sor_omega[slot];
    for (uint32_t k = 0; rc == RBC_OK && k < count; ++k) {
        for (uint32_t color = 0; rc == RBC_OK && color < d->ncolors; ++color) {
            const uint32_t c0 = d->color_start[color], nc = d->color_start[color + 1] - c0;
            rc = launch(bk, RBC_KERNEL_GS, &a, c0, nc);
            if (rc == RBC_OK && ctx->color_pass) rc = contacts_project(bk, d, c0, nc, d->p, ctx->h);
        }
        if (rc == RBC_OK && a.variant == RBC_K_GS_STASH) {
            rbc_kargs bl = {.c = d};
            bl.omega = rbc_chebyshev_omega(k, s->settings.chebyshev_delay, ctx->cheb_rho[slot]);
            rc = launch(bk, RBC_KERNEL_CHEB_BLEND, &bl, 0, d->n);
        }
        if (rc == RBC_OK && !ctx->color_pass) rc = contacts_project(bk, d, 0, d->n, d->p, 0.0f);
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

/* Every substep of cloth k; its state comes back to the host only if all are
 * finite. */
static int32_t cloth_step(const rbc_backend_handle *bk, step_ctx *ctx, uint32_t k) {
    rbc_solver *s = ctx->s;
    rbc_cloth_state *c = s->cloths[k];
    rbc_dcloth *d = c->dev;
    const float h = ctx->h, h2 = h * h;
    float keep = 1.0f - c->damping * h;
    if (keep < 0.0f) keep = 0.0f; /* as stage_integrate */
    int32_t rc = RBC_OK;
    for (uint32_t sub = 0; rc == RBC_OK && sub < ctx->substeps; ++sub) {
        rbc_kargs a = {.c = d, .keep = keep};
        for (int ax = 0; ax < 3; ++ax) a.g_h2[ax] = s->gravity[ax] * h2;
        rc = launch(bk, RBC_KERNEL_PREDICT, &a, 0, d->n);
        a.f = (float)(sub + 1) / (float)ctx->substeps;
        a.last = sub + 1 == ctx->substeps;
        if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_PINS, &a, 0, d->pin_count);
        if (rc == RBC_OK) rc = contacts_detect(bk, ctx, c, d, sub);
        for (uint32_t nl = 0; rc == RBC_OK && nl < s->nonlinear_iterations; ++nl) {
            rc = launch(bk, RBC_KERNEL_LOCAL, &a, 0, d->ns);
            if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_RHS, &a, 0, d->n);
            if (rc == RBC_OK) rc = global_step(bk, ctx, rbc_step_slot(k), d);
        }
        if (rc == RBC_OK) rc = contacts_finish(bk, ctx, c, d);
        /* Non-finite values stay so in later substeps (every kernel reads them), so
         * the check's verdict is read once, after the last. */
        if (rc == RBC_OK) rc = launch(bk, RBC_KERNEL_CHECK, &a, 0, d->n);
        if (rc == RBC_OK && a.last && rbc_step_can_run_away(s->settings.kind)) {
            a.stretch = RBC_BLOWUP_STRETCH;
            a.floor_len = RBC_BLOWUP_STRETCH * c->mean_rest;
            rc = launch(bk, RBC_KERNEL_SPRINGS, &a, 0, d->ns);
        }
        for (int ax = 0; ax < 3; ++ax) { /* commit: q <- x <- p */
            float *old_q = d->q[ax];
            d->q[ax] = d->x[ax];
            d->x[ax] = d->p[ax];
            d->p[ax] = old_q;
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

void rbc_backend_run(const rbc_backend_handle *bk, step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    const char *name = bk->ops->name;
    int32_t rc = RBC_OK;
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (!c->dev) rc = cloth_create(bk, s, c, ctx->err, ctx->errlen);
        if (rc == RBC_OK) rc = cloth_upload(bk, c, ctx->h, ctx->err, ctx->errlen);
        if (rc == RBC_OK) rc = colliders_upload(bk, s, c, ctx->err, ctx->errlen);
    }
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        rc = cloth_step(bk, ctx, k);
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "cloth 0x%08x: a launch on the %s backend "
                     "failed: %s", s->cloths[k]->public_id, name, bk->ops->last_error(bk->be));
    }
    if (rc == RBC_OK && (rc = bk->ops->sync(bk->be)) != RBC_OK)
        rbc_fail(ctx->err, ctx->errlen, rc, "the %s backend's step failed: %s", name,
                 bk->ops->last_error(bk->be));
    /* The verdicts first: the host's state changes only when every cloth passed. */
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        int32_t bad[4];
        rc = bk->ops->download(bk->be, bad, s->cloths[k]->dev->bad, sizeof bad);
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "readback from the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
        else if (bad[0] || bad[1] || bad[2])
            rc = report_bad(ctx, k, bad);
        else /* the stats' collider contacts, as the pool's detect stage counts them */
            s->last_contacts += (uint32_t)bad[3];
    }
    /* Readback of x and q into the host's arrays; a failure half-way is the snapshot's
     * to undo (rbc_solver_step restores it on any failed step). */
    for (uint32_t k = 0; rc == RBC_OK && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const size_t nf = (size_t)c->topo.n * sizeof(float);
        for (int a = 0; rc == RBC_OK && a < 3; ++a) {
            rc = bk->ops->download(bk->be, c->x[a], c->dev->x[a], nf);
            if (rc == RBC_OK) rc = bk->ops->download(bk->be, c->q[a], c->dev->q[a], nf);
        }
        if (rc != RBC_OK)
            rbc_fail(ctx->err, ctx->errlen, rc, "readback from the %s backend failed: %s",
                     name, bk->ops->last_error(bk->be));
    }
    if (rc == RBC_OK)
        ctx->linear_done = ctx->substeps * s->nonlinear_iterations * s->linear_iterations;
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
