/* convert.c -- the import pipeline of rbc_mesh_import, run by the import helper
 * (rbcloth-import, main.c) in its own process: a file read with assimp into a cloth
 * mesh (positions, quads, springs, pins and a report).
 *
 * The pipeline, in the order rbc_import_convert runs it:
 *   0. Guards against inputs known to send assimp 5.2.5 into an endless loop or an
 *      unbounded allocation (a PLY header without end_header, an OFF header that
 *      declares more elements than the file holds). The helper process is the real
 *      protection (a crash, hang or exhausted memory ends the helper, not the
 *      host); these give a precise message instead of a time-out.
 *   1. assimp reads the file with JoinIdenticalVertices | ValidateDataStructure and
 *      nothing else: no triangulation, so quads and n-gons reach us as the file
 *      has them (docs/facts.md: quads survive in OBJ, PLY, Collada).
 *   2. The node hierarchy is walked here (not aiProcess_PreTransformVertices, which
 *      would also merge and reorder meshes): every placement of a selected mesh
 *      contributes its vertices transformed by the product of its nodes' matrices,
 *      then scaled.
 *   3. Welding by position (hash of the bit pattern, or a grid of cells of the weld
 *      distance), since assimp keeps copies that differ in normal or UV.
 *   4. Faces: points and lines skipped, corners repeated after welding removed,
 *      degenerate faces dropped (the core's quad test), n-gons split into a quad fan
 *      or refused.
 *   5. Triangle pairing: every pair of triangles that are the only two on an edge is
 *      a candidate if its quad is convex and within the angle and fold bounds; best
 *      score first, greedy (a maximal matching, not a maximum one).
 *   6. Leftover triangles: their edges that no quad has become explicit springs.
 *   7. Unused vertices dropped; pins from vertex colors and from the def's rules;
 *      bipartiteness by BFS and the color count from the core's own coloring (which
 *      also checks that rbc_cloth_create will accept the mesh).
 * A failing step frees what it allocated and leaves its message in the error buffer. */
#define _GNU_SOURCE /* memmem */
#include <assimp/cimport.h>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "convert.h"
#include "errors.h"
#include "file_vertices.h"
#include "obj_vertices.h"
#include "topology.h"

#define RBC_PI 3.14159265358979323846

/* ------------------------------------------------------------------------- */
/* Build state                                                               */
/* ------------------------------------------------------------------------- */

typedef struct u32vec {
    uint32_t *v;
    size_t n, cap;
} u32vec;

static int vec_reserve(u32vec *a, size_t more) {
    if (a->n + more <= a->cap) return 1;
    size_t cap = a->cap ? a->cap : 64;
    while (cap < a->n + more) {
        if (cap > SIZE_MAX / 8) return 0;
        cap *= 2;
    }
    uint32_t *p = realloc(a->v, cap * sizeof *p);
    if (!p) return 0;
    a->v = p;
    a->cap = cap;
    return 1;
}

typedef struct instance {
    uint32_t mesh;     /* index into aiScene::mMeshes */
    int pin_all;       /* the placement is the pin group's: pin all its vertices */
    double m[12];      /* rows 1..3 of the 4x4 affine transform */
    uint32_t base;     /* first source vertex */
    char name[64];     /* the placing node's name ("" for a mesh no node places) */
} instance;

typedef struct build {
    const char *path;
    rbc_mesh_import_def def;
    rbc_mesh_info info;
    /* source vertices (all placements), then welded vertices */
    size_t nsrc;
    float *src_pos;       /* [3 nsrc] transformed and scaled */
    float *src_raw;       /* [3 nsrc] as assimp read them (the file's coordinates) */
    uint32_t *src_inst;   /* [nsrc] the placement (instance) of each */
    uint8_t *src_red;     /* [nsrc] pinned by color */
    uint8_t *src_bad;     /* [nsrc] non-finite position */
    uint32_t *weld_map;   /* [nsrc] -> welded index */
    uint32_t nw;
    float *w_pos;         /* [3 nw] */
    uint8_t *w_red;       /* [nw] */
    u32vec quads, tris, corners;
    uint32_t tris_from_ngon_pending;
    instance *inst;
    size_t ninst, cap_inst;
    double scale;         /* applied after the node transforms: units times def.scale */
    uint32_t *remap;      /* [nw] welded vertex -> mesh vertex, UINT32_MAX = dropped */
    rbc_file_vertices file; /* the file's own vertex lists (or assimp's arrays) */
} build;

static void build_free(build *b) {
    free(b->src_pos);
    free(b->src_raw);
    free(b->src_inst);
    free(b->remap);
    rbc_file_vertices_free(&b->file);
    free(b->src_red);
    free(b->src_bad);
    free(b->weld_map);
    free(b->w_pos);
    free(b->w_red);
    free(b->quads.v);
    free(b->tris.v);
    free(b->corners.v);
    free(b->inst);
}

static rbc_result oom(const build *b) {
    return rbc_import_error(b->path, RBC_ERR_OUT_OF_MEMORY, "out of memory");
}

/* ------------------------------------------------------------------------- */
/* Geometry tests                                                            */
/* ------------------------------------------------------------------------- */

static void sub3(const float *p, uint32_t a, uint32_t b, double out[3]) {
    for (int c = 0; c < 3; ++c) out[c] = (double)p[3 * a + c] - p[3 * b + c];
}
static void cross3(const double u[3], const double v[3], double out[3]) {
    out[0] = u[1] * v[2] - u[2] * v[1];
    out[1] = u[2] * v[0] - u[0] * v[2];
    out[2] = u[0] * v[1] - u[1] * v[0];
}
static double dot3(const double u[3], const double v[3]) {
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
}

/* The core's quad test (topology.c): no coincident consecutive corners, and area^2
 * above 1e-12 of the longest edge^4 (zero area up to float rounding). */
static int quad_ok(const float *p, const uint32_t q[4]) {
    double longest2 = 0.0, e[3];
    for (int k = 0; k < 4; ++k) {
        sub3(p, q[k], q[(k + 1) & 3], e);
        double len2 = dot3(e, e);
        if (len2 == 0.0) return 0;
        if (len2 > longest2) longest2 = len2;
    }
    double d1[3], d2[3], c[3];
    sub3(p, q[2], q[0], d1);
    sub3(p, q[3], q[1], d2);
    cross3(d1, d2, c);
    double area2 = 0.25 * dot3(c, c);
    return area2 > 1e-12 * longest2 * longest2;
}

/* The same criterion for a triangle. */
static int tri_ok(const float *p, uint32_t a, uint32_t b, uint32_t c) {
    double ab[3], ac[3], bc[3], n[3];
    sub3(p, b, a, ab);
    sub3(p, c, a, ac);
    sub3(p, c, b, bc);
    double l1 = dot3(ab, ab), l2 = dot3(ac, ac), l3 = dot3(bc, bc);
    if (l1 == 0.0 || l2 == 0.0 || l3 == 0.0) return 0;
    double longest2 = fmax(l1, fmax(l2, l3));
    cross3(ab, ac, n);
    double area2 = 0.25 * dot3(n, n);
    return area2 > 1e-12 * longest2 * longest2;
}

/* Quality of the quad q: convex (every corner turns the same way about the normal of
 * the diagonals), largest |corner angle - 90| and fold between the triangles
 * (q0 q1 q2) and (q2 q3 q0), degrees. Returns 0 if not convex. */
static int quad_quality(const float *p, const uint32_t q[4], double *dev, double *fold) {
    double d1[3], d2[3], nq[3];
    sub3(p, q[2], q[0], d1);
    sub3(p, q[3], q[1], d2);
    cross3(d1, d2, nq);
    double worst = 0.0;
    for (int k = 0; k < 4; ++k) {
        double ein[3], eout[3], t[3];
        sub3(p, q[k], q[(k + 3) & 3], ein);
        sub3(p, q[(k + 1) & 3], q[k], eout);
        cross3(ein, eout, t);
        if (!(dot3(t, nq) > 0.0)) return 0;
        /* interior angle between (prev - cur) and (next - cur) */
        double a[3] = {-ein[0], -ein[1], -ein[2]};
        double la = sqrt(dot3(a, a)), lb = sqrt(dot3(eout, eout));
        double cosang = dot3(a, eout) / (la * lb);
        if (cosang > 1.0) cosang = 1.0;
        if (cosang < -1.0) cosang = -1.0;
        double ang = acos(cosang) * (180.0 / RBC_PI);
        if (fabs(ang - 90.0) > worst) worst = fabs(ang - 90.0);
    }
    double u[3], v[3], n1[3], n2[3];
    sub3(p, q[1], q[0], u);
    sub3(p, q[2], q[0], v);
    cross3(u, v, n1);
    sub3(p, q[3], q[2], u);
    sub3(p, q[0], q[2], v);
    cross3(u, v, n2);
    double c = dot3(n1, n2) / (sqrt(dot3(n1, n1)) * sqrt(dot3(n2, n2)));
    if (!(c == c)) return 0;
    if (c > 1.0) c = 1.0;
    if (c < -1.0) c = -1.0;
    *dev = worst;
    *fold = acos(c) * (180.0 / RBC_PI);
    return 1;
}

/* ------------------------------------------------------------------------- */
/* 2. Placements and vertices                                                */
/* ------------------------------------------------------------------------- */

static int name_is(const struct aiString *s, const char *name) {
    size_t len = strlen(name);
    return s->length == len && memcmp(s->data, name, len) == 0;
}

