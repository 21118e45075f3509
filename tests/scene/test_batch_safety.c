/* test_batch_safety.c -- what a killed, stopped or doubled `rbcloth batch` (and a
 * stopped `rbcloth run`) leaves behind (issue 17, "A resumed batch can corrupt
 * finished outputs"). One case per CTest test:
 *
 *  parent_kill  SIGKILL of the batch parent alone in the middle of its jobs, then a
 *               resume at once: no worker of the first run is alive 0.3 s later
 *               (they die with the parent), and every output of every job equals,
 *               byte for byte, that of an uninterrupted batch.
 *  lock         a second batch on a folder a batch runs in is refused at once,
 *               naming the folder and the holder's pid; so is `rbcloth run` into
 *               one of its jobs' folders; two --only tasks share a folder.
 *  abs_out      a batch run with a relative --out from one folder is resumed with
 *               the absolute --out from another: every finished job is skipped.
 *  job_timeout  --job-timeout 1 (and a job's "timeout" key) kills a job that runs
 *               too long; it fails "timed out", the next job runs, no temporary
 *               file is left.
 *  sigterm      SIGTERM to the parent while one worker is inside a frame that
 *               takes minutes: the batch ends within --term-grace 1 plus a margin,
 *               its workers are gone and no temporary file is left.
 *  run_sigint   SIGINT and SIGTERM to `rbcloth run`: exit 1, a message, no
 *               NAME.pc2.tmp; a second SIGINT during a frame that takes minutes
 *               stops it at once.
 *
 * Usage: test_batch_safety CASE RBCLOTH MESH_DIR OUT_DIR
 */
#define _POSIX_C_SOURCE 200809L
#include <dirent.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "files.h"
#include "proc.h"
#include "text_file.h"

static const char *g_cli, *g_meshes, *g_out;

/* Start RBCLOTH ARGS... (NULL-terminated) in folder cwd (NULL: this one), stdout
 * and stderr to log. */
static pid_t start(const char *cwd, const char *log, const char *const *args) {
    return proc_start(g_cli, cwd, log, args);
}

static int run_cli(const char *cwd, const char *log, const char *const *args, double limit) {
    return proc_wait_for(start(cwd, log, args), limit);
}

/* Start RBCLOTH ARGS... with its output in log, wait (at most 1000 naps of 10 ms)
 * until path a, and b unless NULL, show how far it got, then `settle` seconds more
 * (0: none); its pid. */
static pid_t start_until(const char *log, const char *const *args, const char *a, const char *b,
                         double settle) {
    pid_t pid = start(NULL, log, args);
    int seen = wait_for_files(a, b, 1000, 0.01);
    if (!seen) fprintf(stderr, "%s%s%s did not appear\n", a, b ? " or " : "", b ? b : "");
    CHECK(seen);
    if (settle > 0) nap(settle);
    return pid;
}

/* A case's manifest g_out/MANIFEST (json, whose each %s is the mesh folder), its
 * --out folder g_out/OUT and its log g_out/LOG. */
static struct batch_case setup_case(const char *manifest, const char *out, const char *log,
                                    const char *json) {
    return batch_case_in(g_out, g_meshes, manifest, out, log, json);
}

/* Compare every file under ref/rel with the same file under got/rel, and the other
 * way round for presence; results (.result.json, .status.json: timings) are left
 * out. Adds the files compared and the mismatches. */
static void compare_trees(const char *ref, const char *got, const char *rel, int *compared,
                          int *mismatches) {
    char rdir[2048], gdir[2048];
    snprintf(rdir, sizeof rdir, "%s/%s", ref, rel);
    snprintf(gdir, sizeof gdir, "%s/%s", got, rel);
    for (int side = 0; side < 2; ++side) {
        DIR *d = opendir(side == 0 ? rdir : gdir);
        if (!d) {
            fprintf(stderr, "cannot open %s\n", side == 0 ? rdir : gdir);
            (*mismatches)++;
            continue;
        }
        struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            const char *name = e->d_name;
            if (strcmp(name, ".") == 0 || strcmp(name, "..") == 0 || strstr(name, ".result.json") ||
                strstr(name, ".status.json"))
                continue;
            char sub[2048], rp[4096], gp[4096];
            snprintf(sub, sizeof sub, "%s/%s", rel, name);
            snprintf(rp, sizeof rp, "%s/%s", ref, sub);
            snprintf(gp, sizeof gp, "%s/%s", got, sub);
            struct stat st;
            if (side == 1) {
                if (!exists(rp)) {
                    fprintf(stderr, "%s: not in the reference\n", gp);
                    (*mismatches)++;
                }
                continue;
            }
            if (stat(rp, &st) == 0 && S_ISDIR(st.st_mode)) {
                compare_trees(ref, got, sub, compared, mismatches);
                continue;
            }
            size_t rs = 0, gs = 0;
            unsigned char *rb = file_read_bytes(rp, &rs), *gb = file_read_bytes(gp, &gs);
            (*compared)++;
            if (!rb || !gb || rs != gs || memcmp(rb, gb, rs) != 0) {
                fprintf(stderr, "%s differs from %s (%zu and %zu bytes)\n", gp, rp, gs, rs);
                (*mismatches)++;
            }
            free(rb);
            free(gb);
        }
        closedir(d);
    }
}

