/* global.h -- the solvers of the global step (Eq. 6) for one cloth, each over one
 * thread's share of the particles: Gauss-Seidel by color (red-black, or more colors),
 * with over-relaxation or Chebyshev acceleration; Jacobi, plain or Chebyshev; serial
 * lexicographic Gauss-Seidel; and the residual and spectral radius that measure and
 * tune them. The step (step.c, sweep.c) calls these between barriers.
 *
 * rbc_global_* pick the layout a cloth has (sweep.c: the lattice of lattice.h, the
 * ELLPACK rows of ell.h, or these CSR rows, rbc_csr_*); every layout gives the CSR
 * rows' result bitwise. */
#ifndef RBC_CORE_GLOBAL_H
#define RBC_CORE_GLOBAL_H
#include <stdint.h>

#include "cloth_state.h"

/* How a Gauss-Seidel color sweep writes its result g_i (Eq. 6). */
typedef enum rbc_gs_variant {
    RBC_GS_PLAIN,     /* p_i = g_i */
    RBC_GS_SOR,       /* p_i += omega (g_i - p_i) */
    RBC_GS_STASH      /* p_i = g_i, and the old p_i kept in alt (for Chebyshev) */
} rbc_gs_variant;

/* b_i = m_i/h^2 y_i + sum_j s_ij d_ij for this thread's share of the particles: the
 * part of Eq. 6 that the linear iterations of one non-linear iteration share (after
 * the local step, before the sweeps). */
void rbc_global_rhs(rbc_cloth_state *c, uint32_t tid, uint32_t nt);
/* One color of one Gauss-Seidel iteration, this thread's share. */
void rbc_global_gs_color(rbc_cloth_state *c, uint32_t color, rbc_gs_variant v, float omega,
                         uint32_t tid, uint32_t nt);
void rbc_csr_gs_color(rbc_cloth_state *c, uint32_t color, rbc_gs_variant v, float omega,
                      uint32_t tid, uint32_t nt);
/* Chebyshev blend after a full Gauss-Seidel iteration (this thread's share of the
 * particles): p = omega (p - prev) + prev, then prev = the iterate before the
 * iteration (stashed in alt by RBC_GS_STASH). Blending after the whole sweep, not
 * inside it, keeps every color's sweep a plain Gauss-Seidel step of the same
 * iteration, which is what the semi-iterative method accelerates. */
void rbc_global_chebyshev_blend(rbc_cloth_state *c, float omega, uint32_t tid, uint32_t nt);
/* One Jacobi iteration, this thread's share: dst = Eq. 6 of src for free particles,
 * dst = src for pinned ones; with chebyshev, dst = omega (g - prev) + prev and
 * prev = src. On a lattice the share is rows (rbc_lattice_jacobi), else particles: every
 * particle is written by exactly one thread either way, and the result does not depend
 * on the split (callers barrier before reading dst). */
void rbc_global_jacobi(rbc_cloth_state *c, float *const src[3], float *const dst[3],
                       int chebyshev, float omega, uint32_t tid, uint32_t nt);
void rbc_csr_jacobi(rbc_cloth_state *c, float *const src[3], float *const dst[3], int chebyshev,
                    float omega, uint32_t tid, uint32_t nt);
/* One serial lexicographic Gauss-Seidel iteration in the host's vertex order, one
 * thread (on a lattice rbc_lattice_gs_serial, the same result bitwise). */
void rbc_global_gs_serial(rbc_cloth_state *c);
void rbc_csr_gs_serial(rbc_cloth_state *c);
/* Squared residual and right-hand side norms of the global system at p, over this
 * thread's share of the particles of colors [0, color_end). */
void rbc_global_residual(const rbc_cloth_state *c, uint32_t color_end, uint32_t tid,
                         uint32_t nt, double *r2, double *b2);
/* Chebyshev weight of iteration k (0-based) for spectral radius rho, starting after
 * `delay` plain iterations (Wang 2015): 1 before, then 2/(2 - rho^2), then
 * 4/(4 - rho^2 omega_prev). */
float rbc_chebyshev_omega(uint32_t k, uint32_t delay, float rho);
/* The Jacobi spectral radius of the cloth's global system for substep h (power
 * iteration; cached per h and in the last RBC_RHO_CACHE substep lengths). */
float rbc_global_spectral_radius(rbc_cloth_state *c, float h);
#endif
