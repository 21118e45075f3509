/* cloth_state.h -- the data of one cloth (rbc_cloth_state), apart from its life cycle
 * (cloth.h): what the sweeps, the energy and strain sums and the step read and write.
 *
 * The split follows NvCloth's fabric / cloth: `topo` and its two sweep layouts
 * (`grid`, the lattice; `ell`, ELLPACK) are built once from the mesh and only tearing
 * changes them (tear.h, through each layout's own break function); everything else
 * is per-cloth state. The step reads the hot positions every sweep, so they come
 * first; scratch that only some solvers or features use is allocated only when they
 * are selected. */
#ifndef RBC_CORE_CLOTH_STATE_H
#define RBC_CORE_CLOTH_STATE_H
#include <stddef.h>
#include <stdint.h>

#include "topology.h"

struct rbc_direct;
struct rbc_lattice;
struct rbc_ell;

/* The energy guard's account of one cloth (energy_guard.h). Committed at the end of
 * a successful step: last, kinetic + gravitational energy then (velocities over h),
 * and budget, what the cloth was given so far. valid 0: recompute the energy at the
 * next step (new cloth, state, pins or gravity); keep_slack 1: keep budget - energy
 * across that (a pin or gravity change), 0: budget = energy (new cloth, set_state). */
typedef struct rbc_cloth_guard {
    double last, budget;
    float h;
    int valid, keep_slack;
    /* During a step: its budget, the energy at its end, and the guard's action. */
    double step_budget, end, removed, kept;
    float scale;                /* velocity scale of the clamp (1 = none) */
} rbc_cloth_guard;

/* Attachments (attach.h): host vertex, collider public id, point in the collider
 * frame. */
typedef struct rbc_cloth_attachments {
    uint32_t count, cap;
    uint32_t *vertex, *collider;
    float *local;
} rbc_cloth_attachments;

typedef struct rbc_cloth_state {
    /* The immutable part: topology and its sweep layouts. */
    rbc_topology topo;
    struct rbc_lattice *lattice;   /* the lattice fast path (lattice.h), or NULL */
    struct rbc_ell *ell;        /* the ELLPACK sweep (ell.h) when not a lattice, or NULL */
    uint32_t public_id;         /* the host's id, for messages */
    float damping;              /* 1/s */
    float mean_rest;            /* mean spring rest length, m (the blow-up guard's scale) */

    /* Hot state. Position sets, SoA, internal order. x: now (t); q: previous
     * (t - h); p: the iterate of the current substep; y: its inertial target. A
     * committed substep rotates the buffers (q <- x <- p), so the state before a
     * substep stays intact until the substep is known to be finite. */
    float *x[3], *q[3], *p[3], *y[3];
    uint8_t *pinned;            /* [n] */
    /* Pins: internal index, target, and position at the start of the step (pins move
     * linearly from start to target over the substeps). */
    uint32_t pin_count, pin_cap;
    uint32_t *pin_idx;
    float *pin_target, *pin_start; /* 3 per pin */

    /* Solver scratch: rewritten by every substep (or cached per substep length). */
    struct {
        float *snap_x[3], *snap_q[3]; /* start of a multi-substep step, for restore */
        float *dx, *dy, *dz;    /* [2 ns] local-step targets d_ij per half-edge */
        float *bx, *by, *bz;    /* [n] m_i/h^2 y_i + sum_j s_ij d_ij (rbc_global_rhs) */
        float *w, *inv_denom;   /* [n] m_i/h^2 and 1/(m_i/h^2 + sum s_ij) for h_cached */
        float h_cached;
        /* Buffers only some solvers need, allocated when such a solver is selected:
         * alt: the Jacobi destination iterate; prev: p^(k-1) for Chebyshev. */
        float *alt[3], *prev[3];
        /* The exact solver's factorisation (RBC_SOLVER_DIRECT), for h_direct; rebuilt
         * when h or the pins change (direct_dirty). */
        struct rbc_direct *direct;
        float h_direct;
        int direct_dirty;
        /* Jacobi spectral radius of the global system for h_rho (0 = not estimated),
         * and the last RBC_RHO_CACHE estimates by substep length: the target mode
         * moves between a few substep counts, and each estimate is 150 sweeps of the
         * matrix (the same value again: the estimate depends on h, topology and pins
         * only). rbc_cloth_state_rho_invalidate empties both. */
        float rho_est, h_rho;
#define RBC_RHO_CACHE 8
        float rho_cache_h[RBC_RHO_CACHE], rho_cache_v[RBC_RHO_CACHE];
        uint32_t rho_cache_next;
        /* 1 when y, d and w describe the global system of the last substep (false
         * before the first step and after set_state). */
        int system_valid;
        /* Substep length of the last committed substep (0: none since creation or
         * set_state). The target mode keeps velocities when it changes the substeps:
         * q is rescaled so (x - q) / h stays the same. */
        float h_last;
        double *e_blk;          /* [rbc_energy_block_doubles] per-block partial sums */
        double *strain_blk;     /* [rbc_strain_block_doubles] (strain.h) */
        float *strain_max_blk;  /* [rbc_strain_block_doubles / 2]: largest per block */
        /* Host-order buffers for the host callbacks (allocated while one is set). */
        float *cb_pos, *cb_prev;
    };

    /* Optional features. */
    rbc_cloth_guard guard;
    uint32_t *pin_springs;      /* springs with a pinned end (the pins' work) */
    uint32_t pin_spring_count, pin_spring_cap;
    /* Contact (1.3): distance kept from surfaces, Coulomb coefficient, and the
     * rbc_cloth_def collision flags (cloth contact). The quads (internal indices, 4
     * each) and, while the cloth takes part in cloth contact, their triangles (3
     * each, two per quad). */
    float thickness, friction;
    uint32_t collision_flags;
    uint32_t quad_count;
    uint32_t *quads;
    uint32_t tri_count, tri_cap;
    uint32_t *tris;
    /* Tearing (tear.h): strain at which springs break (0 = never), springs broken so
     * far (their stiffness is 0), and quads as created (before tears). */
    float tear_strain;
    uint32_t torn;
    uint32_t quad_count0;
    rbc_cloth_attachments att;
    /* Renderers (render.h, 1.10): an imported mesh's leftover triangles (internal
     * indices, 3 each; tearing drops those with a torn edge), the triangle revision
     * (1 at creation, +1 whenever a tear or cut removes a face), and the normals'
     * scratch (3 floats a vertex, allocated on the first read that asks). */
    uint32_t lone_count, lone_cap;
    uint32_t *lone_tris;
    uint32_t tri_revision;
    float *normal_acc;
    /* The cloth's copy on its world's backend (backend.h), made at its first step
     * there; NULL on the CPU pool. */
    struct rbc_dcloth *dev;

    size_t state_bytes;
} rbc_cloth_state;

/* The topology, pins or masses changed: every spectral radius estimate is stale. */
static inline void rbc_cloth_state_rho_invalidate(rbc_cloth_state *c) {
    c->rho_est = 0.0f;
    for (int k = 0; k < RBC_RHO_CACHE; ++k) c->rho_cache_h[k] = 0.0f;
}
#endif
