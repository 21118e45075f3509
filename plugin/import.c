/* import.c -- rbc_mesh_import and the meshes it makes: the def is checked here,
 * the file is read by the import helper (rbcloth-import, importer/) in a process of
 * its own, and the mesh it sends back is registered here; then the mesh accessors
 * and rbc_cloth_create_from_mesh.
 *
 * Why a process (docs/design/import.md, "Isolation"): assimp crashes, aborts, hangs
 * and allocates without bound on crafted files, and an exception of its can escape
 * its C API. None of that may end the host, and a thread cannot be stopped safely
 * in the middle of a C++ library; a process can. It also keeps assimp and its
 * libraries out of the plugin that an engine loads. The cost is a spawn per import
 * (about 17 ms on small files, docs/results/import.md) and a copy of the mesh. */
#define _GNU_SOURCE /* dladdr, pipe2 */
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if !defined(_WIN32)
#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#endif

#include "errors.h"
#include "handles.h"
#include "importer/convert.h"
#if !defined(_WIN32)
#include "importer/wire.h"
#endif
#include "registry.h"
#include "replace_file.h"
#include "rbcloth.h"
#include "world.h"

#if !defined(_WIN32)
extern char **environ;
#endif

#define RBC_MAX_MESHES 4096u
#define RBC_IMPORT_DEFAULT_TIMEOUT_MS 60000u

static rbc_reg_entry g_mesh_entries[RBC_MAX_MESHES];
static rbc_registry g_meshes = RBC_REGISTRY_INIT(RBC_KIND_MESH, RBC_MAX_MESHES, g_mesh_entries);

static const char fn_import[] = "rbc_mesh_import";

/* ------------------------------------------------------------------------- */
/* Defaults                                                                  */
/* ------------------------------------------------------------------------- */

static rbc_mesh_import_def import_def_defaults(void) {
    rbc_mesh_import_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.mesh_index = -1;
    d.mesh_name = NULL;
    d.pin_group = NULL;
    d.scale = 1.0f;
    d.weld = 1;
    d.weld_distance = 0.0f;
    d.pair_triangles = 1;
    d.pair_max_angle_deviation_deg = 45.0f;
    d.pair_max_fold_deg = 30.0f;
    d.ngons = RBC_NGON_SPLIT;
    d.pin_color_threshold = 0.5f;
    d.pin_plane[1] = 1.0f;
    d.pin_plane_distance = -1.0f;
    d.pin_point_distance = -1.0f;
    d.pin_top_axis = -1;
    d.pin_top_tolerance = 1e-4f;
    d.timeout_ms = RBC_IMPORT_DEFAULT_TIMEOUT_MS;
    d.memory_limit_mb = 0;
    d.keep_file_units = 0;
    return d;
}

RBC_API rbc_result RBC_CALL rbc_mesh_import_def_init(rbc_mesh_import_def *def,
                                                     uint32_t struct_size) {
    rbc_mesh_import_def d = import_def_defaults();
    return rbc_def_init_common(def, struct_size, &d, &rbc_sizes_import_def,
                               "rbc_mesh_import_def_init");
}

static rbc_result check_def(const char *path, const rbc_mesh_import_def *d) {
    if (d->mesh_index < -1)
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->mesh_index is %d; it must be >= 0, or -1 for all meshes",
                                (int)d->mesh_index);
    if (!(isfinite(d->scale) && d->scale > 0.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->scale is %g; it must be finite and > 0", (double)d->scale);
    if (d->weld > 1 || d->pair_triangles > 1)
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->weld is %u and def->pair_triangles %u; each must be 0 or 1",
                                d->weld, d->pair_triangles);
    if (!(isfinite(d->weld_distance) && d->weld_distance >= 0.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->weld_distance is %g m; it must be finite and >= 0",
                                (double)d->weld_distance);
    if (!(d->pair_max_angle_deviation_deg >= 0.0f && d->pair_max_angle_deviation_deg <= 90.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->pair_max_angle_deviation_deg is %g; range 0..90",
                                (double)d->pair_max_angle_deviation_deg);
    if (!(d->pair_max_fold_deg >= 0.0f && d->pair_max_fold_deg <= 180.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->pair_max_fold_deg is %g; range 0..180",
                                (double)d->pair_max_fold_deg);
    if (d->ngons != RBC_NGON_SPLIT && d->ngons != RBC_NGON_REFUSE)
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->ngons %d is not an rbc_ngon_mode", (int)d->ngons);
    if (!(d->pin_color_threshold >= 0.0f && d->pin_color_threshold <= 1.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->pin_color_threshold is %g; range 0 (off) ..1",
                                (double)d->pin_color_threshold);
    if (!(isfinite(d->pin_plane_distance) && isfinite(d->pin_point_distance) &&
          isfinite(d->pin_top_tolerance) && d->pin_top_tolerance >= 0.0f))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->pin_plane_distance %g, pin_point_distance %g and "
                                "pin_top_tolerance %g must be finite (the tolerance >= 0)",
                                (double)d->pin_plane_distance, (double)d->pin_point_distance,
                                (double)d->pin_top_tolerance);
    if (d->pin_plane_distance >= 0.0f) {
        for (int c = 0; c < 4; ++c)
            if (!isfinite(d->pin_plane[c]))
                return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                        "def->pin_plane[%d] is not finite", c);
        if (d->pin_plane[0] == 0.0f && d->pin_plane[1] == 0.0f && d->pin_plane[2] == 0.0f)
            return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                    "def->pin_plane has a zero normal (its first three values)");
    }
    if (d->pin_point_distance >= 0.0f)
        for (int c = 0; c < 3; ++c)
            if (!isfinite(d->pin_point[c]))
                return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                        "def->pin_point[%d] is not finite", c);
    if (d->keep_file_units > 1)
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->keep_file_units is %u; it must be 0 or 1",
                                d->keep_file_units);
    if (d->pin_top_axis < -1 || d->pin_top_axis > 2)
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "def->pin_top_axis is %d; 0 (x), 1 (y), 2 (z) or -1 (off)",
                                (int)d->pin_top_axis);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* The import helper                                                         */
