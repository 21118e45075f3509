/* test_bad_input.c -- every bad input of the public ABI gets its own documented
 * error code, a non-empty rbc_last_error(), and leaves every existing object
 * exactly as it was (abi/rbcloth.h, "Conventions": "A failing call leaves every
 * existing object exactly as it was").
 *
 * A reference world W holds a pinned 8 x 8 cloth that has been stepped (so it
 * has a velocity) and a plane collider far below it. Every failing call is
 * followed by a comparison of W with a snapshot taken before: stats counts
 * (cloths, colliders, particles, springs, colors, steps) equal, and the
 * positions of the reference cloth equal byte for byte (memcmp, not a
 * tolerance: nothing at all may have moved).
 *
 * Which code is expected follows the header's definitions:
 *   RBC_ERR_INVALID_ARGUMENT  "an argument or a def field is out of its documented
 *                             range (NULL pointer, non-finite number, dt <= 0,
 *                             wrong struct_size, ...)"
 *   RBC_ERR_BAD_MESH          "index out of range, degenerate quad, ...": quads
 *                             and springs define the mesh/graph. A non-bipartite
 *                             graph is no longer one (ABI 1.1 colors it with
 *                             more colors); it is checked to be accepted.
 *   RBC_ERR_STALE_HANDLE      "destroyed, belongs to another world or is of
 *                             another kind".
 * Pins are not part of the mesh (they are a def field holding vertex numbers
 * whose range is the vertex count), so an out-of-range pin is
 * RBC_ERR_INVALID_ARGUMENT, like rbc_cloth_set_pin with an out-of-range vertex.
 */
#include <pthread.h>
#include <stddef.h>
#include <sys/stat.h>
#include <unistd.h>

#include "abi_util.h"
#include "files.h"

/* ------------------------------------------------------------------------- */
/* The reference world and the "nothing changed" check                       */
/* ------------------------------------------------------------------------- */

static rbc_world_id W;      /* reference world */
static rbc_cloth_id C;      /* its cloth: 8 x 8 grid, pins 0 and 7, stepped */
static rbc_collider_id K;   /* its plane collider at y = -10 */
static test_grid G;         /* the grid of C */
static test_snap S;         /* W as it must stay */

/* Other worlds that the current checks must leave as they were, besides W. */
static test_snap *EXTRA[2];
static int N_EXTRA;

static void resnap(void) {
    test_snap_free(&S);
    S = test_snap_take(W, &C, 1);
}

/* After a failing call: the code is the expected one, the message is not empty,
 * and W is unchanged. If W did change (the call wrongly succeeded or corrupted
 * state), the failure is reported once and the snapshot is retaken so later
 * checks are not a cascade of the same fault. */
static void after_fail(rbc_result got, rbc_result want, const char *what, int line) {
    CHECK_EQ(got, want);
    if (got != want)
        fprintf(stderr, "  line %d: %s: got %s (%d), want %s (%d); last_error \"%s\"\n", line,
                what, rbc_result_string(got), (int)got, rbc_result_string(want), (int)want,
                got == RBC_OK ? "(the call succeeded)" : rbc_last_error());
    const char *msg = rbc_last_error();
    CHECK(msg != NULL && msg[0] != '\0');
    if (!(msg != NULL && msg[0] != '\0'))
        fprintf(stderr, "  line %d: %s: rbc_last_error() is empty\n", line, what);
    int same = test_snap_same(&S, line);
    CHECK(same);
    if (!same) {
        fprintf(stderr, "  line %d: %s changed the reference world\n", line, what);
        resnap();
    }
    for (int k = 0; k < N_EXTRA; k++) {
        int same_k = test_snap_same(EXTRA[k], line);
        CHECK(same_k);
        if (!same_k) {
            fprintf(stderr, "  line %d: %s changed world %#x\n", line, what,
                    (unsigned)EXTRA[k]->world);
            test_snap fresh = test_snap_take(EXTRA[k]->world, EXTRA[k]->cloths,
                                             EXTRA[k]->n_cloths);
            test_snap_free(EXTRA[k]);
            *EXTRA[k] = fresh;
        }
    }
}

#define EXPECT(call, want) after_fail((call), (want), #call, __LINE__)

/* Calls that create something: if the call wrongly succeeds, destroy what it made
 * so the reference world goes back to its snapshot. */
static void try_world(const rbc_world_def *d, rbc_result want, const char *what, int line) {
    rbc_world_id w = 0;
    rbc_result r = rbc_world_create(d, &w);
    if (r == RBC_OK && w != 0) rbc_world_destroy(w);
    after_fail(r, want, what, line);
}
static void try_cloth(const rbc_cloth_def *d, rbc_result want, const char *what, int line) {
    rbc_cloth_id c = 0;
    rbc_result r = rbc_cloth_create(W, d, &c);
    if (r == RBC_OK && c != 0) rbc_cloth_destroy(W, c);
    after_fail(r, want, what, line);
}
static void try_collider(const rbc_collider_def *d, rbc_result want, const char *what,
                         int line) {
    rbc_collider_id k = 0;
    rbc_result r = rbc_collider_create(W, d, &k);
    if (r == RBC_OK && k != 0) rbc_collider_destroy(W, k);
    after_fail(r, want, what, line);
}
#define TRY_WORLD(d, want, what) try_world((d), (want), (what), __LINE__)
#define TRY_CLOTH(d, want, what) try_cloth((d), (want), (what), __LINE__)
#define TRY_COLLIDER(d, want, what) try_collider((d), (want), (what), __LINE__)

/* The message of the last error names the index (checked as a whole number). */
static void expect_message_names(unsigned long index, const char *what, int line) {
    const char *msg = rbc_last_error();
    int ok = msg && test_contains_number(msg, index);
    CHECK(ok);
    if (!ok)
        fprintf(stderr, "  line %d: %s: message \"%s\" does not name index %lu\n", line, what,
                msg ? msg : "(null)", index);
}
#define EXPECT_NAMES(index, what) expect_message_names((index), (what), __LINE__)

/* ------------------------------------------------------------------------- */
/* Result strings and the per-thread last error                              */
/* ------------------------------------------------------------------------- */

static void test_result_strings(void) {
    static const struct {
        rbc_result code;
        const char *name;
    } codes[] = {
        {RBC_OK, "RBC_OK"},
        {RBC_ERR_INVALID_ARGUMENT, "RBC_ERR_INVALID_ARGUMENT"},
        {RBC_ERR_OUT_OF_MEMORY, "RBC_ERR_OUT_OF_MEMORY"},
        {RBC_ERR_UNSUPPORTED, "RBC_ERR_UNSUPPORTED"},
        {RBC_ERR_BACKEND_UNAVAILABLE, "RBC_ERR_BACKEND_UNAVAILABLE"},
        {RBC_ERR_BAD_MESH, "RBC_ERR_BAD_MESH"},
        {RBC_ERR_IO, "RBC_ERR_IO"},
        {RBC_ERR_UNSTABLE, "RBC_ERR_UNSTABLE"},
        {RBC_ERR_STALE_HANDLE, "RBC_ERR_STALE_HANDLE"},
        {RBC_ERR_CALLBACK, "RBC_ERR_CALLBACK"},
        {RBC_ERR_CAPACITY, "RBC_ERR_CAPACITY"},
        {RBC_ERR_BUSY, "RBC_ERR_BUSY"},
    };
    const size_t n = sizeof codes / sizeof codes[0];
    for (size_t a = 0; a < n; a++) {
        const char *s = rbc_result_string(codes[a].code);
        CHECK(s != NULL);
        if (!s) continue;
        /* The header's example ("RBC_ERR_BAD_MESH") is the enumerator's name. */
        int named = strcmp(s, codes[a].name) == 0;
        CHECK(named);
        if (!named) fprintf(stderr, "  rbc_result_string(%d) = \"%s\", want \"%s\"\n",
                            (int)codes[a].code, s, codes[a].name);
        for (size_t b = 0; b < a; b++) {
            const char *t = rbc_result_string(codes[b].code);
            int distinct = t && strcmp(s, t) != 0;
            CHECK(distinct);
            if (!distinct) fprintf(stderr, "  codes %d and %d share the name \"%s\"\n",
                                   (int)codes[a].code, (int)codes[b].code, s);
        }
    }
    /* Codes that do not exist: "unknown result". */
    const rbc_result unknown[] = {1, -12, -100, RBC_RESULT_FORCE32, INT32_MIN};
    for (size_t k = 0; k < sizeof unknown / sizeof unknown[0]; k++) {
        const char *s = rbc_result_string(unknown[k]);
        CHECK(s != NULL && strcmp(s, "unknown result") == 0);
    }
}

typedef struct thread_probe {
    char before[256];       /* last_error in a fresh thread */
    rbc_result fail_code;   /* result of a failing call in that thread */
    char after[256];        /* its message afterwards */
} thread_probe;

