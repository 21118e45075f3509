/* pick.h -- picking a vertex with a ray (pick.c), for a host's mouse or controller. */
#ifndef RBC_CORE_PICK_H
#define RBC_CORE_PICK_H
#include <stdint.h>

#include "solver.h"

/* The vertex within radius of the ray o + t d, t in [0, tmax], with the least t
 * (ties: nearer the ray, then lower cloth, then lower vertex). Returns 1 if found. */
int rbc_pick(const rbc_solver *s, const float o[3], const float d[3], float tmax, float radius,
             uint32_t *cloth_index, uint32_t *host_vertex, float *t_out);
#endif