static rbc_result add_instance(build *b, uint32_t mesh, const double m[12], int pin_all,
                               const char *name) {
    if (b->ninst == b->cap_inst) {
        size_t cap = b->cap_inst ? 2 * b->cap_inst : 16;
        instance *p = realloc(b->inst, cap * sizeof *p);
        if (!p) return oom(b);
        b->inst = p;
        b->cap_inst = cap;
    }
    instance *in = &b->inst[b->ninst++];
    in->mesh = mesh;
    in->pin_all = pin_all;
    memcpy(in->m, m, sizeof in->m);
    in->base = 0;
    snprintf(in->name, sizeof in->name, "%.63s", name);
    return RBC_OK;
}

/* Names of meshes and nodes, for the message of a name that matches nothing. */
static void list_names(const struct aiScene *s, char *out, size_t cap) {
    size_t k = 0;
    out[0] = '\0';
    for (unsigned m = 0; m < s->mNumMeshes; ++m) {
        if (k + 48 >= cap) {
            snprintf(out + k, cap - k, ", ...");
            return;
        }
        int w = snprintf(out + k, cap - k, "%s\"%.32s\"", k ? ", " : "",
                         s->mMeshes[m]->mName.data);
        if (w < 0) return;
        k += (size_t)w;
    }
}

static rbc_result collect_instances(build *b, const struct aiScene *s) {
    const rbc_mesh_import_def *d = &b->def;
    if (s->mNumMeshes == 0 || !s->mMeshes)
        return rbc_import_error(b->path, RBC_ERR_BAD_MESH, "no mesh in the file");
    if (d->mesh_index >= 0 && (uint32_t)d->mesh_index >= s->mNumMeshes)
        return rbc_import_error(b->path, RBC_ERR_INVALID_ARGUMENT,
                                "mesh_index out of range: mesh_index is %d and the file has %u "
                                "meshes",
                                (int)d->mesh_index, s->mNumMeshes);
    uint8_t *placed = calloc(s->mNumMeshes, 1);
    if (!placed) return oom(b);
    /* Depth-first over the node tree with the accumulated transform. */
    typedef struct frame {
        const struct aiNode *node;
        double m[12];
    } frame;
    size_t cap = 64, top = 0, visited = 0;
    frame *stack = malloc(cap * sizeof *stack);
    rbc_result rc = RBC_OK;
    if (!stack) {
        free(placed);
        return oom(b);
    }
    if (s->mRootNode) {
        static const double id[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        stack[top].node = s->mRootNode;
        memcpy(stack[top].m, id, sizeof id);
        top++;
    }
    while (top > 0 && rc == RBC_OK) {
        frame f = stack[--top];
        const struct aiNode *nd = f.node;
        if (++visited > RBC_IMPORT_MAX_ELEMENTS) {
            rc = rbc_import_error(b->path, RBC_ERR_BAD_MESH, "too many nodes: more than %u",
                                  RBC_IMPORT_MAX_ELEMENTS);
            break;
        }
        const struct aiMatrix4x4 *t = &nd->mTransformation;
        const double l[12] = {t->a1, t->a2, t->a3, t->a4, t->b1, t->b2,
                              t->b3, t->b4, t->c1, t->c2, t->c3, t->c4};
        double m[12]; /* parent * local, affine (the last row of assimp's is 0 0 0 1) */
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) {
                double v = 0.0;
                for (int k = 0; k < 3; ++k) v += f.m[4 * r + k] * l[4 * k + c];
                if (c == 3) v += f.m[4 * r + 3];
                m[4 * r + c] = v;
            }
        }
        for (unsigned k = 0; k < nd->mNumMeshes && rc == RBC_OK; ++k) {
            unsigned mi = nd->mMeshes[k];
            if (mi >= s->mNumMeshes) {
                rc = rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                      "node refers to a missing mesh: node \"%.64s\" names mesh "
                                      "%u of %u",
                                      nd->mName.data, mi, s->mNumMeshes);
                break;
            }
            placed[mi] = 1;
            int take = d->mesh_index >= 0 ? mi == (unsigned)d->mesh_index
                       : d->mesh_name     ? name_is(&s->mMeshes[mi]->mName, d->mesh_name) ||
                                            name_is(&nd->mName, d->mesh_name)
                                          : 1;
            int group = d->pin_group && (name_is(&s->mMeshes[mi]->mName, d->pin_group) ||
                                         name_is(&nd->mName, d->pin_group));
            if (take) rc = add_instance(b, mi, m, group, nd->mName.data);
        }
        for (unsigned k = 0; k < nd->mNumChildren && rc == RBC_OK; ++k) {
            if (!nd->mChildren || !nd->mChildren[k]) continue;
            if (top == cap) {
                frame *p = realloc(stack, 2 * cap * sizeof *p);
                if (!p) {
                    rc = oom(b);
                    break;
                }
                stack = p;
                cap *= 2;
            }
            stack[top].node = nd->mChildren[k];
            memcpy(stack[top].m, m, sizeof m);
            top++;
        }
    }
    /* Meshes no node places are taken once, untransformed. */
    for (unsigned mi = 0; mi < s->mNumMeshes && rc == RBC_OK; ++mi) {
        if (placed[mi]) continue;
        int take = d->mesh_index >= 0 ? mi == (unsigned)d->mesh_index
                   : d->mesh_name     ? name_is(&s->mMeshes[mi]->mName, d->mesh_name)
                                      : 1;
        static const double id[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
        int group = d->pin_group && name_is(&s->mMeshes[mi]->mName, d->pin_group);
        if (take) rc = add_instance(b, mi, id, group, "");
    }
    free(stack);
    free(placed);
    if (rc) return rc;
    if (b->ninst && d->pin_group) {
        int any = 0;
        for (size_t k = 0; k < b->ninst; ++k) any |= b->inst[k].pin_all;
        if (!any) {
            char names[400];
            list_names(s, names, sizeof names);
            return rbc_import_error(b->path, RBC_ERR_INVALID_ARGUMENT,
                                    "pin_group \"%.128s\" names no mesh or node taken: the file's "
                                    "meshes are %s (node names match too)",
                                    d->pin_group, names);
        }
    }
    if (b->ninst == 0) {
        char names[400];
        list_names(s, names, sizeof names);
        return rbc_import_error(b->path, RBC_ERR_INVALID_ARGUMENT,
                                "no mesh named \"%.128s\": the file's meshes are %s (node names "
                                "match too)",
                                d->mesh_name ? d->mesh_name : "", names);
    }
    return RBC_OK;
}

