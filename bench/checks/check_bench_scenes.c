/* check_bench_scenes.c -- checks the outputs of `rbcloth bench scenes --frames 3`
 * (default threads: 1 and 2).
 *
 * Usage: check_bench_scenes DIR
 *
 * scenes.csv must have exactly its documented header and one row per scene and thread
 * count: the paper's four scenes (cloth_on_chair, four_layers_sphere, funnel,
 * cannonballs_tearing), the two references (cloth_on_sphere, hanging_cloth) and
 * issue 23's crumpled cloth (crumpled_cloth: absent under --quick, or with both), each
 * with 1 and 2 threads (as stats report them), every row with 3 measured frames and
 * no note. Times are finite and positive (per step, per substep, p90 >= median, the
 * host's wall time); substep times are the step times over the substeps (to the
 * CSV's 6 significant digits: 1e-5 relative for a quotient of two printed values);
 * fps is 1000 / median ms per step; particle and spring counts are the scenes'
 * (structural springs of their grids); contacts, torn springs and fail-safe vertices
 * are counts >= 0;
 * the paper's figures are those the bench quotes. No timing is compared with a
 * threshold: the machine is noisy. scenes.md has a row per CSV row.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "checker.h"

static const char header[] =
    "scene,threads,frames,substeps,particles,springs,colliders,step_ms_median,step_ms_p90,"
    "substep_ms_median,substep_ms_p90,integrate_ms,local_ms,global_ms,collide_ms,other_ms,"
    "wall_ms_median,fps,collider_contacts_median,cloth_contacts_median,torn_springs,"
    "failsafe_vertices,max_penetration_mm,paper_ms_per_substep,paper_ms_per_frame,paper_figure,note,cores,cpu";

enum {
    C_SCENE, C_THREADS, C_FRAMES, C_SUBSTEPS, C_PARTICLES, C_SPRINGS, C_COLLIDERS, C_STEP,
    C_STEP90, C_SUB, C_SUB90, C_INTEGRATE, C_LOCAL, C_GLOBAL, C_COLLIDE, C_OTHER, C_WALL, C_FPS,
    C_CCON, C_XCON, C_TORN, C_FAILSAFE, C_PEN, C_PAPER_SUB, C_PAPER_FRAME, C_PAPER, C_NOTE, C_CORES, C_CPU,
    C_COUNT
};

#define ROUND2 1.0001e-5

/* The scenes, their sizes (grids: n particles, 2 n (n - 1) springs each), substeps
 * per frame, colliders, the paper's figures (NaN: none), and whether --quick leaves
 * the scene out (then its rows are all there or none). */
static const struct {
    const char *name;
    double particles, springs, substeps, colliders, paper_substep, paper_frame;
    int heavy;
} scenes[] = {
    {"cloth_on_chair", 10000, 19800, 8, 7, 2.5, NAN, 0},
    {"four_layers_sphere", 16384, 32256, 8, 2, 4.1, 1000.0 / 35.0, 0},
    {"funnel", 30000, 59400, 8, 3, 1000.0 / 35.0 / 8.0, 1000.0 / 35.0, 0},
    {"cannonballs_tearing", 4096, 8064, 8, 4, NAN, 1000.0 / 60.0, 0},
    {"cloth_on_sphere", 3600, 7080, 8, 2, NAN, NAN, 0},
    {"hanging_cloth_paper", 10000, 19800, 1, 0, NAN, NAN, 0},
    /* Issue 23's, not the paper's: a sphere, the ground and four walls. */
    {"crumpled_cloth", 100489, 200344, 8, 6, NAN, NAN, 1},
};
enum { SCENE_COUNT = sizeof scenes / sizeof scenes[0] };

static double rel(double a, double b) {
    double s = fmax(fabs(a), fabs(b));
    return s > 0.0 ? fabs(a - b) / s : 0.0;
}

/* A finite number, or NaN for "n/a" (*na = 1). */
static int parse_value(const char *text, double *out, int *na) {
    *na = strcmp(text, "n/a") == 0;
    if (*na) {
        *out = NAN;
        return 1;
    }
    char *end;
    *out = strtod(text, &end);
    return end != text && *end == '\0' && isfinite(*out);
}

static int same_or_both_nan(double a, double b) {
    return (isnan(a) && isnan(b)) || rel(a, b) <= 5.0001e-6;
}

