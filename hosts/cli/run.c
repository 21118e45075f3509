/* run.c -- `rbcloth run`: simulate a scene through the plugin's function table and
 * write, per cloth, the rest mesh (OBJ) and every frame's positions (PC2), then a
 * JSON summary of the run, last, once the others are on disk (fsync'd).
 *
 * SIGINT/SIGTERM stop the run at the end of the frame: the caches are destroyed,
 * which removes their temporary files, and the exit status is 1. A second signal
 * (a frame that does not end) removes the temporaries at once and exits.
 */
#include "run.h"

#include <cJSON.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fsutil.h"
#include "scene.h"
#include "timings.h"
#include "viewer.h"

/* ------------------------------------------------------------------------- */
/* Messages and progress                                                     */
/* ------------------------------------------------------------------------- */

/* Whether a progress line is on stderr (log messages clear it first). */
static int progress_visible = 0;

static void progress_clear(void) {
    if (progress_visible) {
        fputs("\r\033[K", stderr);
        progress_visible = 0;
    }
}

static void progress_draw(uint32_t done, uint32_t total, double step_ms) {
    enum { WIDTH = 32 };
    char bar[WIDTH + 1];
    uint32_t filled = (uint32_t)((uint64_t)done * WIDTH / (total ? total : 1));
    for (uint32_t i = 0; i < WIDTH; ++i)
        bar[i] = i < filled ? '#' : '.';
    bar[WIDTH] = '\0';
    fprintf(stderr, "\r[%s] %u/%u frames, %.3f ms/step", bar, done, total, step_ms);
    fflush(stderr);
    progress_visible = 1;
}

/* ------------------------------------------------------------------------- */
/* Signals                                                                   */
/* ------------------------------------------------------------------------- */

/* The signal that stops the run (0: none yet), and how many came. */
static volatile sig_atomic_t g_stop_signal = 0, g_stop_count = 0;
/* Every temporary file the run may have open ("<output>.tmp", and the summary's
 * "<summary>.<pid>.tmp"), listed once the outputs are known (the count set last):
 * the second signal unlinks them (async-signal-safe) and exits. */
static char **g_tmp_paths = NULL;
static size_t g_tmp_count = 0;

static void on_stop_signal(int sig) {
    g_stop_signal = sig;
    if (g_stop_count++ == 0) return;
    for (size_t k = 0; k < g_tmp_count; ++k) unlink(g_tmp_paths[k]);
    static const char msg[] = "\nrbcloth: stopped by a second signal; temporary files removed\n";
    ssize_t w = write(STDERR_FILENO, msg, sizeof msg - 1);
    (void)w;
    _exit(1);
}

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The plugin's log hook, called on the thread that called rbc_world_step (ours).
 * Error-level messages are skipped: every error is also returned by the failing
 * call and reported once, by report_api, with its result code. */
static void RBC_CALL log_to_stderr(void *user, rbc_log_level level, const char *message) {
    static const char *const names[] = {"error", "warning", "info", "debug"};
    if (level == RBC_LOG_ERROR)
        return;
    const char *name = level >= 0 && level <= RBC_LOG_DEBUG ? names[level] : "log";
    progress_clear();
    fprintf(stderr, "rbcloth: plugin %s: %s\n", name, message ? message : "");
}

/* "rbcloth: <result string>: <message>", exit code 1. */
static int report(const rbc_api_v1 *api, rbc_result result, const char *message) {
    progress_clear();
    fprintf(stderr, "rbcloth: %s: %s\n", api->result_string(result), message);
    return 1;
}

static int report_api(const rbc_api_v1 *api, rbc_result result) {
    return report(api, result, api->last_error());
}

static const char *backend_name(rbc_backend backend) {
    switch (backend) {
    case RBC_BACKEND_AUTO: return "auto";
    case RBC_BACKEND_CPU: return "cpu";
    case RBC_BACKEND_CUDA: return "cuda";
    default: return "unknown";
    }
}

/* A float as the shortest decimal that reads back to the same float (0.002f ->
 * 0.002, not 0.00200000009), for a readable summary. */
static double float_as_decimal(float value) {
    char text[32];
    for (int digits = 1; digits <= 9; ++digits) {
        snprintf(text, sizeof text, "%.*g", digits, (double)value);
        double decimal = strtod(text, NULL);
        if ((float)decimal == value)
            return decimal;
    }
    return (double)value;
}

/* ------------------------------------------------------------------------- */
/* State of one run                                                          */
/* ------------------------------------------------------------------------- */

typedef struct cloth_output {
    char *obj_path;
    char *pc2_path;
    /// A cloth that can tear (tear_strain > 0): STEM_torn.obj, its last frame with the
    /// quads that remain (rbc_cloth_get_quads), and their count. NULL otherwise.
    char *torn_obj_path;
    uint32_t quads_remaining;
    rbc_cache_id cache;
    uint32_t spring_count;
    uint32_t color_count;
} cloth_output;

typedef struct run_state {
    const cli_plugin *plugin;
    const rbc_api_v1 *api;
    const cli_run_options *options;
    rbc_scene scene;
    rbc_scene_instance instance;
    cloth_output *outputs;
    char *summary_path;
    /// The still and the player (viewer.h): NAME.png and NAME.html of every cloth
    /// and collider; NULL with --no-view. view_collider[j]: scene collider j's index
    /// in the view, or -1 (a mesh read from a file: the scene keeps no triangles).
    char *png_path, *html_path;
    cli_view *view;
    int32_t *view_collider;
    float *positions;
    size_t positions_capacity;
    cli_timings timings;
    rbc_world_stats stats;
    uint32_t frames_done;
    /// Shared locks on the lock files of a batch's output folder (fsutil.h) that
    /// --out is, or is inside: -1 where there is none.
    int lock_fds[2];
    double wall_seconds;
    /// --mode target, over the frames: what the controller chose (substeps and
    /// linear iterations per frame) and what the frames reached.
    struct {
        uint32_t met, substeps_min, substeps_max, linear_max;
        uint64_t substeps_sum, linear_sum;
        double reached_max;
    } target;
} run_state;

