/* clothcontact.c -- cloth-cloth and self contacts (see clothcontact.h).
 *
 * Detection, per substep:
 *  1. boxes: the swept box (x..p) of every vertex and triangle of the bodies that
 *     collide at all;
 *  2. two spatial hashes over one uniform grid of cell size
 *     max(2 (thickness + margin), mean longest triangle edge at x): triangles, in
 *     patches (cc_patches), by the patch's swept box grown by the largest thickness +
 *     margin, and vertices by theirs
 *     grown by thickness + margin / 2 (for vertex-vertex pairs). A cell's integer
 *     coordinates are hashed to a bucket; a counting sort puts the objects of every
 *     cell into one flat table, bucket by bucket, in object order;
 *  3. every vertex looks up the buckets of the cells its own box covers and tests the
 *     boxes exactly (a patch's, then its triangles'; this also drops the objects of
 *     other cells that share a bucket).
 *     A pair whose boxes share several cells is taken only in the cell holding the
 *     lower corner of the boxes' intersection, so it is seen once and no set is
 *     needed (an object in two cells of one bucket can still be seen twice: the sort
 *     below drops the copy);
 *  4. exact tests: bounds from each triangle's boxes and planes at x and at p
 *     (computed once per triangle) reject most pairs before a corner is read; then
 *     the rest exclusion, and closest points for distance at x, the plane crossing
 *     and distance at p. The vertex's contacts are sorted by partner, so the list
 *     does not depend on the cell size, the table size or the order of a bucket.
 *  5. edge-edge: each border edge looks up the triangle hash with its own swept box
 *     and tests the edges of the triangles found (once each: a sorted set per
 *     border edge).
 * A box over more than CC_BIG_CELLS cells (a vertex moving many cells in one
 * substep, a non-finite position) is not hashed: it is tested against everything. A
 * query over more cells than its hash's scan_cells (at most CC_BIG_CELLS, fewer when
 * the buckets are crowded) tests every object in order instead of reading buckets.
 */
#include "clothcontact.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../abi/rbcloth.h"

/* Boxes over more cells than this are tested by brute force: a hash lookup over a
 * huge box costs more than the scan, and the table stays O(objects). */
#define CC_BIG_CELLS 512u
/* Cell coordinates are clamped to +-(2^20 - 1) and packed in 21 bits each. */
#define CC_CELL_OFF (1 << 20)
#define CC_CELL_MAX ((1 << 20) - 1)

/* A buffer that only grows (by half its size at least), kept between steps. */
typedef struct cc_buf {
    void *ptr;
    size_t bytes;
} cc_buf;

typedef struct cc_hash {
    cc_buf start;               /* uint32 [nb + 1]: bucket b holds entries start[b] .. start[b+1]-1 */
    cc_buf id;                  /* uint32 [entries]: object */
    cc_buf big;                 /* uint32 [objects]: boxes too big to hash, ascending */
    uint32_t nb, big_count;
    uint32_t scan_cells;        /* a query over more cells scans every object (hash_build) */
} cc_hash;

/* Patches: runs of up to CC_PATCH consecutive triangles of one body, at most
 * CC_PATCH_CELLS cells across in any axis (a mesh whose triangles are not in spatial
 * order gets patches of one), with the union of their boxes (patches_build). The
 * hashes hold patches, not triangles: in a pile of flat layers a query's cells hold
 * the triangles of the layers above and below it, whose boxes it does not meet (the
 * four layers at rest: 16,384 vertex queries read 1.16 million triangles a substep
 * and 48,132 fail-safe edge queries 2.7 million, and not one box met), and a
 * patch's box rejects a row of them at once. */
typedef struct cc_patches {
    cc_buf start;               /* uint32 [n + 1]: first triangle (global) of a patch */
    cc_buf body;                /* uint32 [n]: its body */
    cc_buf box;                 /* float [6 per patch]: the union of its triangles' boxes */
    uint32_t n;
} cc_patches;

/* The contact pass on several threads (group_contacts): at most this many slabs
 * of the scene, each at least CC_SLAB_MIN contacts, and the histogram that cuts
 * them. */
#define CC_SLABS 16u
#define CC_SLAB_MIN 2048u
#define CC_SLAB_BINS 1024u
/* Groups: one per slab, one per pair of neighbouring slabs, and the rest. */
#define CC_GROUPS (2u * CC_SLABS)

struct rbc_clothcontact {
    rbc_allocator alloc;
    uint32_t body_count;        /* of the last detect */
    float cell, inv_cell;
    float tri_grow;             /* largest thickness + margin: what triangle boxes are grown by */
    cc_buf vbase, tbase;        /* uint32 [count + 1]: first global vertex / triangle of a body */
    cc_buf bgrow;               /* float [count]: thickness + margin / 2 (vertex hash) */
    cc_buf active;              /* uint8 [count]: 1 if the body collides at all */
    cc_buf vbox, tbox;          /* float [6 per object]: swept box lo[3], hi[3] */
    cc_buf bbox;                /* float [6 per body]: its vertices' grown swept boxes */
    cc_buf vbody, tbody;        /* uint32 [object]: its body */
    cc_buf trec;                /* float [CC_TREC per triangle]: see tri_record() */
    cc_hash th, vh;             /* triangle patches (tp) by their swept boxes; vertices */
    cc_hash fh;                 /* patches (fp) by their boxes at p: the fail-safe's round 0 */
    cc_patches tp, fp;
    cc_buf contacts;            /* rbc_contact, ordered by color (color_contacts) */
    uint32_t count;
    /* The list's groups (group_contacts): groups of one phase share no particle, so
     * threads project them at once with the serial pass's result. */
    cc_buf cslab;               /* uint8 [vertices]: a particle's slab */
    cc_buf cscratch;            /* rbc_contact [count]: the list before its sort by group */
    cc_buf cgroup;              /* uint8 [count]: each contact's group, in detection order */
    uint32_t gstart[CC_GROUPS + 1]; /* first contact of group g; [CC_GROUPS]: count */
    uint32_t phase[4];          /* first group of phases 1-3 and of the rest (phase[3]
                                   .. CC_GROUPS - 1 is one group: thread 0's) */
    uint32_t gk;                /* slabs of the sort in progress (0: none) */
    cc_buf gcount;              /* uint32 [threads x CC_GROUPS]: counts, then slots */
    /* Border edges (in one triangle only) of every body, kept while the bodies'
     * triangles stay the same (checked by pointer, count and vertex count). */
    cc_buf ebase;               /* uint32 [count + 1]: first border edge of a body */
    cc_buf bedge;               /* uint32 [2 per border edge]: its ends, local indices */
    cc_buf ekey;                /* cc_ekey [count]: what the border edges were found from */
    cc_buf escratch;            /* uint64 [3 per triangle of one body]: sort keys */
    cc_buf abase;               /* uint32 [count + 1]: first edge of a body (all edges) */
    cc_buf aedge;               /* uint32 [2 per edge]: every edge's ends, ascending */
    cc_buf eborder;             /* uint8 [edges]: 1 for a border edge */
    cc_buf tedge;               /* uint32 [3 per triangle, global]: the global index of
                                   its edge k (from corner k), CC_TEDGE_FIRST set in the
                                   first triangle that has it */
    int any_self;               /* a body of the last detect collides with itself */
    cc_buf frozen;              /* uint8 [vertices]: the fail-safe put it back to x */
    cc_buf pbox;                /* float [6 per triangle]: its box at p, in a fail-safe round */
    /* The fail-safe's impact zones (per vertex, global): union-find parent (UINT32_MAX:
     * in none), p before the fail-safe, the zones' vertices in the order they joined,
     * and per root the mass-weighted sum of p - x (x, y, z, mass) and flags. */
    cc_buf zparent, zp0, zlist, zsum, zflag;
    uint32_t zcount;
    uint32_t capped;            /* vertices whose contacts the last detect cut to the cap */
    /* Threads: each detects the contacts of its share of the vertices into its own
     * lists, and scans its share of the edges in a fail-safe round. */
    cc_buf parts;               /* cc_part [part_cap] */
    uint32_t part_cap;
    const rbc_contact_body *dbodies; /* of the detect or fail-safe in progress */
    float dmargin;
    size_t dcap;                /* most contacts (RBC_CC_MAX_TOTAL_PER_VERTEX per vertex) */
    int32_t stage_rc;           /* what thread 0's stage of a detect found */
    uint32_t fs_newly;          /* vertices the last fail-safe round moved */
    int regrow;                 /* thread 0 grew a thread's full list: run the stage again */
    uint32_t ekey_count;
};

#define CC_TEDGE_FIRST 0x80000000u

/* One thread's lists. */
typedef struct cc_part {
    cc_buf vt, vv;              /* rbc_contact: its vertices' vertex-triangle and -vertex ones */
    cc_buf ee;                  /* rbc_contact: its edges' edge-edge ones within a body */
    cc_buf nearest;             /* cc_key: keep_nearest's scratch */
    cc_buf hits;                /* uint32 [4 per crossing]: body, edge ends, triangle (global) */
    uint32_t nvt, nvv, nee, nhits, capped;
    int oom, over;
    /* Threads never allocate (the host's allocator hooks are called on the thread
     * that called rbc_world_step only): a list that is full counts what did not fit,
     * and thread 0 grows it to that and the stage runs again. */
    int full;                   /* something did not fit this time */
    uint64_t raw_vt, raw_vv, raw_ee; /* contacts pushed (copies included) */
    uint64_t need_ee;           /* edge-edge pushes, at most the cap per edge */
    uint64_t need_vt, need_vv;  /* what the lists need: the pushes, at most the cap per
                                   vertex, plus the longest run (kept until it is cut) */
    uint32_t near_need;         /* longest run of one vertex (keep_nearest's scratch) */
    uint32_t ee_run;            /* most edge-edge contacts one patch found (before the cap) */
    uint32_t hits_need;         /* crossings found in a fail-safe scan */
    char pad[64];               /* no false sharing of the counts */
} cc_part;

typedef struct cc_ekey {
    const uint32_t *tris;
    uint32_t tri_count, n;
} cc_ekey;

static int buf_reserve(const rbc_allocator *a, cc_buf *b, size_t count, size_t elem,
                       size_t keep_bytes) {
    size_t need = rbc_mul_size(count, elem);
    if (need <= b->bytes) return 1;
    if (need == SIZE_MAX) return 0;
    size_t nb = b->bytes + b->bytes / 2;
    if (nb < need) nb = need;
    if (nb < 256) nb = 256;
    void *p = rbc_mem_alloc(a, nb);
    if (!p) return 0;
    if (keep_bytes) memcpy(p, b->ptr, keep_bytes);
    rbc_mem_free(a, b->ptr, b->bytes);
    b->ptr = p;
    b->bytes = nb;
    return 1;
}

static void buf_free(const rbc_allocator *a, cc_buf *b) {
    rbc_mem_free(a, b->ptr, b->bytes);
    b->ptr = NULL;
    b->bytes = 0;
}

int32_t rbc_clothcontact_create(const rbc_allocator *a, rbc_clothcontact **out) {
    *out = NULL;
    rbc_clothcontact *cc = rbc_mem_alloc(a, sizeof *cc);
    if (!cc) return RBC_ERR_OUT_OF_MEMORY;
    cc->alloc = *a;
    *out = cc;
    return RBC_OK;
}

static void hash_free(const rbc_allocator *a, cc_hash *h) {
    buf_free(a, &h->start);
    buf_free(a, &h->id);
    buf_free(a, &h->big);
}

void rbc_clothcontact_destroy(rbc_clothcontact *cc) {
    if (!cc) return;
    const rbc_allocator a = cc->alloc;
    cc_buf *bufs[] = {&cc->vbase, &cc->tbase, &cc->bgrow, &cc->active, &cc->vbox,
                      &cc->tbox, &cc->vbody, &cc->tbody, &cc->trec, &cc->contacts,
                      &cc->bbox, &cc->ebase, &cc->bedge, &cc->ekey, &cc->escratch,
                      &cc->abase, &cc->aedge, &cc->frozen, &cc->pbox, &cc->zparent,
                      &cc->zp0, &cc->zlist, &cc->zsum, &cc->zflag, &cc->tp.start,
                      &cc->tp.body, &cc->tp.box, &cc->fp.start, &cc->fp.body, &cc->fp.box,
                      &cc->eborder, &cc->tedge, &cc->cslab, &cc->cscratch, &cc->cgroup, &cc->gcount};
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; ++k) buf_free(&a, bufs[k]);
    cc_part *parts = cc->parts.ptr;
    for (uint32_t t = 0; t < cc->part_cap; ++t) {
        buf_free(&a, &parts[t].vt);
        buf_free(&a, &parts[t].vv);
        buf_free(&a, &parts[t].ee);
        buf_free(&a, &parts[t].nearest);
        buf_free(&a, &parts[t].hits);
    }
    buf_free(&a, &cc->parts);
    hash_free(&a, &cc->th);
    hash_free(&a, &cc->vh);
    hash_free(&a, &cc->fh);
    rbc_mem_free(&a, cc, sizeof *cc);
}

uint32_t rbc_clothcontact_count(const rbc_clothcontact *cc) { return cc->count; }

uint32_t rbc_clothcontact_capped(const rbc_clothcontact *cc) { return cc->capped; }

const rbc_contact *rbc_clothcontact_list(const rbc_clothcontact *cc) {
    return (const rbc_contact *)cc->contacts.ptr;
}

size_t rbc_clothcontact_bytes(const rbc_clothcontact *cc) {
    const cc_buf *bufs[] = {&cc->vbase, &cc->tbase, &cc->bgrow, &cc->active, &cc->vbox,
                            &cc->tbox, &cc->vbody, &cc->tbody, &cc->contacts, &cc->bbox,
                            &cc->trec, &cc->th.start, &cc->th.id, &cc->th.big,
                            &cc->vh.start, &cc->vh.id, &cc->vh.big, &cc->ebase, &cc->bedge,
                            &cc->ekey, &cc->escratch, &cc->abase, &cc->aedge, &cc->frozen,
                            &cc->parts, &cc->pbox, &cc->fh.start, &cc->fh.id, &cc->fh.big,
                            &cc->zparent, &cc->zp0, &cc->zlist, &cc->zsum, &cc->zflag,
                            &cc->tp.start, &cc->tp.body, &cc->tp.box, &cc->fp.start,
                            &cc->fp.body, &cc->fp.box, &cc->eborder, &cc->tedge,
                            &cc->cslab, &cc->cscratch, &cc->cgroup, &cc->gcount};
    size_t b = sizeof *cc;
    for (size_t k = 0; k < sizeof bufs / sizeof bufs[0]; ++k) b += bufs[k]->bytes;
    const cc_part *parts = cc->parts.ptr;
    for (uint32_t t = 0; t < cc->part_cap; ++t)
        b += parts[t].vt.bytes + parts[t].vv.bytes + parts[t].ee.bytes + parts[t].nearest.bytes +
             parts[t].hits.bytes;
    return b;
}

/* ---- small vector helpers ---------------------------------------------------- */

static inline float dot3(const float a[3], const float b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void sub3(float r[3], const float a[3], const float b[3]) {
    r[0] = a[0] - b[0], r[1] = a[1] - b[1], r[2] = a[2] - b[2];
}
static inline void cross3(float r[3], const float a[3], const float b[3]) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
static inline void load3(float r[3], const float *const s[3], uint32_t i) {
    r[0] = s[0][i], r[1] = s[1][i], r[2] = s[2][i];
}
/* The iterate p as the read-only view load3 takes (C has no implicit
 * float ** -> const float *const * conversion). */
#define CONST3(a) ((const float *const *)(a))

/* Barycentric weights w of the point of triangle abc closest to p (Ericson,
 * Real-Time Collision Detection, 5.1.5: the Voronoi regions of the corners, then of
 * the edges, then the face). The closest point is w0 a + w1 b + w2 c. A degenerate
 * triangle that reaches the face case gets a (the caller skips those). */
static void closest_bary(const float p[3], const float a[3], const float b[3], const float c[3],
                         float w[3]) {
    float ab[3], ac[3], ap[3], bp[3], cp[3];
    sub3(ab, b, a);
    sub3(ac, c, a);
    sub3(ap, p, a);
    float d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0.0f && d2 <= 0.0f) {
        w[0] = 1.0f, w[1] = 0.0f, w[2] = 0.0f;
        return;
    }
    sub3(bp, p, b);
    float d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0.0f && d4 <= d3) {
        w[0] = 0.0f, w[1] = 1.0f, w[2] = 0.0f;
        return;
    }
    float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) {
        float v = d1 / (d1 - d3);
        w[0] = 1.0f - v, w[1] = v, w[2] = 0.0f;
        return;
    }
    sub3(cp, p, c);
    float d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0.0f && d5 <= d6) {
        w[0] = 0.0f, w[1] = 0.0f, w[2] = 1.0f;
        return;
    }
    float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) {
        float t = d2 / (d2 - d6);
        w[0] = 1.0f - t, w[1] = 0.0f, w[2] = t;
        return;
    }
    float va = d3 * d6 - d5 * d4;
    if (va <= 0.0f && (d4 - d3) >= 0.0f && (d5 - d6) >= 0.0f) {
        float t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        w[0] = 0.0f, w[1] = 1.0f - t, w[2] = t;
        return;
    }
    float sum = va + vb + vc;
    if (!(sum > 0.0f)) {
        w[0] = 1.0f, w[1] = 0.0f, w[2] = 0.0f;
        return;
    }
    float v = vb / sum, t = vc / sum;
    w[0] = 1.0f - v - t, w[1] = v, w[2] = t;
}

static inline void bary_point(float r[3], const float w[3], const float a[3], const float b[3],
                              const float c[3]) {
    for (int k = 0; k < 3; ++k) r[k] = w[0] * a[k] + w[1] * b[k] + w[2] * c[k];
}

/* Not fminf/fmaxf: their NaN rules make them library calls. */
static inline float min2(float a, float b) { return a < b ? a : b; }
static inline float max2(float a, float b) { return a > b ? a : b; }

/* 1 if triangle abc is a sliver (RBC_CC_SLIVER); n = (b - a) x (c - a). */
static inline int tri_sliver(const float a[3], const float b[3], const float c[3],
                             const float n[3]) {
    float e[3];
    sub3(e, b, a);
    float l = dot3(e, e);
    sub3(e, c, a);
    l = max2(l, dot3(e, e));
    sub3(e, c, b);
    l = max2(l, dot3(e, e));
    const float k = RBC_CC_SLIVER * l;
    return dot3(n, n) < k * k;
}

/* Distance from p to triangle abc (m). */
static float tri_distance(const float p[3], const float a[3], const float b[3], const float c[3]) {
    float w[3], q[3], d[3];
    closest_bary(p, a, b, c, w);
    bary_point(q, w, a, b, c);
    sub3(d, p, q);
    return sqrtf(dot3(d, d));
}

/* ---- the hash ------------------------------------------------------------------ */

