/* viewer.c -- stills (a small software rasterizer + libpng), the WebGL player page
 * and the batch index of a simulated clip. See viewer.h for the strain colour and
 * camera conventions; the page reads every constant below from the meta JSON this
 * file writes, so the still and the page cannot drift apart.
 */
#include "viewer.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "player_html.h" /* generated: rbc_player_html[], from player.html */
#include "rbcloth.h"

#define NEVER UINT32_MAX
#define DEFAULT_MEMORY_BUDGET ((size_t)256 << 20)
#define DEFAULT_PAGE_BUDGET ((size_t)48 << 20)
/* The browser holds the inflated data and its decoded positions (twice as much):
 * keep the inflated size bounded too, whatever deflate achieves. */
#define PAGE_RAW_CAP ((size_t)256 << 20)

/* Shared look: camera, light (view space: x right, y up, z towards the viewer),
 * colours. Strain stops: {strain, r, g, b}; every colour has r > b, every grey
 * r = g = b and the background b > r, so a pixel's kind shows in its hue. */
static const double CAM_AZ_DEG = 35.0, CAM_EL_DEG = 25.0, CAM_FOV_DEG = 30.0, CAM_MARGIN = 1.1;
static const float LIGHT[3] = {-0.3f, 0.4f, 0.85f}; /* mostly from the eye; normalised where used */
static const float AMBIENT = 0.4f;
static const float BG_TOP[3] = {0.86f, 0.89f, 0.94f}, BG_BOTTOM[3] = {0.62f, 0.67f, 0.75f};
static const float COLLIDER_GREY = 0.60f, PLANE_GREY = 0.72f;
enum { STOP_COUNT = 5 };
static const float STOPS[STOP_COUNT][4] = {{0.00f, 0.94f, 0.91f, 0.83f},
                                           {0.02f, 0.98f, 0.90f, 0.55f},
                                           {0.10f, 1.00f, 0.72f, 0.20f},
                                           {0.30f, 0.95f, 0.40f, 0.12f},
                                           {1.00f, 0.80f, 0.08f, 0.08f}};

typedef struct vcloth {
    char *name;
    uint32_t n, nq, nt, ne;
    float *rest;
    uint32_t *quads, *tris;
    uint32_t *quad_removed; /* first frame without the quad, NEVER if it stays */
    uint32_t *edges;        /* ne pairs, deduplicated */
    float *rest_len;
    uint32_t *face_edges;   /* 4 per quad, then 3 per triangle: indices into edges */
    float *frames;          /* stored frames, 3n floats each */
    uint32_t count;         /* frames received */
} vcloth;

typedef struct vcollider {
    int shape;
    float radius, half[3];
    uint32_t mv, mt;
    float *mesh_pos;
    uint32_t *mesh_tris;
    float *poses; /* 7 floats per stored frame */
    uint32_t count;
} vcollider;

struct cli_view {
    char *title;
    double dt;
    uint32_t frame_count, stride, capacity; /* stride, capacity: set by the first frame */
    int started;
    size_t memory_budget, page_budget;
    vcloth *cloths;
    uint32_t cloth_count;
    vcollider *colliders;
    uint32_t collider_count;
    char last_error[256];
};

static void set_err(char *err, size_t len, const char *fmt, ...) {
    if (!err || !len) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, len, fmt, ap);
    va_end(ap);
}

static char *dup_str(const char *s) {
    size_t len = strlen(s) + 1;
    char *d = malloc(len);
    if (d) memcpy(d, s, len);
    return d;
}

/* The array p of `count` elements of `size` bytes with one more, zeroed, at its end;
 * NULL when out of memory (p is kept). */
static void *append_zeroed(void *p, size_t count, size_t size) {
    unsigned char *grown = realloc(p, (count + 1) * size);
    if (grown) memset(grown + count * size, 0, size);
    return grown;
}

static void *dup_mem(const void *src, size_t bytes) {
    void *d = malloc(bytes ? bytes : 1);
    if (d && bytes) memcpy(d, src, bytes);
    return d;
}

static int all_finite(const float *x, size_t count) {
    for (size_t i = 0; i < count; ++i)
        if (!isfinite(x[i])) return 0;
    return 1;
}

/* ------------------------------------------------------------------------- */
/* Building the clip                                                         */
/* ------------------------------------------------------------------------- */

int cli_view_create(cli_view **out, const char *title, double frame_dt, uint32_t frame_count,
                    char *err, size_t errlen) {
    if (!out) return set_err(err, errlen, "cli_view_create: out is NULL"), 1;
    *out = NULL;
    if (!(frame_dt > 0.0) || !isfinite(frame_dt))
        return set_err(err, errlen, "cli_view_create: frame_dt %g is not finite and > 0",
                       frame_dt), 1;
    if (frame_count == 0) return set_err(err, errlen, "cli_view_create: frame_count is 0"), 1;
    cli_view *v = calloc(1, sizeof *v);
    if (v) v->title = dup_str(title ? title : "rbcloth");
    if (!v || !v->title) {
        free(v);
        return set_err(err, errlen, "cli_view_create: out of memory"), 1;
    }
    v->dt = frame_dt;
    v->frame_count = frame_count;
    v->memory_budget = DEFAULT_MEMORY_BUDGET;
    v->page_budget = DEFAULT_PAGE_BUDGET;
    *out = v;
    return 0;
}

int cli_view_set_budget(cli_view *v, size_t memory_bytes, size_t page_bytes, char *err,
                        size_t errlen) {
    if (!v) return set_err(err, errlen, "cli_view_set_budget: view is NULL"), 1;
    if (v->started)
        return set_err(err, errlen, "cli_view_set_budget: frames were already added"), 1;
    if (memory_bytes) v->memory_budget = memory_bytes;
    if (page_bytes) v->page_budget = page_bytes;
    return 0;
}

static int cmp_edge_key(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Deduplicated edges of the faces, and for every face corner the index of its edge:
 * keys (lo << 32 | hi) sorted with their face-corner slot, then runs merged. */
static int build_edges(vcloth *c) {
    size_t slots = (size_t)c->nq * 4 + (size_t)c->nt * 3;
    uint64_t *keys = malloc((slots ? slots : 1) * 2 * sizeof *keys);
    c->face_edges = malloc((slots ? slots : 1) * sizeof *c->face_edges);
    c->edges = malloc((slots ? slots : 1) * 2 * sizeof *c->edges);
    c->rest_len = malloc((slots ? slots : 1) * sizeof *c->rest_len);
    if (!keys || !c->face_edges || !c->edges || !c->rest_len) return free(keys), 1;
    size_t s = 0;
    for (uint32_t q = 0; q < c->nq; ++q)
        for (int k = 0; k < 4; ++k, ++s) {
            uint64_t a = c->quads[4 * q + k], b = c->quads[4 * q + (k + 1) % 4];
            keys[2 * s] = a < b ? a << 32 | b : b << 32 | a;
            keys[2 * s + 1] = s;
        }
    for (uint32_t t = 0; t < c->nt; ++t)
        for (int k = 0; k < 3; ++k, ++s) {
            uint64_t a = c->tris[3 * t + k], b = c->tris[3 * t + (k + 1) % 3];
            keys[2 * s] = a < b ? a << 32 | b : b << 32 | a;
            keys[2 * s + 1] = s;
        }
    qsort(keys, slots, 2 * sizeof *keys, cmp_edge_key);
    c->ne = 0;
    for (size_t i = 0; i < slots; ++i) {
        if (i == 0 || keys[2 * i] != keys[2 * i - 2]) {
            uint32_t a = (uint32_t)(keys[2 * i] >> 32), b = (uint32_t)keys[2 * i];
            const float *pa = c->rest + 3 * (size_t)a, *pb = c->rest + 3 * (size_t)b;
            float dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
            c->edges[2 * c->ne] = a;
            c->edges[2 * c->ne + 1] = b;
            c->rest_len[c->ne++] = sqrtf(dx * dx + dy * dy + dz * dz);
        }
        c->face_edges[keys[2 * i + 1]] = c->ne - 1;
    }
    free(keys);
    return 0;
}

static void free_cloth(vcloth *c) {
    free(c->name), free(c->rest), free(c->quads), free(c->tris), free(c->quad_removed);
    free(c->edges), free(c->rest_len), free(c->face_edges), free(c->frames);
}

int cli_view_add_cloth(cli_view *v, const cli_view_cloth_def *def, char *err, size_t errlen) {
    if (!v || !def) return set_err(err, errlen, "cli_view_add_cloth: %s is NULL", v ? "def" : "view"), 1;
    uint32_t id = v->cloth_count;
    const char *name = def->name ? def->name : "cloth";
    if (v->started)
        return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s) added after the first frame",
                       id, name), 1;
    if (def->vertex_count == 0 || !def->rest)
        return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s) has no vertices or rest "
                       "is NULL", id, name), 1;
    if (def->quad_count + (uint64_t)def->tri_count == 0 || (def->quad_count && !def->quads) ||
        (def->tri_count && !def->tris))
        return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s) has no faces, or quads/tris "
                       "is NULL with a count", id, name), 1;
    if (!all_finite(def->rest, (size_t)def->vertex_count * 3))
        return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s): rest has a non-finite "
                       "coordinate", id, name), 1;
    for (uint64_t i = 0; i < (uint64_t)def->quad_count * 4; ++i)
        if (def->quads[i] >= def->vertex_count)
            return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s): quad %llu has vertex "
                           "%u >= vertex_count %u", id, name, (unsigned long long)(i / 4),
                           def->quads[i], def->vertex_count), 1;
    for (uint64_t i = 0; i < (uint64_t)def->tri_count * 3; ++i)
        if (def->tris[i] >= def->vertex_count)
            return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s): triangle %llu has "
                           "vertex %u >= vertex_count %u", id, name, (unsigned long long)(i / 3),
                           def->tris[i], def->vertex_count), 1;
    vcloth *grown = append_zeroed(v->cloths, id, sizeof *grown);
    if (!grown) return set_err(err, errlen, "cli_view_add_cloth: cloth %u: out of memory", id), 1;
    v->cloths = grown;
    vcloth *c = &v->cloths[id];
    c->n = def->vertex_count, c->nq = def->quad_count, c->nt = def->tri_count;
    c->name = dup_str(name);
    c->rest = dup_mem(def->rest, (size_t)c->n * 3 * sizeof(float));
    c->quads = dup_mem(def->quads, (size_t)c->nq * 4 * sizeof(uint32_t));
    c->tris = dup_mem(def->tris, (size_t)c->nt * 3 * sizeof(uint32_t));
    c->quad_removed = malloc(((size_t)c->nq + 1) * sizeof(uint32_t));
    if (!c->name || !c->rest || !c->quads || !c->tris || !c->quad_removed || build_edges(c)) {
        free_cloth(c);
        return set_err(err, errlen, "cli_view_add_cloth: cloth %u (%s): out of memory", id, name), 1;
    }
    for (uint32_t q = 0; q < c->nq; ++q) c->quad_removed[q] = NEVER;
    v->cloth_count++;
    return 0;
}