static void run_state_free(run_state *s) {
    for (uint32_t i = 0; s->outputs && i < s->scene.cloth_count; ++i) {
        if (s->outputs[i].cache)
            s->api->cache_destroy(s->outputs[i].cache); /* removes the temporary file */
        free(s->outputs[i].obj_path);
        free(s->outputs[i].pc2_path);
        free(s->outputs[i].torn_obj_path);
    }
    free(s->outputs);
    free(s->summary_path);
    free(s->png_path);
    free(s->html_path);
    cli_view_destroy(s->view);
    free(s->view_collider);
    free(s->positions);
    cli_timings_free(&s->timings);
    rbc_scene_instance_destroy(s->api, &s->instance);
    rbc_scene_free(&s->scene);
    for (int k = 0; k < 2; ++k)
        if (s->lock_fds[k] >= 0) close(s->lock_fds[k]);
}

static int out_of_memory(const run_state *s) {
    return report(s->api, RBC_ERR_OUT_OF_MEMORY, "out of memory in the rbcloth host");
}

/* ------------------------------------------------------------------------- */
/* Steps of a run                                                            */
/* ------------------------------------------------------------------------- */

static int load_scene(run_state *s) {
    char err[RBC_SCENE_ERROR_MAX];
    const cli_run_options *o = s->options;
    int rc = o->scene_path ? rbc_scene_load_file(o->scene_path, &s->scene, err, sizeof err)
                           : rbc_scene_load_default(&s->scene, err, sizeof err);
    if (rc) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return 1;
    }
    /* The command line wins over the scene (ranges checked by the caller). */
    if (o->frames >= 0)
        s->scene.frames = (uint32_t)o->frames;
    if (o->threads >= 0)
        s->scene.world.thread_count = (uint32_t)o->threads;
    if (o->substeps >= 0)
        s->scene.world.substeps = (uint32_t)o->substeps;
    if (o->iterations >= 0)
        s->scene.world.linear_iterations = (uint32_t)o->iterations;
    if (o->nonlinear >= 0)
        s->scene.world.nonlinear_iterations = (uint32_t)o->nonlinear;
    if (o->substep_rate > 0.0)
        s->scene.world.substep_rate = (float)o->substep_rate;
    rbc_solver_def *sd = &s->scene.world.solver;
    for (int k = 0; o->preset && rbc_scene_preset_names[k]; ++k)
        if (strcmp(o->preset, rbc_scene_preset_names[k]) == 0) {
            rbc_result r = s->api->solver_def_preset(sd, sizeof *sd, (rbc_preset)k);
            if (r != RBC_OK)
                return report_api(s->api, r);
        }
    for (int k = 0; o->solver && rbc_scene_solver_names[k]; ++k)
        if (strcmp(o->solver, rbc_scene_solver_names[k]) == 0) sd->solver = (rbc_solver_kind)k;
    for (int k = 0; o->mode && rbc_scene_mode_names[k]; ++k)
        if (strcmp(o->mode, rbc_scene_mode_names[k]) == 0) sd->mode = (rbc_iteration_mode)k;
    for (int k = 0; o->energy_guard && rbc_scene_energy_guard_names[k]; ++k)
        if (strcmp(o->energy_guard, rbc_scene_energy_guard_names[k]) == 0)
            sd->energy_guard = (rbc_energy_guard)k;
    if (o->tolerance >= 0.0) sd->tolerance = (float)o->tolerance;
    if (o->budget_ms >= 0.0) sd->budget_ms = (float)o->budget_ms;
    if (o->omega >= 0.0) sd->omega = (float)o->omega;
    if (o->target_strain >= 0.0) sd->target_strain = (float)o->target_strain;
    if (o->max_substeps >= 0) sd->max_substeps = (uint32_t)o->max_substeps;
    if (o->max_linear >= 0) sd->max_linear_iterations = (uint32_t)o->max_linear;
    return 0;
}

/* The folder that holds `dir`, malloc'd: "a/b" -> "a", "b" -> ".", "a/.." -> "a/../..". */
static char *parent_folder(const char *dir) {
    size_t n = strlen(dir);
    while (n > 1 && dir[n - 1] == '/')
        --n;
    size_t slash = n;
    while (slash > 0 && dir[slash - 1] != '/')
        --slash;
    const char *base = dir + slash;
    size_t base_len = n - slash;
    if ((base_len == 1 && base[0] == '.') || (base_len == 2 && strncmp(base, "..", 2) == 0))
        return fs_path(dir, "..", "");
    if (slash == 0)
        return strdup(".");
    if (slash == 1)
        return strdup("/");
    return strndup(dir, slash - 1);
}

