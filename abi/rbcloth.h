/*
 * rbcloth.h -- the public C ABI of librbcloth, a real-time quad mass-spring cloth
 * solver (Projective Dynamics with a Red-Black Gauss-Seidel global step; Pall,
 * Nylen, Fratarcangeli, "Fast Quadrangular Mass-Spring Systems using Red-Black
 * Ordering").
 *
 * This is the only file a host includes. It is C11 and C++ compatible and depends
 * on <stdint.h> and <stddef.h> alone. Every public struct uses fixed-width types,
 * enums are stored as int32_t, and there are no bool fields, so the structs are
 * blittable for C# P/Invoke, Python ctypes and similar FFIs.
 *
 * Conventions
 *  - Units are SI: metres, kilograms, seconds, newtons.
 *  - Every fallible call returns an rbc_result (0 = RBC_OK, errors are negative).
 *    After an error, rbc_last_error() returns a message for the calling thread that
 *    names the object, the index and what was wrong. A failing call leaves every
 *    existing object exactly as it was.
 *  - Defs (rbc_world_def, ...) start with uint32_t struct_size. Fill a def with its
 *    *_def_init() function (or the *_def_default() inline), change what you need,
 *    and pass it. The library reads
 *    only the fields that fit in struct_size, so a host compiled against an older
 *    header keeps working when fields are appended; a struct_size that matches no
 *    released version of the struct is refused with RBC_ERR_INVALID_ARGUMENT.
 *  - Handles are 32-bit ids that carry a kind and a generation: a destroyed or
 *    foreign id is reported as RBC_ERR_STALE_HANDLE, never dereferenced. 0 is the
 *    null id of every kind.
 *  - The library copies what it is given; outputs go into caller buffers.
 *  - The library never prints to stdout or stderr; messages go to the log hook of
 *    the world def, if any.
 *
 * Thread contract
 *  - Different worlds may be used concurrently from different threads.
 *  - One world is used by one thread at a time (the host serialises calls on it).
 *    A world may run its own worker threads inside rbc_world_step; host callbacks
 *    are always called on the thread that runs the step: the one that called
 *    rbc_world_step, or after rbc_world_step_begin (1.10) the world's step thread.
 *  - Between rbc_world_step_begin and rbc_world_step_wait a world is stepping: every
 *    other call on it, and on its cloths and colliders, returns RBC_ERR_BUSY and
 *    changes nothing (rbc_world_destroy first waits for the step). step_wait may be
 *    called from any thread; calls on one world, step_wait and destroy included, are
 *    still made one at a time.
 *  - A point cache, like a world, is used by one thread at a time; different caches
 *    may be used concurrently.
 *  - A mesh (rbc_mesh_import) is immutable: its getters and
 *    rbc_cloth_create_from_mesh may use it from several threads at once.
 *  - rbc_last_error() is per thread.
 *  - The remaining functions without a world or cache argument are thread-safe.
 *
 * ABI versioning
 *  - RBC_ABI_VERSION_MAJOR changes only when an existing function, struct layout or
 *    meaning changes incompatibly; functions and struct fields are only appended
 *    within a major. rbc_get_api(major) returns the function table of that major.
 *  - Each def and stats struct accepts the struct_size of every minor that had it:
 *    RBC_*_SIZE_V1_0 name the 1.0 sizes; fields appended later take their defaults.
 *  - 1.0: worlds, cloths (structural springs), plane/sphere colliders, callback,
 *    OBJ/PC2 writers. 1.1: selectable global solvers and iteration control
 *    (rbc_solver_def), shear and bend springs, multicolor coloring, residual and
 *    PD objective in stats, cloth state get/set, color sizes. 1.2: the energy guard
 *    (rbc_solver_def.energy_guard; energy, budget and clamps in stats), the
 *    memory a world holds (stats.memory_bytes), and mesh import (rbc_mesh_import:
 *    files read with assimp into library-owned meshes, rbc_cloth_create_from_mesh),
 *    MDD and OBJ-sequence caches (RBC_CACHE_MDD, RBC_CACHE_OBJ_SEQUENCE, with
 *    rbc_cache_def.quads). 1.3: contact inside the solve (capsule, box and
 *    triangle mesh colliders, friction, thickness, continuous detection), cloth
 *    against cloth and self contact (rbc_cloth_def.collision_flags), host contacts
 *    (rbc_world_set_contact_callback), picking, attachments, tearing and cuts
 *    (rbc_cloth_cut, rbc_cloth_get_quads), wind, and triangles of imported meshes.
 *    1.4: the target error mode (RBC_ITERATE_TARGET: rbc_solver_def.target_strain
 *    and max_substeps; what was chosen and reached in stats) and quality presets
 *    (rbc_solver_def_preset, RBC_PRESET_GAME_60HZ). 1.5: the cloth contact
 *    fail-safe's counts in stats. 1.6: defaults that give cloth at any dt: substeps
 *    from a rate (rbc_world_def.substeps 0 and substep_rate, 480 Hz by default)
 *    and red-black SOR (RBC_PRESET_CLOTH, what a 1.6 world def gets with `solver`
 *    NULL; defs of older sizes keep the paper's 1 substep of 11 RBGS iterations),
 *    RBC_PRESET_PAPER, and the strain warning (rbc_world_def.strain_warning;
 *    stats.step_max_strain and strain_warning_steps). 1.7: rbc_world_stats_init;
 *    the default thread count probes whether its threads pay. 1.8: mesh import
 *    runs in a helper process (rbcloth-import) with a time and a memory limit
 *    (rbc_mesh_import_def.timeout_ms, memory_limit_mb). 1.9: the round trip to the
 *    file's own mesh: every imported mesh maps the file's vertices, in the file's
 *    order, to its own (rbc_mesh_get_file_map, rbc_mesh_to_file_positions,
 *    rbc_mesh_write_file_obj); the file's units (rbc_mesh_import_def.keep_file_units,
 *    rbc_mesh_info.file_unit_metres and applied_scale); MDD times in seconds
 *    (rbc_cache_def.frame_rate). 1.10: a game loop: positions and normals into a
 *    host's own vertex buffer at a stride and offsets, several cloths per call
 *    (rbc_world_read_vertices), a triangle index buffer for every cloth with a
 *    revision that changes on tears and cuts (rbc_cloth_get_triangles), a rigid
 *    move of a whole cloth (rbc_cloth_transform), the split step
 *    (rbc_world_step_begin / rbc_world_step_wait, RBC_ERR_BUSY) and the host's own
 *    job system for the step's parallel work (rbc_world_def.enqueue_task,
 *    finish_task).
 *  - The ABI version is not the library's release version (rbc_version_string).
 */
#ifndef RBCLOTH_H
#define RBCLOTH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32)
#  if defined(RBC_BUILDING_LIBRARY)
#    define RBC_API __declspec(dllexport)
#  else
#    define RBC_API __declspec(dllimport)
#  endif
#  define RBC_CALL __cdecl
#else
#  if defined(RBC_BUILDING_LIBRARY)
#    define RBC_API __attribute__((visibility("default")))
#  else
#    define RBC_API
#  endif
#  define RBC_CALL
#endif

/// Major version of this ABI: incompatible changes bump it.
#define RBC_ABI_VERSION_MAJOR 1
/// Minor version of this ABI: appended functions or fields bump it.
#define RBC_ABI_VERSION_MINOR 10
/// (major << 16) | minor, as returned by rbc_abi_version().
#define RBC_ABI_VERSION ((RBC_ABI_VERSION_MAJOR << 16) | RBC_ABI_VERSION_MINOR)

/* ------------------------------------------------------------------------- */
/* Results                                                                   */
/* ------------------------------------------------------------------------- */

/// Result of every fallible call: 0 is success, errors are negative.
typedef int32_t rbc_result;
enum {
    RBC_OK = 0,
    /// An argument or a def field is out of its documented range (NULL pointer,
    /// non-finite number, dt <= 0, wrong struct_size, ...).
    RBC_ERR_INVALID_ARGUMENT = -1,
    /// An allocation failed (the library's or the host's allocator hook).
    RBC_ERR_OUT_OF_MEMORY = -2,
    /// The request is valid but this build does not support it.
    RBC_ERR_UNSUPPORTED = -3,
    /// The requested backend (e.g. CUDA) is not available on this machine or build.
    RBC_ERR_BACKEND_UNAVAILABLE = -4,
    /// The mesh is unusable: index out of range, degenerate quad, more than 64 colors.
    RBC_ERR_BAD_MESH = -5,
    /// A file could not be read or written.
    RBC_ERR_IO = -6,
    /// A step produced a non-finite position; the world was restored to its state
    /// before the step.
    RBC_ERR_UNSTABLE = -7,
    /// A handle was destroyed, belongs to another world or is of another kind.
    RBC_ERR_STALE_HANDLE = -8,
    /// A host callback reported failure (or wrote non-finite data); the world was
    /// restored to its state before the step.
    RBC_ERR_CALLBACK = -9,
    /// A fixed capacity (worlds, cloths, colliders per world) is exhausted.
    RBC_ERR_CAPACITY = -10,
    /// The world is stepping (between rbc_world_step_begin and rbc_world_step_wait):
    /// the call changed nothing; call rbc_world_step_wait first. (1.10)
    RBC_ERR_BUSY = -11,
    RBC_RESULT_FORCE32 = 0x7FFFFFFF
};

/* ------------------------------------------------------------------------- */
/* Handles                                                                   */
/* ------------------------------------------------------------------------- */

/// A world: owns cloths, colliders, threads and memory. 0 is null.
typedef uint32_t rbc_world_id;
/// A cloth inside one world. 0 is null.
typedef uint32_t rbc_cloth_id;
/// A collider inside one world. 0 is null.
typedef uint32_t rbc_collider_id;
/// A point-cache writer. 0 is null.
typedef uint32_t rbc_cache_id;

/* ------------------------------------------------------------------------- */
/* Enums (stored as int32_t)                                                 */
/* ------------------------------------------------------------------------- */

/// Which backend runs the solver. RBC_BACKEND_CUDA loads librbcloth_cuda.so from the
/// library's folder (or $RBC_CUDA_MODULE) with the first CUDA world: without it, a
/// driver or a GPU, rbc_world_create says why with RBC_ERR_BACKEND_UNAVAILABLE. A
/// CUDA world runs every iteration mode, the energy guard and plane, sphere, capsule
/// and box colliders, and refuses with RBC_ERR_UNSUPPORTED, naming it, what its
/// backend does not run yet: the serial and direct solvers (at creation and
/// rbc_world_set_solver); triangle mesh colliders, the energy guard with colliders,
/// the host callbacks, wind, cloth contact, tearing and attachments (at the step,
/// which then changes nothing), and a particle inside more than four colliders in one
/// substep (that step fails, changing nothing). Not yet run on a GPU in this release
/// (README.md).
typedef int32_t rbc_backend;
enum {
    RBC_BACKEND_AUTO = 0,  ///< the fastest available (CPU in this release)
    RBC_BACKEND_CPU = 1,   ///< threads on the host CPU
    RBC_BACKEND_CUDA = 2,  ///< an NVIDIA GPU (RBC_ERR_BACKEND_UNAVAILABLE if none)
    RBC_BACKEND_FORCE32 = 0x7FFFFFFF
};

/// Severity passed to the log hook.
typedef int32_t rbc_log_level;
enum {
    RBC_LOG_ERROR = 0,
    RBC_LOG_WARNING = 1,
    RBC_LOG_INFO = 2,
    RBC_LOG_DEBUG = 3,
    RBC_LOG_FORCE32 = 0x7FFFFFFF
};

/// Collider shapes.
typedef int32_t rbc_shape;
enum {
    /// The plane y = 0 of the collider's frame; cloth is kept on its +y side.
    RBC_SHAPE_PLANE = 1,
    /// A sphere of `radius` around the collider's origin.
    RBC_SHAPE_SPHERE = 2,
    /// A capsule: the points within `radius` of the segment from (0, -h, 0) to
    /// (0, h, 0) of the collider's frame, h = half_extents[1]. (1.3)
    RBC_SHAPE_CAPSULE = 3,
    /// An oriented box: |x| <= half_extents[0], |y| <= half_extents[1],
    /// |z| <= half_extents[2] in the collider's frame. (1.3)
    RBC_SHAPE_BOX = 4,
    /// A triangle mesh in the collider's frame (mesh_positions, mesh_triangles),
    /// copied and put in a bounding volume hierarchy. A closed mesh keeps cloth
    /// outside; an open one keeps cloth on the side it came from (the side of its
    /// triangles' normals at the first contact). (1.3)
    RBC_SHAPE_TRIANGLE_MESH = 5,
    RBC_SHAPE_FORCE32 = 0x7FFFFFFF
};

/// Point-cache formats.
typedef int32_t rbc_cache_format;
enum {
    /// PC2 (Blender's Mesh Cache modifier, 3ds Max): little-endian, "POINTCACHE2".
    RBC_CACHE_PC2 = 1,
    /// MDD (LightWave, Blender's Mesh Cache modifier): big-endian; int32 frames,
    /// int32 points, float32 times[frames] in seconds ((start_frame + k *
    /// sample_rate) / frame_rate; before 1.9 the frame numbers themselves), then
    /// float32[frames][points][3]. (1.2)
    RBC_CACHE_MDD = 2,
    /// A sequence of Wavefront OBJ files, one per frame: `path` is a prefix and
    /// frame k (0-based, in write order) goes to "<path>_%04d.obj" numbered k + 1
    /// ("cloth_0001.obj", ...), "v" lines in the given vertex order with %.9g (every
    /// float reads back exactly), then rbc_cache_def.quads as 1-based "f" lines. (1.2)
    RBC_CACHE_OBJ_SEQUENCE = 3,
    RBC_CACHE_FORMAT_FORCE32 = 0x7FFFFFFF
};

