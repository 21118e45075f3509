/* Cloth-cloth and self contact (core/clothcontact.c). The test plays the solver: each
 * substep p = x + a prescribed displacement (pinned: p = x), detect, a few project
 * passes, friction where asked, then x = p.
 *  1. a particle crossing a triangle of another cloth by 10 thicknesses in one
 *     substep is found and put back on its starting side at >= thickness; so is one
 *     moving so far that its box is beyond the hash (brute-force path), a triangle
 *     sweeping through a particle, and a particle flying through another;
 *  2. two parallel 20x20 grids pressed into each other for 50 substeps never swap
 *     sides, and keep the thickness to the measured residual;
 *  3. four stacked layers pressed together keep their order;
 *  4. a grid folded onto itself keeps its halves apart; flat at rest it has no
 *     contacts (and with a wider margin, none that acts);
 *  5. friction: mu large stops a sliding particle, mu = 0 leaves its tangential
 *     motion bitwise alone, mu in between shortens it by mu * the normal correction;
 *     on a free triangle the relative slip is removed and momentum kept;
 *  6. pinned vertices never move;
 *  7. determinism: fresh objects, a repeated call and grown buffers give bitwise
 *     equal results; a repeated detect of the same scene allocates nothing; a query
 *     that scans every object gives the bits of the same query through the hash;
 *  8. a failing allocator (every k-th allocation) gives RBC_ERR_OUT_OF_MEMORY and
 *     leaks nothing;
 *  9. the fail-safe moves an impact zone rigidly by its mean motion in its first
 *     round, and leaves a crossing that was there at x alone.
 * Prints the time of detect and of one project pass for four 64x64 layers (16K
 * vertices).
 */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "check.h"
#include "clothcontact.h"
#include "rbcloth.h"

/* ---- scenes ---------------------------------------------------------------------- */

/* A grid of nx x nz vertices in a plane y = const, spacing L, two triangles per quad
 * with normals +y; d: the prescribed displacement per substep. */
typedef struct sheet {
    uint32_t n, nx, nz, nt;
    float *x[3], *p[3], *rest[3], *d[3];
    float *mass;
    uint8_t *pinned;
    uint32_t *tris;
} sheet;

static sheet sheet_grid(uint32_t nx, uint32_t nz, float L, float ox, float oy, float oz) {
    sheet s;
    memset(&s, 0, sizeof s);
    s.nx = nx, s.nz = nz, s.n = nx * nz, s.nt = 2 * (nx - 1) * (nz - 1);
    for (int k = 0; k < 3; ++k) {
        s.x[k] = calloc(s.n, sizeof(float));
        s.p[k] = calloc(s.n, sizeof(float));
        s.rest[k] = calloc(s.n, sizeof(float));
        s.d[k] = calloc(s.n, sizeof(float));
    }
    s.mass = malloc(sizeof(float) * s.n);
    s.pinned = calloc(s.n, 1);
    s.tris = malloc(sizeof(uint32_t) * 3 * s.nt);
    for (uint32_t j = 0; j < nz; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            uint32_t v = i + nx * j;
            s.rest[0][v] = s.x[0][v] = s.p[0][v] = ox + L * (float)i;
            s.rest[1][v] = s.x[1][v] = s.p[1][v] = oy;
            s.rest[2][v] = s.x[2][v] = s.p[2][v] = oz + L * (float)j;
            s.mass[v] = 1e-4f;
        }
    uint32_t t = 0;
    for (uint32_t j = 0; j + 1 < nz; ++j)
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t a = i + nx * j, b = a + 1, c = a + 1 + nx, dd = a + nx;
            /* (d - a) x (c - a) and (c - a) x (b - a) are +y for the grid above. */
            uint32_t *f = s.tris + 3 * t;
            f[0] = a, f[1] = dd, f[2] = c;
            f[3] = a, f[4] = c, f[5] = b;
            t += 2;
        }
    return s;
}

static void sheet_free(sheet *s) {
    for (int k = 0; k < 3; ++k) {
        free(s->x[k]);
        free(s->p[k]);
        free(s->rest[k]);
        free(s->d[k]);
    }
    free(s->mass);
    free(s->pinned);
    free(s->tris);
}

static rbc_contact_body body_of(sheet *s, float thickness, float mu, int self, int others) {
    rbc_contact_body b = {.n = s->n, .mass = s->mass, .pinned = s->pinned, .tri_count = s->nt,
                          .tris = s->tris, .thickness = thickness, .friction = mu, .self = self,
                          .others = others};
    for (int k = 0; k < 3; ++k) {
        b.p[k] = s->p[k];
        b.x[k] = s->x[k];
        b.rest[k] = s->rest[k];
    }
    return b;
}

/* One particle as a body: x, p its 3 coordinates at the start and predicted; with the
 * other bodies, not itself, no friction. mass, pinned: NULL as in rbc_contact_body. */
static rbc_contact_body particle_body(float *x, float *p, const float *mass, const uint8_t *pinned,
                                      float thickness) {
    rbc_contact_body b = {.n = 1, .mass = mass, .pinned = pinned, .thickness = thickness,
                          .others = 1};
    for (int k = 0; k < 3; ++k) b.x[k] = &x[k], b.p[k] = &p[k];
    return b;
}

/* One triangle as a body: its corners' coordinates x[axis][corner] at the start and p
 * predicted, tri their order; otherwise as particle_body. */
static rbc_contact_body triangle_body(float x[3][3], float p[3][3], const float *mass,
                                      const uint8_t *pinned, const uint32_t *tri,
                                      float thickness) {
    rbc_contact_body b = {.n = 3, .mass = mass, .pinned = pinned, .tri_count = 1, .tris = tri,
                          .thickness = thickness, .others = 1};
    for (int k = 0; k < 3; ++k) b.x[k] = x[k], b.p[k] = p[k];
    return b;
}

/* A contact object on the default allocator (it keeps a copy). */
static rbc_clothcontact *new_contact(void) {
    rbc_allocator al = rbc_allocator_default();
    rbc_clothcontact *cc = NULL;
    CHECK_EQ(rbc_clothcontact_create(&al, &cc), RBC_OK);
    return cc;
}

/* One substep as the solver would run it. Returns the violation left after the
 * passes (measured, nothing moved) in *left. */
static int32_t substep(rbc_clothcontact *cc, sheet *s, rbc_contact_body *b, uint32_t count,
                       float margin, int passes, int friction, float *left) {
    for (uint32_t m = 0; m < count; ++m)
        for (int k = 0; k < 3; ++k)
            for (uint32_t i = 0; i < s[m].n; ++i)
                s[m].p[k][i] = s[m].x[k][i] + (s[m].pinned[i] ? 0.0f : s[m].d[k][i]);
    int32_t r = rbc_clothcontact_detect(cc, b, count, margin);
    if (r != RBC_OK) return r;
    for (int it = 0; it < passes; ++it) rbc_clothcontact_project(cc, b, count);
    if (left) *left = rbc_clothcontact_violation(cc, b, count);
    if (friction) rbc_clothcontact_friction(cc, b, count);
    for (uint32_t m = 0; m < count; ++m)
        for (int k = 0; k < 3; ++k) memcpy(s[m].x[k], s[m].p[k], sizeof(float) * s[m].n);
    return RBC_OK;
}

/* ---- geometry for the checks (independent of the library's) ---------------------- */

/* Distance from p to triangle abc, by brute force over the face and the three edges. */
static double seg_dist(const double p[3], const double a[3], const double b[3]) {
    double ab[3], ap[3], t = 0.0, l2 = 0.0, d = 0.0;
    for (int k = 0; k < 3; ++k) ab[k] = b[k] - a[k], ap[k] = p[k] - a[k], l2 += ab[k] * ab[k],
                                t += ab[k] * ap[k];
    t = l2 > 0.0 ? fmin(1.0, fmax(0.0, t / l2)) : 0.0;
    for (int k = 0; k < 3; ++k) d += (ap[k] - t * ab[k]) * (ap[k] - t * ab[k]);
    return sqrt(d);
}

static double tri_dist(const double p[3], const double a[3], const double b[3], const double c[3]) {
    double e1[3], e2[3], n[3], r[3];
    for (int k = 0; k < 3; ++k) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], r[k] = p[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    double best = fmin(seg_dist(p, a, b), fmin(seg_dist(p, b, c), seg_dist(p, c, a)));
    if (nn > 0.0) {
        double h = (r[0] * n[0] + r[1] * n[1] + r[2] * n[2]) / nn, q[3];
        for (int k = 0; k < 3; ++k) q[k] = p[k] - h * n[k] / nn;
        /* Inside if q is on the inner side of every edge. */
        const double *v[3] = {a, b, c};
        int inside = 1;
        for (int e = 0; e < 3 && inside; ++e) {
            const double *u = v[e], *w = v[(e + 1) % 3];
            double f[3], g[3], x[3];
            for (int k = 0; k < 3; ++k) f[k] = w[k] - u[k], g[k] = q[k] - u[k];
            x[0] = f[1] * g[2] - f[2] * g[1];
            x[1] = f[2] * g[0] - f[0] * g[2];
            x[2] = f[0] * g[1] - f[1] * g[0];
            inside = x[0] * n[0] + x[1] * n[1] + x[2] * n[2] >= 0.0;
        }
        if (inside) best = fmin(best, fabs(h));
    }
    return best;
}

/* Signed distance of p from the plane of abc, normal (b - a) x (c - a). */
static double plane_dist(const double p[3], const double a[3], const double b[3],
                         const double c[3]) {
    double n[3], e1[3], e2[3];
    for (int k = 0; k < 3; ++k) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    return ((p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2]) / nn;
}

