/* solver.c -- a world of the core: its life cycle, its cloths and colliders, the
 * global solver's settings and the host callbacks (solver.h). The step is step.c. */
#include "solver.h"

#include <math.h>
#include <string.h>

#include "clothcontact.h"

int32_t rbc_solver_init(rbc_solver *s, const rbc_allocator *a, uint32_t nthreads) {
    memset(s, 0, sizeof *s);
    s->alloc = *a;
    s->substeps = 1;
    s->nonlinear_iterations = 1;
    s->linear_iterations = 11;
    s->gravity[1] = -9.81f;
    s->settings.kind = RBC_SOLVER_RBGS;
    s->settings.chebyshev_delay = 2;
    s->settings.mode = RBC_ITERATE_FIXED;
    s->settings.tolerance = 1e-3f;
    s->settings.budget_ms = 2.0f;
    s->settings.max_linear_iterations = 1000;
    s->settings.energy_guard = RBC_ENERGY_GUARD_CLAMP;
    s->settings.target_strain = 0.05f;
    s->settings.max_substeps = 16;
    rbc_solver_target_reset(s);
    if (rbc_pool_create(&s->pool, nthreads, a) != 0) return RBC_ERR_OUT_OF_MEMORY;
    return RBC_OK;
}

void rbc_solver_fini(rbc_solver *s) {
    rbc_solver_set_backend(s, NULL);
    for (uint32_t k = 0; k < s->cloth_count; ++k) rbc_cloth_state_destroy(&s->alloc, s->cloths[k]);
    rbc_mem_free(&s->alloc, s->cloths, sizeof(*s->cloths) * s->cloth_cap);
    rbc_mem_free(&s->alloc, s->cb_list, sizeof(*s->cb_list) * s->cloth_cap);
    for (uint32_t k = 0; k < s->collider_count; ++k) rbc_trimesh_destroy(s->colliders[k].mesh, &s->alloc);
    rbc_mem_free(&s->alloc, s->colliders, sizeof(*s->colliders) * s->collider_cap);
    for (uint32_t k = 0; k < 64; ++k) rbc_contact_list_free(&s->contacts[k], &s->alloc);
    rbc_contact_list_free(&s->host_contacts, &s->alloc);
    rbc_clothcontact_destroy(s->cc);
    rbc_mem_free(&s->alloc, s->cc_bodies, sizeof(*s->cc_bodies) * s->cc_bodies_cap);
    rbc_pool_destroy(s->pool);
    memset(s, 0, sizeof *s);
}

int32_t rbc_solver_create_cloth(rbc_solver *s, const rbc_mesh_input *in, float damping,
                                rbc_cloth_state **out, char *err, size_t errlen) {
    return rbc_cloth_state_create(&s->alloc, s->settings.kind, s->callback || s->contact_fn, in,
                                  damping, out, err, errlen);
}

int32_t rbc_solver_set_cloth_contact(rbc_solver *s, rbc_cloth_state *c, float thickness,
                                     float friction, uint32_t flags) {
    if (flags && !s->cc) {
        int32_t rc = rbc_clothcontact_create(&s->alloc, &s->cc);
        if (rc != RBC_OK) return rc;
    }
    return rbc_cloth_state_set_contact(&s->alloc, c, thickness, friction, flags);
}

int32_t rbc_solver_add_cloth(rbc_solver *s, rbc_cloth_state *c) {
    if (s->cloth_count == s->cloth_cap) {
        uint32_t cap = s->cloth_cap ? s->cloth_cap * 2 : 4;
        rbc_cloth_state **list = rbc_mem_alloc(&s->alloc, sizeof(*list) * cap);
        rbc_collision_cloth *cbl = rbc_mem_alloc(&s->alloc, sizeof(*cbl) * cap);
        if (!list || !cbl) {
            rbc_mem_free(&s->alloc, list, sizeof(*list) * cap);
            rbc_mem_free(&s->alloc, cbl, sizeof(*cbl) * cap);
            return RBC_ERR_OUT_OF_MEMORY;
        }
        if (s->cloth_count) memcpy(list, s->cloths, sizeof(*list) * s->cloth_count);
        rbc_mem_free(&s->alloc, s->cloths, sizeof(*s->cloths) * s->cloth_cap);
        rbc_mem_free(&s->alloc, s->cb_list, sizeof(*s->cb_list) * s->cloth_cap);
        s->cloths = list;
        s->cb_list = cbl;
        s->cloth_cap = cap;
    }
    s->cloths[s->cloth_count++] = c;
    return RBC_OK;
}

void rbc_solver_remove_cloth(rbc_solver *s, rbc_cloth_state *c) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (s->cloths[k] != c) continue;
        if (s->backend.ops) rbc_solver_release_backend_copy(s, c);
        /* Keep creation order (stable iteration order for hosts and tests). */
        memmove(&s->cloths[k], &s->cloths[k + 1], sizeof(*s->cloths) * (s->cloth_count - k - 1));
        s->cloth_count--;
        return;
    }
}

