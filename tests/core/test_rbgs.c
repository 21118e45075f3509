/* The solver against theory:
 *  1. One red-black Gauss-Seidel iteration (Eq. 6 over the red particles, then the
 *     black) equals a lexicographic Gauss-Seidel sweep that visits the red vertices
 *     and then the black ones, computed independently in double precision from the
 *     host mesh.
 *  2. With integration disabled (the paper's Fig. 3: a stretched network shrinking
 *     back, y = current positions), Eq. 7 never increases from frame to frame: each
 *     local step and each Gauss-Seidel update minimises the Projective Dynamics
 *     objective over its own variables, so with y = x the spring energy after a
 *     frame is at most the energy before it (derivation in the comment below).
 *  3. The result does not depend on the thread count (bitwise).
 */
#include <string.h>

#include "check.h"
#include "meshes.h"
#include "rbcloth.h"
#include "solver.h"

static rbc_cloth_state *make_cloth(rbc_solver *s, const test_mesh *m, const uint32_t *pins,
                                   uint32_t npins, float damping) {
    rbc_mesh_input in = mesh_input(m, pins, npins);
    rbc_cloth_state *c = NULL;
    char err[256];
    int32_t rc = rbc_solver_create_cloth(s, &in, damping, &c, err, sizeof err);
    CHECK_EQ(rc, RBC_OK);
    if (rc) fprintf(stderr, "%s\n", err);
    CHECK_EQ(rbc_solver_add_cloth(s, c), RBC_OK);
    return c;
}

/* Put the cloth (host order xyz) into x and q: at rest at those positions, with the
 * pins held where they now are. */
static void set_state(rbc_cloth_state *c, const float *xyz) {
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        uint32_t i = c->topo.to_internal[v];
        for (int a = 0; a < 3; ++a) c->x[a][i] = c->q[a][i] = xyz[3 * v + a];
    }
    for (uint32_t m = 0; m < c->pin_count; ++m)
        for (int a = 0; a < 3; ++a) c->pin_target[3 * m + a] = c->x[a][c->pin_idx[m]];
}

static double eq7(const rbc_cloth_state *c) {
    double e, strain;
    rbc_cloth_state_error(c, &e, &strain);
    return e;
}

/* 1. One RBGS iteration against an independent double-precision GS sweep. */
static void test_rbgs_equals_gs(const char *name, const test_mesh *m) {
    rbc_allocator a = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &a, 1), RBC_OK);
    s.gravity[1] = 0.0f;
    s.linear_iterations = 1;
    s.nonlinear_iterations = 1;
    uint32_t pins[2] = {0, 1};
    rbc_cloth_state *c = make_cloth(&s, m, pins, 2, 0.0f);
    const uint32_t n = m->nv;
    /* A stretched and sheared start, so every spring is violated. */
    float *start = malloc(sizeof(float) * 3 * n);
    for (uint32_t v = 0; v < n; ++v) {
        start[3 * v] = 1.5f * m->pos[3 * v] + 0.2f * m->pos[3 * v + 2];
        start[3 * v + 1] = 0.3f * m->pos[3 * v] * m->pos[3 * v + 2];
        start[3 * v + 2] = 1.2f * m->pos[3 * v + 2];
    }
    set_state(c, start);
    const float h = 0.002f;
    char err[256];
    CHECK_EQ(rbc_solver_step(&s, h, err, sizeof err), RBC_OK);

    /* Reference: with zero velocity and no gravity y = x; d_ij from x (local step);
     * then Gauss-Seidel over host vertices, red ones first, then black, in double. */
    const rbc_topology *t = &c->topo;
    double *p = malloc(sizeof(double) * 3 * n);
    for (uint32_t k = 0; k < 3 * n; ++k) p[k] = start[k];
    const double w = 1e-4 / ((double)h * h), k_s = 1000.0;
    for (uint32_t color = 0; color < 2; ++color) {
        for (uint32_t v = 0; v < n; ++v) {
            uint32_t i = t->to_internal[v];
            if ((i >= t->color_start[1]) != color || v < 2) continue; /* v 0, 1 pinned */
            double acc[3] = {w * start[3 * v], w * start[3 * v + 1], w * start[3 * v + 2]};
            double ksum = w;
            for (uint32_t q = 0; q < t->ns; ++q) {
                uint32_t ha = t->to_host[t->sa[q]], hb = t->to_host[t->sb[q]];
                if (ha != v && hb != v) continue;
                uint32_t o = ha == v ? hb : ha;
                /* d_vo = L (x_v - x_o)/|x_v - x_o| from the start positions. */
                double e[3], len = 0.0;
                for (int ax = 0; ax < 3; ++ax) {
                    e[ax] = (double)start[3 * v + ax] - start[3 * o + ax];
                    len += e[ax] * e[ax];
                }
                len = sqrt(len);
                for (int ax = 0; ax < 3; ++ax)
                    acc[ax] += k_s * (p[3 * o + ax] + t->rest_len[q] * e[ax] / len);
                ksum += k_s;
            }
            for (int ax = 0; ax < 3; ++ax) p[3 * v + ax] = acc[ax] / ksum;
        }
    }
    float *got = malloc(sizeof(float) * 3 * n);
    rbc_cloth_state_read(c, got);
    /* Bound: each float update rounds ~10 operations (relative 10 * 2^-24 of the
     * particle's coordinate magnitude, here <= 2), and an update is a convex
     * combination of neighbours with weights summing to < 1, so earlier errors do
     * not grow within one sweep: 16 * 2^-24 * 2 ~ 2e-6 m covers it. */
    double worst = 0.0;
    for (uint32_t k = 0; k < 3 * n; ++k) {
        double d = fabs(p[k] - got[k]);
        if (d > worst) worst = d;
    }
    printf("%s: one RBGS iteration vs lexicographic GS (red then black): max |diff| %.3g m\n",
           name, worst);
    CHECK(worst <= 16.0 * 5.96e-8 * 2.0);
    /* And the iteration did move the particles (the comparison is not vacuous). */
    double moved = 0.0;
    for (uint32_t k = 0; k < 3 * n; ++k) moved = fmax(moved, fabs(got[k] - start[k]));
    CHECK(moved > 1e-3);
    free(start);
    free(p);
    free(got);
    rbc_solver_fini(&s);
}

