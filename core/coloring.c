/* coloring.c -- red-black BFS, DSATUR, lattice coloring and class balancing; see
 * coloring.h for the policy. */
#include "coloring.h"

#include <string.h>

#include "prefetch.h"

#define NONE UINT32_MAX
#define UNCOLORED 0xFF

static inline unsigned lowest_bit(uint64_t x) { /* x != 0 */
#if defined(__GNUC__) || defined(__clang__)
    return (unsigned)__builtin_ctzll(x);
#else
    unsigned k = 0;
    while (!(x & 1)) x >>= 1, ++k;
    return k;
#endif
}

static inline uint64_t colors_below(uint32_t k) { /* bits 0 .. k-1, k <= 64 */
    return k >= 64 ? ~(uint64_t)0 : (((uint64_t)1 << k) - 1);
}

int rbc_color_bipartite(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                        uint8_t *color, uint32_t *queue, uint32_t *bad_a, uint32_t *bad_b) {
    memset(color, UNCOLORED, n);
    for (uint32_t root = 0; root < n; ++root) {
        if (color[root] != UNCOLORED) continue;
        /* Breadth-first from each uncolored vertex: a vertex at even distance from
         * the root is red (0), at odd distance black (1). */
        uint32_t head = 0, tail = 0;
        color[root] = 0;
        queue[tail++] = root;
        while (head < tail) {
            /* The queue holds the next vertices to visit: their adjacency, at random
             * in a scattered mesh, is asked for ahead (bounds 2 ahead of the list). */
            if (head + 2 * RBC_PREFETCH_AHEAD < tail)
                RBC_PREFETCH(&adj_start[queue[head + 2 * RBC_PREFETCH_AHEAD]]);
            if (head + RBC_PREFETCH_AHEAD < tail)
                RBC_PREFETCH(&adj[adj_start[queue[head + RBC_PREFETCH_AHEAD]]]);
            uint32_t v = queue[head++];
            uint8_t other = (uint8_t)(1 - color[v]);
            for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k) {
                uint32_t w = adj[k];
                if (color[w] == UNCOLORED) {
                    color[w] = other;
                    queue[tail++] = w;
                } else if (color[w] != other) {
                    *bad_a = v;
                    *bad_b = w;
                    return -1;
                }
            }
        }
    }
    return 0;
}

/* ------------------------------------------------------------------------- */
/* DSATUR                                                                    */
/* ------------------------------------------------------------------------- */

int rbc_color_dsatur(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                     uint32_t max_colors, const rbc_allocator *a, uint8_t *color,
                     uint32_t *bad_vertex) {
    if (max_colors > 64) max_colors = 64;
    /* used[v]: the colors of v's colored neighbors; sat[v] = popcount(used[v]) is
     * v's bucket. Buckets are doubly linked lists through nxt/prv. */
    uint64_t *used = rbc_mem_alloc(a, rbc_mul_size(n, 8));
    uint32_t *nxt = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    uint32_t *prv = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    uint8_t *sat = rbc_mem_alloc(a, n);
    int result = 0;
    if (!used || !nxt || !prv || !sat) {
        result = RBC_COLOR_NO_MEMORY;
        goto done;
    }
    uint32_t head[65];
    for (int s = 0; s < 65; ++s) head[s] = NONE;
    /* Bucket 0 holds every vertex, vertex 0 first: the first pick of each
     * connected component is its lowest-numbered vertex. */
    for (uint32_t v = 0; v < n; ++v) {
        prv[v] = v ? v - 1 : NONE;
        nxt[v] = v + 1 < n ? v + 1 : NONE;
    }
    if (n) head[0] = 0;
    memset(color, UNCOLORED, n);
    const uint64_t allowed = colors_below(max_colors);
    uint32_t top = 0, ncolors = 0;
    for (uint32_t done_count = 0; done_count < n; ++done_count) {
        while (head[top] == NONE) --top; /* an uncolored vertex is left */
        uint32_t v = head[top];
        head[top] = nxt[v];
        if (nxt[v] != NONE) prv[nxt[v]] = NONE;
        uint64_t free_colors = ~used[v] & allowed;
        if (!free_colors) {
            *bad_vertex = v;
            result = RBC_COLOR_TOO_MANY;
            goto done;
        }
        unsigned c = lowest_bit(free_colors);
        color[v] = (uint8_t)c;
        if (c + 1 > ncolors) ncolors = c + 1;
        const uint64_t bit = (uint64_t)1 << c;
        for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k) {
            uint32_t w = adj[k];
            if (color[w] != UNCOLORED || (used[w] & bit)) continue;
            used[w] |= bit;
            /* Unlink w from bucket sat[w], push it on bucket sat[w] + 1. */
            uint32_t s = sat[w];
            if (prv[w] != NONE) nxt[prv[w]] = nxt[w];
            else head[s] = nxt[w];
            if (nxt[w] != NONE) prv[nxt[w]] = prv[w];
            ++s;
            sat[w] = (uint8_t)s;
            prv[w] = NONE;
            nxt[w] = head[s];
            if (head[s] != NONE) prv[head[s]] = w;
            head[s] = w;
            if (s > top) top = s;
        }
    }
    result = (int)ncolors;