/// The solver of the global step (Eq. 6), per world. (1.1)
typedef int32_t rbc_solver_kind;
enum {
    /// Gauss-Seidel in parallel sweeps, one per color (Red-Black for a bipartite
    /// spring graph, more colors when shear/bend springs or odd cycles need them).
    /// The default.
    RBC_SOLVER_RBGS = 0,
    /// Jacobi: every particle from the previous iterate, fully parallel.
    RBC_SOLVER_JACOBI = 1,
    /// Jacobi with Chebyshev semi-iterative acceleration (Wang 2015).
    RBC_SOLVER_JACOBI_CHEBYSHEV = 2,
    /// Serial lexicographic Gauss-Seidel in the host's vertex order on one thread
    /// (the paper's CPU baseline).
    RBC_SOLVER_GAUSS_SEIDEL = 3,
    /// RBGS with successive over-relaxation by `omega`.
    RBC_SOLVER_RBGS_SOR = 4,
    /// RBGS with Chebyshev semi-iterative acceleration.
    RBC_SOLVER_RBGS_CHEBYSHEV = 5,
    /// Gauss-Seidel over the cloth's k-coloring: the same sweeps as RBC_SOLVER_RBGS,
    /// named for graphs that need more than two colors.
    RBC_SOLVER_MULTICOLOR_GS = 6,
    /// The exact global step: a sparse Cholesky factorisation (CHOLMOD) of the
    /// global matrix, made once and redone only when h, pins or topology change
    /// (Liu 2013, Projective Dynamics). Linear iteration counts do not apply. The
    /// factorisation happens in the first step with a new h or pin set: that step
    /// allocates (CHOLMOD's factor too, through the world's allocator hooks) and
    /// takes longer (about 13 ms at 10K particles, 1.4 s at 250K on one core); keep
    /// dt constant to pay it once. The library does not link CHOLMOD: the first
    /// def that names this solver (rbc_world_create, rbc_world_set_solver) loads
    /// libcholmod.so.3 (Debian's libcholmod3; $RBC_CHOLMOD_LIBRARY names another
    /// file of CHOLMOD 3) and its libraries, once per process; where it cannot,
    /// that call fails with RBC_ERR_BACKEND_UNAVAILABLE, naming the file and why,
    /// and changes nothing. The loader's and those libraries' own start-up
    /// allocations are malloc's, not the world's hooks. Builds without CHOLMOD
    /// (Windows) refuse it the same way.
    RBC_SOLVER_DIRECT = 7,
    RBC_SOLVER_FORCE32 = 0x7FFFFFFF
};

/// When the linear iterations of a global step stop. (1.1)
typedef int32_t rbc_iteration_mode;
enum {
    /// linear_iterations of the world (Alg. 1's fixed counts). The default.
    RBC_ITERATE_FIXED = 0,
    /// Until the relative residual of the global system falls below `tolerance`
    /// (checked after every iteration; the check costs about half an iteration for
    /// the Gauss-Seidel solvers, whose last color is exact, and one for Jacobi),
    /// or max_linear_iterations.
    RBC_ITERATE_TOLERANCE = 1,
    /// As many iterations as fit in budget_ms per rbc_world_step (the paper's
    /// Fig. 3/4 bottom rows), at least one per non-linear iteration, at most
    /// max_linear_iterations.
    RBC_ITERATE_BUDGET = 2,
    /// Ask for an error, not a count (1.4): the world chooses the substeps and the
    /// linear iterations of every step to bring the RMS relative strain of every
    /// cloth at the end of the step,
    ///     strain_rms = sqrt( sum_s ((|p_a - p_b| - L_s) / L_s)^2 / N )
    /// over its N springs that are not torn and have rest length L_s > 0 (Eq. 7 with
    /// each violation relative to its rest length), to `target_strain` or below,
    /// within a cap of `max_substeps` substeps and `max_linear_iterations` linear
    /// iterations per non-linear iteration (a deterministic cap in counts: a step
    /// never does more than max_substeps x nonlinear_iterations x
    /// max_linear_iterations linear iterations in max_substeps substeps).
    /// How it chooses:
    ///  - In the last global step of each step the strain of the iterate is checked
    ///    after every linear iteration (one pass over the springs, in float with
    ///    double sums, in fixed blocks: bitwise the same for any thread count), from
    ///    a quarter below the count that step needed last time on; it stops at 0.8
    ///    target_strain (room for the earlier substeps, friction and the post-solve
    ///    safety pass) or at max_linear_iterations. The earlier global steps run
    ///    that last count, unchecked (so the lattice fast path serves them); the
    ///    first step starts from the world's linear_iterations, within the cap.
    ///  - Between steps, substeps: a step that missed the target, or whose last
    ///    global step reached the cap above 0.95 target_strain, raises them by half
    ///    (at least 1) for the next step; after 8 steps in a row that met it without
    ///    that, the controller tries a quarter fewer, and undoes that if the next
    ///    step costs more (linear iterations + 3 per substep), doubling the 8 (up to
    ///    256) each time a lowering is undone, so it does not oscillate. The first
    ///    step in this mode (after rbc_world_create, rbc_world_set_solver or
    ///    rbc_world_set_iterations) runs max_substeps; the world's `substeps` is not
    ///    used.
    ///  - When the substeps change, previous positions are rescaled so velocities
    ///    are kept. (RBC_SOLVER_DIRECT refactors at every change of substeps.)
    /// Whether a step met the target is decided on its final positions, in double
    /// (stats.target_reached). What was done and reached is in rbc_world_stats
    /// (substeps, linear_iterations, target_reached, target_met, next_substeps,
    /// target_missed_steps, target_capped_steps). A step that misses at
    /// max_substeps (the target cannot be met within the cap) still returns
    /// RBC_OK; it is counted in target_capped_steps and logged as a warning at the
    /// first such step and at every power of two after it.
    RBC_ITERATE_TARGET = 3,
    RBC_ITERATE_FORCE32 = 0x7FFFFFFF
};

/* ------------------------------------------------------------------------- */
/* Host hooks                                                                */
/* ------------------------------------------------------------------------- */

/// Allocate `size` bytes aligned to `alignment` (a power of two, at most 64).
/// Return NULL on failure.
typedef void *(RBC_CALL *rbc_alloc_fn)(void *user, size_t size, size_t alignment);
/// Free memory returned by the matching rbc_alloc_fn; `size` is the size asked for.
typedef void (RBC_CALL *rbc_free_fn)(void *user, void *ptr, size_t size);
/// Receive a NUL-terminated message from the library.
typedef void (RBC_CALL *rbc_log_fn)(void *user, rbc_log_level level, const char *message);

/// One cloth as seen by the collision callback.
typedef struct rbc_collision_cloth {
    /// The cloth.
    rbc_cloth_id cloth;
    /// Number of vertices (entries of 3 floats in the arrays below).
    uint32_t vertex_count;
    /// Positions at the end of this substep, x y z per vertex in the order the cloth
    /// was created with, metres. The callback may move vertices (to resolve its own
    /// contacts); pinned vertices are put back on their pins afterwards.
    float *positions;
    /// Positions at the start of this substep, same layout, metres. Read only.
    const float *previous_positions;
} rbc_collision_cloth;

/// The host's collision code, called once per substep on the thread that runs the
/// step (the caller of rbc_world_step, or the world's step thread after
/// rbc_world_step_begin), after the solver and the built-in colliders. `dt` is the
/// substep length in seconds. Return 0 on success; any other value ends the step
/// with RBC_ERR_CALLBACK and the world as it was before the step.
typedef int32_t (RBC_CALL *rbc_collision_fn)(void *user, rbc_world_id world, float dt,
                                             const rbc_collision_cloth *cloths,
                                             uint32_t cloth_count);

/// A contact the host reports (rbc_contact_fn): keep `vertex` of `cloth` in the
/// half-space normal . p >= offset (normal unit, world frame, metres), with Coulomb
/// friction `friction` against a surface moving at `velocity` (m/s). It joins the
/// solve like a built-in collider's contact: projected after every linear
/// iteration, so the springs relax around it. (1.3)
typedef struct rbc_host_contact {
    rbc_cloth_id cloth;
    uint32_t vertex;
    float normal[3];
    float offset;
    float friction;
    float velocity[3];
} rbc_host_contact;

/// Where the contact callback puts its contacts: call `add` (any number of times,
/// from the callback's thread, during the callback only). It returns 0, or
/// RBC_ERR_INVALID_ARGUMENT for a contact with an unknown cloth, a vertex out of
/// range or a non-finite or non-unit normal (that contact is dropped and the step
/// fails with RBC_ERR_CALLBACK naming it), or RBC_ERR_OUT_OF_MEMORY. (1.3)
typedef struct rbc_contact_sink {
    void *impl;
    rbc_result (RBC_CALL *add)(struct rbc_contact_sink *sink, const rbc_host_contact *contacts,
                               uint32_t count);
} rbc_contact_sink;

/// The host's contact generation, called once per substep on the thread that runs
/// the step (as the collision callback), after the prediction and before the solve: `positions` hold the
/// predicted (inertial) positions and `previous_positions` those at the start of the
/// substep, both read only. Report contacts through `sink`. Return 0 on success;
/// any other value ends the step with RBC_ERR_CALLBACK and the world as it was. (1.3)
typedef int32_t (RBC_CALL *rbc_contact_fn)(void *user, rbc_world_id world, float dt,
                                           const rbc_collision_cloth *cloths,
                                           uint32_t cloth_count, rbc_contact_sink *sink);

/* ------------------------------------------------------------------------- */
/* Defs                                                                      */
/* ------------------------------------------------------------------------- */

/// What a world does when a step gives a cloth more energy than it was given. (1.2)
///
/// The guard bounds G = kinetic (free vertices, v = (x - x_prev) / h) +
/// gravitational (-m g . x) energy by a budget: the cloth's whole mechanical energy
/// (spring energy included) at its first step or after rbc_cloth_set_state, plus the
/// work done on it since: by pins moving (the change of spring energy they cause), by
/// moving built-in colliders (impulse . collider velocity; a static collider supplies
/// nothing) and by the host callback (the change of G it makes). Physical motion
/// never exceeds it (what G gains, the springs or a driver gave). Spring energy is
/// left out of G: a solve that has not converged leaves springs more stretched than
/// the energy supplied explains, an accuracy matter (Eq. 7), while a solver that adds
/// energy (Jacobi, Chebyshev or SOR past their stable range, float rounding at very
/// small h, post-solve collision projection) makes the cloth move faster or rise.
/// The check is one pass over the particles per step. It lets rounding through: 2^-20
/// of the magnitudes of its sums plus what half an ulp in every coordinate changes.
typedef int32_t rbc_energy_guard;
enum {
    /// No check; the solver's result is kept as is.
    RBC_ENERGY_GUARD_OFF = 0,
    /// Scale the free vertices' velocities (positions stay) so that E returns to the
    /// budget, count the step in stats.energy_clamped_steps and log a warning (at
    /// the first clamped step and at every power of two after it). If the excess
    /// is more than the kinetic energy (the positions alone hold more energy than
    /// the budget), every free vertex is stopped (velocities 0), the positions are
    /// kept and the budget is raised by what they hold; the step returns RBC_OK,
    /// counted and logged like any clamp.
    RBC_ENERGY_GUARD_CLAMP = 1,
    /// Fail the step with RBC_ERR_UNSTABLE (state restored) on any excess.
    RBC_ENERGY_GUARD_FAIL = 2,
    RBC_ENERGY_GUARD_FORCE32 = 0x7FFFFFFF
};

/// How the global step is solved. Fill one with rbc_solver_def_init. (1.1)
typedef struct rbc_solver_def {
    /// sizeof(rbc_solver_def) as compiled by the host.
    uint32_t struct_size;
    /// An rbc_solver_kind. Default RBC_SOLVER_RBGS.
    rbc_solver_kind solver;
    /// SOR relaxation factor for RBC_SOLVER_RBGS_SOR, in (0, 2); 0 = the optimal
    /// omega* = 2 / (1 + sqrt(1 - rho_J^2)) from the estimated Jacobi spectral radius
    /// rho_J. Default 0.
    float omega;
    /// Jacobi spectral radius rho_J for the Chebyshev solvers (RBGS_CHEBYSHEV uses
    /// rho_J^2, Gauss-Seidel's radius under red-black ordering), in (0, 1); 0 = estimated
    /// by the library (power iteration on the global system, redone when h or the
    /// topology change). Default 0.
    float rho;
    /// Plain iterations before Chebyshev acceleration starts (Wang 2015). Default 2.
    uint32_t chebyshev_delay;
    /// An rbc_iteration_mode. Default RBC_ITERATE_FIXED.
    rbc_iteration_mode mode;
    /// Relative residual |b - A p| / |b| to reach in RBC_ITERATE_TOLERANCE, > 0.
    /// Default 1e-3.
    float tolerance;
    /// Milliseconds per rbc_world_step in RBC_ITERATE_BUDGET, > 0. Default 2.
    float budget_ms;
    /// Most linear iterations per non-linear iteration in the TOLERANCE, BUDGET and
    /// TARGET modes, 1..100000. Default 1000 (RBC_PRESET_GAME_60HZ: 8).
    uint32_t max_linear_iterations;
    /* --- 1.2 --- */
    /// An rbc_energy_guard. Default RBC_ENERGY_GUARD_CLAMP.
    rbc_energy_guard energy_guard;
    /* --- 1.4 --- */
    /// RBC_ITERATE_TARGET: the RMS relative strain of every cloth to reach at the
    /// end of each step (see RBC_ITERATE_TARGET; 0.05 = springs 5 % off their rest
    /// length, root mean square), finite and > 0. Default 0.05.
    float target_strain;
    /// Most substeps per rbc_world_step: in RBC_ITERATE_TARGET, and (1.6) in a world
    /// whose substeps follow its substep_rate; 1..1024. Default 16
    /// (RBC_PRESET_GAME_60HZ and RBC_PRESET_CLOTH: 32).
    uint32_t max_substeps;
} rbc_solver_def;