/* 2. Fig. 3's experiment: monotone decrease of Eq. 7 with integration disabled.
 * With y = x (damping * h >= 1 clamps Alg. 2's velocity term to zero; no gravity),
 * let F(p, d) = sum_i m_i/2h^2 |p_i - x_i|^2 + sum_s k/2 |p_a - p_b - d_s|^2. The local
 * step sets d to argmin over |d_s| = L_s, giving F(x, d(x)) = E(x) = k/2 Eq7(x); the
 * Gauss-Seidel updates each minimise F over one particle, so F(p_new, d(x)) <= E(x);
 * and E(p_new) = min_d F - inertia <= F(p_new, d(x)). Hence Eq7(p_new) <= Eq7(x). */
static void test_monotone(const char *name, const test_mesh *m, uint32_t linear) {
    rbc_allocator a = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &a, 2), RBC_OK);
    s.gravity[1] = 0.0f;
    s.linear_iterations = linear;
    const float h = 0.002f;
    rbc_cloth_state *c = make_cloth(&s, m, NULL, 0, 1.0f / h);
    float *start = malloc(sizeof(float) * 3 * m->nv);
    for (uint32_t k = 0; k < 3 * m->nv; ++k) start[k] = 2.0f * m->pos[k]; /* stretched 2x */
    set_state(c, start);
    double e0 = eq7(c), prev = e0;
    uint32_t increases = 0;
    char err[256];
    for (int f = 0; f < 200; ++f) {
        CHECK_EQ(rbc_solver_step(&s, h, err, sizeof err), RBC_OK);
        double e = eq7(c);
        /* Slack for float rounding of the positions: relative 1e-5 of the energy. */
        if (e > prev * (1.0 + 1e-5)) {
            increases++;
            fprintf(stderr, "%s: frame %d: Eq. 7 rose from %.9g to %.9g\n", name, f, prev, e);
        }
        prev = e;
    }
    printf("%s: Eq. 7 %.4g -> %.4g after 200 frames of %u iterations (integration off)\n", name,
           e0, prev, linear);
    CHECK_EQ(increases, 0);
    CHECK(prev < 0.5 * e0); /* it does shrink back */
    free(start);
    rbc_solver_fini(&s);
}

/* 3. Bitwise the same positions with 1 and 2 threads. */
static void test_thread_independence(const test_mesh *m) {
    float *out[2];
    for (int run = 0; run < 2; ++run) {
        rbc_allocator a = rbc_allocator_default();
        rbc_solver s;
        CHECK_EQ(rbc_solver_init(&s, &a, (uint32_t)run + 1), RBC_OK);
        s.substeps = 2;
        uint32_t pins[2] = {0, 99};
        rbc_cloth_state *c = make_cloth(&s, m, pins, 2, 0.5f);
        char err[256];
        for (int f = 0; f < 60; ++f) CHECK_EQ(rbc_solver_step(&s, 1.0f / 120.0f, err, sizeof err), RBC_OK);
        out[run] = malloc(sizeof(float) * 3 * m->nv);
        rbc_cloth_state_read(c, out[run]);
        rbc_solver_fini(&s);
    }
    CHECK(memcmp(out[0], out[1], sizeof(float) * 3 * m->nv) == 0);
    free(out[0]);
    free(out[1]);
}

int main(void) {
    test_mesh g = mesh_grid(20, 20, 1.0f / 19.0f);
    test_rbgs_equals_gs("grid 20x20", &g);
    mesh_free(&g);
    test_mesh split = mesh_split_triangles(6);
    test_rbgs_equals_gs("split triangles 6", &split);

    test_mesh paper = mesh_grid(100, 100, 1.0f / 99.0f);
    test_monotone("grid 100x100", &paper, 11);
    test_monotone("split triangles 6", &split, 3);
    mesh_free(&split);

    test_thread_independence(&paper);
    mesh_free(&paper);
    return check_report("core_rbgs");
}
