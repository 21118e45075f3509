/* topology.c -- quad mesh -> particles and unique springs (structural, explicit,
 * shear, bend) -> coloring -> color-contiguous particle order (Fig. 2 of the
 * paper) -> CSR adjacency. */
#include "report.h"
#include "topology.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../abi/rbcloth.h"
#include "coloring.h"
#include "prefetch.h"


static double dist3_sq(const float *p, uint32_t a, uint32_t b) {
    double dx = (double)p[3 * a] - p[3 * b], dy = (double)p[3 * a + 1] - p[3 * b + 1],
           dz = (double)p[3 * a + 2] - p[3 * b + 2];
    return dx * dx + dy * dy + dz * dz;
}

/* Squared norm of the cross product of a quad's diagonals, m^4: the area of a
 * (possibly non-planar) quad is half its square root. */
static double diag_cross_sq(const float *p, const uint32_t *q) {
    double d1[3], d2[3];
    for (int c = 0; c < 3; ++c) {
        d1[c] = (double)p[3 * q[2] + c] - p[3 * q[0] + c];
        d2[c] = (double)p[3 * q[3] + c] - p[3 * q[1] + c];
    }
    double cx = d1[1] * d2[2] - d1[2] * d2[1], cy = d1[2] * d2[0] - d1[0] * d2[2],
           cz = d1[0] * d2[1] - d1[1] * d2[0];
    return cx * cx + cy * cy + cz * cz;
}

static int32_t validate(const rbc_mesh_input *in, char *err, size_t errlen) {
    const uint32_t n = in->vertex_count;
    if (n == 0) return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "vertex_count is 0");
    if (!in->positions) return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "positions is NULL");
    if (in->quad_count && !in->quads)
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "quads is NULL but quad_count is %u",
                    in->quad_count);
    if (in->spring_count && !in->springs)
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "springs is NULL but spring_count is %u", in->spring_count);
    if (in->pin_count && !in->pins)
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "pins is NULL but pin_count is %u",
                    in->pin_count);
    if (!(isfinite(in->stiffness) && in->stiffness > 0.0f))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "stiffness is %g N/m; it must be finite and > 0", (double)in->stiffness);
    if (!(isfinite(in->shear_stiffness) && in->shear_stiffness >= 0.0f))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "shear_stiffness is %g N/m; it must be finite and >= 0",
                    (double)in->shear_stiffness);
    if (!(isfinite(in->bend_stiffness) && in->bend_stiffness >= 0.0f))
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "bend_stiffness is %g N/m; it must be finite and >= 0",
                    (double)in->bend_stiffness);
    for (uint32_t v = 0; v < n; ++v) {
        const float *p = in->positions + 3 * (size_t)v;
        if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])))
            return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "vertex %u has a non-finite position (%g, %g, %g)", v, (double)p[0],
                        (double)p[1], (double)p[2]);
    }
    for (uint32_t f = 0; f < in->quad_count; ++f) {
        const uint32_t *q = in->quads + 4 * (size_t)f;
        /* The corners of a quad ahead (range-checked here before it is read):
         * corners at random in a scattered mesh. */
        if (f + RBC_PREFETCH_AHEAD < in->quad_count)
            for (int k = 0; k < 4; ++k) {
                const uint32_t v = q[4 * RBC_PREFETCH_AHEAD + k];
                if (v < n) RBC_PREFETCH(&in->positions[3 * (size_t)v]);
            }
        for (int k = 0; k < 4; ++k) {
            if (q[k] >= n)
                return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                            "quad %u: corner %d is vertex %u, out of range (vertex_count %u)", f,
                            k, q[k], n);
            for (int l = 0; l < k; ++l)
                if (q[l] == q[k])
                    return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                                "quad %u repeats vertex %u (corners %d and %d)", f, q[k], l, k);
        }
        double longest2 = 0.0; /* squared, m^2: no square root per quad */
        for (int k = 0; k < 4; ++k) {
            double len2 = dist3_sq(in->positions, q[k], q[(k + 1) & 3]);
            if (len2 == 0.0)
                return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                            "quad %u is degenerate: vertices %u and %u coincide", f, q[k],
                            q[(k + 1) & 3]);
            if (len2 > longest2) longest2 = len2;
        }
        /* Zero area up to float rounding of the coordinates (relative 1e-6 of the
         * square of the longest edge): collinear or folded-flat corners. */
        double area2 = 0.25 * diag_cross_sq(in->positions, q);
        if (!(area2 > 1e-12 * longest2 * longest2))
            return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                        "quad %u is degenerate: area %g m^2 for an edge of %g m", f,
                        sqrt(area2), sqrt(longest2));
    }
    for (uint32_t s = 0; s < in->spring_count; ++s) {
        uint32_t a = in->springs[2 * (size_t)s], b = in->springs[2 * (size_t)s + 1];
        if (a >= n || b >= n)
            return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                        "spring %u joins vertices %u and %u; vertex_count is %u", s, a, b, n);
        if (a == b)
            return rbc_fail(err, errlen, RBC_ERR_BAD_MESH, "spring %u joins vertex %u to itself", s,
                        a);
    }
    for (uint32_t k = 0; k < in->pin_count; ++k)
        if (in->pins[k] >= n)
            return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "pin %u is vertex %u, out of range (vertex_count %u)", k, in->pins[k], n);
    if (in->masses) {
        for (uint32_t v = 0; v < n; ++v)
            if (!(isfinite(in->masses[v]) && in->masses[v] > 0.0f))
                return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                            "vertex %u has mass %g kg; it must be finite and > 0", v,
                            (double)in->masses[v]);
    } else if (in->density != 0.0f) {
        if (!(isfinite(in->density) && in->density > 0.0f))
            return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "density is %g kg/m^2; it must be finite and >= 0", (double)in->density);
    } else if (!(isfinite(in->vertex_mass) && in->vertex_mass > 0.0f)) {
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "vertex_mass is %g kg; it must be finite and > 0", (double)in->vertex_mass);
    }
    return RBC_OK;
}

