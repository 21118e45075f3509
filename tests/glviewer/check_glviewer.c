/* check_glviewer.c -- checks what rbcloth-viewer drew and printed for drag_cut.script
 * on drag_cut.json (run_glviewer.sh runs both under Xvfb).
 *
 * usage: check_glviewer LOG STILL.png BEFORE.png DRAGGED.png PRECUT.png CUT.png
 *        check_glviewer keys LOG BEFORE.png BALL.png     (keys.script)
 *
 * The geometry the bounds come from. The viewer's window is 800 x 600, camera
 * --camera 0,0 (looking along -z), vertical field of view 30 deg. It fits the
 * cloth's rest box (x 0..1, y 0..1, z 0) extended by its size along gravity
 * (y -1..1): half diagonal r = sqrt(1 + 4) / 2 = 1.118 m, distance
 * d = 1.1 r / sin(15 deg) = 4.752 m, so 1 m at the cloth is
 * 600 / (2 d tan 15 deg) = 235.6 px and the box centre (0.5, 0, 0) is pixel
 * (399.5, 299.5). The cloth at rest covers x 281.7..517.3, y 63.9..299.5: 236 x 236
 * = 55.5K pixels. Hanging from its whole top row it barely stretches (the test
 * scene's springs sag less than 1 %), so the still cloth covers 0.8 to 1.2 times
 * that whatever the rasteriser's edge rules.
 *
 * Cloth pixels are told from the background by hue (tests/viewer/png_util.h): every
 * colour of the strain ramp has red above blue, the viewer's background
 * (0.16, 0.19, 0.25) has blue 23 levels above red, and the light is white.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "png_util.h"

enum { W = 800, H = 600 };
/* The bottom-right corner, vertex 23, at rest: pixel (517.3, 299.5); the script
 * presses at (518, 300) and drags it to (580, 200) (reachable: 0.63 m from the
 * nearest pin, 1.39 m from the far top corner, under the 1.41 m of the cloth). */
static const double PRESS_X = 518, PRESS_Y = 300, TARGET_X = 580, TARGET_Y = 200;
static const double REST_AREA = 235.6 * 235.6;

static int failures;
#define CHECK(cond, ...)                                      \
    do {                                                      \
        if (!(cond)) {                                        \
            ++failures;                                       \
            fprintf(stderr, "check_glviewer: FAIL: " __VA_ARGS__); \
            fputc('\n', stderr);                              \
        }                                                     \
    } while (0)

static int cloth_at(const test_image *im, int x, int y) {
    return test_is_cloth(im->rgb + 3 * ((size_t)y * im->w + x));
}

/* Cloth pixels in [x0, x1) x [y0, y1), and their centroid. */
static long count_cloth(const test_image *im, int x0, int y0, int x1, int y1, double *cx, double *cy) {
    long n = 0;
    double sx = 0, sy = 0;
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
            if (cloth_at(im, x, y)) ++n, sx += x, sy += y;
    if (cx) *cx = n ? sx / n : 0;
    if (cy) *cy = n ? sy / n : 0;
    return n;
}

/* The value of KEY= on a line, as a string (static buffer), or NULL. */
static const char *field(const char *line, const char *key) {
    static char value[256];
    size_t k = strlen(key);
    for (const char *p = line; (p = strstr(p, key)) != NULL; ++p) {
        if ((p == line || p[-1] == ' ') && p[k] == '=') {
            size_t n = strcspn(p + k + 1, " \n");
            if (n >= sizeof value) n = sizeof value - 1;
            memcpy(value, p + k + 1, n);
            value[n] = 0;
            return value;
        }
    }
    return NULL;
}

static long number(const char *line, const char *key) {
    const char *v = field(line, key);
    return v ? strtol(v, NULL, 10) : -1;
}

