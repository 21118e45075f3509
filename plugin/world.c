/* world.c -- the ABI's worlds, cloths and colliders over core/: id tables, def
 * validation, error messages and logging. Every function validates all of its input
 * before it changes anything, so a failing call leaves the world as it was. */
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "errors.h"
#include "handles.h"
#include "interact.h"
#include "registry.h"
#include "rbcloth.h"
#include "solver.h"
#include "strain.h"

#define RBC_MAX_WORLDS 1024u
#define RBC_MAX_THREADS 64u

typedef struct rbc_world {
    rbc_solver solver;
    rbc_allocator alloc;
    rbc_world_def def;
    uint32_t id;
} rbc_world;

/* Ids of worlds, cloths and colliders (registry.h). Cloth and collider ids are
 * unique across worlds, so a foreign id is told apart from a live one. */
static rbc_reg_entry g_world_entries[RBC_MAX_WORLDS];
static rbc_reg_entry g_cloth_entries[RBC_MAX_SLOTS];
static rbc_reg_entry g_collider_entries[RBC_MAX_SLOTS];
static rbc_registry g_worlds = RBC_REGISTRY_INIT(RBC_KIND_WORLD, RBC_MAX_WORLDS, g_world_entries);
static rbc_registry g_cloths = RBC_REGISTRY_INIT(RBC_KIND_CLOTH, RBC_MAX_SLOTS, g_cloth_entries);
static rbc_registry g_colliders =
    RBC_REGISTRY_INIT(RBC_KIND_COLLIDER, RBC_MAX_SLOTS, g_collider_entries);

/* ------------------------------------------------------------------------- */
/* Helpers                                                                   */
/* ------------------------------------------------------------------------- */

static void world_log(rbc_world *w, rbc_log_level level, const char *msg) {
    if (w && w->def.log && level <= w->def.log_level) w->def.log(w->def.log_user, level, msg);
}

/* Set the error, send it to the world's log hook (if any) and return the code. */
static rbc_result world_error(rbc_world *w, rbc_result code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static rbc_result world_error(rbc_world *w, rbc_result code, const char *fmt, ...) {
    char *buf = rbc_error_buffer();
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, RBC_ERROR_CAP, fmt, ap);
    va_end(ap);
    world_log(w, RBC_LOG_ERROR, buf);
    return code;
}

static int finite3(const float *v) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

/* Copy a def of a released size into a defaults-filled struct. */
/* Copy a def of a released size into a defaults-filled struct: the current size, or
 * the ABI 1.0 size `old_size` (0 if the struct had no other release), whose missing
 * fields keep their defaults. */
static rbc_result read_def2(void *dst, size_t dst_size, size_t old_size, size_t old_size2,
                            const void *src, const char *fn, const char *what) {
    if (!src) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: %s is NULL", fn, what);
    uint32_t size;
    memcpy(&size, src, sizeof size);
    if (size != dst_size && (old_size == 0 || size != old_size) &&
        (old_size2 == 0 || size != old_size2))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: %s->struct_size is %u, which matches no released version "
                             "(this library knows %zu and the older sizes %zu, %zu); set it "
                             "to sizeof(%s)",
                             fn, what, size, dst_size, old_size, old_size2, what);
    memcpy(dst, src, size);
    return RBC_OK;
}

static rbc_result read_def(void *dst, size_t dst_size, size_t old_size, const void *src,
                           const char *fn, const char *what) {
    return read_def2(dst, dst_size, old_size, 0, src, fn, what);
}

static rbc_result lookup_world(rbc_world_id id, const char *fn, rbc_world **out) {
    *out = rbc_reg_get(&g_worlds, id, 0, fn);
    return *out ? RBC_OK : RBC_ERR_STALE_HANDLE;
}

/* ------------------------------------------------------------------------- */
/* Defaults                                                                  */
/* ------------------------------------------------------------------------- */

static rbc_world_def world_def_defaults(void) {
    rbc_world_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.gravity[1] = -9.81f;
    d.substeps = 0; /* 1.6: from substep_rate; defs of older sizes get 1 */
    d.nonlinear_iterations = 1;
    d.linear_iterations = 11;
    d.backend = RBC_BACKEND_AUTO;
    d.thread_count = 0;
    d.log_level = RBC_LOG_WARNING;
    d.substep_rate = 480.0f;
    d.strain_warning = 2.0f;
    return d;
}

static rbc_cloth_def cloth_def_defaults(void) {
    rbc_cloth_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.vertex_mass = 1e-4f;
    d.stiffness = 1000.0f;
    return d;
}

static rbc_collider_def collider_def_defaults(void) {
    rbc_collider_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.shape = RBC_SHAPE_PLANE;
    d.radius = 0.5f;
    d.rotation[3] = 1.0f;
    d.half_extents[0] = d.half_extents[1] = d.half_extents[2] = 0.5f;
    return d;
}

/* Write the first struct_size bytes of the defaults into a host's def. */
rbc_result rbc_def_init_common(void *def, uint32_t struct_size, const void *defaults,
                               size_t released_size, size_t old_size, const char *fn,
                               const char *what) {
    if (!def) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: def is NULL", fn);
    if (struct_size != released_size && (old_size == 0 || struct_size != old_size))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: struct_size is %u, which matches no released version of %s "
                             "(this library knows %zu and the older size %zu)",
                             fn, struct_size, what, released_size, old_size);
    memcpy(def, defaults, struct_size);
    memcpy(def, &struct_size, sizeof struct_size);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_def_init(rbc_world_def *def, uint32_t struct_size) {
    rbc_world_def d = world_def_defaults();
    if (struct_size != sizeof d) d.substeps = 1; /* what the 1.0-1.5 headers document */
    /* Three released sizes: 1.0, 1.1-1.5 and this one. */
    if (struct_size == RBC_WORLD_DEF_SIZE_V1_1)
        return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_WORLD_DEF_SIZE_V1_1,
                                   "rbc_world_def_init", "rbc_world_def");
    return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_WORLD_DEF_SIZE_V1_0,
                               "rbc_world_def_init",
                               "rbc_world_def");
}

RBC_API rbc_result RBC_CALL rbc_cloth_def_init(rbc_cloth_def *def, uint32_t struct_size) {
    rbc_cloth_def d = cloth_def_defaults();
    /* Three released sizes: 1.0, 1.1-1.2 and this one. */
    if (struct_size == RBC_CLOTH_DEF_SIZE_V1_1)
        return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_CLOTH_DEF_SIZE_V1_1,
                                   "rbc_cloth_def_init", "rbc_cloth_def");
    return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_CLOTH_DEF_SIZE_V1_0,
                               "rbc_cloth_def_init",
                               "rbc_cloth_def");
}

RBC_API rbc_result RBC_CALL rbc_collider_def_init(rbc_collider_def *def, uint32_t struct_size) {
    rbc_collider_def d = collider_def_defaults();
    return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_COLLIDER_DEF_SIZE_V1_0,
                               "rbc_collider_def_init", "rbc_collider_def");
}

static rbc_solver_def solver_def_defaults(void) {
    rbc_solver_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.solver = RBC_SOLVER_RBGS;
    d.omega = 0.0f;
    d.rho = 0.0f;
    d.chebyshev_delay = 2;
    d.mode = RBC_ITERATE_FIXED;
    d.tolerance = 1e-3f;
    d.budget_ms = 2.0f;
    d.max_linear_iterations = 1000;
    d.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    d.target_strain = 0.05f;
    d.max_substeps = 16;
    return d;
}

