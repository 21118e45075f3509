/* Collider shape geometry (core/shapes.c), each check against a bound derived from
 * float rounding (u = 2^-24) or from the geometry:
 *  - sphere, capsule, box: phi and n against closed forms (double) at random points
 *    inside, outside, near faces, edges and corners: phi within u |phi| plus double
 *    noise (evaluated in double, rounded once), n within u per component plus double
 *    noise, |n| = 1 within 2u; the conventions at the centre / on the axis / inside a
 *    box; plane; the max_dist contract; bounds;
 *  - n is the gradient: central differences of phi agree within L h / 2 + rounding / h
 *    (L the Lipschitz constant of grad phi, 1 / distance to the medial axis), and
 *    phi(q + s n) = phi(q) + s outside (a distance field grows along its gradient);
 *  - raycasts enter where the segment was built to enter (t within the rounding of
 *    the endpoints over len cos theta), with the analytic normal; no hit for segments
 *    that miss, stop short, or start inside; the plane's t = a_y / (a_y - b_y);
 *  - triangle meshes: a closed subdivided box (and its inside-out twin) has the
 *    analytic box's phi, sign and n to the rounding of the mesh (one float rounding of
 *    a double result, whose error grows as 1 / sin^2 of the smallest angle); a UV
 *    sphere lies between the sphere through its vertices and that sphere shrunk by its
 *    tessellation error H (computed here), so sd(R_max) - tol <= phi_mesh <= sd(R) + H
 *    + tol; box-mesh raycasts match the analytic box; an open grid gives the unsigned
 *    distance to the square and raycasts from both sides with the normal facing the
 *    start;
 *  - the BVH equals the brute-force loop bitwise (phi, n, t, return) for 10,000 random
 *    points (max_dist inf, 0.05, 0, -0.05 in turn: the bounds and grid culls of closed
 *    meshes included) and 10,000 random segments on a UV sphere, the box, the grid and
 *    a fan of slivers; an independent closest point in double agrees to rounding;
 *  - errors name the triangle and corner / the vertex; degenerate triangles are
 *    counted and skipped; a counting allocator failing at the k-th allocation, for
 *    every k, gets RBC_ERR_OUT_OF_MEMORY and nothing leaked; info.bytes is what the
 *    allocator holds.
 * Also prints (not asserted) the median query time on a 20K-triangle sphere.
 */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "check.h"
#include "shapes.h"

#define U 0x1p-24 /* unit roundoff of float */

/* ---- deterministic random numbers (splitmix64) ---- */
static uint64_t rng = 0x243F6A8885A308D3ull;
static double urand(void) {
    uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1p-53;
}
static double rrange(double a, double b) { return a + (b - a) * urand(); }
static void rand_dir(double d[3]) {
    for (;;) {
        double x = rrange(-1, 1), y = rrange(-1, 1), z = rrange(-1, 1), l = x * x + y * y + z * z;
        if (l > 1e-4 && l <= 1.0) {
            l = sqrt(l);
            d[0] = x / l, d[1] = y / l, d[2] = z / l;
            return;
        }
    }
}
static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }
static double normf(const float a[3]) {
    return sqrt((double)a[0] * a[0] + (double)a[1] * a[1] + (double)a[2] * a[2]);
}
static void to_float(const double d[3], float f[3]) {
    f[0] = (float)d[0], f[1] = (float)d[1], f[2] = (float)d[2];
}

static rbc_shape_geom geom(rbc_shape kind, float r, float hx, float hy, float hz) {
    rbc_shape_geom g;
    memset(&g, 0, sizeof g);
    g.kind = kind, g.radius = r;
    g.half_extents[0] = hx, g.half_extents[1] = hy, g.half_extents[2] = hz;
    return g;
}

/* ---- closed forms (double) ---- */
/* sphere radius; capsule radius, half-length: the floats the shapes hold */
#define SR ((double)0.7f)
#define CR ((double)0.3f)
#define CH 0.5
static const double BH[3] = {0.75, 0.375, 0.5}; /* box half extents (exact floats, and
                                                   exact on a 4 x 4 face lattice) */

/* The shapes of the closed forms, and their geoms in that order. */
static const rbc_shape KINDS[3] = {RBC_SHAPE_SPHERE, RBC_SHAPE_CAPSULE, RBC_SHAPE_BOX};
static void analytic_geoms(rbc_shape_geom gs[3]) {
    gs[0] = geom(RBC_SHAPE_SPHERE, (float)SR, 0, 0, 0);
    gs[1] = geom(RBC_SHAPE_CAPSULE, (float)CR, 0, (float)CH, 0);
    gs[2] = geom(RBC_SHAPE_BOX, 0, (float)BH[0], (float)BH[1], (float)BH[2]);
}

static double ref_distance(rbc_shape kind, const float qf[3], double n[3]) {
    double q[3] = {qf[0], qf[1], qf[2]};
    if (kind == RBC_SHAPE_SPHERE || kind == RBC_SHAPE_CAPSULE) {
        double c[3] = {0, 0, 0}, r = SR;
        if (kind == RBC_SHAPE_CAPSULE) c[1] = fmin(fmax(q[1], -CH), CH), r = CR;
        double d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]}, l = norm3(d);
        for (int i = 0; i < 3; ++i) n[i] = d[i] / l;
        return l - r;
    }
    /* box: outside, the distance to the clamped point; inside, minus the least
     * penetration */
    double o[3], s = 0, pen = INFINITY;
    int k = 0;
    for (int i = 0; i < 3; ++i) {
        o[i] = fmax(fabs(q[i]) - BH[i], 0.0);
        s += o[i] * o[i];
        if (BH[i] - fabs(q[i]) < pen) pen = BH[i] - fabs(q[i]), k = i;
    }
    if (s > 0) {
        double d = sqrt(s);
        for (int i = 0; i < 3; ++i) n[i] = copysign(o[i] / d, q[i]);
        return d;
    }
    n[0] = n[1] = n[2] = 0;
    n[k] = q[k] < 0 ? -1 : 1;
    return -pen;
}

/* A random point near the shape: anywhere around it, near its surface, or (box)
 * near an edge or a corner. */
static void sample_point(rbc_shape kind, float q[3]) {
    double p[3], d[3];
    int mode = (int)(urand() * 4);
    if (mode == 0) {
        for (int i = 0; i < 3; ++i) p[i] = rrange(-1.6, 1.6);
    } else if (kind == RBC_SHAPE_BOX && mode >= 2) {
        /* a corner (mode 2) or an edge (mode 3), plus a small offset */
        for (int i = 0; i < 3; ++i) p[i] = (urand() < 0.5 ? -1 : 1) * BH[i];
        if (mode == 3) {
            int ax = (int)(urand() * 3);
            p[ax] = rrange(-BH[ax], BH[ax]);
        }
        rand_dir(d);
        double s = pow(10.0, rrange(-4, -1));
        for (int i = 0; i < 3; ++i) p[i] += s * d[i];
    } else {
        rand_dir(d);
        double off = (urand() < 0.5 ? -1 : 1) * pow(10.0, rrange(-4, -0.5));
        if (kind == RBC_SHAPE_SPHERE) {
            for (int i = 0; i < 3; ++i) p[i] = (SR + off) * d[i];
        } else if (kind == RBC_SHAPE_CAPSULE) {
            double y = rrange(-CH - 0.4, CH + 0.4), c = fmin(fmax(y, -CH), CH);
            if (fabs(y) <= CH) d[1] = 0, d[0] /= hypot(d[0], d[2]), d[2] /= hypot(d[0], d[2]);
            double rr = fmax(CR + off, 0.0);
            for (int i = 0; i < 3; ++i) p[i] = rr * d[i];
            p[1] += c;
        } else {
            int ax = (int)(urand() * 3);
            for (int i = 0; i < 3; ++i) p[i] = rrange(-BH[i], BH[i]);
            p[ax] = (urand() < 0.5 ? -1 : 1) * (BH[ax] + off);
        }
    }
    to_float(p, q);
}

