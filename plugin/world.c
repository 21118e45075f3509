/* world.c -- the ABI's worlds over core/'s solver: create, destroy, step (and the
 * warnings a step logs), iterations, gravity, solver settings, stats, and the calls
 * that act on the whole world (the collision and contact callbacks, picking, wind).
 * Also what every object's file uses: the world's error and log hook, and the world
 * lookup. Every function validates all of its input before it changes anything, so
 * a failing call leaves the world as it was. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "errors.h"
#include "handles.h"
#include "pick.h"
#include "registry.h"
#include "rbcloth.h"
#include "solver.h"
#include "strain.h"
#include "threads.h"
#include "world.h"
#include "backend_step.h"
#include "cuda.h"

#define RBC_MAX_WORLDS 1024u
#define RBC_MAX_THREADS 64u

/* Ids of worlds (registry.h); cloth.c and collider.c hold the cloths' and the
 * colliders'. */
static rbc_reg_entry g_world_entries[RBC_MAX_WORLDS];
rbc_registry rbc_plugin_worlds = RBC_REGISTRY_INIT(RBC_KIND_WORLD, RBC_MAX_WORLDS, g_world_entries);

/* ------------------------------------------------------------------------- */
/* Errors, logging and the world lookup                                      */
/* ------------------------------------------------------------------------- */

void rbc_plugin_world_log(rbc_world *w, rbc_log_level level, const char *msg) {
    if (w && w->def.log && level <= w->def.log_level) w->def.log(w->def.log_user, level, msg);
}

rbc_result rbc_plugin_world_error(rbc_world *w, rbc_result code, const char *fmt, ...) {
    char *buf = rbc_error_buffer();
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, RBC_ERROR_CAP, fmt, ap);
    va_end(ap);
    rbc_plugin_world_log(w, RBC_LOG_ERROR, buf);
    return code;
}

/* The world, stepping or not: step_wait and destroy. */
static rbc_result lookup_any(rbc_world_id id, const char *fn, rbc_world **out) {
    *out = rbc_reg_get(&rbc_plugin_worlds, id, 0, fn);
    return *out ? RBC_OK : RBC_ERR_STALE_HANDLE;
}

rbc_result rbc_plugin_lookup_world(rbc_world_id id, const char *fn, rbc_world **out) {
    rbc_result rc = lookup_any(id, fn, out);
    if (rc) return rc;
    if (atomic_load_explicit(&(*out)->stepping, memory_order_acquire)) {
        /* Not sent to the log hook: the step thread may be calling it right now, and
         * the hook was promised one thread at a time. */
        rbc_set_error(RBC_ERR_BUSY,
                      "%s: world 0x%08x is stepping (rbc_world_step_begin); nothing was "
                      "changed: call rbc_world_step_wait first",
                      fn, id);
        *out = NULL;
        return RBC_ERR_BUSY;
    }
    return RBC_OK;
}

rbc_result rbc_plugin_create_begin(rbc_world_id wid, const char *fn, uint32_t *out,
                                   const char *out_name, rbc_world **w) {
    rbc_result rc = rbc_plugin_lookup_world(wid, fn, w);
    if (rc) return rc;
    if (!out)
        return rbc_plugin_world_error(*w, RBC_ERR_INVALID_ARGUMENT, "%s: %s is NULL", fn,
                                      out_name);
    *out = 0;
    return RBC_OK;
}

rbc_result rbc_plugin_world_read_def(rbc_world *w, void *dst, const rbc_struct_sizes *s,
                                     const void *src, const char *fn, const char *what) {
    rbc_result rc = rbc_plugin_read_def(dst, s, src, fn, what);
    if (rc) rbc_plugin_world_log(w, RBC_LOG_ERROR, rbc_last_error());
    return rc;
}

/* ------------------------------------------------------------------------- */
/* World                                                                     */
/* ------------------------------------------------------------------------- */

