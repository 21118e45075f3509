/* test_game_loop.c -- ABI 1.10, what a game loop reads and does each frame (issue 21):
 * rbc_world_read_vertices (normals against analytic ones, interleaved output against
 * rbc_cloth_read_positions, several cloths, every bad entry refused with its index
 * and no buffer written), rbc_cloth_get_triangles and its revision (cuts, an import's
 * leftover triangles), rbc_cloth_transform (keep and reset velocity, pins, refusals),
 * the split step (bitwise the plain step, RBC_ERR_BUSY, errors and callbacks on the
 * step thread, destroy while stepping) and the host's task callbacks (bitwise the
 * world's own threads, with a serial executor and a threaded one). */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "abi_util.h"
#include "check.h"
#include "rbcloth.h"

#define PI 3.14159265358979323846

/* 2 ulp of a unit float: what normalising a float vector can leave of |n| - 1. */
#define UNIT_TOL (2.0 * FLT_EPSILON)

static int contains(const char *s, const char *part) { return strstr(s, part) != NULL; }

/* A hanging cloth (the ABI tests' grid, two corners pinned) in world w. */
static rbc_cloth_id hanging(rbc_world_id w, const test_grid *g) {
    const uint32_t pins[2] = {0, g->nx - 1};
    rbc_cloth_def d = test_grid_def(g, pins, 2);
    d.stiffness = 800.0f;
    d.vertex_mass = 2e-4f;
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(w, &d, &c), RBC_OK);
    return c;
}

static rbc_vertex_output output_for(rbc_cloth_id c, void *buf, size_t size, uint32_t stride,
                                    uint32_t pos, uint32_t nrm) {
    rbc_vertex_output o;
    CHECK_EQ(rbc_vertex_output_init(&o, (uint32_t)sizeof o), RBC_OK);
    o.cloth = c;
    o.buffer = buf;
    o.buffer_size = size;
    o.stride = stride;
    o.position_offset = pos;
    o.normal_offset = nrm;
    return o;
}

/* ------------------------------------------------------------------------- */
/* Normals                                                                   */
/* ------------------------------------------------------------------------- */

/* The defaults, and a flat sheet in the xz plane: (c - a) x (d - b) of the grid's quad
 * (i,j) (i+1,j) (i+1,j+1) (i,j+1) is (h,0,h) x (-h,0,h) = (0, -2h^2, 0), so every
 * vertex's normal is (0, -1, 0): its x and z are exact zeros, y within UNIT_TOL. */
static void test_flat_normals(void) {
    rbc_vertex_output d;
    memset(&d, 0x5A, sizeof d);
    CHECK_EQ(rbc_vertex_output_init(&d, (uint32_t)sizeof d), RBC_OK);
    CHECK_EQ(d.stride, 12);
    CHECK_EQ(d.position_offset, 0);
    CHECK_EQ(d.normal_offset, RBC_NO_ATTRIBUTE);
    CHECK(d.buffer == NULL && d.cloth == 0 && d.buffer_size == 0);
    CHECK_EQ(rbc_vertex_output_init(&d, (uint32_t)sizeof d - 4), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_vertex_output_init(NULL, (uint32_t)sizeof d), RBC_ERR_INVALID_ARGUMENT);

    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = test_world(&wd);
    test_grid g = test_grid_make(6, 5, 0.1f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_def cd = test_grid_def(&g, NULL, 0);
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    float nrm[3 * 30];
    rbc_vertex_output o = output_for(c, nrm, sizeof nrm, 12, RBC_NO_ATTRIBUTE, 0);
    CHECK_EQ(rbc_world_read_vertices(w, &o, 1), RBC_OK);
    CHECK_EQ(o.triangle_revision, 1);
    int exact = 1;
    for (uint32_t v = 0; v < g.vertex_count; ++v) {
        exact &= nrm[3 * v] == 0.0f && nrm[3 * v + 2] == 0.0f;
        CHECK_NEAR(nrm[3 * v + 1], -1.0, UNIT_TOL);
    }
    CHECK(exact);
    test_grid_free(&g);
    rbc_world_destroy(w);
}

/* A cylinder patch of radius R about the z axis: vertex (i, j) at angle
 * t_i = i * dt, (R sin t_i, R cos t_i, j * h). An interior vertex's four quads are
 * mirror images across the plane through the axis and the vertex, so their summed
 * vector area is radial: the normal is +-(sin t_i, cos t_i, 0) exactly but for float
 * rounding of the positions (|p| ~ 1: 6e-8 each) through edge vectors of length
 * ~0.1, a relative 1e-6 of the area; 1e-5 bounds that with room, where one wrong
 * corner would be off by about 0.1. Its sign: (c - a) x (d - b) of quad (0, 0). */
static void test_cylinder_normals(void) {
    enum { NX = 9, NY = 5 };
    const double R = 1.0, dth = 0.1, h = 0.1;
    float pos[3 * NX * NY];
    uint32_t quads[4 * (NX - 1) * (NY - 1)];
    for (uint32_t j = 0; j < NY; ++j)
        for (uint32_t i = 0; i < NX; ++i) {
            float *p = &pos[3 * (i + NX * j)];
            p[0] = (float)(R * sin(i * dth));
            p[1] = (float)(R * cos(i * dth));
            p[2] = (float)(j * h);
        }
    for (uint32_t j = 0; j + 1 < NY; ++j)
        for (uint32_t i = 0; i + 1 < NX; ++i) {
            uint32_t *q = &quads[4 * (i + (NX - 1) * j)];
            q[0] = i + NX * j, q[1] = i + 1 + NX * j, q[2] = i + 1 + NX * (j + 1);
            q[3] = i + NX * (j + 1);
        }
    /* The sign the formula gives: quad 0's (c - a) x (d - b), dotted with the radial
     * direction at its centre. */
    const float *a = &pos[3 * quads[0]], *b = &pos[3 * quads[1]], *cc = &pos[3 * quads[2]],
                *dd = &pos[3 * quads[3]];
    const double e[3] = {cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]};
    const double f[3] = {dd[0] - b[0], dd[1] - b[1], dd[2] - b[2]};
    const double n0[3] = {e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2],
                          e[0] * f[1] - e[1] * f[0]};
    const double sign = n0[0] * sin(0.5 * dth) + n0[1] * cos(0.5 * dth) > 0 ? 1.0 : -1.0;

    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = test_world(&wd);
    rbc_cloth_def cd = rbc_cloth_def_default();
    cd.vertex_count = NX * NY;
    cd.positions = pos;
    cd.quad_count = (NX - 1) * (NY - 1);
    cd.quads = quads;
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    float nrm[3 * NX * NY];
    rbc_vertex_output o = output_for(c, nrm, sizeof nrm, 12, RBC_NO_ATTRIBUTE, 0);
    CHECK_EQ(rbc_world_read_vertices(w, &o, 1), RBC_OK);
    double worst = 0.0;
    for (uint32_t j = 1; j + 1 < NY; ++j)
        for (uint32_t i = 1; i + 1 < NX; ++i) {
            const float *n = &nrm[3 * (i + NX * j)];
            const double want[3] = {sign * sin(i * dth), sign * cos(i * dth), 0.0};
            for (int k = 0; k < 3; ++k) {
                double d = fabs(n[k] - want[k]);
                if (d > worst) worst = d;
            }
        }
    CHECK(worst <= 1e-5);
    printf("cylinder normals: largest error %.3g (bound 1e-5), sign %+g\n", worst, sign);
    /* Every normal, edge ones too, is unit. */
    for (uint32_t v = 0; v < NX * NY; ++v) {
        const float *n = &nrm[3 * v];
        CHECK_NEAR(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]), 1.0,
                   UNIT_TOL);
    }
    rbc_world_destroy(w);
}

