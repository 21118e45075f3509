/* text_file.h -- small helpers for tests that check files a program wrote: read a
 * whole file into a NUL-terminated buffer, and split a line into fields in place. */
#ifndef RBC_TEST_TEXT_FILE_H
#define RBC_TEST_TEXT_FILE_H
#include <stdio.h>
#include <stdlib.h>

/* The whole file, NUL-terminated, malloc'd; NULL if it cannot be read. */
static inline char *text_file_read(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *text = size >= 0 ? malloc((size_t)size + 1) : NULL;
    if (text && fread(text, 1, (size_t)size, f) != (size_t)size) {
        free(text);
        text = NULL;
    }
    if (text)
        text[size] = '\0';
    fclose(f);
    return text;
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
#endif
