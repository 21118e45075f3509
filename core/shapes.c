/* shapes.c -- collider shape geometry; see shapes.h. */
#include "shapes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kernels/collide_kernels.h"
#include "report.h"

enum {
    LEAF_MAX = 4,       /* triangles per BVH leaf */
    SAH_BINS = 16,      /* binned SAH (Wald 2007), per axis */
    SAH_MAX_DEPTH = 48, /* deeper nodes split at the median: depth <= 48 + 30 */
    STACK_MAX = 96      /* nearest-first traversal holds at most depth + 1 entries */
};
#define NONE UINT32_MAX

/* Rounding and the BVH. A triangle's closest point is computed in double: it lies
 * within ~1e-16 / sin^2(smallest angle) of the coordinates' magnitude M of the
 * triangle, and a Moller-Trumbore hit within EDGE_EPS (|e1| + |e2|) <= 2^-21 M of it.
 * Node boxes grow by BVH_INFLATE M_node, so they hold every point a query can compute
 * for their triangles; the squared distance to a box, computed in float with a
 * relative error of a few float ulps, is compared with the best squared distance
 * times BVH_MARGIN (2^12 float ulps). So no box holding the brute-force winner is
 * ever pruned, and the BVH's answer is bitwise the loop's (ties to the lower triangle
 * in both). */
#define BVH_INFLATE 0x1p-18f
#define BVH_MARGIN (1.0 + 0x1p-12)
#define EDGE_EPS 0x1p-23
/* max_dist^2 grows by this before it bounds the search: (float)sqrt(d2) <= max_dist
 * holds for sqrt(d2) up to half a float ulp above max_dist. */
#define BOUND_GROW (1.0 + 0x1p-20)

typedef struct bvh_node {
    float lo[3];
    uint32_t first; /* leaf: first triangle; inner: left child (right = first + 1) */
    float hi[3];
    uint32_t count; /* leaf: 1 .. LEAF_MAX triangles; inner: 0 */
} bvh_node;

/* Closest feature of a triangle (Ericson's Voronoi regions). */
enum { F_FACE, F_VA, F_VB, F_VC, F_EAB, F_EBC, F_ECA };

struct rbc_trimesh {
    uint32_t nv;      /* vertices as given */
    uint32_t nt;      /* non-degenerate triangles, in BVH order below */
    uint32_t ndeg;    /* degenerate triangles skipped */
    uint32_t ne;      /* unique edges (closed meshes; 0 otherwise) */
    uint32_t closed;
    uint32_t ncap;    /* nodes allocated: 2 nt (root 0, 1 unused, pairs from 2) */
    float *pos;       /* [3 nv] */
    uint32_t *tri;    /* [3 nt] vertex indices (turned round if the closed mesh was
                         inside out) */
    float *tv;        /* [9 nt] corners a, b, c: what the hot loops read */
    float *fn;        /* [3 nt] unit face normals */
    uint32_t *tedge;  /* [3 nt] edge ids of (a,b), (b,c), (c,a); closed only */
    float *en;        /* [3 ne] edge pseudo-normals; closed only */
    float *vn;        /* [3 nv] vertex pseudo-normals; closed only */
    bvh_node *nodes;  /* [ncap] 64-byte aligned: siblings share a cache line */
    /* Closed meshes: a grid of gn[0] x gn[1] x gn[2] cells of side gh from glo (the
     * bounds padded by a cell), x fastest. At each cell centre c: glb, a lower bound
     * of phi(c) (-INFINITY inside, far from the surface); gub, an upper bound of
     * |phi(c)| (INFINITY where unknown). See build_grid. */
    float glo[3], gh, gmag;
    uint32_t gn[3];
    size_t gcells;
    float *glb, *gub;
    size_t bytes;
    float lo[3], hi[3];
};

static inline float maxf(float a, float b) { return a > b ? a : b; }
static inline float minf(float a, float b) { return a < b ? a : b; }

/* ---- analytic shapes ----
 * In kernels/collide_kernels.h (double inside, rounded once), shared with the
 * backends' collider kernels so that both round alike. */
_Static_assert((int)RBC_KC_PLANE == (int)RBC_SHAPE_PLANE &&
                   (int)RBC_KC_SPHERE == (int)RBC_SHAPE_SPHERE &&
                   (int)RBC_KC_CAPSULE == (int)RBC_SHAPE_CAPSULE &&
                   (int)RBC_KC_BOX == (int)RBC_SHAPE_BOX,
               "collide_kernels.h's shapes are the ABI's");

/* ---- triangles ---- */

/* Ericson, Real-Time Collision Detection 5.1.5: the closest point of triangle
 * t = (a, b, c) to q by Voronoi regions, in double: the barycentrics of the face case
 * are ratios of differences of products (vb = d5 d2 - d1 d6 ...) whose relative error
 * grows as 1 / sin^2 of the triangle's smallest angle, which float cannot afford for
 * the slivers of CAD meshes. Returns |q - p|^2, writes diff = q - p and the feature p
 * lies on. Divisions are guarded so that a near-degenerate triangle gives a point of
 * it, never NaN. Not inlined: the BVH, the brute-force loop and the winner's
 * recomputation run the very same instructions, so their distances are bitwise equal
 * whatever the compiler might contract in one inlined copy. */
