/* viewer_pngtool.c -- pixel checks for browser_check.sh (no image tools needed):
 *   viewer_pngtool cloth SHOT MIN_FRACTION
 *       the share of cloth-coloured pixels (png_util.h) is at least MIN_FRACTION
 *   viewer_pngtool compare STILL SHOT MIN_IOU [MIN_GREY_IOU]
 *       the cloth masks of two images of the same size overlap: |A and B| / |A or B|
 *       at least MIN_IOU, and their colours agree there (mean channel difference at
 *       most 4 levels, at most 2 % of the pixels off by more than 16); with
 *       MIN_GREY_IOU, so do their grey (collider) masks (when the still has
 *       colliders: 0.2 % of its pixels grey or more)
 *   viewer_pngtool size PNG
 *       prints "W H"
 *   viewer_pngtool differ A B MIN_FRACTION
 *       at least MIN_FRACTION of the pixels differ by more than 8 levels in a channel
 * Prints what it measured; exit 0 if the check holds, 1 if not, 2 on bad input.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "png_util.h"

/* Measured 0.03 to 0.42 on the test clips and the paper's hanging cloth; a strain
 * colour lost on 5 % of the cloth (about 100 levels there) averages 5. */
enum { MAX_MEAN_COLOUR_DIFF = 4 };
/* Pixels whose colour is off by more than 16 levels in a channel: outline pixels
 * blended differently, a fraction of a per cent; a region of wrong colour shows. */
static const double MAX_OFF_COLOUR = 0.02;

static int load(const char *path, test_image *im) {
    char err[512];
    if (test_png_read(path, im, err, sizeof err)) {
        fprintf(stderr, "viewer_pngtool: %s\n", err);
        return 1;
    }
    return 0;
}

static int same_size(const test_image *a, const test_image *b, const char *pa, const char *pb) {
    if (a->w == b->w && a->h == b->h) return 1;
    fprintf(stderr, "viewer_pngtool: %s is %u x %u but %s is %u x %u\n", pa, a->w, a->h, pb, b->w, b->h);
    return 0;
}

int main(int argc, char **argv) {
    int args_ok = argc >= 3 && (!strcmp(argv[1], "size") ? argc == 3 : !strcmp(argv[1], "cloth") ? argc == 4
                                : !strcmp(argv[1], "compare") ? argc == 5 || argc == 6 : argc == 5);
    if (!args_ok) {
        fprintf(stderr, "usage: viewer_pngtool cloth SHOT MIN_FRACTION | compare STILL SHOT MIN_IOU "
                        "[MIN_GREY_IOU] | differ A B MIN_FRACTION | size PNG\n");
        return 2;
    }
    test_image a = {0}, b = {0};
    int rc = 2;
    if (!strcmp(argv[1], "size")) {
        if (load(argv[2], &a)) return 2;
        printf("%u %u\n", a.w, a.h);
        rc = 0;
    } else if (!strcmp(argv[1], "cloth")) {
        if (load(argv[2], &a)) return 2;
        size_t n = (size_t)a.w * a.h, cloth = 0;
        for (size_t i = 0; i < n; ++i) cloth += test_is_cloth(a.rgb + 3 * i);
        double frac = (double)cloth / (double)n, min = atof(argv[3]);
        printf("%s: %u x %u, cloth pixels %zu (%.4f of the image, at least %.4f wanted)\n", argv[2], a.w,
               a.h, cloth, frac, min);
        rc = frac >= min ? 0 : 1;
    } else if (!strcmp(argv[1], "compare") || !strcmp(argv[1], "differ")) {
        if (load(argv[2], &a) || load(argv[3], &b) || !same_size(&a, &b, argv[2], argv[3])) {
            test_image_free(&a), test_image_free(&b);
            return 2;
        }
        size_t n = (size_t)a.w * a.h, both = 0, either = 0, ca = 0, cb = 0, differ = 0;
        size_t gboth = 0, geither = 0, ga = 0, gb = 0;
        double colour_diff = 0; /* summed over the pixels cloth in both, all channels */
        size_t off_colour = 0;  /* pixels cloth in both with a channel off by more than 16 */
        for (size_t i = 0; i < n; ++i) {
            const unsigned char *p = a.rgb + 3 * i, *q = b.rgb + 3 * i;
            int x = test_is_cloth(p), y = test_is_cloth(q);
            both += x && y, either += x || y, ca += x, cb += y;
            if (x && y) {
                int worst = 0;
                for (int k = 0; k < 3; ++k) {
                    colour_diff += abs(p[k] - q[k]);
                    if (abs(p[k] - q[k]) > worst) worst = abs(p[k] - q[k]);
                }
                off_colour += worst > 16;
            }
            x = test_is_grey(p), y = test_is_grey(q);
            gboth += x && y, geither += x || y, ga += x, gb += y;
            int d = 0;
            for (int k = 0; k < 3; ++k) d |= abs(p[k] - q[k]) > 8;
            differ += d;
        }
        double min = atof(argv[4]);
        if (!strcmp(argv[1], "compare")) {
            double iou = either ? (double)both / (double)either : 0.0;
            /* The same colour map and shading: where both have cloth, channels agree to
             * within a few levels on average (8-bit strain, 16-bit positions, and the
             * two interpolations differ a little); a lost strain colour (neutral for
             * red) moves a channel by 100 or more where it happens. */
            double mean_diff = both ? colour_diff / (3.0 * (double)both) : 0.0;
            double off_frac = both ? (double)off_colour / (double)both : 0.0;
            printf("cloth pixels: %zu in %s, %zu in %s; overlap %.4f (at least %.4f wanted); "
                   "colours differ by %.2f levels on average (at most %d wanted), by more than 16 "
                   "in %.4f of the pixels (at most %.2f wanted)\n", ca, argv[2], cb, argv[3], iou, min,
                   mean_diff, MAX_MEAN_COLOUR_DIFF, off_frac, MAX_OFF_COLOUR);
            rc = cb > 0 && iou >= min && mean_diff <= MAX_MEAN_COLOUR_DIFF && off_frac <= MAX_OFF_COLOUR ? 0 : 1;
            if (argc == 6 && ga < n / 500) {
                printf("grey (collider) pixels: %zu in %s: no colliders to compare\n", ga, argv[2]);
            } else if (argc == 6) {
                double giou = geither ? (double)gboth / (double)geither : 0.0, gmin = atof(argv[5]);
                printf("grey (collider) pixels: %zu in %s, %zu in %s; overlap %.4f (at least %.4f "
                       "wanted)\n", ga, argv[2], gb, argv[3], giou, gmin);
                if (!(gb > 0 && giou >= gmin)) rc = 1;
            }
        } else {
            double frac = (double)differ / (double)n;
            printf("%s vs %s: %.4f of the pixels differ (at least %.4f wanted)\n", argv[2], argv[3], frac, min);
            rc = frac >= min ? 0 : 1;
        }
    } else {
        fprintf(stderr, "viewer_pngtool: unknown check %s\n", argv[1]);
    }
    test_image_free(&a), test_image_free(&b);
    return rc;
}