/* One cloth: NAME.obj/.pc2; several: NAME_CLOTH.obj/.pc2. */
static int plan_outputs(run_state *s) {
    const char *dir = s->options->out_dir;
    if (fs_mkdir_p_or_say(dir))
        return 1;
    /* Not into a running batch's folder, nor one of its jobs' (DIR/JOB): its
     * workers write there. A batch started during this run is refused in turn. */
    char *parent = parent_folder(dir);
    if (!parent)
        return out_of_memory(s);
    const char *folders[2] = {dir, parent};
    for (int k = 0; k < 2; ++k) {
        char lock_err[1024];
        int lk = fs_lock_dir(folders[k], 0, 0, "rbcloth run", 10.0, &s->lock_fds[k], lock_err,
                             sizeof lock_err);
        if (lk == FS_LOCK_BUSY) {
            fprintf(stderr, "rbcloth: cannot write into %s: %s\n", dir, lock_err);
            free(parent);
            return 1;
        }
    }
    free(parent);
    s->outputs = calloc(s->scene.cloth_count, sizeof *s->outputs);
    s->summary_path = fs_path(dir, s->scene.name, ".json");
    if (!s->outputs || !s->summary_path)
        return out_of_memory(s);
    if (!s->options->no_view &&
        (!(s->png_path = fs_path(dir, s->scene.name, ".png")) ||
         !(s->html_path = fs_path(dir, s->scene.name, ".html"))))
        return out_of_memory(s);
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        char *stem;
        if (s->scene.cloth_count == 1) {
            stem = strdup(s->scene.name);
        } else {
            size_t size = strlen(s->scene.name) + 1 + strlen(s->scene.cloths[i].name) + 1;
            stem = malloc(size);
            if (stem)
                snprintf(stem, size, "%s_%s", s->scene.name, s->scene.cloths[i].name);
        }
        if (!stem)
            return out_of_memory(s);
        s->outputs[i].obj_path = fs_path(dir, stem, ".obj");
        s->outputs[i].pc2_path = fs_path(dir, stem, ".pc2");
        /* PC2 keeps the vertices, not the faces: a cloth that tears also gets its
         * last frame with the quads that remain. */
        if (s->scene.cloths[i].tear_strain > 0.0f &&
            !(s->outputs[i].torn_obj_path = fs_path(dir, stem, "_torn.obj"))) {
            free(stem);
            return out_of_memory(s);
        }
        free(stem);
        if (!s->outputs[i].obj_path || !s->outputs[i].pc2_path)
            return out_of_memory(s);
    }
    return 0;
}

/* Whether a cloth can tear, so that its remaining quads are written at the end. */
static int any_torn_output(const run_state *s) {
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i)
        if (s->outputs[i].torn_obj_path)
            return 1;
    return 0;
}

static int create_world(run_state *s) {
    const rbc_api_v1 *api = s->api;
    char err[RBC_SCENE_ERROR_MAX];
    rbc_result r = rbc_scene_instantiate(api, &s->scene, log_to_stderr, NULL, &s->instance, err,
                                         sizeof err);
    if (r != RBC_OK)
        return report(api, r, err);

    uint32_t max_vertices = 0;
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        cloth_output *o = &s->outputs[i];
        r = api->cloth_get_topology(s->instance.world, s->instance.cloths[i], &o->spring_count,
                                    &o->color_count);
        if (r != RBC_OK)
            return report_api(api, r);
        if (s->scene.cloths[i].vertex_count > max_vertices)
            max_vertices = s->scene.cloths[i].vertex_count;
    }
    /* A cloth that can tear needs rbc_cloth_get_quads (ABI 1.3) for its last frame. */
    if (any_torn_output(s) &&
        (api->struct_size < offsetof(rbc_api_v1, cloth_get_quads) + sizeof api->cloth_get_quads ||
         !api->cloth_get_quads)) {
        fprintf(stderr, "rbcloth: %s: a cloth with tear_strain needs rbc_cloth_get_quads (ABI "
                        "1.3), which this plugin's function table does not have\n",
                s->scene.source);
        return 1;
    }
    s->positions_capacity = (size_t)max_vertices * 3;
    s->positions = malloc(s->positions_capacity * sizeof *s->positions);
    if (!s->positions || cli_timings_init(&s->timings, s->scene.frames))
        return out_of_memory(s);
    return 0;
}

/* Rest meshes, then one open cache per cloth. */
static int start_outputs(run_state *s) {
    const rbc_api_v1 *api = s->api;
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        const rbc_scene_cloth *c = &s->scene.cloths[i];
        cloth_output *o = &s->outputs[i];
        rbc_result r = api->write_obj(o->obj_path, c->positions, c->vertex_count, c->quads,
                                      c->quad_count);
        if (r != RBC_OK)
            return report_api(api, r);

        rbc_cache_def cd;
        r = api->cache_def_init(&cd, (uint32_t)sizeof cd);
        if (r != RBC_OK)
            return report_api(api, r);
        cd.format = RBC_CACHE_PC2;
        cd.path = o->pc2_path;
        cd.point_count = c->vertex_count;
        /* Sample k holds the positions after k + 1 steps: frame 0 is the rest pose
         * of the OBJ, the cache starts at frame 1. */
        cd.start_frame = 1.0f;
        cd.sample_rate = 1.0f;
        r = api->cache_create(&cd, &o->cache);
        if (r != RBC_OK)
            return report_api(api, r);
    }
    return 0;
}

/* The still and the player: every cloth (rest mesh) and collider, and frame 0, the
 * rest pose (the caches start at frame 1). */
