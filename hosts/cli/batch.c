/* batch.c -- `rbcloth batch MANIFEST.json [-j N] [--out DIR]`: simulate every job
 * of a manifest (a mesh file imported with rbc_mesh_import, or a scene JSON) into
 * point caches, N jobs at a time, one forked process per job.
 *
 * Why processes: a job that crashes (assimp on a hostile file, a bug) takes only
 * itself down, and a job killed by a signal cannot corrupt the others' state.
 *
 * Outputs of job NAME, in DIR/NAME/: NAME.obj (rest mesh, input vertex order),
 * NAME.pc2, NAME.mdd, frames/NAME_0001.obj ... (as the job asks), and
 * NAME.result.json, written last, once every output is renamed into place and
 * fsync'd: a job whose result and outputs all exist (with the sizes the result
 * lists) is skipped on the next run (resume). Every file is written to a temporary
 * name and renamed, so an interrupted job leaves no half-written output; the parent
 * also removes the temporary files of a job that died without cleaning up.
 * The run closes with DIR/batch_report.json and DIR/batch_report.md.
 *
 * One batch per folder: the parent holds an flock on DIR/.rbcloth-batch.lock for the
 * whole run, and its workers share it (they inherit the descriptor), so the lock is
 * free only once every process that could write into DIR is gone. Workers die with
 * the parent (PR_SET_PDEATHSIG), so a killed batch can be resumed at once.
 */
#define _POSIX_C_SOURCE 200809L
#include "batch.h"

#include <cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif
#include <time.h>
#include <unistd.h>

#include "fsutil.h"
#include "scene.h"
#include "viewer.h"

enum { MAX_COLLIDERS = 8, MESSAGE_MAX = 1024 };

typedef enum job_status {
    JOB_PENDING = 0,
    JOB_RUNNING,
    JOB_OK,
    JOB_SKIPPED,
    JOB_FAILED,
    JOB_INTERRUPTED,
    JOB_NOT_RUN
} job_status;

static const char *const status_names[] = {"pending", "running", "ok", "skipped",
                                           "failed", "interrupted", "not run"};

typedef struct batch_job {
    char *name;
    /* Exactly one of mesh (a file for rbc_mesh_import) or scene (a scene JSON),
     * resolved against the manifest's folder; "scene": "default" = built-in. */
    char *mesh, *scene;
    long frames;
    double dt;
    long substeps, iterations, nonlinear, threads;
    int solver, energy_guard; /* indices into rbc_scene_*_names, -1 = default */
    double stiffness, vertex_mass, damping;
    rbc_mesh_import_def import; /* pin_group set from pin_group below at import time */
    char pin_group[128];        /* pins.group, or "" */
    uint32_t collider_count;
    rbc_collider_def colliders[MAX_COLLIDERS];
    int out_pc2, out_mdd, out_objseq;
    /* Mesh jobs: caches and JOB.obj in the file's vertex order and coordinates (1,
     * "cache_order": "file", the default: they play on the user's own mesh) or in
     * the simulation's (0, "simulation"). */
    int file_order;
    double timeout; /* seconds, 0 = none; -1 = not in the manifest: --job-timeout */
    /* The run */
    char *dir, *stem_path, *result_path;
    job_status status;
    pid_t pid;
    int pipe_fd;
    double started, seconds;
    /* Killed by the parent: over its time limit (timed_out); still running when the
     * grace period after SIGINT/SIGTERM ended (killed 1) or at a second signal (2). */
    int timed_out, killed;
    char message[MESSAGE_MAX];
    cJSON *result; /* the job's result.json, once finished or skipped */
} batch_job;

typedef struct batch {
    const rbc_api_v1 *api;
    const cli_batch_options *options;
    batch_job *jobs;
    size_t job_count;
} batch;

/* Signals received: 1 stops the batch (SIGTERM forwarded to the workers), 2 kills
 * the workers at once. A worker checks it between frames. */
static volatile sig_atomic_t g_stop = 0;

static void on_stop_signal(int sig) {
    (void)sig;
    if (g_stop < 2) g_stop = g_stop + 1;
}

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int file_exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

static char *read_text(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    char *b = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        if (n >= 0 && fseek(f, 0, SEEK_SET) == 0 && (b = malloc((size_t)n + 1)) != NULL) {
            if (fread(b, 1, (size_t)n, f) != (size_t)n) {
                free(b);
                b = NULL;
            } else {
                b[n] = '\0';
                if (size) *size = (size_t)n;
            }
        }
    }
    fclose(f);
    return b;
}

/* ------------------------------------------------------------------------- */
/* Manifest                                                                  */
/* ------------------------------------------------------------------------- */

/* A key from the job object, else from "defaults". */
static const cJSON *setting(const cJSON *job, const cJSON *defaults, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(job, key);
    return v ? v : cJSON_GetObjectItemCaseSensitive(defaults, key);
}

static int safe_name(const char *s) {
    if (!s || !*s || s[0] == '.' || strlen(s) > 128) return 0;
    for (; *s; ++s)
        if (!((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z') || (*s >= '0' && *s <= '9') ||
              *s == '_' || *s == '-' || *s == '.'))
            return 0;
    return 1;
}

/* A path relative to the manifest's folder (absolute paths kept). */
static char *resolve(const char *base_dir, const char *path) {
    if (path[0] == '/' || !base_dir[0]) return strdup(path);
    size_t n = strlen(base_dir) + 1 + strlen(path) + 1;
    char *r = malloc(n);
    if (r) snprintf(r, n, "%s/%s", base_dir, path);
    return r;
}

typedef struct parse_ctx {
    const char *source;
    char *err;
    size_t err_size;
} parse_ctx;

static int fail(parse_ctx *p, const char *job, const char *key, const char *what) {
    snprintf(p->err, p->err_size, "%s: jobs[%s].%s: %s", p->source, job, key, what);
    return -1;
}

static int get_number(parse_ctx *p, const char *job, const cJSON *jo, const cJSON *defaults,
                      const char *key, double min, double max, double *out) {
    const cJSON *v = setting(jo, defaults, key);
    if (!v) return 0;
    if (!cJSON_IsNumber(v) || !(v->valuedouble >= min && v->valuedouble <= max)) {
        char what[160];
        snprintf(what, sizeof what, "must be a number in [%g, %g]", min, max);
        return fail(p, job, key, what);
    }
    *out = v->valuedouble;
    return 0;
}

static int get_long(parse_ctx *p, const char *job, const cJSON *jo, const cJSON *defaults,
                    const char *key, long min, long max, long *out) {
    double d = (double)*out;
    if (get_number(p, job, jo, defaults, key, (double)min, (double)max, &d)) return -1;
    if (d != floor(d)) return fail(p, job, key, "must be an integer");
    *out = (long)d;
    return 0;
}

static int get_floats(parse_ctx *p, const char *job, const cJSON *obj, const char *key,
                      float *out, int n) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v) return 0;
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n) {
        char what[64];
        snprintf(what, sizeof what, "must be an array of %d numbers", n);
        return fail(p, job, key, what);
    }
    for (int k = 0; k < n; ++k) {
        const cJSON *e = cJSON_GetArrayItem(v, k);
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble))
            return fail(p, job, key, "holds something that is not a finite number");
        out[k] = (float)e->valuedouble;
    }
    return 0;
}

static int get_name(parse_ctx *p, const char *job, const cJSON *jo, const cJSON *defaults,
                    const char *key, const char *const *names, int *out) {
    const cJSON *v = setting(jo, defaults, key);
    if (!v) return 0;
    for (int k = 0; cJSON_IsString(v) && names[k]; ++k)
        if (strcmp(v->valuestring, names[k]) == 0) {
            *out = k;
            return 0;
        }
    char what[512] = "must be one of:";
    for (int k = 0; names[k]; ++k) {
        strncat(what, " ", sizeof what - strlen(what) - 1);
        strncat(what, names[k], sizeof what - strlen(what) - 1);
    }
    return fail(p, job, key, what);
}

/* Pin rules of the import def: {"top_axis": "x"|"y"|"z", "top_tolerance", "plane":
 * [nx, ny, nz, d], "plane_distance", "point": [x, y, z], "point_distance",
 * "color_threshold", "group": "NAME"} (group: a mesh or node name of the file). */
static int parse_pins(parse_ctx *p, const char *job, const cJSON *pins, rbc_mesh_import_def *d,
                      char *group, size_t group_cap) {
    if (!pins) return 0;
    if (!cJSON_IsObject(pins)) return fail(p, job, "pins", "must be an object");
    const cJSON *grp = cJSON_GetObjectItemCaseSensitive(pins, "group");
    if (grp) {
        if (!cJSON_IsString(grp) || !grp->valuestring[0] || strlen(grp->valuestring) >= group_cap)
            return fail(p, job, "pins.group", "must be a non-empty name of under 128 bytes");
        snprintf(group, group_cap, "%s", grp->valuestring);
    }
    const cJSON *axis = cJSON_GetObjectItemCaseSensitive(pins, "top_axis");
    if (axis) {
        static const char *const axes[] = {"x", "y", "z"};
        int found = -1;
        for (int k = 0; k < 3; ++k)
            if (cJSON_IsString(axis) && strcmp(axis->valuestring, axes[k]) == 0) found = k;
        if (found < 0) return fail(p, job, "pins.top_axis", "must be \"x\", \"y\" or \"z\"");
        d->pin_top_axis = found;
    }
    struct {
        const char *key;
        float *target;
    } scalars[] = {{"top_tolerance", &d->pin_top_tolerance},
                   {"plane_distance", &d->pin_plane_distance},
                   {"point_distance", &d->pin_point_distance},
                   {"color_threshold", &d->pin_color_threshold}};
    for (size_t k = 0; k < sizeof scalars / sizeof scalars[0]; ++k) {
        const cJSON *v = cJSON_GetObjectItemCaseSensitive(pins, scalars[k].key);
        if (!v) continue;
        if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
            return fail(p, job, scalars[k].key, "must be a finite number");
        *scalars[k].target = (float)v->valuedouble;
    }
    if (get_floats(p, job, pins, "plane", d->pin_plane, 4) ||
        get_floats(p, job, pins, "point", d->pin_point, 3))
        return -1;
    return 0;
}