static void *probe_thread(void *arg) {
    thread_probe *p = (thread_probe *)arg;
    snprintf(p->before, sizeof p->before, "%s", rbc_last_error());
    p->fail_code = rbc_world_step(0x7FFF0001u, 0.01f); /* made-up world id */
    snprintf(p->after, sizeof p->after, "%s", rbc_last_error());
    return NULL;
}

static void test_last_error_per_thread(void) {
    /* Main thread: make a distinctive error, then let another thread fail. */
    rbc_world_def d = abi_world_def_fixed();
    d.substeps = 1025;
    rbc_world_id w = 0;
    rbc_result r = rbc_world_create(&d, &w);
    CHECK_EQ(r, RBC_ERR_INVALID_ARGUMENT);
    char mine[256];
    snprintf(mine, sizeof mine, "%s", rbc_last_error());
    CHECK(mine[0] != '\0');

    thread_probe p;
    memset(&p, 0, sizeof p);
    pthread_t t;
    CHECK_EQ(pthread_create(&t, NULL, probe_thread, &p), 0);
    pthread_join(t, NULL);
    /* A thread that has had no error sees "" (not the main thread's message). */
    CHECK(strcmp(p.before, "") == 0);
    if (p.before[0]) fprintf(stderr, "  fresh thread sees last_error \"%s\"\n", p.before);
    CHECK_EQ(p.fail_code, RBC_ERR_STALE_HANDLE);
    CHECK(p.after[0] != '\0');
    /* ... and its failure did not replace the main thread's message. */
    CHECK(strcmp(rbc_last_error(), mine) == 0);
}

/* ------------------------------------------------------------------------- */
/* Defs: struct_size                                                         */
/* ------------------------------------------------------------------------- */

/* Defs are passed inside a larger zeroed buffer so a library that wrongly reads
 * struct_size bytes of an enlarged size reads our zeros, not beyond the object. */
typedef union big_world_def { rbc_world_def d; unsigned char pad[sizeof(rbc_world_def) + 64]; } big_world_def;
typedef union big_cloth_def { rbc_cloth_def d; unsigned char pad[sizeof(rbc_cloth_def) + 64]; } big_cloth_def;
typedef union big_collider_def { rbc_collider_def d; unsigned char pad[sizeof(rbc_collider_def) + 64]; } big_collider_def;
typedef union big_cache_def { rbc_cache_def d; unsigned char pad[sizeof(rbc_cache_def) + 64]; } big_cache_def;

static char TMPDIR_[256];

/* TMPDIR_/name (fmt's buffers: it stays valid for the next 15 paths). */
static const char *tmp_path(const char *name) { return fmt("%s/%s", TMPDIR_, name); }

/* The struct sizes a create refuses: 0; only the struct_size field; cut before the
 * last field (a prefix that is no released version); one field larger than this
 * header knows, and two. */
#define BAD_STRUCT_SIZES(T, last_field)                                                   \
    {0, 4, (uint32_t)offsetof(T, last_field), (uint32_t)sizeof(T) + 4,                    \
     (uint32_t)sizeof(T) + 8}

/* TRY (TRY_WORLD, ...) refuses def (an expression of type T, in a big_T with zeros
 * after it) at each of those sizes. */
#define TRY_STRUCT_SIZES(T, big_T, def, last_field, TRY, what)                             \
    do {                                                                                  \
        const uint32_t sizes_[] = BAD_STRUCT_SIZES(T, last_field);                        \
        for (size_t k_ = 0; k_ < sizeof sizes_ / sizeof sizes_[0]; k_++) {                \
            big_T b_;                                                                     \
            memset(&b_, 0, sizeof b_);                                                    \
            b_.d = (def);                                                                 \
            b_.d.struct_size = sizes_[k_];                                                \
            TRY(&b_.d, RBC_ERR_INVALID_ARGUMENT, what);                                   \
        }                                                                                 \
    } while (0)

static void test_struct_sizes(void) {
    TRY_STRUCT_SIZES(rbc_world_def, big_world_def, abi_world_def_fixed(), log_user, TRY_WORLD,
                     "world def struct_size");
    TRY_STRUCT_SIZES(rbc_cloth_def, big_cloth_def, test_grid_def(&G, NULL, 0), pins, TRY_CLOTH,
                     "cloth def struct_size");
    TRY_STRUCT_SIZES(rbc_collider_def, big_collider_def, rbc_collider_def_default(), rotation,
                     TRY_COLLIDER, "collider def struct_size");
    {
        const char *path = tmp_path("size.pc2");
        char tmp[520];
        snprintf(tmp, sizeof tmp, "%s.tmp", path);
        const uint32_t sizes[] = BAD_STRUCT_SIZES(rbc_cache_def, sample_rate);
        for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
            big_cache_def b;
            memset(&b, 0, sizeof b);
            b.d = rbc_cache_def_default();
            b.d.path = path;
            b.d.point_count = 4;
            b.d.struct_size = sizes[k];
            rbc_cache_id c = 0;
            rbc_result r = rbc_cache_create(&b.d, &c);
            if (r == RBC_OK && c != 0) rbc_cache_destroy(c);
            after_fail(r, RBC_ERR_INVALID_ARGUMENT, "cache def struct_size", __LINE__);
            /* A refused cache leaves no file behind. */
            CHECK(!exists(path) && !exists(tmp));
        }
    }
    /* *_def_init: a struct_size that is no released size, or a NULL def, is
     * refused and the host's buffer is left as it was (nothing written at all);
     * the released size writes exactly that many bytes. */
#define CHECK_DEF_INIT(T, fn, last_field)                                                 \
    do {                                                                                  \
        union { T d; unsigned char b[sizeof(T) + 16]; } u_;                               \
        const uint32_t bad_[] = {0, 4, (uint32_t)offsetof(T, last_field),                 \
                                 (uint32_t)sizeof(T) - 1, (uint32_t)sizeof(T) + 4};       \
        for (size_t k_ = 0; k_ < sizeof bad_ / sizeof bad_[0]; k_++) {                    \
            memset(&u_, 0xCD, sizeof u_);                                                 \
            EXPECT(fn(&u_.d, bad_[k_]), RBC_ERR_INVALID_ARGUMENT);                        \
            int untouched_ = 1;                                                           \
            for (size_t i_ = 0; i_ < sizeof u_; i_++) untouched_ &= u_.b[i_] == 0xCD;     \
            CHECK(untouched_);                                                            \
            if (!untouched_) fprintf(stderr, "  %s(size %u) refused but wrote the def\n",  \
                                     #fn, (unsigned)bad_[k_]);                            \
        }                                                                                 \
        EXPECT(fn(NULL, (uint32_t)sizeof(T)), RBC_ERR_INVALID_ARGUMENT);                  \
        memset(&u_, 0xCD, sizeof u_);                                                     \
        CHECK_EQ(fn(&u_.d, (uint32_t)sizeof(T)), RBC_OK);                                 \
        CHECK_EQ(u_.d.struct_size, sizeof(T));                                            \
        int tail_ = 1;                                                                    \
        for (size_t i_ = sizeof(T); i_ < sizeof u_; i_++) tail_ &= u_.b[i_] == 0xCD;      \
        CHECK(tail_);                                                                     \
    } while (0)
    CHECK_DEF_INIT(rbc_world_def, rbc_world_def_init, log_user);
    CHECK_DEF_INIT(rbc_cloth_def, rbc_cloth_def_init, pins);
    CHECK_DEF_INIT(rbc_collider_def, rbc_collider_def_init, rotation);
    CHECK_DEF_INIT(rbc_cache_def, rbc_cache_def_init, sample_rate);
#undef CHECK_DEF_INIT

    /* The defaults carry this header's sizes. */
    CHECK_EQ(rbc_world_def_default().struct_size, sizeof(rbc_world_def));
    CHECK_EQ(rbc_cloth_def_default().struct_size, sizeof(rbc_cloth_def));
    CHECK_EQ(rbc_collider_def_default().struct_size, sizeof(rbc_collider_def));
    CHECK_EQ(rbc_cache_def_default().struct_size, sizeof(rbc_cache_def));
}

/* ------------------------------------------------------------------------- */
/* NULL defs and out pointers                                                */
/* ------------------------------------------------------------------------- */

