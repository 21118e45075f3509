/* check_bench_peers.c -- checks the outputs of `rbcloth bench peers --quick`.
 *
 * Usage: check_bench_peers DIR
 *
 * peers.csv must have exactly its documented header and a row for each solver of
 * the sweep (rbgs, rbgs_sor, rbgs_chebyshev, jacobi_chebyshev, direct), every
 * numeric field finite, every row that held all frames.
 *
 * E: for every row the checker reads the final positions the bench wrote
 * (peers_positions/ID.f32) and recomputes Eq. 7 itself, over the 19,800 springs of
 * the 100 x 100 grid with rest lengths from the grid's float rest positions (as
 * samples/grid.c makes them). Against the bench's own recomputation (eq7_host: the
 * same formula over the same floats) it must agree to 1e-11 relative: two double
 * sums of 19,800 positive terms differ by at most 19,800 x 2^-53 ~ 2.2e-12 relative in
 * any order, and the CSV prints 12 digits (at most 5e-12 relative). Against the
 * library's stats (eq7) it must agree within B = sum_k (2 |v_k| + d_k) d_k,
 * d_k = 2^-24 L_k: the library keeps rest lengths as floats (each within half an ulp,
 * at most 2^-24 L of the double length), which moves each violation v_k by at most d_k
 * and its square by (2|v| + d) d; plus the same 1e-11 for sums and digits. A CSV
 * whose E came from another frame or configuration than its positions differs by
 * orders of magnitude more. The last frame's E lies within the tail columns (the
 * least and largest E over the last tenth of the frames).
 *
 * The Pareto flags are recomputed from the CSV (a row is on the front iff it held
 * and no other row is at least as fast and as accurate and better in one), and
 * meets_target from E <= 1.45e-5 and ms <= 0.3.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "checker.h"

enum { MAX_ROWS = 4096, GRID = 100 };

static const char header[] =
    "id,phase,solver,substeps,nonlinear,linear,omega_set,rho_set,energy_guard,threads,frames,"
    "ms_per_frame,integrate_ms,local_ms,global_ms,other_ms,eq7,eq7_host,max_strain,eq7_tail_min,"
    "eq7_tail_max,omega,rho,guard_clamps,unstable,diverged,pareto,meets_target";

/* Column indices in the header above. */
enum { C_ID, C_PHASE, C_SOLVER, C_SUBSTEPS, C_NONLINEAR, C_LINEAR, C_OMEGA_SET, C_RHO_SET,
       C_GUARD, C_THREADS, C_FRAMES, C_MS, C_INTEGRATE, C_LOCAL, C_GLOBAL, C_OTHER, C_EQ7,
       C_EQ7_HOST, C_STRAIN, C_TAIL_MIN, C_TAIL_MAX, C_OMEGA, C_RHO, C_CLAMPS, C_UNSTABLE,
       C_DIVERGED, C_PARETO, C_MEETS, C_COUNT };

typedef struct row {
    double v[C_COUNT];
    char solver[32];
} row;

static row rows[MAX_ROWS];

/* Eq. 7 of positions p over the grid's springs, and the bound B (header comment)
 * on what float rest lengths change in it. Rest positions as samples/grid.c: the
 * float nearest to (i s, 0, j s), s = 1/99 as the default scene writes it. */
static double eq7_of(const float *p, double *bound) {
    const double s = 0.010101010101010102;
    double e = 0.0, b = 0.0;
    for (int j = 0; j < GRID; ++j)
        for (int i = 0; i < GRID; ++i)
            for (int dir = 0; dir < 2; ++dir) {
                int i2 = i + (dir == 0), j2 = j + (dir == 1);
                if (i2 >= GRID || j2 >= GRID)
                    continue;
                float ra[3] = {(float)(i * s), 0.0f, (float)(j * s)};
                float rb[3] = {(float)(i2 * s), 0.0f, (float)(j2 * s)};
                const float *pa = p + 3 * (i + GRID * j), *pb = p + 3 * (i2 + GRID * j2);
                double l2 = 0.0, r2 = 0.0;
                for (int a = 0; a < 3; ++a) {
                    double d = (double)pa[a] - pb[a], r = (double)ra[a] - rb[a];
                    l2 += d * d;
                    r2 += r * r;
                }
                double L = sqrt(r2), v = sqrt(l2) - L, dk = ldexp(L, -24);
                e += v * v;
                b += (2.0 * fabs(v) + dk) * dk;
            }
    *bound = b;
    return e;
}

