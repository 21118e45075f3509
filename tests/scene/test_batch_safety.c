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
#include <errno.h>
#include <fcntl.h>
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

static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void nap(double seconds) {
    struct timespec ts = {(time_t)seconds, (long)((seconds - (double)(time_t)seconds) * 1e9)};
    nanosleep(&ts, NULL);
}

static char *fmt(const char *f, const char *a, const char *b) {
    static char buf[16][2048];
    static int next = 0;
    char *p = buf[next++ % 16];
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

static int contains(const char *log, const char *needle, int say) {
    char *text = (char *)file_read_bytes(log, NULL);
    int found = text && strstr(text, needle) != NULL;
    if (!found && say)
        fprintf(stderr, "%s does not contain '%s':\n%s\n", log, needle, text ? text : "");
    free(text);
    return found;
}

static int log_contains(const char *log, const char *needle) { return contains(log, needle, 1); }

/* Start RBCLOTH ARGS... (NULL-terminated) in folder cwd (NULL: this one), stdout
 * and stderr to log. */
static pid_t start(const char *cwd, const char *log, const char *const *args) {
    char *argv[40];
    int n = 0;
    argv[n++] = (char *)g_cli;
    for (; args[n - 1] && n < 39; ++n) argv[n] = (char *)args[n - 1];
    argv[n] = NULL;
    pid_t pid = fork();
    if (pid == 0) {
        if (cwd && chdir(cwd) != 0) _exit(126);
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, STDOUT_FILENO);
            dup2(fd, STDERR_FILENO);
            close(fd);
        }
        execv(g_cli, argv);
        _exit(127);
    }
    return pid;
}

/* Its exit status (128 + signal when killed), or -1 after `limit` seconds, when it
 * is killed so that no test leaves a process behind. */
static int wait_exit(pid_t pid, double limit) {
    const double t0 = now_seconds();
    for (;;) {
        int st = 0;
        pid_t r = waitpid(pid, &st, WNOHANG);
        if (r == pid) return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
        if (r < 0) return -1;
        if (now_seconds() - t0 > limit) {
            fprintf(stderr, "pid %ld still running after %.0f s: killed\n", (long)pid, limit);
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            return -1;
        }
        nap(0.01);
    }
}

static int run_cli(const char *cwd, const char *log, const char *const *args, double limit) {
    return wait_exit(start(cwd, log, args), limit);
}

/* /proc/PID/stat: its parent and state ('Z' zombie); 0 when there is no such pid. */
static int proc_stat(long pid, long *ppid, char *state) {
    char path[64];
    snprintf(path, sizeof path, "/proc/%ld/stat", pid);
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    char text[1024];
    size_t n = fread(text, 1, sizeof text - 1, f); /* /proc files report size 0 */
    fclose(f);
    text[n] = '\0';
    const char *rp = strrchr(text, ')'); /* pid (comm) state ppid ...; comm may hold spaces */
    if (!rp || sscanf(rp + 2, "%c %ld", state, ppid) != 2) return 0;
    return 1;
}

/* Whether pid runs (a zombie has exited). */
static int alive(long pid) {
    long ppid;
    char state;
    return proc_stat(pid, &ppid, &state) && state != 'Z' && state != 'X';
}

/* The children of `parent` (its workers), at most `cap`. */
static int children(pid_t parent, long *out, int cap) {
    DIR *d = opendir("/proc");
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL && n < cap) {
        long p = strtol(e->d_name, NULL, 10), ppid;
        char state;
        if (p > 0 && proc_stat(p, &ppid, &state) && ppid == (long)parent && state != 'Z')
            out[n++] = p;
    }
    closedir(d);
    return n;
}

/* Files whose name contains ".tmp" under dir (recursive), named on stderr if `say`. */
static int count_tmp_in(const char *dir, int say) {
    DIR *d = opendir(dir);
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        char p[2048];
        snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (strstr(e->d_name, ".tmp")) {
            if (say) fprintf(stderr, "left behind: %s\n", p);
            n++;
        }
        struct stat st;
        if (stat(p, &st) == 0 && S_ISDIR(st.st_mode)) n += count_tmp_in(p, say);
    }
    closedir(d);
    return n;
}

static int count_tmp(const char *dir) { return count_tmp_in(dir, 1); }

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

