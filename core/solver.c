/* solver.c -- Algorithm 1 of the paper on the CPU backend.
 *
 * One rbc_solver_step runs a single SPMD function on every pool thread. Each phase
 * splits its range statically among the threads and ends at a barrier:
 *
 *   for each substep:
 *     integrate    Alg. 2: y = Verlet prediction, p = y; pins set       (particles)
 *     loop nonlinear_iterations:
 *       local      Alg. 3: d_ij for every spring                        (springs)
 *       loop linear_iterations:
 *         global   Eq. 6 over the red particles, then over the black    (per color)
 *     collide      built-in colliders project the free particles       (particles)
 *     callback     the host's collision code, on thread 0
 *     check        every position finite, else restore and fail
 *     commit       q <- x <- p (buffer rotation, thread 0)
 *
 * The particles of one color share no spring, so the threads of a color sweep never
 * read a position another thread writes: the result is bitwise independent of the
 * thread count.
 */
#include "solver.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "kernels/collide_kernels.h"
#include "kernels/pd_kernels.h"

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static int32_t fail(char *err, size_t errlen, int32_t code, const char *fmt, ...) {
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return code;
}

/* [begin, end) of `count` items for thread tid of n (contiguous static split). */
static inline void split(uint32_t count, uint32_t tid, uint32_t n, uint32_t *begin,
                         uint32_t *end) {
    uint64_t b = (uint64_t)count * tid / n, e = (uint64_t)count * (tid + 1) / n;
    *begin = (uint32_t)b;
    *end = (uint32_t)e;
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
    if (rbc_pool_create(&s->pool, nthreads, a) != 0) return RBC_ERR_OUT_OF_MEMORY;
    return RBC_OK;
}

void rbc_solver_fini(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) rbc_cloth_state_destroy(s, s->cloths[k]);
    rbc_mem_free(&s->alloc, s->cloths, sizeof(*s->cloths) * s->cloth_cap);
    rbc_mem_free(&s->alloc, s->cb_list, sizeof(*s->cb_list) * s->cloth_cap);
    rbc_mem_free(&s->alloc, s->colliders, sizeof(*s->colliders) * s->collider_cap);
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
    X(w, float, n) X(inv_denom, float, n) X(pinned, uint8_t, n)

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

void rbc_cloth_state_destroy(rbc_solver *s, rbc_cloth_state *c) {
    if (!c) return;
    size_t n = c->topo.n, ns = c->topo.ns;
    (void)n;
    (void)ns;
#define FREE_ONE(name, type, count) rbc_mem_free(&s->alloc, c->name, rbc_mul_size(count, sizeof(type)));
    STATE_ARRAYS(FREE_ONE)
#undef FREE_ONE
    free_pins(s, c);
    free_cb_buffers(s, c);
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
    if (!c) return fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for a cloth");
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
    if (ok && s->callback) ok = alloc_cb_buffers(s, c);
    if (!ok) {
        rbc_cloth_state_destroy(s, c);
        return fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %zu particles", n);
    }
    c->state_bytes = bytes;
    c->damping = damping;
    const rbc_topology *t = &c->topo;
    memcpy(c->x[0], t->rest_x, n * sizeof(float));
    memcpy(c->x[1], t->rest_y, n * sizeof(float));
    memcpy(c->x[2], t->rest_z, n * sizeof(float));
    memcpy(c->q[0], t->rest_x, n * sizeof(float)); /* at rest: zero initial velocity */
    memcpy(c->q[1], t->rest_y, n * sizeof(float));
    memcpy(c->q[2], t->rest_z, n * sizeof(float));
    /* d_ij starts at the rest configuration's (used only before the first local step). */
    for (uint32_t k = 0; k < t->ns; ++k) {
        rbc_k_local(k, t->sa, t->sb, t->rest_len, t->ux, t->uy, t->uz, t->he_a, t->he_b, c->x[0],
                    c->x[1], c->x[2], c->dx, c->dy, c->dz);
    }
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
    c->h_cached = 0.0f;
    *out = c;
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
        uint32_t last = --c->pin_count;
        c->pin_idx[m] = c->pin_idx[last];
        memcpy(&c->pin_target[3 * m], &c->pin_target[3 * last], 3 * sizeof(float));
        c->pinned[i] = 0;
        return RBC_OK;
    }
    if (m == c->pin_count) {
        if (!grow_pins(s, c, c->pin_count + 1)) return RBC_ERR_OUT_OF_MEMORY;
        c->pin_idx[m] = i;
        c->pin_count++;
        c->pinned[i] = 1;
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
    rbc_collider_update_frame(&s->colliders[s->collider_count]);
    s->collider_count++;
    return RBC_OK;
}

