/* common.c -- helpers shared by the benches (bench.h). */
#include "bench.h"
#include "scene.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

const bench_solver bench_solvers[BENCH_SOLVER_COUNT] = {
    {RBC_SOLVER_RBGS, "rbgs", 1, 1},
    {RBC_SOLVER_JACOBI, "jacobi", 1, 1},
    {RBC_SOLVER_JACOBI_CHEBYSHEV, "jacobi_chebyshev", 1, 1},
    {RBC_SOLVER_GAUSS_SEIDEL, "gauss_seidel", 0, 1},
    {RBC_SOLVER_RBGS_SOR, "rbgs_sor", 1, 1},
    {RBC_SOLVER_RBGS_CHEBYSHEV, "rbgs_chebyshev", 1, 1},
    {RBC_SOLVER_MULTICOLOR_GS, "multicolor_gs", 1, 1},
    {RBC_SOLVER_DIRECT, "direct", 0, 0},
};

int bench_require_v1_1(const cli_plugin *plugin) {
    const rbc_api_v1 *api = plugin->api;
    uint32_t abi = api->abi_version_fn();
    const char *missing = NULL;
    if (!api->solver_def_init)
        missing = "solver_def_init";
    else if (!api->world_set_solver)
        missing = "world_set_solver";
    else if (!api->world_get_solver)
        missing = "world_get_solver";
    else if (!api->cloth_get_state)
        missing = "cloth_get_state";
    else if (!api->cloth_set_state)
        missing = "cloth_set_state";
    else if (!api->cloth_get_colors)
        missing = "cloth_get_colors";
    if ((abi & 0xFFFFu) < 1 || missing) {
        fprintf(stderr,
                "rbcloth: the benches need ABI 1.1 (solver selection, cloth state); %s reports "
                "ABI %u.%u%s%s\n",
                plugin->path, abi >> 16, abi & 0xFFFFu,
                missing ? " and has no " : "", missing ? missing : "");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Mesh                                                                      */
/* ------------------------------------------------------------------------- */

int bench_mesh_grid(bench_mesh *m, uint32_t nx, uint32_t ny, double spacing, int plane,
                    double y0) {
    memset(m, 0, sizeof *m);
    if (nx < 2 || ny < 2 || !(spacing > 0.0))
        return -1;
    m->n = nx * ny;
    m->nx = nx;
    m->ny = ny;
    m->quad_count = (nx - 1) * (ny - 1);
    m->rest = malloc((size_t)m->n * 3 * sizeof *m->rest);
    m->quads = malloc((size_t)m->quad_count * 4 * sizeof *m->quads);
    if (!m->rest || !m->quads) {
        bench_mesh_free(m);
        return -1;
    }
    /* As samples/grid.c: origin + index * spacing in double, not accumulated. */
    for (uint32_t j = 0; j < ny; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            float *p = m->rest + 3 * ((size_t)i + (size_t)nx * j);
            p[0] = (float)(i * spacing);
            p[1] = plane == 0 ? (float)y0 : (float)(y0 + j * spacing);
            p[2] = plane == 0 ? (float)(j * spacing) : 0.0f;
        }
    for (uint32_t j = 0; j + 1 < ny; ++j)
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t *q = m->quads + 4 * ((size_t)i + (size_t)(nx - 1) * j);
            q[0] = i + nx * j;
            q[1] = i + 1 + nx * j;
            q[2] = i + 1 + nx * (j + 1);
            q[3] = i + nx * (j + 1);
        }
    m->vertex_mass = 1e-4f;
    m->stiffness = 1000.0f;
    return 0;
}

static int cmp_pair(const void *a, const void *b) {
    const uint32_t *x = a, *y = b;
    if (x[0] != y[0])
        return x[0] < y[0] ? -1 : 1;
    return x[1] < y[1] ? -1 : x[1] > y[1];
}

int bench_mesh_finish(bench_mesh *m) {
    free(m->springs);
    free(m->rest_len);
    free(m->pinned);
    m->springs = NULL;
    m->rest_len = NULL;
    m->pinned = NULL;
    size_t cap = (size_t)m->quad_count * 4 + m->extra_count;
    uint32_t *pairs = malloc((cap ? cap : 1) * 2 * sizeof *pairs);
    m->pinned = calloc(m->n ? m->n : 1, 1);
    if (!pairs || !m->pinned) {
        free(pairs);
        return -1;
    }
    size_t count = 0;
    for (uint32_t q = 0; q < m->quad_count; ++q)
        for (int e = 0; e < 4; ++e) {
            uint32_t a = m->quads[4 * (size_t)q + e], b = m->quads[4 * (size_t)q + (e + 1) % 4];
            pairs[2 * count] = a < b ? a : b;
            pairs[2 * count + 1] = a < b ? b : a;
            ++count;
        }
    for (uint32_t s = 0; s < m->extra_count; ++s) {
        uint32_t a = m->extra[2 * (size_t)s], b = m->extra[2 * (size_t)s + 1];
        pairs[2 * count] = a < b ? a : b;
        pairs[2 * count + 1] = a < b ? b : a;
        ++count;
    }
    qsort(pairs, count, 2 * sizeof *pairs, cmp_pair);
    size_t unique = 0;
    for (size_t k = 0; k < count; ++k) {
        if (unique && pairs[2 * k] == pairs[2 * (unique - 1)] &&
            pairs[2 * k + 1] == pairs[2 * (unique - 1) + 1])
            continue;
        pairs[2 * unique] = pairs[2 * k];
        pairs[2 * unique + 1] = pairs[2 * k + 1];
        ++unique;
    }
    m->springs = pairs;
    m->spring_count = (uint32_t)unique;
    m->rest_len = malloc((unique ? unique : 1) * sizeof *m->rest_len);
    if (!m->rest_len)
        return -1;
    for (size_t s = 0; s < unique; ++s) {
        const float *a = m->rest + 3 * (size_t)pairs[2 * s], *b = m->rest + 3 * (size_t)pairs[2 * s + 1];
        double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
        m->rest_len[s] = sqrt(dx * dx + dy * dy + dz * dz);
    }
    for (uint32_t k = 0; k < m->pin_count; ++k)
        m->pinned[m->pins[k]] = 1;
    return 0;
}

int bench_mesh_from_scene(const rbc_scene *sc, bench_mesh *m) {
    const rbc_scene_cloth *c = &sc->cloths[0];
    memset(m, 0, sizeof *m);
    m->n = c->vertex_count;
    m->quad_count = c->quad_count;
    m->rest = malloc((size_t)m->n * 3 * sizeof *m->rest);
    m->quads = malloc((size_t)m->quad_count * 4 * sizeof *m->quads);
    m->pins = malloc((c->pin_count ? c->pin_count : 1) * sizeof *m->pins);
    if (!m->rest || !m->quads || !m->pins)
        return -1;
    memcpy(m->rest, c->positions, (size_t)m->n * 3 * sizeof *m->rest);
    memcpy(m->quads, c->quads, (size_t)m->quad_count * 4 * sizeof *m->quads);
    memcpy(m->pins, c->pins, c->pin_count * sizeof *m->pins);
    m->pin_count = c->pin_count;
    m->vertex_mass = c->vertex_mass;
    m->stiffness = c->stiffness;
    m->damping = c->damping;
    if (c->from_grid) {
        m->nx = c->grid.nx;
        m->ny = c->grid.ny;
    }
    return bench_mesh_finish(m);
}

void bench_mesh_free(bench_mesh *m) {
    free(m->rest);
    free(m->quads);
    free(m->extra);
    free(m->masses);
    free(m->pins);
    free(m->springs);
    free(m->rest_len);
    free(m->pinned);
    memset(m, 0, sizeof *m);
}

double bench_free_mass(const bench_mesh *m) {
    double total = 0.0;
    for (uint32_t i = 0; i < m->n; ++i)
        if (!m->pinned[i])
            total += bench_mass(m, i);
    return total;
}

/* |p_a - p_b| - L for spring s. */
static inline double violation(const bench_mesh *m, const float *xyz, uint32_t s) {
    const float *a = xyz + 3 * (size_t)m->springs[2 * (size_t)s];
    const float *b = xyz + 3 * (size_t)m->springs[2 * (size_t)s + 1];
    double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz) - m->rest_len[s];
}

