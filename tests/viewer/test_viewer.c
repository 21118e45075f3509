/* test_viewer.c -- hosts/cli/viewer.c on synthetic clips: the still's pixels (area,
 * strain colours, a torn quad, collider conventions), the page's embedded data read
 * back (self-contained, frame counts, positions within the 16-bit quantum, strain,
 * tearing, thinning under budgets), the batch index, and bad input.
 *
 * usage: test_viewer OUT_DIR  (writes clip.html, clip_f15.png, shapes.html,
 * shapes.png, index.html there: tests/viewer/browser_check.sh loads them)
 */
#include <cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "check.h"
#include "png_util.h"
#include "rbcloth.h"
#include "text_file.h"
#include "viewer.h"

#define PI 3.14159265358979323846

/* The clip: a 30 x 20 vertex grid (5 cm spacing) hanging from its top row and
 * swinging about it by 0.5 sin(2 pi f / 40) rad, rigidly, so its strain is what the
 * rest mesh makes it: a 7 x 7 vertex block at the bottom left has rest positions
 * shrunk 2.5 times towards its corner (strain 1.5 inside: red), everything else is
 * unstretched. A sphere moves behind it; quad (14, 9) tears at frame 10. */
enum { NX = 30, NY = 20, NQ = (NX - 1) * (NY - 1), FRAMES = 40, TEST_FRAME = 15, TORN_FRAME = 10 };
enum { TORN_QI = 14, TORN_QJ = 9, TORN_QUAD = TORN_QJ * (NX - 1) + TORN_QI };
enum { W = 960, HGT = 720 };
static const double SPACING = 0.05, SHRINK = 2.5;

static int vid(int i, int j) { return j * NX + i; }
static int in_block(int i, int j) { return i <= 6 && j >= NY - 7; }

static void grid_quads(uint32_t *q) {
    for (int j = 0; j < NY - 1; ++j)
        for (int i = 0; i < NX - 1; ++i) {
            uint32_t *o = q + 4 * (j * (NX - 1) + i);
            o[0] = vid(i, j), o[1] = vid(i + 1, j), o[2] = vid(i + 1, j + 1), o[3] = vid(i, j + 1);
        }
}

static void frame_positions(int f, float *x) {
    double th = 0.5 * sin(2 * PI * f / FRAMES);
    for (int j = 0; j < NY; ++j)
        for (int i = 0; i < NX; ++i) {
            double y = -j * SPACING;
            float *p = x + 3 * vid(i, j);
            p[0] = (float)(i * SPACING), p[1] = (float)(y * cos(th)), p[2] = (float)(y * sin(th));
        }
}

/* The camera as viewer.h documents it, written again here from the text. */
typedef struct cam { double eye[3], r[3], u[3], f[3], focal; } cam;
static void cam_fit(cam *c, const double lo[3], const double hi[3]) {
    double az = 35 * PI / 180, el = 25 * PI / 180, fy = 30 * PI / 180;
    double fx = 2 * atan((double)W / HGT * tan(fy / 2)), fmin = fx < fy ? fx : fy, r2 = 0, t[3];
    for (int k = 0; k < 3; ++k) t[k] = (lo[k] + hi[k]) / 2, r2 += (hi[k] - lo[k]) * (hi[k] - lo[k]) / 4;
    double d = 1.1 * sqrt(r2) / sin(fmin / 2);
    double dir[3] = {cos(el) * sin(az), sin(el), cos(el) * cos(az)};
    for (int k = 0; k < 3; ++k) c->eye[k] = t[k] + d * dir[k], c->f[k] = -dir[k];
    double rl = hypot(c->f[0], c->f[2]);
    c->r[0] = -c->f[2] / rl, c->r[1] = 0, c->r[2] = c->f[0] / rl; /* f x y */
    c->u[0] = c->r[1] * c->f[2] - c->r[2] * c->f[1];            /* r x f */
    c->u[1] = c->r[2] * c->f[0] - c->r[0] * c->f[2];
    c->u[2] = c->r[0] * c->f[1] - c->r[1] * c->f[0];
    c->focal = HGT / 2.0 / tan(fy / 2);
}
static void cam_project(const cam *c, const double p[3], double out[2]) {
    double d[3] = {p[0] - c->eye[0], p[1] - c->eye[1], p[2] - c->eye[2]};
    double x = d[0] * c->r[0] + d[1] * c->r[1] + d[2] * c->r[2];
    double y = d[0] * c->u[0] + d[1] * c->u[1] + d[2] * c->u[2];
    double z = d[0] * c->f[0] + d[1] * c->f[1] + d[2] * c->f[2];
    out[0] = W / 2.0 + c->focal * x / z, out[1] = HGT / 2.0 - c->focal * y / z;
}
static void cam_fit_points(cam *c, const float *x, int n) {
    double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) lo[k] = fmin(lo[k], x[3 * i + k]), hi[k] = fmax(hi[k], x[3 * i + k]);
    cam_fit(c, lo, hi);
}
static void project_vertex(const cam *c, const float *x, int v, double out[2]) {
    double p[3] = {x[3 * v], x[3 * v + 1], x[3 * v + 2]};
    cam_project(c, p, out);
}

/* Mean colour of the 3 x 3 pixels around (px, py), which must be inside the image. */
static void mean3(const test_image *im, double px, double py, double rgb[3]) {
    int cx = (int)px, cy = (int)py;
    rgb[0] = rgb[1] = rgb[2] = 0;
    CHECK(cx >= 1 && cy >= 1 && cx + 1 < (int)im->w && cy + 1 < (int)im->h);
    if (!(cx >= 1 && cy >= 1 && cx + 1 < (int)im->w && cy + 1 < (int)im->h)) return;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
            for (int k = 0; k < 3; ++k) rgb[k] += im->rgb[3 * ((cy + dy) * (int)im->w + cx + dx) + k] / 9.0;
}