done:
    rbc_mem_free(a, used, rbc_mul_size(n, 8));
    rbc_mem_free(a, nxt, rbc_mul_size(n, 4));
    rbc_mem_free(a, prv, rbc_mul_size(n, 4));
    rbc_mem_free(a, sat, n);
    return result;
}

/* ------------------------------------------------------------------------- */
/* Lattice coloring                                                          */
/* ------------------------------------------------------------------------- */

/* Coordinates are kept modulo 840 = lcm(1..8): every candidate k <= 8 divides it, so
 * (a i + b j) mod k is exact and nothing overflows however far the walk goes. */
#define LAT_M 840u
#define LAT_MAX_K 8u
#define LAT_MAX_OFFSETS 256u
#define LAT_HASH 1024u /* slots, a power of two > 2 * LAT_MAX_OFFSETS */

/* x, y < LAT_M */
static inline uint32_t lat_add(uint32_t x, uint32_t y) {
    uint32_t r = x + y;
    return r >= LAT_M ? r - LAT_M : r;
}
static inline uint32_t lat_sub(uint32_t x, uint32_t y) { return lat_add(x, LAT_M - y); }

/* A lattice point (i, j), both < LAT_M, packed as i | j << 16; NONE = none yet. */
static inline uint32_t pt_add(uint32_t p, uint32_t d) {
    return lat_add(p & 0xFFFF, d & 0xFFFF) | lat_add(p >> 16, d >> 16) << 16;
}
static inline uint32_t pt_sub(uint32_t p, uint32_t d) {
    return lat_sub(p & 0xFFFF, d & 0xFFFF) | lat_sub(p >> 16, d >> 16) << 16;
}

