/* fuzz_scene.c -- bytes as a scene file (samples/scene.c, rbc_scene_parse from
 * memory), then the world it describes built through the plugin's function table
 * (rbc_scene_instantiate, as `rbcloth run` does) and stepped a few frames with small
 * caps (rbc_scene_apply_frame + world_step), then destroyed.
 *
 * Promises checked (a broken one aborts): a refused scene has a message and *out
 * zeroed; a loaded one is freed without leaks (LeakSanitizer); instantiation returns
 * RBC_OK or a documented error with a message in err and the instance zeroed; each
 * frame's calls return RBC_OK or a documented error with rbc_last_error() set;
 * nothing is printed to stdout.
 * Caps (so an input runs in milliseconds): at most 8 cloths with 4096 vertices in
 * all, 16 colliders (inline meshes of at most 1024 triangles), 3 frames, 4 substeps
 * (8 when they follow the rate), 16 linear iterations, 2 threads; scenes naming a
 * mesh file (read from disk relative to the scene) are parsed but not built. */
#include "fuzz_common.h"
#include "scene.h"

static void RBC_CALL quiet_log(void *user, rbc_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static int all_zero(const void *p, size_t n) {
    const unsigned char *c = p;
    for (size_t i = 0; i < n; i++)
        if (c[i]) return 0;
    return 1;
}

static int small_enough(rbc_scene *s) {
    if (s->cloth_count > 8 || s->collider_count > 16) return 0;
    uint64_t vertices = 0;
    for (uint32_t i = 0; i < s->cloth_count; i++) vertices += s->cloths[i].vertex_count;
    if (vertices > 4096) return 0;
    for (uint32_t i = 0; i < s->collider_count; i++) {
        if (s->colliders[i].mesh_file) return 0;
        if (s->colliders[i].mesh_triangle_count > 1024) return 0;
    }
    rbc_scene_world *w = &s->world;
    if (w->substeps > 4) w->substeps = 4;
    if (w->linear_iterations > 16) w->linear_iterations = 16;
    if (w->nonlinear_iterations > 2) w->nonlinear_iterations = 2;
    if (w->thread_count == 0 || w->thread_count > 2) w->thread_count = 2;
    if (w->solver.max_substeps > 8) w->solver.max_substeps = 8;
    if (w->solver.max_linear_iterations > 64) w->solver.max_linear_iterations = 64;
    if (w->solver.budget_ms > 1.0f) w->solver.budget_ms = 1.0f;
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    fuzz_capture_stdout();
    static const rbc_api_v1 *api;
    if (!api) api = (const rbc_api_v1 *)rbc_get_api(1);
    FUZZ_CHECK(api != NULL, "rbc_get_api(1) is NULL");

    rbc_scene scene;
    char err[RBC_SCENE_ERROR_MAX];
    err[0] = '\0';
    if (rbc_scene_parse((const char *)data, size, "fuzz.json", &scene, err, sizeof err) != 0) {
        fuzz_note("refused: %s", err);
        FUZZ_CHECK(err[0] != '\0', "rbc_scene_parse refused the scene without a message");
        FUZZ_CHECK(all_zero(&scene, sizeof scene), "rbc_scene_parse failed (%s) but left *out set",
                   err);
        fuzz_check_stdout("rbc_scene_parse");
        return 0;
    }
    int small = small_enough(&scene);
    if (!small) fuzz_note("loaded; too big to build here");
    if (small) {
        rbc_scene_instance inst;
        err[0] = '\0';
        rbc_result r = rbc_scene_instantiate(api, &scene, quiet_log, NULL, &inst, err, sizeof err);
        fuzz_note("instantiate: %s %s", rbc_result_string(r), err);
        if (r != RBC_OK) {
            FUZZ_CHECK(fuzz_known_result(r), "rbc_scene_instantiate returned %d", (int)r);
            FUZZ_CHECK(err[0] != '\0', "rbc_scene_instantiate failed (%s) without a message",
                       rbc_result_string(r));
            FUZZ_CHECK(all_zero(&inst, sizeof inst),
                       "rbc_scene_instantiate failed (%s) but left the instance set", err);
        } else {
            uint32_t frames = scene.frames < 3 ? scene.frames : 3;
            for (uint32_t f = 0; f < frames; f++) {
                err[0] = '\0';
                r = rbc_scene_apply_frame(api, &scene, &inst, f, err, sizeof err);
                if (r != RBC_OK) {
                    FUZZ_CHECK(fuzz_known_result(r) && err[0], "rbc_scene_apply_frame: %d '%s'",
                               (int)r, err);
                    break;
                }
                r = api->world_step(inst.world, scene.dt);
                fuzz_note("frame %u: %s", f, rbc_result_string(r));
                if (r != RBC_OK) {
                    fuzz_check_error(r, "world_step");
                    break;
                }
            }
            rbc_scene_instance_destroy(api, &inst);
            FUZZ_CHECK(all_zero(&inst, sizeof inst), "rbc_scene_instance_destroy left the instance set");
        }
    }
    rbc_scene_free(&scene);
    FUZZ_CHECK(all_zero(&scene, sizeof scene), "rbc_scene_free left the scene set");
    fuzz_check_stdout("the scene target");
    return 0;
}
