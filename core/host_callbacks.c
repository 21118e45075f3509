/* host_callbacks.c -- the host's collision and contact callbacks inside a step
 * (host_callbacks.h). */
#include "host_callbacks.h"

#include <math.h>
#include <string.h>

#include "collide.h"
#include "energy_guard.h"
#include "report.h"

/* The host callbacks' view: p (positions) and x (previous) of every cloth in host
 * order, in the host-order buffers, listed in s->cb_list. */
static void fill_host_buffers(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const uint32_t *to_int = c->topo.to_internal;
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            uint32_t i = to_int[v];
            for (int a = 0; a < 3; ++a) {
                c->cb_pos[3 * (size_t)v + a] = c->p[a][i];
                c->cb_prev[3 * (size_t)v + a] = c->x[a][i];
            }
        }
        s->cb_list[k].cloth = c->public_id;
        s->cb_list[k].vertex_count = c->topo.n;
        s->cb_list[k].positions = c->cb_pos;
        s->cb_list[k].previous_positions = c->cb_prev;
    }
}

/* Thread 0, all others waiting at a barrier: hand host-order positions to the host's
 * collision code and take its corrections back (pins win). */
static void run_callback(step_ctx *ctx, uint32_t sub) {
    rbc_solver *s = ctx->s;
    fill_host_buffers(s);
    int32_t r = s->callback(s->callback_user, s->public_world_id, ctx->h, s->cb_list,
                            s->cloth_count);
    if (r != 0) {
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                               "the collision callback returned %d at substep %u", (int)r, sub);
        return;
    }
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const uint32_t *to_int = c->topo.to_internal;
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            const float *hp = &c->cb_pos[3 * (size_t)v];
            if (!(isfinite(hp[0]) && isfinite(hp[1]) && isfinite(hp[2]))) {
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                                       "the collision callback wrote a non-finite position for "
                                       "cloth 0x%08x vertex %u at substep %u",
                                       c->public_id, v, sub);
                return;
            }
            uint32_t i = to_int[v];
            if (c->pinned[i]) continue;
            c->p[0][i] = hp[0];
            c->p[1][i] = hp[1];
            c->p[2][i] = hp[2];
        }
    }
}

void rbc_stage_callback(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    /* The host's corrections count as work it does: the change of energy. */
    const int guard = rbc_step_guarded(ctx);
    if (guard)
        rbc_guard_budget_add(ctx, -1.0, at->tid, at->nt);
    else if (rbc_step_uses(ctx, RBC_STAGE_CLOTH_CONTACT))
        /* The cloth-contact stage's verdict is read at its end: no thread may have
         * a failure of this stage in ctx->result before every thread has read it. */
        rbc_pool_barrier(s->pool);
    if (at->tid == 0) run_callback(ctx, at->sub);
    rbc_pool_barrier(s->pool);
    if (ctx->result != RBC_OK) return;
    if (guard) rbc_guard_budget_add(ctx, 1.0, at->tid, at->nt);
}

/* The host's contact sink (rbc_contact_sink.add): check each contact, append it to
 * the host list with its particle's internal index and cloth position. */
typedef struct sink_impl {
    step_ctx *ctx;
    uint32_t sub;
} sink_impl;

/* What is wrong with a host contact, or NULL; *k is its cloth's index. */
static const char *host_contact_problem(const rbc_solver *s, const rbc_host_contact *h,
                                        uint32_t *k, float *nn) {
    *k = 0;
    while (*k < s->cloth_count && s->cloths[*k]->public_id != h->cloth) ++*k;
    *nn = h->normal[0] * h->normal[0] + h->normal[1] * h->normal[1] + h->normal[2] * h->normal[2];
    if (*k == s->cloth_count) return "names no cloth of the world";
    if (h->vertex >= s->cloths[*k]->topo.n) return "has a vertex out of range";
    if (!(fabsf(*nn - 1.0f) <= 1e-3f)) return "has a normal that is not unit";
    if (!(isfinite(h->offset) && isfinite(h->velocity[0]) && isfinite(h->velocity[1]) &&
          isfinite(h->velocity[2])))
        return "has a non-finite offset or velocity";
    if (!(isfinite(h->friction) && h->friction >= 0.0f))
        return "has a friction that is not finite and >= 0";
    return NULL;
}

static rbc_result RBC_CALL sink_add(rbc_contact_sink *sink, const rbc_host_contact *hc,
                                    uint32_t count) {
    sink_impl *im = sink->impl;
    step_ctx *ctx = im->ctx;
    rbc_solver *s = ctx->s;
    rbc_contact_list *l = &s->host_contacts;
    if (count && !hc) return RBC_ERR_INVALID_ARGUMENT;
    for (uint32_t m = 0; m < count; ++m) {
        const rbc_host_contact *h = &hc[m];
        uint32_t k;
        float nn;
        const char *what = host_contact_problem(s, h, &k, &nn);
        if (what) {
            if (ctx->result == RBC_OK)
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                                       "the contact callback's contact %u (cloth 0x%08x, vertex "
                                       "%u) %s, at substep %u",
                                       m, h->cloth, h->vertex, what, im->sub);
            return RBC_ERR_INVALID_ARGUMENT;
        }
        rbc_cloth_state *c = s->cloths[k];
        uint32_t i = c->topo.to_internal[h->vertex];
        if (c->pinned[i]) continue; /* pins win */
        if (l->count == l->cap) {
            l->need = l->cap + 1;
            if (rbc_contact_list_reserve(l, &s->alloc) != 0) {
                if (ctx->result == RBC_OK)
                    ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                           "out of memory for %u host contacts", l->cap + 1);
                return RBC_ERR_OUT_OF_MEMORY;
            }
        }
        rbc_col_contact *ct = &l->c[l->count++];
        memset(ct, 0, sizeof *ct);
        ct->cloth = k;
        ct->idx = i;
        float inv = 1.0f / sqrtf(nn);
        for (int a = 0; a < 3; ++a) {
            ct->n[a] = h->normal[a] * inv;
            ct->u[a] = h->velocity[a];
        }
        ct->d = h->offset;
        float pen = ct->d - (ct->n[0] * c->p[0][i] + ct->n[1] * c->p[1][i] + ct->n[2] * c->p[2][i]);
        ct->depth = pen > 0.0f ? pen : 0.0f;
        ct->mu = h->friction;
        ct->collider = UINT32_MAX;
        ct->color = rbc_collide_color_of(&c->topo, i);
    }
    return RBC_OK;
}

void rbc_step_run_contact_callback(step_ctx *ctx, uint32_t sub) {
    rbc_solver *s = ctx->s;
    fill_host_buffers(s);
    s->host_contacts.count = 0;
    sink_impl im = {ctx, sub};
    rbc_contact_sink sink = {&im, sink_add};
    int32_t r = s->contact_fn(s->contact_user, s->public_world_id, ctx->h, s->cb_list,
                              s->cloth_count, &sink);
    if (r != 0 && ctx->result == RBC_OK)
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                               "the contact callback returned %d at substep %u", (int)r, sub);
    ctx->host_contacts = s->host_contacts.count > 0;
    s->last_host_contacts = s->host_contacts.count;
}