static int contains(const char *hay, const char *needle) { return hay && strstr(hay, needle) != NULL; }

/* ---- reading the page back: meta JSON and the deflated base64 blob ---- */

static char *between(const char *s, const char *open, const char *close, size_t *len) {
    const char *a = strstr(s, open);
    if (!a) return NULL;
    a += strlen(open);
    const char *b = strstr(a, close);
    if (!b) return NULL;
    *len = (size_t)(b - a);
    return (char *)a;
}

static unsigned char *b64_decode(const char *s, size_t len, size_t *out_len) {
    unsigned char *o = malloc(len / 4 * 3 + 3);
    uint32_t acc = 0;
    int bits = 0;
    size_t n = 0;
    for (size_t i = 0; i < len; ++i) {
        int c = (unsigned char)s[i], v;
        if (c >= 'A' && c <= 'Z') v = c - 'A';
        else if (c >= 'a' && c <= 'z') v = c - 'a' + 26;
        else if (c >= '0' && c <= '9') v = c - '0' + 52;
        else if (c == '+') v = 62;
        else if (c == '/') v = 63;
        else continue; /* '=' and line breaks */
        acc = acc << 6 | (uint32_t)v, bits += 6;
        if (bits >= 8) bits -= 8, o[n++] = (unsigned char)(acc >> bits);
    }
    *out_len = n;
    return o;
}

typedef struct page {
    char *html;
    cJSON *meta;
    unsigned char *raw;
    size_t raw_len;
} page;

static int page_read(const char *path, page *pg) {
    memset(pg, 0, sizeof *pg);
    size_t size, len;
    pg->html = (char *)file_read_bytes(path, &size);
    if (!pg->html) return 1;
    char *m = between(pg->html, "id=\"rbc-meta\">", "</script>", &len);
    if (!m) return 1;
    char save = m[len];
    m[len] = '\0';
    pg->meta = cJSON_Parse(m);
    m[len] = save;
    char *d = between(pg->html, "id=\"rbc-data\">", "</script>", &len);
    if (!pg->meta || !d) return 1;
    size_t zlen;
    unsigned char *z = b64_decode(d, len, &zlen);
    uLongf raw = (uLongf)cJSON_GetNumberValue(cJSON_GetObjectItem(pg->meta, "raw_bytes"));
    pg->raw = malloc(raw + 1);
    int bad = uncompress(pg->raw, &raw, z, (uLong)zlen) != Z_OK;
    pg->raw_len = raw;
    free(z);
    return bad;
}

static void page_free(page *pg) {
    free(pg->html), free(pg->raw);
    cJSON_Delete(pg->meta);
}

static double jnum(const cJSON *o, const char *k) { return cJSON_GetNumberValue(cJSON_GetObjectItem(o, k)); }
static size_t jsec(const cJSON *o, const char *k, int i) {
    return (size_t)cJSON_GetNumberValue(cJSON_GetArrayItem(cJSON_GetObjectItem(o, k), i));
}

/* Page frame j's positions of cloth c (the encoding of viewer.c's encode_positions). */
static void page_positions(const page *pg, const cJSON *c, uint32_t page_frames, uint32_t j, float *x) {
    uint32_t n = (uint32_t)jnum(c, "vertices");
    size_t m = (size_t)n * 3, off = jsec(c, "pos", 0);
    const unsigned char *modes = pg->raw + jsec(c, "pos_modes", 0);
    uint16_t *q = malloc(m * 3 * sizeof *q), *q1 = q + m, *q2 = q + 2 * m;
    const cJSON *box = cJSON_GetObjectItem(pg->meta, "box");
    for (uint32_t f = 0; f <= j && f < page_frames; ++f) {
        const unsigned char *lo = pg->raw + off + 2 * m * f, *hi = lo + m;
        for (size_t k = 0; k < m; ++k) {
            uint16_t zz = (uint16_t)(lo[k] | hi[k] << 8);
            uint16_t r = (uint16_t)((zz >> 1) ^ (zz & 1 ? 0xFFFF : 0));
            int mode = modes[3 * f + k / n];
            uint32_t pred = mode == 0 ? (k % n ? q[k - 1] : 0) : mode == 1 ? q1[k] : 2u * q1[k] - q2[k];
            q[k] = (uint16_t)(pred + r);
        }
        memcpy(q2, q1, m * sizeof *q), memcpy(q1, q, m * sizeof *q);
    }
    for (int a = 0; a < 3; ++a)
        for (uint32_t i = 0; i < n; ++i)
            x[3 * i + a] = (float)(cJSON_GetNumberValue(cJSON_GetArrayItem(box, a)) +
                                   q[(size_t)a * n + i] / 65535.0 *
                                   cJSON_GetNumberValue(cJSON_GetArrayItem(box, 3 + a)));
    free(q);
}

/* ------------------------------------------------------------------------- */