typedef struct cc_range {
    int32_t lo[3], hi[3];
} cc_range;

/* floor(v / cell), clamped. The conversion and a correction for negatives stand in
 * for floorf, which without SSE4.1 is a library call (the hottest line otherwise). */
static inline int32_t cell_of(float v, float inv) {
    float c = v * inv;
    if (!(c >= -(float)CC_CELL_MAX)) c = -(float)CC_CELL_MAX; /* NaN lands here too */
    if (c > (float)CC_CELL_MAX) c = (float)CC_CELL_MAX;
    int32_t i = (int32_t)c;
    return (float)i > c ? i - 1 : i;
}

static inline uint64_t cell_key(int32_t i, int32_t j, int32_t k) {
    return ((uint64_t)(uint32_t)(i + CC_CELL_OFF) << 42) |
           ((uint64_t)(uint32_t)(j + CC_CELL_OFF) << 21) | (uint64_t)(uint32_t)(k + CC_CELL_OFF);
}

/* splitmix64's finalizer: neighbouring cells land in unrelated buckets. */
static inline uint32_t cell_bucket(uint64_t key, uint32_t mask) {
    key ^= key >> 30;
    key *= 0xbf58476d1ce4e5b9ull;
    key ^= key >> 27;
    key *= 0x94d049bb133111ebull;
    key ^= key >> 31;
    return (uint32_t)key & mask;
}

static inline void box_range(const float lo[3], const float hi[3], float inv, cc_range *r) {
    for (int k = 0; k < 3; ++k) {
        r->lo[k] = cell_of(lo[k], inv);
        r->hi[k] = cell_of(hi[k], inv);
        if (r->hi[k] < r->lo[k]) r->hi[k] = r->lo[k]; /* NaN boxes */
    }
}

static inline uint64_t range_cells(const cc_range *r) {
    return (uint64_t)(r->hi[0] - r->lo[0] + 1) * (uint64_t)(r->hi[1] - r->lo[1] + 1) *
           (uint64_t)(r->hi[2] - r->lo[2] + 1);
}

/* The box of object i as hashed: its swept box grown by g. Computed by this one
 * function wherever it is needed, so the lower-corner test sees the very floats the
 * insertion saw. */
static inline void grown_box(const float *box, uint32_t i, float g, float lo[3], float hi[3]) {
    for (int k = 0; k < 3; ++k) {
        lo[k] = box[6 * (size_t)i + k] - g;
        hi[k] = box[6 * (size_t)i + 3 + k] + g;
    }
}

/* 1: the pair of boxes (query lo/hi, object olo/ohi) is to be taken in cell c, the one
 * holding the lower corner of their intersection. */
static inline int lower_corner_is(const float lo[3], const float olo[3], float inv,
                                  const int32_t c[3]) {
    for (int k = 0; k < 3; ++k)
        if (cell_of(lo[k] > olo[k] ? lo[k] : olo[k], inv) != c[k]) return 0;
    return 1;
}

/* Hash the m objects (boxes grown by grow[body[i]], or by grow0 when grow is NULL)
 * whose body is active. Entries of a bucket are in object order. 0 = out of memory. */
static int hash_build(rbc_clothcontact *cc, cc_hash *h, uint32_t m, const float *box,
                      const uint32_t *body, const float *grow, float grow0,
                      const uint8_t *active) {
    const rbc_allocator *a = &cc->alloc;
    uint32_t nb = 16;
    while (nb < (uint64_t)m * 2u && nb < (1u << 30)) nb *= 2u;
    if (!buf_reserve(a, &h->start, (size_t)nb + 1, sizeof(uint32_t), 0)) return 0;
    if (!buf_reserve(a, &h->big, m, sizeof(uint32_t), 0)) return 0;
    uint32_t *start = h->start.ptr, *big = h->big.ptr;
    memset(start, 0, sizeof(uint32_t) * ((size_t)nb + 1));
    const uint32_t mask = nb - 1;
    const float inv = cc->inv_cell;
    uint64_t total = 0;
    uint32_t nbig = 0;
    for (uint32_t i = 0; i < m; ++i) {
        if (!active[body[i]]) continue;
        float lo[3], hi[3];
        grown_box(box, i, grow ? grow[body[i]] : grow0, lo, hi);
        cc_range r;
        box_range(lo, hi, inv, &r);
        uint64_t cells = range_cells(&r);
        if (cells > CC_BIG_CELLS) {
            big[nbig++] = i;
            continue;
        }
        total += cells;
        for (int32_t x = r.lo[0]; x <= r.hi[0]; ++x)
            for (int32_t y = r.lo[1]; y <= r.hi[1]; ++y)
                for (int32_t z = r.lo[2]; z <= r.hi[2]; ++z)
                    start[cell_bucket(cell_key(x, y, z), mask)]++;
    }
    if (total > UINT32_MAX) return 0;
    h->nb = nb;
    h->big_count = nbig;
    if (!buf_reserve(a, &h->id, (size_t)total, sizeof(uint32_t), 0)) return 0;
    uint32_t *id = h->id.ptr;
    uint32_t sum = 0;
    for (uint32_t b = 0; b < nb; ++b) {
        uint32_t c = start[b];
        start[b] = sum;
        sum += c;
    }
    /* Fill: start[b] advances to the end of bucket b (= the start of b + 1). */
    for (uint32_t i = 0, bi = 0; i < m; ++i) {
        if (!active[body[i]]) continue;
        if (bi < nbig && big[bi] == i) {
            bi++;
            continue;
        }
        float lo[3], hi[3];
        grown_box(box, i, grow ? grow[body[i]] : grow0, lo, hi);
        cc_range r;
        box_range(lo, hi, inv, &r);
        for (int32_t x = r.lo[0]; x <= r.hi[0]; ++x)
            for (int32_t y = r.lo[1]; y <= r.hi[1]; ++y)
                for (int32_t z = r.lo[2]; z <= r.hi[2]; ++z)
                    id[start[cell_bucket(cell_key(x, y, z), mask)]++] = i;
    }
    for (uint32_t b = nb; b > 0; --b) start[b] = start[b - 1];
    start[0] = 0;
    /* A query reads a bucket per cell, with total / nb entries each on average; past
     * m / (1 + total / nb) cells that costs more than one box test per object. Boxes
     * far larger than the mesh (a thickness of a metre on a 40 cm cloth, a cloth
     * thrown across the scene) would otherwise read up to CC_BIG_CELLS buckets each,
     * every bucket holding every object: the fuzzer's 128 vertices took seconds. */
    uint64_t scan = (uint64_t)m / (1u + total / nb);
    h->scan_cells = scan < 1 ? 1u : scan > CC_BIG_CELLS ? CC_BIG_CELLS : (uint32_t)scan;
    return 1;
}

#define CC_PATCH 8u
#define CC_PATCH_CELLS 3.0f
/* The patches of every body's triangles whose boxes are pb (thread 0). 0 = out of
 * memory. */
static int patches_build(rbc_clothcontact *cc, cc_patches *P, const float *pb) {
    const uint32_t count = cc->body_count, *tbase = cc->tbase.ptr;
    const uint32_t ntr = tbase[count];
    const rbc_allocator *al = &cc->alloc;
    if (!buf_reserve(al, &P->start, (size_t)ntr + 1, sizeof(uint32_t), 0) ||
        !buf_reserve(al, &P->body, ntr ? ntr : 1, sizeof(uint32_t), 0) ||
        !buf_reserve(al, &P->box, ntr ? ntr : 1, 6 * sizeof(float), 0))
        return 0;
    uint32_t *ps = P->start.ptr, *pbd = P->body.ptr, k = 0;
    float *pab = P->box.ptr;
    const float span = CC_PATCH_CELLS * cc->cell;
    for (uint32_t b = 0; b < count; ++b)
        for (uint32_t g = tbase[b]; g < tbase[b + 1];) {
            float *o = pab + 6 * (size_t)k;
            memcpy(o, pb + 6 * (size_t)g, 6 * sizeof(float));
            ps[k] = g;
            pbd[k] = b;
            uint32_t e = g + 1;
            for (; e < tbase[b + 1] && e - g < CC_PATCH; ++e) {
                const float *t = pb + 6 * (size_t)e;
                float u[6];
                int fits = 1;
                for (int a = 0; a < 3; ++a) {
                    u[a] = min2(o[a], t[a]);
                    u[3 + a] = max2(o[3 + a], t[3 + a]);
                    if (!(u[3 + a] - u[a] <= span)) fits = 0; /* NaN does not fit */
                }
                if (!fits) break;
                memcpy(o, u, sizeof u);
            }
            g = e;
            k++;
        }
    ps[k] = ntr;
    P->n = k;
    return 1;
}

/* ---- detection ------------------------------------------------------------------ */

typedef struct cc_detect {
    rbc_clothcontact *cc;
    const rbc_contact_body *bodies;
    const uint32_t *vbase, *tbase, *vbody, *tbody;
    const float *vbox, *tbox, *trec, *bgrow;
    float margin;
    int oom;
    size_t cap;   /* most contacts taken (RBC_CC_MAX_TOTAL_PER_VERTEX per vertex) */
    int over;     /* the cap was reached */
    cc_buf *out;  /* the list contacts go to, and its count */
    uint32_t *n;
    cc_buf *nearest; /* keep_nearest's scratch */
    uint32_t *capped;
    cc_part *part;   /* a thread's stage: never allocate (see cc_part), else NULL */
    uint64_t *raw;   /* with part: contacts pushed to out, written or not */
    rbc_contact sink; /* where a push that does not fit writes */
} cc_detect;

static rbc_contact *push_contact(cc_detect *d) {
    rbc_clothcontact *cc = d->cc;
    if (d->oom) return NULL; /* failed once: ask for nothing more, the list is dropped */
    if (*d->n >= d->cap) {
        d->over = d->oom = 1; /* stop as on a failure; reported as a tangle */
        return NULL;
    }
    if (d->part) {
        (*d->raw)++;
        if (d->part->full || (size_t)*d->n >= d->out->bytes / sizeof(rbc_contact)) {
            d->part->full = 1; /* count the rest; thread 0 grows the list */
            memset(&d->sink, 0, sizeof d->sink);
            return &d->sink;
        }
        rbc_contact *c = (rbc_contact *)d->out->ptr + (*d->n)++;
        memset(c, 0, sizeof *c);
        return c;
    }
    if (!buf_reserve(&cc->alloc, d->out, (size_t)*d->n + 1, sizeof(rbc_contact),
                     sizeof(rbc_contact) * *d->n)) {
        d->oom = 1;
        return NULL;
    }
    rbc_contact *c = (rbc_contact *)d->out->ptr + (*d->n)++;
    memset(c, 0, sizeof *c);
    return c;
}

static inline int boxes_overlap(const float *a, const float *b, float g) {
    for (int k = 0; k < 3; ++k)
        if (a[k] > b[3 + k] + g || b[k] - g > a[3 + k]) return 0;
    return 1;
}

static inline int bodies_pair(const rbc_contact_body *A, const rbc_contact_body *B, int same) {
    return same ? A->self != 0 : (A->others != 0 && B->others != 0);
}

/* Squared distance from p to the bounding box of a, b, c: a lower bound of the
 * squared distance to the triangle, to skip most closest-point computations. */
static inline float box_dist2(const float p[3], const float a[3], const float b[3],
                              const float c[3]) {
    float s = 0.0f;
    for (int k = 0; k < 3; ++k) {
        float lo = min2(a[k], min2(b[k], c[k])), hi = max2(a[k], max2(b[k], c[k]));
        float e = p[k] < lo ? lo - p[k] : p[k] > hi ? p[k] - hi : 0.0f;
        s += e * e;
    }
    return s;
}

/* What a triangle's tests need, once per triangle and substep rather than once per
 * candidate pair: its boxes at x and at p, and its planes there (unit normal n and
 * offset n . a; a zero normal where the triangle is degenerate). */
enum { CC_TREC = 20 };
enum { CC_XBOX = 0, CC_PBOX = 6, CC_N0 = 12, CC_O0 = 15, CC_N1 = 16, CC_O1 = 19 };

static void tri_record(const rbc_contact_body *B, const uint32_t *tri, float *o) {
    for (int pass = 0; pass < 2; ++pass) {
        float P[3][3], e1[3], e2[3], n[3];
        for (int c = 0; c < 3; ++c) load3(P[c], pass ? CONST3(B->p) : B->x, tri[c]);
        float *box = o + (pass ? CC_PBOX : CC_XBOX), *no = o + (pass ? CC_N1 : CC_N0);
        for (int k = 0; k < 3; ++k) {
            box[k] = min2(P[0][k], min2(P[1][k], P[2][k]));
            box[3 + k] = max2(P[0][k], max2(P[1][k], P[2][k]));
        }
        sub3(e1, P[1], P[0]);
        sub3(e2, P[2], P[0]);
        cross3(n, e1, e2);
        const float l = sqrtf(dot3(n, n));
        const int ok = l > 0.0f && isfinite(l);
        for (int k = 0; k < 3; ++k) no[k] = ok ? n[k] / l : 0.0f;
        no[3] = dot3(no, P[0]);
    }
}

/* Squared distance from p to a box lo[3], hi[3]. */
static inline float point_box2(const float p[3], const float *box) {
    float s = 0.0f;
    for (int k = 0; k < 3; ++k) {
        float e = p[k] < box[k] ? box[k] - p[k] : p[k] > box[3 + k] ? p[k] - box[3 + k] : 0.0f;
        s += e * e;
    }
    return s;
}

/* One vertex as its candidate pairs see it. */
typedef struct cc_vq {
    uint32_t v, bv, i;          /* global index, body, local index */
    const rbc_contact_body *V;
    float X[3], P[3], g;        /* at x, at p; thickness + margin */
} cc_vq;

static void vq_load(const cc_detect *d, uint32_t v, cc_vq *q) {
    q->v = v;
    q->bv = d->vbody[v];
    q->i = v - d->vbase[q->bv];
    q->V = &d->bodies[q->bv];
    load3(q->X, q->V->x, q->i);
    load3(q->P, CONST3(q->V->p), q->i);
    q->g = q->V->thickness + d->margin;
}

/* The vertex of q against triangle t (global), whose swept boxes overlap grown by g:
 * append a contact if they qualify. Cheap bounds reject most candidates before any
 * corner is read: a vertex near the triangle at x (or p) is within g of its box and
 * its plane there; one crossing it changes sides of the plane. */
static void try_vt(cc_detect *d, const cc_vq *q, uint32_t t) {
    const uint32_t bt = d->tbody[t];
    const rbc_contact_body *V = q->V, *T = &d->bodies[bt];
    const int same = q->bv == bt;
    if (!bodies_pair(V, T, same)) return;
    const float *rec = d->trec + CC_TREC * (size_t)t;
    const float *n0 = rec + CC_N0, *n1 = rec + CC_N1;
    if (n0[0] == 0.0f && n0[1] == 0.0f && n0[2] == 0.0f) return; /* degenerate at x: no side */
    const float g = q->g, g2 = g * g;
    const float d0 = dot3(n0, q->X) - rec[CC_O0];
    const int n1ok = n1[0] != 0.0f || n1[1] != 0.0f || n1[2] != 0.0f;
    const float d1 = n1ok ? dot3(n1, q->P) - rec[CC_O1] : 0.0f;
    const int maybe0 = fabsf(d0) < g && point_box2(q->X, rec + CC_XBOX) < g2;
    const int maybe1 = n1ok && fabsf(d1) < g && point_box2(q->P, rec + CC_PBOX) < g2;
    const int maybe_cross = n1ok && d0 * d1 <= 0.0f && d0 != d1;
    if (!maybe0 && !maybe1 && !maybe_cross) return;
    const uint32_t i = q->i, tl = t - d->tbase[bt];
    const uint32_t *tri = T->tris + 3 * (size_t)tl;
    if (same) {
        if (tri[0] == i || tri[1] == i || tri[2] == i) return;
        if (V->rest[0]) {
            /* Neighbours that touch at rest are not contacts. */
            float RX[3], RA[3], RB[3], RC[3];
            load3(RX, V->rest, i);
            load3(RA, V->rest, tri[0]);
            load3(RB, V->rest, tri[1]);
            load3(RC, V->rest, tri[2]);
            const float lim = 2.0f * V->thickness;
            if (box_dist2(RX, RA, RB, RC) < lim * lim && tri_distance(RX, RA, RB, RC) < lim)
                return;
        }
    }
    float A[3], B[3], C[3], PA[3], PB[3], PC[3];
    load3(A, T->x, tri[0]);
    load3(B, T->x, tri[1]);
    load3(C, T->x, tri[2]);
    load3(PA, CONST3(T->p), tri[0]);
    load3(PB, CONST3(T->p), tri[1]);
    load3(PC, CONST3(T->p), tri[2]);
    const float *X = q->X, *P = q->P;
    /* Near at x, crossing the plane inside the triangle, or near at p. */
    int crossed = 0, through = 0;
    if (maybe_cross) {
        /* The plane distance, taken linear in time between its end values, is 0 at s;
         * vertex and triangle there are interpolated linearly. */
        const float s = d0 / (d0 - d1);
        float Xs[3], As[3], Bs[3], Cs[3];
        for (int k = 0; k < 3; ++k) {
            Xs[k] = X[k] + s * (P[k] - X[k]);
            As[k] = A[k] + s * (PA[k] - A[k]);
            Bs[k] = B[k] + s * (PB[k] - B[k]);
            Cs[k] = C[k] + s * (PC[k] - C[k]);
        }
        crossed = box_dist2(Xs, As, Bs, Cs) < g2 && tri_distance(Xs, As, Bs, Cs) < g;
        /* Only a real pass through the triangle (the crossing point within a quarter
         * of the thickness of it) may later pull the vertex back to the triangle's
         * plane from beside it: a crossing past an edge or over a neighbouring
         * triangle, on a curved stack that slides, threw vertices by millimetres per
         * substep (3-7 m/s where a 1 m/s sphere pushed four layers). */
        through = crossed && tri_distance(Xs, As, Bs, Cs) < 0.25f * V->thickness;
    }
    const int hit = crossed || (maybe0 && tri_distance(X, A, B, C) < g) ||
                    (maybe1 && tri_distance(P, PA, PB, PC) < g);
    if (!hit) return;
    float side;
    if (d0 > 0.0f) {
        side = 1.0f;
    } else if (d0 < 0.0f) {
        side = -1.0f;
    } else {
        /* On the plane: the side its motion relative to the triangle point goes to. */
        float w[3], rel = 0.0f;
        closest_bary(X, A, B, C, w);
        for (int k = 0; k < 3; ++k)
            rel += (P[k] - X[k] - (w[0] * (PA[k] - A[k]) + w[1] * (PB[k] - B[k]) +
                                   w[2] * (PC[k] - C[k]))) * n0[k];
        side = rel < 0.0f ? -1.0f : 1.0f;
    }
    rbc_contact *c = push_contact(d);
    if (!c) return;
    float e1[3], e2[3], nx[3];
    sub3(e1, B, A);
    sub3(e2, C, A);
    cross3(nx, e1, e2);
    c->kind = RBC_CONTACT_VT;
    /* Held for the first pass (which sees the prediction p) unless the prediction is
     * deeper than the thickness on the far side: the inertial motion took it there,
     * around the triangle (through it is RBC_CONTACT_CROSSED), not the solve. */
    const int deep_p = n1ok && side * d1 < -V->thickness;
    c->flags = (through ? RBC_CONTACT_CROSSED : 0u) |
               (tri_sliver(A, B, C, nx) ? RBC_CONTACT_THIN : 0u) | (deep_p ? 0u : RBC_CONTACT_HELD);
    c->body_a = q->bv, c->a = i;
    c->body_b = bt, c->b = tl;
    c->side = side;
}

