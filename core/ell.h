/* ell.h -- the Gauss-Seidel sweep for meshes without lattice structure, in sliced
 * ELLPACK layout (SELL-C): each color is cut into chunks of RBC_ELL_CHUNK consecutive
 * particles; slot j of a chunk's m-th particle sits at [offset + j * len + m]
 * (neighbour index and stiffness), padded to the chunk's own largest degree with
 * stiffness 0. A chunk accumulates slot by slot, so the neighbour loads become vector
 * gathers (AVX2/AVX-512 clones, simd.h) instead of a scalar walk of CSR rows, and a
 * chunk of degree-4 particles does 4 slots, not the color's largest degree
 * (topology.c groups a scattered mesh's particles by degree within small windows).
 */
#ifndef RBC_CORE_ELL_H
#define RBC_CORE_ELL_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "kernels/ell_kernels.h"
#include "topology.h"

struct rbc_cloth_state;

/* RBC_ELL_CHUNK and the chunk's update: kernels/ell_kernels.h. */

typedef struct rbc_ell {
    uint32_t ncolors, nchunks;
    uint32_t chunk_start[RBC_MAX_COLORS + 1]; /* first chunk of each color */
    uint32_t *width;                 /* [nchunks] the chunk's largest degree */
    size_t *offset;                  /* [nchunks + 1] start of the chunk's slots */
    uint32_t *nbr;                   /* internal neighbour index (padding: a particle of
                                        another color, never written by the sweep) */
    float *k;                        /* stiffness (padding: 0) */
    float *p4;                       /* [4 n] x, y, z, 0 per particle: the packed copy the
                                        sweeps of a global step read (rbc_ell_pack) */
    size_t slots, bytes;
    uint32_t n4;                     /* particles in p4 */
} rbc_ell;

/* 1 and *out set when the layout is worth it (padding at most doubles the slots);
 * 0 (*out NULL); -1 out of memory. Needs at least two colors. */
int rbc_ell_build(const rbc_topology *t, const rbc_allocator *a, rbc_ell **out);
void rbc_ell_free(rbc_ell *e, const rbc_allocator *a);

/* Tearing (tear.h): spring sp of t is gone; zero the two slots that mirror its CSR
 * half-edges. */
void rbc_ell_break_spring(rbc_ell *e, const rbc_topology *t, uint32_t sp);

/* One color of a Gauss-Seidel iteration from b (rbc_global_rhs), this thread's
 * share: p_i = g_i (omega == 0) or p_i += omega (g_i - p_i); pinned particles stay. */
void rbc_ell_sweep(const rbc_ell *e, struct rbc_cloth_state *c, uint32_t color, float omega,
                   uint32_t tid, uint32_t nt);

/* The packed form of the sweep: the neighbours' x, y, z are one 16-byte load from p4
 * instead of three scalar loads from p[0..2]. rbc_ell_pack copies this thread's share
 * of p into p4 (a barrier must follow before any packed sweep); a packed sweep then
 * writes its color to both p and p4, so p4 stays p's copy for as long as only
 * packed sweeps write p. Each particle's sums are rbc_ell_sweep's, in the same order:
 * bitwise its result. */
void rbc_ell_pack(rbc_ell *e, const struct rbc_cloth_state *c, uint32_t tid, uint32_t nt);
void rbc_ell_sweep_packed(rbc_ell *e, struct rbc_cloth_state *c, uint32_t color, float omega,
                          uint32_t tid, uint32_t nt);
#endif