void rbc_solver_remove_collider(rbc_solver *s, uint32_t index) {
    memmove(&s->colliders[index], &s->colliders[index + 1],
            sizeof(*s->colliders) * (s->collider_count - index - 1));
    s->collider_count--;
}

int32_t rbc_solver_set_callback(rbc_solver *s, rbc_collision_fn fn, void *user) {
    if (fn && !s->callback) {
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            if (alloc_cb_buffers(s, s->cloths[k])) continue;
            for (uint32_t j = 0; j < k; ++j) free_cb_buffers(s, s->cloths[j]);
            return RBC_ERR_OUT_OF_MEMORY;
        }
    } else if (!fn && s->callback) {
        for (uint32_t k = 0; k < s->cloth_count; ++k) free_cb_buffers(s, s->cloths[k]);
    }
    s->callback = fn;
    s->callback_user = user;
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* The step                                                                  */
/* ------------------------------------------------------------------------- */

typedef struct step_ctx {
    rbc_solver *s;
    float h;
    uint32_t substeps;
    uint32_t ncolors; /* most colors of any cloth */
    /* Set by thread 0 between barriers; read by all after the barrier. */
    volatile int32_t result;
    char *err;
    size_t errlen;
    /* Per-thread first non-finite particle found, (cloth index, internal index). */
    int64_t bad[64][2];
    rbc_step_times t;
} step_ctx;

/* m_i/h^2 and 1/(m_i/h^2 + sum s_ij), recomputed only when h changes. */
static void prepare_weights(rbc_cloth_state *c, float h, uint32_t tid, uint32_t nt) {
    uint32_t b, e;
    split(c->topo.n, tid, nt, &b, &e);
    float inv_h2 = 1.0f / (h * h);
    for (uint32_t i = b; i < e; ++i) {
        float wi = c->topo.mass[i] * inv_h2;
        c->w[i] = wi;
        c->inv_denom[i] = 1.0f / (wi + c->topo.ksum[i]);
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
        split(c->topo.n, tid, nt, &b, &e);
        for (uint32_t i = b; i < e; ++i)
            rbc_k_predict(i, c->x[0], c->x[1], c->x[2], c->q[0], c->q[1], c->q[2], c->y[0],
                          c->y[1], c->y[2], c->p[0], c->p[1], c->p[2], keep,
                          s->gravity[0] * h2, s->gravity[1] * h2, s->gravity[2] * h2);
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
        split(c->topo.n, tid, nt, &b, &e);
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

static void phase_local(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const rbc_topology *t = &c->topo;
        uint32_t b, e;
        split(t->ns, tid, nt, &b, &e);
        for (uint32_t sp = b; sp < e; ++sp)
            rbc_k_local(sp, t->sa, t->sb, t->rest_len, t->ux, t->uy, t->uz, t->he_a, t->he_b,
                        c->p[0], c->p[1], c->p[2], c->dx, c->dy, c->dz);
    }
}

static void phase_global_color(step_ctx *ctx, uint32_t color, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const rbc_topology *t = &c->topo;
        if (color >= t->ncolors) continue;
        uint32_t c0 = t->color_start[color], count = t->color_start[color + 1] - c0;
        uint32_t b, e;
        split(count, tid, nt, &b, &e);
        /* Local copies: stores to p must not force reloads of these pointers. */
        const uint32_t *restrict adj_start = t->adj_start, *restrict adj_nbr = t->adj_nbr;
        const float *restrict adj_k = t->adj_k, *restrict dx = c->dx, *restrict dy = c->dy,
                              *restrict dz = c->dz, *restrict w = c->w,
                              *restrict inv_denom = c->inv_denom, *restrict yx = c->y[0],
                              *restrict yy = c->y[1], *restrict yz = c->y[2];
        const uint8_t *restrict pinned = c->pinned;
        float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
        for (uint32_t i = c0 + b; i < c0 + e; ++i) {
            if (pinned[i]) continue;
            rbc_k_global(i, adj_start, adj_nbr, adj_k, dx, dy, dz, w, inv_denom, yx, yy, yz, px,
                         py, pz);
        }
    }
}

