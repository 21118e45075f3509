/* main.c -- rbcloth-viewer: a real-time OpenGL viewer of any scene `rbcloth run`
 * reads. Each frame steps the world by the scene's dt and draws every cloth with the
 * library's normals, coloured by strain; the mouse picks and drags vertices or cuts
 * springs, keys shoot balls and change the solve. See README.md beside this file.
 *
 * It is a host like the CLI: the plugin is loaded with dlopen (hosts/cli/plugin.c)
 * and scenes are read and built by the CLI's own code (samples/scene.c, rbc_scene),
 * so a scene behaves here as in `rbcloth run`. GL 2.1 with the fixed-function
 * pipeline and buffer objects: what Mesa's llvmpipe under Xvfb runs everywhere.
 */
#define GL_GLEXT_PROTOTYPES 1
#define GLFW_INCLUDE_GLEXT
#include <GLFW/glfw3.h>

#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "plugin.h"
#include "rbcloth.h"
#include "scene.h"
#include "script.h"
#include "viewer.h"

#define PI_F 3.14159265358979f
/* The still's camera (hosts/cli/viewer.h), so the first view matches `rbcloth run`'s
 * PNG: azimuth 35 deg, elevation 25 deg, vertical field of view 30 deg. */
#define DEFAULT_AZIMUTH 35.0f
#define DEFAULT_ELEVATION 25.0f
#define FOV_Y_DEG 30.0f
/* Balls: at most this many at once (the oldest goes first); each lives BALL_LIFE s. */
#define MAX_BALLS 8
#define BALL_LIFE 3.0

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* ------------------------------------------------------------------------- */
/* Small vector helpers                                                      */
/* ------------------------------------------------------------------------- */

