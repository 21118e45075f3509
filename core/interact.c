/* interact.c -- tearing and cuts, picking, attachments, wind (interact.h). */
#include "interact.h"

#include <math.h>
#include <string.h>

#include "collide.h"
#include "ell.h"
#include "grid.h"

/* ------------------------------------------------------------------------- */
/* Tearing                                                                    */
/* ------------------------------------------------------------------------- */

/* Zero the stiffness of the ELL slot that mirrors CSR slot s of particle i. */
static void ell_zero(rbc_ell *e, const rbc_topology *t, uint32_t i, uint32_t s) {
    *rbc_ell_slot_k(e, t, i, s - t->adj_start[i]) = 0.0f;
}

/* Zero the lattice stiffness from i toward j (its left/right/down/up neighbour). */
static void grid_zero(rbc_grid *g, const rbc_cloth_state *c, uint32_t i, uint32_t j) {
    uint32_t hi = c->topo.to_host[i], hj = c->topo.to_host[j];
    uint32_t nx = g->nx;
    if (hj + 1 == hi && hi % nx != 0) g->kl[i] = 0.0f;
    else if (hi + 1 == hj && hj % nx != 0) g->kr[i] = 0.0f;
    else if (hj + nx == hi) g->kd[i] = 0.0f;
    else if (hi + nx == hj) g->ku[i] = 0.0f;
}