static void test_null_pointers(void) {
    rbc_world_id w = 0;
    rbc_cloth_id c = 0;
    rbc_collider_id k = 0;
    rbc_cache_id h = 0;
    rbc_world_def wd = abi_world_def_fixed();
    rbc_cloth_def cd = test_grid_def(&G, NULL, 0);
    rbc_collider_def kd = rbc_collider_def_default();
    rbc_cache_def hd = rbc_cache_def_default();
    const char *path = tmp_path("null.pc2");
    hd.path = path;
    hd.point_count = 4;

    EXPECT(rbc_world_create(NULL, &w), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_create(&wd, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_create(W, NULL, &c), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_create(W, &cd, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_collider_create(W, NULL, &k), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_collider_create(W, &kd, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cache_create(NULL, &h), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cache_create(&hd, NULL), RBC_ERR_INVALID_ARGUMENT);
    CHECK(!exists(path));
    EXPECT(rbc_world_get_stats(W, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_set_gravity(W, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_get_vertex_count(W, C, NULL), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_collider_set_transform(W, K, NULL, (const float[4]){0, 0, 0, 1}),
           RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_collider_set_transform(W, K, (const float[3]){0, 5, 0}, NULL),
           RBC_ERR_INVALID_ARGUMENT);
    /* Cache: a frame from NULL, and def path NULL. */
    {
        rbc_cache_def d2 = hd;
        d2.path = NULL;
        EXPECT(rbc_cache_create(&d2, &h), RBC_ERR_INVALID_ARGUMENT);
    }
    {
        rbc_cache_id ok = 0;
        CHECK_EQ(rbc_cache_create(&hd, &ok), RBC_OK);
        EXPECT(rbc_cache_write_frame(ok, NULL), RBC_ERR_INVALID_ARGUMENT);
        CHECK_EQ(rbc_cache_destroy(ok), RBC_OK);
        CHECK(!exists(path));
    }
}

/* ------------------------------------------------------------------------- */
/* World def fields                                                          */
/* ------------------------------------------------------------------------- */

static void *dummy_alloc(void *u, size_t s, size_t a) {
    (void)u; (void)a;
    return malloc(s);
}
static void dummy_free(void *u, void *p, size_t s) {
    (void)u; (void)s;
    free(p);
}

static void test_world_def(void) {
    const float bad[] = {NAN, INFINITY, -INFINITY};
    for (int axis = 0; axis < 3; axis++)
        for (int k = 0; k < 3; k++) {
            rbc_world_def d = abi_world_def_fixed();
            d.gravity[axis] = bad[k];
            TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "non-finite gravity");
        }
    {
        rbc_world_def d = abi_world_def_fixed();
        d.substeps = 0; /* from the rate (1.6): needs one */
        d.substep_rate = 0.0f;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "substeps 0 without a substep rate");
        d.substep_rate = 480.0f;
        d.substeps = 1025;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "substeps 1025");
    }
    {
        rbc_world_def d = abi_world_def_fixed();
        d.nonlinear_iterations = 0;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "nonlinear_iterations 0");
        d.nonlinear_iterations = 1025;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "nonlinear_iterations 1025");
    }
    {
        rbc_world_def d = abi_world_def_fixed();
        d.linear_iterations = 0;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "linear_iterations 0");
        d.linear_iterations = 4097;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "linear_iterations 4097");
    }
    {
        const rbc_backend unknown[] = {3, -1, 1000, RBC_BACKEND_FORCE32};
        for (size_t k = 0; k < sizeof unknown / sizeof unknown[0]; k++) {
            rbc_world_def d = abi_world_def_fixed();
            d.backend = unknown[k];
            TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "unknown backend");
        }
    }
    {
        rbc_world_def d = abi_world_def_fixed();
        d.alloc = dummy_alloc;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "alloc without free");
        d.alloc = NULL;
        d.free = dummy_free;
        TRY_WORLD(&d, RBC_ERR_INVALID_ARGUMENT, "free without alloc");
    }
    /* CUDA is valid: it either works (and says so) or is unavailable. */
    {
        rbc_world_def d = abi_world_def_fixed();
        d.backend = RBC_BACKEND_CUDA;
        rbc_world_id w = 0;
        rbc_result r = rbc_world_create(&d, &w);
        CHECK(r == RBC_OK || r == RBC_ERR_BACKEND_UNAVAILABLE);
        if (r == RBC_OK) {
            CHECK_EQ(test_stats(w).backend, RBC_BACKEND_CUDA);
            CHECK_EQ(rbc_world_destroy(w), RBC_OK);
        } else {
            CHECK(rbc_last_error()[0] != '\0');
        }
        CHECK(test_snap_same(&S, __LINE__));
    }
}

/* ------------------------------------------------------------------------- */
/* Cloth def fields                                                          */
/* ------------------------------------------------------------------------- */

/* A nu x nv quad torus (periodic both ways) embedded as a real torus (R = 1, r = 0.3,
 * so no quad is degenerate) is accepted in W with one u and one v edge per vertex
 * and `colors` colors; destroyed again, W as it was. */
static void check_torus(uint32_t nu, uint32_t nv, uint32_t colors_expected) {
    float *pos = (float *)malloc(sizeof(float) * 3 * nu * nv);
    uint32_t *quads = (uint32_t *)malloc(sizeof(uint32_t) * 4 * nu * nv);
    const double R = 1.0, r = 0.3, two_pi = 6.283185307179586;
    for (uint32_t j = 0; j < nv; j++)
        for (uint32_t i = 0; i < nu; i++) {
            double u = two_pi * i / nu, v = two_pi * j / nv;
            uint32_t k = i + nu * j;
            pos[3 * k + 0] = (float)((R + r * cos(v)) * cos(u));
            pos[3 * k + 1] = (float)(r * sin(v));
            pos[3 * k + 2] = (float)((R + r * cos(v)) * sin(u));
        }
    for (uint32_t j = 0; j < nv; j++)
        for (uint32_t i = 0; i < nu; i++) {
            uint32_t q = i + nu * j, i1 = (i + 1) % nu, j1 = (j + 1) % nv;
            quads[4 * q + 0] = i + nu * j;
            quads[4 * q + 1] = i1 + nu * j;
            quads[4 * q + 2] = i1 + nu * j1;
            quads[4 * q + 3] = i + nu * j1;
        }
    rbc_cloth_def d = rbc_cloth_def_default();
    d.vertex_count = nu * nv;
    d.positions = pos;
    d.quad_count = nu * nv;
    d.quads = quads;
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(W, &d, &c), RBC_OK);
    if (c) {
        uint32_t springs = 0, colors = 0;
        CHECK_EQ(rbc_cloth_get_topology(W, c, &springs, &colors), RBC_OK);
        CHECK_EQ(springs, 2 * nu * nv);
        CHECK_EQ(colors, colors_expected);
        CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
    }
    CHECK(test_snap_same(&S, __LINE__));
    free(pos);
    free(quads);
}

/* An 11 x 10 torus: its cycle around the 11 columns has odd length, so the spring
 * graph is not bipartite (docs/facts.md, Coloring: an 11 x 10 torus is not bipartite).
 * Since ABI 1.1 such a graph is colored with more colors instead of refused: it is
 * accepted with 3 (an odd cycle needs 3; 3 suffice here). The control, a 12 x 10
 * torus (even cycles both ways), is bipartite: red-black, 2 colors. */
static void test_torus(void) {
    check_torus(11, 10, 3);
    check_torus(12, 10, 2);
}