/* Vertices v < u (global) whose swept boxes overlap (grown by thickness + margin / 2
 * each): append a contact if they qualify. */
static void try_vv(cc_detect *d, uint32_t v, uint32_t u) {
    const uint32_t bv = d->vbody[v], bu = d->vbody[u];
    const rbc_contact_body *V = &d->bodies[bv], *U = &d->bodies[bu];
    if (!bodies_pair(V, U, bv == bu)) return;
    const uint32_t i = v - d->vbase[bv], j = u - d->vbase[bu];
    float A[3], B[3], e[3];
    if (bv == bu && V->rest[0]) {
        load3(A, V->rest, i);
        load3(B, V->rest, j);
        sub3(e, A, B);
        if (sqrtf(dot3(e, e)) < 2.0f * V->thickness) return;
    }
    float PA[3], PB[3], d0[3], dd[3];
    load3(A, V->x, i);
    load3(B, U->x, j);
    load3(PA, CONST3(V->p), i);
    load3(PB, CONST3(U->p), j);
    sub3(d0, A, B);
    for (int k = 0; k < 3; ++k) dd[k] = (PA[k] - A[k]) - (PB[k] - B[k]);
    /* Closest approach of the relative motion d0 + s dd, s in [0, 1]. */
    float s = 0.0f, dd2 = dot3(dd, dd);
    if (dd2 > 0.0f) {
        s = -dot3(d0, dd) / dd2;
        s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
    }
    float m[3];
    for (int k = 0; k < 3; ++k) m[k] = d0[k] + s * dd[k];
    const float reach = V->thickness + U->thickness + d->margin;
    if (!(dot3(m, m) < reach * reach)) return;
    rbc_contact *c = push_contact(d);
    if (!c) return;
    c->kind = RBC_CONTACT_VV;
    c->body_a = bv, c->a = i;
    c->body_b = bu, c->b = j;
    c->side = 1.0f;
    c->w[0] = 1.0f;
    /* The start direction: x_a - x_b, else their relative motion, else +y. */
    float l = sqrtf(dot3(d0, d0));
    if (l > 0.0f) {
        for (int k = 0; k < 3; ++k) c->n0[k] = d0[k] / l;
    } else if (dd2 > 0.0f) {
        l = sqrtf(dd2);
        for (int k = 0; k < 3; ++k) c->n0[k] = dd[k] / l;
    } else {
        c->n0[1] = 1.0f;
    }
}

/* Sort contacts [from, to) by partner (body, index), insertion sort (a vertex has
 * few), and drop copies (an object hashed to one bucket from two cells); returns the
 * new end. */
static uint32_t sort_partners(rbc_contact *c, uint32_t from, uint32_t to) {
    for (uint32_t k = from + 1; k < to; ++k) {
        rbc_contact t = c[k];
        uint32_t m = k;
        while (m > from && (c[m - 1].body_b > t.body_b ||
                            (c[m - 1].body_b == t.body_b && c[m - 1].b > t.b))) {
            c[m] = c[m - 1];
            m--;
        }
        c[m] = t;
    }
    uint32_t end = from;
    for (uint32_t k = from; k < to; ++k)
        if (k == from || c[k].body_b != c[end - 1].body_b || c[k].b != c[end - 1].b) c[end++] = c[k];
    return end;
}

typedef struct cc_key {
    float d;
    uint32_t i;
} cc_key;

static int cmp_key(const void *a, const void *b) {
    const cc_key *x = a, *y = b;
    if (x->d != y->d) return x->d < y->d ? -1 : 1;
    return x->i < y->i ? -1 : x->i > y->i; /* i: partner order, so ties are fixed too */
}

/* Contacts [from, to) of one vertex, sorted by partner: if more than
 * RBC_CC_MAX_PER_VERTEX, keep the nearest that many at p (vertex to triangle or to
 * the other vertex), still in partner order, and end the list after them. Returns 0
 * when out of memory. */
static int keep_nearest(cc_detect *d, uint32_t from) {
    rbc_clothcontact *cc = d->cc;
    const uint32_t n = *d->n - from, cap = RBC_CC_MAX_PER_VERTEX;
    if (n <= cap) return 1;
    if (d->part) {
        if (n > d->part->near_need) d->part->near_need = n;
        if ((size_t)n > d->nearest->bytes / sizeof(cc_key)) {
            d->part->full = 1; /* thread 0 grows the scratch; the stage runs again */
            return 1;
        }
    } else if (!buf_reserve(&cc->alloc, d->nearest, n, sizeof(cc_key), 0)) {
        return 0;
    }
    cc_key *key = d->nearest->ptr;
    rbc_contact *c = (rbc_contact *)d->out->ptr + from;
    for (uint32_t k = 0; k < n; ++k) {
        const rbc_contact_body *A = &d->bodies[c[k].body_a], *B = &d->bodies[c[k].body_b];
        float q[3], o[3];
        load3(q, CONST3(A->p), c[k].a);
        if (c[k].kind == RBC_CONTACT_VT) {
            const uint32_t *tri = B->tris + 3 * (size_t)c[k].b;
            float P[3][3];
            for (int m = 0; m < 3; ++m) load3(P[m], CONST3(B->p), tri[m]);
            key[k].d = tri_distance(q, P[0], P[1], P[2]);
        } else {
            load3(o, CONST3(B->p), c[k].b);
            sub3(o, q, o);
            key[k].d = sqrtf(dot3(o, o));
        }
        if (!(key[k].d == key[k].d)) key[k].d = INFINITY; /* NaN last */
        key[k].i = k;
    }
    qsort(key, n, sizeof *key, cmp_key);
    /* The kept ones in partner order (their indices ascending), moved down in place:
     * slot k <= index. */
    for (uint32_t k = 0; k < cap; ++k) key[k].d = (float)key[k].i;
    qsort(key, cap, sizeof *key, cmp_key);
    for (uint32_t k = 0; k < cap; ++k) c[k] = c[key[k].i];
    if (c[0].kind == RBC_CONTACT_VT) (*d->capped)++; /* a vertex once, by its triangles */
    *d->n = from + cap;
    return 1;
}

/* ---- edge-edge: border edges --------------------------------------------------- */

static int cmp_u64(const void *a, const void *b) {
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* The border edges of every body (an edge of exactly one triangle), found again only
 * when some body's triangles changed (tearing, a new cloth). 0 = out of memory. */
static int border_edges(rbc_clothcontact *cc, const rbc_contact_body *bodies, uint32_t count) {
    const rbc_allocator *a = &cc->alloc;
    int same = cc->ekey_count == count && cc->ekey.ptr && cc->ebase.ptr;
    for (uint32_t b = 0; b < count && same; ++b) {
        const cc_ekey *k = (const cc_ekey *)cc->ekey.ptr + b;
        same = k->tris == bodies[b].tris && k->tri_count == bodies[b].tri_count &&
               k->n == bodies[b].n;
    }
    if (same) return 1;
    cc->ekey_count = 0;
    if (!buf_reserve(a, &cc->ekey, count, sizeof(cc_ekey), 0) ||
        !buf_reserve(a, &cc->ebase, (size_t)count + 1, sizeof(uint32_t), 0))
        return 0;
    if (!buf_reserve(a, &cc->abase, (size_t)count + 1, sizeof(uint32_t), 0)) return 0;
    size_t ntri = 0;
    for (uint32_t b = 0; b < count; ++b) ntri += bodies[b].tri_count;
    if (!buf_reserve(a, &cc->tedge, 3 * ntri + 1, sizeof(uint32_t), 0)) return 0;
    uint32_t total = 0, all = 0;
    size_t tfirst = 0; /* global index of the body's first triangle */
    for (uint32_t b = 0; b < count; ++b) {
        const rbc_contact_body *B = &bodies[b];
        ((uint32_t *)cc->ebase.ptr)[b] = total;
        ((uint32_t *)cc->abase.ptr)[b] = all;
        if (!B->tri_count) continue;
        const size_t m = 3 * (size_t)B->tri_count;
        if (!buf_reserve(a, &cc->escratch, m, sizeof(uint64_t), 0)) return 0;
        uint64_t *key = cc->escratch.ptr;
        for (uint32_t t = 0; t < B->tri_count; ++t)
            for (int e = 0; e < 3; ++e) {
                uint32_t u = B->tris[3 * (size_t)t + e], v = B->tris[3 * (size_t)t + (e + 1) % 3];
                key[3 * (size_t)t + e] = u < v ? (uint64_t)u << 32 | v : (uint64_t)v << 32 | u;
            }
        if (m > 1) qsort(key, m, sizeof(uint64_t), cmp_u64);
        for (size_t i = 0; i < m;) {
            size_t j = i + 1;
            while (j < m && key[j] == key[i]) ++j;
            if (!buf_reserve(a, &cc->aedge, 2 * ((size_t)all + 1), sizeof(uint32_t),
                             sizeof(uint32_t) * 2 * (size_t)all))
                return 0;
            if (!buf_reserve(a, &cc->eborder, (size_t)all + 1, 1, (size_t)all)) return 0;
            ((uint32_t *)cc->aedge.ptr)[2 * (size_t)all] = (uint32_t)(key[i] >> 32);
            ((uint32_t *)cc->aedge.ptr)[2 * (size_t)all + 1] = (uint32_t)key[i];
            ((uint8_t *)cc->eborder.ptr)[all] = j - i == 1;
            all++;
            if (j - i == 1) {
                if (!buf_reserve(a, &cc->bedge, 2 * ((size_t)total + 1), sizeof(uint32_t),
                                 sizeof(uint32_t) * 2 * (size_t)total))
                    return 0;
                uint32_t *be = cc->bedge.ptr;
                be[2 * (size_t)total] = (uint32_t)(key[i] >> 32);
                be[2 * (size_t)total + 1] = (uint32_t)key[i];
                total++;
            }
            i = j;
        }
        /* Each triangle's edges by global index (a binary search among the body's,
         * ascending by key), marked in the first triangle that has each. */
        const uint32_t *ae = cc->aedge.ptr, first = ((uint32_t *)cc->abase.ptr)[b];
        uint32_t *te = (uint32_t *)cc->tedge.ptr + 3 * tfirst;
        uint8_t *eb = cc->eborder.ptr;
        for (uint32_t t = 0; t < B->tri_count; ++t)
            for (int e = 0; e < 3; ++e) {
                uint32_t u = B->tris[3 * (size_t)t + e], v = B->tris[3 * (size_t)t + (e + 1) % 3];
                if (u > v) {
                    const uint32_t w = u;
                    u = v, v = w;
                }
                const uint64_t k = (uint64_t)u << 32 | v;
                uint32_t lo = first, hi = all;
                while (lo < hi) {
                    const uint32_t mid = lo + (hi - lo) / 2;
                    const uint64_t km = (uint64_t)ae[2 * (size_t)mid] << 32 | ae[2 * (size_t)mid + 1];
                    if (km < k) lo = mid + 1;
                    else hi = mid;
                }
                te[3 * (size_t)t + e] = lo | (eb[lo] & 2 ? 0u : CC_TEDGE_FIRST);
                eb[lo] |= 2; /* seen (cleared below) */
            }
        for (uint32_t g = first; g < all; ++g) eb[g] &= 1;
        tfirst += B->tri_count;
    }
    ((uint32_t *)cc->ebase.ptr)[count] = total;
    ((uint32_t *)cc->abase.ptr)[count] = all;
    for (uint32_t b = 0; b < count; ++b) {
        cc_ekey *k = (cc_ekey *)cc->ekey.ptr + b;
        k->tris = bodies[b].tris;
        k->tri_count = bodies[b].tri_count;
        k->n = bodies[b].n;
    }
    cc->ekey_count = count;
    return 1;
}

/* Closest points of segments p1 q1 and p2 q2: parameters s, t in [0, 1] (Ericson,
 * Real-Time Collision Detection, 5.1.9; parallel segments get s = 0 or the clamped
 * projection). */
static void closest_seg_seg(const float p1[3], const float q1[3], const float p2[3],
                            const float q2[3], float *s_out, float *t_out) {
    float d1[3], d2[3], r[3];
    sub3(d1, q1, p1);
    sub3(d2, q2, p2);
    sub3(r, p1, p2);
    const float a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r);
    float s = 0.0f, t = 0.0f;
    if (!(a > 0.0f) && !(e > 0.0f)) {
        s = t = 0.0f;
    } else if (!(a > 0.0f)) {
        t = f / e;
        t = t < 0.0f ? 0.0f : t > 1.0f ? 1.0f : t;
    } else {
        const float c = dot3(d1, r);
        if (!(e > 0.0f)) {
            s = -c / a;
            s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
        } else {
            const float b = dot3(d1, d2), den = a * e - b * b;
            if (den > 1e-6f * a * e) {
                s = (b * f - c * e) / den;
                s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
            }
            t = (b * s + f) / e;
            if (t < 0.0f) {
                t = 0.0f;
                s = -c / a;
                s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
            } else if (t > 1.0f) {
                t = 1.0f;
                s = (b - c) / a;
                s = s < 0.0f ? 0.0f : s > 1.0f ? 1.0f : s;
            }
        }
    }
    *s_out = s;
    *t_out = t;
}

/* r = (point s of a0 a1) - (point t of b0 b1). */
static inline void seg_diff(float r[3], const float a0[3], const float a1[3], float s,
                            const float b0[3], const float b1[3], float t) {
    for (int k = 0; k < 3; ++k)
        r[k] = a0[k] + s * (a1[k] - a0[k]) - (b0[k] + t * (b1[k] - b0[k]));
}

/* Edge u0 u1 of body A (an edge of a triangle of it) against border edge v0 v1 of body
 * B: a contact if they are within g at x or at p (their closest points over the
 * substep's motion are within reach of one of the ends, the motion being at most
 * about a margin), not sharing a vertex and, within one body, >= 2 * thickness apart
 * at rest. */
/* Squared distance between the boxes of segments a0 a1 and b0 b1: at most their
 * distance. */
static inline float seg_box_dist2(const float a0[3], const float a1[3], const float b0[3],
                                  const float b1[3]) {
    float d2 = 0.0f;
    for (int k = 0; k < 3; ++k) {
        const float g = max2(min2(b0[k], b1[k]) - max2(a0[k], a1[k]),
                             min2(a0[k], a1[k]) - max2(b0[k], b1[k]));
        if (g > 0.0f) d2 += g * g;
    }
    return d2;
}

static void try_ee(cc_detect *d, uint32_t ba, uint32_t u0, uint32_t u1, uint32_t bb, uint32_t v0,
                   uint32_t v1) {
    const rbc_contact_body *A = &d->bodies[ba], *B = &d->bodies[bb];
    if (ba == bb && (u0 == v0 || u0 == v1 || u1 == v0 || u1 == v1)) return;
    const float th = A->thickness > B->thickness ? A->thickness : B->thickness;
    const float g = th + d->margin;
    float X[4][3], P[4][3], s, t, r[3], rp[3];
    load3(X[0], A->x, u0);
    load3(X[1], A->x, u1);
    load3(X[2], B->x, v0);
    load3(X[3], B->x, v1);
    load3(P[0], CONST3(A->p), u0);
    load3(P[1], CONST3(A->p), u1);
    load3(P[2], CONST3(B->p), v0);
    load3(P[3], CONST3(B->p), v1);
    /* The boxes first: most pairs found are neighbours a spring apart. */
    if (!(seg_box_dist2(X[0], X[1], X[2], X[3]) < g * g) &&
        !(seg_box_dist2(P[0], P[1], P[2], P[3]) < g * g))
        return;
    closest_seg_seg(X[0], X[1], X[2], X[3], &s, &t);
    seg_diff(r, X[0], X[1], s, X[2], X[3], t);
    const float r2 = dot3(r, r);
    float sp, tp;
    closest_seg_seg(P[0], P[1], P[2], P[3], &sp, &tp);
    seg_diff(rp, P[0], P[1], sp, P[2], P[3], tp);
    if (!(r2 < g * g) && !(dot3(rp, rp) < g * g)) return;
    if (ba == bb && A->rest[0]) {
        float R[4][3], rs, rt, rr[3];
        load3(R[0], A->rest, u0);
        load3(R[1], A->rest, u1);
        load3(R[2], A->rest, v0);
        load3(R[3], A->rest, v1);
        closest_seg_seg(R[0], R[1], R[2], R[3], &rs, &rt);
        seg_diff(rr, R[0], R[1], rs, R[2], R[3], rt);
        const float lim = 2.0f * A->thickness;
        if (dot3(rr, rr) < lim * lim) return;
    }
    if (!(r2 > 1e-12f)) return; /* touching at x: no direction to keep */
    rbc_contact *c = push_contact(d);
    if (!c) return;
    c->kind = RBC_CONTACT_EE;
    c->body_a = ba, c->a = u0, c->a2 = u1;
    c->body_b = bb, c->b = v0, c->b2 = v1;
    c->side = 1.0f;
    c->w[0] = s, c->w[1] = t;
    const float l = sqrtf(r2);
    for (int k = 0; k < 3; ++k) c->n0[k] = r[k] / l;
}

/* Index of edge (u0 < u1) of body b among the border edges, or -1 (each body's border
 * edges are in ascending key order). */
