/* cholmod_alloc.h -- CHOLMOD's (SuiteSparse's) allocations through the rbc_allocator
 * of the world whose CHOLMOD call is running.
 *
 * SuiteSparse 5 allocates through the process-global SuiteSparse_config
 * (malloc_func, calloc_func, realloc_func, free_func), and its free gets no size.
 * When CHOLMOD is loaded (cholmod_load.c, once per process) those four are
 * pointed at wrappers that allocate the size asked plus a 64-byte header through the
 * calling thread's current allocator, set by rbc_cholmod_enter; the header keeps
 * the size and a copy of the allocator, so a block is freed with its allocator and
 * size from any thread. The user part of a block is 64-byte aligned.
 *
 *   - Not installed if the host has already changed any of the four (a host that
 *     sets SuiteSparse_config itself keeps its allocator, and CHOLMOD's blocks go
 *     there, not to the world's hooks). A host that sets them must do so before its
 *     first direct-solver world (SuiteSparse asks for that too: "once at the
 *     beginning of the application"), and never after: blocks of the wrappers must
 *     not reach another free.
 *   - An allocation on a thread with no current allocator (a host's own SuiteSparse
 *     calls, or a thread CHOLMOD itself started) is plain malloc/calloc, with no
 *     header. CHOLMOD starts no thread in what direct.c calls: its only OpenMP
 *     region is in cholmod_updown_mask, and the simplicial path calls no BLAS. So a
 *     world's CHOLMOD blocks all come from its hooks. A second copy of the core in
 *     one process (two builds of the plugin) finds the first copy's wrappers
 *     installed and installs nothing; its CHOLMOD blocks come from malloc.
 *   - free and realloc tell the wrappers' blocks from malloc's by a registry of the
 *     live blocks of an allocator, chained through their headers (no allocation of
 *     its own). malloc's blocks include those SuiteSparse got before the wrappers
 *     were installed (a host that used it earlier); they go to free and realloc.
 *   - When the library is unloaded with no world's block alive, SuiteSparse's
 *     defaults are put back (rbc_cholmod_alloc_release).
 *   - SuiteSparse_config is the one of the CHOLMOD that cholmod_load.c loaded;
 *     without CHOLMOD nothing is installed and nothing needs to be.
 */
#ifndef RBC_CORE_CHOLMOD_ALLOC_H
#define RBC_CORE_CHOLMOD_ALLOC_H
#include "alloc.h"

/* Point SuiteSparse_config *c (the loaded CHOLMOD's) at the wrappers, unless the
 * host has changed any of its four functions. Once, by cholmod_load.c. */
struct SuiteSparse_config_struct;
void rbc_cholmod_alloc_install(struct SuiteSparse_config_struct *c);

/* Make *a the allocator of this thread's SuiteSparse allocations until rbc_cholmod_leave with the value returned (the
 * previous one: scopes nest). *a must stay valid until then. */
const rbc_allocator *rbc_cholmod_enter(const rbc_allocator *a);
void rbc_cholmod_leave(const rbc_allocator *previous);

/* 1 if the wrappers are installed (CHOLMOD loaded, rbc_cholmod_get), 0 if the host
 * had set SuiteSparse_config itself or CHOLMOD is not loaded. */
int rbc_cholmod_hooks_installed(void);

/* Put SuiteSparse_config *c back to malloc's functions if the wrappers are
 * installed and no block of theirs is alive; 1 if none of the wrappers is left in
 * it (or they never were), 0 if blocks are alive and the wrappers stay. For the
 * unloading plugin only (cholmod_load.c). */
int rbc_cholmod_alloc_release(struct SuiteSparse_config_struct *c);
#endif
