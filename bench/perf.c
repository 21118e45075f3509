/* perf.c -- `rbcloth bench perf`: what a frame costs and how it scales
 * (issue 4). Everything runs through the function table, as any host would.
 *
 * Setup: the paper's hanging cloth (samples/scenes/hanging_cloth.json) at other
 * sizes: an n x n grid, 1 m square (spacing 1/(n-1) m) in the xz plane, 1e-4 kg per
 * vertex, k = 1000 N/m, no damping, pinned at the corners (0, 0) and (1, 0), gravity
 * -9.81 m/s^2, h = 2 ms, 1 substep, 1 non-linear and 11 linear iterations; the other
 * solver settings are the library's defaults. Measured:
 *
 *   1. scaling   RBGS on grids of 1K .. 1M particles with 1 and N threads (default
 *                N = 2): the median over frames of stats.step_ms and of each stage
 *                (integrate, local, global, other), particle updates per second
 *                (particles x linear iterations / step time), the wall time of
 *                rbc_cloth_create (coloring, reordering, allocation) and
 *                stats.memory_bytes per particle and per spring;
 *   2. speedup   N threads over 1, per size;
 *   3. irregular an all-quad mesh with no grid structure at the same sizes: a
 *                triangulated grid with jittered interior vertices and random
 *                diagonals, each triangle split into 3 quads (vertex, edge midpoints,
 *                centroid; Catmull-Clark's first step), vertices and quads shuffled
 *                with a fixed seed. Its spring graph is bipartite ({vertices,
 *                centroids} against {midpoints}) with valences 3 to 8, so RBGS still
 *                has two colors but no regular stencil. Reported as time per
 *                particle-iteration against the grid's (target: within 1.5x);
 *   4. solvers   RBGS, Jacobi and serial Gauss-Seidel at equal iterations (11) on
 *                the 100 x 100 grid, 1 and N threads.
 *   5. readback  (ABI 1.10) what a renderer's read costs per frame on the grids:
 *                rbc_cloth_read_positions, rbc_world_read_vertices with positions
 *                only (stride 12), positions and normals interleaved (stride 24)
 *                and normals alone, against the step they follow; the four reads
 *                alternate, medians over PERF_READS rounds (perf_readback.csv).
 *
 * Each configuration runs 2 warm-up frames (first-touch page faults, lazily sized
 * buffers) and then F frames; the stage columns are medians of each stage on its
 * own, so they need not add up to the median step. Timings are the library's
 * (stats), the host's wall time around rbc_world_step is kept beside them as a
 * cross-check. Outputs: perf.csv, perf.md and perf_scaling.png (gnuplot) in DIR.
 * Timings mean something only on an otherwise idle machine: the load average is
 * recorded with them.
 */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "fsutil.h"

enum { PERF_WARMUP = 2, PERF_MAX_ROWS = 64, PERF_MIN_JIFFIES = 20 };

/// The scene's time step (samples/scenes/hanging_cloth.json), s.
#define PERF_DT 0.002f
/// Linear iterations of every run (Alg. 1 line 4, the paper's count).
#define PERF_ITERATIONS 11u
/// Seed of the irregular mesh's jitter, diagonals and shuffles (any fixed value).
#define PERF_SEED 0x5eedc107ULL
/// Target of the grid-vs-irregular comparison (issue 4).
#define PERF_IRREGULAR_TARGET 1.5
/// Others' CPU share above which a configuration's timings are flagged: on 2 cores
/// 10% is a fifth of one core, enough to stall a spinning barrier now and then.
#define PERF_OTHERS_SUSPECT 0.10

typedef enum perf_mesh_kind { PERF_GRID, PERF_IRREGULAR } perf_mesh_kind;

static const char *const mesh_names[] = {"grid", "irregular"};

/* One measured configuration and its medians. */
typedef struct perf_row {
    perf_mesh_kind mesh;
    /// Index into bench_solvers.
    uint32_t solver;
    /// Grid side n: the grid has n x n particles, the irregular mesh about as many.
    uint32_t side;
    /// Threads asked for (0 = one per core) and reported by stats.
    uint32_t threads_requested, threads;
    uint32_t particles, springs, colors;
    uint32_t frames_asked, frames;
    uint32_t linear_iterations;
    double step_ms, integrate_ms, local_ms, global_ms, other_ms, wall_ms;
    double setup_ms;
    /// stats.memory_bytes; 0 = not reported (a 1.1 plugin, or one that does not
    /// fill it yet).
    uint64_t memory_bytes;
    /// Share of the machine's CPU time that other processes (and the hypervisor's
    /// steal) took while the frames ran, 0..1; NaN when the run was too short to
    /// tell (under PERF_MIN_JIFFIES).
    double others_cpu;
    /// Set when a step failed: the medians are over the frames before it.
    char note[256];
} perf_row;

/* Section 5: one grid's reads, ms (medians), beside its step on one thread. */
enum { PERF_READS = 200, PERF_READ_KINDS = 4, PERF_MAX_READBACK = 8 };
typedef struct perf_readback {
    uint32_t side, particles;
    double step_ms;
    double ms[PERF_READ_KINDS];
} perf_readback;

typedef struct perf_ctx {
    bench_run run;
    /// The ABI minor of the plugin: 2 has memory_bytes and the energy guard.
    uint32_t abi_minor;
    /// The thread counts measured: 1 and, unless it is 1, threads_many.
    uint32_t thread_list[2], thread_count;
    uint32_t threads_many;
    /// Grid side of the solver comparison (100: the paper's 10K cloth).
    uint32_t solver_side;
    /// "off", "clamp", "fail" (ABI 1.2) or "n/a".
    const char *energy_guard;
    perf_row rows[PERF_MAX_ROWS];
    uint32_t row_count;
    /// Rows in the order of perf.csv (series contiguous for gnuplot).
    uint32_t order[PERF_MAX_ROWS];
    /// Scratch per frame, sized for the largest frame count.
    double *samples[6];
    uint32_t sample_cap;
    char cpu[256];
    long cores;
    double load_start, load_end;
    uint32_t failed_rows;
    /// Memory bandwidth by a STREAM-style triad, GB/s, with 1 and threads_many
    /// threads (0 if it could not run): the roofline's other axis.
    double triad_gbs[2];
    /// Arithmetic peak of one thread, GFLOP/s (peak_loop): the roofline's roof.
    double peak_gflops;
    /// Section 5 (ABI 1.10 plugins only).
    perf_readback readback[PERF_MAX_READBACK];
    uint32_t readback_count;
} perf_ctx;

static int out_of_memory(void) { return bench_out_of_memory("perf"); }

/* ------------------------------------------------------------------------- */
/* Machine: memory bandwidth (a STREAM-style triad)                          */
/* ------------------------------------------------------------------------- */

enum { TRIAD_N = 8 * 1024 * 1024 }; /* 3 arrays of 32 MiB: far beyond the caches */

typedef struct triad_arg {
    float *a, *b, *c;
    size_t begin, end;
} triad_arg;

static void *triad_part(void *p) {
    triad_arg *t = p;
    for (size_t i = t->begin; i < t->end; ++i) t->a[i] = t->b[i] + 3.0f * t->c[i];
    return NULL;
}

/* Best of 5 triads a = b + 3 c over TRIAD_N floats with `threads` threads, counting
 * 12 bytes per element (two loads, one store; the write-allocate read is not
 * counted, as in STREAM). */
static double triad_gbs(uint32_t threads) {
    float *a = malloc(sizeof(float) * TRIAD_N), *b = malloc(sizeof(float) * TRIAD_N),
          *c = malloc(sizeof(float) * TRIAD_N);
    double best = 0.0;
    if (a && b && c && threads >= 1 && threads <= 64) {
        for (size_t i = 0; i < TRIAD_N; ++i) a[i] = 0.0f, b[i] = 1.0f, c[i] = 2.0f;
        pthread_t th[64];
        triad_arg args[64];
        for (int rep = 0; rep < 5; ++rep) {
            double t0 = bench_now();
            for (uint32_t k = 0; k < threads; ++k) {
                args[k] = (triad_arg){a, b, c, (size_t)TRIAD_N * k / threads,
                                      (size_t)TRIAD_N * (k + 1) / threads};
                if (k && pthread_create(&th[k], NULL, triad_part, &args[k]) != 0) {
                    threads = k; /* run with the threads that started */
                    break;
                }
            }
            triad_part(&args[0]);
            for (uint32_t k = 1; k < threads; ++k) pthread_join(th[k], NULL);
            double sec = bench_now() - t0;
            double gbs = sec > 0.0 ? 12.0 * TRIAD_N / sec / 1e9 : 0.0;
            if (gbs > best) best = gbs;
        }
    }
    free(a), free(b), free(c);
    return best;
}


