/* step_threads.c -- the thread count of a step (step_threads.h). */
#include "step_threads.h"

#include <math.h>

/* Results do not depend on the thread count (every reduction is over fixed blocks,
 * every partition is checked bitwise on 1 and 2 threads), so the count may change
 * from one step to the next. Every probe_every steps a probe runs PROBE_STEPS steps
 * on the other count and the fastest of them counts: 8 after a change, doubling to
 * 256 while the choice holds. */
enum { PROBE_FIRST = 8, PROBE_MAX = 256, PROBE_STEPS = 2 };

uint32_t rbc_step_threads_choose(rbc_solver *s) {
    const uint32_t all = rbc_pool_size(s->pool);
    if (!s->threads_auto || all == 1) return all;
    if (!s->threads_now) {
        /* First step: a small cloth's phases take microseconds, less than waking a
         * worker; start on one thread there, on all above 4096 particles per thread. */
        uint64_t n = 0;
        for (uint32_t k = 0; k < s->cloth_count; ++k) n += s->cloths[k]->topo.n;
        s->threads_now = n >= 4096ull * all ? all : 1;
        s->probe_every = PROBE_FIRST;
        s->probe_in = 2; /* the other count after two steps */
        s->probe_nrecent = 0;
        s->probe_left = 0;
    }
    const uint32_t other = s->threads_now == 1 ? all : 1;
    if (s->probe_left) return other;
    if (s->probe_in == 0 && s->probe_nrecent > 0) {
        /* A probe is two steps, the faster one counts: the first step on all threads
         * after a while on one wakes sleeping workers and warms their caches. */
        s->probe_left = PROBE_STEPS;
        s->probe_best = INFINITY;
        return other;
    }
    return s->threads_now;
}

static double median3(const double *v, uint32_t n) {
    if (n == 1) return v[0];
    if (n == 2) return v[0] < v[1] ? v[0] : v[1];
    double a = v[0], b = v[1], c = v[2];
    return a > b ? (b > c ? b : (a > c ? c : a)) : (a > c ? a : (b > c ? c : b));
}

void rbc_step_threads_record(rbc_solver *s, uint32_t used, double ms_per_substep) {
    if (!s->threads_auto || rbc_pool_size(s->pool) == 1) return;
    if (used != s->threads_now) {
        if (ms_per_substep < s->probe_best) s->probe_best = ms_per_substep;
        if (s->probe_left) s->probe_left--;
        if (s->probe_left) return;
        /* Switch when the probe beat the recent steps by 10 %. */
        double base = median3(s->probe_recent, s->probe_nrecent);
        if (s->probe_best < 0.9 * base) {
            s->threads_now = used;
            s->probe_recent[0] = s->probe_best;
            s->probe_nrecent = 1;
            s->probe_every = PROBE_FIRST;
        } else if (s->probe_every < PROBE_MAX) {
            s->probe_every *= 2;
        }
        s->probe_in = s->probe_every;
        return;
    }
    if (s->probe_nrecent < 3) s->probe_recent[s->probe_nrecent++] = ms_per_substep;
    else {
        s->probe_recent[0] = s->probe_recent[1];
        s->probe_recent[1] = s->probe_recent[2];
        s->probe_recent[2] = ms_per_substep;
    }
    if (s->probe_in) s->probe_in--;
}
