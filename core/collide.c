/* collide.c -- contact with the built-in colliders inside the solve (collide.h). */
#include "collide.h"

#include <math.h>
#include <string.h>

#include "energy.h"
#include "simd.h"
#include "shapes.h"
#include "solver.h"

/* Rotation matrix of a unit quaternion (x, y, z, w), row-major. */
static void quat_matrix(const float q[4], float r[9]) {
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

void rbc_collider_frame_at(const rbc_collider_state *c, float f, rbc_frame *out) {
    float q[4];
    const float *a = c->last_rotation, *b = c->rotation;
    if (f >= 1.0f) {
        memcpy(q, b, sizeof q);
        memcpy(out->t, c->position, sizeof out->t);
    } else {
        /* nlerp along the shorter arc. */
        float dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        float sb = dot < 0.0f ? -f : f, n2 = 0.0f;
        for (int k = 0; k < 4; ++k) {
            q[k] = (1.0f - f) * a[k] + sb * b[k];
            n2 += q[k] * q[k];
        }
        float inv = n2 > 0.0f ? 1.0f / sqrtf(n2) : 1.0f;
        for (int k = 0; k < 4; ++k) q[k] *= inv;
        for (int k = 0; k < 3; ++k)
            out->t[k] = c->last_position[k] + (c->position[k] - c->last_position[k]) * f;
    }
    quat_matrix(q, out->r);
}

static inline void to_local(const rbc_frame *fr, const float w[3], float l[3]) {
    float d0 = w[0] - fr->t[0], d1 = w[1] - fr->t[1], d2 = w[2] - fr->t[2];
    l[0] = fr->r[0] * d0 + fr->r[3] * d1 + fr->r[6] * d2;
    l[1] = fr->r[1] * d0 + fr->r[4] * d1 + fr->r[7] * d2;
    l[2] = fr->r[2] * d0 + fr->r[5] * d1 + fr->r[8] * d2;
}
static inline void to_world_dir(const rbc_frame *fr, const float l[3], float w[3]) {
    w[0] = fr->r[0] * l[0] + fr->r[1] * l[1] + fr->r[2] * l[2];
    w[1] = fr->r[3] * l[0] + fr->r[4] * l[1] + fr->r[5] * l[2];
    w[2] = fr->r[6] * l[0] + fr->r[7] * l[1] + fr->r[8] * l[2];
}
static inline void to_world(const rbc_frame *fr, const float l[3], float w[3]) {
    to_world_dir(fr, l, w);
    w[0] += fr->t[0];
    w[1] += fr->t[1];
    w[2] += fr->t[2];
}

/* The contact of a particle moving from a to b (collider frame at the substep's
 * start and end) with the shape: 1 and the surface point sl with outward normal nl
 * when the motion enters the shape (the entry point) or b is within reach of the
 * surface (its closest point). Planes and spheres are done inline (most scenes'
 * colliders, and most particles are far from them); the rest go to shapes.c. */
static inline int shape_contact(const rbc_collider_state *col, const float a[3],
                                const float b[3], float reach, float sl[3], float nl[3]) {
    if (col->shape == RBC_SHAPE_PLANE) {
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
    if (col->shape == RBC_SHAPE_SPHERE) {
        const float r = col->radius, R = r + reach;
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
    if (rbc_shape_raycast(&col->geom, a, b, &t, nl)) {
        for (int ax = 0; ax < 3; ++ax) sl[ax] = a[ax] + t * (b[ax] - a[ax]);
        return 1;
    }
    if (rbc_shape_distance(&col->geom, b, reach, &phi, nl) && phi < reach) {
        for (int ax = 0; ax < 3; ++ax) sl[ax] = b[ax] - phi * nl[ax];
        return 1;
    }
    return 0;
}

/* Cull a run of particles against a collider's bounds grown by reach, in vector
 * lanes: the indices [i0, i1) whose motion a (from x in frame A) -> b (from p in
 * frame B) may come within reach of the shape go to cand; returns their count. */
enum { CULL_CHUNK = 256 };
RBC_VECTOR_CLONES
static uint32_t cull_chunk(uint32_t i0, uint32_t len, const float *restrict x0,
                           const float *restrict x1, const float *restrict x2,
                           const float *restrict p0, const float *restrict p1,
                           const float *restrict p2, const uint8_t *restrict pinned,
                           const rbc_frame *A, const rbc_frame *B, const float lo[3],
                           const float hi[3], float reach, uint32_t *restrict cand) {
    int32_t keep[CULL_CHUNK];
    const float ra0 = A->r[0], ra1 = A->r[1], ra2 = A->r[2], ra3 = A->r[3], ra4 = A->r[4],
                ra5 = A->r[5], ra6 = A->r[6], ra7 = A->r[7], ra8 = A->r[8];
    const float rb0 = B->r[0], rb1 = B->r[1], rb2 = B->r[2], rb3 = B->r[3], rb4 = B->r[4],
                rb5 = B->r[5], rb6 = B->r[6], rb7 = B->r[7], rb8 = B->r[8];
    const float ta0 = A->t[0], ta1 = A->t[1], ta2 = A->t[2];
    const float tb0 = B->t[0], tb1 = B->t[1], tb2 = B->t[2];
    const float l0 = lo[0] - reach, l1 = lo[1] - reach, l2 = lo[2] - reach;
    const float h0 = hi[0] + reach, h1 = hi[1] + reach, h2 = hi[2] + reach;
    const float *restrict X0 = x0 + i0, *restrict X1 = x1 + i0, *restrict X2 = x2 + i0;
    const float *restrict Q0 = p0 + i0, *restrict Q1 = p1 + i0, *restrict Q2 = p2 + i0;
    for (uint32_t m = 0; m < len; ++m) {
        float d0 = X0[m] - ta0, d1 = X1[m] - ta1, d2 = X2[m] - ta2;
        float a0 = ra0 * d0 + ra3 * d1 + ra6 * d2;
        float a1 = ra1 * d0 + ra4 * d1 + ra7 * d2;
        float a2 = ra2 * d0 + ra5 * d1 + ra8 * d2;
        float e0 = Q0[m] - tb0, e1 = Q1[m] - tb1, e2 = Q2[m] - tb2;
        float b0 = rb0 * e0 + rb3 * e1 + rb6 * e2;
        float b1 = rb1 * e0 + rb4 * e1 + rb7 * e2;
        float b2 = rb2 * e0 + rb5 * e1 + rb8 * e2;
        float n0 = a0 < b0 ? a0 : b0, x0m = a0 < b0 ? b0 : a0;
        float n1 = a1 < b1 ? a1 : b1, x1m = a1 < b1 ? b1 : a1;
        float n2 = a2 < b2 ? a2 : b2, x2m = a2 < b2 ? b2 : a2;
        /* Bitwise &: no branches, so the loop vectorizes. */
        keep[m] = (n0 <= h0) & (x0m >= l0) & (n1 <= h1) & (x1m >= l1) & (n2 <= h2) & (x2m >= l2);
    }
    uint32_t n = 0;
    for (uint32_t m = 0; m < len; ++m) {
        cand[n] = i0 + m;
        n += (uint32_t)(keep[m] & (pinned[i0 + m] == 0));
    }
    return n;
}

/* At most this many colliders are looked at with frames on the stack; more are
 * handled in chunks. */
#define RBC_FRAME_CHUNK 16

void rbc_collide_detect(rbc_solver *s, rbc_contact_list *list, float f0, float f1, float h,
                        uint32_t tid, uint32_t nt) {
    list->count = 0;
    list->need = 0;
    const float inv_h = 1.0f / h;
    for (uint32_t c0 = 0; c0 < s->collider_count; c0 += RBC_FRAME_CHUNK) {
        uint32_t c1 = c0 + RBC_FRAME_CHUNK < s->collider_count ? c0 + RBC_FRAME_CHUNK
                                                               : s->collider_count;
        rbc_frame fa[RBC_FRAME_CHUNK], fb[RBC_FRAME_CHUNK];
        for (uint32_t ci = c0; ci < c1; ++ci) {
            rbc_collider_frame_at(&s->colliders[ci], f0, &fa[ci - c0]);
            rbc_collider_frame_at(&s->colliders[ci], f1, &fb[ci - c0]);
        }
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            rbc_cloth_state *c = s->cloths[k];
            uint32_t i0, i1;
            rbc_energy_particle_range(c->topo.n, tid, nt, &i0, &i1);
            /* How far outside the surface a particle still gets a contact: the solve
             * moves particles by up to about a spring length from y. */
            const float margin = 0.5f * c->mean_rest;
            for (uint32_t ci = c0; ci < c1; ++ci) {
                const rbc_collider_state *col = &s->colliders[ci];
                const rbc_frame *A = &fa[ci - c0], *B = &fb[ci - c0];
                const float thick = col->thickness + c->thickness;
                const float reach = thick + margin;
                const float mu = col->friction > c->friction ? col->friction : c->friction;
                const float *X0 = c->x[0], *X1 = c->x[1], *X2 = c->x[2];
                const float *P0 = c->p[0], *P1 = c->p[1], *P2 = c->p[2];
                uint32_t cand[CULL_CHUNK];
                for (uint32_t j0 = i0; j0 < i1; j0 += CULL_CHUNK) {
                  uint32_t len = i1 - j0 < CULL_CHUNK ? i1 - j0 : CULL_CHUNK;
                  uint32_t nc = cull_chunk(j0, len, X0, X1, X2, P0, P1, P2, c->pinned, A, B,
                                           col->lo, col->hi, reach, cand);
                  for (uint32_t m = 0; m < nc; ++m) {
                    const uint32_t i = cand[m];
                    float xw[3] = {X0[i], X1[i], X2[i]};
                    float yw[3] = {P0[i], P1[i], P2[i]};
                    float a[3], b[3];
                    to_local(A, xw, a);
                    to_local(B, yw, b);
                    /* The motion entered the shape: the tangent plane at the entry point,
                     * wherever y ended up (through a thin shape, or deep in); else the
                     * closest point of y, if within reach. */
                    float nl[3], sl[3];
                    if (!shape_contact(col, a, b, reach, sl, nl)) continue;
                    uint32_t slot = list->need++;
                    if (slot >= list->cap) continue;
                    rbc_col_contact *ct = &list->c[slot];
                    float sw[3], sa[3];
                    to_world_dir(B, nl, ct->n);
                    to_world(B, sl, sw);
                    to_world(A, sl, sa);
                    ct->cloth = k;
                    ct->idx = i;
                    ct->d = ct->n[0] * sw[0] + ct->n[1] * sw[1] + ct->n[2] * sw[2] + thick;
                    for (int ax = 0; ax < 3; ++ax) ct->u[ax] = (sw[ax] - sa[ax]) * inv_h;
                    float pen = ct->d - (ct->n[0] * yw[0] + ct->n[1] * yw[1] + ct->n[2] * yw[2]);
                    ct->depth = pen > 0.0f ? pen : 0.0f;
                    ct->last = 0.0f;
                    ct->mu = mu;
                    ct->collider = ci;
                    ct->fn_row = 0.0f;
                    ct->ft[0] = ct->ft[1] = ct->ft[2] = 0.0f;
                    ct->color = rbc_collide_color_of(&c->topo, i);
                  }
                }
            }
        }
    }
    /* The list is in (collider chunk, cloth, collider, particle) order. A projection
     * touches only its own particle, so what matters is the order of each particle's
     * contacts: by increasing collider, whatever the thread split. */
    list->count = list->need < list->cap ? list->need : list->cap;
}

/* Coulomb friction of contact ct on particle i of c, after its normal push v > 0 in
 * the same pass: the slip (motion since the substep's start less the surface's,
 * tangential) removed while within mu v, else cut by mu v. */
static void pass_friction(rbc_col_contact *ct, rbc_cloth_state *c, float *const P[3], uint32_t i,
                          float v, float h) {
    ct->ft[0] = ct->ft[1] = ct->ft[2] = 0.0f;
    if (!(ct->mu > 0.0f)) return;
    const float *n = ct->n;
    float dl[3];
    for (int a = 0; a < 3; ++a) dl[a] = P[a][i] - c->x[a][i] - ct->u[a] * h;
    float dn = dl[0] * n[0] + dl[1] * n[1] + dl[2] * n[2];
    float tg[3] = {dl[0] - dn * n[0], dl[1] - dn * n[1], dl[2] - dn * n[2]};
    float tl = sqrtf(tg[0] * tg[0] + tg[1] * tg[1] + tg[2] * tg[2]);
    float lim = ct->mu * v;
    float f = tl <= lim ? 1.0f : lim / tl; /* static: all of it; kinetic: mu v */
    for (int a = 0; a < 3; ++a) {
        ct->ft[a] = -f * tg[a];
        P[a][i] += ct->ft[a];
    }
}

int rbc_collide_project(rbc_solver *s, rbc_contact_list *list, int alt, float h) {
    int moved = 0;
    uint32_t m = 0;
    while (m < list->count) {
        /* Contacts come in runs of one cloth: its arrays once per run. */
        uint32_t k = list->c[m].cloth;
        rbc_cloth_state *c = s->cloths[k];
        float *const *P = alt ? c->alt : c->p;
        float *restrict P0 = P[0], *restrict P1 = P[1], *restrict P2 = P[2];
        for (; m < list->count && list->c[m].cloth == k; ++m) {
            rbc_col_contact *ct = &list->c[m];
            uint32_t i = ct->idx;
            float v = ct->d - (ct->n[0] * P0[i] + ct->n[1] * P1[i] + ct->n[2] * P2[i]);
            if (v > 0.0f) {
                P0[i] += v * ct->n[0];
                P1[i] += v * ct->n[1];
                P2[i] += v * ct->n[2];
                ct->last = v;
                moved = 1;
                if (h > 0.0f) pass_friction(ct, c, P, i, v, h);
            } else {
                ct->last = 0.0f;
            }
        }
    }
    return moved;
}

uint32_t rbc_collide_color_of(const rbc_topology *t, uint32_t i) {
    uint32_t c = 0;
    while (c + 1 < t->ncolors && i >= t->color_start[c + 1]) ++c;
    return c;
}

int rbc_collide_project_color(rbc_solver *s, rbc_contact_list *list, uint32_t color, float h) {
    int moved = 0;
    for (uint32_t m = 0; m < list->count; ++m) {
        rbc_col_contact *ct = &list->c[m];
        if (ct->color != color) continue;
        rbc_cloth_state *c = s->cloths[ct->cloth];
        const uint32_t i = ct->idx;
        float *const *P = c->p;
        const float *n = ct->n;
        float v = ct->d - (n[0] * P[0][i] + n[1] * P[1][i] + n[2] * P[2][i]);
        if (!(v > 0.0f)) {
            ct->last = 0.0f; /* not pressed: no friction, the last one's stays counted */
            continue;
        }
        for (int a = 0; a < 3; ++a) P[a][i] += v * n[a];
        ct->last = v;
        moved = 1;
        pass_friction(ct, c, P, i, v, h);
    }
    return moved;
}

void rbc_collide_normal_forces(rbc_solver *s, rbc_contact_list *list, float h) {
    const float inv_h2 = 1.0f / (h * h);
    for (uint32_t m = 0; m < list->count; ++m) {
        rbc_col_contact *ct = &list->c[m];
        ct->fn_row = 0.0f;
        if (!(ct->mu > 0.0f)) continue; /* only friction reads it */
        const rbc_cloth_state *c = s->cloths[ct->cloth];
        const rbc_topology *t = &c->topo;
        const uint32_t i = ct->idx;
        const float row = t->mass[i] * inv_h2 + t->ksum[i];
        float f[3] = {row * c->p[0][i] - c->bx[i], row * c->p[1][i] - c->by[i],
                      row * c->p[2][i] - c->bz[i]};
        for (uint32_t k = t->adj_start[i]; k < t->adj_start[i + 1]; ++k) {
            const uint32_t j = t->adj_nbr[k];
            const float kk = t->adj_k[k];
            f[0] -= kk * c->p[0][j];
            f[1] -= kk * c->p[1][j];
            f[2] -= kk * c->p[2][j];
        }
        const float fn = f[0] * ct->n[0] + f[1] * ct->n[1] + f[2] * ct->n[2];
        ct->fn_row = fn > 0.0f ? fn : 0.0f;
    }
}

void rbc_collide_finish(rbc_solver *s, rbc_contact_list *list, float h, uint32_t tid, uint32_t nt,
                        double *work_out, int in_pass) {
    /* Zero this thread's collider-work slots. */
    for (uint32_t k = 0; !work_out && k < s->cloth_count; ++k) {
        rbc_cloth_state *c = s->cloths[k];
        uint32_t b0, b1;
        rbc_energy_block_range(rbc_energy_blocks_of(c->topo.n), tid, nt, &b0, &b1);
        for (uint32_t blk = b0; blk < b1; ++blk) c->e_blk[(size_t)RBC_EPB * blk + RBC_E_WC] = 0.0;
    }
    const float inv_h = 1.0f / h;
    for (uint32_t m = 0; m < list->count; ++m) {
        const rbc_col_contact *ct = &list->c[m];
        rbc_cloth_state *c = s->cloths[ct->cloth];
        uint32_t i = ct->idx;
        const float *n = ct->n;
        float p[3] = {c->p[0][i], c->p[1][i], c->p[2][i]};
        float gap = n[0] * p[0] + n[1] * p[1] + n[2] * p[2] - ct->d;
        /* The normal correction the contact made this substep: what the prediction
         * went in, or what the last pass pushed (springs pressing the particle in). */
        float push = ct->depth > ct->last ? ct->depth : ct->last;
        /* Touching at the end (within a hair of the plane) and pushed at some point. */
        int active = push > 0.0f && gap <= 1e-3f * push + 1e-7f;
        /* The contact's normal force, as the global step sees it: the last pass moved
         * the particle by `last` from its Gauss-Seidel value, against a stiffness of
         * m/h^2 + sum s (its row of Eq. 6), so f = (m/h^2 + sum s) last; or what
         * stopping the prediction needs, m/h^2 depth, if more. Over the substep a
         * collider moving at u does f h (n . u) of work on the particle (plus the
         * friction impulse's), which the energy guard adds to the budget. */
        const float wi = c->topo.mass[i] * inv_h * inv_h;
        float fn_last = (wi + c->topo.ksum[i]) * ct->last, fn_depth = wi * ct->depth;
        float fn = fn_last > fn_depth ? fn_last : fn_depth;
        const float disp = fn * h * h / c->topo.mass[i]; /* the impulse f h, as m / h * disp */
        float moved[3] = {disp * n[0], disp * n[1], disp * n[2]};
        if (in_pass) {
            /* The passes applied the friction: the last correction's impulse. */
            for (int ax = 0; ax < 3; ++ax) moved[ax] += ct->ft[ax];
        } else if (active && ct->mu > 0.0f) {
            /* Tangential displacement relative to the collider's surface. */
            float dl[3];
            for (int ax = 0; ax < 3; ++ax) dl[ax] = p[ax] - c->x[ax][i] - ct->u[ax] * h;
            float dn = dl[0] * n[0] + dl[1] * n[1] + dl[2] * n[2];
            float tg[3] = {dl[0] - dn * n[0], dl[1] - dn * n[1], dl[2] - dn * n[2]};
            float tl = sqrtf(tg[0] * tg[0] + tg[1] * tg[1] + tg[2] * tg[2]);
            /* The solvers without color passes (Jacobi, serial Gauss-Seidel,
             * Chebyshev, direct). Coulomb: the tangential impulse is at most mu times
             * the normal one, its force from the row residual
             * (rbc_collide_normal_forces; the push estimate above was about twice too
             * large for the color swept last). On a slope that is Coulomb's law
             * (test_contact, Jacobi and direct, within 1%); the static test is in a
             * free particle's units, so a particle its springs pull along a box's edge
             * can still be held, which the color passes avoid (collide.h). The energy
             * guard's work estimate keeps the push estimate: moved to the residual it
             * changed the stacked layers' test (a piercing at frame 6). */
            float lim = ct->mu * ct->fn_row * h * h / c->topo.mass[i];
            float f = tl <= lim ? 1.0f : lim / tl; /* static: all of it; kinetic: mu disp */
            for (int ax = 0; ax < 3; ++ax) {
                float corr = -f * tg[ax];
                c->p[ax][i] += corr;
                moved[ax] += corr;
            }
        }
        /* Work of a moving collider: impulse (m * displacement / h) . its velocity. */
        const float *u = ct->u;
        if (fn > 0.0f && (u[0] != 0.0f || u[1] != 0.0f || u[2] != 0.0f)) {
            double wk = (double)c->topo.mass[i] * inv_h *
                        ((double)moved[0] * u[0] + (double)moved[1] * u[1] + (double)moved[2] * u[2]);
            if (work_out)
                *work_out += wk;
            else
                c->e_blk[(size_t)RBC_EPB * (i / RBC_ENERGY_BLOCK) + RBC_E_WC] += wk;
        }
    }
}

void rbc_collide_post(rbc_solver *s, float f0, float f1, float h, uint32_t tid, uint32_t nt) {
    const float inv_h = 1.0f / h;
    for (uint32_t ci = 0; ci < s->collider_count; ++ci) {
        const rbc_collider_state *col = &s->colliders[ci];
        rbc_frame A, B;
        rbc_collider_frame_at(col, f0, &A);
        rbc_collider_frame_at(col, f1, &B);
        for (uint32_t k = 0; k < s->cloth_count; ++k) {
            rbc_cloth_state *c = s->cloths[k];
            uint32_t i0, i1;
            rbc_energy_particle_range(c->topo.n, tid, nt, &i0, &i1);
            const float thick = col->thickness + c->thickness;
            /* Detection covered every particle whose prediction y came within thickness +
             * margin of the surface; one that ended within margin of y and did not enter
             * the shape then cannot be within thickness now (distance is 1-Lipschitz):
             * only particles the solve moved farther than the margin need a look. */
            const float margin = 0.5f * c->mean_rest, m2 = margin * margin;
            const float *restrict Y0 = c->y[0], *restrict Y1 = c->y[1], *restrict Y2 = c->y[2];
            for (uint32_t i = i0; i < i1; ++i) {
                float e0 = c->p[0][i] - Y0[i], e1 = c->p[1][i] - Y1[i], e2 = c->p[2][i] - Y2[i];
                if (e0 * e0 + e1 * e1 + e2 * e2 <= m2 || c->pinned[i]) continue;
                float xw[3] = {c->x[0][i], c->x[1][i], c->x[2][i]};
                float pw[3] = {c->p[0][i], c->p[1][i], c->p[2][i]};
                float a[3], b[3];
                to_local(&A, xw, a);
                to_local(&B, pw, b);
                int out = 0;
                for (int ax = 0; ax < 3 && !out; ++ax) {
                    float lo = a[ax] < b[ax] ? a[ax] : b[ax], hi = a[ax] < b[ax] ? b[ax] : a[ax];
                    out = hi < col->lo[ax] - thick || lo > col->hi[ax] + thick;
                }
                if (out) continue;
                float nl[3], sl[3];
                if (!shape_contact(col, a, b, thick, sl, nl)) continue;
                float nw[3], sw[3], sa[3];
                to_world_dir(&B, nl, nw);
                to_world(&B, sl, sw);
                to_world(&A, sl, sa);
                float d = nw[0] * sw[0] + nw[1] * sw[1] + nw[2] * sw[2] + thick;
                float v = d - (nw[0] * pw[0] + nw[1] * pw[1] + nw[2] * pw[2]);
                if (!(v > 0.0f)) continue;
                double wk = 0.0;
                for (int ax = 0; ax < 3; ++ax) {
                    c->p[ax][i] += v * nw[ax];
                    wk += (double)v * nw[ax] * ((sw[ax] - sa[ax]) * inv_h);
                }
                if (wk != 0.0)
                    c->e_blk[(size_t)RBC_EPB * (i / RBC_ENERGY_BLOCK) + RBC_E_WC] +=
                        (double)c->topo.mass[i] * inv_h * wk;
            }
        }
    }
}
