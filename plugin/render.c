/* render.c -- what a renderer reads each frame (ABI 1.10): positions and normals into
 * the host's own vertex buffers (rbc_world_read_vertices), the triangle index buffer
 * and its revision (rbc_cloth_get_triangles), and the rigid move of a whole cloth
 * (rbc_cloth_transform). Every entry of a read is checked before any buffer is
 * written, so a refused call leaves every buffer as it was. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "errors.h"
#include "rbcloth.h"
#include "render.h"
#include "world.h"

/* The largest stride accepted: a vertex of a real engine is well below it, and the
 * bound keeps (n - 1) * stride far from size_t's range on 32-bit hosts. */
#define MAX_STRIDE 65536u

static rbc_vertex_output output_defaults(void) {
    rbc_vertex_output d;
    memset(&d, 0, sizeof d);
    d.struct_size = sizeof d;
    d.stride = 12;
    d.position_offset = 0;
    d.normal_offset = RBC_NO_ATTRIBUTE;
    return d;
}

RBC_API rbc_result RBC_CALL rbc_vertex_output_init(rbc_vertex_output *output,
                                                   uint32_t struct_size) {
    static const char fn[] = "rbc_vertex_output_init";
    if (!output) return rbc_set_error(RBC_ERR_INVALID_ARGUMENT, "%s: output is NULL", fn);
    if (struct_size != sizeof *output)
        return rbc_set_error(RBC_ERR_INVALID_ARGUMENT,
                             "%s: struct_size is %u; this library's rbc_vertex_output has %u "
                             "bytes (the only released size)",
                             fn, struct_size, (unsigned)sizeof *output);
    *output = output_defaults();
    return RBC_OK;
}

/* One attribute of an entry: absent, or 12 bytes inside the stride. */
static rbc_result check_attribute(rbc_world *w, const char *fn, uint32_t k, const char *name,
                                  uint32_t offset, uint32_t stride) {
    if (offset == RBC_NO_ATTRIBUTE || ((uint64_t)offset + 12u <= stride)) return RBC_OK;
    return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                  "%s: outputs[%u]: %s is %u; 3 floats there end at byte %llu, "
                                  "past the stride of %u",
                                  fn, k, name, offset, (unsigned long long)offset + 12u, stride);
}

static rbc_result check_output(rbc_world *w, const char *fn, uint32_t k,
                               const rbc_vertex_output *o, rbc_cloth_state **out) {
    if (o->struct_size != sizeof *o)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs[%u]: struct_size is %u; rbc_vertex_output "
                                      "has %u bytes (fill it with rbc_vertex_output_init)",
                                      fn, k, o->struct_size, (unsigned)sizeof *o);
    rbc_cloth_state *c = rbc_reg_get(&rbc_plugin_cloths, o->cloth, w->id, fn);
    if (!c) {
        char why[RBC_ERROR_CAP];
        snprintf(why, sizeof why, "%s", rbc_last_error());
        return rbc_plugin_world_error(w, RBC_ERR_STALE_HANDLE, "%s: outputs[%u]: %s", fn, k, why);
    }
    if (!o->buffer)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs[%u]: cloth 0x%08x: buffer is NULL", fn, k,
                                      o->cloth);
    if (o->stride < 12 || o->stride > MAX_STRIDE)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs[%u]: cloth 0x%08x: stride is %u bytes; range "
                                      "12..%u",
                                      fn, k, o->cloth, o->stride, MAX_STRIDE);
    rbc_result rc;
    if ((rc = check_attribute(w, fn, k, "position_offset", o->position_offset, o->stride)) ||
        (rc = check_attribute(w, fn, k, "normal_offset", o->normal_offset, o->stride)))
        return rc;
    const uint32_t po = o->position_offset, no = o->normal_offset;
    if (po != RBC_NO_ATTRIBUTE && no != RBC_NO_ATTRIBUTE && (po < no ? no - po : po - no) < 12)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs[%u]: cloth 0x%08x: position_offset %u and "
                                      "normal_offset %u overlap (each attribute is 12 bytes)",
                                      fn, k, o->cloth, po, no);
    uint64_t end = 0;
    if (po != RBC_NO_ATTRIBUTE) end = po + 12u;
    if (no != RBC_NO_ATTRIBUTE && no + 12u > end) end = no + 12u;
    const uint64_t need = end ? (uint64_t)(c->topo.n - 1) * o->stride + end : 0;
    if (need > o->buffer_size)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs[%u]: cloth 0x%08x: %u vertices at a stride of "
                                      "%u need %llu bytes; buffer_size is %zu",
                                      fn, k, o->cloth, c->topo.n, o->stride,
                                      (unsigned long long)need, o->buffer_size);
    if (no != RBC_NO_ATTRIBUTE && rbc_cloth_normals_reserve(&w->solver.alloc, c) != 0)
        return rbc_plugin_world_error(w, RBC_ERR_OUT_OF_MEMORY,
                                      "%s: outputs[%u]: cloth 0x%08x: out of memory for the "
                                      "normals of %u vertices; nothing was written",
                                      fn, k, o->cloth, c->topo.n);
    *out = c;
    return RBC_OK;
}

