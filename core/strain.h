/* strain.h -- the RMS relative strain of a cloth, the measure of the target error
 * mode (RBC_ITERATE_TARGET, ABI 1.4):
 *
 *   strain_rms = sqrt( sum_s ((|p_a - p_b| - L_s) / L_s)^2 / N )
 *
 * over the N springs s of the cloth that are not torn and have L_s > 0 (Eq. 7 with
 * each spring's violation divided by its rest length, averaged, square-rooted).
 *
 * Computed in double from the float positions, in fixed blocks of the internal
 * spring order (RBC_STRAIN_BLOCK springs each); threads take whole blocks and
 * thread 0 adds the block sums in block order, so the value is bitwise the same for
 * any thread count. Inside a block the sum may be reassociated into vector lanes
 * (the order is fixed by the code, never by the threads). */
#ifndef RBC_CORE_STRAIN_H
#define RBC_CORE_STRAIN_H
#include <stdint.h>

struct rbc_cloth_state;

#define RBC_STRAIN_BLOCK 2048u

/* Doubles of per-block partial sums a cloth with ns springs needs (2 per block). */
static inline uint32_t rbc_strain_block_doubles(uint32_t ns) {
    return 2u * ((ns + RBC_STRAIN_BLOCK - 1u) / RBC_STRAIN_BLOCK + 1u);
}

/* This thread's share of the blocks of cloth c for positions p[3] (internal order):
 * sum of squared relative strains and count of the springs counted, per block, into
 * c->strain_blk. Call on every thread of the pool, then barrier. */
void rbc_strain_blocks(struct rbc_cloth_state *c, float *const p[3], uint32_t tid, uint32_t nt);
/* The same in float arithmetic (sums in double), for the checks inside a solve
 * (strain.c gives its error bound). */
void rbc_strain_blocks_fast(struct rbc_cloth_state *c, float *const p[3], uint32_t tid,
                            uint32_t nt);
/* One block of springs [b, e): what rbc_strain_blocks_fast sums per block (the
 * squares, and in *count the springs counted), from plain arrays (the CPU backend's
 * strain kernel). torn: skip springs of stiffness 0. */
double rbc_strain_block_sum_f(const uint32_t *sa, const uint32_t *sb, const float *rest,
                              const float *stiff, int torn, const float *px, const float *py,
                              const float *pz, uint32_t b, uint32_t e, double *count);
/* The largest relative strain | |p_a - p_b| / L - 1 | of this thread's blocks (live
 * springs with L > 0), in float, into c->strain_max_blk: the strain warning's pass
 * at the end of a step (rbc_world_def.strain_warning). Call on every thread, then
 * barrier. */
void rbc_strain_max_blocks(struct rbc_cloth_state *c, float *const p[3], uint32_t tid,
                           uint32_t nt);
/* After the barrier (one thread): the largest of the blocks, and in *spring (if not
 * NULL) the first spring of the internal order that has it. */
float rbc_strain_max(const struct rbc_cloth_state *c, float *const p[3], uint32_t *spring);
/* After the barrier (one thread): the RMS relative strain from the block sums. */
double rbc_strain_sum(const struct rbc_cloth_state *c);
/* Both, serially (one thread; the same value as the pair above). */
double rbc_strain_rms(struct rbc_cloth_state *c, float *const p[3]);
#endif
