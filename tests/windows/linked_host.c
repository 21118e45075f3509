/* linked_host.c -- a host LINKED to the library (rbcloth.dll through its import
 * library librbcloth.dll.a under mingw-w64, librbcloth.so natively), built for both
 * by tests/windows/run.sh: a 10x10 cloth pinned at two corners falls for 60 frames;
 * the positions must be finite, the pins exactly where they were, the rest moved,
 * and 1 and 2 solver threads must agree bit for bit (the pool's futex is
 * WaitOnAddress on Windows, a syscall on Linux). A bad call and mesh import must
 * fail as the header says. The positions and a PC2 cache are written to files so
 * run.sh can compare the Windows and the Linux build byte for byte.
 *
 *   linked_host POSITIONS_FILE PC2_FILE
 *
 * Prints TAP; exits 0 when every check passed. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rbcloth.h"

enum { N = 10, NV = N * N, NQ = (N - 1) * (N - 1), FRAMES = 60 };

static int failures, checks;

static void check(int ok, const char *what) {
    ++checks;
    if (!ok) ++failures;
    printf("%s %d - %s\n", ok ? "ok" : "not ok", checks, what);
    if (!ok) printf("# last error: %s\n", rbc_last_error());
}

static float rest[3 * NV];
static uint32_t quads[4 * NQ];
static const uint32_t pins[2] = {0, N - 1};

static void make_grid(void) {
    /* Horizontal, 0.1 m apart, 1 m up: exact in float (the same bits for every
     * compiler). */
    for (uint32_t j = 0; j < N; ++j)
        for (uint32_t i = 0; i < N; ++i) {
            float *p = &rest[3 * (j * N + i)];
            p[0] = (float)i * 0.1f;
            p[1] = 1.0f;
            p[2] = (float)j * 0.1f;
        }
    uint32_t q = 0;
    for (uint32_t j = 0; j + 1 < N; ++j)
        for (uint32_t i = 0; i + 1 < N; ++i, ++q) {
            uint32_t v = j * N + i;
            quads[4 * q + 0] = v;
            quads[4 * q + 1] = v + 1;
            quads[4 * q + 2] = v + N + 1;
            quads[4 * q + 3] = v + N;
        }
}

/* Run the scene with `threads` solver threads; its positions into out. 0 on
 * success. With keep_world, the world is left in *world_out for more checks. */
static int run_scene(uint32_t threads, float out[3 * NV], rbc_world_id *world_out) {
    /* The paper's fixed counts: the default solve (the target mode) picks its own
     * iteration counts from timing, which no two runs need to share. */
    rbc_solver_def solver;
    if (rbc_solver_def_preset(&solver, (uint32_t)sizeof solver, RBC_PRESET_PAPER) != RBC_OK)
        return -1;
    rbc_world_def wd = rbc_world_def_default();
    wd.solver = &solver;
    wd.thread_count = threads;
    rbc_world_id w = 0;
    if (rbc_world_create(&wd, &w) != RBC_OK) return -1;
    rbc_cloth_def cd = rbc_cloth_def_default();
    cd.vertex_count = NV;
    cd.positions = rest;
    cd.quad_count = NQ;
    cd.quads = quads;
    cd.pin_count = 2;
    cd.pins = pins;
    rbc_cloth_id c = 0;
    int rc = rbc_cloth_create(w, &cd, &c) != RBC_OK;
    for (int f = 0; !rc && f < FRAMES; ++f) rc = rbc_world_step(w, 1.0f / 60.0f) != RBC_OK;
    size_t written = 0;
    if (!rc) rc = rbc_cloth_read_positions(w, c, out, 3 * NV, &written) != RBC_OK;
    if (!rc) rc = written != 3 * NV;
    if (rc || !world_out) rbc_world_destroy(w);
    else *world_out = w;
    return rc ? -1 : 0;
}

static long file_size(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    long n = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
    fclose(f);
    return n;
}