/* Four jobs, -j 2, about a second in all; "first" ends well before the others. */
static void write_four_jobs(const char *manifest) {
    char json[4096];
    snprintf(json, sizeof json,
             "{\"defaults\": {\"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             " \"jobs\": [\n"
             "  {\"name\": \"first\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 20},\n"
             "  {\"name\": \"grid\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 500,"
             " \"pins\": {\"top_axis\": \"z\"}, \"outputs\": [\"pc2\", \"mdd\"]},\n"
             "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 60,"
             " \"outputs\": [\"pc2\", \"mdd\"]},\n"
             "  {\"name\": \"patch\", \"mesh\": \"%s/tri_patch.obj\", \"frames\": 400,"
             " \"pins\": {\"top_axis\": \"y\"}}\n"
             " ]}\n",
             g_meshes, g_meshes, g_meshes);
    write_text(manifest, json);
}

static void test_parent_kill(void) {
    char manifest[1100], ref[1100], out[1100], log[1100];
    snprintf(manifest, sizeof manifest, "%s/four.json", g_out);
    snprintf(ref, sizeof ref, "%s/reference", g_out);
    snprintf(out, sizeof out, "%s/killed", g_out);
    snprintf(log, sizeof log, "%s/killed.log", g_out);
    write_four_jobs(manifest);
    const char *ref_args[] = {"batch", manifest, "-j", "2", "--out", ref, "--quiet", NULL};
    CHECK_EQ(run_cli(NULL, fmt("%s/%s", g_out, "reference.log"), ref_args, 60), 0);

    const char *args[] = {"batch", manifest, "-j", "2", "--out", out, "--quiet", NULL};
    pid_t pid = start(NULL, log, args);
    /* Once "first" is done, two long jobs run with their temporaries open. */
    int seen = 0;
    for (int k = 0; k < 1000 && !seen; ++k) {
        nap(0.01);
        seen = exists(fmt("%s/%s", out, "first/first.result.json"));
    }
    CHECK(seen);
    nap(0.2);
    long workers[8];
    int n = children(pid, workers, 8);
    CHECK(n > 0);
    CHECK(count_tmp_in(out, 0) > 0); /* in the middle of writing */
    kill(pid, SIGKILL);
    CHECK_EQ(wait_exit(pid, 10), 128 + SIGKILL);
    /* Resume at once. */
    char log2[1100];
    snprintf(log2, sizeof log2, "%s/resumed.log", g_out);
    pid_t again = start(NULL, log2, args);
    nap(0.3);
    for (int k = 0; k < n; ++k) {
        if (alive(workers[k]))
            fprintf(stderr, "worker %ld of the killed batch is alive\n", workers[k]);
        CHECK(!alive(workers[k]));
    }
    CHECK_EQ(wait_exit(again, 60), 0);
    CHECK(log_contains(log2, "skipped first"));
    for (int k = 0; k < n; ++k) CHECK(!alive(workers[k]));
    CHECK_EQ(count_tmp(out), 0);
    int compared = 0, mismatches = 0;
    static const char *const jobs[] = {"first", "grid", "scene", "patch"};
    for (int k = 0; k < 4; ++k) compare_trees(ref, out, jobs[k], &compared, &mismatches);
    /* first: obj, pc2, mdd, 20 frames, png, html; the others obj, pc2, mdd, png, html
     * (patch: and 400 frames). */
    CHECK_EQ(compared, 25 + 5 + 5 + 405);
    CHECK_EQ(mismatches, 0);
}

