/* check_bench_perf.c -- checks the outputs of `rbcloth bench perf --quick` (default
 * threads: 1 and 2).
 *
 * Usage: check_bench_perf DIR
 *
 * perf.csv must have exactly its documented header and one row per configuration
 * of the quick run: RBGS on the 32 x 32, 64 x 64 and 100 x 100 grids and on an
 * irregular mesh of about 10K particles, Jacobi and serial Gauss-Seidel on the
 * 100 x 100 grid, each with 1 and 2 threads (as stats report them). Every numeric
 * field is finite; counts, times and rates that must be positive are; RBGS's grids
 * and the irregular mesh (bipartite by construction) have 2 colors; every run did 11
 * linear iterations per frame. The derived columns must agree with the measured
 * ones to the rounding of the CSV: each value is printed with 6 significant digits,
 * so relative error <= 5e-6 each, and a product or quotient of two (three) printed
 * values agrees within 1e-5 (1.5e-5) relative. memory_bytes is "n/a" (not reported
 * by the plugin) in all three memory columns together, or a positive count that
 * bytes_per_particle and bytes_per_spring divide; others_cpu is a fraction in
 * [0, 1] or "n/a". No timing is compared with a threshold: the machine is noisy.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "checker.h"

enum { MAX_ROWS = 64 };

static const char header[] =
    "mesh,solver,particles,springs,colors,threads,frames,linear_iterations,step_ms,"
    "integrate_ms,local_ms,global_ms,other_ms,wall_ms,particle_updates_per_s,"
    "ns_per_particle_iteration,speedup_vs_1_thread,setup_ms,memory_bytes,bytes_per_particle,"
    "bytes_per_spring,others_cpu,energy_guard,cores,cpu";

enum {
    C_MESH, C_SOLVER, C_PARTICLES, C_SPRINGS, C_COLORS, C_THREADS, C_FRAMES, C_ITERATIONS,
    C_STEP, C_INTEGRATE, C_LOCAL, C_GLOBAL, C_OTHER, C_WALL, C_UPDATES, C_NS, C_SPEEDUP,
    C_SETUP, C_MEMORY, C_BPP, C_BPS, C_OTHERS, C_GUARD, C_CORES, C_CPU, C_COUNT
};

/* Relative agreement of printed values: see the header comment. */
#define ROUND2 1.0001e-5
#define ROUND3 1.5001e-5

typedef struct row {
    char mesh[16], solver[32];
    double v[C_COUNT];
    int memory_reported;
} row;

static double rel(double a, double b) {
    double s = fmax(fabs(a), fabs(b));
    return s > 0.0 ? fabs(a - b) / s : 0.0;
}

static int parse_number(const char *text, double *out) {
    char *end;
    *out = strtod(text, &end);
    return end != text && *end == '\0' && isfinite(*out);
}

static const row *find(const row *rows, int n, const char *mesh, const char *solver,
                       double particles, double threads) {
    for (int k = 0; k < n; ++k)
        if (!strcmp(rows[k].mesh, mesh) && !strcmp(rows[k].solver, solver) &&
            (particles < 0 || rows[k].v[C_PARTICLES] == particles) && rows[k].v[C_THREADS] == threads)
            return &rows[k];
    return NULL;
}

