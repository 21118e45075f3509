/* cloth.c -- a cloth's life cycle and what a host reads and writes of its state
 * (cloth.h). */
#include "cloth.h"

#include <math.h>
#include <string.h>

#include "direct.h"
#include "energy.h"
#include "ell.h"
#include "global.h"
#include "lattice.h"
#include "prefetch.h"
#include "report.h"
#include "strain.h"

/* Per-particle state arrays (count n) and per-half-edge ones (count 2 ns). */
#define STATE_ARRAYS(X)                                                                  \
    X(x[0], float, n) X(x[1], float, n) X(x[2], float, n) X(q[0], float, n)              \
    X(q[1], float, n) X(q[2], float, n) X(p[0], float, n) X(p[1], float, n)              \
    X(p[2], float, n) X(y[0], float, n) X(y[1], float, n) X(y[2], float, n)              \
    X(snap_x[0], float, n) X(snap_x[1], float, n) X(snap_x[2], float, n)                 \
    X(snap_q[0], float, n) X(snap_q[1], float, n) X(snap_q[2], float, n)                 \
    X(dx, float, 2 * (size_t)ns) X(dy, float, 2 * (size_t)ns) X(dz, float, 2 * (size_t)ns) \
    X(bx, float, n) X(by, float, n) X(bz, float, n)                                      \
    X(w, float, n) X(inv_denom, float, n) X(pinned, uint8_t, n)                          \
    X(e_blk, double, rbc_energy_block_doubles((uint32_t)n, (uint32_t)ns))               \
    X(strain_blk, double, rbc_strain_block_doubles((uint32_t)ns))                       \
    X(strain_max_blk, float, rbc_strain_block_doubles((uint32_t)ns) / 2)

static void free_pins(const rbc_allocator *al, rbc_cloth_state *c) {
    rbc_mem_free(al, c->pin_idx, sizeof(uint32_t) * c->pin_cap);
    rbc_mem_free(al, c->pin_target, sizeof(float) * 3 * c->pin_cap);
    rbc_mem_free(al, c->pin_start, sizeof(float) * 3 * c->pin_cap);
    c->pin_idx = NULL;
    c->pin_target = c->pin_start = NULL;
    c->pin_cap = c->pin_count = 0;
}

int rbc_cloth_state_host_buffers(const rbc_allocator *al, rbc_cloth_state *c, int want) {
    size_t bytes = rbc_mul_size((size_t)c->topo.n * 3, sizeof(float));
    if (want && !c->cb_pos) {
        c->cb_pos = rbc_mem_alloc(al, bytes);
        c->cb_prev = rbc_mem_alloc(al, bytes);
        if (c->cb_pos && c->cb_prev) return 1;
    }
    if (want && c->cb_pos && c->cb_prev) return 1;
    rbc_mem_free(al, c->cb_pos, bytes);
    rbc_mem_free(al, c->cb_prev, bytes);
    c->cb_pos = c->cb_prev = NULL;
    return !want;
}

/* Which optional buffers a solver needs. */
static int needs_alt(rbc_solver_kind k) {
    return k == RBC_SOLVER_JACOBI || k == RBC_SOLVER_JACOBI_CHEBYSHEV ||
           k == RBC_SOLVER_RBGS_CHEBYSHEV;
}
static int needs_prev(rbc_solver_kind k) {
    return k == RBC_SOLVER_JACOBI_CHEBYSHEV || k == RBC_SOLVER_RBGS_CHEBYSHEV;
}

static void free_solver_buffers(const rbc_allocator *al, rbc_cloth_state *c, int alt, int prev) {
    size_t bytes = (size_t)c->topo.n * sizeof(float);
    for (int a = 0; a < 3; ++a) {
        if (alt) {
            rbc_mem_free(al, c->alt[a], bytes);
            c->alt[a] = NULL;
        }
        if (prev) {
            rbc_mem_free(al, c->prev[a], bytes);
            c->prev[a] = NULL;
        }
    }
}

int rbc_cloth_state_solver_buffers(const rbc_allocator *al, rbc_cloth_state *c, rbc_solver_kind k) {
    size_t bytes = (size_t)c->topo.n * sizeof(float);
    int want_alt = needs_alt(k) && !c->alt[0], want_prev = needs_prev(k) && !c->prev[0];
    for (int a = 0; a < 3; ++a) {
        if (want_alt && !(c->alt[a] = rbc_mem_alloc(al, bytes))) goto fail;
        if (want_prev && !(c->prev[a] = rbc_mem_alloc(al, bytes))) goto fail;
    }
    return 1;
fail:
    free_solver_buffers(al, c, want_alt, want_prev);
    return 0;
}