static cli_view *make_clip(char *err, size_t errlen, size_t memory_budget, size_t page_budget) {
    static float rest[NX * NY * 3], x[NX * NY * 3];
    static uint32_t quads[NQ * 4];
    grid_quads(quads);
    frame_positions(0, rest);
    double c[2] = {0, -(NY - 1) * SPACING};
    for (int j = 0; j < NY; ++j)
        for (int i = 0; i < NX; ++i)
            if (in_block(i, j)) {
                float *p = rest + 3 * vid(i, j);
                p[0] = (float)(c[0] + (p[0] - c[0]) / SHRINK), p[1] = (float)(c[1] + (p[1] - c[1]) / SHRINK);
            }
    cli_view *v = NULL;
    if (cli_view_create(&v, "swing <test> & tear", 1.0 / 60, FRAMES, err, errlen)) return NULL;
    if (memory_budget || page_budget) cli_view_set_budget(v, memory_budget, page_budget, err, errlen);
    cli_view_cloth_def cd = {"grid", NX * NY, rest, NQ, quads, 0, NULL};
    cli_view_collider_def sphere = {RBC_SHAPE_SPHERE, 0.3f, {0, 0, 0}, 0, NULL, 0, NULL};
    cli_view_collider_def ground = {RBC_SHAPE_PLANE, 0, {0, 0, 0}, 0, NULL, 0, NULL};
    if (cli_view_add_cloth(v, &cd, err, errlen) || cli_view_add_collider(v, &sphere, err, errlen) ||
        cli_view_add_collider(v, &ground, err, errlen))
        return cli_view_destroy(v), NULL;
    for (int f = 0; f < FRAMES; ++f) {
        frame_positions(f, x);
        float pos[3] = {0.7f, -0.5f, (float)(-0.8 + 0.01 * f)}, q[4] = {0, 0, 0, 2}; /* unit after scaling */
        if (f == TORN_FRAME) CHECK_EQ(cli_view_remove_quad(v, 0, TORN_QUAD), 0);
        /* The ground: y = 0 of a frame 1.2 m down, turned about its own normal. */
        float gpos[3] = {0, -1.2f, 0}, gq[4] = {0, 0.38268343f, 0, 0.92387953f};
        if (cli_view_frame_cloth(v, 0, x) || cli_view_frame_collider(v, 0, pos, q) ||
            cli_view_frame_collider(v, 1, gpos, gq)) {
            snprintf(err, errlen, "frame %d: %s", f, cli_view_last_error(v));
            return cli_view_destroy(v), NULL;
        }
    }
    return v;
}

static void test_still(cli_view *v, const char *dir) {
    char path[512], err[256] = "";
    snprintf(path, sizeof path, "%s/clip_f%d.png", dir, TEST_FRAME);
    CHECK_EQ(cli_view_write_png(v, path, TEST_FRAME, W, HGT, err, sizeof err), 0);
    test_image im;
    if (test_png_read(path, &im, err, sizeof err)) {
        fprintf(stderr, "%s\n", err);
        CHECK(0);
        return;
    }
    CHECK_EQ(im.w, W);
    CHECK_EQ(im.h, HGT);
    float x[NX * NY * 3];
    frame_positions(TEST_FRAME, x);
    cam c;
    cam_fit_points(&c, x, NX * NY); /* the torn quad's corners stay: their neighbours keep them */
    /* Expected cloth area: the grid at this frame is one plane, so its quads'
     * projections do not overlap and their areas add up (the torn one left out). */
    double area = 0, perimeter = 0;
    for (int q = 0; q < NQ; ++q) {
        if (q == TORN_QUAD) continue;
        int i = q % (NX - 1), j = q / (NX - 1);
        double p[4][2];
        project_vertex(&c, x, vid(i, j), p[0]), project_vertex(&c, x, vid(i + 1, j), p[1]);
        project_vertex(&c, x, vid(i + 1, j + 1), p[2]), project_vertex(&c, x, vid(i, j + 1), p[3]);
        double a = 0;
        for (int k = 0; k < 4; ++k) a += p[k][0] * p[(k + 1) % 4][1] - p[(k + 1) % 4][0] * p[k][1];
        area += fabs(a) / 2;
        /* Boundary edges (outer rim, and the torn quad's four): one visible quad. */
        int nb[4][2] = {{i, j - 1}, {i + 1, j}, {i, j + 1}, {i - 1, j}};
        for (int k = 0; k < 4; ++k) {
            int ni = nb[k][0], nj = nb[k][1];
            int outside = ni < 0 || nj < 0 || ni >= NX - 1 || nj >= NY - 1 || nj * (NX - 1) + ni == TORN_QUAD;
            if (outside) perimeter += hypot(p[(k + 1) % 4][0] - p[k][0], p[(k + 1) % 4][1] - p[k][1]);
        }
    }
    long cloth = 0;
    for (size_t k = 0; k < (size_t)W * HGT; ++k) cloth += test_is_cloth(im.rgb + 3 * k);
    /* A pixel's class can differ from "its centre is inside" only where the outline
     * crosses it: a band one pixel wide along the outline, half of it on each side,
     * so the count is within perimeter / 2 of the area plus the 2 x 2 sampling's
     * rounding; perimeter x 1 doubles that. (The area is about 1e5 px, the
     * perimeter 2e3 px.) */
    printf("still: cloth pixels %ld, projected area %.0f, perimeter %.0f\n", cloth, area, perimeter);
    CHECK(area > 0.05 * W * HGT); /* the framing rule: the grid fills a good part of the image */
    CHECK_NEAR(cloth, area, perimeter);
    /* Inside the shrunk block every edge has strain 1.5: red, r several times g and
     * b ((0.80, 0.08, 0.08) at any shade; blends within the block stay red). */
    double px[2], rgb[3];
    project_vertex(&c, x, vid(3, NY - 4), px);
    mean3(&im, px[0], px[1], rgb);
    printf("still: stretched block (%.0f, %.0f) rgb %.0f %.0f %.0f\n", px[0], px[1], rgb[0], rgb[1], rgb[2]);
    CHECK(rgb[0] > 3 * rgb[1] && rgb[0] > 3 * rgb[2]);
    /* Unstretched (strain ~1e-7): the neutral (0.94, 0.91, 0.83), g/r = 0.97 and
     * b/r = 0.88 at any shade; pale yellow (2 %) would have b/r = 0.56. */
    project_vertex(&c, x, vid(24, 5), px);
    mean3(&im, px[0], px[1], rgb);
    printf("still: unstretched part rgb %.0f %.0f %.0f\n", rgb[0], rgb[1], rgb[2]);
    CHECK(rgb[1] > 0.95 * rgb[0] && rgb[2] > 0.85 * rgb[0] && test_is_cloth((unsigned char[]){
        (unsigned char)rgb[0], (unsigned char)rgb[1], (unsigned char)rgb[2]}));
    /* The torn quad (about 15 x 18 px here) shows what is behind it: not cloth. */
    double hole[2] = {0, 0};
    int corners[4] = {vid(TORN_QI, TORN_QJ), vid(TORN_QI + 1, TORN_QJ), vid(TORN_QI + 1, TORN_QJ + 1),
                      vid(TORN_QI, TORN_QJ + 1)};
    for (int k = 0; k < 4; ++k) {
        project_vertex(&c, x, corners[k], px);
        hole[0] += px[0] / 4, hole[1] += px[1] / 4;
    }
    int hole_cloth = 0;
    for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
            hole_cloth += test_is_cloth(im.rgb + 3 * (((int)hole[1] + dy) * W + (int)hole[0] + dx));
    CHECK_EQ(hole_cloth, 0);
    /* The ground plane shows grey in front of and below the cloth. */
    double ground[3] = {0.7, -1.2, 0.0};
    cam_project(&c, ground, px);
    mean3(&im, px[0], px[1], rgb);
    printf("still: ground at (%.0f, %.0f) rgb %.0f %.0f %.0f\n", px[0], px[1], rgb[0], rgb[1], rgb[2]);
    CHECK(fabs(rgb[0] - rgb[1]) <= 3 && fabs(rgb[1] - rgb[2]) <= 3);
    test_image_free(&im);
    /* Before the tear the quad is there. */
    snprintf(path, sizeof path, "%s/clip_f%d.png", dir, TORN_FRAME - 1);
    CHECK_EQ(cli_view_write_png(v, path, TORN_FRAME - 1, W, HGT, err, sizeof err), 0);
    if (!test_png_read(path, &im, err, sizeof err)) {
        frame_positions(TORN_FRAME - 1, x);
        cam_fit_points(&c, x, NX * NY);
        hole[0] = hole[1] = 0;
        for (int k = 0; k < 4; ++k) {
            project_vertex(&c, x, corners[k], px);
            hole[0] += px[0] / 4, hole[1] += px[1] / 4;
        }
        CHECK(test_is_cloth(im.rgb + 3 * ((int)hole[1] * W + (int)hole[0])));
        test_image_free(&im);
    }
}

