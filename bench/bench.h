/* bench.h -- what `rbcloth bench accuracy`, `stability`, `perf`, `scenes` and `peers`
 * share:
 * the solver list, a host-side copy of a cloth's mesh (to evaluate Eq. 7, spring
 * energy and the Projective Dynamics objective without trusting the library's
 * stats), world creation through the function table, CSV and gnuplot helpers.
 *
 * Everything goes through `const rbc_api_v1 *` (ABI 1.1 entries included): the
 * benches are hosts like any other and never link the plugin.
 */
#ifndef RBC_BENCH_H
#define RBC_BENCH_H

#include <stdint.h>
#include <stdio.h>

#include "plugin.h"

/* ------------------------------------------------------------------------- */
/* Options and entry points                                                  */
/* ------------------------------------------------------------------------- */

typedef struct cli_bench_options {
    /// Output directory (created like mkdir -p). Default "out/bench".
    const char *out_dir;
    /// Frames per run (accuracy: per scene and solver); -1 = the bench's default.
    long frames;
    /// Worker threads of every world; -1 = the library's default (one per core).
    /// perf measures 1 thread and this many (-1 there: 2).
    long threads;
    /// Fewer frames, budgets and cases: a smoke run for the tests.
    int quick;
    /// perf only: the worlds' rbc_backend (--backend cpu|cuda). Default RBC_BACKEND_CPU.
    int backend;
    /// perf only: time the set-up (cloth creation) of the 1M grid and the 1M
    /// irregular mesh, this many times each, and nothing else (--setup-only N); 0 = off.
    long setup_only;
    /// perf only (--irregular): the grid-against-irregular comparison alone, i.e. the
    /// irregular meshes and the grids of their sizes, without the other sections.
    int irregular_only;
} cli_bench_options;