/* ------------------------------------------------------------------------- */

/* Windows builds have no helper (plugin/CMakeLists.txt): it is spawned with
 * posix_spawn, answers over a socketpair and is limited with setrlimit, none of
 * which Windows has; rbc_mesh_import refuses there (below). */
#if !defined(_WIN32)

#define HELPER_NAME "rbcloth-import"

/* Where the helper is: $RBC_IMPORT_HELPER, else next to this library, else
 * ../libexec/rbcloth/ from it (an installed tree). 0 and the places looked in
 * (for the message) when none is executable. */
static int find_helper(char *out, size_t cap, char *looked, size_t lcap) {
    looked[0] = '\0';
    const char *env = getenv("RBC_IMPORT_HELPER");
    if (env && *env) {
        snprintf(looked, lcap, "%s ($RBC_IMPORT_HELPER)", env);
        if (access(env, X_OK) != 0) return 0;
        snprintf(out, cap, "%s", env);
        return 1;
    }
    Dl_info dl;
    char lib[PATH_MAX];
    if (!dladdr((void *)&rbc_mesh_import, &dl) || !dl.dli_fname ||
        !realpath(dl.dli_fname, lib)) {
        snprintf(looked, lcap, "(the library's own path is unknown; set $RBC_IMPORT_HELPER)");
        return 0;
    }
    char *slash = strrchr(lib, '/');
    if (slash) *slash = '\0';
    static const char *const rel[] = {"/" HELPER_NAME, "/../libexec/rbcloth/" HELPER_NAME};
    size_t used = 0;
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; ++i) {
        int k = snprintf(out, cap, "%s%s", lib, rel[i]);
        if (k > 0 && (size_t)k < cap && access(out, X_OK) == 0) return 1;
        int w = snprintf(looked + used, lcap - used, "%s%s", i ? ", " : "", out);
        if (w > 0 && used + (size_t)w < lcap) used += (size_t)w;
    }
    return 0;
}

static uint64_t now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

/* The answer as it arrives: a growing buffer, parsed once the helper is done. */
typedef struct answer_buf {
    char *p;
    size_t n, cap;
    int alloc_failed; /* an 'M' frame came */
} answer_buf;

/* The 'R' frame's size once its counts are in, or 0 while they are not; SIZE_MAX for
 * a frame that cannot be right. */
static size_t frame_size(const answer_buf *a) {
    const size_t fixed = 1 + 3 * sizeof(uint32_t);
    if (a->n < fixed) return 0;
    uint32_t w[3];
    memcpy(w, a->p + 1, sizeof w);
    if (w[0] != RBC_WIRE_ANSWER || w[2] >= RBC_ERROR_CAP) return SIZE_MAX;
    size_t need = fixed + w[2];
    if ((int32_t)w[1] != RBC_OK) return need;
    const size_t info_at = need;
    uint32_t isz, c[RBC_MESH_COUNTS];
    need += sizeof isz + sizeof(rbc_mesh_info) + sizeof c;
    if (a->n < need) return 0;
    memcpy(&isz, a->p + info_at, sizeof isz);
    if (isz != sizeof(rbc_mesh_info)) return SIZE_MAX;
    memcpy(c, a->p + info_at + sizeof isz + sizeof(rbc_mesh_info), sizeof c);
    for (int i = 0; i < RBC_MESH_COUNTS; ++i)
        if (c[i] > RBC_IMPORT_MAX_ELEMENTS) return SIZE_MAX;
    rbc_mesh scratch;
    rbc_mesh_array arr[RBC_MESH_ARRAYS];
    rbc_mesh_arrays(&scratch, c, arr);
    for (int i = 0; arr[i].p; ++i) need += arr[i].bytes;
    return need;
}

