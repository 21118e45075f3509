/* test_file_vertices.c -- the FBX and Collada vertex-list readers
 * (plugin/importer/file_vertices.h), built into this test from their sources.
 *
 *   test_file_vertices blender DIR   Blender's exports (tests/import/file_vertices/,
 *       made by make_fixtures.py): count, order and coordinates of each list equal
 *       Blender's mesh.vertices as exported (FBX exactly; Collada, which Blender
 *       writes with 7 significant digits, within 1e-6 relative) and as Blender's own
 *       importers make them again; the names; the declared unit and up axis; every
 *       position assimp gives (aiImportFile, no post-processing) is in the lists.
 *   test_file_vertices models DIR    assimp-testmodels' FBX (binary and ASCII) and
 *       Collada files: each read (or refused, for the files listed below, with a
 *       message), and every position assimp gives for it in its lists.
 *   test_file_vertices bad FIXDIR MODELSDIR STEP TMPDIR   broken input: every
 *       STEP-th prefix of a binary FBX (Blender's) and an ASCII FBX
 *       (assimp-testmodels'), every 7 STEP-th of a Collada file (Blender's), corrupt zlib, absurd
 *       array lengths, bad offsets, deep nesting, XML entities (XXE, billion laughs),
 *       other formats: -1 with a message (0 for other formats), never a crash; run
 *       under ASan/UBSan and valgrind as well (CMakeLists.txt). */
#define _XOPEN_SOURCE 700
#include <assimp/cimport.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "check.h"
#include "file_vertices.h"

/* ---- small helpers ---------------------------------------------------------- */

static unsigned char *slurp(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *d = malloc((size_t)len + 1);
    if (d && fread(d, 1, (size_t)len, f) != (size_t)len) {
        free(d);
        d = NULL;
    }
    fclose(f);
    *n = (size_t)len;
    return d;
}

static int spew(const char *path, const void *d, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    int ok = fwrite(d, 1, n, f) == n;
    return fclose(f) == 0 && ok;
}

typedef int (*reader_fn)(const char *, rbc_file_vertices *, char *, size_t);

/* A file's lists; also checks the contract on the way (out zeroed unless 1, a
 * message for -1, none for 0, list_start consistent). */
static int read_checked(reader_fn fn, const char *path, rbc_file_vertices *v, char *err, size_t cap) {
    memset(err, 'x', cap);
    err[cap - 1] = 0;
    int r = fn(path, v, err, cap);
    CHECK(r == 1 || r == 0 || r == -1);
    if (r == 1) {
        CHECK(v->xyz != NULL && v->list_start != NULL);
        CHECK(v->list_count == 0 || v->list_name != NULL);
        if (v->list_start) {
            CHECK_EQ(v->list_start[v->list_count], v->count);
            for (uint32_t i = 0; i < v->list_count; ++i) CHECK(v->list_start[i] <= v->list_start[i + 1]);
        }
        CHECK(v->up_axis >= -1 && v->up_axis <= 2);
    } else {
        static const rbc_file_vertices zero;
        CHECK(memcmp(v, &zero, sizeof zero) == 0);
        if (r == -1) {
            CHECK(err[0] && strlen(err) < cap && !strchr(err, '\n'));
        } else {
            CHECK(err[0] == 0);
        }
    }
    return r;
}

/* ---- the vertex text of make_fixtures.py -------------------------------------- */

typedef struct txt_mesh {
    char name[128];
    size_t n;
    double *xyz;
} txt_mesh;

static int read_txt(const char *path, txt_mesh *m, int cap) {
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    int k = 0;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        size_t n;
        char name[128];
        if (sscanf(line, "mesh %127s %zu", name, &n) == 2 && k < cap) {
            snprintf(m[k].name, sizeof m[k].name, "%s", name);
            m[k].n = n;
            m[k].xyz = malloc((n ? n : 1) * 3 * sizeof(double));
            for (size_t i = 0; i < n; ++i) {
                if (!fgets(line, sizeof line, f) ||
                    sscanf(line, "%lf %lf %lf", &m[k].xyz[3 * i], &m[k].xyz[3 * i + 1], &m[k].xyz[3 * i + 2]) != 3) {
                    fclose(f);
                    return -1;
                }
            }
            k++;
        }
    }
    fclose(f);
    return k;
}

static int list_named(const rbc_file_vertices *v, const char *name) {
    for (uint32_t i = 0; i < v->list_count; ++i)
        if (strcmp(v->list_name[i], name) == 0) return (int)i;
    return -1;
}

/* Largest |file - expected| / max(|expected|, abs_floor) over a mesh, in its order; -1 on
 * a count mismatch. */
static double list_vs_txt(const rbc_file_vertices *v, int li, const txt_mesh *m, double abs_floor) {
    uint32_t n = v->list_start[li + 1] - v->list_start[li];
    if (n != m->n) return -1;
    double worst = 0;
    const double *p = v->xyz + 3 * (size_t)v->list_start[li];
    for (size_t i = 0; i < 3 * m->n; ++i) {
        double d = fabs(p[i] - m->xyz[i]);
        double rel = d / fmax(fabs(m->xyz[i]), abs_floor);
        if (rel > worst) worst = rel;
    }
    return worst;
}

/* ---- assimp's positions in the lists ---------------------------------------- */