double bench_eq7(const bench_mesh *m, const float *xyz) {
    double sum = 0.0;
    for (uint32_t s = 0; s < m->spring_count; ++s) {
        double v = violation(m, xyz, s);
        sum += v * v;
    }
    return sum;
}

double bench_spring_energy(const bench_mesh *m, const float *xyz) {
    return 0.5 * (double)m->stiffness * bench_eq7(m, xyz);
}

double bench_max_strain(const bench_mesh *m, const float *xyz) {
    double worst = 0.0;
    for (uint32_t s = 0; s < m->spring_count; ++s) {
        if (!(m->rest_len[s] > 0.0))
            continue;
        double e = fabs(violation(m, xyz, s) / m->rest_len[s]);
        if (e > worst)
            worst = e;
    }
    return worst;
}

double bench_kinetic_energy(const bench_mesh *m, const float *x, const float *q, double h) {
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    return bench_kinetic_energy_in_frame(m, x, q, h, zero);
}

double bench_kinetic_energy_in_frame(const bench_mesh *m, const float *x, const float *q, double h,
                                     const float u[3]) {
    double sum = 0.0;
    for (uint32_t i = 0; i < m->n; ++i) {
        if (m->pinned[i])
            continue; /* kinematic: a pin moved by the host is not cloth motion */
        double v2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double v = ((double)x[3 * (size_t)i + a] - q[3 * (size_t)i + a]) / h - u[a];
            v2 += v * v;
        }
        sum += 0.5 * bench_mass(m, i) * v2;
    }
    return sum;
}