/* Split the complete frame into *m (arrays malloc'd). */
static rbc_result parse_answer(const answer_buf *a, const char *path, rbc_mesh *m) {
    const char *q = a->p + 1;
    uint32_t w[3];
    memcpy(w, q, sizeof w);
    q += sizeof w;
    rbc_result code = (rbc_result)(int32_t)w[1];
    if (code != RBC_OK) {
        if (code > RBC_OK || code < RBC_ERR_CAPACITY)
            return rbc_import_error(path, RBC_ERR_IO,
                                    "the import helper answered an unknown code %d", (int)code);
        char *buf = rbc_error_buffer();
        memcpy(buf, q, w[2]);
        buf[w[2]] = '\0';
        return code;
    }
    q += w[2] + sizeof(uint32_t);
    memcpy(&m->info, q, sizeof m->info);
    q += sizeof m->info;
    uint32_t c[RBC_MESH_COUNTS];
    memcpy(c, q, sizeof c);
    q += sizeof c;
    rbc_mesh_set_counts(m, c);
    rbc_mesh_array arr[RBC_MESH_ARRAYS];
    rbc_mesh_arrays(m, c, arr);
    for (int i = 0; arr[i].p; ++i) {
        *arr[i].p = malloc(arr[i].bytes + 1);
        if (!*arr[i].p) return rbc_import_error(path, RBC_ERR_OUT_OF_MEMORY, "out of memory");
        memcpy(*arr[i].p, q, arr[i].bytes);
        q += arr[i].bytes;
    }
    /* The helper is ours, but what it sends is checked like input: an index out of
     * range would be read by rbc_cloth_create_from_mesh. */
    uint32_t bad = 0;
    for (size_t i = 0; i < 4 * (size_t)m->nq; ++i) bad |= m->quads[i] >= m->n;
    for (size_t i = 0; i < 2 * (size_t)m->ns; ++i) bad |= m->springs[i] >= m->n;
    for (size_t i = 0; i < m->np; ++i) bad |= m->pins[i] >= m->n;
    for (size_t i = 0; i < 3 * (size_t)m->nlt; ++i) bad |= m->ltris[i] >= m->n;
    for (size_t k = 0; k < m->nf; ++k) {
        bad |= m->file_map[k] >= m->n && m->file_map[k] != UINT32_MAX;
        bad |= m->file_inst[k] >= m->ninst && m->file_inst[k] != UINT32_MAX;
    }
    for (size_t i = 0; i < m->ncv; ++i) {
        bad |= m->cv_file[i] >= m->nf && m->cv_file[i] != UINT32_MAX;
        bad |= m->cv_mesh[i] >= m->n && m->cv_mesh[i] != UINT32_MAX;
    }
    for (size_t f = 0; f < m->nfc; ++f) {
        bad |= m->fc_start[f] > m->fc_start[f + 1] || m->fc_inst[f] >= m->ninst;
    }
    bad |= m->fc_start[m->nfc] != m->nfcorner || (m->nfc && m->fc_start[0] != 0);
    for (size_t i = 0; i < m->nfcorner; ++i) bad |= m->fc_corner[i] >= m->ncv;
    for (size_t k = 0; k < m->ninst; ++k) m->inst_name[k][63] = '\0';
    bad |= m->info.file_vertex_count != m->nf;
    if (bad || m->info.vertex_count != m->n || m->info.quad_count != m->nq)
        return rbc_import_error(path, RBC_ERR_IO, "the import helper sent a malformed mesh");
    return RBC_OK;
}

static const char *signal_name(int sig) {
    switch (sig) {
    case SIGSEGV: return "SIGSEGV";
    case SIGABRT: return "SIGABRT";
    case SIGBUS: return "SIGBUS";
    case SIGFPE: return "SIGFPE";
    case SIGILL: return "SIGILL";
    case SIGKILL: return "SIGKILL";
    case SIGTERM: return "SIGTERM";
    case SIGXCPU: return "SIGXCPU";
    default: return "a signal";
    }
}

static uint64_t default_memory_limit(void) {
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || size <= 0) return 0;
    return (uint64_t)pages * (uint64_t)size / 2;
}

static int send_string(int fd, const char *s) {
    uint32_t len = s ? (uint32_t)strlen(s) : RBC_WIRE_NULL;
    if (rbc_wire_send(fd, &len, sizeof len)) return -1;
    return s ? rbc_wire_send(fd, s, len) : 0;
}

/* Run the helper on `path` and take its mesh into *m. Every way the helper can end
 * (an answer, an exit without one, a signal, the time limit) is an error naming the
 * file, and nothing of the helper outlives the call. */