static void phase_collide(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        split(c->topo.n, tid, nt, &b, &e);
        for (uint32_t ci = 0; ci < s->collider_count; ++ci) {
            const rbc_collider_state *col = &s->colliders[ci];
            for (uint32_t i = b; i < e; ++i) {
                if (c->pinned[i]) continue;
                if (col->shape == RBC_SHAPE_PLANE)
                    rbc_k_collide_plane(&c->p[0][i], &c->p[1][i], &c->p[2][i], col->position,
                                        col->normal, col->thickness);
                else
                    rbc_k_collide_sphere(&c->p[0][i], &c->p[1][i], &c->p[2][i], col->position,
                                         col->radius + col->thickness);
            }
        }
    }
}

/* Thread 0, all others waiting at a barrier: hand host-order positions to the host's
 * collision code and take its corrections back (pins win). */
static void run_callback(step_ctx *ctx, uint32_t sub) {
    rbc_solver *s = ctx->s;
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
    int32_t r = s->callback(s->callback_user, s->public_world_id, ctx->h, s->cb_list,
                            s->cloth_count);
    if (r != 0) {
        ctx->result = fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
                           "the collision callback returned %d at substep %u", (int)r, sub);
        return;
    }
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        const uint32_t *to_int = c->topo.to_internal;
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            const float *hp = &c->cb_pos[3 * (size_t)v];
            if (!(isfinite(hp[0]) && isfinite(hp[1]) && isfinite(hp[2]))) {
                ctx->result = fail(ctx->err, ctx->errlen, RBC_ERR_CALLBACK,
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

/* Record the first non-finite particle this thread sees. */
static void phase_check(step_ctx *ctx, uint32_t tid, uint32_t nt) {
    rbc_solver *s = ctx->s;
    ctx->bad[tid][0] = -1;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b, e;
        split(c->topo.n, tid, nt, &b, &e);
        const float *px = c->p[0], *py = c->p[1], *pz = c->p[2];
        /* Branch-free accumulation: x - x is 0 for finite x and NaN otherwise. */
        float acc = 0.0f;
        for (uint32_t i = b; i < e; ++i) acc += (px[i] - px[i]) + (py[i] - py[i]) + (pz[i] - pz[i]);
        if (acc == 0.0f) continue;
        for (uint32_t i = b; i < e; ++i) {
            if (!(isfinite(px[i]) && isfinite(py[i]) && isfinite(pz[i]))) {
                ctx->bad[tid][0] = k;
                ctx->bad[tid][1] = i;
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

    STAGE_BEGIN();
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        if (c->h_cached != ctx->h) prepare_weights(c, ctx->h, tid, nt);
    }
    STAGE_END(other);
    if (tid == 0) {
        for (uint32_t k = 0; k < s->cloth_count; ++k) s->cloths[k]->h_cached = ctx->h;
    }

    for (uint32_t sub = 0; sub < ctx->substeps; ++sub) {
        STAGE_BEGIN();
        phase_integrate(ctx, tid, nt);
        place_pins(ctx, sub, tid, nt);
        STAGE_END(integrate);

        for (uint32_t nl = 0; nl < s->nonlinear_iterations; ++nl) {
            STAGE_BEGIN();
            phase_local(ctx, tid, nt);
            STAGE_END(local);
            STAGE_BEGIN();
            for (uint32_t it = 0; it < s->linear_iterations; ++it) {
                for (uint32_t color = 0; color < ctx->ncolors; ++color) {
                    phase_global_color(ctx, color, tid, nt);
                    rbc_pool_barrier(pool);
                }
            }
            if (tid == 0) ctx->t.global += now_ms() - t0;
        }

        if (s->collider_count) {
            STAGE_BEGIN();
            phase_collide(ctx, tid, nt);
            STAGE_END(collide);
        }
        if (s->callback) {
            if (tid == 0) {
                t0 = now_ms();
                run_callback(ctx, sub);
                ctx->t.callback += now_ms() - t0;
            }
            rbc_pool_barrier(pool);
            if (ctx->result != RBC_OK) return;
        }

        STAGE_BEGIN();
        phase_check(ctx, tid, nt);
        rbc_pool_barrier(pool);
        if (tid == 0) {
            for (uint32_t th = 0; th < nt; ++th) {
                if (ctx->bad[th][0] < 0) continue;
                rbc_cloth_state *c = s->cloths[ctx->bad[th][0]];
                uint32_t i = (uint32_t)ctx->bad[th][1];
                ctx->result = fail(ctx->err, ctx->errlen, RBC_ERR_UNSTABLE,
                                   "cloth 0x%08x: vertex %u became non-finite at substep %u of %u "
                                   "(h = %g s, stiffness*h^2/mass up to %g); the world was "
                                   "restored to its state before the step",
                                   c->public_id, c->topo.to_host[i], sub, ctx->substeps,
                                   (double)ctx->h,
                                   (double)(c->topo.ksum[i] / c->w[i]));
                break;
            }
            if (ctx->result == RBC_OK) commit(s);
            t1 = now_ms();
            ctx->t.other += t1 - t0;
        }
        rbc_pool_barrier(pool);
        if (ctx->result != RBC_OK) return;
    }
#undef STAGE_BEGIN
#undef STAGE_END
}

int32_t rbc_solver_step(rbc_solver *s, float dt, char *err, size_t errlen) {
    double start = now_ms();
    step_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    ctx.s = s;
    ctx.substeps = s->substeps;
    ctx.h = dt / (float)s->substeps;
    ctx.result = RBC_OK;
    ctx.err = err;
    ctx.errlen = errlen;
    if (!(ctx.h > 0.0f))
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "dt / substeps = %g s underflows to zero", (double)ctx.h);

    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->pin_count; ++m)
            for (int a = 0; a < 3; ++a) c->pin_start[3 * m + a] = c->x[a][c->pin_idx[m]];
    }
    /* With one substep nothing is committed before the check, so the state before the
     * step is intact on failure; with several, earlier substeps are, so keep a copy. */
    int need_snapshot = ctx.substeps > 1;
    if (need_snapshot) snapshot(s, 0);

    for (uint32_t k = 0; k < s->cloth_count; ++k)
        if (s->cloths[k]->topo.ncolors > ctx.ncolors) ctx.ncolors = s->cloths[k]->topo.ncolors;

    rbc_pool_run(s->pool, step_spmd, &ctx);

    if (ctx.result != RBC_OK) {
        if (need_snapshot) snapshot(s, 1);
        return ctx.result;
    }
    ctx.t.step = now_ms() - start;
    s->last = ctx.t;
    s->last_substeps = ctx.substeps;
    s->last_nonlinear = ctx.substeps * s->nonlinear_iterations;
    s->last_linear = s->last_nonlinear * s->linear_iterations;
    s->step_count++;
    return RBC_OK;
}