static int parse_colliders(parse_ctx *p, const rbc_api_v1 *api, const char *job,
                           const cJSON *list, batch_job *j) {
    if (!list) return 0;
    if (!cJSON_IsArray(list) || cJSON_GetArraySize(list) > MAX_COLLIDERS)
        return fail(p, job, "colliders", "must be an array of at most 8 colliders");
    const cJSON *c;
    cJSON_ArrayForEach(c, list) {
        rbc_collider_def *d = &j->colliders[j->collider_count++];
        api->collider_def_init(d, (uint32_t)sizeof *d);
        const cJSON *shape = cJSON_GetObjectItemCaseSensitive(c, "shape");
        if (cJSON_IsString(shape) && strcmp(shape->valuestring, "sphere") == 0)
            d->shape = RBC_SHAPE_SPHERE;
        else if (cJSON_IsString(shape) && strcmp(shape->valuestring, "plane") == 0)
            d->shape = RBC_SHAPE_PLANE;
        else
            return fail(p, job, "colliders[].shape", "must be \"sphere\" or \"plane\"");
        float r[1] = {d->radius}, t[1] = {d->thickness};
        const cJSON *radius = cJSON_GetObjectItemCaseSensitive(c, "radius");
        const cJSON *thick = cJSON_GetObjectItemCaseSensitive(c, "thickness");
        if (radius) r[0] = cJSON_IsNumber(radius) ? (float)radius->valuedouble : -1.0f;
        if (thick) t[0] = cJSON_IsNumber(thick) ? (float)thick->valuedouble : -1.0f;
        if (!(r[0] > 0.0f) || !(t[0] >= 0.0f))
            return fail(p, job, "colliders[]", "radius must be > 0 and thickness >= 0");
        d->radius = r[0];
        d->thickness = t[0];
        if (get_floats(p, job, c, "position", d->position, 3) ||
            get_floats(p, job, c, "rotation", d->rotation, 4))
            return -1;
    }
    return 0;
}

static int parse_job(parse_ctx *p, const rbc_api_v1 *api, const char *base_dir,
                     const cJSON *jo, const cJSON *defaults, size_t index, batch_job *j) {
    char label[160];
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(jo, "name");
    snprintf(label, sizeof label, "%zu", index);
    if (!cJSON_IsObject(jo)) return fail(p, label, "", "must be an object");
    if (!cJSON_IsString(name) || !safe_name(name->valuestring))
        return fail(p, label, "name",
                    "must be a file-safe name ([A-Za-z0-9_.-], not starting with '.')");
    j->name = strdup(name->valuestring);
    snprintf(label, sizeof label, "%zu (%s)", index, j->name);
    const cJSON *mesh = cJSON_GetObjectItemCaseSensitive(jo, "mesh");
    const cJSON *scene = cJSON_GetObjectItemCaseSensitive(jo, "scene");
    if ((mesh != NULL) == (scene != NULL) || (mesh && !cJSON_IsString(mesh)) ||
        (scene && !cJSON_IsString(scene)))
        return fail(p, label, "mesh",
                    "a job needs exactly one of \"mesh\" (a mesh file) or \"scene\" (a scene "
                    "JSON, or \"default\")");
    if (mesh) j->mesh = resolve(base_dir, mesh->valuestring);
    if (scene)
        j->scene = strcmp(scene->valuestring, "default") == 0
                       ? strdup("default")
                       : resolve(base_dir, scene->valuestring);
    /* Mesh jobs default to the sample scenes' settings; scene jobs to the scene. */
    j->frames = -1;
    j->dt = -1.0;
    j->substeps = j->iterations = j->nonlinear = -1;
    j->threads = 1; /* parallelism comes from -j */
    j->solver = j->energy_guard = -1;
    j->stiffness = j->vertex_mass = j->damping = -1.0;
    j->timeout = -1.0;
    if (get_number(p, label, jo, defaults, "timeout", 0.0, 1e7, &j->timeout) ||
        get_long(p, label, jo, defaults, "frames", 1, 1000000, &j->frames) ||
        get_number(p, label, jo, defaults, "dt", 1e-7, 10.0, &j->dt) ||
        get_long(p, label, jo, defaults, "substeps", 1, 1024, &j->substeps) ||
        get_long(p, label, jo, defaults, "iterations", 1, 4096, &j->iterations) ||
        get_long(p, label, jo, defaults, "nonlinear", 1, 1024, &j->nonlinear) ||
        get_long(p, label, jo, defaults, "threads", 0, 1024, &j->threads) ||
        get_number(p, label, jo, defaults, "stiffness", 1e-9, 1e12, &j->stiffness) ||
        get_number(p, label, jo, defaults, "vertex_mass", 1e-12, 1e6, &j->vertex_mass) ||
        get_number(p, label, jo, defaults, "damping", 0.0, 1e6, &j->damping) ||
        get_name(p, label, jo, defaults, "solver", rbc_scene_solver_names, &j->solver) ||
        get_name(p, label, jo, defaults, "energy_guard", rbc_scene_energy_guard_names,
                 &j->energy_guard))
        return -1;
    api->mesh_import_def_init(&j->import, (uint32_t)sizeof j->import);
    double scale = 1.0;
    if (get_number(p, label, jo, defaults, "scale", 1e-9, 1e9, &scale)) return -1;
    j->import.scale = (float)scale;
    static const char *const orders[] = {"simulation", "file", NULL};
    j->file_order = 1;
    if (get_name(p, label, jo, defaults, "cache_order", orders, &j->file_order)) return -1;
    const cJSON *keep = setting(jo, defaults, "keep_file_units");
    if (keep && !cJSON_IsBool(keep))
        return fail(p, label, "keep_file_units", "must be true or false");
    j->import.keep_file_units = keep && cJSON_IsTrue(keep);
    if (j->scene && (cJSON_GetObjectItemCaseSensitive(jo, "cache_order") ||
                     cJSON_GetObjectItemCaseSensitive(jo, "keep_file_units")))
        return fail(p, label, "cache_order",
                    "cache_order and keep_file_units are for mesh jobs (a scene has no file "
                    "mesh)");
    if (parse_pins(p, label, setting(jo, defaults, "pins"), &j->import, j->pin_group,
                   sizeof j->pin_group) ||
        parse_colliders(p, api, label, setting(jo, defaults, "colliders"), j))
        return -1;
    if (j->scene && (setting(jo, defaults, "pins") || setting(jo, defaults, "colliders")) &&
        (cJSON_GetObjectItemCaseSensitive(jo, "pins") ||
         cJSON_GetObjectItemCaseSensitive(jo, "colliders")))
        return fail(p, label, "pins",
                    "pins and colliders of a scene job come from the scene file");
    const cJSON *outputs = setting(jo, defaults, "outputs");
    if (!outputs) {
        j->out_pc2 = 1;
    } else {
        const cJSON *o;
        if (!cJSON_IsArray(outputs) || cJSON_GetArraySize(outputs) == 0)
            return fail(p, label, "outputs", "must be a non-empty array of \"pc2\", \"mdd\", \"objseq\"");
        cJSON_ArrayForEach(o, outputs) {
            const char *s = cJSON_IsString(o) ? o->valuestring : "";
            if (strcmp(s, "pc2") == 0) j->out_pc2 = 1;
            else if (strcmp(s, "mdd") == 0) j->out_mdd = 1;
            else if (strcmp(s, "objseq") == 0) j->out_objseq = 1;
            else return fail(p, label, "outputs", "must hold only \"pc2\", \"mdd\", \"objseq\"");
        }
    }
    return 0;
}

static void job_free(batch_job *j) {
    free(j->name);
    free(j->mesh);
    free(j->scene);
    free(j->dir);
    free(j->stem_path);
    free(j->result_path);
    cJSON_Delete(j->result);
}

static cJSON *read_json(const char *path, char *err, size_t err_size) {
    size_t size = 0;
    char *text = read_text(path, &size);
    if (!text) {
        snprintf(err, err_size, "%s: cannot open: %s", path, strerror(errno));
        return NULL;
    }
    cJSON *root = cJSON_ParseWithLength(text, size);
    free(text);
    if (!root) snprintf(err, err_size, "%s: not valid JSON", path);
    return root;
}

/* Folder mode: the mesh files assimp reads, by extension (case-insensitive). Not
 * every format assimp knows: the ones a cloth pipeline exports. */
static int mesh_extension(const char *file) {
    static const char *const exts[] = {"obj", "ply", "off", "stl", "dae", "gltf", "glb", "fbx",
                                       "3ds", "x",   "ase", "ms3d", "lwo", "x3d", "3mf", "amf",
                                       "ac",  "blend", "ifc", "smd", NULL};
    const char *dot = strrchr(file, '.');
    if (!dot || dot == file) return 0;
    for (int k = 0; exts[k]; ++k)
        if (strcasecmp(dot + 1, exts[k]) == 0) return 1;
    return 0;
}

static int compare_names(const void *a, const void *b) {
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* A job name from a file name: its stem, characters outside [A-Za-z0-9_.-] as '_';
 * the extension is kept (stem_ext) when two files share a stem. */
static void job_name_of(const char *file, int keep_ext, char *out, size_t size) {
    snprintf(out, size, "%s", file);
    char *dot = strrchr(out, '.');
    if (dot && !keep_ext) *dot = '\0';
    else if (dot) *dot = '_';
    for (char *c = out; *c; ++c)
        if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
              *c == '_' || *c == '-' || *c == '.'))
            *c = '_';
    if (out[0] == '.') out[0] = '_';
}

/* Folder mode as a manifest: {"defaults": TEMPLATE, "jobs": [{"name": STEM, "mesh":
 * FILE}, ...]} over the folder's mesh files in name order, so that the job list,
 * the runner, resume, --only and the report are the manifest's. */
static cJSON *folder_manifest(const char *dir, const char *template_path, char *err,
                              size_t err_size) {
    if (!template_path) {
        snprintf(err, err_size, "%s is a folder: folder mode needs --template SCENE.json", dir);
        return NULL;
    }
    cJSON *tmpl = read_json(template_path, err, err_size);
    if (!tmpl) return NULL;
    if (!cJSON_IsObject(tmpl)) {
        snprintf(err, err_size, "%s: a template must be a JSON object", template_path);
        cJSON_Delete(tmpl);
        return NULL;
    }
    cJSON *defaults = cJSON_DetachItemFromObjectCaseSensitive(tmpl, "defaults");
    if (!defaults) defaults = tmpl, tmpl = NULL;
    cJSON_Delete(tmpl);
    static const char *const per_job[] = {"jobs", "name", "mesh", "scene", "description"};
    for (size_t k = 0; k < sizeof per_job / sizeof per_job[0]; ++k)
        cJSON_DeleteItemFromObjectCaseSensitive(defaults, per_job[k]);
    DIR *d = opendir(dir);
    if (!d) {
        snprintf(err, err_size, "%s: cannot open folder: %s", dir, strerror(errno));
        cJSON_Delete(defaults);
        return NULL;
    }
    char **files = NULL;
    size_t count = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.' || !mesh_extension(e->d_name)) continue;
        char *full = fs_path(dir, e->d_name, "");
        int regular = full && file_exists(full);
        free(full);
        if (!regular) continue;
        if (count == cap) {
            cap = cap ? 2 * cap : 16;
            char **grown = realloc(files, cap * sizeof *files);
            if (!grown) break;
            files = grown;
        }
        files[count++] = strdup(e->d_name);
    }
    closedir(d);
    cJSON *root = NULL;
    if (count == 0) {
        snprintf(err, err_size, "%s: no mesh file (.obj .ply .off .stl .dae .gltf .glb .fbx ...)",
                 dir);
    } else {
        qsort(files, count, sizeof *files, compare_names);
        root = cJSON_CreateObject();
        cJSON *jobs = cJSON_AddArrayToObject(root, "jobs");
        for (size_t k = 0; k < count; ++k) {
            char name[256], other[256];
            job_name_of(files[k], 0, name, sizeof name);
            int clash = 0;
            for (size_t i = 0; i < count; ++i) {
                job_name_of(files[i], 0, other, sizeof other);
                clash += i != k && strcmp(name, other) == 0;
            }
            if (clash) job_name_of(files[k], 1, name, sizeof name);
            cJSON *job = cJSON_CreateObject();
            cJSON_AddStringToObject(job, "name", name);
            cJSON_AddStringToObject(job, "mesh", files[k]);
            cJSON_AddItemToArray(jobs, job);
        }
        cJSON_AddItemToObject(root, "defaults", defaults);
        defaults = NULL;
    }
    for (size_t k = 0; k < count; ++k) free(files[k]);
    free(files);
    cJSON_Delete(defaults);
    return root;
}

