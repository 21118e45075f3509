/* test_cache.c -- every point-cache format read back bit for bit.
 *
 * Known positions (awkward floats: -0, subnormals, 1/3, huge and tiny values) and a
 * real simulation's positions are written as PC2, MDD and an OBJ sequence; this
 * file's own readers (little-endian PC2, big-endian MDD, OBJ text parsed with
 * strtof) read them back and every float must have the same bits. Then bad input:
 * each refused with its code and nothing left on disk, and an abandoned or failed
 * cache leaves no temporary file.
 *
 * Usage: test_cache DIR (created; emptied of this test's files first)
 */
#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "abi_util.h"
#include "check.h"
#include "files.h"
#include "text_file.h"
#include "rbcloth.h"

static const char *g_dir;

/* g_dir/name (fmt's buffers: it stays valid for the next 15 paths). */
static const char *path_in(const char *name) { return fmt("%s/%s", g_dir, name); }

/* Files in g_dir whose name contains ".tmp". */
static int count_tmp_files(void) {
    DIR *d = opendir(g_dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) n += strstr(e->d_name, ".tmp") != NULL;
    closedir(d);
    return n;
}

static uint32_t le32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint32_t be32(const unsigned char *p) {
    return (uint32_t)p[3] | (uint32_t)p[2] << 8 | (uint32_t)p[1] << 16 | (uint32_t)p[0] << 24;
}
static uint32_t bits(float x) {
    uint32_t v;
    memcpy(&v, &x, 4);
    return v;
}
static float from_bits(uint32_t v) {
    float x;
    memcpy(&x, &v, 4);
    return x;
}

/* Compare frames[f][p][3] with what a reader produced; counts mismatching floats. */
static size_t mismatches(const float *expect, const float *got, size_t n) {
    size_t bad = 0;
    for (size_t k = 0; k < n; ++k) bad += bits(expect[k]) != bits(got[k]);
    return bad;
}

/* The file at path, if it could be read and has `expect` bytes (both checked); NULL
 * otherwise. */
static unsigned char *read_sized(const char *path, size_t expect) {
    size_t size = 0;
    unsigned char *b = file_read_bytes(path, &size);
    CHECK(b != NULL);
    if (!b) return NULL;
    CHECK_EQ(size, expect);
    if (size == expect) return b;
    free(b);
    return NULL;
}

/* The n floats at data, read by word (le32 or be32), against frames: no float differs. */
static void check_floats(const unsigned char *data, uint32_t (*word)(const unsigned char *),
                         const float *frames, size_t n) {
    float *got = malloc(n * sizeof *got);
    for (size_t k = 0; k < n; ++k) got[k] = from_bits(word(data + 4 * k));
    CHECK_EQ(mismatches(frames, got, n), 0);
    free(got);
}

/* PC2: "POINTCACHE2\0", version 1, points, start, rate, samples; little-endian. */
static void check_pc2(const char *path, const float *frames, uint32_t points, uint32_t count,
                      float start, float rate) {
    unsigned char *b = read_sized(path, 32 + (size_t)count * points * 12);
    if (!b) return;
    CHECK(memcmp(b, "POINTCACHE2\0", 12) == 0);
    CHECK_EQ(le32(b + 12), 1);
    CHECK_EQ(le32(b + 16), points);
    CHECK_EQ(le32(b + 20), bits(start));
    CHECK_EQ(le32(b + 24), bits(rate));
    CHECK_EQ(le32(b + 28), count);
    check_floats(b + 32, le32, frames, (size_t)count * points * 3);
    free(b);
}

/* MDD: frames, points, times[frames] in seconds at `fps` (what Blender's Mesh Cache
 * modifier plays in its TIME mode), positions; big-endian. */
static void check_mdd(const char *path, const float *frames, uint32_t points, uint32_t count,
                      float start, float rate, float fps) {
    unsigned char *b = read_sized(path, 8 + 4 * (size_t)count + (size_t)count * points * 12);
    if (!b) return;
    CHECK_EQ(be32(b), count);
    CHECK_EQ(be32(b + 4), points);
    for (uint32_t k = 0; k < count; ++k)
        CHECK_EQ(be32(b + 8 + 4 * k),
                 bits((float)(((double)start + (double)k * rate) / (double)fps)));
    check_floats(b + 8 + 4 * (size_t)count, be32, frames, (size_t)count * points * 3);
    free(b);
}