/* ------------------------------------------------------------------------- */
/* Interleaved output, several cloths, bad entries                           */
/* ------------------------------------------------------------------------- */

static void test_interleaved(void) {
    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = test_world(&wd);
    test_grid g1 = test_grid_make(12, 9, 0.05f, 0.0f, 1.0f, 0.0f);
    test_grid g2 = test_grid_make(5, 7, 0.05f, 1.0f, 1.0f, 0.0f);
    rbc_cloth_id c1 = hanging(w, &g1), c2 = hanging(w, &g2);
    for (int f = 0; f < 30; ++f) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    uint32_t n1 = 0, n2 = 0;
    float *p1 = test_read(w, c1, &n1), *p2 = test_read(w, c2, &n2);

    /* Cloth 1: position and normal interleaved (stride 24); cloth 2: a 32-byte vertex
     * with the normal at 0, the position at 16 and padding that must stay as it was. */
    const size_t s1 = 24 * (size_t)n1, s2 = 32 * (size_t)n2;
    unsigned char *b1 = malloc(s1), *b2 = malloc(s2);
    memset(b1, 0xAB, s1);
    memset(b2, 0xAB, s2);
    rbc_vertex_output o[2] = {output_for(c1, b1, s1, 24, 0, 12),
                              output_for(c2, b2, s2 - 4, 32, 16, 0)};
    /* The last vertex's bytes 28..31 are beyond the last attribute: s2 - 4 is exactly
     * what the entry needs. */
    CHECK_EQ(rbc_world_read_vertices(w, o, 2), RBC_OK);
    CHECK_EQ(o[0].triangle_revision, 1);
    CHECK_EQ(o[1].triangle_revision, 1);
    int same = 1, unit = 1, pad = 1;
    for (uint32_t v = 0; v < n1; ++v) {
        same &= memcmp(b1 + 24 * (size_t)v, &p1[3 * v], 12) == 0;
        float n[3];
        memcpy(n, b1 + 24 * (size_t)v + 12, 12);
        unit &= fabs(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]) - 1.0) <=
                UNIT_TOL;
    }
    for (uint32_t v = 0; v < n2; ++v) {
        same &= memcmp(b2 + 32 * (size_t)v + 16, &p2[3 * v], 12) == 0;
        pad &= test_bytes_are(b2, 32 * (size_t)v + 12, 32 * (size_t)v + 16, 0xAB) &&
               test_bytes_are(b2, 32 * (size_t)v + 28, 32 * (size_t)v + 32, 0xAB);
    }
    CHECK(same);
    CHECK(unit);
    CHECK(pad);

    /* Bad entries: each refused with its index and what was wrong, no byte written
     * to either buffer (entry 0 is good in every case). */
    memset(b1, 0xCD, s1);
    memset(b2, 0xCD, s2);
    int ncase = 0;
