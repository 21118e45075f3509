/* stability.c -- `rbcloth bench stability`: a stability map of every global
 * solver over stress dimensions (stiffness k h^2/m, time step, mass ratio, size,
 * degenerate springs, a 10x stretched start, pins pulled apart, a fast sphere).
 *
 * Each (case, solver) runs N frames through the function table and records:
 *   - any non-finite value that reaches the host (positions, previous positions,
 *     stats): never allowed, a library bug;
 *   - whether a step returned RBC_ERR_UNSTABLE (allowed: the library restores the
 *     state; the bench checks that it did and stops the run there);
 *   - the kinetic energy against the energy the configuration can supply (below);
 *   - final Eq. 7 and the largest strain.
 *
 * Energy bound. Velocities are Verlet's, v = (x - x_prev) / h. With no damping and
 * pins that stand still, the only energy sources are the initial spring energy E_s(0)
 * and the work of gravity W_g(t) = sum m g . (x(t) - x(0)) over the free vertices:
 * the exact motion keeps KE + E_s - W_g = E_s(0), so KE(t) <= E_s(0) + W_g(t), and
 * implicit Euler (the PD step minimises its objective) only dissipates: in free fall
 * it gives KE / W_g = n / (n + 1) after n steps. Driven cases:
 *   - pins teleported to new targets at the first step and held there: the state
 *     right after the jump holds E_s of the rest pose with the pins moved, and nothing
 *     adds more, so E_s(0) is replaced by that (E_drive = the difference);
 *   - a sphere moving at constant velocity u: in the sphere's frame (inertial) a
 *     static frictionless sphere does no work, so the bound holds there with
 *     velocities v - u, gravity work on x - x(0) - u t, and the cloth's initial
 *     kinetic energy 1/2 M |u|^2 in that frame as E_drive.
 * The supply so far is E_ref(t) = E_s(0) + E_drive + max_{t' <= t} max(W_g(t'), 0)
 * + E_round: positions are floats, so the velocities of a correctly rounded state are
 * known to delta = 2^-23 X / h per coordinate (half an ulp in x and in x_prev,
 * |x| <= X), and KE to E_round = sum m (sqrt(3) |v| delta + 3/2 delta^2).
 * ke_ratio = max_t KE(t) / E_ref(t) is <= 1 for physically bounded motion; a run
 * whose steps all return OK and whose ke_ratio exceeds 1 + 1e-6 (double rounding of
 * the host's sums) is "energy-growth".
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "fsutil.h"

/// Classification threshold of ke_ratio (see the header comment).
#define STAB_KE_BOUND (1.0 + 1e-6)

typedef enum case_kind {
    CASE_HANGING,        /* pinned at vertices 0 and nx-1, at rest */
    CASE_ZERO_LENGTH,    /* two coincident layers, twins joined by zero-length springs */
    CASE_COINCIDENT_PAIR,/* one vertex started on top of its neighbour */
    CASE_COLLAPSED,      /* every vertex started at the origin (free cloth) */
    CASE_STRETCH10,      /* free cloth started 10x larger in its plane */
    CASE_PINS3X,         /* the two pins moved 3x apart at the first step */
    CASE_SPHERE          /* a sphere rising at 10 m/s through a free cloth */
} case_kind;

typedef struct stab_case {
    const char *dimension;
    char value[40];
    case_kind kind;
    uint32_t nx, ny;
    /// k h^2 / m with m = 1e-4 kg (sets k); 0 = k 1000 N/m.
    double khm;
    float dt;
    /// Largest / smallest vertex mass (log-uniform between, mean-preserving in log).
    double mass_ratio;
    uint32_t frames;
    /// Only the parallel solvers and the direct one (large meshes).
    int large;
} stab_case;

/* The outcome of one (case, solver). */
typedef enum stab_status {
    ST_OK,
    ST_UNSTABLE,
    ST_CLAMPED,
    ST_ENERGY,
    ST_NAN,
    ST_SKIPPED,
    ST_REJECTED,
    ST_ERROR
} stab_status;

static const char *const status_names[] = {"ok",      "unstable-reported", "clamped-reported",
                                           "energy-growth", "NaN-leak",   "skipped",
                                           "rejected", "error"};
enum { ST_COUNT = 8 };

typedef struct stab_result {
    stab_status status;
    uint32_t frames_run;
    long first_unstable;
    long nonfinite_frame;
    double ke_max, energy_ref, ke_ratio;
    double final_eq7, final_strain, peak_strain;
    double median_ms, wall_s;
    uint32_t particles, springs;
    /// Steps the library's energy guard clamped (stats.energy_clamped_steps) and the
    /// energy it removed in all of them (J).
    uint64_t clamped_steps;
    double energy_removed;
    char note[256];
} stab_result;

typedef struct stab_ctx {
    bench_run run;
    uint32_t threads;
    stab_case *cases;
    uint32_t case_count;
    size_t case_cap;
    stab_result *results; /* [case][solver] */
    /// Wall seconds of the direct solver's first step at the largest size run so
    /// far (to decide whether 1000 x 1000 is worth factoring).
    double direct_first_step_s;
    uint32_t direct_first_step_n;
    uint32_t nan_leaks, restore_mismatches, stats_mismatches;
} stab_ctx;

static int out_of_memory(void) { return bench_out_of_memory("stability"); }

