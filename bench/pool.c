/* pool.c -- `rbcloth bench pool`: what the default thread count costs on a
 * machine whose cores other work holds (issue 17: an engine's job system always
 * holds the cores).
 *
 * For each cloth (grids of 244 to 65536 particles, the default solve at 1/60 s) and
 * each load (none, and one busy loop per core in child processes), three worlds
 * step in alternation, a block of steps each in turn, so that a change of load on a
 * shared machine hits them alike: thread_count 1, thread_count 0 (the default: the
 * library probes whether its threads pay) and thread_count = cores (every step on
 * every thread, what the default was before). The figure is the host's wall time of
 * rbc_world_step, median and mean over all steps (the mean includes the default's
 * probe steps), and the ratio of the default's median to one thread's.
 */
#define _GNU_SOURCE
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench.h"
#include "fsutil.h"

typedef struct pool_cloth {
    const char *name;
    uint32_t nx, ny;
} pool_cloth;

/* 244 particles: the small cloth the issue measured (a 4 x 61 strip); 100 x 100:
 * the demo's cloth. */
static const pool_cloth cloths[] = {
    {"strip_4x61", 4, 61},
    {"grid_32x32", 32, 32},
    {"demo_100x100", 100, 100},
    {"grid_256x256", 256, 256},
};
enum { CLOTH_COUNT = sizeof cloths / sizeof cloths[0] };

enum { CFG_ONE, CFG_DEFAULT, CFG_ALL, CFG_HOST, CFG_HOST_AUTO, CFG_COUNT };

typedef struct pool_row {
    double median, mean, p90;
    uint32_t steps;
    uint32_t threads_last; /* stats.thread_count after the last step */
    uint32_t steps_multi;  /* steps whose stats said more than one thread */
    char error[256];
} pool_row;

/* pool.csv: a line per cloth, load and configuration. */
static const char csv_header[] =
    "cloth,load,particles,cores,one_median_ms,one_mean_ms,one_steps,default_median_ms,"
    "default_mean_ms,default_steps,all_median_ms,all_mean_ms,all_steps,default_over_one,"
    "all_over_one,default_steps_multithreaded,host_median_ms,host_mean_ms,host_steps,"
    "host_over_one,host_steps_multithreaded,host_auto_median_ms,host_auto_mean_ms,"
    "host_auto_steps,host_auto_over_one,host_auto_steps_multithreaded,error";

/* The host's job system of CFG_HOST: workers take ranges from a queue under a mutex
 * and sleep on a condition variable when it is empty; finish_task waits for the
 * task's ranges (the library has one task in flight at a time). */
#define JOBS_MAX_WORKERS 63
#define JOBS_QUEUE 64
typedef struct jobs_item {
    rbc_task_fn fn;
    uint32_t begin, end;
    void *ctx;
} jobs_item;
typedef struct jobs {
    pthread_mutex_t mu;
    pthread_cond_t work, done;
    jobs_item queue[JOBS_QUEUE];
    uint32_t head, tail, pending, workers;
    int quit;
    pthread_t threads[JOBS_MAX_WORKERS];
} jobs;

static void *jobs_worker(void *arg) {
    jobs *j = arg;
    pthread_mutex_lock(&j->mu);
    for (;;) {
        while (j->head == j->tail && !j->quit) pthread_cond_wait(&j->work, &j->mu);
        if (j->head == j->tail) break;
        jobs_item it = j->queue[j->head++ % JOBS_QUEUE];
        pthread_mutex_unlock(&j->mu);
        it.fn(it.begin, it.end, 1, it.ctx);
        pthread_mutex_lock(&j->mu);
        if (--j->pending == 0) pthread_cond_broadcast(&j->done);
    }
    pthread_mutex_unlock(&j->mu);
    return NULL;
}

static void *RBC_CALL jobs_enqueue(rbc_task_fn fn, uint32_t count, uint32_t min_range,
                                   void *ctx, void *user) {
    jobs *j = user;
    pthread_mutex_lock(&j->mu);
    for (uint32_t b = 0; b < count && j->tail - j->head < JOBS_QUEUE; b += min_range) {
        const uint32_t e = b + min_range < count ? b + min_range : count;
        j->queue[j->tail++ % JOBS_QUEUE] = (jobs_item){fn, b, e, ctx};
        j->pending++;
    }
    pthread_cond_broadcast(&j->work);
    pthread_mutex_unlock(&j->mu);
    return j;
}