double bench_kinetic_energy_rounding(const bench_mesh *m, const float *x, const float *q,
                                     double h, const float u[3], double delta) {
    double sum = 0.0;
    for (uint32_t i = 0; i < m->n; ++i) {
        if (m->pinned[i])
            continue;
        double v2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double v = ((double)x[3 * (size_t)i + a] - q[3 * (size_t)i + a]) / h - u[a];
            v2 += v * v;
        }
        sum += bench_mass(m, i) * (sqrt(3.0 * v2) * delta + 1.5 * delta * delta);
    }
    return sum;
}

double bench_gravity_work(const bench_mesh *m, const float *x0, const float *x,
                          const float g[3]) {
    double sum = 0.0;
    for (uint32_t i = 0; i < m->n; ++i) {
        if (m->pinned[i])
            continue;
        double w = 0.0;
        for (int a = 0; a < 3; ++a)
            w += (double)g[a] * ((double)x[3 * (size_t)i + a] - x0[3 * (size_t)i + a]);
        sum += bench_mass(m, i) * w;
    }
    return sum;
}

void bench_inertial_target(const bench_mesh *m, const float *x, const float *q, double h,
                           const float g[3], const float *pin_pos, double *y) {
    /* The library computes in float: keep = 1 - damping * h clamped at 0. */
    float keep = 1.0f - m->damping * (float)h;
    if (keep < 0.0f)
        keep = 0.0f;
    for (uint32_t i = 0; i < m->n; ++i)
        for (int a = 0; a < 3; ++a) {
            size_t k = 3 * (size_t)i + a;
            if (m->pinned[i])
                y[k] = pin_pos ? pin_pos[k] : x[k];
            else
                y[k] = (double)x[k] + ((double)x[k] - q[k]) * keep + h * h * g[a];
        }
}

static inline double pos(const double *pd, const float *pf, size_t k) {
    return pd ? pd[k] : (double)pf[k];
}

double bench_pd_objective(const bench_mesh *m, const double *y, const double *pd,
                          const float *pf, double h) {
    double inertial = 0.0;
    for (uint32_t i = 0; i < m->n; ++i) {
        if (m->pinned[i])
            continue;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double d = pos(pd, pf, 3 * (size_t)i + a) - y[3 * (size_t)i + a];
            d2 += d * d;
        }
        inertial += bench_mass(m, i) / (2.0 * h * h) * d2;
    }
    double spring = 0.0;
    for (uint32_t s = 0; s < m->spring_count; ++s) {
        size_t a = 3 * (size_t)m->springs[2 * (size_t)s], b = 3 * (size_t)m->springs[2 * (size_t)s + 1];
        double dx = pos(pd, pf, a) - pos(pd, pf, b);
        double dy = pos(pd, pf, a + 1) - pos(pd, pf, b + 1);
        double dz = pos(pd, pf, a + 2) - pos(pd, pf, b + 2);
        double v = sqrt(dx * dx + dy * dy + dz * dz) - m->rest_len[s];
        spring += v * v;
    }
    return inertial + 0.5 * (double)m->stiffness * spring;
}