/// sizeof(rbc_solver_def) in ABI 1.1 (before `energy_guard`).
#define RBC_SOLVER_DEF_SIZE_V1_1 ((uint32_t)offsetof(rbc_solver_def, energy_guard))
/// sizeof(rbc_solver_def) in ABI 1.2 and 1.3 (before `target_strain`).
#define RBC_SOLVER_DEF_SIZE_V1_2 ((uint32_t)offsetof(rbc_solver_def, target_strain))

/// Quality presets for rbc_solver_def_preset. (1.4)
typedef int32_t rbc_preset;
enum {
    /// The paper's solve, and rbc_solver_def_init's values: RBGS with fixed counts
    /// (the world's substeps and iterations; its defaults are the paper's 1 substep
    /// x 11 iterations). Fast, and far from converged at game time steps: at 1/60 s
    /// it stretches springs of the paper's cloth to 246 times their length, of a
    /// 64 x 48 grid to 52 times (docs/results/defaults.md). (Named
    /// RBC_PRESET_DEFAULT before 1.6, when it was also what a world got by default.)
    RBC_PRESET_PAPER = 0,
    RBC_PRESET_DEFAULT = RBC_PRESET_PAPER,
    /// Cloth in a game at 60 Hz (rbc_world_step(world, 1/60.f)): RBGS in
    /// RBC_ITERATE_TARGET, target_strain 0.05, max_substeps 32,
    /// max_linear_iterations 8 (at most 256 linear iterations per step), energy
    /// guard clamp. See docs/results/target.md for what it reaches and costs.
    RBC_PRESET_GAME_60HZ = 1,
    /// The default solve since 1.6 (a world whose 1.6-sized def leaves `solver`
    /// NULL runs it): red-black SOR (omega = Young's optimum for each substep
    /// length) with fixed counts, max_substeps 32 (the cap of a world whose
    /// substeps follow its substep_rate), energy guard clamp. With the world
    /// def's defaults (480 substeps a second, 11 iterations each) it gives cloth
    /// at any dt from 1/240 to 1/30 s at a cost proportional to dt;
    /// docs/results/defaults.md has its strain and cost on the paper's cloth and a
    /// 64 x 48 grid at 1/240, 1/60 and 1/30 s, beside the other presets. (1.6)
    RBC_PRESET_CLOTH = 2,
    RBC_PRESET_FORCE32 = 0x7FFFFFFF
};

/// A piece of the library's parallel work for the host's job system (1.10): run
/// items [begin, end) of it. `worker` is the index of the host's worker running it,
/// below the world def's thread_count (informative: the library does not rely on
/// it). Return promptly; never call back into the library from it.
typedef void (RBC_CALL *rbc_task_fn)(uint32_t begin, uint32_t end, uint32_t worker,
                                     void *task_context);
/// Hand `task` to the host's job system: items [0, item_count), split into ranges
/// of at least min_range items, each range one call of task(begin, end, worker,
/// task_context), on any threads, in any order, at once or later. Return a handle
/// for finish_task, or NULL when every range has already run (a serial executor
/// may run task(0, item_count, 0, task_context) inside this call). (1.10)
typedef void *(RBC_CALL *rbc_enqueue_task_fn)(rbc_task_fn task, uint32_t item_count,
                                              uint32_t min_range, void *task_context,
                                              void *user);
/// Wait until every range of the task behind `handle` has returned. (1.10)
typedef void (RBC_CALL *rbc_finish_task_fn)(void *handle, void *user);

/// How a world is made. Fill one with rbc_world_def_init (or rbc_world_def_default).
typedef struct rbc_world_def {
    /// sizeof(rbc_world_def) as compiled by the host.
    uint32_t struct_size;
    /// Gravity, m/s^2. Default (0, -9.81, 0).
    float gravity[3];
    /// Substeps per rbc_world_step call (each of length dt/substeps), 1..1024; or
    /// (1.6) 0: as many as `substep_rate` asks for, ceil(dt * substep_rate) per
    /// step, at most the solver's max_substeps (later substeps are longer), so the
    /// substep length and the result do not depend on the dt the host passes.
    /// Default 0 (for a def of an older struct_size: 1).
    uint32_t substeps;
    /// Non-linear (local/global) iterations per substep, Alg. 1 line 2. Default 1,
    /// range 1..1024.
    uint32_t nonlinear_iterations;
    /// Linear iterations per non-linear iteration, Alg. 1 line 4. Default 11 (the
    /// paper's count), range 1..4096.
    uint32_t linear_iterations;
    /// Backend, an rbc_backend. Default RBC_BACKEND_AUTO.
    rbc_backend backend;
    /// Worker threads including the caller's, for the CPU backend; 0 = one per
    /// available core (at most 64), and each step runs on all of them or on the
    /// caller's alone, whichever its probes measure faster (every 8 to 256 steps, two
    /// steps try the other): a machine whose cores other work holds gets one thread, so
    /// a step is not slowed by waiting for descheduled workers. Results are the same
    /// bits either way. A count > 0 is used as given. Default 0.
    uint32_t thread_count;
    /// Log threshold: messages of this level and more severe reach `log`.
    /// Default RBC_LOG_WARNING.
    rbc_log_level log_level;
    /// Optional allocator hooks; both or neither. Default NULL (malloc/free).
    /// Every allocation of the world's calls goes through them, RBC_SOLVER_DIRECT's
    /// CHOLMOD blocks included (CHOLMOD's through SuiteSparse's process-global
    /// SuiteSparse_config, which the library points at its own wrappers unless the
    /// host has set it: then CHOLMOD uses the host's SuiteSparse allocator instead).
    rbc_alloc_fn alloc;
    rbc_free_fn free;
    void *alloc_user;
    /// Optional log hook. Default NULL (messages are dropped).
    rbc_log_fn log;
    void *log_user;
    /* --- 1.1 --- */
    /// The global solver and iteration control, copied; NULL = the default solve:
    /// RBC_PRESET_CLOTH (red-black SOR) for a def of the 1.6 size,
    /// rbc_solver_def_init's values (RBC_PRESET_PAPER: RBGS) for the 1.1-1.5
    /// sizes, which is what their headers documented. Default NULL.
    const rbc_solver_def *solver;
    /* --- 1.6 --- */
    /// Substeps per second of simulated time when `substeps` is 0, Hz; finite and
    /// > 0 (ignored when substeps > 0). Default 480: 8 substeps of a 1/60 s step,
    /// 2 of a 1/240 s one, each about the paper's 2 ms. docs/results/defaults.md
    /// has the strain and cost of 240, 480 and 960 Hz at 1/240, 1/60 and 1/30 s.
    float substep_rate;
    /// The strain warning: a step that leaves some spring with a relative strain
    /// | |p_a - p_b| / L - 1 | above this is not cloth any more. The step still
    /// returns RBC_OK; it is counted in stats.strain_warning_steps, its largest
    /// strain is stats.step_max_strain, and the log hook gets a warning (at the
    /// first such step and at every power of two after it) naming the cloth, the
    /// spring and advice that fits the world's solver settings. The check is one
    /// pass over the springs at the end of each step. 0 turns it off (no pass;
    /// step_max_strain reads 0); else finite and > 0. Default 2 (a spring at three
    /// times its rest length): the converged motion of the paper's cloth peaks at
    /// 1.23 (at its pins, swinging) and the default solve at 1.29, while the
    /// paper's step at 1/240 to 1/30 s reaches 4 to 850 (docs/results/defaults.md).
    float strain_warning;
    /* --- 1.10 --- */
    /// Optional: the host's job system runs the step's parallel work (as Box2D v3's
    /// enqueueTask / finishTask); both or neither. Then the world starts no thread
    /// of its own: each parallel phase of a step hands the host thread_count - 1
    /// items with min_range 1, runs its own share on the calling thread, and shares
    /// the work with those items that start within a short wait (a quarter of the
    /// last phase's time; items that start later return at once), then calls
    /// finish_task before the step returns. thread_count 0 is one participant per
    /// core, and each step asks for the items or runs on the calling thread alone,
    /// whichever the world's probes measure faster (as for its own threads). A job
    /// system whose workers are busy costs a short wait, never a deadlock, and the
    /// result is bitwise the one of the world's own threads at any thread count.
    /// The library calls them only inside a step, on the thread running the step.
    /// Default NULL.
    rbc_enqueue_task_fn enqueue_task;
    rbc_finish_task_fn finish_task;
    /// Passed to enqueue_task and finish_task as `user`. Default NULL.
    void *task_user;
} rbc_world_def;

/// sizeof(rbc_world_def) in ABI 1.0 (before `solver`).
#define RBC_WORLD_DEF_SIZE_V1_0 ((uint32_t)offsetof(rbc_world_def, solver))
/// sizeof(rbc_world_def) in ABI 1.1 to 1.5 (before `substep_rate`).
#define RBC_WORLD_DEF_SIZE_V1_1 ((uint32_t)offsetof(rbc_world_def, substep_rate))
/// sizeof(rbc_world_def) in ABI 1.6 to 1.9 (before `enqueue_task`).
#define RBC_WORLD_DEF_SIZE_V1_6 ((uint32_t)offsetof(rbc_world_def, enqueue_task))

/// How a cloth is made. Fill one with rbc_cloth_def_init (or rbc_cloth_def_default).
/// All arrays are copied.
typedef struct rbc_cloth_def {
    /// sizeof(rbc_cloth_def) as compiled by the host.
    uint32_t struct_size;
    /// Number of vertices (particles), at least 1.
    uint32_t vertex_count;
    /// Rest positions, x y z per vertex, metres. Also the initial positions.
    const float *positions;
    /// Number of quads.
    uint32_t quad_count;
    /// Quads, 4 vertex indices each, in order around the face. Each quad edge
    /// becomes one structural spring (shared edges once).
    const uint32_t *quads;
    /// Number of explicit extra springs.
    uint32_t spring_count;
    /// Extra springs, 2 vertex indices each; duplicates of quad edges are merged. An
    /// index out of range or a spring from a vertex to itself is RBC_ERR_BAD_MESH, as
    /// are quads with an index out of range, a repeated vertex, coincident corners or
    /// zero area, and (since 1.1) a spring graph that needs more than 64 colors.
    const uint32_t *springs;
    /// Per-vertex masses, kg (finite, > 0), or NULL to use `density` or `vertex_mass`.
    const float *masses;
    /// Areal density, kg/m^2: if > 0 and `masses` is NULL, each quad's area is
    /// split equally among its four vertices. Default 0.
    float density;
    /// Mass of every vertex, kg, when `masses` is NULL and `density` is 0.
    /// Default 1e-4.
    float vertex_mass;
    /// Spring stiffness s of Eq. 4, N/m, for every spring; finite and > 0.
    /// Default 1000.
    float stiffness;
    /// Velocity damping, 1/s: Alg. 2's f_damping as an acceleration -damping * v.
    /// Default 0. damping * substep length is clamped to 1 (critical).
    float damping;
    /// Number of pinned vertices.
    uint32_t pin_count;
    /// Vertices pinned at their initial positions (move them with rbc_cloth_set_pin).
    /// An index out of range is RBC_ERR_INVALID_ARGUMENT.
    const uint32_t *pins;
    /* --- 1.1 --- */
    /// Stiffness of shear springs, N/m: one along each diagonal of every quad; 0 (the
    /// default) adds none. Shear springs make the graph need 4 colors on a grid.
    float shear_stiffness;
    /// Stiffness of bend springs, N/m: one joining the far ends of every pair of
    /// edges that are opposite at a vertex (skip-one springs: (i,j)-(i+2,j) on a
    /// grid); 0 (the default) adds none.
    float bend_stiffness;
    /* --- 1.3 --- */
    /// Distance the cloth's particles keep from collider surfaces (added to the
    /// collider's thickness) and from cloth surfaces (self and cloth-cloth contact),
    /// metres, >= 0. Default 0.
    float thickness;
    /// Coulomb friction coefficient, >= 0: against colliders (the larger of the two
    /// applies) and against cloth. Default 0.
    float friction;
    /// Which cloth contact this cloth takes part in: RBC_CLOTH_COLLIDE_* flags, or 0
    /// (the default: colliders only; a scene without cloth contact pays nothing for
    /// it). Cloth contact needs thickness > 0.
    uint32_t collision_flags;
    /// Tearing: a spring whose length exceeds (1 + tear_strain) times its rest length
    /// at the end of a step breaks (it and the quads that have it as an edge are
    /// removed; rbc_cloth_get_quads reads what remains). 0 (the default) = never;
    /// else finite and > 0. Explicit cuts (rbc_cloth_cut) work either way.
    float tear_strain;
} rbc_cloth_def;

