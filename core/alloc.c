/* MAP_ANONYMOUS is not POSIX 2008: ask for the BSD/GNU names too. */
#define _DEFAULT_SOURCE 1
#include "alloc.h"

#include <stdlib.h>
#include <string.h>
#if defined(__unix__)
#include <sys/mman.h>
#define RBC_HAVE_MMAP 1
#endif

/* Large blocks of the default allocator come straight from mmap: the kernel hands
 * out zero pages on first touch, so a 1M-particle cloth does not fault in and clear
 * ~300 MB at creation (arrays a scene never uses, like the substep snapshots of a
 * one-substep world, are never touched at all). Page alignment covers the 64 bytes
 * asked for. */
enum { RBC_MMAP_MIN = 256 * 1024 };
/* Blocks from this size on are offered huge pages (below, in rbc_mem_alloc): at
 * least two 2 MB pages, so that most of the block can use them. */
enum { RBC_HUGE_MIN = 4 * 1024 * 1024 };

#if defined(_WIN32)
/* The Windows C runtimes (msvcrt, the UCRT) have no aligned_alloc: a free() that takes
 * any block cannot release an over-aligned one there. _aligned_malloc's blocks are
 * released by _aligned_free, and only by it. */
#include <malloc.h>

static void *default_alloc(void *user, size_t size, size_t alignment) {
    (void)user;
    return _aligned_malloc(size, alignment);
}

static void default_free(void *user, void *ptr, size_t size) {
    (void)user;
    (void)size;
    _aligned_free(ptr);
}
#else
static void *default_alloc(void *user, size_t size, size_t alignment) {
    (void)user;
    /* aligned_alloc needs size to be a multiple of the alignment. */
    size_t rounded = (size + alignment - 1) / alignment * alignment;
    if (rounded < size) return NULL;
    return aligned_alloc(alignment, rounded);
}

static void default_free(void *user, void *ptr, size_t size) {
    (void)user;
    (void)size;
    free(ptr);
}
#endif

rbc_allocator rbc_allocator_default(void) {
    rbc_allocator a = {default_alloc, default_free, NULL};
    return a;
}

void *rbc_mem_alloc(const rbc_allocator *a, size_t size) {
    if (size == SIZE_MAX) return NULL;
    if (size == 0) size = 1;
#ifdef RBC_HAVE_MMAP
    if (a->alloc == default_alloc && size >= RBC_MMAP_MIN) {
        void *m = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (m == MAP_FAILED) return NULL;
#ifdef MADV_HUGEPAGE
        /* Blocks of several huge pages take them where the kernel has them (THP in
         * "madvise" mode, the usual default): a 1M-particle cloth's creation faults
         * in ~300 MB, and 4 KB pages made that a fault per page, a fifth of its time
         * in the kernel. Untouched ranges still cost nothing; only a hint, so a
         * refusal changes nothing. */
        if (size >= RBC_HUGE_MIN) (void)madvise(m, size, MADV_HUGEPAGE);
#endif
        return m;
    }
#endif
    void *p = a->alloc(a->user, size, 64);
    if (p) memset(p, 0, size);
    return p;
}

void rbc_mem_free(const rbc_allocator *a, void *ptr, size_t size) {
    if (!ptr) return;
    if (size == 0) size = 1;
#ifdef RBC_HAVE_MMAP
    if (a->free == default_free && size >= RBC_MMAP_MIN) {
        munmap(ptr, size);
        return;
    }
#endif
    a->free(a->user, ptr, size);
}
