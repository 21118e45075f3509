/* step.c -- Algorithm 1 of the paper on the CPU backend: rbc_solver_step.
 *
 * One step runs a single SPMD function (step_spmd) on every pool thread. It calls
 * the stages of rbc_stage in order; each stage splits its range statically among
 * the threads and ends at a barrier where the next stage reads what it wrote:
 *
 *   budget         energy guard: the energy each cloth may end the step with
 *   for each substep:
 *     integrate    Alg. 2: y = Verlet prediction, p = y                 (particles)
 *     pins         pinned particles on their way to the pin targets
 *     wind         drag and lift on the quads
 *     detect       the substep's collider, host and cloth contacts
 *     loop nonlinear_iterations:
 *       local      Alg. 3: d_ij for every spring, and the right-hand side (springs)
 *       global     Eq. 6 by the selected solver and sweep (sweep.c), with the
 *                  contacts joining each linear iteration
 *     friction     collider and host contacts: friction, the colliders' work
 *     cloth contact  friction and the fail-safe
 *     callback     the host's collision code, on thread 0
 *     check        every position finite, every spring within bounds
 *     energy       (last substep) clamp or fail an energy gain
 *     commit       q <- x <- p (buffer rotation, thread 0)
 *
 * The particles of one color share no spring, so the threads of a color sweep never
 * read a position another thread writes: the result is bitwise independent of the
 * thread count. A stage a scene does not use (no wind, no contact, no callback, no
 * guard) is skipped whole.
 */
#include "stage.h"

#include <math.h>
#include <string.h>

#include "attach.h"
#include "clothcontact.h"
#include "contact_step.h"
#include "energy.h"
#include "energy_guard.h"
#include "global.h"
#include "backend_step.h"
#include "lattice.h"
#include "host_callbacks.h"
#include "kernels/pd_kernels.h"
#include "report.h"
#include "simd.h"
#include "step_threads.h"
#include "strain.h"
#include "sweep.h"
#include "target.h"
#include "tear.h"
#include "wind.h"

/* ------------------------------------------------------------------------- */
/* The stages kept here: integrate, pins, wind, local, check, energy, commit  */
/* ------------------------------------------------------------------------- */

RBC_VECTOR_CLONES
static void predict_axis(uint32_t count, const float *restrict x, const float *restrict q,
                         float *restrict y, float *restrict p, float keep, float g_h2) {
    for (uint32_t i = 0; i < count; ++i) {
        float v = x[i] + keep * (x[i] - q[i]) + g_h2;
        y[i] = v;
        p[i] = v;
    }
}

/* No barrier: each thread places the pins of its own range next (stage_pins). */
static void stage_integrate(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    float h = ctx->h, h2 = h * h;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        float keep = 1.0f - c->damping * h;
        if (keep < 0.0f) keep = 0.0f; /* damping * h > 1 would reverse velocities */
        uint32_t b, e;
        rbc_split(c->topo.n, at->tid, at->nt, &b, &e);
        /* rbc_k_predict one coordinate at a time, through restrict pointers: the
         * same arithmetic, vectorized (the buffers never alias). */
        for (int a = 0; a < 3; ++a)
            predict_axis(e - b, c->x[a] + b, c->q[a] + b, c->y[a] + b, c->p[a] + b, keep,
                         s->gravity[a] * h2);
    }
}

/* Pinned particles follow their pins: linearly from where they were at the start of
 * the step to the target, reached at the last substep. Each thread places the pins
 * inside its own integrate range; the barrier closes the prediction, so the stage
 * runs in every scene. */
static void stage_pins(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    float f = (float)(at->sub + 1) / (float)ctx->substeps;
    int last = at->sub + 1 == ctx->substeps;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        rbc_split(c->topo.n, at->tid, at->nt, &b, &e);
        for (uint32_t m = 0; m < c->pin_count; ++m) {
            uint32_t i = c->pin_idx[m];
            if (i < b || i >= e) continue;
            rbc_k_pin(m, c->pin_idx, c->pin_start, c->pin_target, f, last, c->p[0], c->p[1],
                      c->p[2]);
        }
    }
    rbc_pool_barrier(s->pool);
    if (rbc_step_guarded(ctx) && at->tid == 0) rbc_guard_add_pin_work(ctx);
}

