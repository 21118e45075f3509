/* render.c -- normals, triangles and the rigid move of a cloth (render.h). */
#include "render.h"

#include <math.h>
#include <string.h>

#include "cloth.h"

int rbc_cloth_set_lone_triangles(const rbc_allocator *al, rbc_cloth_state *c,
                                 const uint32_t *tris, uint32_t count) {
    if (!count) return 0;
    uint32_t *t = rbc_mem_alloc(al, rbc_mul_size(3 * (size_t)count, sizeof(uint32_t)));
    if (!t) return -1;
    /* Internal indices, as the quads: tearing and normals work in that order. */
    for (size_t k = 0; k < 3 * (size_t)count; ++k) t[k] = c->topo.to_internal[tris[k]];
    rbc_mem_free(al, c->lone_tris, sizeof(uint32_t) * 3 * (size_t)c->lone_cap);
    c->lone_tris = t;
    c->lone_count = c->lone_cap = count;
    return 0;
}

int rbc_cloth_normals_reserve(const rbc_allocator *al, rbc_cloth_state *c) {
    if (c->normal_acc) return 0;
    c->normal_acc = rbc_mem_alloc(al, rbc_mul_size(3 * (size_t)c->topo.n, sizeof(float)));
    return c->normal_acc ? 0 : -1;
}

/* Twice the vector area of the face a b c d, (c - a) x (d - b): the diagonals' cross
 * product, the same from whichever corner it is taken, planar or not. A triangle
 * a b c is the face a b c a: (c - a) x (a - b) = (b - a) x (c - a). */
static inline void face_area2(const float *restrict x, const float *restrict y,
                              const float *restrict z, uint32_t a, uint32_t b, uint32_t c,
                              uint32_t d, float m[3]) {
    const float e0 = x[c] - x[a], e1 = y[c] - y[a], e2 = z[c] - z[a];
    const float f0 = x[d] - x[b], f1 = y[d] - y[b], f2 = z[d] - z[b];
    m[0] = e1 * f2 - e2 * f1;
    m[1] = e2 * f0 - e0 * f2;
    m[2] = e0 * f1 - e1 * f0;
}

/* Summed at each corner into SoA accumulators (nx, ny, nz, n floats each, in the
 * scratch), so that the normalisation below is one loop the compiler vectorizes
 * (render.c builds without errno or trapping math). */
const float *rbc_cloth_normals(rbc_cloth_state *c) {
    const size_t n = c->topo.n;
    float *restrict nx = c->normal_acc, *restrict ny = nx + n, *restrict nz = ny + n;
    const float *x = c->x[0], *y = c->x[1], *z = c->x[2];
    memset(nx, 0, 3 * n * sizeof(float));
    /* Quads and triangles apart: one loop with a branch per face was slower. */
    for (uint32_t q = 0; q < c->quad_count; ++q) {
        const uint32_t *v = &c->quads[4 * (size_t)q];
        float m[3];
        face_area2(x, y, z, v[0], v[1], v[2], v[3], m);
        for (int k = 0; k < 4; ++k) nx[v[k]] += m[0], ny[v[k]] += m[1], nz[v[k]] += m[2];
    }
    for (uint32_t t = 0; t < c->lone_count; ++t) {
        const uint32_t *v = &c->lone_tris[3 * (size_t)t];
        float m[3];
        face_area2(x, y, z, v[0], v[1], v[2], v[0], m);
        for (int k = 0; k < 3; ++k) nx[v[k]] += m[0], ny[v[k]] += m[1], nz[v[k]] += m[2];
    }
    for (size_t i = 0; i < n; ++i) {
        const float l2 = nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i];
        /* 0 where no face (or only faces of zero area) meets the vertex. Selects of
         * values, not a branch around the division: the loop vectorizes. */
        const float safe = l2 > 0.0f ? l2 : 1.0f, one = l2 > 0.0f ? 1.0f : 0.0f;
        const float s = one / sqrtf(safe);
        nx[i] *= s;
        ny[i] *= s;
        nz[i] *= s;
    }
    return nx;
}

size_t rbc_cloth_triangles_host(const rbc_cloth_state *c, uint32_t *out, size_t cap) {
    const uint32_t *h = c->topo.to_host;
    const size_t need = 6 * (size_t)c->quad_count + 3 * (size_t)c->lone_count;
    if (!out) return need;
    size_t m = 0;
    for (uint32_t q = 0; q < c->quad_count && m + 6 <= cap; ++q, m += 6) {
        const uint32_t *v = &c->quads[4 * (size_t)q];
        out[m] = h[v[0]], out[m + 1] = h[v[1]], out[m + 2] = h[v[2]];
        out[m + 3] = h[v[0]], out[m + 4] = h[v[2]], out[m + 5] = h[v[3]];
    }
    for (uint32_t k = 0; k < c->lone_count && m + 3 <= cap; ++k, m += 3) {
        const uint32_t *v = &c->lone_tris[3 * (size_t)k];
        out[m] = h[v[0]], out[m + 1] = h[v[1]], out[m + 2] = h[v[2]];
    }
    return need;
}

/* R p + t in double (a float rotation of a float point rounds once at the end), so
 * the same move of x and q keeps their difference, the velocity, as exact as floats
 * allow. */
static void move_point(const double R[9], const float t[3], float *px, float *py, float *pz) {
    const double x = *px, y = *py, z = *pz;
    *px = (float)(R[0] * x + R[1] * y + R[2] * z + t[0]);
    *py = (float)(R[3] * x + R[4] * y + R[5] * z + t[1]);
    *pz = (float)(R[6] * x + R[7] * y + R[8] * z + t[2]);
}

void rbc_cloth_move(rbc_cloth_state *c, const float t[3], const float quat[4],
                    int reset_velocity) {
    /* Normalised here: the plugin accepts |q| within 1e-3 of 1. */
    double qx = quat[0], qy = quat[1], qz = quat[2], qw = quat[3];
    const double l = sqrt(qx * qx + qy * qy + qz * qz + qw * qw);
    qx /= l, qy /= l, qz /= l, qw /= l;
    const double R[9] = {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw),
                         2 * (qx * qz + qy * qw),     2 * (qx * qy + qz * qw),
                         1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw),
                         2 * (qx * qz - qy * qw),     2 * (qy * qz + qx * qw),
                         1 - 2 * (qx * qx + qy * qy)};
    for (uint32_t i = 0; i < c->topo.n; ++i) {
        move_point(R, t, &c->x[0][i], &c->x[1][i], &c->x[2][i]);
        if (reset_velocity) {
            c->q[0][i] = c->x[0][i];
            c->q[1][i] = c->x[1][i];
            c->q[2][i] = c->x[2][i];
        } else {
            move_point(R, t, &c->q[0][i], &c->q[1][i], &c->q[2][i]);
        }
    }
    for (uint32_t k = 0; k < c->pin_count; ++k) {
        float *g = &c->pin_target[3 * (size_t)k], *s = &c->pin_start[3 * (size_t)k];
        move_point(R, t, &g[0], &g[1], &g[2]);
        move_point(R, t, &s[0], &s[1], &s[2]);
    }
    /* The warm start and the last substep's system describe the old place; the
     * height changed, so the energy account is rebuilt, keeping its slack. */
    c->system_valid = 0;
    rbc_cloth_state_energy_invalidate(c, 1);
}