/* ------------------------------------------------------------------------- */
/* Machine: arithmetic peak (the roofline's roof)                            */
/* ------------------------------------------------------------------------- */

/* Eight lanes, as the library's vectorized loops use (its AVX2 and AVX-512 clones both
 * run 256-bit vectors): twelve independent chains of a = a * m + c, one multiply and
 * one add per lane each (ISO C does not contract them into an FMA, nor does the
 * library). Twelve hide the latency (eight measured 28% less here) and fit the 16
 * vector registers of AVX2 with m and c (sixteen spill). Built for AVX-512, AVX2 and
 * the baseline, picked at load time like the library's loops. */
typedef float peak_v8 __attribute__((vector_size(32)));
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
__attribute__((target_clones("avx512f", "avx2", "default")))
#endif
static float peak_loop(uint64_t iterations, float m, float c) {
    enum { CHAINS = 12 };
    peak_v8 a[CHAINS];
    for (int k = 0; k < CHAINS; ++k)
        for (int l = 0; l < 8; ++l) a[k][l] = 1.0f + 0.01f * (float)(8 * k + l);
    for (uint64_t i = 0; i < iterations; ++i)
        for (int k = 0; k < CHAINS; ++k) a[k] = a[k] * m + c;
    float sum = 0.0f;
    for (int k = 0; k < CHAINS; ++k)
        for (int l = 0; l < 8; ++l) sum += a[k][l];
    return sum;
}

/* Best of 5 runs of peak_loop, GFLOP/s: 192 flops per iteration (12 chains x 8 lanes x
 * a multiply and an add). m < 1 and c keep the values finite (a -> c / (1 - m)). */
static double peak_gflops(void) {
    const uint64_t iterations = 20u * 1000u * 1000u;
    double best = 0.0;
    volatile float sink = 0.0f;
    for (int rep = 0; rep < 5; ++rep) {
        double t0 = bench_now();
        sink += peak_loop(iterations, 0.999f, 0.001f);
        double sec = bench_now() - t0;
        double g = sec > 0.0 ? 192.0 * (double)iterations / sec / 1e9 : 0.0;
        if (g > best) best = g;
    }
    (void)sink;
    return best;
}

/* ------------------------------------------------------------------------- */
/* Machine                                                                   */
/* ------------------------------------------------------------------------- */

/* CPU time in clock ticks: the whole machine's (busy and total, first line of
 * /proc/stat; steal counts as busy: another guest had the core) and this process's
 * (utime + stime of /proc/self/stat, every thread). Returns 0, or -1 where /proc
 * is not readable. */
typedef struct cpu_ticks {
    double machine_busy, machine_total, self;
} cpu_ticks;

static int read_cpu_ticks(cpu_ticks *t) {
    FILE *f = fopen("/proc/stat", "r");
    if (!f)
        return -1;
    /* user nice system idle iowait irq softirq steal */
    unsigned long long v[8];
    int n = fscanf(f, "cpu %llu %llu %llu %llu %llu %llu %llu %llu", &v[0], &v[1], &v[2], &v[3],
                   &v[4], &v[5], &v[6], &v[7]);
    fclose(f);
    if (n != 8)
        return -1;
    t->machine_total = 0.0;
    for (int k = 0; k < 8; ++k) t->machine_total += (double)v[k];
    t->machine_busy = t->machine_total - (double)v[3] - (double)v[4];
    f = fopen("/proc/self/stat", "r");
    if (!f)
        return -1;
    char buf[1024];
    size_t len = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[len] = '\0';
    /* Fields after the command name (which may hold spaces) start after the last
     * ')': state is field 3, utime and stime are fields 14 and 15. */
    const char *p = strrchr(buf, ')');
    unsigned long long ut, st;
    if (!p || sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &ut, &st) != 2)
        return -1;
    t->self = (double)ut + (double)st;
    return 0;
}

/* Others' share of the machine between two readings; NaN if unknown or too short. */
static double others_share(const cpu_ticks *a, const cpu_ticks *b) {
    double total = b->machine_total - a->machine_total;
    if (!(total >= PERF_MIN_JIFFIES))
        return NAN;
    double others = (b->machine_busy - a->machine_busy) - (b->self - a->self);
    return fmin(1.0, fmax(0.0, others / total));
}

/* ------------------------------------------------------------------------- */
/* Meshes                                                                    */
/* ------------------------------------------------------------------------- */

