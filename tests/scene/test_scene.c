/* test_scene.c -- the sample scene loader (samples/scene.c), the grid generator
 * (samples/grid.c) and scene creation against a scripted function table.
 * Needs no plugin. Usage: test_scene SCENES_DIR
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "grid.h"
#include "scene.h"

static const char *scenes_dir = ".";

#define TEST_PI 3.14159265358979323846

static int load_sample(const char *file, rbc_scene *scene, char *err, size_t err_size) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", scenes_dir, file);
    return rbc_scene_load_file(path, scene, err, err_size);
}

/* Deep equality of two loaded scenes, floats compared bit for bit. */
static int scenes_equal(const rbc_scene *a, const rbc_scene *b) {
    if (strcmp(a->name, b->name) != 0 || a->frames != b->frames || a->dt != b->dt)
        return 0;
    if ((a->description == NULL) != (b->description == NULL) ||
        (a->description && strcmp(a->description, b->description) != 0))
        return 0;
    if (memcmp(&a->world, &b->world, sizeof a->world) != 0)
        return 0;
    if (a->cloth_count != b->cloth_count || a->collider_count != b->collider_count)
        return 0;
    for (uint32_t i = 0; i < a->cloth_count; ++i) {
        const rbc_scene_cloth *x = &a->cloths[i], *y = &b->cloths[i];
        if (strcmp(x->name, y->name) != 0 || x->from_grid != y->from_grid ||
            x->vertex_count != y->vertex_count || x->quad_count != y->quad_count ||
            x->pin_count != y->pin_count || x->vertex_mass != y->vertex_mass ||
            x->stiffness != y->stiffness || x->damping != y->damping)
            return 0;
        if (x->from_grid &&
            (x->grid.nx != y->grid.nx || x->grid.ny != y->grid.ny ||
             x->grid.spacing != y->grid.spacing || x->grid.plane != y->grid.plane ||
             memcmp(x->grid.origin, y->grid.origin, sizeof x->grid.origin) != 0))
            return 0;
        if (memcmp(x->positions, y->positions, 3 * sizeof(float) * x->vertex_count) != 0 ||
            memcmp(x->quads, y->quads, 4 * sizeof(uint32_t) * x->quad_count) != 0 ||
            (x->pin_count && memcmp(x->pins, y->pins, sizeof(uint32_t) * x->pin_count) != 0))
            return 0;
    }
    for (uint32_t i = 0; i < a->collider_count; ++i)
        if (memcmp(&a->colliders[i], &b->colliders[i], sizeof a->colliders[i]) != 0)
            return 0;
    return 1;
}

static int is_zeroed(const void *p, size_t size) {
    const unsigned char *c = p;
    for (size_t i = 0; i < size; ++i)
        if (c[i])
            return 0;
    return 1;
}

/* ------------------------------------------------------------------------- */

/* Parses the len bytes of json as `source` into s: 0, or -1 when they are refused (a
 * failed check; the message printed). */
static int parse_ok(const char *json, size_t len, const char *source, rbc_scene *s) {
    char err[RBC_SCENE_ERROR_MAX];
    int rc = rbc_scene_parse(json, len, source, s, err, sizeof err);
    CHECK_EQ(rc, 0);
    if (rc) fprintf(stderr, "%s\n", err);
    return rc;
}

static void test_grid(void) {
    /* 3 x 2 in the xy plane at (1, 2, 3), spacing 0.5. */
    rbc_grid_def g = {3, 2, 0.5, {1.0, 2.0, 3.0}, RBC_GRID_PLANE_XY};
    float *pos = NULL;
    uint32_t *quads = NULL, nv = 0, nq = 0;
    CHECK_EQ(rbc_grid_build(&g, &pos, &nv, &quads, &nq), RBC_GRID_OK);
    CHECK_EQ(nv, 6);
    CHECK_EQ(nq, 2);
    /* vertex (i, j) = i + 3 j at origin + (i, j, 0) * 0.5 */
    const float expect_pos[18] = {1, 2, 3, 1.5f, 2, 3, 2, 2, 3, 1, 2.5f, 3, 1.5f, 2.5f, 3, 2, 2.5f, 3};
    const uint32_t expect_quads[8] = {0, 1, 4, 3, 1, 2, 5, 4};
    CHECK(pos && memcmp(pos, expect_pos, sizeof expect_pos) == 0);
    CHECK(quads && memcmp(quads, expect_quads, sizeof expect_quads) == 0);
    free(pos);
    free(quads);

    /* The same in the xz plane: the second axis is z. */
    g.plane = RBC_GRID_PLANE_XZ;
    CHECK_EQ(rbc_grid_build(&g, &pos, &nv, &quads, &nq), RBC_GRID_OK);
    CHECK_NEAR(pos[3 * 4 + 0], 1.5, 0);
    CHECK_NEAR(pos[3 * 4 + 1], 2.0, 0);
    CHECK_NEAR(pos[3 * 4 + 2], 3.5, 0);
    free(pos);
    free(quads);

    /* Refused: too few vertices, bad spacing, unknown plane, too many vertices,
     * coordinates beyond float range. Outputs untouched. */
    const rbc_grid_def bad[] = {
        {1, 5, 0.1, {0, 0, 0}, RBC_GRID_PLANE_XZ},
        {5, 5, 0.0, {0, 0, 0}, RBC_GRID_PLANE_XZ},
        {5, 5, NAN, {0, 0, 0}, RBC_GRID_PLANE_XZ},
        {5, 5, 0.1, {0, 0, 0}, (rbc_grid_plane)7},
        {65536, 65536, 0.1, {0, 0, 0}, RBC_GRID_PLANE_XZ},
        {5, 5, 1e38, {0, 0, 0}, RBC_GRID_PLANE_XZ},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        float *p = (float *)&g;
        uint32_t *q = (uint32_t *)&g;
        CHECK_EQ(rbc_grid_build(&bad[i], &p, &nv, &q, &nq), RBC_GRID_INVALID);
        CHECK(p == (float *)&g && q == (uint32_t *)&g);
    }
}

/* The demo scene, hanging_cloth.json: the paper's cloth at 1/60 s with the default
 * solve (no counts, no solver object); and the paper's experiment,
 * hanging_cloth_paper.json: 2 ms, 1 x 11 RBGS iterations, fixed. Same cloth. */
static void test_hanging_cloth_file(int paper) {
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    int rc = load_sample(paper ? "hanging_cloth_paper.json" : "hanging_cloth.json", &s, err,
                         sizeof err);
    CHECK_EQ(rc, 0);
    if (rc) {
        fprintf(stderr, "%s\n", err);
        return;
    }
    CHECK(strcmp(s.name, paper ? "hanging_cloth_paper" : "hanging_cloth") == 0);
    CHECK_EQ(s.frames, 240);
    CHECK(s.dt == (paper ? 0.002f : (float)(1.0 / 60.0)));
    CHECK(s.world.gravity[0] == 0.0f && s.world.gravity[1] == -9.81f && s.world.gravity[2] == 0.0f);
    CHECK_EQ(s.world.substeps, paper ? 1 : 0);
    CHECK(s.world.substep_rate == 480.0f);
    CHECK_EQ(s.world.nonlinear_iterations, 1);
    CHECK_EQ(s.world.linear_iterations, 11);
    rbc_solver_def want;
    rbc_scene_solver_preset(&want, paper ? RBC_PRESET_PAPER : RBC_PRESET_CLOTH);
    CHECK(memcmp(&s.world.solver, &want, sizeof want) == 0);
    CHECK_EQ(s.world.solver.solver, paper ? RBC_SOLVER_RBGS : RBC_SOLVER_RBGS_SOR);
    CHECK_EQ(s.world.thread_count, 0);
    CHECK_EQ(s.world.backend, RBC_BACKEND_AUTO);
    CHECK_EQ(s.cloth_count, 1);
    CHECK_EQ(s.collider_count, 0);

    const rbc_scene_cloth *c = &s.cloths[0];
    CHECK(strcmp(c->name, "cloth") == 0);
    CHECK_EQ(c->from_grid, 1);
    CHECK_EQ(c->grid.nx, 100);
    CHECK_EQ(c->grid.ny, 100);
    CHECK(c->grid.spacing == 1.0 / 99.0); /* the double nearest 1/99, exactly */
    CHECK_EQ(c->grid.plane, RBC_GRID_PLANE_XZ);
    CHECK_EQ(c->vertex_count, 10000);
    CHECK_EQ(c->quad_count, 9801);
    CHECK(c->vertex_mass == 1e-4f);
    CHECK(c->stiffness == 1000.0f);
    CHECK(c->damping == 0.0f);
    CHECK_EQ(c->pin_count, 2);
    CHECK(c->pin_count == 2 && c->pins[0] == 0 && c->pins[1] == 99);

    /* Vertex i + 100 j at (i / 99, 0, j / 99): the corners span exactly 1 m. */
    const float *p = c->positions;
    CHECK(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f);
    CHECK(p[3 * 99 + 0] == 1.0f && p[3 * 99 + 2] == 0.0f);
    CHECK(p[3 * 9999 + 0] == 1.0f && p[3 * 9999 + 1] == 0.0f && p[3 * 9999 + 2] == 1.0f);
    CHECK(p[3 * (7 + 100 * 42) + 0] == (float)(7.0 / 99.0));
    CHECK(p[3 * (7 + 100 * 42) + 2] == (float)(42.0 / 99.0));
    /* Quad (i, j) = (i, j), (i+1, j), (i+1, j+1), (i, j+1), index i + 99 j. */
    const uint32_t *q = c->quads + 4 * (5 + 99 * 3);
    CHECK(q[0] == 305 && q[1] == 306 && q[2] == 406 && q[3] == 405);
    q = c->quads + 4 * 9800;
    CHECK(q[0] == 9898 && q[1] == 9899 && q[2] == 9999 && q[3] == 9998);

    /* Each interior edge is shared by two quads: 2 * 100 * 99 distinct edges, the
     * 19,800 structural springs. */
    uint64_t edges = 4ull * c->quad_count;
    uint64_t boundary = 4ull * (100 - 1);
    CHECK_EQ((edges + boundary) / 2, 19800);
    rbc_scene_free(&s);
    CHECK(is_zeroed(&s, sizeof s));
}

