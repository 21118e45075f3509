/* lattice.h -- the lattice fast path of the Gauss-Seidel sweep.
 *
 * A cloth whose spring graph is an nx x ny lattice in host order (vertex i + nx j
 * joined only to i +- 1 and j +- 1, structural springs only: two colors) has, in the
 * color-contiguous internal order (each color in host order, topology.c), a fixed
 * stencil: the particles of one color in row j are consecutive, and their left,
 * right, down and up neighbours are consecutive runs of the other color at known
 * offsets. The sweep then streams contiguous arrays with no index arrays, which the
 * compiler vectorizes (SSE2 baseline, AVX2 and AVX-512 clones chosen at run time).
 * Missing neighbours at the edges have stiffness 0; rows beyond the edges read a row
 * of zeros. Any other mesh uses the CSR path (global.c).
 */
#ifndef RBC_CORE_LATTICE_H
#define RBC_CORE_LATTICE_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "topology.h"

struct rbc_cloth_state;

typedef struct rbc_lattice {
    uint32_t nx, ny;
    uint32_t c0;                /* color of host vertex 0 (row 0, column 0) */
    uint32_t *row_first[2];     /* [ny + 1]: internal index of the first particle of
                                   color c in row j; [ny] = the color's end */
    float *kl, *kr, *kd, *ku;   /* [n] stiffness of the spring to the left (i - 1),
                                   right, down (j - 1) and up neighbour; 0 if none */
    float *ll, *lr, *ld, *lu;   /* [n] their rest lengths (as topology.c computes them) */
    float *zeros;               /* [nx / 2 + 2] neighbours of rows beyond the edges */
    float *nzeros;              /* [nx / 2 + 2] -0.0f, the same for the Jacobi rows: a term
                                   s * (-0) = -0 added to any float leaves it unchanged */
    float k_uniform;            /* the one stiffness of every spring, or 0 (also 0 when a
                                   lattice edge has no spring: the broadcast would add it) */
    uint32_t csr_order;         /* 1: every lattice edge is a spring and every CSR row lists
                                   the neighbours down, left, right, up (j - 1, i - 1, i + 1,
                                   j + 1) with these stiffnesses, so rbc_lattice_jacobi and
                                   rbc_lattice_gs_serial add the same terms in the same order as
                                   the CSR rows (rbc_k_eq6b) and give their result bitwise */
    size_t bytes;
} rbc_lattice;

/* 1 and *out set if t is such a lattice; 0 (not a lattice, *out NULL); -1 out of
 * memory. O(n + springs). */
int rbc_lattice_detect(const rbc_topology *t, const rbc_allocator *a, rbc_lattice **out);
void rbc_lattice_free(rbc_lattice *g, const rbc_allocator *a);
/* Tearing (tear.h): spring sp of t is gone; zero its stiffness toward both ends and
 * turn off the one-stiffness broadcast (a stiffness of 0 reads as no spring). */
void rbc_lattice_break_spring(rbc_lattice *g, const rbc_topology *t, uint32_t sp);

/* The local step and the right-hand side in one pass, this thread's rows of both
 * colors: b_i = m_i/h^2 y_i + sum_j s_ij d_ij with d_ij = L (p_i - p_j) / |p_i - p_j|
 * (the rest direction when |p_i - p_j| <= 1e-12 m), as rbc_k_local and rbc_k_rhs
 * compute it, from p, without the per-spring d arrays. */
void rbc_lattice_rhs(const rbc_lattice *g, struct rbc_cloth_state *c, uint32_t tid, uint32_t nt);

/* One color of a Gauss-Seidel iteration (Eq. 6 from b, rbc_global_rhs), this
 * thread's rows: p_i = g_i (omega == 0) or p_i += omega (g_i - p_i). Pinned particles
 * keep their positions. */
void rbc_lattice_sweep(const rbc_lattice *g, struct rbc_cloth_state *c, uint32_t color, float omega,
                    uint32_t tid, uint32_t nt);

/* One Jacobi iteration (Eq. 6 of src into dst; rbc_global_jacobi), this thread's rows
 * of both colors: dst_i = g_i(src) for free particles, dst_i = src_i for pinned ones;
 * with chebyshev, dst_i = omega (g_i - prev_i) + prev_i and prev_i = src_i. Each
 * particle's sum is b_i + s_down p_down + s_left p_left + s_right p_right + s_up p_up,
 * in that order, the terms of missing neighbours left out (a row beyond the edge
 * adds s * (-0), which changes no float): the CSR row's order, so the result is
 * bitwise rbc_global_jacobi's (g->csr_order must be 1) whatever nt. Reads src only:
 * the interior of a row vectorizes with no dependency. */
void rbc_lattice_jacobi(const rbc_lattice *g, struct rbc_cloth_state *c, float *const src[3],
                     float *const dst[3], int chebyshev, float omega, uint32_t tid, uint32_t nt);

/* One serial lexicographic Gauss-Seidel iteration in the host's vertex order (row by
 * row, one thread; rbc_global_gs_serial): every update sees its left and lower
 * neighbours' new values. The left one is carried in registers from the previous
 * update, the other neighbours are found by the stencil, not by index arrays, and two
 * rows advance together, the upper one a column behind (each update still reads what
 * it reads in host order). Same sums in the same order as the CSR rows: bitwise
 * rbc_global_gs_serial's result (g->csr_order must be 1). */
void rbc_lattice_gs_serial(const rbc_lattice *g, struct rbc_cloth_state *c);

/* `iterations` whole red-black iterations, temporally blocked: at step w iteration
 * it updates red row w - 2 it, then black row w - 2 it - 1, so a band of 2 iterations
 * + 2 rows is all that must stay in cache, and every row update sees exactly the
 * inputs of plain red-then-black iterations (the result is bitwise theirs). Threads
 * form a pipeline over the 2 * iterations color sweeps (thread t does its rbc_split
 * share); thread t starts step w once thread t - 1 has finished it (progress[stride *
 * t] counts the steps a thread finished; zero them and barrier before). Color 0 must be "red": the
 * lattice's two colors play symmetric roles, so either works. */
void rbc_lattice_wavefront(const rbc_lattice *g, struct rbc_cloth_state *c, uint32_t iterations,
                        float omega, volatile uint32_t *progress, size_t stride, uint32_t tid,
                        uint32_t nt);
#endif