static int start_view(run_state *s) {
    const rbc_scene *sc = &s->scene;
    char err[512];
    if (!s->png_path) return 0;
    s->view_collider = malloc((sc->collider_count ? sc->collider_count : 1) * sizeof(int32_t));
    if (!s->view_collider) return out_of_memory(s);
    if (cli_view_create(&s->view, sc->name, sc->dt, sc->frames + 1, err, sizeof err))
        goto fail;
    for (uint32_t i = 0; i < sc->cloth_count; ++i) {
        const rbc_scene_cloth *c = &sc->cloths[i];
        cli_view_cloth_def d = {c->name, c->vertex_count, c->positions, c->quad_count,
                                c->quads, 0, NULL};
        if (cli_view_add_cloth(s->view, &d, err, sizeof err)) goto fail;
    }
    int32_t shown = 0;
    for (uint32_t j = 0; j < sc->collider_count; ++j) {
        const rbc_scene_collider *k = &sc->colliders[j];
        s->view_collider[j] = -1;
        if (k->shape == RBC_SHAPE_TRIANGLE_MESH && !k->mesh_positions) continue;
        cli_view_collider_def d = {k->shape,
                                   k->radius,
                                   {k->half_extents[0], k->half_extents[1], k->half_extents[2]},
                                   k->mesh_vertex_count,
                                   k->mesh_positions,
                                   k->mesh_triangle_count,
                                   k->mesh_triangles};
        if (cli_view_add_collider(s->view, &d, err, sizeof err)) goto fail;
        s->view_collider[j] = shown++;
    }
    for (uint32_t i = 0; i < sc->cloth_count; ++i)
        if (cli_view_frame_cloth(s->view, i, sc->cloths[i].positions)) goto fail_frame;
    for (uint32_t j = 0; j < sc->collider_count; ++j) {
        float p[3], q[4];
        if (s->view_collider[j] < 0) continue;
        rbc_scene_collider_pose(&sc->colliders[j], 0.0, p, q);
        if (cli_view_frame_collider(s->view, (uint32_t)s->view_collider[j], p, q))
            goto fail_frame;
    }
    return 0;
fail_frame:
    snprintf(err, sizeof err, "%s", cli_view_last_error(s->view));
fail:
    progress_clear();
    fprintf(stderr, "rbcloth: the viewer of %s: %s\n", sc->name, err);
    return 1;
}

/* One frame of the viewer: cloth i's positions (in s->positions), after its torn
 * quads; or, with cloth == UINT32_MAX, the colliders' poses at `time`. */
static int view_frame(run_state *s, uint32_t cloth, double time) {
    if (!s->view) return 0;
    const rbc_scene *sc = &s->scene;
    int bad = 0;
    if (cloth == UINT32_MAX) {
        for (uint32_t j = 0; j < sc->collider_count && !bad; ++j) {
            float p[3], q[4];
            if (s->view_collider[j] < 0) continue;
            rbc_scene_collider_pose(&sc->colliders[j], time, p, q);
            bad = cli_view_frame_collider(s->view, (uint32_t)s->view_collider[j], p, q);
        }
    } else {
        if (s->outputs[cloth].torn_obj_path) {
            /* A cloth that tears: the quads that remain, so holes show as they open. */
            const rbc_api_v1 *api = s->api;
            size_t count = 0;
            rbc_result r = api->cloth_get_quads(s->instance.world, s->instance.cloths[cloth],
                                                NULL, 0, &count);
            uint32_t *quads = r == RBC_OK ? malloc((count ? count : 1) * sizeof *quads) : NULL;
            if (r == RBC_OK && !quads) return out_of_memory(s);
            if (r == RBC_OK)
                r = api->cloth_get_quads(s->instance.world, s->instance.cloths[cloth], quads,
                                         count, &count);
            char err[512];
            int failed = r == RBC_OK && cli_view_set_remaining_quads(s->view, cloth, quads,
                                                                      count / 4, err, sizeof err);
            free(quads);
            if (r != RBC_OK) return report_api(api, r);
            if (failed) {
                progress_clear();
                fprintf(stderr, "rbcloth: the viewer of %s: %s\n", sc->name, err);
                return 1;
            }
        }
        bad = cli_view_frame_cloth(s->view, cloth, s->positions);
    }
    if (bad) {
        progress_clear();
        fprintf(stderr, "rbcloth: the viewer of %s: %s\n", sc->name, cli_view_last_error(s->view));
        return 1;
    }
    return 0;
}

/* NAME.png (the last frame) and NAME.html. */
static int finish_view(run_state *s) {
    if (!s->view) return 0;
    char err[512];
    uint32_t total = cli_view_frame_total(s->view);
    if (cli_view_write_png(s->view, s->png_path, total ? total - 1 : 0, 0, 0, err, sizeof err) ||
        cli_view_write_html(s->view, s->html_path, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return 1;
    }
    return 0;
}

/* STEM_torn.obj of each cloth that can tear: the last frame's positions and the quads
 * that remain (rbc_cloth_get_quads, ABI 1.3). */
static int write_torn_meshes(run_state *s) {
    const rbc_api_v1 *api = s->api;
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        cloth_output *o = &s->outputs[i];
        if (!o->torn_obj_path)
            continue;
        const size_t floats = (size_t)s->scene.cloths[i].vertex_count * 3;
        size_t count = 0;
        rbc_result r = api->cloth_read_positions(s->instance.world, s->instance.cloths[i],
                                                 s->positions, s->positions_capacity, NULL);
        if (r == RBC_OK)
            r = api->cloth_get_quads(s->instance.world, s->instance.cloths[i], NULL, 0, &count);
        if (r != RBC_OK)
            return report_api(api, r);
        uint32_t *quads = malloc((count ? count : 1) * sizeof *quads);
        if (!quads)
            return out_of_memory(s);
        r = api->cloth_get_quads(s->instance.world, s->instance.cloths[i], quads, count, &count);
        if (r == RBC_OK)
            r = api->write_obj(o->torn_obj_path, s->positions, (uint32_t)(floats / 3), quads,
                               (uint32_t)(count / 4));
        free(quads);
        if (r != RBC_OK)
            return report_api(api, r);
        o->quads_remaining = (uint32_t)(count / 4);
    }
    return 0;
}

