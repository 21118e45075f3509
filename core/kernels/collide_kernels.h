/* collide_kernels.h -- the per-particle math of contact with the built-in analytic
 * colliders (collide.h), shared by the CPU path (collide.c, shapes.c) and every
 * backend (backend_step.c's schedule; backend_cpu.c loops over these, the CUDA
 * module wraps them in one thread per particle). One source for both, so the
 * backend's contacts round exactly as the CPU's: the frame of a collider at a
 * fraction of the step, the analytic shapes' distance and first entry (double inside,
 * rounded once, as shapes.h documents), the contact of a particle's motion with a
 * shape, its half-space projection with Coulomb friction, the friction after the
 * solve and the safety pass. The triangle mesh (its BVH) stays in shapes.c, on the CPU.
 *
 * The backend's contacts live in fixed per-particle slots (RBC_KC_SLOTS at most):
 * slot s of particle i holds field F at ct[(F * slots + s) * n + i], so a warp reads
 * each field of consecutive particles from consecutive words. A particle's contacts
 * are in increasing collider order, the order the CPU's list projects them in. */
#ifndef RBC_COLLIDE_KERNELS_H
#define RBC_COLLIDE_KERNELS_H
#include <math.h>
#include <stdint.h>

#include "rbc_hd.h"

/* world = r * local + t (r row-major). */
typedef struct rbc_frame {
    float r[9];
    float t[3];
} rbc_frame;

/* The shapes these bodies know (abi/rbcloth.h's rbc_shape values, repeated so that
 * the CUDA module need not see the ABI header here). */
enum { RBC_KC_PLANE = 1, RBC_KC_SPHERE = 2, RBC_KC_CAPSULE = 3, RBC_KC_BOX = 4 };

/* A collider as a backend holds it (uploaded every step): its shape, its poses at the
 * end of the last step and now, and the frames of the current substep, which
 * RBC_KERNEL_COLLIDE_FRAMES computes from them. */
typedef struct rbc_dcollider {
    int32_t shape;
    float radius, he[3];       /* radius; half extents (capsule: he[1]) */
    float lo[3], hi[3];        /* local bounds of the solid (rbc_shape_bounds) */
    float thickness, friction;
    float last_position[3], last_rotation[4], position[3], rotation[4];
    rbc_frame A, B;            /* at the substep's start and end */
} rbc_dcollider;

/* Contact slots per particle on a backend: up to this many colliders may touch one
 * particle in one substep (the CPU's lists have no such bound; more fails the step on
 * a backend, backend_step.c). */
#define RBC_KC_SLOTS 4
/* The fields of a slot: the half-space n . p >= d, the surface's velocity u, how far
 * the prediction went in, the latest pass's push, Coulomb's mu, the normal force
 * (rbc_collide_normal_forces). */
enum {
    RBC_KC_N0, RBC_KC_N1, RBC_KC_N2, RBC_KC_D, RBC_KC_U0, RBC_KC_U1, RBC_KC_U2, RBC_KC_DEPTH,
    RBC_KC_LAST, RBC_KC_MU, RBC_KC_FN, RBC_KC_FIELDS
};

/* ---- frames ---- */

/* Rotation matrix of a unit quaternion (x, y, z, w), row-major. */
RBC_HD void rbc_kc_quat_matrix(const float q[4], float r[9]) {
    float x = q[0], y = q[1], z = q[2], w = q[3];
    r[0] = 1.0f - 2.0f * (y * y + z * z);
    r[1] = 2.0f * (x * y - z * w);
    r[2] = 2.0f * (x * z + y * w);
    r[3] = 2.0f * (x * y + z * w);
    r[4] = 1.0f - 2.0f * (x * x + z * z);
    r[5] = 2.0f * (y * z - x * w);
    r[6] = 2.0f * (x * z - y * w);
    r[7] = 2.0f * (y * z + x * w);
    r[8] = 1.0f - 2.0f * (x * x + y * y);
}

/* The pose at fraction f of the step (0: last_*, 1: now): position interpolated
 * linearly, rotation by nlerp along the shorter arc. */
RBC_HD void rbc_kc_frame_at(const float last_position[3], const float last_rotation[4],
                            const float position[3], const float rotation[4], float f,
                            rbc_frame *out) {
    float q[4];
    const float *a = last_rotation, *b = rotation;
    if (f >= 1.0f) {
        for (int k = 0; k < 4; ++k) q[k] = b[k];
        for (int k = 0; k < 3; ++k) out->t[k] = position[k];
    } else {
        float dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        float sb = dot < 0.0f ? -f : f, n2 = 0.0f;
        for (int k = 0; k < 4; ++k) {
            q[k] = (1.0f - f) * a[k] + sb * b[k];
            n2 += q[k] * q[k];
        }
        float inv = n2 > 0.0f ? 1.0f / sqrtf(n2) : 1.0f;
        for (int k = 0; k < 4; ++k) q[k] *= inv;
        for (int k = 0; k < 3; ++k)
            out->t[k] = last_position[k] + (position[k] - last_position[k]) * f;
    }
    rbc_kc_quat_matrix(q, out->r);
}