double bench_spring_energy_rounding(const bench_mesh *m, const float *xyz) {
    double sum = 0.0;
    for (uint32_t s = 0; s < m->spring_count; ++s) {
        double v = violation(m, xyz, s);
        sum += fabs(v) * (v + 2.0 * m->rest_len[s]);
    }
    return ldexp((double)m->stiffness * sum, -22);
}

double bench_linear_residual(const bench_mesh *m, const double *y, const float *p, double h,
                             double *floor_out) {
    size_t n3 = 3 * (size_t)m->n;
    double *r = calloc(n3, sizeof *r), *b = calloc(n3, sizeof *b);
    double *row_scale = calloc(m->n ? m->n : 1, sizeof *row_scale);
    if (!r || !b || !row_scale) {
        free(r);
        free(b);
        free(row_scale);
        return NAN;
    }
    const double s = m->stiffness;
    for (uint32_t i = 0; i < m->n; ++i) {
        if (m->pinned[i])
            continue;
        double w = bench_mass(m, i) / (h * h);
        for (int a = 0; a < 3; ++a)
            row_scale[i] = fmax(row_scale[i], w * fabs(y[3 * (size_t)i + a]));
        for (int a = 0; a < 3; ++a) {
            b[3 * (size_t)i + a] = w * y[3 * (size_t)i + a];
            r[3 * (size_t)i + a] = w * (y[3 * (size_t)i + a] - p[3 * (size_t)i + a]);
        }
    }
    /* Eq. 6 row i: (w_i + sum s) p_i - sum s p_j = w_i y_i + sum s d_ij, with
     * d_ij = L (y_i - y_j) / |y_i - y_j| from the local step at p = y. Pinned
     * neighbours are known: they move to b. */
    for (uint32_t k = 0; k < m->spring_count; ++k) {
        uint32_t v[2] = {m->springs[2 * (size_t)k], m->springs[2 * (size_t)k + 1]};
        const double *ya = y + 3 * (size_t)v[0], *yb = y + 3 * (size_t)v[1];
        double d[3] = {ya[0] - yb[0], ya[1] - yb[1], ya[2] - yb[2]};
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        double scale = len > 0.0 ? m->rest_len[k] / len : 0.0;
        for (int side = 0; side < 2; ++side) {
            uint32_t i = v[side], j = v[1 - side];
            if (m->pinned[i])
                continue;
            double sign = side == 0 ? 1.0 : -1.0;
            double pmax = 0.0;
            for (int a = 0; a < 3; ++a)
                pmax = fmax(pmax, fabs((double)p[3 * (size_t)i + a]) + fabs((double)p[3 * (size_t)j + a]));
            row_scale[i] += s * (pmax + m->rest_len[k]);
            for (int a = 0; a < 3; ++a) {
                double dij = sign * scale * d[a];
                double pj = m->pinned[j] ? y[3 * (size_t)j + a] : (double)p[3 * (size_t)j + a];
                r[3 * (size_t)i + a] += s * (pj + dij - p[3 * (size_t)i + a]);
                b[3 * (size_t)i + a] += s * dij + (m->pinned[j] ? s * pj : 0.0);
            }
        }
    }
    double rn = 0.0, bn = 0.0, fl = 0.0;
    for (size_t k = 0; k < n3; ++k) {
        rn += r[k] * r[k];
        bn += b[k] * b[k];
    }
    for (uint32_t i = 0; i < m->n; ++i)
        fl += 3.0 * row_scale[i] * row_scale[i];
    free(r);
    free(b);
    free(row_scale);
    if (floor_out)
        *floor_out = bn > 0.0 ? ldexp(sqrt(fl / bn), -21) : 0.0;
    return bn > 0.0 ? sqrt(rn / bn) : 0.0;
}

/* ------------------------------------------------------------------------- */
/* Worlds                                                                    */
/* ------------------------------------------------------------------------- */

int bench_world_config_init(const rbc_api_v1 *api, bench_world_config *c) {
    memset(c, 0, sizeof *c);
    c->gravity[1] = -9.81f;
    c->substeps = 1;
    c->nonlinear_iterations = 1;
    c->linear_iterations = 11;
    return api->solver_def_init(&c->solver, (uint32_t)sizeof c->solver) == RBC_OK ? 0 : -1;
}

