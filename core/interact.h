/* interact.h -- what a host does to cloth besides stepping it: tearing and cuts,
 * picking, attachments to colliders, and wind.
 *
 * Tearing removes springs (their stiffness becomes 0 everywhere the sweeps read it:
 * the CSR slots, the lattice's per-particle stiffness, the ELLPACK copy) and the quads
 * that have both ends of a removed spring as corners. Removing springs keeps a valid
 * coloring (docs/facts.md), so nothing is recolored or reordered; the lattice path
 * stays (it reads a stiffness of 0 as "no spring"), only its one-stiffness broadcast
 * is turned off.
 */
#ifndef RBC_CORE_INTERACT_H
#define RBC_CORE_INTERACT_H
#include <stddef.h>
#include <stdint.h>

#include "solver.h"

/* Break spring sp (internal spring index) of a cloth; 0 if it was already broken.
 * Call rbc_tear_finish once after a batch of breaks. */
int rbc_tear_spring(rbc_cloth_state *c, uint32_t sp);
/* Break the springs joining host vertex pairs (indices validated by the caller);
 * pairs without an unbroken spring are skipped. RBC_ERR_OUT_OF_MEMORY: nothing cut. */
int32_t rbc_cut_pairs(rbc_solver *s, rbc_cloth_state *c, const uint32_t *pairs, uint32_t count,
                      uint32_t *out_cut);
/* After breaks: drop the quads that lost a spring, rebuild the contact triangles, and
 * invalidate what depended on the stiffness (weights, spectral radius, the direct
 * factorisation, pin springs). */
void rbc_tear_finish(rbc_solver *s, rbc_cloth_state *c);
/* Break every spring stretched past (1 + tear_strain) of its rest length at x.
 * Returns the number broken (rbc_tear_finish already called). */
uint32_t rbc_tear_scan(rbc_solver *s, rbc_cloth_state *c);

/* Remaining quads / springs in host indices (4 / 2 per item), up to cap values;
 * returns the values there are. */
size_t rbc_cloth_quads_host(const rbc_cloth_state *c, uint32_t *out, size_t cap);
size_t rbc_cloth_springs_host(const rbc_cloth_state *c, uint32_t *out, size_t cap);

/* Picking: the vertex within radius of the ray o + t d, t in [0, tmax], with the least
 * t (ties: nearer the ray, then lower cloth, then lower vertex). Returns 1 if found. */
int rbc_pick(const rbc_solver *s, const float o[3], const float d[3], float tmax, float radius,
             uint32_t *cloth_index, uint32_t *host_vertex, float *t_out);

/* Attachments (pins that follow a collider). */
int32_t rbc_attach(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                   uint32_t collider_public_id, const float local[3]);
/* Forget the attachment of a vertex (rbc_cloth_state_set_pin calls it). */
void rbc_detach_vertex(rbc_cloth_state *c, uint32_t host_vertex);
/* Before a step: every attached vertex's pin target from its collider's pose now. */
void rbc_attachments_update(rbc_solver *s);
/* A collider is going away: release the vertices attached to it. */
int32_t rbc_attachments_drop_collider(rbc_solver *s, uint32_t collider_public_id);

/* Wind and drag: add h^2 F / m to the prediction (y and p) of every free corner of
 * every quad. Thread 0, after the prediction. */
void rbc_wind_apply(rbc_solver *s, float h);
#endif