RBC_HD void rbc_kc_to_local(const rbc_frame *fr, const float w[3], float l[3]) {
    float d0 = w[0] - fr->t[0], d1 = w[1] - fr->t[1], d2 = w[2] - fr->t[2];
    l[0] = fr->r[0] * d0 + fr->r[3] * d1 + fr->r[6] * d2;
    l[1] = fr->r[1] * d0 + fr->r[4] * d1 + fr->r[7] * d2;
    l[2] = fr->r[2] * d0 + fr->r[5] * d1 + fr->r[8] * d2;
}
RBC_HD void rbc_kc_to_world_dir(const rbc_frame *fr, const float l[3], float w[3]) {
    w[0] = fr->r[0] * l[0] + fr->r[1] * l[1] + fr->r[2] * l[2];
    w[1] = fr->r[3] * l[0] + fr->r[4] * l[1] + fr->r[5] * l[2];
    w[2] = fr->r[6] * l[0] + fr->r[7] * l[1] + fr->r[8] * l[2];
}
RBC_HD void rbc_kc_to_world(const rbc_frame *fr, const float l[3], float w[3]) {
    rbc_kc_to_world_dir(fr, l, w);
    w[0] += fr->t[0];
    w[1] += fr->t[1];
    w[2] += fr->t[2];
}

/* ---- the analytic shapes (shapes.h: double inside, rounded once) ---- */

RBC_HD float rbc_kc_sphere_distance(const float q[3], double r, float n[3]) {
    double x = q[0], y = q[1], z = q[2];
    double d = sqrt(x * x + y * y + z * z);
    if (d > 0.0) {
        n[0] = (float)(x / d), n[1] = (float)(y / d), n[2] = (float)(z / d);
    } else {
        n[0] = 0.0f, n[1] = 1.0f, n[2] = 0.0f;
    }
    return (float)(d - r);
}

RBC_HD float rbc_kc_capsule_distance(const float q[3], double r, double h, float n[3]) {
    double y = q[1], s = y < -h ? -h : y > h ? h : y;
    double x = q[0], dy = y - s, z = q[2];
    double d = sqrt(x * x + dy * dy + z * z);
    if (d > 0.0) {
        n[0] = (float)(x / d), n[1] = (float)(dy / d), n[2] = (float)(z / d);
    } else {
        n[0] = 1.0f, n[1] = 0.0f, n[2] = 0.0f;
    }
    return (float)(d - r);
}

RBC_HD float rbc_kc_box_distance(const float q[3], const double h[3], float n[3]) {
    double g[3];
    int outside = 0;
    for (int i = 0; i < 3; ++i) {
        g[i] = fabs((double)q[i]) - h[i];
        outside |= g[i] > 0.0;
    }
    if (outside) {
        double o[3], s = 0.0;
        for (int i = 0; i < 3; ++i) {
            o[i] = g[i] > 0.0 ? g[i] : 0.0;
            s += o[i] * o[i];
        }
        double d = sqrt(s); /* > 0: some g > 0, and a float's square is no double
                               denormal */
        for (int i = 0; i < 3; ++i) n[i] = (float)copysign(o[i] / d, (double)q[i]);
        return (float)d;
    }
    /* Inside (or on): the face of least penetration, the lower axis on ties. */
    int k = 0;
    if (g[1] > g[k]) k = 1;
    if (g[2] > g[k]) k = 2;
    n[0] = n[1] = n[2] = 0.0f;
    n[k] = q[k] < 0.0f ? -1.0f : 1.0f;
    return (float)g[k];
}

/* Entry of o + t d, t in [0, 1], into the sphere |x - c| <= r (c = (0, cy, 0)) from
 * outside or from its surface; 1 and *t on entry. C = |o - c|^2 - r^2 >= 0, B < 0
 * (moving inward), two roots; the smaller, C / (-B + sqrt(disc)), without
 * cancellation. */