/* Every array of the topology, for allocation and release in one place. */
#define TOPO_ARRAYS(X)                                                                   \
    X(to_internal, uint32_t, n) X(to_host, uint32_t, n) X(rest_x, float, n)              \
    X(rest_y, float, n) X(rest_z, float, n) X(mass, float, n) X(ksum, float, n)           \
    X(pinned_at_rest, uint8_t, n) X(sa, uint32_t, ns) X(sb, uint32_t, ns)                 \
    X(rest_len, float, ns) X(stiff, float, ns) X(ux, float, ns) X(uy, float, ns)          \
    X(uz, float, ns) X(he_a, uint32_t, ns) X(he_b, uint32_t, ns)                          \
    X(adj_start, uint32_t, (size_t)n + 1) X(adj_nbr, uint32_t, 2 * (size_t)ns)           \
    X(adj_k, float, 2 * (size_t)ns)

void rbc_topology_free(rbc_topology *t, const rbc_allocator *a) {
    size_t n = t->n, ns = t->ns;
    (void)n;
    (void)ns;
#define FREE_ONE(name, type, count) rbc_mem_free(a, t->name, rbc_mul_size(count, sizeof(type)));
    TOPO_ARRAYS(FREE_ONE)
#undef FREE_ONE
    memset(t, 0, sizeof *t);
}

#define NONE UINT32_MAX

/* Scratch used only while building, released in one place. */
typedef struct build_scratch {
    size_t n, nq, maxd, nbend_cap, nbend, nkeys;
    uint32_t *vq_start;   /* [n+1] quad corners at each vertex: vq[vq_start[v] ..] */
    uint32_t *vq;         /* [4 nq] corner as 4 f + k */
    uint32_t *quad_nbr;   /* [4 nq] quad across edge k (corners k, k+1), or NONE */
    uint64_t *bend;       /* [nbend_cap] bend springs, host (lo << 32 | hi) */
    uint64_t *items;      /* [2 maxd] fan scratch */
    uint32_t *fan;        /* [10 maxd] fan scratch */
    uint32_t *bstart;     /* [n+1] spring keys bucketed by their lower host vertex */
    uint32_t *fill;       /* [n] */
    uint64_t *entries;    /* [nkeys] (upper host vertex << 32 | stiffness bits) */
    uint8_t *color;       /* [n] */
} build_scratch;

static void scratch_free(build_scratch *s, const rbc_allocator *a) {
    rbc_mem_free(a, s->vq_start, rbc_mul_size(s->n + 1, 4));
    rbc_mem_free(a, s->vq, rbc_mul_size(s->nq, 16));
    rbc_mem_free(a, s->quad_nbr, rbc_mul_size(s->nq, 16));
    rbc_mem_free(a, s->bend, rbc_mul_size(s->nbend_cap, 8));
    rbc_mem_free(a, s->items, rbc_mul_size(s->maxd, 16));
    rbc_mem_free(a, s->fan, rbc_mul_size(s->maxd, 40));
    rbc_mem_free(a, s->bstart, rbc_mul_size(s->n + 1, 4));
    rbc_mem_free(a, s->fill, rbc_mul_size(s->n, 4));
    rbc_mem_free(a, s->entries, rbc_mul_size(s->nkeys, 8));
    rbc_mem_free(a, s->color, s->n);
    memset(s, 0, sizeof *s);
}