#if defined(__GNUC__) || defined(__clang__)
#define RBC_NOINLINE __attribute__((noinline))
#elif defined(_MSC_VER)
#define RBC_NOINLINE __declspec(noinline)
#else
#define RBC_NOINLINE
#endif
RBC_NOINLINE static double tri_closest(const float *restrict t, const double q[3],
                                       double diff[3], int *feat) {
    const double a[3] = {t[0], t[1], t[2]}, b[3] = {t[3], t[4], t[5]}, c[3] = {t[6], t[7], t[8]};
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double ap[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
    double p[3];
    double d1 = ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2];
    double d2 = ac[0] * ap[0] + ac[1] * ap[1] + ac[2] * ap[2];
    if (d1 <= 0.0 && d2 <= 0.0) {
        p[0] = a[0], p[1] = a[1], p[2] = a[2], *feat = F_VA;
        goto done;
    }
    double bp[3] = {q[0] - b[0], q[1] - b[1], q[2] - b[2]};
    double d3 = ab[0] * bp[0] + ab[1] * bp[1] + ab[2] * bp[2];
    double d4 = ac[0] * bp[0] + ac[1] * bp[1] + ac[2] * bp[2];
    if (d3 >= 0.0 && d4 <= d3) {
        p[0] = b[0], p[1] = b[1], p[2] = b[2], *feat = F_VB;
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        double den = d1 - d3, v = den > 0.0 ? d1 / den : 0.0;
        p[0] = a[0] + v * ab[0], p[1] = a[1] + v * ab[1], p[2] = a[2] + v * ab[2];
        *feat = F_EAB;
        goto done;
    }
    double cp[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
    double d5 = ab[0] * cp[0] + ab[1] * cp[1] + ab[2] * cp[2];
    double d6 = ac[0] * cp[0] + ac[1] * cp[1] + ac[2] * cp[2];
    if (d6 >= 0.0 && d5 <= d6) {
        p[0] = c[0], p[1] = c[1], p[2] = c[2], *feat = F_VC;
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        double den = d2 - d6, w = den > 0.0 ? d2 / den : 0.0;
        p[0] = a[0] + w * ac[0], p[1] = a[1] + w * ac[1], p[2] = a[2] + w * ac[2];
        *feat = F_ECA;
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    double e43 = d4 - d3, e56 = d5 - d6;
    if (va <= 0.0 && e43 >= 0.0 && e56 >= 0.0) {
        double den = e43 + e56, w = den > 0.0 ? e43 / den : 0.0;
        p[0] = b[0] + w * (c[0] - b[0]), p[1] = b[1] + w * (c[1] - b[1]),
        p[2] = b[2] + w * (c[2] - b[2]);
        *feat = F_EBC;
        goto done;
    }
    double sum = va + vb + vc;
    if (sum > 0.0) {
        double inv = 1.0 / sum, v = vb * inv, w = vc * inv;
        p[0] = a[0] + ab[0] * v + ac[0] * w;
        p[1] = a[1] + ab[1] * v + ac[1] * w;
        p[2] = a[2] + ab[2] * v + ac[2] * w;
        *feat = F_FACE;
    } else {
        /* Rounding left no region (a sliver): the nearest of the edge points. */
        double den = d1 - d3, v = den > 0.0 ? fmax(0.0, fmin(1.0, d1 / den)) : 0.0;
        p[0] = a[0] + v * ab[0], p[1] = a[1] + v * ab[1], p[2] = a[2] + v * ab[2];
        *feat = F_EAB;
        double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        double best = dx * dx + dy * dy + dz * dz;
        den = d2 - d6;
        double w = den > 0.0 ? fmax(0.0, fmin(1.0, d2 / den)) : 0.0;
        double r[3] = {a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]};
        dx = q[0] - r[0], dy = q[1] - r[1], dz = q[2] - r[2];
        double d = dx * dx + dy * dy + dz * dz;
        if (d < best) best = d, p[0] = r[0], p[1] = r[1], p[2] = r[2], *feat = F_ECA;
        den = e43 + e56;
        w = den > 0.0 ? fmax(0.0, fmin(1.0, e43 / den)) : 0.0;
        r[0] = b[0] + w * (c[0] - b[0]), r[1] = b[1] + w * (c[1] - b[1]),
        r[2] = b[2] + w * (c[2] - b[2]);
        dx = q[0] - r[0], dy = q[1] - r[1], dz = q[2] - r[2];
        d = dx * dx + dy * dy + dz * dz;
        if (d < best) p[0] = r[0], p[1] = r[1], p[2] = r[2], *feat = F_EBC;
    }
done:
    diff[0] = q[0] - p[0], diff[1] = q[1] - p[1], diff[2] = q[2] - p[2];
    return diff[0] * diff[0] + diff[1] * diff[1] + diff[2] * diff[2];
}

/* Moller & Trumbore 1997, in double: 1 and *t, *front (the segment crosses from the
 * side the normal (b - a) x (c - a) faces) when o + t d, t in [0, 1], meets the
 * triangle, barycentrics within EDGE_EPS. */
static int tri_ray(const float *restrict tv, const double o[3], const double d[3], double *t,
                   int *front) {
    double e1[3], e2[3], s[3];
    for (int i = 0; i < 3; ++i) {
        e1[i] = (double)tv[3 + i] - tv[i];
        e2[i] = (double)tv[6 + i] - tv[i];
        s[i] = o[i] - tv[i];
    }
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2],
                    d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0.0) return 0; /* parallel */
    double inv = 1.0 / det;
    double u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) * inv;
    if (u < -EDGE_EPS || u > 1.0 + EDGE_EPS) return 0;
    double qv[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                    s[0] * e1[1] - s[1] * e1[0]};
    double v = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) * inv;
    if (v < -EDGE_EPS || u + v > 1.0 + EDGE_EPS) return 0;
    double th = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) * inv;
    if (!(th >= 0.0 && th <= 1.0)) return 0;
    *t = th;
    *front = det > 0.0; /* det = -d . (e1 x e2) */
    return 1;
}

/* ---- BVH queries ---- */

/* Squared distance from q to a node's box (0 inside); straight-line code (maxss). */
static inline float box_d2(const bvh_node *nd, const float q[3]) {
    float d2 = 0.0f;
    for (int k = 0; k < 3; ++k) {
        float below = nd->lo[k] - q[k], above = q[k] - nd->hi[k];
        float d = below > above ? below : above;
        d = d > 0.0f ? d : 0.0f;
        d2 += d * d;
    }
    return d2;
}

/* Closest triangle to q with |q - p|^2 <= *d2 (the bound on entry, the distance on
 * exit), ties to the lower index; NONE if none. Nearest child first, an explicit
 * stack, boxes pruned against the best so far. */
static uint32_t closest_bvh(const struct rbc_trimesh *m, const float q[3], const double qd[3],
                            double *d2) {
    struct {
        uint32_t node;
        float d2;
    } stack[STACK_MAX];
    double best = *d2, diff[3];
    uint32_t bi = NONE, sp = 0;
    int feat;
    float r = box_d2(&m->nodes[0], q);
    if (r > best * BVH_MARGIN) return NONE;
    stack[sp].node = 0, stack[sp].d2 = r, ++sp;
    while (sp) {
        --sp;
        if (stack[sp].d2 > best * BVH_MARGIN) continue;
        const bvh_node *nd = &m->nodes[stack[sp].node];
        if (nd->count) {
            for (uint32_t i = nd->first, e = nd->first + nd->count; i < e; ++i) {
                double d = tri_closest(m->tv + 9 * (size_t)i, qd, diff, &feat);
                if (d < best || (d == best && i < bi)) best = d, bi = i;
            }
            continue;
        }
        uint32_t c = nd->first;
        float r0 = box_d2(&m->nodes[c], q), r1 = box_d2(&m->nodes[c + 1], q);
        double lim = best * BVH_MARGIN;
        if (r1 < r0) { /* nearer on top */
            float tr = r0;
            r0 = r1, r1 = tr;
            c ^= 1u; /* pairs start at even indices */
        }
        if (r1 <= lim) stack[sp].node = c ^ 1u, stack[sp].d2 = r1, ++sp;
        if (r0 <= lim) stack[sp].node = c, stack[sp].d2 = r0, ++sp;
    }
    *d2 = best;
    return bi;
}

static uint32_t closest_brute(const struct rbc_trimesh *m, const float q[3], const double qd[3],
                              double *d2) {
    double best = *d2, diff[3];
    uint32_t bi = NONE;
    int feat;
    (void)q;
    for (uint32_t i = 0; i < m->nt; ++i) {
        double d = tri_closest(m->tv + 9 * (size_t)i, qd, diff, &feat);
        if (d < best || (d == best && i < bi)) best = d, bi = i;
    }
    *d2 = best;
    return bi;
}

static const float up[3] = {0.0f, 1.0f, 0.0f};

/* The pseudo-normal of feature f of triangle i (closed meshes; the face normal of an
 * open one). */