static size_t test_page(cli_view *v, const char *dir) {
    char path[512], err[256] = "";
    snprintf(path, sizeof path, "%s/clip.html", dir);
    CHECK_EQ(cli_view_write_html(v, path, err, sizeof err), 0);
    page pg;
    if (page_read(path, &pg)) {
        fprintf(stderr, "%s: cannot read back the page data\n", path);
        CHECK(0);
        page_free(&pg);
        return 0;
    }
    /* Self-contained: nothing fetched from a network or another file. */
    CHECK(!contains(pg.html, "http://") && !contains(pg.html, "https://"));
    CHECK(!contains(pg.html, "src=") && !contains(pg.html, "<link") && !contains(pg.html, "@import") &&
          !contains(pg.html, "url("));
    CHECK(contains(pg.html, "<title>swing &lt;test&gt; &amp; tear</title>"));
    CHECK(contains(pg.html, "DecompressionStream(\"deflate\")") && contains(pg.html, "id=\"status\""));
    const cJSON *m = pg.meta, *c0 = cJSON_GetArrayItem(cJSON_GetObjectItem(m, "cloths"), 0);
    CHECK_EQ(jnum(m, "frames"), FRAMES);
    CHECK_EQ(jnum(m, "page_frames"), FRAMES);
    CHECK_EQ(jnum(m, "stride"), 1);
    CHECK_EQ(pg.raw_len, (size_t)jnum(m, "raw_bytes"));
    CHECK_EQ(jnum(c0, "vertices"), NX * NY);
    CHECK_EQ(jnum(c0, "removed"), 1);
    CHECK_EQ(cJSON_GetArraySize(cJSON_GetObjectItem(m, "colliders")), 2);
    /* Positions back within half a quantum (box / 65535 / 2) of what went in, at
     * every frame: the predictor's modular arithmetic round-trips exactly. */
    const cJSON *box = cJSON_GetObjectItem(m, "box");
    float x[NX * NY * 3], y[NX * NY * 3];
    double worst = 0, quantum = 0;
    for (int a = 0; a < 3; ++a)
        quantum = fmax(quantum, cJSON_GetNumberValue(cJSON_GetArrayItem(box, 3 + a)) / 65535.0);
    for (uint32_t f = 0; f < FRAMES; ++f) {
        frame_positions((int)f, x);
        page_positions(&pg, c0, FRAMES, f, y);
        for (int k = 0; k < NX * NY * 3; ++k) worst = fmax(worst, fabs(x[k] - y[k]));
    }
    printf("page: %zu bytes raw, worst position error %.3g (quantum %.3g)\n", pg.raw_len, worst, quantum);
    CHECK(worst <= 0.5 * quantum + 1e-6); /* + float rounding of metre-sized values */
    /* Strain bytes (each frame's change from the one before, mod 256): 255
     * (saturated) inside the block, 0 on the unstretched part, at every frame. */
    const unsigned char *st = pg.raw + jsec(c0, "strain", 0);
    unsigned red = 0, plain = 0, red_ok = 1, plain_ok = 1;
    for (int f = 0; f < FRAMES; ++f) {
        red = (red + st[(size_t)f * NX * NY + vid(3, NY - 4)]) & 255;
        plain = (plain + st[(size_t)f * NX * NY + vid(24, 5)]) & 255;
        red_ok &= red == 255, plain_ok &= plain == 0;
    }
    CHECK(red_ok && plain_ok);
    const uint32_t *removed = (const uint32_t *)(pg.raw + jsec(c0, "quad_removed", 0));
    CHECK_EQ(removed[TORN_QUAD], TORN_FRAME);
    CHECK_EQ(removed[TORN_QUAD + 1], 0xFFFFFFFFu);
    size_t deflated = (size_t)jnum(m, "deflated_bytes");
    page_free(&pg);
    return deflated;
}

