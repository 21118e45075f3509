/* check_self_crossings.c -- does a cloth that `rbcloth run` wrote pass through
 * itself? Independent of the library's contact detection.
 *
 * Usage: check_self_crossings OBJ PC2 [FIRST_FRAME [MAX_CROSSINGS]]
 *   OBJ  the rest mesh `rbcloth run` writes (NAME.obj: "v" lines, quad "f" lines)
 *   PC2  its point cache (NAME.pc2: the positions after every frame, frame k + 1 in
 *        sample k)
 * Checks the frames from FIRST_FRAME (1-based; default: the last frame only; 1 =
 * every frame) to the last. Exit status 0 when no checked frame has more than
 * MAX_CROSSINGS (default 0) crossings, 1 otherwise or on a bad file.
 *
 * A crossing: an edge of the cloth (a quad's side or its 0-2 diagonal, the split
 * the library's contact uses: core/cloth.c) passes through a triangle of the same
 * cloth (v0 v1 v2 or v0 v2 v3 of a quad) that has none of the edge's vertices,
 * exactly as tests/abi/test_layer_order.c tests two layers: p and q strictly on
 * opposite sides of abc's plane and the line pq strictly inside abc (Shewchuk's
 * orient3d signs, in double from the float positions). A cloth that starts flat
 * and moves continuously cannot fold through itself without such a crossing (an
 * edge entering the other side of a sheet passes through one of its triangles), so a
 * frame with none is a frame where the cloth has not passed through itself, or has
 * passed through and back out in between frames (sampled, not continuous).
 *
 * Candidate pairs come from a uniform grid of cells twice the longest edge of the
 * frame (capped at 1/64 of the cloth's extent): each triangle goes into the cells
 * its bounding box overlaps, each edge is tested against the triangles of the cells
 * its box overlaps, once each.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double orient3d(const double *a, const double *b, const double *c, const double *d) {
    double u[3], v[3], w[3];
    for (int k = 0; k < 3; ++k) u[k] = b[k] - a[k], v[k] = c[k] - a[k], w[k] = d[k] - a[k];
    return u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) +
           u[2] * (v[0] * w[1] - v[1] * w[0]);
}

static int seg_tri(const double *p, const double *q, const double *a, const double *b,
                   const double *c) {
    double sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
    if (!((sp > 0 && sq < 0) || (sp < 0 && sq > 0)))
        return 0;
    double s1 = orient3d(p, q, a, b), s2 = orient3d(p, q, b, c), s3 = orient3d(p, q, c, a);
    return (s1 > 0 && s2 > 0 && s3 > 0) || (s1 < 0 && s2 < 0 && s3 < 0);
}

static int32_t le_i32(const unsigned char *p) {
    return (int32_t)((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                     (uint32_t)p[3] << 24);
}
static float le_f32(const unsigned char *p) {
    uint32_t u = (uint32_t)le_i32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

typedef struct {
    uint64_t cell;
    uint32_t tri;
} cell_entry;

static int by_cell(const void *a, const void *b) {
    const cell_entry *x = a, *y = b;
    return x->cell < y->cell ? -1 : x->cell > y->cell ? 1 : (x->tri > y->tri) - (x->tri < y->tri);
}

static int by_edge(const void *a, const void *b) {
    const uint32_t *x = a, *y = b;
    return x[0] != y[0] ? (x[0] > y[0]) - (x[0] < y[0]) : (x[1] > y[1]) - (x[1] < y[1]);
}

static void *xmalloc(size_t n) {
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "check_self_crossings: out of memory\n");
        exit(1);
    }
    return p;
}

int main(int argc, char **argv) {
    if (argc < 3 || argc > 5) {
        fprintf(stderr, "usage: check_self_crossings OBJ PC2 [FIRST_FRAME [MAX_CROSSINGS]]\n");
        return 1;
    }
    /* The OBJ's quads (the vertex count comes from the PC2). */
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", argv[1]);
        return 1;
    }
    size_t nq = 0, qcap = 1024, nv_obj = 0;
    uint32_t *quads = xmalloc(sizeof(uint32_t) * 4 * qcap);
    char line[512];
    while (fgets(line, sizeof line, f)) {
        if (line[0] == 'v' && line[1] == ' ')
            ++nv_obj;
        if (line[0] != 'f' || line[1] != ' ')
            continue;
        long v[4];
        if (sscanf(line + 2, "%ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3]) != 4) {
            fprintf(stderr, "%s: not a quad: %s", argv[1], line);
            return 1;
        }
        if (nq == qcap)
            quads = realloc(quads, sizeof(uint32_t) * 4 * (qcap *= 2));
        if (!quads)
            return 1;
        for (int k = 0; k < 4; ++k) {
            if (v[k] < 1 || (size_t)v[k] > nv_obj) {
                fprintf(stderr, "%s: bad index %ld\n", argv[1], v[k]);
                return 1;
            }
            quads[4 * nq + k] = (uint32_t)(v[k] - 1);
        }
        ++nq;
    }
    fclose(f);

    f = fopen(argv[2], "rb");
    unsigned char head[32];
    if (!f || fread(head, 1, 32, f) != 32 || memcmp(head, "POINTCACHE2\0", 12) != 0) {
        fprintf(stderr, "%s: not a PC2 file\n", argv[2]);
        return 1;
    }
    const long points = le_i32(head + 16), samples = le_i32(head + 28);
    if (points <= 0 || (size_t)points != nv_obj || samples <= 0) {
        fprintf(stderr, "%s: %ld points, %ld samples; the OBJ has %zu vertices\n", argv[2], points,
                samples, nv_obj);
        return 1;
    }
    long first = argc > 3 ? atol(argv[3]) : samples;
    const long max_crossings = argc > 4 ? atol(argv[4]) : 0;
    if (first < 1 || first > samples) {
        fprintf(stderr, "FIRST_FRAME %ld is not in 1..%ld\n", first, samples);
        return 1;
    }

    /* Triangles and unique edges. */
    const size_t nt = 2 * nq;
    uint32_t *tri = xmalloc(sizeof(uint32_t) * 3 * nt);
    uint32_t *edge = xmalloc(sizeof(uint32_t) * 2 * 3 * nt);
    for (size_t q = 0; q < nq; ++q) {
        const uint32_t *v = &quads[4 * q];
        uint32_t *t = &tri[6 * q];
        t[0] = v[0], t[1] = v[1], t[2] = v[2], t[3] = v[0], t[4] = v[2], t[5] = v[3];
    }
    for (size_t t = 0; t < nt; ++t)
        for (int e = 0; e < 3; ++e) {
            uint32_t a = tri[3 * t + e], b = tri[3 * t + (e + 1) % 3];
            edge[2 * (3 * t + e)] = a < b ? a : b;
            edge[2 * (3 * t + e) + 1] = a < b ? b : a;
        }
    qsort(edge, 3 * nt, 2 * sizeof(uint32_t), by_edge);
    size_t ne = 0;
    for (size_t k = 0; k < 3 * nt; ++k)
        if (!ne || edge[2 * k] != edge[2 * (ne - 1)] || edge[2 * k + 1] != edge[2 * (ne - 1) + 1]) {
            edge[2 * ne] = edge[2 * k], edge[2 * ne + 1] = edge[2 * k + 1];
            ++ne;
        }

    double *x = xmalloc(sizeof(double) * 3 * (size_t)points);
    unsigned char *raw = xmalloc(12 * (size_t)points);
    uint32_t *stamp = xmalloc(sizeof(uint32_t) * nt);
    memset(stamp, 0, sizeof(uint32_t) * nt);
    uint32_t stamp_now = 0;
    cell_entry *cells = NULL;
    size_t cells_cap = 0;
    long worst = 0, worst_frame = 0, total = 0, frames_checked = 0;
    int bad = 0;
    for (long s = first - 1; s < samples; ++s) {
        if (fseek(f, 32 + s * 12 * points, SEEK_SET) != 0 ||
            fread(raw, 12, (size_t)points, f) != (size_t)points) {
            fprintf(stderr, "%s: short file at sample %ld\n", argv[2], s);
            return 1;
        }
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (long i = 0; i < points; ++i)
            for (int k = 0; k < 3; ++k) {
                double c = le_f32(raw + 12 * i + 4 * k);
                if (!isfinite(c)) {
                    fprintf(stderr, "frame %ld: vertex %ld is not finite\n", s + 1, i);
                    return 1;
                }
                x[3 * i + k] = c;
                lo[k] = c < lo[k] ? c : lo[k];
                hi[k] = c > hi[k] ? c : hi[k];
            }
        double longest = 0, extent = 0;
        for (size_t e = 0; e < ne; ++e) {
            const double *p = &x[3 * edge[2 * e]], *q = &x[3 * edge[2 * e + 1]];
            double d = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) +
                            (p[2] - q[2]) * (p[2] - q[2]));
            longest = d > longest ? d : longest;
        }
        for (int k = 0; k < 3; ++k)
            extent = hi[k] - lo[k] > extent ? hi[k] - lo[k] : extent;
        double h = 2 * longest;
        if (h < extent / 64)
            h = extent / 64;
        if (!(h > 0))
            h = 1;
        long dim[3];
        for (int k = 0; k < 3; ++k)
            dim[k] = (long)((hi[k] - lo[k]) / h) + 1;