int cli_view_add_collider(cli_view *v, const cli_view_collider_def *def, char *err,
                          size_t errlen) {
    if (!v || !def)
        return set_err(err, errlen, "cli_view_add_collider: %s is NULL", v ? "def" : "view"), 1;
    uint32_t id = v->collider_count;
    if (v->started)
        return set_err(err, errlen, "cli_view_add_collider: collider %u added after the first "
                       "frame", id), 1;
    int s = def->shape;
    if (s < RBC_SHAPE_PLANE || s > RBC_SHAPE_TRIANGLE_MESH)
        return set_err(err, errlen, "cli_view_add_collider: collider %u: shape %d is not an "
                       "rbc_shape (1 plane .. 5 triangle mesh)", id, s), 1;
    if ((s == RBC_SHAPE_SPHERE || s == RBC_SHAPE_CAPSULE) && !(def->radius > 0 && isfinite(def->radius)))
        return set_err(err, errlen, "cli_view_add_collider: collider %u: radius %g", id,
                       (double)def->radius), 1;
    if ((s == RBC_SHAPE_BOX || s == RBC_SHAPE_CAPSULE) &&
        (!all_finite(def->half_extents, 3) || def->half_extents[1] <= 0 ||
         (s == RBC_SHAPE_BOX && (def->half_extents[0] <= 0 || def->half_extents[2] <= 0))))
        return set_err(err, errlen, "cli_view_add_collider: collider %u: half_extents must be "
                       "finite and > 0", id), 1;
    if (s == RBC_SHAPE_TRIANGLE_MESH) {
        if (!def->mesh_positions || !def->mesh_triangles || !def->mesh_vertex_count ||
            !def->mesh_triangle_count ||
            !all_finite(def->mesh_positions, (size_t)def->mesh_vertex_count * 3))
            return set_err(err, errlen, "cli_view_add_collider: collider %u: triangle mesh without "
                           "vertices/triangles, or a non-finite position", id), 1;
        for (uint64_t i = 0; i < (uint64_t)def->mesh_triangle_count * 3; ++i)
            if (def->mesh_triangles[i] >= def->mesh_vertex_count)
                return set_err(err, errlen, "cli_view_add_collider: collider %u: triangle %llu has "
                               "vertex %u >= %u", id, (unsigned long long)(i / 3),
                               def->mesh_triangles[i], def->mesh_vertex_count), 1;
    }
    vcollider *grown = append_zeroed(v->colliders, id, sizeof *grown);
    if (!grown) return set_err(err, errlen, "cli_view_add_collider: collider %u: out of memory", id), 1;
    v->colliders = grown;
    vcollider *c = &v->colliders[id];
    c->shape = s, c->radius = def->radius;
    memcpy(c->half, def->half_extents, sizeof c->half);
    if (s == RBC_SHAPE_TRIANGLE_MESH) {
        c->mv = def->mesh_vertex_count, c->mt = def->mesh_triangle_count;
        c->mesh_pos = dup_mem(def->mesh_positions, (size_t)c->mv * 3 * sizeof(float));
        c->mesh_tris = dup_mem(def->mesh_triangles, (size_t)c->mt * 3 * sizeof(uint32_t));
        if (!c->mesh_pos || !c->mesh_tris) {
            free(c->mesh_pos), free(c->mesh_tris);
            return set_err(err, errlen, "cli_view_add_collider: collider %u: out of memory", id), 1;
        }
    }
    v->collider_count++;
    return 0;
}

/* The first frame fixes the stride: every k-th frame is kept so that the floats of
 * all cloths over frame_count frames fit the memory budget. */
static int start_frames(cli_view *v) {
    uint64_t floats = 0;
    for (uint32_t i = 0; i < v->cloth_count; ++i) floats += (uint64_t)v->cloths[i].n * 3;
    uint64_t per_frame = floats * sizeof(float), total = per_frame * v->frame_count;
    uint64_t k = total <= v->memory_budget ? 1 : (total + v->memory_budget - 1) / v->memory_budget;
    v->stride = k > v->frame_count ? v->frame_count : (uint32_t)k;
    v->capacity = (v->frame_count + v->stride - 1) / v->stride;
    for (uint32_t i = 0; i < v->cloth_count; ++i) {
        vcloth *c = &v->cloths[i];
        if (!c->frames) c->frames = malloc((size_t)v->capacity * c->n * 3 * sizeof(float));
        if (!c->frames) {
            snprintf(v->last_error, sizeof v->last_error, "cloth %u: out of memory for %u frames",
                     i, v->capacity);
            return 1;
        }
    }
    for (uint32_t i = 0; i < v->collider_count; ++i) {
        vcollider *c = &v->colliders[i];
        if (!c->poses) c->poses = malloc((size_t)v->capacity * 7 * sizeof(float));
        if (!c->poses) {
            snprintf(v->last_error, sizeof v->last_error, "collider %u: out of memory", i);
            return 1;
        }
    }
    v->started = 1;
    return 0;
}

uint32_t cli_view_frame_total(const cli_view *v) {
    if (!v || !v->started) return 0;
    uint32_t m = UINT32_MAX;
    for (uint32_t i = 0; i < v->cloth_count; ++i)
        if (v->cloths[i].count < m) m = v->cloths[i].count;
    for (uint32_t i = 0; i < v->collider_count; ++i)
        if (v->colliders[i].count < m) m = v->colliders[i].count;
    return m == UINT32_MAX ? 0 : m;
}

const char *cli_view_last_error(const cli_view *v) { return v ? v->last_error : "view is NULL"; }

/* Common checks of a per-frame call; `count` is the object's frames so far. */
static int frame_check(cli_view *v, const char *what, uint32_t id, uint32_t count) {
    if (!v->started && start_frames(v)) return 1;
    uint32_t done = cli_view_frame_total(v);
    if (count > done) {
        snprintf(v->last_error, sizeof v->last_error, "%s %u already has frame %u; the other "
                 "cloths and colliders have %u frame(s)", what, id, count - 1, done);
        return 1;
    }
    if (count >= v->frame_count) {
        snprintf(v->last_error, sizeof v->last_error, "%s %u: frame %u is beyond frame_count %u",
                 what, id, count, v->frame_count);
        return 1;
    }
    return 0;
}

int cli_view_frame_cloth(cli_view *v, uint32_t cloth, const float *xyz) {
    if (!v) return 1;
    v->last_error[0] = '\0';
    if (cloth >= v->cloth_count || !xyz) {
        snprintf(v->last_error, sizeof v->last_error, !xyz ? "cloth %u: positions are NULL"
                 : "cloth %u out of range (%u cloths)", cloth, v->cloth_count);
        return 1;
    }
    vcloth *c = &v->cloths[cloth];
    if (frame_check(v, "cloth", cloth, c->count)) return 1;
    for (size_t i = 0; i < (size_t)c->n * 3; ++i)
        if (!isfinite(xyz[i])) {
            snprintf(v->last_error, sizeof v->last_error, "cloth %u frame %u: vertex %zu is not "
                     "finite", cloth, c->count, i / 3);
            return 1;
        }
    if (c->count % v->stride == 0)
        memcpy(c->frames + (size_t)(c->count / v->stride) * c->n * 3, xyz,
               (size_t)c->n * 3 * sizeof(float));
    c->count++;
    return 0;
}

