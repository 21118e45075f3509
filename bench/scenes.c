/* scenes.c -- `rbcloth bench scenes`: the paper's test cases (Fig. 1, Sec. 5.2)
 * as shipped in samples/scenes, timed with their collision handling, beside the
 * figures the paper reports for them (measured elsewhere: a GTX 970 GPU).
 *
 * Scenes: cloth_on_chair (Fig. 1 middle), four_layers_sphere (Fig. 1 right, Fig. 6),
 * funnel (Fig. 7), cannonballs_tearing (Fig. 8), and for reference cloth_on_sphere
 * and hanging_cloth (the paper's Fig. 4 cloth). Each runs as `rbcloth run` would run
 * it (rbc_scene_instantiate, then per frame rbc_scene_apply_frame and rbc_world_step)
 * with 1 and N threads (default N = 2), writing nothing but timings:
 *
 *   - the first BENCH_WARMUP frames are simulated but not measured (first touch,
 *     lazily sized buffers); then F frames (default: the scene's frames minus the
 *     warm-up; --frames F; --quick 10, and without the crumpled cloth, which takes
 *     seconds a frame);
 *   - per frame: stats.step_ms (one rbc_world_step: all substeps, collisions
 *     included), the stages (integrate, local, global, collide, other), the contacts
 *     of the last substep (stats.collider_contacts, stats.cloth_contacts), and the
 *     host's wall time around apply + step as a cross-check;
 *   - reported: median and p90 (nearest rank) of ms per step and per substep (step /
 *     stats.substeps), the median of each stage, frames per second (1000 / median
 *     step ms), median contacts, springs torn by the end (stats.torn_springs), the
 *     vertices cloth contact's fail-safe put into impact zones over the measured
 *     frames (stats.cloth_contact_frozen, ABI 1.5: 0 where the contact solve alone
 *     kept every layer in order), and the deepest penetration of a cloth vertex into an analytic collider (sphere,
 *     plane, capsule, box; meshes are skipped) at the last frame, in mm: how far
 *     inside the solid, not counting thickness.
 *
 * The paper's timings are of a GTX 970 (2015) and are quoted as measured there, not
 * reproduced: per time step (= one substep here) for the chair and the four layers,
 * per frame of 8 substeps for the funnel and four layers (35 fps) and the cannonballs
 * (above 60 fps, an upper bound on ms per frame). Outputs in DIR: scenes.csv,
 * scenes.md, and scenes.png (gnuplot, from scenes_plot.csv and scenes.gp).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "bench.h"
#include "fsutil.h"
#include "scene.h"

enum { BENCH_WARMUP = 2, QUICK_FRAMES = 10, MAX_THREAD_COUNTS = 2 };

/// Wall-clock seconds after which a run stops (after its current frame, with at
/// least one measured frame): a scene whose contact handling degenerates (steps of
/// many seconds) must not hold the bench for hours. The row says where it stopped.
#define BENCH_RUN_SECONDS 60.0

#ifndef RBC_SOURCE_SCENES_DIR
#define RBC_SOURCE_SCENES_DIR "samples/scenes"
#endif

/* A scene of the bench and what the paper says of it. */
typedef struct scene_entry {
    const char *file;
    /// The paper's figure, as text (no commas: it goes into the CSV).
    const char *paper;
    /// The paper's ms per time step (one substep here) and per frame; NaN = not given.
    double paper_ms_substep, paper_ms_frame;
    /// Seconds a frame today: left out under --quick (the tests' smoke runs, which
    /// also run under the sanitizers).
    int heavy;
} scene_entry;

