/* check_target_json.c -- the target error mode (ABI 1.4) on a paper scene, from the
 * summary `rbcloth run ... --preset game_60hz` writes.
 *
 * Usage: check_target_json SUMMARY.json FRAMES
 *   - the run took FRAMES frames and every one is counted met or missed;
 *   - the cost cap held in every frame: the most substeps a frame chose is at most
 *     max_substeps, and the most linear iterations a frame did at most
 *     max_substeps x max_linear_iterations (the cap is the product of the two);
 *   - the target was met in at least 9 of 10 frames (what the README promises for
 *     the preset), and the last frame's strain is within the target;
 *   - the largest strain reached is finite. */
#include <cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "check.h"
#include "text_file.h"

static double num(const cJSON *o, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v)) {
        fprintf(stderr, "check_target_json: no number '%s'\n", key);
        return NAN;
    }
    return v->valuedouble;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: check_target_json SUMMARY.json FRAMES\n");
        return 2;
    }
    char *text = text_file_read(argv[1]);
    CHECK(text != NULL);
    if (!text) return check_report("check_target_json");
    cJSON *root = cJSON_Parse(text);
    CHECK(root != NULL);
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(root, "target");
    CHECK(cJSON_IsObject(t));
    if (root && cJSON_IsObject(t)) {
        const double frames = atof(argv[2]);
        const double met = num(t, "frames_met"), missed = num(t, "frames_missed");
        const double target = num(t, "target_strain");
        const double cap_sub = num(t, "max_substeps"), cap_it = num(t, "max_linear_iterations");
        printf("%s: met %g of %g frames, substeps up to %g (cap %g), iterations up to %g "
               "(cap %g), strain %.4g last, %.4g at worst (target %g)\n",
               argv[1], met, frames, num(t, "substeps_max"), cap_sub,
               num(t, "linear_iterations_max"), cap_sub * cap_it, num(t, "reached_last"),
               num(t, "reached_max"), target);
        CHECK(num(root, "frames") == frames);
        CHECK(met + missed == frames);
        CHECK(num(t, "substeps_max") <= cap_sub);
        CHECK(num(t, "linear_iterations_max") <= cap_sub * cap_it);
        CHECK(10.0 * met >= 9.0 * frames);
        CHECK(num(t, "reached_last") <= target);
        CHECK(isfinite(num(t, "reached_max")));
    }
    cJSON_Delete(root);
    free(text);
    return check_report("check_target_json");
}