int cli_view_frame_collider(cli_view *v, uint32_t collider, const float pos[3],
                            const float quat[4]) {
    if (!v) return 1;
    v->last_error[0] = '\0';
    if (collider >= v->collider_count || !pos || !quat) {
        snprintf(v->last_error, sizeof v->last_error, collider >= v->collider_count ?
                 "collider %u out of range (%u colliders)" : "collider %u: pose is NULL",
                 collider, v->collider_count);
        return 1;
    }
    vcollider *c = &v->colliders[collider];
    if (frame_check(v, "collider", collider, c->count)) return 1;
    double qn = sqrt((double)quat[0] * quat[0] + (double)quat[1] * quat[1] +
                     (double)quat[2] * quat[2] + (double)quat[3] * quat[3]);
    if (!all_finite(pos, 3) || !(qn > 1e-6) || !isfinite(qn)) {
        snprintf(v->last_error, sizeof v->last_error, "collider %u frame %u: position not finite "
                 "or quaternion not a rotation", collider, c->count);
        return 1;
    }
    if (c->count % v->stride == 0) {
        float *p = c->poses + (size_t)(c->count / v->stride) * 7;
        for (int k = 0; k < 3; ++k) p[k] = pos[k];
        for (int k = 0; k < 4; ++k) p[3 + k] = (float)(quat[k] / qn);
    }
    c->count++;
    return 0;
}

int cli_view_remove_quad(cli_view *v, uint32_t cloth, uint32_t quad) {
    if (!v) return 1;
    v->last_error[0] = '\0';
    if (cloth >= v->cloth_count || quad >= v->cloths[cloth].nq) {
        snprintf(v->last_error, sizeof v->last_error, cloth >= v->cloth_count ?
                 "cloth %u out of range (%u cloths)" : "cloth %u: quad %u out of range",
                 cloth, cloth >= v->cloth_count ? v->cloth_count : quad);
        return 1;
    }
    vcloth *c = &v->cloths[cloth];
    if (c->quad_removed[quad] != NEVER) {
        snprintf(v->last_error, sizeof v->last_error, "cloth %u: quad %u was already removed at "
                 "frame %u", cloth, quad, c->quad_removed[quad]);
        return 1;
    }
    c->quad_removed[quad] = c->count;
    return 0;
}

int cli_view_set_remaining_quads(cli_view *v, uint32_t cloth, const uint32_t *quads,
                                 size_t quad_count, char *err, size_t errlen) {
    if (!v || cloth >= v->cloth_count || (quad_count && !quads))
        return set_err(err, errlen, "cli_view_set_remaining_quads: %s", !v ? "view is NULL" :
                       cloth >= v->cloth_count ? "cloth out of range" : "quads is NULL"), 1;
    vcloth *c = &v->cloths[cloth];
    /* Both lists are in creation order: one merge pass finds what went, a first pass
     * checks that every remaining quad is a quad of the cloth still there. */
    for (int apply = 0; apply < 2; ++apply) {
        size_t j = 0;
        for (uint32_t q = 0; q < c->nq; ++q) {
            if (c->quad_removed[q] != NEVER) continue;
            if (j < quad_count && !memcmp(quads + 4 * j, c->quads + 4 * (size_t)q, 4 * sizeof *quads))
                ++j;
            else if (apply)
                c->quad_removed[q] = c->count;
        }
        if (j < quad_count)
            return set_err(err, errlen, "cli_view_set_remaining_quads: cloth %u (%s): remaining "
                           "quad %zu is not one of its quads still present, in creation order",
                           cloth, c->name, j), 1;
    }
    return 0;
}

void cli_view_destroy(cli_view *v) {
    if (!v) return;
    for (uint32_t i = 0; i < v->cloth_count; ++i) free_cloth(&v->cloths[i]);
    for (uint32_t i = 0; i < v->collider_count; ++i) {
        free(v->colliders[i].mesh_pos), free(v->colliders[i].mesh_tris);
        free(v->colliders[i].poses);
    }
    free(v->cloths), free(v->colliders), free(v->title), free(v);
}

/* ------------------------------------------------------------------------- */
/* Strain                                                                    */
/* ------------------------------------------------------------------------- */

void cli_view_strain_colour(float strain, float rgb[3]) {
    float s = strain > 0 && isfinite(strain) ? strain : (strain > 0 ? STOPS[STOP_COUNT - 1][0] : 0);
    int i = 1;
    while (i < STOP_COUNT - 1 && s > STOPS[i][0]) ++i;
    float t = (s - STOPS[i - 1][0]) / (STOPS[i][0] - STOPS[i - 1][0]);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    for (int k = 0; k < 3; ++k) rgb[k] = STOPS[i - 1][1 + k] + t * (STOPS[i][1 + k] - STOPS[i - 1][1 + k]);
}

/* Whether quad q / edge e shows in (original) frame f: an edge shows while one of
 * its faces does, so edge_dead is the latest removal over its faces. */
static uint32_t *edge_dead_frames(const vcloth *c) {
    uint32_t *dead = calloc(c->ne ? c->ne : 1, sizeof *dead);
    if (!dead) return NULL;
    for (uint32_t q = 0; q < c->nq; ++q)
        for (int k = 0; k < 4; ++k) {
            uint32_t *d = &dead[c->face_edges[4 * (size_t)q + k]];
            if (c->quad_removed[q] > *d) *d = c->quad_removed[q];
        }
    for (size_t s = (size_t)c->nq * 4; s < (size_t)c->nq * 4 + (size_t)c->nt * 3; ++s)
        dead[c->face_edges[s]] = NEVER;
    return dead;
}

/* Per-vertex strain of positions x at frame f; strain < 0 marks a vertex no visible
 * face uses (left out of bounding boxes and drawn nowhere). */
static void vertex_strain(const vcloth *c, const uint32_t *edge_dead, uint32_t f, const float *x,
                          float *strain) {
    for (uint32_t i = 0; i < c->n; ++i) strain[i] = -1.0f;
    for (uint32_t e = 0; e < c->ne; ++e) {
        if (edge_dead[e] <= f) continue;
        uint32_t a = c->edges[2 * e], b = c->edges[2 * e + 1];
        float s = 0.0f;
        if (c->rest_len[e] > 0.0f) {
            const float *pa = x + 3 * (size_t)a, *pb = x + 3 * (size_t)b;
            float dx = pb[0] - pa[0], dy = pb[1] - pa[1], dz = pb[2] - pa[2];
            s = fabsf(sqrtf(dx * dx + dy * dy + dz * dz) / c->rest_len[e] - 1.0f);
        }
        if (s > strain[a]) strain[a] = s;
        if (s > strain[b]) strain[b] = s;
    }
}

/* ------------------------------------------------------------------------- */
/* Camera and geometry shared by the still                                   */
/* ------------------------------------------------------------------------- */

typedef struct camera {
    double eye[3], right[3], up[3], fwd[3];
    double focal; /* pixels: x_screen = width / 2 + focal * x_view / z_view */
    double target[3], radius;
} camera;

static void camera_fit(camera *cam, const double lo[3], const double hi[3], double w, double h) {
    const double deg = 3.14159265358979323846 / 180.0;
    double az = CAM_AZ_DEG * deg, el = CAM_EL_DEG * deg, fy = CAM_FOV_DEG * deg;
    double fx = 2.0 * atan(w / h * tan(fy / 2.0)), fmin = fx < fy ? fx : fy;
    double r2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        cam->target[k] = 0.5 * (lo[k] + hi[k]);
        r2 += 0.25 * (hi[k] - lo[k]) * (hi[k] - lo[k]);
    }
    double r = sqrt(r2) > 1e-6 ? sqrt(r2) : 1e-6;
    double d = CAM_MARGIN * r / sin(fmin / 2.0);
    double dir[3] = {cos(el) * sin(az), sin(el), cos(el) * cos(az)};
    for (int k = 0; k < 3; ++k) cam->eye[k] = cam->target[k] + d * dir[k], cam->fwd[k] = -dir[k];
    /* right = fwd x (0,1,0), up = right x fwd */
    double rl = sqrt(cam->fwd[2] * cam->fwd[2] + cam->fwd[0] * cam->fwd[0]);
    cam->right[0] = -cam->fwd[2] / rl, cam->right[1] = 0.0, cam->right[2] = cam->fwd[0] / rl;
    cam->up[0] = cam->right[1] * cam->fwd[2] - cam->right[2] * cam->fwd[1];
    cam->up[1] = cam->right[2] * cam->fwd[0] - cam->right[0] * cam->fwd[2];
    cam->up[2] = cam->right[0] * cam->fwd[1] - cam->right[1] * cam->fwd[0];
    cam->focal = (h / 2.0) / tan(fy / 2.0);
    cam->radius = r;
}

static void to_view(const camera *cam, const float p[3], float out[3]) {
    double d[3] = {p[0] - cam->eye[0], p[1] - cam->eye[1], p[2] - cam->eye[2]};
    out[0] = (float)(d[0] * cam->right[0] + d[1] * cam->right[1] + d[2] * cam->right[2]);
    out[1] = (float)(d[0] * cam->up[0] + d[1] * cam->up[1] + d[2] * cam->up[2]);
    out[2] = (float)(d[0] * cam->fwd[0] + d[1] * cam->fwd[1] + d[2] * cam->fwd[2]);
}

