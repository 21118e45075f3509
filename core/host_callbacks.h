/* host_callbacks.h -- the host's code inside a step (host_callbacks.c): the collision
 * callback (rbc_collision_fn), which corrects positions, and the contact callback
 * (rbc_contact_fn), whose sink adds contacts the solve then keeps. Both run on
 * thread 0 while the others wait, on positions in host order. */
#ifndef RBC_CORE_HOST_CALLBACKS_H
#define RBC_CORE_HOST_CALLBACKS_H
#include "stage.h"

/* The CALLBACK stage: the collision callback, and the energy it adds or removes
 * counted as work it does (energy guard). */
void rbc_stage_callback(step_ctx *ctx, const rbc_step_at *at);
/* Thread 0, in the DETECT stage: the contact callback of substep sub. */
void rbc_step_run_contact_callback(step_ctx *ctx, uint32_t sub);
#endif