/* One OBJ: "v x y z" lines (strtof), "f a b c d" lines (1-based). */
static void check_obj(const char *path, const float *xyz, uint32_t points, const uint32_t *quads,
                      uint32_t quad_count) {
    size_t size = 0;
    char *text = (char *)file_read_bytes(path, &size);
    CHECK(text != NULL);
    if (!text) return;
    float *got = calloc(3 * (size_t)points + 3, sizeof *got);
    uint32_t nv = 0, nf = 0, bad_faces = 0;
    for (char *line = strtok(text, "\n"); line; line = strtok(NULL, "\n")) {
        if (line[0] == 'v' && line[1] == ' ') {
            char *p = line + 2;
            for (int k = 0; k < 3; ++k) {
                float v = strtof(p, &p);
                if (nv < points) got[3 * (size_t)nv + k] = v;
            }
            nv++;
        } else if (line[0] == 'f' && line[1] == ' ') {
            char *p = line + 2;
            for (int k = 0; k < 4; ++k) {
                unsigned long v = strtoul(p, &p, 10);
                if (nf >= quad_count || v != quads[4 * (size_t)nf + k] + 1ul) bad_faces++;
            }
            nf++;
        }
    }
    CHECK_EQ(nv, points);
    CHECK_EQ(nf, quad_count);
    CHECK_EQ(bad_faces, 0);
    CHECK_EQ(mismatches(xyz, got, 3 * (size_t)points), 0);
    free(got);
    free(text);
}

static char *objseq_frame(const char *prefix, uint32_t k) {
    static char buf[1100];
    snprintf(buf, sizeof buf, "%s_%04u.obj", prefix, k + 1);
    return buf;
}

/* Write frames with one format; RBC_OK expected all the way. */
static void write_cache(rbc_cache_format format, const char *path, const float *frames,
                        uint32_t points, uint32_t count, const uint32_t *quads,
                        uint32_t quad_count, float start, float rate, float fps) {
    rbc_cache_def d = rbc_cache_def_default();
    CHECK_EQ(d.frame_rate, 24.0f); /* Blender's default scene rate */
    if (fps > 0.0f) d.frame_rate = fps;
    d.format = format;
    d.path = path;
    d.point_count = points;
    d.start_frame = start;
    d.sample_rate = rate;
    d.quads = quads;
    d.quad_count = quad_count;
    rbc_cache_id c = 0;
    CHECK_EQ(rbc_cache_create(&d, &c), RBC_OK);
    for (uint32_t f = 0; f < count; ++f)
        CHECK_EQ(rbc_cache_write_frame(c, frames + 3 * (size_t)points * f), RBC_OK);
    /* Nothing visible before finish. */
    CHECK(!exists(format == RBC_CACHE_OBJ_SEQUENCE ? objseq_frame(path, 0) : path));
    CHECK_EQ(rbc_cache_finish(c), RBC_OK);
    CHECK_EQ(count_tmp_files(), 0);
}

static void check_all_formats(const char *stem, const float *frames, uint32_t points,
                              uint32_t count, const uint32_t *quads, uint32_t quad_count) {
    char name[256];
    snprintf(name, sizeof name, "%s.pc2", stem);
    const char *pc2 = path_in(name);
    snprintf(name, sizeof name, "%s.mdd", stem);
    const char *mdd = path_in(name);
    const char *seq = path_in(stem);
    write_cache(RBC_CACHE_PC2, pc2, frames, points, count, NULL, 0, 1.0f, 1.0f, 0.0f);
    check_pc2(pc2, frames, points, count, 1.0f, 1.0f);
    write_cache(RBC_CACHE_MDD, mdd, frames, points, count, NULL, 0, 0.5f, 0.25f, 0.0f);
    check_mdd(mdd, frames, points, count, 0.5f, 0.25f, 24.0f);
    snprintf(name, sizeof name, "%s_30fps.mdd", stem);
    const char *mdd30 = path_in(name);
    write_cache(RBC_CACHE_MDD, mdd30, frames, points, count, NULL, 0, 1.0f, 1.0f, 30.0f);
    check_mdd(mdd30, frames, points, count, 1.0f, 1.0f, 30.0f);
    write_cache(RBC_CACHE_OBJ_SEQUENCE, seq, frames, points, count, quads, quad_count, 0, 1, 0);
    for (uint32_t f = 0; f < count; ++f)
        check_obj(objseq_frame(seq, f), frames + 3 * (size_t)points * f, points, quads,
                  quad_count);
    CHECK(!exists(objseq_frame(seq, count))); /* exactly `count` files */
}