void rbc_cloth_state_release_solver_buffers(const rbc_allocator *al, rbc_cloth_state *c,
                                            rbc_solver_kind k) {
    /* A scene pays only for its solver. */
    free_solver_buffers(al, c, !needs_alt(k), !needs_prev(k));
}

void rbc_cloth_state_destroy(const rbc_allocator *al, rbc_cloth_state *c) {
    if (!c) return;
    free_solver_buffers(al, c, 1, 1);
    rbc_direct_destroy(c->direct);
    size_t n = c->topo.n, ns = c->topo.ns;
    (void)n;
    (void)ns;
#define FREE_ONE(name, type, count) rbc_mem_free(al, c->name, rbc_mul_size(count, sizeof(type)));
    STATE_ARRAYS(FREE_ONE)
#undef FREE_ONE
    free_pins(al, c);
    rbc_lattice_free(c->lattice, al);
    rbc_ell_free(c->ell, al);
    rbc_mem_free(al, c->pin_springs, sizeof(uint32_t) * c->pin_spring_cap);
    rbc_cloth_state_host_buffers(al, c, 0);
    /* quad_count0: cuts and tearing shrink quad_count, not the array. */
    rbc_mem_free(al, c->quads, sizeof(uint32_t) * 4 * (size_t)c->quad_count0);
    rbc_mem_free(al, c->tris, sizeof(uint32_t) * 3 * (size_t)c->tri_cap);
    rbc_mem_free(al, c->att.vertex, sizeof(uint32_t) * c->att.cap);
    rbc_mem_free(al, c->att.collider, sizeof(uint32_t) * c->att.cap);
    rbc_mem_free(al, c->att.local, sizeof(float) * 3 * c->att.cap);
    rbc_mem_free(al, c->lone_tris, sizeof(uint32_t) * 3 * (size_t)c->lone_cap);
    if (c->normal_acc) rbc_mem_free(al, c->normal_acc, 3 * (size_t)c->topo.n * sizeof(float));
    rbc_topology_free(&c->topo, al);
    rbc_mem_free(al, c, sizeof *c);
}

static int grow_pins(const rbc_allocator *al, rbc_cloth_state *c, uint32_t need) {
    if (need <= c->pin_cap) return 1;
    uint32_t cap = c->pin_cap ? c->pin_cap : 8;
    while (cap < need) cap *= 2;
    uint32_t *idx = rbc_mem_alloc(al, sizeof(uint32_t) * cap);
    float *tgt = rbc_mem_alloc(al, sizeof(float) * 3 * cap);
    float *st = rbc_mem_alloc(al, sizeof(float) * 3 * cap);
    if (!idx || !tgt || !st) {
        rbc_mem_free(al, idx, sizeof(uint32_t) * cap);
        rbc_mem_free(al, tgt, sizeof(float) * 3 * cap);
        rbc_mem_free(al, st, sizeof(float) * 3 * cap);
        return 0;
    }
    if (c->pin_count) {
        memcpy(idx, c->pin_idx, sizeof(uint32_t) * c->pin_count);
        memcpy(tgt, c->pin_target, sizeof(float) * 3 * c->pin_count);
        memcpy(st, c->pin_start, sizeof(float) * 3 * c->pin_count);
    }
    uint32_t count = c->pin_count;
    free_pins(al, c);
    c->pin_idx = idx;
    c->pin_target = tgt;
    c->pin_start = st;
    c->pin_cap = cap;
    c->pin_count = count;
    return 1;
}

