/* backend.h -- the seam between a step's schedule and the machine that runs it.
 *
 * A backend owns memory (device memory on a GPU, plain memory on the CPU), copies
 * into and out of it, and launches the per-element kernels of kernels/pd_kernels.h
 * over a range of elements. The schedule of a step (backend_step.c: which kernels,
 * in which order, with which arguments) is written once against these operations, so
 * the CPU backend (backend_cpu.c) runs and tests the very schedule the CUDA backend
 * (core/cuda/) runs. Launches on one backend run in order; only sync and download
 * wait for them (docs/design/backends.md). */
#ifndef RBC_CORE_BACKEND_H
#define RBC_CORE_BACKEND_H
#include <stddef.h>
#include <stdint.h>

#include "kernels/collide_kernels.h" /* rbc_dcollider, the contact slots */
#include "topology.h"                /* RBC_MAX_COLORS */

/* The version of this interface: a CUDA module built from another tree is refused
 * (2: the measurement and collider kernels, recorded steps; rbc_dcloth, rbc_kargs
 * and rbc_backend_ops grew). */
#define RBC_BACKEND_INTERFACE 2

typedef enum rbc_kernel {
    RBC_KERNEL_PREDICT,    /* rbc_k_predict over particles */
    RBC_KERNEL_PINS,       /* rbc_k_pin over pins */
    RBC_KERNEL_LOCAL,      /* rbc_k_local over springs */
    RBC_KERNEL_RHS,        /* rbc_k_rhs over particles */
    RBC_KERNEL_GS,         /* rbc_k_gs over the particles of one color */
    RBC_KERNEL_JACOBI,     /* rbc_k_jacobi over particles, src -> dst */
    RBC_KERNEL_CHEB_BLEND, /* rbc_k_cheb_blend over particles, each coordinate */
    RBC_KERNEL_COPY,       /* dst = src, each coordinate (Chebyshev's first p^(k-1)) */
    RBC_KERNEL_CHECK,      /* the lowest non-finite particle into bad[0] (index + 1) */
    RBC_KERNEL_SPRINGS,    /* the lowest spring past the blow-up bound into bad[1] */
    /* The measurements the iteration modes and the energy guard decide on; each
     * writes into the cloth's sums or blocks, which the host reads back. */
    RBC_KERNEL_RESIDUAL,   /* rbc_k_residual over particles: += sums[0], sums[1] */
    RBC_KERNEL_STRAIN,     /* per block of RBC_STRAIN_BLOCK springs of pos: strain_blk */
    RBC_KERNEL_ENERGY,     /* per block of RBC_ENERGY_BLOCK particles, pos against
                              prev: e_blk (energy.h's particle terms) */
    RBC_KERNEL_PIN_WORK,   /* the pins' work, prev (before) to pos (after): += sums[2] */
    /* Colliders (kernels/collide_kernels.h; the cloth's copy of them in cols): */
    RBC_KERNEL_COLLIDE_FRAMES,  /* rbc_kc_frames over colliders, fractions f0 and f */
    RBC_KERNEL_COLLIDE_DETECT,  /* rbc_kc_detect over particles; a particle past the
                                   slots into bad[2]; with last, the count into bad[3] */
    RBC_KERNEL_COLLIDE_PROJECT, /* rbc_kc_project_particle over particles of dst[] */
    RBC_KERNEL_COLLIDE_NORMAL,  /* rbc_kc_normal_particle over particles */
    RBC_KERNEL_COLLIDE_FINISH,  /* rbc_kc_finish_particle over particles */
    RBC_KERNEL_COLLIDE_POST,    /* rbc_kc_post_particle over particles */
    RBC_KERNEL_COUNT
} rbc_kernel;

/* One cloth as a backend holds it: every pointer is the backend's memory (device
 * pointers on CUDA), in the core's internal particle order. */
typedef struct rbc_dcloth {
    uint32_t n, ns, ncolors, pin_count, pin_cap;
    uint32_t color_start[RBC_MAX_COLORS + 1];
    /* Topology (uploaded once; tearing is not on a backend). */
    uint32_t *adj_start, *adj_nbr;
    float *adj_k;
    uint32_t *sa, *sb, *he_a, *he_b;
    float *rest, *ux, *uy, *uz;
    /* For the substep length h: m_i/h^2 and 1/(m_i/h^2 + sum_j s_ij). */
    float *w, *inv_denom;
    float h;               /* what w and inv_denom are for (0: not uploaded) */
    uint8_t *pinned;
    uint32_t *pin_idx;
    float *pin_start, *pin_target; /* 3 per pin */
    /* State and scratch: x now, q before, p the iterate, y its inertial target, d
     * the local step's targets per half-edge, b the right-hand side, alt Jacobi's
     * second iterate and Chebyshev's stash, prev Chebyshev's p^(k-1). */
    float *x[3], *q[3], *p[3], *y[3], *d[3], *b[3], *alt[3], *prev[3];
    /* The measurements (allocated with the topology): the residual's |r|^2 and
     * |b|^2 and the energy guard's budget with the pins' work added (sums[0..2], in
     * double), the strain and energy blocks (strain.h, energy.h), and what the
     * energy and pin work read (with mass, below). */
    double *sums, *strain_blk, *e_blk;
    uint32_t strain_blocks, energy_blocks;
    float *stiff;
    uint32_t *pin_springs; /* springs with a pinned end (uploaded with the pins) */
    uint32_t pin_spring_count, pin_spring_cap;
    int32_t *bad;          /* [4]: index + 1 of what the checks found (0: nothing): a
                              non-finite particle, a blown-up spring, a particle with
                              more contacts than slots; [3] the last substep's contacts */
    /* Colliders: their descriptions (uploaded every step, ncols of them), the
     * particles' masses and stiffness sums (Eq. 6's rows, for the normal forces), and
     * the contacts, `slots` per particle (collide_kernels.h's layout). */
    rbc_dcollider *cols;
    uint32_t ncols, cols_cap, slots, slots_cap;
    float *mass, *ksum;
    uint32_t *ncon;
    float *ct;
} rbc_dcloth;

