/* abi_util.h -- helpers shared by the ABI tests in tests/abi (and the cache test):
 * quad meshes built by the test itself (so the tests depend on nothing but
 * abi/rbcloth.h), float ulp arithmetic for derived tolerances, and world snapshots
 * for "a failing call leaves every existing object exactly as it was" checks; worlds
 * made with their creation checked, a counter of repeated warnings, the checks that a
 * struct of an older size gets nothing written past it, twin worlds compared bitwise,
 * and the table of an allocator hook's live blocks.
 *
 * Everything here goes through the public functions of rbcloth.h only. The
 * conformance test does not include this file (it must not reference any
 * library symbol).
 */
#ifndef RBC_TEST_ABI_UTIL_H
#define RBC_TEST_ABI_UTIL_H

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "rbcloth.h"

/* ------------------------------------------------------------------------- */
/* Worlds                                                                    */
/* ------------------------------------------------------------------------- */

/* The default solver def with another solver. */
static inline rbc_solver_def test_solver_def(rbc_solver_kind kind) {
    rbc_solver_def d = rbc_solver_def_default();
    d.solver = kind;
    return d;
}

/* The world def of rbc_world_def_default with the paper's fixed counts
 * (RBC_PRESET_PAPER): most tests check what a step does at given substeps and
 * iterations, which the default solve (the target mode, ABI 1.6) chooses itself.
 * The solver def is static, so the def stays valid as the test passes it around;
 * one per thread (test_behaviour's thread test calls this from two threads at once,
 * and a shared one was written by both: a data race ThreadSanitizer reported). */
static inline rbc_world_def abi_world_def_fixed(void) {
    static _Thread_local rbc_solver_def paper;
    if (rbc_solver_def_preset(&paper, (uint32_t)sizeof paper, RBC_PRESET_PAPER) != RBC_OK) {
        fprintf(stderr, "abi_world_def_fixed: %s\n", rbc_last_error());
        exit(2);
    }
    rbc_world_def d = rbc_world_def_default();
    d.solver = &paper;
    return d;
}

/* A world of def d, its creation checked (and the library's message printed when it
 * is refused); 0 then. */
static inline rbc_world_id test_world(const rbc_world_def *d) {
    rbc_world_id w = 0;
    rbc_result r = rbc_world_create(d, &w);
    CHECK_EQ(r, RBC_OK);
    if (r != RBC_OK) fprintf(stderr, "rbc_world_create: %s\n", rbc_last_error());
    return w;
}

/* A log hook (wd.log = test_count_log, wd.log_user = the counter) for the warnings a
 * mode repeats at the 1st, 2nd, 4th, ... time: those containing `phrase` are counted,
 * and for the first 64 the number the message gives just before `count_before`
 * ("(K clamped so far)") is kept in at[]. */
typedef struct test_log_count {
    const char *phrase;
    const char *count_before;
    int warnings;
    uint64_t at[64];
} test_log_count;

static inline void RBC_CALL test_count_log(void *user, rbc_log_level level, const char *msg) {
    test_log_count *lc = (test_log_count *)user;
    if (level != RBC_LOG_WARNING || !strstr(msg, lc->phrase)) return;
    const char *p = strstr(msg, lc->count_before);
    uint64_t k = 0;
    if (p) {
        const char *q = p;
        while (q > msg && q[-1] >= '0' && q[-1] <= '9') --q;
        k = strtoull(q, NULL, 10);
    }
    if (lc->warnings < 64) lc->at[lc->warnings] = k;
    lc->warnings++;
}

/* ------------------------------------------------------------------------- */
/* Meshes                                                                    */
/* ------------------------------------------------------------------------- */

/* A regular nx x ny grid in the horizontal plane y = y0: vertex (i, j) has index
 * i + nx * j and sits at (x0 + i * spacing, y0, z0 + j * spacing). Quad (i, j)
 * joins (i, j), (i+1, j), (i+1, j+1), (i, j+1) and has index i + (nx - 1) * j.
 * Its structural springs: ny * (nx - 1) + nx * (ny - 1). */
