/* test_file_order.c -- the file's own mesh (ABI 1.9, issue 19): every imported mesh
 * maps the file's vertices, in the file's order, to its own; states go back into the
 * file's order and coordinates (node transforms, units and scale undone); the OBJ it
 * writes keeps the file's faces, UVs, normals and groups; the file's units are found
 * and applied or kept; cloths made from a mesh keep its pins and take the host's
 * extra ones. Every number is checked exactly or to a stated float rounding, on files
 * this test writes (their vertex order deliberately differs from first use in faces). */
#define _XOPEN_SOURCE 700 /* mkdtemp */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "rbcloth.h"
#include "text_file.h"

static char g_dir[256];

static const char *write_file(const char *name, const char *text) {
    return text_file_write_in(g_dir, name, text);
}

static rbc_mesh_info info_of(rbc_mesh_id m) {
    rbc_mesh_info info;
    memset(&info, 0, sizeof info);
    info.struct_size = sizeof info;
    CHECK_EQ(rbc_mesh_get_info(m, &info), RBC_OK);
    return info;
}

/* A 4 x 3 grid (12 vertices, 6 quads) whose "v" lines run bottom row last and right
 * to left, so first use in faces is not file order; one loose vertex (in no face) in
 * the middle of the list; a UV seam between columns 1 and 2 (two "vt" per seam
 * vertex); two groups. File vertex k of the grid is at (x, y) = (3 - k % 4, k / 4) for
 * k < 6, the loose vertex is line 7, then the rest. */
#define GRID_V 13
static float g_file_v[GRID_V][3];
static const char *write_scrambled_obj(void) {
    char text[8192], *p = text;
    p += sprintf(p, "# scrambled grid\no sheet\n");
    int line_of[12]; /* grid vertex (i + 4 j) -> 1-based v line */
    int v = 0;
    for (int k = 0; k < 12; ++k) {
        if (k == 6) { /* the loose vertex */
            g_file_v[v][0] = 9.5f, g_file_v[v][1] = 9.25f, g_file_v[v][2] = -1.0f;
            p += sprintf(p, "v 9.5 9.25 -1\n");
            ++v;
        }
        int j = 2 - k / 4, i = 3 - k % 4;
        float x = 0.25f * (float)i, y = 0.5f * (float)j;
        g_file_v[v][0] = x, g_file_v[v][1] = y, g_file_v[v][2] = 0.125f;
        p += sprintf(p, "v %.9g %.9g 0.125\n", (double)x, (double)y);
        line_of[i + 4 * j] = ++v;
    }
    /* UVs: column i at u = i / 3, the seam columns' right copies shifted by 0.5 */
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 4; ++i) p += sprintf(p, "vt %.9g %.9g\n", i / 3.0, j / 2.0);
    for (int j = 0; j < 3; ++j) p += sprintf(p, "vt %.9g %.9g\n", 0.5 + 2 / 3.0, j / 2.0);
    p += sprintf(p, "vn 0 0 1\n");
    for (int j = 0; j < 2; ++j) {
        p += sprintf(p, "g %s\n", j == 0 ? "bottom" : "top");
        for (int i = 0; i < 3; ++i) {
            int c[4] = {i + 4 * j, i + 1 + 4 * j, i + 1 + 4 * (j + 1), i + 4 * (j + 1)};
            p += sprintf(p, "f");
            for (int k = 0; k < 4; ++k) {
                int gi = c[k] % 4, gj = c[k] / 4;
                int vt = 1 + gi + 4 * gj;
                if (i == 2 && gi == 2) vt = 13 + gj; /* right of the seam */
                p += sprintf(p, " %d/%d/1", line_of[c[k]], vt);
            }
            p += sprintf(p, "\n");
        }
    }
    return write_file("scrambled.obj", text);
}

/* An OBJ's lines starting with `tag` (e.g. "v ", "vt ", "f ", "g ") and, for "v ", the
 * values. */
static size_t count_lines(const char *path, const char *tag, float (*v)[3], size_t cap) {
    FILE *f = fopen(path, "r");
    if (!f) return (size_t)-1;
    char line[1024];
    size_t n = 0, len = strlen(tag);
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, tag, len) != 0) continue;
        if (v && n < cap) sscanf(line + len, "%f %f %f", &v[n][0], &v[n][1], &v[n][2]);
        ++n;
    }
    fclose(f);
    return n;
}

