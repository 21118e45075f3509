/* energy.c -- mechanical energy of a cloth in fixed blocks (see energy.h). */
#include "energy.h"

#include <math.h>
#include <string.h>

#include "kernels/measure_kernels.h"
#include "simd.h"
#include "cloth_state.h"

/* One block of particles [i0, i1): its sums into out[RBC_EPB] (the collider-work slot
 * left alone). Exported for the CPU backend's energy kernel, which must sum as the
 * pool does (this file's flags let the sums be reassociated into vector lanes). */
RBC_VECTOR_CLONES
void rbc_energy_particle_block(float *const pos[3], float *const prev[3], const float *w,
                               const float *mass, const uint8_t *pinned, const float g[3],
                               uint32_t i0, uint32_t i1, double *o) {
    const double gx = g[0], gy = g[1], gz = g[2];
    const double gn = sqrt(gx * gx + gy * gy + gz * gz);
    /* Branch-free, per-particle terms in float (each is exact to a float ulp, far
     * inside the tolerance), sums in double. Upper bounds stand in for norms in the
     * tolerance terms (|a|+|b|+|c| >= |(a, b, c)|): no square roots. */
    double ke = 0.0, ug = 0.0, mag = 0.0, wsum = 0.0, md = 0.0;
    const float *restrict X = pos[0], *restrict Y = pos[1], *restrict Z = pos[2];
    const float *restrict QX = prev[0], *restrict QY = prev[1], *restrict QZ = prev[2];
    const float *restrict W = w, *restrict M = mass;
    const uint8_t *restrict pin = pinned;
    const float gxf = g[0], gyf = g[1], gzf = g[2];
    /* Largest |coordinate|: the bits of a non-negative float order as integers. */
    uint32_t xbits = 0;
    for (uint32_t i = i0; i < i1; ++i) {
        uint32_t bx, by, bz;
        memcpy(&bx, &X[i], 4);
        memcpy(&by, &Y[i], 4);
        memcpy(&bz, &Z[i], 4);
        bx &= 0x7FFFFFFFu, by &= 0x7FFFFFFFu, bz &= 0x7FFFFFFFu;
        uint32_t bm = bx > by ? bx : by;
        bm = bm > bz ? bm : bz;
        xbits = xbits > bm ? xbits : bm;
    }
    float xmax;
    memcpy(&xmax, &xbits, 4);
    for (uint32_t i = i0; i < i1; ++i)
        rbc_k_energy_terms(i, X, Y, Z, QX, QY, QZ, W, M, pin, gxf, gyf, gzf, &ke, &ug, &mag,
                           &md, &wsum);
    mag *= gn;
    o[RBC_E_KE] = 0.5 * ke;
    o[RBC_E_UG] = ug;
    o[RBC_E_MAG] = mag;
    o[RBC_E_WSUM] = wsum;
    o[RBC_E_MD] = md;
    o[RBC_E_XMAX] = xmax;
}

void rbc_energy_blocks(rbc_cloth_state *c, float *const pos[3], float *const prev[3],
                       const float g[3], int springs, uint32_t tid, uint32_t nt) {
    const rbc_topology *t = &c->topo;
    const uint32_t nbp = rbc_energy_blocks_of(t->n), nbs = rbc_energy_blocks_of(t->ns);
    double *pb = c->e_blk, *sbk = c->e_blk + (size_t)RBC_EPB * nbp;
    uint32_t b0, b1;
    rbc_energy_block_range(nbp, tid, nt, &b0, &b1);
    for (uint32_t b = b0; b < b1; ++b) {
        uint32_t i0 = b * RBC_ENERGY_BLOCK, i1 = i0 + RBC_ENERGY_BLOCK;
        if (i1 > t->n) i1 = t->n;
        rbc_energy_particle_block(pos, prev, c->w, t->mass, c->pinned, g, i0, i1,
                                  pb + (size_t)RBC_EPB * b);
    }
    if (!springs) return;
    rbc_energy_block_range(nbs, tid, nt, &b0, &b1);
    for (uint32_t b = b0; b < b1; ++b) {
        uint32_t s0 = b * RBC_ENERGY_BLOCK, s1 = s0 + RBC_ENERGY_BLOCK;
        if (s1 > t->ns) s1 = t->ns;
        double us = 0.0, ks = 0.0, kext = 0.0;
        for (uint32_t k = s0; k < s1; ++k) {
            uint32_t a = t->sa[k], bb = t->sb[k];
            double ex = (double)pos[0][a] - pos[0][bb], ey = (double)pos[1][a] - pos[1][bb],
                   ez = (double)pos[2][a] - pos[2][bb];
            double v = sqrt(ex * ex + ey * ey + ez * ez) - t->rest_len[k];
            us += t->stiff[k] * v * v;
            ks += t->stiff[k];
            kext += t->stiff[k] * fabs(v);
        }
        double *o = sbk + (size_t)RBC_ESB * b;
        o[RBC_E_US] = 0.5 * us;
        o[RBC_E_KSUM] = ks;
        o[RBC_E_KEXT] = kext;
    }
}

