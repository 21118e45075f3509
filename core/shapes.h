/* shapes.h -- the geometry of the built-in collider shapes, in the collider's local
 * frame (metres): signed distance with the outward normal, the first entry of a
 * segment, local bounds, and the triangle mesh with its bounding volume hierarchy.
 * The solver's contact generation (contact_step.c) moves points into the local frame and
 * calls these; nothing here allocates or locks after rbc_trimesh_create, so queries
 * may run from any number of threads at once.
 *
 * Shapes (abi/rbcloth.h): RBC_SHAPE_PLANE y = 0, solid below, normal +y;
 * RBC_SHAPE_SPHERE |q| <= radius; RBC_SHAPE_CAPSULE the points within radius of the
 * segment (0,-h,0)-(0,h,0), h = half_extents[1]; RBC_SHAPE_BOX |q_i| <= half_extents[i];
 * RBC_SHAPE_TRIANGLE_MESH a copied triangle mesh. Negative half extents are read as 0
 * (a flat box, a capsule that is a sphere); the radius is used as given (phi =
 * distance to the centre or segment - radius).
 *
 * Triangle meshes. A mesh is closed when every edge is shared by exactly two
 * triangles that run through it in opposite directions (degenerate triangles left
 * out). A closed mesh bounds a solid: the signed distance takes its sign from the
 * angle-weighted pseudo-normal of the closest feature (face, edge or vertex;
 * Baerentzen & Aanaes 2005, "Signed distance computation using the angle weighted
 * pseudonormal", Theorem 1), and a closed mesh whose triangles wind clockwise seen
 * from outside (negative enclosed volume) is turned around at creation, so that
 * "inside" is always the bounded side. An open mesh is a two-sided shell: the
 * distance is unsigned, n points from the closest surface point to q, and the solver
 * keeps track of sides itself.
 *
 * Precision: everything is evaluated in double from the float input and rounded
 * once (phi within about a float ulp of the exact value): analytic shapes in closed
 * form; meshes by the closest point per triangle after Ericson, Real-Time Collision
 * Detection 5.1.5 (double, because its face case loses 1 / sin^2 of the smallest
 * angle to cancellation), segment-triangle by Moller & Trumbore 1997. The BVH's
 * boxes and their distances are float. BVH queries return bitwise the result of
 * the brute-force loop over all triangles (rbc_trimesh_*_brute): node boxes are
 * inflated and compared with a margin that covers the rounding of both
 * (shapes.c, BVH_INFLATE and BVH_MARGIN), and ties go to the lower triangle.
 */
#ifndef RBC_CORE_SHAPES_H
#define RBC_CORE_SHAPES_H
#include <stddef.h>
#include <stdint.h>

#include "../abi/rbcloth.h"
#include "alloc.h"

/* Opaque: vertices, triangles, a BVH, per-vertex/edge/face pseudo-normals. */
struct rbc_trimesh;

typedef struct rbc_shape_geom {
    rbc_shape kind;
    float radius;                   /* sphere, capsule, m */
    float half_extents[3];          /* box; capsule uses half_extents[1] as the segment
                                       half-length, m */
    const struct rbc_trimesh *mesh; /* RBC_SHAPE_TRIANGLE_MESH */
} rbc_shape_geom;

/* Signed distance from local point q to the surface (negative inside the solid) and
 * the outward unit normal n at the closest surface point, the gradient of phi (for a
 * point inside a box: the face of least penetration, the lower axis on ties; exactly
 * at a sphere's centre: +y; exactly on a capsule's axis: +x). Returns 1 and sets
 * *phi, n when phi <= max_dist. Returns 0 otherwise: analytic shapes still set *phi
 * and n; a triangle mesh may return 0 without computing the distance when the point
 * is certainly farther than max_dist (BVH / bounds culling) and leaves them alone:
 * an open mesh searches only within max_dist; a closed mesh culls by its bounds and
 * by a coarse grid of distance bounds, and otherwise needs the closest feature (for
 * the sign), which deep inside a round mesh can mean visiting most triangles (all at
 * a sphere's centre). An unknown kind or a mesh shape without a mesh returns 0. Never
 * NaN for finite input. */