/* ------------------------------------------------------------------------- */
/* Cases                                                                     */
/* ------------------------------------------------------------------------- */

static stab_case *add_case(stab_ctx *ctx, const char *dimension, case_kind kind) {
    stab_case *cases = bench_grow(ctx->cases, &ctx->case_cap, ctx->case_count, sizeof *cases, 64);
    if (!cases)
        return NULL;
    ctx->cases = cases;
    stab_case *c = &ctx->cases[ctx->case_count++];
    memset(c, 0, sizeof *c);
    c->dimension = dimension;
    c->kind = kind;
    const cli_bench_options *o = ctx->run.opt;
    uint32_t side = o->quick ? 10 : 20;
    c->nx = c->ny = side;
    c->dt = 0.002f;
    c->mass_ratio = 1.0;
    c->frames = o->frames > 0 ? (uint32_t)o->frames : o->quick ? 60 : 200;
    return c;
}

static int build_cases(stab_ctx *ctx) {
    const int quick = ctx->run.opt->quick;
    stab_case *c;
/* A case of dimension `dim` and its value as the tables show it (printf). */
#define ADD(dim, kind, ...)                                \
    if (!(c = add_case(ctx, dim, kind)))                   \
        return out_of_memory();                            \
    snprintf(c->value, sizeof c->value, __VA_ARGS__);

    static const double khm_full[] = {1e-2, 1e-1, 1, 10, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7};
    static const double khm_quick[] = {1e-2, 1e7};
    const double *khm = quick ? khm_quick : khm_full;
    size_t nk = quick ? 2 : sizeof khm_full / sizeof khm_full[0];
    for (size_t k = 0; k < nk; ++k) {
        ADD("k h^2/m", CASE_HANGING, "%g", khm[k]);
        c->khm = khm[k];
    }

    static const float dt_full[] = {1e-5f, 1e-4f, 1e-3f, 2e-3f, 1.0f / 120, 1.0f / 60, 1.0f / 30};
    static const char *const dt_full_names[] = {"1e-5", "1e-4", "1e-3", "2e-3", "1/120", "1/60", "1/30"};
    static const float dt_quick[] = {1e-5f, 1.0f / 30};
    static const char *const dt_quick_names[] = {"1e-5", "1/30"};
    size_t nd = quick ? 2 : sizeof dt_full / sizeof dt_full[0];
    for (size_t k = 0; k < nd; ++k) {
        ADD("dt (s) at k = 1000 N/m", CASE_HANGING, "%s",
            quick ? dt_quick_names[k] : dt_full_names[k]);
        c->dt = quick ? dt_quick[k] : dt_full[k];
    }

    static const double mr_full[] = {10, 1e2, 1e3, 1e4, 1e5, 1e6};
    static const double mr_quick[] = {1e6};
    size_t nm = quick ? 1 : sizeof mr_full / sizeof mr_full[0];
    for (size_t k = 0; k < nm; ++k) {
        double mass_ratio = quick ? mr_quick[k] : mr_full[k];
        ADD("mass ratio", CASE_HANGING, "%g", mass_ratio);
        c->mass_ratio = mass_ratio;
    }

    static const uint32_t size_full[] = {2, 4, 10, 32, 100, 316, 1000};
    static const uint32_t size_quick[] = {2, 4};
    size_t ns = quick ? 2 : sizeof size_full / sizeof size_full[0];
    for (size_t k = 0; k < ns; ++k) {
        uint32_t n = quick ? size_quick[k] : size_full[k];
        ADD("size (particles)", CASE_HANGING, "%ux%u", n, n);
        c->nx = c->ny = n;
        if (n >= 316) {
            c->large = 1;
            /* A few frames: these rows ask whether the solver stays finite and bounded
             * at scale, not how it converges. */
            c->frames = n >= 1000 ? 3 : 10;
        }
    }

    ADD("degenerate springs", CASE_ZERO_LENGTH, "zero-length (2 coincident layers)");
    ADD("degenerate springs", CASE_COINCIDENT_PAIR, "coincident neighbours");
    ADD("degenerate springs", CASE_COLLAPSED, "all particles at one point");

    ADD("start", CASE_STRETCH10, "stretched 10x");
    if (!quick) {
        ADD("start", CASE_STRETCH10, "stretched 10x at dt 1/30");
        c->dt = 1.0f / 30;
    }

    ADD("pins", CASE_PINS3X, "pulled 3x apart");

    ADD("collider", CASE_SPHERE, "sphere 10 m/s at dt 2e-3");
    ADD("collider", CASE_SPHERE, "sphere 10 m/s at dt 1/60");
    c->dt = 1.0f / 60;

    /* A few extremes together. */
    ADD("combined", CASE_HANGING, "mass ratio 1e6 + dt 1/30");
    c->mass_ratio = 1e6;
    c->dt = 1.0f / 30;
    if (!quick) {
        ADD("combined", CASE_HANGING, "k h^2/m 1e7 + mass ratio 1e6");
        c->khm = 1e7;
        c->mass_ratio = 1e6;
        ADD("combined", CASE_SPHERE, "sphere + mass ratio 1e6");
        c->mass_ratio = 1e6;
    }
#undef ADD
    return 0;
}