static const char *solver_name(rbc_solver_kind k) {
    static const char *const names[] = {"rbgs",          "jacobi",         "jacobi_chebyshev",
                                        "gauss_seidel",  "rbgs_sor",       "rbgs_chebyshev",
                                        "multicolor_gs", "direct"};
    return k >= 0 && k <= RBC_SOLVER_DIRECT ? names[k] : "?";
}

/* substep_rate: the world's (> 0 lets substeps be 0: from the rate), or 0 for a world
 * made with a def older than 1.6. */
static rbc_result check_iterations(rbc_world *w, const char *fn, uint32_t substeps,
                                   uint32_t nonlinear, uint32_t linear, float substep_rate) {
    if (substeps == 0 && !(substep_rate > 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: substeps is 0, which takes them from the substep rate, but "
            "this world has none (substep_rate is a 1.6 field of rbc_world_def); "
            "range 1..1024",
            fn);
    if (substeps > 1024)
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: substeps is %u; range 1..1024, or 0 for the substep rate", fn, substeps);
    if (nonlinear < 1 || nonlinear > 1024)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: nonlinear_iterations is %u; range 1..1024", fn,
                                      nonlinear);
    if (linear < 1 || linear > 4096)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: linear_iterations is %u; range 1..4096", fn, linear);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_create(const rbc_world_def *user_def,
                                             rbc_world_id *out_world) {
    static const char fn[] = "rbc_world_create";
    if (!out_world) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: out_world is NULL", fn);
    *out_world = 0;
    rbc_world_def def = rbc_plugin_world_def_defaults();
    rbc_result rc = rbc_plugin_read_def(&def, &rbc_sizes_world_def, user_def, fn, "rbc_world_def");
    if (rc) return rc;
    /* A host built against a 1.0-1.5 header was promised the paper's fixed counts
     * when it leaves the solver NULL, and no strain warning; a 1.6 host gets the
     * default solve and the warning. */
    const int def_v16 = def.struct_size >= RBC_WORLD_DEF_SIZE_V1_6;
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
    if (!rbc_plugin_finite3(def.gravity))
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
    if (def.thread_count > RBC_MAX_THREADS)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: thread_count is %u; at most %u", fn,
                             def.thread_count, RBC_MAX_THREADS);
    if (def.log_level < RBC_LOG_ERROR || def.log_level > RBC_LOG_DEBUG)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: log_level %d is not an rbc_log_level",
                             fn, (int)def.log_level);
    if ((def.alloc == NULL) != (def.free == NULL))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: give both alloc and free hooks, or neither", fn);
    if ((def.enqueue_task == NULL) != (def.finish_task == NULL))
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: give both enqueue_task and finish_task, or neither", fn);
    const int hosted = def.enqueue_task != NULL;

    /* A given solver def starts from the field defaults, as rbc_solver_def_init's. */
    rbc_solver_def sdef =
        def_v16 && !def.solver ? rbc_plugin_solver_def_cloth() : rbc_plugin_solver_def_defaults();
    rbc_solver_settings settings;
    if (def.solver && (rc = rbc_plugin_read_def(&sdef, &rbc_sizes_solver_def, def.solver, fn,
                                                "rbc_world_def.solver")))
        return rc;
    if ((rc = rbc_plugin_solver_settings_from(NULL, fn, &sdef, &settings))) return rc;

    /* RBC_BACKEND_CUDA: the module and a device, then what the scene asks of it
     * (backend_step.h), before anything is made. RBC_BACKEND_AUTO is the CPU: the
     * scene size above which the GPU is faster has not been measured on a device
     * yet (docs/design/backends.md). */
    rbc_backend_handle dev = {NULL, NULL};
    if (def.backend == RBC_BACKEND_CUDA) {
        char why[768];
        rc = rbc_plugin_cuda_open(&dev, why, sizeof why);
        if (rc != RBC_OK)
            return rbc_set_error(rc, "%s: RBC_BACKEND_CUDA is unavailable: %s; use "
                                 "RBC_BACKEND_CPU or RBC_BACKEND_AUTO", fn, why);
        char err[512];
        if ((rc = rbc_backend_settings_check(&settings, dev.ops->name, err, sizeof err))) {
            dev.ops->close(dev.be);
            return rbc_set_error(rc, "%s: %s", fn, err);
        }
    }

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
    if (!w) {
        if (dev.ops) dev.ops->close(dev.be);
        return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: out of memory", fn);
    }
    w->alloc = alloc;
    w->def = def;
    /* On the host's job system the world starts no thread: its pool has one, and
     * the host's workers join it (core/cpu/pool.c, run_hosted). */
    if (rbc_solver_init(&w->solver, &alloc, hosted ? 1 : threads) != RBC_OK) {
        rbc_mem_free(&alloc, w, sizeof *w);
        if (dev.ops) dev.ops->close(dev.be);
        return rbc_set_error(RBC_ERR_OUT_OF_MEMORY, "%s: could not start %u worker threads", fn,
                             threads);
    }
    if (dev.ops) rbc_solver_set_backend(&w->solver, &dev); /* the solver closes it */
    /* thread_count 0: the step measures whether its threads pay (core/step_threads.c,
     * threads_for_step); a count the host gives is used as given. */
    /* On the host's job system too: thread_count 0 asks for every item or none,
     * whichever the probes measure faster. */
    w->solver.threads_auto = def.thread_count == 0;
    if (hosted) {
        const rbc_pool_host h = {(void *(*)(rbc_pool_task_fn, uint32_t, uint32_t, void *,
                                            void *))def.enqueue_task,
                                 (void (*)(void *, void *))def.finish_task, def.task_user};
        rbc_pool_set_host(w->solver.pool, &h, threads);
    }
    if (rbc_reg_add(&rbc_plugin_worlds, w, 0, &w->id) != RBC_OK) {
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
    char msg[320];
    if (dev.ops)
        snprintf(msg, sizeof msg, "world 0x%08x created: CUDA backend, %.200s", w->id,
                 dev.ops->describe(dev.be));
    else
        snprintf(msg, sizeof msg, "world 0x%08x created: CPU backend, %u threads%s", w->id,
                 threads, hosted ? " on the host's job system" : "");
    rbc_plugin_world_log(w, RBC_LOG_INFO, msg);
    return RBC_OK;
}

