#include "alloc.h"

#include <stdlib.h>
#include <string.h>

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

rbc_allocator rbc_allocator_default(void) {
    rbc_allocator a = {default_alloc, default_free, NULL};
    return a;
}

void *rbc_mem_alloc(const rbc_allocator *a, size_t size) {
    if (size == SIZE_MAX) return NULL;
    if (size == 0) size = 1;
    void *p = a->alloc(a->user, size, 64);
    if (p) memset(p, 0, size);
    return p;
}

void rbc_mem_free(const rbc_allocator *a, void *ptr, size_t size) {
    if (!ptr) return;
    if (size == 0) size = 1;
    a->free(a->user, ptr, size);
}