static int simulate_frames(run_state *s, uint32_t frames, int show_progress, double start,
                           double *last_draw_io, char *err, FILE *fs);

static int simulate(run_state *s) {
    const int show_progress = !s->options->quiet && isatty(STDERR_FILENO);
    const uint32_t frames = s->scene.frames;
    double start = now_seconds(), last_draw = 0.0;
    char err[RBC_SCENE_ERROR_MAX];
    FILE *fs = NULL;
    if (s->options->frame_stats) {
        fs = fopen(s->options->frame_stats, "w");
        if (!fs) {
            fprintf(stderr, "rbcloth: cannot write %s: %s\n", s->options->frame_stats,
                    strerror(errno));
            return 1;
        }
        fputs("frame,step_ms,collide_ms,kinetic_energy,potential_energy,energy_budget,"
              "energy_removed,collider_contacts,cloth_contacts,max_strain,strain_rms,"
              "cloth_contact_frozen,cloth_contact_capped\n",
              fs);
    }
    int rc = simulate_frames(s, frames, show_progress, start, &last_draw, err, fs);
    if (fs && fclose(fs) != 0 && rc == 0) {
        fprintf(stderr, "rbcloth: cannot write %s\n", s->options->frame_stats);
        rc = 1;
    }
    return rc;
}

static int simulate_frames(run_state *s, uint32_t frames, int show_progress, double start,
                           double *last_draw_io, char *err, FILE *fs) {
    const rbc_api_v1 *api = s->api;
    double last_draw = *last_draw_io;

    for (uint32_t frame = 0; frame < frames; ++frame) {
        if (g_stop_signal)
            return 1; /* cli_run says so, once the temporaries are gone */
        /* Moving colliders and drags to where they are at the end of this frame. */
        rbc_result r = rbc_scene_apply_frame(api, &s->scene, &s->instance, frame, err,
                                             RBC_SCENE_ERROR_MAX);
        if (r != RBC_OK)
            return report(api, r, err);
        r = api->world_step(s->instance.world, s->scene.dt);
        if (r != RBC_OK)
            return report_api(api, r);
        /* Timings every frame; Eq. 7 and the energies (a pass over the cloth) once,
         * after the last frame. */
        memset(&s->stats, 0, sizeof s->stats);
        s->stats.struct_size = sizeof s->stats;
        s->stats.skip_measures = frame + 1 < frames && !fs;
        r = api->world_get_stats(s->instance.world, &s->stats);
        if (r != RBC_OK)
            return report_api(api, r);
        if (fs) {
            const rbc_world_stats *st = &s->stats;
            fprintf(fs, "%u,%.4f,%.4f,%.9g,%.9g,%.9g,%.9g,%u,%u,%.6g,%.6g,%u,%u\n", frame + 1,
                    st->step_ms, st->collide_ms, st->kinetic_energy, st->potential_energy,
                    st->energy_budget, st->energy_removed, st->collider_contacts,
                    st->cloth_contacts, st->max_strain, st->strain_rms,
                    st->cloth_contact_frozen, st->cloth_contact_capped);
            fflush(fs);
        }
        cli_timings_add(&s->timings, &s->stats);
        if (s->stats.iteration_mode == RBC_ITERATE_TARGET) {
            const rbc_world_stats *st = &s->stats;
            if (frame == 0 || st->substeps < s->target.substeps_min)
                s->target.substeps_min = st->substeps;
            if (st->substeps > s->target.substeps_max) s->target.substeps_max = st->substeps;
            if (st->linear_iterations > s->target.linear_max)
                s->target.linear_max = st->linear_iterations;
            s->target.substeps_sum += st->substeps;
            s->target.linear_sum += st->linear_iterations;
            s->target.met += st->target_met;
            if (st->target_reached > s->target.reached_max)
                s->target.reached_max = st->target_reached;
        }

        for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
            size_t written = 0;
            r = api->cloth_read_positions(s->instance.world, s->instance.cloths[i], s->positions,
                                          s->positions_capacity, &written);
            if (r != RBC_OK)
                return report_api(api, r);
            if (written != (size_t)s->scene.cloths[i].vertex_count * 3) {
                char message[160];
                snprintf(message, sizeof message,
                         "cloth %s: read %zu floats of positions, expected %zu",
                         s->scene.cloths[i].name, written,
                         (size_t)s->scene.cloths[i].vertex_count * 3);
                return report(api, RBC_ERR_INVALID_ARGUMENT, message);
            }
            r = api->cache_write_frame(s->outputs[i].cache, s->positions);
            if (r != RBC_OK)
                return report_api(api, r);
            if (view_frame(s, i, 0.0))
                return 1;
        }
        if (view_frame(s, UINT32_MAX, (double)(frame + 1) * s->scene.dt))
            return 1;
        s->frames_done = frame + 1;

        double now = now_seconds();
        if (show_progress && (now - last_draw >= 0.1 || frame + 1 == frames)) {
            progress_draw(frame + 1, frames, s->stats.step_ms);
            last_draw = now;
        }
    }
    *last_draw_io = last_draw;
    s->wall_seconds = now_seconds() - start;
    progress_clear();
    if (g_stop_signal)
        return 1;
    if (write_torn_meshes(s))
        return 1;

    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        rbc_result r = api->cache_finish(s->outputs[i].cache);
        s->outputs[i].cache = 0; /* finish destroys the writer, whatever its result */
        if (r != RBC_OK)
            return report_api(api, r);
    }
    return finish_view(s);
}

