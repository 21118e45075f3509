/* wind.c -- wind and drag on the quads (wind.h). */
#include "wind.h"

#include <math.h>

void rbc_wind_apply(rbc_solver *s, float h) {
    const float drag = s->wind_drag, lift = s->wind_lift;
    const float h2 = h * h, inv_h = 1.0f / h;
    for (uint32_t k = 0; k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        double work = 0.0;
        for (uint32_t q = 0; q < c->quad_count; ++q) {
            const uint32_t *v = &c->quads[4 * (size_t)q];
            float P[4][3], vel[3] = {0, 0, 0};
            for (int m = 0; m < 4; ++m)
                for (int a = 0; a < 3; ++a) {
                    P[m][a] = c->x[a][v[m]];
                    vel[a] += 0.25f * (c->x[a][v[m]] - c->q[a][v[m]]) * inv_h;
                }
            /* Area vector of the quad: half the cross product of its diagonals. */
            float d1[3] = {P[2][0] - P[0][0], P[2][1] - P[0][1], P[2][2] - P[0][2]};
            float d2[3] = {P[3][0] - P[1][0], P[3][1] - P[1][1], P[3][2] - P[1][2]};
            float an[3] = {0.5f * (d1[1] * d2[2] - d1[2] * d2[1]),
                           0.5f * (d1[2] * d2[0] - d1[0] * d2[2]),
                           0.5f * (d1[0] * d2[1] - d1[1] * d2[0])};
            float area = sqrtf(an[0] * an[0] + an[1] * an[1] + an[2] * an[2]);
            if (!(area > 0.0f)) continue;
            float n[3] = {an[0] / area, an[1] / area, an[2] / area};
            float r[3] = {s->wind[0] - vel[0], s->wind[1] - vel[1], s->wind[2] - vel[2]};
            float rn = r[0] * n[0] + r[1] * n[1] + r[2] * n[2];
            float F[3];
            for (int a = 0; a < 3; ++a) {
                float tang = r[a] - rn * n[a];
                F[a] = area * (drag * rn * n[a] + lift * fabsf(rn) * tang);
            }
            float fm = 0.25f * sqrtf(F[0] * F[0] + F[1] * F[1] + F[2] * F[2]);
            for (int m = 0; m < 4; ++m) {
                uint32_t i = v[m];
                if (c->pinned[i]) continue;
                float sc = 0.25f * h2 / c->topo.mass[i];
                for (int a = 0; a < 3; ++a) {
                    c->y[a][i] += sc * F[a];
                    c->p[a][i] += sc * F[a];
                }
                /* The wind's work on the corner over the substep, bounded by its force
                 * times how far the corner moves: what it moved last substep plus what
                 * the force alone adds. */
                float dx = c->x[0][i] - c->q[0][i], dy = c->x[1][i] - c->q[1][i],
                      dz = c->x[2][i] - c->q[2][i];
                work += (double)fm * (sqrtf(dx * dx + dy * dy + dz * dz) + sc * 4.0f * fm);
            }
        }
        c->guard.step_budget += work; /* the energy guard's budget (wind supplies energy) */
    }
}
