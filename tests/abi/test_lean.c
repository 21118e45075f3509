/* test_lean.c -- issue 20 item 2: CHOLMOD is loaded on first use, and a process
 * without it keeps every other solver.
 *
 *   test_abi_lean present
 *       no libcholmod is mapped by the plugin until the first direct-solver def:
 *       an RBGS world steps with none mapped; rbc_world_set_solver(DIRECT) maps it
 *       and the world then factors and steps.
 *   test_abi_lean absent WORDS   (ctest sets $RBC_CHOLMOD_LIBRARY to a file that
 *                                 is missing, or is not CHOLMOD 3)
 *       rbc_world_create with RBC_SOLVER_DIRECT is RBC_ERR_BACKEND_UNAVAILABLE and
 *       makes no world; rbc_world_set_solver(DIRECT) on a stepping RBGS world is
 *       refused the same way with the world bitwise as it was, and its next steps
 *       equal those of a twin that was never asked; both messages name the file and
 *       contain WORDS (dlerror's, or the missing symbol); no libcholmod is mapped.
 */
#define _GNU_SOURCE 1 /* dl_iterate_phdr */
#include <link.h>

#include "abi_util.h"

static int found_cholmod(struct dl_phdr_info *info, size_t size, void *user) {
    (void)size;
    if (info->dlpi_name && strstr(info->dlpi_name, "libcholmod")) *(int *)user = 1;
    return 0;
}

static int cholmod_mapped(void) {
    int found = 0;
    dl_iterate_phdr(found_cholmod, &found);
    return found;
}

/* An RBGS world with a 12 x 12 cloth pinned at two corners, stepped 3 times. */
static rbc_world_id rbgs_world(rbc_cloth_id *c, test_grid *g) {
    rbc_world_def d = abi_world_def_fixed();
    d.thread_count = 1;
    rbc_world_id w = test_world(&d);
    const uint32_t pins[2] = {0, 11};
    rbc_cloth_def cd = test_grid_def(g, pins, 2);
    CHECK_EQ(rbc_cloth_create(w, &cd, c), RBC_OK);
    for (int s = 0; s < 3; s++) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    return w;
}

static void check_message(const char *msg, const char *file, const char *words) {
    int ok = strstr(msg, "RBC_SOLVER_DIRECT") && strstr(msg, file) && strstr(msg, words);
    CHECK(ok);
    if (!ok) fprintf(stderr, "message: %s\n(expected %s and '%s')\n", msg, file, words);
}

static void absent(const char *words) {
    const char *file = getenv("RBC_CHOLMOD_LIBRARY");
    CHECK(file && file[0]);
    if (!file || !file[0]) return;
    test_grid g = test_grid_make(12, 12, 0.05f, 0.0f, 1.0f, 0.0f);

    rbc_solver_def direct = test_solver_def(RBC_SOLVER_DIRECT);
    rbc_world_def d = rbc_world_def_default();
    d.solver = &direct;
    rbc_world_id none = 0;
    CHECK_EQ(rbc_world_create(&d, &none), RBC_ERR_BACKEND_UNAVAILABLE);
    CHECK_EQ(none, 0);
    check_message(rbc_last_error(), file, words);
    printf("rbc_world_create: %s\n", rbc_last_error());

    rbc_cloth_id c = 0, twin_c = 0;
    rbc_world_id w = rbgs_world(&c, &g), twin = rbgs_world(&twin_c, &g);
    test_snap before = test_snap_take(w, &c, 1);
    CHECK_EQ(rbc_world_set_solver(w, &direct), RBC_ERR_BACKEND_UNAVAILABLE);
    check_message(rbc_last_error(), file, words);
    printf("rbc_world_set_solver: %s\n", rbc_last_error());
    CHECK(test_snap_same(&before, __LINE__));
    test_snap_free(&before);
    CHECK(test_twins_same(w, c, twin, twin_c, 5, 1.0f / 60.0f));
    CHECK(!cholmod_mapped());
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    CHECK_EQ(rbc_world_destroy(twin), RBC_OK);
    test_grid_free(&g);
}

static void present(void) {
    test_grid g = test_grid_make(12, 12, 0.05f, 0.0f, 1.0f, 0.0f);
    rbc_cloth_id c = 0;
    rbc_world_id w = rbgs_world(&c, &g);
    CHECK(!cholmod_mapped()); /* an RBGS world needs no CHOLMOD */
    rbc_solver_def direct = test_solver_def(RBC_SOLVER_DIRECT);
    rbc_result r = rbc_world_set_solver(w, &direct);
    CHECK_EQ(r, RBC_OK);
    if (r != RBC_OK) fprintf(stderr, "rbc_world_set_solver: %s\n", rbc_last_error());
    CHECK(cholmod_mapped());
    for (int s = 0; s < 3; s++) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    uint32_t n = 0;
    float *p = test_read(w, c, &n);
    CHECK(p && n == 144 && test_all_finite(p, 3 * (size_t)n));
    free(p);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    test_grid_free(&g);
}

int main(int argc, char **argv) {
    if (argc >= 2 && strcmp(argv[1], "present") == 0)
        present();
    else if (argc >= 3 && strcmp(argv[1], "absent") == 0)
        absent(argv[2]);
    else {
        fprintf(stderr, "usage: %s present | absent WORDS\n", argv[0]);
        return 2;
    }
    return check_report("abi_lean");
}