static void step_thread_stop(rbc_world *w);

RBC_API rbc_result RBC_CALL rbc_world_destroy(rbc_world_id id) {
    rbc_world *w;
    rbc_result rc = lookup_any(id, "rbc_world_destroy", &w);
    if (rc) return rc;
    /* A step in flight finishes first (its result is dropped), then the thread goes. */
    step_thread_stop(w);
    rbc_solver *sol = &w->solver;
    for (uint32_t k = 0; k < sol->cloth_count; ++k)
        rbc_reg_remove(&rbc_plugin_cloths, sol->cloths[k]->public_id);
    for (uint32_t k = 0; k < sol->collider_count; ++k)
        rbc_reg_remove(&rbc_plugin_colliders, sol->colliders[k].public_id);
    rbc_reg_remove(&rbc_plugin_worlds, id);
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

/* A step of a world whose dt was checked, on the calling thread (rbc_world_step's) or
 * on the world's step thread (rbc_world_step_begin's); fn names the call for the
 * messages. */
static rbc_result step_now(rbc_world *w, float dt, const char *fn) {
    char msg[RBC_ERROR_CAP - 64];
    rbc_result rc = rbc_solver_step(&w->solver, dt, msg, sizeof msg);
    if (rc) return rbc_plugin_world_error(w, rc, "%s: world 0x%08x: %s", fn, w->id, msg);
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
        rbc_plugin_world_log(w, RBC_LOG_WARNING, note);
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
        rbc_plugin_world_log(w, RBC_LOG_WARNING, note);
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
        rbc_plugin_world_log(w, RBC_LOG_WARNING, note);
    }
    return RBC_OK;
}

static rbc_result check_dt(rbc_world *w, const char *fn, float dt) {
    if (isfinite(dt) && dt > 0.0f) return RBC_OK;
    return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                  "%s: dt is %g s; it must be finite and > 0", fn, (double)dt);
}