/* Awkward floats, 3 frames of 4 points, one quad. */
static void test_known_positions(void) {
    enum { POINTS = 4, FRAMES = 3 };
    float frames[FRAMES * POINTS * 3];
    const float special[] = {0.0f, -0.0f, 1.0f / 3.0f, FLT_MIN, FLT_MIN / 8.0f /* subnormal */,
                             FLT_MAX, -FLT_MAX, 1e-30f, 123456.789f, -2.5e-7f, 0.1f, 16777217.0f};
    uint32_t seed = 12345u;
    for (size_t k = 0; k < sizeof frames / sizeof frames[0]; ++k) {
        if (k < sizeof special / sizeof special[0]) {
            frames[k] = special[k];
        } else { /* random finite bit patterns */
            uint32_t v;
            do {
                seed = seed * 1664525u + 1013904223u;
                v = seed;
            } while (((v >> 23) & 0xFFu) == 0xFFu);
            frames[k] = from_bits(v);
        }
    }
    const uint32_t quads[] = {0, 1, 3, 2};
    check_all_formats("known", frames, POINTS, FRAMES, quads, 1);
}

/* The solver's positions: a 5 x 4 grid falling 6 frames with two pins. */
static void test_solver_positions(void) {
    enum { NX = 5, NY = 4, N = NX * NY, FRAMES = 6 };
    test_grid g = test_grid_make(NX, NY, 0.1f, 0.0f, 1.0f, 0.0f);
    const float *rest = g.positions;
    const uint32_t *quads = g.quads, nq = g.quad_count;
    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = 1;
    rbc_world_id w = test_world(&wd);
    const uint32_t pins[] = {0, NX - 1};
    rbc_cloth_def cd = test_grid_def(&g, pins, 2);
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create(w, &cd, &c), RBC_OK);
    float frames[FRAMES * 3 * N];
    for (uint32_t f = 0; f < FRAMES; ++f) {
        CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
        size_t written = 0;
        CHECK_EQ(rbc_cloth_read_positions(w, c, frames + 3 * (size_t)N * f, 3 * N, &written),
                 RBC_OK);
        CHECK_EQ(written, 3 * N);
    }
    rbc_world_destroy(w);
    /* The last frame moved (gravity), so the comparison is not of the rest pose. */
    CHECK(bits(frames[3 * N * (FRAMES - 1) + 3 * (N - 1) + 1]) != bits(rest[3 * (N - 1) + 1]));
    check_all_formats("solver", frames, N, FRAMES, quads, nq);
    /* The rest mesh as OBJ, in the input vertex order. */
    const char *obj = path_in("solver_rest.obj");
    CHECK_EQ(rbc_write_obj(obj, rest, N, quads, nq), RBC_OK);
    check_obj(obj, rest, N, quads, nq);
    test_grid_free(&g);
}

