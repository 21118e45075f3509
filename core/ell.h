/* ell.h -- the Gauss-Seidel sweep for meshes without lattice structure, in ELLPACK
 * layout: per color, slot j of the color's m-th particle at [j * count + m] (neighbour
 * index and stiffness), padded to the color's largest degree with stiffness 0. A
 * chunk of particles accumulates slot by slot, so the neighbour loads become vector
 * gathers (AVX2/AVX-512 clones, simd.h) instead of a scalar walk of CSR rows.
 */
#ifndef RBC_CORE_ELL_H
#define RBC_CORE_ELL_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "topology.h"

struct rbc_cloth_state;

typedef struct rbc_ell {
    uint32_t ncolors;
    uint32_t width[RBC_MAX_COLORS];  /* largest degree in the color */
    size_t offset[RBC_MAX_COLORS];   /* start of the color's slots in nbr / k */
    uint32_t *nbr;                   /* internal neighbour index (padding: a particle of
                                        another color, never written by the sweep) */
    float *k;                        /* stiffness (padding: 0) */
    size_t slots, bytes;
} rbc_ell;

/* 1 and *out set when the layout is worth it (padding at most doubles the slots);
 * 0 (*out NULL); -1 out of memory. Needs at least two colors. */
int rbc_ell_build(const rbc_topology *t, const rbc_allocator *a, rbc_ell **out);
void rbc_ell_free(rbc_ell *e, const rbc_allocator *a);

/* One color of a Gauss-Seidel iteration from b (rbc_global_rhs), this thread's
 * share: p_i = g_i (omega == 0) or p_i += omega (g_i - p_i); pinned particles stay. */
void rbc_ell_sweep(const rbc_ell *e, struct rbc_cloth_state *c, uint32_t color, float omega,
                   uint32_t tid, uint32_t nt);
#endif
