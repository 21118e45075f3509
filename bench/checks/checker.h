/* checker.h -- what the checkers of the benches' outputs (check_bench_*.c) do alike
 * beyond reading a CSV (csv.h): a main over DIR/FILE.csv, a row's fields, a page's
 * phrases. Static inline, so that each check counts in the checker that
 * includes it (check.h's counters are its own). */
#ifndef RBC_BENCH_CHECKER_H
#define RBC_BENCH_CHECKER_H
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "csv.h"
#include "text_file.h"

/// The main of a checker of one CSV: argv must be "checker DIR"; DIR/name is read and
/// its header compared with `header` (each a check), then `check` checks the rest of
/// DIR. Returns main's exit code: 2 after the usage, else check_report(report).
static inline int checker_main(int argc, char **argv, const char *name, const char *header,
                               const char *report,
                               void (*check)(const char *dir, const csv_file *csv)) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s DIR\n", argv[0]);
        return 2;
    }
    csv_file csv;
    int have_csv = csv_read_in(argv[1], name, &csv) == 0;
    CHECK(have_csv);
    if (have_csv) {
        CHECK(csv_header_is(&csv, header));
        check(argv[1], &csv);
    }
    csv_free(&csv);
    return check_report(report);
}

/// The fields of row i when it has `cols` of them (a check), else NULL.
static inline char **checker_fields(const csv_file *csv, int i, int cols) {
    const int count = csv->rows[i].count;
    CHECK_EQ(count, cols);
    return count == cols ? csv->rows[i].field : NULL;
}

/// The text of the page dir/name (a check that it can be read), with a check per
/// phrase that it holds it (stderr names a missing one). Returns the text, malloc'd,
/// or NULL.
static inline char *checker_page(const char *dir, const char *name, const char *const *phrases,
                                 size_t count) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    char *text = text_file_read(path);
    CHECK(text != NULL);
    if (!text) {
        fprintf(stderr, "cannot open %s\n", path);
        return NULL;
    }
    for (size_t k = 0; k < count; ++k) {
        if (!strstr(text, phrases[k]))
            fprintf(stderr, "%s has no '%s'\n", name, phrases[k]);
        CHECK(strstr(text, phrases[k]) != NULL);
    }
    return text;
}
#endif