static const scene_entry entries[] = {
    {"cloth_on_chair.json", "Fig. 1 middle: 19K springs; 2.5 ms per time step", 2.5, NAN, 0},
    {"four_layers_sphere.json",
     "Fig. 1 right: 32K springs; 4.1 ms per time step. Fig. 6: 16K particles; 35 fps at 8 "
     "substeps of 2 ms",
     4.1, 1000.0 / 35.0, 0},
    {"funnel.json", "Fig. 7: 30K particles; 59K constraints; 35 fps at 8 substeps of 2 ms",
     1000.0 / 35.0 / 8.0, 1000.0 / 35.0, 0},
    {"cannonballs_tearing.json", "Fig. 8: 4K particles; 8K springs; never below 60 fps", NAN,
     1000.0 / 60.0, 0},
    {"crumpled_cloth.json", "not in the paper; issue 23 asks for at most 100 ms a frame on 2 threads",
     NAN, NAN, 1},
    {"cloth_on_sphere.json", "(reference; not in the paper)", NAN, NAN, 0},
    {"hanging_cloth_paper.json", "Fig. 4: 10K particles; 11 iterations within a 2 ms budget", NAN,
     NAN, 0},
};
enum { ENTRY_COUNT = sizeof entries / sizeof entries[0] };

typedef struct scene_row {
    const scene_entry *entry;
    char name[72];
    uint32_t threads_requested, threads;
    uint32_t frames, substeps, particles, springs, colliders;
    double step_median, step_p90, substep_median, substep_p90;
    double integrate, local, global, collide, other, wall_median;
    double collider_contacts, cloth_contacts;
    uint64_t torn_springs;
    uint64_t failsafe_vertices; /* stats.cloth_contact_frozen over the measured frames */
    /// mm; NaN when the scene has no analytic collider.
    double max_penetration_mm;
    /// A failure: the figures are over the frames before it.
    char note[RBC_SCENE_ERROR_MAX + 160];
} scene_row;

typedef struct scenes_ctx {
    bench_run run;
    char scenes_dir[1024];
    uint32_t thread_list[MAX_THREAD_COUNTS], thread_count;
    scene_row rows[ENTRY_COUNT * MAX_THREAD_COUNTS];
    uint32_t row_count, failed_rows;
    /// Per-frame samples of the run in progress: step, integrate, local, global,
    /// collide, other, wall, collider contacts, cloth contacts.
    double *samples[9];
    uint32_t sample_cap;
    char cpu[256];
    long cores;
    double load_start, load_end;
} scenes_ctx;

static int out_of_memory(void) { return bench_out_of_memory("scenes"); }

/* ------------------------------------------------------------------------- */
/* Set-up                                                                    */
/* ------------------------------------------------------------------------- */

/* The library must have the ABI 1.3 entries (contact, tearing, wind, mesh
 * triangles): the four paper scenes need them. */
static int require_v1_3(const cli_plugin *plugin) {
    const rbc_api_v1 *api = plugin->api;
    uint32_t abi = api->abi_version_fn();
    const char *missing = NULL;
    if (api->struct_size < sizeof(rbc_api_v1))
        missing = "the 1.3 entries";
    else if (!api->world_set_contact_callback)
        missing = "world_set_contact_callback";
    else if (!api->cloth_cut)
        missing = "cloth_cut";
    else if (!api->cloth_get_quads)
        missing = "cloth_get_quads";
    else if (!api->world_set_wind)
        missing = "world_set_wind";
    else if (!api->mesh_get_triangles)
        missing = "mesh_get_triangles";
    if ((abi >> 16) != RBC_ABI_VERSION_MAJOR || (abi & 0xFFFFu) < 3 || missing) {
        fprintf(stderr,
                "rbcloth: the scenes bench needs ABI 1.3 (boxes, meshes, friction, cloth contact, "
                "tearing); %s reports ABI %u.%u%s%s\n",
                plugin->path, abi >> 16, abi & 0xFFFFu, missing ? " and has no " : "",
                missing ? missing : "");
        return -1;
    }
    return 0;
}