RBC_API rbc_result RBC_CALL rbc_world_step(rbc_world_id id, float dt) {
    static const char fn[] = "rbc_world_step";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if ((rc = check_dt(w, fn, dt))) return rc;
    return step_now(w, dt, fn);
}

/* ------------------------------------------------------------------------- */
/* The split step (1.10)                                                     */
/* ------------------------------------------------------------------------- */

/* One thread per world that has used rbc_world_step_begin, asleep between steps. A
 * mutex and condition variable hand it a dt and hand back the result; a step costs
 * two wake-ups, microseconds against a step's milliseconds. */
enum { STEP_IDLE, STEP_RUN, STEP_DONE };
typedef struct rbc_step_thread {
    rbc_thread thread;
    rbc_mutex mu;
    rbc_cond cv;
    int state, quit;
    uint32_t waiters; /* step_wait calls inside step_thread_wait */
    float dt;
    rbc_result rc;
    char msg[RBC_ERROR_CAP];
} rbc_step_thread;

static void step_thread_main(void *arg) {
    rbc_world *w = arg;
    rbc_step_thread *t = w->stepper;
    rbc_mutex_lock(&t->mu);
    for (;;) {
        while (t->state != STEP_RUN && !t->quit) rbc_cond_wait(&t->cv, &t->mu);
        if (t->quit) break;
        const float dt = t->dt;
        rbc_mutex_unlock(&t->mu);
        const rbc_result rc = step_now(w, dt, "rbc_world_step_begin");
        rbc_mutex_lock(&t->mu);
        t->rc = rc;
        /* The message is in this thread's buffer; step_wait hands it to its own. */
        if (rc) snprintf(t->msg, sizeof t->msg, "%s", rbc_last_error());
        t->state = STEP_DONE;
        rbc_cond_broadcast(&t->cv);
    }
    rbc_mutex_unlock(&t->mu);
}

/* Wait for the step in flight, if any, and take its result: its message becomes this
 * thread's (under the lock, before `stepping` is cleared: once it is, the host may
 * begin the next step, whose thread writes t->msg). A step another thread already
 * took the result of is RBC_OK here. `waiters` lets destroy free the thread only
 * when no wait is inside. */
static rbc_result step_thread_wait(rbc_world *w) {
    rbc_step_thread *t = w->stepper;
    if (!t || !atomic_load(&w->stepping)) return RBC_OK;
    rbc_mutex_lock(&t->mu);
    t->waiters++;
    while (t->state == STEP_RUN) rbc_cond_wait(&t->cv, &t->mu);
    rbc_result rc = RBC_OK;
    if (t->state == STEP_DONE) {
        rc = t->rc;
        if (rc) rbc_set_error(rc, "%s", t->msg);
        t->state = STEP_IDLE;
        atomic_store_explicit(&w->stepping, 0, memory_order_release);
    }
    if (--t->waiters == 0) rbc_cond_broadcast(&t->cv);
    rbc_mutex_unlock(&t->mu);
    return rc;
}

/* The thread's record, once no thread runs on it (stopped, or never started). */
static void step_thread_free(rbc_world *w) {
    rbc_step_thread *t = w->stepper;
    rbc_mutex_destroy(&t->mu);
    rbc_cond_destroy(&t->cv);
    rbc_mem_free(&w->alloc, t, sizeof *t);
    w->stepper = NULL;
}

static void step_thread_stop(rbc_world *w) {
    rbc_step_thread *t = w->stepper;
    if (!t) return;
    step_thread_wait(w);
    rbc_mutex_lock(&t->mu);
    while (t->waiters) rbc_cond_wait(&t->cv, &t->mu);
    t->quit = 1;
    rbc_cond_broadcast(&t->cv);
    rbc_mutex_unlock(&t->mu);
    rbc_thread_join(&t->thread);
    step_thread_free(w);
}