/* ------------------------------------------------------------------------- */

/* Four jobs, -j 2, a few seconds in all; "first" ends well before the others, and
 * "grid" runs for over a second after it (at 500 frames it and the others could
 * all be done 0.2 s after it on an idle machine: the kill then found no temporary). */
static const char four_jobs[] =
    "{\"defaults\": {\"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
    " \"jobs\": [\n"
    "  {\"name\": \"first\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 20},\n"
    "  {\"name\": \"grid\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 4000,"
    " \"pins\": {\"top_axis\": \"z\"}, \"outputs\": [\"pc2\", \"mdd\"]},\n"
    "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 60,"
    " \"outputs\": [\"pc2\", \"mdd\"]},\n"
    "  {\"name\": \"patch\", \"mesh\": \"%s/tri_patch.obj\", \"frames\": 400,"
    " \"pins\": {\"top_axis\": \"y\"}}\n"
    " ]}\n";

static void test_parent_kill(void) {
    struct batch_case c = setup_case("four.json", "killed", "killed.log", four_jobs);
    char ref[1100];
    snprintf(ref, sizeof ref, "%s/reference", g_out);
    const char *ref_args[] = {"batch", c.manifest, "-j", "2", "--out", ref, "--quiet", NULL};
    CHECK_EQ(run_cli(NULL, fmt("%s/%s", g_out, "reference.log"), ref_args, 60), 0);

    const char *args[] = {"batch", c.manifest, "-j", "2", "--out", c.out, "--quiet", NULL};
    /* Once "first" is done, two long jobs run with their temporaries open. */
    pid_t pid = start_until(c.log, args, fmt("%s/%s", c.out, "first/first.result.json"), NULL, 0.2);
    long workers[8];
    int n = proc_children(pid, workers, 8);
    CHECK(n > 0);
    CHECK(count_tmp_in(c.out, 0) > 0); /* in the middle of writing */
    kill(pid, SIGKILL);
    CHECK_EQ(proc_wait_for(pid, 10), 128 + SIGKILL);
    /* Resume at once. */
    char log2[1100];
    snprintf(log2, sizeof log2, "%s/resumed.log", g_out);
    pid_t again = start(NULL, log2, args);
    nap(0.3);
    for (int k = 0; k < n; ++k) {
        if (proc_alive(workers[k]))
            fprintf(stderr, "worker %ld of the killed batch is alive\n", workers[k]);
        CHECK(!proc_alive(workers[k]));
    }
    CHECK_EQ(proc_wait_for(again, 60), 0);
    CHECK(log_contains(log2, "skipped first"));
    for (int k = 0; k < n; ++k) CHECK(!proc_alive(workers[k]));
    CHECK_EQ(count_tmp(c.out), 0);
    int compared = 0, mismatches = 0;
    static const char *const jobs[] = {"first", "grid", "scene", "patch"};
    for (int k = 0; k < 4; ++k) compare_trees(ref, c.out, jobs[k], &compared, &mismatches);
    /* first: obj, pc2, mdd, 20 frames, png, html; the others obj, pc2, mdd, png, html
     * (patch: and 400 frames). */
    CHECK_EQ(compared, 25 + 5 + 5 + 405);
    CHECK_EQ(mismatches, 0);
}