/// `rbcloth bench accuracy`: the paper's Fig. 3/4 experiments for every solver.
/// Returns the process exit code (0, or 1 after a message on stderr).
int cli_bench_accuracy(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench stability`: a stability map of every solver over stress
/// dimensions. Returns 0, or 1 after a message; a NaN reaching the host is
/// reported on stderr and in the outputs but still returns 0 (the map is the
/// result; bench/checks checks it).
int cli_bench_stability(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench perf`: ms per frame, per stage, particle updates per second, setup
/// time and memory of RBGS on 1K .. 1M particle grids with 1 and N threads, an
/// irregular quad mesh against the grid, and Jacobi and serial Gauss-Seidel at equal
/// iterations (issue 4). Returns 0, or 1 after a message on stderr.
int cli_bench_perf(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench scenes`: the paper's scenes (samples/scenes: chair, four layers and
/// a sphere, funnel, cannonballs and tearing; cloth_on_sphere and hanging_cloth for
/// reference) with 1 and N threads, collisions included, beside the paper's figures
/// (ABI 1.3). Returns 0, or 1 after a message on stderr.
int cli_bench_scenes(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench peers`: rbcloth's configurations (solver, substeps, non-linear and
/// linear iterations, SOR omega, Chebyshev rho, energy guard) on the peer scene of
/// docs/facts.md, their Pareto front of ms per frame against Eq. 7 at the last frame,
/// beside the peers' published figures (issue 7). One thread unless --threads says
/// otherwise. Returns 0, or 1 after a message on stderr.
int cli_bench_peers(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench defaults`: the default solve beside the presets and other substep
/// rates on the paper's cloth and a 64 x 48 grid at 1/240, 1/60 and 1/30 s: largest
/// and RMS strain, sag, ms per frame (issue 16). One thread unless --threads says
/// otherwise. Returns 0, or 1 after a message on stderr.
int cli_bench_defaults(const cli_plugin *plugin, const cli_bench_options *options);

/// `rbcloth bench pool`: ms per step with 1 thread, the default thread count and
/// every core, idle and with one busy loop per core (issue 17). Returns 0, or 1.
int cli_bench_pool(const cli_plugin *plugin, const cli_bench_options *options);

/// What the context of each bench that measures starts with: the plugin's function
/// table, the options and the output folder (their out_dir).
typedef struct bench_run {
    const rbc_api_v1 *api;
    const cli_bench_options *opt;
    const char *dir;
} bench_run;

static inline bench_run bench_run_of(const cli_plugin *plugin, const cli_bench_options *options) {
    bench_run run = {plugin->api, options, options->out_dir};
    return run;
}

/// The head of a results page (docs/results/): the command that regenerates it
/// (`rbcloth bench BENCH --out DIR`, --quick as given), and the date (UTC), the commit
/// of the source tree this binary was built from (with "+ uncommitted changes" when
/// the tree differs; "unknown" without git) and the machine (CPU model, cores,
/// memory, OS, load average) of this run.
void bench_write_provenance(FILE *md, const char *bench, const cli_bench_options *options);

/// The plugin is of ABI 1.minor or later, as `rbcloth bench BENCH` needs. Returns 0, or
/// 1 after a message on stderr.
int bench_require_minor(const cli_plugin *plugin, const char *bench, uint32_t minor);

/* ------------------------------------------------------------------------- */
/* Solvers                                                                   */
/* ------------------------------------------------------------------------- */

enum { BENCH_SOLVER_COUNT = 8 };

typedef struct bench_solver {
    rbc_solver_kind kind;
    /// Short name for CSV, plots and tables: "rbgs", "jacobi", ...
    const char *name;
    /// 1 if the solver's sweeps run in parallel (all but serial Gauss-Seidel and the
    /// direct solve).
    int parallel;
    /// 1 if linear iteration counts apply (all but the direct solver).
    int iterative;
} bench_solver;

/// Every rbc_solver_kind of ABI 1.1, in enum order.
extern const bench_solver bench_solvers[BENCH_SOLVER_COUNT];

/// The plugin has the ABI 1.1 entries the benches call. Returns 0, or -1 with a
/// message on stderr.
int bench_require_v1_1(const cli_plugin *plugin);

/* ------------------------------------------------------------------------- */
/* Host copy of a cloth                                                      */
/* ------------------------------------------------------------------------- */

/// A cloth as the host creates it, plus the spring list the library derives from it
/// (quad edges and explicit springs, each pair once), so the host can evaluate
/// energies itself. All arrays malloc'd; bench_mesh_free releases them.
typedef struct bench_mesh {
    uint32_t n;
    /// Rest positions (x y z per vertex), metres: also the creation positions.
    float *rest;
    uint32_t quad_count;
    uint32_t *quads;
    /// Explicit springs given to the library (2 indices each).
    uint32_t extra_count;
    uint32_t *extra;
    /// Per-vertex masses (kg) or NULL: then every vertex has vertex_mass.
    float *masses;
    float vertex_mass;
    /// N/m (every spring), 1/s.
    float stiffness;
    float damping;
    uint32_t pin_count;
    uint32_t *pins;
    /// Derived by bench_mesh_finish: unique springs (a < b) and their rest lengths
    /// (m, from `rest` in double), and a per-vertex pinned flag.
    uint32_t spring_count;
    uint32_t *springs;
    double *rest_len;
    uint8_t *pinned;
    /// Grid size when made by bench_mesh_grid (0 otherwise).
    uint32_t nx, ny;
} bench_mesh;

/// An nx x ny grid (vertex (i, j) = i + nx j) in the xz plane at height y0 (plane 0)
/// or the xy plane (plane 1), `spacing` metres, vertex_mass 1e-4 kg, k 1000 N/m,
/// no damping, no pins. Returns 0, or -1 when out of memory / invalid.
int bench_mesh_grid(bench_mesh *m, uint32_t nx, uint32_t ny, double spacing, int plane,
                    double y0);
/// Derive springs, rest lengths and pinned flags (call after changing quads, extra
/// springs, pins or rest positions). Returns 0, or -1 when out of memory.
int bench_mesh_finish(bench_mesh *m);
/// The first cloth of a loaded scene (samples/scene.h) as a bench_mesh: arrays
/// copied, springs derived. Returns 0, or -1 when out of memory.
struct rbc_scene;
int bench_mesh_from_scene(const struct rbc_scene *sc, bench_mesh *m);
void bench_mesh_free(bench_mesh *m);

static inline double bench_mass(const bench_mesh *m, uint32_t i) {
    return m->masses ? (double)m->masses[i] : (double)m->vertex_mass;
}

/// Total mass of the free (unpinned) vertices, kg.
double bench_free_mass(const bench_mesh *m);

/// Eq. 7: sum over springs of (|p_a - p_b| - L)^2, m^2, in double.
double bench_eq7(const bench_mesh *m, const float *xyz);
/// Spring energy sum s/2 (|p_a - p_b| - L)^2, J.
double bench_spring_energy(const bench_mesh *m, const float *xyz);
/// Largest | |p_a - p_b| / L - 1 | over springs with L > 0.
double bench_max_strain(const bench_mesh *m, const float *xyz);
/// Kinetic energy of the free vertices from the Verlet state, J:
/// sum m_i / 2 |(x_i - q_i) / h|^2.
double bench_kinetic_energy(const bench_mesh *m, const float *x, const float *q, double h);
/// The same in a frame moving at velocity u (m/s): velocities v - u.
double bench_kinetic_energy_in_frame(const bench_mesh *m, const float *x, const float *q, double h,
                                     const float u[3]);
/// How much that kinetic energy can change when every velocity component changes by
/// at most delta (m/s): sum m (sqrt(3) |v - u| delta + 3/2 delta^2), J.
double bench_kinetic_energy_rounding(const bench_mesh *m, const float *x, const float *q,
                                     double h, const float u[3], double delta);
/// Work done by gravity on the free vertices since `x0`, J: sum m_i g . (x_i - x0_i).
double bench_gravity_work(const bench_mesh *m, const float *x0, const float *x,
                          const float g[3]);

/// The inertial target of Alg. 2 for the free vertices: y = x + (x - q) keep + h^2 g,
/// keep = max(0, 1 - damping h) (the library's clamp); pinned vertices get
/// `pin_pos` (their pin targets; NULL = x). Written into y (3n doubles).
void bench_inertial_target(const bench_mesh *m, const float *x, const float *q, double h,
                           const float g[3], const float *pin_pos, double *y);
/// Projective Dynamics objective at positions p (3n doubles or floats via one of
/// the two pointers): sum_free m_i/(2h^2) |p_i - y_i|^2 + sum_s s/2 (|p_a-p_b|-L)^2, J.
double bench_pd_objective(const bench_mesh *m, const double *y, const double *pd,
                          const float *pf, double h);
/// Relative residual |b - A p| / |b| of Eq. 6 over the free vertices, with the local
/// step evaluated at `y` (one non-linear iteration: the local step sees p = y) and
/// pinned vertices at y. Used to check stats.linear_residual. *floor_out (if not
/// NULL) receives what float evaluation can change in it: each row of Eq. 6 sums at
/// most 8 rounded terms, 2^-21 times |w y| + sum s (|p_i| + |p_j| + L) per row.
double bench_linear_residual(const bench_mesh *m, const double *y, const float *p, double h,
                             double *floor_out);
/// How much the spring energy at xyz can change when each spring length and rest
/// length is evaluated in float: sum s |v| (|v| + 2L) 2^-22, J (v = |p_a-p_b| - L).
double bench_spring_energy_rounding(const bench_mesh *m, const float *xyz);

/* ------------------------------------------------------------------------- */
/* Worlds                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct bench_world_config {
    float gravity[3];
    uint32_t substeps;
    uint32_t nonlinear_iterations;
    uint32_t linear_iterations;
    /// 0 = one per core.
    uint32_t threads;
    rbc_solver_def solver;
} bench_world_config;

/// Defaults: gravity (0, -9.81, 0), 1 substep, 1 non-linear and 11 linear
/// iterations, the library's thread default and solver def (RBGS, FIXED).
int bench_world_config_init(const rbc_api_v1 *api, bench_world_config *c);

/// A cloth def of the library's defaults with `m`'s mesh, masses, stiffness, damping
/// and pins (the arrays point into m).
rbc_result bench_cloth_def(const rbc_api_v1 *api, const bench_mesh *m, rbc_cloth_def *cd);

/// A world with one cloth made from `m`. Returns the library's result (message in
/// api->last_error()); nothing is left created on failure.
rbc_result bench_world_create(const rbc_api_v1 *api, const bench_mesh *m,
                              const bench_world_config *c, rbc_world_id *out_world,
                              rbc_cloth_id *out_cloth);

/// Stats with struct_size set.
rbc_result bench_stats(const rbc_api_v1 *api, rbc_world_id world, rbc_world_stats *st);

/// 1 if every floating-point field of the stats is finite.
int bench_stats_finite(const rbc_world_stats *st, const char **bad_field);
/// Index of the first non-finite float in v[0..count), or -1.
long bench_first_nonfinite(const float *v, size_t count);

/* ------------------------------------------------------------------------- */
/* Small helpers                                                             */
/* ------------------------------------------------------------------------- */

double bench_now(void);
/// Median of v[0..n) (sorts a copy; 0 when n == 0).
double bench_median(const double *v, size_t n);
/// Sort v[0..n) ascending.
void bench_sort(double *v, size_t n);
/// Sort v[0..n) (n > 0), then its median (the mean of the middle two when n is even)
/// and its p90 (v[(n - 1) 0.9], rounded down).
void bench_median_p90(double *v, size_t n, double *median, double *p90);
/// fopen(dir/name, "w") with a message on stderr on failure.
FILE *bench_open(const char *dir, const char *name);
/// bench_open, and *order room for an ordering of a table's `rows` rows (malloc'd, at
/// least one entry). NULL after a message when either fails (nothing left open).
FILE *bench_open_ordered(const char *dir, const char *name, const char *bench, size_t rows,
                         size_t **order);
/// bench_open, then `header` and a newline: a CSV file's first line.
FILE *bench_open_csv(const char *dir, const char *name, const char *header);
/// fclose with an error check; message on stderr on failure. Returns 0 or -1.
int bench_close(FILE *f, const char *dir, const char *name);
/// 1 if an executable `gnuplot` is on PATH.
int bench_have_gnuplot(void);
/// Run `gnuplot SCRIPT` inside dir. Returns its exit status (or -1).
int bench_run_gnuplot(const char *dir, const char *script);
/// The 1-minute load average (/proc/loadavg), or -1 where unknown: timings taken
/// while other processes compete for the cores are not the solver's.
double bench_load_average(void);
/// Room for element `count` of the array p, *cap elements of `size` bytes: p as it
/// is, or reallocated to twice as many (`first` when empty). NULL when out of
/// memory, p and *cap then unchanged.
void *bench_grow(void *p, size_t *cap, size_t count, size_t size, size_t first);
/// Room for n values in each of the `count` per-frame arrays samples[] (*cap each,
/// grown together). Returns 0, or -1 when out of memory.
int bench_reserve_samples(double **samples, int count, uint32_t *cap, uint32_t n);
/// "rbcloth: out of memory in the <bench> bench" on stderr; returns 1.
int bench_out_of_memory(const char *bench);
/// Run `gnuplot script` in dir when gnuplot is on PATH, else say on stdout how to;
/// a gnuplot that fails is reported on stderr but is no error of the bench (the CSV
/// and the tables are its results).
void bench_plot(const char *dir, const char *script);
/// The same, when gnuplot is known to be there: only the run and its report.
void bench_plot_run(const char *dir, const char *script);
/// 1 if gnuplot is on PATH; else 0 after `skipped` (a printf format of dir, the
/// folder of the scripts) on stdout.
int bench_gnuplot_or_say(const char *dir, const char *skipped);
/// The CPU's model name from /proc/cpuinfo ("model name"; with `fallbacks`, else
/// "Hardware" or "CPU part" as some ARM kernels have them), "unknown" without one,
/// with commas and quotes replaced so that it fits a CSV field and a gnuplot title.
void bench_cpu_model(char *buf, size_t size, int fallbacks);
/// The thread counts a bench that compares them measures: 1 and, unless it is 1,
/// --threads (default 2). Returns how many (1 or 2); the last is the larger.
uint32_t bench_thread_list(const cli_bench_options *options, uint32_t list[2]);
/// "rbcloth: <result>: <last error>" on stderr; returns 1.
int bench_report(const rbc_api_v1 *api, rbc_result r, const char *context);
/// The same message as a string (for tables), into buf.
const char *bench_result_text(const rbc_api_v1 *api, rbc_result r, char *buf, size_t size);

#endif
