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
    /// 0 = from substep_rate (ABI 1.6, the default).
    uint32_t substeps;
    /// Hz, > 0: substeps per second when substeps is 0. Default 480.
    float substep_rate;
    uint32_t nonlinear_iterations;
    uint32_t linear_iterations;
    /// 0 = one per available core.
    uint32_t thread_count;
    rbc_backend backend;
    /// The "solver" object: the global solver and iteration control (ABI 1.1).
    rbc_solver_def solver;
    /// The "wind" object (ABI 1.3): 1 if given; then rbc_world_set_wind(velocity,
    /// drag, lift) is called once after the world is made. 0 = no call (no wind).
    int32_t has_wind;
    /// m/s; drag and lift in kg/m^3 (see rbc_world_set_wind).
    float wind_velocity[3];
    float wind_drag;
    float wind_lift;
} rbc_scene_world;

/// One keyframe of a drag: where the dragged vertex is pulled at `time`.
typedef struct rbc_scene_drag_key {
    /// Seconds from the start of the scene.
    double time;
    /// Metres.
    float target[3];
} rbc_scene_drag_key;

/// A scripted drag (the paper's Fig. 8 "pick and drag until it tears"): from the
/// first keyframe's time the vertex is pinned (rbc_cloth_set_pin) to the target
/// interpolated linearly between keyframes (held at the last one after it), until
/// `release`, when its pin is released (target NULL).
typedef struct rbc_scene_drag {
    uint32_t vertex;
    uint32_t key_count;
    /// Times strictly increasing.
    rbc_scene_drag_key *keys;
    /// Seconds; < 0 = never released. Otherwise after the first keyframe's time.
    double release;
} rbc_scene_drag;

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
    /* --- ABI 1.3 (0 = the library's defaults, which need no 1.3 library) --- */
    /// Distance kept from colliders and cloth surfaces, metres (rbc_cloth_def).
    float thickness;
    /// Coulomb friction coefficient.
    float friction;
    /// RBC_CLOTH_COLLIDE_SELF | RBC_CLOTH_COLLIDE_CLOTHS from "self_collision" and
    /// "cloth_collision".
    uint32_t collision_flags;
    /// Springs break beyond (1 + tear_strain) times their rest length; 0 = never.
    float tear_strain;
    /// Scripted drags, in file order; each vertex dragged at most once.
    uint32_t drag_count;
    rbc_scene_drag *drags;
} rbc_scene_cloth;

/// How a collider moves (ABI 1.0 set_transform; the library derives the collider's
/// velocity from the change of pose over a step).
typedef int32_t rbc_scene_motion;
enum {
    /// It stays where it was created.
    RBC_SCENE_MOTION_NONE = 0,
    /// position(t) = position + velocity t; it turns at angular_velocity (rad/s, a
    /// world-frame axis times the rate) about its own origin.
    RBC_SCENE_MOTION_VELOCITY = 1,
    /// Linear positions and normalised-lerp rotations between keyframes; the first
    /// pose is held before the first keyframe, the last after the last one.
    RBC_SCENE_MOTION_KEYFRAMES = 2
};

/// One keyframe of a collider.
typedef struct rbc_scene_collider_key {
    /// Seconds from the start of the scene.
    double time;
    float position[3];
    /// Unit quaternion x y z w.
    float rotation[4];
} rbc_scene_collider_key;

/// One collider, as rbc_collider_def has it, and how it moves.
typedef struct rbc_scene_collider {
    /// RBC_SHAPE_SPHERE, _PLANE, _CAPSULE, _BOX or _TRIANGLE_MESH.
    rbc_shape shape;
    /// Sphere or capsule radius, metres (0 for other shapes).
    float radius;
    float thickness;
    /// Where it is created (the pose at time 0 for keyframed colliders).
    float position[3];
    /// Unit quaternion x y z w.
    float rotation[4];
    /* --- ABI 1.3 --- */
    /// Coulomb friction coefficient (0 = the default).
    float friction;
    /// Box half sizes, metres; a capsule's half axis length is half_extents[1] (its
    /// other entries 0). All 0 for other shapes.
    float half_extents[3];
    /// RBC_SHAPE_TRIANGLE_MESH given inline ("vertices", "triangles"): positions in
    /// the collider's frame (3 floats each, metres) and triangles (3 indices each).
    uint32_t mesh_vertex_count;
    float *mesh_positions;
    uint32_t mesh_triangle_count;
    uint32_t *mesh_triangles;
    /// RBC_SHAPE_TRIANGLE_MESH from a file: its path (resolved against the scene
    /// file's directory) and "scale"; read by rbc_scene_instantiate through
    /// rbc_mesh_import. NULL otherwise.
    char *mesh_file;
    float mesh_scale;
    /// Motion: RBC_SCENE_MOTION_*; velocity m/s, angular_velocity rad/s.
    rbc_scene_motion motion;
    float velocity[3];
    float angular_velocity[3];
    uint32_t key_count;
    /// Times strictly increasing.
    rbc_scene_collider_key *keys;
} rbc_scene_collider;