/* The vertex index of every face corner of an OBJ, in order (at most cap). */
static size_t face_vertices(const char *path, char *out, size_t cap) {
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t n = 0;
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "f ", 2) != 0) continue;
        for (char *t = strtok(line + 2, " \n"); t; t = strtok(NULL, " \n"))
            if (n < cap) out[n++] = (char)atoi(t);
    }
    fclose(f);
    return n;
}

/* Distinct "vt" lines of an OBJ (exact text). */
static size_t distinct_vt(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    static char seen[256][64];
    size_t n = 0;
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "vt ", 3) != 0) continue;
        int dup = 0;
        for (size_t k = 0; k < n && !dup; ++k) dup = strncmp(seen[k], line, 63) == 0;
        if (!dup && n < 256) snprintf(seen[n++], sizeof seen[0], "%.63s", line);
    }
    fclose(f);
    return n;
}

static void test_obj_order(void) {
    const char *path = write_scrambled_obj();
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    if (!m) {
        fprintf(stderr, "  scrambled.obj: %s\n", rbc_last_error());
        return;
    }
    rbc_mesh_info i = info_of(m);
    CHECK_EQ(i.vertex_count, 12);
    CHECK_EQ(i.quad_count, 6);
    CHECK_EQ(i.file_vertex_count, GRID_V);
    CHECK_EQ(i.file_order, RBC_FILE_ORDER_FILE);
    CHECK_EQ(i.unmapped_file_vertices, 1);
    CHECK_EQ(i.file_unit_metres, 0.0f); /* OBJ declares no unit */
    CHECK_EQ(i.applied_scale, 1.0f);
    uint32_t map[GRID_V];
    size_t n = 0;
    CHECK_EQ(rbc_mesh_get_file_map(m, NULL, 0, &n), RBC_OK);
    CHECK_EQ(n, GRID_V);
    CHECK_EQ(rbc_mesh_get_file_map(m, map, GRID_V - 1, NULL), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "capacity is 12") != NULL);
    CHECK_EQ(rbc_mesh_get_file_map(m, map, GRID_V, &n), RBC_OK);
    float pos[36];
    CHECK_EQ(rbc_mesh_get_positions(m, pos, 36, NULL), RBC_OK);
    /* Each file vertex follows the mesh vertex at its place (no transform: exact);
     * the first use in faces is not the file's order, so the map is not identity. */
    int identity = 1;
    for (int k = 0; k < GRID_V; ++k) {
        if (k == 6) {
            CHECK_EQ(map[k], UINT32_MAX);
            continue;
        }
        CHECK(map[k] < 12);
        if (map[k] >= 12) continue;
        identity &= map[k] == (uint32_t)k;
        for (int c = 0; c < 3; ++c) CHECK_EQ(pos[3 * map[k] + c], g_file_v[k][c]);
    }
    CHECK(!identity);
    /* Back to the file: rest, then a state moved by a known offset per vertex. */
    float out[3 * GRID_V];
    CHECK_EQ(rbc_mesh_to_file_positions(m, NULL, 0, out, 3 * GRID_V, &n), RBC_OK);
    CHECK_EQ(n, 3 * GRID_V);
    for (int k = 0; k < GRID_V; ++k)
        for (int c = 0; c < 3; ++c) CHECK_EQ(out[3 * k + c], g_file_v[k][c]);
    float state[36];
    for (int v = 0; v < 36; ++v) state[v] = pos[v] + 0.5f * (float)(v / 3) + 0.25f * (float)(v % 3);
    CHECK_EQ(rbc_mesh_to_file_positions(m, state, 36, out, 3 * GRID_V, NULL), RBC_OK);
    for (int k = 0; k < GRID_V; ++k)
        for (int c = 0; c < 3; ++c)
            CHECK_EQ(out[3 * k + c], k == 6 ? g_file_v[k][c] : state[3 * map[k] + c]);

    /* The OBJ in the file's order: the file's 13 "v" lines (values exact with %.9g),
     * its UVs (13 + 3 distinct corners of assimp's), one normal per corner vertex, 6
     * faces in 2 groups, and the faces' vertices are the file's own line numbers. */
    char obj[600];
    snprintf(obj, sizeof obj, "%s/scrambled_file.obj", g_dir);
    CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, RBC_ORDER_FILE, obj), RBC_OK);
    float v[GRID_V + 2][3];
    CHECK_EQ(count_lines(obj, "v ", v, GRID_V + 2), GRID_V);
    for (int k = 0; k < GRID_V; ++k)
        for (int c = 0; c < 3; ++c) CHECK_EQ(v[k][c], g_file_v[k][c]);
    /* One "vt" per corner vertex of assimp's (per group: the row the two groups share
     * is in both), 15 distinct: the grid's 12 and the seam's 3 copies. */
    CHECK_EQ(count_lines(obj, "vt ", NULL, 0), 20);
    CHECK_EQ(distinct_vt(obj), 15);
    CHECK(count_lines(obj, "vn ", NULL, 0) >= 1);
    CHECK_EQ(count_lines(obj, "f ", NULL, 0), 6);
    CHECK_EQ(count_lines(obj, "g ", NULL, 0), 2);
    CHECK_EQ(count_lines(obj, "g bottom", NULL, 0), 1);
    /* Read back, it is the same mesh in the same order. */
    rbc_mesh_id back = 0;
    CHECK_EQ(rbc_mesh_import(obj, NULL, &back), RBC_OK);
    if (back) {
        rbc_mesh_info bi = info_of(back);
        CHECK_EQ(bi.vertex_count, 12);
        CHECK_EQ(bi.quad_count, 6);
        CHECK_EQ(bi.file_vertex_count, GRID_V);
        uint32_t bmap[GRID_V];
        float bpos[36];
        CHECK_EQ(rbc_mesh_get_file_map(back, bmap, GRID_V, NULL), RBC_OK);
        CHECK_EQ(rbc_mesh_get_positions(back, bpos, 36, NULL), RBC_OK);
        for (int k = 0; k < GRID_V; ++k) {
            CHECK_EQ(bmap[k] == UINT32_MAX, map[k] == UINT32_MAX);
            if (bmap[k] < 12 && map[k] < 12)
                for (int c = 0; c < 3; ++c) CHECK_EQ(bpos[3 * bmap[k] + c], pos[3 * map[k] + c]);
        }
        CHECK_EQ(rbc_mesh_destroy(back), RBC_OK);
    }
    /* Welding off: each corner vertex is its own mesh vertex, so the faces' file
     * vertices are searched for one by one (not taken from the welded vertex): the
     * same faces. */
    {
        rbc_mesh_import_def nw = rbc_mesh_import_def_default();
        nw.weld = 0;
        rbc_mesh_id u = 0;
        CHECK_EQ(rbc_mesh_import(path, &nw, &u), RBC_OK);
        char a[600], b2[600];
        snprintf(a, sizeof a, "%s/weld1.obj", g_dir);
        snprintf(b2, sizeof b2, "%s/weld0.obj", g_dir);
        CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, RBC_ORDER_FILE, a), RBC_OK);
        if (u) CHECK_EQ(rbc_mesh_write_file_obj(u, NULL, 0, RBC_ORDER_FILE, b2), RBC_OK);
        char fa[64], fb[64];
        CHECK_EQ(face_vertices(a, fa, sizeof fa), 24);
        CHECK_EQ(face_vertices(b2, fb, sizeof fb), 24);
        CHECK(memcmp(fa, fb, 24) == 0);
        if (u) CHECK_EQ(rbc_mesh_destroy(u), RBC_OK);
    }
    /* The simulation's order: 12 "v" lines, the mesh's positions. */
    snprintf(obj, sizeof obj, "%s/scrambled_mesh.obj", g_dir);
    CHECK_EQ(rbc_mesh_write_file_obj(m, state, 36, RBC_ORDER_MESH, obj), RBC_OK);
    CHECK_EQ(count_lines(obj, "v ", v, GRID_V + 2), 12);
    for (int k = 0; k < 12; ++k)
        for (int c = 0; c < 3; ++c) CHECK_EQ(v[k][c], state[3 * k + c]);
    CHECK_EQ(count_lines(obj, "f ", NULL, 0), 6);

    /* Bad input: named, nothing written, the mesh intact. */
    char bad[600];
    snprintf(bad, sizeof bad, "%s/bad.obj", g_dir);
    CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, 7, bad), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "order 7") != NULL);
    CHECK_EQ(rbc_mesh_write_file_obj(m, state, 35, RBC_ORDER_FILE, bad), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "xyz_count is 35") != NULL);
    state[17] = NAN;
    CHECK_EQ(rbc_mesh_to_file_positions(m, state, 36, out, 3 * GRID_V, NULL),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "xyz[17] (vertex 5, coordinate 2) is not finite") != NULL);
    CHECK_EQ(rbc_mesh_to_file_positions(m, NULL, 0, out, 3 * GRID_V - 1, NULL),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, RBC_ORDER_FILE, ""), RBC_ERR_INVALID_ARGUMENT);
    snprintf(bad, sizeof bad, "%s/no-such-dir/x.obj", g_dir);
    CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, RBC_ORDER_FILE, bad), RBC_ERR_IO);
    CHECK(strstr(rbc_last_error(), "no-such-dir") != NULL);
    snprintf(bad, sizeof bad, "%s/bad.obj", g_dir);
    CHECK_EQ(count_lines(bad, "v ", NULL, 0), (size_t)-1); /* never written */
    CHECK_EQ(rbc_mesh_get_file_map(m, map, GRID_V, NULL), RBC_OK);
    CHECK_EQ(map[6], UINT32_MAX);

    /* A 1.2-1.8 host's rbc_mesh_info: the old fields only, nothing written past. */
    unsigned char buf[sizeof(rbc_mesh_info) + 16];
    memset(buf, 0xAB, sizeof buf);
    uint32_t old = RBC_MESH_INFO_SIZE_V1_2;
    memcpy(buf, &old, sizeof old);
    CHECK_EQ(rbc_mesh_get_info(m, (rbc_mesh_info *)(void *)buf), RBC_OK);
    int untouched = 1;
    for (size_t k = old; k < sizeof buf; ++k) untouched &= buf[k] == 0xAB;
    CHECK(untouched);
    rbc_mesh_info head;
    memcpy(&head, buf, old);
    CHECK_EQ(head.vertex_count, 12);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    CHECK_EQ(rbc_mesh_get_file_map(m, map, GRID_V, NULL), RBC_ERR_STALE_HANDLE);
    CHECK_EQ(rbc_mesh_write_file_obj(m, NULL, 0, RBC_ORDER_FILE, obj), RBC_ERR_STALE_HANDLE);
}