static void v3_sub(const float a[3], const float b[3], float o[3]) {
    for (int k = 0; k < 3; ++k) o[k] = a[k] - b[k];
}
static float v3_dot(const float a[3], const float b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void v3_cross(const float a[3], const float b[3], float o[3]) {
    float r[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    memcpy(o, r, sizeof r);
}
static void v3_normalize(float a[3]) {
    float n = sqrtf(v3_dot(a, a));
    if (n > 0) for (int k = 0; k < 3; ++k) a[k] /= n;
}

/* ------------------------------------------------------------------------- */
/* State                                                                     */
/* ------------------------------------------------------------------------- */

/* What the viewer keeps of one cloth to draw it. */
typedef struct view_cloth {
    uint32_t vertex_count;
    /// Rest positions (the scene's; the cloth is created at them): strain reference.
    const float *rest;
    /// Interleaved position and normal, 6 floats (24 bytes) per vertex, as
    /// rbc_world_read_vertices writes them.
    float *vertices;
    /// Strain colour, 3 floats per vertex; and the strain itself.
    float *colours;
    float *strain;
    /// Triangles (3 indices each) and the revision they were read at.
    uint32_t *triangles;
    size_t triangle_values;
    uint32_t revision;
    /// Springs that remain (2 indices each) and their rest lengths.
    uint32_t *springs;
    size_t spring_values;
    float *spring_rest;
    /// Pixel coordinates of each vertex (x, y, and 1 if in front of the camera).
    float *screen;
    GLuint vertex_buffer, colour_buffer, index_buffer;
    int index_dirty;
} view_cloth;

typedef struct ball {
    rbc_collider_id id;
    float origin[3], velocity[3], radius;
    double born; /* simulated seconds */
} ball;

typedef struct app {
    const rbc_api_v1 *api;
    uint32_t abi_version;
    rbc_scene scene;
    rbc_scene_instance inst;
    view_cloth *cloths;
    ball balls[MAX_BALLS];
    uint32_t ball_count;
    uint32_t sim_frame; /* frames stepped since load or reset */
    int paused;
    int preset; /* last preset chosen with P, -1 = the scene's solve */

    /* Window and camera. */
    GLFWwindow *window;
    int width, height;   /* window (event) coordinates */
    int fb_width, fb_height;
    float centre[3], radius, distance, azimuth, elevation;
    float eye[3], forward[3], right[3], up[3];
    float view[16], proj[16];

    /* Mouse. */
    double mouse_x, mouse_y;
    int button; /* -1 none, 0 dragging a vertex, 1 cutting */
    int glfw_button; /* the GLFW button that is down (interactive mode) */
    int cut_mode;
    double stroke_x, stroke_y; /* last point of the cut stroke */
    int drag_cloth;             /* index into cloths, -1 none */
    uint32_t drag_vertex;
    int drag_was_pinned;
    float drag_point[3]; /* plane point: the picked vertex when picked */
    int last_pick_cloth;
    uint32_t last_pick_vertex;
    uint64_t springs_cut;

    /* Timings, smoothed. */
    double step_ms, frame_ms, max_strain;
    int scripted;
} app;

static void RBC_CALL log_to_stderr(void *user, rbc_log_level level, const char *message) {
    static const char *const names[] = {"error", "warning", "info", "debug"};
    if (level == RBC_LOG_ERROR) return; /* returned as a result and reported by the caller */
    const char *name = level >= 0 && level <= RBC_LOG_DEBUG ? names[level] : "log";
    fprintf(stderr, "rbcloth-viewer: plugin %s: %s\n", name, message ? message : "");
}

static void report_api(const app *a, rbc_result r, const char *what) {
    fprintf(stderr, "rbcloth-viewer: %s: %s (%s)\n", what, a->api->last_error(),
            a->api->result_string(r));
}

/* ------------------------------------------------------------------------- */
/* Reading the cloths                                                        */
/* ------------------------------------------------------------------------- */

static void view_cloth_free(view_cloth *c) {
    free(c->vertices);
    free(c->colours);
    free(c->strain);
    free(c->triangles);
    free(c->springs);
    free(c->spring_rest);
    free(c->screen);
    if (c->vertex_buffer) glDeleteBuffers(1, &c->vertex_buffer);
    if (c->colour_buffer) glDeleteBuffers(1, &c->colour_buffer);
    if (c->index_buffer) glDeleteBuffers(1, &c->index_buffer);
    memset(c, 0, sizeof *c);
}

/* Read a uint32 array with the count-then-fill convention of rbc_cloth_get_quads. */
typedef rbc_result(RBC_CALL *get_u32_fn)(rbc_world_id, rbc_cloth_id, uint32_t *, size_t, size_t *);
static int read_u32(const app *a, get_u32_fn fn, rbc_cloth_id id, uint32_t **out, size_t *count,
                    const char *what) {
    size_t n = 0;
    rbc_result r = fn(a->inst.world, id, NULL, 0, &n);
    if (r != RBC_OK) {
        report_api(a, r, what);
        return -1;
    }
    uint32_t *p = realloc(*out, (n ? n : 1) * sizeof *p);
    if (!p) {
        fprintf(stderr, "rbcloth-viewer: out of memory (%s)\n", what);
        return -1;
    }
    *out = p;
    if (n && (r = fn(a->inst.world, id, p, n, &n)) != RBC_OK) {
        report_api(a, r, what);
        return -1;
    }
    *count = n;
    return 0;
}

/* The springs that remain and their rest lengths from the rest positions. */
static int read_springs(app *a, uint32_t i) {
    view_cloth *c = &a->cloths[i];
    if (read_u32(a, a->api->cloth_get_springs, a->inst.cloths[i], &c->springs, &c->spring_values,
                 "rbc_cloth_get_springs"))
        return -1;
    size_t n = c->spring_values / 2;
    float *rest = realloc(c->spring_rest, (n ? n : 1) * sizeof *rest);
    if (!rest) return -1;
    c->spring_rest = rest;
    for (size_t s = 0; s < n; ++s) {
        float d[3];
        v3_sub(c->rest + 3 * c->springs[2 * s], c->rest + 3 * c->springs[2 * s + 1], d);
        rest[s] = sqrtf(v3_dot(d, d));
    }
    return 0;
}

/* Triangles from ABI 1.10's rbc_cloth_get_triangles, with its revision. */
static int read_triangles(app *a, uint32_t i) {
    view_cloth *c = &a->cloths[i];
    rbc_cloth_id id = a->inst.cloths[i];
    size_t n = 0;
    uint32_t revision = 0;
    rbc_result r = a->api->cloth_get_triangles(a->inst.world, id, NULL, 0, &n, &revision);
    uint32_t *p = r == RBC_OK ? realloc(c->triangles, (n ? n : 1) * sizeof *p) : NULL;
    if (p) {
        c->triangles = p;
        if (n) r = a->api->cloth_get_triangles(a->inst.world, id, p, n, &n, &revision);
    }
    if (r != RBC_OK || !p) {
        if (r != RBC_OK) report_api(a, r, "rbc_cloth_get_triangles");
        else fprintf(stderr, "rbcloth-viewer: out of memory (triangles)\n");
        return -1;
    }
    c->triangle_values = n;
    c->revision = revision;
    c->index_dirty = 1;
    return 0;
}

/* Per vertex the largest |len / rest - 1| of its springs, as a colour (the CLI
 * still's ramp, cli_view_strain_colour). Springs of rest length 0 are skipped. */
static void compute_strain(view_cloth *c) {
    for (uint32_t k = 0; k < c->vertex_count; ++k) c->strain[k] = 0;
    for (size_t s = 0; s < c->spring_values / 2; ++s) {
        if (!(c->spring_rest[s] > 0)) continue;
        uint32_t i = c->springs[2 * s], j = c->springs[2 * s + 1];
        float d[3];
        v3_sub(c->vertices + 6 * i, c->vertices + 6 * j, d);
        float e = fabsf(sqrtf(v3_dot(d, d)) / c->spring_rest[s] - 1.0f);
        if (e > c->strain[i]) c->strain[i] = e;
        if (e > c->strain[j]) c->strain[j] = e;
    }
    for (uint32_t k = 0; k < c->vertex_count; ++k) cli_view_strain_colour(c->strain[k], c->colours + 3 * k);
}

/* This frame's vertices of every cloth (position and normal, ABI 1.10's
 * rbc_world_read_vertices, all cloths in one call per 64), and its triangles and
 * springs when a tear or a cut changed them (the triangle revision moved). */
static int read_cloths(app *a) {
    const rbc_scene *sc = &a->scene;
    rbc_vertex_output out[64];
    for (uint32_t base = 0; base < sc->cloth_count; base += 64) {
        uint32_t n = sc->cloth_count - base < 64 ? sc->cloth_count - base : 64;
        for (uint32_t k = 0; k < n; ++k) {
            view_cloth *c = &a->cloths[base + k];
            a->api->vertex_output_init(&out[k], (uint32_t)sizeof out[k]);
            out[k].cloth = a->inst.cloths[base + k];
            out[k].buffer = c->vertices;
            out[k].buffer_size = (size_t)c->vertex_count * 24;
            out[k].stride = 24;
            out[k].position_offset = 0;
            out[k].normal_offset = 12;
        }
        rbc_result r = a->api->world_read_vertices(a->inst.world, out, n);
        if (r != RBC_OK) {
            report_api(a, r, "rbc_world_read_vertices");
            return -1;
        }
        for (uint32_t k = 0; k < n; ++k) {
            view_cloth *c = &a->cloths[base + k];
            if (out[k].triangle_revision != c->revision &&
                (read_triangles(a, base + k) || read_springs(a, base + k)))
                return -1;
            /* A tear can break a spring whose faces are already gone, which leaves
             * the revision as it was: the spring count tells. */
            size_t springs = 0;
            if (a->api->cloth_get_springs(a->inst.world, out[k].cloth, NULL, 0, &springs) == RBC_OK &&
                springs != c->spring_values && read_springs(a, base + k))
                return -1;
        }
    }
    for (uint32_t i = 0; i < sc->cloth_count; ++i) compute_strain(&a->cloths[i]);
    return 0;
}

/* ------------------------------------------------------------------------- */
/* World: load, reset, solver                                                */
/* ------------------------------------------------------------------------- */

static void destroy_world(app *a) {
    for (uint32_t i = 0; a->cloths && i < a->scene.cloth_count; ++i) view_cloth_free(&a->cloths[i]);
    free(a->cloths);
    a->cloths = NULL;
    rbc_scene_instance_destroy(a->api, &a->inst); /* its colliders, the balls among them */
    a->ball_count = 0;
    a->drag_cloth = -1;
}

static int create_world(app *a) {
    char err[RBC_SCENE_ERROR_MAX];
    rbc_result r = rbc_scene_instantiate(a->api, &a->scene, log_to_stderr, NULL, &a->inst, err,
                                         sizeof err);
    if (r != RBC_OK) {
        fprintf(stderr, "rbcloth-viewer: %s\n", err);
        return -1;
    }
    a->cloths = calloc(a->scene.cloth_count ? a->scene.cloth_count : 1, sizeof *a->cloths);
    if (!a->cloths) return -1;
    for (uint32_t i = 0; i < a->scene.cloth_count; ++i) {
        view_cloth *c = &a->cloths[i];
        const rbc_scene_cloth *sc = &a->scene.cloths[i];
        c->vertex_count = sc->vertex_count;
        c->rest = sc->positions;
        size_t n = sc->vertex_count ? sc->vertex_count : 1;
        c->vertices = calloc(6 * n, sizeof(float));
        c->colours = calloc(3 * n, sizeof(float));
        c->strain = calloc(n, sizeof(float));
        c->screen = calloc(3 * n, sizeof(float));
        if (!c->vertices || !c->colours || !c->strain || !c->screen) {
            fprintf(stderr, "rbcloth-viewer: out of memory (cloth %s)\n", sc->name);
            return -1;
        }
        c->revision = 0; /* 1.10 revisions start at 1: the first read fetches */
        if (read_springs(a, i)) return -1;
        glGenBuffers(1, &c->vertex_buffer);
        glGenBuffers(1, &c->colour_buffer);
        glGenBuffers(1, &c->index_buffer);
    }
    a->sim_frame = 0;
    a->drag_cloth = -1;
    a->last_pick_cloth = -1;
    a->springs_cut = 0;
    return read_cloths(a);
}

static const char *solver_name(const app *a) {
    rbc_solver_def d;
    a->api->solver_def_init(&d, sizeof d);
    if (a->api->world_get_solver(a->inst.world, &d) != RBC_OK) return "?";
    return d.solver >= 0 && d.solver <= RBC_SOLVER_DIRECT ? rbc_scene_solver_names[d.solver] : "?";
}

/* Apply a solver def to the world, and keep it in the scene so that R (reset)
 * builds the world with it. */
static void set_solver(app *a, const rbc_solver_def *d) {
    rbc_result r = a->api->world_set_solver(a->inst.world, d);
    if (r != RBC_OK) {
        report_api(a, r, "rbc_world_set_solver");
        return;
    }
    a->scene.world.solver = *d;
}

static void next_solver(app *a) {
    rbc_solver_def d;
    a->api->solver_def_init(&d, sizeof d);
    a->api->world_get_solver(a->inst.world, &d);
    d.solver = (d.solver + 1) % (RBC_SOLVER_DIRECT + 1);
    set_solver(a, &d);
}

static void next_preset(app *a) {
    a->preset = (a->preset + 1) % 3;
    rbc_solver_def d;
    rbc_result r = a->api->solver_def_preset(&d, sizeof d, (rbc_preset)a->preset);
    if (r != RBC_OK) {
        report_api(a, r, "rbc_solver_def_preset");
        return;
    }
    set_solver(a, &d);
}

static void change_iterations(app *a, int delta) {
    rbc_scene_world *w = &a->scene.world;
    long linear = (long)w->linear_iterations + delta;
    if (linear < 1 || linear > 4096) return;
    rbc_result r = a->api->world_set_iterations(a->inst.world, w->substeps, w->nonlinear_iterations,
                                                (uint32_t)linear);
    if (r != RBC_OK) {
        report_api(a, r, "rbc_world_set_iterations");
        return;
    }
    w->linear_iterations = (uint32_t)linear;
}

/* ------------------------------------------------------------------------- */
/* Camera                                                                    */
/* ------------------------------------------------------------------------- */

/* Fit the camera to the rest box of the cloths, as the CLI's still does:
 * distance 1.1 r / sin(min(fov_y, fov_x) / 2), r the box's half diagonal. */
static void fit_camera(app *a) {
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    for (uint32_t i = 0; i < a->scene.cloth_count; ++i)
        for (uint32_t k = 0; k < a->scene.cloths[i].vertex_count; ++k)
            for (int j = 0; j < 3; ++j) {
                float x = a->scene.cloths[i].positions[3 * k + j];
                if (x < lo[j]) lo[j] = x;
                if (x > hi[j]) hi[j] = x;
            }
    if (lo[0] > hi[0]) for (int j = 0; j < 3; ++j) lo[j] = -1, hi[j] = 1;
    float d[3];
    v3_sub(hi, lo, d);
    /* Room for the cloth to fall: a pinned cloth hangs at most about its own size
     * below its rest box, along gravity (the default scene starts horizontal). */
    float size = d[0] > d[1] ? (d[0] > d[2] ? d[0] : d[2]) : (d[1] > d[2] ? d[1] : d[2]);
    float g[3] = {a->scene.world.gravity[0], a->scene.world.gravity[1], a->scene.world.gravity[2]};
    v3_normalize(g);
    for (int j = 0; j < 3; ++j) {
        if (g[j] < 0) lo[j] += size * g[j];
        else hi[j] += size * g[j];
    }
    v3_sub(hi, lo, d);
    for (int j = 0; j < 3; ++j) a->centre[j] = 0.5f * (lo[j] + hi[j]);
    a->radius = 0.5f * sqrtf(v3_dot(d, d));
    if (!(a->radius > 1e-6f)) a->radius = 1.0f;
    float half_y = 0.5f * FOV_Y_DEG * PI_F / 180.0f;
    float aspect = (float)a->width / (float)a->height;
    float half_x = atanf(tanf(half_y) * aspect);
    a->distance = 1.1f * a->radius / sinf(half_y < half_x ? half_y : half_x);
}

static void update_camera(app *a) {
    float az = a->azimuth * PI_F / 180.0f, el = a->elevation * PI_F / 180.0f;
    float dir[3] = {cosf(el) * sinf(az), sinf(el), cosf(el) * cosf(az)};
    for (int k = 0; k < 3; ++k) a->eye[k] = a->centre[k] + a->distance * dir[k];
    for (int k = 0; k < 3; ++k) a->forward[k] = -dir[k];
    float world_up[3] = {0, 1, 0};
    v3_cross(a->forward, world_up, a->right);
    if (v3_dot(a->right, a->right) < 1e-12f) a->right[0] = 1, a->right[1] = a->right[2] = 0;
    v3_normalize(a->right);
    v3_cross(a->right, a->forward, a->up);
    /* Column-major view and projection matrices for glLoadMatrixf. */
    const float *r = a->right, *u = a->up, *f = a->forward, *e = a->eye;
    float v[16] = {r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
                   -v3_dot(r, e), -v3_dot(u, e), v3_dot(f, e), 1};
    memcpy(a->view, v, sizeof v);
    float n = a->distance * 0.01f, far_ = a->distance + 20.0f * a->radius;
    float t = 1.0f / tanf(0.5f * FOV_Y_DEG * PI_F / 180.0f), asp = (float)a->width / a->height;
    float p[16] = {t / asp, 0, 0, 0, 0, t, 0, 0, 0, 0, (far_ + n) / (n - far_), -1,
                   0, 0, 2 * far_ * n / (n - far_), 0};
    memcpy(a->proj, p, sizeof p);
}

/* The ray through window pixel (x, y): origin the eye, dir not normalised. */
static void pixel_ray(const app *a, double x, double y, float dir[3]) {
    float th = tanf(0.5f * FOV_Y_DEG * PI_F / 180.0f), asp = (float)a->width / a->height;
    float nx = (float)(2.0 * (x + 0.5) / a->width - 1.0), ny = (float)(1.0 - 2.0 * (y + 0.5) / a->height);
    for (int k = 0; k < 3; ++k)
        dir[k] = a->forward[k] + a->right[k] * nx * th * asp + a->up[k] * ny * th;
}

/* Window pixel of a world point; 0 if it is behind the eye. */
static int project(const app *a, const float p[3], float *x, float *y) {
    float d[3];
    v3_sub(p, a->eye, d);
    float z = v3_dot(d, a->forward);
    if (z <= a->distance * 0.01f) return 0;
    float th = tanf(0.5f * FOV_Y_DEG * PI_F / 180.0f), asp = (float)a->width / a->height;
    float nx = v3_dot(d, a->right) / (z * th * asp), ny = v3_dot(d, a->up) / (z * th);
    *x = (nx + 1.0f) * 0.5f * a->width - 0.5f;
    *y = (1.0f - ny) * 0.5f * a->height - 0.5f;
    return 1;
}

/* ------------------------------------------------------------------------- */
/* Interaction                                                               */
/* ------------------------------------------------------------------------- */

/* Where the mouse ray meets the plane through the picked vertex facing the camera. */
static void drag_target(const app *a, float target[3]) {
    float dir[3], d[3];
    pixel_ray(a, a->mouse_x, a->mouse_y, dir);
    v3_sub(a->drag_point, a->eye, d);
    float t = v3_dot(d, a->forward) / v3_dot(dir, a->forward);
    for (int k = 0; k < 3; ++k) target[k] = a->eye[k] + t * dir[k];
}

static int cloth_index(const app *a, rbc_cloth_id id) {
    for (uint32_t i = 0; i < a->scene.cloth_count; ++i)
        if (a->inst.cloths[i] == id) return (int)i;
    return -1;
}

static void pick(app *a) {
    float dir[3];
    pixel_ray(a, a->mouse_x, a->mouse_y, dir);
    /* Pixel size at the scene's distance, in metres. */
    float pixel = 2.0f * a->distance * tanf(0.5f * FOV_Y_DEG * PI_F / 180.0f) / a->height;
    float len = sqrtf(v3_dot(dir, dir));
    rbc_cloth_id cloth = 0;
    uint32_t vertex = 0;
    float t = 0;
    /* The library takes the hit nearest the eye among the vertices within the radius:
     * first a tight 3-pixel radius, so the vertex under the cursor wins on a cloth
     * facing the camera, then 12 pixels, so a near miss still grabs. */
    rbc_result r = RBC_OK;
    for (int pass = 0; pass < 2 && r == RBC_OK && !cloth; ++pass)
        r = a->api->world_pick(a->inst.world, a->eye, dir, (a->distance + 4.0f * a->radius) / len,
                               (pass ? 12.0f : 3.0f) * pixel, &cloth, &vertex, &t);
    if (r != RBC_OK) {
        report_api(a, r, "rbc_world_pick");
        return;
    }
    int i = cloth ? cloth_index(a, cloth) : -1;
    a->last_pick_cloth = i;
    a->last_pick_vertex = vertex;
    if (a->scripted) {
        if (i < 0) printf("pick frame=%u none\n", a->sim_frame);
        else printf("pick frame=%u cloth=%d vertex=%u\n", a->sim_frame, i, vertex);
    }
    if (i < 0) return;
    a->drag_cloth = i;
    a->drag_vertex = vertex;
    memcpy(a->drag_point, a->cloths[i].vertices + 6 * vertex, sizeof a->drag_point);
    a->drag_was_pinned = 0;
    const rbc_scene_cloth *sc = &a->scene.cloths[i];
    for (uint32_t k = 0; k < sc->pin_count; ++k)
        if (sc->pins[k] == vertex) a->drag_was_pinned = 1;
}

/* Let go: a vertex the scene pins stays pinned where it was dropped; any other is
 * released (rbc_cloth_set_pin with NULL). */
static void release(app *a) {
    if (a->drag_cloth < 0) return;
    float target[3];
    drag_target(a, target);
    rbc_result r = a->api->cloth_set_pin(a->inst.world, a->inst.cloths[a->drag_cloth],
                                         a->drag_vertex, a->drag_was_pinned ? target : NULL);
    if (r != RBC_OK) report_api(a, r, "rbc_cloth_set_pin");
    a->drag_cloth = -1;
}

static double orient(double ax, double ay, double bx, double by, double cx, double cy) {
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
}

/* Cut every spring whose screen segment the stroke segment (x0 y0)-(x1 y1) crosses
 * (both ends in front of the camera; springs hidden behind others are cut too). */
static void cut_stroke(app *a, double x0, double y0, double x1, double y1) {
    if (x0 == x1 && y0 == y1) return;
    for (uint32_t i = 0; i < a->scene.cloth_count; ++i) {
        view_cloth *c = &a->cloths[i];
        for (uint32_t k = 0; k < c->vertex_count; ++k)
            c->screen[3 * k + 2] =
                (float)project(a, c->vertices + 6 * k, &c->screen[3 * k], &c->screen[3 * k + 1]);
        size_t n = c->spring_values / 2, found = 0;
        uint32_t *pairs = malloc((n ? n : 1) * 2 * sizeof *pairs);
        if (!pairs) {
            fprintf(stderr, "rbcloth-viewer: out of memory (cut)\n");
            return;
        }
        for (size_t s = 0; s < n; ++s) {
            const float *p = c->screen + 3 * c->springs[2 * s], *q = c->screen + 3 * c->springs[2 * s + 1];
            if (!p[2] || !q[2]) continue;
            double d1 = orient(x0, y0, x1, y1, p[0], p[1]), d2 = orient(x0, y0, x1, y1, q[0], q[1]);
            double d3 = orient(p[0], p[1], q[0], q[1], x0, y0), d4 = orient(p[0], p[1], q[0], q[1], x1, y1);
            if (((d1 < 0 && d2 > 0) || (d1 > 0 && d2 < 0)) && ((d3 < 0 && d4 > 0) || (d3 > 0 && d4 < 0))) {
                pairs[2 * found] = c->springs[2 * s];
                pairs[2 * found + 1] = c->springs[2 * s + 1];
                ++found;
            }
        }
        uint32_t cut = 0;
        if (found) {
            rbc_result r = a->api->cloth_cut(a->inst.world, a->inst.cloths[i], pairs,
                                             (uint32_t)found, &cut);
            if (r != RBC_OK) report_api(a, r, "rbc_cloth_cut");
            else if (cut && read_springs(a, i)) fprintf(stderr, "rbcloth-viewer: springs not re-read\n");
        }
        free(pairs);
        a->springs_cut += cut;
        if (a->scripted && cut) printf("cut frame=%u cloth=%u springs=%u\n", a->sim_frame, i, cut);
    }
}

static void mouse_down(app *a, int button) {
    if (a->button >= 0) return;
    a->button = button;
    if (button == 1 || a->cut_mode) {
        a->button = 1;
        a->stroke_x = a->mouse_x, a->stroke_y = a->mouse_y;
    } else {
        pick(a);
    }
}

static void mouse_move(app *a, double x, double y) {
    a->mouse_x = x, a->mouse_y = y;
    if (a->button == 1) {
        cut_stroke(a, a->stroke_x, a->stroke_y, x, y);
        a->stroke_x = x, a->stroke_y = y;
    }
}

static void mouse_up(app *a) {
    if (a->button == 0) release(a);
    a->button = -1;
}

/* B: a sphere from the eye along the mouse ray, crossing the view in about 0.4 s. */
static void shoot_ball(app *a) {
    if (a->ball_count == MAX_BALLS) {
        a->api->collider_destroy(a->inst.world, a->balls[0].id);
        memmove(a->balls, a->balls + 1, (MAX_BALLS - 1) * sizeof *a->balls);
        --a->ball_count;
    }
    ball *b = &a->balls[a->ball_count];
    float dir[3];
    pixel_ray(a, a->mouse_x, a->mouse_y, dir);
    v3_normalize(dir);
    b->radius = 0.12f * a->radius;
    float speed = 2.5f * a->distance;
    for (int k = 0; k < 3; ++k) b->origin[k] = a->eye[k], b->velocity[k] = speed * dir[k];
    rbc_collider_def d;
    a->api->collider_def_init(&d, sizeof d);
    d.shape = RBC_SHAPE_SPHERE;
    d.radius = b->radius;
    memcpy(d.position, b->origin, sizeof d.position);
    b->born = a->sim_frame * (double)a->scene.dt;
    rbc_result r = a->api->collider_create(a->inst.world, &d, &b->id);
    if (r != RBC_OK) {
        report_api(a, r, "rbc_collider_create (ball)");
        return;
    }
    ++a->ball_count;
}

static void ball_position(const app *a, const ball *b, double time, float p[3]) {
    for (int k = 0; k < 3; ++k) p[k] = b->origin[k] + (float)(time - b->born) * b->velocity[k];
}

/* Move the balls to where they are at the end of the coming step; drop old ones. */
static void move_balls(app *a, double time) {
    uint32_t kept = 0;
    for (uint32_t i = 0; i < a->ball_count; ++i) {
        ball *b = &a->balls[i];
        if (time - b->born > BALL_LIFE) {
            a->api->collider_destroy(a->inst.world, b->id);
            continue;
        }
        float p[3], q[4] = {0, 0, 0, 1};
        ball_position(a, b, time, p);
        rbc_result r = a->api->collider_set_transform(a->inst.world, b->id, p, q);
        if (r != RBC_OK) report_api(a, r, "rbc_collider_set_transform (ball)");
        a->balls[kept++] = *b;
    }
    a->ball_count = kept;
}

static int reset(app *a);

static void key_press(app *a, int key) {
    switch (key) {
    case GLFW_KEY_SPACE: a->paused = !a->paused; break;
    case GLFW_KEY_R:
        if (reset(a)) glfwSetWindowShouldClose(a->window, 1);
        break;
    case GLFW_KEY_S: next_solver(a); break;
    case GLFW_KEY_P: next_preset(a); break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: change_iterations(a, +1); break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: change_iterations(a, -1); break;
    case GLFW_KEY_B: shoot_ball(a); break;
    case GLFW_KEY_C:
        a->cut_mode = !a->cut_mode;
        break;
    case GLFW_KEY_LEFT: a->azimuth -= 5; break;
    case GLFW_KEY_RIGHT: a->azimuth += 5; break;
    case GLFW_KEY_UP: a->elevation = a->elevation + 5 > 89 ? 89 : a->elevation + 5; break;
    case GLFW_KEY_DOWN: a->elevation = a->elevation - 5 < -89 ? -89 : a->elevation - 5; break;
    case GLFW_KEY_PAGE_UP: a->distance *= 0.9f; break;
    case GLFW_KEY_PAGE_DOWN: a->distance /= 0.9f; break;
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: glfwSetWindowShouldClose(a->window, 1); break;
    default: break;
    }
}

static int reset(app *a) {
    destroy_world(a);
    return create_world(a);
}

/* ------------------------------------------------------------------------- */
/* Drawing                                                                   */
/* ------------------------------------------------------------------------- */

static void draw_sphere(const float c[3], float r) {
    enum { SLICES = 24, STACKS = 12 };
    for (int i = 0; i < STACKS; ++i) {
        float t0 = PI_F * i / STACKS - PI_F / 2, t1 = PI_F * (i + 1) / STACKS - PI_F / 2;
        glBegin(GL_TRIANGLE_STRIP);
        for (int j = 0; j <= SLICES; ++j) {
            float p = 2 * PI_F * j / SLICES;
            float n0[3] = {cosf(t0) * cosf(p), sinf(t0), cosf(t0) * sinf(p)};
            float n1[3] = {cosf(t1) * cosf(p), sinf(t1), cosf(t1) * sinf(p)};
            /* Lower ring first: counter-clockwise seen from outside, so the front
             * face (which two-sided lighting lights with the normal as given) is out. */
            glNormal3fv(n0);
            glVertex3f(c[0] + r * n0[0], c[1] + r * n0[1], c[2] + r * n0[2]);
            glNormal3fv(n1);
            glVertex3f(c[0] + r * n1[0], c[1] + r * n1[1], c[2] + r * n1[2]);
        }
        glEnd();
    }
}

static void quat_matrix(const float q[4], const float p[3], float m[16]) {
    float x = q[0], y = q[1], z = q[2], w = q[3];
    float r[16] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
                   2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
                   2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
                   p[0], p[1], p[2], 1};
    memcpy(m, r, sizeof r);
}

static void draw_box(const float h[3]) {
    static const float n[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    glBegin(GL_QUADS);
    for (int f = 0; f < 6; ++f) {
        int a = f / 2, b = (a + 1) % 3, c = (a + 2) % 3;
        float s = n[f][a];
        glNormal3fv(n[f]);
        float corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        for (int k = 0; k < 4; ++k) {
            int kk = s > 0 ? k : 3 - k;
            float v[3];
            v[a] = s * h[a];
            v[b] = corners[kk][0] * h[b];
            v[c] = corners[kk][1] * h[c];
            glVertex3fv(v);
        }
    }
    glEnd();
}

/* Scene colliders in grey at their pose at `time`, and the balls. Grey keeps them
 * apart from the cloth's colours, whose red always exceeds their blue. */
static void draw_colliders(const app *a, double time) {
    glColor3f(0.62f, 0.62f, 0.62f);
    for (uint32_t j = 0; j < a->scene.collider_count; ++j) {
        const rbc_scene_collider *k = &a->scene.colliders[j];
        float p[3], q[4], m[16];
        rbc_scene_collider_pose(k, time, p, q);
        quat_matrix(q, p, m);
        glPushMatrix();
        glMultMatrixf(m);
        static const float origin[3] = {0, 0, 0};
        if (k->shape == RBC_SHAPE_SPHERE) {
            draw_sphere(origin, k->radius);
        } else if (k->shape == RBC_SHAPE_PLANE) {
            /* The frame's y = 0, drawn as a square a few scene sizes wide. */
            float s = 4.0f * a->radius;
            glBegin(GL_QUADS);
            glNormal3f(0, 1, 0);
            glVertex3f(-s, 0, -s), glVertex3f(-s, 0, s), glVertex3f(s, 0, s), glVertex3f(s, 0, -s);
            glEnd();
        } else if (k->shape == RBC_SHAPE_BOX) {
            draw_box(k->half_extents);
        } else if (k->shape == RBC_SHAPE_CAPSULE) {
            float h = k->half_extents[1], e0[3] = {0, -h, 0}, e1[3] = {0, h, 0};
            draw_sphere(e0, k->radius);
            draw_sphere(e1, k->radius);
            glBegin(GL_TRIANGLE_STRIP);
            for (int s = 0; s <= 24; ++s) {
                float ang = 2 * PI_F * s / 24, cx = cosf(ang), cz = sinf(ang);
                glNormal3f(cx, 0, cz);
                glVertex3f(k->radius * cx, -h, k->radius * cz); /* bottom first: outward front */
                glVertex3f(k->radius * cx, h, k->radius * cz);
            }
            glEnd();
        } else if (k->shape == RBC_SHAPE_TRIANGLE_MESH && k->mesh_positions) {
            /* Inline meshes only: a mesh read from a file is not kept by the scene. */
            glBegin(GL_TRIANGLES);
            for (uint32_t t = 0; t < k->mesh_triangle_count; ++t) {
                const float *v0 = k->mesh_positions + 3 * k->mesh_triangles[3 * t];
                const float *v1 = k->mesh_positions + 3 * k->mesh_triangles[3 * t + 1];
                const float *v2 = k->mesh_positions + 3 * k->mesh_triangles[3 * t + 2];
                float e1[3], e2[3], nn[3];
                v3_sub(v1, v0, e1);
                v3_sub(v2, v0, e2);
                v3_cross(e1, e2, nn);
                v3_normalize(nn);
                glNormal3fv(nn);
                glVertex3fv(v0), glVertex3fv(v1), glVertex3fv(v2);
            }
            glEnd();
        }
        glPopMatrix();
    }
    for (uint32_t i = 0; i < a->ball_count; ++i) {
        float p[3];
        ball_position(a, &a->balls[i], time, p);
        draw_sphere(p, a->balls[i].radius);
    }
}

static void draw(app *a) {
    glViewport(0, 0, a->fb_width, a->fb_height);
    /* Bluish background: its blue exceeds its red, unlike any cloth colour. */
    glClearColor(0.16f, 0.19f, 0.25f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glMatrixMode(GL_PROJECTION);
    glLoadMatrixf(a->proj);
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    /* A white light from above the eye, fixed in eye space; grey ambient. */
    static const float light_pos[4] = {0.3f, 0.6f, 1.0f, 0.0f};
    static const float light_diffuse[4] = {0.6f, 0.6f, 0.6f, 1.0f};
    static const float ambient[4] = {0.4f, 0.4f, 0.4f, 1.0f};
    static const float black[4] = {0, 0, 0, 1};
    glLightfv(GL_LIGHT0, GL_POSITION, light_pos);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, light_diffuse);
    glLightfv(GL_LIGHT0, GL_SPECULAR, black);
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
    glLoadMatrixf(a->view);

    for (uint32_t i = 0; i < a->scene.cloth_count; ++i) {
        view_cloth *c = &a->cloths[i];
        glBindBuffer(GL_ARRAY_BUFFER, c->vertex_buffer);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)c->vertex_count * 24, c->vertices, GL_STREAM_DRAW);
        glVertexPointer(3, GL_FLOAT, 24, (const void *)0);
        glNormalPointer(GL_FLOAT, 24, (const void *)12);
        glBindBuffer(GL_ARRAY_BUFFER, c->colour_buffer);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)c->vertex_count * 12, c->colours, GL_STREAM_DRAW);
        glColorPointer(3, GL_FLOAT, 0, (const void *)0);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, c->index_buffer);
        if (c->index_dirty) {
            /* The triangles change only when a tear or cut bumps the revision. */
            glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(c->triangle_values * sizeof(uint32_t)),
                         c->triangles, GL_STATIC_DRAW);
            c->index_dirty = 0;
        }
        glEnableClientState(GL_VERTEX_ARRAY);
        glEnableClientState(GL_NORMAL_ARRAY);
        glEnableClientState(GL_COLOR_ARRAY);
        glDrawElements(GL_TRIANGLES, (GLsizei)c->triangle_values, GL_UNSIGNED_INT, (const void *)0);
        glDisableClientState(GL_VERTEX_ARRAY);
        glDisableClientState(GL_NORMAL_ARRAY);
        glDisableClientState(GL_COLOR_ARRAY);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
        glBindBuffer(GL_ARRAY_BUFFER, 0);
    }
    draw_colliders(a, a->sim_frame * (double)a->scene.dt);
}