static void vert(const sheet *s, uint32_t i, double v[3]) {
    for (int k = 0; k < 3; ++k) v[k] = s->p[k][i];
}

/* How vertex i of s lies against sheet o (triangles selected by use, or all if NULL):
 * *gap: the smallest height of the vertex above a triangle whose xz projection holds
 * it (+inf if none does), *dist: its distance to the nearest triangle within reach. */
static void against(const sheet *s, uint32_t i, const sheet *o, const uint8_t *use, double reach,
                    double *gap, double *dist) {
    double P[3];
    vert(s, i, P);
    *gap = INFINITY;
    *dist = INFINITY;
    for (uint32_t t = 0; t < o->nt; ++t) {
        if (use && !use[t]) continue;
        const uint32_t *f = o->tris + 3 * t;
        double A[3], B[3], C[3];
        vert(o, f[0], A);
        vert(o, f[1], B);
        vert(o, f[2], C);
        double lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
            lo[k] = fmin(A[k], fmin(B[k], C[k])) - reach;
            hi[k] = fmax(A[k], fmax(B[k], C[k])) + reach;
        }
        if (P[0] < lo[0] || P[0] > hi[0] || P[2] < lo[2] || P[2] > hi[2]) continue;
        if (P[1] >= lo[1] && P[1] <= hi[1]) *dist = fmin(*dist, tri_dist(P, A, B, C));
        /* Barycentric coordinates in the xz plane. */
        double den = (B[2] - C[2]) * (A[0] - C[0]) + (C[0] - B[0]) * (A[2] - C[2]);
        if (fabs(den) < 1e-18) continue;
        double l1 = ((B[2] - C[2]) * (P[0] - C[0]) + (C[0] - B[0]) * (P[2] - C[2])) / den;
        double l2 = ((C[2] - A[2]) * (P[0] - C[0]) + (A[0] - C[0]) * (P[2] - C[2])) / den;
        double l3 = 1.0 - l1 - l2;
        if (l1 < 0.0 || l2 < 0.0 || l3 < 0.0) continue;
        *gap = fmin(*gap, P[1] - (l1 * A[1] + l2 * B[1] + l3 * C[1]));
    }
}

/* ---- 1. a fast particle through a triangle -------------------------------------- */

static void test_fast_particle(void) {
    const float th = 0.004f;
    rbc_clothcontact *cc = new_contact();
    /* Triangle abc in y = 0, normal (b - a) x (c - a) = (0.1, 0, 0) x (0, 0, 0.1) =
     * (0, -0.01, 0): the particle above it is on side -1. */
    float tx[3][3] = {{0.0f, 0.1f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.1f}};
    float tp[3][3], tm[3] = {1e-4f, 1e-4f, 1e-4f};
    uint8_t tpin[3] = {0, 0, 0};
    const uint32_t tri[3] = {0, 1, 2};
    float px[3], pp[3], pm = 1e-4f;
    uint8_t ppin = 0;
    for (int variant = 0; variant < 4; ++variant) {
        /* 0: free triangle, hit at the centroid; 1: pinned triangle, hit off centre;
         * 2: the triangle rises while the particle falls; 3: everything pinned. */
        const float hx = variant == 1 ? 0.07f : 0.1f / 3.0f, hz = variant == 1 ? 0.02f : 0.1f / 3.0f;
        for (int k = 0; k < 3; ++k) {
            for (int c = 0; c < 3; ++c) tp[k][c] = tx[k][c] + (variant == 2 && k == 1 ? 3.0f * th : 0.0f);
            tpin[k] = variant == 1 || variant == 3;
        }
        ppin = variant == 3;
        px[0] = pp[0] = hx, px[2] = pp[2] = hz;
        px[1] = 2.0f * th;
        pp[1] = px[1] - 10.0f * th; /* through it by 8 thicknesses */
        rbc_contact_body b[2] = {particle_body(px, pp, &pm, &ppin, th),
                                 triangle_body(tx, tp, tm, tpin, tri, th)};
        CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
        CHECK_EQ(rbc_clothcontact_count(cc), 1);
        const rbc_contact *c = rbc_clothcontact_list(cc);
        CHECK(c[0].kind == RBC_CONTACT_VT && c[0].body_a == 0 && c[0].body_b == 1);
        CHECK(c[0].side == -1.0f);
        float tp0[3][3];
        memcpy(tp0, tp, sizeof tp);
        const float before = rbc_clothcontact_project(cc, b, 2);
        /* The plane stays level (the corners move together in variants 0 and 2: equal
         * weights, 1/3 to rounding, and masses; pinned in 1 and 3), so one pass solves
         * the one constraint up to float rounding of a few operations on coordinates
         * < 0.1 m: well under 1e-6 m. */
        double P[3] = {pp[0], pp[1], pp[2]}, Q[3][3];
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) Q[j][k] = tp[k][j];
        const double dist = tri_dist(P, Q[0], Q[1], Q[2]);
        const int above = P[1] > Q[0][1] && P[1] > Q[1][1] && P[1] > Q[2][1];
        if (variant == 3) {
            CHECK(before > 0.0f);
            CHECK(pp[1] == px[1] - 10.0f * th); /* nothing can move */
            CHECK(memcmp(tp, tp0, sizeof tp) == 0);
        } else {
            CHECK_NEAR(before, variant == 2 ? 12.0f * th : 9.0f * th, 1e-6);
            CHECK(above);
            CHECK(dist >= th - 1e-6);
            CHECK(rbc_clothcontact_violation(cc, b, 2) <= 1e-6f);
        }
        if (variant == 1) CHECK(memcmp(tp, tp0, sizeof tp) == 0);
        if (variant == 0) {
            /* Momentum along y is kept: particle up by 3/4 of the violation, each corner
             * down by 1/4 (weights 1/3, den = 1/m (1 + 3 / 9)). Each term is ~1e-4 kg x
             * 0.03 m = 3e-6 kg m, rounded to float (6e-8 relative): 1e-12 covers it. */
            CHECK_NEAR(pm * (pp[1] - (px[1] - 10.0f * th)) + 3.0f * tm[0] * tp[1][0], 0.0, 1e-12);
        }
    }
    /* The same fall beside the triangle (outside it by more than the thickness +
     * margin): no contact. */
    px[0] = pp[0] = 0.2f;
    px[1] = 2.0f * th, pp[1] = -8.0f * th;
    rbc_contact_body b[2] = {particle_body(px, pp, NULL, NULL, th),
                             triangle_body(tx, tx, NULL, NULL, tri, th)};
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
    CHECK_EQ(rbc_clothcontact_count(cc), 0);
    /* Without others on one side: no contact either. */
    px[0] = pp[0] = 0.03f;
    b[1].others = 0;
    b[1].self = 1;
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
    CHECK_EQ(rbc_clothcontact_count(cc), 0);
    rbc_clothcontact_destroy(cc);
}

/* A particle (or a triangle) moving so far in one substep that its swept box covers
 * more than the hash's limit of cells: it is tested by brute force, and caught all
 * the same. Vertex-triangle both ways round, and vertex-vertex in both body orders. */