/* splitmix64: a small, well-mixed generator; the sequence depends only on the seed. */
static uint64_t rng_next(uint64_t *state) {
    uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* Uniform in [0, 1). */
static double rng_unit(uint64_t *state) {
    return (double)(rng_next(state) >> 11) * 0x1.0p-53;
}

/* Uniform in [0, n) (n > 0; the modulo bias is below 2^-32 for n < 2^32). */
static uint32_t rng_below(uint64_t *state, uint32_t n) {
    return (uint32_t)(rng_next(state) % n);
}

/* The hanging cloth's grid: n x n, 1 m square, pinned at vertices 0 and n - 1. */
static int perf_mesh_grid(bench_mesh *m, uint32_t n) {
    if (bench_mesh_grid(m, n, n, 1.0 / (n - 1), 0, 0.0))
        return -1;
    m->pins = malloc(2 * sizeof *m->pins);
    if (!m->pins) {
        bench_mesh_free(m);
        return -1;
    }
    m->pins[0] = 0;
    m->pins[1] = n - 1;
    m->pin_count = 2;
    return 0;
}

/* Particles of the split mesh of a t x t triangulated grid: vertices + edges (one
 * midpoint each) + triangles (one centroid each). */
static uint64_t irregular_particles(uint64_t t) {
    uint64_t c = (t - 1) * (t - 1);
    return t * t + (2 * t * (t - 1) + c) + 2 * c;
}

/* The irregular all-quad mesh with about `target` particles (see the header
 * comment), 1 m square in the xz plane, pinned at the corners (0, 0) and (1, 0).
 * Mass, stiffness and damping as the grid's. Returns 0, or -1 out of memory. */
static int perf_mesh_irregular(bench_mesh *m, uint32_t target, uint64_t seed) {
    memset(m, 0, sizeof *m);
    /* The triangle-grid side whose split mesh comes closest to target (about 6 t^2). */
    uint64_t t = 2;
    while (irregular_particles(t) < target)
        ++t;
    if (t > 2 && target - irregular_particles(t - 1) < irregular_particles(t) - target)
        --t;
    const uint64_t cells = (t - 1) * (t - 1);
    const uint64_t nv = t * t;               /* triangle-grid vertices */
    const uint64_t nh = (t - 1) * t;         /* horizontal edges (i,j)-(i+1,j) */
    const uint64_t nvert = t * (t - 1);      /* vertical edges (i,j)-(i,j+1) */
    const uint64_t ne = nh + nvert + cells;  /* plus one diagonal per cell */
    const uint64_t ntri = 2 * cells;
    const uint64_t n = nv + ne + ntri;
    if (n > UINT32_MAX / 3)
        return -1;
    m->n = (uint32_t)n;
    m->quad_count = (uint32_t)(3 * ntri);
    m->rest = malloc(n * 3 * sizeof *m->rest);
    m->quads = malloc((size_t)m->quad_count * 4 * sizeof *m->quads);
    m->pins = malloc(2 * sizeof *m->pins);
    uint32_t *perm = malloc(n * sizeof *perm);
    uint8_t *diag = malloc(cells ? cells : 1);
    if (!m->rest || !m->quads || !m->pins || !perm || !diag) {
        free(perm);
        free(diag);
        bench_mesh_free(m);
        return -1;
    }
    uint64_t rng = seed;
    const double h = 1.0 / (double)(t - 1);
    /* Triangle-grid vertices: interior ones jittered by up to 0.3 h per axis, which
     * keeps every triangle's orientation (a vertex would have to cross the 0.5 h
     * mid-lines) and every split quad convex; the boundary stays the 1 m square. */
    for (uint64_t j = 0; j < t; ++j)
        for (uint64_t i = 0; i < t; ++i) {
            double x = (double)i * h, z = (double)j * h;
            if (i > 0 && j > 0 && i + 1 < t && j + 1 < t) {
                x += 0.6 * h * (rng_unit(&rng) - 0.5);
                z += 0.6 * h * (rng_unit(&rng) - 0.5);
            }
            float *p = m->rest + 3 * (i + t * j);
            p[0] = (float)x;
            p[1] = 0.0f;
            p[2] = (float)z;
        }
    for (uint64_t c = 0; c < cells; ++c)
        diag[c] = (uint8_t)(rng_next(&rng) & 1);
#define VID(i, j) ((i) + t * (j))
#define HEDGE(i, j) (nv + (i) + (t - 1) * (j))
#define VEDGE(i, j) (nv + nh + (j) + (t - 1) * (i))
#define DEDGE(i, j) (nv + nh + nvert + (i) + (t - 1) * (j))
    /* Edge midpoints and triangle centroids (in double, rounded once). */
    for (uint64_t j = 0; j < t; ++j)
        for (uint64_t i = 0; i < t; ++i) {
            const float *a = m->rest + 3 * VID(i, j);
            if (i + 1 < t) {
                const float *b = m->rest + 3 * VID(i + 1, j);
                float *p = m->rest + 3 * HEDGE(i, j);
                for (int k = 0; k < 3; ++k) p[k] = (float)(0.5 * ((double)a[k] + b[k]));
            }
            if (j + 1 < t) {
                const float *b = m->rest + 3 * VID(i, j + 1);
                float *p = m->rest + 3 * VEDGE(i, j);
                for (int k = 0; k < 3; ++k) p[k] = (float)(0.5 * ((double)a[k] + b[k]));
            }
        }
    uint32_t *q = m->quads;
    uint64_t tri = 0;
    for (uint64_t j = 0; j + 1 < t; ++j)
        for (uint64_t i = 0; i + 1 < t; ++i) {
            uint64_t c = i + (t - 1) * j;
            uint64_t v00 = VID(i, j), v10 = VID(i + 1, j), v01 = VID(i, j + 1),
                     v11 = VID(i + 1, j + 1);
            uint64_t e_bottom = HEDGE(i, j), e_top = HEDGE(i, j + 1), e_left = VEDGE(i, j),
                     e_right = VEDGE(i + 1, j), e_diag = DEDGE(i, j);
            /* Two triangles per cell, corners in one rotational order, each with its
             * edges' midpoints: tri[k] = (a, b, c, m_ab, m_bc, m_ca). */
            uint64_t tv[2][6];
            if (diag[c]) { /* diagonal v00 - v11 */
                const uint64_t tri6[2][6] = {{v00, v10, v11, e_bottom, e_right, e_diag},
                                            {v00, v11, v01, e_diag, e_top, e_left}};
                memcpy(tv, tri6, sizeof tri6);
            } else { /* diagonal v10 - v01 */
                const uint64_t tri6[2][6] = {{v00, v10, v01, e_bottom, e_diag, e_left},
                                            {v10, v11, v01, e_right, e_top, e_diag}};
                memcpy(tv, tri6, sizeof tri6);
            }
            /* The diagonal's ends. */
            const float *da = m->rest + 3 * (diag[c] ? v00 : v10);
            const float *db = m->rest + 3 * (diag[c] ? v11 : v01);
            float *pd = m->rest + 3 * DEDGE(i, j);
            for (int k = 0; k < 3; ++k) pd[k] = (float)(0.5 * ((double)da[k] + db[k]));
            for (int k = 0; k < 2; ++k, ++tri) {
                const uint64_t *v = tv[k];
                uint64_t g = nv + ne + tri;
                float *pg = m->rest + 3 * g;
                for (int a = 0; a < 3; ++a)
                    pg[a] = (float)(((double)m->rest[3 * v[0] + a] + m->rest[3 * v[1] + a] +
                                     m->rest[3 * v[2] + a]) / 3.0);
                /* Corner c_k with the midpoints of its two edges and the centroid:
                 * (a, m_ab, g, m_ca), (b, m_bc, g, m_ab), (c, m_ca, g, m_bc). */
                uint64_t quads[3][4] = {{v[0], v[3], g, v[5]}, {v[1], v[4], g, v[3]},
                                        {v[2], v[5], g, v[4]}};
                for (int s = 0; s < 3; ++s, q += 4)
                    for (int a = 0; a < 4; ++a) q[a] = (uint32_t)quads[s][a];
            }
        }
#undef VID
#undef HEDGE
#undef VEDGE
#undef DEDGE
    free(diag);
    /* Shuffle the vertex order (Fisher-Yates: perm[old] = new) and the quad order,
     * so that neither memory order nor quad order remembers the grid. */
    for (uint64_t k = 0; k < n; ++k) perm[k] = (uint32_t)k;
    for (uint64_t k = n - 1; k > 0; --k) {
        uint32_t r = rng_below(&rng, (uint32_t)(k + 1));
        uint32_t tmp = perm[k];
        perm[k] = perm[r];
        perm[r] = tmp;
    }
    float *moved = malloc(n * 3 * sizeof *moved);
    if (!moved) {
        free(perm);
        bench_mesh_free(m);
        return -1;
    }
    for (uint64_t k = 0; k < n; ++k)
        memcpy(moved + 3 * (size_t)perm[k], m->rest + 3 * k, 3 * sizeof *moved);
    free(m->rest);
    m->rest = moved;
    for (size_t k = 0; k < 4 * (size_t)m->quad_count; ++k) m->quads[k] = perm[m->quads[k]];
    for (uint32_t k = m->quad_count - 1; k > 0; --k) {
        uint32_t r = rng_below(&rng, k + 1);
        uint32_t tmp[4];
        memcpy(tmp, m->quads + 4 * (size_t)k, sizeof tmp);
        memcpy(m->quads + 4 * (size_t)k, m->quads + 4 * (size_t)r, sizeof tmp);
        memcpy(m->quads + 4 * (size_t)r, tmp, sizeof tmp);
    }
    m->pins[0] = perm[0];     /* corner (0, 0) */
    m->pins[1] = perm[t - 1]; /* corner (1, 0) */
    m->pin_count = 2;
    free(perm);
    m->vertex_mass = 1e-4f;
    m->stiffness = 1000.0f;
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Worlds and runs                                                           */
/* ------------------------------------------------------------------------- */

/* struct_size for the stats read once per configuration: the 1.2 struct (with
 * memory_bytes) where the plugin has it, else the 1.1 one. */
static uint32_t full_stats_size(const perf_ctx *ctx) {
    return ctx->abi_minor >= 2 ? (uint32_t)sizeof(rbc_world_stats) : RBC_WORLD_STATS_SIZE_V1_1;
}

static uint32_t solver_def_size(const perf_ctx *ctx) {
    return ctx->abi_minor >= 2 ? (uint32_t)sizeof(rbc_solver_def) : RBC_SOLVER_DEF_SIZE_V1_1;
}

/* A world with one cloth from `m`; *setup_ms receives the wall time of
 * rbc_cloth_create alone (the world's thread pool is not part of it). */
static rbc_result perf_world_create(const perf_ctx *ctx, const bench_mesh *m, uint32_t solver,
                                    uint32_t threads, rbc_world_id *out_world,
                                    rbc_cloth_id *out_cloth, double *setup_ms) {
    const rbc_api_v1 *api = ctx->run.api;
    *out_world = 0;
    *out_cloth = 0;
    rbc_solver_def sd;
    rbc_result r = api->solver_def_init(&sd, solver_def_size(ctx));
    if (r != RBC_OK)
        return r;
    sd.solver = bench_solvers[solver].kind;
    rbc_world_def wd;
    if ((r = api->world_def_init(&wd, (uint32_t)sizeof wd)) != RBC_OK)
        return r;
    wd.gravity[0] = 0.0f;
    wd.gravity[1] = -9.81f;
    wd.gravity[2] = 0.0f;
    wd.substeps = 1;
    wd.nonlinear_iterations = 1;
    wd.linear_iterations = PERF_ITERATIONS;
    wd.thread_count = threads;
    wd.solver = &sd;
    /* --backend cuda: the same worlds (the energy guard included) on the device. */
    if (ctx->run.opt->backend == RBC_BACKEND_CUDA) wd.backend = RBC_BACKEND_CUDA;
    rbc_world_id world;
    if ((r = api->world_create(&wd, &world)) != RBC_OK)
        return r;
    rbc_cloth_def cd;
    if ((r = bench_cloth_def(api, m, &cd)) == RBC_OK) {
        double t0 = bench_now();
        r = api->cloth_create(world, &cd, out_cloth);
        *setup_ms = 1e3 * (bench_now() - t0);
    }
    if (r != RBC_OK) {
        api->world_destroy(world); /* last_error() keeps cloth_create's message */
        *out_cloth = 0;
        return r;
    }
    *out_world = world;
    return RBC_OK;
}

/* Default frames per configuration: enough for a stable median at every size (the
 * spread between frames is a few percent), and a full run of about 1.5 minutes on
 * 2 cores. */
static uint32_t default_frames(const perf_ctx *ctx, uint32_t particles) {
    if (ctx->run.opt->frames > 0)
        return (uint32_t)ctx->run.opt->frames;
    if (ctx->run.opt->quick)
        return 20;
    if (particles <= 20000)
        return 200;
    if (particles <= 100000)
        return 100;
    if (particles <= 500000)
        return 40;
    return 20;
}

/* Measure one configuration into row (mesh, solver, side and threads set). */
static int run_row(perf_ctx *ctx, perf_row *row, const bench_mesh *m) {
    const rbc_api_v1 *api = ctx->run.api;
    fprintf(stderr, "rbcloth: bench perf: %s, %u particles, %s, %u thread%s ...\n",
            mesh_names[row->mesh], m->n, bench_solvers[row->solver].name, row->threads_requested,
            row->threads_requested == 1 ? "" : "s");
    rbc_world_id world;
    rbc_cloth_id cloth;
    rbc_result r = perf_world_create(ctx, m, row->solver, row->threads_requested, &world, &cloth,
                                     &row->setup_ms);
    if (r != RBC_OK) {
        char what[160];
        snprintf(what, sizeof what, "(creating the %s world of %u particles)", mesh_names[row->mesh],
                 m->n);
        return bench_report(api, r, what);
    }
    row->frames_asked = default_frames(ctx, m->n);
    if (bench_reserve_samples(ctx->samples, 6, &ctx->sample_cap, row->frames_asked)) {
        api->world_destroy(world);
        return out_of_memory();
    }
    double **s = ctx->samples;
    uint32_t done = 0;
    double iterations_sum = 0.0;
    cpu_ticks ticks0, ticks1;
    int have_ticks = 0;
    for (uint32_t f = 0; f < PERF_WARMUP + row->frames_asked; ++f) {
        if (f == PERF_WARMUP)
            have_ticks = read_cpu_ticks(&ticks0) == 0;
        double t0 = bench_now();
        r = api->world_step(world, PERF_DT);
        double wall = 1e3 * (bench_now() - t0);
        if (r != RBC_OK) {
            char text[200];
            snprintf(row->note, sizeof row->note, "frame %u: %s", f,
                     bench_result_text(api, r, text, sizeof text));
            fprintf(stderr, "rbcloth: bench perf: %s, %u particles, %s: step %s; %u frames "
                            "measured\n",
                    mesh_names[row->mesh], m->n, bench_solvers[row->solver].name, row->note, done);
            break;
        }
        /* Timings only: from ABI 1.2 with skip_measures (no pass over the cloth); a
         * 1.1 plugin gets the 1.0 stats, which evaluate Eq. 7. */
        rbc_world_stats st;
        memset(&st, 0, sizeof st);
        st.struct_size = ctx->abi_minor >= 2 ? (uint32_t)sizeof st : RBC_WORLD_STATS_SIZE_V1_0;
        st.skip_measures = ctx->abi_minor >= 2;
        if ((r = api->world_get_stats(world, &st)) != RBC_OK) {
            api->world_destroy(world);
            return bench_report(api, r, "(reading stats)");
        }
        if (f < PERF_WARMUP)
            continue;
        s[0][done] = st.step_ms;
        s[1][done] = st.integrate_ms;
        s[2][done] = st.local_ms;
        s[3][done] = st.global_ms;
        s[4][done] = st.other_ms;
        s[5][done] = wall;
        iterations_sum += st.linear_iterations;
        ++done;
    }
    row->others_cpu = have_ticks && read_cpu_ticks(&ticks1) == 0 ? others_share(&ticks0, &ticks1)
                                                                   : NAN;
    rbc_world_stats st;
    memset(&st, 0, sizeof st);
    st.struct_size = full_stats_size(ctx);
    r = api->world_get_stats(world, &st);
    api->world_destroy(world);
    if (r != RBC_OK)
        return bench_report(api, r, "(reading stats)");
    row->frames = done;
    row->particles = st.particle_count;
    row->springs = st.spring_count;
    row->colors = st.color_count;
    row->threads = st.thread_count;
    row->memory_bytes = ctx->abi_minor >= 2 ? st.memory_bytes : 0;
    /* Every step does the same count in the FIXED mode; the mean guards against a
     * plugin that does not. */
    row->linear_iterations = done ? (uint32_t)lround(iterations_sum / done) : 0;
    double *medians[6] = {&row->step_ms,   &row->integrate_ms, &row->local_ms,
                          &row->global_ms, &row->other_ms,     &row->wall_ms};
    for (int k = 0; k < 6; ++k)
        *medians[k] = done ? bench_median(s[k], done) : NAN;
    if (!done)
        ++ctx->failed_rows;
    return 0;
}

/* ------------------------------------------------------------------------- */
/* Derived figures                                                           */
/* ------------------------------------------------------------------------- */

/* Particle updates per second: particles x linear iterations / step time. */
static double updates_per_s(const perf_row *r) {
    return (double)r->particles * r->linear_iterations / (1e-3 * r->step_ms);
}

/* Nanoseconds per particle-iteration: the step time over particles x iterations. */
static double ns_per_update(const perf_row *r) {
    return 1e6 * r->step_ms / ((double)r->particles * r->linear_iterations);
}

static const perf_row *find_row(const perf_ctx *ctx, perf_mesh_kind mesh, uint32_t solver,
                                uint32_t side, uint32_t threads_requested) {
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[k];
        if (r->mesh == mesh && r->solver == solver && r->side == side &&
            r->threads_requested == threads_requested)
            return r;
    }
    return NULL;
}

/* Step time with 1 thread over this row's (1 for the 1-thread rows; NaN if the
 * 1-thread row is missing). */
static double speedup(const perf_ctx *ctx, const perf_row *r) {
    const perf_row *one = find_row(ctx, r->mesh, r->solver, r->side, 1);
    return one ? one->step_ms / r->step_ms : NAN;
}

/* Others' CPU share as a percentage, "n/a" when unknown. */
static const char *others_text(const perf_row *r, char *buf, size_t size) {
    if (!isfinite(r->others_cpu))
        return "n/a";
    snprintf(buf, size, "%.0f%%", 100.0 * r->others_cpu);
    return buf;
}

/* "n/a" for an unreported memory figure. */
static const char *memory_text(const perf_row *r, double per, char *buf, size_t size) {
    if (r->memory_bytes == 0)
        return "n/a";
    snprintf(buf, size, "%.6g", per);
    return buf;
}

/* ------------------------------------------------------------------------- */
/* Outputs                                                                   */
/* ------------------------------------------------------------------------- */

static const char csv_header[] =
    "mesh,solver,particles,springs,colors,threads,frames,linear_iterations,step_ms,"
    "integrate_ms,local_ms,global_ms,other_ms,wall_ms,particle_updates_per_s,"
    "ns_per_particle_iteration,speedup_vs_1_thread,setup_ms,memory_bytes,bytes_per_particle,"
    "bytes_per_spring,others_cpu,energy_guard,cores,cpu";

/* Row order of perf.csv: by mesh, solver and threads, then size, so that each
 * series gnuplot draws is contiguous. */
static const perf_ctx *g_order_ctx;
static int cmp_order(const void *a, const void *b) {
    const perf_row *x = &g_order_ctx->rows[*(const uint32_t *)a];
    const perf_row *y = &g_order_ctx->rows[*(const uint32_t *)b];
    if (x->mesh != y->mesh)
        return x->mesh < y->mesh ? -1 : 1;
    if (x->solver != y->solver)
        return x->solver < y->solver ? -1 : 1;
    if (x->threads_requested != y->threads_requested)
        return x->threads_requested == 1 ? -1 : y->threads_requested == 1 ? 1 : 0;
    return x->side < y->side ? -1 : x->side > y->side;
}

static int write_csv(perf_ctx *ctx) {
    for (uint32_t k = 0; k < ctx->row_count; ++k) ctx->order[k] = k;
    g_order_ctx = ctx;
    qsort(ctx->order, ctx->row_count, sizeof ctx->order[0], cmp_order);
    FILE *f = bench_open_csv(ctx->run.dir, "perf.csv", csv_header);
    if (!f)
        return 1;
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[ctx->order[k]];
        char mem[3][32], others[32];
        if (isfinite(r->others_cpu))
            snprintf(others, sizeof others, "%.3f", r->others_cpu);
        else
            snprintf(others, sizeof others, "n/a");
        if (r->memory_bytes)
            snprintf(mem[0], sizeof mem[0], "%llu", (unsigned long long)r->memory_bytes);
        else
            snprintf(mem[0], sizeof mem[0], "n/a");
        fprintf(f, "%s,%s,%u,%u,%u,%u,%u,%u,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%s,%s,%s,"
                   "%s,%s,%ld,%s\n",
                mesh_names[r->mesh], bench_solvers[r->solver].name, r->particles, r->springs,
                r->colors, r->threads, r->frames, r->linear_iterations, r->step_ms,
                r->integrate_ms, r->local_ms, r->global_ms, r->other_ms, r->wall_ms,
                updates_per_s(r), ns_per_update(r), speedup(ctx, r), r->setup_ms, mem[0],
                memory_text(r, (double)r->memory_bytes / r->particles, mem[1], sizeof mem[1]),
                memory_text(r, (double)r->memory_bytes / r->springs, mem[2], sizeof mem[2]),
                others, ctx->energy_guard, ctx->cores, ctx->cpu);
    }
    return bench_close(f, ctx->run.dir, "perf.csv") ? 1 : 0;
}