RBC_API rbc_result RBC_CALL rbc_world_step_begin(rbc_world_id id, float dt) {
    static const char fn[] = "rbc_world_step_begin";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if ((rc = check_dt(w, fn, dt))) return rc;
    if (!w->stepper) {
        rbc_step_thread *t = rbc_mem_alloc(&w->alloc, sizeof *t);
        if (!t)
            return rbc_plugin_world_error(w, RBC_ERR_OUT_OF_MEMORY,
                                          "%s: world 0x%08x: out of memory for its step thread",
                                          fn, w->id);
        rbc_mutex_init(&t->mu);
        rbc_cond_init(&t->cv);
        t->state = STEP_IDLE;
        w->stepper = t;
        if (rbc_thread_create(&t->thread, step_thread_main, w) != 0) {
            step_thread_free(w);
            return rbc_plugin_world_error(w, RBC_ERR_OUT_OF_MEMORY,
                                          "%s: world 0x%08x: could not start its step thread",
                                          fn, w->id);
        }
    }
    rbc_step_thread *t = w->stepper;
    /* stepping before the thread can run: the host's next call already sees it. */
    atomic_store_explicit(&w->stepping, 1, memory_order_release);
    rbc_mutex_lock(&t->mu);
    t->dt = dt;
    t->state = STEP_RUN;
    rbc_cond_broadcast(&t->cv);
    rbc_mutex_unlock(&t->mu);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_step_wait(rbc_world_id id) {
    static const char fn[] = "rbc_world_step_wait";
    rbc_world *w;
    rbc_result rc = lookup_any(id, fn, &w);
    if (rc) return rc;
    /* The step thread logged a failure already; step_thread_wait made its message
     * this thread's. */
    return step_thread_wait(w);
}

RBC_API rbc_result RBC_CALL rbc_world_set_iterations(rbc_world_id id, uint32_t substeps,
                                                     uint32_t nonlinear, uint32_t linear) {
    static const char fn[] = "rbc_world_set_iterations";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
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
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!gravity)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: gravity is NULL", fn);
    if (!rbc_plugin_finite3(gravity))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: gravity (%g, %g, %g) is not finite", fn,
                                      (double)gravity[0], (double)gravity[1], (double)gravity[2]);
    memcpy(w->solver.gravity, gravity, 3 * sizeof(float));
    for (uint32_t k = 0; k < w->solver.cloth_count; ++k) /* a new potential: recompute E */
        rbc_cloth_state_energy_invalidate(w->solver.cloths[k], 1);
    return RBC_OK;
}