static int cmp_u64(const void *x, const void *y) {
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

/* The few keys of one vertex: insertion sort for the usual handful, qsort beyond
 * (a fan of hundreds of quads stays O(d log d)). */
static void sort_u64(uint64_t *v, size_t m) {
    if (m > 32) {
        qsort(v, m, sizeof *v, cmp_u64);
        return;
    }
    for (size_t i = 1; i < m; ++i) {
        uint64_t x = v[i];
        size_t j = i;
        for (; j && v[j - 1] > x; --j) v[j] = v[j - 1];
        v[j] = x;
    }
}

static uint32_t float_bits(float x) {
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static float bits_float(uint32_t u) {
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* Corners at each vertex (CSR), and the largest count. */
static void build_vertex_quads(const rbc_mesh_input *in, build_scratch *s) {
    const uint32_t n = in->vertex_count;
    for (size_t c = 0; c < 4 * (size_t)in->quad_count; ++c) s->vq_start[in->quads[c] + 1]++;
    s->maxd = 1;
    for (uint32_t v = 0; v < n; ++v) {
        if (s->vq_start[v + 1] > s->maxd) s->maxd = s->vq_start[v + 1];
        s->vq_start[v + 1] += s->vq_start[v];
    }
    memcpy(s->fill, s->vq_start, (size_t)n * 4);
    for (size_t c = 0; c < 4 * (size_t)in->quad_count; ++c)
        s->vq[s->fill[in->quads[c]]++] = (uint32_t)c;
}

/* Going around each vertex b. Each quad at b is a link between its two edges at b
 * (to the corners after and before b); each edge (b, x) is a node with as many
 * links as quads share it: 1 on the boundary, 2 inside, 3+ where the mesh is
 * non-manifold. Going around b through its quads is walking this small graph.
 *
 * Records, when asked, the quad across every manifold edge (s->quad_nbr) and the
 * bend springs (s->bend): for every node f with two links, the nodes e and g at the
 * far ends of its links are two quads apart on that side; they make a spring unless
 * one of e, f, g is non-manifold (the walk stops there), e = g, or the other side is
 * a single quad (e's other link reaches g: a valence-3 fan). Around an interior
 * valence-4 vertex e and g are two apart both ways: the pair is kept from the middle
 * with the lower node number only. */
static void walk_fans(const rbc_mesh_input *in, build_scratch *s, int want_nbr, int want_bend) {
    const uint32_t n = in->vertex_count;
    const uint32_t *Q = in->quads;
    const size_t m2 = 2 * s->maxd;
    uint64_t *items = s->items;            /* (x << 32 | item), item = 2 link + side */
    uint32_t *node_of = s->fan;            /* [item] the node of its edge */
    uint32_t *node_x = s->fan + m2;        /* [node] the far vertex x of edge (b, x) */
    uint32_t *node_cnt = s->fan + 2 * m2;  /* [node] links (quads) at that edge */
    uint32_t *node_it = s->fan + 3 * m2;   /* [2 node] its first two items */
    size_t nbend = 0;
    for (uint32_t b = 0; b < n; ++b) {
        const uint32_t s0 = s->vq_start[b], d = s->vq_start[b + 1] - s0;
        for (uint32_t l = 0; l < d; ++l) {
            uint32_t c = s->vq[s0 + l], k = c & 3;
            const uint32_t *q = Q + (c & ~3u);
            items[2 * l] = (uint64_t)q[(k + 1) & 3] << 32 | (2 * l);
            items[2 * l + 1] = (uint64_t)q[(k + 3) & 3] << 32 | (2 * l + 1);
        }
        sort_u64(items, 2 * (size_t)d);
        uint32_t nn = 0;
        for (uint32_t t = 0; t < 2 * d; ++t) {
            uint32_t x = (uint32_t)(items[t] >> 32), it = (uint32_t)items[t];
            if (nn == 0 || node_x[nn - 1] != x) {
                node_x[nn] = x;
                node_cnt[nn++] = 0;
            }
            uint32_t g = nn - 1;
            if (node_cnt[g] < 2) node_it[2 * g + node_cnt[g]] = it;
            node_cnt[g]++;
            node_of[it] = g;
        }
        if (want_nbr)
            for (uint32_t g = 0; g < nn; ++g) {
                if (node_cnt[g] != 2 || node_x[g] < b) continue; /* once per edge */
                uint32_t c1 = s->vq[s0 + (node_it[2 * g] >> 1)];
                uint32_t c2 = s->vq[s0 + (node_it[2 * g + 1] >> 1)];
                /* Side 0 (after b) is edge k of the quad, side 1 edge k-1. */
                uint32_t e1 = (node_it[2 * g] & 1) ? (c1 + 3) & 3 : c1 & 3;
                uint32_t e2 = (node_it[2 * g + 1] & 1) ? (c2 + 3) & 3 : c2 & 3;
                s->quad_nbr[(c1 & ~3u) + e1] = c2 >> 2;
                s->quad_nbr[(c2 & ~3u) + e2] = c1 >> 2;
            }
        if (want_bend)
            for (uint32_t f = 0; f < nn; ++f) {
                if (node_cnt[f] != 2) continue;
                const uint32_t i1 = node_it[2 * f], i2 = node_it[2 * f + 1];
                const uint32_t e = node_of[i1 ^ 1], g = node_of[i2 ^ 1];
                if (e == g || node_cnt[e] > 2 || node_cnt[g] > 2) continue;
                if (node_cnt[e] == 2) {
                    uint32_t io = (node_it[2 * e] >> 1) == (i1 >> 1) ? node_it[2 * e + 1]
                                                                      : node_it[2 * e];
                    uint32_t h = node_of[io ^ 1];
                    if (h == g) continue; /* the other side is a single quad */
                    if (node_cnt[h] == 2) {
                        uint32_t ho = (node_it[2 * h] >> 1) == (io >> 1) ? node_it[2 * h + 1]
                                                                          : node_it[2 * h];
                        if (node_of[ho ^ 1] == g && h < f) continue; /* 4-fan: once */
                    }
                }
                uint64_t xa = node_x[e], xc = node_x[g];
                s->bend[nbend++] = xa < xc ? (xa << 32 | xc) : (xc << 32 | xa);
            }
    }
    if (want_bend) s->nbend = nbend;
}

/* Every spring key once, with its stiffness: counted into the bucket of its lower
 * host vertex (scatter 0), then written there (scatter 1). */
static void put_key(build_scratch *s, uint32_t i, uint32_t j, uint32_t kbits, int scatter) {
    if (i > j) {
        uint32_t t = i;
        i = j;
        j = t;
    }
    if (scatter) s->entries[s->fill[i]++] = (uint64_t)j << 32 | kbits;
    else s->bstart[i + 1]++;
}

/* The lines put_key will write for the edges of the quad `ahead` quads on: the
 * count (scatter 0), or the fill pointer (2 ahead) and then the entry it points at
 * (1 ahead), each at random in a scattered mesh. */
static void prefetch_quad_keys(const rbc_mesh_input *in, const build_scratch *s, uint32_t f,
                               int scatter) {
    const uint32_t D = RBC_PREFETCH_AHEAD;
    for (uint32_t a = 1; a <= (scatter ? 2u : 1u); ++a) {
        if (f + a * D >= in->quad_count) continue;
        const uint32_t *q = in->quads + 4 * ((size_t)f + a * D);
        for (int k = 0; k < 4; ++k) {
            const uint32_t i = q[k] < q[(k + 1) & 3] ? q[k] : q[(k + 1) & 3];
            if (!scatter) RBC_PREFETCH_W(&s->bstart[i + 1]);
            else if (a == 2) RBC_PREFETCH_W(&s->fill[i]);
            else RBC_PREFETCH_W(&s->entries[s->fill[i]]);
        }
    }
}

static void emit_keys(const rbc_mesh_input *in, build_scratch *s, int scatter) {
    const uint32_t ks = float_bits(in->stiffness);
    for (uint32_t f = 0; f < in->quad_count; ++f) {
        const uint32_t *q = in->quads + 4 * (size_t)f;
        prefetch_quad_keys(in, s, f, scatter);
        for (int k = 0; k < 4; ++k) /* an edge of two quads from the lower one only */
            if (!s->quad_nbr || s->quad_nbr[4 * (size_t)f + k] == NONE ||
                s->quad_nbr[4 * (size_t)f + k] > f)
                put_key(s, q[k], q[(k + 1) & 3], ks, scatter);
    }
    for (uint32_t e = 0; e < in->spring_count; ++e)
        put_key(s, in->springs[2 * (size_t)e], in->springs[2 * (size_t)e + 1], ks, scatter);
    if (in->shear_stiffness > 0.0f) {
        const uint32_t kh = float_bits(in->shear_stiffness);
        for (uint32_t f = 0; f < in->quad_count; ++f) {
            const uint32_t *q = in->quads + 4 * (size_t)f;
            put_key(s, q[0], q[2], kh, scatter);
            put_key(s, q[1], q[3], kh, scatter);
        }
    }
    const uint32_t kb = float_bits(in->bend_stiffness);
    for (size_t k = 0; k < s->nbend; ++k)
        put_key(s, (uint32_t)(s->bend[k] >> 32), (uint32_t)s->bend[k], kb, scatter);
}


/* Whether the host order is far from local: the mean |v - w| over the springs above
 * 4 sqrt(n) + 16 (a grid in row order has about sqrt(n) / 2; a shuffled mesh n / 3). */
static int host_order_scattered(uint32_t n, const uint32_t *adj_start, const uint32_t *adj) {
    if (n < 1024) return 0;
    double sum = 0.0;
    uint64_t count = 0;
    for (uint32_t v = 0; v < n; ++v)
        for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k) {
            uint32_t w = adj[k];
            sum += w > v ? (double)(w - v) : (double)(v - w);
            ++count;
        }
    return count && sum / (double)count > 4.0 * sqrt((double)n) + 16.0;
}

/* 10 bits of x spread to every third bit. */
static uint32_t spread3(uint32_t x) {
    x &= 0x3FFu;
    x = (x | (x << 16)) & 0x030000FFu;
    x = (x | (x << 8)) & 0x0300F00Fu;
    x = (x | (x << 4)) & 0x030C30C3u;
    x = (x | (x << 2)) & 0x09249249u;
    return x;
}

/* order[r] (low 32 bits) = the r-th vertex by the Morton code of its position in the
 * bounding box (10 bits per axis), the host index breaking ties: deterministic. The
 * caller places each vertex in its color's range in this order. A stable radix sort
 * on the 30-bit code, 3 passes of 10 bits from host order (ties stay in host order,
 * as a sort of code << 32 | v would put them): O(n), where qsort's comparisons were a
 * third of a 1M-vertex irregular mesh's creation. tmp: n entries. */
static void morton_order(uint32_t n, const float *P, uint64_t *order, uint64_t *tmp) {
    float lo[3] = {P[0], P[1], P[2]}, hi[3] = {P[0], P[1], P[2]};
    for (uint32_t v = 0; v < n; ++v)
        for (int a = 0; a < 3; ++a) {
            float x = P[3 * (size_t)v + a];
            if (x < lo[a]) lo[a] = x;
            if (x > hi[a]) hi[a] = x;
        }
    double scale[3];
    for (int a = 0; a < 3; ++a)
        scale[a] = hi[a] > lo[a] ? 1023.0 / ((double)hi[a] - lo[a]) : 0.0;
    for (uint32_t v = 0; v < n; ++v) {
        uint32_t code = 0;
        for (int a = 0; a < 3; ++a) {
            double q = ((double)P[3 * (size_t)v + a] - lo[a]) * scale[a];
            code |= spread3((uint32_t)(q < 0.0 ? 0.0 : q > 1023.0 ? 1023.0 : q)) << a;
        }
        order[v] = ((uint64_t)code << 32) | v;
    }
    uint64_t *src = order, *dst = tmp;
    for (int pass = 0; pass < 3; ++pass) {
        const int shift = 32 + 10 * pass;
        uint32_t count[1025] = {0};
        for (uint32_t r = 0; r < n; ++r) count[((src[r] >> shift) & 1023u) + 1]++;
        for (uint32_t b = 0; b < 1024; ++b) count[b + 1] += count[b];
        for (uint32_t r = 0; r < n; ++r) dst[count[(src[r] >> shift) & 1023u]++] = src[r];
        uint64_t *t = src;
        src = dst, dst = t;
    }
    if (src != order) memcpy(order, src, sizeof *order * n); /* 3 passes end in tmp */
}

/* Within each window of RBC_DEGREE_WINDOW consecutive particles of a color (in Morton
 * order: a patch of the surface), particles of equal degree are put together, lower
 * degrees first, Morton order otherwise kept (stable). The sliced ELLPACK sweep
 * (ell.c) then pads each chunk only to its own largest degree: an irregular mesh of
 * valences 3 to 8 does about its mean degree of slots per particle instead of 8. The
 * window keeps a chunk's neighbours within a patch (locality). */
enum { RBC_DEGREE_WINDOW = 1024 };

static void group_by_degree(rbc_topology *t, const uint32_t *hadj_start) {
    for (uint32_t c = 0; c < t->ncolors; ++c)
        for (uint32_t w = t->color_start[c]; w < t->color_start[c + 1]; w += RBC_DEGREE_WINDOW) {
            uint32_t end = t->color_start[c + 1] - w < RBC_DEGREE_WINDOW
                               ? t->color_start[c + 1]
                               : w + RBC_DEGREE_WINDOW;
            /* A stable counting sort by degree (degrees past 63 share the last bin). */
            uint32_t count[65] = {0}, tmp[RBC_DEGREE_WINDOW];
            for (uint32_t i = w; i < end; ++i) {
                uint32_t v = t->to_host[i], d = hadj_start[v + 1] - hadj_start[v];
                if (i + RBC_PREFETCH_AHEAD < end) /* host vertices at random */
                    RBC_PREFETCH(&hadj_start[t->to_host[i + RBC_PREFETCH_AHEAD]]);
                count[(d < 63 ? d : 63) + 1]++;
            }
            for (uint32_t b = 0; b < 64; ++b) count[b + 1] += count[b];
            for (uint32_t i = w; i < end; ++i) {
                uint32_t v = t->to_host[i], d = hadj_start[v + 1] - hadj_start[v];
                tmp[count[d < 63 ? d : 63]++] = v;
            }
            memcpy(t->to_host + w, tmp, sizeof(uint32_t) * (end - w));
        }
}

static int32_t topology_oom(char *err, size_t errlen) {
    return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory building the topology");
}

/* Step 1 (and the coloring's lattice try): the quads around each vertex and the
 * quad across each edge; with want_bend the bend springs too (at most one per quad at
 * a vertex, so 4 nq bound them). 0, or -1 out of memory. */
static int find_quad_neighbours(const rbc_mesh_input *in, const rbc_allocator *a,
                                build_scratch *s, int want_bend) {
    const size_t nq = in->quad_count;
    s->vq = rbc_mem_alloc(a, rbc_mul_size(nq, 16));
    s->quad_nbr = rbc_mem_alloc(a, rbc_mul_size(nq, 16));
    if (!s->vq || !s->quad_nbr) return -1;
    memset(s->quad_nbr, 0xFF, nq * 16);
    build_vertex_quads(in, s);
    s->items = rbc_mem_alloc(a, rbc_mul_size(s->maxd, 16));
    s->fan = rbc_mem_alloc(a, rbc_mul_size(s->maxd, 40));
    if (!s->items || !s->fan) return -1;
    if (want_bend) {
        s->nbend_cap = 4 * nq;
        if (!(s->bend = rbc_mem_alloc(a, rbc_mul_size(s->nbend_cap, 8)))) return -1;
    }
    walk_fans(in, s, 1, want_bend);
    return 0;
}

/* Step 2, unique springs: every key bucketed by its lower host vertex (a counting
 * sort, O(n + keys)), each bucket sorted by (upper vertex, stiffness bits) and cut to
 * one entry per upper vertex: the last, whose stiffness is the largest (non-negative
 * floats order as their bits). */
static int32_t unique_springs(const rbc_mesh_input *in, const rbc_allocator *a, build_scratch *s,
                              uint32_t *out_ns, char *err, size_t errlen) {
    const uint32_t n = in->vertex_count;
    const size_t nq = in->quad_count;
    const size_t most_keys = 4 * nq + in->spring_count + s->nbend +
                             (in->shear_stiffness > 0.0f ? 2 * nq : 0);
    if (most_keys > UINT32_MAX / 2) /* 32-bit counts and 2 ns adjacency slots */
        return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "too many springs (up to %zu; at most %u)", most_keys, UINT32_MAX / 2);
    s->bstart = rbc_mem_alloc(a, rbc_mul_size((size_t)n + 1, 4));
    if (!s->bstart) return topology_oom(err, errlen);
    emit_keys(in, s, 0);
    for (uint32_t v = 0; v < n; ++v) s->bstart[v + 1] += s->bstart[v];
    s->nkeys = s->bstart[n];
    if (!(s->entries = rbc_mem_alloc(a, rbc_mul_size(s->nkeys, 8)))) return topology_oom(err, errlen);
    memcpy(s->fill, s->bstart, (size_t)n * 4);
    emit_keys(in, s, 1);
    uint32_t ns = 0;
    for (uint32_t v = 0, r = 0; v < n; ++v) {
        const uint32_t end = s->bstart[v + 1];
        sort_u64(s->entries + r, end - r);
        s->bstart[v] = ns;
        for (; r < end; ++r)
            if (r + 1 == end || (s->entries[r] >> 32) != (s->entries[r + 1] >> 32))
                s->entries[ns++] = s->entries[r];
    }
    s->bstart[n] = ns;
    *out_ns = ns;
    return RBC_OK;
}

/* Step 3: the topology's arrays. Its adjacency arrays hold the host-order CSR of the
 * spring graph for the coloring first (so no second copy is faulted in), the internal
 * one after (step 8). */
static int32_t alloc_topology(rbc_topology *t, const rbc_allocator *a, const build_scratch *s,
                              uint32_t n, uint32_t ns, char *err, size_t errlen) {
    t->n = n;
    t->ns = ns;
    int ok = 1;
    size_t bytes = 0;
#define ALLOC_ONE(name, type, count) RBC_ALLOC_ARRAY(a, t->name, count, type, ok, bytes);
    TOPO_ARRAYS(ALLOC_ONE)
#undef ALLOC_ONE
    if (!ok) return rbc_fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %u particles", n);
    t->bytes = bytes;
    uint32_t *hadj_start = t->adj_start, *hadj = t->adj_nbr;
    /* The upper ends w are at random in a scattered mesh: their count, fill pointer
     * and slot are asked for ahead (the entries are read in order). */
    const uint32_t D = RBC_PREFETCH_AHEAD, nk = s->bstart[n];
    for (uint32_t v = 0; v < n; ++v)
        for (uint32_t k = s->bstart[v]; k < s->bstart[v + 1]; ++k) {
            if (k + D < nk) RBC_PREFETCH_W(&hadj_start[(uint32_t)(s->entries[k + D] >> 32) + 1]);
            hadj_start[v + 1]++;
            hadj_start[(uint32_t)(s->entries[k] >> 32) + 1]++;
        }
    for (uint32_t v = 0; v < n; ++v) hadj_start[v + 1] += hadj_start[v];
    memcpy(s->fill, hadj_start, (size_t)n * 4);
    for (uint32_t v = 0; v < n; ++v)
        for (uint32_t k = s->bstart[v]; k < s->bstart[v + 1]; ++k) {
            if (k + 2 * D < nk) RBC_PREFETCH_W(&s->fill[(uint32_t)(s->entries[k + 2 * D] >> 32)]);
            if (k + D < nk) RBC_PREFETCH_W(&hadj[s->fill[(uint32_t)(s->entries[k + D] >> 32)]]);
            uint32_t w = (uint32_t)(s->entries[k] >> 32);
            hadj[s->fill[v]++] = w;
            hadj[s->fill[w]++] = v;
        }
    return RBC_OK;
}

/* Step 4, coloring: red-black when the graph is bipartite; otherwise multicolor
 * (coloring.h), with the lattice try when the quads' neighbours are known. */
static int32_t color_springs(const rbc_mesh_input *in, const rbc_allocator *a, rbc_topology *t,
                             build_scratch *s, char *err, size_t errlen) {
    const uint32_t n = t->n, nq = in->quad_count;
    const uint32_t *hadj_start = t->adj_start, *hadj = t->adj_nbr;
    uint32_t bad_a = 0, bad_b = 0, ncolors = 0;
    rbc_color_method method = RBC_COLOR_METHOD_BIPARTITE;
    if (rbc_color_bipartite(n, hadj_start, hadj, s->color, s->fill, &bad_a, &bad_b) == 0) {
        ncolors = 1;
        for (uint32_t v = 0; v < n && ncolors == 1; ++v) ncolors += s->color[v];
    } else {
        /* Structural springs only: an odd loop; the lattice try needs the quads'
         * neighbours. */
        if (nq && !s->quad_nbr && find_quad_neighbours(in, a, s, 0) != 0)
            return topology_oom(err, errlen);
        rbc_color_input cg = {n, hadj_start, hadj, nq, in->quads, s->quad_nbr};
        uint32_t bad = 0;
        int cr = rbc_color_graph(&cg, RBC_MAX_COLORS, a, s->color, &ncolors, &bad, &method);
        if (cr == RBC_COLOR_NO_MEMORY)
            return topology_oom(err, errlen);
        if (cr != 0)
            return rbc_fail(err, errlen, RBC_ERR_BAD_MESH,
                            "vertex %u: its %u springs reach vertices of all %d colors; the "
                            "spring graph needs more than %d colors (too dense explicit springs?)",
                            bad, hadj_start[bad + 1] - hadj_start[bad], RBC_MAX_COLORS,
                            RBC_MAX_COLORS);
    }
    t->ncolors = ncolors;
    t->color_method = (uint32_t)method;
    return RBC_OK;
}

/* Step 6, color-contiguous order: color 0 first, then 1, ..., each in host order when
 * that order is already local (a grid's rows stay together, and lattice.c's path
 * needs exactly that), else by a Morton (Z-order) code of the rest position, so that a
 * sweep's neighbours sit close in memory whatever order the file had. *scattered: the
 * host order was not local. */
static int32_t internal_order(const float *P, const rbc_allocator *a, rbc_topology *t,
                              const build_scratch *s, int *scattered, char *err, size_t errlen) {
    const uint32_t n = t->n, ncolors = t->ncolors;
    uint32_t next[RBC_MAX_COLORS] = {0};
    for (uint32_t v = 0; v < n; ++v) next[s->color[v]]++;
    t->color_start[0] = 0;
    for (uint32_t c = 0; c < ncolors; ++c) {
        t->color_start[c + 1] = t->color_start[c] + next[c];
        next[c] = t->color_start[c];
    }
    uint64_t *order = NULL;
    *scattered = host_order_scattered(n, t->adj_start, t->adj_nbr);
    if (*scattered) {
        order = rbc_mem_alloc(a, rbc_mul_size(n, sizeof *order));
        uint64_t *tmp = order ? rbc_mem_alloc(a, rbc_mul_size(n, sizeof *order)) : NULL;
        if (!tmp) {
            rbc_mem_free(a, order, rbc_mul_size(n, sizeof *order));
            return topology_oom(err, errlen);
        }
        morton_order(n, P, order, tmp);
        rbc_mem_free(a, tmp, rbc_mul_size(n, sizeof *order));
    }
    for (uint32_t r = 0; r < n; ++r) {
        uint32_t v = order ? (uint32_t)order[r] : r;
        /* Morton order visits the host's vertices at random: their colors ahead. */
        if (order && r + RBC_PREFETCH_AHEAD < n)
            RBC_PREFETCH(&s->color[(uint32_t)order[r + RBC_PREFETCH_AHEAD]]);
        t->to_host[next[s->color[v]]++] = v;
    }
    if (order) group_by_degree(t, t->adj_start);
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t v = t->to_host[i];
        if (*scattered && i + RBC_PREFETCH_AHEAD < n)
            RBC_PREFETCH(&P[3 * (size_t)t->to_host[i + RBC_PREFETCH_AHEAD]]);
        t->to_internal[v] = i;
        t->rest_x[i] = P[3 * (size_t)v];
        t->rest_y[i] = P[3 * (size_t)v + 1];
        t->rest_z[i] = P[3 * (size_t)v + 2];
    }
    rbc_mem_free(a, order, rbc_mul_size(n, sizeof *order));
    return RBC_OK;
}

