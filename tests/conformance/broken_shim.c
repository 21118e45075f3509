/* broken_shim.c -- a library that keeps the rbcloth ABI but for one rule, for
 * testing that rbcloth-conformance catches each rule it claims to check.
 *
 * Built once per rule with -DBREAK_<RULE>: the shim exports rbc_get_api, which
 * returns a copy of the real library's table with the entries the rule concerns
 * replaced by wrappers that break it; everything else is the real library's. The
 * shim links librbcloth (so its named exports stay visible through the shim's
 * handle), except BREAK_EXPORTS, which loads it at run time and so exports
 * rbc_get_api alone. RBC_REAL_LIBRARY is the real library's path.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "rbcloth.h"

static rbc_api_v1 real, table;

/* --- the rules ------------------------------------------------------------ */

#if defined(BREAK_UNKNOWN_SIZE)
/* A struct size no minor had is taken. */
static rbc_result world_def_init(rbc_world_def *d, uint32_t size) {
    if (size == 4 && d) {
        d->struct_size = 4;
        return RBC_OK;
    }
    return real.world_def_init(d, size);
}
#define WRAPPED world_def_init
#endif

#if defined(BREAK_OLD_SIZE)
/* The 1.0 size of the cloth def is refused. */
static rbc_result cloth_def_init(rbc_cloth_def *d, uint32_t size) {
    if (size == RBC_CLOTH_DEF_SIZE_V1_0) return real.cloth_def_init(d, 4); /* refused, with a message */
    return real.cloth_def_init(d, size);
}
#define WRAPPED cloth_def_init
#endif

#if defined(BREAK_INIT_OVERRUN)
/* The collider def's init writes the whole current struct whatever size it is given. */
static rbc_result collider_def_init(rbc_collider_def *d, uint32_t size) {
    rbc_result r = real.collider_def_init(d, size);
    if (r == RBC_OK) {
        real.collider_def_init(d, (uint32_t)sizeof *d);
        d->struct_size = size;
    }
    return r;
}
#define WRAPPED collider_def_init
#endif

#if defined(BREAK_WRONG_CODE) || defined(BREAK_OOM_CODE)
/* A refusal with another class's code. */
static rbc_result cloth_create(rbc_world_id w, const rbc_cloth_def *d, rbc_cloth_id *out) {
    rbc_result r = real.cloth_create(w, d, out);
#if defined(BREAK_WRONG_CODE)
    if (r == RBC_ERR_BAD_MESH) return RBC_ERR_INVALID_ARGUMENT;
#else
    if (r == RBC_ERR_OUT_OF_MEMORY) return RBC_ERR_INVALID_ARGUMENT;
#endif
    return r;
}
#define WRAPPED cloth_create
#endif

#if defined(BREAK_NO_MESSAGE)
/* A refusal that leaves no message of its own. */
static rbc_result world_set_iterations(rbc_world_id w, uint32_t s, uint32_t n, uint32_t l) {
    if (n == 0) return RBC_ERR_INVALID_ARGUMENT;
    return real.world_set_iterations(w, s, n, l);
}
#define WRAPPED world_set_iterations
#endif

#if defined(BREAK_STATE_CHANGED)
/* A refused set_state applies what it can before refusing. */
static rbc_result cloth_set_state(rbc_world_id w, rbc_cloth_id c, const float *p, const float *q) {
    uint32_t nv = 0;
    if (p && real.cloth_get_vertex_count(w, c, &nv) == RBC_OK) {
        float *clean = malloc(sizeof(float) * 3 * nv);
        int bad = 0;
        for (uint32_t k = 0; clean && k < 3 * nv; k++) {
            bad |= !isfinite(p[k]);
            clean[k] = isfinite(p[k]) ? p[k] : 0.0f;
        }
        if (bad && clean) real.cloth_set_state(w, c, clean, NULL);
        free(clean);
    }
    return real.cloth_set_state(w, c, p, q);
}
#define WRAPPED cloth_set_state
#endif

#if defined(BREAK_STALE_ACCEPTED)
/* Destroying a cloth does nothing: its id stays valid. */
static rbc_result cloth_destroy(rbc_world_id w, rbc_cloth_id c) {
    uint32_t nv;
    return real.cloth_get_vertex_count(w, c, &nv);
}
#define WRAPPED cloth_destroy
#endif

