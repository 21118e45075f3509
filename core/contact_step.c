/* contact_step.c -- the contact stages of a step (contact_step.h). */
#include "contact_step.h"

#include <string.h>

#include "clothcontact.h"
#include "collide.h"
#include "energy.h"
#include "energy_guard.h"
#include "host_callbacks.h"
#include "report.h"

/* Contacts join the solve after a linear iteration (its barrier passed): each thread
 * projects the collider contacts of its own particles (unary constraints: no race),
 * then thread 0 the host's contacts, then every thread one pass of cloth contact by
 * the contacts' own colors (constraints between particles that may share a spring
 * color, so not inside the parallel color sweeps: docs/design/cloth-contact.md). Friction is added only on the first pass of a substep,
 * onto the prediction, when the color sweeps solve the contacts (color_pass). */
static void pool_sync(void *pool) { rbc_pool_barrier(pool); }

void rbc_step_project_contacts(step_ctx *ctx, unsigned pass, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    const int colliders = (pass & RBC_PASS_COLLIDERS) != 0, alt = (pass & RBC_PASS_ALT) != 0;
    const int cloth = (pass & RBC_PASS_CLOTH) && ctx->cc_active;
    const int any = colliders && ctx->any_contacts, host = colliders && ctx->host_contacts;
    const float fh = (pass & RBC_PASS_FRICTION) && ctx->color_pass ? ctx->h : 0.0f;
    if (!any && !host && !cloth) return;
    if (any) rbc_collide_project(s, &s->contacts[tid], alt, fh);
    if (host || cloth) {
        rbc_pool_barrier(s->pool);
        if (tid == 0 && host) rbc_collide_project(s, &s->host_contacts, alt, fh);
    }
    if (cloth) {
        if (tid == 0)
            for (uint32_t k = 0; k < s->cloth_count; ++k)
                for (int a = 0; a < 3; ++a)
                    s->cc_bodies[k].p[a] = alt ? s->cloths[k]->alt[a] : s->cloths[k]->p[a];
        /* After the host's contacts, which may move the same particles. */
        rbc_pool_barrier(s->pool);
        rbc_clothcontact_project_mt(s->cc, s->cc_bodies, s->cloth_count, tid, nt, pool_sync,
                                    s->pool);
    }
    rbc_pool_barrier(s->pool);
}

/* Collider contacts over the substep's motion, per thread. Lists that overflow grow
 * (thread 0, between barriers; a steady scene stops allocating) and detection runs
 * again. */
static void detect_colliders(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    const float f0 = (float)at->sub / (float)ctx->substeps;
    const float f1 = (float)(at->sub + 1) / (float)ctx->substeps;
    for (;;) {
        rbc_collide_detect(s, &s->contacts[at->tid], f0, f1, ctx->h, at->tid, at->nt);
        rbc_pool_barrier(s->pool);
        if (at->tid == 0) {
            ctx->grow = 0;
            ctx->any_contacts = 0;
            uint32_t total = 0;
            for (uint32_t th = 0; th < at->nt; ++th) {
                rbc_contact_list *l = &s->contacts[th];
                total += l->need;
                if (l->need <= l->cap) continue;
                ctx->grow = 1;
                if (rbc_contact_list_reserve(l, &s->alloc) != 0) {
                    ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                           "out of memory for %u collider contacts at "
                                           "substep %u", l->need, at->sub);
                    break;
                }
            }
            ctx->any_contacts = total > 0;
            s->last_contacts = total;
        }
        rbc_pool_barrier(s->pool);
        if (ctx->result != RBC_OK || !ctx->grow) break;
    }
}

/* Thread 0: the cloth-contact view of every cloth (positions, rest shape, flags). */
static void fill_contact_bodies(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        rbc_contact_body *b = &s->cc_bodies[k];
        memset(b, 0, sizeof *b);
        b->n = c->topo.n;
        for (int a = 0; a < 3; ++a) {
            b->p[a] = c->p[a];
            b->x[a] = c->x[a];
        }
        b->rest[0] = c->topo.rest_x;
        b->rest[1] = c->topo.rest_y;
        b->rest[2] = c->topo.rest_z;
        b->mass = c->topo.mass;
        b->pinned = c->pinned;
        b->tri_count = c->collision_flags ? c->tri_count : 0;
        b->tris = c->tris;
        b->thickness = c->thickness;
        b->friction = c->friction;
        b->self = (c->collision_flags & RBC_CLOTH_COLLIDE_SELF) != 0;
        b->others = (c->collision_flags & RBC_CLOTH_COLLIDE_CLOTHS) != 0;
    }
}

/* Cloth contact is found every substep, over each particle's motion from x to its
 * prediction (once per step, over the motion extrapolated to the step's end, was 8x
 * cheaper but let stacked layers pass through each other: docs/design/cloth-contact.md). */
