/* rbcloth-conformance PATH/TO/LIBRARY -- check any build of the rbcloth ABI against
 * the contract written in rbcloth.h, the way a host that loads it sees it.
 *
 * The library is loaded at run time (dlopen, or LoadLibrary on Windows) and used
 * through the one symbol rbc_get_api and its function table; the named exports are
 * only looked up. The header is included for its types and its size tables alone,
 * so the program checks a library of any 1.x minor: everything it asks is what the
 * minor that library reports promises (struct sizes from rbc_struct_size_for, table
 * entries from RBC_API_V1_SIZE_*), and the entries of later minors are not called.
 *
 * Output is TAP version 13 on standard output; every check has a stable name
 * "group.what" (table, exports, sizes, defaults, errors, intact, handles, callbacks,
 * memory, threads, determinism, stdout), and failures carry "# " diagnostics. The
 * exit status is 0 when every check passed, 1 when one failed, 2 when the library
 * could not be loaded or used at all.
 *
 * While the library runs, the process's stdout and stderr descriptors point at
 * files of a private temporary folder (the report goes to a copy of the original
 * stdout): the contract says the library writes to neither, and the last checks
 * read both files. The folder also holds the caches and OBJ files the checks write;
 * it is removed at the end.
 */
#if !defined(_WIN32) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 200809L
#endif
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rbcloth.h"

#if defined(_WIN32)
#include <windows.h>
#include <io.h>
#include <process.h>
#else
#include <dlfcn.h>
#include <pthread.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>
#endif

/* ------------------------------------------------------------------------- */
/* Platform: loading, threads, flags, files                                  */
/* ------------------------------------------------------------------------- */

#if defined(_WIN32)
typedef HMODULE lib_handle;
static lib_handle lib_open(const char *path) { return LoadLibraryA(path); }
static void *lib_sym(lib_handle h, const char *name) {
    FARPROC f = GetProcAddress(h, name);
    void *p;
    memcpy(&p, &f, sizeof p);
    return p;
}
static const char *lib_error(void) {
    static char buf[64];
    snprintf(buf, sizeof buf, "Windows error %lu", (unsigned long)GetLastError());
    return buf;
}
typedef HANDLE thread_handle;
typedef unsigned long thread_ident;
static thread_ident thread_self(void) { return (thread_ident)GetCurrentThreadId(); }
typedef struct { void (*fn)(void *); void *arg; } thread_start_arg;
static unsigned __stdcall thread_tramp(void *p) {
    thread_start_arg *a = (thread_start_arg *)p;
    a->fn(a->arg);
    return 0;
}
static int thread_start(thread_handle *t, thread_start_arg *a) {
    uintptr_t h = _beginthreadex(NULL, 0, thread_tramp, a, 0, NULL);
    *t = (HANDLE)h;
    return h ? 0 : -1;
}
static void thread_join(thread_handle t) {
    WaitForSingleObject(t, INFINITE);
    CloseHandle(t);
}
typedef volatile LONG flag_t;
static void flag_set(flag_t *f, long v) { InterlockedExchange(f, v); }
static long flag_get(flag_t *f) { return InterlockedCompareExchange(f, 0, 0); }
static long flag_add(flag_t *f) { return InterlockedIncrement(f); }
static void yield_now(void) { SwitchToThread(); }
#define dup_fd _dup
#define dup2_fd _dup2
#define fileno_of _fileno
#define close_fd _close
#define fdopen_fd _fdopen
#else
typedef void *lib_handle;
static lib_handle lib_open(const char *path) { return dlopen(path, RTLD_NOW | RTLD_LOCAL); }
static void *lib_sym(lib_handle h, const char *name) { return dlsym(h, name); }
static const char *lib_error(void) {
    const char *e = dlerror();
    return e ? e : "unknown dlopen error";
}
typedef pthread_t thread_handle;
typedef pthread_t thread_ident;
static thread_ident thread_self(void) { return pthread_self(); }
typedef struct { void (*fn)(void *); void *arg; } thread_start_arg;
static void *thread_tramp(void *p) {
    thread_start_arg *a = (thread_start_arg *)p;
    a->fn(a->arg);
    return NULL;
}
static int thread_start(thread_handle *t, thread_start_arg *a) {
    return pthread_create(t, NULL, thread_tramp, a);
}
static void thread_join(thread_handle t) { pthread_join(t, NULL); }
/* A flag two threads hand over with: the GCC/Clang builtins are enough here (C11
 * <stdatomic.h> would do as well, but MSVC compiles the branch above). */
typedef volatile long flag_t;
static void flag_set(flag_t *f, long v) { __atomic_store_n(f, v, __ATOMIC_SEQ_CST); }
static long flag_get(flag_t *f) { return __atomic_load_n(f, __ATOMIC_SEQ_CST); }
static long flag_add(flag_t *f) { return __atomic_add_fetch(f, 1, __ATOMIC_SEQ_CST); }
static void yield_now(void) { sched_yield(); }
#define dup_fd dup
#define dup2_fd dup2
#define fileno_of fileno
#define close_fd close
#define fdopen_fd fdopen
#endif

static int same_thread(thread_ident a, thread_ident b) {
#if defined(_WIN32)
    return a == b;
#else
    return pthread_equal(a, b);
#endif
}

/* The private temporary folder: every file the checks write is under it. */
static char g_dir[1024];
#define MAX_TEMP_FILES 64
static char g_files[MAX_TEMP_FILES][1100];
static int g_file_count;

static int make_temp_dir(void) {
#if defined(_WIN32)
    char base[MAX_PATH];
    DWORD n = GetTempPathA(MAX_PATH, base);
    if (n == 0 || n >= MAX_PATH) return -1;
    for (int k = 0; k < 100; k++) {
        snprintf(g_dir, sizeof g_dir, "%srbcloth-conformance-%lu-%d", base,
                 (unsigned long)GetCurrentProcessId(), k);
        if (CreateDirectoryA(g_dir, NULL)) return 0;
    }
    return -1;
#else
    const char *t = getenv("TMPDIR");
    snprintf(g_dir, sizeof g_dir, "%s/rbcloth-conformance-XXXXXX", t && *t ? t : "/tmp");
    return mkdtemp(g_dir) ? 0 : -1;
#endif
}

/* A path in the folder, remembered so that the folder can be emptied. */
static const char *temp_path(const char *name) {
    if (g_file_count >= MAX_TEMP_FILES) abort();
    char *p = g_files[g_file_count++];
#if defined(_WIN32)
    snprintf(p, sizeof g_files[0], "%s\\%s", g_dir, name);
#else
    snprintf(p, sizeof g_files[0], "%s/%s", g_dir, name);
#endif
    return p;
}

static void remove_temp_dir(void) {
    for (int k = 0; k < g_file_count; k++) remove(g_files[k]);
#if defined(_WIN32)
    RemoveDirectoryA(g_dir);
#else
    rmdir(g_dir);
#endif
}

/* ------------------------------------------------------------------------- */
/* TAP                                                                       */
/* ------------------------------------------------------------------------- */

static FILE *g_tap;
static int g_count, g_failed;

static void diag(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("# ", g_tap);
    vfprintf(g_tap, fmt, ap);
    fputc('\n', g_tap);
    va_end(ap);
}

/* One check: "ok N - name: what" or "not ok N - name: what". Returns cond. */
static int check(int cond, const char *name, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    g_count++;
    if (!cond) g_failed++;
    fprintf(g_tap, "%sok %d - %s: ", cond ? "" : "not ", g_count, name);
    vfprintf(g_tap, fmt, ap);
    fputc('\n', g_tap);
    va_end(ap);
    fflush(g_tap);
    return cond;
}

static void skip(const char *name, const char *why) {
    g_count++;
    fprintf(g_tap, "ok %d - %s # SKIP %s\n", g_count, name, why);
}

/* ------------------------------------------------------------------------- */
/* The library                                                               */
/* ------------------------------------------------------------------------- */

static const rbc_api_v1 *A;   /* the table; entries past g_table_size are never called */
static uint32_t g_version;    /* what the library reports: (major << 16) | minor */
static uint32_t g_minor;
static uint32_t g_table_size; /* bytes of the table this program may read */

/* The codes' names, the kit's own: rbc_result_string is one of the functions under
 * test (its strings are checked against these), so it cannot name them here. */
static const char *code_name(rbc_result r) {
    switch (r) {
    case RBC_OK: return "RBC_OK";
    case RBC_ERR_INVALID_ARGUMENT: return "RBC_ERR_INVALID_ARGUMENT";
    case RBC_ERR_OUT_OF_MEMORY: return "RBC_ERR_OUT_OF_MEMORY";
    case RBC_ERR_UNSUPPORTED: return "RBC_ERR_UNSUPPORTED";
    case RBC_ERR_BACKEND_UNAVAILABLE: return "RBC_ERR_BACKEND_UNAVAILABLE";
    case RBC_ERR_BAD_MESH: return "RBC_ERR_BAD_MESH";
    case RBC_ERR_IO: return "RBC_ERR_IO";
    case RBC_ERR_UNSTABLE: return "RBC_ERR_UNSTABLE";
    case RBC_ERR_STALE_HANDLE: return "RBC_ERR_STALE_HANDLE";
    case RBC_ERR_CALLBACK: return "RBC_ERR_CALLBACK";
    case RBC_ERR_CAPACITY: return "RBC_ERR_CAPACITY";
    case RBC_ERR_BUSY: return "RBC_ERR_BUSY";
    default: return "(not an rbc_result)";
    }
}

/* The struct size this library takes for `kind` (its minor's largest). */
static uint32_t size_of(rbc_struct_kind kind) { return rbc_struct_size_for(kind, g_version); }

/* Table size of ABI 1.m: what a library reporting minor m must provide at least. */
static uint32_t table_size_for_minor(uint32_t m) {
    if (m >= RBC_ABI_VERSION_MINOR) return (uint32_t)sizeof(rbc_api_v1);
    if (m == 9) return RBC_API_V1_SIZE_V1_9;
    if (m >= 7) return RBC_API_V1_SIZE_V1_8;
    if (m >= 4) return RBC_API_V1_SIZE_V1_6;
    if (m == 3) return RBC_API_V1_SIZE_V1_3;
    if (m == 2) return RBC_API_V1_SIZE_V1_2;
    if (m == 1) return RBC_API_V1_SIZE_V1_1;
    return RBC_API_V1_SIZE_V1_0;
}

/* Whether the table entry at this offset may be called. */
#define HAS(field) (offsetof(rbc_api_v1, field) + sizeof(A->field) <= g_table_size)

