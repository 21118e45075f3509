/* The step through the backend seam (core/backend.h) against the CPU pool's own
 * stages (step.c). Without an argument on the CPU backend, on every machine: the
 * schedule the CUDA backend runs (backend_step.c) is this one. With the CUDA module's
 * path (test cuda_parity), on the CUDA backend: the same checks, bit for bit too
 * (the module rounds as the CPU does: no FMA contraction, IEEE division and square
 * root); without a CUDA device it says so and exits 77, which CTest reports as
 * skipped.
 *
 *  1. For every solver a backend runs (rbgs, multicolor, SOR, Chebyshev-RBGS,
 *     Jacobi, Chebyshev-Jacobi), on a lattice, a cube (valence 3 corners, the ELL
 *     path), a triangle mesh split into quads and an odd torus (three colors), with
 *     moving pins, 3 substeps (and, for two cases, 8 from the default 480 Hz rate),
 *     2 non-linear iterations: 12 steps on both give the
 *     same positions and previous positions, bit for bit. Both run the same float
 *     operations in the same order (the pool's ELL sweeps are bitwise the CSR rows'
 *     result, and the seam's kernels are those rows; the grid's lattice rows are
 *     not, so the grid runs the pool on its CSR rows), so any difference is a
 *     schedule bug, not rounding.
 *  2. The iteration modes and the energy guard through the seam's measurement
 *     kernels (residual, strain, energy, the pins' work), for rbgs, Chebyshev-RBGS
 *     and Jacobi on the four meshes, and on two cloths in one world (the sums run
 *     over both): the tolerance and target modes stop at the same iteration and
 *     choose the same substeps, the guard clamps the same steps by the same energy
 *     (a diverging Jacobi case clamps), and the positions are bit for bit the
 *     pool's; the guard's fail mode fails the same step and restores the state; the
 *     budget at its two ends (never reached: the cap every global step; always
 *     passed: one iteration), where its decisions do not depend on the clock.
 *  3. A non-finite position fails the step with RBC_ERR_UNSTABLE naming the vertex,
 *     and the state is as it was before the step.
 *  4. A scene feature the backends do not run (a triangle mesh collider, the direct
 *     solver, the energy guard with a sphere) is refused with RBC_ERR_UNSUPPORTED
 *     naming it, and nothing changes.
 *     (The analytic colliders run: test_backend_colliders.c.)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backend_module.h"
#include "check.h"
#include "meshes.h"
#include "rbcloth.h"
#include "shapes.h"
#include "solver.h"

/* The backend under test: the CPU's, or the CUDA module's open function. */
static rbc_backend_open_fn *cuda_open;
static const char *backend_name = "cpu";
/* 1: substeps from the rate (480 Hz: 8 a 1/60 s step), as the default world def. */
static int from_rate;

typedef struct world {
    rbc_solver s;
    rbc_cloth_state *c, *c2;
} world;

/* What a case changes in the settings (the mode, the guard), and a second cloth of
 * the same mesh 1 m beside the first (the modes' sums run over every cloth). */
static void (*tweak)(rbc_solver_settings *st);
static int two_cloths;
/* The iteration counts and step of a case (the energy guard's diverging one: a
 * Jacobi iteration per 2 ms step, as tests/abi/test_energy_guard.c). */
static uint32_t substeps_n = 3, nonlinear_n = 2, linear_n = 7;
static float dt_step = 1.0f / 60.0f;
static int steps_n = 12;

