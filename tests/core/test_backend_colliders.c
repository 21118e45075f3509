/* Colliders on a backend (backend_step.c's contact kernels, kernels/collide_kernels.h)
 * against the CPU pool's contact stages (contact_step.c, collide.c). Without an
 * argument on the CPU backend, on every machine; with the CUDA module's path (test
 * cuda_colliders_parity) on the CUDA backend, skipped (77) without a device.
 *
 *  1. A 16x16 cloth falls onto a plane (tilted), a sphere, a capsule (lying along x)
 *     and a box (turned about y), each static and moving (translating and turning
 *     every step), without friction and with it (the collider's mu 0.6, and once
 *     the cloth's own thickness and friction too), under rbgs (contacts per color
 *     with friction in the pass) and jacobi (contacts after every iteration, friction
 *     after the solve), and for one shape each the other solvers a backend runs: 24
 *     steps on both give the same positions and previous positions BIT FOR BIT, and
 *     the same contact counts. Both run the same float operations in the same order
 *     per particle (the contact math is one source; a particle's contacts are
 *     projected in collider order on both), so any difference is a schedule bug. The
 *     pool runs on the CSR rows, as in test_backend_seam (the lattice rows are not the
 *     kernels' sums).
 *     So that a pass proves something: contacts were found, the cloth did not fall
 *     through the collider (it rests on it: every particle outside the solid up to
 *     1 cm; free fall would put it 1 m below), and friction changed the result.
 *     Two cloths over two colliders, the pool on two threads: both cloths bit for
 *     bit, the contact count both cloths' sum. The tolerance and target modes on
 *     two shapes each, rbgs and jacobi (their checks read the iterate after the
 *     contacts' projection, on both).
 *  2. Four spheres in one place: every particle under them has four contacts, the
 *     backend's slots exactly, and the result is still the pool's bit for bit. A
 *     fifth fails the backend's step with RBC_ERR_UNSUPPORTED naming the slots, the
 *     state as it was; the pool runs it.
 *  3. A triangle mesh collider is refused by name, nothing changes.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backend_module.h"
#include "check.h"
#include "collide.h"
#include "meshes.h"
#include "rbcloth.h"
#include "shapes.h"
#include "solver.h"

static rbc_backend_open_fn *cuda_open;
static const char *backend_name = "cpu";

typedef struct world {
    rbc_solver s;
    rbc_cloth_state *c;
    struct rbc_lattice *lattice; /* the pool's, set aside while it runs on CSR rows */
} world;

enum { NX = 16, STEPS = 24 };
static const float spacing = 0.04f;

/* The pool's threads (threads_auto stays 0 after init: the step uses them all). */
static uint32_t pool_threads = 1;
/* The iteration mode of the worlds (the modes' checks read the iterate after the
 * contacts' projection, as the pool's do). */
static rbc_iteration_mode mode = RBC_ITERATE_FIXED;

static void make(world *w, const test_mesh *m, rbc_solver_kind kind, int on_backend,
                 float cloth_thick, float cloth_mu) {
    rbc_allocator a = rbc_allocator_default();
    CHECK_EQ(rbc_solver_init(&w->s, &a, on_backend ? 1 : pool_threads), RBC_OK);
    w->s.substeps = 3;
    w->s.nonlinear_iterations = 2;
    w->s.linear_iterations = 7;
    rbc_mesh_input in = mesh_input(m, NULL, 0);
    char err[256];
    CHECK_EQ(rbc_solver_create_cloth(&w->s, &in, 0.5f, &w->c, err, sizeof err), RBC_OK);
    CHECK_EQ(rbc_solver_add_cloth(&w->s, w->c), RBC_OK);
    if (cloth_thick > 0.0f || cloth_mu > 0.0f) /* no collision flags: no cloth contact */
        CHECK_EQ(rbc_solver_set_cloth_contact(&w->s, w->c, cloth_thick, cloth_mu, 0), RBC_OK);
    rbc_solver_settings st = w->s.settings;
    st.kind = kind;
    st.energy_guard = RBC_ENERGY_GUARD_OFF;
    st.mode = mode;
    st.tolerance = 1e-3f;
    st.target_strain = 0.01f;
    st.max_substeps = 6;
    st.max_linear_iterations = 20;
    CHECK_EQ(rbc_solver_set_settings(&w->s, &st), RBC_OK);
    w->lattice = NULL;
    if (on_backend) {
        rbc_backend_handle bk;
        char why[512];
        if (cuda_open)
            CHECK_EQ(cuda_open(RBC_BACKEND_INTERFACE, &bk, why, sizeof why), RBC_OK);
        else
            CHECK_EQ(rbc_backend_cpu_open(&bk), RBC_OK);
        rbc_solver_set_backend(&w->s, &bk);
    } else {
        w->lattice = w->c->lattice;
        w->c->lattice = NULL;
    }
}

