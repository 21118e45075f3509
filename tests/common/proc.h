/* proc.h -- helpers for tests that run a program (the CLI) as a child process: a
 * monotonic clock and a sleep, start it with its output in a log, wait for it with
 * or without a time limit or until it writes a file, and read /proc for its state
 * and its children (workers).
 * POSIX and Linux: the test defines _POSIX_C_SOURCE 200809L before any include. */
#ifndef RBC_TEST_PROC_H
#define RBC_TEST_PROC_H
#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* Seconds on a clock no change of the wall clock moves. */
static inline double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static inline void nap(double seconds) {
    struct timespec ts = {(time_t)seconds, (long)((seconds - (double)(time_t)seconds) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Start EXE ARGS... (args NULL-terminated, at most 38) in folder cwd (NULL: this
 * one), stdout and stderr to log (truncated); its pid. */
static inline pid_t proc_start(const char *exe, const char *cwd, const char *log,
                               const char *const *args) {
    char *argv[40];
    int n = 0;
    argv[n++] = (char *)exe;
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
        execv(exe, argv);
        _exit(127);
    }
    return pid;
}

/* A waitpid status as one number: the exit status, or 128 + signal when killed. */
static inline int proc_exit_code(int st) {
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/* Its exit code (proc_exit_code), waiting as long as it takes (the test's CTest
 * TIMEOUT is the bound); -1 if it is no child of this process. */
static inline int proc_wait(pid_t pid) {
    int st = 0;
    if (waitpid(pid, &st, 0) != pid) return -1;
    return proc_exit_code(st);
}

/* Its exit code (proc_exit_code), or -1 after `limit` seconds, when it is killed so
 * that no test leaves a process behind. */
static inline int proc_wait_for(pid_t pid, double limit) {
    const double t0 = now_seconds();
    for (;;) {
        int st = 0;
        pid_t r = waitpid(pid, &st, WNOHANG);
        if (r == pid) return proc_exit_code(st);
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

/* Whether path a, and b unless NULL, exist after at most `tries` naps of `step`
 * seconds: a running program marks how far it got by the files it writes. */
static inline int wait_for_files(const char *a, const char *b, int tries, double step) {
    struct stat st;
    int seen = 0;
    for (int k = 0; k < tries && !seen; ++k) {
        nap(step);
        seen = stat(a, &st) == 0 && (!b || stat(b, &st) == 0);
    }
    return seen;
}

/* /proc/PID/stat: its parent, its state ('Z' zombie) and, unless start is NULL, its
 * start time (field 22, clock ticks after boot); 0 when there is no such pid. */
static inline int proc_stat(long pid, long *ppid, char *state, unsigned long long *start) {
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
    if (start) {
        const char *q = rp + 2; /* field 3 */
        for (int field = 3; field < 22 && q; ++field) {
            q = strchr(q, ' ');
            if (q) ++q;
        }
        if (!q) return 0;
        *start = strtoull(q, NULL, 10);
    }
    return 1;
}

/* Whether pid runs (a zombie has exited). */
static inline int proc_alive(long pid) {
    long ppid;
    char state;
    return proc_stat(pid, &ppid, &state, NULL) && state != 'Z' && state != 'X';
}

/* The running children of `parent` (its workers), at most `cap`. (/proc/PID/task/TID/
 * children needs a kernel option not every machine has, so all of /proc is read.) */
static inline int proc_children(pid_t parent, long *out, int cap) {
    DIR *d = opendir("/proc");
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL && n < cap) {
        long p = strtol(e->d_name, NULL, 10), ppid;
        char state;
        if (p > 0 && proc_stat(p, &ppid, &state, NULL) && ppid == (long)parent && state != 'Z')
            out[n++] = p;
    }
    closedir(d);
    return n;
}

/* The oldest child of `parent` (the first forked, zombie or not): the smallest start
 * time among the pids whose parent it is; 0 if none. */
static inline long proc_first_child(pid_t parent) {
    DIR *d = opendir("/proc");
    if (!d) return 0;
    long best = 0;
    unsigned long long best_start = ~0ull;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        long p = strtol(e->d_name, NULL, 10), ppid;
        char state;
        unsigned long long start;
        if (p > 0 && proc_stat(p, &ppid, &state, &start) && ppid == (long)parent &&
            start < best_start)
            best = p, best_start = start;
    }
    closedir(d);
    return best;
}
#endif