static void make(world *w, const test_mesh *m, rbc_solver_kind kind, int on_backend) {
    rbc_allocator a = rbc_allocator_default();
    CHECK_EQ(rbc_solver_init(&w->s, &a, 1), RBC_OK);
    w->s.substeps = from_rate ? 0 : substeps_n;
    w->s.substep_rate = 480.0f;
    w->s.nonlinear_iterations = nonlinear_n;
    w->s.linear_iterations = linear_n;
    uint32_t pins[2] = {0, m->nv - 1};
    rbc_mesh_input in = mesh_input(m, pins, 2);
    char err[256];
    CHECK_EQ(rbc_solver_create_cloth(&w->s, &in, 0.5f, &w->c, err, sizeof err), RBC_OK);
    CHECK_EQ(rbc_solver_add_cloth(&w->s, w->c), RBC_OK);
    w->c2 = NULL;
    if (two_cloths) {
        float *moved = malloc(3 * (size_t)m->nv * sizeof(float));
        for (uint32_t v = 0; v < m->nv; ++v)
            for (int ax = 0; ax < 3; ++ax)
                moved[3 * v + ax] = m->pos[3 * v + ax] + (ax == 0 ? 1.0f : 0.0f);
        rbc_mesh_input in2 = in;
        in2.positions = moved;
        in2.pin_count = 1; /* one pin: the two cloths' iterations differ */
        CHECK_EQ(rbc_solver_create_cloth(&w->s, &in2, 0.8f, &w->c2, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_add_cloth(&w->s, w->c2), RBC_OK);
        free(moved);
    }
    rbc_solver_settings st = w->s.settings;
    st.kind = kind;
    st.energy_guard = RBC_ENERGY_GUARD_OFF;
    if (tweak) tweak(&st);
    CHECK_EQ(rbc_solver_set_settings(&w->s, &st), RBC_OK);
    if (on_backend) {
        rbc_backend_handle bk;
        char why[512];
        if (cuda_open)
            CHECK_EQ(cuda_open(RBC_BACKEND_INTERFACE, &bk, why, sizeof why), RBC_OK);
        else
            CHECK_EQ(rbc_backend_cpu_open(&bk), RBC_OK);
        rbc_solver_set_backend(&w->s, &bk);
    }
}

static int same_cloth(const rbc_cloth_state *a, const rbc_cloth_state *b) {
    const uint32_t n = a->topo.n;
    for (int ax = 0; ax < 3; ++ax)
        if (memcmp(a->x[ax], b->x[ax], n * sizeof(float)) ||
            memcmp(a->q[ax], b->q[ax], n * sizeof(float)))
            return 0;
    return 1;
}

/* The same positions and previous positions, and the same iterations and substeps
 * (the modes decided alike) and energy guard verdicts. */
static int same_state(const world *a, const world *b) {
    if (a->s.last_linear != b->s.last_linear || a->s.last_substeps != b->s.last_substeps ||
        a->s.energy_removed_last != b->s.energy_removed_last ||
        a->s.energy_clamped_steps != b->s.energy_clamped_steps)
        return 0;
    return same_cloth(a->c, b->c) && (!a->c2 || same_cloth(a->c2, b->c2));
}

/* Largest |a - b| over the positions, for the message when they differ. */
static double max_diff(const world *a, const world *b) {
    double m = 0.0;
    for (int ax = 0; ax < 3; ++ax)
        for (uint32_t i = 0; i < a->c->topo.n; ++i)
            m = fmax(m, fabs((double)a->c->x[ax][i] - b->c->x[ax][i]));
    return m;
}

/* What the parity runs saw on the backend: linear iterations, clamped steps. */
static uint64_t linear_seen, clamped_seen;

static void parity(const char *mesh_name, const test_mesh *m, rbc_solver_kind kind,
                   const char *kind_name) {
    world a, b;
    make(&a, m, kind, 0);
    make(&b, m, kind, 1);
    /* The pool's lattice rows are not the CSR rows' sums in their order (uniform rows
     * factor the stiffness out; the right-hand side sums left, right, down, up): a
     * few roundings apart, which the one-source work of the kernels is to remove.
     * The schedule is compared on the CSR rows the kernels are. */
    struct rbc_lattice *lattice = a.c->lattice, *lattice2 = a.c2 ? a.c2->lattice : NULL;
    a.c->lattice = NULL;
    if (a.c2) a.c2->lattice = NULL;
    char err[512];
    int ok = 1;
    for (int step = 0; step < steps_n && ok; ++step) {
        /* The second pin travels 2 cm a step, so the pins' paths are exercised. */
        float tgt[3] = {m->pos[3 * (m->nv - 1)] + 0.02f * (float)step,
                        m->pos[3 * (m->nv - 1) + 1], m->pos[3 * (m->nv - 1) + 2]};
        CHECK_EQ(rbc_cloth_state_set_pin(&a.s.alloc, a.c, m->nv - 1, tgt), RBC_OK);
        CHECK_EQ(rbc_cloth_state_set_pin(&b.s.alloc, b.c, m->nv - 1, tgt), RBC_OK);
        int32_t ra = rbc_solver_step(&a.s, dt_step, err, sizeof err);
        int32_t rb = rbc_solver_step(&b.s, dt_step, err, sizeof err);
        CHECK_EQ(ra, RBC_OK);
        CHECK_EQ(rb, RBC_OK);
        if (!same_state(&a, &b)) {
            fprintf(stderr,
                    "%s, %s: step %d differs (largest %.3g m; linear iterations %u and %u, "
                    "substeps %u and %u, energy removed %.9g and %.9g J)\n",
                    mesh_name, kind_name, step, max_diff(&a, &b), a.s.last_linear,
                    b.s.last_linear, a.s.last_substeps, b.s.last_substeps,
                    a.s.energy_removed_last, b.s.energy_removed_last);
            ok = 0;
        }
        linear_seen += b.s.last_linear;
        clamped_seen += b.s.energy_clamped_last;
    }
    CHECK(ok);
    /* The cloth moved: a comparison of two resting cloths would prove little. */
    CHECK(fabs((double)a.c->x[1][a.c->topo.to_internal[m->nv / 2]] - m->pos[3 * (m->nv / 2) + 1]) >
          1e-3);
    a.c->lattice = lattice;
    if (a.c2) a.c2->lattice = lattice2;
    rbc_solver_fini(&a.s);
    rbc_solver_fini(&b.s);
}

static void failure_restores(void) {
    test_mesh m = mesh_grid(12, 12, 0.05f);
    world b;
    make(&b, &m, RBC_SOLVER_RBGS, 1);
    char err[512];
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    const uint32_t n = b.c->topo.n, v = 77, i = b.c->topo.to_internal[v];
    b.c->x[1][i] = NAN; /* as a host's set_state would not allow; the step must catch it */
    float *before[2][3];
    for (int ax = 0; ax < 3; ++ax) {
        before[0][ax] = malloc(n * sizeof(float));
        before[1][ax] = malloc(n * sizeof(float));
        memcpy(before[0][ax], b.c->x[ax], n * sizeof(float));
        memcpy(before[1][ax], b.c->q[ax], n * sizeof(float));
    }
    err[0] = 0;
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSTABLE);
    /* NaN spreads to the neighbours within the step: the lowest non-finite vertex is
     * named, one of v's neighbourhood. */
    CHECK(strstr(err, "became non-finite") != NULL);
    fprintf(stderr, "  (message: %s)\n", err);
    int intact = 1;
    for (int ax = 0; ax < 3; ++ax)
        intact = intact && !memcmp(before[0][ax], b.c->x[ax], n * sizeof(float)) &&
                 !memcmp(before[1][ax], b.c->q[ax], n * sizeof(float));
    /* memcmp: the NaN's bits are as they were. */
    CHECK(intact);
    for (int ax = 0; ax < 3; ++ax) {
        free(before[0][ax]);
        free(before[1][ax]);
    }
    rbc_solver_fini(&b.s);
    mesh_free(&m);
}

