/* energy.h -- the energy guard's bookkeeping (rbc_energy_guard in the ABI).
 *
 * Energies of a cloth: kinetic (free particles, v = (x - x_prev) / h), spring (sum
 * s/2 (|x_a - x_b| - L)^2) and gravitational (-sum m g . x, free particles). The
 * guard bounds G = kinetic + gravitational by the budget (the energy at the start
 * plus the work done since); spring energy is left out of G because a solve that has
 * not converged leaves springs more stretched than the energy supplied explains (an
 * accuracy matter, Eq. 7), while an unstable one makes things move (G grows). Sums run over fixed blocks of RBC_ENERGY_BLOCK particles or springs,
 * each summed in order in double, and the blocks are added in order by one thread:
 * the result is bitwise the same for any thread count (a clamp decided on it changes
 * positions, which must not depend on the thread count).
 */
#ifndef RBC_CORE_ENERGY_H
#define RBC_CORE_ENERGY_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"

#define RBC_ENERGY_BLOCK 2048u

struct rbc_cloth_state;

/* Per particle block: kinetic, gravitational, sum m |g| |x|, sum m / h^2, sum m |x -
 * x_prev| (free particles), largest |coordinate| (all particles), collider work; per
 * spring block: spring energy, sum of stiffness, sum of stiffness * |extension|. */
enum { RBC_EPB = 7, RBC_ESB = 3 };
enum { RBC_E_KE, RBC_E_UG, RBC_E_MAG, RBC_E_WSUM, RBC_E_MD, RBC_E_XMAX, RBC_E_WC };
enum { RBC_E_US, RBC_E_KSUM, RBC_E_KEXT };

static inline uint32_t rbc_energy_blocks_of(uint32_t count) {
    return (count + RBC_ENERGY_BLOCK - 1) / RBC_ENERGY_BLOCK;
}
/* Doubles of block storage a cloth of n particles and ns springs needs. */
static inline size_t rbc_energy_block_doubles(uint32_t n, uint32_t ns) {
    return (size_t)RBC_EPB * rbc_energy_blocks_of(n) + (size_t)RBC_ESB * rbc_energy_blocks_of(ns);
}

typedef struct rbc_energy {
    double kinetic, spring, gravity; /* J (spring 0 unless summed) */
    double guarded;                  /* kinetic + gravity: what the guard bounds */
    double tolerance;                /* what rounding of the float state can change in
                                        the summed terms, J */
} rbc_energy;

/* Fill the blocks this thread owns (blocks split statically among nt threads) with
 * the energy of positions pos against previous positions prev; w[i] = m_i / h^2. The
 * collider-work slot is left alone. */
void rbc_energy_blocks(struct rbc_cloth_state *c, float *const pos[3], float *const prev[3],
                       const float g[3], int springs, uint32_t tid, uint32_t nt);
/* Add the blocks in order (one thread, after a barrier); the spring terms only if the
 * blocks were filled with springs = 1. */
rbc_energy rbc_energy_sum(const struct rbc_cloth_state *c, float h, const float g[3],
                          int springs);
/* Zero / sum the collider-work slots (J). */
void rbc_energy_clear_work(struct rbc_cloth_state *c, uint32_t tid, uint32_t nt);
double rbc_energy_sum_work(const struct rbc_cloth_state *c);
/* One block of particles [i0, i1) of positions pos against prev into out[RBC_EPB]
 * (w = m/h^2; the collider-work slot left alone): what rbc_energy_blocks does per
 * block, for the CPU backend's energy kernel. */
void rbc_energy_particle_block(float *const pos[3], float *const prev[3], const float *w,
                               const float *mass, const uint8_t *pinned, const float g[3],
                               uint32_t i0, uint32_t i1, double *out);
/* rbc_energy_pin_work over a list of springs with a pinned end, from plain arrays
 * (the CPU backend's pin-work kernel). */
double rbc_energy_pin_work_list(const uint32_t *list, uint32_t count, const uint32_t *sa,
                                const uint32_t *sb, const float *rest, const float *stiff,
                                const uint8_t *pinned, float *const before[3],
                                float *const after[3]);
/* Work of moving pins on the springs that touch them: spring energy with the pinned
 * particles at `after` minus at `before`, free particles at `before` (both in
 * internal order). Serial; O(springs at pins). */
double rbc_energy_pin_work(const struct rbc_cloth_state *c, float *const before[3],
                           float *const after[3]);
/* Rebuild the list of springs with a pinned end (after the pin set changed).
 * Returns 0 when out of memory (the old list is kept). */
int rbc_energy_rebuild_pin_springs(struct rbc_cloth_state *c, const rbc_allocator *a);
/* [begin, end) of the blocks (of nb) thread tid of nt owns. */
static inline void rbc_energy_block_range(uint32_t nb, uint32_t tid, uint32_t nt, uint32_t *b,
                                          uint32_t *e) {
    *b = (uint32_t)((uint64_t)nb * tid / nt);
    *e = (uint32_t)((uint64_t)nb * (tid + 1) / nt);
}
/* [begin, end) of the particles (of n) in the blocks thread tid of nt owns: a pass
 * that adds to the per-block sums (collider work) walks exactly these. */
static inline void rbc_energy_particle_range(uint32_t n, uint32_t tid, uint32_t nt, uint32_t *i0,
                                             uint32_t *i1) {
    uint32_t b0, b1;
    rbc_energy_block_range(rbc_energy_blocks_of(n), tid, nt, &b0, &b1);
    *i0 = b0 * RBC_ENERGY_BLOCK;
    *i1 = b1 * RBC_ENERGY_BLOCK;
    if (*i1 > n) *i1 = n;
}
#endif