/* The table's entries in order, with the exported name of each. */
static const char *const k_entry_names[] = {
    "rbc_abi_version", "rbc_version_string", "rbc_result_string", "rbc_last_error",
    "rbc_world_def_init", "rbc_cloth_def_init", "rbc_collider_def_init", "rbc_cache_def_init",
    "rbc_world_create", "rbc_world_destroy", "rbc_world_step", "rbc_world_set_iterations",
    "rbc_world_set_gravity", "rbc_world_get_stats", "rbc_world_set_collision_callback",
    "rbc_cloth_create", "rbc_cloth_destroy", "rbc_cloth_get_vertex_count",
    "rbc_cloth_get_topology", "rbc_cloth_read_positions", "rbc_cloth_set_pin",
    "rbc_collider_create", "rbc_collider_set_transform", "rbc_collider_destroy",
    "rbc_write_obj", "rbc_cache_create", "rbc_cache_write_frame", "rbc_cache_finish",
    "rbc_cache_destroy",
    /* 1.1 */
    "rbc_solver_def_init", "rbc_world_set_solver", "rbc_world_get_solver",
    "rbc_cloth_get_colors", "rbc_cloth_get_state", "rbc_cloth_set_state",
    /* 1.2 */
    "rbc_mesh_import_def_init", "rbc_mesh_import", "rbc_mesh_destroy", "rbc_mesh_get_info",
    "rbc_mesh_get_positions", "rbc_mesh_get_quads", "rbc_mesh_get_springs",
    "rbc_mesh_get_pins", "rbc_cloth_create_from_mesh",
    /* 1.3 */
    "rbc_world_set_contact_callback", "rbc_world_pick", "rbc_cloth_attach", "rbc_cloth_cut",
    "rbc_cloth_get_quads", "rbc_cloth_get_springs", "rbc_world_set_wind",
    "rbc_mesh_get_triangles",
    /* 1.4 */
    "rbc_solver_def_preset",
    /* 1.7 */
    "rbc_world_stats_init",
    /* 1.9 */
    "rbc_mesh_get_file_map", "rbc_mesh_to_file_positions", "rbc_mesh_write_file_obj",
    /* 1.10 */
    "rbc_vertex_output_init", "rbc_world_read_vertices", "rbc_cloth_get_triangles",
    "rbc_cloth_transform", "rbc_world_step_begin", "rbc_world_step_wait",
};
#define ENTRY_COUNT (sizeof k_entry_names / sizeof k_entry_names[0])
#define FIRST_ENTRY offsetof(rbc_api_v1, abi_version_fn)

/* The message of the calling thread's last error, copied. */
static char g_msg[1024];
static const char *msg_now(void) {
    const char *m = A->last_error();
    snprintf(g_msg, sizeof g_msg, "%s", m ? m : "(NULL)");
    return g_msg;
}

/* Leave a known message behind, so that a check can tell that the next refusal
 * wrote its own. */
static char g_poison[1024];
static void poison_message(void) {
    /* A call no check makes: set_gravity on a world id never made. */
    A->world_set_gravity(0xFFFFFFFFu, NULL);
    snprintf(g_poison, sizeof g_poison, "%s", A->last_error() ? A->last_error() : "");
}

/* A refusal: the code expected, and a message of its own (not empty, not the one
 * the previous refusal left). Call poison_message() before the refused call. */
static int refused(rbc_result got, rbc_result want, const char *name, const char *what) {
    const char *m = msg_now();
    int fresh = m[0] != '\0' && strcmp(m, g_poison) != 0;
    int ok = check(got == want && fresh, name, "%s -> %s", what, code_name(want));
    if (got != want) diag("  returned %s (%d)", code_name(got), (int)got);
    if (!fresh) diag("  no message of its own: rbc_last_error() is \"%s\"", m);
    else if (!ok) diag("  message: %s", m);
    return ok;
}

/* ------------------------------------------------------------------------- */
/* Scenes                                                                    */
/* ------------------------------------------------------------------------- */

/* An n x n grid of 0.1 m squares, horizontal at height y0, pinned at two corners. */
typedef struct grid {
    uint32_t n, nv, nq;
    float *pos;
    uint32_t *quads;
    uint32_t pins[2];
} grid;

static int grid_make(grid *g, uint32_t n, float y0) {
    g->n = n;
    g->nv = n * n;
    g->nq = (n - 1) * (n - 1);
    g->pos = malloc(sizeof(float) * 3 * g->nv);
    g->quads = malloc(sizeof(uint32_t) * 4 * g->nq);
    if (!g->pos || !g->quads) return -1;
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            uint32_t v = i + n * j;
            g->pos[3 * v + 0] = 0.1f * (float)i;
            g->pos[3 * v + 1] = y0;
            g->pos[3 * v + 2] = 0.1f * (float)j;
        }
    for (uint32_t j = 0; j + 1 < n; j++)
        for (uint32_t i = 0; i + 1 < n; i++) {
            uint32_t q = i + (n - 1) * j;
            g->quads[4 * q + 0] = i + n * j;
            g->quads[4 * q + 1] = i + 1 + n * j;
            g->quads[4 * q + 2] = i + 1 + n * (j + 1);
            g->quads[4 * q + 3] = i + n * (j + 1);
        }
    g->pins[0] = 0;
    g->pins[1] = n - 1;
    return 0;
}

static void grid_free(grid *g) {
    free(g->pos);
    free(g->quads);
}

static void world_def_for(rbc_world_def *d, uint32_t threads) {
    memset(d, 0, sizeof *d);
    A->world_def_init(d, size_of(RBC_STRUCT_WORLD_DEF));
    d->thread_count = threads;
}

static void cloth_def_for(rbc_cloth_def *d, const grid *g) {
    memset(d, 0, sizeof *d);
    A->cloth_def_init(d, size_of(RBC_STRUCT_CLOTH_DEF));
    d->vertex_count = g->nv;
    d->positions = g->pos;
    d->quad_count = g->nq;
    d->quads = g->quads;
    d->pin_count = 2;
    d->pins = g->pins;
}

/* A world with one grid cloth and a sphere under it. */
typedef struct scene {
    rbc_world_id w;
    rbc_cloth_id c;
    rbc_collider_id k;
    uint32_t nv;
} scene;

static rbc_result scene_make(scene *s, const grid *g, uint32_t threads, float sphere_x) {
    memset(s, 0, sizeof *s);
    rbc_world_def wd;
    world_def_for(&wd, threads);
    rbc_result r = A->world_create(&wd, &s->w);
    if (r) return r;
    rbc_cloth_def cd;
    cloth_def_for(&cd, g);
    if ((r = A->cloth_create(s->w, &cd, &s->c))) return r;
    rbc_collider_def kd;
    memset(&kd, 0, sizeof kd);
    A->collider_def_init(&kd, size_of(RBC_STRUCT_COLLIDER_DEF));
    kd.shape = RBC_SHAPE_SPHERE;
    kd.radius = 0.1f * (float)g->n / 4.0f;
    kd.position[0] = sphere_x;
    kd.position[1] = g->pos[1] - 0.1f * (float)g->n / 2.0f;
    kd.position[2] = 0.05f * (float)g->n;
    if ((r = A->collider_create(s->w, &kd, &s->k))) return r;
    s->nv = g->nv;
    return RBC_OK;
}

/* Positions of the scene's cloth after `steps` steps of dt into out (3 nv floats). */
static rbc_result scene_run(const scene *s, int steps, float dt, float *out) {
    for (int k = 0; k < steps; k++) {
        rbc_result r = A->world_step(s->w, dt);
        if (r) return r;
    }
    size_t written = 0;
    return A->cloth_read_positions(s->w, s->c, out, 3 * (size_t)s->nv, &written);
}

/* Everything of a world a host can read, as bytes: positions (and previous
 * positions from 1.1), topology, quads and springs (1.3), solver settings (1.1),
 * and the stats' counts. Two snapshots are equal when nothing observable changed. */
typedef struct snapshot {
    unsigned char *b;
    size_t n, cap;
} snapshot;

static void snap_put(snapshot *s, const void *p, size_t n) {
    if (s->n + n > s->cap) {
        size_t cap = s->cap ? s->cap * 2 : 4096;
        while (cap < s->n + n) cap *= 2;
        unsigned char *nb = realloc(s->b, cap);
        if (!nb) abort();
        s->b = nb;
        s->cap = cap;
    }
    memcpy(s->b + s->n, p, n);
    s->n += n;
}

static int snap_equal(const snapshot *x, const snapshot *y) {
    return x->n == y->n && memcmp(x->b, y->b, x->n) == 0;
}

static void snap_world(snapshot *s, rbc_world_id w, const rbc_cloth_id *cloths, int ncloths) {
    s->n = 0;
    for (int i = 0; i < ncloths; i++) {
        uint32_t nv = 0, ns = 0, nc = 0;
        rbc_result r = A->cloth_get_vertex_count(w, cloths[i], &nv);
        snap_put(s, &r, sizeof r);
        r = A->cloth_get_topology(w, cloths[i], &ns, &nc);
        snap_put(s, &r, sizeof r);
        snap_put(s, &nv, sizeof nv);
        snap_put(s, &ns, sizeof ns);
        snap_put(s, &nc, sizeof nc);
        size_t cap = 3 * (size_t)nv;
        float *p = calloc(cap + 1, sizeof(float)), *q = calloc(cap + 1, sizeof(float));
        if (!p || !q) abort();
        if (HAS(cloth_get_state)) {
            r = A->cloth_get_state(w, cloths[i], p, q, cap);
        } else {
            size_t written = 0;
            r = A->cloth_read_positions(w, cloths[i], p, cap, &written);
        }
        snap_put(s, &r, sizeof r);
        snap_put(s, p, cap * sizeof(float));
        snap_put(s, q, cap * sizeof(float));
        free(p);
        free(q);
        if (HAS(cloth_get_quads)) {
            size_t nq = 0, nsp = 0;
            A->cloth_get_quads(w, cloths[i], NULL, 0, &nq);
            A->cloth_get_springs(w, cloths[i], NULL, 0, &nsp);
            snap_put(s, &nq, sizeof nq);
            snap_put(s, &nsp, sizeof nsp);
        }
    }
    if (HAS(world_get_solver)) {
        rbc_solver_def sd;
        memset(&sd, 0, sizeof sd);
        sd.struct_size = size_of(RBC_STRUCT_SOLVER_DEF);
        rbc_result r = A->world_get_solver(w, &sd);
        snap_put(s, &r, sizeof r);
        snap_put(s, &sd, sizeof sd);
    }
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = size_of(RBC_STRUCT_WORLD_STATS);
    if (st.struct_size > offsetof(rbc_world_stats, skip_measures)) st.skip_measures = 1;
    rbc_result r = A->world_get_stats(w, &st);
    snap_put(s, &r, sizeof r);
    snap_put(s, &st.cloth_count, sizeof st.cloth_count);
    snap_put(s, &st.collider_count, sizeof st.collider_count);
    snap_put(s, &st.particle_count, sizeof st.particle_count);
    snap_put(s, &st.spring_count, sizeof st.spring_count);
    snap_put(s, &st.step_count, sizeof st.step_count);
}

/* ------------------------------------------------------------------------- */
/* table, exports                                                            */
/* ------------------------------------------------------------------------- */