/// sizeof(rbc_cloth_def) in ABI 1.0 (before `shear_stiffness`).
#define RBC_CLOTH_DEF_SIZE_V1_0 ((uint32_t)offsetof(rbc_cloth_def, shear_stiffness))
/// sizeof(rbc_cloth_def) in ABI 1.1 and 1.2 (before `thickness`).
#define RBC_CLOTH_DEF_SIZE_V1_1 ((uint32_t)offsetof(rbc_cloth_def, thickness))

/// rbc_cloth_def.collision_flags. (1.3)
enum {
    /// The cloth collides with itself (vertex-triangle and vertex-vertex contact
    /// between parts that do not touch at rest, and edge-edge contact between its
    /// edges; its interior edges also against those of the cloths it collides with).
    RBC_CLOTH_COLLIDE_SELF = 1,
    /// The cloth collides with the other cloths that have this flag.
    RBC_CLOTH_COLLIDE_CLOTHS = 2
};

/// How a collider is made. Fill one with rbc_collider_def_init (or
/// rbc_collider_def_default).
typedef struct rbc_collider_def {
    /// sizeof(rbc_collider_def) as compiled by the host.
    uint32_t struct_size;
    /// An rbc_shape. Default RBC_SHAPE_PLANE.
    rbc_shape shape;
    /// Sphere radius, metres (> 0 for spheres). Default 0.5.
    float radius;
    /// Distance kept between the cloth and the surface, metres (>= 0). Default 0.
    float thickness;
    /// Origin of the collider's frame in the world, metres. Default (0, 0, 0).
    float position[3];
    /// Orientation of the collider's frame, unit quaternion x y z w. Default identity.
    float rotation[4];
    /* --- 1.3 --- */
    /// Coulomb friction coefficient against cloth, >= 0 (a contact uses the larger of
    /// the collider's and the cloth's). Default 0.
    float friction;
    /// Box half sizes along the frame's x, y, z (RBC_SHAPE_BOX), metres, each > 0;
    /// RBC_SHAPE_CAPSULE uses half_extents[1] as the half length of its axis (> 0).
    /// Default (0.5, 0.5, 0.5).
    float half_extents[3];
    /// RBC_SHAPE_TRIANGLE_MESH: vertex positions in the collider's frame (3 floats
    /// each, metres) and triangles (3 vertex indices each), copied. Default NULL, 0.
    const float *mesh_positions;
    uint32_t mesh_vertex_count;
    const uint32_t *mesh_triangles;
    uint32_t mesh_triangle_count;
} rbc_collider_def;

/// sizeof(rbc_collider_def) in ABI 1.0 to 1.2 (before `friction`).
#define RBC_COLLIDER_DEF_SIZE_V1_0 ((uint32_t)offsetof(rbc_collider_def, friction))

/// How a point cache is written. Fill one with rbc_cache_def_init (or
/// rbc_cache_def_default).
typedef struct rbc_cache_def {
    /// sizeof(rbc_cache_def) as compiled by the host.
    uint32_t struct_size;
    /// An rbc_cache_format. Default RBC_CACHE_PC2.
    rbc_cache_format format;
    /// Output file (UTF-8). It appears only when rbc_cache_finish succeeds; until
    /// then data goes to "<path>.tmp" (written, then renamed). MDD also uses
    /// "<path>.tmp.frames" while writing. RBC_CACHE_OBJ_SEQUENCE: the prefix of the
    /// files; every frame is written to "<name>.tmp" and all are renamed into place,
    /// in frame order, by rbc_cache_finish (so the last file appearing means the
    /// whole sequence is there). rbc_cache_destroy, a failed finish or a failed
    /// create removes every temporary file and leaves the destinations untouched.
    const char *path;
    /// Points per frame, at least 1.
    uint32_t point_count;
    /// First frame number stored in the header. Default 0.
    float start_frame;
    /// Frames between samples, stored in the header. Default 1.
    float sample_rate;
    /// The faces written by RBC_CACHE_OBJ_SEQUENCE: quad_count quads of 4 vertex
    /// indices (each < point_count), copied at rbc_cache_create; NULL and 0 = "v"
    /// lines only. Ignored by PC2 and MDD. Default NULL, 0. (1.2)
    const uint32_t *quads;
    uint32_t quad_count;
    /// Unused and ignored: the 1.2-1.8 layout's trailing padding, named so that the
    /// 1.9 field below starts after the size those hosts pass (48 bytes on LP64).
    uint32_t reserved_v1_2;
    /* --- 1.9 --- */
    /// Frames per second, finite and > 0: MDD stores times in seconds, frame /
    /// frame_rate, which Blender's Mesh Cache modifier plays in its TIME mode at the
    /// scene's rate. Ignored by PC2 and OBJ sequences. Default 24 (Blender's default
    /// scene rate); a def of an older size gets 24 too.
    float frame_rate;
} rbc_cache_def;

/// sizeof(rbc_cache_def) in ABI 1.0 and 1.1 (before quads).
#define RBC_CACHE_DEF_SIZE_V1_0 ((uint32_t)offsetof(rbc_cache_def, quads))
/// sizeof(rbc_cache_def) in ABI 1.2 to 1.8 (before frame_rate).
#define RBC_CACHE_DEF_SIZE_V1_2 ((uint32_t)offsetof(rbc_cache_def, frame_rate))

/* ------------------------------------------------------------------------- */
/* Stats                                                                     */
/* ------------------------------------------------------------------------- */

/// Figures of a world, filled by rbc_world_get_stats. Set struct_size first; only
/// the fields that fit in it are written.
typedef struct rbc_world_stats {
    /// sizeof(rbc_world_stats) as compiled by the host.
    uint32_t struct_size;
    /// Live cloths and colliders.
    uint32_t cloth_count;
    uint32_t collider_count;
    /// Particles and springs over all cloths.
    uint32_t particle_count;
    uint32_t spring_count;
    /// Largest number of colors used by any cloth (2 for a quad grid).
    uint32_t color_count;
    /// Worker threads including the caller's that the last step ran on (before the
    /// first step: the pool's size).
    uint32_t thread_count;
    /// Backend in use, an rbc_backend (never AUTO).
    rbc_backend backend;
    /// Successful rbc_world_step calls so far.
    uint64_t step_count;
    /// Substeps, non-linear and linear iterations done by the last step (totals over
    /// its substeps).
    uint32_t substeps;
    uint32_t nonlinear_iterations;
    uint32_t linear_iterations;
    uint32_t reserved0;
    /// Wall time of the last step and of its stages, milliseconds: Verlet
    /// integration (Alg. 2), local step (Alg. 3), global Red-Black Gauss-Seidel
    /// sweeps (Eq. 6), built-in colliders, the host callback, and the rest
    /// (pins, stability checks, bookkeeping).
    double step_ms;
    double integrate_ms;
    double local_ms;
    double global_ms;
    double collide_ms;
    double callback_ms;
    double other_ms;
    /// Eq. 7 of the paper at the current positions: sum over springs of
    /// (|p_i - p_j| - L_ij)^2, m^2.
    double error_eq7;
    /// Largest relative spring violation | |p_i - p_j| / L_ij - 1 | now (0 for
    /// zero-length springs).
    double max_strain;
    /* --- 1.1 --- */
    /// The solver in use, an rbc_solver_kind.
    rbc_solver_kind solver;
    /// An rbc_iteration_mode.
    rbc_iteration_mode iteration_mode;
    /// Relative residual |b - A p| / |b| of the last substep's global linear system
    /// (Eq. 6 over the free particles, with that substep's last local step) at the
    /// current positions; 0 before the first step.
    double linear_residual;
    /// Projective Dynamics objective of the last substep at the current positions:
    /// sum_i m_i / (2 h^2) |p_i - y_i|^2 + sum_s s / 2 (|p_a - p_b| - L)^2, joules.
    double pd_objective;
    /// Jacobi spectral radius in use (estimated or given; 0 if no solver needed it).
    double spectral_radius;
    /// SOR omega in use (RBGS_SOR), else 0.
    double omega;
    /* --- 1.2 --- */
    /// Kinetic energy of the free vertices (velocities (x - x_prev) / h of the last
    /// step) and potential energy (springs, and gravity as -m g . x over the free
    /// vertices) of all cloths now, joules.
    double kinetic_energy;
    double potential_energy;
    /// What the energy guard lets kinetic + gravitational energy reach (see
    /// rbc_energy_guard), joules; 0 while the guard is off or before the first step.
    double energy_budget;
    /// Energy the guard removed in the last step, joules (0 if it did not act).
    double energy_removed;
    /// Steps so far whose velocities the guard scaled (RBC_ENERGY_GUARD_CLAMP).
    uint64_t energy_clamped_steps;
    /// Bytes the world holds for its cloths and solver buffers (not the thread pool
    /// or the registry).
    uint64_t memory_bytes;
    /// Input, set before the call: 1 skips the fields that cost a pass over every
    /// cloth (error_eq7, max_strain, linear_residual, pd_objective, kinetic_energy,
    /// potential_energy read 0); counts, timings, iterations, the energy budget and
    /// clamps stay. For a host that reads stats every frame for timings: a full
    /// reading costs about as much as a step of 11 RBGS iterations. Kept as given.
    /// Any value but 0 skips (hosts of 1.2 to 1.6 that left it unset keep what they
    /// got): fill the struct with rbc_world_stats_init (1.7) so that it is 0.
    uint32_t skip_measures;
    uint32_t reserved1;
    /* --- 1.3 --- */
    /// Contacts of the last step's last substep: particles against built-in colliders
    /// and host contacts (rbc_world_set_contact_callback), and cloth against cloth
    /// (self contact included).
    uint32_t collider_contacts;
    uint32_t cloth_contacts;
    /// Springs broken so far (tearing and rbc_cloth_cut), over all cloths.
    uint64_t torn_springs;
    /* --- 1.4 --- */
    /// RMS relative strain now (RBC_ITERATE_TARGET's measure), the largest over the
    /// cloths; a pass over every cloth (0 with skip_measures).
    double strain_rms;
    /// RBC_ITERATE_TARGET: the strain the last step reached (the same measure at the
    /// end of that step, computed by the step itself: kept with skip_measures), and
    /// 1 if it was <= target_strain, else 0. Both 0 in the other modes.
    double target_reached;
    uint32_t target_met;
    /// The substeps the next step will use: the controller's choice in
    /// RBC_ITERATE_TARGET, else the world's count (0 when it follows the substep
    /// rate: then they depend on the next dt). (The last step's substeps and
    /// iterations are `substeps` and `linear_iterations` above.)
    uint32_t next_substeps;
    /// Steps so far in RBC_ITERATE_TARGET whose end strain exceeded the target, and
    /// among them those run at max_substeps: the target could not be met within the
    /// cap (each such step is also logged, at 1, 2, 4, ...).
    uint64_t target_missed_steps;
    uint64_t target_capped_steps;
    /* --- 1.5 --- */
    /// Cloth contact's fail-safe in the last step (summed over its substeps): the
    /// vertices it sent back to where their substep started because an edge ended
    /// the substep through a triangle the contact solve had not kept it from (they
    /// lose that substep's motion). 0 in a scene whose contacts hold.
    uint32_t cloth_contact_frozen;
    /// Vertices of the last step's last substep with more triangles in reach than a
    /// vertex keeps contacts with (64, the nearest; as many vertex-vertex contacts):
    /// cloth crushed, or folded through itself (a cloth without self contact).
    uint32_t cloth_contact_capped;
    /* --- 1.6 --- */
    /// The largest relative strain | |p_a - p_b| / L - 1 | over the live springs of
    /// every cloth at the end of the last step, computed by the step (in float: to
    /// about 1e-5; kept with skip_measures); 0 if rbc_world_def.strain_warning is 0.
    double step_max_strain;
    /// Steps so far whose step_max_strain exceeded rbc_world_def.strain_warning (each
    /// logged at 1, 2, 4, ...).
    uint64_t strain_warning_steps;
} rbc_world_stats;

/// sizeof(rbc_world_stats) in ABI 1.5 (before `step_max_strain`).
#define RBC_WORLD_STATS_SIZE_V1_5 ((uint32_t)offsetof(rbc_world_stats, step_max_strain))

/// sizeof(rbc_world_stats) in ABI 1.4 (before `cloth_contact_frozen`).
#define RBC_WORLD_STATS_SIZE_V1_4 ((uint32_t)offsetof(rbc_world_stats, cloth_contact_frozen))

/// sizeof(rbc_world_stats) in ABI 1.3 (before `strain_rms`).
#define RBC_WORLD_STATS_SIZE_V1_3 ((uint32_t)offsetof(rbc_world_stats, strain_rms))

/// sizeof(rbc_world_stats) in ABI 1.2 (before `collider_contacts`).
#define RBC_WORLD_STATS_SIZE_V1_2 ((uint32_t)offsetof(rbc_world_stats, collider_contacts))

/// sizeof(rbc_world_stats) in ABI 1.1 (before `kinetic_energy`).
#define RBC_WORLD_STATS_SIZE_V1_1 ((uint32_t)offsetof(rbc_world_stats, kinetic_energy))

/// sizeof(rbc_world_stats) in ABI 1.0 (before `solver`).
#define RBC_WORLD_STATS_SIZE_V1_0 ((uint32_t)offsetof(rbc_world_stats, solver))

/* ------------------------------------------------------------------------- */
/* Functions                                                                 */
/* ------------------------------------------------------------------------- */