/* The keys a job or "defaults" may hold (a template is "defaults"), and the
 * manifest's own. A key outside them is refused with the nearest one: a mistyped
 * key silently ignored would run the job with settings nobody asked for. */
static const char *const job_keys[] = {"name",  "mesh",      "scene",       "frames",
                                       "dt",    "substeps",  "iterations",  "nonlinear",
                                       "threads", "stiffness", "vertex_mass", "damping",
                                       "solver", "energy_guard", "scale",   "pins",
                                       "colliders", "outputs", "timeout", "description",
                                       "cache_order", "keep_file_units", NULL};
static const char *const manifest_keys[] = {"jobs", "defaults", "description", NULL};

static int check_keys(const cJSON *obj, const char *const *allowed, const char *source,
                      const char *where, char *err, size_t err_size) {
    for (const cJSON *c = obj ? obj->child : NULL; c; c = c->next) {
        int known = 0;
        for (int k = 0; allowed[k]; ++k) known |= strcmp(c->string, allowed[k]) == 0;
        if (known) continue;
        const char *near = rbc_scene_nearest(c->string, allowed);
        snprintf(err, err_size, "%s: %s%s: unknown key%s%s%s", source, where, c->string,
                 near ? "; did you mean \"" : "", near ? near : "", near ? "\"?" : "");
        return -1;
    }
    return 0;
}

static int is_dir(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

static int load_manifest(batch *b, char *err, size_t err_size) {
    const char *path = b->options->manifest_path;
    const int folder = is_dir(path);
    if (!folder && b->options->template_path) {
        snprintf(err, err_size, "--template is for a folder of meshes; %s is a manifest", path);
        return -1;
    }
    cJSON *root = folder ? folder_manifest(path, b->options->template_path, err, err_size)
                         : read_json(path, err, err_size);
    if (!root) return -1;
    /* Mesh paths resolve against the manifest's folder, or the mesh folder. */
    char *base = strdup(path);
    char *slash = base && !folder ? strrchr(base, '/') : NULL;
    if (slash) *slash = '\0';
    else if (base && !folder) base[0] = '\0';
    parse_ctx p = {folder ? b->options->template_path : path, err, err_size};
    const cJSON *jobs = cJSON_GetObjectItemCaseSensitive(root, "jobs");
    const cJSON *defaults = cJSON_GetObjectItemCaseSensitive(root, "defaults");
    int rc = 0;
    if (!folder && check_keys(root, manifest_keys, path, "", err, err_size)) {
        rc = -1;
    } else if (defaults && check_keys(defaults, job_keys, p.source, folder ? "" : "defaults.", err,
                                      err_size)) {
        rc = -1;
    } else if (!cJSON_IsArray(jobs) || cJSON_GetArraySize(jobs) == 0) {
        snprintf(err, err_size, "%s: jobs: must be a non-empty array", path);
        rc = -1;
    } else if (defaults && !cJSON_IsObject(defaults)) {
        snprintf(err, err_size, "%s: defaults: must be an object", path);
        rc = -1;
    } else {
        b->job_count = (size_t)cJSON_GetArraySize(jobs);
        b->jobs = calloc(b->job_count, sizeof *b->jobs);
        if (!b->jobs) rc = -1, snprintf(err, err_size, "out of memory");
        for (size_t k = 0; rc == 0 && k < b->job_count; ++k) {
            char where[48];
            snprintf(where, sizeof where, "jobs[%zu].", k);
            const cJSON *jo = cJSON_GetArrayItem(jobs, (int)k);
            rc = cJSON_IsObject(jo) ? check_keys(jo, job_keys, path, where, err, err_size) : 0;
            if (rc == 0)
                rc = parse_job(&p, b->api, base ? base : "", jo, defaults, k, &b->jobs[k]);
            for (size_t i = 0; rc == 0 && i < k; ++i)
                if (strcmp(b->jobs[i].name, b->jobs[k].name) == 0) {
                    snprintf(err, err_size, "%s: jobs[%zu].name: '%s' is also the name of jobs[%zu]",
                             path, k, b->jobs[k].name, i);
                    rc = -1;
                }
        }
    }
    free(base);
    cJSON_Delete(root);
    return rc;
}

/* ------------------------------------------------------------------------- */
/* Outputs of a job                                                          */
/* ------------------------------------------------------------------------- */

/* DIR/NAME/STEM.EXT for cloth `stem`; objseq prefix DIR/NAME/frames/STEM. */
static char *job_file(const batch_job *j, const char *stem, const char *ext) {
    return fs_path(j->dir, stem, ext);
}

static char *objseq_prefix(const batch_job *j, const char *stem) {
    size_t n = strlen(j->dir) + strlen("/frames/") + strlen(stem) + 1;
    char *r = malloc(n);
    if (r) snprintf(r, n, "%s/frames/%s", j->dir, stem);
    return r;
}

/* Remove "*.tmp*" files of a job (a job killed before it could clean up); with
 * `prefix`, only those whose name starts with it. */
static void remove_tmp_in(const char *dir, const char *prefix) {
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (!strstr(e->d_name, ".tmp") ||
            (prefix && strncmp(e->d_name, prefix, strlen(prefix)) != 0))
            continue;
        size_t n = strlen(dir) + 1 + strlen(e->d_name) + 1;
        char *p = malloc(n);
        if (p) {
            snprintf(p, n, "%s/%s", dir, e->d_name);
            remove(p);
        }
        free(p);
    }
    closedir(d);
}

static void remove_job_tmp(const batch_job *j) {
    remove_tmp_in(j->dir, NULL);
    size_t n = strlen(j->dir) + 8;
    char *frames = malloc(n);
    if (frames) {
        snprintf(frames, n, "%s/frames", j->dir);
        remove_tmp_in(frames, NULL);
    }
    free(frames);
    /* fs_write_atomic's temporary result file */
}

/* An output that result.json lists, as a path: they are relative to the job's
 * folder; an absolute one is kept. */
static char *output_path(const batch_job *j, const char *listed) {
    return listed[0] == '/' ? strdup(listed) : fs_path(j->dir, listed, "");
}

/* Finished before: result.json parses and every output it lists exists, with the
 * size it records. The paths are relative to the job's folder, so that a resume
 * with --out spelled another way (absolute, or from another working folder) finds
 * them. A result without sizes (written before they were recorded, its paths as
 * --out gave them) counts when its outputs exist as listed. */
static int job_done(batch_job *j) {
    char *text = read_text(j->result_path, NULL);
    if (!text) return 0;
    cJSON *r = cJSON_Parse(text);
    free(text);
    const cJSON *outs = cJSON_GetObjectItemCaseSensitive(r, "outputs");
    const cJSON *sizes = cJSON_GetObjectItemCaseSensitive(r, "output_bytes");
    int ok = cJSON_IsArray(outs) && cJSON_GetArraySize(outs) > 0 &&
             (!sizes ||
              (cJSON_IsArray(sizes) && cJSON_GetArraySize(sizes) == cJSON_GetArraySize(outs)));
    int k = 0;
    const cJSON *o;
    cJSON_ArrayForEach(o, outs) {
        if (!ok) break;
        if (!cJSON_IsString(o)) {
            ok = 0;
            break;
        }
        if (sizes) {
            char *path = output_path(j, o->valuestring);
            const cJSON *n = cJSON_GetArrayItem(sizes, k++);
            struct stat st;
            ok = path && stat(path, &st) == 0 && S_ISREG(st.st_mode) && cJSON_IsNumber(n) &&
                 (double)st.st_size == n->valuedouble;
            free(path);
        } else {
            ok = file_exists(o->valuestring);
        }
    }
    if (!ok) {
        cJSON_Delete(r);
        return 0;
    }
    j->result = r;
    return 1;
}

/* ------------------------------------------------------------------------- */
/* One job, in its own process                                               */
/* ------------------------------------------------------------------------- */

typedef struct job_cloth {
    char *stem;
    rbc_cloth_id id;
    uint32_t vertex_count, quad_count, color_count, spring_count;
    float *rest;
    uint32_t *quads;
    rbc_cache_id caches[3];
    /* A mesh job in the file's order: the caches marked in file_order[] (PC2, MDD)
     * hold the file's file_count vertices (rbc_mesh_to_file_positions into
     * file_xyz); an OBJ sequence stays in the simulation's. */
    uint32_t file_count;
    float *file_xyz;
    uint8_t file_order[3];
} job_cloth;

typedef struct job_run {
    const rbc_api_v1 *api;
    batch_job *job;
    rbc_scene scene;
    rbc_scene_instance instance;
    rbc_mesh_id mesh;
    rbc_world_id world; /* mesh jobs */
    uint32_t cloth_count;
    job_cloth *cloths;
    /* JOB.png and JOB.html (viewer.h): every cloth, and the colliders the job has
     * (a scene's mesh colliders from files are left out: the scene keeps no
     * triangles of them); view_collider[k]: collider k's index in the view or -1. */
    cli_view *view;
    int32_t view_collider[1024];
    cJSON *outputs;
    char *err;
    size_t err_size;
} job_run;

static int api_fail(job_run *r, rbc_result rc, const char *what) {
    snprintf(r->err, r->err_size, "%s: %s: %s", what, r->api->result_string(rc),
             r->api->last_error());
    return -1;
}

static int oom(job_run *r) {
    snprintf(r->err, r->err_size, "out of memory");
    return -1;
}

