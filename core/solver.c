/* solver.c -- Algorithm 1 of the paper on the CPU backend.
 *
 * One rbc_solver_step runs a single SPMD function on every pool thread. Each phase
 * splits its range statically among the threads and ends at a barrier:
 *
 *   for each substep:
 *     integrate    Alg. 2: y = Verlet prediction, p = y; pins set       (particles)
 *     loop nonlinear_iterations:
 *       local      Alg. 3: d_ij for every spring                        (springs)
 *       global     Eq. 6 by the selected solver (global.c): RBGS sweeps one
 *                  color at a time (red, then black; more colors when the graph
 *                  needs them), Jacobi, SOR, Chebyshev, serial Gauss-Seidel, or the
 *                  exact direct solve; linear iterations fixed, to a tolerance,
 *                  or within a time budget
 *     collide      built-in colliders project the free particles       (particles)
 *     callback     the host's collision code, on thread 0
 *     check        every position finite, else restore and fail
 *     commit       q <- x <- p (buffer rotation, thread 0)
 *
 * The particles of one color share no spring, so the threads of a color sweep never
 * read a position another thread writes: the result is bitwise independent of the
 * thread count.
 */
#include "report.h"
#include "solver.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "clothcontact.h"
#include "direct.h"
#include "energy.h"
#include "ell.h"
#include "grid.h"
#include "interact.h"
#include "simd.h"
#include "strain.h"
#include "global.h"
#include "kernels/pd_kernels.h"

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}



/* ------------------------------------------------------------------------- */
/* Life cycle                                                                */
/* ------------------------------------------------------------------------- */

int32_t rbc_solver_init(rbc_solver *s, const rbc_allocator *a, uint32_t nthreads) {
    memset(s, 0, sizeof *s);
    s->alloc = *a;
    s->substeps = 1;
    s->nonlinear_iterations = 1;
    s->linear_iterations = 11;
    s->gravity[1] = -9.81f;
    s->settings.kind = RBC_SOLVER_RBGS;
    s->settings.chebyshev_delay = 2;
    s->settings.mode = RBC_ITERATE_FIXED;
    s->settings.tolerance = 1e-3f;
    s->settings.budget_ms = 2.0f;
    s->settings.max_linear_iterations = 1000;
    s->settings.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    s->settings.target_strain = 0.05f;
    s->settings.max_substeps = 16;
    rbc_solver_target_reset(s);
    if (rbc_pool_create(&s->pool, nthreads, a) != 0) return RBC_ERR_OUT_OF_MEMORY;
    return RBC_OK;
}

void rbc_solver_fini(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) rbc_cloth_state_destroy(s, s->cloths[k]);
    rbc_mem_free(&s->alloc, s->cloths, sizeof(*s->cloths) * s->cloth_cap);
    rbc_mem_free(&s->alloc, s->cb_list, sizeof(*s->cb_list) * s->cloth_cap);
    for (uint32_t k = 0; k < s->collider_count; ++k) rbc_trimesh_destroy(s->colliders[k].mesh, &s->alloc);
    rbc_mem_free(&s->alloc, s->colliders, sizeof(*s->colliders) * s->collider_cap);
    for (uint32_t k = 0; k < 64; ++k) rbc_contact_list_free(&s->contacts[k], &s->alloc);
    rbc_contact_list_free(&s->host_contacts, &s->alloc);
    rbc_clothcontact_destroy(s->cc);
    rbc_mem_free(&s->alloc, s->cc_bodies, sizeof(*s->cc_bodies) * s->cc_bodies_cap);
    rbc_pool_destroy(s->pool);
    memset(s, 0, sizeof *s);
}

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

static void free_pins(rbc_solver *s, rbc_cloth_state *c) {
    rbc_mem_free(&s->alloc, c->pin_idx, sizeof(uint32_t) * c->pin_cap);
    rbc_mem_free(&s->alloc, c->pin_target, sizeof(float) * 3 * c->pin_cap);
    rbc_mem_free(&s->alloc, c->pin_start, sizeof(float) * 3 * c->pin_cap);
    c->pin_idx = NULL;
    c->pin_target = c->pin_start = NULL;
    c->pin_cap = c->pin_count = 0;
}

static void free_cb_buffers(rbc_solver *s, rbc_cloth_state *c) {
    size_t bytes = rbc_mul_size((size_t)c->topo.n * 3, sizeof(float));
    rbc_mem_free(&s->alloc, c->cb_pos, bytes);
    rbc_mem_free(&s->alloc, c->cb_prev, bytes);
    c->cb_pos = c->cb_prev = NULL;
}

static int alloc_cb_buffers(rbc_solver *s, rbc_cloth_state *c) {
    size_t bytes = rbc_mul_size((size_t)c->topo.n * 3, sizeof(float));
    c->cb_pos = rbc_mem_alloc(&s->alloc, bytes);
    c->cb_prev = rbc_mem_alloc(&s->alloc, bytes);
    if (c->cb_pos && c->cb_prev) return 1;
    free_cb_buffers(s, c);
    return 0;
}

/* Which optional buffers a solver needs. */
static int needs_alt(rbc_solver_kind k) {
    return k == RBC_SOLVER_JACOBI || k == RBC_SOLVER_JACOBI_CHEBYSHEV ||
           k == RBC_SOLVER_RBGS_CHEBYSHEV;
}
static int needs_prev(rbc_solver_kind k) {
    return k == RBC_SOLVER_JACOBI_CHEBYSHEV || k == RBC_SOLVER_RBGS_CHEBYSHEV;
}

static void free_solver_buffers(rbc_solver *s, rbc_cloth_state *c, int alt, int prev) {
    size_t bytes = (size_t)c->topo.n * sizeof(float);
    for (int a = 0; a < 3; ++a) {
        if (alt) {
            rbc_mem_free(&s->alloc, c->alt[a], bytes);
            c->alt[a] = NULL;
        }
        if (prev) {
            rbc_mem_free(&s->alloc, c->prev[a], bytes);
            c->prev[a] = NULL;
        }
    }
}

/* Allocate what solver kind k needs and this cloth lacks; all or nothing. */
static int alloc_solver_buffers(rbc_solver *s, rbc_cloth_state *c, rbc_solver_kind k) {
    size_t bytes = (size_t)c->topo.n * sizeof(float);
    int want_alt = needs_alt(k) && !c->alt[0], want_prev = needs_prev(k) && !c->prev[0];
    for (int a = 0; a < 3; ++a) {
        if (want_alt && !(c->alt[a] = rbc_mem_alloc(&s->alloc, bytes))) goto fail;
        if (want_prev && !(c->prev[a] = rbc_mem_alloc(&s->alloc, bytes))) goto fail;
    }
    return 1;
fail:
    free_solver_buffers(s, c, want_alt, want_prev);
    return 0;
}

void rbc_cloth_state_destroy(rbc_solver *s, rbc_cloth_state *c) {
    if (!c) return;
    free_solver_buffers(s, c, 1, 1);
    rbc_direct_destroy(c->direct);
    size_t n = c->topo.n, ns = c->topo.ns;
    (void)n;
    (void)ns;
#define FREE_ONE(name, type, count) rbc_mem_free(&s->alloc, c->name, rbc_mul_size(count, sizeof(type)));
    STATE_ARRAYS(FREE_ONE)
#undef FREE_ONE
    free_pins(s, c);
    rbc_grid_free(c->grid, &s->alloc);
    rbc_ell_free(c->ell, &s->alloc);
    rbc_mem_free(&s->alloc, c->pin_springs, sizeof(uint32_t) * c->pin_spring_cap);
    free_cb_buffers(s, c);
    /* quad_count0: cuts and tearing shrink quad_count, not the array. */
    rbc_mem_free(&s->alloc, c->quads, sizeof(uint32_t) * 4 * (size_t)c->quad_count0);
    rbc_mem_free(&s->alloc, c->tris, sizeof(uint32_t) * 3 * (size_t)c->tri_cap);
    rbc_mem_free(&s->alloc, c->att_vertex, sizeof(uint32_t) * c->att_cap);
    rbc_mem_free(&s->alloc, c->att_collider, sizeof(uint32_t) * c->att_cap);
    rbc_mem_free(&s->alloc, c->att_local, sizeof(float) * 3 * c->att_cap);
    rbc_topology_free(&c->topo, &s->alloc);
    rbc_mem_free(&s->alloc, c, sizeof *c);
}

static int grow_pins(rbc_solver *s, rbc_cloth_state *c, uint32_t need) {
    if (need <= c->pin_cap) return 1;
    uint32_t cap = c->pin_cap ? c->pin_cap : 8;
    while (cap < need) cap *= 2;
    uint32_t *idx = rbc_mem_alloc(&s->alloc, sizeof(uint32_t) * cap);
    float *tgt = rbc_mem_alloc(&s->alloc, sizeof(float) * 3 * cap);
    float *st = rbc_mem_alloc(&s->alloc, sizeof(float) * 3 * cap);
    if (!idx || !tgt || !st) {
        rbc_mem_free(&s->alloc, idx, sizeof(uint32_t) * cap);
        rbc_mem_free(&s->alloc, tgt, sizeof(float) * 3 * cap);
        rbc_mem_free(&s->alloc, st, sizeof(float) * 3 * cap);
        return 0;
    }
    if (c->pin_count) {
        memcpy(idx, c->pin_idx, sizeof(uint32_t) * c->pin_count);
        memcpy(tgt, c->pin_target, sizeof(float) * 3 * c->pin_count);
        memcpy(st, c->pin_start, sizeof(float) * 3 * c->pin_count);
    }
    uint32_t count = c->pin_count;
    free_pins(s, c);
    c->pin_idx = idx;
    c->pin_target = tgt;
    c->pin_start = st;
    c->pin_cap = cap;
    c->pin_count = count;
    return 1;
}

