/* accuracy.c -- `rbcloth bench accuracy`: the paper's two convergence
 * experiments (Sec. 5.1, Figs. 3 and 4) for every global solver of ABI 1.1.
 *
 *   stretched  the 100 x 100 grid started 1.5x larger in its plane, gravity 0,
 *              integration disabled (damping = 1/h: Alg. 2's velocity term is 0, so
 *              each frame's inertial target is the previous positions), no pins.
 *   hanging    the default scene: 100 x 100 in the xz plane, pins 0 and 99, gravity,
 *              no damping, h = 2 ms.
 *
 * Per scene and solver: Eq. 7 per frame at 11 linear iterations per frame (Figs.
 * 3/4 top) and within a 2 ms budget (bottom); a sweep of budgets and of fixed
 * substeps x iterations (final Eq. 7, median ms and iterations per frame, a Pareto
 * front); and the fraction of the Projective Dynamics objective gap left after one
 * step, (F - F*) / (F0 - F*), against an exact reference step. Host-side
 * recomputations of Eq. 7, the PD objective and the linear residual check the
 * library's stats on the way.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "fsutil.h"
#include "scene.h"

enum { MAX_SCENES = 4, MAX_GAP_FRAMES = 3 };

/* ------------------------------------------------------------------------- */
/* Scenes                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct acc_scene {
    char name[40];
    const char *title;
    bench_mesh mesh;
    float gravity[3];
    float dt;
    /// Start positions (3n floats), NULL = the rest positions.
    float *start;
    /// Only the gap at 11 iterations is measured (the cross-check of docs/facts.md, Convergence).
    int gap_only;
    uint32_t frames;
    /// Sum of squared rest lengths, m^2: Eq. 7 above it means an rms strain above 1
    /// (springs on average twice their length or collapsed): the run diverged.
    double sum_rest2;
} acc_scene;

/* How the linear iterations of one run are controlled. */
typedef struct acc_control {
    /// "iter11", "budget" or "fixed".
    const char *label;
    int budget;
    double budget_ms;
    uint32_t substeps, nonlinear, linear;
} acc_control;

/* One run's outcome. */
typedef struct acc_result {
    int available;
    uint32_t frames_done;
    uint32_t unstable_steps;
    /// Final Eq. 7 above the scene's sum_rest2 (or not finite).
    int diverged;
    double final_eq7;
    double median_ms;
    double median_iterations;
} acc_result;

/* A row of the sweep, kept for the Pareto table. */
typedef struct sweep_row {
    uint32_t scene, solver;
    acc_control control;
    acc_result result;
} sweep_row;

typedef struct acc_ctx {
    bench_run run;
    uint32_t threads;
    uint32_t frames;
    acc_scene scenes[MAX_SCENES];
    uint32_t scene_count;
    int available[BENCH_SOLVER_COUNT];
    char unavailable_why[BENCH_SOLVER_COUNT][256];
    uint32_t gap_frames[MAX_GAP_FRAMES];
    uint32_t gap_count;
    /// The reference of the gap measure: "direct x30" or the RBGS fallback.
    char reference[96];
    rbc_solver_def reference_def;
    uint32_t reference_nonlinear;
    /// The exact linear solve (one reference step per gap row, with the solver's own
    /// non-linear iteration count).
    rbc_solver_def linear_def;
    FILE *iter_csv, *budget_csv, *sweep_csv, *gap_csv;
    /* Scratch: the state before a step, after it, the reference's, y. */
    float *x, *q, *p, *ref_p;
    double *y;
    /* Summary: [scene][solver]. */
    double eq7_iter11[MAX_SCENES][BENCH_SOLVER_COUNT];
    double eq7_budget[MAX_SCENES][BENCH_SOLVER_COUNT];
    double its_budget[MAX_SCENES][BENCH_SOLVER_COUNT];
    double ms_iter11[MAX_SCENES][BENCH_SOLVER_COUNT];
    double gap[MAX_SCENES][BENCH_SOLVER_COUNT][MAX_GAP_FRAMES];
    double gap_linear[MAX_SCENES][BENCH_SOLVER_COUNT][MAX_GAP_FRAMES];
    sweep_row *rows;
    size_t row_count, row_cap;
    double load_start;
    /// Disagreements between the library's stats and the host's recomputation.
    uint32_t stats_mismatches;
} acc_ctx;

static int out_of_memory(void) { return bench_out_of_memory("accuracy"); }