static int64_t border_index(const rbc_clothcontact *cc, uint32_t b, uint32_t u0, uint32_t u1) {
    const uint32_t *ebase = cc->ebase.ptr, *be = cc->bedge.ptr;
    uint32_t lo = ebase[b], hi = ebase[b + 1];
    const uint64_t key = (uint64_t)u0 << 32 | u1;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        const uint64_t k = (uint64_t)be[2 * (size_t)mid] << 32 | be[2 * (size_t)mid + 1];
        if (k == key) return mid;
        if (k < key) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

typedef struct cc_ecand {
    uint32_t body, u0, u1;
} cc_ecand;

static int cmp_ecand(const void *a, const void *b) {
    const cc_ecand *x = a, *y = b;
    if (x->body != y->body) return x->body < y->body ? -1 : 1;
    if (x->u0 != y->u0) return x->u0 < y->u0 ? -1 : 1;
    return x->u1 < y->u1 ? -1 : x->u1 > y->u1;
}

/* Add the edges of triangle t (global) whose swept boxes (their ends') meet box, once
 * each (insertion into the sorted set cand of *nc; 0 = the set is full). */
static int add_tri_edges(const cc_detect *d, uint32_t t, const float box[6], cc_ecand *cand,
                         uint32_t *nc, uint32_t cap) {
    const uint32_t bt = d->tbody[t];
    const uint32_t *tri = d->bodies[bt].tris + 3 * (size_t)(t - d->tbase[bt]);
    const uint32_t vb = d->vbase[bt];
    for (int k = 0; k < 3; ++k) {
        uint32_t a = tri[k], b = tri[(k + 1) % 3];
        if (a > b) {
            uint32_t tmp = a;
            a = b, b = tmp;
        }
        const float *ba = d->vbox + 6 * ((size_t)vb + a), *bb = d->vbox + 6 * ((size_t)vb + b);
        int out = 0;
        for (int j = 0; j < 3 && !out; ++j)
            out = min2(ba[j], bb[j]) > box[3 + j] || max2(ba[3 + j], bb[3 + j]) < box[j];
        if (out) continue;
        const cc_ecand e = {bt, a, b};
        uint32_t m = *nc;
        while (m > 0 && cmp_ecand(&cand[m - 1], &e) > 0) --m;
        if (m > 0 && cmp_ecand(&cand[m - 1], &e) == 0) continue;
        if (*nc >= cap) return 0;
        memmove(&cand[m + 1], &cand[m], sizeof(cc_ecand) * (*nc - m));
        cand[m] = e;
        (*nc)++;
    }
    return 1;
}


/* The patches of the triangle hash (cc->th, cc->tp) whose box meets box, each once:
 * keep(ctx, k) first (which bodies), then the box test, then visit(ctx, k). Once: in
 * the cell holding the lower corner of the box's intersection with the patch's
 * hashed box (grown by tri_grow), and a patch hashed from two cells into one bucket
 * lies there twice, side by side (a bucket holds its objects in order: without the
 * check, the interior edge pass made every contact of such a patch twice). A box over
 * more than CC_BIG_CELLS cells: every patch, in order. The patches too big to hash
 * come last. Static, with constant keep and visit: the calls are inlined. */
static inline void patches_near(const rbc_clothcontact *cc, const float box[6],
                                int (*keep)(void *, uint32_t), void (*visit)(void *, uint32_t),
                                void *ctx) {
    const cc_hash *h = &cc->th;
    const uint32_t *start = h->start.ptr, *id = h->id.ptr, *big = h->big.ptr;
    const float *pab = cc->tp.box.ptr, inv = cc->inv_cell;
    cc_range r;
    box_range(box, box + 3, inv, &r);
    if (range_cells(&r) > h->scan_cells) {
        for (uint32_t k = 0; k < cc->tp.n; ++k)
            if (keep(ctx, k) && boxes_overlap(box, pab + 6 * (size_t)k, 0.0f)) visit(ctx, k);
        return;
    }
    int32_t c[3];
    for (c[0] = r.lo[0]; c[0] <= r.hi[0]; ++c[0])
        for (c[1] = r.lo[1]; c[1] <= r.hi[1]; ++c[1])
            for (c[2] = r.lo[2]; c[2] <= r.hi[2]; ++c[2]) {
                const uint32_t bk = cell_bucket(cell_key(c[0], c[1], c[2]), h->nb - 1);
                for (uint32_t q = start[bk]; q < start[bk + 1]; ++q) {
                    const uint32_t k = id[q];
                    if (q > start[bk] && id[q - 1] == k) continue;
                    if (!keep(ctx, k) || !boxes_overlap(box, pab + 6 * (size_t)k, 0.0f)) continue;
                    float olo[3], ohi[3];
                    grown_box(pab, k, cc->tri_grow, olo, ohi);
                    if (lower_corner_is(box, olo, inv, c)) visit(ctx, k);
                }
            }
    for (uint32_t m = 0; m < h->big_count; ++m)
        if (keep(ctx, big[m]) && boxes_overlap(box, pab + 6 * (size_t)big[m], 0.0f)) visit(ctx, big[m]);
}

/* Border edge queries (detect_ee): which patches, and their triangles' edges. */
typedef struct cc_eeq {
    cc_detect *d;
    const uint8_t *active;
    const rbc_contact_body *B;
    uint32_t bb, nc, cap;
    const float *box;
    cc_ecand *cand;             /* the sorted set of candidate edges, cap at most */
    int full;
} cc_eeq;

static int eeq_keep(void *ctx, uint32_t k) {
    const cc_eeq *q = ctx;
    const uint32_t bt = ((const uint32_t *)q->d->cc->tp.body.ptr)[k];
    return q->active[bt] && bodies_pair(&q->d->bodies[bt], q->B, bt == q->bb);
}

static void eeq_visit(void *ctx, uint32_t k) {
    cc_eeq *q = ctx;
    const uint32_t *ps = q->d->cc->tp.start.ptr;
    for (uint32_t t = ps[k]; t < ps[k + 1]; ++t)
        if (boxes_overlap(q->box, q->d->tbox + 6 * (size_t)t, 0.0f) &&
            !add_tri_edges(q->d, t, q->box, q->cand, &q->nc, q->cap))
            q->full = 1;
}

/* Edge-edge contacts: every border edge looks up the triangles around its swept box
 * (the triangle hash) and tests their edges, each once (a small sorted set per border
 * edge: in body, then index order, so the list is deterministic). */
static void detect_ee(cc_detect *d, const uint8_t *active, uint32_t count) {
    rbc_clothcontact *cc = d->cc;
    const uint32_t *ebase = cc->ebase.ptr, *be = cc->bedge.ptr;
    enum { CAND_MAX = 192 };
    cc_ecand cand[CAND_MAX];
    for (uint32_t bb = 0; bb < count && !d->oom; ++bb) {
        if (!active[bb]) continue;
        const rbc_contact_body *B = &d->bodies[bb];
        const float g = B->thickness + d->margin;
        for (uint32_t e = ebase[bb]; e < ebase[bb + 1] && !d->oom; ++e) {
            const uint32_t v0 = be[2 * (size_t)e], v1 = be[2 * (size_t)e + 1];
            float lo[3], hi[3];
            for (int k = 0; k < 3; ++k) {
                float a0 = B->x[k][v0], a1 = B->x[k][v1], p0 = B->p[k][v0], p1 = B->p[k][v1];
                lo[k] = min2(min2(a0, a1), min2(p0, p1)) - g;
                hi[k] = max2(max2(a0, a1), max2(p0, p1)) + g;
            }
            const float box[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
            /* Candidate triangles: from the hash of patches (or all, for a huge box). */
            cc_eeq eq = {d, active, B, bb, 0, CAND_MAX, box, cand, 0};
            patches_near(cc, box, eeq_keep, eeq_visit, &eq);
            const uint32_t nc = eq.nc;
            /* eq.full: near more than CAND_MAX / 3 triangles, the first found (in hash
             * order) kept. */
            for (uint32_t k = 0; k < nc && !d->oom; ++k) {
                /* Not the border edge itself; two border edges once (from the later). */
                const int64_t o = border_index(cc, cand[k].body, cand[k].u0, cand[k].u1);
                if (o >= 0 && (uint64_t)o >= e) continue;
                try_ee(d, cand[k].body, cand[k].u0, cand[k].u1, bb, v0, v1);
            }
        }
    }
}

/* Edge-edge contacts between interior edges (neither a border edge: those are the
 * pass above's), within a self-colliding body and between it and the bodies it
 * collides with, for this thread's share of the triangle patches. Vertex-triangle
 * contacts cannot stop an edge from passing another where a cloth folds sharply: in
 * one 50 x 50 cloth (1 cm, thickness 3 mm) crumpled through a funnel, 12,330 of the
 * fail-safe's 12,500 crossings in 318 substeps were an edge that crossed the
 * triangle's plane beside it at x and moved into it, 11,661 of them with an end one
 * spring from the triangle at rest; the zones they made held 1,500-2,000 of the 2,500
 * vertices a frame. With contacts within each cloth only, three such cloths piled on
 * a box still had 9,825 of 10,000 crossings of that kind between cloths (730 zone
 * vertices a frame at rest, strain 0.17); with these, none in 100 frames (strain
 * 0.12). A cloth without self contact pays nothing: flat layers need none (four
 * pressed layers with them: 2.7 times the contacts, detection 3-4 times, a pass 3.5
 * times). Every edge belongs to the first triangle that has it (CC_TEDGE_FIRST), so
 * to one patch; a patch looks up the patches around its box grown by the largest
 * thickness + margin, and the edges of each pair of patches (P, Q >= P; within P,
 * later edges) whose triangles' boxes meet are tested, each pair of edges once. One
 * lookup a patch, not one an edge: the buckets of a pile hold the patches of every
 * layer, and walking them per edge tripled the detection of four pressed layers. A
 * patch's contacts are sorted (by its edge, then the other), so the list does not
 * depend on the hash. */
static void ees_pair(cc_detect *d, uint32_t b, uint32_t bq, uint32_t P, uint32_t Q, float g) {
    const rbc_clothcontact *cc = d->cc;
    const uint32_t *ps = cc->tp.start.ptr, *te = cc->tedge.ptr, *ae = cc->aedge.ptr;
    const uint8_t *eb = cc->eborder.ptr;
    const uint32_t vb = d->vbase[b], vq = d->vbase[bq];
    for (uint32_t t = ps[P]; t < ps[P + 1]; ++t) {
        const float *tb = d->tbox + 6 * (size_t)t;
        /* Pairs by owner triangle: the edge of the lower one asks (Q > P: all of Q's
         * are higher), whatever the patches. */
        for (uint32_t u = P == Q ? t + 1 : ps[Q]; u < ps[Q + 1]; ++u) {
            if (!boxes_overlap(tb, d->tbox + 6 * (size_t)u, g)) continue;
            for (int i = 0; i < 3; ++i) {
                const uint32_t wi = te[3 * (size_t)t + i], e = wi & ~CC_TEDGE_FIRST;
                if (!(wi & CC_TEDGE_FIRST) || eb[e]) continue;
                const uint32_t v0 = ae[2 * (size_t)e], v1 = ae[2 * (size_t)e + 1];
                const float *b0 = d->vbox + 6 * ((size_t)vb + v0), *b1 = d->vbox + 6 * ((size_t)vb + v1);
                float box[6];
                for (int k = 0; k < 3; ++k) {
                    box[k] = min2(b0[k], b1[k]) - g;
                    box[3 + k] = max2(b0[3 + k], b1[3 + k]) + g;
                }
                for (int j = 0; j < 3; ++j) {
                    const uint32_t wj = te[3 * (size_t)u + j], f = wj & ~CC_TEDGE_FIRST;
                    if (!(wj & CC_TEDGE_FIRST) || eb[f]) continue;
                    const uint32_t u0 = ae[2 * (size_t)f], u1 = ae[2 * (size_t)f + 1];
                    const float *c0 = d->vbox + 6 * ((size_t)vq + u0), *c1 = d->vbox + 6 * ((size_t)vq + u1);
                    int out = 0;
                    for (int k = 0; k < 3 && !out; ++k)
                        out = min2(c0[k], c1[k]) > box[3 + k] || max2(c0[3 + k], c1[3 + k]) < box[k];
                    if (out) continue;
                    const uint32_t n0 = *d->n;
                    try_ee(d, bq, u0, u1, b, v0, v1);
                    /* The asking edge's triangle, for the sort (cleared after it). */
                    if (*d->n > n0 && !d->part->full) ((rbc_contact *)d->out->ptr)[n0].flags = t;
                }
            }
        }
    }
}

static int cmp_ee_contact(const void *x, const void *y) {
    const rbc_contact *a = x, *b = y;
    if (a->flags != b->flags) return a->flags < b->flags ? -1 : 1; /* the asking triangle */
    if (a->b != b->b) return a->b < b->b ? -1 : 1;
    if (a->b2 != b->b2) return a->b2 < b->b2 ? -1 : 1;
    if (a->body_a != b->body_a) return a->body_a < b->body_a ? -1 : 1;
    if (a->a != b->a) return a->a < b->a ? -1 : 1;
    return a->a2 < b->a2 ? -1 : a->a2 > b->a2;
}

static int cmp_ee_near(const void *x, const void *y) {
    const rbc_contact *a = x, *b = y;
    if (a->dn != b->dn) return a->dn < b->dn ? -1 : 1;
    return cmp_ee_contact(x, y);
}

/* Interior edge queries (detect_ee_self): patch P of body b asks the patches Q >= P
 * of its own body (with self contact) and of the bodies it collides with where either
 * has self contact. */
typedef struct cc_eesq {
    cc_detect *d;
    const uint8_t *active;
    const rbc_contact_body *B;
    uint32_t b, P;
    float g;
} cc_eesq;

static int eesq_keep(void *ctx, uint32_t Q) {
    const cc_eesq *q = ctx;
    const uint32_t bq = ((const uint32_t *)q->d->cc->tp.body.ptr)[Q];
    if (Q < q->P) return 0;
    if (bq == q->b) return q->B->self != 0;
    return q->active[bq] && (q->B->self || q->d->bodies[bq].self) &&
           bodies_pair(q->B, &q->d->bodies[bq], 0);
}

static void eesq_visit(void *ctx, uint32_t Q) {
    cc_eesq *q = ctx;
    ees_pair(q->d, q->b, ((const uint32_t *)q->d->cc->tp.body.ptr)[Q], q->P, Q, q->g);
}

static void detect_ee_self(cc_detect *d, uint32_t tid, uint32_t nth) {
    rbc_clothcontact *cc = d->cc;
    const uint8_t *active = cc->active.ptr;
    const uint32_t *pbd = cc->tp.body.ptr;
    const float *pab = cc->tp.box.ptr;
    const uint32_t np = cc->tp.n;
    const uint32_t p0 = (uint32_t)((uint64_t)np * tid / nth), p1 = (uint32_t)((uint64_t)np * (tid + 1) / nth);
    for (uint32_t P = p0; P < p1 && !d->oom; ++P) {
        const uint32_t b = pbd[P];
        const rbc_contact_body *B = &d->bodies[b];
        if (!active[b] || !(B->self || B->others)) continue;
        const float g = cc->tri_grow;
        float box[6];
        for (int k = 0; k < 3; ++k) box[k] = pab[6 * (size_t)P + k] - g, box[3 + k] = pab[6 * (size_t)P + 3 + k] + g;
        const uint32_t first = *d->n;
        const uint64_t raw0 = *d->raw;
        cc_eesq eq = {d, active, B, b, P, g};
        patches_near(cc, box, eesq_keep, eesq_visit, &eq);
        {
            /* What the list needs: this patch's pushes (before the cap), and at most the
             * cap for each edge it owns after. */
            const uint64_t pushed = *d->raw - raw0;
            uint64_t owned = 0;
            const uint32_t *ps = cc->tp.start.ptr, *te = cc->tedge.ptr;
            const uint8_t *eb = cc->eborder.ptr;
            for (uint32_t t = ps[P]; t < ps[P + 1]; ++t)
                for (int k = 0; k < 3; ++k) {
                    const uint32_t w = te[3 * (size_t)t + k];
                    owned += (w & CC_TEDGE_FIRST) && !eb[w & ~CC_TEDGE_FIRST];
                }
            const uint64_t capped = owned * RBC_CC_MAX_EE_PER_EDGE;
            d->part->need_ee += pushed < capped ? pushed : capped;
            if (pushed > d->part->ee_run) d->part->ee_run = (uint32_t)(pushed < UINT32_MAX ? pushed : UINT32_MAX);
        }
        if (d->oom || d->part->full) continue;
        rbc_contact *c = (rbc_contact *)d->out->ptr;
        /* By asking triangle, asking edge, then partner: patches are runs of
         * consecutive triangles, so the list (and which edge's cap a pair counts
         * against) does not depend on how the triangles were cut into patches. */
        /* c is NULL while the list is empty: qsort (and c + first) need a real array. */
        if (*d->n > first + 1) qsort(c + first, *d->n - first, sizeof(rbc_contact), cmp_ee_contact);
        /* Each edge's run (by its query edge b, b2): the nearest RBC_CC_MAX_EE_PER_EDGE
         * at p, in partner order. */
        uint32_t out = first;
        for (uint32_t k = first; k < *d->n;) {
            uint32_t m = k + 1;
            while (m < *d->n && c[m].b == c[k].b && c[m].b2 == c[k].b2) ++m;
            if (m - k <= RBC_CC_MAX_EE_PER_EDGE) {
                memmove(c + out, c + k, (size_t)(m - k) * sizeof(rbc_contact));
                out += m - k;
            } else {
                /* Nearest first (the distance at p in dn, which the projection sets
                 * later; ties in partner order), the first RBC_CC_MAX_EE_PER_EDGE kept,
                 * put back in partner order. */
                for (uint32_t j = k; j < m; ++j) {
                    float E[4][3], sp, tp, rr[3];
                    load3(E[0], CONST3(d->bodies[c[j].body_a].p), c[j].a);
                    load3(E[1], CONST3(d->bodies[c[j].body_a].p), c[j].a2);
                    load3(E[2], CONST3(B->p), c[j].b);
                    load3(E[3], CONST3(B->p), c[j].b2);
                    closest_seg_seg(E[0], E[1], E[2], E[3], &sp, &tp);
                    seg_diff(rr, E[0], E[1], sp, E[2], E[3], tp);
                    c[j].dn = dot3(rr, rr);
                    if (!(c[j].dn == c[j].dn)) c[j].dn = INFINITY;
                }
                qsort(c + k, m - k, sizeof(rbc_contact), cmp_ee_near);
                for (uint32_t j = k; j < k + RBC_CC_MAX_EE_PER_EDGE; ++j) c[j].dn = 0.0f;
                qsort(c + k, RBC_CC_MAX_EE_PER_EDGE, sizeof(rbc_contact), cmp_ee_contact);
                memmove(c + out, c + k, RBC_CC_MAX_EE_PER_EDGE * sizeof(rbc_contact));
                out += RBC_CC_MAX_EE_PER_EDGE;
                (*d->capped)++;
            }
            k = m;
        }
        *d->n = out;
        for (uint32_t k = first; k < out; ++k) c[k].flags = 0;
    }
}

/* A part per thread, kept (with their buffers) as the count grows. */
static int parts_reserve(rbc_clothcontact *cc, uint32_t nth) {
    if (nth <= cc->part_cap) return 1;
    const size_t old = (size_t)cc->part_cap * sizeof(cc_part);
    if (!buf_reserve(&cc->alloc, &cc->parts, nth, sizeof(cc_part), old)) return 0;
    memset((char *)cc->parts.ptr + old, 0, (size_t)(nth - cc->part_cap) * sizeof(cc_part));
    cc->part_cap = nth;
    return 1;
}

/* Thread 0's first stage: bodies, boxes, the hashes, and a part per thread. */
static int32_t detect_prepare(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count,
                              float margin, uint32_t nth) {
    const rbc_allocator *al = &cc->alloc;
    cc->count = 0;
    cc->capped = 0;
    cc->body_count = count;
    if (!(margin >= 0.0f)) margin = 0.0f;
    /* Bodies: global numbering, growth, and which take part at all. */
    if (!buf_reserve(al, &cc->vbase, (size_t)count + 1, sizeof(uint32_t), 0) ||
        !buf_reserve(al, &cc->tbase, (size_t)count + 1, sizeof(uint32_t), 0) ||
        !buf_reserve(al, &cc->bgrow, count, sizeof(float), 0) ||
        !buf_reserve(al, &cc->active, count, 1, 0))
        goto oom;
    uint32_t *vbase = cc->vbase.ptr, *tbase = cc->tbase.ptr;
    float *bgrow = cc->bgrow.ptr;
    uint8_t *active = cc->active.ptr;
    uint64_t nv = 0, nt = 0;
    float thmax = 0.0f;
    for (uint32_t b = 0; b < count; ++b) {
        const rbc_contact_body *B = &bodies[b];
        vbase[b] = (uint32_t)nv;
        tbase[b] = (uint32_t)nt;
        nv += B->n;
        nt += B->tri_count;
        active[b] = (B->self || B->others) && B->n > 0;
        bgrow[b] = B->thickness + 0.5f * margin;
        if (active[b] && B->thickness > thmax) thmax = B->thickness;
    }
    if (nv > UINT32_MAX || nt > UINT32_MAX) goto oom;
    vbase[count] = (uint32_t)nv;
    tbase[count] = (uint32_t)nt;
    if (!buf_reserve(al, &cc->vbox, nv, 6 * sizeof(float), 0) ||
        !buf_reserve(al, &cc->tbox, nt, 6 * sizeof(float), 0) ||
        !buf_reserve(al, &cc->trec, nt, CC_TREC * sizeof(float), 0) ||
        !buf_reserve(al, &cc->vbody, nv, sizeof(uint32_t), 0) ||
        !buf_reserve(al, &cc->tbody, nt, sizeof(uint32_t), 0))
        goto oom;
    float *vbox = cc->vbox.ptr, *tbox = cc->tbox.ptr, *trec = cc->trec.ptr;
    uint32_t *vbody = cc->vbody.ptr, *tbody = cc->tbody.ptr;

    /* Swept boxes, and the mean longest edge at x of the active triangles. */
    double edge_sum = 0.0;
    uint64_t edge_count = 0;
    for (uint32_t b = 0; b < count; ++b) {
        const rbc_contact_body *B = &bodies[b];
        for (uint32_t i = 0; i < B->n; ++i) {
            float *o = vbox + 6 * ((size_t)vbase[b] + i);
            vbody[vbase[b] + i] = b;
            for (int k = 0; k < 3; ++k) {
                float u = B->x[k][i], v = B->p[k][i];
                o[k] = u < v ? u : v;
                o[3 + k] = u < v ? v : u;
            }
        }
        for (uint32_t t = 0; t < B->tri_count; ++t) {
            const uint32_t *tri = B->tris + 3 * (size_t)t;
            float *o = tbox + 6 * ((size_t)tbase[b] + t);
            tbody[tbase[b] + t] = b;
            for (int k = 0; k < 3; ++k) {
                float lo = B->x[k][tri[0]], hi = lo;
                for (int c = 0; c < 3; ++c) {
                    float u = B->x[k][tri[c]], v = B->p[k][tri[c]];
                    lo = u < lo ? u : lo;
                    hi = u > hi ? u : hi;
                    lo = v < lo ? v : lo;
                    hi = v > hi ? v : hi;
                }
                o[k] = lo;
                o[3 + k] = hi;
            }
            if (!active[b]) continue;
            tri_record(B, tri, trec + CC_TREC * ((size_t)tbase[b] + t));
            float P[3][3], e[3];
            for (int c = 0; c < 3; ++c) load3(P[c], B->x, tri[c]);
            float longest = 0.0f;
            for (int c = 0; c < 3; ++c) {
                sub3(e, P[(c + 1) % 3], P[c]);
                float l = dot3(e, e);
                longest = l > longest ? l : longest;
            }
            longest = sqrtf(longest);
            if (isfinite(longest)) {
                edge_sum += longest;
                edge_count++;
            }
        }
    }
    /* Body-level broad phase: a body without self contact whose swept box (grown by
     * its reach) meets no other colliding body's takes no part this time (a cloth
     * falling alone pays for its boxes, not for the hash or the queries). */
    if (!buf_reserve(al, &cc->bbox, count, 6 * sizeof(float), 0)) goto oom;
    float *bb = cc->bbox.ptr;
    for (uint32_t b = 0; b < count; ++b) {
        float *o = bb + 6 * (size_t)b;
        o[0] = o[1] = o[2] = INFINITY;
        o[3] = o[4] = o[5] = -INFINITY;
        if (!active[b]) continue;
        const float g = bodies[b].thickness + margin;
        for (uint32_t i = 0; i < bodies[b].n; ++i) {
            const float *v = vbox + 6 * ((size_t)vbase[b] + i);
            for (int k = 0; k < 3; ++k) {
                o[k] = v[k] - g < o[k] ? v[k] - g : o[k];
                o[3 + k] = v[3 + k] + g > o[3 + k] ? v[3 + k] + g : o[3 + k];
            }
        }
    }
    for (uint32_t b = 0; b < count; ++b) {
        if (!active[b] || bodies[b].self) continue;
        int partner = 0;
        for (uint32_t o = 0; o < count && !partner; ++o)
            partner = o != b && active[o] && bodies[o].others && bodies[b].others &&
                      boxes_overlap(bb + 6 * (size_t)b, bb + 6 * (size_t)o, 0.0f);
        if (!partner) active[b] = 0;
    }
    thmax = 0.0f;
    for (uint32_t b = 0; b < count; ++b)
        if (active[b] && bodies[b].thickness > thmax) thmax = bodies[b].thickness;

    cc->tri_grow = thmax + margin;
    float cell = 2.0f * cc->tri_grow;
    if (edge_count && edge_sum / (double)edge_count > cell) cell = (float)(edge_sum / (double)edge_count);
    if (!(cell > 0.0f) || !isfinite(cell)) cell = 1.0f;
    cc->cell = cell;
    cc->inv_cell = 1.0f / cell;

    if (!patches_build(cc, &cc->tp, tbox) ||
        !hash_build(cc, &cc->th, cc->tp.n, cc->tp.box.ptr, cc->tp.body.ptr, NULL, cc->tri_grow,
                    active) ||
        !hash_build(cc, &cc->vh, (uint32_t)nv, vbox, vbody, bgrow, 0.0f, active))
        goto oom;

    /* Every body's edges (kept while its triangles stay the same). */
    if (!border_edges(cc, bodies, count)) goto oom;
    uint64_t nactive = 0;
    cc->any_self = 0;
    for (uint32_t b = 0; b < count; ++b)
        if (active[b]) {
            nactive += bodies[b].n;
            cc->any_self |= bodies[b].self != 0;
        }
    cc->dbodies = bodies;
    cc->dmargin = margin;
    uint64_t ninterior = 0; /* interior edges of self-colliding bodies */
    for (uint32_t b = 0; b < count; ++b)
        if (active[b] && (bodies[b].self || (cc->any_self && bodies[b].others)))
            for (uint32_t e = ((const uint32_t *)cc->abase.ptr)[b]; e < ((const uint32_t *)cc->abase.ptr)[b + 1]; ++e)
                ninterior += !((const uint8_t *)cc->eborder.ptr)[e];
    cc->dcap = (size_t)(RBC_CC_MAX_TOTAL_PER_VERTEX * nactive + RBC_CC_MAX_EE_PER_EDGE * ninterior + 4096);
    if (!parts_reserve(cc, nth)) goto oom;
    return RBC_OK;
oom:
    cc->count = 0;
    return RBC_ERR_OUT_OF_MEMORY;
}


/* What a vertex's run of contacts needs and keeps (after its queries). */
static void vertex_done(cc_detect *d, uint32_t first, uint64_t raw_first) {
    cc_part *part = d->part;
    if (!d->oom && !part->full) *d->n = sort_partners(d->out->ptr, first, *d->n);
    if (!d->oom && !part->full && !keep_nearest(d, first)) d->oom = 1;
    const uint64_t run = *d->raw - raw_first;
    *(d->raw == &part->raw_vt ? &part->need_vt : &part->need_vv) +=
        run < RBC_CC_MAX_PER_VERTEX ? run : RBC_CC_MAX_PER_VERTEX;
    if (run > part->near_need) part->near_need = (uint32_t)(run < UINT32_MAX ? run : UINT32_MAX);
}

/* Vertex v against the triangle patches near its swept box (pair_ok: which of the
 * first 64 bodies its body collides with; later bodies are judged in try_vt). */
static void vt_vertex(cc_detect *d, uint32_t v, const uint8_t *pair_ok) {
    const rbc_clothcontact *cc = d->cc;
    const uint32_t first = *d->n;
    const uint64_t raw_first = *d->raw;
    const float *lo = d->vbox + 6 * (size_t)v, *hi = lo + 3;
    const uint32_t *ps = cc->tp.start.ptr, *pbd = cc->tp.body.ptr;
    const float *pab = cc->tp.box.ptr, *tbox = d->tbox;
    const uint8_t *active = cc->active.ptr;
    cc_vq q;
    vq_load(d, v, &q);
    const float vgrow = q.g, inv = cc->inv_cell;
    cc_range r;
    box_range(lo, hi, inv, &r);
    const uint64_t cells = range_cells(&r);
    /* A box in one cell meets every object there once (per bucket copy). */
    const int one_cell = cells == 1;
    if (cells > cc->th.scan_cells) {
        /* Every patch, in order (so every triangle in order, as the hash would find
         * them after vertex_done's sort). */
        for (uint32_t k = 0; k < cc->tp.n; ++k) {
            if (!active[pbd[k]] || !boxes_overlap(lo, pab + 6 * (size_t)k, vgrow)) continue;
            for (uint32_t t = ps[k]; t < ps[k + 1]; ++t)
                if (boxes_overlap(lo, tbox + 6 * (size_t)t, vgrow)) try_vt(d, &q, t);
        }
    } else {
        const cc_hash *h = &cc->th;
        const uint32_t *start = h->start.ptr, *id = h->id.ptr;
        int32_t c[3];
        for (c[0] = r.lo[0]; c[0] <= r.hi[0]; ++c[0])
            for (c[1] = r.lo[1]; c[1] <= r.hi[1]; ++c[1])
                for (c[2] = r.lo[2]; c[2] <= r.hi[2]; ++c[2]) {
                    const uint32_t bk = cell_bucket(cell_key(c[0], c[1], c[2]), h->nb - 1);
                    for (uint32_t e = start[bk]; e < start[bk + 1]; ++e) {
                        const uint32_t k = id[e];
                        /* Bodies that do not collide (a cloth's own triangles without
                         * self contact: most of a cell) first. */
                        if (pbd[k] < 64 && !pair_ok[pbd[k]]) continue;
                        /* The exact box test first: it rejects most, and is cheaper
                         * than the lower-corner test. */
                        if (!boxes_overlap(lo, pab + 6 * (size_t)k, vgrow)) continue;
                        if (!one_cell) {
                            float olo[3], ohi[3];
                            grown_box(pab, k, cc->tri_grow, olo, ohi);
                            if (!lower_corner_is(lo, olo, inv, c)) continue;
                        }
                        for (uint32_t t = ps[k]; t < ps[k + 1]; ++t)
                            if (boxes_overlap(lo, tbox + 6 * (size_t)t, vgrow)) try_vt(d, &q, t);
                    }
                }
        const uint32_t *big = h->big.ptr;
        for (uint32_t m = 0; m < h->big_count; ++m) {
            const uint32_t k = big[m];
            if (!boxes_overlap(lo, pab + 6 * (size_t)k, vgrow)) continue;
            for (uint32_t t = ps[k]; t < ps[k + 1]; ++t)
                if (boxes_overlap(lo, tbox + 6 * (size_t)t, vgrow)) try_vt(d, &q, t);
        }
    }
    vertex_done(d, first, raw_first);
}

/* Vertex v against the vertices after it whose grown boxes meet its own. */
static void vv_vertex(cc_detect *d, uint32_t v) {
    const rbc_clothcontact *cc = d->cc;
    const uint32_t first = *d->n;
    const uint64_t raw_first = *d->raw;
    const float *vbox = d->vbox, *bgrow = d->bgrow;
    const uint32_t *vbody = d->vbody;
    const uint8_t *active = cc->active.ptr;
    const float vg = bgrow[vbody[v]], inv = cc->inv_cell;
    const float *vb = vbox + 6 * (size_t)v;
    float lo[3], hi[3];
    grown_box(vbox, v, vg, lo, hi);
    cc_range r;
    box_range(lo, hi, inv, &r);
    const uint64_t cells = range_cells(&r);
    const int one_cell = cells == 1;
    const uint32_t nvall = ((const uint32_t *)cc->vbase.ptr)[cc->body_count];
    if (cells > cc->vh.scan_cells) {
        for (uint32_t u = v + 1; u < nvall; ++u)
            if (active[vbody[u]] && boxes_overlap(vb, vbox + 6 * (size_t)u, vg + bgrow[vbody[u]]))
                try_vv(d, v, u);
    } else {
        const cc_hash *h = &cc->vh;
        const uint32_t *start = h->start.ptr, *id = h->id.ptr;
        int32_t c[3];
        for (c[0] = r.lo[0]; c[0] <= r.hi[0]; ++c[0])
            for (c[1] = r.lo[1]; c[1] <= r.hi[1]; ++c[1])
                for (c[2] = r.lo[2]; c[2] <= r.hi[2]; ++c[2]) {
                    const uint32_t bk = cell_bucket(cell_key(c[0], c[1], c[2]), h->nb - 1);
                    /* A bucket's entries ascend: those after v are at its end. */
                    for (uint32_t e = start[bk + 1]; e > start[bk];) {
                        const uint32_t u = id[--e];
                        if (u <= v) break;
                        const float ug = bgrow[vbody[u]];
                        if (!boxes_overlap(vb, vbox + 6 * (size_t)u, vg + ug)) continue;
                        if (!one_cell) {
                            float olo[3], ohi[3];
                            grown_box(vbox, u, ug, olo, ohi);
                            if (!lower_corner_is(lo, olo, inv, c)) continue;
                        }
                        try_vv(d, v, u);
                    }
                }
        const uint32_t *big = h->big.ptr;
        for (uint32_t m = 0; m < h->big_count; ++m)
            if (big[m] > v && boxes_overlap(vb, vbox + 6 * (size_t)big[m], vg + bgrow[vbody[big[m]]]))
                try_vv(d, v, big[m]);
    }
    vertex_done(d, first, raw_first);
}

/* Every thread's stage: the vertex-triangle and vertex-vertex contacts of vertices
 * [n tid / nth, n (tid + 1) / nth), each vertex's sorted on its own, into the
 * thread's lists (in vertex order, so their concatenation in thread order is the
 * single thread's list). */
static void detect_range(rbc_clothcontact *cc, uint32_t tid, uint32_t nth) {
    const rbc_contact_body *bodies = cc->dbodies;
    const uint32_t count = cc->body_count;
    const uint32_t *vbase = cc->vbase.ptr, *tbase = cc->tbase.ptr;
    const uint32_t *vbody = cc->vbody.ptr, *tbody = cc->tbody.ptr;
    const float *vbox = cc->vbox.ptr, *tbox = cc->tbox.ptr, *trec = cc->trec.ptr;
    const float *bgrow = cc->bgrow.ptr;
    const uint8_t *active = cc->active.ptr;
    const uint32_t nvall = vbase[count];
    const uint32_t v_begin = (uint32_t)((uint64_t)nvall * tid / nth),
                   v_end = (uint32_t)((uint64_t)nvall * (tid + 1) / nth);
    cc_part *part = (cc_part *)cc->parts.ptr + tid;
    part->nvt = part->nvv = part->nee = part->capped = 0;
    part->oom = part->over = part->full = 0;
    part->raw_vt = part->raw_vv = part->raw_ee = part->need_vt = part->need_vv = part->need_ee = 0;
    part->near_need = part->ee_run = 0;
    cc_detect d = {cc, bodies, vbase, tbase, vbody, tbody, vbox, tbox, trec, bgrow,
                   cc->dmargin, 0, cc->dcap, 0, &part->vt, &part->nvt, &part->nearest,
                   &part->capped, part, &part->raw_vt, {0}};

    /* Vertex-triangle: each vertex looks up the triangles around its swept box. */
    uint32_t pair_body = UINT32_MAX;
    uint8_t pair_ok[64];
    for (uint32_t v = v_begin; v < v_end && !d.oom; ++v) {
        const uint32_t bv = vbody[v];
        if (!active[bv]) continue;
        if (bv != pair_body) {
            for (uint32_t b = 0; b < 64; ++b)
                pair_ok[b] = b >= count ||
                             (active[b] && bodies_pair(&bodies[bv], &bodies[b], b == bv));
            pair_body = bv;
        }
        vt_vertex(&d, v, pair_ok);
    }
    /* Vertex-vertex: each vertex looks up the vertices after it. */
    d.out = &part->vv;
    d.n = &part->nvv;
    d.raw = &part->raw_vv;
    for (uint32_t v = v_begin; v < v_end && !d.oom; ++v)
        if (active[vbody[v]]) vv_vertex(&d, v);
    /* Edge-edge within self-colliding bodies. */
    if (cc->any_self) {
        d.out = &part->ee;
        d.n = &part->nee;
        d.raw = &part->raw_ee;
        detect_ee_self(&d, tid, nth);
    }
    part->oom = d.oom && !d.over;
    part->over = d.over;
}

/* Thread 0's last stage: the threads' lists joined in order (vertex-triangle, then
 * vertex-vertex), then the edge contacts. */
/* The particles contact c moves (global indices): the vertex and the triangle's
 * corners, the two vertices, or the two edges' ends. */
static uint32_t contact_particles(const rbc_contact *c, const rbc_contact_body *bodies,
                                  const uint32_t *vbase, uint32_t g[4]) {
    const uint32_t ga = vbase[c->body_a], gb = vbase[c->body_b];
    g[0] = ga + c->a;
    if (c->kind == RBC_CONTACT_VT) {
        const uint32_t *tri = bodies[c->body_b].tris + 3 * (size_t)c->b;
        g[1] = gb + tri[0], g[2] = gb + tri[1], g[3] = gb + tri[2];
        return 4;
    }
    if (c->kind == RBC_CONTACT_EE) {
        g[1] = ga + c->a2, g[2] = gb + c->b, g[3] = gb + c->b2;
        return 4;
    }
    g[1] = gb + c->b;
    return 2;
}

/* No groups: the whole list is the rest (thread 0's). */
static void groups_none(rbc_clothcontact *cc) {
    for (uint32_t g = 0; g < CC_GROUPS; ++g) cc->gstart[g] = 0;
    cc->gstart[CC_GROUPS] = cc->count;
    for (int k = 0; k < 4; ++k) cc->phase[k] = CC_GROUPS - 1;
}

/* After detection, the list is sorted (stably) into groups that let the threads
 * share the contact pass. The scene is cut across its longest axis into K slabs of
 * about equal vertex counts (K from the contact count alone), and each particle
 * takes the slab of its position at p. A contact whose particles all lie in slab s
 * is in group s (phase 1); one that spans slabs s and s + 1 is in a group of phase 2
 * (s even) or 3 (s odd); any other is in the rest. Groups of one phase share no
 * particle, so the threads project them at once, each group in list order, with
 * the result of projecting them one after the other: a pass gives the same bits for
 * any thread count, and needs three barriers. (The pass ran on one thread in
 * detection order: a quarter of the four-layer scene's time. A greedy coloring of
 * the contacts needed 42 colors there, a barrier each: docs/design/cloth-contact.md.)
 * The sort runs on every thread (group_assign, group_scatter): on thread 0 alone it
 * cost the four layers 9 % on one thread. */

/* Thread 0: the slabs (cc->cslab per particle) and K; 0 = out of memory. */
static int group_prepare(rbc_clothcontact *cc, const rbc_contact_body *bodies, uint32_t nth) {
    const uint32_t n = cc->count, count = cc->body_count;
    const uint32_t *vbase = cc->vbase.ptr;
    const uint8_t *active = cc->active.ptr;
    const uint32_t nv = vbase[count];
    groups_none(cc);
    cc->gk = 0;
    uint32_t K = n / CC_SLAB_MIN;
    if (K > CC_SLABS) K = CC_SLABS;
    if (K < 2) return 1;
    if (!buf_reserve(&cc->alloc, &cc->cslab, nv, 1, 0) ||
        !buf_reserve(&cc->alloc, &cc->cscratch, n, sizeof(rbc_contact), 0) ||
        !buf_reserve(&cc->alloc, &cc->cgroup, n, 1, 0) ||
        !buf_reserve(&cc->alloc, &cc->gcount, (size_t)nth * CC_GROUPS, sizeof(uint32_t), 0))
        return 0;
    /* The longest axis of the colliding vertices at p. */
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t b = 0; b < count; ++b) {
        if (!active[b]) continue;
        for (int k = 0; k < 3; ++k) {
            const float *c = bodies[b].p[k];
            for (uint32_t i = 0; i < bodies[b].n; ++i) lo[k] = min2(lo[k], c[i]), hi[k] = max2(hi[k], c[i]);
        }
    }
    int ax = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[ax] - lo[ax]) ax = k;
    const float ext = hi[ax] - lo[ax];
    if (!(ext > 0.0f) || !isfinite(ext)) return 1;
    const float scale = (float)CC_SLAB_BINS / ext;
#define CC_BIN(v) ((uint32_t)fminf(fmaxf(((v) - lo[ax]) * scale, 0.0f), (float)(CC_SLAB_BINS - 1)))
    uint32_t hist[CC_SLAB_BINS] = {0};
    uint64_t total = 0;
    for (uint32_t b = 0; b < count; ++b) {
        if (!active[b]) continue;
        const float *c = bodies[b].p[ax];
        for (uint32_t i = 0; i < bodies[b].n; ++i) hist[CC_BIN(c[i])]++;
        total += bodies[b].n;
    }
    /* Slab of a bin: by the vertices before it, so slabs hold about total / K each. */
    uint8_t slab_of[CC_SLAB_BINS];
    uint64_t before = 0;
    for (uint32_t b = 0; b < CC_SLAB_BINS; ++b) {
        slab_of[b] = (uint8_t)(before * K / total);
        before += hist[b];
    }
    uint8_t *slab = cc->cslab.ptr;
    for (uint32_t b = 0; b < count; ++b) {
        if (!active[b]) continue;
        const float *c = bodies[b].p[ax];
        for (uint32_t i = 0; i < bodies[b].n; ++i) slab[vbase[b] + i] = slab_of[CC_BIN(c[i])];
    }
#undef CC_BIN
    cc->gk = K;
    return 1;
}