static void test_default_equals_file(void) {
    rbc_scene file, builtin;
    char err[RBC_SCENE_ERROR_MAX];
    int rc_file = load_sample("hanging_cloth.json", &file, err, sizeof err);
    CHECK_EQ(rc_file, 0);
    int rc_builtin = rbc_scene_load_default(&builtin, err, sizeof err);
    CHECK_EQ(rc_builtin, 0);
    if (rc_builtin)
        fprintf(stderr, "%s\n", err);
    CHECK(rc_file == 0 && rc_builtin == 0 && scenes_equal(&file, &builtin));
    rbc_scene_free(&file);
    rbc_scene_free(&builtin);
    /* The built-in paper scene is hanging_cloth_paper.json. */
    rc_file = load_sample("hanging_cloth_paper.json", &file, err, sizeof err);
    CHECK_EQ(rc_file, 0);
    rc_builtin = rbc_scene_load_paper(&builtin, err, sizeof err);
    CHECK_EQ(rc_builtin, 0);
    CHECK(rc_file == 0 && rc_builtin == 0 && scenes_equal(&file, &builtin));
    rbc_scene_free(&file);
    rbc_scene_free(&builtin);
    /* rbc_scene_default_json() is the text the default is parsed from. */
    CHECK_EQ(rbc_scene_parse(rbc_scene_default_json(), strlen(rbc_scene_default_json()), "x",
                             &builtin, err, sizeof err),
             0);
    rbc_scene_free(&builtin);
}

static void test_cloth_on_sphere(void) {
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    int rc = load_sample("cloth_on_sphere.json", &s, err, sizeof err);
    CHECK_EQ(rc, 0);
    if (rc) {
        fprintf(stderr, "%s\n", err);
        return;
    }
    CHECK_EQ(s.cloth_count, 1);
    CHECK_EQ(s.collider_count, 2);
    int spheres = 0, planes = 0;
    for (uint32_t i = 0; i < s.collider_count; ++i) {
        spheres += s.colliders[i].shape == RBC_SHAPE_SPHERE;
        planes += s.colliders[i].shape == RBC_SHAPE_PLANE;
    }
    CHECK_EQ(spheres, 1);
    CHECK_EQ(planes, 1);
    /* The cloth starts above the sphere and the ground. */
    for (uint32_t i = 0; i < s.collider_count; ++i) {
        const rbc_scene_collider *k = &s.colliders[i];
        float top = k->position[1] + (k->shape == RBC_SHAPE_SPHERE ? k->radius : 0.0f);
        CHECK(s.cloths[0].positions[1] > top + k->thickness);
    }
    rbc_scene_free(&s);
}

static void test_inline_mesh(void) {
    /* Two quads sharing an edge, one pin; a rotated plane collider. */
    static const char json[] =
        "{\"name\": \"strip\", \"frames\": 3, \"dt\": 0.01,\n"
        " \"cloths\": [{\"vertices\": [[0,0,0],[1,0,0],[2,0,0],[0,0,1],[1,0,1],[2,0,1]],\n"
        "              \"quads\": [[0,1,4,3],[1,2,5,4]], \"pins\": [2], \"damping\": 0.5}],\n"
        " \"colliders\": [{\"shape\": \"plane\", \"position\": [0,-1,0],\n"
        "                  \"rotation\": [0, 0, 0.7071, 0.7071]}]}";
    rbc_scene s;
    if (parse_ok(json, sizeof json - 1, "strip.json", &s))
        return;
    const rbc_scene_cloth *c = &s.cloths[0];
    CHECK(strcmp(c->name, "cloth0") == 0); /* default name */
    CHECK_EQ(c->from_grid, 0);
    CHECK_EQ(c->vertex_count, 6);
    CHECK_EQ(c->quad_count, 2);
    CHECK(c->positions[3 * 5 + 0] == 2.0f && c->positions[3 * 5 + 2] == 1.0f);
    CHECK(c->quads[4] == 1 && c->quads[7] == 4);
    CHECK(c->pin_count == 1 && c->pins[0] == 2);
    CHECK(c->vertex_mass == 1e-4f && c->stiffness == 1000.0f && c->damping == 0.5f);
    /* World defaults are rbc_world_def's. */
    CHECK(s.world.gravity[1] == -9.81f);
    CHECK_EQ(s.world.substeps, 0); /* ABI 1.6: from the substep rate */
    CHECK(s.world.substep_rate == 480.0f);
    CHECK_EQ(s.world.linear_iterations, 11);
    /* The rotation is normalised exactly. */
    const float *r = s.colliders[0].rotation;
    CHECK_NEAR(sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]), 1.0, 1e-7);
    CHECK_EQ(s.colliders[0].shape, RBC_SHAPE_PLANE);
    CHECK(s.colliders[0].thickness == 0.0f);
    rbc_scene_free(&s);
}

/* Every malformed scene is refused with "SOURCE: KEY: reason". */
typedef struct bad_case {
    const char *json;
    const char *expect; /* substring of the message */
} bad_case;

/* c's json is refused as bad.json: rc -1, the scene left zeroed, and a message (into
 * err) that contains c->expect, else the failure is printed as case i of `table`.
 * Whether the message did. */
static int refused_with(const bad_case *c, const char *table, size_t i, char *err, size_t size) {
    rbc_scene s;
    memset(&s, 0xAB, sizeof s);
    err[0] = '\0';
    int rc = rbc_scene_parse(c->json, strlen(c->json), "bad.json", &s, err, size);
    CHECK_EQ(rc, -1);
    CHECK(is_zeroed(&s, sizeof s));
    const int named = strstr(err, c->expect) != NULL;
    if (!named) {
        CHECK(!"message names the key and the problem");
        fprintf(stderr, "  %s case %zu: expected \"%s\"\n  got \"%s\"\n", table, i, c->expect,
                err);
    }
    if (rc == 0)
        rbc_scene_free(&s);
    return named;
}

#define BASE_HEAD "{\"name\":\"t\",\"frames\":1,\"dt\":0.01,"
#define GRID_CLOTH "{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1}}"

static void test_malformed(void) {
    static const bad_case cases[] = {
        /* missing keys */
        {"{\"name\":\"t\",\"dt\":0.01,\"cloths\":[" GRID_CLOTH "]}",
         "bad.json: frames: required key is missing"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"ny\":3,\"spacing\":0.1}}]}",
         "bad.json: cloths[0].grid.nx: required key is missing"},
        {BASE_HEAD "\"cloths\":[{\"vertex_mass\":1}]}", "bad.json: cloths[0].grid: required key is missing"},
        {BASE_HEAD "\"cloths\":[{\"vertices\":[[0,0,0]]}]}", "cloths[0].quads: required key is missing"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"sphere\"}]}",
         "colliders[0].radius: required key is missing"},
        /* wrong types */
        {"{\"name\":\"t\",\"frames\":\"240\",\"dt\":0.01,\"cloths\":[" GRID_CLOTH "]}",
         "bad.json: frames: must be an integer in [1, 10000000], got a string"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":\"x\"}}]}",
         "cloths[0].grid.spacing: must be a number > 0, got a string"},
        {BASE_HEAD "\"cloths\":{}}", "bad.json: cloths: must be an array, got an object"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"world\":[]}", "bad.json: world: must be an object, got an array"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1,\"origin\":[0,0]}}]}",
         "cloths[0].grid.origin: must be an array of 3 numbers"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3.5,\"ny\":3,\"spacing\":0.1}}]}",
         "cloths[0].grid.nx: must be an integer in [2, 65536], got 3.5"},
        {"[1, 2]", "bad.json: (top level): must be an object, got an array"},
        /* out of range */
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":-5,\"ny\":3,\"spacing\":0.1}}]}",
         "bad.json: cloths[0].grid.nx: must be an integer in [2, 65536], got -5"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":100,\"ny\":100,\"spacing\":0.01},\"pins\":[0,10000]}]}",
         "bad.json: cloths[0].pins[1]: vertex index 10000 is out of range (the cloth has 10000 vertices)"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"pins\":[-1]}]}",
         "cloths[0].pins[0]: must be a vertex index (an integer >= 0), got -1"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"pins\":[4,2,4]}]}",
         "cloths[0].pins[2]: vertex 4 is pinned twice"},
        {"{\"name\":\"t\",\"frames\":1,\"dt\":0,\"cloths\":[" GRID_CLOTH "]}", "bad.json: dt: must be a number > 0, got 0"},
        {BASE_HEAD "\"cloths\":[]}", "bad.json: cloths: must have 1 to 1024 elements, got 0"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"stiffness\":1e39}]}",
         "cloths[0].stiffness: must be a number > 0 that fits a float, got 1e+39"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"damping\":-1}]}",
         "cloths[0].damping: must be a number >= 0, got -1"},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":65536,\"ny\":65536,\"spacing\":0.1}}]}",
         "cloths[0].grid: nx * ny = 4294967296 vertices, more than the limit of 16777216"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"world\":{\"substeps\":-1}}",
         "world.substeps: must be an integer in [0, 1024], got -1"},
        /* Grids are a few bytes that allocate nx * ny vertices: all of a scene's grids
         * share the one-grid limit (64 grids of 2^24 vertices ran out of memory). */
        {BASE_HEAD "\"cloths\":[{\"name\":\"a\",\"grid\":{\"nx\":4096,\"ny\":2048,\"spacing\":0.001}},"
                   "{\"name\":\"b\",\"grid\":{\"nx\":4096,\"ny\":2049,\"spacing\":0.001}}]}",
         "bad.json: cloths[1].grid: nx * ny = 8392704 vertices; with the 8388608 of the grids "
         "before it the scene would have 16781312, more than the limit of 16777216 for all its "
         "grids together"},
        /* bad choices and names */
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"world\":{\"backend\":\"gpu\"}}",
         "world.backend: must be one of \"auto\", \"cpu\", \"cuda\", got \"gpu\""},
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1,\"plane\":\"yz\"}}]}",
         "cloths[0].grid.plane: must be one of \"xz\", \"xy\", got \"yz\""},
        {"{\"name\":\"../evil\",\"frames\":1,\"dt\":0.01,\"cloths\":[" GRID_CLOTH "]}",
         "bad.json: name: must be 1 to 64 characters of [A-Za-z0-9_.-]"},
        {BASE_HEAD "\"cloths\":[{\"name\":\"a\",\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1}},"
                   "{\"name\":\"a\",\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1}}]}",
         "cloths[1]: cloth name \"a\" is already used by cloths[0]"},
        /* unknown and duplicate keys */
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"world\":{\"substep\":2}}",
         "bad.json: world.substep: unknown key; did you mean \"substeps\"? (expected one of: "
         "gravity, substeps,"},
        {BASE_HEAD "\"frames\":2,\"cloths\":[" GRID_CLOTH "]}", "bad.json: frames: key given twice"},
        /* meshes */
        {BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":2,\"ny\":2,\"spacing\":1},\"vertices\":[[0,0,0]],\"quads\":[[0,0,0,0]]}]}",
         "cloths[0]: give either \"grid\" or \"vertices\" and \"quads\", not both"},
        {BASE_HEAD "\"cloths\":[{\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],\"quads\":[[0,1,2,4]]}]}",
         "cloths[0].quads[0][3]: must be an integer in [0, 3], got 4"},
        {BASE_HEAD "\"cloths\":[{\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]],\"quads\":[[0,1,2,1]]}]}",
         "cloths[0].quads[0]: degenerate quad: vertex 1 appears twice"},
        {BASE_HEAD "\"cloths\":[{\"vertices\":[[0,0,0],[1,0]],\"quads\":[[0,1,1,0]]}]}",
         "cloths[0].vertices[1]: must be an array of 3 numbers"},
        /* colliders */
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"plane\",\"radius\":1}]}",
         "colliders[0].radius: not for a plane: only spheres and capsules have a radius"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"cube\"}]}",
         "colliders[0].shape: must be one of \"sphere\", \"plane\", \"capsule\", \"box\", "
         "\"mesh\", got \"cube\""},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"sphere\",\"radius\":1,\"rotation\":[0,0,0,2]}]}",
         "colliders[0].rotation: must be a unit quaternion [x, y, z, w], got one of length 2"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"sphere\",\"radius\":-0.5}]}",
         "colliders[0].radius: must be a number > 0, got -0.5"},
        /* JSON syntax */
        {"{\"name\": \"t\",\n \"frames\": 1,\n \"dt\": 0.01,,\n}", "bad.json:3:13: invalid JSON near ','"},
        {"{\"name\": \"t\"", "bad.json:1:13: invalid JSON: unexpected end of input"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "]} trailing", "bad.json:1:"},
        {"", "bad.json:1:1: invalid JSON: unexpected end of input"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char err[RBC_SCENE_ERROR_MAX];
        if (refused_with(&cases[i], "1.0", i, err, sizeof err))
            CHECK(strncmp(err, "bad.json", 8) == 0);
    }
}