static void job_run_free(job_run *r) {
    for (uint32_t i = 0; r->cloths && i < r->cloth_count; ++i) {
        for (int k = 0; k < 3; ++k)
            if (r->cloths[i].caches[k]) r->api->cache_destroy(r->cloths[i].caches[k]);
        free(r->cloths[i].stem);
        free(r->cloths[i].rest);
        free(r->cloths[i].quads);
        free(r->cloths[i].file_xyz);
    }
    free(r->cloths);
    if (r->world) r->api->world_destroy(r->world);
    if (r->mesh) r->api->mesh_destroy(r->mesh);
    rbc_scene_instance_destroy(r->api, &r->instance);
    rbc_scene_free(&r->scene);
    cli_view_destroy(r->view);
    cJSON_Delete(r->outputs);
}

static void fill_solver(const batch_job *j, rbc_solver_def *sd) {
    if (j->solver >= 0) sd->solver = (rbc_solver_kind)j->solver;
    if (j->energy_guard >= 0) sd->energy_guard = (rbc_energy_guard)j->energy_guard;
}

/* A mesh job: import, one world with the library's default solve (RBC_PRESET_CLOTH:
 * red-black SOR, 480 substeps a second of 11 iterations) unless the job says
 * otherwise, 60 frames at 60 Hz, 0.1 g per vertex, 1000 N/m. */
static int setup_mesh_job(job_run *r) {
    const rbc_api_v1 *api = r->api;
    batch_job *j = r->job;
    j->import.pin_group = j->pin_group[0] ? j->pin_group : NULL;
    rbc_result rc = api->mesh_import(j->mesh, &j->import, &r->mesh);
    if (rc != RBC_OK) return api_fail(r, rc, "import");
    rbc_solver_def sd;
    api->solver_def_preset(&sd, (uint32_t)sizeof sd, RBC_PRESET_CLOTH);
    fill_solver(j, &sd);
    rbc_world_def wd;
    api->world_def_init(&wd, (uint32_t)sizeof wd);
    wd.substeps = j->substeps > 0 ? (uint32_t)j->substeps : 0; /* 0: the substep rate */
    wd.linear_iterations = j->iterations > 0 ? (uint32_t)j->iterations : 11;
    wd.nonlinear_iterations = j->nonlinear > 0 ? (uint32_t)j->nonlinear : 1;
    wd.thread_count = (uint32_t)j->threads;
    wd.solver = &sd;
    rc = api->world_create(&wd, &r->world);
    if (rc != RBC_OK) return api_fail(r, rc, "world");
    rbc_cloth_def cd;
    api->cloth_def_init(&cd, (uint32_t)sizeof cd);
    cd.vertex_mass = j->vertex_mass > 0 ? (float)j->vertex_mass : 1e-4f;
    cd.stiffness = j->stiffness > 0 ? (float)j->stiffness : 1000.0f;
    if (j->damping >= 0) cd.damping = (float)j->damping;
    r->cloth_count = 1;
    r->cloths = calloc(1, sizeof *r->cloths);
    if (!r->cloths) return oom(r);
    job_cloth *c = &r->cloths[0];
    rc = api->cloth_create_from_mesh(r->world, r->mesh, &cd, &c->id);
    if (rc != RBC_OK) return api_fail(r, rc, "cloth");
    for (uint32_t k = 0; k < j->collider_count; ++k) {
        rbc_collider_id id;
        rc = api->collider_create(r->world, &j->colliders[k], &id);
        if (rc != RBC_OK) return api_fail(r, rc, "collider");
    }
    size_t np = 0, nq = 0;
    api->mesh_get_positions(r->mesh, NULL, 0, &np);
    api->mesh_get_quads(r->mesh, NULL, 0, &nq);
    c->stem = strdup(j->name);
    c->vertex_count = (uint32_t)(np / 3);
    c->quad_count = (uint32_t)(nq / 4);
    c->rest = malloc((np ? np : 1) * sizeof *c->rest);
    c->quads = malloc((nq ? nq : 1) * sizeof *c->quads);
    if (!c->stem || !c->rest || !c->quads) return oom(r);
    if ((rc = api->mesh_get_positions(r->mesh, c->rest, np, NULL)) != RBC_OK ||
        (rc = api->mesh_get_quads(r->mesh, c->quads, nq, NULL)) != RBC_OK)
        return api_fail(r, rc, "mesh");
    if (j->file_order) {
        size_t nf = 0;
        if ((rc = api->mesh_to_file_positions(r->mesh, NULL, 0, NULL, 0, &nf)) != RBC_OK)
            return api_fail(r, rc, "mesh");
        c->file_count = (uint32_t)(nf / 3);
        c->file_xyz = malloc((nf ? nf : 1) * sizeof *c->file_xyz);
        if (!c->file_xyz) return oom(r);
    }
    return 0;
}

/* A scene job: the scene file (or the built-in one) with the manifest's overrides. */
static int setup_scene_job(job_run *r) {
    const rbc_api_v1 *api = r->api;
    batch_job *j = r->job;
    int load = strcmp(j->scene, "default") == 0
                   ? rbc_scene_load_default(&r->scene, r->err, r->err_size)
                   : rbc_scene_load_file(j->scene, &r->scene, r->err, r->err_size);
    if (load) return -1;
    rbc_scene *s = &r->scene;
    if (j->substeps > 0) s->world.substeps = (uint32_t)j->substeps;
    if (j->iterations > 0) s->world.linear_iterations = (uint32_t)j->iterations;
    if (j->nonlinear > 0) s->world.nonlinear_iterations = (uint32_t)j->nonlinear;
    s->world.thread_count = (uint32_t)j->threads;
    fill_solver(j, &s->world.solver);
    for (uint32_t i = 0; i < s->cloth_count; ++i) {
        if (j->stiffness > 0) s->cloths[i].stiffness = (float)j->stiffness;
        if (j->vertex_mass > 0) s->cloths[i].vertex_mass = (float)j->vertex_mass;
        if (j->damping >= 0) s->cloths[i].damping = (float)j->damping;
    }
    rbc_result rc = rbc_scene_instantiate(api, s, NULL, NULL, &r->instance, r->err, r->err_size);
    if (rc != RBC_OK) return -1;
    r->world = 0;
    r->cloth_count = s->cloth_count;
    r->cloths = calloc(s->cloth_count, sizeof *r->cloths);
    if (!r->cloths) return oom(r);
    for (uint32_t i = 0; i < s->cloth_count; ++i) {
        job_cloth *c = &r->cloths[i];
        const rbc_scene_cloth *sc = &s->cloths[i];
        size_t n = strlen(j->name) + 1 + strlen(sc->name) + 1;
        c->stem = malloc(n);
        if (!c->stem) return oom(r);
        if (s->cloth_count == 1) snprintf(c->stem, n, "%s", j->name);
        else snprintf(c->stem, n, "%s_%s", j->name, sc->name);
        c->id = r->instance.cloths[i];
        c->vertex_count = sc->vertex_count;
        c->quad_count = sc->quad_count;
        c->rest = malloc(3 * sizeof(float) * sc->vertex_count);
        c->quads = malloc(4 * sizeof(uint32_t) * (sc->quad_count ? sc->quad_count : 1));
        if (!c->rest || !c->quads) return oom(r);
        memcpy(c->rest, sc->positions, 3 * sizeof(float) * sc->vertex_count);
        memcpy(c->quads, sc->quads, 4 * sizeof(uint32_t) * sc->quad_count);
    }
    return 0;
}

/* `path` (under the job's folder) into the outputs list, relative to that folder. */
static int add_output(job_run *r, const char *path) {
    const char *dir = r->job->dir;
    size_t n = strlen(dir);
    const char *rel = strncmp(path, dir, n) == 0 && path[n] == '/' ? path + n + 1 : path;
    return cJSON_AddItemToArray(r->outputs, cJSON_CreateString(rel)) ? 0 : oom(r);
}

/* The rest mesh, then one open cache per output format and cloth. */
static int start_outputs(job_run *r) {
    const rbc_api_v1 *api = r->api;
    batch_job *j = r->job;
    for (uint32_t i = 0; i < r->cloth_count; ++i) {
        job_cloth *c = &r->cloths[i];
        rbc_world_id world = r->world ? r->world : r->instance.world;
        rbc_result rc = api->cloth_get_topology(world, c->id, &c->spring_count, &c->color_count);
        if (rc != RBC_OK) return api_fail(r, rc, "topology");
        char *obj = job_file(j, c->stem, ".obj");
        if (!obj) return oom(r);
        /* A mesh job's rest mesh is the file's own (its faces, UVs, normals and
         * groups), in the order its caches have. */
        rc = r->mesh ? api->mesh_write_file_obj(r->mesh, NULL, 0,
                                                j->file_order ? RBC_ORDER_FILE : RBC_ORDER_MESH,
                                                obj)
                     : api->write_obj(obj, c->rest, c->vertex_count, c->quads, c->quad_count);
        int bad = rc != RBC_OK ? api_fail(r, rc, "rest mesh") : add_output(r, obj);
        free(obj);
        if (bad) return -1;
        const struct {
            int on;
            rbc_cache_format format;
            const char *ext;
        } kinds[3] = {{j->out_pc2, RBC_CACHE_PC2, ".pc2"},
                      {j->out_mdd, RBC_CACHE_MDD, ".mdd"},
                      {j->out_objseq, RBC_CACHE_OBJ_SEQUENCE, NULL}};
        for (int k = 0; k < 3; ++k) {
            if (!kinds[k].on) continue;
            rbc_cache_def cd;
            api->cache_def_init(&cd, (uint32_t)sizeof cd);
            cd.format = kinds[k].format;
            char *path = kinds[k].ext ? job_file(j, c->stem, kinds[k].ext) : objseq_prefix(j, c->stem);
            if (!path) return oom(r);
            cd.path = path;
            /* An OBJ sequence stays in the simulation's order: each frame is a whole
             * mesh with its own faces, not a cache played on the file's mesh. */
            c->file_order[k] = c->file_xyz && kinds[k].format != RBC_CACHE_OBJ_SEQUENCE;
            cd.point_count = c->file_order[k] ? c->file_count : c->vertex_count;
            cd.start_frame = 1.0f; /* sample k = after k + 1 steps; frame 0 is the OBJ */
            cd.sample_rate = 1.0f;
            cd.frame_rate = (float)(1.0 / j->dt); /* MDD times: frame k at k dt seconds */
            cd.quads = c->quads;
            cd.quad_count = c->quad_count;
            rc = api->cache_create(&cd, &c->caches[k]);
            if (rc == RBC_OK && !kinds[k].ext) {
                /* The sequence is complete when its last frame exists. */
                size_t n = strlen(path) + 32;
                char *last = malloc(n);
                if (last) snprintf(last, n, "%s_%04ld.obj", path, j->frames);
                bad = last ? add_output(r, last) : oom(r);
                free(last);
            } else if (rc == RBC_OK) {
                bad = add_output(r, path);
            }
            free(path);
            if (rc != RBC_OK) return api_fail(r, rc, "cache");
            if (bad) return -1;
        }
    }
    return 0;
}