/* A PC2 cache of `frames` frames (the positions shifted up a little each frame). */
static int write_cache(const char *path, const float *xyz, uint32_t frames) {
    rbc_cache_def d = rbc_cache_def_default();
    d.format = RBC_CACHE_PC2;
    d.path = path;
    d.point_count = NV;
    rbc_cache_id id = 0;
    if (rbc_cache_create(&d, &id) != RBC_OK) return -1;
    float frame[3 * NV];
    for (uint32_t k = 0; k < frames; ++k) {
        for (size_t i = 0; i < 3 * NV; ++i) frame[i] = xyz[i] + (i % 3 == 1 ? 0.01f * (float)k : 0.0f);
        if (rbc_cache_write_frame(id, frame) != RBC_OK) {
            rbc_cache_destroy(id);
            return -1;
        }
    }
    return rbc_cache_finish(id) == RBC_OK ? 0 : -1;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s POSITIONS_FILE PC2_FILE\n", argv[0]);
        return 2;
    }
    make_grid();
    check((rbc_abi_version() >> 16) == RBC_ABI_VERSION_MAJOR, "the library's ABI major is the header's");

    static float one[3 * NV], two[3 * NV];
    rbc_world_id w = 0;
    check(run_scene(1, one, NULL) == 0, "60 frames with 1 thread");
    check(run_scene(2, two, &w) == 0, "60 frames with 2 threads");
    check(memcmp(one, two, sizeof one) == 0, "1 and 2 threads give the same bits");

    int finite = 1, pinned = 1;
    float drop = 0.0f;
    for (size_t i = 0; i < 3 * NV; ++i) finite = finite && isfinite(two[i]);
    for (size_t k = 0; k < 2; ++k)
        pinned = pinned && memcmp(&two[3 * pins[k]], &rest[3 * pins[k]], 3 * sizeof(float)) == 0;
    for (size_t v = 0; v < NV; ++v)
        if (rest[3 * v + 1] - two[3 * v + 1] > drop) drop = rest[3 * v + 1] - two[3 * v + 1];
    check(finite, "every position is finite");
    check(pinned, "the pinned corners are exactly where they were");
    /* That it moved, not how far: 0.22 m natively; a grid spacing (0.1 m, less a
     * float's rounding) is far above any rounding and far below a second's fall. */
    printf("# largest drop %.6f m\n", (double)drop);
    check(drop > 0.09f, "the free cloth fell");

    if (w) {
        rbc_result r = rbc_world_step(w, -1.0f);
        check(r == RBC_ERR_INVALID_ARGUMENT, "rbc_world_step(w, -1) is RBC_ERR_INVALID_ARGUMENT");
        check(rbc_last_error()[0] != '\0', "... with a message");
        printf("# %s\n", rbc_last_error());
        rbc_world_destroy(w);
    }

    rbc_mesh_id mesh = 0;
    rbc_result r = rbc_mesh_import("no-such-cloth.obj", NULL, &mesh);
#if defined(_WIN32)
    check(r == RBC_ERR_UNSUPPORTED && mesh == 0, "rbc_mesh_import is RBC_ERR_UNSUPPORTED on Windows");
    check(strstr(rbc_last_error(), "not available in Windows builds") != NULL,
          "... with a message saying so");
#else
    /* Natively, import exists and the file is missing. */
    check(r == RBC_ERR_IO && mesh == 0, "rbc_mesh_import of a missing file is RBC_ERR_IO");
    check(rbc_last_error()[0] != '\0', "... with a message");
#endif
    printf("# %s\n", rbc_last_error());

    /* The cache twice to one path: the second must replace the first (Windows'
     * rename() refuses an existing target; the library uses MoveFileExA), and the
     * file is binary, 32 header bytes and 12 per point and frame ("wb": text mode
     * would turn every 0x0A byte of a float into two). */
    remove(argv[2]);
    check(write_cache(argv[2], two, 2) == 0, "a PC2 cache of 2 frames");
    check(file_size(argv[2]) == 32 + 2L * 12 * NV, "... of 32 + 2 * 12 * 100 bytes");
    check(write_cache(argv[2], two, 3) == 0, "a PC2 cache of 3 frames over it");
    check(file_size(argv[2]) == 32 + 3L * 12 * NV, "... replaced it (32 + 3 * 12 * 100 bytes)");

    FILE *f = fopen(argv[1], "wb");
    int ok = f && fwrite(two, sizeof two, 1, f) == 1;
    ok = f && fclose(f) == 0 && ok;
    check(ok, "the positions written");
    printf("1..%d\n", checks);
    return failures ? 1 : 0;
}