static void test_far_motion(void) {
    const float th = 0.004f;
    rbc_clothcontact *cc = new_contact();
    /* A 20x20 grid, L = 1 cm (cells of 1.4 cm), and a particle that crosses it at
     * the centroid of triangle 100 after moving 0.33 m along every axis (24^3 cells). */
    sheet g = sheet_grid(20, 20, 0.01f, 0.0f, 0.0f, 0.0f);
    const uint32_t *f = g.tris + 3 * 100;
    float cx = 0.0f, cz = 0.0f;
    for (int c = 0; c < 3; ++c) cx += g.x[0][f[c]] / 3.0f, cz += g.x[2][f[c]] / 3.0f;
    float px[3] = {cx - 0.3f, 0.3f, cz - 0.3f}, pp[3] = {cx + 0.03f, -0.03f, cz + 0.03f};
    float pm = 1e-4f;
    uint8_t ppin = 0;
    rbc_contact_body b[2] = {body_of(&g, th, 0.0f, 0, 1), particle_body(px, pp, &pm, &ppin, th)};
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
    int found = 0;
    const rbc_contact *l = rbc_clothcontact_list(cc);
    for (uint32_t m = 0; m < rbc_clothcontact_count(cc); ++m)
        found += l[m].kind == RBC_CONTACT_VT && l[m].body_a == 1 && l[m].body_b == 0 && l[m].b == 100;
    CHECK_EQ(found, 1);
    /* It ends 4 cm to the side of triangle 100 (and 3 cm under the grid), where no
     * other triangle knows it: this contact alone puts it back over the plane. */
    for (int it = 0; it < 8; ++it) rbc_clothcontact_project(cc, b, 2);
    float left = rbc_clothcontact_violation(cc, b, 2);
    double P[3] = {pp[0], pp[1], pp[2]}, Q[3][3];
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) Q[c][k] = g.p[k][f[c]];
    printf("far motion: particle %.3g mm over the plane of the triangle it crossed after 8 "
           "passes (thickness %.3g mm, violation left %.3g mm)\n",
           plane_dist(P, Q[0], Q[1], Q[2]) * 1e3, th * 1e3, left * 1e3);
    CHECK(plane_dist(P, Q[0], Q[1], Q[2]) >= th - left - 1e-6);
    CHECK(left <= 0.25f * th);

    /* The other way round: a triangle sweeps down 0.33 m and sideways 0.3 m through a
     * particle at rest (it crosses the particle's height where the particle is under
     * its centroid): the particle keeps the side it was on (below). A grid far away
     * (y = 5 m) keeps the cells small, so the triangle's box is over the limit. */
    float tx[3][3] = {{0.5f, 0.6f, 0.5f}, {0.3f, 0.3f, 0.3f}, {0.5f, 0.5f, 0.6f}};
    float tp[3][3] = {{0.8f, 0.9f, 0.8f}, {-0.03f, -0.03f, -0.03f}, {0.8f, 0.8f, 0.9f}};
    const uint32_t tri[3] = {0, 2, 1}; /* (c - a) x (b - a): +y */
    float tm[3] = {1e-4f, 1e-4f, 1e-4f};
    uint8_t tpin[3] = {0, 0, 0};
    const float s_cross = 0.3f / 0.33f, q0 = 0.5f + 0.3f * s_cross + 0.1f / 3.0f;
    float qx[3] = {q0, 0.0f, q0}, qp[3];
    memcpy(qp, qx, sizeof qp);
    sheet far = sheet_grid(20, 20, 0.01f, 0.0f, 5.0f, 0.0f);
    rbc_contact_body t[3] = {triangle_body(tx, tp, tm, tpin, tri, th),
                             particle_body(qx, qp, &pm, &ppin, th),
                             body_of(&far, th, 0.0f, 0, 1)};
    CHECK_EQ(rbc_clothcontact_detect(cc, t, 3, 0.001f), RBC_OK);
    CHECK_EQ(rbc_clothcontact_count(cc), 1);
    CHECK(rbc_clothcontact_list(cc)[0].side == -1.0f);
    for (int it = 0; it < 8; ++it) rbc_clothcontact_project(cc, t, 3);
    left = rbc_clothcontact_violation(cc, t, 3);
    double Qp[3] = {qp[0], qp[1], qp[2]}, T3[3][3];
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) T3[c][k] = tp[k][tri[c]];
    /* Under the plane ((b - a) x (c - a) is +y): its side at x. */
    CHECK(-plane_dist(Qp, T3[0], T3[1], T3[2]) >= th - left - 1e-6);
    CHECK(left <= 0.25f * th);

    /* Vertex-vertex: a particle flying 0.33 m per axis past (through) one at rest. */
    for (int order = 0; order < 2; ++order) {
        float ax[3] = {-0.3f, -0.3f, -0.3f}, ap[3] = {0.03f, 0.03f, 0.03f};
        float bx[3] = {0.0f, 0.0f, 0.0f}, bp[3] = {0.0f, 0.0f, 0.0f};
        float ma = 1e-4f, mb = 1e-4f;
        rbc_contact_body v[2];
        v[order] = particle_body(ax, ap, &ma, NULL, th);     /* the fast one */
        v[1 - order] = particle_body(bx, bp, &mb, NULL, th); /* the one at rest */
        CHECK_EQ(rbc_clothcontact_detect(cc, v, 2, 0.001f), RBC_OK);
        CHECK_EQ(rbc_clothcontact_count(cc), 1);
        rbc_clothcontact_project(cc, v, 2);
        /* Back along the start direction (they crossed): the fast one stays on the
         * -(1,1,1) side of the one at rest, 2 th apart along it. */
        const double along = ((double)ap[0] - bp[0] + ap[1] - bp[1] + ap[2] - bp[2]) / sqrt(3.0);
        CHECK(along <= -2.0 * th + 1e-6);
    }
    sheet_free(&g);
    sheet_free(&far);
    rbc_clothcontact_destroy(cc);
}

/* ---- 2. and 3. stacked layers pressed together ----------------------------------- */

/* Layers k = 0 .. nl-1 of nx x nx vertices at y = k gap, each shifted by a third of a
 * cell against the one below; layer k moves by D (1.5 - k) (nl = 4) or +-D (nl = 2)
 * per substep, the top one with a bump of +-50% and a slide of 0.3 D in x. */
static void make_stack(sheet *s, uint32_t nl, uint32_t nx, float L, float gap, float D) {
    for (uint32_t k = 0; k < nl; ++k) {
        float off = (float)(k % 3) * L / 3.0f;
        s[k] = sheet_grid(nx, nx, L, off, gap * (float)k, off);
        float v = nl == 2 ? (k ? -D : D) : D * (1.5f - (float)k);
        for (uint32_t j = 0; j < nx; ++j)
            for (uint32_t i = 0; i < nx; ++i) {
                uint32_t m = i + nx * j;
                float bump = 1.0f;
                if (k == nl - 1) {
                    bump += 0.5f * sinf(3.14159265f * (float)i / (float)(nx - 1)) *
                            sinf(3.14159265f * (float)j / (float)(nx - 1));
                    s[k].d[0][m] = 0.3f * D;
                }
                s[k].d[1][m] = v * bump;
            }
    }
}

/* Press a stack for `steps` substeps; check after each that every vertex of layer k+1
 * is above layer k (height over the triangle under it > 0) and at least th - left
 * from it, where left is the violation the passes left (measured). Returns the
 * smallest distance seen. */
static double press(uint32_t nl, uint32_t nx, int steps, int passes, const char *name) {
    const float L = 0.01f, gap = 0.01f, th = 0.004f, margin = 0.002f, D = 0.001f;
    sheet s[4];
    rbc_contact_body b[4];
    make_stack(s, nl, nx, L, gap, D);
    for (uint32_t k = 0; k < nl; ++k) b[k] = body_of(&s[k], th, 0.0f, 1, 1);
    rbc_clothcontact *cc = new_contact();
    double min_gap = INFINITY, min_dist = INFINITY, worst_slack = -INFINITY;
    float worst_left = 0.0f;
    uint32_t max_contacts = 0, unmatched = 0, swapped = 0;
    for (int st = 0; st < steps; ++st) {
        float left = 0.0f;
        CHECK_EQ(substep(cc, s, b, nl, margin, passes, 0, &left), RBC_OK);
        worst_left = fmaxf(worst_left, left);
        if (rbc_clothcontact_count(cc) > max_contacts) max_contacts = rbc_clothcontact_count(cc);
        for (uint32_t k = 0; k + 1 < nl; ++k)
            for (uint32_t i = 0; i < s[k + 1].n; ++i) {
                double g, dist;
                against(&s[k + 1], i, &s[k], NULL, 2.0 * th, &g, &dist);
                if (g == INFINITY) {
                    unmatched++; /* beyond the edge of the layer below */
                    continue;
                }
                if (!(g > 0.0)) swapped++;
                min_gap = fmin(min_gap, g);
                min_dist = fmin(min_dist, dist);
                worst_slack = fmax(worst_slack, (th - left) - dist);
            }
    }
    printf("%s: %u layers of %ux%u, %d substeps x %d passes: up to %u contacts, min height "
           "over the layer below %.3g mm, min distance %.3g mm (thickness %.3g mm), largest "
           "violation left %.3g mm, %u vertices beyond the edge\n",
           name, nl, nx, nx, steps, passes, max_contacts, min_gap * 1e3, min_dist * 1e3, th * 1e3,
           worst_left * 1e3, unmatched / (uint32_t)steps);
    CHECK_EQ(swapped, 0);
    /* Every vertex sits over the layer below. The distance it keeps is the thickness
     * less what the passes left: a pair the contact list missed would break this.
     * 1e-6 m: float rounding of the measure. The passes must also have converged to
     * within a quarter of the thickness for this to mean anything. */
    CHECK(worst_slack <= 1e-6);
    CHECK(worst_left <= 0.25f * th);
    /* The press really pressed: the layers reached contact distance. */
    CHECK(min_dist < 1.5 * th);
    rbc_clothcontact_destroy(cc);
    for (uint32_t k = 0; k < nl; ++k) sheet_free(&s[k]);
    return min_dist;
}

/* ---- 4. self-collision of a folded grid ------------------------------------------ */

static void test_fold(void) {
    const uint32_t nx = 20;
    const float L = 0.01f, th = 0.004f, gap = 0.01f, D = 0.001f, margin = 0.001f;
    rbc_clothcontact *cc = new_contact();
    sheet s = sheet_grid(nx, nx, L, 0.0f, 0.0f, 0.0f);
    rbc_contact_body b = body_of(&s, th, 0.0f, 1, 0);
    /* Flat at rest (x = p = rest): the nearest non-incident triangle is 7.1 mm away
     * (across a diagonal: excluded, < 2 th at rest), the next 10 mm > th + margin;
     * neighbours 10 mm > 2 th + margin. */
    CHECK_EQ(rbc_clothcontact_detect(cc, &b, 1, margin), RBC_OK);
    CHECK_EQ(rbc_clothcontact_count(cc), 0);
    /* With a margin that reaches the neighbours, contacts exist but none acts: the
     * rest pose violates nothing, and nothing moves. */
    CHECK_EQ(rbc_clothcontact_detect(cc, &b, 1, 0.004f), RBC_OK);
    CHECK(rbc_clothcontact_count(cc) > 0);
    CHECK(rbc_clothcontact_project(cc, &b, 1) == 0.0f);
    for (uint32_t i = 0; i < s.n; ++i)
        CHECK(s.p[0][i] == s.rest[0][i] && s.p[1][i] == s.rest[1][i] && s.p[2][i] == s.rest[2][i]);

    /* Fold: columns 0..9 flat at y = 0, columns 10..19 mirrored over them at y = gap
     * (column i over column 19 - i, shifted by half a cell in x and z, so that the
     * vertices of the halves do not meet head-on: there the vertex-vertex contacts,
     * 2 th, would keep them apart before the vertex-triangle ones, th, act); the
     * halves move toward each other by D each. */
    for (uint32_t j = 0; j < nx; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            uint32_t v = i + nx * j;
            int top = i >= nx / 2;
            s.x[0][v] = L * (float)(top ? nx - 1 - i : i) + (top ? 0.5f * L : 0.0f);
            s.x[1][v] = top ? gap : 0.0f;
            s.x[2][v] = L * (float)j + (top ? 0.5f * L : 0.0f);
            s.d[1][v] = top ? -D : D;
        }
    uint8_t *bottom_tri = calloc(s.nt, 1);
    for (uint32_t t = 0; t < s.nt; ++t) {
        const uint32_t *f = s.tris + 3 * t;
        bottom_tri[t] = f[0] % nx < nx / 2 && f[1] % nx < nx / 2 && f[2] % nx < nx / 2;
    }
    double min_dist = INFINITY, worst_slack = -INFINITY;
    uint32_t swapped = 0, max_contacts = 0;
    float worst_left = 0.0f;
    for (int st = 0; st < 50; ++st) {
        float left = 0.0f;
        CHECK_EQ(substep(cc, &s, &b, 1, margin, 8, 0, &left), RBC_OK);
        worst_left = fmaxf(worst_left, left);
        if (rbc_clothcontact_count(cc) > max_contacts) max_contacts = rbc_clothcontact_count(cc);
        for (uint32_t v = 0; v < s.n; ++v) {
            if (v % nx < nx / 2) continue;
            double g, dist;
            against(&s, v, &s, bottom_tri, 2.0 * th, &g, &dist);
            if (g == INFINITY) continue;
            if (!(g > 0.0)) swapped++;
            min_dist = fmin(min_dist, dist);
            worst_slack = fmax(worst_slack, (th - left) - dist);
        }
    }
    printf("fold: 20x20 folded over itself, 50 substeps x 8 passes: up to %u contacts, min "
           "distance between the halves %.3g mm (thickness %.3g mm), violation left %.3g mm\n",
           max_contacts, min_dist * 1e3, th * 1e3, worst_left * 1e3);
    CHECK_EQ(swapped, 0);
    CHECK(worst_slack <= 1e-6);
    CHECK(worst_left <= 0.25f * th);
    CHECK(min_dist < 1.5 * th);
    free(bottom_tri);
    sheet_free(&s);
    rbc_clothcontact_destroy(cc);
}

