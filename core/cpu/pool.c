#define _GNU_SOURCE
#include "pool.h"

#include <stdatomic.h>
#include <stdint.h>
#include <string.h>

#include "../threads.h"
#if defined(_WIN32)
/* Windows (threads.h's Win32 threads): the futex is WaitOnAddress and
 * WakeByAddress* (Windows 8+), which wait while a word still holds a value exactly as
 * FUTEX_WAIT does, so the sleeps and wake-ups below keep their meaning. (threads.h
 * has included <windows.h>.) */

static void futex_wait(_Atomic uint32_t *word, uint32_t val) {
    WaitOnAddress((volatile VOID *)word, &val, sizeof val, INFINITE);
}
static void futex_wake(_Atomic uint32_t *word, int all) {
    if (all) WakeByAddressAll((PVOID)word);
    else WakeByAddressSingle((PVOID)word);
}
#else
#include <linux/futex.h>
#include <sched.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

static void futex_wait(_Atomic uint32_t *word, uint32_t val) {
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAIT_PRIVATE, val, NULL, NULL, 0);
}
static void futex_wake(_Atomic uint32_t *word, int all) {
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAKE_PRIVATE, all ? INT32_MAX : 1, NULL, NULL, 0);
}
#endif

/* (_M_X64, _M_IX86, _M_ARM64: MSVC's names of the targets.) */
#if defined(__x86_64__) || defined(__i386__) || defined(_M_X64) || defined(_M_IX86)
#include <immintrin.h>
#define CPU_RELAX() _mm_pause()
#elif defined(_M_ARM64)
#include <intrin.h>
#define CPU_RELAX() __yield()
#else
#define CPU_RELAX() ((void)0)
#endif

/* Spins before yielding the core (rbc_pool_spin: the wavefront's neighbour waits):
 * long enough to cover a phase of a 10K-particle step (a few microseconds). */
#define SPIN_BEFORE_YIELD 4000
/* Spins before a worker sleeps on the condition variable between steps. */
#define SPIN_BEFORE_SLEEP 20000
/* Spins before a thread waiting at a barrier, or the caller waiting for the workers
 * to finish, sleeps on a futex. No sched_yield in between: on a machine whose cores
 * other processes hold, a yield hands the core to a busy loop for the rest of its
 * time slice (milliseconds), and a step has hundreds of barriers; a futex sleeper
 * is woken by the last arrival and preempts the busy loop at once. */
#define SPIN_BEFORE_FUTEX 2000

/* Host tasks (rbc_pool_set_host): the joined count and the seal share one word, so a
 * late item either joins before the seal or sees it and returns. */
#define HOST_SEALED 0x80000000u
#define HOST_COUNT 0x0000FFFFu
/* The caller waits for items to start at most a quarter of the last run of the same
 * function, within these bounds (ms): long enough for a woken worker, short enough
 * that a job system whose workers are all busy costs little. */
#define HOST_WAIT_FIRST_MS 0.05
#define HOST_WAIT_MIN_MS 0.02
#define HOST_WAIT_MAX_MS 1.0
/* An item that started while enqueue had not returned leaves after this (ms) if it is
 * still not sealed: a job system whose enqueue waits for its items would otherwise
 * wait on the caller, which waits inside enqueue. */
#define HOST_LEAVE_MS 1.0
#define HOST_FNS 4

struct rbc_pool {
    rbc_allocator alloc;
    uint32_t n;
    /* Host tasks: the job system, the participants, and the state of the current
     * run (set, joined, go, next tid, finished) and the last run time per function. */
    int hosted;
    uint32_t host_n;
    rbc_pool_host host;
    _Alignas(64) _Atomic uint32_t h_state;
    _Atomic uint32_t h_go, h_tid, h_done;
    _Atomic int h_in_enqueue;
    rbc_pool_fn h_fn[HOST_FNS];
    double h_ms[HOST_FNS];
    rbc_thread *threads;
    rbc_mutex mu;
    rbc_cond cv;
    _Atomic uint32_t job_gen;
    _Atomic int quit;
    _Atomic uint32_t done;
    _Atomic uint32_t done_sleeper; /* the caller sleeps on `done` */
    uint32_t active;               /* threads taking part in the current run */
    rbc_pool_fn fn;
    void *ctx;
    _Alignas(64) _Atomic uint32_t bar_count;
    _Alignas(64) _Atomic uint32_t bar_gen;
    _Atomic uint32_t bar_sleepers;
};