static void dir_to_view(const camera *cam, const float n[3], float out[3]) {
    out[0] = (float)(n[0] * cam->right[0] + n[1] * cam->right[1] + n[2] * cam->right[2]);
    out[1] = (float)(n[0] * cam->up[0] + n[1] * cam->up[1] + n[2] * cam->up[2]);
    out[2] = (float)(n[0] * cam->fwd[0] + n[1] * cam->fwd[1] + n[2] * cam->fwd[2]);
}

/* v' = v + 2w (u x v) + 2 u x (u x v), q = (u, w) unit. */
static void quat_rotate(const float q[4], const float vin[3], float out[3]) {
    float t[3] = {2 * (q[1] * vin[2] - q[2] * vin[1]), 2 * (q[2] * vin[0] - q[0] * vin[2]),
                  2 * (q[0] * vin[1] - q[1] * vin[0])};
    out[0] = vin[0] + q[3] * t[0] + (q[1] * t[2] - q[2] * t[1]);
    out[1] = vin[1] + q[3] * t[1] + (q[2] * t[0] - q[0] * t[2]);
    out[2] = vin[2] + q[3] * t[2] + (q[0] * t[1] - q[1] * t[0]);
}

/* ------------------------------------------------------------------------- */
/* Rasterizer: 2 x 2 supersampling, 1/z buffer, two-sided Lambert per sample    */
/* ------------------------------------------------------------------------- */

typedef struct rvert { float p[3], n[3], c[3]; } rvert; /* view space, z forward */

typedef struct raster {
    int w, h;          /* samples */
    float *inv_z, *rgb;
    float light[3];    /* unit, view space with z forward */
    float near_z, focal; /* focal: output pixels; the raster has 2 x 2 samples a pixel */
} raster;

static void shade_sample(const raster *r, size_t s, const float p[3], const float n_in[3],
                         const float c[3]) {
    float len = sqrtf(n_in[0] * n_in[0] + n_in[1] * n_in[1] + n_in[2] * n_in[2]);
    float n[3] = {0, 0, -1};
    if (len > 1e-20f) n[0] = n_in[0] / len, n[1] = n_in[1] / len, n[2] = n_in[2] / len;
    /* Two-sided: cloth has no outside, so the normal always faces the eye. */
    if (n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0) n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
    float lam = n[0] * r->light[0] + n[1] * r->light[1] + n[2] * r->light[2];
    float k = AMBIENT + (1.0f - AMBIENT) * (lam > 0 ? lam : 0);
    for (int i = 0; i < 3; ++i) r->rgb[3 * s + i] = c[i] * k;
}

static void draw_clipped(raster *r, const rvert *v0, const rvert *v1, const rvert *v2) {
    const rvert *v[3] = {v0, v1, v2};
    double sx[3], sy[3], iz[3];
    for (int i = 0; i < 3; ++i) {
        iz[i] = 1.0 / v[i]->p[2];
        sx[i] = r->w / 2.0 + 2.0 * r->focal * v[i]->p[0] * iz[i];
        sy[i] = r->h / 2.0 - 2.0 * r->focal * v[i]->p[1] * iz[i];
    }
    double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
    if (fabs(area) < 1e-12) return;
    double xmin = fmin(sx[0], fmin(sx[1], sx[2])), xmax = fmax(sx[0], fmax(sx[1], sx[2]));
    double ymin = fmin(sy[0], fmin(sy[1], sy[2])), ymax = fmax(sy[0], fmax(sy[1], sy[2]));
    int x0 = xmin < 0 ? 0 : (int)floor(xmin), x1 = xmax >= r->w ? r->w - 1 : (int)ceil(xmax);
    int y0 = ymin < 0 ? 0 : (int)floor(ymin), y1 = ymax >= r->h ? r->h - 1 : (int)ceil(ymax);
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            double px = x + 0.5, py = y + 0.5, b[3];
            b[0] = ((sx[1] - px) * (sy[2] - py) - (sx[2] - px) * (sy[1] - py)) / area;
            b[1] = ((sx[2] - px) * (sy[0] - py) - (sx[0] - px) * (sy[2] - py)) / area;
            b[2] = 1.0 - b[0] - b[1];
            if (b[0] < 0 || b[1] < 0 || b[2] < 0) continue;
            double z = b[0] * iz[0] + b[1] * iz[1] + b[2] * iz[2];
            size_t s = (size_t)y * r->w + x;
            if (z <= r->inv_z[s]) continue;
            r->inv_z[s] = (float)z;
            /* Screen-linear 1/z weights give perspective-correct attributes. */
            float w[3], p[3], n[3], c[3];
            for (int i = 0; i < 3; ++i) w[i] = (float)(b[i] * iz[i] / z);
            for (int k = 0; k < 3; ++k) {
                p[k] = w[0] * v0->p[k] + w[1] * v1->p[k] + w[2] * v2->p[k];
                n[k] = w[0] * v0->n[k] + w[1] * v1->n[k] + w[2] * v2->n[k];
                c[k] = w[0] * v0->c[k] + w[1] * v1->c[k] + w[2] * v2->c[k];
            }
            shade_sample(r, s, p, n, c);
        }
}

static void lerp_vert(const rvert *a, const rvert *b, float t, rvert *o) {
    for (int k = 0; k < 3; ++k) {
        o->p[k] = a->p[k] + t * (b->p[k] - a->p[k]);
        o->n[k] = a->n[k] + t * (b->n[k] - a->n[k]);
        o->c[k] = a->c[k] + t * (b->c[k] - a->c[k]);
    }
}

/* Colliders (a ground plane, a big box) may reach behind the eye: clip against the
 * near plane (Sutherland-Hodgman, one plane) before dividing by z. */
static void raster_tri(raster *r, const rvert *a, const rvert *b, const rvert *c) {
    const rvert *in[3] = {a, b, c};
    rvert out[4];
    int n = 0;
    for (int i = 0; i < 3; ++i) {
        const rvert *p = in[i], *q = in[(i + 1) % 3];
        int pin = p->p[2] >= r->near_z, qin = q->p[2] >= r->near_z;
        if (pin) out[n++] = *p;
        if (pin != qin) lerp_vert(p, q, (r->near_z - p->p[2]) / (q->p[2] - p->p[2]), &out[n++]);
    }
    for (int i = 1; i + 1 < n; ++i) draw_clipped(r, &out[0], &out[i], &out[i + 1]);
}

/* A collider's surface as triangles in view space (grey, normals from the shape):
 * spheres and capsules as latitude-longitude grids (a capsule is a sphere whose
 * halves move apart by 2h, the band between them its cylinder). */
