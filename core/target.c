/* target.c -- the target error mode's controller (target.h). */
#include "target.h"

#include "cpu/pool.h"
#include "strain.h"

void rbc_solver_target_reset(rbc_solver *s) {
    s->tgt_substeps = 0;
    s->tgt_iters = 0;
    s->tgt_calm = 0;
    s->tgt_hold = RBC_TARGET_HOLD;
    s->tgt_lowered_at = 0;
    s->tgt_probe = 0;
}

void rbc_target_begin(rbc_solver *s, step_ctx *ctx) {
    /* The controller's choice; the first step of the mode starts at the cap (the
     * most accurate) and the controller lowers it while that pays. */
    ctx->substeps = s->tgt_substeps ? s->tgt_substeps : s->settings.max_substeps;
    if (ctx->substeps > s->settings.max_substeps) ctx->substeps = s->settings.max_substeps;
    /* Start from the world's linear iterations, within the cap. */
    ctx->tgt_iters = s->tgt_iters ? s->tgt_iters : s->linear_iterations;
    if (ctx->tgt_iters > s->settings.max_linear_iterations)
        ctx->tgt_iters = s->settings.max_linear_iterations;
    ctx->tgt_iters_next = ctx->tgt_iters; /* the direct solver keeps it */
}

void rbc_target_check(step_ctx *ctx, uint32_t k, uint32_t limit, int alt, uint32_t tid,
                      uint32_t nt) {
    /* The strain of the latest iterate (in float: strain.h); stop at RBC_TARGET_AIM
     * of the target (room for the substeps before this one, which ran last step's
     * count unchecked, and for what friction and the safety pass change after the
     * solve), or at the cap; the cap with the strain above RBC_TARGET_INNER of the
     * target asks for substeps. */
    rbc_solver *s = ctx->s;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        rbc_cloth_state *c = s->cloths[q];
        rbc_strain_blocks_fast(c, alt ? c->alt : c->p, tid, nt);
    }
    rbc_pool_barrier(s->pool);
    if (tid == 0) rbc_target_decide(ctx, k, limit);
}

void rbc_target_decide(step_ctx *ctx, uint32_t k, uint32_t limit) {
    rbc_solver *s = ctx->s;
    double worst = 0.0;
    for (uint32_t q = 0; q < s->cloth_count; ++q) {
        double r = rbc_strain_sum(s->cloths[q]);
        if (r > worst) worst = r;
    }
    const double target = (double)s->settings.target_strain;
    int met = worst <= RBC_TARGET_AIM * target;
    ctx->stop = met || k >= limit;
    if (ctx->stop) {
        if (worst > RBC_TARGET_INNER * target) ctx->hit_cap = 1;
        ctx->tgt_iters_next = k;
    }
}

/* The controller, after a successful step of `used` substeps that reached `reached`
 * (the largest RMS relative strain of any cloth) at `cost` units. Substeps are the
 * lever (the linear iterations adapt inside each global step):
 *  - a miss, or a global step that needed max_linear_iterations, raises them by half
 *    (at least one) up to max_substeps;
 *  - after tgt_hold steps in a row that met the target without the cap, a probe
 *    lowers them by a quarter (at least one); if the next step costs more units
 *    than the step before the probe, the probe is undone and tgt_hold doubles (up
 *    to 256), so a lowering that does not pay is tried ever less often.
 * Counts only: the choice is deterministic and independent of the thread count. */
static void target_decide(rbc_solver *s, uint32_t used, int hit_cap, double reached,
                          uint64_t cost) {
    const uint32_t smax = s->settings.max_substeps;
    const int met = reached <= (double)s->settings.target_strain;
    s->tgt_reached = reached;
    s->tgt_met = met;
    s->tgt_capped = !met && used >= smax;
    if (!met) s->tgt_missed_steps++;
    if (s->tgt_capped) s->tgt_capped_steps++;
    uint32_t next = used;
    if ((!met || hit_cap) && used < smax) {
        next = used + (used / 2 > 1 ? used / 2 : 1);
        if (next > smax) next = smax;
        if (s->tgt_probe || (s->tgt_lowered_at && s->step_count - s->tgt_lowered_at <= s->tgt_hold))
            s->tgt_hold = s->tgt_hold < 128 ? 2 * s->tgt_hold : 256;
        s->tgt_probe = 0;
        s->tgt_calm = 0;
    } else if (s->tgt_probe) {
        if (cost > s->tgt_prev_cost) {
            next = s->tgt_prev_substeps; /* the fewer substeps cost more: back */
            s->tgt_hold = s->tgt_hold < 128 ? 2 * s->tgt_hold : 256;
        }
        s->tgt_probe = 0;
        s->tgt_calm = 0;
    } else if (met && !hit_cap && used > 1) {
        if (++s->tgt_calm >= s->tgt_hold) {
            s->tgt_prev_substeps = used;
            s->tgt_prev_cost = cost;
            s->tgt_probe = 1;
            s->tgt_lowered_at = s->step_count;
            next = used - (used / 4 > 1 ? used / 4 : 1);
            s->tgt_calm = 0;
        }
    } else {
        s->tgt_calm = 0;
    }
    s->tgt_substeps = next;
}

void rbc_target_end(rbc_solver *s, const step_ctx *ctx, double reached) {
    /* The unchecked global steps of the next step: what the checked one needed, at
     * most twice this step's count and at least 2 (within the cap). A jump from a
     * loose solve to a tight one releases the stretch the loose one stored as motion
     * (energy no one supplied, which the energy guard clamps): on the paper's cloth
     * at 1/60 s the preset's run had 3 clamped steps when the count could go from 1
     * to 8 at once, none with this. */
    uint32_t next = ctx->tgt_iters_next;
    if (next > 2 * ctx->tgt_iters) next = 2 * ctx->tgt_iters;
    if (next < 2) next = 2;
    if (next > s->settings.max_linear_iterations) next = s->settings.max_linear_iterations;
    s->tgt_iters = next;
    target_decide(s, ctx->substeps, ctx->hit_cap, reached,
                  ctx->linear_done +
                      (uint64_t)RBC_TARGET_SUBSTEP_COST * ctx->substeps * s->nonlinear_iterations);
}