/* The drawn frame (back buffer, before the swap) as an RGB PNG. */
static int screenshot(const app *a, const char *path) {
    size_t w = (size_t)a->fb_width, h = (size_t)a->fb_height;
    unsigned char *px = malloc(w * h * 3), *flipped = malloc(w * h * 3);
    if (!px || !flipped) {
        free(px);
        free(flipped);
        fprintf(stderr, "rbcloth-viewer: out of memory (screenshot)\n");
        return -1;
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, (GLsizei)w, (GLsizei)h, GL_RGB, GL_UNSIGNED_BYTE, px);
    for (size_t y = 0; y < h; ++y) memcpy(flipped + y * w * 3, px + (h - 1 - y) * w * 3, w * 3);
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    img.width = (png_uint_32)w;
    img.height = (png_uint_32)h;
    img.format = PNG_FORMAT_RGB;
    int ok = png_image_write_to_file(&img, path, 0, flipped, (png_int_32)(w * 3), NULL);
    if (!ok) fprintf(stderr, "rbcloth-viewer: cannot write %s: %s\n", path, img.message);
    png_image_free(&img);
    free(px);
    free(flipped);
    return ok ? 0 : -1;
}

/* The line scripted mode prints: what a test checks besides the pixels. */
static void print_state(const app *a, const char *tag) {
    rbc_world_stats st;
    a->api->world_stats_init(&st, rbc_struct_size_for(RBC_STRUCT_WORLD_STATS, a->abi_version));
    st.skip_measures = 1;
    a->api->world_get_stats(a->inst.world, &st);
    printf("%s frame=%u", tag, a->sim_frame);
    for (uint32_t i = 0; i < a->scene.cloth_count; ++i)
        printf(" cloth%u.triangles=%zu cloth%u.revision=%u cloth%u.springs=%zu", i,
               a->cloths[i].triangle_values / 3, i, a->cloths[i].revision, i,
               a->cloths[i].spring_values / 2);
    if (a->drag_cloth >= 0) printf(" dragging=%d:%u", a->drag_cloth, a->drag_vertex);
    else printf(" dragging=none");
    if (a->last_pick_cloth >= 0) printf(" picked=%d:%u", a->last_pick_cloth, a->last_pick_vertex);
    else printf(" picked=none");
    printf(" springs_cut=%llu balls=%u solver=%s linear=%u max_strain=%.4g step_ms=%.2f "
           "frame_ms=%.2f\n",
           (unsigned long long)a->springs_cut, a->ball_count, solver_name(a),
           a->scene.world.linear_iterations, st.step_max_strain, a->step_ms, a->frame_ms);
    fflush(stdout);
}

