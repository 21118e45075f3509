/* scene.c -- sample scenes: JSON loading and validation, and creation of the world
 * through the plugin's function table (see scene.h; format in scenes/README.md).
 *
 * Validation is strict: unknown or duplicate keys, wrong types, out-of-range numbers
 * and bad indices are errors naming the file and the key path, so a typo in a scene
 * is reported instead of silently falling back to a default.
 */
#include "scene.h"

#include <cJSON.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------- */
/* The built-in default scene: keep identical to scenes/hanging_cloth.json     */
/* (tests/scene checks that both parse to the same scene).                    */
/* ------------------------------------------------------------------------- */

static const char default_scene_json[] =
    "{\n"
    "  \"name\": \"hanging_cloth\",\n"
    "  \"description\": \"The paper's hanging cloth stepped as a game steps it: 100 x 100 "
    "particles 1/99 m apart (1 m square, 19,800 structural springs), horizontal at rest, "
    "pinned at vertices 0 and 99, 1e-4 kg per vertex, k = 1000 N/m, no damping, one 1/60 s "
    "frame per step for 4 s, with the library's default solve: 480 substeps a second (8 a "
    "frame) of 11 red-black SOR iterations each (RBC_PRESET_CLOTH). The built-in default "
    "scene of rbcloth run and make demo.\",\n"
    "  \"frames\": 240,\n"
    "  \"dt\": 0.016666666666666666,\n"
    "  \"world\": {\n"
    "    \"gravity\": [0, -9.81, 0],\n"
    "    \"threads\": 0,\n"
    "    \"backend\": \"auto\"\n"
    "  },\n"
    "  \"cloths\": [\n"
    "    {\n"
    "      \"name\": \"cloth\",\n"
    "\"grid\": {\"nx\": 100, \"ny\": 100, \"spacing\": 0.010101010101010102, \"origin\": "
    "[0, 0, 0], \"plane\": \"xz\"},\n"
    "      \"vertex_mass\": 1e-4,\n"
    "      \"stiffness\": 1000,\n"
    "      \"damping\": 0,\n"
    "      \"pins\": [0, 99]\n"
    "    }\n"
    "  ],\n"
    "  \"colliders\": []\n"
    "}\n";

/* The paper's experiment: keep identical to scenes/hanging_cloth_paper.json (the
 * benches that reproduce the paper load it; tests/scene checks the two agree). */
static const char paper_scene_json[] =
    "{\n"
    "  \"name\": \"hanging_cloth_paper\",\n"
    "  \"description\": \"The paper's experiment (its Fig. 4): the hanging cloth, 100 x 100 "
    "particles 1/99 m apart (1 m square, 19,800 structural springs), horizontal at rest, "
    "pinned at vertices 0 and 99, falling under gravity. 1e-4 kg per vertex, k = 1000 "
    "N/m, h = 2 ms, one step of 11 red-black Gauss-Seidel iterations per frame (the paper "
    "preset), no damping. Far from converged: springs near the pins reach five times "
    "their length.\",\n"
    "  \"frames\": 240,\n"
    "  \"dt\": 0.002,\n"
    "  \"world\": {\n"
    "    \"gravity\": [0, -9.81, 0],\n"
    "    \"substeps\": 1,\n"
    "    \"nonlinear_iterations\": 1,\n"
    "    \"linear_iterations\": 11,\n"
    "    \"threads\": 0,\n"
    "    \"backend\": \"auto\",\n"
    "    \"solver\": {\"preset\": \"paper\"}\n"
    "  },\n"
    "  \"cloths\": [\n"
    "    {\n"
    "      \"name\": \"cloth\",\n"
    "      \"grid\": {\"nx\": 100, \"ny\": 100, \"spacing\": 0.010101010101010102, \"origin\": "
    "[0, 0, 0], \"plane\": \"xz\"},\n"
    "      \"vertex_mass\": 1e-4,\n"
    "      \"stiffness\": 1000,\n"
    "      \"damping\": 0,\n"
    "      \"pins\": [0, 99]\n"
    "    }\n"
    "  ],\n"
    "  \"colliders\": []\n"
    "}\n";

const char *rbc_scene_default_json(void) { return default_scene_json; }

/* ------------------------------------------------------------------------- */
/* Limits (sanity bounds; the plugin checks its own ranges again)             */
/* ------------------------------------------------------------------------- */

#define SCENE_MAX_FILE_BYTES (1u << 30)
#define SCENE_MAX_NAME 64
#define SCENE_MAX_FRAMES 10000000u
#define SCENE_MAX_CLOTHS 1024u
#define SCENE_MAX_COLLIDERS 1024u
#define SCENE_MAX_GRID_SIDE 65536u
/* All grids of a scene together get one grid's limit, whatever the number of
 * cloths. */
#define SCENE_MAX_GRID_VERTICES RBC_GRID_MAX_VERTICES
#define SCENE_MAX_THREADS 1024u
/* Iteration ranges of rbc_world_def. */
#define SCENE_MAX_SUBSTEPS 1024u
#define SCENE_MAX_NONLINEAR 1024u
#define SCENE_MAX_LINEAR 4096u
/* Keyframes per collider or drag, and triangles of an inline collider mesh. */
#define SCENE_MAX_KEYS 1000000u
#define SCENE_MAX_MESH_VERTICES (1u << 24)
#define SCENE_MAX_MESH_TRIANGLES (1u << 25)
/* Key paths such as "cloths[3].drags[12].keyframes[40].target[2]" fit easily. */
#define KEY_MAX 128

/* ------------------------------------------------------------------------- */
/* Messages                                                                  */
/* ------------------------------------------------------------------------- */

typedef struct parser {
    const char *source;
    char *err;
    size_t err_size;
    /* Vertices of the grids generated so far: a grid is a few bytes of JSON that
     * allocate nx * ny vertices, so the whole scene's grids share one cap. */
    uint64_t grid_vertices;
} parser;

static void vformat(char *dst, size_t size, const char *fmt, va_list ap) {
    if (size > 0)
        vsnprintf(dst, size, fmt, ap);
}

static void format(char *dst, size_t size, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vformat(dst, size, fmt, ap);
    va_end(ap);
}

/* "SOURCE: KEY: message". Always returns -1 so callers can `return fail(...)`. */
static int fail(parser *p, const char *key, const char *fmt, ...) {
    if (p->err_size == 0)
        return -1;
    int n = snprintf(p->err, p->err_size, "%s: %s: ", p->source, key);
    if (n >= 0 && (size_t)n < p->err_size) {
        va_list ap;
        va_start(ap, fmt);
        vformat(p->err + n, p->err_size - (size_t)n, fmt, ap);
        va_end(ap);
    }
    return -1;
}

/* Key paths are cut (ending in "...") rather than overrun; KEY_MAX is ample for
 * every path the format allows. */
static void key_mark_cut(char out[KEY_MAX], int written) {
    if (written < 0 || written >= KEY_MAX)
        memcpy(out + KEY_MAX - 4, "...", 4);
}

static void key_join(char out[KEY_MAX], const char *parent, const char *name) {
    int n = parent[0] ? snprintf(out, KEY_MAX, "%s.%s", parent, name)
                      : snprintf(out, KEY_MAX, "%s", name);
    key_mark_cut(out, n);
}

static void key_index(char out[KEY_MAX], const char *parent, size_t index) {
    key_mark_cut(out, snprintf(out, KEY_MAX, "%s[%zu]", parent, index));
}

static const char *json_type(const cJSON *item) {
    if (cJSON_IsNull(item)) return "null";
    if (cJSON_IsBool(item)) return "a boolean";
    if (cJSON_IsNumber(item)) return "a number";
    if (cJSON_IsString(item)) return "a string";
    if (cJSON_IsArray(item)) return "an array";
    if (cJSON_IsObject(item)) return "an object";
    return "an invalid value";
}

/* ------------------------------------------------------------------------- */
/* Typed readers                                                             */
/* ------------------------------------------------------------------------- */

/* Reject keys not in `allowed` (NULL-terminated) and keys given twice. */
/* Edit distance with transpositions (optimal string alignment), capped: words longer
 * than 63 characters are not compared. */
static int edit_distance(const char *a, const char *b) {
    size_t n = strlen(a), m = strlen(b);
    if (n > 63 || m > 63) return 99;
    int d[64][64];
    for (size_t i = 0; i <= n; ++i) d[i][0] = (int)i;
    for (size_t j = 0; j <= m; ++j) d[0][j] = (int)j;
    for (size_t i = 1; i <= n; ++i)
        for (size_t j = 1; j <= m; ++j) {
            int cost = a[i - 1] != b[j - 1];
            int v = d[i - 1][j] + 1;
            if (d[i][j - 1] + 1 < v) v = d[i][j - 1] + 1;
            if (d[i - 1][j - 1] + cost < v) v = d[i - 1][j - 1] + cost;
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] &&
                d[i - 2][j - 2] + 1 < v)
                v = d[i - 2][j - 2] + 1;
            d[i][j] = v;
        }
    return d[n][m];
}

const char *rbc_scene_nearest(const char *word, const char *const *choices) {
    if (!word || !word[0]) return NULL;
    size_t len = strlen(word);
    /* A typo: one edit, two from 6 characters on ("rn" -> "run", "substep" ->
     * "substeps"); a unique choice the word begins, from 3 characters on, also
     * counts ("--iter" -> "--iterations"). */
    int limit = len >= 6 ? 2 : 1;
    const char *best = NULL, *prefix = NULL;
    int best_d = limit + 1, prefixes = 0;
    for (const char *const *c = choices; *c; ++c) {
        int dist = edit_distance(word, *c);
        if (dist < best_d) {
            best_d = dist;
            best = *c;
        }
        if (len >= 3 && strncmp(*c, word, len) == 0) {
            prefix = *c;
            ++prefixes;
        }
    }
    if (best && best_d > 0) return best;
    return prefixes == 1 ? prefix : NULL;
}

static int check_keys(parser *p, const cJSON *obj, const char *key,
                      const char *const *allowed) {
    for (const cJSON *child = obj->child; child; child = child->next) {
        char child_key[KEY_MAX];
        key_join(child_key, key, child->string);
        int known = 0;
        for (const char *const *a = allowed; *a; ++a)
            known |= strcmp(*a, child->string) == 0;
        if (!known) {
            char list[512] = "";
            size_t used = 0;
            for (const char *const *a = allowed; *a && used < sizeof list; ++a) {
                int n = snprintf(list + used, sizeof list - used, "%s%s",
                                 a == allowed ? "" : ", ", *a);
                if (n < 0)
                    break;
                used += (size_t)n;
            }
            const char *near = rbc_scene_nearest(child->string, allowed);
            if (near)
                return fail(p, child_key, "unknown key; did you mean \"%s\"? (expected one of: %s)",
                            near, list);
            return fail(p, child_key, "unknown key (expected one of: %s)", list);
        }
        for (const cJSON *prev = obj->child; prev != child; prev = prev->next)
            if (strcmp(prev->string, child->string) == 0)
                return fail(p, child_key, "key given twice");
    }
    return 0;
}

