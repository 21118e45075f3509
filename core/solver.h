/* solver.h -- a world of the core: its cloths (cloth.h), colliders, settings and host
 * callbacks, and the step of Algorithm 1 that advances them (step.c: Verlet
 * integration, local step, Red-Black Gauss-Seidel global step, contact), scheduled on
 * the CPU backend's thread pool.
 *
 * The core knows nothing of handles or error strings for hosts: the plugin maps ids
 * to these objects, validates defs and turns results into messages. */
#ifndef RBC_CORE_SOLVER_H
#define RBC_CORE_SOLVER_H
#include <stddef.h>
#include <stdint.h>

#include "../abi/rbcloth.h"
#include "alloc.h"
#include "backend.h"
#include "contact_list.h"
#include "cloth.h"
#include "cpu/pool.h"
#include "shapes.h"
#include "topology.h"

struct rbc_direct;
struct rbc_lattice;
struct rbc_ell;

/* The global solver settings (the ABI's rbc_solver_def, validated by the plugin). */
typedef struct rbc_solver_settings {
    rbc_solver_kind kind;
    float omega;                /* SOR factor; 0 = optimal from rho */
    float rho;                  /* Chebyshev spectral radius; 0 = estimate */
    uint32_t chebyshev_delay;
    rbc_iteration_mode mode;
    float tolerance;
    float budget_ms;
    uint32_t max_linear_iterations;
    rbc_energy_guard energy_guard;
    /* RBC_ITERATE_TARGET (1.4): the RMS relative strain to reach (strain.h) and the
     * most substeps per step; max_linear_iterations caps each global step. */
    float target_strain;
    uint32_t max_substeps;
} rbc_solver_settings;

typedef struct rbc_collider_state {
    uint32_t public_id;
    rbc_shape shape;
    float radius, thickness, friction;
    float half_extents[3];
    float position[3], rotation[4];
    float normal[3];            /* plane normal: rotation applied to +y */
    /* Where it was at the end of the last step: contacts are found over the motion
     * from there to the current pose (collide.h). */
    float last_position[3], last_rotation[4];
    float velocity[3];
    rbc_shape_geom geom;        /* shapes.h; geom.mesh is `mesh` */
    struct rbc_trimesh *mesh;   /* owned, RBC_SHAPE_TRIANGLE_MESH */
    float lo[3], hi[3];         /* local bounds of the solid */
} rbc_collider_state;

typedef struct rbc_step_times {
    double step, integrate, local, global, collide, callback, other; /* ms */
} rbc_step_times;

typedef struct rbc_solver {
    rbc_allocator alloc;
    rbc_pool *pool;
    float gravity[3];
    uint32_t substeps, nonlinear_iterations, linear_iterations;

    rbc_cloth_state **cloths;   /* dense list of live cloths, in creation order */
    uint32_t cloth_count, cloth_cap;
    rbc_collider_state *colliders; /* dense */
    uint32_t collider_count, collider_cap;

    rbc_solver_settings settings;
    rbc_collision_fn callback;
    void *callback_user;
    uint32_t public_world_id;
    rbc_collision_cloth *cb_list; /* [cloth_cap] */

    /* Collider contacts of the current substep, one list per thread (collide.h). */
    rbc_contact_list contacts[64];
    /* Cloth contact (clothcontact.h), while some cloth has collision flags. */
    struct rbc_clothcontact *cc;
    struct rbc_contact_body *cc_bodies; /* [cloth_cap] */
    uint32_t cc_bodies_cap;
    uint32_t last_contacts, last_cloth_contacts; /* found in the last substep */
    uint32_t last_frozen;       /* vertices the cloth contact fail-safe froze in the last
                                   step (over its substeps) */
    uint32_t last_cloth_capped; /* vertices whose cloth contacts were cut to the cap in
                                   the last substep */
    /* Host contacts (rbc_contact_fn) of the current substep, projected by thread 0. */
    rbc_contact_fn contact_fn;
    void *contact_user;
    rbc_contact_list host_contacts;
    uint32_t last_host_contacts;
    /* Wind (wind.h): velocity, drag and lift; off while both are 0. */
    float wind[3], wind_drag, wind_lift;
    uint64_t torn_springs;      /* over all cloths, ever (stats) */

    rbc_step_times last;        /* of the last successful step */
    uint32_t last_substeps, last_nonlinear, last_linear; /* done by it (totals) */
    /* Threads per step when the host left the count to the library (thread_count 0):
     * the pool's size or 1, whichever the last probes measured faster. On a machine
     * whose cores other work holds (an engine's job system), every barrier waits for
     * a descheduled thread and one thread is faster; on an idle one, the pool is. */
    uint32_t threads_auto;      /* 1: choose; 0: always the pool's size */
    uint32_t threads_now;       /* for the next step */
    uint32_t threads_last;      /* used by the last step (stats.thread_count) */
    uint32_t probe_in, probe_every; /* steps until the other count is tried once */
    double probe_recent[3];     /* ms per substep of the last steps at threads_now */
    uint32_t probe_nrecent;
    uint32_t probe_left;        /* steps of the running probe still to go */
    double probe_best;          /* its fastest step, ms per substep */
    uint64_t step_count;
    /* Energy guard: steps whose velocities it scaled, and energy it removed in the
     * last step (J). */
    uint64_t energy_clamped_steps;
    double energy_removed_last;
    int energy_clamped_last;    /* 1 if the last step was clamped */
    char energy_note[320];      /* what the guard did in the last step, for the log */

    /* The target error mode's controller (RBC_ITERATE_TARGET, 1.4). tgt_substeps: the
     * substeps of the next step (0 = start at max_substeps); tgt_iters: the linear
     * iterations its global steps run before the last (the count the last one of
     * the previous step needed; 0 = the world's count, within the cap); tgt_calm: steps in a row met with a
     * margin; tgt_hold: how many such steps lower the substeps (doubled each time a
     * lowering had to be undone); tgt_lowered_at: step_count of the last lowering. */
    uint32_t tgt_substeps, tgt_iters, tgt_calm, tgt_hold;
    uint64_t tgt_lowered_at;
    /* A lowering on probation: the substeps and cost (units above) before it; the
     * next step undoes it if it cost more. */
    uint32_t tgt_probe, tgt_prev_substeps;
    uint64_t tgt_prev_cost;
    double tgt_reached;         /* RMS relative strain at the end of the last step */
    int tgt_met, tgt_capped;    /* the last step met the target; missed it at the cap */
    uint64_t tgt_missed_steps, tgt_capped_steps;
    /* The strain warning (rbc_world_def.strain_warning, 1.6; 0 = off): the largest
     * relative strain at the end of the last step, where it was (cloth index,
     * spring, internal order), whether it was past the threshold, and how many
     * steps were. */
    float strain_warning;
    /* Substeps per second when `substeps` is 0 (rbc_world_def.substep_rate, 1.6;
     * 0 for worlds made with an older def, whose substeps are >= 1). */
    float substep_rate;
    double step_max_strain;
    uint32_t strain_warn_cloth, strain_warn_spring;
    int strain_warn_last;
    uint64_t strain_warn_steps;
    /* The backend the step's substeps run on (backend_step.h); ops NULL: the CPU
     * pool's stages (step.c). Owned: closed by rbc_solver_fini. */
    rbc_backend_handle backend;
} rbc_solver;