static void raster_collider(raster *r, const camera *cam, const vcollider *c, const float *pose) {
    enum { SEG = 32, RINGS = 16 };
    const float *q = pose + 3;
    float grey = c->shape == RBC_SHAPE_PLANE ? PLANE_GREY : COLLIDER_GREY;
    rvert tri[3];
#define EMIT_LOCAL(slot, px, py, pz, nx, ny, nz)                                               \
    do {                                                                                       \
        float lp_[3] = {(px), (py), (pz)}, ln_[3] = {(nx), (ny), (nz)}, wp_[3], wn_[3];        \
        quat_rotate(q, lp_, wp_);                                                              \
        quat_rotate(q, ln_, wn_);                                                              \
        for (int k_ = 0; k_ < 3; ++k_) wp_[k_] += pose[k_];                                    \
        to_view(cam, wp_, tri[slot].p);                                                        \
        dir_to_view(cam, wn_, tri[slot].n);                                                    \
        tri[slot].c[0] = tri[slot].c[1] = tri[slot].c[2] = grey;                               \
    } while (0)
    if (c->shape == RBC_SHAPE_SPHERE || c->shape == RBC_SHAPE_CAPSULE) {
        const double pi = 3.14159265358979323846;
        float h = c->shape == RBC_SHAPE_CAPSULE ? c->half[1] : 0.0f, rad = c->radius;
        /* rows 0..RINGS+1: rows up to RINGS/2 on the upper half (shifted by +h), the
         * rest on the lower (-h); band RINGS/2 joins the two equators. */
        for (int i = 0; i <= RINGS; ++i)
            for (int j = 0; j < SEG; ++j) {
                float corner[4][6];
                for (int k = 0; k < 4; ++k) {
                    int ri = i + (k >> 1), sj = j + ((k ^ (k >> 1)) & 1);
                    int upper = ri <= RINGS / 2;
                    double th = pi * (upper ? ri : ri - 1) / RINGS, ph = 2 * pi * sj / SEG;
                    float nx = (float)(sin(th) * cos(ph)), ny = (float)cos(th), nz = (float)(sin(th) * sin(ph));
                    float off = upper ? h : -h;
                    float cc[6] = {rad * nx, rad * ny + off, rad * nz, nx, ny, nz};
                    memcpy(corner[k], cc, sizeof cc);
                }
                if (i == RINGS / 2 && h == 0.0f) continue; /* a sphere has no band */
                for (int t = 0; t < 2; ++t) {
                    int idx[3] = {0, 1 + t, 2 + t};
                    for (int k = 0; k < 3; ++k) {
                        const float *cc = corner[idx[k]];
                        EMIT_LOCAL(k, cc[0], cc[1], cc[2], cc[3], cc[4], cc[5]);
                    }
                    raster_tri(r, &tri[0], &tri[1], &tri[2]);
                }
            }
    } else if (c->shape == RBC_SHAPE_BOX) {
        for (int axis = 0; axis < 3; ++axis)
            for (int sign = -1; sign <= 1; sign += 2) {
                int u = (axis + 1) % 3, w = (axis + 2) % 3;
                float corner[4][3];
                for (int k = 0; k < 4; ++k) {
                    corner[k][axis] = sign * c->half[axis];
                    corner[k][u] = ((k == 1 || k == 2) ? 1 : -1) * c->half[u];
                    corner[k][w] = (k >= 2 ? 1 : -1) * c->half[w];
                }
                float nrm[3] = {0, 0, 0};
                nrm[axis] = (float)sign;
                for (int t = 0; t < 2; ++t) {
                    int idx[3] = {0, 1 + t, 2 + t};
                    for (int k = 0; k < 3; ++k)
                        EMIT_LOCAL(k, corner[idx[k]][0], corner[idx[k]][1], corner[idx[k]][2],
                                   nrm[0], nrm[1], nrm[2]);
                    raster_tri(r, &tri[0], &tri[1], &tri[2]);
                }
            }
    } else if (c->shape == RBC_SHAPE_TRIANGLE_MESH) {
        for (uint32_t t = 0; t < c->mt; ++t) {
            const float *p[3];
            for (int k = 0; k < 3; ++k) p[k] = c->mesh_pos + 3 * (size_t)c->mesh_tris[3 * t + k];
            float e1[3], e2[3];
            for (int k = 0; k < 3; ++k) e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k];
            float nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0]};
            for (int k = 0; k < 3; ++k) EMIT_LOCAL(k, p[k][0], p[k][1], p[k][2], nrm[0], nrm[1], nrm[2]);
            raster_tri(r, &tri[0], &tri[1], &tri[2]);
        }
    } else { /* plane: a square of 3 r around the target's foot on the plane */
        float n[3], up[3] = {0, 1, 0};
        quat_rotate(q, up, n);
        double dist = 0;
        for (int k = 0; k < 3; ++k) dist += (cam->target[k] - pose[k]) * n[k];
        float foot_w[3], foot_l[3], qc[4] = {-q[0], -q[1], -q[2], q[3]};
        for (int k = 0; k < 3; ++k) foot_w[k] = (float)(cam->target[k] - dist * n[k] - pose[k]);
        quat_rotate(qc, foot_w, foot_l); /* into the collider's frame */
        float s = (float)(3.0 * cam->radius);
        float cx[4] = {-s, s, s, -s}, cz[4] = {-s, -s, s, s};
        for (int t = 0; t < 2; ++t) {
            int idx[3] = {0, 1 + t, 2 + t};
            for (int k = 0; k < 3; ++k)
                EMIT_LOCAL(k, foot_l[0] + cx[idx[k]], 0.0f, foot_l[2] + cz[idx[k]], 0, 1, 0);
            raster_tri(r, &tri[0], &tri[1], &tri[2]);
        }
    }
#undef EMIT_LOCAL
}

/* Triangle t of a cloth (quads split along their 0-2 diagonal first, then the
 * triangles); 0 if it belongs to a quad removed by frame f. */
static int cloth_triangle(const vcloth *c, uint64_t t, uint32_t f, uint32_t ix[3]) {
    if (t < 2ull * c->nq) {
        uint32_t qd = (uint32_t)(t / 2);
        if (c->quad_removed[qd] <= f) return 0;
        const uint32_t *qq = c->quads + 4 * (size_t)qd;
        ix[0] = qq[0], ix[1] = qq[1 + (t & 1)], ix[2] = qq[2 + (t & 1)];
    } else {
        memcpy(ix, c->tris + 3 * (t - 2ull * c->nq), 3 * sizeof *ix);
    }
    return 1;
}

/* A cloth's visible triangles with smooth (area-weighted) vertex normals; nr: 3n
 * zeroed floats of scratch. */
static void raster_cloth(raster *r, const camera *cam, const vcloth *c, uint32_t f,
                         const float *x, const float *strain, float *nr) {
    uint64_t tri_total = 2ull * c->nq + c->nt;
    uint32_t ix[3];
    for (uint64_t t = 0; t < tri_total; ++t) {
        if (!cloth_triangle(c, t, f, ix)) continue;
        const float *a = x + 3 * (size_t)ix[0], *b = x + 3 * (size_t)ix[1], *d = x + 3 * (size_t)ix[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        float e2[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        float nn[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                       e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; ++k)
            for (int m = 0; m < 3; ++m) nr[3 * (size_t)ix[k] + m] += nn[m];
    }
    for (uint64_t t = 0; t < tri_total; ++t) {
        if (!cloth_triangle(c, t, f, ix)) continue;
        rvert rv[3];
        for (int k = 0; k < 3; ++k) {
            to_view(cam, x + 3 * (size_t)ix[k], rv[k].p);
            dir_to_view(cam, nr + 3 * (size_t)ix[k], rv[k].n);
            cli_view_strain_colour(strain[ix[k]], rv[k].c);
        }
        raster_tri(r, &rv[0], &rv[1], &rv[2]);
    }
}

/* Bounding box of the vertices some visible face uses, over all cloths, of stored
 * frame s; strain of each cloth into strain[i] (cloth i's n floats). Returns 0 if
 * no vertex is visible. */
static int frame_box(const cli_view *v, uint32_t s, uint32_t *const *edge_dead, float **strain,
                     double lo[3], double hi[3]) {
    int any = 0;
    for (int k = 0; k < 3; ++k) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (uint32_t i = 0; i < v->cloth_count; ++i) {
        const vcloth *c = &v->cloths[i];
        const float *x = c->frames + (size_t)s * c->n * 3;
        vertex_strain(c, edge_dead[i], s * v->stride, x, strain[i]);
        for (uint32_t j = 0; j < c->n; ++j) {
            if (strain[i][j] < 0) continue;
            any = 1;
            for (int k = 0; k < 3; ++k) {
                if (x[3 * j + k] < lo[k]) lo[k] = x[3 * j + k];
                if (x[3 * j + k] > hi[k]) hi[k] = x[3 * j + k];
            }
        }
    }
    return any;
}

/* Per-view buffers of one frame: edge visibility and strain, per cloth. */
typedef struct frame_scratch {
    uint32_t **edge_dead;
    float **strain;
    uint32_t count;
} frame_scratch;

static void scratch_free(frame_scratch *fs) {
    for (uint32_t i = 0; i < fs->count; ++i) free(fs->edge_dead[i]), free(fs->strain[i]);
    free(fs->edge_dead), free(fs->strain);
}

static int scratch_init(frame_scratch *fs, const cli_view *v) {
    fs->count = v->cloth_count;
    fs->edge_dead = calloc(fs->count + 1, sizeof *fs->edge_dead);
    fs->strain = calloc(fs->count + 1, sizeof *fs->strain);
    if (!fs->edge_dead || !fs->strain) return scratch_free(fs), 1;
    for (uint32_t i = 0; i < fs->count; ++i) {
        fs->edge_dead[i] = edge_dead_frames(&v->cloths[i]);
        fs->strain[i] = malloc(v->cloths[i].n * sizeof(float));
        if (!fs->edge_dead[i] || !fs->strain[i]) return scratch_free(fs), 1;
    }
    return 0;
}

static int write_png_rgb(const char *path, const unsigned char *rgb, uint32_t w, uint32_t h,
                         char *err, size_t errlen) {
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 5);
    png_bytep *rows = malloc(h * sizeof *rows);
    if (!tmp || !rows)
        return free(tmp), free(rows), set_err(err, errlen, "cli_view_write_png: %s: out of memory", path), 1;
    memcpy(tmp, path, plen), memcpy(tmp + plen, ".tmp", 5);
    for (uint32_t y = 0; y < h; ++y) rows[y] = (png_bytep)(rgb + (size_t)y * w * 3);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        set_err(err, errlen, "cli_view_write_png: cannot write %s: %s", tmp, strerror(errno));
        return free(tmp), free(rows), 1;
    }
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    int ok = 0;
    if (png && info && !setjmp(png_jmpbuf(png))) {
        png_init_io(png, f);
        png_set_IHDR(png, info, w, h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        png_write_image(png, rows);
        png_write_end(png, NULL);
        ok = 1;
    }
    png_destroy_write_struct(&png, &info);
    int closed = fclose(f) == 0;
    if (!ok || !closed || rename(tmp, path) != 0) {
        set_err(err, errlen, "cli_view_write_png: cannot write %s: %s", ok && closed ? path : tmp,
                ok && closed ? strerror(errno) : "libpng or I/O error");
        remove(tmp);
        return free(tmp), free(rows), 1;
    }
    free(tmp), free(rows);
    return 0;
}

int cli_view_write_png(const cli_view *v, const char *path, uint32_t frame, uint32_t width,
                       uint32_t height, char *err, size_t errlen) {
    if (!v || !path) return set_err(err, errlen, "cli_view_write_png: %s is NULL", v ? "path" : "view"), 1;
    if (!width || !height) width = 960, height = 720;
    if (width > 16384 || height > 16384)
        return set_err(err, errlen, "cli_view_write_png: %s: %u x %u is over 16384", path, width, height), 1;
    uint32_t total = cli_view_frame_total(v);
    if (frame >= total || v->cloth_count == 0)
        return set_err(err, errlen, "cli_view_write_png: %s: frame %u of %u complete frames (%u "
                       "cloths)", path, frame, total, v->cloth_count), 1;
    uint32_t s = frame / v->stride;
    frame_scratch fs = {0};
    raster r = {0};
    r.w = (int)width * 2, r.h = (int)height * 2;
    size_t samples = (size_t)r.w * r.h;
    r.inv_z = calloc(samples, sizeof(float));
    r.rgb = malloc(samples * 3 * sizeof(float));
    unsigned char *out = malloc((size_t)width * height * 3);
    float **vnorm = calloc(v->cloth_count, sizeof *vnorm);
    int have_fs = 0, failed = !r.inv_z || !r.rgb || !out || !vnorm;
    if (!failed) failed = scratch_init(&fs, v), have_fs = !failed;
    for (uint32_t i = 0; !failed && i < v->cloth_count; ++i)
        failed = !(vnorm[i] = calloc((size_t)v->cloths[i].n * 3, sizeof(float)));
    if (failed) {
        set_err(err, errlen, "cli_view_write_png: %s: out of memory for %u x %u", path, width, height);
    } else {
        double lo[3], hi[3];
        if (!frame_box(v, s, fs.edge_dead, fs.strain, lo, hi))
            for (int k = 0; k < 3; ++k) lo[k] = hi[k] = 0; /* everything torn: colliders only */
        camera cam;
        camera_fit(&cam, lo, hi, width, height);
        /* view space here has z forward; the shared light has z towards the viewer */
        float ll = sqrtf(LIGHT[0] * LIGHT[0] + LIGHT[1] * LIGHT[1] + LIGHT[2] * LIGHT[2]);
        r.light[0] = LIGHT[0] / ll, r.light[1] = LIGHT[1] / ll, r.light[2] = -LIGHT[2] / ll;
        r.near_z = (float)(0.01 * cam.radius);
        r.focal = (float)cam.focal;
        for (int y = 0; y < r.h; ++y) {
            float t = (y + 0.5f) / r.h, bg[3];
            for (int k = 0; k < 3; ++k) bg[k] = BG_TOP[k] + t * (BG_BOTTOM[k] - BG_TOP[k]);
            for (int x = 0; x < r.w; ++x) memcpy(r.rgb + 3 * ((size_t)y * r.w + x), bg, sizeof bg);
        }
        for (uint32_t i = 0; i < v->cloth_count; ++i)
            raster_cloth(&r, &cam, &v->cloths[i], s * v->stride,
                         v->cloths[i].frames + (size_t)s * v->cloths[i].n * 3, fs.strain[i], vnorm[i]);
        for (uint32_t i = 0; i < v->collider_count; ++i)
            raster_collider(&r, &cam, &v->colliders[i], v->colliders[i].poses + (size_t)s * 7);
        /* 2 x 2 box filter down to the image */
        for (uint32_t y = 0; y < height; ++y)
            for (uint32_t x = 0; x < width; ++x)
                for (int k = 0; k < 3; ++k) {
                    size_t s0 = (size_t)(2 * y) * r.w + 2 * x, s1 = s0 + r.w;
                    float sum = r.rgb[3 * s0 + k] + r.rgb[3 * (s0 + 1) + k] + r.rgb[3 * s1 + k] +
                                r.rgb[3 * (s1 + 1) + k];
                    float c8 = sum * 0.25f * 255.0f + 0.5f;
                    out[3 * ((size_t)y * width + x) + k] = (unsigned char)(c8 > 255 ? 255 : c8 < 0 ? 0 : c8);
                }
        failed = write_png_rgb(path, out, width, height, err, errlen);
    }
    if (vnorm)
        for (uint32_t i = 0; i < v->cloth_count; ++i) free(vnorm[i]);
    if (have_fs) scratch_free(&fs);
    free(vnorm), free(r.inv_z), free(r.rgb), free(out);
    return failed ? 1 : 0;
}

/* ------------------------------------------------------------------------- */
/* The player page                                                           */
/* ------------------------------------------------------------------------- */

typedef struct sbuf {
    unsigned char *p;
    size_t len, cap;
    int oom;
} sbuf;

static void sb_reserve(sbuf *b, size_t more) {
    if (b->oom || b->len + more <= b->cap) return;
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->len + more) cap *= 2;
    unsigned char *p = realloc(b->p, cap);
    if (!p) b->oom = 1;
    else b->p = p, b->cap = cap;
}