static void test_cloth_def(void) {
    /* A 20 x 20 grid to damage: 400 vertices, 361 quads. Indices used below are
     * distinctive three-digit numbers so the message check is meaningful. */
    test_grid g = test_grid_make(20, 20, 0.05f, 0.0f, 1.0f, 0.0f);
    const uint32_t nv = g.vertex_count, nq = g.quad_count;
    float *pos = (float *)malloc(sizeof(float) * 3 * nv);
    uint32_t *quads = (uint32_t *)malloc(sizeof(uint32_t) * 4 * nq);
    float *masses = (float *)malloc(sizeof(float) * nv);
#define RESET()                                                          \
    do {                                                                 \
        memcpy(pos, g.positions, sizeof(float) * 3 * nv);                \
        memcpy(quads, g.quads, sizeof(uint32_t) * 4 * nq);               \
        for (uint32_t k_ = 0; k_ < nv; k_++) masses[k_] = 1e-3f;         \
    } while (0)
    rbc_cloth_def base = rbc_cloth_def_default();
    base.vertex_count = nv;
    base.positions = pos;
    base.quad_count = nq;
    base.quads = quads;

    /* Control: the undamaged def is accepted (so each refusal below is caused by
     * the one thing changed). */
    RESET();
    {
        rbc_cloth_id c = 0;
        CHECK_EQ(rbc_cloth_create(W, &base, &c), RBC_OK);
        if (c) CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
        rbc_cloth_def d = base;
        d.masses = masses;
        c = 0;
        CHECK_EQ(rbc_cloth_create(W, &d, &c), RBC_OK);
        if (c) CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
        CHECK(test_snap_same(&S, __LINE__));
    }

    { rbc_cloth_def d = base; d.vertex_count = 0;
      TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "vertex_count 0"); }
    { rbc_cloth_def d = base; d.positions = NULL;
      TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "positions NULL"); }
    { rbc_cloth_def d = base; d.quads = NULL;
      TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "quads NULL with quad_count > 0"); }

    /* Non-finite positions: vertex 217, each coordinate. */
    const float nonfinite[] = {NAN, INFINITY, -INFINITY};
    for (int k = 0; k < 3; k++)
        for (int axis = 0; axis < 3; axis++) {
            RESET();
            pos[3 * 217 + axis] = nonfinite[k];
            TRY_CLOTH(&base, RBC_ERR_INVALID_ARGUMENT, "non-finite position");
            EXPECT_NAMES(217, "non-finite position of vertex 217");
        }

    /* Quad 293: an index out of range (= vertex_count, and far out). */
    const uint32_t out_of_range[] = {nv, nv + 1000, UINT32_MAX};
    for (size_t k = 0; k < 3; k++)
        for (int corner = 0; corner < 4; corner += 3) {
            RESET();
            quads[4 * 293 + corner] = out_of_range[k];
            TRY_CLOTH(&base, RBC_ERR_BAD_MESH, "quad index out of range");
            EXPECT_NAMES(293, "quad 293 out of range");
        }
    /* Quad 293 with a repeated index (a, b, a, d and a, a, c, d). */
    {
        RESET();
        quads[4 * 293 + 2] = quads[4 * 293 + 0];
        TRY_CLOTH(&base, RBC_ERR_BAD_MESH, "quad with repeated index (a b a d)");
        EXPECT_NAMES(293, "quad 293 repeated index");
        RESET();
        quads[4 * 293 + 1] = quads[4 * 293 + 0];
        TRY_CLOTH(&base, RBC_ERR_BAD_MESH, "quad with repeated index (a a c d)");
        EXPECT_NAMES(293, "quad 293 repeated index");
    }
    /* Quad 293 degenerate, zero area: four collinear vertices, and four
     * coincident vertices (distinct indices, same point). The four corner
     * vertices of quad 293 are moved; they belong to other quads too, which may
     * become degenerate as well, so only the code is required here. */
    {
        RESET();
        for (int c4 = 0; c4 < 4; c4++) {
            uint32_t v = quads[4 * 293 + c4];
            pos[3 * v + 0] = 0.5f + 0.1f * (float)c4;
            pos[3 * v + 1] = 1.0f;
            pos[3 * v + 2] = 0.5f;
        }
        TRY_CLOTH(&base, RBC_ERR_BAD_MESH, "degenerate quad (collinear)");
        RESET();
        for (int c4 = 0; c4 < 4; c4++) {
            uint32_t v = quads[4 * 293 + c4];
            pos[3 * v + 0] = 0.5f;
            pos[3 * v + 1] = 1.0f;
            pos[3 * v + 2] = 0.5f;
        }
        TRY_CLOTH(&base, RBC_ERR_BAD_MESH, "degenerate quad (coincident)");
    }
    /* A lone degenerate quad: one quad of four collinear vertices, nothing else,
     * so the message must name quad 0 ... and a lone non-degenerate quad as the
     * control. */
    {
        const float line4[12] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0};
        const float square[12] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
        const uint32_t q[4] = {0, 1, 2, 3};
        rbc_cloth_def d = rbc_cloth_def_default();
        d.vertex_count = 4;
        d.positions = line4;
        d.quad_count = 1;
        d.quads = q;
        TRY_CLOTH(&d, RBC_ERR_BAD_MESH, "single collinear quad");
        d.positions = square;
        rbc_cloth_id c = 0;
        CHECK_EQ(rbc_cloth_create(W, &d, &c), RBC_OK);
        if (c) CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
        CHECK(test_snap_same(&S, __LINE__));
    }

    /* Masses: vertex 341 NaN, Inf, 0, negative, -0. */
    {
        const float bad_mass[] = {NAN, INFINITY, 0.0f, -0.0f, -1e-3f};
        for (size_t k = 0; k < sizeof bad_mass / sizeof bad_mass[0]; k++) {
            RESET();
            masses[341] = bad_mass[k];
            rbc_cloth_def d = base;
            d.masses = masses;
            TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "bad mass in masses[]");
            EXPECT_NAMES(341, "bad mass of vertex 341");
        }
    }
    RESET();
    /* vertex_mass (used: masses NULL and density 0) and density. */
    /* base with `field` set to each of the values after `what`: refused. */
#define TRY_CLOTH_FIELD(field, what, ...)                                                 \
    do {                                                                                  \
        const float bad_[] = {__VA_ARGS__};                                               \
        for (size_t k_ = 0; k_ < sizeof bad_ / sizeof bad_[0]; k_++) {                    \
            rbc_cloth_def d_ = base;                                                      \
            d_.field = bad_[k_];                                                          \
            TRY_CLOTH(&d_, RBC_ERR_INVALID_ARGUMENT, what);                               \
        }                                                                                 \
    } while (0)
    TRY_CLOTH_FIELD(vertex_mass, "bad vertex_mass", 0.0f, -1e-4f, NAN, INFINITY);
    TRY_CLOTH_FIELD(density, "bad density", -1.0f, NAN, INFINITY);
    /* Stiffness zero / negative / non-finite; damping negative / non-finite. */
    TRY_CLOTH_FIELD(stiffness, "bad stiffness", 0.0f, -1.0f, NAN, INFINITY);
    TRY_CLOTH_FIELD(damping, "bad damping", -0.5f, NAN, INFINITY);
    /* Pins: an index out of range (entry 1 of 3), and NULL with pin_count > 0. */
    {
        uint32_t pins[3] = {0, nv, 19};
        rbc_cloth_def d = base;
        d.pin_count = 3;
        d.pins = pins;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "pin index out of range");
        pins[1] = UINT32_MAX;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "pin index UINT32_MAX");
        d.pins = NULL;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "pins NULL with pin_count > 0");
    }
    /* Extra springs: spring 2 of 3 out of range, a self-spring i-i, NULL, and a
     * diagonal (shear) spring, which closes a triangle with two quad edges: an
     * odd cycle, so the graph is not bipartite and takes 3 colors (ABI 1.1;
     * refused before). */
    {
        uint32_t springs[6] = {0, 1, 5, 25, 10, nv}; /* two quad edges, then 10-nv */
        rbc_cloth_def d = base;
        d.spring_count = 3;
        d.springs = springs;
        TRY_CLOTH(&d, RBC_ERR_BAD_MESH, "spring index out of range");
        {
            const char *m = rbc_last_error();
            int named = m && (test_contains_number(m, 2) || test_contains_number(m, nv));
            CHECK(named);
            if (!named) fprintf(stderr, "  spring message \"%s\" names neither spring 2 nor vertex %u\n", m, nv);
        }
        springs[5] = 10;
        TRY_CLOTH(&d, RBC_ERR_BAD_MESH, "spring i == i");
        d.springs = NULL;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "springs NULL with spring_count > 0");
        /* Control: extra springs that duplicate quad edges (0-1, 20-0) are fine
         * and merged: the spring count stays the structural count. */
        uint32_t dup[4] = {0, 1, 20, 0};
        d.springs = dup;
        d.spring_count = 2;
        rbc_cloth_id c = 0;
        CHECK_EQ(rbc_cloth_create(W, &d, &c), RBC_OK);
        if (c) {
            uint32_t ns = 0;
            CHECK_EQ(rbc_cloth_get_topology(W, c, &ns, NULL), RBC_OK);
            CHECK_EQ(ns, test_grid_spring_count(&g));
            CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
        }
        CHECK(test_snap_same(&S, __LINE__));
        uint32_t diag[2] = {0, 21}; /* (0,0)-(1,1): with 0-1 and 1-21, a triangle */
        d.springs = diag;
        d.spring_count = 1;
        c = 0;
        CHECK_EQ(rbc_cloth_create(W, &d, &c), RBC_OK); /* "diagonal spring (odd cycle)" */
        if (c) {
            uint32_t ns = 0, colors = 0;
            CHECK_EQ(rbc_cloth_get_topology(W, c, &ns, &colors), RBC_OK);
            CHECK_EQ(ns, test_grid_spring_count(&g) + 1);
            CHECK_EQ(colors, 3);
            CHECK_EQ(rbc_cloth_destroy(W, c), RBC_OK);
        }
        CHECK(test_snap_same(&S, __LINE__));
    }
    test_torus();
#undef TRY_CLOTH_FIELD
#undef RESET
    free(pos);
    free(quads);
    free(masses);
    test_grid_free(&g);
}

/* ------------------------------------------------------------------------- */
/* World calls: step, iterations, gravity                                    */
/* ------------------------------------------------------------------------- */

