/* files.h -- helpers for tests that look at the files and folders a program (the
 * CLI) leaves: paths built in place, whether a path exists, a file written (from a
 * template) or searched for a phrase, the temporary files left under a folder, and
 * an empty folder to start in. POSIX: the
 * test defines _POSIX_C_SOURCE 200809L before any include. */
#ifndef RBC_TEST_FILES_H
#define RBC_TEST_FILES_H
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "check.h"
#include "text_file.h"

/* f (two %s) formatted with a and b, in one of 16 buffers used in turn, so that a
 * call can build several paths for the same expression. */
static inline char *fmt(const char *f, const char *a, const char *b) {
    static char buf[16][2048];
    static int next = 0;
    char *p = buf[next++ % 16];
    snprintf(p, sizeof buf[0], f, a, b);
    return p;
}

static inline int exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0;
}

/* Write text to path; a file that cannot be opened fails a CHECK. */
static inline void write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* Write text to path with each %s in it (at most four) replaced by arg, as a
 * manifest names the mesh folder for each of its jobs; the text is cut at 4095
 * bytes. */
static inline void write_text_sub(const char *path, const char *text, const char *arg) {
    char buf[4096];
    snprintf(buf, sizeof buf, text, arg, arg, arg, arg); /* unused ones are ignored */
    write_text(path, buf);
}

/* A case of `rbcloth batch` in folder dir: its manifest dir/MANIFEST, written from json
 * (each %s: the mesh folder `meshes`), its --out folder dir/OUT and its log dir/LOG. */
struct batch_case {
    char manifest[1100], out[1100], log[1100];
};

static inline struct batch_case batch_case_in(const char *dir, const char *meshes,
                                              const char *manifest, const char *out,
                                              const char *log, const char *json) {
    struct batch_case c;
    snprintf(c.manifest, sizeof c.manifest, "%s/%s", dir, manifest);
    snprintf(c.out, sizeof c.out, "%s/%s", dir, out);
    snprintf(c.log, sizeof c.log, "%s/%s", dir, log);
    write_text_sub(c.manifest, json, meshes);
    return c;
}

/* Whether the file at path holds needle; if not and `say`, the file is printed to
 * stderr, so that a failed check shows what the program said instead. */
static inline int file_contains(const char *path, const char *needle, int say) {
    char *text = text_file_read(path);
    int found = text && strstr(text, needle) != NULL;
    if (!found && say)
        fprintf(stderr, "%s does not contain '%s':\n%s\n", path, needle, text ? text : "");
    free(text);
    return found;
}

static inline int log_contains(const char *log, const char *needle) {
    return file_contains(log, needle, 1);
}

/* Files whose name contains ".tmp" under dir (recursive), named on stderr if `say`. */
static inline int count_tmp_in(const char *dir, int say) {
    DIR *d = opendir(dir);
    if (!d) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        char p[2048];
        const int len = snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
        if (strstr(e->d_name, ".tmp")) {
            if (say) fprintf(stderr, "left behind: %s\n", p);
            n++;
        }
        struct stat st; /* a cut path would name another file: not descended into */
        if (len < (int)sizeof p && stat(p, &st) == 0 && S_ISDIR(st.st_mode))
            n += count_tmp_in(p, say);
    }
    closedir(d);
    return n;
}

static inline int count_tmp(const char *dir) { return count_tmp_in(dir, 1); }

/* An empty folder at path, whatever an earlier run left there; 0 if made. (path
 * holds no single quote: it goes to the shell quoted.) */
static inline int fresh_dir(const char *path) {
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", path, path);
    return system(cmd) != 0 ? -1 : 0;
}
#endif
