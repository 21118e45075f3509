/* pick.c -- the vertex a ray picks (pick.h). */
#include "pick.h"

int rbc_pick(const rbc_solver *s, const float o[3], const float d[3], float tmax, float radius,
             uint32_t *cloth_index, uint32_t *host_vertex, float *t_out) {
    double dd = (double)d[0] * d[0] + (double)d[1] * d[1] + (double)d[2] * d[2];
    double r2 = (double)radius * radius;
    int found = 0;
    double best_t = 0.0, best_d2 = 0.0;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        const rbc_cloth_state *c = s->cloths[k];
        for (uint32_t v = 0; v < c->topo.n; ++v) {
            uint32_t i = c->topo.to_internal[v];
            double w[3] = {(double)c->x[0][i] - o[0], (double)c->x[1][i] - o[1],
                           (double)c->x[2][i] - o[2]};
            double t = (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd;
            if (t < 0.0) t = 0.0;
            if (t > tmax) t = tmax;
            double e2 = 0.0;
            for (int a = 0; a < 3; ++a) {
                double e = w[a] - t * d[a];
                e2 += e * e;
            }
            if (e2 > r2) continue;
            if (!found || t < best_t || (t == best_t && e2 < best_d2)) {
                found = 1;
                best_t = t;
                best_d2 = e2;
                *cloth_index = k;
                *host_vertex = v;
            }
        }
    }
    if (found) *t_out = (float)best_t;
    return found;
}
