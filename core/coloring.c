#include "coloring.h"

#include <string.h>

int rbc_color_bipartite(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                        uint8_t *color, uint32_t *queue, uint32_t *bad_a, uint32_t *bad_b) {
    const uint8_t uncolored = 0xFF;
    memset(color, uncolored, n);
    for (uint32_t root = 0; root < n; ++root) {
        if (color[root] != uncolored) continue;
        /* Breadth-first from each uncolored vertex: a vertex at even distance from
         * the root is red (0), at odd distance black (1). */
        uint32_t head = 0, tail = 0;
        color[root] = 0;
        queue[tail++] = root;
        while (head < tail) {
            uint32_t v = queue[head++];
            uint8_t other = (uint8_t)(1 - color[v]);
            for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k) {
                uint32_t w = adj[k];
                if (color[w] == uncolored) {
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

int rbc_coloring_is_valid(uint32_t n, const uint32_t *adj_start, const uint32_t *adj,
                          const uint8_t *color) {
    for (uint32_t v = 0; v < n; ++v)
        for (uint32_t k = adj_start[v]; k < adj_start[v + 1]; ++k)
            if (color[adj[k]] == color[v]) return 0;
    return 1;
}