int32_t rbc_cloth_state_create(rbc_solver *s, const rbc_mesh_input *in, float damping,
                               rbc_cloth_state **out, char *err, size_t errlen) {
    *out = NULL;
    rbc_cloth_state *c = rbc_mem_alloc(&s->alloc, sizeof *c);
    if (!c) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for a cloth");
    int32_t rc = rbc_topology_build(in, &s->alloc, &c->topo, err, errlen);
    if (rc != RBC_OK) {
        rbc_mem_free(&s->alloc, c, sizeof *c);
        return rc;
    }
    const size_t n = c->topo.n, ns = c->topo.ns;
    int ok = 1;
    size_t bytes = 0;
#define ALLOC_ONE(name, type, count)                                   \
    c->name = rbc_mem_alloc(&s->alloc, rbc_mul_size(count, sizeof(type))); \
    ok = ok && c->name;                                                \
    bytes += rbc_mul_size(count, sizeof(type));
    STATE_ARRAYS(ALLOC_ONE)
#undef ALLOC_ONE
    if (ok && in->pin_count) ok = grow_pins(s, c, in->pin_count);
    if (ok && (s->callback || s->contact_fn)) ok = alloc_cb_buffers(s, c);
    if (ok) ok = alloc_solver_buffers(s, c, s->settings.kind);
    if (ok && in->quad_count) {
        /* The quads in internal indices: cloth contact's triangles and what remains
         * after tearing are made from them. */
        c->quads = rbc_mem_alloc(&s->alloc, rbc_mul_size((size_t)in->quad_count * 4, sizeof(uint32_t)));
        ok = c->quads != NULL;
        if (ok) {
            c->quad_count = c->quad_count0 = in->quad_count;
            for (size_t k = 0; k < 4 * (size_t)in->quad_count; ++k)
                c->quads[k] = c->topo.to_internal[in->quads[k]];
        }
    }
    if (!ok) {
        rbc_cloth_state_destroy(s, c);
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
    if (!rbc_energy_rebuild_pin_springs(c, &s->alloc) ||
        rbc_grid_detect(&c->topo, &s->alloc, &c->grid) < 0 ||
        (!c->grid && rbc_ell_build(&c->topo, &s->alloc, &c->ell) < 0)) {
        rbc_cloth_state_destroy(s, c);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %zu particles", n);
    }
    c->h_cached = 0.0f;
    c->h_last = 0.0f;
    c->e_valid = 0;
    c->e_keep_slack = 0;
    *out = c;
    return RBC_OK;
}

int32_t rbc_cloth_state_set_contact(rbc_solver *s, rbc_cloth_state *c, float thickness,
                                    float friction, uint32_t flags) {
    if (flags && !s->cc) {
        int32_t rc = rbc_clothcontact_create(&s->alloc, &s->cc);
        if (rc != RBC_OK) return rc;
    }
    if (flags && !c->tris && c->quad_count) {
        size_t count = 2 * (size_t)c->quad_count;
        uint32_t *t = rbc_mem_alloc(&s->alloc, rbc_mul_size(count * 3, sizeof(uint32_t)));
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
        rbc_mem_free(&s->alloc, c->tris, sizeof(uint32_t) * 3 * (size_t)c->tri_cap);
        c->tris = NULL;
        c->tri_count = c->tri_cap = 0;
    }
    c->thickness = thickness;
    c->friction = friction;
    c->collision_flags = flags;
    return RBC_OK;
}

int32_t rbc_solver_add_cloth(rbc_solver *s, rbc_cloth_state *c) {
    if (s->cloth_count == s->cloth_cap) {
        uint32_t cap = s->cloth_cap ? s->cloth_cap * 2 : 4;
        rbc_cloth_state **list = rbc_mem_alloc(&s->alloc, sizeof(*list) * cap);
        rbc_collision_cloth *cbl = rbc_mem_alloc(&s->alloc, sizeof(*cbl) * cap);
        if (!list || !cbl) {
            rbc_mem_free(&s->alloc, list, sizeof(*list) * cap);
            rbc_mem_free(&s->alloc, cbl, sizeof(*cbl) * cap);
            return RBC_ERR_OUT_OF_MEMORY;
        }
        if (s->cloth_count) memcpy(list, s->cloths, sizeof(*list) * s->cloth_count);
        rbc_mem_free(&s->alloc, s->cloths, sizeof(*s->cloths) * s->cloth_cap);
        rbc_mem_free(&s->alloc, s->cb_list, sizeof(*s->cb_list) * s->cloth_cap);
        s->cloths = list;
        s->cb_list = cbl;
        s->cloth_cap = cap;
    }
    s->cloths[s->cloth_count++] = c;
    return RBC_OK;
}

void rbc_solver_remove_cloth(rbc_solver *s, rbc_cloth_state *c) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (s->cloths[k] != c) continue;
        /* Keep creation order (stable iteration order for hosts and tests). */
        memmove(&s->cloths[k], &s->cloths[k + 1], sizeof(*s->cloths) * (s->cloth_count - k - 1));
        s->cloth_count--;
        return;
    }
}

int32_t rbc_cloth_state_set_pin(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                                const float *target) {
    uint32_t i = c->topo.to_internal[host_vertex];
    uint32_t m = c->pin_count;
    for (uint32_t k = 0; k < c->pin_count; ++k)
        if (c->pin_idx[k] == i) m = k;
    if (!target) {
        if (m == c->pin_count) return RBC_OK; /* not pinned: nothing to release */
        c->pinned[i] = 0;
        if (!rbc_energy_rebuild_pin_springs(c, &s->alloc)) {
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
        if (!grow_pins(s, c, c->pin_count + 1)) return RBC_ERR_OUT_OF_MEMORY;
        c->pinned[i] = 1;
        if (!rbc_energy_rebuild_pin_springs(c, &s->alloc)) {
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

/* ------------------------------------------------------------------------- */
/* Colliders and callback                                                    */
/* ------------------------------------------------------------------------- */

void rbc_collider_update_frame(rbc_collider_state *c) {
    /* Rotate +y by the unit quaternion (x, y, z, w): the second column of R. */
    float qx = c->rotation[0], qy = c->rotation[1], qz = c->rotation[2], qw = c->rotation[3];
    c->normal[0] = 2.0f * (qx * qy - qz * qw);
    c->normal[1] = 1.0f - 2.0f * (qx * qx + qz * qz);
    c->normal[2] = 2.0f * (qy * qz + qx * qw);
    float len = sqrtf(c->normal[0] * c->normal[0] + c->normal[1] * c->normal[1] +
                      c->normal[2] * c->normal[2]);
    for (int k = 0; k < 3; ++k) c->normal[k] /= len;
}

int32_t rbc_solver_add_collider(rbc_solver *s, const rbc_collider_state *c) {
    if (s->collider_count == s->collider_cap) {
        uint32_t cap = s->collider_cap ? s->collider_cap * 2 : 4;
        rbc_collider_state *arr = rbc_mem_alloc(&s->alloc, sizeof(*arr) * cap);
        if (!arr) return RBC_ERR_OUT_OF_MEMORY;
        if (s->collider_count) memcpy(arr, s->colliders, sizeof(*arr) * s->collider_count);
        rbc_mem_free(&s->alloc, s->colliders, sizeof(*s->colliders) * s->collider_cap);
        s->colliders = arr;
        s->collider_cap = cap;
    }
    s->colliders[s->collider_count] = *c;
    rbc_collider_state *added = &s->colliders[s->collider_count];
    memcpy(added->last_position, added->position, sizeof added->position);
    memcpy(added->last_rotation, added->rotation, sizeof added->rotation);
    memset(&added->geom, 0, sizeof added->geom);
    added->geom.kind = added->shape;
    added->geom.radius = added->radius;
    memcpy(added->geom.half_extents, added->half_extents, sizeof added->half_extents);
    added->geom.mesh = added->mesh;
    rbc_shape_bounds(&added->geom, added->lo, added->hi);
    memset(added->velocity, 0, sizeof added->velocity);
    rbc_collider_update_frame(added);
    s->collider_count++;
    return RBC_OK;
}

void rbc_solver_remove_collider(rbc_solver *s, uint32_t index) {
    rbc_trimesh_destroy(s->colliders[index].mesh, &s->alloc);
    memmove(&s->colliders[index], &s->colliders[index + 1],
            sizeof(*s->colliders) * (s->collider_count - index - 1));
    s->collider_count--;
}

/* Host-order buffers exist while either host callback is installed. */
static int32_t cb_buffers_for(rbc_solver *s, int had, int want) {
    if (want && !had) {
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            if (alloc_cb_buffers(s, s->cloths[k])) continue;
            for (uint32_t j = 0; j < k; ++j) free_cb_buffers(s, s->cloths[j]);
            return RBC_ERR_OUT_OF_MEMORY;
        }
    } else if (!want && had) {
        for (uint32_t k = 0; k < s->cloth_count; ++k) free_cb_buffers(s, s->cloths[k]);
    }
    return RBC_OK;
}

int32_t rbc_solver_set_callback(rbc_solver *s, rbc_collision_fn fn, void *user) {
    int had = s->callback || s->contact_fn;
    int32_t rc = cb_buffers_for(s, had, fn || s->contact_fn);
    if (rc != RBC_OK) return rc;
    s->callback = fn;
    s->callback_user = user;
    return RBC_OK;
}

int32_t rbc_solver_set_contact_callback(rbc_solver *s, rbc_contact_fn fn, void *user) {
    int had = s->callback || s->contact_fn;
    int32_t rc = cb_buffers_for(s, had, fn || s->callback);
    if (rc != RBC_OK) return rc;
    s->contact_fn = fn;
    s->contact_user = user;
    return RBC_OK;
}

int32_t rbc_solver_set_settings(rbc_solver *s, const rbc_solver_settings *st) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (alloc_solver_buffers(s, s->cloths[k], st->kind)) continue;
        return RBC_ERR_OUT_OF_MEMORY; /* buffers kept so far are harmless extras */
    }
    /* Release what the new solver does not use (a scene pays only for its solver). */
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        free_solver_buffers(s, s->cloths[k], !needs_alt(st->kind), !needs_prev(st->kind));
    if (s->settings.energy_guard == RBC_ENERGY_GUARD_OFF && st->energy_guard != RBC_ENERGY_GUARD_OFF)
        for (uint32_t k = 0; k < s->cloth_count; ++k) /* unguarded steps: start afresh */
            rbc_cloth_state_energy_invalidate(s->cloths[k], 0);
    s->settings = *st;
    rbc_solver_target_reset(s); /* the controller starts again from the world's counts */
    return RBC_OK;
}

void rbc_solver_target_reset(rbc_solver *s) {
    s->tgt_substeps = 0;
    s->tgt_iters = 0;
    s->tgt_calm = 0;
    s->tgt_hold = RBC_TARGET_HOLD;
    s->tgt_lowered_at = 0;
    s->tgt_probe = 0;
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
    if (c->grid) b += c->grid->bytes;
    if (c->ell) b += c->ell->bytes;
    b += (size_t)c->quad_count0 * 4 * sizeof(uint32_t) + (size_t)c->tri_cap * 3 * sizeof(uint32_t);
    b += (size_t)c->att_cap * 5 * sizeof(uint32_t);
    return b;
}

void rbc_cloth_state_energy(const rbc_cloth_state *c, const float g[3], int measure,
                            double *kinetic, double *potential, double *budget) {
    *budget = c->e_valid ? c->e_budget : 0.0;
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
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t a = t->sa[k], b = t->sb[k];
        double ex = (double)c->x[0][a] - c->x[0][b], ey = (double)c->x[1][a] - c->x[1][b],
               ez = (double)c->x[2][a] - c->x[2][b];
        double v = sqrt(ex * ex + ey * ey + ez * ez) - t->rest_len[k];
        us += 0.5 * t->stiff[k] * v * v;
    }
    *kinetic = ke;
    *potential = us + ug;
}

