/* core/cholmod_alloc.c, SuiteSparse's allocations through an rbc_allocator, on its
 * own (SuiteSparse_config left at its defaults, as a host that never sets it has it):
 *   1. a block SuiteSparse got from malloc before the wrappers were installed (by
 *      loading CHOLMOD, rbc_cholmod_get) is
 *      still freed and reallocated by malloc's own functions afterwards;
 *   2. inside rbc_cholmod_enter: malloc, calloc and realloc go to the hook with the
 *      size plus the 64-byte header, 64-byte aligned; calloc is zero; realloc keeps
 *      the contents and frees the old block with its size; a refused realloc
 *      leaves the block as it was (SuiteSparse_realloc's ok = 0); a refused malloc
 *      is NULL;
 *   3. a block is freed through its own allocator from a thread with none set, and
 *      from inside another allocator's scope; scopes nest;
 *   4. with no allocator set: malloc's, 16-byte aligned, freed by free;
 *   5. cholmod_start/allocate_sparse/free_sparse/finish in a scope: every block
 *      through the hook, none left.
 * First, with the plugin's path as argument (ctest gives it): the plugin, loaded
 * with dlopen, installs its wrappers for a direct-solver world, and dlclose puts
 * SuiteSparse's defaults back (this executable keeps libsuitesparseconfig loaded,
 * as a host that uses SuiteSparse itself does), so nothing calls unmapped code.
 */
#define _GNU_SOURCE 1 /* RTLD_NOLOAD */
#include <dlfcn.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/cholmod.h>

#include "check.h"
#include "cholmod_alloc.h"
#include "cholmod_load.h"
#include "rbcloth.h"

enum { MAXB = 256 };
typedef struct hook {
    void *ptr[MAXB];
    size_t size[MAXB];
    long live, allocs, frees, bad_free, bad_size, bad_align;
    int refuse; /* the next allocation returns NULL */
} hook;

static void *hook_alloc(void *user, size_t size, size_t alignment) {
    hook *h = user;
    if (alignment != 64) h->bad_align++;
    if (h->refuse) {
        h->refuse = 0;
        return NULL;
    }
    void *p = aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
    if (!p) return NULL;
    for (int k = 0; k < MAXB; k++) {
        if (!h->ptr[k]) {
            h->ptr[k] = p;
            h->size[k] = size;
            h->live++;
            h->allocs++;
            return p;
        }
    }
    free(p);
    return NULL;
}

static void hook_free(void *user, void *ptr, size_t size) {
    hook *h = user;
    for (int k = 0; k < MAXB; k++) {
        if (h->ptr[k] == ptr) {
            if (h->size[k] != size) h->bad_size++;
            h->ptr[k] = NULL;
            h->live--;
            h->frees++;
            free(ptr);
            return;
        }
    }
    h->bad_free++;
}

static hook H1, H2;

static void *free_on_thread(void *p) {
    SuiteSparse_free(p); /* no current allocator on this thread */
    return NULL;
}