/* Collada: a quad in centimetres (<unit meter="0.01">), z-up, placed by two nodes
 * (translate, then scale 2). The mesh is in metres, y-up; back in the file's
 * coordinates each vertex is its float_array entry again (to float rounding: the
 * transform is undone in double from floats). With keep_file_units the unit is not
 * applied. */
static const char *write_cm_dae(void) {
    return write_file(
        "cm.dae",
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
        "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
        "<asset><unit name=\"centimeter\" meter=\"0.01\"/><up_axis>Z_UP</up_axis></asset>\n"
        "<library_geometries><geometry id=\"quad\" name=\"quad\"><mesh>\n"
        "<source id=\"quad-pos\"><float_array id=\"quad-pos-array\" count=\"15\">"
        "100 0 30 0 0 30 7 7 7 0 100 30 100 100 30</float_array>\n"
        "<technique_common><accessor source=\"#quad-pos-array\" count=\"5\" stride=\"3\">"
        "<param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/>"
        "<param name=\"Z\" type=\"float\"/></accessor></technique_common></source>\n"
        "<vertices id=\"quad-vtx\"><input semantic=\"POSITION\" source=\"#quad-pos\"/></vertices>\n"
        "<polylist count=\"1\"><input semantic=\"VERTEX\" source=\"#quad-vtx\" offset=\"0\"/>"
        "<vcount>4</vcount><p>1 0 4 3</p></polylist>\n"
        "</mesh></geometry></library_geometries>\n"
        "<library_visual_scenes><visual_scene id=\"scene\">\n"
        "<node id=\"outer\" name=\"outer\"><translate>10 0 5</translate>\n"
        "<node id=\"inner\" name=\"inner\"><scale>2 2 2</scale>"
        "<instance_geometry url=\"#quad\"/></node></node>\n"
        "</visual_scene></library_visual_scenes>\n"
        "<scene><instance_visual_scene url=\"#scene\"/></scene>\n"
        "</COLLADA>\n");
}