static const char *threads_label(uint32_t requested, char *buf, size_t size) {
    if (requested == 0)
        snprintf(buf, size, "all");
    else
        snprintf(buf, size, "%u", requested);
    return buf;
}

/* The Markdown tables (perf.md and stdout). */
static void write_tables(const perf_ctx *ctx, FILE *f) {
    const uint32_t many = ctx->threads_many;
    char tl[16], oc[16];

    fprintf(f, "## Scaling: grid, RBGS, %u linear iterations\n\n", PERF_ITERATIONS);
    fprintf(f, "| particles | springs | threads | frames | ms/frame | integrate | local | global | "
               "other | host wall ms | M particle-updates/s | ns/particle-iteration | setup ms | "
               "others' CPU |\n");
    fprintf(f, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[ctx->order[k]];
        if (r->mesh != PERF_GRID || r->solver != 0)
            continue;
        fprintf(f, "| %u | %u | %u | %u | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.1f | %.2f | "
                   "%.1f | %s |\n",
                r->particles, r->springs, r->threads, r->frames, r->step_ms, r->integrate_ms,
                r->local_ms, r->global_ms, r->other_ms, r->wall_ms, 1e-6 * updates_per_s(r),
                ns_per_update(r), r->setup_ms, others_text(r, oc, sizeof oc));
    }

    if (ctx->thread_count > 1) {
        fprintf(f, "\n## Speedup of %s threads over 1 (RBGS, grid)\n\n",
                threads_label(many, tl, sizeof tl));
        fprintf(f, "| particles | 1 thread ms | %s threads ms | speedup | efficiency |\n",
                threads_label(many, tl, sizeof tl));
        fprintf(f, "|---:|---:|---:|---:|---:|\n");
        for (uint32_t k = 0; k < ctx->row_count; ++k) {
            const perf_row *r = &ctx->rows[ctx->order[k]];
            if (r->mesh != PERF_GRID || r->solver != 0 || r->threads_requested == 1)
                continue;
            const perf_row *one = find_row(ctx, PERF_GRID, 0, r->side, 1);
            if (!one)
                continue;
            double sp = speedup(ctx, r);
            fprintf(f, "| %u | %.3f | %.3f | %.2f | %.0f%% |\n", r->particles, one->step_ms,
                    r->step_ms, sp, 100.0 * sp / (r->threads ? r->threads : 1));
        }
    }

    fprintf(f, "\n## Grid against irregular mesh (RBGS): time per particle-iteration\n\n");
    fprintf(f, "| threads | grid particles | irregular particles | irregular springs | colors | "
               "grid ns | irregular ns | irregular / grid | within %.1fx | others' CPU "
               "(grid, irregular) |\n",
            PERF_IRREGULAR_TARGET);
    fprintf(f, "|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|\n");
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[ctx->order[k]];
        if (r->mesh != PERF_IRREGULAR)
            continue;
        const perf_row *g = find_row(ctx, PERF_GRID, r->solver, r->side, r->threads_requested);
        if (!g)
            continue;
        double ratio = ns_per_update(r) / ns_per_update(g);
        char og[16];
        fprintf(f, "| %u | %u | %u | %u | %u | %.2f | %.2f | %.2f | %s | %s, %s |\n", r->threads,
                g->particles, r->particles, r->springs, r->colors, ns_per_update(g),
                ns_per_update(r), ratio, ratio <= PERF_IRREGULAR_TARGET ? "yes" : "**no**",
                others_text(g, og, sizeof og), others_text(r, oc, sizeof oc));
    }

    const perf_row *ref1 = find_row(ctx, PERF_GRID, 0, ctx->solver_side, 1);
    if (ref1) {
        fprintf(f, "\n## Solvers at equal iterations (%u), %u-particle grid\n\n", PERF_ITERATIONS,
                ref1->particles);
        fprintf(f, "| solver | threads | ms/frame | global ms | M particle-updates/s | "
                   "ns/particle-iteration | time / RBGS | others' CPU |\n");
        fprintf(f, "|---|---:|---:|---:|---:|---:|---:|---:|\n");
        for (uint32_t t = 0; t < ctx->thread_count; ++t)
            for (uint32_t k = 0; k < ctx->row_count; ++k) {
                const perf_row *r = &ctx->rows[ctx->order[k]];
                if (r->mesh != PERF_GRID || r->side != ctx->solver_side ||
                    r->threads_requested != ctx->thread_list[t])
                    continue;
                const perf_row *rb = find_row(ctx, PERF_GRID, 0, r->side, r->threads_requested);
                fprintf(f, "| %s | %u | %.3f | %.3f | %.1f | %.2f | %.2f | %s |\n",
                        bench_solvers[r->solver].name, r->threads, r->step_ms, r->global_ms,
                        1e-6 * updates_per_s(r), ns_per_update(r),
                        rb ? r->step_ms / rb->step_ms : NAN, others_text(r, oc, sizeof oc));
            }
    }

    fprintf(f, "\n## Memory (stats.memory_bytes: the world's cloths and solver buffers, not "
               "its thread pool)\n\n");
    fprintf(f, "| mesh | particles | springs | memory MiB | bytes/particle | bytes/spring | "
               "setup ms (1 thread) |\n");
    fprintf(f, "|---|---:|---:|---:|---:|---:|---:|\n");
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[ctx->order[k]];
        if (r->threads_requested != 1 || r->solver != 0)
            continue;
        char mib[32], bp[32], bs[32];
        if (r->memory_bytes)
            snprintf(mib, sizeof mib, "%.2f", (double)r->memory_bytes / (1024.0 * 1024.0));
        else
            snprintf(mib, sizeof mib, "n/a");
        if (r->memory_bytes) {
            snprintf(bp, sizeof bp, "%.1f", (double)r->memory_bytes / r->particles);
            snprintf(bs, sizeof bs, "%.1f", (double)r->memory_bytes / r->springs);
        } else {
            snprintf(bp, sizeof bp, "n/a");
            snprintf(bs, sizeof bs, "n/a");
        }
        fprintf(f, "| %s | %u | %u | %s | %s | %s | %.1f |\n", mesh_names[r->mesh], r->particles,
                r->springs, mib, bp, bs, r->setup_ms);
    }

    int notes = 0;
    uint32_t busy = 0;
    for (uint32_t k = 0; k < ctx->row_count; ++k)
        busy += ctx->rows[k].others_cpu > PERF_OTHERS_SUSPECT;
    if (busy) {
        fprintf(f, "\n## Notes\n\n");
        fprintf(f, "- %u configuration%s ran while other processes (or the hypervisor) took more "
                   "than %.0f%% of the machine's CPU time (others' CPU): %s timings are "
                   "suspect; rerun on an idle machine\n",
                busy, busy == 1 ? "" : "s", 100.0 * PERF_OTHERS_SUSPECT, busy == 1 ? "its" : "their");
        notes = 1;
    }
    for (uint32_t k = 0; k < ctx->row_count; ++k) {
        const perf_row *r = &ctx->rows[ctx->order[k]];
        if (!r->note[0])
            continue;
        if (!notes++)
            fprintf(f, "\n## Notes\n\n");
        fprintf(f, "- %s, %u particles, %s, %u threads: a step failed (%s); medians over the "
                   "%u frames before it\n",
                mesh_names[r->mesh], r->particles, bench_solvers[r->solver].name, r->threads,
                r->note, r->frames);
    }
}

