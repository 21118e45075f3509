/* coloring.h -- distance-1 coloring of the particle graph (Sec. 4.2).
 *
 * A quad mesh of disk or sphere topology is bipartite: two colors (red-black) make
 * every spring join a red and a black particle, so each color's particles can be
 * updated in parallel by Gauss-Seidel. Odd cycles (triangles, diagonal springs,
 * odd loops around a torus) need more colors; this release refuses them. */
#ifndef RBC_CORE_COLORING_H
#define RBC_CORE_COLORING_H
#include <stddef.h>
#include <stdint.h>

/* Two-color the graph given as CSR (adj_start[n+1], adj[...], host indices) by BFS.
 * color[n] receives 0 or 1 (isolated vertices get 0). Returns 0, or -1 if the graph
 * has an odd cycle; then *bad_a, *bad_b name an edge whose ends got the same color.
 * queue is scratch of n entries. */
int rbc_color_bipartite(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                        uint8_t *color, uint32_t *queue, uint32_t *bad_a, uint32_t *bad_b);

/* 1 if no edge of the CSR graph joins two particles of one color. */
int rbc_coloring_is_valid(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                          const uint8_t *color);
#endif