int rbc_tear_spring(rbc_cloth_state *c, uint32_t sp) {
    rbc_topology *t = &c->topo;
    float k = t->stiff[sp];
    if (k == 0.0f) return 0;
    uint32_t a = t->sa[sp], b = t->sb[sp];
    uint32_t sa = t->he_a[sp], sb = t->he_b[sp];
    t->stiff[sp] = 0.0f;
    t->adj_k[sa] = 0.0f;
    t->adj_k[sb] = 0.0f;
    /* Sums of what remains, recomputed (no drift from subtracting). */
    for (int e = 0; e < 2; ++e) {
        uint32_t i = e ? b : a;
        float sum = 0.0f;
        for (uint32_t s = t->adj_start[i]; s < t->adj_start[i + 1]; ++s) sum += t->adj_k[s];
        t->ksum[i] = sum;
    }
    if (c->ell) {
        ell_zero(c->ell, t, a, sa);
        ell_zero(c->ell, t, b, sb);
    }
    if (c->grid) {
        grid_zero(c->grid, c, a, b);
        grid_zero(c->grid, c, b, a);
        c->grid->k_uniform = 0.0f;
    }
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

void rbc_tear_finish(rbc_solver *s, rbc_cloth_state *c) {
    (void)s;
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
    c->h_cached = 0.0f;  /* 1 / (m/h^2 + sum s) changed */
    rbc_cloth_state_rho_invalidate(c);   /* the spectral radius too */
    c->direct_dirty = 1; /* and the matrix */
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
    if (broken) rbc_tear_finish(s, c);
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
    if (cut) rbc_tear_finish(s, c);
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

/* ------------------------------------------------------------------------- */
/* Picking                                                                    */
/* ------------------------------------------------------------------------- */

int rbc_pick(const rbc_solver *s, const float o[3], const float d[3], float tmax, float radius,
             uint32_t *cloth_index, uint32_t *host_vertex, float *t_out) {
    double dd = (double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2];
    double r2 = (double)radius * radius;
    int found = 0;
    double best_t = 0.0, best_d2 = 0.0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        const rbc_cloth_state *c = s->cloths[k];
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            uint32_t i = c->topo.to_internal[v];
            double w[3] = {(double)c->x[0][i] - o[0], (double)c->x[1][i] - o[1],
                           (double)c->x[2][i] - o[2]};
            double t = (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd;
            if (t < 0.0) t = 0.0;
            if (t > tmax) t = tmax;
            double e2 = 0.0;
            for (int a = 0; a < 3; ++a) {
                double e = w[a] - t * d[a];
                e2 += e * e;
            }
            if (e2 > r2) continue;
            if (!found || t < best_t || (t == best_t && e2 < best_d2)) {
                found = 1;
                best_t = t;
                best_d2 = e2;
                *cloth_index = k;
                *host_vertex = v;
            }
        }
    }
    if (found) *t_out = (float)best_t;
    return found;
}

/* ------------------------------------------------------------------------- */
/* Attachments                                                                */
/* ------------------------------------------------------------------------- */

static const rbc_collider_state *find_collider(const rbc_solver *s, uint32_t id) {
    for (uint32_t k = 0; k < s->collider_count; ++k)
        if (s->colliders[k].public_id == id) return &s->colliders[k];
    return NULL;
}

void rbc_detach_vertex(rbc_cloth_state *c, uint32_t host_vertex) {
    for (uint32_t m = 0; m < c->att_count; ++m) {
        if (c->att_vertex[m] != host_vertex) continue;
        uint32_t last = --c->att_count;
        c->att_vertex[m] = c->att_vertex[last];
        c->att_collider[m] = c->att_collider[last];
        memcpy(&c->att_local[3 * (size_t)m], &c->att_local[3 * (size_t)last], 3 * sizeof(float));
        return;
    }
}

static void frame_apply(const rbc_collider_state *col, const float l[3], float w[3]) {
    rbc_frame f;
    rbc_collider_frame_at(col, 1.0f, &f);
    for (int a = 0; a < 3; ++a)
        w[a] = f.r[3 * a] * l[0] + f.r[3 * a + 1] * l[1] + f.r[3 * a + 2] * l[2] + f.t[a];
}

int32_t rbc_attach(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                   uint32_t collider_public_id, const float local[3]) {
    const rbc_collider_state *col = find_collider(s, collider_public_id);
    if (!col) return RBC_ERR_STALE_HANDLE;
    float l[3], target[3];
    if (local) {
        memcpy(l, local, sizeof l);
    } else {
        /* Where the vertex is now, in the collider's frame. */
        rbc_frame f;
        rbc_collider_frame_at(col, 1.0f, &f);
        uint32_t i = c->topo.to_internal[host_vertex];
        float d[3] = {c->x[0][i] - f.t[0], c->x[1][i] - f.t[1], c->x[2][i] - f.t[2]};
        for (int a = 0; a < 3; ++a) l[a] = f.r[a] * d[0] + f.r[3 + a] * d[1] + f.r[6 + a] * d[2];
    }
    frame_apply(col, l, target);
    rbc_detach_vertex(c, host_vertex);
    if (c->att_count == c->att_cap) {
        uint32_t cap = c->att_cap ? 2 * c->att_cap : 8;
        uint32_t *v = rbc_mem_alloc(&s->alloc, sizeof(uint32_t) * cap);
        uint32_t *id = rbc_mem_alloc(&s->alloc, sizeof(uint32_t) * cap);
        float *lo = rbc_mem_alloc(&s->alloc, sizeof(float) * 3 * cap);
        if (!v || !id || !lo) {
            rbc_mem_free(&s->alloc, v, sizeof(uint32_t) * cap);
            rbc_mem_free(&s->alloc, id, sizeof(uint32_t) * cap);
            rbc_mem_free(&s->alloc, lo, sizeof(float) * 3 * cap);
            return RBC_ERR_OUT_OF_MEMORY;
        }
        if (c->att_count) {
            memcpy(v, c->att_vertex, sizeof(uint32_t) * c->att_count);
            memcpy(id, c->att_collider, sizeof(uint32_t) * c->att_count);
            memcpy(lo, c->att_local, sizeof(float) * 3 * c->att_count);
        }
        rbc_mem_free(&s->alloc, c->att_vertex, sizeof(uint32_t) * c->att_cap);
        rbc_mem_free(&s->alloc, c->att_collider, sizeof(uint32_t) * c->att_cap);
        rbc_mem_free(&s->alloc, c->att_local, sizeof(float) * 3 * c->att_cap);
        c->att_vertex = v;
        c->att_collider = id;
        c->att_local = lo;
        c->att_cap = cap;
    }
    int32_t rc = rbc_cloth_state_set_pin(s, c, host_vertex, target);
    if (rc != RBC_OK) return rc;
    uint32_t m = c->att_count++;
    c->att_vertex[m] = host_vertex;
    c->att_collider[m] = collider_public_id;
    memcpy(&c->att_local[3 * (size_t)m], l, sizeof l);
    return RBC_OK;
}

void rbc_attachments_update(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->att_count; ++m) {
            const rbc_collider_state *col = find_collider(s, c->att_collider[m]);
            if (!col) continue; /* dropped with its collider */
            float target[3];
            frame_apply(col, &c->att_local[3 * (size_t)m], target);
            /* The vertex is pinned (attach pinned it): only the target moves, which
             * cannot fail. */
            uint32_t i = c->topo.to_internal[c->att_vertex[m]];
            for (uint32_t p = 0; p < c->pin_count; ++p)
                if (c->pin_idx[p] == i) memcpy(&c->pin_target[3 * (size_t)p], target, sizeof target);
        }
    }
}