static void test_dae_units(void) {
    static const float file_v[5][3] = {{100, 0, 30}, {0, 0, 30}, {7, 7, 7}, {0, 100, 30},
                                       {100, 100, 30}};
    const char *path = write_cm_dae();
    for (int keep = 0; keep < 2; ++keep) {
        rbc_mesh_import_def d = rbc_mesh_import_def_default();
        CHECK_EQ(d.keep_file_units, 0);
        d.keep_file_units = (uint32_t)keep;
        rbc_mesh_id m = 0;
        CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
        if (!m) {
            fprintf(stderr, "  cm.dae: %s\n", rbc_last_error());
            continue;
        }
        rbc_mesh_info i = info_of(m);
        CHECK_EQ(i.vertex_count, 4);
        CHECK_EQ(i.file_vertex_count, 5); /* the float_array's 5, the unused one too */
        CHECK_EQ(i.file_order, RBC_FILE_ORDER_FILE);
        CHECK_EQ(i.unmapped_file_vertices, 1);
        CHECK_NEAR(i.file_unit_metres, 0.01, 1e-9);
        CHECK_NEAR(i.applied_scale, keep ? 1.0 : 0.01, 1e-9);
        CHECK_EQ(i.file_units_kept, (uint32_t)keep);
        /* x = 2 x_file + 10, y-up from z-up, times the unit: the quad spans 4 m. */
        double s = keep ? 1.0 : 0.01;
        CHECK_NEAR(i.bounds_min[0], s * 10.0, 1e-5 * s * 210);
        CHECK_NEAR(i.bounds_max[0], s * 210.0, 1e-5 * s * 210);
        CHECK_NEAR(i.bounds_max[1] - i.bounds_min[1], 0.0, 1e-5 * s * 210);
        CHECK_NEAR(i.bounds_max[1], s * 65.0, 1e-5 * s * 210); /* 2 * 30 + 5 */
        float out[15];
        CHECK_EQ(rbc_mesh_to_file_positions(m, NULL, 0, out, 15, NULL), RBC_OK);
        /* Undone in double from the float mesh positions: within 4 roundings of the
         * largest coordinate, 100. */
        for (int k = 0; k < 5; ++k)
            for (int c = 0; c < 3; ++c) CHECK_NEAR(out[3 * k + c], file_v[k][c], 4 * 100 * 0x1p-23);
        CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    }
}