/* Wind on the quads (shared corners: one thread). */
static void stage_wind(step_ctx *ctx, const rbc_step_at *at) {
    if (at->tid == 0) rbc_wind_apply(ctx->s, ctx->h);
    rbc_pool_barrier(ctx->s->pool);
}

/* Whether a cloth's local step runs fused with the right-hand side on the lattice
 * (lattice.h): not for the direct solver, which reads the per-spring d arrays. */
static int grid_local(const rbc_solver *s, const rbc_cloth_state *c) {
    return c->lattice && s->settings.kind != RBC_SOLVER_DIRECT;
}

static void stage_local(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (grid_local(s, c)) continue;
        const rbc_topology *t = &c->topo;
        uint32_t b, e;
        rbc_split(t->ns, at->tid, at->nt, &b, &e);
        for (uint32_t sp = b; sp < e; ++sp)
            rbc_k_local(sp, t->sa, t->sb, t->rest_len, t->ux, t->uy, t->uz, t->he_a, t->he_b,
                        c->p[0], c->p[1], c->p[2], c->dx, c->dy, c->dz);
    }
    rbc_pool_barrier(s->pool); /* every spring's d before the sums over them */
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        if (grid_local(s, c))
            rbc_lattice_rhs(c->lattice, c, at->tid, at->nt);
        else
            rbc_global_rhs(c, at->tid, at->nt);
    }
    rbc_pool_barrier(s->pool);
}

/* This thread's first spring past the bound: 1 and ctx->bad set if one is. */
static int check_springs(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const rbc_topology *t = &c->topo;
        uint32_t b, e;
        rbc_split(t->ns, tid, nt, &b, &e);
        const float floor_len = RBC_BLOWUP_STRETCH * c->mean_rest;
        for (uint32_t sp = b; sp < e; ++sp) {
            if (c->torn && t->stiff[sp] == 0.0f) continue; /* broken: no bound */
            /* A NaN passes here; the particle check names it. */
            if (!rbc_k_spring_ok(sp, t->sa, t->sb, t->rest_len, RBC_BLOWUP_STRETCH, floor_len,
                                 c->p[0], c->p[1], c->p[2])) {
                ctx->bad[tid][0] = k;
                ctx->bad[tid][1] = sp;
                ctx->bad[tid][2] = 2;
                return 1;
            }
        }
    }
    return 0;
}

/* This thread's first non-finite particle. */
static void check_particles(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        const float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
        /* Branch-free accumulation: x - x is 0 for finite x and NaN otherwise. */
        float acc = 0.0f;
        for (uint32_t i = b; i < e; ++i) acc += (px[i] - px[i]) + (py[i] - py[i]) + (pz[i] - pz[i]);
        if (acc == 0.0f) continue;
        for (uint32_t i = b; i < e; ++i) {
            if (!(isfinite(px[i]) && isfinite(py[i]) && isfinite(pz[i]))) {
                ctx->bad[tid][0] = k;
                ctx->bad[tid][1] = i;
                ctx->bad[tid][2] = 1;
                return;
            }
        }
    }
}

