/* fuzz_import.c -- bytes as a mesh file for rbc_mesh_import, through the public ABI
 * only (whether the library imports in this process or in a helper process is its
 * own business). The first byte picks the file's extension (low 5 bits, the table
 * below) and import options (high 3 bits: no weld, no triangle pairing, n-gons
 * refused); the rest is the file, written to a private temporary folder.
 *
 * Promises checked (a broken one aborts): RBC_OK or a documented error code with a
 * non-empty rbc_last_error(); on RBC_OK the info's identities hold (quad_count =
 * file_quads + quads_from_ngons + paired_triangles / 2, file_triangles +
 * triangles_from_ngons = paired_triangles + leftover_triangles), every array reads
 * back at its count with indices below vertex_count, positions finite, pins
 * ascending; a mesh of at most 4096 vertices makes a cloth in a world (or a clean
 * error) that steps once; nothing is printed to stdout. */
#include <math.h>
#include <sys/stat.h>

#include "fuzz_common.h"

static const char *const extensions[32] = {
    "obj", "ply",  "off", "stl", "dae",  "gltf", "glb", "fbx", "3ds",  "x",    "md2",
    "ms3d", "ase", "ac",  "lwo", "blend", "smd", "nff", "raw", "dxf",  "cob",  "irrmesh",
    "ogex", "3mf", "amf", "md5mesh", "q3o", "xgl", "b3d", "lws", "mdl", "csm"};

static char dir[64];

static void remove_dir(void) {
    if (dir[0]) rmdir(dir);
}

int LLVMFuzzerInitialize(int *argc, char ***argv) {
    (void)argc;
    (void)argv;
    snprintf(dir, sizeof dir, "/tmp/rbc_fuzz_import_XXXXXX");
    if (!mkdtemp(dir)) {
        perror("fuzz_import: mkdtemp");
        abort();
    }
    atexit(remove_dir);
    return 0;
}

