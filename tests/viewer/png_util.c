/* png_util.c -- see png_util.h. */
#include "png_util.h"

#include <errno.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int test_png_read(const char *path, test_image *img, char *err, size_t errlen) {
    memset(img, 0, sizeof *img);
    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&pi, path)) {
        snprintf(err, errlen, "%s: not a readable PNG (%s)", path, pi.message);
        return 1;
    }
    pi.format = PNG_FORMAT_RGB; /* alpha, if any, composited on black by libpng */
    img->w = pi.width, img->h = pi.height;
    img->rgb = malloc(PNG_IMAGE_SIZE(pi));
    if (!img->rgb || !png_image_finish_read(&pi, NULL, img->rgb, 0, NULL)) {
        snprintf(err, errlen, "%s: cannot decode (%s)", path, img->rgb ? pi.message : "out of memory");
        png_image_free(&pi);
        test_image_free(img);
        return 1;
    }
    return 0;
}

void test_image_free(test_image *img) {
    free(img->rgb);
    img->rgb = NULL;
}