static void write_intro(const perf_ctx *ctx, FILE *f) {
    fprintf(f, "Machine: %s, %ld cores online; load average %.2f at the start, %.2f at the end "
               "(timings assume an otherwise idle machine). Memory bandwidth (triad a = b + 3c "
               "over 3 x 32 MiB, best of 5, 12 bytes per element): %.1f GB/s with 1 thread, "
               "%.1f GB/s with %u. Arithmetic peak of one thread (12 chains of 8-lane multiply "
               "+ add, the vectors the library's loops use, best of 5): %.1f GFLOP/s.\n\n",
            ctx->cpu, ctx->cores, ctx->load_start, ctx->load_end, ctx->triad_gbs[0],
            ctx->triad_gbs[1], ctx->threads_many, ctx->peak_gflops);
    fprintf(f, "Setup: the hanging cloth (1 m square, spacing 1/(n-1), 1e-4 kg per vertex, "
               "k = 1000 N/m, pinned at two corners, gravity), h = %g ms, 1 substep, 1 non-linear "
               "and %u linear iterations, library defaults otherwise (energy guard: %s). "
               "Medians over the frames after %d warm-up frames; each stage column is the median "
               "of that stage, so they need not add up to ms/frame. ms/frame is stats.step_ms; "
               "host wall ms is the host's clock around rbc_world_step. Particle-updates/s = "
               "particles x linear iterations / ms/frame. Setup = wall time of rbc_cloth_create. "
               "Others' CPU = the share of the machine's CPU time that other processes and steal "
               "took while the frames ran (/proc/stat; n/a under %d clock ticks). "
               "The irregular mesh: a triangulated grid with jittered vertices and random "
               "diagonals, each triangle split into 3 quads, vertex and quad order shuffled "
               "(seed 0x%llx): two colors, valence 3 to 8, no grid order.\n\n",
            1e3 * (double)PERF_DT, PERF_ITERATIONS, ctx->energy_guard, PERF_WARMUP,
            PERF_MIN_JIFFIES, (unsigned long long)PERF_SEED);
}

