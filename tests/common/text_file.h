/* text_file.h -- small helpers for tests that check files a program wrote: read a
 * whole file (text or binary) into a NUL-terminated buffer, split a line into
 * fields in place, and write a test's input file into its folder. */
#ifndef RBC_TEST_TEXT_FILE_H
#define RBC_TEST_TEXT_FILE_H
#include <stdio.h>
#include <stdlib.h>

/* The whole file (binary safe), with a NUL after its *size bytes, malloc'd; NULL if
 * it cannot be read. */
static inline unsigned char *file_read_bytes(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    if (b)
        b[n] = 0;
    fclose(f);
    if (size)
        *size = n >= 0 ? (size_t)n : 0;
    return b;
}

/* The whole file, NUL-terminated, malloc'd; NULL if it cannot be read. */
static inline char *text_file_read(const char *path) {
    return (char *)file_read_bytes(path, NULL);
}

/* Split line at sep in place into at most max fields; returns the count. */
static inline int text_split(char *line, char sep, char **out, int max) {
    int n = 0;
    out[n++] = line;
    for (char *p = line; *p && n < max; ++p)
        if (*p == sep) {
            *p = '\0';
            out[n++] = p + 1;
        }
    return n;
}

/* Write text to dir/name and return that path, which stays valid for the next 31
 * calls (a test holds a few inputs at once). A test that cannot write its own input
 * has nothing to check: it exits 2. */
static inline const char *text_file_write_in(const char *dir, const char *name, const char *text) {
    static char paths[32][512];
    static int next;
    char *p = paths[next++ % 32];
    snprintf(p, 512, "%s/%s", dir, name);
    FILE *f = fopen(p, "wb");
    if (!f) {
        perror(p);
        exit(2);
    }
    fputs(text, f);
    fclose(f);
    return p;
}

/* A private folder $TMPDIR/STEM_XXXXXX (default /tmp) into dir (cap bytes), for the
 * inputs a test writes; the test exits 2 if it cannot make one. */
static inline void text_file_tempdir(char *dir, size_t cap, const char *stem) {
    const char *tmp = getenv("TMPDIR");
    snprintf(dir, cap, "%s/%s_XXXXXX", tmp ? tmp : "/tmp", stem);
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        exit(2);
    }
}

/* Remove that folder and what is in it. */
static inline void text_file_remove_tree(const char *dir) {
    char cmd[1100];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
}
#endif