static void test_world_calls(void) {
    const float bad_dt[] = {0.0f, -0.0f, -0.01f, NAN, INFINITY, -INFINITY};
    for (size_t k = 0; k < sizeof bad_dt / sizeof bad_dt[0]; k++)
        EXPECT(rbc_world_step(W, bad_dt[k]), RBC_ERR_INVALID_ARGUMENT);

    /* substeps 0 (the rate) is valid for W, a 1.6 world: test_defaults.c refuses it
     * for a world from a 1.5 def. */
    EXPECT(rbc_world_set_iterations(W, 1, 0, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_set_iterations(W, 1, 1, 0), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_set_iterations(W, 1025, 1, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_set_iterations(W, 1, 1025, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_world_set_iterations(W, 1, 1, 4097), RBC_ERR_INVALID_ARGUMENT);
    /* Partially valid triples must not be half applied: set known counts, fail
     * with the first two changed, step, and check the step used the known ones. */
    CHECK_EQ(rbc_world_set_iterations(W, 2, 3, 5), RBC_OK);
    EXPECT(rbc_world_set_iterations(W, 7, 7, 0), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_world_step(W, 1.0f / 60.0f), RBC_OK);
    {
        rbc_world_stats st = test_stats(W);
        /* Totals over the substeps: 2 substeps, 2*3 non-linear, 2*3*5 linear. */
        CHECK_EQ(st.substeps, 2);
        CHECK_EQ(st.nonlinear_iterations, 6);
        CHECK_EQ(st.linear_iterations, 30);
    }
    CHECK_EQ(rbc_world_set_iterations(W, 1, 1, 11), RBC_OK);
    resnap();

    const float bad[] = {NAN, INFINITY, -INFINITY};
    for (int axis = 0; axis < 3; axis++)
        for (int k = 0; k < 3; k++) {
            float g[3] = {0.0f, -9.81f, 0.0f};
            g[axis] = bad[k];
            EXPECT(rbc_world_set_gravity(W, g), RBC_ERR_INVALID_ARGUMENT);
        }
    /* The refused gravity did not reach the world: one more step stays finite. */
    CHECK_EQ(rbc_world_step(W, 1.0f / 60.0f), RBC_OK);
    {
        uint32_t n = 0;
        float *p = test_read(W, C, &n);
        CHECK(p && test_all_finite(p, 3 * (size_t)n));
        free(p);
    }
    resnap();
}

/* ------------------------------------------------------------------------- */
/* Cloth calls: read_positions, set_pin, counts                              */
/* ------------------------------------------------------------------------- */

static void test_cloth_calls(void) {
    const uint32_t n = G.vertex_count;
    float *buf = (float *)malloc(sizeof(float) * 3 * n);
    size_t written = 12345;
    EXPECT(rbc_cloth_read_positions(W, C, buf, 3 * (size_t)n - 1, &written),
           RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_read_positions(W, C, buf, 0, &written), RBC_ERR_INVALID_ARGUMENT);
    /* NULL xyz: the count needed, and success. */
    written = 0;
    CHECK_EQ(rbc_cloth_read_positions(W, C, NULL, 0, &written), RBC_OK);
    CHECK_EQ(written, 3 * (size_t)n);
    CHECK_EQ(rbc_cloth_read_positions(W, C, NULL, 0, NULL), RBC_OK);
    /* Exact capacity works, a larger one too, and reports what was written. */
    written = 0;
    CHECK_EQ(rbc_cloth_read_positions(W, C, buf, 3 * (size_t)n, &written), RBC_OK);
    CHECK_EQ(written, 3 * (size_t)n);
    CHECK(memcmp(buf, S.pos[0], sizeof(float) * 3 * n) == 0);

    const float target[3] = {0.25f, 0.5f, 0.25f};
    EXPECT(rbc_cloth_set_pin(W, C, n, target), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_set_pin(W, C, UINT32_MAX, target), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_cloth_set_pin(W, C, n, NULL), RBC_ERR_INVALID_ARGUMENT);
    const float bad[] = {NAN, INFINITY, -INFINITY};
    for (int axis = 0; axis < 3; axis++)
        for (int k = 0; k < 3; k++) {
            float t[3] = {0.25f, 0.5f, 0.25f};
            t[axis] = bad[k];
            /* Vertex 0 is pinned: a refused target must leave the pin where it is. */
            EXPECT(rbc_cloth_set_pin(W, C, 0, t), RBC_ERR_INVALID_ARGUMENT);
        }
    /* The pins (0 and 7) are where they were after a step: nothing was half set. */
    CHECK_EQ(rbc_world_step(W, 1.0f / 60.0f), RBC_OK);
    {
        uint32_t nn = 0;
        float *p = test_read(W, C, &nn);
        CHECK(p && memcmp(p + 0, G.positions + 0, 3 * sizeof(float)) == 0);
        CHECK(p && memcmp(p + 3 * 7, G.positions + 3 * 7, 3 * sizeof(float)) == 0);
        CHECK(p && test_all_finite(p, 3 * (size_t)nn));
        free(p);
    }
    resnap();
    free(buf);
}

/* ------------------------------------------------------------------------- */
/* Colliders                                                                 */
/* ------------------------------------------------------------------------- */

static void test_collider_defs(void) {
    {
        const float bad_r[] = {0.0f, -0.0f, -0.5f, NAN, INFINITY};
        for (size_t k = 0; k < sizeof bad_r / sizeof bad_r[0]; k++) {
            rbc_collider_def d = rbc_collider_def_default();
            d.shape = RBC_SHAPE_SPHERE;
            d.radius = bad_r[k];
            TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "sphere radius <= 0 or non-finite");
        }
    }
    {
        const float bad_t[] = {-0.01f, NAN, INFINITY};
        for (size_t k = 0; k < 3; k++) {
            rbc_collider_def d = rbc_collider_def_default();
            d.shape = RBC_SHAPE_SPHERE;
            d.thickness = bad_t[k];
            TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "bad sphere thickness");
            d.shape = RBC_SHAPE_PLANE;
            TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "bad plane thickness");
        }
    }
    {
        const rbc_shape bad_shape[] = {0, 6, -1, RBC_SHAPE_FORCE32};
        for (size_t k = 0; k < 4; k++) {
            rbc_collider_def d = rbc_collider_def_default();
            d.shape = bad_shape[k];
            TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "unknown shape");
        }
    }
    {
        rbc_collider_def d = rbc_collider_def_default();
        d.position[1] = NAN;
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "NaN collider position");
        d = rbc_collider_def_default();
        const float bad_q[][4] = {{0, 0, 0, 2}, {0, 0, 0, 0}, {0, 0, 0, 0.5f},
                                  {0, 0, 0, NAN}, {1, 1, 1, 1}};
        for (size_t k = 0; k < 5; k++) {
            memcpy(d.rotation, bad_q[k], sizeof d.rotation);
            TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "non-unit quaternion in def");
        }
    }
    /* Controls: a plane ignores radius ("> 0 for spheres"), so radius 0 is fine for
     * a plane; a quaternion normalised in float (|q| = 1 within rounding) is
     * unit for any sane check. */
    {
        rbc_collider_def d = rbc_collider_def_default();
        d.shape = RBC_SHAPE_PLANE;
        d.radius = 0.0f;
        d.position[1] = -20.0f;
        float h = 0.3f;
        d.rotation[0] = sinf(h) * 0.6f;
        d.rotation[1] = 0.0f;
        d.rotation[2] = sinf(h) * 0.8f;
        d.rotation[3] = cosf(h);
        rbc_collider_id k = 0;
        CHECK_EQ(rbc_collider_create(W, &d, &k), RBC_OK);
        if (k) CHECK_EQ(rbc_collider_destroy(W, k), RBC_OK);
        CHECK(test_snap_same(&S, __LINE__));
    }

    /* set_transform: the plane K (at y = -10) must not move when refused. Every
     * refused call below carries a valid position (0, 5, 0): if it were applied,
     * the plane would lift the cloth above y = 5 on the next step. */
    const float up[3] = {0.0f, 5.0f, 0.0f};
    const float bad_q[][4] = {{0, 0, 0, 2}, {0, 0, 0, 0}, {0, 0, 0, 0.5f},
                              {NAN, 0, 0, 1}, {0, 0, 0, INFINITY}, {1, 1, 1, 1}};
    for (size_t k = 0; k < 6; k++)
        EXPECT(rbc_collider_set_transform(W, K, up, bad_q[k]), RBC_ERR_INVALID_ARGUMENT);
    const float ident[4] = {0, 0, 0, 1};
    const float bad_pos[][3] = {{NAN, 5, 0}, {0, INFINITY, 0}, {0, 5, -INFINITY}};
    for (size_t k = 0; k < 3; k++)
        EXPECT(rbc_collider_set_transform(W, K, bad_pos[k], ident), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_world_step(W, 1.0f / 60.0f), RBC_OK);
    {
        uint32_t n = 0;
        float *p = test_read(W, C, &n);
        float ymax = -INFINITY;
        for (uint32_t v = 0; p && v < n; v++) ymax = fmaxf(ymax, p[3 * v + 1]);
        /* The cloth hangs from pins at y = 1 and has fallen for a few frames; a
         * plane lifted to y = 5 would have put every vertex at y >= 5. */
        CHECK(p && ymax < 4.0f);
        free(p);
    }
    resnap();
}

/* ------------------------------------------------------------------------- */
/* Stale handles                                                             */
/* ------------------------------------------------------------------------- */