rbc_energy rbc_energy_sum(const rbc_cloth_state *c, float h, const float g[3], int springs) {
    const rbc_topology *t = &c->topo;
    const uint32_t nbp = rbc_energy_blocks_of(t->n), nbs = rbc_energy_blocks_of(t->ns);
    const double *pb = c->e_blk, *sbk = c->e_blk + (size_t)RBC_EPB * nbp;
    double ke = 0.0, ug = 0.0, mag = 0.0, wsum = 0.0, md = 0.0, xmax = 0.0, us = 0.0, ks = 0.0,
           kext = 0.0;
    for (uint32_t b = 0; b < nbp; ++b) {
        const double *o = pb + (size_t)RBC_EPB * b;
        ke += o[RBC_E_KE];
        ug += o[RBC_E_UG];
        mag += o[RBC_E_MAG];
        wsum += o[RBC_E_WSUM];
        md += o[RBC_E_MD];
        if (o[RBC_E_XMAX] > xmax) xmax = o[RBC_E_XMAX];
    }
    for (uint32_t b = 0; springs && b < nbs; ++b) {
        const double *o = sbk + (size_t)RBC_ESB * b;
        us += o[RBC_E_US];
        ks += o[RBC_E_KSUM];
        kext += o[RBC_E_KEXT];
    }
    rbc_energy e;
    e.kinetic = ke;
    e.spring = us;
    e.gravity = ug;
    e.guarded = ke + ug;
    /* What rounding the float state to nearest can change: a coordinate is known to
     * half an ulp, delta = 2^-24 X (|coordinates| <= X), so a velocity component to
     * 2 delta / h and a spring's extension to e = 2 sqrt(3) delta. First order:
     * sum m |v|_1 2 delta / h (|v|_1 = |vx| + |vy| + |vz|, the exact bound of v . dv)
     * + sum s |ext| e + sum m |g| sqrt(3) delta; second order: (sum m/h^2 + sum s)
     * e^2 / 2; and relative 2^-20 of the kinetic and spring sums (float products per
     * particle, each within 2^-22 of exact, summed in double), 2^-40 of the
     * gravitational one (double products). */
    const double delta = ldexp(xmax, -24), eps = 2.0 * sqrt(3.0) * delta;
    const double hd = h, gn = sqrt((double)g[0] * g[0] + (double)g[1] * g[1] + (double)g[2] * g[2]);
    const double mass = wsum * hd * hd;
    e.tolerance = ldexp(ke + us, -20) + ldexp(mag, -40) + md / (hd * hd) * 2.0 * delta +
                  kext * eps +
                  gn * mass * sqrt(3.0) * delta + 0.5 * (wsum + ks) * eps * eps;
    return e;
}

void rbc_energy_clear_work(rbc_cloth_state *c, uint32_t tid, uint32_t nt) {
    const uint32_t nbp = rbc_energy_blocks_of(c->topo.n);
    uint32_t b0, b1;
    rbc_energy_block_range(nbp, tid, nt, &b0, &b1);
    for (uint32_t b = b0; b < b1; ++b) c->e_blk[(size_t)RBC_EPB * b + RBC_E_WC] = 0.0;
}

double rbc_energy_sum_work(const rbc_cloth_state *c) {
    const uint32_t nbp = rbc_energy_blocks_of(c->topo.n);
    double w = 0.0;
    for (uint32_t b = 0; b < nbp; ++b) w += c->e_blk[(size_t)RBC_EPB * b + RBC_E_WC];
    return w;
}

double rbc_energy_pin_work_list(const uint32_t *list, uint32_t count, const uint32_t *sa,
                                const uint32_t *sb, const float *rest, const float *stiff,
                                const uint8_t *pinned, float *const before[3],
                                float *const after[3]) {
    double w = 0.0;
    for (uint32_t m = 0; m < count; ++m) {
        uint32_t k = list[m];
        w += rbc_k_spring_energy_at(k, sa, sb, rest, stiff, pinned, before[0], before[1],
                                    before[2], after[0], after[1], after[2]) -
             rbc_k_spring_energy_at(k, sa, sb, rest, stiff, pinned, before[0], before[1],
                                    before[2], before[0], before[1], before[2]);
    }
    return w;
}

double rbc_energy_pin_work(const rbc_cloth_state *c, float *const before[3],
                           float *const after[3]) {
    const rbc_topology *t = &c->topo;
    return rbc_energy_pin_work_list(c->pin_springs, c->pin_spring_count, t->sa, t->sb,
                                    t->rest_len, t->stiff, c->pinned, before, after);
}

int rbc_energy_rebuild_pin_springs(rbc_cloth_state *c, const rbc_allocator *a) {
    const rbc_topology *t = &c->topo;
    uint32_t count = 0;
    for (uint32_t k = 0; k < t->ns; ++k) count += c->pinned[t->sa[k]] || c->pinned[t->sb[k]];
    uint32_t *list = NULL;
    if (count) {
        list = rbc_mem_alloc(a, sizeof(uint32_t) * count);
        if (!list) return 0;
        uint32_t m = 0;
        for (uint32_t k = 0; k < t->ns; ++k)
            if (c->pinned[t->sa[k]] || c->pinned[t->sb[k]]) list[m++] = k;
    }
    rbc_mem_free(a, c->pin_springs, sizeof(uint32_t) * c->pin_spring_cap);
    c->pin_springs = list;
    c->pin_spring_count = c->pin_spring_cap = count;
    return 1;
}
