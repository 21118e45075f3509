/* sweep.h -- the global step (Eq. 6) of a step: the one place that chooses how it
 * runs (the lattice wavefront, lattice, ELLPACK or CSR sweeps, the direct solve) and
 * when its iterations stop (sweep.c). */
#ifndef RBC_CORE_SWEEP_H
#define RBC_CORE_SWEEP_H
#include "stage.h"

/* Serial, before the threads start: what the solver needs for this substep length
 * (SOR's omega, Chebyshev's rho, the direct factorisation) and whether fixed counts
 * run as the wavefront. Needs ctx->h and ctx->cc_active. */
int32_t rbc_sweep_prepare(step_ctx *ctx);
/* The linear iterations the global step of one non-linear iteration runs (segment
 * of nsegments = substeps x non-linear iterations), as the mode plans them; a
 * backend's schedule (backend_step.c) follows the same plan. */
typedef struct rbc_sweep_plan {
    int fixed;          /* a fixed count: limit iterations */
    int target_check;   /* the target mode's checked global step (the step's last) */
    uint32_t limit;     /* the count, or the cap */
    uint32_t first;     /* the target's first checked iteration */
    uint32_t pre;       /* iterations run as the wavefront before the loop */
    int wave;           /* the whole global step is the wavefront */
} rbc_sweep_plan;
rbc_sweep_plan rbc_sweep_plan_global(const step_ctx *ctx, uint32_t segment, uint32_t nsegments);
/* The colors whose rows the tolerance mode's residual counts: all but the last a
 * Gauss-Seidel sweep just solved exactly (their residual is rounding). */
uint32_t rbc_sweep_residual_colors(rbc_solver_kind kind, uint32_t ncolors);
/* The global step of one non-linear iteration, with the contacts that join it. */
void rbc_stage_global(step_ctx *ctx, const rbc_step_at *at);
#endif