static rbc_result collect_vertices(build *b, const struct aiScene *s) {
    size_t total = 0;
    for (size_t k = 0; k < b->ninst; ++k) {
        const struct aiMesh *me = s->mMeshes[b->inst[k].mesh];
        b->inst[k].base = (uint32_t)total;
        total += me->mVertices ? me->mNumVertices : 0;
        if (total > RBC_IMPORT_MAX_ELEMENTS)
            return rbc_import_error(b->path, RBC_ERR_BAD_MESH, "too many vertices: more than %u",
                                    RBC_IMPORT_MAX_ELEMENTS);
        b->info.source_face_count += me->mNumFaces;
    }
    b->info.source_mesh_count = (uint32_t)b->ninst;
    b->info.source_vertex_count = (uint32_t)total;
    b->nsrc = total;
    b->src_pos = malloc((3 * total + 1) * sizeof(float));
    b->src_raw = malloc((3 * total + 1) * sizeof(float));
    b->src_inst = malloc((total + 1) * sizeof(uint32_t));
    b->src_red = calloc(total + 1, 1);
    b->src_bad = calloc(total + 1, 1);
    if (!b->src_pos || !b->src_raw || !b->src_inst || !b->src_red || !b->src_bad) return oom(b);
    const double scale = b->scale;
    const float thr = b->def.pin_color_threshold;
    for (size_t k = 0; k < b->ninst; ++k) {
        const instance *in = &b->inst[k];
        const struct aiMesh *me = s->mMeshes[in->mesh];
        if (!me->mVertices) continue;
        const struct aiColor4D *col = me->mColors[0];
        for (unsigned v = 0; v < me->mNumVertices; ++v) {
            size_t i = in->base + (size_t)v;
            const struct aiVector3D *p = &me->mVertices[v];
            double x = p->x, y = p->y, z = p->z;
            b->src_raw[3 * i] = p->x, b->src_raw[3 * i + 1] = p->y, b->src_raw[3 * i + 2] = p->z;
            b->src_inst[i] = (uint32_t)k;
            for (int r = 0; r < 3; ++r) {
                double val = in->m[4 * r] * x + in->m[4 * r + 1] * y + in->m[4 * r + 2] * z +
                             in->m[4 * r + 3];
                float fv = (float)(val * scale);
                if (!isfinite(fv)) b->src_bad[i] = 1;
                if (fv == 0.0f) fv = 0.0f; /* -0 welds with +0 */
                b->src_pos[3 * i + r] = fv;
            }
            /* Bit 0: pinned by color; bit 1: by the pin group. */
            if (col && thr > 0.0f && col[v].r >= thr && col[v].g < thr && col[v].b < thr)
                b->src_red[i] |= 1;
            if (in->pin_all) b->src_red[i] |= 2;
        }
    }
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* 3. Welding                                                                */
/* ------------------------------------------------------------------------- */

static uint64_t mix64(uint64_t h) {
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    h *= 0xc4ceb9fe1a85ec53ull;
    h ^= h >> 33;
    return h;
}

typedef struct cell_table {
    int64_t *keys;  /* [3 cap] */
    uint32_t *head; /* [cap] first welded vertex of the cell, UINT32_MAX = empty slot */
    size_t mask;
} cell_table;

/* Slot of the cell `key` (its head may be UINT32_MAX: not there yet). */
static size_t cell_slot(const cell_table *t, const int64_t key[3]) {
    uint64_t h = mix64((uint64_t)key[0] * 0x9E3779B97F4A7C15ull ^ mix64((uint64_t)key[1]) ^
                       mix64((uint64_t)key[2] + 0x632BE59BD9B4E019ull));
    size_t s = (size_t)h & t->mask;
    while (t->head[s] != UINT32_MAX &&
           (t->keys[3 * s] != key[0] || t->keys[3 * s + 1] != key[1] || t->keys[3 * s + 2] != key[2]))
        s = (s + 1) & t->mask;
    return s;
}

static void cell_key(const float *p, double inv, int64_t key[3]) {
    for (int c = 0; c < 3; ++c) {
        if (inv == 0.0) {
            uint32_t bits;
            memcpy(&bits, &p[c], 4);
            key[c] = bits;
        } else {
            double q = floor((double)p[c] * inv);
            if (q > 4e18) q = 4e18;
            if (q < -4e18) q = -4e18;
            key[c] = (int64_t)q;
        }
    }
}

static rbc_result weld(build *b) {
    size_t n = b->nsrc;
    b->weld_map = malloc((n + 1) * sizeof(uint32_t));
    b->w_pos = malloc((3 * n + 1) * sizeof(float));
    b->w_red = calloc(n + 1, 1);
    if (!b->weld_map || !b->w_pos || !b->w_red) return oom(b);
    if (!b->def.weld) {
        for (size_t i = 0; i < n; ++i) {
            b->weld_map[i] = (uint32_t)i;
            b->w_red[i] = b->src_red[i];
        }
        if (n) memcpy(b->w_pos, b->src_pos, 3 * n * sizeof(float));
        b->nw = (uint32_t)n;
        return RBC_OK;
    }
    const double dist = b->def.weld_distance;
    const double inv = dist > 0.0 ? 1.0 / dist : 0.0;
    size_t cap = 16;
    while (cap < 2 * n) cap *= 2;
    cell_table t;
    t.mask = cap - 1;
    t.keys = malloc(3 * cap * sizeof(int64_t));
    t.head = malloc(cap * sizeof(uint32_t));
    uint32_t *next = malloc((n + 1) * sizeof(uint32_t)); /* chain of welded vertices per cell */
    if (!t.keys || !t.head || !next) {
        free(t.keys);
        free(t.head);
        free(next);
        return oom(b);
    }
    memset(t.head, 0xFF, cap * sizeof(uint32_t));
    uint32_t nw = 0;
    for (size_t i = 0; i < n; ++i) {
        const float *p = b->src_pos + 3 * i;
        int64_t key[3] = {0, 0, 0};
        uint32_t found = UINT32_MAX;
        if (b->src_bad[i]) {
            found = UINT32_MAX; /* never weld a non-finite vertex; it is refused if used */
        } else if (inv == 0.0) {
            cell_key(p, 0.0, key);
            size_t s = cell_slot(&t, key);
            if (t.head[s] != UINT32_MAX) found = t.head[s];
        } else {
            cell_key(p, inv, key);
            for (int dx = -1; dx <= 1 && found == UINT32_MAX; ++dx)
                for (int dy = -1; dy <= 1 && found == UINT32_MAX; ++dy)
                    for (int dz = -1; dz <= 1 && found == UINT32_MAX; ++dz) {
                        int64_t k2[3] = {key[0] + dx, key[1] + dy, key[2] + dz};
                        size_t s = cell_slot(&t, k2);
                        for (uint32_t w = t.head[s]; w != UINT32_MAX; w = next[w]) {
                            const float *q = b->w_pos + 3 * (size_t)w;
                            double ex = (double)p[0] - q[0], ey = (double)p[1] - q[1],
                                   ez = (double)p[2] - q[2];
                            if (ex * ex + ey * ey + ez * ez <= dist * dist) {
                                found = w;
                                break;
                            }
                        }
                    }
        }
        if (found == UINT32_MAX) {
            found = nw++;
            memcpy(b->w_pos + 3 * (size_t)found, p, 3 * sizeof(float));
            if (!b->src_bad[i]) {
                if (inv != 0.0) cell_key(p, inv, key);
                size_t s = cell_slot(&t, key);
                if (t.head[s] == UINT32_MAX) memcpy(&t.keys[3 * s], key, sizeof key);
                next[found] = t.head[s];
                t.head[s] = found;
            }
        }
        b->weld_map[i] = found;
        b->w_red[found] |= b->src_red[i];
    }
    free(t.keys);
    free(t.head);
    free(next);
    b->nw = nw;
    b->info.welded_vertices = (uint32_t)(n - nw);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* 4. Faces                                                                  */
/* ------------------------------------------------------------------------- */

/* A triangle or quad (k corners) kept in v, counted by origin (a face of the file, or
 * a piece of an n-gon); a degenerate one (ok 0) is dropped and counted. */
static rbc_result push_face(build *b, u32vec *v, const uint32_t *c, size_t k, int ok,
                            int from_ngon, uint32_t *ngon_pieces, uint32_t *file_faces) {
    if (!ok) {
        b->info.degenerate_faces++;
        return RBC_OK;
    }
    if (!vec_reserve(v, k)) return oom(b);
    memcpy(v->v + v->n, c, k * sizeof *c);
    v->n += k;
    ++*(from_ngon ? ngon_pieces : file_faces);
    return RBC_OK;
}

static rbc_result push_tri(build *b, uint32_t a, uint32_t c1, uint32_t c2, int from_ngon) {
    const uint32_t t[3] = {a, c1, c2};
    return push_face(b, &b->tris, t, 3, tri_ok(b->w_pos, a, c1, c2), from_ngon,
                     &b->info.triangles_from_ngons, &b->info.file_triangles);
}

static rbc_result push_quad(build *b, const uint32_t q[4], int from_ngon) {
    return push_face(b, &b->quads, q, 4, quad_ok(b->w_pos, q), from_ngon,
                     &b->info.quads_from_ngons, &b->info.file_quads);
}

static rbc_result add_faces(build *b, const struct aiScene *s) {
    for (size_t k = 0; k < b->ninst; ++k) {
        const instance *in = &b->inst[k];
        const struct aiMesh *me = s->mMeshes[in->mesh];
        if (!me->mFaces) continue;
        for (unsigned f = 0; f < me->mNumFaces; ++f) {
            const struct aiFace *fa = &me->mFaces[f];
            unsigned ni = fa->mNumIndices;
            if (ni < 3) {
                b->info.points_lines_skipped++;
                continue;
            }
            if (!fa->mIndices)
                return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                        "face without indices: mesh %u (\"%.64s\") face %u",
                                        in->mesh, me->mName.data, f);
            b->corners.n = 0;
            if (!vec_reserve(&b->corners, ni)) return oom(b);
            uint32_t *c = b->corners.v;
            size_t nc = 0;
            for (unsigned j = 0; j < ni; ++j) {
                unsigned idx = fa->mIndices[j];
                if (idx >= me->mNumVertices || !me->mVertices)
                    return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                            "face index out of range: mesh %u (\"%.64s\") face %u "
                                            "corner %u is vertex %u of %u",
                                            in->mesh, me->mName.data, f, j, idx, me->mNumVertices);
                size_t src = in->base + (size_t)idx;
                if (b->src_bad[src]) {
                    const float *p = b->src_pos + 3 * src;
                    return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                            "non-finite position: mesh %u (\"%.64s\") vertex %u is "
                                            "(%g, %g, %g) after transform and scale (face %u uses "
                                            "it)",
                                            in->mesh, me->mName.data, idx, (double)p[0],
                                            (double)p[1], (double)p[2], f);
                }
                uint32_t w = b->weld_map[src];
                if (nc == 0 || c[nc - 1] != w) c[nc++] = w;
            }
            while (nc > 1 && c[nc - 1] == c[0]) nc--;
            int repeated = 0; /* a corner repeated apart from its neighbour: a pinched face */
            if (nc <= 8) {
                for (size_t x = 0; x < nc && !repeated; ++x)
                    for (size_t y = x + 1; y < nc; ++y)
                        if (c[x] == c[y]) {
                            repeated = 1;
                            break;
                        }
            }
            if (nc < 3 || repeated) {
                b->info.degenerate_faces++;
                continue;
            }
            rbc_result rc = RBC_OK;
            if (nc == 3) {
                rc = push_tri(b, c[0], c[1], c[2], 0);
            } else if (nc == 4) {
                rc = push_quad(b, c, 0);
            } else {
                if (b->def.ngons == RBC_NGON_REFUSE)
                    return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                            "n-gon refused: mesh %u (\"%.64s\") face %u has %zu "
                                            "corners (ngons = RBC_NGON_REFUSE)",
                                            in->mesh, me->mName.data, f, nc);
                b->info.ngons_split++;
                size_t i = 1;
                for (; i + 2 < nc && !rc; i += 2) {
                    uint32_t q[4] = {c[0], c[i], c[i + 1], c[i + 2]};
                    rc = push_quad(b, q, 1);
                }
                if (!rc && i + 1 < nc) rc = push_tri(b, c[0], c[i], c[i + 1], 1);
            }
            if (rc) return rc;
        }
    }
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* 5. Triangle pairing                                                       */
/* ------------------------------------------------------------------------- */

