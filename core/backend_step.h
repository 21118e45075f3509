/* backend_step.h -- a step's substeps on a backend (backend.h), for rbc_solver_step.
 * A world whose solver has a backend (rbc_solver.backend) runs them there instead of
 * on the CPU pool's SPMD stages (step.c); the serial work around them is shared. */
#ifndef RBC_CORE_BACKEND_STEP_H
#define RBC_CORE_BACKEND_STEP_H
#include <stddef.h>
#include <stdint.h>

#include "backend.h"
#include "solver.h"
#include "stage.h"

/* RBC_OK, or RBC_ERR_UNSUPPORTED naming the first feature of these solver settings,
 * or of this world's whole scene, that the backends do not run yet (backend: its
 * name, for the message). */
int32_t rbc_backend_settings_check(const rbc_solver_settings *st, const char *backend,
                                   char *err, size_t errlen);
int32_t rbc_backend_scene_check(const rbc_solver *s, const char *backend, char *err,
                                size_t errlen);
/* Every substep of ctx's step on bk, then the state back into the host's x and q;
 * ctx->result says how it went (on failure the host's state may be half-written: the
 * caller restores its snapshot). */
void rbc_backend_run(const rbc_backend_handle *bk, step_ctx *ctx);
/* Release cloth c's copy on bk (if any). */
void rbc_backend_cloth_free(const rbc_backend_handle *bk, const rbc_allocator *al, rbc_cloth_state *c);
#endif