static void write_readback(const perf_ctx *ctx, FILE *f);

static int write_md(const perf_ctx *ctx) {
    FILE *f = bench_open(ctx->run.dir, "perf.md");
    if (!f)
        return 1;
    fprintf(f, "# Performance (`rbcloth bench perf%s`)\n\n", ctx->run.opt->quick ? " --quick" : "");
    write_intro(ctx, f);
    write_tables(ctx, f);
    write_readback(ctx, f);
    return bench_close(f, ctx->run.dir, "perf.md") ? 1 : 0;
}

/* perf_scaling.gp: ms per frame and particle updates per second against particles,
 * log-log, for each thread count (grid lines, irregular points). Columns of
 * perf.csv: 1 mesh, 2 solver, 3 particles, 6 threads, 9 step_ms, 15 updates/s. */
static int write_plot(const perf_ctx *ctx) {
    FILE *f = bench_open(ctx->run.dir, "perf_scaling.gp");
    if (!f)
        return 1;
    fprintf(f, "# Generated by `rbcloth bench perf`; run `gnuplot perf_scaling.gp` in this "
               "directory.\n");
    fprintf(f, "set terminal pngcairo size 1400,560 font 'sans,10'\n");
    fprintf(f, "set output 'perf_scaling.png'\n");
    fprintf(f, "set datafile separator ','\n");
    fprintf(f, "set grid lc rgb '#dddddd'\n");
    fprintf(f, "set key inside opaque box lc rgb '#bbbbbb' spacing 1.1 font ',9'\n");
    fprintf(f, "set linetype 1 lc rgb '#1f77b4' lw 2 pt 7 ps 0.9\n");
    fprintf(f, "set linetype 2 lc rgb '#d62728' lw 2 pt 5 ps 0.9\n");
    fprintf(f, "set linetype 3 lc rgb '#1f77b4' lw 1 pt 6 ps 1.4\n");
    fprintf(f, "set linetype 4 lc rgb '#d62728' lw 1 pt 4 ps 1.4\n");
    /* Enhanced text for the 10^{n} tick labels: keep its control characters out of
     * the CPU's name. */
    char cpu[sizeof ctx->cpu];
    snprintf(cpu, sizeof cpu, "%s", ctx->cpu);
    for (char *c = cpu; *c; ++c)
        if (strchr("_^{}@&~\\", *c))
            *c = ' ';
    fprintf(f, "set multiplot layout 1,2 title 'RBGS, %u linear iterations, hanging cloth: medians "
               "over frames (%s, %ld cores)'\n",
            PERF_ITERATIONS, cpu, ctx->cores);
    fprintf(f, "set logscale xy\nset format x '10^{%%L}'\nset xrange [500:2e6]\n"
               "set xlabel 'particles'\n");
    const char *panels[2][3] = {{"Time per frame", "ms per frame (stats.step\\_ms)", "9"},
                                {"Throughput", "million particle updates per second",
                                 "($15 / 1e6)"}};
    for (int p = 0; p < 2; ++p) {
        fprintf(f, "set title '%s'\nset ylabel '%s'\nset key %s left\n", panels[p][0],
                panels[p][1], p == 0 ? "top" : "bottom");
        fprintf(f, "plot ");
        for (uint32_t t = 0; t < ctx->thread_count; ++t) {
            /* Series by the thread count stats reported (column 6), which resolves 0. */
            uint32_t threads = ctx->thread_list[t];
            for (uint32_t k = 0; k < ctx->row_count; ++k)
                if (ctx->rows[k].threads_requested == ctx->thread_list[t])
                    threads = ctx->rows[k].threads;
            fprintf(f, "%s'perf.csv' using (strcol(1) eq 'grid' && strcol(2) eq 'rbgs' && $6 == %u ? "
                       "$3 : NaN):%s with linespoints lt %u title 'grid, %u thread%s', \\\n     "
                       "'perf.csv' using (strcol(1) eq 'irregular' && strcol(2) eq 'rbgs' && $6 == %u "
                       "? $3 : NaN):%s with points lt %u title 'irregular, %u thread%s'",
                    t ? ", \\\n     " : "", threads, panels[p][2], t + 1, threads,
                    threads == 1 ? "" : "s", threads, panels[p][2], t + 3, threads,
                    threads == 1 ? "" : "s");
        }
        fprintf(f, "\n");
    }
    fprintf(f, "unset multiplot\n");
    if (bench_close(f, ctx->run.dir, "perf_scaling.gp"))
        return 1;
    bench_plot(ctx->run.dir, "perf_scaling.gp");
    return 0;
}