typedef struct vkey {
    double x, y, z;
} vkey;
static int cmp_vkey(const void *a, const void *b) {
    const vkey *p = a, *q = b;
    if (p->x != q->x) return p->x < q->x ? -1 : 1;
    if (p->y != q->y) return p->y < q->y ? -1 : 1;
    if (p->z != q->z) return p->z < q->z ? -1 : 1;
    return 0;
}

/* Every vertex of every aiMesh of the file (aiImportFile, no post-processing) is,
 * within tol (relative to max(1, |c|)), a vertex of the lists. Returns the number of
 * assimp vertices (-1 if assimp does not read the file), *missing those not found,
 * *worst the largest distance among the found. */
static long assimp_in_lists(const char *path, const rbc_file_vertices *v, double tol, long *missing,
                            double *worst) {
    *missing = 0;
    *worst = 0;
    const struct aiScene *s = aiImportFile(path, 0);
    if (!s) return -1;
    vkey *keys = malloc(((size_t)v->count + 1) * sizeof *keys);
    for (uint32_t i = 0; i < v->count; ++i) {
        keys[i].x = (float)v->xyz[3 * i];
        keys[i].y = (float)v->xyz[3 * i + 1];
        keys[i].z = (float)v->xyz[3 * i + 2];
    }
    qsort(keys, v->count, sizeof *keys, cmp_vkey);
    long total = 0;
    for (unsigned mi = 0; mi < s->mNumMeshes; ++mi) {
        const struct aiMesh *m = s->mMeshes[mi];
        for (unsigned i = 0; i < m->mNumVertices; ++i, ++total) {
            vkey k = {m->mVertices[i].x, m->mVertices[i].y, m->mVertices[i].z};
            if (v->count && bsearch(&k, keys, v->count, sizeof *keys, cmp_vkey)) continue;
            /* Not exact as float: the nearest within tol (ASCII numbers assimp parses
             * itself, with its own rounding). */
            double best = INFINITY;
            for (uint32_t j = 0; j < v->count; ++j) {
                double d = fmax(fabs(keys[j].x - k.x), fmax(fabs(keys[j].y - k.y), fabs(keys[j].z - k.z)));
                double sc = fmax(1.0, fmax(fabs(k.x), fmax(fabs(k.y), fabs(k.z))));
                if (d / sc < best) best = d / sc;
            }
            if (best <= tol) {
                if (best > *worst) *worst = best;
            } else {
                if (*missing < 3)
                    fprintf(stderr, "  %s: assimp vertex (%.9g %.9g %.9g) of mesh %u not in the lists "
                            "(nearest %.3g)\n", path, k.x, k.y, k.z, mi, best);
                (*missing)++;
            }
        }
    }
    free(keys);
    aiReleaseImport(s);
    return total;
}

/* ---- blender ---------------------------------------------------------------- */

static void check_against_txt(const rbc_file_vertices *v, const char *txt, double tol, double floor_,
                              const char *what) {
    txt_mesh m[8];
    int nm = read_txt(txt, m, 8);
    CHECK(nm >= 1);
    CHECK_EQ(nm, (int)v->list_count);
    for (int i = 0; i < nm; ++i) {
        int li = list_named(v, m[i].name);
        if (li < 0) {
            fprintf(stderr, "%s: no list named '%s'\n", what, m[i].name);
            CHECK(li >= 0);
        } else {
            double w = list_vs_txt(v, li, &m[i], floor_);
            fprintf(stderr, "%s: list '%s' %zu vertices in Blender's order, largest difference %.3g (bound %.3g) "
                    "from %s\n", what, m[i].name, m[i].n, w, tol, txt);
            CHECK(w >= 0 && w <= tol);
        }
        free(m[i].xyz);
    }
}