static void RBC_CALL jobs_finish(void *handle, void *user) {
    (void)handle;
    jobs *j = user;
    pthread_mutex_lock(&j->mu);
    while (j->pending) pthread_cond_wait(&j->done, &j->mu);
    pthread_mutex_unlock(&j->mu);
}

static int jobs_start(jobs *j, uint32_t workers) {
    memset(j, 0, sizeof *j);
    pthread_mutex_init(&j->mu, NULL);
    pthread_cond_init(&j->work, NULL);
    pthread_cond_init(&j->done, NULL);
    if (workers > JOBS_MAX_WORKERS) workers = JOBS_MAX_WORKERS;
    for (; j->workers < workers; ++j->workers)
        if (pthread_create(&j->threads[j->workers], NULL, jobs_worker, j) != 0) return -1;
    return 0;
}

static void jobs_stop(jobs *j) {
    pthread_mutex_lock(&j->mu);
    j->quit = 1;
    pthread_cond_broadcast(&j->work);
    pthread_mutex_unlock(&j->mu);
    for (uint32_t k = 0; k < j->workers; ++k) pthread_join(j->threads[k], NULL);
    pthread_mutex_destroy(&j->mu);
    pthread_cond_destroy(&j->work);
    pthread_cond_destroy(&j->done);
}

/* One busy loop per core, each a child process that dies with us. */
static int start_load(pid_t *pids, uint32_t count) {
    for (uint32_t k = 0; k < count; ++k) {
        pid_t p = fork();
        if (p < 0) return -1;
        if (p == 0) {
            prctl(PR_SET_PDEATHSIG, SIGKILL);
            volatile unsigned long x = 0;
            for (;;) x++;
        }
        pids[k] = p;
    }
    return 0;
}

static void stop_load(pid_t *pids, uint32_t count) {
    for (uint32_t k = 0; k < count; ++k)
        if (pids[k] > 0) {
            kill(pids[k], SIGKILL);
            waitpid(pids[k], NULL, 0);
            pids[k] = 0;
        }
}

static rbc_result make_world(const rbc_api_v1 *api, uint32_t threads, jobs *host,
                             const bench_mesh *m, rbc_world_id *world) {
    rbc_world_def wd;
    rbc_result r = api->world_def_init(&wd, (uint32_t)sizeof wd);
    if (r != RBC_OK) return r;
    wd.thread_count = threads;
    if (host) {
        wd.enqueue_task = jobs_enqueue;
        wd.finish_task = jobs_finish;
        wd.task_user = host;
    }
    if ((r = api->world_create(&wd, world)) != RBC_OK) return r;
    rbc_cloth_def cd;
    rbc_cloth_id cloth;
    if ((r = bench_cloth_def(api, m, &cd)) == RBC_OK) r = api->cloth_create(*world, &cd, &cloth);
    if (r != RBC_OK) {
        api->world_destroy(*world);
        *world = 0;
    }
    return r;
}