/* The ABI 1.3 keys: every bad value names its key. */
#define C3 "\"cloths\":[" GRID_CLOTH "],"
#define COLLIDER(body) BASE_HEAD C3 "\"colliders\":[{" body "}]}"
#define CLOTH(body) BASE_HEAD "\"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1}," body "}]}"
#define DRAG(body) CLOTH("\"drags\":[{" body "}]")
#define KEYS(body) COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"keyframes\":[" body "]")
#define WIND(body) BASE_HEAD C3 "\"world\":{\"wind\":" body "}}"
#define TRI "\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0,0],[0,0,1]],"

/* How a scene chooses its solve: without a solver object the default solve
 * (RBC_PRESET_CLOTH) with substeps from the substep rate; a preset replaces the
 * default and the other keys change it; world counts are the world's. */
static void test_solver_rules(void) {
    static const struct {
        const char *world; /* the "world" object, or NULL for none */
        int preset;        /* what the solver must equal, before `kind`/`mode` edits */
        rbc_solver_kind kind;
        rbc_iteration_mode mode;
        uint32_t substeps;
        float rate;
    } cases[] = {
        {NULL, RBC_PRESET_CLOTH, RBC_SOLVER_RBGS_SOR, RBC_ITERATE_FIXED, 0, 480.0f},
        {"{\"threads\":1}", RBC_PRESET_CLOTH, RBC_SOLVER_RBGS_SOR, RBC_ITERATE_FIXED, 0, 480.0f},
        {"{\"substeps\":4}", RBC_PRESET_CLOTH, RBC_SOLVER_RBGS_SOR, RBC_ITERATE_FIXED, 4, 480.0f},
        {"{\"substep_rate\":960}", RBC_PRESET_CLOTH, RBC_SOLVER_RBGS_SOR, RBC_ITERATE_FIXED, 0,
         960.0f},
        {"{\"substeps\":4,\"solver\":{\"mode\":\"target\"}}", RBC_PRESET_CLOTH,
         RBC_SOLVER_RBGS_SOR, RBC_ITERATE_TARGET, 4, 480.0f},
        {"{\"solver\":{\"kind\":\"direct\"}}", RBC_PRESET_CLOTH, RBC_SOLVER_DIRECT,
         RBC_ITERATE_FIXED, 0, 480.0f},
        {"{\"substeps\":1,\"solver\":{\"preset\":\"paper\"}}", RBC_PRESET_PAPER,
         RBC_SOLVER_RBGS, RBC_ITERATE_FIXED, 1, 480.0f},
        {"{\"solver\":{\"preset\":\"game_60hz\"}}", RBC_PRESET_GAME_60HZ, RBC_SOLVER_RBGS,
         RBC_ITERATE_TARGET, 0, 480.0f},
        {"{\"solver\":{\"kind\":\"jacobi\",\"preset\":\"paper\"}}", RBC_PRESET_PAPER,
         RBC_SOLVER_JACOBI, RBC_ITERATE_FIXED, 0, 480.0f},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char text[512];
        snprintf(text, sizeof text, BASE_HEAD "%s%s%s\"cloths\":[" GRID_CLOTH "]}",
                 cases[i].world ? "\"world\":" : "", cases[i].world ? cases[i].world : "",
                 cases[i].world ? "," : "");
        rbc_scene s;
        char err[RBC_SCENE_ERROR_MAX];
        int rc = rbc_scene_parse(text, strlen(text), "rules.json", &s, err, sizeof err);
        CHECK_EQ(rc, 0);
        if (rc) {
            fprintf(stderr, "  case %zu: %s\n", i, err);
            continue;
        }
        rbc_solver_def want;
        rbc_scene_solver_preset(&want, cases[i].preset);
        want.solver = cases[i].kind;
        want.mode = cases[i].mode;
        CHECK(memcmp(&s.world.solver, &want, sizeof want) == 0);
        CHECK_EQ(s.world.substeps, cases[i].substeps);
        CHECK(s.world.substep_rate == cases[i].rate);
        if (memcmp(&s.world.solver, &want, sizeof want) != 0)
            fprintf(stderr, "  case %zu (%s): kind %d mode %d\n", i, text,
                    (int)s.world.solver.solver, (int)s.world.solver.mode);
        rbc_scene_free(&s);
    }
    /* An unknown preset names the choices and the likely one; so does a typo in a
     * key. */
    static const struct {
        const char *world, *expect;
    } bad[] = {
        {"{\"solver\":{\"preset\":\"fast\"}}", "world.solver.preset: must be one of \"paper\""},
        {"{\"solver\":{\"preset\":\"papr\"}}", "did you mean \"paper\"?"},
        {"{\"substep\":4}", "world.substep: unknown key; did you mean \"substeps\"?"},
        {"{\"substep_rate\":0}", "world.substep_rate"},
        {"{\"substeps\":1025}", "world.substeps"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        char text[512];
        snprintf(text, sizeof text, BASE_HEAD "\"world\":%s,\"cloths\":[" GRID_CLOTH "]}",
                 bad[i].world);
        rbc_scene s;
        char err[RBC_SCENE_ERROR_MAX];
        CHECK(rbc_scene_parse(text, strlen(text), "rules.json", &s, err, sizeof err) != 0);
        CHECK(strstr(err, bad[i].expect) != NULL);
        if (!strstr(err, bad[i].expect))
            fprintf(stderr, "  bad case %zu: got \"%s\", want \"%s\"\n", i, err, bad[i].expect);
    }
}

static void test_malformed_v1_3(void) {
    static const bad_case cases[] = {
        /* shapes */
        {COLLIDER("\"shape\":\"capsule\",\"half_length\":1"),
         "bad.json: colliders[0].radius: required key is missing (capsules need a radius)"},
        {COLLIDER("\"shape\":\"capsule\",\"radius\":0.1"),
         "bad.json: colliders[0].half_length: required key is missing"},
        {COLLIDER("\"shape\":\"capsule\",\"radius\":0.1,\"half_length\":-1"),
         "bad.json: colliders[0].half_length: must be a number > 0, got -1"},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":0.1,\"half_length\":1"),
         "bad.json: colliders[0].half_length: not for a sphere: only capsules have a half_length"},
        {COLLIDER("\"shape\":\"box\""), "bad.json: colliders[0].half_extents: required key is missing"},
        {COLLIDER("\"shape\":\"box\",\"half_extents\":[1,0,1]"),
         "bad.json: colliders[0].half_extents[1]: must be a number > 0, got 0"},
        {COLLIDER("\"shape\":\"box\",\"half_extents\":[1,1]"),
         "bad.json: colliders[0].half_extents: must be an array of 3 numbers"},
        {COLLIDER("\"shape\":\"box\",\"half_extents\":[1,1,1],\"radius\":1"),
         "bad.json: colliders[0].radius: not for a box: only spheres and capsules have a radius"},
        {COLLIDER("\"shape\":\"plane\",\"half_extents\":[1,1,1]"),
         "bad.json: colliders[0].half_extents: not for a plane: only boxes have half_extents"},
        {COLLIDER("\"shape\":\"plane\",\"friction\":-0.1"),
         "bad.json: colliders[0].friction: must be a number >= 0, got -0.1"},
        {COLLIDER("\"shape\":\"plane\",\"friction\":\"x\""),
         "bad.json: colliders[0].friction: must be a number >= 0, got a string"},
        /* meshes */
        {COLLIDER("\"shape\":\"mesh\""),
         "bad.json: colliders[0].vertices: required key is missing (a mesh needs"},
        {COLLIDER("\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0,0],[0,0,1]]"),
         "bad.json: colliders[0].triangles: required key is missing"},
        {COLLIDER(TRI "\"triangles\":[[0,1,3]]"),
         "bad.json: colliders[0].triangles[0][2]: must be an integer in [0, 2], got 3"},
        {COLLIDER(TRI "\"triangles\":[[0,1,2],[0,1,1]]"),
         "bad.json: colliders[0].triangles[1]: degenerate triangle: vertex 1 appears twice"},
        {COLLIDER(TRI "\"triangles\":[[0,1,2,0]]"),
         "bad.json: colliders[0].triangles[0]: must be an array of 3 vertex indices"},
        {COLLIDER(TRI "\"triangles\":[]"),
         "bad.json: colliders[0].triangles: must have 1 to"},
        {COLLIDER("\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0,0]],\"triangles\":[[0,1,0]]"),
         "bad.json: colliders[0].vertices: must have 3 to 16777216 elements, got 2"},
        {COLLIDER("\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0],[0,0,1]],\"triangles\":[[0,1,2]]"),
         "bad.json: colliders[0].vertices[1]: must be an array of 3 numbers"},
        {COLLIDER(TRI "\"triangles\":[[0,1,2]],\"file\":\"x.obj\""),
         "bad.json: colliders[0].file: give either \"file\" or \"vertices\" and \"triangles\""},
        {COLLIDER("\"shape\":\"mesh\",\"file\":\"/nonexistent/x.obj\""),
         "bad.json: colliders[0].file: cannot open /nonexistent/x.obj: No such file or directory"},
        {COLLIDER("\"shape\":\"mesh\",\"file\":\"\""), "bad.json: colliders[0].file: must name a mesh file"},
        {COLLIDER("\"shape\":\"mesh\",\"file\":5"),
         "bad.json: colliders[0].file: must be a string, got a number"},
        {COLLIDER(TRI "\"triangles\":[[0,1,2]],\"scale\":2"),
         "bad.json: colliders[0].scale: only mesh files have a scale"},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"scale\":2"),
         "bad.json: colliders[0].scale: not for a sphere: only mesh files have a scale"},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"vertices\":[]"),
         "bad.json: colliders[0].vertices: not for a sphere: only meshes have vertices"},
        /* motion */
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"velocity\":[0,0,1],\"keyframes\":[{\"time\":0}]"),
         "bad.json: colliders[0].keyframes: give either \"keyframes\" or \"velocity\"/\"angular_velocity\""},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"angular_velocity\":[0,0,1],\"keyframes\":[{\"time\":0}]"),
         "bad.json: colliders[0].keyframes: give either"},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"velocity\":[1,2]"),
         "bad.json: colliders[0].velocity: must be an array of 3 numbers"},
        {COLLIDER("\"shape\":\"sphere\",\"radius\":1,\"angular_velocity\":\"x\""),
         "bad.json: colliders[0].angular_velocity: must be an array of 3 numbers, got a string"},
        {KEYS(""), "bad.json: colliders[0].keyframes: must have 1 to 1000000 elements, got 0"},
        {KEYS("{\"position\":[0,0,0]}"), "bad.json: colliders[0].keyframes[0].time: required key is missing"},
        {KEYS("{\"time\":-1}"), "bad.json: colliders[0].keyframes[0].time: must be a number >= 0, got -1"},
        {KEYS("{\"time\":1},{\"time\":1}"),
         "bad.json: colliders[0].keyframes[1].time: keyframe times must increase: got 1 after 1"},
        {KEYS("{\"time\":0},{\"time\":1,\"rotation\":[0,0,0,3]}"),
         "bad.json: colliders[0].keyframes[1].rotation: must be a unit quaternion [x, y, z, w], got one of length 3"},
        {KEYS("{\"time\":0,\"position\":[1]}"),
         "bad.json: colliders[0].keyframes[0].position: must be an array of 3 numbers"},
        {KEYS("{\"time\":0,\"velocity\":[0,0,0]}"),
         "bad.json: colliders[0].keyframes[0].velocity: unknown key (expected one of: time, position, rotation)"},
        {KEYS("5"), "bad.json: colliders[0].keyframes[0]: must be an object, got a number"},
        /* cloths */
        {CLOTH("\"thickness\":-1"), "bad.json: cloths[0].thickness: must be a number >= 0, got -1"},
        {CLOTH("\"friction\":\"a\""), "bad.json: cloths[0].friction: must be a number >= 0, got a string"},
        {CLOTH("\"self_collision\":1"), "bad.json: cloths[0].self_collision: must be true or false, got a number"},
        {CLOTH("\"cloth_collision\":\"yes\""),
         "bad.json: cloths[0].cloth_collision: must be true or false, got a string"},
        {CLOTH("\"self_collision\":true"),
         "bad.json: cloths[0].self_collision: cloth contact needs a \"thickness\" > 0"},
        {CLOTH("\"cloth_collision\":true,\"thickness\":0"),
         "bad.json: cloths[0].cloth_collision: cloth contact needs a \"thickness\" > 0"},
        {CLOTH("\"tear_strain\":-0.5"), "bad.json: cloths[0].tear_strain: must be a number >= 0, got -0.5"},
        {CLOTH("\"tear_strain\":1e39"), "bad.json: cloths[0].tear_strain: must be a number >= 0 that fits a float"},
        /* drags */
        {CLOTH("\"drags\":{}"), "bad.json: cloths[0].drags: must be an array, got an object"},
        {DRAG("\"keyframes\":[{\"time\":0,\"target\":[0,0,0]}]"),
         "bad.json: cloths[0].drags[0].vertex: required key is missing"},
        {DRAG("\"vertex\":9,\"keyframes\":[{\"time\":0,\"target\":[0,0,0]}]"),
         "bad.json: cloths[0].drags[0].vertex: vertex index 9 is out of range (the cloth has 9 vertices)"},
        {DRAG("\"vertex\":1.5,\"keyframes\":[{\"time\":0,\"target\":[0,0,0]}]"),
         "bad.json: cloths[0].drags[0].vertex: must be a vertex index (an integer >= 0), got 1.5"},
        {DRAG("\"vertex\":1"), "bad.json: cloths[0].drags[0].keyframes: required key is missing"},
        {DRAG("\"vertex\":1,\"keyframes\":[{\"time\":0}]"),
         "bad.json: cloths[0].drags[0].keyframes[0].target: required key is missing"},
        {DRAG("\"vertex\":1,\"keyframes\":[{\"time\":0,\"target\":[0,0]}]"),
         "bad.json: cloths[0].drags[0].keyframes[0].target: must be an array of 3 numbers"},
        {DRAG("\"vertex\":1,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]},{\"time\":0.5,\"target\":[0,0,0]}]"),
         "bad.json: cloths[0].drags[0].keyframes[1].time: keyframe times must increase: got 0.5 after 1"},
        {DRAG("\"vertex\":1,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]}],\"release\":0.5"),
         "bad.json: cloths[0].drags[0].release: must be after the first keyframe (time 1), got 0.5"},
        {DRAG("\"vertex\":1,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]}],\"release\":\"x\""),
         "bad.json: cloths[0].drags[0].release: must be a number >= 0, got a string"},
        {DRAG("\"vertex\":1,\"pin\":true,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]}]"),
         "bad.json: cloths[0].drags[0].pin: unknown key (expected one of: vertex, keyframes, release)"},
        {CLOTH("\"drags\":[{\"vertex\":4,\"keyframes\":[{\"time\":0,\"target\":[0,0,0]}]},"
               "{\"vertex\":4,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]}]}]"),
         "bad.json: cloths[0].drags[1].vertex: vertex 4 is already dragged by cloths[0].drags[0]"},
        /* wind */
        {WIND("[]"), "bad.json: world.wind: must be an object, got an array"},
        {WIND("{\"drag\":1}"), "bad.json: world.wind.velocity: required key is missing"},
        {WIND("{\"velocity\":[1,0,0],\"drag\":-1}"), "bad.json: world.wind.drag: must be a number >= 0, got -1"},
        {WIND("{\"velocity\":[1,0,0],\"lift\":\"x\"}"),
         "bad.json: world.wind.lift: must be a number >= 0, got a string"},
        {WIND("{\"velocity\":[1,0]}"), "bad.json: world.wind.velocity: must be an array of 3 numbers"},
        {WIND("{\"velocity\":[1,0,0],\"speed\":1}"),
         "bad.json: world.wind.speed: unknown key (expected one of: velocity, drag, lift)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char err[RBC_SCENE_ERROR_MAX];
        refused_with(&cases[i], "1.3", i, err, sizeof err);
    }
}