static const float *feature_normal(const struct rbc_trimesh *m, uint32_t i, int f) {
    if (!m->closed || f == F_FACE) return m->fn + 3 * (size_t)i;
    const uint32_t *tri = m->tri + 3 * (size_t)i, *te = m->tedge + 3 * (size_t)i;
    switch (f) {
    case F_VA: return m->vn + 3 * (size_t)tri[0];
    case F_VB: return m->vn + 3 * (size_t)tri[1];
    case F_VC: return m->vn + 3 * (size_t)tri[2];
    case F_EAB: return m->en + 3 * (size_t)te[0];
    case F_EBC: return m->en + 3 * (size_t)te[1];
    default: return m->en + 3 * (size_t)te[2];
    }
}

/* phi and n at q from its closest triangle i: outside, the gradient (q - p) / d;
 * inside (Baerentzen & Aanaes, Theorem 1: the pseudo-normal of the closest feature
 * points away from q), -(q - p) / d; on the surface, the feature's normal. */
static float signed_at(const struct rbc_trimesh *m, const double qd[3], uint32_t i, float n[3]) {
    double diff[3];
    int feat;
    double d2 = tri_closest(m->tv + 9 * (size_t)i, qd, diff, &feat);
    const float *pn = feature_normal(m, i, feat);
    if (!(d2 > 0.0)) {
        n[0] = pn[0], n[1] = pn[1], n[2] = pn[2];
        return 0.0f;
    }
    double s = m->closed && pn[0] * diff[0] + pn[1] * diff[1] + pn[2] * diff[2] < 0.0 ? -1.0
                                                                                       : 1.0;
    double d = sqrt(d2), k = s / d;
    n[0] = (float)(diff[0] * k), n[1] = (float)(diff[1] * k), n[2] = (float)(diff[2] * k);
    return (float)(s * d);
}

/* The culling grid's cell of q (clamped: the bound holds for any q) and its centre. */
static size_t grid_cell(const struct rbc_trimesh *m, const float q[3], float c[3]) {
    size_t idx = 0;
    for (int k = 2; k >= 0; --k) {
        float x = (q[k] - m->glo[k]) / m->gh, top = (float)(m->gn[k] - 1);
        x = x > 0.0f ? x : 0.0f; /* also NaN -> 0 */
        x = x < top ? x : top;
        uint32_t i = (uint32_t)x;
        c[k] = m->glo[k] + ((float)i + 0.5f) * m->gh;
        idx = idx * m->gn[k] + i;
    }
    return idx;
}

static int mesh_distance(const struct rbc_trimesh *m, const float q[3], float max_dist,
                         float *phi, float n[3], int bvh) {
    if (max_dist != max_dist) return 0;
    if (!m->closed && max_dist < 0.0f) return 0; /* unsigned */
    const double qd[3] = {q[0], q[1], q[2]};
    double bound = max_dist >= 0.0f ? (double)max_dist * max_dist * BOUND_GROW : INFINITY;
    uint32_t (*closest)(const struct rbc_trimesh *, const float *, const double *, double *) =
        bvh ? closest_bvh : closest_brute;
    double reach = INFINITY; /* |phi(q)| is at most this, when the grid knows */
    if (bvh && m->closed) {
        /* Outside the bounds by more than max_dist; or, by the grid, phi(q) >=
         * lb(c) - |q - c| > max_dist (phi is 1-Lipschitz). The margin covers the
         * rounding of lb, of the centre and of |q - c|. */
        if (max_dist >= 0.0f && box_d2(&m->nodes[0], q) > bound * BVH_MARGIN) return 0;
        float c[3];
        size_t cell = grid_cell(m, q, c);
        double dx = qd[0] - c[0], dy = qd[1] - c[1], dz = qd[2] - c[2];
        double dist = sqrt(dx * dx + dy * dy + dz * dz);
        double lb = m->glb[cell], ub = m->gub[cell];
        double margin = 0x1p-18 * (fabs(lb) + dist + m->gmag);
        if (lb - dist - margin > max_dist) return 0;
        reach = ub + dist + margin;
    }
    double d2 = bound;
    uint32_t i = closest(m, q, qd, &d2);
    if (i == NONE) {
        /* Nothing within max_dist: farther outside (open: done), or deeper inside,
         * which only the closest feature can tell. */
        if (!m->closed) return 0;
        d2 = reach * reach;
        i = closest(m, q, qd, &d2);
        if (i == NONE) { /* not reached: reach cannot be short, but be safe */
            d2 = INFINITY;
            i = closest(m, q, qd, &d2);
        }
    }
    float nn[3], p = signed_at(m, qd, i, nn);
    if (!(p <= max_dist)) return 0;
    *phi = p;
    n[0] = nn[0], n[1] = nn[1], n[2] = nn[2];
    return 1;
}

/* Segment-box slabs in double: the entry parameter, or -1 if the segment [0, tmax]
 * misses the box. */
static inline double box_ray(const bvh_node *nd, const double o[3], const double d[3],
                             const double inv[3], double tmax) {
    double t0 = 0.0, t1 = tmax;
    for (int i = 0; i < 3; ++i) {
        if (d[i] == 0.0) {
            if (o[i] < nd->lo[i] || o[i] > nd->hi[i]) return -1.0;
            continue;
        }
        double ta = (nd->lo[i] - o[i]) * inv[i], tb = (nd->hi[i] - o[i]) * inv[i];
        if (ta > tb) {
            double tmp = ta;
            ta = tb, tb = tmp;
        }
        t0 = ta > t0 ? ta : t0;
        t1 = tb < t1 ? tb : t1;
    }
    return t0 <= t1 ? t0 : -1.0;
}

static uint32_t ray_bvh(const struct rbc_trimesh *m, const double o[3], const double d[3],
                        double *t, int *front) {
    struct {
        uint32_t node;
        double t;
    } stack[STACK_MAX];
    double inv[3], best = 1.0;
    for (int i = 0; i < 3; ++i) inv[i] = d[i] != 0.0 ? 1.0 / d[i] : 0.0;
    uint32_t bi = NONE, sp = 0;
    double r = box_ray(&m->nodes[0], o, d, inv, best);
    if (r < 0.0) return NONE;
    stack[sp].node = 0, stack[sp].t = r, ++sp;
    while (sp) {
        --sp;
        if (stack[sp].t > best) continue;
        const bvh_node *nd = &m->nodes[stack[sp].node];
        if (nd->count) {
            for (uint32_t i = nd->first, e = nd->first + nd->count; i < e; ++i) {
                double th;
                int f;
                if (tri_ray(m->tv + 9 * (size_t)i, o, d, &th, &f) &&
                    (th < best || (th == best && i < bi)))
                    best = th, bi = i, *front = f;
            }
            continue;
        }
        uint32_t c = nd->first;
        double r0 = box_ray(&m->nodes[c], o, d, inv, best);
        double r1 = box_ray(&m->nodes[c + 1], o, d, inv, best);
        /* Misses (-1) are not pushed; the nearer entry goes on top. */
        if (r0 >= 0.0 && r1 >= 0.0 && r1 < r0) {
            double tr = r0;
            r0 = r1, r1 = tr;
            c ^= 1u;
        }
        if (r1 >= 0.0) stack[sp].node = c ^ 1u, stack[sp].t = r1, ++sp;
        if (r0 >= 0.0) stack[sp].node = c, stack[sp].t = r0, ++sp;
    }
    *t = best;
    return bi;
}

