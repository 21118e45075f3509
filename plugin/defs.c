/* defs.c -- the ABI's defs: their defaults, the *_def_init functions, the solver
 * presets, and what reads and checks a host's def for the other files (a def of any
 * released size, rbc_plugin_read_def2; a solver def into core settings,
 * rbc_plugin_solver_settings_from). A def's defaults are here once, so that
 * rbc_*_def_init and a create given a def of an older size fill the same fields. */
#include <math.h>
#include <string.h>

#include "errors.h"
#include "rbcloth.h"
#include "world.h"

/* ------------------------------------------------------------------------- */
/* Reading a host's def                                                      */
/* ------------------------------------------------------------------------- */

/* Copy a def of a released size into a defaults-filled struct: the current size, or
 * the ABI 1.0 size `old_size` (0 if the struct had no other release), whose missing
 * fields keep their defaults. */
rbc_result rbc_plugin_read_def2(void *dst, size_t dst_size, size_t old_size, size_t old_size2,
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

/* ------------------------------------------------------------------------- */
/* Defaults                                                                  */
/* ------------------------------------------------------------------------- */

rbc_world_def rbc_plugin_world_def_defaults(void) {
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

rbc_cloth_def rbc_plugin_cloth_def_defaults(void) {
    rbc_cloth_def d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.vertex_mass = 1e-4f;
    d.stiffness = 1000.0f;
    return d;
}

rbc_collider_def rbc_plugin_collider_def_defaults(void) {
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
    rbc_world_def d = rbc_plugin_world_def_defaults();
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
    rbc_cloth_def d = rbc_plugin_cloth_def_defaults();
    /* Three released sizes: 1.0, 1.1-1.2 and this one. */
    if (struct_size == RBC_CLOTH_DEF_SIZE_V1_1)
        return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_CLOTH_DEF_SIZE_V1_1,
                                   "rbc_cloth_def_init", "rbc_cloth_def");
    return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_CLOTH_DEF_SIZE_V1_0,
                               "rbc_cloth_def_init",
                               "rbc_cloth_def");
}

RBC_API rbc_result RBC_CALL rbc_collider_def_init(rbc_collider_def *def, uint32_t struct_size) {
    rbc_collider_def d = rbc_plugin_collider_def_defaults();
    return rbc_def_init_common(def, struct_size, &d, sizeof d, RBC_COLLIDER_DEF_SIZE_V1_0,
                               "rbc_collider_def_init", "rbc_collider_def");
}

/* ------------------------------------------------------------------------- */
/* Solver defs and presets                                                   */
/* ------------------------------------------------------------------------- */

rbc_solver_def rbc_plugin_solver_def_defaults(void) {
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
rbc_solver_def rbc_plugin_solver_def_cloth(void) {
    rbc_solver_def d = rbc_plugin_solver_def_defaults();
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
    rbc_solver_def d = rbc_plugin_solver_def_defaults();
    return solver_def_fill(def, struct_size, &d, "rbc_solver_def_init");
}

RBC_API rbc_result RBC_CALL rbc_solver_def_preset(rbc_solver_def *def, uint32_t struct_size,
                                                  rbc_preset preset) {
    static const char fn[] = "rbc_solver_def_preset";
    rbc_solver_def d = rbc_plugin_solver_def_defaults();
    /* These presets need fields a 1.1-1.3 def does not have: the game preset its
     * target, the cloth preset its cap (max_substeps). */
    if ((preset == RBC_PRESET_GAME_60HZ || preset == RBC_PRESET_CLOTH) && def &&
        struct_size != sizeof d)
        return rbc_set_error(
            RBC_ERR_INVALID_ARGUMENT,
            "%s: %s needs the ABI 1.4 rbc_solver_def (struct_size %zu, got "
            "%u): its fields from target_strain on do not fit",
            fn, preset == RBC_PRESET_CLOTH ? "RBC_PRESET_CLOTH" : "RBC_PRESET_GAME_60HZ", sizeof d,
            struct_size);
    switch (preset) {
    case RBC_PRESET_PAPER:
        break;
    case RBC_PRESET_CLOTH:
        d = rbc_plugin_solver_def_cloth();
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

/* ------------------------------------------------------------------------- */
/* Validation                                                                */
/* ------------------------------------------------------------------------- */

/* Validate a solver def (already read at a released size) into core settings. */
rbc_result rbc_plugin_solver_settings_from(rbc_world *w, const char *fn, const rbc_solver_def *d,
                                           rbc_solver_settings *out) {
    if (d->solver < RBC_SOLVER_RBGS || d->solver > RBC_SOLVER_DIRECT)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: solver %d is not an rbc_solver_kind", fn,
                                      (int)d->solver);
    if (!(isfinite(d->omega) && d->omega >= 0.0f && d->omega < 2.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: omega is %g; it must be in (0, 2), or 0 for the optimal value", fn,
            (double)d->omega);
    if (!(isfinite(d->rho) && d->rho >= 0.0f && d->rho < 1.0f))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: rho is %g; it must be in (0, 1), or 0 to estimate it",
                                      fn, (double)d->rho);
    if (d->chebyshev_delay > 100000)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: chebyshev_delay is %u; at most 100000", fn,
                                      d->chebyshev_delay);
    if (d->mode < RBC_ITERATE_FIXED || d->mode > RBC_ITERATE_TARGET)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: mode %d is not an rbc_iteration_mode", fn, (int)d->mode);
    if (!(isfinite(d->tolerance) && d->tolerance > 0.0f))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: tolerance is %g; it must be finite and > 0", fn,
                                      (double)d->tolerance);
    if (!(isfinite(d->budget_ms) && d->budget_ms > 0.0f))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: budget_ms is %g; it must be finite and > 0", fn,
                                      (double)d->budget_ms);
    if (d->max_linear_iterations < 1 || d->max_linear_iterations > 100000)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: max_linear_iterations is %u; range 1..100000", fn,
                                      d->max_linear_iterations);
    if (d->energy_guard < RBC_ENERGY_GUARD_OFF || d->energy_guard > RBC_ENERGY_GUARD_FAIL)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: energy_guard %d is not an rbc_energy_guard", fn,
                                      (int)d->energy_guard);
    if (!(isfinite(d->target_strain) && d->target_strain > 0.0f))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: target_strain is %g; it must be finite and > 0 (an RMS "
                                      "relative strain, 0.05 = 5 %%)",
                                      fn, (double)d->target_strain);
    if (d->max_substeps < 1 || d->max_substeps > 1024)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: max_substeps is %u; range 1..1024", fn, d->max_substeps);
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