/* Bad input: its code, a message, nothing on disk. */
static void test_bad_input(void) {
    const float xyz[12] = {0};
    const uint32_t quad[4] = {0, 1, 2, 3}, bad_quad[4] = {0, 1, 2, 9};
    rbc_cache_id c = 0;
    rbc_cache_def d = rbc_cache_def_default();
    d.path = path_in("bad.pc2");
    d.point_count = 4;
    CHECK_EQ(rbc_cache_create(NULL, &c), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_cache_create(&d, NULL), RBC_ERR_INVALID_ARGUMENT);
    d.format = 7;
    CHECK_EQ(rbc_cache_create(&d, &c), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "format 7") != NULL);
    CHECK_EQ(c, 0);
    for (int f = RBC_CACHE_PC2; f <= RBC_CACHE_OBJ_SEQUENCE; ++f) {
        rbc_cache_def u = d;
        u.format = f;
        u.path = "/nonexistent-dir/sub/out";
        CHECK_EQ(rbc_cache_create(&u, &c), RBC_ERR_IO);
        CHECK(strstr(rbc_last_error(), "/nonexistent-dir/sub/out") != NULL);
        CHECK(strstr(rbc_last_error(), "No such file") != NULL);
        u.path = NULL;
        CHECK_EQ(rbc_cache_create(&u, &c), RBC_ERR_INVALID_ARGUMENT);
        u.path = path_in("bad");
        u.point_count = 0;
        CHECK_EQ(rbc_cache_create(&u, &c), RBC_ERR_INVALID_ARGUMENT);
    }
    d.format = RBC_CACHE_OBJ_SEQUENCE;
    d.path = path_in("badseq");
    d.quads = bad_quad;
    d.quad_count = 1;
    CHECK_EQ(rbc_cache_create(&d, &c), RBC_ERR_BAD_MESH);
    CHECK(strstr(rbc_last_error(), "quad 0 corner 3 is vertex 9") != NULL);
    d.quads = NULL;
    CHECK_EQ(rbc_cache_create(&d, &c), RBC_ERR_INVALID_ARGUMENT);
    /* An MDD needs a frame rate to store seconds: 0, negative, NaN, inf refused. */
    const float bad_fps[4] = {0.0f, -24.0f, NAN, INFINITY};
    for (int k = 0; k < 4; ++k) {
        rbc_cache_def u = rbc_cache_def_default();
        u.format = RBC_CACHE_MDD;
        u.path = path_in("badfps.mdd");
        u.point_count = 4;
        u.frame_rate = bad_fps[k];
        CHECK_EQ(rbc_cache_create(&u, &c), RBC_ERR_INVALID_ARGUMENT);
        CHECK(strstr(rbc_last_error(), "frame_rate") != NULL);
        CHECK_EQ(c, 0);
    }
    CHECK_EQ(count_tmp_files(), 0);
    CHECK(!exists(path_in("bad.pc2")) && !exists(path_in("badseq_0001.obj")));

    /* A 1.0-sized def (no quads) still works and writes a PC2. */
    rbc_cache_def old = rbc_cache_def_default();
    old.struct_size = RBC_CACHE_DEF_SIZE_V1_0;
    old.path = path_in("old.pc2");
    old.point_count = 4;
    CHECK_EQ(rbc_cache_create(&old, &c), RBC_OK);
    CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_OK);
    CHECK_EQ(rbc_cache_finish(c), RBC_OK);
    check_pc2(path_in("old.pc2"), xyz, 4, 1, 0.0f, 1.0f);
    /* A 1.2-1.8-sized def (no frame_rate) writes MDD times in seconds at 24 fps. */
    rbc_cache_def v12 = rbc_cache_def_default();
    v12.struct_size = RBC_CACHE_DEF_SIZE_V1_2;
    v12.format = RBC_CACHE_MDD;
    v12.path = path_in("v12.mdd");
    v12.point_count = 4;
    v12.start_frame = 1.0f;
    v12.frame_rate = -1.0f; /* beyond its size: must not be read */
    CHECK_EQ(rbc_cache_create(&v12, &c), RBC_OK);
    CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_OK);
    CHECK_EQ(rbc_cache_finish(c), RBC_OK);
    check_mdd(path_in("v12.mdd"), xyz, 4, 1, 1.0f, 1.0f, 24.0f);

    /* Abandoned caches of every format: no destination, no temporary file. */
    for (int f = RBC_CACHE_PC2; f <= RBC_CACHE_OBJ_SEQUENCE; ++f) {
        rbc_cache_def a = rbc_cache_def_default();
        a.format = f;
        a.path = path_in("abandoned");
        a.point_count = 4;
        a.quads = quad;
        a.quad_count = 1;
        CHECK_EQ(rbc_cache_create(&a, &c), RBC_OK);
        CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_OK);
        CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_OK);
        CHECK(count_tmp_files() > 0);
        CHECK_EQ(rbc_cache_destroy(c), RBC_OK);
        CHECK_EQ(count_tmp_files(), 0);
        CHECK(!exists(path_in("abandoned")) && !exists(path_in("abandoned_0001.obj")));
        CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_ERR_STALE_HANDLE);
    }

    /* A finish that cannot rename (a directory holds the name): RBC_ERR_IO, the
     * temporary files removed, the directory untouched. */
    for (int f = RBC_CACHE_PC2; f <= RBC_CACHE_OBJ_SEQUENCE; ++f) {
        const char *blocked = path_in("blocked");
        const char *dir = f == RBC_CACHE_OBJ_SEQUENCE ? path_in("blocked_0001.obj") : blocked;
        CHECK(mkdir(dir, 0755) == 0);
        rbc_cache_def a = rbc_cache_def_default();
        a.format = f;
        a.path = blocked;
        a.point_count = 4;
        CHECK_EQ(rbc_cache_create(&a, &c), RBC_OK);
        CHECK_EQ(rbc_cache_write_frame(c, xyz), RBC_OK);
        CHECK_EQ(rbc_cache_finish(c), RBC_ERR_IO);
        CHECK(strstr(rbc_last_error(), "blocked") != NULL);
        CHECK_EQ(count_tmp_files(), 0);
        CHECK(rmdir(dir) == 0);
    }
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: test_cache DIR\n");
        return 2;
    }
    g_dir = argv[1];
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", g_dir, g_dir);
    if (system(cmd) != 0) {
        fprintf(stderr, "test_cache: cannot create %s\n", g_dir);
        return 2;
    }
    test_known_positions();
    test_solver_positions();
    test_bad_input();
    return check_report("test_cache");
}
