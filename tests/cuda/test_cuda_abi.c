/* test_cuda_abi.c -- RBC_BACKEND_CUDA through the public ABI (issue 22, item 4).
 *
 *   test_cuda_abi module      the CUDA module was built beside the plugin
 *   test_cuda_abi missing     $RBC_CUDA_MODULE names a file that does not exist
 *   test_cuda_abi standin     $RBC_CUDA_MODULE names the stand-in module (the CPU
 *                             backend behind the module's entry point): the device
 *                             checks below run on every machine, through the CPU
 *                             backend instead of the GPU
 *
 * Without a CUDA device (or without the module):
 *   - rbc_world_create with RBC_BACKEND_CUDA is RBC_ERR_BACKEND_UNAVAILABLE, makes no
 *     world, and says why: "no CUDA device" and the runtime's own words when the
 *     module loaded, the dlopen error when it did not;
 *   - RBC_BACKEND_AUTO makes a CPU world (stats.backend) that steps.
 * With a device (module mode; not yet run on a GPU: none was lent where this was
 * written), or the stand-in:
 *   - the default def (the energy guard on, substeps from the rate) makes a CUDA
 *     world that steps a pinned cloth;
 *   - the paper's def (one substep a frame) with the guard off makes a CUDA world
 *     (stats.backend) whose 32 x 32 cloth, stepped 60 times (1 s), stays within
 *     1 mm of the CPU world's at every step while it falls more than 0.1 m: the two
 *     run the same kernels, but the CPU's lattice rows round differently (7.8e-7 m
 *     apart after the first step, 4.6e-5 m at most over the second, through the
 *     stand-in); cuda_parity checks the schedule bit for bit on the CSR rows;
 *   - rbc_world_set_solver(DIRECT) is RBC_ERR_UNSUPPORTED and changes nothing;
 *   - a sphere collider runs: the cloth swings onto it for 1 s, the stats count its
 *     contacts and no particle gets inside it (tests/core/test_backend_colliders.c
 *     checks colliders bit for bit against the pool).
 */
#include "abi_util.h"

static int contains(const char *s, const char *w) { return s && strstr(s, w) != NULL; }

static void no_device(const char *mode) {
    rbc_world_def d = abi_world_def_fixed();
    d.backend = RBC_BACKEND_CUDA;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&d, &w), RBC_ERR_BACKEND_UNAVAILABLE);
    CHECK_EQ(w, 0u);
    const char *msg = rbc_last_error();
    fprintf(stderr, "  (message: %s)\n", msg);
    CHECK(contains(msg, "RBC_BACKEND_CUDA is unavailable"));
    CHECK(contains(msg, "RBC_BACKEND_CPU or RBC_BACKEND_AUTO"));
    if (!strcmp(mode, "module"))
        CHECK(contains(msg, "no CUDA device") && contains(msg, "cudaGetDeviceCount"));
    else
        CHECK(contains(msg, "could not be loaded") && contains(msg, "No such file"));
}

