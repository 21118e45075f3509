/* peers.c -- `rbcloth bench peers`: rbcloth's configurations on the peer scene
 * of docs/facts.md ("The peer scene"), against the peers' figures
 * (issue 7).
 *
 * The peer scene is the built-in default scene (samples/scene.c): 100 x 100
 * hanging cloth, L = 1/99 m, 1e-4 kg per vertex, k = 1000 N/m, h = 2 ms, no damping,
 * pins at vertices 0 and 99, 500 frames; E = Eq. 7 over all 19,800 springs at the
 * last frame; whole-step ms per frame on one thread.
 *
 * The sweep measures substeps x non-linear x linear iterations x solver (RBGS,
 * RBGS+SOR, RBGS+Chebyshev, Jacobi+Chebyshev, direct) in two passes: a coarse grid
 * (every product substeps x non-linear x linear up to a cost cap), then rounds of
 * refinement around the Pareto front (neighbouring counts; SOR's omega and
 * Chebyshev's rho for the front's iterative rows) until the front stops changing.
 * Every row runs the library's default energy guard (clamp); the front's rows whose
 * guard clamped are run again with it off, and one energy probe (guard off, the
 * state read every frame) says whether the clamped solver really added energy.
 * Warm starts are not an axis: the library starts every linear solve from the
 * Verlet prediction y (core/solver.c, phase_integrate: p = y) and offers no other
 * choice.
 *
 * Per row: the median over frames of stats.step_ms and of its stages, Eq. 7 at the
 * last frame from the library's stats and from the host's recomputation on the
 * positions it reads back, the largest strain, the guard's clamps, and whether the
 * row is on the Pareto front (ms per frame against E: no other row is at least as
 * fast and at least as accurate, and better in one). The final positions of every
 * row (--quick) or of the front's rows are written as raw float32 (x y z per vertex,
 * host order) under peers_positions/ID.f32, so a checker can recompute E itself.
 * Outputs: peers.csv, peers.md, peers.gp and peers.png (gnuplot) in DIR.
 */
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "fsutil.h"
#include "scene.h"

/// The target of issue 7: E at the last frame and ms per frame (one thread).
#define PEERS_TARGET_E 1.45e-5
#define PEERS_TARGET_MS 0.3
/// Most linear iterations per frame (substeps x non-linear x linear) in the coarse
/// grid: 48 keep a row near 1.5 ms here, 5x the target and far from the peers'.
#define PEERS_COARSE_CAP 48u
/// A coarse series (more linear iterations, or more substeps) stops past this many
/// ms per frame: the target is 0.3 ms and the peers' best 7 ms.
#define PEERS_COARSE_MS 2.0
/// The refinement looks only at front rows faster than this (ms per frame): beyond
/// it only the direct solver and the peers are drawn.
#define PEERS_REFINE_MS 1.5
enum { PEERS_MAX_ROUNDS = 4 };

/* The peers, as docs/facts.md gives them (built and run elsewhere, one thread,
 * ranges over 3 runs). */
typedef struct peer_figure {
    const char *name;
    const char *config;
    double ms_lo, ms_hi, eq7;
} peer_figure;

static const peer_figure peer_figures[] = {
    {"ShapeOp", "PD, prefactored Cholesky, double", 15.0, 17.0, 2.5e-5},
    {"Liu 2013", "fast mass-springs, Cholesky, float", 18.0, 22.0, 1.0e-4},
    {"XPBD 1x11", "Bender PBD, 1 substep x 11 iterations", 4.5, 5.5, 6.1e-3},
    {"XPBD 11x1", "Bender PBD, 11 substeps x 1 iteration", 6.8, 7.1, 1.45e-5},
    {"naive RBGS 1x11", "scalar, float, 1 substep x 11 iterations", 0.6, 0.9, 1.0e-2},
    {"naive RBGS 11x1", "scalar, float, 11 substeps x 1 iteration", 1.5, 1.5, 3.8e-5},
};
enum { PEER_FIGURE_COUNT = sizeof peer_figures / sizeof peer_figures[0] };

/* The solvers of the sweep (indices into bench_solvers). */
static const rbc_solver_kind sweep_kinds[] = {RBC_SOLVER_RBGS, RBC_SOLVER_RBGS_SOR,
                                              RBC_SOLVER_RBGS_CHEBYSHEV,
                                              RBC_SOLVER_JACOBI_CHEBYSHEV, RBC_SOLVER_DIRECT};
enum { SWEEP_SOLVERS = sizeof sweep_kinds / sizeof sweep_kinds[0] };

typedef struct peer_config {
    rbc_solver_kind solver;
    uint32_t substeps, nonlinear, linear;
    /// SOR factor asked for (0 = the library's optimum) and Chebyshev's rho_J asked
    /// for (0 = estimated).
    float omega, rho;
    rbc_energy_guard guard;
    /// "coarse", "refine", "guard_off", "quick".
    const char *phase;
} peer_config;

typedef struct peer_row {
    peer_config c;
    uint32_t frames_done;
    /// A step returned RBC_ERR_UNSTABLE (the run stops there).
    int unstable;
    /// Final E above the sum of squared rest lengths (rms strain > 1), or not finite.
    int diverged;
    double ms, integrate_ms, local_ms, global_ms, other_ms;
    /// E from the library's stats and from the host's positions; largest strain.
    double eq7, eq7_host, max_strain;
    /// The least and largest E (library stats) over the last tenth of the frames:
    /// E at one frame depends on where the swinging cloth is.
    double eq7_tail_min, eq7_tail_max;
    /// In use, from the stats: SOR omega, Jacobi spectral radius.
    double omega_used, rho_used;
    uint64_t clamps;
    int pareto;
    /// The final positions (3n floats), kept until the files are written.
    float *positions;
} peer_row;

/* What the energy probe found (guard off, state read every frame). */
typedef struct energy_probe {
    int done;
    peer_config c;
    /// Largest (kinetic + gravitational) - budget and (kinetic + gravitational +
    /// spring) - budget over the frames, J, and the frames where they occurred;
    /// the budget is the start's energy, 0 at rest.
    double guarded_excess, total_excess;
    uint32_t guarded_frame, total_frame;
    /// The host's bound on what float rounding of the state changes in the kinetic
    /// energy at guarded_frame, J (bench_kinetic_energy_rounding).
    double rounding;
    /// Frames whose guarded energy exceeded the budget by more than that bound.
    uint32_t frames_over;
} energy_probe;

typedef struct peers_ctx {
    bench_run run;
    uint32_t threads, frames;
    float dt;
    float gravity[3];
    bench_mesh mesh;
    double sum_rest2;
    int available[SWEEP_SOLVERS];
    peer_row *rows;
    size_t row_count, row_cap;
    double *samples[5];
    float *x, *q;
    /// The energy probes: [0] the configuration the guard clamped most, [1] the
    /// exact solve (direct) at the same substeps, for comparison.
    energy_probe probe[2];
    double load_start;
    uint32_t stats_mismatches;
} peers_ctx;

static int out_of_memory(void) { return bench_out_of_memory("peers"); }

static const char *solver_name(rbc_solver_kind k) {
    for (uint32_t i = 0; i < BENCH_SOLVER_COUNT; ++i)
        if (bench_solvers[i].kind == k)
            return bench_solvers[i].name;
    return "?";
}