/* Thread 0: the message for the first failure any thread found. */
static void report_check(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    for (uint32_t th = 0; th < at->nt; ++th) {
        if (ctx->bad[th][0] < 0) continue;
        rbc_cloth_state *c = s->cloths[ctx->bad[th][0]];
        const rbc_topology *t = &c->topo;
        uint32_t i = (uint32_t)ctx->bad[th][1];
        if (ctx->bad[th][2] == 2)
            ctx->result = rbc_fail(
                ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                "cloth 0x%08x: the spring between vertices %u and %u was stretched past %g "
                "times its rest length at substep %u of %u: the global solver diverged (more "
                "iterations, more substeps, or rbgs/direct keep it stable); the world was "
                "restored to its state before the step",
                c->public_id, t->to_host[t->sa[i]], t->to_host[t->sb[i]],
                (double)RBC_BLOWUP_STRETCH, at->sub, ctx->substeps);
        else
            ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                                   "cloth 0x%08x: vertex %u became non-finite at substep %u of %u "
                                   "(h = %g s, stiffness*h^2/mass up to %g); the world was "
                                   "restored to its state before the step",
                                   c->public_id, t->to_host[i], at->sub, ctx->substeps,
                                   (double)ctx->h, (double)(t->ksum[i] / c->w[i]));
        return;
    }
}

/* Every position finite, and (last substep) every spring within the blow-up bound;
 * with the guard, the same pass measures the energy and thread 0 decides the clamp
 * (or the failure) with the check's verdict, before the barrier that publishes both. */
static void stage_check(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    const int last = at->sub + 1 == ctx->substeps;
    const int guard = last && rbc_step_guarded(ctx);
    ctx->bad[at->tid][0] = -1;
    if (guard)
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            rbc_energy_blocks(s->cloths[k], s->cloths[k]->p, s->cloths[k]->x, s->gravity, 0,
                              at->tid, at->nt);
    if (!(last && rbc_step_can_run_away(s->settings.kind) && check_springs(ctx, at->tid, at->nt)))
        check_particles(ctx, at->tid, at->nt);
    rbc_pool_barrier(s->pool);
    if (at->tid == 0) {
        report_check(ctx, at);
        if (ctx->result == RBC_OK && guard) rbc_guard_decide(ctx);
    }
    rbc_pool_barrier(s->pool);
}

/* The energy guard's clamp, decided by the check of the last substep. */
static void stage_energy(step_ctx *ctx, const rbc_step_at *at) {
    if (!ctx->clamp) return;
    rbc_guard_apply(ctx, at->tid, at->nt);
    rbc_pool_barrier(ctx->s->pool);
}

static void stage_commit(step_ctx *ctx, const rbc_step_at *at) {
    rbc_solver *s = ctx->s;
    if (at->tid == 0)
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            rbc_cloth_state *c = s->cloths[k];
            for (int a = 0; a < 3; ++a) {
                float *old_q = c->q[a];
                c->q[a] = c->x[a];
                c->x[a] = c->p[a];
                c->p[a] = old_q;
            }
        }
    rbc_pool_barrier(s->pool);
}

/* ------------------------------------------------------------------------- */
/* One dispatch, and the step as Algorithm 1                                  */
/* ------------------------------------------------------------------------- */

typedef void rbc_stage_fn(step_ctx *ctx, const rbc_step_at *at);
static rbc_stage_fn *const stage_fns[RBC_STAGE_COUNT] = {
    [RBC_STAGE_BUDGET] = rbc_stage_budget,
    [RBC_STAGE_INTEGRATE] = stage_integrate,
    [RBC_STAGE_PINS] = stage_pins,
    [RBC_STAGE_WIND] = stage_wind,
    [RBC_STAGE_DETECT] = rbc_stage_detect,
    [RBC_STAGE_LOCAL] = stage_local,
    [RBC_STAGE_GLOBAL] = rbc_stage_global,
    [RBC_STAGE_FRICTION] = rbc_stage_friction,
    [RBC_STAGE_CLOTH_CONTACT] = rbc_stage_cloth_contact,
    [RBC_STAGE_CALLBACK] = rbc_stage_callback,
    [RBC_STAGE_CHECK] = stage_check,
    [RBC_STAGE_ENERGY] = stage_energy,
    [RBC_STAGE_COMMIT] = stage_commit,
};

/* The stages whose failure ends the step. Each writes ctx->result (thread 0) only
 * before a barrier of its own and ends at a barrier, and no stage writes it before
 * its first barrier, so every thread reads the same verdict at a failing stage's end
 * (stage.h). */
