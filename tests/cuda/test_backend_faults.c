/* test_backend_faults.c -- a backend that fails part-way through a step (a lost
 * device, an allocation that fails) never corrupts the world: every call the step
 * makes to the backend is failed in turn, through the stand-in module's fault
 * injection (standin_module.c), and each time
 *   - the step returns an error naming the backend's failure, not RBC_OK;
 *   - the host's state (x and q of every cloth) and the step count are bitwise as
 *     they were before the step;
 *   - the next step, with no fault, succeeds and gives bit for bit what a world that
 *     never failed gives (the backend's copy is uploaded again each step).
 * The calls are those of a first step (the cloth's copy is allocated and uploaded)
 * and of a later one, in the fixed mode (a recorded step, as a CUDA graph), the
 * tolerance mode (readbacks between iterations), with the energy guard and with a
 * sphere collider the cloths lie on, on two cloths. Run: test_backend_faults STANDIN_MODULE. */
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backend_module.h"
#include "check.h"
#include "meshes.h"
#include "rbcloth.h"
#include "solver.h"

static rbc_backend_open_fn *open_fn;
/* A sphere under the cloth (its contacts' kernels and uploads in the step). */
static int with_sphere;
static void (*fail_at)(long);
static long (*calls)(void);

typedef struct world {
    rbc_solver s;
    rbc_cloth_state *c[2];
} world;