static void RBC_CALL quiet_log(void *user, rbc_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static void check(rbc_result r, const char *call) {
    if (r != RBC_OK) fuzz_check_error(r, call);
}

static void read_back(rbc_mesh_id mesh, const rbc_mesh_info *info) {
    size_t n = 0;
    check(rbc_mesh_get_positions(mesh, NULL, 0, &n), "rbc_mesh_get_positions");
    FUZZ_CHECK(n == 3 * (size_t)info->vertex_count, "%zu position floats, %u vertices", n,
               info->vertex_count);
    float *xyz = malloc(n * sizeof *xyz + 1);
    FUZZ_CHECK(xyz != NULL, "out of memory");
    check(rbc_mesh_get_positions(mesh, xyz, n, &n), "rbc_mesh_get_positions");
    for (size_t i = 0; i < n; i++) FUZZ_CHECK(isfinite(xyz[i]), "position %zu not finite", i);
    free(xyz);

    struct {
        rbc_result (RBC_CALL *get)(rbc_mesh_id, uint32_t *, size_t, size_t *);
        const char *name;
        size_t expect;
    } arrays[] = {
        {rbc_mesh_get_quads, "rbc_mesh_get_quads", 4 * (size_t)info->quad_count},
        {rbc_mesh_get_springs, "rbc_mesh_get_springs", 2 * (size_t)info->spring_count},
        {rbc_mesh_get_pins, "rbc_mesh_get_pins", info->pin_count},
        {rbc_mesh_get_triangles, "rbc_mesh_get_triangles", (size_t)-1},
    };
    for (size_t a = 0; a < sizeof arrays / sizeof arrays[0]; a++) {
        check(arrays[a].get(mesh, NULL, 0, &n), arrays[a].name);
        if (arrays[a].expect != (size_t)-1)
            FUZZ_CHECK(n == arrays[a].expect, "%s: %zu values, the info says %zu", arrays[a].name,
                       n, arrays[a].expect);
        uint32_t *v = malloc(n * sizeof *v + 1);
        FUZZ_CHECK(v != NULL, "out of memory");
        check(arrays[a].get(mesh, v, n, &n), arrays[a].name);
        for (size_t i = 0; i < n; i++) {
            FUZZ_CHECK(v[i] < info->vertex_count, "%s: index %u of %u vertices", arrays[a].name,
                       v[i], info->vertex_count);
            if (a == 2 && i) FUZZ_CHECK(v[i] > v[i - 1], "pins not ascending");
        }
        free(v);
    }

    /* 1.9: the file's own vertices. The map is file_vertex_count long, each entry a
     * mesh vertex or UINT32_MAX (as many as the info says); the state goes back
     * into the file's order; the file's mesh writes as OBJ (or fails with a clean
     * error), and the file appears only whole. */
    check(rbc_mesh_get_file_map(mesh, NULL, 0, &n), "rbc_mesh_get_file_map");
    FUZZ_CHECK(n == info->file_vertex_count, "%zu map entries, the info says %u", n,
               info->file_vertex_count);
    uint32_t *map = malloc(n * sizeof *map + 1);
    FUZZ_CHECK(map != NULL, "out of memory");
    check(rbc_mesh_get_file_map(mesh, map, n, &n), "rbc_mesh_get_file_map");
    size_t unmapped = 0;
    for (size_t i = 0; i < n; i++) {
        FUZZ_CHECK(map[i] < info->vertex_count || map[i] == UINT32_MAX,
                   "file vertex %zu maps to %u of %u vertices", i, map[i], info->vertex_count);
        unmapped += map[i] == UINT32_MAX;
    }
    FUZZ_CHECK(unmapped == info->unmapped_file_vertices, "%zu unmapped, the info says %u",
               unmapped, info->unmapped_file_vertices);
    free(map);
    size_t nf = 0;
    check(rbc_mesh_to_file_positions(mesh, NULL, 0, NULL, 0, &nf), "rbc_mesh_to_file_positions");
    FUZZ_CHECK(nf == 3 * (size_t)info->file_vertex_count, "%zu file floats", nf);
    float *fx = malloc(nf * sizeof *fx + 1);
    FUZZ_CHECK(fx != NULL, "out of memory");
    check(rbc_mesh_to_file_positions(mesh, NULL, 0, fx, nf, NULL), "rbc_mesh_to_file_positions");
    free(fx);
    char obj[128];
    snprintf(obj, sizeof obj, "%s/file.obj", dir);
    for (int order = RBC_ORDER_FILE; order <= RBC_ORDER_MESH; ++order) {
        rbc_result r = rbc_mesh_write_file_obj(mesh, NULL, 0, order, obj);
        if (r != RBC_OK) fuzz_check_error(r, "rbc_mesh_write_file_obj");
        struct stat st;
        FUZZ_CHECK((r == RBC_OK) == (stat(obj, &st) == 0), "write_file_obj %d: file %s",
                   (int)r, r == RBC_OK ? "missing" : "left behind");
        remove(obj);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    fuzz_capture_stdout();
    if (!dir[0]) LLVMFuzzerInitialize(NULL, NULL);
    if (size < 1) return 0;
    const char *ext = extensions[data[0] & 31];
    char path[128];
    snprintf(path, sizeof path, "%s/input.%s", dir, ext);
    FILE *f = fopen(path, "wb");
    FUZZ_CHECK(f != NULL, "cannot write %s", path);
    if (size > 1) fwrite(data + 1, 1, size - 1, f);
    FUZZ_CHECK(fclose(f) == 0, "cannot write %s", path);

    rbc_mesh_import_def def;
    check(rbc_mesh_import_def_init(&def, (uint32_t)sizeof def), "rbc_mesh_import_def_init");
    if (data[0] & 32) def.weld = 0;
    if (data[0] & 64) def.pair_triangles = 0;
    if (data[0] & 128) def.ngons = RBC_NGON_REFUSE;
    /* Under libFuzzer's own -timeout (run_fuzz.sh), so that a hang in assimp is the
     * library's clean time-out, which is the promise, not a fuzzer finding. */
    def.timeout_ms = 2000;
    def.memory_limit_mb = 1024; /* a file that wants more is an out-of-memory error */
    rbc_mesh_id mesh = 0;
    rbc_result r = rbc_mesh_import(path, &def, &mesh);
    if (r != RBC_OK) {
        fuzz_check_error(r, "rbc_mesh_import");
        fuzz_note("%s refused: %s: %s", ext, rbc_result_string(r), rbc_last_error());
    } else {
        rbc_mesh_info info;
        memset(&info, 0, sizeof info);
        info.struct_size = (uint32_t)sizeof info;
        check(rbc_mesh_get_info(mesh, &info), "rbc_mesh_get_info");
        FUZZ_CHECK(info.quad_count ==
                       info.file_quads + info.quads_from_ngons + info.paired_triangles / 2,
                   "quad_count %u != %u + %u + %u / 2", info.quad_count, info.file_quads,
                   info.quads_from_ngons, info.paired_triangles);
        FUZZ_CHECK(info.file_triangles + info.triangles_from_ngons ==
                       info.paired_triangles + info.leftover_triangles,
                   "triangles %u + %u != %u + %u", info.file_triangles, info.triangles_from_ngons,
                   info.paired_triangles, info.leftover_triangles);
        fuzz_note("%s: %u vertices, %u quads, %u springs, %u pins", ext, info.vertex_count,
                  info.quad_count, info.spring_count, info.pin_count);
        read_back(mesh, &info);
        if (info.vertex_count <= 4096) {
            rbc_world_def wd;
            check(rbc_world_def_init(&wd, (uint32_t)sizeof wd), "rbc_world_def_init");
            wd.thread_count = 1;
            wd.substeps = 1;
            wd.log = quiet_log;
            rbc_world_id world = 0;
            check(rbc_world_create(&wd, &world), "rbc_world_create");
            rbc_cloth_id cloth = 0;
            r = rbc_cloth_create_from_mesh(world, mesh, NULL, &cloth);
            if (r != RBC_OK) {
                fuzz_check_error(r, "rbc_cloth_create_from_mesh");
            } else {
                r = rbc_world_step(world, 1.0f / 60.0f);
                if (r != RBC_OK) fuzz_check_error(r, "rbc_world_step");
            }
            check(rbc_world_destroy(world), "rbc_world_destroy");
        }
        check(rbc_mesh_destroy(mesh), "rbc_mesh_destroy");
    }
    unlink(path);
    fuzz_check_stdout("the import target");
    return 0;
}