/* Every thread: the groups of its share of the list, counted. Groups in the order
 * they run: slabs 0 .. K-1; pairs (0,1), (2,3), ...; pairs (1,2), (3,4), ...; the
 * rest. */
static void group_assign(rbc_clothcontact *cc, const rbc_contact_body *bodies, uint32_t tid,
                         uint32_t nth) {
    const uint32_t K = cc->gk, n = cc->count;
    const uint32_t even = K / 2, odd = (K - 1) / 2, rest = K + even + odd;
    const uint32_t *vbase = cc->vbase.ptr;
    const uint8_t *slab = cc->cslab.ptr;
    const rbc_contact *list = cc->contacts.ptr;
    uint8_t *group = cc->cgroup.ptr;
    uint32_t *size = (uint32_t *)cc->gcount.ptr + (size_t)tid * CC_GROUPS;
    for (uint32_t g = 0; g < CC_GROUPS; ++g) size[g] = 0;
    const uint32_t m0 = (uint32_t)((uint64_t)n * tid / nth), m1 = (uint32_t)((uint64_t)n * (tid + 1) / nth);
    for (uint32_t m = m0; m < m1; ++m) {
        uint32_t g[4];
        const uint32_t np = contact_particles(&list[m], bodies, vbase, g);
        uint32_t smin = slab[g[0]], smax = smin;
        for (uint32_t k = 1; k < np; ++k) {
            const uint32_t sk = slab[g[k]];
            smin = sk < smin ? sk : smin, smax = sk > smax ? sk : smax;
        }
        const uint32_t gr = smin == smax       ? smin
                            : smax != smin + 1 ? rest
                            : (smin & 1)       ? K + even + smin / 2
                                               : K + smin / 2;
        group[m] = (uint8_t)gr;
        size[gr]++;
    }
}