/* RBC_PRESET_CLOTH, the default solve since 1.6: red-black SOR at fixed counts,
 * with the world's default 480 substeps a second of 11 iterations. `rbcloth bench
 * defaults` (docs/results/defaults.md) measured it beside RBGS at the same counts
 * (the paper's cloth at 1/60 s: springs at up to 7 times their length against 2.3),
 * other rates and the target mode (which, aimed below the cloth's physical stretch,
 * runs at its cap for most frames of a swing). The result depends on the substep
 * length only, so it is the same at 1/240 s and 1/30 s. */
static rbc_solver_def solver_def_cloth(void) {
    rbc_solver_def d = solver_def_defaults();
    d.solver = RBC_SOLVER_RBGS_SOR;
    d.mode = RBC_ITERATE_FIXED;
    d.max_substeps = 32;
    d.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    return d;
}

/* Three released sizes: 1.1, 1.2-1.3 and this one. */
static rbc_result solver_def_fill(rbc_solver_def *def, uint32_t struct_size,
                                  const rbc_solver_def *d, const char *fn) {
    if (struct_size == RBC_SOLVER_DEF_SIZE_V1_2)
        return rbc_def_init_common(def, struct_size, d, sizeof *d, RBC_SOLVER_DEF_SIZE_V1_2, fn,
                                   "rbc_solver_def");
    return rbc_def_init_common(def, struct_size, d, sizeof *d, RBC_SOLVER_DEF_SIZE_V1_1, fn,
                               "rbc_solver_def");
}

RBC_API rbc_result RBC_CALL rbc_solver_def_init(rbc_solver_def *def, uint32_t struct_size) {
    rbc_solver_def d = solver_def_defaults();
    return solver_def_fill(def, struct_size, &d, "rbc_solver_def_init");
}

RBC_API rbc_result RBC_CALL rbc_solver_def_preset(rbc_solver_def *def, uint32_t struct_size,
                                                  rbc_preset preset) {
    static const char fn[] = "rbc_solver_def_preset";
    rbc_solver_def d = solver_def_defaults();
    /* These presets need fields a 1.1-1.3 def does not have: the game preset its
     * target, the cloth preset its cap (max_substeps). */
    if ((preset == RBC_PRESET_GAME_60HZ || preset == RBC_PRESET_CLOTH) && def &&
        struct_size != sizeof d)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: %s needs the ABI 1.4 rbc_solver_def (struct_size %zu, got "
                             "%u): its fields from target_strain on do not fit",
                             fn, preset == RBC_PRESET_CLOTH ? "RBC_PRESET_CLOTH" : "RBC_PRESET_GAME_60HZ",
                             sizeof d, struct_size);
    switch (preset) {
    case RBC_PRESET_PAPER:
        break;
    case RBC_PRESET_CLOTH:
        d = solver_def_cloth();
        break;
    case RBC_PRESET_GAME_60HZ:
        /* Measured on the paper's 100 x 100 cloth at dt = 1/60 s
         * (docs/results/target.md): the figures there are this preset's. */
        d.solver = RBC_SOLVER_RBGS;
        d.mode = RBC_ITERATE_TARGET;
        d.target_strain = 0.05f;
        d.max_substeps = 32;
        d.max_linear_iterations = 8;
        d.energy_guard = RBC_ENERGY_GUARD_CLAMP;
        break;
    default:
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: preset %d is not an rbc_preset", fn,
                             (int)preset);
    }
    return solver_def_fill(def, struct_size, &d, fn);
}

static const char *solver_name(rbc_solver_kind k) {
    static const char *const names[] = {"rbgs",          "jacobi",         "jacobi_chebyshev",
                                        "gauss_seidel",  "rbgs_sor",       "rbgs_chebyshev",
                                        "multicolor_gs", "direct"};
    return k >= 0 && k <= RBC_SOLVER_DIRECT ? names[k] : "?";
}