/* Over the memory budget every k-th frame is kept; over the page budget the page
 * thins further; both say so in the page's meta (the page prints it). */
static void test_thinning(const char *dir, size_t full_deflated) {
    char path[512], err[256] = "";
    /* One frame is 600 x 12 = 7200 bytes, 40 frames 288000: a 100000-byte budget
     * keeps every 3rd (ceil(288000 / 100000)). */
    cli_view *v = make_clip(err, sizeof err, 100000, 0);
    CHECK(v != NULL);
    if (!v) return;
    snprintf(path, sizeof path, "%s/thin.html", dir);
    CHECK_EQ(cli_view_write_html(v, path, err, sizeof err), 0);
    page pg;
    if (!page_read(path, &pg)) {
        CHECK_EQ(jnum(pg.meta, "memory_stride"), 3);
        CHECK_EQ(jnum(pg.meta, "stride"), 3);
        CHECK_EQ(jnum(pg.meta, "page_frames"), 14); /* frames 0, 3, ..., 39 */
        CHECK_EQ(jnum(pg.meta, "frames"), FRAMES);
    } else {
        CHECK(0);
    }
    page_free(&pg);
    /* A still of a dropped frame shows the kept one before it (viewer_browser_thin
     * compares it with the page). */
    snprintf(path, sizeof path, "%s/thin_f16.png", dir);
    CHECK_EQ(cli_view_write_png(v, path, 16, 480, 360, err, sizeof err), 0);
    cli_view_destroy(v);
    /* A page budget of 80 % of what the whole clip deflates to must thin it, to no
     * more than every 4th frame: the faces and the first frame are about half of
     * this clip's page and do not thin, each further frame costs about 2 %, so 80 %
     * keeps about half of them (a stride of 2 or 3 after rounding); 4 leaves room. */
    size_t budget = full_deflated * 8 / 10;
    v = make_clip(err, sizeof err, 0, budget);
    if (!v) {
        CHECK(0);
        return;
    }
    snprintf(path, sizeof path, "%s/thin_page.html", dir);
    int wrote = cli_view_write_html(v, path, err, sizeof err) == 0;
    if (!wrote) fprintf(stderr, "%s\n", err);
    CHECK(wrote);
    if (!page_read(path, &pg)) {
        printf("page budget %zu: page_stride %g, %g bytes deflated\n", budget,
               jnum(pg.meta, "page_stride"), jnum(pg.meta, "deflated_bytes"));
        CHECK(jnum(pg.meta, "page_stride") > 1 && jnum(pg.meta, "page_stride") <= 4);
        CHECK(jnum(pg.meta, "deflated_bytes") <= budget);
        CHECK_EQ(jnum(pg.meta, "memory_stride"), 1);
        CHECK_EQ(jnum(pg.meta, "stride"), jnum(pg.meta, "page_stride"));
    } else {
        CHECK(0);
    }
    page_free(&pg);
    cli_view_destroy(v);
}

/* Colliders follow abi/rbcloth.h: a capsule's axis is its frame's y, from -h to h;
 * turned onto the world x axis it must cover (+-0.5, 0, 0) and not (0, 0.4, 0),
 * where the sheet under everything (it frames the view) or the sky shows. A
 * box, a sphere and a triangle mesh are grey (the plane: in the clip's still). */