int32_t rbc_cloth_state_create(const rbc_allocator *al, rbc_solver_kind kind, int host_buffers,
                               const rbc_mesh_input *in, float damping,
                               rbc_cloth_state **out, char *err, size_t errlen) {
    *out = NULL;
    rbc_cloth_state *c = rbc_mem_alloc(al, sizeof *c);
    if (!c) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for a cloth");
    int32_t rc = rbc_topology_build(in, al, &c->topo, err, errlen);
    if (rc != RBC_OK) {
        rbc_mem_free(al, c, sizeof *c);
        return rc;
    }
    const size_t n = c->topo.n, ns = c->topo.ns;
    int ok = 1;
    size_t bytes = 0;
#define ALLOC_ONE(name, type, count) RBC_ALLOC_ARRAY(al, c->name, count, type, ok, bytes);
    STATE_ARRAYS(ALLOC_ONE)
#undef ALLOC_ONE
    if (ok && in->pin_count) ok = grow_pins(al, c, in->pin_count);
    if (ok && host_buffers) ok = rbc_cloth_state_host_buffers(al, c, 1);
    if (ok) ok = rbc_cloth_state_solver_buffers(al, c, kind);
    if (ok && in->quad_count) {
        /* The quads in internal indices: cloth contact's triangles and what remains
         * after tearing are made from them. */
        c->quads = rbc_mem_alloc(al, rbc_mul_size((size_t)in->quad_count * 4, sizeof(uint32_t)));
        ok = c->quads != NULL;
        if (ok) {
            c->quad_count = c->quad_count0 = in->quad_count;
            const size_t nc = 4 * (size_t)in->quad_count, ahead = 4 * RBC_PREFETCH_AHEAD;
            for (size_t k = 0; k < nc; ++k) {
                /* Corners at random in a scattered mesh: their internal index ahead. */
                if (k + ahead < nc) RBC_PREFETCH(&c->topo.to_internal[in->quads[k + ahead]]);
                c->quads[k] = c->topo.to_internal[in->quads[k]];
            }
        }
    }
    if (!ok) {
        rbc_cloth_state_destroy(al, c);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %zu particles", n);
    }
    c->state_bytes = bytes;
    c->damping = damping;
    double rest_sum = 0.0;
    for (uint32_t k = 0; k < c->topo.ns; ++k) rest_sum += c->topo.rest_len[k];
    c->mean_rest = c->topo.ns ? (float)(rest_sum / c->topo.ns) : 0.0f;
    const rbc_topology *t = &c->topo;
    memcpy(c->x[0], t->rest_x, n * sizeof(float));
    memcpy(c->x[1], t->rest_y, n * sizeof(float));
    memcpy(c->x[2], t->rest_z, n * sizeof(float));
    memcpy(c->q[0], t->rest_x, n * sizeof(float)); /* at rest: zero initial velocity */
    memcpy(c->q[1], t->rest_y, n * sizeof(float));
    memcpy(c->q[2], t->rest_z, n * sizeof(float));
    /* d_ij is not set here: every reader (the right-hand side, the direct solve) runs
     * after the local step of the same non-linear iteration has written it, and the
     * lattice path never uses it. Left untouched, its pages are never faulted in. */
    for (uint32_t k = 0; k < in->pin_count; ++k) {
        uint32_t i = t->to_internal[in->pins[k]];
        if (c->pinned[i]) continue; /* a vertex listed twice is one pin */
        c->pinned[i] = 1;
        uint32_t m = c->pin_count++;
        c->pin_idx[m] = i;
        c->pin_target[3 * m] = c->x[0][i];
        c->pin_target[3 * m + 1] = c->x[1][i];
        c->pin_target[3 * m + 2] = c->x[2][i];
    }
    if (!rbc_energy_rebuild_pin_springs(c, al) ||
        rbc_lattice_detect(&c->topo, al, &c->lattice) < 0 ||
        (!c->lattice && rbc_ell_build(&c->topo, al, &c->ell) < 0)) {
        rbc_cloth_state_destroy(al, c);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %zu particles", n);
    }
    c->h_cached = 0.0f;
    c->h_last = 0.0f;
    c->tri_revision = 1;
    c->guard.valid = 0;
    c->guard.keep_slack = 0;
    *out = c;
    return RBC_OK;
}

int32_t rbc_cloth_state_set_contact(const rbc_allocator *al, rbc_cloth_state *c, float thickness,
                                    float friction, uint32_t flags) {
    if (flags && !c->tris && c->quad_count) {
        size_t count = 2 * (size_t)c->quad_count;
        uint32_t *t = rbc_mem_alloc(al, rbc_mul_size(count * 3, sizeof(uint32_t)));
        if (!t) return RBC_ERR_OUT_OF_MEMORY;
        for (size_t q = 0; q < c->quad_count; ++q) {
            const uint32_t *v = &c->quads[4 * q];
            uint32_t *a = &t[6 * q];
            a[0] = v[0], a[1] = v[1], a[2] = v[2];
            a[3] = v[0], a[4] = v[2], a[5] = v[3];
        }
        c->tris = t;
        c->tri_count = c->tri_cap = (uint32_t)count;
    } else if (!flags && c->tris) {
        rbc_mem_free(al, c->tris, sizeof(uint32_t) * 3 * (size_t)c->tri_cap);
        c->tris = NULL;
        c->tri_count = c->tri_cap = 0;
    }
    c->thickness = thickness;
    c->friction = friction;
    c->collision_flags = flags;
    return RBC_OK;
}

