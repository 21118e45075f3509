/* cholmod_alloc.c -- SuiteSparse_config's allocation functions over the rbc_allocator
 * of the running CHOLMOD call (see cholmod_alloc.h).
 *
 * A block of an allocator is [header 64 bytes][size bytes]; the header holds the
 * registry link, the allocator and the size. A block made with no current allocator
 * is a plain malloc block with no header and not in the registry, like one from
 * before the wrappers: free and realloc tell the two kinds apart by the registry
 * alone. SuiteSparse's contract: malloc and calloc return NULL on failure (CHOLMOD
 * then reports CHOLMOD_OUT_OF_MEMORY), realloc returns NULL and leaves the block as
 * it was, free(NULL) does nothing.
 */
#include "cholmod_alloc.h"

#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <suitesparse/SuiteSparse_config.h>

enum { HEADER = 64, BUCKETS = 1024 };

typedef struct block {
    struct block *next; /* the registry chain of its bucket */
    rbc_allocator a;    /* the allocator it came from */
    size_t size;        /* what SuiteSparse asked for */
} block;
_Static_assert(sizeof(block) <= HEADER, "the header must fit in 64 bytes");

/* The allocator of this thread's CHOLMOD call, or NULL. */
static _Thread_local const rbc_allocator *current;

static int installed;

/* Live blocks of the wrappers, by header address. Only our own headers are ever
 * read: a pointer SuiteSparse frees is ours if its header address is in the chain. */
static pthread_mutex_t registry_lock = PTHREAD_MUTEX_INITIALIZER;
static block *registry[BUCKETS];

static size_t bucket_of(const block *b) {
    uint64_t h = (uint64_t)((uintptr_t)b / HEADER) * 0x9E3779B97F4A7C15ull;
    return (size_t)(h >> 54) & (BUCKETS - 1);
}

static void registry_add(block *b) {
    size_t k = bucket_of(b);
    pthread_mutex_lock(&registry_lock);
    b->next = registry[k];
    registry[k] = b;
    pthread_mutex_unlock(&registry_lock);
}

/* Remove b if it is one of ours; 1 if it was. */
static int registry_remove(const block *b) {
    size_t k = bucket_of(b);
    int found = 0;
    pthread_mutex_lock(&registry_lock);
    for (block **pp = &registry[k]; *pp; pp = &(*pp)->next) {
        if (*pp == b) {
            *pp = b->next;
            found = 1;
            break;
        }
    }
    pthread_mutex_unlock(&registry_lock);
    return found;
}

static int registry_has(const block *b) {
    size_t k = bucket_of(b);
    int found = 0;
    pthread_mutex_lock(&registry_lock);
    for (const block *q = registry[k]; q && !found; q = q->next) found = q == b;
    pthread_mutex_unlock(&registry_lock);
    return found;
}

/* The header a user pointer would have (arithmetic only: not read unless it is
 * in the registry). */
static block *header_of(void *p) { return (block *)(void *)((uintptr_t)p - HEADER); }

/* size bytes through a, after a header; zero-filled (rbc_mem_alloc). */
static void *block_alloc(size_t size, const rbc_allocator *a) {
    if (size == 0) size = 1;
    if (size > SIZE_MAX - HEADER) return NULL;
    block *b = rbc_mem_alloc(a, size + HEADER); /* 64-byte aligned */
    if (!b) return NULL;
    b->a = *a;
    b->size = size;
    registry_add(b);
    return (char *)b + HEADER;
}

/* No current allocator (a thread outside direct.c's scopes: see cholmod_alloc.h):
 * malloc's functions, as if the wrappers were not there. */
static void *ss_malloc(size_t size) {
    const rbc_allocator *a = current;
    return a ? block_alloc(size, a) : malloc(size);
}

static void *ss_calloc(size_t n, size_t size) {
    const rbc_allocator *a = current;
    if (!a) return calloc(n, size);
    size_t total = rbc_mul_size(n, size);
    return total == SIZE_MAX ? NULL : block_alloc(total, a);
}

static void ss_free(void *p) {
    if (!p) return;
    block *b = header_of(p);
    if (registry_remove(b)) {
        rbc_allocator a = b->a;
        rbc_mem_free(&a, b, b->size + HEADER);
    } else {
        free(p); /* a malloc block (no allocator, or from before the wrappers) */
    }
}

/* A block of an allocator: a new block of the same allocator, the common part
 * copied, the old one freed; on failure NULL and the old block untouched. A malloc
 * block stays one (realloc). */
static void *ss_realloc(void *p, size_t size) {
    if (!p) return ss_malloc(size);
    block *b = header_of(p);
    if (!registry_has(b)) return realloc(p, size);
    rbc_allocator a = b->a;
    void *q = block_alloc(size, &a);
    if (!q) return NULL;
    memcpy(q, p, b->size < size ? b->size : size);
    ss_free(p);
    return q;
}

void rbc_cholmod_alloc_install(struct SuiteSparse_config_struct *c) {
    if (c->malloc_func != malloc || c->calloc_func != calloc || c->realloc_func != realloc ||
        c->free_func != free)
        return; /* the host's own allocator: leave it */
    /* free first, malloc last: a block of ss_malloc never reaches free(), and
     * ss_free/ss_realloc take anything from malloc (registry miss). The volatile
     * stores keep this order; the hooks are meant to be set before other threads
     * use SuiteSparse (SuiteSparse_config.h). */
    volatile struct SuiteSparse_config_struct *v = c;
    v->free_func = ss_free;
    v->realloc_func = ss_realloc;
    v->calloc_func = ss_calloc;
    v->malloc_func = ss_malloc;
    installed = 1;
}

/* Called by cholmod_load.c's finalizer when the plugin is unloaded, before it
 * closes CHOLMOD: put SuiteSparse's defaults back, so that a SuiteSparse that stays
 * loaded (the host uses it too) is not left calling unmapped code. Only with no
 * block of an allocator alive: every world destroyed, as a host must before
 * unloading. */
int rbc_cholmod_alloc_release(struct SuiteSparse_config_struct *c) {
    if (!installed) return 1;
    pthread_mutex_lock(&registry_lock);
    int empty = 1;
    for (size_t k = 0; k < BUCKETS && empty; ++k) empty = registry[k] == NULL;
    pthread_mutex_unlock(&registry_lock);
    if (!empty) return 0;
    if (c->malloc_func != ss_malloc || c->calloc_func != ss_calloc ||
        c->realloc_func != ss_realloc || c->free_func != ss_free)
        return 1; /* the host replaced them after us: theirs now, and none is ours */
    /* malloc first, free last: the reverse of install. */
    volatile struct SuiteSparse_config_struct *v = c;
    v->malloc_func = malloc;
    v->calloc_func = calloc;
    v->realloc_func = realloc;
    v->free_func = free;
    installed = 0;
    return 1;
}

const rbc_allocator *rbc_cholmod_enter(const rbc_allocator *a) {
    const rbc_allocator *previous = current;
    current = a;
    return previous;
}

void rbc_cholmod_leave(const rbc_allocator *previous) { current = previous; }

int rbc_cholmod_hooks_installed(void) {
    return installed;
}