#define BAD(W, C, S, BODY)                                                   \
    do {                                                                     \
        rbc_vertex_output e[2] = {output_for(c1, b1, s1, 24, 0, 12),         \
                                  output_for(c2, b2, s2, 32, 16, 0)};        \
        rbc_vertex_output *x = &e[1];                                        \
        BODY;                                                                \
        rbc_result r = rbc_world_read_vertices(w, e, 2);                     \
        CHECK_EQ(r, C);                                                      \
        CHECK(contains(rbc_last_error(), "outputs[1]"));                     \
        CHECK(contains(rbc_last_error(), S));                                \
        if (r != (C) || !contains(rbc_last_error(), S))                      \
            fprintf(stderr, "case %s: %s\n", W, rbc_last_error());          \
        CHECK(test_bytes_are(b1, 0, s1, 0xCD) && test_bytes_are(b2, 0, s2, 0xCD)); \
        ncase++;                                                             \
    } while (0)
    BAD("stride", RBC_ERR_INVALID_ARGUMENT, "stride is 8", x->stride = 8);
    BAD("offset", RBC_ERR_INVALID_ARGUMENT, "past the stride", x->position_offset = 24);
    BAD("overlap", RBC_ERR_INVALID_ARGUMENT, "overlap", x->normal_offset = 8);
    BAD("small", RBC_ERR_INVALID_ARGUMENT, "buffer_size is", x->buffer_size = s2 - 5);
    BAD("null", RBC_ERR_INVALID_ARGUMENT, "buffer is NULL", x->buffer = NULL);
    BAD("size", RBC_ERR_INVALID_ARGUMENT, "struct_size", x->struct_size = 16);
    BAD("cloth", RBC_ERR_STALE_HANDLE, "null", x->cloth = 0);
    /* A cloth of another world. */
    rbc_world_id w2 = test_world(&wd);
    rbc_cloth_id other = hanging(w2, &g2);
    BAD("foreign", RBC_ERR_STALE_HANDLE, "belongs to world", x->cloth = other);
    CHECK_EQ(ncase, 8);
    CHECK_EQ(rbc_world_read_vertices(w, NULL, 1), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_world_read_vertices(w, NULL, 0), RBC_OK);
    /* Nothing asked: nothing but the revision is written. */
    rbc_vertex_output none = output_for(c1, b1, 0, 12, RBC_NO_ATTRIBUTE, RBC_NO_ATTRIBUTE);
    CHECK_EQ(rbc_world_read_vertices(w, &none, 1), RBC_OK);
    CHECK(test_bytes_are(b1, 0, s1, 0xCD));
    /* A destroyed cloth. */
    CHECK_EQ(rbc_cloth_destroy(w, c2), RBC_OK);
    rbc_vertex_output gone = output_for(c2, b2, s2, 32, 16, 0);
    CHECK_EQ(rbc_world_read_vertices(w, &gone, 1), RBC_ERR_STALE_HANDLE);
    CHECK(contains(rbc_last_error(), "outputs[0]") && contains(rbc_last_error(), "stale"));
    CHECK(test_bytes_are(b2, 0, s2, 0xCD));
    free(b1);
    free(b2);
    free(p1);
    free(p2);
    test_grid_free(&g1);
    test_grid_free(&g2);
    rbc_world_destroy(w2);
    rbc_world_destroy(w);
}

/* ------------------------------------------------------------------------- */
/* Triangles and their revision                                              */
/* ------------------------------------------------------------------------- */