/* A direct-solver world in the plugin at `path`, then dlclose. */
static void unload_check(const char *path) {
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    CHECK(lib != NULL);
    if (!lib) {
        fprintf(stderr, "dlopen %s: %s\n", path, dlerror());
        return;
    }
#define SYM(name) __typeof__(&name) p_##name = (__typeof__(&name))dlsym(lib, #name)
    SYM(rbc_world_def_init);
    SYM(rbc_cloth_def_init);
    SYM(rbc_solver_def_preset);
    SYM(rbc_world_create);
    SYM(rbc_cloth_create);
    SYM(rbc_world_step);
    SYM(rbc_world_destroy);
#undef SYM
    CHECK(p_rbc_world_def_init && p_rbc_cloth_def_init && p_rbc_solver_def_preset &&
          p_rbc_world_create && p_rbc_cloth_create && p_rbc_world_step && p_rbc_world_destroy);
    if (!p_rbc_world_def_init || !p_rbc_cloth_def_init || !p_rbc_solver_def_preset ||
        !p_rbc_world_create || !p_rbc_cloth_create || !p_rbc_world_step || !p_rbc_world_destroy)
        return;
    /* A 4 x 4 grid of 9 quads, pinned at two corners. */
    float pos[16 * 3];
    uint32_t quads[9 * 4];
    for (uint32_t j = 0; j < 4; j++)
        for (uint32_t i = 0; i < 4; i++) {
            pos[3 * (i + 4 * j)] = 0.1f * (float)i;
            pos[3 * (i + 4 * j) + 1] = 1.0f;
            pos[3 * (i + 4 * j) + 2] = 0.1f * (float)j;
        }
    for (uint32_t j = 0; j < 3; j++)
        for (uint32_t i = 0; i < 3; i++) {
            uint32_t *q = quads + 4 * (i + 3 * j), v = i + 4 * j;
            q[0] = v;
            q[1] = v + 1;
            q[2] = v + 5;
            q[3] = v + 4;
        }
    const uint32_t pins[2] = {0, 3};
    rbc_solver_def sd;
    CHECK_EQ(p_rbc_solver_def_preset(&sd, (uint32_t)sizeof sd, RBC_PRESET_PAPER), RBC_OK);
    sd.solver = RBC_SOLVER_DIRECT;
    rbc_world_def wd;
    CHECK_EQ(p_rbc_world_def_init(&wd, (uint32_t)sizeof wd), RBC_OK);
    wd.solver = &sd;
    rbc_cloth_def cd;
    CHECK_EQ(p_rbc_cloth_def_init(&cd, (uint32_t)sizeof cd), RBC_OK);
    cd.vertex_count = 16;
    cd.positions = pos;
    cd.quad_count = 9;
    cd.quads = quads;
    cd.pin_count = 2;
    cd.pins = pins;
    rbc_world_id w = 0;
    rbc_cloth_id c = 0;
    CHECK_EQ(p_rbc_world_create(&wd, &w), RBC_OK);
    CHECK_EQ(p_rbc_cloth_create(w, &cd, &c), RBC_OK);
    CHECK_EQ(p_rbc_world_step(w, 1.0f / 60.0f), RBC_OK); /* factorises */
    CHECK(SuiteSparse_config.malloc_func != malloc);     /* the plugin's wrappers */
    CHECK_EQ(p_rbc_world_destroy(w), RBC_OK);
    CHECK_EQ(dlclose(lib), 0);
    CHECK(dlopen(path, RTLD_NOW | RTLD_NOLOAD) == NULL); /* really unloaded */
    CHECK(SuiteSparse_config.malloc_func == malloc);
    CHECK(SuiteSparse_config.calloc_func == calloc);
    CHECK(SuiteSparse_config.realloc_func == realloc);
    CHECK(SuiteSparse_config.free_func == free);
}