static rbc_result import_in_helper(const char *path, const rbc_mesh_import_def *def,
                                   rbc_mesh *m) {
    char helper[PATH_MAX], looked[3 * PATH_MAX];
    if (!find_helper(helper, sizeof helper, looked, sizeof looked))
        /* An optional module that is absent, not a file that cannot be read. */
        return rbc_import_error(path, RBC_ERR_UNSUPPORTED,
                                "mesh import is not available: the import helper " HELPER_NAME
                                " was not found (looked for %s); "
                                "it belongs next to librbcloth.so, or set $RBC_IMPORT_HELPER",
                                looked);
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
        return rbc_import_error(path, RBC_ERR_IO, "cannot make the import helper's socket: %s",
                                strerror(errno));
    /* The helper's descriptors: 3 the socket (dup2 clears close-on-exec), 0-2
     * /dev/null (the library prints nothing, nor does its helper). Signals at their
     * defaults and none blocked, whatever the host's thread had. */
    posix_spawn_file_actions_t fa;
    posix_spawnattr_t at;
    posix_spawn_file_actions_init(&fa);
    posix_spawnattr_init(&at);
    posix_spawn_file_actions_adddup2(&fa, sv[1], RBC_WIRE_FD);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    if (!getenv("RBC_IMPORT_HELPER_STDERR"))
        posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    sigset_t none, all;
    sigemptyset(&none);
    sigfillset(&all);
    sigdelset(&all, SIGKILL);
    sigdelset(&all, SIGSTOP);
    posix_spawnattr_setsigmask(&at, &none);
    posix_spawnattr_setsigdefault(&at, &all);
    posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    char *argv[] = {helper, (char *)RBC_WIRE_ARG, NULL};
    pid_t pid;
    int err = posix_spawn(&pid, helper, &fa, &at, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&at);
    close(sv[1]);
    if (err) {
        close(sv[0]);
        return rbc_import_error(path, RBC_ERR_IO, "cannot start the import helper %s: %s", helper,
                                strerror(err));
    }
    const int fd = sv[0];

    /* The request. A helper that dies before reading it shows as EPIPE here and as
     * its exit status below. */
    rbc_mesh_import_def wire_def = *def;
    wire_def.mesh_name = NULL;
    wire_def.pin_group = NULL;
    uint64_t limit = def->memory_limit_mb ? (uint64_t)def->memory_limit_mb << 20
                                          : default_memory_limit();
    uint32_t head[2] = {RBC_WIRE_REQUEST, (uint32_t)sizeof wire_def};
    (void)(rbc_wire_send(fd, head, sizeof head) || rbc_wire_send(fd, &wire_def, sizeof wire_def) ||
           rbc_wire_send(fd, &limit, sizeof limit) || send_string(fd, path) ||
           send_string(fd, def->mesh_name) || send_string(fd, def->pin_group));

    /* The answer, within the time limit. */
    const uint64_t start = now_ms();
    const uint64_t deadline = def->timeout_ms ? start + def->timeout_ms : UINT64_MAX;
    answer_buf a = {0};
    size_t want = 0;
    int timed_out = 0, read_err = 0, oom = 0;
    for (;;) {
        if (a.n > 0 && a.p[0] == 'M') { /* drop the allocation-failure tag */
            a.alloc_failed = 1;
            memmove(a.p, a.p + 1, --a.n);
            continue;
        }
        if (a.n > 0 && a.p[0] != 'R') {
            read_err = EPROTO;
            break;
        }
        if (a.n > 0 && (want = frame_size(&a)) != 0 && (want == SIZE_MAX || a.n >= want)) break;
        uint64_t t = now_ms();
        if (t >= deadline) {
            timed_out = 1;
            break;
        }
        struct pollfd pf = {fd, POLLIN, 0};
        int wait = deadline == UINT64_MAX ? -1 : (int)(deadline - t > INT_MAX ? INT_MAX : deadline - t);
        int r = poll(&pf, 1, wait);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) {
            read_err = errno;
            break;
        }
        if (r == 0) continue;
        if (a.cap - a.n < 65536) {
            size_t cap = a.cap ? 2 * a.cap : 1u << 17;
            if (want && want != SIZE_MAX && want + 1 > cap) cap = want + 1;
            char *q = realloc(a.p, cap);
            if (!q) {
                oom = 1;
                break;
            }
            a.p = q;
            a.cap = cap;
        }
        ssize_t k = read(fd, a.p + a.n, a.cap - a.n);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) {
            read_err = errno;
            break;
        }
        if (k == 0) break; /* the helper has gone */
        a.n += (size_t)k;
    }
    close(fd);
    int complete = !timed_out && !read_err && !oom && a.n > 0 && want && want != SIZE_MAX &&
                   a.n >= want;

    /* The helper is done, or is made to be: a complete answer is followed by its exit
     * at once; anything else ends it. */
    if (!complete) kill(pid, SIGKILL);
    int status = 0, reaped = 0;
    for (;;) {
        pid_t r = waitpid(pid, &status, 0);
        if (r == pid) {
            reaped = 1;
            break;
        }
        if (r < 0 && errno == EINTR) continue;
        break; /* ECHILD: the host reaps its children itself (SIGCHLD ignored) */
    }

    rbc_result rc;
    double secs = (double)(now_ms() - start) / 1000.0;
    if (complete) {
        rc = parse_answer(&a, path, m);
    } else if (oom) {
        rc = rbc_import_error(path, RBC_ERR_OUT_OF_MEMORY,
                              "out of memory reading the helper's answer");
    } else if (timed_out) {
        rc = rbc_import_error(path, RBC_ERR_IO,
                              "the import did not finish within %u ms (def->timeout_ms): the "
                              "import helper was stopped; assimp hangs or is slow on this file",
                              def->timeout_ms);
    } else if (a.alloc_failed && reaped && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
        rc = rbc_import_error(path, RBC_ERR_OUT_OF_MEMORY,
                              "out of memory: the import needed more than its %llu MiB "
                              "(def->memory_limit_mb) and assimp %s after %.1f s",
                              (unsigned long long)(limit >> 20),
                              WIFSIGNALED(status) ? signal_name(WTERMSIG(status)) : "gave up",
                              secs);
    } else if (reaped && WIFSIGNALED(status)) {
        rc = rbc_import_error(path, RBC_ERR_IO,
                              "assimp crashed reading the file (the import helper died of %s, "
                              "signal %d, after %.1f s); the file is malformed or assimp has a "
                              "bug with it",
                              signal_name(WTERMSIG(status)), WTERMSIG(status), secs);
    } else if (reaped && WIFEXITED(status)) {
        rc = rbc_import_error(path, RBC_ERR_IO,
                              "the import helper %s exited with status %d without an answer%s",
                              helper, WEXITSTATUS(status),
                              read_err ? " (its answer was malformed)" : "");
    } else {
        rc = rbc_import_error(path, RBC_ERR_IO,
                              "the import helper ended without an answer (its exit status was "
                              "taken by the host's own SIGCHLD handling)");
    }
    free(a.p);
    return rc;
}
#endif /* !_WIN32 */