/* ------------------------------------------------------------------------- */

/* The energy guard the worlds run with (the library's default), as text. */
static const char *energy_guard_name(const perf_ctx *ctx) {
    if (ctx->abi_minor < 2)
        return "n/a";
    rbc_solver_def d;
    if (ctx->run.api->solver_def_init(&d, (uint32_t)sizeof d) != RBC_OK)
        return "n/a";
    switch (d.energy_guard) {
    case RBC_ENERGY_GUARD_OFF: return "off";
    case RBC_ENERGY_GUARD_CLAMP: return "clamp";
    case RBC_ENERGY_GUARD_FAIL: return "fail";
    default: return "unknown";
    }
}

/* Add a row to measure; NULL when the table is full (a programming error). */
static perf_row *add_row(perf_ctx *ctx, perf_mesh_kind mesh, uint32_t solver, uint32_t side,
                         uint32_t threads) {
    if (ctx->row_count == PERF_MAX_ROWS)
        return NULL;
    perf_row *r = &ctx->rows[ctx->row_count++];
    memset(r, 0, sizeof *r);
    r->mesh = mesh;
    r->solver = solver;
    r->side = side;
    r->threads_requested = threads;
    return r;
}

/* Every thread count on one mesh and solver. */
static int run_threads(perf_ctx *ctx, const bench_mesh *m, perf_mesh_kind mesh, uint32_t solver,
                       uint32_t side) {
    for (uint32_t t = 0; t < ctx->thread_count; ++t) {
        perf_row *r = add_row(ctx, mesh, solver, side, ctx->thread_list[t]);
        if (!r)
            return out_of_memory();
        if (run_row(ctx, r, m))
            return 1;
    }
    return 0;
}


/* Section 5: the four reads of a renderer on one grid, alternating, after the step's
 * own median on one thread. */
static int run_readback(perf_ctx *ctx, const bench_mesh *m, uint32_t side) {
    const rbc_api_v1 *api = ctx->run.api;
    if (ctx->run.api->struct_size <= RBC_API_V1_SIZE_V1_9 ||
        ctx->readback_count == PERF_MAX_READBACK)
        return 0;
    rbc_world_id w;
    rbc_cloth_id c;
    double setup;
    rbc_result r = perf_world_create(ctx, m, 0, 1, &w, &c, &setup);
    if (r != RBC_OK) {
        fprintf(stderr, "rbcloth: bench perf: readback world: %s\n", api->last_error());
        return 1;
    }
    fprintf(stderr, "rbcloth: bench perf: readback, %u particles ...\n", m->n);
    const uint32_t n = m->n, rounds = ctx->run.opt->quick ? 20 : PERF_READS;
    unsigned char *buf = malloc(24 * (size_t)n);
    double *t = malloc(sizeof(double) * rounds * (PERF_READ_KINDS + 1));
    if (!buf || !t) {
        free(buf);
        free(t);
        api->world_destroy(w);
        return out_of_memory();
    }
    perf_readback *row = &ctx->readback[ctx->readback_count];
    row->side = side;
    row->particles = n;
    const uint32_t steps = rounds < 40 ? rounds : 40;
    for (uint32_t k = 0; k < steps + PERF_WARMUP && r == RBC_OK; ++k) {
        const double t0 = bench_now();
        r = api->world_step(w, PERF_DT);
        if (k >= PERF_WARMUP) t[k - PERF_WARMUP] = 1e3 * (bench_now() - t0);
    }
    row->step_ms = bench_median(t, steps);
    rbc_vertex_output o[PERF_READ_KINDS];
    for (int k = 1; k < PERF_READ_KINDS; ++k) {
        api->vertex_output_init(&o[k], (uint32_t)sizeof o[k]);
        o[k].cloth = c;
        o[k].buffer = buf;
        o[k].buffer_size = 24 * (size_t)n;
    }
    o[2].stride = 24, o[2].normal_offset = 12;
    o[3].position_offset = RBC_NO_ATTRIBUTE, o[3].normal_offset = 0;
    for (uint32_t k = 0; k < rounds && r == RBC_OK; ++k)
        for (int j = 0; j < PERF_READ_KINDS && r == RBC_OK; ++j) {
            /* Alternate the order: 0 1 2 3, 3 2 1 0, ... */
            const int kind = k % 2 ? PERF_READ_KINDS - 1 - j : j;
            size_t written;
            const double t0 = bench_now();
            r = kind == 0 ? api->cloth_read_positions(w, c, (float *)buf, 3 * (size_t)n, &written)
                          : api->world_read_vertices(w, &o[kind], 1);
            t[kind * rounds + k] = 1e3 * (bench_now() - t0);
        }
    if (r != RBC_OK) fprintf(stderr, "rbcloth: bench perf: readback: %s\n", api->last_error());
    for (int kind = 0; kind < PERF_READ_KINDS; ++kind)
        row->ms[kind] = bench_median(t + kind * rounds, rounds);
    ctx->readback_count += r == RBC_OK;
    free(buf);
    free(t);
    api->world_destroy(w);
    return r == RBC_OK ? 0 : 1;
}

static void write_readback(const perf_ctx *ctx, FILE *f) {
    if (!ctx->readback_count) return;
    fprintf(f, "\n## Readback for renderers (ABI 1.10)\n\n"
               "What a renderer's read costs each frame, after the step it follows (the setup "
               "above, one thread). The four reads alternate; medians over %u rounds. The normals "
               "are computed by the read that asks for them (a sum over the quads and a "
               "normalisation); the other reads pay nothing for them.\n\n"
               "| particles | step, ms | read_positions, ms | positions (stride 12), ms | "
               "positions + normals (stride 24), ms | normals only, ms | normals / step |\n"
               "|---:|---:|---:|---:|---:|---:|---:|\n",
            ctx->run.opt->quick ? 20 : PERF_READS);
    for (uint32_t k = 0; k < ctx->readback_count; ++k) {
        const perf_readback *r = &ctx->readback[k];
        fprintf(f, "| %u | %.3f | %.4f | %.4f | %.4f | %.4f | %.3f |\n", r->particles, r->step_ms,
                r->ms[0], r->ms[1], r->ms[2], r->ms[3], r->ms[3] / r->step_ms);
    }
}

static int write_readback_csv(const perf_ctx *ctx) {
    if (!ctx->readback_count) return 0;
    FILE *f = bench_open_csv(ctx->run.dir, "perf_readback.csv",
                             "particles,step_ms,read_positions_ms,vertices_positions_ms,"
                             "vertices_interleaved_ms,vertices_normals_ms");
    if (!f) return 1;
    for (uint32_t k = 0; k < ctx->readback_count; ++k) {
        const perf_readback *r = &ctx->readback[k];
        fprintf(f, "%u,%.5f,%.6f,%.6f,%.6f,%.6f\n", r->particles, r->step_ms, r->ms[0], r->ms[1],
                r->ms[2], r->ms[3]);
    }
    return bench_close(f, ctx->run.dir, "perf_readback.csv") ? 1 : 0;
}

/* --setup-only N: the set-up of the 1M grid and the 1M irregular mesh (issue 23's
 * figure), N creations each on one thread, the two interleaved so that the VM's drift
 * hits both alike; each time, then the medians. The meshes are built once (their
 * generation is not timed). Returns 0, or 1 after a message. */