/* Thread 0: where each thread's contacts of each group go (groups in order, threads
 * in order within a group: the stable sort), and the groups' starts. */
static void group_offsets(rbc_clothcontact *cc, uint32_t nth) {
    const uint32_t K = cc->gk;
    const uint32_t even = K / 2, odd = (K - 1) / 2, rest = K + even + odd;
    uint32_t *size = cc->gcount.ptr, at = 0;
    for (uint32_t g = 0; g < CC_GROUPS; ++g) {
        cc->gstart[g] = at;
        for (uint32_t t = 0; t < nth; ++t) {
            const uint32_t c = size[(size_t)t * CC_GROUPS + g];
            size[(size_t)t * CC_GROUPS + g] = at; /* now the thread's next slot */
            at += c;
        }
    }
    cc->gstart[CC_GROUPS] = at;
    cc->phase[0] = 0, cc->phase[1] = K, cc->phase[2] = K + even, cc->phase[3] = rest;
}

/* Every thread: its share of the list into the scratch list at its slots. */
static void group_scatter(rbc_clothcontact *cc, uint32_t tid, uint32_t nth) {
    const uint32_t n = cc->count;
    const rbc_contact *list = cc->contacts.ptr;
    const uint8_t *group = cc->cgroup.ptr;
    uint32_t *next = (uint32_t *)cc->gcount.ptr + (size_t)tid * CC_GROUPS;
    rbc_contact *out = cc->cscratch.ptr;
    const uint32_t m0 = (uint32_t)((uint64_t)n * tid / nth), m1 = (uint32_t)((uint64_t)n * (tid + 1) / nth);
    for (uint32_t m = m0; m < m1; ++m) out[next[group[m]]++] = list[m];
}

static int32_t detect_finish(rbc_clothcontact *cc, uint32_t nth) {
    const rbc_contact_body *bodies = cc->dbodies;
    cc->count = 0;
    groups_none(cc);
    const uint32_t count = cc->body_count;
    cc_part *parts = cc->parts.ptr;
    uint64_t total = 0;
    int over = 0, oom = 0;
    for (uint32_t t = 0; t < nth; ++t) {
        total += (uint64_t)parts[t].nvt + parts[t].nvv + parts[t].nee;
        over |= parts[t].over;
        oom |= parts[t].oom;
        cc->capped += parts[t].capped;
    }
    if (total > cc->dcap) over = 1;
    if (over) {
        cc->count = 0;
        return RBC_ERR_UNSTABLE;
    }
    if (oom || !buf_reserve(&cc->alloc, &cc->contacts, (size_t)total, sizeof(rbc_contact), 0))
        goto oom;
    rbc_contact *list = cc->contacts.ptr;
    cc->count = 0;
    for (int kind = 0; kind < 3; ++kind)
        for (uint32_t t = 0; t < nth; ++t) {
            const uint32_t n = kind == 0 ? parts[t].nvt : kind == 1 ? parts[t].nvv : parts[t].nee;
            const cc_buf *l = kind == 0 ? &parts[t].vt : kind == 1 ? &parts[t].vv : &parts[t].ee;
            if (n) memcpy(list + cc->count, l->ptr, (size_t)n * sizeof(rbc_contact));
            cc->count += n;
        }
    cc_detect d = {cc, bodies, cc->vbase.ptr, cc->tbase.ptr, cc->vbody.ptr, cc->tbody.ptr,
                   cc->vbox.ptr, cc->tbox.ptr, cc->trec.ptr, cc->bgrow.ptr, cc->dmargin, 0,
                   cc->dcap, 0, &cc->contacts, &cc->count, NULL, NULL, NULL, NULL, {0}};
    /* Edge against border edge (the edges were found in detect_prepare). */
    (void)count;
    if (!d.oom) detect_ee(&d, cc->active.ptr, count);
    if (d.over) {
        cc->count = 0;
        return RBC_ERR_UNSTABLE;
    }
    if (d.oom) goto oom;
    return RBC_OK;
oom:
    cc->count = 0;
    return RBC_ERR_OUT_OF_MEMORY;
}


int32_t rbc_clothcontact_detect_mt(rbc_clothcontact *cc, rbc_contact_body *bodies,
                                   uint32_t count, float margin, uint32_t tid, uint32_t nth,
                                   void (*sync)(void *), void *sync_ctx) {
    if (nth == 0) nth = 1;
    if (tid == 0) cc->stage_rc = detect_prepare(cc, bodies, count, margin, nth);
    if (sync) sync(sync_ctx);
    while (cc->stage_rc == RBC_OK) {
        detect_range(cc, tid, nth);
        if (sync) sync(sync_ctx);
        /* Thread 0 grows what was full (to what was counted, which bounds what is
         * kept) and the stage runs again: a steady scene stops allocating. */
        if (tid == 0) {
            cc->regrow = 0;
            cc_part *parts = cc->parts.ptr;
            for (uint32_t t = 0; t < nth && cc->stage_rc == RBC_OK; ++t) {
                cc_part *pt = &parts[t];
                if (!pt->full || pt->over) continue;
                const uint64_t nvt = pt->need_vt + pt->near_need, nvv = pt->need_vv + pt->near_need;
                if (!buf_reserve(&cc->alloc, &pt->vt, (size_t)(nvt + nvt / 4 + 64),
                                 sizeof(rbc_contact), 0) ||
                    !buf_reserve(&cc->alloc, &pt->vv, (size_t)(nvv + nvv / 4 + 64),
                                 sizeof(rbc_contact), 0) ||
                    !buf_reserve(&cc->alloc, &pt->ee,
                                 (size_t)(pt->need_ee + pt->ee_run + pt->need_ee / 4 + 64),
                                 sizeof(rbc_contact), 0) ||
                    !buf_reserve(&cc->alloc, &pt->nearest, (size_t)pt->near_need + 64,
                                 sizeof(cc_key), 0))
                    cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
                else
                    cc->regrow = 1;
            }
        }
        if (sync) sync(sync_ctx);
        if (!cc->regrow) break;
        if (sync) sync(sync_ctx); /* everyone has read it */
    }
    if (tid == 0 && cc->stage_rc == RBC_OK) {
        cc->stage_rc = detect_finish(cc, nth);
        if (cc->stage_rc == RBC_OK && !group_prepare(cc, cc->dbodies, nth)) {
            cc->count = 0;
            groups_none(cc);
            cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
        }
    }
    if (sync) sync(sync_ctx);
    if (cc->stage_rc == RBC_OK && cc->gk) {
        group_assign(cc, cc->dbodies, tid, nth);
        if (sync) sync(sync_ctx);
        if (tid == 0) group_offsets(cc, nth);
        if (sync) sync(sync_ctx);
        group_scatter(cc, tid, nth);
        if (sync) sync(sync_ctx);
        if (tid == 0) {
            cc_buf t = cc->contacts;
            cc->contacts = cc->cscratch;
            cc->cscratch = t;
        }
        if (sync) sync(sync_ctx);
    }
    return cc->stage_rc;
}

int32_t rbc_clothcontact_detect(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count,
                                float margin) {
    return rbc_clothcontact_detect_mt(cc, bodies, count, margin, 0, 1, NULL, NULL);
}

/* ---- projection and friction ------------------------------------------------ */

static inline float inv_mass(const rbc_contact_body *B, uint32_t i) {
    if (B->pinned && B->pinned[i]) return 0.0f;
    if (!B->mass) return 1.0f;
    return B->mass[i] > 0.0f ? 1.0f / B->mass[i] : 0.0f;
}

/* Move vertex i of A by +f dir and the triangle point (corners of T by weights w) by
 * -f dir in total, split by inverse mass: vertex im_a / den, corner k im_k w_k / den. */
static inline void apply(const rbc_contact_body *A, uint32_t i, float ima,
                         const rbc_contact_body *T, const uint32_t *tri, const float im[3],
                         const float w[3], const float dv[3]) {
    if (ima > 0.0f)
        for (int k = 0; k < 3; ++k) A->p[k][i] += ima * dv[k];
    for (int c = 0; c < 3; ++c) {
        const float f = im[c] * w[c];
        if (f > 0.0f)
            for (int k = 0; k < 3; ++k) T->p[k][tri[c]] -= f * dv[k];
    }
}

/* What one contact asks for at the current iterate: a relative move of viol along
 * dir of the vertex against the triangle point (weights w). */
typedef struct cc_eval {
    float viol, dir[3], w[3], im[3], ima;
    float vmax;                 /* the most a pass corrects (viol is the violation) */
    int held;                   /* VT: the flag RBC_CONTACT_HELD for the next pass */
    float ee_s, ima2;           /* EE: the edge's parameter, its second end's inverse mass */
    const uint32_t *tri;        /* the triangle's corners, or one[] (the other vertex) */
    uint32_t one[3];
} cc_eval;

/* Vertex-vertex and edge-edge: the points r apart (r = a - b) are kept target apart,
 * along r while they are on the side of n0 (their direction at x), else back along
 * n0 (they crossed over, or lie on top of each other). 1 and e->viol, e->dir set if
 * violated. */
static int apart(cc_eval *e, const float r[3], const float n0[3], float target) {
    const float r2 = dot3(r, r), along = dot3(r, n0);
    if (along >= 0.0f && r2 > 0.0f) {
        if (r2 >= target * target) return 0;
        const float l = sqrtf(r2);
        e->viol = target - l;
        for (int k = 0; k < 3; ++k) e->dir[k] = r[k] / l;
    } else {
        if (along >= target) return 0;
        e->viol = target - along;
        for (int k = 0; k < 3; ++k) e->dir[k] = n0[k];
    }
    return 1;
}