static void test_lock(void) {
    struct batch_case c = setup_case(
        "long.json", "locked", "first.log",
        "{\"jobs\": [\n"
        "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000},\n"
        "  {\"name\": \"short\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 5}\n"
        " ]}\n");
    const char *out = c.out;
    const char *args[] = {"batch", c.manifest, "-j", "1", "--out", out, "--quiet", NULL};
    pid_t pid = start_until(c.log, args, fmt("%s/%s", out, "long/long.pc2.tmp"), NULL, 0);
    /* A second batch on the folder: refused at once, naming it and the holder. */
    char second[1100], expect[4096];
    snprintf(second, sizeof second, "%s/second.log", g_out);
    double t0 = now_seconds();
    CHECK_EQ(run_cli(NULL, second, args, 30), 1);
    CHECK(now_seconds() - t0 < 3.0);
    snprintf(expect, sizeof expect, "rbcloth: batch: %s is in use by another rbcloth (pid %ld on ",
             out, (long)pid);
    CHECK(log_contains(second, expect));
    CHECK(log_contains(second, "wait for it to end or choose another --out"));
    CHECK(!file_contains(second, "rbcloth batch: 2 jobs", 0));
    /* So is an array task of the same folder, and `rbcloth run` into a job's folder. */
    const char *task[] = {"batch", c.manifest, "--only", "1", "--out", out, "--quiet", NULL};
    CHECK_EQ(run_cli(NULL, second, task, 30), 1);
    CHECK(log_contains(second, "is in use by another rbcloth"));
    CHECK(!exists(fmt("%s/%s", out, "short/short.result.json")));
    const char *run[] = {"run", "--frames", "2", "--quiet", "--out", fmt("%s/%s", out, "long"),
                         NULL};
    CHECK_EQ(run_cli(NULL, second, run, 30), 1);
    snprintf(expect, sizeof expect, "cannot write into %s/long: %s is in use", out, out);
    CHECK(log_contains(second, expect));
    CHECK(!exists(fmt("%s/%s", out, "long/hanging_cloth.json")));
    kill(pid, SIGTERM);
    CHECK_EQ(proc_wait_for(pid, 30), 1);
    /* Free again once it ended: the short job runs. */
    CHECK_EQ(run_cli(NULL, second, task, 30), 0);
    CHECK(exists(fmt("%s/%s", out, "short/short.result.json")));

    /* Array tasks share a folder: a task ends while another one runs there. */
    char tasks[1100];
    snprintf(tasks, sizeof tasks, "%s/tasks", g_out);
    const char *task0[] = {"batch", c.manifest, "--only", "0", "--out", tasks, "--quiet", NULL};
    const char *task1[] = {"batch", c.manifest, "--only", "1", "--out", tasks, "--quiet", NULL};
    pid_t t = start_until(fmt("%s/%s", g_out, "task0.log"), task0,
                          fmt("%s/%s", tasks, "long/long.pc2.tmp"), NULL, 0);
    CHECK_EQ(run_cli(NULL, fmt("%s/%s", g_out, "task1.log"), task1, 30), 0);
    CHECK(exists(fmt("%s/%s", tasks, "short/short.result.json")));
    kill(t, SIGTERM);
    CHECK_EQ(proc_wait_for(t, 30), 1);
    CHECK_EQ(count_tmp(out) + count_tmp(tasks), 0);
}

static void test_abs_out(void) {
    char work[1100], manifest[1200], log[1100], abs_out[4096];
    snprintf(work, sizeof work, "%s/workdir", g_out);
    snprintf(manifest, sizeof manifest, "%s/two.json", work);
    snprintf(log, sizeof log, "%s/abs.log", g_out);
    mkdir(work, 0755);
    write_text_sub(manifest,
                   "{\"defaults\": {\"frames\": 6, \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
                   " \"jobs\": [\n"
                   "  {\"name\": \"strip\", \"mesh\": \"%s/strip_8x4.obj\"},\n"
                   "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 2}\n"
                   " ]}\n",
                   g_meshes);
    /* From workdir with a relative --out ... */
    const char *rel[] = {"batch", "two.json", "--out", "rel/out", "--quiet", NULL};
    CHECK_EQ(run_cli(work, log, rel, 60), 0);
    CHECK(log_contains(log, "2 ok, 0 skipped"));
    /* ... resumed from another folder with the absolute --out, and with a trailing
     * slash and a doubled one from workdir: nothing is redone. */
    char *cwd = getcwd(NULL, 0);
    if (work[0] == '/')
        snprintf(abs_out, sizeof abs_out, "%s/rel/out", work);
    else
        snprintf(abs_out, sizeof abs_out, "%s/%s/rel/out", cwd, work);
    free(cwd);
    const char *absolute[] = {"batch", manifest, "--out", abs_out, "--quiet", NULL};
    CHECK_EQ(run_cli(g_out, log, absolute, 60), 0);
    CHECK(log_contains(log, "0 ok, 2 skipped"));
    const char *respelled[] = {"batch", "two.json", "--out", "./rel//out/", "--quiet", NULL};
    CHECK_EQ(run_cli(work, log, respelled, 60), 0);
    CHECK(log_contains(log, "0 ok, 2 skipped"));
    /* The result lists its outputs relative to the job's folder. */
    CHECK(log_contains(fmt("%s/%s", work, "rel/out/strip/strip.result.json"),
                       "\"frames/strip_0006.obj\""));
    /* A changed output (its size) is no finished job: it is redone. */
    write_text(fmt("%s/%s", work, "rel/out/strip/strip.mdd"), "truncated");
    CHECK_EQ(run_cli(g_out, log, absolute, 60), 0);
    CHECK(log_contains(log, "1 ok, 1 skipped"));
}