void rbc_collider_update_frame(rbc_collider_state *c) {
    /* Rotate +y by the unit quaternion (x, y, z, w): the second column of R. */
    float qx = c->rotation[0], qy = c->rotation[1], qz = c->rotation[2], qw = c->rotation[3];
    c->normal[0] = 2.0f * (qx * qy - qz * qw);
    c->normal[1] = 1.0f - 2.0f * (qx * qx + qz * qz);
    c->normal[2] = 2.0f * (qy * qz + qx * qw);
    float len = sqrtf(c->normal[0] * c->normal[0] + c->normal[1] * c->normal[1] +
                      c->normal[2] * c->normal[2]);
    for (int k = 0; k < 3; ++k) c->normal[k] /= len;
}

int32_t rbc_solver_add_collider(rbc_solver *s, const rbc_collider_state *c) {
    if (s->collider_count == s->collider_cap) {
        uint32_t cap = s->collider_cap ? s->collider_cap * 2 : 4;
        rbc_collider_state *arr = rbc_mem_alloc(&s->alloc, sizeof(*arr) * cap);
        if (!arr) return RBC_ERR_OUT_OF_MEMORY;
        if (s->collider_count) memcpy(arr, s->colliders, sizeof(*arr) * s->collider_count);
        rbc_mem_free(&s->alloc, s->colliders, sizeof(*s->colliders) * s->collider_cap);
        s->colliders = arr;
        s->collider_cap = cap;
    }
    s->colliders[s->collider_count] = *c;
    rbc_collider_state *added = &s->colliders[s->collider_count];
    memcpy(added->last_position, added->position, sizeof added->position);
    memcpy(added->last_rotation, added->rotation, sizeof added->rotation);
    memset(&added->geom, 0, sizeof added->geom);
    added->geom.kind = added->shape;
    added->geom.radius = added->radius;
    memcpy(added->geom.half_extents, added->half_extents, sizeof added->half_extents);
    added->geom.mesh = added->mesh;
    rbc_shape_bounds(&added->geom, added->lo, added->hi);
    memset(added->velocity, 0, sizeof added->velocity);
    rbc_collider_update_frame(added);
    s->collider_count++;
    return RBC_OK;
}

void rbc_solver_remove_collider(rbc_solver *s, uint32_t index) {
    rbc_trimesh_destroy(s->colliders[index].mesh, &s->alloc);
    memmove(&s->colliders[index], &s->colliders[index + 1],
            sizeof(*s->colliders) * (s->collider_count - index - 1));
    s->collider_count--;
}

/* Host-order buffers exist while either host callback is installed. */
static int32_t cb_buffers_for(rbc_solver *s, int had, int want) {
    if (want == had) return RBC_OK;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (rbc_cloth_state_host_buffers(&s->alloc, s->cloths[k], want)) continue;
        for (uint32_t j = 0; j < k; ++j) rbc_cloth_state_host_buffers(&s->alloc, s->cloths[j], 0);
        return RBC_ERR_OUT_OF_MEMORY;
    }
    return RBC_OK;
}

int32_t rbc_solver_set_callback(rbc_solver *s, rbc_collision_fn fn, void *user) {
    int had = s->callback || s->contact_fn;
    int32_t rc = cb_buffers_for(s, had, fn || s->contact_fn);
    if (rc != RBC_OK) return rc;
    s->callback = fn;
    s->callback_user = user;
    return RBC_OK;
}

int32_t rbc_solver_set_contact_callback(rbc_solver *s, rbc_contact_fn fn, void *user) {
    int had = s->callback || s->contact_fn;
    int32_t rc = cb_buffers_for(s, had, fn || s->callback);
    if (rc != RBC_OK) return rc;
    s->contact_fn = fn;
    s->contact_user = user;
    return RBC_OK;
}

int32_t rbc_solver_set_settings(rbc_solver *s, const rbc_solver_settings *st) {
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        if (rbc_cloth_state_solver_buffers(&s->alloc, s->cloths[k], st->kind)) continue;
        return RBC_ERR_OUT_OF_MEMORY; /* buffers kept so far are harmless extras */
    }
    for (uint32_t k = 0; k < s->cloth_count; ++k)
        rbc_cloth_state_release_solver_buffers(&s->alloc, s->cloths[k], st->kind);
    if (s->settings.energy_guard == RBC_ENERGY_GUARD_OFF && st->energy_guard != RBC_ENERGY_GUARD_OFF)
        for (uint32_t k = 0; k < s->cloth_count; ++k) /* unguarded steps: start afresh */
            rbc_cloth_state_energy_invalidate(s->cloths[k], 0);
    s->settings = *st;
    rbc_solver_target_reset(s); /* the controller starts again from the world's counts */
    return RBC_OK;
}