static void test_analytic_distance(void) {
    rbc_shape_geom gs[3];
    analytic_geoms(gs);
    for (int s = 0; s < 3; ++s) {
        double worst_phi = 0, worst_n = 0, worst_unit = 0;
        int bad_ret = 0, inside = 0;
        for (int it = 0; it < 20000; ++it) {
            float q[3], n[3], phi = NAN;
            sample_point(KINDS[s], q);
            double nr[3], pr = ref_distance(KINDS[s], q, nr);
            int ret = rbc_shape_distance(&gs[s], q, INFINITY, &phi, n);
            bad_ret += ret != 1;
            inside += pr < 0;
            /* Evaluated in double (relative error ~1e-16 of |q| + size) and rounded
             * to float once: |phi - pr| <= u |pr| + 2^-45 (|q| + 1). */
            double qn = normf(q) + 1.0;
            worst_phi = fmax(worst_phi, fabs(phi - pr) / (U * fabs(pr) + 0x1p-45 * qn));
            /* Box points inside with two penetrations within rounding: either face. */
            int tie = 0;
            if (KINDS[s] == RBC_SHAPE_BOX && pr < 0) {
                double pen[3];
                for (int i = 0; i < 3; ++i) pen[i] = BH[i] - fabs((double)q[i]);
                for (int i = 0; i < 3; ++i)
                    for (int j = i + 1; j < 3; ++j) tie |= fabs(pen[i] - pen[j]) < 1e-12;
            }
            if (!tie)
                for (int i = 0; i < 3; ++i)
                    worst_n = fmax(worst_n, fabs(n[i] - nr[i]) / (U + 0x1p-45 * qn / fabs(pr)));
            worst_unit = fmax(worst_unit, fabs(normf(n) - 1.0) / (2 * U));
            /* max_dist: 1 exactly when phi <= max_dist */
            float md = phi - 0.01f;
            CHECK_EQ(rbc_shape_distance(&gs[s], q, md, &phi, n), 0);
            md = phi;
            CHECK_EQ(rbc_shape_distance(&gs[s], q, md, &phi, n), 1);
        }
        printf("%s: %d inside of 20000; worst phi error %.3g, n error %.3g, | |n| - 1 | %.3g "
               "of their bounds\n",
               s == 0 ? "sphere" : s == 1 ? "capsule" : "box", inside, worst_phi, worst_n,
               worst_unit);
        CHECK_EQ(bad_ret, 0);
        CHECK(inside > 2000 && inside < 18000);
        CHECK(worst_phi <= 1.0);
        CHECK(worst_n <= 1.0);
        CHECK(worst_unit <= 1.0);
    }
    /* The conventions where n is not defined, and the plane. */
    float z[3] = {0, 0, 0}, phi, n[3];
    CHECK_EQ(rbc_shape_distance(&gs[0], z, 0.0f, &phi, n), 1);
    CHECK(phi == -(float)SR && n[0] == 0 && n[1] == 1 && n[2] == 0);
    float ax[3] = {0, 0.2f, 0};
    CHECK_EQ(rbc_shape_distance(&gs[1], ax, 0.0f, &phi, n), 1);
    CHECK(phi == -(float)CR && n[0] == 1 && n[1] == 0 && n[2] == 0);
    CHECK_EQ(rbc_shape_distance(&gs[2], z, 0.0f, &phi, n), 1); /* y: least penetration */
    CHECK(phi == -(float)BH[1] && n[0] == 0 && n[1] == 1 && n[2] == 0);
    float cube_c[3] = {0, 0, 0};
    rbc_shape_geom cube = geom(RBC_SHAPE_BOX, 0, 0.5f, 0.5f, 0.5f);
    CHECK_EQ(rbc_shape_distance(&cube, cube_c, 0.0f, &phi, n), 1); /* ties: lowest axis */
    CHECK(phi == -0.5f && n[0] == 1 && n[1] == 0 && n[2] == 0);
    rbc_shape_geom pl = geom(RBC_SHAPE_PLANE, 0, 0, 0, 0);
    float qp[3] = {3.0f, -0.25f, -7.0f};
    CHECK_EQ(rbc_shape_distance(&pl, qp, 0.0f, &phi, n), 1);
    CHECK(phi == -0.25f && n[0] == 0 && n[1] == 1 && n[2] == 0);
    qp[1] = 2.0f;
    CHECK_EQ(rbc_shape_distance(&pl, qp, 1.0f, &phi, n), 0);
    /* Unknown kind, and a mesh shape without a mesh: no contact. */
    rbc_shape_geom bad = geom(99, 1, 1, 1, 1);
    CHECK_EQ(rbc_shape_distance(&bad, z, INFINITY, &phi, n), 0);
    rbc_shape_geom nomesh = geom(RBC_SHAPE_TRIANGLE_MESH, 0, 0, 0, 0);
    CHECK_EQ(rbc_shape_distance(&nomesh, z, INFINITY, &phi, n), 0);
    /* Bounds. */
    float lo[3], hi[3];
    rbc_shape_bounds(&gs[1], lo, hi);
    CHECK(lo[0] == -(float)CR && hi[0] == (float)CR && hi[1] == (float)(CH + CR) &&
          lo[1] == -(float)(CH + CR) && hi[2] == (float)CR);
    rbc_shape_bounds(&gs[2], lo, hi);
    CHECK(lo[0] == -0.75f && hi[1] == 0.375f && lo[2] == -0.5f);
    rbc_shape_bounds(&gs[0], lo, hi);
    CHECK(lo[1] == -(float)SR && hi[2] == (float)SR);
    rbc_shape_bounds(&pl, lo, hi);
    CHECK(lo[0] == -INFINITY && lo[1] == -INFINITY && hi[0] == INFINITY && hi[1] == 0.0f &&
          hi[2] == INFINITY);
}

/* n is the gradient of phi. Central differences with step h of a function whose
 * gradient is L-Lipschitz along the stencil err by at most L h / 2 (Taylor with the
 * integral remainder), plus the rounding of the two values (u |phi| each) over 2h;
 * h = sqrt(2 u |phi| / L) balances the two. L = 1 / (distance to the medial axis -
 * h): outside a convex shape 1 / (phi - h); inside a sphere or capsule 1 / (|q - c| -
 * h); inside a box, 0 while the stencil stays off the planes where two penetrations
 * tie. */