static void detect_cloth(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    if (at->tid == 0) fill_contact_bodies(s);
    /* A quarter of a spring: the solve moves particles from their prediction by up
     * to about half a spring where they hit something, and what a smaller margin
     * misses the fail-safe catches (half a spring made 13 times the contacts in the
     * resting four-layer pile and the scene twice as slow: docs/design/cloth-contact.md). */
    float margin = 0.0f;
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        if (s->cloths[k]->collision_flags && 0.25f * s->cloths[k]->mean_rest > margin)
            margin = 0.25f * s->cloths[k]->mean_rest;
    rbc_pool_barrier(s->pool);
    /* Every thread finds the contacts of its share of the vertices (the list is the
     * same for any thread count). */
    int32_t rc = rbc_clothcontact_detect_mt(s->cc, s->cc_bodies, s->cloth_count, margin, at->tid,
                                            at->nt, pool_sync, s->pool);
    if (at->tid != 0) return;
    if (rc == RBC_ERR_UNSTABLE)
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                               "cloth contact: more than %u contacts per vertex at substep %u "
                               "of %u: the cloths are crushed or tangled beyond what contact "
                               "can hold (smaller steps, more iterations, or a larger "
                               "thickness keep them apart); the world was restored to its "
                               "state before the step",
                               RBC_CC_MAX_TOTAL_PER_VERTEX, at->sub, ctx->substeps);
    else if (rc != RBC_OK)
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                               "out of memory for cloth contacts at substep %u", at->sub);
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        for (int a = 0; a < 3; ++a) s->cc_bodies[k].p[a] = s->cloths[k]->p[a];
    s->last_cloth_contacts = rbc_clothcontact_count(s->cc);
    s->last_cloth_capped = rbc_clothcontact_capped(s->cc);
}

void rbc_stage_detect(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    if (s->collider_count) detect_colliders(ctx, at);
    /* Every thread meets this barrier: thread 0 may fail the step inside the
     * callback, and a worker that read ctx->result after that would skip the
     * barrier and leave thread 0 waiting for ever (found by rbcloth-conformance). */
    if (s->contact_fn) {
        /* detect_colliders' workers read ctx->result after its last barrier: they
         * must be past that read before the callback may write it (a data race
         * ThreadSanitizer found under rbcloth-conformance). */
        if (s->collider_count) rbc_pool_barrier(s->pool);
        if (at->tid == 0 && ctx->result == RBC_OK) rbc_step_run_contact_callback(ctx, at->sub);
        rbc_pool_barrier(s->pool);
    }
    if (ctx->cc_active && ctx->result == RBC_OK) detect_cloth(ctx, at);
    if (ctx->cc_active) rbc_pool_barrier(s->pool);
    /* Start the solve from the prediction moved onto the contacts, so the first
     * local step takes the springs' directions from a state that respects them.
     * (From y itself, a contact that lifts part of the cloth during the solve would
     * carry the rest along rigidly: the global step keeps each spring's direction
     * from the local step. The inertial target y stays as predicted.) */
    if (ctx->result == RBC_OK)
        rbc_step_project_contacts(ctx, RBC_PASS_CLOTH | RBC_PASS_COLLIDERS | RBC_PASS_FRICTION,
                                  at->tid, at->nt);
    rbc_pool_barrier(s->pool);
}

void rbc_stage_friction(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    const uint32_t tid = at->tid;
    const float f0 = (float)at->sub / (float)ctx->substeps;
    const float f1 = (float)(at->sub + 1) / (float)ctx->substeps;
    if (s->collider_count) {
        /* Every contact's normal force from the solve's positions, before any
         * friction moves one (a neighbour may be another thread's). */
        if (!ctx->color_pass) {
            rbc_collide_normal_forces(s, &s->contacts[tid], ctx->h);
            if (tid == 0 && ctx->host_contacts)
                rbc_collide_normal_forces(s, &s->host_contacts, ctx->h);
            rbc_pool_barrier(s->pool);
        }
        rbc_collide_finish(s, &s->contacts[tid], ctx->h, tid, at->nt, NULL, ctx->color_pass);
        /* The work the colliders did (impulse . their velocity; a static one supplies
         * nothing). */
        rbc_collide_post(s, f0, f1, ctx->h, tid, at->nt);
        rbc_pool_barrier(s->pool);
        if (rbc_step_guarded(ctx) && tid == 0) rbc_guard_add_collider_work(ctx);
        rbc_pool_barrier(s->pool);
    }
    if (ctx->host_contacts) {
        /* Host contacts: friction, and their work on the cloth they touch. */
        if (tid == 0) {
            const int guard = rbc_step_guarded(ctx);
            rbc_contact_list *l = &s->host_contacts;
            if (!s->collider_count && !ctx->color_pass) rbc_collide_normal_forces(s, l, ctx->h);
            for (uint32_t m = 0; m < l->count; ++m) {
                rbc_contact_list one = {&l->c[m], 1, 1, 1};
                double w = 0.0;
                rbc_collide_finish(s, &one, ctx->h, 0, 1, &w, ctx->color_pass);
                if (guard) s->cloths[l->c[m].cloth]->guard.step_budget += w;
            }
        }
        rbc_pool_barrier(s->pool);
    }
}

void rbc_stage_cloth_contact(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    if (at->tid == 0) rbc_clothcontact_friction(s->cc, s->cc_bodies, s->cloth_count);
    rbc_pool_barrier(s->pool);
    /* The last word: no edge ends the substep through another layer. */
    uint32_t frozen = 0;
    if (rbc_clothcontact_failsafe_mt(s->cc, s->cc_bodies, s->cloth_count, at->tid, at->nt,
                                     pool_sync, s->pool, &frozen) != RBC_OK &&
        at->tid == 0)
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                               "out of memory for the cloth contact fail-safe at substep %u; "
                               "the world was restored to its state before the step",
                               at->sub);
    if (at->tid == 0) s->last_frozen += frozen;
    rbc_pool_barrier(s->pool);
}