/* A deterministic uniform number in [0, 1) per vertex (splitmix64). */
static double hash01(uint64_t i) {
    uint64_t z = i + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) / 9007199254740992.0;
}

/* The mesh of a case, its start state (3n floats, or NULL = rest) and pin targets. */
static int build_mesh(const stab_case *c, bench_mesh *m, float **start) {
    *start = NULL;
    double spacing = 1.0 / (c->nx - 1);
    if (bench_mesh_grid(m, c->nx, c->ny, spacing, 0, 0.0))
        return -1;
    uint32_t n = m->n;
    if (c->kind == CASE_ZERO_LENGTH) {
        /* A second layer on top of the first: vertices n..2n-1, its own quads, and a
         * zero-length spring from each vertex to its twin. Twins take opposite
         * colors, so the graph stays bipartite. */
        float *rest = realloc(m->rest, (size_t)2 * n * 3 * sizeof *rest);
        if (!rest)
            return -1;
        m->rest = rest;
        memcpy(m->rest + 3 * (size_t)n, m->rest, (size_t)n * 3 * sizeof *rest);
        uint32_t *quads = realloc(m->quads, (size_t)2 * m->quad_count * 4 * sizeof *quads);
        if (!quads)
            return -1;
        m->quads = quads;
        for (size_t k = 0; k < (size_t)m->quad_count * 4; ++k)
            m->quads[(size_t)m->quad_count * 4 + k] = m->quads[k] + n;
        m->quad_count *= 2;
        m->extra = malloc((size_t)n * 2 * sizeof *m->extra);
        if (!m->extra)
            return -1;
        for (uint32_t i = 0; i < n; ++i) {
            m->extra[2 * (size_t)i] = i;
            m->extra[2 * (size_t)i + 1] = i + n;
        }
        m->extra_count = n;
        m->n = 2 * n;
    }
    int pinned = c->kind == CASE_HANGING || c->kind == CASE_ZERO_LENGTH ||
                 c->kind == CASE_COINCIDENT_PAIR || c->kind == CASE_PINS3X;
    if (pinned) {
        m->pins = malloc(2 * sizeof *m->pins);
        if (!m->pins)
            return -1;
        m->pins[0] = 0;
        m->pins[1] = c->nx - 1;
        m->pin_count = 2;
    }
    const double m0 = 1e-4;
    m->vertex_mass = (float)m0;
    if (c->mass_ratio > 1.0) {
        m->masses = malloc((size_t)m->n * sizeof *m->masses);
        if (!m->masses)
            return -1;
        for (uint32_t i = 0; i < m->n; ++i)
            m->masses[i] = (float)(m0 * pow(c->mass_ratio, hash01(i) - 0.5));
        /* Make sure both extremes occur. */
        m->masses[m->n / 2] = (float)(m0 * sqrt(c->mass_ratio));
        m->masses[m->n / 2 + 1] = (float)(m0 / sqrt(c->mass_ratio));
    }
    m->stiffness = c->khm > 0.0 ? (float)(c->khm * m0 / ((double)c->dt * c->dt)) : 1000.0f;
    if (bench_mesh_finish(m))
        return -1;

    if (c->kind == CASE_COINCIDENT_PAIR || c->kind == CASE_COLLAPSED ||
        c->kind == CASE_STRETCH10) {
        float *s = malloc((size_t)m->n * 3 * sizeof *s);
        if (!s)
            return -1;
        memcpy(s, m->rest, (size_t)m->n * 3 * sizeof *s);
        if (c->kind == CASE_COINCIDENT_PAIR) {
            uint32_t i = c->nx / 2 + c->nx * (c->ny / 2), j = i + 1;
            memcpy(s + 3 * (size_t)i, s + 3 * (size_t)j, 3 * sizeof *s);
        } else if (c->kind == CASE_COLLAPSED) {
            memset(s, 0, (size_t)m->n * 3 * sizeof *s);
        } else {
            double ctr[3] = {0.5, 0.0, 0.5};
            for (size_t k = 0; k < (size_t)m->n * 3; ++k)
                s[k] = (float)(ctr[k % 3] + 10.0 * ((double)s[k] - ctr[k % 3]));
        }
        *start = s;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* One run                                                                   */
/* ------------------------------------------------------------------------- */

static const float sphere_speed = 10.0f;  /* m/s, upwards */
static const float sphere_radius = 0.25f; /* m */
static const float sphere_y0 = -0.5f;     /* m, centre at t = 0 */

static void sphere_at(float t, float out[3]) {
    out[0] = 0.5f;
    out[1] = sphere_y0 + sphere_speed * t;
    out[2] = 0.5f;
}

static void set_note(stab_result *res, const char *fmt, const char *a, const char *b) {
    if (res->note[0])
        return;
    snprintf(res->note, sizeof res->note, fmt, a, b);
    for (char *p = res->note; *p; ++p)
        if (*p == ',' || *p == '\n' || *p == '"')
            *p = ';';
}

static int run_case(stab_ctx *ctx, const stab_case *c, uint32_t solver, stab_result *res) {
    const rbc_api_v1 *api = ctx->run.api;
    memset(res, 0, sizeof *res);
    res->first_unstable = -1;
    res->nonfinite_frame = -1;
    res->ke_ratio = res->final_eq7 = res->final_strain = res->peak_strain = NAN;
    res->median_ms = NAN;

    bench_mesh m;
    float *start = NULL;
    if (build_mesh(c, &m, &start)) {
        bench_mesh_free(&m);
        free(start);
        return out_of_memory();
    }
    res->particles = m.n;
    res->springs = m.spring_count;

    size_t n3 = 3 * (size_t)m.n;
    float *x0 = malloc(n3 * sizeof *x0), *x = malloc(n3 * sizeof *x), *q = malloc(n3 * sizeof *q);
    float *px = malloc(n3 * sizeof *px), *pq = malloc(n3 * sizeof *pq);
    double *ms = malloc((c->frames ? c->frames : 1) * sizeof *ms);
    if (!x0 || !x || !q || !px || !pq || !ms) {
        free(x0), free(x), free(q), free(px), free(pq), free(ms), free(start);
        bench_mesh_free(&m);
        return out_of_memory();
    }

    bench_world_config cfg;
    bench_world_config_init(api, &cfg);
    cfg.threads = ctx->threads;
    cfg.solver.solver = bench_solvers[solver].kind;
    rbc_world_id world = 0;
    rbc_cloth_id cloth = 0;
    double t0 = bench_now();
    rbc_result r = bench_world_create(api, &m, &cfg, &world, &cloth);
    char text[512];
    if (r != RBC_OK) {
        res->status = r == RBC_ERR_BAD_MESH || r == RBC_ERR_INVALID_ARGUMENT ? ST_REJECTED
                      : r == RBC_ERR_UNSUPPORTED || r == RBC_ERR_BACKEND_UNAVAILABLE
                          ? ST_SKIPPED
                          : ST_ERROR;
        set_note(res, "%s%s", bench_result_text(api, r, text, sizeof text), "");
        goto done;
    }
    if (start && (r = api->cloth_set_state(world, cloth, start, NULL)) != RBC_OK) {
        res->status = ST_ERROR;
        set_note(res, "set_state: %s%s", bench_result_text(api, r, text, sizeof text), "");
        goto done;
    }

    double e_drive = 0.0;
    rbc_collider_id sphere = 0;
    /* Velocity of the frame the energy is measured in (the sphere's). */
    float u[3] = {0.0f, 0.0f, 0.0f};
    if (c->kind == CASE_PINS3X) {
        /* Pins 0 and nx-1 are 1 m apart; move them to 3 m apart, symmetrically. */
        const float t0p[3] = {-1.0f, 0.0f, 0.0f}, t1p[3] = {2.0f, 0.0f, 0.0f};
        memcpy(px, m.rest, n3 * sizeof *px);
        memcpy(px + 3 * (size_t)m.pins[0], t0p, sizeof t0p);
        memcpy(px + 3 * (size_t)m.pins[1], t1p, sizeof t1p);
        e_drive = bench_spring_energy(&m, px) - bench_spring_energy(&m, m.rest);
        r = api->cloth_set_pin(world, cloth, m.pins[0], t0p);
        if (r == RBC_OK)
            r = api->cloth_set_pin(world, cloth, m.pins[1], t1p);
        if (r != RBC_OK) {
            res->status = ST_ERROR;
            set_note(res, "set_pin: %s%s", bench_result_text(api, r, text, sizeof text), "");
            goto done;
        }
    } else if (c->kind == CASE_SPHERE) {
        rbc_collider_def cd;
        api->collider_def_init(&cd, (uint32_t)sizeof cd);
        cd.shape = RBC_SHAPE_SPHERE;
        cd.radius = sphere_radius;
        sphere_at(0.0f, cd.position);
        r = api->collider_create(world, &cd, &sphere);
        if (r != RBC_OK) {
            res->status = ST_ERROR;
            set_note(res, "collider: %s%s", bench_result_text(api, r, text, sizeof text), "");
            goto done;
        }
        u[1] = sphere_speed;
        e_drive = 0.5 * bench_free_mass(&m) * (double)sphere_speed * sphere_speed;
    }

    r = api->cloth_get_state(world, cloth, x0, q, n3);
    if (r != RBC_OK) {
        res->status = ST_ERROR;
        set_note(res, "get_state: %s%s", bench_result_text(api, r, text, sizeof text), "");
        goto done;
    }
    memcpy(px, x0, n3 * sizeof *px);
    memcpy(pq, q, n3 * sizeof *pq);
    const double h = c->dt; /* one substep */
    const double e_s0 = bench_spring_energy(&m, x0);
    /* A floor far below any energy here, so a run at rest with no supply divides
     * by something: 1e-12 J. */
    const double e_floor = 1e-12;
    res->ke_ratio = 0.0;
    res->peak_strain = 0.0;
    res->energy_ref = e_s0 + e_drive;
    const double free_mass = bench_free_mass(&m);
    double wg_max = 0.0;
    stab_status status = ST_OK;
    for (uint32_t f = 0; f < c->frames; ++f) {
        if (sphere) {
            float p[3];
            const float id[4] = {0, 0, 0, 1};
            sphere_at((float)(f + 1) * c->dt, p);
            api->collider_set_transform(world, sphere, p, id);
        }
        double ts = bench_now();
        r = api->world_step(world, c->dt);
        if (f == 0 && bench_solvers[solver].kind == RBC_SOLVER_DIRECT &&
            m.n > ctx->direct_first_step_n) {
            ctx->direct_first_step_n = m.n;
            ctx->direct_first_step_s = bench_now() - ts;
        }
        if (r == RBC_ERR_UNSTABLE) {
            res->first_unstable = f + 1;
            status = ST_UNSTABLE;
            /* The contract: the world is as it was before the step. */
            if (api->cloth_get_state(world, cloth, x, q, n3) == RBC_OK &&
                (memcmp(x, px, n3 * sizeof *x) != 0 || memcmp(q, pq, n3 * sizeof *q) != 0)) {
                ++ctx->restore_mismatches;
                set_note(res, "LIBRARY BUG: state not restored after RBC_ERR_UNSTABLE%s%s", "", "");
            }
            set_note(res, "%s%s", api->last_error(), "");
            break;
        }
        if (r != RBC_OK) {
            status = ST_ERROR;
            set_note(res, "step: %s%s", bench_result_text(api, r, text, sizeof text), "");
            break;
        }
        res->frames_run = f + 1;
        rbc_world_stats st;
        r = bench_stats(api, world, &st);
        if (r == RBC_OK)
            r = api->cloth_get_state(world, cloth, x, q, n3);
        if (r != RBC_OK) {
            status = ST_ERROR;
            set_note(res, "read back: %s%s", bench_result_text(api, r, text, sizeof text), "");
            break;
        }
        ms[f] = st.step_ms;
        res->clamped_steps = st.energy_clamped_steps;
        res->energy_removed += st.energy_removed;
        const char *bad_field = NULL;
        long bad = bench_first_nonfinite(x, n3);
        long badq = bad < 0 ? bench_first_nonfinite(q, n3) : -1;
        if (bad >= 0 || badq >= 0 || !bench_stats_finite(&st, &bad_field)) {
            status = ST_NAN;
            res->nonfinite_frame = f + 1;
            char where[96];
            if (bad >= 0)
                snprintf(where, sizeof where, "position of vertex %ld", bad / 3);
            else if (badq >= 0)
                snprintf(where, sizeof where, "previous position of vertex %ld", badq / 3);
            else
                snprintf(where, sizeof where, "stats.%s", bad_field);
            set_note(res, "LIBRARY BUG: non-finite %s after a step that returned %s", where,
                     "RBC_OK");
            ++ctx->nan_leaks;
            break;
        }
        double t = (double)(f + 1) * h;
        double ke = bench_kinetic_energy_in_frame(&m, x, q, h, u);
        double wg = bench_gravity_work(&m, x0, x, cfg.gravity) -
                    free_mass * t * ((double)cfg.gravity[0] * u[0] + (double)cfg.gravity[1] * u[1] +
                                     (double)cfg.gravity[2] * u[2]);
        if (wg > wg_max)
            wg_max = wg;
        double xmax = 0.0;
        for (size_t k = 0; k < n3; ++k)
            xmax = fmax(xmax, fabs((double)x[k]));
        double e_round = bench_kinetic_energy_rounding(&m, x, q, h, u, ldexp(xmax, -23) / h);
        double ref = e_s0 + e_drive + wg_max + e_round + e_floor;
        double ratio = ke / ref;
        if (ratio > res->ke_ratio) {
            res->ke_ratio = ratio;
            res->ke_max = ke;
            res->energy_ref = ref;
        }
        double strain = bench_max_strain(&m, x);
        if (strain > res->peak_strain)
            res->peak_strain = strain;
        res->final_strain = strain;
        res->final_eq7 = bench_eq7(&m, x);
        /* Eq. 7 is the library's as well: a plain sum the host can redo. */
        if (f + 1 == c->frames) {
            double lib = st.error_eq7, host = res->final_eq7;
            if (fabs(lib - host) > 1e-4 * fmax(fabs(lib), fabs(host)) + 1e-12) {
                ++ctx->stats_mismatches;
                char a[64], b[64];
                snprintf(a, sizeof a, "%.6g", lib);
                snprintf(b, sizeof b, "%.6g", host);
                set_note(res, "stats.error_eq7 %s but the host computes %s", a, b);
            }
        }
        memcpy(px, x, n3 * sizeof *px);
        memcpy(pq, q, n3 * sizeof *pq);
    }
    if (status == ST_OK && res->ke_ratio > STAB_KE_BOUND)
        status = ST_ENERGY;
    /* Bounded, and the library said it had to act (stats and log): reported. */
    if (status == ST_OK && res->clamped_steps > 0)
        status = ST_CLAMPED;
    res->status = status;
    res->median_ms = bench_median(ms, res->frames_run);

done:
    res->wall_s = bench_now() - t0;
    if (world)
        api->world_destroy(world);
    free(x0), free(x), free(q), free(px), free(pq), free(ms), free(start);
    bench_mesh_free(&m);
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Outputs                                                                   */
/* ------------------------------------------------------------------------- */

/* A CSV field without separators. */
static const char *csv_text(const char *in, char *buf, size_t size) {
    snprintf(buf, size, "%s", in);
    for (char *p = buf; *p; ++p)
        if (*p == ',' || *p == '\n' || *p == '"')
            *p = ';';
    return buf;
}

static int write_csv(stab_ctx *ctx) {
    FILE *f = bench_open_csv(
        ctx->run.dir, "stability.csv",
        "dimension,value,solver,nx,ny,particles,springs,dt,khm,mass_ratio,frames_planned,"
        "frames_run,status,first_unstable_frame,nonfinite_frame,ke_max,energy_ref,ke_ratio,"
        "final_eq7,final_max_strain,peak_max_strain,median_step_ms,wall_s,clamped_steps,"
        "energy_removed,note");
    if (!f)
        return 1;
    for (uint32_t i = 0; i < ctx->case_count; ++i) {
        const stab_case *c = &ctx->cases[i];
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            const stab_result *r = &ctx->results[i * BENCH_SOLVER_COUNT + k];
            double khm = c->khm > 0.0 ? c->khm : 1000.0 * (double)c->dt * c->dt / 1e-4;
            char d1[96], d2[96];
            fprintf(f, "%s,%s,%s,%u,%u,%u,%u,%.9g,%.6g,%g,%u,%u,%s,%ld,%ld,%.6e,%.6e,%.6g,%.6e,%.6e,"
                       "%.6e,%.5f,%.3f,%llu,%.6e,%s\n",
                    csv_text(c->dimension, d1, sizeof d1), csv_text(c->value, d2, sizeof d2),
                    bench_solvers[k].name, c->nx, c->ny, r->particles,
                    r->springs, (double)c->dt, khm, c->mass_ratio, c->frames, r->frames_run,
                    status_names[r->status], r->first_unstable, r->nonfinite_frame, r->ke_max,
                    r->energy_ref, r->ke_ratio, r->final_eq7, r->final_strain, r->peak_strain,
                    r->median_ms, r->wall_s, (unsigned long long)r->clamped_steps,
                    r->energy_removed, r->note);
        }
    }
    return bench_close(f, ctx->run.dir, "stability.csv") ? 1 : 0;
}

static void md_map(stab_ctx *ctx, FILE *f, int what) {
    fprintf(f, "| dimension | value |");
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k)
        fprintf(f, " %s |", bench_solvers[k].name);
    fprintf(f, "\n|---|---|");
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k)
        fprintf(f, "---|");
    fprintf(f, "\n");
    for (uint32_t i = 0; i < ctx->case_count; ++i) {
        const stab_case *c = &ctx->cases[i];
        fprintf(f, "| %s | %s |", c->dimension, c->value);
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            const stab_result *r = &ctx->results[i * BENCH_SOLVER_COUNT + k];
            if (what == 0) {
                if (r->status == ST_UNSTABLE)
                    fprintf(f, " unstable-reported (frame %ld) |", r->first_unstable);
                else if (r->status == ST_CLAMPED)
                    fprintf(f, " clamped-reported (%llu of %u steps) |",
                            (unsigned long long)r->clamped_steps, r->frames_run);
                else if (r->status == ST_OK)
                    fprintf(f, " ok |");
                else
                    fprintf(f, " **%s** |", status_names[r->status]);
            } else if (r->status == ST_SKIPPED || r->status == ST_REJECTED || r->status == ST_ERROR) {
                fprintf(f, " – |");
            } else if (what == 1) {
                fprintf(f, " %.3g |", r->ke_ratio);
            } else {
                fprintf(f, " %.3g |", r->peak_strain);
            }
        }
        fprintf(f, "\n");
    }
}

