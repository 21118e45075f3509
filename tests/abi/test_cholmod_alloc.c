/* test_cholmod_alloc.c -- issue 17 item 4: with allocator hooks in the world def,
 * every allocation of the world's operations goes through them, CHOLMOD's too (the
 * direct solver, core/direct.c; SuiteSparse allocates through the process-global
 * SuiteSparse_config, which core/cholmod_alloc.c points at the world's hooks).
 *
 * This executable replaces malloc, calloc, realloc, free, aligned_alloc,
 * posix_memalign and memalign with counting wrappers over glibc's own
 * (__libc_malloc, ...; glibc's documented way to replace malloc). While a scenario
 * runs, every call of them not made by the test itself (the hook's own blocks, the
 * test's reads of positions) is a bypassing allocation and is recorded with the
 * shared object it was called from. Scenario, with a checking hook (every free names
 * a live block with the size it was allocated with): world create (2 threads), a
 * 20 x 20 cloth with the direct solver, steps at one dt (one factorisation), a pin
 * moved, steps at another dt (a second factorisation), the cloth destroyed, a second
 * cloth stepped and left to the world's destroy.
 *   - bypassing allocations: 0 (the old code: 102, all from libcholmod: 34 per
 *     factorisation), except one named in main;
 *   - every hook block freed with its size; nothing live after world destroy;
 *   - the direct solver's hook allocations exceed the same scenario's with RBGS by at
 *     least 14 per factorisation: 7 of direct.c's own, and 7 of CHOLMOD's:
 *     cholmod_allocate_sparse makes 4 blocks (the cholmod_sparse and its p, i, x;
 *     CHOLMOD's documented layout) and cholmod_analyze at least 3 (the
 *     cholmod_factor, its Perm and ColCount). The old code: exactly 7.
 * Not counted: valloc and pvalloc (obsolete; nothing here uses them) and mmap.
 *
 * Not built in the sanitizer configurations: ASan and TSan supply their own malloc,
 * which this executable's would replace (tests/abi/CMakeLists.txt).
 */
#define _GNU_SOURCE 1 /* dladdr, dl_iterate_phdr */
#include <dlfcn.h>
#include <link.h>
#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "abi_util.h"

/* ------------------------------------------------------------------------- */
/* The malloc family, counted                                                 */
/* ------------------------------------------------------------------------- */

extern void *__libc_malloc(size_t size);
extern void *__libc_calloc(size_t n, size_t size);
extern void *__libc_realloc(void *ptr, size_t size);
extern void __libc_free(void *ptr);
extern void *__libc_memalign(size_t alignment, size_t size);

enum { MAX_CALLERS = 4096 };
static atomic_int counting;              /* a scenario is running */
static atomic_long bypass;               /* allocating calls while counting */
static void *callers[MAX_CALLERS];       /* the return address of each */
static _Thread_local int test_own;       /* the test's own calls: not counted */

static void note(void *caller) {
    if (!atomic_load_explicit(&counting, memory_order_relaxed) || test_own) return;
    long k = atomic_fetch_add(&bypass, 1);
    if (k < MAX_CALLERS) callers[k] = caller;
}

/* Exported: the build hides everything by default (-fvisibility=hidden), and a
 * hidden malloc would replace only this executable's own calls. */
#define EXPORT __attribute__((visibility("default")))

EXPORT void *malloc(size_t size) {
    note(__builtin_return_address(0));
    return __libc_malloc(size);
}
EXPORT void *calloc(size_t n, size_t size) {
    note(__builtin_return_address(0));
    return __libc_calloc(n, size);
}
EXPORT void *realloc(void *ptr, size_t size) {
    note(__builtin_return_address(0));
    return __libc_realloc(ptr, size);
}
EXPORT void free(void *ptr) { __libc_free(ptr); }
EXPORT void *aligned_alloc(size_t alignment, size_t size) {
    note(__builtin_return_address(0));
    return __libc_memalign(alignment, size);
}
EXPORT void *memalign(size_t alignment, size_t size) {
    note(__builtin_return_address(0));
    return __libc_memalign(alignment, size);
}
EXPORT int posix_memalign(void **out, size_t alignment, size_t size) {
    note(__builtin_return_address(0));
    if (alignment < sizeof(void *) || (alignment & (alignment - 1)) != 0) return EINVAL;
    void *p = __libc_memalign(alignment, size);
    if (!p) return ENOMEM;
    *out = p;
    return 0;
}

/* The shared objects mapped before a scenario (dl_iterate_phdr), by file name. */
enum { MAX_OBJECTS = 128 };
static char mapped[MAX_OBJECTS][64];
static int mapped_count;

static const char *base_name(const char *path) {
    const char *b = strrchr(path, '/');
    return b ? b + 1 : path;
}

