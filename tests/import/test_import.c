/* test_import.c -- rbc_mesh_import on meshes this test writes (OBJ and PLY in a
 * temporary folder), with every number of the report checked exactly: a quad grid,
 * the same grid as triangles (pairing back into quads, or springs), n-gons (split or
 * refused), welding across objects, mesh selection, scale, pins by vertex color and
 * by rules, the getters, a cloth made from a mesh, and broken input (missing,
 * empty, garbage, truncated, out-of-range indices, bad defs): an error naming the
 * file and what is wrong, and no mesh. */
#define _XOPEN_SOURCE 700 /* mkdtemp, M_PI */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "rbcloth.h"
#include "text_file.h"

static char g_dir[256];

/* Every input goes in this test's temporary folder. */
static const char *write_file(const char *name, const char *text) {
    return text_file_write_in(g_dir, name, text);
}

/* An nx x ny grid in the plane z = 0 (y up), spacing h: vertex (i, j) is the
 * (1 + i + nx j)-th "v" line; faces are quads, or two triangles split along the
 * (i,j)-(i+1,j+1) diagonal. */
static char *grid_obj(int nx, int ny, double h, int triangles) {
    size_t cap = 64 + (size_t)nx * ny * 120;
    char *s = malloc(cap), *p = s;
    p += sprintf(p, "# rbcloth test grid\no grid\n");
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) p += sprintf(p, "v %.9g %.9g 0\n", i * h, j * h);
    for (int j = 0; j + 1 < ny; ++j)
        for (int i = 0; i + 1 < nx; ++i) {
            int a = 1 + i + nx * j, b = a + 1, c = b + nx, d = a + nx;
            if (triangles)
                p += sprintf(p, "f %d %d %d\nf %d %d %d\n", a, b, c, a, c, d);
            else
                p += sprintf(p, "f %d %d %d %d\n", a, b, c, d);
        }
    return s;
}

static rbc_mesh_info info_of(rbc_mesh_id m) {
    rbc_mesh_info info;
    memset(&info, 0, sizeof info);
    info.struct_size = sizeof info;
    CHECK_EQ(rbc_mesh_get_info(m, &info), RBC_OK);
    return info;
}

/* Mesh m's report, with the counts `expect` names checked exactly: "name value" pairs
 * separated by commas ("vertex_count 12, quad_count 6"); a failure names the field and
 * the caller's line. */
#define CHECK_INFO(m, expect) check_info((m), (expect), __LINE__)
#define INFO_FIELD(f) {#f, offsetof(rbc_mesh_info, f)}
static const struct {
    const char *name;
    size_t offset; /* of a uint32_t */
} INFO_FIELDS[] = {
    INFO_FIELD(vertex_count), INFO_FIELD(quad_count), INFO_FIELD(spring_count),
    INFO_FIELD(pin_count), INFO_FIELD(source_mesh_count), INFO_FIELD(source_vertex_count),
    INFO_FIELD(source_face_count), INFO_FIELD(file_quads), INFO_FIELD(file_triangles),
    INFO_FIELD(paired_triangles), INFO_FIELD(leftover_triangles), INFO_FIELD(ngons_split),
    INFO_FIELD(quads_from_ngons), INFO_FIELD(triangles_from_ngons),
    INFO_FIELD(points_lines_skipped), INFO_FIELD(degenerate_faces), INFO_FIELD(welded_vertices),
    INFO_FIELD(unused_vertices), INFO_FIELD(color_count), INFO_FIELD(bipartite),
    INFO_FIELD(pins_from_colors), INFO_FIELD(pins_from_rules), INFO_FIELD(pins_from_group),
};

static rbc_mesh_info check_info(rbc_mesh_id m, const char *expect, int line) {
    rbc_mesh_info info = info_of(m);
    for (const char *p = expect; *p;) {
        char name[64];
        unsigned long want = 0;
        int used = 0;
        if (sscanf(p, " %63[a-z_] %lu%n", name, &want, &used) != 2) {
            CHECK(!"CHECK_INFO: \"name value\" pairs");
            fprintf(stderr, "  line %d: cannot read \"%s\"\n", line, p);
            break;
        }
        p += used;
        p += *p == ',';
        size_t k = 0, n = sizeof INFO_FIELDS / sizeof INFO_FIELDS[0];
        while (k < n && strcmp(INFO_FIELDS[k].name, name) != 0) ++k;
        if (k == n) {
            CHECK(!"CHECK_INFO: counts of rbc_mesh_info");
            fprintf(stderr, "  line %d: rbc_mesh_info has no count %s\n", line, name);
            continue;
        }
        uint32_t got;
        memcpy(&got, (const char *)&info + INFO_FIELDS[k].offset, sizeof got);
        CHECK_EQ(got, want);
        if (got != want) fprintf(stderr, "  line %d: info.%s\n", line, name);
    }
    return info;
}