/* ------------------------------------------------------------------------- */
/* Summary                                                                   */
/* ------------------------------------------------------------------------- */

/* cJSON's Add* return NULL when out of memory: remember it instead of checking
 * each call. */
typedef struct json_builder {
    int failed;
} json_builder;

static cJSON *jcheck(json_builder *b, cJSON *item) {
    if (!item)
        b->failed = 1;
    return item;
}

static void jnum(json_builder *b, cJSON *obj, const char *name, double value) {
    jcheck(b, obj ? cJSON_AddNumberToObject(obj, name, value) : NULL);
}

static void jstr(json_builder *b, cJSON *obj, const char *name, const char *value) {
    jcheck(b, obj ? (value ? cJSON_AddStringToObject(obj, name, value)
                           : cJSON_AddNullToObject(obj, name))
                  : NULL);
}

static void jarray_str(json_builder *b, cJSON *array, const char *value) {
    cJSON *item = jcheck(b, cJSON_CreateString(value));
    if (item && array && !cJSON_AddItemToArray(array, item)) {
        cJSON_Delete(item);
        b->failed = 1;
    } else if (item && !array) {
        cJSON_Delete(item);
    }
}

static cJSON *build_summary(const run_state *s, json_builder *b) {
    const rbc_scene *sc = &s->scene;
    const rbc_world_stats *st = &s->stats;
    const rbc_api_v1 *api = s->api;
    cJSON *root = jcheck(b, cJSON_CreateObject());
    if (!root)
        return NULL;

    jstr(b, root, "scene", sc->name);
    jstr(b, root, "scene_file", s->options->scene_path); /* null: the built-in default */
    cJSON *plugin = jcheck(b, cJSON_AddObjectToObject(root, "plugin"));
    char abi[32];
    uint32_t v = api->abi_version_fn();
    snprintf(abi, sizeof abi, "%u.%u", v >> 16, v & 0xFFFFu);
    jstr(b, plugin, "path", s->plugin->path);
    jstr(b, plugin, "version", api->version_string());
    jstr(b, plugin, "abi_version", abi);

    jstr(b, root, "backend", backend_name(st->backend));
    jnum(b, root, "particles", st->particle_count);
    jnum(b, root, "springs", st->spring_count);
    jnum(b, root, "colors", st->color_count);
    jnum(b, root, "threads", st->thread_count);
    jnum(b, root, "frames", s->frames_done);
    jnum(b, root, "dt", float_as_decimal(sc->dt));
    jnum(b, root, "substeps", sc->world.substeps);
    jnum(b, root, "nonlinear_iterations", sc->world.nonlinear_iterations);
    jnum(b, root, "linear_iterations", sc->world.linear_iterations);
    cJSON_AddStringToObject(root, "solver", rbc_scene_solver_names[sc->world.solver.solver]);
    cJSON_AddStringToObject(root, "iteration_mode", rbc_scene_mode_names[sc->world.solver.mode]);
    jnum(b, root, "colliders", st->collider_count);
    if (sc->world.solver.mode == RBC_ITERATE_TARGET && s->frames_done) {
        /* What the target mode chose and reached, over the frames. */
        const rbc_solver_def *sd = &sc->world.solver;
        cJSON *t = jcheck(b, cJSON_AddObjectToObject(root, "target"));
        jnum(b, t, "target_strain", float_as_decimal(sd->target_strain));
        jnum(b, t, "max_substeps", sd->max_substeps);
        jnum(b, t, "max_linear_iterations", sd->max_linear_iterations);
        jnum(b, t, "frames_met", s->target.met);
        jnum(b, t, "frames_missed", (double)st->target_missed_steps);
        jnum(b, t, "frames_missed_at_cap", (double)st->target_capped_steps);
        jnum(b, t, "substeps_min", s->target.substeps_min);
        jnum(b, t, "substeps_max", s->target.substeps_max);
        jnum(b, t, "substeps_mean", (double)s->target.substeps_sum / s->frames_done);
        jnum(b, t, "linear_iterations_mean", (double)s->target.linear_sum / s->frames_done);
        jnum(b, t, "linear_iterations_max", s->target.linear_max);
        jnum(b, t, "reached_last", st->target_reached);
        jnum(b, t, "reached_max", s->target.reached_max);
    }

    cJSON *cloths = jcheck(b, cJSON_AddArrayToObject(root, "cloths"));
    for (uint32_t i = 0; cloths && i < sc->cloth_count; ++i) {
        cJSON *c = jcheck(b, cJSON_CreateObject());
        if (!c)
            break;
        if (!cJSON_AddItemToArray(cloths, c)) {
            cJSON_Delete(c);
            b->failed = 1;
            break;
        }
        jstr(b, c, "name", sc->cloths[i].name);
        jnum(b, c, "vertices", sc->cloths[i].vertex_count);
        jnum(b, c, "quads", sc->cloths[i].quad_count);
        jnum(b, c, "springs", s->outputs[i].spring_count);
        jnum(b, c, "colors", s->outputs[i].color_count);
        jnum(b, c, "pins", sc->cloths[i].pin_count);
        jstr(b, c, "obj", s->outputs[i].obj_path);
        jstr(b, c, "pc2", s->outputs[i].pc2_path);
        if (s->outputs[i].torn_obj_path) {
            jstr(b, c, "torn_obj", s->outputs[i].torn_obj_path);
            jnum(b, c, "quads_remaining", s->outputs[i].quads_remaining);
        }
    }

    cJSON *timing = jcheck(b, cJSON_AddObjectToObject(root, "ms_per_frame"));
    for (int stage = 0; timing && stage < CLI_STAGE_COUNT; ++stage) {
        double median, mean;
        cli_timings_summary(&s->timings, (cli_stage)stage, &median, &mean);
        cJSON *entry = jcheck(b, cJSON_AddObjectToObject(timing, cli_stage_names[stage]));
        jnum(b, entry, "median", median);
        jnum(b, entry, "mean", mean);
    }
    jnum(b, root, "wall_seconds", s->wall_seconds);

    cJSON *final = jcheck(b, cJSON_AddObjectToObject(root, "final"));
    jnum(b, final, "error_eq7", st->error_eq7);
    jnum(b, final, "max_strain", st->max_strain);
    jnum(b, final, "strain_rms", st->strain_rms);
    jnum(b, final, "kinetic_energy", st->kinetic_energy);
    jnum(b, final, "potential_energy", st->potential_energy);
    jnum(b, final, "energy_budget", st->energy_budget);
    jnum(b, final, "energy_clamped_steps", (double)st->energy_clamped_steps);
    jnum(b, final, "strain_warning_steps", (double)st->strain_warning_steps);
    jnum(b, final, "memory_bytes", (double)st->memory_bytes);
    if (any_torn_output(s))
        jnum(b, final, "torn_springs", (double)st->torn_springs);

    cJSON *outputs = jcheck(b, cJSON_AddObjectToObject(root, "outputs"));
    cJSON *objs = outputs ? jcheck(b, cJSON_AddArrayToObject(outputs, "obj")) : NULL;
    cJSON *pc2s = outputs ? jcheck(b, cJSON_AddArrayToObject(outputs, "pc2")) : NULL;
    for (uint32_t i = 0; i < sc->cloth_count; ++i) {
        jarray_str(b, objs, s->outputs[i].obj_path);
        jarray_str(b, pc2s, s->outputs[i].pc2_path);
    }
    jstr(b, outputs, "summary", s->summary_path);
    if (s->png_path) {
        jstr(b, outputs, "png", s->png_path);
        jstr(b, outputs, "html", s->html_path);
    }
    return root;
}