/* 1 and e filled if contact c is violated. */
static int evaluate(const rbc_contact *c, const rbc_contact_body *bodies, cc_eval *e) {
    const rbc_contact_body *A = &bodies[c->body_a], *B = &bodies[c->body_b];
    float q[3];
    load3(q, CONST3(A->p), c->a);
    e->w[0] = 1.0f, e->w[1] = 0.0f, e->w[2] = 0.0f;
    e->im[0] = e->im[1] = e->im[2] = 0.0f;
    e->held = 1;
    e->vmax = INFINITY;
    if (c->kind == RBC_CONTACT_VT) {
        const uint32_t *tri = B->tris + 3 * (size_t)c->b;
        float P[3][3], e1[3], e2[3], n[3], r[3], cp[3];
        for (int k = 0; k < 3; ++k) load3(P[k], CONST3(B->p), tri[k]);
        sub3(e1, P[1], P[0]);
        sub3(e2, P[2], P[0]);
        cross3(n, e1, e2);
        const float nn2 = dot3(n, n), th = A->thickness;
        if (!(nn2 > 0.0f)) {
            e->held = (c->flags & RBC_CONTACT_HELD) != 0; /* no plane: no news */
            return 0;
        }
        const float nsl[3] = {n[0], n[1], n[2]};
        /* Most contacts are not touching: on their side at >= th from the plane means
         * >= th from the triangle too, so no closest point and no square root. */
        sub3(r, q, P[0]);
        const float hn = c->side * dot3(r, n); /* |n| times the plane distance */
        if (hn > 0.0f && hn * hn >= th * th * nn2) return 0;
        const float nn = sqrtf(nn2);
        for (int k = 0; k < 3; ++k) n[k] *= c->side / nn; /* toward the vertex's side */
        closest_bary(q, P[0], P[1], P[2], e->w);
        bary_point(cp, e->w, P[0], P[1], P[2]);
        sub3(r, q, cp);
        const float dn = dot3(r, n), r2 = dot3(r, r);
        if ((c->flags & RBC_CONTACT_THIN) || tri_sliver(P[0], P[1], P[2], nsl)) {
            /* A sliver: its plane says nothing; keep th from the closest point. A
             * vertex deep on its far side is not held (the sliver may unfold with it
             * there, which is not the solve moving it through). */
            e->held = dn >= -th;
            if (r2 >= th * th || !(r2 > 0.0f)) return 0;
            const float l = sqrtf(r2);
            e->viol = th - l;
            for (int k = 0; k < 3; ++k) e->dir[k] = r[k] / l;
        } else if (r2 - dn * dn <= th * th) {
            /* Over the triangle (its projection on the plane is within th of the
             * triangle): the plane constraint n . (q - cp) >= th, n on its side. */
            if (dn >= th) return 0;
            /* Deeper than th on the far side of the plane: not a pass through this
             * triangle since the last pass (the passes run every iteration and would
             * have caught it shallow), unless detection saw the vertex's motion go
             * through it (RBC_CONTACT_CROSSED). It got there around the triangle, by
             * the plane turning, or pushed by other contacts; pushing it back across
             * was the largest move of a pass (up to 16 mm in the funnel, at 3 mm
             * thickness), and those moves fed each other in a pile until it tore. */
            /* Unless it was held at the last pass: then one iteration of the solve
             * moved it through (in the funnel's landing pile, 90 % of the edges the
             * fail-safe found through a triangle had a contact with it, most left
             * alone by this rule). */
            if (dn < -th && !(c->flags & (RBC_CONTACT_CROSSED | RBC_CONTACT_HELD))) {
                e->held = 0;
                return 0;
            }
            e->viol = th - dn;
            /* A held vertex found deep moves back at most twice the thickness a pass
             * (the rest in the next passes). Unbounded, those pushes fed each other in
             * the funnel's settling pile: kinetic energy went from 1.5 to 3.9 J in
             * frames 52-55 and the largest strain to 2.6; capped, the pile settles
             * (0.07 J by frame 60, strain 0.42). */
            if (dn < -th && !(c->flags & RBC_CONTACT_CROSSED)) e->vmax = 2.0f * th;
            for (int k = 0; k < 3; ++k) e->dir[k] = n[k];
        } else if (dn >= 0.0f) {
            /* Beside it, on its side: keep th from the closest point. */
            if (r2 >= th * th) return 0;
            const float l = sqrtf(r2);
            e->viol = th - l;
            for (int k = 0; k < 3; ++k) e->dir[k] = r[k] / l;
        } else if (c->flags & RBC_CONTACT_CROSSED) {
            /* Beside it on the other side, after going through it: back to the plane. */
            e->viol = th - dn;
            for (int k = 0; k < 3; ++k) e->dir[k] = n[k];
        } else {
            e->held = 0;
            return 0; /* beside it on the other side: around the edge, or a neighbour's */
        }
        e->tri = tri;
        for (int k = 0; k < 3; ++k) e->im[k] = inv_mass(B, tri[k]);
    } else if (c->kind == RBC_CONTACT_EE) {
        float a0[3], a1[3], b0[3], b1[3], r[3], s, t;
        load3(a0, CONST3(A->p), c->a);
        load3(a1, CONST3(A->p), c->a2);
        load3(b0, CONST3(B->p), c->b);
        load3(b1, CONST3(B->p), c->b2);
        closest_seg_seg(a0, a1, b0, b1, &s, &t);
        seg_diff(r, a0, a1, s, b0, b1, t);
        const float target = A->thickness > B->thickness ? A->thickness : B->thickness;
        /* Crossed over: the edge went around the border. */
        if (!apart(e, r, c->n0, target)) return 0;
        /* The edge's ends as "vertex" a (weight 1 - s) and a2 (weight s, in slot 3 of
         * the partner's weights, applied on A's side); the border edge's as corners
         * b (1 - t) and b2 (t). */
        e->one[0] = c->b, e->one[1] = c->b2, e->one[2] = c->a2;
        e->tri = e->one;
        e->w[0] = 1.0f - t, e->w[1] = t, e->w[2] = 0.0f;
        e->im[0] = inv_mass(B, c->b);
        e->im[1] = inv_mass(B, c->b2);
        e->im[2] = 0.0f;
        e->ee_s = s;
        e->ima = inv_mass(A, c->a);
        e->ima2 = inv_mass(A, c->a2);
        return 1;
    } else {
        float o[3], r[3];
        load3(o, CONST3(B->p), c->b);
        sub3(r, q, o);
        const float target = A->thickness + B->thickness;
        if (!apart(e, r, c->n0, target)) return 0;
        e->one[0] = e->one[1] = e->one[2] = c->b;
        e->tri = e->one;
        e->im[0] = inv_mass(B, c->b);
    }
    e->ima = inv_mass(A, c->a);
    return 1;
}

/* Edge-edge: the point s of edge a a2 and the point t of edge b b2 apart by viol along
 * dir, split by the weights (1 - s, s, 1 - t, t) and inverse masses. */
static void project_ee(rbc_contact_body *bodies, rbc_contact *c, const cc_eval *e) {
    const float s = e->ee_s, wa0 = 1.0f - s, wa1 = s;
    const float den = wa0 * wa0 * e->ima + wa1 * wa1 * e->ima2 + e->w[0] * e->w[0] * e->im[0] +
                      e->w[1] * e->w[1] * e->im[1];
    if (!(den > 0.0f)) return;
    const float lam = e->viol / den;
    rbc_contact_body *A = &bodies[c->body_a], *B = &bodies[c->body_b];
    for (int k = 0; k < 3; ++k) {
        const float dv = lam * e->dir[k];
        A->p[k][c->a] += e->ima * wa0 * dv;
        A->p[k][c->a2] += e->ima2 * wa1 * dv;
        B->p[k][c->b] -= e->im[0] * e->w[0] * dv;
        B->p[k][c->b2] -= e->im[1] * e->w[1] * dv;
    }
    for (int k = 0; k < 3; ++k) c->n[k] = e->dir[k];
    c->w[0] = s, c->w[1] = e->w[1], c->w[2] = 0.0f;
    if (e->viol > c->dn) c->dn = e->viol;
}

/* One pass over contacts [from, to) in list order; the largest violation found. */
static float project_range(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t from,
                           uint32_t to) {
    rbc_contact *list = cc->contacts.ptr;
    float worst = 0.0f;
    for (uint32_t m = from; m < to; ++m) {
        rbc_contact *c = &list[m];
        cc_eval e;
        const int v = evaluate(c, bodies, &e);
        if (c->kind == RBC_CONTACT_VT)
            c->flags = e.held ? c->flags | RBC_CONTACT_HELD : c->flags & ~(uint32_t)RBC_CONTACT_HELD;
        if (!v) continue;
        if (e.viol > worst) worst = e.viol;
        if (e.viol > e.vmax) e.viol = e.vmax;
        if (c->kind == RBC_CONTACT_EE) {
            project_ee(bodies, c, &e);
            continue;
        }
        const float den = e.ima + e.w[0] * e.w[0] * e.im[0] + e.w[1] * e.w[1] * e.im[1] +
                          e.w[2] * e.w[2] * e.im[2];
        if (!(den > 0.0f)) continue; /* everything pinned */
        /* One Gauss-Seidel update of a linearised inequality (PBD): the
         * relative move along dir is lam (ima + sum w_k^2 im_k) = viol (Mueller 2007). */
        const float lam = e.viol / den;
        const float dv[3] = {lam * e.dir[0], lam * e.dir[1], lam * e.dir[2]};
        apply(&bodies[c->body_a], c->a, e.ima, &bodies[c->body_b], e.tri, e.im, e.w, dv);
        for (int k = 0; k < 3; ++k) c->n[k] = e.dir[k], c->w[k] = e.w[k];
        if (e.viol > c->dn) c->dn = e.viol;
    }
    return worst;
}

float rbc_clothcontact_project(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count) {
    if (count != cc->body_count) return 0.0f;
    return project_range(cc, bodies, 0, cc->count);
}

void rbc_clothcontact_project_mt(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count,
                                 uint32_t tid, uint32_t nth, void (*sync)(void *),
                                 void *sync_ctx) {
    if (count != cc->body_count) return;
    /* The groups are those of the list (a failed detection leaves none). */
    const int grouped = cc->gstart[CC_GROUPS] == cc->count;
    const uint32_t *gs = cc->gstart, last = grouped ? cc->phase[3] : 0;
    if (nth > 1 && sync && grouped) {
        for (int ph = 0; ph < 3; ++ph) {
            /* This thread's run of the phase's groups, one after the other. */
            const uint32_t g0 = cc->phase[ph], ng = cc->phase[ph + 1] - g0;
            if (ng == 0) continue;
            const uint32_t a = g0 + ng * tid / nth, b = g0 + ng * (tid + 1) / nth;
            if (a < b) project_range(cc, bodies, gs[a], gs[b]);
            sync(sync_ctx);
        }
    } else if (tid == 0) {
        project_range(cc, bodies, 0, gs[last]);
    }
    if (tid == 0) project_range(cc, bodies, grouped ? gs[last] : 0, cc->count);
}

float rbc_clothcontact_violation(const rbc_clothcontact *cc, const rbc_contact_body *bodies,
                                 uint32_t count) {
    if (count != cc->body_count) return 0.0f;
    const rbc_contact *list = cc->contacts.ptr;
    float worst = 0.0f;
    for (uint32_t m = 0; m < cc->count; ++m) {
        cc_eval e;
        if (evaluate(&list[m], bodies, &e) && e.viol > worst) worst = e.viol;
    }
    return worst;
}

void rbc_clothcontact_friction(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count) {
    if (count != cc->body_count) return;
    rbc_contact *list = cc->contacts.ptr;
    for (uint32_t m = 0; m < cc->count; ++m) {
        const rbc_contact *c = &list[m];
        if (!(c->dn > 0.0f) || c->kind == RBC_CONTACT_EE) continue; /* EE: no friction */
        const rbc_contact_body *A = &bodies[c->body_a], *B = &bodies[c->body_b];
        const float mu = A->friction > B->friction ? A->friction : B->friction;
        const float limit = mu * c->dn;
        if (!(limit > 0.0f)) continue;
        uint32_t tri_one[3] = {c->b, c->b, c->b};
        const uint32_t *tri = c->kind == RBC_CONTACT_VT ? B->tris + 3 * (size_t)c->b : tri_one;
        float im[3] = {0.0f, 0.0f, 0.0f};
        const int corners = c->kind == RBC_CONTACT_VT ? 3 : 1;
        const float ima = inv_mass(A, c->a);
        /* Relative displacement over the substep: vertex minus triangle point. */
        float rel[3];
        for (int k = 0; k < 3; ++k) {
            rel[k] = A->p[k][c->a] - A->x[k][c->a];
            for (int j = 0; j < corners; ++j)
                rel[k] -= c->w[j] * (B->p[k][tri[j]] - B->x[k][tri[j]]);
        }
        for (int j = 0; j < corners; ++j) im[j] = inv_mass(B, tri[j]);
        const float rn = dot3(rel, c->n);
        float t[3];
        for (int k = 0; k < 3; ++k) t[k] = rel[k] - rn * c->n[k];
        const float tl = sqrtf(dot3(t, t));
        if (!(tl > 0.0f)) continue;
        /* Static: remove it all; kinetic: shorten it by mu dn (Macklin 2014). */
        const float keep = tl < limit ? 0.0f : 1.0f - limit / tl;
        const float den = ima + c->w[0] * c->w[0] * im[0] + c->w[1] * c->w[1] * im[1] +
                          c->w[2] * c->w[2] * im[2];
        if (!(den > 0.0f)) continue;
        const float f = -(1.0f - keep) / den;
        float dv[3] = {f * t[0], f * t[1], f * t[2]};
        apply(A, c->a, ima, B, tri, im, c->w, dv);
    }
}

/* ---- fail-safe ------------------------------------------------------------------- */

/* Signed volume of (b - a, c - a, d - a), in double from the floats. */
static double orient3d(const float a[3], const float b[3], const float c[3], const float d[3]) {
    const double u0 = (double)b[0] - a[0], u1 = (double)b[1] - a[1], u2 = (double)b[2] - a[2];
    const double v0 = (double)c[0] - a[0], v1 = (double)c[1] - a[1], v2 = (double)c[2] - a[2];
    const double w0 = (double)d[0] - a[0], w1 = (double)d[1] - a[1], w2 = (double)d[2] - a[2];
    return u0 * (v1 * w2 - v2 * w1) - u1 * (v0 * w2 - v2 * w0) + u2 * (v0 * w1 - v1 * w0);
}

/* 1: segment pq crosses triangle abc properly (p, q strictly on either side of its
 * plane, the line through the inside). */
static int seg_crosses_tri(const float p[3], const float q[3], const float a[3], const float b[3],
                           const float c[3]) {
    const double sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
    if (!((sp > 0.0 && sq < 0.0) || (sp < 0.0 && sq > 0.0))) return 0;
    const double s1 = orient3d(p, q, a, b), s2 = orient3d(p, q, b, c), s3 = orient3d(p, q, c, a);
    return (s1 > 0.0 && s2 > 0.0 && s3 > 0.0) || (s1 < 0.0 && s2 < 0.0 && s3 < 0.0);
}

/* fr[v]: 0 = untouched, r + 1 = moved by round r. */
typedef struct cc_fs {
    rbc_clothcontact *cc;
    rbc_contact_body *bodies;
    cc_part *part;              /* where this thread records the crossings it finds */
    const cc_hash *h;           /* the patches P, hashed by their boxes grown by hgrow */
    const cc_patches *P;
    float hgrow;
} cc_fs;

/* Edge u0 u1 of body ba against triangle t (global): if the edge crosses the triangle
 * at p, record it (all five vertices go back to x when the round's scan is over). */
static void failsafe_pair(cc_fs *f, uint32_t ba, uint32_t u0, uint32_t u1, const float box[6],
                          uint32_t t) {
    rbc_clothcontact *cc = f->cc;
    const uint32_t bt = ((const uint32_t *)cc->tbody.ptr)[t];
    rbc_contact_body *A = &f->bodies[ba], *T = &f->bodies[bt];
    if (!bodies_pair(A, T, ba == bt)) return;
    const uint32_t *tbase = cc->tbase.ptr, *vbase = cc->vbase.ptr;
    const uint32_t *tri = T->tris + 3 * (size_t)(t - tbase[bt]);
    if (ba == bt && (tri[0] == u0 || tri[1] == u0 || tri[2] == u0 || tri[0] == u1 ||
                     tri[1] == u1 || tri[2] == u1))
        return;
    float C[3][3];
    for (int k = 0; k < 3; ++k) load3(C[k], CONST3(T->p), tri[k]);
    for (int k = 0; k < 3; ++k)
        if (min2(C[0][k], min2(C[1][k], C[2][k])) > box[3 + k] ||
            max2(C[0][k], max2(C[1][k], C[2][k])) < box[k])
            return;
    float P0[3], P1[3];
    load3(P0, CONST3(A->p), u0);
    load3(P1, CONST3(A->p), u1);
    if (!seg_crosses_tri(P0, P1, C[0], C[1], C[2])) return;
    /* Crossing at x too: a tangle older than this substep, which neither a zone's
     * mean motion nor a stop at x can undo. Stopping it (the rule for a zone that
     * crosses again) held its vertices where they were, substep after substep, while
     * the rest of their cloths moved on: in the funnel, vertices on the spout's axis
     * stayed put for frames on end until their springs were 3 times their length. It
     * is left to the contacts, which keep each vertex on its side at x and so do not
     * make it deeper. */
    float X0[3], X1[3], D[3][3];
    load3(X0, A->x, u0);
    load3(X1, A->x, u1);
    for (int k = 0; k < 3; ++k) load3(D[k], T->x, tri[k]);
    if (seg_crosses_tri(X0, X1, D[0], D[1], D[2])) return;
    (void)vbase;
    cc_part *part = f->part;
    (void)cc;
    part->hits_need++;
    if ((size_t)part->nhits >= part->hits.bytes / (4 * sizeof(uint32_t))) {
        part->full = 1; /* thread 0 grows the list and the scan runs again */
        return;
    }
    uint32_t *h = (uint32_t *)part->hits.ptr + 4 * (size_t)part->nhits++;
    h[0] = ba, h[1] = u0, h[2] = u1, h[3] = t;
}

/* The triangles whose hashed boxes meet box (lo, hi at p), each once: the edge u0 u1
 * of body ba against each (tri_other = UINT32_MAX), or, for triangle tri_other, the
 * edges of each against it. The hashed boxes hold x..p of the prediction grown by the
 * largest thickness + margin, which the solve's moves stay within. */
static void failsafe_query(cc_fs *f, const float lo[3], const float hi[3], uint32_t ba,
                           uint32_t u0, uint32_t u1, uint32_t tri_other) {
    const rbc_clothcontact *cc = f->cc;
    const cc_hash *h = f->h;
    const uint32_t *start = h->start.ptr, *id = h->id.ptr, *big = h->big.ptr;
    const uint32_t *tbody = cc->tbody.ptr, *tbase = cc->tbase.ptr;
    const float *pbox = cc->pbox.ptr, inv = cc->inv_cell;
    const float box[6] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
    cc_range r;
    box_range(lo, hi, inv, &r);
    const int all = range_cells(&r) > h->scan_cells;
    const uint8_t *active = cc->active.ptr;
    /* An edge's query skips the triangles of bodies it does not collide with first
     * (its own, without self contact: the nearest triangles, and a quarter of a
     * four-layer pile's). */
    const rbc_contact_body *A = tri_other == UINT32_MAX ? &f->bodies[ba] : NULL;
#define CC_FS_VISIT(T)                                                                      \
    do {                                                                                    \
        const uint32_t t_ = (T);                                                            \
        if (tri_other == UINT32_MAX) {                                                      \
            failsafe_pair(f, ba, u0, u1, box, t_);                                          \
        } else {                                                                            \
            const uint32_t b_ = tbody[t_];                                                  \
            const uint32_t *tr_ = f->bodies[b_].tris + 3 * (size_t)(t_ - tbase[b_]);         \
            for (int k_ = 0; k_ < 3; ++k_) {                                                \
                const uint32_t a_ = tr_[k_], c_ = tr_[(k_ + 1) % 3];                        \
                float e0_[3], e1_[3], eb_[6];                                               \
                load3(e0_, CONST3(f->bodies[b_].p), a_);                                    \
                load3(e1_, CONST3(f->bodies[b_].p), c_);                                    \
                for (int j_ = 0; j_ < 3; ++j_)                                              \
                    eb_[j_] = min2(e0_[j_], e1_[j_]), eb_[3 + j_] = max2(e0_[j_], e1_[j_]); \
                failsafe_pair(f, b_, a_, c_, eb_, tri_other);                               \
            }                                                                               \
        }                                                                                   \
    } while (0)
    int32_t c[3];
    /* Patches: body (edge queries) and box first, then each triangle's box at p; each
     * patch once (in the cell of the lower corner of its hashed box's intersection
     * with the query). Round 0's (fp) are hashed by their boxes at p; later rounds'
     * (tp) by the swept boxes grown by thickness + margin, which hold the boxes at p
     * of every round. */
    const cc_patches *P = f->P;
    const uint32_t *ps = P->start.ptr, *pbd = P->body.ptr;
    const float *pab = P->box.ptr, pg = f->hgrow;
#define CC_FS_PATCH(K)                                                                      \
    do {                                                                                    \
        const uint32_t pk_ = (K);                                                           \
        for (uint32_t g_ = ps[pk_]; g_ < ps[pk_ + 1]; ++g_)                                 \
            if (boxes_overlap(box, pbox + 6 * (size_t)g_, 0.0f)) CC_FS_VISIT(g_);           \
    } while (0)
    if (all) {
        /* Every patch in order: every triangle in order, as before patches. */
        for (uint32_t k = 0; k < P->n; ++k)
            if (active[pbd[k]] && (!A || bodies_pair(A, &f->bodies[pbd[k]], pbd[k] == ba)) &&
                boxes_overlap(box, pab + 6 * (size_t)k, pg))
                CC_FS_PATCH(k);
        return;
    }
    for (c[0] = r.lo[0]; c[0] <= r.hi[0]; ++c[0])
        for (c[1] = r.lo[1]; c[1] <= r.hi[1]; ++c[1])
            for (c[2] = r.lo[2]; c[2] <= r.hi[2]; ++c[2]) {
                const uint32_t bk = cell_bucket(cell_key(c[0], c[1], c[2]), h->nb - 1);
                for (uint32_t q = start[bk]; q < start[bk + 1]; ++q) {
                    const uint32_t k = id[q];
                    if (A && !bodies_pair(A, &f->bodies[pbd[k]], pbd[k] == ba)) continue;
                    if (!boxes_overlap(box, pab + 6 * (size_t)k, pg)) continue;
                    float olo[3], ohi[3];
                    grown_box(pab, k, pg, olo, ohi);
                    if (!lower_corner_is(lo, olo, inv, c)) continue;
                    CC_FS_PATCH(k);
                }
            }
    for (uint32_t m = 0; m < h->big_count; ++m) {
        const uint32_t k = big[m];
        if ((!A || bodies_pair(A, &f->bodies[pbd[k]], pbd[k] == ba)) &&
            boxes_overlap(box, pab + 6 * (size_t)k, pg))
            CC_FS_PATCH(k);
    }
#undef CC_FS_PATCH
#undef CC_FS_VISIT
}