typedef struct edge_ref {
    uint64_t key; /* (min << 32) | max */
    uint32_t tri;
} edge_ref;

static int cmp_edge_ref(const void *x, const void *y) {
    const edge_ref *a = x, *b = y;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->tri < b->tri ? -1 : a->tri > b->tri;
}

typedef struct pair_cand {
    double dev, fold;
    uint64_t key;
    uint32_t t1, t2;
    uint32_t q[4];
} pair_cand;

static int cmp_cand(const void *x, const void *y) {
    const pair_cand *a = x, *b = y;
    if (a->dev != b->dev) return a->dev < b->dev ? -1 : 1;
    if (a->fold != b->fold) return a->fold < b->fold ? -1 : 1;
    return a->key < b->key ? -1 : a->key > b->key;
}

static uint64_t edge_key(uint32_t a, uint32_t b) {
    return a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
}

/* Pair triangles into quads; paired[t] = 1 for those merged. */
static rbc_result pair_triangles(build *b, uint8_t *paired) {
    size_t nt = b->tris.n / 3;
    if (!b->def.pair_triangles || nt < 2) return RBC_OK;
    const uint32_t *T = b->tris.v;
    edge_ref *e = malloc(3 * nt * sizeof *e);
    pair_cand *cand = malloc(nt * sizeof *cand); /* at most 3nt/2 shared edges... */
    size_t ncap = nt, nc = 0;
    if (!e || !cand) {
        free(e);
        free(cand);
        return oom(b);
    }
    for (size_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) {
            e[3 * t + k].key = edge_key(T[3 * t + k], T[3 * t + (k + 1) % 3]);
            e[3 * t + k].tri = (uint32_t)t;
        }
    qsort(e, 3 * nt, sizeof *e, cmp_edge_ref);
    const double max_dev = b->def.pair_max_angle_deviation_deg;
    const double max_fold = b->def.pair_max_fold_deg;
    for (size_t i = 0; i < 3 * nt;) {
        size_t j = i;
        while (j < 3 * nt && e[j].key == e[i].key) j++;
        if (j - i == 2 && e[i].tri != e[i + 1].tri) {
            uint32_t t1 = e[i].tri, t2 = e[i + 1].tri;
            uint32_t u = (uint32_t)(e[i].key >> 32), v = (uint32_t)e[i].key;
            /* Rotate t1 to (c1, x, y): x -> y is its directed shared edge. */
            const uint32_t *a = T + 3 * (size_t)t1, *bb = T + 3 * (size_t)t2;
            int r = 0;
            while (r < 3 && (a[r] == u || a[r] == v)) r++;
            uint32_t c1 = a[r], x = a[(r + 1) % 3], y = a[(r + 2) % 3];
            uint32_t c2 = bb[0] != u && bb[0] != v ? bb[0] : bb[1] != u && bb[1] != v ? bb[1] : bb[2];
            if (c1 != c2) {
                pair_cand pc;
                pc.q[0] = x;
                pc.q[1] = c2;
                pc.q[2] = y;
                pc.q[3] = c1;
                pc.key = e[i].key;
                pc.t1 = t1;
                pc.t2 = t2;
                if (quad_ok(b->w_pos, pc.q) && quad_quality(b->w_pos, pc.q, &pc.dev, &pc.fold) &&
                    pc.dev <= max_dev && pc.fold <= max_fold) {
                    if (nc == ncap) {
                        pair_cand *p = realloc(cand, 2 * ncap * sizeof *p);
                        if (!p) {
                            free(e);
                            free(cand);
                            return oom(b);
                        }
                        cand = p;
                        ncap *= 2;
                    }
                    cand[nc++] = pc;
                }
            }
        }
        i = j;
    }
    free(e);
    qsort(cand, nc, sizeof *cand, cmp_cand);
    for (size_t k = 0; k < nc; ++k) {
        if (paired[cand[k].t1] || paired[cand[k].t2]) continue;
        if (!vec_reserve(&b->quads, 4)) {
            free(cand);
            return oom(b);
        }
        memcpy(b->quads.v + b->quads.n, cand[k].q, 4 * sizeof(uint32_t));
        b->quads.n += 4;
        paired[cand[k].t1] = paired[cand[k].t2] = 1;
        b->info.paired_triangles += 2;
    }
    free(cand);
    return RBC_OK;
}