/* Validate a solver def (already read at a released size) into core settings. */
static rbc_result solver_settings_from(rbc_world *w, const char *fn, const rbc_solver_def *d,
                                       rbc_solver_settings *out) {
    if (d->solver < RBC_SOLVER_RBGS || d->solver > RBC_SOLVER_DIRECT)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: solver %d is not an rbc_solver_kind",
                           fn, (int)d->solver);
    if (!(isfinite(d->omega) && d->omega >= 0.0f && d->omega < 2.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: omega is %g; it must be in (0, 2), or 0 for the optimal value",
                           fn, (double)d->omega);
    if (!(isfinite(d->rho) && d->rho >= 0.0f && d->rho < 1.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: rho is %g; it must be in (0, 1), or 0 to estimate it", fn,
                           (double)d->rho);
    if (d->chebyshev_delay > 100000)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: chebyshev_delay is %u; at most 100000",
                           fn, d->chebyshev_delay);
    if (d->mode < RBC_ITERATE_FIXED || d->mode > RBC_ITERATE_TARGET)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: mode %d is not an rbc_iteration_mode",
                           fn, (int)d->mode);
    if (!(isfinite(d->tolerance) && d->tolerance > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: tolerance is %g; it must be finite and > 0", fn,
                           (double)d->tolerance);
    if (!(isfinite(d->budget_ms) && d->budget_ms > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: budget_ms is %g; it must be finite and > 0", fn,
                           (double)d->budget_ms);
    if (d->max_linear_iterations < 1 || d->max_linear_iterations > 100000)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: max_linear_iterations is %u; range 1..100000", fn,
                           d->max_linear_iterations);
    if (d->energy_guard < RBC_ENERGY_GUARD_OFF || d->energy_guard > RBC_ENERGY_GUARD_FAIL)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: energy_guard %d is not an rbc_energy_guard", fn,
                           (int)d->energy_guard);
    if (!(isfinite(d->target_strain) && d->target_strain > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: target_strain is %g; it must be finite and > 0 (an RMS "
                           "relative strain, 0.05 = 5 %%)",
                           fn, (double)d->target_strain);
    if (d->max_substeps < 1 || d->max_substeps > 1024)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: max_substeps is %u; range 1..1024",
                           fn, d->max_substeps);
    out->kind = d->solver;
    out->energy_guard = d->energy_guard;
    out->target_strain = d->target_strain;
    out->max_substeps = d->max_substeps;
    out->omega = d->omega;
    out->rho = d->rho;
    out->chebyshev_delay = d->chebyshev_delay;
    out->mode = d->mode;
    out->tolerance = d->tolerance;
    out->budget_ms = d->budget_ms;
    out->max_linear_iterations = d->max_linear_iterations;
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* World                                                                     */
/* ------------------------------------------------------------------------- */

/* substep_rate: the world's (> 0 lets substeps be 0: from the rate), or 0 for a world
 * made with a def older than 1.6. */
static rbc_result check_iterations(rbc_world *w, const char *fn, uint32_t substeps,
                                   uint32_t nonlinear, uint32_t linear, float substep_rate) {
    if (substeps == 0 && !(substep_rate > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: substeps is 0, which takes them from the substep rate, but "
                           "this world has none (substep_rate is a 1.6 field of rbc_world_def); "
                           "range 1..1024",
                           fn);
    if (substeps > 1024)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: substeps is %u; range 1..1024, or 0 for the substep rate", fn,
                           substeps);
    if (nonlinear < 1 || nonlinear > 1024)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: nonlinear_iterations is %u; range 1..1024", fn, nonlinear);
    if (linear < 1 || linear > 4096)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: linear_iterations is %u; range 1..4096", fn, linear);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_create(const rbc_world_def *user_def,
                                             rbc_world_id *out_world) {
    static const char fn[] = "rbc_world_create";
    if (!out_world) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: out_world is NULL", fn);
    *out_world = 0;
    rbc_world_def def = world_def_defaults();
    rbc_result rc = read_def2(&def, sizeof def, RBC_WORLD_DEF_SIZE_V1_0, RBC_WORLD_DEF_SIZE_V1_1,
                              user_def, fn, "rbc_world_def");
    if (rc) return rc;
    /* A host built against a 1.0-1.5 header was promised the paper's fixed counts
     * when it leaves the solver NULL, and no strain warning; a 1.6 host gets the
     * default solve and the warning. */
    const int def_v16 = def.struct_size == sizeof def;
    if (!def_v16) {
        def.substep_rate = 0.0f;
        def.strain_warning = 0.0f;
    }
    if (def_v16 && !(isfinite(def.substep_rate) && def.substep_rate > 0.0f))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: substep_rate is %g Hz; it must be finite and > 0 (substeps "
                             "per second when substeps is 0; default 480)",
                             fn, (double)def.substep_rate);
    if (!(isfinite(def.strain_warning) && def.strain_warning >= 0.0f))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: strain_warning is %g; it must be finite and >= 0 (a relative "
                             "strain: 2 = a spring at three times its rest length; 0 = no check)",
                             fn, (double)def.strain_warning);
    if (!finite3(def.gravity))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: gravity (%g, %g, %g) is not finite",
                             fn, (double)def.gravity[0], (double)def.gravity[1],
                             (double)def.gravity[2]);
    if ((rc = check_iterations(NULL, fn, def.substeps, def.nonlinear_iterations,
                               def.linear_iterations, def.substep_rate)))
        return rc;
    if (def.backend != RBC_BACKEND_AUTO && def.backend != RBC_BACKEND_CPU &&
        def.backend != RBC_BACKEND_CUDA)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: backend %d is not an rbc_backend",
                             fn, (int)def.backend);
    if (def.backend == RBC_BACKEND_CUDA)
        return rbc_set_error(RBC_ERR_BACKEND_UNAVAILABLE,
                             "%s: this build of librbcloth has no CUDA backend; use "
                             "RBC_BACKEND_CPU or RBC_BACKEND_AUTO",
                             fn);
    if (def.thread_count > RBC_MAX_THREADS)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: thread_count is %u; at most %u", fn,
                             def.thread_count, RBC_MAX_THREADS);
    if (def.log_level < RBC_LOG_ERROR || def.log_level > RBC_LOG_DEBUG)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: log_level %d is not an rbc_log_level",
                             fn, (int)def.log_level);
    if ((def.alloc == NULL) != (def.free == NULL))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: give both alloc and free hooks, or neither", fn);

    /* A given solver def starts from the field defaults, as rbc_solver_def_init's. */
    rbc_solver_def sdef = def_v16 && !def.solver ? solver_def_cloth() : solver_def_defaults();
    rbc_solver_settings settings;
    if (def.solver &&
        (rc = read_def2(&sdef, sizeof sdef, RBC_SOLVER_DEF_SIZE_V1_1, RBC_SOLVER_DEF_SIZE_V1_2,
                        def.solver, fn, "rbc_world_def.solver")))
        return rc;
    if ((rc = solver_settings_from(NULL, fn, &sdef, &settings))) return rc;

    rbc_allocator alloc = rbc_allocator_default();
    if (def.alloc) {
        alloc.alloc = (void *(*)(void *, size_t, size_t))def.alloc;
        alloc.free = (void (*)(void *, void *, size_t))def.free;
        alloc.user = def.alloc_user;
    }
    uint32_t threads = def.thread_count;
    if (threads == 0) {
        threads = rbc_cpu_count();
        if (threads > RBC_MAX_THREADS) threads = RBC_MAX_THREADS;
    }

    rbc_world *w = rbc_mem_alloc(&alloc, sizeof *w);
    if (!w) return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
    w->alloc = alloc;
    w->def = def;
    if (rbc_solver_init(&w->solver, &alloc, threads) != RBC_OK) {
        rbc_mem_free(&alloc, w, sizeof *w);
        return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: could not start %u worker threads", fn,
                             threads);
    }
    /* thread_count 0: the step measures whether its threads pay (core/solver.c,
     * threads_for_step); a count the host gives is used as given. */
    w->solver.threads_auto = def.thread_count == 0;
    if (rbc_reg_add(&g_worlds, w, 0, &w->id) != RBC_OK) {
        rbc_solver_fini(&w->solver);
        rbc_mem_free(&alloc, w, sizeof *w);
        return rbc_set_error(RBC_ERR_CAPACITY, "%s: %u worlds exist already", fn, RBC_MAX_WORLDS);
    }
    memcpy(w->solver.gravity, def.gravity, sizeof def.gravity);
    w->solver.substeps = def.substeps;
    w->solver.nonlinear_iterations = def.nonlinear_iterations;
    w->solver.linear_iterations = def.linear_iterations;
    w->solver.settings = settings; /* no cloth yet: no buffers to allocate */
    w->solver.strain_warning = def.strain_warning;
    w->solver.substep_rate = def.substep_rate;
    w->solver.public_world_id = w->id;
    *out_world = w->id;
    char msg[128];
    snprintf(msg, sizeof msg, "world 0x%08x created: CPU backend, %u threads", w->id, threads);
    world_log(w, RBC_LOG_INFO, msg);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_destroy(rbc_world_id id) {
    rbc_world *w;
    rbc_result rc = lookup_world(id, "rbc_world_destroy", &w);
    if (rc) return rc;
    rbc_solver *sol = &w->solver;
    for (uint32_t k = 0; k < sol->cloth_count; ++k) rbc_reg_remove(&g_cloths, sol->cloths[k]->public_id);
    for (uint32_t k = 0; k < sol->collider_count; ++k)
        rbc_reg_remove(&g_colliders, sol->colliders[k].public_id);
    rbc_reg_remove(&g_worlds, id);
    rbc_allocator alloc = w->alloc;
    rbc_solver_fini(sol); /* destroys every cloth and collider */
    rbc_mem_free(&alloc, w, sizeof *w);
    return RBC_OK;
}