rbc_result bench_cloth_def(const rbc_api_v1 *api, const bench_mesh *m, rbc_cloth_def *cd) {
    rbc_result r = api->cloth_def_init(cd, (uint32_t)sizeof *cd);
    if (r != RBC_OK) return r;
    cd->vertex_count = m->n;
    cd->positions = m->rest;
    cd->quad_count = m->quad_count;
    cd->quads = m->quads;
    cd->spring_count = m->extra_count;
    cd->springs = m->extra;
    cd->masses = m->masses;
    cd->vertex_mass = m->vertex_mass;
    cd->stiffness = m->stiffness;
    cd->damping = m->damping;
    cd->pin_count = m->pin_count;
    cd->pins = m->pins;
    return RBC_OK;
}

rbc_result bench_world_create(const rbc_api_v1 *api, const bench_mesh *m,
                              const bench_world_config *c, rbc_world_id *out_world,
                              rbc_cloth_id *out_cloth) {
    *out_world = 0;
    *out_cloth = 0;
    rbc_world_def wd;
    rbc_result r = api->world_def_init(&wd, (uint32_t)sizeof wd);
    if (r != RBC_OK)
        return r;
    memcpy(wd.gravity, c->gravity, sizeof wd.gravity);
    wd.substeps = c->substeps;
    wd.nonlinear_iterations = c->nonlinear_iterations;
    wd.linear_iterations = c->linear_iterations;
    wd.thread_count = c->threads;
    wd.solver = &c->solver;
    rbc_world_id world;
    r = api->world_create(&wd, &world);
    if (r != RBC_OK)
        return r;

    rbc_cloth_def cd;
    if ((r = bench_cloth_def(api, m, &cd)) == RBC_OK) r = api->cloth_create(world, &cd, out_cloth);
    if (r != RBC_OK) {
        /* last_error() keeps cloth_create's message: it changes only on a failing
         * call, and destroying the world succeeds. */
        api->world_destroy(world);
        *out_cloth = 0;
        return r;
    }
    *out_world = world;
    return RBC_OK;
}

rbc_result bench_stats(const rbc_api_v1 *api, rbc_world_id world, rbc_world_stats *st) {
    memset(st, 0, sizeof *st);
    st->struct_size = (uint32_t)sizeof *st;
    return api->world_get_stats(world, st);
}

int bench_stats_finite(const rbc_world_stats *st, const char **bad_field) {
    const struct {
        const char *name;
        double value;
    } fields[] = {
        {"step_ms", st->step_ms},           {"integrate_ms", st->integrate_ms},
        {"local_ms", st->local_ms},         {"global_ms", st->global_ms},
        {"collide_ms", st->collide_ms},     {"callback_ms", st->callback_ms},
        {"other_ms", st->other_ms},         {"error_eq7", st->error_eq7},
        {"max_strain", st->max_strain},     {"linear_residual", st->linear_residual},
        {"pd_objective", st->pd_objective}, {"spectral_radius", st->spectral_radius},
        {"omega", st->omega},               {"kinetic_energy", st->kinetic_energy},
        {"potential_energy", st->potential_energy}, {"energy_budget", st->energy_budget},
        {"energy_removed", st->energy_removed},
    };
    for (size_t k = 0; k < sizeof fields / sizeof fields[0]; ++k)
        if (!isfinite(fields[k].value)) {
            if (bad_field)
                *bad_field = fields[k].name;
            return 0;
        }
    return 1;
}

long bench_first_nonfinite(const float *v, size_t count) {
    for (size_t k = 0; k < count; ++k)
        if (!isfinite(v[k]))
            return (long)k;
    return -1;
}

/* ------------------------------------------------------------------------- */
/* Small helpers                                                             */
/* ------------------------------------------------------------------------- */

double bench_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double bench_median(const double *v, size_t n) {
    if (n == 0)
        return 0.0;
    double *copy = malloc(n * sizeof *copy);
    if (!copy)
        return NAN;
    memcpy(copy, v, n * sizeof *copy);
    qsort(copy, n, sizeof *copy, cmp_double);
    double med = n % 2 ? copy[n / 2] : 0.5 * (copy[n / 2 - 1] + copy[n / 2]);
    free(copy);
    return med;
}

void bench_sort(double *v, size_t n) { qsort(v, n, sizeof *v, cmp_double); }

void bench_median_p90(double *v, size_t n, double *median, double *p90) {
    bench_sort(v, n);
    *median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
    *p90 = v[(size_t)((n - 1) * 0.9)];
}

