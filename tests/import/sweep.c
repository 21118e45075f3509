/* sweep.c -- import every file under a folder (assimp-testmodels) through
 * rbc_mesh_import, each in a forked child with a time limit, and check that every
 * file is imported or refused with a clear error: never a crash, a hang, a leak or
 * a byte on stdout/stderr from the library.
 *
 *   import_sweep [--timeout S] [--every K] [--max-bytes B] [--max-memory-mb M]
 *                [--min-imported N] [--exclude SUBSTRING] [--quiet] PATH...
 *
 * PATHs are files or folders (walked recursively); files are taken in sorted order,
 * every K-th of them with --every (a subset for slow runs under valgrind), none over
 * B bytes with --max-bytes, none whose path contains an --exclude string; children
 * get an address-space limit of M MiB with --max-memory-mb (a host's memory is
 * finite: assimp allocates without bound on some files). Per file, a child imports it with the default def; on
 * success it reads the report and arrays back, checks they agree, makes a cloth in a
 * one-thread world, steps it once and destroys everything; it then exit()s, so
 * LeakSanitizer or valgrind (--leak-check=full --error-exitcode=N, which follows
 * forked children) check the child's leaks file by file.
 *
 * The library imports in a helper process (rbcloth-import) with the def's time
 * limit, set here to half of --timeout so that the library's limit is the one hit.
 *
 * Outcomes:
 *   imported                       the child printed "OK ..." and exited 0
 *   refused: CODE: reason          "ERR ...": the library's message, grouped by its
 *                                  first clause after the path
 *   isolated: CODE: reason         the library reported that assimp crashed, hung or
 *                                  ran out of memory in the helper, AND a second
 *                                  child that runs only assimp's own import (same
 *                                  flags) on the file fails too: assimp's bug, kept
 *                                  out of the host
 *   FAIL                           anything else: the child crashed, hung, had a
 *                                  memory error or leak, wrote to stdout/stderr, got
 *                                  an error without a message or an inconsistent
 *                                  report; or the helper failed where assimp alone
 *                                  does not (our bug), or exited without an answer.
 * With --min-imported N, fewer than N files imported is a failure too: a run in
 * which every import fails the same way (a helper that cannot start, a sanitizer
 * that kills every child) must not pass as "all refused cleanly".
 * Prints one line per file (unless --quiet: failures and assimp's bugs only), then
 * the counts by outcome, and exits 1 if any file FAILed or too few imported. */
#define _XOPEN_SOURCE 700 /* nftw */
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <errno.h>
#include <ftw.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "rbcloth.h"

/* An address-space limit cannot coexist with a sanitizer's shadow memory (ASan maps
 * terabytes of it, and so would the sanitized import helper the child starts):
 * --max-memory-mb is ignored in such builds, and says so. */
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SWEEP_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define SWEEP_SANITIZED 1
#endif
#endif
#ifndef SWEEP_SANITIZED
#define SWEEP_SANITIZED 0
#endif

static char **g_files;
static size_t g_nfiles, g_cap;
static long long g_max_bytes = -1;
static long long g_max_mb = 0; /* address-space limit of the children, MiB; 0 = none */
static uint32_t g_import_timeout_ms; /* the def's timeout_ms */
static const char *g_exclude[8]; /* leave out paths containing these */
static int g_nexclude;

static int add_file(const char *path, const struct stat *st, int type, struct FTW *ftw) {
    (void)ftw;
    if (type != FTW_F || !S_ISREG(st->st_mode)) return 0;
    if (g_max_bytes >= 0 && st->st_size > g_max_bytes) return 0;
    for (int k = 0; k < g_nexclude; ++k)
        if (strstr(path, g_exclude[k])) return 0;
    if (g_nfiles == g_cap) {
        g_cap = g_cap ? 2 * g_cap : 256;
        g_files = realloc(g_files, g_cap * sizeof *g_files);
        if (!g_files) abort();
    }
    g_files[g_nfiles++] = strdup(path);
    return 0;
}