static int check_table(lib_handle lib, rbc_get_api_fn get_api) {
    const rbc_api_v1 *t = (const rbc_api_v1 *)get_api(1);
    if (!check(t != NULL, "table.get_api", "rbc_get_api(1) returns the major-1 table"))
        return -1;
    check(get_api(0) == NULL, "table.other_major", "rbc_get_api(0) is NULL");
    check(get_api(2) == NULL, "table.other_major", "rbc_get_api(2) is NULL");
    check(get_api(0xFFFFFFFFu) == NULL, "table.other_major", "rbc_get_api(0xFFFFFFFF) is NULL");
    check(get_api(1) == (const void *)t, "table.static", "rbc_get_api(1) returns the same table");
    g_version = t->abi_version;
    g_minor = g_version & 0xFFFFu;
    diag("library: ABI %u.%u, table of %u bytes (this kit's header: ABI %u.%u, %u bytes)",
         (unsigned)(g_version >> 16), (unsigned)g_minor, (unsigned)t->struct_size,
         (unsigned)RBC_ABI_VERSION_MAJOR, (unsigned)RBC_ABI_VERSION_MINOR,
         (unsigned)sizeof(rbc_api_v1));
    if (!check(g_version >> 16 == 1, "table.major", "abi_version has major 1 (got 0x%08x)",
               (unsigned)g_version))
        return -1;
    const uint32_t need = table_size_for_minor(g_minor);
    if (!check(t->struct_size >= need, "table.size",
               "struct_size %u covers the entries of ABI 1.%u (%u bytes)",
               (unsigned)t->struct_size, (unsigned)g_minor, (unsigned)need))
        return -1;
    g_table_size = t->struct_size < sizeof(rbc_api_v1) ? t->struct_size : (uint32_t)sizeof(rbc_api_v1);
    /* Entries of the minors it reports are all there. */
    int missing = 0, names_missing = 0;
    const size_t n = (g_table_size - FIRST_ENTRY) / sizeof(void (*)(void));
    for (size_t k = 0; k < n && k < ENTRY_COUNT; k++) {
        void (*fp)(void);
        memcpy(&fp, (const char *)t + FIRST_ENTRY + k * sizeof fp, sizeof fp);
        if (!fp) {
            missing++;
            diag("  table entry %zu (%s) is NULL", k, k_entry_names[k]);
        }
        if (!lib_sym(lib, k_entry_names[k])) {
            names_missing++;
            diag("  %s is not exported", k_entry_names[k]);
        }
    }
    check(missing == 0, "table.entries", "the %zu entries of ABI 1.%u are non-NULL", n,
          (unsigned)g_minor);
    check(names_missing == 0, "exports.names",
          "the %zu functions of ABI 1.%u are exported by name too", n, (unsigned)g_minor);
    if (missing) return -1;
    A = t;
    check(A->abi_version_fn() == g_version, "table.version",
          "abi_version_fn() = 0x%08x, as the table says", (unsigned)A->abi_version_fn());
    const char *v = A->version_string();
    check(v && v[0], "table.version_string", "version_string() = \"%s\"", v ? v : "(NULL)");
    diag("library release: %s", v ? v : "(NULL)");
    static const rbc_result codes[] = {RBC_OK, RBC_ERR_INVALID_ARGUMENT, RBC_ERR_OUT_OF_MEMORY,
                                       RBC_ERR_UNSUPPORTED, RBC_ERR_BACKEND_UNAVAILABLE,
                                       RBC_ERR_BAD_MESH, RBC_ERR_IO, RBC_ERR_UNSTABLE,
                                       RBC_ERR_STALE_HANDLE, RBC_ERR_CALLBACK, RBC_ERR_CAPACITY};
    int names_ok = 1;
    for (size_t k = 0; k < sizeof codes / sizeof codes[0]; k++) {
        const char *s = A->result_string(codes[k]);
        if (!s || strcmp(s, code_name(codes[k])) != 0) {
            names_ok = 0;
            diag("  result_string(%d) = \"%s\"", (int)codes[k], s ? s : "(NULL)");
        }
    }
    /* 1.10 added RBC_ERR_BUSY; an older library may call it unknown. */
    if ((g_version & 0xFFFFu) >= 10) {
        const char *s = A->result_string(RBC_ERR_BUSY);
        if (!s || strcmp(s, "RBC_ERR_BUSY") != 0) {
            names_ok = 0;
            diag("  result_string(%d) = \"%s\"", (int)RBC_ERR_BUSY, s ? s : "(NULL)");
        }
    }
    check(names_ok, "table.result_string", "result_string names every rbc_result");
    const char *u = A->result_string(-1000);
    check(u && strcmp(u, "unknown result") == 0, "table.result_string",
          "result_string(-1000) = \"unknown result\"");
    check(A->last_error() != NULL, "table.last_error", "last_error() is never NULL");
    return 0;
}

/* ------------------------------------------------------------------------- */
/* sizes                                                                     */
/* ------------------------------------------------------------------------- */

typedef rbc_result (*init_fn)(void *def, uint32_t size);

/* The init entries behind one signature (calling them through a cast pointer of
 * another type would be undefined). */
static rbc_result init_world(void *d, uint32_t s) { return A->world_def_init(d, s); }
static rbc_result init_cloth(void *d, uint32_t s) { return A->cloth_def_init(d, s); }
static rbc_result init_collider(void *d, uint32_t s) { return A->collider_def_init(d, s); }
static rbc_result init_cache(void *d, uint32_t s) { return A->cache_def_init(d, s); }
static rbc_result init_solver(void *d, uint32_t s) { return A->solver_def_init(d, s); }
static rbc_result init_import(void *d, uint32_t s) { return A->mesh_import_def_init(d, s); }

/* The sizes of `kind` released up to the library's minor, ascending, unique. */
static int released_sizes(rbc_struct_kind kind, uint32_t *out) {
    int n = 0;
    const uint32_t top = g_minor < RBC_ABI_VERSION_MINOR ? g_minor : RBC_ABI_VERSION_MINOR;
    for (uint32_t m = 0; m <= top; m++) {
        uint32_t s = rbc_struct_size_for(kind, (1u << 16) | m);
        if (s && (n == 0 || out[n - 1] != s)) out[n++] = s;
    }
    return n;
}

static int is_released(uint32_t s, const uint32_t *sizes, int n) {
    for (int k = 0; k < n; k++)
        if (sizes[k] == s) return 1;
    return 0;
}

/* An init entry: every released size accepted, exactly that many bytes written and
 * struct_size set; sizes that no minor released refused, the def untouched. */
static void check_init(const char *what, rbc_struct_kind kind, init_fn fn, size_t full) {
    uint32_t sizes[16];
    const int n = released_sizes(kind, sizes);
    enum { CAP = 2048 };
    static unsigned char buf[CAP];
    if (full + 64 > CAP) abort();
    char name[96];
    snprintf(name, sizeof name, "sizes.%s", what);
    for (int k = 0; k < n; k++) {
        memset(buf, 0xCD, sizeof buf);
        rbc_result r = fn(buf, sizes[k]);
        uint32_t got;
        memcpy(&got, buf, sizeof got);
        int overrun = 0;
        for (size_t b = sizes[k]; b < full + 64; b++) overrun |= buf[b] != 0xCD;
        check(r == RBC_OK && got == sizes[k] && !overrun, name,
              "%s(def, %u) accepts the size, sets struct_size and writes %u bytes only", what,
              (unsigned)sizes[k], (unsigned)sizes[k]);
        if (r) diag("  returned %s: %s", code_name(r), msg_now());
        if (overrun) diag("  bytes past struct_size were written");
    }
    /* Sizes no minor had: 0, 4, and one word either side of each released size (the
     * larger ones only where this header is as new as the library). */
    uint32_t bad[40];
    int nb = 0;
    bad[nb++] = 0;
    bad[nb++] = 4;
    for (int k = 0; k < n; k++) {
        bad[nb++] = sizes[k] - 4;
        if (g_minor <= RBC_ABI_VERSION_MINOR) bad[nb++] = sizes[k] + 4;
    }
    if (g_minor <= RBC_ABI_VERSION_MINOR) bad[nb++] = 0x10000u;
    /* An older library refuses this header's size where its minor had another. */
    bad[nb++] = (uint32_t)full;
    for (int k = 0; k < nb; k++) {
        if (is_released(bad[k], sizes, n) || is_released(bad[k], bad, k)) continue;
        memset(buf, 0xCD, sizeof buf);
        poison_message();
        rbc_result r = fn(buf, bad[k]);
        int untouched = 1;
        for (size_t b = 0; b < full + 64; b++) untouched &= buf[b] == 0xCD;
        char call[128];
        snprintf(call, sizeof call, "%s(def, %u)", what, (unsigned)bad[k]);
        refused(r, RBC_ERR_INVALID_ARGUMENT, name, call);
        check(untouched, name, "%s leaves the def untouched", call);
    }
    poison_message();
    char call[128];
    snprintf(call, sizeof call, "%s(NULL, %u)", what, (unsigned)(n ? sizes[n - 1] : 0));
    refused(fn(NULL, n ? sizes[n - 1] : 0), RBC_ERR_INVALID_ARGUMENT, name, call);
}

/* What takes each struct takes every released size too (and refuses others). */
static void check_sizes_in_use(const grid *g) {
    uint32_t sizes[16];
    int n = released_sizes(RBC_STRUCT_WORLD_DEF, sizes);
    for (int k = 0; k < n; k++) {
        rbc_world_def d;
        memset(&d, 0, sizeof d);
        A->world_def_init(&d, sizes[k]);
        d.thread_count = 1;
        rbc_world_id w = 0;
        rbc_result r = A->world_create(&d, &w);
        check(r == RBC_OK && w != 0, "sizes.world_create", "a world def of %u bytes makes a world",
              (unsigned)sizes[k]);
        if (r) diag("  %s: %s", code_name(r), msg_now());
        rbc_cloth_def cd;
        uint32_t cs[16];
        int nc = released_sizes(RBC_STRUCT_CLOTH_DEF, cs);
        for (int j = 0; j < nc && r == RBC_OK && k == n - 1; j++) {
            memset(&cd, 0, sizeof cd);
            A->cloth_def_init(&cd, cs[j]);
            cd.vertex_count = g->nv;
            cd.positions = g->pos;
            cd.quad_count = g->nq;
            cd.quads = g->quads;
            rbc_cloth_id c = 0;
            rbc_result rc = A->cloth_create(w, &cd, &c);
            check(rc == RBC_OK && c != 0, "sizes.cloth_create",
                  "a cloth def of %u bytes makes a cloth", (unsigned)cs[j]);
            if (rc) diag("  %s: %s", code_name(rc), msg_now());
        }
        uint32_t ks[16];
        int nk = released_sizes(RBC_STRUCT_COLLIDER_DEF, ks);
        for (int j = 0; j < nk && r == RBC_OK && k == n - 1; j++) {
            rbc_collider_def kd;
            memset(&kd, 0, sizeof kd);
            A->collider_def_init(&kd, ks[j]);
            rbc_collider_id c = 0;
            rbc_result rc = A->collider_create(w, &kd, &c);
            check(rc == RBC_OK && c != 0, "sizes.collider_create",
                  "a collider def of %u bytes makes a collider", (unsigned)ks[j]);
        }
        uint32_t ss[16];
        int ns = released_sizes(RBC_STRUCT_WORLD_STATS, ss);
        for (int j = 0; j < ns && r == RBC_OK && k == n - 1; j++) {
            union { rbc_world_stats s; unsigned char b[sizeof(rbc_world_stats) + 32]; } u;
            memset(&u, 0, sizeof u);
            memset(u.b + ss[j], 0xCD, sizeof u - ss[j]);
            u.s.struct_size = ss[j];
            rbc_result rs = A->world_get_stats(w, &u.s);
            int overrun = 0;
            for (size_t b = ss[j]; b < sizeof u; b++) overrun |= u.b[b] != 0xCD;
            check(rs == RBC_OK && !overrun, "sizes.world_get_stats",
                  "stats of %u bytes are filled, nothing past them", (unsigned)ss[j]);
        }
        if (r == RBC_OK && k == n - 1) {
            rbc_world_stats st;
            memset(&st, 0, sizeof st);
            st.struct_size = ss[0] - 4;
            poison_message();
            refused(A->world_get_stats(w, &st), RBC_ERR_INVALID_ARGUMENT, "sizes.world_get_stats",
                    "stats of a size no minor had");
        }
        if (HAS(world_set_solver) && r == RBC_OK && k == n - 1) {
            uint32_t vs[16];
            int nv = released_sizes(RBC_STRUCT_SOLVER_DEF, vs);
            for (int j = 0; j < nv; j++) {
                rbc_solver_def sd;
                memset(&sd, 0, sizeof sd);
                A->solver_def_init(&sd, vs[j]);
                rbc_result rs = A->world_set_solver(w, &sd);
                check(rs == RBC_OK, "sizes.world_set_solver", "a solver def of %u bytes is taken",
                      (unsigned)vs[j]);
            }
        }
        if (r == RBC_OK) A->world_destroy(w);
    }
    /* A world def of a size no minor had. */
    rbc_world_def d;
    world_def_for(&d, 1);
    d.struct_size = sizes[0] - 4;
    rbc_world_id w = 0;
    poison_message();
    refused(A->world_create(&d, &w), RBC_ERR_INVALID_ARGUMENT, "sizes.world_create",
            "world_create with a def of a size no minor had");
    check(w == 0, "sizes.world_create", "and *out_world is not a world");
    /* Caches of every size (a file each). */
    uint32_t hs[16];
    int nh = released_sizes(RBC_STRUCT_CACHE_DEF, hs);
    for (int j = 0; j < nh; j++) {
        char fname[64];
        snprintf(fname, sizeof fname, "size%u.pc2", (unsigned)hs[j]);
        const char *path = temp_path(fname);
        rbc_cache_def hd;
        memset(&hd, 0, sizeof hd);
        A->cache_def_init(&hd, hs[j]);
        hd.path = path;
        hd.point_count = g->nv;
        rbc_cache_id h = 0;
        rbc_result r = A->cache_create(&hd, &h);
        if (r == RBC_OK) r = A->cache_write_frame(h, g->pos);
        if (r == RBC_OK) r = A->cache_finish(h);
        FILE *f = fopen(path, "rb");
        long len = -1;
        if (f) {
            fseek(f, 0, SEEK_END);
            len = ftell(f);
            fclose(f);
        }
        /* PC2: a 32-byte header and one frame of floats. */
        check(r == RBC_OK && len == 32 + 12 * (long)g->nv, "sizes.cache_create",
              "a cache def of %u bytes writes a PC2 of one frame (%ld bytes)", (unsigned)hs[j], len);
        if (r) diag("  %s: %s", code_name(r), msg_now());
    }
}