/* rbc_cloth_create_from_mesh: the import's pins hold; the host's settings->pins add
 * to them; a bad extra pin is named and nothing is made. */
static void test_pins_from_mesh(void) {
    const char *path = write_scrambled_obj();
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.pin_top_axis = 1; /* the top row, y = 1 */
    d.pin_top_tolerance = 1e-3f;
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
    if (!m) return;
    CHECK_EQ(info_of(m).pin_count, 4);
    float rest[36];
    CHECK_EQ(rbc_mesh_get_positions(m, rest, 36, NULL), RBC_OK);
    uint32_t extra = 0; /* a vertex of the bottom row */
    for (uint32_t v = 0; v < 12; ++v)
        if (rest[3 * v + 1] == 0.0f) extra = v;
    rbc_world_def wd = rbc_world_def_default();
    /* across the sheet (it lies in z = 0.125), so the free vertices swing away */
    wd.gravity[0] = 0.0f, wd.gravity[1] = 0.0f, wd.gravity[2] = -9.81f;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_OK);
    rbc_cloth_def cd = rbc_cloth_def_default();
    const uint32_t bad_pins[2] = {extra, 999};
    cd.pin_count = 2;
    cd.pins = bad_pins;
    rbc_cloth_id c = 0;
    CHECK_EQ(rbc_cloth_create_from_mesh(w, m, &cd, &c), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "settings->pins[1] is vertex 999; the mesh has 12 vertices") !=
          NULL);
    CHECK_EQ(c, 0);
    cd.pin_count = 1;
    CHECK_EQ(rbc_cloth_create_from_mesh(w, m, &cd, &c), RBC_OK);
    for (int s = 0; s < 30; ++s) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    float now[36];
    CHECK_EQ(rbc_cloth_read_positions(w, c, now, 36, NULL), RBC_OK);
    double drop = 0.0;
    for (uint32_t v = 0; v < 12; ++v) {
        int pinned = rest[3 * v + 1] == 1.0f || v == extra;
        double dz = fabs((double)now[3 * v + 2] - rest[3 * v + 2]);
        if (pinned)
            for (int k = 0; k < 3; ++k) CHECK_EQ(now[3 * v + k], rest[3 * v + k]);
        else if (dz > drop)
            drop = dz;
    }
    CHECK(drop > 0.1); /* the free vertices swung: 0.5 s of gravity (1.2 m free fall) */
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