void rbc_cloth_state_energy_invalidate(rbc_cloth_state *c, int keep_slack) {
    /* Keep the slack only if there was a budget to keep it from. */
    c->e_keep_slack = keep_slack && (c->e_valid || c->e_keep_slack);
    c->e_valid = 0;
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
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t a = t->sa[k], b = t->sb[k];
        double ex = (double)c->x[0][a] - c->x[0][b], ey = (double)c->x[1][a] - c->x[1][b],
               ez = (double)c->x[2][a] - c->x[2][b];
        double v = sqrt(ex * ex + ey * ey + ez * ez) - t->rest_len[k];
        obj += 0.5 * t->stiff[k] * v * v;
    }
    *objective = obj;
}

float rbc_solver_sor_omega(const rbc_solver *s, rbc_cloth_state *c, float h) {
    if (s->settings.omega > 0.0f) return s->settings.omega;
    /* Optimal SOR for a consistently ordered matrix (red-black): Young's formula. */
    float rho = rbc_cloth_state_spectral_radius(c, h);
    return 2.0f / (1.0f + sqrtf(1.0f - rho * rho));
}

/* ------------------------------------------------------------------------- */
/* The step                                                                  */
/* ------------------------------------------------------------------------- */

typedef struct step_ctx {
    rbc_solver *s;
    float h;
    uint32_t substeps;
    uint32_t ncolors; /* most colors of any cloth */
    double start_ms;  /* for the budget */
    /* Set by thread 0 between barriers; read by all after the barrier. */
    volatile int32_t result;
    volatile int stop;
    uint32_t linear_done; /* linear iterations of the step (thread 0 counts) */
    char *err;
    size_t errlen;
    /* Per-thread first failure found: (cloth index, internal particle or spring
     * index, kind: 1 non-finite particle, 2 spring past the blow-up guard). */
    int64_t bad[64][3];
    /* Per-thread partial residual sums, padded to their own cache lines. */
    struct {
        double r2, b2;
        char pad[48];
    } part[64];
    int clamp;            /* the energy guard scales velocities at this commit */
    int any_contacts;     /* some collider contact exists in this substep */
    int color_pass;       /* collider and host contacts are projected after each color's
                             sweep, with their friction (rbc_collide_project_color) */
    int host_contacts;    /* the host reported contacts for this substep */
    int cc_active;        /* some cloth takes part in cloth contact */
    int grow;             /* a contact list must grow: detect again */
    /* Steps each thread finished in the lattice wavefront (grid.h), a cache line
     * apart. */
    volatile uint32_t progress[64 * 16];
    /* RBC_ITERATE_TARGET: the linear iterations of the global steps before the
     * step's last (the count the last one of the previous step needed), what the
     * last one needed (thread 0 writes it), and whether it stopped at
     * max_linear_iterations above the target. */
    uint32_t tgt_iters, tgt_iters_next;
    int hit_cap;
    float cheb_rho[64];   /* per cloth (first 64): the Chebyshev rho in use */
    float sor_omega[64];  /* per cloth: the SOR omega in use */
    rbc_step_times t;
} step_ctx;

/* m_i/h^2 and 1/(m_i/h^2 + sum s_ij), recomputed only when h changes. */
static void prepare_weights(rbc_cloth_state *c, float h) {
    if (c->h_cached == h) return;
    float inv_h2 = 1.0f / (h * h);
    for (uint32_t i = 0; i < c->topo.n; ++i) {
        float wi = c->topo.mass[i] * inv_h2;
        c->w[i] = wi;
        c->inv_denom[i] = 1.0f / (wi + c->topo.ksum[i]);
    }
    c->h_cached = h;
}
RBC_VECTOR_CLONES
static void predict_axis(uint32_t count, const float *restrict x, const float *restrict q,
                         float *restrict y, float *restrict p, float keep, float g_h2) {
    for (uint32_t i = 0; i < count; ++i) {
        float v = x[i] + keep * (x[i] - q[i]) + g_h2;
        y[i] = v;
        p[i] = v;
    }
}

static void phase_integrate(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    float h = ctx->h, h2 = h * h;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        float keep = 1.0f - c->damping * h;
        if (keep < 0.0f) keep = 0.0f; /* damping * h > 1 would reverse velocities */
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        /* rbc_k_predict one coordinate at a time, through restrict pointers: the
         * same arithmetic, vectorized (the buffers never alias). */
        for (int a = 0; a < 3; ++a)
            predict_axis(e - b, c->x[a] + b, c->q[a] + b, c->y[a] + b, c->p[a] + b, keep,
                         s->gravity[a] * h2);
    }
}

/* Pinned particles follow their pins: linearly from where they were at the start of
 * the step to the target, reached at the last substep. Each thread places the pins
 * inside its own integrate range, so no extra barrier is needed. */
static void place_pins(step_ctx *ctx, uint32_t sub, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    float f = (float)(sub + 1) / (float)ctx->substeps;
    int last = sub + 1 == ctx->substeps;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        for (uint32_t m = 0; m < c->pin_count; ++m) {
            uint32_t i = c->pin_idx[m];
            if (i < b || i >= e) continue;
            for (int a = 0; a < 3; ++a) {
                float st = c->pin_start[3 * m + a], tg = c->pin_target[3 * m + a];
                c->p[a][i] = last ? tg : st + (tg - st) * f;
            }
        }
    }
}

/* Whether a cloth's local step runs fused with the right-hand side on the lattice
 * (grid.h): not for the direct solver, which reads the per-spring d arrays. */
static int grid_local(const rbc_solver *s, const rbc_cloth_state *c) {
    return c->grid && s->settings.kind != RBC_SOLVER_DIRECT;
}

static void phase_local(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (grid_local(s, c)) continue;
        const rbc_topology *t = &c->topo;
        uint32_t b, e;
        rbc_split(t->ns, tid, nt, &b, &e);
        for (uint32_t sp = b; sp < e; ++sp)
            rbc_k_local(sp, t->sa, t->sb, t->rest_len, t->ux, t->uy, t->uz, t->he_a, t->he_b,
                        c->p[0], c->p[1], c->p[2], c->dx, c->dy, c->dz);
    }
}

/* The host callbacks' view: p (positions) and x (previous) of every cloth in host
 * order, in the host-order buffers, listed in s->cb_list. */
static void fill_host_buffers(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const uint32_t *to_int = c->topo.to_internal;
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            uint32_t i = to_int[v];
            for (int a = 0; a < 3; ++a) {
                c->cb_pos[3 * (size_t)v + a] = c->p[a][i];
                c->cb_prev[3 * (size_t)v + a] = c->x[a][i];
            }
        }
        s->cb_list[k].cloth = c->public_id;
        s->cb_list[k].vertex_count = c->topo.n;
        s->cb_list[k].positions = c->cb_pos;
        s->cb_list[k].previous_positions = c->cb_prev;
    }
}

/* Thread 0, all others waiting at a barrier: hand host-order positions to the host's
 * collision code and take its corrections back (pins win). */
static void run_callback(step_ctx *ctx, uint32_t sub) {
    rbc_solver *s = ctx->s;
    fill_host_buffers(s);
    int32_t r = s->callback(s->callback_user, s->public_world_id, ctx->h, s->cb_list,
                            s->cloth_count);
    if (r != 0) {
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                           "the collision callback returned %d at substep %u", (int)r, sub);
        return;
    }
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const uint32_t *to_int = c->topo.to_internal;
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            const float *hp = &c->cb_pos[3 * (size_t)v];
            if (!(isfinite(hp[0]) && isfinite(hp[1]) && isfinite(hp[2]))) {
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                                   "the collision callback wrote a non-finite position for "
                                   "cloth 0x%08x vertex %u at substep %u",
                                   c->public_id, v, sub);
                return;
            }
            uint32_t i = to_int[v];
            if (c->pinned[i]) continue;
            c->p[0][i] = hp[0];
            c->p[1][i] = hp[1];
            c->p[2][i] = hp[2];
        }
    }
}

/* The blow-up guard: an iterative solver that does not converge (Jacobi, SOR or
 * Chebyshev with too few iterations on stiff cloth) can inject energy until the
 * positions are huge but still finite. No cloth is stretched to RBC_BLOWUP_STRETCH
 * times its rest length (the mean rest length for shorter springs) by physics that
 * the solver resolved, so a spring past that counts as divergence, like a NaN. */
#define RBC_BLOWUP_STRETCH 1000.0f

/* Record the first non-finite particle, or over-stretched spring, this thread sees. */
static void phase_check(step_ctx *ctx, int energy, int springs, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    ctx->bad[tid][0] = -1;
    if (energy)
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            rbc_energy_blocks(s->cloths[k], s->cloths[k]->p, s->cloths[k]->x, s->gravity, 0, tid,
                              nt);
    /* Gauss-Seidel sweeps (red-black, multicolor, serial) and the exact solve only
     * lower the PD objective, so they cannot run away; the guard (one pass over the
     * springs, ~4% of a 10K-particle RBGS frame) is paid by the solvers that can, once
     * per step (springs: the last substep): a step that fails is undone whole, and a
     * run-away in an earlier substep is still there, larger, at the last one (or has
     * become non-finite, which the particle check below finds every substep). At 3
     * substeps it was a fifth of an SOR frame on the paper's cloth. */
    rbc_solver_kind kind = s->settings.kind;
    int guard = springs && (kind == RBC_SOLVER_JACOBI || kind == RBC_SOLVER_JACOBI_CHEBYSHEV ||
                            kind == RBC_SOLVER_RBGS_SOR || kind == RBC_SOLVER_RBGS_CHEBYSHEV);
    for (uint32_t k = 0; guard && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const rbc_topology *t = &c->topo;
        uint32_t b, e;
        rbc_split(t->ns, tid, nt, &b, &e);
        const float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
        const float floor_len = RBC_BLOWUP_STRETCH * c->mean_rest;
        for (uint32_t sp = b; sp < e; ++sp) {
            uint32_t i = t->sa[sp], j = t->sb[sp];
            float ex = px[i] - px[j], ey = py[i] - py[j], ez = pz[i] - pz[j];
            float lim = RBC_BLOWUP_STRETCH * t->rest_len[sp];
            if (lim < floor_len) lim = floor_len;
            if (c->torn && t->stiff[sp] == 0.0f) continue; /* broken: no bound */
            /* NaN compares false here; the particle check below names it. */
            if (ex * ex + ey * ey + ez * ez > lim * lim) {
                ctx->bad[tid][0] = k;
                ctx->bad[tid][1] = sp;
                ctx->bad[tid][2] = 2;
                return;
            }
        }
    }
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        const float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
        /* Branch-free accumulation: x - x is 0 for finite x and NaN otherwise. */
        float acc = 0.0f;
        for (uint32_t i = b; i < e; ++i) acc += (px[i] - px[i]) + (py[i] - py[i]) + (pz[i] - pz[i]);
        if (acc == 0.0f) continue;
        for (uint32_t i = b; i < e; ++i) {
            if (!(isfinite(px[i]) && isfinite(py[i]) && isfinite(pz[i]))) {
                ctx->bad[tid][0] = k;
                ctx->bad[tid][1] = i;
                ctx->bad[tid][2] = 1;
                return;
            }
        }
    }
}