FILE *bench_open(const char *dir, const char *name) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f)
        fprintf(stderr, "rbcloth: cannot write %s: %s\n", path, strerror(errno));
    return f;
}

FILE *bench_open_ordered(const char *dir, const char *name, const char *bench, size_t rows,
                         size_t **order) {
    FILE *f = bench_open(dir, name);
    if (!f)
        return NULL;
    if (!(*order = malloc((rows ? rows : 1) * sizeof **order))) {
        fclose(f);
        bench_out_of_memory(bench);
        return NULL;
    }
    return f;
}

FILE *bench_open_csv(const char *dir, const char *name, const char *header) {
    FILE *f = bench_open(dir, name);
    if (f)
        fprintf(f, "%s\n", header);
    return f;
}

int bench_close(FILE *f, const char *dir, const char *name) {
    int bad = ferror(f);
    if (fclose(f) != 0 || bad) {
        fprintf(stderr, "rbcloth: cannot write %s/%s: %s\n", dir, name, strerror(errno));
        return -1;
    }
    return 0;
}

int bench_have_gnuplot(void) {
    const char *path = getenv("PATH");
    if (!path)
        return 0;
    char dir[4096];
    while (*path) {
        size_t len = strcspn(path, ":");
        if (len > 0 && len < sizeof dir - 16) {
            memcpy(dir, path, len);
            strcpy(dir + len, "/gnuplot");
            if (access(dir, X_OK) == 0)
                return 1;
        }
        path += len;
        if (*path == ':')
            ++path;
    }
    return 0;
}

int bench_run_gnuplot(const char *dir, const char *script) {
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        if (chdir(dir) != 0)
            _exit(127);
        execlp("gnuplot", "gnuplot", script, (char *)NULL);
        _exit(127);
    }
    int status;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void bench_plot_run(const char *dir, const char *script) {
    int status = bench_run_gnuplot(dir, script);
    if (status != 0)
        fprintf(stderr, "rbcloth: bench: gnuplot %s/%s exited with %d\n", dir, script, status);
}

int bench_gnuplot_or_say(const char *dir, const char *skipped) {
    if (bench_have_gnuplot())
        return 1;
    printf(skipped, dir);
    return 0;
}

void bench_plot(const char *dir, const char *script) {
    if (bench_have_gnuplot())
        bench_plot_run(dir, script);
    else
        printf("Plot skipped: gnuplot is not on PATH. Install it (Debian: apt-get install "
               "gnuplot-nox) and run `gnuplot %s` in %s.\n",
               script, dir);
}

double bench_load_average(void) {
    FILE *f = fopen("/proc/loadavg", "r");
    double load = -1.0;
    if (f) {
        if (fscanf(f, "%lf", &load) != 1)
            load = -1.0;
        fclose(f);
    }
    return load;
}

void *bench_grow(void *p, size_t *cap, size_t count, size_t size, size_t first) {
    if (count < *cap)
        return p;
    size_t n = *cap ? 2 * *cap : first;
    void *grown = realloc(p, n * size);
    if (grown)
        *cap = n;
    return grown;
}

int bench_reserve_samples(double **samples, int count, uint32_t *cap, uint32_t n) {
    if (n <= *cap)
        return 0;
    for (int k = 0; k < count; ++k) {
        double *p = realloc(samples[k], n * sizeof *p);
        if (!p)
            return -1;
        samples[k] = p;
    }
    *cap = n;
    return 0;
}

int bench_out_of_memory(const char *bench) {
    fprintf(stderr, "rbcloth: out of memory in the %s bench\n", bench);
    return 1;
}

uint32_t bench_thread_list(const cli_bench_options *options, uint32_t list[2]) {
    uint32_t many = options->threads >= 0 ? (uint32_t)options->threads : 2u, count = 0;
    list[count++] = 1;
    if (many != 1)
        list[count++] = many;
    return count;
}