/* Everything after the header (checker_main). */
static void check_file(const char *dir, const csv_file *csv) {
    static row rows[MAX_ROWS];
    int n = 0;
    for (int i = 0; i < csv->row_count; ++i) {
        char **f = checker_fields(csv, i, C_COUNT);
        const int line = csv->rows[i].line;
        if (!f || n == MAX_ROWS)
            continue;
        row *r = &rows[n++];
        snprintf(r->mesh, sizeof r->mesh, "%s", f[C_MESH]);
        snprintf(r->solver, sizeof r->solver, "%s", f[C_SOLVER]);
        CHECK(!strcmp(r->mesh, "grid") || !strcmp(r->mesh, "irregular"));
        CHECK(f[C_GUARD][0] != '\0');
        CHECK(f[C_CPU][0] != '\0');
        int na = !strcmp(f[C_MEMORY], "n/a");
        r->memory_reported = !na;
        CHECK(na == !strcmp(f[C_BPP], "n/a"));
        CHECK(na == !strcmp(f[C_BPS], "n/a"));
        for (int k = C_PARTICLES; k <= C_CORES; ++k) {
            if (k == C_GUARD || (na && (k == C_MEMORY || k == C_BPP || k == C_BPS)) ||
                (k == C_OTHERS && !strcmp(f[k], "n/a"))) {
                r->v[k] = NAN;
                continue;
            }
            if (!parse_number(f[k], &r->v[k])) {
                fprintf(stderr, "%s:%d: column %d = '%s' is not a finite number\n", csv->path, line, k + 1, f[k]);
                CHECK(!"finite numbers");
                r->v[k] = NAN;
            }
        }
        const double *v = r->v;
        /* Positive where they must be; stage times may read 0 but never less. */
        int positive[] = {C_PARTICLES, C_SPRINGS, C_COLORS, C_THREADS, C_FRAMES, C_ITERATIONS,
                          C_STEP,      C_WALL,    C_UPDATES, C_NS,     C_SPEEDUP, C_SETUP,
                          C_CORES};
        for (size_t k = 0; k < sizeof positive / sizeof positive[0]; ++k)
            if (!(v[positive[k]] > 0.0)) {
                fprintf(stderr, "%s:%d (%s %s): column %d = %g is not positive\n", csv->path, line,
                        r->mesh, r->solver, positive[k] + 1, v[positive[k]]);
                CHECK(!"positive");
            }
        for (int k = C_INTEGRATE; k <= C_OTHER; ++k)
            CHECK(v[k] >= 0.0);
        /* Others' share of the CPU: a fraction, or n/a for runs too short to tell. */
        CHECK(isnan(v[C_OTHERS]) || (v[C_OTHERS] >= 0.0 && v[C_OTHERS] <= 1.0));
        CHECK_EQ(v[C_ITERATIONS], 11);
        /* particle updates/s = particles x iterations / step time */
        double updates = v[C_PARTICLES] * v[C_ITERATIONS] / (1e-3 * v[C_STEP]);
        if (rel(v[C_UPDATES], updates) > ROUND2)
            fprintf(stderr, "%s:%d (%s %s, %g particles): %g updates/s, but %g x %g / %g ms = %.9g\n",
                    csv->path, line, r->mesh, r->solver, v[C_PARTICLES], v[C_UPDATES], v[C_PARTICLES],
                    v[C_ITERATIONS], v[C_STEP], updates);
        CHECK(rel(v[C_UPDATES], updates) <= ROUND2);
        CHECK(rel(v[C_NS] * v[C_UPDATES], 1e9) <= ROUND2);
        if (r->memory_reported) {
            CHECK(v[C_MEMORY] > 0.0);
            CHECK(rel(v[C_BPP] * v[C_PARTICLES], v[C_MEMORY]) <= 5.0001e-6);
            CHECK(rel(v[C_BPS] * v[C_SPRINGS], v[C_MEMORY]) <= 5.0001e-6);
        }
        if (!strcmp(r->solver, "rbgs"))
            CHECK_EQ(v[C_COLORS], 2);
    }
    printf("perf.csv: %d rows\n", n);

    /* The quick run's configurations, each with 1 and 2 threads. */
    static const double grid_sizes[] = {1024, 4096, 10000};
    for (int t = 1; t <= 2; ++t) {
        for (int k = 0; k < 3; ++k) {
            const row *r = find(rows, n, "grid", "rbgs", grid_sizes[k], t);
            if (!r)
                fprintf(stderr, "perf.csv: no grid rbgs row with %g particles and %d threads\n",
                        grid_sizes[k], t);
            CHECK(r != NULL);
            if (r)
                CHECK_EQ(r->v[C_SPRINGS], 2 * sqrt(grid_sizes[k]) * (sqrt(grid_sizes[k]) - 1));
        }
        const char *solvers[] = {"jacobi", "gauss_seidel"};
        for (int k = 0; k < 2; ++k) {
            const row *r = find(rows, n, "grid", solvers[k], 10000, t);
            if (!r)
                fprintf(stderr, "perf.csv: no %s row on the 10K grid with %d threads\n", solvers[k], t);
            CHECK(r != NULL);
        }
        const row *irr = find(rows, n, "irregular", "rbgs", -1, t);
        if (!irr)
            fprintf(stderr, "perf.csv: no irregular rbgs row with %d threads\n", t);
        CHECK(irr != NULL);
        if (irr) {
            /* About as many particles as the 100 x 100 grid (the split mesh of a t x t
             * triangle grid has 6 t^2 - 8 t + 3 particles: steps of about 12 t). */
            CHECK(fabs(irr->v[C_PARTICLES] - 10000) <= 0.05 * 10000);
            /* Each triangle's 3 quads: 3 centroid springs + 2 per split edge. */
            CHECK(irr->v[C_SPRINGS] > 1.8 * irr->v[C_PARTICLES] &&
                  irr->v[C_SPRINGS] < 2.0 * irr->v[C_PARTICLES]);
        }
    }
    /* The speedup column: the 1-thread row's step time over this row's. */
    for (int k = 0; k < n; ++k) {
        const row *r = &rows[k];
        const row *one = NULL;
        for (int j = 0; j < n && !one; ++j)
            if (!strcmp(rows[j].mesh, r->mesh) && !strcmp(rows[j].solver, r->solver) &&
                rows[j].v[C_PARTICLES] == r->v[C_PARTICLES] && rows[j].v[C_THREADS] == 1)
                one = &rows[j];
        CHECK(one != NULL);
        if (one)
            CHECK(rel(r->v[C_SPEEDUP], one->v[C_STEP] / r->v[C_STEP]) <= ROUND3);
    }
    CHECK_EQ(n, 2 * (3 + 2 + 1));

    static const char *const sections[] = {"## Scaling", "## Speedup of 2 threads over 1",
                                           "## Grid against irregular mesh",
                                           "## Solvers at equal iterations", "## Memory"};
    free(checker_page(dir, "perf.md", sections, sizeof sections / sizeof sections[0]));
}

int main(int argc, char **argv) {
    return checker_main(argc, argv, "perf.csv", header, "bench_perf", check_file);
}