static int note_object(struct dl_phdr_info *info, size_t size, void *user) {
    (void)size, (void)user;
    if (mapped_count < MAX_OBJECTS && info->dlpi_name && info->dlpi_name[0])
        snprintf(mapped[mapped_count++], sizeof mapped[0], "%s", base_name(info->dlpi_name));
    return 0;
}

static void snapshot_objects(void) {
    test_own++;
    mapped_count = 0;
    dl_iterate_phdr(note_object, NULL);
    test_own--;
}

static int was_mapped(const char *name) {
    for (int k = 0; k < mapped_count; k++)
        if (strcmp(mapped[k], name) == 0) return 1;
    return 0;
}

typedef struct bypass_count {
    long total;
    long from_ldso;   /* the dynamic loader */
    long from_libc;   /* libc.so.6 (dlopen's own work is there since glibc 2.34) */
    long from_loaded; /* objects mapped during the scenario (their constructors) */
} bypass_count;

/* The bypassing calls of the last scenario, by the shared object they came from. */
static bypass_count report_bypass(const char *what) {
    bypass_count c = {atomic_load(&bypass), 0, 0, 0};
    printf("%s: %ld allocations bypassed the hooks\n", what, c.total);
    const char *names[32];
    long counts[32];
    int kinds = 0;
    for (long k = 0; k < c.total && k < MAX_CALLERS; k++) {
        Dl_info info;
        const char *name = "?";
        if (dladdr(callers[k], &info) && info.dli_fname) name = base_name(info.dli_fname);
        int j = 0;
        while (j < kinds && strcmp(names[j], name) != 0) j++;
        if (j == kinds && kinds < 32) {
            names[kinds] = name;
            counts[kinds++] = 0;
        }
        if (j < kinds) counts[j]++;
        if (strncmp(name, "ld-linux", 8) == 0)
            c.from_ldso++;
        else if (strcmp(name, "libc.so.6") == 0)
            c.from_libc++;
        else if (strcmp(name, "?") != 0 && !was_mapped(name))
            c.from_loaded++;
    }
    for (int j = 0; j < kinds; j++)
        printf("  %ld from %s%s\n", counts[j], names[j],
               strcmp(names[j], "?") && !was_mapped(names[j]) ? " (loaded in this scenario)" : "");
    return c;
}

/* ------------------------------------------------------------------------- */
/* The hook: every live block with its size                                   */
/* ------------------------------------------------------------------------- */

enum { TABLE = 1 << 14 };
static void *block_ptr[TABLE];
static size_t block_size[TABLE];
static test_blocks T = TEST_BLOCKS_INIT;
static size_t bad_align; /* alignments the hook contract does not allow */

static void *RBC_CALL track_alloc(void *user, size_t size, size_t alignment) {
    if (alignment == 0 || (alignment & (alignment - 1)) != 0 || alignment > 64) {
        bad_align++;
        return NULL;
    }
    size_t rounded = (size + alignment - 1) / alignment * alignment;
    test_own++;
    void *p = aligned_alloc(alignment, rounded ? rounded : alignment);
    test_own--;
    if (p) test_blocks_add(user, p, size);
    return p;
}

static void RBC_CALL track_free(void *user, void *ptr, size_t size) {
    /* Not ours, or freed twice: leave it. */
    if (ptr && test_blocks_remove(user, ptr, size, NULL)) free(ptr);
}

static void tracker_reset(void) {
    test_blocks_reset(&T, block_ptr, block_size, TABLE);
    bad_align = 0;
}

/* ------------------------------------------------------------------------- */
/* The scenario                                                               */
/* ------------------------------------------------------------------------- */

static void step_ok(rbc_world_id w, float dt, int line) {
    rbc_result r = rbc_world_step(w, dt);
    if (r != RBC_OK) {
        fprintf(stderr, "line %d: step: %s (%s)\n", line, rbc_result_string(r), rbc_last_error());
        CHECK_EQ(r, RBC_OK);
    }
}

/* A position read, made by the test (not counted). */
static void touch_positions(rbc_world_id w, rbc_cloth_id c) {
    test_own++;
    uint32_t n = 0;
    float *p = test_read(w, c, &n);
    CHECK(p != NULL && n == 400);
    free(p);
    test_own--;
}

typedef struct outcome {
    size_t hook_allocs;
    bypass_count bypass;
} outcome;

/* The scenario of the file comment with the given solver; 2 factorisations with
 * RBC_SOLVER_DIRECT. */