int rbc_color_lattice(const rbc_color_input *g, uint32_t max_k, const rbc_allocator *a,
                      uint8_t *color, int *seamless) {
    const uint32_t n = g->n, nq = g->quad_count;
    if (seamless) *seamless = 0;
    if (!g->quads || !g->quad_nbr || nq == 0) return 0;
    if (max_k > LAT_MAX_K) max_k = LAT_MAX_K;
    uint32_t *vp = rbc_mem_alloc(a, rbc_mul_size(n, 4));  /* vertex points */
    uint32_t *qp = rbc_mem_alloc(a, rbc_mul_size(nq, 16)); /* quad corner points */
    uint8_t *seen = rbc_mem_alloc(a, nq);
    uint32_t *queue = rbc_mem_alloc(a, rbc_mul_size(nq, 4));
    int result = 0;
    if (!vp || !qp || !seen || !queue) {
        result = RBC_COLOR_NO_MEMORY;
        goto done;
    }
    memset(vp, 0xFF, (size_t)n * 4);
    /* 1. Breadth-first over quads: the seed of each component is the unit square
     * (0,0) (1,0) (1,1) (0,1) (shifted to its first corner's point when a vertex
     * shared with an earlier component has one); crossing edge k of quad f (corners
     * k, k+1) into quad h, the shared corners keep their points and the other two
     * are those points moved one step away from f. */
    for (uint32_t f0 = 0; f0 < nq; ++f0) {
        if (seen[f0]) continue;
        const uint32_t *q0 = g->quads + 4 * (size_t)f0;
        const uint32_t base = vp[q0[0]] != NONE ? vp[q0[0]] : 0;
        static const uint32_t square[4] = {0, 1, 1 | 1u << 16, 1u << 16};
        for (int k = 0; k < 4; ++k) qp[4 * (size_t)f0 + k] = pt_add(base, square[k]);
        seen[f0] = 1;
        uint32_t head = 0, tail = 0;
        queue[tail++] = f0;
        while (head < tail) {
            const uint32_t f = queue[head++];
            const uint32_t *q = g->quads + 4 * (size_t)f;
            const uint32_t *fp = qp + 4 * (size_t)f;
            for (int k = 0; k < 4; ++k)
                if (vp[q[k]] == NONE) vp[q[k]] = fp[k];
            for (int k = 0; k < 4; ++k) {
                const uint32_t h = g->quad_nbr[4 * (size_t)f + k];
                if (h == NONE || seen[h]) continue;
                const int k1 = (k + 1) & 3, kp = (k + 3) & 3;
                const uint32_t *r = g->quads + 4 * (size_t)h;
                int mu = -1, mv = -1;
                for (int m = 0; m < 4; ++m) {
                    if (r[m] == q[k]) mu = m;
                    if (r[m] == q[k1]) mv = m;
                }
                if (mu < 0 || mv < 0) continue;
                int up, vq; /* h's corners next to mu and mv, away from the edge */
                if (mv == ((mu + 1) & 3)) up = (mu + 3) & 3, vq = (mv + 1) & 3;
                else if (mu == ((mv + 1) & 3)) up = (mu + 1) & 3, vq = (mv + 3) & 3;
                else continue; /* the two vertices are a diagonal of h: odd mesh */
                /* Unit step from edge k of f away from f: f's corner k minus corner k-1. */
                const uint32_t step = pt_sub(fp[k], fp[kp]);
                uint32_t *hp = qp + 4 * (size_t)h;
                hp[mu] = fp[k];
                hp[mv] = fp[k1];
                hp[up] = pt_add(fp[k], step);
                hp[vq] = pt_add(fp[k1], step);
                seen[h] = 1;
                queue[tail++] = h;
            }
        }
    }

    /* 2. The distinct spring offsets, with d and -d as one (key di * M + dj of the
     * smaller of the two), in a small open-addressing set. */
    uint32_t set[LAT_HASH], offs[LAT_MAX_OFFSETS], noffs = 0, last = NONE;
    for (uint32_t s = 0; s < LAT_HASH; ++s) set[s] = NONE;
    for (uint32_t v = 0; v < n; ++v) {
        const uint32_t pv = vp[v];
        for (uint32_t k = g->adj_start[v]; k < g->adj_start[v + 1]; ++k) {
            const uint32_t w = g->adj[k];
            if (w < v) continue;
            const uint32_t pw = vp[w];
            if (pv == NONE || pw == NONE) goto done; /* a spring off the quad lattice */
            const uint32_t d = pt_sub(pw, pv), e = pt_sub(pv, pw);
            uint32_t key = (d & 0xFFFF) * LAT_M + (d >> 16);
            const uint32_t neg = (e & 0xFFFF) * LAT_M + (e >> 16);
            if (neg < key) key = neg;
            if (key == 0) goto done; /* two ends on one lattice point */
            if (key == last) continue;
            last = key;
            uint32_t slot = (key * 2654435761u) & (LAT_HASH - 1);
            while (set[slot] != NONE && set[slot] != key) slot = (slot + 1) & (LAT_HASH - 1);
            if (set[slot] == NONE) {
                if (noffs == LAT_MAX_OFFSETS) goto done;
                set[slot] = key;
                offs[noffs++] = key;
            }
        }
    }

    /* 3. The smallest k, then the first (a, b), with a di + b dj != 0 mod k for
     * every offset. */
    for (uint32_t k = 2; k <= max_k; ++k)
        for (uint32_t ca = 0; ca < k; ++ca)
            for (uint32_t cb = 0; cb < k; ++cb) {
                uint32_t o = 0;
                while (o < noffs && (ca * (offs[o] / LAT_M) + cb * (offs[o] % LAT_M)) % k) ++o;
                if (o < noffs) continue;
                for (uint32_t v = 0; v < n; ++v)
                    color[v] = vp[v] == NONE
                                   ? 0
                                   : (uint8_t)((ca * (vp[v] & 0xFFFF) + cb * (vp[v] >> 16)) % k);
                result = (int)k;
                if (seamless) {
                    *seamless = 1;
                    for (o = 0; o < noffs; ++o) {
                        uint32_t di = offs[o] / LAT_M, dj = offs[o] % LAT_M;
                        if ((di > 2 && di < LAT_M - 2) || (dj > 2 && dj < LAT_M - 2)) *seamless = 0;
                    }
                }
                goto done;
            }
done:
    rbc_mem_free(a, vp, rbc_mul_size(n, 4));
    rbc_mem_free(a, qp, rbc_mul_size(nq, 16));
    rbc_mem_free(a, seen, nq);
    rbc_mem_free(a, queue, rbc_mul_size(nq, 4));
    return result;
}

