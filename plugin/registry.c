#include "registry.h"

#include "errors.h"
#include "handles.h"

rbc_result rbc_reg_add(rbc_registry *r, void *ptr, uint32_t owner, uint32_t *out_id) {
    rbc_mutex_lock(&r->lock);
    uint32_t s;
    if (r->free_head != UINT32_MAX) {
        s = r->free_head;
        r->free_head = r->entries[s].next_free;
    } else if (r->used < r->cap) {
        s = r->used++;
    } else {
        rbc_mutex_unlock(&r->lock);
        return RBC_ERR_CAPACITY;
    }
    rbc_reg_entry *e = &r->entries[s];
    uint32_t gen = rbc_gen_next(atomic_load(&e->gen));
    atomic_store(&e->gen, gen);
    atomic_store(&e->owner, owner);
    atomic_store(&e->ptr, ptr);
    rbc_mutex_unlock(&r->lock);
    *out_id = rbc_id_make(r->kind, gen, s);
    return RBC_OK;
}

void rbc_reg_remove(rbc_registry *r, uint32_t id) {
    uint32_t s = rbc_id_slot(id);
    rbc_mutex_lock(&r->lock);
    atomic_store(&r->entries[s].ptr, NULL);
    r->entries[s].next_free = r->free_head;
    r->free_head = s;
    rbc_mutex_unlock(&r->lock);
}

void *rbc_reg_get(rbc_registry *r, uint32_t id, uint32_t owner, const char *fn) {
    const char *kname = rbc_kind_name(r->kind);
    if (id == 0) {
        rbc_set_error(RBC_ERR_STALE_HANDLE, "%s: %s id is 0 (null)", fn, kname);
        return NULL;
    }
    if (rbc_id_kind(id) != r->kind) {
        rbc_set_error(RBC_ERR_STALE_HANDLE, "%s: id 0x%08x is a %s id, not a %s id", fn, id,
                      rbc_kind_name(rbc_id_kind(id)), kname);
        return NULL;
    }
    uint32_t s = rbc_id_slot(id);
    rbc_reg_entry *e = s < r->cap ? &r->entries[s] : NULL;
    void *ptr = e ? atomic_load(&e->ptr) : NULL;
    if (!ptr || atomic_load(&e->gen) != rbc_id_gen(id)) {
        rbc_set_error(RBC_ERR_STALE_HANDLE,
                      "%s: %s id 0x%08x is stale (destroyed, or never created)", fn, kname, id);
        return NULL;
    }
    uint32_t o = atomic_load(&e->owner);
    if (o != owner) {
        rbc_set_error(RBC_ERR_STALE_HANDLE, "%s: %s 0x%08x belongs to world 0x%08x, not 0x%08x",
                      fn, kname, id, o, owner);
        return NULL;
    }
    return ptr;
}