static void test_triangles(void) {
    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = test_world(&wd);
    test_grid g = test_grid_make(5, 4, 0.1f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_id c = hanging(w, &g);
    size_t count = 0;
    uint32_t rev = 0;
    CHECK_EQ(rbc_cloth_get_triangles(w, c, NULL, 0, &count, &rev), RBC_OK);
    CHECK_EQ(count, 6 * g.quad_count);
    CHECK_EQ(rev, 1);
    uint32_t tris[6 * 12], quads[4 * 12];
    size_t nq = 0;
    CHECK_EQ(rbc_cloth_get_triangles(w, c, tris, count, &count, &rev), RBC_OK);
    CHECK_EQ(rbc_cloth_get_quads(w, c, quads, 4 * 12, &nq), RBC_OK);
    int split = nq == 4 * g.quad_count;
    for (uint32_t q = 0; split && q < g.quad_count; ++q) {
        const uint32_t *v = &quads[4 * q], *t = &tris[6 * q];
        split &= t[0] == v[0] && t[1] == v[1] && t[2] == v[2] && t[3] == v[0] && t[4] == v[2] &&
                 t[5] == v[3];
    }
    CHECK(split);
    /* Too small: refused, nothing written. */
    uint32_t small[6];
    memset(small, 0xEE, sizeof small);
    CHECK_EQ(rbc_cloth_get_triangles(w, c, small, 6, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "capacity is 6"));
    CHECK(test_bytes_are(small, 0, sizeof small, 0xEE));
    /* An interior edge, (1,1)-(2,1), borders two quads: both go, the revision moves
     * once; the same cut again removes nothing and leaves it. */
    const uint32_t pair[2] = {1 + 5 * 1, 2 + 5 * 1};
    uint32_t cut = 0;
    CHECK_EQ(rbc_cloth_cut(w, c, pair, 1, &cut), RBC_OK);
    CHECK_EQ(cut, 1);
    CHECK_EQ(rbc_cloth_get_triangles(w, c, NULL, 0, &count, &rev), RBC_OK);
    CHECK_EQ(count, 6 * (g.quad_count - 2));
    CHECK_EQ(rev, 2);
    CHECK_EQ(rbc_cloth_cut(w, c, pair, 1, &cut), RBC_OK);
    CHECK_EQ(cut, 0);
    CHECK_EQ(rbc_cloth_get_triangles(w, c, NULL, 0, &count, &rev), RBC_OK);
    CHECK_EQ(rev, 2);
    /* Normals still read (the cut vertices keep the faces they have). */
    float nrm[3 * 20];
    rbc_vertex_output o = output_for(c, nrm, sizeof nrm, 12, RBC_NO_ATTRIBUTE, 0);
    CHECK_EQ(rbc_world_read_vertices(w, &o, 1), RBC_OK);
    CHECK_EQ(o.triangle_revision, 2);
    CHECK_EQ(rbc_cloth_get_triangles(w, 0, NULL, 0, &count, &rev), RBC_ERR_STALE_HANDLE);
    test_grid_free(&g);
    rbc_world_destroy(w);
}

/* An imported mesh with a quad and a triangle: the cloth's triangles are the mesh's
 * (rbc_mesh_get_triangles), the triangle's normal counts at its corners, and a cut of
 * the triangle's own edge removes it. */
static void test_import_triangles(void) {
    char dir[] = "/tmp/rbc_game_loop_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0);
        return;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/quad_tri.obj", dir);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) return;
    /* A unit quad in the xz plane and a triangle hinged on its edge 2-3, folded up
     * to vertical. */
    fputs("v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0.5 1 1\nf 1 2 3 4\nf 4 3 5\n", f);
    fclose(f);
    rbc_mesh_import_def id = rbc_mesh_import_def_default();
    rbc_mesh_id m = 0;
    rbc_result r = rbc_mesh_import(path, &id, &m);
    CHECK_EQ(r, RBC_OK);
    if (r) {
        fprintf(stderr, "import: %s\n", rbc_last_error());
        return;
    }
    size_t mt = 0;
    uint32_t mtris[16], ctris[16];
    CHECK_EQ(rbc_mesh_get_triangles(m, mtris, 16, &mt), RBC_OK);
    CHECK_EQ(mt, 9);
    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id w = test_world(&wd);
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create_from_mesh(w, m, NULL, &c), RBC_OK);
    size_t ct = 0;
    uint32_t rev = 0;
    CHECK_EQ(rbc_cloth_get_triangles(w, c, ctris, 16, &ct, &rev), RBC_OK);
    CHECK_EQ(ct, mt);
    CHECK(memcmp(ctris, mtris, sizeof(uint32_t) * mt) == 0);
    CHECK_EQ(rev, 1);
    /* The shared edge's vertices sum the quad's normal and the triangle's (the
     * triangle (b - a) x (c - a) is twice its area, as the quad's diagonals' cross
     * product is twice its): not the quad's alone. The triangle's apex has only it. */
    uint32_t nv = 0;
    CHECK_EQ(rbc_cloth_get_vertex_count(w, c, &nv), RBC_OK);
    float pos[3 * 8], nrm[3 * 8];
    rbc_vertex_output o[2] = {output_for(c, nrm, sizeof nrm, 12, RBC_NO_ATTRIBUTE, 0),
                              output_for(c, pos, sizeof pos, 12, 0, RBC_NO_ATTRIBUTE)};
    CHECK_EQ(rbc_world_read_vertices(w, o, 2), RBC_OK);
    const uint32_t *t = &ctris[6];
    const float *a = &pos[3 * t[0]], *b = &pos[3 * t[1]], *cc = &pos[3 * t[2]];
    double e[3], g[3], tn[3];
    for (int k = 0; k < 3; ++k) e[k] = b[k] - a[k], g[k] = cc[k] - a[k];
    tn[0] = e[1] * g[2] - e[2] * g[1], tn[1] = e[2] * g[0] - e[0] * g[2],
    tn[2] = e[0] * g[1] - e[1] * g[0];
    const double l = sqrt(tn[0] * tn[0] + tn[1] * tn[1] + tn[2] * tn[2]);
    for (int k = 0; k < 3; ++k) CHECK_NEAR(nrm[3 * t[2] + k], tn[k] / l, 1e-6);
    /* Cut the apex off along one of the triangle's own edges. */
    const uint32_t pair[2] = {t[1], t[2]};
    uint32_t cut = 0;
    CHECK_EQ(rbc_cloth_cut(w, c, pair, 1, &cut), RBC_OK);
    CHECK_EQ(cut, 1);
    CHECK_EQ(rbc_cloth_get_triangles(w, c, ctris, 16, &ct, &rev), RBC_OK);
    CHECK_EQ(ct, 6);
    CHECK_EQ(rev, 2);
    CHECK_EQ(rbc_world_read_vertices(w, o, 2), RBC_OK);
    CHECK(nrm[3 * t[2]] == 0.0f && nrm[3 * t[2] + 1] == 0.0f && nrm[3 * t[2] + 2] == 0.0f);
    rbc_world_destroy(w);
    rbc_mesh_destroy(m);
    unlink(path);
    rmdir(dir);
}

/* ------------------------------------------------------------------------- */
/* Moving a whole cloth                                                      */
/* ------------------------------------------------------------------------- */

static void rotate(const double q[4], const float *p, const float *t, double out[3]) {
    const double x = q[0], y = q[1], z = q[2], s = q[3];
    const double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - z * s), 2 * (x * z + y * s),
                         2 * (x * y + z * s), 1 - 2 * (x * x + z * z), 2 * (y * z - x * s),
                         2 * (x * z - y * s), 2 * (y * z + x * s), 1 - 2 * (x * x + y * y)};
    for (int k = 0; k < 3; ++k)
        out[k] = R[3 * k] * p[0] + R[3 * k + 1] * p[1] + R[3 * k + 2] * p[2] + (t ? t[k] : 0.0);
}

