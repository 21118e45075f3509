/* grid.c -- the quad grid generator of the sample scenes (see grid.h). */
#include "grid.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

rbc_grid_status rbc_grid_build(const rbc_grid_def *def, float **out_positions,
                               uint32_t *out_vertex_count, uint32_t **out_quads,
                               uint32_t *out_quad_count) {
    if (!def || !out_positions || !out_vertex_count || !out_quads || !out_quad_count)
        return RBC_GRID_INVALID;
    if (def->nx < 2 || def->ny < 2 || !isfinite(def->spacing) || def->spacing <= 0.0)
        return RBC_GRID_INVALID;
    if (def->plane != RBC_GRID_PLANE_XZ && def->plane != RBC_GRID_PLANE_XY)
        return RBC_GRID_INVALID;
    /* Compare in 64 bits: nx * ny may overflow 32. */
    if ((uint64_t)def->nx * def->ny > RBC_GRID_MAX_VERTICES)
        return RBC_GRID_INVALID;
    /* Every coordinate must be a finite float. */
    const double extent = (double)(def->nx > def->ny ? def->nx : def->ny) * def->spacing;
    for (int k = 0; k < 3; ++k)
        if (!isfinite(def->origin[k]) || fabs(def->origin[k]) + extent > FLT_MAX)
            return RBC_GRID_INVALID;

    const uint32_t nx = def->nx, ny = def->ny;
    const uint32_t vertex_count = nx * ny;
    const uint32_t quad_count = (nx - 1) * (ny - 1);
    float *positions = malloc((size_t)vertex_count * 3 * sizeof *positions);
    uint32_t *quads = malloc((size_t)quad_count * 4 * sizeof *quads);
    if (!positions || !quads) {
        free(positions);
        free(quads);
        return RBC_GRID_OUT_OF_MEMORY;
    }

    /* The second grid axis is z for "xz" and y for "xy". Coordinates are computed
     * in double as origin + index * spacing (not by accumulation), so vertex (i, j)
     * is the float nearest to its exact position. */
    const int second_axis = def->plane == RBC_GRID_PLANE_XZ ? 2 : 1;
    for (uint32_t j = 0; j < ny; ++j) {
        for (uint32_t i = 0; i < nx; ++i) {
            double p[3] = {def->origin[0], def->origin[1], def->origin[2]};
            p[0] += (double)i * def->spacing;
            p[second_axis] += (double)j * def->spacing;
            float *dst = positions + 3 * ((size_t)i + (size_t)nx * j);
            dst[0] = (float)p[0];
            dst[1] = (float)p[1];
            dst[2] = (float)p[2];
        }
    }

    for (uint32_t j = 0; j + 1 < ny; ++j) {
        for (uint32_t i = 0; i + 1 < nx; ++i) {
            uint32_t *q = quads + 4 * ((size_t)i + (size_t)(nx - 1) * j);
            q[0] = i + nx * j;
            q[1] = (i + 1) + nx * j;
            q[2] = (i + 1) + nx * (j + 1);
            q[3] = i + nx * (j + 1);
        }
    }

    *out_positions = positions;
    *out_vertex_count = vertex_count;
    *out_quads = quads;
    *out_quad_count = quad_count;
    return RBC_GRID_OK;
}