/// RBC_ABI_VERSION of the loaded library: (major << 16) | minor.
RBC_API uint32_t RBC_CALL rbc_abi_version(void);
/// The three functions below return borrowed strings (UTF-8, NUL-terminated): the
/// library owns them (static text, or the calling thread's error buffer) and the
/// host must never free them. Declare them as pointers, not as owned strings:
///   C# (Mono, .NET): `[DllImport("rbcloth")] static extern IntPtr rbc_last_error();`
///       and `Marshal.PtrToStringUTF8(p)` (or PtrToStringAnsi on Mono 6.8). A
///       `string` return type makes the marshaller free the pointer: Mono aborts
///       with "free(): invalid pointer" on the first call.
///   Python ctypes: `restype = ctypes.c_char_p` (ctypes copies into bytes, frees
///       nothing); cffi: `ffi.string(lib.rbc_last_error())`.
///   Rust: `fn rbc_last_error() -> *const c_char`, then
///       `CStr::from_ptr(p).to_string_lossy().into_owned()` to keep a copy.
/// Release version of the library, e.g. "0.1.0". Borrowed, static.
RBC_API const char *RBC_CALL rbc_version_string(void);
/// Name of a result code, e.g. "RBC_ERR_BAD_MESH"; "unknown result" otherwise.
/// Borrowed, static.
RBC_API const char *RBC_CALL rbc_result_string(rbc_result result);
/// Message of the last error on the calling thread ("" if none yet). Borrowed: valid
/// until the next failing call on this thread; copy it to keep it.
RBC_API const char *RBC_CALL rbc_last_error(void);

/// Fill a def with the defaults documented on its fields. `struct_size` is
/// sizeof(the def) as compiled by the host and must be a released size of it; only
/// that many bytes are written (the def's own struct_size field is set to it), so a
/// host built against an older header is never overrun by a newer library.
RBC_API rbc_result RBC_CALL rbc_world_def_init(rbc_world_def *def, uint32_t struct_size);
RBC_API rbc_result RBC_CALL rbc_cloth_def_init(rbc_cloth_def *def, uint32_t struct_size);
RBC_API rbc_result RBC_CALL rbc_collider_def_init(rbc_collider_def *def, uint32_t struct_size);
RBC_API rbc_result RBC_CALL rbc_cache_def_init(rbc_cache_def *def, uint32_t struct_size);

/// C and C++ conveniences for hosts linked to the library: a def with defaults.
/// (Hosts that load the library at run time call the *_def_init entries instead.)
static inline rbc_world_def rbc_world_def_default(void) {
    rbc_world_def d;
    rbc_world_def_init(&d, (uint32_t)sizeof d);
    return d;
}
static inline rbc_cloth_def rbc_cloth_def_default(void) {
    rbc_cloth_def d;
    rbc_cloth_def_init(&d, (uint32_t)sizeof d);
    return d;
}
static inline rbc_collider_def rbc_collider_def_default(void) {
    rbc_collider_def d;
    rbc_collider_def_init(&d, (uint32_t)sizeof d);
    return d;
}
static inline rbc_cache_def rbc_cache_def_default(void) {
    rbc_cache_def d;
    rbc_cache_def_init(&d, (uint32_t)sizeof d);
    return d;
}
/* rbc_solver_def_default() is declared with the 1.1 functions below. */

/// Create a world. *out_world receives its id.
RBC_API rbc_result RBC_CALL rbc_world_create(const rbc_world_def *def, rbc_world_id *out_world);
/// Destroy a world with everything in it.
RBC_API rbc_result RBC_CALL rbc_world_destroy(rbc_world_id world);
/// Advance the world by dt seconds (> 0) in `substeps` substeps. On error the world
/// is as it was before the call.
RBC_API rbc_result RBC_CALL rbc_world_step(rbc_world_id world, float dt);
/// Change the iteration counts used by the next steps (ranges as in rbc_world_def;
/// substeps 0 = from the substep rate, for a world made with a 1.6 def).
RBC_API rbc_result RBC_CALL rbc_world_set_iterations(rbc_world_id world, uint32_t substeps,
                                                     uint32_t nonlinear_iterations,
                                                     uint32_t linear_iterations);
/// Change gravity, m/s^2.
RBC_API rbc_result RBC_CALL rbc_world_set_gravity(rbc_world_id world, const float gravity[3]);
/// Fill *stats (set stats->struct_size first). Computes Eq. 7 at call time.
/// skip_measures is read from *stats: start from rbc_world_stats_init (or zero the
/// struct) so that it is not whatever the memory held.
RBC_API rbc_result RBC_CALL rbc_world_get_stats(rbc_world_id world, rbc_world_stats *stats);
/// Zero *stats and set its struct_size (sizeof(rbc_world_stats) as the host compiled
/// it, at least RBC_WORLD_STATS_SIZE_V1_0): every input (skip_measures) then has its
/// default. (1.7)
RBC_API rbc_result RBC_CALL rbc_world_stats_init(rbc_world_stats *stats, uint32_t struct_size);
/// Install (or, with fn NULL, remove) the host collision callback.
RBC_API rbc_result RBC_CALL rbc_world_set_collision_callback(rbc_world_id world,
                                                             rbc_collision_fn fn, void *user);

/// Create a cloth from a quad mesh. *out_cloth receives its id.
RBC_API rbc_result RBC_CALL rbc_cloth_create(rbc_world_id world, const rbc_cloth_def *def,
                                             rbc_cloth_id *out_cloth);
RBC_API rbc_result RBC_CALL rbc_cloth_destroy(rbc_world_id world, rbc_cloth_id cloth);
/// Number of vertices of the cloth into *out_count.
RBC_API rbc_result RBC_CALL rbc_cloth_get_vertex_count(rbc_world_id world, rbc_cloth_id cloth,
                                                       uint32_t *out_count);
/// Number of springs and of colors of the cloth (either pointer may be NULL).
RBC_API rbc_result RBC_CALL rbc_cloth_get_topology(rbc_world_id world, rbc_cloth_id cloth,
                                                   uint32_t *out_spring_count,
                                                   uint32_t *out_color_count);
/// Copy current positions, x y z per vertex in the creation order, into xyz.
/// `capacity` is the number of floats xyz holds (at least 3 * vertex count).
/// With xyz NULL, only *out_written (if not NULL) receives the float count needed.
RBC_API rbc_result RBC_CALL rbc_cloth_read_positions(rbc_world_id world, rbc_cloth_id cloth,
                                                     float *xyz, size_t capacity,
                                                     size_t *out_written);
/// Pin `vertex` at `target` (x y z, metres), moving it there linearly over the
/// substeps of the next step; or release its pin with target NULL.
RBC_API rbc_result RBC_CALL rbc_cloth_set_pin(rbc_world_id world, rbc_cloth_id cloth,
                                              uint32_t vertex, const float *target);

/// Create a collider. *out_collider receives its id.
RBC_API rbc_result RBC_CALL rbc_collider_create(rbc_world_id world, const rbc_collider_def *def,
                                                rbc_collider_id *out_collider);
/// Move a collider: position (metres) and unit quaternion x y z w.
RBC_API rbc_result RBC_CALL rbc_collider_set_transform(rbc_world_id world,
                                                       rbc_collider_id collider,
                                                       const float position[3],
                                                       const float rotation[4]);
RBC_API rbc_result RBC_CALL rbc_collider_destroy(rbc_world_id world, rbc_collider_id collider);

/// Write a quad mesh as Wavefront OBJ ("v" lines in the given order, 1-based "f"
/// lines), atomically (temporary file, then rename).
RBC_API rbc_result RBC_CALL rbc_write_obj(const char *path, const float *xyz,
                                          uint32_t vertex_count, const uint32_t *quads,
                                          uint32_t quad_count);
/// Start a point cache. *out_cache receives its id.
RBC_API rbc_result RBC_CALL rbc_cache_create(const rbc_cache_def *def, rbc_cache_id *out_cache);
/// Append one frame: 3 * point_count floats.
RBC_API rbc_result RBC_CALL rbc_cache_write_frame(rbc_cache_id cache, const float *xyz);
/// Complete the file (header, flush, rename into place) and destroy the writer.
RBC_API rbc_result RBC_CALL rbc_cache_finish(rbc_cache_id cache);
/// Abandon a cache: its temporary file is removed, the destination is untouched.
RBC_API rbc_result RBC_CALL rbc_cache_destroy(rbc_cache_id cache);

/* --- 1.1 --- */
/// Fill a solver def with its field defaults (see rbc_world_def_init for
/// struct_size): RBGS with the world's fixed counts, RBC_PRESET_PAPER. The default
/// solve of a world (RBC_PRESET_CLOTH since 1.6) is rbc_solver_def_preset's.
RBC_API rbc_result RBC_CALL rbc_solver_def_init(rbc_solver_def *def, uint32_t struct_size);
/// Change the global solver and iteration control for the next steps.
RBC_API rbc_result RBC_CALL rbc_world_set_solver(rbc_world_id world, const rbc_solver_def *def);
/// Read the solver settings in use (set def->struct_size first).
RBC_API rbc_result RBC_CALL rbc_world_get_solver(rbc_world_id world, rbc_solver_def *def);
/// Fill a solver def with a quality preset (an rbc_preset): the defaults of
/// rbc_solver_def_init, then the preset's fields. A 1.1-1.3 struct_size gets the
/// fields that fit (RBC_PRESET_GAME_60HZ and RBC_PRESET_CLOTH then need 1.4:
/// refused with RBC_ERR_INVALID_ARGUMENT, since the game preset's mode would run
/// without its target and the cloth preset's cap, max_substeps, would not fit).
/// (1.4)
RBC_API rbc_result RBC_CALL rbc_solver_def_preset(rbc_solver_def *def, uint32_t struct_size,
                                                  rbc_preset preset);
/// Sizes of the cloth's color classes: sizes[c] = particles of color c, for
/// c < min(capacity, colors); *out_color_count (if not NULL) = number of colors.
RBC_API rbc_result RBC_CALL rbc_cloth_get_colors(rbc_world_id world, rbc_cloth_id cloth,
                                                 uint32_t *sizes, uint32_t capacity,
                                                 uint32_t *out_color_count);
/// Copy positions and previous positions (the state Verlet integrates: velocity is
/// (positions - previous) / h), x y z per vertex in the creation order; either
/// pointer may be NULL. `capacity` is the number of floats each array holds.
RBC_API rbc_result RBC_CALL rbc_cloth_get_state(rbc_world_id world, rbc_cloth_id cloth,
                                                float *positions, float *previous,
                                                size_t capacity);
/// Replace positions and previous positions (NULL previous = the same as
/// positions: at rest). Pinned vertices keep their pins. All values must be finite.
RBC_API rbc_result RBC_CALL rbc_cloth_set_state(rbc_world_id world, rbc_cloth_id cloth,
                                                const float *positions,
                                                const float *previous);

/* --- 1.3: contact, interaction, tearing, wind --- */
/// Install (or with NULL remove) the host contact callback (rbc_contact_fn). Its
/// contacts join the solve with the built-in colliders'. (1.3)
RBC_API rbc_result RBC_CALL rbc_world_set_contact_callback(rbc_world_id world,
                                                           rbc_contact_fn fn, void *user);
/// The vertex nearest to a ray: over all cloths, the vertex within `radius` metres
/// of the ray origin + t dir (t in [0, max_distance], dir non-zero, need not be unit)
/// with the least t (ties: the one nearer the ray). RBC_OK with *out_cloth = 0 when
/// none is. For picking: grab it with rbc_cloth_set_pin, drag the pin's target,
/// release with a NULL target. (1.3)
RBC_API rbc_result RBC_CALL rbc_world_pick(rbc_world_id world, const float origin[3],
                                           const float dir[3], float max_distance,
                                           float radius, rbc_cloth_id *out_cloth,
                                           uint32_t *out_vertex, float *out_t);
/// Attach a vertex to a collider: it is pinned and follows the collider's frame at
/// the point `local` (collider frame, metres; NULL = where the vertex is now). The
/// attachment ends with rbc_cloth_set_pin on that vertex, or when the collider is
/// destroyed (the vertex is then released). (1.3)
RBC_API rbc_result RBC_CALL rbc_cloth_attach(rbc_world_id world, rbc_cloth_id cloth,
                                             uint32_t vertex, rbc_collider_id collider,
                                             const float local[3]);
/// Cut springs: for each of `pair_count` vertex pairs (2 indices each) the spring
/// joining them breaks, with the quads that have both as corners. A pair with no
/// spring between them (or one already torn) is skipped; an index out of range is
/// RBC_ERR_INVALID_ARGUMENT and nothing is cut. *out_cut (may be NULL) = springs
/// cut. The coloring stays valid (removing springs never needs recoloring). (1.3)
RBC_API rbc_result RBC_CALL rbc_cloth_cut(rbc_world_id world, rbc_cloth_id cloth,
                                          const uint32_t *pairs, uint32_t pair_count,
                                          uint32_t *out_cut);
/// The quads that remain (all of them until something tears), 4 vertex indices
/// each in the creation order. Pass NULL to learn the count (*out_count, in
/// uint32_t values); `capacity` counts uint32_t values. (1.3)
RBC_API rbc_result RBC_CALL rbc_cloth_get_quads(rbc_world_id world, rbc_cloth_id cloth,
                                                uint32_t *quads, size_t capacity,
                                                size_t *out_count);
/// The springs that remain, 2 vertex indices each (creation order); as
/// rbc_cloth_get_quads. (1.3)
RBC_API rbc_result RBC_CALL rbc_cloth_get_springs(rbc_world_id world, rbc_cloth_id cloth,
                                                  uint32_t *pairs, size_t capacity,
                                                  size_t *out_count);