/* Step 7, masses: given, lumped from areal density (a quarter of each quad's area to
 * each corner), or uniform; and the pins at rest. */
static int32_t lump_masses(const rbc_mesh_input *in, rbc_topology *t, char *err, size_t errlen) {
    const uint32_t n = t->n;
    const float *P = in->positions;
    if (in->masses) {
        for (uint32_t v = 0; v < n; ++v) t->mass[t->to_internal[v]] = in->masses[v];
    } else if (in->density > 0.0f) {
        for (uint32_t f = 0; f < in->quad_count; ++f) {
            const uint32_t *q = in->quads + 4 * (size_t)f;
            float m = (float)(0.25 * in->density * (0.5 * sqrt(diag_cross_sq(P, q))));
            for (int k = 0; k < 4; ++k) t->mass[t->to_internal[q[k]]] += m;
        }
        for (uint32_t v = 0; v < n; ++v) {
            float m = t->mass[t->to_internal[v]];
            if (!(m > 0.0f) || !isfinite(m))
                return rbc_fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                                "vertex %u gets mass %g kg from the density (it belongs to no "
                                "quad of positive area); give masses or vertex_mass",
                                v, (double)m);
        }
    } else {
        for (uint32_t i = 0; i < n; ++i) t->mass[i] = in->vertex_mass;
    }
    for (uint32_t k = 0; k < in->pin_count; ++k) t->pinned_at_rest[t->to_internal[in->pins[k]]] = 1;
    return RBC_OK;
}