/* The energy guard's fail mode on the diverging case: both fail at the same step
 * with RBC_ERR_UNSTABLE naming the guard, and the backend's state is as before. */
static void guard_fails(void) {
    test_mesh m = mesh_grid(24, 20, 0.04f);
    world a, b;
    make(&a, &m, RBC_SOLVER_JACOBI, 0);
    make(&b, &m, RBC_SOLVER_JACOBI, 1);
    struct rbc_lattice *lattice = a.c->lattice; /* the pool on its CSR rows, as parity */
    a.c->lattice = NULL;
    const uint32_t n = b.c->topo.n;
    float *x0 = malloc(n * sizeof(float)), *q0 = malloc(n * sizeof(float));
    char err[512];
    int failed_at = -1;
    for (int step = 0; step < 60 && failed_at < 0; ++step) {
        memcpy(x0, b.c->x[1], n * sizeof(float));
        memcpy(q0, b.c->q[1], n * sizeof(float));
        float tgt[3] = {m.pos[3 * (m.nv - 1)] + 0.02f * (float)step, m.pos[3 * (m.nv - 1) + 1],
                        m.pos[3 * (m.nv - 1) + 2]}; /* as parity's */
        CHECK_EQ(rbc_cloth_state_set_pin(&a.s.alloc, a.c, m.nv - 1, tgt), RBC_OK);
        CHECK_EQ(rbc_cloth_state_set_pin(&b.s.alloc, b.c, m.nv - 1, tgt), RBC_OK);
        int32_t ra = rbc_solver_step(&a.s, dt_step, err, sizeof err);
        int32_t rb = rbc_solver_step(&b.s, dt_step, err, sizeof err);
        CHECK_EQ(ra, rb);
        if (rb != RBC_OK) {
            failed_at = step;
            CHECK_EQ(rb, RBC_ERR_UNSTABLE);
            CHECK(strstr(err, "energy guard") != NULL);
            fprintf(stderr, "  (fail mode at step %d: %s)\n", step, err);
            CHECK(!memcmp(x0, b.c->x[1], n * sizeof(float)) &&
                  !memcmp(q0, b.c->q[1], n * sizeof(float)));
        }
        CHECK(same_state(&a, &b));
    }
    CHECK(failed_at >= 0);
    a.c->lattice = lattice;
    free(x0);
    free(q0);
    rbc_solver_fini(&a.s);
    rbc_solver_fini(&b.s);
    mesh_free(&m);
}

