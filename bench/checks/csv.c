/* csv.c -- see csv.h. */
#include "csv.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "text_file.h"

static char *copy_of(const char *s) {
    size_t n = strlen(s) + 1;
    char *c = malloc(n);
    if (c)
        memcpy(c, s, n);
    return c;
}

void csv_free(csv_file *csv) {
    free(csv->path);
    free(csv->header_text);
    free(csv->rows);
    free(csv->text);
    free(csv->fields);
    memset(csv, 0, sizeof *csv);
}

int csv_read(const char *path, csv_file *csv) {
    memset(csv, 0, sizeof *csv);
    csv->path = copy_of(path);
    errno = 0;
    csv->text = text_file_read(path);
    if (!csv->text || !csv->path) {
        fprintf(stderr, "cannot read %s: %s\n", path, errno ? strerror(errno) : "out of memory");
        csv_free(csv);
        return -1;
    }
    /* Sizes first: a row per line at most, a field per line and per comma. */
    size_t lines = 1, commas = 0;
    for (const char *p = csv->text; *p; ++p) {
        lines += *p == '\n';
        commas += *p == ',';
    }
    csv->rows = malloc(lines * sizeof *csv->rows);
    csv->fields = malloc((lines + commas) * sizeof *csv->fields);
    if (!csv->rows || !csv->fields) {
        fprintf(stderr, "cannot read %s: out of memory\n", path);
        csv_free(csv);
        return -1;
    }
    char **next_field = csv->fields;
    int line_number = 0, have_header = 0;
    for (char *line = csv->text, *end; line; line = end) {
        ++line_number;
        end = strchr(line, '\n');
        if (end)
            *end++ = '\0';
        if (!*line)
            continue;
        if (!have_header) {
            csv->header_text = copy_of(line);
            if (!csv->header_text) {
                fprintf(stderr, "cannot read %s: out of memory\n", path);
                csv_free(csv);
                return -1;
            }
        }
        csv_row *r = have_header ? &csv->rows[csv->row_count++] : &csv->header;
        have_header = 1;
        r->line = line_number;
        r->field = next_field;
        r->count = 0;
        r->field[r->count++] = line;
        for (char *p = line; *p; ++p)
            if (*p == ',') {
                *p = '\0';
                r->field[r->count++] = p + 1;
            }
        next_field += r->count;
    }
    return 0;
}

int csv_read_in(const char *dir, const char *name, csv_file *csv) {
    size_t n = strlen(dir) + strlen(name) + 2;
    char *path = malloc(n);
    if (!path) {
        memset(csv, 0, sizeof *csv);
        fprintf(stderr, "cannot read %s/%s: out of memory\n", dir, name);
        return -1;
    }
    snprintf(path, n, "%s/%s", dir, name);
    int rc = csv_read(path, csv);
    free(path);
    return rc;
}

int csv_header_is(const csv_file *csv, const char *expected) {
    const char *have = csv->header_text ? csv->header_text : "";
    if (csv->header_text && strcmp(have, expected) == 0)
        return 1;
    if (csv->header_text)
        fprintf(stderr, "%s:%d: header\n  %s\nexpected\n  %s\n", csv->path, csv->header.line, have,
                expected);
    else
        fprintf(stderr, "%s: no header line; expected\n  %s\n", csv->path, expected);
    return 0;
}

int csv_column(const csv_file *csv, const char *name) {
    for (int k = 0; k < csv->header.count; ++k)
        if (strcmp(csv->header.field[k], name) == 0)
            return k;
    return -1;
}