static int run_blender(const char *dir) {
    char path[1024], txt[1024], err[512];
    rbc_file_vertices v;
    long missing;
    double worst;

    /* FBX: Blender writes Vertices as float64 copies of its float32 coordinates;
     * make_fixtures.py writes the same float32 values with repr: exact. */
    snprintf(path, sizeof path, "%s/grid.fbx", dir);
    int r = read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err);
    if (r != 1) fprintf(stderr, "%s: %d %s\n", path, r, err);
    CHECK_EQ(r, 1);
    if (r == 1) {
        CHECK_EQ(v.count, 488);
        CHECK_EQ(v.list_count, 2);
        snprintf(txt, sizeof txt, "%s/grid_vertices.txt", dir);
        check_against_txt(&v, txt, 0.0, 1e-300, "grid.fbx");
        snprintf(txt, sizeof txt, "%s/grid_fbx_reimport.txt", dir);
        check_against_txt(&v, txt, 0.0, 1e-300, "grid.fbx vs Blender's FBX import");
        /* Blender 3.4, default apply_unit_scale: UnitScaleFactor 1 (a centimetre per
         * unit; the objects carry the x100), UpAxis 1 (Y, axis_up 'Y'). */
        CHECK_NEAR(v.unit_metres, 0.01, 0);
        CHECK_EQ(v.up_axis, 1);
        long n = assimp_in_lists(path, &v, 0.0, &missing, &worst);
        fprintf(stderr, "grid.fbx: assimp gives %ld vertices, %ld of them not in the file's lists\n", n, missing);
        CHECK(n > 488); /* one per face corner: the lists are what assimp does not keep */
        CHECK_EQ(missing, 0);
        rbc_file_vertices_free(&v);
    }
    CHECK_EQ(read_checked(rbc_dae_file_vertices, path, &v, err, sizeof err), 0);

    /* Collada: Blender 3.4 writes 7 significant digits ("-0.04761904", "0.0476191");
     * |file - Blender| <= 1e-6 max(|Blender|, 1) bounds that rounding (the grid's
     * coordinates are within [-1, 1]; near-zero ones are printed with exponents). */
    snprintf(path, sizeof path, "%s/grid.dae", dir);
    r = read_checked(rbc_dae_file_vertices, path, &v, err, sizeof err);
    if (r != 1) fprintf(stderr, "%s: %d %s\n", path, r, err);
    CHECK_EQ(r, 1);
    if (r == 1) {
        CHECK_EQ(v.count, 488);
        CHECK_EQ(v.list_count, 2);
        snprintf(txt, sizeof txt, "%s/grid_vertices.txt", dir);
        check_against_txt(&v, txt, 1e-6, 1.0, "grid.dae");
        snprintf(txt, sizeof txt, "%s/grid_dae_reimport.txt", dir);
        check_against_txt(&v, txt, 1e-6, 1.0, "grid.dae vs Blender's Collada import");
        CHECK_NEAR(v.unit_metres, 1.0, 0);
        CHECK_EQ(v.up_axis, 2);
        long n = assimp_in_lists(path, &v, 0.0, &missing, &worst);
        fprintf(stderr, "grid.dae: assimp gives %ld vertices, %ld of them not in the file's lists\n", n, missing);
        CHECK(n > 488);
        CHECK_EQ(missing, 0);
        rbc_file_vertices_free(&v);
    }
    CHECK_EQ(read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err), 0);
    return check_report("test_file_vertices");
}

/* ---- assimp-testmodels ------------------------------------------------------ */

typedef struct model_case {
    const char *file;
    int expect;          /* 1 read, -1 refused */
    const char *message; /* a part of the message, for -1 */
    int lists;           /* expected list count for 1, -1 unchecked */
    int assimp_exempt;   /* 1: assimp's positions are not the file's (placeholder meshes
                            it makes for cameras and lights); 2: assimp does not read it */
} model_case;

static const model_case k_models[] = {
    {"FBX/animation_with_skeleton.fbx", 1, NULL, 1, 0},
    {"FBX/box.fbx", 1, NULL, 1, 0},
    {"FBX/boxWithCompressedCTypeArray.FBX", 1, NULL, 1, 0},
    {"FBX/boxWithUncompressedCTypeArray.FBX", 1, NULL, 1, 0},
    {"FBX/box_orphant_embedded_texture.fbx", 1, NULL, 1, 0},
    {"FBX/close_to_identity_transforms.fbx", 1, NULL, 4, 0},
    {"FBX/cubes_nonames.fbx", 1, NULL, 4, 0},
    {"FBX/cubes_with_mirroring_and_pivot.fbx", 1, NULL, 4, 0},
    {"FBX/cubes_with_names.fbx", 1, NULL, 4, 0},
    {"FBX/cubes_with_outofrange_float.fbx", 1, NULL, 4, 0},
    {"FBX/global_settings.fbx", 1, NULL, 2, 0},
    {"FBX/huesitos.fbx", 1, NULL, 1, 0},
    {"FBX/maxPbrMaterial_metalRough.fbx", 1, NULL, 1, 0},
    {"FBX/maxPbrMaterial_specGloss.fbx", 1, NULL, 1, 0},
    {"FBX/phong_cube.fbx", 1, NULL, 1, 0},
    {"FBX/spider.fbx", 1, NULL, 19, 0},
    /* Every 0x00 byte turned into 0x20 (a text-mode transfer): no reader can. */
    {"FBX/transparentTest.fbx", -1, "binary header damaged", -1, 0},
    {"FBX/embedded_ascii/box.FBX", 1, NULL, 1, 0},
    {"FBX/embedded_ascii/box_embedded_texture_fragmented.fbx", 1, NULL, 1, 0},
    {"Collada/AsXML.xml", 1, NULL, 1, 0},
    {"Collada/COLLADA.dae", 1, NULL, 2, 0},
    {"Collada/COLLADA_triangulate.dae", 1, NULL, 2, 0},
    {"Collada/Cinema4D.dae", 1, NULL, 3, 0},
    {"Collada/ConcavePolygon.dae", 1, NULL, 1, 0},
    {"Collada/anims_with_full_rotations_between_keys.DAE", 1, NULL, 64, 0},
    {"Collada/box_nested_animation.dae", 1, NULL, 1, 0},
    {"Collada/cameras.dae", 1, NULL, 0, 1},
    {"Collada/cube_UTF16LE.dae", 1, NULL, 1, 2},
    {"Collada/cube_UTF8BOM.dae", 1, NULL, 1, 0},
    {"Collada/cube_emptyTags.dae", 1, NULL, 1, 0},
    {"Collada/cube_triangulate.dae", 1, NULL, 1, 0},
    {"Collada/cube_tristrips.dae", 1, NULL, 1, 0},
    {"Collada/cube_with_2UVs.DAE", 1, NULL, 1, 0},
    {"Collada/cube_xmlspecialchars.dae", 1, NULL, 1, 0},
    {"Collada/duck.dae", 1, NULL, 1, 0},
    {"Collada/duck_triangulate.dae", 1, NULL, 1, 0},
    {"Collada/kwxport_test_vcolors.dae", 1, NULL, 1, 0},
    {"Collada/library_animation_clips.dae", 1, NULL, 1, 2},
    {"Collada/lights.dae", 1, NULL, 0, 1},
    {"Collada/regr01.dae", 1, NULL, 1, 0},
    {"Collada/sphere.dae", 1, NULL, 1, 0},
    {"Collada/sphere_triangulate.dae", 1, NULL, 1, 0},
    {"Collada/teapot_instancenodes.DAE", 1, NULL, 1, 0},
    /* Decimal commas ("21,920870", a 3ds Max exporter under some locale), which
     * assimp reads as points. */
    {"Collada/earthCylindrical.DAE", 1, NULL, 2, 0},
    {"Collada/teapots.DAE", 1, NULL, 3, 0},
};

