/* energy_guard.c -- the energy guard's stages of a step (energy_guard.h). */
#include "energy_guard.h"

#include <math.h>
#include <stdio.h>

#include "energy.h"
#include "kernels/measure_kernels.h"
#include "report.h"

int rbc_guard_on(const rbc_solver *s) {
    return s->settings.energy_guard != RBC_ENERGY_GUARD_OFF;
}

/* The energy and budget at the step's start: cached from the last step, or
 * recomputed (all threads) for cloths whose state, pins, gravity or h changed. */
void rbc_stage_budget(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    int any = 0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->guard.valid && c->guard.h == ctx->h) continue;
        rbc_energy_blocks(c, c->x, c->q, s->gravity, 1, at->tid, at->nt);
        any = 1;
    }
    if (any) rbc_pool_barrier(s->pool);
    if (at->tid != 0) return;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_guard *g = &s->cloths[k]->guard;
        if (g->valid && g->h == ctx->h) {
            g->step_budget = g->budget;
        } else {
            rbc_energy e = rbc_energy_sum(s->cloths[k], ctx->h, s->gravity, 1);
            /* A new state: everything it holds may become motion, spring energy
             * included. Otherwise keep what the cloth had not yet spent (the springs'
             * energy among it). */
            double slack = e.spring;
            if (g->valid || g->keep_slack) {
                slack = g->budget - g->last;
                if (slack < 0.0) slack = 0.0;
            }
            g->step_budget = e.guarded + slack;
        }
        g->removed = g->kept = 0.0;
        g->scale = 1.0f;
    }
}

void rbc_guard_add_pin_work(step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->pin_spring_count) c->guard.step_budget += rbc_energy_pin_work(c, c->x, c->p);
    }
}

void rbc_guard_add_collider_work(step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        s->cloths[k]->guard.step_budget += rbc_energy_sum_work(s->cloths[k]);
}

void rbc_guard_budget_add(step_ctx *ctx, double sign, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        rbc_energy_blocks(s->cloths[k], s->cloths[k]->p, s->cloths[k]->x, s->gravity, 0, tid, nt);
    rbc_pool_barrier(s->pool);
    if (tid == 0)
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            s->cloths[k]->guard.step_budget +=
                sign * rbc_energy_sum(s->cloths[k], ctx->h, s->gravity, 0).guarded;
    /* Thread 0 reads every thread's energy blocks above; the next pass that writes
     * them (the check, or the callback's budget pass) must wait for it. */
    rbc_pool_barrier(s->pool);
}

void rbc_guard_decide(step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    int fail_mode = s->settings.energy_guard == RBC_ENERGY_GUARD_FAIL;
    ctx->clamp = 0;
    s->energy_note[0] = '\0';
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        rbc_cloth_guard *g = &c->guard;
        rbc_energy e = rbc_energy_sum(c, ctx->h, s->gravity, 0);
        double excess = e.guarded - g->step_budget;
        g->end = e.guarded;
        g->scale = 1.0f;
        if (!(excess > e.tolerance)) continue;
        if (fail_mode) {
            ctx->result = rbc_fail(
                ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                "cloth 0x%08x: the step ended with %.6g J of kinetic + gravitational energy, "
                "%.3g J more than the %.6g J the cloth was given (start, pins, colliders, "
                "callback): the global solver added energy (more iterations, rbgs or direct, "
                "or smaller steps keep it out); the energy guard (RBC_ENERGY_GUARD_FAIL) "
                "restored the world to its state before the step",
                c->public_id, e.guarded, excess, g->step_budget);
            return;
        }
        if (excess < e.kinetic) {
            /* Scale the velocities: kinetic energy s^2 KE = KE - excess. */
            g->scale = (float)sqrt(1.0 - excess / e.kinetic);
            g->removed = excess;
            g->end = g->step_budget;
        } else {
            /* The positions alone hold more than the budget: stop every free particle
             * and keep the rest (reported; the budget grows by it). */
            g->scale = 0.0f;
            g->removed = e.kinetic;
            g->kept = excess - e.kinetic;
            g->end = e.guarded - e.kinetic;
            g->step_budget += g->kept;
        }
        ctx->clamp = 1;
        if (!s->energy_note[0])
            snprintf(s->energy_note, sizeof s->energy_note,
                     "cloth 0x%08x: the step added %.3g J of kinetic + gravitational energy "
                     "beyond the %.6g J the cloth was given; the energy guard removed %.3g J "
                     "of kinetic energy (velocities scaled by %.6g)%s",
                     c->public_id, excess, g->step_budget - g->kept, g->removed,
                     (double)g->scale,
                     g->kept > 0.0 ? " and kept the rest, held in the positions" : "");
    }
}

/* The clamp's new previous positions x = p - scale (p - x), so that after the commit
 * (q <- x, x <- p) the velocities are scaled and positions kept. */
void rbc_guard_apply(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->guard.scale == 1.0f) continue;
        const float f = c->guard.scale;
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        for (int a = 0; a < 3; ++a)
            for (uint32_t i = b; i < e; ++i) rbc_k_guard_scale(i, f, c->pinned, c->p[a], c->x[a]);
    }
}

void rbc_guard_apply_committed(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->guard.scale == 1.0f) continue;
        for (int a = 0; a < 3; ++a)
            for (uint32_t i = 0; i < c->topo.n; ++i)
                rbc_k_guard_scale(i, c->guard.scale, c->pinned, c->x[a], c->q[a]);
    }
}

void rbc_guard_commit(rbc_solver *s, const step_ctx *ctx) {
    s->energy_removed_last = 0.0;
    s->energy_clamped_last = 0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_guard *g = &s->cloths[k]->guard;
        if (!rbc_guard_on(s)) {
            g->valid = 0;
            continue;
        }
        g->last = g->end;
        g->budget = g->step_budget;
        g->h = ctx->h;
        g->valid = 1;
        g->keep_slack = 1;
        s->energy_removed_last += g->removed;
        if (g->scale != 1.0f) s->energy_clamped_last = 1;
    }
    if (s->energy_clamped_last) s->energy_clamped_steps++;
}