static int build_scenes(acc_ctx *ctx) {
    rbc_scene sc;
    char err[RBC_SCENE_ERROR_MAX];
    if (rbc_scene_load_paper(&sc, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return 1;
    }
    int rc = 0;
    /* Fig. 3: stretched 1.5x about the centroid (the grid is planar, so this is in
     * its plane), no gravity, no pins, damping 1/h. */
    acc_scene *s = &ctx->scenes[ctx->scene_count++];
    snprintf(s->name, sizeof s->name, "stretched");
    s->title = "stretched 1.5x, shrinking (Fig. 3)";
    if (bench_mesh_from_scene(&sc, &s->mesh))
        rc = out_of_memory();
    s->mesh.pin_count = 0;
    s->mesh.damping = 1.0f / sc.dt;
    s->dt = sc.dt;
    s->frames = ctx->frames;
    if (!rc && bench_mesh_finish(&s->mesh))
        rc = out_of_memory();
    if (!rc) {
        s->start = malloc((size_t)s->mesh.n * 3 * sizeof *s->start);
        if (!s->start)
            rc = out_of_memory();
    }
    if (!rc) {
        double c[3] = {0, 0, 0};
        for (uint32_t i = 0; i < s->mesh.n; ++i)
            for (int a = 0; a < 3; ++a)
                c[a] += s->mesh.rest[3 * (size_t)i + a] / (double)s->mesh.n;
        for (uint32_t i = 0; i < s->mesh.n; ++i)
            for (int a = 0; a < 3; ++a) {
                size_t k = 3 * (size_t)i + a;
                s->start[k] = (float)(c[a] + 1.5 * ((double)s->mesh.rest[k] - c[a]));
            }
    }

    /* Fig. 4: the default scene as it is. */
    if (!rc) {
        s = &ctx->scenes[ctx->scene_count++];
        snprintf(s->name, sizeof s->name, "hanging");
        s->title = "hanging cloth (Fig. 4)";
        if (bench_mesh_from_scene(&sc, &s->mesh))
            rc = out_of_memory();
        memcpy(s->gravity, sc.world.gravity, sizeof s->gravity);
        s->dt = sc.dt;
        s->frames = ctx->frames;
    }

    /* The convergence experiment of docs/facts.md: the hanging cloth at h = 1/60 with
     * k h^2/m = 10 and 100 (gap after 11 iterations only). */
    static const double ratios[2] = {10.0, 100.0};
    for (int k = 0; !rc && !ctx->run.opt->quick && k < 2; ++k) {
        s = &ctx->scenes[ctx->scene_count++];
        snprintf(s->name, sizeof s->name, "hanging_h60_khm%g", ratios[k]);
        s->title = "hanging cloth, h = 1/60 s";
        if (bench_mesh_from_scene(&sc, &s->mesh)) {
            rc = out_of_memory();
            break;
        }
        memcpy(s->gravity, sc.world.gravity, sizeof s->gravity);
        s->dt = 1.0f / 60.0f;
        s->mesh.stiffness =
            (float)(ratios[k] * s->mesh.vertex_mass / ((double)s->dt * (double)s->dt));
        s->gap_only = 1;
        s->frames = 121;
    }
    for (uint32_t k = 0; !rc && k < ctx->scene_count; ++k) {
        acc_scene *t = &ctx->scenes[k];
        for (uint32_t q = 0; q < t->mesh.spring_count; ++q)
            t->sum_rest2 += t->mesh.rest_len[q] * t->mesh.rest_len[q];
    }
    rbc_scene_free(&sc);
    return rc;
}

/* ------------------------------------------------------------------------- */
/* Worlds                                                                    */
/* ------------------------------------------------------------------------- */

static rbc_result make_world(acc_ctx *ctx, const acc_scene *s, const rbc_solver_def *solver,
                             uint32_t substeps, uint32_t nonlinear, uint32_t linear,
                             rbc_world_id *world, rbc_cloth_id *cloth) {
    const rbc_api_v1 *api = ctx->run.api;
    bench_world_config cfg;
    if (bench_world_config_init(api, &cfg))
        return RBC_ERR_INVALID_ARGUMENT;
    memcpy(cfg.gravity, s->gravity, sizeof cfg.gravity);
    cfg.substeps = substeps;
    cfg.nonlinear_iterations = nonlinear;
    cfg.linear_iterations = linear;
    cfg.threads = ctx->threads;
    cfg.solver = *solver;
    rbc_result r = bench_world_create(api, &s->mesh, &cfg, world, cloth);
    if (r == RBC_OK && s->start) {
        r = api->cloth_set_state(*world, *cloth, s->start, NULL);
        if (r != RBC_OK) {
            api->world_destroy(*world);
            *world = 0;
        }
    }
    return r;
}

static rbc_solver_def solver_def(const acc_ctx *ctx, uint32_t solver, const acc_control *c) {
    rbc_solver_def d;
    ctx->run.api->solver_def_init(&d, (uint32_t)sizeof d);
    d.solver = bench_solvers[solver].kind;
    /* The solvers themselves are measured: the energy guard (on by default) would
     * scale velocities where Chebyshev or SOR overshoot and so change their error;
     * its effect is what `rbcloth bench stability` shows. */
    d.energy_guard = RBC_ENERGY_GUARD_OFF;
    if (c && c->budget) {
        d.mode = RBC_ITERATE_BUDGET;
        d.budget_ms = (float)c->budget_ms;
        d.max_linear_iterations = 100000; /* let the budget decide */
    }
    return d;
}

/* Which solvers this plugin supports: a 3 x 3 cloth stepped once with each. */
static void probe_solvers(acc_ctx *ctx) {
    const rbc_api_v1 *api = ctx->run.api;
    acc_scene probe;
    memset(&probe, 0, sizeof probe);
    if (bench_mesh_grid(&probe.mesh, 3, 3, 0.1, 0, 0.0) || bench_mesh_finish(&probe.mesh)) {
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k)
            ctx->available[k] = 1;
        bench_mesh_free(&probe.mesh);
        return;
    }
    probe.gravity[1] = -9.81f;
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
        rbc_solver_def d = solver_def(ctx, k, NULL);
        rbc_world_id w;
        rbc_cloth_id c;
        rbc_result r = make_world(ctx, &probe, &d, 1, 1, 11, &w, &c);
        if (r == RBC_OK) {
            r = api->world_step(w, 0.002f);
            if (r != RBC_OK)
                bench_result_text(api, r, ctx->unavailable_why[k], sizeof ctx->unavailable_why[k]);
            api->world_destroy(w);
        } else {
            bench_result_text(api, r, ctx->unavailable_why[k], sizeof ctx->unavailable_why[k]);
        }
        ctx->available[k] = r == RBC_OK;
        if (r != RBC_OK)
            fprintf(stderr, "rbcloth: bench: solver %s is not available (%s); skipped\n",
                    bench_solvers[k].name, ctx->unavailable_why[k]);
    }
    bench_mesh_free(&probe.mesh);
}

/* The gap reference: the direct solver with 30 non-linear iterations, or, without
 * it, RBGS to a relative residual of 1e-7 (at most 5000 iterations) x 30. */
static void choose_reference(acc_ctx *ctx) {
    const rbc_api_v1 *api = ctx->run.api;
    ctx->reference_nonlinear = 30;
    api->solver_def_init(&ctx->reference_def, (uint32_t)sizeof ctx->reference_def);
    if (ctx->available[RBC_SOLVER_DIRECT]) {
        ctx->reference_def.solver = RBC_SOLVER_DIRECT;
        snprintf(ctx->reference, sizeof ctx->reference, "direct_x30");
    } else {
        ctx->reference_def.solver = RBC_SOLVER_RBGS;
        ctx->reference_def.mode = RBC_ITERATE_TOLERANCE;
        ctx->reference_def.tolerance = 1e-7f;
        ctx->reference_def.max_linear_iterations = 5000;
        snprintf(ctx->reference, sizeof ctx->reference, "rbgs_tol1e-7_max5000_x30");
    }
    ctx->linear_def = ctx->reference_def;
}

/* ------------------------------------------------------------------------- */
/* One run                                                                   */
/* ------------------------------------------------------------------------- */

static int is_gap_frame(const acc_ctx *ctx, uint32_t frame, uint32_t *slot) {
    for (uint32_t k = 0; k < ctx->gap_count; ++k)
        if (ctx->gap_frames[k] == frame) {
            *slot = k;
            return 1;
        }
    return 0;
}