static void check_sizes(const grid *g) {
    check_init("rbc_world_def_init", RBC_STRUCT_WORLD_DEF, init_world,
               sizeof(rbc_world_def));
    check_init("rbc_cloth_def_init", RBC_STRUCT_CLOTH_DEF, init_cloth,
               sizeof(rbc_cloth_def));
    check_init("rbc_collider_def_init", RBC_STRUCT_COLLIDER_DEF, init_collider,
               sizeof(rbc_collider_def));
    check_init("rbc_cache_def_init", RBC_STRUCT_CACHE_DEF, init_cache,
               sizeof(rbc_cache_def));
    if (HAS(solver_def_init))
        check_init("rbc_solver_def_init", RBC_STRUCT_SOLVER_DEF, init_solver,
                   sizeof(rbc_solver_def));
    if (HAS(mesh_import_def_init))
        check_init("rbc_mesh_import_def_init", RBC_STRUCT_MESH_IMPORT_DEF, init_import, sizeof(rbc_mesh_import_def));
    if (HAS(world_stats_init)) {
        /* stats_init zeroes: a released size is filled with zeros and its size. */
        uint32_t ss[16];
        int n = released_sizes(RBC_STRUCT_WORLD_STATS, ss);
        for (int k = 0; k < n; k++) {
            union { rbc_world_stats s; unsigned char b[sizeof(rbc_world_stats) + 32]; } u;
            memset(&u, 0xCD, sizeof u);
            rbc_result r = A->world_stats_init(&u.s, ss[k]);
            int zero = 1, overrun = 0;
            for (size_t b = 4; b < ss[k]; b++) zero &= u.b[b] == 0;
            for (size_t b = ss[k]; b < sizeof u; b++) overrun |= u.b[b] != 0xCD;
            check(r == RBC_OK && u.s.struct_size == ss[k] && zero && !overrun,
                  "sizes.rbc_world_stats_init", "stats_init(st, %u) zeroes %u bytes and sets the size",
                  (unsigned)ss[k], (unsigned)ss[k]);
        }
        union { rbc_world_stats s; unsigned char b[sizeof(rbc_world_stats)]; } u;
        poison_message();
        refused(A->world_stats_init(&u.s, 4), RBC_ERR_INVALID_ARGUMENT,
                "sizes.rbc_world_stats_init", "stats_init(st, 4)");
    }
    check_sizes_in_use(g);
}

/* ------------------------------------------------------------------------- */
/* defaults                                                                  */
/* ------------------------------------------------------------------------- */

static void check_defaults(void) {
    rbc_world_def wd;
    rbc_cloth_def cd;
    rbc_collider_def kd;
    rbc_cache_def hd;
    memset(&wd, 0, sizeof wd);
    memset(&cd, 0, sizeof cd);
    memset(&kd, 0, sizeof kd);
    memset(&hd, 0, sizeof hd);
    A->world_def_init(&wd, size_of(RBC_STRUCT_WORLD_DEF));
    A->cloth_def_init(&cd, size_of(RBC_STRUCT_CLOTH_DEF));
    A->collider_def_init(&kd, size_of(RBC_STRUCT_COLLIDER_DEF));
    A->cache_def_init(&hd, size_of(RBC_STRUCT_CACHE_DEF));
    /* The defaults every minor documents alike. */
    check(wd.gravity[0] == 0.0f && wd.gravity[1] == -9.81f && wd.gravity[2] == 0.0f &&
              wd.nonlinear_iterations == 1 && wd.linear_iterations == 11 &&
              wd.backend == RBC_BACKEND_AUTO && wd.thread_count == 0 &&
              wd.log_level == RBC_LOG_WARNING && !wd.alloc && !wd.free && !wd.log,
          "defaults.world", "world def: gravity (0, -9.81, 0), 1 x 11 iterations, AUTO, no hooks");
    check(cd.stiffness == 1000.0f && cd.vertex_mass == 1e-4f && cd.damping == 0.0f &&
              cd.density == 0.0f && cd.vertex_count == 0 && !cd.positions,
          "defaults.cloth", "cloth def: stiffness 1000, vertex mass 1e-4, no damping, no mesh");
    check(kd.shape == RBC_SHAPE_PLANE && kd.radius == 0.5f && kd.thickness == 0.0f &&
              kd.rotation[0] == 0.0f && kd.rotation[3] == 1.0f,
          "defaults.collider", "collider def: plane, radius 0.5, identity rotation");
    check(hd.format == RBC_CACHE_PC2 && hd.sample_rate == 1.0f && hd.start_frame == 0.0f,
          "defaults.cache", "cache def: PC2, sample rate 1, start frame 0");
}

/* ------------------------------------------------------------------------- */
/* errors + intact: every refusal on a live world, compared with its twin    */
/* ------------------------------------------------------------------------- */