static void sb_add(sbuf *b, const void *data, size_t len) {
    /* Nothing to add: an empty buffer has no storage yet, and memcpy to NULL is
     * undefined even for 0 bytes (UBSan). */
    if (len == 0) return;
    sb_reserve(b, len);
    if (b->oom) return;
    memcpy(b->p + b->len, data, len);
    b->len += len;
}

/* Formatted text of any length: measured first, then written in place. */
static void sb_printf(sbuf *b, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n <= 0) return;
    sb_reserve(b, (size_t)n + 1);
    if (b->oom) return;
    va_start(ap, fmt);
    vsnprintf((char *)b->p + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
}

/* A JSON string that is also safe inside <script>: <, >, & as \u escapes. */
static void sb_json_str(sbuf *b, const char *s) {
    sb_add(b, "\"", 1);
    for (; *s; ++s) {
        unsigned char ch = (unsigned char)*s;
        if (ch < 0x20 || ch == '"' || ch == '\\' || ch == '<' || ch == '>' || ch == '&')
            sb_printf(b, "\\u%04x", ch);
        else
            sb_add(b, s, 1);
    }
    sb_add(b, "\"", 1);
}

static void sb_html(sbuf *b, const char *s) {
    for (; *s; ++s) {
        switch (*s) {
        case '<': sb_add(b, "&lt;", 4); break;
        case '>': sb_add(b, "&gt;", 4); break;
        case '&': sb_add(b, "&amp;", 5); break;
        case '"': sb_add(b, "&quot;", 6); break;
        case '\'': sb_add(b, "&#39;", 5); break;
        default: sb_add(b, s, 1);
        }
    }
}

static void sb_floats(sbuf *b, const float *x, int n) {
    sb_add(b, "[", 1);
    for (int i = 0; i < n; ++i) sb_printf(b, "%s%.9g", i ? "," : "", (double)x[i]);
    sb_add(b, "]", 1);
}

/* Sections of the binary blob start 4-aligned so the page can view them as typed
 * arrays in place; the JSON gets [byte offset, element count]. */
static size_t blob_begin(sbuf *blob) {
    static const unsigned char zero[4] = {0};
    sb_add(blob, zero, (4 - blob->len % 4) % 4);
    return blob->len;
}

static void sb_section(sbuf *meta, const char *key, size_t offset, size_t count) {
    sb_printf(meta, ",\"%s\":[%zu,%zu]", key, offset, count);
}

/* One page frame's quantized positions: each axis of every vertex as 16 bits over
 * the clip's box, predicted per axis by whichever of three predictors leaves the
 * smallest residuals (0: the previous vertex; 1: the previous frame; 2: linear
 * extrapolation of the two frames before -- smooth motion favours 2, noise that
 * 2 amplifies favours 1), the residual zigzagged and written as a plane of low
 * bytes and a plane of high bytes: nearly constant high bytes, and deflate does
 * the rest. modes[a] receives axis a's predictor. */
static uint32_t predict(int mode, const uint16_t *q, const uint16_t *q1, const uint16_t *q2,
                        size_t k, uint32_t n) {
    return mode == 0 ? (k % n ? q[k - 1] : 0) : mode == 1 ? q1[k] : 2u * q1[k] - q2[k];
}

static void encode_positions(sbuf *blob, const float *x, uint32_t n, uint32_t j, const double box[6],
                             uint16_t *q, uint16_t *q1, uint16_t *q2, unsigned char *planes,
                             unsigned char modes[3]) {
    size_t m = (size_t)n * 3;
    for (int a = 0; a < 3; ++a)
        for (uint32_t i = 0; i < n; ++i) {
            double t = (x[3 * (size_t)i + a] - box[a]) / box[3 + a] * 65535.0 + 0.5;
            q[(size_t)a * n + i] = (uint16_t)(t < 0 ? 0 : t > 65535 ? 65535 : t);
        }
    for (int a = 0; a < 3; ++a) {
        uint64_t best = UINT64_MAX;
        for (int mode = 0; mode <= (j < 2 ? (int)j : 2); ++mode) {
            uint64_t cost = 0;
            for (size_t k = (size_t)a * n; k < (size_t)(a + 1) * n; ++k) {
                int16_t r = (int16_t)(uint16_t)(q[k] - predict(mode, q, q1, q2, k, n));
                cost += (uint64_t)(r < 0 ? -(int32_t)r : r);
            }
            if (cost < best) best = cost, modes[a] = (unsigned char)mode;
        }
        for (size_t k = (size_t)a * n; k < (size_t)(a + 1) * n; ++k) {
            uint16_t r = (uint16_t)(q[k] - predict(modes[a], q, q1, q2, k, n));
            uint16_t zz = (uint16_t)((uint16_t)(r << 1) ^ (r & 0x8000 ? 0xFFFF : 0));
            planes[k] = (unsigned char)(zz & 0xFF);
            planes[m + k] = (unsigned char)(zz >> 8);
        }
    }
    sb_add(blob, planes, 2 * m);
    memcpy(q2, q1, m * sizeof *q);
    memcpy(q1, q, m * sizeof *q);
}