/* ------------------------------------------------------------------------- */
/* Balancing and the policy                                                  */
/* ------------------------------------------------------------------------- */

void rbc_color_balance(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                       uint8_t *color, uint32_t ncolors, uint32_t max_passes) {
    if (ncolors < 2) return;
    uint32_t count[64] = {0};
    for (uint32_t v = 0; v < n; ++v) count[color[v]]++;
    /* A vertex is worth moving only out of a class above the mean. */
    for (uint32_t pass = 0; pass < max_passes; ++pass) {
        uint32_t moved = 0;
        for (uint32_t v = 0; v < n; ++v) {
            uint32_t c = color[v];
            if ((uint64_t)count[c] * ncolors <= n) continue;
            uint64_t taken = 0;
            for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k)
                taken |= (uint64_t)1 << color[adj[k]];
            uint32_t best = c;
            for (uint32_t d = 0; d < ncolors; ++d)
                if (!(taken >> d & 1) && count[d] < count[best]) best = d;
            if (best != c && count[best] + 1 < count[c]) {
                color[v] = (uint8_t)best;
                count[c]--;
                count[best]++;
                moved++;
            }
        }
        if (!moved) break;
    }
}

int rbc_color_iterated_greedy(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                              uint8_t *color, uint32_t ncolors, uint32_t iterations,
                              uint32_t lower_bound, const rbc_allocator *a) {
    if (ncolors <= lower_bound || ncolors < 2) return (int)ncolors;
    uint32_t *order = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    uint8_t *next = rbc_mem_alloc(a, n);
    if (!order || !next) {
        rbc_mem_free(a, order, rbc_mul_size(n, 4));
        rbc_mem_free(a, next, n);
        return RBC_COLOR_NO_MEMORY;
    }
    uint32_t k = ncolors, stall = 0, seed = 0x9E3779B9u;
    for (uint32_t it = 0; it < iterations && k > lower_bound && stall < 4; ++it) {
        /* The classes in a random order (Fisher-Yates on an LCG: deterministic). */
        uint32_t count[64] = {0}, by_rank[64], rank[64], start[65];
        for (uint32_t v = 0; v < n; ++v) count[color[v]]++;
        for (uint32_t c = 0; c < k; ++c) by_rank[c] = c;
        for (uint32_t c = k - 1; c > 0; --c) {
            seed = seed * 1664525u + 1013904223u;
            uint32_t r = (seed >> 8) % (c + 1), tmp = by_rank[c];
            by_rank[c] = by_rank[r];
            by_rank[r] = tmp;
        }
        for (uint32_t r = 0; r < k; ++r) rank[by_rank[r]] = r;
        start[0] = 0;
        for (uint32_t r = 0; r < k; ++r) start[r + 1] = start[r] + count[by_rank[r]];
        for (uint32_t v = 0; v < n; ++v) order[start[rank[color[v]]]++] = v;
        /* First fit in that order: a vertex never needs more than its class's rank,
         * since the earlier classes were independent sets. */
        memset(next, UNCOLORED, n);
        uint32_t used = 0;
        for (uint32_t t = 0; t < n; ++t) {
            uint32_t v = order[t];
            uint64_t taken = 0;
            for (uint32_t e = adj_start[v]; e < adj_start[v + 1]; ++e)
                if (next[adj[e]] != UNCOLORED) taken |= (uint64_t)1 << next[adj[e]];
            uint32_t c = lowest_bit(~taken);
            next[v] = (uint8_t)c;
            if (c + 1 > used) used = c + 1;
        }
        memcpy(color, next, n);
        stall = used < k ? 0 : stall + 1;
        k = used;
    }
    rbc_mem_free(a, order, rbc_mul_size(n, 4));
    rbc_mem_free(a, next, n);
    return (int)k;
}