static void check_errors_intact(const grid *g) {
    scene a, b;
    rbc_result ra = scene_make(&a, g, 1, 0.3f), rb = scene_make(&b, g, 1, 0.3f);
    if (!check(ra == RBC_OK && rb == RBC_OK, "errors.setup", "two identical worlds")) {
        diag("  %s / %s: %s", code_name(ra), code_name(rb), msg_now());
        return;
    }
    for (int k = 0; k < 5; k++) {
        A->world_step(a.w, 1.0f / 60.0f);
        A->world_step(b.w, 1.0f / 60.0f);
    }
    snapshot before = {0}, after = {0};
    const rbc_cloth_id cl[1] = {a.c};
    const float nanf_ = nanf(""), inf = INFINITY;
    char what[160];

/* One refused call on world a: its code, its message, and a equal to before. */
#define REFUSE(want, group, call, ...)                                                   \
    do {                                                                                 \
        snap_world(&before, a.w, cl, 1);                                                 \
        snprintf(what, sizeof what, __VA_ARGS__);                                        \
        poison_message();                                                                \
        rbc_result got_ = (call);                                                        \
        refused(got_, want, group, what);                                                \
        snap_world(&after, a.w, cl, 1);                                                  \
        int same_ = snap_equal(&before, &after);     \
        check(same_, "intact.after_refusal", "world as it was after %s", what);         \
    } while (0)

    /* INVALID_ARGUMENT: steps, gravity, iterations. */
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_step(a.w, 0.0f), "world_step(dt 0)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_step(a.w, -1.0f), "world_step(dt -1)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_step(a.w, nanf_), "world_step(dt NaN)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_step(a.w, inf), "world_step(dt inf)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_gravity(a.w, NULL),
           "world_set_gravity(NULL)");
    {
        const float gv[3] = {0.0f, nanf_, 0.0f};
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_gravity(a.w, gv),
               "world_set_gravity(0, NaN, 0)");
    }
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_iterations(a.w, 1, 0, 11),
           "world_set_iterations(nonlinear 0)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_iterations(a.w, 1, 1, 0),
           "world_set_iterations(linear 0)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_iterations(a.w, 5000, 1, 11),
           "world_set_iterations(substeps 5000)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_get_stats(a.w, NULL),
           "world_get_stats(NULL)");

    /* Cloth defs. */
    rbc_cloth_def cd;
    rbc_cloth_id nc = 0;
    cloth_def_for(&cd, g);
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, NULL, &nc),
           "cloth_create(def NULL)");
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, NULL),
           "cloth_create(out NULL)");
    cd.positions = NULL;
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, &nc),
           "cloth_create(positions NULL)");
    cloth_def_for(&cd, g);
    cd.vertex_count = 0;
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, &nc),
           "cloth_create(vertex_count 0)");
    cloth_def_for(&cd, g);
    cd.stiffness = -1.0f;
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, &nc),
           "cloth_create(stiffness -1)");
    cd.stiffness = nanf_;
    REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, &nc),
           "cloth_create(stiffness NaN)");
    cloth_def_for(&cd, g);
    {
        uint32_t pins[2] = {0, g->nv + 7};
        cd.pins = pins;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(pin %u of %u vertices)", (unsigned)pins[1], (unsigned)g->nv);
        char idx[32];
        snprintf(idx, sizeof idx, "%u", (unsigned)pins[1]);
        check(strstr(msg_now(), idx) != NULL, "errors.names_index",
              "the message names the index %s: \"%s\"", idx, g_msg);
    }
    /* BAD_MESH: what a quad or a spring may not be. */
    {
        uint32_t *q = malloc(sizeof(uint32_t) * 4 * g->nq);
        memcpy(q, g->quads, sizeof(uint32_t) * 4 * g->nq);
        cloth_def_for(&cd, g);
        cd.quads = q;
        q[4 * 3 + 2] = g->nv + 100;
        REFUSE(RBC_ERR_BAD_MESH, "errors.bad_mesh", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(quad 3 corner 2 = %u, out of range)", (unsigned)q[4 * 3 + 2]);
        char idx[32];
        snprintf(idx, sizeof idx, "%u", (unsigned)(g->nv + 100));
        check(strstr(msg_now(), idx) != NULL, "errors.names_index",
              "the message names the vertex %s: \"%s\"", idx, g_msg);
        memcpy(q, g->quads, sizeof(uint32_t) * 4 * g->nq);
        q[4 * 2 + 1] = q[4 * 2 + 0];
        REFUSE(RBC_ERR_BAD_MESH, "errors.bad_mesh", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(quad 2 repeats a vertex)");
        memcpy(q, g->quads, sizeof(uint32_t) * 4 * g->nq);
        free(q);
        /* Coincident corners: a copy of the positions with two corners moved together. */
        float *p = malloc(sizeof(float) * 3 * g->nv);
        memcpy(p, g->pos, sizeof(float) * 3 * g->nv);
        memcpy(p + 3 * g->quads[1], p + 3 * g->quads[0], 3 * sizeof(float));
        cloth_def_for(&cd, g);
        cd.positions = p;
        REFUSE(RBC_ERR_BAD_MESH, "errors.bad_mesh", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(quad 0 has two corners at one point)");
        free(p);
        uint32_t sp[4] = {0, 1, 5, 5};
        cloth_def_for(&cd, g);
        cd.springs = sp;
        cd.spring_count = 2;
        REFUSE(RBC_ERR_BAD_MESH, "errors.bad_mesh", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(spring 1 from vertex 5 to itself)");
        sp[3] = g->nv;
        REFUSE(RBC_ERR_BAD_MESH, "errors.bad_mesh", A->cloth_create(a.w, &cd, &nc),
               "cloth_create(spring 1 to vertex %u, out of range)", (unsigned)g->nv);
    }
    /* Per-cloth calls. */
    {
        const float t[3] = {0.0f, 1.0f, 0.0f}, tn[3] = {0.0f, nanf_, 0.0f};
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_set_pin(a.w, a.c, g->nv, t),
               "cloth_set_pin(vertex %u of %u)", (unsigned)g->nv, (unsigned)g->nv);
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_set_pin(a.w, a.c, 3, tn),
               "cloth_set_pin(target NaN)");
        float small[6];
        size_t written = 0;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid",
               A->cloth_read_positions(a.w, a.c, small, 6, &written),
               "cloth_read_positions(capacity 6 for %u vertices)", (unsigned)g->nv);
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_get_vertex_count(a.w, a.c, NULL),
               "cloth_get_vertex_count(out NULL)");
    }
    if (HAS(cloth_set_state)) {
        float *p = malloc(sizeof(float) * 3 * g->nv);
        A->cloth_get_state(a.w, a.c, p, NULL, 3 * (size_t)g->nv);
        p[3 * 7 + 1] = nanf_;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_set_state(a.w, a.c, p, NULL),
               "cloth_set_state(vertex 7 y NaN)");
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cloth_set_state(a.w, a.c, NULL, NULL),
               "cloth_set_state(positions NULL)");
        free(p);
    }
    /* Colliders. */
    {
        rbc_collider_def kd;
        rbc_collider_id nk = 0;
        memset(&kd, 0, sizeof kd);
        A->collider_def_init(&kd, size_of(RBC_STRUCT_COLLIDER_DEF));
        kd.shape = 99;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->collider_create(a.w, &kd, &nk),
               "collider_create(shape 99)");
        kd.shape = RBC_SHAPE_SPHERE;
        kd.radius = 0.0f;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->collider_create(a.w, &kd, &nk),
               "collider_create(sphere of radius 0)");
        const float pn[3] = {nanf_, 0.0f, 0.0f}, rot[4] = {0, 0, 0, 1};
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid",
               A->collider_set_transform(a.w, a.k, pn, rot), "collider_set_transform(x NaN)");
    }
    /* Solver settings (1.1). */
    if (HAS(world_set_solver)) {
        rbc_solver_def sd;
        memset(&sd, 0, sizeof sd);
        A->solver_def_init(&sd, size_of(RBC_STRUCT_SOLVER_DEF));
        sd.solver = 99;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_solver(a.w, &sd),
               "world_set_solver(solver 99)");
        A->solver_def_init(&sd, size_of(RBC_STRUCT_SOLVER_DEF));
        sd.solver = RBC_SOLVER_RBGS_SOR;
        sd.omega = 2.5f;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_solver(a.w, &sd),
               "world_set_solver(SOR omega 2.5)");
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_solver(a.w, NULL),
               "world_set_solver(NULL)");
    }
    /* Interaction (1.3). */
    if (HAS(world_set_wind)) {
        const float wv[3] = {1.0f, 0.0f, 0.0f}, zero[3] = {0, 0, 0}, o[3] = {0, 2, 0};
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_set_wind(a.w, wv, -1.0f, 0.0f),
               "world_set_wind(drag -1)");
        rbc_cloth_id pc = 0;
        uint32_t pv = 0;
        float pt = 0;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid",
               A->world_pick(a.w, o, zero, 10.0f, 0.1f, &pc, &pv, &pt), "world_pick(dir 0)");
        const uint32_t pairs[2] = {0, g->nv + 3};
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid",
               A->cloth_cut(a.w, a.c, pairs, 1, NULL), "cloth_cut(pair 0 to vertex %u)",
               (unsigned)pairs[1]);
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid",
               A->cloth_attach(a.w, a.c, g->nv, a.k, NULL), "cloth_attach(vertex %u of %u)",
               (unsigned)g->nv, (unsigned)g->nv);
    }
    /* Worlds that cannot be made leave this one as it was. */
    {
        rbc_world_def wd;
        rbc_world_id nw = 0;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_create(NULL, &nw),
               "world_create(def NULL)");
        world_def_for(&wd, 1);
        wd.backend = 99;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_create(&wd, &nw),
               "world_create(backend 99)");
        world_def_for(&wd, 1);
        wd.gravity[2] = inf;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_create(&wd, &nw),
               "world_create(gravity z inf)");
        world_def_for(&wd, 1);
        wd.alloc = (rbc_alloc_fn)0x1;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->world_create(&wd, &nw),
               "world_create(alloc hook without free)");
    }
    /* IO: files in a folder that does not exist. */
    {
        const char *missing = temp_path("missing-folder");
        char path[1200];
        snprintf(path, sizeof path, "%s%cx.obj", missing,
#if defined(_WIN32)
                 '\\'
#else
                 '/'
#endif
        );
        REFUSE(RBC_ERR_IO, "errors.io", A->write_obj(path, g->pos, g->nv, g->quads, g->nq),
               "write_obj into a missing folder");
        rbc_cache_def hd;
        memset(&hd, 0, sizeof hd);
        A->cache_def_init(&hd, size_of(RBC_STRUCT_CACHE_DEF));
        hd.path = path;
        hd.point_count = g->nv;
        rbc_cache_id h = 0;
        REFUSE(RBC_ERR_IO, "errors.io", A->cache_create(&hd, &h), "cache_create into a missing folder");
        hd.point_count = 0;
        REFUSE(RBC_ERR_INVALID_ARGUMENT, "errors.invalid", A->cache_create(&hd, &h),
               "cache_create(point_count 0)");
    }
    /* UNSTABLE: a gravity so large that positions overflow; the step is undone. */
    {
        const float huge[3] = {0.0f, -3.0e38f, 0.0f};
        A->world_set_gravity(a.w, huge);
        A->world_set_gravity(b.w, huge);
        REFUSE(RBC_ERR_UNSTABLE, "errors.unstable", A->world_step(a.w, 1.0f / 60.0f),
               "world_step under gravity -3e38 (positions overflow)");
        const float gv[3] = {0.0f, -9.81f, 0.0f};
        A->world_set_gravity(a.w, gv);
        A->world_set_gravity(b.w, gv);
    }
    /* BACKEND_UNAVAILABLE or a working backend: CUDA, and the direct solver (1.1). */
    {
        rbc_world_def wd;
        rbc_world_id nw = 0;
        world_def_for(&wd, 1);
        wd.backend = RBC_BACKEND_CUDA;
        snap_world(&before, a.w, cl, 1);
        poison_message();
        rbc_result r = A->world_create(&wd, &nw);
        if (r == RBC_OK) {
            skip("errors.backend", "this build runs the CUDA backend here");
            A->world_destroy(nw);
        } else {
            refused(r, RBC_ERR_BACKEND_UNAVAILABLE, "errors.backend", "world_create(backend CUDA)");
        }
        if (HAS(world_set_solver)) {
            rbc_solver_def sd;
            memset(&sd, 0, sizeof sd);
            A->solver_def_init(&sd, size_of(RBC_STRUCT_SOLVER_DEF));
            sd.solver = RBC_SOLVER_DIRECT;
            snap_world(&before, a.w, cl, 1);
            poison_message();
            r = A->world_set_solver(a.w, &sd);
            if (r == RBC_OK) {
                skip("errors.backend", "this build has the direct solver (CHOLMOD)");
                rbc_solver_def sb;
                memset(&sb, 0, sizeof sb);
                sb.struct_size = size_of(RBC_STRUCT_SOLVER_DEF);
                A->world_get_solver(b.w, &sb);
                /* The twin goes through the same switch and back. */
                A->world_set_solver(b.w, &sd);
                A->world_set_solver(a.w, &sb);
                A->world_set_solver(b.w, &sb);
            } else {
                refused(r, RBC_ERR_BACKEND_UNAVAILABLE, "errors.backend",
                        "world_set_solver(RBC_SOLVER_DIRECT)");
                snap_world(&after, a.w, cl, 1);
                check(snap_equal(&before, &after),
                      "intact.after_refusal", "world as it was after the direct solver's refusal");
            }
        }
    }
    /* The last word: a and its twin, which saw none of this, step alike, bit for bit. */
    {
        float *pa = malloc(sizeof(float) * 3 * g->nv), *pb = malloc(sizeof(float) * 3 * g->nv);
        rbc_result r1 = scene_run(&a, 20, 1.0f / 60.0f, pa), r2 = scene_run(&b, 20, 1.0f / 60.0f, pb);
        check(r1 == RBC_OK && r2 == RBC_OK && memcmp(pa, pb, sizeof(float) * 3 * g->nv) == 0,
              "intact.twin", "after every refusal the world steps bitwise like its twin (20 steps)");
        if (r1 || r2) diag("  %s / %s: %s", code_name(r1), code_name(r2), msg_now());
        free(pa);
        free(pb);
    }
#undef REFUSE
    A->world_destroy(a.w);
    A->world_destroy(b.w);
    free(before.b);
    free(after.b);
}

/* ------------------------------------------------------------------------- */
/* handles                                                                   */
/* ------------------------------------------------------------------------- */