static void test_shapes(const char *dir) {
    char path[512], err[256] = "";
    float rest[4 * 3] = {-1.2f, -0.3f, -1.2f, 1.2f, -0.3f, -1.2f, 1.2f, -0.3f, 1.2f, -1.2f, -0.3f, 1.2f};
    uint32_t quad[4] = {0, 1, 2, 3};
    float tet[4 * 3] = {0, 0, 0, 0.3f, 0, 0, 0, 0.3f, 0, 0, 0, 0.3f};
    uint32_t tet_tris[4 * 3] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    cli_view *v = NULL;
    CHECK_EQ(cli_view_create(&v, "shapes", 0.02, 2, err, sizeof err), 0);
    if (!v) return;
    cli_view_cloth_def cd = {"sheet", 4, rest, 1, quad, 0, NULL};
    cli_view_collider_def defs[4] = {
        {RBC_SHAPE_CAPSULE, 0.12f, {0, 0.5f, 0}, 0, NULL, 0, NULL},
        {RBC_SHAPE_BOX, 0, {0.15f, 0.15f, 0.15f}, 0, NULL, 0, NULL},
        {RBC_SHAPE_SPHERE, 0.2f, {0, 0, 0}, 0, NULL, 0, NULL},
        {RBC_SHAPE_TRIANGLE_MESH, 0, {0, 0, 0}, 4, tet, 4, tet_tris}};
    float pos[4][3] = {{0, 0, 0}, {0.9f, 0, -0.3f}, {-0.9f, 0, 0.3f}, {-0.5f, 0.45f, -0.3f}};
    float rot[4][4] = {{0, 0, -0.70710678f, 0.70710678f}, {0, 0, 0, 1}, {0, 0, 0, 1}, {0, 0, 0, 1}};
    CHECK_EQ(cli_view_add_cloth(v, &cd, err, sizeof err), 0);
    for (int i = 0; i < 4; ++i) CHECK_EQ(cli_view_add_collider(v, &defs[i], err, sizeof err), 0);
    for (int f = 0; f < 2; ++f) {
        CHECK_EQ(cli_view_frame_cloth(v, 0, rest), 0);
        for (uint32_t i = 0; i < 4; ++i) CHECK_EQ(cli_view_frame_collider(v, i, pos[i], rot[i]), 0);
    }
    snprintf(path, sizeof path, "%s/shapes.png", dir);
    CHECK_EQ(cli_view_write_png(v, path, 1, W, HGT, err, sizeof err), 0);
    snprintf(path, sizeof path, "%s/shapes.html", dir);
    CHECK_EQ(cli_view_write_html(v, path, err, sizeof err), 0);
    cli_view_destroy(v);
    test_image im;
    snprintf(path, sizeof path, "%s/shapes.png", dir);
    if (test_png_read(path, &im, err, sizeof err)) {
        fprintf(stderr, "%s\n", err);
        CHECK(0);
        return;
    }
    cam c;
    cam_fit_points(&c, rest, 4);
    /* Grey: the three channels within 3 levels (shading scales them alike; 8-bit
     * rounding of the 2 x 2 mean can part them by 1), and not the background. */
    const double grey_at[][3] = {{0.5, 0, 0}, {-0.5, 0, 0}, {0.9, 0, -0.3}, {-0.9, 0, 0.3}, {-0.45, 0.5, -0.25}};
    for (size_t k = 0; k < sizeof grey_at / sizeof grey_at[0]; ++k) {
        double px[2], rgb[3];
        cam_project(&c, grey_at[k], px);
        mean3(&im, px[0], px[1], rgb);
        int grey = fabs(rgb[0] - rgb[1]) <= 3 && fabs(rgb[1] - rgb[2]) <= 3;
        if (!grey) printf("shapes: point %zu at (%.0f, %.0f) rgb %.0f %.0f %.0f is not grey\n", k, px[0], px[1], rgb[0], rgb[1], rgb[2]);
        CHECK(grey);
    }
    double above[3] = {0, 0.4, 0}, px[2], rgb[3];
    cam_project(&c, above, px);
    mean3(&im, px[0], px[1], rgb);
    CHECK(fabs(rgb[0] - rgb[2]) > 3); /* background (b > r) or cloth (r > b), not grey */
    test_image_free(&im);
}

static void test_index(const char *dir) {
    char path[512], err[256] = "";
    snprintf(path, sizeof path, "%s/index.html", dir);
    cli_view_index_entry e[2] = {{"swing", "clip.html", "clip_f15.png", "ok"},
                                 {"shapes \"quoted\" <b>", "shapes.html", "shapes.png", "failed: unstable"}};
    CHECK_EQ(cli_view_write_index(path, "batch <1>", e, 2, err, sizeof err), 0);
    size_t size;
    char *html = (char *)file_read_bytes(path, &size);
    CHECK(contains(html, "<a href=\"clip.html\"><img loading=\"lazy\" alt=\"swing\" src=\"clip_f15.png\">"));
    CHECK(contains(html, "shapes &quot;quoted&quot; &lt;b&gt;") && !contains(html, "<b>"));
    CHECK(contains(html, "<title>batch &lt;1&gt;</title>"));
    /* The whole style sheet and the heading (a fixed-size format buffer once cut the
     * page off inside its style sheet, and the browser drew nothing). */
    CHECK(contains(html, "text-decoration:none}</style></head><body>\n<h1>batch &lt;1&gt;</h1>"));
    CHECK(contains(html, "class=\"status ok\">ok<") && contains(html, "class=\"status bad\">failed: unstable<"));
    CHECK(!contains(html, "http"));
    free(html);
}

