/* grid.h -- the quad grid generator of the sample scenes.
 *
 * A grid of nx x ny vertices, `spacing` metres apart, starting at `origin` and
 * lying in the plane "xz" (vertex (i, j) at origin + (i, 0, j) * spacing) or "xy"
 * (origin + (i, j, 0) * spacing). Vertices are row-major: vertex (i, j) has index
 * i + nx * j. Quad (i, j) joins (i, j), (i+1, j), (i+1, j+1), (i, j+1) and has
 * index i + (nx - 1) * j.
 */
#ifndef RBC_SAMPLES_GRID_H
#define RBC_SAMPLES_GRID_H

#include <stdint.h>

/// Largest vertex count a grid may have (2^24: 192 MiB of positions).
#define RBC_GRID_MAX_VERTICES (1u << 24)

typedef enum rbc_grid_plane {
    RBC_GRID_PLANE_XZ = 0,
    RBC_GRID_PLANE_XY = 1
} rbc_grid_plane;

typedef struct rbc_grid_def {
    /// Vertices along the first and second axis, each at least 2.
    uint32_t nx, ny;
    /// Distance between neighbouring vertices, metres (> 0).
    double spacing;
    /// Position of vertex 0, metres.
    double origin[3];
    rbc_grid_plane plane;
} rbc_grid_def;

typedef enum rbc_grid_status {
    RBC_GRID_OK = 0,
    /// nx or ny < 2, too many vertices, spacing not finite and positive, a
    /// coordinate that is not a finite float, or
    /// an unknown plane.
    RBC_GRID_INVALID = -1,
    RBC_GRID_OUT_OF_MEMORY = -2
} rbc_grid_status;

/// Build the grid: *out_positions (3 floats per vertex) and *out_quads (4 indices
/// per quad) are malloc'd and owned by the caller (free()). On failure nothing is
/// allocated and the outputs are left as they were.
rbc_grid_status rbc_grid_build(const rbc_grid_def *def, float **out_positions,
                               uint32_t *out_vertex_count, uint32_t **out_quads,
                               uint32_t *out_quad_count);

#endif