static void check_handles(const grid *g) {
    scene a, b;
    if (!check(scene_make(&a, g, 1, 0.3f) == RBC_OK && scene_make(&b, g, 1, 0.3f) == RBC_OK,
               "handles.setup", "two worlds"))
        return;
    uint32_t nv = 0;
    float xyz[3];
    size_t written = 0;
    const float t[3] = {0, 1, 0};
#define STALE(call, ...)                                                        \
    do {                                                                        \
        char w_[160];                                                           \
        snprintf(w_, sizeof w_, __VA_ARGS__);                                   \
        poison_message();                                                       \
        refused((call), RBC_ERR_STALE_HANDLE, "handles.stale", w_);             \
    } while (0)
    STALE(A->world_step(0, 1.0f / 60.0f), "world_step(world 0)");
    STALE(A->cloth_get_vertex_count(a.w, 0, &nv), "cloth_get_vertex_count(cloth 0)");
    STALE(A->cloth_get_vertex_count(a.w, b.c, &nv), "a cloth of world b used with world a");
    STALE(A->collider_destroy(a.w, b.k), "a collider of world b destroyed through world a");
    STALE(A->cloth_get_vertex_count(a.w, a.k, &nv), "a collider id used as a cloth id");
    STALE(A->collider_destroy(a.w, a.c), "a cloth id used as a collider id");
    STALE(A->world_step(a.c, 1.0f / 60.0f), "a cloth id used as a world id");
    STALE(A->cloth_set_pin(a.w, a.c ^ 0x5A5A0000u, 0, t), "a forged cloth id");
    /* Destroyed cloths and colliders stay stale when their slot is reused. */
    {
        rbc_cloth_def cd;
        cloth_def_for(&cd, g);
        rbc_cloth_id c2 = 0, c3 = 0;
        A->cloth_create(a.w, &cd, &c2);
        check(A->cloth_destroy(a.w, c2) == RBC_OK, "handles.destroy", "cloth_destroy");
        STALE(A->cloth_destroy(a.w, c2), "cloth_destroy twice");
        STALE(A->cloth_read_positions(a.w, c2, xyz, 3, &written), "a destroyed cloth read");
        rbc_result r = A->cloth_create(a.w, &cd, &c3);
        check(r == RBC_OK && c3 != c2, "handles.generation",
              "a new cloth gets a new id (0x%08x, the destroyed one was 0x%08x)", (unsigned)c3,
              (unsigned)c2);
        STALE(A->cloth_get_vertex_count(a.w, c2, &nv), "the destroyed id after its slot's reuse");
        check(A->cloth_get_vertex_count(a.w, c3, &nv) == RBC_OK && nv == g->nv, "handles.generation",
              "the new cloth works");
        rbc_collider_def kd;
        memset(&kd, 0, sizeof kd);
        A->collider_def_init(&kd, size_of(RBC_STRUCT_COLLIDER_DEF));
        rbc_collider_id k2 = 0;
        A->collider_create(a.w, &kd, &k2);
        check(A->collider_destroy(a.w, k2) == RBC_OK, "handles.destroy", "collider_destroy");
        const float rot[4] = {0, 0, 0, 1};
        STALE(A->collider_set_transform(a.w, k2, t, rot), "a destroyed collider moved");
        A->cloth_destroy(a.w, c3);
    }
    /* Caches: finished and destroyed ids are stale. */
    {
        const char *path = temp_path("handles.pc2");
        rbc_cache_def hd;
        memset(&hd, 0, sizeof hd);
        A->cache_def_init(&hd, size_of(RBC_STRUCT_CACHE_DEF));
        hd.path = path;
        hd.point_count = 1;
        rbc_cache_id h = 0;
        if (check(A->cache_create(&hd, &h) == RBC_OK, "handles.cache", "cache_create")) {
            A->cache_write_frame(h, xyz);
            check(A->cache_finish(h) == RBC_OK, "handles.cache", "cache_finish");
            STALE(A->cache_write_frame(h, xyz), "a finished cache written");
            STALE(A->cache_destroy(h), "a finished cache destroyed");
        }
        STALE(A->cache_finish(a.w), "a world id used as a cache id");
    }
    if (HAS(mesh_destroy)) {
        STALE(A->mesh_destroy(0x00010001u), "mesh_destroy of an id never made");
        rbc_cloth_id mc = 0;
        STALE(A->cloth_create_from_mesh(a.w, 0, NULL, &mc), "cloth_create_from_mesh(mesh 0)");
    }
    /* A destroyed world, and what was in it. */
    rbc_world_id dead = a.w;
    check(A->world_destroy(a.w) == RBC_OK, "handles.destroy", "world_destroy");
    STALE(A->world_step(dead, 1.0f / 60.0f), "a destroyed world stepped");
    STALE(A->world_destroy(dead), "world_destroy twice");
    STALE(A->cloth_get_vertex_count(dead, a.c, &nv), "a cloth of a destroyed world");
    /* b did not notice. */
    check(A->world_step(b.w, 1.0f / 60.0f) == RBC_OK, "handles.other_world",
          "the other world steps on");
    A->world_destroy(b.w);
#undef STALE
}

/* ------------------------------------------------------------------------- */
/* callbacks                                                                 */
/* ------------------------------------------------------------------------- */

typedef struct cb_state {
    int mode; /* 0 pass, 1 return failure, 2 write NaN, 3 bad contact */
    int calls;
    int wrong_thread;
    thread_ident stepper;
    rbc_result add_result;
} cb_state;

static int32_t RBC_CALL collision_cb(void *user, rbc_world_id w, float dt,
                                     const rbc_collision_cloth *cloths, uint32_t n) {
    cb_state *s = (cb_state *)user;
    s->calls++;
    if (!same_thread(thread_self(), s->stepper)) s->wrong_thread++;
    if (s->mode == 1) return 1;
    if (s->mode == 2 && n > 0 && cloths[0].vertex_count > 3) cloths[0].positions[3 * 3 + 1] = NAN;
    return 0;
}

static int32_t RBC_CALL contact_cb(void *user, rbc_world_id w, float dt,
                                   const rbc_collision_cloth *cloths, uint32_t n,
                                   rbc_contact_sink *sink) {
    cb_state *s = (cb_state *)user;
    s->calls++;
    if (!same_thread(thread_self(), s->stepper)) s->wrong_thread++;
    if (s->mode == 1) return 7;
    if (s->mode == 3 && n > 0) {
        rbc_host_contact c;
        memset(&c, 0, sizeof c);
        c.cloth = cloths[0].cloth;
        c.vertex = cloths[0].vertex_count + 5; /* out of range */
        c.normal[1] = 1.0f;
        s->add_result = sink->add(sink, &c, 1);
    }
    return 0;
}

/* A step a host callback fails: RBC_ERR_CALLBACK with a message of its own, and
 * the world as it was before the step. */
static void failing_step(rbc_world_id w, rbc_cloth_id c, const char *what) {
    snapshot before = {0}, after = {0};
    snap_world(&before, w, &c, 1);
    poison_message();
    refused(A->world_step(w, 1.0f / 60.0f), RBC_ERR_CALLBACK, "callbacks.failure", what);
    snap_world(&after, w, &c, 1);
    check(snap_equal(&before, &after), "callbacks.undone", "the world as before the step after %s",
          what);
    free(before.b);
    free(after.b);
}

static void check_callbacks(const grid *g) {
    scene a, b;
    if (!check(scene_make(&a, g, 2, 0.3f) == RBC_OK && scene_make(&b, g, 2, 0.3f) == RBC_OK,
               "callbacks.setup", "two identical worlds of 2 threads"))
        return;
    cb_state s;
    memset(&s, 0, sizeof s);
    s.stepper = thread_self();
    A->world_set_collision_callback(a.w, collision_cb, &s);
    A->world_set_collision_callback(b.w, collision_cb, &s);
    int fail = 0;
    for (int k = 0; k < 5; k++) {
        fail |= A->world_step(a.w, 1.0f / 60.0f) != RBC_OK;
        fail |= A->world_step(b.w, 1.0f / 60.0f) != RBC_OK;
    }
    check(!fail && s.calls >= 10, "callbacks.called", "a passing callback is called (%d calls in 10 steps)",
          s.calls);
    static const char *const what[] = {"", "the collision callback returns 1",
                                       "the collision callback writes NaN"};
    for (int mode = 1; mode <= 2; mode++) {
        s.mode = mode;
        failing_step(a.w, a.c, what[mode]);
    }
    s.mode = 0;
    if (HAS(world_set_contact_callback)) {
        A->world_set_contact_callback(a.w, contact_cb, &s);
        A->world_set_contact_callback(b.w, contact_cb, &s);
        static const char *const cwhat[] = {"", "the contact callback returns 7", "",
                                            "the contact callback adds a vertex out of range"};
        for (int mode = 1; mode <= 3; mode += 2) {
            s.mode = mode;
            s.add_result = RBC_OK;
            failing_step(a.w, a.c, cwhat[mode]);
            if (mode == 3)
                check(s.add_result == RBC_ERR_INVALID_ARGUMENT, "callbacks.sink",
                      "the sink refuses the contact with RBC_ERR_INVALID_ARGUMENT (got %s)",
                      code_name(s.add_result));
        }
        s.mode = 0;
    }
    check(s.wrong_thread == 0, "threads.callback_thread",
          "every callback ran on the thread that called world_step (%d did not)", s.wrong_thread);
    /* Failed steps leave nothing behind: a and b, stepped alike, still agree. */
    float *pa = malloc(sizeof(float) * 3 * g->nv), *pb = malloc(sizeof(float) * 3 * g->nv);
    rbc_result r1 = scene_run(&a, 10, 1.0f / 60.0f, pa), r2 = scene_run(&b, 10, 1.0f / 60.0f, pb);
    check(r1 == RBC_OK && r2 == RBC_OK && memcmp(pa, pb, sizeof(float) * 3 * g->nv) == 0,
          "callbacks.undone", "after the failed steps the world steps bitwise like its twin");
    check(A->world_set_collision_callback(a.w, NULL, NULL) == RBC_OK, "callbacks.remove",
          "set_collision_callback(NULL) removes it");
    int before_calls = s.calls;
    if (HAS(world_set_contact_callback)) A->world_set_contact_callback(a.w, NULL, NULL);
    A->world_step(a.w, 1.0f / 60.0f);
    check(s.calls == before_calls, "callbacks.remove", "a removed callback is not called");
    free(pa);
    free(pb);
    A->world_destroy(a.w);
    A->world_destroy(b.w);
}

/* ------------------------------------------------------------------------- */
/* memory: allocator hooks, out of memory                                    */
/* ------------------------------------------------------------------------- */

typedef struct hooks {
    long live, total, fail_after, size_mismatch, bad_align;
    size_t live_bytes;
} hooks;

/* Header before each block: the size asked for, and the malloc'd pointer. */
typedef struct block_head { size_t size; void *base; } block_head;

static void *RBC_CALL hook_alloc(void *user, size_t size, size_t alignment) {
    hooks *h = (hooks *)user;
    if (h->fail_after >= 0 && h->total >= h->fail_after) return NULL;
    if (alignment == 0 || (alignment & (alignment - 1)) || alignment > 64) h->bad_align++;
    if (alignment < sizeof(void *)) alignment = sizeof(void *);
    unsigned char *base = malloc(size + alignment + sizeof(block_head));
    if (!base) return NULL;
    uintptr_t p = ((uintptr_t)(base + sizeof(block_head)) + alignment - 1) & ~(uintptr_t)(alignment - 1);
    block_head *hd = (block_head *)(p - sizeof(block_head));
    hd->size = size;
    hd->base = base;
    h->live++;
    h->total++;
    h->live_bytes += size;
    return (void *)p;
}

static void RBC_CALL hook_free(void *user, void *ptr, size_t size) {
    hooks *h = (hooks *)user;
    if (!ptr) return;
    block_head *hd = (block_head *)((unsigned char *)ptr - sizeof(block_head));
    if (hd->size != size) h->size_mismatch++;
    h->live--;
    h->live_bytes -= hd->size;
    free(hd->base);
}