static int is_dir(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

/* $RBC_SCENES_DIR, else ./samples/scenes, else the source tree's (compiled in). */
static int find_scenes_dir(scenes_ctx *ctx) {
    const char *env = getenv("RBC_SCENES_DIR");
    const char *candidates[] = {env && env[0] ? env : NULL, "samples/scenes", RBC_SOURCE_SCENES_DIR};
    for (size_t k = 0; k < sizeof candidates / sizeof candidates[0]; ++k) {
        if (!candidates[k] || !is_dir(candidates[k]))
            continue;
        char probe[1100];
        snprintf(probe, sizeof probe, "%s/%s", candidates[k], entries[0].file);
        if (access(probe, R_OK) == 0) {
            snprintf(ctx->scenes_dir, sizeof ctx->scenes_dir, "%s", candidates[k]);
            return 0;
        }
    }
    fprintf(stderr, "rbcloth: bench scenes: cannot find the sample scenes (%s); set "
                    "RBC_SCENES_DIR to samples/scenes of the source tree\n",
            entries[0].file);
    return -1;
}

/* ------------------------------------------------------------------------- */
/* Penetration                                                               */
/* ------------------------------------------------------------------------- */

/* p in the collider's frame: R^T (p - origin), R from the unit quaternion q. */
static void to_local(const float origin[3], const float q[4], const float p[3], double out[3]) {
    double d[3] = {(double)p[0] - origin[0], (double)p[1] - origin[1], (double)p[2] - origin[2]};
    double x = q[0], y = q[1], z = q[2], w = q[3];
    /* Rows of R^T are the columns of R. */
    double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)},
                      {2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)},
                      {2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)}};
    for (int i = 0; i < 3; ++i)
        out[i] = r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2];
}

/* Signed distance from the collider's surface (negative inside), metres; NaN for
 * shapes without a closed form here (meshes). */
static double signed_distance(const rbc_scene_collider *c, const double p[3]) {
    switch (c->shape) {
    case RBC_SHAPE_SPHERE:
        return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - c->radius;
    case RBC_SHAPE_PLANE:
        return p[1];
    case RBC_SHAPE_CAPSULE: {
        double h = c->half_extents[1], y = p[1] < -h ? -h : p[1] > h ? h : p[1];
        double dy = p[1] - y;
        return sqrt(p[0] * p[0] + dy * dy + p[2] * p[2]) - c->radius;
    }
    case RBC_SHAPE_BOX: {
        double q[3], outside = 0.0, inside = -INFINITY;
        for (int i = 0; i < 3; ++i) {
            q[i] = fabs(p[i]) - c->half_extents[i];
            outside += q[i] > 0.0 ? q[i] * q[i] : 0.0;
            inside = fmax(inside, q[i]);
        }
        return sqrt(outside) + fmin(inside, 0.0);
    }
    default:
        return NAN;
    }
}

/* The deepest vertex inside an analytic collider at time t, mm (NaN: none to check). */
static double max_penetration_mm(const scenes_ctx *ctx, const rbc_scene *s,
                                 const rbc_scene_instance *inst, double t, float *xyz,
                                 size_t capacity) {
    double deepest = NAN;
    for (uint32_t i = 0; i < s->cloth_count; ++i) {
        size_t written = 0;
        if (ctx->run.api->cloth_read_positions(inst->world, inst->cloths[i], xyz, capacity,
                                               &written) != RBC_OK)
            return NAN;
        for (uint32_t k = 0; k < s->collider_count; ++k) {
            const rbc_scene_collider *c = &s->colliders[k];
            if (c->shape == RBC_SHAPE_TRIANGLE_MESH)
                continue;
            float origin[3], rotation[4];
            rbc_scene_collider_pose(c, t, origin, rotation);
            if (isnan(deepest))
                deepest = 0.0;
            for (size_t v = 0; v + 3 <= written; v += 3) {
                double local[3];
                to_local(origin, rotation, xyz + v, local);
                double d = signed_distance(c, local);
                if (d < 0.0 && -d > deepest)
                    deepest = -d;
            }
        }
    }
    return 1e3 * deepest;
}

/* ------------------------------------------------------------------------- */
/* Measuring                                                                 */
/* ------------------------------------------------------------------------- */

/* Nearest-rank p-quantile of v[0..n) (sorts v). */
static double quantile(double *v, uint32_t n, double p) {
    if (n == 0)
        return NAN;
    bench_sort(v, n);
    uint32_t rank = (uint32_t)ceil(p * n);
    return v[rank ? rank - 1 : 0];
}