static void stale_cloth_calls(rbc_world_id w, rbc_cloth_id c, const char *what, int line) {
    uint32_t u = 0;
    size_t z = 0;
    float buf[3 * 64];
    const float t[3] = {0, 0, 0};
    after_fail(rbc_cloth_read_positions(w, c, buf, 3 * 64, &z), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_read_positions(w, c, NULL, 0, &z), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_get_vertex_count(w, c, &u), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_get_topology(w, c, &u, &u), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_set_pin(w, c, 0, t), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_set_pin(w, c, 0, NULL), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_destroy(w, c), RBC_ERR_STALE_HANDLE, what, line);
}

static void stale_collider_calls(rbc_world_id w, rbc_collider_id k, const char *what, int line) {
    const float p[3] = {0, 5, 0}, q[4] = {0, 0, 0, 1};
    after_fail(rbc_collider_set_transform(w, k, p, q), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_collider_destroy(w, k), RBC_ERR_STALE_HANDLE, what, line);
}

static int32_t noop_cb(void *u, rbc_world_id w, float dt, const rbc_collision_cloth *c,
                       uint32_t n) {
    return 0;
}

static void stale_world_calls(rbc_world_id w, const char *what, int line) {
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    const float g[3] = {0, -9.81f, 0};
    rbc_cloth_def cd = test_grid_def(&G, NULL, 0);
    rbc_collider_def kd = rbc_collider_def_default();
    rbc_cloth_id c = 0;
    rbc_collider_id k = 0;
    after_fail(rbc_world_step(w, 0.01f), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_set_iterations(w, 1, 1, 1), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_set_gravity(w, g), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_get_stats(w, &st), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_set_collision_callback(w, noop_cb, NULL), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_set_collision_callback(w, NULL, NULL), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_cloth_create(w, &cd, &c), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_collider_create(w, &kd, &k), RBC_ERR_STALE_HANDLE, what, line);
    after_fail(rbc_world_destroy(w), RBC_ERR_STALE_HANDLE, what, line);
}

/* Ids from another world. Two fresh worlds A and B get the same content (a
 * cloth, then a collider), so a library whose ids do not tell worlds apart hands
 * out equal ids in both. Each world must refuse the other's ids with
 * RBC_ERR_STALE_HANDLE and both must stay as they were. The worlds are rebuilt
 * for each direction and kind, so a library that wrongly acts on its own object
 * (e.g. destroys it) is reported once per case, and the reference world W is
 * not involved. */
static void foreign_case(int kind, int reverse) {
    rbc_world_def wd = abi_world_def_fixed();
    rbc_world_id w[2] = {0, 0};
    rbc_cloth_id c[2] = {0, 0};
    rbc_collider_id k[2] = {0, 0};
    rbc_cloth_def cd = test_grid_def(&G, NULL, 0);
    rbc_collider_def kd = rbc_collider_def_default();
    kd.position[1] = -10.0f;
    for (int i = 0; i < 2; i++) {
        CHECK_EQ(rbc_world_create(&wd, &w[i]), RBC_OK);
        CHECK_EQ(rbc_cloth_create(w[i], &cd, &c[i]), RBC_OK);
        CHECK_EQ(rbc_collider_create(w[i], &kd, &k[i]), RBC_OK);
    }
    test_snap sa = test_snap_take(w[0], &c[0], 1), sb = test_snap_take(w[1], &c[1], 1);
    EXTRA[0] = &sa;
    EXTRA[1] = &sb;
    N_EXTRA = 2;
    int from = reverse ? 1 : 0, other = 1 - from;
    if (kind == 0) {
        if (c[0] == c[1])
            fprintf(stderr, "  note: the first cloths of two worlds have the same id %#x\n",
                    (unsigned)c[0]);
        stale_cloth_calls(w[from], c[other], "cloth id of another world", __LINE__);
    } else {
        if (k[0] == k[1])
            fprintf(stderr, "  note: the first colliders of two worlds have the same id %#x\n",
                    (unsigned)k[0]);
        stale_collider_calls(w[from], k[other], "collider id of another world", __LINE__);
    }
    N_EXTRA = 0;
    test_snap_free(&sa);
    test_snap_free(&sb);
    rbc_world_destroy(w[0]);
    rbc_world_destroy(w[1]);
}

/* ABI 1.3: the new def fields and calls refuse bad input with a message naming the
 * field or index and change nothing. */
static int32_t RBC_CALL bad_contacts(void *user, rbc_world_id world, float dt,
                                     const rbc_collision_cloth *cloths, uint32_t count,
                                     rbc_contact_sink *sink) {
    (void)world;
    (void)dt;
    (void)count;
    const int *mode = user;
    rbc_host_contact c = {cloths[0].cloth, 0, {0, 1, 0}, -100.0f, 0.0f, {0, 0, 0}};
    if (*mode == 0) c.vertex = cloths[0].vertex_count;     /* out of range */
    if (*mode == 1) c.normal[1] = 2.0f;                    /* not unit */
    if (*mode == 2) c.cloth = 0x7fffffff;                  /* no such cloth */
    if (*mode == 3) c.offset = NAN;
    sink->add(sink, &c, 1);
    return 0;
}

