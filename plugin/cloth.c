/* cloth.c -- the ABI's cloths: create and destroy, read back positions, topology,
 * colors and state, set pins and state, and the calls that act on one cloth:
 * attaching a vertex to a collider, cutting springs, copying its quads and springs.
 * rbc_cloth_create_from_mesh is in import.c, with the meshes. */
#include <math.h>
#include <string.h>

#include "errors.h"
#include "handles.h"
#include "attach.h"
#include "tear.h"
#include "registry.h"
#include "rbcloth.h"
#include "solver.h"
#include "world.h"

/* Ids of cloths (registry.h), unique across worlds, so that a foreign id is told
 * apart from a live one. */
static rbc_reg_entry g_cloth_entries[RBC_MAX_SLOTS];
rbc_registry rbc_plugin_cloths = RBC_REGISTRY_INIT(RBC_KIND_CLOTH, RBC_MAX_SLOTS, g_cloth_entries);

/* ------------------------------------------------------------------------- */
/* Cloth                                                                     */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_cloth_create(rbc_world_id wid, const rbc_cloth_def *user_def,
                                             rbc_cloth_id *out_cloth) {
    static const char fn[] = "rbc_cloth_create";
    rbc_world *w;
    rbc_result rc = rbc_plugin_create_begin(wid, fn, out_cloth, "out_cloth", &w);
    if (rc) return rc;
    rbc_cloth_def def = rbc_plugin_cloth_def_defaults();
    if ((rc = rbc_plugin_world_read_def(w, &def, &rbc_sizes_cloth_def, user_def, fn,
                                        "rbc_cloth_def")))
        return rc;
    if (!(isfinite(def.shear_stiffness) && def.shear_stiffness >= 0.0f) ||
        !(isfinite(def.bend_stiffness) && def.bend_stiffness >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth def: shear_stiffness %g and bend_stiffness %g N/m must be "
            "finite and >= 0",
            fn, (double)def.shear_stiffness, (double)def.bend_stiffness);
    if (!(isfinite(def.damping) && def.damping >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth def: damping is %g 1/s; it must be finite and >= 0", fn,
            (double)def.damping);
    if (!(isfinite(def.thickness) && def.thickness >= 0.0f) ||
        !(isfinite(def.friction) && def.friction >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth def: thickness %g m and friction %g must be finite and >= 0", fn,
            (double)def.thickness, (double)def.friction);
    if (def.collision_flags & ~(uint32_t)(RBC_CLOTH_COLLIDE_SELF | RBC_CLOTH_COLLIDE_CLOTHS))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth def: collision_flags 0x%x has bits that are not "
                                      "RBC_CLOTH_COLLIDE_* flags",
                                      fn, def.collision_flags);
    if (!(isfinite(def.tear_strain) && def.tear_strain >= 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth def: tear_strain is %g; it must be finite and >= 0 (0 = no "
            "tearing)",
            fn, (double)def.tear_strain);
    if (def.collision_flags && !(def.thickness > 0.0f))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth def: collision_flags 0x%x need a thickness > 0 (it is %g m)", fn,
            def.collision_flags, (double)def.thickness);
    rbc_mesh_input in;
    memset(&in, 0, sizeof in);
    in.vertex_count = def.vertex_count;
    in.positions = def.positions;
    in.quad_count = def.quad_count;
    in.quads = def.quads;
    in.spring_count = def.spring_count;
    in.springs = def.springs;
    in.masses = def.masses;
    in.density = def.density;
    in.vertex_mass = def.vertex_mass;
    in.stiffness = def.stiffness;
    in.shear_stiffness = def.shear_stiffness;
    in.bend_stiffness = def.bend_stiffness;
    in.pin_count = def.pin_count;
    in.pins = def.pins;
    char msg[RBC_ERROR_CAP - 64];
    rbc_cloth_state *c;
    rc = rbc_solver_create_cloth(&w->solver, &in, def.damping, &c, msg, sizeof msg);
    if (rc) return rbc_plugin_world_error(w, rc, "%s: cloth def: %s", fn, msg);
    if ((rc = rbc_solver_set_cloth_contact(&w->solver, c, def.thickness, def.friction,
                                          def.collision_flags))) {
        rbc_cloth_state_destroy(&w->solver.alloc, c);
        return rbc_plugin_world_error(w, rc, "%s: out of memory for cloth contact", fn);
    }
    c->tear_strain = def.tear_strain;
    if (rbc_reg_add(&rbc_plugin_cloths, c, w->id, &c->public_id) != RBC_OK) {
        rbc_cloth_state_destroy(&w->solver.alloc, c);
        return rbc_plugin_world_error(w, RBC_ERR_CAPACITY, "%s: %u cloths exist already", fn,
                                      RBC_MAX_SLOTS);
    }
    if ((rc = rbc_solver_add_cloth(&w->solver, c))) {
        rbc_reg_remove(&rbc_plugin_cloths, c->public_id);
        rbc_cloth_state_destroy(&w->solver.alloc, c);
        return rbc_plugin_world_error(w, rc, "%s: out of memory", fn);
    }
    *out_cloth = c->public_id;
    return RBC_OK;
}

rbc_result rbc_plugin_lookup_cloth(rbc_world_id wid, rbc_cloth_id cid, const char *fn,
                                   rbc_world **ow, rbc_cloth_state **oc) {
    rbc_result rc = rbc_plugin_lookup_world(wid, fn, ow);
    if (rc) return rc;
    *oc = rbc_reg_get(&rbc_plugin_cloths, cid, (*ow)->id, fn);
    if (!*oc) {
        rbc_plugin_world_log(*ow, RBC_LOG_ERROR, rbc_last_error());
        return RBC_ERR_STALE_HANDLE;
    }
    return RBC_OK;
}

/* A vertex argument in range, and the point that goes with it (a pin's target, an
 * attachment's local point; NULL: none) finite: set_pin and attach refuse alike. */
static rbc_result check_vertex(rbc_world *w, const char *fn, rbc_cloth_id cid,
                               const rbc_cloth_state *c, uint32_t vertex, const float *point,
                               const char *what) {
    if (vertex >= c->topo.n)
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth 0x%08x: vertex %u is out of range (vertex count %u)", fn, cid, vertex,
            c->topo.n);
    if (point && !rbc_plugin_finite3(point))
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth 0x%08x: vertex %u: %s (%g, %g, %g) is not finite", fn, cid, vertex, what,
            (double)point[0], (double)point[1], (double)point[2]);
    return RBC_OK;
}

/* A host array of 3 floats per vertex: read_positions and get_state. */
static rbc_result check_capacity(rbc_world *w, const char *fn, rbc_cloth_id cid,
                                 const rbc_cloth_state *c, size_t capacity) {
    size_t need = 3 * (size_t)c->topo.n;
    if (capacity < need)
        return rbc_plugin_world_error(
            w, RBC_ERR_INVALID_ARGUMENT,
            "%s: cloth 0x%08x has %u vertices and needs %zu floats; capacity is %zu", fn, cid,
            c->topo.n, need, capacity);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_destroy(rbc_world_id wid, rbc_cloth_id cid) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, "rbc_cloth_destroy", &w, &c);
    if (rc) return rc;
    rbc_solver_remove_cloth(&w->solver, c);
    rbc_cloth_state_destroy(&w->solver.alloc, c);
    rbc_reg_remove(&rbc_plugin_cloths, cid);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_vertex_count(rbc_world_id wid, rbc_cloth_id cid,
                                                       uint32_t *out_count) {
    static const char fn[] = "rbc_cloth_get_vertex_count";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!out_count)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: out_count is NULL", fn);
    *out_count = c->topo.n;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_topology(rbc_world_id wid, rbc_cloth_id cid,
                                                   uint32_t *out_spring_count,
                                                   uint32_t *out_color_count) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, "rbc_cloth_get_topology", &w, &c);
    if (rc) return rc;
    if (out_spring_count) *out_spring_count = c->topo.ns;
    if (out_color_count) *out_color_count = c->topo.ncolors;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_read_positions(rbc_world_id wid, rbc_cloth_id cid,
                                                     float *xyz, size_t capacity,
                                                     size_t *out_written) {
    static const char fn[] = "rbc_cloth_read_positions";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    size_t need = 3 * (size_t)c->topo.n;
    if (!xyz) {
        if (out_written) *out_written = need;
        return RBC_OK;
    }
    if ((rc = check_capacity(w, fn, cid, c, capacity))) return rc;
    rbc_cloth_state_read(c, xyz);
    if (out_written) *out_written = need;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_set_pin(rbc_world_id wid, rbc_cloth_id cid, uint32_t vertex,
                                              const float *target) {
    static const char fn[] = "rbc_cloth_set_pin";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if ((rc = check_vertex(w, fn, cid, c, vertex, target, "target"))) return rc;
    rc = rbc_cloth_state_set_pin(&w->solver.alloc, c, vertex, target);
    if (rc) return rbc_plugin_world_error(w, rc, "%s: out of memory", fn);
    rbc_detach_vertex(c, vertex); /* a pin of the host's own: no longer attached */
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* ABI 1.1: colors, state                                                    */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_cloth_get_colors(rbc_world_id wid, rbc_cloth_id cid,
                                                 uint32_t *sizes, uint32_t capacity,
                                                 uint32_t *out_color_count) {
    static const char fn[] = "rbc_cloth_get_colors";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!sizes && capacity)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: sizes is NULL but capacity is %u", fn, capacity);
    const rbc_topology *t = &c->topo;
    for (uint32_t k = 0; k < t->ncolors && k < capacity; ++k)
        sizes[k] = t->color_start[k + 1] - t->color_start[k];
    if (out_color_count) *out_color_count = t->ncolors;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_state(rbc_world_id wid, rbc_cloth_id cid,
                                                float *positions, float *previous,
                                                size_t capacity) {
    static const char fn[] = "rbc_cloth_get_state";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if ((positions || previous) && (rc = check_capacity(w, fn, cid, c, capacity))) return rc;
    rbc_cloth_state_get(c, positions, previous);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_set_state(rbc_world_id wid, rbc_cloth_id cid,
                                                const float *positions, const float *previous) {
    static const char fn[] = "rbc_cloth_set_state";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!positions)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: positions is NULL", fn);
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        if (!rbc_plugin_finite3(positions + 3 * (size_t)v))
            return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                          "%s: cloth 0x%08x: vertex %u has a non-finite position",
                                          fn, cid, v);
        if (previous && !rbc_plugin_finite3(previous + 3 * (size_t)v))
            return rbc_plugin_world_error(
                w, RBC_ERR_INVALID_ARGUMENT,
                "%s: cloth 0x%08x: vertex %u has a non-finite previous position", fn, cid, v);
    }
    rbc_cloth_state_set(c, positions, previous);
    return RBC_OK;
}