/* ------------------------------------------------------------------------- */
/* rbc_mesh_import                                                           */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_mesh_import(const char *path, const rbc_mesh_import_def *user_def,
                                            rbc_mesh_id *out_mesh) {
    const char *fn = fn_import;
    if (!out_mesh) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: out_mesh is NULL", fn);
    *out_mesh = 0;
    if (!path || !*path) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: path is empty", fn);
    rbc_mesh_import_def def = import_def_defaults();
    if (user_def) {
        uint32_t size;
        memcpy(&size, user_def, sizeof size);
        if (!rbc_size_known(&rbc_sizes_import_def, size))
            return rbc_size_refused(&rbc_sizes_import_def, size, fn, "def");
        memcpy(&def, user_def, size); /* an older def keeps the newer fields' defaults */
        def.struct_size = sizeof def;
    }
    rbc_result rc = check_def(path, &def);
    if (rc) return rc;
#if defined(_WIN32)
    /* A bad call is still named as one (above); a good one cannot be served. */
    return rbc_import_error(path, RBC_ERR_UNSUPPORTED,
                            "mesh import is not available in Windows builds of rbcloth "
                            "(its helper process needs POSIX); import the mesh on Linux, or "
                            "pass its quads to rbc_cloth_create");
#else
    size_t plen = strlen(path);
    if (plen >= RBC_WIRE_MAX_STRING || (def.mesh_name && strlen(def.mesh_name) >= RBC_WIRE_MAX_STRING) ||
        (def.pin_group && strlen(def.pin_group) >= RBC_WIRE_MAX_STRING))
        return rbc_import_error(path, RBC_ERR_INVALID_ARGUMENT,
                                "the path, def->mesh_name or def->pin_group is %u bytes or longer",
                                RBC_WIRE_MAX_STRING);
    /* Open errors are named here, before any process is started. */
    struct stat st;
    if (stat(path, &st) != 0)
        return rbc_import_error(path, RBC_ERR_IO, "cannot open the file: %s", strerror(errno));
    if (!S_ISREG(st.st_mode))
        return rbc_import_error(path, RBC_ERR_IO, "cannot open the file: not a regular file");
    if (access(path, R_OK) != 0)
        return rbc_import_error(path, RBC_ERR_IO, "cannot open the file: %s", strerror(errno));

    rbc_mesh *m = calloc(1, sizeof *m);
    if (!m) return rbc_import_error(path, RBC_ERR_OUT_OF_MEMORY, "out of memory");
    rc = import_in_helper(path, &def, m);
    if (!rc && rbc_reg_add(&g_meshes, m, 0, &m->id) != RBC_OK)
        rc = rbc_import_error(path, RBC_ERR_CAPACITY, "%u meshes exist already", RBC_MAX_MESHES);
    if (rc) {
        rbc_import_mesh_free(m);
        free(m);
        return rc;
    }
    *out_mesh = m->id;
    return RBC_OK;
#endif
}

/* ------------------------------------------------------------------------- */
/* Mesh access                                                               */
/* ------------------------------------------------------------------------- */

static rbc_mesh *lookup_mesh(rbc_mesh_id id, const char *fn) {
    return rbc_reg_get(&g_meshes, id, 0, fn);
}