static int view_colliders(job_run *r, double time);

/* Cloth i's positions of this frame into the viewer, after the quads torn so far
 * (scene cloths with tear_strain). */
static int view_cloth(job_run *r, uint32_t i, const float *xyz) {
    const rbc_api_v1 *api = r->api;
    if (!r->job->mesh && r->scene.cloths[i].tear_strain > 0.0f) {
        rbc_world_id world = r->world ? r->world : r->instance.world;
        size_t count = 0;
        rbc_result rc = api->cloth_get_quads(world, r->cloths[i].id, NULL, 0, &count);
        uint32_t *quads = rc == RBC_OK ? malloc((count ? count : 1) * sizeof *quads) : NULL;
        if (rc == RBC_OK && !quads) return oom(r);
        if (rc == RBC_OK) rc = api->cloth_get_quads(world, r->cloths[i].id, quads, count, &count);
        int bad = rc == RBC_OK &&
                  cli_view_set_remaining_quads(r->view, i, quads, count / 4, r->err, r->err_size);
        free(quads);
        if (rc != RBC_OK) return api_fail(r, rc, "torn quads");
        if (bad) return -1;
    }
    if (cli_view_frame_cloth(r->view, i, xyz)) {
        snprintf(r->err, r->err_size, "viewer: %s", cli_view_last_error(r->view));
        return -1;
    }
    return 0;
}

/* The viewer of a job: its cloths (rest meshes) and colliders, and frame 0. */
static int start_view(job_run *r) {
    batch_job *j = r->job;
    const rbc_scene *sc = j->mesh ? NULL : &r->scene;
    if (cli_view_create(&r->view, j->name, j->dt, (uint32_t)j->frames + 1, r->err, r->err_size))
        return -1;
    for (uint32_t i = 0; i < r->cloth_count; ++i) {
        const job_cloth *c = &r->cloths[i];
        cli_view_cloth_def d = {c->stem, c->vertex_count, c->rest, c->quad_count, c->quads, 0, NULL};
        if (cli_view_add_cloth(r->view, &d, r->err, r->err_size)) return -1;
    }
    uint32_t count = sc ? sc->collider_count : j->collider_count;
    if (count > sizeof r->view_collider / sizeof r->view_collider[0])
        count = sizeof r->view_collider / sizeof r->view_collider[0];
    int32_t shown = 0;
    for (uint32_t k = 0; k < count; ++k) {
        r->view_collider[k] = -1;
        cli_view_collider_def d;
        memset(&d, 0, sizeof d);
        if (sc) {
            const rbc_scene_collider *c = &sc->colliders[k];
            if (c->shape == RBC_SHAPE_TRIANGLE_MESH && !c->mesh_positions) continue;
            d.shape = c->shape;
            d.radius = c->radius;
            memcpy(d.half_extents, c->half_extents, sizeof d.half_extents);
            d.mesh_vertex_count = c->mesh_vertex_count;
            d.mesh_positions = c->mesh_positions;
            d.mesh_triangle_count = c->mesh_triangle_count;
            d.mesh_triangles = c->mesh_triangles;
        } else {
            d.shape = j->colliders[k].shape;
            d.radius = j->colliders[k].radius;
            memcpy(d.half_extents, j->colliders[k].half_extents, sizeof d.half_extents);
        }
        if (cli_view_add_collider(r->view, &d, r->err, r->err_size)) return -1;
        r->view_collider[k] = shown++;
    }
    for (uint32_t i = 0; i < r->cloth_count; ++i)
        if (cli_view_frame_cloth(r->view, i, r->cloths[i].rest)) goto fail;
    return view_colliders(r, 0.0);
fail:
    snprintf(r->err, r->err_size, "viewer: %s", cli_view_last_error(r->view));
    return -1;
}

/* Every collider's pose at `time` into the viewer. */
static int view_colliders(job_run *r, double time) {
    batch_job *j = r->job;
    const rbc_scene *sc = j->mesh ? NULL : &r->scene;
    uint32_t count = sc ? sc->collider_count : j->collider_count;
    if (count > sizeof r->view_collider / sizeof r->view_collider[0])
        count = sizeof r->view_collider / sizeof r->view_collider[0];
    for (uint32_t k = 0; k < count; ++k) {
        if (r->view_collider[k] < 0) continue;
        float p[3], q[4];
        if (sc) {
            rbc_scene_collider_pose(&sc->colliders[k], time, p, q);
        } else {
            memcpy(p, j->colliders[k].position, sizeof p);
            memcpy(q, j->colliders[k].rotation, sizeof q);
        }
        if (cli_view_frame_collider(r->view, (uint32_t)r->view_collider[k], p, q)) {
            snprintf(r->err, r->err_size, "viewer: %s", cli_view_last_error(r->view));
            return -1;
        }
    }
    return 0;
}

/* JOB.png (the last frame) and JOB.html, listed with the outputs. */
static int finish_view(job_run *r) {
    batch_job *j = r->job;
    char *png = job_file(j, j->name, ".png"), *html = job_file(j, j->name, ".html");
    uint32_t total = cli_view_frame_total(r->view);
    int rc = !png || !html ? oom(r)
             : cli_view_write_png(r->view, png, total ? total - 1 : 0, 0, 0, r->err, r->err_size) ||
                     cli_view_write_html(r->view, html, r->err, r->err_size)
                 ? -1
                 : 0;
    if (rc == 0) rc = add_output(r, png) || add_output(r, html) ? -1 : 0;
    free(png);
    free(html);
    return rc;
}

/* Returns 0 done, -1 failed (message in r->err), 1 stopped by a signal. */
static int simulate(job_run *r, rbc_world_stats *last, double *ms_per_frame) {
    const rbc_api_v1 *api = r->api;
    batch_job *j = r->job;
    rbc_world_id world = r->world ? r->world : r->instance.world;
    uint32_t max_n = 0;
    for (uint32_t i = 0; i < r->cloth_count; ++i)
        if (r->cloths[i].vertex_count > max_n) max_n = r->cloths[i].vertex_count;
    float *xyz = malloc(3 * sizeof(float) * (max_n ? max_n : 1));
    if (!xyz) return oom(r);
    double step_ms = 0.0;
    float dt = (float)j->dt;
    for (long f = 0; f < j->frames; ++f) {
        if (g_stop) {
            free(xyz);
            return 1;
        }
        if (!j->mesh) {
            /* A scene's moving colliders and drags, as `rbcloth run` moves them. */
            rbc_result ac = rbc_scene_apply_frame(api, &r->scene, &r->instance, (uint32_t)f, r->err,
                                                  r->err_size);
            if (ac != RBC_OK) {
                free(xyz);
                return -1;
            }
        }
        rbc_result rc = api->world_step(world, dt);
        memset(last, 0, sizeof *last);
        last->struct_size = sizeof *last;
        last->skip_measures = f + 1 < j->frames; /* Eq. 7 and energies: last frame only */
        if (rc == RBC_OK) rc = api->world_get_stats(world, last);
        if (rc != RBC_OK) {
            free(xyz);
            char what[64];
            snprintf(what, sizeof what, "frame %ld", f + 1);
            return api_fail(r, rc, what);
        }
        step_ms += last->step_ms;
        for (uint32_t i = 0; i < r->cloth_count; ++i) {
            job_cloth *c = &r->cloths[i];
            rc = api->cloth_read_positions(world, c->id, xyz, 3 * (size_t)max_n, NULL);
            if (rc == RBC_OK && c->file_xyz)
                rc = api->mesh_to_file_positions(r->mesh, xyz, 3 * (size_t)c->vertex_count,
                                                 c->file_xyz, 3 * (size_t)c->file_count, NULL);
            for (int k = 0; rc == RBC_OK && k < 3; ++k)
                if (c->caches[k])
                    rc = api->cache_write_frame(c->caches[k], c->file_order[k] ? c->file_xyz : xyz);
            if (rc != RBC_OK) {
                free(xyz);
                return api_fail(r, rc, "writing a frame");
            }
            if (r->view && view_cloth(r, i, xyz)) {
                free(xyz);
                return -1;
            }
        }
        if (r->view && view_colliders(r, (double)(f + 1) * j->dt)) {
            free(xyz);
            return -1;
        }
    }
    free(xyz);
    *ms_per_frame = j->frames > 0 ? step_ms / (double)j->frames : 0.0;
    for (uint32_t i = 0; i < r->cloth_count; ++i)
        for (int k = 0; k < 3; ++k) {
            if (!r->cloths[i].caches[k]) continue;
            rbc_result rc = api->cache_finish(r->cloths[i].caches[k]);
            r->cloths[i].caches[k] = 0;
            if (rc != RBC_OK) return api_fail(r, rc, "finishing a cache");
        }
    return 0;
}

/* Every output on disk before result.json says so: each file fsync'd (an OBJ
 * sequence's frames by one syncfs: one fsync per frame took 2.1 s for 2,000 frames,
 * syncfs 0.06 s), then the folders that hold them; with each one's size (resume
 * checks it) and CRC-32 (to check a copy) for the result. */
static int sync_outputs(job_run *r, cJSON *sizes, cJSON *crcs) {
    batch_job *j = r->job;
    char *frames = j->out_objseq ? fs_path(j->dir, "frames", "") : NULL;
    if (j->out_objseq && !frames) return oom(r);
    int rc = 0;
    if (frames) {
        rc = fs_sync_filesystem(frames, r->err, r->err_size);
        if (rc == 1) {
            /* No syncfs: every frame of every cloth, one by one. */
            rc = 0;
            for (long f = 1; rc == 0 && f <= j->frames; ++f)
                for (uint32_t i = 0; rc == 0 && i < r->cloth_count; ++i) {
                    char name[300];
                    snprintf(name, sizeof name, "%s_%04ld.obj", r->cloths[i].stem, f);
                    char *path = fs_path(frames, name, "");
                    rc = !path ? oom(r) : fs_sync(path, r->err, r->err_size);
                    free(path);
                }
        }
        if (rc == 0) rc = fs_sync(frames, r->err, r->err_size);
    }
    const cJSON *o;
    cJSON_ArrayForEach(o, r->outputs) {
        if (rc) break;
        char *path = output_path(j, o->valuestring);
        uint64_t size = 0;
        uint32_t crc = 0;
        char hex[16];
        if (!path) {
            rc = oom(r);
            break;
        }
        rc = (strncmp(o->valuestring, "frames/", 7) != 0 && fs_sync(path, r->err, r->err_size)) ||
                     fs_file_crc32(path, &size, &crc, r->err, r->err_size)
                 ? -1
                 : 0;
        free(path);
        snprintf(hex, sizeof hex, "%08x", (unsigned)crc);
        if (rc == 0 && (!cJSON_AddItemToArray(sizes, cJSON_CreateNumber((double)size)) ||
                        !cJSON_AddItemToArray(crcs, cJSON_CreateString(hex))))
            rc = oom(r);
    }
    if (rc == 0) rc = fs_sync(j->dir, r->err, r->err_size);
    free(frames);
    return rc;
}

