/* energy_guard.h -- the energy guard's part of a step (rbc_energy_guard, energy.h):
 * each cloth's budget of kinetic + gravitational energy (what it had, plus the work
 * of pins, colliders, wind and the host), and the clamp or failure when a step ends
 * above it. The energy sums themselves are energy.h. */
#ifndef RBC_CORE_ENERGY_GUARD_H
#define RBC_CORE_ENERGY_GUARD_H
#include "stage.h"

/* The world's settings ask for the guard. */
int rbc_guard_on(const rbc_solver *s);
/* The BUDGET stage: energy and budget at the step's start. */
void rbc_stage_budget(step_ctx *ctx, const rbc_step_at *at);
/* Thread 0: the pins' work (they moved from x to p), the colliders' work (the
 * impulses of the friction stage). */
void rbc_guard_add_pin_work(step_ctx *ctx);
void rbc_guard_add_collider_work(step_ctx *ctx);
/* All threads: add sign * (kinetic + gravitational energy of p against x) to every
 * cloth's budget (around the host callback). Ends at a barrier. */
void rbc_guard_budget_add(step_ctx *ctx, double sign, uint32_t tid, uint32_t nt);
/* Thread 0, in the last substep's check: decide the clamp or the failure. */
void rbc_guard_decide(step_ctx *ctx);
/* All threads: the clamp's velocity scaling (before the commit). */
void rbc_guard_apply(step_ctx *ctx, uint32_t tid, uint32_t nt);
/* The same clamp after the commit (a backend's step: x is the solve's p, q the
 * substep's start): q = x - scale (x - q) for every cloth's free particles. */
void rbc_guard_apply_committed(rbc_solver *s);
/* After a successful step: each cloth's account for the next one, and the stats. */
void rbc_guard_commit(rbc_solver *s, const step_ctx *ctx);
#endif