/* Imports path with def (NULL: the defaults): it succeeds, its report has the counts
 * `expect` names (as CHECK_INFO), and the mesh is destroyed. */
#define CHECK_IMPORT(path, def, expect) check_import((path), (def), (expect), __LINE__)
static void check_import(const char *path, const rbc_mesh_import_def *def, const char *expect,
                         int line) {
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, def, &m), RBC_OK);
    if (!m) fprintf(stderr, "  line %d: %s: %s\n", line, path, rbc_last_error());
    check_info(m, expect, line);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

/* grid_obj(4, 3, 0.1, triangles) written to the file `name`: its path. */
static const char *write_grid(const char *name, int triangles) {
    char *text = grid_obj(4, 3, 0.1, triangles);
    const char *path = write_file(name, text);
    free(text);
    return path;
}

/* Every quad of the mesh is a square of side h (its four edges). */
static int quads_are_squares(rbc_mesh_id m, double h) {
    size_t np = 0, nq = 0;
    rbc_mesh_get_positions(m, NULL, 0, &np);
    rbc_mesh_get_quads(m, NULL, 0, &nq);
    float *p = malloc((np + 1) * sizeof *p);
    uint32_t *q = malloc((nq + 1) * sizeof *q);
    rbc_mesh_get_positions(m, p, np, NULL);
    rbc_mesh_get_quads(m, q, nq, NULL);
    int ok = 1;
    for (size_t k = 0; k < nq; ++k) {
        uint32_t a = q[k], b = q[4 * (k / 4) + (k + 1) % 4];
        double dx = p[3 * a] - p[3 * b], dy = p[3 * a + 1] - p[3 * b + 1],
               dz = p[3 * a + 2] - p[3 * b + 2];
        if (fabs(sqrt(dx * dx + dy * dy + dz * dz) - h) > 1e-6 * h) ok = 0;
    }
    free(p);
    free(q);
    return ok;
}

/* The import must fail with `code`, name the file, say `what`, and make no mesh. */
static void expect_refused(const char *path, const rbc_mesh_import_def *def, rbc_result code,
                           const char *what) {
    rbc_mesh_id m = 12345;
    rbc_result rc = rbc_mesh_import(path, def, &m);
    CHECK_EQ(rc, code);
    CHECK_EQ(m, 0);
    const char *msg = rbc_last_error();
    int names_file = strstr(msg, path) != NULL, says = strstr(msg, what) != NULL;
    CHECK(names_file);
    CHECK(says);
    if (rc != code || !names_file || !says)
        fprintf(stderr, "  %s: got %s \"%s\", wanted %s with \"%s\"\n", path,
                rbc_result_string(rc), msg, rbc_result_string(code), what);
}