/* Boxes at p of this thread's share of the triangles (of colliding bodies). */
static void failsafe_boxes(rbc_clothcontact *cc, const rbc_contact_body *bodies, uint32_t tid,
                           uint32_t nth) {
    const uint32_t count = cc->body_count, *tbase = cc->tbase.ptr;
    const uint8_t *active = cc->active.ptr;
    float *pb = cc->pbox.ptr;
    const uint32_t ntr = tbase[count];
    const uint32_t t0 = (uint32_t)((uint64_t)ntr * tid / nth), t1 = (uint32_t)((uint64_t)ntr * (tid + 1) / nth);
    for (uint32_t b = 0; b < count; ++b) {
        const uint32_t tb = tbase[b] > t0 ? tbase[b] : t0, te = tbase[b + 1] < t1 ? tbase[b + 1] : t1;
        if (!active[b]) {
            for (uint32_t g = tb; g < te; ++g) /* an empty box: meets nothing */
                for (int k = 0; k < 3; ++k) pb[6 * (size_t)g + k] = INFINITY, pb[6 * (size_t)g + 3 + k] = -INFINITY;
            continue;
        }
        const rbc_contact_body *B = &bodies[b];
        for (uint32_t g = tb; g < te; ++g) {
            const uint32_t *tri = B->tris + 3 * (size_t)(g - tbase[b]);
            float *o = pb + 6 * (size_t)g;
            for (int k = 0; k < 3; ++k) {
                const float a = B->p[k][tri[0]], c = B->p[k][tri[1]], e = B->p[k][tri[2]];
                o[k] = min2(a, min2(c, e));
                o[3 + k] = max2(a, max2(c, e));
            }
        }
    }
}

/* One thread's scan of a round: its share of the edges (round 0: all of them; later
 * rounds: those with a vertex the last round froze) against the triangles, and of
 * the triangles with a corner the last round froze against the edges. */

static void failsafe_scan(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t round,
                          uint32_t tid, uint32_t nth) {
    const uint32_t count = cc->body_count;
    const uint32_t *vbase = cc->vbase.ptr, *tbase = cc->tbase.ptr, *abase = cc->abase.ptr;
    const uint32_t *ae = cc->aedge.ptr;
    const uint8_t *active = cc->active.ptr, *fr = cc->frozen.ptr;
    const uint8_t last = (uint8_t)round; /* fr of the vertices the last round froze */
    cc_part *part = (cc_part *)cc->parts.ptr + tid;
    part->nhits = part->hits_need = 0;
    part->oom = part->full = 0;
    /* Triangles are looked up by their boxes at the round's start (patches hashed
     * just before it): far fewer per cell than the swept boxes grown by thickness +
     * margin. */
    cc_fs f = {cc, bodies, part, &cc->fh, &cc->fp, 0.0f};
    const uint32_t ne = abase[count], ntr = tbase[count];
    const uint32_t e0 = (uint32_t)((uint64_t)ne * tid / nth), e1 = (uint32_t)((uint64_t)ne * (tid + 1) / nth);
    const uint32_t t0 = (uint32_t)((uint64_t)ntr * tid / nth), t1 = (uint32_t)((uint64_t)ntr * (tid + 1) / nth);
    for (uint32_t ba = 0; ba < count; ++ba) {
        if (!active[ba]) continue;
        const rbc_contact_body *A = &bodies[ba];
        const uint32_t eb = abase[ba] > e0 ? abase[ba] : e0, ee = abase[ba + 1] < e1 ? abase[ba + 1] : e1;
        for (uint32_t e = eb; e < ee; ++e) {
            const uint32_t u0 = ae[2 * (size_t)e], u1 = ae[2 * (size_t)e + 1];
            if (round && fr[vbase[ba] + u0] != last && fr[vbase[ba] + u1] != last) continue;
            float P0[3], P1[3], lo[3], hi[3];
            load3(P0, CONST3(A->p), u0);
            load3(P1, CONST3(A->p), u1);
            for (int k = 0; k < 3; ++k) lo[k] = min2(P0[k], P1[k]), hi[k] = max2(P0[k], P1[k]);
            failsafe_query(&f, lo, hi, ba, u0, u1, UINT32_MAX);
        }
        if (!round) continue;
        const uint32_t tb = tbase[ba] > t0 ? tbase[ba] : t0, te = tbase[ba + 1] < t1 ? tbase[ba + 1] : t1;
        for (uint32_t g = tb; g < te; ++g) {
            const uint32_t *tri = A->tris + 3 * (size_t)(g - tbase[ba]);
            if (fr[vbase[ba] + tri[0]] != last && fr[vbase[ba] + tri[1]] != last &&
                fr[vbase[ba] + tri[2]] != last)
                continue;
            float C[3][3], lo[3], hi[3];
            for (int k = 0; k < 3; ++k) load3(C[k], CONST3(A->p), tri[k]);
            for (int k = 0; k < 3; ++k) {
                lo[k] = min2(C[0][k], min2(C[1][k], C[2][k]));
                hi[k] = max2(C[0][k], max2(C[1][k], C[2][k]));
            }
            failsafe_query(&f, lo, hi, 0, 0, 0, g);
        }
    }
}

static int cmp_u32(const void *a, const void *b) {
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t zone_find(uint32_t *parent, uint32_t g) {
    while (parent[g] != g) {
        parent[g] = parent[parent[g]];
        g = parent[g];
    }
    return g;
}

enum { CC_ZONE_TOUCHED = 1, CC_ZONE_PINNED = 2, CC_ZONE_REST = 4, CC_ZONE_GREW = 8 };

/* Thread 0, after a round's scan: the five vertices of every crossing found join an
 * impact zone (Bridson, Fedkiw and Anderson 2002; Harmon et al. 2008): zones that
 * share a vertex merge, and every zone this round touched moves rigidly from x by
 * the mass-weighted mean of its vertices' motion over the substep (p - x before the
 * fail-safe). x had no crossing the fail-safe acts on (a pair crossing at x is no
 * hit) and a common translation keeps every pair inside a
 * zone as it was at x, so a zone has none within; crossings with the rest are the
 * next round's. A zone with a pinned vertex, or one found crossing again without
 * growing, goes back to x (stops), which also has none. Stopping every zone
 * instead (the fail-safe before) left stopped vertices where they were while their
 * neighbours moved on: in the funnel's frames 38-42 the
 * largest strain was 0.75-1.8 with it and 0.38-0.75 with no fail-safe at all. Hits in thread
 * order: the same for any thread count. Returns the vertices that moved this round
 * (0: no crossing was found), or UINT32_MAX if a scan ran out of memory. */
static uint32_t failsafe_apply(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t round,
                               uint32_t nth) {
    const uint32_t *vbase = cc->vbase.ptr, *tbase = cc->tbase.ptr, *tbody = cc->tbody.ptr;
    const uint32_t *vbody = cc->vbody.ptr;
    uint8_t *fr = cc->frozen.ptr, *zf = cc->zflag.ptr;
    uint32_t *parent = cc->zparent.ptr, *zl = cc->zlist.ptr;
    float *p0 = cc->zp0.ptr;
    double *sum = cc->zsum.ptr;
    const uint8_t mark = (uint8_t)(round + 1 < 255 ? round + 1 : 255);
    const cc_part *parts = cc->parts.ptr;
    uint32_t changed = 0; /* vertices that joined, zones merged, zones stopped */
    for (uint32_t t = 0; t < nth; ++t) {
        if (parts[t].oom) return UINT32_MAX;
        const uint32_t *h = parts[t].hits.ptr;
        for (uint32_t m = 0; m < parts[t].nhits; ++m, h += 4) {
            const uint32_t bt = tbody[h[3]];
            const uint32_t *tri = bodies[bt].tris + 3 * (size_t)(h[3] - tbase[bt]);
            const uint32_t g[5] = {vbase[h[0]] + h[1], vbase[h[0]] + h[2], vbase[bt] + tri[0],
                                   vbase[bt] + tri[1], vbase[bt] + tri[2]};
            uint32_t root = UINT32_MAX, grew = 0;
            for (int k = 0; k < 5; ++k) {
                const uint32_t v = g[k];
                if (parent[v] == UINT32_MAX) {
                    const rbc_contact_body *B = &bodies[vbody[v]];
                    const uint32_t i = v - vbase[vbody[v]];
                    parent[v] = v;
                    zf[v] = inv_mass(B, i) == 0.0f ? CC_ZONE_PINNED : 0;
                    for (int a = 0; a < 3; ++a) p0[3 * (size_t)v + a] = B->p[a][i];
                    zl[cc->zcount++] = v;
                    grew++;
                }
                const uint32_t r = zone_find(parent, v);
                if (root == UINT32_MAX) {
                    root = r;
                } else if (r != root) {
                    parent[r] = root;
                    zf[root] |= zf[r] & (CC_ZONE_PINNED | CC_ZONE_REST);
                    grew++;
                }
            }
            zf[root] |= CC_ZONE_TOUCHED | (grew ? CC_ZONE_GREW : 0);
            changed += grew;
        }
    }
    /* The zones' vertices in index order: the mean motions below are sums in this
     * order, and the order vertices joined depends on how the round's scan was split
     * over the threads (later rounds scan edges, then triangles, per thread). */
    if (cc->zcount > 1) qsort(zl, cc->zcount, sizeof(uint32_t), cmp_u32);
    /* Flags to the roots; a zone crossing again that neither gained a vertex nor
     * merged in this round stops. Decided per zone after all the round's hits, not
     * per hit: two triangles that pass through each other give two or more hits on
     * the same five or six vertices, and the second of those, taken as "crossing
     * again", stopped zones in their first round (in the funnel, vertices on the
     * spout's axis stayed put for 20 frames while their springs stretched to 2.4
     * times their length). */
    for (uint32_t m = 0; m < cc->zcount; ++m) {
        const uint32_t v = zl[m], r = zone_find(parent, v);
        if (r != v) zf[r] |= zf[v] & (CC_ZONE_TOUCHED | CC_ZONE_PINNED | CC_ZONE_REST | CC_ZONE_GREW);
    }
    for (uint32_t m = 0; m < cc->zcount; ++m) {
        const uint32_t r = zl[m];
        if (zone_find(parent, r) != r) continue;
        if ((zf[r] & (CC_ZONE_TOUCHED | CC_ZONE_GREW | CC_ZONE_REST | CC_ZONE_PINNED)) ==
            CC_ZONE_TOUCHED) {
            zf[r] |= CC_ZONE_REST; /* crossing again, unchanged: stop it */
            changed++;
        }
    }
    /* No crossing, or only ones no zone can change (a stopped zone against a pinned
     * vertex's motion): done. */
    if (!changed) {
        for (uint32_t m = 0; m < cc->zcount; ++m)
            zf[zl[m]] &= (uint8_t) ~(CC_ZONE_TOUCHED | CC_ZONE_GREW);
        return 0;
    }
    /* Each touched zone's mean motion: the sums cleared, then added up. */
    for (uint32_t m = 0; m < cc->zcount; ++m) {
        const uint32_t v = zl[m], r = zone_find(parent, v);
        sum[4 * (size_t)r] = sum[4 * (size_t)r + 1] = sum[4 * (size_t)r + 2] =
            sum[4 * (size_t)r + 3] = 0.0;
    }
    for (uint32_t m = 0; m < cc->zcount; ++m) {
        const uint32_t v = zl[m], r = zone_find(parent, v);
        if (!(zf[r] & CC_ZONE_TOUCHED)) continue;
        const rbc_contact_body *B = &bodies[vbody[v]];
        const uint32_t i = v - vbase[vbody[v]];
        const float im = inv_mass(B, i);
        if (!(im > 0.0f)) continue;
        const double w = 1.0 / im;
        for (int a = 0; a < 3; ++a) sum[4 * (size_t)r + a] += w * ((double)p0[3 * (size_t)v + a] - B->x[a][i]);
        sum[4 * (size_t)r + 3] += w;
    }
    uint32_t moved = 0;
    for (uint32_t m = 0; m < cc->zcount; ++m) {
        const uint32_t v = zl[m], r = zone_find(parent, v);
        if (!(zf[r] & CC_ZONE_TOUCHED)) continue;
        rbc_contact_body *B = &bodies[vbody[v]];
        const uint32_t i = v - vbase[vbody[v]];
        fr[v] = mark;
        moved++;
        if (inv_mass(B, i) == 0.0f) continue; /* pinned: where its pin put it */
        const int rest = (zf[r] & (CC_ZONE_PINNED | CC_ZONE_REST)) || !(sum[4 * (size_t)r + 3] > 0.0);
        for (int a = 0; a < 3; ++a) {
            const double d = rest ? 0.0 : sum[4 * (size_t)r + a] / sum[4 * (size_t)r + 3];
            B->p[a][i] = (float)((double)B->x[a][i] + d);
        }
    }
    for (uint32_t m = 0; m < cc->zcount; ++m) zf[zl[m]] &= (uint8_t) ~(CC_ZONE_TOUCHED | CC_ZONE_GREW);
    return moved;
}

int32_t rbc_clothcontact_failsafe_mt(rbc_clothcontact *cc, rbc_contact_body *bodies,
                                     uint32_t count, uint32_t tid, uint32_t nth,
                                     void (*sync)(void *), void *sync_ctx, uint32_t *frozen) {
    if (nth == 0) nth = 1;
    if (tid == 0) {
        cc->stage_rc = RBC_OK;
        cc->fs_newly = 0;
        const int run = count == cc->body_count && cc->ekey_count;
        const uint32_t nv = run ? ((const uint32_t *)cc->vbase.ptr)[count] : 0;
        if (!run) {
            cc->stage_rc = 1; /* nothing to do */
        } else if (!buf_reserve(&cc->alloc, &cc->frozen, nv ? nv : 1, 1, 0) ||
                   !buf_reserve(&cc->alloc, &cc->pbox,
                                (size_t)((const uint32_t *)cc->tbase.ptr)[count] + 1,
                                6 * sizeof(float), 0) ||
                   !buf_reserve(&cc->alloc, &cc->zparent, nv ? nv : 1, sizeof(uint32_t), 0) ||
                   !buf_reserve(&cc->alloc, &cc->zp0, nv ? nv : 1, 3 * sizeof(float), 0) ||
                   !buf_reserve(&cc->alloc, &cc->zlist, nv ? nv : 1, sizeof(uint32_t), 0) ||
                   !buf_reserve(&cc->alloc, &cc->zsum, nv ? nv : 1, 4 * sizeof(double), 0) ||
                   !buf_reserve(&cc->alloc, &cc->zflag, nv ? nv : 1, 1, 0) ||
                   !parts_reserve(cc, nth)) {
            cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
        } else {
            memset(cc->frozen.ptr, 0, nv);
            memset(cc->zparent.ptr, 0xFF, (size_t)nv * sizeof(uint32_t));
            cc->zcount = 0;
        }
    }
    if (sync) sync(sync_ctx);
    uint32_t total = 0;
    if (cc->stage_rc == RBC_OK) {
        /* Round 0 tests every edge; a later round only what the last one moved: edges
         * with a vertex it froze against all triangles, and triangles with a corner it
         * froze against all edges. Each round freezes another vertex or ends, and a
         * pair whose five vertices are all back at x does not cross (x did not, or the
         * pair is no hit). */
        for (uint32_t round = 0; round < 250; ++round) {
            failsafe_boxes(cc, bodies, tid, nth);
            if (sync) sync(sync_ctx);
            /* Every round hashes the patches by their boxes now: a zone's mean motion can
             * take a triangle outside its swept box grown by thickness + margin (a
             * resting vertex in a zone with a fast one), where the swept hash would
             * miss it. */
            if (tid == 0 &&
                (!patches_build(cc, &cc->fp, cc->pbox.ptr) ||
                 !hash_build(cc, &cc->fh, cc->fp.n, cc->fp.box.ptr, cc->fp.body.ptr, NULL, 0.0f,
                             cc->active.ptr)))
                cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
            if (sync) sync(sync_ctx);
            if (cc->stage_rc != RBC_OK) break;
            failsafe_scan(cc, bodies, round, tid, nth);
            if (sync) sync(sync_ctx);
            /* A full list: thread 0 grows it to what was found and the scan (which
             * only reads) runs again. */
            if (tid == 0) {
                cc->regrow = 0;
                cc_part *parts = cc->parts.ptr;
                for (uint32_t t = 0; t < nth; ++t)
                    if (parts[t].full) {
                        if (!buf_reserve(&cc->alloc, &parts[t].hits,
                                         4 * ((size_t)parts[t].hits_need + 64), sizeof(uint32_t), 0))
                            cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
                        cc->regrow = 1;
                    }
            }
            if (sync) sync(sync_ctx);
            if (cc->stage_rc != RBC_OK) break;
            if (cc->regrow) {
                if (sync) sync(sync_ctx); /* everyone has read it */
                failsafe_scan(cc, bodies, round, tid, nth);
                if (sync) sync(sync_ctx);
            }
            if (tid == 0) {
                const uint32_t newly = failsafe_apply(cc, bodies, round, nth);
                if (newly == UINT32_MAX) cc->stage_rc = RBC_ERR_OUT_OF_MEMORY;
                cc->fs_newly = newly == UINT32_MAX ? 0 : newly;
            }
            if (sync) sync(sync_ctx);
            if (!cc->fs_newly) break;
            if (sync) sync(sync_ctx); /* everyone has read fs_newly */
        }
    }
    const int32_t rc = cc->stage_rc == 1 ? RBC_OK : cc->stage_rc;
    if (cc->stage_rc == RBC_OK) total = cc->zcount;
    if (frozen) *frozen = total;
    if (sync) sync(sync_ctx);
    return rc;
}
