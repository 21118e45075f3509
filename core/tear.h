/* tear.h -- tearing and cuts (tear.c).
 *
 * Tearing removes springs: their stiffness becomes 0 everywhere the sweeps read it
 * (the topology's CSR rows, the lattice's per-particle stiffness, the ELLPACK copy;
 * each owner zeroes its own copy, called from rbc_tear_spring only), and the quads
 * that have both ends of a removed spring as corners go. Removing springs keeps a
 * valid coloring (docs/design/coloring.md), so nothing is recolored or reordered;
 * the lattice path stays (it reads a stiffness of 0 as no spring), only its
 * one-stiffness broadcast is turned off. */
#ifndef RBC_CORE_TEAR_H
#define RBC_CORE_TEAR_H
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
 * factorisation). */
void rbc_tear_finish(rbc_cloth_state *c);
/* Break every spring stretched past (1 + tear_strain) of its rest length at x.
 * Returns the number broken (rbc_tear_finish already called). */
uint32_t rbc_tear_scan(rbc_solver *s, rbc_cloth_state *c);

/* Remaining quads / springs in host indices (4 / 2 per item), up to cap values;
 * returns the values there are. */
size_t rbc_cloth_quads_host(const rbc_cloth_state *c, uint32_t *out, size_t cap);
size_t rbc_cloth_springs_host(const rbc_cloth_state *c, uint32_t *out, size_t cap);
#endif
