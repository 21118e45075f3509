/* prefetch.h -- a software prefetch for the set-up's passes over scattered meshes.
 *
 * A mesh whose host order is shuffled makes the set-up read per-vertex arrays at
 * random: each such read is a cache miss, and in a loop whose trip counts vary the
 * core overlaps few of them. Asking for the line some iterations ahead overlaps them
 * without changing what is computed. */
#ifndef RBC_CORE_PREFETCH_H
#define RBC_CORE_PREFETCH_H

#if defined(__GNUC__) || defined(__clang__)
#define RBC_PREFETCH(addr) __builtin_prefetch((addr), 0, 3)
#define RBC_PREFETCH_W(addr) __builtin_prefetch((addr), 1, 3)
#else
#define RBC_PREFETCH(addr) ((void)(addr))
#define RBC_PREFETCH_W(addr) ((void)(addr))
#endif

/* How far ahead the set-up's gathers ask: enough iterations to cover a miss to memory
 * (about 100 ns) at a few ns per iteration. */
enum { RBC_PREFETCH_AHEAD = 16 };

#endif