static void test_gradient(void) {
    rbc_shape_geom gs[3];
    analytic_geoms(gs);
    for (int s = 0; s < 3; ++s) {
        double worst_fd = 0, worst_ray = 0;
        int used = 0, along = 0;
        for (int it = 0; it < 4000; ++it) {
            float q[3], n[3], phi;
            sample_point(KINDS[s], q);
            rbc_shape_distance(&gs[s], q, INFINITY, &phi, n);
            double L, axis_dist;
            if (KINDS[s] == RBC_SHAPE_BOX) {
                if (phi >= 0) {
                    axis_dist = phi;
                } else {
                    double pen[3];
                    for (int i = 0; i < 3; ++i) pen[i] = BH[i] - fabs((double)q[i]);
                    double a = fmin(pen[0], fmin(pen[1], pen[2])), b = INFINITY;
                    for (int i = 0; i < 3; ++i)
                        if (pen[i] != a) b = fmin(b, pen[i]);
                    axis_dist = INFINITY;
                    if (b - a < 0.02) continue; /* near a tie plane */
                }
            } else {
                double c = KINDS[s] == RBC_SHAPE_CAPSULE ? fmin(fmax(q[1], -CH), CH) : 0;
                double d[3] = {q[0], q[1] - c, q[2]};
                axis_dist = phi >= 0 ? phi : norm3(d);
            }
            if (axis_dist < 0.05) continue;
            double rough = U * (fabs(phi) + 1e-3);
            double h = axis_dist == INFINITY ? 1e-3 : sqrt(2 * rough * axis_dist);
            L = axis_dist == INFINITY ? 0 : 1.0 / (axis_dist - 2 * h);
            ++used;
            for (int i = 0; i < 3; ++i) {
                float qp[3] = {q[0], q[1], q[2]}, qm[3] = {q[0], q[1], q[2]}, np[3], pp, pm;
                qp[i] = (float)(q[i] + h), qm[i] = (float)(q[i] - h);
                rbc_shape_distance(&gs[s], qp, INFINITY, &pp, np);
                rbc_shape_distance(&gs[s], qm, INFINITY, &pm, np);
                double step = (double)qp[i] - qm[i]; /* the step actually taken */
                double fd = ((double)pp - pm) / step;
                double tol = L * step / 4 + U * (fabs(pp) + fabs(pm)) / step + 4 * U;
                worst_fd = fmax(worst_fd, fabs(fd - n[i]) / tol);
            }
            /* Outside: phi(q + s n) = phi(q) + (q2 - q) . n exactly (the closest point
             * stays), up to u of each phi and the rounding of n (u per component). */
            if (phi > 0) {
                float q2[3];
                double sd = 0.05, dlt = 0, mag = 0;
                for (int i = 0; i < 3; ++i) {
                    q2[i] = (float)(q[i] + sd * n[i]);
                    dlt += ((double)q2[i] - q[i]) * n[i];
                    mag += fabs((double)q2[i] - q[i]);
                }
                float n2[3], phi2;
                rbc_shape_distance(&gs[s], q2, INFINITY, &phi2, n2);
                double tol = U * (fabs(phi) + fabs(phi2)) + 2 * U * mag + 0x1p-45;
                worst_ray = fmax(worst_ray, fabs(phi2 - (phi + dlt)) / tol);
                ++along;
            }
        }
        printf("%s: central differences vs n at %d points, worst %.3g of the bound; "
               "phi(q + s n) - phi(q) - s at %d, worst %.3g of the bound\n",
               s == 0 ? "sphere" : s == 1 ? "capsule" : "box", used, worst_fd, along, worst_ray);
        CHECK(used > 1000);
        CHECK(worst_fd <= 1.0);
        CHECK(worst_ray <= 1.0);
    }
}

/* ---- raycasts against the analytic shapes ---- */

/* A random surface point of shape s and its outward normal; box face points stay
 * 0.01 from the edges. */
static void surface_point(rbc_shape kind, double p[3], double n[3]) {
    if (kind == RBC_SHAPE_SPHERE) {
        rand_dir(n);
        for (int i = 0; i < 3; ++i) p[i] = SR * n[i];
    } else if (kind == RBC_SHAPE_CAPSULE) {
        rand_dir(n);
        double c = 0;
        if (urand() < 0.5) {
            double l = hypot(n[0], n[2]);
            n[0] /= l, n[1] = 0, n[2] /= l;
            c = rrange(-CH, CH);
        } else {
            c = n[1] >= 0 ? CH : -CH;
        }
        for (int i = 0; i < 3; ++i) p[i] = CR * n[i];
        p[1] += c;
    } else {
        int ax = (int)(urand() * 3);
        double sg = urand() < 0.5 ? -1 : 1;
        for (int i = 0; i < 3; ++i) p[i] = rrange(-BH[i] + 0.01, BH[i] - 0.01), n[i] = 0;
        p[ax] = sg * BH[ax], n[ax] = sg;
    }
}

static void test_analytic_raycast(void) {
    rbc_shape_geom gs[3];
    analytic_geoms(gs);
    const double radius[3] = {SR, CR, INFINITY};
    for (int s = 0; s < 3; ++s) {
        double worst_t = 0, worst_n = 0;
        int missed = 0, false_hits = 0;
        for (int it = 0; it < 5000; ++it) {
            double p[3], ns[3], d[3];
            surface_point(KINDS[s], p, ns);
            do rand_dir(d);
            while (dot3(d, ns) > -0.3);
            double cos_t = -dot3(d, ns), len = rrange(0.1, 2.0), te = rrange(0.02, 0.98);
            double ad[3], bd[3];
            float a[3], b[3], t, n[3];
            for (int i = 0; i < 3; ++i) ad[i] = p[i] - te * len * d[i], bd[i] = ad[i] + len * d[i];
            to_float(ad, a), to_float(bd, b);
            /* Entry: phi(a + t (b - a)) = 0; moving the endpoints by da, db (their
             * rounding, u |a| and u |b|) moves t by at most (|da| + |db|) / (len cos)
             * to first order; twice that, plus the rounding of t. */
            double da = U * norm3(ad), db = U * norm3(bd);
            double tol_t = 2 * (da + db) / (len * cos_t) + 2 * U;
            if (rbc_shape_raycast(&gs[s], a, b, &t, n)) {
                worst_t = fmax(worst_t, fabs(t - te) / tol_t);
                /* n at the hit point: off by |dp| / radius, |dp| <= the endpoints'
                 * rounding / cos plus len tol_t; the box's is exact. */
                double tol_n = radius[s] == INFINITY
                                   ? 0
                                   : (2 * (da + db) / cos_t + len * tol_t + 2 * U * norm3(p)) /
                                             radius[s] +
                                         2 * U;
                for (int i = 0; i < 3; ++i)
                    worst_n = fmax(worst_n, tol_n ? fabs(n[i] - ns[i]) / tol_n
                                                  : (n[i] == ns[i] ? 0 : INFINITY));
            } else {
                ++missed;
            }
            /* Stopping short (entry at te > 1): no hit. */
            double te2 = rrange(1.05, 2.0);
            for (int i = 0; i < 3; ++i) ad[i] = p[i] - te2 * len * d[i], bd[i] = ad[i] + len * d[i];
            to_float(ad, a), to_float(bd, b);
            false_hits += rbc_shape_raycast(&gs[s], a, b, &t, n);
            /* In the tangent plane lifted by gap (outside a convex shape by gap): no hit. */
            double tg[3] = {d[0] + cos_t * ns[0], d[1] + cos_t * ns[1], d[2] + cos_t * ns[2]};
            double tl = norm3(tg), gap = pow(10.0, rrange(-3, -1));
            if (tl > 1e-3) {
                for (int i = 0; i < 3; ++i) {
                    ad[i] = p[i] + gap * ns[i] - len * tg[i] / tl;
                    bd[i] = p[i] + gap * ns[i] + len * tg[i] / tl;
                }
                to_float(ad, a), to_float(bd, b);
                false_hits += rbc_shape_raycast(&gs[s], a, b, &t, n);
            }
            /* Starting inside (depth >= 1e-3), going anywhere: no entry. */
            double depth = rrange(1e-3, 0.2);
            for (int i = 0; i < 3; ++i) ad[i] = p[i] - depth * ns[i], bd[i] = ad[i] + len * d[i];
            if (KINDS[s] == RBC_SHAPE_BOX) { /* keep inside: not deeper than the box */
                for (int i = 0; i < 3; ++i) ad[i] = fmax(fmin(ad[i], BH[i] - 1e-3), -BH[i] + 1e-3);
            }
            if (urand() < 0.5)
                for (int i = 0; i < 3; ++i) bd[i] = ad[i] - 2 * len * ns[i] + 0.3 * d[i];
            to_float(ad, a), to_float(bd, b);
            false_hits += rbc_shape_raycast(&gs[s], a, b, &t, n);
        }
        printf("%s raycast: worst t error %.3g, n error %.3g of the bounds; %d entries "
               "missed, %d false hits\n",
               s == 0 ? "sphere" : s == 1 ? "capsule" : "box", worst_t, worst_n, missed,
               false_hits);
        CHECK_EQ(missed, 0);
        CHECK_EQ(false_hits, 0);
        CHECK(worst_t <= 1.0);
        CHECK(worst_n <= 1.0);
    }
    /* The plane: t = a_y / (a_y - b_y) (computed in double from the floats, rounded). */
    rbc_shape_geom pl = geom(RBC_SHAPE_PLANE, 0, 0, 0, 0);
    int bad = 0;
    for (int it = 0; it < 2000; ++it) {
        float a[3] = {(float)rrange(-5, 5), (float)rrange(0, 2), (float)rrange(-5, 5)};
        float b[3] = {(float)rrange(-5, 5), (float)rrange(-2, -1e-3), (float)rrange(-5, 5)};
        float t, n[3];
        double te = (double)a[1] / ((double)a[1] - b[1]);
        if (!rbc_shape_raycast(&pl, a, b, &t, n) || fabs(t - te) > U * te || n[1] != 1.0f) ++bad;
        if (rbc_shape_raycast(&pl, b, a, &t, n)) ++bad; /* from below: starts inside */
        float c[3] = {b[0], (float)rrange(0, 2), b[2]};
        if (rbc_shape_raycast(&pl, a, c, &t, n)) ++bad; /* stays above */
    }
    CHECK_EQ(bad, 0);
    /* Touching without entering: a tangent to the sphere, along a box face. */
    rbc_shape_geom sp = geom(RBC_SHAPE_SPHERE, 1.0f, 0, 0, 0), bx = geom(RBC_SHAPE_BOX, 0, 1, 1, 1);
    float a[3] = {-2, 1, 0}, b[3] = {2, 1, 0}, t, n[3];
    CHECK_EQ(rbc_shape_raycast(&sp, a, b, &t, n), 0);
    CHECK_EQ(rbc_shape_raycast(&bx, a, b, &t, n), 0);
    /* On the surface going in: t = 0. */
    float a2[3] = {0, 1, 0}, b2[3] = {0, 0, 0};
    CHECK_EQ(rbc_shape_raycast(&bx, a2, b2, &t, n), 1);
    CHECK(t == 0.0f && !signbit(t) && n[1] == 1.0f);
    CHECK_EQ(rbc_shape_raycast(&sp, a2, b2, &t, n), 1);
    CHECK(t == 0.0f && n[1] == 1.0f);
}