int main(int argc, char **argv) {
    if (argc > 1) unload_check(argv[1]);
    rbc_allocator a1 = {hook_alloc, hook_free, &H1}, a2 = {hook_alloc, hook_free, &H2};

    /* 1. Before the wrappers: plain malloc (SuiteSparse_config as shipped). */
    CHECK(SuiteSparse_config.malloc_func == malloc);
    char *early = SuiteSparse_malloc(100, 1);
    char *early2 = SuiteSparse_malloc(100, 1);
    CHECK(early && early2);
    if (!early || !early2) return check_report("core_cholmod_alloc");
    memset(early, 7, 100);

    /* Loading CHOLMOD (this executable's, linked: dlopen finds it loaded) installs. */
    CHECK(rbc_cholmod_get(NULL, 0) != NULL);
    const rbc_allocator *outer = rbc_cholmod_enter(&a1);
    CHECK(outer == NULL);
    CHECK(rbc_cholmod_hooks_installed());
    CHECK(SuiteSparse_config.malloc_func != malloc);
    SuiteSparse_free(early2); /* free()d: a crash or an error here otherwise */
    int ok = 0;
    early = SuiteSparse_realloc(1000, 100, 1, early, &ok);
    CHECK(ok && early && early[99] == 7);
    CHECK_EQ(H1.allocs, 0); /* neither went through the hook */

    /* 2. In a1's scope. */
    double *x = SuiteSparse_malloc(10, sizeof(double));
    CHECK(x && (uintptr_t)x % 64 == 0);
    CHECK_EQ(H1.allocs, 1);
    CHECK_EQ(H1.size[0], 10 * sizeof(double) + 64);
    for (int i = 0; i < 10; i++) x[i] = i;
    int *z = SuiteSparse_calloc(1000, sizeof(int));
    int zero = z != NULL;
    for (int i = 0; z && i < 1000; i++) zero = zero && z[i] == 0;
    CHECK(zero);
    x = SuiteSparse_realloc(20, 10, sizeof(double), x, &ok);
    CHECK(ok && x && (uintptr_t)x % 64 == 0);
    int kept = x != NULL;
    for (int i = 0; x && i < 10; i++) kept = kept && x[i] == i;
    CHECK(kept);
    CHECK_EQ(H1.allocs, 3);
    CHECK_EQ(H1.frees, 1); /* the old x, with its size (bad_size below) */
    H1.refuse = 1;
    double *same = SuiteSparse_realloc(40, 20, sizeof(double), x, &ok);
    CHECK(!ok && same == x && x[9] == 9);
    H1.refuse = 1;
    CHECK(SuiteSparse_malloc(5, 1) == NULL);

    /* 3. Freed with its own allocator from another thread and another scope. */
    pthread_t th;
    CHECK_EQ(pthread_create(&th, NULL, free_on_thread, z), 0);
    pthread_join(th, NULL);
    CHECK_EQ(H1.live, 1);
    const rbc_allocator *prev = rbc_cholmod_enter(&a2);
    CHECK(prev == &a1);
    void *y = SuiteSparse_malloc(3, 1);
    SuiteSparse_free(x); /* a1's block, in a2's scope */
    CHECK_EQ(H1.live, 0);
    CHECK_EQ(H2.live, 1);
    rbc_cholmod_leave(prev);
    SuiteSparse_free(y); /* a2's block, in a1's scope */
    CHECK_EQ(H2.live, 0);
    rbc_cholmod_leave(outer);

    /* 4. No allocator set: malloc's, freed by free. */
    long before = H1.allocs + H2.allocs;
    char *m = SuiteSparse_malloc(33, 1);
    CHECK(m && (uintptr_t)m % 16 == 0);
    m = SuiteSparse_realloc(66, 33, 1, m, &ok);
    CHECK(ok && m);
    SuiteSparse_free(m);
    SuiteSparse_free(early);
    CHECK_EQ(H1.allocs + H2.allocs, before);

    /* 5. CHOLMOD itself. */
    memset(&H1, 0, sizeof H1);
    outer = rbc_cholmod_enter(&a1);
    cholmod_common cm;
    cholmod_start(&cm);
    cm.print = 0;
    cholmod_sparse *A = cholmod_allocate_sparse(50, 50, 200, 1, 1, -1, CHOLMOD_REAL, &cm);
    CHECK(A != NULL);
    CHECK(H1.allocs >= 4); /* the struct, p, i, x */
    cholmod_free_sparse(&A, &cm);
    H1.refuse = 1;
    A = cholmod_allocate_sparse(50, 50, 200, 1, 1, -1, CHOLMOD_REAL, &cm);
    CHECK(A == NULL && cm.status == CHOLMOD_OUT_OF_MEMORY);
    cholmod_finish(&cm);
    rbc_cholmod_leave(outer);
    CHECK_EQ(H1.live, 0);
    CHECK_EQ(H1.allocs, H1.frees);

    CHECK_EQ(H1.bad_free + H2.bad_free, 0);
    CHECK_EQ(H1.bad_size + H2.bad_size, 0);
    CHECK_EQ(H1.bad_align + H2.bad_align, 0);
    return check_report("core_cholmod_alloc");
}
