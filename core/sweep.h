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
/* The global step of one non-linear iteration, with the contacts that join it. */
void rbc_stage_global(step_ctx *ctx, const rbc_step_at *at);
#endif
