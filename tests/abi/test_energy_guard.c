/* The energy guard (ABI 1.2, rbc_energy_guard) as a host sees it:
 *  - 1.1 hosts (solver defs and stats at the 1.1 sizes) get the default guard and no
 *    byte past their structs; a bad guard value is refused and changes nothing;
 *  - on the paper's hanging cloth the default solvers (rbgs, direct) never trigger
 *    it: the clamped run is bitwise the run with the guard off;
 *  - a diverging solver (Jacobi, 1 iteration per 2 ms step) is held: every step
 *    returns OK, kinetic + gravitational energy (the host's own sums) never exceeds
 *    the reported budget, the clamps are counted and logged at 1, 2, 4, ... and the
 *    result does not depend on the thread count;
 *  - fail mode refuses the first such step and restores the state bitwise;
 *  - the work of moving pins is part of the budget: pins pulled slowly apart under
 *    the exact solver trigger nothing;
 *  - rbc_cloth_set_state starts a new budget that counts the spring energy it holds.
 */
#include "abi_util.h"

#define N 100       /* the paper's 100 x 100 cloth */
#define MASS 1e-4f  /* kg per vertex */
#define STIFF 1000.0f
#define DT 0.002f

static rbc_world_id make_world(rbc_solver_kind kind, uint32_t linear, rbc_energy_guard guard,
                               uint32_t threads, test_log_count *lc) {
    rbc_world_def wd = abi_world_def_fixed();
    rbc_solver_def sd = test_solver_def(kind);
    sd.energy_guard = guard;
    wd.solver = &sd;
    wd.thread_count = threads;
    wd.linear_iterations = linear;
    if (lc) {
        wd.log = test_count_log;
        wd.log_user = lc;
        wd.log_level = RBC_LOG_WARNING;
    }
    return test_world(&wd);
}

static rbc_cloth_id add_cloth(rbc_world_id w, const test_grid *g, const uint32_t *pins,
                              uint32_t pin_count) {
    rbc_cloth_def cd = test_grid_def(g, pins, pin_count);
    cd.vertex_mass = MASS;
    cd.stiffness = STIFF;
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    return c;
}

/* Kinetic + gravitational energy of the free vertices of the N x N grid, computed by
 * the host in double, and *tol, the rounding allowance rbc_energy_guard documents,
 * recomputed here from the same state: 2^-20 of the kinetic and spring sums, 2^-40
 * of sum m |g| |x|_1, and what half an ulp (delta = 2^-24 X, X the largest
 * |coordinate|) in every coordinate changes: sum m |v|_1 2 delta / h + sum s |ext| e
 * + |g| M sqrt(3) delta + (sum m / h^2 + sum s) e^2 / 2, with e = 2 sqrt(3) delta. */
static double guarded_energy(rbc_world_id w, rbc_cloth_id c, const uint8_t *pinned, double h,
                             double *tol) {
    uint32_t n = 0;
    CHECK_EQ(rbc_cloth_get_vertex_count(w, c, &n), RBC_OK);
    float *x = malloc(sizeof(float) * 3 * n), *q = malloc(sizeof(float) * 3 * n);
    CHECK_EQ(rbc_cloth_get_state(w, c, x, q, 3 * (size_t)n), RBC_OK);
    double e = 0.0, ke = 0.0, mag = 0.0, md = 0.0, mass = 0.0, xmax = 0.0;
    for (uint32_t v = 0; v < n; ++v) {
        for (int a = 0; a < 3; ++a) xmax = fmax(xmax, fabs((double)x[3 * v + a]));
        if (pinned && pinned[v]) continue;
        mag += MASS * 9.81 * (fabs(x[3 * v]) + fabs(x[3 * v + 1]) + fabs(x[3 * v + 2]));
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double d = (double)x[3 * v + a] - q[3 * v + a];
            d2 += d * d;
            md += MASS * fabs(d);
        }
        ke += 0.5 * MASS * d2 / (h * h);
        e += MASS * 9.81 * x[3 * v + 1];
        mass += MASS;
    }
    e += ke;
    /* The structural springs of the grid: (i, i + 1) in rows, (i, i + N) in columns. */
    const double L = 1.0 / (N - 1);
    double us = 0.0, kext = 0.0, ksum = 0.0;
    for (uint32_t v = 0; v < n; ++v)
        for (int dir = 0; dir < 2; ++dir) {
            uint32_t u = dir ? v + N : v + 1;
            if (dir ? u >= n : (v % N) + 1 >= N) continue;
            double ex = (double)x[3 * v] - x[3 * u], ey = (double)x[3 * v + 1] - x[3 * u + 1],
                   ez = (double)x[3 * v + 2] - x[3 * u + 2];
            double ext = sqrt(ex * ex + ey * ey + ez * ez) - L;
            us += 0.5 * STIFF * ext * ext;
            kext += STIFF * fabs(ext);
            ksum += STIFF;
        }
    const double delta = ldexp(xmax, -24), eps = 2.0 * sqrt(3.0) * delta;
    *tol = ldexp(ke + us, -20) + ldexp(mag, -40) + md / (h * h) * 2.0 * delta + kext * eps +
           9.81 * mass * sqrt(3.0) * delta + 0.5 * (mass / (h * h) + ksum) * eps * eps;
    free(x);
    free(q);
    return e;
}