static uint32_t ray_brute(const struct rbc_trimesh *m, const double o[3], const double d[3],
                          double *t, int *front) {
    double best = 1.0;
    uint32_t bi = NONE;
    for (uint32_t i = 0; i < m->nt; ++i) {
        double th;
        int f;
        if (tri_ray(m->tv + 9 * (size_t)i, o, d, &th, &f) && (th < best || (th == best && i < bi)))
            best = th, bi = i, *front = f;
    }
    *t = best;
    return bi;
}

static int mesh_raycast(const struct rbc_trimesh *m, const float a[3], const float b[3],
                        float *t, float n[3], int bvh) {
    double o[3] = {a[0], a[1], a[2]}, d[3] = {(double)b[0] - a[0], (double)b[1] - a[1],
                                               (double)b[2] - a[2]};
    double th;
    int front = 0;
    uint32_t i = bvh ? ray_bvh(m, o, d, &th, &front) : ray_brute(m, o, d, &th, &front);
    if (i == NONE) return 0;
    /* Closed: the first crossing from inside means a started inside. */
    if (m->closed && !front) return 0;
    const float *fn = m->fn + 3 * (size_t)i;
    float s = front ? 1.0f : -1.0f;
    n[0] = s * fn[0], n[1] = s * fn[1], n[2] = s * fn[2];
    *t = (float)th;
    return 1;
}

int rbc_trimesh_distance_brute(const struct rbc_trimesh *m, const float q[3], float max_dist,
                               float *phi, float n[3]) {
    return mesh_distance(m, q, max_dist, phi, n, 0);
}

int rbc_trimesh_raycast_brute(const struct rbc_trimesh *m, const float a[3], const float b[3],
                              float *t, float n[3]) {
    return mesh_raycast(m, a, b, t, n, 0);
}

/* ---- the shape interface ---- */

int rbc_shape_distance(const rbc_shape_geom *g, const float q[3], float max_dist, float *phi,
                       float n[3]) {
    if (g->kind == RBC_SHAPE_TRIANGLE_MESH)
        return g->mesh ? mesh_distance(g->mesh, q, max_dist, phi, n, 1) : 0;
    return rbc_kc_distance(g->kind, g->radius, g->half_extents, q, max_dist, phi, n);
}

int rbc_shape_raycast(const rbc_shape_geom *g, const float a[3], const float b[3], float *t,
                      float n[3]) {
    if (g->kind == RBC_SHAPE_TRIANGLE_MESH)
        return g->mesh ? mesh_raycast(g->mesh, a, b, t, n, 1) : 0;
    return rbc_kc_raycast(g->kind, g->radius, g->half_extents, a, b, t, n);
}

void rbc_shape_bounds(const rbc_shape_geom *g, float lo[3], float hi[3]) {
    float r = maxf(g->radius, 0.0f), e[3] = {0.0f, 0.0f, 0.0f};
    switch (g->kind) {
    case RBC_SHAPE_PLANE:
        lo[0] = lo[1] = lo[2] = -INFINITY;
        hi[0] = hi[2] = INFINITY;
        hi[1] = 0.0f;
        return;
    case RBC_SHAPE_SPHERE:
        e[0] = e[1] = e[2] = r;
        break;
    case RBC_SHAPE_CAPSULE:
        e[0] = e[2] = r;
        e[1] = maxf(g->half_extents[1], 0.0f) + r;
        break;
    case RBC_SHAPE_BOX:
        for (int i = 0; i < 3; ++i) e[i] = maxf(g->half_extents[i], 0.0f);
        break;
    case RBC_SHAPE_TRIANGLE_MESH:
        if (g->mesh) {
            memcpy(lo, g->mesh->lo, sizeof g->mesh->lo);
            memcpy(hi, g->mesh->hi, sizeof g->mesh->hi);
            return;
        }
        break;
    default:
        break;
    }
    for (int i = 0; i < 3; ++i) lo[i] = -e[i], hi[i] = e[i];
}

/* ---- building a mesh ---- */

/* Temporary arrays of one build, freed together. */
typedef struct scratch {
    void *p[12];
    size_t size[12];
    int n;
} scratch;

static void *scratch_alloc(scratch *s, const rbc_allocator *a, size_t size) {
    void *p = rbc_mem_alloc(a, size);
    if (p) s->p[s->n] = p, s->size[s->n] = size, s->n++;
    return p;
}

static void scratch_free(scratch *s, const rbc_allocator *a) {
    while (s->n > 0) {
        --s->n;
        rbc_mem_free(a, s->p[s->n], s->size[s->n]);
    }
}

static void mesh_free_arrays(struct rbc_trimesh *m, const rbc_allocator *a) {
    rbc_mem_free(a, m->pos, sizeof(float) * 3 * (size_t)m->nv);
    rbc_mem_free(a, m->tri, sizeof(uint32_t) * 3 * (size_t)m->nt);
    rbc_mem_free(a, m->tv, sizeof(float) * 9 * (size_t)m->nt);
    rbc_mem_free(a, m->fn, sizeof(float) * 3 * (size_t)m->nt);
    rbc_mem_free(a, m->tedge, sizeof(uint32_t) * 3 * (size_t)m->nt);
    rbc_mem_free(a, m->en, sizeof(float) * 3 * (size_t)m->ne);
    rbc_mem_free(a, m->vn, sizeof(float) * 3 * (size_t)m->nv);
    rbc_mem_free(a, m->nodes, sizeof(bvh_node) * (size_t)m->ncap);
    rbc_mem_free(a, m->glb, sizeof(float) * m->gcells);
    rbc_mem_free(a, m->gub, sizeof(float) * m->gcells);
}

void rbc_trimesh_destroy(struct rbc_trimesh *m, const rbc_allocator *a) {
    if (!m) return;
    mesh_free_arrays(m, a);
    rbc_mem_free(a, m, sizeof *m);
}

