/* solver.h -- per-frame state of cloths and colliders and the step of Algorithm 1
 * (Verlet integration, local step, Red-Black Gauss-Seidel global step), scheduled on
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
#include "collide.h"
#include "cpu/pool.h"
#include "shapes.h"
#include "topology.h"

struct rbc_direct;
struct rbc_grid;
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

/* One cloth: immutable topology plus the state that a step changes. */
typedef struct rbc_cloth_state {
    rbc_topology topo;
    struct rbc_grid *grid;      /* the lattice fast path (grid.h), or NULL */
    struct rbc_ell *ell;        /* the ELLPACK sweep (ell.h) when not a lattice, or NULL */
    uint32_t public_id;         /* the host's id, for messages */
    float damping;              /* 1/s */
    float mean_rest;            /* mean spring rest length, m (the blow-up guard's scale) */

    /* Position sets, SoA, internal order. x: now (t); q: previous (t - h); p: the
     * iterate of the current substep; y: its inertial target. A committed substep
     * rotates the buffers (q <- x <- p), so the state before a substep stays intact
     * until the substep is known to be finite. */
    float *x[3], *q[3], *p[3], *y[3];
    float *snap_x[3], *snap_q[3]; /* start of a multi-substep step, for restore */
    float *dx, *dy, *dz;        /* [2 ns] local-step targets d_ij per half-edge */
    float *bx, *by, *bz;        /* [n] m_i/h^2 y_i + sum_j s_ij d_ij (rbc_global_rhs) */
    float *w, *inv_denom;       /* [n] m_i/h^2 and 1/(m_i/h^2 + sum s_ij) for h_cached */
    float h_cached;
    uint8_t *pinned;            /* [n] */

    /* Pins: internal index, target, and position at the start of the step (pins move
     * linearly from start to target over the substeps). */
    uint32_t pin_count, pin_cap;
    uint32_t *pin_idx;
    float *pin_target, *pin_start; /* 3 per pin */

    /* Host-order buffers for the collision callback (allocated while one is set). */
    float *cb_pos, *cb_prev;

    /* Buffers only some solvers need, allocated when such a solver is selected:
     * alt: the Jacobi destination iterate; prev: p^(k-1) for Chebyshev. */
    float *alt[3], *prev[3];
    /* The exact solver's factorisation (RBC_SOLVER_DIRECT), for h_direct; rebuilt
     * when h or the pins change (direct_dirty). */
    struct rbc_direct *direct;
    float h_direct;
    int direct_dirty;
    /* Jacobi spectral radius of the global system for h_rho (0 = not estimated), and
     * the last RBC_RHO_CACHE estimates by substep length: the target mode moves
     * between a few substep counts, and each estimate is 150 sweeps of the matrix
     * (the same value again: the estimate depends on h, topology and pins only).
     * rbc_cloth_state_rho_invalidate empties both. */
    float rho_est, h_rho;
#define RBC_RHO_CACHE 8
    float rho_cache_h[RBC_RHO_CACHE], rho_cache_v[RBC_RHO_CACHE];
    uint32_t rho_cache_next;
    /* 1 when y, d and w describe the global system of the last substep (false
     * before the first step and after set_state). */
    int system_valid;

    /* Energy guard (energy.h). Committed at the end of a successful step: e_last,
     * kinetic + gravitational energy then (velocities over e_h), and e_budget, what
     * the cloth was given so far. e_valid 0: recompute the energy at the next step (new cloth, state,
     * pins or gravity); e_keep_slack 1: keep budget - energy across that (a pin or
     * gravity change), 0: budget = energy (new cloth, set_state). */
    double e_last, e_budget;
    float e_h;
    int e_valid, e_keep_slack;
    double *e_blk;              /* [rbc_energy_block_doubles] per-block partial sums */
    double *strain_blk;         /* [rbc_strain_block_doubles] (strain.h) */
    float *strain_max_blk;      /* [rbc_strain_block_doubles / 2]: largest per block */
    /* Substep length of the last committed substep (0: none since creation or
     * set_state). The target mode keeps velocities when it changes the substeps:
     * q is rescaled so (x - q) / h stays the same. */
    float h_last;
    uint32_t *pin_springs;      /* springs with a pinned end (pin work) */
    uint32_t pin_spring_count, pin_spring_cap;
    /* During a step: its budget, the energy at its end, and the guard's action. */
    double e_step_budget, e_end, e_removed, e_kept;
    float e_scale;              /* velocity scale of the clamp (1 = none) */

    /* Contact (1.3): distance kept from surfaces, Coulomb coefficient, and the
     * rbc_cloth_def collision flags (cloth contact). */
    float thickness, friction;
    uint32_t collision_flags;
    /* The quads (internal indices, 4 each) and, while the cloth takes part in cloth
     * contact, their triangles (3 each, two per quad). */
    uint32_t quad_count;
    uint32_t *quads;
    uint32_t tri_count, tri_cap;
    uint32_t *tris;
    /* Tearing (interact.h): strain at which springs break (0 = never), springs
     * broken so far (their stiffness is 0), and quads as created (before tears). */
    float tear_strain;
    uint32_t torn;
    uint32_t quad_count0;
    /* Attachments: host vertex, collider public id, point in the collider frame. */
    uint32_t att_count, att_cap;
    uint32_t *att_vertex, *att_collider;
    float *att_local;

    size_t state_bytes;
} rbc_cloth_state;

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
    /* Wind (interact.h): velocity, drag and lift; off while both are 0. */
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
} rbc_solver;

/* Solver life cycle. nthreads >= 1. */
int32_t rbc_solver_init(rbc_solver *s, const rbc_allocator *a, uint32_t nthreads);
void rbc_solver_fini(rbc_solver *s);

