/* test_behaviour.c -- what a host can observe through abi/rbcloth.h when every
 * input is valid: free fall against the closed-form Verlet solution, pins,
 * damping, the built-in colliders, the collision callback, instability handling,
 * stats (counts and Eq. 7), the allocator and log hooks, silence on
 * stdout/stderr, and the thread contract.
 *
 * Every tolerance is derived in a comment next to it from float rounding (ulp =
 * spacing of floats at the magnitude involved; FLT_EPSILON = ulp(1) = 2^-23) or
 * from the physics of the scene; none was tuned to make a run pass.
 */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stddef.h>
#include <sys/stat.h>
#include <unistd.h>

#include "abi_util.h"

static pthread_t MAIN_THREAD;

static rbc_world_id make_world(uint32_t substeps, uint32_t threads) {
    rbc_world_def d = abi_world_def_fixed();
    d.substeps = substeps;
    d.thread_count = threads;
    rbc_world_id w = test_world(&d);
    if (!w) exit(1); /* every test needs its world */
    return w;
}

/* The default collider def of a shape. */
static rbc_collider_def shape_def(rbc_shape shape) {
    rbc_collider_def d = rbc_collider_def_default();
    d.shape = shape;
    return d;
}

static rbc_cloth_id make_cloth(rbc_world_id w, const rbc_cloth_def *d) {
    rbc_cloth_id c = 0;
    rbc_result r = rbc_cloth_create(w, d, &c);
    CHECK_EQ(r, RBC_OK);
    if (r != RBC_OK) {
        fprintf(stderr, "make_cloth: %s\n", rbc_last_error());
        exit(1);
    }
    return c;
}

static void step_ok(rbc_world_id w, float dt, int line) {
    rbc_result r = rbc_world_step(w, dt);
    CHECK_EQ(r, RBC_OK);
    if (r != RBC_OK) fprintf(stderr, "  line %d: step -> %s: %s\n", line, rbc_result_string(r), rbc_last_error());
}
#define STEP_OK(w, dt) step_ok((w), (dt), __LINE__)

/* ========================================================================= */
/* (a) Free fall                                                             */
/* ========================================================================= */

/* Four isolated vertices (no quads, no springs, mass 1 kg) under gravity g with
 * one substep of h. Verlet with zero initial velocity (previous position = rest
 * position): y_1 = y_0 + g h^2, y_{k+1} = 2 y_k - y_{k-1} + g h^2, hence
 *     y_n = y_0 + g h^2 n (n + 1) / 2.
 * Without springs the global step (Eq. 6) reduces to p = (m/h^2 y) / (m/h^2) = y.
 *
 * Tolerance. The library works in float. A rounding error e made at step j in
 * y_j propagates through the recurrence e_{k+1} = 2 e_k - e_{k-1} as
 * (k - j + 1) e at step k, so errors of at most u per step add up to at most
 * u * n (n + 1) / 2 after n steps. Per step: 2y - y_prev (1 rounding), + g h^2
 * (1), the spring-free solve (m/h^2 * y) / (m/h^2) (2), 4 roundings of at most
 * half an ulp at the largest magnitude M reached, so u = 2 ulp(M); plus the
 * constant g h^2 itself is formed in float with relative error <= 3 eps (h^2,
 * times g, and one spare), a systematic error that accumulates the same way:
 * 3 eps |g| h^2 per step. Bound: n (n + 1) / 2 * (2 ulp(M) + 3 eps |g| h^2).
 * For n = 50, h = 0.01, M = 1.25 m this is 3.1e-4 m, while the nearest wrong
 * scheme (n^2/2 instead of n(n+1)/2, or an explicit-Euler start) is off by
 * g h^2 n / 2 = 2.5e-2 m: the test separates them by 80x. */
static void test_free_fall(void) {
    rbc_world_def wd = abi_world_def_fixed();
    wd.gravity[0] = 0.0f;
    wd.gravity[1] = -9.81f;
    wd.gravity[2] = 0.0f;
    wd.substeps = 1;
    wd.thread_count = 1;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_OK);
    const float p0[12] = {0.0f, 0.0f, 0.0f, 0.5f, 0.0f, 0.0f,
                          0.0f, 0.0f, 0.5f, 1.0f, 0.0f, 1.0f};
    rbc_cloth_def cd = rbc_cloth_def_default();
    cd.vertex_count = 4;
    cd.positions = p0;
    cd.quad_count = 0;
    cd.quads = NULL;
    cd.vertex_mass = 1.0f;
    rbc_cloth_id c = make_cloth(w, &cd);

    const float h = 0.01f;
    const double g = (double)-9.81f, hd = (double)h;
    const int n = 50;
    const double M = 1.25; /* |y_50| = 9.81e-4 * 1275 = 1.251; x, z <= 1 */
    const double u = 2.0 * test_ulp(M) + 3.0 * FLT_EPSILON * fabs(g) * hd * hd;
    int bad_steps = 0;
    double worst_ratio = 0.0;
    for (int k = 1; k <= n; k++) {
        STEP_OK(w, h);
        uint32_t nv = 0;
        float *p = test_read(w, c, &nv);
        if (!p) { CHECK(0); break; }
        const double tol = u * k * (k + 1) / 2.0;
        const double y_expect = g * hd * hd * k * (k + 1) / 2.0;
        for (uint32_t v = 0; v < 4; v++) {
            double dy = fabs((double)p[3 * v + 1] - (p0[3 * v + 1] + y_expect));
            double dx = fabs((double)p[3 * v + 0] - p0[3 * v + 0]);
            double dz = fabs((double)p[3 * v + 2] - p0[3 * v + 2]);
            worst_ratio = fmax(worst_ratio, fmax(dy, fmax(dx, dz)) / tol);
            if (dy > tol || dx > tol || dz > tol) {
                if (bad_steps++ < 5)
                    fprintf(stderr, "  free fall step %d vertex %u: got (%.9g %.9g %.9g), want "
                            "(%.9g %.9g %.9g), tol %.3g\n", k, v, p[3 * v], p[3 * v + 1],
                            p[3 * v + 2], p0[3 * v], p0[3 * v + 1] + y_expect, p0[3 * v + 2], tol);
            }
        }
        free(p);
    }
    CHECK_EQ(bad_steps, 0);
    printf("free fall: %d steps, largest error %.3g of its bound\n", n, worst_ratio);
    rbc_world_stats st = test_stats(w);
    CHECK_EQ(st.step_count, (uint64_t)n);
    CHECK_EQ(st.particle_count, 4);
    CHECK_EQ(st.spring_count, 0);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
}

/* ========================================================================= */
/* (b) Pins                                                                  */
/* ========================================================================= */