RBC_API rbc_result RBC_CALL rbc_mesh_destroy(rbc_mesh_id id) {
    rbc_mesh *m = lookup_mesh(id, "rbc_mesh_destroy");
    if (!m) return RBC_ERR_STALE_HANDLE;
    rbc_reg_remove(&g_meshes, id);
    rbc_import_mesh_free(m);
    free(m);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_info(rbc_mesh_id id, rbc_mesh_info *out) {
    static const char fn[] = "rbc_mesh_get_info";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    if (!out) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: info is NULL", fn);
    uint32_t size = out->struct_size;
    if (!rbc_size_known(&rbc_sizes_mesh_info, size))
        return rbc_size_refused(&rbc_sizes_mesh_info, size, fn, "info");
    memcpy(out, &m->info, size);
    out->struct_size = size;
    return RBC_OK;
}

static rbc_result copy_out(rbc_mesh_id id, const char *fn, const char *what, const void *src,
                           size_t count, size_t elem, void *dst, size_t capacity,
                           size_t *out_count) {
    if (dst) {
        if (capacity < count)
            return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                 "%s: mesh 0x%08x has %zu %s values; capacity is %zu", fn, id,
                                 count, what, capacity);
        if (count) memcpy(dst, src, count * elem);
    }
    if (out_count) *out_count = count;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_positions(rbc_mesh_id id, float *xyz, size_t capacity,
                                                   size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_positions";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    return copy_out(id, fn, "position", m->pos, 3 * (size_t)m->n, sizeof(float), xyz, capacity,
                    out_count);
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_quads(rbc_mesh_id id, uint32_t *quads, size_t capacity,
                                               size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_quads";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    return copy_out(id, fn, "quad index", m->quads, 4 * (size_t)m->nq, sizeof(uint32_t), quads,
                    capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_triangles(rbc_mesh_id id, uint32_t *tris,
                                                   size_t capacity, size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_triangles";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    size_t need = 6 * (size_t)m->nq + 3 * (size_t)m->nlt;
    uint32_t *all = malloc((need + 1) * sizeof *all);
    if (!all) return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: mesh 0x%08x: out of memory", fn, id);
    for (size_t q = 0; q < m->nq; ++q) {
        const uint32_t *v = &m->quads[4 * q];
        uint32_t *t = &all[6 * q];
        t[0] = v[0], t[1] = v[1], t[2] = v[2];
        t[3] = v[0], t[4] = v[2], t[5] = v[3];
    }
    memcpy(&all[6 * (size_t)m->nq], m->ltris, 3 * (size_t)m->nlt * sizeof(uint32_t));
    rbc_result rc = copy_out(id, fn, "triangle index", all, need, sizeof(uint32_t), tris,
                             capacity, out_count);
    free(all);
    return rc;
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_springs(rbc_mesh_id id, uint32_t *springs,
                                                 size_t capacity, size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_springs";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    return copy_out(id, fn, "spring index", m->springs, 2 * (size_t)m->ns, sizeof(uint32_t),
                    springs, capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_mesh_get_pins(rbc_mesh_id id, uint32_t *pins, size_t capacity,
                                              size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_pins";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    return copy_out(id, fn, "pin", m->pins, m->np, sizeof(uint32_t), pins, capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_cloth_create_from_mesh(rbc_world_id world, rbc_mesh_id id,
                                                       const rbc_cloth_def *settings,
                                                       rbc_cloth_id *out_cloth) {
    static const char fn[] = "rbc_cloth_create_from_mesh";
    if (out_cloth) *out_cloth = 0;
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    rbc_cloth_def def;
    rbc_cloth_def_init(&def, sizeof def);
    if (settings) {
        uint32_t size;
        memcpy(&size, settings, sizeof size);
        if (!rbc_size_known(&rbc_sizes_cloth_def, size))
            return rbc_size_refused(&rbc_sizes_cloth_def, size, fn, "settings");
        memcpy(&def, settings, size);
        def.struct_size = sizeof def;
    }
    def.vertex_count = m->n;
    def.positions = m->pos;
    def.quad_count = m->nq;
    def.quads = m->quads;
    def.spring_count = m->ns;
    def.springs = m->springs;
    /* The import's pins, and the host's own on top (settings->pins: extra pins, not
     * a replacement; each checked against the mesh here, naming the index). */
    uint32_t *pins = NULL;
    size_t np = m->np;
    if (settings && def.pin_count) {
        if (!def.pins)
            return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                 "%s: mesh 0x%08x: settings->pin_count is %u but pins is NULL",
                                 fn, id, def.pin_count);
        for (uint32_t k = 0; k < def.pin_count; ++k)
            if (def.pins[k] >= m->n)
                return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                     "%s: mesh 0x%08x: settings->pins[%u] is vertex %u; the mesh "
                                     "has %u vertices",
                                     fn, id, k, def.pins[k], m->n);
        uint8_t *seen = calloc((size_t)m->n + 1, 1);
        pins = malloc(((size_t)m->np + def.pin_count + 1) * sizeof *pins);
        if (!seen || !pins) {
            free(seen);
            free(pins);
            return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: mesh 0x%08x: out of memory", fn, id);
        }
        for (uint32_t k = 0; k < m->np; ++k) seen[m->pins[k]] = 1;
        for (uint32_t k = 0; k < def.pin_count; ++k) seen[def.pins[k]] = 1;
        np = 0;
        for (uint32_t v = 0; v < m->n; ++v)
            if (seen[v]) pins[np++] = v;
        free(seen);
    }
    def.pin_count = (uint32_t)np;
    def.pins = pins ? pins : m->pins;
    rbc_result rc = rbc_cloth_create(world, &def, out_cloth);
    free(pins);
    /* The file's triangles that made no quad: drawn (rbc_cloth_get_triangles) and
     * shaded with the quads; a cloth that cannot keep them is not made. */
    if (!rc && m->nlt &&
        (rc = rbc_plugin_cloth_lone_triangles(world, *out_cloth, fn, m->ltris, m->nlt))) {
        rbc_cloth_destroy(world, *out_cloth);
        *out_cloth = 0;
        return rc;
    }
    if (rc) {
        char inner[RBC_ERROR_CAP];
        snprintf(inner, sizeof inner, "%s", rbc_last_error());
        rbc_set_error(rc, "%s: mesh 0x%08x: %s", fn, id, inner);
    }
    return rc;
}


/* ------------------------------------------------------------------------- */
/* The file's own mesh (1.9)                                                 */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_mesh_get_file_map(rbc_mesh_id id, uint32_t *map, size_t capacity,
                                                  size_t *out_count) {
    static const char fn[] = "rbc_mesh_get_file_map";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    return copy_out(id, fn, "file map", m->file_map, m->nf, sizeof(uint32_t), map, capacity,
                    out_count);
}

/* xyz (3n floats, or NULL for the rest positions) checked for `fn`. */
static rbc_result check_state(const rbc_mesh *m, const char *fn, const float *xyz,
                              size_t xyz_count) {
    if (!xyz) return RBC_OK;
    if (xyz_count != 3 * (size_t)m->n)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: mesh 0x%08x has %u vertices, so xyz must hold %zu floats; "
                             "xyz_count is %zu",
                             fn, m->id, m->n, 3 * (size_t)m->n, xyz_count);
    for (size_t i = 0; i < xyz_count; ++i)
        if (!isfinite(xyz[i]))
            return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                 "%s: mesh 0x%08x: xyz[%zu] (vertex %zu, coordinate %zu) is not "
                                 "finite",
                                 fn, m->id, i, i / 3, i % 3);
    return RBC_OK;
}

