/* import_cost.c -- what the import helper costs: rbc_mesh_import (a helper process
 * per import) against assimp alone in this process (the old in-process import
 * minus rbcloth's own steps), alternating, on the files given.
 *   import_cost [--runs N] FILE...
 * Prints CSV (file,run,helper_ms,in_process_ms), then per file the medians and
 * their difference: the spawn, assimp's library loading in a fresh process and the
 * mesh's copy over the socket, plus rbcloth's own conversion steps. */
#define _POSIX_C_SOURCE 200809L
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "rbcloth.h"

static double now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return 1e3 * (double)t.tv_sec + 1e-6 * (double)t.tv_nsec;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int main(int argc, char **argv) {
    int runs = 31, first = 1;
    if (argc > 2 && strcmp(argv[1], "--runs") == 0) runs = atoi(argv[2]), first = 3;
    if (first >= argc || runs < 1) {
        fprintf(stderr, "usage: %s [--runs N] FILE...\n", argv[0]);
        return 2;
    }
    double *a = malloc(sizeof *a * (size_t)runs), *b = malloc(sizeof *b * (size_t)runs);
    printf("file,run,helper_ms,in_process_ms\n");
    for (int f = first; f < argc; ++f) {
        for (int r = 0; r < runs; ++r) {
            double t0 = now_ms();
            rbc_mesh_id m = 0;
            rbc_result rc = rbc_mesh_import(argv[f], NULL, &m);
            a[r] = now_ms() - t0;
            if (rc) {
                fprintf(stderr, "import_cost: %s\n", rbc_last_error());
                return 1;
            }
            rbc_mesh_destroy(m);
            t0 = now_ms();
            const struct aiScene *s = aiImportFile(
                argv[f], aiProcess_JoinIdenticalVertices | aiProcess_ValidateDataStructure);
            b[r] = now_ms() - t0;
            if (s) aiReleaseImport(s);
            printf("%s,%d,%.3f,%.3f\n", argv[f], r, a[r], b[r]);
        }
        double ma = median(a, runs), mb = median(b, runs);
        fprintf(stderr, "%s: helper %.2f ms, in process %.2f ms (medians of %d, alternating); "
                "the helper adds %.2f ms\n", argv[f], ma, mb, runs, ma - mb);
    }
    free(a);
    free(b);
    return 0;
}
