/* topology.c -- quad mesh -> particles and unique springs -> 2-coloring ->
 * color-contiguous particle order (Fig. 2 of the paper) -> CSR adjacency. */
#include "topology.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "../abi/rbcloth.h"
#include "coloring.h"

static int32_t fail(char *err, size_t errlen, int32_t code, const char *fmt, ...) {
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return code;
}

/* LSD radix sort of keys (i << 32 | j) with i, j < n, 16 bits a pass; the passes
 * over the upper 16 bits of each half are skipped when n <= 65536 (they are 0). */
static void radix_sort_u64(uint64_t *keys, uint64_t *tmp, size_t count, uint32_t n,
                           uint32_t *hist /* 65536 */) {
    for (unsigned shift = 0; shift < 64; shift += 16) {
        if ((shift == 16 || shift == 48) && n <= 65536) continue;
        memset(hist, 0, 65536 * sizeof *hist);
        for (size_t i = 0; i < count; ++i) hist[(keys[i] >> shift) & 0xFFFF]++;
        uint32_t sum = 0;
        for (size_t d = 0; d < 65536; ++d) {
            uint32_t c = hist[d];
            hist[d] = sum;
            sum += c;
        }
        for (size_t i = 0; i < count; ++i) tmp[hist[(keys[i] >> shift) & 0xFFFF]++] = keys[i];
        memcpy(keys, tmp, count * sizeof *keys);
    }
}