/* (b - a) x (c - a) in double. */
static void cross_d(const float *pos, const uint32_t *t, double n[3]) {
    const float *a = pos + 3 * (size_t)t[0], *b = pos + 3 * (size_t)t[1],
                *c = pos + 3 * (size_t)t[2];
    double u[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double v[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

static int degenerate(const float *pos, const uint32_t *t) {
    double n[3];
    cross_d(pos, t, n);
    return n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0;
}

static void normalize_to_float(const double v[3], float out[3]) {
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (l > 0.0) {
        out[0] = (float)(v[0] / l), out[1] = (float)(v[1] / l), out[2] = (float)(v[2] / l);
    } else {
        out[0] = up[0], out[1] = up[1], out[2] = up[2]; /* opposite faces cancel */
    }
}

static int cmp_u64(const void *x, const void *y) {
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return (a > b) - (a < b);
}

typedef struct build_ctx {
    bvh_node *nodes;
    uint32_t next;
    uint32_t *idx;     /* [m] triangles (kept order), partitioned in place */
    const float *tbox; /* [6 m] lo, hi */
    const float *cen;  /* [3 m] */
} build_ctx;

static inline uint32_t bin_of(float c, float cmin, float scale) {
    int k = (int)((c - cmin) * scale);
    return k < 0 ? 0u : k >= SAH_BINS ? (uint32_t)SAH_BINS - 1u : (uint32_t)k;
}

static inline float half_area(const float lo[3], const float hi[3]) {
    float x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
    return x * y + y * z + z * x;
}

static inline void grow(float lo[3], float hi[3], const float *box) {
    for (int k = 0; k < 3; ++k) lo[k] = minf(lo[k], box[k]), hi[k] = maxf(hi[k], box[3 + k]);
}

/* Binned SAH over centroids: the split of least nl area(L) + nr area(R) over every
 * bin boundary of every axis (the first on ties); the position of the first right
 * triangle after partitioning, or 0 if no axis can be binned. */
static uint32_t split_sah(build_ctx *b, uint32_t begin, uint32_t end, const float clo[3],
                          const float chi[3]) {
    float best_cost = INFINITY, best_scale = 0.0f;
    int best_ax = -1;
    uint32_t best_bin = 0;
    for (int ax = 0; ax < 3; ++ax) {
        float ext = chi[ax] - clo[ax], scale = (float)SAH_BINS / ext;
        if (!(ext > 0.0f) || !isfinite(scale)) continue;
        uint32_t cnt[SAH_BINS] = {0}, rcnt[SAH_BINS];
        float blo[SAH_BINS][3], bhi[SAH_BINS][3], rarea[SAH_BINS];
        for (int k = 0; k < SAH_BINS; ++k)
            for (int j = 0; j < 3; ++j) blo[k][j] = INFINITY, bhi[k][j] = -INFINITY;
        for (uint32_t i = begin; i < end; ++i) {
            uint32_t t = b->idx[i], k = bin_of(b->cen[3 * (size_t)t + ax], clo[ax], scale);
            cnt[k]++;
            grow(blo[k], bhi[k], b->tbox + 6 * (size_t)t);
        }
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        uint32_t nr = 0;
        for (int k = SAH_BINS - 1; k > 0; --k) {
            float box[6] = {blo[k][0], blo[k][1], blo[k][2], bhi[k][0], bhi[k][1], bhi[k][2]};
            grow(lo, hi, box);
            nr += cnt[k];
            rcnt[k] = nr;
            rarea[k] = nr ? half_area(lo, hi) : 0.0f;
        }
        for (int j = 0; j < 3; ++j) lo[j] = INFINITY, hi[j] = -INFINITY;
        uint32_t nl = 0;
        for (int k = 0; k < SAH_BINS - 1; ++k) {
            float box[6] = {blo[k][0], blo[k][1], blo[k][2], bhi[k][0], bhi[k][1], bhi[k][2]};
            grow(lo, hi, box);
            nl += cnt[k];
            if (!nl || !rcnt[k + 1]) continue;
            float cost = (float)nl * half_area(lo, hi) + (float)rcnt[k + 1] * rarea[k + 1];
            if (cost < best_cost) best_cost = cost, best_ax = ax, best_bin = (uint32_t)k,
                                  best_scale = scale;
        }
    }
    if (best_ax < 0) return 0;
    uint32_t i = begin, j = end;
    while (i < j) {
        uint32_t t = b->idx[i];
        if (bin_of(b->cen[3 * (size_t)t + best_ax], clo[best_ax], best_scale) <= best_bin) {
            ++i;
        } else {
            --j;
            b->idx[i] = b->idx[j], b->idx[j] = t;
        }
    }
    return i; /* begin < i < end: both sides of the chosen boundary hold triangles */
}

static inline int cen_less(const float *cen, int ax, uint32_t x, uint32_t y) {
    float a = cen[3 * (size_t)x + ax], c = cen[3 * (size_t)y + ax];
    return a < c || (a == c && x < y);
}

/* Quickselect (median-of-three pivot): v[k] is where a sort by (centroid, index)
 * would put it, smaller ones before. */
static void select_kth(uint32_t *v, uint32_t n, uint32_t k, const float *cen, int ax) {
    size_t lo = 0, hi = n - 1;
#define SWAP_(x, y) do { uint32_t t_ = v[x]; v[x] = v[y]; v[y] = t_; } while (0)
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cen_less(cen, ax, v[mid], v[lo])) SWAP_(mid, lo);
        if (cen_less(cen, ax, v[hi], v[lo])) SWAP_(hi, lo);
        if (cen_less(cen, ax, v[hi], v[mid])) SWAP_(hi, mid);
        SWAP_(mid, hi);
        uint32_t pivot = v[hi];
        size_t store = lo;
        for (size_t i = lo; i < hi; ++i)
            if (cen_less(cen, ax, v[i], pivot)) {
                SWAP_(i, store);
                ++store;
            }
        SWAP_(store, hi);
        if (k == store) break;
        if (k < store) hi = store - 1;
        else lo = store + 1;
    }
#undef SWAP_
}

/* Half the triangles each side, along the longest centroid extent: depth stays
 * logarithmic whatever SAH did above. */
static uint32_t split_median(build_ctx *b, uint32_t begin, uint32_t end, const float clo[3],
                             const float chi[3]) {
    int ax = 0;
    for (int i = 1; i < 3; ++i)
        if (chi[i] - clo[i] > chi[ax] - clo[ax]) ax = i;
    uint32_t k = (end - begin) / 2;
    if (chi[ax] > clo[ax]) select_kth(b->idx + begin, end - begin, k, b->cen, ax);
    return begin + k;
}

static void build_node(build_ctx *b, uint32_t node, uint32_t begin, uint32_t end,
                       uint32_t depth) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    float clo[3] = {INFINITY, INFINITY, INFINITY}, chi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = begin; i < end; ++i) {
        uint32_t t = b->idx[i];
        grow(lo, hi, b->tbox + 6 * (size_t)t);
        const float *c = b->cen + 3 * (size_t)t;
        for (int k = 0; k < 3; ++k) clo[k] = minf(clo[k], c[k]), chi[k] = maxf(chi[k], c[k]);
    }
    float mag = 0.0f;
    for (int k = 0; k < 3; ++k) mag = maxf(mag, maxf(fabsf(lo[k]), fabsf(hi[k])));
    float grow_by = mag * BVH_INFLATE;
    bvh_node *nd = &b->nodes[node];
    for (int k = 0; k < 3; ++k) nd->lo[k] = lo[k] - grow_by, nd->hi[k] = hi[k] + grow_by;
    if (end - begin <= LEAF_MAX) {
        nd->first = begin;
        nd->count = end - begin;
        return;
    }
    uint32_t mid = depth < SAH_MAX_DEPTH ? split_sah(b, begin, end, clo, chi) : 0;
    if (!mid) mid = split_median(b, begin, end, clo, chi);
    uint32_t c = b->next;
    b->next += 2;
    nd->first = c;
    nd->count = 0;
    build_node(b, c, begin, mid, depth + 1);
    build_node(b, c + 1, mid, end, depth + 1);
}