static void test_quad_grid(void) {
    const char *path = write_grid("quads.obj", 0);
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    rbc_mesh_info i = CHECK_INFO(m, "vertex_count 12, quad_count 6, spring_count 0, "
                                    "file_quads 6, file_triangles 0, paired_triangles 0, "
                                    "leftover_triangles 0, ngons_split 0, degenerate_faces 0, "
                                    "source_mesh_count 1, source_face_count 6, pin_count 0, "
                                    "bipartite 1, color_count 2");
    CHECK_NEAR(i.bounds_max[0], 0.3, 1e-7);
    CHECK_NEAR(i.bounds_max[1], 0.2, 1e-7);
    CHECK(quads_are_squares(m, 0.1));

    /* Getters: counts with NULL, a short buffer refused. */
    size_t n = 0;
    CHECK_EQ(rbc_mesh_get_positions(m, NULL, 0, &n), RBC_OK);
    CHECK_EQ(n, 36);
    CHECK_EQ(rbc_mesh_get_quads(m, NULL, 0, &n), RBC_OK);
    CHECK_EQ(n, 24);
    CHECK_EQ(rbc_mesh_get_springs(m, NULL, 0, &n), RBC_OK);
    CHECK_EQ(n, 0);
    float pos[36];
    CHECK_EQ(rbc_mesh_get_positions(m, pos, 35, &n), RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(rbc_last_error(), "capacity") != NULL);
    rbc_mesh_info small;
    small.struct_size = 8;
    CHECK_EQ(rbc_mesh_get_info(m, &small), RBC_ERR_INVALID_ARGUMENT);

    /* A cloth from the mesh: 6 quads -> 17 structural springs, 2 colors; the top
     * row pinned by rule stays put under gravity. */
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.pin_top_axis = 1;
    rbc_mesh_id mp = 0;
    CHECK_EQ(rbc_mesh_import(path, &d, &mp), RBC_OK);
    rbc_mesh_info ip = CHECK_INFO(mp, "pin_count 4, pins_from_rules 4, pins_from_colors 0");
    uint32_t pins[4];
    CHECK_EQ(rbc_mesh_get_pins(mp, pins, 4, &n), RBC_OK);
    float p[36];
    CHECK_EQ(rbc_mesh_get_positions(mp, p, 36, NULL), RBC_OK);
    for (int k = 0; k < 4; ++k) CHECK_NEAR(p[3 * pins[k] + 1], 0.2, 1e-7);

    rbc_world_def wd = rbc_world_def_default();
    wd.thread_count = 1;
    rbc_world_id w = 0;
    CHECK_EQ(rbc_world_create(&wd, &w), RBC_OK);
    rbc_cloth_def settings = rbc_cloth_def_default();
    settings.stiffness = -1.0f; /* bad: refused, nothing made */
    rbc_cloth_id c = 77;
    CHECK_EQ(rbc_cloth_create_from_mesh(w, mp, &settings, &c), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(c, 0);
    CHECK(strstr(rbc_last_error(), "rbc_cloth_create_from_mesh") != NULL);
    settings.stiffness = 500.0f;
    settings.positions = NULL; /* geometry fields are ignored */
    settings.vertex_count = 999;
    CHECK_EQ(rbc_cloth_create_from_mesh(w, mp, &settings, &c), RBC_OK);
    uint32_t nv = 0, ns = 0, ncol = 0;
    CHECK_EQ(rbc_cloth_get_vertex_count(w, c, &nv), RBC_OK);
    CHECK_EQ(rbc_cloth_get_topology(w, c, &ns, &ncol), RBC_OK);
    CHECK_EQ(nv, 12);
    CHECK_EQ(ns, 17);
    CHECK_EQ(ncol, 2);
    for (int s = 0; s < 10; ++s) CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    float after[36];
    CHECK_EQ(rbc_cloth_read_positions(w, c, after, 36, NULL), RBC_OK);
    for (int k = 0; k < 4; ++k)
        for (int x = 0; x < 3; ++x) CHECK_EQ(after[3 * pins[k] + x], p[3 * pins[k] + x]);
    int fell = 0;
    /* It hangs in its own plane: the free vertices sag by about m g / k (micrometres). */
    for (uint32_t v = 0; v < 12; ++v) fell += after[3 * v + 1] < p[3 * v + 1];
    CHECK_EQ(fell, 8);
    /* A destroyed mesh is stale; the cloth made from it lives on. */
    CHECK_EQ(rbc_mesh_destroy(mp), RBC_OK);
    CHECK_EQ(rbc_mesh_destroy(mp), RBC_ERR_STALE_HANDLE);
    CHECK_EQ(rbc_cloth_create_from_mesh(w, mp, NULL, &c), RBC_ERR_STALE_HANDLE);
    CHECK_EQ(rbc_mesh_get_info(w, &ip), RBC_ERR_STALE_HANDLE); /* a world id is no mesh id */
    CHECK_EQ(rbc_world_step(w, 1.0f / 60.0f), RBC_OK);
    CHECK_EQ(rbc_world_destroy(w), RBC_OK);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

static void test_triangle_grid(void) {
    const char *path = write_grid("triangles.obj", 1);
    /* Paired back into the 6 squares (score 0 beats the 45-degree parallelograms). */
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    CHECK_INFO(m, "vertex_count 12, file_triangles 12, paired_triangles 12, "
                  "leftover_triangles 0, quad_count 6, spring_count 0, bipartite 1, "
                  "color_count 2");
    CHECK(quads_are_squares(m, 0.1));
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);

    /* No pairing: every edge a spring (9 horizontal, 8 vertical, 6 diagonals). */
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.pair_triangles = 0;
    CHECK_IMPORT(path, &d, "quad_count 0, leftover_triangles 12, spring_count 23, bipartite 0, "
                           "color_count 3");

    /* A strip of three triangles: one pair, one leftover whose two free edges are
     * springs (the third is the quad's edge). Bounds too tight: no pair at all. */
    const char *strip = write_file("strip.obj",
                                   "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                                   "f 1 2 3\nf 1 3 4\nf 2 5 3\n");
    CHECK_IMPORT(strip, NULL, "quad_count 1, paired_triangles 2, leftover_triangles 1, "
                              "spring_count 2, bipartite 0, color_count 3");
    /* The angle bound: within 1 degree of square, 1-2 still pairs. The fold bound: two
     * triangles folded 90 degrees about their shared edge pair only when allowed. */
    d = rbc_mesh_import_def_default();
    d.pair_max_angle_deviation_deg = 1.0f; /* squares only: 1-2 is one */
    CHECK_IMPORT(strip, &d, "paired_triangles 2");
    /* A unit square folded 60 degrees about its diagonal (1)-(3): corner angles 90
     * and 75.5 (deviation 14.5), fold 60. */
    const char *folded = write_file("folded.obj",
                                    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.25 0.75 0.612372436\n"
                                    "f 1 2 3\nf 1 3 4\n");
    CHECK_IMPORT(folded, NULL, "paired_triangles 0, " /* 60-degree fold > 30 */
                               "leftover_triangles 2, spring_count 5");
    d = rbc_mesh_import_def_default();
    d.pair_max_fold_deg = 61.0f;
    CHECK_IMPORT(folded, &d, "paired_triangles 2");
}

static void test_ngons(void) {
    /* A regular hexagon and a pentagon beside it (sharing an edge). */
    char text[1024], *p = text;
    for (int k = 0; k < 6; ++k)
        p += sprintf(p, "v %.9g %.9g 0\n", cos(k * M_PI / 3), sin(k * M_PI / 3));
    p += sprintf(p, "v 2 0 0\nv 2.5 1 0\nv 2 1.5 0\n"); /* 7 8 9 */
    p += sprintf(p, "f 1 2 3 4 5 6\nf 1 7 8 9 2\n");
    const char *path = write_file("ngons.obj", text);
    CHECK_IMPORT(path, NULL, "ngons_split 2, "
                             "quads_from_ngons 3, " /* 2 from the hexagon, 1 from the pentagon */
                             "triangles_from_ngons 1, " /* the pentagon's last piece */
                             "quad_count 3, leftover_triangles 1, vertex_count 9");
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.ngons = RBC_NGON_REFUSE;
    expect_refused(path, &d, RBC_ERR_BAD_MESH, "face 0 has 6 corners");
}

static void test_weld_select_scale(void) {
    /* Two objects (two meshes), each a unit quad, sharing an edge by position only;
     * a third 1e-4 away from the second. */
    const char *path = write_file("two.obj",
                                  "o A\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
                                  "o B\nv 1 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nf 5 6 7 8\n"
                                  "o C\nv 2.0001 0 0\nv 3 0 0\nv 3 1 0\nv 2.0001 1 0\nf 9 10 11 12\n");
    rbc_mesh_id m = 0;
    CHECK_IMPORT(path, NULL, "source_mesh_count 3, source_vertex_count 12, welded_vertices 2, "
                             "vertex_count 10, quad_count 3");

    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.weld_distance = 1e-3f;
    CHECK_IMPORT(path, &d, "welded_vertices 4");
    d = rbc_mesh_import_def_default();
    d.weld = 0;
    CHECK_IMPORT(path, &d, "vertex_count 12");

    d = rbc_mesh_import_def_default();
    d.mesh_name = "B";
    d.scale = 0.01f;
    CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
    rbc_mesh_info i = CHECK_INFO(m, "source_mesh_count 1, quad_count 1");
    CHECK_NEAR(i.bounds_min[0], 0.01, 1e-9);
    CHECK_NEAR(i.bounds_max[0], 0.02, 1e-9);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    d = rbc_mesh_import_def_default();
    d.mesh_index = 2;
    CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
    i = CHECK_INFO(m, "source_mesh_count 1");
    CHECK_NEAR(i.bounds_max[0], 3.0, 1e-7);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    d.mesh_index = 3;
    expect_refused(path, &d, RBC_ERR_INVALID_ARGUMENT, "the file has 3 meshes");
    d = rbc_mesh_import_def_default();
    d.mesh_name = "nope";
    expect_refused(path, &d, RBC_ERR_INVALID_ARGUMENT, "no mesh named \"nope\"");

    /* Pins from a named group: every vertex of object B (4), among them the two it
     * shares with A by welding; the group need not be taken alone. */
    d = rbc_mesh_import_def_default();
    d.pin_group = "B";
    CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
    CHECK_INFO(m, "vertex_count 10, pin_count 4, pins_from_group 4, pins_from_colors 0, "
                  "pins_from_rules 0");
    uint32_t pins[10];
    size_t pc = 0, pn = 0;
    float pos[30];
    CHECK_EQ(rbc_mesh_get_pins(m, pins, 10, &pc), RBC_OK);
    CHECK_EQ(rbc_mesh_get_positions(m, pos, 30, &pn), RBC_OK);
    int all_b = pc == 4;
    for (size_t k = 0; k < pc && k < 10; ++k)
        all_b &= pos[3 * pins[k]] >= 1.0f && pos[3 * pins[k]] <= 2.0f; /* x in [1, 2] */
    CHECK(all_b);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    /* Only meshes taken are pinned: taking C alone, group B is not among them. */
    d.mesh_name = "C";
    expect_refused(path, &d, RBC_ERR_INVALID_ARGUMENT, "pin_group \"B\" names no mesh or node taken");
    d = rbc_mesh_import_def_default();
    d.pin_group = "nope";
    expect_refused(path, &d, RBC_ERR_INVALID_ARGUMENT, "pin_group \"nope\"");
}

/* Node transforms, numerically: a Collada quad (unit square in y = 0) placed by a
 * node scaled 2x inside a node translated by (10, 0, 0): its corners must land on
 * x in [10, 12], z in [0, 2]; def.scale applies after them. */
static void test_node_transforms(void) {
    const char *path = write_file(
        "nodes.dae",
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
        "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
        "<asset><unit name=\"meter\" meter=\"1\"/><up_axis>Y_UP</up_axis></asset>\n"
        "<library_geometries><geometry id=\"quad\" name=\"quad\"><mesh>\n"
        "<source id=\"quad-pos\"><float_array id=\"quad-pos-array\" count=\"12\">"
        "0 0 0 1 0 0 1 0 1 0 0 1</float_array>\n"
        "<technique_common><accessor source=\"#quad-pos-array\" count=\"4\" stride=\"3\">"
        "<param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/>"
        "<param name=\"Z\" type=\"float\"/></accessor></technique_common></source>\n"
        "<vertices id=\"quad-vtx\"><input semantic=\"POSITION\" source=\"#quad-pos\"/></vertices>\n"
        "<polylist count=\"1\"><input semantic=\"VERTEX\" source=\"#quad-vtx\" offset=\"0\"/>"
        "<vcount>4</vcount><p>0 1 2 3</p></polylist>\n"
        "</mesh></geometry></library_geometries>\n"
        "<library_visual_scenes><visual_scene id=\"scene\">\n"
        "<node id=\"outer\" name=\"outer\"><translate>10 0 0</translate>\n"
        "<node id=\"inner\" name=\"inner\"><scale>2 2 2</scale>"
        "<instance_geometry url=\"#quad\"/></node></node>\n"
        "</visual_scene></library_visual_scenes>\n"
        "<scene><instance_visual_scene url=\"#scene\"/></scene>\n"
        "</COLLADA>\n");
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    if (!m) {
        fprintf(stderr, "  nodes.dae: %s\n", rbc_last_error());
        return;
    }
    rbc_mesh_info i = CHECK_INFO(m, "vertex_count 4, quad_count 1");
    /* Exact in floats: 2 * {0, 1} + 10. */
    CHECK_NEAR(i.bounds_min[0], 10.0, 1e-6);
    CHECK_NEAR(i.bounds_max[0], 12.0, 1e-6);
    CHECK_NEAR(i.bounds_min[1], 0.0, 1e-6);
    CHECK_NEAR(i.bounds_max[1], 0.0, 1e-6);
    CHECK_NEAR(i.bounds_min[2], 0.0, 1e-6);
    CHECK_NEAR(i.bounds_max[2], 2.0, 1e-6);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.scale = 0.5f;
    d.pin_group = "inner"; /* a node name */
    CHECK_EQ(rbc_mesh_import(path, &d, &m), RBC_OK);
    i = info_of(m);
    CHECK_NEAR(i.bounds_min[0], 5.0, 1e-6);
    CHECK_NEAR(i.bounds_max[0], 6.0, 1e-6);
    CHECK_NEAR(i.bounds_max[2], 1.0, 1e-6);
    CHECK_EQ(i.pins_from_group, 4);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

static void test_ply_pins(void) {
    /* A 3 x 3 grid of quads (4 x 4 vertices) with vertex colors: the top row red, one
     * green vertex, the rest white. */
    char text[4096], *p = text;
    p += sprintf(p, "ply\nformat ascii 1.0\nelement vertex 16\nproperty float x\n"
                    "property float y\nproperty float z\nproperty uchar red\n"
                    "property uchar green\nproperty uchar blue\nelement face 9\n"
                    "property list uchar int vertex_indices\nend_header\n");
    for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 4; ++k) {
            int r = 255, g = 255, b = 255;
            if (j == 3) g = b = 0;
            if (j == 1 && k == 1) r = b = 0;
            p += sprintf(p, "%d %d 0 %d %d %d\n", k, j, r, g, b);
        }
    for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) {
            int a = k + 4 * j;
            p += sprintf(p, "4 %d %d %d %d\n", a, a + 1, a + 5, a + 4);
        }
    const char *path = write_file("pins.ply", text);
    rbc_mesh_id m = 0;
    CHECK_EQ(rbc_mesh_import(path, NULL, &m), RBC_OK);
    CHECK_INFO(m, "vertex_count 16, file_quads 9, quad_count 9, pins_from_colors 4, pin_count 4");
    uint32_t pins[16];
    float pos[48];
    size_t n = 0;
    CHECK_EQ(rbc_mesh_get_pins(m, pins, 16, &n), RBC_OK);
    CHECK_EQ(n, 4);
    CHECK_EQ(rbc_mesh_get_positions(m, pos, 48, NULL), RBC_OK);
    for (size_t k = 0; k < n; ++k) CHECK_EQ(pos[3 * pins[k] + 1], 3.0f);
    for (size_t k = 1; k < n; ++k) CHECK(pins[k - 1] < pins[k]);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);

    /* Colors off; rules: the plane y = 0 (bottom row, 4) and the point (3, 3, 0)
     * within 1.01 (itself and its two neighbours, 3) -> 7 distinct. */
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.pin_color_threshold = 0.0f;
    d.pin_plane_distance = 0.01f;
    d.pin_point[0] = 3.0f;
    d.pin_point[1] = 3.0f;
    d.pin_point_distance = 1.01f;
    CHECK_IMPORT(path, &d, "pins_from_colors 0, pins_from_rules 7, pin_count 7");
    /* Both: colors (top row, 4) and the plane (bottom row, 4). */
    d.pin_color_threshold = 0.5f;
    d.pin_point_distance = -1.0f;
    CHECK_IMPORT(path, &d, "pin_count 8");
}