static const uint32_t can_fail = 1u << RBC_STAGE_DETECT | 1u << RBC_STAGE_CLOTH_CONTACT |
                                 1u << RBC_STAGE_CALLBACK | 1u << RBC_STAGE_CHECK;

/* Run a stage the step uses, timed on thread 0. Returns 0 when it failed the step. */
static int run_stage(step_ctx *ctx, rbc_stage st, const rbc_step_at *at) {
    if (!rbc_step_uses(ctx, st)) return 1;
    double t0 = at->tid == 0 ? rbc_now_ms() : 0.0;
    stage_fns[st](ctx, at);
    if (at->tid == 0) ctx->stage_ms[st] += rbc_now_ms() - t0;
    return !((can_fail >> st) & 1u) || ctx->result == RBC_OK;
}

static void step_spmd(void *arg, uint32_t tid, uint32_t nt) {
    step_ctx *ctx = arg;
    rbc_step_at at = {0, 0, tid, nt};
    run_stage(ctx, RBC_STAGE_BUDGET, &at);
    for (at.sub = 0; at.sub < ctx->substeps; ++at.sub) {
        run_stage(ctx, RBC_STAGE_INTEGRATE, &at);
        run_stage(ctx, RBC_STAGE_PINS, &at);
        run_stage(ctx, RBC_STAGE_WIND, &at);
        if (!run_stage(ctx, RBC_STAGE_DETECT, &at)) return;
        for (at.nl = 0; at.nl < ctx->s->nonlinear_iterations; ++at.nl) {
            run_stage(ctx, RBC_STAGE_LOCAL, &at);
            run_stage(ctx, RBC_STAGE_GLOBAL, &at);
        }
        run_stage(ctx, RBC_STAGE_FRICTION, &at);
        if (!run_stage(ctx, RBC_STAGE_CLOTH_CONTACT, &at)) return;
        if (!run_stage(ctx, RBC_STAGE_CALLBACK, &at)) return;
        if (!run_stage(ctx, RBC_STAGE_CHECK, &at)) return;
        if (at.sub + 1 == ctx->substeps) run_stage(ctx, RBC_STAGE_ENERGY, &at);
        run_stage(ctx, RBC_STAGE_COMMIT, &at);
    }
}

/* A backend's step: the energy guard's budget at the start, on the pool (the host
 * holds the state between steps), as the first stage of step_spmd. */
static void budget_spmd(void *arg, uint32_t tid, uint32_t nt) {
    rbc_step_at at = {0, 0, tid, nt};
    run_stage(arg, RBC_STAGE_BUDGET, &at);
}

/* The stages this world's scene needs. */
static uint32_t stages_used(const rbc_solver *s, const step_ctx *ctx) {
    const int guard = rbc_guard_on(s);
    uint32_t u = 1u << RBC_STAGE_INTEGRATE | 1u << RBC_STAGE_PINS | 1u << RBC_STAGE_LOCAL |
                 1u << RBC_STAGE_GLOBAL | 1u << RBC_STAGE_CHECK | 1u << RBC_STAGE_COMMIT;
    if (guard) u |= 1u << RBC_STAGE_BUDGET | 1u << RBC_STAGE_ENERGY;
    if (s->wind_drag != 0.0f || s->wind_lift != 0.0f) u |= 1u << RBC_STAGE_WIND;
    if (s->collider_count || ctx->cc_active || s->contact_fn) u |= 1u << RBC_STAGE_DETECT;
    if (s->collider_count || s->contact_fn) u |= 1u << RBC_STAGE_FRICTION;
    if (ctx->cc_active) u |= 1u << RBC_STAGE_CLOTH_CONTACT;
    if (s->callback) u |= 1u << RBC_STAGE_CALLBACK;
    return u;
}

