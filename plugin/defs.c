/* defs.c -- the ABI's defs: their defaults, the *_def_init functions, the solver
 * presets, and what reads and checks a host's def for the other files (a def of any
 * released size, rbc_plugin_read_def, with the sizes each struct accepts in one table
 * per struct, rbc_sizes_*; a solver def into core settings,
 * rbc_plugin_solver_settings_from). A def's defaults are here once, so that
 * rbc_*_def_init and a create given a def of an older size fill the same fields. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "direct.h"
#include "errors.h"
#include "rbcloth.h"
#include "world.h"

/* ------------------------------------------------------------------------- */
/* Reading a host's def                                                      */
/* ------------------------------------------------------------------------- */

const rbc_struct_sizes rbc_sizes_world_def = {
    "rbc_world_def", 4,
    {sizeof(rbc_world_def), RBC_WORLD_DEF_SIZE_V1_6, RBC_WORLD_DEF_SIZE_V1_1, RBC_WORLD_DEF_SIZE_V1_0}};
const rbc_struct_sizes rbc_sizes_cloth_def = {
    "rbc_cloth_def", 3, {sizeof(rbc_cloth_def), RBC_CLOTH_DEF_SIZE_V1_1, RBC_CLOTH_DEF_SIZE_V1_0}};
const rbc_struct_sizes rbc_sizes_collider_def = {
    "rbc_collider_def", 2, {sizeof(rbc_collider_def), RBC_COLLIDER_DEF_SIZE_V1_0}};
const rbc_struct_sizes rbc_sizes_solver_def = {
    "rbc_solver_def", 3,
    {sizeof(rbc_solver_def), RBC_SOLVER_DEF_SIZE_V1_2, RBC_SOLVER_DEF_SIZE_V1_1}};
const rbc_struct_sizes rbc_sizes_cache_def = {
    "rbc_cache_def", 3, {sizeof(rbc_cache_def), RBC_CACHE_DEF_SIZE_V1_2, RBC_CACHE_DEF_SIZE_V1_0}};
const rbc_struct_sizes rbc_sizes_import_def = {
    "rbc_mesh_import_def", 3,
    {sizeof(rbc_mesh_import_def), RBC_MESH_IMPORT_DEF_SIZE_V1_8, RBC_MESH_IMPORT_DEF_SIZE_V1_2}};
const rbc_struct_sizes rbc_sizes_mesh_info = {
    "rbc_mesh_info", 2, {sizeof(rbc_mesh_info), RBC_MESH_INFO_SIZE_V1_2}};
const rbc_struct_sizes rbc_sizes_world_stats = {
    "rbc_world_stats", 7,
    {sizeof(rbc_world_stats), RBC_WORLD_STATS_SIZE_V1_5, RBC_WORLD_STATS_SIZE_V1_4,
     RBC_WORLD_STATS_SIZE_V1_3, RBC_WORLD_STATS_SIZE_V1_2, RBC_WORLD_STATS_SIZE_V1_1,
     RBC_WORLD_STATS_SIZE_V1_0}};

int rbc_size_known(const rbc_struct_sizes *s, uint32_t size) {
    for (uint32_t k = 0; k < s->count; ++k)
        if (size == s->size[k]) return 1;
    return 0;
}

void rbc_size_message(const rbc_struct_sizes *s, uint32_t size, const char *fn,
                      const char *where, char *buf, size_t cap) {
    int n = snprintf(buf, cap,
                     "%s: %s->struct_size is %u, which matches no released version of %s "
                     "(this library accepts %u, its own",
                     fn, where, size, s->name, s->size[0]);
    for (uint32_t k = 1; k < s->count && n > 0 && (size_t)n < cap; ++k)
        n += snprintf(buf + n, cap - (size_t)n, "%s%u", k == 1 ? ", and the older sizes " : ", ",
                      s->size[k]);
    if (n > 0 && (size_t)n < cap)
        snprintf(buf + n, cap - (size_t)n, "); set it to sizeof(%s)", s->name);
}

rbc_result rbc_size_refused(const rbc_struct_sizes *s, uint32_t size, const char *fn,
                            const char *where) {
    char msg[512];
    rbc_size_message(s, size, fn, where, msg, sizeof msg);
    return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s", msg);
}

/* Copy a def of a released size into a defaults-filled struct of s's current size;
 * the fields an older size lacks keep their defaults. */
rbc_result rbc_plugin_read_def(void *dst, const rbc_struct_sizes *s, const void *src,
                               const char *fn, const char *what) {
    if (!src) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: %s is NULL", fn, what);
    uint32_t size;
    memcpy(&size, src, sizeof size);
    if (!rbc_size_known(s, size)) return rbc_size_refused(s, size, fn, what);
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
                               const rbc_struct_sizes *s, const char *fn) {
    if (!def) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: def is NULL", fn);
    if (!rbc_size_known(s, struct_size)) return rbc_size_refused(s, struct_size, fn, "def");
    memcpy(def, defaults, struct_size);
    memcpy(def, &struct_size, sizeof struct_size);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_def_init(rbc_world_def *def, uint32_t struct_size) {
    rbc_world_def d = rbc_plugin_world_def_defaults();
    if (struct_size < RBC_WORLD_DEF_SIZE_V1_6) d.substeps = 1; /* what the 1.0-1.5 headers document */
    return rbc_def_init_common(def, struct_size, &d, &rbc_sizes_world_def, "rbc_world_def_init");
}

RBC_API rbc_result RBC_CALL rbc_cloth_def_init(rbc_cloth_def *def, uint32_t struct_size) {
    rbc_cloth_def d = rbc_plugin_cloth_def_defaults();
    return rbc_def_init_common(def, struct_size, &d, &rbc_sizes_cloth_def, "rbc_cloth_def_init");
}

RBC_API rbc_result RBC_CALL rbc_collider_def_init(rbc_collider_def *def, uint32_t struct_size) {
    rbc_collider_def d = rbc_plugin_collider_def_defaults();
    return rbc_def_init_common(def, struct_size, &d, &rbc_sizes_collider_def,
                               "rbc_collider_def_init");
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

static rbc_result solver_def_fill(rbc_solver_def *def, uint32_t struct_size,
                                  const rbc_solver_def *d, const char *fn) {
    return rbc_def_init_common(def, struct_size, d, &rbc_sizes_solver_def, fn);
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
    /* CHOLMOD is loaded here, on the first direct-solver def (core/cholmod_load.h):
     * a host without it hears so from rbc_world_create or rbc_world_set_solver,
     * with the world as it was, not from a later step. */
    char why[600];
    if (d->solver == RBC_SOLVER_DIRECT && !rbc_direct_available(why, sizeof why))
        return rbc_plugin_world_error(w, RBC_ERR_BACKEND_UNAVAILABLE, "%s: %s", fn, why);
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
