/* replay_main.c -- a plain main() for the fuzz targets: runs every file given, and
 * every file of every folder given (sorted by name, README files skipped), through
 * LLVMFuzzerTestOneInput once, in this process. Built with the normal compiler in
 * every build, so the seed corpora and the regression inputs (tests/fuzz/regress)
 * replay under `make test` and the sanitizer builds; a broken promise aborts, a bug
 * crashes (or is reported by the sanitizer) with the input's name on stderr first.
 *
 *   fuzz_scene_replay [--min N] FILE_OR_FOLDER...
 *
 * --min N: fail unless at least N inputs were run (a corpus that went missing is a
 * failure, not a vacuous pass). */
#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
__attribute__((weak)) int LLVMFuzzerInitialize(int *argc, char ***argv);

static unsigned long replayed;

static int run_file(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "replay: cannot open %s: %s\n", path, strerror(errno));
        return -1;
    }
    size_t cap = 4096, size = 0;
    uint8_t *data = malloc(cap);
    for (;;) {
        if (!data) {
            fclose(f);
            fprintf(stderr, "replay: out of memory reading %s\n", path);
            return -1;
        }
        size_t got = fread(data + size, 1, cap - size, f);
        size += got;
        if (size < cap) break;
        cap *= 2;
        uint8_t *grown = realloc(data, cap);
        if (!grown) free(data);
        data = grown;
    }
    fclose(f);
    fprintf(stderr, "replay: %s (%zu bytes)\n", path, size);
    /* libFuzzer never passes NULL; a zero-size input gets a valid pointer too. */
    LLVMFuzzerTestOneInput(data, size);
    free(data);
    replayed++;
    return 0;
}

/* The inputs of a folder: no hidden files, no README. */
static int is_input(const struct dirent *e) {
    return e->d_name[0] != '.' && strncmp(e->d_name, "README", 6) != 0;
}

/* By name, byte for byte (alphasort would follow the locale). */
static int cmp_names(const struct dirent **a, const struct dirent **b) {
    return strcmp((*a)->d_name, (*b)->d_name);
}

static int run_path(const char *path) {
    struct stat st;
    if (stat(path, &st) != 0) {
        fprintf(stderr, "replay: %s: %s\n", path, strerror(errno));
        return -1;
    }
    if (!S_ISDIR(st.st_mode)) return run_file(path);
    struct dirent **names = NULL;
    int n = scandir(path, &names, is_input, cmp_names);
    if (n < 0) {
        fprintf(stderr, "replay: cannot read folder %s: %s\n", path, strerror(errno));
        return -1;
    }
    int rc = 0;
    for (int i = 0; i < n; i++) {
        size_t len = strlen(path) + strlen(names[i]->d_name) + 2;
        char *full = malloc(len);
        if (full) {
            snprintf(full, len, "%s/%s", path, names[i]->d_name);
            struct stat fs;
            if (stat(full, &fs) == 0 && S_ISREG(fs.st_mode) && run_file(full) != 0) rc = -1;
            free(full);
        }
        free(names[i]);
    }
    free(names);
    return rc;
}

int main(int argc, char **argv) {
    unsigned long min = 0;
    int first = 1;
    if (argc > 2 && strcmp(argv[1], "--min") == 0) {
        min = strtoul(argv[2], NULL, 10);
        first = 3;
    }
    if (first >= argc) {
        fprintf(stderr, "usage: %s [--min N] FILE_OR_FOLDER...\n", argv[0]);
        return 2;
    }
    if (LLVMFuzzerInitialize) LLVMFuzzerInitialize(&argc, &argv);
    int rc = 0;
    for (int i = first; i < argc; i++)
        if (run_path(argv[i]) != 0) rc = 1;
    fprintf(stderr, "replay: %lu inputs run through %s\n", replayed, argv[0]);
    if (replayed < min) {
        fprintf(stderr, "replay: FAIL: expected at least %lu inputs\n", min);
        return 1;
    }
    return rc;
}