static int run_models(const char *dir) {
    char path[1024], err[512];
    for (size_t i = 0; i < sizeof k_models / sizeof k_models[0]; ++i) {
        const model_case *mc = &k_models[i];
        snprintf(path, sizeof path, "%s/%s", dir, mc->file);
        int is_fbx = strncmp(mc->file, "FBX/", 4) == 0;
        rbc_file_vertices v;
        clock_t t0 = clock();
        int r = read_checked(is_fbx ? rbc_fbx_file_vertices : rbc_dae_file_vertices, path, &v, err, sizeof err);
        double ms = 1e3 * (double)(clock() - t0) / CLOCKS_PER_SEC;
        if (r != mc->expect) fprintf(stderr, "%s: returned %d (%s), expected %d\n", mc->file, r, err, mc->expect);
        CHECK_EQ(r, mc->expect);
        /* The other reader says "not mine". */
        rbc_file_vertices w;
        char err2[256];
        CHECK_EQ(read_checked(is_fbx ? rbc_dae_file_vertices : rbc_fbx_file_vertices, path, &w, err2, sizeof err2), 0);
        if (r == -1) {
            fprintf(stderr, "%s: refused: %s\n", mc->file, err);
            if (mc->message) CHECK(strstr(err, mc->message) != NULL);
            continue;
        }
        if (r != 1) continue;
        if (mc->lists >= 0) CHECK_EQ(v.list_count, mc->lists);
        long missing;
        double worst;
        /* Binary FBX: assimp's floats are the file's values rounded to float, exact.
         * ASCII FBX and Collada: assimp parses the text itself (fast_atoreal_move),
         * within a few float ulps of strtod's value: 2e-6 relative. */
        long n = assimp_in_lists(path, &v, 2e-6, &missing, &worst);
        fprintf(stderr, "%s: %u vertices in %u lists (unit %g m, up %d) in %.1f ms; assimp %ld vertices, "
                "%ld not in the lists, worst %.2g\n", mc->file, v.count, v.list_count, v.unit_metres, v.up_axis,
                ms, n, missing, worst);
        if (mc->assimp_exempt == 0) {
            CHECK(n >= 0);
            CHECK_EQ(missing, 0);
        } else if (mc->assimp_exempt == 2) {
            CHECK(n < 0);
        }
        rbc_file_vertices_free(&v);
    }
    return check_report("test_file_vertices");
}

/* ---- bad input -------------------------------------------------------------- */

/* The offset of a binary node named name (its name-length byte). */
static size_t find_node(const unsigned char *d, size_t n, const char *name) {
    size_t l = strlen(name);
    for (size_t i = 13; i + 1 + l < n; ++i)
        if (d[i] == l && memcmp(d + i + 1, name, l) == 0) return i;
    return 0;
}

static void expect_fail(reader_fn fn, const char *path, const char *what, const char *needle) {
    rbc_file_vertices v;
    char err[512];
    int r = read_checked(fn, path, &v, err, sizeof err);
    if (r != -1 || (needle && !strstr(err, needle)))
        fprintf(stderr, "%s: returned %d, message '%s' (wanted -1 and '%s')\n", what, r, err,
                needle ? needle : "");
    else
        fprintf(stderr, "%s: -1: %s\n", what, err);
    CHECK_EQ(r, -1);
    if (needle) CHECK(strstr(err, needle) != NULL);
    rbc_file_vertices_free(&v);
}

/* Every step-th prefix of a file (every one of the first 64): -1 (or 0 before the
 * format shows), never a crash; one that reads (1) reads like the whole file. With
 * tail_ok (binary FBX, XML: the end is marked), the shortest prefix that reads is
 * within tail_ok bytes of the end and every longer one reads too; ASCII FBX has no end
 * mark: a prefix cut between two top-level scopes after Objects reads. */