static void test_abi_sizes(const test_grid *g) {
    /* A 1.1 host's solver def: garbage past the 1.1 size, default guard applies. */
    TEST_PADDED(rbc_solver_def, 32) sbuf;
    memset(&sbuf, 0xAB, sizeof sbuf);
    CHECK_EQ(rbc_solver_def_init(&sbuf.d, RBC_SOLVER_DEF_SIZE_V1_1), RBC_OK);
    CHECK(test_bytes_are(&sbuf, RBC_SOLVER_DEF_SIZE_V1_1, sizeof sbuf, 0xAB));
    rbc_world_def wd = abi_world_def_fixed();
    wd.solver = &sbuf.d;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_OK);
    rbc_solver_def got = rbc_solver_def_default();
    got.energy_guard = RBC_ENERGY_GUARD_OFF;
    CHECK_EQ(rbc_world_get_solver(w, &got), RBC_OK);
    CHECK_EQ(got.energy_guard, RBC_ENERGY_GUARD_CLAMP);
    /* get_solver into a 1.1 struct writes only its bytes */
    memset(&sbuf, 0xAB, sizeof sbuf);
    sbuf.d.struct_size = RBC_SOLVER_DEF_SIZE_V1_1;
    CHECK_EQ(rbc_world_get_solver(w, &sbuf.d), RBC_OK);
    CHECK(test_bytes_are(&sbuf, RBC_SOLVER_DEF_SIZE_V1_1, sizeof sbuf, 0xAB));
    CHECK_EQ(sbuf.d.solver, RBC_SOLVER_RBGS);

    /* A bad guard is refused, names the field, and changes nothing. */
    rbc_solver_def bad = test_solver_def(RBC_SOLVER_JACOBI);
    bad.energy_guard = 7;
    CHECK_EQ(rbc_world_set_solver(w, &bad), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "energy_guard 7") != NULL);
    CHECK_EQ(rbc_world_get_solver(w, &got), RBC_OK);
    CHECK_EQ(got.solver, RBC_SOLVER_RBGS);
    CHECK_EQ(got.energy_guard, RBC_ENERGY_GUARD_CLAMP);

    /* 1.1 stats: nothing past their size. */
    add_cloth(w, g, NULL, 0);
    CHECK_EQ(rbc_world_step(w, DT), RBC_OK);
    TEST_PADDED(rbc_world_stats, 32) st;
    CHECK(test_stats_sized(w, &st, sizeof st, RBC_WORLD_STATS_SIZE_V1_1, 0xEF));
    CHECK_EQ(st.d.step_count, 1);

    /* skip_measures: counts and timings without the pass over the cloth; the
     * measured fields read 0, and the flag is kept. */
    rbc_world_stats full = test_stats(w), fast;
    memset(&fast, 0xEF, sizeof fast);
    fast.struct_size = sizeof fast;
    fast.skip_measures = 1;
    CHECK_EQ(rbc_world_get_stats(w, &fast), RBC_OK);
    CHECK(full.error_eq7 > 0.0 && full.kinetic_energy > 0.0 && full.potential_energy != 0.0);
    CHECK(fast.error_eq7 == 0.0 && fast.max_strain == 0.0 && fast.kinetic_energy == 0.0 &&
          fast.potential_energy == 0.0 && fast.linear_residual == 0.0 && fast.pd_objective == 0.0);
    CHECK_EQ(fast.skip_measures, 1);
    CHECK_EQ(fast.particle_count, full.particle_count);
    CHECK_EQ(fast.step_count, full.step_count);
    CHECK(fast.step_ms == full.step_ms && fast.step_ms > 0.0);
    CHECK(fast.energy_budget == full.energy_budget);
    CHECK_EQ(fast.memory_bytes, full.memory_bytes);
    rbc_world_destroy(w);
}