static void test_transform(void) {
    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = 1;
    rbc_world_id wa = test_world(&wd);
    test_grid g = test_grid_make(10, 8, 0.05f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_id ca = hanging(wa, &g);
    for (int f = 0; f < 20; ++f) CHECK_EQ(rbc_world_step(wa, 1.0f / 60.0f), RBC_OK);
    const uint32_t n = g.vertex_count;
    float *x0 = malloc(12 * n), *q0 = malloc(12 * n), *x1 = malloc(12 * n), *q1 = malloc(12 * n);
    CHECK_EQ(rbc_cloth_get_state(wa, ca, x0, q0, 3 * (size_t)n), RBC_OK);

    /* Refusals first: the state stays bitwise as it was. */
    const float t[3] = {1.0f, 2.0f, 3.0f};
    const float bad_q[4] = {0.0f, 0.5f, 0.0f, 0.5f}, nan_t[3] = {0.0f, NAN, 0.0f};
    const double h = sqrt(0.5);
    const float qy[4] = {0.0f, (float)h, 0.0f, (float)h}; /* 90 degrees about y */
    CHECK_EQ(rbc_cloth_transform(wa, ca, t, bad_q, 0), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "not a unit quaternion"));
    CHECK_EQ(rbc_cloth_transform(wa, ca, nan_t, qy, 0), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "not finite"));
    CHECK_EQ(rbc_cloth_transform(wa, ca, t, qy, 7), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "flags is 7"));
    CHECK_EQ(rbc_cloth_transform(wa, ca, NULL, qy, 0), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_cloth_transform(wa, 0, t, qy, 0), RBC_ERR_STALE_HANDLE);
    CHECK_EQ(rbc_cloth_get_state(wa, ca, x1, q1, 3 * (size_t)n), RBC_OK);
    CHECK(memcmp(x0, x1, 12 * n) == 0 && memcmp(q0, q1, 12 * n) == 0);

    /* Keep velocity: x and q move by the same rigid map (computed in double and
     * rounded once: within an ulp of |p| <= 4 m, 4.8e-7; 1e-6 bounds it), so the
     * velocity (x - q) turns with the cloth, within two roundings of that size. */
    CHECK_EQ(rbc_cloth_transform(wa, ca, t, qy, RBC_TRANSFORM_KEEP_VELOCITY), RBC_OK);
    CHECK_EQ(rbc_cloth_get_state(wa, ca, x1, q1, 3 * (size_t)n), RBC_OK);
    const double qd[4] = {0.0, h, 0.0, h};
    double worst_p = 0.0, worst_v = 0.0;
    for (uint32_t v = 0; v < n; ++v) {
        double px[3], pq[3], dv[3];
        const float vel[3] = {x0[3 * v] - q0[3 * v], x0[3 * v + 1] - q0[3 * v + 1],
                              x0[3 * v + 2] - q0[3 * v + 2]};
        rotate(qd, &x0[3 * v], t, px);
        rotate(qd, &q0[3 * v], t, pq);
        rotate(qd, vel, NULL, dv);
        for (int k = 0; k < 3; ++k) {
            worst_p = fmax(worst_p, fabs(x1[3 * v + k] - px[k]));
            worst_p = fmax(worst_p, fabs(q1[3 * v + k] - pq[k]));
            worst_v = fmax(worst_v, fabs((x1[3 * v + k] - q1[3 * v + k]) - dv[k]));
        }
    }
    CHECK(worst_p <= 1e-6);
    CHECK(worst_v <= 2e-6);
    printf("transform: position error %.3g (bound 1e-6), velocity error %.3g m/step (2e-6)\n",
           worst_p, worst_v);
    /* Reset velocity: previous = current, exactly; a pinned corner is where its pin
     * moved to. */
    CHECK_EQ(rbc_cloth_transform(wa, ca, t, qy, RBC_TRANSFORM_RESET_VELOCITY), RBC_OK);
    CHECK_EQ(rbc_cloth_get_state(wa, ca, x1, q1, 3 * (size_t)n), RBC_OK);
    CHECK(memcmp(x1, q1, 12 * n) == 0);
    CHECK_EQ(rbc_world_step(wa, 1.0f / 60.0f), RBC_OK);
    float *xr = test_read(wa, ca, NULL);
    /* Pin 0 started at (0, 1, 0); two moves by (R, t) put it at R (R p + t) + t. */
    double once[3], twice[3];
    const float p0[3] = {0.0f, 1.0f, 0.0f};
    rotate(qd, p0, t, once);
    const float once_f[3] = {(float)once[0], (float)once[1], (float)once[2]};
    rotate(qd, once_f, t, twice);
    for (int k = 0; xr && k < 3; ++k) CHECK_NEAR(xr[k], twice[k], 2e-6);
    free(xr);
    free(x0);
    free(q0);
    free(x1);
    free(q1);
    test_grid_free(&g);
    rbc_world_destroy(wa);
}


/* A cloth at rest without gravity stays at rest where it was moved: a move that left
 * the previous positions or the pins behind would show as motion at once (a pin left
 * behind drags its corner back by the whole move, metres; a previous position left
 * behind is a velocity of metres per substep). Not exactly at rest: float positions
 * round by an ulp of their coordinates each substep and the solve and integrator
 * carry that into the velocity, so any cloth at rest creeps (the default solve's,
 * 1 m from the origin: about 1 mm in 30 steps). The reference is the creep of the
 * same cloth made at rest where the move puts it (world wb): the moved one must creep
 * less than ten times that, an order of magnitude of room for the different rounding
 * and four below what a pin or velocity left behind gives. (A twin falling under
 * gravity cannot be compared at rounding level: the falling sheet buckles, which
 * amplifies a one-ulp difference to millimetres within five steps.) */
static double creep(rbc_world_id w, rbc_cloth_id c, const float *from, uint32_t n, int steps) {
    for (int f = 0; f < steps; ++f) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    float *x = test_read(w, c, NULL);
    double worst = 0.0;
    for (size_t i = 0; x && i < 3 * (size_t)n; ++i) worst = fmax(worst, fabs(x[i] - from[i]));
    free(x);
    return worst;
}