static int write_md(stab_ctx *ctx) {
    const int quick = ctx->run.opt->quick;
    FILE *f = bench_open(ctx->run.dir, "stability.md");
    if (!f)
        return 1;
    fprintf(f, "# Stability map\n\n");
    fprintf(f, "Every solver on every stress case (`rbcloth bench stability%s`). Base case: a "
               "%ux%u cloth, 1 m square, hanging from two corners, 1e-4 kg per vertex, "
               "k = 1000 N/m, h = 2 ms, 11 linear iterations, no damping; each row changes one "
               "thing. Cells: **ok**; **unstable-reported** (a step returned RBC_ERR_UNSTABLE and "
               "the library restored the state; the run stops there); **clamped-reported** "
               "(every step returned OK, the energy stayed bounded, and the library's energy "
               "guard scaled velocities in the steps counted, reporting each through stats "
               "and the log: the solver added energy there); **energy-growth** (every "
               "step returned OK but the kinetic energy exceeded what the configuration can "
               "supply, ke_ratio > %g); **NaN-leak** (a non-finite value reached the host: a "
               "library bug); skipped, rejected (the library refused the mesh) or error.\n\n",
            quick ? " --quick" : "", quick ? 10 : 20, quick ? 10 : 20, STAB_KE_BOUND);
    md_map(ctx, f, 0);
    fprintf(f, "\n## Kinetic energy against the energy supplied\n\n"
               "ke_ratio = max over frames of KE / (E_spring(0) + E_drive + max(W_gravity, 0)); "
               "<= 1 for physically bounded motion (see bench/stability.c).\n\n");
    md_map(ctx, f, 1);
    fprintf(f, "\n## Largest strain seen\n\nmax over frames and springs of | |p_a - p_b| / L - 1 |.\n\n");
    md_map(ctx, f, 2);
    int skipped = 0;
    for (uint32_t i = 0; i < ctx->case_count; ++i)
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            const stab_result *r = &ctx->results[i * BENCH_SOLVER_COUNT + k];
            if (r->note[0] && r->status != ST_OK) {
                if (!skipped++)
                    fprintf(f, "\n## Notes\n\n");
                fprintf(f, "- %s = %s, %s: %s\n", ctx->cases[i].dimension, ctx->cases[i].value,
                        bench_solvers[k].name, r->note);
            }
        }
    return bench_close(f, ctx->run.dir, "stability.md") ? 1 : 0;
}