static int expect_object(parser *p, const cJSON *item, const char *key) {
    if (!cJSON_IsObject(item))
        return fail(p, key, "must be an object, got %s", json_type(item));
    return 0;
}

/* *out = obj[name] or NULL. Fails if required and missing. */
static int member(parser *p, const cJSON *obj, const char *obj_key, const char *name,
                  int required, const cJSON **out) {
    *out = cJSON_GetObjectItemCaseSensitive(obj, name);
    if (!*out && required) {
        char key[KEY_MAX];
        key_join(key, obj_key, name);
        return fail(p, key, "required key is missing");
    }
    return 0;
}

static int read_u32(parser *p, const cJSON *item, const char *key, uint32_t min, uint32_t max,
                    uint32_t *out) {
    if (!cJSON_IsNumber(item))
        return fail(p, key, "must be an integer in [%u, %u], got %s", min, max,
                    json_type(item));
    double v = item->valuedouble;
    if (!isfinite(v) || v != floor(v))
        return fail(p, key, "must be an integer in [%u, %u], got %g", min, max, v);
    if (v < (double)min || v > (double)max)
        return fail(p, key, "must be an integer in [%u, %u], got %.0f", min, max, v);
    *out = (uint32_t)v;
    return 0;
}

typedef enum number_range {
    RANGE_ANY,
    RANGE_POSITIVE,
    RANGE_NON_NEGATIVE
} number_range;

/* A number that is finite as a float (and > 0 as a float for RANGE_POSITIVE). */
static int read_number(parser *p, const cJSON *item, const char *key, number_range range,
                       double *out) {
    static const char *const what[] = {"a number", "a number > 0", "a number >= 0"};
    if (!cJSON_IsNumber(item))
        return fail(p, key, "must be %s, got %s", what[range], json_type(item));
    double v = item->valuedouble;
    if (!isfinite(v) || fabs(v) > FLT_MAX)
        return fail(p, key, "must be %s that fits a float, got %g", what[range], v);
    if ((range == RANGE_POSITIVE && !((float)v > 0.0f)) || (range == RANGE_NON_NEGATIVE && v < 0.0))
        return fail(p, key, "must be %s, got %g", what[range], v);
    *out = v;
    return 0;
}

static int read_float(parser *p, const cJSON *item, const char *key, number_range range,
                      float *out) {
    double v;
    if (read_number(p, item, key, range, &v))
        return -1;
    *out = (float)v;
    return 0;
}

/* An array of exactly n numbers, each finite as a float. */
static int read_vector(parser *p, const cJSON *item, const char *key, int n, double *out) {
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) != n)
        return fail(p, key, "must be an array of %d numbers, got %s%s", n, json_type(item),
                    cJSON_IsArray(item) ? " of another length" : "");
    int i = 0;
    for (const cJSON *e = item->child; e; e = e->next, ++i) {
        char element_key[KEY_MAX];
        key_index(element_key, key, (size_t)i);
        if (read_number(p, e, element_key, RANGE_ANY, &out[i]))
            return -1;
    }
    return 0;
}

static int read_vector_f(parser *p, const cJSON *item, const char *key, int n, float *out) {
    double v[4];
    if (n > 4 || read_vector(p, item, key, n, v))
        return -1;
    for (int i = 0; i < n; ++i)
        out[i] = (float)v[i];
    return 0;
}

static int read_string(parser *p, const cJSON *item, const char *key, const char **out) {
    if (!cJSON_IsString(item))
        return fail(p, key, "must be a string, got %s", json_type(item));
    *out = item->valuestring;
    return 0;
}

/* A string that is one of `choices` (NULL-terminated); *out = its index. */
static int read_choice(parser *p, const cJSON *item, const char *key,
                       const char *const *choices, int *out) {
    const char *s = NULL;
    if (read_string(p, item, key, &s))
        return -1;
    for (int i = 0; choices[i]; ++i) {
        if (strcmp(s, choices[i]) == 0) {
            *out = i;
            return 0;
        }
    }
    char list[256] = "";
    size_t used = 0;
    for (int i = 0; choices[i] && used < sizeof list; ++i) {
        int n = snprintf(list + used, sizeof list - used, "%s\"%s\"", i ? ", " : "", choices[i]);
        if (n < 0)
            break;
        used += (size_t)n;
    }
    const char *near = rbc_scene_nearest(s, choices);
    if (near)
        return fail(p, key, "must be one of %s, got \"%s\"; did you mean \"%s\"?", list, s,
                    near);
    return fail(p, key, "must be one of %s, got \"%s\"", list, s);
}

/* Names become parts of output file names: keep them portable. */
static int read_name(parser *p, const cJSON *item, const char *key, char **out) {
    const char *s = NULL;
    if (read_string(p, item, key, &s))
        return -1;
    size_t len = strlen(s);
    int ok = len > 0 && len <= SCENE_MAX_NAME && s[0] != '.';
    for (size_t i = 0; ok && i < len; ++i) {
        char c = s[i];
        ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
             c == '_' || c == '-' || c == '.';
    }
    if (!ok)
        return fail(p, key,
                    "must be 1 to %d characters of [A-Za-z0-9_.-] not starting with '.' "
                    "(it is used in file names), got \"%s\"",
                    SCENE_MAX_NAME, s);
    *out = strdup(s);
    if (!*out)
        return fail(p, key, "out of memory");
    return 0;
}

/* An array of 1..max elements; *out_count receives the length. */
static int read_array(parser *p, const cJSON *item, const char *key, uint32_t min,
                      uint32_t max, uint32_t *out_count) {
    if (!cJSON_IsArray(item))
        return fail(p, key, "must be an array, got %s", json_type(item));
    int n = cJSON_GetArraySize(item);
    if (n < 0 || (uint32_t)n < min || (uint32_t)n > max)
        return fail(p, key, "must have %u to %u elements, got %d", min, max, n);
    *out_count = (uint32_t)n;
    return 0;
}

/* An array of min..max points [x, y, z] at `key`: *out malloc'd, *count set. */
static int read_points(parser *p, const cJSON *item, const char *key, uint32_t min, uint32_t max,
                       float **out, uint32_t *count) {
    char k[KEY_MAX];
    uint32_t n = 0;
    if (read_array(p, item, key, min, max, &n))
        return -1;
    if (!(*out = malloc((size_t)n * 3 * sizeof **out)))
        return fail(p, key, "out of memory");
    *count = n;
    uint32_t i = 0;
    for (const cJSON *v = item->child; v; v = v->next, ++i) {
        key_index(k, key, i);
        if (read_vector_f(p, v, k, 3, *out + 3 * (size_t)i))
            return -1;
    }
    return 0;
}

/* An array of min..max faces at `key`, each `corners` distinct indices below
 * vertex_count (`what`, "quad" or "triangle", names one in the messages): *out
 * malloc'd, *count set. */
static int read_faces(parser *p, const cJSON *item, const char *key, uint32_t min, uint32_t max,
                      int corners, const char *what, uint32_t vertex_count, uint32_t **out,
                      uint32_t *count) {
    char k[KEY_MAX];
    uint32_t n = 0;
    if (read_array(p, item, key, min, max, &n))
        return -1;
    if (!(*out = malloc((size_t)n * (size_t)corners * sizeof **out)))
        return fail(p, key, "out of memory");
    *count = n;
    uint32_t i = 0;
    for (const cJSON *f = item->child; f; f = f->next, ++i) {
        key_index(k, key, i);
        if (!cJSON_IsArray(f) || cJSON_GetArraySize(f) != corners)
            return fail(p, k, "must be an array of %d vertex indices, got %s%s", corners,
                        json_type(f), cJSON_IsArray(f) ? " of another length" : "");
        uint32_t *dst = *out + (size_t)corners * i;
        int corner = 0;
        for (const cJSON *e = f->child; e; e = e->next, ++corner) {
            char ek[KEY_MAX];
            key_index(ek, k, (size_t)corner);
            if (read_u32(p, e, ek, 0, vertex_count - 1, &dst[corner]))
                return -1;
            for (int prev = 0; prev < corner; ++prev)
                if (dst[prev] == dst[corner])
                    return fail(p, k, "degenerate %s: vertex %u appears twice", what, dst[corner]);
        }
    }
    return 0;
}

static int read_bool(parser *p, const cJSON *item, const char *key, int *out) {
    if (!cJSON_IsBool(item))
        return fail(p, key, "must be true or false, got %s", json_type(item));
    *out = cJSON_IsTrue(item) ? 1 : 0;
    return 0;
}

/* A unit quaternion [x, y, z, w]: a length within 1e-3 of 1 (what a human types
 * with a few digits), normalised exactly. */
static int read_quaternion(parser *p, const cJSON *item, const char *key, float out[4]) {
    double q[4];
    if (read_vector(p, item, key, 4, q))
        return -1;
    double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(fabs(norm - 1.0) <= 1e-3))
        return fail(p, key, "must be a unit quaternion [x, y, z, w], got one of length %g", norm);
    for (int i = 0; i < 4; ++i)
        out[i] = (float)(q[i] / norm);
    return 0;
}

/* A vertex index < count, as pins and drags give them. */
static int read_vertex(parser *p, const cJSON *e, const char *key, uint32_t count, uint32_t *out) {
    if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 0.0)
        return cJSON_IsNumber(e)
                   ? fail(p, key, "must be a vertex index (an integer >= 0), got %g", e->valuedouble)
                   : fail(p, key, "must be a vertex index (an integer >= 0), got %s", json_type(e));
    if (e->valuedouble >= (double)count)
        return fail(p, key, "vertex index %.0f is out of range (the cloth has %u vertices)",
                    e->valuedouble, count);
    *out = (uint32_t)e->valuedouble;
    return 0;
}

