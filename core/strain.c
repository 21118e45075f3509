/* strain.c -- the RMS relative strain of a cloth (strain.h). */
#include "strain.h"

#include <math.h>

#include "report.h"
#include "kernels/measure_kernels.h"
#include "simd.h"
#include "cloth_state.h"

/* One block: sum of ((len - L) / L)^2 over its live springs with L > 0. torn: some
 * springs of the cloth are broken (stiffness 0) and are skipped. */
RBC_VECTOR_CLONES
static double block_sum(const uint32_t *restrict sa, const uint32_t *restrict sb,
                        const float *restrict rest, const float *restrict stiff, int torn,
                        const float *restrict px, const float *restrict py,
                        const float *restrict pz, uint32_t b, uint32_t e, double *count) {
    double sum = 0.0, n = 0.0;
    for (uint32_t k = b; k < e; ++k) {
        uint32_t i = sa[k], j = sb[k];
        double ex = (double)px[i] - (double)px[j], ey = (double)py[i] - (double)py[j],
               ez = (double)pz[i] - (double)pz[j];
        double L = rest[k];
        int live = L > 0.0 && !(torn && stiff[k] == 0.0f);
        double r = live ? sqrt(ex * ex + ey * ey + ez * ez) / L - 1.0 : 0.0;
        sum += r * r;
        n += live ? 1.0 : 0.0;
    }
    *count = n;
    return sum;
}

/* The same in float (the squares summed in double): for the checks inside a solve,
 * about an order of magnitude cheaper (the gathers and square roots vectorize in
 * float lanes). Each relative strain is off by at most about 2 sqrt(3) ulp(|p|) / L
 * + 3 ulp(1) from the double value (a float subtraction of coordinates up to |p|,
 * a float square root and division), 1e-5 for 1 m coordinates and 1 cm springs.
 * Exported for the CPU backend's strain kernel, which must sum as the pool does. */
RBC_VECTOR_CLONES
double rbc_strain_block_sum_f(const uint32_t *restrict sa, const uint32_t *restrict sb,
                          const float *restrict rest, const float *restrict stiff, int torn,
                          const float *restrict px, const float *restrict py,
                          const float *restrict pz, uint32_t b, uint32_t e, double *count) {
    double sum = 0.0;
    float n = 0.0f;
    for (uint32_t k = b; k < e; ++k) {
        uint32_t i = sa[k], j = sb[k];
        float ex = px[i] - px[j], ey = py[i] - py[j], ez = pz[i] - pz[j];
        float L = rest[k];
        int live = L > 0.0f && !(torn && stiff[k] == 0.0f);
        float r = rbc_k_rel_strain_f(ex, ey, ez, L, live);
        sum += (double)(r * r);
        n += live ? 1.0f : 0.0f;
    }
    *count = n; /* exact: a block holds at most 2048 springs */
    return sum;
}

double rbc_strain_sum(const rbc_cloth_state *c) {
    uint32_t nblk = (c->topo.ns + RBC_STRAIN_BLOCK - 1u) / RBC_STRAIN_BLOCK;
    double sum = 0.0, n = 0.0;
    for (uint32_t k = 0; k < nblk; ++k) {
        sum += c->strain_blk[2 * (size_t)k];
        n += c->strain_blk[2 * (size_t)k + 1];
    }
    return n > 0.0 ? sqrt(sum / n) : 0.0;
}

double rbc_strain_rms(rbc_cloth_state *c, float *const p[3]) {
    rbc_strain_blocks(c, p, 0, 1);
    return rbc_strain_sum(c);
}

/* One spring's |relative strain| in float, as block_max_f computes it. */
static inline float spring_strain_f(const rbc_topology *t, int torn, const float *px,
                                    const float *py, const float *pz, uint32_t k) {
    uint32_t i = t->sa[k], j = t->sb[k];
    float L = t->rest_len[k];
    int live = L > 0.0f && !(torn && t->stiff[k] == 0.0f);
    return fabsf(rbc_k_rel_strain_f(px[i] - px[j], py[i] - py[j], pz[i] - pz[j], L, live));
}