/* The paper's hanging cloth, 240 frames: the default solver and the exact one stay
 * inside the budget (implicit Euler dissipates), so the guard must not act. */
static void test_paper_scene_untouched(const test_grid *g, rbc_solver_kind kind) {
    const uint32_t pins[2] = {0, N - 1};
    rbc_world_id w0 = make_world(kind, 11, RBC_ENERGY_GUARD_OFF, 1, NULL);
    rbc_world_id w1 = make_world(kind, 11, RBC_ENERGY_GUARD_CLAMP, 1, NULL);
    rbc_cloth_id c0 = add_cloth(w0, g, pins, 2), c1 = add_cloth(w1, g, pins, 2);
    CHECK(test_twins_same(w0, c0, w1, c1, 240, DT));
    rbc_world_stats s0 = test_stats(w0), s1 = test_stats(w1);
    CHECK_EQ(s1.energy_clamped_steps, 0);
    CHECK_EQ(s0.energy_clamped_steps, 0);
    CHECK(s0.energy_budget == 0.0);   /* guard off: no budget kept */
    /* At rest at the start (no spring energy, no motion): the budget is 0 J and
     * kinetic + gravitational energy must be at most that. */
    CHECK(s1.energy_budget == 0.0);
    CHECK(s1.kinetic_energy > 0.0);
    rbc_world_destroy(w0);
    rbc_world_destroy(w1);
}

/* One Jacobi iteration per 2 ms step diverges on this cloth (k h^2 / m = 40). */
static void test_diverging_jacobi_held(const test_grid *g) {
    const uint32_t pins[2] = {0, N - 1};
    uint8_t *pinned = calloc(g->vertex_count, 1);
    pinned[0] = pinned[N - 1] = 1;
    test_log_count lc = {.phrase = "energy guard", .count_before = " clamped so far"};
    rbc_world_id w = make_world(RBC_SOLVER_JACOBI, 1, RBC_ENERGY_GUARD_CLAMP, 2, &lc);
    rbc_world_id w1 = make_world(RBC_SOLVER_JACOBI, 1, RBC_ENERGY_GUARD_CLAMP, 1, NULL);
    rbc_cloth_id c = add_cloth(w, g, pins, 2), c1 = add_cloth(w1, g, pins, 2);
    double worst = -1e300;
    for (int f = 0; f < 240; ++f) {
        CHECK_EQ(rbc_world_step(w, DT), RBC_OK);
        CHECK_EQ(rbc_world_step(w1, DT), RBC_OK);
        rbc_world_stats st = test_stats(w);
        double tol;
        double e = guarded_energy(w, c, pinned, DT, &tol);
        /* The documented allowance, from the host's own sums (which differ from the
         * library's float-product sums by far less than its 2^-20 terms). */
        double over = e - st.energy_budget - tol;
        if (over > worst) worst = over;
    }
    printf("diverging Jacobi: largest (host energy - budget - allowance) over 240 frames: %.3g J\n",
           worst);
    CHECK(worst <= 0.0);
    rbc_world_stats st = test_stats(w);
    CHECK(st.energy_clamped_steps > 10);
    /* Logged at the 1st, 2nd, 4th, ... clamp: floor(log2(count)) + 1 warnings. */
    int expect = 0;
    for (uint64_t k = st.energy_clamped_steps; k; k >>= 1) ++expect;
    CHECK_EQ(lc.warnings, expect);
    for (int k = 0; k < lc.warnings && k < 64; ++k) CHECK_EQ(lc.at[k], 1ull << k);
    uint32_t n = 0;
    float *x = test_read(w, c, &n), *x1 = test_read(w1, c1, NULL);
    CHECK(test_all_finite(x, 3 * (size_t)n));
    /* Threads do not change the result, clamps included. */
    CHECK(memcmp(x, x1, sizeof(float) * 3 * n) == 0);
    free(x);
    free(x1);
    free(pinned);
    rbc_world_destroy(w);
    rbc_world_destroy(w1);

    /* Fail mode: the first step over the budget is refused, state kept bitwise. */
    rbc_world_id wf = make_world(RBC_SOLVER_JACOBI, 1, RBC_ENERGY_GUARD_FAIL, 2, NULL);
    rbc_cloth_id cf = add_cloth(wf, g, pins, 2);
    float *before = malloc(sizeof(float) * 6 * g->vertex_count);
    float *after = malloc(sizeof(float) * 6 * g->vertex_count);
    rbc_result r = RBC_OK;
    int steps = 0;
    for (; steps < 240; ++steps) {
        CHECK_EQ(rbc_cloth_get_state(wf, cf, before, before + 3 * g->vertex_count,
                                     3 * (size_t)g->vertex_count), RBC_OK);
        if ((r = rbc_world_step(wf, DT)) != RBC_OK) break;
    }
    CHECK_EQ(r, RBC_ERR_UNSTABLE);
    CHECK(strstr(rbc_last_error(), "RBC_ENERGY_GUARD_FAIL") != NULL);
    CHECK_EQ(rbc_cloth_get_state(wf, cf, after, after + 3 * g->vertex_count,
                                 3 * (size_t)g->vertex_count), RBC_OK);
    CHECK(memcmp(before, after, sizeof(float) * 6 * g->vertex_count) == 0);
    CHECK_EQ(test_stats(wf).step_count, (uint64_t)steps);
    free(before);
    free(after);
    rbc_world_destroy(wf);
}