/* What to change when a step is past the strain warning, for the settings in use. */
static void strain_advice(const rbc_solver *s, char *out, size_t size) {
    const rbc_solver_settings *st = &s->settings;
    const char *name = solver_name(st->kind);
    if (st->kind == RBC_SOLVER_JACOBI || st->kind == RBC_SOLVER_JACOBI_CHEBYSHEV) {
        snprintf(out, size,
                 "solver %s converges the slowest per iteration: use rbgs_sor "
                 "(RBC_PRESET_CLOTH, the default solve) or raise its iterations",
                 name);
        return;
    }
    switch (st->mode) {
    case RBC_ITERATE_TARGET:
        if (s->tgt_capped || s->last_substeps >= st->max_substeps)
            snprintf(out, size,
                     "the target mode ran at its cap (max_substeps %u x max_linear_iterations "
                     "%u): raise max_substeps",
                     st->max_substeps, st->max_linear_iterations);
        else
            snprintf(out, size,
                     "the target (RMS strain %g) was met while a few springs stretched: the "
                     "load gathers on them (pins, contacts): lower target_strain, stiffen the "
                     "cloth, or spread the pins",
                     (double)st->target_strain);
        return;
    case RBC_ITERATE_BUDGET:
        snprintf(out, size,
                 "the budget of %g ms a step buys too few iterations (%u in the last step): "
                 "raise budget_ms or substeps, or use the default solve (RBC_PRESET_CLOTH)",
                 (double)st->budget_ms, s->last_linear);
        return;
    case RBC_ITERATE_TOLERANCE:
        snprintf(out, size,
                 "a relative residual of %g per global step leaves the springs loose at "
                 "%u substep(s): raise substeps, or use the default solve (RBC_PRESET_CLOTH)",
                 (double)st->tolerance, s->last_substeps);
        return;
    default:
        break;
    }
    if (st->kind == RBC_SOLVER_DIRECT)
        snprintf(out, size,
                 "the global solve is exact: one local/global pass per substep at %u "
                 "substep(s) is too few for this stiffness and time step: raise substeps or "
                 "nonlinear_iterations",
                 s->last_substeps);
    else if (st->kind == RBC_SOLVER_RBGS_SOR)
        snprintf(out, size,
                 "%s at %u substep(s) x %u linear iterations a step is far from converged "
                 "at this time step: raise the substeps (or the substep rate) or the "
                 "iterations",
                 name, s->last_substeps, s->linear_iterations);
    else
        snprintf(out, size,
                 "%s at %u substep(s) x %u linear iterations a step is far from converged "
                 "at this time step: use rbgs_sor (RBC_PRESET_CLOTH, the default solve), "
                 "which converges far faster per iteration, or raise the substeps",
                 name, s->last_substeps, s->linear_iterations);
}

RBC_API rbc_result RBC_CALL rbc_world_step(rbc_world_id id, float dt) {
    static const char fn[] = "rbc_world_step";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!(isfinite(dt) && dt > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: dt is %g s; it must be finite and > 0",
                           fn, (double)dt);
    char msg[RBC_ERROR_CAP - 64];
    rc = rbc_solver_step(&w->solver, dt, msg, sizeof msg);
    if (rc) return world_error(w, rc, "%s: world 0x%08x: %s", fn, w->id, msg);
    uint64_t clamps = w->solver.energy_clamped_steps;
    /* Warn at the first clamped step and at every power of two after it: the
     * host hears of it without a message per step; stats count every one. */
    if (w->solver.energy_clamped_last && (clamps & (clamps - 1)) == 0) {
        char note[sizeof w->solver.energy_note + 160];
        snprintf(note, sizeof note,
                 "world 0x%08x step %llu (%llu clamped so far): %s; solver %s (more iterations, "
                 "rbgs or direct, or smaller steps avoid it)",
                 w->id, (unsigned long long)w->solver.step_count, (unsigned long long)clamps,
                 w->solver.energy_note, solver_name(w->solver.settings.kind));
        world_log(w, RBC_LOG_WARNING, note);
    }
    uint64_t capped = w->solver.tgt_capped_steps;
    if (w->solver.tgt_capped && (capped & (capped - 1)) == 0) {
        const rbc_solver *s = &w->solver;
        char note[400];
        snprintf(note, sizeof note,
                 "world 0x%08x step %llu (%llu missed at the cap so far): the target "
                 "strain %g was not met within the cap: the step reached an RMS relative "
                 "strain of %.4g with max_substeps %u x %u non-linear x at most %u linear "
                 "iterations (%u done); raise max_substeps or max_linear_iterations, or ask "
                 "for a larger target_strain",
                 w->id, (unsigned long long)s->step_count, (unsigned long long)capped,
                 (double)s->settings.target_strain, s->tgt_reached, s->settings.max_substeps,
                 s->nonlinear_iterations, s->settings.max_linear_iterations, s->last_linear);
        world_log(w, RBC_LOG_WARNING, note);
    }
    uint64_t warned = w->solver.strain_warn_steps;
    if (w->solver.strain_warn_last && (warned & (warned - 1)) == 0) {
        const rbc_solver *s = &w->solver;
        const rbc_cloth_state *c = s->cloths[s->strain_warn_cloth];
        const rbc_topology *t = &c->topo;
        uint32_t sp = s->strain_warn_spring;
        char advice[400], note[800];
        strain_advice(s, advice, sizeof advice);
        snprintf(note, sizeof note,
                 "world 0x%08x step %llu (%llu such steps so far): cloth 0x%08x: the spring "
                 "between vertices %u and %u is %.3g times its rest length (strain %.3g, over "
                 "the strain_warning of %g): the result is not cloth; %s",
                 w->id, (unsigned long long)s->step_count, (unsigned long long)warned,
                 c->public_id, t->to_host[t->sa[sp]], t->to_host[t->sb[sp]],
                 1.0 + s->step_max_strain, s->step_max_strain, (double)s->strain_warning,
                 advice);
        world_log(w, RBC_LOG_WARNING, note);
    }
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_set_iterations(rbc_world_id id, uint32_t substeps,
                                                     uint32_t nonlinear, uint32_t linear) {
    static const char fn[] = "rbc_world_set_iterations";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if ((rc = check_iterations(w, fn, substeps, nonlinear, linear, w->solver.substep_rate)))
        return rc;
    w->solver.substeps = substeps;
    w->solver.nonlinear_iterations = nonlinear;
    w->solver.linear_iterations = linear;
    rbc_solver_target_reset(&w->solver);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_set_gravity(rbc_world_id id, const float gravity[3]) {
    static const char fn[] = "rbc_world_set_gravity";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!gravity) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: gravity is NULL", fn);
    if (!finite3(gravity))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: gravity (%g, %g, %g) is not finite",
                           fn, (double)gravity[0], (double)gravity[1], (double)gravity[2]);
    memcpy(w->solver.gravity, gravity, 3 * sizeof(float));
    for (uint32_t k = 0; k < w->solver.cloth_count; ++k) /* a new potential: recompute E */
        rbc_cloth_state_energy_invalidate(w->solver.cloths[k], 1);
    return RBC_OK;
}

static int stats_size_known(uint32_t size) {
    return size == sizeof(rbc_world_stats) || size == RBC_WORLD_STATS_SIZE_V1_5 ||
           size == RBC_WORLD_STATS_SIZE_V1_4 || size == RBC_WORLD_STATS_SIZE_V1_3 ||
           size == RBC_WORLD_STATS_SIZE_V1_2 || size == RBC_WORLD_STATS_SIZE_V1_1 ||
           size == RBC_WORLD_STATS_SIZE_V1_0;
}

#define STATS_SIZES_MESSAGE                                                                \
    "%s: stats->struct_size is %u, which matches no released version (this library knows " \
    "%zu, the 1.5 size %u, the 1.4 size %u, the 1.3 size %u, the 1.2 size %u, the 1.1 size " \
    "%u and the 1.0 size %u)"