/* ---- triangle meshes built here ---- */
typedef struct tmesh {
    float *pos;
    uint32_t *tri;
    uint32_t nv, nt;
} tmesh;

static void tmesh_free(tmesh *m) {
    free(m->pos);
    free(m->tri);
}

/* The box |x_i| <= h_i, each face an N x N lattice of quads cut in two, outward
 * (or, flip, inward) winding, vertices shared along the edges: closed. */
static tmesh box_mesh(const double h[3], uint32_t N, int flip) {
    uint32_t S = N + 1;
    uint32_t *id = malloc(sizeof(uint32_t) * S * S * S);
    for (uint32_t i = 0; i < S * S * S; ++i) id[i] = UINT32_MAX;
    tmesh m = {malloc(sizeof(float) * 3 * S * S * S), malloc(sizeof(uint32_t) * 36 * N * N), 0, 0};
    for (int ax = 0; ax < 3; ++ax)
        for (int sg = -1; sg <= 1; sg += 2) {
            int u = (ax + 1) % 3, v = (ax + 2) % 3;
            for (uint32_t i = 0; i < N; ++i)
                for (uint32_t j = 0; j < N; ++j) {
                    uint32_t c[4];
                    for (int k = 0; k < 4; ++k) { /* (i,j) (i+1,j) (i+1,j+1) (i,j+1) */
                        uint32_t l[3];
                        l[ax] = sg > 0 ? N : 0;
                        l[u] = i + (k == 1 || k == 2), l[v] = j + (k >= 2);
                        uint32_t key = (l[0] * S + l[1]) * S + l[2];
                        if (id[key] == UINT32_MAX) {
                            for (int x = 0; x < 3; ++x)
                                m.pos[3 * m.nv + x] = (float)(-h[x] + 2.0 * h[x] * l[x] / N);
                            id[key] = m.nv++;
                        }
                        c[k] = id[key];
                    }
                    /* e_u x e_v = e_ax: (c0, c1, c2) faces +ax */
                    uint32_t t2[2][3] = {{c[0], c[1], c[2]}, {c[0], c[2], c[3]}};
                    for (int k = 0; k < 2; ++k) {
                        int rev = (sg < 0) != (flip != 0);
                        m.tri[3 * m.nt] = t2[k][0];
                        m.tri[3 * m.nt + 1] = t2[k][rev ? 2 : 1];
                        m.tri[3 * m.nt + 2] = t2[k][rev ? 1 : 2];
                        m.nt++;
                    }
                }
        }
    free(id);
    return m;
}

/* A UV sphere of radius R: L slices, S stacks, 2 L (S - 1) triangles, each wound so
 * its normal faces away from the centre. */
static tmesh uv_sphere(double R, uint32_t L, uint32_t S) {
    tmesh m;
    m.nv = 2 + (S - 1) * L;
    m.nt = 2 * L * (S - 1);
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.tri = malloc(sizeof(uint32_t) * 3 * m.nt);
    const double pi = 3.14159265358979323846;
    m.pos[0] = 0, m.pos[1] = (float)R, m.pos[2] = 0;
    for (uint32_t j = 1; j < S; ++j)
        for (uint32_t i = 0; i < L; ++i) {
            double th = pi * j / S, ph = 2 * pi * i / L;
            float *p = m.pos + 3 * (1 + (j - 1) * L + i);
            p[0] = (float)(R * sin(th) * cos(ph)), p[1] = (float)(R * cos(th));
            p[2] = (float)(R * sin(th) * sin(ph));
        }
    float *sp = m.pos + 3 * (m.nv - 1);
    sp[0] = 0, sp[1] = (float)-R, sp[2] = 0;
    uint32_t k = 0;
#define RING(j, i) (1 + ((j) - 1) * L + ((i) % L))
    for (uint32_t i = 0; i < L; ++i) {
        uint32_t t[3] = {0, RING(1, i), RING(1, i + 1)};
        memcpy(m.tri + 3 * k++, t, sizeof t);
        uint32_t b[3] = {m.nv - 1, RING(S - 1, i), RING(S - 1, i + 1)};
        memcpy(m.tri + 3 * k++, b, sizeof b);
        for (uint32_t j = 1; j + 1 < S; ++j) {
            uint32_t q1[3] = {RING(j, i), RING(j + 1, i), RING(j + 1, i + 1)};
            uint32_t q2[3] = {RING(j, i), RING(j + 1, i + 1), RING(j, i + 1)};
            memcpy(m.tri + 3 * k++, q1, sizeof q1);
            memcpy(m.tri + 3 * k++, q2, sizeof q2);
        }
    }
#undef RING
    for (uint32_t t = 0; t < m.nt; ++t) {
        uint32_t *c = m.tri + 3 * t;
        double p[3][3];
        for (int a = 0; a < 3; ++a)
            for (int x = 0; x < 3; ++x) p[a][x] = m.pos[3 * c[a] + x];
        double e1[3], e2[3], s[3];
        for (int x = 0; x < 3; ++x) e1[x] = p[1][x] - p[0][x], e2[x] = p[2][x] - p[0][x],
                                    s[x] = p[0][x] + p[1][x] + p[2][x];
        double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                        e1[0] * e2[1] - e1[1] * e2[0]};
        if (dot3(cr, s) < 0) {
            uint32_t x = c[1];
            c[1] = c[2], c[2] = x;
        }
    }
    return m;
}

/* An open G x G grid of quads cut in two on y = 0, x and z in [-half, half]. */
static tmesh grid_mesh(uint32_t G, double half) {
    tmesh m;
    m.nv = (G + 1) * (G + 1);
    m.nt = 2 * G * G;
    m.pos = malloc(sizeof(float) * 3 * m.nv);
    m.tri = malloc(sizeof(uint32_t) * 3 * m.nt);
    for (uint32_t j = 0; j <= G; ++j)
        for (uint32_t i = 0; i <= G; ++i) {
            float *p = m.pos + 3 * (j * (G + 1) + i);
            p[0] = (float)(-half + 2 * half * i / G), p[1] = 0,
            p[2] = (float)(-half + 2 * half * j / G);
        }
    for (uint32_t j = 0, k = 0; j < G; ++j)
        for (uint32_t i = 0; i < G; ++i) {
            uint32_t p00 = j * (G + 1) + i, p10 = p00 + 1, p01 = p00 + G + 1, p11 = p01 + 1;
            uint32_t t[6] = {p00, p01, p11, p00, p11, p10}; /* normals +y */
            memcpy(m.tri + 3 * k, t, sizeof t);
            k += 2;
        }
    return m;
}