/* The culling grid of a closed mesh (after its BVH and triangles). A cell whose
 * centre has a surface point within R = sqrt(3) h (h the cell side; the search bound
 * is a hair larger) is near: its exact phi is stored (glb = phi, gub = |phi|). Every
 * surface point lies in a cell, within sqrt(3) h / 2 of its centre, which is therefore
 * near; so at any other (far) centre |phi| >= max(R, D - sqrt(3) h / 2), D the distance
 * to the nearest near centre, at least h times the Chebyshev steps to it, which a
 * multi-source breadth-first search over the 26 neighbours counts. Two neighbours'
 * centres are at most R apart, closer than a far centre is to the surface, so no
 * surface lies between them: the search carries the sign out of the near cells. Far
 * outside: glb = that bound; far inside: glb = -INFINITY (nothing to cull). Cost: one
 * BVH search of radius R per cell (at most 34^3 cells). */
static int build_grid(struct rbc_trimesh *m, const rbc_allocator *a, scratch *s) {
    float ext = 0.0f;
    for (int k = 0; k < 3; ++k) ext = maxf(ext, m->hi[k] - m->lo[k]);
    int K = (int)cbrt(8.0 * m->nt);
    K = K < 4 ? 4 : K > 32 ? 32 : K;
    float h = ext / (float)K;
    m->gh = h;
    m->gcells = 1;
    m->gmag = 0.0f;
    for (int k = 0; k < 3; ++k) {
        m->gn[k] = (uint32_t)ceilf((m->hi[k] - m->lo[k]) / h) + 2;
        if (m->gn[k] > (uint32_t)K + 3) m->gn[k] = (uint32_t)K + 3; /* rounding */
        m->glo[k] = m->lo[k] - h;
        m->gcells *= m->gn[k];
        m->gmag = maxf(m->gmag, maxf(fabsf(m->glo[k]), fabsf(m->glo[k] + (float)m->gn[k] * h)));
    }
    const size_t nc = m->gcells;
    m->glb = rbc_mem_alloc(a, sizeof(float) * nc);
    m->gub = rbc_mem_alloc(a, sizeof(float) * nc);
    int32_t *steps = scratch_alloc(s, a, sizeof(int32_t) * nc);
    uint32_t *queue = scratch_alloc(s, a, sizeof(uint32_t) * nc);
    if (!m->glb || !m->gub || !steps || !queue) return 0;
    const double R = sqrt(3.0) * h, R2 = R * R * (1.0 + 0x1p-10), half = 0.5 * R;
    size_t tail = 0;
    for (uint32_t z = 0; z < m->gn[2]; ++z)
        for (uint32_t y = 0; y < m->gn[1]; ++y)
            for (uint32_t x = 0; x < m->gn[0]; ++x) {
                size_t cell = ((size_t)z * m->gn[1] + y) * m->gn[0] + x;
                /* the centre exactly as grid_cell computes it */
                float c[3] = {m->glo[0] + ((float)x + 0.5f) * h, m->glo[1] + ((float)y + 0.5f) * h,
                              m->glo[2] + ((float)z + 0.5f) * h};
                double cd[3] = {c[0], c[1], c[2]}, d2 = R2;
                uint32_t t = closest_bvh(m, c, cd, &d2);
                steps[cell] = -1;
                if (t == NONE) continue;
                float n[3], phi = signed_at(m, cd, t, n);
                m->glb[cell] = phi, m->gub[cell] = fabsf(phi);
                steps[cell] = 0;
                queue[tail++] = (uint32_t)cell;
            }
    if (tail == 0) { /* cannot happen (the surface is inside the grid): cull nothing */
        for (size_t c = 0; c < nc; ++c) m->glb[c] = -INFINITY, m->gub[c] = INFINITY;
        return 1;
    }
    const uint32_t nx = m->gn[0], ny = m->gn[1], nz = m->gn[2];
    for (size_t head = 0; head < tail; ++head) {
        uint32_t cell = queue[head];
        uint32_t x = cell % nx, y = cell / nx % ny, z = cell / nx / ny;
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    int64_t X = (int64_t)x + dx, Y = (int64_t)y + dy, Z = (int64_t)z + dz;
                    if (X < 0 || Y < 0 || Z < 0 || X >= nx || Y >= ny || Z >= nz) continue;
                    size_t nb = ((size_t)Z * ny + (size_t)Y) * nx + (size_t)X;
                    if (steps[nb] >= 0) continue;
                    steps[nb] = steps[cell] + 1;
                    /* a far cell: the sign of where the search came from */
                    double lb = fmax(R, steps[nb] * (double)h - half) * (1.0 - 0x1p-20);
                    m->glb[nb] = m->glb[cell] < 0.0f ? -INFINITY : (float)lb;
                    m->gub[nb] = INFINITY;
                    queue[tail++] = (uint32_t)nb;
                }
    }
    return 1;
}

/* The checks of rbc_trimesh_create; *kept: the triangles that are not degenerate. */
static int32_t trimesh_check(const float *positions, uint32_t nv, const uint32_t *tris,
                             uint32_t nt, uint32_t *kept, char *err, size_t errlen) {
    const int32_t BAD = RBC_ERR_INVALID_ARGUMENT;
    if (!positions) return rbc_fail(err, errlen, BAD, "positions is NULL");
    if (!tris) return rbc_fail(err, errlen, BAD, "triangles is NULL");
    if (nv == 0) return rbc_fail(err, errlen, BAD, "vertex count is 0");
    if (nt == 0) return rbc_fail(err, errlen, BAD, "triangle count is 0");
    if (nt > UINT32_MAX / 3)
        return rbc_fail(err, errlen, BAD, "%u triangles: at most %u", nt, UINT32_MAX / 3);
    for (uint32_t v = 0; v < nv; ++v) {
        const float *p = positions + 3 * (size_t)v;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return rbc_fail(err, errlen, BAD, "vertex %u has a non-finite position (%g, %g, %g)",
                            v, p[0], p[1], p[2]);
    }
    for (uint32_t t = 0; t < nt; ++t)
        for (uint32_t k = 0; k < 3; ++k)
            if (tris[3 * (size_t)t + k] >= nv)
                return rbc_fail(err, errlen, BAD,
                                "triangle %u corner %u: vertex index %u out of range (%u "
                                "vertices)",
                                t, k, tris[3 * (size_t)t + k], nv);
    uint32_t m = 0;
    for (uint32_t t = 0; t < nt; ++t) m += !degenerate(positions, tris + 3 * (size_t)t);
    if (m == 0)
        return rbc_fail(err, errlen, BAD, "all %u triangles are degenerate (zero area)", nt);
    *kept = m;
    return RBC_OK;
}

/* What the build of one mesh shares between its steps (the scratch is freed at its
 * end). */
typedef struct mesh_build {
    struct rbc_trimesh *mesh;
    scratch s;
    const rbc_allocator *a;
    uint32_t m, ne;       /* triangles kept, edges */
    size_t nh;            /* half-edges: 3 m */
    int closed;
    uint32_t *t3;         /* [3 m] the kept triangles' corners */
    uint32_t *tedge;      /* [3 m] the edge of each half-edge */
    double *fnd;          /* [3 m] unit face normals */
    uint32_t *idx;        /* [m] triangles in BVH leaf order */
} mesh_build;