/* Every 1.3 key with a good value reaches the scene struct. */
static void test_v1_3_keys(void) {
    static const char json[] =
        "{\"name\":\"all\",\"frames\":2,\"dt\":0.5,\n"
        " \"world\":{\"wind\":{\"velocity\":[1,0,-2],\"drag\":0.6,\"lift\":0.25}},\n"
        " \"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"thickness\":0.003,\"friction\":0.4,\n"
        "              \"self_collision\":true,\"cloth_collision\":false,\"tear_strain\":0.5,\n"
        "              \"drags\":[{\"vertex\":8,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]},\n"
        "                                       {\"time\":2,\"target\":[1,2,3]}],\"release\":3},\n"
        "                         {\"vertex\":0,\"keyframes\":[{\"time\":0,\"target\":[5,5,5]}]}]},\n"
        "            {\"grid\":{\"nx\":2,\"ny\":2,\"spacing\":0.1},\"thickness\":0.001,\"cloth_collision\":true}],\n"
        " \"colliders\":[\n"
        "  {\"shape\":\"capsule\",\"radius\":0.1,\"half_length\":0.3,\"friction\":0.2,\"velocity\":[0,1,0],\n"
        "   \"angular_velocity\":[0,0,3.14159]},\n"
        "  {\"shape\":\"box\",\"half_extents\":[0.1,0.2,0.3],\"position\":[1,2,3],\n"
        "   \"keyframes\":[{\"time\":0},{\"time\":1,\"position\":[2,2,3],\"rotation\":[0,0,1,0]}]},\n"
        "  {\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0,0],[0,0,1],[0,1,0]],\n"
        "   \"triangles\":[[0,1,2],[0,3,1]],\"thickness\":0.01},\n"
        "  {\"shape\":\"sphere\",\"radius\":0.5,\"angular_velocity\":[1,0,0]}]}";
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    if (parse_ok(json, sizeof json - 1, "all.json", &s))
        return;
    CHECK(strcmp(s.source, "all.json") == 0);
    CHECK_EQ(s.world.has_wind, 1);
    CHECK(s.world.wind_velocity[0] == 1.0f && s.world.wind_velocity[2] == -2.0f);
    CHECK(s.world.wind_drag == 0.6f && s.world.wind_lift == 0.25f);
    const rbc_scene_cloth *c = &s.cloths[0];
    CHECK(c->thickness == 0.003f && c->friction == 0.4f && c->tear_strain == 0.5f);
    CHECK_EQ(c->collision_flags, RBC_CLOTH_COLLIDE_SELF);
    CHECK_EQ(s.cloths[1].collision_flags, RBC_CLOTH_COLLIDE_CLOTHS);
    CHECK_EQ(c->drag_count, 2);
    CHECK(c->drags[0].vertex == 8 && c->drags[0].key_count == 2 && c->drags[0].release == 3.0);
    CHECK(c->drags[0].keys[1].time == 2.0 && c->drags[0].keys[1].target[2] == 3.0f);
    CHECK(c->drags[1].vertex == 0 && c->drags[1].release < 0.0);
    CHECK_EQ(s.collider_count, 4);
    const rbc_scene_collider *k = s.colliders;
    CHECK_EQ(k[0].shape, RBC_SHAPE_CAPSULE);
    CHECK(k[0].radius == 0.1f && k[0].half_extents[1] == 0.3f && k[0].half_extents[0] == 0.0f);
    CHECK(k[0].friction == 0.2f);
    CHECK_EQ(k[0].motion, RBC_SCENE_MOTION_VELOCITY);
    CHECK(k[0].velocity[1] == 1.0f && k[0].angular_velocity[2] == 3.14159f);
    CHECK_EQ(k[1].shape, RBC_SHAPE_BOX);
    CHECK(k[1].half_extents[0] == 0.1f && k[1].half_extents[1] == 0.2f && k[1].half_extents[2] == 0.3f);
    CHECK(k[1].radius == 0.0f);
    CHECK_EQ(k[1].motion, RBC_SCENE_MOTION_KEYFRAMES);
    CHECK_EQ(k[1].key_count, 2);
    /* A keyframe without position or rotation takes the collider's. */
    CHECK(k[1].keys[0].position[0] == 1.0f && k[1].keys[0].position[2] == 3.0f);
    CHECK(k[1].keys[0].rotation[3] == 1.0f);
    CHECK(k[1].keys[1].position[0] == 2.0f && k[1].keys[1].rotation[2] == 1.0f);
    CHECK_EQ(k[2].shape, RBC_SHAPE_TRIANGLE_MESH);
    CHECK(k[2].mesh_vertex_count == 4 && k[2].mesh_triangle_count == 2);
    CHECK(k[2].mesh_positions[3 * 3 + 1] == 1.0f);
    CHECK(k[2].mesh_triangles[3] == 0 && k[2].mesh_triangles[4] == 3 && k[2].mesh_triangles[5] == 1);
    CHECK(k[2].mesh_file == NULL && k[2].thickness == 0.01f);
    CHECK_EQ(k[2].motion, RBC_SCENE_MOTION_NONE);
    /* angular_velocity alone: turning in place. */
    CHECK_EQ(k[3].motion, RBC_SCENE_MOTION_VELOCITY);
    char key[128];
    CHECK_EQ(rbc_scene_needs_v1_3(&s, key, sizeof key), 1);
    CHECK(strcmp(key, "world.wind") == 0);
    rbc_scene_free(&s);
    CHECK(is_zeroed(&s, sizeof s));

    /* needs_v1_3 names the first 1.3 key; the existing scenes need none. */
    CHECK_EQ(load_sample("hanging_cloth.json", &s, err, sizeof err), 0);
    CHECK_EQ(rbc_scene_needs_v1_3(&s, key, sizeof key), 0);
    CHECK(key[0] == '\0');
    rbc_scene_free(&s);
    CHECK_EQ(load_sample("cloth_on_sphere.json", &s, err, sizeof err), 0);
    CHECK_EQ(rbc_scene_needs_v1_3(&s, key, sizeof key), 0);
    rbc_scene_free(&s);
    CHECK_EQ(load_sample("cloth_on_chair.json", &s, err, sizeof err), 0);
    CHECK_EQ(rbc_scene_needs_v1_3(&s, key, sizeof key), 1);
    CHECK(strcmp(key, "cloths[0].thickness") == 0);
    rbc_scene_free(&s);

    /* A mesh file is resolved against the scene file's directory. */
    char path[1024], text[512];
    snprintf(path, sizeof path, "%s/inline.json", scenes_dir);
    snprintf(text, sizeof text,
             BASE_HEAD C3 "\"colliders\":[{\"shape\":\"mesh\",\"file\":\"../meshes/tri_patch.obj\","
                          "\"scale\":0.5}]}");
    int rc = rbc_scene_parse(text, strlen(text), path, &s, err, sizeof err);
    CHECK_EQ(rc, 0);
    if (rc == 0) {
        char expect[1024];
        snprintf(expect, sizeof expect, "%s/../meshes/tri_patch.obj", scenes_dir);
        CHECK(strcmp(s.colliders[0].mesh_file, expect) == 0);
        CHECK(s.colliders[0].mesh_scale == 0.5f);
        rbc_scene_free(&s);
    } else {
        fprintf(stderr, "%s\n", err);
    }
    snprintf(text, sizeof text,
             BASE_HEAD C3 "\"colliders\":[{\"shape\":\"mesh\",\"file\":\"../meshes/tri_patch.obj\","
                          "\"scale\":0}]}");
    CHECK_EQ(rbc_scene_parse(text, strlen(text), path, &s, err, sizeof err), -1);
    CHECK(strstr(err, "inline.json: colliders[0].scale: must be a number > 0, got 0") != NULL);
    snprintf(text, sizeof text,
             BASE_HEAD C3 "\"colliders\":[{\"shape\":\"mesh\",\"file\":\"no_such_mesh.obj\"}]}");
    CHECK_EQ(rbc_scene_parse(text, strlen(text), path, &s, err, sizeof err), -1);
    CHECK(strstr(err, "inline.json: colliders[0].file: cannot open ") != NULL);
    CHECK(strstr(err, "/no_such_mesh.obj: No such file or directory") != NULL);
}