/* The outputs on disk before the summary that lists them: each file, then the folder. */
static int sync_outputs(const run_state *s) {
    char err[1100];
    const char *extra[2] = {s->png_path, s->html_path};
    int rc = 0;
    for (uint32_t i = 0; rc == 0 && i < s->scene.cloth_count; ++i) {
        const cloth_output *o = &s->outputs[i];
        rc = fs_sync(o->obj_path, err, sizeof err) || fs_sync(o->pc2_path, err, sizeof err) ||
             (o->torn_obj_path && fs_sync(o->torn_obj_path, err, sizeof err));
    }
    for (int k = 0; rc == 0 && k < 2; ++k)
        rc = extra[k] && fs_sync(extra[k], err, sizeof err);
    if (rc == 0)
        rc = fs_sync(s->options->out_dir, err, sizeof err);
    return rc ? report(s->api, RBC_ERR_IO, err) : 0;
}

static int write_summary(const run_state *s) {
    if (sync_outputs(s))
        return 1;
    json_builder b = {0};
    cJSON *root = build_summary(s, &b);
    char *text = root && !b.failed ? cJSON_Print(root) : NULL;
    cJSON_Delete(root);
    if (!text)
        return out_of_memory(s);
    char err[512];
    size_t len = strlen(text);
    text[len] = '\n'; /* cJSON_Print's NUL becomes the final newline */
    int rc = fs_write_atomic(s->summary_path, text, len + 1, err, sizeof err);
    cJSON_free(text);
    if (rc)
        return report(s->api, RBC_ERR_IO, err);
    return 0;
}