static void unmake(world *w) {
    if (w->lattice) w->c->lattice = w->lattice;
    rbc_solver_fini(&w->s);
}

static int same_cloth(const rbc_cloth_state *a, const rbc_cloth_state *b);
static int same_state(const world *a, const world *b) { return same_cloth(a->c, b->c); }

static int same_cloth(const rbc_cloth_state *a, const rbc_cloth_state *b) {
    for (int ax = 0; ax < 3; ++ax)
        if (memcmp(a->x[ax], b->x[ax], a->topo.n * sizeof(float)) ||
            memcmp(a->q[ax], b->q[ax], a->topo.n * sizeof(float)))
            return 0;
    return 1;
}

static double max_diff(const world *a, const world *b) {
    double m = 0.0;
    for (int ax = 0; ax < 3; ++ax)
        for (uint32_t i = 0; i < a->c->topo.n; ++i)
            m = fmax(m, fabs((double)a->c->x[ax][i] - b->c->x[ax][i]));
    return m;
}

/* A unit quaternion: angle about axis (unit). */
static void quat(float out[4], const float axis[3], float angle) {
    float s = sinf(0.5f * angle);
    out[0] = axis[0] * s, out[1] = axis[1] * s, out[2] = axis[2] * s, out[3] = cosf(0.5f * angle);
}

typedef struct shape_case {
    const char *name;
    rbc_shape shape;
    float radius, he[3], pos[3], axis[3], angle;
} shape_case;

/* Under the cloth's middle (0.3, 0, 0.3); the cloth falls onto it within ~10 steps. */
static const shape_case shapes[] = {
    {"plane", RBC_SHAPE_PLANE, 0.0f, {0, 0, 0}, {0.3f, -0.15f, 0.3f}, {0, 0, 1}, 0.2f},
    {"sphere", RBC_SHAPE_SPHERE, 0.2f, {0, 0, 0}, {0.3f, -0.3f, 0.3f}, {0, 1, 0}, 0.0f},
    {"capsule", RBC_SHAPE_CAPSULE, 0.1f, {0, 0.2f, 0}, {0.3f, -0.25f, 0.3f}, {0, 0, 1}, 1.5707964f},
    {"box", RBC_SHAPE_BOX, 0.0f, {0.15f, 0.1f, 0.15f}, {0.3f, -0.25f, 0.3f}, {0, 1, 0}, 0.5f},
};

static rbc_collider_state collider(const shape_case *sc, float mu) {
    rbc_collider_state col;
    memset(&col, 0, sizeof col);
    col.shape = sc->shape;
    col.radius = sc->radius;
    memcpy(col.half_extents, sc->he, sizeof col.half_extents);
    memcpy(col.position, sc->pos, sizeof col.position);
    quat(col.rotation, sc->axis, sc->angle);
    col.thickness = 0.005f;
    col.friction = mu;
    rbc_collider_update_frame(&col);
    return col;
}

/* The collider's pose at step k when moving: 1 cm a step along x and up (speed 1), or
 * 6 cm (speed 2: it strikes the cloth, and the springs drag particles past the
 * detection margin, which the safety pass catches), turning 0.05 rad a step about a
 * tilted axis. */
static void move(rbc_collider_state *col, const shape_case *sc, int k, int speed) {
    const float v = speed > 1 ? 0.06f : 0.01f;
    col->position[0] = sc->pos[0] + v * (float)k;
    col->position[1] = sc->pos[1] + v * (float)k;
    col->position[2] = sc->pos[2];
    const float ax[3] = {0.6f, 0.0f, 0.8f};
    float q0[4], q1[4];
    quat(q0, sc->axis, sc->angle);
    quat(q1, ax, 0.05f * (float)k);
    /* q1 * q0 */
    col->rotation[0] = q1[3] * q0[0] + q1[0] * q0[3] + q1[1] * q0[2] - q1[2] * q0[1];
    col->rotation[1] = q1[3] * q0[1] - q1[0] * q0[2] + q1[1] * q0[3] + q1[2] * q0[0];
    col->rotation[2] = q1[3] * q0[2] + q1[0] * q0[1] - q1[1] * q0[0] + q1[2] * q0[3];
    col->rotation[3] = q1[3] * q0[3] - q1[0] * q0[0] - q1[1] * q0[1] - q1[2] * q0[2];
    rbc_collider_update_frame(col);
}