int32_t rbc_attachments_drop_collider(rbc_solver *s, uint32_t collider_public_id) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->att_count;) {
            if (c->att_collider[m] != collider_public_id) {
                ++m;
                continue;
            }
            uint32_t v = c->att_vertex[m];
            rbc_detach_vertex(c, v);
            int32_t rc = rbc_cloth_state_set_pin(s, c, v, NULL);
            if (rc != RBC_OK) return rc;
        }
    }
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* Wind                                                                       */
/* ------------------------------------------------------------------------- */

void rbc_wind_apply(rbc_solver *s, float h) {
    const float drag = s->wind_drag, lift = s->wind_lift;
    const float h2 = h * h, inv_h = 1.0f / h;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        double work = 0.0;
        for (uint32_t q = 0; q < c->quad_count; ++q) {
            const uint32_t *v = &c->quads[4 * (size_t)q];
            float P[4][3], vel[3] = {0, 0, 0};
            for (int m = 0; m < 4; ++m)
                for (int a = 0; a < 3; ++a) {
                    P[m][a] = c->x[a][v[m]];
                    vel[a] += 0.25f * (c->x[a][v[m]] - c->q[a][v[m]]) * inv_h;
                }
            /* Area vector of the quad: half the cross product of its diagonals. */
            float d1[3] = {P[2][0] - P[0][0], P[2][1] - P[0][1], P[2][2] - P[0][2]};
            float d2[3] = {P[3][0] - P[1][0], P[3][1] - P[1][1], P[3][2] - P[1][2]};
            float an[3] = {0.5f * (d1[1] * d2[2] - d1[2] * d2[1]),
                           0.5f * (d1[2] * d2[0] - d1[0] * d2[2]),
                           0.5f * (d1[0] * d2[1] - d1[1] * d2[0])};
            float area = sqrtf(an[0] * an[0] + an[1] * an[1] + an[2] * an[2]);
            if (!(area > 0.0f)) continue;
            float n[3] = {an[0] / area, an[1] / area, an[2] / area};
            float r[3] = {s->wind[0] - vel[0], s->wind[1] - vel[1], s->wind[2] - vel[2]};
            float rn = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
            float F[3];
            for (int a = 0; a < 3; ++a) {
                float tang = r[a] - rn * n[a];
                F[a] = area * (drag * rn * n[a] + lift * fabsf(rn) * tang);
            }
            float fm = 0.25f * sqrtf(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
            for (int m = 0; m < 4; ++m) {
                uint32_t i = v[m];
                if (c->pinned[i]) continue;
                float sc = 0.25f * h2 / c->topo.mass[i];
                for (int a = 0; a < 3; ++a) {
                    c->y[a][i] += sc * F[a];
                    c->p[a][i] += sc * F[a];
                }
                /* The wind's work on the corner over the substep, bounded by its force
                 * times how far the corner moves: what it moved last substep plus what
                 * the force alone adds. */
                float dx = c->x[0][i] - c->q[0][i], dy = c->x[1][i] - c->q[1][i],
                      dz = c->x[2][i] - c->q[2][i];
                work += (double)fm * (sqrtf(dx * dx + dy * dy + dz * dz) + sc * 4.0f * fm);
            }
        }
        c->e_step_budget += work; /* the energy guard's budget (wind supplies energy) */
    }
}