#define STATS_SIZES_ARGS(fn, size)                                                          \
    fn, size, sizeof(rbc_world_stats), RBC_WORLD_STATS_SIZE_V1_5, RBC_WORLD_STATS_SIZE_V1_4, \
        RBC_WORLD_STATS_SIZE_V1_3, RBC_WORLD_STATS_SIZE_V1_2, RBC_WORLD_STATS_SIZE_V1_1,     \
        RBC_WORLD_STATS_SIZE_V1_0

RBC_API rbc_result RBC_CALL rbc_world_stats_init(rbc_world_stats *stats, uint32_t struct_size) {
    static const char fn[] = "rbc_world_stats_init";
    if (!stats) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: stats is NULL", fn);
    if (!stats_size_known(struct_size))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, STATS_SIZES_MESSAGE,
                             STATS_SIZES_ARGS(fn, struct_size));
    memset(stats, 0, struct_size);
    stats->struct_size = struct_size;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_get_stats(rbc_world_id id, rbc_world_stats *out) {
    static const char fn[] = "rbc_world_get_stats";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!out) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: stats is NULL", fn);
    if (!stats_size_known(out->struct_size))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, STATS_SIZES_MESSAGE,
                           STATS_SIZES_ARGS(fn, out->struct_size));
    rbc_solver *s = &w->solver;
    double res_num = 0.0, res_den = 0.0;
    /* 1.2 and later hold the energy fields and skip_measures. */
    const int full = out->struct_size >= RBC_WORLD_STATS_SIZE_V1_2;
    /* What costs a pass over the cloths is evaluated only if asked for. */
    const int measure = !(full && out->skip_measures);
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = out->struct_size;
    if (full) st.skip_measures = out->skip_measures;
    st.cloth_count = s->cloth_count;
    st.collider_count = s->collider_count;
    st.thread_count = s->threads_last ? s->threads_last : rbc_pool_size(s->pool);
    st.backend = RBC_BACKEND_CPU;
    st.step_count = s->step_count;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        const rbc_cloth_state *c = s->cloths[k];
        st.particle_count += c->topo.n;
        st.spring_count += c->topo.ns;
        if (c->topo.ncolors > st.color_count) st.color_count = c->topo.ncolors;
        if (measure) {
            double e, strain;
            rbc_cloth_state_error(c, &e, &strain);
            st.error_eq7 += e;
            if (strain > st.max_strain) st.max_strain = strain;
            if (out->struct_size > RBC_WORLD_STATS_SIZE_V1_3) { /* strain_rms: 1.4 */
                double rms = rbc_strain_rms(s->cloths[k], s->cloths[k]->x);
                if (rms > st.strain_rms) st.strain_rms = rms;
            }
        }
        if (full) {
            double ke = 0.0, pe = 0.0, e_budget;
            rbc_cloth_state_energy(c, s->gravity, measure, &ke, &pe, &e_budget);
            st.kinetic_energy += ke;
            st.potential_energy += pe;
            st.energy_budget += e_budget;
            st.memory_bytes += rbc_cloth_state_bytes(c);
        }
        if (measure && out->struct_size >= RBC_WORLD_STATS_SIZE_V1_1) {
            double r2, b2, obj;
            rbc_cloth_state_system_error(c, &r2, &b2, &obj);
            res_num += r2;
            res_den += b2;
            st.pd_objective += obj;
        }
        if (c->rho_est > st.spectral_radius) st.spectral_radius = c->rho_est;
    }
    st.solver = s->settings.kind;
    st.iteration_mode = s->settings.mode;
    st.linear_residual = res_den > 0.0 ? sqrt(res_num / res_den) : 0.0;
    if (s->settings.kind == RBC_SOLVER_RBGS_SOR && s->cloth_count) {
        rbc_cloth_state *c0 = s->cloths[0];
        /* The omega of the last step: given, or Young's optimum from the cached rho_J
         * (stats never estimate: reading them must not change the world). */
        double rho = c0->rho_est;
        st.omega = s->settings.omega > 0.0f ? s->settings.omega
                   : rho > 0.0           ? 2.0 / (1.0 + sqrt(1.0 - rho * rho))
                                         : 0.0;
    }
    st.substeps = s->last_substeps;
    st.nonlinear_iterations = s->last_nonlinear;
    st.linear_iterations = s->last_linear;
    st.step_ms = s->last.step;
    st.integrate_ms = s->last.integrate;
    st.local_ms = s->last.local;
    st.global_ms = s->last.global;
    st.collide_ms = s->last.collide;
    st.callback_ms = s->last.callback;
    st.other_ms = s->last.other;
    st.energy_removed = s->energy_removed_last;
    st.energy_clamped_steps = s->energy_clamped_steps;
    st.collider_contacts = s->last_contacts + s->last_host_contacts;
    st.cloth_contacts = s->last_cloth_contacts;
    st.torn_springs = s->torn_springs;
    const int target = s->settings.mode == RBC_ITERATE_TARGET;
    st.target_reached = s->tgt_reached;
    st.target_met = (uint32_t)s->tgt_met;
    st.next_substeps = !target            ? s->substeps /* 0: from the rate */
                       : s->tgt_substeps ? s->tgt_substeps
                                         : s->settings.max_substeps;
    st.target_missed_steps = s->tgt_missed_steps;
    st.target_capped_steps = s->tgt_capped_steps;
    st.cloth_contact_frozen = s->last_frozen;
    st.cloth_contact_capped = s->last_cloth_capped;
    st.step_max_strain = s->step_max_strain;
    st.strain_warning_steps = s->strain_warn_steps;
    memcpy(out, &st, out->struct_size); /* only what the host's struct holds */
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_set_collision_callback(rbc_world_id id, rbc_collision_fn fn_,
                                                             void *user) {
    static const char fn[] = "rbc_world_set_collision_callback";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    rc = rbc_solver_set_callback(&w->solver, fn_, user);
    if (rc) return world_error(w, rc, "%s: out of memory for the callback's buffers", fn);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* Cloth                                                                     */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_cloth_create(rbc_world_id wid, const rbc_cloth_def *user_def,
                                             rbc_cloth_id *out_cloth) {
    static const char fn[] = "rbc_cloth_create";
    rbc_world *w;
    rbc_result rc = lookup_world(wid, fn, &w);
    if (rc) return rc;
    if (!out_cloth) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: out_cloth is NULL", fn);
    *out_cloth = 0;
    rbc_cloth_def def = cloth_def_defaults();
    if ((rc = read_def2(&def, sizeof def, RBC_CLOTH_DEF_SIZE_V1_0, RBC_CLOTH_DEF_SIZE_V1_1, user_def, fn,
                        "rbc_cloth_def"))) {
        world_log(w, RBC_LOG_ERROR, rbc_last_error());
        return rc;
    }
    if (!(isfinite(def.shear_stiffness) && def.shear_stiffness >= 0.0f) ||
        !(isfinite(def.bend_stiffness) && def.bend_stiffness >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: shear_stiffness %g and bend_stiffness %g N/m must be "
                           "finite and >= 0",
                           fn, (double)def.shear_stiffness, (double)def.bend_stiffness);
    if (!(isfinite(def.damping) && def.damping >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: damping is %g 1/s; it must be finite and >= 0", fn,
                           (double)def.damping);
    if (!(isfinite(def.thickness) && def.thickness >= 0.0f) ||
        !(isfinite(def.friction) && def.friction >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: thickness %g m and friction %g must be finite and >= 0",
                           fn, (double)def.thickness, (double)def.friction);
    if (def.collision_flags & ~(uint32_t)(RBC_CLOTH_COLLIDE_SELF | RBC_CLOTH_COLLIDE_CLOTHS))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: collision_flags 0x%x has bits that are not "
                           "RBC_CLOTH_COLLIDE_* flags",
                           fn, def.collision_flags);
    if (!(isfinite(def.tear_strain) && def.tear_strain >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: tear_strain is %g; it must be finite and >= 0 (0 = no "
                           "tearing)",
                           fn, (double)def.tear_strain);
    if (def.collision_flags && !(def.thickness > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth def: collision_flags 0x%x need a thickness > 0 (it is %g m)",
                           fn, def.collision_flags, (double)def.thickness);
    rbc_mesh_input in;
    memset(&in, 0, sizeof in);
    in.vertex_count = def.vertex_count;
    in.positions = def.positions;
    in.quad_count = def.quad_count;
    in.quads = def.quads;
    in.spring_count = def.spring_count;
    in.springs = def.springs;
    in.masses = def.masses;
    in.density = def.density;
    in.vertex_mass = def.vertex_mass;
    in.stiffness = def.stiffness;
    in.shear_stiffness = def.shear_stiffness;
    in.bend_stiffness = def.bend_stiffness;
    in.pin_count = def.pin_count;
    in.pins = def.pins;
    char msg[RBC_ERROR_CAP - 64];
    rbc_cloth_state *c;
    rc = rbc_cloth_state_create(&w->solver, &in, def.damping, &c, msg, sizeof msg);
    if (rc) return world_error(w, rc, "%s: cloth def: %s", fn, msg);
    if ((rc = rbc_cloth_state_set_contact(&w->solver, c, def.thickness, def.friction,
                                          def.collision_flags))) {
        rbc_cloth_state_destroy(&w->solver, c);
        return world_error(w, rc, "%s: out of memory for cloth contact", fn);
    }
    c->tear_strain = def.tear_strain;
    if (rbc_reg_add(&g_cloths, c, w->id, &c->public_id) != RBC_OK) {
        rbc_cloth_state_destroy(&w->solver, c);
        return world_error(w, RBC_ERR_CAPACITY, "%s: %u cloths exist already", fn, RBC_MAX_SLOTS);
    }
    if ((rc = rbc_solver_add_cloth(&w->solver, c))) {
        rbc_reg_remove(&g_cloths, c->public_id);
        rbc_cloth_state_destroy(&w->solver, c);
        return world_error(w, rc, "%s: out of memory", fn);
    }
    *out_cloth = c->public_id;
    return RBC_OK;
}

static rbc_result lookup_cloth(rbc_world_id wid, rbc_cloth_id cid, const char *fn,
                               rbc_world **ow, rbc_cloth_state **oc) {
    rbc_result rc = lookup_world(wid, fn, ow);
    if (rc) return rc;
    *oc = rbc_reg_get(&g_cloths, cid, (*ow)->id, fn);
    if (!*oc) {
        world_log(*ow, RBC_LOG_ERROR, rbc_last_error());
        return RBC_ERR_STALE_HANDLE;
    }
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_destroy(rbc_world_id wid, rbc_cloth_id cid) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, "rbc_cloth_destroy", &w, &c);
    if (rc) return rc;
    rbc_solver_remove_cloth(&w->solver, c);
    rbc_cloth_state_destroy(&w->solver, c);
    rbc_reg_remove(&g_cloths, cid);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_vertex_count(rbc_world_id wid, rbc_cloth_id cid,
                                                       uint32_t *out_count) {
    static const char fn[] = "rbc_cloth_get_vertex_count";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!out_count) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: out_count is NULL", fn);
    *out_count = c->topo.n;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_topology(rbc_world_id wid, rbc_cloth_id cid,
                                                   uint32_t *out_spring_count,
                                                   uint32_t *out_color_count) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, "rbc_cloth_get_topology", &w, &c);
    if (rc) return rc;
    if (out_spring_count) *out_spring_count = c->topo.ns;
    if (out_color_count) *out_color_count = c->topo.ncolors;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_read_positions(rbc_world_id wid, rbc_cloth_id cid,
                                                     float *xyz, size_t capacity,
                                                     size_t *out_written) {
    static const char fn[] = "rbc_cloth_read_positions";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    size_t need = 3 * (size_t)c->topo.n;
    if (!xyz) {
        if (out_written) *out_written = need;
        return RBC_OK;
    }
    if (capacity < need)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x has %u vertices and needs %zu floats; capacity is %zu",
                           fn, cid, c->topo.n, need, capacity);
    rbc_cloth_state_read(c, xyz);
    if (out_written) *out_written = need;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_set_pin(rbc_world_id wid, rbc_cloth_id cid, uint32_t vertex,
                                              const float *target) {
    static const char fn[] = "rbc_cloth_set_pin";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (vertex >= c->topo.n)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x: vertex %u is out of range (vertex count %u)", fn,
                           cid, vertex, c->topo.n);
    if (target && !finite3(target))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x: vertex %u: target (%g, %g, %g) is not finite", fn,
                           cid, vertex, (double)target[0], (double)target[1], (double)target[2]);
    rc = rbc_cloth_state_set_pin(&w->solver, c, vertex, target);
    if (rc) return world_error(w, rc, "%s: out of memory", fn);
    rbc_detach_vertex(c, vertex); /* a pin of the host's own: no longer attached */
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* Colliders                                                                 */
/* ------------------------------------------------------------------------- */

static rbc_result check_transform(rbc_world *w, const char *fn, const float *pos,
                                  const float *rot) {
    if (!pos || !rot)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: position or rotation is NULL", fn);
    if (!finite3(pos))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: position (%g, %g, %g) is not finite",
                           fn, (double)pos[0], (double)pos[1], (double)pos[2]);
    double n2 = (double)rot[0] * rot[0] + (double)rot[1] * rot[1] + (double)rot[2] * rot[2] +
                (double)rot[3] * rot[3];
    /* Unit within float rounding of a normalised quaternion (a few ulp, 1e-4 leaves
     * room for hosts that normalise in float and then compose). */
    if (!(isfinite(n2) && fabs(n2 - 1.0) <= 1e-4))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: rotation (%g, %g, %g, %g) is not a unit quaternion (norm^2 %g)",
                           fn, (double)rot[0], (double)rot[1], (double)rot[2], (double)rot[3],
                           n2);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_collider_create(rbc_world_id wid, const rbc_collider_def *user_def,
                                                rbc_collider_id *out) {
    static const char fn[] = "rbc_collider_create";
    rbc_world *w;
    rbc_result rc = lookup_world(wid, fn, &w);
    if (rc) return rc;
    if (!out) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: out_collider is NULL", fn);
    *out = 0;
    rbc_collider_def def = collider_def_defaults();
    if ((rc = read_def(&def, sizeof def, RBC_COLLIDER_DEF_SIZE_V1_0, user_def, fn, "rbc_collider_def"))) {
        world_log(w, RBC_LOG_ERROR, rbc_last_error());
        return rc;
    }
    if (def.shape < RBC_SHAPE_PLANE || def.shape > RBC_SHAPE_TRIANGLE_MESH)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: collider def: shape %d is not an rbc_shape", fn, (int)def.shape);
    if ((def.shape == RBC_SHAPE_SPHERE || def.shape == RBC_SHAPE_CAPSULE) &&
        !(isfinite(def.radius) && def.radius > 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: collider def: %s radius is %g m; it must be finite and > 0", fn,
                           def.shape == RBC_SHAPE_SPHERE ? "sphere" : "capsule",
                           (double)def.radius);
    if (def.shape == RBC_SHAPE_BOX || def.shape == RBC_SHAPE_CAPSULE)
        for (int a = def.shape == RBC_SHAPE_CAPSULE ? 1 : 0;
             a < (def.shape == RBC_SHAPE_CAPSULE ? 2 : 3); ++a)
            if (!(isfinite(def.half_extents[a]) && def.half_extents[a] > 0.0f))
                return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                   "%s: collider def: %s half_extents[%d] is %g m; it must be "
                                   "finite and > 0",
                                   fn, def.shape == RBC_SHAPE_BOX ? "box" : "capsule", a,
                                   (double)def.half_extents[a]);
    if (!(isfinite(def.friction) && def.friction >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: collider def: friction is %g; it must be finite and >= 0", fn,
                           (double)def.friction);
    if (!(isfinite(def.thickness) && def.thickness >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: collider def: thickness is %g m; it must be finite and >= 0", fn,
                           (double)def.thickness);
    if ((rc = check_transform(w, fn, def.position, def.rotation))) return rc;
    rbc_collider_state cs;
    memset(&cs, 0, sizeof cs);
    cs.shape = def.shape;
    cs.radius = def.radius;
    cs.thickness = def.thickness;
    cs.friction = def.friction;
    memcpy(cs.half_extents, def.half_extents, sizeof cs.half_extents);
    if (def.shape == RBC_SHAPE_TRIANGLE_MESH) {
        char msg[RBC_ERROR_CAP - 64];
        rc = rbc_trimesh_create(def.mesh_positions, def.mesh_vertex_count, def.mesh_triangles,
                                def.mesh_triangle_count, &w->solver.alloc, &cs.mesh, msg,
                                sizeof msg);
        if (rc) return world_error(w, rc, "%s: collider def: triangle mesh: %s", fn, msg);
    }
    memcpy(cs.position, def.position, sizeof cs.position);
    memcpy(cs.rotation, def.rotation, sizeof cs.rotation);
    /* The registry holds a marker; the collider itself lives in the solver's dense
     * array, found by its id. */
    if (rbc_reg_add(&g_colliders, (void *)(uintptr_t)1, w->id, &cs.public_id) != RBC_OK) {
        rbc_trimesh_destroy(cs.mesh, &w->solver.alloc);
        return world_error(w, RBC_ERR_CAPACITY, "%s: %u colliders exist already", fn,
                           RBC_MAX_SLOTS);
    }
    if ((rc = rbc_solver_add_collider(&w->solver, &cs))) {
        rbc_trimesh_destroy(cs.mesh, &w->solver.alloc);
        rbc_reg_remove(&g_colliders, cs.public_id);
        return world_error(w, rc, "%s: out of memory", fn);
    }
    *out = cs.public_id;
    return RBC_OK;
}

static rbc_result lookup_collider(rbc_world_id wid, rbc_collider_id cid, const char *fn,
                                  rbc_world **ow, uint32_t *index) {
    rbc_result rc = lookup_world(wid, fn, ow);
    if (rc) return rc;
    if (!rbc_reg_get(&g_colliders, cid, (*ow)->id, fn)) {
        world_log(*ow, RBC_LOG_ERROR, rbc_last_error());
        return RBC_ERR_STALE_HANDLE;
    }
    rbc_solver *sol = &(*ow)->solver;
    for (uint32_t k = 0; k < sol->collider_count; ++k)
        if (sol->colliders[k].public_id == cid) {
            *index = k;
            return RBC_OK;
        }
    return world_error(*ow, RBC_ERR_STALE_HANDLE, "%s: collider 0x%08x is not in the world", fn,
                       cid);
}

RBC_API rbc_result RBC_CALL rbc_collider_set_transform(rbc_world_id wid, rbc_collider_id cid,
                                                       const float position[3],
                                                       const float rotation[4]) {
    static const char fn[] = "rbc_collider_set_transform";
    rbc_world *w;
    uint32_t k = 0;
    rbc_result rc = lookup_collider(wid, cid, fn, &w, &k);
    if (rc) return rc;
    if ((rc = check_transform(w, fn, position, rotation))) return rc;
    rbc_collider_state *c = &w->solver.colliders[k];
    memcpy(c->position, position, sizeof c->position);
    memcpy(c->rotation, rotation, sizeof c->rotation);
    rbc_collider_update_frame(c);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_collider_destroy(rbc_world_id wid, rbc_collider_id cid) {
    rbc_world *w;
    uint32_t k = 0;
    rbc_result rc = lookup_collider(wid, cid, "rbc_collider_destroy", &w, &k);
    if (rc) return rc;
    if ((rc = rbc_attachments_drop_collider(&w->solver, cid)))
        return world_error(w, rc, "rbc_collider_destroy: out of memory releasing attached vertices");
    rbc_solver_remove_collider(&w->solver, k);
    rbc_reg_remove(&g_colliders, cid);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* ABI 1.1: solvers, colors, state                                           */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_world_set_solver(rbc_world_id id, const rbc_solver_def *user_def) {
    static const char fn[] = "rbc_world_set_solver";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    rbc_solver_def def = solver_def_defaults();
    if ((rc = read_def2(&def, sizeof def, RBC_SOLVER_DEF_SIZE_V1_1, RBC_SOLVER_DEF_SIZE_V1_2,
                        user_def, fn, "rbc_solver_def"))) {
        world_log(w, RBC_LOG_ERROR, rbc_last_error());
        return rc;
    }
    rbc_solver_settings st;
    if ((rc = solver_settings_from(w, fn, &def, &st))) return rc;
    if ((rc = rbc_solver_set_settings(&w->solver, &st)))
        return world_error(w, rc, "%s: out of memory for the solver's buffers", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_get_solver(rbc_world_id id, rbc_solver_def *out) {
    static const char fn[] = "rbc_world_get_solver";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!out) return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: def is NULL", fn);
    if (out->struct_size != sizeof(rbc_solver_def) && out->struct_size != RBC_SOLVER_DEF_SIZE_V1_2 &&
        out->struct_size != RBC_SOLVER_DEF_SIZE_V1_1)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: def->struct_size is %u, which matches no released version "
                           "(this library knows %zu, the 1.2 size %u and the 1.1 size %u)",
                           fn, out->struct_size, sizeof(rbc_solver_def), RBC_SOLVER_DEF_SIZE_V1_2,
                           RBC_SOLVER_DEF_SIZE_V1_1);
    const rbc_solver_settings *st = &w->solver.settings;
    rbc_solver_def d = solver_def_defaults();
    d.solver = st->kind;
    d.omega = st->omega;
    d.rho = st->rho;
    d.chebyshev_delay = st->chebyshev_delay;
    d.mode = st->mode;
    d.tolerance = st->tolerance;
    d.budget_ms = st->budget_ms;
    d.max_linear_iterations = st->max_linear_iterations;
    d.energy_guard = st->energy_guard;
    d.target_strain = st->target_strain;
    d.max_substeps = st->max_substeps;
    d.struct_size = out->struct_size;
    memcpy(out, &d, out->struct_size); /* only what the host's struct holds */
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_colors(rbc_world_id wid, rbc_cloth_id cid,
                                                 uint32_t *sizes, uint32_t capacity,
                                                 uint32_t *out_color_count) {
    static const char fn[] = "rbc_cloth_get_colors";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!sizes && capacity)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: sizes is NULL but capacity is %u",
                           fn, capacity);
    const rbc_topology *t = &c->topo;
    for (uint32_t k = 0; k < t->ncolors && k < capacity; ++k)
        sizes[k] = t->color_start[k + 1] - t->color_start[k];
    if (out_color_count) *out_color_count = t->ncolors;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_state(rbc_world_id wid, rbc_cloth_id cid,
                                                float *positions, float *previous,
                                                size_t capacity) {
    static const char fn[] = "rbc_cloth_get_state";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    size_t need = 3 * (size_t)c->topo.n;
    if ((positions || previous) && capacity < need)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x has %u vertices and needs %zu floats; capacity is %zu",
                           fn, cid, c->topo.n, need, capacity);
    rbc_cloth_state_get(c, positions, previous);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_set_state(rbc_world_id wid, rbc_cloth_id cid,
                                                const float *positions, const float *previous) {
    static const char fn[] = "rbc_cloth_set_state";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!positions)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: positions is NULL", fn);
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        if (!finite3(positions + 3 * (size_t)v))
            return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                               "%s: cloth 0x%08x: vertex %u has a non-finite position", fn, cid, v);
        if (previous && !finite3(previous + 3 * (size_t)v))
            return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                               "%s: cloth 0x%08x: vertex %u has a non-finite previous position",
                               fn, cid, v);
    }
    rbc_cloth_state_set(c, positions, previous);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* ABI 1.3: host contacts, picking, attachments, tearing, wind                */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_world_set_contact_callback(rbc_world_id id, rbc_contact_fn fn_,
                                                           void *user) {
    static const char fn[] = "rbc_world_set_contact_callback";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    rc = rbc_solver_set_contact_callback(&w->solver, fn_, user);
    if (rc) return world_error(w, rc, "%s: out of memory for the callback's buffers", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_pick(rbc_world_id id, const float origin[3],
                                           const float dir[3], float max_distance, float radius,
                                           rbc_cloth_id *out_cloth, uint32_t *out_vertex,
                                           float *out_t) {
    static const char fn[] = "rbc_world_pick";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!origin || !dir || !out_cloth)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: origin, dir or out_cloth is NULL", fn);
    *out_cloth = 0;
    if (!finite3(origin) || !finite3(dir) ||
        !(dir[0] != 0.0f || dir[1] != 0.0f || dir[2] != 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: origin (%g, %g, %g) and dir (%g, %g, %g) must be finite and dir "
                           "non-zero",
                           fn, (double)origin[0], (double)origin[1], (double)origin[2],
                           (double)dir[0], (double)dir[1], (double)dir[2]);
    if (!(max_distance >= 0.0f) || !(radius >= 0.0f) || !isfinite(radius))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: max_distance %g and radius %g must be >= 0 (radius finite)", fn,
                           (double)max_distance, (double)radius);
    uint32_t k = 0, v = 0;
    float t = 0.0f;
    if (rbc_pick(&w->solver, origin, dir, max_distance, radius, &k, &v, &t)) {
        *out_cloth = w->solver.cloths[k]->public_id;
        if (out_vertex) *out_vertex = v;
        if (out_t) *out_t = t;
    }
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_attach(rbc_world_id wid, rbc_cloth_id cid, uint32_t vertex,
                                             rbc_collider_id collider, const float local[3]) {
    static const char fn[] = "rbc_cloth_attach";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (vertex >= c->topo.n)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x: vertex %u is out of range (vertex count %u)", fn,
                           cid, vertex, c->topo.n);
    if (local && !finite3(local))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x: vertex %u: local point (%g, %g, %g) is not finite",
                           fn, cid, vertex, (double)local[0], (double)local[1], (double)local[2]);
    uint32_t k = 0;
    if ((rc = lookup_collider(wid, collider, fn, &w, &k))) return rc;
    rc = rbc_attach(&w->solver, c, vertex, collider, local);
    if (rc) return world_error(w, rc, "%s: out of memory", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_cut(rbc_world_id wid, rbc_cloth_id cid,
                                          const uint32_t *pairs, uint32_t pair_count,
                                          uint32_t *out_cut) {
    static const char fn[] = "rbc_cloth_cut";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (out_cut) *out_cut = 0;
    if (pair_count && !pairs)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: pairs is NULL", fn);
    for (uint32_t m = 0; m < 2 * pair_count; ++m)
        if (pairs[m] >= c->topo.n)
            return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                               "%s: cloth 0x%08x: pair %u: vertex %u is out of range (vertex "
                               "count %u); nothing was cut",
                               fn, cid, m / 2, pairs[m], c->topo.n);
    rc = rbc_cut_pairs(&w->solver, c, pairs, pair_count, out_cut);
    if (rc) return world_error(w, rc, "%s: out of memory; nothing was cut", fn);
    return RBC_OK;
}

static rbc_result copy_topology(rbc_world_id wid, rbc_cloth_id cid, const char *fn, int quads,
                                uint32_t *dst, size_t capacity, size_t *out_count) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    size_t need = quads ? rbc_cloth_quads_host(c, NULL, 0) : rbc_cloth_springs_host(c, NULL, 0);
    if (dst && capacity < need)
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: cloth 0x%08x has %zu values to write; capacity is %zu", fn, cid,
                           need, capacity);
    if (dst) {
        if (quads)
            rbc_cloth_quads_host(c, dst, capacity);
        else
            rbc_cloth_springs_host(c, dst, capacity);
    }
    if (out_count) *out_count = need;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_quads(rbc_world_id wid, rbc_cloth_id cid, uint32_t *quads,
                                                size_t capacity, size_t *out_count) {
    return copy_topology(wid, cid, "rbc_cloth_get_quads", 1, quads, capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_springs(rbc_world_id wid, rbc_cloth_id cid,
                                                  uint32_t *pairs, size_t capacity,
                                                  size_t *out_count) {
    return copy_topology(wid, cid, "rbc_cloth_get_springs", 0, pairs, capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_world_set_wind(rbc_world_id id, const float velocity[3], float drag,
                                               float lift) {
    static const char fn[] = "rbc_world_set_wind";
    rbc_world *w;
    rbc_result rc = lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!velocity || !finite3(velocity))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: velocity is NULL or not finite", fn);
    if (!(isfinite(drag) && drag >= 0.0f) || !(isfinite(lift) && lift >= 0.0f))
        return world_error(w, RBC_ERR_INVALID_ARGUMENT,
                           "%s: drag %g and lift %g must be finite and >= 0", fn, (double)drag,
                           (double)lift);
    memcpy(w->solver.wind, velocity, sizeof w->solver.wind);
    w->solver.wind_drag = drag;
    w->solver.wind_lift = lift;
    return RBC_OK;
}