/* A non-finite vertex no face uses is not refused (only used ones are): it maps to
 * no mesh vertex and keeps its place in the file. */
static void test_loose_nan(void) {
    const char *path = write_file("loose_nan.obj", "v 0 0 0\nv 1 0 0\nv nan 0 inf\nv 1 1 0\n"
                                                   "v 0 1 0\nf 1 2 4 5\n");
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    if (!m) return;
    rbc_mesh_info i = info_of(m);
    CHECK_EQ(i.vertex_count, 4);
    CHECK_EQ(i.file_vertex_count, 5);
    CHECK_EQ(i.unmapped_file_vertices, 1);
    uint32_t map[5];
    CHECK_EQ(rbc_mesh_get_file_map(m, map, 5, NULL), RBC_OK);
    CHECK_EQ(map[2], UINT32_MAX);
    float out[15];
    CHECK_EQ(rbc_mesh_to_file_positions(m, NULL, 0, out, 15, NULL), RBC_OK);
    CHECK(isnan(out[6]) && out[7] == 0.0f && isinf(out[8]));
    CHECK_EQ(out[9], 1.0f);
    CHECK_EQ(out[10], 1.0f);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

/* PLY has no reader of ours: assimp's vertex arrays stand for the file's order
 * (RBC_FILE_ORDER_ASSIMP), which for PLY is the vertex element's. A 3 x 3 grid
 * whose element lists the vertices in reverse of their use in faces comes back, in
 * the file's order, as the file's lines exactly. */
static void test_ply_order(void) {
    char text[2048], *p = text;
    p += sprintf(p, "ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\n"
                    "property float y\nproperty float z\nelement face 4\n"
                    "property list uchar int vertex_indices\nend_header\n");
    float file_v[9][3];
    for (int k = 0; k < 9; ++k) { /* file vertex k is grid vertex 8 - k */
        int g = 8 - k;
        file_v[k][0] = (float)(g % 3), file_v[k][1] = 0.5f * (float)(g / 3), file_v[k][2] = 0.0f;
        p += sprintf(p, "%g %g 0\n", (double)file_v[k][0], (double)file_v[k][1]);
    }
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            int g[4] = {i + 3 * j, i + 1 + 3 * j, i + 4 + 3 * j, i + 3 + 3 * j};
            p += sprintf(p, "4 %d %d %d %d\n", 8 - g[0], 8 - g[1], 8 - g[2], 8 - g[3]);
        }
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(write_file("reversed.ply", text), NULL, &m), RBC_OK);
    if (!m) return;
    rbc_mesh_info i = info_of(m);
    CHECK_EQ(i.file_order, RBC_FILE_ORDER_ASSIMP);
    CHECK_EQ(i.file_vertex_count, 9);
    CHECK_EQ(i.unmapped_file_vertices, 0);
    float out[27];
    CHECK_EQ(rbc_mesh_to_file_positions(m, NULL, 0, out, 27, NULL), RBC_OK);
    for (int k = 0; k < 9; ++k)
        for (int c = 0; c < 3; ++c) CHECK_EQ(out[3 * k + c], file_v[k][c]);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

int main(void) {
    text_file_tempdir(g_dir, sizeof g_dir, "rbc_order");
    test_obj_order();
    test_dae_units();
    test_pins_from_mesh();
    test_loose_nan();
    test_ply_order();
    text_file_remove_tree(g_dir);
    return check_report("import_file_order");
}