/* Collider keyframes: linear positions, normalised-lerp rotations, the first pose held
 * before and the last after; velocity motion; drags. Expected values worked out by
 * hand; tolerances are float rounding of numbers of order 1 (2^-23 ~ 1.2e-7, a few
 * roundings). */
static void test_motion_numbers(void) {
    const double tol = 5e-7;
    const double h = sqrt(0.5); /* sin 45 deg = cos 45 deg */
    rbc_scene_collider_key keys[3] = {
        {1.0, {0, 0, 0}, {0, 0, 0, 1}},
        {3.0, {2, 4, -6}, {0, 0, (float)h, (float)h}}, /* 90 deg about z */
        {4.0, {2, 4, -6}, {0, 0, -(float)h, -(float)h}}, /* the same rotation as -q */
    };
    rbc_scene_collider c;
    memset(&c, 0, sizeof c);
    c.shape = RBC_SHAPE_SPHERE;
    c.position[1] = 9.0f; /* the creation pose: not used by keyframed colliders */
    c.rotation[3] = 1.0f;
    c.motion = RBC_SCENE_MOTION_KEYFRAMES;
    c.key_count = 3;
    c.keys = keys;
    float p[3], q[4];
    /* Before the first keyframe: its pose, bit for bit. */
    rbc_scene_collider_pose(&c, 0.0, p, q);
    CHECK(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f && q[3] == 1.0f && q[2] == 0.0f);
    rbc_scene_collider_pose(&c, 1.0, p, q);
    CHECK(p[1] == 0.0f && q[3] == 1.0f);
    /* Half way: position (1, 2, -3); nlerp at the midpoint is the slerp, 45 deg about z:
     * (0, 0, sin 22.5, cos 22.5). */
    rbc_scene_collider_pose(&c, 2.0, p, q);
    CHECK_NEAR(p[0], 1.0, tol);
    CHECK_NEAR(p[1], 2.0, tol);
    CHECK_NEAR(p[2], -3.0, tol);
    CHECK_NEAR(q[0], 0.0, 0.0);
    CHECK_NEAR(q[2], sin(TEST_PI / 8), tol);
    CHECK_NEAR(q[3], cos(TEST_PI / 8), tol);
    /* Three quarters: position (1.5, 3, -4.5); nlerp (1/4) q0 + (3/4) q1, normalised:
     * z = 0.75 h / |(0.75 h, 0.25 + 0.75 h)|. */
    rbc_scene_collider_pose(&c, 2.5, p, q);
    CHECK_NEAR(p[0], 1.5, tol);
    CHECK_NEAR(p[1], 3.0, tol);
    CHECK_NEAR(p[2], -4.5, tol);
    double qz = 0.75 * h, qw = 0.25 + 0.75 * h, n = sqrt(qz * qz + qw * qw);
    CHECK_NEAR(q[2], qz / n, tol);
    CHECK_NEAR(q[3], qw / n, tol);
    CHECK_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, tol);
    /* q1 to -q1 is no rotation at all: the shorter arc keeps the orientation (up to
     * the sign of q). */
    rbc_scene_collider_pose(&c, 3.5, p, q);
    CHECK_NEAR(fabs(q[2]), h, tol);
    CHECK_NEAR(fabs(q[3]), h, tol);
    CHECK(q[2] * q[3] > 0.0f);
    /* After the last keyframe: its pose. */
    rbc_scene_collider_pose(&c, 100.0, p, q);
    CHECK(p[2] == -6.0f && q[2] == -(float)h && q[3] == -(float)h);

    /* Velocity motion: (1, 0, 0) + (0, 2, 0) t; pi rad/s about z after 90 deg about x.
     * At t = 0.5: position (1, 1, 0), rotation (0, 0, h, h) * (h, 0, 0, h) =
     * (0.5, 0.5, 0.5, 0.5). */
    rbc_scene_collider v;
    memset(&v, 0, sizeof v);
    v.position[0] = 1.0f;
    v.rotation[0] = (float)h;
    v.rotation[3] = (float)h;
    v.motion = RBC_SCENE_MOTION_VELOCITY;
    v.velocity[1] = 2.0f;
    v.angular_velocity[2] = (float)TEST_PI;
    rbc_scene_collider_pose(&v, 0.5, p, q);
    CHECK(p[0] == 1.0f && p[1] == 1.0f && p[2] == 0.0f);
    for (int i = 0; i < 4; ++i)
        CHECK_NEAR(q[i], 0.5, tol);
    /* Without a turn the rotation is kept bit for bit. */
    v.angular_velocity[2] = 0.0f;
    rbc_scene_collider_pose(&v, 0.25, p, q);
    CHECK(p[1] == 0.5f && q[0] == (float)h && q[3] == (float)h);
    /* No motion: the creation pose bit for bit, at any time. */
    v.motion = RBC_SCENE_MOTION_NONE;
    rbc_scene_collider_pose(&v, 7.0, p, q);
    CHECK(p[0] == 1.0f && p[1] == 0.0f && q[0] == (float)h);

    /* Drags: waiting before the first keyframe, linear in between, held at the last
     * target, released at `release`. */
    rbc_scene_drag_key dk[2] = {{1.0, {0, 0, 0}}, {2.0, {1, 2, 3}}};
    rbc_scene_drag d = {5, 2, dk, 3.0};
    float t[3] = {-1, -1, -1};
    CHECK_EQ(rbc_scene_drag_target(&d, 0.5, t), RBC_SCENE_DRAG_WAITING);
    CHECK(t[0] == -1.0f);
    CHECK_EQ(rbc_scene_drag_target(&d, 1.0, t), RBC_SCENE_DRAG_PINNED);
    CHECK(t[0] == 0.0f && t[1] == 0.0f && t[2] == 0.0f);
    CHECK_EQ(rbc_scene_drag_target(&d, 1.25, t), RBC_SCENE_DRAG_PINNED);
    CHECK(t[0] == 0.25f && t[1] == 0.5f && t[2] == 0.75f);
    CHECK_EQ(rbc_scene_drag_target(&d, 2.5, t), RBC_SCENE_DRAG_PINNED);
    CHECK(t[0] == 1.0f && t[1] == 2.0f && t[2] == 3.0f);
    CHECK_EQ(rbc_scene_drag_target(&d, 3.0, t), RBC_SCENE_DRAG_RELEASED);
    d.release = -1.0;
    CHECK_EQ(rbc_scene_drag_target(&d, 1e6, t), RBC_SCENE_DRAG_PINNED);
}