static void test_lock(void) {
    char manifest[1100], out[1100], log[1100], json[4096];
    snprintf(manifest, sizeof manifest, "%s/long.json", g_out);
    snprintf(out, sizeof out, "%s/locked", g_out);
    snprintf(log, sizeof log, "%s/first.log", g_out);
    snprintf(json, sizeof json,
             "{\"jobs\": [\n"
             "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000},\n"
             "  {\"name\": \"short\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 5}\n"
             " ]}\n",
             g_meshes, g_meshes);
    write_text(manifest, json);
    const char *args[] = {"batch", manifest, "-j", "1", "--out", out, "--quiet", NULL};
    pid_t pid = start(NULL, log, args);
    int seen = 0;
    for (int k = 0; k < 1000 && !seen; ++k) {
        nap(0.01);
        seen = exists(fmt("%s/%s", out, "long/long.pc2.tmp"));
    }
    CHECK(seen);
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
    CHECK(!contains(second, "rbcloth batch: 2 jobs", 0));
    /* So is an array task of the same folder, and `rbcloth run` into a job's folder. */
    const char *task[] = {"batch", manifest, "--only", "1", "--out", out, "--quiet", NULL};
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
    CHECK_EQ(wait_exit(pid, 30), 1);
    /* Free again once it ended: the short job runs. */
    CHECK_EQ(run_cli(NULL, second, task, 30), 0);
    CHECK(exists(fmt("%s/%s", out, "short/short.result.json")));

    /* Array tasks share a folder: a task ends while another one runs there. */
    char tasks[1100];
    snprintf(tasks, sizeof tasks, "%s/tasks", g_out);
    const char *task0[] = {"batch", manifest, "--only", "0", "--out", tasks, "--quiet", NULL};
    const char *task1[] = {"batch", manifest, "--only", "1", "--out", tasks, "--quiet", NULL};
    pid_t t = start(NULL, fmt("%s/%s", g_out, "task0.log"), task0);
    seen = 0;
    for (int k = 0; k < 1000 && !seen; ++k) {
        nap(0.01);
        seen = exists(fmt("%s/%s", tasks, "long/long.pc2.tmp"));
    }
    CHECK(seen);
    CHECK_EQ(run_cli(NULL, fmt("%s/%s", g_out, "task1.log"), task1, 30), 0);
    CHECK(exists(fmt("%s/%s", tasks, "short/short.result.json")));
    kill(t, SIGTERM);
    CHECK_EQ(wait_exit(t, 30), 1);
    CHECK_EQ(count_tmp(out) + count_tmp(tasks), 0);
}