static int write_result(job_run *r, const rbc_world_stats *st, double ms_per_frame,
                        double seconds) {
    batch_job *j = r->job;
    cJSON *o = cJSON_CreateObject();
    if (!o) return oom(r);
    uint32_t vertices = 0, colors = 0, springs = 0;
    for (uint32_t i = 0; i < r->cloth_count; ++i) {
        vertices += r->cloths[i].vertex_count;
        springs += r->cloths[i].spring_count;
        if (r->cloths[i].color_count > colors) colors = r->cloths[i].color_count;
    }
    cJSON_AddStringToObject(o, "name", j->name);
    cJSON_AddStringToObject(o, "source", j->mesh ? j->mesh : j->scene);
    cJSON_AddNumberToObject(o, "cloths", r->cloth_count);
    cJSON_AddNumberToObject(o, "vertices", vertices);
    cJSON_AddNumberToObject(o, "springs", springs);
    cJSON_AddNumberToObject(o, "colors", colors);
    if (r->mesh) {
        rbc_mesh_info info;
        memset(&info, 0, sizeof info);
        info.struct_size = sizeof info;
        if (r->api->mesh_get_info(r->mesh, &info) == RBC_OK) {
            cJSON_AddNumberToObject(o, "quads", info.quad_count);
            cJSON_AddNumberToObject(o, "paired_triangles", info.paired_triangles);
            cJSON_AddNumberToObject(o, "leftover_triangles", info.leftover_triangles);
            cJSON_AddNumberToObject(o, "pins", info.pin_count);
            cJSON_AddBoolToObject(o, "bipartite", info.bipartite != 0);
            /* What a user checks before applying a cache to their own mesh: its
             * order and vertex count, and the units the import found and applied. */
            cJSON_AddStringToObject(o, "cache_order", j->file_order ? "file" : "simulation");
            cJSON_AddNumberToObject(o, "cache_vertices",
                                    j->file_order ? info.file_vertex_count : info.vertex_count);
            cJSON_AddStringToObject(o, "file_order",
                                    info.file_order == RBC_FILE_ORDER_FILE ? "file lists"
                                                                           : "assimp arrays");
            cJSON_AddNumberToObject(o, "file_vertices", info.file_vertex_count);
            cJSON_AddNumberToObject(o, "unmapped_file_vertices", info.unmapped_file_vertices);
            cJSON *u = cJSON_AddObjectToObject(o, "units");
            if (u) {
                if (info.file_unit_metres > 0.0f)
                    cJSON_AddNumberToObject(u, "file_unit_metres", info.file_unit_metres);
                else
                    cJSON_AddNullToObject(u, "file_unit_metres");
                cJSON_AddNumberToObject(u, "applied_scale", info.applied_scale);
                cJSON_AddBoolToObject(u, "kept_file_units", j->import.keep_file_units != 0);
            }
        }
    }
    cJSON_AddNumberToObject(o, "frames", (double)j->frames);
    cJSON_AddNumberToObject(o, "ms_per_frame", ms_per_frame);
    cJSON_AddNumberToObject(o, "seconds", seconds);
    cJSON_AddNumberToObject(o, "error_eq7", st->error_eq7);
    cJSON_AddNumberToObject(o, "max_strain", st->max_strain);
    cJSON_AddNumberToObject(o, "energy_clamped_steps", (double)st->energy_clamped_steps);
    cJSON_AddStringToObject(o, "stability",
                            st->energy_clamped_steps ? "energy guard clamped" : "stable");
    cJSON *sizes = cJSON_CreateArray(), *crcs = cJSON_CreateArray();
    if (!sizes || !crcs || sync_outputs(r, sizes, crcs)) {
        cJSON_Delete(sizes);
        cJSON_Delete(crcs);
        cJSON_Delete(o);
        return sizes && crcs ? -1 : oom(r);
    }
    /* Paths relative to the job's folder (DIR/NAME/), as resume reads them. */
    cJSON_AddItemToObject(o, "outputs", r->outputs);
    r->outputs = NULL;
    cJSON_AddItemToObject(o, "output_bytes", sizes);
    cJSON_AddItemToObject(o, "output_crc32", crcs);
    char *text = cJSON_Print(o);
    cJSON_Delete(o);
    if (!text) return oom(r);
    int rc = fs_write_atomic(j->result_path, text, strlen(text), r->err, r->err_size);
    free(text);
    return rc;
}

/* The child: returns its exit status (0 ok, 1 failed, 3 stopped), message in err. */
static int run_job(const rbc_api_v1 *api, batch_job *j, char *err, size_t err_size) {
    double start = now_seconds();
    job_run r = {.api = api, .job = j, .err = err, .err_size = err_size,
                 .outputs = cJSON_CreateArray()};
    int rc = fs_mkdir_p(j->dir, err, err_size);
    if (rc == 0 && j->out_objseq) {
        size_t n = strlen(j->dir) + 8;
        char *frames = malloc(n);
        if (frames) snprintf(frames, n, "%s/frames", j->dir);
        rc = frames ? fs_mkdir_p(frames, err, err_size) : oom(&r);
        free(frames);
    }
    if (rc == 0) rc = j->mesh ? setup_mesh_job(&r) : setup_scene_job(&r);
    if (rc == 0) {
        if (j->frames < 0) j->frames = j->mesh ? 60 : (long)r.scene.frames;
        if (j->dt < 0) j->dt = j->mesh ? 1.0 / 60.0 : (double)r.scene.dt;
        rc = start_outputs(&r);
        if (rc == 0) rc = start_view(&r);
    }
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    double ms = 0.0;
    if (rc == 0) rc = simulate(&r, &st, &ms);
    if (rc == 0) rc = finish_view(&r);
    if (rc == 0) rc = write_result(&r, &st, ms, now_seconds() - start);
    job_run_free(&r); /* destroys unfinished caches: their temporary files go */
    return rc == 0 ? 0 : rc == 1 ? 3 : 1;
}

/* ------------------------------------------------------------------------- */
/* The parent: scheduling, progress, report                                  */
/* ------------------------------------------------------------------------- */

/* A job's time limit in seconds (0: none): its manifest's "timeout", else
 * --job-timeout. */
static double job_timeout(const batch *b, const batch_job *j) {
    return j->timeout >= 0.0 ? j->timeout : b->options->job_timeout;
}

static int launch(batch *b, batch_job *j) {
    int fds[2];
    if (pipe(fds) != 0) {
        snprintf(j->message, sizeof j->message, "pipe: %s", strerror(errno));
        return -1;
    }
    /* Close-on-exec: a process the worker execs (the import helper) must not keep
     * the write end, or collect()'s read would wait for it after the worker died. */
    fcntl(fds[0], F_SETFD, FD_CLOEXEC);
    fcntl(fds[1], F_SETFD, FD_CLOEXEC);
    fflush(stdout);
    fflush(stderr);
    const pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(j->message, sizeof j->message, "fork: %s", strerror(errno));
        close(fds[0]);
        close(fds[1]);
        return -1;
    }
    if (pid == 0) {
#ifdef __linux__
        /* A worker dies with the batch: one left running after `kill -9` of the
         * parent would write the same files as a resumed batch. If the parent died
         * before prctl, this process has been re-parented already. */
        if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != parent) _exit(4);
#endif
        (void)parent;
        close(fds[0]);
        char err[MESSAGE_MAX] = "";
        int status = run_job(b->api, j, err, sizeof err);
        if (status != 0 && err[0]) {
            ssize_t w = write(fds[1], err, strlen(err));
            (void)w;
        }
        close(fds[1]);
        _exit(status);
    }
    close(fds[1]);
    j->pid = pid;
    j->pipe_fd = fds[0];
    j->status = JOB_RUNNING;
    j->started = now_seconds();
    return 0;
}

static void collect(const batch *b, batch_job *j, int wstatus) {
    ssize_t n = read(j->pipe_fd, j->message, sizeof j->message - 1);
    j->message[n > 0 ? n : 0] = '\0';
    close(j->pipe_fd);
    j->pipe_fd = -1;
    j->seconds = now_seconds() - j->started;
    remove_job_tmp(j);
    const int exited_ok = WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0;
    if (j->timed_out && !exited_ok) { /* (not one that ended as the kill was sent) */
        j->status = JOB_FAILED;
        snprintf(j->message, sizeof j->message, "timed out after %g s (killed)", job_timeout(b, j));
    } else if (j->killed && !exited_ok) {
        j->status = JOB_INTERRUPTED;
        if (j->killed == 2)
            snprintf(j->message, sizeof j->message,
                     "stopped by a signal: killed at a second signal");
        else
            snprintf(j->message, sizeof j->message,
                     "stopped by a signal: killed, still running %g s after SIGTERM",
                     b->options->term_grace);
    } else if (exited_ok) {
        if (job_done(j)) {
            j->status = JOB_OK;
        } else {
            j->status = JOB_FAILED;
            snprintf(j->message, sizeof j->message, "finished but its outputs are missing");
        }
    } else if ((WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 3) ||
               (g_stop && WIFSIGNALED(wstatus) &&
                (WTERMSIG(wstatus) == SIGTERM || WTERMSIG(wstatus) == SIGINT))) {
        j->status = JOB_INTERRUPTED;
        snprintf(j->message, sizeof j->message, "stopped by a signal");
    } else {
        j->status = JOB_FAILED;
        if (WIFSIGNALED(wstatus))
            snprintf(j->message, sizeof j->message, "crashed: signal %d (%s)", WTERMSIG(wstatus),
                     strsignal(WTERMSIG(wstatus)));
        else if (!j->message[0])
            snprintf(j->message, sizeof j->message, "exit status %d", WEXITSTATUS(wstatus));
    }
}

static double result_number(const batch_job *j, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(j->result, key);
    return cJSON_IsNumber(v) ? v->valuedouble : NAN;
}

static void print_job_line(const batch_job *j, size_t finished, size_t total) {
    if (j->status == JOB_OK || j->status == JOB_SKIPPED)
        printf("[%zu/%zu] %-7s %s: %.0f vertices, %.0f colors, %.3f ms/frame, Eq. 7 %.3g, "
               "%.0f clamped steps%s\n",
               finished, total, status_names[j->status], j->name, result_number(j, "vertices"),
               result_number(j, "colors"), result_number(j, "ms_per_frame"),
               result_number(j, "error_eq7"), result_number(j, "energy_clamped_steps"),
               j->status == JOB_SKIPPED ? " (outputs exist)" : "");
    else
        printf("[%zu/%zu] %-7s %s: %s\n", finished, total, status_names[j->status], j->name,
               j->message);
    fflush(stdout);
}