RBC_API rbc_result RBC_CALL rbc_world_stats_init(rbc_world_stats *stats, uint32_t struct_size) {
    static const char fn[] = "rbc_world_stats_init";
    if (!stats) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: stats is NULL", fn);
    if (!rbc_size_known(&rbc_sizes_world_stats, struct_size))
        return rbc_size_refused(&rbc_sizes_world_stats, struct_size, fn, "stats");
    memset(stats, 0, struct_size);
    stats->struct_size = struct_size;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_get_stats(rbc_world_id id, rbc_world_stats *out) {
    static const char fn[] = "rbc_world_get_stats";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!out) return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: stats is NULL", fn);
    if (!rbc_size_known(&rbc_sizes_world_stats, out->struct_size)) {
        char msg[512];
        rbc_size_message(&rbc_sizes_world_stats, out->struct_size, fn, "stats", msg, sizeof msg);
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s", msg);
    }
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
    st.backend = s->backend.ops ? RBC_BACKEND_CUDA : RBC_BACKEND_CPU;
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

/* The collision callback (1.0) and the contact callback (1.3): the same lookup and
 * the same failure (the buffers the core hands the callback); `contact` says which
 * of the two is set. */
static rbc_result set_callback(rbc_world_id id, const char *fn, int contact,
                               rbc_collision_fn collision_fn, rbc_contact_fn contact_fn,
                               void *user) {
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    rc = contact ? rbc_solver_set_contact_callback(&w->solver, contact_fn, user)
                 : rbc_solver_set_callback(&w->solver, collision_fn, user);
    if (rc)
        return rbc_plugin_world_error(w, rc, "%s: out of memory for the callback's buffers", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_set_collision_callback(rbc_world_id id, rbc_collision_fn fn_,
                                                             void *user) {
    return set_callback(id, "rbc_world_set_collision_callback", 0, fn_, NULL, user);
}

/* ------------------------------------------------------------------------- */
/* ABI 1.1: solvers                                                          */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_world_set_solver(rbc_world_id id, const rbc_solver_def *user_def) {
    static const char fn[] = "rbc_world_set_solver";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    rbc_solver_def def = rbc_plugin_solver_def_defaults();
    if ((rc = rbc_plugin_world_read_def(w, &def, &rbc_sizes_solver_def, user_def, fn,
                                        "rbc_solver_def")))
        return rc;
    rbc_solver_settings st;
    if ((rc = rbc_plugin_solver_settings_from(w, fn, &def, &st))) return rc;
    if (w->solver.backend.ops) { /* what the world's backend does not run is refused here */
        char err[512];
        rc = rbc_backend_settings_check(&st, w->solver.backend.ops->name, err, sizeof err);
        if (rc) return rbc_plugin_world_error(w, rc, "%s: %s", fn, err);
    }
    if ((rc = rbc_solver_set_settings(&w->solver, &st)))
        return rbc_plugin_world_error(w, rc, "%s: out of memory for the solver's buffers", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_world_get_solver(rbc_world_id id, rbc_solver_def *out) {
    static const char fn[] = "rbc_world_get_solver";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!out) return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: def is NULL", fn);
    if (!rbc_size_known(&rbc_sizes_solver_def, out->struct_size)) {
        char msg[512];
        rbc_size_message(&rbc_sizes_solver_def, out->struct_size, fn, "def", msg, sizeof msg);
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s", msg);
    }
    const rbc_solver_settings *st = &w->solver.settings;
    rbc_solver_def d = rbc_plugin_solver_def_defaults();
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

/* ------------------------------------------------------------------------- */
/* ABI 1.3: host contacts, picking, wind                                     */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_world_set_contact_callback(rbc_world_id id, rbc_contact_fn fn_,
                                                           void *user) {
    return set_callback(id, "rbc_world_set_contact_callback", 1, NULL, fn_, user);
}

RBC_API rbc_result RBC_CALL rbc_world_pick(rbc_world_id id, const float origin[3],
                                           const float dir[3], float max_distance, float radius,
                                           rbc_cloth_id *out_cloth, uint32_t *out_vertex,
                                           float *out_t) {
    static const char fn[] = "rbc_world_pick";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!origin || !dir || !out_cloth)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: origin, dir or out_cloth is NULL", fn);
    *out_cloth = 0;
    if (!rbc_plugin_finite3(origin) || !rbc_plugin_finite3(dir) ||
        !(dir[0] != 0.0f || dir[1] != 0.0f || dir[2] != 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: origin (%g, %g, %g) and dir (%g, %g, %g) must be finite and dir "
            "non-zero",
            fn, (double)origin[0], (double)origin[1], (double)origin[2], (double)dir[0],
            (double)dir[1], (double)dir[2]);
    if (!(max_distance >= 0.0f) || !(radius >= 0.0f) || !isfinite(radius))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
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

RBC_API rbc_result RBC_CALL rbc_world_set_wind(rbc_world_id id, const float velocity[3], float drag,
                                               float lift) {
    static const char fn[] = "rbc_world_set_wind";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(id, fn, &w);
    if (rc) return rc;
    if (!velocity || !rbc_plugin_finite3(velocity))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: velocity is NULL or not finite", fn);
    if (!(isfinite(drag) && drag >= 0.0f) || !(isfinite(lift) && lift >= 0.0f))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: drag %g and lift %g must be finite and >= 0", fn,
                                      (double)drag, (double)lift);
    memcpy(w->solver.wind, velocity, sizeof w->solver.wind);
    w->solver.wind_drag = drag;
    w->solver.wind_lift = lift;
    return RBC_OK;
}
