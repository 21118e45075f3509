/* render.h -- what a renderer reads of a cloth (ABI 1.10): area-weighted vertex
 * normals, a triangle index buffer in host order, and the rigid move of a whole
 * cloth. Nothing here runs inside a step: the host asks, between steps. */
#ifndef RBC_CORE_RENDER_H
#define RBC_CORE_RENDER_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"
#include "cloth_state.h"

/* Keep an imported mesh's leftover triangles (host indices, 3 each, already checked
 * against the vertex count). Returns 0, or -1 out of memory (nothing changed). */
int rbc_cloth_set_lone_triangles(const rbc_allocator *al, rbc_cloth_state *c,
                                 const uint32_t *tris, uint32_t count);
/* The scratch normals need (3 floats a vertex), allocated on first use: 0, or -1 out
 * of memory. Separate from rbc_cloth_normals so a caller can fail before it writes. */
int rbc_cloth_normals_reserve(const rbc_allocator *al, rbc_cloth_state *c);
/* Unit normals in internal order into the reserved scratch, which it returns as SoA:
 * n x values, then n y, then n z. Each vertex sums (c - a) x (d - b) over its quads
 * and (b - a) x (c - a) over its leftover triangles (twice their vector areas) and
 * normalises; 0 where the sum is 0. */
const float *rbc_cloth_normals(rbc_cloth_state *c);
/* Triangles in host order, 3 indices each: (a b c) (a c d) per remaining quad, then
 * the remaining leftover triangles. Writes at most cap values (out may be NULL) and
 * returns the count of values. */
size_t rbc_cloth_triangles_host(const rbc_cloth_state *c, uint32_t *out, size_t cap);
/* p -> R p + t for positions, previous positions (or previous = positions with
 * reset_velocity) and pin targets; R from the unit quaternion x y z w. */
void rbc_cloth_move(rbc_cloth_state *c, const float t[3], const float quat[4],
                    int reset_velocity);
/* cloth.c frees the leftover triangles and the normals' scratch with the rest of
 * the state, and counts them in its bytes. */
#endif
