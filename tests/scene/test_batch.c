/* test_batch.c -- `rbcloth batch` end to end.
 *
 *  1. Four jobs with -j 2, one of them a missing mesh file: exit 1; the good jobs'
 *     PC2, MDD and OBJ-sequence outputs exist and read back (headers, sizes, and
 *     the last frame bit-identical across the three formats); the report lists
 *     every job with its status.
 *  2. The same manifest again: the finished jobs are skipped, the missing one fails.
 *  3. A long job beside a short one, SIGINT to the batch once the short one is
 *     done: exit 1, the short job's outputs kept, the long one reported
 *     interrupted, and no temporary file anywhere.
 *
 * Usage: test_batch RBCLOTH MESH_DIR OUT_DIR
 */
#define _POSIX_C_SOURCE 200809L
#include <cJSON.h>
#include <dirent.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "check.h"
#include "text_file.h"

static const char *g_cli, *g_meshes, *g_out;

static char *fmt(const char *f, const char *a, const char *b) {
    static char buf[8][2048];
    static int next = 0;
    char *p = buf[next++ % 8];
    snprintf(p, sizeof buf[0], f, a, b);
    return p;
}

static int exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0;
}

static void write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* Files whose name contains ".tmp" under dir (recursive). */
static int count_tmp(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        char p[2048];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (strstr(e->d_name, ".tmp")) {
            fprintf(stderr, "left behind: %s\n", p);
            n++;
        }
        struct stat st;
        if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) n += count_tmp(p);
    }
    closedir(d);
    return n;
}

/* Start `rbcloth batch MANIFEST -j 2 --out OUT --quiet`, stdout+stderr to log. */
static pid_t start_batch(const char *manifest, const char *out, const char *log) {
    pid_t pid = fork();
    if (pid == 0) {
        FILE *f = freopen(log, "w", stdout);
        (void)f;
        dup2(STDOUT_FILENO, STDERR_FILENO);
        execl(g_cli, g_cli, "batch", manifest, "-j", "2", "--out", out, "--quiet", (char *)NULL);
        _exit(127);
    }
    return pid;
}