static void test_transform_rest(void) {
    rbc_world_def wd = rbc_world_def_default();
    wd.gravity[1] = 0.0f;
    const float t[3] = {1.0f, 2.0f, 3.0f};
    const double h = sqrt(0.5);
    const float q[4] = {(float)h, 0.0f, 0.0f, (float)h}; /* 90 degrees about x */
    const double qd[4] = {h, 0.0, 0.0, h};
    for (uint32_t flags = 0; flags < 2; ++flags) {
        rbc_world_id wa = test_world(&wd), wb = test_world(&wd);
        test_grid g = test_grid_make(10, 8, 0.05f, 0.0f, 1.0f, 0.0f);
        const uint32_t n = g.vertex_count;
        rbc_cloth_id ca = hanging(wa, &g);
        float *moved = malloc(12 * (size_t)n);
        for (uint32_t v = 0; v < n; ++v) {
            double p[3];
            rotate(qd, &g.positions[3 * v], t, p);
            for (int k = 0; k < 3; ++k) moved[3 * v + k] = (float)p[k];
        }
        CHECK_EQ(rbc_cloth_transform(wa, ca, t, q, flags), RBC_OK);
        float *xa = test_read(wa, ca, NULL);
        /* R p + t within an ulp of coordinates below 4 m (the float quaternion is a
         * rounding away from qd). */
        double off = 0.0;
        for (size_t i = 0; xa && i < 3 * (size_t)n; ++i) off = fmax(off, fabs(xa[i] - moved[i]));
        CHECK(xa && off <= 4.8e-7);
        memcpy(g.positions, moved, 12 * (size_t)n);
        rbc_cloth_id cb = hanging(wb, &g);
        const double da = creep(wa, ca, moved, n, 5), db = creep(wb, cb, moved, n, 5);
        CHECK(da <= 10.0 * db + 1e-7);
        printf("transform at rest (flags %u): moved cloth crept %.3g m in 5 steps, one made "
               "there %.3g m (bound 10x)\n",
               flags, da, db);
        free(xa);
        free(moved);
        test_grid_free(&g);
        rbc_world_destroy(wa);
        rbc_world_destroy(wb);
    }
}

/* ------------------------------------------------------------------------- */
/* The split step                                                            */
/* ------------------------------------------------------------------------- */

static pthread_t g_main;
static int g_cb_calls, g_cb_on_main, g_cb_fail;

static int32_t RBC_CALL count_thread_cb(void *user, rbc_world_id world, float dt,
                                        const rbc_collision_cloth *cloths,
                                        uint32_t cloth_count) {
    (void)user, (void)world, (void)dt, (void)cloths, (void)cloth_count;
    g_cb_calls++;
    g_cb_on_main += pthread_equal(pthread_self(), g_main) != 0;
    return g_cb_fail ? -1 : 0;
}

typedef struct waiter {
    rbc_world_id w;
    rbc_result rc;
} waiter;

static void *wait_thread(void *arg) {
    waiter *x = arg;
    x->rc = rbc_world_step_wait(x->w);
    return NULL;
}

