/* collide.c -- contact with the built-in colliders inside the solve (collide.h). */
#include "collide.h"

#include <math.h>
#include <string.h>

#include "energy.h"
#include "simd.h"
#include "shapes.h"
#include "solver.h"

/* The per-particle math is in kernels/collide_kernels.h, shared with the backends'
 * collider kernels (backend_step.c), so both round alike. */

void rbc_collider_frame_at(const rbc_collider_state *c, float f, rbc_frame *out) {
    rbc_kc_frame_at(c->last_position, c->last_rotation, c->position, c->rotation, f, out);
}


/* The contact of a particle moving from a to b (collider frame at the substep's
 * start and end) with the shape: 1 and the surface point sl with outward normal nl
 * when the motion enters the shape (the entry point) or b is within reach of the
 * surface (its closest point). The analytic shapes in collide_kernels.h; the triangle
 * mesh through its BVH (shapes.c). */
static inline int shape_contact(const rbc_collider_state *col, const float a[3],
                                const float b[3], float reach, float sl[3], float nl[3]) {
    if (col->shape != RBC_SHAPE_TRIANGLE_MESH)
        return rbc_kc_shape_contact(col->shape, col->radius, col->half_extents, a, b, reach, sl,
                                    nl);
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
                    rbc_kc_to_local(A, xw, a);
                    rbc_kc_to_local(B, yw, b);
                    /* The motion entered the shape: the tangent plane at the entry point,
                     * wherever y ended up (through a thin shape, or deep in); else the
                     * closest point of y, if within reach. */
                    float nl[3], sl[3];
                    if (!shape_contact(col, a, b, reach, sl, nl)) continue;
                    uint32_t slot = list->need++;
                    if (slot >= list->cap) continue;
                    rbc_col_contact *ct = &list->c[slot];
                    rbc_kc_contact_make(A, B, sl, nl, thick, inv_h, yw, ct->n, &ct->d, ct->u,
                                        &ct->depth);
                    ct->cloth = k;
                    ct->idx = i;
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

/* Project contact ct of particle i of P (with the pass's friction when h > 0). */
static int project_one(rbc_col_contact *ct, const rbc_cloth_state *c, float *const P[3],
                       uint32_t i, float h) {
    float p[3] = {P[0][i], P[1][i], P[2][i]};
    const float x[3] = {c->x[0][i], c->x[1][i], c->x[2][i]};
    if (!rbc_kc_project(ct->n, ct->d, ct->mu, ct->u, x, p, h, &ct->last, ct->ft)) return 0;
    for (int a = 0; a < 3; ++a) P[a][i] = p[a];
    return 1;
}

int rbc_collide_project(rbc_solver *s, rbc_contact_list *list, int alt, float h) {
    int moved = 0;
    for (uint32_t m = 0; m < list->count; ++m) {
        rbc_col_contact *ct = &list->c[m];
        const rbc_cloth_state *c = s->cloths[ct->cloth];
        moved |= project_one(ct, c, alt ? c->alt : c->p, ct->idx, h);
    }
    return moved;
}

uint32_t rbc_collide_color_of(const rbc_topology *t, uint32_t i) {
    uint32_t c = 0;
    while (c + 1 < t->ncolors && i >= t->color_start[c + 1]) ++c;
    return c;
}

int rbc_collide_project_color(rbc_solver *s, rbc_contact_list *list, uint32_t color, float h) {
    /* Not pressed: no friction, the last one's stays counted (rbc_kc_project leaves
     * ft as it was). */
    int moved = 0;
    for (uint32_t m = 0; m < list->count; ++m) {
        rbc_col_contact *ct = &list->c[m];
        if (ct->color != color) continue;
        const rbc_cloth_state *c = s->cloths[ct->cloth];
        moved |= project_one(ct, c, c->p, ct->idx, h);
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
        float *const bv[3] = {c->bx, c->by, c->bz};
        float f[3];
        rbc_kc_row_residual(ct->idx, t->adj_start, t->adj_nbr, t->adj_k, t->mass, t->ksum, bv,
                            c->p, inv_h2, f);
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
        } else {
            /* The solvers without color passes (Jacobi, serial Gauss-Seidel,
             * Chebyshev, direct): the tangential displacement relative to the
             * collider's surface, for a contact touching at the end (within a hair of
             * the plane) and pushed at some point (by the prediction's depth or the
             * last pass, rbc_kc_finish_friction). Coulomb: the tangential impulse is at most mu
             * times the normal one, its force from the row residual
             * (rbc_collide_normal_forces; the push estimate above was about twice too
             * large for the color swept last). On a slope that is Coulomb's law
             * (test_contact, Jacobi and direct, within 1%); the static test is in a
             * free particle's units, so a particle its springs pull along a box's edge
             * can still be held, which the color passes avoid (collide.h). The energy
             * guard's work estimate keeps the push estimate: moved to the residual it
             * changed the stacked layers' test (a piercing at frame 6). */
            const float x[3] = {c->x[0][i], c->x[1][i], c->x[2][i]};
            float corr[3];
            if (rbc_kc_finish_friction(n, ct->d, ct->u, ct->depth, ct->last, ct->mu, ct->fn_row,
                                       c->topo.mass[i], x, p, h, corr))
                for (int ax = 0; ax < 3; ++ax) {
                    c->p[ax][i] = p[ax];
                    moved[ax] += corr[ax];
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

/* rbc_kc_post_one for a triangle mesh (its queries are shapes.c's). */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((noinline)) /* as post_one below */
#endif
static int mesh_post_one(const rbc_collider_state *col, const rbc_frame *A, const rbc_frame *B,
                         float thick, const float xw[3], const float pw[3], float *v, float nw[3],
                         float sw[3], float sa[3]) {
    float a[3], b[3];
    rbc_kc_to_local(A, xw, a);
    rbc_kc_to_local(B, pw, b);
    for (int ax = 0; ax < 3; ++ax) {
        float lo = a[ax] < b[ax] ? a[ax] : b[ax], hi = a[ax] < b[ax] ? b[ax] : a[ax];
        if (hi < col->lo[ax] - thick || lo > col->hi[ax] + thick) return 0;
    }
    float nl[3], sl[3];
    if (!shape_contact(col, a, b, thick, sl, nl)) return 0;
    rbc_kc_to_world_dir(B, nl, nw);
    rbc_kc_to_world(B, sl, sw);
    rbc_kc_to_world(A, sl, sa);
    float d = nw[0] * sw[0] + nw[1] * sw[1] + nw[2] * sw[2] + thick;
    *v = d - (nw[0] * pw[0] + nw[1] * pw[1] + nw[2] * pw[2]);
    return *v > 0.0f;
}

/* The shapes' test for the few particles the cull lets through, out of line: inlined
 * (all four shapes, the double-precision queries), it made the loop around it spill
 * for every particle (+31 % instructions in rbc_collide_post, callgrind). */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((noinline))
#endif
static int post_one(const rbc_collider_state *col, const rbc_frame *A, const rbc_frame *B,
                    float thick, const float xw[3], const float pw[3], float *v, float nw[3],
                    float sw[3], float sa[3]) {
    return rbc_kc_post_one(col->shape, col->radius, col->half_extents, col->lo, col->hi, A, B,
                           thick, xw, pw, v, nw, sw, sa);
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
            /* The arrays in locals: the test below runs for every particle, and through
             * c-> the compiler reloads them after each store of the rare path. */
            float *restrict P0 = c->p[0], *restrict P1 = c->p[1], *restrict P2 = c->p[2];
            const float *restrict X0 = c->x[0], *restrict X1 = c->x[1], *restrict X2 = c->x[2];
            const uint8_t *restrict pin = c->pinned;
            for (uint32_t i = i0; i < i1; ++i) {
                float e0 = P0[i] - Y0[i], e1 = P1[i] - Y1[i], e2 = P2[i] - Y2[i];
                if (e0 * e0 + e1 * e1 + e2 * e2 <= m2 || pin[i]) continue;
                float xw[3] = {X0[i], X1[i], X2[i]};
                float pw[3] = {P0[i], P1[i], P2[i]};
                float v, nw[3], sw[3], sa[3];
                if (col->shape == RBC_SHAPE_TRIANGLE_MESH) {
                    if (!mesh_post_one(col, &A, &B, thick, xw, pw, &v, nw, sw, sa)) continue;
                } else if (!post_one(col, &A, &B, thick, xw, pw, &v, nw, sw, sa)) {
                    continue;
                }
                double wk = 0.0;
                float *const P[3] = {P0, P1, P2};
                for (int ax = 0; ax < 3; ++ax) {
                    P[ax][i] += v * nw[ax];
                    wk += (double)v * nw[ax] * ((sw[ax] - sa[ax]) * inv_h);
                }
                if (wk != 0.0)
                    c->e_blk[(size_t)RBC_EPB * (i / RBC_ENERGY_BLOCK) + RBC_E_WC] +=
                        (double)c->topo.mass[i] * inv_h * wk;
            }
        }
    }
}
