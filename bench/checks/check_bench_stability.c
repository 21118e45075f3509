/* check_bench_stability.c -- checks the stability.csv of `rbcloth bench stability
 * --quick`.
 *
 * Usage: check_bench_stability STABILITY.csv KNOWN_ENERGY_GROWTH.txt
 *
 * Asserted for every (case, solver) row:
 *   - no non-finite value ever reached the host (status NaN-leak, nonfinite_frame,
 *     or a "LIBRARY BUG" note: non-finite stats, state not restored after
 *     RBC_ERR_UNSTABLE) -- never allowed;
 *   - no run failed with another error, and no degenerate mesh of the ABI's valid
 *     kinds (coincident vertices, zero-length springs) was rejected;
 *   - where every step returned RBC_OK, the kinetic energy stayed within the energy
 *     the configuration supplies: ke_ratio <= 1 + 1e-6. The bound (initial spring
 *     energy + work of gravity + what pins or a moving sphere can supply, in the
 *     sphere's frame, + the rounding of a float state) is derived in
 *     bench/stability.c. A step that returns RBC_ERR_UNSTABLE is allowed:
 *     the library restored the state and said so.
 * Energy growth that is known and reported is listed in KNOWN_ENERGY_GROWTH.txt
 * (dimension|value|solver|why); such rows are printed, not failed, and a listed row
 * that no longer grows is printed so the list can shrink. Any other growth fails.
 * The extreme cases the test is about must be present for all 8 solvers.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "csv.h"
#include "text_file.h"

enum { MAX_LINES = 4096, MAX_KNOWN = 256, SOLVERS = 8 };

static int col(const csv_file *csv, const char *name) {
    int k = csv_column(csv, name);
    if (k < 0) {
        fprintf(stderr, "%s has no column %s\n", csv->path, name);
        exit(1);
    }
    return k;
}

typedef struct known {
    char *dimension, *value, *solver, *why;
    int seen_growing;
} known;

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s STABILITY.csv KNOWN_ENERGY_GROWTH.txt\n", argv[0]);
        return 2;
    }
    csv_file csv;
    int have_csv = csv_read(argv[1], &csv) == 0;
    char *list = text_file_read(argv[2]);
    CHECK(have_csv);
    CHECK(list != NULL);
    if (!have_csv || !list) {
        csv_free(&csv);
        free(list);
        return check_report("bench_stability");
    }

    known known_rows[MAX_KNOWN];
    int known_count = 0;
    char *lines[MAX_LINES];
    int nl = text_split(list, '\n', lines, MAX_LINES);
    for (int i = 0; i < nl && known_count < MAX_KNOWN; ++i) {
        if (!lines[i][0] || lines[i][0] == '#')
            continue;
        char *f[4];
        if (text_split(lines[i], '|', f, 4) != 4) {
            fprintf(stderr, "%s: line %d is not dimension|value|solver|why\n", argv[2], i + 1);
            CHECK(0);
            continue;
        }
        known_rows[known_count++] = (known){f[0], f[1], f[2], f[3], 0};
    }

    const csv_row *h = &csv.header, *rows = csv.rows;
    const int row_count = csv.row_count;
    CHECK(row_count > 0);
    if (row_count < 1) {
        csv_free(&csv);
        free(list);
        return check_report("bench_stability");
    }
    const int c_dim = col(&csv, "dimension"), c_val = col(&csv, "value"),
              c_sol = col(&csv, "solver"), c_status = col(&csv, "status"),
              c_nonfinite = col(&csv, "nonfinite_frame"), c_ratio = col(&csv, "ke_ratio"),
              c_eq7 = col(&csv, "final_eq7"), c_strain = col(&csv, "peak_max_strain"),
              c_run = col(&csv, "frames_run"), c_planned = col(&csv, "frames_planned"),
              c_unst = col(&csv, "first_unstable_frame"), c_clamped = col(&csv, "clamped_steps"),
              c_note = col(&csv, "note");

    int growth_known = 0, unstable = 0, clamped = 0;
    for (int i = 0; i < row_count; ++i) {
        const csv_row *r = &rows[i];
        CHECK_EQ(r->count, h->count);
        if (r->count != h->count)
            continue;
        const char *status = r->field[c_status], *note = r->field[c_note];
        char label[256];
        snprintf(label, sizeof label, "%s = %s, %s", r->field[c_dim], r->field[c_val], r->field[c_sol]);
        if (strcmp(status, "NaN-leak") == 0 || atol(r->field[c_nonfinite]) != -1 ||
            strstr(note, "LIBRARY BUG")) {
            fprintf(stderr, "%s: a non-finite value or broken state reached the host: %s\n", label,
                    note);
            CHECK(!"no non-finite value reaches the host");
            continue;
        }
        if (strcmp(status, "error") == 0 || strcmp(status, "rejected") == 0) {
            fprintf(stderr, "%s: %s: %s\n", label, status, note);
            CHECK(!"every case runs");
            continue;
        }
        if (strcmp(status, "skipped") == 0) {
            printf("skipped: %s: %s\n", label, note);
            continue;
        }
        if (strcmp(status, "unstable-reported") == 0) {
            CHECK(atol(r->field[c_unst]) >= 1);
            ++unstable;
            continue;
        }
        double ratio = strtod(r->field[c_ratio], NULL);
        CHECK(isfinite(ratio));
        CHECK(isfinite(strtod(r->field[c_eq7], NULL)));
        CHECK(isfinite(strtod(r->field[c_strain], NULL)));
        CHECK_EQ(atol(r->field[c_run]), atol(r->field[c_planned]));
        known *k = NULL;
        for (int j = 0; j < known_count; ++j)
            if (strcmp(known_rows[j].dimension, r->field[c_dim]) == 0 &&
                strcmp(known_rows[j].value, r->field[c_val]) == 0 &&
                strcmp(known_rows[j].solver, r->field[c_sol]) == 0)
                k = &known_rows[j];
        if (strcmp(status, "energy-growth") == 0 || !(ratio <= 1.0 + 1e-6)) {
            if (k) {
                k->seen_growing = 1;
                ++growth_known;
                printf("known energy growth: %s: ke_ratio %.4g (%s)\n", label, ratio, k->why);
            } else {
                fprintf(stderr, "%s: kinetic energy %.4g x the energy supplied, every step RBC_OK\n",
                        label, ratio);
                CHECK(!"energy bounded where every step returned RBC_OK");
            }
        } else if (strcmp(status, "clamped-reported") == 0) {
            /* Bounded because the library acted and said so (stats; the log). */
            CHECK(atol(r->field[c_clamped]) >= 1);
            ++clamped;
        } else {
            CHECK(strcmp(status, "ok") == 0);
            CHECK_EQ(atol(r->field[c_clamped]), 0);
        }
    }
    for (int j = 0; j < known_count; ++j)
        if (!known_rows[j].seen_growing)
            printf("listed as known but not growing now (remove it from the list?): %s = %s, %s\n",
                   known_rows[j].dimension, known_rows[j].value, known_rows[j].solver);

    /* The extremes this test is about, each for every solver. */
    static const char *const required[][2] = {
        {"k h^2/m", "1e+07"},
        {"dt (s) at k = 1000 N/m", "1e-5"},
        {"dt (s) at k = 1000 N/m", "1/30"},
        {"mass ratio", "1e+06"},
        {"start", "stretched 10x"},
        {"degenerate springs", "zero-length (2 coincident layers)"},
        {"degenerate springs", "coincident neighbours"},
        {"degenerate springs", "all particles at one point"},
        {"collider", "sphere 10 m/s at dt 2e-3"},
        {"pins", "pulled 3x apart"},
        {"size (particles)", "2x2"},
    };
    for (size_t q = 0; q < sizeof required / sizeof required[0]; ++q) {
        int found = 0;
        for (int i = 0; i < row_count; ++i)
            if (rows[i].count == h->count && strcmp(rows[i].field[c_dim], required[q][0]) == 0 &&
                strcmp(rows[i].field[c_val], required[q][1]) == 0)
                ++found;
        if (found != SOLVERS)
            fprintf(stderr, "case %s = %s: %d rows, expected %d\n", required[q][0], required[q][1],
                    found, SOLVERS);
        CHECK_EQ(found, SOLVERS);
    }
    printf("%d rows: %d unstable-reported (allowed), %d clamped-reported (allowed), %d known "
           "energy growth\n",
           row_count, unstable, clamped, growth_known);
    csv_free(&csv);
    free(list);
    return check_report("bench_stability");
}