/* ------------------------------------------------------------------------- */
/* Serial work around the threads                                             */
/* ------------------------------------------------------------------------- */

/* The substeps of this step: the world's count, from the substep rate, or the
 * target controller's choice. Returns 1 when they come from the rate. */
static int choose_substeps(rbc_solver *s, step_ctx *ctx, float dt) {
    ctx->substeps = s->substeps;
    if (s->settings.mode == RBC_ITERATE_TARGET) {
        rbc_target_begin(s, ctx);
        return 0;
    }
    if (s->substeps != 0) return 0;
    /* Substeps from the rate (world substeps 0, 1.6): the substep length stays near
     * 1 / rate whatever dt the host passes, up to the cap. The 1e-3 lets a float dt
     * such as 1/60.f (8.0000006 substeps at 480 Hz) take 8, not 9: substeps at most
     * 0.1 % longer than 1 / rate. */
    double want = ceil((double)dt * (double)s->substep_rate - 1e-3);
    uint32_t cap = s->settings.max_substeps;
    ctx->substeps = want < 1.0 ? 1u : want > (double)cap ? cap : (uint32_t)want;
    return 1;
}

/* m_i/h^2 and 1/(m_i/h^2 + sum s_ij), recomputed only when h changes. */
static void prepare_weights(rbc_cloth_state *c, float h) {
    if (c->h_cached == h) return;
    float inv_h2 = 1.0f / (h * h);
    for (uint32_t i = 0; i < c->topo.n; ++i) {
        float wi = c->topo.mass[i] * inv_h2;
        c->w[i] = wi;
        c->inv_denom[i] = 1.0f / (wi + c->topo.ksum[i]);
    }
    c->h_cached = h;
}

/* The colliders' and pins' motion over the step, and cloth contact's buffers (out
 * of memory: the step fails before any cloth changed). */
static int32_t prepare_motion(rbc_solver *s, step_ctx *ctx, float dt) {
    for (uint32_t k = 0; k < s->collider_count; ++k) {
        rbc_collider_state *col = &s->colliders[k];
        for (int a = 0; a < 3; ++a) col->velocity[a] = (col->position[a] - col->last_position[a]) / dt;
    }
    if (ctx->cc_active && s->cc_bodies_cap < s->cloth_count) {
        rbc_contact_body *b = rbc_mem_alloc(&s->alloc, sizeof(*b) * s->cloth_cap);
        if (!b)
            return rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                            "out of memory for cloth contact");
        rbc_mem_free(&s->alloc, s->cc_bodies, sizeof(*s->cc_bodies) * s->cc_bodies_cap);
        s->cc_bodies = b;
        s->cc_bodies_cap = s->cloth_cap;
    }
    s->last_contacts = s->last_cloth_contacts = 0;
    s->last_frozen = s->last_cloth_capped = 0;
    rbc_attachments_update(s);
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->pin_count; ++m)
            for (int a = 0; a < 3; ++a) c->pin_start[3 * m + a] = c->x[a][c->pin_idx[m]];
    }
    return RBC_OK;
}

/* Keep (restore = 0) or put back (1) every cloth's x and q. */
static void snapshot(rbc_solver *s, int restore) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        size_t bytes = (size_t)c->topo.n * sizeof(float);
        for (int a = 0; a < 3; ++a) {
            if (restore) {
                memcpy(c->x[a], c->snap_x[a], bytes);
                memcpy(c->q[a], c->snap_q[a], bytes);
            } else {
                memcpy(c->snap_x[a], c->x[a], bytes);
                memcpy(c->snap_q[a], c->q[a], bytes);
            }
        }
    }
}

/* The target mode or a new dt changed the substep length: keep each velocity
 * (x - q) / h by rescaling q to the new h (Verlet reads it from x - q). */
static void rescale_velocities(rbc_solver *s, float h) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (!(c->h_last > 0.0f) || c->h_last == h) continue;
        const float f = h / c->h_last;
        for (int a = 0; a < 3; ++a)
            for (uint32_t i = 0; i < c->topo.n; ++i)
                c->q[a][i] = c->x[a][i] - (c->x[a][i] - c->q[a][i]) * f;
    }
}

