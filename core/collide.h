/* collide.h -- contact with the built-in colliders, inside the solve.
 *
 * Once per substep, after the prediction y, every free particle is tested against
 * every collider over its motion: the segment from its position at the start of the
 * substep (in the collider's frame then) to y (in the collider's frame at the end of
 * the substep). A segment that enters the shape gives a contact at the entry point,
 * so a fast collider or particle cannot pass through a thin shape between two
 * substeps (continuous detection); otherwise a particle within thickness + margin of
 * the surface at y gives a contact at its closest surface point. A contact is a
 * half-space n . p >= d: the tangent plane there, offset by the thickness, with the
 * collider at its end-of-substep pose.
 *
 * The half-spaces join the global solve: after every linear iteration each contact's
 * particle is projected onto its half-space (unary constraints, so they never race
 * with the color sweeps and one pass after each whole iteration suffices), and the
 * next iteration lets the springs relax around it. Projecting once after the solve
 * instead (the 1.0 behaviour) left springs stretched against the collider, energy the
 * solve had not supplied. After the solve, Coulomb friction removes the tangential
 * motion relative to the collider's surface up to mu times the normal correction
 * (position-based friction, Macklin et al. 2014).
 *
 * Contacts live in one list per thread, for the particles of the energy blocks that
 * thread owns (energy.h), in (cloth, particle, collider) order: the projection of a
 * particle reads and writes only that particle, so the result is the same for any
 * thread count, and the collider work summed per block is bitwise deterministic.
 */
#ifndef RBC_CORE_COLLIDE_H
#define RBC_CORE_COLLIDE_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "contact_list.h"
#include "kernels/collide_kernels.h" /* rbc_frame */
#include "topology.h"

struct rbc_solver;
struct rbc_collider_state;


/* The collider's pose at fraction f of the step (0 = where it was at the end of the
 * last step, 1 = its pose now): position interpolated linearly, rotation by nlerp. */
void rbc_collider_frame_at(const struct rbc_collider_state *c, float f, rbc_frame *out);

/* The normal force of each contact for its friction, from the positions the solve
 * ended with: the residual of the particle's row of Eq. 6, f = (m/h^2 + sum s) p_i -
 * b_i - sum_j s_ij p_j (b_i = m/h^2 y_i + sum s d_ij), which is what the contacts had
 * to supply to hold the particle there, inertia and springs together, along n (0 if
 * it pulls). It only reads positions: every thread computes its list, then a barrier,
 * then rbc_collide_finish corrects positions. */
void rbc_collide_normal_forces(struct rbc_solver *s, rbc_contact_list *list, float h);

/* Detect the contacts of this thread's particles (its energy blocks of every cloth)
 * against every collider; f0/f1 the substep's fractions of the step, h its length.
 * Positions at the start are the cloths' x, the prediction is p. Writes list->need;
 * contacts beyond list->cap are counted, not stored. */
void rbc_collide_detect(struct rbc_solver *s, rbc_contact_list *list, float f0, float f1, float h,
                        uint32_t tid, uint32_t nt);
/* Project every contact of the list onto its half-space; alt = 1 projects the Jacobi
 * destination iterate (cloth->alt) instead of p. With friction (h > 0), also Coulomb
 * friction in the same pass, as rbc_collide_project_color: the first pass of a
 * substep, onto the prediction, whose push is the prediction's whole depth (what a
 * cloth sliding as a whole feels). Returns 1 if any particle moved. */
int rbc_collide_project(struct rbc_solver *s, rbc_contact_list *list, int alt, float h);
/* Project the contacts of particles of one color, after that color's Gauss-Seidel
 * sweep, with their friction: a particle's normal push v and its slip (its motion
 * from where it was at the substep's start, less the surface's, tangential) come from
 * the one value it was just given, so the slip is removed while it is within mu v
 * (static) and cut by mu v otherwise (kinetic), one unit for both. After the first
 * pass (rbc_collide_project with h) has taken the prediction's share, what these add
 * is what the springs did: a particle they pull along the surface with more than mu
 * times what they press it in with slides. Returns 1 if any particle moved. */
int rbc_collide_project_color(struct rbc_solver *s, rbc_contact_list *list, uint32_t color,
                              float h);
/* The color of internal particle i. */
uint32_t rbc_collide_color_of(const rbc_topology *t, uint32_t i);
/* After the solve: friction, and the work the colliders did, h the substep: into this
 * thread's energy blocks (their collider-work slots, zeroed first) when work_out is
 * NULL, else added to *work_out (host contacts, one thread). in_pass: the passes
 * applied the friction (rbc_collide_project_color); its last correction counts in the
 * work. */
void rbc_collide_finish(struct rbc_solver *s, rbc_contact_list *list, float h, uint32_t tid,
                        uint32_t nt, double *work_out, int in_pass);
/* The safety pass after the solve and friction: a particle whose solved motion
 * (relative to a collider) still enters it, or ends within thickness of its surface,
 * is projected onto the entry's tangent plane (the springs pulled it into the
 * collider's path after detection). Its work goes to this thread's energy blocks
 * (after rbc_collide_finish zeroed them). Costs a second culled pass over the
 * particles; acts rarely. */
void rbc_collide_post(struct rbc_solver *s, float f0, float f1, float h, uint32_t tid,
                      uint32_t nt);
#endif