static void test_v13(void) {
    /* Collider shapes and fields. */
    const float bad[] = {0.0f, -1.0f, NAN, INFINITY};
    for (size_t k = 0; k < 4; k++) {
        rbc_collider_def d = rbc_collider_def_default();
        d.shape = RBC_SHAPE_CAPSULE;
        d.radius = bad[k];
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "capsule radius");
        CHECK(strstr(rbc_last_error(), "radius") != NULL);
        d.radius = 0.1f;
        d.half_extents[1] = bad[k];
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "capsule half length");
        CHECK(strstr(rbc_last_error(), "half_extents[1]") != NULL);
        for (int a = 0; a < 3; a++) {
            rbc_collider_def b = rbc_collider_def_default();
            b.shape = RBC_SHAPE_BOX;
            b.half_extents[a] = bad[k];
            TRY_COLLIDER(&b, RBC_ERR_INVALID_ARGUMENT, "box half extent");
            CHECK(test_contains_number(rbc_last_error(), (unsigned long)a));
        }
        if (k > 0) {
            rbc_collider_def f = rbc_collider_def_default();
            f.friction = bad[k];
            TRY_COLLIDER(&f, RBC_ERR_INVALID_ARGUMENT, "collider friction");
            CHECK(strstr(rbc_last_error(), "friction") != NULL);
        }
    }
    {
        const float v[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
        const uint32_t t_bad[3] = {0, 1, 3};
        rbc_collider_def d = rbc_collider_def_default();
        d.shape = RBC_SHAPE_TRIANGLE_MESH;
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "mesh without arrays");
        d.mesh_positions = v;
        d.mesh_vertex_count = 3;
        d.mesh_triangles = t_bad;
        d.mesh_triangle_count = 1;
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "mesh index out of range");
        CHECK(test_contains_number(rbc_last_error(), 3));
        float vn[9] = {0, 0, 0, 1, 0, 0, 0, 0, 1};
        const uint32_t t_ok[3] = {0, 1, 2};
        vn[4] = NAN;
        d.mesh_positions = vn;
        d.mesh_triangles = t_ok;
        TRY_COLLIDER(&d, RBC_ERR_INVALID_ARGUMENT, "mesh NaN vertex");
        CHECK(test_contains_number(rbc_last_error(), 1));
    }
    /* Cloth def fields. */
    {
        rbc_cloth_def d = test_grid_def(&G, NULL, 0);
        d.thickness = -0.01f;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "negative thickness");
        d = test_grid_def(&G, NULL, 0);
        d.friction = NAN;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "NaN friction");
        d = test_grid_def(&G, NULL, 0);
        d.thickness = 0.01f;
        d.collision_flags = 4;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "unknown collision flag");
        d = test_grid_def(&G, NULL, 0);
        d.collision_flags = RBC_CLOTH_COLLIDE_SELF;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "self collision without thickness");
        CHECK(strstr(rbc_last_error(), "thickness") != NULL);
        d = test_grid_def(&G, NULL, 0);
        d.tear_strain = -0.5f;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "negative tear_strain");
        d.tear_strain = NAN;
        TRY_CLOTH(&d, RBC_ERR_INVALID_ARGUMENT, "NaN tear_strain");
        CHECK(strstr(rbc_last_error(), "tear_strain") != NULL);
    }
    /* Calls on the reference cloth C of world W. */
    {
        uint32_t pairs[4] = {0, 1, 2, G.vertex_count + 5};
        uint32_t cut = 99;
        EXPECT(rbc_cloth_cut(W, C, pairs, 2, &cut), RBC_ERR_INVALID_ARGUMENT);
        CHECK(test_contains_number(rbc_last_error(), G.vertex_count + 5));
        CHECK_EQ(cut, 0u);
        EXPECT(rbc_cloth_cut(W, C, NULL, 1, &cut), RBC_ERR_INVALID_ARGUMENT);
        uint32_t small[4];
        EXPECT(rbc_cloth_get_quads(W, C, small, 4, NULL), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_cloth_get_springs(W, C, small, 4, NULL), RBC_ERR_INVALID_ARGUMENT);
        const float o[3] = {0, 0, 0}, zero[3] = {0, 0, 0}, dn[3] = {0, NAN, 1};
        rbc_cloth_id got = 1;
        EXPECT(rbc_world_pick(W, o, zero, 1.0f, 0.1f, &got, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_world_pick(W, o, dn, 1.0f, 0.1f, &got, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
        const float d1[3] = {0, 0, 1};
        EXPECT(rbc_world_pick(W, o, d1, 1.0f, -0.1f, &got, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_world_pick(W, NULL, d1, 1.0f, 0.1f, &got, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_cloth_attach(W, C, G.vertex_count, K, NULL), RBC_ERR_INVALID_ARGUMENT);
        CHECK(test_contains_number(rbc_last_error(), G.vertex_count));
        const float nan3[3] = {NAN, 0, 0};
        EXPECT(rbc_cloth_attach(W, C, 0, K, nan3), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_cloth_attach(W, C, 0, 0x12345u, NULL), RBC_ERR_STALE_HANDLE);
        const float wv[3] = {1, 0, 0};
        EXPECT(rbc_world_set_wind(W, nan3, 0.5f, 0.0f), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_world_set_wind(W, wv, -0.5f, 0.0f), RBC_ERR_INVALID_ARGUMENT);
        EXPECT(rbc_world_set_wind(W, wv, 0.5f, NAN), RBC_ERR_INVALID_ARGUMENT);
    }
    /* A host contact that is wrong fails the step with RBC_ERR_CALLBACK naming it, and
     * the world is as it was. */
    for (int mode = 0; mode < 4; mode++) {
        int m = mode;
        CHECK_EQ(rbc_world_set_contact_callback(W, bad_contacts, &m), RBC_OK);
        EXPECT(rbc_world_step(W, 1.0f / 60.0f), RBC_ERR_CALLBACK);
        CHECK(strstr(rbc_last_error(), "contact callback") != NULL);
        CHECK_EQ(rbc_world_set_contact_callback(W, NULL, NULL), RBC_OK);
    }
}

static void test_foreign_ids(void) {
    for (int kind = 0; kind < 2; kind++)
        for (int reverse = 0; reverse < 2; reverse++) foreign_case(kind, reverse);
}

static void test_stale_handles(void) {
    /* A destroyed cloth; then a new cloth (which may reuse its slot): the old id
     * stays stale, the new one works, and they differ. */
    rbc_cloth_def cd = test_grid_def(&G, NULL, 0);
    rbc_cloth_id dead = 0;
    CHECK_EQ(rbc_cloth_create(W, &cd, &dead), RBC_OK);
    CHECK_EQ(rbc_cloth_destroy(W, dead), RBC_OK);
    stale_cloth_calls(W, dead, "destroyed cloth id", __LINE__);
    rbc_cloth_id fresh = 0;
    CHECK_EQ(rbc_cloth_create(W, &cd, &fresh), RBC_OK);
    CHECK(fresh != dead);
    resnap();
    stale_cloth_calls(W, dead, "destroyed cloth id after slot reuse", __LINE__);
    CHECK_EQ(rbc_cloth_destroy(W, fresh), RBC_OK);
    resnap();

    /* Ids of another kind: collider as cloth, world as cloth, cloth as collider,
     * world as collider, cloth/collider as world. */
    stale_cloth_calls(W, K, "collider id as cloth id", __LINE__);
    stale_cloth_calls(W, W, "world id as cloth id", __LINE__);
    stale_collider_calls(W, C, "cloth id as collider id", __LINE__);
    stale_collider_calls(W, W, "world id as collider id", __LINE__);
    stale_world_calls(C, "cloth id as world id", __LINE__);
    stale_world_calls(K, "collider id as world id", __LINE__);

    /* Made-up ids. */
    const uint32_t madeup[] = {0x7FFF1234u, 0xFFFFFFFFu, 0x00010001u ^ C, C + 1u, C + 0x10000u};
    for (size_t k = 0; k < sizeof madeup / sizeof madeup[0]; k++) {
        if (madeup[k] == C || madeup[k] == K || madeup[k] == W || madeup[k] == 0) continue;
        stale_cloth_calls(W, madeup[k], "made-up cloth id", __LINE__);
        stale_collider_calls(W, madeup[k], "made-up collider id", __LINE__);
        stale_world_calls(madeup[k], "made-up world id", __LINE__);
    }

    /* Ids from another world: see test_foreign_ids. W2 for the destroyed-world
     * checks below. */
    rbc_world_def wd = abi_world_def_fixed();
    rbc_world_id W2 = 0;
    CHECK_EQ(rbc_world_create(&wd, &W2), RBC_OK);
    rbc_cloth_def cd2 = test_grid_def(&G, NULL, 0);
    rbc_cloth_id C2 = 0;
    CHECK_EQ(rbc_cloth_create(W2, &cd2, &C2), RBC_OK);
    rbc_collider_def kd = rbc_collider_def_default();
    kd.position[1] = -10.0f;
    rbc_collider_id K2 = 0;
    CHECK_EQ(rbc_collider_create(W2, &kd, &K2), RBC_OK);
    /* Destroyed world: every world call, and its cloth/collider ids with it. */
    CHECK_EQ(rbc_world_destroy(W2), RBC_OK);
    stale_world_calls(W2, "destroyed world id", __LINE__);
    stale_cloth_calls(W2, C2, "cloth of a destroyed world", __LINE__);
    stale_collider_calls(W2, K2, "collider of a destroyed world", __LINE__);
    /* A new world may reuse the slot: the old id stays stale. */
    rbc_world_id W3 = 0;
    CHECK_EQ(rbc_world_create(&wd, &W3), RBC_OK);
    CHECK(W3 != W2);
    stale_world_calls(W2, "destroyed world id after slot reuse", __LINE__);
    CHECK_EQ(rbc_world_destroy(W3), RBC_OK);

    /* A destroyed collider. */
    rbc_collider_id deadk = 0;
    CHECK_EQ(rbc_collider_create(W, &kd, &deadk), RBC_OK);
    CHECK_EQ(rbc_collider_destroy(W, deadk), RBC_OK);
    stale_collider_calls(W, deadk, "destroyed collider id", __LINE__);

    /* The null id 0 is no object of any kind: refused (the header does not say
     * with which code, so any error). */
    {
        uint32_t u = 0;
        rbc_result r;
        r = rbc_world_step(0, 0.01f);
        CHECK(r < 0);
        r = rbc_world_destroy(0);
        CHECK(r < 0);
        r = rbc_cloth_get_vertex_count(W, 0, &u);
        CHECK(r < 0);
        r = rbc_cloth_destroy(W, 0);
        CHECK(r < 0);
        r = rbc_collider_destroy(W, 0);
        CHECK(r < 0);
        CHECK(test_snap_same(&S, __LINE__));
    }

    /* Cache ids: finished, destroyed, made-up and of another kind. */
    {
        const char *path = tmp_path("stale.pc2");
        rbc_cache_def hd = rbc_cache_def_default();
        hd.path = path;
        hd.point_count = 2;
        const float frame[6] = {0, 1, 2, 3, 4, 5};
        rbc_cache_id h = 0;
        CHECK_EQ(rbc_cache_create(&hd, &h), RBC_OK);
        CHECK_EQ(rbc_cache_write_frame(h, frame), RBC_OK);
        CHECK_EQ(rbc_cache_finish(h), RBC_OK);
        CHECK(exists(path));
        EXPECT(rbc_cache_write_frame(h, frame), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_finish(h), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_destroy(h), RBC_ERR_STALE_HANDLE);
        rbc_cache_id h2 = 0;
        CHECK_EQ(rbc_cache_create(&hd, &h2), RBC_OK);
        CHECK_EQ(rbc_cache_destroy(h2), RBC_OK);
        EXPECT(rbc_cache_write_frame(h2, frame), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_destroy(h2), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_write_frame(0x7FFF1234u, frame), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_write_frame(C, frame), RBC_ERR_STALE_HANDLE);
        EXPECT(rbc_cache_finish(W), RBC_ERR_STALE_HANDLE);
        unlink(path);
    }
}

/* ------------------------------------------------------------------------- */
/* Cache and OBJ writer arguments                                            */
/* ------------------------------------------------------------------------- */

static void test_writers(void) {
    const char *path = tmp_path("w.pc2");
    rbc_cache_def hd = rbc_cache_def_default();
    hd.path = path;
    hd.point_count = 0;
    rbc_cache_id h = 0;
    EXPECT(rbc_cache_create(&hd, &h), RBC_ERR_INVALID_ARGUMENT);
    hd.point_count = 2;
    hd.format = 7;
    EXPECT(rbc_cache_create(&hd, &h), RBC_ERR_INVALID_ARGUMENT);
    hd.format = RBC_CACHE_PC2;
    hd.sample_rate = NAN;
    EXPECT(rbc_cache_create(&hd, &h), RBC_ERR_INVALID_ARGUMENT);
    CHECK(!exists(path));
    /* A directory that does not exist: IO, at create or at the latest at finish. */
    {
        const char *nodir = tmp_path("no/such/dir/x.pc2");
        rbc_cache_def d = rbc_cache_def_default();
        d.path = nodir;
        d.point_count = 2;
        rbc_cache_id hh = 0;
        rbc_result r = rbc_cache_create(&d, &hh);
        if (r == RBC_OK) {
            const float f[6] = {0};
            rbc_result rw = rbc_cache_write_frame(hh, f);
            rbc_result rf = rbc_cache_finish(hh);
            CHECK(rw == RBC_ERR_IO || rf == RBC_ERR_IO);
            if (rf != RBC_ERR_IO && rw != RBC_ERR_IO) rbc_cache_destroy(hh);
        } else {
            after_fail(r, RBC_ERR_IO, "cache in a missing directory", __LINE__);
        }
    }

    const float xyz[12] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 1};
    const uint32_t q_ok[4] = {0, 1, 2, 3};
    const uint32_t q_bad[4] = {0, 1, 2, 4};
    const char *obj = tmp_path("m.obj");
    EXPECT(rbc_write_obj(NULL, xyz, 4, q_ok, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_write_obj(obj, NULL, 4, q_ok, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_write_obj(obj, xyz, 4, NULL, 1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_write_obj(obj, xyz, 4, q_bad, 1), RBC_ERR_BAD_MESH);
    CHECK(!exists(obj));
    const char *nodir = tmp_path("no/such/dir/m.obj");
    EXPECT(rbc_write_obj(nodir, xyz, 4, q_ok, 1), RBC_ERR_IO);
    /* Control: the same call with a good path works. */
    CHECK_EQ(rbc_write_obj(obj, xyz, 4, q_ok, 1), RBC_OK);
    CHECK(exists(obj));
    unlink(obj);
}

/* ------------------------------------------------------------------------- */

/* Solver def d is refused by rbc_world_set_solver and, in a world def, by
 * rbc_world_create, each time with a message naming `field`. */
static void refuse_target_def(const rbc_solver_def *d, const char *field, const char *what,
                              int line) {
    after_fail(rbc_world_set_solver(W, d), RBC_ERR_INVALID_ARGUMENT, "rbc_world_set_solver",
               line);
    CHECK(strstr(rbc_last_error(), field) != NULL);
    rbc_world_def wd = abi_world_def_fixed();
    wd.solver = d;
    try_world(&wd, RBC_ERR_INVALID_ARGUMENT, what, line);
    CHECK(strstr(rbc_last_error(), field) != NULL);
}

/* ABI 1.4: the target error mode's fields and the presets. Each bad value is refused
 * by rbc_world_set_solver (the settings in use stay as they were) and by
 * rbc_world_create, with a message naming the field. */
static void test_v14(void) {
    rbc_solver_def before;
    before.struct_size = sizeof before;
    CHECK_EQ(rbc_world_get_solver(W, &before), RBC_OK);
    const float bad_target[] = {0.0f, -0.05f, NAN, INFINITY, -INFINITY};
    for (size_t k = 0; k < sizeof bad_target / sizeof bad_target[0]; k++) {
        rbc_solver_def d = rbc_solver_def_default();
        d.mode = RBC_ITERATE_TARGET;
        d.target_strain = bad_target[k];
        refuse_target_def(&d, "target_strain", "world with a bad target_strain", __LINE__);
    }
    const uint32_t bad_cap[] = {0, 1025, 0xFFFFFFFFu};
    for (size_t k = 0; k < sizeof bad_cap / sizeof bad_cap[0]; k++) {
        rbc_solver_def d = rbc_solver_def_default();
        d.mode = RBC_ITERATE_TARGET;
        d.max_substeps = bad_cap[k];
        refuse_target_def(&d, "max_substeps", "world with a bad max_substeps", __LINE__);
    }
    {   /* the other cap of the mode: max_linear_iterations 0 */
        rbc_solver_def d = rbc_solver_def_default();
        d.mode = RBC_ITERATE_TARGET;
        d.max_linear_iterations = 0;
        EXPECT(rbc_world_set_solver(W, &d), RBC_ERR_INVALID_ARGUMENT);
        CHECK(strstr(rbc_last_error(), "max_linear_iterations") != NULL);
        d = rbc_solver_def_default();
        d.mode = RBC_ITERATE_TARGET + 1;
        EXPECT(rbc_world_set_solver(W, &d), RBC_ERR_INVALID_ARGUMENT);
        CHECK(strstr(rbc_last_error(), "mode") != NULL);
    }
    rbc_solver_def after;
    after.struct_size = sizeof after;
    CHECK_EQ(rbc_world_get_solver(W, &after), RBC_OK);
    CHECK(memcmp(&before, &after, sizeof before) == 0);

    /* Presets: an unknown one, a NULL def, a size that is no release, and the game
     * preset into a 1.3 def (its fields would not fit): nothing is written. */
    rbc_solver_def d;
    memset(&d, 0xAB, sizeof d);
    EXPECT(rbc_solver_def_preset(&d, sizeof d, (rbc_preset)3), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "preset") != NULL);
    EXPECT(rbc_solver_def_preset(&d, sizeof d, (rbc_preset)-1), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_solver_def_preset(NULL, sizeof d, RBC_PRESET_GAME_60HZ), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_solver_def_preset(&d, 12, RBC_PRESET_GAME_60HZ), RBC_ERR_INVALID_ARGUMENT);
    EXPECT(rbc_solver_def_preset(&d, RBC_SOLVER_DEF_SIZE_V1_2, RBC_PRESET_GAME_60HZ),
           RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "1.4") != NULL);
    EXPECT(rbc_solver_def_preset(&d, RBC_SOLVER_DEF_SIZE_V1_2, RBC_PRESET_CLOTH),
           RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "RBC_PRESET_CLOTH") != NULL);
    const unsigned char *b = (const unsigned char *)&d;
    int untouched = 1;
    for (size_t k = 0; k < sizeof d; k++) untouched &= b[k] == 0xAB;
    CHECK(untouched);
}

int main(void) {
    /* Before any error on this thread: "" (header: "" if none yet). */
    CHECK(rbc_last_error() != NULL && strcmp(rbc_last_error(), "") == 0);
    CHECK_EQ(rbc_abi_version(), RBC_ABI_VERSION);

    snprintf(TMPDIR_, sizeof TMPDIR_, "/tmp/rbc_bad_input_XXXXXX");
    if (!mkdtemp(TMPDIR_)) {
        perror("mkdtemp");
        return 2;
    }

    test_result_strings();
    test_last_error_per_thread();

    /* The reference world: an 8 x 8 cloth (pins 0 and 7) and a plane at y = -10,
     * stepped three times so positions and velocities are non-trivial. */
    rbc_world_def wd = abi_world_def_fixed();
    wd.thread_count = 1;
    if (rbc_world_create(&wd, &W) != RBC_OK) {
        fprintf(stderr, "cannot create the reference world: %s\n", rbc_last_error());
        return 1;
    }
    G = test_grid_make(8, 8, 0.1f, 0.0f, 1.0f, 0.0f);
    const uint32_t pins[2] = {0, 7};
    rbc_cloth_def cd = test_grid_def(&G, pins, 2);
    if (rbc_cloth_create(W, &cd, &C) != RBC_OK) {
        fprintf(stderr, "cannot create the reference cloth: %s\n", rbc_last_error());
        return 1;
    }
    rbc_collider_def kd = rbc_collider_def_default();
    kd.position[1] = -10.0f;
    CHECK_EQ(rbc_collider_create(W, &kd, &K), RBC_OK);
    for (int k = 0; k < 3; k++) CHECK_EQ(rbc_world_step(W, 1.0f / 60.0f), RBC_OK);
    S = test_snap_take(W, &C, 1);
    CHECK(S.pos[0] != NULL);
    CHECK_EQ(S.cloth_count, 1);
    CHECK_EQ(S.collider_count, 1);

    test_struct_sizes();
    test_null_pointers();
    test_world_def();
    test_cloth_def();
    test_world_calls();
    test_cloth_calls();
    test_collider_defs();
    test_v13();
    test_v14();
    test_stale_handles();
    test_foreign_ids();
    test_writers();

    CHECK_EQ(rbc_world_destroy(W), RBC_OK);
    {
        rbc_result r = rbc_world_step(W, 0.01f);
        CHECK_EQ(r, RBC_ERR_STALE_HANDLE);
    }
    test_snap_free(&S);
    test_grid_free(&G);
    rmdir(TMPDIR_);
    return check_report("abi_bad_input");
}
