/* meshes.h -- quad meshes for the core tests: a grid, a cube surface (sphere
 * topology, valence 3 at the corners), a triangle mesh split into quads (valences
 * 3, 4 and 6, no grid structure at all), and a periodic torus (odd sizes are not
 * bipartite). */
#ifndef RBC_TEST_MESHES_H
#define RBC_TEST_MESHES_H
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "topology.h"

typedef struct test_mesh {
    uint32_t nv, nq;
    float *pos;
    uint32_t *quads;
} test_mesh;

/* The solver's input for a test mesh: the paper's material (1e-4 kg per vertex,
 * k = 1000 N/m), the given pins. */
static inline rbc_mesh_input mesh_input(const test_mesh *m, const uint32_t *pins, uint32_t npins) {
    rbc_mesh_input in;
    memset(&in, 0, sizeof in);
    in.vertex_count = m->nv;
    in.positions = m->pos;
    in.quad_count = m->nq;
    in.quads = m->quads;
    in.vertex_mass = 1e-4f;
    in.stiffness = 1000.0f;
    in.pins = pins;
    in.pin_count = npins;
    return in;
}

static inline void mesh_free(test_mesh *m) {
    free(m->pos);
    free(m->quads);
}

/* nx * ny vertices in the xz plane, spacing L, vertex i + nx j. */
static inline test_mesh mesh_grid(uint32_t nx, uint32_t ny, float L) {
    test_mesh m;
    m.nv = nx * ny;
    m.nq = (nx - 1) * (ny - 1);
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.quads = malloc(sizeof(uint32_t) * 4 * m.nq);
    for (uint32_t j = 0; j < ny; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            float *p = m.pos + 3 * (i + nx * j);
            p[0] = L * (float)i;
            p[1] = 0.0f;
            p[2] = L * (float)j;
        }
    uint32_t q = 0;
    for (uint32_t j = 0; j + 1 < ny; ++j)
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t a = i + nx * j;
            uint32_t *f = m.quads + 4 * q++;
            f[0] = a;
            f[1] = a + 1;
            f[2] = a + 1 + nx;
            f[3] = a + nx;
        }
    return m;
}

/* Torus of nu x nv quads (both directions wrap), radii 1 and 0.3. */
static inline test_mesh mesh_torus(uint32_t nu, uint32_t nv) {
    test_mesh m;
    m.nv = nu * nv;
    m.nq = nu * nv;
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.quads = malloc(sizeof(uint32_t) * 4 * m.nq);
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            double u = 6.283185307179586 * i / nu, v = 6.283185307179586 * j / nv;
            float *p = m.pos + 3 * (i + nu * j);
            p[0] = (float)((1.0 + 0.3 * cos(v)) * cos(u));
            p[1] = (float)(0.3 * sin(v));
            p[2] = (float)((1.0 + 0.3 * cos(v)) * sin(u));
        }
    for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
            uint32_t *f = m.quads + 4 * (i + nu * j);
            uint32_t i1 = (i + 1) % nu, j1 = (j + 1) % nv;
            f[0] = i + nu * j;
            f[1] = i1 + nu * j;
            f[2] = i1 + nu * j1;
            f[3] = i + nu * j1;
        }
    return m;
}

/* The surface of a cube, each face an n x n grid of quads, shared edges welded. */
static inline test_mesh mesh_cube(uint32_t n) {
    /* Vertices on a (n+1)^3 lattice that lie on the surface, indexed through a map. */
    uint32_t s = n + 1;
    int32_t *map = malloc(sizeof(int32_t) * s * s * s);
    test_mesh m;
    m.nv = 0;
    for (uint32_t z = 0; z < s; ++z)
        for (uint32_t y = 0; y < s; ++y)
            for (uint32_t x = 0; x < s; ++x) {
                int surf = x == 0 || y == 0 || z == 0 || x == n || y == n || z == n;
                map[x + s * (y + s * z)] = surf ? (int32_t)m.nv++ : -1;
            }
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    for (uint32_t z = 0; z < s; ++z)
        for (uint32_t y = 0; y < s; ++y)
            for (uint32_t x = 0; x < s; ++x) {
                int32_t v = map[x + s * (y + s * z)];
                if (v < 0) continue;
                m.pos[3 * v] = (float)x / n;
                m.pos[3 * v + 1] = (float)y / n;
                m.pos[3 * v + 2] = (float)z / n;
            }
    m.nq = 6 * n * n;
    m.quads = malloc(sizeof(uint32_t) * 4 * m.nq);
    uint32_t q = 0;
    /* For each axis a and side (0 or n), the face's two in-plane axes b, c. */
    for (int a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side)
            for (uint32_t i = 0; i < n; ++i)
                for (uint32_t j = 0; j < n; ++j) {
                    uint32_t corner[4][3];
                    const uint32_t di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
                    for (int k = 0; k < 4; ++k) {
                        corner[k][a] = side ? n : 0;
                        corner[k][(a + 1) % 3] = i + di[k];
                        corner[k][(a + 2) % 3] = j + dj[k];
                    }
                    uint32_t *f = m.quads + 4 * q++;
                    for (int k = 0; k < 4; ++k)
                        f[k] = (uint32_t)map[corner[k][0] + s * (corner[k][1] + s * corner[k][2])];
                }
    free(map);
    return m;
}

/* A triangulated n x n grid (each cell split on a diagonal, alternating so vertices
 * get valences 4, 6 and 8), every triangle split into three quads around its
 * centroid through its edge midpoints: an irregular all-quad mesh of disk topology
 * with valences 3 (centroids), 4 (midpoints) and up to 8. Positions are jittered
 * by a deterministic hash so no two edges have the same length. */