/* keyframes[i].time: a number >= 0, greater than the previous keyframe's. */
static int read_key_time(parser *p, const cJSON *obj, const char *key, uint32_t index,
                         double previous, double *out) {
    const cJSON *time;
    char k[KEY_MAX];
    if (member(p, obj, key, "time", 1, &time))
        return -1;
    key_join(k, key, "time");
    if (read_number(p, time, k, RANGE_NON_NEGATIVE, out))
        return -1;
    if (index > 0 && !(*out > previous))
        return fail(p, k, "keyframe times must increase: got %g after %g", *out, previous);
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Sections                                                                  */
/* ------------------------------------------------------------------------- */

static const char *const backend_names[] = {"auto", "cpu", "cuda", NULL};
static const rbc_backend backend_values[] = {RBC_BACKEND_AUTO, RBC_BACKEND_CPU,
                                             RBC_BACKEND_CUDA};

/* Solver names as the CLI and the scenes spell them, in rbc_solver_kind order. */
const char *const rbc_scene_solver_names[] = {"rbgs",     "jacobi",          "jacobi_chebyshev",
                                              "gauss_seidel", "rbgs_sor",    "rbgs_chebyshev",
                                              "multicolor_gs", "direct",     NULL};
const char *const rbc_scene_mode_names[] = {"fixed", "tolerance", "budget", "target", NULL};
/* Indexed by rbc_preset (ABI 1.4; "cloth" 1.6). */
const char *const rbc_scene_preset_names[] = {"paper", "game_60hz", "cloth", NULL};

void rbc_scene_solver_preset(rbc_solver_def *d, int preset) {
    /* rbc_solver_def's documented field defaults (RBC_PRESET_PAPER); the loader does
     * not call the library, so the presets are written out here and the test
     * scene_presets checks them against rbc_solver_def_preset. */
    memset(d, 0, sizeof *d);
    d->struct_size = sizeof *d;
    d->solver = RBC_SOLVER_RBGS;
    d->chebyshev_delay = 2;
    d->mode = RBC_ITERATE_FIXED;
    d->tolerance = 1e-3f;
    d->budget_ms = 2.0f;
    d->max_linear_iterations = 1000;
    d->energy_guard = RBC_ENERGY_GUARD_CLAMP;
    d->target_strain = 0.05f;
    d->max_substeps = 16;
    if (preset == RBC_PRESET_GAME_60HZ) {
        d->mode = RBC_ITERATE_TARGET;
        d->max_substeps = 32;
        d->max_linear_iterations = 8;
    } else if (preset == RBC_PRESET_CLOTH) {
        d->solver = RBC_SOLVER_RBGS_SOR;
        d->max_substeps = 32;
    }
}
/* Indexed by rbc_energy_guard. */
const char *const rbc_scene_energy_guard_names[] = {"off", "clamp", "fail", NULL};

/* The solver object. It starts from the default solve; "preset" replaces that, the
 * other keys change it. */
static int parse_solver(parser *p, const cJSON *obj, const char *key, rbc_solver_def *d) {
    static const char *const keys[] = {"preset",    "kind",      "omega",     "rho",
                                       "chebyshev_delay", "mode", "tolerance",
                                       "budget_ms", "max_linear_iterations", "energy_guard",
                                       "target_strain", "max_substeps", NULL};
    const cJSON *item;
    char k[KEY_MAX];
    int choice;
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "preset"))) {
        key_join(k, key, "preset");
        if (read_choice(p, item, k, rbc_scene_preset_names, &choice))
            return -1;
        rbc_scene_solver_preset(d, choice);
    }
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "kind"))) {
        key_join(k, key, "kind");
        if (read_choice(p, item, k, rbc_scene_solver_names, &choice))
            return -1;
        d->solver = (rbc_solver_kind)choice;
    }
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "mode"))) {
        key_join(k, key, "mode");
        if (read_choice(p, item, k, rbc_scene_mode_names, &choice))
            return -1;
        d->mode = (rbc_iteration_mode)choice;
    }
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "energy_guard"))) {
        key_join(k, key, "energy_guard");
        if (read_choice(p, item, k, rbc_scene_energy_guard_names, &choice))
            return -1;
        d->energy_guard = (rbc_energy_guard)choice;
    }
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "omega")) &&
        (key_join(k, key, "omega"), read_float(p, item, k, RANGE_NON_NEGATIVE, &d->omega)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "rho")) &&
        (key_join(k, key, "rho"), read_float(p, item, k, RANGE_NON_NEGATIVE, &d->rho)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "chebyshev_delay")) &&
        (key_join(k, key, "chebyshev_delay"), read_u32(p, item, k, 0, 100000, &d->chebyshev_delay)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "tolerance")) &&
        (key_join(k, key, "tolerance"), read_float(p, item, k, RANGE_POSITIVE, &d->tolerance)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "budget_ms")) &&
        (key_join(k, key, "budget_ms"), read_float(p, item, k, RANGE_POSITIVE, &d->budget_ms)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "max_linear_iterations")) &&
        (key_join(k, key, "max_linear_iterations"),
         read_u32(p, item, k, 1, 100000, &d->max_linear_iterations)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "target_strain")) &&
        (key_join(k, key, "target_strain"), read_float(p, item, k, RANGE_POSITIVE, &d->target_strain)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "max_substeps")) &&
        (key_join(k, key, "max_substeps"), read_u32(p, item, k, 1, 1024, &d->max_substeps)))
        return -1;
    return 0;
}

/* "wind": {"velocity": [x, y, z], "drag": d, "lift": l} for rbc_world_set_wind. */
static int parse_wind(parser *p, const cJSON *obj, const char *key, rbc_scene_world *w) {
    static const char *const keys[] = {"velocity", "drag", "lift", NULL};
    const cJSON *velocity, *drag, *lift;
    char k[KEY_MAX];
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys) ||
        member(p, obj, key, "velocity", 1, &velocity) || member(p, obj, key, "drag", 0, &drag) ||
        member(p, obj, key, "lift", 0, &lift))
        return -1;
    w->wind_drag = 0.0f;
    w->wind_lift = 0.0f;
    if ((key_join(k, key, "velocity"), read_vector_f(p, velocity, k, 3, w->wind_velocity)) ||
        (drag && (key_join(k, key, "drag"), read_float(p, drag, k, RANGE_NON_NEGATIVE, &w->wind_drag))) ||
        (lift && (key_join(k, key, "lift"), read_float(p, lift, k, RANGE_NON_NEGATIVE, &w->wind_lift))))
        return -1;
    w->has_wind = 1;
    return 0;
}

static int parse_world(parser *p, const cJSON *obj, rbc_scene_world *w) {
    static const char *const keys[] = {"gravity", "substeps", "substep_rate",
                                       "nonlinear_iterations",
                                       "linear_iterations", "threads", "backend", "solver",
                                       "wind", NULL};
    const char *key = "world";
    const cJSON *item;
    char k[KEY_MAX];
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "gravity")) &&
        (key_join(k, key, "gravity"), read_vector_f(p, item, k, 3, w->gravity)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "substeps")) &&
        (key_join(k, key, "substeps"), read_u32(p, item, k, 0, SCENE_MAX_SUBSTEPS, &w->substeps)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "substep_rate")) &&
        (key_join(k, key, "substep_rate"), read_float(p, item, k, RANGE_POSITIVE, &w->substep_rate)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "nonlinear_iterations")) &&
        (key_join(k, key, "nonlinear_iterations"),
         read_u32(p, item, k, 1, SCENE_MAX_NONLINEAR, &w->nonlinear_iterations)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "linear_iterations")) &&
        (key_join(k, key, "linear_iterations"),
         read_u32(p, item, k, 1, SCENE_MAX_LINEAR, &w->linear_iterations)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "threads")) &&
        (key_join(k, key, "threads"), read_u32(p, item, k, 0, SCENE_MAX_THREADS, &w->thread_count)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "backend"))) {
        int choice;
        key_join(k, key, "backend");
        if (read_choice(p, item, k, backend_names, &choice))
            return -1;
        w->backend = backend_values[choice];
    }
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "solver")) &&
        (key_join(k, key, "solver"), parse_solver(p, item, k, &w->solver)))
        return -1;
    if ((item = cJSON_GetObjectItemCaseSensitive(obj, "wind")) &&
        (key_join(k, key, "wind"), parse_wind(p, item, k, w)))
        return -1;
    return 0;
}

static int parse_grid(parser *p, const cJSON *obj, const char *key, rbc_scene_cloth *c) {
    static const char *const keys[] = {"nx", "ny", "spacing", "origin", "plane", NULL};
    static const char *const planes[] = {"xz", "xy", NULL};
    const cJSON *nx, *ny, *spacing, *origin, *plane;
    char k[KEY_MAX];
    rbc_grid_def *g = &c->grid;
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys) ||
        member(p, obj, key, "nx", 1, &nx) || member(p, obj, key, "ny", 1, &ny) ||
        member(p, obj, key, "spacing", 1, &spacing) || member(p, obj, key, "origin", 0, &origin) ||
        member(p, obj, key, "plane", 0, &plane))
        return -1;
    if ((key_join(k, key, "nx"), read_u32(p, nx, k, 2, SCENE_MAX_GRID_SIDE, &g->nx)) ||
        (key_join(k, key, "ny"), read_u32(p, ny, k, 2, SCENE_MAX_GRID_SIDE, &g->ny)) ||
        (key_join(k, key, "spacing"), read_number(p, spacing, k, RANGE_POSITIVE, &g->spacing)))
        return -1;
    g->origin[0] = g->origin[1] = g->origin[2] = 0.0;
    if (origin && (key_join(k, key, "origin"), read_vector(p, origin, k, 3, g->origin)))
        return -1;
    g->plane = RBC_GRID_PLANE_XZ;
    if (plane) {
        int choice;
        key_join(k, key, "plane");
        if (read_choice(p, plane, k, planes, &choice))
            return -1;
        g->plane = choice == 0 ? RBC_GRID_PLANE_XZ : RBC_GRID_PLANE_XY;
    }
    if ((uint64_t)g->nx * g->ny > RBC_GRID_MAX_VERTICES)
        return fail(p, key, "nx * ny = %llu vertices, more than the limit of %u",
                    (unsigned long long)g->nx * g->ny, RBC_GRID_MAX_VERTICES);
    if (p->grid_vertices + (uint64_t)g->nx * g->ny > SCENE_MAX_GRID_VERTICES)
        return fail(p, key,
                    "nx * ny = %llu vertices; with the %llu of the grids before it the scene "
                    "would have %llu, more than the limit of %u for all its grids together",
                    (unsigned long long)g->nx * g->ny, (unsigned long long)p->grid_vertices,
                    (unsigned long long)(p->grid_vertices + (uint64_t)g->nx * g->ny),
                    SCENE_MAX_GRID_VERTICES);
    p->grid_vertices += (uint64_t)g->nx * g->ny;

    rbc_grid_status status = rbc_grid_build(g, &c->positions, &c->vertex_count, &c->quads,
                                            &c->quad_count);
    if (status == RBC_GRID_OUT_OF_MEMORY)
        return fail(p, key, "out of memory building a %u x %u grid", g->nx, g->ny);
    if (status != RBC_GRID_OK)
        return fail(p, key, "the grid reaches coordinates that do not fit a float");
    c->from_grid = 1;
    return 0;
}