/// Wind and aerodynamic drag for every cloth of the world: each quad feels
/// drag * area * ((w - v) . n) n (n its unit normal, v its mean velocity, w the wind
/// velocity, m/s) plus lift * area * |(w - v) . n| times the part of w - v along the
/// quad, in newtons, spread over its corners. drag and lift in kg/m^3 (air: about
/// 0.6 = 0.5 * 1.2 kg/m^3 for a drag coefficient of 1), finite and >= 0; all zero
/// (the default) costs nothing. (1.3)
RBC_API rbc_result RBC_CALL rbc_world_set_wind(rbc_world_id world, const float velocity[3],
                                               float drag, float lift);

/* --- 1.2: mesh import --- */

/// A mesh read from a file by rbc_mesh_import (assimp). It belongs to the library,
/// not to a world: one mesh can make cloths in several worlds. Immutable once made:
/// its getters may run on any thread at once; destroy it when no call uses it.
/// 0 is null. (1.2)
typedef uint32_t rbc_mesh_id;

/// What rbc_mesh_import does with a face of more than 4 corners. (1.2)
typedef int32_t rbc_ngon_mode;
enum {
    /// Split it into a fan of quads from its first corner, (0, i, i+1, i+2) for
    /// i = 1, 3, 5, ..., and one triangle (0, n-2, n-1) when n is odd (which may
    /// then pair with a neighbour). Convex n-gons give convex pieces. The default.
    RBC_NGON_SPLIT = 0,
    /// Refuse the file with RBC_ERR_BAD_MESH naming the mesh and the face.
    RBC_NGON_REFUSE = 1,
    RBC_NGON_FORCE32 = 0x7FFFFFFF
};

/// How a file is turned into a cloth mesh. Fill one with rbc_mesh_import_def_init
/// (or rbc_mesh_import_def_default). Lengths are metres after `scale`. (1.2)
typedef struct rbc_mesh_import_def {
    /// sizeof(rbc_mesh_import_def) as compiled by the host.
    uint32_t struct_size;
    /// Which meshes of the file's scene to take, merged into one: index -1 = all of
    /// them; otherwise only aiScene::mMeshes[mesh_index] (0-based, file order).
    /// Default -1.
    int32_t mesh_index;
    /// With mesh_index -1, take only the meshes whose name, or the name of a node
    /// that places them, equals this (UTF-8, exact); NULL = no name filter. A name
    /// that matches nothing is RBC_ERR_INVALID_ARGUMENT (the message lists the
    /// names there are). Default NULL.
    const char *mesh_name;
    /// Factor applied to every position after the node hierarchy's transforms
    /// (0.01 for a file in centimetres); finite and > 0. Default 1.
    float scale;
    /// 1: merge vertices at one position (assimp keeps the copies that differ in
    /// normal or UV, at seams and hard edges) so the cloth is connected there; 0:
    /// keep them. Default 1.
    uint32_t weld;
    /// With weld 1: vertices closer than this, metres, merge into the first of them;
    /// 0 = only bit-identical positions. Finite and >= 0. Default 0.
    float weld_distance;
    /// 1: pair triangles across shared edges into quads, best pairs first (greedy
    /// on the score below), where the quad is convex and within both bounds; 0:
    /// leave every triangle as springs. Default 1.
    uint32_t pair_triangles;
    /// Largest |corner angle - 90| of a paired quad, degrees, in [0, 90]. The
    /// pair's score is its largest deviation (best first). Default 45 (a square
    /// scores 0, the rhombus of two equilateral triangles 30).
    float pair_max_angle_deviation_deg;
    /// Largest angle between the normals of the two triangles of a pair, degrees
    /// (near-planar), in [0, 180]. Default 30.
    float pair_max_fold_deg;
    /// An rbc_ngon_mode. Default RBC_NGON_SPLIT.
    rbc_ngon_mode ngons;
    /// Pins from the file's vertex colors (its first color set): a vertex is pinned
    /// when red >= pin_color_threshold and green and blue are < it (a red vertex;
    /// white is not). Colors are in [0, 1] (8-bit colors are divided by 255). 0 =
    /// off, else in (0, 1]. Default 0.5.
    float pin_color_threshold;
    /// Pin the vertices within pin_plane_distance of the plane n . x = d with
    /// pin_plane = (n, d); n need not be unit but must not be zero. A negative
    /// distance turns the rule off. Default -1 (off), pin_plane (0, 1, 0, 0).
    float pin_plane[4];
    float pin_plane_distance;
    /// Pin the vertices within pin_point_distance of pin_point; negative = off.
    /// Default -1 (off), pin_point (0, 0, 0).
    float pin_point[3];
    float pin_point_distance;
    /// Pin the top row: the vertices whose coordinate along axis pin_top_axis (0 x,
    /// 1 y, 2 z) is within pin_top_tolerance of the largest; -1 = off. Default -1,
    /// tolerance 1e-4.
    int32_t pin_top_axis;
    float pin_top_tolerance;
    /// Pin every vertex of the meshes whose name, or the name of a node that places
    /// them, equals this (UTF-8, exact): a named group or selection of the file (an
    /// OBJ `g`/`o` group, a Collada/FBX/glTF node or mesh name). The group need not
    /// be among the meshes taken by mesh_name; only vertices of meshes taken are
    /// pinned, and a name that matches no placement taken is
    /// RBC_ERR_INVALID_ARGUMENT (listing the names). NULL = off. Default NULL.
    const char *pin_group;
    /* --- 1.8 --- */
    /// Wall-clock limit of the import, milliseconds: past it the import helper is
    /// stopped and the import fails with RBC_ERR_IO ("did not finish within").
    /// 0 = no limit. Default 60000.
    uint32_t timeout_ms;
    /// Address-space limit of the import helper, MiB: an import that needs more
    /// fails with RBC_ERR_OUT_OF_MEMORY. 0 = half of the machine's physical memory.
    /// Default 0. (Not applied in sanitizer builds of the helper.)
    uint32_t memory_limit_mb;
    /* --- 1.9 --- */
    /// 0: convert the file's declared unit to metres (an FBX's UnitScaleFactor, a
    /// Collada <unit meter>; glTF is metres; OBJ, PLY, STL declare none and are
    /// taken as metres), then apply `scale`. 1: keep the file's units (only `scale`
    /// is applied). rbc_mesh_info.file_unit_metres and applied_scale say what was
    /// found and done. Default 0.
    uint32_t keep_file_units;
} rbc_mesh_import_def;

/// sizeof(rbc_mesh_import_def) in ABI 1.2 to 1.7 (before timeout_ms).
#define RBC_MESH_IMPORT_DEF_SIZE_V1_2 ((uint32_t)offsetof(rbc_mesh_import_def, timeout_ms))
/// sizeof(rbc_mesh_import_def) in ABI 1.8 (before keep_file_units).
#define RBC_MESH_IMPORT_DEF_SIZE_V1_8 ((uint32_t)offsetof(rbc_mesh_import_def, keep_file_units))

/// Where rbc_mesh_info.file_vertex_count's vertices come from. (1.9)
typedef int32_t rbc_file_order;
enum {
    /// The file's own position lists, as Blender, Maya and the other DCCs create a
    /// mesh's vertices from them: OBJ "v" lines, FBX Geometry Vertices (control
    /// points), Collada <vertices> POSITION sources; several lists in file order.
    RBC_FILE_ORDER_FILE = 1,
    /// The vertex arrays as assimp reads them, mesh after mesh: the file's order for
    /// formats whose vertices assimp keeps as they are (glTF accessors, one list per
    /// primitive; PLY's vertex element, ...).
    RBC_FILE_ORDER_ASSIMP = 2,
    RBC_FILE_ORDER_FORCE32 = 0x7FFFFFFF
};

/// What rbc_mesh_import made of a file, read with rbc_mesh_get_info (set
/// struct_size first). Counts of faces are of the meshes taken. (1.2)
typedef struct rbc_mesh_info {
    /// sizeof(rbc_mesh_info) as compiled by the host.
    uint32_t struct_size;
    /// The mesh: vertices, quads (all kinds below), explicit springs (edges of
    /// leftover triangles that are no quad's edge) and pinned vertices.
    uint32_t vertex_count;
    uint32_t quad_count;
    uint32_t spring_count;
    uint32_t pin_count;
    /// Mesh placements taken (a mesh placed by two nodes counts twice), and their
    /// vertices and faces as assimp gave them.
    uint32_t source_mesh_count;
    uint32_t source_vertex_count;
    uint32_t source_face_count;
    /// Faces of the file kept as quads and as triangles, by their corners after
    /// welding (a quad with two corners welded into one is a triangle).
    uint32_t file_quads;
    uint32_t file_triangles;
    /// Triangles merged into quads (2 per quad made), and triangles left as springs.
    uint32_t paired_triangles;
    uint32_t leftover_triangles;
    /// Faces of more than 4 corners split, and the quads and triangles they gave.
    /// Always quad_count = file_quads + quads_from_ngons + paired_triangles / 2 and
    /// file_triangles + triangles_from_ngons = paired_triangles + leftover_triangles.
    uint32_t ngons_split;
    uint32_t quads_from_ngons;
    uint32_t triangles_from_ngons;
    /// Points and lines left out (faces of 1 or 2 indices).
    uint32_t points_lines_skipped;
    /// Faces and n-gon pieces dropped as degenerate: fewer than 3 corners after
    /// welding, a corner repeated apart from its neighbour, or zero area (as
    /// rbc_cloth_create judges a quad: area^2 <= 1e-12 longest edge^4).
    uint32_t degenerate_faces;
    /// Vertices merged away by welding, and vertices no face uses (dropped).
    uint32_t welded_vertices;
    uint32_t unused_vertices;
    /// Colors rbc_cloth_create gives this mesh without shear or bend springs, and
    /// whether its spring graph (quad edges and springs) is bipartite: 1 = two colors
    /// do (Red-Black), 0 = an odd cycle exists (triangles, odd loops).
    uint32_t color_count;
    uint32_t bipartite;
    /// Pins by vertex color and by the def's rules (a vertex found by both counts
    /// in both; pin_count counts it once).
    uint32_t pins_from_colors;
    uint32_t pins_from_rules;
    /// Pinned vertices that belong to the pin_group (counted here too when also
    /// pinned by a color or rule).
    uint32_t pins_from_group;
    /// Axis-aligned bounds of the positions, metres.
    float bounds_min[3];
    float bounds_max[3];
    /* --- 1.9 --- */
    /// The file's own vertices (rbc_mesh_get_file_map): how many, where the list
    /// comes from (an rbc_file_order), and how many of them no mesh vertex follows
    /// (in no face taken: another mesh's, a loose vertex).
    uint32_t file_vertex_count;
    rbc_file_order file_order;
    uint32_t unmapped_file_vertices;
    /// Metres per unit as the file declares it (FBX UnitScaleFactor / 100, Collada
    /// <unit meter>, glTF 1); 0 = the file declares none.
    float file_unit_metres;
    /// The factor between the file's coordinates (after its node transforms) and
    /// the mesh's: the unit conversion (unless keep_file_units) times `scale`.
    float applied_scale;
    /// 1 when keep_file_units kept a declared unit that is not metres.
    uint32_t file_units_kept;
} rbc_mesh_info;

/// sizeof(rbc_mesh_info) in ABI 1.2 to 1.8 (before file_vertex_count).
#define RBC_MESH_INFO_SIZE_V1_2 ((uint32_t)offsetof(rbc_mesh_info, file_vertex_count))

/// Fill an import def with its defaults (see rbc_world_def_init for struct_size).
RBC_API rbc_result RBC_CALL rbc_mesh_import_def_init(rbc_mesh_import_def *def,
                                                     uint32_t struct_size);
/// Read `path` (UTF-8; any format assimp reads: OBJ, PLY, FBX, glTF, Collada, STL,
/// ...) into a cloth mesh, as `def` says (NULL = the defaults). Polygons are kept
/// (assimp runs with JoinIdenticalVertices | ValidateDataStructure only, no
/// triangulation); the node hierarchy's transforms are applied, then `scale`; then
/// welding, n-gon splitting, triangle pairing, leftover triangles as springs,
/// unused vertices dropped, pins. *out_mesh receives its id.
/// Errors (nothing is created): RBC_ERR_IO the file cannot be opened or assimp
/// cannot parse it (assimp's message is quoted); RBC_ERR_UNSUPPORTED no assimp
/// reader for the format, or no import in this install (the helper is not found,
/// and the message lists where it looked; Windows builds have none);
/// RBC_ERR_BAD_MESH no face to simulate, a non-finite
/// position, an n-gon with RBC_NGON_REFUSE (the message names the file, mesh and
/// face or vertex); RBC_ERR_INVALID_ARGUMENT a bad def or a mesh_index/mesh_name
/// that selects nothing; RBC_ERR_CAPACITY 4096 meshes exist. Nothing is printed
/// (assimp's logging stays off).
/// Isolation (1.8): assimp runs in a helper process, rbcloth-import, that the
/// library spawns for each import and that sends the mesh back over a socket.
/// Whatever a file does to assimp ends the helper, never the host: a crash or
/// abort is RBC_ERR_IO naming the signal, an import past def->timeout_ms is
/// RBC_ERR_IO ("did not finish within"), one past def->memory_limit_mb is
/// RBC_ERR_OUT_OF_MEMORY. The helper is $RBC_IMPORT_HELPER if set, else
/// rbcloth-import in the folder of this library, else
/// ../libexec/rbcloth/rbcloth-import from it; missing, imports fail with RBC_ERR_IO
/// naming where it was looked for. Imports on several threads run in parallel,
/// each in its own helper. The host's SIGCHLD handling is left alone (the helper
/// is waited for by its pid, or through a pidfd where the kernel has them).
RBC_API rbc_result RBC_CALL rbc_mesh_import(const char *path, const rbc_mesh_import_def *def,
                                            rbc_mesh_id *out_mesh);
