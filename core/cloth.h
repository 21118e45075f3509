/* cloth.h -- the life cycle of one cloth of a world (cloth.c): its creation from a
 * mesh, the buffers the world's solver and callbacks need, pins, contact settings,
 * and what a host reads and writes (positions, errors, energy, bytes). The data is
 * cloth_state.h. */
#ifndef RBC_CORE_CLOTH_H
#define RBC_CORE_CLOTH_H
#include <stddef.h>
#include <stdint.h>

#include "../abi/rbcloth.h"
#include "alloc.h"
#include "cloth_state.h"
#include "topology.h"

/* Build a cloth (validates the mesh; allocates the buffers solver `kind` needs, and
 * the host-order buffers when host_buffers: a host callback is installed). The world
 * adds it (rbc_solver_create_cloth does both). */
int32_t rbc_cloth_state_create(const rbc_allocator *a, rbc_solver_kind kind, int host_buffers,
                               const rbc_mesh_input *in, float damping, rbc_cloth_state **out,
                               char *err, size_t errlen);
void rbc_cloth_state_destroy(const rbc_allocator *a, rbc_cloth_state *c);
/* Contact settings of a cloth (rbc_cloth_def 1.3): builds its triangles when flags
 * need them (the world's cloth-contact context: rbc_solver_set_cloth_contact). On
 * failure nothing changes. */
int32_t rbc_cloth_state_set_contact(const rbc_allocator *a, rbc_cloth_state *c, float thickness,
                                    float friction, uint32_t flags);
/* The buffers solver kind k needs and this cloth lacks (all or nothing; 0 = out of
 * memory), and the release of those it does not need. */
int rbc_cloth_state_solver_buffers(const rbc_allocator *a, rbc_cloth_state *c, rbc_solver_kind k);
void rbc_cloth_state_release_solver_buffers(const rbc_allocator *a, rbc_cloth_state *c,
                                            rbc_solver_kind k);
/* Host-order buffers for the host callbacks: allocate (0 = out of memory) or free. */
int rbc_cloth_state_host_buffers(const rbc_allocator *a, rbc_cloth_state *c, int want);

/* Pins (host vertex index; validated by the caller). target NULL releases. */
int32_t rbc_cloth_state_set_pin(const rbc_allocator *a, rbc_cloth_state *c, uint32_t host_vertex,
                                const float *target);
/* The stiffness changed (tearing): the weights, the spectral radius and the direct
 * factorisation are stale. */
void rbc_cloth_state_stiffness_changed(rbc_cloth_state *c);
/* Positions in host order, 3 floats per vertex. */
void rbc_cloth_state_read(const rbc_cloth_state *c, float *xyz);
/* Eq. 7 (sum of squared spring violations, m^2) and the largest relative
 * violation, at the current positions, in double precision. */
void rbc_cloth_state_error(const rbc_cloth_state *c, double *eq7, double *max_strain);
/* Positions and previous positions in host order; either may be NULL. */
void rbc_cloth_state_get(const rbc_cloth_state *c, float *pos, float *prev);
/* Replace them (prev NULL = pos); pinned particles stay on their pins. */
void rbc_cloth_state_set(rbc_cloth_state *c, const float *pos, const float *prev);
/* Relative residual of the last substep's global system at the current positions
 * and the PD objective there (both 0 when no step has been made). */
void rbc_cloth_state_system_error(const rbc_cloth_state *c, double *res_num2, double *res_den2,
                                  double *objective);
/* Bytes a cloth holds: state, topology, pins, solver and callback buffers, and the
 * direct solver's factor. */
size_t rbc_cloth_state_bytes(const rbc_cloth_state *c);
/* Kinetic energy (velocities over the last h; 0 before the first step), potential
 * energy (springs + gravity, -m g . x) of the current state (only if measure: a pass
 * over the cloth; else left alone), and the energy guard's budget for kinetic +
 * gravitational energy (0 before the first guarded step). */
void rbc_cloth_state_energy(const rbc_cloth_state *c, const float g[3], int measure,
                            double *kinetic, double *potential, double *budget);
/* The state, pins or gravity changed: recompute the energy at the next step;
 * keep_slack 0 also resets the budget to it. */
void rbc_cloth_state_energy_invalidate(rbc_cloth_state *c, int keep_slack);
#endif