static int progress_visible = 0;

static void progress_draw(const batch *b, size_t finished, size_t running, size_t failed,
                          double elapsed) {
    enum { WIDTH = 30 };
    char bar[WIDTH + 1];
    size_t filled = finished * WIDTH / (b->job_count ? b->job_count : 1);
    for (size_t i = 0; i < WIDTH; ++i) bar[i] = i < filled ? '#' : '.';
    bar[WIDTH] = '\0';
    fprintf(stderr, "\r\033[K[%s] %zu/%zu jobs, %zu running, %zu failed, %.1f s", bar, finished,
            b->job_count, running, failed, elapsed);
    fflush(stderr);
    progress_visible = 1;
}

static void progress_clear(void) {
    if (progress_visible) fputs("\r\033[K", stderr);
    progress_visible = 0;
}

/* The report's "caches" cell of a mesh job: the order and vertex count of its
 * PC2/MDD, and the file's unit with the scale applied (so a user sees at once that
 * a centimetre FBX became metres). Empty for a scene job. */
static void cache_summary(const cJSON *result, char *out, size_t cap) {
    out[0] = '\0';
    const cJSON *order = cJSON_GetObjectItemCaseSensitive(result, "cache_order");
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(result, "cache_vertices");
    const cJSON *u = cJSON_GetObjectItemCaseSensitive(result, "units");
    if (!cJSON_IsString(order) || !cJSON_IsNumber(n)) return;
    const cJSON *unit = cJSON_GetObjectItemCaseSensitive(u, "file_unit_metres");
    const cJSON *scale = cJSON_GetObjectItemCaseSensitive(u, "applied_scale");
    const cJSON *kept = cJSON_GetObjectItemCaseSensitive(u, "kept_file_units");
    char unit_text[64] = "no unit declared";
    if (cJSON_IsNumber(unit))
        snprintf(unit_text, sizeof unit_text, "file unit %.6g m%s", unit->valuedouble,
                 cJSON_IsTrue(kept) ? " (kept)" : "");
    snprintf(out, cap, "%s order, %.0f vertices; %s, scale %.6g", order->valuestring,
             n->valuedouble, unit_text, cJSON_IsNumber(scale) ? scale->valuedouble : 1.0);
}

static cJSON *report_entry(const batch_job *j) {
    cJSON *o = j->result ? cJSON_Duplicate(j->result, 1) : cJSON_CreateObject();
    if (!o) return NULL;
    if (!j->result) {
        cJSON_AddStringToObject(o, "name", j->name);
        cJSON_AddStringToObject(o, "source", j->mesh ? j->mesh : j->scene);
        cJSON_AddItemToObject(o, "outputs", cJSON_CreateArray());
    }
    cJSON_DeleteItemFromObjectCaseSensitive(o, "status");
    cJSON_AddStringToObject(o, "status", status_names[j->status]);
    if (j->message[0]) cJSON_AddStringToObject(o, "message", j->message);
    return o;
}

/* DIR/index.html: a still per job, each linking to the job's player page. */
static int write_index(const batch *b, char *err, size_t err_size) {
    cli_view_index_entry *e = calloc(b->job_count ? b->job_count : 1, sizeof *e);
    char (*hrefs)[2][300] = calloc(b->job_count ? b->job_count : 1, sizeof *hrefs);
    char *path = fs_path(b->options->out_dir, "index", ".html");
    int rc = -1;
    if (!e || !hrefs || !path) {
        snprintf(err, err_size, "out of memory");
        goto done;
    }
    for (size_t k = 0; k < b->job_count; ++k) {
        const batch_job *j = &b->jobs[k];
        e[k].name = j->name;
        e[k].status = status_names[j->status];
        if (j->status == JOB_OK || j->status == JOB_SKIPPED) {
            snprintf(hrefs[k][0], sizeof hrefs[k][0], "%s/%s.html", j->name, j->name);
            snprintf(hrefs[k][1], sizeof hrefs[k][1], "%s/%s.png", j->name, j->name);
            e[k].page_href = hrefs[k][0];
            e[k].png_href = hrefs[k][1];
        }
    }
    char title[300];
    const char *m = b->options->manifest_path;
    snprintf(title, sizeof title, "rbcloth batch: %s", strrchr(m, '/') ? strrchr(m, '/') + 1 : m);
    rc = cli_view_write_index(path, title, e, (uint32_t)b->job_count, err, err_size);
    /* The viewer renames its file into place; on disk too, as the reports are. */
    if (rc == 0) rc = fs_sync(path, err, err_size) || fs_sync_parent(path, err, err_size) ? -1 : 0;
done:
    free(e);
    free(hrefs);
    free(path);
    return rc;
}

static int write_reports(const batch *b, double wall, char *err, size_t err_size) {
    cJSON *root = cJSON_CreateObject();
    cJSON *list = cJSON_CreateArray();
    size_t counts[7] = {0};
    for (size_t k = 0; k < b->job_count; ++k) counts[b->jobs[k].status]++;
    cJSON_AddStringToObject(root, "manifest", b->options->manifest_path);
    cJSON_AddNumberToObject(root, "workers", (double)b->options->jobs);
    cJSON_AddNumberToObject(root, "wall_seconds", wall);
    /* --report-only: merged from results that earlier runs (array tasks) left. */
    if (b->options->report_only) cJSON_AddTrueToObject(root, "merged");
    cJSON_AddNumberToObject(root, "jobs_total", (double)b->job_count);
    for (int s = JOB_OK; s <= JOB_NOT_RUN; ++s) {
        char key[32];
        snprintf(key, sizeof key, "jobs_%s", status_names[s]);
        for (char *c = key; *c; ++c)
            if (*c == ' ') *c = '_';
        cJSON_AddNumberToObject(root, key, (double)counts[s]);
    }
    for (size_t k = 0; k < b->job_count; ++k) cJSON_AddItemToArray(list, report_entry(&b->jobs[k]));
    cJSON_AddItemToObject(root, "jobs", list);
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    char *json_path = fs_path(b->options->out_dir, "batch_report", ".json");
    char *md_path = fs_path(b->options->out_dir, "batch_report", ".md");
    int rc = !text || !json_path || !md_path ? (snprintf(err, err_size, "out of memory"), -1)
                                             : fs_write_atomic(json_path, text, strlen(text), err,
                                                               err_size);
    free(text);
    /* The Markdown table. */
    size_t cap = 4096 + b->job_count * 2048, len = 0;
    char *md = rc == 0 ? malloc(cap) : NULL;
    if (rc == 0 && !md) rc = -1, snprintf(err, err_size, "out of memory");
    if (md) {
        char how[96];
        if (b->options->report_only)
            snprintf(how, sizeof how, "merged from the results in the output folder");
        else
            snprintf(how, sizeof how, "%.2f s wall with -j %ld", wall, b->options->jobs);
        len += (size_t)snprintf(md + len, cap - len,
                                "# rbcloth batch report\n\n%s: %zu jobs, %zu ok, %zu skipped, %zu "
                                "failed, %zu interrupted, %zu not run; %s\n\n"
                                "| job | status | mesh | vertices | colors | ms/frame | final Eq. 7 "
                                "| clamped steps | stability | caches | outputs |\n"
                                "|---|---|---|---|---|---|---|---|---|---|---|\n",
                                b->options->manifest_path, b->job_count, counts[JOB_OK],
                                counts[JOB_SKIPPED], counts[JOB_FAILED], counts[JOB_INTERRUPTED],
                                counts[JOB_NOT_RUN], how);
        for (size_t k = 0; k < b->job_count && len < cap; ++k) {
            const batch_job *j = &b->jobs[k];
            const char *src = j->mesh ? j->mesh : j->scene;
            const char *base = strrchr(src, '/') ? strrchr(src, '/') + 1 : src;
            if (j->result) {
                const cJSON *st = cJSON_GetObjectItemCaseSensitive(j->result, "stability");
                char caches[160];
                cache_summary(j->result, caches, sizeof caches);
                len += (size_t)snprintf(md + len, cap - len,
                                        "| %s | %s | %s | %.0f | %.0f | %.3f | %.3g | %.0f | %s | %s | ",
                                        j->name, status_names[j->status], base,
                                        result_number(j, "vertices"), result_number(j, "colors"),
                                        result_number(j, "ms_per_frame"),
                                        result_number(j, "error_eq7"),
                                        result_number(j, "energy_clamped_steps"),
                                        cJSON_IsString(st) ? st->valuestring : "", caches);
                const cJSON *o;
                int first = 1;
                const int sized =
                    cJSON_GetObjectItemCaseSensitive(j->result, "output_bytes") != NULL;
                cJSON_ArrayForEach(o, cJSON_GetObjectItemCaseSensitive(j->result, "outputs")) {
                    /* As DIR/..: relative to the job's folder; a result without sizes
                     * has them as --out gave them. */
                    const char *p = cJSON_IsString(o) ? o->valuestring : "";
                    const size_t n = strlen(b->options->out_dir);
                    const int legacy =
                        !sized && strncmp(p, b->options->out_dir, n) == 0 && p[n] == '/';
                    const int as_is = legacy || p[0] == '/';
                    if (len < cap)
                        len += (size_t)snprintf(md + len, cap - len, "%s%s%s%s",
                                                first ? "" : "<br>", as_is ? "" : j->name,
                                                as_is ? "" : "/", legacy ? p + n + 1 : p);
                    first = 0;
                }
                if (len < cap) len += (size_t)snprintf(md + len, cap - len, " |\n");
            } else {
                char msg[256];
                snprintf(msg, sizeof msg, "%s", j->message);
                for (char *c = msg; *c; ++c)
                    if (*c == '|' || *c == '\n') *c = ' ';
                len += (size_t)snprintf(md + len, cap - len,
                                        "| %s | %s | %s | | | | | | %s | |\n", j->name,
                                        status_names[j->status], base, msg);
            }
        }
        if (len >= cap) len = cap - 1;
        rc = fs_write_atomic(md_path, md, len, err, err_size);
        free(md);
    }
    free(json_path);
    free(md_path);
    if (rc == 0) rc = write_index(b, err, err_size);
    return rc;
}

/* DIR/NAME/NAME.status.json: why a job did not finish ({"status", "message"}), so
 * that --report-only (the merge step of a Slurm array, where each task ran one job)
 * can report failures as well as results. Removed once the job succeeds. */
static char *status_path(const batch_job *j) { return fs_path(j->dir, j->name, ".status.json"); }