static void prefixes(reader_fn fn, const char *src, const char *tmp, size_t step, size_t tail_ok) {
    size_t n;
    unsigned char *d = slurp(src, &n);
    CHECK(d != NULL);
    if (!d) return;
    char path[1024], err[512];
    snprintf(path, sizeof path, "%s/prefix.bin", tmp);
    rbc_file_vertices full;
    CHECK_EQ(read_checked(fn, src, &full, err, sizeof err), 1);
    size_t first_ok = n, tried = 0, zeros = 0, fails = 0;
    int bad = 0;
    for (size_t len = 0; len < n; len += (len < 64 ? 1 : step)) {
        spew(path, d, len);
        rbc_file_vertices v;
        int r = read_checked(fn, path, &v, err, sizeof err);
        tried++;
        if (r == 1) {
            if (len < first_ok) first_ok = len;
            if (v.count != full.count || memcmp(v.xyz, full.xyz, 3 * sizeof(double) * v.count) != 0) bad++;
        } else if (r == 0) {
            zeros++;
            if (len > 64) bad++;
        } else {
            fails++;
            if (tail_ok && len > first_ok) bad++; /* once complete, stays complete */
        }
        rbc_file_vertices_free(&v);
    }
    fprintf(stderr, "%s: %zu prefixes of %zu bytes: %zu refused, %zu 'not this format' (first 64 bytes), "
            "%zu read, the first of them %zu bytes long\n", src, tried, n, fails, zeros, tried - fails - zeros,
            first_ok);
    CHECK_EQ(bad, 0);
    if (tail_ok) CHECK(first_ok + tail_ok >= n);
    rbc_file_vertices_free(&full);
    free(d);
}

static void put32(unsigned char *p, uint32_t v) {
    p[0] = v & 255;
    p[1] = v >> 8 & 255;
    p[2] = v >> 16 & 255;
    p[3] = v >> 24;
}

/* A binary FBX 7400 of depth nested empty nodes "N", then the end record. */
static size_t deep_fbx(unsigned char *buf, int depth) {
    memcpy(buf, "Kaydara FBX Binary  \0\x1a\0", 23);
    put32(buf + 23, 7400);
    size_t node = 13 + 1; /* header + name "N" */
    size_t total = 27 + (size_t)depth * (node + 13) + 13;
    for (int i = 0; i < depth; ++i) {
        unsigned char *p = buf + 27 + (size_t)i * node;
        size_t end = 27 + (size_t)depth * node + (size_t)(depth - i) * 13;
        put32(p, (uint32_t)end);
        put32(p + 4, 0);
        put32(p + 8, 0);
        p[12] = 1;
        p[13] = 'N';
    }
    memset(buf + 27 + (size_t)depth * node, 0, (size_t)depth * 13 + 13);
    return total;
}