/* ---- 5. friction ------------------------------------------------------------------ */

static void test_friction(void) {
    const float th = 0.004f;
    rbc_clothcontact *cc = new_contact();
    /* A big triangle in y = 0, normal +y: (0,0,1) x (1,0,0) = (0, 1, 0). */
    float tx[3][3] = {{0.0f, 0.0f, 1.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}};
    float tp[3][3], tm[3] = {1e-4f, 1e-4f, 1e-4f};
    uint8_t tpin[3];
    const uint32_t tri[3] = {0, 1, 2};
    const float slide = 0.001f, sink = 0.0005f;
    const float mus[4] = {3.0f, 0.0f, 1.0f, 3.0f};
    for (int m = 0; m < 4; ++m) {
        /* m = 0..2: a static (pinned) triangle; 3: a free one. */
        const int free_tri = m == 3;
        memcpy(tp, tx, sizeof tp);
        for (int c = 0; c < 3; ++c) tpin[c] = !free_tri;
        float px[3] = {0.3f, th, 0.3f}, pp[3], pm = 1e-4f;
        uint8_t ppin = 0;
        pp[0] = px[0] + slide, pp[1] = px[1] - sink, pp[2] = px[2];
        const float pred_x = pp[0];
        rbc_contact_body b[2] = {particle_body(px, pp, &pm, &ppin, th),
                                 triangle_body(tx, tp, tm, tpin, tri, th)};
        b[0].friction = mus[m];
        b[1].friction = 0.5f; /* the larger of the two is used */
        if (m == 1) b[1].friction = 0.0f;
        CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
        CHECK_EQ(rbc_clothcontact_count(cc), 1);
        rbc_clothcontact_project(cc, b, 2);
        const float dn = rbc_clothcontact_list(cc)[0].dn;
        /* The normal correction: the sink (pinned), up to rounding. */
        CHECK_NEAR(dn, sink, 1e-9);
        double mom0 = (double)pm * pp[0];
        for (int c = 0; c < 3; ++c) mom0 += (double)tm[c] * tp[0][c];
        rbc_clothcontact_friction(cc, b, 2);
        /* Slip of the vertex against the contact's triangle point (its weights). */
        const float *w = rbc_clothcontact_list(cc)[0].w;
        double tmove = 0.0;
        for (int c = 0; c < 3; ++c) tmove += (double)w[c] * (tp[0][c] - tx[0][c]);
        const double slip = (double)(pp[0] - px[0]) - tmove;
        const double slide0 = (double)(pred_x - px[0]);
        /* Bounds: each coordinate is rounded to an ulp of itself: 3e-8 m near 0.3 m
         * (the vertex), 1.2e-7 m near 1 m (a free corner, weight <= 0.4). */
        const double tol = free_tri ? 3e-8 + 0.4 * 1.2e-7 * 3 : 6e-8;
        if (m == 0 || m == 3) {
            /* mu dn = 1.5 mm > 1 mm of slide: it stops. */
            CHECK_NEAR(slip, 0.0, tol);
        } else if (m == 1) {
            CHECK(pp[0] == pred_x); /* mu = 0: bitwise untouched */
        } else {
            /* mu dn = 0.5 mm < 1 mm: shortened by mu dn. */
            CHECK_NEAR(slip, slide0 - 1.0 * dn, tol);
        }
        CHECK(pp[2] == px[2]);
        if (free_tri) {
            /* Friction is internal: x momentum is kept (to float rounding). */
            double mom1 = (double)pm * pp[0];
            for (int c = 0; c < 3; ++c) mom1 += (double)tm[c] * tp[0][c];
            /* 4 particles of 1e-4 kg, each x rounded to at most an ulp of 1 m. */
            CHECK_NEAR(mom1, mom0, 4 * 1e-4 * 1.2e-7);
        } else {
            CHECK(memcmp(tp, tx, sizeof tp) == 0);
        }
    }
    rbc_clothcontact_destroy(cc);
}

/* ---- 6. pins ---------------------------------------------------------------------- */

static void test_pins(void) {
    const float th = 0.004f;
    sheet s[2];
    make_stack(s, 2, 16, 0.01f, 0.01f, 0.001f);
    /* Bottom: its border and every third interior vertex; top: its corners. */
    for (uint32_t j = 0; j < 16; ++j)
        for (uint32_t i = 0; i < 16; ++i) {
            uint32_t v = i + 16 * j;
            s[0].pinned[v] = i == 0 || j == 0 || i == 15 || j == 15 || v % 3 == 0;
            s[1].pinned[v] = (i == 0 || i == 15) && (j == 0 || j == 15);
        }
    float *start[2][3];
    for (int m = 0; m < 2; ++m)
        for (int k = 0; k < 3; ++k) {
            start[m][k] = malloc(sizeof(float) * s[m].n);
            memcpy(start[m][k], s[m].x[k], sizeof(float) * s[m].n);
        }
    rbc_contact_body b[2] = {body_of(&s[0], th, 0.5f, 1, 1), body_of(&s[1], th, 0.5f, 1, 1)};
    rbc_clothcontact *cc = new_contact();
    uint32_t moved = 0, nonfinite = 0, contacts = 0;
    for (int st = 0; st < 30; ++st) {
        CHECK_EQ(substep(cc, s, b, 2, 0.002f, 4, 1, NULL), RBC_OK);
        contacts += rbc_clothcontact_count(cc);
        for (int m = 0; m < 2; ++m)
            for (uint32_t i = 0; i < s[m].n; ++i)
                for (int k = 0; k < 3; ++k) {
                    if (s[m].pinned[i] && s[m].x[k][i] != start[m][k][i]) moved++;
                    if (!isfinite(s[m].x[k][i])) nonfinite++;
                }
    }
    CHECK(contacts > 0);
    CHECK_EQ(moved, 0);
    CHECK_EQ(nonfinite, 0);
    for (int m = 0; m < 2; ++m) {
        for (int k = 0; k < 3; ++k) free(start[m][k]);
        sheet_free(&s[m]);
    }
    rbc_clothcontact_destroy(cc);
}

/* ---- 7. determinism and steady buffers ---------------------------------------------- */

typedef struct counter {
    long allocs, frees, live, fail_at, armed_count;
    size_t live_bytes;
    int armed, failed;
} counter;

static void *counter_alloc(void *user, size_t size, size_t alignment) {
    counter *c = user;
    if (c->armed && c->fail_at && ++c->armed_count == c->fail_at) {
        c->failed = 1;
        return NULL;
    }
    void *p = NULL;
    if (posix_memalign(&p, alignment < sizeof(void *) ? sizeof(void *) : alignment, size)) return NULL;
    c->allocs++;
    c->live++;
    c->live_bytes += size;
    return p;
}

static void counter_free(void *user, void *ptr, size_t size) {
    counter *c = user;
    c->frees++;
    c->live--;
    c->live_bytes -= size;
    free(ptr);
}

/* The pins scene with friction for 20 substeps on cc; returns the top sheet's final
 * positions (3 n floats, malloc'd) and copies the last contact list to *list. */
static float *run_scene(rbc_clothcontact *cc, rbc_contact **list, uint32_t *count) {
    sheet s[2];
    make_stack(s, 2, 20, 0.01f, 0.01f, 0.0015f);
    s[0].pinned[0] = s[0].pinned[399] = 1;
    rbc_contact_body b[2] = {body_of(&s[0], 0.004f, 0.3f, 1, 1), body_of(&s[1], 0.004f, 0.6f, 1, 1)};
    for (int st = 0; st < 20; ++st) CHECK_EQ(substep(cc, s, b, 2, 0.002f, 4, 1, NULL), RBC_OK);
    float *out = malloc(sizeof(float) * 3 * 2 * 400);
    for (int m = 0; m < 2; ++m)
        for (int k = 0; k < 3; ++k) memcpy(out + (3 * m + k) * 400, s[m].x[k], sizeof(float) * 400);
    *count = rbc_clothcontact_count(cc);
    *list = malloc(sizeof(rbc_contact) * (*count + 1));
    memcpy(*list, rbc_clothcontact_list(cc), sizeof(rbc_contact) * *count);
    sheet_free(&s[0]);
    sheet_free(&s[1]);
    return out;
}