static double dist3(const float *p, uint32_t a, uint32_t b) {
    double dx = (double)p[3 * a] - p[3 * b], dy = (double)p[3 * a + 1] - p[3 * b + 1],
           dz = (double)p[3 * a + 2] - p[3 * b + 2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* Area of a (possibly non-planar) quad: half the norm of the diagonals' cross product. */
static double quad_area(const float *p, const uint32_t *q) {
    double d1[3], d2[3];
    for (int c = 0; c < 3; ++c) {
        d1[c] = (double)p[3 * q[2] + c] - p[3 * q[0] + c];
        d2[c] = (double)p[3 * q[3] + c] - p[3 * q[1] + c];
    }
    double cx = d1[1] * d2[2] - d1[2] * d2[1], cy = d1[2] * d2[0] - d1[0] * d2[2],
           cz = d1[0] * d2[1] - d1[1] * d2[0];
    return 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
}

static int32_t validate(const rbc_mesh_input *in, char *err, size_t errlen) {
    const uint32_t n = in->vertex_count;
    if (n == 0) return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "vertex_count is 0");
    if (!in->positions) return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "positions is NULL");
    if (in->quad_count && !in->quads)
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "quads is NULL but quad_count is %u",
                    in->quad_count);
    if (in->spring_count && !in->springs)
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "springs is NULL but spring_count is %u", in->spring_count);
    if (in->pin_count && !in->pins)
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "pins is NULL but pin_count is %u",
                    in->pin_count);
    if (!(isfinite(in->stiffness) && in->stiffness > 0.0f))
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                    "stiffness is %g N/m; it must be finite and > 0", (double)in->stiffness);
    for (uint32_t v = 0; v < n; ++v) {
        const float *p = in->positions + 3 * (size_t)v;
        if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])))
            return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "vertex %u has a non-finite position (%g, %g, %g)", v, (double)p[0],
                        (double)p[1], (double)p[2]);
    }
    for (uint32_t f = 0; f < in->quad_count; ++f) {
        const uint32_t *q = in->quads + 4 * (size_t)f;
        for (int k = 0; k < 4; ++k) {
            if (q[k] >= n)
                return fail(err, errlen, RBC_ERR_BAD_MESH,
                            "quad %u: corner %d is vertex %u, out of range (vertex_count %u)", f,
                            k, q[k], n);
            for (int l = 0; l < k; ++l)
                if (q[l] == q[k])
                    return fail(err, errlen, RBC_ERR_BAD_MESH,
                                "quad %u repeats vertex %u (corners %d and %d)", f, q[k], l, k);
        }
        double longest = 0.0;
        for (int k = 0; k < 4; ++k) {
            double len = dist3(in->positions, q[k], q[(k + 1) & 3]);
            if (len == 0.0)
                return fail(err, errlen, RBC_ERR_BAD_MESH,
                            "quad %u is degenerate: vertices %u and %u coincide", f, q[k],
                            q[(k + 1) & 3]);
            if (len > longest) longest = len;
        }
        /* Zero area up to float rounding of the coordinates (relative 1e-6 of the
         * square of the longest edge): collinear or folded-flat corners. */
        double area = quad_area(in->positions, q);
        if (!(area > 1e-6 * longest * longest))
            return fail(err, errlen, RBC_ERR_BAD_MESH,
                        "quad %u is degenerate: area %g m^2 for an edge of %g m", f, area,
                        longest);
    }
    for (uint32_t s = 0; s < in->spring_count; ++s) {
        uint32_t a = in->springs[2 * (size_t)s], b = in->springs[2 * (size_t)s + 1];
        if (a >= n || b >= n)
            return fail(err, errlen, RBC_ERR_BAD_MESH,
                        "spring %u joins vertices %u and %u; vertex_count is %u", s, a, b, n);
        if (a == b)
            return fail(err, errlen, RBC_ERR_BAD_MESH, "spring %u joins vertex %u to itself", s,
                        a);
    }
    for (uint32_t k = 0; k < in->pin_count; ++k)
        if (in->pins[k] >= n)
            return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "pin %u is vertex %u, out of range (vertex_count %u)", k, in->pins[k], n);
    if (in->masses) {
        for (uint32_t v = 0; v < n; ++v)
            if (!(isfinite(in->masses[v]) && in->masses[v] > 0.0f))
                return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                            "vertex %u has mass %g kg; it must be finite and > 0", v,
                            (double)in->masses[v]);
    } else if (in->density != 0.0f) {
        if (!(isfinite(in->density) && in->density > 0.0f))
            return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                        "density is %g kg/m^2; it must be finite and >= 0", (double)in->density);
    } else if (!(isfinite(in->vertex_mass) && in->vertex_mass > 0.0f)) {
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
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

/* Scratch used only while building. */
typedef struct build_scratch {
    uint64_t *keys, *tmp;
    uint32_t *hist;
    uint32_t *hadj_start, *hadj, *fill, *queue;
    uint8_t *color;
    size_t nkeys, n;
} build_scratch;

static void scratch_free(build_scratch *s, const rbc_allocator *a) {
    rbc_mem_free(a, s->keys, rbc_mul_size(s->nkeys, 8));
    rbc_mem_free(a, s->tmp, rbc_mul_size(s->nkeys, 8));
    rbc_mem_free(a, s->hist, 65536 * 4);
    rbc_mem_free(a, s->hadj_start, rbc_mul_size(s->n + 1, 4));
    rbc_mem_free(a, s->hadj, rbc_mul_size(s->nkeys, 8));
    rbc_mem_free(a, s->fill, rbc_mul_size(s->n, 4));
    rbc_mem_free(a, s->queue, rbc_mul_size(s->n, 4));
    rbc_mem_free(a, s->color, s->n);
}

int32_t rbc_topology_build(const rbc_mesh_input *in, const rbc_allocator *a, rbc_topology *out,
                           char *err, size_t errlen) {
    memset(out, 0, sizeof *out);
    int32_t rc = validate(in, err, errlen);
    if (rc != RBC_OK) return rc;

    const uint32_t n = in->vertex_count;
    const float *P = in->positions;
    build_scratch s;
    memset(&s, 0, sizeof s);
    s.n = n;
    s.nkeys = 4 * (size_t)in->quad_count + in->spring_count;
    s.keys = rbc_mem_alloc(a, rbc_mul_size(s.nkeys, 8));
    s.tmp = rbc_mem_alloc(a, rbc_mul_size(s.nkeys, 8));
    s.hist = rbc_mem_alloc(a, 65536 * 4);
    s.hadj_start = rbc_mem_alloc(a, rbc_mul_size((size_t)n + 1, 4));
    s.hadj = rbc_mem_alloc(a, rbc_mul_size(s.nkeys, 8));
    s.fill = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    s.queue = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    s.color = rbc_mem_alloc(a, n);
    if (!s.keys || !s.tmp || !s.hist || !s.hadj_start || !s.hadj || !s.fill || !s.queue ||
        !s.color) {
        scratch_free(&s, a);
        return fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory building the topology");
    }

    /* 1. Unique springs: every quad edge and extra spring as the key (min << 32 | max),
     * sorted; duplicates (edges shared by two quads) collapse to one spring. */
    size_t nk = 0;
    for (uint32_t f = 0; f < in->quad_count; ++f) {
        const uint32_t *q = in->quads + 4 * (size_t)f;
        for (int k = 0; k < 4; ++k) {
            uint64_t i = q[k], j = q[(k + 1) & 3];
            s.keys[nk++] = i < j ? (i << 32 | j) : (j << 32 | i);
        }
    }
    for (uint32_t e = 0; e < in->spring_count; ++e) {
        uint64_t i = in->springs[2 * (size_t)e], j = in->springs[2 * (size_t)e + 1];
        s.keys[nk++] = i < j ? (i << 32 | j) : (j << 32 | i);
    }
    radix_sort_u64(s.keys, s.tmp, nk, n, s.hist);
    size_t ns = 0;
    for (size_t k = 0; k < nk; ++k)
        if (ns == 0 || s.keys[k] != s.keys[ns - 1]) s.keys[ns++] = s.keys[k];
    if (ns > UINT32_MAX / 2) {
        scratch_free(&s, a);
        return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT, "too many springs (%zu)", ns);
    }

    /* 2. Host-order CSR of the spring graph, for coloring. */
    for (size_t k = 0; k < ns; ++k) {
        s.hadj_start[(uint32_t)(s.keys[k] >> 32) + 1]++;
        s.hadj_start[(uint32_t)s.keys[k] + 1]++;
    }
    for (uint32_t v = 0; v < n; ++v) s.hadj_start[v + 1] += s.hadj_start[v];
    memcpy(s.fill, s.hadj_start, (size_t)n * 4);
    for (size_t k = 0; k < ns; ++k) {
        uint32_t i = (uint32_t)(s.keys[k] >> 32), j = (uint32_t)s.keys[k];
        s.hadj[s.fill[i]++] = j;
        s.hadj[s.fill[j]++] = i;
    }

    /* 3. Red-black coloring. */
    uint32_t bad_a = 0, bad_b = 0;
    if (rbc_color_bipartite(n, s.hadj_start, s.hadj, s.color, s.queue, &bad_a, &bad_b) != 0) {
        scratch_free(&s, a);
        return fail(err, errlen, RBC_ERR_BAD_MESH,
                    "the spring graph is not bipartite (an odd cycle closes at the spring "
                    "between vertices %u and %u); two colors cannot separate it and "
                    "multicolor solving is not supported in this release",
                    bad_a, bad_b);
    }

    /* 4. Allocate the topology. */
    rbc_topology *t = out;
    t->n = n;
    t->ns = (uint32_t)ns;
    int ok = 1;
    size_t bytes = 0;
#define ALLOC_ONE(name, type, count)                                         \
    t->name = rbc_mem_alloc(a, rbc_mul_size(count, sizeof(type)));           \
    ok = ok && t->name;                                                      \
    bytes += rbc_mul_size(count, sizeof(type));
    TOPO_ARRAYS(ALLOC_ONE)
#undef ALLOC_ONE
    if (!ok) {
        rbc_topology_free(t, a);
        scratch_free(&s, a);
        return fail(err, errlen, RBC_ERR_OUT_OF_MEMORY, "out of memory for %u particles", n);
    }
    t->bytes = bytes;

    /* 5. Color-contiguous order: red particles first, then black, each in host order
     * (keeps a grid's rows together within a color for locality). */
    uint32_t count[2] = {0, 0};
    for (uint32_t v = 0; v < n; ++v) count[s.color[v]]++;
    t->ncolors = count[1] ? 2 : 1;
    t->color_start[0] = 0;
    t->color_start[1] = count[0];
    t->color_start[2] = n;
    uint32_t next[2] = {0, count[0]};
    for (uint32_t v = 0; v < n; ++v) {
        uint32_t i = next[s.color[v]]++;
        t->to_internal[v] = i;
        t->to_host[i] = v;
        t->rest_x[i] = P[3 * (size_t)v];
        t->rest_y[i] = P[3 * (size_t)v + 1];
        t->rest_z[i] = P[3 * (size_t)v + 2];
    }

    /* 6. Masses: given, lumped from areal density (a quarter of each quad's area to
     * each corner), or uniform. */
    if (in->masses) {
        for (uint32_t v = 0; v < n; ++v) t->mass[t->to_internal[v]] = in->masses[v];
    } else if (in->density > 0.0f) {
        for (uint32_t f = 0; f < in->quad_count; ++f) {
            const uint32_t *q = in->quads + 4 * (size_t)f;
            float m = (float)(0.25 * in->density * quad_area(P, q));
            for (int k = 0; k < 4; ++k) t->mass[t->to_internal[q[k]]] += m;
        }
        for (uint32_t v = 0; v < n; ++v)
            if (!(t->mass[t->to_internal[v]] > 0.0f) || !isfinite(t->mass[t->to_internal[v]])) {
                float m = t->mass[t->to_internal[v]];
                rbc_topology_free(t, a);
                scratch_free(&s, a);
                return fail(err, errlen, RBC_ERR_INVALID_ARGUMENT,
                            "vertex %u gets mass %g kg from the density (it belongs to no quad "
                            "of positive area); give masses or vertex_mass",
                            v, (double)m);
            }
    } else {
        for (uint32_t i = 0; i < n; ++i) t->mass[i] = in->vertex_mass;
    }
    for (uint32_t k = 0; k < in->pin_count; ++k) t->pinned_at_rest[t->to_internal[in->pins[k]]] = 1;

    /* 7. Springs and the internal CSR adjacency with one slot per spring end. */
    for (size_t k = 0; k < ns; ++k) {
        uint32_t hi = (uint32_t)(s.keys[k] >> 32), hj = (uint32_t)s.keys[k];
        uint32_t i = t->to_internal[hi], j = t->to_internal[hj];
        t->sa[k] = i;
        t->sb[k] = j;
        double len = dist3(P, hi, hj);
        t->rest_len[k] = (float)len;
        t->stiff[k] = in->stiffness;
        if (len > 0.0) {
            t->ux[k] = (float)(((double)P[3 * (size_t)hi] - P[3 * (size_t)hj]) / len);
            t->uy[k] = (float)(((double)P[3 * (size_t)hi + 1] - P[3 * (size_t)hj + 1]) / len);
            t->uz[k] = (float)(((double)P[3 * (size_t)hi + 2] - P[3 * (size_t)hj + 2]) / len);
        }
        t->adj_start[i + 1]++;
        t->adj_start[j + 1]++;
    }
    for (uint32_t i = 0; i < n; ++i) t->adj_start[i + 1] += t->adj_start[i];
    memcpy(s.fill, t->adj_start, (size_t)n * 4);
    for (size_t k = 0; k < ns; ++k) {
        uint32_t i = t->sa[k], j = t->sb[k];
        uint32_t si = s.fill[i]++, sj = s.fill[j]++;
        t->adj_nbr[si] = j;
        t->adj_k[si] = t->stiff[k];
        t->he_a[k] = si;
        t->adj_nbr[sj] = i;
        t->adj_k[sj] = t->stiff[k];
        t->he_b[k] = sj;
        t->ksum[i] += t->stiff[k];
        t->ksum[j] += t->stiff[k];
    }
    scratch_free(&s, a);
    return RBC_OK;
}