static void record_status(const batch_job *j) {
    char *path = status_path(j);
    if (!path) return;
    if (j->status == JOB_OK || j->status == JOB_SKIPPED) {
        remove(path);
    } else if (j->status == JOB_FAILED || j->status == JOB_INTERRUPTED) {
        char err[512];
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", j->name);
        cJSON_AddStringToObject(o, "status", status_names[j->status]);
        cJSON_AddStringToObject(o, "message", j->message);
        char *text = cJSON_Print(o);
        if (text && fs_mkdir_p(j->dir, err, sizeof err) == 0)
            fs_write_atomic(path, text, strlen(text), err, sizeof err);
        free(text);
        cJSON_Delete(o);
    }
    free(path);
}

/* --report-only: a job's state from what earlier runs left in its folder. */
static void load_status(batch_job *j) {
    if (job_done(j)) {
        j->status = JOB_OK;
        return;
    }
    j->status = JOB_NOT_RUN;
    char *path = status_path(j);
    char *text = path ? read_text(path, NULL) : NULL;
    cJSON *o = text ? cJSON_Parse(text) : NULL;
    const cJSON *st = cJSON_GetObjectItemCaseSensitive(o, "status");
    const cJSON *msg = cJSON_GetObjectItemCaseSensitive(o, "message");
    if (cJSON_IsString(st))
        j->status = strcmp(st->valuestring, "interrupted") == 0 ? JOB_INTERRUPTED : JOB_FAILED;
    if (cJSON_IsString(msg)) snprintf(j->message, sizeof j->message, "%s", msg->valuestring);
    if (j->status == JOB_NOT_RUN) snprintf(j->message, sizeof j->message, "no result");
    cJSON_Delete(o);
    free(text);
    free(path);
}

int cli_batch(const cli_plugin *plugin, const cli_batch_options *options) {
    batch b;
    memset(&b, 0, sizeof b);
    b.api = plugin->api;
    b.options = options;
    char err[2048];
    if (load_manifest(&b, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
        free(b.jobs);
        return 1;
    }
    if (options->count_only) {
        printf("%zu\n", b.job_count);
        for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
        free(b.jobs);
        return 0;
    }
    if (options->only >= 0 && (size_t)options->only >= b.job_count) {
        fprintf(stderr, "rbcloth: --only %ld: %s has %zu jobs (0 to %zu)\n", options->only,
                options->manifest_path, b.job_count, b.job_count - 1);
        for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
        free(b.jobs);
        return 1;
    }
    if (fs_mkdir_p(options->out_dir, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
        free(b.jobs);
        return 1;
    }
    /* One batch per folder. --only tasks (a Slurm array's, side by side) and
     * --report-only share the lock; a whole batch needs it alone. A holder that was
     * killed is waited for while its workers exit (they die with it). */
    int lock_fd = -1;
    {
        char owner[128];
        if (options->only >= 0)
            snprintf(owner, sizeof owner, "rbcloth batch --only %ld", options->only);
        else
            snprintf(owner, sizeof owner, "rbcloth batch%s",
                     options->report_only ? " --report-only" : "");
        int lk = fs_lock_dir(options->out_dir, options->only < 0 && !options->report_only, 1,
                             owner, 10.0, &lock_fd, err, sizeof err);
        if (lk != FS_LOCK_TAKEN) {
            fprintf(stderr, "rbcloth: batch: %s\n", err);
            for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
            free(b.jobs);
            return 1;
        }
        if (err[0]) fprintf(stderr, "rbcloth: warning: %s\n", err);
        /* Alone in the folder: the report temporaries of a killed batch go (only
         * theirs: DIR may hold files of its owner). */
        if (options->only < 0 && !options->report_only) {
            remove_tmp_in(options->out_dir, "batch_report.");
            remove_tmp_in(options->out_dir, "index.html");
        }
    }
    for (size_t k = 0; k < b.job_count; ++k) {
        batch_job *j = &b.jobs[k];
        j->pipe_fd = -1;
        j->dir = fs_path(options->out_dir, j->name, "");
        j->result_path = j->dir ? fs_path(j->dir, j->name, ".result.json") : NULL;
        if (!j->dir || !j->result_path) {
            fprintf(stderr, "rbcloth: out of memory\n");
            return 1;
        }
    }

    /* The jobs this run owns: all, or exactly one (--only). */
    const size_t first = options->only >= 0 ? (size_t)options->only : 0;
    const size_t end = options->only >= 0 ? first + 1 : b.job_count;
    const size_t owned = end - first;
    const double start = now_seconds();
    if (options->report_only) {
        for (size_t k = 0; k < b.job_count; ++k) load_status(&b.jobs[k]);
        goto report;
    }

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    struct sigaction old_int, old_term;
    sigaction(SIGINT, &sa, &old_int);
    sigaction(SIGTERM, &sa, &old_term);

    const int show_progress = !options->quiet && isatty(STDERR_FILENO);
    double last_draw = 0.0;
    size_t next = first, running = 0, finished = 0, failed = 0;
    int stopping = 0, hard_stop = 0;
    double kill_at = 0.0; /* after a signal: when workers still running get SIGKILL */
    if (options->only >= 0)
        printf("rbcloth batch: job %ld (%s) of %zu from %s, outputs in %s\n", options->only,
               b.jobs[first].name, b.job_count, options->manifest_path, options->out_dir);
    else
        printf("rbcloth batch: %zu jobs from %s, %ld workers, outputs in %s\n", b.job_count,
               options->manifest_path, options->jobs, options->out_dir);
    fflush(stdout);
    while (next < end || running > 0) {
        double now = now_seconds();
        if (g_stop && !stopping) {
            /* Stop launching; running jobs get SIGTERM and stop at their next frame
             * (their caches are destroyed, so their temporary files go). */
            for (size_t k = 0; k < b.job_count; ++k)
                if (b.jobs[k].status == JOB_RUNNING) kill(b.jobs[k].pid, SIGTERM);
            for (size_t k = next; k < end; ++k) b.jobs[k].status = JOB_NOT_RUN;
            next = end;
            stopping = 1;
            kill_at = now + options->term_grace;
        }
        if (stopping && !hard_stop && (g_stop >= 2 || now >= kill_at)) {
            /* A worker stuck in an importer or in a long frame never reaches its
             * check: it must not keep the batch alive. collect() removes what it
             * left. */
            for (size_t k = 0; k < b.job_count; ++k)
                if (b.jobs[k].status == JOB_RUNNING && !b.jobs[k].timed_out) {
                    kill(b.jobs[k].pid, SIGKILL);
                    b.jobs[k].killed = g_stop >= 2 && now < kill_at ? 2 : 1;
                }
            hard_stop = 1;
        }
        for (size_t k = first; k < end; ++k) {
            batch_job *j = &b.jobs[k];
            double limit = job_timeout(&b, j);
            if (j->status == JOB_RUNNING && limit > 0.0 && !j->timed_out && !j->killed &&
                now - j->started >= limit) {
                kill(j->pid, SIGKILL);
                j->timed_out = 1;
            }
        }
        if (!g_stop && next < end && running < (size_t)options->jobs) {
            batch_job *j = &b.jobs[next++];
            if (job_done(j)) {
                j->status = JOB_SKIPPED;
                finished++;
                progress_clear();
                print_job_line(j, finished, owned);
                continue;
            }
            /* What an earlier run of this job left goes first: temporaries of a
             * killed worker, a result whose outputs are gone or changed. The lock
             * says that no other process writes here. */
            remove_job_tmp(j);
            if (remove(j->result_path) == 0) fs_sync(j->dir, err, sizeof err);
            if (launch(&b, j) == 0) {
                running++;
            } else {
                j->status = JOB_FAILED;
                finished++;
                failed++;
                progress_clear();
                print_job_line(j, finished, owned);
            }
            continue;
        }
        int wstatus = 0;
        pid_t pid = waitpid(-1, &wstatus, WNOHANG);
        if (pid > 0) {
            for (size_t k = 0; k < b.job_count; ++k) {
                batch_job *j = &b.jobs[k];
                if (j->status != JOB_RUNNING || j->pid != pid) continue;
                collect(&b, j, wstatus);
                running--;
                finished++;
                failed += j->status != JOB_OK;
                progress_clear();
                print_job_line(j, finished, owned);
            }
            continue;
        }
        if (show_progress && now - last_draw > 0.2) {
            progress_draw(&b, finished, running, failed, now - start);
            last_draw = now;
        }
        struct timespec ts = {0, 20 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    progress_clear();
    sigaction(SIGINT, &old_int, NULL);
    sigaction(SIGTERM, &old_term, NULL);
    for (size_t k = first; k < end; ++k) record_status(&b.jobs[k]);

report:;
    double wall = now_seconds() - start;
    int rc = 0;
    size_t counts[7] = {0};
    for (size_t k = first; k < end; ++k) counts[b.jobs[k].status]++;
    if (options->only >= 0) {
        /* One array task: its result (or status) file is its report. */
        const batch_job *j = &b.jobs[first];
        if (j->status != JOB_OK && j->status != JOB_SKIPPED) {
            fprintf(stderr, "rbcloth: batch: %s: %s%s%s\n", j->name, status_names[j->status],
                    j->message[0] ? ": " : "", j->message);
            rc = 1;
        }
        for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
        free(b.jobs);
        if (lock_fd >= 0) close(lock_fd);
        return rc;
    }
    if (write_reports(&b, wall, err, sizeof err)) {
        fprintf(stderr, "rbcloth: report: %s\n", err);
        rc = 1;
    }
    printf("rbcloth batch: %zu ok, %zu skipped, %zu failed, %zu interrupted, %zu not run in %.2f s "
           "(-j %ld); report in %s/batch_report.md, stills in index.html\n",
           counts[JOB_OK], counts[JOB_SKIPPED], counts[JOB_FAILED], counts[JOB_INTERRUPTED],
           counts[JOB_NOT_RUN], wall, options->jobs, options->out_dir);
    if (counts[JOB_FAILED] + counts[JOB_INTERRUPTED] + counts[JOB_NOT_RUN] > 0) {
        rc = 1;
        fprintf(stderr, "rbcloth: batch: not every job succeeded:\n");
        for (size_t k = 0; k < b.job_count; ++k) {
            const batch_job *j = &b.jobs[k];
            if (j->status == JOB_FAILED || j->status == JOB_INTERRUPTED || j->status == JOB_NOT_RUN)
                fprintf(stderr, "  %s: %s%s%s\n", j->name, status_names[j->status],
                        j->message[0] ? ": " : "", j->message);
        }
    }
    for (size_t k = 0; k < b.job_count; ++k) job_free(&b.jobs[k]);
    free(b.jobs);
    if (lock_fd >= 0) close(lock_fd); /* the lock goes with the last worker's copy too */
    return rc;
}