static void print_table(const run_state *s) {
    const rbc_scene *sc = &s->scene;
    const rbc_world_stats *st = &s->stats;
    printf("%s: %u frames of %g ms, %u particles, %u springs, %u colors, %s backend, %u "
           "thread%s\n",
           sc->name, s->frames_done, 1e3 * float_as_decimal(sc->dt), st->particle_count,
           st->spring_count, st->color_count, backend_name(st->backend), st->thread_count,
           st->thread_count == 1 ? "" : "s");
    printf("  solver %s, iterations %s: %u substep(s) x %u non-linear x %u linear per frame "
           "(last frame)\n",
           rbc_scene_solver_names[sc->world.solver.solver],
           rbc_scene_mode_names[sc->world.solver.mode], st->substeps,
           st->substeps ? st->nonlinear_iterations / st->substeps : 0,
           st->nonlinear_iterations ? st->linear_iterations / st->nonlinear_iterations : 0);
    if (sc->world.solver.mode == RBC_ITERATE_TARGET && s->frames_done) {
        const rbc_solver_def *sd = &sc->world.solver;
        printf("  target RMS strain %g within %u substeps x %u iterations: met in %u of %u "
               "frames (%llu missed, %llu at the cap); reached %.4g last, %.4g at worst\n",
               (double)sd->target_strain, sd->max_substeps, sd->max_linear_iterations,
               s->target.met, s->frames_done, (unsigned long long)st->target_missed_steps,
               (unsigned long long)st->target_capped_steps, st->target_reached,
               s->target.reached_max);
        printf("  chosen: substeps %u..%u (mean %.2f), linear iterations per frame %.1f mean, "
               "%u at most\n",
               s->target.substeps_min, s->target.substeps_max,
               (double)s->target.substeps_sum / s->frames_done,
               (double)s->target.linear_sum / s->frames_done, s->target.linear_max);
    }
    printf("  %-10s %12s %12s\n", "stage", "median ms", "mean ms");
    for (int stage = 0; stage < CLI_STAGE_COUNT; ++stage) {
        double median, mean;
        cli_timings_summary(&s->timings, (cli_stage)stage, &median, &mean);
        printf("  %-10s %12.4f %12.4f\n", cli_stage_names[stage], median, mean);
    }
    printf("  Eq. 7 error %.6e m^2, max strain %.4e, RMS strain %.4e\n", st->error_eq7,
           st->max_strain, st->strain_rms);
    printf("  energy: kinetic %.6g J, potential %.6g J (kinetic + gravity budget %.6g J); "
           "steps clamped by the energy guard: %llu\n",
           st->kinetic_energy, st->potential_energy, st->energy_budget,
           (unsigned long long)st->energy_clamped_steps);
    if (st->strain_warning_steps)
        printf("  steps with a spring past the strain warning (not cloth): %llu of %u\n",
               (unsigned long long)st->strain_warning_steps, s->frames_done);
    printf("  memory %.2f MB (%.0f bytes per particle)\n", (double)st->memory_bytes / 1e6,
           st->particle_count ? (double)st->memory_bytes / st->particle_count : 0.0);
    if (any_torn_output(s))
        printf("  springs torn: %llu\n", (unsigned long long)st->torn_springs);
    for (uint32_t i = 0; i < sc->cloth_count; ++i) {
        printf("  wrote %s, %s\n", s->outputs[i].obj_path, s->outputs[i].pc2_path);
        if (s->outputs[i].torn_obj_path)
            printf("  wrote %s (last frame, %u quads remain of %u)\n",
                   s->outputs[i].torn_obj_path, s->outputs[i].quads_remaining,
                   sc->cloths[i].quad_count);
    }
    printf("  wrote %s\n", s->summary_path);
    if (s->png_path)
        printf("  wrote %s (the last frame) and %s (open it in a browser)\n", s->png_path,
               s->html_path);
}

/* ------------------------------------------------------------------------- */

/* malloc'd path + suffix, or NULL. */
static char *with_suffix(const char *path, const char *suffix) {
    size_t n = strlen(path) + strlen(suffix) + 1;
    char *r = malloc(n);
    if (r)
        snprintf(r, n, "%s%s", path, suffix);
    return r;
}

/* Every temporary file the run may leave (g_tmp_paths), once the outputs are known. */
static int list_temporaries(const run_state *s) {
    const size_t most = 3 * (size_t)s->scene.cloth_count + 3;
    char **list = calloc(most, sizeof *list);
    if (!list)
        return out_of_memory(s);
    size_t n = 0;
    char pid[32];
    snprintf(pid, sizeof pid, ".%ld.tmp", (long)getpid());
    for (uint32_t i = 0; i < s->scene.cloth_count; ++i) {
        const cloth_output *o = &s->outputs[i];
        list[n++] = with_suffix(o->obj_path, ".tmp");
        list[n++] = with_suffix(o->pc2_path, ".tmp");
        if (o->torn_obj_path)
            list[n++] = with_suffix(o->torn_obj_path, ".tmp");
    }
    if (s->png_path) {
        list[n++] = with_suffix(s->png_path, ".tmp");
        list[n++] = with_suffix(s->html_path, ".tmp");
    }
    list[n++] = with_suffix(s->summary_path, pid);
    for (size_t k = 0; k < n; ++k)
        if (!list[k]) {
            for (size_t i = 0; i < n; ++i) free(list[i]);
            free(list);
            return out_of_memory(s);
        }
    g_tmp_paths = list;
    g_tmp_count = n; /* last: the handler reads the count, then the list */
    return 0;
}

int cli_run(const cli_plugin *plugin, const cli_run_options *options) {
    run_state s;
    memset(&s, 0, sizeof s);
    s.plugin = plugin;
    s.api = plugin->api;
    s.options = options;
    s.lock_fds[0] = s.lock_fds[1] = -1;

    struct sigaction sa, old_int, old_term;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old_int);
    sigaction(SIGTERM, &sa, &old_term);

    /* Each step returns 0, or 1 after saying why: the first to fail ends the run. */
    int rc = load_scene(&s) || plan_outputs(&s) || list_temporaries(&s) || create_world(&s) ||
             start_outputs(&s) || start_view(&s) || simulate(&s) || write_summary(&s);
    if (!rc && !options->quiet)
        print_table(&s);
    const uint32_t frames_done = s.frames_done, frames = s.scene.frames;
    run_state_free(&s); /* destroys unfinished caches, which removes their files */
    const int sig = g_stop_signal;
    sigaction(SIGINT, &old_int, NULL);
    sigaction(SIGTERM, &old_term, NULL);
    char **list = g_tmp_paths;
    const size_t count = g_tmp_count;
    g_tmp_count = 0;
    g_tmp_paths = NULL;
    if (sig && rc) {
        /* What the plugin's and the viewer's writers left, whatever they were doing. */
        for (size_t k = 0; k < count; ++k)
            unlink(list[k]);
        progress_clear();
        fprintf(stderr, "rbcloth: stopped by %s after %u of %u frames: no cache or summary "
                "written, temporary files removed\n", sig == SIGINT ? "SIGINT" : "SIGTERM",
                frames_done, frames);
    }
    for (size_t k = 0; k < count; ++k)
        free(list[k]);
    free(list);
    return rc;
}
