/* alloc.h -- the allocator every core allocation goes through (the world def's
 * hooks, or malloc), and small helpers for 64-byte aligned arrays. */
#ifndef RBC_CORE_ALLOC_H
#define RBC_CORE_ALLOC_H
#include <stddef.h>
#include <stdint.h>

typedef struct rbc_allocator {
    void *(*alloc)(void *user, size_t size, size_t alignment);
    void (*free)(void *user, void *ptr, size_t size);
    void *user;
} rbc_allocator;

/* The default allocator: aligned_alloc/free (_aligned_malloc/_aligned_free on Windows). */
rbc_allocator rbc_allocator_default(void);

/* size bytes, 64-byte aligned, zero-filled; NULL on failure (or size 0 -> a valid
 * non-NULL minimal block so callers need no special case). */
void *rbc_mem_alloc(const rbc_allocator *a, size_t size);
void rbc_mem_free(const rbc_allocator *a, void *ptr, size_t size);

/* count * elem with overflow check; SIZE_MAX on overflow (then alloc fails). */
static inline size_t rbc_mul_size(size_t count, size_t elem) {
    if (elem && count > SIZE_MAX / elem) return SIZE_MAX;
    return count * elem;
}
/* One array of an X-macro list of arrays (a struct's NAME_ARRAYS(X)): ptr gets count
 * elements of type, ok stays 1 only while every allocation succeeds, and bytes adds
 * what was asked for (the struct's footprint). */
#define RBC_ALLOC_ARRAY(a, ptr, count, type, ok, bytes)                 \
    do {                                                                \
        (ptr) = rbc_mem_alloc((a), rbc_mul_size((count), sizeof(type))); \
        (ok) = (ok) && (ptr) != NULL;                                    \
        (bytes) += rbc_mul_size((count), sizeof(type));                  \
    } while (0)
#endif