/* The blob for page stride m (every m-th stored frame) and the meta JSON. */
static int build_page_data(const cli_view *v, uint32_t m, const double box[6], sbuf *blob,
                           sbuf *meta, uint32_t *page_frames) {
    uint32_t stored = (cli_view_frame_total(v) + v->stride - 1) / v->stride;
    uint32_t pf = (stored + m - 1) / m;
    *page_frames = pf;
    blob->len = 0, meta->len = 0;
    sb_printf(meta, "\"cloths\":[");
    frame_scratch fs;
    if (scratch_init(&fs, v)) return 1;
    int failed = 0;
    for (uint32_t ci = 0; ci < v->cloth_count && !failed; ++ci) {
        const vcloth *c = &v->cloths[ci];
        size_t mm = (size_t)c->n * 3;
        uint16_t *q = malloc(mm * 3 * sizeof *q);
        unsigned char *planes = malloc(mm * 2), *modes = malloc((size_t)pf * 3);
        if (!q || !planes || !modes) {
            free(q), free(planes), free(modes);
            failed = 1;
            break;
        }
        uint32_t removed = 0;
        for (uint32_t k = 0; k < c->nq; ++k) removed += c->quad_removed[k] != NEVER;
        sb_printf(meta, "%s{\"name\":", ci ? "," : "");
        sb_json_str(meta, c->name);
        sb_printf(meta, ",\"vertices\":%u,\"quads\":%u,\"triangles\":%u,\"removed\":%u", c->n, c->nq,
                  c->nt, removed);
        size_t off = blob_begin(blob);
        for (uint64_t t = 0; t < 2ull * c->nq + c->nt; ++t) {
            uint32_t ix[3];
            if (t < 2ull * c->nq) {
                const uint32_t *qq = c->quads + 4 * (size_t)(t / 2);
                ix[0] = qq[0], ix[1] = qq[1 + (t & 1)], ix[2] = qq[2 + (t & 1)];
            } else {
                memcpy(ix, c->tris + 3 * (t - 2ull * c->nq), sizeof ix);
            }
            sb_add(blob, ix, sizeof ix);
        }
        sb_section(meta, "tris", off, (2ull * c->nq + c->nt) * 3);
        off = blob_begin(blob);
        sb_add(blob, c->quad_removed, (size_t)c->nq * sizeof(uint32_t));
        sb_section(meta, "quad_removed", off, c->nq);
        off = blob_begin(blob);
        for (uint32_t j = 0; j < pf; ++j)
            encode_positions(blob, c->frames + (size_t)j * m * mm, c->n, j, box, q, q + mm,
                             q + 2 * mm, planes, modes + 3 * (size_t)j);
        sb_section(meta, "pos", off, (size_t)pf * mm * 2);
        off = blob_begin(blob);
        sb_add(blob, modes, (size_t)pf * 3);
        sb_section(meta, "pos_modes", off, (size_t)pf * 3);
        off = blob_begin(blob);
        /* Strain as a byte per vertex: b = 255 sqrt(min(s, 1)), finer where the map
         * changes fastest (0..10 %); 0 also for vertices no face shows. Written as
         * the change from the page frame before (mod 256): strain moves slowly. */
        unsigned char *prev = planes + c->n;
        memset(prev, 0, c->n);
        for (uint32_t j = 0; j < pf; ++j) {
            uint32_t s = j * m;
            vertex_strain(c, fs.edge_dead[ci], s * v->stride, c->frames + (size_t)s * mm, fs.strain[ci]);
            for (uint32_t i = 0; i < c->n; ++i) {
                float st = fs.strain[ci][i];
                unsigned char b = (unsigned char)(st <= 0 ? 0 : st >= 1 ? 255 : sqrtf(st) * 255.0f + 0.5f);
                planes[i] = (unsigned char)(b - prev[i]);
                prev[i] = b;
            }
            sb_add(blob, planes, c->n);
        }
        sb_section(meta, "strain", off, (size_t)pf * c->n);
        sb_add(meta, "}", 1);
        free(q), free(planes), free(modes);
    }
    scratch_free(&fs);
    sb_printf(meta, "],\"colliders\":[");
    for (uint32_t ci = 0; ci < v->collider_count && !failed; ++ci) {
        const vcollider *c = &v->colliders[ci];
        sb_printf(meta, "%s{\"shape\":%d,\"radius\":%.9g,\"half\":", ci ? "," : "", c->shape,
                  (double)c->radius);
        sb_floats(meta, c->half, 3);
        size_t off = blob_begin(blob);
        for (uint32_t j = 0; j < pf; ++j) sb_add(blob, c->poses + (size_t)j * m * 7, 7 * sizeof(float));
        sb_section(meta, "poses", off, (size_t)pf * 7);
        if (c->shape == RBC_SHAPE_TRIANGLE_MESH) {
            off = blob_begin(blob);
            sb_add(blob, c->mesh_pos, (size_t)c->mv * 3 * sizeof(float));
            sb_section(meta, "mesh_pos", off, (size_t)c->mv * 3);
            off = blob_begin(blob);
            sb_add(blob, c->mesh_tris, (size_t)c->mt * 3 * sizeof(uint32_t));
            sb_section(meta, "mesh_tris", off, (size_t)c->mt * 3);
        }
        sb_add(meta, "}", 1);
    }
    sb_add(meta, "]", 1);
    blob_begin(blob);
    return failed || blob->oom || meta->oom;
}

static void write_base64(FILE *f, const unsigned char *p, size_t len) {
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char line[4 * 1024 + 2];
    size_t n = 0;
    for (size_t i = 0; i < len; i += 3) {
        uint32_t a = p[i], b = i + 1 < len ? p[i + 1] : 0, c = i + 2 < len ? p[i + 2] : 0;
        uint32_t w = a << 16 | b << 8 | c;
        line[n++] = tab[w >> 18];
        line[n++] = tab[(w >> 12) & 63];
        line[n++] = i + 1 < len ? tab[(w >> 6) & 63] : '=';
        line[n++] = i + 2 < len ? tab[w & 63] : '=';
        if (n >= 4 * 1024) fwrite(line, 1, n, f), n = 0;
    }
    fwrite(line, 1, n, f);
}

/* The template with {{TITLE}}, {{META}} and {{DATA}} filled in. */
static void write_template(FILE *f, const char *title_html, const sbuf *meta,
                           const unsigned char *data, size_t data_len) {
    const char *t = rbc_player_html;
    for (;;) {
        const char *mark = strstr(t, "{{");
        if (!mark) break;
        fwrite(t, 1, (size_t)(mark - t), f);
        if (!strncmp(mark, "{{TITLE}}", 9)) fputs(title_html, f), t = mark + 9;
        else if (!strncmp(mark, "{{META}}", 8)) fwrite(meta->p, 1, meta->len, f), t = mark + 8;
        else if (!strncmp(mark, "{{DATA}}", 8)) write_base64(f, data, data_len), t = mark + 8;
        else fwrite(mark, 1, 2, f), t = mark + 2;
    }
    fputs(t, f);
}

static int write_file_atomic(const char *path, const char *who, char *err, size_t errlen,
                             void (*body)(FILE *, void *), void *ctx) {
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 5);
    if (!tmp) return set_err(err, errlen, "%s: %s: out of memory", who, path), 1;
    memcpy(tmp, path, plen), memcpy(tmp + plen, ".tmp", 5);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        set_err(err, errlen, "%s: cannot write %s: %s", who, tmp, strerror(errno));
        return free(tmp), 1;
    }
    body(f, ctx);
    int bad = ferror(f);
    if (fclose(f) != 0) bad = 1;
    if (bad || rename(tmp, path) != 0) {
        set_err(err, errlen, "%s: cannot write %s: %s", who, bad ? tmp : path, strerror(errno));
        remove(tmp);
        return free(tmp), 1;
    }
    free(tmp);
    return 0;
}

typedef struct page_ctx {
    const char *title_html;
    const sbuf *meta;
    const unsigned char *data;
    size_t data_len;
} page_ctx;

static void page_body(FILE *f, void *ctx) {
    const page_ctx *p = ctx;
    write_template(f, p->title_html, p->meta, p->data, p->data_len);
}