typedef struct test_grid {
    uint32_t nx, ny;
    uint32_t vertex_count;
    uint32_t quad_count;
    float *positions;
    uint32_t *quads;
} test_grid;

static inline test_grid test_grid_make(uint32_t nx, uint32_t ny, float spacing, float x0,
                                       float y0, float z0) {
    test_grid g;
    g.nx = nx;
    g.ny = ny;
    g.vertex_count = nx * ny;
    g.quad_count = (nx - 1) * (ny - 1);
    g.positions = (float *)malloc(sizeof(float) * 3 * g.vertex_count);
    g.quads = (uint32_t *)malloc(sizeof(uint32_t) * 4 * (g.quad_count ? g.quad_count : 1));
    if (!g.positions || !g.quads) {
        fprintf(stderr, "test_grid_make: out of memory\n");
        exit(2);
    }
    for (uint32_t j = 0; j < ny; j++)
        for (uint32_t i = 0; i < nx; i++) {
            uint32_t v = i + nx * j;
            g.positions[3 * v + 0] = x0 + (float)i * spacing;
            g.positions[3 * v + 1] = y0;
            g.positions[3 * v + 2] = z0 + (float)j * spacing;
        }
    for (uint32_t j = 0; j + 1 < ny; j++)
        for (uint32_t i = 0; i + 1 < nx; i++) {
            uint32_t q = i + (nx - 1) * j;
            g.quads[4 * q + 0] = i + nx * j;
            g.quads[4 * q + 1] = (i + 1) + nx * j;
            g.quads[4 * q + 2] = (i + 1) + nx * (j + 1);
            g.quads[4 * q + 3] = i + nx * (j + 1);
        }
    return g;
}

static inline void test_grid_free(test_grid *g) {
    free(g->positions);
    free(g->quads);
    g->positions = NULL;
    g->quads = NULL;
}

static inline uint32_t test_grid_spring_count(const test_grid *g) {
    return g->ny * (g->nx - 1) + g->nx * (g->ny - 1);
}

/* A cloth def for the grid with the given pins (may be NULL/0), default mass and
 * stiffness unless changed afterwards. */
static inline rbc_cloth_def test_grid_def(const test_grid *g, const uint32_t *pins,
                                          uint32_t pin_count) {
    rbc_cloth_def d = rbc_cloth_def_default();
    d.vertex_count = g->vertex_count;
    d.positions = g->positions;
    d.quad_count = g->quad_count;
    d.quads = g->quads;
    d.pin_count = pin_count;
    d.pins = pins;
    return d;
}

/* ------------------------------------------------------------------------- */
/* Float arithmetic                                                          */
/* ------------------------------------------------------------------------- */

/* The spacing of floats at magnitude |x| (ulp(x)); for x = 0 the smallest
 * normal's spacing is irrelevant here, so FLT_MIN is returned. */
static inline double test_ulp(double x) {
    float a = fabsf((float)x);
    if (a < FLT_MIN) return FLT_MIN;
    return (double)nextafterf(a, INFINITY) - (double)a;
}

static inline int test_all_finite(const float *v, size_t n) {
    for (size_t k = 0; k < n; k++)
        if (!isfinite(v[k])) return 0;
    return 1;
}

/* Whether bytes [from, to) of buf all still hold `mark`: a host whose struct is older
 * (shorter) than the library's fills it with a mark first, and a call given the old
 * struct_size must write nothing past it. */
static inline int test_bytes_are(const void *buf, size_t from, size_t to, unsigned char mark) {
    const unsigned char *b = (const unsigned char *)buf;
    for (size_t k = from; k < to; ++k)
        if (b[k] != mark) return 0;
    return 1;
}

/* A struct of type T and `extra` bytes after it: what a host built against an older,
 * shorter header passes (d), marked first; the library must write nothing past the
 * struct_size it is given (test_bytes_are). */
#define TEST_PADDED(T, extra)      \
    struct {                       \
        T d;                       \
        unsigned char tail[extra]; \
    }

/* Does the decimal number n occur in s as a whole number (not as part of a longer
 * run of digits)? Used to check that error messages name the offending index. */
