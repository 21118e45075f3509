/* obj_vertices.c -- a Wavefront OBJ file's "v" list in file order, and a check of
 * every face, line and point index before assimp sees the file.
 *
 * The "v" order is the order Blender, Maya and Houdini give an OBJ's vertices; assimp
 * keeps one vertex per face corner instead. assimp answers an index out of range
 * with "OBJ: vertex index out of range" and no more; here the message names the
 * line and the face, as a user needs to fix the file. The parse follows the OBJ
 * rules assimp applies: "\" at the end of a line continues it, '#' starts a comment,
 * indices are 1-based and a negative one counts back from the last vertex defined
 * so far; a positive one may refer forward (assimp resolves it once the file is
 * read), so it is checked against the file's total. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obj_vertices.h"

int rbc_path_has_ext(const char *path, const char *ext) {
    size_t n = strlen(path), e = strlen(ext);
    if (n < e) return 0;
    for (size_t i = 0; i < e; ++i)
        if (tolower((unsigned char)path[n - e + i]) != ext[i]) return 0;
    return 1;
}

/* One logical line (continuations joined) into *buf; 0 at the end of the file. */
static int read_line(FILE *f, char **buf, size_t *cap, size_t *lineno, size_t *first_line) {
    size_t n = 0;
    int any = 0;
    *first_line = *lineno + 1;
    for (;;) {
        int c = getc_unlocked(f); /* one thread reads the file */
        if (c == EOF) break;
        any = 1;
        if (n + 2 > *cap) {
            size_t nc = *cap ? 2 * *cap : 256;
            char *p = realloc(*buf, nc);
            if (!p) return -1;
            *buf = p;
            *cap = nc;
        }
        if (c == '\n') {
            ++*lineno;
            /* "\" then the newline (or "\r\n"): the line goes on. */
            size_t k = n;
            if (k && (*buf)[k - 1] == '\r') --k;
            if (k && (*buf)[k - 1] == '\\') {
                n = k - 1;
                (*buf)[n++] = ' ';
                continue;
            }
            break;
        }
        (*buf)[n++] = (char)c;
    }
    if (!any) return 0;
    if (!*buf) return -1;
    (*buf)[n] = '\0';
    char *hash = strchr(*buf, '#');
    if (hash) *hash = '\0';
    return 1;
}

typedef struct counts {
    size_t v, vt, vn;
} counts;

/* Check one "a/b/c" corner of line `text`; 0 ok, else the message in err. */
static int check_corner(const char *tok, size_t len, const counts *sofar, const counts *total,
                        const char *what, size_t element, size_t line, int corner, char *err,
                        size_t errcap) {
    static const char *kind[3] = {"vertex", "texture coordinate", "normal"};
    static const char *list[3] = {"v", "vt", "vn"};
    size_t have_sofar[3] = {sofar->v, sofar->vt, sofar->vn};
    size_t have_total[3] = {total->v, total->vt, total->vn};
    size_t at = 0;
    for (int part = 0; part < 3 && at < len; ++part) {
        size_t end = at;
        while (end < len && tok[end] != '/') ++end;
        if (end > at) {
            char num[32];
            size_t k = end - at < sizeof num - 1 ? end - at : sizeof num - 1;
            memcpy(num, tok + at, k);
            num[k] = '\0';
            char *stop = NULL;
            errno = 0;
            long long idx = strtoll(num, &stop, 10);
            int bad = stop == num || *stop != '\0' || errno != 0 || idx == 0;
            if (!bad && idx > 0 && (unsigned long long)idx > have_total[part]) bad = 2;
            if (!bad && idx < 0 && (unsigned long long)(-idx) > have_sofar[part]) bad = 3;
            if (bad) {
                if (bad == 1)
                    snprintf(err, errcap,
                             "line %zu, %s %zu (0-based), corner %d: \"%s\" is not a %s index",
                             line, what, element, corner, num, kind[part]);
                else if (bad == 2)
                    snprintf(err, errcap,
                             "line %zu, %s %zu (0-based), corner %d: %s index %lld is out of "
                             "range (the file has %zu \"%s\" lines)",
                             line, what, element, corner, kind[part], idx, have_total[part],
                             list[part]);
                else
                    snprintf(err, errcap,
                             "line %zu, %s %zu (0-based), corner %d: %s index %lld is out of "
                             "range (%zu \"%s\" lines come before it)",
                             line, what, element, corner, kind[part], idx, have_sofar[part],
                             list[part]);
                return -1;
            }
        }
        at = end + 1;
    }
    return 0;
}