/* Everything after the header (checker_main). */
static void check_file(const char *dir, const csv_file *csv) {
    char path[4096];
    int n = 0;
    for (int i = 0; i < csv->row_count; ++i) {
        char **f = checker_fields(csv, i, C_COUNT);
        if (!f || n == MAX_ROWS)
            continue;
        row *r = &rows[n++];
        snprintf(r->solver, sizeof r->solver, "%s", f[C_SOLVER]);
        CHECK(!strcmp(f[C_GUARD], "clamp") || !strcmp(f[C_GUARD], "off"));
        for (int k = 0; k < C_COUNT; ++k) {
            if (k == C_PHASE || k == C_SOLVER || k == C_GUARD)
                continue;
            char *end;
            r->v[k] = strtod(f[k], &end);
            if (*end || !isfinite(r->v[k]))
                fprintf(stderr, "%s:%d: %s = '%s' is not a finite number\n", csv->path,
                        csv->rows[i].line, f[C_SOLVER], f[k]);
            CHECK(*end == '\0' && isfinite(r->v[k]));
        }
    }
    CHECK(n >= 5);
    static const char *const solvers[] = {"rbgs", "rbgs_sor", "rbgs_chebyshev", "jacobi_chebyshev",
                                          "direct"};
    for (size_t s = 0; s < sizeof solvers / sizeof solvers[0]; ++s) {
        int seen = 0;
        for (int i = 0; i < n; ++i)
            seen |= !strcmp(rows[i].solver, solvers[s]);
        if (!seen)
            fprintf(stderr, "peers.csv has no row for %s\n", solvers[s]);
        CHECK(seen);
    }

    int fronts = 0;
    for (int i = 0; i < n; ++i) {
        const row *r = &rows[i];
        /* The quick configurations are all stable: every frame ran, the cloth held. */
        CHECK_EQ(r->v[C_ID], i);
        CHECK(r->v[C_FRAMES] == rows[0].v[C_FRAMES] && r->v[C_FRAMES] > 0);
        CHECK_EQ(r->v[C_UNSTABLE], 0);
        CHECK_EQ(r->v[C_DIVERGED], 0);
        CHECK(r->v[C_MS] > 0.0);
        CHECK(r->v[C_GLOBAL] >= 0.0 && r->v[C_GLOBAL] <= r->v[C_MS] * 1.5);

        snprintf(path, sizeof path, "%s/peers_positions/%d.f32", dir, i);
        size_t size = 0;
        unsigned char *bytes = file_read_bytes(path, &size);
        CHECK(bytes != NULL);
        CHECK_EQ(size, (size_t)GRID * GRID * 3 * sizeof(float));
        if (bytes && size == (size_t)GRID * GRID * 3 * sizeof(float)) {
            float *p = malloc(size);
            memcpy(p, bytes, size);
            double bound = 0.0, e = eq7_of(p, &bound);
            CHECK(isfinite(e) && e > 0.0);
            CHECK_NEAR(r->v[C_EQ7_HOST], e, 1e-11 * e);
            CHECK_NEAR(r->v[C_EQ7], e, bound + 1e-11 * e);
            /* The last frame is inside the tail window (6 significant digits). */
            CHECK(r->v[C_TAIL_MIN] <= e * (1.0 + 1e-5) && r->v[C_TAIL_MAX] >= e * (1.0 - 1e-5));
            free(p);
        }
        free(bytes);

        int dominated = 0;
        for (int j = 0; j < n; ++j) {
            const row *o = &rows[j];
            if (j != i && o->v[C_MS] <= r->v[C_MS] && o->v[C_EQ7_HOST] <= r->v[C_EQ7_HOST] &&
                (o->v[C_MS] < r->v[C_MS] || o->v[C_EQ7_HOST] < r->v[C_EQ7_HOST]))
                dominated = 1;
        }
        CHECK_EQ(r->v[C_PARETO], !dominated);
        fronts += !dominated;
        CHECK_EQ(r->v[C_MEETS], r->v[C_EQ7_HOST] <= 1.45e-5 && r->v[C_MS] <= 0.3);
    }
    CHECK(fronts >= 1);

    static const char *const phrases[] = {"## Pareto front", "measured elsewhere, docs/facts.md",
                                          "XPBD 11x1"};
    free(checker_page(dir, "peers.md", phrases, 3));
}

int main(int argc, char **argv) {
    return checker_main(argc, argv, "peers.csv", header, "check_bench_peers", check_file);
}