static void test_pins(void) {
    rbc_world_id w = make_world(2, 0);
    test_grid g = test_grid_make(20, 20, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 19};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id c = make_cloth(w, &cd);

    /* Pinned vertices stay at their initial positions, bit for bit, every step:
     * the header says they are pinned "at their initial positions", and a pin is
     * a position written, not computed, so no tolerance applies. */
    int moved = 0, nonfinite = 0;
    float ymin = INFINITY;
    for (int k = 0; k < 200; k++) {
        STEP_OK(w, 1.0f / 60.0f);
        uint32_t n = 0;
        float *p = test_read(w, c, &n);
        if (!p) { CHECK(0); break; }
        for (int a = 0; a < 2; a++)
            if (memcmp(p + 3 * pins[a], g.positions + 3 * pins[a], 3 * sizeof(float)) != 0) {
                if (moved++ < 3)
                    fprintf(stderr, "  step %d: pin %u at (%.9g %.9g %.9g)\n", k, pins[a],
                            p[3 * pins[a]], p[3 * pins[a] + 1], p[3 * pins[a] + 2]);
            }
        if (!test_all_finite(p, 3 * (size_t)n)) nonfinite++;
        for (uint32_t v = 0; v < n; v++) ymin = fminf(ymin, p[3 * v + 1]);
        free(p);
    }
    CHECK_EQ(moved, 0);
    CHECK_EQ(nonfinite, 0);
    /* And the rest of the cloth did hang down (so the pins held real load): the
     * far edge falls at least 0.5 m within 3.3 s (it hangs ~0.95 m below). */
    CHECK(ymin < 0.5f);

    /* set_pin moves pin 0 to a target over the substeps of the next step: after
     * that step it is exactly at the target (a written value: bitwise). */
    uint32_t n = 0;
    float *p = test_read(w, c, &n);
    const float target[3] = {g.positions[0] + 0.1f, g.positions[1] + 0.05f,
                             g.positions[2] - 0.02f};
    CHECK_EQ(rbc_cloth_set_pin(w, c, 0, target), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    free(p);
    p = test_read(w, c, &n);
    CHECK(p && memcmp(p, target, sizeof target) == 0);
    if (p && memcmp(p, target, sizeof target) != 0)
        fprintf(stderr, "  set_pin: vertex 0 at (%.9g %.9g %.9g), target (%.9g %.9g %.9g)\n",
                p[0], p[1], p[2], target[0], target[1], target[2]);
    CHECK(p && memcmp(p + 3 * 19, g.positions + 3 * 19, 3 * sizeof(float)) == 0);
    /* It stays there. */
    for (int k = 0; k < 10; k++) STEP_OK(w, 1.0f / 60.0f);
    free(p);
    p = test_read(w, c, &n);
    CHECK(p && memcmp(p, target, sizeof target) == 0);

    /* Pinning a free vertex (399, the far corner) pins it at the target. */
    const float t399[3] = {0.95f, 0.2f, 0.3f};
    CHECK_EQ(rbc_cloth_set_pin(w, c, 399, t399), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    free(p);
    p = test_read(w, c, &n);
    CHECK(p && memcmp(p + 3 * 399, t399, sizeof t399) == 0);

    /* Releasing pin 0 lets it fall: starting at rest, after 0.5 s a corner hanging
     * from a cloth of 0.95 m drops far more than 0.1 m (free fall: 1.2 m; a 1 m
     * pendulum released from horizontal: > 0.5 m). */
    CHECK_EQ(rbc_cloth_set_pin(w, c, 0, NULL), RBC_OK);
    for (int k = 0; k < 30; k++) STEP_OK(w, 1.0f / 60.0f);
    free(p);
    p = test_read(w, c, &n);
    CHECK(p && p[1] < target[1] - 0.1f);
    CHECK(p && test_all_finite(p, 3 * (size_t)n));
    /* The other pins did not move. */
    CHECK(p && memcmp(p + 3 * 19, g.positions + 3 * 19, 3 * sizeof(float)) == 0);
    CHECK(p && memcmp(p + 3 * 399, t399, sizeof t399) == 0);
    free(p);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* ========================================================================= */
/* (c) A damped hanging cloth comes to rest                                  */
/* ========================================================================= */

/* 20 x 20 grid, 0.95 m square, pins at two corners, damping c = 2 /s, frames of
 * h = 1/60 s, one substep. Measured: the largest per-vertex displacement between
 * consecutive frames over one second starting at T = 20 s.
 *
 * Bound. Damping -c v as an acceleration is mass-proportional: every mode of
 * frequency w > c/2 keeps its frequency and its amplitude decays as e^{-ct/2}.
 * The slowest mode is the swing about the pin line, w ~ sqrt(g / l) with l at
 * most the cloth diagonal 1.34 m, so w >= 2.7 /s > c/2 = 1 /s: underdamped, and
 * the scheme's own numerical damping only adds to c. Every vertex starts at rest
 * and can drop at most H = 1.34 m, so speeds are at most sqrt(2 g H) = 5.1 m/s.
 * At T = 20 s: v <= 5.1 e^{-20} = 1.1e-8 m/s, i.e. 1.8e-10 m per frame.
 * Rounding keeps the float state from settling exactly: each frame rewrites
 * each coordinate at most ~32 times (Verlet 3, local step, 11 Red-Black sweeps
 * of the global step with a few operations each), each rounding by at most half
 * an ulp at the cloth's magnitude (|coords| < 2 m, ulp 1.2e-7): 16 ulp per frame.
 * Verlet carries such a jump on as a velocity that damping shrinks by
 * (1 - c h) per frame, so the jumps add up to at most 1/(c h) = 30 times one
 * frame's: 480 ulp = 5.7e-5 m. Bound = 1.8e-10 + 5.7e-5 m. A cloth that is still
 * moving (or undamped and swinging at ~1 m/s) moves ~1e-2 m per frame. */
static void test_damped_rest(void) {
    rbc_world_id w = make_world(1, 0);
    test_grid g = test_grid_make(20, 20, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 19};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    cd.damping = 2.0f;
    rbc_cloth_id c = make_cloth(w, &cd);
    const float h = 1.0f / 60.0f;
    const double c_damp = 2.0, T = 20.0;
    const double v0 = sqrt(2.0 * 9.81 * 1.34);
    const double bound = v0 * exp(-c_damp * T / 2.0) * h +
                         (1.0 / (c_damp * h)) * 32.0 * 0.5 * test_ulp(1.9);
    int nonfinite = 0;
    for (int k = 0; k < (int)(T * 60.0); k++) {
        STEP_OK(w, h);
        if (k % 60 == 59) {
            uint32_t n = 0;
            float *p = test_read(w, c, &n);
            if (!p || !test_all_finite(p, 3 * (size_t)n)) nonfinite++;
            free(p);
        }
    }
    uint32_t n = 0;
    float *prev = test_read(w, c, &n);
    double dmax = 0.0, cmax = 0.0;
    for (int k = 0; k < 60 && prev; k++) {
        STEP_OK(w, h);
        float *p = test_read(w, c, &n);
        if (!p || !test_all_finite(p, 3 * (size_t)n)) { nonfinite++; free(p); break; }
        for (uint32_t v = 0; v < n; v++) {
            double dx = p[3 * v] - (double)prev[3 * v], dy = p[3 * v + 1] - (double)prev[3 * v + 1],
                   dz = p[3 * v + 2] - (double)prev[3 * v + 2];
            dmax = fmax(dmax, sqrt(dx * dx + dy * dy + dz * dz));
            for (int a = 0; a < 3; a++) cmax = fmax(cmax, fabs(p[3 * v + a]));
        }
        free(prev);
        prev = p;
    }
    free(prev);
    CHECK_EQ(nonfinite, 0);
    CHECK(cmax < 1.9); /* the magnitude the rounding bound assumed */
    CHECK_NEAR(dmax, 0.0, bound);
    printf("damped rest: max per-frame displacement after %.0f s: %.3g m (bound %.3g m)\n", T,
           dmax, bound);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* ========================================================================= */
/* (d) Built-in colliders                                                    */
/* ========================================================================= */

/* After every step no vertex is closer to the surface than the thickness.
 * Projection onto a sphere c + e r / |e| rounds: e (1 per coordinate), |e|^2 (5),
 * sqrt, r/|e|, times e, plus c (1 each): about 6 roundings of at most half an ulp
 * of the largest coordinate magnitude M, plus r + thickness (1): tolerance
 * 8 ulp(M). The plane projection p - (n.(p - o) - t) n has fewer operations;
 * the same 8 ulp(M) covers it. For a tilted plane the library forms the normal
 * from the float quaternion in float, a direction off by a few eps from ours
 * (computed in double), which moves n.(p - o) by at most 4 eps |p - o|. */
static double max_abs_coord(const float *p, uint32_t n) {
    double m = 0.0;
    for (size_t k = 0; k < 3 * (size_t)n; k++) m = fmax(m, fabs(p[k]));
    return m;
}

static void test_sphere(void) {
    rbc_world_id w = make_world(2, 0);
    rbc_collider_def kd = shape_def(RBC_SHAPE_SPHERE);
    kd.radius = 0.5f;
    kd.thickness = 0.01f;
    kd.position[0] = 0.0f;
    kd.position[1] = 0.0f;
    kd.position[2] = 0.0f;
    rbc_collider_id k = 0;
    CHECK_EQ(rbc_collider_create(w, &kd, &k), RBC_OK);
    /* 20 x 20 cloth, 0.95 m square centred above the sphere at y = 0.8. */
    test_grid g = test_grid_make(20, 20, 0.05f, -0.475f, 0.8f, -0.475f);
    rbc_cloth_def cd = test_grid_def(&g, NULL, 0);
    rbc_cloth_id c = make_cloth(w, &cd);
    const double R = (double)kd.radius + (double)kd.thickness;
    int inside = 0;
    double worst = INFINITY;
    float mid_y_1s = -INFINITY;
    float *p = NULL;
    uint32_t n = 0;
    for (int s = 0; s < 180; s++) {
        STEP_OK(w, 1.0f / 60.0f);
        free(p);
        p = test_read(w, c, &n);
        if (!p) { CHECK(0); break; }
        const double tol = 8.0 * test_ulp(max_abs_coord(p, n));
        if (s == 59) mid_y_1s = p[3 * (10 + 20 * 10) + 1];
        for (uint32_t v = 0; v < n; v++) {
            double x = p[3 * v], y = p[3 * v + 1], z = p[3 * v + 2];
            double d = sqrt(x * x + y * y + z * z) - R;
            worst = fmin(worst, d);
            if (d < -tol && inside++ < 5)
                fprintf(stderr, "  step %d vertex %u: %.3g m inside sphere+thickness (tol %.3g)\n",
                        s, v, -d, tol);
        }
    }
    CHECK_EQ(inside, 0);
    /* The cloth did land on the sphere: something touches it (resting contact is
     * projected onto the surface, so within a millimetre is generous), and 1 s in
     * (0.75 s after landing) the middle of the cloth lies on top of the sphere
     * (y ~ 0.51), not below it (no tunnelling). Later the frictionless cloth may
     * slide off, which is why this is not checked at the end. */
    CHECK(worst < 1e-3);
    CHECK(mid_y_1s > 0.4f);
    printf("sphere: closest approach %.3g m from radius + thickness, middle at y %.4g after 1 s\n",
           worst, mid_y_1s);
    CHECK(p && test_all_finite(p, 3 * (size_t)n));
    free(p);

    /* Moving the sphere by set_transform moves the contact: put it 0.3 m higher;
     * after one step nothing is inside it at its new place. */
    const float up[3] = {0.0f, 0.3f, 0.0f}, q[4] = {0, 0, 0, 1};
    CHECK_EQ(rbc_collider_set_transform(w, k, up, q), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    p = test_read(w, c, &n);
    if (p) {
        const double tol = 8.0 * test_ulp(max_abs_coord(p, n));
        int in2 = 0;
        for (uint32_t v = 0; v < n; v++) {
            double x = p[3 * v], y = p[3 * v + 1] - 0.3, z = p[3 * v + 2];
            if (sqrt(x * x + y * y + z * z) - R < -tol) in2++;
        }
        CHECK_EQ(in2, 0);
    }
    free(p);
    CHECK_EQ(test_stats(w).collider_count, 1);
    CHECK_EQ(rbc_collider_destroy(w, k), RBC_OK);
    CHECK_EQ(test_stats(w).collider_count, 0);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* Signed distance of p from the plane (o, n) minus the kept thickness t, and the
 * count of vertices beyond the tolerance. */
static int count_below_plane(const float *p, uint32_t n, const double o[3], const double nrm[3],
                             double t, double *min_d, int step) {
    const double M = max_abs_coord(p, n);
    double maxdist = 0.0;
    for (uint32_t v = 0; v < n; v++) {
        double dd = 0.0;
        for (int a = 0; a < 3; a++) dd += (p[3 * v + a] - o[a]) * (p[3 * v + a] - o[a]);
        maxdist = fmax(maxdist, sqrt(dd));
    }
    const double tol = 8.0 * test_ulp(M) + 4.0 * FLT_EPSILON * maxdist;
    int below = 0;
    for (uint32_t v = 0; v < n; v++) {
        double d = 0.0;
        for (int a = 0; a < 3; a++) d += (p[3 * v + a] - o[a]) * nrm[a];
        d -= t;
        if (d < *min_d) *min_d = d;
        if (d < -tol && below++ < 3)
            fprintf(stderr, "  step %d vertex %u: %.3g m below plane+thickness (tol %.3g)\n", step,
                    v, -d, tol);
    }
    return below;
}

/* Steps w `steps` times at 1/60 s: the vertices of cloth c below the plane (o, nrm) by
 * more than count_below_plane allows, summed over the steps; *min_d: the closest
 * approach to plane + t in the last step read. */
static int fall_onto_plane(rbc_world_id w, rbc_cloth_id c, int steps, const double o[3],
                           const double nrm[3], double t, double *min_d) {
    int below = 0;
    uint32_t n = 0;
    for (int s = 0; s < steps; s++) {
        STEP_OK(w, 1.0f / 60.0f);
        float *p = test_read(w, c, &n);
        if (!p) { CHECK(0); break; }
        *min_d = INFINITY;
        below += count_below_plane(p, n, o, nrm, t, min_d, s);
        free(p);
    }
    return below;
}

static void test_planes(void) {
    /* Horizontal plane at y = -0.3, thickness 0.02; cloth dropped from y = 0.5. */
    rbc_world_id w = make_world(1, 0);
    rbc_collider_def kd = shape_def(RBC_SHAPE_PLANE);
    kd.thickness = 0.02f;
    kd.position[1] = -0.3f;
    rbc_collider_id k = 0;
    CHECK_EQ(rbc_collider_create(w, &kd, &k), RBC_OK);
    test_grid g = test_grid_make(20, 20, 0.05f, -0.475f, 0.5f, -0.475f);
    rbc_cloth_def cd = test_grid_def(&g, NULL, 0);
    rbc_cloth_id c = make_cloth(w, &cd);
    double o[3] = {0.0, (double)kd.position[1], 0.0};
    const double up[3] = {0.0, 1.0, 0.0};
    double min_d = INFINITY;
    CHECK_EQ(fall_onto_plane(w, c, 120, o, up, kd.thickness, &min_d), 0);
    uint32_t n = 0;
    /* After 2 s the cloth lies on the plane (fall time from 0.8 m above: 0.4 s). */
    CHECK(min_d < 1e-3);

    /* Lift the plane by 1 cm with set_transform: after one step everything is
     * above it at its new place (the resting cloth was 1 cm below that). Only
     * 1 cm, because the push gives the cloth an upward velocity of 1 cm per
     * frame (0.6 m/s), which the fall below must overcome. */
    const float lift[3] = {0.0f, -0.29f, 0.0f}, ident[4] = {0, 0, 0, 1};
    CHECK_EQ(rbc_collider_set_transform(w, k, lift, ident), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    {
        float *p = test_read(w, c, &n);
        o[1] = (double)lift[1];
        min_d = INFINITY;
        if (p) CHECK_EQ(count_below_plane(p, n, o, up, kd.thickness, &min_d, -1), 0);
        free(p);
    }
    /* Destroying the plane lets the cloth fall through where it was: 0.5 s with
     * 0.6 m/s upward start is 0.3 - 1.23 = -0.93 m of travel; require 0.3 m. */
    CHECK_EQ(rbc_collider_destroy(w, k), RBC_OK);
    for (int s = 0; s < 30; s++) STEP_OK(w, 1.0f / 60.0f);
    {
        float *p = test_read(w, c, &n);
        float ymax = -INFINITY;
        for (uint32_t v = 0; p && v < n; v++) ymax = fmaxf(ymax, p[3 * v + 1]);
        CHECK(p && ymax < lift[1] + 0.02f - 0.3f);
        free(p);
    }
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);

    /* A plane tilted 0.3 rad about z, through (0, -0.3, 0): normal
     * R(q) (0, 1, 0) = (-sin 0.3, cos 0.3, 0). Checked for 1 s of sliding. */
    w = make_world(1, 0);
    const float th = 0.3f;
    kd = shape_def(RBC_SHAPE_PLANE);
    kd.thickness = 0.01f;
    kd.position[1] = -0.3f;
    kd.rotation[0] = 0.0f;
    kd.rotation[1] = 0.0f;
    kd.rotation[2] = sinf(th / 2.0f);
    kd.rotation[3] = cosf(th / 2.0f);
    CHECK_EQ(rbc_collider_create(w, &kd, &k), RBC_OK);
    c = make_cloth(w, &cd);
    {
        /* The normal from the float quaternion, in double. */
        double qz = kd.rotation[2], qw = kd.rotation[3], nq = sqrt(qz * qz + qw * qw);
        qz /= nq;
        qw /= nq;
        /* Rotation of (0,1,0) by (0,0,qz,qw): (-2 qz qw, 1 - 2 qz^2, 0). */
        const double nrm[3] = {-2.0 * qz * qw, 1.0 - 2.0 * qz * qz, 0.0};
        CHECK_NEAR(nrm[0], -sin(0.3), 1e-6);
        const double ot[3] = {0.0, (double)kd.position[1], 0.0};
        double md = INFINITY;
        CHECK_EQ(fall_onto_plane(w, c, 60, ot, nrm, kd.thickness, &md), 0);
        CHECK(md < 1e-3); /* it reached the plane: the tilt was applied, not ignored */
    }
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* ========================================================================= */
/* (e) The collision callback                                                */
/* ========================================================================= */

typedef struct cb_ctx {
    rbc_world_id world;
    rbc_cloth_id id[2];
    uint32_t nv[2];
    uint32_t substeps;          /* expected per step */
    float dt;                   /* step dt */
    int calls;                  /* in the current step */
    int total_calls;
    int bad_world, bad_dt, bad_count, bad_ids, bad_thread, bad_prev, bad_user;
    float *last[2];             /* positions at the end of the previous callback */
    int have_last;
    int edit_on_last;           /* edit positions in the last substep */
    int fail_on;                /* return non-zero on this call (1-based), 0 never */
    int nan_on;                 /* write NaN on this call (1-based), 0 never */
} cb_ctx;

static int32_t record_cb(void *user, rbc_world_id world, float dt,
                         const rbc_collision_cloth *cloths, uint32_t cloth_count) {
    cb_ctx *x = (cb_ctx *)user;
    if (!x || x->world != world) {
        if (x) x->bad_world++;
        return 0;
    }
    x->calls++;
    x->total_calls++;
    if (!pthread_equal(pthread_self(), MAIN_THREAD)) x->bad_thread++;
    /* dt/substeps: a correctly rounded float division is within half an ulp of the
     * exact quotient; a library that multiplies by 1/substeps instead is within
     * one ulp. Allow one ulp. */
    double want = (double)x->dt / x->substeps;
    if (fabs((double)dt - want) > test_ulp(want)) {
        if (x->bad_dt++ < 3) fprintf(stderr, "  callback dt %.9g, want %.9g\n", dt, want);
    }
    if (cloth_count != 2 || !cloths) {
        x->bad_count++;
        return 0;
    }
    for (uint32_t k = 0; k < 2; k++) {
        /* The order of cloths is not specified: match by id. */
        int slot = cloths[k].cloth == x->id[0] ? 0 : cloths[k].cloth == x->id[1] ? 1 : -1;
        if (slot < 0 || (k == 1 && cloths[0].cloth == cloths[1].cloth)) {
            x->bad_ids++;
            continue;
        }
        if (cloths[k].vertex_count != x->nv[slot] || !cloths[k].positions ||
            !cloths[k].previous_positions) {
            x->bad_count++;
            continue;
        }
        /* Positions at the start of this substep = those at the end of the
         * previous one, as the previous callback left them. Cloth 1's vertex 0
         * is pinned: the header puts pins back after the callback, so where a
         * pinned vertex is during the callback is not specified; it is skipped. */
        if (x->have_last) {
            uint32_t from = slot == 1 ? 1 : 0;
            if (memcmp(cloths[k].previous_positions + 3 * from, x->last[slot] + 3 * from,
                       sizeof(float) * 3 * (x->nv[slot] - from)) != 0)
                x->bad_prev++;
        }
    }
    if (x->nan_on && x->total_calls == x->nan_on) cloths[0].positions[4] = NAN;
    int last_substep = (uint32_t)x->calls == x->substeps;
    if (x->edit_on_last && last_substep) {
        for (uint32_t k = 0; k < 2; k++) {
            float *p = cloths[k].positions;
            if (cloths[k].cloth == x->id[0]) {
                p[3 * 2 + 0] = 5.0f; p[3 * 2 + 1] = 6.0f; p[3 * 2 + 2] = 7.0f;
            } else {
                p[3 * 0 + 0] = 9.0f; p[3 * 0 + 1] = 9.0f; p[3 * 0 + 2] = 9.0f; /* pinned */
                p[3 * 5 + 0] = -1.0f; p[3 * 5 + 1] = -2.0f; p[3 * 5 + 2] = -3.0f;
            }
        }
    }
    for (uint32_t k = 0; k < 2; k++) {
        int slot = cloths[k].cloth == x->id[0] ? 0 : 1;
        if (cloths[k].vertex_count == x->nv[slot])
            memcpy(x->last[slot], cloths[k].positions, sizeof(float) * 3 * x->nv[slot]);
    }
    x->have_last = 1;
    if (x->fail_on && x->total_calls == x->fail_on) return 1;
    return 0;
}

/* How often record_cb found each thing wrong (world, dt, counts, ids, thread, previous
 * positions), those that did named on stderr: 0 when nothing was. */
static int cb_wrong(const cb_ctx *x) {
    const int n[6] = {x->bad_world, x->bad_dt,     x->bad_count,
                      x->bad_ids,   x->bad_thread, x->bad_prev};
    static const char *const what[6] = {"world", "dt", "count", "ids", "thread", "prev"};
    int sum = 0;
    for (int k = 0; k < 6; ++k) {
        if (n[k]) fprintf(stderr, "  callback: bad_%s %d times\n", what[k], n[k]);
        sum += n[k];
    }
    return sum;
}

static void test_callback(void) {
    rbc_world_id w = make_world(3, 0);
    test_grid ga = test_grid_make(5, 5, 0.1f, 0.0f, 1.0f, 0.0f);
    test_grid gb = test_grid_make(4, 6, 0.1f, 1.0f, 1.0f, 0.0f);
    rbc_cloth_def da = test_grid_def(&ga, NULL, 0);
    const uint32_t pin_b = 0;
    rbc_cloth_def db = test_grid_def(&gb, &pin_b, 1);
    cb_ctx x;
    memset(&x, 0, sizeof x);
    x.world = w;
    x.id[0] = make_cloth(w, &da);
    x.id[1] = make_cloth(w, &db);
    x.nv[0] = ga.vertex_count;
    x.nv[1] = gb.vertex_count;
    x.last[0] = (float *)malloc(sizeof(float) * 3 * x.nv[0]);
    x.last[1] = (float *)malloc(sizeof(float) * 3 * x.nv[1]);
    x.substeps = 3;
    x.dt = 0.02f;
    CHECK_EQ(rbc_world_set_collision_callback(w, record_cb, &x), RBC_OK);

    /* The first substep starts from the positions a host reads before the step. */
    for (int k = 0; k < 2; k++) {
        float *a = test_read(w, x.id[0], NULL), *b = test_read(w, x.id[1], NULL);
        memcpy(x.last[0], a, sizeof(float) * 3 * x.nv[0]);
        memcpy(x.last[1], b, sizeof(float) * 3 * x.nv[1]);
        free(a);
        free(b);
        x.have_last = 1;
        x.calls = 0;
        STEP_OK(w, x.dt);
        CHECK_EQ(x.calls, 3); /* once per substep */
    }
    /* Edits in the last substep take effect; a moved pin goes back on its pin. */
    x.edit_on_last = 1;
    x.calls = 0;
    STEP_OK(w, x.dt);
    x.edit_on_last = 0;
    {
        float *a = test_read(w, x.id[0], NULL), *b = test_read(w, x.id[1], NULL);
        const float e2[3] = {5, 6, 7}, e5[3] = {-1, -2, -3};
        CHECK(a && memcmp(a + 3 * 2, e2, sizeof e2) == 0);
        CHECK(b && memcmp(b + 3 * 5, e5, sizeof e5) == 0);
        CHECK(b && memcmp(b + 0, gb.positions + 0, 3 * sizeof(float)) == 0);
        /* The next step starts from these (prev check in the callback). */
        if (a && b) {
            memcpy(x.last[0], a, sizeof(float) * 3 * x.nv[0]);
            memcpy(x.last[1], b, sizeof(float) * 3 * x.nv[1]);
        }
        free(a);
        free(b);
    }
    x.calls = 0;
    STEP_OK(w, x.dt);
    CHECK_EQ(x.calls, 3);
    /* Changing the substep count changes the number of calls and their dt. */
    CHECK_EQ(rbc_world_set_iterations(w, 5, 1, 11), RBC_OK);
    x.substeps = 5;
    x.calls = 0;
    {
        float *a = test_read(w, x.id[0], NULL), *b = test_read(w, x.id[1], NULL);
        memcpy(x.last[0], a, sizeof(float) * 3 * x.nv[0]);
        memcpy(x.last[1], b, sizeof(float) * 3 * x.nv[1]);
        free(a);
        free(b);
    }
    STEP_OK(w, x.dt);
    CHECK_EQ(x.calls, 5);
    CHECK_EQ(x.total_calls, 3 + 3 + 3 + 3 + 5);
    CHECK_EQ(cb_wrong(&x), 0);

    /* A failing callback (on substep 2 of 5): RBC_ERR_CALLBACK, the world as it
     * was, step_count unchanged. */
    x.have_last = 0;
    test_snap s = test_snap_take(w, x.id, 2);
    x.fail_on = x.total_calls + 2;
    x.calls = 0;
    rbc_result r = rbc_world_step(w, x.dt);
    CHECK_EQ(r, RBC_ERR_CALLBACK);
    CHECK(rbc_last_error()[0] != '\0');
    CHECK(test_snap_same(&s, __LINE__));
    x.fail_on = 0;
    test_snap_free(&s);

    /* Removing the callback: no more calls. */
    CHECK_EQ(rbc_world_set_collision_callback(w, NULL, NULL), RBC_OK);
    int before = x.total_calls;
    STEP_OK(w, x.dt);
    CHECK_EQ(x.total_calls, before);
    free(x.last[0]);
    free(x.last[1]);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&ga);
    test_grid_free(&gb);
}

/* ========================================================================= */
/* (e, f) A failed step restores the world: twin worlds                      */
/* ========================================================================= */

/* "The world as it was before the step" includes the velocity (the previous
 * positions Verlet keeps), which reading positions cannot show. Two worlds built
 * and stepped identically on one thread evolve bit for bit alike (checked first,
 * as a control); then one of them has a failed step; afterwards both are stepped
 * again and must still agree bit for bit. */
typedef struct fail_ctx {
    int mode;     /* 1: return non-zero; 2: write NaN into vertex 3's y; 3: write +Inf */
    int on_call;  /* which call of the step (1-based) */
    int calls;
} fail_ctx;

static int32_t failing_cb(void *user, rbc_world_id world, float dt,
                          const rbc_collision_cloth *cloths, uint32_t cloth_count) {
    fail_ctx *f = (fail_ctx *)user;
    if (++f->calls != f->on_call || cloth_count < 1) return 0;
    if (f->mode == 1) return -5;
    if (f->mode == 2) cloths[0].positions[3 * 3 + 1] = NAN;
    if (f->mode == 3) cloths[0].positions[3 * 3 + 1] = INFINITY;
    return 0;
}

static void twin_failure(int mode, const char *what) {
    test_grid g = test_grid_make(10, 10, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 9};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_world_id a = make_world(3, 1), b = make_world(3, 1);
    rbc_cloth_id ca = make_cloth(a, &cd), cb = make_cloth(b, &cd);
    /* Determinism of one thread: the premise of this check. */
    CHECK(test_twins_same(a, ca, b, cb, 5, 1.0f / 60.0f));

    fail_ctx f = {mode, 2, 0};
    CHECK_EQ(rbc_world_set_collision_callback(a, failing_cb, &f), RBC_OK);
    test_snap s = test_snap_take(a, &ca, 1);
    rbc_result r = rbc_world_step(a, 1.0f / 60.0f);
    CHECK_EQ(r, RBC_ERR_CALLBACK);
    if (r != RBC_ERR_CALLBACK) fprintf(stderr, "  %s: step -> %s\n", what, rbc_result_string(r));
    CHECK(rbc_last_error()[0] != '\0');
    CHECK(test_snap_same(&s, __LINE__));
    test_snap_free(&s);
    CHECK_EQ(rbc_world_set_collision_callback(a, NULL, NULL), RBC_OK);

    int same = test_twins_same(a, ca, b, cb, 5, 1.0f / 60.0f);
    CHECK(same);
    if (!same) fprintf(stderr, "  %s: the failed step left a trace (velocity not restored)\n", what);
    float *pa = test_read(a, ca, NULL);
    CHECK(pa && test_all_finite(pa, 3 * (size_t)g.vertex_count));
    CHECK_EQ(test_stats(a).step_count, test_stats(b).step_count);
    free(pa);
    rbc_world_destroy(a);
    rbc_world_destroy(b);
    test_grid_free(&g);
}

/* (f) Extreme but valid parameters. The header promises: a step that produces a
 * non-finite position returns RBC_ERR_UNSTABLE with the world restored. So the
 * only acceptable outcomes are RBC_OK with all positions finite, or
 * RBC_ERR_UNSTABLE with the world bitwise as before. */
static void extreme_step(rbc_world_id w, rbc_cloth_id c, float dt, const char *what) {
    test_snap s = test_snap_take(w, &c, 1);
    rbc_result r = rbc_world_step(w, dt);
    if (r == RBC_OK) {
        float *p = test_read(w, c, NULL);
        int finite = p && test_all_finite(p, 3 * (size_t)s.n[0]);
        CHECK(finite);
        if (!finite) fprintf(stderr, "  %s: RBC_OK with non-finite positions\n", what);
        free(p);
    } else {
        CHECK_EQ(r, RBC_ERR_UNSTABLE);
        if (r != RBC_ERR_UNSTABLE) fprintf(stderr, "  %s: got %s\n", what, rbc_result_string(r));
        CHECK(rbc_last_error()[0] != '\0');
        CHECK(test_snap_same(&s, __LINE__));
    }
    test_snap_free(&s);
}

static void test_unstable(void) {
    twin_failure(1, "callback returning non-zero");
    twin_failure(2, "callback writing NaN");
    twin_failure(3, "callback writing Inf");

    test_grid g = test_grid_make(10, 10, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 9};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    cd.stiffness = 1e30f;
    rbc_world_id w = make_world(1, 0);
    rbc_cloth_id c = 0;
    /* No upper limit on stiffness is documented: 1e30 N/m is valid input. */
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    if (!c) {
        fprintf(stderr, "  stiffness 1e30 refused: %s\n", rbc_last_error());
        rbc_world_destroy(w);
        test_grid_free(&g);
        return;
    }
    extreme_step(w, c, 1e3f, "stiffness 1e30, dt 1e3");
    extreme_step(w, c, 1e30f, "stiffness 1e30, dt 1e30");
    /* Gravity 1e30 m/s^2 with dt 1e30 s: h^2 g = 1e90 overflows float, so a
     * faithful solver cannot stay finite here. */
    const float huge_g[3] = {0.0f, -1e30f, 0.0f};
    CHECK_EQ(rbc_world_set_gravity(w, huge_g), RBC_OK);
    extreme_step(w, c, 1e30f, "gravity 1e30, dt 1e30");
    extreme_step(w, c, 1.0f, "gravity 1e30, dt 1");
    /* After all that the world still works with sane values. */
    const float g0[3] = {0.0f, -9.81f, 0.0f};
    CHECK_EQ(rbc_world_set_gravity(w, g0), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    float *p = test_read(w, c, NULL);
    CHECK(p && test_all_finite(p, 3 * (size_t)g.vertex_count));
    free(p);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* ========================================================================= */
/* (g) Stats                                                                 */
/* ========================================================================= */

/* Eq. 7 recomputed in double from positions read back: sum over springs of
 * (|p_i - p_j| - L_ij)^2, with L_ij from the rest positions. Also the largest
 * relative violation. `bound` receives the worst-case difference a float
 * implementation may have from this: its |p_i - p_j| has a relative error of at
 * most 3 eps (3 differences, 3 squares, 2 sums, a sqrt: each half an eps of the
 * result; the differences are exact here or contribute to the same count), its
 * L the same, and its term (d - L)^2 another 2 eps relative; summed in double. */
static double eq7_grid(const test_grid *g, const float *p, double *max_strain, double *bound) {
    double e = 0.0, ms = 0.0, b = 0.0;
    for (uint32_t j = 0; j < g->ny; j++)
        for (uint32_t i = 0; i < g->nx; i++) {
            uint32_t v = i + g->nx * j;
            uint32_t nb[2] = {v + 1, v + g->nx};
            int ok[2] = {i + 1 < g->nx, j + 1 < g->ny};
            for (int k = 0; k < 2; k++) {
                if (!ok[k]) continue;
                uint32_t u = nb[k];
                double d2 = 0.0, l2 = 0.0;
                for (int a = 0; a < 3; a++) {
                    double dd = (double)p[3 * v + a] - p[3 * u + a];
                    double dl = (double)g->positions[3 * v + a] - g->positions[3 * u + a];
                    d2 += dd * dd;
                    l2 += dl * dl;
                }
                double d = sqrt(d2), L = sqrt(l2), t = d - L;
                e += t * t;
                if (L > 0) ms = fmax(ms, fabs(d / L - 1.0));
                double err = 3.0 * FLT_EPSILON * (d + L);
                b += 2.0 * fabs(t) * err + err * err + 2.0 * FLT_EPSILON * t * t;
            }
        }
    if (max_strain) *max_strain = ms;
    if (bound) *bound = b + 1e-12 * e; /* + double summation: 19,800 * 2^-53 < 1e-12 */
    return e;
}

typedef struct stretch_ctx {
    const test_grid *g;
    uint32_t substeps;
    int calls;
    int active;
} stretch_ctx;

/* On the last substep: move every vertex to 3x its rest x and z (rest y). With a
 * grid spacing of 1/128 m all these numbers are exact floats. */
static int32_t stretch_cb(void *user, rbc_world_id world, float dt,
                          const rbc_collision_cloth *cloths, uint32_t cloth_count) {
    stretch_ctx *s = (stretch_ctx *)user;
    s->calls++;
    if (!s->active || (uint32_t)s->calls != s->substeps || cloth_count != 1) return 0;
    float *p = cloths[0].positions;
    for (uint32_t v = 0; v < s->g->vertex_count; v++) {
        p[3 * v + 0] = 3.0f * s->g->positions[3 * v + 0];
        p[3 * v + 1] = s->g->positions[3 * v + 1];
        p[3 * v + 2] = 3.0f * s->g->positions[3 * v + 2];
    }
    return 0;
}

static void test_stats_figures(void) {
    rbc_world_id w = make_world(1, 0);
    /* 100 x 100 grid, spacing 1/128 m (exact in float, as are all coordinates
     * i/128), at y = 1. */
    test_grid g = test_grid_make(100, 100, 1.0f / 128.0f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 99};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id c = make_cloth(w, &cd);

    uint32_t ns = 0, ncol = 0, nv = 0;
    CHECK_EQ(rbc_cloth_get_topology(w, c, &ns, &ncol), RBC_OK);
    CHECK_EQ(ns, 19800);
    CHECK_EQ(ncol, 2);
    ns = 0;
    CHECK_EQ(rbc_cloth_get_topology(w, c, &ns, NULL), RBC_OK);
    CHECK_EQ(ns, 19800);
    ncol = 0;
    CHECK_EQ(rbc_cloth_get_topology(w, c, NULL, &ncol), RBC_OK);
    CHECK_EQ(ncol, 2);
    CHECK_EQ(rbc_cloth_get_vertex_count(w, c, &nv), RBC_OK);
    CHECK_EQ(nv, 10000);

    rbc_world_stats st = test_stats(w);
    CHECK_EQ(st.cloth_count, 1);
    CHECK_EQ(st.collider_count, 0);
    CHECK_EQ(st.particle_count, 10000);
    CHECK_EQ(st.spring_count, 19800);
    CHECK_EQ(st.color_count, 2);
    CHECK_EQ(st.step_count, 0);
    CHECK(st.thread_count >= 1);
    CHECK(st.backend == RBC_BACKEND_CPU || st.backend == RBC_BACKEND_CUDA);
    /* At rest every spring has its rest length, computed from the same exact
     * floats: Eq. 7 and the strain are exactly 0. */
    CHECK_NEAR(st.error_eq7, 0.0, 0.0);
    CHECK_NEAR(st.max_strain, 0.0, 0.0);

    /* step_count counts successful steps only. */
    for (int k = 1; k <= 3; k++) {
        STEP_OK(w, 1.0f / 60.0f);
        CHECK_EQ(test_stats(w).step_count, (uint64_t)k);
    }
    CHECK_EQ(rbc_world_step(w, 0.0f), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(test_stats(w).step_count, 3);

    /* Iteration totals over the substeps of the last step. */
    CHECK_EQ(rbc_world_set_iterations(w, 2, 3, 5), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    st = test_stats(w);
    CHECK_EQ(st.substeps, 2);
    CHECK_EQ(st.nonlinear_iterations, 2 * 3);
    CHECK_EQ(st.linear_iterations, 2 * 3 * 5);
    CHECK_EQ(st.step_count, 4);
    CHECK(st.step_ms >= 0.0 && isfinite(st.step_ms));
    CHECK_EQ(rbc_world_set_iterations(w, 1, 1, 11), RBC_OK);

    /* Eq. 7 in the natural state (hanging for 100 frames) against our double
     * recomputation, within the float bound derived in eq7_grid. */
    for (int k = 0; k < 100; k++) STEP_OK(w, 1.0f / 60.0f);
    {
        float *p = test_read(w, c, NULL);
        double ms = 0.0, bound = 0.0;
        double mine = p ? eq7_grid(&g, p, &ms, &bound) : -1.0;
        st = test_stats(w);
        CHECK(mine > 0.0);
        CHECK_NEAR(st.error_eq7, mine, bound);
        printf("Eq. 7 hanging: library %.9g, ours %.9g, |diff| %.3g, bound %.3g\n", st.error_eq7,
               mine, fabs(st.error_eq7 - mine), bound);
        /* Strain: |d/L - 1| with d, L each within 3 eps: 6 eps (d/L) + 1 eps. */
        CHECK_NEAR(st.max_strain, ms, 7.0 * FLT_EPSILON * (ms + 1.0));
        free(p);
    }

    /* Eq. 7 in a stretched state of exact floats: every spring is 3 L long, L =
     * 1/128, except those at the two pins, which are put back after the callback
     * (still exact floats). Each term is computed exactly by any float or double
     * implementation (differences and squares of multiples of 2^-7, sqrt of
     * exact squares), so the only error is summation: relative 1e-6 admits a
     * double (2e-12) accumulator and rejects a careless float one (up to
     * 19,800 * 6e-8 = 1.2e-3). */
    stretch_ctx sc = {&g, 1, 0, 1};
    CHECK_EQ(rbc_world_set_collision_callback(w, stretch_cb, &sc), RBC_OK);
    sc.calls = 0;
    STEP_OK(w, 1.0f / 60.0f);
    CHECK_EQ(rbc_world_set_collision_callback(w, NULL, NULL), RBC_OK);
    {
        float *p = test_read(w, c, NULL);
        CHECK(p && p[3 * 50 + 0] == 150.0f / 128.0f); /* the edit took effect */
        double ms = 0.0;
        double mine = p ? eq7_grid(&g, p, &ms, NULL) : -1.0;
        st = test_stats(w);
        CHECK(mine > 0.0);
        CHECK_NEAR(st.error_eq7, mine, 1e-6 * mine);
        printf("Eq. 7 stretched: library %.12g, ours %.12g\n", st.error_eq7, mine);
        /* d / L is exact here too (multiples of 1/128 over 1/128). */
        CHECK_NEAR(st.max_strain, ms, 4.0 * FLT_EPSILON * ms);
        CHECK(ms >= 2.0); /* at least 3L / L - 1 */
        free(p);
    }

    /* A host with an older, shorter stats struct: only the fields that fit are
     * written. struct_size ends before step_count; the bytes after it keep our
     * marker whatever the call returns. */
    {
        union { rbc_world_stats s; unsigned char b[sizeof(rbc_world_stats)]; } u;
        memset(&u, 0xAB, sizeof u);
        const size_t cut = offsetof(rbc_world_stats, step_count);
        u.s.struct_size = (uint32_t)cut;
        rbc_result r = rbc_world_get_stats(w, &u.s);
        CHECK(test_bytes_are(&u, cut, sizeof u, 0xAB));
        if (r == RBC_OK) {
            CHECK_EQ(u.s.cloth_count, 1);
            CHECK_EQ(u.s.particle_count, 10000);
        }
    }

    /* A second cloth adds its counts; destroying it removes them. */
    test_grid g2 = test_grid_make(7, 5, 0.1f, 2.0f, 1.0f, 0.0f);
    rbc_cloth_def cd2 = test_grid_def(&g2, NULL, 0);
    rbc_cloth_id c2 = make_cloth(w, &cd2);
    st = test_stats(w);
    CHECK_EQ(st.cloth_count, 2);
    CHECK_EQ(st.particle_count, 10000 + 35);
    CHECK_EQ(st.spring_count, 19800 + test_grid_spring_count(&g2));
    CHECK_EQ(st.color_count, 2);
    CHECK_EQ(rbc_cloth_destroy(w, c2), RBC_OK);
    st = test_stats(w);
    CHECK_EQ(st.cloth_count, 1);
    CHECK_EQ(st.particle_count, 10000);
    CHECK_EQ(st.spring_count, 19800);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
    test_grid_free(&g2);
}

/* ========================================================================= */
/* (h) Allocator and log hooks; silence on stdout and stderr                 */
/* ========================================================================= */

#define MAX_LIVE 65536
typedef struct alloc_ctx {
    void *ptr[MAX_LIVE];
    size_t size[MAX_LIVE];
    size_t live;
    long allocs, frees;
    long bad_align_arg, bad_free, bad_size, bad_user;
    long fail_at;    /* fail the fail_at-th armed allocation (1-based); 0 never */
    long armed_count;
    int armed;
    int failed;      /* an allocation was refused */
} alloc_ctx;

static alloc_ctx AC;

static void *count_alloc(void *user, size_t size, size_t alignment) {
    alloc_ctx *a = (alloc_ctx *)user;
    if (a != &AC) { AC.bad_user++; return NULL; }
    if (alignment == 0 || (alignment & (alignment - 1)) != 0 || alignment > 64) a->bad_align_arg++;
    if (a->armed) {
        a->armed_count++;
        if (a->fail_at && a->armed_count == a->fail_at) {
            a->failed = 1;
            return NULL;
        }
    }
    if (a->live >= MAX_LIVE) return NULL;
    void *p = NULL;
    size_t al = alignment < sizeof(void *) ? sizeof(void *) : alignment;
    if ((al & (al - 1)) != 0) al = 64;
    if (posix_memalign(&p, al, size ? size : 1) != 0) return NULL;
    a->ptr[a->live] = p;
    a->size[a->live] = size;
    a->live++;
    a->allocs++;
    return p;
}

static void count_free(void *user, void *ptr, size_t size) {
    alloc_ctx *a = (alloc_ctx *)user;
    if (a != &AC) { AC.bad_user++; return; }
    if (!ptr) return; /* free(NULL) is harmless; nothing to account */
    for (size_t k = a->live; k-- > 0;) {
        if (a->ptr[k] == ptr) {
            if (a->size[k] != size) a->bad_size++;
            a->live--;
            a->ptr[k] = a->ptr[a->live];
            a->size[k] = a->size[a->live];
            a->frees++;
            free(ptr);
            return;
        }
    }
    a->bad_free++; /* not ours, or freed twice: do not touch it */
}

static void alloc_reset(void) {
    memset(&AC, 0, sizeof AC);
}

static rbc_world_def hooked_def(void) {
    rbc_world_def d = abi_world_def_fixed();
    d.alloc = count_alloc;
    d.free = count_free;
    d.alloc_user = &AC;
    d.thread_count = 2;
    return d;
}

static void test_counting_allocator(void) {
    alloc_reset();
    rbc_world_def d = hooked_def();
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&d, &w), RBC_OK);
    test_grid g = test_grid_make(20, 20, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 19};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id c = make_cloth(w, &cd), c2 = make_cloth(w, &cd);
    rbc_collider_def kd = shape_def(RBC_SHAPE_SPHERE);
    kd.position[1] = 0.2f;
    rbc_collider_id k = 0;
    CHECK_EQ(rbc_collider_create(w, &kd, &k), RBC_OK);
    for (int s = 0; s < 10; s++) STEP_OK(w, 1.0f / 60.0f);
    const float t[3] = {0.1f, 1.1f, 0.0f};
    CHECK_EQ(rbc_cloth_set_pin(w, c, 0, t), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    CHECK_EQ(rbc_cloth_destroy(w, c2), RBC_OK);
    CHECK_EQ(rbc_collider_destroy(w, k), RBC_OK);
    STEP_OK(w, 1.0f / 60.0f);
    CHECK(AC.allocs > 0); /* the hooks are used at all */
    printf("counting allocator: %ld allocations before world destroy\n", AC.allocs);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    CHECK_EQ(AC.live, 0);
    CHECK_EQ(AC.allocs, AC.frees);
    CHECK_EQ(AC.bad_free, 0);
    CHECK_EQ(AC.bad_size, 0);
    CHECK_EQ(AC.bad_align_arg, 0);
    CHECK_EQ(AC.bad_user, 0);
    test_grid_free(&g);
}

/* Fail the k-th allocation for k = 1, 2, ... through a whole scenario until one
 * runs with no failure. A call that hit a refused allocation returns
 * RBC_ERR_OUT_OF_MEMORY (or copes and succeeds); a call that returns OOM must
 * have been refused something; a failing call leaves the world as it was; after
 * the world is destroyed nothing is left allocated. With RBC_SOLVER_DIRECT the
 * first step and the step at a new dt factorise (direct.c), and CHOLMOD's blocks
 * come from the hooks too (issue 17): each of them is refused in turn, and the
 * retry of the next k gets past it. */
static void test_failing_allocator(rbc_solver_kind kind, const char *name) {
    test_grid g = test_grid_make(12, 12, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 11};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_collider_def kd = shape_def(RBC_SHAPE_SPHERE);
    kd.position[1] = 0.2f;
    rbc_solver_def sd;
    CHECK_EQ(rbc_solver_def_preset(&sd, (uint32_t)sizeof sd, RBC_PRESET_PAPER), RBC_OK);
    sd.solver = kind;
    /* dt of each step: the third one changes h (a new factorisation for direct). */
    const float dts[3] = {1.0f / 60.0f, 1.0f / 60.0f, 1.0f / 50.0f};
    int oom_seen = 0, step_oom = 0, injected = 0;
    int leaks = 0, phantom = 0, wrong_code = 0, changed = 0, retry_bad = 0;
    /* The positions after each step of the run with no failure: a step retried after
     * a refused allocation must give them bitwise. */
    float *ref[3] = {NULL, NULL, NULL};
    uint32_t ref_n = 0;
    {
        alloc_reset();
        rbc_world_def d = hooked_def();
        d.solver = &sd;
        rbc_world_id w = 0;
        rbc_cloth_id c = 0;
        rbc_collider_id col = 0;
        CHECK_EQ(rbc_world_create(&d, &w), RBC_OK);
        CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
        CHECK_EQ(rbc_collider_create(w, &kd, &col), RBC_OK);
        for (int st = 0; st < 3; st++) {
            STEP_OK(w, dts[st]);
            ref[st] = test_read(w, c, &ref_n);
        }
        CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    }
    long k;
    for (k = 1; k < 100000; k++) {
        alloc_reset();
        AC.fail_at = k;
        rbc_world_def d = hooked_def();
        d.solver = &sd;
        rbc_world_id w = 0;
        rbc_cloth_id c = 0;
        rbc_collider_id col = 0;
        rbc_result r;
        int done = 0;

#define ARMED(call) do { AC.armed = 1; r = (call); AC.armed = 0; } while (0)
#define VERDICT()                                                                  \
    do {                                                                           \
        if (r == RBC_ERR_OUT_OF_MEMORY) {                                          \
            oom_seen++;                                                            \
            if (!AC.failed) phantom++;                                             \
        } else if (r != RBC_OK) {                                                  \
            if (wrong_code++ < 3)                                                  \
                fprintf(stderr, "  fail_at %ld: line %d: %s (%s)\n", k, __LINE__,  \
                        rbc_result_string(r), rbc_last_error());                   \
        }                                                                          \
    } while (0)

        ARMED(rbc_world_create(&d, &w));
        VERDICT();
        if (r != RBC_OK) goto cleanup;
        {
            test_snap s = test_snap_take(w, NULL, 0);
            ARMED(rbc_cloth_create(w, &cd, &c));
            VERDICT();
            if (r != RBC_OK) {
                if (!test_snap_same(&s, __LINE__)) changed++;
                if (r == RBC_ERR_OUT_OF_MEMORY && rbc_cloth_create(w, &cd, &c) != RBC_OK)
                    retry_bad++; /* the retry, unarmed, succeeds */
                goto cleanup;
            }
        }
        {
            test_snap s = test_snap_take(w, &c, 1);
            ARMED(rbc_collider_create(w, &kd, &col));
            VERDICT();
            if (r != RBC_OK) {
                if (!test_snap_same(&s, __LINE__)) changed++;
                if (r == RBC_ERR_OUT_OF_MEMORY && rbc_collider_create(w, &kd, &col) != RBC_OK)
                    retry_bad++;
                test_snap_free(&s);
                goto cleanup;
            }
            test_snap_free(&s);
        }
        for (int st = 0; st < 3; st++) {
            test_snap s = test_snap_take(w, &c, 1);
            ARMED(rbc_world_step(w, dts[st]));
            VERDICT();
            if (r == RBC_ERR_OUT_OF_MEMORY) step_oom++;
            if (r != RBC_OK) {
                if (!test_snap_same(&s, __LINE__)) changed++;
                if (r == RBC_ERR_OUT_OF_MEMORY) {
                    /* The retry, unarmed, succeeds with the positions of the run
                     * that never failed (nothing of the failed step was kept). */
                    uint32_t n = 0;
                    float *p = NULL;
                    if (rbc_world_step(w, dts[st]) != RBC_OK ||
                        !(p = test_read(w, c, &n)) || n != ref_n || !ref[st] ||
                        memcmp(p, ref[st], sizeof(float) * 3 * n) != 0) {
                        if (retry_bad++ < 3)
                            fprintf(stderr, "  fail_at %ld: step %d retried: %s\n", k, st,
                                    rbc_last_error());
                    }
                    free(p);
                }
                test_snap_free(&s);
                goto cleanup;
            }
            test_snap_free(&s);
        }
        ARMED(rbc_cloth_destroy(w, c));
        VERDICT();
        done = !AC.failed;
    cleanup:
        injected += AC.failed;
        if (w) {
            rbc_result rd = rbc_world_destroy(w);
            if (rd != RBC_OK) wrong_code++;
        }
        if (AC.live != 0 || AC.allocs != AC.frees) {
            if (leaks++ < 3)
                fprintf(stderr, "  fail_at %ld: %zu blocks left after world destroy\n", k, AC.live);
        }
        if (done) break;
#undef ARMED
#undef VERDICT
    }
    printf("failing allocator (%s): %ld scenarios, %d injected failures, %d OOM results "
           "(%d in steps)\n",
           name, k, injected, oom_seen, step_oom);
    CHECK(k < 100000);  /* the scenario ran through without failure in the end */
    CHECK(oom_seen > 0); /* at least one injected failure surfaced as OOM */
    CHECK_EQ(leaks, 0);
    CHECK_EQ(phantom, 0);
    CHECK_EQ(wrong_code, 0);
    CHECK_EQ(changed, 0);
    CHECK_EQ(retry_bad, 0);
    /* Direct: two factorisations (dt 1/60 s, then 1/50 s), each refused in turn at
     * direct.c's own 7 blocks (the rbc_direct and its 6 arrays) and at CHOLMOD's,
     * at least 7 (cholmod_allocate_sparse's 4, cholmod_analyze's 3; see
     * test_cholmod_alloc.c). Before CHOLMOD used the hooks: 2 x 7. */
    if (kind == RBC_SOLVER_DIRECT) CHECK(step_oom >= 2 * (7 + 7));
    CHECK_EQ(AC.bad_free, 0);
    CHECK_EQ(AC.bad_size, 0);
    for (int st = 0; st < 3; st++) free(ref[st]);
    test_grid_free(&g);
}

typedef struct log_ctx {
    int count;
    int bad_level;
    int bad_msg;
    int bad_thread;
    rbc_log_level threshold;
} log_ctx;

static void log_hook(void *user, rbc_log_level level, const char *message) {
    log_ctx *l = (log_ctx *)user;
    l->count++;
    /* "messages of this level and more severe reach log": level <= threshold. */
    if (level < RBC_LOG_ERROR || level > l->threshold) l->bad_level++;
    if (!message || strnlen(message, 1 << 16) == (1 << 16)) l->bad_msg++;
    if (!pthread_equal(pthread_self(), MAIN_THREAD)) l->bad_thread++;
}

/* A set of failing and succeeding calls with log hooks, run while stdout and
 * stderr are redirected to files: the library must write nothing to either. */
static void noisy_calls(log_ctx *quiet, log_ctx *chatty) {
    rbc_world_def d = abi_world_def_fixed();
    d.log = log_hook;
    d.log_user = quiet;
    d.log_level = RBC_LOG_ERROR;
    rbc_world_id w1 = 0, w2 = 0, w3 = 0;
    rbc_world_create(&d, &w1);
    d.log_user = chatty;
    d.log_level = RBC_LOG_DEBUG;
    rbc_world_create(&d, &w2);
    rbc_world_def plain = abi_world_def_fixed(); /* no log hook at all */
    rbc_world_create(&plain, &w3);
    test_grid g = test_grid_make(10, 10, 0.05f, 0.0f, 1.0f, 0.0f);
    rbc_world_id ws[3] = {w1, w2, w3};
    for (int k = 0; k < 3; k++) {
        rbc_world_id w = ws[k];
        rbc_cloth_def cd = test_grid_def(&g, NULL, 0);
        rbc_cloth_id c = 0;
        rbc_cloth_create(w, &cd, &c);
        cd.quads = NULL;
        rbc_cloth_create(w, &cd, &c);
        rbc_cloth_def bad = test_grid_def(&g, NULL, 0);
        bad.stiffness = -1.0f;
        rbc_cloth_id cb = 0;
        rbc_cloth_create(w, &bad, &cb);
        rbc_world_step(w, 0.0f);
        rbc_world_step(w, NAN);
        rbc_world_set_iterations(w, 0, 0, 0);
        rbc_cloth_read_positions(w, 0x7FFF1234u, NULL, 0, NULL);
        for (int s = 0; s < 5; s++) rbc_world_step(w, 1.0f / 60.0f);
        const float huge[3] = {0.0f, -1e30f, 0.0f};
        rbc_world_set_gravity(w, huge);
        rbc_world_step(w, 1e30f); /* unstable */
    }
    rbc_world_def bd = abi_world_def_fixed();
    bd.backend = RBC_BACKEND_CUDA;
    rbc_world_id wc = 0;
    if (rbc_world_create(&bd, &wc) == RBC_OK) rbc_world_destroy(wc);
    bd.substeps = 1025;
    rbc_world_create(&bd, &wc);
    rbc_write_obj("/nonexistent-dir-rbc/x.obj", g.positions, g.vertex_count, g.quads, g.quad_count);
    rbc_cache_def hd = rbc_cache_def_default();
    hd.path = "/nonexistent-dir-rbc/x.pc2";
    hd.point_count = 1;
    rbc_cache_id h = 0;
    if (rbc_cache_create(&hd, &h) == RBC_OK) rbc_cache_finish(h);
    for (int k = 0; k < 3; k++) rbc_world_destroy(ws[k]);
    rbc_world_destroy(w1); /* stale */
    test_grid_free(&g);
}

static long file_size(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

static void test_silence_and_log(void) {
    char out_path[] = "/tmp/rbc_stdout_XXXXXX", err_path[] = "/tmp/rbc_stderr_XXXXXX";
    int fo = mkstemp(out_path), fe = mkstemp(err_path);
    CHECK(fo >= 0 && fe >= 0);
    if (fo < 0 || fe < 0) return;
    fflush(NULL);
    int saved_out = dup(1), saved_err = dup(2);
    dup2(fo, 1);
    dup2(fe, 2);
    log_ctx quiet = {0, 0, 0, 0, RBC_LOG_ERROR}, chatty = {0, 0, 0, 0, RBC_LOG_DEBUG};
    /* No CHECK in here: a failing CHECK would itself write to stderr. */
    noisy_calls(&quiet, &chatty);
    fflush(NULL);
    dup2(saved_out, 1);
    dup2(saved_err, 2);
    close(saved_out);
    close(saved_err);
    close(fo);
    close(fe);
    long so = file_size(out_path), se = file_size(err_path);
    CHECK_EQ(so, 0);
    CHECK_EQ(se, 0);
    if (so > 0 || se > 0) {
        char buf[512];
        FILE *f = fopen(so > 0 ? out_path : err_path, "r");
        size_t nr = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
        buf[nr] = '\0';
        if (f) fclose(f);
        fprintf(stderr, "  the library wrote to %s: \"%s\"\n", so > 0 ? "stdout" : "stderr", buf);
    }
    unlink(out_path);
    unlink(err_path);
    CHECK_EQ(quiet.bad_level, 0);
    CHECK_EQ(chatty.bad_level, 0);
    CHECK_EQ(quiet.bad_msg + chatty.bad_msg, 0);
    CHECK_EQ(quiet.bad_thread + chatty.bad_thread, 0);
    /* The quiet world saw at most as many messages as the chatty one (its
     * threshold admits a subset of levels for the same calls). */
    CHECK(quiet.count <= chatty.count);
    printf("log hook: %d messages at ERROR, %d at DEBUG threshold\n", quiet.count, chatty.count);
}

/* ========================================================================= */
/* (i) Thread contract: worlds on different threads; callbacks on the caller  */
/* ========================================================================= */

/* "Different worlds may be used concurrently from different threads" and "host
 * callbacks are always called on the thread that called rbc_world_step". Two
 * threads each build and step their own world (with worker threads of its own)
 * at the same time; each world's callback must run on its stepping thread, and
 * the results must equal those of the same scene run alone on the main thread
 * (one solver thread per world, so the arithmetic is the same: bitwise). */
typedef struct thread_job {
    pthread_t self;
    int wrong_thread;
    int calls;
    int failures;
    float result[3 * 144];
} thread_job;

static int32_t thread_cb(void *user, rbc_world_id world, float dt,
                         const rbc_collision_cloth *cloths, uint32_t cloth_count) {
    thread_job *j = (thread_job *)user;
    j->calls++;
    if (!pthread_equal(pthread_self(), j->self)) j->wrong_thread++;
    return 0;
}

static void run_scene(thread_job *j) {
    j->self = pthread_self();
    rbc_world_def d = abi_world_def_fixed();
    d.substeps = 2;
    d.thread_count = 1;
    rbc_world_id w = 0;
    if (rbc_world_create(&d, &w) != RBC_OK) { j->failures++; return; }
    test_grid g = test_grid_make(12, 12, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 11};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id c = 0;
    if (rbc_cloth_create(w, &cd, &c) != RBC_OK) j->failures++;
    if (rbc_world_set_collision_callback(w, thread_cb, j) != RBC_OK) j->failures++;
    for (int k = 0; k < 200; k++)
        if (rbc_world_step(w, 1.0f / 60.0f) != RBC_OK) j->failures++;
    size_t written = 0;
    if (rbc_cloth_read_positions(w, c, j->result, 3 * 144, &written) != RBC_OK || written != 3 * 144)
        j->failures++;
    rbc_world_destroy(w);
    test_grid_free(&g);
}

static void *thread_main(void *arg) {
    run_scene((thread_job *)arg);
    return NULL;
}

static void test_threads(void) {
    static thread_job ref, a, b;
    memset(&ref, 0, sizeof ref);
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    run_scene(&ref);
    pthread_t ta, tb;
    CHECK_EQ(pthread_create(&ta, NULL, thread_main, &a), 0);
    CHECK_EQ(pthread_create(&tb, NULL, thread_main, &b), 0);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    CHECK_EQ(ref.failures + a.failures + b.failures, 0);
    CHECK_EQ(a.calls, 400); /* 200 steps x 2 substeps */
    CHECK_EQ(b.calls, 400);
    CHECK_EQ(a.wrong_thread + b.wrong_thread + ref.wrong_thread, 0);
    CHECK(memcmp(a.result, ref.result, sizeof ref.result) == 0);
    CHECK(memcmp(b.result, ref.result, sizeof ref.result) == 0);
    CHECK(test_all_finite(ref.result, 3 * 144));
}

/* ========================================================================= */

int main(void) {
    MAIN_THREAD = pthread_self();
    test_free_fall();
    test_pins();
    test_damped_rest();
    test_sphere();
    test_planes();
    test_callback();
    test_unstable();
    test_stats_figures();
    test_counting_allocator();
    test_failing_allocator(RBC_SOLVER_RBGS, "rbgs");
    test_failing_allocator(RBC_SOLVER_DIRECT, "direct");
    test_silence_and_log();
    test_threads();
    return check_report("abi_behaviour");
}
