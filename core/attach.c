/* attach.c -- attachments: pins that follow a collider (attach.h). */
#include "attach.h"

#include <string.h>

#include "collide.h"

static const rbc_collider_state *find_collider(const rbc_solver *s, uint32_t id) {
    for (uint32_t k = 0; k < s->collider_count; ++k)
        if (s->colliders[k].public_id == id) return &s->colliders[k];
    return NULL;
}

void rbc_detach_vertex(rbc_cloth_state *c, uint32_t host_vertex) {
    for (uint32_t m = 0; m < c->att.count; ++m) {
        if (c->att.vertex[m] != host_vertex) continue;
        uint32_t last = --c->att.count;
        c->att.vertex[m] = c->att.vertex[last];
        c->att.collider[m] = c->att.collider[last];
        memcpy(&c->att.local[3 * (size_t)m], &c->att.local[3 * (size_t)last], 3 * sizeof(float));
        return;
    }
}

static void frame_apply(const rbc_collider_state *col, const float l[3], float w[3]) {
    rbc_frame f;
    rbc_collider_frame_at(col, 1.0f, &f);
    for (int a = 0; a < 3; ++a)
        w[a] = f.r[3 * a] * l[0] + f.r[3 * a + 1] * l[1] + f.r[3 * a + 2] * l[2] + f.t[a];
}

int32_t rbc_attach(rbc_solver *s, rbc_cloth_state *c, uint32_t host_vertex,
                   uint32_t collider_public_id, const float local[3]) {
    const rbc_collider_state *col = find_collider(s, collider_public_id);
    if (!col) return RBC_ERR_STALE_HANDLE;
    float l[3], target[3];
    if (local) {
        memcpy(l, local, sizeof l);
    } else {
        /* Where the vertex is now, in the collider's frame. */
        rbc_frame f;
        rbc_collider_frame_at(col, 1.0f, &f);
        uint32_t i = c->topo.to_internal[host_vertex];
        float d[3] = {c->x[0][i] - f.t[0], c->x[1][i] - f.t[1], c->x[2][i] - f.t[2]};
        for (int a = 0; a < 3; ++a) l[a] = f.r[a] * d[0] + f.r[3 + a] * d[1] + f.r[6 + a] * d[2];
    }
    frame_apply(col, l, target);
    rbc_detach_vertex(c, host_vertex);
    if (c->att.count == c->att.cap) {
        uint32_t cap = c->att.cap ? 2 * c->att.cap : 8;
        uint32_t *v = rbc_mem_alloc(&s->alloc, sizeof(uint32_t) * cap);
        uint32_t *id = rbc_mem_alloc(&s->alloc, sizeof(uint32_t) * cap);
        float *lo = rbc_mem_alloc(&s->alloc, sizeof(float) * 3 * cap);
        if (!v || !id || !lo) {
            rbc_mem_free(&s->alloc, v, sizeof(uint32_t) * cap);
            rbc_mem_free(&s->alloc, id, sizeof(uint32_t) * cap);
            rbc_mem_free(&s->alloc, lo, sizeof(float) * 3 * cap);
            return RBC_ERR_OUT_OF_MEMORY;
        }
        if (c->att.count) {
            memcpy(v, c->att.vertex, sizeof(uint32_t) * c->att.count);
            memcpy(id, c->att.collider, sizeof(uint32_t) * c->att.count);
            memcpy(lo, c->att.local, sizeof(float) * 3 * c->att.count);
        }
        rbc_mem_free(&s->alloc, c->att.vertex, sizeof(uint32_t) * c->att.cap);
        rbc_mem_free(&s->alloc, c->att.collider, sizeof(uint32_t) * c->att.cap);
        rbc_mem_free(&s->alloc, c->att.local, sizeof(float) * 3 * c->att.cap);
        c->att.vertex = v;
        c->att.collider = id;
        c->att.local = lo;
        c->att.cap = cap;
    }
    int32_t rc = rbc_cloth_state_set_pin(&s->alloc, c, host_vertex, target);
    if (rc != RBC_OK) return rc;
    uint32_t m = c->att.count++;
    c->att.vertex[m] = host_vertex;
    c->att.collider[m] = collider_public_id;
    memcpy(&c->att.local[3 * (size_t)m], l, sizeof l);
    return RBC_OK;
}

void rbc_attachments_update(rbc_solver *s) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->att.count; ++m) {
            const rbc_collider_state *col = find_collider(s, c->att.collider[m]);
            if (!col) continue; /* dropped with its collider */
            float target[3];
            frame_apply(col, &c->att.local[3 * (size_t)m], target);
            /* The vertex is pinned (attach pinned it): only the target moves, which
             * cannot fail. */
            uint32_t i = c->topo.to_internal[c->att.vertex[m]];
            for (uint32_t p = 0; p < c->pin_count; ++p)
                if (c->pin_idx[p] == i) memcpy(&c->pin_target[3 * (size_t)p], target, sizeof target);
        }
    }
}

int32_t rbc_attachments_drop_collider(rbc_solver *s, uint32_t collider_public_id) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        for (uint32_t m = 0; m < c->att.count;) {
            if (c->att.collider[m] != collider_public_id) {
                ++m;
                continue;
            }
            uint32_t v = c->att.vertex[m];
            rbc_detach_vertex(c, v);
            int32_t rc = rbc_cloth_state_set_pin(&s->alloc, c, v, NULL);
            if (rc != RBC_OK) return rc;
        }
    }
    return RBC_OK;
}