/* Step 8, springs (sorted by host (lower, upper) vertex; for a scattered host order,
 * by the internal index of the lower host vertex, so that the local step walks the
 * particles in memory order instead of at random) with their own stiffness, and the
 * internal CSR adjacency with one slot per spring end, built where the host adjacency
 * was (it has served: coloring, the order). Positions are read from the internal
 * copies (the same floats as the input, placed in step 6): i runs in memory order and
 * j is near it, where the input's of a scattered mesh were two cache misses per
 * spring. */
static void internal_springs(rbc_topology *t, build_scratch *s, int scattered) {
    const uint32_t n = t->n, ns = t->ns;
    memset(t->adj_start, 0, ((size_t)n + 1) * 4);
    uint32_t k = 0;
    const uint32_t D = RBC_PREFETCH_AHEAD;
    for (uint32_t r = 0; r < n; ++r) {
        const uint32_t hi = scattered ? t->to_host[r] : r;
        if (scattered) {
            /* Three chained reads per particle (its bucket's bounds, the bucket, the
             * upper ends' internal indices), each at random in a scattered mesh:
             * asked for 3D, 2D and D particles ahead, each after the one before it
             * has had time to arrive. */
            if (r + 3 * D < n) RBC_PREFETCH(&s->bstart[t->to_host[r + 3 * D]]);
            if (r + 2 * D < n) {
                const uint32_t h = t->to_host[r + 2 * D];
                RBC_PREFETCH(&s->entries[s->bstart[h]]);
                RBC_PREFETCH(&s->entries[s->bstart[h + 1]] - 1);
            }
            if (r + D < n) {
                const uint32_t h = t->to_host[r + D];
                for (uint32_t e = s->bstart[h]; e < s->bstart[h + 1]; ++e)
                    RBC_PREFETCH(&t->to_internal[(uint32_t)(s->entries[e] >> 32)]);
            }
        }
        for (uint32_t e = s->bstart[hi]; e < s->bstart[hi + 1]; ++e, ++k) {
            uint32_t hj = (uint32_t)(s->entries[e] >> 32);
            uint32_t i = t->to_internal[hi], j = t->to_internal[hj];
            t->sa[k] = i;
            t->sb[k] = j;
            double dx = (double)t->rest_x[i] - t->rest_x[j], dy = (double)t->rest_y[i] - t->rest_y[j],
                   dz = (double)t->rest_z[i] - t->rest_z[j];
            double len = sqrt(dx * dx + dy * dy + dz * dz); /* dist3_sq's arithmetic */
            t->rest_len[k] = (float)len;
            t->stiff[k] = bits_float((uint32_t)s->entries[e]);
            if (len > 0.0) {
                t->ux[k] = (float)(dx / len);
                t->uy[k] = (float)(dy / len);
                t->uz[k] = (float)(dz / len);
            }
            t->adj_start[i + 1]++;
            t->adj_start[j + 1]++;
        }
    }
    for (uint32_t i = 0; i < n; ++i) t->adj_start[i + 1] += t->adj_start[i];
    memcpy(s->fill, t->adj_start, (size_t)n * 4);
    for (k = 0; k < ns; ++k) {
        uint32_t i = t->sa[k], j = t->sb[k];
        uint32_t si = s->fill[i]++, sj = s->fill[j]++;
        t->adj_nbr[si] = j;
        t->adj_k[si] = t->stiff[k];
        t->he_a[k] = si;
        t->adj_nbr[sj] = i;
        t->adj_k[sj] = t->stiff[k];
        t->he_b[k] = sj;
        t->ksum[i] += t->stiff[k];
        t->ksum[j] += t->stiff[k];
    }
}