static void test_bad_input(void) {
    char missing[512];
    snprintf(missing, sizeof missing, "%s/does-not-exist.obj", g_dir);
    expect_refused(missing, NULL, RBC_ERR_IO, "cannot open the file");
    expect_refused(g_dir, NULL, RBC_ERR_IO, "not a regular file");
    expect_refused(write_file("empty.obj", ""), NULL, RBC_ERR_IO, "assimp could not read");
    /* A cut PLY header: assimp 5.2.5 alone loops forever on it; refused before. */
    expect_refused(write_file("cut.ply", "ply\nformat binary_little_endian 1.0\n\x01\x02"),
                   NULL, RBC_ERR_IO, "without end_header");
    /* Indices out of range: named by line, element and corner before assimp (whose
     * own message is only "OBJ: vertex index out of range"). */
    expect_refused(write_file("garbage.obj", "\x01\x02\x03 f 9 9 9\nf -5 2\n"), NULL,
                   RBC_ERR_BAD_MESH,
                   "line 2, face 0 (0-based), corner 0: vertex index -5 is out of range (0 "
                   "\"v\" lines come before it)");
    expect_refused(write_file("outofrange.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 99\n"),
                   NULL, RBC_ERR_BAD_MESH,
                   "line 4, face 0 (0-based), corner 2: vertex index 99 is out of range (the "
                   "file has 3 \"v\" lines)");
    expect_refused(write_file("outofrange_vt.obj",
                              "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\n# a comment\n"
                              "f 1/1 2/1 3/1 4/2\n"),
                   NULL, RBC_ERR_BAD_MESH,
                   "line 7, face 0 (0-based), corner 3: texture coordinate index 2 is out of "
                   "range (the file has 1 \"vt\" lines)");
    expect_refused(write_file("outofrange_cont.obj",
                              "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 \\\n 3 0\n"),
                   NULL, RBC_ERR_BAD_MESH,
                   "line 5, face 1 (0-based), corner 3: \"0\" is not a vertex index");
    /* PLY: assimp's own check names the face and corner; it is the mesh that is bad. */
    expect_refused(write_file("outofrange.ply",
                              "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                              "property float y\nproperty float z\nelement face 1\n"
                              "property list uchar int vertex_indices\nend_header\n0 0 0\n"
                              "1 0 0\n1 1 0\n0 1 0\n4 0 1 2 99\n"),
                   NULL, RBC_ERR_BAD_MESH, "aiMesh::mFaces[0]::mIndices[3] is out of range");
    /* OFF: assimp 5.2.5 would replace 99 by the last vertex and import a square. */
    expect_refused(write_file("outofrange.off", "OFF\n# four corners\n4 1 0\n0 0 0\n1 0 0\n"
                                                "1 1 0\n0 1 0\n4 0 1 2 99\n"),
                   NULL, RBC_ERR_BAD_MESH,
                   "line 8, face 0 (0-based), corner 3: vertex index 99 is out of range (the "
                   "file has 4 vertices)");
    /* A non-finite vertex its only face uses: refused, not merged away by assimp's
     * JoinIdenticalVertices (which made it a 3-vertex mesh before 1.9). */
    expect_refused(write_file("nan_vertex.obj",
                              "v 0 0 0\nv 1 0 0\nv 1 0 nan\nv 0 0 1\nf 1 2 3 4\n"),
                   NULL, RBC_ERR_BAD_MESH, "face 0 corner 2 is at (1, 0, nan) in the file");
    expect_refused(write_file("truncated.ply",
                              "ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\n"
                              "property float y\nproperty float z\nelement face 1\n"
                              "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n"),
                   NULL, RBC_ERR_BAD_MESH, "no face to simulate"); /* assimp reads it */
    expect_refused(write_file("hello.xyz123", "hello\n"), NULL, RBC_ERR_UNSUPPORTED,
                   "no assimp reader");
    expect_refused(write_file("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1\np 2\nl 1 3\n"),
                   NULL, RBC_ERR_BAD_MESH, "no face to simulate");
    expect_refused(write_file("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), NULL,
                   RBC_ERR_BAD_MESH, "no face to simulate: 1 faces in 1 meshes, 0 points or "
                                     "lines, 1 degenerate");
    const char *grid = write_file("ok.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    rbc_mesh_import_def d = rbc_mesh_import_def_default();
    d.scale = 0.0f;
    expect_refused(grid, &d, RBC_ERR_INVALID_ARGUMENT, "scale");
    d = rbc_mesh_import_def_default();
    d.ngons = 7;
    expect_refused(grid, &d, RBC_ERR_INVALID_ARGUMENT, "rbc_ngon_mode");
    d = rbc_mesh_import_def_default();
    d.pin_plane_distance = 0.1f;
    d.pin_plane[1] = 0.0f;
    expect_refused(grid, &d, RBC_ERR_INVALID_ARGUMENT, "zero normal");
    d = rbc_mesh_import_def_default();
    d.struct_size = 12;
    rbc_mesh_id m = 5;
    CHECK_EQ(rbc_mesh_import(grid, &d, &m), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(m, 0);
    CHECK_EQ(rbc_mesh_import(NULL, NULL, &m), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_mesh_import(grid, NULL, NULL), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_mesh_import_def_init(&d, 3), RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_mesh_get_info(0, NULL), RBC_ERR_STALE_HANDLE);
    /* After all that, a good file still imports (nothing was left half-made). */
    CHECK_EQ(rbc_mesh_import(grid, NULL, &m), RBC_OK);
    CHECK_EQ(rbc_mesh_destroy(m), RBC_OK);
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "%s/rbc_import_XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 2;
    }
    test_quad_grid();
    test_triangle_grid();
    test_ngons();
    test_weld_select_scale();
    test_node_transforms();
    test_ply_pins();
    test_bad_input();
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
    return check_report("import_unit");
}