static int status_code(stab_status s) {
    switch (s) {
    case ST_OK: return 0;
    case ST_CLAMPED: return 1;
    case ST_UNSTABLE: return 2;
    case ST_ENERGY: return 3;
    case ST_NAN: return 4;
    default: return -1;
    }
}

static int write_plot(stab_ctx *ctx) {
    FILE *d = bench_open(ctx->run.dir, "stability_map.dat");
    if (!d)
        return 1;
    /* x y code label: one line per cell, for `with image` and `with labels`. */
    for (uint32_t i = 0; i < ctx->case_count; ++i) {
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            const stab_result *r = &ctx->results[i * BENCH_SOLVER_COUNT + k];
            char label[32];
            if (r->status == ST_OK || r->status == ST_ENERGY)
                snprintf(label, sizeof label, "%.3g", r->ke_ratio);
            else if (r->status == ST_CLAMPED)
                snprintf(label, sizeof label, "C %.3g", r->ke_ratio);
            else if (r->status == ST_UNSTABLE)
                snprintf(label, sizeof label, "U@%ld", r->first_unstable);
            else
                snprintf(label, sizeof label, "%s", status_names[r->status]);
            fprintf(d, "%u %u %d \"%s\"\n", k, ctx->case_count - 1 - i, status_code(r->status), label);
        }
        fprintf(d, "\n");
    }
    if (bench_close(d, ctx->run.dir, "stability_map.dat"))
        return 1;

    FILE *f = bench_open(ctx->run.dir, "stability.gp");
    if (!f)
        return 1;
    int height = 140 + 22 * (int)ctx->case_count;
    fprintf(f, "# Generated by `rbcloth bench stability`; run `gnuplot stability.gp` here.\n");
    fprintf(f, "set terminal pngcairo size 1500,%d font 'sans,9'\n", height);
    fprintf(f, "set output 'stability.png'\nset termoption noenhanced\n");
    fprintf(f, "set title 'Stability map: colour = outcome; text = max kinetic energy / energy supplied (C: the energy guard clamped; U@n: RBC_ERR_UNSTABLE at frame n)'\n");
    fprintf(f, "set cbrange [-1.5:4.5]\nset palette defined (-1.5 '#cccccc', -0.5 '#cccccc', -0.5 '#8fd18f', 0.5 '#8fd18f', 0.5 '#b5d98a', 1.5 '#b5d98a', 1.5 '#f7e27a', 2.5 '#f7e27a', 2.5 '#f5a04a', 3.5 '#f5a04a', 3.5 '#e0474c', 4.5 '#e0474c')\n");
    fprintf(f, "set cbtics ('skipped' -1, 'ok' 0, 'clamped-reported' 1, 'unstable-reported' 2, 'energy-growth' 3, 'NaN-leak' 4)\n");
    fprintf(f, "set xrange [-0.5:%d.5]\nset yrange [-0.5:%u.5]\n", BENCH_SOLVER_COUNT - 1, ctx->case_count - 1);
    fprintf(f, "set x2tics (");
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k)
        fprintf(f, "%s'%s' %u", k ? ", " : "", bench_solvers[k].name, k);
    fprintf(f, ")\nunset xtics\nset x2tics scale 0\nset ytics scale 0 (");
    for (uint32_t i = 0; i < ctx->case_count; ++i) {
        const stab_case *c = &ctx->cases[i];
        char label[160];
        snprintf(label, sizeof label, "%s: %s", c->dimension, c->value);
        for (char *p = label; *p; ++p)
            if (*p == '\'')
                *p = ' ';
        fprintf(f, "%s'%s' %u", i ? ", " : "", label, ctx->case_count - 1 - i);
    }
    fprintf(f, ")\nset lmargin 46\nset rmargin 18\nunset key\n");
    fprintf(f, "plot 'stability_map.dat' using 1:2:3 with image, '' using 1:2:4 with labels font ',8'\n");
    return bench_close(f, ctx->run.dir, "stability.gp") ? 1 : 0;
}