typedef struct worker_arg {
    rbc_pool *pool;
    uint32_t tid;
} worker_arg;

static void worker_main(void *arg) {
    rbc_pool *pool = ((worker_arg *)arg)->pool;
    uint32_t tid = ((worker_arg *)arg)->tid;
    uint32_t seen = 0;
    for (;;) {
        uint32_t spins = 0;
        while (atomic_load_explicit(&pool->job_gen, memory_order_acquire) == seen &&
               !atomic_load_explicit(&pool->quit, memory_order_acquire)) {
            if (++spins < SPIN_BEFORE_SLEEP) {
                CPU_RELAX();
                continue;
            }
            rbc_mutex_lock(&pool->mu);
            while (atomic_load(&pool->job_gen) == seen && !atomic_load(&pool->quit))
                rbc_cond_wait(&pool->cv, &pool->mu);
            rbc_mutex_unlock(&pool->mu);
        }
        if (atomic_load(&pool->quit)) break;
        seen = atomic_load(&pool->job_gen);
        if (tid < pool->active) pool->fn(pool->ctx, tid, pool->active);
        atomic_fetch_add(&pool->done, 1);
        if (atomic_load(&pool->done_sleeper))
            futex_wake(&pool->done, 0);
    }
}

#if defined(_WIN32)
/* QueryPerformanceCounter, monotonic: mingw-w64's clock_gettime is winpthreads' and
 * MSVC has none. The frequency is asked each time (it reads a value Windows fixed at
 * boot, no system call) rather than cached in a static that threads would race on.
 * Whole seconds and the remainder apart, so that no tick count loses digits. */
double rbc_now_ms(void) {
    LARGE_INTEGER t, f;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&t);
    return (double)(t.QuadPart / f.QuadPart) * 1e3 +
           (double)(t.QuadPart % f.QuadPart) * 1e3 / (double)f.QuadPart;
}

uint32_t rbc_cpu_count(void) {
    /* The process's affinity mask, as sched_getaffinity below (one processor group:
     * up to 64 cores). */
    DWORD_PTR proc, sys;
    if (GetProcessAffinityMask(GetCurrentProcess(), &proc, &sys) && proc) {
        uint32_t c = 0;
        for (; proc; proc &= proc - 1) ++c;
        return c;
    }
    SYSTEM_INFO si;
    GetSystemInfo(&si);
    return si.dwNumberOfProcessors > 0 ? (uint32_t)si.dwNumberOfProcessors : 1u;
}
#else
double rbc_now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

uint32_t rbc_cpu_count(void) {
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof set, &set) == 0) {
        int c = CPU_COUNT(&set);
        if (c > 0) return (uint32_t)c;
    }
    long c = sysconf(_SC_NPROCESSORS_ONLN);
    return c > 0 ? (uint32_t)c : 1u;
}
#endif

int rbc_pool_create(rbc_pool **out, uint32_t nthreads, const rbc_allocator *a) {
    *out = NULL;
    if (nthreads < 1) nthreads = 1;
    rbc_pool *pool = rbc_mem_alloc(a, sizeof *pool);
    if (!pool) return -1;
    pool->alloc = *a;
    pool->n = nthreads;
    pool->active = nthreads;
    rbc_mutex_init(&pool->mu);
    rbc_cond_init(&pool->cv);
    size_t bytes = sizeof(rbc_thread) * nthreads + sizeof(worker_arg) * nthreads;
    pool->threads = rbc_mem_alloc(a, bytes);
    if (!pool->threads) {
        rbc_pool_destroy(pool);
        return -1;
    }
    worker_arg *args = (worker_arg *)(pool->threads + nthreads);
    for (uint32_t t = 1; t < nthreads; ++t) {
        args[t].pool = pool;
        args[t].tid = t;
        if (rbc_thread_create(&pool->threads[t], worker_main, &args[t]) != 0) {
            pool->n = t; /* join only the ones started */
            rbc_pool_destroy(pool);
            return -1;
        }
    }
    *out = pool;
    return 0;
}