/* Relative difference, for stats checks. */
static double rel_diff(double a, double b) {
    double scale = fmax(fabs(a), fabs(b));
    return scale > 0.0 ? fabs(a - b) / scale : 0.0;
}

static void stats_mismatch(acc_ctx *ctx, const char *what, const acc_scene *s, uint32_t solver,
                           uint32_t frame, double library, double host) {
    ++ctx->stats_mismatches;
    if (ctx->stats_mismatches <= 20)
        fprintf(stderr,
                "rbcloth: bench: stats check: %s %s frame %u: library %s = %.9g, host "
                "recomputation %.9g\n",
                s->name, bench_solvers[solver].name, frame, what, library, host);
}

/* Step a fresh world of solver `def` once from the state (ctx->x, ctx->q); its
 * positions into p, its stats into *st. */
static int reference_step(acc_ctx *ctx, const acc_scene *s, const rbc_solver_def *def,
                          uint32_t substeps, uint32_t nonlinear, float *p, rbc_world_stats *st) {
    const rbc_api_v1 *api = ctx->run.api;
    rbc_world_id rw;
    rbc_cloth_id rc;
    acc_scene at_state = *s;
    at_state.start = NULL;
    rbc_result r = make_world(ctx, &at_state, def, substeps, nonlinear, 11, &rw, &rc);
    if (r != RBC_OK)
        return bench_report(api, r, "(creating a reference world)");
    r = api->cloth_set_state(rw, rc, ctx->x, ctx->q);
    if (r == RBC_OK)
        r = api->world_step(rw, s->dt);
    if (r == RBC_OK)
        r = bench_stats(api, rw, st);
    if (r == RBC_OK)
        r = api->cloth_get_state(rw, rc, p, NULL, 3 * (size_t)s->mesh.n);
    api->world_destroy(rw);
    if (r != RBC_OK)
        return bench_report(api, r, "(stepping a reference world)");
    return 0;
}

/* The gap row for the step that just took the solver's world from (x, q) to p. */
static int measure_gap(acc_ctx *ctx, const acc_scene *s, uint32_t scene, uint32_t solver,
                       const acc_control *c, uint32_t frame, uint32_t slot,
                       const rbc_world_stats *st, rbc_world_id world, rbc_cloth_id cloth) {
    const rbc_api_v1 *api = ctx->run.api;
    const bench_mesh *m = &s->mesh;
    size_t n3 = 3 * (size_t)m->n;
    double h = (double)s->dt / c->substeps;
    rbc_result r = api->cloth_get_state(world, cloth, ctx->p, NULL, n3);
    if (r != RBC_OK)
        return bench_report(api, r, "(reading the state after a step)");

    /* Pins do not move in these scenes: their targets are their rest positions. */
    bench_inertial_target(m, ctx->x, ctx->q, h, s->gravity, m->rest, ctx->y);
    double f0 = bench_pd_objective(m, ctx->y, ctx->y, NULL, h);
    double f = bench_pd_objective(m, ctx->y, NULL, ctx->p, h);
    double eq7 = bench_eq7(m, ctx->p);
    double residual_floor = 0.0;
    double residual = c->substeps == 1 && c->nonlinear == 1
                          ? bench_linear_residual(m, ctx->y, ctx->p, h, &residual_floor)
                          : NAN;

    /* F*: a fresh world of the reference solver at the same state, stepped once;
     * F_lin*: the same with the exact linear solve and the solver's own non-linear
     * iteration count (what the linear iterations alone can reach). */
    rbc_world_stats rst, lst;
    int rc = reference_step(ctx, s, &ctx->reference_def, c->substeps, ctx->reference_nonlinear,
                            ctx->ref_p, &rst);
    if (rc)
        return rc;
    double fstar = bench_pd_objective(m, ctx->y, NULL, ctx->ref_p, h);
    rc = reference_step(ctx, s, &ctx->linear_def, c->substeps, c->nonlinear, ctx->ref_p, &lst);
    if (rc)
        return rc;
    double flin = bench_pd_objective(m, ctx->y, NULL, ctx->ref_p, h);
    double gap = (f - fstar) / (f0 - fstar);
    double gap_linear = (f - flin) / (f0 - flin);

    /* Stats checks. Eq. 7 is a double sum over the same float positions on both
     * sides (1e-6 relative covers the summation order). The PD objective's inertial
     * term I = sum m/(2h^2) |p - y|^2 depends on y, which the library holds in float
     * (each coordinate within half an ulp, 2^-24 Y, Y = max |y|): by Cauchy-Schwarz
     * |dI| <= sqrt(3) 2^-24 Y sqrt(sum m / h^2) sqrt(2 I); its spring term may use
     * float lengths (bench_spring_energy_rounding). The residual agrees to 1e-3
     * relative plus the float floor of its evaluation (bench_linear_residual). */
    double ymax = 0.0, mass = bench_free_mass(m);
    for (size_t k = 0; k < n3; ++k)
        ymax = fmax(ymax, fabs(ctx->y[k]));
    double dy = ldexp(ymax, -24), w = sqrt(mass / (h * h));
    double inertial = fmax(0.0, f - bench_spring_energy(m, ctx->p));
    double inertial_star = fmax(0.0, fstar - bench_spring_energy(m, ctx->ref_p));
    double f_tol = 1e-9 * fabs(f) + sqrt(3.0) * dy * w * sqrt(2.0 * inertial) +
                   bench_spring_energy_rounding(m, ctx->p);
    double fstar_tol = 1e-9 * fabs(fstar) + sqrt(3.0) * dy * w * sqrt(2.0 * inertial_star) +
                       bench_spring_energy_rounding(m, ctx->ref_p);
    double residual_tol = 1e-3 * fabs(residual) + residual_floor;
    if (rel_diff(st->error_eq7, eq7) > 1e-6)
        stats_mismatch(ctx, "error_eq7", s, solver, frame + 1, st->error_eq7, eq7);
    if (fabs(st->pd_objective - f) > f_tol)
        stats_mismatch(ctx, "pd_objective", s, solver, frame + 1, st->pd_objective, f);
    if (isfinite(residual) && fabs(st->linear_residual - residual) > residual_tol)
        stats_mismatch(ctx, "linear_residual", s, solver, frame + 1, st->linear_residual,
                       residual);

    fprintf(ctx->gap_csv,
            "%s,%s,%s,%u,%u,%.12g,%.12g,%.12g,%.9g,%s,%.12g,%.12g,%.9g,%.9g,%.9g,%.9g,%.12g,%.9g,"
            "%.3g,%.3g,%.3g\n",
            s->name, bench_solvers[solver].name, c->label, frame, st->linear_iterations, f0, f,
            fstar, gap, ctx->reference, st->pd_objective, rst.pd_objective, eq7, st->error_eq7,
            residual, st->linear_residual, flin, gap_linear, f_tol, fstar_tol, residual_tol);
    if (c->budget == 0 && c->linear == 11 && c->substeps == 1) {
        ctx->gap[scene][solver][slot] = gap;
        ctx->gap_linear[scene][solver][slot] = gap_linear;
    }
    return 0;
}