static inline int test_contains_number(const char *s, unsigned long n) {
    char buf[32];
    snprintf(buf, sizeof buf, "%lu", n);
    size_t len = strlen(buf);
    for (const char *p = s; (p = strstr(p, buf)) != NULL; p++) {
        int before_ok = (p == s) || !(p[-1] >= '0' && p[-1] <= '9');
        int after_ok = !(p[len] >= '0' && p[len] <= '9');
        if (before_ok && after_ok) return 1;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Reading state                                                             */
/* ------------------------------------------------------------------------- */

/* Read all positions of a cloth into a malloc'd buffer (3 floats per vertex);
 * *out_n receives the vertex count. Returns NULL (and prints why) on failure. */
static inline float *test_read(rbc_world_id w, rbc_cloth_id c, uint32_t *out_n) {
    uint32_t n = 0;
    rbc_result r = rbc_cloth_get_vertex_count(w, c, &n);
    if (r != RBC_OK || n == 0) {
        fprintf(stderr, "test_read: get_vertex_count -> %s (%s)\n", rbc_result_string(r),
                rbc_last_error());
        return NULL;
    }
    float *xyz = (float *)malloc(sizeof(float) * 3 * n);
    size_t written = 0;
    r = rbc_cloth_read_positions(w, c, xyz, (size_t)3 * n, &written);
    if (r != RBC_OK || written != (size_t)3 * n) {
        fprintf(stderr, "test_read: read_positions -> %s, written %zu of %u (%s)\n",
                rbc_result_string(r), written, 3 * n, rbc_last_error());
        free(xyz);
        return NULL;
    }
    if (out_n) *out_n = n;
    return xyz;
}

static inline rbc_world_stats test_stats(rbc_world_id w) {
    rbc_world_stats s;
    memset(&s, 0, sizeof s);
    s.struct_size = (uint32_t)sizeof s;
    rbc_result r = rbc_world_get_stats(w, &s);
    if (r != RBC_OK)
        fprintf(stderr, "test_stats: get_stats -> %s (%s)\n", rbc_result_string(r),
                rbc_last_error());
    return s;
}

/* Steps worlds wa and wb `frames` times at dt, each step checked; then whether cloth ca
 * of wa and cb of wb hold bitwise the same positions. */
static inline int test_twins_same(rbc_world_id wa, rbc_cloth_id ca, rbc_world_id wb,
                                  rbc_cloth_id cb, int frames, float dt) {
    for (int f = 0; f < frames; ++f) {
        CHECK_EQ(rbc_world_step(wa, dt), RBC_OK);
        CHECK_EQ(rbc_world_step(wb, dt), RBC_OK);
    }
    uint32_t na = 0, nb = 0;
    float *a = test_read(wa, ca, &na), *b = test_read(wb, cb, &nb);
    int same = a && b && na == nb && memcmp(a, b, sizeof(float) * 3 * na) == 0;
    free(a);
    free(b);
    return same;
}

/* rbc_world_get_stats as such a host calls it: the stats at the start of buf (buf_size
 * bytes, room after them) with struct_size `size`, buf marked with `mark` first.
 * Whether the call succeeded and wrote nothing past size. */
static inline int test_stats_sized(rbc_world_id w, void *buf, size_t buf_size, uint32_t size,
                                   unsigned char mark) {
    memset(buf, mark, buf_size);
    rbc_world_stats *s = (rbc_world_stats *)buf;
    s->struct_size = size;
    rbc_result r = rbc_world_get_stats(w, s);
    if (r != RBC_OK)
        fprintf(stderr, "test_stats_sized(%u): %s (%s)\n", (unsigned)size, rbc_result_string(r),
                rbc_last_error());
    return r == RBC_OK && test_bytes_are(buf, size, buf_size, mark);
}

/* The host's measure: RMS relative strain of cloth c of world w, and the largest
 * |relative strain| into *max_r. rest: the creation positions. */
static inline double test_host_strain(rbc_world_id w, rbc_cloth_id c, const float *rest, double *max_r) {
    size_t count = 0;
    CHECK_EQ(rbc_cloth_get_springs(w, c, NULL, 0, &count), RBC_OK);
    uint32_t *pairs = (uint32_t *)malloc(sizeof(uint32_t) * (count ? count : 1));
    CHECK_EQ(rbc_cloth_get_springs(w, c, pairs, count, &count), RBC_OK);
    uint32_t n = 0;
    float *p = test_read(w, c, &n);
    double sum = 0.0, m = 0.0, worst = 0.0;
    for (size_t k = 0; p && k < count / 2; k++) {
        uint32_t a = pairs[2 * k], b = pairs[2 * k + 1];
        double L = 0.0, len = 0.0;
        for (int d = 0; d < 3; d++) {
            double r = (double)rest[3 * a + d] - rest[3 * b + d];
            double e = (double)p[3 * a + d] - p[3 * b + d];
            L += r * r;
            len += e * e;
        }
        L = sqrt(L);
        len = sqrt(len);
        if (!(L > 0.0)) continue;
        double r = len / L - 1.0;
        sum += r * r;
        m += 1.0;
        if (fabs(r) > worst) worst = fabs(r);
    }
    free(p);
    free(pairs);
    if (max_r) *max_r = worst;
    return m > 0.0 ? sqrt(sum / m) : 0.0;
}

/* A snapshot of what a failing call must not change: the counts of the world's
 * stats and the positions of the listed cloths, byte for byte. */
#define TEST_SNAP_MAX_CLOTHS 4
typedef struct test_snap {
    rbc_world_id world;
    uint32_t cloth_count, collider_count, particle_count, spring_count, color_count;
    uint64_t step_count;
    uint32_t n_cloths;
    rbc_cloth_id cloths[TEST_SNAP_MAX_CLOTHS];
    uint32_t n[TEST_SNAP_MAX_CLOTHS];
    float *pos[TEST_SNAP_MAX_CLOTHS];
} test_snap;

static inline void test_snap_free(test_snap *s) {
    for (uint32_t k = 0; k < s->n_cloths; k++) {
        free(s->pos[k]);
        s->pos[k] = NULL;
    }
    s->n_cloths = 0;
}

static inline test_snap test_snap_take(rbc_world_id w, const rbc_cloth_id *cloths,
                                       uint32_t n_cloths) {
    test_snap s;
    memset(&s, 0, sizeof s);
    s.world = w;
    rbc_world_stats st = test_stats(w);
    s.cloth_count = st.cloth_count;
    s.collider_count = st.collider_count;
    s.particle_count = st.particle_count;
    s.spring_count = st.spring_count;
    s.color_count = st.color_count;
    s.step_count = st.step_count;
    s.n_cloths = n_cloths;
    for (uint32_t k = 0; k < n_cloths; k++) {
        s.cloths[k] = cloths[k];
        s.pos[k] = test_read(w, cloths[k], &s.n[k]);
    }
    return s;
}

/* Compare the world now with the snapshot; prints the differences with `line`
 * (the caller's source line) and returns 1 if identical. */
static inline int test_snap_same(const test_snap *s, int line) {
    test_snap now = test_snap_take(s->world, s->cloths, s->n_cloths);
    int same = 1;
#define TEST_SNAP_FIELD(f)                                                            \
    if (now.f != s->f) {                                                              \
        fprintf(stderr, "  line %d: world changed: %s %llu -> %llu\n", line, #f,       \
                (unsigned long long)s->f, (unsigned long long)now.f);                 \
        same = 0;                                                                     \
    }
    TEST_SNAP_FIELD(cloth_count)
    TEST_SNAP_FIELD(collider_count)
    TEST_SNAP_FIELD(particle_count)
    TEST_SNAP_FIELD(spring_count)
    TEST_SNAP_FIELD(color_count)
    TEST_SNAP_FIELD(step_count)
#undef TEST_SNAP_FIELD
    for (uint32_t k = 0; k < s->n_cloths; k++) {
        if (!now.pos[k] || !s->pos[k] || now.n[k] != s->n[k] ||
            memcmp(now.pos[k], s->pos[k], sizeof(float) * 3 * s->n[k]) != 0) {
            fprintf(stderr, "  line %d: world changed: positions of cloth %u differ\n", line,
                    (unsigned)s->cloths[k]);
            same = 0;
        }
    }
    test_snap_free(&now);
    return same;
}

/* ------------------------------------------------------------------------- */
/* The blocks of an allocator hook                                           */
/* ------------------------------------------------------------------------- */

/* The live blocks a test's allocator hook handed out, by pointer, with the size asked
 * for: open addressing (linear probing from a multiplicative hash's top bits,
 * backward-shift deletion) over arrays the test owns, of cap slots (a power of 2), so
 * that the table allocates nothing (test_cholmod_alloc counts every malloc). add and
 * remove hold the lock: the hooks are called from the world's threads. */
typedef struct test_blocks {
    pthread_mutex_t lock;
    void **ptr;
    size_t *size;
    size_t cap;
    unsigned shift; /* 64 - log2(cap) */
    size_t live, peak_live, allocs, frees, bytes;
    size_t bad_size, bad_ptr, table_full;
} test_blocks;
#define TEST_BLOCKS_INIT {.lock = PTHREAD_MUTEX_INITIALIZER}

/* Empties t (its lock aside) over ptr[cap] and size[cap], while no hook runs. */
static inline void test_blocks_reset(test_blocks *t, void **ptr, size_t *size, size_t cap) {
    memset(ptr, 0, sizeof *ptr * cap);
    memset(size, 0, sizeof *size * cap);
    t->ptr = ptr;
    t->size = size;
    t->cap = cap;
    t->shift = 64;
    for (size_t c = cap; c > 1; c >>= 1) t->shift--;
    t->live = t->peak_live = t->allocs = t->frees = t->bytes = 0;
    t->bad_size = t->bad_ptr = t->table_full = 0;
}

static inline size_t test_blocks_home(const test_blocks *t, const void *p) {
    uint64_t h = (uint64_t)(uintptr_t)p * 0x9E3779B97F4A7C15ull;
    return (size_t)(h >> t->shift) & (t->cap - 1);
}

/* Block p of `size` bytes was handed out; counted in table_full if no slot is free. */
static inline void test_blocks_add(test_blocks *t, void *p, size_t size) {
    pthread_mutex_lock(&t->lock);
    size_t k = test_blocks_home(t, p), tries = 0;
    while (t->ptr[k] && ++tries < t->cap) k = (k + 1) & (t->cap - 1);
    if (t->ptr[k]) {
        t->table_full++;
    } else {
        t->ptr[k] = p;
        t->size[k] = size;
        t->live++;
        t->allocs++;
        t->bytes += size;
        if (t->live > t->peak_live) t->peak_live = t->live;
    }
    pthread_mutex_unlock(&t->lock);
}

/* Block p is freed with `size`: 1 if it was live (it is no longer; a size other than
 * the one asked for is counted in bad_size, *asked gets that one), 0 if not (bad_ptr:
 * not one of the hook's, or freed twice). */
static inline int test_blocks_remove(test_blocks *t, const void *p, size_t size, size_t *asked) {
    pthread_mutex_lock(&t->lock);
    size_t k = test_blocks_home(t, p), tries = 0;
    while (t->ptr[k] != p && ++tries < t->cap) k = (k + 1) & (t->cap - 1);
    if (t->ptr[k] != p) {
        t->bad_ptr++;
        pthread_mutex_unlock(&t->lock);
        return 0;
    }
    if (asked) *asked = t->size[k];
    if (t->size[k] != size) t->bad_size++;
    t->live--;
    t->frees++;
    /* Backward-shift deletion keeps every other block findable from its home slot. */
    size_t hole = k;
    for (size_t j = (hole + 1) & (t->cap - 1); t->ptr[j]; j = (j + 1) & (t->cap - 1)) {
        size_t home = test_blocks_home(t, t->ptr[j]);
        if (((j - home) & (t->cap - 1)) >= ((j - hole) & (t->cap - 1))) {
            t->ptr[hole] = t->ptr[j];
            t->size[hole] = t->size[j];
            hole = j;
        }
    }
    t->ptr[hole] = NULL;
    pthread_mutex_unlock(&t->lock);
    return 1;
}

#endif