static void test_bad_input(const char *dir) {
    char err[256] = "", path[512];
    float xyz[12] = {0}, rest[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    uint32_t quad[4] = {0, 1, 2, 3}, bad_quad[4] = {0, 1, 2, 7};
    cli_view *v = NULL;
    CHECK(cli_view_create(NULL, "t", 0.01, 5, err, sizeof err) != 0 && contains(err, "out is NULL"));
    CHECK(cli_view_create(&v, "t", 0.0, 5, err, sizeof err) != 0 && contains(err, "frame_dt") && !v);
    CHECK(cli_view_create(&v, "t", 0.01, 0, err, sizeof err) != 0 && contains(err, "frame_count"));
    CHECK_EQ(cli_view_create(&v, "t", 0.01, 2, err, sizeof err), 0);
    if (!v) return;
    cli_view_cloth_def cd = {"sq", 4, rest, 1, bad_quad, 0, NULL};
    CHECK(cli_view_add_cloth(v, &cd, err, sizeof err) != 0 && contains(err, "cloth 0 (sq)") &&
          contains(err, "quad 0 has vertex 7"));
    CHECK(cli_view_add_cloth(v, NULL, err, sizeof err) != 0 && contains(err, "def is NULL"));
    cd.quads = quad;
    CHECK_EQ(cli_view_add_cloth(v, &cd, err, sizeof err), 0);
    cli_view_collider_def bad = {0, 1, {0, 0, 0}, 0, NULL, 0, NULL};
    CHECK(cli_view_add_collider(v, &bad, err, sizeof err) != 0 && contains(err, "shape 0"));
    bad.shape = RBC_SHAPE_SPHERE, bad.radius = -1;
    CHECK(cli_view_add_collider(v, &bad, err, sizeof err) != 0 && contains(err, "collider 0: radius"));
    bad.radius = 1;
    CHECK_EQ(cli_view_add_collider(v, &bad, err, sizeof err), 0);
    float p[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, q0[4] = {0, 0, 0, 0};
    CHECK(cli_view_frame_cloth(v, 1, xyz) != 0 && contains(cli_view_last_error(v), "cloth 1 out of range"));
    CHECK(cli_view_frame_cloth(v, 0, NULL) != 0 && contains(cli_view_last_error(v), "positions are NULL"));
    xyz[4] = NAN;
    CHECK(cli_view_frame_cloth(v, 0, xyz) != 0 && contains(cli_view_last_error(v), "vertex 1 is not finite"));
    xyz[4] = 0;
    CHECK_EQ(cli_view_frame_cloth(v, 0, xyz), 0);
    /* Frame order: cloth 0 again before collider 0 has frame 0. */
    CHECK(cli_view_frame_cloth(v, 0, xyz) != 0 && contains(cli_view_last_error(v), "cloth 0 already has frame 0"));
    CHECK(cli_view_frame_collider(v, 3, p, q) != 0 && contains(cli_view_last_error(v), "collider 3 out of range"));
    CHECK(cli_view_frame_collider(v, 0, p, q0) != 0 && contains(cli_view_last_error(v), "quaternion"));
    CHECK_EQ(cli_view_frame_collider(v, 0, p, q), 0);
    CHECK_EQ(cli_view_frame_total(v), 1);
    CHECK(cli_view_add_cloth(v, &cd, err, sizeof err) != 0 && contains(err, "after the first frame"));
    CHECK(cli_view_remove_quad(v, 0, 1) != 0 && contains(cli_view_last_error(v), "quad 1 out of range"));
    CHECK(cli_view_remove_quad(v, 2, 0) != 0 && contains(cli_view_last_error(v), "cloth 2 out of range"));
    uint32_t other[4] = {3, 2, 1, 0};
    CHECK(cli_view_set_remaining_quads(v, 0, other, 1, err, sizeof err) != 0 && contains(err, "remaining quad 0"));
    CHECK_EQ(cli_view_set_remaining_quads(v, 0, quad, 1, err, sizeof err), 0); /* nothing went */
    CHECK_EQ(cli_view_set_remaining_quads(v, 0, NULL, 0, err, sizeof err), 0); /* the quad went */
    CHECK(cli_view_remove_quad(v, 0, 0) != 0 && contains(cli_view_last_error(v), "already removed at frame 1"));
    CHECK_EQ(cli_view_frame_cloth(v, 0, xyz), 0);
    CHECK_EQ(cli_view_frame_collider(v, 0, p, q), 0);
    CHECK(cli_view_frame_cloth(v, 0, xyz) != 0 && contains(cli_view_last_error(v), "beyond frame_count 2"));
    CHECK(cli_view_set_budget(v, 1, 1, err, sizeof err) != 0 && contains(err, "already added"));
    /* Unwritable paths name the file and the reason. */
    const char *nodir = "/nonexistent-rbcloth-dir/x.png";
    CHECK(cli_view_write_png(v, nodir, 0, 64, 48, err, sizeof err) != 0 && contains(err, nodir) &&
          contains(err, "No such file"));
    CHECK(cli_view_write_png(v, "x.png", 5, 64, 48, err, sizeof err) != 0 && contains(err, "frame 5 of 2"));
    CHECK(cli_view_write_png(NULL, "x.png", 0, 64, 48, err, sizeof err) != 0 && contains(err, "view is NULL"));
    CHECK(cli_view_write_html(v, "/nonexistent-rbcloth-dir/x.html", err, sizeof err) != 0 &&
          contains(err, "/nonexistent-rbcloth-dir/x.html") && contains(err, "No such file"));
    CHECK(cli_view_write_html(v, NULL, err, sizeof err) != 0 && contains(err, "path is NULL"));
    /* Frame 1 has no quad left: the still shows the collider only, the page writes. */
    snprintf(path, sizeof path, "%s/all_torn.png", dir);
    CHECK_EQ(cli_view_write_png(v, path, 1, 64, 48, err, sizeof err), 0);
    cli_view_index_entry e = {NULL, "a.html", "a.png", "ok"};
    CHECK(cli_view_write_index("/tmp/i.html", "t", &e, 1, err, sizeof err) != 0 && contains(err, "entry 0 has no name"));
    cli_view_destroy(v);
    cli_view_destroy(NULL);
    /* No frame: nothing to draw or play. */
    CHECK_EQ(cli_view_create(&v, "t", 0.01, 2, err, sizeof err), 0);
    CHECK(cli_view_write_html(v, "/tmp/never.html", err, sizeof err) != 0 && contains(err, "no complete frame"));
    cli_view_destroy(v);
}

/* The strain map's stops as viewer.h documents them. */
static void test_colour_map(void) {
    float c[3], d[3];
    cli_view_strain_colour(0, c);
    CHECK(c[0] > 0.85f && c[1] > 0.85f && c[2] > 0.75f && c[0] > c[2]);
    cli_view_strain_colour(0.1f, c); /* yellow-orange */
    CHECK(c[0] > 0.95f && c[1] > 0.6f && c[1] < 0.8f && c[2] < 0.3f);
    cli_view_strain_colour(1.0f, c);
    cli_view_strain_colour(5.0f, d); /* saturated */
    CHECK(c[0] > 0.75f && c[1] < 0.1f && c[2] < 0.1f && c[0] == d[0] && c[1] == d[1]);
    cli_view_strain_colour(NAN, d);
    CHECK(d[0] == 0.94f); /* NaN shows as unstrained, not as garbage */
    for (float s = 0; s <= 1.2f; s += 0.01f) { /* every cloth colour keeps r > b */
        cli_view_strain_colour(s, c);
        CHECK(c[0] - c[2] >= 0.11f - 1e-6f);
    }
}

#include <time.h>
static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* The paper's cloth as a page: 100 x 100 vertices (1 m, 1/99 m apart) for 240 frames
 * of 2 ms, swinging down about its pinned edge with a travelling ripple, plus a
 * deterministic jitter of +-1e-5 m per coordinate and frame (noise of the order of
 * the 16-bit quantum, 1.5e-5 m here, that no predictor removes). The real
 * `rbcloth run` clip of this scene gives a 3.1 MB page. */
static void test_size(const char *dir) {
    enum { N = 100, F = 240 };
    static float rest[N * N * 3], x[N * N * 3];
    static uint32_t quads[(N - 1) * (N - 1) * 4];
    for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i) {
            float *p = rest + 3 * (j * N + i);
            p[0] = i / 99.0f, p[1] = 0, p[2] = j / 99.0f;
            if (i < N - 1 && j < N - 1) {
                uint32_t *q = quads + 4 * (j * (N - 1) + i);
                q[0] = j * N + i, q[1] = j * N + i + 1, q[2] = (j + 1) * N + i + 1, q[3] = (j + 1) * N + i;
            }
        }
    char err[256] = "", html[512], png[512];
    cli_view *v = NULL;
    CHECK_EQ(cli_view_create(&v, "hanging cloth, synthetic", 0.002, F, err, sizeof err), 0);
    cli_view_cloth_def cd = {"cloth", N * N, rest, (N - 1) * (N - 1), quads, 0, NULL};
    CHECK_EQ(cli_view_add_cloth(v, &cd, err, sizeof err), 0);
    uint32_t seed = 12345;
    for (int f = 0; f < F; ++f) {
        double t = f * 0.002, th = 1.2 * (1 - cos(6.0 * t)) / 2;
        for (int j = 0; j < N; ++j)
            for (int i = 0; i < N; ++i) {
                const float *r = rest + 3 * (j * N + i);
                double ripple = 0.03 * sin(9 * r[0] - 20 * t) * sin(5 * r[2]) * r[2];
                double z = r[2] * cos(th) - ripple * sin(th), y = -r[2] * sin(th) + ripple * cos(th);
                double pos[3] = {r[0], y, z};
                for (int k = 0; k < 3; ++k) {
                    seed = seed * 1664525u + 1013904223u;
                    x[3 * (j * N + i) + k] = (float)(pos[k] + 2e-5 * ((seed >> 8) / 16777216.0 - 0.5));
                }
            }
        CHECK_EQ(cli_view_frame_cloth(v, 0, x), 0);
    }
    snprintf(html, sizeof html, "%s/size.html", dir);
    snprintf(png, sizeof png, "%s/size.png", dir);
    double t0 = now_s();
    CHECK_EQ(cli_view_write_html(v, html, err, sizeof err), 0);
    double t1 = now_s();
    CHECK_EQ(cli_view_write_png(v, png, F - 1, 0, 0, err, sizeof err), 0);
    double t2 = now_s();
    struct stat st;
    CHECK_EQ(stat(html, &st), 0);
    printf("100 x 100 x 240 frames: page %.2f MB written in %.2f s, 960 x 720 still in %.3f s\n",
           st.st_size / 1e6, t1 - t0, t2 - t1);
    /* "A few MB at most": 16-bit positions would be 14.4 MB raw (17.2 MB with the
     * strain bytes and faces) and 23 MB as base64; prediction and deflate must bring
     * the page under 6 MB even with noise in the lowest bit. */
    CHECK(st.st_size < 6000000);
    cli_view_destroy(v);
}

int main(int argc, char **argv) {
    if (argc == 3 && !strcmp(argv[1], "--size")) {
        mkdir(argv[2], 0777);
        test_size(argv[2]);
        return check_report("test_viewer --size");
    }
    if (argc != 2) {
        fprintf(stderr, "usage: test_viewer [--size] OUT_DIR\n");
        return 2;
    }
    const char *dir = argv[1];
    mkdir(dir, 0777);
    char err[256] = "";
    test_colour_map();
    cli_view *v = make_clip(err, sizeof err, 0, 0);
    if (!v) fprintf(stderr, "make_clip: %s\n", err);
    CHECK(v != NULL);
    size_t deflated = 0;
    if (v) {
        CHECK_EQ(cli_view_frame_total(v), FRAMES);
        test_still(v, dir);
        deflated = test_page(v, dir);
        cli_view_destroy(v);
    }
    test_thinning(dir, deflated);
    test_shapes(dir);
    test_index(dir);
    test_bad_input(dir);
    return check_report("test_viewer");
}