/* Replace commas (CSV) and newlines in a message. */
static void sanitize(char *text) {
    for (char *p = text; *p; ++p)
        if (*p == ',' || *p == '\n' || *p == '\r')
            *p = ';';
}

/* Run one scene with `threads` threads into row. Returns 0 (a failing step or a scene
 * the library refuses is a note on the row) or 1 (out of memory). */
static int run_scene(scenes_ctx *ctx, const scene_entry *e, uint32_t threads, scene_row *row) {
    const rbc_api_v1 *api = ctx->run.api;
    memset(row, 0, sizeof *row);
    row->entry = e;
    row->threads_requested = threads;
    row->max_penetration_mm = NAN;
    snprintf(row->name, sizeof row->name, "%.*s", (int)(strcspn(e->file, ".")), e->file);
    row->step_median = row->step_p90 = row->substep_median = row->substep_p90 = NAN;
    row->integrate = row->local = row->global = row->collide = row->other = NAN;
    row->wall_median = row->collider_contacts = row->cloth_contacts = NAN;

    char path[1200], err[RBC_SCENE_ERROR_MAX];
    snprintf(path, sizeof path, "%s/%s", ctx->scenes_dir, e->file);
    rbc_scene s;
    if (rbc_scene_load_file(path, &s, err, sizeof err)) {
        snprintf(row->note, sizeof row->note, "%s", err);
        sanitize(row->note);
        fprintf(stderr, "rbcloth: bench scenes: %s\n", err);
        ++ctx->failed_rows;
        return 0;
    }
    s.world.thread_count = threads;
    uint32_t measured;
    if (ctx->run.opt->frames > 0)
        measured = (uint32_t)ctx->run.opt->frames;
    else if (ctx->run.opt->quick)
        measured = QUICK_FRAMES;
    else
        measured = s.frames > BENCH_WARMUP ? s.frames - BENCH_WARMUP : 1;
    const uint32_t total = BENCH_WARMUP + measured;
    fprintf(stderr, "rbcloth: bench scenes: %s, %u thread%s, %u frames ...\n", row->name, threads,
            threads == 1 ? "" : "s", total);

    rbc_scene_instance inst;
    rbc_result r = rbc_scene_instantiate(api, &s, NULL, NULL, &inst, err, sizeof err);
    if (r != RBC_OK) {
        snprintf(row->note, sizeof row->note, "%s: %.*s", api->result_string(r),
                 RBC_SCENE_ERROR_MAX, err);
        sanitize(row->note);
        fprintf(stderr, "rbcloth: bench scenes: %s: %s\n", row->name, row->note);
        rbc_scene_free(&s);
        ++ctx->failed_rows;
        return 0;
    }
    if (bench_reserve_samples(ctx->samples, 9, &ctx->sample_cap, measured)) {
        rbc_scene_instance_destroy(api, &inst);
        rbc_scene_free(&s);
        return out_of_memory();
    }
    double **v = ctx->samples;
    uint32_t done = 0, frame = 0;
    rbc_world_stats st;
    const double run_start = bench_now();
    for (; frame < total; ++frame) {
        if (done > 0 && bench_now() - run_start > BENCH_RUN_SECONDS) {
            snprintf(row->note, sizeof row->note,
                     "stopped after %u of %u frames (%.2f s of the scene): the run took more "
                     "than %.0f s",
                     frame, total, (double)s.dt * frame, BENCH_RUN_SECONDS);
            fprintf(stderr, "rbcloth: bench scenes: %s: %s\n", row->name, row->note);
            break;
        }
        double t0 = bench_now();
        r = rbc_scene_apply_frame(api, &s, &inst, frame, err, sizeof err);
        if (r == RBC_OK && (r = api->world_step(inst.world, s.dt)) != RBC_OK)
            snprintf(err, sizeof err, "%s", api->last_error());
        double wall = 1e3 * (bench_now() - t0);
        if (r != RBC_OK) {
            snprintf(row->note, sizeof row->note, "frame %u: %s: %.*s", frame,
                     api->result_string(r), RBC_SCENE_ERROR_MAX, err);
            sanitize(row->note);
            fprintf(stderr, "rbcloth: bench scenes: %s: %s; %u frames measured\n", row->name,
                    row->note, done);
            break;
        }
        memset(&st, 0, sizeof st);
        st.struct_size = sizeof st;
        st.skip_measures = 1;
        if ((r = api->world_get_stats(inst.world, &st)) != RBC_OK) {
            snprintf(row->note, sizeof row->note, "reading stats: %s", api->last_error());
            sanitize(row->note);
            break;
        }
        row->substeps = st.substeps;
        if (frame < BENCH_WARMUP)
            continue;
        v[0][done] = st.step_ms;
        v[1][done] = st.integrate_ms;
        v[2][done] = st.local_ms;
        v[3][done] = st.global_ms;
        v[4][done] = st.collide_ms;
        v[5][done] = st.other_ms;
        v[6][done] = wall;
        v[7][done] = st.collider_contacts;
        v[8][done] = st.cloth_contacts;
        row->failsafe_vertices += st.cloth_contact_frozen;
        ++done;
    }

    memset(&st, 0, sizeof st);
    st.struct_size = sizeof st;
    st.skip_measures = 1;
    if (api->world_get_stats(inst.world, &st) == RBC_OK) {
        row->threads = st.thread_count;
        row->particles = st.particle_count;
        row->springs = st.spring_count;
        row->colliders = st.collider_count;
        row->torn_springs = st.torn_springs;
    }
    size_t capacity = 0;
    for (uint32_t i = 0; i < s.cloth_count; ++i)
        if ((size_t)s.cloths[i].vertex_count * 3 > capacity)
            capacity = (size_t)s.cloths[i].vertex_count * 3;
    float *xyz = malloc((capacity ? capacity : 1) * sizeof *xyz);
    if (xyz)
        row->max_penetration_mm =
            max_penetration_mm(ctx, &s, &inst, (double)s.dt * frame, xyz, capacity);
    free(xyz);
    rbc_scene_instance_destroy(api, &inst);
    rbc_scene_free(&s);

    row->frames = done;
    if (done) {
        double sub = row->substeps ? (double)row->substeps : 1.0;
        row->step_median = bench_median(v[0], done);
        row->step_p90 = quantile(v[0], done, 0.9); /* sorts v[0] */
        row->substep_median = row->step_median / sub;
        row->substep_p90 = row->step_p90 / sub;
        row->integrate = bench_median(v[1], done);
        row->local = bench_median(v[2], done);
        row->global = bench_median(v[3], done);
        row->collide = bench_median(v[4], done);
        row->other = bench_median(v[5], done);
        row->wall_median = bench_median(v[6], done);
        row->collider_contacts = bench_median(v[7], done);
        row->cloth_contacts = bench_median(v[8], done);
    } else {
        ++ctx->failed_rows;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Outputs                                                                   */
/* ------------------------------------------------------------------------- */

static const char csv_header[] =
    "scene,threads,frames,substeps,particles,springs,colliders,step_ms_median,step_ms_p90,"
    "substep_ms_median,substep_ms_p90,integrate_ms,local_ms,global_ms,collide_ms,other_ms,"
    "wall_ms_median,fps,collider_contacts_median,cloth_contacts_median,torn_springs,"
    "failsafe_vertices,max_penetration_mm,paper_ms_per_substep,paper_ms_per_frame,paper_figure,note,cores,cpu";

/* %.6g, or "n/a" for NaN. */
static const char *num(double x, char *buf, size_t size) {
    if (isnan(x))
        snprintf(buf, size, "n/a");
    else
        snprintf(buf, size, "%.6g", x);
    return buf;
}

static int write_csv(const scenes_ctx *ctx) {
    FILE *f = bench_open_csv(ctx->run.dir, "scenes.csv", csv_header);
    if (!f)
        return 1;
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const scene_row *r = &ctx->rows[k];
        char b[16][32];
        double fps = r->step_median > 0.0 ? 1e3 / r->step_median : NAN;
        fprintf(f, "%s,%u,%u,%u,%u,%u,%u,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%s,%llu,%llu,%s,%s,%s,%s,%s,%ld,%s\n",
                r->name, r->threads ? r->threads : r->threads_requested, r->frames, r->substeps,
                r->particles, r->springs, r->colliders, num(r->step_median, b[0], 32),
                num(r->step_p90, b[1], 32), num(r->substep_median, b[2], 32),
                num(r->substep_p90, b[3], 32), num(r->integrate, b[4], 32), num(r->local, b[5], 32),
                num(r->global, b[6], 32), num(r->collide, b[7], 32), num(r->other, b[8], 32),
                num(r->wall_median, b[9], 32), num(fps, b[10], 32),
                num(r->collider_contacts, b[11], 32), num(r->cloth_contacts, b[12], 32),
                (unsigned long long)r->torn_springs, (unsigned long long)r->failsafe_vertices,
                num(r->max_penetration_mm, b[13], 32),
                num(r->entry->paper_ms_substep, b[14], 32), num(r->entry->paper_ms_frame, b[15], 32),
                r->entry->paper, r->note, ctx->cores, ctx->cpu);
    }
    return bench_close(f, ctx->run.dir, "scenes.csv") ? 1 : 0;
}

static const char *fixed(double x, int digits, char *buf, size_t size) {
    if (isnan(x))
        snprintf(buf, size, "n/a");
    else
        snprintf(buf, size, "%.*f", digits, x);
    return buf;
}

static void write_tables(const scenes_ctx *ctx, FILE *f) {
    fprintf(f, "| scene | particles | springs | threads | frames | ms/step median | p90 | "
               "ms/substep median | p90 | integrate | local | global | collide | other | fps | "
               "contacts collider / cloth | torn springs | fail-safe vertices | max penetration mm "
               "| paper (GTX 970, measured elsewhere) |\n");
    fprintf(f, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
               "---:|---:|---:|---|\n");
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const scene_row *r = &ctx->rows[k];
        char b[16][32];
        fprintf(f, "| %s | %u | %u | %u | %u | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | "
                   "%s / %s | %llu | %llu | %s | %s |\n",
                r->name, r->particles, r->springs, r->threads ? r->threads : r->threads_requested,
                r->frames, fixed(r->step_median, 3, b[0], 32), fixed(r->step_p90, 3, b[1], 32),
                fixed(r->substep_median, 3, b[2], 32), fixed(r->substep_p90, 3, b[3], 32),
                fixed(r->integrate, 3, b[4], 32), fixed(r->local, 3, b[5], 32),
                fixed(r->global, 3, b[6], 32), fixed(r->collide, 3, b[7], 32),
                fixed(r->other, 3, b[8], 32),
                fixed(r->step_median > 0.0 ? 1e3 / r->step_median : NAN, 1, b[9], 32),
                fixed(r->collider_contacts, 0, b[10], 32), fixed(r->cloth_contacts, 0, b[11], 32),
                (unsigned long long)r->torn_springs, (unsigned long long)r->failsafe_vertices,
                fixed(r->max_penetration_mm, 2, b[12], 32), r->entry->paper);
    }
    int notes = 0;
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const scene_row *r = &ctx->rows[k];
        if (!r->note[0])
            continue;
        if (!notes++)
            fprintf(f, "\nNotes:\n\n");
        fprintf(f, "- %s, %u thread%s: %s (figures over the %u frames before it)\n", r->name,
                r->threads_requested, r->threads_requested == 1 ? "" : "s", r->note, r->frames);
    }
}