/// Destroy a mesh (cloths made from it are not affected).
RBC_API rbc_result RBC_CALL rbc_mesh_destroy(rbc_mesh_id mesh);
/// Fill *info (set info->struct_size first).
RBC_API rbc_result RBC_CALL rbc_mesh_get_info(rbc_mesh_id mesh, rbc_mesh_info *info);
/// Copy the mesh's arrays into caller buffers: positions (3 floats per vertex,
/// metres), quads (4 vertex indices each, in order around the face), springs (2
/// indices each) and pins (vertex indices, ascending). `capacity` is the number of
/// elements (floats or uint32_t) the buffer holds; with the buffer NULL only
/// *out_count (if not NULL) receives the number of elements needed.
RBC_API rbc_result RBC_CALL rbc_mesh_get_positions(rbc_mesh_id mesh, float *xyz,
                                                   size_t capacity, size_t *out_count);
RBC_API rbc_result RBC_CALL rbc_mesh_get_quads(rbc_mesh_id mesh, uint32_t *quads,
                                               size_t capacity, size_t *out_count);
RBC_API rbc_result RBC_CALL rbc_mesh_get_springs(rbc_mesh_id mesh, uint32_t *springs,
                                                 size_t capacity, size_t *out_count);
RBC_API rbc_result RBC_CALL rbc_mesh_get_pins(rbc_mesh_id mesh, uint32_t *pins,
                                              size_t capacity, size_t *out_count);
/// Create a cloth in `world` from a mesh: its positions, quads, springs and pins
/// (rbc_mesh_get_pins: the import's vertex colors, rules and pin group);
/// everything else (masses or density or vertex_mass, stiffness, shear and bend
/// stiffness, damping) from `settings` (NULL = the defaults). The geometry fields of
/// settings (vertex_count, positions, quad_count, quads, spring_count, springs) are
/// ignored; settings->pins (pin_count of them), if given, pin more vertices besides
/// the import's (from 1.9; before, they were ignored), each an index below the
/// mesh's vertex_count (else RBC_ERR_INVALID_ARGUMENT naming it); `masses`, if
/// given, must hold the mesh's vertex_count values. Errors as rbc_cloth_create.
RBC_API rbc_result RBC_CALL rbc_cloth_create_from_mesh(rbc_world_id world, rbc_mesh_id mesh,
                                                       const rbc_cloth_def *settings,
                                                       rbc_cloth_id *out_cloth);
/// The faces of an imported mesh as triangles (quads split along the diagonal 0-2,
/// triangles as they were), 3 vertex indices each: for triangle mesh colliders
/// (rbc_collider_def.mesh_triangles). As rbc_mesh_get_quads. (1.3)
RBC_API rbc_result RBC_CALL rbc_mesh_get_triangles(rbc_mesh_id mesh, uint32_t *triangles,
                                                   size_t capacity, size_t *out_count);

/* --- 1.9: the file's own mesh --- */

/// Vertex orders of rbc_mesh_write_file_obj. (1.9)
typedef int32_t rbc_vertex_order;
enum {
    /// The file's vertices in the file's order and coordinates (what a DCC that
    /// imported the file has as the mesh's own, local, coordinates).
    RBC_ORDER_FILE = 1,
    /// The mesh's vertices (the simulation's order), in its coordinates.
    RBC_ORDER_MESH = 2,
    RBC_ORDER_FORCE32 = 0x7FFFFFFF
};
/// For every vertex of the file, in the file's own order (rbc_mesh_info.file_order:
/// OBJ "v" lines, FBX control points, Collada position lists, glTF accessors), the
/// mesh vertex it follows: an index into the mesh's positions, or UINT32_MAX for a
/// file vertex in no face taken. Copies the file splits only for UVs or normals
/// follow one mesh vertex (they are welded for the simulation). An engine drives
/// its own render mesh with it: render[k] = positions[map[k]] (mesh coordinates)
/// or, in the file's coordinates, rbc_mesh_to_file_positions. As
/// rbc_mesh_get_quads; file_vertex_count values. (1.9)
RBC_API rbc_result RBC_CALL rbc_mesh_get_file_map(rbc_mesh_id mesh, uint32_t *map,
                                                  size_t capacity, size_t *out_count);
/// A state of a cloth made from this mesh, `xyz` (3 * vertex_count floats, as
/// rbc_cloth_read_positions gives them; NULL = the mesh's rest positions;
/// xyz_count counts its floats), in the file's vertex order and coordinates:
/// out[k] is file vertex k with the scale, the unit conversion and its node
/// transforms undone, which is what a DCC that imported the file holds as the
/// mesh's local coordinates; a file vertex no mesh vertex follows stays where the
/// file has it. `capacity` and *out_count count floats (3 * file_vertex_count);
/// with `out` NULL only *out_count is set. Values of xyz must be finite. (1.9)
RBC_API rbc_result RBC_CALL rbc_mesh_to_file_positions(rbc_mesh_id mesh, const float *xyz,
                                                       size_t xyz_count, float *out,
                                                       size_t capacity, size_t *out_count);
/// Write a state (`xyz` as for rbc_mesh_to_file_positions, NULL = rest) as a
/// Wavefront OBJ with the file's own faces (n-gons and triangles as the file has
/// them, not the quads made for the simulation), its texture coordinates, its
/// normals (at rest) and a "g" group per placement of a mesh taken, named after
/// its node (or mesh). RBC_ORDER_FILE: "v" lines in the file's order and
/// coordinates, one per file vertex (the file's vertex count, so a cache in that
/// order plays on it); RBC_ORDER_MESH: "v" lines are the mesh's vertices and the
/// faces use them. Floats are written with %.9g (they read back exactly). The file
/// is written to "<path>.tmp" and renamed; on error nothing appears. (1.9)
RBC_API rbc_result RBC_CALL rbc_mesh_write_file_obj(rbc_mesh_id mesh, const float *xyz,
                                                    size_t xyz_count, rbc_vertex_order order,
                                                    const char *path);

/* --- 1.10: a game loop --- */

/// An offset of rbc_vertex_output that writes nothing. (1.10)
#define RBC_NO_ATTRIBUTE 0xFFFFFFFFu

/// Where rbc_world_read_vertices writes one cloth's vertices: vertex i (creation
/// order) at buffer + i * stride; its position (3 floats) at position_offset and
/// its normal (3 floats) at normal_offset bytes into it. Floats are copied byte by
/// byte, so the buffer needs no alignment. Fill with rbc_vertex_output_init. (1.10)
typedef struct rbc_vertex_output {
    /// sizeof(rbc_vertex_output) as compiled by the host.
    uint32_t struct_size;
    /// The cloth to read.
    rbc_cloth_id cloth;
    /// The host's buffer, at least (vertex_count - 1) * stride + the end of the
    /// last attribute bytes.
    void *buffer;
    /// Bytes the buffer holds.
    size_t buffer_size;
    /// Bytes from one vertex to the next, >= the end of every attribute written
    /// and at most 65536. Default 12 (packed positions).
    uint32_t stride;
    /// Byte offset of the position in a vertex, or RBC_NO_ATTRIBUTE. Default 0.
    uint32_t position_offset;
    /// Byte offset of the unit normal, or RBC_NO_ATTRIBUTE. Normals are
    /// area-weighted: each vertex sums the vector areas of its quads (and leftover
    /// triangles), (c - a) x (d - b) / 2 for a quad a b c d, so they point to the
    /// side from which the quads' corners run counter-clockwise, and normalises
    /// the sum; a vertex with no face (or faces of zero area) gets (0, 0, 0). They
    /// are computed only when asked for. Default RBC_NO_ATTRIBUTE.
    uint32_t normal_offset;
    /// Out: the cloth's triangle revision (rbc_cloth_get_triangles) at this read.
    uint32_t triangle_revision;
} rbc_vertex_output;

/// Fill an rbc_vertex_output with its defaults (cloth 0, buffer NULL). (1.10)
RBC_API rbc_result RBC_CALL rbc_vertex_output_init(rbc_vertex_output *output,
                                                   uint32_t struct_size);
/// Write the vertices of several cloths of one world, one rbc_vertex_output each.
/// Every entry is checked first (cloth of this world, buffer, stride, offsets, that
/// position and normal do not overlap, size): a bad one fails the call with a
/// message naming its index, and no buffer is written. (1.10)
RBC_API rbc_result RBC_CALL rbc_world_read_vertices(rbc_world_id world,
                                                    rbc_vertex_output *outputs,
                                                    uint32_t count);
/// The cloth's triangles, 3 vertex indices each (creation order) into triangles:
/// two per remaining quad a b c d, (a b c) and (a c d), in the order of
/// rbc_cloth_get_quads, then the triangles an imported mesh kept as they were
/// (rbc_mesh_get_triangles) that have not torn. Pass NULL to learn the count
/// (*out_count, in uint32_t values); `capacity` counts uint32_t values.
/// *out_revision (may be NULL) is the triangle revision: 1 when the cloth is made,
/// +1 each time a tear or a cut removes a face, so a host re-uploads its index
/// buffer when it changes. (1.10)
RBC_API rbc_result RBC_CALL rbc_cloth_get_triangles(rbc_world_id world, rbc_cloth_id cloth,
                                                    uint32_t *triangles, size_t capacity,
                                                    size_t *out_count, uint32_t *out_revision);

/// rbc_cloth_transform flags. (1.10)
enum {
    /// Rotate the velocity with the cloth (a character turning carries its cape).
    RBC_TRANSFORM_KEEP_VELOCITY = 0,
    /// The cloth is at rest after the move (a teleport).
    RBC_TRANSFORM_RESET_VELOCITY = 1
};
/// Move a whole cloth rigidly: every position p becomes R p + t (R the unit
/// quaternion rotation x y z w, t the translation in metres), and so do its
/// previous positions and pin targets, so the move adds no velocity and no strain.
/// Apply the change of the carrying transform: new * inverse(old). (1.10)
RBC_API rbc_result RBC_CALL rbc_cloth_transform(rbc_world_id world, rbc_cloth_id cloth,
                                                const float translation[3],
                                                const float rotation[4], uint32_t flags);
/// Start a step of the world (as rbc_world_step) on the world's step thread and
/// return at once; dt is checked here. Until rbc_world_step_wait the world is
/// stepping (the thread contract). (1.10)
RBC_API rbc_result RBC_CALL rbc_world_step_begin(rbc_world_id world, float dt);
/// Wait for the step rbc_world_step_begin started and return its result, with its
/// message in this thread's rbc_last_error; RBC_OK at once when none is running.
/// (1.10)
RBC_API rbc_result RBC_CALL rbc_world_step_wait(rbc_world_id world);

/* ------------------------------------------------------------------------- */
/* Function table                                                            */
/* ------------------------------------------------------------------------- */