static void measure(const rbc_api_v1 *api, const bench_mesh *m, uint32_t cores, uint32_t rounds,
                    uint32_t block, double block_limit_s, pool_row rows[CFG_COUNT]) {
    const uint32_t threads[CFG_COUNT] = {1, 0, cores, cores, 0};
    rbc_world_id worlds[CFG_COUNT] = {0};
    double *ms[CFG_COUNT] = {0};
    const uint32_t cap = rounds * block;
    int ok = 1;
    static jobs host;
    const int have_host = api->struct_size > RBC_API_V1_SIZE_V1_9 && jobs_start(&host, cores - 1) == 0;
    for (int k = 0; k < CFG_COUNT; ++k) {
        memset(&rows[k], 0, sizeof rows[k]);
        const int hosted = k == CFG_HOST || k == CFG_HOST_AUTO;
        if (hosted && !have_host) {
            snprintf(rows[k].error, sizeof rows[k].error, "no host tasks (ABI before 1.10)");
            continue;
        }
        rbc_result r = make_world(api, threads[k], hosted ? &host : NULL, m, &worlds[k]);
        if (r != RBC_OK) {
            bench_result_text(api, r, rows[k].error, sizeof rows[k].error);
            ok = 0;
        }
        if (!(ms[k] = malloc(sizeof(double) * cap))) {
            snprintf(rows[k].error, sizeof rows[k].error, "out of memory");
            ok = 0;
        }
    }
    const float dt = 1.0f / 60.0f;
    /* Warm-up: the first steps fault in pages and estimate the spectral radius. */
    for (int k = 0; ok && k < CFG_COUNT; ++k)
        for (int f = 0; worlds[k] && f < 3; ++f) api->world_step(worlds[k], dt);
    for (uint32_t round = 0; ok && round < rounds; ++round)
        for (int j = 0; j < CFG_COUNT; ++j) {
            /* Alternate the order too: 0 1 2 3, 3 2 1 0, ... */
            int k = round % 2 ? CFG_COUNT - 1 - j : j;
            if (!worlds[k]) continue;
            const double t_block = bench_now();
            for (uint32_t s = 0; s < block; ++s) {
                const double t0 = bench_now();
                rbc_result r = api->world_step(worlds[k], dt);
                const double t1 = bench_now();
                if (r != RBC_OK) {
                    bench_result_text(api, r, rows[k].error, sizeof rows[k].error);
                    ok = 0;
                    break;
                }
                ms[k][rows[k].steps++] = (t1 - t0) * 1e3;
                rbc_world_stats st;
                api->world_stats_init(&st, (uint32_t)sizeof st);
                st.skip_measures = 1;
                api->world_get_stats(worlds[k], &st);
                rows[k].threads_last = st.thread_count;
                rows[k].steps_multi += st.thread_count > 1;
                if (t1 - t_block > block_limit_s) break;
            }
        }
    for (int k = 0; k < CFG_COUNT; ++k) {
        if (worlds[k]) api->world_destroy(worlds[k]);
        pool_row *row = &rows[k];
        if (row->steps) {
            double sum = 0.0;
            for (uint32_t s = 0; s < row->steps; ++s) sum += ms[k][s];
            row->mean = sum / row->steps;
            bench_median_p90(ms[k], row->steps, &row->median, &row->p90);
        }
        free(ms[k]);
    }
    if (have_host) jobs_stop(&host);
}

static int write_plot(const char *dir, pool_row rows[CLOTH_COUNT][2][CFG_COUNT]) {
    FILE *f = bench_open(dir, "pool.gp");
    if (!f) return -1;
    fprintf(f, "# Generated by `rbcloth bench pool` (the figures of pool.csv); run `gnuplot "
               "pool.gp` here.\n");
    for (int load = 0; load < 2; ++load) {
        fprintf(f, "$%s << EOD\n", load ? "busy" : "idle");
        for (int c = 0; c < CLOTH_COUNT; ++c) {
            const pool_row *r = rows[c][load];
            if (!r[CFG_ONE].steps) continue;
            fprintf(f, "%s %.5f %.5f %.5f %.5f %.5f\n", cloths[c].name, r[CFG_ONE].median,
                    r[CFG_DEFAULT].median, r[CFG_ALL].median, r[CFG_HOST].median,
                    r[CFG_HOST_AUTO].median);
        }
        fprintf(f, "EOD\n");
    }
    fprintf(f, "set terminal pngcairo size 1200,480 font ',10' noenhanced\n"
               "set output 'pool.png'\n"
               "set multiplot layout 1,2\n"
               "set logscale y\n"
               "set ylabel 'ms per step (median, host wall time)'\n"
               "set style data histograms\n"
               "set style histogram clustered gap 1\n"
               "set style fill solid 0.8 border -1\n"
               "set key top left\n"
               "set grid ytics\n");
    for (int load = 0; load < 2; ++load)
        fprintf(f, "set title '%s'\n"
                   "plot $%s using 2:xtic(1) title '1 thread', '' using 3 title 'default', "
                   "'' using 4 title 'all cores', '' using 5 title 'host tasks', '' using 6 "
                   "title 'host tasks, default count'\n",
                load ? "every core busy with other work" : "idle machine", load ? "busy" : "idle");
    fprintf(f, "unset multiplot\n");
    return bench_close(f, dir, "pool.gp");
}