/* Run `frames` steps of scene s with a solver under control c. series: the per-frame
 * CSV (NULL for none); gaps: measure the gap at ctx->gap_frames. */
static int run_one(acc_ctx *ctx, uint32_t scene, uint32_t solver, const acc_control *c,
                   uint32_t frames, FILE *series, int gaps, acc_result *out) {
    const rbc_api_v1 *api = ctx->run.api;
    const acc_scene *s = &ctx->scenes[scene];
    memset(out, 0, sizeof *out);
    out->final_eq7 = NAN;
    if (!ctx->available[solver])
        return 0;
    out->available = 1;
    rbc_solver_def d = solver_def(ctx, solver, c);
    rbc_world_id world;
    rbc_cloth_id cloth;
    rbc_result r = make_world(ctx, s, &d, c->substeps, c->nonlinear, c->linear, &world, &cloth);
    if (r != RBC_OK)
        return bench_report(api, r, "(creating a bench world)");
    double *ms = malloc((frames ? frames : 1) * sizeof *ms);
    double *its = malloc((frames ? frames : 1) * sizeof *its);
    if (!ms || !its) {
        free(ms);
        free(its);
        api->world_destroy(world);
        return out_of_memory();
    }
    size_t n3 = 3 * (size_t)s->mesh.n;
    int rc = 0;
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    for (uint32_t frame = 0; frame < frames && !rc; ++frame) {
        uint32_t slot = 0;
        int gap_here = gaps && is_gap_frame(ctx, frame, &slot);
        if (gap_here) {
            r = api->cloth_get_state(world, cloth, ctx->x, ctx->q, n3);
            if (r != RBC_OK) {
                rc = bench_report(api, r, "(reading the state before a step)");
                break;
            }
        }
        r = api->world_step(world, s->dt);
        if (r == RBC_ERR_UNSTABLE) {
            /* The library restored the state: stepping again fails the same way. */
            ++out->unstable_steps;
            fprintf(stderr, "rbcloth: bench: %s %s (%s): step %u returned RBC_ERR_UNSTABLE: %s\n",
                    s->name, bench_solvers[solver].name, c->label, frame + 1, api->last_error());
            break;
        }
        if (r != RBC_OK) {
            rc = bench_report(api, r, "(stepping a bench world)");
            break;
        }
        r = bench_stats(api, world, &st);
        if (r != RBC_OK) {
            rc = bench_report(api, r, "(reading stats)");
            break;
        }
        const char *bad = NULL;
        if (!bench_stats_finite(&st, &bad))
            fprintf(stderr, "rbcloth: bench: LIBRARY BUG: %s %s frame %u: stats.%s is not finite\n",
                    s->name, bench_solvers[solver].name, frame + 1, bad);
        ms[frame] = st.step_ms;
        its[frame] = st.linear_iterations;
        out->frames_done = frame + 1;
        out->final_eq7 = st.error_eq7;
        if (series && c->budget)
            fprintf(series, "%s,%s,%u,%g,%.9g,%u,%.9g,%.9g,%.6f\n", s->name,
                    bench_solvers[solver].name, frame + 1, c->budget_ms, st.error_eq7,
                    st.linear_iterations, st.linear_residual, st.pd_objective, st.step_ms);
        else if (series)
            fprintf(series, "%s,%s,%u,%.9g,%.9g,%.9g,%.6f\n", s->name, bench_solvers[solver].name,
                    frame + 1, st.error_eq7, st.linear_residual, st.pd_objective, st.step_ms);
        if (gap_here)
            rc = measure_gap(ctx, s, scene, solver, c, frame, slot, &st, world, cloth);
    }
    /* The final Eq. 7 once more from the host's own positions. */
    if (!rc && out->frames_done > 0) {
        r = api->cloth_get_state(world, cloth, ctx->p, NULL, n3);
        if (r == RBC_OK) {
            long bad = bench_first_nonfinite(ctx->p, n3);
            if (bad >= 0)
                fprintf(stderr, "rbcloth: bench: LIBRARY BUG: %s %s: position %ld is not finite\n",
                        s->name, bench_solvers[solver].name, bad / 3);
            double eq7 = bench_eq7(&s->mesh, ctx->p);
            if (rel_diff(eq7, out->final_eq7) > 1e-4)
                stats_mismatch(ctx, "error_eq7", s, solver, out->frames_done, out->final_eq7, eq7);
        }
    }
    out->median_ms = bench_median(ms, out->frames_done);
    out->median_iterations = bench_median(its, out->frames_done);
    out->diverged = !(out->final_eq7 <= s->sum_rest2);
    free(ms);
    free(its);
    api->world_destroy(world);
    return rc;
}

static int add_row(acc_ctx *ctx, uint32_t scene, uint32_t solver, const acc_control *c,
                   const acc_result *res) {
    sweep_row *rows = bench_grow(ctx->rows, &ctx->row_cap, ctx->row_count, sizeof *rows, 64);
    if (!rows)
        return out_of_memory();
    ctx->rows = rows;
    sweep_row *row = &ctx->rows[ctx->row_count++];
    row->scene = scene;
    row->solver = solver;
    row->control = *c;
    row->result = *res;
    fprintf(ctx->sweep_csv, "%s,%s,%s,%g,%u,%u,%u,%u,%.9g,%.6f,%g,%u,%d\n", ctx->scenes[scene].name,
            bench_solvers[solver].name, c->budget ? "budget" : "fixed", c->budget ? c->budget_ms : 0.0,
            c->substeps, c->nonlinear, c->budget ? 0 : c->linear, res->frames_done, res->final_eq7,
            res->median_ms, res->median_iterations, res->unstable_steps, res->diverged);
    return 0;
}

/* ------------------------------------------------------------------------- */
/* The experiments                                                           */
/* ------------------------------------------------------------------------- */