static int wait_exit(pid_t pid) {
    int st = 0;
    if (waitpid(pid, &st, 0) != pid) return -1;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

static uint32_t le32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint32_t be32(const unsigned char *p) {
    return (uint32_t)p[3] | (uint32_t)p[2] << 8 | (uint32_t)p[1] << 16 | (uint32_t)p[0] << 24;
}

/* Job NAME with N points and F frames: PC2 and MDD headers and sizes; if objseq,
 * the last OBJ frame; the last frame's floats agree bit for bit across them. */
static void check_caches(const char *out, const char *name, uint32_t n, uint32_t frames,
                         int mdd, int objseq) {
    size_t size = 0;
    char path[2048];
    snprintf(path, sizeof path, "%s/%s/%s.pc2", out, name, name);
    unsigned char *pc2 = file_read_bytes(path, &size);
    CHECK(pc2 != NULL);
    if (!pc2) return;
    CHECK_EQ(size, 32 + (size_t)frames * n * 12);
    CHECK(memcmp(pc2, "POINTCACHE2", 12) == 0);
    CHECK_EQ(le32(pc2 + 16), n);
    CHECK_EQ(le32(pc2 + 28), frames);
    const unsigned char *last = pc2 + 32 + (size_t)(frames - 1) * n * 12;
    if (size != 32 + (size_t)frames * n * 12) {
        free(pc2);
        return;
    }
    if (mdd) {
        size_t msize = 0;
        snprintf(path, sizeof path, "%s/%s/%s.mdd", out, name, name);
        unsigned char *m = file_read_bytes(path, &msize);
        CHECK(m != NULL);
        size_t expect = 8 + 4 * (size_t)frames + (size_t)frames * n * 12;
        CHECK_EQ(msize, expect);
        if (m && msize == expect) {
            CHECK_EQ(be32(m), frames);
            CHECK_EQ(be32(m + 4), n);
            const unsigned char *ml = m + 8 + 4 * (size_t)frames + (size_t)(frames - 1) * n * 12;
            size_t bad = 0;
            for (size_t k = 0; k < 3 * (size_t)n; ++k) bad += le32(last + 4 * k) != be32(ml + 4 * k);
            CHECK_EQ(bad, 0);
        }
        free(m);
    }
    if (objseq) {
        char file[256];
        snprintf(file, sizeof file, "%s/frames/%s_%04u.obj", name, name, frames);
        size_t osize = 0;
        char *text = (char *)file_read_bytes(fmt("%s/%s", out, file), &osize);
        CHECK(text != NULL);
        snprintf(file, sizeof file, "%s/frames/%s_%04u.obj", name, name, frames + 1);
        CHECK(!exists(fmt("%s/%s", out, file)));
        size_t v = 0, bad = 0;
        for (char *line = text ? strtok(text, "\n") : NULL; line; line = strtok(NULL, "\n")) {
            if (strncmp(line, "v ", 2) != 0) continue;
            char *p = line + 2;
            for (int k = 0; k < 3; ++k) {
                float x = strtof(p, &p);
                uint32_t bits;
                memcpy(&bits, &x, 4);
                if (v < n) bad += bits != le32(last + 4 * (3 * v + (size_t)k));
            }
            v++;
        }
        CHECK_EQ(v, n);
        CHECK_EQ(bad, 0);
        free(text);
    }
    free(pc2);
}

/* The report: each named job with its status. */
static void check_report_json(const char *out, const char *const *names,
                              const char *const *statuses, int count) {
    size_t size = 0;
    char *text = (char *)file_read_bytes(fmt("%s/%s", out, "batch_report.json"), &size);
    CHECK(text != NULL);
    cJSON *root = text ? cJSON_Parse(text) : NULL;
    CHECK(root != NULL);
    const cJSON *jobs = cJSON_GetObjectItemCaseSensitive(root, "jobs");
    CHECK_EQ(cJSON_GetArraySize(jobs), count);
    for (int k = 0; k < count; ++k) {
        const cJSON *j = cJSON_GetArrayItem(jobs, k);
        const cJSON *name = cJSON_GetObjectItemCaseSensitive(j, "name");
        const cJSON *status = cJSON_GetObjectItemCaseSensitive(j, "status");
        int ok = cJSON_IsString(name) && strcmp(name->valuestring, names[k]) == 0 &&
                 cJSON_IsString(status) && strcmp(status->valuestring, statuses[k]) == 0;
        CHECK(ok);
        if (!ok)
            fprintf(stderr, "  report job %d: expected %s %s\n", k, names[k], statuses[k]);
        if (strcmp(statuses[k], "ok") == 0) {
            const cJSON *e = cJSON_GetObjectItemCaseSensitive(j, "error_eq7");
            const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, "vertices");
            CHECK(cJSON_IsNumber(e) && cJSON_IsNumber(v) && v->valuedouble > 0);
        }
    }
    cJSON_Delete(root);
    free(text);
    CHECK(exists(fmt("%s/%s", out, "batch_report.md")));
}

static int log_contains(const char *log, const char *needle) {
    size_t size = 0;
    char *text = (char *)file_read_bytes(log, &size);
    int found = text && strstr(text, needle) != NULL;
    if (!found) fprintf(stderr, "%s does not contain '%s':\n%s\n", log, needle, text ? text : "");
    free(text);
    return found;
}