void rbc_pool_destroy(rbc_pool *pool) {
    if (!pool) return;
    rbc_mutex_lock(&pool->mu);
    atomic_store(&pool->quit, 1);
    rbc_cond_broadcast(&pool->cv);
    rbc_mutex_unlock(&pool->mu);
    if (pool->threads)
        for (uint32_t t = 1; t < pool->n; ++t) rbc_thread_join(&pool->threads[t]);
    rbc_mutex_destroy(&pool->mu);
    rbc_cond_destroy(&pool->cv);
    rbc_allocator a = pool->alloc;
    uint32_t n = pool->n;
    rbc_mem_free(&a, pool->threads, sizeof(rbc_thread) * n + sizeof(worker_arg) * n);
    rbc_mem_free(&a, pool, sizeof *pool);
}

uint32_t rbc_pool_size(const rbc_pool *pool) { return pool->hosted ? pool->host_n : pool->n; }

void rbc_pool_set_host(rbc_pool *pool, const rbc_pool_host *host, uint32_t participants) {
    pool->hosted = 1;
    pool->host = *host;
    pool->host_n = participants < 1 ? 1 : participants > HOST_COUNT ? HOST_COUNT : participants;
}

/* The pool whose enqueue call this thread is inside, if any: a serial executor that
 * runs an item inside enqueue runs it on the caller's own thread, which must not wait
 * for itself. */
#if defined(_MSC_VER) && !defined(__clang__)
static __declspec(thread) const rbc_pool *tls_enqueuing;
#else
static _Thread_local const rbc_pool *tls_enqueuing;
#endif

/* One item of the host's: join the run unless it is sealed, wait for the go, run fn
 * as the next thread id. The range is one participant however many items it holds. */
static void host_entry(uint32_t begin, uint32_t end, uint32_t worker, void *arg) {
    (void)begin, (void)end, (void)worker;
    rbc_pool *pool = arg;
    if (tls_enqueuing == pool) return;
    uint32_t s = atomic_load(&pool->h_state);
    do {
        if (s & HOST_SEALED) return;
    } while (!atomic_compare_exchange_weak(&pool->h_state, &s, s + 1));
    uint32_t spins = 0;
    double since = 0.0;
    while (!atomic_load_explicit(&pool->h_go, memory_order_acquire)) {
        if (atomic_load(&pool->h_in_enqueue)) {
            const double now = rbc_now_ms();
            if (since == 0.0) {
                since = now;
            } else if (now - since > HOST_LEAVE_MS) {
                /* Leave, unless the seal counted this item already. */
                s = atomic_load(&pool->h_state);
                while (!(s & HOST_SEALED))
                    if (atomic_compare_exchange_weak(&pool->h_state, &s, s - 1)) return;
            }
        }
        rbc_pool_spin(&spins);
    }
    const uint32_t tid = atomic_fetch_add(&pool->h_tid, 1);
    pool->fn(pool->ctx, tid, pool->active);
    atomic_fetch_add_explicit(&pool->h_done, 1, memory_order_release);
}

static double *host_last_ms(rbc_pool *pool, rbc_pool_fn fn) {
    for (int k = 0; k < HOST_FNS; ++k)
        if (pool->h_fn[k] == fn || !pool->h_fn[k]) {
            pool->h_fn[k] = fn;
            return &pool->h_ms[k];
        }
    return &pool->h_ms[0];
}

static uint32_t run_hosted(rbc_pool *pool, uint32_t n, rbc_pool_fn fn, void *ctx) {
    pool->fn = fn;
    pool->ctx = ctx;
    atomic_store(&pool->h_state, 0);
    atomic_store(&pool->h_go, 0);
    atomic_store(&pool->h_tid, 1);
    atomic_store(&pool->h_done, 0);
    atomic_store(&pool->h_in_enqueue, 1);
    /* Restored, not cleared: a serial executor may step another hosted world from
     * inside this enqueue, on this thread. */
    const rbc_pool *outer = tls_enqueuing;
    tls_enqueuing = pool;
    void *handle = pool->host.enqueue(host_entry, n - 1, 1, pool, pool->host.user);
    tls_enqueuing = outer;
    atomic_store(&pool->h_in_enqueue, 0);
    double *last = host_last_ms(pool, fn);
    double wait = *last > 0.0 ? 0.25 * *last : HOST_WAIT_FIRST_MS;
    wait = wait < HOST_WAIT_MIN_MS ? HOST_WAIT_MIN_MS : wait > HOST_WAIT_MAX_MS ? HOST_WAIT_MAX_MS : wait;
    const double t0 = rbc_now_ms();
    for (uint32_t spins = 0; (atomic_load(&pool->h_state) & HOST_COUNT) < n - 1; ++spins) {
        if ((spins & 63) == 63 && rbc_now_ms() - t0 >= wait) break;
        CPU_RELAX();
    }
    const uint32_t joined = atomic_fetch_or(&pool->h_state, HOST_SEALED) & HOST_COUNT;
    pool->active = joined + 1;
    atomic_store_explicit(&pool->h_go, 1, memory_order_release);
    const double r0 = rbc_now_ms();
    fn(ctx, 0, joined + 1);
    for (uint32_t spins = 0; atomic_load_explicit(&pool->h_done, memory_order_acquire) < joined;)
        rbc_pool_spin(&spins);
    *last = rbc_now_ms() - r0;
    /* Every item has returned or will return at once (sealed); finish_task waits for
     * the late ones, so none reads this run's state when the next run resets it. */
    if (handle) pool->host.finish(handle, pool->host.user);
    return joined + 1;
}

