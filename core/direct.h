/* direct.h -- the exact global step (RBC_SOLVER_DIRECT): the linear system of Eq. 6
 * solved by a sparse Cholesky factorisation (CHOLMOD) instead of Red-Black
 * Gauss-Seidel sweeps.
 *
 * The global step of Projective Dynamics (Sec. 3.2, 4.5) minimises, over the free
 * particles, sum_i m_i/2h^2 |p_i - y_i|^2 + sum_springs s_ij/2 |p_i - p_j - d_ij|^2. Its
 * normal equations are the fixed point of Eq. 6: for every free particle i
 *
 *   (m_i/h^2 + sum_j s_ij) p_i - sum_{j free} s_ij p_j
 *       = m_i/h^2 y_i + sum_j s_ij d_ij + sum_{j pinned} s_ij p_j       (N/m * m)
 *
 * i.e. A p = b with A = diag(m_i/h^2) + sum_s s_ij (e_a - e_b)(e_a - e_b)^T restricted
 * to the free particles (pinned ones are Dirichlet values moved to b). A depends only
 * on the topology, the pin set and h, so it is factored once (create) and each global
 * step is two triangular solves with three right-hand sides (x, y, z).
 *
 * Indices are internal (topology.h); positions are SoA floats as in solver.h. The
 * factorisation and the solve run in double. Everything is allocated through the
 * rbc_allocator, CHOLMOD's factor and workspaces too (cholmod_alloc.h: SuiteSparse 5's
 * allocator hooks are process-global, so they are pointed at wrappers that take the
 * allocator of the calling thread's create or destroy), unless the host set
 * SuiteSparse_config's allocator itself. Nothing prints.
 *
 * Thread-compatible: one rbc_direct per cloth, used by one thread at a time; distinct
 * objects may be used from different threads concurrently.
 */
#ifndef RBC_CORE_DIRECT_H
#define RBC_CORE_DIRECT_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "topology.h"

typedef struct rbc_direct rbc_direct;

/* Factor the global matrix of one cloth for substep h (s):
 *   A = diag(m_i / h^2) + sum over springs s of s_ij (e_a - e_b)(e_a - e_b)^T,
 * restricted to the free (not pinned) particles; pinned particles are Dirichlet
 * values moved to the right-hand side. pinned[n] is 1 for a pinned particle.
 * m_i/h^2 is formed exactly as the RBGS path forms w (float mass * (1.0f/(h*h)), see
 * rbc_direct_weight), so the direct and iterative paths solve the same system.
 * Returns RBC_OK (0) or a negative rbc_result with a message in err:
 * RBC_ERR_BACKEND_UNAVAILABLE (no CHOLMOD: rbc_direct_available), RBC_ERR_INVALID_ARGUMENT (h not finite and > 0, or m_i/h^2 overflowing),
 * RBC_ERR_OUT_OF_MEMORY (also for a factor beyond CHOLMOD's 32-bit indices), or
 * RBC_ERR_UNSTABLE if the factorisation fails (not positive definite: the message
 * names the vertex). On error *out is NULL.
 * A cloth with no free particle gives a valid object whose solve does nothing. */
int32_t rbc_direct_create(rbc_direct **out, const rbc_topology *t, const uint8_t *pinned,
                          float h, const rbc_allocator *a, char *err, size_t errlen);

/* Solve the global step exactly: for every free particle i,
 *   (m_i/h^2 + sum_j s_ij) p_i - sum_{j free} s_ij p_j
 *       = w_i y_i + sum_j s_ij d_ij + sum_{j pinned} s_ij p_j
 * where d_ij is stored in half-edge slot k of i (dx[k], dy[k], dz[k]; slots
 * adj_start[i]..adj_start[i+1]-1, neighbour adj_nbr[k], stiffness adj_k[k]), w[i] =
 * m_i/h^2 for the h of create, y the inertial targets, and p[] holds the pinned
 * particles' positions on entry; the free particles' p is written (rounded to float).
 * t and pinned must be those given to create (the pin set of the factor is used).
 * Never allocates and cannot fail. Single-threaded; cost O(nnz(L)), see direct.c. */
void rbc_direct_solve(rbc_direct *d, const rbc_topology *t, const uint8_t *pinned, const float *w,
                      const float *const y[3], const float *dx, const float *dy, const float *dz,
                      float *const p[3]);

/* NULL is a no-op. */
void rbc_direct_destroy(rbc_direct *d);

/* 1 if this build and process can make a factor: CHOLMOD is loaded (on the first
 * call, cholmod_load.h). 0 with the reason in err (RBC_ERR_BACKEND_UNAVAILABLE's
 * message: which library, why) if not, or if the build has no direct solver
 * (RBC_WITH_CHOLMOD=OFF). rbc_direct_create then fails the same way. */
int rbc_direct_available(char *err, size_t errlen);

/* Bytes held (factor + workspace), for stats. */
size_t rbc_direct_bytes(const rbc_direct *d);

/* m_i/h^2 as the factor uses it (and as the RBGS path's prepare_weights computes it):
 * mass * (1.0f / (h * h)) in float. */
static inline float rbc_direct_weight(float mass, float h) { return mass * (1.0f / (h * h)); }

#endif