static void test_determinism(void) {
    rbc_allocator al = rbc_allocator_default();
    rbc_clothcontact *a = NULL, *b = NULL;
    CHECK_EQ(rbc_clothcontact_create(&al, &a), RBC_OK);
    CHECK_EQ(rbc_clothcontact_create(&al, &b), RBC_OK);
    rbc_contact *la, *lb, *lc;
    uint32_t na, nb, nc;
    float *ra = run_scene(a, &la, &na);
    float *rb = run_scene(b, &lb, &nb);
    CHECK(na > 0);
    CHECK(na == nb && memcmp(la, lb, sizeof(rbc_contact) * na) == 0);
    CHECK(memcmp(ra, rb, sizeof(float) * 3 * 2 * 400) == 0);
    /* Grow b's buffers on a bigger scene (4 layers), then run the first one again. */
    const size_t small = rbc_clothcontact_bytes(b);
    {
        sheet s[4];
        rbc_contact_body bb[4];
        make_stack(s, 4, 40, 0.01f, 0.01f, 0.002f);
        for (int k = 0; k < 4; ++k) bb[k] = body_of(&s[k], 0.004f, 0.0f, 1, 1);
        for (int st = 0; st < 8; ++st) CHECK_EQ(substep(b, s, bb, 4, 0.002f, 2, 0, NULL), RBC_OK);
        for (int k = 0; k < 4; ++k) sheet_free(&s[k]);
    }
    printf("determinism: %u contacts; buffers %zu bytes, %zu after a bigger scene\n", na, small,
           rbc_clothcontact_bytes(b));
    CHECK(rbc_clothcontact_bytes(b) > small);
    float *rc = run_scene(b, &lc, &nc);
    CHECK(na == nc && memcmp(la, lc, sizeof(rbc_contact) * na) == 0);
    CHECK(memcmp(ra, rc, sizeof(float) * 3 * 2 * 400) == 0);
    free(ra), free(rb), free(rc), free(la), free(lb), free(lc);
    rbc_clothcontact_destroy(a);
    rbc_clothcontact_destroy(b);

    /* A repeated detect of one input: the same list, and no allocation after the
     * first. */
    counter ctr;
    memset(&ctr, 0, sizeof ctr);
    rbc_allocator ca = {counter_alloc, counter_free, &ctr};
    rbc_clothcontact *c = NULL;
    CHECK_EQ(rbc_clothcontact_create(&ca, &c), RBC_OK);
    sheet s[2];
    make_stack(s, 2, 20, 0.01f, 0.004f, 0.002f);
    rbc_contact_body bb[2] = {body_of(&s[0], 0.004f, 0.0f, 1, 1), body_of(&s[1], 0.004f, 0.0f, 1, 1)};
    for (int m = 0; m < 2; ++m)
        for (int k = 0; k < 3; ++k)
            for (uint32_t i = 0; i < s[m].n; ++i) s[m].p[k][i] = s[m].x[k][i] + s[m].d[k][i];
    CHECK_EQ(rbc_clothcontact_detect(c, bb, 2, 0.002f), RBC_OK);
    const uint32_t n1 = rbc_clothcontact_count(c);
    rbc_contact *first = malloc(sizeof(rbc_contact) * (n1 + 1));
    memcpy(first, rbc_clothcontact_list(c), sizeof(rbc_contact) * n1);
    const long allocs = ctr.allocs;
    CHECK_EQ(rbc_clothcontact_detect(c, bb, 2, 0.002f), RBC_OK);
    CHECK(n1 > 0 && rbc_clothcontact_count(c) == n1 &&
          memcmp(first, rbc_clothcontact_list(c), sizeof(rbc_contact) * n1) == 0);
    CHECK_EQ(ctr.allocs, allocs);
    free(first);
    rbc_clothcontact_destroy(c);
    CHECK_EQ(ctr.live, 0);
    CHECK_EQ(ctr.live_bytes, 0);
    sheet_free(&s[0]);
    sheet_free(&s[1]);
}

/* A query over more cells than its hash's scan limit tests every object in order
 * instead (the hash's scan_cells, set by hash_build, falls as its buckets fill: a
 * box far larger than the mesh no longer reads the same crowded buckets hundreds of
 * times). Both ways must give the same bits. Two 8 x 8 sheets, one a metre thick
 * (everything in reach of everything, as the fuzzer's input), both moving 6 m a
 * substep: their swept boxes cover 36-64 of the 2 m cells, over the limit (4) of a
 * hash of 196 patches of one triangle each, so they are scanned. A third grid of
 * 100 x 100, far away and touching nothing, raises the limit to CC_BIG_CELLS (2,451
 * more patches, none hashed): the same queries go through the hash. The contacts and
 * the positions after the passes are compared bitwise; dropping one patch from the
 * scan fails it. (The fail-safe's scan is not reached by this scene.) */
static void scan_run(int far, rbc_contact **list, uint32_t *n, float **pos) {
    rbc_clothcontact *cc = new_contact();
    sheet s[3] = {sheet_grid(8, 8, 0.05f, 0.0f, 1.0f, 0.0f), sheet_grid(8, 8, 0.05f, 0.0f, 1.01f, 0.0f),
                  sheet_grid(100, 100, 0.01f, 0.0f, 50.0f, 0.0f)};
    for (int m = 0; m < 2; ++m)
        for (int k = 0; k < 3; ++k)
            for (uint32_t i = 0; i < s[m].n; ++i) s[m].p[k][i] = s[m].x[k][i] + 6.0f;
    /* B pressed into A at its far corner: not every contact alike. */
    s[1].p[1][s[1].n - 1] -= 0.02f;
    rbc_contact_body b[3] = {body_of(&s[0], 0.003f, 0.0f, 1, 1), body_of(&s[1], 1.003f, 0.0f, 1, 1),
                             body_of(&s[2], 0.003f, 0.0f, 0, 1)};
    CHECK_EQ(rbc_clothcontact_detect(cc, b, far ? 3 : 2, 0.002f), RBC_OK);
    *n = rbc_clothcontact_count(cc);
    *list = malloc(sizeof(rbc_contact) * (*n + 1));
    memcpy(*list, rbc_clothcontact_list(cc), sizeof(rbc_contact) * *n);
    for (int it = 0; it < 4; ++it) rbc_clothcontact_project(cc, b, far ? 3 : 2);
    *pos = malloc(sizeof(float) * 3 * 128);
    for (int m = 0; m < 2; ++m)
        for (int k = 0; k < 3; ++k) memcpy(*pos + 64 * (3 * m + k), s[m].p[k], sizeof(float) * 64);
    rbc_clothcontact_destroy(cc);
    for (int m = 0; m < 3; ++m) sheet_free(&s[m]);
}

static void test_scan_equals_hash(void) {
    rbc_contact *ls, *lh;
    uint32_t ns, nh;
    float *ps, *ph;
    scan_run(0, &ls, &ns, &ps);
    scan_run(1, &lh, &nh, &ph);
    printf("scan against hash: %u and %u contacts\n", ns, nh);
    CHECK(ns > 100);
    CHECK(ns == nh && memcmp(ls, lh, sizeof(rbc_contact) * ns) == 0);
    CHECK(memcmp(ps, ph, sizeof(float) * 3 * 128) == 0);
    free(ls), free(lh), free(ps), free(ph);
}

/* ---- 8. out of memory ------------------------------------------------------------- */

static void test_oom(void) {
    long k;
    int oom_seen = 0, phantom = 0, leaks = 0, wrong = 0, nonempty = 0;
    for (k = 1; k < 1000; ++k) {
        counter ctr;
        memset(&ctr, 0, sizeof ctr);
        ctr.fail_at = k;
        ctr.armed = 1;
        rbc_allocator ca = {counter_alloc, counter_free, &ctr};
        rbc_clothcontact *c = NULL;
        int32_t r = rbc_clothcontact_create(&ca, &c);
        int done = 0;
        if (r == RBC_OK) {
            /* A small scene, then a bigger one (every buffer grows), with passes. */
            for (int round = 0; round < 2 && r == RBC_OK; ++round) {
                sheet s[2];
                make_stack(s, 2, round ? 24 : 8, 0.01f, 0.004f, 0.002f);
                rbc_contact_body bb[2] = {body_of(&s[0], 0.004f, 0.2f, 1, 1),
                                          body_of(&s[1], 0.004f, 0.2f, 1, 1)};
                r = substep(c, s, bb, 2, 0.002f, 2, 1, NULL);
                if (r != RBC_OK && rbc_clothcontact_count(c) != 0) nonempty++;
                /* The object is still usable after a failure: project does nothing. */
                if (r != RBC_OK) rbc_clothcontact_project(c, bb, 2);
                sheet_free(&s[0]);
                sheet_free(&s[1]);
            }
            done = r == RBC_OK && !ctr.failed;
            rbc_clothcontact_destroy(c);
        } else {
            CHECK(c == NULL);
        }
        if (r == RBC_ERR_OUT_OF_MEMORY) {
            oom_seen++;
            if (!ctr.failed) phantom++;
        } else if (r != RBC_OK) {
            wrong++;
        }
        if (ctr.live != 0 || ctr.live_bytes != 0) leaks++;
        if (done) break;
    }
    printf("failing allocator: %ld scenarios, %d out-of-memory results\n", k, oom_seen);
    CHECK(k < 1000);
    CHECK(oom_seen > 5);
    CHECK_EQ(phantom, 0);
    CHECK_EQ(wrong, 0);
    CHECK_EQ(leaks, 0);
    CHECK_EQ(nonempty, 0);
}