/* File vertex k of state p (mesh coordinates) back in the file's coordinates. */
static void to_file(const rbc_mesh *m, const float *p, size_t k, float out[3]) {
    uint32_t v = m->file_map[k], in = m->file_inst[k];
    if (v == UINT32_MAX || in == UINT32_MAX) {
        memcpy(out, &m->file_rest[3 * k], 3 * sizeof(float));
        return;
    }
    const double *a = &m->inst_inv[12 * (size_t)in];
    const float *x = &p[3 * (size_t)v];
    for (int r = 0; r < 3; ++r)
        out[r] = (float)(a[4 * r] * x[0] + a[4 * r + 1] * x[1] + a[4 * r + 2] * x[2] + a[4 * r + 3]);
}

RBC_API rbc_result RBC_CALL rbc_mesh_to_file_positions(rbc_mesh_id id, const float *xyz,
                                                       size_t xyz_count, float *out,
                                                       size_t capacity, size_t *out_count) {
    static const char fn[] = "rbc_mesh_to_file_positions";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    size_t need = 3 * (size_t)m->nf;
    if (out) {
        if (capacity < need)
            return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                                 "%s: mesh 0x%08x has %u file vertices, %zu floats; capacity is "
                                 "%zu",
                                 fn, id, m->nf, need, capacity);
        rbc_result rc = check_state(m, fn, xyz, xyz_count);
        if (rc) return rc;
        const float *p = xyz ? xyz : m->pos;
        for (size_t k = 0; k < m->nf; ++k) to_file(m, p, k, &out[3 * k]);
    }
    if (out_count) *out_count = need;
    return RBC_OK;
}

/* An OBJ group name: one token (whitespace would start a second group). */
static void put_group(FILE *f, const char *name) {
    fputs("g ", f);
    if (!*name) fputs("mesh", f);
    for (const char *c = name; *c; ++c) fputc(isspace((unsigned char)*c) ? '_' : *c, f);
    fputc('\n', f);
}