/* The lowest signed distance of the cloth's particles to collider col, m. */
static double lowest_phi(const world *w, const rbc_collider_state *col) {
    rbc_frame fr;
    rbc_collider_frame_at(col, 1.0f, &fr);
    double lo = INFINITY;
    for (uint32_t i = 0; i < w->c->topo.n; ++i) {
        float p[3] = {w->c->x[0][i], w->c->x[1][i], w->c->x[2][i]}, l[3], n[3], phi;
        rbc_kc_to_local(&fr, p, l);
        rbc_shape_distance(&col->geom, l, INFINITY, &phi, n);
        lo = fmin(lo, phi);
    }
    return lo;
}

/* One scene on the pool and the backend; the pool's final x[1] into y_out (for the
 * friction comparison). Returns 1 if every step matched. */
static int parity(const test_mesh *m, const shape_case *sc, int moving, float mu,
                  float cloth_thick, float cloth_mu, rbc_solver_kind kind, const char *kind_name,
                  float *y_out) {
    world a, b;
    make(&a, m, kind, 0, cloth_thick, cloth_mu);
    make(&b, m, kind, 1, cloth_thick, cloth_mu);
    rbc_collider_state col = collider(sc, mu);
    CHECK_EQ(rbc_solver_add_collider(&a.s, &col), RBC_OK);
    CHECK_EQ(rbc_solver_add_collider(&b.s, &col), RBC_OK);
    char err[512];
    int ok = 1;
    uint32_t contacts = 0;
    for (int step = 0; step < STEPS && ok; ++step) {
        if (moving) {
            move(&a.s.colliders[0], sc, step + 1, moving);
            move(&b.s.colliders[0], sc, step + 1, moving);
        }
        int32_t ra = rbc_solver_step(&a.s, 1.0f / 60.0f, err, sizeof err);
        CHECK_EQ(ra, RBC_OK);
        int32_t rb = rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err);
        CHECK_EQ(rb, RBC_OK);
        if (rb != RBC_OK) fprintf(stderr, "  (%s)\n", err);
        CHECK_EQ(a.s.last_contacts, b.s.last_contacts);
        if (contacts < a.s.last_contacts) contacts = a.s.last_contacts;
        if (!same_state(&a, &b) || ra != RBC_OK || rb != RBC_OK) {
            fprintf(stderr, "%s %s, mu %.1f, %s: step %d differs (largest %.3g m)\n", sc->name,
                    moving > 1 ? "fast" : moving ? "moving" : "static", (double)mu, kind_name, step, max_diff(&a, &b));
            ok = 0;
        }
    }
    CHECK(ok);
    /* It touched, and it rests on the collider rather than falling through. */
    CHECK(contacts > 0);
    const double phi = lowest_phi(&b, &b.s.colliders[0]);
    if (!(phi > -0.01)) fprintf(stderr, "%s, %s: a particle %.3g m inside\n", sc->name, kind_name, phi);
    CHECK(phi > -0.01);
    if (y_out) memcpy(y_out, a.c->x[1], a.c->topo.n * sizeof(float));
    unmake(&a);
    unmake(&b);
    return ok;
}

static void friction_matters(const test_mesh *m, const shape_case *sc, rbc_solver_kind kind,
                             const char *kind_name) {
    float *y0 = malloc(m->nv * sizeof(float)), *y1 = malloc(m->nv * sizeof(float));
    parity(m, sc, 1, 0.0f, 0.0f, 0.0f, kind, kind_name, y0);
    parity(m, sc, 1, 0.6f, 0.0f, 0.0f, kind, kind_name, y1);
    /* Friction changed where the cloth went: a contact kernel that ignored mu on both
     * paths alike would pass the parity checks. */
    CHECK(memcmp(y0, y1, m->nv * sizeof(float)) != 0);
    free(y0);
    free(y1);
}