static const double full_budgets[] = {0.1, 0.2, 0.5, 1, 2, 5, 10, 20};
static const double quick_budgets[] = {0.5, 2};
/* substeps x linear iterations of the fixed sweep */
static const uint32_t full_fixed[][2] = {{1, 1},  {1, 2}, {1, 5}, {1, 11}, {1, 22},
                                          {1, 50}, {1, 100}, {2, 5}, {4, 3}, {11, 1}};
static const uint32_t quick_fixed[][2] = {{1, 1}, {1, 11}};

static int run_scene(acc_ctx *ctx, uint32_t scene) {
    const acc_scene *s = &ctx->scenes[scene];
    int rc = 0;
    const acc_control iter11 = {"iter11", 0, 0.0, 1, 1, 11};
    const acc_control budget2 = {"budget", 1, 2.0, 1, 1, 11};
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT && !rc; ++k) {
        acc_result res;
        fprintf(stderr, "rbcloth: bench accuracy: %s, %s ...\n", s->name, bench_solvers[k].name);
        rc = run_one(ctx, scene, k, &iter11, s->frames, s->gap_only ? NULL : ctx->iter_csv, 1, &res);
        ctx->eq7_iter11[scene][k] = res.final_eq7;
        ctx->ms_iter11[scene][k] = res.median_ms;
        if (rc || s->gap_only)
            continue;
        rc = run_one(ctx, scene, k, &budget2, s->frames, ctx->budget_csv, 1, &res);
        ctx->eq7_budget[scene][k] = res.final_eq7;
        ctx->its_budget[scene][k] = res.median_iterations;
        if (!rc && res.available)
            rc = add_row(ctx, scene, k, &budget2, &res);

        const double *budgets = ctx->run.opt->quick ? quick_budgets : full_budgets;
        size_t nb = ctx->run.opt->quick ? sizeof quick_budgets / sizeof quick_budgets[0]
                                    : sizeof full_budgets / sizeof full_budgets[0];
        for (size_t b = 0; b < nb && !rc && bench_solvers[k].iterative; ++b) {
            /* 2 ms: the run above; the direct solver has no iterations to budget. */
            if (budgets[b] == 2.0)
                continue;
            acc_control c = {"budget", 1, budgets[b], 1, 1, 11};
            rc = run_one(ctx, scene, k, &c, s->frames, NULL, 0, &res);
            if (!rc && res.available)
                rc = add_row(ctx, scene, k, &c, &res);
        }
        const uint32_t(*fixed)[2] = ctx->run.opt->quick ? quick_fixed : full_fixed;
        size_t nf = ctx->run.opt->quick ? sizeof quick_fixed / sizeof quick_fixed[0]
                                    : sizeof full_fixed / sizeof full_fixed[0];
        uint32_t last_substeps = 0;
        for (size_t f = 0; f < nf && !rc; ++f) {
            /* The direct solver has no linear iterations: one run per substep count. */
            if (!bench_solvers[k].iterative && fixed[f][0] == last_substeps)
                continue;
            last_substeps = fixed[f][0];
            acc_control c = {"fixed", 0, 0.0, fixed[f][0], 1, fixed[f][1]};
            rc = run_one(ctx, scene, k, &c, s->frames, NULL, 0, &res);
            if (!rc && res.available)
                rc = add_row(ctx, scene, k, &c, &res);
        }
    }
    return rc;
}

/* ------------------------------------------------------------------------- */
/* Pareto table                                                              */
/* ------------------------------------------------------------------------- */

static int row_valid(const sweep_row *r) {
    return r->result.available && r->result.unstable_steps == 0 && !r->result.diverged &&
           r->result.frames_done > 0;
}

static int dominated(const acc_ctx *ctx, size_t i) {
    const sweep_row *a = &ctx->rows[i];
    for (size_t j = 0; j < ctx->row_count; ++j) {
        const sweep_row *b = &ctx->rows[j];
        if (j == i || b->scene != a->scene || !row_valid(b))
            continue;
        if (b->result.median_ms <= a->result.median_ms &&
            b->result.final_eq7 <= a->result.final_eq7 &&
            (b->result.median_ms < a->result.median_ms ||
             b->result.final_eq7 < a->result.final_eq7))
            return 1;
    }
    return 0;
}

static const sweep_row *g_sort_rows;
static int cmp_row_ms(const void *a, const void *b) {
    const sweep_row *x = &g_sort_rows[*(const size_t *)a], *y = &g_sort_rows[*(const size_t *)b];
    return x->result.median_ms < y->result.median_ms ? -1 : x->result.median_ms > y->result.median_ms;
}

static void config_text(const sweep_row *r, char *buf, size_t size) {
    const acc_control *c = &r->control;
    if (c->budget && bench_solvers[r->solver].iterative) {
        snprintf(buf, size, "budget %g ms (%g it)", c->budget_ms, r->result.median_iterations);
        return;
    }
    if (!bench_solvers[r->solver].iterative)
        snprintf(buf, size, "%u substep%s, exact solve", c->substeps, c->substeps == 1 ? "" : "s");
    else
        snprintf(buf, size, "%u x %u", c->substeps, c->linear);
}

static int write_pareto(acc_ctx *ctx) {
    size_t *order;
    FILE *f = bench_open_ordered(ctx->run.dir, "pareto.md", "accuracy", ctx->row_count, &order);
    if (!f)
        return 1;
    fprintf(f, "# Accuracy against time: Pareto front per scene\n\n");
    fprintf(f,
            "Every run of the sweep (budgets of RBC_ITERATE_BUDGET and fixed substeps x linear "
            "iterations, one non-linear iteration) over %u frames of 2 ms. **front** marks the "
            "runs that no other run beats on both median ms per frame and final Eq. 7; "
            "*diverged* marks runs whose final Eq. 7 exceeds the sum of squared rest lengths "
            "(rms strain > 1: the cloth blew up without a non-finite value, so no "
            "RBC_ERR_UNSTABLE). In the hanging scene Eq. 7 does not go to 0: gravity stretches "
            "the cloth, and the converged implicit step (direct, 11 substeps) sets the floor.\n",
            ctx->frames);
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        if (ctx->scenes[sc].gap_only)
            continue;
        size_t n = 0;
        for (size_t i = 0; i < ctx->row_count; ++i)
            if (ctx->rows[i].scene == sc)
                order[n++] = i;
        g_sort_rows = ctx->rows;
        qsort(order, n, sizeof *order, cmp_row_ms);
        fprintf(f, "\n## %s: %s\n\n", ctx->scenes[sc].name, ctx->scenes[sc].title);
        fprintf(f, "| solver | substeps x iterations | median ms/frame | median iterations | final Eq. 7 (m^2) | Pareto |\n");
        fprintf(f, "|---|---|---:|---:|---:|---|\n");
        for (size_t k = 0; k < n; ++k) {
            const sweep_row *r = &ctx->rows[order[k]];
            char cfg[96];
            config_text(r, cfg, sizeof cfg);
            const char *mark = r->result.unstable_steps ? "unstable (RBC_ERR_UNSTABLE)"
                               : r->result.diverged ? "diverged (rms strain > 1)"
                               : dominated(ctx, order[k]) ? ""
                                                          : "**front**";
            fprintf(f, "| %s | %s | %.3f | %g | %.3e | %s |\n", bench_solvers[r->solver].name, cfg,
                    r->result.median_ms, r->result.median_iterations, r->result.final_eq7, mark);
        }
    }
    free(order);
    return bench_close(f, ctx->run.dir, "pareto.md") ? 1 : 0;
}