/* A launch: kernel k over elements [first, first + count) of cloth c. */
typedef struct rbc_kargs {
    const rbc_dcloth *c;
    uint32_t first, count;
    float keep, g_h2[3];   /* PREDICT */
    float f;               /* PINS: the fraction of the path; last: the last substep */
    int last;
    int variant;           /* GS: RBC_K_GS_*; JACOBI: 1 for Chebyshev */
    float omega;           /* GS (SOR), JACOBI and CHEB_BLEND (Chebyshev) */
    float *src[3], *dst[3]; /* JACOBI, COPY */
    float stretch, floor_len; /* SPRINGS: the blow-up bound (step.c) */
    float *pos[3], *prev[3];  /* STRAIN (pos), ENERGY and PIN_WORK (pos against prev) */
    float g[3];               /* ENERGY: gravity, m/s^2 */
    /* Colliders: the substep's start fraction (FRAMES), its length h (DETECT, NORMAL,
     * FINISH; PROJECT: h for the pass's friction, 0 for none), the cloth's thickness,
     * friction and detection margin. PROJECT projects dst[]. */
    float f0, h, thick, mu, margin;
} rbc_kargs;

/* A launch passes both by value as kernel arguments, which CUDA limits to 4 KB. */
#ifdef __cplusplus
static_assert(sizeof(rbc_dcloth) + sizeof(rbc_kargs) + 16 <= 4096,
              "a launch's arguments must stay under CUDA's 4 KB");
#else
_Static_assert(sizeof(rbc_dcloth) + sizeof(rbc_kargs) + 16 <= 4096,
               "a launch's arguments must stay under CUDA's 4 KB");
#endif

typedef struct rbc_backend_ops {
    const char *name;
    /* Memory of the backend (NULL: out of memory; bytes > 0), and its release. */
    void *(*alloc)(void *be, size_t bytes);
    void (*release)(void *be, void *ptr);
    /* Copies between host memory and the backend's; RBC_OK or an rbc_result. */
    int32_t (*upload)(void *be, void *dst, const void *src, size_t bytes);
    int32_t (*download)(void *be, void *dst, const void *src, size_t bytes);
    /* Queue one kernel; the range may be empty. */
    int32_t (*launch)(void *be, rbc_kernel k, const rbc_kargs *a);
    /* Wait for every queued launch; RBC_OK or the first failure. */
    int32_t (*sync)(void *be);
    /* What the last failure was (never NULL). */
    const char *(*last_error)(void *be);
    /* A one-line description of the device, for stats and logs. */
    const char *(*describe)(void *be);
    void (*close)(void *be);
    /* Optional (NULL: launches run as they come). Between step_begin and step_end a
     * backend may record the launches, each with its arguments as they are at the
     * launch, and run them at step_end as one unit (the CUDA backend: a CUDA graph,
     * so a step of many small launches is not latency-bound). The schedule makes no
     * upload, download or sync in between, and calls step_end whenever step_begin
     * succeeded. */
    int32_t (*step_begin)(void *be);
    int32_t (*step_end)(void *be);
} rbc_backend_ops;

/* A backend opened for a world. */
typedef struct rbc_backend_handle {
    const rbc_backend_ops *ops;
    void *be;
} rbc_backend_handle;

/* The CPU backend: plain memory, and every kernel a loop on the calling thread over
 * the same per-element bodies (backend_cpu.c). Never fails to open. */
int32_t rbc_backend_cpu_open(rbc_backend_handle *out);

/* The entry point a backend module exports (core/cuda/), looked up by name with
 * dlsym: RBC_OK and *out filled, or RBC_ERR_BACKEND_UNAVAILABLE with why (no driver,
 * no device, a driver too old) and *out untouched. */
typedef int32_t rbc_backend_open_fn(uint32_t interface_version, rbc_backend_handle *out, char *why,
                                    size_t whylen);
#define RBC_BACKEND_OPEN_SYMBOL "rbc_cuda_backend_open"
#endif