/* Internal SoA (positions, or the normals' scratch) to the host's strided bytes. */
static void write_attribute(const rbc_cloth_state *c, unsigned char *buf, uint32_t stride,
                            uint32_t offset, const float *x, const float *y, const float *z) {
    const uint32_t *to_int = c->topo.to_internal;
    for (uint32_t v = 0; v < c->topo.n; ++v) {
        const uint32_t i = to_int[v];
        const float p[3] = {x[i], y[i], z[i]};
        /* memcpy: the host's buffer need not be float-aligned at this offset. */
        memcpy(buf + (size_t)v * stride + offset, p, sizeof p);
    }
}

RBC_API rbc_result RBC_CALL rbc_world_read_vertices(rbc_world_id wid, rbc_vertex_output *outputs,
                                                    uint32_t count) {
    static const char fn[] = "rbc_world_read_vertices";
    rbc_world *w;
    rbc_result rc = rbc_plugin_lookup_world(wid, fn, &w);
    if (rc) return rc;
    if (count && !outputs)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: outputs is NULL and count is %u", fn, count);
    for (uint32_t k = 0; k < count; ++k) {
        rbc_cloth_state *c;
        if ((rc = check_output(w, fn, k, &outputs[k], &c))) return rc;
    }
    for (uint32_t k = 0; k < count; ++k) {
        rbc_vertex_output *o = &outputs[k];
        rbc_cloth_state *c = rbc_reg_get(&rbc_plugin_cloths, o->cloth, w->id, fn);
        unsigned char *buf = o->buffer;
        if (o->position_offset != RBC_NO_ATTRIBUTE)
            write_attribute(c, buf, o->stride, o->position_offset, c->x[0], c->x[1], c->x[2]);
        if (o->normal_offset != RBC_NO_ATTRIBUTE) {
            const float *n = rbc_cloth_normals(c);
            const size_t nv = c->topo.n;
            write_attribute(c, buf, o->stride, o->normal_offset, n, n + nv, n + 2 * nv);
        }
        o->triangle_revision = c->tri_revision;
    }
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_get_triangles(rbc_world_id wid, rbc_cloth_id cid,
                                                    uint32_t *triangles, size_t capacity,
                                                    size_t *out_count, uint32_t *out_revision) {
    static const char fn[] = "rbc_cloth_get_triangles";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    const size_t need = rbc_cloth_triangles_host(c, NULL, 0);
    if (triangles && capacity < need)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x has %zu values to write; capacity is %zu",
                                      fn, cid, need, capacity);
    if (triangles) rbc_cloth_triangles_host(c, triangles, capacity);
    if (out_count) *out_count = need;
    if (out_revision) *out_revision = c->tri_revision;
    return RBC_OK;
}

RBC_API rbc_result RBC_CALL rbc_cloth_transform(rbc_world_id wid, rbc_cloth_id cid,
                                                const float translation[3],
                                                const float rotation[4], uint32_t flags) {
    static const char fn[] = "rbc_cloth_transform";
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (!translation || !rotation)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x: translation or rotation is NULL", fn, cid);
    if (!rbc_plugin_finite3(translation))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x: translation (%g, %g, %g) is not finite",
                                      fn, cid, (double)translation[0], (double)translation[1],
                                      (double)translation[2]);
    const double n2 = (double)rotation[0] * rotation[0] + (double)rotation[1] * rotation[1] +
                      (double)rotation[2] * rotation[2] + (double)rotation[3] * rotation[3];
    /* The tolerance of rbc_collider_set_transform: float rounding of a host's
     * normalised, composed quaternion. */
    if (!(isfinite(n2) && fabs(n2 - 1.0) <= 1e-4))
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x: rotation (%g, %g, %g, %g) is not a unit "
                                      "quaternion x y z w (norm^2 %g)",
                                      fn, cid, (double)rotation[0], (double)rotation[1],
                                      (double)rotation[2], (double)rotation[3], n2);
    if (flags > RBC_TRANSFORM_RESET_VELOCITY)
        return rbc_plugin_world_error(w, RBC_ERR_INVALID_ARGUMENT,
                                      "%s: cloth 0x%08x: flags is %u; RBC_TRANSFORM_KEEP_VELOCITY "
                                      "(0) or RBC_TRANSFORM_RESET_VELOCITY (1)",
                                      fn, cid, flags);
    rbc_cloth_move(c, translation, rotation, flags == RBC_TRANSFORM_RESET_VELOCITY);
    return RBC_OK;
}

rbc_result rbc_plugin_cloth_lone_triangles(rbc_world_id wid, rbc_cloth_id cid, const char *fn,
                                           const uint32_t *tris, uint32_t count) {
    rbc_world *w;
    rbc_cloth_state *c;
    rbc_result rc = rbc_plugin_lookup_cloth(wid, cid, fn, &w, &c);
    if (rc) return rc;
    if (rbc_cloth_set_lone_triangles(&w->solver.alloc, c, tris, count) != 0)
        return rbc_plugin_world_error(w, RBC_ERR_OUT_OF_MEMORY,
                                      "%s: cloth 0x%08x: out of memory for %u triangles", fn, cid,
                                      count);
    return RBC_OK;
}
