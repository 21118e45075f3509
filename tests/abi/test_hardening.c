/* test_hardening.c -- issue 17's findings in the solver, through the public ABI:
 *   - a cut or torn cloth is destroyed with the sizes it was allocated with: every
 *     free a host allocator hook receives names a live block and the size asked for,
 *     and nothing is left when the world is gone (the quad array was freed with the
 *     count after cuts; with the default allocator a 130 x 130 cloth's quad array of
 *     266 KiB comes from mmap and was handed to free(): SIGSEGV);
 *   - the energy guard with a collision callback on several threads (the budget pass
 *     read the energy blocks while other threads rewrote them: TSan) gives the same
 *     bits as one thread;
 *   - the default thread count (0) switches between all threads and one from step
 *     to step (core/solver.c, threads_for_step): bitwise the same as one thread;
 *   - rbc_world_stats_init: skip_measures is an input of an output struct, and a
 *     host that only sets struct_size on a stack struct got it from garbage.
 */
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abi_util.h"

/* ------------------------------------------------------------------------- */
/* A checking allocator: every block's size by pointer.                       */
/* ------------------------------------------------------------------------- */

enum { TABLE = 1 << 16 };
static void *block_ptr[TABLE]; /* 1 MiB of table: static */
static size_t block_size[TABLE];

static void *RBC_CALL check_alloc(void *user, size_t size, size_t alignment) {
    size_t rounded = (size + alignment - 1) / alignment * alignment;
    void *p = aligned_alloc(alignment, rounded ? rounded : alignment);
    if (p) test_blocks_add(user, p, size);
    return p;
}

static void RBC_CALL check_free(void *user, void *ptr, size_t size) {
    size_t asked = size;
    if (!test_blocks_remove(user, ptr, size, &asked))
        fprintf(stderr, "  free of %p (%zu bytes): not a live block\n", ptr, size);
    else if (asked != size)
        fprintf(stderr, "  free of %p: %zu bytes given, %zu allocated\n", ptr, size, asked);
    free(ptr);
}

/* ------------------------------------------------------------------------- */
/* A cloth that is cut and one that tears                                      */
/* ------------------------------------------------------------------------- */

enum { SIDE = 130 };

/* 4 rows of 129 horizontal springs each: 516 cut, and the 4 * 129 quads on one side
 * of them go with them (each quad has one of those springs as an edge). */
static uint32_t cut_pairs(uint32_t *pairs) {
    uint32_t m = 0;
    for (uint32_t j = 60; j < 64; ++j)
        for (uint32_t i = 0; i + 1 < SIDE; ++i) {
            pairs[2 * m] = i + SIDE * j;
            pairs[2 * m + 1] = i + 1 + SIDE * j;
            m++;
        }
    return m;
}

/* Make a world (hooks or the default allocator), a cut cloth and a tearing one,
 * step, destroy the cloths one by one, then the world. Returns 0 if every call
 * succeeded. */
static int cut_tear_destroy(test_blocks *hooks, uint32_t threads, uint32_t *out_cut,
                            uint32_t *out_torn, size_t *out_quads_left) {
    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = threads;
    if (hooks) {
        wd.alloc = check_alloc;
        wd.free = check_free;
        wd.alloc_user = hooks;
    }
    rbc_world_id w = 0;
    if (rbc_world_create(&wd, &w) != RBC_OK) {
        fprintf(stderr, "  rbc_world_create: %s\n", rbc_last_error());
        return 1;
    }
    int failed = 0;
    test_grid g = test_grid_make(SIDE, SIDE, 0.01f, 0.0f, 1.0f, 0.0f);
    /* The cut cloth. */
    uint32_t pins[2] = {0, SIDE - 1};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id cut_cloth = 0, torn_cloth = 0;
    if (rbc_cloth_create(w, &cd, &cut_cloth) != RBC_OK) {
        fprintf(stderr, "  rbc_cloth_create (cut cloth): %s\n", rbc_last_error());
        failed = 1;
    }
    /* The tearing one: one pinned corner, weak springs that give under gravity. */
    test_grid g2 = test_grid_make(SIDE, SIDE, 0.01f, 0.0f, 3.0f, 0.0f);
    rbc_cloth_def td = test_grid_def(&g2, pins, 1);
    td.tear_strain = 0.05f;
    td.stiffness = 20.0f;
    if (rbc_cloth_create(w, &td, &torn_cloth) != RBC_OK) {
        fprintf(stderr, "  rbc_cloth_create (tearing cloth): %s\n", rbc_last_error());
        failed = 1;
    }
    uint32_t *pairs = malloc(sizeof(uint32_t) * 2 * 4 * SIDE);
    uint32_t m = cut_pairs(pairs);
    *out_cut = 0;
    failed |= rbc_cloth_cut(w, cut_cloth, pairs, m, out_cut) != RBC_OK;
    free(pairs);
    for (int f = 0; f < 20 && !failed; ++f) failed |= rbc_world_step(w, 1.0f / 60.0f) != RBC_OK;
    if (failed) fprintf(stderr, "  %s\n", rbc_last_error());
    rbc_world_stats st;
    rbc_world_stats_init(&st, (uint32_t)sizeof st);
    failed |= rbc_world_get_stats(w, &st) != RBC_OK;
    *out_torn = (uint32_t)(st.torn_springs - *out_cut);
    *out_quads_left = 0;
    failed |= rbc_cloth_get_quads(w, cut_cloth, NULL, 0, out_quads_left) != RBC_OK;
    failed |= rbc_cloth_destroy(w, cut_cloth) != RBC_OK;
    failed |= rbc_cloth_destroy(w, torn_cloth) != RBC_OK;
    /* And one destroyed with its world, cut, with self contact so that its
     * triangles are made (and remade after the cut) too. */
    test_grid g3 = test_grid_make(20, 20, 0.01f, 0.0f, 5.0f, 0.0f);
    rbc_cloth_def sd = test_grid_def(&g3, pins, 1);
    sd.collision_flags = RBC_CLOTH_COLLIDE_SELF;
    sd.thickness = 0.002f;
    rbc_cloth_id third = 0;
    failed |= rbc_cloth_create(w, &sd, &third) != RBC_OK;
    uint32_t one[2] = {0, 1}, c1 = 0;
    failed |= rbc_cloth_cut(w, third, one, 1, &c1) != RBC_OK || c1 != 1;
    failed |= rbc_world_step(w, 1.0f / 60.0f) != RBC_OK;
    test_grid_free(&g3);
    failed |= rbc_world_destroy(w) != RBC_OK;
    test_grid_free(&g);
    test_grid_free(&g2);
    return failed;
}