static void auto_is_cpu(void) {
    rbc_world_def d = abi_world_def_fixed();
    d.backend = RBC_BACKEND_AUTO;
    d.thread_count = 1;
    rbc_world_id w = test_world(&d);
    test_grid g = test_grid_make(8, 8, 0.05f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_def cd = test_grid_def(&g, NULL, 0);
    rbc_cloth_id c;
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    CHECK_EQ(rbc_world_get_stats(w, &st), RBC_OK);
    CHECK_EQ(st.backend, RBC_BACKEND_CPU);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

/* The paper's def with the energy guard off: what the CUDA backend runs. */
static rbc_world_def cuda_def(rbc_solver_def *sd) {
    CHECK_EQ(rbc_solver_def_preset(sd, (uint32_t)sizeof *sd, RBC_PRESET_PAPER), RBC_OK);
    sd->energy_guard = RBC_ENERGY_GUARD_OFF;
    rbc_world_def d = rbc_world_def_default();
    d.solver = sd;
    d.thread_count = 1;
    /* The paper's one substep a frame: with the rate's 8, a rounding apart grows
     * to centimetres within a second of this swinging cloth (measured 2.6 cm),
     * which says how sensitive the cloth is, not how far apart the backends are. */
    d.substeps = 1;
    return d;
}

static void with_device(void) {
    /* The default def (the energy guard on, substeps from the rate) runs on it. */
    rbc_world_def dd = rbc_world_def_default();
    dd.backend = RBC_BACKEND_CUDA;
    rbc_world_id w = test_world(&dd);
    test_grid g0 = test_grid_make(16, 16, 0.04f, 0.0f, 1.0f, 0.0f);
    const uint32_t pin0[1] = {0};
    rbc_cloth_def cd0 = test_grid_def(&g0, pin0, 1);
    rbc_cloth_id c0;
    CHECK_EQ(rbc_cloth_create(w, &cd0, &c0), RBC_OK);
    for (int s = 0; s < 10; ++s) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g0);

    rbc_solver_def sd;
    rbc_world_def d = cuda_def(&sd);
    rbc_world_id wc = test_world(&d);
    d.backend = RBC_BACKEND_CUDA;
    rbc_world_id wg = test_world(&d);
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    CHECK_EQ(rbc_world_get_stats(wg, &st), RBC_OK);
    CHECK_EQ(st.backend, RBC_BACKEND_CUDA);

    test_grid g = test_grid_make(32, 32, 1.0f / 31.0f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 31};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id cc, cg;
    CHECK_EQ(rbc_cloth_create(wc, &cd, &cc), RBC_OK);
    CHECK_EQ(rbc_cloth_create(wg, &cd, &cg), RBC_OK);
    const uint32_t n = g.vertex_count;
    float *pc = malloc(3 * n * sizeof(float)), *pg = malloc(3 * n * sizeof(float));
    double diff = 0.0, fell = 0.0;
    for (int s = 0; s < 60; ++s) {
        CHECK_EQ(rbc_world_step(wc, 1.0f / 60.0f), RBC_OK);
        CHECK_EQ(rbc_world_step(wg, 1.0f / 60.0f), RBC_OK);
        CHECK_EQ(rbc_cloth_read_positions(wc, cc, pc, 3 * (size_t)n, NULL), RBC_OK);
        CHECK_EQ(rbc_cloth_read_positions(wg, cg, pg, 3 * (size_t)n, NULL), RBC_OK);
        for (uint32_t k = 0; k < 3 * n; ++k) diff = fmax(diff, fabs((double)pc[k] - pg[k]));
    }
    for (uint32_t v = 0; v < n; ++v) fell = fmax(fell, 1.0 - pg[3 * v + 1]);
    fprintf(stderr, "  CUDA against CPU over 1 s: largest difference %.3g m, fell %.3g m\n",
            diff, fell);
    CHECK(diff < 1e-3);
    CHECK(fell > 0.1);

    rbc_solver_def direct = test_solver_def(RBC_SOLVER_DIRECT);
    CHECK_EQ(rbc_world_set_solver(wg, &direct), RBC_ERR_UNSUPPORTED);
    CHECK(contains(rbc_last_error(), "direct solver"));
    /* A sphere 0.1 m behind the hanging cloth's centroid, in both worlds: the CUDA
     * world runs it now (backend_step.c's collider kernels). It pushes the cloth out;
     * the two worlds' lattice rows round differently (above), which contact
     * amplifies, so the comparison is the physics: contacts found, the stats count
     * them, and no particle inside the sphere (beyond its 5 mm thickness, 1 cm
     * allowed). */
    rbc_collider_def col = rbc_collider_def_default();
    col.shape = RBC_SHAPE_SPHERE;
    col.radius = 0.25f;
    double cen[3] = {0.0, 0.0, 0.0};
    for (uint32_t v = 0; v < n; ++v)
        for (int ax = 0; ax < 3; ++ax) cen[ax] += pg[3 * v + ax] / n;
    for (int ax = 0; ax < 3; ++ax) col.position[ax] = (float)cen[ax];
    col.position[2] += 0.1f;
    col.thickness = 0.005f;
    col.friction = 0.3f;
    rbc_collider_id ci, cj;
    CHECK_EQ(rbc_collider_create(wc, &col, &cj), RBC_OK);
    CHECK_EQ(rbc_collider_create(wg, &col, &ci), RBC_OK);
    uint32_t contacts = 0;
    double cdiff = 0.0, inside = 0.0;
    for (int s = 0; s < 60; ++s) {
        CHECK_EQ(rbc_world_step(wc, 1.0f / 60.0f), RBC_OK);
        CHECK_EQ(rbc_world_step(wg, 1.0f / 60.0f), RBC_OK);
        CHECK_EQ(rbc_world_get_stats(wg, &st), RBC_OK);
        if (st.collider_contacts > contacts) contacts = st.collider_contacts;
        CHECK_EQ(rbc_cloth_read_positions(wc, cc, pc, 3 * (size_t)n, NULL), RBC_OK);
        CHECK_EQ(rbc_cloth_read_positions(wg, cg, pg, 3 * (size_t)n, NULL), RBC_OK);
        for (uint32_t k = 0; k < 3 * n; ++k) cdiff = fmax(cdiff, fabs((double)pc[k] - pg[k]));
        for (uint32_t v = 0; v < n; ++v) {
            double dx = pg[3 * v] - col.position[0], dy = pg[3 * v + 1] - col.position[1],
                   dz = pg[3 * v + 2] - col.position[2];
            inside = fmax(inside, 0.25 - sqrt(dx * dx + dy * dy + dz * dz));
        }
    }
    fprintf(stderr, "  with a sphere at (%.2f, %.2f, %.2f): up to %u contacts, deepest %.3g m inside, %.3g m from "
                    "the CPU world\n", (double)col.position[0], (double)col.position[1],
            (double)col.position[2], contacts, inside, cdiff);
    CHECK(contacts > 0);
    CHECK(inside < 0.01);
    /* The same 1 mm as without it (measured 1.4e-4 m through the stand-in). */
    CHECK(cdiff < 1e-3);
    free(pc);
    free(pg);
    CHECK_EQ(rbc_world_destroy(wc), RBC_OK);
    CHECK_EQ(rbc_world_destroy(wg), RBC_OK);
    test_grid_free(&g);
}

int main(int argc, char **argv) {
    const char *mode = argc > 1 ? argv[1] : "module";
    rbc_world_def d = abi_world_def_fixed();
    d.backend = RBC_BACKEND_CUDA;
    rbc_world_id w = 0;
    rbc_result r = rbc_world_create(&d, &w);
    /* No device: unavailable. */
    const int device = r == RBC_OK;
    if (w) rbc_world_destroy(w);
    const char *req = getenv("RBC_REQUIRE_CUDA");
    if (req && !strcmp(req, "1") && !strcmp(mode, "module") && !device) {
        fprintf(stderr, "FAIL: RBC_REQUIRE_CUDA=1 and no CUDA world opens: %s\n",
                rbc_last_error());
        return 1;
    }
    if (!strcmp(mode, "standin")) {
        CHECK(device);
        if (!device) fprintf(stderr, "the stand-in did not open: %s\n", rbc_last_error());
        else with_device();
    } else if (device && !strcmp(mode, "module")) {
        fprintf(stderr, "  a CUDA device is present: checking the device path\n");
        with_device();
    } else {
        no_device(mode);
    }
    auto_is_cpu();
    return check_report("cuda_abi");
}