int32_t rbc_cloth_state_set_pin(const rbc_allocator *al, rbc_cloth_state *c, uint32_t host_vertex,
                                const float *target) {
    uint32_t i = c->topo.to_internal[host_vertex];
    uint32_t m = c->pin_count;
    for (uint32_t k = 0; k < c->pin_count; ++k)
        if (c->pin_idx[k] == i) m = k;
    if (!target) {
        if (m == c->pin_count) return RBC_OK; /* not pinned: nothing to release */
        c->pinned[i] = 0;
        if (!rbc_energy_rebuild_pin_springs(c, al)) {
            c->pinned[i] = 1;
            return RBC_ERR_OUT_OF_MEMORY;
        }
        uint32_t last = --c->pin_count;
        c->pin_idx[m] = c->pin_idx[last];
        memcpy(&c->pin_target[3 * m], &c->pin_target[3 * last], 3 * sizeof(float));
        c->direct_dirty = 1; /* the free set changed: refactor */
        rbc_cloth_state_rho_invalidate(c);
        rbc_cloth_state_energy_invalidate(c, 1); /* a free particle more */
        return RBC_OK;
    }
    if (m == c->pin_count) {
        if (!grow_pins(al, c, c->pin_count + 1)) return RBC_ERR_OUT_OF_MEMORY;
        c->pinned[i] = 1;
        if (!rbc_energy_rebuild_pin_springs(c, al)) {
            c->pinned[i] = 0;
            return RBC_ERR_OUT_OF_MEMORY;
        }
        c->pin_idx[m] = i;
        c->pin_count++;
        c->direct_dirty = 1;
        rbc_cloth_state_rho_invalidate(c);
        rbc_cloth_state_energy_invalidate(c, 1); /* a free particle less */
    }
    memcpy(&c->pin_target[3 * m], target, 3 * sizeof(float));
    return RBC_OK;
}

void rbc_cloth_state_read(const rbc_cloth_state *c, float *xyz) {
    const uint32_t *to_int = c->topo.to_internal;
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        uint32_t i = to_int[v];
        xyz[3 * (size_t)v] = c->x[0][i];
        xyz[3 * (size_t)v + 1] = c->x[1][i];
        xyz[3 * (size_t)v + 2] = c->x[2][i];
    }
}

void rbc_cloth_state_error(const rbc_cloth_state *c, double *eq7, double *max_strain) {
    const rbc_topology *t = &c->topo;
    double e = 0.0, worst = 0.0;
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t a = t->sa[k], b = t->sb[k];
        double ex = (double)c->x[0][a] - c->x[0][b], ey = (double)c->x[1][a] - c->x[1][b],
               ez = (double)c->x[2][a] - c->x[2][b];
        if (c->torn && t->stiff[k] == 0.0f) continue; /* broken */
        double len = sqrt(ex * ex + ey * ey + ez * ez), L = t->rest_len[k];
        e += (len - L) * (len - L);
        if (L > 0.0) {
            double strain = fabs(len / L - 1.0);
            if (strain > worst) worst = strain;
        }
    }
    *eq7 = e;
    *max_strain = worst;
}

void rbc_cloth_state_get(const rbc_cloth_state *c, float *pos, float *prev) {
    const uint32_t *to_int = c->topo.to_internal;
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        uint32_t i = to_int[v];
        for (int a = 0; a < 3; ++a) {
            if (pos) pos[3 * (size_t)v + a] = c->x[a][i];
            if (prev) prev[3 * (size_t)v + a] = c->q[a][i];
        }
    }
}

void rbc_cloth_state_set(rbc_cloth_state *c, const float *pos, const float *prev) {
    const uint32_t *to_int = c->topo.to_internal;
    if (!prev) prev = pos;
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        uint32_t i = to_int[v];
        if (c->pinned[i]) continue;
        for (int a = 0; a < 3; ++a) {
            c->x[a][i] = pos[3 * (size_t)v + a];
            c->q[a][i] = prev[3 * (size_t)v + a];
        }
    }
    c->system_valid = 0;
    c->h_last = 0.0f; /* prev is the host's: its velocity is over the next h */
    rbc_cloth_state_energy_invalidate(c, 0); /* a new state: a new budget */
}