static void test_cut_and_torn_destroy(void) {
    static test_blocks hooks = TEST_BLOCKS_INIT;
    test_blocks_reset(&hooks, block_ptr, block_size, TABLE);
    for (uint32_t threads = 1; threads <= 2; ++threads) {
        uint32_t cut = 0, torn = 0;
        size_t quads_left = 0;
        size_t allocs0 = hooks.allocs;
        CHECK_EQ(cut_tear_destroy(&hooks, threads, &cut, &torn, &quads_left), 0);
        CHECK_EQ(cut, 516);
        /* 516 springs of rows 60..63 cut: the quads of rows 59..63 that have one of
         * them as an edge, 5 * 129, are gone (4 indices each). */
        CHECK_EQ(quads_left, 4 * ((size_t)(SIDE - 1) * (SIDE - 1) - 5 * (SIDE - 1)));
        CHECK(torn > 0); /* the weak cloth did tear, so its quads shrank too */
        CHECK(hooks.allocs > allocs0);
        CHECK_EQ(hooks.bad_size, 0);
        CHECK_EQ(hooks.bad_ptr, 0);
        CHECK_EQ(hooks.table_full, 0);
        CHECK_EQ(hooks.live, 0);
        printf("threads %u: %zu blocks allocated and freed with their sizes (peak %zu live), "
               "%u cut, %u torn\n",
               threads, hooks.allocs - allocs0, hooks.peak_live, cut, torn);
    }
    /* The default allocator: blocks of 256 KiB and more are mmap'd, and one freed
     * with a smaller size went to free(). */
    uint32_t cut = 0, torn = 0;
    size_t quads_left = 0;
    CHECK_EQ(cut_tear_destroy(NULL, 2, &cut, &torn, &quads_left), 0);
    CHECK_EQ(cut, 516);
}

/* A world of `wd` with one nx x nx grid cloth at height y, spacing apart, pinned
 * at `pins`; *g holds the grid (free it after the world). */
static rbc_world_id grid_world(const rbc_world_def *wd, uint32_t nx, float spacing, float y,
                               const uint32_t *pins, uint32_t pin_count, test_grid *g,
                               rbc_cloth_id *c) {
    rbc_world_id w = test_world(wd);
    *g = test_grid_make(nx, nx, spacing, 0.0f, y, 0.0f);
    rbc_cloth_def cd = test_grid_def(g, pins, pin_count);
    *c = 0;
    CHECK_EQ(rbc_cloth_create(w, &cd, c), RBC_OK);
    return w;
}

/* ------------------------------------------------------------------------- */
/* Energy guard + collision callback on threads                                */
/* ------------------------------------------------------------------------- */

/* A callback that pushes every particle below y = 0 back up: the guard counts the
 * energy it adds, in a budget pass around the callback. */
static int32_t RBC_CALL floor_callback(void *user, rbc_world_id world, float dt,
                                       const rbc_collision_cloth *cloths, uint32_t count) {
    (void)user;
    (void)world;
    (void)dt;
    for (uint32_t c = 0; c < count; ++c)
        for (uint32_t i = 0; i < cloths[c].vertex_count; ++i)
            if (cloths[c].positions[3 * i + 1] < 0.0f) cloths[c].positions[3 * i + 1] = 0.0f;
    return 0;
}