int rbc_shape_distance(const rbc_shape_geom *g, const float q[3], float max_dist, float *phi,
                       float n[3]);

/* First parameter t in [0,1] at which the segment a -> b crosses the surface going
 * from outside (phi >= 0) to inside (phi < 0), with the outward normal there; 1 and
 * *t, n set on a hit. 0 = no entry: a segment that misses, only touches (tangent,
 * grazing a face), stops short, or starts inside. For a closed mesh: the first
 * triangle crossed, if it is crossed from its outer side (crossed from the inner side
 * first means a starts inside: 0). For an open triangle mesh: the first triangle the
 * segment crosses, either direction, with n the triangle normal facing a (the side it
 * came from). Triangle edges are hit with a tolerance of 2^-23 of the barycentric
 * coordinates, so a segment through an edge or a vertex is not lost between the
 * triangles that share it. */
int rbc_shape_raycast(const rbc_shape_geom *g, const float a[3], const float b[3], float *t,
                      float n[3]);

/* Local axis-aligned bounds of the solid; the plane's are infinite (-/+INFINITY except
 * hi[1] = 0). A mesh's: the vertices of its non-degenerate triangles. */
void rbc_shape_bounds(const rbc_shape_geom *g, float lo[3], float hi[3]);

/* Copy a triangle mesh (positions 3 floats per vertex, tris 3 uint32 per triangle) and
 * build its BVH (binned SAH over triangle centroids, leaves of at most 4 triangles);
 * a closed mesh also gets its pseudo-normals and a grid of at most 34^3 distance
 * bounds (one BVH search per cell: ~0.1 s for 20K triangles, ~2 s for 1M).
 * Errors (return a negative rbc_result, message into err naming the index, nothing
 * created, *out = NULL): RBC_ERR_INVALID_ARGUMENT for nv == 0, nt == 0, NULL arrays, an
 * index >= nv (naming the triangle and the corner), a non-finite position (naming the
 * vertex), more than UINT32_MAX / 3 triangles, or no triangle of non-zero area.
 * Degenerate triangles (zero area: the cross product of two edges, in double, is
 * exactly 0, as with a repeated index) are skipped and counted (rbc_trimesh_info).
 * RBC_ERR_OUT_OF_MEMORY on allocation failure, nothing leaked. Deterministic: the same
 * input gives the same structure and the same query results. */
int32_t rbc_trimesh_create(const float *positions, uint32_t nv, const uint32_t *tris,
                           uint32_t nt, const rbc_allocator *a, struct rbc_trimesh **out,
                           char *err, size_t errlen);
void rbc_trimesh_destroy(struct rbc_trimesh *m, const rbc_allocator *a);

typedef struct rbc_trimesh_info {
    uint32_t vertices;   /* as given */
    uint32_t triangles;  /* in the BVH: the given ones less the degenerate ones */
    uint32_t degenerate; /* skipped: zero area */
    uint32_t closed;     /* 1 closed (signed distance), 0 open (unsigned) */
    size_t bytes;        /* held by the mesh, through its allocator */
    float lo[3], hi[3];  /* bounds of the non-degenerate triangles */
} rbc_trimesh_info;
void rbc_trimesh_info_get(const struct rbc_trimesh *m, rbc_trimesh_info *out);

/* The same queries by a loop over every triangle, no BVH: the reference the tests hold
 * the BVH to (bitwise the same results). */
int rbc_trimesh_distance_brute(const struct rbc_trimesh *m, const float q[3], float max_dist,
                               float *phi, float n[3]);
int rbc_trimesh_raycast_brute(const struct rbc_trimesh *m, const float a[3], const float b[3],
                              float *t, float n[3]);
#endif