static int run_setup_only(perf_ctx *ctx, uint32_t repeats) {
    const rbc_api_v1 *api = ctx->run.api;
    bench_mesh m[2];
    if (perf_mesh_grid(&m[PERF_GRID], 1000))
        return out_of_memory();
    if (perf_mesh_irregular(&m[PERF_IRREGULAR], 1000 * 1000, PERF_SEED)) {
        bench_mesh_free(&m[PERF_GRID]);
        return out_of_memory();
    }
    double *ms = calloc(2 * (size_t)repeats, sizeof *ms);
    int rc = ms ? 0 : out_of_memory();
    printf("Set-up (rbc_cloth_create) on 1 thread, load average %.2f\n", bench_load_average());
    for (uint32_t k = 0; k < repeats && !rc; ++k)
        for (int kind = 0; kind < 2 && !rc; ++kind) {
            rbc_world_id w;
            rbc_cloth_id c;
            double *t = &ms[(size_t)kind * repeats + k];
            rbc_result r = perf_world_create(ctx, &m[kind], 0, 1, &w, &c, t);
            if (r != RBC_OK) {
                rc = bench_report(api, r, "(creating a world for --setup-only)");
                break;
            }
            api->world_destroy(w);
            printf("%-9s %u particles: %8.1f ms\n", mesh_names[kind], m[kind].n, *t);
        }
    for (int kind = 0; kind < 2 && !rc; ++kind) {
        double *t = &ms[(size_t)kind * repeats];
        double med = bench_median(t, repeats);
        bench_sort(t, repeats);
        printf("median %-9s %8.1f ms (min %.1f, max %.1f, %u runs)\n", mesh_names[kind], med,
               t[0], t[repeats - 1], repeats);
    }
    if (!rc) printf("load average %.2f\n", bench_load_average());
    free(ms);
    bench_mesh_free(&m[PERF_GRID]);
    bench_mesh_free(&m[PERF_IRREGULAR]);
    return rc;
}

int cli_bench_perf(const cli_plugin *plugin, const cli_bench_options *options) {
    if (bench_require_v1_1(plugin))
        return 1;
    perf_ctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx)
        return out_of_memory();
    ctx->run = bench_run_of(plugin, options);
    ctx->abi_minor = plugin->api->abi_version_fn() & 0xFFFFu;
    ctx->energy_guard = energy_guard_name(ctx);
    bench_cpu_model(ctx->cpu, sizeof ctx->cpu, 1);
    ctx->cores = sysconf(_SC_NPROCESSORS_ONLN);
    ctx->thread_count = bench_thread_list(options, ctx->thread_list);
    ctx->threads_many = ctx->thread_list[ctx->thread_count - 1];
    if (ctx->threads_many > 1 && ctx->cores > 0 && ctx->threads_many > (uint32_t)ctx->cores)
        fprintf(stderr, "rbcloth: bench perf: %u threads on %ld cores: the %u-thread timings "
                        "measure oversubscription\n",
                ctx->threads_many, ctx->cores, ctx->threads_many);

    if (options->setup_only) {
        int rc = run_setup_only(ctx, (uint32_t)options->setup_only);
        free(ctx);
        return rc;
    }
    if (fs_mkdir_p_or_say(ctx->run.dir)) {
        free(ctx);
        return 1;
    }
    /* Grid sides: about 1K, 4K, 10K, 40K, 250K and 1M particles (--quick: <= 10K). */
    static const uint32_t full_sides[] = {32, 64, 100, 200, 500, 1000};
    static const uint32_t quick_sides[] = {32, 64, 100};
    /* Sides also measured as irregular meshes of as many particles. */
    static const uint32_t full_irregular[] = {100, 500, 1000};
    static const uint32_t quick_irregular[] = {100};
    const uint32_t *sides = options->quick ? quick_sides : full_sides;
    uint32_t side_count = options->quick ? 3 : 6;
    const uint32_t *irr = options->quick ? quick_irregular : full_irregular;
    uint32_t irr_count = options->quick ? 1 : 3;
    /* --backend cuda: 10K, 100K, 1M and 4M particles on one host thread (the issue's
     * range), after a world is known to open: without a device the bench says why
     * and measures nothing. */
    static const uint32_t cuda_sides[] = {100, 316, 1000, 2000};
    const int cuda = options->backend == RBC_BACKEND_CUDA;
    if (cuda) {
        bench_mesh probe;
        rbc_world_id w = 0;
        rbc_cloth_id c = 0;
        double setup = 0.0;
        rbc_result r = perf_mesh_grid(&probe, 8) ? RBC_ERR_OUT_OF_MEMORY
                                                  : perf_world_create(ctx, &probe, 0, 1, &w, &c, &setup);
        if (r == RBC_OK) ctx->run.api->world_destroy(w);
        else
            fprintf(stderr, "rbcloth: bench perf --backend cuda: %s\n", ctx->run.api->last_error());
        bench_mesh_free(&probe);
        if (r != RBC_OK) {
            free(ctx);
            return 1;
        }
        sides = cuda_sides;
        side_count = options->quick ? 1 : 4;
        irr_count = options->quick ? 0 : 1;
        irr = full_irregular + 2;
        ctx->thread_count = 1;
        ctx->thread_list[0] = 1;
    }
    ctx->solver_side = 100;
    /* --irregular: the grids the irregular meshes are compared with, nothing else
     * (no readback, no solver rows: the solver side is set to none of them). */
    const int irr_only = options->irregular_only;
    if (irr_only) {
        sides = irr;
        side_count = irr_count;
        ctx->solver_side = 0;
    }

    double start = bench_now();
    ctx->triad_gbs[0] = triad_gbs(1);
    ctx->triad_gbs[1] = ctx->threads_many > 1 ? triad_gbs(ctx->threads_many) : ctx->triad_gbs[0];
    ctx->peak_gflops = peak_gflops();
    printf("Memory bandwidth (triad): %.1f GB/s with 1 thread, %.1f GB/s with %u; arithmetic "
           "peak of one thread %.1f GFLOP/s\n",
           ctx->triad_gbs[0], ctx->triad_gbs[1], ctx->threads_many, ctx->peak_gflops);
    ctx->load_start = bench_load_average();
    int rc = 0;
    for (uint32_t k = 0; k < side_count && !rc; ++k) {
        bench_mesh m;
        if (perf_mesh_grid(&m, sides[k])) {
            rc = out_of_memory();
            break;
        }
        rc = run_threads(ctx, &m, PERF_GRID, 0, sides[k]);
        if (!rc && sides[k] <= 500 && !cuda && !irr_only) rc = run_readback(ctx, &m, sides[k]);
        /* Jacobi and serial Gauss-Seidel on the same grid, at equal iterations (the
         * CUDA backend: Jacobi only). */
        if (!rc && sides[k] == ctx->solver_side) {
            for (uint32_t s = 0; s < BENCH_SOLVER_COUNT && !rc; ++s)
                if (bench_solvers[s].kind == RBC_SOLVER_JACOBI ||
                    (bench_solvers[s].kind == RBC_SOLVER_GAUSS_SEIDEL && !cuda))
                    rc = run_threads(ctx, &m, PERF_GRID, s, sides[k]);
        }
        bench_mesh_free(&m);
    }
    for (uint32_t k = 0; k < irr_count && !rc; ++k) {
        bench_mesh m;
        if (perf_mesh_irregular(&m, irr[k] * irr[k], PERF_SEED)) {
            rc = out_of_memory();
            break;
        }
        rc = run_threads(ctx, &m, PERF_IRREGULAR, 0, irr[k]);
        bench_mesh_free(&m);
    }
    ctx->load_end = bench_load_average();
    double seconds = bench_now() - start;
    if (!rc) /* each returns 0, or 1 after a message: the first to fail ends it */
        rc = write_csv(ctx) || write_readback_csv(ctx) || write_md(ctx) || write_plot(ctx);
    if (!rc) {
        printf("\nPerformance bench\n\n");
        write_intro(ctx, stdout);
        write_tables(ctx, stdout);
        write_readback(ctx, stdout);
        printf("\nWrote perf.csv, perf.md%s in %s (%.1f s)\n",
               bench_have_gnuplot() ? ", perf_scaling.png" : "", ctx->run.dir, seconds);
        if (ctx->failed_rows) {
            fprintf(stderr, "rbcloth: bench perf: %u configuration%s measured no frame (see "
                            "perf.md, Notes)\n",
                    ctx->failed_rows, ctx->failed_rows == 1 ? "" : "s");
            rc = 1;
        }
    }
    for (int k = 0; k < 6; ++k) free(ctx->samples[k]);
    free(ctx);
    return rc;
}
