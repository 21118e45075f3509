/* scene.h -- sample scenes: a JSON scene file loaded into a struct, and the world,
 * cloths and colliders it describes created through the plugin's function table.
 *
 * The format is documented in samples/scenes/README.md. Loading never prints: every
 * failure is returned as one message of the form "SOURCE: KEY: what was wrong"
 * (SOURCE is the file name, KEY a path such as cloths[0].grid.nx). Creation goes
 * through a `const rbc_api_v1 *` only, so the same code serves hosts that dlopen
 * the plugin and hosts linked to it.
 */
#ifndef RBC_SAMPLES_SCENE_H
#define RBC_SAMPLES_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "grid.h"
#include "rbcloth.h"

/// A buffer of this many chars holds any message of the loader unshortened,
/// except for very long file names (messages are cut to the buffer, never overrun).
#define RBC_SCENE_ERROR_MAX 1024

/// Name of the built-in scene, used as SOURCE in its messages.
#define RBC_SCENE_DEFAULT_SOURCE "(built-in default scene)"

/// The "world" object: the fields of rbc_world_def a scene sets.
typedef struct rbc_scene_world {
    float gravity[3];
    uint32_t substeps;
    uint32_t nonlinear_iterations;
    uint32_t linear_iterations;
    /// 0 = one per available core.
    uint32_t thread_count;
    rbc_backend backend;
    /// The "solver" object: the global solver and iteration control (ABI 1.1).
    rbc_solver_def solver;
} rbc_scene_world;

/// One cloth: its mesh (generated from "grid" or given inline) and material.
typedef struct rbc_scene_cloth {
    /// Unique within the scene; safe in a file name.
    char *name;
    /// 1 if the mesh was generated from `grid`, 0 if given as "vertices"/"quads".
    int32_t from_grid;
    /// The grid, when from_grid.
    rbc_grid_def grid;
    uint32_t vertex_count;
    /// Rest positions, x y z per vertex, metres.
    float *positions;
    uint32_t quad_count;
    /// 4 vertex indices per quad.
    uint32_t *quads;
    /// kg, N/m, 1/s.
    float vertex_mass;
    float stiffness;
    float damping;
    /// Shear and bend spring stiffness, N/m (0 = none; ABI 1.1).
    float shear_stiffness;
    float bend_stiffness;
    uint32_t pin_count;
    /// Pinned vertex indices, in file order, each < vertex_count, no duplicates.
    uint32_t *pins;
} rbc_scene_cloth;

/// One collider, as rbc_collider_def has it.
typedef struct rbc_scene_collider {
    /// RBC_SHAPE_SPHERE or RBC_SHAPE_PLANE.
    rbc_shape shape;
    /// Sphere radius, metres (0 for planes).
    float radius;
    float thickness;
    float position[3];
    /// Unit quaternion x y z w.
    float rotation[4];
} rbc_scene_collider;

typedef struct rbc_scene {
    /// Safe in a file name: [A-Za-z0-9_.-], not starting with '.'.
    char *name;
    /// Free text, or NULL.
    char *description;
    /// Frames to simulate; one rbc_world_step of `dt` seconds per frame.
    uint32_t frames;
    float dt;
    rbc_scene_world world;
    uint32_t cloth_count;
    rbc_scene_cloth *cloths;
    uint32_t collider_count;
    rbc_scene_collider *colliders;
} rbc_scene;

/// Parse `length` bytes of JSON (need not be NUL-terminated). `source` names it in
/// messages (a file name). Returns 0 and fills *out, or -1 with *out zeroed and the
/// reason in err (if err_size > 0).
int rbc_scene_parse(const char *json, size_t length, const char *source, rbc_scene *out,
                    char *err, size_t err_size);

/// Read and parse a scene file. Returns 0 or -1 as rbc_scene_parse.
int rbc_scene_load_file(const char *path, rbc_scene *out, char *err, size_t err_size);

/// Solver and iteration-mode names as scenes and the CLI spell them, indexed by
/// rbc_solver_kind / rbc_iteration_mode, NULL-terminated.
extern const char *const rbc_scene_solver_names[];
extern const char *const rbc_scene_mode_names[];
/// "off", "clamp", "fail": rbc_energy_guard values by index, NULL-terminated.
extern const char *const rbc_scene_energy_guard_names[];

/// The built-in default scene, identical to samples/scenes/hanging_cloth.json: the
/// paper's 100 x 100 hanging cloth. Returns 0 or -1 as rbc_scene_parse.
int rbc_scene_load_default(rbc_scene *out, char *err, size_t err_size);

/// The JSON text of the built-in default scene.
const char *rbc_scene_default_json(void);

/// Free what a successful load allocated and zero *scene. Safe on a zeroed scene.
void rbc_scene_free(rbc_scene *scene);

/// The objects created from a scene. ids[i] belongs to scene->cloths[i] and
/// scene->colliders[i].
typedef struct rbc_scene_instance {
    rbc_world_id world;
    uint32_t cloth_count;
    rbc_cloth_id *cloths;
    uint32_t collider_count;
    rbc_collider_id *colliders;
} rbc_scene_instance;

/// Create the world of `scene` with its cloths and colliders through `api`. `log`
/// (may be NULL) becomes the world's log hook, at RBC_LOG_WARNING. Returns RBC_OK
/// and fills *out; or the failing call's result, with nothing left created, *out
/// zeroed and err set to "<api->last_error()> (<what was being created>)".
rbc_result rbc_scene_instantiate(const rbc_api_v1 *api, const rbc_scene *scene,
                                 rbc_log_fn log, void *log_user, rbc_scene_instance *out,
                                 char *err, size_t err_size);

/// Destroy the world of an instance (with its cloths and colliders), free the id
/// arrays and zero *instance. Safe on a zeroed instance.
void rbc_scene_instance_destroy(const rbc_api_v1 *api, rbc_scene_instance *instance);

#endif