static void test_split_step(void) {
    g_main = pthread_self();
    rbc_world_def wd = rbc_world_def_default();
    rbc_world_id wa = test_world(&wd), wb = test_world(&wd);
    test_grid g = test_grid_make(16, 12, 0.05f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_id ca = hanging(wa, &g), cb = hanging(wb, &g);
    CHECK_EQ(rbc_world_step_wait(wa), RBC_OK); /* nothing running */
    int busy_ok = 1;
    for (int f = 0; f < 40; ++f) {
        CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
        CHECK_EQ(rbc_world_step(wb, 1.0f / 60.0f), RBC_OK);
        if (f == 3) {
            /* Stepping until step_wait, however far the step is: every other call on
             * the world, its cloths and colliders is refused and changes nothing. */
            float xyz[3 * 192];
            rbc_world_stats st;
            CHECK_EQ(rbc_world_stats_init(&st, (uint32_t)sizeof st), RBC_OK);
            const float grav[3] = {0.0f, 0.0f, 0.0f};
            busy_ok &= rbc_cloth_read_positions(wa, ca, xyz, sizeof xyz / 4, NULL) == RBC_ERR_BUSY;
            busy_ok &= contains(rbc_last_error(), "stepping");
            busy_ok &= rbc_world_step(wa, 0.01f) == RBC_ERR_BUSY;
            busy_ok &= rbc_world_step_begin(wa, 0.01f) == RBC_ERR_BUSY;
            busy_ok &= rbc_world_get_stats(wa, &st) == RBC_ERR_BUSY;
            busy_ok &= rbc_world_set_gravity(wa, grav) == RBC_ERR_BUSY;
            busy_ok &= rbc_cloth_set_pin(wa, ca, 0, NULL) == RBC_ERR_BUSY;
            rbc_vertex_output o = output_for(ca, xyz, sizeof xyz, 12, 0, RBC_NO_ATTRIBUTE);
            busy_ok &= rbc_world_read_vertices(wa, &o, 1) == RBC_ERR_BUSY;
            rbc_collider_def cd = rbc_collider_def_default();
            rbc_collider_id col = 0;
            busy_ok &= rbc_collider_create(wa, &cd, &col) == RBC_ERR_BUSY && col == 0;
        }
        CHECK_EQ(rbc_world_step_wait(wa), RBC_OK);
    }
    CHECK(busy_ok);
    CHECK(test_twins_same(wa, ca, wb, cb, 0, 0.0f));
    CHECK_EQ(rbc_world_step_begin(wa, -1.0f), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "dt is -1"));
    CHECK_EQ(rbc_world_step(wa, 1.0f / 60.0f), RBC_OK); /* not stepping after a refusal */

    /* Callbacks run on the step thread; a failing one fails the step, whose result and
     * message reach the thread that waits (here another thread), and the world is
     * as it was before the step. */
    CHECK_EQ(rbc_world_set_collision_callback(wa, count_thread_cb, NULL), RBC_OK);
    g_cb_calls = g_cb_on_main = 0;
    CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(rbc_world_step_wait(wa), RBC_OK);
    CHECK(g_cb_calls > 0);
    CHECK_EQ(g_cb_on_main, 0);
    float *before = test_read(wa, ca, NULL);
    g_cb_fail = 1;
    CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
    waiter x = {wa, RBC_OK};
    pthread_t th;
    pthread_create(&th, NULL, wait_thread, &x);
    pthread_join(th, NULL);
    CHECK_EQ(x.rc, RBC_ERR_CALLBACK);
    CHECK_EQ(rbc_world_step_wait(wa), RBC_OK); /* already waited for */
    float *after = test_read(wa, ca, NULL);
    CHECK(before && after && memcmp(before, after, 12 * (size_t)g.vertex_count) == 0);
    free(before);
    free(after);
    /* Two threads waiting for one failing step: one takes its result, the other
     * gets RBC_OK (the step it waited for is over), and neither hangs. */
    CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
    waiter two[2] = {{wa, RBC_OK}, {wa, RBC_OK}};
    pthread_t th2[2];
    for (int k = 0; k < 2; ++k) pthread_create(&th2[k], NULL, wait_thread, &two[k]);
    for (int k = 0; k < 2; ++k) pthread_join(th2[k], NULL);
    CHECK((two[0].rc == RBC_ERR_CALLBACK) + (two[1].rc == RBC_ERR_CALLBACK) == 1);
    CHECK((two[0].rc == RBC_OK) + (two[1].rc == RBC_OK) == 1);
    /* The message in the waiting thread's buffer: make the failure here. */
    g_cb_fail = 1;
    CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(rbc_world_step_wait(wa), RBC_ERR_CALLBACK);
    CHECK(contains(rbc_last_error(), "rbc_world_step_begin"));
    g_cb_fail = 0;

    /* Destroy while stepping: waits, then the ids are stale. */
    CHECK_EQ(rbc_world_set_collision_callback(wa, NULL, NULL), RBC_OK);
    CHECK_EQ(rbc_world_step_begin(wa, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(rbc_world_destroy(wa), RBC_OK);
    CHECK_EQ(rbc_world_step_wait(wa), RBC_ERR_STALE_HANDLE);
    CHECK_EQ(rbc_cloth_read_positions(wa, ca, NULL, 0, NULL), RBC_ERR_STALE_HANDLE);
    test_grid_free(&g);
    rbc_world_destroy(wb);
}


/* ------------------------------------------------------------------------- */
/* The host's job system                                                     */
/* ------------------------------------------------------------------------- */

/* Executors as engines have them. serial: runs every range inside enqueue (Box2D's
 * single-threaded default) and returns NULL. pool: K threads take ranges from a queue
 * (a job system). deferred: ranges run only inside finish_task, on the caller (a job
 * system whose workers are all busy: every item is late). sync: enqueue starts a
 * thread per range and joins them before it returns (a parallel-for that blocks). */
enum { EXEC_SERIAL, EXEC_POOL, EXEC_DEFERRED, EXEC_SYNC, EXEC_KINDS };
static const char *const exec_names[EXEC_KINDS] = {"serial", "pool", "deferred", "sync"};

#define EXEC_WORKERS 3
#define EXEC_QUEUE 64
typedef struct job {
    rbc_task_fn fn;
    uint32_t begin, end;
    void *ctx;
    int *pending;
} job;
typedef struct executor {
    int kind;
    pthread_mutex_t mu;
    pthread_cond_t cv, done;
    job queue[EXEC_QUEUE];
    int head, tail, quit;
    int pending; /* of the one task in flight (the library has one at a time) */
    pthread_t workers[EXEC_WORKERS];
    uint64_t enqueues, items, off_thread_calls;
    pthread_t stepper;
} executor;

static void *exec_worker(void *arg) {
    executor *e = arg;
    pthread_mutex_lock(&e->mu);
    for (;;) {
        while (e->head == e->tail && !e->quit) pthread_cond_wait(&e->cv, &e->mu);
        if (e->head == e->tail) break;
        job j = e->queue[e->head++ % EXEC_QUEUE];
        pthread_mutex_unlock(&e->mu);
        j.fn(j.begin, j.end, 1, j.ctx);
        pthread_mutex_lock(&e->mu);
        if (--*j.pending == 0) pthread_cond_broadcast(&e->done);
    }
    pthread_mutex_unlock(&e->mu);
    return NULL;
}

typedef struct sync_arg {
    rbc_task_fn fn;
    uint32_t k;
    void *ctx;
} sync_arg;
static void *sync_item(void *arg) {
    sync_arg *a = arg;
    a->fn(a->k, a->k + 1, a->k, a->ctx);
    return NULL;
}

static void *RBC_CALL exec_enqueue(rbc_task_fn fn, uint32_t count, uint32_t min_range, void *ctx,
                                   void *user) {
    executor *e = user;
    e->enqueues++;
    e->items += count;
    e->off_thread_calls += !pthread_equal(pthread_self(), e->stepper);
    CHECK(min_range >= 1 && count >= 1);
    switch (e->kind) {
    case EXEC_SERIAL:
        fn(0, count, 0, ctx);
        return NULL;
    case EXEC_SYNC: {
        pthread_t th[64];
        sync_arg a[64];
        for (uint32_t k = 0; k < count && k < 64; ++k) {
            a[k] = (sync_arg){fn, k, ctx};
            pthread_create(&th[k], NULL, sync_item, &a[k]);
        }
        for (uint32_t k = 0; k < count && k < 64; ++k) pthread_join(th[k], NULL);
        return NULL;
    }
    default:
        break;
    }
    pthread_mutex_lock(&e->mu);
    e->pending = 0;
    for (uint32_t b = 0; b < count; b += min_range) {
        uint32_t end = b + min_range < count ? b + min_range : count;
        e->queue[e->tail++ % EXEC_QUEUE] = (job){fn, b, end, ctx, &e->pending};
        e->pending++;
    }
    if (e->kind == EXEC_POOL) pthread_cond_broadcast(&e->cv);
    pthread_mutex_unlock(&e->mu);
    return e;
}

static void RBC_CALL exec_finish(void *handle, void *user) {
    executor *e = user;
    CHECK(handle == e);
    e->off_thread_calls += !pthread_equal(pthread_self(), e->stepper);
    pthread_mutex_lock(&e->mu);
    if (e->kind == EXEC_DEFERRED) {
        /* Run what is queued here, on the caller: every item is late. */
        while (e->head != e->tail) {
            job j = e->queue[e->head++ % EXEC_QUEUE];
            pthread_mutex_unlock(&e->mu);
            j.fn(j.begin, j.end, 0, j.ctx);
            pthread_mutex_lock(&e->mu);
            --*j.pending;
        }
    }
    while (e->pending) pthread_cond_wait(&e->done, &e->mu);
    pthread_mutex_unlock(&e->mu);
}

static void exec_start(executor *e, int kind) {
    memset(e, 0, sizeof *e);
    e->kind = kind;
    e->stepper = pthread_self();
    pthread_mutex_init(&e->mu, NULL);
    pthread_cond_init(&e->cv, NULL);
    pthread_cond_init(&e->done, NULL);
    if (kind == EXEC_POOL)
        for (int k = 0; k < EXEC_WORKERS; ++k) pthread_create(&e->workers[k], NULL, exec_worker, e);
}

static void exec_stop(executor *e) {
    pthread_mutex_lock(&e->mu);
    e->quit = 1;
    pthread_cond_broadcast(&e->cv);
    pthread_mutex_unlock(&e->mu);
    if (e->kind == EXEC_POOL)
        for (int k = 0; k < EXEC_WORKERS; ++k) pthread_join(e->workers[k], NULL);
    pthread_mutex_destroy(&e->mu);
    pthread_cond_destroy(&e->cv);
    pthread_cond_destroy(&e->done);
}

/* A 32 x 24 hanging cloth and a sphere it falls on, 40 steps at 1/60 s: the world's own
 * threads (1 and 2) and each executor give bitwise the same positions. */
static float *task_run(uint32_t threads, executor *e, uint32_t *used_max, uint32_t *n) {
    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = threads;
    if (e) {
        wd.enqueue_task = exec_enqueue;
        wd.finish_task = exec_finish;
        wd.task_user = e;
    }
    rbc_world_id w = test_world(&wd);
    test_grid g = test_grid_make(32, 24, 0.03f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_id c = hanging(w, &g);
    rbc_collider_def cd = rbc_collider_def_default();
    cd.shape = RBC_SHAPE_SPHERE;
    cd.radius = 0.2f;
    cd.position[0] = 0.45f, cd.position[1] = 0.7f, cd.position[2] = 0.35f;
    rbc_collider_id col = 0;
    CHECK_EQ(rbc_collider_create(w, &cd, &col), RBC_OK);
    *used_max = 0;
    for (int f = 0; f < 40; ++f) {
        CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
        uint32_t u = test_stats(w).thread_count;
        if (u > *used_max) *used_max = u;
    }
    float *x = test_read(w, c, n);
    test_grid_free(&g);
    rbc_world_destroy(w);
    return x;
}

static void test_host_tasks(void) {
    /* Both or neither. */
    rbc_world_def wd = rbc_world_def_default();
    wd.enqueue_task = exec_enqueue;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_ERR_INVALID_ARGUMENT);
    CHECK(contains(rbc_last_error(), "enqueue_task and finish_task"));
    CHECK_EQ(w, 0);
    /* A def of the 1.6 size has none (the fields past it are not read). */
    executor e;
    exec_start(&e, EXEC_POOL);
    wd.finish_task = exec_finish;
    wd.task_user = &e;
    wd.struct_size = RBC_WORLD_DEF_SIZE_V1_6;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_OK);
    test_grid g = test_grid_make(8, 8, 0.05f, 0.0f, 1.0f, 0.0f);
    hanging(w, &g);
    CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(e.enqueues, 0);
    rbc_world_destroy(w);
    test_grid_free(&g);
    exec_stop(&e);

    uint32_t n1 = 0, n = 0, used = 0;
    float *ref = task_run(1, NULL, &used, &n1);
    CHECK_EQ(used, 1);
    float *two = task_run(2, NULL, &used, &n);
    CHECK(ref && two && n == n1 && memcmp(ref, two, 12 * (size_t)n) == 0);
    free(two);
    for (int kind = 0; kind < EXEC_KINDS; ++kind)
        for (uint32_t threads = 2; threads <= 4; threads += 2) {
            exec_start(&e, kind);
            float *x = task_run(threads, &e, &used, &n);
            const int same = ref && x && n == n1 && memcmp(ref, x, 12 * (size_t)n) == 0;
            CHECK(same);
            CHECK(used >= 1 && used <= threads);
            CHECK(e.enqueues > 0);
            /* threads - 1 items for a step; the strain pass after it asks for as many
             * threads as joined the step. */
            CHECK(e.items >= e.enqueues && e.items <= e.enqueues * (threads - 1));
            CHECK_EQ(e.off_thread_calls, 0);
            /* Late items never run the solver's work: the deferred executor's and a
             * blocking one's steps run on the caller alone. */
            if (kind == EXEC_DEFERRED || kind == EXEC_SERIAL || kind == EXEC_SYNC)
                CHECK_EQ(used, 1);
            printf("host tasks: %s executor, %u threads asked: bitwise %s, at most %u joined a "
                   "step, %llu enqueues\n",
                   exec_names[kind], threads, same ? "equal" : "DIFFERENT", used,
                   (unsigned long long)e.enqueues);
            free(x);
            exec_stop(&e);
        }
    free(ref);
}

int main(void) {
    test_flat_normals();
    test_cylinder_normals();
    test_interleaved();
    test_triangles();
    test_import_triangles();
    test_transform();
    test_transform_rest();
    test_split_step();
    test_host_tasks();
    return check_report("abi_game_loop");
}