static int run_bad(const char *fix, const char *models, const char *tmp, size_t step) {
    char src[1024], path[1024], ascii[1024], dae[1024];
    size_t n;
    snprintf(src, sizeof src, "%s/grid.fbx", fix);
    snprintf(dae, sizeof dae, "%s/grid.dae", fix);
    snprintf(ascii, sizeof ascii, "%s/FBX/box_orphant_embedded_texture.fbx", models);
    snprintf(path, sizeof path, "%s/bad.fbx", tmp);

    /* Truncations. */
    prefixes(rbc_fbx_file_vertices, src, tmp, step, 200); /* the footer: ~180 bytes */
    char v7500[1024];
    snprintf(v7500, sizeof v7500, "%s/FBX/boxWithCompressedCTypeArray.FBX", models);
    prefixes(rbc_fbx_file_vertices, v7500, tmp, step, 200); /* 64-bit offsets */
    prefixes(rbc_fbx_file_vertices, ascii, tmp, step, 0);
    prefixes(rbc_dae_file_vertices, dae, tmp, step * 7, 2);

    unsigned char *d = slurp(src, &n);
    CHECK(d != NULL);
    if (!d) return check_report("test_file_vertices");
    unsigned char *b = malloc(n);
    size_t vn = find_node(d, n, "Vertices");
    CHECK(vn > 0);
    size_t pp = vn + 1 + 8; /* the Vertices' first property */
    CHECK(d[pp] == 'd');
    uint32_t enc = d[pp + 5] | d[pp + 6] << 8, clen = d[pp + 9] | d[pp + 10] << 8 | d[pp + 11] << 16;
    fprintf(stderr, "grid.fbx: Vertices array at byte %zu, encoding %u, %u bytes\n", pp, enc, clen);
    CHECK_EQ(enc, 1); /* Blender compresses arrays over 128 bytes */

    /* Corrupt zlib data. */
    memcpy(b, d, n);
    for (size_t i = 0; i < 16; ++i) b[pp + 13 + clen / 2 + i] ^= 0x5a;
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "corrupt zlib", "zlib");
    memcpy(b, d, n);
    b[pp + 13] ^= 0xff; /* the zlib header */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "bad zlib header", "zlib");
    memcpy(b, d, n);
    b[pp + 13 + clen - 1] ^= 0x01; /* the adler32 */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "bad adler32", "zlib");

    /* Absurd lengths. */
    memcpy(b, d, n);
    put32(b + pp + 1, 0x7fffffffu); /* element count, zlib */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "absurd element count (zlib)", "absurd");
    memcpy(b, d, n);
    put32(b + pp + 1, 1452 * 2); /* plausible but wrong: decompresses short */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "wrong element count (zlib)", "zlib");
    memcpy(b, d, n);
    put32(b + pp + 5, 0); /* raw, but the bytes are not count x 8 */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "raw array of the wrong length", "values of 8 bytes");
    memcpy(b, d, n);
    put32(b + pp + 5, 7);
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "unknown encoding", "encoding");
    memcpy(b, d, n);
    put32(b + pp + 9, 0xfffffff0u); /* byte length */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "absurd byte length", "truncated");
    memcpy(b, d, n);
    put32(b + pp + 1, 1451); /* not a multiple of 3 */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "count not a multiple of 3", NULL);
    memcpy(b, d, n);
    put32(b + vn - 12, 0xffffff00u); /* the Vertices node's end offset */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "node end past the file", "past the end of the file");
    memcpy(b, d, n);
    put32(b + vn - 12, (uint32_t)vn); /* ends before its name */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "node end before its name", NULL);
    memcpy(b, d, n);
    put32(b + vn - 4, 0xfffffff0u); /* property list length */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "absurd property list length", NULL);
    memcpy(b, d, n);
    put32(b + vn - 8, 0xfffffff0u); /* property count */
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "absurd property count", NULL);
    memcpy(b, d, n);
    b[pp] = 'Q';
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "unknown property type", "unknown type");
    memcpy(b, d, n);
    memcpy(b + 20, "\r\n\x1a", 3);
    spew(path, b, n);
    expect_fail(rbc_fbx_file_vertices, path, "damaged magic", "header");

    /* A name that is not UTF-8 comes back as UTF-8. */
    memcpy(b, d, n);
    {
        static const char nm[] = "ClothGrid\0\1Geometry";
        unsigned char *at = NULL;
        for (size_t i = 0; i + sizeof nm - 1 <= n && !at; ++i)
            if (memcmp(d + i, nm, sizeof nm - 1) == 0) at = b + i;
        CHECK(at != NULL);
        if (at) {
            at[0] = 0xff;
            at[5] = 0xc3; /* a lead byte without its continuation */
            spew(path, b, n);
            rbc_file_vertices v;
            char err[512];
            CHECK_EQ(read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err), 1);
            int li = list_named(&v, "?loth?rid");
            CHECK(li >= 0);
            rbc_file_vertices_free(&v);
        }
    }

    /* Random byte damage: never a crash; any result. */
    unsigned seed = 12345;
    for (int t = 0; t < 300; ++t) {
        memcpy(b, d, n);
        for (int k = 0; k < 4; ++k) {
            seed = seed * 1103515245u + 12345u;
            size_t at = 27 + (seed >> 8) % (n - 27);
            seed = seed * 1103515245u + 12345u;
            b[at] = (unsigned char)(seed >> 16);
        }
        spew(path, b, n);
        rbc_file_vertices v;
        char err[512];
        read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err);
        rbc_file_vertices_free(&v);
    }
    free(b);
    free(d);

    /* Deep nesting: binary, ASCII, XML. */
    unsigned char *deep = malloc(27 + 10000 * 27 + 13);
    size_t dn = deep_fbx(deep, 60);
    spew(path, deep, dn);
    {
        rbc_file_vertices v;
        char err[512];
        int r = read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err);
        if (r != 1) fprintf(stderr, "60 nested nodes: %d %s\n", r, err);
        CHECK_EQ(r, 1); /* deep but allowed: no Geometry, no lists */
        CHECK_EQ(v.list_count, 0);
        rbc_file_vertices_free(&v);
    }
    dn = deep_fbx(deep, 10000);
    spew(path, deep, dn);
    expect_fail(rbc_fbx_file_vertices, path, "10000 nested binary nodes", "deeper");
    free(deep);
    {
        size_t cap = 64 + 100000 * 6;
        char *t = malloc(cap), *p = t;
        p += sprintf(p, "; FBX 7.4.0 project file\n");
        for (int i = 0; i < 100000; ++i) p += sprintf(p, "A: {");
        spew(path, t, (size_t)(p - t));
        expect_fail(rbc_fbx_file_vertices, path, "100000 nested ASCII scopes", "deeper");
        free(t);
    }
    snprintf(path, sizeof path, "%s/bad.dae", tmp);
    {
        size_t cap = 128 + 100000 * 8;
        char *t = malloc(cap), *p = t;
        p += sprintf(p, "<?xml version=\"1.0\"?>\n<COLLADA>");
        for (int i = 0; i < 100000; ++i) p += sprintf(p, "<a>");
        spew(path, t, (size_t)(p - t));
        expect_fail(rbc_dae_file_vertices, path, "100000 nested XML elements", NULL);
        free(t);
    }

    /* XML entities: an external one (XXE) is never read, internal ones refused. */
    char secret[1024];
    snprintf(secret, sizeof secret, "%s/secret.txt", tmp);
    spew(secret, "1 2 3", 5);
    static const char geo[] =
        "<library_geometries><geometry id=\"g\" name=\"G\"><mesh>"
        "<source id=\"p\"><float_array id=\"pa\" count=\"3\">%s</float_array>"
        "<technique_common><accessor source=\"#pa\" count=\"1\" stride=\"3\">"
        "<param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/>"
        "</accessor></technique_common></source>"
        "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#p\"/></vertices>"
        "</mesh></geometry></library_geometries></COLLADA>\n";
    char doc[4096], body[2048];
    snprintf(body, sizeof body, geo, "&xxe;");
    snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<!DOCTYPE COLLADA [<!ENTITY xxe SYSTEM \"file://%s\">]>\n"
             "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">%s", secret, body);
    spew(path, doc, strlen(doc));
    expect_fail(rbc_dae_file_vertices, path, "external entity (XXE, file)", "entities");
    snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<!DOCTYPE COLLADA [<!ENTITY xxe SYSTEM \"http://127.0.0.1:9/x\">]>\n"
             "<COLLADA>%s", body);
    spew(path, doc, strlen(doc));
    expect_fail(rbc_dae_file_vertices, path, "external entity (XXE, http)", NULL);
    {
        char *t = malloc(8192), *p = t;
        p += sprintf(p, "<?xml version=\"1.0\"?>\n<!DOCTYPE COLLADA [<!ENTITY l0 \"1 \">");
        for (int i = 1; i < 12; ++i)
            p += sprintf(p, "<!ENTITY l%d \"&l%d;&l%d;&l%d;&l%d;&l%d;&l%d;&l%d;&l%d;&l%d;&l%d;\">", i, i - 1, i - 1,
                         i - 1, i - 1, i - 1, i - 1, i - 1, i - 1, i - 1, i - 1);
        p += sprintf(p, "]>\n<COLLADA>");
        p += sprintf(p, geo, "&l11;");
        spew(path, t, (size_t)(p - t));
        clock_t t0 = clock();
        expect_fail(rbc_dae_file_vertices, path, "billion laughs", NULL);
        double s = (double)(clock() - t0) / CLOCKS_PER_SEC;
        fprintf(stderr, "billion laughs: %.3f s\n", s);
        CHECK(s < 5);
        free(t);
    }
    /* The document itself without entities reads. */
    snprintf(body, sizeof body, geo, "1 2 3");
    snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<COLLADA>%s", body);
    spew(path, doc, strlen(doc));
    {
        rbc_file_vertices v;
        char err[512];
        CHECK_EQ(read_checked(rbc_dae_file_vertices, path, &v, err, sizeof err), 1);
        CHECK_EQ(v.count, 1);
        if (v.count == 1) CHECK(v.xyz[0] == 1 && v.xyz[1] == 2 && v.xyz[2] == 3);
        CHECK_EQ(v.up_axis, -1);
        CHECK_NEAR(v.unit_metres, 0, 0);
        rbc_file_vertices_free(&v);
    }
    /* Collada accessors that read past their array, bad references. */
    static const char *bad_geo[][2] = {
        {"count=\"2\" stride=\"3\"", "past"},
        {"count=\"1\" stride=\"3\" offset=\"1\"", "past"},
        {"count=\"18446744073709551615\" stride=\"3\"", "past"},
        {"count=\"2\" stride=\"18446744073709551615\"", "past"},
        {"count=\"1\" stride=\"2\"", "stride"},
        {"count=\"-1\" stride=\"3\"", "count"},
        {"count=\"1\" stride=\"0\"", "stride"},
    };
    for (size_t i = 0; i < sizeof bad_geo / sizeof bad_geo[0]; ++i) {
        char g2[2048];
        snprintf(g2, sizeof g2, "%s", geo);
        char *a = strstr(g2, "count=\"1\" stride=\"3\"");
        char rest[2048];
        snprintf(rest, sizeof rest, "%s", a + strlen("count=\"1\" stride=\"3\""));
        snprintf(a, sizeof g2 - (size_t)(a - g2), "%s%s", bad_geo[i][0], rest);
        snprintf(body, sizeof body, g2, "1 2 3");
        snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<COLLADA>%s", body);
        spew(path, doc, strlen(doc));
        expect_fail(rbc_dae_file_vertices, path, bad_geo[i][0], bad_geo[i][1]);
    }
    snprintf(body, sizeof body, geo, "1 2 x");
    snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<COLLADA>%s", body);
    spew(path, doc, strlen(doc));
    expect_fail(rbc_dae_file_vertices, path, "a float_array value that is not a number", "not a number");
    {
        char g2[2048];
        snprintf(g2, sizeof g2, "%s", geo);
        char *a = strstr(g2, "source=\"#p\"");
        memcpy(a, "source=\"#q\"", 11);
        snprintf(body, sizeof body, g2, "1 2 3");
        snprintf(doc, sizeof doc, "<?xml version=\"1.0\"?>\n<COLLADA>%s", body);
        spew(path, doc, strlen(doc));
        expect_fail(rbc_dae_file_vertices, path, "a POSITION source that does not exist", "not found");
    }

    /* FBX 6.1 ASCII (none among assimp-testmodels; assimp 5.2.5 does not read 6.x):
     * Objects/Model "Mesh" with its own Vertices across lines, GlobalSettings
     * inside Objects with Properties60. */
    snprintf(path, sizeof path, "%s/fbx61.fbx", tmp);
    static const char fbx61[] =
        "; FBX 6.1.0 project file\n; ----\n\nFBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n"
        "\tFBXVersion: 6100\n}\nDefinitions:  {\n\tVersion: 100\n\tObjectType: \"Model\" {\n\t\tCount: 1\n\t}\n}\n"
        "Objects:  {\n\tModel: \"Model::Plane\", \"Mesh\" {\n\t\tVersion: 232\n\t\tProperties60:  {\n"
        "\t\t\tProperty: \"Lcl Scaling\", \"Lcl Scaling\", \"A+\",2.0,2.0,2.0\n\t\t}\n\t\tShading: Y\n"
        "\t\tVertices: 1.000000,1.000000,0.250000,1.000000,-1.000000,0.000000,-1.000000,-1.000000,0.000000,\n"
        "-1.000000,1.000000,0.125000\n\t\tPolygonVertexIndex: 0,3,2,-2\n\t\tGeometryVersion: 124\n\t}\n"
        "\tModel: \"Model::Camera\", \"Camera\" {\n\t\tVersion: 232\n\t}\n"
        "\tGlobalSettings:  {\n\t\tVersion: 1000\n\t\tProperties60:  {\n"
        "\t\t\tProperty: \"UpAxis\", \"int\", \"\",2\n\t\t\tProperty: \"UnitScaleFactor\", \"double\", \"\",2.54\n"
        "\t\t}\n\t}\n}\nConnections:  {\n\tConnect: \"OO\", \"Model::Plane\", \"Model::Scene\"\n}\n";
    spew(path, fbx61, strlen(fbx61));
    {
        rbc_file_vertices v;
        char err[512];
        int r = read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err);
        if (r != 1) fprintf(stderr, "FBX 6.1 ASCII: %d %s\n", r, err);
        CHECK_EQ(r, 1);
        if (r == 1) {
            static const double want[12] = {1, 1, 0.25, 1, -1, 0, -1, -1, 0, -1, 1, 0.125};
            CHECK_EQ(v.count, 4);
            CHECK_EQ(v.list_count, 1);
            CHECK(v.count == 4 && memcmp(v.xyz, want, sizeof want) == 0);
            CHECK(v.list_count == 1 && strcmp(v.list_name[0], "Plane") == 0);
            CHECK_NEAR(v.unit_metres, 0.0254, 1e-15);
            CHECK_EQ(v.up_axis, 2);
            fprintf(stderr, "FBX 6.1 ASCII: 4 vertices of 'Plane', unit %g m, up %d\n", v.unit_metres, v.up_axis);
        }
        rbc_file_vertices_free(&v);
    }
    /* FBX 7 ASCII whose *N disagrees with its a: values, and a value that is not a
     * number. */
    static const char fbx7[] =
        "; FBX 7.4.0 project file\nObjects:  {\n\tGeometry: 1, \"Geometry::G\", \"Mesh\" {\n"
        "\t\tVertices: *%s {\n\t\t\ta: %s\n\t\t}\n\t}\n}\n";
    char txt7[1024];
    snprintf(txt7, sizeof txt7, fbx7, "6", "0,1,2,3,4,5");
    spew(path, txt7, strlen(txt7));
    {
        rbc_file_vertices v;
        char err[512];
        CHECK_EQ(read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err), 1);
        CHECK(v.count == 2 && v.xyz[5] == 5 && strcmp(v.list_name[0], "G") == 0);
        CHECK_EQ(v.up_axis, -1);
        CHECK_NEAR(v.unit_metres, 0, 0);
        rbc_file_vertices_free(&v);
    }
    snprintf(txt7, sizeof txt7, fbx7, "9", "0,1,2,3,4,5");
    spew(path, txt7, strlen(txt7));
    expect_fail(rbc_fbx_file_vertices, path, "ASCII *N disagreeing", "declares *9");
    snprintf(txt7, sizeof txt7, fbx7, "6", "0,1,2,3,4,5x");
    spew(path, txt7, strlen(txt7));
    expect_fail(rbc_fbx_file_vertices, path, "ASCII value not a number", "not a number");
    snprintf(txt7, sizeof txt7, fbx7, "4", "0,1,2,3");
    spew(path, txt7, strlen(txt7));
    expect_fail(rbc_fbx_file_vertices, path, "ASCII count not a multiple of 3", "multiple of 3");
    snprintf(txt7, sizeof txt7, fbx7, "6\"", "0,1,2,3,4,5");
    spew(path, txt7, strlen(txt7));
    expect_fail(rbc_fbx_file_vertices, path, "ASCII unterminated string", NULL);

    /* Other formats, empty and missing files. */
    snprintf(path, sizeof path, "%s/empty", tmp);
    spew(path, "", 0);
    rbc_file_vertices v;
    char err[512];
    CHECK_EQ(read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err), 0);
    CHECK_EQ(read_checked(rbc_dae_file_vertices, path, &v, err, sizeof err), 0);
    snprintf(path, sizeof path, "%s/box.obj", tmp);
    spew(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 32);
    CHECK_EQ(read_checked(rbc_fbx_file_vertices, path, &v, err, sizeof err), 0);
    CHECK_EQ(read_checked(rbc_dae_file_vertices, path, &v, err, sizeof err), 0);
    snprintf(path, sizeof path, "%s/not-there.fbx", tmp);
    expect_fail(rbc_fbx_file_vertices, path, "missing file", "cannot read");
    expect_fail(rbc_dae_file_vertices, path, "missing file", "cannot read");
    expect_fail(rbc_fbx_file_vertices, tmp, "a folder", "cannot read");
    /* NULL error buffer with no room: still no crash. */
    CHECK_EQ(rbc_fbx_file_vertices(path, &v, NULL, 0), -1);
    return check_report("test_file_vertices");
}

int main(int argc, char **argv) {
    if (argc >= 3 && strcmp(argv[1], "blender") == 0) return run_blender(argv[2]);
    if (argc >= 3 && strcmp(argv[1], "models") == 0) return run_models(argv[2]);
    if (argc >= 6 && strcmp(argv[1], "bad") == 0) {
        size_t step = (size_t)strtoul(argv[4], NULL, 10);
        return run_bad(argv[2], argv[3], argv[5], step ? step : 1);
    }
    fprintf(stderr, "usage: test_file_vertices blender DIR | models DIR | bad FIXDIR MODELSDIR STEP TMPDIR\n");
    return 2;
}