int cli_view_write_html(const cli_view *v, const char *path, char *err, size_t errlen) {
    if (!v || !path) return set_err(err, errlen, "cli_view_write_html: %s is NULL", v ? "path" : "view"), 1;
    uint32_t total = cli_view_frame_total(v);
    if (!total || !v->cloth_count)
        return set_err(err, errlen, "cli_view_write_html: %s: no complete frame (%u cloths)", path,
                       v->cloth_count), 1;
    uint32_t stored = (total + v->stride - 1) / v->stride;
    /* The quantization box: every stored position of every cloth. */
    double box[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    size_t per_frame_raw = 0, fixed_raw = 0;
    for (uint32_t i = 0; i < v->cloth_count; ++i) {
        const vcloth *c = &v->cloths[i];
        for (size_t k = 0; k < (size_t)stored * c->n * 3; ++k) {
            double x = c->frames[k];
            if (x < box[k % 3]) box[k % 3] = x;
            if (x > box[3 + k % 3]) box[3 + k % 3] = x;
        }
        per_frame_raw += (size_t)c->n * 7;
        fixed_raw += (2 * (size_t)c->nq + c->nt) * 12 + (size_t)c->nq * 4;
    }
    for (int k = 0; k < 3; ++k) box[3 + k] = box[3 + k] - box[k] > 0 ? box[3 + k] - box[k] : 1.0;
    per_frame_raw += (size_t)v->collider_count * 28;
    for (uint32_t i = 0; i < v->collider_count; ++i)
        fixed_raw += (size_t)v->colliders[i].mv * 12 + (size_t)v->colliders[i].mt * 12;
    /* Thin first for the inflated size, then for the deflated budget. Deflated size
     * is about a + b * page_frames (faces once, then frames; b grows as frames get
     * further apart and predict each other worse), so after two tries the line
     * through them picks the next stride; the first retry scales by how far over. */
    uint32_t m = 1;
    if (fixed_raw + per_frame_raw * stored > PAGE_RAW_CAP && PAGE_RAW_CAP > fixed_raw)
        m = (uint32_t)((per_frame_raw * stored + (PAGE_RAW_CAP - fixed_raw) - 1) / (PAGE_RAW_CAP - fixed_raw));
    sbuf blob = {0}, meta = {0}, head = {0}, title = {0};
    unsigned char *z = NULL;
    uLongf zlen = 0;
    uint32_t pf = 0, prev_pf = 0;
    double prev_z = 0;
    int rc = 1;
    for (int attempt = 0; attempt < 12; ++attempt) {
        if (m > stored) m = stored;
        if (build_page_data(v, m, box, &blob, &meta, &pf)) {
            set_err(err, errlen, "cli_view_write_html: %s: out of memory building the page data", path);
            goto done;
        }
        uLong bound = compressBound((uLong)blob.len);
        free(z);
        z = malloc(bound);
        zlen = bound;
        if (!z || compress2(z, &zlen, blob.p, (uLong)blob.len, 6) != Z_OK) {
            set_err(err, errlen, "cli_view_write_html: %s: deflate of %zu bytes failed", path, blob.len);
            goto done;
        }
        if (zlen <= v->page_budget) break;
        if (pf == 1) {
            set_err(err, errlen, "cli_view_write_html: %s: one frame deflates to %lu bytes, over "
                    "the page budget of %zu", path, (unsigned long)zlen, v->page_budget);
            goto done;
        }
        double want_pf = (double)pf * v->page_budget / (double)zlen / 1.1;
        if (prev_pf > pf && prev_z > (double)zlen) {
            double b = (prev_z - (double)zlen) / (double)(prev_pf - pf), a = (double)zlen - b * pf;
            want_pf = (0.95 * (double)v->page_budget - a) / b;
        }
        prev_pf = pf, prev_z = (double)zlen;
        uint64_t next = want_pf >= 1.0 ? (uint64_t)ceil((double)stored / want_pf) : stored;
        m = next > m ? (next > stored ? stored : (uint32_t)next) : m + 1;
    }
    if (zlen > v->page_budget) {
        set_err(err, errlen, "cli_view_write_html: %s: the page data stays over its budget", path);
        goto done;
    }
    /* Everything the page needs besides the blob, constants of the look included. */
    uint32_t stride = v->stride * m;
    sb_printf(&head, "{\"format\":1,\"title\":");
    sb_json_str(&head, v->title);
    sb_printf(&head, ",\"frame_dt\":%.17g,\"frames\":%u,\"frame_count\":%u,\"stride\":%u,"
              "\"memory_stride\":%u,\"page_stride\":%u,\"page_frames\":%u,\"raw_bytes\":%zu,"
              "\"deflated_bytes\":%lu,\"box\":[%.17g,%.17g,%.17g,%.17g,%.17g,%.17g],",
              v->dt, total, v->frame_count, stride, v->stride, m, pf, blob.len,
              (unsigned long)zlen, box[0], box[1], box[2], box[3], box[4], box[5]);
    sb_printf(&head, "\"look\":{\"az\":%g,\"el\":%g,\"fov\":%g,\"margin\":%g,\"ambient\":%g,"
              "\"collider_grey\":%g,\"plane_grey\":%g,\"light\":", CAM_AZ_DEG, CAM_EL_DEG,
              CAM_FOV_DEG, CAM_MARGIN, (double)AMBIENT, (double)COLLIDER_GREY, (double)PLANE_GREY);
    sb_floats(&head, LIGHT, 3);
    sb_printf(&head, ",\"bg_top\":");
    sb_floats(&head, BG_TOP, 3);
    sb_printf(&head, ",\"bg_bottom\":");
    sb_floats(&head, BG_BOTTOM, 3);
    sb_printf(&head, ",\"stops\":[");
    for (int i = 0; i < STOP_COUNT; ++i) {
        sb_printf(&head, "%s", i ? "," : "");
        sb_floats(&head, STOPS[i], 4);
    }
    sb_printf(&head, "]},");
    sb_add(&head, meta.p, meta.len);
    sb_add(&head, "}", 1);
    sb_html(&title, v->title);
    sb_add(&title, "", 1);
    if (head.oom || title.oom) {
        set_err(err, errlen, "cli_view_write_html: %s: out of memory", path);
        goto done;
    }
    page_ctx ctx = {(const char *)title.p, &head, z, zlen};
    rc = write_file_atomic(path, "cli_view_write_html", err, errlen, page_body, &ctx);
done:
    free(blob.p), free(meta.p), free(head.p), free(title.p), free(z);
    return rc;
}

/* ------------------------------------------------------------------------- */
/* Batch index                                                               */
/* ------------------------------------------------------------------------- */

static void buffer_body(FILE *f, void *ctx) {
    const sbuf *b = ctx;
    fwrite(b->p, 1, b->len, f);
}

static void index_html(sbuf *b, const char *title, const cli_view_index_entry *entries,
                       uint32_t count) {
    sb_printf(b, "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>");
    sb_html(b, title);
    sb_printf(b, "</title>\n<style>body{margin:0;padding:16px 24px;font:14px/1.4 system-ui,sans-serif;"
              "background:#eef1f5;color:#222}h1{font-size:20px;font-weight:600}"
              ".grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(260px,1fr));gap:16px}"
              ".job{background:#fff;border-radius:6px;box-shadow:0 1px 3px rgba(0,0,0,.15);overflow:hidden}"
              ".job img{display:block;width:100%%;aspect-ratio:4/3;object-fit:cover;background:#9aa6b8}"
              ".job .noimg{aspect-ratio:4/3;background:#9aa6b8}"
              ".job p{margin:6px 10px}.name{font-weight:600;word-break:break-all}.status{color:#555}"
              ".status.ok{color:#1a7f37}.status.bad{color:#b42318}a{color:inherit;text-decoration:none}"
              "</style></head><body>\n<h1>");
    sb_html(b, title);
    sb_printf(b, "</h1>\n<div class=\"grid\">\n");
    for (uint32_t i = 0; i < count; ++i) {
        const cli_view_index_entry *e = &entries[i];
        const char *st = e->status ? e->status : "";
        int ok = !strncmp(st, "ok", 2) || !strncmp(st, "done", 4) || !strncmp(st, "success", 7);
        sb_printf(b, "<div class=\"job\">");
        if (e->page_href) sb_printf(b, "<a href=\""), sb_html(b, e->page_href), sb_printf(b, "\">");
        if (e->png_href) {
            sb_printf(b, "<img loading=\"lazy\" alt=\"");
            sb_html(b, e->name);
            sb_printf(b, "\" src=\"");
            sb_html(b, e->png_href);
            sb_printf(b, "\">");
        } else {
            sb_printf(b, "<div class=\"noimg\"></div>");
        }
        sb_printf(b, "<p class=\"name\">");
        sb_html(b, e->name);
        sb_printf(b, "</p>");
        if (e->page_href) sb_printf(b, "</a>");
        sb_printf(b, "<p class=\"status %s\">", st[0] ? (ok ? "ok" : "bad") : "");
        sb_html(b, st);
        sb_printf(b, "</p></div>\n");
    }
    sb_printf(b, "</div>\n</body></html>\n");
}

int cli_view_write_index(const char *path, const char *title, const cli_view_index_entry *entries,
                         uint32_t count, char *err, size_t errlen) {
    if (!path || (count && !entries))
        return set_err(err, errlen, "cli_view_write_index: %s is NULL", path ? "entries" : "path"), 1;
    for (uint32_t i = 0; i < count; ++i)
        if (!entries[i].name)
            return set_err(err, errlen, "cli_view_write_index: %s: entry %u has no name", path, i), 1;
    sbuf b = {0};
    index_html(&b, title ? title : "rbcloth batch", entries, count);
    int rc = b.oom ? (set_err(err, errlen, "cli_view_write_index: %s: out of memory", path), 1)
                   : write_file_atomic(path, "cli_view_write_index", err, errlen, buffer_body, &b);
    free(b.p);
    return rc;
}