static int cmp_u64(const void *x, const void *y) {
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

/* ------------------------------------------------------------------------- */
/* 6-7. Springs, compaction, pins, report                                    */
/* ------------------------------------------------------------------------- */

/* Two-coloring by BFS over the springs graph; 1 if bipartite. */
static int is_bipartite(uint32_t n, const uint32_t *quads, uint32_t nq, const uint32_t *springs,
                        uint32_t ns, int *ok) {
    size_t ne = 4 * (size_t)nq + ns;
    uint32_t *start = calloc((size_t)n + 1, sizeof *start);
    uint32_t *adj = malloc((2 * ne + 1) * sizeof *adj);
    uint32_t *fill = malloc(((size_t)n + 1) * sizeof *fill);
    int8_t *side = malloc((size_t)n + 1);
    uint32_t *queue = malloc(((size_t)n + 1) * sizeof *queue);
    int result = 1;
    *ok = start && adj && fill && side && queue;
    if (*ok) {
#define EDGE_AT(k, a_, b_)                                                        \
    do {                                                                          \
        if ((k) < 4 * (size_t)nq) {                                               \
            size_t q_ = (k) / 4, c_ = (k) % 4;                                    \
            a_ = quads[4 * q_ + c_];                                              \
            b_ = quads[4 * q_ + (c_ + 1) % 4];                                    \
        } else {                                                                  \
            size_t s_ = (k) - 4 * (size_t)nq;                                     \
            a_ = springs[2 * s_];                                                 \
            b_ = springs[2 * s_ + 1];                                             \
        }                                                                         \
    } while (0)
        for (size_t k = 0; k < ne; ++k) {
            uint32_t a, c;
            EDGE_AT(k, a, c);
            start[a + 1]++;
            start[c + 1]++;
        }
        for (uint32_t v = 0; v < n; ++v) start[v + 1] += start[v];
        memcpy(fill, start, (size_t)n * sizeof *fill);
        for (size_t k = 0; k < ne; ++k) {
            uint32_t a, c;
            EDGE_AT(k, a, c);
            adj[fill[a]++] = c;
            adj[fill[c]++] = a;
        }
#undef EDGE_AT
        memset(side, -1, n);
        for (uint32_t s0 = 0; s0 < n && result; ++s0) {
            if (side[s0] >= 0) continue;
            side[s0] = 0;
            size_t head = 0, tail = 0;
            queue[tail++] = s0;
            while (head < tail && result) {
                uint32_t v = queue[head++];
                for (uint32_t k = start[v]; k < start[v + 1]; ++k) {
                    uint32_t w = adj[k];
                    if (side[w] < 0) {
                        side[w] = (int8_t)(1 - side[v]);
                        queue[tail++] = w;
                    } else if (side[w] == side[v]) {
                        result = 0;
                        break;
                    }
                }
            }
        }
    }
    free(start);
    free(adj);
    free(fill);
    free(side);
    free(queue);
    return result;
}

static rbc_result finish(build *b, rbc_mesh *out) {
    size_t nt = b->tris.n / 3;
    uint8_t *paired = calloc(nt + 1, 1);
    if (!paired) return oom(b);
    rbc_result rc = pair_triangles(b, paired);
    if (rc) {
        free(paired);
        return rc;
    }
    size_t nq = b->quads.n / 4;
    /* Springs: leftover triangles' edges that are no quad's edge, once each. */
    uint64_t *qe = malloc((4 * nq + 1) * sizeof *qe);
    uint64_t *se = malloc((3 * nt + 1) * sizeof *se);
    uint32_t *lt = malloc((3 * nt + 1) * sizeof *lt); /* leftover triangles */
    if (!qe || !se || !lt) {
        free(paired);
        free(qe);
        free(se);
        free(lt);
        return oom(b);
    }
    size_t nlt = 0;
    for (size_t q = 0; q < nq; ++q)
        for (int k = 0; k < 4; ++k)
            qe[4 * q + k] = edge_key(b->quads.v[4 * q + k], b->quads.v[4 * q + (k + 1) % 4]);
    qsort(qe, 4 * nq, sizeof *qe, cmp_u64);
    size_t nse = 0;
    for (size_t t = 0; t < nt; ++t) {
        if (paired[t]) continue;
        b->info.leftover_triangles++;
        memcpy(&lt[3 * nlt++], &b->tris.v[3 * t], 3 * sizeof(uint32_t));
        for (int k = 0; k < 3; ++k) {
            uint64_t key = edge_key(b->tris.v[3 * t + k], b->tris.v[3 * t + (k + 1) % 3]);
            if (!bsearch(&key, qe, 4 * nq, sizeof *qe, cmp_u64)) se[nse++] = key;
        }
    }
    free(paired);
    free(qe);
    qsort(se, nse, sizeof *se, cmp_u64);
    size_t ns = 0;
    for (size_t k = 0; k < nse; ++k)
        if (ns == 0 || se[ns - 1] != se[k]) se[ns++] = se[k];
    if (nq == 0 && ns == 0) {
        free(se);
        free(lt);
        return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                "no face to simulate: %u faces in %u meshes, %u points or lines, "
                                "%u degenerate",
                                b->info.source_face_count, b->info.source_mesh_count,
                                b->info.points_lines_skipped, b->info.degenerate_faces);
    }
    /* Drop unused vertices, keeping the order of the rest. */
    uint32_t *remap = malloc(((size_t)b->nw + 1) * sizeof *remap);
    if (!remap) {
        free(se);
        free(lt);
        return oom(b);
    }
    memset(remap, 0xFF, (size_t)b->nw * sizeof *remap);
    for (size_t k = 0; k < 4 * nq; ++k) remap[b->quads.v[k]] = 0;
    for (size_t k = 0; k < ns; ++k) {
        remap[se[k] >> 32] = 0;
        remap[(uint32_t)se[k]] = 0;
    }
    uint32_t n = 0;
    for (uint32_t v = 0; v < b->nw; ++v)
        if (remap[v] == 0) remap[v] = n++;
    b->info.unused_vertices = b->nw - n;
    out->n = n;
    out->nq = (uint32_t)nq;
    out->ns = (uint32_t)ns;
    out->pos = malloc((3 * (size_t)n + 1) * sizeof(float));
    out->quads = malloc((4 * nq + 1) * sizeof(uint32_t));
    out->springs = malloc((2 * ns + 1) * sizeof(uint32_t));
    out->pins = malloc(((size_t)n + 1) * sizeof(uint32_t));
    out->ltris = lt;
    out->nlt = (uint32_t)nlt;
    uint8_t *red = malloc((size_t)n + 1);
    if (!out->pos || !out->quads || !out->springs || !out->pins || !red) {
        free(se);
        free(remap);
        free(red);
        return oom(b);
    }
    for (size_t k = 0; k < 3 * nlt; ++k) lt[k] = remap[lt[k]];
    for (uint32_t v = 0; v < b->nw; ++v) {
        if (remap[v] == UINT32_MAX) continue;
        memcpy(out->pos + 3 * (size_t)remap[v], b->w_pos + 3 * (size_t)v, 3 * sizeof(float));
        red[remap[v]] = b->w_red[v];
    }
    for (size_t k = 0; k < 4 * nq; ++k) out->quads[k] = remap[b->quads.v[k]];
    for (size_t k = 0; k < ns; ++k) {
        out->springs[2 * k] = remap[se[k] >> 32];
        out->springs[2 * k + 1] = remap[(uint32_t)se[k]];
    }
    free(se);
    b->remap = remap;

    /* Bounds and pins. */
    const rbc_mesh_import_def *d = &b->def;
    rbc_mesh_info *info = &b->info;
    for (int c = 0; c < 3; ++c) {
        info->bounds_min[c] = INFINITY;
        info->bounds_max[c] = -INFINITY;
    }
    for (uint32_t v = 0; v < n; ++v)
        for (int c = 0; c < 3; ++c) {
            float x = out->pos[3 * (size_t)v + c];
            if (x < info->bounds_min[c]) info->bounds_min[c] = x;
            if (x > info->bounds_max[c]) info->bounds_max[c] = x;
        }
    double plane_norm = sqrt((double)d->pin_plane[0] * d->pin_plane[0] +
                             (double)d->pin_plane[1] * d->pin_plane[1] +
                             (double)d->pin_plane[2] * d->pin_plane[2]);
    uint32_t np = 0;
    for (uint32_t v = 0; v < n; ++v) {
        const float *p = out->pos + 3 * (size_t)v;
        int rule = 0;
        if (d->pin_plane_distance >= 0.0f) {
            double s = ((double)d->pin_plane[0] * p[0] + (double)d->pin_plane[1] * p[1] +
                        (double)d->pin_plane[2] * p[2] - d->pin_plane[3]) /
                       plane_norm;
            if (fabs(s) <= d->pin_plane_distance) rule = 1;
        }
        if (d->pin_point_distance >= 0.0f) {
            double ex = (double)p[0] - d->pin_point[0], ey = (double)p[1] - d->pin_point[1],
                   ez = (double)p[2] - d->pin_point[2];
            if (sqrt(ex * ex + ey * ey + ez * ez) <= d->pin_point_distance) rule = 1;
        }
        if (d->pin_top_axis >= 0 &&
            (double)p[d->pin_top_axis] >=
                (double)info->bounds_max[d->pin_top_axis] - d->pin_top_tolerance)
            rule = 1;
        info->pins_from_rules += (uint32_t)rule;
        info->pins_from_colors += red[v] & 1;
        info->pins_from_group += (red[v] >> 1) & 1;
        if (rule || red[v]) out->pins[np++] = v;
    }
    free(red);
    out->np = np;
    info->vertex_count = n;
    info->quad_count = (uint32_t)nq;
    info->spring_count = (uint32_t)ns;
    info->pin_count = np;

    int ok;
    info->bipartite = (uint32_t)is_bipartite(n, out->quads, out->nq, out->springs, out->ns, &ok);
    if (!ok) return oom(b);
    /* The core's coloring on the cloth this mesh makes without shear and bend springs;
     * building it also runs every check rbc_cloth_create will run. */
    rbc_mesh_input in;
    memset(&in, 0, sizeof in);
    in.vertex_count = n;
    in.positions = out->pos;
    in.quad_count = out->nq;
    in.quads = out->quads;
    in.spring_count = out->ns;
    in.springs = out->springs;
    in.vertex_mass = 1.0f;
    in.stiffness = 1.0f;
    rbc_topology topo;
    rbc_allocator alloc = rbc_allocator_default();
    char msg[RBC_ERROR_CAP / 2];
    int32_t trc = rbc_topology_build(&in, &alloc, &topo, msg, sizeof msg);
    if (trc) return rbc_import_error(b->path, trc, "not a cloth mesh: %s", msg);
    info->color_count = topo.ncolors;
    rbc_topology_free(&topo, &alloc);
    return RBC_OK;
}


/* ------------------------------------------------------------------------- */
/* 0b. Checks assimp's own processing would hide                             */
/* ------------------------------------------------------------------------- */

/* An ASCII OFF file's face indices: assimp 5.2.5 replaces an index past the vertex
 * count by the last vertex and reads the file as another mesh. The header is
 * "[ST][C][N][4][n]OFF", the counts "V F E", V vertex lines, then F faces of "k i1 ..
 * ik" (colors may follow). Only a clear integer index out of range is reported;
 * anything this reading does not understand is left to assimp. */
static rbc_result check_off_indices(build *b, const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return RBC_OK; /* assimp says why */
    char line[4096];
    size_t lineno = 0;
    long long nv = -1, nf = -1, v = 0, face = 0;
    int header = 0;
    rbc_result rc = RBC_OK;
    while (rc == RBC_OK && fgets(line, sizeof line, f)) {
        ++lineno;
        char *hash = strchr(line, '#');
        if (hash) *hash = '\0';
        char *p = line;
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') ++p;
        if (!*p) continue;
        if (!header) {
            while (*p == 'S' || *p == 'T' || *p == 'C' || *p == 'N' || *p == '4' || *p == 'n') ++p;
            if (strncmp(p, "OFF", 3) != 0) break;
            p += 3;
            header = 1;
            while (*p == ' ' || *p == '\t') ++p;
            if (strncmp(p, "BINARY", 6) == 0) break;
            if (!*p || *p == '\r' || *p == '\n') continue; /* counts on the next line */
        }
        if (nv < 0) {
            char *e1, *e2;
            nv = strtoll(p, &e1, 10);
            nf = e1 != p ? strtoll(e1, &e2, 10) : -1;
            if (e1 == p || nv < 0 || nf < 0) break;
            continue;
        }
        if (v < nv) {
            ++v;
            continue;
        }
        if (face >= nf) break;
        char *e;
        long long k = strtoll(p, &e, 10);
        if (e == p || k < 0 || k > 1 << 20) break;
        p = e;
        for (long long j = 0; j < k; ++j) {
            long long idx = strtoll(p, &e, 10);
            if (e == p) break;
            p = e;
            if (idx < 0 || idx >= nv) {
                rc = rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                      "line %zu, face %lld (0-based), corner %lld: vertex index "
                                      "%lld is out of range (the file has %lld vertices)",
                                      lineno, face, j, idx, nv);
                break;
            }
        }
        ++face;
    }
    fclose(f);
    return rc;
}

/* A vertex with a non-finite coordinate that a face uses is refused before
 * JoinIdenticalVertices runs: it merges such a vertex into another one (the file
 * would import as a different mesh). */