static const char *short_status(const stab_result *r, char *buf, size_t size) {
    switch (r->status) {
    case ST_OK: snprintf(buf, size, "ok %.2g", r->ke_ratio); break;
    case ST_UNSTABLE: snprintf(buf, size, "UNST@%ld", r->first_unstable); break;
    case ST_CLAMPED: snprintf(buf, size, "CLMP %.2g", r->ke_ratio); break;
    case ST_ENERGY: snprintf(buf, size, "GROW %.2g", r->ke_ratio); break;
    case ST_NAN: snprintf(buf, size, "NaN!"); break;
    case ST_SKIPPED: snprintf(buf, size, "skip"); break;
    case ST_REJECTED: snprintf(buf, size, "rejected"); break;
    default: snprintf(buf, size, "error"); break;
    }
    return buf;
}

static void print_summary(const stab_ctx *ctx, double seconds) {
    static const char *const abbrev[BENCH_SOLVER_COUNT] = {"rbgs",   "jacobi", "jac_cheb",
                                                           "gs",     "rbgs_sor", "rbgs_cheb",
                                                           "mc_gs",  "direct"};
    printf("\nStability map (cell: outcome and max KE / energy supplied; CLMP: the energy "
           "guard clamped; UNST@n = RBC_ERR_UNSTABLE at frame n)\n");
    printf("%-44s", "case");
    for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k)
        printf(" %10s", abbrev[k]);
    printf("\n");
    for (uint32_t i = 0; i < ctx->case_count; ++i) {
        char name[96];
        snprintf(name, sizeof name, "%s: %s", ctx->cases[i].dimension, ctx->cases[i].value);
        printf("%-44.44s", name);
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT; ++k) {
            char cell[32];
            printf(" %10s", short_status(&ctx->results[i * BENCH_SOLVER_COUNT + k], cell, sizeof cell));
        }
        printf("\n");
    }
    uint32_t counts[ST_COUNT] = {0};
    for (uint32_t i = 0; i < ctx->case_count * BENCH_SOLVER_COUNT; ++i)
        ++counts[ctx->results[i].status];
    printf("\n%u runs: %u ok, %u clamped-reported, %u unstable-reported, %u energy-growth, "
           "%u NaN-leak, %u skipped, %u rejected, %u error; %.1f s\n",
           ctx->case_count * BENCH_SOLVER_COUNT, counts[ST_OK], counts[ST_CLAMPED],
           counts[ST_UNSTABLE], counts[ST_ENERGY],
           counts[ST_NAN], counts[ST_SKIPPED], counts[ST_REJECTED], counts[ST_ERROR], seconds);
    if (ctx->nan_leaks)
        printf("LIBRARY BUG: %u run%s read a non-finite value back (see stability.md, Notes)\n",
               ctx->nan_leaks, ctx->nan_leaks == 1 ? "" : "s");
    if (ctx->restore_mismatches)
        printf("LIBRARY BUG: %u run%s found the state changed after RBC_ERR_UNSTABLE\n",
               ctx->restore_mismatches, ctx->restore_mismatches == 1 ? "" : "s");
    if (ctx->stats_mismatches)
        printf("%u run%s with stats.error_eq7 different from the host's Eq. 7\n",
               ctx->stats_mismatches, ctx->stats_mismatches == 1 ? "" : "s");
}