/* ---- timing ----------------------------------------------------------------------- */

static double now_ms(clockid_t clock) {
    struct timespec t;
    clock_gettime(clock, &t);
    return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

/* Four 64x64 layers 6 mm apart pressed together (1 mm per substep per pair) until
 * they touch, then detect and one project pass timed (best of 3). */
static void time_layers(float th, float margin) {
    sheet s[4];
    rbc_contact_body b[4];
    make_stack(s, 4, 64, 0.01f, 0.006f, 0.001f);
    for (int k = 0; k < 4; ++k) b[k] = body_of(&s[k], th, 0.3f, 1, 1);
    rbc_clothcontact *cc = new_contact();
    for (int st = 0; st < 4; ++st) CHECK_EQ(substep(cc, s, b, 4, margin, 4, 1, NULL), RBC_OK);
    enum { REPS = 3 };
    /* Wall time and this thread's CPU time (the machine may be shared: CPU time leaves
     * out the time the thread waited for a core). */
    double td = INFINITY, tp = INFINITY, cd = INFINITY, cp = INFINITY;
    for (int r = 0; r < REPS; ++r) {
        /* The same prediction each time (the pass below moves p). */
        for (int m = 0; m < 4; ++m)
            for (int k = 0; k < 3; ++k)
                for (uint32_t i = 0; i < s[m].n; ++i) s[m].p[k][i] = s[m].x[k][i] + s[m].d[k][i];
        double t0 = now_ms(CLOCK_MONOTONIC), c0 = now_ms(CLOCK_THREAD_CPUTIME_ID);
        CHECK_EQ(rbc_clothcontact_detect(cc, b, 4, margin), RBC_OK);
        double t1 = now_ms(CLOCK_MONOTONIC), c1 = now_ms(CLOCK_THREAD_CPUTIME_ID);
        rbc_clothcontact_project(cc, b, 4);
        double t2 = now_ms(CLOCK_MONOTONIC), c2 = now_ms(CLOCK_THREAD_CPUTIME_ID);
        td = fmin(td, t1 - t0);
        tp = fmin(tp, t2 - t1);
        cd = fmin(cd, c1 - c0);
        cp = fmin(cp, c2 - c1);
    }
    printf("timing: 4 layers of 64x64 (%u vertices, %u triangles, L = 10 mm), thickness %.0f "
           "mm, margin %.0f mm, pressed: %u contacts; detect %.3f ms (CPU %.3f), one project "
           "pass %.3f ms (CPU %.3f), best of %d, one thread; %zu bytes\n",
           4 * s[0].n, 4 * s[0].nt, th * 1e3, margin * 1e3, rbc_clothcontact_count(cc), td, cd,
           tp, cp, REPS, rbc_clothcontact_bytes(cc));
    rbc_clothcontact_destroy(cc);
    for (int k = 0; k < 4; ++k) sheet_free(&s[k]);
}

/* ---- 5. slivers and deep far sides ---------------------------------------------- */

/* One vertex (body 0) against one triangle (body 1), 0.1 mg each, thickness 2 mm,
 * margin 1 mm (no vertex-vertex contact beyond 5 mm); detect with the vertex moving
 * from vx to vpred (NULL: staying at vx) and the triangle at tx; then (vmid not NULL)
 * move the vertex to vmid and run a pass, then move it to vp, the triangle to tp, and
 * run one pass. Returns the vertex's y after it. */
static float passes(const float vx[3], const float *vpred, const float *vmid, const float vp[3],
                    const float tx[3][3], const float tp[3][3], rbc_clothcontact *cc) {
    float v[3][1], vxs[3][1], t[3][3], txs[3][3], m1[1] = {1e-7f}, m3[3] = {1e-7f, 1e-7f, 1e-7f};
    static const uint32_t tri[3] = {0, 1, 2};
    rbc_contact_body b[2];
    memset(b, 0, sizeof b);
    for (int k = 0; k < 3; ++k) {
        v[k][0] = vpred ? vpred[k] : vx[k], vxs[k][0] = vx[k];
        for (int c = 0; c < 3; ++c) t[k][c] = tx[c][k], txs[k][c] = tx[c][k];
        b[0].p[k] = v[k], b[0].x[k] = vxs[k];
        b[1].p[k] = t[k], b[1].x[k] = txs[k];
    }
    b[0].n = 1, b[0].mass = m1;
    b[1].n = 3, b[1].mass = m3, b[1].tri_count = 1, b[1].tris = tri;
    b[0].thickness = b[1].thickness = 0.002f;
    b[0].others = b[1].others = 1;
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.001f), RBC_OK);
    CHECK_EQ(rbc_clothcontact_count(cc), 1);
    if (vmid) {
        for (int k = 0; k < 3; ++k) v[k][0] = vmid[k];
        rbc_clothcontact_project(cc, b, 2);
    }
    for (int k = 0; k < 3; ++k) {
        v[k][0] = vp[k];
        for (int c = 0; c < 3; ++c) t[k][c] = tp[c][k];
    }
    rbc_clothcontact_project(cc, b, 2);
    return v[1][0];
}

static float one_pass(const float vx[3], const float vp[3], const float tx[3][3],
                      const float tp[3][3], rbc_clothcontact *cc) {
    return passes(vx, NULL, NULL, vp, tx, tp, cc);
}

static void test_sliver_and_deep(void) {
    rbc_clothcontact *cc = new_contact();
    /* A sliver (a quad sheared flat: corners nearly in a line) whose third corner
     * crosses the line by 1 mm, which turns its normal from -y to +y; the vertex,
     * 1.5 mm above the middle of its first edge, does not move. It was on the -y side
     * of the plane at x and is 1.5 mm on the wrong side now: the plane rule threw it
     * 3.5 mm down through the edge. Against the sliver's closest point it is pushed
     * up to the thickness. */
    {
        const float tx[3][3] = {{0.0f, 0.0f, 0.0f}, {0.01f, 0.0f, 0.0f}, {0.02f, 0.0f, 0.0005f}};
        const float tp[3][3] = {{0.0f, 0.0f, 0.0f}, {0.01f, 0.0f, 0.0f}, {0.02f, 0.0f, -0.0005f}};
        const float v[3] = {0.005f, 0.0015f, 0.0f};
        const float y = one_pass(v, v, tx, tp, cc);
        printf("sliver: vertex 1.5 mm over a sliver's edge ends at y = %.4g mm\n", y * 1e3);
        /* The pass moves the vertex and the edge's midpoint 0.5 mm apart, mass-
         * weighted: den = ima + (1/4 + 1/4) im, the vertex's share 2/3: 1.5 + 1/3 mm
         * (1e-7 m: float rounding). */
        CHECK(fabsf(y - (0.0015f + 0.0005f / 1.5f)) < 1e-7f);
    }
    /* A vertex 3 mm on the far side of an ordinary triangle's plane, over it, that did
     * not get there through the motion detection saw (no RBC_CONTACT_CROSSED).
     *  - Held at the last pass (on its side: here at x, detection's pass): one
     *    iteration of the solve moved it through, and it is pushed back toward its
     *    side, by at most twice the thickness a pass (in the funnel's landing pile,
     *    90 % of the edges the fail-safe found through a triangle had a contact with
     *    it, most of them left alone before).
     *  - Not held: the last pass found it beside the triangle on the far side (it came
     *    around the edge). Pushing such a vertex back across (5 mm) was the largest
     *    move of a pass in the funnel; it is left where it is.
     * Shallower than the thickness (1 mm) it is pushed back to its side either way. */
    {
        const float tx[3][3] = {{-0.01f, 0.0f, -0.01f}, {0.01f, 0.0f, -0.01f}, {0.0f, 0.0f, 0.01f}};
        const float v0[3] = {0.0f, 0.0025f, 0.0f}, beside[3] = {0.02f, -0.003f, 0.0f};
        const float deep[3] = {0.0f, -0.003f, 0.0f}, shallow[3] = {0.0f, -0.001f, 0.0f};
        const float yh = one_pass(v0, deep, tx, tx, cc), ya = passes(v0, NULL, beside, deep, tx, tx, cc),
                    ys = one_pass(v0, shallow, tx, tx, cc);
        printf("deep far side: vertex at -3 mm after held goes to %.3g mm; come around, it stays "
               "at %.3g mm; at -1 mm it goes to %.3g mm\n",
               yh * 1e3, ya * 1e3, ys * 1e3);
        /* The vertex's share of the correction (th - dn: 5 mm capped to 2 th = 4 mm;
         * 3 mm): ima / (ima + sum w^2 im) with the closest point's weights (1/4, 1/4,
         * 1/2): 8/11 (1e-7 m: rounding). */
        CHECK(fabsf(yh - (-0.003f + 0.004f * 8.0f / 11.0f)) < 1e-7f);
        CHECK(ya == -0.003f);
        /* Around the border edge by its predicted motion: from 1 mm over the plane, 3 mm
         * beyond the edge, to 3 mm under the triangle (the path meets the plane 1 mm
         * outside it: not through). The first pass sees the prediction; it was not
         * the solve that took it there, and it is left alone (held at detection, it
         * was pulled up through the face). */
        const float xa[3] = {0.0f, 0.001f, -0.013f}, pa[3] = {0.0f, -0.003f, -0.005f};
        const float yp = passes(xa, pa, NULL, pa, tx, tx, cc);
        printf("deep far side by the prediction, around the edge: stays at %.3g mm\n", yp * 1e3);
        CHECK(yp == -0.003f);
        CHECK(fabsf(ys - (-0.001f + 0.003f * 8.0f / 11.0f)) < 1e-7f);
    }
    rbc_clothcontact_destroy(cc);
}