static void write_intro(const scenes_ctx *ctx, FILE *f) {
    fprintf(f, "Machine: %s, %ld cores online; load average %.2f at the start, %.2f at the end "
               "(timings assume an otherwise idle machine).\n\n",
            ctx->cpu, ctx->cores, ctx->load_start, ctx->load_end);
    fprintf(f, "Each scene of samples/scenes runs as `rbcloth run` runs it (moving colliders and "
               "drags applied before each step), collision handling included, after %d warm-up "
               "frames. ms/step is stats.step_ms of one rbc_world_step (one frame: all its "
               "substeps); ms/substep = ms/step / substeps; p90 is the nearest-rank 90th "
               "percentile; stage columns are medians of each stage on its own (they need not "
               "add up); fps = 1000 / median ms/step. Contacts are medians over frames of the "
               "last substep's counts. Max penetration: the deepest cloth vertex inside a "
               "sphere, plane, capsule or box at the last frame, not counting thickness (mesh "
               "colliders are not checked). A run stops after the frame that takes it past "
               "%.0f s of wall time (see Notes). The paper's figures are of its GPU "
               "implementation on a GTX 970, quoted, not reproduced: its \"time step\" is one "
               "substep here.\n\n",
            BENCH_WARMUP, BENCH_RUN_SECONDS);
}