/* ------------------------------------------------------------------------- */
/* Window callbacks (interactive mode only: a script owns the input)         */
/* ------------------------------------------------------------------------- */

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods) {
    if (action == GLFW_PRESS || (action == GLFW_REPEAT && key != GLFW_KEY_B && key != GLFW_KEY_C &&
                                 key != GLFW_KEY_R && key != GLFW_KEY_SPACE))
        key_press(glfwGetWindowUserPointer(w), key);
}
static void on_button(GLFWwindow *w, int button, int action, int mods) {
    app *a = glfwGetWindowUserPointer(w);
    if (button != GLFW_MOUSE_BUTTON_LEFT && button != GLFW_MOUSE_BUTTON_RIGHT) return;
    /* One button at a time: the one that started a drag or stroke ends it. */
    if (action == GLFW_PRESS && a->button < 0) {
        a->glfw_button = button;
        mouse_down(a, button == GLFW_MOUSE_BUTTON_RIGHT);
    } else if (action == GLFW_RELEASE && a->button >= 0 && button == a->glfw_button) {
        mouse_up(a);
    }
}
static void on_cursor(GLFWwindow *w, double x, double y) {
    mouse_move(glfwGetWindowUserPointer(w), x, y);
}
static void on_scroll(GLFWwindow *w, double dx, double dy) {
    app *a = glfwGetWindowUserPointer(w);
    a->distance *= powf(0.9f, (float)dy);
}
static void on_glfw_error(int code, const char *message) {
    fprintf(stderr, "rbcloth-viewer: GLFW: %s\n", message);
}