/* Two cloths (one above the other, no cloth contact) over a moving box and a static
 * sphere, the pool on two threads (its contact lists split by particle blocks): both
 * cloths bit for bit, and the stats' contact count the sum of both cloths'. */
static void two_cloths(const test_mesh *m) {
    world a, b;
    rbc_cloth_state *a2 = NULL, *b2 = NULL;
    struct rbc_lattice *lat2 = NULL;
    test_mesh up = mesh_grid(NX, NX, spacing);
    for (uint32_t v = 0; v < up.nv; ++v) up.pos[3 * v + 1] += 0.1f;
    for (int w = 0; w < 2; ++w) {
        world *x = w ? &b : &a;
        rbc_cloth_state **c2 = w ? &b2 : &a2;
        pool_threads = 2;
        make(x, m, RBC_SOLVER_RBGS, w, 0.0f, 0.0f);
        pool_threads = 1;
        rbc_mesh_input in = mesh_input(&up, NULL, 0);
        char err[256];
        CHECK_EQ(rbc_solver_create_cloth(&x->s, &in, 0.5f, c2, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_add_cloth(&x->s, *c2), RBC_OK);
        rbc_collider_state col = collider(&shapes[3], 0.6f);
        CHECK_EQ(rbc_solver_add_collider(&x->s, &col), RBC_OK);
        col = collider(&shapes[1], 0.0f);
        col.position[0] = 0.1f;
        CHECK_EQ(rbc_solver_add_collider(&x->s, &col), RBC_OK);
    }
    lat2 = a2->lattice;
    a2->lattice = NULL;
    CHECK_EQ(a.s.threads_auto, 0u);
    char err[512];
    int ok = 1;
    uint32_t contacts = 0;
    for (int step = 0; step < STEPS && ok; ++step) {
        move(&a.s.colliders[0], &shapes[3], step + 1, 1);
        move(&b.s.colliders[0], &shapes[3], step + 1, 1);
        CHECK_EQ(rbc_solver_step(&a.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
        CHECK_EQ(a.s.last_contacts, b.s.last_contacts);
        if (contacts < a.s.last_contacts) contacts = a.s.last_contacts;
        if (!same_state(&a, &b) || !same_cloth(a2, b2)) {
            fprintf(stderr, "two cloths: step %d differs\n", step);
            ok = 0;
        }
    }
    CHECK(ok);
    /* More than one cloth's worth: the 16 x 16 grid has 256 particles. */
    CHECK(contacts > 256);
    a2->lattice = lat2;
    unmake(&a);
    unmake(&b);
    mesh_free(&up);
}

/* Four, then five, spheres in one place. */
static void slots(const test_mesh *m) {
    const shape_case *sc = &shapes[1];
    for (int count = 4; count <= 5; ++count) {
        world a, b;
        make(&a, m, RBC_SOLVER_RBGS, 0, 0.0f, 0.0f);
        make(&b, m, RBC_SOLVER_RBGS, 1, 0.0f, 0.0f);
        rbc_collider_state col = collider(sc, 0.3f);
        for (int k = 0; k < count; ++k) {
            CHECK_EQ(rbc_solver_add_collider(&a.s, &col), RBC_OK);
            CHECK_EQ(rbc_solver_add_collider(&b.s, &col), RBC_OK);
        }
        char err[512];
        const uint32_t n = b.c->topo.n;
        float *x0 = malloc(n * sizeof(float));
        int failed = 0, ok = 1;
        for (int step = 0; step < STEPS && !failed; ++step) {
            memcpy(x0, b.c->x[1], n * sizeof(float));
            const uint64_t steps = b.s.step_count;
            CHECK_EQ(rbc_solver_step(&a.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
            int32_t rb = rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err);
            if (rb != RBC_OK) {
                failed = 1;
                CHECK_EQ(count, 5);
                CHECK_EQ(rb, RBC_ERR_UNSUPPORTED);
                CHECK(strstr(err, "contact slots") != NULL);
                fprintf(stderr, "  (message: %s)\n", err);
                CHECK(!memcmp(x0, b.c->x[1], n * sizeof(float)));
                CHECK_EQ(b.s.step_count, steps);
            } else {
                ok = ok && same_state(&a, &b);
            }
        }
        CHECK(ok);
        /* Five colliders over the cloth's middle must overflow before the end. */
        CHECK_EQ(failed, count == 5);
        free(x0);
        unmake(&a);
        unmake(&b);
    }
}

static void mesh_refused(const test_mesh *m) {
    world b;
    make(&b, m, RBC_SOLVER_RBGS, 1, 0.0f, 0.0f);
    char err[512];
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    static const float tet[] = {0, -1, 0, 1, -1, 0, 0, -1, 1, 0, -0.5f, 0};
    static const uint32_t tris[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
    rbc_collider_state col;
    memset(&col, 0, sizeof col);
    col.shape = RBC_SHAPE_TRIANGLE_MESH;
    col.rotation[3] = 1.0f;
    CHECK_EQ(rbc_trimesh_create(tet, 4, tris, 4, &b.s.alloc, &col.mesh, err, sizeof err), RBC_OK);
    rbc_collider_update_frame(&col);
    CHECK_EQ(rbc_solver_add_collider(&b.s, &col), RBC_OK);
    const uint32_t n = b.c->topo.n;
    float *x0 = malloc(n * sizeof(float));
    memcpy(x0, b.c->x[1], n * sizeof(float));
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_ERR_UNSUPPORTED);
    char named[64];
    snprintf(named, sizeof named, "%s backend", backend_name);
    CHECK(strstr(err, "RBC_SHAPE_TRIANGLE_MESH") != NULL && strstr(err, named) != NULL);
    fprintf(stderr, "  (message: %s)\n", err);
    CHECK(!memcmp(x0, b.c->x[1], n * sizeof(float)));
    rbc_solver_remove_collider(&b.s, 0);
    CHECK_EQ(rbc_solver_step(&b.s, 1.0f / 60.0f, err, sizeof err), RBC_OK);
    free(x0);
    unmake(&b);
}

int main(int argc, char **argv) {
    if (argc > 1) {
        const int status = backend_module_open(argv[1], &cuda_open);
        if (status >= 0) return status;
        backend_name = "cuda";
    }
    test_mesh m = mesh_grid(NX, NX, spacing);
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; ++s)
        for (int moving = 0; moving < 3; ++moving)
            for (int f = 0; f < 2; ++f) {
                const float mu = f ? 0.6f : 0.0f;
                parity(&m, &shapes[s], moving, mu, 0.0f, 0.0f, RBC_SOLVER_RBGS, "rbgs", NULL);
                parity(&m, &shapes[s], moving, mu, 0.0f, 0.0f, RBC_SOLVER_JACOBI, "jacobi", NULL);
            }
    /* The cloth's own thickness and friction (no collision flags: no cloth contact). */
    parity(&m, &shapes[3], 1, 0.2f, 0.004f, 0.5f, RBC_SOLVER_RBGS, "rbgs", NULL);
    parity(&m, &shapes[3], 1, 0.2f, 0.004f, 0.5f, RBC_SOLVER_JACOBI, "jacobi", NULL);
    /* The other solvers a backend runs, each on one shape, moving, with friction. */
    /* The tolerance and target modes with contacts (same_state: the same positions;
     * the contact counts too). */
    mode = RBC_ITERATE_TOLERANCE;
    parity(&m, &shapes[1], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_RBGS, "rbgs, tolerance", NULL);
    parity(&m, &shapes[3], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_JACOBI, "jacobi, tolerance", NULL);
    mode = RBC_ITERATE_TARGET;
    parity(&m, &shapes[0], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_RBGS, "rbgs, target", NULL);
    parity(&m, &shapes[2], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_JACOBI, "jacobi, target", NULL);
    mode = RBC_ITERATE_FIXED;
    parity(&m, &shapes[0], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_RBGS_SOR, "rbgs-sor", NULL);
    parity(&m, &shapes[1], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_MULTICOLOR_GS, "multicolor", NULL);
    parity(&m, &shapes[2], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_RBGS_CHEBYSHEV, "rbgs-chebyshev", NULL);
    parity(&m, &shapes[3], 1, 0.6f, 0.0f, 0.0f, RBC_SOLVER_JACOBI_CHEBYSHEV, "jacobi-chebyshev",
           NULL);
    friction_matters(&m, &shapes[0], RBC_SOLVER_RBGS, "rbgs");
    friction_matters(&m, &shapes[3], RBC_SOLVER_JACOBI, "jacobi");
    two_cloths(&m);
    slots(&m);
    mesh_refused(&m);
    mesh_free(&m);
    return check_report(cuda_open ? "cuda_colliders_parity" : "core_backend_colliders");
}
