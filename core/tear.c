/* tear.c -- tearing and cuts (tear.h). */
#include "tear.h"

#include <string.h>

#include "ell.h"
#include "lattice.h"

/* The one place a spring breaks: each owner of a copy of its stiffness (the
 * topology's spring list and CSR rows, the ELLPACK slots, the lattice's stencil)
 * zeroes its own. */
int rbc_tear_spring(rbc_cloth_state *c, uint32_t sp) {
    if (!rbc_topology_break_spring(&c->topo, sp)) return 0;
    if (c->ell) rbc_ell_break_spring(c->ell, &c->topo, sp);
    if (c->lattice) rbc_lattice_break_spring(c->lattice, &c->topo, sp);
    c->torn++;
    return 1;
}

/* 1 if the pair has a spring and it is broken. */
static int broken_pair(const rbc_cloth_state *c, uint32_t i, uint32_t j) {
    const rbc_topology *t = &c->topo;
    for (uint32_t s = t->adj_start[i]; s < t->adj_start[i + 1]; ++s)
        if (t->adj_nbr[s] == j) return t->adj_k[s] == 0.0f;
    return 0;
}

void rbc_tear_finish(rbc_cloth_state *c) {
    uint32_t kept = 0;
    for (uint32_t q = 0; q < c->quad_count; ++q) {
        const uint32_t *v = &c->quads[4 * (size_t)q];
        int gone = 0;
        for (int a = 0; a < 4 && !gone; ++a)
            for (int b = a + 1; b < 4 && !gone; ++b) gone = broken_pair(c, v[a], v[b]);
        if (gone) continue;
        if (kept != q) memmove(&c->quads[4 * (size_t)kept], v, 4 * sizeof(uint32_t));
        kept++;
    }
    /* Leftover triangles of an imported mesh go with any torn edge, as quads do. */
    uint32_t lone = 0;
    for (uint32_t k = 0; k < c->lone_count; ++k) {
        const uint32_t *v = &c->lone_tris[3 * (size_t)k];
        if (broken_pair(c, v[0], v[1]) || broken_pair(c, v[1], v[2]) ||
            broken_pair(c, v[2], v[0]))
            continue;
        if (lone != k) memmove(&c->lone_tris[3 * (size_t)lone], v, 3 * sizeof(uint32_t));
        lone++;
    }
    if (kept != c->quad_count || lone != c->lone_count) c->tri_revision++;
    c->lone_count = lone;
    c->quad_count = kept;
    if (c->tris) {
        for (uint32_t q = 0; q < kept; ++q) {
            const uint32_t *v = &c->quads[4 * (size_t)q];
            uint32_t *a = &c->tris[6 * (size_t)q];
            a[0] = v[0], a[1] = v[1], a[2] = v[2];
            a[3] = v[0], a[4] = v[2], a[5] = v[3];
        }
        c->tri_count = 2 * kept;
    }
    rbc_cloth_state_stiffness_changed(c);
}

uint32_t rbc_tear_scan(rbc_solver *s, rbc_cloth_state *c) {
    if (!(c->tear_strain > 0.0f)) return 0;
    const rbc_topology *t = &c->topo;
    const float *px = c->x[0], *py = c->x[1], *pz = c->x[2];
    const float f = 1.0f + c->tear_strain, f2 = f * f;
    uint32_t broken = 0;
    for (uint32_t k = 0; k < t->ns; ++k) {
        if (t->stiff[k] == 0.0f) continue;
        uint32_t a = t->sa[k], b = t->sb[k];
        float ex = px[a] - px[b], ey = py[a] - py[b], ez = pz[a] - pz[b];
        float L = t->rest_len[k];
        if (ex * ex + ey * ey + ez * ez > f2 * L * L) broken += (uint32_t)rbc_tear_spring(c, k);
    }
    if (broken) rbc_tear_finish(c);
    s->torn_springs += broken;
    return broken;
}

int32_t rbc_cut_pairs(rbc_solver *s, rbc_cloth_state *c, const uint32_t *pairs, uint32_t count,
                      uint32_t *out_cut) {
    const rbc_topology *t = &c->topo;
    /* Which spring owns each CSR slot: one O(springs) pass per call, not per pair. */
    size_t slots = 2 * (size_t)t->ns;
    uint32_t *owner = rbc_mem_alloc(&s->alloc, rbc_mul_size(slots ? slots : 1, sizeof(uint32_t)));
    if (!owner) return RBC_ERR_OUT_OF_MEMORY;
    for (uint32_t k = 0; k < t->ns; ++k) {
        owner[t->he_a[k]] = k;
        owner[t->he_b[k]] = k;
    }
    uint32_t cut = 0;
    for (uint32_t m = 0; m < count; ++m) {
        uint32_t i = t->to_internal[pairs[2 * (size_t)m]], j = t->to_internal[pairs[2 * (size_t)m + 1]];
        for (uint32_t sl = t->adj_start[i]; sl < t->adj_start[i + 1]; ++sl)
            if (t->adj_nbr[sl] == j) {
                cut += (uint32_t)rbc_tear_spring(c, owner[sl]);
                break;
            }
    }
    rbc_mem_free(&s->alloc, owner, rbc_mul_size(slots ? slots : 1, sizeof(uint32_t)));
    if (cut) rbc_tear_finish(c);
    s->torn_springs += cut;
    if (out_cut) *out_cut = cut;
    return RBC_OK;
}

size_t rbc_cloth_quads_host(const rbc_cloth_state *c, uint32_t *out, size_t cap) {
    size_t need = 4 * (size_t)c->quad_count;
    for (size_t k = 0; out && k < need && k < cap; ++k) out[k] = c->topo.to_host[c->quads[k]];
    return need;
}

size_t rbc_cloth_springs_host(const rbc_cloth_state *c, uint32_t *out, size_t cap) {
    const rbc_topology *t = &c->topo;
    size_t m = 0;
    for (uint32_t k = 0; k < t->ns; ++k) {
        if (t->stiff[k] == 0.0f) continue;
        if (out && m + 2 <= cap) {
            out[m] = t->to_host[t->sa[k]];
            out[m + 1] = t->to_host[t->sb[k]];
        }
        m += 2;
    }
    return m;
}