static void test_failures_and_resume(void) {
    char out[1024], manifest[1100], log[1100], json[4096];
    snprintf(out, sizeof out, "%s/mixed", g_out);
    snprintf(manifest, sizeof manifest, "%s/mixed.json", g_out);
    snprintf(log, sizeof log, "%s/mixed.log", g_out);
    snprintf(json, sizeof json,
             "{\"defaults\": {\"frames\": 12, \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             " \"jobs\": [\n"
             "  {\"name\": \"grid\", \"mesh\": \"%s/grid_20x20.obj\", \"pins\": {\"top_axis\": \"z\"}},\n"
             "  {\"name\": \"missing\", \"mesh\": \"%s/no_such_mesh.obj\"},\n"
             "  {\"name\": \"patch\", \"mesh\": \"%s/tri_patch.obj\", \"solver\": \"multicolor_gs\","
             " \"pins\": {\"top_axis\": \"y\"}, \"frames\": 7},\n"
             "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 3, \"outputs\": [\"pc2\", \"mdd\"]}\n"
             " ]}\n",
             g_meshes, g_meshes, g_meshes);
    write_text(manifest, json);
    CHECK_EQ(wait_exit(start_batch(manifest, out, log)), 1);
    CHECK(log_contains(log, "missing: failed: import: RBC_ERR_IO"));
    CHECK(log_contains(log, "no_such_mesh.obj"));
    check_caches(out, "grid", 441, 12, 1, 1);
    check_caches(out, "patch", 121, 7, 1, 1);
    check_caches(out, "scene", 10000, 3, 1, 0);
    CHECK(exists(fmt("%s/%s", out, "grid/grid.obj")));
    CHECK_EQ(count_tmp(out), 0);
    static const char *const names[] = {"grid", "missing", "patch", "scene"};
    static const char *const first[] = {"ok", "failed", "ok", "ok"};
    check_report_json(out, names, first, 4);

    /* Rerun: finished jobs skipped, the missing mesh still fails. */
    CHECK_EQ(wait_exit(start_batch(manifest, out, log)), 1);
    CHECK(log_contains(log, "skipped grid"));
    CHECK(log_contains(log, "0 ok, 3 skipped, 1 failed"));
    static const char *const second[] = {"skipped", "failed", "skipped", "skipped"};
    check_report_json(out, names, second, 4);
}

static void test_interrupt(void) {
    char out[1024], manifest[1100], log[1100], json[4096];
    snprintf(out, sizeof out, "%s/interrupted", g_out);
    snprintf(manifest, sizeof manifest, "%s/interrupted.json", g_out);
    snprintf(log, sizeof log, "%s/interrupted.log", g_out);
    snprintf(json, sizeof json,
             "{\"jobs\": [\n"
             "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
             " \"pins\": {\"top_axis\": \"z\"}, \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             "  {\"name\": \"short\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 10,"
             " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             "  {\"name\": \"later\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 1000000}\n"
             " ]}\n",
             g_meshes, g_meshes, g_meshes);
    write_text(manifest, json);
    pid_t pid = start_batch(manifest, out, log);
    /* Wait until the short job has finished ("later" then runs), at most 10 s. */
    int seen = 0;
    for (int k = 0; k < 500 && !seen; ++k) {
        struct timespec ts = {0, 20 * 1000 * 1000};
        nanosleep(&ts, NULL);
        seen = exists(fmt("%s/%s", out, "short/short.result.json"));
    }
    CHECK(seen);
    struct timespec ts = {0, 200 * 1000 * 1000}; /* let the long jobs write tmp files */
    nanosleep(&ts, NULL);
    kill(pid, SIGINT);
    CHECK_EQ(wait_exit(pid), 1);
    CHECK(log_contains(log, "long: interrupted"));
    check_caches(out, "short", 45, 10, 1, 1);
    CHECK(!exists(fmt("%s/%s", out, "long/long.pc2")));
    CHECK(!exists(fmt("%s/%s", out, "long/frames/long_0001.obj")));
    CHECK_EQ(count_tmp(out), 0);
    static const char *const names[] = {"long", "short", "later"};
    static const char *const statuses[] = {"interrupted", "ok", "interrupted"};
    check_report_json(out, names, statuses, 3);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: test_batch RBCLOTH MESH_DIR OUT_DIR\n");
        return 2;
    }
    g_cli = argv[1];
    g_meshes = argv[2];
    g_out = argv[3];
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", g_out, g_out);
    if (system(cmd) != 0) return 2;
    test_failures_and_resume();
    test_interrupt();
    return check_report("test_batch");
}