typedef struct rbc_scene {
    /// The SOURCE the scene was loaded from (file name), for messages.
    char *source;
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
/// "paper", "game_60hz", "cloth": rbc_preset values by index (rbc_solver_def_preset,
/// the CLI's --preset, a scene's world.solver.preset), NULL-terminated.
extern const char *const rbc_scene_preset_names[];
/// The entry of `choices` (NULL-terminated) that `word` is likely a typo of (one
/// edit, two from 6 characters on; or the one choice it begins, from 3 characters),
/// or NULL: for "did you mean" in messages.
const char *rbc_scene_nearest(const char *word, const char *const *choices);
/// Fill *d with what rbc_solver_def_preset(d, sizeof *d, preset) gives (written out,
/// so that loading a scene needs no library).
void rbc_scene_solver_preset(rbc_solver_def *d, int preset);
/// "off", "clamp", "fail": rbc_energy_guard values by index, NULL-terminated.
extern const char *const rbc_scene_energy_guard_names[];

/// The pose of a collider at `time` seconds: its creation pose for
/// RBC_SCENE_MOTION_NONE (bit for bit), else as its motion says (computed in double,
/// rounded once; rotations normalised).
void rbc_scene_collider_pose(const rbc_scene_collider *collider, double time,
                             float position[3], float rotation[4]);

/// What a drag does at `time`.
typedef int32_t rbc_scene_drag_state;
enum {
    /// Before its first keyframe: the vertex is left as it is.
    RBC_SCENE_DRAG_WAITING = 0,
    /// Pinned at the target written to `target`.
    RBC_SCENE_DRAG_PINNED = 1,
    /// At or after `release`: the pin is released.
    RBC_SCENE_DRAG_RELEASED = 2
};
rbc_scene_drag_state rbc_scene_drag_target(const rbc_scene_drag *drag, double time,
                                           float target[3]);

/// 1 if the scene uses something only an ABI 1.3 library has (a 1.3 shape, friction,
/// cloth thickness, cloth contact, tearing, wind), with the first such key written
/// to `key` (e.g. "cloths[0].tear_strain"); 0 if an ABI 1.0-1.2 library can run it.
int rbc_scene_needs_v1_3(const rbc_scene *scene, char *key, size_t key_size);

/// The built-in default scene, identical to samples/scenes/hanging_cloth.json: the
/// paper's 100 x 100 hanging cloth at 1/60 s with the default solve. Returns 0 or
/// -1 as rbc_scene_parse.
int rbc_scene_load_default(rbc_scene *out, char *err, size_t err_size);
/// The paper's experiment, identical to samples/scenes/hanging_cloth_paper.json: the
/// same cloth at h = 2 ms, 1 x 11 RBGS iterations (the benches that reproduce the
/// paper). Returns 0 or -1 as rbc_scene_parse.
int rbc_scene_load_paper(rbc_scene *out, char *err, size_t err_size);

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
/// (may be NULL) becomes the world's log hook, at RBC_LOG_WARNING. Colliders are
/// created at their pose at time 0. Mesh colliders given by "file" are read here:
/// rbc_mesh_import with the default import def (and the scene's scale), then
/// rbc_mesh_get_positions and rbc_mesh_get_triangles. A world "wind" is set with
/// rbc_world_set_wind. Defs are asked for at this header's sizes; a library of ABI
/// 1.0-1.2 gets its own sizes when the scene needs nothing of 1.3, and is refused
/// (RBC_ERR_UNSUPPORTED naming the key) when it does. Returns RBC_OK and fills *out;
/// or the failing call's result, with nothing left created, *out zeroed and err set
/// to "<api->last_error()> (<what was being created>)" (mesh files:
/// "SOURCE: colliders[i].file: <message>").
rbc_result rbc_scene_instantiate(const rbc_api_v1 *api, const rbc_scene *scene,
                                 rbc_log_fn log, void *log_user, rbc_scene_instance *out,
                                 char *err, size_t err_size);

/// Move what the scene animates to where it is at the end of frame `frame` (0-based),
/// time (frame + 1) * dt: call it just before the rbc_world_step of that frame. Moving
/// colliders get rbc_collider_set_transform (the library derives their velocity from
/// the change of pose over the step); drags get rbc_cloth_set_pin with their target
/// while pinned, and once NULL at their release. A scene with neither makes no call.
/// Returns RBC_OK, or the failing call's result with err set as by
/// rbc_scene_instantiate.
rbc_result rbc_scene_apply_frame(const rbc_api_v1 *api, const rbc_scene *scene,
                                 const rbc_scene_instance *instance, uint32_t frame, char *err,
                                 size_t err_size);

/// Destroy the world of an instance (with its cloths and colliders), free the id
/// arrays and zero *instance. Safe on a zeroed instance.
void rbc_scene_instance_destroy(const rbc_api_v1 *api, rbc_scene_instance *instance);

#endif
