/* check_cli_outputs.c -- checks what `rbcloth run` wrote for a one-cloth scene.
 *
 * Usage: check_cli_outputs DIR STEM POINTS QUADS SAMPLES [SCENE PARTICLES SPRINGS]
 *   DIR/STEM.pc2   header "POINTCACHE2\0", version 1, POINTS points, start frame 1,
 *                  sample rate 1, SAMPLES samples, size 32 + SAMPLES * POINTS * 12,
 *                  every coordinate finite
 *   DIR/STEM.obj   POINTS "v" lines and QUADS "f" lines of 4 indices in 1..POINTS
 *   DIR/SCENE.json the summary: PARTICLES and SPRINGS over all cloths, SAMPLES frames,
 *                  the median and mean of every stage, the final Eq. 7 error
 */
#include <cJSON.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

static char *read_file(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return NULL;
    }
    size_t cap = 1 << 16, n = 0;
    char *data = malloc(cap + 1);
    size_t got;
    while (data && (got = fread(data + n, 1, cap - n, f)) > 0) {
        n += got;
        if (n == cap) {
            char *bigger = realloc(data, 2 * cap + 1);
            if (!bigger) {
                free(data);
                data = NULL;
                break;
            }
            data = bigger;
            cap *= 2;
        }
    }
    fclose(f);
    if (data)
        data[n] = '\0';
    *size = n;
    return data;
}

static int32_t le_i32(const unsigned char *p) {
    return (int32_t)((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                     (uint32_t)p[3] << 24);
}

static float le_f32(const unsigned char *p) {
    uint32_t bits = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                    (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

static void check_pc2(const char *path, long points, long samples) {
    size_t size = 0;
    unsigned char *data = (unsigned char *)read_file(path, &size);
    CHECK(data != NULL);
    if (!data)
        return;
    CHECK_EQ(size, 32 + samples * points * 12);
    if (size >= 32) {
        CHECK(memcmp(data, "POINTCACHE2\0", 12) == 0);
        CHECK_EQ(le_i32(data + 12), 1);
        CHECK_EQ(le_i32(data + 16), points);
        CHECK_NEAR(le_f32(data + 20), 1.0, 0.0); /* start frame: sample k is frame k + 1 */
        CHECK_NEAR(le_f32(data + 24), 1.0, 0.0); /* sample rate */
        CHECK_EQ(le_i32(data + 28), samples);
    }
    if (size == (size_t)(32 + samples * points * 12)) {
        long non_finite = 0;
        for (size_t i = 32; i < size; i += 4)
            non_finite += !isfinite(le_f32(data + i));
        CHECK_EQ(non_finite, 0);
    }
    free(data);
}

static void check_obj(const char *path, long points, long quads) {
    size_t size = 0;
    char *text = read_file(path, &size);
    CHECK(text != NULL);
    if (!text)
        return;
    long v = 0, f = 0, bad_faces = 0;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        if (strncmp(line, "v ", 2) == 0) {
            ++v;
        } else if (strncmp(line, "f ", 2) == 0) {
            ++f;
            long idx[5];
            int n = sscanf(line + 2, "%ld %ld %ld %ld %ld", &idx[0], &idx[1], &idx[2], &idx[3],
                           &idx[4]);
            int ok = n == 4;
            for (int k = 0; ok && k < 4; ++k)
                ok = idx[k] >= 1 && idx[k] <= points;
            bad_faces += !ok;
        }
    }
    CHECK_EQ(v, points);
    CHECK_EQ(f, quads);
    CHECK_EQ(bad_faces, 0);
    free(text);
}

static void check_summary(const char *path, long particles, long samples, long springs) {
    size_t size = 0;
    char *text = read_file(path, &size);
    CHECK(text != NULL);
    if (!text)
        return;
    cJSON *root = cJSON_Parse(text);
    free(text);
    CHECK(root != NULL);
    if (!root)
        return;
    const cJSON *particle_count = cJSON_GetObjectItemCaseSensitive(root, "particles");
    const cJSON *spring_count = cJSON_GetObjectItemCaseSensitive(root, "springs");
    const cJSON *frames = cJSON_GetObjectItemCaseSensitive(root, "frames");
    CHECK(cJSON_IsNumber(particle_count) && particle_count->valuedouble == (double)particles);
    CHECK(cJSON_IsNumber(spring_count) && spring_count->valuedouble == (double)springs);
    CHECK(cJSON_IsNumber(frames) && frames->valuedouble == (double)samples);
    const cJSON *timing = cJSON_GetObjectItemCaseSensitive(root, "ms_per_frame");
    static const char *const stages[] = {"step",    "integrate", "local", "global",
                                         "collide", "callback",  "other"};
    for (size_t i = 0; i < sizeof stages / sizeof stages[0]; ++i) {
        const cJSON *stage = cJSON_GetObjectItemCaseSensitive(timing, stages[i]);
        const cJSON *median = cJSON_GetObjectItemCaseSensitive(stage, "median");
        const cJSON *mean = cJSON_GetObjectItemCaseSensitive(stage, "mean");
        CHECK(cJSON_IsNumber(median) && median->valuedouble >= 0.0);
        CHECK(cJSON_IsNumber(mean) && mean->valuedouble >= 0.0);
    }
    const cJSON *final = cJSON_GetObjectItemCaseSensitive(root, "final");
    const cJSON *error = cJSON_GetObjectItemCaseSensitive(final, "error_eq7");
    CHECK(cJSON_IsNumber(error) && error->valuedouble >= 0.0);
    cJSON_Delete(root);
}

int main(int argc, char **argv) {
    if (argc != 6 && argc != 9) {
        fprintf(stderr, "usage: %s DIR STEM POINTS QUADS SAMPLES [SCENE PARTICLES SPRINGS]\n",
                argv[0]);
        return 2;
    }
    const char *dir = argv[1], *stem = argv[2];
    long points = atol(argv[3]), quads = atol(argv[4]), samples = atol(argv[5]);
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.pc2", dir, stem);
    check_pc2(path, points, samples);
    snprintf(path, sizeof path, "%s/%s.obj", dir, stem);
    check_obj(path, points, quads);
    if (argc == 9) {
        snprintf(path, sizeof path, "%s/%s.json", dir, argv[6]);
        check_summary(path, atol(argv[7]), samples, atol(argv[8]));
    }
    return check_report("check_cli_outputs");
}