static void check_memory(const grid *g) {
    hooks h;
    memset(&h, 0, sizeof h);
    h.fail_after = 0;
    rbc_world_def wd;
    world_def_for(&wd, 1);
    wd.alloc = hook_alloc;
    wd.free = hook_free;
    wd.alloc_user = &h;
    rbc_world_id w = 0;
    poison_message();
    rbc_result r = A->world_create(&wd, &w);
    refused(r, RBC_ERR_OUT_OF_MEMORY, "memory.out_of_memory", "world_create whose first allocation fails");
    check(h.live == 0, "memory.balanced", "nothing left allocated (%ld blocks)", h.live);
    if (r == RBC_OK) A->world_destroy(w);
    /* A world whose cloth_create meets a failure at every allocation in turn. */
    h.fail_after = -1;
    if (!check(A->world_create(&wd, &w) == RBC_OK, "memory.hooks", "a world with allocator hooks"))
        return;
    rbc_cloth_def cd;
    cloth_def_for(&cd, g);
    rbc_cloth_id c0 = 0;
    A->cloth_create(w, &cd, &c0);
    for (int k = 0; k < 3; k++) A->world_step(w, 1.0f / 60.0f);
    snapshot before = {0}, after = {0};
    const rbc_cloth_id cl[1] = {c0};
    int refusals = 0, wrong = 0, changed = 0, made = 0;
    for (long k = 0; k < 400 && !made; k++) {
        snap_world(&before, w, cl, 1);
        h.fail_after = h.total + k;
        rbc_cloth_id c = 0;
        poison_message();
        r = A->cloth_create(w, &cd, &c);
        h.fail_after = -1;
        if (r == RBC_OK) {
            made = 1;
            break;
        }
        refusals++;
        const char *m = msg_now();
        if (r != RBC_ERR_OUT_OF_MEMORY || !m[0] || strcmp(m, g_poison) == 0) wrong++;
        snap_world(&after, w, cl, 1);
        if (!snap_equal(&before, &after)) changed++;
    }
    check(made && wrong == 0, "memory.out_of_memory",
          "cloth_create failing at each of its %d allocations returns RBC_ERR_OUT_OF_MEMORY "
          "with a message (%d did not)", refusals, wrong);
    check(changed == 0, "intact.out_of_memory",
          "the world as it was after each of them (%d changed it)", changed);
    check(A->world_step(w, 1.0f / 60.0f) == RBC_OK, "memory.out_of_memory",
          "and the world steps on");
    A->world_destroy(w);
    check(h.live == 0 && h.live_bytes == 0, "memory.balanced",
          "world_destroy frees every block the hooks gave (%ld left, %zu bytes)", h.live,
          h.live_bytes);
    check(h.size_mismatch == 0 && h.bad_align == 0, "memory.hooks",
          "free gets the size asked for, alignments are powers of two <= 64 (%ld, %ld wrong)",
          h.size_mismatch, h.bad_align);
    free(before.b);
    free(after.b);
}

/* CAPACITY: worlds until the library's limit, if it has one below 4096. */
static void check_capacity(const grid *g) {
    enum { MAXW = 4096 };
    static rbc_world_id ws[MAXW];
    scene a;
    if (scene_make(&a, g, 1, 0.3f) != RBC_OK) return;
    snapshot before = {0}, after = {0};
    const rbc_cloth_id cl[1] = {a.c};
    snap_world(&before, a.w, cl, 1);
    int n = 0;
    rbc_result r = RBC_OK;
    rbc_world_def wd;
    world_def_for(&wd, 1);
    for (; n < MAXW; n++) {
        poison_message();
        r = A->world_create(&wd, &ws[n]);
        if (r) break;
    }
    if (n == MAXW) {
        skip("errors.capacity", "no world capacity below 4096 worlds");
    } else {
        char what[64];
        snprintf(what, sizeof what, "world %d of a full registry", n + 2);
        refused(r, RBC_ERR_CAPACITY, "errors.capacity", what);
    }
    for (int k = 0; k < n; k++) A->world_destroy(ws[k]);
    snap_world(&after, a.w, cl, 1);
    check(snap_equal(&before, &after), "intact.capacity",
          "a world made before is as it was");
    rbc_world_id w = 0;
    check(A->world_create(&wd, &w) == RBC_OK, "errors.capacity", "worlds can be made again");
    A->world_destroy(w);
    A->world_destroy(a.w);
    free(before.b);
    free(after.b);
}

/* ------------------------------------------------------------------------- */
/* threads, determinism                                                      */
/* ------------------------------------------------------------------------- */

typedef struct job {
    const grid *g;
    float sphere_x, dt;
    uint32_t threads;
    int steps;
    float *out;
    rbc_result result;
    flag_t *start;
    /* The per-thread error message check. */
    flag_t *handoff;
    int role; /* 1: fails first, reads after the other failed; 2: fails second */
    char message[512];
} job;

/* Two threads in lockstep: each arrives, and goes on when both have arrived `round`
 * times. The threads test steps its worlds this way so that the two steps of each
 * round run at the same time (without it, on a busy machine one thread could run
 * all its steps before the other starts, and a shared-state bug would go unseen). */
static void lockstep(flag_t *f, long round) {
    flag_add(f);
    while (flag_get(f) < 2 * round) yield_now();
}

static void run_job(void *p) {
    job *j = (job *)p;
    if (j->start) lockstep(j->start, 1);
    scene s;
    j->result = scene_make(&s, j->g, j->threads, j->sphere_x);
    for (int k = 0; k < j->steps; k++) {
        if (j->start) lockstep(j->start, k + 2); /* a failed thread still arrives */
        if (j->result == RBC_OK) j->result = A->world_step(s.w, j->dt);
    }
    if (j->result == RBC_OK) j->result = scene_run(&s, 0, j->dt, j->out);
    if (s.w) A->world_destroy(s.w);
    if (j->handoff) {
        rbc_world_def d;
        rbc_cloth_def c;
        if (j->role == 1) {
            A->world_def_init(&d, 3);
            flag_set(j->handoff, 1);
            while (flag_get(j->handoff) != 2) yield_now();
        } else {
            while (flag_get(j->handoff) != 1) yield_now();
            A->cloth_def_init(&c, 5);
            flag_set(j->handoff, 2);
        }
        snprintf(j->message, sizeof j->message, "%s", A->last_error());
    }
}

static void check_threads(const grid *g) {
    const size_t n = 3 * (size_t)g->nv;
    float *seq1 = malloc(n * sizeof(float)), *seq2 = malloc(n * sizeof(float));
    float *par1 = malloc(n * sizeof(float)), *par2 = malloc(n * sizeof(float));
    job j1 = {g, 0.25f, 1.0f / 60.0f, 2, 40, seq1, RBC_OK, NULL, NULL, 1, ""};
    job j2 = {g, 0.55f, 1.0f / 50.0f, 1, 40, seq2, RBC_OK, NULL, NULL, 2, ""};
    run_job(&j1);
    run_job(&j2);
    /* The messages each would leave alone. */
    rbc_world_def d;
    rbc_cloth_def c;
    char m1[512], m2[512];
    A->world_def_init(&d, 3);
    snprintf(m1, sizeof m1, "%s", A->last_error());
    A->cloth_def_init(&c, 5);
    snprintf(m2, sizeof m2, "%s", A->last_error());
    flag_t start = 0, handoff = 0;
    job p1 = j1, p2 = j2;
    p1.out = par1;
    p2.out = par2;
    p1.start = p2.start = &start;
    p1.handoff = p2.handoff = &handoff;
    thread_start_arg a1 = {run_job, &p1}, a2 = {run_job, &p2};
    thread_handle t1, t2;
    int started = thread_start(&t1, &a1) == 0;
    started = started && thread_start(&t2, &a2) == 0;
    if (!check(started, "threads.start", "two host threads")) return;
    thread_join(t1);
    thread_join(t2);
    check(j1.result == RBC_OK && j2.result == RBC_OK && p1.result == RBC_OK && p2.result == RBC_OK,
          "threads.run", "two worlds stepped on two threads at once");
    check(memcmp(seq1, par1, n * sizeof(float)) == 0 && memcmp(seq2, par2, n * sizeof(float)) == 0,
          "threads.independent", "each is bitwise what it is alone (40 steps, 2 + 1 workers)");
    check(strcmp(p1.message, m1) == 0 && strcmp(p2.message, m2) == 0 && m1[0] && m2[0] &&
              strcmp(m1, m2) != 0,
          "threads.last_error", "last_error is per thread: each thread reads its own message");
    if (strcmp(p1.message, m1) != 0) diag("  thread 1 read \"%s\", not \"%s\"", p1.message, m1);
    free(seq1);
    free(seq2);
    free(par1);
    free(par2);
}

/* ------------------------------------------------------------------------- */
/* 1.10: what a game loop reads and does                                     */
/* ------------------------------------------------------------------------- */

/* Interleaved positions and normals equal read_positions and are unit; a bad entry
 * is refused by its index with no byte written; triangles are two per quad at
 * revision 1; a transform that is not a rotation is refused; the split step is the
 * plain step bitwise, and a stepping world refuses with RBC_ERR_BUSY. */