/* Edges: half-edge h = 3 t + k runs t3[h] -> t3[next(h)]; bucket half-edges by their
 * lower vertex (counting sort), sort each bucket by (upper vertex, h): a run of one
 * upper vertex is one edge. Closed: every run is two half-edges of opposite
 * direction. 0, or -1 out of memory. */
static int label_edges(mesh_build *b) {
    const uint32_t nv = b->mesh->nv;
    const size_t nh = b->nh;
    const uint32_t *t3 = b->t3;
    uint32_t *hstart = scratch_alloc(&b->s, b->a, sizeof(uint32_t) * ((size_t)nv + 1));
    uint64_t *hent = scratch_alloc(&b->s, b->a, sizeof(uint64_t) * nh);
    b->tedge = scratch_alloc(&b->s, b->a, sizeof(uint32_t) * nh);
    if (!hstart || !hent || !b->tedge) return -1;
#define NEXT_(h) ((h) - (h) % 3 + ((h) % 3 + 1) % 3)
    for (size_t h = 0; h < nh; ++h) {
        uint32_t u = t3[h], v = t3[NEXT_(h)];
        hstart[(u < v ? u : v) + 1]++;
    }
    for (uint32_t v = 0; v < nv; ++v) hstart[v + 1] += hstart[v];
    for (size_t h = 0; h < nh; ++h) {
        uint32_t u = t3[h], v = t3[NEXT_(h)], lo = u < v ? u : v, hi = u < v ? v : u;
        hent[hstart[lo]++] = (uint64_t)hi << 32 | (uint64_t)h;
    }
#undef NEXT_
    /* hstart[v] is now the end of v's bucket. */
    uint32_t ne = 0, closed = 1;
    for (uint32_t v = 0; v < nv; ++v) {
        uint32_t b0 = v ? hstart[v - 1] : 0, b1 = hstart[v];
        if (b1 - b0 > 1) qsort(hent + b0, b1 - b0, sizeof *hent, cmp_u64);
        for (uint32_t i = b0; i < b1;) {
            uint32_t j = i + 1;
            while (j < b1 && hent[j] >> 32 == hent[i] >> 32) ++j;
            if (j - i != 2 || t3[(uint32_t)hent[i]] == t3[(uint32_t)hent[i + 1]]) closed = 0;
            for (uint32_t r = i; r < j; ++r) b->tedge[(uint32_t)hent[r]] = ne;
            ++ne, i = j;
        }
    }
    b->ne = ne;
    b->closed = (int)closed;
    return 0;
}

/* A closed mesh enclosing negative volume winds inward: turn every triangle round
 * (swap corners 1 and 2; edges (a,b) and (c,a) trade places). */
static void orient_outward(mesh_build *b) {
    const struct rbc_trimesh *mesh = b->mesh;
    const float *pos = mesh->pos;
    uint32_t *t3 = b->t3, *tedge = b->tedge;
    double c0[3], vol = 0.0;
    for (int k = 0; k < 3; ++k) c0[k] = 0.5 * ((double)mesh->lo[k] + mesh->hi[k]);
    for (uint32_t t = 0; t < b->m; ++t) {
        double p[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) p[k][j] = (double)pos[3 * (size_t)t3[3 * t + k] + j] - c0[j];
        vol += p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) +
               p[0][1] * (p[1][2] * p[2][0] - p[1][0] * p[2][2]) +
               p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
    }
    if (vol < 0.0)
        for (uint32_t t = 0; t < b->m; ++t) {
            uint32_t x = t3[3 * t + 1];
            t3[3 * t + 1] = t3[3 * t + 2], t3[3 * t + 2] = x;
            x = tedge[3 * t];
            tedge[3 * t] = tedge[3 * t + 2], tedge[3 * t + 2] = x;
        }
}

/* Pseudo-normals (Baerentzen & Aanaes 2005) of a closed mesh: a vertex's is the sum of
 * its faces' normals weighted by the face angle there, an edge's the sum of its two
 * faces'. 0, or -1 out of memory. */
static int pseudo_normals(mesh_build *b) {
    struct rbc_trimesh *mesh = b->mesh;
    const uint32_t nv = mesh->nv, ne = b->ne, *t3 = b->t3;
    const float *pos = mesh->pos;
    const double *fnd = b->fnd;
    mesh->closed = 1, mesh->ne = ne;
    size_t nacc = nv > ne ? nv : ne;
    double *acc = scratch_alloc(&b->s, b->a, sizeof(double) * 3 * nacc);
    mesh->vn = rbc_mem_alloc(b->a, sizeof(float) * 3 * (size_t)nv);
    mesh->en = rbc_mem_alloc(b->a, sizeof(float) * 3 * (size_t)ne);
    if (!acc || !mesh->vn || !mesh->en) return -1;
    for (uint32_t t = 0; t < b->m; ++t)
        for (int k = 0; k < 3; ++k) {
            const float *p0 = pos + 3 * (size_t)t3[3 * t + k],
                        *p1 = pos + 3 * (size_t)t3[3 * t + (k + 1) % 3],
                        *p2 = pos + 3 * (size_t)t3[3 * t + (k + 2) % 3];
            double e1[3], e2[3];
            for (int j = 0; j < 3; ++j) e1[j] = (double)p1[j] - p0[j], e2[j] = (double)p2[j] - p0[j];
            double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                   cz = e1[0] * e2[1] - e1[1] * e2[0];
            double ang = atan2(sqrt(cx * cx + cy * cy + cz * cz),
                               e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]);
            double *o = acc + 3 * (size_t)t3[3 * t + k];
            for (int j = 0; j < 3; ++j) o[j] += ang * fnd[3 * (size_t)t + j];
        }
    for (uint32_t v = 0; v < nv; ++v) normalize_to_float(acc + 3 * (size_t)v, mesh->vn + 3 * (size_t)v);
    memset(acc, 0, sizeof(double) * 3 * nacc);
    for (size_t h = 0; h < b->nh; ++h)
        for (int j = 0; j < 3; ++j) acc[3 * (size_t)b->tedge[h] + j] += fnd[3 * (h / 3) + j];
    for (uint32_t e = 0; e < ne; ++e) normalize_to_float(acc + 3 * (size_t)e, mesh->en + 3 * (size_t)e);
    return 0;
}

/* The BVH over triangle boxes and centroids; b->idx: the triangles in leaf order.
 * 0, or -1 out of memory. */