static struct rbc_trimesh *make(const tmesh *t) {
    rbc_allocator a = rbc_allocator_default();
    struct rbc_trimesh *m = NULL;
    char err[256] = "";
    int32_t rc = rbc_trimesh_create(t->pos, t->nv, t->tri, t->nt, &a, &m, err, sizeof err);
    CHECK_EQ(rc, RBC_OK);
    if (rc) fprintf(stderr, "rbc_trimesh_create: %s\n", err);
    return m;
}

static void destroy(struct rbc_trimesh *m) {
    rbc_allocator a = rbc_allocator_default();
    rbc_trimesh_destroy(m, &a);
}

/* Independent reference: closest point on a triangle in double by projecting on its
 * plane (inside: the plane distance) or else the nearest of its three edges. */
static double seg_d2(const double q[3], const double a[3], const double b[3]) {
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
           aq[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
    double t = fmin(fmax(dot3(aq, ab) / dot3(ab, ab), 0.0), 1.0);
    double d[3] = {aq[0] - t * ab[0], aq[1] - t * ab[1], aq[2] - t * ab[2]};
    return dot3(d, d);
}
static double tri_d2_ref(const double q[3], const float *pos, const uint32_t *t) {
    double p[3][3];
    for (int a = 0; a < 3; ++a)
        for (int x = 0; x < 3; ++x) p[a][x] = pos[3 * t[a] + x];
    double e1[3], e2[3], aq[3];
    for (int x = 0; x < 3; ++x)
        e1[x] = p[1][x] - p[0][x], e2[x] = p[2][x] - p[0][x], aq[x] = q[x] - p[0][x];
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                   e1[0] * e2[1] - e1[1] * e2[0]};
    double nn = dot3(n, n), h = dot3(aq, n) / nn;
    double f[3] = {aq[0] - h * n[0], aq[1] - h * n[1], aq[2] - h * n[2]}; /* in-plane, from a */
    /* barycentrics of the foot by sub-areas */
    double c1[3] = {e1[1] * f[2] - e1[2] * f[1], e1[2] * f[0] - e1[0] * f[2],
                    e1[0] * f[1] - e1[1] * f[0]};
    double c2[3] = {f[1] * e2[2] - f[2] * e2[1], f[2] * e2[0] - f[0] * e2[2],
                    f[0] * e2[1] - f[1] * e2[0]};
    double w = dot3(c1, n) / nn, v = dot3(c2, n) / nn;
    if (v >= 0 && w >= 0 && v + w <= 1) return h * h * nn;
    return fmin(seg_d2(q, p[0], p[1]), fmin(seg_d2(q, p[1], p[2]), seg_d2(q, p[2], p[0])));
}
static double mesh_d_ref(const tmesh *t, const float qf[3]) {
    double q[3] = {qf[0], qf[1], qf[2]}, best = INFINITY;
    for (uint32_t i = 0; i < t->nt; ++i) best = fmin(best, tri_d2_ref(q, t->pos, t->tri + 3 * i));
    return sqrt(best);
}

/* The mesh's rounding: the closest point is computed in double, within about
 * 2^-52 kappa (M + |q|) of the exact one (M the coordinates' magnitude, kappa =
 * 1 / sin^2 of the smallest triangle angle: Ericson's face case divides differences
 * of products by the squared area), then phi is rounded to float once (u |phi|).
 * 2^-47 kappa (M + |q|) + u |phi| bounds both with a factor 32 on the first. */
static double mesh_kappa(const tmesh *t) {
    double k = 1.0;
    for (uint32_t i = 0; i < t->nt; ++i)
        for (int c = 0; c < 3; ++c) {
            const float *p0 = t->pos + 3 * t->tri[3 * i + c],
                        *p1 = t->pos + 3 * t->tri[3 * i + (c + 1) % 3],
                        *p2 = t->pos + 3 * t->tri[3 * i + (c + 2) % 3];
            double e1[3], e2[3];
            for (int x = 0; x < 3; ++x)
                e1[x] = (double)p1[x] - p0[x], e2[x] = (double)p2[x] - p0[x];
            double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0]};
            double s2 = dot3(cr, cr) / (dot3(e1, e1) * dot3(e2, e2)); /* sin^2 */
            if (s2 > 0) k = fmax(k, 1.0 / s2);
        }
    return k;
}
static double mesh_tol(double kappa, double M, const float q[3], double phi) {
    return 0x1p-47 * kappa * (M + normf(q)) + U * fabs(phi);
}

/* A tmesh as a triangle-mesh shape for the distance tests: the mesh, its geom and
 * info, and its rounding factor (mesh_kappa). */
typedef struct mesh_shape {
    tmesh t;
    struct rbc_trimesh *m;
    rbc_shape_geom g;
    rbc_trimesh_info info;
    double kappa;
} mesh_shape;

/* Makes t (now owned by *s) a shape, closed or not as expected (checked); whether it
 * could be made (t is freed if not). */
static int mesh_shape_make(mesh_shape *s, tmesh t, int closed) {
    s->t = t;
    s->kappa = mesh_kappa(&s->t);
    s->m = make(&s->t);
    if (!s->m) {
        tmesh_free(&s->t);
        return 0;
    }
    rbc_trimesh_info_get(s->m, &s->info);
    CHECK_EQ(s->info.closed, closed);
    s->g = geom(RBC_SHAPE_TRIANGLE_MESH, 0, 0, 0, 0);
    s->g.mesh = s->m;
    return 1;
}

static void mesh_shape_free(mesh_shape *s) {
    destroy(s->m);
    tmesh_free(&s->t);
}