static void test_abs_out(void) {
    char work[1100], manifest[1200], log[1100], abs_out[4096], json[4096];
    snprintf(work, sizeof work, "%s/workdir", g_out);
    snprintf(manifest, sizeof manifest, "%s/two.json", work);
    snprintf(log, sizeof log, "%s/abs.log", g_out);
    mkdir(work, 0755);
    snprintf(json, sizeof json,
             "{\"defaults\": {\"frames\": 6, \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             " \"jobs\": [\n"
             "  {\"name\": \"strip\", \"mesh\": \"%s/strip_8x4.obj\"},\n"
             "  {\"name\": \"scene\", \"scene\": \"default\", \"frames\": 2}\n"
             " ]}\n",
             g_meshes);
    write_text(manifest, json);
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
    char manifest[1100], out[1100], log[1100], json[4096];
    snprintf(manifest, sizeof manifest, "%s/slow.json", g_out);
    snprintf(out, sizeof out, "%s/timeout", g_out);
    snprintf(log, sizeof log, "%s/timeout.log", g_out);
    snprintf(json, sizeof json,
             "{\"jobs\": [\n"
             "  {\"name\": \"slow\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
             " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             "  {\"name\": \"fast\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 10},\n"
             "  {\"name\": \"own\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 1000000,"
             " \"timeout\": 0.5}\n"
             " ]}\n",
             g_meshes, g_meshes, g_meshes);
    write_text(manifest, json);
    const char *args[] = {"batch", manifest, "-j", "1", "--job-timeout", "1", "--out", out,
                          "--quiet", NULL};
    double t0 = now_seconds();
    CHECK_EQ(run_cli(NULL, log, args, 60), 1);
    const double wall = now_seconds() - t0;
    CHECK(wall < 1.5 + 6.0); /* 1 s, 0.5 s and the short job, with a margin */
    CHECK(log_contains(log, "slow: failed: timed out after 1 s"));
    CHECK(log_contains(log, "own: failed: timed out after 0.5 s"));
    CHECK(log_contains(log, "ok      fast"));
    CHECK(exists(fmt("%s/%s", out, "fast/fast.result.json")));
    CHECK(!exists(fmt("%s/%s", out, "slow/slow.result.json")));
    CHECK(log_contains(fmt("%s/%s", out, "slow/slow.status.json"), "timed out after 1 s"));
    CHECK(log_contains(fmt("%s/%s", out, "batch_report.json"), "timed out after 0.5 s"));
    CHECK_EQ(count_tmp(out), 0);
    /* The key is known (a typo gets it), and the option needs seconds. */
    write_text(fmt("%s/%s", g_out, "typo.json"), "{\"jobs\": [{\"name\": \"x\", \"scene\": "
                                                 "\"default\", \"timout\": 3}]}\n");
    const char *typo[] = {"batch", fmt("%s/%s", g_out, "typo.json"), "--out", out, NULL};
    CHECK_EQ(run_cli(NULL, log, typo, 30), 1);
    CHECK(log_contains(log, "jobs[0].timout: unknown key; did you mean \"timeout\"?"));
    const char *bad[] = {"batch", manifest, "--job-timeout", "-1", NULL};
    CHECK_EQ(run_cli(NULL, log, bad, 30), 2);
    CHECK(log_contains(log, "--job-timeout needs a number of seconds"));
}

static void test_sigterm(void) {
    char manifest[1100], out[1100], log[1100], json[4096];
    snprintf(manifest, sizeof manifest, "%s/stuck.json", g_out);
    snprintf(out, sizeof out, "%s/sigterm", g_out);
    snprintf(log, sizeof log, "%s/sigterm.log", g_out);
    /* "stuck": one frame of 1024 substeps x 4096 iterations on 10,000 vertices takes
     * minutes, so its worker never reaches its check of the signal, like a job
     * inside an importer. "long": many short frames; it stops at the next one. */
    snprintf(json, sizeof json,
             "{\"jobs\": [\n"
             "  {\"name\": \"stuck\", \"scene\": \"default\", \"frames\": 3, \"substeps\": 1024,"
             " \"iterations\": 4096, \"outputs\": [\"pc2\", \"mdd\"]},\n"
             "  {\"name\": \"long\", \"mesh\": \"%s/grid_20x20.obj\", \"frames\": 1000000,"
             " \"outputs\": [\"pc2\", \"mdd\", \"objseq\"]},\n"
             "  {\"name\": \"later\", \"mesh\": \"%s/strip_8x4.obj\", \"frames\": 5}\n"
             " ]}\n",
             g_meshes, g_meshes);
    write_text(manifest, json);
    const char *args[] = {"batch", manifest, "-j", "2", "--term-grace", "1", "--out", out,
                          "--quiet", NULL};
    pid_t pid = start(NULL, log, args);
    int seen = 0;
    for (int k = 0; k < 1000 && !seen; ++k) {
        nap(0.01);
        seen = exists(fmt("%s/%s", out, "stuck/stuck.pc2.tmp")) &&
               exists(fmt("%s/%s", out, "long/long.pc2.tmp"));
    }
    CHECK(seen);
    nap(0.3);
    long workers[8];
    int n = children(pid, workers, 8);
    CHECK_EQ(n, 2);
    double t0 = now_seconds();
    kill(pid, SIGTERM);
    CHECK_EQ(wait_exit(pid, 60), 1);
    const double took = now_seconds() - t0;
    if (took >= 1.0 + 3.0) fprintf(stderr, "the batch took %.2f s to stop\n", took);
    CHECK(took < 1.0 + 3.0); /* the grace period, then the reports */
    for (int k = 0; k < n; ++k) CHECK(!alive(workers[k]));
    CHECK(log_contains(log, "stuck: interrupted: stopped by a signal: killed, still running 1 s "
                            "after SIGTERM"));
    CHECK(log_contains(log, "long: interrupted: stopped by a signal"));
    CHECK(log_contains(log, "later: not run"));
    CHECK_EQ(count_tmp(out), 0);
    CHECK(!exists(fmt("%s/%s", out, "stuck/stuck.pc2")));
}

static void test_run_sigint(void) {
    char out[1100], log[1100];
    static const int sigs[2] = {SIGINT, SIGTERM};
    for (int k = 0; k < 2; ++k) {
        snprintf(out, sizeof out, "%s/run_%d", g_out, k);
        snprintf(log, sizeof log, "%s/run_%d.log", g_out, k);
        const char *args[] = {"run", "--frames", "1000000", "--threads", k ? "2" : "1", "--quiet",
                              "--out", out, NULL};
        pid_t pid = start(NULL, log, args);
        int seen = 0;
        for (int i = 0; i < 1000 && !seen; ++i) {
            nap(0.01);
            seen = exists(fmt("%s/%s", out, "hanging_cloth.pc2.tmp"));
        }
        CHECK(seen);
        nap(0.3);
        kill(pid, sigs[k]);
        CHECK_EQ(wait_exit(pid, 10), 1);
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
    pid_t pid = start(NULL, log, args);
    int seen = 0;
    for (int i = 0; i < 1000 && !seen; ++i) {
        nap(0.01);
        seen = exists(fmt("%s/%s", out, "hanging_cloth.pc2.tmp"));
    }
    CHECK(seen);
    nap(0.5); /* inside the first frame */
    kill(pid, SIGINT);
    nap(0.3);
    kill(pid, SIGINT);
    CHECK_EQ(wait_exit(pid, 5), 1);
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
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", g_out, g_out);
    if (system(cmd) != 0) return 2;
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