static int write_md(const scenes_ctx *ctx) {
    FILE *f = bench_open(ctx->run.dir, "scenes.md");
    if (!f)
        return 1;
    fprintf(f, "# The paper's scenes (`rbcloth bench scenes%s`)\n\n",
            ctx->run.opt->quick ? " --quick" : "");
    write_intro(ctx, f);
    write_tables(ctx, f);
    return bench_close(f, ctx->run.dir, "scenes.md") ? 1 : 0;
}

/* scenes_plot.csv (one line per scene: ms per substep and per frame for each thread
 * count, and the paper's) and scenes.gp: two clustered bar charts. */
static int write_plot(const scenes_ctx *ctx) {
    FILE *f = bench_open(ctx->run.dir, "scenes_plot.csv");
    if (!f)
        return 1;
    fprintf(f, "# scene"); /* a comment for gnuplot, a header for people */
    for (uint32_t t = 0; t < ctx->thread_count; ++t)
        fprintf(f, ",substep_ms_%u_threads", ctx->thread_list[t]);
    fprintf(f, ",paper_substep_ms");
    for (uint32_t t = 0; t < ctx->thread_count; ++t)
        fprintf(f, ",step_ms_%u_threads", ctx->thread_list[t]);
    fprintf(f, ",paper_frame_ms\n");
    for (uint32_t e = 0; e < ENTRY_COUNT; ++e) {
        const scene_row *first = NULL;
        for (uint32_t k = 0; k < ctx->row_count && !first; ++k)
            if (ctx->rows[k].entry == &entries[e])
                first = &ctx->rows[k];
        if (!first)
            continue;
        fprintf(f, "%s", first->name);
        for (int pass = 0; pass < 2; ++pass) {
            for (uint32_t t = 0; t < ctx->thread_count; ++t) {
                double ms = NAN;
                for (uint32_t k = 0; k < ctx->row_count; ++k)
                    if (ctx->rows[k].entry == &entries[e] &&
                        ctx->rows[k].threads_requested == ctx->thread_list[t])
                        ms = pass ? ctx->rows[k].step_median : ctx->rows[k].substep_median;
                fprintf(f, isnan(ms) ? ",NaN" : ",%.6g", ms);
            }
            double paper = pass ? entries[e].paper_ms_frame : entries[e].paper_ms_substep;
            fprintf(f, isnan(paper) ? ",NaN" : ",%.6g", paper);
        }
        fprintf(f, "\n");
    }
    if (bench_close(f, ctx->run.dir, "scenes_plot.csv"))
        return 1;

    f = bench_open(ctx->run.dir, "scenes.gp");
    if (!f)
        return 1;
    char cpu[sizeof ctx->cpu];
    snprintf(cpu, sizeof cpu, "%s", ctx->cpu);
    for (char *c = cpu; *c; ++c)
        if (strchr("_^{}@&~\\'", *c))
            *c = ' ';
    const uint32_t n = ctx->thread_count;
    fprintf(f, "# Generated by `rbcloth bench scenes`; run `gnuplot scenes.gp` in this directory.\n");
    /* noenhanced: scene names have underscores, which enhanced text subscripts. */
    fprintf(f, "set terminal pngcairo noenhanced size 1400,560 font 'sans,10'\n");
    fprintf(f, "set output 'scenes.png'\n");
    fprintf(f, "set datafile separator ','\nset datafile missing 'NaN'\n");
    fprintf(f, "set style data histogram\nset style histogram clustered gap 1\n");
    fprintf(f, "set style fill solid 0.85 border -1\nset boxwidth 0.9\n");
    fprintf(f, "set grid ytics lc rgb '#dddddd'\nset key top left font ',9'\n");
    /* Log scale: the scenes span three decades (and a degenerate run more). */
    fprintf(f, "set xtics rotate by -25 font ',9'\nset logscale y\nset yrange [0.1:*]\n");
    fprintf(f, "set linetype 1 lc rgb '#1f77b4'\nset linetype 2 lc rgb '#ff7f0e'\n"
               "set linetype 3 lc rgb '#7f7f7f'\n");
    fprintf(f, "set multiplot layout 1,2 title 'The paper scenes with collisions: medians over "
               "frames (%s, %ld cores); paper: GTX 970, measured elsewhere'\n",
            cpu, ctx->cores);
    for (int pass = 0; pass < 2; ++pass) {
        fprintf(f, "set title '%s'\nset ylabel '%s'\n",
                pass ? "Per frame (rbc_world_step, all substeps)" : "Per substep (= the paper time step)",
                pass ? "ms per frame" : "ms per substep");
        uint32_t base = pass ? n + 3 : 2; /* first column of this panel */
        fprintf(f, "plot ");
        for (uint32_t t = 0; t < n; ++t)
            fprintf(f, "%s'scenes_plot.csv' using %u:xtic(1) lt %u title '%u thread%s'",
                    t ? ", " : "", base + t, t + 1, ctx->thread_list[t],
                    ctx->thread_list[t] == 1 ? "" : "s");
        fprintf(f, ", '' using %u lt 3 title 'paper (GTX 970)'\n", base + n);
    }
    fprintf(f, "unset multiplot\n");
    if (bench_close(f, ctx->run.dir, "scenes.gp"))
        return 1;
    bench_plot(ctx->run.dir, "scenes.gp");
    return 0;
}