static void test_box_mesh(void) {
    rbc_shape_geom box = geom(RBC_SHAPE_BOX, 0, (float)BH[0], (float)BH[1], (float)BH[2]);
    for (int flip = 0; flip < 2; ++flip) {
        mesh_shape ms;
        if (!mesh_shape_make(&ms, box_mesh(BH, 4, flip), 1)) return;
        CHECK_EQ(ms.info.triangles, 6 * 2 * 16);
        CHECK_EQ(ms.info.degenerate, 0);
        CHECK_EQ(ms.info.vertices, ms.t.nv);
        CHECK(ms.info.lo[0] == -0.75f && ms.info.hi[1] == 0.375f && ms.info.lo[2] == -0.5f);
        float lo[3], hi[3];
        rbc_shape_bounds(&ms.g, lo, hi);
        CHECK(lo[1] == -0.375f && hi[0] == 0.75f);
        double worst_phi = 0, worst_n = 0, worst_along = 0;
        int sign_bad = 0, inside = 0;
        for (int it = 0; it < 20000; ++it) {
            float q[3], n[3], na[3], phi, pa;
            sample_point(RBC_SHAPE_BOX, q);
            rbc_shape_distance(&box, q, INFINITY, &pa, na);
            CHECK_EQ(rbc_shape_distance(&ms.g, q, INFINITY, &phi, n), 1);
            double tol = mesh_tol(ms.kappa, 0.75, q, pa) + U * fabs(pa); /* + the box's rounding */
            worst_phi = fmax(worst_phi, fabs(phi - pa) / tol);
            sign_bad += fabs(pa) > tol && (phi < 0) != (pa < 0);
            inside += pa < 0;
            /* n: the mesh's direction q - p is off by its point's error over |phi|.
             * Inside, two penetrations within tol of each other may pick either face. */
            double pen[3], tie = 0;
            for (int i = 0; i < 3; ++i) pen[i] = BH[i] - fabs((double)q[i]);
            if (pa < 0) {
                double sorted[3] = {pen[0], pen[1], pen[2]};
                for (int i = 0; i < 3; ++i)
                    for (int j = i + 1; j < 3; ++j)
                        if (sorted[j] < sorted[i]) {
                            double x = sorted[i];
                            sorted[i] = sorted[j], sorted[j] = x;
                        }
                tie = sorted[1] - sorted[0] <= 2 * tol;
            }
            if (!tie && fabs(pa) > 1e-4) {
                double tol_n = 2 * tol / fabs(pa) + 4 * U;
                for (int i = 0; i < 3; ++i) worst_n = fmax(worst_n, fabs(n[i] - na[i]) / tol_n);
            }
            /* Outside a convex mesh: phi(q + s n) = phi(q) + (q2 - q) . n. */
            if (pa > 1e-3) {
                float q2[3], n2[3], phi2;
                double dlt = 0, mag = 0;
                for (int i = 0; i < 3; ++i) {
                    q2[i] = (float)(q[i] + 0.05 * n[i]);
                    dlt += ((double)q2[i] - q[i]) * n[i];
                    mag += fabs((double)q2[i] - q[i]);
                }
                rbc_shape_distance(&ms.g, q2, INFINITY, &phi2, n2);
                /* each phi's rounding, and n's (u per component) in dlt */
                double tol2 = mesh_tol(ms.kappa, 0.75, q, phi) +
                              mesh_tol(ms.kappa, 0.75, q2, phi2) + 2 * U * mag;
                worst_along = fmax(worst_along, fabs(phi2 - (phi + dlt)) / tol2);
            }
        }
        printf("closed box mesh%s: %d inside; worst |phi - box| %.3g, n %.3g, along n %.3g "
               "of the bounds; %d wrong signs\n",
               flip ? " (inside out)" : "", inside, worst_phi, worst_n, worst_along, sign_bad);
        CHECK(worst_phi <= 1.0);
        CHECK(worst_n <= 1.0);
        CHECK(worst_along <= 1.0);
        CHECK_EQ(sign_bad, 0);
        CHECK(inside > 3000);
        /* Raycasts: the analytic box's entries (both in double from the same floats:
         * t within a few ulps), misses and starts inside alike. */
        int disagree = 0;
        double worst_t = 0;
        for (int it = 0; it < 10000; ++it) {
            float a[3], b[3], ta, tm, na[3], nm[3];
            sample_point(RBC_SHAPE_BOX, a);
            sample_point(RBC_SHAPE_BOX, b);
            int ha = rbc_shape_raycast(&box, a, b, &ta, na);
            int hm = rbc_shape_raycast(&ms.g, a, b, &tm, nm);
            double dd[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
            /* grazing (|cos| < 0.05) segments may round either way */
            if (ha && fabs(dd[0] * na[0] + dd[1] * na[1] + dd[2] * na[2]) < 0.05 * norm3(dd))
                continue;
            if (ha != hm) {
                ++disagree;
                continue;
            }
            if (ha) {
                worst_t = fmax(worst_t, fabs(tm - ta) / (8 * U + 1e-12));
                disagree += na[0] != nm[0] || na[1] != nm[1] || na[2] != nm[2];
            }
        }
        printf("closed box mesh%s raycasts vs box: %d disagree, worst t difference %.3g of "
               "8 ulps\n", flip ? " (inside out)" : "", disagree, worst_t);
        CHECK_EQ(disagree, 0);
        CHECK(worst_t <= 1.0);
        mesh_shape_free(&ms);
    }
}

/* r_min: the least distance from the centre to the mesh; R_max: the largest vertex
 * radius (float rounding). Inscribed and convex: sd_sphere(R_max) <= sd_mesh <=
 * sd_sphere(R) + (R - r_min) (support functions differ by at most that). */
static void test_sphere_mesh(void) {
    const double R = 1.0;
    mesh_shape ms;
    if (!mesh_shape_make(&ms, uv_sphere(R, 64, 33), 1)) return;
    CHECK_EQ(ms.info.triangles, ms.t.nt);
    double o[3] = {0, 0, 0}, rmin = INFINITY, rmax = 0;
    for (uint32_t i = 0; i < ms.t.nt; ++i)
        rmin = fmin(rmin, sqrt(tri_d2_ref(o, ms.t.pos, ms.t.tri + 3 * i)));
    for (uint32_t v = 0; v < ms.t.nv; ++v) rmax = fmax(rmax, normf(ms.t.pos + 3 * v));
    double H = R - rmin;
    printf("UV sphere (%u triangles): tessellation error H = R - r_min = %.4g\n", ms.t.nt, H);
    double lo_gap = INFINITY, hi_gap = INFINITY;
    int sign_bad = 0, inside = 0, out_of_band = 0;
    for (int it = 0; it < 20000; ++it) {
        double d[3], rr = urand() < 0.5 ? rrange(0, 1.6) : R * (1 + rrange(-0.05, 0.05));
        rand_dir(d);
        float q[3] = {(float)(rr * d[0]), (float)(rr * d[1]), (float)(rr * d[2])}, n[3], phi;
        CHECK_EQ(rbc_shape_distance(&ms.g, q, INFINITY, &phi, n), 1);
        double qn = normf(q), ps = qn - R, tol = mesh_tol(ms.kappa, R, q, phi);
        /* qn - R_max - tol <= phi <= qn - R + H + tol; the gaps to each side, in H */
        out_of_band += phi < qn - rmax - tol || phi > ps + H + tol;
        lo_gap = fmin(lo_gap, (phi - (qn - rmax)) / H);
        hi_gap = fmin(hi_gap, (ps + H - phi) / H);
        if (fabs(ps) > H + tol) sign_bad += (phi < 0) != (ps < 0);
        inside += phi < 0;
        if (fabs(normf(n) - 1) > 4 * U) ++sign_bad;
    }
    printf("UV sphere: %d inside; %d outside [sd_sphere(R_max), sd_sphere(R) + H] (closest "
           "approaches %.3g H and %.3g H); %d wrong signs or non-unit n\n",
           inside, out_of_band, lo_gap, hi_gap, sign_bad);
    CHECK_EQ(out_of_band, 0);
    CHECK_EQ(sign_bad, 0);
    CHECK(inside > 4000);
    mesh_shape_free(&ms);
}

static void test_open_mesh(void) {
    mesh_shape ms;
    if (!mesh_shape_make(&ms, grid_mesh(16, 1.0), 0)) return;
    double worst_phi = 0, worst_n = 0;
    for (int it = 0; it < 20000; ++it) {
        float q[3] = {(float)rrange(-1.5, 1.5),
                      (float)(urand() < 0.5 ? rrange(-1, 1) : rrange(-1e-3, 1e-3)),
                      (float)rrange(-1.5, 1.5)},
              n[3], phi;
        /* the square: |(max(|x| - 1, 0), y, max(|z| - 1, 0))|, n along it */
        double o[3] = {fmax(fabs(q[0]) - 1.0, 0.0), q[1], fmax(fabs(q[2]) - 1.0, 0.0)};
        o[0] = copysign(o[0], q[0]), o[2] = copysign(o[2], q[2]);
        double d = norm3(o);
        CHECK_EQ(rbc_shape_distance(&ms.g, q, INFINITY, &phi, n), 1);
        double tol = mesh_tol(ms.kappa, 1.0, q, d);
        worst_phi = fmax(worst_phi, fabs(phi - d) / tol);
        if (d > 1e-4)
            for (int i = 0; i < 3; ++i)
                worst_n = fmax(worst_n, fabs(n[i] - o[i] / d) / (2 * tol / d + 4 * U));
    }
    printf("open grid: worst |phi - unsigned distance| %.3g, n %.3g of the bounds\n", worst_phi,
           worst_n);
    CHECK(worst_phi <= 1.0);
    CHECK(worst_n <= 1.0);
    /* Unsigned: nothing is within a negative max_dist; a point below gets n = -y. */
    float below[3] = {0.1f, -0.25f, 0.2f}, n[3], phi;
    CHECK_EQ(rbc_shape_distance(&ms.g, below, -0.01f, &phi, n), 0);
    CHECK_EQ(rbc_shape_distance(&ms.g, below, 0.3f, &phi, n), 1);
    CHECK(phi == 0.25f && n[1] == -1.0f);
    CHECK_EQ(rbc_shape_distance(&ms.g, below, 0.2f, &phi, n), 0);
    /* Raycasts from both sides: t = a_y / (a_y - b_y) (the plane y = 0 in double from
     * the floats, rounded), n facing a. */
    int bad = 0;
    double worst_t = 0;
    for (int it = 0; it < 5000; ++it) {
        int from_above = urand() < 0.5;
        float a[3] = {(float)rrange(-0.9, 0.9), (float)rrange(1e-3, 1), (float)rrange(-0.9, 0.9)};
        float b[3] = {(float)rrange(-0.9, 0.9), (float)rrange(-1, -1e-3), (float)rrange(-0.9, 0.9)};
        if (!from_above) a[1] = -a[1], b[1] = -b[1];
        float th, nn[3];
        double te = (double)a[1] / ((double)a[1] - b[1]);
        if (!rbc_shape_raycast(&ms.g, a, b, &th, nn)) {
            ++bad;
            continue;
        }
        worst_t = fmax(worst_t, fabs(th - te) / (2 * U));
        bad += nn[0] != 0 || nn[1] != (from_above ? 1.0f : -1.0f) || nn[2] != 0;
        /* Crossing y = 0 outside the square, or not at all: no hit. */
        float c[3] = {a[0] + 3, a[1], a[2]}, d2[3] = {b[0] + 3, b[1], b[2]};
        bad += rbc_shape_raycast(&ms.g, c, d2, &th, nn);
        float e[3] = {b[0], a[1] * 0.5f, b[2]};
        bad += rbc_shape_raycast(&ms.g, a, e, &th, nn);
    }
    printf("open grid raycasts: worst t error %.3g of 2 ulps, %d wrong\n", worst_t, bad);
    CHECK_EQ(bad, 0);
    CHECK(worst_t <= 1.0);
    mesh_shape_free(&ms);
}

/* BVH against the loop over every triangle: bitwise the same phi, n, t and returns
 * (shapes.h); and the distance against an independent double-precision loop. */
static int same_bits(const void *a, const void *b, size_t n) { return memcmp(a, b, n) == 0; }

static void bvh_vs_brute(const char *name, const tmesh *t, double M, double span) {
    double kap = mesh_kappa(t);
    struct rbc_trimesh *m = make(t);
    if (!m) return;
    rbc_shape_geom g = geom(RBC_SHAPE_TRIANGLE_MESH, 0, 0, 0, 0);
    g.mesh = m;
    const float mds[4] = {INFINITY, 0.05f, 0.0f, -0.05f};
    int differ = 0, hits = 0, rays = 0;
    double worst_ref = 0;
    for (int it = 0; it < 10000; ++it) {
        float q[3];
        double s = urand() < 0.5 ? span : 0.1 * span;
        for (int i = 0; i < 3; ++i) q[i] = (float)rrange(-s, s);
        if (urand() < 0.3) { /* near a vertex */
            uint32_t v = (uint32_t)(urand() * t->nv);
            for (int i = 0; i < 3; ++i) q[i] = t->pos[3 * v + i] + (float)rrange(-0.02, 0.02);
        }
        {
            float p1 = 7, p2 = 7, n1[3] = {7, 7, 7}, n2[3] = {7, 7, 7};
            float md = mds[it % 4];
            int r1 = rbc_shape_distance(&g, q, md, &p1, n1);
            int r2 = rbc_trimesh_distance_brute(m, q, md, &p2, n2);
            differ += r1 != r2 || !same_bits(&p1, &p2, 4) || !same_bits(n1, n2, 12);
            hits += r1;
            if (it < 2000) {
                rbc_trimesh_distance_brute(m, q, INFINITY, &p1, n1);
                double dref = mesh_d_ref(t, q);
                /* + the reference's own rounding, as the library's */
                worst_ref =
                    fmax(worst_ref, fabs(fabs(p1) - dref) / (2 * mesh_tol(kap, M, q, dref)));
            }
        }
        float a[3], b[3];
        for (int i = 0; i < 3; ++i)
            a[i] = (float)rrange(-span, span), b[i] = (float)rrange(-span, span);
        float t1 = 7, t2 = 7, n1[3] = {7, 7, 7}, n2[3] = {7, 7, 7};
        int r1 = rbc_shape_raycast(&g, a, b, &t1, n1);
        int r2 = rbc_trimesh_raycast_brute(m, a, b, &t2, n2);
        differ += r1 != r2 || !same_bits(&t1, &t2, 4) || !same_bits(n1, n2, 12);
        rays += r1;
    }
    printf("%s (%u triangles, kappa %.3g): BVH vs brute force, 10000 points, max_dist inf, "
           "0.05, 0, -0.05 in turn (%d within) and 10000 segments (%d entries): %d differ; |phi| "
           "vs double reference (2000 points) worst %.3g of the bound\n",
           name, t->nt, kap, hits, rays, differ, worst_ref);
    CHECK_EQ(differ, 0);
    CHECK(hits > 3000);
    CHECK(rays > 100);
    CHECK(worst_ref <= 1.0);
    destroy(m);
}

static void test_bvh(void) {
    tmesh s = uv_sphere(1.0, 48, 25); /* 2256 triangles */
    bvh_vs_brute("UV sphere", &s, 1.0, 1.5);
    tmesh_free(&s);
    tmesh b = box_mesh(BH, 4, 0);
    bvh_vs_brute("box mesh", &b, 0.75, 1.2);
    tmesh_free(&b);
    tmesh g = grid_mesh(24, 1.0);
    bvh_vs_brute("open grid", &g, 1.0, 1.3);
    tmesh_free(&g);
    /* A mesh whose triangles are a fan of slivers around one vertex: deep, lopsided
     * SAH splits and the sliver fallback of the closest-point code. */
    tmesh f;
    f.nv = 1001, f.nt = 1000;
    f.pos = malloc(sizeof(float) * 3 * f.nv);
    f.tri = malloc(sizeof(uint32_t) * 3 * f.nt);
    f.pos[0] = f.pos[1] = f.pos[2] = 0;
    for (uint32_t i = 0; i < 1000; ++i) {
        double ang = 0.25 * i / 1000.0, r = pow(1.006, i);
        f.pos[3 * (i + 1)] = (float)(r * cos(ang)),
                       f.pos[3 * (i + 1) + 1] = (float)(0.01 * sin(7.0 * i));
        f.pos[3 * (i + 1) + 2] = (float)(r * sin(ang));
    }
    for (uint32_t i = 0; i < 1000; ++i)
        f.tri[3 * i] = 0, f.tri[3 * i + 1] = 1 + i, f.tri[3 * i + 2] = 1 + (i + 1) % 1000;
    bvh_vs_brute("sliver fan", &f, 400.0, 10.0);
    tmesh_free(&f);
}

/* ---- errors, degenerate triangles, allocation failure ---- */
static long live_count, alloc_calls, fail_at;
static size_t live_bytes;
static int bad_align;

static void *count_alloc(void *user, size_t size, size_t alignment) {
    (void)user;
    if (alignment != 64) bad_align = 1;
    if (++alloc_calls == fail_at) return NULL;
    void *p = aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
    if (p) live_count++, live_bytes += size;
    return p;
}
static void count_free(void *user, void *p, size_t size) {
    (void)user;
    if (!p) return;
    live_count--, live_bytes -= size;
    free(p);
}

static void test_errors(void) {
    rbc_allocator a = rbc_allocator_default();
    tmesh t = box_mesh(BH, 2, 0);
    struct rbc_trimesh *m = (struct rbc_trimesh *)&a; /* must be reset to NULL */
    char err[256] = "";
    uint32_t saved = t.tri[3 * 5 + 2];
    t.tri[3 * 5 + 2] = t.nv + 7;
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, t.tri, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    printf("out of range: %s\n", err);
    CHECK(m == NULL);
    CHECK(strstr(err, "triangle 5 ") != NULL && strstr(err, "corner 2") != NULL);
    t.tri[3 * 5 + 2] = saved;
    float saved_p = t.pos[3 * 3 + 1];
    t.pos[3 * 3 + 1] = NAN;
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, t.tri, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    printf("NaN: %s\n", err);
    CHECK(strstr(err, "vertex 3 ") != NULL);
    t.pos[3 * 3 + 1] = INFINITY;
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, t.tri, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK(strstr(err, "vertex 3 ") != NULL);
    t.pos[3 * 3 + 1] = saved_p;
    CHECK_EQ(rbc_trimesh_create(t.pos, 0, t.tri, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, t.tri, 0, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_trimesh_create(NULL, t.nv, t.tri, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, NULL, t.nt, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    CHECK_EQ(rbc_trimesh_create(t.pos, t.nv, t.tri, t.nt, &a, &m, NULL, 0), RBC_OK); /* no buffer */
    destroy(m);

    /* Degenerate triangles (a repeated index, three collinear vertices along a box
     * edge) are skipped and counted; the box stays closed. */
    tmesh d = t;
    d.tri = malloc(sizeof(uint32_t) * 3 * (t.nt + 2));
    memcpy(d.tri, t.tri, sizeof(uint32_t) * 3 * t.nt);
    /* vertices along the edge y = -h, z = -h: x = -h, 0, +h in the N = 2 lattice */
    uint32_t col[3] = {0, 0, 0}, found = 0;
    for (uint32_t v = 0; v < t.nv && found < 3; ++v) {
        const float *p = t.pos + 3 * v;
        if (p[1] == -(float)BH[1] && p[2] == -(float)BH[2]) col[found++] = v;
    }
    CHECK_EQ(found, 3);
    uint32_t extra[6] = {1, 1, 2, col[0], col[1], col[2]};
    memcpy(d.tri + 3 * t.nt, extra, sizeof extra);
    d.nt = t.nt + 2;
    CHECK_EQ(rbc_trimesh_create(d.pos, d.nv, d.tri, d.nt, &a, &m, err, sizeof err), RBC_OK);
    rbc_trimesh_info info;
    rbc_trimesh_info_get(m, &info);
    CHECK_EQ(info.degenerate, 2);
    CHECK_EQ(info.triangles, t.nt);
    CHECK_EQ(info.closed, 1);
    destroy(m);
    /* Only degenerate triangles: nothing to collide with. */
    CHECK_EQ(rbc_trimesh_create(d.pos, d.nv, d.tri + 3 * t.nt, 2, &a, &m, err, sizeof err),
             RBC_ERR_INVALID_ARGUMENT);
    printf("all degenerate: %s\n", err);
    free(d.tri);

    /* Allocation failure at every k: OUT_OF_MEMORY, nothing leaked; then success
     * holds exactly info.bytes, and destroy returns it all. */
    rbc_allocator ca = {count_alloc, count_free, NULL};
    tmesh open = grid_mesh(6, 1.0);
    const tmesh *ms[2] = {&t, &open};
    for (int w = 0; w < 2; ++w) {
        int failures = 0, leaks = 0, wrong = 0;
        for (fail_at = 1;; ++fail_at) {
            alloc_calls = 0;
            m = (struct rbc_trimesh *)&a;
            int32_t rc = rbc_trimesh_create(ms[w]->pos, ms[w]->nv, ms[w]->tri, ms[w]->nt, &ca, &m,
                                            err, sizeof err);
            if (rc == RBC_OK) break;
            ++failures;
            wrong += rc != RBC_ERR_OUT_OF_MEMORY || m != NULL;
            leaks += live_count != 0 || live_bytes != 0;
        }
        fail_at = 0;
        printf("%s mesh: %d allocations, each failing in turn: %d wrong results, %d leaks\n",
               w ? "open" : "closed", failures, wrong, leaks);
        CHECK(failures >= 8);
        CHECK_EQ(wrong, 0);
        CHECK_EQ(leaks, 0);
        rbc_trimesh_info_get(m, &info);
        CHECK_EQ(info.bytes, live_bytes);
        CHECK_EQ(info.closed, w ? 0 : 1);
        rbc_trimesh_destroy(m, &ca);
        CHECK_EQ(live_count, 0);
        CHECK_EQ(live_bytes, 0);
    }
    CHECK_EQ(bad_align, 0);
    tmesh_free(&open);
    tmesh_free(&t);
}

/* ---- timing (printed, not asserted) ---- */
static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static int cmp_double(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

enum { BATCH = 64, BATCHES = 301 };
static double median_query_ns(const rbc_shape_geom *g, const float *pts, float max_dist, int ray,
                              double *sink) {
    static double per[BATCHES];
    for (int b = 0; b < BATCHES; ++b) {
        double t0 = now_s();
        for (int i = 0; i < BATCH; ++i) {
            const float *q = pts + 3 * (size_t)(b * BATCH + i);
            float phi = 0, n[3];
            if (ray)
                rbc_shape_raycast(g, q, q + 3 * (size_t)BATCHES * BATCH, &phi, n);
            else
                rbc_shape_distance(g, q, max_dist, &phi, n);
            *sink += phi;
        }
        per[b] = (now_s() - t0) / BATCH * 1e9;
    }
    qsort(per, BATCHES, sizeof per[0], cmp_double);
    return per[BATCHES / 2];
}

static void test_timing(void) {
    tmesh t = uv_sphere(1.0, 100, 101); /* 20000 triangles */
    double t0 = now_s();
    struct rbc_trimesh *m = make(&t);
    double t_create = now_s() - t0;
    if (!m) return;
    rbc_shape_geom g = geom(RBC_SHAPE_TRIANGLE_MESH, 0, 0, 0, 0);
    g.mesh = m;
    const size_t np = (size_t)BATCHES * BATCH;
    float *near = malloc(sizeof(float) * 6 * np), *far = malloc(sizeof(float) * 6 * np);
    float *mid = malloc(sizeof(float) * 6 * np), *sweep = malloc(sizeof(float) * 6 * np);
    for (size_t i = 0; i < 2 * np; ++i) {
        double d[3], rn = 1.0 + rrange(-0.05, 0.05), rf = rrange(2.0, 3.0);
        rand_dir(d);
        /* a cloth-like sheet 0.02 over the surface, visited row by row (the order a
         * solver meets its particles in) */
        size_t row = i % np / 128, col = i % np % 128;
        double th = 0.4 + 1.2 * (double)row / (double)(np / 128), ph = 1.5 * (double)col / 128.0;
        double sw[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)};
        for (int k = 0; k < 3; ++k) {
            near[3 * i + k] = (float)(rn * d[k]);
            far[3 * i + k] = (float)(rf * d[k]);
            /* inside the bounds, outside the sphere, beyond max_dist */
            mid[3 * i + k] = (float)((d[k] < 0 ? -0.95 : 0.95));
            sweep[3 * i + k] = (float)(1.02 * sw[k]);
        }
    }
    double sink = 0;
    median_query_ns(&g, near, 0.1f, 0, &sink); /* warm up */
    double tn = median_query_ns(&g, near, 0.1f, 0, &sink);
    double ts = median_query_ns(&g, sweep, 0.1f, 0, &sink);
    double tf = median_query_ns(&g, far, 0.1f, 0, &sink);
    double tm = median_query_ns(&g, mid, 0.1f, 0, &sink);
    double tr = median_query_ns(&g, far, 0.1f, 1, &sink); /* far -> far segments */
    rbc_trimesh_info info;
    rbc_trimesh_info_get(m, &info);
    printf("timing, %u-triangle UV sphere (created in %.0f ms, %zu bytes), median ns per "
           "query over %d batches of %d, max_dist 0.1:\n"
           "  near (|phi| < 0.05), random order  %8.0f\n"
           "  near (phi = 0.02), sheet order     %8.0f\n"
           "  far (|q| in [2, 3]: culled)        %8.0f\n"
           "  in the bounds, 0.6 out (culled)    %8.0f\n"
           "  raycast between far points         %8.0f   [%g]\n",
           info.triangles, t_create * 1e3, info.bytes, BATCHES, BATCH, tn, ts, tf, tm, tr,
           sink > 0 ? 1.0 : 0.0);
    free(near), free(far), free(mid), free(sweep);
    destroy(m);
    tmesh_free(&t);
}

int main(void) {
    test_analytic_distance();
    test_gradient();
    test_analytic_raycast();
    test_box_mesh();
    test_sphere_mesh();
    test_open_mesh();
    test_bvh();
    test_errors();
    test_timing();
    return check_report("core_shapes");
}
