/* target.h -- the target error mode (RBC_ITERATE_TARGET, 1.4; target.c): substeps
 * and linear iterations chosen per step so that the RMS relative strain at the
 * step's end stays at the target at the least cost. */
#ifndef RBC_CORE_TARGET_H
#define RBC_CORE_TARGET_H
#include "stage.h"

/* Steps in a row that must meet the target with a margin before a probe lowers the
 * substeps (the first hold; it doubles when a lowering is undone). */
#define RBC_TARGET_HOLD 8u
/* The checked global step stops at RBC_TARGET_AIM of the target (it met more frames
 * than 0.95 for 3 % more time); reaching the cap above RBC_TARGET_INNER of it asks
 * for more substeps, so a cloth whose physical stretch lies between the two does not
 * ask for substeps that cannot help (docs/design/target-mode.md). */
#define RBC_TARGET_AIM 0.8
#define RBC_TARGET_INNER 0.95
/* Cost units of a substep besides its linear iterations (integrate, local step and
 * right-hand side, a strain check), in linear iterations, from the stage times of a
 * 10K RBGS frame (docs/design/target-mode.md). */
#define RBC_TARGET_SUBSTEP_COST 3u

/* Before a step: its substeps (the controller's choice) and the linear iterations
 * of its unchecked global steps. */
void rbc_target_begin(rbc_solver *s, step_ctx *ctx);
/* The checked global step, after linear iteration k of at most limit: the strain of
 * the latest iterate (alt: the Jacobi destination buffer) decides ctx->stop. */
void rbc_target_check(step_ctx *ctx, uint32_t k, uint32_t limit, int alt, uint32_t tid,
                      uint32_t nt);
/* The decision of that check from every cloth's strain blocks (c->strain_blk, filled
 * as rbc_strain_blocks_fast fills them): one thread, after they are complete. A
 * backend's step fills them with its own strain kernel and calls this. */
void rbc_target_decide(step_ctx *ctx, uint32_t k, uint32_t limit);
/* After a successful step that reached `reached`: the next step's counts. */
void rbc_target_end(rbc_solver *s, const step_ctx *ctx, double reached);
#endif