static int parse_inline_mesh(parser *p, const cJSON *vertices, const cJSON *quads,
                             const char *cloth_key, rbc_scene_cloth *c) {
    char key[KEY_MAX];
    key_join(key, cloth_key, "vertices");
    if (read_points(p, vertices, key, 1, RBC_GRID_MAX_VERTICES, &c->positions, &c->vertex_count))
        return -1;
    key_join(key, cloth_key, "quads");
    if (read_faces(p, quads, key, 1, UINT32_MAX / 4, 4, "quad", c->vertex_count, &c->quads,
                   &c->quad_count))
        return -1;
    c->from_grid = 0;
    return 0;
}

static int parse_pins(parser *p, const cJSON *item, const char *key, rbc_scene_cloth *c) {
    uint32_t n;
    if (read_array(p, item, key, 0, c->vertex_count, &n))
        return -1;
    if (n == 0)
        return 0;
    c->pins = malloc((size_t)n * sizeof *c->pins);
    unsigned char *pinned = calloc(c->vertex_count, 1);
    if (!c->pins || !pinned) {
        free(pinned);
        return fail(p, key, "out of memory");
    }
    c->pin_count = n;
    uint32_t i = 0;
    int rc = 0;
    for (const cJSON *e = item->child; e && rc == 0; e = e->next, ++i) {
        char k[KEY_MAX];
        uint32_t v;
        key_index(k, key, i);
        rc = read_vertex(p, e, k, c->vertex_count, &v);
        if (rc == 0 && pinned[v])
            rc = fail(p, k, "vertex %u is pinned twice", v);
        if (rc == 0) {
            pinned[v] = 1;
            c->pins[i] = v;
        }
    }
    free(pinned);
    return rc;
}

/* One drag: {"vertex": i, "keyframes": [{"time": t, "target": [x, y, z]}, ...],
 * "release": t}. */
static int parse_drag(parser *p, const cJSON *obj, const char *key, uint32_t vertex_count,
                      rbc_scene_drag *d) {
    static const char *const keys[] = {"vertex", "keyframes", "release", NULL};
    static const char *const key_keys[] = {"time", "target", NULL};
    const cJSON *vertex, *keyframes, *release;
    char k[KEY_MAX], kk[KEY_MAX], kt[KEY_MAX];
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys) ||
        member(p, obj, key, "vertex", 1, &vertex) ||
        member(p, obj, key, "keyframes", 1, &keyframes) ||
        member(p, obj, key, "release", 0, &release))
        return -1;
    key_join(k, key, "vertex");
    if (read_vertex(p, vertex, k, vertex_count, &d->vertex))
        return -1;
    key_join(k, key, "keyframes");
    uint32_t n = 0;
    if (read_array(p, keyframes, k, 1, SCENE_MAX_KEYS, &n))
        return -1;
    if (!(d->keys = calloc(n, sizeof *d->keys)))
        return fail(p, k, "out of memory");
    d->key_count = n;
    uint32_t i = 0;
    for (const cJSON *e = keyframes->child; e; e = e->next, ++i) {
        const cJSON *target;
        key_index(kk, k, i);
        if (expect_object(p, e, kk) || check_keys(p, e, kk, key_keys) ||
            read_key_time(p, e, kk, i, i ? d->keys[i - 1].time : 0.0, &d->keys[i].time) ||
            member(p, e, kk, "target", 1, &target) ||
            (key_join(kt, kk, "target"), read_vector_f(p, target, kt, 3, d->keys[i].target)))
            return -1;
    }
    d->release = -1.0;
    if (release) {
        key_join(k, key, "release");
        if (read_number(p, release, k, RANGE_NON_NEGATIVE, &d->release))
            return -1;
        if (!(d->release > d->keys[0].time))
            return fail(p, k, "must be after the first keyframe (time %g), got %g",
                        d->keys[0].time, d->release);
    }
    return 0;
}

static int parse_drags(parser *p, const cJSON *item, const char *key, rbc_scene_cloth *c) {
    uint32_t n = 0;
    if (read_array(p, item, key, 0, c->vertex_count, &n))
        return -1;
    if (n == 0)
        return 0;
    if (!(c->drags = calloc(n, sizeof *c->drags)))
        return fail(p, key, "out of memory");
    c->drag_count = n;
    uint32_t i = 0;
    for (const cJSON *e = item->child; e; e = e->next, ++i) {
        char k[KEY_MAX];
        key_index(k, key, i);
        if (parse_drag(p, e, k, c->vertex_count, &c->drags[i]))
            return -1;
        for (uint32_t j = 0; j < i; ++j)
            if (c->drags[j].vertex == c->drags[i].vertex) {
                char kv[KEY_MAX];
                key_join(kv, k, "vertex");
                return fail(p, kv, "vertex %u is already dragged by %s[%u]", c->drags[i].vertex,
                            key, j);
            }
    }
    return 0;
}

static int parse_cloth(parser *p, const cJSON *obj, const char *key, uint32_t index,
                       rbc_scene_cloth *c) {
    static const char *const keys[] = {"name",      "grid",   "vertices", "quads",
                                       "vertex_mass", "stiffness", "damping", "pins",
                                       "shear_stiffness", "bend_stiffness", "thickness",
                                       "friction", "self_collision", "cloth_collision",
                                       "tear_strain", "drags", NULL};
    const cJSON *name, *grid, *vertices, *quads, *mass, *stiffness, *damping, *pins, *shear,
        *bend, *thickness, *friction, *self_collision, *cloth_collision, *tear, *drags;
    char k[KEY_MAX];
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys) ||
        member(p, obj, key, "name", 0, &name) || member(p, obj, key, "grid", 0, &grid) ||
        member(p, obj, key, "vertices", 0, &vertices) || member(p, obj, key, "quads", 0, &quads) ||
        member(p, obj, key, "vertex_mass", 0, &mass) ||
        member(p, obj, key, "stiffness", 0, &stiffness) ||
        member(p, obj, key, "damping", 0, &damping) || member(p, obj, key, "pins", 0, &pins) ||
        member(p, obj, key, "shear_stiffness", 0, &shear) ||
        member(p, obj, key, "bend_stiffness", 0, &bend) ||
        member(p, obj, key, "thickness", 0, &thickness) ||
        member(p, obj, key, "friction", 0, &friction) ||
        member(p, obj, key, "self_collision", 0, &self_collision) ||
        member(p, obj, key, "cloth_collision", 0, &cloth_collision) ||
        member(p, obj, key, "tear_strain", 0, &tear) || member(p, obj, key, "drags", 0, &drags))
        return -1;

    if (name) {
        key_join(k, key, "name");
        if (read_name(p, name, k, &c->name))
            return -1;
    } else {
        char fallback[32];
        snprintf(fallback, sizeof fallback, "cloth%u", index);
        c->name = strdup(fallback);
        if (!c->name)
            return fail(p, key, "out of memory");
    }

    if (grid && (vertices || quads))
        return fail(p, key, "give either \"grid\" or \"vertices\" and \"quads\", not both");
    if (grid) {
        key_join(k, key, "grid");
        if (parse_grid(p, grid, k, c))
            return -1;
    } else if (vertices || quads) {
        if (!vertices || !quads) {
            key_join(k, key, vertices ? "quads" : "vertices");
            return fail(p, k, "required key is missing (\"vertices\" and \"quads\" go together)");
        }
        if (parse_inline_mesh(p, vertices, quads, key, c))
            return -1;
    } else {
        key_join(k, key, "grid");
        return fail(p, k, "required key is missing (give \"grid\", or \"vertices\" and \"quads\")");
    }

    /* Defaults of rbc_cloth_def. */
    c->vertex_mass = 1e-4f;
    c->stiffness = 1000.0f;
    c->damping = 0.0f;
    if ((mass && (key_join(k, key, "vertex_mass"),
                  read_float(p, mass, k, RANGE_POSITIVE, &c->vertex_mass))) ||
        (stiffness && (key_join(k, key, "stiffness"),
                       read_float(p, stiffness, k, RANGE_POSITIVE, &c->stiffness))) ||
        (damping && (key_join(k, key, "damping"),
                     read_float(p, damping, k, RANGE_NON_NEGATIVE, &c->damping))) ||
        (shear && (key_join(k, key, "shear_stiffness"),
                   read_float(p, shear, k, RANGE_NON_NEGATIVE, &c->shear_stiffness))) ||
        (bend && (key_join(k, key, "bend_stiffness"),
                  read_float(p, bend, k, RANGE_NON_NEGATIVE, &c->bend_stiffness))))
        return -1;
    if (pins && (key_join(k, key, "pins"), parse_pins(p, pins, k, c)))
        return -1;

    /* ABI 1.3: contact and tearing; 0 and false are the library's defaults. */
    int self = 0, others = 0;
    if ((thickness && (key_join(k, key, "thickness"),
                       read_float(p, thickness, k, RANGE_NON_NEGATIVE, &c->thickness))) ||
        (friction && (key_join(k, key, "friction"),
                      read_float(p, friction, k, RANGE_NON_NEGATIVE, &c->friction))) ||
        (self_collision && (key_join(k, key, "self_collision"), read_bool(p, self_collision, k, &self))) ||
        (cloth_collision &&
         (key_join(k, key, "cloth_collision"), read_bool(p, cloth_collision, k, &others))) ||
        (tear && (key_join(k, key, "tear_strain"),
                  read_float(p, tear, k, RANGE_NON_NEGATIVE, &c->tear_strain))))
        return -1;
    c->collision_flags = (self ? RBC_CLOTH_COLLIDE_SELF : 0u) | (others ? RBC_CLOTH_COLLIDE_CLOTHS : 0u);
    if (c->collision_flags && !(c->thickness > 0.0f)) {
        key_join(k, key, self ? "self_collision" : "cloth_collision");
        return fail(p, k, "cloth contact needs a \"thickness\" > 0 (the distance the cloth keeps "
                          "from cloth surfaces), got %g",
                    (double)c->thickness);
    }
    if (drags && (key_join(k, key, "drags"), parse_drags(p, drags, k, c)))
        return -1;
    return 0;
}