static rbc_result check_finite(build *b, const struct aiScene *s) {
    for (unsigned mi = 0; mi < s->mNumMeshes; ++mi) {
        const struct aiMesh *me = s->mMeshes[mi];
        if (!me || !me->mVertices || !me->mFaces) continue;
        for (unsigned f = 0; f < me->mNumFaces; ++f) {
            const struct aiFace *fa = &me->mFaces[f];
            if (!fa->mIndices) continue;
            for (unsigned j = 0; j < fa->mNumIndices; ++j) {
                unsigned v = fa->mIndices[j];
                if (v >= me->mNumVertices) continue; /* add_faces names it */
                const struct aiVector3D *p = &me->mVertices[v];
                if (isfinite(p->x) && isfinite(p->y) && isfinite(p->z)) continue;
                return rbc_import_error(b->path, RBC_ERR_BAD_MESH,
                                        "non-finite position: mesh %u (\"%.64s\") face %u corner "
                                        "%u is at (%g, %g, %g) in the file",
                                        mi, me->mName.data, f, j, (double)p->x, (double)p->y,
                                        (double)p->z);
            }
        }
    }
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* 0c. The file's vertex order and units                                     */
/* ------------------------------------------------------------------------- */

/* assimp's vertex arrays, mesh after mesh, before JoinIdenticalVertices: the file's
 * order for formats whose vertices assimp keeps (glTF accessors, PLY). */
static rbc_result assimp_order(build *b, const struct aiScene *s) {
    rbc_file_vertices *fv = &b->file;
    size_t n = 0;
    for (unsigned mi = 0; mi < s->mNumMeshes; ++mi)
        if (s->mMeshes[mi] && s->mMeshes[mi]->mVertices) n += s->mMeshes[mi]->mNumVertices;
    if (n > RBC_IMPORT_MAX_ELEMENTS)
        return rbc_import_error(b->path, RBC_ERR_BAD_MESH, "too many vertices: more than %u",
                                RBC_IMPORT_MAX_ELEMENTS);
    fv->xyz = malloc((3 * n + 1) * sizeof(double));
    fv->list_start = malloc((s->mNumMeshes + 1) * sizeof(uint32_t));
    fv->list_name = calloc(s->mNumMeshes + 1, sizeof(char *));
    if (!fv->xyz || !fv->list_start || !fv->list_name) return oom(b);
    size_t k = 0;
    for (unsigned mi = 0; mi < s->mNumMeshes; ++mi) {
        const struct aiMesh *me = s->mMeshes[mi];
        fv->list_start[mi] = (uint32_t)k;
        fv->list_name[mi] = strdup(me ? me->mName.data : "");
        fv->list_count = mi + 1;
        if (!fv->list_name[mi]) return oom(b);
        if (!me || !me->mVertices) continue;
        for (unsigned v = 0; v < me->mNumVertices; ++v, ++k) {
            fv->xyz[3 * k] = me->mVertices[v].x;
            fv->xyz[3 * k + 1] = me->mVertices[v].y;
            fv->xyz[3 * k + 2] = me->mVertices[v].z;
        }
    }
    fv->list_start[s->mNumMeshes] = (uint32_t)k;
    fv->count = (uint32_t)k;
    b->info.file_order = RBC_FILE_ORDER_ASSIMP;
    return RBC_OK;
}

/* An OBJ's "v" lines, read before assimp runs so that an index out of range is
 * named here; nothing for another format. */
static rbc_result read_obj_lists(build *b) {
    char err[400] = "";
    int r = rbc_obj_file_vertices(b->path, &b->file, err, sizeof err);
    if (r == -2) return rbc_import_error(b->path, RBC_ERR_BAD_MESH, "%s", err);
    if (r < 0)
        return rbc_import_error(b->path, RBC_ERR_IO, "reading the file's vertex lists: %s", err);
    if (r > 0) b->info.file_order = RBC_FILE_ORDER_FILE;
    return RBC_OK;
}

/* After assimp: the OBJ's lists if read, else an FBX's or Collada file's, else
 * assimp's arrays. A file assimp reads but our reader cannot (an FBX or Collada
 * variant it does not know) still simulates, in assimp's order, which the report
 * says. */
static rbc_result read_file_lists(build *b, const struct aiScene *s) {
    if (b->info.file_order == RBC_FILE_ORDER_FILE) return RBC_OK;
    char err[400] = "";
    int r = rbc_fbx_file_vertices(b->path, &b->file, err, sizeof err);
    if (r == 0) r = rbc_dae_file_vertices(b->path, &b->file, err, sizeof err);
    if (r <= 0) {
        rbc_file_vertices_free(&b->file);
        return assimp_order(b, s);
    }
    b->info.file_order = RBC_FILE_ORDER_FILE;
    return RBC_OK;
}

/* A double from assimp's metadata (FBX stores UnitScaleFactor as a double, some
 * exporters as a float or an integer). */
static int meta_number(const struct aiScene *s, const char *key, double *out) {
    const struct aiMetadata *m = s->mMetaData;
    for (unsigned i = 0; m && m->mKeys && m->mValues && i < m->mNumProperties; ++i) {
        if (strcmp(m->mKeys[i].data, key) != 0 || !m->mValues[i].mData) continue;
        switch (m->mValues[i].mType) {
        case AI_DOUBLE: *out = *(const double *)m->mValues[i].mData; return 1;
        case AI_FLOAT: *out = *(const float *)m->mValues[i].mData; return 1;
        case AI_INT32: *out = *(const int32_t *)m->mValues[i].mData; return 1;
        default: return 0;
        }
    }
    return 0;
}

/* The factor from the file's coordinates (after its node transforms) to metres and
 * `scale`. assimp scales a Collada scene's root node by <unit meter> itself (so
 * keeping the file's units divides it out again) and leaves an FBX's
 * UnitScaleFactor (centimetres per unit) in the metadata. */
static void file_units(build *b, const struct aiScene *s) {
    double declared = 0.0, by_assimp = 1.0, fbx = 0.0;
    if (b->info.file_order == RBC_FILE_ORDER_FILE && b->file.unit_metres > 0.0 &&
        isfinite(b->file.unit_metres))
        declared = b->file.unit_metres;
    if (meta_number(s, "UnitScaleFactor", &fbx) && fbx > 0.0 && isfinite(fbx)) {
        declared = fbx / 100.0;
    } else if (declared > 0.0) {
        by_assimp = declared; /* Collada: assimp applied it on the root node */
    } else if (rbc_path_has_ext(b->path, ".gltf") || rbc_path_has_ext(b->path, ".glb")) {
        declared = 1.0; /* glTF 2.0 is metres by definition */
    }
    double unit = declared > 0.0 ? declared : 1.0;
    int keep = b->def.keep_file_units != 0;
    b->scale = (double)b->def.scale * (keep ? 1.0 / by_assimp : unit / by_assimp);
    b->info.file_unit_metres = (float)declared;
    b->info.applied_scale = (float)((double)b->def.scale * (keep ? 1.0 : unit));
    b->info.file_units_kept = (uint32_t)(keep && declared > 0.0 && declared != 1.0);
}

/* ------------------------------------------------------------------------- */
/* 8. The file's vertices mapped to the mesh's                               */
/* ------------------------------------------------------------------------- */

/* Points hashed by cells of side 16h, for "the nearest point within h": a query
 * looks only in the cells its box of half-side h touches, 1.4 on average and at most
 * 8 (a hash probe each; a cell of side 2h took 8 nearly always, and sorting the cells
 * and searching them took most of a 1M-vertex import's time). h is a few float
 * roundings, so a cell still holds one vertex, or the copies at one place. */
typedef struct point_grid {
    int64_t *keys;  /* [3 cap] */
    uint32_t *head; /* [cap] first point of the cell, UINT32_MAX = empty slot */
    uint32_t *next; /* [n] next point of the same cell */
    size_t mask;
    double inv;     /* 1 / (16h) */
} point_grid;

static void grid_free(point_grid *g) {
    free(g->keys);
    free(g->head);
    free(g->next);
}

static int64_t cell_coord(double x, double inv) {
    double t = x * inv;
    if (isnan(t)) return 0; /* a loose non-finite vertex: never within h of anything */
    if (t > 4e18) return (int64_t)4e18;
    if (t < -4e18) return (int64_t)-4e18;
    int64_t q = (int64_t)t; /* floor without libm's call (no SSE4.1 in the baseline) */
    return q - ((double)q > t);
}

static int grid_build(point_grid *g, const double *xyz, size_t n, double h) {
    memset(g, 0, sizeof *g);
    size_t cap = 16;
    while (cap < 2 * n) cap *= 2;
    g->mask = cap - 1;
    g->inv = 1.0 / (16.0 * h);
    g->keys = malloc(3 * cap * sizeof *g->keys);
    g->head = malloc(cap * sizeof *g->head);
    g->next = malloc((n + 1) * sizeof *g->next);
    if (!g->keys || !g->head || !g->next) return 0;
    memset(g->head, 0xFF, cap * sizeof *g->head);
    cell_table t = {g->keys, g->head, g->mask};
    for (size_t i = n; i-- > 0;) { /* backwards: each cell's chain in index order */
        int64_t key[3];
        for (int c = 0; c < 3; ++c) key[c] = cell_coord(xyz[3 * i + c], g->inv);
        size_t slot = cell_slot(&t, key);
        if (g->head[slot] == UINT32_MAX) memcpy(&g->keys[3 * slot], key, sizeof key);
        g->next[i] = g->head[slot];
        g->head[slot] = (uint32_t)i;
    }
    return 1;
}

/* The point nearest p within h (per coordinate) among `xyz`; among equally near
 * ones the one `prefer` marks, then the lowest index. UINT32_MAX if none. */
static uint32_t grid_nearest(const point_grid *g, const double *xyz, const double p[3], double h,
                             const uint8_t *prefer) {
    int64_t lo[3], hi[3];
    for (int c = 0; c < 3; ++c) {
        lo[c] = cell_coord(p[c] - h, g->inv);
        hi[c] = cell_coord(p[c] + h, g->inv);
        if (hi[c] - lo[c] > 1) hi[c] = lo[c] + 1; /* cells are wider than the box */
    }
    cell_table t = {g->keys, g->head, g->mask};
    uint32_t best = UINT32_MAX;
    double best_d = INFINITY;
    int best_pref = 0;
    for (int64_t x = lo[0]; x <= hi[0]; ++x)
        for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t z = lo[2]; z <= hi[2]; ++z) {
                const int64_t key[3] = {x, y, z};
                for (uint32_t k = g->head[cell_slot(&t, key)]; k != UINT32_MAX; k = g->next[k]) {
                    const double *o = xyz + 3 * (size_t)k;
                    double ex = fabs(o[0] - p[0]), ey = fabs(o[1] - p[1]), ez = fabs(o[2] - p[2]);
                    if (!(ex <= h && ey <= h && ez <= h)) continue;
                    double d = ex * ex + ey * ey + ez * ez;
                    int pref = prefer ? prefer[k] : 0;
                    if (d < best_d || (d == best_d && (pref > best_pref ||
                                                       (pref == best_pref && k < best)))) {
                        best = k;
                        best_d = d;
                        best_pref = pref;
                    }
                }
            }
    return best;
}