static int cmp_str(const void *a, const void *b) {
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ------------------------------------------------------------------------- */
/* Children                                                                  */
/* ------------------------------------------------------------------------- */

/* The library's side: import, check, simulate one step, destroy. Writes one line. */
static void child_import(const char *path, FILE *res) {
    rbc_mesh_id m = 0;
    rbc_mesh_import_def def;
    rbc_mesh_import_def_init(&def, sizeof def);
    def.timeout_ms = g_import_timeout_ms;
    rbc_result rc = rbc_mesh_import(path, &def, &m);
    if (rc != RBC_OK) {
        const char *msg = rbc_last_error();
        if (m != 0 || !msg || !*msg)
            fprintf(res, "BUG error %s without a message or with a mesh id\n",
                    rbc_result_string(rc));
        else
            fprintf(res, "ERR %s %s\n", rbc_result_string(rc), msg);
        return;
    }
    rbc_mesh_info info;
    memset(&info, 0, sizeof info);
    info.struct_size = sizeof info;
    size_t np = 0, nq = 0, ns = 0, npin = 0;
    if (rbc_mesh_get_info(m, &info) || rbc_mesh_get_positions(m, NULL, 0, &np) ||
        rbc_mesh_get_quads(m, NULL, 0, &nq) || rbc_mesh_get_springs(m, NULL, 0, &ns) ||
        rbc_mesh_get_pins(m, NULL, 0, &npin)) {
        fprintf(res, "BUG getters failed: %s\n", rbc_last_error());
        return;
    }
    if (np != 3 * (size_t)info.vertex_count || nq != 4 * (size_t)info.quad_count ||
        ns != 2 * (size_t)info.spring_count || npin != info.pin_count ||
        info.paired_triangles % 2 != 0 ||
        info.quad_count != info.file_quads + info.quads_from_ngons + info.paired_triangles / 2 ||
        info.file_triangles + info.triangles_from_ngons !=
            info.paired_triangles + info.leftover_triangles) {
        fprintf(res, "BUG report and arrays disagree\n");
        return;
    }
    float *pos = malloc((np + 1) * sizeof *pos);
    uint32_t *quads = malloc((nq + 1) * sizeof *quads);
    uint32_t *springs = malloc((ns + 1) * sizeof *springs);
    int bad = !pos || !quads || !springs || rbc_mesh_get_positions(m, pos, np, NULL) ||
              rbc_mesh_get_quads(m, quads, nq, NULL) || rbc_mesh_get_springs(m, springs, ns, NULL);
    for (size_t k = 0; !bad && k < nq; ++k) bad = quads[k] >= info.vertex_count;
    for (size_t k = 0; !bad && k < ns; ++k) bad = springs[k] >= info.vertex_count;
    free(pos);
    free(quads);
    free(springs);
    if (bad) {
        fprintf(res, "BUG arrays out of range\n");
        return;
    }
    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = 1;
    rbc_world_id w = 0;
    rbc_cloth_id c = 0;
    if (rbc_world_create(&wd, &w)) {
        fprintf(res, "BUG world: %s\n", rbc_last_error());
        return;
    }
    rc = rbc_cloth_create_from_mesh(w, m, NULL, &c);
    const char *step = "-";
    if (rc == RBC_OK) step = rbc_result_string(rbc_world_step(w, 1.0f / 600.0f));
    if (rc != RBC_OK)
        fprintf(res, "BUG cloth from an imported mesh: %s\n", rbc_last_error());
    else
        fprintf(res, "OK v=%u q=%u s=%u pins=%u paired=%u left=%u ngons=%u colors=%u bip=%u step=%s\n",
                info.vertex_count, info.quad_count, info.spring_count, info.pin_count,
                info.paired_triangles, info.leftover_triangles, info.ngons_split,
                info.color_count, info.bipartite, step);
    rbc_world_destroy(w);
    rbc_mesh_destroy(m);
}

/* assimp alone, as rbc_mesh_import calls it: tells assimp's own crashes apart. */
static void child_assimp_only(const char *path, FILE *res) {
    const struct aiScene *s =
        aiImportFile(path, aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure);
    fprintf(res, "%s\n", s ? "read" : "refused");
    if (s) aiReleaseImport(s);
}

typedef struct outcome {
    int status;        /* waitpid status */
    int timed_out;
    char line[1200];   /* the child's result line */
    char out[600];     /* what it wrote on stdout (first bytes) */
    size_t out_len;
    char err[600];     /* and on stderr */
    size_t err_len;
    double seconds;
} outcome;

static void run_child(const char *path, int assimp_only, double timeout, outcome *o) {
    memset(o, 0, sizeof *o);
    int rp[2], op[2], ep[2];
    if (pipe(rp) || pipe(op) || pipe(ep)) {
        perror("pipe");
        exit(2);
    }
    fflush(NULL);
    double t0 = now_s();
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        exit(2);
    }
    if (pid == 0) {
        close(rp[0]);
        close(op[0]);
        close(ep[0]);
        dup2(op[1], 1);
        dup2(ep[1], 2);
        close(op[1]);
        close(ep[1]);
        if (g_max_mb > 0) {
            struct rlimit rl = {(rlim_t)g_max_mb << 20, (rlim_t)g_max_mb << 20};
            setrlimit(RLIMIT_AS, &rl);
        }
        FILE *res = fdopen(rp[1], "w");
        if (!res) _exit(3);
        if (assimp_only)
            child_assimp_only(path, res);
        else
            child_import(path, res);
        fclose(res);
        exit(0); /* exit, not _exit: leak checkers run at exit */
    }
    close(rp[1]);
    close(op[1]);
    close(ep[1]);
    struct pollfd fds[3] = {{rp[0], POLLIN, 0}, {op[0], POLLIN, 0}, {ep[0], POLLIN, 0}};
    char *dst[3] = {o->line, o->out, o->err};
    size_t cap[3] = {sizeof o->line, sizeof o->out, sizeof o->err};
    size_t len[3] = {0, 0, 0};
    int open_fds = 3;
    while (open_fds > 0) {
        double left = timeout - (now_s() - t0);
        if (left <= 0) {
            o->timed_out = 1;
            kill(pid, SIGKILL);
            break;
        }
        int r = poll(fds, 3, (int)(left * 1000) + 1);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) continue;
        for (int k = 0; k < 3; ++k) {
            if (fds[k].fd < 0 || !(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            char buf[4096];
            ssize_t n = read(fds[k].fd, buf, sizeof buf);
            if (n <= 0) {
                close(fds[k].fd);
                fds[k].fd = -1;
                open_fds--;
                continue;
            }
            size_t c = (size_t)n;
            if (len[k] + c >= cap[k]) c = cap[k] - 1 - len[k];
            memcpy(dst[k] + len[k], buf, c);
            len[k] += c;
        }
    }
    o->out_len = len[1];
    o->err_len = len[2];
    for (int k = 0; k < 3; ++k)
        if (fds[k].fd >= 0) close(fds[k].fd);
    waitpid(pid, &o->status, 0);
    o->seconds = now_s() - t0;
    char *nl = strchr(o->line, '\n');
    if (nl) *nl = '\0';
}

/* ------------------------------------------------------------------------- */
/* Tally                                                                     */
/* ------------------------------------------------------------------------- */

typedef struct bucket {
    char key[200];
    int count;
    char example[160];
} bucket;
static bucket g_buckets[256];
static int g_nbuckets;

static void tally(const char *key, const char *example) {
    for (int k = 0; k < g_nbuckets; ++k)
        if (strcmp(g_buckets[k].key, key) == 0) {
            g_buckets[k].count++;
            return;
        }
    if (g_nbuckets == 256) return;
    bucket *b = &g_buckets[g_nbuckets++];
    snprintf(b->key, sizeof b->key, "%s", key);
    snprintf(b->example, sizeof b->example, "%s", example);
    b->count = 1;
}

static int cmp_bucket(const void *a, const void *b) {
    const bucket *x = a, *y = b;
    if (x->count != y->count) return y->count - x->count;
    return strcmp(x->key, y->key);
}

/* "ERR CODE rbc_mesh_import: PATH: reason: details" -> "CODE: reason". */
static void refusal_key(const char *line, const char *path, char *key, size_t cap) {
    const char *code = line + 4;
    const char *sp = strchr(code, ' ');
    if (!sp) {
        snprintf(key, cap, "%s", code);
        return;
    }
    const char *msg = sp + 1;
    const char *p = strstr(msg, path);
    const char *reason = p ? p + strlen(path) : msg;
    if (reason[0] == ':' && reason[1] == ' ') reason += 2;
    size_t rl = strcspn(reason, ":");
    if (rl > 80) rl = 80;
    snprintf(key, cap, "%.*s: %.*s", (int)(sp - code), code, (int)rl, reason);
}

/* Did the child fail (crash, hang, non-zero exit)? Describe it. */
static int child_failed(const outcome *o, char *what, size_t cap) {
    if (o->timed_out) {
        snprintf(what, cap, "hung (killed after %.0f s)", o->seconds);
        return 1;
    }
    if (WIFSIGNALED(o->status)) {
        snprintf(what, cap, "crashed (signal %d)", WTERMSIG(o->status));
        return 1;
    }
    if (WIFEXITED(o->status) && WEXITSTATUS(o->status) != 0) {
        snprintf(what, cap, "memory error or leak (exit status %d)", WEXITSTATUS(o->status));
        return 1;
    }
    return 0;
}

int main(int argc, char **argv) {
    double timeout = 30.0;
    long every = 1;
    int quiet = 0, first_path = argc;
    long min_imported = 0;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc) {
            timeout = atof(argv[++i]);
        } else if (strcmp(argv[i], "--every") == 0 && i + 1 < argc) {
            every = atol(argv[++i]);
        } else if (strcmp(argv[i], "--max-bytes") == 0 && i + 1 < argc) {
            g_max_bytes = atoll(argv[++i]);
        } else if (strcmp(argv[i], "--max-memory-mb") == 0 && i + 1 < argc) {
            g_max_mb = atoll(argv[++i]);
        } else if (strcmp(argv[i], "--min-imported") == 0 && i + 1 < argc) {
            min_imported = atol(argv[++i]);
        } else if (strcmp(argv[i], "--exclude") == 0 && i + 1 < argc && g_nexclude < 8) {
            g_exclude[g_nexclude++] = argv[++i];
        } else if (strcmp(argv[i], "--quiet") == 0) {
            quiet = 1;
        } else {
            first_path = i;
            break;
        }
    }
    if (first_path >= argc || timeout <= 0 || every < 1) {
        fprintf(stderr,
                "usage: %s [--timeout S] [--every K] [--max-bytes B] [--max-memory-mb M] "
                "[--min-imported N] [--exclude SUBSTRING] [--quiet] PATH...\n",
                argv[0]);
        return 2;
    }
    for (int i = first_path; i < argc; ++i) {
        struct stat st;
        if (stat(argv[i], &st) != 0) {
            fprintf(stderr, "import_sweep: %s: %s\n", argv[i], strerror(errno));
            return 2;
        }
        if (nftw(argv[i], add_file, 16, FTW_PHYS) != 0) {
            fprintf(stderr, "import_sweep: cannot walk %s\n", argv[i]);
            return 2;
        }
    }
    g_import_timeout_ms = (uint32_t)(timeout * 500.0);
    if (SWEEP_SANITIZED && g_max_mb > 0) {
        printf("import_sweep: a sanitizer build: --max-memory-mb %lld is not applied\n", g_max_mb);
        g_max_mb = 0;
    }
    qsort(g_files, g_nfiles, sizeof *g_files, cmp_str);
    if (g_nfiles == 0) {
        fprintf(stderr, "import_sweep: no files under the given paths\n");
        return 1;
    }
    double t0 = now_s(), slowest = 0.0;
    const char *slowest_file = "";
    int imported = 0, refused = 0, isolated_bugs = 0, failed = 0, taken = 0;
    outcome o, raw;
    for (size_t f = 0; f < g_nfiles; f += (size_t)every) {
        const char *path = g_files[f];
        taken++;
        run_child(path, 0, timeout, &o);
        if (o.seconds > slowest) {
            slowest = o.seconds;
            slowest_file = path;
        }
        char what[200], key[300];
        int assimp_stderr = 0; /* the output on stderr is assimp's own: it alone writes it */
        if (o.err_len > 0 && !child_failed(&o, what, sizeof what)) {
            run_child(path, 1, timeout, &raw);
            assimp_stderr = raw.err_len > 0 && raw.out_len == 0 && !child_failed(&raw, what, sizeof what);
            if (assimp_stderr) {
                tally("note: assimp itself wrote to stderr", path);
                printf("NOTE %s: assimp itself writes to stderr: %.*s\n", path,
                       (int)strcspn(o.err, "\n"), o.err);
            }
        }
        const char *verdict = NULL;
        if (child_failed(&o, what, sizeof what)) {
            verdict = what; /* the host died or hung: isolation failed */
        } else if (o.out_len > 0) {
            verdict = "the library wrote to stdout";
        } else if (o.err_len > 0 && !assimp_stderr) {
            verdict = "the library wrote to stderr (assimp alone does not)";
        } else if (strncmp(o.line, "OK ", 3) == 0) {
            imported++;
            tally("imported", path);
            if (!quiet) printf("imported %s: %s (%.2f s)\n", path, o.line + 3, o.seconds);
            continue;
        } else if (strncmp(o.line, "ERR ", 4) == 0) {
            refusal_key(o.line, path, key, sizeof key);
            /* A failure the helper isolated: assimp's, if assimp alone fails too. A
             * helper that exits without an answer is ours whatever assimp does. */
            int helper_died = strstr(o.line, "the import helper") && strstr(o.line, "exited with status");
            int isolated = strstr(o.line, "assimp crashed reading the file") ||
                           strstr(o.line, "the import did not finish within") ||
                           strstr(o.line, "out of memory: the import needed more");
            if (helper_died) {
                verdict = "the import helper exited without an answer";
            } else if (isolated) {
                run_child(path, 1, timeout, &raw);
                char raw_what[200];
                if (!child_failed(&raw, raw_what, sizeof raw_what)) {
                    verdict = "the import helper failed where assimp alone does not";
                } else {
                    char full[400];
                    snprintf(full, sizeof full, "isolated: %s", key);
                    tally(full, path);
                    refused++;
                    isolated_bugs++;
                    printf("ISOLATED %s: %s; assimp alone %s\n", path, o.line + 4, raw_what);
                    continue;
                }
            } else {
                char full[400];
                snprintf(full, sizeof full, "refused: %s", key);
                tally(full, path);
                refused++;
                if (!quiet) printf("refused %s: %s\n", path, o.line + 4);
                continue;
            }
        } else {
            verdict = o.line[0] ? o.line : "no result line";
        }
        failed++;
        tally("FAIL", path);
        printf("FAIL %s: %s\n  result: %s\n", path, verdict, o.line);
        if (o.out_len) printf("  stdout: %.*s\n", (int)o.out_len, o.out);
        if (o.err_len) printf("  stderr: %.*s\n", (int)o.err_len, o.err);
    }
    double total = now_s() - t0;
    qsort(g_buckets, (size_t)g_nbuckets, sizeof *g_buckets, cmp_bucket);
    printf("\nimport_sweep: %d files (of %zu found, every %ld), %.1f s, slowest %.2f s (%s)\n",
           taken, g_nfiles, every, total, slowest, slowest_file);
    for (int k = 0; k < g_nbuckets; ++k)
        printf("  %5d  %s   (e.g. %s)\n", g_buckets[k].count, g_buckets[k].key,
               g_buckets[k].example);
    printf("import_sweep: imported %d, refused %d (of which assimp's own crash, hang or "
           "memory exhaustion, isolated in the helper: %d), failed %d\n",
           imported, refused, isolated_bugs, failed);
    int too_few = imported < min_imported;
    if (too_few)
        printf("import_sweep: FAIL: %d files imported, fewer than the floor of %ld "
               "(--min-imported)\n", imported, min_imported);
    for (size_t f = 0; f < g_nfiles; ++f) free(g_files[f]);
    free(g_files);
    return failed || too_few ? 1 : 0;
}