/* Everything after the header (checker_main). */
static void check_file(const char *dir, const csv_file *csv) {
    int seen[SCENE_COUNT][3] = {{0}};
    int n = 0;
    for (int i = 0; i < csv->row_count; ++i) {
        char **f = checker_fields(csv, i, C_COUNT);
        const int line = csv->rows[i].line;
        if (!f)
            continue;
        ++n;
        int s = -1;
        for (int k = 0; k < SCENE_COUNT; ++k)
            if (strcmp(f[C_SCENE], scenes[k].name) == 0)
                s = k;
        if (s < 0)
            fprintf(stderr, "%s:%d: unknown scene '%s'\n", csv->path, line, f[C_SCENE]);
        CHECK(s >= 0);
        if (f[C_NOTE][0])
            fprintf(stderr, "%s:%d (%s): note '%s'\n", csv->path, line, f[C_SCENE], f[C_NOTE]);
        CHECK(f[C_NOTE][0] == '\0');
        CHECK(f[C_PAPER][0] != '\0' && f[C_CPU][0] != '\0');
        double v[C_COUNT];
        int na[C_COUNT] = {0};
        for (int k = C_THREADS; k <= C_CORES; ++k) {
            if (k == C_PAPER || k == C_NOTE) {
                v[k] = NAN;
                continue;
            }
            if (!parse_value(f[k], &v[k], &na[k])) {
                fprintf(stderr, "%s:%d (%s): column %d = '%s' is not a finite number\n",
                        csv->path, line, f[C_SCENE], k + 1, f[k]);
                CHECK(!"finite numbers");
            }
        }
        /* n/a only where the bench may say so: no analytic collider, or no paper figure. */
        for (int k = C_THREADS; k <= C_CORES; ++k)
            if (na[k] && k != C_PEN && k != C_PAPER_SUB && k != C_PAPER_FRAME) {
                fprintf(stderr, "%s:%d (%s): column %d is n/a\n", csv->path, line, f[C_SCENE], k + 1);
                CHECK(!"a measured value");
            }
        int positive[] = {C_THREADS, C_FRAMES, C_SUBSTEPS, C_PARTICLES, C_SPRINGS, C_STEP, C_STEP90,
                          C_SUB, C_SUB90, C_WALL, C_FPS, C_CORES};
        for (size_t k = 0; k < sizeof positive / sizeof positive[0]; ++k)
            if (!(v[positive[k]] > 0.0)) {
                fprintf(stderr, "%s:%d (%s): column %d = %g is not positive\n", csv->path, line,
                        f[C_SCENE], positive[k] + 1, v[positive[k]]);
                CHECK(!"positive");
            }
        for (int k = C_INTEGRATE; k <= C_OTHER; ++k)
            CHECK(v[k] >= 0.0);
        CHECK(v[C_CCON] >= 0.0 && v[C_XCON] >= 0.0 && v[C_TORN] >= 0.0 && v[C_FAILSAFE] >= 0.0);
        CHECK(na[C_PEN] || v[C_PEN] >= 0.0);
        CHECK(v[C_STEP90] >= v[C_STEP] && v[C_SUB90] >= v[C_SUB]);
        CHECK(rel(v[C_SUB] * v[C_SUBSTEPS], v[C_STEP]) <= ROUND2);
        CHECK(rel(v[C_SUB90] * v[C_SUBSTEPS], v[C_STEP90]) <= ROUND2);
        CHECK(rel(v[C_FPS] * v[C_STEP], 1000.0) <= ROUND2);
        CHECK_EQ(v[C_FRAMES], 3);
        if (s < 0)
            continue;
        CHECK_EQ(v[C_PARTICLES], scenes[s].particles);
        CHECK_EQ(v[C_SPRINGS], scenes[s].springs);
        CHECK_EQ(v[C_SUBSTEPS], scenes[s].substeps);
        CHECK_EQ(v[C_COLLIDERS], scenes[s].colliders);
        CHECK(same_or_both_nan(v[C_PAPER_SUB], scenes[s].paper_substep));
        CHECK(same_or_both_nan(v[C_PAPER_FRAME], scenes[s].paper_frame));
        /* Penetration is checked where a scene has a sphere, plane, capsule or box. */
        CHECK(na[C_PEN] == (scenes[s].colliders == 0));
        if (v[C_THREADS] == 1 || v[C_THREADS] == 2)
            seen[s][(int)v[C_THREADS]]++;
    }
    printf("scenes.csv: %d rows\n", n);
    int absent[SCENE_COUNT], nabsent = 0;
    for (int s = 0; s < SCENE_COUNT; ++s) {
        absent[s] = scenes[s].heavy && seen[s][1] == 0 && seen[s][2] == 0;
        nabsent += absent[s];
    }
    for (int s = 0; s < SCENE_COUNT; ++s)
        for (int t = 1; t <= 2; ++t) {
            if (absent[s]) continue;
            if (seen[s][t] != 1)
                fprintf(stderr, "scenes.csv: %d rows for %s with %d threads, expected 1\n",
                        seen[s][t], scenes[s].name, t);
            CHECK_EQ(seen[s][t], 1);
        }
    CHECK_EQ(n, 2 * (SCENE_COUNT - nabsent));

    static const char *const paper[] = {"GTX 970"};
    char *md = checker_page(dir, "scenes.md", paper, 1);
    if (md) {
        for (int s = 0; s < SCENE_COUNT; ++s) {
            if (absent[s]) continue;
            char cell[64];
            snprintf(cell, sizeof cell, "| %s | ", scenes[s].name);
            int rows = 0;
            for (const char *p = md; (p = strstr(p, cell)) != NULL; p += strlen(cell))
                ++rows;
            CHECK_EQ(rows, 2);
        }
        free(md);
    }
}

int main(int argc, char **argv) {
    return checker_main(argc, argv, "scenes.csv", header, "bench_scenes", check_file);
}