static void make(world *w, const test_mesh *m, rbc_solver_kind kind, rbc_iteration_mode mode,
                 rbc_energy_guard guard, int on_backend) {
    rbc_allocator a = rbc_allocator_default();
    CHECK_EQ(rbc_solver_init(&w->s, &a, 1), RBC_OK);
    w->s.substeps = 2;
    w->s.linear_iterations = 5;
    char err[256];
    for (int k = 0; k < 2; ++k) {
        uint32_t pins[2] = {0, m->nv - 1};
        rbc_mesh_input in = mesh_input(m, pins, k ? 1u : 2u);
        CHECK_EQ(rbc_solver_create_cloth(&w->s, &in, 0.5f, &w->c[k], err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_add_cloth(&w->s, w->c[k]), RBC_OK);
    }
    rbc_solver_settings st = w->s.settings;
    st.kind = kind;
    st.mode = mode;
    st.tolerance = 1e-3f;
    st.max_linear_iterations = 20;
    st.energy_guard = guard;
    CHECK_EQ(rbc_solver_set_settings(&w->s, &st), RBC_OK);
    if (with_sphere) {
        rbc_collider_state col;
        memset(&col, 0, sizeof col);
        col.shape = RBC_SHAPE_SPHERE;
        col.radius = 0.1f;
        col.position[0] = 0.2f;
        col.position[1] = -0.12f;
        col.position[2] = 0.15f;
        col.rotation[3] = 1.0f;
        col.friction = 0.4f;
        memcpy(col.last_position, col.position, sizeof col.position);
        memcpy(col.last_rotation, col.rotation, sizeof col.rotation);
        rbc_collider_update_frame(&col);
        CHECK_EQ(rbc_solver_add_collider(&w->s, &col), RBC_OK);
    }
    if (on_backend) {
        rbc_backend_handle bk;
        char why[256];
        CHECK_EQ(open_fn(RBC_BACKEND_INTERFACE, &bk, why, sizeof why), RBC_OK);
        rbc_solver_set_backend(&w->s, &bk);
    }
}

/* Both cloths' x and q into / compared with a saved copy. */
typedef struct saved {
    float *v[2][2][3];
} saved;

static void save(const world *w, saved *sv) {
    for (int k = 0; k < 2; ++k)
        for (int a = 0; a < 3; ++a) {
            size_t bytes = w->c[k]->topo.n * sizeof(float);
            sv->v[k][0][a] = malloc(bytes);
            sv->v[k][1][a] = malloc(bytes);
            memcpy(sv->v[k][0][a], w->c[k]->x[a], bytes);
            memcpy(sv->v[k][1][a], w->c[k]->q[a], bytes);
        }
}
static int unchanged(const world *w, const saved *sv) {
    int same = 1;
    for (int k = 0; k < 2; ++k)
        for (int a = 0; a < 3; ++a) {
            size_t bytes = w->c[k]->topo.n * sizeof(float);
            same = same && !memcmp(sv->v[k][0][a], w->c[k]->x[a], bytes) &&
                   !memcmp(sv->v[k][1][a], w->c[k]->q[a], bytes);
        }
    return same;
}
static void unsave(saved *sv) {
    for (int k = 0; k < 2; ++k)
        for (int a = 0; a < 3; ++a) {
            free(sv->v[k][0][a]);
            free(sv->v[k][1][a]);
        }
}
static int same_worlds(const world *a, const world *b) {
    saved sv;
    save(a, &sv);
    int same = unchanged(b, &sv);
    unsave(&sv);
    return same;
}

/* Fail each backend call of the step after `warm` good ones, in turn. */
static void faults(const char *name, const test_mesh *m, rbc_solver_kind kind,
                   rbc_iteration_mode mode, rbc_energy_guard guard, int warm) {
    world ref, dev;
    make(&ref, m, kind, mode, guard, 0);
    make(&dev, m, kind, mode, guard, 1);
    struct rbc_lattice *lat[2]; /* the pool on the CSR rows, as the kernels */
    for (int k = 0; k < 2; ++k) {
        lat[k] = ref.c[k]->lattice;
        ref.c[k]->lattice = NULL;
    }
    char err[512];
    const float dt = 1.0f / 60.0f;
    for (int s = 0; s < warm; ++s) {
        CHECK_EQ(rbc_solver_step(&ref.s, dt, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_step(&dev.s, dt, err, sizeof err), RBC_OK);
    }
    /* How many calls the step makes: count them on a copy of the step, then undo it
     * on the device world by failing its last call (its state is the check below). */
    fail_at(0);
    world probe;
    make(&probe, m, kind, mode, guard, 1);
    for (int s = 0; s < warm; ++s) CHECK_EQ(rbc_solver_step(&probe.s, dt, err, sizeof err), RBC_OK);
    fail_at(0);
    CHECK_EQ(rbc_solver_step(&probe.s, dt, err, sizeof err), RBC_OK);
    const long n = calls();
    rbc_solver_fini(&probe.s);
    CHECK(n > 10);
    int all_ok = 1;
    for (long f = 1; f <= n; ++f) {
        /* A first step's faults each on a new world: a failed creation leaves part of
         * the backend's copies made, and the next try makes fewer calls. */
        if (!warm && f > 1) {
            rbc_solver_fini(&dev.s);
            make(&dev, m, kind, mode, guard, 1);
        }
        saved sv;
        save(&dev, &sv);
        const uint64_t steps = dev.s.step_count;
        fail_at(f);
        err[0] = 0;
        int32_t rc = rbc_solver_step(&dev.s, dt, err, sizeof err);
        fail_at(0);
        int ok = rc != RBC_OK && strstr(err, "injected fault") && unchanged(&dev, &sv) &&
                 dev.s.step_count == steps;
        if (!ok && all_ok)
            fprintf(stderr, "%s: failing call %ld of %ld: rc %d, \"%s\", state %s\n", name, f, n,
                    (int)rc, err, unchanged(&dev, &sv) ? "intact" : "CHANGED");
        all_ok = all_ok && ok;
        unsave(&sv);
        if (!warm) { /* and the next try makes the cloths' copies and steps */
            world one;
            make(&one, m, kind, mode, guard, 0);
            struct rbc_lattice *ol[2];
            for (int k = 0; k < 2; ++k) {
                ol[k] = one.c[k]->lattice;
                one.c[k]->lattice = NULL;
            }
            CHECK_EQ(rbc_solver_step(&one.s, dt, err, sizeof err), RBC_OK);
            CHECK_EQ(rbc_solver_step(&dev.s, dt, err, sizeof err), RBC_OK);
            all_ok = all_ok && same_worlds(&one, &dev);
            for (int k = 0; k < 2; ++k) one.c[k]->lattice = ol[k];
            rbc_solver_fini(&one.s);
        }
    }
    CHECK(all_ok);
    fprintf(stderr, "  %s: each of the step's %ld backend calls failed in turn, the state "
                    "intact each time\n", name, n);
    /* Recovery: the next good step is the reference's. */
    if (warm) {
        CHECK_EQ(rbc_solver_step(&ref.s, dt, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_step(&dev.s, dt, err, sizeof err), RBC_OK);
        CHECK(same_worlds(&ref, &dev));
        CHECK_EQ(dev.s.last_contacts, ref.s.last_contacts);
        if (with_sphere) CHECK(dev.s.last_contacts > 0); /* the cloths lie on it */
    }
    for (int k = 0; k < 2; ++k) ref.c[k]->lattice = lat[k];
    rbc_solver_fini(&ref.s);
    rbc_solver_fini(&dev.s);
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: test_backend_faults STANDIN_MODULE\n");
        return 2;
    }
    const int status = backend_module_open(argv[1], &open_fn);
    if (status >= 0) return status;
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL); /* loaded already: its handle */
    fail_at = h ? (void (*)(long))dlsym(h, "rbc_standin_fail_at") : NULL;
    calls = h ? (long (*)(void))dlsym(h, "rbc_standin_calls") : NULL;
    if (!fail_at || !calls) {
        fprintf(stderr, "FAIL: %s is not the stand-in module\n", argv[1]);
        return 1;
    }
    test_mesh grid = mesh_grid(10, 8, 0.05f), torus = mesh_torus(7, 5);
    faults("first step, fixed, rbgs", &grid, RBC_SOLVER_RBGS, RBC_ITERATE_FIXED,
           RBC_ENERGY_GUARD_OFF, 0);
    faults("later step, fixed, rbgs, energy guard", &grid, RBC_SOLVER_RBGS, RBC_ITERATE_FIXED,
           RBC_ENERGY_GUARD_CLAMP, 2);
    with_sphere = 1;
    faults("later step, fixed, rbgs, a sphere", &grid, RBC_SOLVER_RBGS, RBC_ITERATE_FIXED,
           RBC_ENERGY_GUARD_OFF, 8);
    with_sphere = 0;
    faults("later step, tolerance, jacobi", &torus, RBC_SOLVER_JACOBI, RBC_ITERATE_TOLERANCE,
           RBC_ENERGY_GUARD_OFF, 2);
    mesh_free(&grid);
    mesh_free(&torus);
    return check_report("cuda_backend_faults");
}