RBC_API rbc_result RBC_CALL rbc_mesh_write_file_obj(rbc_mesh_id id, const float *xyz,
                                                    size_t xyz_count, rbc_vertex_order order,
                                                    const char *path) {
    static const char fn[] = "rbc_mesh_write_file_obj";
    rbc_mesh *m = lookup_mesh(id, fn);
    if (!m) return RBC_ERR_STALE_HANDLE;
    if (order != RBC_ORDER_FILE && order != RBC_ORDER_MESH)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: order %d is not an rbc_vertex_order (RBC_ORDER_FILE 1, "
                             "RBC_ORDER_MESH 2)",
                             fn, (int)order);
    if (!path || !*path) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: path is empty", fn);
    rbc_result rc = check_state(m, fn, xyz, xyz_count);
    if (rc) return rc;
    const float *p = xyz ? xyz : m->pos;
    const int file = order == RBC_ORDER_FILE;
    size_t nv = file ? m->nf : m->n;
    uint32_t *vt = malloc(((size_t)m->ncv + 1) * sizeof *vt); /* corner vertex -> vt/vn index */
    uint32_t *vn = malloc(((size_t)m->ncv + 1) * sizeof *vn);
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 5);
    if (!vt || !vn || !tmp) {
        free(vt);
        free(vn);
        free(tmp);
        return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: mesh 0x%08x: out of memory", fn, id);
    }
    memcpy(tmp, path, plen);
    memcpy(tmp + plen, ".tmp", 5);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        rc = rbc_set_error(RBC_ERR_IO, "%s: cannot open %s: %s", fn, tmp, strerror(errno));
        goto done;
    }
    fprintf(f, "# rbcloth: mesh 0x%08x in the %s's vertex order (%zu vertices)\n", id,
            file ? "file" : "simulation", nv);
    for (size_t k = 0; k < nv; ++k) {
        float q[3];
        if (file) to_file(m, p, k, q);
        else memcpy(q, &p[3 * k], sizeof q);
        fprintf(f, "v %.9g %.9g %.9g\n", (double)q[0], (double)q[1], (double)q[2]);
    }
    uint32_t nvt = 0, nvn = 0;
    for (size_t c = 0; c < m->ncv; ++c) {
        vt[c] = vn[c] = 0;
        if (m->cv_flags[c] & 1) {
            fprintf(f, "vt %.9g %.9g\n", (double)m->cv_uv[2 * c], (double)m->cv_uv[2 * c + 1]);
            vt[c] = ++nvt;
        }
    }
    for (size_t c = 0; c < m->ncv; ++c) {
        if (!(m->cv_flags[c] & 2)) continue;
        double n[3] = {m->cv_nrm[3 * c], m->cv_nrm[3 * c + 1], m->cv_nrm[3 * c + 2]};
        if (!file) {
            /* normals follow the inverse transpose of the placement's transform */
            uint32_t fi = m->cv_file[c];
            uint32_t in = fi != UINT32_MAX ? m->file_inst[fi] : UINT32_MAX;
            if (in != UINT32_MAX) {
                const double *a = &m->inst_inv[12 * (size_t)in];
                double t[3];
                for (int k = 0; k < 3; ++k) t[k] = a[k] * n[0] + a[4 + k] * n[1] + a[8 + k] * n[2];
                double len = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
                if (len > 0.0)
                    for (int k = 0; k < 3; ++k) n[k] = t[k] / len;
            }
        }
        fprintf(f, "vn %.9g %.9g %.9g\n", n[0], n[1], n[2]);
        vn[c] = ++nvn;
    }
    uint32_t group = UINT32_MAX;
    for (size_t fc = 0; fc < m->nfc; ++fc) {
        const uint32_t *cs = &m->fc_corner[m->fc_start[fc]];
        size_t k = m->fc_start[fc + 1] - m->fc_start[fc];
        int ok = 1;
        for (size_t j = 0; j < k && ok; ++j)
            ok = (file ? m->cv_file[cs[j]] : m->cv_mesh[cs[j]]) != UINT32_MAX;
        if (!ok) continue; /* a corner the mesh dropped (a degenerate face's) */
        if (m->fc_inst[fc] != group) {
            group = m->fc_inst[fc];
            put_group(f, m->inst_name[group]);
        }
        fputc('f', f);
        for (size_t j = 0; j < k; ++j) {
            uint32_t c = cs[j];
            uint32_t v = (file ? m->cv_file[c] : m->cv_mesh[c]) + 1;
            if (vt[c] && vn[c]) fprintf(f, " %u/%u/%u", v, vt[c], vn[c]);
            else if (vt[c]) fprintf(f, " %u/%u", v, vt[c]);
            else if (vn[c]) fprintf(f, " %u//%u", v, vn[c]);
            else fprintf(f, " %u", v);
        }
        fputc('\n', f);
    }
    int bad = ferror(f);
    bad |= fclose(f) != 0;
    if (bad) {
        rc = rbc_set_error(RBC_ERR_IO, "%s: writing %s failed: %s", fn, tmp, strerror(errno));
        remove(tmp);
    } else if (rbc_replace_file(tmp, path) != 0) {
        rc = rbc_set_error(RBC_ERR_IO, "%s: cannot rename %s to %s: %s", fn, tmp, path,
                           strerror(errno));
        remove(tmp);
    }
done:
    free(vt);
    free(vn);
    free(tmp);
    return rc;
}