static int is_chebyshev(rbc_solver_kind k) {
    return k == RBC_SOLVER_RBGS_CHEBYSHEV || k == RBC_SOLVER_JACOBI_CHEBYSHEV;
}

static const char *guard_name(rbc_energy_guard g) {
    return g == RBC_ENERGY_GUARD_OFF ? "off" : g == RBC_ENERGY_GUARD_FAIL ? "fail" : "clamp";
}

static int same_config(const peer_config *a, const peer_config *b) {
    return a->solver == b->solver && a->substeps == b->substeps && a->nonlinear == b->nonlinear &&
           (a->solver == RBC_SOLVER_DIRECT || a->linear == b->linear) && a->omega == b->omega &&
           a->rho == b->rho && a->guard == b->guard;
}

/* A row is a usable point of the front: every frame ran and the cloth held. */
static int row_valid(const peer_row *r, uint32_t frames) {
    return r->frames_done == frames && !r->unstable && !r->diverged && isfinite(r->eq7_host);
}

/* printf onto buf after its first n characters: the new length, or n as it is once
 * the text is full or an earlier printf failed. */
static int append(char *buf, size_t size, int n, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int append(char *buf, size_t size, int n, const char *fmt, ...) {
    if (n <= 0 || (size_t)n >= size)
        return n;
    va_list ap;
    va_start(ap, fmt);
    n += vsnprintf(buf + n, size - (size_t)n, fmt, ap);
    va_end(ap);
    return n;
}

/* What a configuration sets beyond the counts (omega, rho, an energy guard other than
 * the default clamp), in the words of the text it goes into (printf formats). */
static void append_settings(const peer_config *c, char *buf, size_t size, int n,
                            const char *omega, const char *rho, const char *guard) {
    if (c->omega > 0.0f)
        n = append(buf, size, n, omega, (double)c->omega);
    if (c->rho > 0.0f)
        n = append(buf, size, n, rho, (double)c->rho);
    if (c->guard != RBC_ENERGY_GUARD_CLAMP)
        append(buf, size, n, guard, guard_name(c->guard));
}

/* "rbgs 11x1x1", "rbgs_sor 2x1x3 w1.6", "direct 4x2", + " guard off". */
static void config_text(const peer_config *c, char *buf, size_t size) {
    int n;
    if (c->solver == RBC_SOLVER_DIRECT)
        n = snprintf(buf, size, "%s %ux%u", solver_name(c->solver), c->substeps, c->nonlinear);
    else
        n = snprintf(buf, size, "%s %ux%ux%u", solver_name(c->solver), c->substeps, c->nonlinear,
                     c->linear);
    append_settings(c, buf, size, n, " w%.2g", " rho%.4g", " guard %s");
}

/* The command line that runs the same configuration. */
static void command_text(const peers_ctx *ctx, const peer_config *c, char *buf, size_t size) {
    int n = snprintf(buf, size, "rbcloth run --threads %u --frames %u --solver %s --substeps %u "
                                "--nonlinear %u",
                     ctx->threads, ctx->frames, solver_name(c->solver), c->substeps, c->nonlinear);
    if (c->solver != RBC_SOLVER_DIRECT)
        n = append(buf, size, n, " --iterations %u", c->linear);
    append_settings(c, buf, size, n, " --omega %.2g", " (scene: \"rho\": %.4g)",
                    " --energy-guard %s");
}

/* ------------------------------------------------------------------------- */
/* One run                                                                   */
/* ------------------------------------------------------------------------- */

static rbc_result make_world(peers_ctx *ctx, const peer_config *c, rbc_world_id *world,
                             rbc_cloth_id *cloth) {
    bench_world_config cfg;
    if (bench_world_config_init(ctx->run.api, &cfg))
        return RBC_ERR_INVALID_ARGUMENT;
    memcpy(cfg.gravity, ctx->gravity, sizeof cfg.gravity);
    cfg.substeps = c->substeps;
    cfg.nonlinear_iterations = c->nonlinear;
    cfg.linear_iterations = c->solver == RBC_SOLVER_DIRECT ? 1 : c->linear;
    cfg.threads = ctx->threads;
    cfg.solver.solver = c->solver;
    cfg.solver.omega = c->omega;
    cfg.solver.rho = c->rho;
    cfg.solver.energy_guard = c->guard;
    return bench_world_create(ctx->run.api, &ctx->mesh, &cfg, world, cloth);
}

static double rel_diff(double a, double b) {
    double s = fmax(fabs(a), fabs(b));
    return s > 0.0 ? fabs(a - b) / s : 0.0;
}

/* Run configuration c for ctx->frames frames into *out (positions kept). */
static int run_config(peers_ctx *ctx, const peer_config *c, peer_row *out) {
    const rbc_api_v1 *api = ctx->run.api;
    memset(out, 0, sizeof *out);
    out->c = *c;
    out->eq7 = out->eq7_host = out->max_strain = NAN;
    out->eq7_tail_min = out->eq7_tail_max = NAN;
    rbc_world_id world;
    rbc_cloth_id cloth;
    rbc_result r = make_world(ctx, c, &world, &cloth);
    if (r != RBC_OK)
        return bench_report(api, r, "(creating a peers world)");
    int rc = 0;
    rbc_world_stats st;
    const uint32_t tail = ctx->frames - ctx->frames / 10;
    out->eq7_tail_min = INFINITY;
    out->eq7_tail_max = -INFINITY;
    for (uint32_t f = 0; f < ctx->frames; ++f) {
        r = api->world_step(world, ctx->dt);
        if (r == RBC_ERR_UNSTABLE) {
            /* The state was restored; the run ends here and is marked. */
            out->unstable = 1;
            break;
        }
        if (r != RBC_OK) {
            rc = bench_report(api, r, "(stepping a peers world)");
            break;
        }
        memset(&st, 0, sizeof st);
        st.struct_size = (uint32_t)sizeof st;
        /* Timings every frame; Eq. 7 and strain (a pass over the cloth, outside the
         * step and its timings) over the last tenth of the frames. */
        st.skip_measures = f < tail;
        r = api->world_get_stats(world, &st);
        if (r != RBC_OK) {
            rc = bench_report(api, r, "(reading stats)");
            break;
        }
        ctx->samples[0][f] = st.step_ms;
        ctx->samples[1][f] = st.integrate_ms;
        ctx->samples[2][f] = st.local_ms;
        ctx->samples[3][f] = st.global_ms;
        ctx->samples[4][f] = st.other_ms;
        out->frames_done = f + 1;
        out->clamps = st.energy_clamped_steps;
        if (f >= tail) {
            out->eq7_tail_min = fmin(out->eq7_tail_min, st.error_eq7);
            out->eq7_tail_max = fmax(out->eq7_tail_max, st.error_eq7);
        }
        if (f + 1 == ctx->frames) {
            out->eq7 = st.error_eq7;
            out->max_strain = st.max_strain;
            out->omega_used = st.omega;
            out->rho_used = st.spectral_radius;
        }
    }
    if (out->frames_done < ctx->frames)
        out->eq7_tail_min = out->eq7_tail_max = NAN; /* the run stopped: no tail */
    double *med[] = {&out->ms, &out->integrate_ms, &out->local_ms, &out->global_ms, &out->other_ms};
    for (int k = 0; k < 5; ++k)
        *med[k] = bench_median(ctx->samples[k], out->frames_done);
    if (!rc && out->frames_done == ctx->frames) {
        size_t n3 = 3 * (size_t)ctx->mesh.n;
        out->positions = malloc(n3 * sizeof *out->positions);
        if (!out->positions) {
            rc = out_of_memory();
        } else {
            r = api->cloth_read_positions(world, cloth, out->positions, n3, NULL);
            if (r != RBC_OK) {
                rc = bench_report(api, r, "(reading positions)");
            } else {
                out->eq7_host = bench_eq7(&ctx->mesh, out->positions);
                /* Both are double sums over the same float positions; the library's
                 * rest lengths are floats (2^-24 relative), which moves E by far
                 * less than 1e-4 of itself here (bench/checks derives the bound). */
                if (rel_diff(out->eq7_host, out->eq7) > 1e-4 && ++ctx->stats_mismatches <= 10)
                    fprintf(stderr,
                            "rbcloth: bench peers: stats check: library Eq. 7 %.9g, host "
                            "recomputation %.9g\n",
                            out->eq7, out->eq7_host);
            }
        }
    }
    out->diverged = out->frames_done == ctx->frames && !(out->eq7_host <= ctx->sum_rest2);
    api->world_destroy(world);
    return rc;
}

/* ------------------------------------------------------------------------- */
/* The sweep                                                                 */
/* ------------------------------------------------------------------------- */

static int kind_available(const peers_ctx *ctx, rbc_solver_kind k) {
    for (uint32_t i = 0; i < SWEEP_SOLVERS; ++i)
        if (sweep_kinds[i] == k)
            return ctx->available[i];
    return 0;
}

/* Run c unless an identical configuration already ran. */
static int add_config(peers_ctx *ctx, const peer_config *c) {
    if (!kind_available(ctx, c->solver) || c->substeps < 1 || c->substeps > 1024 ||
        c->nonlinear < 1 || c->nonlinear > 1024 || c->linear < 1 || c->linear > 4096)
        return 0;
    for (size_t i = 0; i < ctx->row_count; ++i)
        if (same_config(&ctx->rows[i].c, c))
            return 0;
    peer_row *rows = bench_grow(ctx->rows, &ctx->row_cap, ctx->row_count, sizeof *rows, 128);
    if (!rows)
        return out_of_memory();
    ctx->rows = rows;
    peer_row *row = &ctx->rows[ctx->row_count];
    int rc = run_config(ctx, c, row);
    ++ctx->row_count;
    char text[96];
    config_text(c, text, sizeof text);
    fprintf(stderr, "rbcloth: bench peers: %-34s %8.3f ms/frame  E %.3e%s%s\n", text, row->ms,
            row->eq7_host, row->unstable ? "  unstable" : "", row->diverged ? "  diverged" : "");
    return rc;
}

/* Mark the Pareto front over the valid rows. Returns how many are on it. */
static size_t mark_front(peers_ctx *ctx) {
    size_t count = 0;
    for (size_t i = 0; i < ctx->row_count; ++i) {
        peer_row *a = &ctx->rows[i];
        a->pareto = row_valid(a, ctx->frames);
        for (size_t j = 0; a->pareto && j < ctx->row_count; ++j) {
            const peer_row *b = &ctx->rows[j];
            if (j == i || !row_valid(b, ctx->frames))
                continue;
            if (b->ms <= a->ms && b->eq7_host <= a->eq7_host &&
                (b->ms < a->ms || b->eq7_host < a->eq7_host))
                a->pareto = 0;
        }
        count += (size_t)a->pareto;
    }
    return count;
}

/* ms per frame of the row add_config just ran (0 if it ran none). */
static double added_ms(const peers_ctx *ctx, size_t before) {
    return ctx->row_count > before ? ctx->rows[ctx->row_count - 1].ms : 0.0;
}

static int coarse_grid(peers_ctx *ctx) {
    static const uint32_t substeps[] = {1, 2, 3, 4, 6, 8, 11, 16};
    static const uint32_t linear[] = {1, 2, 3, 4, 6, 8, 11, 16};
    int rc = 0;
    for (uint32_t k = 0; k < SWEEP_SOLVERS && !rc; ++k) {
        rbc_solver_kind kind = sweep_kinds[k];
        for (uint32_t nl = 1; nl <= 3 && !rc; ++nl)
            for (size_t s = 0; s < sizeof substeps / sizeof substeps[0] && !rc; ++s) {
                if (kind == RBC_SOLVER_DIRECT) {
                    /* An exact solve costs about 10 RBGS iterations here. */
                    if (substeps[s] * nl > 8)
                        break;
                    peer_config c = {kind, substeps[s], nl, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP,
                                     "coarse"};
                    rc = add_config(ctx, &c);
                    continue;
                }
                /* Rows past PEERS_COARSE_MS end their series: more linear iterations
                 * (or substeps) only cost more. */
                double first_ms = 0.0;
                for (size_t l = 0; l < sizeof linear / sizeof linear[0] && !rc; ++l) {
                    /* More non-linear iterations only with few linear ones. */
                    if ((nl > 1 && linear[l] > 4) ||
                        substeps[s] * nl * linear[l] > PEERS_COARSE_CAP)
                        break;
                    /* Chebyshev runs plain iterations for its first chebyshev_delay (2):
                     * with fewer than 3 it is RBGS or Jacobi. */
                    if (is_chebyshev(kind) && linear[l] < 3)
                        continue;
                    peer_config c = {kind, substeps[s], nl, linear[l], 0.0f, 0.0f,
                                     RBC_ENERGY_GUARD_CLAMP, "coarse"};
                    size_t before = ctx->row_count;
                    rc = add_config(ctx, &c);
                    double ms = added_ms(ctx, before);
                    if (first_ms == 0.0)
                        first_ms = ms;
                    if (ms > PEERS_COARSE_MS)
                        break;
                }
                if (first_ms > PEERS_COARSE_MS)
                    break;
            }
    }
    return rc;
}

/* Neighbours of the front's rows; SOR's omega and Chebyshev's rho at them. Returns
 * through *added how many rows this round ran. */
static int refine_round(peers_ctx *ctx, size_t *added) {
    size_t before = ctx->row_count;
    mark_front(ctx);
    /* Configurations first (running one reallocates rows). */
    size_t n = 0;
    peer_config *front = malloc((ctx->row_count ? ctx->row_count : 1) * sizeof *front);
    double *rho_used = malloc((ctx->row_count ? ctx->row_count : 1) * sizeof *rho_used);
    if (!front || !rho_used) {
        free(front);
        free(rho_used);
        return out_of_memory();
    }
    for (size_t i = 0; i < ctx->row_count; ++i)
        if (ctx->rows[i].pareto && ctx->rows[i].ms <= PEERS_REFINE_MS) {
            rho_used[n] = ctx->rows[i].rho_used;
            front[n++] = ctx->rows[i].c;
        }
    int rc = 0;
    static const float omegas[] = {1.1f, 1.2f, 1.3f, 1.4f, 1.5f, 1.6f, 1.7f, 1.8f, 1.9f};
    static const double rho_factors[] = {0.9, 0.95, 0.98, 1.01};
    for (size_t i = 0; i < n && !rc; ++i) {
        peer_config b = front[i];
        b.phase = "refine";
        int direct = b.solver == RBC_SOLVER_DIRECT;
        const int ds[][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1},
                             {1, 0, -1}, {-1, 0, 1}};
        for (size_t d = 0; d < sizeof ds / sizeof ds[0] && !rc; ++d) {
            if (direct && ds[d][2] != 0)
                continue;
            peer_config c = b;
            c.substeps = (uint32_t)((int)b.substeps + ds[d][0]);
            c.nonlinear = (uint32_t)((int)b.nonlinear + ds[d][1]);
            c.linear = (uint32_t)((int)b.linear + ds[d][2]);
            if (is_chebyshev(c.solver) && c.linear < 3)
                continue;
            rc = add_config(ctx, &c);
        }
        if (b.solver == RBC_SOLVER_RBGS_SOR)
            for (size_t w = 0; w < sizeof omegas / sizeof omegas[0] && !rc; ++w) {
                peer_config c = b;
                c.omega = omegas[w];
                rc = add_config(ctx, &c);
            }
        if (is_chebyshev(b.solver) && rho_used[i] > 0.0)
            for (size_t w = 0; w < sizeof rho_factors / sizeof rho_factors[0] && !rc; ++w) {
                /* rho is Jacobi's radius (RBGS+Chebyshev squares it); the
                 * library's estimate scaled. RBGS+Chebyshev reports rho_J^2. */
                double rj = b.solver == RBC_SOLVER_RBGS_CHEBYSHEV ? sqrt(rho_used[i]) : rho_used[i];
                peer_config c = b;
                c.rho = (float)fmin(0.9999, rj * rho_factors[w]);
                rc = add_config(ctx, &c);
            }
    }
    free(front);
    free(rho_used);
    *added = ctx->row_count - before;
    return rc;
}

