/* png_util.h -- reading RGB(A) PNGs for the viewer tests, and the pixel classes the
 * viewer's palette makes separable by hue: cloth colours all have r > b (neutral
 * 0.94/0.83 to red 0.80/0.08), colliders are grey (r = g = b) and the background
 * gradient is bluish (b - r from 20 to 33 levels).
 */
#ifndef RBC_TEST_PNG_UTIL_H
#define RBC_TEST_PNG_UTIL_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct test_image {
    uint32_t w, h;
    unsigned char *rgb; /* w * h * 3 */
} test_image;

/* 0, or nonzero with a message in err naming the file. */
int test_png_read(const char *path, test_image *img, char *err, size_t errlen);
void test_image_free(test_image *img);

/* Cloth: r exceeds b by CLOTH_MARGIN levels. The darkest cloth colour (neutral at
 * the ambient 0.4) has r - b = 0.11 x 0.4 x 255 = 11 levels; grey has 0 (1 after
 * rounding) and the background b > r, so blends of the two stay below 4. */
enum { CLOTH_MARGIN = 4 };
static inline int test_is_cloth(const unsigned char *p) { return p[0] >= p[2] + CLOTH_MARGIN; }
/* Grey (colliders): channels within 3 levels of each other; shading scales them
 * alike, and 8-bit rounding of blends parts them by 1 or 2. */
static inline int test_is_grey(const unsigned char *p) {
    return abs(p[0] - p[1]) <= 3 && abs(p[1] - p[2]) <= 3 && abs(p[0] - p[2]) <= 3;
}

#endif