static void commit(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (int a = 0; a < 3; ++a) {
            float *old_q = c->q[a];
            c->q[a] = c->x[a];
            c->x[a] = c->p[a];
            c->p[a] = old_q;
        }
    }
}

static void snapshot(rbc_solver *s, int restore) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        size_t bytes = (size_t)c->topo.n * sizeof(float);
        for (int a = 0; a < 3; ++a) {
            if (restore) {
                memcpy(c->x[a], c->snap_x[a], bytes);
                memcpy(c->q[a], c->snap_q[a], bytes);
            } else {
                memcpy(c->snap_x[a], c->x[a], bytes);
                memcpy(c->snap_q[a], c->q[a], bytes);
            }
        }
    }
}

/* One linear iteration of the selected iterative solver over every cloth, with the
 * barriers it needs; k is the iteration's index in this non-linear iteration. */
static void linear_iteration(step_ctx *ctx, uint32_t k, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    rbc_pool *pool = s->pool;
    const rbc_solver_settings *st = &s->settings;
    switch (st->kind) {
    case RBC_SOLVER_JACOBI:
    case RBC_SOLVER_JACOBI_CHEBYSHEV: {
        int cheb = st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV;
        for (uint32_t q = 0; q < s->cloth_count; ++q) {
            rbc_cloth_state *c = s->cloths[q];
            /* Even k reads p and writes alt, odd k the reverse; the step swaps the
             * buffers afterwards when the count is odd. */
            float *const *src = (k & 1) ? c->alt : c->p;
            float *const *dst = (k & 1) ? c->p : c->alt;
            float omega = cheb ? rbc_chebyshev_omega(k, st->chebyshev_delay,
                                                     ctx->cheb_rho[q < 64 ? q : 63])
                               : 1.0f;
            rbc_global_jacobi(c, src, dst, cheb, omega, tid, nt);
        }
        rbc_pool_barrier(pool);
        break;
    }
    case RBC_SOLVER_GAUSS_SEIDEL:
        if (tid == 0)
            for (uint32_t q = 0; q < s->cloth_count; ++q) rbc_global_gs_serial(s->cloths[q]);
        rbc_pool_barrier(pool);
        break;
    default: { /* RBGS, MULTICOLOR_GS, RBGS_SOR, RBGS_CHEBYSHEV */
        rbc_gs_variant v = st->kind == RBC_SOLVER_RBGS_SOR         ? RBC_GS_SOR
                           : st->kind == RBC_SOLVER_RBGS_CHEBYSHEV ? RBC_GS_STASH
                                                                   : RBC_GS_PLAIN;
        for (uint32_t color = 0; color < ctx->ncolors; ++color) {
            for (uint32_t q = 0; q < s->cloth_count; ++q)
                rbc_global_gs_color(s->cloths[q], color, v, ctx->sor_omega[q < 64 ? q : 63], tid,
                                    nt);
            rbc_pool_barrier(pool);
            /* Collider contacts join particles of one color (each touches only its own
             * particle), so they are solved right after that color's sweep, before the
             * next color reads it: a particle's push and its friction then come from
             * the one Gauss-Seidel value it was just given (collide.h). */
            if (ctx->color_pass && (ctx->any_contacts || ctx->host_contacts)) {
                if (ctx->any_contacts)
                    rbc_collide_project_color(s, &s->contacts[tid], color, ctx->h);
                if (tid == 0 && ctx->host_contacts)
                    rbc_collide_project_color(s, &s->host_contacts, color, ctx->h);
                rbc_pool_barrier(pool);
            }
        }
        if (v == RBC_GS_STASH) {
            for (uint32_t q = 0; q < s->cloth_count; ++q)
                rbc_global_chebyshev_blend(
                    s->cloths[q],
                    rbc_chebyshev_omega(k, st->chebyshev_delay, ctx->cheb_rho[q < 64 ? q : 63]),
                    tid, nt);
            rbc_pool_barrier(pool);
        }
        break;
    }
    }
}

/* Contacts join the solve: after a whole linear iteration (its barrier passed), each
 * thread projects the collider contacts of its own particles (unary constraints: no
 * race), then thread 0 runs one pass of cloth contact (constraints between particles
 * that may share a color, so not inside the parallel color sweeps: docs/facts.md), and
 * the next iteration relaxes the springs around them. alt: the latest iterate is the
 * Jacobi destination buffer. cloth: run the cloth contact pass (every
 * RBC_CC_EVERY-th iteration and the last; it reads four particles per contact at
 * random, so a pass costs several sweeps, but every third iteration left four
 * stacked layers 2-3 mm deeper than their 2 mm thickness and let them pass through
 * each other sooner). */
#define RBC_CC_EVERY 1u
/* colliders: 0 skips the collider and host contacts (after an iteration whose color
 * passes projected them, ctx->color_pass); 2 projects them with friction (the first
 * pass of a substep, onto the prediction, under ctx->color_pass); 1 without. */
static void contact_pass(step_ctx *ctx, int alt, uint32_t tid, int cloth, int colliders) {
    rbc_solver *s = ctx->s;
    const int any = colliders && ctx->any_contacts, host = colliders && ctx->host_contacts;
    const float fh = colliders == 2 && ctx->color_pass ? ctx->h : 0.0f;
    if (!any && !host && !(ctx->cc_active && cloth)) return;
    if (any) rbc_collide_project(s, &s->contacts[tid], alt, fh);
    if (host || (ctx->cc_active && cloth)) {
        rbc_pool_barrier(s->pool);
        if (tid == 0 && host) rbc_collide_project(s, &s->host_contacts, alt, fh);
    }
    if (ctx->cc_active && cloth) {
        if (tid == 0) {
            for (uint32_t k = 0; k < s->cloth_count; ++k)
                for (int a = 0; a < 3; ++a)
                    s->cc_bodies[k].p[a] = alt ? s->cloths[k]->alt[a] : s->cloths[k]->p[a];
            rbc_clothcontact_project(s->cc, s->cc_bodies, s->cloth_count);
        }
    }
    rbc_pool_barrier(s->pool);
}

/* The global step of one non-linear iteration: iterate until the mode says stop. */
static void global_step(step_ctx *ctx, uint32_t segment, uint32_t nsegments, uint32_t tid,
                        uint32_t nt) {
    rbc_solver *s = ctx->s;
    rbc_pool *pool = s->pool;
    const rbc_solver_settings *st = &s->settings;
    int chebyshev = st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV || st->kind == RBC_SOLVER_RBGS_CHEBYSHEV;
    if (chebyshev) {
        /* p^(k-1) starts as the initial guess: the first (unaccelerated) iteration
         * does not read it. */
        for (uint32_t q = 0; q < s->cloth_count; ++q) {
            rbc_cloth_state *c = s->cloths[q];
            uint32_t b = (uint32_t)((uint64_t)c->topo.n * tid / nt),
                     e = (uint32_t)((uint64_t)c->topo.n * (tid + 1) / nt);
            for (int a = 0; a < 3; ++a)
                memcpy(c->prev[a] + b, c->p[a] + b, (size_t)(e - b) * sizeof(float));
        }
        rbc_pool_barrier(pool);
    }
    /* Residual check over all colors but the last one a Gauss-Seidel sweep just
     * solved exactly (its rows have zero residual up to rounding). */
    int gs_family = st->kind != RBC_SOLVER_JACOBI && st->kind != RBC_SOLVER_JACOBI_CHEBYSHEV;
    /* RBC_ITERATE_TARGET: every global step of a step but its last runs the count
     * the last one of the previous step needed (a fixed count, so the wavefront
     * below serves it); the last one checks the strain from a quarter below that count on,
     * every iteration, up to max_linear_iterations. Checking where the step ends is
     * what decides; a check costs several lattice sweeps, so only ~2 per step. */
    const int tgt = st->mode == RBC_ITERATE_TARGET;
    const int tgt_check = tgt && segment + 1 == nsegments;
    const int fixed = st->mode == RBC_ITERATE_FIXED || (tgt && !tgt_check);
    uint32_t limit = st->mode == RBC_ITERATE_FIXED ? s->linear_iterations
                     : fixed                      ? ctx->tgt_iters
                                                  : st->max_linear_iterations;
    /* The first check a quarter (at least one) below last step's count: the count
     * comes down quickly when the cloth settles, and a step that needs the full
     * count pays a check or two more. */
    uint32_t first = 0;
    if (tgt_check) {
        uint32_t n = ctx->tgt_iters, less = n / 4 > 1 ? n / 4 : 1;
        first = n > less ? n - less : 1;
    }
    /* Fixed counts of plain or over-relaxed red-black sweeps on lattices: the
     * temporally blocked wavefront does the same updates with the same inputs (the
     * result is bitwise that of the loop below) but streams the mesh once instead of
     * once per iteration, in a pipeline of the threads. */
    int wave_ok = !ctx->any_contacts && !ctx->host_contacts && !ctx->cc_active &&
                  (st->kind == RBC_SOLVER_RBGS || st->kind == RBC_SOLVER_RBGS_SOR ||
                   st->kind == RBC_SOLVER_MULTICOLOR_GS);
    for (uint32_t q = 0; wave_ok && q < s->cloth_count; ++q) wave_ok = s->cloths[q]->grid != NULL;
    const int wave = wave_ok && fixed;
    /* The target's checked global step: the iterations before its first check too. */
    const uint32_t pre = tgt_check && wave_ok ? first - 1 : 0;
    if (wave || pre) {
        const uint32_t count = wave ? limit : pre;
        for (uint32_t q = 0; q < s->cloth_count; ++q) {
            rbc_cloth_state *c = s->cloths[q];
            float omega = st->kind == RBC_SOLVER_RBGS_SOR ? ctx->sor_omega[q < 64 ? q : 63] : 0.0f;
            ctx->progress[16 * tid] = 0;
            rbc_pool_barrier(pool);
            rbc_grid_wavefront(c->grid, c, count, omega, ctx->progress, 16, tid, nt);
            rbc_pool_barrier(pool);
        }
        if (wave) {
            if (tid == 0) ctx->linear_done += limit;
            return;
        }
    }
    double deadline = ctx->start_ms + (double)st->budget_ms * (segment + 1) / nsegments;
    uint32_t k = pre;
    int cloth_done = 1;
    double t_iter = 0.0;
    for (;;) {
        double t0 = tid == 0 ? now_ms() : 0.0;
        linear_iteration(ctx, k, tid, nt);
        const int jac = st->kind == RBC_SOLVER_JACOBI || st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV;
        cloth_done = (k + 1) % RBC_CC_EVERY == 0 || (fixed && k + 1 >= limit);
        contact_pass(ctx, jac ? !(k & 1) : 0, tid, cloth_done, !ctx->color_pass);
        k++;
        if (fixed) {
            if (k >= limit) break;
            continue;
        }
        if (st->mode == RBC_ITERATE_TARGET) {
            /* Check the strain of the latest iterate (in float: strain.h) and stop
             * at RBC_TARGET_AIM of the target (room for the substeps before this
             * one, which ran last step's count unchecked, and for what friction and
             * the safety pass change after the solve), or at the cap; the cap with
             * the strain above RBC_TARGET_INNER of the target asks for substeps. */
            if (k < first && k < limit) continue;
            for (uint32_t q = 0; q < s->cloth_count; ++q) {
                rbc_cloth_state *c = s->cloths[q];
                rbc_strain_blocks_fast(c, jac && (k & 1) ? c->alt : c->p, tid, nt);
            }
            rbc_pool_barrier(pool);
            if (tid == 0) {
                double worst = 0.0;
                for (uint32_t q = 0; q < s->cloth_count; ++q) {
                    double r = rbc_strain_sum(s->cloths[q]);
                    if (r > worst) worst = r;
                }
                const double target = (double)st->target_strain;
                int met = worst <= RBC_TARGET_AIM * target;
                ctx->stop = met || k >= limit;
                if (ctx->stop) {
                    if (worst > RBC_TARGET_INNER * target) ctx->hit_cap = 1;
                    ctx->tgt_iters_next = k;
                }
            }
        } else if (st->mode == RBC_ITERATE_TOLERANCE) {
            double r2 = 0.0, b2 = 0.0;
            for (uint32_t q = 0; q < s->cloth_count; ++q) {
                const rbc_cloth_state *c = s->cloths[q];
                uint32_t end = gs_family && c->topo.ncolors > 1 && st->kind != RBC_SOLVER_GAUSS_SEIDEL
                                   ? c->topo.ncolors - 1
                                   : c->topo.ncolors;
                rbc_global_residual(c, end, tid, nt, &r2, &b2);
            }
            ctx->part[tid].r2 = r2;
            ctx->part[tid].b2 = b2;
            rbc_pool_barrier(pool);
            if (tid == 0) {
                double R = 0.0, B = 0.0;
                for (uint32_t th = 0; th < nt; ++th) {
                    R += ctx->part[th].r2;
                    B += ctx->part[th].b2;
                }
                double tol = st->tolerance;
                ctx->stop = k >= limit || R <= tol * tol * B;
            }
        } else { /* budget: stop when another iteration would pass the deadline */
            if (tid == 0) {
                double t1 = now_ms();
                t_iter = t1 - t0;
                ctx->stop = k >= limit || t1 + t_iter > deadline;
            }
        }
        rbc_pool_barrier(pool);
        if (ctx->stop) break;
    }
    if (ctx->cc_active && !cloth_done) /* the last iteration gets its cloth pass */
        contact_pass(ctx,
                     (st->kind == RBC_SOLVER_JACOBI || st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV) &&
                         !((k - 1) & 1),
                     tid, 1, !ctx->color_pass);
    if (tid == 0) ctx->linear_done += k;
    if ((st->kind == RBC_SOLVER_JACOBI || st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV) && (k & 1)) {
        /* The last iteration wrote alt: make it p. */
        if (tid == 0)
            for (uint32_t q = 0; q < s->cloth_count; ++q)
                for (int a = 0; a < 3; ++a) {
                    rbc_cloth_state *c = s->cloths[q];
                    float *tmp = c->p[a];
                    c->p[a] = c->alt[a];
                    c->alt[a] = tmp;
                }
        rbc_pool_barrier(pool);
    }
}