/* The directory part of `source` joined with `file` (absolute files as they are). */
static char *resolve_path(const char *source, const char *file) {
    const char *slash = strrchr(source, '/');
    size_t dir_len = file[0] == '/' || !slash ? 0 : (size_t)(slash - source) + 1;
    char *path = malloc(dir_len + strlen(file) + 1);
    if (path) {
        memcpy(path, source, dir_len);
        strcpy(path + dir_len, file);
    }
    return path;
}

/* An inline triangle mesh: "vertices" [[x, y, z], ...] and "triangles" [[a, b, c], ...]. */
static int parse_collider_mesh(parser *p, const cJSON *vertices, const cJSON *triangles,
                               const char *collider_key, rbc_scene_collider *c) {
    char key[KEY_MAX];
    key_join(key, collider_key, "vertices");
    if (read_points(p, vertices, key, 3, SCENE_MAX_MESH_VERTICES, &c->mesh_positions,
                    &c->mesh_vertex_count))
        return -1;
    key_join(key, collider_key, "triangles");
    return read_faces(p, triangles, key, 1, SCENE_MAX_MESH_TRIANGLES, 3, "triangle",
                      c->mesh_vertex_count, &c->mesh_triangles, &c->mesh_triangle_count);
}

/* "keyframes": [{"time": t, "position": [x, y, z], "rotation": [x, y, z, w]}, ...];
 * a keyframe without position or rotation takes the collider's. */
static int parse_collider_keys(parser *p, const cJSON *item, const char *key,
                               rbc_scene_collider *c) {
    static const char *const key_keys[] = {"time", "position", "rotation", NULL};
    char kk[KEY_MAX], k[KEY_MAX];
    uint32_t n;
    if (read_array(p, item, key, 1, SCENE_MAX_KEYS, &n))
        return -1;
    if (!(c->keys = calloc(n, sizeof *c->keys)))
        return fail(p, key, "out of memory");
    c->key_count = n;
    uint32_t i = 0;
    for (const cJSON *e = item->child; e; e = e->next, ++i) {
        rbc_scene_collider_key *ck = &c->keys[i];
        const cJSON *position, *rotation;
        key_index(kk, key, i);
        if (expect_object(p, e, kk) || check_keys(p, e, kk, key_keys) ||
            read_key_time(p, e, kk, i, i ? c->keys[i - 1].time : 0.0, &ck->time) ||
            member(p, e, kk, "position", 0, &position) ||
            member(p, e, kk, "rotation", 0, &rotation))
            return -1;
        memcpy(ck->position, c->position, sizeof ck->position);
        memcpy(ck->rotation, c->rotation, sizeof ck->rotation);
        if ((position && (key_join(k, kk, "position"), read_vector_f(p, position, k, 3, ck->position))) ||
            (rotation && (key_join(k, kk, "rotation"), read_quaternion(p, rotation, k, ck->rotation))))
            return -1;
    }
    c->motion = RBC_SCENE_MOTION_KEYFRAMES;
    return 0;
}

static int parse_collider(parser *p, const cJSON *obj, const char *key, rbc_scene_collider *c) {
    static const char *const keys[] = {"shape",     "radius",   "half_extents", "half_length",
                                       "friction",  "thickness", "position",    "rotation",
                                       "vertices",  "triangles", "file",        "scale",
                                       "velocity",  "angular_velocity",         "keyframes",
                                       NULL};
    static const char *const shapes[] = {"sphere", "plane", "capsule", "box", "mesh", NULL};
    static const rbc_shape shape_values[] = {RBC_SHAPE_SPHERE, RBC_SHAPE_PLANE, RBC_SHAPE_CAPSULE,
                                             RBC_SHAPE_BOX, RBC_SHAPE_TRIANGLE_MESH};
    /* The keys of one shape only: which shapes take them. */
    static const struct {
        const char *name;
        unsigned shapes; /* bit i = shapes[i] */
        const char *who;
    } shaped[] = {
        {"radius", 1u | 4u, "spheres and capsules have a radius"},
        {"half_length", 4u, "capsules have a half_length"},
        {"half_extents", 8u, "boxes have half_extents"},
        {"vertices", 16u, "meshes have vertices"},
        {"triangles", 16u, "meshes have triangles"},
        {"file", 16u, "meshes are read from a file"},
        {"scale", 16u, "mesh files have a scale"},
    };
    const cJSON *shape, *radius, *half_extents, *half_length, *friction, *thickness, *position,
        *rotation, *vertices, *triangles, *file, *scale, *velocity, *angular, *keyframes;
    char k[KEY_MAX];
    int choice;
    if (expect_object(p, obj, key) || check_keys(p, obj, key, keys) ||
        member(p, obj, key, "shape", 1, &shape) || member(p, obj, key, "radius", 0, &radius) ||
        member(p, obj, key, "half_extents", 0, &half_extents) ||
        member(p, obj, key, "half_length", 0, &half_length) ||
        member(p, obj, key, "friction", 0, &friction) ||
        member(p, obj, key, "thickness", 0, &thickness) ||
        member(p, obj, key, "position", 0, &position) ||
        member(p, obj, key, "rotation", 0, &rotation) ||
        member(p, obj, key, "vertices", 0, &vertices) ||
        member(p, obj, key, "triangles", 0, &triangles) || member(p, obj, key, "file", 0, &file) ||
        member(p, obj, key, "scale", 0, &scale) || member(p, obj, key, "velocity", 0, &velocity) ||
        member(p, obj, key, "angular_velocity", 0, &angular) ||
        member(p, obj, key, "keyframes", 0, &keyframes))
        return -1;
    key_join(k, key, "shape");
    if (read_choice(p, shape, k, shapes, &choice))
        return -1;
    c->shape = shape_values[choice];
    for (size_t i = 0; i < sizeof shaped / sizeof shaped[0]; ++i) {
        if (!(shaped[i].shapes & (1u << choice)) &&
            cJSON_GetObjectItemCaseSensitive(obj, shaped[i].name)) {
            key_join(k, key, shaped[i].name);
            return fail(p, k, "not for a %s: only %s%s", shapes[choice], shaped[i].who,
                        c->shape == RBC_SHAPE_PLANE ? " (a plane is y = 0 of its frame)" : "");
        }
    }

    c->radius = 0.0f;
    key_join(k, key, "radius");
    if (c->shape == RBC_SHAPE_SPHERE || c->shape == RBC_SHAPE_CAPSULE) {
        if (!radius)
            return fail(p, k, "required key is missing (%ss need a radius)", shapes[choice]);
        if (read_float(p, radius, k, RANGE_POSITIVE, &c->radius))
            return -1;
    }
    if (c->shape == RBC_SHAPE_CAPSULE) {
        key_join(k, key, "half_length");
        if (!half_length)
            return fail(p, k, "required key is missing (the half length of the capsule's axis, "
                              "along its frame's y)");
        if (read_float(p, half_length, k, RANGE_POSITIVE, &c->half_extents[1]))
            return -1;
    }
    if (c->shape == RBC_SHAPE_BOX) {
        key_join(k, key, "half_extents");
        if (!half_extents)
            return fail(p, k, "required key is missing (boxes need half_extents [x, y, z])");
        double h[3];
        if (read_vector(p, half_extents, k, 3, h))
            return -1;
        for (int i = 0; i < 3; ++i) {
            char ki[KEY_MAX];
            key_index(ki, k, (size_t)i);
            if (!((float)h[i] > 0.0f))
                return fail(p, ki, "must be a number > 0, got %g", h[i]);
            c->half_extents[i] = (float)h[i];
        }
    }

    c->thickness = 0.0f;
    c->friction = 0.0f;
    if ((thickness && (key_join(k, key, "thickness"),
                       read_float(p, thickness, k, RANGE_NON_NEGATIVE, &c->thickness))) ||
        (friction && (key_join(k, key, "friction"),
                      read_float(p, friction, k, RANGE_NON_NEGATIVE, &c->friction))))
        return -1;
    c->position[0] = c->position[1] = c->position[2] = 0.0f;
    if (position && (key_join(k, key, "position"), read_vector_f(p, position, k, 3, c->position)))
        return -1;
    c->rotation[0] = c->rotation[1] = c->rotation[2] = 0.0f;
    c->rotation[3] = 1.0f;
    if (rotation && (key_join(k, key, "rotation"), read_quaternion(p, rotation, k, c->rotation)))
        return -1;

    if (c->shape == RBC_SHAPE_TRIANGLE_MESH) {
        if (file && (vertices || triangles)) {
            key_join(k, key, "file");
            return fail(p, k, "give either \"file\" or \"vertices\" and \"triangles\", not both");
        }
        if (file) {
            const char *name = NULL;
            key_join(k, key, "file");
            if (read_string(p, file, k, &name))
                return -1;
            if (!name[0])
                return fail(p, k, "must name a mesh file, got \"\"");
            if (!(c->mesh_file = resolve_path(p->source, name)))
                return fail(p, k, "out of memory");
            FILE *f = fopen(c->mesh_file, "rb");
            if (!f)
                return fail(p, k, "cannot open %s: %s", c->mesh_file, strerror(errno));
            fclose(f);
            c->mesh_scale = 1.0f;
            if (scale && (key_join(k, key, "scale"),
                          read_float(p, scale, k, RANGE_POSITIVE, &c->mesh_scale)))
                return -1;
        } else if (vertices || triangles) {
            if (scale) {
                key_join(k, key, "scale");
                return fail(p, k, "only mesh files have a scale (write inline vertices to size)");
            }
            if (!vertices || !triangles) {
                key_join(k, key, vertices ? "triangles" : "vertices");
                return fail(p, k, "required key is missing (\"vertices\" and \"triangles\" go "
                                  "together)");
            }
            if (parse_collider_mesh(p, vertices, triangles, key, c))
                return -1;
        } else {
            key_join(k, key, "vertices");
            return fail(p, k, "required key is missing (a mesh needs \"vertices\" and "
                              "\"triangles\", or a \"file\")");
        }
    }

    c->motion = RBC_SCENE_MOTION_NONE;
    if (keyframes && (velocity || angular)) {
        key_join(k, key, "keyframes");
        return fail(p, k, "give either \"keyframes\" or \"velocity\"/\"angular_velocity\", not both");
    }
    if (velocity || angular) {
        if ((velocity && (key_join(k, key, "velocity"), read_vector_f(p, velocity, k, 3, c->velocity))) ||
            (angular && (key_join(k, key, "angular_velocity"),
                         read_vector_f(p, angular, k, 3, c->angular_velocity))))
            return -1;
        c->motion = RBC_SCENE_MOTION_VELOCITY;
    }
    if (keyframes && (key_join(k, key, "keyframes"), parse_collider_keys(p, keyframes, k, c)))
        return -1;
    return 0;
}

