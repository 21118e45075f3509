/* collider.c -- the ABI's colliders: create (shapes and triangle meshes), move and
 * destroy. A collider lives in its solver's dense array; its id's registry entry is
 * a marker, and the lookup finds the collider's index by its id. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "errors.h"
#include "handles.h"
#include "attach.h"
#include "registry.h"
#include "rbcloth.h"
#include "solver.h"
#include "world.h"

/* Ids of colliders (registry.h), unique across worlds, so that a foreign id is told
 * apart from a live one. */
static rbc_reg_entry g_collider_entries[RBC_MAX_SLOTS];
rbc_registry rbc_plugin_colliders =
    RBC_REGISTRY_INIT(RBC_KIND_COLLIDER, RBC_MAX_SLOTS, g_collider_entries);

static rbc_result check_transform(rbc_world *w, const char *fn, const float *pos,
                                  const float *rot) {
    if (!pos || !rot)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: position or rotation is NULL", fn);
    if (!rbc_plugin_finite3(pos))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: position (%g, %g, %g) is not finite", fn, (double)pos[0],
                                      (double)pos[1], (double)pos[2]);
    double n2 = (double)rot[0] * rot[0] + (double)rot[1] * rot[1] + (double)rot[2] * rot[2] +
                (double)rot[3] * rot[3];
    /* Unit within float rounding of a normalised quaternion (a few ulp, 1e-4 leaves
     * room for hosts that normalise in float and then compose). */
    if (!(isfinite(n2) && fabs(n2 - 1.0) <= 1e-4))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: rotation (%g, %g, %g, %g) is not a unit quaternion (norm^2 %g)", fn,
            (double)rot[0], (double)rot[1], (double)rot[2], (double)rot[3], n2);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_collider_create(rbc_world_id wid, const rbc_collider_def *user_def,
                                                rbc_collider_id *out) {
    static const char fn[] = "rbc_collider_create";
    rbc_world *w;
    rbc_result rc = rbc_plugin_create_begin(wid, fn, out, "out_collider", &w);
    if (rc) return rc;
    rbc_collider_def def = rbc_plugin_collider_def_defaults();
    if ((rc = rbc_plugin_world_read_def(w, &def, &rbc_sizes_collider_def, user_def, fn,
                                        "rbc_collider_def")))
        return rc;
    if (def.shape < RBC_SHAPE_PLANE || def.shape > RBC_SHAPE_TRIANGLE_MESH)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: collider def: shape %d is not an rbc_shape", fn,
                                      (int)def.shape);
    if ((def.shape == RBC_SHAPE_SPHERE || def.shape == RBC_SHAPE_CAPSULE) &&
        !(isfinite(def.radius) && def.radius > 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: collider def: %s radius is %g m; it must be finite and > 0", fn,
            def.shape == RBC_SHAPE_SPHERE ? "sphere" : "capsule", (double)def.radius);
    if (def.shape == RBC_SHAPE_BOX || def.shape == RBC_SHAPE_CAPSULE)
        for (int a = def.shape == RBC_SHAPE_CAPSULE ? 1 : 0;
             a < (def.shape == RBC_SHAPE_CAPSULE ? 2 : 3); ++a)
            if (!(isfinite(def.half_extents[a]) && def.half_extents[a] > 0.0f))
                return rbc_plugin_world_error(
                    w, RBC_ERR_INVALID_ARGUMENT,
                    "%s: collider def: %s half_extents[%d] is %g m; it must be "
                    "finite and > 0",
                    fn, def.shape == RBC_SHAPE_BOX ? "box" : "capsule", a,
                    (double)def.half_extents[a]);
    if (!(isfinite(def.friction) && def.friction >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: collider def: friction is %g; it must be finite and >= 0", fn,
            (double)def.friction);
    if (!(isfinite(def.thickness) && def.thickness >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: collider def: thickness is %g m; it must be finite and >= 0", fn,
            (double)def.thickness);
    if ((rc = check_transform(w, fn, def.position, def.rotation))) return rc;
    rbc_collider_state cs;
    memset(&cs, 0, sizeof cs);
    cs.shape = def.shape;
    cs.radius = def.radius;
    cs.thickness = def.thickness;
    cs.friction = def.friction;
    memcpy(cs.half_extents, def.half_extents, sizeof cs.half_extents);
    if (def.shape == RBC_SHAPE_TRIANGLE_MESH) {
        char msg[RBC_ERROR_CAP - 64];
        rc = rbc_trimesh_create(def.mesh_positions, def.mesh_vertex_count, def.mesh_triangles,
                                def.mesh_triangle_count, &w->solver.alloc, &cs.mesh, msg,
                                sizeof msg);
        if (rc)
            return rbc_plugin_world_error(w, rc, "%s: collider def: triangle mesh: %s", fn, msg);
    }
    memcpy(cs.position, def.position, sizeof cs.position);
    memcpy(cs.rotation, def.rotation, sizeof cs.rotation);
    /* The registry holds a marker; the collider itself lives in the solver's dense
     * array, found by its id. */
    if (rbc_reg_add(&rbc_plugin_colliders, (void *)(uintptr_t)1, w->id, &cs.public_id) != RBC_OK) {
        rbc_trimesh_destroy(cs.mesh, &w->solver.alloc);
        return rbc_plugin_world_error(w, RBC_ERR_CAPACITY, "%s: %u colliders exist already", fn,
                                      RBC_MAX_SLOTS);
    }
    if ((rc = rbc_solver_add_collider(&w->solver, &cs))) {
        rbc_trimesh_destroy(cs.mesh, &w->solver.alloc);
        rbc_reg_remove(&rbc_plugin_colliders, cs.public_id);
        return rbc_plugin_world_error(w, rc, "%s: out of memory", fn);
    }
    *out = cs.public_id;
    return RBC_OK;
}

rbc_result rbc_plugin_lookup_collider(rbc_world_id wid, rbc_collider_id cid, const char *fn,
                                      rbc_world **ow, uint32_t *index) {
    rbc_result rc = rbc_plugin_lookup_world(wid, fn, ow);
    if (rc) return rc;
    if (!rbc_reg_get(&rbc_plugin_colliders, cid, (*ow)->id, fn)) {
        rbc_plugin_world_log(*ow, RBC_LOG_ERROR, rbc_last_error());
        return RBC_ERR_STALE_HANDLE;
    }
    rbc_solver *sol = &(*ow)->solver;
    for (uint32_t k = 0; k < sol->collider_count; ++k)
        if (sol->colliders[k].public_id == cid) {
            *index = k;
            return RBC_OK;
        }
    return rbc_plugin_world_error(*ow, RBC_ERR_STALE_HANDLE,
                                  "%s: collider 0x%08x is not in the world", fn, cid);
}

RBC_API rbc_result RBC_CALL rbc_collider_set_transform(rbc_world_id wid, rbc_collider_id cid,
                                                       const float position[3],
                                                       const float rotation[4]) {
    static const char fn[] = "rbc_collider_set_transform";
    rbc_world *w;
    uint32_t k = 0;
    rbc_result rc = rbc_plugin_lookup_collider(wid, cid, fn, &w, &k);
    if (rc) return rc;
    if ((rc = check_transform(w, fn, position, rotation))) return rc;
    rbc_collider_state *c = &w->solver.colliders[k];
    memcpy(c->position, position, sizeof c->position);
    memcpy(c->rotation, rotation, sizeof c->rotation);
    rbc_collider_update_frame(c);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_collider_destroy(rbc_world_id wid, rbc_collider_id cid) {
    rbc_world *w;
    uint32_t k = 0;
    rbc_result rc = rbc_plugin_lookup_collider(wid, cid, "rbc_collider_destroy", &w, &k);
    if (rc) return rc;
    if ((rc = rbc_attachments_drop_collider(&w->solver, cid)))
        return rbc_plugin_world_error(
            w, rc, "rbc_collider_destroy: out of memory releasing attached vertices");
    rbc_solver_remove_collider(&w->solver, k);
    rbc_reg_remove(&rbc_plugin_colliders, cid);
    return RBC_OK;
}
