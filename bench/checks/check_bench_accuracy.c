/* check_bench_accuracy.c -- checks the outputs of `rbcloth bench accuracy --quick`.
 *
 * Usage: check_bench_accuracy DIR
 *
 * Each CSV must have exactly its documented header, at least one row per paper scene
 * (stretched, hanging) and solver, and every numeric field finite. In
 * accuracy_gap.csv the library's stats must agree with the host's recomputation from
 * the positions it reads back: Eq. 7 is a double sum of the same float positions
 * (relative 1e-6 covers any summation order); the PD objective agrees to the
 * F_tolerance the bench derives for each row (the rounding of the library's float
 * inertial target y and spring lengths, see bench/accuracy.c), and the
 * linear residual to its residual_tolerance (1e-3 relative plus the float floor of
 * evaluating b - A p, derived per row in bench_linear_residual).
 * pareto.md must mark a Pareto front.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "checker.h"

enum { MAX_COLS = 32 };

static int is_text_column(const char *name) {
    return !strcmp(name, "scene") || !strcmp(name, "solver") || !strcmp(name, "control") ||
           !strcmp(name, "mode") || !strcmp(name, "reference");
}

static double rel(double a, double b) {
    double s = fmax(fabs(a), fabs(b));
    return s > 0.0 ? fabs(a - b) / s : 0.0;
}

/* Check one CSV; for the gap file also the stats agreement. Returns the row count. */
static int check_csv(const char *dir, const char *name, const char *header, int gap) {
    csv_file csv;
    int have = csv_read_in(dir, name, &csv) == 0;
    CHECK(have);
    if (!have)
        return 0;
    CHECK(csv_header_is(&csv, header));
    static char copy[1024];
    snprintf(copy, sizeof copy, "%s", header);
    char *head[MAX_COLS];
    const int cols = text_split(copy, ',', head, MAX_COLS);
    int rows = 0;
    int seen[2] = {0, 0}; /* stretched, hanging */
    for (int i = 0; i < csv.row_count; ++i) {
        char **f = checker_fields(&csv, i, cols);
        const int n = cols, line = csv.rows[i].line;
        if (!f)
            continue;
        ++rows;
        seen[0] |= !strcmp(f[0], "stretched");
        seen[1] |= !strcmp(f[0], "hanging");
        double v[MAX_COLS];
        for (int k = 0; k < n; ++k) {
            if (is_text_column(head[k]))
                continue;
            char *end;
            v[k] = strtod(f[k], &end);
            if (!(isfinite(v[k]) && end != f[k] && *end == '\0')) {
                fprintf(stderr, "%s:%d: %s = '%s' is not a finite number\n", csv.path, line, head[k], f[k]);
                CHECK(!"finite numbers");
            }
        }
        if (gap) {
            /* F0 F F_star ... F_library F_star_library eq7_host eq7_library residual_host residual_library */
            /* ... F_linear_star gap_linear F_tolerance F_star_tolerance */
            int bad = fabs(v[6] - v[10]) > v[18] || fabs(v[7] - v[11]) > v[19] || rel(v[12], v[13]) > 1e-6;
            if (bad)
                fprintf(stderr, "%s:%d (%s %s frame %s): F %.12g / %.12g (tol %.3g), F* %.12g / %.12g (tol %.3g), Eq. 7 %.12g / %.12g (host / library)\n",
                        csv.path, line, f[0], f[1], f[3], v[6], v[10], v[18], v[7], v[11], v[19], v[12], v[13]);
            CHECK(fabs(v[6] - v[10]) <= v[18]);
            CHECK(fabs(v[7] - v[11]) <= v[19]);
            CHECK(rel(v[12], v[13]) <= 1e-6);
            if (fabs(v[14] - v[15]) > v[20])
                fprintf(stderr, "%s:%d (%s %s frame %s): linear residual host %.9g, library %.9g (tol %.3g)\n",
                        csv.path, line, f[0], f[1], f[3], v[14], v[15], v[20]);
            CHECK(fabs(v[14] - v[15]) <= v[20]);
        }
    }
    CHECK(rows > 0);
    CHECK(seen[0] && seen[1]);
    csv_free(&csv);
    return rows;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s DIR\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1];
    int n = check_csv(dir, "accuracy_iterations.csv",
                      "scene,solver,frame,eq7,linear_residual,pd_objective,step_ms", 0);
    printf("accuracy_iterations.csv: %d rows\n", n);
    n = check_csv(dir, "accuracy_budget.csv",
                  "scene,solver,frame,budget_ms,eq7,linear_iterations,linear_residual,"
                  "pd_objective,step_ms",
                  0);
    printf("accuracy_budget.csv: %d rows\n", n);
    n = check_csv(dir, "accuracy_sweep.csv",
                  "scene,solver,control,budget_ms,substeps,nonlinear_iterations,linear_iterations,"
                  "frames,final_eq7,median_step_ms,median_linear_iterations,unstable_steps,diverged",
                  0);
    printf("accuracy_sweep.csv: %d rows\n", n);
    n = check_csv(dir, "accuracy_gap.csv",
                  "scene,solver,mode,frame,linear_iterations,F0,F,F_star,gap,reference,"
                  "F_library,F_star_library,eq7_host,eq7_library,residual_host,residual_library,"
                  "F_linear_star,gap_linear,F_tolerance,F_star_tolerance,residual_tolerance",
                  1);
    printf("accuracy_gap.csv: %d rows\n", n);
    static const char *const fronts[] = {"## stretched", "## hanging", "**front**"};
    free(checker_page(dir, "pareto.md", fronts, 3));
    return check_report("bench_accuracy");
}