static int build_bvh(mesh_build *b) {
    struct rbc_trimesh *mesh = b->mesh;
    const uint32_t m = b->m;
    float *tbox = scratch_alloc(&b->s, b->a, sizeof(float) * 6 * (size_t)m);
    float *cen = scratch_alloc(&b->s, b->a, sizeof(float) * 3 * (size_t)m);
    b->idx = scratch_alloc(&b->s, b->a, sizeof(uint32_t) * (size_t)m);
    mesh->nodes = rbc_mem_alloc(b->a, sizeof(bvh_node) * (size_t)mesh->ncap);
    if (!tbox || !cen || !b->idx || !mesh->nodes) return -1;
    for (uint32_t t = 0; t < m; ++t) {
        float *bx = tbox + 6 * (size_t)t;
        for (int k = 0; k < 3; ++k) bx[k] = INFINITY, bx[3 + k] = -INFINITY;
        for (int c = 0; c < 3; ++c) {
            const float *p = mesh->pos + 3 * (size_t)b->t3[3 * t + c];
            for (int k = 0; k < 3; ++k) bx[k] = minf(bx[k], p[k]), bx[3 + k] = maxf(bx[3 + k], p[k]);
        }
        for (int k = 0; k < 3; ++k) cen[3 * (size_t)t + k] = 0.5f * bx[k] + 0.5f * bx[3 + k];
        b->idx[t] = t;
    }
    build_ctx bc = {mesh->nodes, 2, b->idx, tbox, cen};
    build_node(&bc, 0, 0, m, 0);
    return 0;
}

/* Triangles, their corners and normals in leaf order. 0, or -1 out of memory. */
static int leaf_order(mesh_build *b) {
    struct rbc_trimesh *mesh = b->mesh;
    const size_t nh = b->nh;
    mesh->tri = rbc_mem_alloc(b->a, sizeof(uint32_t) * nh);
    mesh->tv = rbc_mem_alloc(b->a, sizeof(float) * 9 * (size_t)b->m);
    mesh->fn = rbc_mem_alloc(b->a, sizeof(float) * nh);
    if (b->closed) mesh->tedge = rbc_mem_alloc(b->a, sizeof(uint32_t) * nh);
    if (!mesh->tri || !mesh->tv || !mesh->fn || (b->closed && !mesh->tedge)) return -1;
    for (uint32_t i = 0; i < b->m; ++i) {
        uint32_t t = b->idx[i];
        for (int k = 0; k < 3; ++k) {
            uint32_t v = b->t3[3 * (size_t)t + k];
            mesh->tri[3 * (size_t)i + k] = v;
            if (b->closed) mesh->tedge[3 * (size_t)i + k] = b->tedge[3 * (size_t)t + k];
            memcpy(mesh->tv + 9 * (size_t)i + 3 * k, mesh->pos + 3 * (size_t)v, 3 * sizeof(float));
        }
        double f[3] = {b->fnd[3 * (size_t)t], b->fnd[3 * (size_t)t + 1], b->fnd[3 * (size_t)t + 2]};
        normalize_to_float(f, mesh->fn + 3 * (size_t)i);
    }
    return 0;
}

/* The mesh's copy of the positions and kept triangles, and its bounds. 0, or -1. */
static int copy_input(mesh_build *b, const float *positions, const uint32_t *tris, uint32_t nt) {
    struct rbc_trimesh *mesh = b->mesh;
    mesh->pos = rbc_mem_alloc(b->a, sizeof(float) * 3 * (size_t)mesh->nv);
    b->t3 = scratch_alloc(&b->s, b->a, sizeof(uint32_t) * b->nh);
    if (!mesh->pos || !b->t3) return -1;
    memcpy(mesh->pos, positions, sizeof(float) * 3 * (size_t)mesh->nv);
    const float *pos = mesh->pos;
    for (uint32_t t = 0, j = 0; t < nt; ++t)
        if (!degenerate(pos, tris + 3 * (size_t)t)) memcpy(b->t3 + 3 * (size_t)j++, tris + 3 * (size_t)t, 12);
    for (int k = 0; k < 3; ++k) mesh->lo[k] = INFINITY, mesh->hi[k] = -INFINITY;
    for (size_t h = 0; h < b->nh; ++h) {
        const float *p = pos + 3 * (size_t)b->t3[h];
        for (int k = 0; k < 3; ++k) mesh->lo[k] = minf(mesh->lo[k], p[k]), mesh->hi[k] = maxf(mesh->hi[k], p[k]);
    }
    return 0;
}

/* Unit face normals (double, kept order). 0, or -1 out of memory. */
static int face_normals(mesh_build *b) {
    b->fnd = scratch_alloc(&b->s, b->a, sizeof(double) * b->nh);
    if (!b->fnd) return -1;
    for (uint32_t t = 0; t < b->m; ++t) {
        double *f = b->fnd + 3 * (size_t)t;
        cross_d(b->mesh->pos, b->t3 + 3 * (size_t)t, f);
        double l = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
        f[0] /= l, f[1] /= l, f[2] /= l;
    }
    return 0;
}

int32_t rbc_trimesh_create(const float *positions, uint32_t nv, const uint32_t *tris,
                           uint32_t nt, const rbc_allocator *a, struct rbc_trimesh **out,
                           char *err, size_t errlen) {
    if (out) *out = NULL;
    if (!out || !a) return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "out or allocator is NULL");
    uint32_t m = 0;
    int32_t rc = trimesh_check(positions, nv, tris, nt, &m, err, errlen);
    if (rc != RBC_OK) return rc;
    mesh_build b = {NULL, {{0}, {0}, 0}, a, m, 0, 3 * (size_t)m, 0, NULL, NULL, NULL, NULL};
    struct rbc_trimesh *mesh = b.mesh = rbc_mem_alloc(a, sizeof *mesh);
    int ok = mesh != NULL;
    if (ok) mesh->nv = nv, mesh->nt = m, mesh->ndeg = nt - m, mesh->ncap = 2 * m;
    ok = ok && copy_input(&b, positions, tris, nt) == 0 && label_edges(&b) == 0;
    if (ok && b.closed) orient_outward(&b);
    ok = ok && face_normals(&b) == 0 && (!b.closed || pseudo_normals(&b) == 0);
    ok = ok && build_bvh(&b) == 0 && leaf_order(&b) == 0;
    ok = ok && (!b.closed || build_grid(mesh, a, &b.s));
    scratch_free(&b.s, a);
    if (!ok) {
        rbc_trimesh_destroy(mesh, a);
        return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY,
                        "out of memory building a mesh of %u vertices and %u triangles", nv, nt);
    }
    const size_t nh = b.nh;
    mesh->bytes = sizeof *mesh + sizeof(float) * 3 * (size_t)nv + sizeof(uint32_t) * nh +
                  sizeof(float) * 9 * (size_t)m + sizeof(float) * nh +
                  sizeof(bvh_node) * (size_t)mesh->ncap;
    if (b.closed)
        mesh->bytes += sizeof(uint32_t) * nh + sizeof(float) * 3 * ((size_t)b.ne + nv) +
                       2 * sizeof(float) * mesh->gcells;
    *out = mesh;
    return RBC_OK;
}

void rbc_trimesh_info_get(const struct rbc_trimesh *m, rbc_trimesh_info *out) {
    out->vertices = m->nv;
    out->triangles = m->nt;
    out->degenerate = m->ndeg;
    out->closed = m->closed;
    out->bytes = m->bytes;
    memcpy(out->lo, m->lo, sizeof m->lo);
    memcpy(out->hi, m->hi, sizeof m->hi);
}