static void check_gameloop(const grid *g) {
    if (!HAS(world_step_wait)) {
        skip("gameloop", "the library is older than ABI 1.10");
        return;
    }
    scene a, b;
    if (scene_make(&a, g, 1, 0.3f) || scene_make(&b, g, 1, 0.3f)) {
        check(0, "gameloop.setup", "two scenes: %s", msg_now());
        return;
    }
    const size_t nv = g->nv;
    float *pa = malloc(12 * nv), *pb = malloc(12 * nv);
    unsigned char *buf = malloc(24 * nv);
    if (!pa || !pb || !buf) abort();
    int split_same = 1, busy = 1;
    for (int f = 0; f < 20; f++) {
        split_same &= A->world_step_begin(a.w, 1.0f / 60.0f) == RBC_OK;
        if (f == 2) {
            size_t w = 0;
            poison_message();
            busy &= refused(A->cloth_read_positions(a.w, a.c, pa, 3 * nv, &w), RBC_ERR_BUSY,
                            "gameloop.busy", "read_positions while stepping");
            busy &= A->world_step(a.w, 0.01f) == RBC_ERR_BUSY;
        }
        split_same &= A->world_step_wait(a.w) == RBC_OK;
        split_same &= A->world_step(b.w, 1.0f / 60.0f) == RBC_OK;
    }
    size_t wa = 0, wb = 0;
    A->cloth_read_positions(a.w, a.c, pa, 3 * nv, &wa);
    A->cloth_read_positions(b.w, b.c, pb, 3 * nv, &wb);
    check(split_same && wa == 3 * nv && memcmp(pa, pb, 12 * nv) == 0, "gameloop.split_step",
          "20 steps of step_begin / step_wait equal 20 of world_step bitwise");
    check(busy, "gameloop.busy", "a stepping world refuses other calls with RBC_ERR_BUSY");

    rbc_vertex_output o;
    memset(&o, 0, sizeof o);
    check(A->vertex_output_init(&o, (uint32_t)sizeof o) == RBC_OK && o.stride == 12 &&
              o.position_offset == 0 && o.normal_offset == RBC_NO_ATTRIBUTE,
          "gameloop.output_init", "defaults: stride 12, position at 0, no normal");
    o.cloth = a.c;
    o.buffer = buf;
    o.buffer_size = 24 * nv;
    o.stride = 24;
    o.normal_offset = 12;
    int same = A->world_read_vertices(a.w, &o, 1) == RBC_OK, unit = same;
    for (size_t v = 0; same && v < nv; v++) {
        float n[3];
        same &= memcmp(buf + 24 * v, &pa[3 * v], 12) == 0;
        memcpy(n, buf + 24 * v + 12, 12);
        const double l = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        unit &= fabs(l - 1.0) <= 1e-6;
    }
    check(same, "gameloop.read_vertices", "stride 24: positions equal read_positions");
    check(unit, "gameloop.normals", "every normal of the grid is unit (within 1e-6)");
    memset(buf, 0xA5, 24 * nv);
    rbc_vertex_output two[2] = {o, o};
    two[1].buffer_size = 24 * nv - 1;
    poison_message();
    refused(A->world_read_vertices(a.w, two, 2), RBC_ERR_INVALID_ARGUMENT, "gameloop.refused",
            "read_vertices with a buffer one byte short");
    int untouched = 1;
    for (size_t k = 0; k < 24 * nv; k++) untouched &= buf[k] == 0xA5;
    check(untouched && strstr(msg_now(), "outputs[1]") != NULL, "gameloop.refused",
          "the bad entry is named (outputs[1]) and no buffer was written");

    size_t nt = 0;
    uint32_t rev = 0;
    const rbc_result tr = A->cloth_get_triangles(a.w, a.c, NULL, 0, &nt, &rev);
    check(tr == RBC_OK && nt == 6 * (size_t)g->nq && rev == 1,
          "gameloop.triangles", "%zu triangle indices (want %u) at revision %u (want 1)", nt,
          6 * g->nq, rev);
    const float t[3] = {0.0f, 1.0f, 0.0f}, not_unit[4] = {0.0f, 0.0f, 0.0f, 2.0f};
    poison_message();
    refused(A->cloth_transform(a.w, a.c, t, not_unit, 0), RBC_ERR_INVALID_ARGUMENT,
            "gameloop.transform", "cloth_transform with a quaternion of norm 2");
    const float id[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    check(A->cloth_transform(a.w, a.c, t, id, RBC_TRANSFORM_RESET_VELOCITY) == RBC_OK &&
              A->cloth_read_positions(a.w, a.c, pb, 3 * nv, &wb) == RBC_OK &&
              fabsf(pb[1] - (pa[1] + 1.0f)) <= 1e-6f,
          "gameloop.transform", "a translation by 1 m up moves vertex 0 by 1 m");
    A->world_destroy(a.w);
    A->world_destroy(b.w);
    free(pa);
    free(pb);
    free(buf);
}

static void check_determinism(void) {
    grid g;
    if (grid_make(&g, 64, 1.0f)) return;
    const size_t n = 3 * (size_t)g.nv;
    float *ref = malloc(n * sizeof(float)), *out = malloc(n * sizeof(float));
    job j = {&g, 3.2f, 1.0f / 60.0f, 1, 30, ref, RBC_OK, NULL, NULL, 0, ""};
    run_job(&j);
    if (!check(j.result == RBC_OK, "determinism.run", "a 64 x 64 cloth, 1 thread, 30 steps")) {
        diag("  %s: %s", code_name(j.result), msg_now());
        free(ref);
        free(out);
        grid_free(&g);
        return;
    }
    static const uint32_t counts[] = {2, 3, 4, 0};
    for (size_t k = 0; k < sizeof counts / sizeof counts[0]; k++) {
        job jk = j;
        jk.threads = counts[k];
        jk.out = out;
        run_job(&jk);
        check(jk.result == RBC_OK && memcmp(ref, out, n * sizeof(float)) == 0,
              "determinism.thread_count", "thread_count %u gives the bits of 1 thread",
              (unsigned)counts[k]);
    }
    free(ref);
    free(out);
    grid_free(&g);
}

/* ------------------------------------------------------------------------- */
/* mesh import, where the build has it                                       */
/* ------------------------------------------------------------------------- */

static void check_import(void) {
    if (!HAS(mesh_import)) return;
    const char *missing = temp_path("no-such-file.obj");
    rbc_mesh_import_def md;
    memset(&md, 0, sizeof md);
    A->mesh_import_def_init(&md, size_of(RBC_STRUCT_MESH_IMPORT_DEF));
    rbc_mesh_id m = 0;
    poison_message();
    rbc_result r = A->mesh_import(missing, &md, &m);
    if (r == RBC_ERR_UNSUPPORTED) {
        refused(r, RBC_ERR_UNSUPPORTED, "errors.unsupported", "mesh_import in a build without it");
        return;
    }
    refused(r, RBC_ERR_IO, "errors.io", "mesh_import of a file that does not exist");
    /* A 3 x 3 grid of quads as OBJ. */
    const char *path = temp_path("grid.obj");
    FILE *f = fopen(path, "w");
    if (!f) return;
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) fprintf(f, "v %d 1 %d\n", i, j);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++)
            fprintf(f, "f %d %d %d %d\n", 1 + i + 4 * j, 2 + i + 4 * j, 6 + i + 4 * j, 5 + i + 4 * j);
    fclose(f);
    r = A->mesh_import(path, &md, &m);
    if (!check(r == RBC_OK, "import.obj", "mesh_import of a 3 x 3 quad OBJ")) {
        diag("  %s: %s", code_name(r), msg_now());
        return;
    }
    rbc_mesh_info info;
    uint32_t is[16];
    int ni = released_sizes(RBC_STRUCT_MESH_INFO, is);
    for (int k = 0; k < ni; k++) {
        memset(&info, 0, sizeof info);
        info.struct_size = is[k];
        r = A->mesh_get_info(m, &info);
        check(r == RBC_OK && info.vertex_count == 16 && info.quad_count == 9, "sizes.mesh_get_info",
              "info of %u bytes: 16 vertices, 9 quads (got %u, %u)", (unsigned)is[k],
              (unsigned)info.vertex_count, (unsigned)info.quad_count);
    }
    info.struct_size = is[0] - 4;
    poison_message();
    refused(A->mesh_get_info(m, &info), RBC_ERR_INVALID_ARGUMENT, "sizes.mesh_get_info",
            "mesh_get_info with a size no minor had");
    check(A->mesh_destroy(m) == RBC_OK, "import.obj", "mesh_destroy");
    poison_message();
    refused(A->mesh_get_info(m, &info), RBC_ERR_STALE_HANDLE, "handles.stale", "a destroyed mesh");
}

/* ------------------------------------------------------------------------- */
/* watchdog                                                                  */
/* ------------------------------------------------------------------------- */

/* A library that deadlocks must not hang whoever runs the kit: after
 * RBC_CONFORMANCE_TIMEOUT seconds (default 300) the report bails out naming the
 * group of checks that did not return, and the process exits 1. */
static const char *volatile g_stage = "load";
static long g_timeout_s = 300;

static void watchdog(void *arg) {
    (void)arg;
    for (long t = 0; t < 10 * g_timeout_s; t++) {
#if defined(_WIN32)
        Sleep(100);
#else
        struct timespec ts = {0, 100000000L};
        nanosleep(&ts, NULL);
#endif
    }
    fprintf(g_tap, "not ok %d - watchdog: the %s checks did not return within %ld s\n", g_count + 1,
            g_stage, g_timeout_s);
    fprintf(g_tap, "Bail out! the library hangs (%s)\n", g_stage);
    fflush(g_tap);
    _exit(1);
}

/* ------------------------------------------------------------------------- */
/* main                                                                      */
/* ------------------------------------------------------------------------- */

int main(int argc, char **argv) {
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr,
                "usage: %s PATH/TO/LIBRARY\n"
                "Checks a build of the rbcloth C ABI against its contract (rbcloth.h, ABI %d.%d\n"
                "or older); prints a TAP report; exit 0 = conforms, 1 = a check failed, 2 = the\n"
                "library could not be used.\n",
                argv[0], RBC_ABI_VERSION_MAJOR, RBC_ABI_VERSION_MINOR);
        return 2;
    }
    /* The report goes to a copy of stdout; stdout and stderr themselves go to files. */
    fflush(stdout);
    fflush(stderr);
    int tap_fd = dup_fd(fileno_of(stdout));
    g_tap = tap_fd >= 0 ? fdopen_fd(tap_fd, "w") : NULL;
    if (!g_tap || make_temp_dir() != 0) {
        fprintf(stderr, "rbcloth-conformance: cannot set up its output or temporary folder\n");
        return 2;
    }
    fprintf(g_tap, "TAP version 13\n");
    diag("rbcloth-conformance: %s", argv[1]);
    const char *out_path = temp_path("stdout.txt"), *err_path = temp_path("stderr.txt");
    FILE *out_f = fopen(out_path, "w+b"), *err_f = fopen(err_path, "w+b");
    int err_fd = dup_fd(fileno_of(stderr));
    if (!out_f || !err_f || dup2_fd(fileno_of(out_f), fileno_of(stdout)) < 0 ||
        dup2_fd(fileno_of(err_f), fileno_of(stderr)) < 0) {
        fprintf(g_tap, "Bail out! cannot redirect stdout and stderr\n");
        return 2;
    }

    const char *to = getenv("RBC_CONFORMANCE_TIMEOUT");
    if (to && atol(to) > 0) g_timeout_s = atol(to);
    static thread_start_arg wd = {watchdog, NULL};
    thread_handle wt;
    if (thread_start(&wt, &wd) != 0) diag("no watchdog thread: a hang would not be reported");

    lib_handle lib = lib_open(argv[1]);
    if (!check(lib != NULL, "load.open", "the library loads")) {
        diag("  %s", lib_error());
        fprintf(g_tap, "1..%d\n", g_count);
        return 2;
    }
    union { void *obj; rbc_get_api_fn fn; } sym;
    sym.obj = lib_sym(lib, "rbc_get_api");
    if (!check(sym.obj != NULL, "load.get_api", "it exports rbc_get_api")) {
        fprintf(g_tap, "1..%d\n", g_count);
        return 2;
    }
    if (check_table(lib, sym.fn) != 0) {
        fprintf(g_tap, "Bail out! the function table is unusable\n1..%d\n", g_count);
        return g_failed ? 1 : 2; /* a table that breaks the contract is a failure */
    }

    grid g;
    if (grid_make(&g, 12, 1.0f)) return 2;
    g_stage = "sizes";
    check_sizes(&g);
    g_stage = "defaults";
    check_defaults();
    g_stage = "errors and intact";
    check_errors_intact(&g);
    g_stage = "handles";
    check_handles(&g);
    g_stage = "callbacks";
    check_callbacks(&g);
    g_stage = "memory";
    check_memory(&g);
    g_stage = "capacity";
    check_capacity(&g);
    g_stage = "import";
    check_import();
    g_stage = "threads";
    check_threads(&g);
    g_stage = "gameloop";
    check_gameloop(&g);
    g_stage = "determinism";
    check_determinism();
    g_stage = "stdout";
    grid_free(&g);

    /* Nothing reached stdout or stderr. */
    fflush(stdout);
    fflush(stderr);
    long out_len, err_len;
    fseek(out_f, 0, SEEK_END);
    fseek(err_f, 0, SEEK_END);
    out_len = ftell(out_f);
    err_len = ftell(err_f);
    char head[256];
    if (!check(out_len == 0, "stdout.silent", "the library wrote nothing to stdout (%ld bytes)", out_len)) {
        fseek(out_f, 0, SEEK_SET);
        size_t k = fread(head, 1, sizeof head - 1, out_f);
        head[k] = 0;
        diag("  it wrote: %s", head);
    }
    if (!check(err_len == 0, "stdout.silent", "the library wrote nothing to stderr (%ld bytes)", err_len)) {
        fseek(err_f, 0, SEEK_SET);
        size_t k = fread(head, 1, sizeof head - 1, err_f);
        head[k] = 0;
        diag("  it wrote: %s", head);
    }
    /* Back to the real stdout and stderr, so that the files can be removed. */
    dup2_fd(tap_fd, fileno_of(stdout));
    dup2_fd(err_fd, fileno_of(stderr));
    fclose(out_f);
    fclose(err_f);
    remove_temp_dir();
    fprintf(g_tap, "1..%d\n", g_count);
    diag("%d checks, %d failed", g_count, g_failed);
    fflush(g_tap);
    (void)lib; /* not unloaded: a host keeps its plugin to the end */
    return g_failed ? 1 : 0;
}