/* Build a cloth (validates the mesh). The cloth is not yet in the solver. */
int32_t rbc_cloth_state_create(rbc_solver *s, const rbc_mesh_input *in, float damping,
                               rbc_cloth_state **out, char *err, size_t errlen);
void rbc_cloth_state_destroy(rbc_solver *s, rbc_cloth_state *c);
/* Contact settings of a cloth (rbc_cloth_def 1.3): builds its triangles and the
 * world's cloth-contact context when flags need them. On failure nothing changes. */
int32_t rbc_cloth_state_set_contact(rbc_solver *s, rbc_cloth_state *c, float thickness,
                                    float friction, uint32_t flags);
/* Add to / remove from the dense list. Add may fail with RBC_ERR_OUT_OF_MEMORY. */
int32_t rbc_solver_add_cloth(rbc_solver *s, rbc_cloth_state *c);
void rbc_solver_remove_cloth(rbc_solver *s, rbc_cloth_state *c);

/* Pins (host vertex index; validated by the caller). target NULL releases. */
int32_t rbc_cloth_state_set_pin(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                                const float *target);
/* The topology, pins or masses changed: every spectral radius estimate is stale. */
static inline void rbc_cloth_state_rho_invalidate(rbc_cloth_state *c) {
    c->rho_est = 0.0f;
    for (int k = 0; k < RBC_RHO_CACHE; ++k) c->rho_cache_h[k] = 0.0f;
}
/* Positions in host order, 3 floats per vertex. */
void rbc_cloth_state_read(const rbc_cloth_state *c, float *xyz);
/* Eq. 7 (sum of squared spring violations, m^2) and the largest relative
 * violation, at the current positions, in double precision. */
void rbc_cloth_state_error(const rbc_cloth_state *c, double *eq7, double *max_strain);

/* Colliders: a dense array; the returned index is valid until the next remove. */
int32_t rbc_solver_add_collider(rbc_solver *s, const rbc_collider_state *c);
void rbc_solver_remove_collider(rbc_solver *s, uint32_t index);
void rbc_collider_update_frame(rbc_collider_state *c);

/* Select the global solver (allocates the buffers it needs; on failure nothing
 * changes). */
int32_t rbc_solver_set_settings(rbc_solver *s, const rbc_solver_settings *st);
/* The target mode's controller starts again (from the world's substeps). */
#define RBC_TARGET_HOLD 8u
/* The checked global step stops at RBC_TARGET_AIM of the target; if it reaches the
 * cap above RBC_TARGET_INNER of it, the next step gets more substeps. On the paper's
 * cloth at 1/60 s (preset caps) aiming at 0.95 met 228 of 240 frames at 1.82 ms per
 * frame, at 0.8 235 at 1.88 ms; the 0.95 cap test keeps a cloth whose physical
 * stretch lies between the two from asking for substeps that cannot help. */
#define RBC_TARGET_AIM 0.8
#define RBC_TARGET_INNER 0.95
/* Cost units of a substep besides its linear iterations (integrate, local step and
 * right-hand side, a strain check), in linear iterations: the stage times of a 10K
 * RBGS frame (README) give 0.045 ms against 0.021 ms per iteration, plus a check. */
#define RBC_TARGET_SUBSTEP_COST 3u
void rbc_solver_target_reset(rbc_solver *s);
/* Positions and previous positions in host order; either may be NULL. */
void rbc_cloth_state_get(const rbc_cloth_state *c, float *pos, float *prev);
/* Replace them (prev NULL = pos); pinned particles stay on their pins. */
void rbc_cloth_state_set(rbc_cloth_state *c, const float *pos, const float *prev);
/* Relative residual of the last substep's global system at the current positions
 * and the PD objective there (both 0 when no step has been made). */
void rbc_cloth_state_system_error(const rbc_cloth_state *c, double *res_num2, double *res_den2,
                                  double *objective);
/* The Jacobi spectral radius of the cloth's global system for substep h (power
 * iteration; cached per h). */
float rbc_cloth_state_spectral_radius(rbc_cloth_state *c, float h);
/* The omega SOR uses for this cloth (given, or optimal from its rho). */
float rbc_solver_sor_omega(const rbc_solver *s, rbc_cloth_state *c, float h);

/* Bytes a cloth holds: state, topology, pins, solver and callback buffers, and the
 * direct solver's factor. */
size_t rbc_cloth_state_bytes(const rbc_cloth_state *c);
/* Kinetic energy (velocities over the last h; 0 before the first step), potential
 * energy (springs + gravity, -m g . x) of the current state (only if measure: a pass
 * over the cloth; else left alone), and the energy guard's budget for kinetic +
 * gravitational energy (0 before the first guarded step). */
void rbc_cloth_state_energy(const rbc_cloth_state *c, const float g[3], int measure,
                            double *kinetic, double *potential, double *budget);
/* The state, pins or gravity changed: recompute the energy at the next step;
 * keep_slack 0 also resets the budget to it. */
void rbc_cloth_state_energy_invalidate(rbc_cloth_state *c, int keep_slack);

/* Install or remove the host collision callback (allocates host-order buffers). */
int32_t rbc_solver_set_callback(rbc_solver *s, rbc_collision_fn fn, void *user);
/* The same for the host contact callback (rbc_contact_fn, 1.3). */
int32_t rbc_solver_set_contact_callback(rbc_solver *s, rbc_contact_fn fn, void *user);

/* Advance by dt (> 0, validated by the caller). On error (RBC_ERR_UNSTABLE,
 * RBC_ERR_CALLBACK) every cloth is as it was before the call and err says which
 * cloth, vertex and substep. */
int32_t rbc_solver_step(rbc_solver *s, float dt, char *err, size_t errlen);

#endif