/* Rows 1..3 of the inverse of the affine map scale * m; 0 if it is singular. */
static int affine_inverse(const double m[12], double scale, double out[12]) {
    double a[9];
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) a[3 * r + c] = scale * m[4 * r + c];
    double t[3] = {scale * m[3], scale * m[7], scale * m[11]};
    double co[9] = {a[4] * a[8] - a[5] * a[7], a[5] * a[6] - a[3] * a[8], a[3] * a[7] - a[4] * a[6],
                    a[2] * a[7] - a[1] * a[8], a[0] * a[8] - a[2] * a[6], a[1] * a[6] - a[0] * a[7],
                    a[1] * a[5] - a[2] * a[4], a[2] * a[3] - a[0] * a[5], a[0] * a[4] - a[1] * a[3]};
    double det = a[0] * co[0] + a[1] * co[1] + a[2] * co[2];
    double norm = 0.0;
    for (int i = 0; i < 9; ++i) norm = fmax(norm, fabs(a[i]));
    if (!(fabs(det) > 1e-12 * norm * norm * norm) || !isfinite(det)) return 0;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) out[4 * r + c] = co[3 * c + r] / det; /* adjugate */
        out[4 * r + 3] = -(out[4 * r] * t[0] + out[4 * r + 1] * t[1] + out[4 * r + 2] * t[2]);
    }
    return 1;
}

/* Each file vertex finds the source vertex at its place in the file's coordinates
 * (within a few float roundings: the file's text is parsed by assimp and by our
 * readers), preferring one the mesh keeps; each source vertex finds its file
 * vertex, for the faces of rbc_mesh_write_file_obj. */
static rbc_result map_file_vertices(build *b, rbc_mesh *out) {
    const rbc_file_vertices *fv = &b->file;
    size_t nf = fv->count, ns = b->nsrc;
    double *sx = malloc((3 * ns + 1) * sizeof *sx);
    double *fx = malloc((3 * nf + 1) * sizeof *fx);
    uint8_t *kept = calloc(ns + 1, 1);
    out->nf = (uint32_t)nf;
    out->ninst = (uint32_t)b->ninst;
    out->file_map = malloc((nf + 1) * sizeof(uint32_t));
    out->file_inst = malloc((nf + 1) * sizeof(uint32_t));
    out->file_rest = malloc((3 * nf + 1) * sizeof(float));
    out->inst_inv = calloc(12 * b->ninst + 1, sizeof(double)); /* a singular one stays 0 */
    out->ncv = (uint32_t)ns;
    out->cv_file = malloc((ns + 1) * sizeof(uint32_t));
    out->cv_mesh = malloc((ns + 1) * sizeof(uint32_t));
    rbc_result rc = RBC_OK;
    point_grid g = {0}, gf = {0};
    uint32_t *file_of = NULL; /* welded vertex -> the first file vertex found for it */
    if (!sx || !fx || !kept || !out->file_map || !out->file_inst || !out->file_rest ||
        !out->inst_inv || !out->cv_file || !out->cv_mesh) {
        rc = oom(b);
        goto done;
    }
    double big = 0.0;
    for (size_t i = 0; i < ns; ++i) {
        uint32_t w = b->weld_map[i];
        uint32_t v = b->remap && w < b->nw ? b->remap[w] : UINT32_MAX;
        out->cv_mesh[i] = v;
        kept[i] = v != UINT32_MAX;
        for (int c = 0; c < 3; ++c) {
            sx[3 * i + c] = b->src_raw[3 * i + c];
            if (isfinite(sx[3 * i + c])) big = fmax(big, fabs(sx[3 * i + c]));
        }
    }
    for (size_t k = 0; k < nf; ++k)
        for (int c = 0; c < 3; ++c) {
            /* as float, the precision assimp reads the file with */
            float f = (float)fv->xyz[3 * k + c];
            fx[3 * k + c] = f;
            out->file_rest[3 * k + c] = f;
            if (isfinite(f)) big = fmax(big, fabs((double)f));
        }
    /* 8 float roundings of the largest coordinate: two parses of one decimal number
     * differ by one at most, distinct vertices far more in any mesh worth simulating. */
    double h = big > 0.0 ? big * 8.0 * 0x1p-24 : 0x1p-126;
    file_of = malloc(((size_t)b->nw + 1) * sizeof *file_of);
    if (!file_of || !grid_build(&g, sx, ns, h)) {
        rc = oom(b);
        goto done;
    }
    memset(file_of, 0xFF, ((size_t)b->nw + 1) * sizeof *file_of);
    uint32_t unmapped = 0;
    for (size_t k = 0; k < nf; ++k) {
        uint32_t s = grid_nearest(&g, sx, fx + 3 * k, h, kept);
        uint32_t v = s == UINT32_MAX ? UINT32_MAX : out->cv_mesh[s];
        out->file_map[k] = v;
        out->file_inst[k] = v == UINT32_MAX ? UINT32_MAX : b->src_inst[s];
        unmapped += v == UINT32_MAX;
        if (s != UINT32_MAX && file_of[b->weld_map[s]] == UINT32_MAX)
            file_of[b->weld_map[s]] = (uint32_t)k;
    }
    /* The other way: a source vertex's file vertex is, nearly always, the one found
     * for its welded vertex (the copies at one place weld); only what that does not
     * settle (welding off, or a weld_distance wider than h) is searched for. */
    size_t left = 0;
    for (size_t i = 0; i < ns; ++i) {
        uint32_t k = file_of[b->weld_map[i]];
        int near = k != UINT32_MAX && fabs(fx[3 * (size_t)k] - sx[3 * i]) <= h &&
                   fabs(fx[3 * (size_t)k + 1] - sx[3 * i + 1]) <= h &&
                   fabs(fx[3 * (size_t)k + 2] - sx[3 * i + 2]) <= h;
        out->cv_file[i] = near ? k : UINT32_MAX;
        left += !near;
    }
    if (left && !grid_build(&gf, fx, nf, h)) {
        rc = oom(b);
        goto done;
    }
    for (size_t i = 0; i < ns && left; ++i)
        if (out->cv_file[i] == UINT32_MAX) out->cv_file[i] = grid_nearest(&gf, fx, sx + 3 * i, h, NULL);
    for (size_t k = 0; k < b->ninst; ++k) {
        if (!affine_inverse(b->inst[k].m, b->scale, out->inst_inv + 12 * k)) {
            /* a placement that flattens its mesh cannot be undone: its vertices keep
             * their place in the file */
            for (size_t j = 0; j < nf; ++j)
                if (out->file_inst[j] == k) out->file_inst[j] = UINT32_MAX;
        }
    }
    b->info.file_vertex_count = (uint32_t)nf;
    b->info.unmapped_file_vertices = unmapped;
done:
    grid_free(&g);
    grid_free(&gf);
    free(file_of);
    free(sx);
    free(fx);
    free(kept);
    return rc;
}

/* The faces of the placements taken, their corner vertices' UVs and normals and
 * the placements' names: what rbc_mesh_write_file_obj writes. */