void rbc_pool_run(rbc_pool *pool, rbc_pool_fn fn, void *ctx) {
    rbc_pool_run_n(pool, rbc_pool_size(pool), fn, ctx);
}

uint32_t rbc_pool_run_n(rbc_pool *pool, uint32_t n, rbc_pool_fn fn, void *ctx) {
    if (n < 1) n = 1;
    if (n > rbc_pool_size(pool)) n = rbc_pool_size(pool);
    if (n == 1) {
        /* Barriers see active 1 and return at once; the workers stay asleep. */
        pool->active = 1;
        fn(ctx, 0, 1);
        return 1;
    }
    if (pool->hosted) return run_hosted(pool, n, fn, ctx);
    pool->fn = fn;
    pool->ctx = ctx;
    pool->active = n;
    atomic_store_explicit(&pool->done, 0, memory_order_relaxed);
    rbc_mutex_lock(&pool->mu);
    atomic_fetch_add_explicit(&pool->job_gen, 1, memory_order_release);
    rbc_cond_broadcast(&pool->cv);
    rbc_mutex_unlock(&pool->mu);
    fn(ctx, 0, n);
    /* Every worker acknowledges the run (those past n at once), so none still reads
     * fn or ctx when the next run sets them. */
    const uint32_t want = pool->n - 1;
    uint32_t spins = 0;
    for (;;) {
        uint32_t d = atomic_load(&pool->done);
        if (d == want) break;
        if (++spins < SPIN_BEFORE_FUTEX) {
            CPU_RELAX();
            continue;
        }
        /* As the barrier's sleep: announce, re-check inside the futex. */
        atomic_store(&pool->done_sleeper, 1);
        d = atomic_load(&pool->done);
        if (d != want)
            futex_wait(&pool->done, d);
        atomic_store(&pool->done_sleeper, 0);
    }
    return n;
}

void rbc_pool_barrier(rbc_pool *pool) {
    const uint32_t n = pool->active;
    if (n == 1) return;
    uint32_t gen = atomic_load_explicit(&pool->bar_gen, memory_order_acquire);
    if (atomic_fetch_add_explicit(&pool->bar_count, 1, memory_order_acq_rel) == n - 1) {
        atomic_store_explicit(&pool->bar_count, 0, memory_order_relaxed);
        atomic_fetch_add(&pool->bar_gen, 1);
        if (atomic_load(&pool->bar_sleepers))
            futex_wake(&pool->bar_gen, 1);
        return;
    }
    uint32_t spins = 0;
    while (atomic_load_explicit(&pool->bar_gen, memory_order_acquire) == gen) {
        if (++spins < SPIN_BEFORE_FUTEX) {
            CPU_RELAX();
            continue;
        }
        /* Sleep while the generation is still gen: the futex checks that atomically,
         * so a release between the load above and the wait is not lost; the releaser
         * wakes only when someone announced a sleep (sequentially consistent order of
         * sleepers++ here and bar_gen++ there: it sees the sleeper, or the sleeper
         * sees the new generation). */
        atomic_fetch_add(&pool->bar_sleepers, 1);
        if (atomic_load(&pool->bar_gen) == gen)
            futex_wait(&pool->bar_gen, gen);
        atomic_fetch_sub(&pool->bar_sleepers, 1);
    }
}

void rbc_pool_spin(uint32_t *spins) {
    if (++*spins < SPIN_BEFORE_YIELD) CPU_RELAX();
#if defined(_WIN32)
    else SwitchToThread();
#else
    else sched_yield();
#endif
}