static void test_messages(void) {
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    /* A file that does not exist. */
    CHECK_EQ(rbc_scene_load_file("/nonexistent/scene.json", &s, err, sizeof err), -1);
    CHECK(strstr(err, "/nonexistent/scene.json: cannot open: No such file or directory") != NULL);
    /* A NUL byte inside the text. */
    static const char with_nul[] = "{\"name\":\"t\"}\0{}";
    CHECK_EQ(rbc_scene_parse(with_nul, sizeof with_nul - 1, "nul.json", &s, err, sizeof err), -1);
    CHECK(strstr(err, "nul.json: (file): contains a NUL byte") != NULL);
    /* A small buffer is filled, cut and terminated, never overrun. */
    char small[12];
    memset(small, 'x', sizeof small);
    CHECK_EQ(rbc_scene_parse("[]", 2, "bad.json", &s, small, 8), -1);
    CHECK(strcmp(small, "bad.jso") == 0 && small[8] == 'x');
    /* No buffer at all. */
    CHECK_EQ(rbc_scene_parse("[]", 2, "bad.json", &s, NULL, 0), -1);
    CHECK_EQ(rbc_scene_parse("{", 1, "bad.json", &s, NULL, 0), -1);
    /* The text need not be NUL-terminated: only `length` bytes are read. */
    const char *text = rbc_scene_default_json();
    char *copy = malloc(strlen(text) + 8);
    memcpy(copy, text, strlen(text));
    memcpy(copy + strlen(text), "garbage", 8);
    CHECK_EQ(rbc_scene_parse(copy, strlen(text), "copy", &s, err, sizeof err), 0);
    free(copy);
    rbc_scene_free(&s);
    rbc_scene_free(&s); /* twice is harmless */
}

/* ------------------------------------------------------------------------- */
/* rbc_scene_instantiate against a scripted function table                   */
/* ------------------------------------------------------------------------- */

static struct {
    int worlds_created, worlds_destroyed, cloths_created, colliders_created;
    int fail_cloth_at; /* 1-based cloth_create call that fails; 0 = none */
    rbc_world_def world_def;
    rbc_cloth_def cloth_def;
    rbc_collider_def collider_def;
    /* ABI 1.3: the last collider's mesh (copied: the def's arrays live only during
     * the call), wind, transforms and pins. */
    float mesh_positions[12];
    uint32_t mesh_triangles[12];
    int winds;
    float wind[5];
    int transforms, pins, releases;
    rbc_collider_id last_collider;
    float last_position[3], last_rotation[4];
    uint32_t last_vertex;
    float last_target[3];
    char imported[1024];
    float import_scale;
    int fail_import;
} fake;

