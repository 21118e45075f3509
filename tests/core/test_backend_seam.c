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
 *  2. A non-finite position fails the step with RBC_ERR_UNSTABLE naming the vertex,
 *     and the state is as it was before the step.
 *  3. A scene feature the backends do not run (a triangle mesh collider, the energy
 *     guard, a tolerance mode) is refused with RBC_ERR_UNSUPPORTED naming it, and
 *     nothing changes. (The analytic colliders run: test_backend_colliders.c.)
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    rbc_cloth_state *c;
} world;

static void make(world *w, const test_mesh *m, rbc_solver_kind kind, int on_backend) {
    rbc_allocator a = rbc_allocator_default();
    CHECK_EQ(rbc_solver_init(&w->s, &a, 1), RBC_OK);
    w->s.substeps = from_rate ? 0 : 3;
    w->s.substep_rate = 480.0f;
    w->s.nonlinear_iterations = 2;
    w->s.linear_iterations = 7;
    uint32_t pins[2] = {0, m->nv - 1};
    rbc_mesh_input in = mesh_input(m, pins, 2);
    char err[256];
    CHECK_EQ(rbc_solver_create_cloth(&w->s, &in, 0.5f, &w->c, err, sizeof err), RBC_OK);
    CHECK_EQ(rbc_solver_add_cloth(&w->s, w->c), RBC_OK);
    rbc_solver_settings st = w->s.settings;
    st.kind = kind;
    st.energy_guard = RBC_ENERGY_GUARD_OFF;
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

static int same_state(const world *a, const world *b) {
    const uint32_t n = a->c->topo.n;
    for (int ax = 0; ax < 3; ++ax)
        if (memcmp(a->c->x[ax], b->c->x[ax], n * sizeof(float)) ||
            memcmp(a->c->q[ax], b->c->q[ax], n * sizeof(float)))
            return 0;
    return 1;
}

/* Largest |a - b| over the positions, for the message when they differ. */
static double max_diff(const world *a, const world *b) {
    double m = 0.0;
    for (int ax = 0; ax < 3; ++ax)
        for (uint32_t i = 0; i < a->c->topo.n; ++i)
            m = fmax(m, fabs((double)a->c->x[ax][i] - b->c->x[ax][i]));
    return m;
}

static void parity(const char *mesh_name, const test_mesh *m, rbc_solver_kind kind,
                   const char *kind_name) {
    world a, b;
    make(&a, m, kind, 0);
    make(&b, m, kind, 1);
    /* The pool's lattice rows are not the CSR rows' sums in their order (uniform rows
     * factor the stiffness out; the right-hand side sums left, right, down, up): a
     * few roundings apart, which the one-source work of the kernels is to remove.
     * The schedule is compared on the CSR rows the kernels are. */
    struct rbc_lattice *lattice = a.c->lattice;
    a.c->lattice = NULL;
    char err[512];
    int ok = 1;
    for (int step = 0; step < 12 && ok; ++step) {
        /* The second pin travels 2 cm a step, so the pins' paths are exercised. */
        float tgt[3] = {m->pos[3 * (m->nv - 1)] + 0.02f * (float)step,
                        m->pos[3 * (m->nv - 1) + 1], m->pos[3 * (m->nv - 1) + 2]};
        CHECK_EQ(rbc_cloth_state_set_pin(&a.s.alloc, a.c, m->nv - 1, tgt), RBC_OK);
        CHECK_EQ(rbc_cloth_state_set_pin(&b.s.alloc, b.c, m->nv - 1, tgt), RBC_OK);
        int32_t ra = rbc_solver_step(&a.s, 1.0f / 60.0f, err, sizeof err);
        int32_t rb = rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err);
        CHECK_EQ(ra, RBC_OK);
        CHECK_EQ(rb, RBC_OK);
        if (!same_state(&a, &b)) {
            fprintf(stderr, "%s, %s: step %d differs (largest %.3g m)\n", mesh_name, kind_name,
                    step, max_diff(&a, &b));
            ok = 0;
        }
    }
    CHECK(ok);
    /* The cloth moved: a comparison of two resting cloths would prove little. */
    CHECK(fabs((double)a.c->x[1][a.c->topo.to_internal[m->nv / 2]] - m->pos[3 * (m->nv / 2) + 1]) >
          1e-3);
    a.c->lattice = lattice;
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
    st.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "energy guard") != NULL);
    st.energy_guard = RBC_ENERGY_GUARD_OFF;
    st.mode = RBC_ITERATE_TOLERANCE;
    st.tolerance = 1e-3f;
    CHECK_EQ(rbc_solver_set_settings(&b.s, &st), RBC_OK);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "RBC_ITERATE_FIXED") != NULL);
    st.mode = RBC_ITERATE_FIXED;
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
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    free(x0);
    rbc_solver_fini(&b.s);
    mesh_free(&m);
}

int main(int argc, char **argv) {
    if (argc > 1) {
        void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
        if (!h) {
            fprintf(stderr, "FAIL: the CUDA module %s does not load: %s\n", argv[1], dlerror());
            return 1;
        }
        cuda_open = (rbc_backend_open_fn *)dlsym(h, RBC_BACKEND_OPEN_SYMBOL);
        if (!cuda_open) {
            fprintf(stderr, "FAIL: %s has no %s\n", argv[1], RBC_BACKEND_OPEN_SYMBOL);
            return 1;
        }
        rbc_backend_handle probe;
        char why[512];
        int32_t rc = cuda_open(RBC_BACKEND_INTERFACE, &probe, why, sizeof why);
        if (rc == RBC_ERR_BACKEND_UNAVAILABLE) {
            /* On a machine that has a GPU, a skip would hide a driver too old for the
             * module's runtime: RBC_REQUIRE_CUDA=1 (tests/cuda/device_check.sh) makes
             * it a failure. */
            const char *req = getenv("RBC_REQUIRE_CUDA");
            if (req && !strcmp(req, "1")) {
                fprintf(stderr, "FAIL: RBC_REQUIRE_CUDA=1 and the CUDA backend is "
                                "unavailable: %s\n", why);
                return 1;
            }
            printf("SKIP: the CUDA backend is unavailable here (%s); parity not run\n", why);
            return 77;
        }
        CHECK_EQ(rc, RBC_OK);
        if (rc != RBC_OK) return check_report("cuda_parity");
        fprintf(stderr, "  CUDA device: %s\n", probe.ops->describe(probe.be));
        probe.ops->close(probe.be);
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
    for (int m = 0; m < 4; ++m) mesh_free(&meshes[m]);
    failure_restores();
    refused();
    return check_report(cuda_open ? "cuda_parity" : "core_backend_seam");
}
