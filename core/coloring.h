/* coloring.h -- distance-1 coloring of the particle graph (Sec. 4.2).
 *
 * A quad mesh of disk or sphere topology is bipartite: two colors (red-black) make
 * every spring join a red and a black particle, so each color's particles can be
 * updated in parallel by Gauss-Seidel. Odd cycles (triangles, shear and bend
 * springs, odd loops around a torus) need more colors; the solver runs one
 * parallel sweep per color, so both few colors and balanced class sizes matter.
 *
 * rbc_color_graph is the policy: red-black BFS when the graph is bipartite (2 is
 * optimal); otherwise the better of a lattice coloring (a linear form of integer
 * quad-lattice coordinates, optimal on grids: 3 with bend, 4 with shear, 5 with
 * both) and a DSATUR greedy coloring (ties go to the lattice); unless that is a
 * seamless lattice coloring (or 3 colors: optimal once the graph is not
 * bipartite), a few rounds of iterated greedy try to drop a color and class
 * balancing evens the sizes. Everything is O(n + springs) per pass, with a
 * bounded number of passes.
 *
 * All graphs are CSR: the neighbors of v are adj[adj_start[v] .. adj_start[v+1]-1]. */
#ifndef RBC_CORE_COLORING_H
#define RBC_CORE_COLORING_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"

/* Returned by the functions below besides a color count. */
#define RBC_COLOR_TOO_MANY (-1) /* a vertex needs more than max_colors colors */
#define RBC_COLOR_NO_MEMORY (-2)

/* What rbc_color_graph colors: the spring graph and, optionally, the quads it was
 * built from with their edge neighbors (for the lattice coloring). */
typedef struct rbc_color_input {
    uint32_t n;
    const uint32_t *adj_start;  /* [n+1] */
    const uint32_t *adj;        /* [adj_start[n]] */
    uint32_t quad_count;
    const uint32_t *quads;      /* [4 quad_count], or NULL */
    /* [4 quad_count]: quad_nbr[4f+k] is the quad across edge k (corners k, k+1) of
     * quad f when exactly two quads share that edge, else UINT32_MAX; or NULL. */
    const uint32_t *quad_nbr;
} rbc_color_input;

/* How a coloring was found, for stats and tests. */
typedef enum rbc_color_method {
    RBC_COLOR_METHOD_BIPARTITE = 0, /* red-black BFS */
    RBC_COLOR_METHOD_LATTICE = 1,   /* (a i + b j) mod k on quad-lattice coordinates */
    RBC_COLOR_METHOD_DSATUR = 2     /* greedy by saturation, then balanced */
} rbc_color_method;

/* Color the graph with at most max_colors (<= 64) colors. color[n] receives the
 * colors; every color 0 .. *ncolors-1 is used (isolated vertices get 0; a graph
 * without edges has 1 color). Returns 0, RBC_COLOR_TOO_MANY (then *bad_vertex names
 * a vertex whose neighbors already use all max_colors colors), or
 * RBC_COLOR_NO_MEMORY. *method (may be NULL) says which coloring was kept. */
int rbc_color_graph(const rbc_color_input *g, uint32_t max_colors, const rbc_allocator *a,
                    uint8_t *color, uint32_t *ncolors, uint32_t *bad_vertex,
                    rbc_color_method *method);

/* Two-color the graph by BFS. color[n] receives 0 or 1 (isolated vertices get 0).
 * Returns 0, or -1 if the graph has an odd cycle; then *bad_a, *bad_b name an edge
 * whose ends got the same color. queue is scratch of n entries. */
int rbc_color_bipartite(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                        uint8_t *color, uint32_t *queue, uint32_t *bad_a, uint32_t *bad_b);

/* Greedy DSATUR-style coloring: repeatedly color, with its smallest free color, an
 * uncolored vertex whose neighbors already use the most distinct colors (ties: the
 * most recently saturated, which keeps the front local). O(n + edges) with a
 * bucket queue. Returns the number of colors used, RBC_COLOR_TOO_MANY (*bad_vertex
 * set) or RBC_COLOR_NO_MEMORY. */
int rbc_color_dsatur(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                     uint32_t max_colors, const rbc_allocator *a, uint8_t *color,
                     uint32_t *bad_vertex);

/* Lattice coloring: integer coordinates (i, j) are propagated quad by quad across
 * manifold edges (each quad a unit square of the lattice; a vertex keeps the first
 * coordinates it gets, so irregular vertices and seams only add distinct spring
 * offsets), the offsets (di, dj) of all springs are collected, and the smallest
 * k <= max_k (<= 8) with a form (a i + b j) mod k that is non-zero on every offset
 * colors the graph; valid by construction. Returns k, 0 when there is none (too many
 * distinct offsets, a spring at a vertex in no quad, or none fits), or
 * RBC_COLOR_NO_MEMORY. *seamless (may be NULL) is 1 when k was found and every
 * offset is within 2 lattice steps (a grid-like patch: no seam, no irregular
 * vertex). */
int rbc_color_lattice(const rbc_color_input *g, uint32_t max_k, const rbc_allocator *a,
                      uint8_t *color, int *seamless);

/* Iterated greedy (Culberson): first-fit over the vertices taken class by class,
 * the classes in a random order (a fixed seed: deterministic), never needs more
 * colors than the coloring it starts from, and sometimes fewer. At most `iterations`
 * rounds of O(n + edges), stopping at lower_bound colors or after 4 rounds without
 * gain. Rewrites color; returns the number of colors or RBC_COLOR_NO_MEMORY. */
int rbc_color_iterated_greedy(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                              uint8_t *color, uint32_t ncolors, uint32_t iterations,
                              uint32_t lower_bound, const rbc_allocator *a);

/* Move vertices to a smaller admissible color while that shrinks the gap between
 * their class and it, at most max_passes passes over the vertices. Keeps the
 * coloring valid and uses no color >= ncolors. */
void rbc_color_balance(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                       uint8_t *color, uint32_t ncolors, uint32_t max_passes);

/* 1 if no edge of the CSR graph joins two particles of one color. */
int rbc_coloring_is_valid(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                          const uint8_t *color);
#endif