static rbc_result file_faces(build *b, const struct aiScene *s, rbc_mesh *out) {
    size_t ns = b->nsrc, nfc = 0, ncorner = 0;
    for (size_t k = 0; k < b->ninst; ++k) {
        const struct aiMesh *me = s->mMeshes[b->inst[k].mesh];
        for (unsigned f = 0; me->mFaces && f < me->mNumFaces; ++f)
            if (me->mFaces[f].mNumIndices >= 3) {
                ++nfc;
                ncorner += me->mFaces[f].mNumIndices;
            }
    }
    if (nfc > RBC_IMPORT_MAX_ELEMENTS || ncorner > RBC_IMPORT_MAX_ELEMENTS)
        return rbc_import_error(b->path, RBC_ERR_BAD_MESH, "too many faces: more than %u",
                                RBC_IMPORT_MAX_ELEMENTS);
    /* zeroed: a corner vertex without a UV or normal still travels to the plugin */
    out->cv_uv = calloc(2 * ns + 1, sizeof(float));
    out->cv_nrm = calloc(3 * ns + 1, sizeof(float));
    out->cv_flags = calloc(ns + 1, 1);
    out->nfc = (uint32_t)nfc;
    out->nfcorner = (uint32_t)ncorner;
    out->fc_start = malloc((nfc + 1) * sizeof(uint32_t));
    out->fc_corner = malloc((ncorner + 1) * sizeof(uint32_t));
    out->fc_inst = malloc((nfc + 1) * sizeof(uint32_t));
    out->inst_name = calloc(b->ninst + 1, sizeof *out->inst_name);
    if (!out->cv_uv || !out->cv_nrm || !out->cv_flags || !out->fc_start || !out->fc_corner ||
        !out->fc_inst || !out->inst_name)
        return oom(b);
    size_t f_at = 0, c_at = 0;
    for (size_t k = 0; k < b->ninst; ++k) {
        const instance *in = &b->inst[k];
        const struct aiMesh *me = s->mMeshes[in->mesh];
        snprintf(out->inst_name[k], sizeof out->inst_name[k], "%.63s",
                 in->name[0] ? in->name : me->mName.data);
        const struct aiVector3D *uv = me->mTextureCoords[0];
        for (unsigned v = 0; v < me->mNumVertices && me->mVertices; ++v) {
            size_t i = in->base + (size_t)v;
            if (uv) {
                out->cv_uv[2 * i] = uv[v].x;
                out->cv_uv[2 * i + 1] = uv[v].y;
                out->cv_flags[i] |= 1;
            }
            if (me->mNormals) {
                out->cv_nrm[3 * i] = me->mNormals[v].x;
                out->cv_nrm[3 * i + 1] = me->mNormals[v].y;
                out->cv_nrm[3 * i + 2] = me->mNormals[v].z;
                if (isfinite(out->cv_nrm[3 * i]) && isfinite(out->cv_nrm[3 * i + 1]) &&
                    isfinite(out->cv_nrm[3 * i + 2]))
                    out->cv_flags[i] |= 2;
            }
        }
        for (unsigned f = 0; me->mFaces && f < me->mNumFaces; ++f) {
            const struct aiFace *fa = &me->mFaces[f];
            if (fa->mNumIndices < 3) continue;
            out->fc_start[f_at] = (uint32_t)c_at;
            out->fc_inst[f_at++] = (uint32_t)k;
            for (unsigned j = 0; j < fa->mNumIndices; ++j)
                out->fc_corner[c_at++] = in->base + fa->mIndices[j]; /* checked by add_faces */
        }
    }
    out->fc_start[nfc] = (uint32_t)c_at;
    return RBC_OK;
}

rbc_result rbc_import_convert(const char *path, const rbc_mesh_import_def *def, rbc_mesh *m) {
    build b;
    memset(&b, 0, sizeof b);
    memset(m, 0, sizeof *m);
    b.path = path;
    b.def = *def;
    rbc_result rc = RBC_OK;

    /* Open errors are ours to name (assimp's message for them is vaguer). */
    struct stat st;
    if (stat(path, &st) != 0)
        return rbc_import_error(b.path, RBC_ERR_IO, "cannot open the file: %s", strerror(errno));
    if (!S_ISREG(st.st_mode))
        return rbc_import_error(b.path, RBC_ERR_IO, "cannot open the file: not a regular file");
    FILE *probe = fopen(path, "rb");
    if (!probe)
        return rbc_import_error(b.path, RBC_ERR_IO, "cannot open the file: %s", strerror(errno));
    /* assimp 5.2.5 loops forever on a PLY file whose header has no end_header (a
     * truncated or cut header; found by tests/import): refuse it before assimp
     * sees it. assimp recognises PLY by its first token, so do we. */
    char head[4096];
    size_t got = fread(head, 1, sizeof head - 1, probe);
    head[got] = '\0';
    int is_ply = got >= 4 && memcmp(head, "ply", 3) == 0 && (head[3] == '\n' || head[3] == '\r' ||
                                                           head[3] == ' ');
    int has_end = 0;
    if (is_ply) { /* the header is text; look through its first MiB */
        size_t seen = got;
        char carry[16] = "";
        for (;;) {
            if (memmem(head, got, "end_header", 10)) {
                has_end = 1;
                break;
            }
            if (seen >= (1u << 20) || got < sizeof head - 1) break;
            memcpy(carry, head + got - 9, 9); /* a token split across reads */
            memcpy(head, carry, 9);
            got = 9 + fread(head + 9, 1, sizeof head - 10, probe);
            seen += got - 9;
            if (got == 9) break;
        }
    }
    fclose(probe);
    /* assimp 5.2.5 reserves memory for the vertex count an OFF header declares before
     * reading any vertex: a header claiming 3.5e11 vertices (assimp-testmodels'
     * invalid/OutOfMemory.off) exhausts memory and takes the host down. A vertex
     * needs at least 6 bytes of text ("0 0 0\n") and a face 8: refuse counts the
     * file cannot hold. The header is "[ST][C][N][4][n]OFF" then the counts. */
    if (!is_ply) {
        const char *q = head;
        while (*q == 'S' || *q == 'T' || *q == 'C' || *q == 'N' || *q == '4' || *q == 'n') ++q;
        if (strncmp(q, "OFF", 3) == 0 && (q[3] == '\n' || q[3] == '\r' || q[3] == ' ' || q[3] == '\t')) {
            q += 3;
            while (*q == ' ' || *q == '\t' || *q == '\r' || *q == '\n' || *q == '#') {
                if (*q == '#') /* a comment line */
                    while (*q && *q != '\n') ++q;
                else
                    ++q;
            }
            char *end1 = NULL, *end2 = NULL;
            unsigned long long nv = strtoull(q, &end1, 10);
            unsigned long long nf = end1 && end1 != q ? strtoull(end1, &end2, 10) : 0;
            unsigned long long sz = (unsigned long long)st.st_size;
            if (strncmp(q, "BINARY", 6) != 0 && end1 != q && (nv > sz / 6 || nf > sz / 8))
                return rbc_import_error(b.path, RBC_ERR_IO,
                                        "the OFF header declares %llu vertices and %llu faces, "
                                        "more than a %llu-byte file can hold (refused here: assimp "
                                        "5.2.5 allocates for the declared counts first)",
                                        nv, nf, sz);
        }
    }
    if (is_ply && !has_end)
        return rbc_import_error(b.path, RBC_ERR_IO,
                                "assimp could not read the file: a PLY header without end_header "
                                "(refused here: assimp 5.2.5 loops forever on it)");
    /* An OBJ's "v" list, and its indices checked, before assimp reads it; an OFF's
     * indices too (assimp would clamp them). */
    rc = read_obj_lists(&b);
    if (!rc && !is_ply && rbc_path_has_ext(path, ".off")) rc = check_off_indices(&b, path);
    if (rc) {
        build_free(&b);
        return rc;
    }

    /* 1. assimp, keeping polygons. No logger is attached, so assimp's DefaultLogger
     * is its NullLogger: nothing is printed. Skeleton-only files are not turned into
     * bone meshes. */
    struct aiPropertyStore *props = aiCreatePropertyStore();
    if (!props) return oom(&b);
    aiSetImportPropertyInteger(props, AI_CONFIG_IMPORT_NO_SKELETON_MESHES, 1);
    char aierr[512] = "";
    const struct aiScene *scene =
        aiImportFileExWithProperties(path, aiProcess_ValidateDataStructure, NULL, props);
    if (!scene) {
        const char *e = aiGetErrorString();
        snprintf(aierr, sizeof aierr, "%s", e && *e ? e : "(no message)");
    }
    aiReleasePropertyStore(props);
    if (!scene) {
        /* Messages end in a newline at times; keep one line. */
        for (char *p = aierr; *p; ++p)
            if (*p == '\n' || *p == '\r') *p = ' ';
        build_free(&b);
        /* assimp's ValidateDataStructure names the face and corner of an index
         * out of range ("aiMesh::mFaces[0]::mIndices[3] is out of range"): the
         * mesh is bad, not the file unreadable. */
        if (strstr(aierr, "Validation failed") && strstr(aierr, "mIndices") &&
            strstr(aierr, "out of range"))
            return rbc_import_error(b.path, RBC_ERR_BAD_MESH,
                                    "a face index is out of range: assimp's check says \"%s\"",
                                    aierr);
        if (strstr(aierr, "No suitable reader found"))
            return rbc_import_error(b.path, RBC_ERR_UNSUPPORTED,
                                    "no assimp reader for this format: %s", aierr);
        return rbc_import_error(b.path, RBC_ERR_IO, "assimp could not read the file: %s", aierr);
    }
    if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)
        rc = rbc_import_error(b.path, RBC_ERR_BAD_MESH,
                              "no mesh in the file: assimp read an incomplete scene (animation or "
                              "skeleton only)");
    /* Before JoinIdenticalVertices: the check it would defeat, and assimp's own
     * vertex arrays (the file's order for glTF, PLY). */
    if (!rc) rc = check_finite(&b, scene);
    if (!rc) rc = read_file_lists(&b, scene);
    if (!rc) {
        file_units(&b, scene);
        scene = aiApplyPostProcessing(scene, aiProcess_JoinIdenticalVertices);
        if (!scene) {
            build_free(&b);
            return rbc_import_error(b.path, RBC_ERR_IO,
                                    "assimp could not join identical vertices");
        }
    }
    if (!rc) rc = collect_instances(&b, scene);
    if (!rc) rc = collect_vertices(&b, scene);
    if (!rc) rc = weld(&b);
    if (!rc) rc = add_faces(&b, scene);
    if (!rc) rc = file_faces(&b, scene, m);
    aiReleaseImport(scene);
    if (!rc) rc = finish(&b, m);
    if (!rc) rc = map_file_vertices(&b, m);
    if (rc) {
        rbc_import_mesh_free(m);
        build_free(&b);
        return rc;
    }
    m->info = b.info;
    build_free(&b);
    return RBC_OK;
}