/* ------------------------------------------------------------------------- */
/* Plots                                                                     */
/* ------------------------------------------------------------------------- */

static const char *const solver_colors[BENCH_SOLVER_COUNT] = {
    "#d62728", "#1f77b4", "#17becf", "#7f7f7f", "#ff7f0e", "#9467bd", "#2ca02c", "#000000"};

static void gp_header(FILE *f, const char *png, int width, int height) {
    fprintf(f, "# Generated by `rbcloth bench accuracy`; run `gnuplot %s` in this directory.\n",
            "<script>");
    fprintf(f, "set terminal pngcairo size %d,%d font 'sans,10'\n", width, height);
    fprintf(f, "set output '%s'\n", png);
    fprintf(f, "set datafile separator ','\n");
    fprintf(f, "set grid lc rgb '#dddddd'\n");
    fprintf(f, "set key inside opaque box lc rgb '#bbbbbb' spacing 1.1 font ',9'\n");
    for (int k = 0; k < BENCH_SOLVER_COUNT; ++k)
        fprintf(f, "set linetype %d lc rgb '%s' lw 2 pt %d ps 0.8\n", k + 1, solver_colors[k], 5 + k % 4 * 2);
}

/* One scene's panel of a log-log error plot: title, key, y range up to 4x the
 * divergence ceiling (the sum of squared rest lengths, rms strain 1), and the ceiling
 * drawn as a dashed line with `label`. Returns the ceiling. */
static double gp_scene_panel(FILE *f, const acc_scene *scene, const char *label) {
    double ceiling = scene->sum_rest2;
    fprintf(f, "set title '%s'\nset key bottom left\n", scene->title);
    fprintf(f, "set yrange [*:%g]\nunset arrow\nunset label\n", 4.0 * ceiling);
    fprintf(f, "set arrow from graph 0, first %g to graph 1, first %g nohead dt 2 lc rgb '#888888'\n",
            ceiling, ceiling);
    fprintf(f, "set label '%s' at graph 0.98, first %g right offset 0,0.7 font ',8' tc rgb '#666666'\n",
            label, ceiling);
    return ceiling;
}

/* Eq. 7 against frame for the two paper scenes: one panel each. */
static void gp_series(acc_ctx *ctx, FILE *f, const char *csv, int eq7_col, int budget) {
    fprintf(f, "set multiplot layout 1,2 title '%s'\n",
            budget ? "Eq. 7 error per frame within a 2 ms budget per frame (median iterations in the key)"
                   : "Eq. 7 error per frame at 11 linear iterations per frame");
    fprintf(f, "set logscale y\nset format y '10^{%%L}'\nset xlabel 'frame (h = 2 ms)'\n"
               "set ylabel 'Eq. 7 error (m^2)'\n");
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        if (ctx->scenes[sc].gap_only)
            continue;
        /* A diverged run is cut at 4x the divergence line (Eq. 7 = sum L^2, rms
         * strain 1) instead of stretching the axis to 1e70. */
        double ceiling = ctx->scenes[sc].sum_rest2;
        fprintf(f, "set title '%s'\n", ctx->scenes[sc].title);
        fprintf(f, "set key %s\n", sc == 0 ? "bottom left" : "bottom right");
        fprintf(f, "set yrange [*:%g]\nunset arrow\nunset label\n", 4.0 * ceiling);
        fprintf(f, "set arrow from graph 0, first %g to graph 1, first %g nohead dt 2 lc rgb '#888888'\n",
                ceiling, ceiling);
        fprintf(f, "set label 'diverged above (rms strain > 1)' at graph 0.02, first %g left offset 0,0.7 font ',8' tc rgb '#666666'\n",
                ceiling);
        fprintf(f, "plot ");
        int first = 1;
        for (int k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            if (!ctx->available[k])
                continue;
            char title[96];
            if (budget && bench_solvers[k].iterative)
                snprintf(title, sizeof title, "%s (%g it)", bench_solvers[k].name, ctx->its_budget[sc][k]);
            else
                snprintf(title, sizeof title, "%s", bench_solvers[k].name);
            fprintf(f, "%s'%s' using (strcol(1) eq '%s' && strcol(2) eq '%s' ? $3 : NaN):%d with lines lt %d title '%s' noenhanced",
                    first ? "" : ", \\\n     ", csv, ctx->scenes[sc].name, bench_solvers[k].name, eq7_col, k + 1,
                    title);
            first = 0;
        }
        fprintf(f, "\n");
    }
    fprintf(f, "unset multiplot\n");
}