/* ------------------------------------------------------------------------- */
/* Options and main                                                          */
/* ------------------------------------------------------------------------- */

static void usage(FILE *f) {
    fprintf(f,
            "usage: rbcloth-viewer [options] [SCENE.json]\n"
            "  Steps and draws a scene (the built-in default scene without SCENE).\n"
            "  --size WxH          window size in pixels (default 1024x768)\n"
            "  --frames N          quit after N frames (default: run until closed; with\n"
            "                      --script: the frame after its last event)\n"
            "  --script FILE       scripted input and screenshots (hosts/viewer/README.md);\n"
            "                      prints the viewer's state to stdout\n"
            "  --camera AZ,EL      view direction in degrees (default 35,25)\n"
            "  --preset NAME       start with a solver preset (paper, game_60hz, cloth)\n"
            "  --solver NAME       start with a global solver (rbgs, jacobi, ...)\n"
            "Keys: mouse left drag = drag a vertex, right drag = cut, C = left drag cuts,\n"
            "B = ball, S = next solver, P = next preset, +/- = iterations, space = pause,\n"
            "R = reset, arrows = orbit, PageUp/PageDown or wheel = zoom, Esc = quit.\n");
}

static int find_name(const char *word, const char *const *names) {
    for (int k = 0; names[k]; ++k)
        if (strcmp(word, names[k]) == 0) return k;
    return -1;
}

