/* registry.h -- process-wide tables that turn 32-bit ids into objects.
 *
 * An id carries a kind, a generation and a slot (handles.h); each entry also
 * records the world that owns it. A lookup therefore tells apart a live object, a
 * destroyed one (generation moved on), an id of another kind, and an id of another
 * world -- a cloth id is unique across all worlds, so one world's cloth id can never
 * name another world's cloth.
 *
 * Thread safety: add and remove take the registry's lock; get reads one entry
 * without it. That is safe under the ABI's thread contract, where only the thread
 * using a world adds, removes or looks up that world's objects. */
#ifndef RBC_PLUGIN_REGISTRY_H
#define RBC_PLUGIN_REGISTRY_H
#include <stdatomic.h>
#include <stdint.h>

#include "rbcloth.h"
#include "threads.h"

typedef struct rbc_reg_entry {
    _Atomic uint32_t gen;      /* generation of the live (or last) object in the slot */
    _Atomic uint32_t owner;    /* world id of the owner (0 for worlds and caches) */
    _Atomic(void *) ptr;       /* NULL when the slot is free */
    uint32_t next_free;        /* free list link, under the lock */
} rbc_reg_entry;

typedef struct rbc_registry {
    rbc_mutex lock;
    uint32_t kind;             /* RBC_KIND_* */
    uint32_t cap;              /* entries, at most 65536 (16-bit slots) */
    uint32_t used;             /* slots ever used: [0, used) */
    uint32_t free_head;        /* UINT32_MAX when empty */
    rbc_reg_entry *entries;    /* [cap] */
} rbc_registry;

#define RBC_REGISTRY_INIT(kind_, cap_, storage_) \
    {RBC_MUTEX_INIT, (kind_), (cap_), 0, UINT32_MAX, (storage_)}

/* Add ptr owned by `owner`; *out_id receives the new id. RBC_ERR_CAPACITY when full. */
rbc_result rbc_reg_add(rbc_registry *r, void *ptr, uint32_t owner, uint32_t *out_id);
/* Remove a live id (the caller has looked it up). */
void rbc_reg_remove(rbc_registry *r, uint32_t id);

/* Look up id as an object of this registry's kind owned by `owner`. On failure
 * returns NULL and sets the thread's error (RBC_ERR_STALE_HANDLE) with a message
 * that starts with `fn` and says which of the cases it was. */
void *rbc_reg_get(rbc_registry *r, uint32_t id, uint32_t owner, const char *fn);
#endif