/* ------------------------------------------------------------------------- */
/* Energy guard (rbc_energy_guard; energy.h)                                  */
/* ------------------------------------------------------------------------- */

static int guard_on(const rbc_solver *s) {
    return s->settings.energy_guard != RBC_ENERGY_GUARD_OFF;
}

/* The energy and budget at the step's start: cached from the last step, or
 * recomputed (all threads) for cloths whose state, pins, gravity or h changed. */
static void energy_start(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    int any = 0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->e_valid && c->e_h == ctx->h) continue;
        rbc_energy_blocks(c, c->x, c->q, s->gravity, 1, tid, nt);
        any = 1;
    }
    if (any) rbc_pool_barrier(s->pool);
    if (tid != 0) return;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->e_valid && c->e_h == ctx->h) {
            c->e_step_budget = c->e_budget;
        } else {
            rbc_energy e = rbc_energy_sum(c, ctx->h, s->gravity, 1);
            /* A new state: everything it holds may become motion, spring energy
             * included. Otherwise keep what the cloth had not yet spent (the springs'
             * energy among it). */
            double slack = e.spring;
            if (c->e_valid || c->e_keep_slack) {
                slack = c->e_budget - c->e_last;
                if (slack < 0.0) slack = 0.0;
            }
            c->e_step_budget = e.guarded + slack;
        }
        c->e_removed = c->e_kept = 0.0;
        c->e_scale = 1.0f;
    }
}

/* All threads: add sign * (kinetic + gravitational energy of p against x) to every
 * cloth's budget of this step (around the host callback: the change it makes is
 * work it does). */
static void budget_add_guarded(step_ctx *ctx, double sign, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        rbc_energy_blocks(s->cloths[k], s->cloths[k]->p, s->cloths[k]->x, s->gravity, 0, tid, nt);
    rbc_pool_barrier(s->pool);
    if (tid == 0)
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            s->cloths[k]->e_step_budget +=
                sign * rbc_energy_sum(s->cloths[k], ctx->h, s->gravity, 0).guarded;
    /* Thread 0 reads every thread's energy blocks above; the next pass that writes
     * them (phase_check, or the callback's budget pass) must wait for it. */
    rbc_pool_barrier(s->pool);
}

/* Thread 0, after the last substep's check: compare each cloth's energy with its
 * budget and decide the clamp (or the failure). */
static void energy_decide(step_ctx *ctx) {
    rbc_solver *s = ctx->s;
    int fail_mode = s->settings.energy_guard == RBC_ENERGY_GUARD_FAIL;
    ctx->clamp = 0;
    s->energy_note[0] = '\0';
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        rbc_energy e = rbc_energy_sum(c, ctx->h, s->gravity, 0);
        double excess = e.guarded - c->e_step_budget;
        c->e_end = e.guarded;
        c->e_scale = 1.0f;
        if (!(excess > e.tolerance)) continue;
        if (fail_mode) {
            ctx->result = rbc_fail(
                ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                "cloth 0x%08x: the step ended with %.6g J of kinetic + gravitational energy, "
                "%.3g J more than the %.6g J the cloth was given (start, pins, colliders, "
                "callback): the global solver added energy (more iterations, rbgs or direct, "
                "or smaller steps keep it out); the energy guard (RBC_ENERGY_GUARD_FAIL) "
                "restored the world to its state before the step",
                c->public_id, e.guarded, excess, c->e_step_budget);
            return;
        }
        if (excess < e.kinetic) {
            /* Scale the velocities: kinetic energy s^2 KE = KE - excess. */
            c->e_scale = (float)sqrt(1.0 - excess / e.kinetic);
            c->e_removed = excess;
            c->e_end = c->e_step_budget;
        } else {
            /* The positions alone hold more than the budget: stop every free particle
             * and keep the rest (reported; the budget grows by it). */
            c->e_scale = 0.0f;
            c->e_removed = e.kinetic;
            c->e_kept = excess - e.kinetic;
            c->e_end = e.guarded - e.kinetic;
            c->e_step_budget += c->e_kept;
        }
        ctx->clamp = 1;
        if (!s->energy_note[0])
            snprintf(s->energy_note, sizeof s->energy_note,
                     "cloth 0x%08x: the step added %.3g J of kinetic + gravitational energy "
                     "beyond the %.6g J the cloth was given; the energy guard removed %.3g J "
                     "of kinetic energy (velocities scaled by %.6g)%s",
                     c->public_id, excess, c->e_step_budget - c->e_kept, c->e_removed,
                     (double)c->e_scale,
                     c->e_kept > 0.0 ? " and kept the rest, held in the positions" : "");
    }
}

/* All threads: the clamp's new previous positions x = p - scale (p - x), so that
 * after the commit (q <- x, x <- p) the velocities are scaled and positions kept. */
static void energy_apply(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->e_scale == 1.0f) continue;
        const float f = c->e_scale;
        uint32_t b, e;
        rbc_split(c->topo.n, tid, nt, &b, &e);
        for (int a = 0; a < 3; ++a) {
            float *x = c->x[a];
            const float *p = c->p[a];
            for (uint32_t i = b; i < e; ++i)
                if (!c->pinned[i]) x[i] = p[i] - f * (p[i] - x[i]);
        }
    }
}

/* The host's contact sink (rbc_contact_sink.add): check each contact, append it to
 * the host list with its particle's internal index and cloth position. */
typedef struct sink_impl {
    step_ctx *ctx;
    uint32_t sub;
} sink_impl;

static rbc_result RBC_CALL sink_add(rbc_contact_sink *sink, const rbc_host_contact *hc,
                                    uint32_t count) {
    sink_impl *im = sink->impl;
    step_ctx *ctx = im->ctx;
    rbc_solver *s = ctx->s;
    rbc_contact_list *l = &s->host_contacts;
    if (count && !hc) return RBC_ERR_INVALID_ARGUMENT;
    for (uint32_t m = 0; m < count; ++m) {
        const rbc_host_contact *h = &hc[m];
        uint32_t k = 0;
        while (k < s->cloth_count && s->cloths[k]->public_id != h->cloth) ++k;
        float nn = h->normal[0] * h->normal[0] + h->normal[1] * h->normal[1] +
                   h->normal[2] * h->normal[2];
        const char *what = k == s->cloth_count                    ? "names no cloth of the world"
                           : h->vertex >= s->cloths[k]->topo.n    ? "has a vertex out of range"
                           : !(fabsf(nn - 1.0f) <= 1e-3f)         ? "has a normal that is not unit"
                           : !(isfinite(h->offset) && isfinite(h->velocity[0]) &&
                               isfinite(h->velocity[1]) && isfinite(h->velocity[2]))
                               ? "has a non-finite offset or velocity"
                           : !(isfinite(h->friction) && h->friction >= 0.0f)
                               ? "has a friction that is not finite and >= 0"
                               : NULL;
        if (what) {
            if (ctx->result == RBC_OK)
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                                       "the contact callback's contact %u (cloth 0x%08x, vertex "
                                       "%u) %s, at substep %u",
                                       m, h->cloth, h->vertex, what, im->sub);
            return RBC_ERR_INVALID_ARGUMENT;
        }
        rbc_cloth_state *c = s->cloths[k];
        uint32_t i = c->topo.to_internal[h->vertex];
        if (c->pinned[i]) continue; /* pins win */
        if (l->count == l->cap) {
            l->need = l->cap + 1;
            if (rbc_contact_list_reserve(l, &s->alloc) != 0) {
                if (ctx->result == RBC_OK)
                    ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                           "out of memory for %u host contacts", l->cap + 1);
                return RBC_ERR_OUT_OF_MEMORY;
            }
        }
        rbc_col_contact *ct = &l->c[l->count++];
        memset(ct, 0, sizeof *ct);
        ct->cloth = k;
        ct->idx = i;
        float inv = 1.0f / sqrtf(nn);
        for (int a = 0; a < 3; ++a) {
            ct->n[a] = h->normal[a] * inv;
            ct->u[a] = h->velocity[a];
        }
        ct->d = h->offset;
        float pen = ct->d - (ct->n[0] * c->p[0][i] + ct->n[1] * c->p[1][i] + ct->n[2] * c->p[2][i]);
        ct->depth = pen > 0.0f ? pen : 0.0f;
        ct->mu = h->friction;
        ct->collider = UINT32_MAX;
        ct->color = rbc_collide_color_of(&c->topo, i);
    }
    return RBC_OK;
}

