/* pool.h -- a persistent thread pool that runs one SPMD function on every thread
 * (the caller is thread 0) with a barrier between the solver's phases (a short spin,
 * then a futex).
 * Workers are woken once per rbc_world_step, not once per phase: a 10K-particle
 * color sweep takes microseconds, so per-phase wake-ups would dominate. */
#ifndef RBC_CPU_POOL_H
#define RBC_CPU_POOL_H
#include <stdint.h>

#include "../alloc.h"

typedef struct rbc_pool rbc_pool;
typedef void (*rbc_pool_fn)(void *ctx, uint32_t tid, uint32_t nthreads);

/* The host's job system (ABI 1.10, rbc_world_def.enqueue_task / finish_task): the
 * same shapes as the ABI's callbacks, which the plugin casts to these. */
typedef void (*rbc_pool_task_fn)(uint32_t begin, uint32_t end, uint32_t worker, void *ctx);
typedef struct rbc_pool_host {
    void *(*enqueue)(rbc_pool_task_fn task, uint32_t items, uint32_t min_range, void *task_ctx,
                     void *user);
    void (*finish)(void *handle, void *user);
    void *user;
} rbc_pool_host;

/* nthreads >= 1; 1 starts no thread. Returns 0, or -1 (out of memory or no thread). */
int rbc_pool_create(rbc_pool **out, uint32_t nthreads, const rbc_allocator *a);
void rbc_pool_destroy(rbc_pool *pool);
uint32_t rbc_pool_size(const rbc_pool *pool);
/* A pool of one thread (rbc_pool_create with 1) made to run on the host's job system
 * with up to `participants` threads, the caller's included: each run hands the host
 * participants - 1 items and shares fn with those that start within a short wait
 * (docs/design/threads.md, "Host tasks"). rbc_pool_size is then `participants`. */
void rbc_pool_set_host(rbc_pool *pool, const rbc_pool_host *host, uint32_t participants);
/* Run fn(ctx, tid, n) on all n threads; returns when every thread has returned. */
void rbc_pool_run(rbc_pool *pool, rbc_pool_fn fn, void *ctx);
/* The same on the first n threads only (1 <= n <= the pool's size; clamped):
 * barriers inside count n. Returns the number of threads fn ran on: n, or on the
 * host's job system those that joined in time (1..n). */
uint32_t rbc_pool_run_n(rbc_pool *pool, uint32_t n, rbc_pool_fn fn, void *ctx);
/* Inside fn: wait until all n threads arrive. */
void rbc_pool_barrier(rbc_pool *pool);
/* One round of a spin-wait (the lattice wavefront waits on its neighbour's row with
 * it): a pause for the first spins, then a yield. The barrier and rbc_pool_run do not
 * use it; they spin briefly and then sleep on a futex. Start with *spins = 0. */
void rbc_pool_spin(uint32_t *spins);
/* The number of cores this process may run on (at least 1). */
uint32_t rbc_cpu_count(void);
/* Milliseconds on the monotonic clock (stage times, the budget mode's deadline):
 * here beside the other calls into the OS, out of line so that no header of the
 * core needs <windows.h>. */
double rbc_now_ms(void);
#endif