/* Pins pulled apart by 0.3 m over 0.6 s under the exact solver: the pins do work
 * (the springs they stretch), counted in the budget, so nothing is clamped; the
 * budget grew by that work. */
static void test_pin_work_counted(const test_grid *g) {
    const uint32_t pins[2] = {0, N - 1};
    rbc_world_id w = make_world(RBC_SOLVER_DIRECT, 1, RBC_ENERGY_GUARD_CLAMP, 1, NULL);
    rbc_cloth_id c = add_cloth(w, g, pins, 2);
    const float spacing = 1.0f / (N - 1);
    double budget0 = 0.0;
    for (int f = 0; f < 300; ++f) {
        float s = 0.15f * (float)(f < 150 ? f + 1 : 150) / 150.0f;
        const float left[3] = {-s, 0.0f, 0.0f}, right[3] = {(N - 1) * spacing + s, 0.0f, 0.0f};
        CHECK_EQ(rbc_cloth_set_pin(w, c, 0, left), RBC_OK);
        CHECK_EQ(rbc_cloth_set_pin(w, c, N - 1, right), RBC_OK);
        CHECK_EQ(rbc_world_step(w, DT), RBC_OK);
        if (f == 0) budget0 = test_stats(w).energy_budget;
    }
    rbc_world_stats st = test_stats(w);
    CHECK_EQ(st.energy_clamped_steps, 0);
    CHECK(st.energy_budget > budget0);
    rbc_world_destroy(w);
}

/* set_state: a state stretched 10% in its plane holds spring energy; the budget at
 * the next step is the state's whole energy (kinetic 0, spring, gravity). */
static void test_set_state_budget(const test_grid *g) {
    rbc_world_id w = make_world(RBC_SOLVER_RBGS, 11, RBC_ENERGY_GUARD_CLAMP, 1, NULL);
    rbc_cloth_id c = add_cloth(w, g, NULL, 0);
    float *x = malloc(sizeof(float) * 3 * g->vertex_count);
    for (uint32_t v = 0; v < g->vertex_count; ++v) {
        x[3 * v] = 1.1f * g->positions[3 * v];
        x[3 * v + 1] = g->positions[3 * v + 1];
        x[3 * v + 2] = 1.1f * g->positions[3 * v + 2];
    }
    CHECK_EQ(rbc_cloth_set_state(w, c, x, NULL), RBC_OK);
    rbc_world_stats s0 = test_stats(w); /* before the step: potential of the state */
    CHECK_EQ(rbc_world_step(w, DT), RBC_OK);
    rbc_world_stats s1 = test_stats(w);
    /* Spring energy: every spring 10% long, sum s/2 (0.1 L)^2; gravity 0 at y = 0. */
    uint32_t springs = test_grid_spring_count(g);
    double L = 1.0 / (N - 1), expect = springs * 0.5 * STIFF * (0.1 * L) * (0.1 * L);
    CHECK_NEAR(s0.potential_energy, expect, 1e-3 * expect);
    CHECK_NEAR(s1.energy_budget, s0.potential_energy, 1e-6 * expect);
    CHECK_EQ(s1.energy_clamped_steps, 0);
    free(x);
    rbc_world_destroy(w);
}

int main(void) {
    test_grid g = test_grid_make(N, N, 1.0f / (N - 1), 0.0f, 0.0f, 0.0f);
    test_abi_sizes(&g);
    test_paper_scene_untouched(&g, RBC_SOLVER_RBGS);
    test_paper_scene_untouched(&g, RBC_SOLVER_DIRECT);
    test_diverging_jacobi_held(&g);
    test_pin_work_counted(&g);
    test_set_state_budget(&g);
    test_grid_free(&g);
    return check_report("abi_energy_guard");
}