/* The final strain of every cloth, block sums on all threads: the RMS for the target
 * mode's decision, the largest for the strain warning. */
static void strain_spmd(void *arg, uint32_t tid, uint32_t nt) {
    rbc_solver *s = arg;
    const int target = s->settings.mode == RBC_ITERATE_TARGET, warn = s->strain_warning > 0.0f;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (target) rbc_strain_blocks(s->cloths[k], s->cloths[k]->x, tid, nt);
        if (warn) rbc_strain_max_blocks(s->cloths[k], s->cloths[k]->x, tid, nt);
    }
}

/* What the step reached, at the positions the host reads (after tearing): the
 * largest RMS strain of any cloth (target mode; returned) and the strain warning. */
static double measure_strain(rbc_solver *s, uint32_t threads) {
    const int target = s->settings.mode == RBC_ITERATE_TARGET, warn = s->strain_warning > 0.0f;
    double reached = 0.0;
    s->step_max_strain = 0.0;
    s->strain_warn_last = 0;
    if (!target && !warn) return 0.0;
    rbc_pool_run_n(s->pool, threads, strain_spmd, s);
    float top = 0.0f;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (target) {
            double r = rbc_strain_sum(s->cloths[k]);
            if (r > reached) reached = r;
        }
        if (!warn) continue;
        float m = rbc_strain_max(s->cloths[k], s->cloths[k]->x, NULL);
        if (m > top) {
            top = m;
            s->strain_warn_cloth = k;
        }
    }
    s->step_max_strain = top;
    if (warn && top > s->strain_warning) {
        /* Past the threshold: find the spring, for the log (one block again). */
        rbc_cloth_state *c = s->cloths[s->strain_warn_cloth];
        rbc_strain_max(c, c->x, &s->strain_warn_spring);
        s->strain_warn_last = 1;
        s->strain_warn_steps++;
    }
    return reached;
}

/* After a successful step: what the next step starts from, and its stats. */
/* threads: the count the step asked for (what the probe chose); used: the count it
 * ran on (fewer on the host's job system when not every item joined in time). */
static void finish_step(rbc_solver *s, const step_ctx *ctx, uint32_t threads, uint32_t used,
                        double start, double run_ms) {
    rbc_step_threads_record(s, threads, run_ms / (ctx->substeps ? ctx->substeps : 1));
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        /* A backend leaves the host's y, d and w of the last substep stale. */
        s->cloths[k]->system_valid = !s->backend.ops;
        s->cloths[k]->h_last = ctx->h;
    }
    for (uint32_t k = 0; k < s->collider_count; ++k) {
        memcpy(s->colliders[k].last_position, s->colliders[k].position, 3 * sizeof(float));
        memcpy(s->colliders[k].last_rotation, s->colliders[k].rotation, 4 * sizeof(float));
    }
    rbc_guard_commit(s, ctx);
    /* Tearing: springs stretched past their limit at the end of the step break. */
    for (uint32_t k = 0; k < s->cloth_count; ++k) rbc_tear_scan(s, s->cloths[k]);
    const double t0 = rbc_now_ms();
    const double reached = measure_strain(s, used);
    const double *ms = ctx->stage_ms;
    s->last.integrate = ms[RBC_STAGE_INTEGRATE] + ms[RBC_STAGE_PINS] + ms[RBC_STAGE_WIND];
    s->last.collide = ms[RBC_STAGE_DETECT] + ms[RBC_STAGE_FRICTION] + ms[RBC_STAGE_CLOTH_CONTACT];
    s->last.local = ms[RBC_STAGE_LOCAL];
    s->last.global = ms[RBC_STAGE_GLOBAL];
    s->last.callback = ms[RBC_STAGE_CALLBACK];
    s->last.other = ms[RBC_STAGE_BUDGET] + ms[RBC_STAGE_CHECK] + ms[RBC_STAGE_ENERGY] +
                    ms[RBC_STAGE_COMMIT] + (rbc_now_ms() - t0);
    s->last.step = rbc_now_ms() - start;
    s->last_substeps = ctx->substeps;
    s->last_nonlinear = ctx->substeps * s->nonlinear_iterations;
    s->last_linear = ctx->linear_done;
    s->step_count++;
    if (s->settings.mode == RBC_ITERATE_TARGET) {
        rbc_target_end(s, ctx, reached);
    } else {
        s->tgt_reached = 0.0;
        s->tgt_met = 0;
        s->tgt_capped = 0;
    }
}