#if defined(BREAK_CALLBACK_THREAD)
/* The step runs on a thread of the library's: the host's callbacks with it. */
typedef struct { rbc_world_id w; float dt; rbc_result r; } step_arg;
static void *step_thread(void *p) {
    step_arg *a = p;
    a->r = real.world_step(a->w, a->dt);
    return NULL;
}
static rbc_result world_step(rbc_world_id w, float dt) {
    step_arg a = {w, dt, RBC_OK};
    pthread_t t;
    if (pthread_create(&t, NULL, step_thread, &a) != 0) return real.world_step(w, dt);
    pthread_join(t, NULL);
    return a.r;
}
#define WRAPPED world_step
#endif

#if defined(BREAK_THREAD_COUNT)
/* More than one thread changes the result (gravity off by one float step). */
static rbc_result world_create(const rbc_world_def *d, rbc_world_id *out) {
    rbc_result r = real.world_create(d, out);
    if (r == RBC_OK && d->thread_count != 1) {
        const float g[3] = {d->gravity[0], nextafterf(d->gravity[1], 0.0f), d->gravity[2]};
        real.world_set_gravity(*out, g);
    }
    return r;
}
#define WRAPPED world_create
#endif

#if defined(BREAK_SHARED_STATE)
/* Steps of two worlds at the same time disturb each other: a step that finds
 * another in flight (waiting up to 20 ms for one) nudges its world's gravity. */
static volatile long in_flight;
static rbc_result world_step(rbc_world_id w, float dt) {
    long mine = __atomic_add_fetch(&in_flight, 1, __ATOMIC_SEQ_CST);
    int other = mine > 1;
    for (int k = 0; k < 200 && !other; k++) {
        struct timespec ts = {0, 100000L};
        nanosleep(&ts, NULL);
        other = __atomic_load_n(&in_flight, __ATOMIC_SEQ_CST) > 1;
    }
    if (other) {
        const float g[3] = {0.0f, -9.8f, 0.0f};
        real.world_set_gravity(w, g);
    }
    rbc_result r = real.world_step(w, dt);
    __atomic_sub_fetch(&in_flight, 1, __ATOMIC_SEQ_CST);
    return r;
}
#define WRAPPED world_step
#endif

#if defined(BREAK_CALLBACK_IGNORED)
/* A host callback's failure is not reported. */
static rbc_result world_step(rbc_world_id w, float dt) {
    rbc_result r = real.world_step(w, dt);
    return r == RBC_ERR_CALLBACK ? RBC_OK : r;
}
#define WRAPPED world_step
#endif

#if defined(BREAK_HANGS)
/* A step a host callback fails never returns. */
static rbc_result world_step(rbc_world_id w, float dt) {
    rbc_result r = real.world_step(w, dt);
    while (r == RBC_ERR_CALLBACK) {
        struct timespec ts = {1, 0};
        nanosleep(&ts, NULL);
    }
    return r;
}
#define WRAPPED world_step
#endif

#if defined(BREAK_PRINTS)
/* The library talks on stdout. */
static rbc_result world_create(const rbc_world_def *d, rbc_world_id *out) {
    rbc_result r = real.world_create(d, out);
    printf("rbcloth: world created (%d)\n", (int)r);
    fflush(stdout);
    return r;
}
#define WRAPPED world_create
#endif

#if defined(BREAK_VERSION)
/* The table and the function disagree on the minor. */
static uint32_t abi_version_fn(void) { return real.abi_version - 1; }
#define WRAPPED abi_version_fn
#endif

/* --- the table ------------------------------------------------------------ */

/* Each rule above replaces one entry, the one named WRAPPED, by its wrapper of
 * the same name. */
static void patch(rbc_api_v1 *t) {
#if defined(BREAK_MISSING_ENTRY)
    t->world_stats_init = NULL;
#elif defined(WRAPPED)
    t->WRAPPED = WRAPPED;
#endif
    (void)t;
}

static pthread_once_t once = PTHREAD_ONCE_INIT;
static int ready;

static void load(void) {
    /* Already loaded as this shim's dependency (or, BREAK_EXPORTS, loaded now). */
    void *h = dlopen(RBC_REAL_LIBRARY, RTLD_NOW | RTLD_LOCAL);
    if (!h) return;
    union { void *obj; rbc_get_api_fn fn; } sym;
    sym.obj = dlsym(h, "rbc_get_api");
    const rbc_api_v1 *t = sym.obj ? sym.fn(1) : NULL;
    if (!t) return;
    real = *t;
    table = real;
    patch(&table);
    ready = 1;
}

__attribute__((visibility("default"))) const void *rbc_get_api(uint32_t major) {
    pthread_once(&once, load);
    if (!ready) return NULL;
#if defined(BREAK_OTHER_MAJOR)
    return &table; /* every major gets the major-1 table */
#else
    return major == 1 ? &table : NULL;
#endif
}