RBC_HD int rbc_kc_sphere_entry(const double o[3], const double d[3], double cy, double r,
                               double *t) {
    double ox = o[0], oy = o[1] - cy, oz = o[2];
    double A = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double B = ox * d[0] + oy * d[1] + oz * d[2];
    double C = ox * ox + oy * oy + oz * oz - r * r;
    if (!(A > 0.0) || C < 0.0 || !(B < 0.0)) return 0;
    double disc = B * B - A * C;
    if (!(disc > 0.0)) return 0;
    double te = C / (-B + sqrt(disc));
    if (te > 1.0) return 0;
    *t = te;
    return 1;
}

RBC_HD int rbc_kc_sphere_raycast(const double o[3], const double d[3], double r, double *t,
                                 float n[3]) {
    if (o[0] * o[0] + o[1] * o[1] + o[2] * o[2] < r * r) return 0; /* starts inside */
    if (!rbc_kc_sphere_entry(o, d, 0.0, r, t)) return 0;
    double p[3] = {o[0] + *t * d[0], o[1] + *t * d[1], o[2] + *t * d[2]};
    float q[3] = {(float)p[0], (float)p[1], (float)p[2]};
    (void)rbc_kc_sphere_distance(q, r, n);
    return 1;
}

RBC_HD int rbc_kc_capsule_raycast(const double o[3], const double d[3], double r, double h,
                                  double *t, float n[3]) {
    double s = o[1] < -h ? -h : o[1] > h ? h : o[1], dy = o[1] - s;
    if (o[0] * o[0] + dy * dy + o[2] * o[2] < r * r) return 0; /* starts inside */
    /* The union of the side (an infinite cylinder cut to |y| <= h) and the two end
     * spheres: from outside, its first point is the first entry into any of them (the
     * cut cylinder's caps lie inside the spheres). */
    double best = 2.0, te;
    double A = d[0] * d[0] + d[2] * d[2];
    double B = o[0] * d[0] + o[2] * d[2];
    double C = o[0] * o[0] + o[2] * o[2] - r * r;
    if (A > 0.0 && C >= 0.0 && B < 0.0) {
        double disc = B * B - A * C;
        if (disc > 0.0) {
            te = C / (-B + sqrt(disc));
            double y = o[1] + te * d[1];
            if (te <= 1.0 && y >= -h && y <= h) best = te;
        }
    }
    if (rbc_kc_sphere_entry(o, d, h, r, &te) && te < best) best = te;
    if (rbc_kc_sphere_entry(o, d, -h, r, &te) && te < best) best = te;
    if (best > 1.0) return 0;
    *t = best;
    float q[3] = {(float)(o[0] + best * d[0]), (float)(o[1] + best * d[1]),
                  (float)(o[2] + best * d[2])};
    /* The gradient at the entry point; the rounded point may sit on the axis only if
     * r is 0: keep the distance's fallback then. */
    (void)rbc_kc_capsule_distance(q, r, h, n);
    return 1;
}

/* Slabs (Kay & Kajiya): the interior is entered when the largest entry parameter is
 * below the smallest exit; a segment along a face (|o_i| = h_i, d_i = 0) only grazes. */
RBC_HD int rbc_kc_box_raycast(const double o[3], const double d[3], const double h[3],
                              double *t, float n[3]) {
    if (fabs(o[0]) < h[0] && fabs(o[1]) < h[1] && fabs(o[2]) < h[2]) return 0;
    double t0 = -INFINITY, t1 = INFINITY;
    int axis = -1;
    for (int i = 0; i < 3; ++i) {
        if (d[i] == 0.0) {
            if (!(fabs(o[i]) < h[i])) return 0;
            continue;
        }
        double ta = (-h[i] - o[i]) / d[i], tb = (h[i] - o[i]) / d[i];
        if (ta > tb) {
            double tmp = ta;
            ta = tb, tb = tmp;
        }
        if (ta > t0) t0 = ta, axis = i;
        if (tb < t1) t1 = tb;
    }
    if (axis < 0 || !(t0 < t1) || t0 < 0.0 || t0 > 1.0) return 0;
    *t = t0 + 0.0; /* not -0 */
    n[0] = n[1] = n[2] = 0.0f;
    n[axis] = d[axis] > 0.0 ? -1.0f : 1.0f; /* the face toward o */
    return 1;
}

RBC_HD float rbc_kc_nonneg(float v) { return v > 0.0f ? v : 0.0f; }

/* rbc_shape_distance for the analytic shapes: phi and n always set; 1 when phi <=
 * max_dist. kind outside plane..box: 0, nothing set. */