static float *guarded_run(uint32_t threads, uint32_t *n_out, uint64_t *clamped) {
    rbc_world_def wd = abi_world_def_fixed();
    rbc_solver_def sd;
    rbc_solver_def_preset(&sd, (uint32_t)sizeof sd, RBC_PRESET_PAPER);
    sd.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    wd.solver = &sd;
    wd.substeps = 4;
    wd.thread_count = threads;
    test_grid g;
    rbc_cloth_id c;
    rbc_world_id w = grid_world(&wd, 48, 0.02f, 0.3f, NULL, 0, &g, &c);
    CHECK_EQ(rbc_world_set_collision_callback(w, floor_callback, NULL), RBC_OK);
    for (int f = 0; f < 60; ++f) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    float *x = test_read(w, c, NULL);
    rbc_world_stats st;
    rbc_world_stats_init(&st, (uint32_t)sizeof st);
    CHECK_EQ(rbc_world_get_stats(w, &st), RBC_OK);
    *clamped = st.energy_clamped_steps;
    *n_out = g.vertex_count;
    rbc_world_destroy(w);
    test_grid_free(&g);
    return x;
}

static void test_guard_callback_threads(void) {
    uint32_t n1 = 0, n2 = 0;
    uint64_t k1 = 0, k2 = 0;
    float *a = guarded_run(1, &n1, &k1);
    float *b = guarded_run(2, &n2, &k2);
    CHECK(a && b && n1 == n2);
    if (a && b && n1 == n2) CHECK(memcmp(a, b, sizeof(float) * 3 * n1) == 0);
    CHECK_EQ(k1, k2);
    free(a);
    free(b);
}

/* ------------------------------------------------------------------------- */
/* The default thread count switches between steps                            */
/* ------------------------------------------------------------------------- */

/* thread_count 0 runs each step on all threads or on one, as its probes measure
 * (every 8 to 256 steps it tries the other count): that must not change a bit of
 * the result. 120 steps of a 100 x 100 cloth start on all threads and probe one
 * thread at least twice (steps 3-4 and 13-14 at the latest). */
static void test_auto_threads_bitwise(void) {
    float *x[2] = {NULL, NULL};
    uint32_t multi = 0, single = 0;
    for (int v = 0; v < 2; ++v) {
        rbc_world_def wd = rbc_world_def_default();
        wd.thread_count = v ? 0 : 1;
        const uint32_t pins[2] = {0, 99};
        test_grid g;
        rbc_cloth_id c;
        rbc_world_id w = grid_world(&wd, 100, 0.0101f, 0.0f, pins, 2, &g, &c);
        for (int f = 0; f < 120; ++f) {
            CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
            rbc_world_stats st;
            rbc_world_stats_init(&st, (uint32_t)sizeof st);
            st.skip_measures = 1;
            rbc_world_get_stats(w, &st);
            if (v) {
                multi += st.thread_count > 1;
                single += st.thread_count == 1;
            }
        }
        x[v] = test_read(w, c, NULL);
        rbc_world_destroy(w);
        test_grid_free(&g);
    }
    CHECK(x[0] && x[1]);
    if (x[0] && x[1]) CHECK(memcmp(x[0], x[1], sizeof(float) * 3 * 100 * 100) == 0);
    /* Both counts ran (on a machine of one core the pool has one thread). */
    if (multi == 0) printf("auto threads: every step on one thread (one core?)\n");
    else CHECK(single > 0);
    printf("auto threads: %u steps on several threads, %u on one, bitwise equal to 1 thread\n",
           multi, single);
    free(x[0]);
    free(x[1]);
}

/* ------------------------------------------------------------------------- */
/* rbc_world_stats_init                                                        */
/* ------------------------------------------------------------------------- */

static void test_stats_init(void) {
    rbc_world_stats st;
    memset(&st, 0xAB, sizeof st); /* what a stack struct may hold */
    CHECK_EQ(rbc_world_stats_init(&st, (uint32_t)sizeof st), RBC_OK);
    CHECK_EQ(st.struct_size, sizeof st);
    CHECK_EQ(st.skip_measures, 0);
    CHECK_EQ(st.cloth_count, 0);
    CHECK_EQ(rbc_world_stats_init(NULL, (uint32_t)sizeof st), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_world_stats_init(&st, 3), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "struct_size") != NULL);

    /* With it, a reading measures: the hanging cloth's Eq. 7 error is > 0. */
    rbc_world_def wd = abi_world_def_fixed();
    const uint32_t pins[2] = {90, 99};
    test_grid g;
    rbc_cloth_id c;
    rbc_world_id w = grid_world(&wd, 10, 0.1f, 1.0f, pins, 2, &g, &c);
    CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    memset(&st, 0xAB, sizeof st);
    rbc_world_stats_init(&st, (uint32_t)sizeof st);
    CHECK_EQ(rbc_world_get_stats(w, &st), RBC_OK);
    CHECK(st.max_strain > 0.0f);
    CHECK_EQ(st.cloth_count, 1);
    rbc_world_destroy(w);
    test_grid_free(&g);
}

int main(void) {
    test_cut_and_torn_destroy();
    test_guard_callback_threads();
    test_auto_threads_bitwise();
    test_stats_init();
    return check_report("test_hardening");
}