int cli_bench_pool(const cli_plugin *plugin, const cli_bench_options *o) {
    if (bench_require_minor(plugin, "pool", 7)) return 1;
    const rbc_api_v1 *api = plugin->api;
    const char *dir = o->out_dir;
    long nproc = sysconf(_SC_NPROCESSORS_ONLN);
    const uint32_t cores = nproc > 0 ? (uint32_t)nproc : 1;
    const uint32_t rounds = o->quick ? 2 : 8, block = o->quick ? 5 : 25;
    const double block_limit = o->quick ? 0.5 : 3.0;
    if (fs_mkdir_p_or_say(dir)) return 1;
    FILE *csv = bench_open_csv(dir, "pool.csv", csv_header);
    if (!csv) return 1;
    static pool_row rows[CLOTH_COUNT][2][CFG_COUNT];
    int failed = 0;
    pid_t pids[256] = {0};
    const uint32_t busy = cores < 256 ? cores : 256;
    for (int load = 0; load < 2; ++load) {
        if (load && start_load(pids, busy)) {
            stop_load(pids, busy);
            fprintf(stderr, "rbcloth: bench pool: cannot start the busy loops\n");
            fclose(csv);
            return 1;
        }
        for (int c = 0; c < CLOTH_COUNT; ++c) {
            if (o->quick && c != 0 && c != 2) continue;
            bench_mesh m;
            if (bench_mesh_grid(&m, cloths[c].nx, cloths[c].ny, 1.0 / (cloths[c].nx - 1), 0, 0.0) ||
                !(m.pins = malloc(2 * sizeof(uint32_t)))) {
                fprintf(stderr, "rbcloth: bench pool: out of memory\n");
                stop_load(pids, busy);
                fclose(csv);
                bench_mesh_free(&m);
                return 1;
            }
            m.pins[0] = 0;
            m.pins[1] = cloths[c].nx - 1;
            m.pin_count = 2;
            pool_row *r = rows[c][load];
            measure(api, &m, cores, rounds, block, block_limit, r);
            bench_mesh_free(&m);
            for (int k = 0; k < CFG_COUNT; ++k) failed |= r[k].error[0] != 0;
            const double d1 = r[CFG_DEFAULT].median / r[CFG_ONE].median;
            const double a1 = r[CFG_ALL].median / r[CFG_ONE].median;
            const double h1 = r[CFG_HOST].median / r[CFG_ONE].median;
            const double h0 = r[CFG_HOST_AUTO].median / r[CFG_ONE].median;
            fprintf(csv,
                    "%s,%s,%u,%u,%.5f,%.5f,%u,%.5f,%.5f,%u,%.5f,%.5f,%u,%.4f,%.4f,%u,%.5f,%.5f,%u,"
                    "%.4f,%u,%.5f,%.5f,%u,%.4f,%u,%s%s%s%s%s\n",
                    cloths[c].name, load ? "busy" : "idle", cloths[c].nx * cloths[c].ny, cores,
                    r[CFG_ONE].median, r[CFG_ONE].mean, r[CFG_ONE].steps, r[CFG_DEFAULT].median,
                    r[CFG_DEFAULT].mean, r[CFG_DEFAULT].steps, r[CFG_ALL].median, r[CFG_ALL].mean,
                    r[CFG_ALL].steps, d1, a1, r[CFG_DEFAULT].steps_multi, r[CFG_HOST].median,
                    r[CFG_HOST].mean, r[CFG_HOST].steps, h1, r[CFG_HOST].steps_multi,
                    r[CFG_HOST_AUTO].median, r[CFG_HOST_AUTO].mean, r[CFG_HOST_AUTO].steps, h0,
                    r[CFG_HOST_AUTO].steps_multi, r[CFG_ONE].error, r[CFG_DEFAULT].error,
                    r[CFG_ALL].error, r[CFG_HOST].error, r[CFG_HOST_AUTO].error);
            fflush(csv);
            printf("%-14s %s: 1 thread %8.3f ms, default %8.3f ms (x%.2f, %u of %u steps on "
                   "several threads), all %u cores %8.3f ms (x%.2f), host tasks %8.3f ms "
                   "(x%.2f, %u of %u steps on several threads), host tasks with the default "
                   "count %8.3f ms (x%.2f, %u of %u)\n",
                   cloths[c].name, load ? "busy" : "idle", r[CFG_ONE].median,
                   r[CFG_DEFAULT].median, d1, r[CFG_DEFAULT].steps_multi, r[CFG_DEFAULT].steps,
                   cores, r[CFG_ALL].median, a1, r[CFG_HOST].median, h1,
                   r[CFG_HOST].steps_multi, r[CFG_HOST].steps, r[CFG_HOST_AUTO].median, h0,
                   r[CFG_HOST_AUTO].steps_multi, r[CFG_HOST_AUTO].steps);
            fflush(stdout);
        }
        if (load) stop_load(pids, busy);
    }
    if (bench_close(csv, dir, "pool.csv")) return 1;

    FILE *md = bench_open(dir, "pool.md");
    if (!md) return 1;
    fprintf(md, "# Threads on a busy machine\n\n");
    bench_write_provenance(md, "pool", o);
    fprintf(md,
            "Each cloth hangs from two corners with the default solve at 1/60 s. Three "
            "worlds step in alternation, %u rounds of up to %u steps each (a block stops "
            "after %.1f s): `thread_count` 1, 0 (the default: every step runs on all %u "
            "cores or on the caller's thread alone, whichever the library's probes measure "
            "faster) and %u (every step on every core, the default before issue 17). *busy*: "
            "%u child processes spin in a loop the whole time, one per core, as an engine's "
            "job system would. *host tasks* (ABI 1.10): the world's parallel work on the "
            "host's job system (`enqueue_task` / `finish_task`, %u participants: the "
            "stepping thread and %u worker threads of a small job system that sleep on a "
            "condition variable between jobs); the library shares each phase with the items "
            "that start within a quarter of the last phase's time and does the rest on the "
            "stepping thread. *host, default*: the same job system with `thread_count` 0, "
            "where the world's probe chooses between asking for the items and the stepping "
            "thread alone. Five worlds step in alternation. Figures: the host's wall "
            "time of `rbc_world_step`, median over all steps (mean in `pool.csv`, which "
            "includes the default's probe steps); *x*: the ratio to one thread's median in "
            "the same load. *multi*: steps of the default (or the host tasks') world that "
            "ran on several threads.\n\n",
            rounds, block, block_limit, cores, cores, busy, cores, cores - 1);
    fprintf(md, "| cloth | particles | load | 1 thread, ms | default, ms | x | multi | all "
                "cores, ms | x | host tasks, ms | x | multi | host, default, ms | x | multi |\n"
                "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int load = 0; load < 2; ++load)
        for (int c = 0; c < CLOTH_COUNT; ++c) {
            const pool_row *r = rows[c][load];
            if (!r[CFG_ONE].steps) continue;
            fprintf(md,
                    "| %s | %u | %s | %.3f | %.3f | %.2f | %u / %u | %.3f | %.2f | %.3f | %.2f | "
                    "%u / %u | %.3f | %.2f | %u / %u |\n",
                    cloths[c].name, cloths[c].nx * cloths[c].ny, load ? "busy" : "idle",
                    r[CFG_ONE].median, r[CFG_DEFAULT].median,
                    r[CFG_DEFAULT].median / r[CFG_ONE].median, r[CFG_DEFAULT].steps_multi,
                    r[CFG_DEFAULT].steps, r[CFG_ALL].median, r[CFG_ALL].median / r[CFG_ONE].median,
                    r[CFG_HOST].median, r[CFG_HOST].median / r[CFG_ONE].median,
                    r[CFG_HOST].steps_multi, r[CFG_HOST].steps, r[CFG_HOST_AUTO].median,
                    r[CFG_HOST_AUTO].median / r[CFG_ONE].median, r[CFG_HOST_AUTO].steps_multi,
                    r[CFG_HOST_AUTO].steps);
        }
    fprintf(md, "\n![ms per step, one thread, the default, all cores and host tasks, idle and busy](pool.png)"
                "\n\nThe plot (`pool.png`, from `pool.gp`) needs gnuplot.\n");
    if (bench_close(md, dir, "pool.md")) return 1;
    if (write_plot(dir, rows)) return 1;
    if (bench_have_gnuplot() && bench_run_gnuplot(dir, "pool.gp") != 0) {
        fprintf(stderr, "rbcloth: bench pool: gnuplot %s/pool.gp failed\n", dir);
        return 1;
    }
    printf("Wrote pool.csv, pool.md and pool.gp%s in %s\n", bench_have_gnuplot() ? ", pool.png" : "",
           dir);
    return failed ? 1 : 0;
}
