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

static void test_hanging_cloth_file(void) {
    rbc_scene s;
    char err[RBC_SCENE_ERROR_MAX];
    int rc = load_sample("hanging_cloth.json", &s, err, sizeof err);
    CHECK_EQ(rc, 0);
    if (rc) {
        fprintf(stderr, "%s\n", err);
        return;
    }
    CHECK(strcmp(s.name, "hanging_cloth") == 0);
    CHECK_EQ(s.frames, 240);
    CHECK(s.dt == 0.002f);
    CHECK(s.world.gravity[0] == 0.0f && s.world.gravity[1] == -9.81f && s.world.gravity[2] == 0.0f);
    CHECK_EQ(s.world.substeps, 1);
    CHECK_EQ(s.world.nonlinear_iterations, 1);
    CHECK_EQ(s.world.linear_iterations, 11);
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
    char err[RBC_SCENE_ERROR_MAX];
    int rc = rbc_scene_parse(json, sizeof json - 1, "strip.json", &s, err, sizeof err);
    CHECK_EQ(rc, 0);
    if (rc) {
        fprintf(stderr, "%s\n", err);
        return;
    }
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
    CHECK_EQ(s.world.substeps, 1);
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
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"world\":{\"substeps\":0}}",
         "world.substeps: must be an integer in [1, 1024], got 0"},
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
         "bad.json: world.substep: unknown key (expected one of: gravity, substeps,"},
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
         "colliders[0].radius: only spheres have a radius"},
        {BASE_HEAD "\"cloths\":[" GRID_CLOTH "],\"colliders\":[{\"shape\":\"cube\"}]}",
         "colliders[0].shape: must be one of \"sphere\", \"plane\", got \"cube\""},
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
        rbc_scene s;
        memset(&s, 0xAB, sizeof s);
        char err[RBC_SCENE_ERROR_MAX] = "";
        int rc = rbc_scene_parse(cases[i].json, strlen(cases[i].json), "bad.json", &s, err,
                                 sizeof err);
        CHECK_EQ(rc, -1);
        CHECK(is_zeroed(&s, sizeof s));
        if (!strstr(err, cases[i].expect)) {
            CHECK(!"message names the key and the problem");
            fprintf(stderr, "  case %zu: expected \"%s\"\n           got      \"%s\"\n", i,
                    cases[i].expect, err);
        } else {
            CHECK(strncmp(err, "bad.json", 8) == 0);
        }
        if (rc == 0)
            rbc_scene_free(&s);
    }
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
    *out = 200 + (rbc_collider_id)++fake.colliders_created;
    return RBC_OK;
}

static void RBC_CALL fake_log(void *user, rbc_log_level level, const char *message) {}

static void test_instantiate(void) {
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

int main(int argc, char **argv) {
    if (argc > 1)
        scenes_dir = argv[1];
    test_grid();
    test_hanging_cloth_file();
    test_default_equals_file();
    test_cloth_on_sphere();
    test_inline_mesh();
    test_malformed();
    test_messages();
    test_instantiate();
    return check_report("test_scene");
}