/* The block's largest strain. No index is kept: the spring is looked up again only
 * when a warning names it. The loop stays scalar (GCC does not vectorize the
 * position gathers): 27 instructions a spring, about 17 % of a step of the paper's
 * 11 RBGS iterations on its cloth and 2 % of a default step (callgrind); writing it
 * over len^2 / L^2 without the square root saved 4 %, not worth a second form. */
RBC_VECTOR_CLONES
static float block_max_f(const uint32_t *restrict sa, const uint32_t *restrict sb,
                         const float *restrict rest, const float *restrict stiff, int torn,
                         const float *restrict px, const float *restrict py,
                         const float *restrict pz, uint32_t b, uint32_t e) {
    float m = 0.0f;
    for (uint32_t k = b; k < e; ++k) {
        uint32_t i = sa[k], j = sb[k];
        float L = rest[k];
        int live = L > 0.0f && !(torn && stiff[k] == 0.0f);
        float r = fabsf(rbc_k_rel_strain_f(px[i] - px[j], py[i] - py[j], pz[i] - pz[j], L, live));
        m = r > m ? r : m;
    }
    return m;
}

/* This thread's blocks of cloth c, by kind: the squared-strain sums in double or
 * in float (into strain_blk), or the largest strain (into strain_max_blk). */
enum { SUM_DOUBLE, SUM_FLOAT, MAX_FLOAT };
static void blocks(rbc_cloth_state *c, float *const p[3], uint32_t tid, uint32_t nt, int kind) {
    const rbc_topology *t = &c->topo;
    uint32_t nblk = (t->ns + RBC_STRAIN_BLOCK - 1u) / RBC_STRAIN_BLOCK, b, e;
    rbc_split(nblk, tid, nt, &b, &e);
    const int torn = c->torn != 0;
    for (uint32_t k = b; k < e; ++k) {
        uint32_t s0 = k * RBC_STRAIN_BLOCK, s1 = s0 + RBC_STRAIN_BLOCK;
        if (s1 > t->ns) s1 = t->ns;
        if (kind == MAX_FLOAT) {
            c->strain_max_blk[k] =
                block_max_f(t->sa, t->sb, t->rest_len, t->stiff, torn, p[0], p[1], p[2], s0, s1);
            continue;
        }
        double n = 0.0;
        c->strain_blk[2 * (size_t)k] =
            kind == SUM_FLOAT
                ? rbc_strain_block_sum_f(t->sa, t->sb, t->rest_len, t->stiff, torn, p[0], p[1], p[2], s0, s1, &n)
                : block_sum(t->sa, t->sb, t->rest_len, t->stiff, torn, p[0], p[1], p[2], s0, s1, &n);
        c->strain_blk[2 * (size_t)k + 1] = n;
    }
}

void rbc_strain_blocks(rbc_cloth_state *c, float *const p[3], uint32_t tid, uint32_t nt) {
    blocks(c, p, tid, nt, SUM_DOUBLE);
}

void rbc_strain_blocks_fast(rbc_cloth_state *c, float *const p[3], uint32_t tid, uint32_t nt) {
    blocks(c, p, tid, nt, SUM_FLOAT);
}

void rbc_strain_max_blocks(rbc_cloth_state *c, float *const p[3], uint32_t tid, uint32_t nt) {
    blocks(c, p, tid, nt, MAX_FLOAT);
}

float rbc_strain_max(const rbc_cloth_state *c, float *const p[3], uint32_t *spring) {
    const rbc_topology *t = &c->topo;
    uint32_t nblk = (t->ns + RBC_STRAIN_BLOCK - 1u) / RBC_STRAIN_BLOCK, best = 0;
    float m = 0.0f;
    for (uint32_t k = 0; k < nblk; ++k)
        if (c->strain_max_blk[k] > m) {
            m = c->strain_max_blk[k];
            best = k;
        }
    if (spring) {
        *spring = 0;
        uint32_t s0 = best * RBC_STRAIN_BLOCK, s1 = s0 + RBC_STRAIN_BLOCK;
        if (s1 > t->ns) s1 = t->ns;
        float top = -1.0f;
        for (uint32_t k = s0; k < s1; ++k) {
            float r = spring_strain_f(t, c->torn != 0, p[0], p[1], p[2], k);
            if (r > top) {
                top = r;
                *spring = k;
            }
        }
    }
    return m;
}