static outcome run_scenario(rbc_solver_kind kind, const char *what) {
    test_own++; /* the meshes and defs are the test's */
    test_grid g = test_grid_make(20, 20, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 19};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_solver_def sd;
    CHECK_EQ(rbc_solver_def_preset(&sd, (uint32_t)sizeof sd, RBC_PRESET_PAPER), RBC_OK);
    sd.solver = kind;
    rbc_world_def d = rbc_world_def_default();
    d.solver = &sd;
    d.alloc = track_alloc;
    d.free = track_free;
    d.alloc_user = &T;
    d.thread_count = 2;
    d.substeps = 1; /* h = dt: each dt its own factorisation */
    tracker_reset();
    test_own--;
    snapshot_objects();

    atomic_store(&bypass, 0);
    atomic_store(&counting, 1);
    rbc_world_id w = 0;
    rbc_cloth_id c = 0, c2 = 0;
    CHECK_EQ(rbc_world_create(&d, &w), RBC_OK);
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    for (int s = 0; s < 5; s++) step_ok(w, 1.0f / 60.0f, __LINE__);
    touch_positions(w, c);
    const float target[3] = {0.1f, 1.1f, 0.0f};
    CHECK_EQ(rbc_cloth_set_pin(w, c, 0, target), RBC_OK);
    step_ok(w, 1.0f / 60.0f, __LINE__);
    for (int s = 0; s < 3; s++) step_ok(w, 1.0f / 120.0f, __LINE__); /* new h: refactor */
    CHECK_EQ(rbc_cloth_destroy(w, c), RBC_OK);
    CHECK_EQ(rbc_cloth_create(w, &cd, &c2), RBC_OK);
    step_ok(w, 1.0f / 120.0f, __LINE__);
    touch_positions(w, c2);
    size_t hook_allocs = T.allocs;
    CHECK_EQ(rbc_world_destroy(w), RBC_OK); /* frees c2 and its factor */
    atomic_store(&counting, 0);

    outcome o = {hook_allocs, report_bypass(what)};
    const test_blocks *b = &T;
    printf("%s: %zu hook allocations (%zu bytes), %zu frees\n", what, b->allocs, b->bytes,
           b->frees);
    CHECK(b->allocs > 0);
    CHECK_EQ(b->live, 0);
    CHECK_EQ(b->allocs, b->frees);
    CHECK_EQ(b->bad_size, 0);
    CHECK_EQ(b->bad_ptr, 0);
    CHECK_EQ(bad_align, 0);
    CHECK_EQ(b->table_full, 0);
    test_own++;
    test_grid_free(&g);
    test_own--;
    return o;
}

int main(void) {
    /* The first run also sets up what lives for the process. The one bypassing
     * allocation it may make is glibc's: pthread_create of the world's first worker
     * thread callocs the thread's DTV in the dynamic loader (allocate_dtv, via
     * _dl_allocate_tls; the caller is ld-linux-x86-64.so.2). The thread's stack and
     * DTV are cached when it exits, and the later worlds' threads reuse them, so
     * the counted runs after it see none. */
    outcome first = run_scenario(RBC_SOLVER_RBGS, "first world (rbgs)");
    /* The first direct-solver world loads CHOLMOD (core/cholmod_load.c): the dynamic
     * loader, dlopen's part in libc, and the constructors of the libraries it maps
     * (libgfortran, libgomp) allocate with malloc, once per process, as any library
     * load does. Nothing else may: not the plugin, not CHOLMOD or SuiteSparse (whose
     * blocks go through SuiteSparse_config, i.e. the hooks, as the equal hook counts
     * of this run and the next direct one show), not a library mapped before. */
    outcome loading = run_scenario(RBC_SOLVER_DIRECT, "loading world (direct)");
    outcome rbgs = run_scenario(RBC_SOLVER_RBGS, "rbgs");
    outcome direct = run_scenario(RBC_SOLVER_DIRECT, "direct");
    CHECK(first.bypass.from_ldso <= 1);
    CHECK_EQ(first.bypass.total - first.bypass.from_ldso, 0);
    CHECK(loading.bypass.from_loaded > 0); /* CHOLMOD was loaded here, not before */
    CHECK_EQ(loading.bypass.total - loading.bypass.from_ldso - loading.bypass.from_libc -
                 loading.bypass.from_loaded,
             0);
    CHECK_EQ(rbgs.bypass.total, 0);
    CHECK_EQ(direct.bypass.total, 0);
    CHECK_EQ(loading.hook_allocs, direct.hook_allocs);
    CHECK_EQ(first.hook_allocs, rbgs.hook_allocs);
    /* 3 factorisations (the first cloth at dt 1/60 s and 1/120 s, the second cloth),
     * each at least 7 blocks of direct.c's own (the rbc_direct and its 6 arrays)
     * and at least 7 of CHOLMOD's (file comment); RBGS allocates nothing the direct
     * solver does not (the old code's difference was exactly 3 x 7). */
    long diff = (long)direct.hook_allocs - (long)rbgs.hook_allocs;
    printf("hook allocations: direct %zu, rbgs %zu (difference %ld, at least %d expected)\n",
           direct.hook_allocs, rbgs.hook_allocs, diff, 3 * (7 + 7));
    CHECK(diff >= 3 * (7 + 7));
    return check_report("abi_cholmod_alloc");
}