int32_t rbc_solver_step(rbc_solver *s, float dt, char *err, size_t errlen) {
    const double start = rbc_now_ms();
    step_ctx ctx = {.s = s, .result = RBC_OK, .err = err, .errlen = errlen, .start_ms = start};
    if (s->backend.ops) { /* before anything changes */
        int32_t rc = rbc_backend_scene_check(s, s->backend.ops->name, err, errlen);
        if (rc != RBC_OK) return rc;
    }
    const int from_rate = choose_substeps(s, &ctx, dt);
    ctx.h = dt / (float)ctx.substeps;
    if (!(ctx.h > 0.0f))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "dt / substeps = %g s underflows to zero", (double)ctx.h);
    /* Cloth contact runs only while some cloth asks for it. */
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        if (s->cloths[k]->collision_flags && s->cloths[k]->thickness > 0.0f) ctx.cc_active = 1;
    /* Serial preparation for h: the weights, and what the sweeps need (changes only
     * with h, the pins or the topology). A failure here changes nothing. */
    for (uint32_t k = 0; k < s->cloth_count; ++k) prepare_weights(s->cloths[k], ctx.h);
    int32_t rc = rbc_sweep_prepare(&ctx);
    if (rc != RBC_OK) return rc;
    rc = prepare_motion(s, &ctx, dt);
    if (rc != RBC_OK) return rc;
    ctx.uses = stages_used(s, &ctx);

    /* With one substep nothing is committed before the check, so the state before the
     * step is intact on failure; with several, earlier substeps are, so keep a copy. */
    int rescale = 0;
    for (uint32_t k = 0; (s->settings.mode == RBC_ITERATE_TARGET || from_rate) && k < s->cloth_count;
         ++k)
        rescale |= s->cloths[k]->h_last > 0.0f && s->cloths[k]->h_last != ctx.h;
    /* A backend writes the host's state only at the end, but a readback that fails
     * half-way leaves it mixed. */
    const int need_snapshot = ctx.substeps > 1 || rescale || s->backend.ops;
    if (need_snapshot) snapshot(s, 0);
    if (rescale) rescale_velocities(s, ctx.h);

    const uint32_t threads = rbc_step_threads_choose(s);
    /* (Before run_t0: the stats count it as the budget stage, not the device's.) */
    if (s->backend.ops && rbc_step_uses(&ctx, RBC_STAGE_BUDGET))
        rbc_pool_run_n(s->pool, threads, budget_spmd, &ctx);
    const double run_t0 = rbc_now_ms();
    /* On the host's job system the threads that joined (1..threads). */
    const uint32_t used = s->backend.ops ? (rbc_backend_run(&s->backend, &ctx), 1u)
                                         : rbc_pool_run_n(s->pool, threads, step_spmd, &ctx);
    if (s->backend.ops) ctx.stage_ms[RBC_STAGE_GLOBAL] = rbc_now_ms() - run_t0;
    const double run_ms = rbc_now_ms() - run_t0;
    s->threads_last = used;
    if (ctx.result != RBC_OK) {
        if (need_snapshot) snapshot(s, 1);
        return ctx.result;
    }
    finish_step(s, &ctx, threads, used, start, run_ms);
    return RBC_OK;
}
