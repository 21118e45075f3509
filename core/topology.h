/* topology.h -- the immutable part of a cloth: particles, unique springs
 * (structural quad edges, explicit springs, shear and bend springs), the coloring
 * and the color-contiguous particle order (the paper's Fig. 2), and the adjacency
 * the global step streams through.
 *
 * Indices: "host" indices are the caller's vertex order; "internal" indices are the
 * reordered ones, where the particles of color c are [color_start[c],
 * color_start[c+1]). Everything below is in internal indices unless named host.
 */
#ifndef RBC_CORE_TOPOLOGY_H
#define RBC_CORE_TOPOLOGY_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"

#define RBC_MAX_COLORS 64

/* What a cloth is built from (host order). Arrays are read, never kept. */
typedef struct rbc_mesh_input {
    uint32_t vertex_count;
    const float *positions;     /* 3 per vertex, m */
    uint32_t quad_count;
    const uint32_t *quads;      /* 4 per quad */
    uint32_t spring_count;
    const uint32_t *springs;    /* 2 per extra spring */
    const float *masses;        /* per vertex, kg, or NULL */
    float density;              /* kg/m^2, used when masses == NULL and > 0 */
    float vertex_mass;          /* kg, otherwise */
    float stiffness;            /* N/m, structural (quad edges) and explicit springs */
    uint32_t pin_count;
    const uint32_t *pins;       /* host indices */
    /* Shear: one spring along each diagonal of every quad (a-c, b-d). N/m, >= 0;
     * 0 adds none. */
    float shear_stiffness;
    /* Bend (skip-one): a spring a-c for every vertex b and pair of edges (b,a), (b,c)
     * with exactly two quads between them going around b on one side and not a
     * single quad on the other: the 2 opposite pairs of an interior valence-4 vertex,
     * the two boundary edges of a boundary vertex with 2 quads, the 2-apart pairs of
     * valence 5+; none at an interior valence-3 vertex. On a grid: (i,j)-(i+2,j) and
     * (i,j)-(i,j+2). Edges shared by 3+ quads (non-manifold) are left out of the walk:
     * no bend spring starts, ends or passes through them. N/m, >= 0; 0 adds none. */
    float bend_stiffness;
} rbc_mesh_input;

typedef struct rbc_topology {
    uint32_t n;                 /* particles */
    uint32_t ns;                /* springs */
    uint32_t ncolors;           /* 1 .. RBC_MAX_COLORS, every color non-empty */
    uint32_t color_start[RBC_MAX_COLORS + 1];
    uint32_t color_method;      /* rbc_color_method of coloring.h, for stats/tests */
    uint32_t *to_internal;      /* [n] host -> internal */
    uint32_t *to_host;          /* [n] internal -> host */

    float *rest_x, *rest_y, *rest_z; /* [n] rest positions */
    float *mass;                /* [n] kg */
    float *ksum;                /* [n] sum of the stiffness of the springs at i, N/m */
    uint8_t *pinned_at_rest;    /* [n] pinned by the def */

    /* springs */
    uint32_t *sa, *sb;          /* [ns] end points, sa < sb in host order */
    float *rest_len;            /* [ns] L_ij, m */
    float *stiff;               /* [ns] s_ij, N/m: structural/explicit, shear or bend;
                                   the largest where one pair is several kinds */
    float *ux, *uy, *uz;        /* [ns] unit rest direction sa - sb (fallback when the
                                   current length is zero), or 0 for L = 0 */
    uint32_t *he_a, *he_b;      /* [ns] half-edge slots owned by sa and by sb */

    /* CSR adjacency: the neighbors of particle i are slots adj_start[i] ..
     * adj_start[i+1]-1; slot k holds neighbor adj_nbr[k] joined by a spring of
     * stiffness adj_k[k]. The local step writes d_ij of that spring, seen from i,
     * into slot k (see kernels/pd_kernels.h). */
    uint32_t *adj_start;        /* [n+1] */
    uint32_t *adj_nbr;          /* [2 ns] */
    float *adj_k;               /* [2 ns] */

    size_t bytes;               /* memory held, for stats */
} rbc_topology;

/* Validate the input and build the topology. On error returns a negative
 * rbc_result (RBC_ERR_INVALID_ARGUMENT, RBC_ERR_BAD_MESH, RBC_ERR_OUT_OF_MEMORY),
 * writes a message naming the index into err, and leaves *out zeroed.
 * Springs that join the same pair of vertices (a quad edge shared by two quads, an
 * explicit spring on a quad edge, a bend spring found from two middles, a shear
 * spring that is also an explicit one ...) collapse into one spring with the
 * largest of their stiffnesses. The coloring needs no more than RBC_MAX_COLORS
 * colors or the build fails with RBC_ERR_BAD_MESH naming a vertex. Time and memory
 * are O(n + springs) (plus a sort of each vertex's few quads). */
int32_t rbc_topology_build(const rbc_mesh_input *in, const rbc_allocator *a, rbc_topology *out,
                           char *err, size_t errlen);
void rbc_topology_free(rbc_topology *t, const rbc_allocator *a);
/* Tearing (tear.h), the one change a topology takes after it is built: spring sp's
 * stiffness becomes 0 in the spring list and both CSR half-edges, and its ends' sums
 * are recomputed from what remains (no drift from subtracting). 0 if it was broken
 * already. The coloring stays valid (removing edges cannot join a color). */
int rbc_topology_break_spring(rbc_topology *t, uint32_t sp);

#endif