/* ------------------------------------------------------------------------- */
/* ABI 1.3: attachments, tearing, topology                                   */
/* ------------------------------------------------------------------------- */

RBC_API rbc_result RBC_CALL rbc_cloth_attach(rbc_world_id wid, rbc_cloth_id cid, uint32_t vertex,
                                             rbc_collider_id collider, const float local[3]) {
    static const char fn[] = "rbc_cloth_attach";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if ((rc = check_vertex(w, fn, cid, c, vertex, local, "local point"))) return rc;
    uint32_t k = 0;
    if ((rc = rbc_plugin_lookup_collider(wid, collider, fn, &w, &k))) return rc;
    rc = rbc_attach(&w->solver, c, vertex, collider, local);
    if (rc) return rbc_plugin_world_error(w, rc, "%s: out of memory", fn);
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_cut(rbc_world_id wid, rbc_cloth_id cid,
                                          const uint32_t *pairs, uint32_t pair_count,
                                          uint32_t *out_cut) {
    static const char fn[] = "rbc_cloth_cut";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (out_cut) *out_cut = 0;
    if (pair_count && !pairs)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT, "%s: pairs is NULL", fn);
    for (uint32_t m = 0; m < 2 * pair_count; ++m)
        if (pairs[m] >= c->topo.n)
            return rbc_plugin_world_error(
                w, RBC_ERR_INVALID_ARGUMENT,
                "%s: cloth 0x%08x: pair %u: vertex %u is out of range (vertex "
                "count %u); nothing was cut",
                fn, cid, m / 2, pairs[m], c->topo.n);
    rc = rbc_cut_pairs(&w->solver, c, pairs, pair_count, out_cut);
    if (rc) return rbc_plugin_world_error(w, rc, "%s: out of memory; nothing was cut", fn);
    return RBC_OK;
}

static rbc_result copy_topology(rbc_world_id wid, rbc_cloth_id cid, const char *fn, int quads,
                                uint32_t *dst, size_t capacity, size_t *out_count) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    size_t need = quads ? rbc_cloth_quads_host(c, NULL, 0) : rbc_cloth_springs_host(c, NULL, 0);
    if (dst && capacity < need)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x has %zu values to write; capacity is %zu",
                                      fn, cid, need, capacity);
    if (dst) {
        if (quads)
            rbc_cloth_quads_host(c, dst, capacity);
        else
            rbc_cloth_springs_host(c, dst, capacity);
    }
    if (out_count) *out_count = need;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_quads(rbc_world_id wid, rbc_cloth_id cid, uint32_t *quads,
                                                size_t capacity, size_t *out_count) {
    return copy_topology(wid, cid, "rbc_cloth_get_quads", 1, quads, capacity, out_count);
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_springs(rbc_world_id wid, rbc_cloth_id cid,
                                                  uint32_t *pairs, size_t capacity,
                                                  size_t *out_count) {
    return copy_topology(wid, cid, "rbc_cloth_get_springs", 0, pairs, capacity, out_count);
}