static int write_plots(acc_ctx *ctx) {
    static const char *const scripts[] = {"accuracy_iterations.gp", "accuracy_budget.gp",
                                          "accuracy_sweep.gp", "accuracy_pareto.gp"};
    /* Eq. 7 per frame (eq7_col of the CSV): at fixed iterations, and within a budget. */
    static const struct {
        const char *png, *csv;
        int eq7_col, budget;
    } series[] = {{"accuracy_iterations.png", "accuracy_iterations.csv", 4, 0},
                  {"accuracy_budget.png", "accuracy_budget.csv", 5, 1}};
    FILE *f;
    for (int k = 0; k < 2; ++k) {
        if (!(f = bench_open(ctx->run.dir, scripts[k])))
            return 1;
        gp_header(f, series[k].png, 1400, 520);
        gp_series(ctx, f, series[k].csv, series[k].eq7_col, series[k].budget);
        if (bench_close(f, ctx->run.dir, scripts[k]))
            return 1;
    }

    /* Final Eq. 7 against budget, log-log, median iterations next to each point. */
    if (!(f = bench_open(ctx->run.dir, scripts[2])))
        return 1;
    gp_header(f, "accuracy_sweep.png", 1400, 560);
    fprintf(f, "set multiplot layout 1,2 title 'Final Eq. 7 error after %u frames against the time budget per frame (labels: median linear iterations per frame)'\n",
            ctx->frames);
    fprintf(f, "set logscale xy\nset format y '10^{%%L}'\nset xlabel 'budget per frame (ms)'\n"
               "set ylabel 'final Eq. 7 error (m^2)'\nset xrange [0.07:30]\n");
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        if (ctx->scenes[sc].gap_only)
            continue;
        double ceiling = gp_scene_panel(f, &ctx->scenes[sc],
                                        "diverged (rms strain > 1): plotted on this line");
        fprintf(f, "plot ");
        int first = 1;
        for (int k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            if (!ctx->available[k])
                continue;
            const char *sel = "strcol(1) eq '%s' && strcol(2) eq '%s' && strcol(3) eq 'budget'";
            char cond[256], yexpr[64];
            snprintf(cond, sizeof cond, sel, ctx->scenes[sc].name, bench_solvers[k].name);
            snprintf(yexpr, sizeof yexpr, "($13 > 0 ? %g : $9)", ceiling);
            fprintf(f, "%s'accuracy_sweep.csv' using (%s ? $4 : NaN):%s with linespoints lt %d title '%s' noenhanced",
                    first ? "" : ", \\\n     ", cond, yexpr, k + 1, bench_solvers[k].name);
            if (bench_solvers[k].iterative)
                fprintf(f, ", \\\n     'accuracy_sweep.csv' using (%s ? $4 : NaN):%s:(sprintf('%%d', int($11))) with labels offset 0.6,0.5 font ',7' tc lt %d notitle",
                        cond, yexpr, k + 1);
            first = 0;
        }
        fprintf(f, "\n");
    }
    fprintf(f, "unset multiplot\n");
    if (bench_close(f, ctx->run.dir, scripts[2]))
        return 1;

    /* Every run: final Eq. 7 against median ms per frame (the time to reach an error). */
    if (!(f = bench_open(ctx->run.dir, scripts[3])))
        return 1;
    gp_header(f, "accuracy_pareto.png", 1400, 560);
    fprintf(f, "set multiplot layout 1,2 title 'Final Eq. 7 error against median ms per frame, every run of the sweep (lower left is better)'\n");
    fprintf(f, "set logscale xy\nset format y '10^{%%L}'\nset xlabel 'median ms per frame'\n"
               "set ylabel 'final Eq. 7 error (m^2)'\n");
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        if (ctx->scenes[sc].gap_only)
            continue;
        double ceiling = gp_scene_panel(f, &ctx->scenes[sc], "diverged");
        fprintf(f, "plot ");
        int first = 1;
        for (int k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            if (!ctx->available[k])
                continue;
            fprintf(f, "%s'accuracy_sweep.csv' using (strcol(1) eq '%s' && strcol(2) eq '%s' ? $10 : NaN):($13 > 0 ? %g : $9) with points lt %d title '%s' noenhanced",
                    first ? "" : ", \\\n     ", ctx->scenes[sc].name, bench_solvers[k].name, ceiling,
                    k + 1, bench_solvers[k].name);
            first = 0;
        }
        fprintf(f, "\n");
    }
    fprintf(f, "unset multiplot\n");
    if (bench_close(f, ctx->run.dir, scripts[3]))
        return 1;

    if (bench_gnuplot_or_say(ctx->run.dir,
                             "Plots skipped: gnuplot is not on PATH. The scripts are in %s; "
                             "install gnuplot (Debian: apt-get install gnuplot-nox) and run "
                             "`gnuplot SCRIPT.gp` there.\n"))
        for (size_t k = 0; k < sizeof scripts / sizeof scripts[0]; ++k)
            bench_plot_run(ctx->run.dir, scripts[k]);
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Summary                                                                   */
/* ------------------------------------------------------------------------- */

static void print_summary(const acc_ctx *ctx) {
    printf("\nAccuracy bench: %u frames of 2 ms per scene, 10,000 particles / 19,800 springs; "
           "gap reference %s\n",
           ctx->frames, ctx->reference);
    printf("Load average %.2f at the start, %.2f at the end (timings assume an otherwise idle "
           "machine)\n",
           ctx->load_start, bench_load_average());
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        const acc_scene *s = &ctx->scenes[sc];
        if (s->gap_only)
            continue;
        printf("\n%s: %s\n", s->name, s->title);
        printf("  %-17s %13s %11s %13s %9s", "solver", "Eq7 @ 11 it", "ms @ 11 it", "Eq7 @ 2 ms",
               "it/2 ms");
        for (uint32_t g = 0; g < ctx->gap_count; ++g)
            printf("  gap@%-3u (lin)", ctx->gap_frames[g]);
        printf("\n");
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            if (!ctx->available[k]) {
                printf("  %-17s not available: %s\n", bench_solvers[k].name, ctx->unavailable_why[k]);
                continue;
            }
            printf("  %-17s %13.4e %11.3f %13.4e %9g", bench_solvers[k].name, ctx->eq7_iter11[sc][k],
                   ctx->ms_iter11[sc][k], ctx->eq7_budget[sc][k], ctx->its_budget[sc][k]);
            for (uint32_t g = 0; g < ctx->gap_count; ++g)
                printf("  %6.3f (%5.3f)", ctx->gap[sc][k][g], ctx->gap_linear[sc][k][g]);
            printf("\n");
        }
    }
    printf("\ngap@f: fraction of the PD objective gap left by one step from the solver's own "
           "state at frame f, (F - F*) / (F0 - F*), F* = %s; (lin): the same against the exact "
           "linear solve with the same single non-linear iteration\n",
           ctx->reference);
    int extra = 0;
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc)
        extra |= ctx->scenes[sc].gap_only;
    if (extra) {
        printf("\nFraction of the PD objective gap left after 11 iterations, hanging cloth at "
               "h = 1/60 s (cross-check of docs/facts.md)\n");
        printf("  %-17s", "solver");
        for (uint32_t sc = 0; sc < ctx->scene_count; ++sc)
            if (ctx->scenes[sc].gap_only)
                for (uint32_t g = 0; g < ctx->gap_count; ++g) {
                    char head[48];
                    snprintf(head, sizeof head, "%s@%u", ctx->scenes[sc].name + strlen("hanging_h60_"),
                             ctx->gap_frames[g]);
                    printf(" %12s", head);
                }
        printf("\n");
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            if (!ctx->available[k])
                continue;
            printf("  %-17s", bench_solvers[k].name);
            for (uint32_t sc = 0; sc < ctx->scene_count; ++sc)
                if (ctx->scenes[sc].gap_only)
                    for (uint32_t g = 0; g < ctx->gap_count; ++g)
                        printf(" %12.4f", ctx->gap[sc][k][g]);
            printf("\n");
        }
    }
    if (ctx->stats_mismatches)
        printf("\n%u disagreement%s between the library's stats and the host's recomputation "
               "(see stderr)\n",
               ctx->stats_mismatches, ctx->stats_mismatches == 1 ? "" : "s");
}