/* Solver life cycle. nthreads >= 1. */
int32_t rbc_solver_init(rbc_solver *s, const rbc_allocator *a, uint32_t nthreads);
void rbc_solver_fini(rbc_solver *s);

/* A cloth for this world (rbc_cloth_state_create with the world's solver and host
 * callbacks), not yet added; and its contact settings, with the world's cloth-contact
 * context when flags need it (on failure nothing changes). */
int32_t rbc_solver_create_cloth(rbc_solver *s, const rbc_mesh_input *in, float damping,
                                rbc_cloth_state **out, char *err, size_t errlen);
int32_t rbc_solver_set_cloth_contact(rbc_solver *s, rbc_cloth_state *c, float thickness,
                                     float friction, uint32_t flags);
/* Add to / remove from the dense list. Add may fail with RBC_ERR_OUT_OF_MEMORY. */
int32_t rbc_solver_add_cloth(rbc_solver *s, rbc_cloth_state *c);
void rbc_solver_remove_cloth(rbc_solver *s, rbc_cloth_state *c);

/* Colliders: a dense array; the returned index is valid until the next remove. */
int32_t rbc_solver_add_collider(rbc_solver *s, const rbc_collider_state *c);
void rbc_solver_remove_collider(rbc_solver *s, uint32_t index);
void rbc_collider_update_frame(rbc_collider_state *c);

/* Select the global solver (allocates the buffers it needs; on failure nothing
 * changes). */
int32_t rbc_solver_set_settings(rbc_solver *s, const rbc_solver_settings *st);
/* The target mode's controller starts again (from the world's substeps; target.c). */
void rbc_solver_target_reset(rbc_solver *s);
/* The omega SOR uses for this cloth (given, or optimal from its rho). */
float rbc_solver_sor_omega(const rbc_solver *s, rbc_cloth_state *c, float h);

/* Install or remove the host collision callback (allocates host-order buffers). */
int32_t rbc_solver_set_callback(rbc_solver *s, rbc_collision_fn fn, void *user);
/* The same for the host contact callback (rbc_contact_fn, 1.3). */
int32_t rbc_solver_set_contact_callback(rbc_solver *s, rbc_contact_fn fn, void *user);

/* Advance by dt (> 0, validated by the caller). On error (RBC_ERR_UNSTABLE,
 * RBC_ERR_CALLBACK) every cloth is as it was before the call and err says which
 * cloth, vertex and substep. */
int32_t rbc_solver_step(rbc_solver *s, float dt, char *err, size_t errlen);
/* Run this world's steps on bk (taken over: closed by rbc_solver_fini), or, with ops
 * NULL, on the CPU pool again. Cloths' copies on the old backend are released. */
void rbc_solver_set_backend(rbc_solver *s, const rbc_backend_handle *bk);
/* Release cloth c's copy on the world's backend (removal). Both in backend_step.c. */
void rbc_solver_release_backend_copy(rbc_solver *s, rbc_cloth_state *c);

#endif