static const char *RBC_CALL fake_last_error(void) { return "cloth def: vertex 3 is bad"; }
static const char *RBC_CALL fake_result_string(rbc_result r) {
    return r == RBC_ERR_BAD_MESH ? "RBC_ERR_BAD_MESH" : "other";
}
/* The fakes record the size asked for: a host must ask at its own struct size. */
static uint32_t fake_init_sizes[3];
static rbc_result RBC_CALL fake_world_def_init(rbc_world_def *d, uint32_t size) {
    fake_init_sizes[0] = size;
    memset(d, 0, sizeof *d);
    d->struct_size = size;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_cloth_def_init(rbc_cloth_def *d, uint32_t size) {
    fake_init_sizes[1] = size;
    memset(d, 0, sizeof *d);
    d->struct_size = size;
    d->density = 5.0f; /* must be reset: the scene gives per-vertex masses */
    return RBC_OK;
}
static rbc_result RBC_CALL fake_collider_def_init(rbc_collider_def *d, uint32_t size) {
    fake_init_sizes[2] = size;
    memset(d, 0, sizeof *d);
    d->struct_size = size;
    d->radius = 0.5f;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_world_create(const rbc_world_def *def, rbc_world_id *out) {
    fake.world_def = *def;
    fake.worlds_created++;
    *out = 42;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_world_destroy(rbc_world_id world) {
    fake.worlds_destroyed += world == 42;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_cloth_create(rbc_world_id world, const rbc_cloth_def *def,
                                             rbc_cloth_id *out) {
    fake.cloth_def = *def;
    if (++fake.cloths_created == fake.fail_cloth_at)
        return RBC_ERR_BAD_MESH;
    *out = 100 + (rbc_cloth_id)fake.cloths_created;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_collider_create(rbc_world_id world, const rbc_collider_def *def,
                                                rbc_collider_id *out) {
    fake.collider_def = *def;
    if (def->struct_size == sizeof *def && def->mesh_positions && def->mesh_vertex_count <= 4 &&
        def->mesh_triangle_count <= 4) {
        memcpy(fake.mesh_positions, def->mesh_positions, 12 * def->mesh_vertex_count);
        memcpy(fake.mesh_triangles, def->mesh_triangles, 12 * def->mesh_triangle_count);
    }
    *out = 200 + (rbc_collider_id)++fake.colliders_created;
    return RBC_OK;
}

static void RBC_CALL fake_log(void *user, rbc_log_level level, const char *message) {}

static rbc_result RBC_CALL fake_set_wind(rbc_world_id world, const float v[3], float drag,
                                         float lift) {
    fake.winds++;
    memcpy(fake.wind, v, 3 * sizeof *v);
    fake.wind[3] = drag;
    fake.wind[4] = lift;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_set_transform(rbc_world_id world, rbc_collider_id collider,
                                              const float position[3], const float rotation[4]) {
    fake.transforms++;
    fake.last_collider = collider;
    memcpy(fake.last_position, position, sizeof fake.last_position);
    memcpy(fake.last_rotation, rotation, sizeof fake.last_rotation);
    return RBC_OK;
}
static rbc_result RBC_CALL fake_set_pin(rbc_world_id world, rbc_cloth_id cloth, uint32_t vertex,
                                        const float *target) {
    fake.last_vertex = vertex;
    if (target) {
        fake.pins++;
        memcpy(fake.last_target, target, sizeof fake.last_target);
    } else {
        fake.releases++;
    }
    return RBC_OK;
}
/* A "file" that is a tetrahedron: 4 vertices, 4 triangles. */
static const float tetra_positions[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const uint32_t tetra_triangles[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
static rbc_result RBC_CALL fake_mesh_import_def_init(rbc_mesh_import_def *d, uint32_t size) {
    memset(d, 0, sizeof *d);
    d->struct_size = size;
    d->scale = 1.0f;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_mesh_import(const char *path, const rbc_mesh_import_def *d,
                                            rbc_mesh_id *out) {
    snprintf(fake.imported, sizeof fake.imported, "%s", path);
    fake.import_scale = d->scale;
    if (fake.fail_import)
        return RBC_ERR_BAD_MESH;
    *out = 7;
    return RBC_OK;
}
static rbc_result RBC_CALL fake_mesh_destroy(rbc_mesh_id mesh) { return RBC_OK; }
static rbc_result RBC_CALL fake_mesh_get_positions(rbc_mesh_id mesh, float *xyz, size_t capacity,
                                                   size_t *out_count) {
    if (out_count)
        *out_count = 12;
    if (xyz && capacity >= 12)
        memcpy(xyz, tetra_positions, sizeof tetra_positions);
    return RBC_OK;
}
static rbc_result RBC_CALL fake_mesh_get_triangles(rbc_mesh_id mesh, uint32_t *tris,
                                                   size_t capacity, size_t *out_count) {
    if (out_count)
        *out_count = 12;
    if (tris && capacity >= 12)
        memcpy(tris, tetra_triangles, sizeof tetra_triangles);
    return RBC_OK;
}

/* The function table of the fakes above as a library of ABI 1.minor fills it: creation
 * (1.0), and from 1.3 motion, drags, wind and mesh files; NULL for the rest. */
static rbc_api_v1 fake_api(int minor) {
    rbc_api_v1 api;
    memset(&api, 0, sizeof api);
    api.struct_size = sizeof api;
    api.abi_version = RBC_ABI_VERSION;
    api.last_error = fake_last_error;
    api.result_string = fake_result_string;
    api.world_def_init = fake_world_def_init;
    api.cloth_def_init = fake_cloth_def_init;
    api.collider_def_init = fake_collider_def_init;
    api.world_create = fake_world_create;
    api.world_destroy = fake_world_destroy;
    api.cloth_create = fake_cloth_create;
    api.collider_create = fake_collider_create;
    if (minor >= 3) {
        api.collider_set_transform = fake_set_transform;
        api.cloth_set_pin = fake_set_pin;
        api.world_set_wind = fake_set_wind;
        api.mesh_import_def_init = fake_mesh_import_def_init;
        api.mesh_import = fake_mesh_import;
        api.mesh_destroy = fake_mesh_destroy;
        api.mesh_get_positions = fake_mesh_get_positions;
        api.mesh_get_triangles = fake_mesh_get_triangles;
    }
    return api;
}

static void test_instantiate(void) {
    rbc_api_v1 api = fake_api(0);

    static const char json[] =
        "{\"name\":\"two\",\"frames\":1,\"dt\":0.01,\n"
        " \"world\":{\"gravity\":[0,0,-1],\"substeps\":3,\"nonlinear_iterations\":2,\n"
        "           \"linear_iterations\":7,\"threads\":5,\"backend\":\"cpu\"},\n"
        " \"cloths\":[{\"name\":\"a\",\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"pins\":[1],\n"
        "             \"vertex_mass\":0.5,\"stiffness\":20,\"damping\":0.25},\n"
        "            {\"name\":\"b\",\"grid\":{\"nx\":4,\"ny\":2,\"spacing\":0.1}}],\n"
        " \"colliders\":[{\"shape\":\"sphere\",\"radius\":0.3,\"thickness\":0.01,\"position\":[1,2,3]},\n"
        "               {\"shape\":\"plane\"}]}";
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    CHECK_EQ(rbc_scene_parse(json, sizeof json - 1, "two.json", &s, err, sizeof err), 0);

    /* Success: every field reaches the defs, struct_size is the host's. */
    memset(&fake, 0, sizeof fake);
    rbc_scene_instance inst;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, fake_log, &fake, &inst, err, sizeof err), RBC_OK);
    CHECK_EQ(inst.world, 42);
    CHECK_EQ(inst.cloth_count, 2);
    CHECK_EQ(inst.collider_count, 2);
    CHECK(inst.cloths[0] == 101 && inst.cloths[1] == 102);
    CHECK(inst.colliders[0] == 201 && inst.colliders[1] == 202);
    CHECK_EQ(fake.world_def.struct_size, sizeof(rbc_world_def));
    CHECK_EQ(fake_init_sizes[0], sizeof(rbc_world_def));
    CHECK_EQ(fake_init_sizes[1], sizeof(rbc_cloth_def));
    CHECK_EQ(fake_init_sizes[2], sizeof(rbc_collider_def));
    CHECK(fake.world_def.gravity[2] == -1.0f);
    CHECK_EQ(fake.world_def.substeps, 3);
    CHECK_EQ(fake.world_def.nonlinear_iterations, 2);
    CHECK_EQ(fake.world_def.linear_iterations, 7);
    CHECK_EQ(fake.world_def.thread_count, 5);
    CHECK_EQ(fake.world_def.backend, RBC_BACKEND_CPU);
    CHECK(fake.world_def.log == fake_log && fake.world_def.log_user == &fake);
    CHECK_EQ(fake.cloth_def.struct_size, sizeof(rbc_cloth_def));
    CHECK_EQ(fake.cloth_def.vertex_count, 8); /* the last cloth created: b */
    CHECK_EQ(fake.cloth_def.quad_count, 3);
    CHECK(fake.cloth_def.density == 0.0f && fake.cloth_def.masses == NULL);
    CHECK(fake.cloth_def.vertex_mass == 1e-4f && fake.cloth_def.pin_count == 0);
    CHECK_EQ(fake.collider_def.struct_size, sizeof(rbc_collider_def));
    CHECK_EQ(fake.collider_def.shape, RBC_SHAPE_PLANE);
    rbc_scene_instance_destroy(&api, &inst);
    CHECK_EQ(fake.worlds_destroyed, 1);
    CHECK(is_zeroed(&inst, sizeof inst));

    /* Failure at the second cloth: the world is destroyed, the message is the
     * library's plus what was being created, and nothing is handed out. */
    memset(&fake, 0, sizeof fake);
    fake.fail_cloth_at = 2;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_ERR_BAD_MESH);
    CHECK(strcmp(err, "cloth def: vertex 3 is bad (creating cloths[1] \"b\")") == 0);
    CHECK_EQ(fake.worlds_created, 1);
    CHECK_EQ(fake.worlds_destroyed, 1);
    CHECK_EQ(fake.colliders_created, 0);
    CHECK(is_zeroed(&inst, sizeof inst));
    CHECK(fake.world_def.log == NULL);

    /* Cloth a's material: create a scene holding only a. */
    memset(&fake, 0, sizeof fake);
    fake.fail_cloth_at = 0;
    s.cloth_count = 1; /* only a */
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK(fake.cloth_def.vertex_mass == 0.5f && fake.cloth_def.stiffness == 20.0f &&
          fake.cloth_def.damping == 0.25f);
    CHECK(fake.cloth_def.pin_count == 1 && fake.cloth_def.pins[0] == 1);
    CHECK(fake.cloth_def.positions == s.cloths[0].positions);
    rbc_scene_instance_destroy(&api, &inst);
    s.cloth_count = 2;

    /* The sphere reached its def. */
    memset(&fake, 0, sizeof fake);
    s.collider_count = 1;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK_EQ(fake.collider_def.shape, RBC_SHAPE_SPHERE);
    CHECK(fake.collider_def.radius == 0.3f && fake.collider_def.thickness == 0.01f);
    CHECK(fake.collider_def.position[2] == 3.0f && fake.collider_def.rotation[3] == 1.0f);
    rbc_scene_instance_destroy(&api, &inst);
    s.collider_count = 2;

    /* NULL arguments. */
    CHECK_EQ(rbc_scene_instantiate(NULL, &s, NULL, NULL, &inst, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    rbc_scene_instance_destroy(&api, NULL);
    rbc_scene_free(&s);
}


/* ABI 1.3 through the scripted table: the new def fields, wind, mesh files, moving
 * colliders and drags per frame, and what an older library gets. */
static void test_instantiate_v1_3(void) {
    rbc_api_v1 api = fake_api(3);

    static const char json[] =
        "{\"name\":\"new\",\"frames\":8,\"dt\":0.5,\n"
        " \"world\":{\"wind\":{\"velocity\":[3,0,0],\"drag\":0.6,\"lift\":0.1}},\n"
        " \"cloths\":[{\"grid\":{\"nx\":3,\"ny\":3,\"spacing\":0.1},\"thickness\":0.002,\"friction\":0.3,\n"
        "              \"self_collision\":true,\"cloth_collision\":true,\"tear_strain\":0.4,\n"
        "              \"drags\":[{\"vertex\":4,\"keyframes\":[{\"time\":1,\"target\":[0,0,0]},\n"
        "                                               {\"time\":2,\"target\":[1,2,3]}],\"release\":3}]}],\n"
        " \"colliders\":[\n"
        "  {\"shape\":\"capsule\",\"radius\":0.1,\"half_length\":0.3,\"friction\":0.2},\n"
        "  {\"shape\":\"box\",\"half_extents\":[0.1,0.2,0.3],\"position\":[9,9,9],\n"
        "   \"keyframes\":[{\"time\":1,\"position\":[0,1,0]},{\"time\":2,\"position\":[2,1,0]}]},\n"
        "  {\"shape\":\"mesh\",\"vertices\":[[0,0,0],[1,0,0],[0,0,1]],\"triangles\":[[0,2,1]]}]}";
    rbc_scene s;
    if (parse_ok(json, sizeof json - 1, "new.json", &s))
        return;
    memset(&fake, 0, sizeof fake);
    char err[RBC_SCENE_ERROR_MAX];
    rbc_scene_instance inst;
    rbc_result r = rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err);
    CHECK_EQ(r, RBC_OK);
    if (r != RBC_OK)
        fprintf(stderr, "%s\n", err);
    CHECK_EQ(fake_init_sizes[1], sizeof(rbc_cloth_def));
    CHECK_EQ(fake_init_sizes[2], sizeof(rbc_collider_def));
    CHECK(fake.cloth_def.thickness == 0.002f && fake.cloth_def.friction == 0.3f);
    CHECK_EQ(fake.cloth_def.collision_flags, RBC_CLOTH_COLLIDE_SELF | RBC_CLOTH_COLLIDE_CLOTHS);
    CHECK(fake.cloth_def.tear_strain == 0.4f);
    /* The last collider is the inline mesh. */
    CHECK_EQ(fake.collider_def.shape, RBC_SHAPE_TRIANGLE_MESH);
    CHECK(fake.collider_def.mesh_vertex_count == 3 && fake.collider_def.mesh_triangle_count == 1);
    CHECK(fake.mesh_positions[3] == 1.0f && fake.mesh_triangles[1] == 2);
    CHECK_EQ(fake.winds, 1);
    CHECK(fake.wind[0] == 3.0f && fake.wind[3] == 0.6f && fake.wind[4] == 0.1f);
    rbc_scene_instance_destroy(&api, &inst);

    /* The capsule: radius, half length in half_extents[1], friction. */
    s.collider_count = 1;
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK_EQ(fake.collider_def.shape, RBC_SHAPE_CAPSULE);
    CHECK(fake.collider_def.radius == 0.1f && fake.collider_def.half_extents[1] == 0.3f);
    CHECK(fake.collider_def.friction == 0.2f);
    rbc_scene_instance_destroy(&api, &inst);
    /* The keyframed box is created at its first keyframe's pose, not "position". */
    s.collider_count = 2;
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK_EQ(fake.collider_def.shape, RBC_SHAPE_BOX);
    CHECK(fake.collider_def.half_extents[0] == 0.1f && fake.collider_def.half_extents[2] == 0.3f);
    CHECK(fake.collider_def.position[0] == 0.0f && fake.collider_def.position[1] == 1.0f);

    /* Per frame (dt 0.5 s): frame k sets the pose and pins of t = (k + 1) 0.5 s. Only
     * the moving box is moved; the drag waits until t = 1, follows its keyframes,
     * holds the last target and is released once, at t = 3. */
    static const struct {
        uint32_t frame;
        int transforms, pins, releases;
        float box_x, target_z;
    } expect[] = {
        {0, 1, 0, 0, 0.0f, -1.0f}, /* t = 0.5: before both */
        {1, 2, 1, 0, 0.0f, 0.0f},  /* t = 1.0: first keyframes */
        {2, 3, 2, 0, 1.0f, 1.5f},  /* t = 1.5: half way */
        {3, 4, 3, 0, 2.0f, 3.0f},  /* t = 2.0: last keyframes */
        {4, 5, 4, 0, 2.0f, 3.0f},  /* t = 2.5: held */
        {5, 6, 4, 1, 2.0f, 3.0f},  /* t = 3.0: released */
        {6, 7, 4, 1, 2.0f, 3.0f},  /* t = 3.5: nothing more */
    };
    memset(&fake, 0, sizeof fake);
    fake.last_target[2] = -1.0f;
    for (size_t i = 0; i < sizeof expect / sizeof expect[0]; ++i) {
        CHECK_EQ(rbc_scene_apply_frame(&api, &s, &inst, expect[i].frame, err, sizeof err), RBC_OK);
        CHECK_EQ(fake.transforms, expect[i].transforms);
        CHECK_EQ(fake.pins, expect[i].pins);
        CHECK_EQ(fake.releases, expect[i].releases);
        CHECK_EQ(fake.last_collider, inst.colliders[1]);
        CHECK(fake.last_position[0] == expect[i].box_x && fake.last_position[1] == 1.0f);
        CHECK(fake.last_target[2] == expect[i].target_z);
        if (fake.pins)
            CHECK_EQ(fake.last_vertex, 4);
    }
    rbc_scene_instance_destroy(&api, &inst);
    s.collider_count = 3;

    /* A table without world_set_wind: refused before anything is created. */
    api.world_set_wind = NULL;
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "new.json: world.wind: needs rbc_world_set_wind (ABI 1.3)") != NULL);
    CHECK_EQ(fake.worlds_created, 0);
    api.world_set_wind = fake_set_wind;

    /* An ABI 1.2 library: a scene with 1.3 keys is refused naming the first. */
    api.abi_version = (1u << 16) | 2u;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "new.json: world.wind: needs an ABI 1.3 library; the plugin has ABI 1.2") != NULL);
    CHECK(is_zeroed(&inst, sizeof inst));
    s.world.has_wind = 0;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_ERR_UNSUPPORTED);
    CHECK(strstr(err, "new.json: cloths[0].thickness: needs an ABI 1.3 library") != NULL);
    rbc_scene_free(&s);
    /* ... and a scene without them gets the library's own def sizes. */
    CHECK_EQ(load_sample("cloth_on_sphere.json", &s, err, sizeof err), 0);
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK_EQ(fake_init_sizes[1], RBC_CLOTH_DEF_SIZE_V1_1);
    CHECK_EQ(fake_init_sizes[2], RBC_COLLIDER_DEF_SIZE_V1_0);
    CHECK_EQ(fake.colliders_created, 2);
    rbc_scene_instance_destroy(&api, &inst);
    /* A static scene makes no call per frame. */
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_apply_frame(&api, &s, &inst, 3, err, sizeof err), RBC_OK);
    CHECK(fake.transforms == 0 && fake.pins == 0 && fake.releases == 0);
    rbc_scene_free(&s);
    api.abi_version = RBC_ABI_VERSION;

    /* A mesh file: imported with the scene's scale, its triangles in the def. */
    char path[1024], text[512];
    snprintf(path, sizeof path, "%s/inline.json", scenes_dir);
    snprintf(text, sizeof text,
             BASE_HEAD C3 "\"colliders\":[{\"shape\":\"mesh\",\"file\":\"../meshes/tri_patch.obj\","
                          "\"scale\":0.5}]}");
    CHECK_EQ(rbc_scene_parse(text, strlen(text), path, &s, err, sizeof err), 0);
    memset(&fake, 0, sizeof fake);
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_OK);
    CHECK(strcmp(fake.imported, s.colliders[0].mesh_file) == 0);
    CHECK(fake.import_scale == 0.5f);
    CHECK(fake.collider_def.mesh_vertex_count == 4 && fake.collider_def.mesh_triangle_count == 4);
    CHECK(memcmp(fake.mesh_positions, tetra_positions, sizeof tetra_positions) == 0);
    CHECK(memcmp(fake.mesh_triangles, tetra_triangles, sizeof tetra_triangles) == 0);
    rbc_scene_instance_destroy(&api, &inst);
    /* An import that fails names the key and the file; nothing is left. */
    memset(&fake, 0, sizeof fake);
    fake.fail_import = 1;
    CHECK_EQ(rbc_scene_instantiate(&api, &s, NULL, NULL, &inst, err, sizeof err), RBC_ERR_BAD_MESH);
    CHECK(strstr(err, "inline.json: colliders[0].file: cannot read ") != NULL);
    CHECK(strstr(err, "tri_patch.obj as a triangle mesh: cloth def: vertex 3 is bad") != NULL);
    CHECK_EQ(fake.worlds_destroyed, 1);
    CHECK(is_zeroed(&inst, sizeof inst));
    rbc_scene_free(&s);
}