/* ------------------------------------------------------------------------- */

static void ctx_free(acc_ctx *ctx) {
    for (uint32_t sc = 0; sc < ctx->scene_count; ++sc) {
        bench_mesh_free(&ctx->scenes[sc].mesh);
        free(ctx->scenes[sc].start);
    }
    free(ctx->x);
    free(ctx->q);
    free(ctx->p);
    free(ctx->ref_p);
    free(ctx->y);
    free(ctx->rows);
    FILE *files[] = {ctx->iter_csv, ctx->budget_csv, ctx->sweep_csv, ctx->gap_csv};
    for (size_t k = 0; k < 4; ++k)
        if (files[k])
            fclose(files[k]);
}

int cli_bench_accuracy(const cli_plugin *plugin, const cli_bench_options *options) {
    if (bench_require_v1_1(plugin))
        return 1;
    acc_ctx ctx = {.run = bench_run_of(plugin, options)};
    ctx.threads = options->threads >= 0 ? (uint32_t)options->threads : 0;
    ctx.frames = options->frames > 0 ? (uint32_t)options->frames : options->quick ? 20u : 240u;
    static const uint32_t full_gaps[] = {10, 60, 120}, quick_gaps[] = {5, 10};
    const uint32_t *gaps = options->quick ? quick_gaps : full_gaps;
    uint32_t ng = options->quick ? 2 : 3;
    for (uint32_t g = 0; g < ng; ++g)
        if (gaps[g] < ctx.frames)
            ctx.gap_frames[ctx.gap_count++] = gaps[g];

    if (fs_mkdir_p_or_say(ctx.run.dir))
        return 1;
    double start = bench_now();
    ctx.load_start = bench_load_average();
    int rc = build_scenes(&ctx);
    if (!rc) {
        size_t n3 = 3 * (size_t)ctx.scenes[0].mesh.n;
        ctx.x = malloc(n3 * sizeof *ctx.x);
        ctx.q = malloc(n3 * sizeof *ctx.q);
        ctx.p = malloc(n3 * sizeof *ctx.p);
        ctx.ref_p = malloc(n3 * sizeof *ctx.ref_p);
        ctx.y = malloc(n3 * sizeof *ctx.y);
        if (!ctx.x || !ctx.q || !ctx.p || !ctx.ref_p || !ctx.y)
            rc = out_of_memory();
    }
    if (!rc) {
        for (uint32_t sc = 0; sc < ctx.scene_count; ++sc)
            for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
                ctx.eq7_iter11[sc][k] = ctx.eq7_budget[sc][k] = ctx.its_budget[sc][k] = NAN;
                ctx.ms_iter11[sc][k] = NAN;
                for (uint32_t g = 0; g < MAX_GAP_FRAMES; ++g)
                    ctx.gap[sc][k][g] = ctx.gap_linear[sc][k][g] = NAN;
            }
        ctx.iter_csv = bench_open_csv(
            ctx.run.dir, "accuracy_iterations.csv",
            "scene,solver,frame,eq7,linear_residual,pd_objective,step_ms");
        ctx.budget_csv = bench_open_csv(
            ctx.run.dir, "accuracy_budget.csv",
            "scene,solver,frame,budget_ms,eq7,linear_iterations,linear_residual,pd_objective,"
            "step_ms");
        ctx.sweep_csv = bench_open_csv(
            ctx.run.dir, "accuracy_sweep.csv",
            "scene,solver,control,budget_ms,substeps,nonlinear_iterations,linear_iterations,"
            "frames,final_eq7,median_step_ms,median_linear_iterations,unstable_steps,diverged");
        ctx.gap_csv = bench_open_csv(
            ctx.run.dir, "accuracy_gap.csv",
            "scene,solver,mode,frame,linear_iterations,F0,F,F_star,gap,reference,F_library,"
            "F_star_library,eq7_host,eq7_library,residual_host,residual_library,F_linear_star,"
            "gap_linear,F_tolerance,F_star_tolerance,residual_tolerance");
        if (!ctx.iter_csv || !ctx.budget_csv || !ctx.sweep_csv || !ctx.gap_csv)
            rc = 1;
    }
    if (!rc) {
        probe_solvers(&ctx);
        choose_reference(&ctx);
        if (!ctx.available[RBC_SOLVER_DIRECT])
            fprintf(stderr, "rbcloth: bench: the direct solver is not available: the gap "
                            "reference is %s\n", ctx.reference);
    }
    for (uint32_t sc = 0; sc < ctx.scene_count && !rc; ++sc)
        rc = run_scene(&ctx, sc);
    if (!rc) {
        const char *names[] = {"accuracy_iterations.csv", "accuracy_budget.csv",
                               "accuracy_sweep.csv", "accuracy_gap.csv"};
        FILE **files[] = {&ctx.iter_csv, &ctx.budget_csv, &ctx.sweep_csv, &ctx.gap_csv};
        for (size_t k = 0; k < 4; ++k) {
            if (bench_close(*files[k], ctx.run.dir, names[k]))
                rc = 1;
            *files[k] = NULL;
        }
    }
    if (!rc)
        rc = write_pareto(&ctx) || write_plots(&ctx);
    if (!rc) {
        print_summary(&ctx);
        printf("\nWrote accuracy_iterations.csv, accuracy_budget.csv, accuracy_sweep.csv, "
               "accuracy_gap.csv, pareto.md and plots in %s (%.1f s)\n",
               ctx.run.dir, bench_now() - start);
    }
    ctx_free(&ctx);
    return rc;
}