/* ------------------------------------------------------------------------- */

int cli_bench_scenes(const cli_plugin *plugin, const cli_bench_options *options) {
    if (require_v1_3(plugin))
        return 1;
    scenes_ctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx)
        return out_of_memory();
    ctx->run = bench_run_of(plugin, options);
    if (find_scenes_dir(ctx)) {
        free(ctx);
        return 1;
    }
    bench_cpu_model(ctx->cpu, sizeof ctx->cpu, 0);
    ctx->cores = sysconf(_SC_NPROCESSORS_ONLN);
    ctx->thread_count = bench_thread_list(options, ctx->thread_list);

    if (fs_mkdir_p_or_say(ctx->run.dir)) {
        free(ctx);
        return 1;
    }
    double start = bench_now();
    ctx->load_start = bench_load_average();
    int rc = 0;
    for (uint32_t e = 0; e < ENTRY_COUNT && !rc; ++e)
        for (uint32_t t = 0; t < ctx->thread_count && !rc; ++t)
            if (!(entries[e].heavy && ctx->run.opt->quick))
                rc = run_scene(ctx, &entries[e], ctx->thread_list[t], &ctx->rows[ctx->row_count++]);
    ctx->load_end = bench_load_average();
    if (!rc) /* each returns 0, or 1 after a message: the first to fail ends it */
        rc = write_csv(ctx) || write_md(ctx) || write_plot(ctx);
    if (!rc) {
        printf("\nThe paper's scenes\n\n");
        write_intro(ctx, stdout);
        write_tables(ctx, stdout);
        printf("\nWrote scenes.csv, scenes.md%s in %s (%.1f s)\n",
               bench_have_gnuplot() ? ", scenes.png" : "", ctx->run.dir, bench_now() - start);
        if (ctx->failed_rows) {
            fprintf(stderr, "rbcloth: bench scenes: %u run%s measured no frame (see scenes.md, "
                            "Notes)\n",
                    ctx->failed_rows, ctx->failed_rows == 1 ? "" : "s");
            rc = 1;
        }
    }
    for (int k = 0; k < 9; ++k)
        free(ctx->samples[k]);
    free(ctx);
    return rc;
}