RBC_HD int rbc_kc_distance(int kind, float radius, const float he[3], const float q[3],
                           float max_dist, float *phi, float n[3]) {
    float p;
    if (kind == RBC_KC_PLANE) {
        p = q[1];
        n[0] = 0.0f, n[1] = 1.0f, n[2] = 0.0f;
    } else if (kind == RBC_KC_SPHERE) {
        p = rbc_kc_sphere_distance(q, radius, n);
    } else if (kind == RBC_KC_CAPSULE) {
        p = rbc_kc_capsule_distance(q, radius, rbc_kc_nonneg(he[1]), n);
    } else if (kind == RBC_KC_BOX) {
        double h[3];
        for (int i = 0; i < 3; ++i) h[i] = rbc_kc_nonneg(he[i]);
        p = rbc_kc_box_distance(q, h, n);
    } else {
        return 0;
    }
    *phi = p;
    return p <= max_dist;
}

/* rbc_shape_raycast for the analytic shapes (kind outside plane..box: 0). */
RBC_HD int rbc_kc_raycast(int kind, float radius, const float he[3], const float a[3],
                          const float b[3], float *t, float n[3]) {
    double o[3] = {a[0], a[1], a[2]};
    double d[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double th;
    if (kind == RBC_KC_PLANE) {
        /* From y >= 0 to y < 0: t = a_y / (a_y - b_y). */
        if (!(o[1] >= 0.0 && b[1] < 0.0f)) return 0;
        *t = (float)(o[1] / (o[1] - (double)b[1]));
        n[0] = 0.0f, n[1] = 1.0f, n[2] = 0.0f;
        return 1;
    } else if (kind == RBC_KC_SPHERE) {
        if (!rbc_kc_sphere_raycast(o, d, radius, &th, n)) return 0;
    } else if (kind == RBC_KC_CAPSULE) {
        if (!rbc_kc_capsule_raycast(o, d, radius, rbc_kc_nonneg(he[1]), &th, n)) return 0;
    } else if (kind == RBC_KC_BOX) {
        double h[3];
        for (int i = 0; i < 3; ++i) h[i] = rbc_kc_nonneg(he[i]);
        if (!rbc_kc_box_raycast(o, d, h, &th, n)) return 0;
    } else {
        return 0;
    }
    *t = (float)th;
    return 1;
}

/* ---- a particle's contact ---- */

/* The contact of a particle moving from a to b (collider frame at the substep's
 * start and end) with an analytic shape: 1 and the surface point sl with outward
 * normal nl when the motion enters the shape (the entry point) or b is within reach
 * of the surface (its closest point). Planes and spheres in single precision here
 * (most scenes' colliders); capsules and boxes by the double-precision queries. */
RBC_HD int rbc_kc_shape_contact(int kind, float radius, const float he[3], const float a[3],
                                const float b[3], float reach, float sl[3], float nl[3]) {
    if (kind == RBC_KC_PLANE) {
        if (a[1] >= 0.0f && b[1] < 0.0f) {
            float t = a[1] / (a[1] - b[1]);
            sl[0] = a[0] + t * (b[0] - a[0]);
            sl[1] = 0.0f;
            sl[2] = a[2] + t * (b[2] - a[2]);
        } else if (b[1] < reach) {
            sl[0] = b[0];
            sl[1] = 0.0f;
            sl[2] = b[2];
        } else {
            return 0;
        }
        nl[0] = 0.0f, nl[1] = 1.0f, nl[2] = 0.0f;
        return 1;
    }
    if (kind == RBC_KC_SPHERE) {
        const float r = radius, R = r + reach;
        float a2 = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
        float b2 = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        float d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        if (a2 >= r * r) {
            /* Entry: the first root of |a + t d|^2 = r^2 in [0, 1]. */
            float dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            float ad = a[0] * d[0] + a[1] * d[1] + a[2] * d[2];
            float disc = ad * ad - dd * (a2 - r * r);
            if (ad < 0.0f && disc > 0.0f && dd > 0.0f) {
                float t = (-ad - sqrtf(disc)) / dd;
                if (t >= 0.0f && t <= 1.0f) {
                    float inv = 1.0f / r;
                    for (int ax = 0; ax < 3; ++ax) {
                        sl[ax] = a[ax] + t * d[ax];
                        nl[ax] = sl[ax] * inv;
                    }
                    return 1;
                }
            }
        }
        if (b2 >= R * R) return 0;
        float len = sqrtf(b2);
        if (len > 1e-12f) {
            float inv = 1.0f / len;
            for (int ax = 0; ax < 3; ++ax) nl[ax] = b[ax] * inv;
        } else {
            nl[0] = 0.0f, nl[1] = 1.0f, nl[2] = 0.0f;
        }
        for (int ax = 0; ax < 3; ++ax) sl[ax] = nl[ax] * r;
        return 1;
    }
    float t, phi;
    if (rbc_kc_raycast(kind, radius, he, a, b, &t, nl)) {
        for (int ax = 0; ax < 3; ++ax) sl[ax] = a[ax] + t * (b[ax] - a[ax]);
        return 1;
    }
    if (rbc_kc_distance(kind, radius, he, b, reach, &phi, nl) && phi < reach) {
        for (int ax = 0; ax < 3; ++ax) sl[ax] = b[ax] - phi * nl[ax];
        return 1;
    }
    return 0;
}

/* Detection's cull: whether the box of the motion a -> b (local) meets the solid's
 * bounds grown by reach. The same comparisons as collide.c's vectorized cull_chunk,
 * on the same local coordinates, so both keep the same particles. */
RBC_HD int rbc_kc_cull(const float a[3], const float b[3], const float lo[3], const float hi[3],
                       float reach) {
    int keep = 1;
    for (int ax = 0; ax < 3; ++ax) {
        float n = a[ax] < b[ax] ? a[ax] : b[ax], x = a[ax] < b[ax] ? b[ax] : a[ax];
        keep &= (n <= hi[ax] + reach) & (x >= lo[ax] - reach);
    }
    return keep;
}

/* A contact's half-space from the surface point sl and normal nl (local) with the
 * collider at B (end of the substep), offset by thick; u the surface's velocity
 * there (from its position at A), depth how far the prediction yw went in. */
RBC_HD void rbc_kc_contact_make(const rbc_frame *A, const rbc_frame *B, const float sl[3],
                                const float nl[3], float thick, float inv_h, const float yw[3],
                                float n[3], float *d, float u[3], float *depth) {
    float sw[3], sa[3];
    rbc_kc_to_world_dir(B, nl, n);
    rbc_kc_to_world(B, sl, sw);
    rbc_kc_to_world(A, sl, sa);
    *d = n[0] * sw[0] + n[1] * sw[1] + n[2] * sw[2] + thick;
    for (int ax = 0; ax < 3; ++ax) u[ax] = (sw[ax] - sa[ax]) * inv_h;
    float pen = *d - (n[0] * yw[0] + n[1] * yw[1] + n[2] * yw[2]);
    *depth = pen > 0.0f ? pen : 0.0f;
}

/* Coulomb friction after a normal push v > 0 in the same pass, on the particle at p
 * (x: where it was at the substep's start): the slip (motion less the surface's u h,
 * tangential) removed while within mu v, else cut by mu v; ft the correction. */
RBC_HD void rbc_kc_pass_friction(float mu, const float n[3], const float u[3], const float x[3],
                                 float p[3], float v, float h, float ft[3]) {
    ft[0] = ft[1] = ft[2] = 0.0f;
    if (!(mu > 0.0f)) return;
    float dl[3];
    for (int a = 0; a < 3; ++a) dl[a] = p[a] - x[a] - u[a] * h;
    float dn = dl[0] * n[0] + dl[1] * n[1] + dl[2] * n[2];
    float tg[3] = {dl[0] - dn * n[0], dl[1] - dn * n[1], dl[2] - dn * n[2]};
    float tl = sqrtf(tg[0] * tg[0] + tg[1] * tg[1] + tg[2] * tg[2]);
    float lim = mu * v;
    float f = tl <= lim ? 1.0f : lim / tl; /* static: all of it; kinetic: mu v */
    for (int a = 0; a < 3; ++a) {
        ft[a] = -f * tg[a];
        p[a] += ft[a];
    }
}

/* Project p onto n . p >= d: the push v into *last (0 if none); with h > 0 also the
 * pass's friction. 1 if p moved. */
RBC_HD int rbc_kc_project(const float n[3], float d, float mu, const float u[3], const float x[3],
                          float p[3], float h, float *last, float ft[3]) {
    float v = d - (n[0] * p[0] + n[1] * p[1] + n[2] * p[2]);
    if (!(v > 0.0f)) {
        *last = 0.0f;
        return 0;
    }
    p[0] += v * n[0];
    p[1] += v * n[1];
    p[2] += v * n[2];
    *last = v;
    if (h > 0.0f) rbc_kc_pass_friction(mu, n, u, x, p, v, h, ft);
    return 1;
}

/* Friction after the solve for the solvers without color passes (collide.c,
 * rbc_collide_finish): a contact touching at the end and pushed at some point has its
 * tangential slip relative to the surface removed up to mu fn_row h^2 / m. 1 when it
 * acted: p corrected by corr; 0: neither touched. */
RBC_HD int rbc_kc_finish_friction(const float n[3], float d, const float u[3], float depth,
                                   float last, float mu, float fn_row, float mass, const float x[3],
                                   float p[3], float h, float corr[3]) {
    float gap = n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - d;
    float push = depth > last ? depth : last;
    int active = push > 0.0f && gap <= 1e-3f * push + 1e-7f;
    if (!(active && mu > 0.0f)) return 0;
    float dl[3];
    for (int ax = 0; ax < 3; ++ax) dl[ax] = p[ax] - x[ax] - u[ax] * h;
    float dn = dl[0] * n[0] + dl[1] * n[1] + dl[2] * n[2];
    float tg[3] = {dl[0] - dn * n[0], dl[1] - dn * n[1], dl[2] - dn * n[2]};
    float tl = sqrtf(tg[0] * tg[0] + tg[1] * tg[1] + tg[2] * tg[2]);
    float lim = mu * fn_row * h * h / mass;
    float f = tl <= lim ? 1.0f : lim / tl; /* static: all of it; kinetic: mu disp */
    for (int ax = 0; ax < 3; ++ax) {
        corr[ax] = -f * tg[ax];
        p[ax] += corr[ax];
    }
    return 1;
}

/* The safety pass for one particle and one collider (collide.c, rbc_collide_post):
 * 1 when the particle's solved motion x -> p enters the shape or ends within thick of
 * it, with the projection v > 0 along nw and the surface point at B and A (sw, sa, for
 * the work). p is not moved here. */
RBC_HD int rbc_kc_post_one(int kind, float radius, const float he[3], const float lo[3],
                           const float hi[3], const rbc_frame *A, const rbc_frame *B, float thick,
                           const float xw[3], const float pw[3], float *v, float nw[3],
                           float sw[3], float sa[3]) {
    float a[3], b[3];
    rbc_kc_to_local(A, xw, a);
    rbc_kc_to_local(B, pw, b);
    for (int ax = 0; ax < 3; ++ax) {
        float l = a[ax] < b[ax] ? a[ax] : b[ax], h = a[ax] < b[ax] ? b[ax] : a[ax];
        if (h < lo[ax] - thick || l > hi[ax] + thick) return 0;
    }
    float nl[3], sl[3];
    if (!rbc_kc_shape_contact(kind, radius, he, a, b, thick, sl, nl)) return 0;
    rbc_kc_to_world_dir(B, nl, nw);
    rbc_kc_to_world(B, sl, sw);
    rbc_kc_to_world(A, sl, sa);
    float d = nw[0] * sw[0] + nw[1] * sw[1] + nw[2] * sw[2] + thick;
    *v = d - (nw[0] * pw[0] + nw[1] * pw[1] + nw[2] * pw[2]);
    return *v > 0.0f;
}

/* ---- a backend's per-particle kernels over the slots ---- */

RBC_HD float *rbc_kc_field(float *ct, uint32_t n, uint32_t slots, int field, uint32_t s,
                           uint32_t i) {
    return ct + ((size_t)field * slots + s) * n + i;
}

/* RBC_KERNEL_COLLIDE_FRAMES: collider ci's frames at the substep's fractions f0, f1. */
RBC_HD void rbc_kc_frames(uint32_t ci, rbc_dcollider *cols, float f0, float f1) {
    rbc_dcollider *c = &cols[ci];
    rbc_kc_frame_at(c->last_position, c->last_rotation, c->position, c->rotation, f0, &c->A);
    rbc_kc_frame_at(c->last_position, c->last_rotation, c->position, c->rotation, f1, &c->B);
}

/* RBC_KERNEL_COLLIDE_DETECT for particle i (rbc_collide_detect): its contacts with
 * every collider, in collider order, over its motion from x to the prediction p.
 * Writes ncon[i] (the slots used) and returns the contacts found, which may exceed
 * slots (the caller fails the step then). */
RBC_HD uint32_t rbc_kc_detect(uint32_t i, const rbc_dcollider *cols, uint32_t ncols,
                              float *const x[3], float *const p[3],
                              const uint8_t *pinned, float cloth_thick, float cloth_mu,
                              float margin, float inv_h, uint32_t n, uint32_t slots, float *ct,
                              uint32_t *ncon) {
    uint32_t m = 0;
    if (!pinned[i])
        for (uint32_t ci = 0; ci < ncols; ++ci) {
            const rbc_dcollider *col = &cols[ci];
            const float thick = col->thickness + cloth_thick;
            const float reach = thick + margin;
            const float mu = col->friction > cloth_mu ? col->friction : cloth_mu;
            float xw[3] = {x[0][i], x[1][i], x[2][i]};
            float yw[3] = {p[0][i], p[1][i], p[2][i]};
            float a[3], b[3], nl[3], sl[3];
            rbc_kc_to_local(&col->A, xw, a);
            rbc_kc_to_local(&col->B, yw, b);
            if (!rbc_kc_cull(a, b, col->lo, col->hi, reach)) continue;
            if (!rbc_kc_shape_contact(col->shape, col->radius, col->he, a, b, reach, sl, nl))
                continue;
            const uint32_t s = m++;
            if (s >= slots) continue;
            float cn[3], d, u[3], depth;
            rbc_kc_contact_make(&col->A, &col->B, sl, nl, thick, inv_h, yw, cn, &d, u, &depth);
            *rbc_kc_field(ct, n, slots, RBC_KC_N0, s, i) = cn[0];
            *rbc_kc_field(ct, n, slots, RBC_KC_N1, s, i) = cn[1];
            *rbc_kc_field(ct, n, slots, RBC_KC_N2, s, i) = cn[2];
            *rbc_kc_field(ct, n, slots, RBC_KC_D, s, i) = d;
            *rbc_kc_field(ct, n, slots, RBC_KC_U0, s, i) = u[0];
            *rbc_kc_field(ct, n, slots, RBC_KC_U1, s, i) = u[1];
            *rbc_kc_field(ct, n, slots, RBC_KC_U2, s, i) = u[2];
            *rbc_kc_field(ct, n, slots, RBC_KC_DEPTH, s, i) = depth;
            *rbc_kc_field(ct, n, slots, RBC_KC_LAST, s, i) = 0.0f;
            *rbc_kc_field(ct, n, slots, RBC_KC_MU, s, i) = mu;
            *rbc_kc_field(ct, n, slots, RBC_KC_FN, s, i) = 0.0f;
        }
    ncon[i] = m < slots ? m : slots;
    return m;
}

/* One slot's half-space, normal and velocity. */
RBC_HD void rbc_kc_slot(const float *ct, uint32_t n, uint32_t slots, uint32_t s, uint32_t i,
                        float cn[3], float *d, float u[3]) {
    const size_t st = (size_t)slots * n, at = (size_t)s * n + i;
    cn[0] = ct[RBC_KC_N0 * st + at];
    cn[1] = ct[RBC_KC_N1 * st + at];
    cn[2] = ct[RBC_KC_N2 * st + at];
    *d = ct[RBC_KC_D * st + at];
    u[0] = ct[RBC_KC_U0 * st + at];
    u[1] = ct[RBC_KC_U1 * st + at];
    u[2] = ct[RBC_KC_U2 * st + at];
}

/* RBC_KERNEL_COLLIDE_PROJECT for particle i of P (p, or Jacobi's destination): its
 * contacts in order (rbc_collide_project, rbc_collide_project_color); h > 0 adds the
 * pass's friction. */
RBC_HD void rbc_kc_project_particle(uint32_t i, uint32_t n, uint32_t slots, const uint32_t *ncon,
                                    float *ct, float *const x[3], float *const P[3],
                                    float h) {
    const uint32_t m = ncon[i];
    if (!m) return;
    float p[3] = {P[0][i], P[1][i], P[2][i]};
    const float xi[3] = {x[0][i], x[1][i], x[2][i]};
    for (uint32_t s = 0; s < m; ++s) {
        float cn[3], d, u[3], ft[3];
        rbc_kc_slot(ct, n, slots, s, i, cn, &d, u);
        const float mu = *rbc_kc_field(ct, n, slots, RBC_KC_MU, s, i);
        rbc_kc_project(cn, d, mu, u, xi, p, h, rbc_kc_field(ct, n, slots, RBC_KC_LAST, s, i), ft);
    }
    P[0][i] = p[0];
    P[1][i] = p[1];
    P[2][i] = p[2];
}

/* The residual of particle i's row of Eq. 6, f = (m/h^2 + sum s) p_i - b_i - sum_j
 * s_ij p_j (rbc_collide_normal_forces), inv_h2 = 1 / (h h). */
RBC_HD void rbc_kc_row_residual(uint32_t i, const uint32_t *adj_start, const uint32_t *adj_nbr,
                                const float *adj_k, const float *mass, const float *ksum,
                                float *const b[3], float *const p[3], float inv_h2,
                                float f[3]) {
    const float row = mass[i] * inv_h2 + ksum[i];
    f[0] = row * p[0][i] - b[0][i];
    f[1] = row * p[1][i] - b[1][i];
    f[2] = row * p[2][i] - b[2][i];
    for (uint32_t k = adj_start[i]; k < adj_start[i + 1]; ++k) {
        const uint32_t j = adj_nbr[k];
        const float kk = adj_k[k];
        f[0] -= kk * p[0][j];
        f[1] -= kk * p[1][j];
        f[2] -= kk * p[2][j];
    }
}

/* RBC_KERNEL_COLLIDE_NORMAL for particle i: each contact's normal force for its
 * friction, from the positions the solve ended with (only reads p). */
RBC_HD void rbc_kc_normal_particle(uint32_t i, uint32_t n, uint32_t slots, const uint32_t *ncon,
                                   float *ct, const uint32_t *adj_start, const uint32_t *adj_nbr,
                                   const float *adj_k, const float *mass, const float *ksum,
                                   float *const b[3], float *const p[3], float h) {
    const uint32_t m = ncon[i];
    if (!m) return;
    const float inv_h2 = 1.0f / (h * h);
    float f[3];
    rbc_kc_row_residual(i, adj_start, adj_nbr, adj_k, mass, ksum, b, p, inv_h2, f);
    for (uint32_t s = 0; s < m; ++s) {
        float *fn_out = rbc_kc_field(ct, n, slots, RBC_KC_FN, s, i);
        *fn_out = 0.0f;
        if (!(*rbc_kc_field(ct, n, slots, RBC_KC_MU, s, i) > 0.0f)) continue;
        const float fn = f[0] * *rbc_kc_field(ct, n, slots, RBC_KC_N0, s, i) +
                         f[1] * *rbc_kc_field(ct, n, slots, RBC_KC_N1, s, i) +
                         f[2] * *rbc_kc_field(ct, n, slots, RBC_KC_N2, s, i);
        *fn_out = fn > 0.0f ? fn : 0.0f;
    }
}

/* RBC_KERNEL_COLLIDE_FINISH for particle i: friction after the solve (without color
 * passes), its contacts in order. */
RBC_HD void rbc_kc_finish_particle(uint32_t i, uint32_t n, uint32_t slots, const uint32_t *ncon,
                                   float *ct, const float *mass, float *const x[3],
                                   float *const P[3], float h) {
    const uint32_t m = ncon[i];
    if (!m) return;
    float p[3] = {P[0][i], P[1][i], P[2][i]};
    const float xi[3] = {x[0][i], x[1][i], x[2][i]};
    for (uint32_t s = 0; s < m; ++s) {
        float cn[3], d, u[3], corr[3];
        rbc_kc_slot(ct, n, slots, s, i, cn, &d, u);
        (void)rbc_kc_finish_friction(cn, d, u, *rbc_kc_field(ct, n, slots, RBC_KC_DEPTH, s, i),
                               *rbc_kc_field(ct, n, slots, RBC_KC_LAST, s, i),
                               *rbc_kc_field(ct, n, slots, RBC_KC_MU, s, i),
                               *rbc_kc_field(ct, n, slots, RBC_KC_FN, s, i), mass[i], xi, p, h,
                               corr);
    }
    P[0][i] = p[0];
    P[1][i] = p[1];
    P[2][i] = p[2];
}

/* RBC_KERNEL_COLLIDE_POST for particle i (rbc_collide_post): the safety pass over every
 * collider in order, for a free particle the solve moved farther than margin from its
 * prediction y. */
RBC_HD void rbc_kc_post_particle(uint32_t i, const rbc_dcollider *cols, uint32_t ncols,
                                 float *const x[3], float *const y[3],
                                 float *const P[3], const uint8_t *pinned, float cloth_thick,
                                 float margin) {
    const float m2 = margin * margin;
    float pw[3] = {P[0][i], P[1][i], P[2][i]};
    const float xw[3] = {x[0][i], x[1][i], x[2][i]};
    for (uint32_t ci = 0; ci < ncols; ++ci) {
        const rbc_dcollider *col = &cols[ci];
        /* Recomputed per collider from the current p, as the CPU's collider-outer
         * loop sees it. */
        float e0 = pw[0] - y[0][i], e1 = pw[1] - y[1][i], e2 = pw[2] - y[2][i];
        if (e0 * e0 + e1 * e1 + e2 * e2 <= m2 || pinned[i]) continue;
        float v, nw[3], sw[3], sa[3];
        if (!rbc_kc_post_one(col->shape, col->radius, col->he, col->lo, col->hi, &col->A,
                             &col->B, col->thickness + cloth_thick, xw, pw, &v, nw, sw, sa))
            continue;
        for (int ax = 0; ax < 3; ++ax) pw[ax] += v * nw[ax];
    }
    P[0][i] = pw[0];
    P[1][i] = pw[1];
    P[2][i] = pw[2];
}
#endif