/* The fail-safe's impact zone (rbc_clothcontact_failsafe_mt): a 10 x 10 sheet 1 cm
 * above another tilts down through it in one substep (its far edge 2 cm lower), with
 * no projection, so the sheets cross along a line. Every edge that crosses a triangle
 * there is a hit, and hits fall on vertices earlier hits put into the zone already.
 * The zone moves rigidly by the mass-weighted mean of its vertices' motion, which is
 * not zero: half its vertices belong to the sheet that moved down. Before, a hit on
 * five vertices already in the zone was taken as the zone "crossing again" and
 * stopped it at x in its first round (in the funnel, vertices stood still for 20
 * frames while the springs around them stretched to 2.4 times their length). */
static void test_failsafe_zone(void) {
    rbc_clothcontact *cc = new_contact();
    const float L = 0.01f;
    sheet s[2] = {sheet_grid(10, 10, L, 0.0f, 0.0f, 0.0f),
                  sheet_grid(10, 10, L, 0.003f, 0.01f, 0.002f)};
    rbc_contact_body b[2] = {body_of(&s[0], 0.001f, 0.0f, 0, 1), body_of(&s[1], 0.001f, 0.0f, 0, 1)};
    for (uint32_t i = 0; i < s[1].n; ++i) s[1].p[1][i] -= 0.02f * (float)(i % 10) / 9.0f;
    float *before[3];
    for (int k = 0; k < 3; ++k) {
        before[k] = malloc(sizeof(float) * 200);
        memcpy(before[k], s[0].p[k], sizeof(float) * 100);
        memcpy(before[k] + 100, s[1].p[k], sizeof(float) * 100);
    }
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.5f * L), RBC_OK);
    uint32_t frozen = 0;
    CHECK_EQ(rbc_clothcontact_failsafe_mt(cc, b, 2, 0, 1, NULL, NULL, &frozen), RBC_OK);
    /* The vertices the fail-safe moved, and the spread of their motion from x. */
    uint32_t moved = 0;
    double d0[3] = {0.0, 0.0, 0.0}, spread = 0.0;
    for (uint32_t g = 0; g < 200; ++g) {
        sheet *S = &s[g / 100];
        const uint32_t i = g % 100;
        int changed = 0;
        for (int k = 0; k < 3; ++k) changed |= S->p[k][i] != before[k][g];
        if (!changed) continue;
        for (int k = 0; k < 3; ++k) {
            const double d = (double)S->p[k][i] - S->x[k][i];
            if (!moved) d0[k] = d;
            if (fabs(d - d0[k]) > spread) spread = fabs(d - d0[k]);
        }
        moved++;
    }
    printf("fail-safe zone: %u vertices, %u moved, by (%.3g %.3g %.3g) mm from x, spread %.3g m\n",
           frozen, moved, d0[0] * 1e3, d0[1] * 1e3, d0[2] * 1e3, spread);
    CHECK(frozen > 0 && moved > 0);
    /* One rigid motion (float rounding of x + d: 1e-8 m) ... */
    CHECK(spread < 1e-6);
    /* ... down: the moved half of the zone went down 1.1 cm on average and the other
     * half not at all; a stopped zone moves by 0. */
    CHECK(d0[1] < -1e-3);
    /* Tangled at x already (the tilted sheet through the other at the start of the
     * substep), both moving 1 cm down together: no zone can undo that crossing, and
     * stopping it held its vertices in place while their cloth moved on. The fail-
     * safe leaves it alone: nothing moves. */
    for (uint32_t i = 0; i < s[1].n; ++i) s[1].x[1][i] = 0.01f - 0.02f * (float)(i % 10) / 9.0f;
    for (int m = 0; m < 2; ++m)
        for (uint32_t i = 0; i < s[m].n; ++i) s[m].p[1][i] = s[m].x[1][i] - 0.01f;
    for (int k = 0; k < 3; ++k) {
        memcpy(before[k], s[0].p[k], sizeof(float) * 100);
        memcpy(before[k] + 100, s[1].p[k], sizeof(float) * 100);
    }
    CHECK_EQ(rbc_clothcontact_detect(cc, b, 2, 0.5f * L), RBC_OK);
    CHECK_EQ(rbc_clothcontact_failsafe_mt(cc, b, 2, 0, 1, NULL, NULL, &frozen), RBC_OK);
    uint32_t changed = 0;
    for (uint32_t g = 0; g < 200; ++g)
        for (int k = 0; k < 3; ++k) changed += s[g / 100].p[k][g % 100] != before[k][g];
    printf("fail-safe, tangled at x: %u vertices in zones, %u coordinates changed\n", frozen,
           changed);
    CHECK_EQ(frozen, 0u);
    CHECK_EQ(changed, 0u);
    for (int k = 0; k < 3; ++k) free(before[k]);
    sheet_free(&s[0]);
    sheet_free(&s[1]);
    rbc_clothcontact_destroy(cc);
}

/* Edge-edge between interior edges: a valley (two quads along x creased downward
 * along their middle edge, walls rising 45 degrees) over a ridge (two quads along z
 * creased upward), their crease edges 2 mm apart, crossed at right angles. The valley
 * moves 3 mm down in one substep: its crease passes through the ridge's while no
 * vertex comes within the thickness of a triangle of the other piece (the valley's
 * crease ends sit 5 mm off the ridge's walls: vertex-triangle contacts see nothing),
 * and neither crease is a border edge. Only an edge-edge contact between interior
 * edges keeps the creases apart: after 8 passes the valley's crease is over the
 * ridge's, the thickness apart (10 % less allowed); without them it ended 1 mm under
 * it, crossed. The pieces are one self-colliding body (mode 0), or two bodies of
 * which the valley's has self contact (1): contacts. Two bodies without self contact
 * (2) get none (flat layers do not pay for them): the crease ends crossed. */
static void test_interior_ee(int mode) {
    rbc_clothcontact *cc = new_contact();
    const float H = 0.005f, th = 0.0005f;
    /* Piece 0, the valley: rows z = -H, 0, H, columns x = -H, H; piece 1, the ridge:
     * rows x = -H, 0, H, columns z = -H, H. */
    sheet s[2] = {sheet_grid(3, 2, 0.01f, 0.0f, 0.0f, 0.0f), sheet_grid(3, 2, 0.01f, 0.0f, 0.0f, 0.0f)};
    for (uint32_t i = 0; i < 6; ++i) {
        const float along = (float)((int)(i / 2) - 1) * H, across = (i % 2) ? H : -H;
        const float wall = i / 2 == 1 ? 0.0f : H;
        s[0].x[0][i] = across, s[0].x[2][i] = along, s[0].x[1][i] = 0.001f + wall;
        s[1].x[0][i] = along, s[1].x[2][i] = across, s[1].x[1][i] = -0.001f - wall;
        for (int m = 0; m < 2; ++m)
            for (int k = 0; k < 3; ++k) {
                s[m].rest[k][i] = s[m].x[k][i] + (k == 1 ? (float)m : 0.0f); /* 1 m apart at rest */
                s[m].d[k][i] = k == 1 && m == 0 ? -0.003f : 0.0f;
            }
    }
    /* Two quads a piece: rows r and r + 1 (vertices 2r, 2r + 1, 2r + 2, 2r + 3). */
    for (int m = 0; m < 2; ++m)
        for (uint32_t r = 0; r < 2; ++r) {
            const uint32_t a = 2 * r, b = a + 1, c = a + 3, dd = a + 2;
            uint32_t *t = s[m].tris + 6 * r;
            t[0] = a, t[1] = dd, t[2] = c, t[3] = a, t[4] = c, t[5] = b;
        }
    sheet one = sheet_grid(4, 3, 0.01f, 0.0f, 0.0f, 0.0f); /* both pieces in one body */
    for (uint32_t i = 0; i < 12; ++i)
        for (int k = 0; k < 3; ++k) {
            one.x[k][i] = s[i / 6].x[k][i % 6];
            one.rest[k][i] = s[i / 6].rest[k][i % 6];
            one.d[k][i] = s[i / 6].d[k][i % 6];
        }
    one.nt = 8;
    for (uint32_t k = 0; k < 24; ++k) one.tris[k] = s[k / 12].tris[k % 12] + 6 * (k / 12);
    rbc_contact_body b[2];
    uint32_t count = 1;
    if (mode == 0) {
        b[0] = body_of(&one, th, 0.0f, 1, 0);
    } else {
        b[0] = body_of(&s[0], th, 0.0f, mode == 1, 1);
        b[1] = body_of(&s[1], th, 0.0f, 0, 1);
        count = 2;
    }
    float left = 0.0f;
    CHECK_EQ(substep(cc, mode == 0 ? &one : s, b, count, 0.001f, 8, 0, &left), RBC_OK);
    uint32_t ee = 0;
    const rbc_contact *list = rbc_clothcontact_list(cc);
    for (uint32_t m = 0; m < rbc_clothcontact_count(cc); ++m) ee += list[m].kind == RBC_CONTACT_EE;
    /* The creases' middles (both at x = z = 0): valley 2-3, ridge 2-3 of piece 1. */
    const sheet *V = mode == 0 ? &one : &s[0], *R = mode == 0 ? &one : &s[1];
    const uint32_t r0 = mode == 0 ? 8 : 2;
    const float yv = 0.5f * (V->x[1][2] + V->x[1][3]), yr = 0.5f * (R->x[1][r0] + R->x[1][r0 + 1]);
    printf("interior edge-edge (%s): %u edge contacts of %u; valley crease %.3g mm over the "
           "ridge's (thickness %.3g mm), violation left %.3g mm\n",
           mode == 0 ? "one body, self" : mode == 1 ? "two bodies, one with self" : "two bodies, no self",
           ee, rbc_clothcontact_count(cc), (yv - yr) * 1e3, th * 1e3, left * 1e3);
    if (mode < 2) {
        CHECK(ee >= 1u);
        CHECK(yv - yr > 0.9f * th);
        CHECK(left < 0.1f * th);
    } else {
        CHECK_EQ(ee, 0u);
        CHECK(yv - yr < 0.0f);
    }
    sheet_free(&s[0]);
    sheet_free(&s[1]);
    sheet_free(&one);
    rbc_clothcontact_destroy(cc);
}