/* Renumber the used colors 0 .. k-1 in order of first use; returns k. */
static uint32_t compact(uint32_t n, uint8_t *color) {
    uint8_t map[256];
    memset(map, UNCOLORED, sizeof map);
    uint32_t k = 0;
    for (uint32_t v = 0; v < n; ++v) {
        if (map[color[v]] == UNCOLORED) map[color[v]] = (uint8_t)k++;
        color[v] = map[color[v]];
    }
    return k ? k : 1;
}

int rbc_color_graph(const rbc_color_input *g, uint32_t max_colors, const rbc_allocator *a,
                    uint8_t *color, uint32_t *ncolors, uint32_t *bad_vertex,
                    rbc_color_method *method) {
    const uint32_t n = g->n;
    rbc_color_method how = RBC_COLOR_METHOD_BIPARTITE;
    int result = 0;
    if (max_colors > 64) max_colors = 64;
    uint32_t *queue = rbc_mem_alloc(a, rbc_mul_size(n, 4));
    uint8_t *other = rbc_mem_alloc(a, n);
    if (!queue || !other) {
        result = RBC_COLOR_NO_MEMORY;
        goto done;
    }
    uint32_t bad_a, bad_b;
    if (rbc_color_bipartite(n, g->adj_start, g->adj, color, queue, &bad_a, &bad_b) == 0)
        goto done;
    /* Not bipartite: at least 3 colors. A lattice coloring with 3 is optimal; with
     * more, DSATUR may still do better on an irregular mesh. */
    uint32_t max_lattice = max_colors < LAT_MAX_K ? max_colors : LAT_MAX_K;
    int seamless = 0;
    int k = rbc_color_lattice(g, max_lattice, a, color, &seamless);
    if (k < 0) {
        result = k;
        goto done;
    }
    how = RBC_COLOR_METHOD_LATTICE;
    if (k == 3) goto done;
    int kd = rbc_color_dsatur(n, g->adj_start, g->adj, k > 0 ? (uint32_t)k - 1 : max_colors,
                              a, other, bad_vertex);
    if (kd == RBC_COLOR_NO_MEMORY) {
        result = kd;
        goto done;
    }
    if (kd > 0) {
        memcpy(color, other, n);
        how = RBC_COLOR_METHOD_DSATUR;
        k = kd;
    } else if (k == 0) { /* neither fits in max_colors */
        result = RBC_COLOR_TOO_MANY;
        goto done;
    } else if (seamless) {
        /* A linear form on a lattice without seams or irregular vertices (all spring
         * offsets within 2 steps, as on a grid): the smallest such k is the chromatic
         * number of the usual patterns (docs/facts.md: 4 shear, 5 shear + bend), and its
         * classes are even. Nothing to improve. */
        goto done;
    }
    k = rbc_color_iterated_greedy(n, g->adj_start, g->adj, color, (uint32_t)k, 16, 3, a);
    if (k < 0) {
        result = k;
        goto done;
    }
    rbc_color_balance(n, g->adj_start, g->adj, color, (uint32_t)k, 8);
done:
    if (result == 0) {
        *ncolors = compact(n, color);
        if (method) *method = how;
    }
    rbc_mem_free(a, queue, rbc_mul_size(n, 4));
    rbc_mem_free(a, other, n);
    return result;
}

int rbc_coloring_is_valid(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                          const uint8_t *color) {
    for (uint32_t v = 0; v < n; ++v)
        for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k)
            if (color[adj[k]] == color[v]) return 0;
    return 1;
}