/// Every function of ABI major 1, for hosts that load the library with dlopen /
/// LoadLibrary and resolve one symbol. Entries are only appended.
typedef struct rbc_api_v1 {
    uint32_t struct_size;
    uint32_t abi_version;
    uint32_t (RBC_CALL *abi_version_fn)(void);
    const char *(RBC_CALL *version_string)(void);
    const char *(RBC_CALL *result_string)(rbc_result result);
    const char *(RBC_CALL *last_error)(void);
    rbc_result (RBC_CALL *world_def_init)(rbc_world_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *cloth_def_init)(rbc_cloth_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *collider_def_init)(rbc_collider_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *cache_def_init)(rbc_cache_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *world_create)(const rbc_world_def *def, rbc_world_id *out_world);
    rbc_result (RBC_CALL *world_destroy)(rbc_world_id world);
    rbc_result (RBC_CALL *world_step)(rbc_world_id world, float dt);
    rbc_result (RBC_CALL *world_set_iterations)(rbc_world_id world, uint32_t substeps,
                                                uint32_t nonlinear_iterations,
                                                uint32_t linear_iterations);
    rbc_result (RBC_CALL *world_set_gravity)(rbc_world_id world, const float gravity[3]);
    rbc_result (RBC_CALL *world_get_stats)(rbc_world_id world, rbc_world_stats *stats);
    rbc_result (RBC_CALL *world_set_collision_callback)(rbc_world_id world, rbc_collision_fn fn,
                                                        void *user);
    rbc_result (RBC_CALL *cloth_create)(rbc_world_id world, const rbc_cloth_def *def,
                                        rbc_cloth_id *out_cloth);
    rbc_result (RBC_CALL *cloth_destroy)(rbc_world_id world, rbc_cloth_id cloth);
    rbc_result (RBC_CALL *cloth_get_vertex_count)(rbc_world_id world, rbc_cloth_id cloth,
                                                  uint32_t *out_count);
    rbc_result (RBC_CALL *cloth_get_topology)(rbc_world_id world, rbc_cloth_id cloth,
                                              uint32_t *out_spring_count,
                                              uint32_t *out_color_count);
    rbc_result (RBC_CALL *cloth_read_positions)(rbc_world_id world, rbc_cloth_id cloth,
                                                float *xyz, size_t capacity,
                                                size_t *out_written);
    rbc_result (RBC_CALL *cloth_set_pin)(rbc_world_id world, rbc_cloth_id cloth, uint32_t vertex,
                                         const float *target);
    rbc_result (RBC_CALL *collider_create)(rbc_world_id world, const rbc_collider_def *def,
                                           rbc_collider_id *out_collider);
    rbc_result (RBC_CALL *collider_set_transform)(rbc_world_id world, rbc_collider_id collider,
                                                  const float position[3],
                                                  const float rotation[4]);
    rbc_result (RBC_CALL *collider_destroy)(rbc_world_id world, rbc_collider_id collider);
    rbc_result (RBC_CALL *write_obj)(const char *path, const float *xyz, uint32_t vertex_count,
                                     const uint32_t *quads, uint32_t quad_count);
    rbc_result (RBC_CALL *cache_create)(const rbc_cache_def *def, rbc_cache_id *out_cache);
    rbc_result (RBC_CALL *cache_write_frame)(rbc_cache_id cache, const float *xyz);
    rbc_result (RBC_CALL *cache_finish)(rbc_cache_id cache);
    rbc_result (RBC_CALL *cache_destroy)(rbc_cache_id cache);
    /* --- 1.1 --- */
    rbc_result (RBC_CALL *solver_def_init)(rbc_solver_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *world_set_solver)(rbc_world_id world, const rbc_solver_def *def);
    rbc_result (RBC_CALL *world_get_solver)(rbc_world_id world, rbc_solver_def *def);
    rbc_result (RBC_CALL *cloth_get_colors)(rbc_world_id world, rbc_cloth_id cloth,
                                            uint32_t *sizes, uint32_t capacity,
                                            uint32_t *out_color_count);
    rbc_result (RBC_CALL *cloth_get_state)(rbc_world_id world, rbc_cloth_id cloth,
                                           float *positions, float *previous, size_t capacity);
    rbc_result (RBC_CALL *cloth_set_state)(rbc_world_id world, rbc_cloth_id cloth,
                                           const float *positions, const float *previous);
    /* --- 1.2 --- */
    rbc_result (RBC_CALL *mesh_import_def_init)(rbc_mesh_import_def *def, uint32_t struct_size);
    rbc_result (RBC_CALL *mesh_import)(const char *path, const rbc_mesh_import_def *def,
                                       rbc_mesh_id *out_mesh);
    rbc_result (RBC_CALL *mesh_destroy)(rbc_mesh_id mesh);
    rbc_result (RBC_CALL *mesh_get_info)(rbc_mesh_id mesh, rbc_mesh_info *info);
    rbc_result (RBC_CALL *mesh_get_positions)(rbc_mesh_id mesh, float *xyz, size_t capacity,
                                              size_t *out_count);
    rbc_result (RBC_CALL *mesh_get_quads)(rbc_mesh_id mesh, uint32_t *quads, size_t capacity,
                                          size_t *out_count);
    rbc_result (RBC_CALL *mesh_get_springs)(rbc_mesh_id mesh, uint32_t *springs,
                                            size_t capacity, size_t *out_count);
    rbc_result (RBC_CALL *mesh_get_pins)(rbc_mesh_id mesh, uint32_t *pins, size_t capacity,
                                         size_t *out_count);
    rbc_result (RBC_CALL *cloth_create_from_mesh)(rbc_world_id world, rbc_mesh_id mesh,
                                                  const rbc_cloth_def *settings,
                                                  rbc_cloth_id *out_cloth);
    /* --- 1.3 --- */
    rbc_result (RBC_CALL *world_set_contact_callback)(rbc_world_id world, rbc_contact_fn fn,
                                                      void *user);
    rbc_result (RBC_CALL *world_pick)(rbc_world_id world, const float origin[3],
                                      const float dir[3], float max_distance, float radius,
                                      rbc_cloth_id *out_cloth, uint32_t *out_vertex,
                                      float *out_t);
    rbc_result (RBC_CALL *cloth_attach)(rbc_world_id world, rbc_cloth_id cloth, uint32_t vertex,
                                        rbc_collider_id collider, const float local[3]);
    rbc_result (RBC_CALL *cloth_cut)(rbc_world_id world, rbc_cloth_id cloth,
                                     const uint32_t *pairs, uint32_t pair_count,
                                     uint32_t *out_cut);
    rbc_result (RBC_CALL *cloth_get_quads)(rbc_world_id world, rbc_cloth_id cloth,
                                           uint32_t *quads, size_t capacity, size_t *out_count);
    rbc_result (RBC_CALL *cloth_get_springs)(rbc_world_id world, rbc_cloth_id cloth,
                                             uint32_t *pairs, size_t capacity,
                                             size_t *out_count);
    rbc_result (RBC_CALL *world_set_wind)(rbc_world_id world, const float velocity[3],
                                          float drag, float lift);
    rbc_result (RBC_CALL *mesh_get_triangles)(rbc_mesh_id mesh, uint32_t *triangles,
                                              size_t capacity, size_t *out_count);
    /* --- 1.4 --- */
    rbc_result (RBC_CALL *solver_def_preset)(rbc_solver_def *def, uint32_t struct_size,
                                             rbc_preset preset);
    /* --- 1.7 --- */
    rbc_result (RBC_CALL *world_stats_init)(rbc_world_stats *stats, uint32_t struct_size);
    /* --- 1.9 --- */
    rbc_result (RBC_CALL *mesh_get_file_map)(rbc_mesh_id mesh, uint32_t *map, size_t capacity,
                                             size_t *out_count);
    rbc_result (RBC_CALL *mesh_to_file_positions)(rbc_mesh_id mesh, const float *xyz,
                                                  size_t xyz_count, float *out, size_t capacity,
                                                  size_t *out_count);
    rbc_result (RBC_CALL *mesh_write_file_obj)(rbc_mesh_id mesh, const float *xyz,
                                               size_t xyz_count, rbc_vertex_order order,
                                               const char *path);
    /* --- 1.10 --- */
    rbc_result (RBC_CALL *vertex_output_init)(rbc_vertex_output *output, uint32_t struct_size);
    rbc_result (RBC_CALL *world_read_vertices)(rbc_world_id world, rbc_vertex_output *outputs,
                                               uint32_t count);
    rbc_result (RBC_CALL *cloth_get_triangles)(rbc_world_id world, rbc_cloth_id cloth,
                                               uint32_t *triangles, size_t capacity,
                                               size_t *out_count, uint32_t *out_revision);
    rbc_result (RBC_CALL *cloth_transform)(rbc_world_id world, rbc_cloth_id cloth,
                                           const float translation[3], const float rotation[4],
                                           uint32_t flags);
    rbc_result (RBC_CALL *world_step_begin)(rbc_world_id world, float dt);
    rbc_result (RBC_CALL *world_step_wait)(rbc_world_id world);
} rbc_api_v1;

/// sizeof(rbc_api_v1) in ABI 1.0 (a host built against 1.0 checks struct_size >= it).
#define RBC_API_V1_SIZE_V1_0 ((uint32_t)offsetof(rbc_api_v1, solver_def_init))
/// sizeof(rbc_api_v1) in ABI 1.1 (before the 1.2 mesh import entries).
#define RBC_API_V1_SIZE_V1_1 ((uint32_t)offsetof(rbc_api_v1, mesh_import_def_init))
/// sizeof(rbc_api_v1) in ABI 1.2 (before the 1.3 entries).
#define RBC_API_V1_SIZE_V1_2 ((uint32_t)offsetof(rbc_api_v1, world_set_contact_callback))
/// sizeof(rbc_api_v1) in ABI 1.3 (before the 1.4 entries).
#define RBC_API_V1_SIZE_V1_3 ((uint32_t)offsetof(rbc_api_v1, solver_def_preset))
/// sizeof(rbc_api_v1) in ABI 1.4 to 1.6 (before the 1.7 entries).
#define RBC_API_V1_SIZE_V1_6 ((uint32_t)offsetof(rbc_api_v1, world_stats_init))
/// sizeof(rbc_api_v1) in ABI 1.7 and 1.8 (before the 1.9 entries).
#define RBC_API_V1_SIZE_V1_8 ((uint32_t)offsetof(rbc_api_v1, mesh_get_file_map))
/// sizeof(rbc_api_v1) in ABI 1.9 (before the 1.10 entries).
#define RBC_API_V1_SIZE_V1_9 ((uint32_t)offsetof(rbc_api_v1, vertex_output_init))

/// The function table of ABI major `abi_major`, or NULL if this library does not
/// implement that major. The table is static: never free it.
RBC_API const void *RBC_CALL rbc_get_api(uint32_t abi_major);

/// Signature of rbc_get_api, for dlsym / GetProcAddress.
typedef const void *(RBC_CALL *rbc_get_api_fn)(uint32_t abi_major);

/// C and C++ convenience, as the others: a solver def with defaults. (1.1)
static inline rbc_solver_def rbc_solver_def_default(void) {
    rbc_solver_def d;
    rbc_solver_def_init(&d, (uint32_t)sizeof d);
    return d;
}
/// C and C++ convenience: an import def with defaults. (1.2)
static inline rbc_mesh_import_def rbc_mesh_import_def_default(void) {
    rbc_mesh_import_def d;
    rbc_mesh_import_def_init(&d, (uint32_t)sizeof d);
    return d;
}

/// The structs that carry a struct_size, for rbc_struct_size_for. (1.9)
typedef int32_t rbc_struct_kind;
enum {
    RBC_STRUCT_WORLD_DEF = 1,
    RBC_STRUCT_CLOTH_DEF = 2,
    RBC_STRUCT_COLLIDER_DEF = 3,
    RBC_STRUCT_SOLVER_DEF = 4,
    RBC_STRUCT_CACHE_DEF = 5,
    RBC_STRUCT_MESH_IMPORT_DEF = 6,
    RBC_STRUCT_MESH_INFO = 7,
    RBC_STRUCT_WORLD_STATS = 8,
    RBC_STRUCT_VERTEX_OUTPUT = 9, /* 1.10 */
    RBC_STRUCT_KIND_FORCE32 = 0x7FFFFFFF
};

/// A host built against this header that loaded an older library: the struct_size
/// to give a `kind` struct for the library whose rbc_abi_version() is
/// `library_version`, the largest size that minor accepts (this header's sizeof for
/// a library as new as the header or newer); 0 for another major, or a minor
/// before the struct existed. Fields past that size must stay at their defaults:
/// the library never reads or writes them. (Header-only; 1.9.)
///     rbc_world_stats st;
///     rbc_world_stats_init(&st, rbc_struct_size_for(RBC_STRUCT_WORLD_STATS,
///                                                   rbc_abi_version()));
static inline uint32_t rbc_struct_size_for(rbc_struct_kind kind, uint32_t library_version) {
    const uint32_t minor = library_version & 0xFFFFu;
    if ((library_version >> 16) != RBC_ABI_VERSION_MAJOR) return 0;
    switch (kind) {
    case RBC_STRUCT_WORLD_DEF:
        return minor >= 10 ? (uint32_t)sizeof(rbc_world_def)
               : minor >= 6 ? RBC_WORLD_DEF_SIZE_V1_6
               : minor >= 1 ? RBC_WORLD_DEF_SIZE_V1_1 : RBC_WORLD_DEF_SIZE_V1_0;
    case RBC_STRUCT_CLOTH_DEF:
        return minor >= 3 ? (uint32_t)sizeof(rbc_cloth_def)
               : minor >= 1 ? RBC_CLOTH_DEF_SIZE_V1_1 : RBC_CLOTH_DEF_SIZE_V1_0;
    case RBC_STRUCT_COLLIDER_DEF:
        return minor >= 3 ? (uint32_t)sizeof(rbc_collider_def) : RBC_COLLIDER_DEF_SIZE_V1_0;
    case RBC_STRUCT_SOLVER_DEF:
        return minor >= 4 ? (uint32_t)sizeof(rbc_solver_def)
               : minor >= 2 ? RBC_SOLVER_DEF_SIZE_V1_2 : minor >= 1 ? RBC_SOLVER_DEF_SIZE_V1_1 : 0;
    case RBC_STRUCT_CACHE_DEF:
        return minor >= 9 ? (uint32_t)sizeof(rbc_cache_def)
               : minor >= 2 ? RBC_CACHE_DEF_SIZE_V1_2 : RBC_CACHE_DEF_SIZE_V1_0;
    case RBC_STRUCT_MESH_IMPORT_DEF:
        return minor >= 9 ? (uint32_t)sizeof(rbc_mesh_import_def)
               : minor >= 8 ? RBC_MESH_IMPORT_DEF_SIZE_V1_8
               : minor >= 2 ? RBC_MESH_IMPORT_DEF_SIZE_V1_2 : 0;
    case RBC_STRUCT_MESH_INFO:
        return minor >= 9 ? (uint32_t)sizeof(rbc_mesh_info) : minor >= 2 ? RBC_MESH_INFO_SIZE_V1_2 : 0;
    case RBC_STRUCT_WORLD_STATS:
        return minor >= 6 ? (uint32_t)sizeof(rbc_world_stats)
               : minor == 5 ? RBC_WORLD_STATS_SIZE_V1_5 : minor == 4 ? RBC_WORLD_STATS_SIZE_V1_4
               : minor == 3 ? RBC_WORLD_STATS_SIZE_V1_3 : minor == 2 ? RBC_WORLD_STATS_SIZE_V1_2
               : minor == 1 ? RBC_WORLD_STATS_SIZE_V1_1 : RBC_WORLD_STATS_SIZE_V1_0;
    case RBC_STRUCT_VERTEX_OUTPUT:
        return minor >= 10 ? (uint32_t)sizeof(rbc_vertex_output) : 0;
    default:
        return 0;
    }
}

#ifdef __cplusplus
}
#endif

#endif /* RBCLOTH_H */