int32_t rbc_topology_build(const rbc_mesh_input *in, const rbc_allocator *a, rbc_topology *out,
                           char *err, size_t errlen) {
    memset(out, 0, sizeof *out);
    int32_t rc = validate(in, err, errlen);
    if (rc != RBC_OK) return rc;
    const uint32_t n = in->vertex_count, nq = in->quad_count;
    const int want_bend = in->bend_stiffness > 0.0f && nq > 0;
    rbc_topology *t = out;
    build_scratch s;
    memset(&s, 0, sizeof s);
    s.n = n;
    s.nq = nq;
    /* Walking the quads around each vertex gives the bend springs and the quad
     * across each edge: the structural keys then skip shared edges the second time,
     * and a multicolor coloring (likely with shear, bend or explicit springs) tries
     * the lattice. */
    const int want_nbr = nq > 0 && (in->shear_stiffness > 0.0f || want_bend || in->spring_count);
    s.vq_start = rbc_mem_alloc(a, rbc_mul_size((size_t)n + 1, 4));
    s.fill = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    s.color = rbc_mem_alloc(a, n);
    uint32_t ns = 0;
    int scattered = 0;
    if (!s.vq_start || !s.fill || !s.color || (want_nbr && find_quad_neighbours(in, a, &s, want_bend)))
        rc = topology_oom(err, errlen);
    if (rc == RBC_OK) rc = unique_springs(in, a, &s, &ns, err, errlen);
    if (rc == RBC_OK) rc = alloc_topology(t, a, &s, n, ns, err, errlen);
    if (rc == RBC_OK) rc = color_springs(in, a, t, &s, err, errlen);
    if (rc == RBC_OK) rc = internal_order(in->positions, a, t, &s, &scattered, err, errlen);
    if (rc == RBC_OK) rc = lump_masses(in, t, err, errlen);
    if (rc == RBC_OK) internal_springs(t, &s, scattered);
    if (rc != RBC_OK) rbc_topology_free(t, a);
    scratch_free(&s, a);
    return rc;
}

int rbc_topology_break_spring(rbc_topology *t, uint32_t sp) {
    if (t->stiff[sp] == 0.0f) return 0;
    t->stiff[sp] = 0.0f;
    t->adj_k[t->he_a[sp]] = 0.0f;
    t->adj_k[t->he_b[sp]] = 0.0f;
    for (int e = 0; e < 2; ++e) {
        uint32_t i = e ? t->sb[sp] : t->sa[sp];
        float sum = 0.0f;
        for (uint32_t s = t->adj_start[i]; s < t->adj_start[i + 1]; ++s) sum += t->adj_k[s];
        t->ksum[i] = sum;
    }
    return 1;
}