static void test_job_timeout(void) {
    struct batch_case c = setup_case(
        "slow.json", "timeout", "timeout.log",
        "{\"jobs\": [\n"
        "  {\"name\": \"slow\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        "  {\"name\": \"fast\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 10},\n"
        "  {\"name\": \"own\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 1000000,"
        " \"timeout\": 0.5}\n"
        " ]}\n");
    const char *args[] = {"batch", c.manifest, "-j", "1", "--job-timeout", "1", "--out", c.out,
                          "--quiet", NULL};
    double t0 = now_seconds();
    CHECK_EQ(run_cli(NULL, c.log, args, 60), 1);
    const double wall = now_seconds() - t0;
    CHECK(wall < 1.5 + 6.0); /* 1 s, 0.5 s and the short job, with a margin */
    CHECK(log_contains(c.log, "slow: failed: timed out after 1 s"));
    CHECK(log_contains(c.log, "own: failed: timed out after 0.5 s"));
    CHECK(log_contains(c.log, "ok      fast"));
    CHECK(exists(fmt("%s/%s", c.out, "fast/fast.result.json")));
    CHECK(!exists(fmt("%s/%s", c.out, "slow/slow.result.json")));
    CHECK(log_contains(fmt("%s/%s", c.out, "slow/slow.status.json"), "timed out after 1 s"));
    CHECK(log_contains(fmt("%s/%s", c.out, "batch_report.json"), "timed out after 0.5 s"));
    CHECK_EQ(count_tmp(c.out), 0);
    /* The key is known (a typo gets it), and the option needs seconds. */
    write_text(fmt("%s/%s", g_out, "typo.json"), "{\"jobs\": [{\"name\": \"x\", \"scene\": "
                                                 "\"default\", \"timout\": 3}]}\n");
    const char *typo[] = {"batch", fmt("%s/%s", g_out, "typo.json"), "--out", c.out, NULL};
    CHECK_EQ(run_cli(NULL, c.log, typo, 30), 1);
    CHECK(log_contains(c.log, "jobs[0].timout: unknown key; did you mean \"timeout\"?"));
    /* The round-trip keys (issue 19): values checked, and only for mesh jobs. */
    static const struct {
        const char *job, *says;
    } keys[] = {
        {"\"mesh\": \"m.obj\", \"cache_order\": \"files\"",
         "jobs[0 (x)].cache_order: must be one of: simulation file"},
        {"\"mesh\": \"m.obj\", \"keep_file_units\": 1",
         "jobs[0 (x)].keep_file_units: must be true or false"},
        {"\"scene\": \"default\", \"cache_order\": \"file\"",
         "jobs[0 (x)].cache_order: cache_order and keep_file_units are for mesh jobs"},
    };
    for (size_t k = 0; k < sizeof keys / sizeof keys[0]; ++k) {
        char json[512];
        snprintf(json, sizeof json, "{\"jobs\": [{\"name\": \"x\", %s}]}\n", keys[k].job);
        write_text(fmt("%s/%s", g_out, "keys.json"), json);
        const char *run[] = {"batch", fmt("%s/%s", g_out, "keys.json"), "--out", c.out, NULL};
        CHECK_EQ(run_cli(NULL, c.log, run, 30), 1);
        CHECK(log_contains(c.log, keys[k].says));
    }
    const char *bad[] = {"batch", c.manifest, "--job-timeout", "-1", NULL};
    CHECK_EQ(run_cli(NULL, c.log, bad, 30), 2);
    CHECK(log_contains(c.log, "--job-timeout needs a number of seconds"));
}

static void test_sigterm(void) {
    /* "stuck": one frame of 1024 substeps x 4096 iterations on 10,000 vertices takes
     * minutes, so its worker never reaches its check of the signal, like a job
     * inside an importer. "long": many short frames; it stops at the next one. */
    struct batch_case c = setup_case(
        "stuck.json", "sigterm", "sigterm.log",
        "{\"jobs\": [\n"
        "  {\"name\": \"stuck\", \"scene\": \"default\", \"frames\": 3, \"substeps\": 1024,"
        " \"iterations\": 4096, \"outputs\": [\"pc2\", \"mdd\"]},\n"
        "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
        " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
        "  {\"name\": \"later\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 5}\n"
        " ]}\n");
    const char *args[] = {"batch", c.manifest, "-j", "2", "--term-grace", "1", "--out", c.out,
                          "--quiet", NULL};
    pid_t pid = start_until(c.log, args, fmt("%s/%s", c.out, "stuck/stuck.pc2.tmp"),
                            fmt("%s/%s", c.out, "long/long.pc2.tmp"), 0.3);
    long workers[8];
    int n = proc_children(pid, workers, 8);
    CHECK_EQ(n, 2);
    double t0 = now_seconds();
    kill(pid, SIGTERM);
    CHECK_EQ(proc_wait_for(pid, 60), 1);
    const double took = now_seconds() - t0;
    if (took >= 1.0 + 3.0) fprintf(stderr, "the batch took %.2f s to stop\n", took);
    CHECK(took < 1.0 + 3.0); /* the grace period, then the reports */
    for (int k = 0; k < n; ++k) CHECK(!proc_alive(workers[k]));
    CHECK(log_contains(c.log, "stuck: interrupted: stopped by a signal: killed, still running "
                              "1 s after SIGTERM"));
    CHECK(log_contains(c.log, "long: interrupted: stopped by a signal"));
    CHECK(log_contains(c.log, "later: not run"));
    CHECK_EQ(count_tmp(c.out), 0);
    CHECK(!exists(fmt("%s/%s", c.out, "stuck/stuck.pc2")));
}

static void test_run_sigint(void) {
    char out[1100], log[1100];
    static const int sigs[2] = {SIGINT, SIGTERM};
    for (int k = 0; k < 2; ++k) {
        snprintf(out, sizeof out, "%s/run_%d", g_out, k);
        snprintf(log, sizeof log, "%s/run_%d.log", g_out, k);
        const char *args[] = {"run", "--frames", "1000000", "--threads", k ? "2" : "1", "--quiet",
                              "--out", out, NULL};
        pid_t pid = start_until(log, args, fmt("%s/%s", out, "hanging_cloth.pc2.tmp"), NULL, 0.3);
        kill(pid, sigs[k]);
        CHECK_EQ(proc_wait_for(pid, 10), 1);
        CHECK(log_contains(log, k ? "rbcloth: stopped by SIGTERM after "
                                  : "rbcloth: stopped by SIGINT after "));
        CHECK(log_contains(log, "temporary files removed"));
        CHECK_EQ(count_tmp(out), 0);
        CHECK(!exists(fmt("%s/%s", out, "hanging_cloth.pc2")));
        CHECK(!exists(fmt("%s/%s", out, "hanging_cloth.json")));
    }
    /* A frame that takes minutes: the second SIGINT stops it at once. */
    snprintf(out, sizeof out, "%s/run_stuck", g_out);
    snprintf(log, sizeof log, "%s/run_stuck.log", g_out);
    const char *args[] = {"run", "--frames", "3", "--substeps", "1024", "--iterations", "4096",
                          "--threads", "1", "--quiet", "--out", out, NULL};
    /* 0.5 s: inside the first frame */
    pid_t pid = start_until(log, args, fmt("%s/%s", out, "hanging_cloth.pc2.tmp"), NULL, 0.5);
    kill(pid, SIGINT);
    nap(0.3);
    kill(pid, SIGINT);
    CHECK_EQ(proc_wait_for(pid, 5), 1);
    CHECK(log_contains(log, "stopped by a second signal; temporary files removed"));
    CHECK_EQ(count_tmp(out), 0);
}

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: test_batch_safety CASE RBCLOTH MESH_DIR OUT_DIR\n");
        return 2;
    }
    const char *which = argv[1];
    g_cli = argv[2];
    g_meshes = argv[3];
    g_out = argv[4];
    if (fresh_dir(g_out) != 0) return 2;
    static const struct {
        const char *name;
        void (*run)(void);
    } cases[] = {{"parent_kill", test_parent_kill}, {"lock", test_lock},
                 {"abs_out", test_abs_out},         {"job_timeout", test_job_timeout},
                 {"sigterm", test_sigterm},         {"run_sigint", test_run_sigint}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        if (strcmp(which, cases[k].name) == 0) {
            cases[k].run();
            return check_report(which);
        }
    fprintf(stderr, "test_batch_safety: unknown case '%s'\n", which);
    return 2;
}