/* Pass 1 counts the lists (forward references are allowed); pass 2 reads "v" and
 * checks every element's indices. */
int rbc_obj_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap) {
    memset(out, 0, sizeof *out);
    out->up_axis = -1;
    if (!rbc_path_has_ext(path, ".obj")) return 0;
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errcap, "cannot open the file: %s", strerror(errno));
        return -1;
    }
    char *buf = NULL;
    size_t cap = 0, lineno = 0, first = 0;
    counts total = {0, 0, 0}, sofar = {0, 0, 0};
    int r;
    while ((r = read_line(f, &buf, &cap, &lineno, &first)) > 0) {
        const char *p = buf;
        while (*p == ' ' || *p == '\t') ++p;
        if (p[0] == 'v' && (p[1] == ' ' || p[1] == '\t')) ++total.v;
        else if (p[0] == 'v' && p[1] == 't' && (p[2] == ' ' || p[2] == '\t')) ++total.vt;
        else if (p[0] == 'v' && p[1] == 'n' && (p[2] == ' ' || p[2] == '\t')) ++total.vn;
    }
    int rc = 1;
    if (r < 0) {
        snprintf(err, errcap, "out of memory reading the OBJ");
        rc = -1;
        goto done;
    }
    if (total.v > (1u << 28)) {
        snprintf(err, errcap, "too many vertices: %zu \"v\" lines", total.v);
        rc = -1;
        goto done;
    }
    out->xyz = malloc((3 * total.v + 1) * sizeof(double));
    out->list_start = malloc(2 * sizeof(uint32_t));
    out->list_name = calloc(1, sizeof(char *));
    if (!out->xyz || !out->list_start || !out->list_name) {
        snprintf(err, errcap, "out of memory reading the OBJ");
        rc = -1;
        goto done;
    }
    rewind(f);
    lineno = 0;
    size_t faces = 0, lines = 0, points = 0;
    while ((r = read_line(f, &buf, &cap, &lineno, &first)) > 0) {
        char *p = buf;
        while (*p == ' ' || *p == '\t') ++p;
        if (p[0] == 'v' && (p[1] == ' ' || p[1] == '\t')) {
            char *q = p + 1;
            double c[3] = {0, 0, 0};
            for (int k = 0; k < 3; ++k) {
                char *stop = NULL;
                c[k] = strtod(q, &stop);
                if (stop == q) {
                    /* assimp reads a missing coordinate as 0; so does the mesh */
                    c[k] = 0.0;
                    break;
                }
                q = stop;
            }
            memcpy(out->xyz + 3 * sofar.v, c, sizeof c);
            ++sofar.v;
        } else if (p[0] == 'v' && p[1] == 't' && (p[2] == ' ' || p[2] == '\t')) {
            ++sofar.vt;
        } else if (p[0] == 'v' && p[1] == 'n' && (p[2] == ' ' || p[2] == '\t')) {
            ++sofar.vn;
        } else if ((p[0] == 'f' || p[0] == 'l' || p[0] == 'p') && (p[1] == ' ' || p[1] == '\t')) {
            const char *what = p[0] == 'f' ? "face" : p[0] == 'l' ? "line element" : "point element";
            size_t element = p[0] == 'f' ? faces++ : p[0] == 'l' ? lines++ : points++;
            const char *t = p + 1;
            int corner = 0;
            for (;;) {
                while (*t == ' ' || *t == '\t' || *t == '\r') ++t;
                if (!*t) break;
                const char *s = t;
                while (*t && *t != ' ' && *t != '\t' && *t != '\r') ++t;
                if (check_corner(s, (size_t)(t - s), &sofar, &total, what, element, first,
                                 corner, err, errcap)) {
                    rc = -2;
                    goto done;
                }
                ++corner;
            }
        }
    }
    if (r < 0) {
        snprintf(err, errcap, "out of memory reading the OBJ");
        rc = -1;
        goto done;
    }
    out->count = (uint32_t)total.v;
    out->list_count = 1;
    out->list_start[0] = 0;
    out->list_start[1] = out->count;
    out->list_name[0] = calloc(1, 1);
    if (!out->list_name[0]) {
        snprintf(err, errcap, "out of memory reading the OBJ");
        rc = -1;
    }
done:
    free(buf);
    fclose(f);
    if (rc != 1) rbc_file_vertices_free(out);
    if (rc != 1) out->up_axis = -1;
    return rc;
}