static inline test_mesh mesh_split_triangles(uint32_t n) {
    uint32_t s = n + 1, ntri = 2 * n * n;
    uint32_t *tri = malloc(sizeof(uint32_t) * 3 * ntri);
    uint32_t t = 0;
    for (uint32_t j = 0; j < n; ++j)
        for (uint32_t i = 0; i < n; ++i) {
            uint32_t a = i + s * j, b = a + 1, c = a + 1 + s, d = a + s;
            if ((i + j) & 1) {
                uint32_t t1[3] = {a, b, c}, t2[3] = {a, c, d};
                for (int k = 0; k < 3; ++k) tri[3 * t + k] = t1[k], tri[3 * (t + 1) + k] = t2[k];
            } else {
                uint32_t t1[3] = {a, b, d}, t2[3] = {b, c, d};
                for (int k = 0; k < 3; ++k) tri[3 * t + k] = t1[k], tri[3 * (t + 1) + k] = t2[k];
            }
            t += 2;
        }
    /* Edge midpoints: one vertex per unique edge, found with a dense (s*s)^2 map
     * replaced by a per-vertex small list (valence <= 8). */
    uint32_t nbase = s * s;
    uint32_t *edge_to = malloc(sizeof(uint32_t) * nbase * 8), *edge_mid = malloc(sizeof(uint32_t) * nbase * 8);
    uint8_t *edge_n = calloc(nbase, 1);
    test_mesh m;
    uint32_t maxv = nbase + 3 * ntri + ntri;
    m.pos = malloc(sizeof(float) * 3 * maxv);
    m.quads = malloc(sizeof(uint32_t) * 4 * 3 * ntri);
    for (uint32_t j = 0; j < s; ++j)
        for (uint32_t i = 0; i < s; ++i) {
            uint32_t v = i + s * j;
            uint32_t h = v * 2654435761u;
            m.pos[3 * v] = (float)i / n + 0.15f / n * (((h >> 8) & 255) / 255.0f - 0.5f);
            m.pos[3 * v + 1] = 0.0f;
            m.pos[3 * v + 2] = (float)j / n + 0.15f / n * (((h >> 16) & 255) / 255.0f - 0.5f);
        }
    m.nv = nbase;
    for (uint32_t k = 0; k < ntri; ++k) {
        uint32_t mid[3];
        for (int e = 0; e < 3; ++e) {
            uint32_t a = tri[3 * k + e], b = tri[3 * k + (e + 1) % 3];
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            uint32_t found = UINT32_MAX;
            for (uint32_t l = 0; l < edge_n[lo]; ++l)
                if (edge_to[8 * lo + l] == hi) found = edge_mid[8 * lo + l];
            if (found == UINT32_MAX) {
                found = m.nv++;
                for (int c = 0; c < 3; ++c)
                    m.pos[3 * found + c] = 0.5f * (m.pos[3 * lo + c] + m.pos[3 * hi + c]);
                edge_to[8 * lo + edge_n[lo]] = hi;
                edge_mid[8 * lo + edge_n[lo]] = found;
                edge_n[lo]++;
            }
            mid[e] = found;
        }
        uint32_t cen = m.nv++;
        for (int c = 0; c < 3; ++c)
            m.pos[3 * cen + c] = (m.pos[3 * tri[3 * k] + c] + m.pos[3 * tri[3 * k + 1] + c] +
                                  m.pos[3 * tri[3 * k + 2] + c]) / 3.0f;
        /* Quad at corner e: corner, mid of edge e, centroid, mid of the previous edge. */
        for (int e = 0; e < 3; ++e) {
            uint32_t *f = m.quads + 4 * (3 * k + e);
            f[0] = tri[3 * k + e];
            f[1] = mid[e];
            f[2] = cen;
            f[3] = mid[(e + 2) % 3];
        }
    }
    m.nq = 3 * ntri;
    free(tri);
    free(edge_to);
    free(edge_mid);
    free(edge_n);
    return m;
}
/* g with its vertices renumbered by a deterministic shuffle (an LCG from seed) and,
 * with flip_odd, every other quad wound backwards: the same mesh in a scattered host
 * order. */
static inline test_mesh mesh_shuffled(const test_mesh *g, uint32_t seed, int flip_odd) {
    uint32_t *perm = malloc(sizeof(uint32_t) * g->nv);
    for (uint32_t v = 0; v < g->nv; ++v) perm[v] = v;
    for (uint32_t v = g->nv - 1; v > 0; --v) {
        seed = seed * 1664525u + 1013904223u;
        uint32_t r = (seed >> 8) % (v + 1), tmp = perm[v];
        perm[v] = perm[r];
        perm[r] = tmp;
    }
    test_mesh m = {g->nv, g->nq, malloc(sizeof(float) * 3 * g->nv),
                   malloc(sizeof(uint32_t) * 4 * g->nq)};
    for (uint32_t v = 0; v < g->nv; ++v)
        for (int c = 0; c < 3; ++c) m.pos[3 * perm[v] + c] = g->pos[3 * v + c];
    for (uint32_t f = 0; f < g->nq; ++f)
        for (int k = 0; k < 4; ++k)
            m.quads[4 * f + k] = perm[g->quads[4 * f + ((flip_odd && (f & 1)) ? 3 - k : k)]];
    free(perm);
    return m;
}
#endif
