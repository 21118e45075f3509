/* stage.h -- what the stages of a step share (internal to the core).
 *
 * rbc_solver_step (step.c) runs one SPMD function on every pool thread; it calls the
 * stages of Algorithm 1 in order, each a function named after its stage, and each
 * stage splits its range statically among the threads. The stages live with their
 * concept: the sweeps in sweep.h, contact in contact_step.h, the host callbacks in
 * host_callbacks.h, the energy guard in energy_guard.h, the target mode's checks in
 * target.h. */
#ifndef RBC_CORE_STAGE_H
#define RBC_CORE_STAGE_H
#include <stddef.h>
#include <stdint.h>

#include "cpu/pool.h" /* rbc_now_ms */
#include "solver.h"

/* The stages of a step, in the order they run. BUDGET runs once at the start of a
 * step, ENERGY once at its last substep, LOCAL and GLOBAL once per non-linear
 * iteration; the others once per substep. A step skips the stages its scene does not
 * use (step_ctx.uses). */
typedef enum rbc_stage {
    RBC_STAGE_BUDGET,        /* energy guard: energy and budget at the step's start */
    RBC_STAGE_INTEGRATE,     /* Alg. 2: Verlet prediction y, p = y */
    RBC_STAGE_PINS,          /* pinned particles placed on their path to the target */
    RBC_STAGE_WIND,          /* drag and lift on the quads */
    RBC_STAGE_DETECT,        /* collider, host and cloth contacts of the substep */
    RBC_STAGE_LOCAL,         /* Alg. 3: d_ij per spring, and the right-hand side */
    RBC_STAGE_GLOBAL,        /* Eq. 6 by the selected sweep (sweep.c) */
    RBC_STAGE_FRICTION,      /* collider and host contacts: friction and their work */
    RBC_STAGE_CLOTH_CONTACT, /* cloth contact: friction and the fail-safe */
    RBC_STAGE_CALLBACK,      /* the host's collision callback */
    RBC_STAGE_CHECK,         /* every position finite, every spring within bounds */
    RBC_STAGE_ENERGY,        /* energy guard: the clamp of an energy gain (the check
                                decides it, or the failure) */
    RBC_STAGE_COMMIT,        /* q <- x <- p */
    RBC_STAGE_COUNT
} rbc_stage;

/* Where every thread is in the step (each thread holds its own copy). */
typedef struct rbc_step_at {
    uint32_t sub, nl;        /* substep, non-linear iteration */
    uint32_t tid, nt;        /* this thread, the threads of the step */
} rbc_step_at;

typedef struct step_ctx {
    rbc_solver *s;
    float h;
    uint32_t substeps;
    uint32_t ncolors; /* most colors of any cloth */
    double start_ms;  /* for the budget */
    uint32_t uses;    /* 1 << rbc_stage for each stage the step runs */
    /* Set by thread 0 between barriers; read by all after the barrier. A stage writes
     * result only after its first barrier (every thread has read the verdict of the
     * stage before), and the stages that can fail end at a barrier. */
    volatile int32_t result;
    volatile int stop;
    uint32_t linear_done; /* linear iterations of the step (thread 0 counts) */
    char *err;
    size_t errlen;
    /* Per-thread first failure found: (cloth index, internal particle or spring
     * index, kind: 1 non-finite particle, 2 spring past the blow-up guard). */
    int64_t bad[64][3];
    /* Per-thread partial residual sums, padded to their own cache lines. */
    struct {
        double r2, b2;
        char pad[48];
    } part[64];
    int clamp;            /* the energy guard scales velocities at this commit */
    int any_contacts;     /* some collider contact exists in this substep */
    int color_pass;       /* collider and host contacts are projected after each color's
                             sweep, with their friction (rbc_collide_project_color) */
    int host_contacts;    /* the host reported contacts for this substep */
    int cc_active;        /* some cloth takes part in cloth contact */
    int grow;             /* a contact list must grow: detect again */
    int wavefront;        /* fixed counts run as the lattice wavefront (sweep.c) */
    /* Steps each thread finished in the lattice wavefront (lattice.h), a cache line
     * apart. */
    volatile uint32_t progress[64 * 16];
    /* RBC_ITERATE_TARGET: the linear iterations of the global steps before the
     * step's last (the count the last one of the previous step needed), what the
     * last one needed (thread 0 writes it), and whether it stopped at
     * max_linear_iterations above the target. */
    uint32_t tgt_iters, tgt_iters_next;
    int hit_cap;
    float cheb_rho[64];   /* per cloth (first 64): the Chebyshev rho in use */
    float sor_omega[64];  /* per cloth: the SOR omega in use */
    double stage_ms[RBC_STAGE_COUNT]; /* thread 0's time in each stage */
} step_ctx;

static inline int rbc_step_uses(const step_ctx *ctx, rbc_stage st) {
    return (ctx->uses >> st) & 1u;
}
/* The energy guard is on for this step (its stages run). */
static inline int rbc_step_guarded(const step_ctx *ctx) {
    return rbc_step_uses(ctx, RBC_STAGE_ENERGY);
}
/* Per-cloth parameters are kept for the first 64 cloths; later ones share the last. */
static inline uint32_t rbc_step_slot(uint32_t cloth) { return cloth < 64 ? cloth : 63; }
/* The blow-up guard: an iterative solver that does not converge can inject energy
 * until the positions are huge but still finite. No cloth is stretched to
 * RBC_BLOWUP_STRETCH times its rest length (the mean rest length for shorter
 * springs) by physics the solver resolved, so a spring past that counts as
 * divergence, like a NaN (docs/design/blowup-guard.md). */
#define RBC_BLOWUP_STRETCH 1000.0f

/* Gauss-Seidel sweeps (red-black, multicolor, serial) and the exact solve only lower
 * the PD objective, so they cannot run away: the spring bound is checked for the
 * solvers that can, once per step (the last substep; a step that fails is undone
 * whole, and a run-away is still there, larger, at its end). */
static inline int rbc_step_can_run_away(rbc_solver_kind kind) {
    return kind == RBC_SOLVER_JACOBI || kind == RBC_SOLVER_JACOBI_CHEBYSHEV ||
           kind == RBC_SOLVER_RBGS_SOR || kind == RBC_SOLVER_RBGS_CHEBYSHEV;
}

#endif