/* The paper's four scenes load with the sizes the paper gives (structural springs
 * counted as distinct quad edges). */
static uint64_t distinct_edges(const rbc_scene_cloth *c) {
    /* Grids and the shipped scenes only: edges of a grid = nx (ny - 1) + ny (nx - 1). */
    return c->from_grid ? (uint64_t)c->grid.nx * (c->grid.ny - 1) + (uint64_t)c->grid.ny * (c->grid.nx - 1)
                        : 0;
}

static void test_paper_scenes(void) {
    static const struct {
        const char *file;
        uint32_t cloths, particles, springs, colliders;
    } scenes[] = {
        {"cloth_on_chair.json", 1, 10000, 19800, 7},
        {"four_layers_sphere.json", 4, 16384, 32256, 2},
        {"funnel.json", 3, 30000, 59400, 3},
        {"cannonballs_tearing.json", 1, 4096, 8064, 4},
    };
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; ++i) {
        rbc_scene s;
        char err[RBC_SCENE_ERROR_MAX];
        int rc = load_sample(scenes[i].file, &s, err, sizeof err);
        CHECK_EQ(rc, 0);
        if (rc) {
            fprintf(stderr, "%s\n", err);
            continue;
        }
        uint64_t particles = 0, springs = 0;
        for (uint32_t c = 0; c < s.cloth_count; ++c) {
            particles += s.cloths[c].vertex_count;
            springs += distinct_edges(&s.cloths[c]);
        }
        CHECK_EQ(s.cloth_count, scenes[i].cloths);
        CHECK_EQ(particles, scenes[i].particles);
        CHECK_EQ(springs, scenes[i].springs);
        CHECK_EQ(s.collider_count, scenes[i].colliders);
        CHECK(s.description != NULL && strstr(s.description, "Fig. ") != NULL);
        /* 2 to 4 s of simulated time (dt is a float: 2^-24 relative). */
        double seconds = (double)s.frames * s.dt;
        CHECK(seconds >= 2.0 * (1.0 - 0x1p-24) && seconds <= 4.0 * (1.0 + 0x1p-24));
        rbc_scene_free(&s);
    }
    /* The funnel: an inline mesh of 480 vertices and 864 triangles. */
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    if (load_sample("funnel.json", &s, err, sizeof err) == 0) {
        CHECK_EQ(s.colliders[0].shape, RBC_SHAPE_TRIANGLE_MESH);
        CHECK_EQ(s.colliders[0].mesh_vertex_count, 480);
        CHECK_EQ(s.colliders[0].mesh_triangle_count, 864);
        rbc_scene_free(&s);
    }
    /* Cannonballs: a tearing cloth with one drag, three keyframed spheres and a
     * static ground plane. */
    if (load_sample("cannonballs_tearing.json", &s, err, sizeof err) == 0) {
        CHECK(s.cloths[0].tear_strain > 0.0f);
        CHECK_EQ(s.cloths[0].drag_count, 1);
        CHECK_EQ(s.cloths[0].pin_count, 64);
        uint32_t keyframed = 0;
        for (uint32_t i = 0; i < s.collider_count; ++i)
            keyframed += s.colliders[i].shape == RBC_SHAPE_SPHERE &&
                         s.colliders[i].motion == RBC_SCENE_MOTION_KEYFRAMES;
        CHECK_EQ(keyframed, 3);
        rbc_scene_free(&s);
    }
}

/* A device that never ends (/dev/zero) is refused at its first NUL byte, not read up
 * to the 1 GiB file limit. */
static void test_endless_file(void) {
    rbc_scene s;
    char err[512];
    CHECK(rbc_scene_load_file("/dev/zero", &s, err, sizeof err) != 0);
    CHECK(strstr(err, "/dev/zero: contains a NUL byte (at offset 0)") != NULL);
    if (!strstr(err, "NUL")) fprintf(stderr, "  got: %s\n", err);
}

int main(int argc, char **argv) {
    if (argc > 1)
        scenes_dir = argv[1];
    test_grid();
    test_hanging_cloth_file(0);
    test_hanging_cloth_file(1);
    test_solver_rules();
    test_default_equals_file();
    test_cloth_on_sphere();
    test_inline_mesh();
    test_malformed();
    test_malformed_v1_3();
    test_v1_3_keys();
    test_motion_numbers();
    test_messages();
    test_instantiate();
    test_instantiate_v1_3();
    test_paper_scenes();
    test_endless_file();
    return check_report("test_scene");
}
