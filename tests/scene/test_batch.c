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
 *  4. Folder mode: a folder holding the sample meshes, an OFF file and files that
 *     are not meshes, with a template: one job per mesh, named after the file, in
 *     name order, with the template's settings; a rerun skips them all; --count.
 *  5. --only and --report-only (what a Slurm array task and its merge step run):
 *     each task runs exactly its entry, and the merged report says ok, failed (with
 *     the task's error) and not run.
 *
 * Usage: test_batch RBCLOTH MESH_DIR OUT_DIR
 */
#define _POSIX_C_SOURCE 200809L
#include <cJSON.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "check.h"
#include "files.h"
#include "proc.h"
#include "text_file.h"

static const char *g_cli, *g_meshes, *g_out;

/* Start `rbcloth batch MANIFEST -j 2 --out OUT --quiet`, stdout+stderr to log. */
static pid_t start_batch(const char *manifest, const char *out, const char *log) {
    const char *args[] = {"batch", manifest, "-j", "2", "--out", out, "--quiet", NULL};
    return proc_start(g_cli, NULL, log, args);
}

/* A case's manifest g_out/NAME.json (json, whose each %s is the mesh folder), its
 * --out folder g_out/NAME and its log g_out/NAME.log. */
static struct batch_case setup_case(const char *name, const char *json) {
    return batch_case_in(g_out, g_meshes, fmt("%s%s", name, ".json"), name,
                         fmt("%s%s", name, ".log"), json);
}

static uint32_t le32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint32_t be32(const unsigned char *p) {
    return (uint32_t)p[3] | (uint32_t)p[2] << 8 | (uint32_t)p[1] << 16 | (uint32_t)p[0] << 24;
}

static int cmp_triple(const void *x, const void *y) {
    return memcmp(x, y, 3 * sizeof(uint32_t));
}

/* Sorts n bit-triples and drops repeats; the count left. */
static size_t unique_triples(uint32_t *t, size_t n) {
    qsort(t, n, 3 * sizeof *t, cmp_triple);
    size_t m = 0;
    for (size_t k = 0; k < n; ++k)
        if (m == 0 || memcmp(t + 3 * (m - 1), t + 3 * k, 3 * sizeof *t) != 0)
            memmove(t + 3 * m++, t + 3 * k, 3 * sizeof *t);
    return m;
}

/* Job NAME with N points and F frames: PC2 and MDD headers and sizes; if objseq,
 * the last OBJ frame; the last frame's floats agree bit for bit across them. An OBJ
 * sequence is in the simulation's order; with same_order 0 the PC2 is in the mesh
 * file's (a mesh job's default, the file's vertices at the simulation's places: the
 * files here have no transform, so the same floats), so the two must hold the same
 * set of positions. */
static void check_caches(const char *out, const char *name, uint32_t n, uint32_t frames,
                         int mdd, int objseq, int same_order) {
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
        uint32_t *seq = malloc(3 * sizeof(uint32_t) * ((size_t)n + 1));
        uint32_t *cache = malloc(3 * sizeof(uint32_t) * ((size_t)n + 1));
        for (char *line = text ? strtok(text, "\n") : NULL; line; line = strtok(NULL, "\n")) {
            if (strncmp(line, "v ", 2) != 0) continue;
            char *p = line + 2;
            for (int k = 0; k < 3; ++k) {
                float x = strtof(p, &p);
                uint32_t bits;
                memcpy(&bits, &x, 4);
                if (v < n && same_order) bad += bits != le32(last + 4 * (3 * v + (size_t)k));
                if (v < n && seq) seq[3 * v + (size_t)k] = bits;
            }
            v++;
        }
        if (!same_order && v <= n && seq && cache) {
            for (size_t k = 0; k < 3 * (size_t)n; ++k) cache[k] = le32(last + 4 * k);
            size_t a = unique_triples(seq, v), b = unique_triples(cache, n);
            CHECK_EQ(a, b);
            if (a == b) bad = (size_t)(memcmp(seq, cache, 3 * sizeof(uint32_t) * a) != 0);
        }
        if (!same_order) CHECK(v <= n); /* a file vertex per welded one, or more */
        else CHECK_EQ(v, n);
        CHECK_EQ(bad, 0);
        free(seq);
        free(cache);
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

static void test_failures_and_resume(void) {
    struct batch_case c = setup_case(
        "mixed",
        "{\"defaults\": {\"frames\": 12,"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        " \"jobs\": [\n"
        "  {\"name\": \"grid\", \"mesh\": \"%s/grid_20x20.obj\","
        " \"pins\": {\"top_axis\": \"z\"}},\n"
        "  {\"name\": \"missing\", \"mesh\": \"%s/no_such_mesh.obj\"},\n"
        "  {\"name\": \"patch\", \"mesh\": \"%s/tri_patch.obj\","
        " \"solver\": \"multicolor_gs\", \"pins\": {\"top_axis\": \"y\"},"
        " \"frames\": 7, \"cache_order\": \"simulation\"},\n"
        "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 3,"
        " \"outputs\": [\"pc2\", \"mdd\"]}\n"
        " ]}\n");
    CHECK_EQ(proc_wait(start_batch(c.manifest, c.out, c.log)), 1);
    CHECK(log_contains(c.log, "missing: failed: import: RBC_ERR_IO"));
    CHECK(log_contains(c.log, "no_such_mesh.obj"));
    check_caches(c.out, "grid", 441, 12, 1, 1, 0);
    check_caches(c.out, "patch", 121, 7, 1, 1, 1);
    check_caches(c.out, "scene", 10000, 3, 1, 0, 1);
    CHECK(exists(fmt("%s/%s", c.out, "grid/grid.obj")));
    CHECK_EQ(count_tmp(c.out), 0);
    static const char *const names[] = {"grid", "missing", "patch", "scene"};
    static const char *const first[] = {"ok", "failed", "ok", "ok"};
    check_report_json(c.out, names, first, 4);

    /* Rerun: finished jobs skipped, the missing mesh still fails. */
    CHECK_EQ(proc_wait(start_batch(c.manifest, c.out, c.log)), 1);
    CHECK(log_contains(c.log, "skipped grid"));
    CHECK(log_contains(c.log, "0 ok, 3 skipped, 1 failed"));
    static const char *const second[] = {"skipped", "failed", "skipped", "skipped"};
    check_report_json(c.out, names, second, 4);
}

/* A worker killed with SIGKILL in the middle of its frames (a job the OOM killer or a
 * user ends): the batch reports it crashed, removes its temporary files, runs the
 * rest, and exits 1. The worker is found as the batch's child process. */
static void test_killed_job(void) {
    struct batch_case c = setup_case(
        "killed",
        "{\"jobs\": [\n"
        "  {\"name\": \"victim\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        "  {\"name\": \"after\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 10,"
        " \"outputs\": [\"pc2\"]}\n"
        " ]}\n");
    pid_t pid = start_batch(c.manifest, c.out, c.log); /* the victim is forked first */
    long worker = 0;
    for (int k = 0; k < 500 && worker <= 0; ++k) { /* at most 10 s */
        nap(0.02);
        if (!exists(fmt("%s/%s", c.out, "victim"))) continue; /* the victim has started */
        worker = proc_first_child(pid);
    }
    CHECK(worker > 0);
    if (worker > 0) {
        nap(0.3); /* some frames into its tmp files */
        kill((pid_t)worker, SIGKILL);
    } else {
        kill(pid, SIGINT); /* never leave the batch running */
    }
    CHECK_EQ(proc_wait(pid), 1);
    CHECK(log_contains(c.log, "victim: crashed: signal 9"));
    CHECK(exists(fmt("%s/%s", c.out, "after/after.pc2")));
    CHECK(!exists(fmt("%s/%s", c.out, "victim/victim.pc2")));
    CHECK_EQ(count_tmp(c.out), 0);
}

static void test_interrupt(void) {
    struct batch_case c = setup_case(
        "interrupted",
        "{\"jobs\": [\n"
        "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
        " \"pins\": {\"top_axis\": \"z\"},"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        "  {\"name\": \"short\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 10,"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        "  {\"name\": \"later\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 1000000}\n"
        " ]}\n");
    pid_t pid = start_batch(c.manifest, c.out, c.log);
    /* Wait until the short job has finished ("later" then runs), at most 10 s. */
    int seen = wait_for_files(fmt("%s/%s", c.out, "short/short.result.json"), NULL, 500, 0.02);
    CHECK(seen);
    nap(0.2); /* let the long jobs write tmp files */
    kill(pid, SIGINT);
    CHECK_EQ(proc_wait(pid), 1);
    CHECK(log_contains(c.log, "long: interrupted"));
    check_caches(c.out, "short", 45, 10, 1, 1, 0);
    CHECK(!exists(fmt("%s/%s", c.out, "long/long.pc2")));
    CHECK(!exists(fmt("%s/%s", c.out, "long/frames/long_0001.obj")));
    CHECK_EQ(count_tmp(c.out), 0);
    static const char *const names[] = {"long", "short", "later"};
    static const char *const statuses[] = {"interrupted", "ok", "interrupted"};
    check_report_json(c.out, names, statuses, 3);
}

/* Run RBCLOTH with the given arguments (NULL-terminated), stdout+stderr to log. */
static int run_cli(const char *log, const char *const *args) {
    return proc_wait(proc_start(g_cli, NULL, log, args));
}

static void copy_file(const char *from, const char *to) {
    size_t size = 0;
    unsigned char *b = file_read_bytes(from, &size);
    CHECK(b != NULL);
    FILE *f = fopen(to, "wb");
    CHECK(f != NULL);
    if (b && f) CHECK_EQ(fwrite(b, 1, size, f), size);
    if (f) fclose(f);
    free(b);
}

static void test_folder(void) {
    char dir[1024], out[1024], tmpl[1100], log[1100];
    snprintf(dir, sizeof dir, "%s/meshes", g_out);
    snprintf(out, sizeof out, "%s/folder", g_out);
    snprintf(tmpl, sizeof tmpl, "%s/template.json", g_out);
    snprintf(log, sizeof log, "%s/folder.log", g_out);
    mkdir(dir, 0755);
    static const char *const objs[] = {"grid_20x20.obj", "strip_8x4.obj", "tri_patch.obj"};
    for (int k = 0; k < 3; ++k)
        copy_file(fmt("%s/%s", g_meshes, objs[k]), fmt("%s/%s", dir, objs[k]));
    /* A 3 x 3 vertex grid hanging in the x-y plane, as OFF (another assimp reader). */
    write_text(fmt("%s/%s", dir, "square.off"),
               "OFF\n9 4 0\n0 0 0\n0.5 0 0\n1 0 0\n0 0.5 0\n0.5 0.5 0\n1 0.5 0\n"
               "0 1 0\n0.5 1 0\n1 1 0\n4 0 1 4 3\n4 1 2 5 4\n4 3 4 7 6\n4 4 5 8 7\n");
    write_text(fmt("%s/%s", dir, "README.txt"), "not a mesh\n");
    write_text(fmt("%s/%s", dir, "notes.json"), "{}\n");
    mkdir(fmt("%s/%s", dir, "sub.obj"), 0755); /* a folder, even with a mesh's name */
    write_text(tmpl, "{\"frames\": 6, \"solver\": \"rbgs\", \"pins\": {\"top_axis\": \"y\","
                     " \"top_tolerance\": 0.001}, \"outputs\": [\"pc2\", \"mdd\"]}\n");
    const char *args[] = {"batch", dir, "--template", tmpl, "-j", "2", "--out", out, "--quiet", NULL};
    CHECK_EQ(run_cli(log, args), 0);
    check_caches(out, "grid_20x20", 441, 6, 1, 0, 0);
    check_caches(out, "square", 9, 6, 1, 0, 0);
    check_caches(out, "strip_8x4", 45, 6, 1, 0, 0);
    check_caches(out, "tri_patch", 121, 6, 1, 0, 0);
    CHECK(!exists(fmt("%s/%s", out, "README")));
    CHECK(!exists(fmt("%s/%s", out, "sub")));
    static const char *const names[] = {"grid_20x20", "square", "strip_8x4", "tri_patch"};
    static const char *const ok[] = {"ok", "ok", "ok", "ok"};
    static const char *const skipped[] = {"skipped", "skipped", "skipped", "skipped"};
    check_report_json(out, names, ok, 4);
    CHECK_EQ(run_cli(log, args), 0);
    CHECK(log_contains(log, "0 ok, 4 skipped, 0 failed"));
    check_report_json(out, names, skipped, 4);
    const char *count[] = {"batch", dir, "--template", tmpl, "--count", NULL};
    CHECK_EQ(run_cli(log, count), 0);
    CHECK(log_contains(log, "4\n"));
    /* Misuse is refused clearly. */
    const char *no_template[] = {"batch", dir, "--out", out, NULL};
    CHECK_EQ(run_cli(log, no_template), 1);
    CHECK(log_contains(log, "folder mode needs --template"));
    const char *empty[] = {"batch", out, "--template", tmpl, "--out", out, NULL};
    CHECK_EQ(run_cli(log, empty), 1);
    CHECK(log_contains(log, "no mesh file"));
}

static void test_only_and_report(void) {
    struct batch_case c = setup_case(
        "only",
        "{\"defaults\": {\"frames\": 5},\n"
        " \"jobs\": [\n"
        "  {\"name\": \"strip\", \"mesh\": \"%s/strip_8x4.obj\"},\n"
        "  {\"name\": \"missing\", \"mesh\": \"%s/no_such_mesh.obj\"},\n"
        "  {\"name\": \"patch\", \"mesh\": \"%s/tri_patch.obj\"}\n"
        " ]}\n");
    const char *task0[] = {"batch", c.manifest, "--only", "0", "--out", c.out, "--quiet", NULL};
    CHECK_EQ(run_cli(c.log, task0), 0);
    CHECK(exists(fmt("%s/%s", c.out, "strip/strip.result.json")));
    CHECK(!exists(fmt("%s/%s", c.out, "patch")));
    CHECK(!exists(fmt("%s/%s", c.out, "batch_report.json")));
    const char *task1[] = {"batch", c.manifest, "--only", "1", "--out", c.out, "--quiet", NULL};
    CHECK_EQ(run_cli(c.log, task1), 1);
    CHECK(log_contains(c.log, "missing: failed"));
    const char *task9[] = {"batch", c.manifest, "--only", "3", "--out", c.out, NULL};
    CHECK_EQ(run_cli(c.log, task9), 1);
    CHECK(log_contains(c.log, "has 3 jobs"));
    const char *merge[] = {"batch", c.manifest, "--report-only", "--out", c.out, NULL};
    CHECK_EQ(run_cli(c.log, merge), 1);
    static const char *const names[] = {"strip", "missing", "patch"};
    static const char *const statuses[] = {"ok", "failed", "not run"};
    check_report_json(c.out, names, statuses, 3);
    CHECK(log_contains(fmt("%s/%s", c.out, "batch_report.json"), "RBC_ERR_IO"));
    CHECK(!exists(fmt("%s/%s", c.out, "patch")));
    /* The last task, then the merge again: everything but the missing mesh is ok. */
    const char *task2[] = {"batch", c.manifest, "--only", "2", "--out", c.out, "--quiet", NULL};
    CHECK_EQ(run_cli(c.log, task2), 0);
    CHECK_EQ(run_cli(c.log, merge), 1);
    static const char *const after[] = {"ok", "failed", "ok"};
    check_report_json(c.out, names, after, 3);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: test_batch RBCLOTH MESH_DIR OUT_DIR\n");
        return 2;
    }
    g_cli = argv[1];
    g_meshes = argv[2];
    g_out = argv[3];
    if (fresh_dir(g_out) != 0) return 2;
    test_failures_and_resume();
    test_interrupt();
    test_killed_job();
    test_folder();
    test_only_and_report();
    return check_report("test_batch");
}