/* Thread 0: hand the prediction to the host's contact code (host order) and collect
 * its contacts. */
static void run_contact_callback(step_ctx *ctx, uint32_t sub) {
    rbc_solver *s = ctx->s;
    fill_host_buffers(s);
    s->host_contacts.count = 0;
    sink_impl im = {ctx, sub};
    rbc_contact_sink sink = {&im, sink_add};
    int32_t r = s->contact_fn(s->contact_user, s->public_world_id, ctx->h, s->cb_list,
                              s->cloth_count, &sink);
    if (r != 0 && ctx->result == RBC_OK)
        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                               "the contact callback returned %d at substep %u", (int)r, sub);
    ctx->host_contacts = s->host_contacts.count > 0;
    s->last_host_contacts = s->host_contacts.count;
}

/* Find this substep's contacts from x and the prediction p (collide.h,
 * clothcontact.h). Lists that overflow grow (thread 0, between barriers; a steady
 * scene stops allocating) and detection runs again. */
static void pool_sync(void *pool) { rbc_pool_barrier(pool); }

static void detect_contacts(step_ctx *ctx, uint32_t sub, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    rbc_pool *pool = s->pool;
    float f0 = (float)sub / (float)ctx->substeps, f1 = (float)(sub + 1) / (float)ctx->substeps;
    if (s->collider_count) {
        for (;;) {
            rbc_collide_detect(s, &s->contacts[tid], f0, f1, ctx->h, tid, nt);
            rbc_pool_barrier(pool);
            if (tid == 0) {
                ctx->grow = 0;
                ctx->any_contacts = 0;
                uint32_t total = 0;
                for (uint32_t th = 0; th < nt; ++th) {
                    rbc_contact_list *l = &s->contacts[th];
                    total += l->need;
                    if (l->need <= l->cap) continue;
                    ctx->grow = 1;
                    if (rbc_contact_list_reserve(l, &s->alloc) != 0) {
                        ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                               "out of memory for %u collider contacts at "
                                               "substep %u", l->need, sub);
                        break;
                    }
                }
                ctx->any_contacts = total > 0;
                s->last_contacts = total;
            }
            rbc_pool_barrier(pool);
            if (ctx->result != RBC_OK || !ctx->grow) break;
        }
    }
    if (s->contact_fn && ctx->result == RBC_OK) {
        if (tid == 0) run_contact_callback(ctx, sub);
        rbc_pool_barrier(pool);
    }
    /* Cloth contact is found every substep, over each particle's motion from x to its
     * prediction. (Once per step, over the motion to the prediction extrapolated to
     * the step's end, was 8x cheaper but missed contacts where edges whip and took
     * sides at the step's start that were wrong by its end: stacked layers passed
     * through each other.) */
    if (ctx->cc_active && ctx->result == RBC_OK) {
        if (tid == 0) {
            for (uint32_t k = 0; k < s->cloth_count; ++k) {
                rbc_cloth_state *c = s->cloths[k];
                rbc_contact_body *b = &s->cc_bodies[k];
                memset(b, 0, sizeof *b);
                b->n = c->topo.n;
                for (int a = 0; a < 3; ++a) {
                    b->p[a] = c->p[a];
                    b->x[a] = c->x[a];
                }
                b->rest[0] = c->topo.rest_x;
                b->rest[1] = c->topo.rest_y;
                b->rest[2] = c->topo.rest_z;
                b->mass = c->topo.mass;
                b->pinned = c->pinned;
                b->tri_count = c->collision_flags ? c->tri_count : 0;
                b->tris = c->tris;
                b->thickness = c->thickness;
                b->friction = c->friction;
                b->self = (c->collision_flags & RBC_CLOTH_COLLIDE_SELF) != 0;
                b->others = (c->collision_flags & RBC_CLOTH_COLLIDE_CLOTHS) != 0;
            }
        }
        /* A quarter of a spring: the solve moves particles from their prediction by
         * up to about half a spring where they hit something, and what a smaller
         * margin misses the fail-safe catches. Half a spring (as for colliders) made
         * 13 times the contacts in the resting four-layer pile (163,416 against
         * 12,288, bench scenes' medians: each vertex reached the next layer's
         * triangles 6 mm away) and the scene twice as slow: 180
         * frames 177 s against 91 s on two threads, with the same largest strain
         * (0.052) and kinetic energy (0.089 J) and no vertex frozen in either. */
        float margin = 0.0f;
        for (uint32_t k = 0; k < s->cloth_count; ++k)
            if (s->cloths[k]->collision_flags && 0.25f * s->cloths[k]->mean_rest > margin)
                margin = 0.25f * s->cloths[k]->mean_rest;
        rbc_pool_barrier(pool);
        /* Every thread finds the contacts of its share of the vertices (the list is
         * the same for any thread count). */
        int32_t rc = rbc_clothcontact_detect_mt(s->cc, s->cc_bodies, s->cloth_count, margin, tid,
                                                nt, pool_sync, pool);
        if (tid != 0) {
            /* thread 0 reports */
        } else if (rc == RBC_ERR_UNSTABLE)
            ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                                   "cloth contact: more than %u contacts per vertex at substep %u "
                                   "of %u: the cloths are crushed or tangled beyond what contact "
                                   "can hold (smaller steps, more iterations, or a larger "
                                   "thickness keep them apart); the world was restored to its "
                                   "state before the step",
                                   RBC_CC_MAX_TOTAL_PER_VERTEX, sub, ctx->substeps);
        else if (rc != RBC_OK)
            ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                   "out of memory for cloth contacts at substep %u", sub);
        if (tid == 0) {
            for (uint32_t k = 0; k < s->cloth_count; ++k)
                for (int a = 0; a < 3; ++a) s->cc_bodies[k].p[a] = s->cloths[k]->p[a];
            s->last_cloth_contacts = rbc_clothcontact_count(s->cc);
            s->last_cloth_capped = rbc_clothcontact_capped(s->cc);
        }
    }
    if (ctx->cc_active) rbc_pool_barrier(pool);
}