static void refused(void) {
    test_mesh m = mesh_grid(8, 8, 0.05f);
    world b;
    make(&b, &m, RBC_SOLVER_RBGS, 1);
    char err[512];
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    const uint32_t n = b.c->topo.n;
    float *x0 = malloc(n * sizeof(float));
    memcpy(x0, b.c->x[1], n * sizeof(float));
    const uint64_t steps = b.s.step_count;

    rbc_solver_settings st = b.s.settings;
    st.kind = RBC_SOLVER_DIRECT;
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "direct solver") != NULL);
    st.kind = RBC_SOLVER_RBGS;
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);

    /* A triangle mesh collider (its BVH queries are the CPU's). */
    static const float tet[] = {0, -1, 0, 1, -1, 0, 0, -1, 1, 0, -0.5f, 0};
    static const uint32_t tris[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
    rbc_collider_state col;
    memset(&col, 0, sizeof col);
    col.shape = RBC_SHAPE_TRIANGLE_MESH;
    col.rotation[3] = 1.0f;
    CHECK_EQ(rbc_trimesh_create(tet, 4, tris, 4, &b.s.alloc, &col.mesh, err, sizeof err), RBC_OK);
    rbc_collider_update_frame(&col);
    CHECK_EQ(rbc_solver_add_collider(&b.s, &col), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    char named[64];
    snprintf(named, sizeof named, "%s backend", backend_name);
    CHECK(strstr(err, "RBC_SHAPE_TRIANGLE_MESH") != NULL && strstr(err, named) != NULL);
    fprintf(stderr, "  (message: %s)\n", err);
    CHECK(!memcmp(x0, b.c->x[1], n * sizeof(float)));
    CHECK_EQ(b.s.step_count, steps);
    rbc_solver_remove_collider(&b.s, 0);

    /* The energy guard with a collider that runs (a sphere): the colliders' work is
     * not summed on a backend, so the pair is refused. */
    memset(&col, 0, sizeof col);
    col.shape = RBC_SHAPE_SPHERE;
    col.radius = 0.1f;
    col.position[1] = -0.5f;
    col.rotation[3] = 1.0f;
    memcpy(col.last_position, col.position, sizeof col.position);
    memcpy(col.last_rotation, col.rotation, sizeof col.rotation);
    rbc_collider_update_frame(&col);
    CHECK_EQ(rbc_solver_add_collider(&b.s, &col), RBC_OK);
    st.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "energy guard with colliders") != NULL);
    CHECK(!memcmp(x0, b.c->x[1], n * sizeof(float)));
    CHECK_EQ(b.s.step_count, steps);
    st.energy_guard = RBC_ENERGY_GUARD_OFF; /* the sphere alone runs */
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    rbc_solver_remove_collider(&b.s, 0);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    free(x0);
    rbc_solver_fini(&b.s);
    mesh_free(&m);
}