size_t rbc_cloth_state_bytes(const rbc_cloth_state *c) {
    size_t n3 = 3 * (size_t)c->topo.n * sizeof(float);
    size_t b = sizeof *c + c->state_bytes + c->topo.bytes;
    b += (size_t)c->pin_cap * (sizeof(uint32_t) + 6 * sizeof(float));
    b += (size_t)c->pin_spring_cap * sizeof(uint32_t);
    if (c->cb_pos) b += 2 * n3;
    if (c->alt[0]) b += n3;
    if (c->prev[0]) b += n3;
    if (c->direct) b += rbc_direct_bytes(c->direct);
    if (c->lattice) b += c->lattice->bytes;
    if (c->ell) b += c->ell->bytes;
    b += (size_t)c->quad_count0 * 4 * sizeof(uint32_t) + (size_t)c->tri_cap * 3 * sizeof(uint32_t);
    b += (size_t)c->att.cap * 5 * sizeof(uint32_t);
    b += (size_t)c->lone_cap * 3 * sizeof(uint32_t); /* render.h's */
    if (c->normal_acc) b += n3;
    return b;
}

/* acc plus the springs' energy at x, sum_k s_k (|x_a - x_b| - L_k)^2 / 2, added in spring
 * order (double precision). */
static double add_spring_energy(const rbc_cloth_state *c, double acc) {
    const rbc_topology *t = &c->topo;
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t a = t->sa[k], b = t->sb[k];
        double ex = (double)c->x[0][a] - c->x[0][b], ey = (double)c->x[1][a] - c->x[1][b],
               ez = (double)c->x[2][a] - c->x[2][b];
        double v = sqrt(ex * ex + ey * ey + ez * ez) - t->rest_len[k];
        acc += 0.5 * t->stiff[k] * v * v;
    }
    return acc;
}

void rbc_cloth_state_energy(const rbc_cloth_state *c, const float g[3], int measure,
                            double *kinetic, double *potential, double *budget) {
    *budget = c->guard.valid ? c->guard.budget : 0.0;
    if (!measure) return;
    const rbc_topology *t = &c->topo;
    double ke = 0.0, ug = 0.0, us = 0.0;
    float h = c->h_cached;
    for (uint32_t i = 0; i < t->n; ++i) {
        if (c->pinned[i]) continue;
        double d2 = 0.0, gp = 0.0;
        for (int a = 0; a < 3; ++a) {
            double d = (double)c->x[a][i] - c->q[a][i];
            d2 += d * d;
            gp += (double)g[a] * c->x[a][i];
        }
        if (h > 0.0f) ke += 0.5 * t->mass[i] * d2 / ((double)h * h);
        ug -= t->mass[i] * gp;
    }
    us = add_spring_energy(c, us);
    *kinetic = ke;
    *potential = us + ug;
}

void rbc_cloth_state_energy_invalidate(rbc_cloth_state *c, int keep_slack) {
    /* Keep the slack only if there was a budget to keep it from. */
    c->guard.keep_slack = keep_slack && (c->guard.valid || c->guard.keep_slack);
    c->guard.valid = 0;
}

void rbc_cloth_state_system_error(const rbc_cloth_state *c, double *res_num2, double *res_den2,
                                  double *objective) {
    *res_num2 = *res_den2 = *objective = 0.0;
    if (!c->system_valid) return;
    const rbc_topology *t = &c->topo;
    /* The residual reads p: evaluate it at the committed positions x. */
    rbc_cloth_state tmp = *c;
    for (int a = 0; a < 3; ++a) tmp.p[a] = c->x[a];
    rbc_global_residual(&tmp, t->ncolors, 0, 1, res_num2, res_den2);
    double obj = 0.0;
    for (uint32_t i = 0; i < t->n; ++i) {
        if (c->pinned[i]) continue;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double d = (double)c->x[a][i] - c->y[a][i];
            d2 += d * d;
        }
        obj += 0.5 * c->w[i] * d2;
    }
    obj = add_spring_energy(c, obj);
    *objective = obj;
}

void rbc_cloth_state_stiffness_changed(rbc_cloth_state *c) {
    c->h_cached = 0.0f;                /* 1 / (m/h^2 + sum s) changed */
    rbc_cloth_state_rho_invalidate(c); /* the spectral radius too */
    c->direct_dirty = 1;               /* and the matrix */
}