static void step_spmd(void *arg, uint32_t tid, uint32_t nt) {
    step_ctx *ctx = arg;
    rbc_solver *s = ctx->s;
    rbc_pool *pool = s->pool;
    double t0 = 0.0, t1 = 0.0;
#define STAGE_BEGIN() \
    do {              \
        if (tid == 0) t0 = now_ms(); \
    } while (0)
#define STAGE_END(field) \
    do {                 \
        rbc_pool_barrier(pool); \
        if (tid == 0) { t1 = now_ms(); ctx->t.field += t1 - t0; } \
    } while (0)

    const uint32_t nl_count = s->nonlinear_iterations;
    const int guard = guard_on(s);
    if (guard) {
        STAGE_BEGIN();
        energy_start(ctx, tid, nt);
        if (tid == 0) ctx->t.other += now_ms() - t0;
    }
    for (uint32_t sub = 0; sub < ctx->substeps; ++sub) {
        const int last = sub + 1 == ctx->substeps;
        STAGE_BEGIN();
        phase_integrate(ctx, tid, nt);
        place_pins(ctx, sub, tid, nt);
        STAGE_END(integrate);
        if (guard && tid == 0) /* the pins' work: they moved from x to p */
            for (uint32_t k = 0; k < s->cloth_count; ++k) {
                rbc_cloth_state *c = s->cloths[k];
                if (c->pin_spring_count) c->e_step_budget += rbc_energy_pin_work(c, c->x, c->p);
            }
        if (s->wind_drag != 0.0f || s->wind_lift != 0.0f) {
            /* Wind on the quads (shared corners: one thread). */
            STAGE_BEGIN();
            if (tid == 0) rbc_wind_apply(s, ctx->h);
            STAGE_END(integrate);
        }
        if (s->collider_count || ctx->cc_active || s->contact_fn) {
            STAGE_BEGIN();
            detect_contacts(ctx, sub, tid, nt);
            if (ctx->result == RBC_OK)
                /* Start the solve from the prediction moved onto the contacts, so the
                 * first local step takes the springs' directions from a state that
                 * respects them. (From y itself, a contact that lifts part of the
                 * cloth during the solve would carry the rest along rigidly: the global
                 * step keeps each spring's direction from the local step, so a particle
                 * whose neighbours the contact lifts is lifted with them. The inertial
                 * target y stays as predicted.) */
                contact_pass(ctx, 0, tid, 1, 2);
            STAGE_END(collide);
            if (ctx->result != RBC_OK) return;
        }

        for (uint32_t nl = 0; nl < nl_count; ++nl) {
            STAGE_BEGIN();
            phase_local(ctx, tid, nt);
            rbc_pool_barrier(pool); /* every spring's d before the sums over them */
            for (uint32_t q = 0; q < s->cloth_count; ++q) {
                rbc_cloth_state *c = s->cloths[q];
                if (grid_local(s, c))
                    rbc_grid_rhs(c->grid, c, tid, nt);
                else
                    rbc_global_rhs(c, tid, nt);
            }
            STAGE_END(local);
            STAGE_BEGIN();
            if (s->settings.kind == RBC_SOLVER_DIRECT) {
                /* One exact solve per cloth; cloths are spread over the threads. */
                for (uint32_t q = tid; q < s->cloth_count; q += nt) {
                    rbc_cloth_state *c = s->cloths[q];
                    rbc_direct_solve(c->direct, &c->topo, c->pinned, c->w,
                                     (const float *const *)c->y, c->dx, c->dy, c->dz, c->p);
                }
                rbc_pool_barrier(pool);
                contact_pass(ctx, 0, tid, 1, 1);
                if (tid == 0) ctx->linear_done += 1;
            } else {
                global_step(ctx, sub * nl_count + nl, ctx->substeps * nl_count, tid, nt);
            }
            if (tid == 0) ctx->t.global += now_ms() - t0;
        }

        if (s->collider_count) {
            /* Friction, and the work the colliders did (impulse . their velocity; a
             * static one supplies nothing). */
            STAGE_BEGIN();
            /* Every contact's normal force from the solve's positions, before any
             * friction moves one (a neighbour may be another thread's). */
            if (!ctx->color_pass) {
                rbc_collide_normal_forces(s, &s->contacts[tid], ctx->h);
                if (tid == 0 && ctx->host_contacts)
                    rbc_collide_normal_forces(s, &s->host_contacts, ctx->h);
                rbc_pool_barrier(pool);
            }
            rbc_collide_finish(s, &s->contacts[tid], ctx->h, tid, nt, NULL, ctx->color_pass);
            rbc_collide_post(s, (float)sub / (float)ctx->substeps,
                             (float)(sub + 1) / (float)ctx->substeps, ctx->h, tid, nt);
            rbc_pool_barrier(pool);
            if (guard && tid == 0)
                for (uint32_t k = 0; k < s->cloth_count; ++k)
                    s->cloths[k]->e_step_budget += rbc_energy_sum_work(s->cloths[k]);
            STAGE_END(collide);
        }
        if (ctx->host_contacts) {
            /* Host contacts: friction, and their work on the cloth they touch. */
            if (tid == 0) {
                rbc_contact_list *l = &s->host_contacts;
                if (!s->collider_count && !ctx->color_pass) rbc_collide_normal_forces(s, l, ctx->h);
                for (uint32_t m = 0; m < l->count; ++m) {
                    rbc_contact_list one = {&l->c[m], 1, 1, 1};
                    double w = 0.0;
                    rbc_collide_finish(s, &one, ctx->h, 0, 1, &w, ctx->color_pass);
                    if (guard) s->cloths[l->c[m].cloth]->e_step_budget += w;
                }
            }
            rbc_pool_barrier(pool);
        }
        if (ctx->cc_active) {
            STAGE_BEGIN();
            if (tid == 0) rbc_clothcontact_friction(s->cc, s->cc_bodies, s->cloth_count);
            rbc_pool_barrier(pool);
            /* The last word: no edge ends the substep through another layer. */
            uint32_t frozen = 0;
            if (rbc_clothcontact_failsafe_mt(s->cc, s->cc_bodies, s->cloth_count, tid, nt,
                                             pool_sync, pool, &frozen) != RBC_OK &&
                tid == 0)
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_OUT_OF_MEMORY,
                                       "out of memory for the cloth contact fail-safe at "
                                       "substep %u; the world was restored to its state "
                                       "before the step", sub);
            if (tid == 0) s->last_frozen += frozen;
            STAGE_END(collide);
            if (ctx->result != RBC_OK) return;
        }
        if (s->callback) {
            /* The host's corrections count as work it does: the change of energy. */
            if (guard) budget_add_guarded(ctx, -1.0, tid, nt);
            if (tid == 0) {
                t0 = now_ms();
                run_callback(ctx, sub);
                ctx->t.callback += now_ms() - t0;
            }
            rbc_pool_barrier(pool);
            if (ctx->result != RBC_OK) return;
            if (guard) budget_add_guarded(ctx, 1.0, tid, nt);
        }

        STAGE_BEGIN();
        phase_check(ctx, guard && last, last, tid, nt);
        rbc_pool_barrier(pool);
        if (tid == 0) {
            for (uint32_t th = 0; th < nt; ++th) {
                if (ctx->bad[th][0] < 0) continue;
                rbc_cloth_state *c = s->cloths[ctx->bad[th][0]];
                uint32_t i = (uint32_t)ctx->bad[th][1];
                if (ctx->bad[th][2] == 2) {
                    const rbc_topology *t = &c->topo;
                    ctx->result = rbc_fail(
                        ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                        "cloth 0x%08x: the spring between vertices %u and %u was stretched "
                        "past %g times its rest length at substep %u of %u: the global "
                        "solver diverged (more iterations, more substeps, or rbgs/direct "
                        "keep it stable); the world was restored to its state before the step",
                        c->public_id, t->to_host[t->sa[i]], t->to_host[t->sb[i]],
                        (double)RBC_BLOWUP_STRETCH, sub, ctx->substeps);
                    break;
                }
                ctx->result = rbc_fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                                   "cloth 0x%08x: vertex %u became non-finite at substep %u of %u "
                                   "(h = %g s, stiffness*h^2/mass up to %g); the world was "
                                   "restored to its state before the step",
                                   c->public_id, c->topo.to_host[i], sub, ctx->substeps,
                                   (double)ctx->h, (double)(c->topo.ksum[i] / c->w[i]));
                break;
            }
            if (ctx->result == RBC_OK && guard && last) energy_decide(ctx);
        }
        rbc_pool_barrier(pool);
        if (ctx->result != RBC_OK) return;
        if (ctx->clamp) {
            energy_apply(ctx, tid, nt);
            rbc_pool_barrier(pool);
        }
        if (tid == 0) {
            commit(s);
            t1 = now_ms();
            ctx->t.other += t1 - t0;
        }
        rbc_pool_barrier(pool);
    }
#undef STAGE_BEGIN
#undef STAGE_END
}

/* The final strain of every cloth, block sums on all threads: the RMS for the target
 * mode's decision, the largest for the strain warning. */
static void strain_spmd(void *arg, uint32_t tid, uint32_t nt) {
    rbc_solver *s = arg;
    const int target = s->settings.mode == RBC_ITERATE_TARGET, warn = s->strain_warning > 0.0f;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (target) rbc_strain_blocks(s->cloths[k], s->cloths[k]->x, tid, nt);
        if (warn) rbc_strain_max_blocks(s->cloths[k], s->cloths[k]->x, tid, nt);
    }
}

/* The target mode's controller, after a successful step of `used` substeps that
 * reached `reached` (the largest RMS relative strain of any cloth) at `cost` units.
 * Substeps are the lever (the linear iterations adapt inside each global step):
 *  - a miss, or a global step that needed max_linear_iterations, raises them by half
 *    (at least one) up to max_substeps;
 *  - after tgt_hold steps in a row that met the target without the cap, a probe
 *    lowers them by a quarter (at least one); if the next step costs more units
 *    than the step before the probe, the probe is undone and tgt_hold doubles (up
 *    to 256), so a lowering that does not pay is tried ever less often.
 * Counts only: the choice is deterministic and independent of the thread count. */
static void target_decide(rbc_solver *s, uint32_t used, int hit_cap, double reached,
                          uint64_t cost) {
    const uint32_t smax = s->settings.max_substeps;
    const int met = reached <= (double)s->settings.target_strain;
    s->tgt_reached = reached;
    s->tgt_met = met;
    s->tgt_capped = !met && used >= smax;
    if (!met) s->tgt_missed_steps++;
    if (s->tgt_capped) s->tgt_capped_steps++;
    uint32_t next = used;
    if ((!met || hit_cap) && used < smax) {
        next = used + (used / 2 > 1 ? used / 2 : 1);
        if (next > smax) next = smax;
        if (s->tgt_probe || (s->tgt_lowered_at && s->step_count - s->tgt_lowered_at <= s->tgt_hold))
            s->tgt_hold = s->tgt_hold < 128 ? 2 * s->tgt_hold : 256;
        s->tgt_probe = 0;
        s->tgt_calm = 0;
    } else if (s->tgt_probe) {
        if (cost > s->tgt_prev_cost) {
            next = s->tgt_prev_substeps; /* the fewer substeps cost more: back */
            s->tgt_hold = s->tgt_hold < 128 ? 2 * s->tgt_hold : 256;
        }
        s->tgt_probe = 0;
        s->tgt_calm = 0;
    } else if (met && !hit_cap && used > 1) {
        if (++s->tgt_calm >= s->tgt_hold) {
            s->tgt_prev_substeps = used;
            s->tgt_prev_cost = cost;
            s->tgt_probe = 1;
            s->tgt_lowered_at = s->step_count;
            next = used - (used / 4 > 1 ? used / 4 : 1);
            s->tgt_calm = 0;
        }
    } else {
        s->tgt_calm = 0;
    }
    s->tgt_substeps = next;
}

/* ------------------------------------------------------------------------- */
/* Threads per step (threads_auto)                                            */
/* ------------------------------------------------------------------------- */

/* Results do not depend on the thread count (every reduction is over fixed blocks,
 * every partition is checked bitwise on 1 and 2 threads), so the count may change
 * from one step to the next. Every probe_every steps a probe runs PROBE_STEPS steps
 * on the other count and the fastest of them counts: 8 after a change, doubling to
 * 256 while the choice holds. */
enum { PROBE_FIRST = 8, PROBE_MAX = 256, PROBE_STEPS = 2 };

static uint32_t threads_for_step(rbc_solver *s) {
    const uint32_t all = rbc_pool_size(s->pool);
    if (!s->threads_auto || all == 1) return all;
    if (!s->threads_now) {
        /* First step: a small cloth's phases take microseconds, less than waking a
         * worker; start on one thread there, on all above 4096 particles per thread. */
        uint64_t n = 0;
        for (uint32_t k = 0; k < s->cloth_count; ++k) n += s->cloths[k]->topo.n;
        s->threads_now = n >= 4096ull * all ? all : 1;
        s->probe_every = PROBE_FIRST;
        s->probe_in = 2; /* the other count after two steps */
        s->probe_nrecent = 0;
        s->probe_left = 0;
    }
    const uint32_t other = s->threads_now == 1 ? all : 1;
    if (s->probe_left) return other;
    if (s->probe_in == 0 && s->probe_nrecent > 0) {
        /* A probe is two steps, the faster one counts: the first step on all threads
         * after a while on one wakes sleeping workers and warms their caches. */
        s->probe_left = PROBE_STEPS;
        s->probe_best = INFINITY;
        return other;
    }
    return s->threads_now;
}

static double median3(const double *v, uint32_t n) {
    if (n == 1) return v[0];
    if (n == 2) return v[0] < v[1] ? v[0] : v[1];
    double a = v[0], b = v[1], c = v[2];
    return a > b ? (b > c ? b : (a > c ? c : a)) : (a > c ? a : (b > c ? c : b));
}

static void threads_record(rbc_solver *s, uint32_t used, double ms_per_substep) {
    if (!s->threads_auto || rbc_pool_size(s->pool) == 1) return;
    if (used != s->threads_now) {
        if (ms_per_substep < s->probe_best) s->probe_best = ms_per_substep;
        if (s->probe_left) s->probe_left--;
        if (s->probe_left) return;
        /* Switch when the probe beat the recent steps by 10 %. */
        double base = median3(s->probe_recent, s->probe_nrecent);
        if (s->probe_best < 0.9 * base) {
            s->threads_now = used;
            s->probe_recent[0] = s->probe_best;
            s->probe_nrecent = 1;
            s->probe_every = PROBE_FIRST;
        } else if (s->probe_every < PROBE_MAX) {
            s->probe_every *= 2;
        }
        s->probe_in = s->probe_every;
        return;
    }
    if (s->probe_nrecent < 3) s->probe_recent[s->probe_nrecent++] = ms_per_substep;
    else {
        s->probe_recent[0] = s->probe_recent[1];
        s->probe_recent[1] = s->probe_recent[2];
        s->probe_recent[2] = ms_per_substep;
    }
    if (s->probe_in) s->probe_in--;
}