/* The iteration modes and the energy guard. */
static void mode_tolerance(rbc_solver_settings *st) {
    st->mode = RBC_ITERATE_TOLERANCE;
    st->tolerance = 1e-3f;
    st->max_linear_iterations = 30;
}
static void mode_budget_all(rbc_solver_settings *st) { /* never reached: the cap, 9 */
    st->mode = RBC_ITERATE_BUDGET;
    st->budget_ms = 1e9f;
    st->max_linear_iterations = 9;
}
static void mode_budget_none(rbc_solver_settings *st) { /* always passed: 1 iteration */
    st->mode = RBC_ITERATE_BUDGET;
    st->budget_ms = 1e-9f;
    st->max_linear_iterations = 9;
}
static void mode_target(rbc_solver_settings *st) {
    st->mode = RBC_ITERATE_TARGET;
    st->target_strain = 0.01f;
    st->max_substeps = 6;
    st->max_linear_iterations = 20;
}
static void guard_clamp(rbc_solver_settings *st) { st->energy_guard = RBC_ENERGY_GUARD_CLAMP; }
static void guard_fail(rbc_solver_settings *st) { st->energy_guard = RBC_ENERGY_GUARD_FAIL; }


int main(int argc, char **argv) {
    if (argc > 1) {
        const int status = backend_module_open(argv[1], &cuda_open);
        if (status >= 0) return status;
        backend_name = "cuda";
    }
    static const struct {
        rbc_solver_kind kind;
        const char *name;
    } kinds[] = {
        {RBC_SOLVER_RBGS, "rbgs"},
        {RBC_SOLVER_MULTICOLOR_GS, "multicolor"},
        {RBC_SOLVER_RBGS_SOR, "rbgs-sor"},
        {RBC_SOLVER_RBGS_CHEBYSHEV, "rbgs-chebyshev"},
        {RBC_SOLVER_JACOBI, "jacobi"},
        {RBC_SOLVER_JACOBI_CHEBYSHEV, "jacobi-chebyshev"},
    };
    test_mesh meshes[4] = {mesh_grid(24, 20, 0.04f), mesh_cube(6), mesh_split_triangles(8),
                           mesh_torus(9, 7)};
    static const char *names[4] = {"grid 24x20", "cube 6", "split triangles 8", "torus 9x7"};
    for (int m = 0; m < 4; ++m)
        for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; ++k)
            parity(names[m], &meshes[m], kinds[k].kind, kinds[k].name);
    from_rate = 1;
    parity("grid 24x20 at 480 Hz", &meshes[0], RBC_SOLVER_RBGS, "rbgs");
    parity("torus 9x7 at 480 Hz", &meshes[3], RBC_SOLVER_JACOBI_CHEBYSHEV, "jacobi-chebyshev");
    from_rate = 0;
    /* The modes: the same stopping decisions from the backend's residual and strain
     * kernels (same_state compares the iteration and substep counts too). */
    static const struct {
        void (*fn)(rbc_solver_settings *);
        const char *name;
    } modes[] = {{mode_tolerance, "tolerance"}, {mode_target, "target"},
                 {guard_clamp, "energy guard"}};
    static const int mode_kinds[3] = {0, 3, 4}; /* rbgs, rbgs-chebyshev, jacobi */
    const uint64_t linear_before = linear_seen;
    for (size_t md = 0; md < sizeof modes / sizeof modes[0]; ++md) {
        tweak = modes[md].fn;
        for (int m = 0; m < 4; ++m)
            for (int k = 0; k < 3; ++k) {
                char label[96];
                snprintf(label, sizeof label, "%s, %s", names[m], modes[md].name);
                parity(label, &meshes[m], kinds[mode_kinds[k]].kind, kinds[mode_kinds[k]].name);
            }
    }
    fprintf(stderr, "  modes: %llu linear iterations, %llu clamped steps\n",
            (unsigned long long)(linear_seen - linear_before), (unsigned long long)clamped_seen);
    /* Two cloths: the residual and the strain are summed over both. */
    two_cloths = 1;
    tweak = mode_tolerance;
    parity("two grids, tolerance", &meshes[0], RBC_SOLVER_RBGS, "rbgs");
    tweak = mode_target;
    parity("two tori, target", &meshes[3], RBC_SOLVER_JACOBI_CHEBYSHEV, "jacobi-chebyshev");
    tweak = guard_clamp;
    parity("two cubes, energy guard", &meshes[1], RBC_SOLVER_JACOBI, "jacobi");
    /* The diverging case: the guard clamps (and the pins' work is in its budget). */
    const uint64_t clamped_before = clamped_seen;
    substeps_n = nonlinear_n = linear_n = 1;
    dt_step = 0.002f;
    steps_n = 60;
    parity("two grids, energy guard clamping", &meshes[0], RBC_SOLVER_JACOBI, "jacobi");
    parity("two tori, energy guard clamping", &meshes[3], RBC_SOLVER_JACOBI, "jacobi");
    substeps_n = 3, nonlinear_n = 2, linear_n = 7;
    dt_step = 1.0f / 60.0f;
    steps_n = 12;
    fprintf(stderr, "  diverging: %llu clamped steps\n",
            (unsigned long long)(clamped_seen - clamped_before));
    CHECK(clamped_seen - clamped_before > 0);
    two_cloths = 0;
    /* The budget, at its two ends (a time in between decides differently on every
     * run): never reached, every global step runs the cap (12 steps x 3 substeps x
     * 2 non-linear x 9); always passed, one iteration each. */
    tweak = guard_fail;
    substeps_n = nonlinear_n = linear_n = 1;
    dt_step = 0.002f;
    guard_fails();
    substeps_n = 3, nonlinear_n = 2, linear_n = 7;
    dt_step = 1.0f / 60.0f;
    tweak = mode_budget_all;
    uint64_t l0 = linear_seen;
    parity("grid 24x20, budget", &meshes[0], RBC_SOLVER_RBGS, "rbgs");
    CHECK_EQ(linear_seen - l0, 12u * 3u * 2u * 9u);
    tweak = mode_budget_none;
    l0 = linear_seen;
    parity("torus 9x7, budget", &meshes[3], RBC_SOLVER_JACOBI, "jacobi");
    CHECK_EQ(linear_seen - l0, 12u * 3u * 2u);
    tweak = NULL;
    for (int m = 0; m < 4; ++m) mesh_free(&meshes[m]);
    failure_restores();
    refused();
    return check_report(cuda_open ? "cuda_parity" : "core_backend_seam");
}