void bench_cpu_model(char *buf, size_t size, int fallbacks) {
    snprintf(buf, size, "unknown");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return;
    char line[512];
    int found = 0;
    while (fgets(line, sizeof line, f)) {
        const char *keys[] = {"model name", "Hardware", "CPU part"};
        for (int k = 0; k < (fallbacks ? 3 : 1) && !found; ++k) {
            size_t len = strlen(keys[k]);
            if (strncmp(line, keys[k], len) != 0)
                continue;
            const char *colon = strchr(line, ':');
            if (!colon)
                continue;
            const char *v = colon + 1;
            while (*v == ' ' || *v == '\t')
                ++v;
            snprintf(buf, size, "%s", v);
            found = k == 0; /* keep looking for "model name" after a fallback */
        }
        if (found)
            break;
    }
    fclose(f);
    size_t len = strlen(buf);
    while (len && (buf[len - 1] == '\n' || buf[len - 1] == ' '))
        buf[--len] = '\0';
    for (char *p = buf; *p; ++p)
        if (*p == ',' || *p == '\'' || *p == '"')
            *p = ';';
}

int bench_report(const rbc_api_v1 *api, rbc_result r, const char *context) {
    fprintf(stderr, "rbcloth: %s: %s%s%s\n", api->result_string(r), api->last_error(),
            context ? " " : "", context ? context : "");
    return 1;
}

const char *bench_result_text(const rbc_api_v1 *api, rbc_result r, char *buf, size_t size) {
    snprintf(buf, size, "%s: %s", api->result_string(r), api->last_error());
    return buf;
}

/* ------------------------------------------------------------------------- */
/* Provenance of a results page                                              */
/* ------------------------------------------------------------------------- */

/* The first line a shell command prints, without its newline ("" if none). */
static void first_line_of(const char *command, char *out, size_t size) {
    out[0] = '\0';
    FILE *p = popen(command, "r");
    if (!p) return;
    if (fgets(out, (int)size, p)) out[strcspn(out, "\r\n")] = '\0';
    pclose(p);
}

/* The value of "key: value" or key=value in a text file ("" if absent). */
static void field_of(const char *path, const char *key, char sep, char *out, size_t size) {
    out[0] = '\0';
    FILE *f = fopen(path, "r");
    if (!f) return;
    char line[512];
    size_t klen = strlen(key);
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, key, klen) != 0) continue;
        char *v = strchr(line + klen, sep);
        if (!v) continue;
        v++;
        while (*v == ' ' || *v == '\t' || *v == '"') v++;
        v[strcspn(v, "\"\r\n")] = '\0';
        snprintf(out, size, "%s", v);
        break;
    }
    fclose(f);
}

int bench_require_minor(const cli_plugin *plugin, const char *bench, uint32_t minor) {
    if ((plugin->api->abi_version_fn() & 0xFFFFu) >= minor)
        return 0;
    fprintf(stderr, "rbcloth: bench %s needs a plugin of ABI 1.%u or later\n", bench, minor);
    return 1;
}

void bench_write_provenance(FILE *md, const char *bench, const cli_bench_options *options) {
    char command[512], when[64], commit[64], dirty[64], cpu[256], os[256];
    snprintf(command, sizeof command, "rbcloth bench %s --out %s%s", bench, options->out_dir,
             options->quick ? " --quick" : "");
    time_t t = time(NULL);
    struct tm tm;
    gmtime_r(&t, &tm);
    strftime(when, sizeof when, "%Y-%m-%d %H:%M UTC", &tm);
#ifdef RBC_SOURCE_DIR
    first_line_of("git -C '" RBC_SOURCE_DIR "' rev-parse --short HEAD 2>/dev/null", commit,
                  sizeof commit);
    first_line_of("git -C '" RBC_SOURCE_DIR "' status --porcelain --untracked-files=no "
                  "2>/dev/null",
                  dirty, sizeof dirty);
#else
    commit[0] = dirty[0] = '\0';
#endif
    field_of("/proc/cpuinfo", "model name", ':', cpu, sizeof cpu);
    field_of("/etc/os-release", "PRETTY_NAME", '=', os, sizeof os);
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    double gib = (double)sysconf(_SC_PHYS_PAGES) * (double)sysconf(_SC_PAGESIZE) / 1073741824.0;
    fprintf(md, "Regenerate: `%s`\n\n", command);
    fprintf(md, "Measured: %s; commit %s%s; %s, %ld cores, %.0f GiB, %s; load average %.2f at "
                "the start.\n\n",
            when, commit[0] ? commit : "unknown", dirty[0] ? " + uncommitted changes" : "",
            cpu[0] ? cpu : "unknown CPU", cores, gib, os[0] ? os : "unknown OS",
            bench_load_average());
}