static int parse_root(parser *p, const cJSON *root, rbc_scene *s) {
    static const char *const keys[] = {"name", "description", "frames", "dt", "world",
                                       "cloths", "colliders", NULL};
    const cJSON *name, *description, *frames, *dt, *world, *cloths, *colliders;
    if (!cJSON_IsObject(root))
        return fail(p, "(top level)", "must be an object, got %s", json_type(root));
    if (check_keys(p, root, "", keys) || member(p, root, "", "name", 1, &name) ||
        member(p, root, "", "description", 0, &description) ||
        member(p, root, "", "frames", 1, &frames) || member(p, root, "", "dt", 1, &dt) ||
        member(p, root, "", "world", 0, &world) || member(p, root, "", "cloths", 1, &cloths) ||
        member(p, root, "", "colliders", 0, &colliders))
        return -1;

    if (!(s->source = strdup(p->source)))
        return fail(p, "(top level)", "out of memory");
    if (read_name(p, name, "name", &s->name))
        return -1;
    if (description) {
        const char *text = NULL;
        if (read_string(p, description, "description", &text))
            return -1;
        if (!(s->description = strdup(text)))
            return fail(p, "description", "out of memory");
    }
    if (read_u32(p, frames, "frames", 1, SCENE_MAX_FRAMES, &s->frames) ||
        read_float(p, dt, "dt", RANGE_POSITIVE, &s->dt))
        return -1;

    /* Defaults of rbc_world_def. */
    s->world.gravity[0] = 0.0f;
    s->world.gravity[1] = -9.81f;
    s->world.gravity[2] = 0.0f;
    s->world.substeps = 0; /* from the substep rate (ABI 1.6) */
    s->world.substep_rate = 480.0f;
    s->world.nonlinear_iterations = 1;
    s->world.linear_iterations = 11;
    s->world.thread_count = 0;
    s->world.backend = RBC_BACKEND_AUTO;
    /* The default solve of a world (ABI 1.6, RBC_PRESET_CLOTH). */
    rbc_scene_solver_preset(&s->world.solver, RBC_PRESET_CLOTH);
    if (world && parse_world(p, world, &s->world))
        return -1;

    uint32_t n = 0;
    if (read_array(p, cloths, "cloths", 1, SCENE_MAX_CLOTHS, &n))
        return -1;
    if (!(s->cloths = calloc(n, sizeof *s->cloths)))
        return fail(p, "cloths", "out of memory");
    s->cloth_count = n;
    uint32_t i = 0;
    for (const cJSON *c = cloths->child; c; c = c->next, ++i) {
        char k[KEY_MAX];
        key_index(k, "cloths", i);
        if (parse_cloth(p, c, k, i, &s->cloths[i]))
            return -1;
        for (uint32_t j = 0; j < i; ++j)
            if (strcmp(s->cloths[j].name, s->cloths[i].name) == 0)
                return fail(p, k, "cloth name \"%s\" is already used by cloths[%u]",
                            s->cloths[i].name, j);
    }

    if (colliders) {
        if (read_array(p, colliders, "colliders", 0, SCENE_MAX_COLLIDERS, &n))
            return -1;
        if (n > 0 && !(s->colliders = calloc(n, sizeof *s->colliders)))
            return fail(p, "colliders", "out of memory");
        s->collider_count = n;
        i = 0;
        for (const cJSON *c = colliders->child; c; c = c->next, ++i) {
            char k[KEY_MAX];
            key_index(k, "colliders", i);
            if (parse_collider(p, c, k, &s->colliders[i]))
                return -1;
        }
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Loading                                                                   */
/* ------------------------------------------------------------------------- */

static int is_json_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

/* "SOURCE:LINE:COLUMN: invalid JSON near '...'" for a syntax error cJSON reports at
 * `at`. cJSON often points at the whitespace after the offending token: step back
 * onto that token, so the position names what is wrong. */
static int syntax_error(parser *p, const char *text, const char *at) {
    if (!at || at < text)
        at = text;
    const char *rest = at;
    while (*rest && is_json_space(*rest))
        ++rest;
    int at_end = *rest == '\0';
    if (at_end)
        at = rest;
    else
        while (at > text && is_json_space(*at))
            --at;
    unsigned line = 1, column = 1;
    for (const char *c = text; c < at; ++c) {
        if (*c == '\n') {
            ++line;
            column = 1;
        } else {
            ++column;
        }
    }
    if (at_end) {
        format(p->err, p->err_size, "%s:%u:%u: invalid JSON: unexpected end of input", p->source,
               line, column);
        return -1;
    }
    char near[24];
    size_t n = 0;
    while (n + 1 < sizeof near && at[n] && at[n] != '\n' && at[n] != '\r')
        ++n;
    memcpy(near, at, n);
    near[n] = '\0';
    format(p->err, p->err_size, "%s:%u:%u: invalid JSON near '%s'", p->source, line, column,
           near);
    return -1;
}

/* Parse a NUL-terminated text. */
static int parse_text(const char *text, const char *source, rbc_scene *out, char *err,
                      size_t err_size) {
    parser p = {source ? source : "(scene)", err, err_size, 0};
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithOpts(text, &end, 1);
    if (!root)
        return syntax_error(&p, text, end);
    rbc_scene scene;
    memset(&scene, 0, sizeof scene);
    int rc = parse_root(&p, root, &scene);
    cJSON_Delete(root);
    if (rc) {
        rbc_scene_free(&scene);
        return -1;
    }
    *out = scene;
    return 0;
}

int rbc_scene_parse(const char *json, size_t length, const char *source, rbc_scene *out,
                    char *err, size_t err_size) {
    parser p = {source ? source : "(scene)", err, err_size, 0};
    if (err_size > 0)
        err[0] = '\0';
    if (!out)
        return fail(&p, "(arguments)", "no scene to fill");
    memset(out, 0, sizeof *out);
    if (!json)
        return fail(&p, "(arguments)", "no JSON text");
    /* cJSON wants a NUL-terminated text to reject trailing garbage; a NUL inside
     * the text would end it early, so refuse one. */
    if (memchr(json, '\0', length))
        return fail(&p, "(file)", "contains a NUL byte; a scene is UTF-8 JSON text");
    char *text = malloc(length + 1);
    if (!text)
        return fail(&p, "(file)", "out of memory");
    memcpy(text, json, length);
    text[length] = '\0';
    int rc = parse_text(text, p.source, out, err, err_size);
    free(text);
    return rc;
}

int rbc_scene_load_file(const char *path, rbc_scene *out, char *err, size_t err_size) {
    if (err_size > 0)
        err[0] = '\0';
    if (out)
        memset(out, 0, sizeof *out);
    if (!path) {
        format(err, err_size, "(scene): no file name given");
        return -1;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        format(err, err_size, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    /* Read in growing chunks: works for pipes and /dev/stdin as for files. */
    size_t size = 0, capacity = 1 << 16;
    char *data = malloc(capacity);
    int failed = data == NULL;
    while (!failed) {
        if (size == capacity) {
            char *bigger = capacity < SCENE_MAX_FILE_BYTES ? realloc(data, capacity * 2) : NULL;
            if (!bigger) {
                failed = 1;
                break;
            }
            data = bigger;
            capacity *= 2;
        }
        size_t got = fread(data + size, 1, capacity - size, f);
        /* A NUL is never in a scene: refuse at the first one rather than read a
         * device such as /dev/zero up to the size limit. */
        const char *nul = memchr(data + size, '\0', got);
        if (nul) {
            size_t at = (size_t)(nul - data);
            fclose(f);
            free(data);
            format(err, err_size,
                   "%s: contains a NUL byte (at offset %zu); a scene is UTF-8 JSON text", path, at);
            return -1;
        }
        size += got;
        if (got == 0)
            break;
    }
    int read_error = ferror(f);
    int saved_errno = errno;
    fclose(f);
    if (failed) {
        free(data);
        format(err, err_size, "%s: out of memory reading the file (or larger than %u bytes)",
               path, SCENE_MAX_FILE_BYTES);
        return -1;
    }
    if (read_error) {
        free(data);
        format(err, err_size, "%s: cannot read: %s", path, strerror(saved_errno));
        return -1;
    }
    int rc = rbc_scene_parse(data, size, path, out, err, err_size);
    free(data);
    return rc;
}

int rbc_scene_load_default(rbc_scene *out, char *err, size_t err_size) {
    return rbc_scene_parse(default_scene_json, sizeof default_scene_json - 1,
                           RBC_SCENE_DEFAULT_SOURCE, out, err, err_size);
}

int rbc_scene_load_paper(rbc_scene *out, char *err, size_t err_size) {
    return rbc_scene_parse(paper_scene_json, sizeof paper_scene_json - 1,
                           "(built-in paper scene)", out, err, err_size);
}

void rbc_scene_free(rbc_scene *scene) {
    if (!scene)
        return;
    for (uint32_t i = 0; scene->cloths && i < scene->cloth_count; ++i) {
        rbc_scene_cloth *c = &scene->cloths[i];
        free(c->name);
        free(c->positions);
        free(c->quads);
        free(c->pins);
        for (uint32_t j = 0; c->drags && j < c->drag_count; ++j)
            free(c->drags[j].keys);
        free(c->drags);
    }
    for (uint32_t i = 0; scene->colliders && i < scene->collider_count; ++i) {
        rbc_scene_collider *c = &scene->colliders[i];
        free(c->mesh_positions);
        free(c->mesh_triangles);
        free(c->mesh_file);
        free(c->keys);
    }
    free(scene->cloths);
    free(scene->colliders);
    free(scene->source);
    free(scene->name);
    free(scene->description);
    memset(scene, 0, sizeof *scene);
}

/* ------------------------------------------------------------------------- */
/* Creation through the function table                                       */
/* ------------------------------------------------------------------------- */

/* err = "<last error> (<context>)", read before anything else can replace it. */
static rbc_result api_fail(const rbc_api_v1 *api, rbc_result result, char *err, size_t err_size,
                           const char *context_fmt, ...) {
    char context[160];
    va_list ap;
    va_start(ap, context_fmt);
    vformat(context, sizeof context, context_fmt, ap);
    va_end(ap);
    const char *message = api->last_error ? api->last_error() : NULL;
    if (!message || !message[0])
        message = api->result_string(result);
    format(err, err_size, "%s (%s)", message, context);
    return result;
}

/* The ABI minor of the library behind `api` (0 for another major). */
static uint32_t api_minor(const rbc_api_v1 *api) {
    return (api->abi_version >> 16) == RBC_ABI_VERSION_MAJOR ? (api->abi_version & 0xFFFFu) : 0u;
}

/* An entry the library's table holds: within its struct_size and not NULL. */
#define API_HAS(api, entry)                                                                  \
    ((api)->struct_size >= offsetof(rbc_api_v1, entry) + sizeof((api)->entry) &&             \
     (api)->entry != NULL)

/* "SOURCE: KEY: the plugin's function table has no ENTRY (ABI 1.3)". */
static rbc_result missing_entry(const rbc_scene *scene, char *err, size_t err_size,
                                const char *key, const char *entry) {
    format(err, err_size,
           "%s: %s: needs rbc_%s (ABI 1.3), which this plugin's function table does not have",
           scene->source ? scene->source : scene->name, key, entry);
    return RBC_ERR_UNSUPPORTED;
}

int rbc_scene_needs_v1_3(const rbc_scene *scene, char *key, size_t key_size) {
    if (scene->world.has_wind) {
        format(key, key_size, "world.wind");
        return 1;
    }
    for (uint32_t i = 0; i < scene->cloth_count; ++i) {
        const rbc_scene_cloth *c = &scene->cloths[i];
        const char *what = c->thickness > 0.0f ? "thickness"
                           : c->friction > 0.0f ? "friction"
                           : (c->collision_flags & RBC_CLOTH_COLLIDE_SELF) ? "self_collision"
                           : c->collision_flags ? "cloth_collision"
                           : c->tear_strain > 0.0f ? "tear_strain"
                                                   : NULL;
        if (what) {
            format(key, key_size, "cloths[%u].%s", i, what);
            return 1;
        }
    }
    for (uint32_t i = 0; i < scene->collider_count; ++i) {
        const rbc_scene_collider *c = &scene->colliders[i];
        int new_shape = c->shape != RBC_SHAPE_SPHERE && c->shape != RBC_SHAPE_PLANE;
        if (new_shape || c->friction > 0.0f) {
            format(key, key_size, "colliders[%u].%s", i, new_shape ? "shape" : "friction");
            return 1;
        }
    }
    if (key_size > 0)
        key[0] = '\0';
    return 0;
}

/* Read a mesh file into a collider def's mesh arrays (malloc'd into *positions and
 * *triangles, which the caller frees). */
static rbc_result import_collider_mesh(const rbc_api_v1 *api, const rbc_scene *scene, uint32_t index,
                                       rbc_collider_def *cd, float **positions,
                                       uint32_t **triangles, char *err, size_t err_size) {
    const rbc_scene_collider *c = &scene->colliders[index];
    const char *source = scene->source ? scene->source : scene->name;
    rbc_mesh_import_def md;
    rbc_mesh_id mesh = 0;
    size_t float_count = 0, index_count = 0;
    rbc_result r = api->mesh_import_def_init(&md, (uint32_t)sizeof md);
    if (r == RBC_OK) {
        md.scale = c->mesh_scale;
        r = api->mesh_import(c->mesh_file, &md, &mesh);
    }
    if (r == RBC_OK)
        r = api->mesh_get_positions(mesh, NULL, 0, &float_count);
    if (r == RBC_OK)
        r = api->mesh_get_triangles(mesh, NULL, 0, &index_count);
    if (r == RBC_OK) {
        *positions = malloc((float_count ? float_count : 1) * sizeof **positions);
        *triangles = malloc((index_count ? index_count : 1) * sizeof **triangles);
        if (!*positions || !*triangles)
            r = RBC_ERR_OUT_OF_MEMORY;
    }
    if (r == RBC_OK)
        r = api->mesh_get_positions(mesh, *positions, float_count, NULL);
    if (r == RBC_OK)
        r = api->mesh_get_triangles(mesh, *triangles, index_count, NULL);
    if (r != RBC_OK) {
        const char *message = r == RBC_ERR_OUT_OF_MEMORY ? "out of memory in the host"
                              : api->last_error && api->last_error()[0] ? api->last_error()
                                                                        : api->result_string(r);
        format(err, err_size, "%s: colliders[%u].file: cannot read %s as a triangle mesh: %s",
               source, index, c->mesh_file, message);
    } else if (float_count / 3 > UINT32_MAX || index_count / 3 > UINT32_MAX) {
        r = RBC_ERR_BAD_MESH;
        format(err, err_size, "%s: colliders[%u].file: %s is too large", source, index, c->mesh_file);
    } else {
        cd->mesh_positions = *positions;
        cd->mesh_vertex_count = (uint32_t)(float_count / 3);
        cd->mesh_triangles = *triangles;
        cd->mesh_triangle_count = (uint32_t)(index_count / 3);
    }
    if (mesh)
        api->mesh_destroy(mesh);
    return r;
}

/* Everything the scene will call exists in the table; the defs' sizes to ask for. */
static rbc_result check_table(const rbc_api_v1 *api, const rbc_scene *scene, uint32_t *cloth_size,
                              uint32_t *collider_size, char *err, size_t err_size) {
    char key[KEY_MAX];
    uint32_t minor = api_minor(api);
    if (rbc_scene_needs_v1_3(scene, key, sizeof key) && minor < 3) {
        format(err, err_size, "%s: %s: needs an ABI 1.3 library; the plugin has ABI %u.%u",
               scene->source ? scene->source : scene->name, key, api->abi_version >> 16, minor);
        return RBC_ERR_UNSUPPORTED;
    }
    /* A 1.3 library reads the 1.3 defs; an older one its own sizes (the scene needs
     * none of the fields beyond them, checked above). */
    *cloth_size = minor >= 3 ? (uint32_t)sizeof(rbc_cloth_def) : RBC_CLOTH_DEF_SIZE_V1_1;
    *collider_size = minor >= 3 ? (uint32_t)sizeof(rbc_collider_def) : RBC_COLLIDER_DEF_SIZE_V1_0;
    if (scene->world.has_wind && !API_HAS(api, world_set_wind))
        return missing_entry(scene, err, err_size, "world.wind", "world_set_wind");
    for (uint32_t i = 0; i < scene->collider_count; ++i) {
        if (!scene->colliders[i].mesh_file)
            continue;
        format(key, sizeof key, "colliders[%u].file", i);
        if (!API_HAS(api, mesh_import_def_init) || !API_HAS(api, mesh_import))
            return missing_entry(scene, err, err_size, key, "mesh_import");
        if (!API_HAS(api, mesh_get_positions) || !API_HAS(api, mesh_destroy))
            return missing_entry(scene, err, err_size, key, "mesh_get_positions");
        if (!API_HAS(api, mesh_get_triangles))
            return missing_entry(scene, err, err_size, key, "mesh_get_triangles");
    }
    return RBC_OK;
}

rbc_result rbc_scene_instantiate(const rbc_api_v1 *api, const rbc_scene *scene,
                                 rbc_log_fn log, void *log_user, rbc_scene_instance *out,
                                 char *err, size_t err_size) {
    if (err_size > 0)
        err[0] = '\0';
    if (out)
        memset(out, 0, sizeof *out);
    if (!api || !scene || !out) {
        format(err, err_size, "rbc_scene_instantiate: api, scene and out must not be NULL");
        return RBC_ERR_INVALID_ARGUMENT;
    }
    uint32_t cloth_def_size, collider_def_size;
    rbc_result r = check_table(api, scene, &cloth_def_size, &collider_def_size, err, err_size);
    if (r != RBC_OK)
        return r;

    rbc_scene_instance inst;
    memset(&inst, 0, sizeof inst);
    inst.cloths = calloc(scene->cloth_count ? scene->cloth_count : 1, sizeof *inst.cloths);
    inst.colliders = calloc(scene->collider_count ? scene->collider_count : 1,
                            sizeof *inst.colliders);
    if (!inst.cloths || !inst.colliders) {
        rbc_scene_instance_destroy(api, &inst);
        format(err, err_size, "out of memory (creating scene \"%s\")", scene->name);
        return RBC_ERR_OUT_OF_MEMORY;
    }

    /* Start from the library's defaults, asked for at this host's struct size: a
     * newer library writes and reads only the fields this host knows. */
    rbc_world_def wd;
    r = api->world_def_init(&wd, (uint32_t)sizeof wd);
    if (r != RBC_OK) {
        api_fail(api, r, err, err_size, "initialising the world def of scene \"%s\"", scene->name);
        rbc_scene_instance_destroy(api, &inst);
        return r;
    }
    memcpy(wd.gravity, scene->world.gravity, sizeof wd.gravity);
    wd.substeps = scene->world.substeps;
    wd.substep_rate = scene->world.substep_rate;
    wd.nonlinear_iterations = scene->world.nonlinear_iterations;
    wd.linear_iterations = scene->world.linear_iterations;
    wd.thread_count = scene->world.thread_count;
    wd.backend = scene->world.backend;
    rbc_solver_def sd = scene->world.solver;
    sd.struct_size = sizeof sd;
    wd.solver = &sd;
    if (log) {
        wd.log = log;
        wd.log_user = log_user;
        wd.log_level = RBC_LOG_WARNING;
    }
    r = api->world_create(&wd, &inst.world);
    if (r != RBC_OK) {
        api_fail(api, r, err, err_size, "creating the world of scene \"%s\"", scene->name);
        rbc_scene_instance_destroy(api, &inst);
        return r;
    }

    for (uint32_t i = 0; i < scene->cloth_count; ++i) {
        const rbc_scene_cloth *c = &scene->cloths[i];
        rbc_cloth_def cd;
        memset(&cd, 0, sizeof cd);
        r = api->cloth_def_init(&cd, cloth_def_size);
        if (r == RBC_OK) {
            cd.vertex_count = c->vertex_count;
            cd.positions = c->positions;
            cd.quad_count = c->quad_count;
            cd.quads = c->quads;
            cd.spring_count = 0;
            cd.springs = NULL;
            cd.masses = NULL;
            cd.density = 0.0f;
            cd.vertex_mass = c->vertex_mass;
            cd.stiffness = c->stiffness;
            cd.damping = c->damping;
            cd.shear_stiffness = c->shear_stiffness;
            cd.bend_stiffness = c->bend_stiffness;
            cd.pin_count = c->pin_count;
            cd.pins = c->pins;
            if (cloth_def_size == sizeof cd) {
                cd.thickness = c->thickness;
                cd.friction = c->friction;
                cd.collision_flags = c->collision_flags;
                cd.tear_strain = c->tear_strain;
            }
            r = api->cloth_create(inst.world, &cd, &inst.cloths[i]);
        }
        if (r != RBC_OK) {
            api_fail(api, r, err, err_size, "creating cloths[%u] \"%s\"", i, c->name);
            rbc_scene_instance_destroy(api, &inst);
            return r;
        }
        inst.cloth_count = i + 1;
    }

    for (uint32_t i = 0; i < scene->collider_count; ++i) {
        const rbc_scene_collider *c = &scene->colliders[i];
        rbc_collider_def cd;
        float *file_positions = NULL;
        uint32_t *file_triangles = NULL;
        int import_failed = 0;
        memset(&cd, 0, sizeof cd);
        r = api->collider_def_init(&cd, collider_def_size);
        if (r == RBC_OK) {
            cd.shape = c->shape;
            if (c->shape == RBC_SHAPE_SPHERE || c->shape == RBC_SHAPE_CAPSULE)
                cd.radius = c->radius;
            cd.thickness = c->thickness;
            rbc_scene_collider_pose(c, 0.0, cd.position, cd.rotation);
            if (collider_def_size == sizeof cd) {
                cd.friction = c->friction;
                if (c->shape == RBC_SHAPE_BOX)
                    memcpy(cd.half_extents, c->half_extents, sizeof cd.half_extents);
                if (c->shape == RBC_SHAPE_CAPSULE)
                    cd.half_extents[1] = c->half_extents[1];
                if (c->shape == RBC_SHAPE_TRIANGLE_MESH && !c->mesh_file) {
                    cd.mesh_positions = c->mesh_positions;
                    cd.mesh_vertex_count = c->mesh_vertex_count;
                    cd.mesh_triangles = c->mesh_triangles;
                    cd.mesh_triangle_count = c->mesh_triangle_count;
                }
                if (c->shape == RBC_SHAPE_TRIANGLE_MESH && c->mesh_file) {
                    r = import_collider_mesh(api, scene, i, &cd, &file_positions,
                                             &file_triangles, err, err_size);
                    import_failed = r != RBC_OK;
                }
            }
            if (r == RBC_OK)
                r = api->collider_create(inst.world, &cd, &inst.colliders[i]);
        }
        free(file_positions);
        free(file_triangles);
        if (r != RBC_OK) {
            if (!import_failed)
                api_fail(api, r, err, err_size, "creating colliders[%u]", i);
            rbc_scene_instance_destroy(api, &inst);
            return r;
        }
        inst.collider_count = i + 1;
    }

    if (scene->world.has_wind) {
        r = api->world_set_wind(inst.world, scene->world.wind_velocity, scene->world.wind_drag,
                                scene->world.wind_lift);
        if (r != RBC_OK) {
            api_fail(api, r, err, err_size, "setting world.wind of scene \"%s\"", scene->name);
            rbc_scene_instance_destroy(api, &inst);
            return r;
        }
    }

    *out = inst;
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* Motion                                                                    */
/* ------------------------------------------------------------------------- */

/* Index i of the segment [keys[i], keys[i+1]) holding t, for keys[0].time <= t <
 * keys[n-1].time (binary search over increasing times). */
#define FIND_SEGMENT(keys, n, t, out)                                                      \
    do {                                                                                   \
        uint32_t lo_ = 0, hi_ = (n) - 1;                                                   \
        while (hi_ - lo_ > 1) {                                                            \
            uint32_t mid_ = lo_ + (hi_ - lo_) / 2;                                         \
            if ((keys)[mid_].time <= (t))                                                  \
                lo_ = mid_;                                                                \
            else                                                                           \
                hi_ = mid_;                                                                \
        }                                                                                  \
        (out) = lo_;                                                                       \
    } while (0)

void rbc_scene_collider_pose(const rbc_scene_collider *c, double t, float position[3],
                             float rotation[4]) {
    if (c->motion == RBC_SCENE_MOTION_VELOCITY) {
        for (int i = 0; i < 3; ++i)
            position[i] = (float)((double)c->position[i] + (double)c->velocity[i] * t);
        const double w[3] = {c->angular_velocity[0], c->angular_velocity[1], c->angular_velocity[2]};
        double rate = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        if (!(rate > 0.0)) {
            memcpy(rotation, c->rotation, 4 * sizeof *rotation);
            return;
        }
        /* q(t) = exp(w t / 2) q0: a turn by |w| t about the world axis w / |w|,
         * after the creation rotation (Hamilton product, x y z w). */
        double half = 0.5 * rate * t, sh = sin(half) / rate;
        const double a[4] = {w[0] * sh, w[1] * sh, w[2] * sh, cos(half)};
        const double b[4] = {c->rotation[0], c->rotation[1], c->rotation[2], c->rotation[3]};
        double q[4] = {a[3] * b[0] + b[3] * a[0] + a[1] * b[2] - a[2] * b[1],
                       a[3] * b[1] + b[3] * a[1] + a[2] * b[0] - a[0] * b[2],
                       a[3] * b[2] + b[3] * a[2] + a[0] * b[1] - a[1] * b[0],
                       a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]};
        double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for (int i = 0; i < 4; ++i)
            rotation[i] = (float)(q[i] / norm);
        return;
    }
    if (c->motion != RBC_SCENE_MOTION_KEYFRAMES || c->key_count == 0) {
        memcpy(position, c->position, 3 * sizeof *position);
        memcpy(rotation, c->rotation, 4 * sizeof *rotation);
        return;
    }
    const rbc_scene_collider_key *k = c->keys;
    const uint32_t n = c->key_count;
    const rbc_scene_collider_key *hold = !(t > k[0].time) ? &k[0] : t >= k[n - 1].time ? &k[n - 1] : NULL;
    if (hold) {
        memcpy(position, hold->position, 3 * sizeof *position);
        memcpy(rotation, hold->rotation, 4 * sizeof *rotation);
        return;
    }
    uint32_t i;
    FIND_SEGMENT(k, n, t, i);
    const rbc_scene_collider_key *ka = &k[i], *kb = &k[i + 1];
    double s = (t - ka->time) / (kb->time - ka->time);
    if (s == 0.0) {
        memcpy(position, ka->position, 3 * sizeof *position);
        memcpy(rotation, ka->rotation, 4 * sizeof *rotation);
        return;
    }
    for (int j = 0; j < 3; ++j)
        position[j] = (float)((double)ka->position[j] +
                              s * ((double)kb->position[j] - (double)ka->position[j]));
    /* Normalised lerp along the shorter arc (q and -q are one rotation). */
    double dot = 0.0;
    for (int j = 0; j < 4; ++j)
        dot += (double)ka->rotation[j] * kb->rotation[j];
    double sign = dot < 0.0 ? -1.0 : 1.0, q[4], norm = 0.0;
    for (int j = 0; j < 4; ++j) {
        q[j] = (1.0 - s) * ka->rotation[j] + s * sign * kb->rotation[j];
        norm += q[j] * q[j];
    }
    norm = sqrt(norm);
    for (int j = 0; j < 4; ++j)
        rotation[j] = (float)(q[j] / norm);
}

rbc_scene_drag_state rbc_scene_drag_target(const rbc_scene_drag *d, double t, float target[3]) {
    if (d->release >= 0.0 && t >= d->release)
        return RBC_SCENE_DRAG_RELEASED;
    if (d->key_count == 0 || t < d->keys[0].time)
        return RBC_SCENE_DRAG_WAITING;
    const rbc_scene_drag_key *k = d->keys;
    const uint32_t n = d->key_count;
    if (t >= k[n - 1].time) {
        memcpy(target, k[n - 1].target, 3 * sizeof *target);
        return RBC_SCENE_DRAG_PINNED;
    }
    uint32_t i;
    FIND_SEGMENT(k, n, t, i);
    double s = (t - k[i].time) / (k[i + 1].time - k[i].time);
    for (int j = 0; j < 3; ++j)
        target[j] = (float)((double)k[i].target[j] +
                            s * ((double)k[i + 1].target[j] - (double)k[i].target[j]));
    return RBC_SCENE_DRAG_PINNED;
}

rbc_result rbc_scene_apply_frame(const rbc_api_v1 *api, const rbc_scene *scene,
                                 const rbc_scene_instance *inst, uint32_t frame, char *err,
                                 size_t err_size) {
    /* Time at the end of the frame, in double (frame counts reach 10^7). */
    const double t = (double)scene->dt * ((double)frame + 1.0);
    const double t_before = (double)scene->dt * (double)frame;
    for (uint32_t i = 0; i < scene->collider_count && i < inst->collider_count; ++i) {
        const rbc_scene_collider *c = &scene->colliders[i];
        if (c->motion == RBC_SCENE_MOTION_NONE)
            continue;
        float position[3], rotation[4];
        rbc_scene_collider_pose(c, t, position, rotation);
        rbc_result r = api->collider_set_transform(inst->world, inst->colliders[i], position, rotation);
        if (r != RBC_OK)
            return api_fail(api, r, err, err_size, "moving colliders[%u] at t = %g s", i, t);
    }
    for (uint32_t i = 0; i < scene->cloth_count && i < inst->cloth_count; ++i) {
        const rbc_scene_cloth *c = &scene->cloths[i];
        for (uint32_t j = 0; j < c->drag_count; ++j) {
            const rbc_scene_drag *d = &c->drags[j];
            float target[3], unused[3];
            rbc_scene_drag_state state = rbc_scene_drag_target(d, t, target);
            rbc_result r = RBC_OK;
            if (state == RBC_SCENE_DRAG_PINNED)
                r = api->cloth_set_pin(inst->world, inst->cloths[i], d->vertex, target);
            else if (state == RBC_SCENE_DRAG_RELEASED &&
                     rbc_scene_drag_target(d, t_before, unused) != RBC_SCENE_DRAG_RELEASED)
                r = api->cloth_set_pin(inst->world, inst->cloths[i], d->vertex, NULL);
            if (r != RBC_OK)
                return api_fail(api, r, err, err_size, "cloths[%u].drags[%u] at t = %g s", i, j, t);
        }
    }
    return RBC_OK;
}

void rbc_scene_instance_destroy(const rbc_api_v1 *api, rbc_scene_instance *instance) {
    if (!instance)
        return;
    /* Destroying the world destroys its cloths and colliders. */
    if (api && instance->world)
        api->world_destroy(instance->world);
    free(instance->cloths);
    free(instance->colliders);
    memset(instance, 0, sizeof *instance);
}