/* ------------------------------------------------------------------------- */

int cli_bench_stability(const cli_plugin *plugin, const cli_bench_options *options) {
    if (bench_require_v1_1(plugin))
        return 1;
    stab_ctx ctx = {.run = bench_run_of(plugin, options)};
    ctx.threads = options->threads >= 0 ? (uint32_t)options->threads : 0;
    if (fs_mkdir_p_or_say(ctx.run.dir))
        return 1;
    int rc = build_cases(&ctx);
    if (!rc) {
        ctx.results = calloc((size_t)ctx.case_count * BENCH_SOLVER_COUNT, sizeof *ctx.results);
        if (!ctx.results)
            rc = out_of_memory();
    }
    double start = bench_now();
    for (uint32_t i = 0; i < ctx.case_count && !rc; ++i) {
        const stab_case *c = &ctx.cases[i];
        fprintf(stderr, "rbcloth: bench stability: %s = %s ...\n", c->dimension, c->value);
        for (uint32_t k = 0; k < BENCH_SOLVER_COUNT && !rc; ++k) {
            stab_result *res = &ctx.results[i * BENCH_SOLVER_COUNT + k];
            const bench_solver *s = &bench_solvers[k];
            if (c->large && !s->parallel && s->iterative) {
                res->status = ST_SKIPPED;
                snprintf(res->note, sizeof res->note,
                         "serial solver: large sizes run only for the parallel solvers and "
                         "the direct one");
                continue;
            }
            /* Factor 1000 x 1000 only if 316 x 316 factored within 3 s (the fill of a
             * nested-dissection Cholesky on a grid grows as n log n: ~12x). */
            if (c->large && !s->iterative && (uint64_t)c->nx * c->ny >= 1000000 &&
                !(ctx.direct_first_step_n >= 90000 && ctx.direct_first_step_s < 3.0)) {
                res->status = ST_SKIPPED;
                snprintf(res->note, sizeof res->note,
                         "direct: 316x316 took %.1f s for its first step (factorisation); "
                         "1000x1000 would take about %.0f s",
                         ctx.direct_first_step_s, 12.0 * ctx.direct_first_step_s);
                continue;
            }
            rc = run_case(&ctx, c, k, res);
            if (!rc && res->status == ST_NAN)
                fprintf(stderr, "rbcloth: bench stability: %s = %s, %s: %s\n", c->dimension,
                        c->value, s->name, res->note);
        }
    }
    double seconds = bench_now() - start;
    if (!rc) /* each returns 0, or 1 after a message: the first to fail ends it */
        rc = write_csv(&ctx) || write_md(&ctx) || write_plot(&ctx);
    if (!rc) {
        bench_plot(ctx.run.dir, "stability.gp");
        print_summary(&ctx, seconds);
        printf("Wrote stability.csv, stability.md%s in %s\n",
               bench_have_gnuplot() ? ", stability.png" : "", ctx.run.dir);
    }
    free(ctx.cases);
    free(ctx.results);
    return rc;
}
