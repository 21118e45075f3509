/* csv.h -- the one CSV reader of the bench checkers (bench/checks/check_bench_*.c):
 * a file a bench wrote, read into its header and rows of fields, each row with the
 * line of the file it came from, for messages.
 *
 * The benches write plain CSV: no field is quoted or holds a comma or a newline, so
 * a line splits at every ','. Blank lines are passed over; the first other line is
 * the header, every later one a row (whatever its field count: the checkers compare
 * it with the header's).
 */
#ifndef RBC_BENCH_CSV_H
#define RBC_BENCH_CSV_H

typedef struct csv_row {
    /// The line of the file (1-based).
    int line;
    /// The fields, NUL-terminated, pointing into the file's text.
    int count;
    char **field;
} csv_row;

typedef struct csv_file {
    /// The path read (a copy), for messages.
    char *path;
    /// The header: its fields, and the line as written (count 0 and NULL when the
    /// file has no line but blank ones).
    csv_row header;
    char *header_text;
    /// The lines after the header.
    csv_row *rows;
    int row_count;
    /// What the fields point into.
    char *text;
    char **fields;
} csv_file;

/// Read `path`. Returns 0, or -1 after "cannot read PATH: why" on stderr; either
/// way csv_free(csv) is then safe.
int csv_read(const char *path, csv_file *csv);
/// csv_read of dir/name.
int csv_read_in(const char *dir, const char *name, csv_file *csv);
void csv_free(csv_file *csv);

/// 1 if the header line is exactly `expected`; otherwise 0 after printing both
/// (PATH:LINE) on stderr.
int csv_header_is(const csv_file *csv, const char *expected);
/// The index of the header's column `name`, or -1.
int csv_column(const csv_file *csv, const char *name);

#endif