int32_t rbc_solver_step(rbc_solver *s, float dt, char *err, size_t errlen) {
    double start = now_ms();
    step_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    ctx.s = s;
    const int target = s->settings.mode == RBC_ITERATE_TARGET;
    ctx.substeps = s->substeps;
    /* Substeps from the rate (world substeps 0, 1.6): the substep length stays near
     * 1 / rate whatever dt the host passes, up to the cap. The 1e-3 lets a float dt
     * such as 1/60.f (8.0000006 substeps at 480 Hz) take 8, not 9: substeps at most
     * 0.1 % longer than 1 / rate. */
    const int from_rate = !target && s->substeps == 0;
    if (from_rate) {
        double want = ceil((double)dt * (double)s->substep_rate - 1e-3);
        uint32_t cap = s->settings.max_substeps;
        ctx.substeps = want < 1.0 ? 1u : want > (double)cap ? cap : (uint32_t)want;
    }
    if (target) {
        /* The controller's choice; the first step of the mode starts at the cap (the
         * most accurate) and the controller lowers it while that pays. */
        ctx.substeps = s->tgt_substeps ? s->tgt_substeps : s->settings.max_substeps;
        if (ctx.substeps > s->settings.max_substeps) ctx.substeps = s->settings.max_substeps;
        /* Start from the world's linear iterations, within the cap. */
        ctx.tgt_iters = s->tgt_iters ? s->tgt_iters : s->linear_iterations;
        if (ctx.tgt_iters > s->settings.max_linear_iterations)
            ctx.tgt_iters = s->settings.max_linear_iterations;
        ctx.tgt_iters_next = ctx.tgt_iters; /* the direct solver keeps it */
    }
    ctx.h = dt / (float)ctx.substeps;
    ctx.result = RBC_OK;
    ctx.err = err;
    ctx.errlen = errlen;
    ctx.start_ms = start;
    if (!(ctx.h > 0.0f))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "dt / substeps = %g s underflows to zero", (double)ctx.h);

    /* Serial preparation: weights for h, and what the solver needs for them (the
     * spectral radius for SOR and Chebyshev, the factorisation for the direct
     * solver). These change only when h, the pins or the topology change. */
    const rbc_solver_settings *st = &s->settings;
    /* The color sweeps of these solvers leave each color's values as they are until its
     * next sweep (Chebyshev blends after the sweeps; the others have no colors): their
     * collider contacts and friction are solved per color. */
    ctx.color_pass = st->kind == RBC_SOLVER_RBGS || st->kind == RBC_SOLVER_RBGS_SOR ||
                     st->kind == RBC_SOLVER_MULTICOLOR_GS;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        prepare_weights(c, ctx.h);
        if (c->topo.ncolors > ctx.ncolors) ctx.ncolors = c->topo.ncolors;
        uint32_t ki = k < 64 ? k : 63;
        if (st->kind == RBC_SOLVER_RBGS_SOR) ctx.sor_omega[ki] = rbc_solver_sor_omega(s, c, ctx.h);
        if (st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV || st->kind == RBC_SOLVER_RBGS_CHEBYSHEV) {
            /* rho_J, given or estimated. Gauss-Seidel's radius is rho_J^2 for a
             * consistently ordered (two color) matrix; used with more colors too. */
            float rho = st->rho > 0.0f ? st->rho : rbc_cloth_state_spectral_radius(c, ctx.h);
            if (st->kind == RBC_SOLVER_RBGS_CHEBYSHEV) rho = rho * rho;
            ctx.cheb_rho[ki] = rho;
        }
        if (st->kind == RBC_SOLVER_DIRECT &&
            (!c->direct || c->h_direct != ctx.h || c->direct_dirty)) {
            rbc_direct *d = NULL;
            int32_t rc = rbc_direct_create(&d, &c->topo, c->pinned, ctx.h, &s->alloc, err, errlen);
            if (rc != RBC_OK) return rc;
            rbc_direct_destroy(c->direct);
            c->direct = d;
            c->h_direct = ctx.h;
            c->direct_dirty = 0;
        }
    }

    for (uint32_t k = 0; k < s->collider_count; ++k) {
        rbc_collider_state *col = &s->colliders[k];
        for (int a = 0; a < 3; ++a) col->velocity[a] = (col->position[a] - col->last_position[a]) / dt;
    }
    /* Cloth contact runs only while some cloth asks for it. */
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        if (s->cloths[k]->collision_flags && s->cloths[k]->thickness > 0.0f) ctx.cc_active = 1;
    if (ctx.cc_active && s->cc_bodies_cap < s->cloth_count) {
        rbc_contact_body *b = rbc_mem_alloc(&s->alloc, sizeof(*b) * s->cloth_cap);
        if (!b)
            return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for cloth contact");
        rbc_mem_free(&s->alloc, s->cc_bodies, sizeof(*s->cc_bodies) * s->cc_bodies_cap);
        s->cc_bodies = b;
        s->cc_bodies_cap = s->cloth_cap;
    }
    s->last_contacts = s->last_cloth_contacts = 0;
    s->last_frozen = s->last_cloth_capped = 0;
    rbc_attachments_update(s);
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->pin_count; ++m)
            for (int a = 0; a < 3; ++a) c->pin_start[3 * m + a] = c->x[a][c->pin_idx[m]];
    }
    /* With one substep nothing is committed before the check, so the state before the
     * step is intact on failure; with several, earlier substeps are, so keep a copy. */
    int rescale = 0;
    for (uint32_t k = 0; (target || from_rate) && k < s->cloth_count; ++k)
        rescale |= s->cloths[k]->h_last > 0.0f && s->cloths[k]->h_last != ctx.h;
    int need_snapshot = ctx.substeps > 1 || rescale;
    if (need_snapshot) snapshot(s, 0);
    if (rescale) {
        /* The target mode or a new dt changed the substep length: keep each velocity
         * (x - q) / h by rescaling q to the new h (Verlet reads it from x - q). */
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            rbc_cloth_state *c = s->cloths[k];
            if (!(c->h_last > 0.0f) || c->h_last == ctx.h) continue;
            const float f = ctx.h / c->h_last;
            for (int a = 0; a < 3; ++a)
                for (uint32_t i = 0; i < c->topo.n; ++i)
                    c->q[a][i] = c->x[a][i] - (c->x[a][i] - c->q[a][i]) * f;
        }
    }

    const uint32_t threads = threads_for_step(s);
    const double run_t0 = now_ms();
    rbc_pool_run_n(s->pool, threads, step_spmd, &ctx);
    const double run_ms = now_ms() - run_t0;
    s->threads_last = threads;

    if (ctx.result != RBC_OK) {
        if (need_snapshot) snapshot(s, 1);
        return ctx.result;
    }
    threads_record(s, threads, run_ms / (ctx.substeps ? ctx.substeps : 1));
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        s->cloths[k]->system_valid = 1;
        s->cloths[k]->h_last = ctx.h;
    }
    for (uint32_t k = 0; k < s->collider_count; ++k) {
        memcpy(s->colliders[k].last_position, s->colliders[k].position, 3 * sizeof(float));
        memcpy(s->colliders[k].last_rotation, s->colliders[k].rotation, 4 * sizeof(float));
    }
    s->energy_removed_last = 0.0;
    s->energy_clamped_last = 0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (!guard_on(s)) {
            c->e_valid = 0;
            continue;
        }
        c->e_last = c->e_end;
        c->e_budget = c->e_step_budget;
        c->e_h = ctx.h;
        c->e_valid = 1;
        c->e_keep_slack = 1;
        s->energy_removed_last += c->e_removed;
        if (c->e_scale != 1.0f) s->energy_clamped_last = 1;
    }
    if (s->energy_clamped_last) s->energy_clamped_steps++;
    /* Tearing: springs stretched past their limit at the end of the step break. */
    for (uint32_t k = 0; k < s->cloth_count; ++k) rbc_tear_scan(s, s->cloths[k]);
    double reached = 0.0;
    const int warn = s->strain_warning > 0.0f;
    s->step_max_strain = 0.0;
    s->strain_warn_last = 0;
    if (target || warn) {
        /* What the step reached, at the positions the host reads (after tearing). */
        double t0 = now_ms();
        rbc_pool_run_n(s->pool, threads, strain_spmd, s);
        float top = 0.0f;
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            if (target) {
                double r = rbc_strain_sum(s->cloths[k]);
                if (r > reached) reached = r;
            }
            if (!warn) continue;
            float m = rbc_strain_max(s->cloths[k], s->cloths[k]->x, NULL);
            if (m > top) {
                top = m;
                s->strain_warn_cloth = k;
            }
        }
        s->step_max_strain = top;
        if (warn && top > s->strain_warning) {
            /* Past the threshold: find the spring, for the log (one block again). */
            rbc_cloth_state *c = s->cloths[s->strain_warn_cloth];
            rbc_strain_max(c, c->x, &s->strain_warn_spring);
            s->strain_warn_last = 1;
            s->strain_warn_steps++;
        }
        ctx.t.other += now_ms() - t0;
    }
    ctx.t.step = now_ms() - start;
    s->last = ctx.t;
    s->last_substeps = ctx.substeps;
    s->last_nonlinear = ctx.substeps * s->nonlinear_iterations;
    s->last_linear = ctx.linear_done;
    s->step_count++;
    if (target) {
        /* The unchecked global steps of the next step: what the checked one needed,
         * at most twice this step's count and at least 2 (within the cap). A jump
         * from a loose solve to a tight one releases the stretch the loose one
         * stored as motion (energy no one supplied, which the energy guard clamps):
         * on the paper's cloth at 1/60 s the preset's run had 3 clamped steps when
         * the count could go from 1 to 8 at once, none with this. */
        uint32_t next = ctx.tgt_iters_next;
        if (next > 2 * ctx.tgt_iters) next = 2 * ctx.tgt_iters;
        if (next < 2) next = 2;
        if (next > s->settings.max_linear_iterations) next = s->settings.max_linear_iterations;
        s->tgt_iters = next;
        target_decide(s, ctx.substeps, ctx.hit_cap, reached,
                      ctx.linear_done + (uint64_t)RBC_TARGET_SUBSTEP_COST * ctx.substeps *
                                            s->nonlinear_iterations);
    } else {
        s->tgt_reached = 0.0;
        s->tgt_met = 0;
        s->tgt_capped = 0;
    }
    return RBC_OK;
}
