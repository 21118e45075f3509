/* collide_kernels.h -- projection of one particle out of the built-in collider
 * shapes (position-based contact: the particle is moved to the surface plus the
 * collider's thickness). Shared by every backend. */
#ifndef RBC_COLLIDE_KERNELS_H
#define RBC_COLLIDE_KERNELS_H
#include <math.h>

#include "rbc_hd.h"

/* Plane through o with unit normal n; keeps p on the +n side at distance >= t. */
RBC_HD void rbc_k_collide_plane(float *px, float *py, float *pz, const float o[3],
                                const float n[3], float t) {
    float dist = (*px - o[0]) * n[0] + (*py - o[1]) * n[1] + (*pz - o[2]) * n[2] - t;
    if (dist < 0.0f) {
        *px -= dist * n[0];
        *py -= dist * n[1];
        *pz -= dist * n[2];
    }
}

/* Sphere of radius r (already including thickness) around c. A particle exactly at
 * the center is pushed out along +y. */
RBC_HD void rbc_k_collide_sphere(float *px, float *py, float *pz, const float c[3], float r) {
    float ex = *px - c[0], ey = *py - c[1], ez = *pz - c[2];
    float d2 = ex * ex + ey * ey + ez * ez;
    if (d2 >= r * r) return;
    if (d2 > 1e-24f) {
        float f = r / sqrtf(d2);
        *px = c[0] + ex * f;
        *py = c[1] + ey * f;
        *pz = c[2] + ez * f;
    } else {
        *px = c[0];
        *py = c[1] + r;
        *pz = c[2];
    }
}
#endif