/* glviewer_keys: the state lines of keys.script (numbered there) after each key. */
static int check_keys(const char *log, const char *before_png, const char *ball_png) {
    FILE *f = fopen(log, "r");
    if (!f) {
        fprintf(stderr, "check_glviewer: cannot open %s\n", log);
        return 2;
    }
    enum { N = 8 };
    char line[4096], st[N][4096];
    int n = 0, picks = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "state ", 6) == 0 && n < N) memcpy(st[n++], line, sizeof line);
        if (strncmp(line, "pick ", 5) == 0) ++picks;
    }
    fclose(f);
    CHECK(n == N, "%s has %d state lines, want %d", log, n, N);
    if (n != N) return 1;
    const char *solver[N] = {"rbgs_sor", "rbgs_chebyshev", "rbgs", "rbgs", "rbgs", "rbgs", "rbgs", "rbgs"};
    const long linear[N] = {11, 11, 11, 12, 12, 12, 12, 12};
    for (int k = 0; k < N; ++k) {
        const char *v = field(st[k], "solver");
        CHECK(v && strcmp(v, solver[k]) == 0, "state %d: solver=%s, want %s", k + 1, v ? v : "?",
              solver[k]);
        CHECK(number(st[k], "linear") == linear[k], "state %d: linear=%ld, want %ld", k + 1,
              number(st[k], "linear"), linear[k]);
    }
    /* Space: frames 16 and 24 both see the steps of frames 0 to 14 (15), none since. */
    CHECK(number(st[4], "frame") == 15 && number(st[5], "frame") == 15,
          "paused: frame=%ld and %ld, want 15 and 15", number(st[4], "frame"), number(st[5], "frame"));
    /* B, then the cut in cut mode: a left press there cuts and never picks. */
    CHECK(number(st[6], "balls") == 1, "after B: balls=%ld, want 1", number(st[6], "balls"));
    CHECK(picks == 0, "%d pick lines: a left press in cut mode must not pick", picks);
    CHECK(number(st[6], "springs_cut") >= 24 && number(st[6], "cloth0.triangles") <= 1058 - 46,
          "cut mode: springs_cut=%ld triangles=%ld, want >= 24 and <= 1012",
          number(st[6], "springs_cut"), number(st[6], "cloth0.triangles"));
    /* R at frame 41: a fresh world that frames 41 and 42 stepped, no balls, nothing cut. */
    CHECK(number(st[7], "frame") == 2 && number(st[7], "balls") == 0 &&
          number(st[7], "springs_cut") == 0 && number(st[7], "cloth0.triangles") == 1058 &&
          number(st[7], "cloth0.revision") == 1,
          "after R: '%.*s', want frame=2 balls=0 springs_cut=0 triangles=1058 revision=1",
          (int)strcspn(st[7], "\n"), st[7]);
    /* The ball: sent through pixel (400, 180), so its centre stays on that pixel; at
     * 1.6 m from the eye its 0.134 m radius spans about 90 px there. Grey (the
     * colliders' colour) where the cloth was before. */
    test_image before, ball;
    char err[512];
    if (test_png_read(before_png, &before, err, sizeof err) || test_png_read(ball_png, &ball, err, sizeof err)) {
        fprintf(stderr, "check_glviewer: %s\n", err);
        return 1;
    }
    long grey_before = 0, grey_ball = 0;
    for (int y = 170; y < 191; ++y)
        for (int x = 390; x < 411; ++x) {
            grey_before += test_is_grey(before.rgb + 3 * ((size_t)y * before.w + x));
            grey_ball += test_is_grey(ball.rgb + 3 * ((size_t)y * ball.w + x));
        }
    CHECK(grey_before == 0 && grey_ball == 21 * 21,
          "ball: %ld grey pixels of 441 around (400, 180) before and %ld after, want 0 and 441",
          grey_before, grey_ball);
    test_image_free(&before);
    test_image_free(&ball);
    if (failures) return 1;
    printf("check_glviewer: keys: all checks passed\n");
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 5 && strcmp(argv[1], "keys") == 0) return check_keys(argv[2], argv[3], argv[4]);
    if (argc != 7) {
        fprintf(stderr, "usage: check_glviewer LOG STILL.png BEFORE.png DRAGGED.png PRECUT.png "
                        "CUT.png\n       check_glviewer keys LOG BEFORE.png BALL.png\n");
        return 2;
    }
    /* The viewer's stdout: its pick line and one state line per screenshot. */
    FILE *f = fopen(argv[1], "r");
    if (!f) {
        fprintf(stderr, "check_glviewer: cannot open %s\n", argv[1]);
        return 2;
    }
    char line[4096], shots[5][4096], pick[4096] = "";
    int nshots = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "screenshot ", 11) == 0 && nshots < 5) memcpy(shots[nshots++], line, sizeof line);
        if (strncmp(line, "pick ", 5) == 0 && !pick[0]) memcpy(pick, line, sizeof line);
    }
    fclose(f);
    CHECK(nshots == 5, "%s has %d screenshot lines, want 5", argv[1], nshots);
    CHECK(pick[0], "%s has no pick line", argv[1]);
    if (nshots != 5 || !pick[0]) return 1;
    /* shots[k]: the state of screenshot k (still, before, dragged, precut, cut). */

    /* The press lands within 1 px of vertex 23's rest pixel, and the viewer's first
     * pick radius is 3 px (0.013 m, under the 0.043 m spacing): exactly vertex 23. */
    CHECK(number(pick, "cloth") == 0 && number(pick, "vertex") == 23,
          "the press at (%g, %g) picked '%.*s', want cloth 0 vertex 23", PRESS_X, PRESS_Y,
          (int)strcspn(pick, "\n"), pick);
    const char *dragging = field(shots[2], "dragging");
    CHECK(dragging && strcmp(dragging, "0:23") == 0, "during the drag: dragging=%s, want 0:23",
          dragging ? dragging : "(missing)");
    const char *released = field(shots[3], "dragging");
    CHECK(released && strcmp(released, "none") == 0, "after the release: dragging=%s, want none",
          released ? released : "(missing)");
    /* 23 x 23 quads, 2 triangles each, until the cut. */
    long tris_before = number(shots[3], "cloth0.triangles"), tris_after = number(shots[4], "cloth0.triangles");
    long rev_before = number(shots[3], "cloth0.revision"), rev_after = number(shots[4], "cloth0.revision");
    CHECK(number(shots[1], "cloth0.triangles") == 1058 && tris_before == 1058,
          "before the cut: %ld and %ld triangles, want 1058", number(shots[1], "cloth0.triangles"),
          tris_before);
    CHECK(rev_before == 1, "before the cut: revision %ld, want 1 (nothing removed yet)", rev_before);
    /* The stroke runs down x = 400 across all 23 rows of quads, between vertex
     * columns 11 and 12: every quad of that column has both ends of a crossed
     * horizontal spring as corners and goes, 46 triangles at least. */
    CHECK(tris_after >= 0 && tris_after <= 1058 - 46, "after the cut: %ld triangles, want <= %d",
          tris_after, 1058 - 46);
    CHECK(rev_after > rev_before, "after the cut: revision %ld, not above %ld", rev_after, rev_before);
    /* Each of the 24 rows has one horizontal spring across the stroke. */
    CHECK(number(shots[4], "springs_cut") >= 24, "springs_cut=%ld, want >= 24",
          number(shots[4], "springs_cut"));

    test_image im[5];
    char err[512];
    for (int k = 0; k < 5; ++k) {
        if (test_png_read(argv[2 + k], &im[k], err, sizeof err)) {
            fprintf(stderr, "check_glviewer: %s\n", err);
            return 1;
        }
        if (im[k].w != W || im[k].h != H) {
            fprintf(stderr, "check_glviewer: %s is %ux%u, want %dx%d\n", argv[2 + k], im[k].w,
                    im[k].h, W, H);
            return 1;
        }
    }
    const test_image *still = &im[0], *before = &im[1], *dragged = &im[2], *precut = &im[3],
                     *cut = &im[4];

    /* (1) The cloth is drawn, at about its projected area. */
    for (int k = 1; k < 5; k += 2) {
        long n = count_cloth(&im[k], 0, 0, W, H, NULL, NULL);
        CHECK(n >= 0.8 * REST_AREA && n <= 1.2 * REST_AREA,
              "%s: %ld cloth pixels, want 0.8 to 1.2 times the projected %.0f", argv[2 + k], n,
              REST_AREA);
    }

    /* (2) It moved where it was dragged. The dragged vertex is pinned at the target
     * (the pin reaches it within a step), so the faces around it cover pixels there,
     * where before the drag there was background (62 px right of the cloth's edge). */
    int tx = (int)TARGET_X, ty = (int)TARGET_Y;
    long at_target_before = count_cloth(before, tx - 6, ty - 6, tx + 7, ty + 7, NULL, NULL);
    long at_target_after = count_cloth(dragged, tx - 6, ty - 6, tx + 7, ty + 7, NULL, NULL);
    CHECK(at_target_before == 0, "before the drag: %ld cloth pixels near the target (%d, %d), want 0",
          at_target_before, tx, ty);
    /* 13 x 13 box: the vertex's faces (quads 10 px a side at rest) fill at least a
     * corner of it even folded; 10 pixels is a sliver. */
    CHECK(at_target_after >= 10, "after the drag: %ld cloth pixels near the target (%d, %d), want >= 10",
          at_target_after, tx, ty);
    /* The right half of the image (x >= 400): its cloth's centroid moves toward the
     * target. The bound comes from what a cloth that did not follow the drag shows:
     * the same measure between the still frame 10 and frame 20 (both before the
     * drag; the cloth hangs settled, sagging under 1 %) must stay under 2 px, and the
     * drag must move it at least 6 px, three times that. On llvmpipe the drag moves
     * it 12 px: the corner goes 118 px, but a sheet held along its top edge and
     * pushed at a corner within its plane folds rather than shifts, and only the
     * part near the corner follows far. */
    double sx, sy, bx, by, ax, ay;
    count_cloth(still, 400, 0, W, H, &sx, &sy);
    count_cloth(before, 400, 0, W, H, &bx, &by);
    count_cloth(dragged, 400, 0, W, H, &ax, &ay);
    double ux = TARGET_X - PRESS_X, uy = TARGET_Y - PRESS_Y, len = sqrt(ux * ux + uy * uy);
    double toward = ((ax - bx) * ux + (ay - by) * uy) / len;
    double drift = sqrt((bx - sx) * (bx - sx) + (by - sy) * (by - sy));
    printf("check_glviewer: right-half centroid (%.1f, %.1f) -> (%.1f, %.1f): %.1f px toward the "
           "target; %.2f px between frames 10 and 20\n", bx, by, ax, ay, toward, drift);
    CHECK(drift < 2.0, "the right half's centroid moved %.2f px between two still frames, want < 2",
          drift);
    CHECK(toward >= 6.0, "the right half's centroid moved %.1f px toward the target, want >= 6",
          toward);

    /* (3) The cut shows: a vertical band at the stroke (x 398..402, inside the removed
     * quad column 394.8..405.2) across the cloth's middle rows (y 100..280) is cloth
     * before the cut and background after, while the cloth beside the gap (x 380 and
     * 420, two quads away) stays. */
    long band = 5 * 180;
    long band_pre = count_cloth(precut, 398, 100, 403, 280, NULL, NULL);
    long band_cut = count_cloth(cut, 398, 100, 403, 280, NULL, NULL);
    long left = count_cloth(cut, 380, 100, 381, 280, NULL, NULL);
    long right = count_cloth(cut, 420, 100, 421, 280, NULL, NULL);
    printf("check_glviewer: cut band %ld -> %ld cloth pixels of %ld; beside it %ld and %ld of 180\n",
           band_pre, band_cut, band, left, right);
    CHECK(band_pre >= 0.95 * band, "before the cut: %ld of %ld band pixels are cloth, want >= 95 %%",
          band_pre, band);
    CHECK(band_cut <= 0.05 * band, "after the cut: %ld of %ld band pixels are cloth, want <= 5 %%",
          band_cut, band);
    CHECK(left >= 0.9 * 180 && right >= 0.9 * 180,
          "after the cut: %ld and %ld of 180 pixels beside the gap are cloth, want >= 90 %%", left,
          right);

    for (int k = 0; k < 5; ++k) test_image_free(&im[k]);
    if (failures) return 1;
    printf("check_glviewer: all checks passed\n");
    return 0;
}