#define CELL(c, k) ((long)((c - lo[k]) / h) < dim[k] ? (long)((c - lo[k]) / h) : dim[k] - 1)
        size_t nc = 0;
        for (int pass = 0; pass < 2; ++pass) {
            nc = 0;
            for (size_t t = 0; t < nt; ++t) {
                long c0[3], c1[3];
                for (int k = 0; k < 3; ++k) {
                    double a = x[3 * tri[3 * t] + k], b = x[3 * tri[3 * t + 1] + k],
                           c = x[3 * tri[3 * t + 2] + k];
                    double mn = fmin(a, fmin(b, c)), mx = fmax(a, fmax(b, c));
                    c0[k] = CELL(mn, k), c1[k] = CELL(mx, k);
                }
                for (long i = c0[0]; i <= c1[0]; ++i)
                    for (long j = c0[1]; j <= c1[1]; ++j)
                        for (long k = c0[2]; k <= c1[2]; ++k) {
                            if (pass) {
                                cells[nc].cell = ((uint64_t)i * dim[1] + j) * dim[2] + k;
                                cells[nc].tri = (uint32_t)t;
                            }
                            ++nc;
                        }
            }
            if (!pass && nc > cells_cap) {
                free(cells);
                cells = xmalloc(sizeof *cells * (cells_cap = nc));
            }
        }
        qsort(cells, nc, sizeof *cells, by_cell);
        long crossings = 0;
        for (size_t e = 0; e < ne; ++e) {
            const uint32_t u = edge[2 * e], w = edge[2 * e + 1];
            const double *p = &x[3 * u], *q = &x[3 * w];
            long c0[3], c1[3];
            for (int k = 0; k < 3; ++k)
                c0[k] = CELL(fmin(p[k], q[k]), k), c1[k] = CELL(fmax(p[k], q[k]), k);
            if (++stamp_now == 0) {
                memset(stamp, 0, sizeof(uint32_t) * nt);
                stamp_now = 1;
            }
            for (long i = c0[0]; i <= c1[0]; ++i)
                for (long j = c0[1]; j <= c1[1]; ++j)
                    for (long k = c0[2]; k <= c1[2]; ++k) {
                        uint64_t key = ((uint64_t)i * dim[1] + j) * dim[2] + k;
                        size_t a = 0, b = nc;
                        while (a < b) { /* first entry with cell >= key */
                            size_t m = a + (b - a) / 2;
                            if (cells[m].cell < key)
                                a = m + 1;
                            else
                                b = m;
                        }
                        for (; a < nc && cells[a].cell == key; ++a) {
                            const uint32_t t = cells[a].tri;
                            if (stamp[t] == stamp_now)
                                continue;
                            stamp[t] = stamp_now;
                            const uint32_t *v = &tri[3 * t];
                            if (v[0] == u || v[1] == u || v[2] == u || v[0] == w || v[1] == w ||
                                v[2] == w)
                                continue;
                            if (seg_tri(p, q, &x[3 * v[0]], &x[3 * v[1]], &x[3 * v[2]])) {
                                if (total + crossings < 5)
                                    printf("frame %ld: edge %u-%u crosses triangle %u %u %u\n",
                                           s + 1, u, w, v[0], v[1], v[2]);
                                ++crossings;
                            }
                        }
                    }
        }
#undef CELL
        ++frames_checked;
        total += crossings;
        if (crossings > worst)
            worst = crossings, worst_frame = s + 1;
        if (crossings > max_crossings)
            bad = 1;
    }
    fclose(f);
    printf("%zu vertices, %zu edges, %zu triangles; frames %ld-%ld checked: %ld crossings in all, "
           "at most %ld in a frame",
           (size_t)points, ne, nt, first, samples, total, worst);
    if (worst)
        printf(" (frame %ld)", worst_frame);
    printf("; allowed %ld a frame\n", max_crossings);
    free(x), free(raw), free(stamp), free(cells), free(tri), free(edge), free(quads);
    return bad;
}