static int bad_name(const char *option, const char *word, const char *const *names) {
    const char *near = rbc_scene_nearest(word, names);
    fprintf(stderr, "rbcloth-viewer: %s: unknown name '%s'%s%s%s\n", option, word,
            near ? " (did you mean " : "", near ? near : "", near ? "?)" : "");
    return 2;
}

int main(int argc, char **argv) {
    const char *scene_path = NULL, *script_path = NULL, *preset = NULL, *solver = NULL;
    long frames = 0;
    int width = 1024, height = 768;
    float azimuth = DEFAULT_AZIMUTH, elevation = DEFAULT_ELEVATION;
    for (int i = 1; i < argc; ++i) {
        const char *o = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        int takes = strcmp(o, "--size") == 0 || strcmp(o, "--frames") == 0 ||
                    strcmp(o, "--script") == 0 || strcmp(o, "--camera") == 0 ||
                    strcmp(o, "--preset") == 0 || strcmp(o, "--solver") == 0;
        if (strcmp(o, "-h") == 0 || strcmp(o, "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (takes && !v) {
            fprintf(stderr, "rbcloth-viewer: %s needs a value\n", o);
            return 2;
        }
        char tail;
        if (strcmp(o, "--size") == 0) {
            if (sscanf(v, "%dx%d%c", &width, &height, &tail) != 2 || width < 16 || height < 16 ||
                width > 8192 || height > 8192) {
                fprintf(stderr, "rbcloth-viewer: --size: '%s' is not WxH (16 to 8192 each)\n", v);
                return 2;
            }
        } else if (strcmp(o, "--frames") == 0) {
            if (sscanf(v, "%ld%c", &frames, &tail) != 1 || frames < 1) {
                fprintf(stderr, "rbcloth-viewer: --frames: '%s' is not a count >= 1\n", v);
                return 2;
            }
        } else if (strcmp(o, "--camera") == 0) {
            if (sscanf(v, "%f,%f%c", &azimuth, &elevation, &tail) != 2 || !isfinite(azimuth) ||
                !(elevation >= -89 && elevation <= 89)) {
                fprintf(stderr, "rbcloth-viewer: --camera: '%s' is not AZ,EL in degrees (EL within "
                                "+-89)\n", v);
                return 2;
            }
        } else if (strcmp(o, "--script") == 0) {
            script_path = v;
        } else if (strcmp(o, "--preset") == 0) {
            if (find_name(v, rbc_scene_preset_names) < 0) return bad_name(o, v, rbc_scene_preset_names);
            preset = v;
        } else if (strcmp(o, "--solver") == 0) {
            if (find_name(v, rbc_scene_solver_names) < 0) return bad_name(o, v, rbc_scene_solver_names);
            solver = v;
        } else if (o[0] == '-') {
            fprintf(stderr, "rbcloth-viewer: unknown option %s (--help lists them)\n", o);
            return 2;
        } else if (scene_path) {
            fprintf(stderr, "rbcloth-viewer: one scene at a time (%s and %s)\n", scene_path, o);
            return 2;
        } else {
            scene_path = o;
        }
        if (takes) ++i;
    }

    static app a; /* zeroed; static: large and lives for the program */
    a.width = width, a.height = height;
    a.azimuth = azimuth, a.elevation = elevation;
    a.button = -1, a.drag_cloth = -1, a.last_pick_cloth = -1, a.preset = -1;
    viewer_script script = {0};
    char err[RBC_SCENE_ERROR_MAX];
    if (script_path) {
        if (viewer_script_load(script_path, &script, err, sizeof err)) {
            fprintf(stderr, "rbcloth-viewer: %s\n", err);
            return 2;
        }
        a.scripted = 1;
        if (!frames) frames = (long)script.events[script.count - 1].frame + 1;
    }
    if ((scene_path ? rbc_scene_load_file(scene_path, &a.scene, err, sizeof err)
                    : rbc_scene_load_default(&a.scene, err, sizeof err))) {
        fprintf(stderr, "rbcloth-viewer: %s\n", err);
        viewer_script_free(&script);
        return 1;
    }
    cli_plugin plugin;
    if (cli_plugin_open(&plugin, err, sizeof err)) {
        fprintf(stderr, "rbcloth-viewer: %s\n", err);
        rbc_scene_free(&a.scene);
        viewer_script_free(&script);
        return 1;
    }
    a.api = plugin.api;
    a.abi_version = a.api->abi_version_fn();
    /* cli_plugin_open refuses a table older than this header's (1.10), but checks
     * only the 1.0 entries: a library built from the 1.10 header alone lacks these. */
    if (!a.api->world_read_vertices || !a.api->cloth_get_triangles || !a.api->vertex_output_init) {
        fprintf(stderr, "rbcloth-viewer: %s lacks rbc_world_read_vertices or "
                        "rbc_cloth_get_triangles (ABI 1.10), which the viewer draws from\n",
                plugin.path);
        cli_plugin_close(&plugin);
        rbc_scene_free(&a.scene);
        viewer_script_free(&script);
        return 1;
    }
    if (preset) {
        a.preset = find_name(preset, rbc_scene_preset_names);
        rbc_result r = a.api->solver_def_preset(&a.scene.world.solver, sizeof a.scene.world.solver,
                                                (rbc_preset)a.preset);
        if (r != RBC_OK) report_api(&a, r, "--preset");
    }
    if (solver) a.scene.world.solver.solver = (rbc_solver_kind)find_name(solver, rbc_scene_solver_names);

    int rc = 1;
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit()) {
        fprintf(stderr, "rbcloth-viewer: cannot start GLFW (no display? under Xvfb: xvfb-run -a "
                        "-s \"-screen 0 800x600x24\" rbcloth-viewer ...)\n");
        goto out_plugin;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    /* A script's screenshots must not depend on the window manager resizing us. */
    glfwWindowHint(GLFW_RESIZABLE, a.scripted ? GLFW_FALSE : GLFW_TRUE);
    a.window = glfwCreateWindow(width, height, "rbcloth-viewer", NULL, NULL);
    if (!a.window) {
        fprintf(stderr, "rbcloth-viewer: cannot open a %dx%d OpenGL 2.1 window\n", width, height);
        goto out_glfw;
    }
    glfwMakeContextCurrent(a.window);
    glfwSwapInterval(a.scripted ? 0 : 1);
    glfwSetWindowUserPointer(a.window, &a);
    if (!a.scripted) {
        glfwSetKeyCallback(a.window, on_key);
        glfwSetMouseButtonCallback(a.window, on_button);
        glfwSetCursorPosCallback(a.window, on_cursor);
        glfwSetScrollCallback(a.window, on_scroll);
    }
    glEnable(GL_DEPTH_TEST);
    glEnable(GL_LIGHTING);
    glEnable(GL_LIGHT0);
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE); /* cloth has two sides */
    glEnable(GL_COLOR_MATERIAL);
    glColorMaterial(GL_FRONT_AND_BACK, GL_AMBIENT_AND_DIFFUSE);
    if (a.scripted)
        printf("viewer abi=%u.%u renderer=%s\n", a.abi_version >> 16, a.abi_version & 0xFFFFu,
               (const char *)glGetString(GL_RENDERER));

    glfwGetWindowSize(a.window, &a.width, &a.height);
    fit_camera(&a);
    if (create_world(&a)) goto out_world;
    size_t next_event = 0;
    double last_frame_start = now_ms(), title_at = 0;
    for (long frame = 0; !glfwWindowShouldClose(a.window) && (!frames || frame < frames); ++frame) {
        double start = now_ms();
        a.frame_ms += 0.1 * ((start - last_frame_start) - a.frame_ms);
        last_frame_start = start;
        glfwPollEvents();
        glfwGetWindowSize(a.window, &a.width, &a.height);
        glfwGetFramebufferSize(a.window, &a.fb_width, &a.fb_height);
        if (a.width < 1 || a.height < 1) { /* minimised: nothing to draw, wait for events */
            glfwWaitEventsTimeout(0.1);
            continue;
        }
        update_camera(&a);
        /* The script's input of this frame; window pixels are event coordinates. */
        size_t first_output = next_event;
        for (; next_event < script.count && script.events[next_event].frame == (uint32_t)frame;
             ++next_event) {
            const viewer_event *e = &script.events[next_event];
            switch (e->kind) {
            case VIEWER_EVENT_DOWN: mouse_move(&a, e->x, e->y), mouse_down(&a, e->button); break;
            case VIEWER_EVENT_MOVE: mouse_move(&a, e->x, e->y); break;
            case VIEWER_EVENT_UP: mouse_up(&a); break;
            case VIEWER_EVENT_KEY: key_press(&a, e->key); break;
            default: break;
            }
            update_camera(&a);
        }
        if (!a.paused) {
            double time = (a.sim_frame + 1) * (double)a.scene.dt; /* end of this step */
            if (a.drag_cloth >= 0) {
                float target[3];
                drag_target(&a, target);
                rbc_result r = a.api->cloth_set_pin(a.inst.world, a.inst.cloths[a.drag_cloth],
                                                    a.drag_vertex, target);
                if (r != RBC_OK) report_api(&a, r, "rbc_cloth_set_pin");
            }
            move_balls(&a, time);
            rbc_result r = rbc_scene_apply_frame(a.api, &a.scene, &a.inst, a.sim_frame, err, sizeof err);
            if (r != RBC_OK) {
                fprintf(stderr, "rbcloth-viewer: %s\n", err);
                goto out_world;
            }
            double t0 = now_ms();
            r = a.api->world_step(a.inst.world, a.scene.dt);
            double t1 = now_ms();
            if (r != RBC_OK) {
                report_api(&a, r, "rbc_world_step");
                goto out_world;
            }
            a.step_ms = a.sim_frame ? a.step_ms + 0.1 * ((t1 - t0) - a.step_ms) : t1 - t0;
            ++a.sim_frame;
            if (read_cloths(&a)) goto out_world;
            rbc_world_stats st;
            a.api->world_stats_init(&st, rbc_struct_size_for(RBC_STRUCT_WORLD_STATS, a.abi_version));
            st.skip_measures = 1; /* timings and the step's own strain: no extra pass */
            if (a.api->world_get_stats(a.inst.world, &st) == RBC_OK) a.max_strain = st.step_max_strain;
        }
        draw(&a);
        for (size_t k = first_output; k < next_event; ++k) {
            const viewer_event *e = &script.events[k];
            if (e->kind == VIEWER_EVENT_SCREENSHOT) {
                if (screenshot(&a, e->path)) goto out_world;
                print_state(&a, "screenshot");
            } else if (e->kind == VIEWER_EVENT_STATE) {
                print_state(&a, "state");
            }
        }
        glfwSwapBuffers(a.window);
        if (start - title_at > 250.0) {
            char title[256];
            snprintf(title, sizeof title,
                     "rbcloth-viewer | step %.2f ms | frame %.2f ms | max strain %.4f | %s, %u iter%s%s",
                     a.step_ms, a.frame_ms, a.max_strain, solver_name(&a),
                     a.scene.world.linear_iterations, a.cut_mode ? " | CUT MODE" : "",
                     a.paused ? " | paused" : "");
            glfwSetWindowTitle(a.window, title);
            title_at = start;
        }
    }
    rc = 0;
    if (a.scripted) print_state(&a, "end");
out_world:
    destroy_world(&a);
    glfwDestroyWindow(a.window);
out_glfw:
    glfwTerminate();
out_plugin:
    cli_plugin_close(&plugin);
    rbc_scene_free(&a.scene);
    viewer_script_free(&script);
    return rc;
}