/* The quick mode: a handful of configurations, one per solver family. */
static int quick_set(peers_ctx *ctx) {
    static const peer_config quick[] = {
        {RBC_SOLVER_RBGS, 1, 1, 11, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
        {RBC_SOLVER_RBGS, 11, 1, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
        {RBC_SOLVER_RBGS, 11, 1, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_OFF, "quick"},
        {RBC_SOLVER_RBGS_SOR, 2, 1, 4, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
        {RBC_SOLVER_RBGS_CHEBYSHEV, 2, 1, 4, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
        {RBC_SOLVER_JACOBI_CHEBYSHEV, 2, 1, 6, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
        {RBC_SOLVER_DIRECT, 2, 1, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "quick"},
    };
    int rc = 0;
    for (size_t k = 0; k < sizeof quick / sizeof quick[0] && !rc; ++k)
        rc = add_config(ctx, &quick[k]);
    return rc;
}

/* The front's rows that the guard clamped, again with the guard off. */
static int guard_off_reruns(peers_ctx *ctx) {
    mark_front(ctx);
    size_t n = 0;
    peer_config *todo = malloc((ctx->row_count ? ctx->row_count : 1) * sizeof *todo);
    if (!todo)
        return out_of_memory();
    for (size_t i = 0; i < ctx->row_count; ++i)
        if (ctx->rows[i].pareto && ctx->rows[i].clamps > 0 &&
            ctx->rows[i].c.guard == RBC_ENERGY_GUARD_CLAMP)
            todo[n++] = ctx->rows[i].c;
    /* And the substepped run of the issue (RBGS 11 x 1 x 1), whatever its place. */
    peer_config eleven = {RBC_SOLVER_RBGS, 11, 1, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_OFF, "guard_off"};
    int rc = add_config(ctx, &eleven);
    for (size_t i = 0; i < n && !rc; ++i) {
        peer_config c = todo[i];
        c.guard = RBC_ENERGY_GUARD_OFF;
        c.phase = "guard_off";
        rc = add_config(ctx, &c);
    }
    free(todo);
    return rc;
}

static const peer_row *best_at_target(const peers_ctx *ctx);

/* What the fixed costs of the best row are made of: the same counts with plain RBGS
 * (no blow-up check: phase_check runs it only for the solvers that can diverge) and
 * with the energy guard off. */
static int cost_runs(peers_ctx *ctx) {
    const peer_row *best = best_at_target(ctx);
    if (!best)
        return 0;
    peer_config b = best->c;
    peer_config plain = b, off = b;
    plain.solver = RBC_SOLVER_RBGS;
    plain.omega = plain.rho = 0.0f;
    plain.phase = off.phase = "cost";
    off.guard = RBC_ENERGY_GUARD_OFF;
    int rc = add_config(ctx, &plain);
    if (!rc)
        rc = add_config(ctx, &off);
    return rc;
}

/* The row of configuration c, or NULL. */
static const peer_row *find_row(const peers_ctx *ctx, const peer_config *c) {
    for (size_t i = 0; i < ctx->row_count; ++i)
        if (same_config(&ctx->rows[i].c, c))
            return &ctx->rows[i];
    return NULL;
}

/* Guard off, the state read every frame: does the solver add energy where the
 * guard clamps? Kinetic (velocities over the substep) + gravitational (work) +
 * spring energy against the start's (0: the cloth starts at rest, unstretched). */
static int run_probe(peers_ctx *ctx, const peer_config *c, energy_probe *p) {
    const rbc_api_v1 *api = ctx->run.api;
    memset(p, 0, sizeof *p);
    p->c = *c;
    p->c.guard = RBC_ENERGY_GUARD_OFF;
    p->guarded_excess = p->total_excess = -INFINITY;
    rbc_world_id world;
    rbc_cloth_id cloth;
    rbc_result r = make_world(ctx, &p->c, &world, &cloth);
    if (r != RBC_OK)
        return bench_report(api, r, "(creating the energy probe's world)");
    const bench_mesh *m = &ctx->mesh;
    size_t n3 = 3 * (size_t)m->n;
    double h = (double)ctx->dt / c->substeps;
    /* A float coordinate near 1 m resolves 2^-24 m: the velocity over one substep
     * up to 2^-23 / h (x and q each rounded). */
    double delta = ldexp(1.0, -23) / h;
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    int rc = 0;
    for (uint32_t f = 0; f < ctx->frames; ++f) {
        r = api->world_step(world, ctx->dt);
        if (r == RBC_OK)
            r = api->cloth_get_state(world, cloth, ctx->x, ctx->q, n3);
        if (r != RBC_OK) {
            rc = bench_report(api, r, "(stepping the energy probe)");
            break;
        }
        double ke = bench_kinetic_energy(m, ctx->x, ctx->q, h);
        double w = bench_gravity_work(m, m->rest, ctx->x, ctx->gravity);
        double guarded = ke - w, total = guarded + bench_spring_energy(m, ctx->x);
        double tol = bench_kinetic_energy_rounding(m, ctx->x, ctx->q, h, zero, delta);
        if (guarded > p->guarded_excess) {
            p->guarded_excess = guarded;
            p->guarded_frame = f + 1;
            p->rounding = tol;
        }
        if (total > p->total_excess) {
            p->total_excess = total;
            p->total_frame = f + 1;
        }
        p->frames_over += guarded > tol;
    }
    api->world_destroy(world);
    p->done = !rc;
    return rc;
}

/* ------------------------------------------------------------------------- */
/* Outputs                                                                   */
/* ------------------------------------------------------------------------- */

static const peer_row *g_sort_rows;
static int cmp_row_ms(const void *a, const void *b) {
    const peer_row *x = &g_sort_rows[*(const size_t *)a], *y = &g_sort_rows[*(const size_t *)b];
    return x->ms < y->ms ? -1 : x->ms > y->ms;
}

/* The front's rows (mark_front) in order of ms per frame, into order[]; returns
 * their count. */
static size_t front_order(const peers_ctx *ctx, size_t *order) {
    size_t n = 0;
    for (size_t i = 0; i < ctx->row_count; ++i)
        if (ctx->rows[i].pareto)
            order[n++] = i;
    g_sort_rows = ctx->rows;
    qsort(order, n, sizeof *order, cmp_row_ms);
    return n;
}

static int write_positions(peers_ctx *ctx) {
    char sub[4096];
    snprintf(sub, sizeof sub, "%s/peers_positions", ctx->run.dir);
    if (fs_mkdir_p_or_say(sub))
        return 1;
    for (size_t i = 0; i < ctx->row_count; ++i) {
        const peer_row *r = &ctx->rows[i];
        char name[64];
        snprintf(name, sizeof name, "%zu.f32", i);
        char path[4096 + 64];
        snprintf(path, sizeof path, "%s/%s", sub, name);
        if (!r->positions || (!ctx->run.opt->quick && !r->pareto)) {
            unlink(path); /* a file from an earlier run would name another row */
            continue;
        }
        FILE *f = bench_open(sub, name);
        if (!f)
            return 1;
        fwrite(r->positions, sizeof(float), 3 * (size_t)ctx->mesh.n, f);
        if (bench_close(f, sub, name))
            return 1;
    }
    return 0;
}

static int write_csv(peers_ctx *ctx) {
    FILE *f = bench_open_csv(
        ctx->run.dir, "peers.csv",
        "id,phase,solver,substeps,nonlinear,linear,omega_set,rho_set,energy_guard,threads,"
        "frames,ms_per_frame,integrate_ms,local_ms,global_ms,other_ms,eq7,eq7_host,max_strain,"
        "eq7_tail_min,eq7_tail_max,omega,rho,guard_clamps,unstable,diverged,pareto,meets_target");
    if (!f)
        return 1;
    for (size_t i = 0; i < ctx->row_count; ++i) {
        const peer_row *r = &ctx->rows[i];
        int meets = row_valid(r, ctx->frames) && r->eq7_host <= PEERS_TARGET_E &&
                    r->ms <= PEERS_TARGET_MS;
        fprintf(f, "%zu,%s,%s,%u,%u,%u,%g,%g,%s,%u,%u,%.6f,%.6f,%.6f,%.6f,%.6f,%.12g,%.12g,%.6g,"
                   "%.6g,%.6g,%.6g,%.6g,%llu,%d,%d,%d,%d\n",
                i, r->c.phase, solver_name(r->c.solver), r->c.substeps, r->c.nonlinear,
                r->c.solver == RBC_SOLVER_DIRECT ? 0u : r->c.linear, (double)r->c.omega,
                (double)r->c.rho, guard_name(r->c.guard), ctx->threads, r->frames_done, r->ms,
                r->integrate_ms, r->local_ms, r->global_ms, r->other_ms, r->eq7, r->eq7_host,
                r->max_strain, r->eq7_tail_min, r->eq7_tail_max, r->omega_used, r->rho_used,
                (unsigned long long)r->clamps,
                r->unstable, r->diverged, r->pareto, meets);
    }
    if (bench_close(f, ctx->run.dir, "peers.csv"))
        return 1;
    /* The front in ms order, for the plot's line. */
    if (!(f = bench_open(ctx->run.dir, "peers_front.csv")))
        return 1;
    fprintf(f, "id,solver,ms_per_frame,eq7_host\n");
    size_t *order = malloc((ctx->row_count ? ctx->row_count : 1) * sizeof *order);
    if (!order) {
        fclose(f);
        return out_of_memory();
    }
    size_t n = front_order(ctx, order);
    for (size_t k = 0; k < n; ++k)
        fprintf(f, "%zu,%s,%.6f,%.12g\n", order[k], solver_name(ctx->rows[order[k]].c.solver),
                ctx->rows[order[k]].ms, ctx->rows[order[k]].eq7_host);
    free(order);
    return bench_close(f, ctx->run.dir, "peers_front.csv") ? 1 : 0;
}

/* The fastest valid row with E <= the target (NULL if none). */
static const peer_row *best_at_target(const peers_ctx *ctx) {
    const peer_row *best = NULL;
    for (size_t i = 0; i < ctx->row_count; ++i) {
        const peer_row *r = &ctx->rows[i];
        if (row_valid(r, ctx->frames) && r->eq7_host <= PEERS_TARGET_E &&
            (!best || r->ms < best->ms))
            best = r;
    }
    return best;
}

/* The valid row of least E (NULL if none). */
static const peer_row *least_error(const peers_ctx *ctx) {
    const peer_row *best = NULL;
    for (size_t i = 0; i < ctx->row_count; ++i) {
        const peer_row *r = &ctx->rows[i];
        if (row_valid(r, ctx->frames) && (!best || r->eq7_host < best->eq7_host))
            best = r;
    }
    return best;
}

/* One row's stages per substep and per linear iteration: the fixed costs. */
static void md_stages(FILE *f, const peer_row *r) {
    double s = r->c.substeps, nl = s * r->c.nonlinear;
    double lin = r->c.solver == RBC_SOLVER_DIRECT ? nl : nl * r->c.linear;
    fprintf(f, "| stage | ms per frame | per substep (ms) | per %s (ms) |\n|---|---:|---:|---:|\n",
            r->c.solver == RBC_SOLVER_DIRECT ? "exact solve" : "linear iteration");
    fprintf(f, "| whole step | %.4f | %.4f | |\n", r->ms, r->ms / s);
    fprintf(f, "| integrate (Alg. 2, pins) | %.4f | %.4f | |\n", r->integrate_ms,
            r->integrate_ms / s);
    fprintf(f, "| local + right-hand side (Alg. 3) | %.4f | %.4f | |\n", r->local_ms,
            r->local_ms / s);
    fprintf(f, "| global (Eq. 6) | %.4f | %.4f | %.4f |\n", r->global_ms, r->global_ms / s,
            r->global_ms / lin);
    fprintf(f, "| other (checks, energy guard, commit) | %.4f | %.4f | |\n\n", r->other_ms,
            r->other_ms / s);
}

/* The per-substep "other" cost of row r against plain RBGS at the same counts (the
 * blow-up check's pass over the springs) and against the guard off (the energy
 * guard's pass), when those rows ran. */
static void md_fixed_costs(const peers_ctx *ctx, FILE *f, const peer_row *best) {
    peer_config base = best->c, plain, off;
    base.guard = RBC_ENERGY_GUARD_CLAMP;
    plain = base;
    plain.solver = RBC_SOLVER_RBGS;
    plain.omega = plain.rho = 0.0f;
    off = base;
    off.guard = RBC_ENERGY_GUARD_OFF;
    const peer_row *r = find_row(ctx, &base), *p = find_row(ctx, &plain), *o = find_row(ctx, &off);
    if (!r)
        return;
    double s = r->c.substeps;
    if (p && r->c.solver != RBC_SOLVER_RBGS)
        fprintf(f, "Fixed costs, default guard (clamp): %s takes %.3f ms per frame, other "
                   "%.4f ms. The same counts with plain RBGS (no blow-up check, which the "
                   "library runs once per step, at its last substep, for SOR, Jacobi and "
                   "Chebyshev only, a pass over the springs): other %.4f ms, so the check "
                   "and what else differs cost %.4f ms per frame (%.0f%% of the step, %.4f "
                   "per substep); the sweeps cost %.4f against RBGS's %.4f ms per frame "
                   "(RBGS's E %.3e).\n\n",
                solver_name(r->c.solver), r->ms, r->other_ms, p->other_ms,
                r->other_ms - p->other_ms, 100.0 * (r->other_ms - p->other_ms) / r->ms,
                (r->other_ms - p->other_ms) / s, r->global_ms, p->global_ms, p->eq7_host);
    if (o)
        fprintf(f, "With the energy guard off: %.3f ms per frame, other %.4f ms (the guard "
                   "costs %.4f ms per frame here), E %.3e (with the guard: %.3e, %llu "
                   "clamps).\n\n",
                o->ms, o->other_ms, r->other_ms - o->other_ms, o->eq7_host, r->eq7_host,
                (unsigned long long)r->clamps);
}

static int write_md(peers_ctx *ctx) {
    size_t *order;
    FILE *f = bench_open_ordered(ctx->run.dir, "peers.md", "peers", ctx->row_count, &order);
    if (!f)
        return 1;
    size_t n = front_order(ctx, order), valid = 0;
    for (size_t i = 0; i < ctx->row_count; ++i)
        valid += (size_t)row_valid(&ctx->rows[i], ctx->frames);
    fprintf(f, "# rbcloth on the peer scene (docs/facts.md), against the peers\n\n");
    fprintf(f,
            "100 x 100 hanging cloth, L = 1/99 m, 1e-4 kg per vertex, k = 1000 N/m, h = 2 ms, no "
            "damping, pins 0 and 99, %u frames; E = Eq. 7 over the 19,800 springs at the last "
            "frame (the host's recomputation from the positions it read back); ms = median over "
            "frames of stats.step_ms, %u thread%s. %zu configurations ran (%zu held every frame; "
            "the others returned RBC_ERR_UNSTABLE or diverged). Load average %.2f at the start, "
            "%.2f at the end.\n\n",
            ctx->frames, ctx->threads, ctx->threads == 1 ? "" : "s", ctx->row_count, valid,
            ctx->load_start, bench_load_average());
    const peer_row *best = best_at_target(ctx), *least = least_error(ctx);
    char cfg[128], cmd[256];
    fprintf(f, "## Target: E <= %.3g at <= %.2g ms per frame\n\n", PEERS_TARGET_E, PEERS_TARGET_MS);
    if (best) {
        config_text(&best->c, cfg, sizeof cfg);
        command_text(ctx, &best->c, cmd, sizeof cmd);
        fprintf(f, "Fastest configuration with E <= %.3g: **%s**, %.3f ms per frame, E = %.3e "
                   "(%s: %s).\n\n`%s`\n\n",
                PEERS_TARGET_E, cfg, best->ms, best->eq7_host,
                best->ms <= PEERS_TARGET_MS ? "meets the target" : "misses the time",
                best->ms <= PEERS_TARGET_MS ? "within 0.3 ms"
                                            : "see the stages below for what it costs",
                cmd);
        md_stages(f, best);
        md_fixed_costs(ctx, f, best);
    } else if (least) {
        config_text(&least->c, cfg, sizeof cfg);
        fprintf(f, "No configuration reached E <= %.3g. The least E was %.3e (%s, %.3f ms per "
                   "frame).\n\n",
                PEERS_TARGET_E, least->eq7_host, cfg, least->ms);
        md_stages(f, least);
    }

    fprintf(f, "## Pareto front (ms per frame against E)\n\n");
    fprintf(f, "Configuration: solver substeps x non-linear x linear iterations (direct: "
               "substeps x non-linear), w = SOR omega asked for (none: the library's optimum), "
               "rho = Chebyshev's rho_J asked for (none: estimated). Energy guard clamp unless "
               "it says otherwise.\n\n");
    fprintf(f, "| configuration | ms/frame | E (m^2) | E over the last %u frames | max strain | "
               "omega / rho in use | guard clamps | E <= target |\n"
               "|---|---:|---:|---:|---:|---:|---:|---|\n",
            ctx->frames / 10);
    for (size_t k = 0; k < n; ++k) {
        const peer_row *r = &ctx->rows[order[k]];
        config_text(&r->c, cfg, sizeof cfg);
        char used[48] = "";
        if (r->c.solver == RBC_SOLVER_RBGS_SOR)
            snprintf(used, sizeof used, "%.3f", r->omega_used);
        else if (is_chebyshev(r->c.solver))
            snprintf(used, sizeof used, "%.4f", r->rho_used);
        fprintf(f, "| %s | %.3f | %.3e | %.2e - %.2e | %.3f | %s | %llu | %s |\n", cfg, r->ms,
                r->eq7_host, r->eq7_tail_min, r->eq7_tail_max, r->max_strain, used,
                (unsigned long long)r->clamps,
                r->eq7_host <= PEERS_TARGET_E ? "yes" : "");
    }
    fprintf(f, "\n## The peers (measured elsewhere, docs/facts.md)\n\n");
    fprintf(f, "| peer | configuration | ms/frame | E (m^2) | source |\n|---|---|---:|---:|---|\n");
    for (int k = 0; k < PEER_FIGURE_COUNT; ++k) {
        const peer_figure *p = &peer_figures[k];
        char ms[32];
        if (p->ms_lo == p->ms_hi)
            snprintf(ms, sizeof ms, "%g", p->ms_lo);
        else
            snprintf(ms, sizeof ms, "%g-%g", p->ms_lo, p->ms_hi);
        fprintf(f, "| %s | %s | %s | %.3g | measured elsewhere, docs/facts.md |\n", p->name,
                p->config, ms, p->eq7);
    }

    fprintf(f, "\n## Per solver: the fastest row at E <= %.3g and the least E within %.2g ms\n\n",
            PEERS_TARGET_E, PEERS_TARGET_MS);
    fprintf(f, "| solver | rows (held) | fastest at E <= target | least E within %.2g ms |\n"
               "|---|---:|---|---|\n",
            PEERS_TARGET_MS);
    for (uint32_t k = 0; k < SWEEP_SOLVERS; ++k) {
        const peer_row *fast = NULL, *acc = NULL;
        size_t rows = 0, held = 0;
        for (size_t i = 0; i < ctx->row_count; ++i) {
            const peer_row *r = &ctx->rows[i];
            if (r->c.solver != sweep_kinds[k])
                continue;
            ++rows;
            if (!row_valid(r, ctx->frames))
                continue;
            ++held;
            if (r->eq7_host <= PEERS_TARGET_E && (!fast || r->ms < fast->ms))
                fast = r;
            if (r->ms <= PEERS_TARGET_MS && (!acc || r->eq7_host < acc->eq7_host))
                acc = r;
        }
        char a[160] = "none", b[160] = "none";
        if (fast) {
            config_text(&fast->c, cfg, sizeof cfg);
            snprintf(a, sizeof a, "%s: %.3f ms, %.3e", cfg, fast->ms, fast->eq7_host);
        }
        if (acc) {
            config_text(&acc->c, cfg, sizeof cfg);
            snprintf(b, sizeof b, "%s: %.3f ms, %.3e", cfg, acc->ms, acc->eq7_host);
        }
        fprintf(f, "| %s | %zu (%zu) | %s | %s |\n", solver_name(sweep_kinds[k]), rows, held, a, b);
    }

    fprintf(f, "\n## The energy guard\n\n");
    fprintf(f, "Rows run again with `--energy-guard off` (E with the default clamp, E without, "
               "and the clamps the default counted):\n\n");
    fprintf(f, "| configuration | clamps | E clamp | E off | change | ms clamp | ms off |\n"
               "|---|---:|---:|---:|---:|---:|---:|\n");
    for (size_t i = 0; i < ctx->row_count; ++i) {
        const peer_row *off = &ctx->rows[i];
        if (off->c.guard != RBC_ENERGY_GUARD_OFF)
            continue;
        for (size_t j = 0; j < ctx->row_count; ++j) {
            const peer_row *on = &ctx->rows[j];
            peer_config c = on->c;
            c.guard = RBC_ENERGY_GUARD_OFF;
            if (on->c.guard != RBC_ENERGY_GUARD_CLAMP || !same_config(&c, &off->c))
                continue;
            config_text(&on->c, cfg, sizeof cfg);
            fprintf(f, "| %s | %llu | %.4e | %.4e | %+.2f%% | %.3f | %.3f |\n", cfg,
                    (unsigned long long)on->clamps, on->eq7_host, off->eq7_host,
                    100.0 * (on->eq7_host - off->eq7_host) / off->eq7_host, on->ms, off->ms);
        }
    }
    for (int k = 0; k < 2; ++k) {
        const energy_probe *p = &ctx->probe[k];
        if (!p->done)
            continue;
        config_text(&p->c, cfg, sizeof cfg);
        fprintf(f,
                "\n%s (%s, the state read after every frame, energies recomputed by the host; "
                "the cloth starts at rest and unstretched, so its budget is 0 J): kinetic + "
                "gravitational energy, what the guard checks, peaks at %+.3e J (frame %u; "
                "float rounding of the state can account for %.1e J there) and exceeds that "
                "rounding in %u of %u frames; kinetic + gravitational + spring energy peaks at "
                "%+.3e J (frame %u).%s\n",
                k == 0 ? "Energy probe" : "The same probe with the exact solve", cfg,
                p->guarded_excess, p->guarded_frame, p->rounding, p->frames_over, ctx->frames,
                p->total_excess, p->total_frame,
                k == 1 ? ""
                : p->frames_over > 0 && p->total_excess > p->rounding
                    ? " The solve adds energy (first as unconverged stretch of the springs, "
                      "which the guard leaves out, then as motion): the clamp acts on a real "
                      "gain, as documented."
                : p->frames_over > 0
                    ? " The guarded energy exceeds the budget only while the springs' energy "
                      "is left out."
                    : " The guarded energy never exceeds the budget beyond rounding: a clamp "
                      "on this run would be the guard's own error.");
    }
    fprintf(f, "\n## Warm starts\n\nNot an axis: every linear solve starts from the Verlet "
               "prediction y (p = y at each substep, then the last iterate for later non-linear "
               "iterations); `rbc_solver_def` offers no other start.\n");
    free(order);
    return bench_close(f, ctx->run.dir, "peers.md") ? 1 : 0;
}

static int write_plot(peers_ctx *ctx) {
    static const char *const colors[SWEEP_SOLVERS] = {"#d62728", "#ff7f0e", "#9467bd", "#17becf",
                                                      "#000000"};
    FILE *f = bench_open(ctx->run.dir, "peers.gp");
    if (!f)
        return 1;
    fprintf(f, "# Generated by `rbcloth bench peers`; run `gnuplot peers.gp` in this directory.\n");
    fprintf(f, "set terminal pngcairo size 1100,760 font 'sans,10'\nset output 'peers.png'\n");
    fprintf(f, "set datafile separator ','\nset grid lc rgb '#dddddd'\nset logscale xy\n");
    fprintf(f, "set format y '10^{%%L}'\nset xlabel 'ms per frame (median, %u thread%s)'\n",
            ctx->threads, ctx->threads == 1 ? "" : "s");
    fprintf(f, "set ylabel 'E = Eq. 7 at frame %u (m^2)'\n", ctx->frames);
    fprintf(f, "set title \"Peer scene: 100 x 100 hanging cloth, h = 2 ms, %u frames\\nrbcloth: "
               "every configuration that held and its Pareto front; peers: measured elsewhere "
               "(docs/facts.md)\"\n",
            ctx->frames);
    fprintf(f, "set key inside right top opaque box lc rgb '#bbbbbb' font ',9'\n");
    fprintf(f, "set xrange [0.03:40]\nset yrange [3e-6:0.2]\n");
    fprintf(f, "set object 1 rect from 0.03, 3e-6 to %g, %g fc rgb '#2ca02c' fs transparent "
               "solid 0.15 noborder\n",
            PEERS_TARGET_MS, PEERS_TARGET_E);
    fprintf(f, "set label 1 'target: E <= %.3g, <= %.2g ms' at 0.035, %g left font ',9' tc "
               "rgb '#2ca02c'\n",
            PEERS_TARGET_E, PEERS_TARGET_MS, PEERS_TARGET_E * 1.35);
    fprintf(f, "$peers << EOD\n");
    for (int k = 0; k < PEER_FIGURE_COUNT; ++k)
        fprintf(f, "%g,%g,%g,%g,%s\n", 0.5 * (peer_figures[k].ms_lo + peer_figures[k].ms_hi),
                peer_figures[k].ms_lo, peer_figures[k].ms_hi, peer_figures[k].eq7,
                peer_figures[k].name);
    fprintf(f, "EOD\n");
    fprintf(f, "ok(s) = strcol(3) eq s && $25 == 0 && $26 == 0 && $11 == %u\n", ctx->frames);
    fprintf(f, "plot ");
    for (uint32_t k = 0; k < SWEEP_SOLVERS; ++k)
        fprintf(f, "'peers.csv' every ::1 using (ok('%s') ? $12 : NaN):18 with points pt %u ps 0.9 "
                   "lc rgb '%s' title '%s' noenhanced, \\\n     ",
                solver_name(sweep_kinds[k]), 6 + 2 * k, colors[k], solver_name(sweep_kinds[k]));
    fprintf(f, "'peers_front.csv' every ::1 using 3:4 with linespoints lw 2 pt 7 ps 0.9 lc rgb "
               "'#2ca02c' title 'rbcloth Pareto front', \\\n     ");
    fprintf(f, "$peers using 1:4:2:3 with xerrorbars pt 5 ps 1.2 lc rgb '#555555' title 'peers "
               "(measured elsewhere, docs/facts.md)', \\\n     ");
    fprintf(f, "$peers using 1:4:5 with labels offset 0.8,0.6 left font ',9' tc rgb '#333333' "
               "notitle noenhanced\n");
    if (bench_close(f, ctx->run.dir, "peers.gp"))
        return 1;
    if (!bench_gnuplot_or_say(ctx->run.dir,
                              "Plot skipped: gnuplot is not on PATH. The script is %s/peers.gp; "
                              "install gnuplot (Debian: apt-get install gnuplot-nox) and run "
                              "`gnuplot peers.gp` there.\n"))
        return 0;
    int status = bench_run_gnuplot(ctx->run.dir, "peers.gp");
    if (status != 0)
        fprintf(stderr, "rbcloth: bench peers: gnuplot %s/peers.gp exited with %d\n", ctx->run.dir,
                status);
    return 0;
}

/* ------------------------------------------------------------------------- */

/* Which solvers this plugin has (the direct one needs CHOLMOD): a 3 x 3 cloth
 * stepped once with each. */
static void probe_solvers(peers_ctx *ctx) {
    bench_mesh saved = ctx->mesh;
    bench_mesh tiny;
    int ok = bench_mesh_grid(&tiny, 3, 3, 0.1, 0, 0.0) == 0 && bench_mesh_finish(&tiny) == 0;
    for (uint32_t k = 0; k < SWEEP_SOLVERS; ++k) {
        ctx->available[k] = 1;
        if (!ok)
            continue;
        ctx->mesh = tiny;
        peer_config c = {sweep_kinds[k], 1, 1, 3, 0.0f, 0.0f, RBC_ENERGY_GUARD_CLAMP, "probe"};
        rbc_world_id w;
        rbc_cloth_id cl;
        rbc_result r = make_world(ctx, &c, &w, &cl);
        if (r == RBC_OK) {
            r = ctx->run.api->world_step(w, ctx->dt);
            ctx->run.api->world_destroy(w);
        }
        if (r != RBC_OK) {
            ctx->available[k] = 0;
            fprintf(stderr, "rbcloth: bench peers: solver %s is not available (%s: %s); skipped\n",
                    solver_name(sweep_kinds[k]), ctx->run.api->result_string(r),
                    ctx->run.api->last_error());
        }
    }
    ctx->mesh = saved;
    bench_mesh_free(&tiny);
}

static void ctx_free(peers_ctx *ctx) {
    for (size_t i = 0; i < ctx->row_count; ++i)
        free(ctx->rows[i].positions);
    free(ctx->rows);
    for (int k = 0; k < 5; ++k)
        free(ctx->samples[k]);
    free(ctx->x);
    free(ctx->q);
    bench_mesh_free(&ctx->mesh);
}

int cli_bench_peers(const cli_plugin *plugin, const cli_bench_options *options) {
    if (bench_require_v1_1(plugin))
        return 1;
    const rbc_api_v1 *api = plugin->api;
    if ((api->abi_version_fn() & 0xFFFFu) < 2) {
        fprintf(stderr, "rbcloth: bench peers needs ABI 1.2 (the energy guard's settings and "
                        "counts); %s is older\n",
                plugin->path);
        return 1;
    }
    peers_ctx ctx = {.run = bench_run_of(plugin, options)};
    /* The peers' figures are one thread: so is this bench unless told otherwise. */
    ctx.threads = options->threads >= 0 ? (uint32_t)options->threads : 1u;
    ctx.frames = options->frames > 0 ? (uint32_t)options->frames : options->quick ? 60u : 500u;
    if (fs_mkdir_p_or_say(ctx.run.dir))
        return 1;
    double start = bench_now();
    ctx.load_start = bench_load_average();
    rbc_scene sc;
    char err[RBC_SCENE_ERROR_MAX];
    if (rbc_scene_load_paper(&sc, err, sizeof err)) {
        fprintf(stderr, "rbcloth: %s\n", err);
        return 1;
    }
    int rc = bench_mesh_from_scene(&sc, &ctx.mesh) ? out_of_memory() : 0;
    ctx.dt = sc.dt;
    memcpy(ctx.gravity, sc.world.gravity, sizeof ctx.gravity);
    rbc_scene_free(&sc);
    for (uint32_t s = 0; !rc && s < ctx.mesh.spring_count; ++s)
        ctx.sum_rest2 += ctx.mesh.rest_len[s] * ctx.mesh.rest_len[s];
    for (int k = 0; !rc && k < 5; ++k)
        if (!(ctx.samples[k] = malloc(ctx.frames * sizeof *ctx.samples[k])))
            rc = out_of_memory();
    if (!rc) {
        ctx.x = malloc(3 * (size_t)ctx.mesh.n * sizeof *ctx.x);
        ctx.q = malloc(3 * (size_t)ctx.mesh.n * sizeof *ctx.q);
        if (!ctx.x || !ctx.q)
            rc = out_of_memory();
    }
    if (!rc)
        probe_solvers(&ctx);
    if (!rc && options->quick) {
        rc = quick_set(&ctx);
    } else if (!rc) {
        rc = coarse_grid(&ctx);
        for (int round = 0; !rc && round < PEERS_MAX_ROUNDS; ++round) {
            size_t added = 0;
            rc = refine_round(&ctx, &added);
            fprintf(stderr, "rbcloth: bench peers: refinement round %d ran %zu rows\n", round + 1,
                    added);
            if (!added)
                break;
        }
        if (!rc)
            rc = guard_off_reruns(&ctx);
        if (!rc)
            rc = cost_runs(&ctx);
    }
    if (!rc) {
        /* The energy probe: the front's row with the most clamps, else RBGS 11 x 1 x 1. */
        mark_front(&ctx);
        peer_config c = {RBC_SOLVER_RBGS, 11, 1, 1, 0.0f, 0.0f, RBC_ENERGY_GUARD_OFF, "probe"};
        uint64_t most = 0;
        for (size_t i = 0; i < ctx.row_count; ++i)
            if (ctx.rows[i].pareto && ctx.rows[i].clamps > most) {
                most = ctx.rows[i].clamps;
                c = ctx.rows[i].c;
            }
        rc = run_probe(&ctx, &c, &ctx.probe[0]);
        c.solver = RBC_SOLVER_DIRECT;
        c.omega = c.rho = 0.0f;
        if (!rc && kind_available(&ctx, RBC_SOLVER_DIRECT))
            rc = run_probe(&ctx, &c, &ctx.probe[1]);
    }
    if (!rc) {
        mark_front(&ctx);
        rc = write_positions(&ctx);
    }
    if (!rc) /* each returns 0, or 1 after a message: the first to fail ends it */
        rc = write_csv(&ctx) || write_md(&ctx) || write_plot(&ctx);
    if (!rc) {
        const peer_row *best = best_at_target(&ctx);
        char cfg[128];
        if (best) {
            config_text(&best->c, cfg, sizeof cfg);
            printf("Peers bench: fastest with E <= %.3g: %s, %.3f ms per frame, E = %.4e (%s)\n",
                   PEERS_TARGET_E, cfg, best->ms, best->eq7_host,
                   best->ms <= PEERS_TARGET_MS ? "meets 0.3 ms" : "misses 0.3 ms");
        } else {
            printf("Peers bench: no configuration reached E <= %.3g\n", PEERS_TARGET_E);
        }
        if (ctx.stats_mismatches)
            printf("%u disagreements between the library's Eq. 7 and the host's (see stderr)\n",
                   ctx.stats_mismatches);
        printf("Wrote peers.csv, peers_front.csv, peers.md, peers.gp, peers.png and "
               "peers_positions/ in %s (%zu configurations, %.1f s)\n",
               ctx.run.dir, ctx.row_count, bench_now() - start);
    }
    ctx_free(&ctx);
    return rc;
}