/* The interior edge contacts do not depend on how the triangles fall into patches
 * or cells, and hold each pair once: a 30 x 30 sheet folded like an accordion (its
 * columns 2.5 mm apart in x, every other one 9.5 mm higher; thickness 2 mm), alone,
 * then beside a far body of two 100 m triangles that makes the hash's cells 0.3 m
 * instead of 1.5 cm (so its patches are cut differently): the same edge contacts
 * of the sheet, in the same order, none twice. Before, a patch hashed from two
 * cells into one bucket made every contact of its pairs twice, and the order
 * followed the patches. */
static void test_ee_layout(void) {
    rbc_allocator al = rbc_allocator_default();
    const float L = 0.01f, th = 0.002f;
    sheet s = sheet_grid(30, 30, L, 0.0f, 0.0f, 0.0f);
    uint32_t seed = 99u;
    for (uint32_t j = 0; j < 30; ++j)
        for (uint32_t i = 0; i < 30; ++i) {
            const uint32_t v = i + 30 * j;
            seed = seed * 1664525u + 1013904223u;
            const float jit = 0.001f * ((float)(seed >> 8) / 16777216.0f - 0.5f);
            s.x[0][v] = 0.25f * L * (float)i;
            s.x[1][v] = (i % 2 ? 0.95f * L : 0.0f) + jit;
            for (int k = 0; k < 3; ++k) s.p[k][v] = s.x[k][v] + (k == 1 ? -0.5f * jit : 0.0f);
        }
    sheet far = sheet_grid(2, 2, 100.0f, 1000.0f, 0.0f, 0.0f);
    rbc_contact_body b[2] = {body_of(&s, th, 0.0f, 1, 0), body_of(&far, th, 0.0f, 1, 0)};
    rbc_contact *list[2] = {NULL, NULL};
    uint32_t n[2] = {0, 0}, dup = 0;
    for (int m = 0; m < 2; ++m) {
        rbc_clothcontact *cc = NULL;
        CHECK_EQ(rbc_clothcontact_create(&al, &cc), RBC_OK);
        CHECK_EQ(rbc_clothcontact_detect(cc, b, (uint32_t)m + 1, 0.002f), RBC_OK);
        const rbc_contact *c = rbc_clothcontact_list(cc);
        list[m] = malloc(sizeof(rbc_contact) * (rbc_clothcontact_count(cc) + 1));
        for (uint32_t k = 0; k < rbc_clothcontact_count(cc); ++k)
            if (c[k].kind == RBC_CONTACT_EE && c[k].body_a == 0 && c[k].body_b == 0) list[m][n[m]++] = c[k];
        rbc_clothcontact_destroy(cc);
    }
    for (uint32_t k = 0; k < n[0]; ++k)
        for (uint32_t q = k + 1; q < n[0]; ++q) {
            const rbc_contact *x = &list[0][k], *y = &list[0][q];
            const uint32_t xa = x->a < x->a2 ? x->a : x->a2, xa2 = x->a < x->a2 ? x->a2 : x->a;
            const uint32_t xb = x->b < x->b2 ? x->b : x->b2, xb2 = x->b < x->b2 ? x->b2 : x->b;
            const uint32_t ya = y->a < y->a2 ? y->a : y->a2, ya2 = y->a < y->a2 ? y->a2 : y->a;
            const uint32_t yb = y->b < y->b2 ? y->b : y->b2, yb2 = y->b < y->b2 ? y->b2 : y->b;
            dup += (xa == ya && xa2 == ya2 && xb == yb && xb2 == yb2) ||
                   (xa == yb && xa2 == yb2 && xb == ya && xb2 == ya2);
        }
    const int same = n[0] == n[1] && memcmp(list[0], list[1], sizeof(rbc_contact) * n[0]) == 0;
    printf("edge contacts and patches: %u of the sheet alone, %u beside a far body (other "
           "cells and patches), %s; %u pairs twice\n",
           n[0], n[1], same ? "the same list" : "DIFFERENT", dup);
    CHECK(n[0] > 100u);
    CHECK(same);
    CHECK_EQ(dup, 0u);
    free(list[0]);
    free(list[1]);
    sheet_free(&s);
    sheet_free(&far);
}

/* ---- the pass on several threads ------------------------------------------------ */

typedef struct mt_run {
    rbc_clothcontact *cc;
    rbc_contact_body *b;
    uint32_t count, tid, nth;
    int passes;
    pthread_barrier_t *bar;
} mt_run;

static void mt_sync(void *bar) { pthread_barrier_wait(bar); }

static void *mt_thread(void *arg) {
    mt_run *r = arg;
    for (int k = 0; k < r->passes; ++k) {
        rbc_clothcontact_project_mt(r->cc, r->b, r->count, r->tid, r->nth, mt_sync, r->bar);
        pthread_barrier_wait(r->bar); /* the caller's barrier after a pass */
    }
    return NULL;
}

/* rbc_clothcontact_project_mt on 2 and 3 threads moves every particle to the same bits
 * as the serial pass, and leaves the same contacts (flags, directions, dn): its groups
 * share no particle. Four pressed layers give enough contacts for several slabs. */
static void test_project_threads(void) {
    rbc_allocator al = rbc_allocator_default();
    sheet s[4];
    rbc_contact_body bb[4];
    make_stack(s, 4, 40, 0.01f, 0.004f, 0.002f);
    for (int k = 0; k < 4; ++k) bb[k] = body_of(&s[k], 0.004f, 0.0f, 1, 1);
    const uint32_t n = s[0].n;
    float *ref = malloc(sizeof(float) * 4 * 3 * n), *out = malloc(sizeof(float) * 4 * 3 * n);
    rbc_contact *lref = NULL;
    uint32_t nref = 0;
    for (uint32_t nth = 1; nth <= 3; ++nth) {
        rbc_clothcontact *cc = NULL;
        CHECK_EQ(rbc_clothcontact_create(&al, &cc), RBC_OK);
        for (int m = 0; m < 4; ++m)
            for (int k = 0; k < 3; ++k)
                for (uint32_t i = 0; i < n; ++i) s[m].p[k][i] = s[m].x[k][i] + s[m].d[k][i];
        CHECK_EQ(rbc_clothcontact_detect(cc, bb, 4, 0.002f), RBC_OK);
        const uint32_t nc = rbc_clothcontact_count(cc);
        /* The slabs need 2 x 2048 contacts at least. */
        CHECK(nc >= 4096);
        if (nth == 1) {
            for (int k = 0; k < 3; ++k) rbc_clothcontact_project(cc, bb, 4);
        } else {
            pthread_barrier_t bar;
            pthread_barrier_init(&bar, NULL, nth);
            mt_run r[3];
            pthread_t th[3];
            for (uint32_t t = 0; t < nth; ++t) {
                r[t] = (mt_run){cc, bb, 4, t, nth, 3, &bar};
                if (t) pthread_create(&th[t], NULL, mt_thread, &r[t]);
            }
            mt_thread(&r[0]);
            for (uint32_t t = 1; t < nth; ++t) pthread_join(th[t], NULL);
            pthread_barrier_destroy(&bar);
        }
        float *dst = nth == 1 ? ref : out;
        for (int m = 0; m < 4; ++m)
            for (int k = 0; k < 3; ++k) memcpy(dst + (3 * m + k) * n, s[m].p[k], sizeof(float) * n);
        if (nth == 1) {
            nref = nc;
            lref = malloc(sizeof(rbc_contact) * nc);
            memcpy(lref, rbc_clothcontact_list(cc), sizeof(rbc_contact) * nc);
            /* The passes moved something (else the comparison says nothing). */
            double moved = 0.0;
            for (int m = 0; m < 4; ++m)
                for (uint32_t i = 0; i < n; ++i)
                    moved += fabs((double)s[m].p[1][i] - (s[m].x[1][i] + s[m].d[1][i]));
            CHECK(moved > 0.0);
            printf("project_mt: %u contacts, serial pass moved %.3g m in y in all\n", nc, moved);
        } else {
            CHECK(nc == nref && memcmp(lref, rbc_clothcontact_list(cc), sizeof(rbc_contact) * nc) == 0);
            CHECK(memcmp(ref, out, sizeof(float) * 4 * 3 * n) == 0);
        }
        rbc_clothcontact_destroy(cc);
    }
    free(ref), free(out), free(lref);
    for (int k = 0; k < 4; ++k) sheet_free(&s[k]);
}

int main(void) {
    test_fast_particle();
    test_far_motion();
    press(2, 20, 50, 8, "two grids");
    press(4, 20, 50, 8, "four layers");
    test_fold();
    test_friction();
    test_pins();
    test_determinism();
    test_project_threads();
    test_scan_equals_hash();
    test_oom();
    test_sliver_and_deep();
    test_failsafe_zone();
    for (int mode = 0; mode < 3; ++mode) test_interior_ee(mode);
    test_ee_layout();
    time_layers(0.004f, 0.002f);
    time_layers(0.002f, 0.001f);
    return check_report("core_clothcontact");
}
