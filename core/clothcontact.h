/* clothcontact.h -- cloth-against-cloth and self-collision: vertex-triangle and
 * vertex-vertex contacts found with a spatial hash, kept apart by a thickness with
 * an inequality projection, and Coulomb friction.
 *
 * Where it sits in a substep (step.c, contact_step.c):
 *     predict        p = inertial prediction, x = start of the substep
 *     detect         contacts from the swept boxes x..p (this file)
 *     solve          after every linear iteration: project (a pass of its own:
 *                    a contact joins particles that may share a color, so it cannot
 *                    run inside a parallel color sweep)
 *     friction       once, after the solve
 *
 * A vertex-triangle contact remembers the side of the triangle the vertex was on at
 * x and is projected back to that side at distance >= thickness (Bridson, Fedkiw and
 * Anderson 2002, "Robust treatment of collisions, contact and friction for cloth
 * animation": repulsions spread over the corners by barycentric weights; Mueller et
 * al. 2007, "Position based dynamics": the mass-weighted projection of a point-
 * triangle constraint). Friction is position-based (Macklin et al. 2014, "Unified
 * particle physics for real-time applications": static and kinetic friction as a
 * limit on the tangential displacement of a contact).
 *
 * The result depends only on the input: the contact list is sorted (vertex, then
 * partner, in body order), so it does not depend on the hash's cell size, table size,
 * buffer capacities or thread count. Detection is a loop over vertices whose output
 * per vertex is sorted on its own: threads split the vertices and their lists are
 * joined in order (rbc_clothcontact_detect_mt); the fail-safe's rounds are split the
 * same way (rbc_clothcontact_failsafe_mt). Projection and friction are Gauss-Seidel
 * over the list on one thread; a coloring of the contacts would parallelize them (a
 * different, still deterministic, result).
 */
#ifndef RBC_CORE_CLOTHCONTACT_H
#define RBC_CORE_CLOTHCONTACT_H
#include <stddef.h>
#include <stdint.h>

#include "alloc.h"

typedef struct rbc_contact_body { /* one cloth; arrays in the solver's internal order */
    uint32_t n;
    float *p[3];                  /* the iterate: projection moves these */
    const float *x[3];            /* positions at the start of the substep (sides are taken here) */
    const float *rest[3];         /* rest positions (to exclude pairs that touch at rest);
                                     NULL: only a triangle's own corners are excluded */
    const float *mass;            /* [n] kg; NULL = 1 kg each; <= 0 counts as pinned */
    const uint8_t *pinned;        /* [n] 1 = does not move (infinite mass); NULL = none */
    uint32_t tri_count;
    const uint32_t *tris;         /* 3 internal indices per triangle (each quad gives 2) */
    float thickness;              /* m: distance kept between this cloth's particles and
                                     cloth surfaces (between two particles: the sum of
                                     their cloths' thicknesses) */
    float friction;               /* Coulomb coefficient >= 0 */
    int self;                     /* 1: collides with itself */
    int others;                   /* 1: collides with other bodies that have others = 1 */
} rbc_contact_body;

/* RBC_CONTACT_EE: an edge of one cloth against a border edge of another (or of the
 * same, with self contact), or two interior edges where either cloth has self
 * contact. Vertex-triangle contacts cannot stop it: where a layer's border slides
 * past another's, an edge can wrap around the other's border edge and cross its
 * border triangle while no vertex passes through any triangle (in the four-layer
 * test, 232 of the first 237 crossings had a border vertex); where a cloth folds
 * sharply, one interior edge passes another (a crumpled cloth: 98 % of the
 * fail-safe's crossings). */
enum { RBC_CONTACT_VT = 0, RBC_CONTACT_VV = 1, RBC_CONTACT_EE = 2 };
/* rbc_contact.flags: the vertex's motion relative to the triangle crosses the plane
 * within thickness + margin of the triangle (it would pass through this triangle). */
/* RBC_CONTACT_THIN: the triangle was a sliver at x (see rbc_clothcontact_project).
 * RBC_CONTACT_HELD (VT): the last projection pass found the vertex on its side of
 * the triangle, within the thickness of the plane on the other side over it, or
 * being pushed back (a sliver: not deeper than the thickness on its far side; not
 * held: beside the triangle on the far side, or left alone deep; a degenerate
 * triangle keeps what the pass before said); at detection: held unless the
 * prediction is deeper than the thickness on the far side. A held vertex found
 * deeper on the far side went through since that pass, moved by the solve, and is
 * pushed back (at most twice the thickness a pass); one that was already there, or
 * came around an edge, is left alone. */
enum { RBC_CONTACT_CROSSED = 1, RBC_CONTACT_THIN = 2, RBC_CONTACT_HELD = 4 };

/* A triangle is a sliver when twice its area is below this fraction of its longest
 * edge squared (a quad's right-angled half: 0.5). The paper's cloth has springs on
 * the quad edges only, so nothing resists shear and a quad pressed or dragged can
 * fold flat: its halves' planes then turn freely while no corner moves much. A vertex
 * kept on one side of such a plane was thrown across by the plane turning (up to 10
 * mm in one substep where three cloths slid down the funnel), stretched its springs
 * through the layer and tore the pile apart. Against a sliver a vertex keeps the
 * thickness from the triangle's closest point instead, on either side. */
#define RBC_CC_SLIVER 0.1f

/* One contact, as detect made it and project / friction update it. */
typedef struct rbc_contact {
    uint32_t kind;                /* RBC_CONTACT_VT or RBC_CONTACT_VV */
    uint32_t flags;               /* RBC_CONTACT_CROSSED, RBC_CONTACT_THIN, RBC_CONTACT_HELD */
    uint32_t body_a, a;           /* VT: the vertex; VV: the first vertex (lower global index);
                                     EE: the first end of the edge */
    uint32_t body_b, b;           /* VT: the triangle; VV: the second vertex; EE: the first
                                     end of the border edge */
    uint32_t a2, b2;              /* EE: the second ends of the two edges; else 0 */
    float side;                   /* VT: +1 / -1, the side of the triangle's normal
                                     (b - a) x (c - a) the vertex keeps; VV: 1 */
    float n0[3];                  /* VV, EE: unit direction b -> a at x (EE: between the
                                     edges' closest points; used when the pair has
                                     crossed or coincides); VT: 0 */
    float n[3];                   /* unit direction of the last correction (moves a) */
    float w[3];                   /* VT: barycentric weights of the triangle point of
                                     the last correction; VV: 1, 0, 0; EE: the closest
                                     points' parameters s (along a -> a2), t (b -> b2), 0 */
    float dn;                     /* largest normal correction made by one pass since
                                     detect (m); 0 = the contact was never active */
} rbc_contact;

typedef struct rbc_clothcontact rbc_clothcontact;

int32_t rbc_clothcontact_create(const rbc_allocator *a, rbc_clothcontact **out);
void rbc_clothcontact_destroy(rbc_clothcontact *cc);

/* A vertex keeps at most this many vertex-triangle contacts, and as many
 * vertex-vertex ones: the nearest at p (ties in partner order). The resting
 * four-layer pile has about 10 per vertex with a margin of half a spring (under 1
 * with the quarter the solver uses) and the funnel's crowded spout up to 60 (a
 * vertex's most, half-spring margin); a cloth without self
 * contact folds through itself into a clump where another cloth's vertex was near
 * 559 triangles, and its contacts grew to millions (1.2 GB) in one scene. The
 * farther contacts of such a vertex are behind the nearer ones. Detection counts
 * the vertices it cut (rbc_clothcontact_capped). */
#define RBC_CC_MAX_PER_VERTEX 64u
/* All contacts together (vertex-triangle, vertex-vertex and edge-edge) are at most
 * this many per vertex taking part, plus RBC_CC_MAX_EE_PER_EDGE per interior edge
 * of a body with interior edge contacts, plus 4096: past it (edge contacts that grow without
 * bound) rbc_clothcontact_detect returns RBC_ERR_UNSTABLE, list empty. */
#define RBC_CC_MAX_TOTAL_PER_VERTEX (2u * RBC_CC_MAX_PER_VERTEX + 32u)
/* An interior edge keeps at most this many interior edge-edge contacts with the
 * later edges it finds, the nearest at p (ties in partner order; an edge cut counts
 * in rbc_clothcontact_capped with the vertices). Before it (and its term in the
 * total above), two self-colliding cloths crushed into a cube (abi_contact) made
 * more contacts than the total allowed and the step failed (RBC_ERR_UNSTABLE). */
#define RBC_CC_MAX_EE_PER_EDGE 16u

/* Find the candidate contacts of this substep from x (start) and p (the inertial
 * prediction, before the solve). With g = thickness of the vertex's cloth + margin:
 *  - vertex-triangle (a triangle of the same body if self, of another if both have
 *    others): the swept boxes (x..p of every corner) grown by g overlap, and the
 *    vertex is within g of the triangle at x, or its motion relative to the triangle
 *    crosses the triangle's plane where the two are within g (positions interpolated
 *    linearly to the time the linearised plane distance is 0), or it is within g at
 *    p. The side is the sign of the plane distance at x (for a vertex exactly on the
 *    plane, the side its relative motion goes to; +1 if none). Excluded: a vertex of
 *    the triangle, and a same-body pair within 2 * thickness at rest. Degenerate
 *    triangles at x (no normal) are skipped.
 *  - vertex-vertex: of different bodies (both others) or of one body (self) that are
 *    >= 2 * thickness apart at rest, whose closest approach over the linear motion
 *    x..p is < thickness_a + thickness_b + margin.
 *  - edge-edge: a border edge (an edge of one triangle only; found once and kept
 *    while the bodies' triangles stay the same) against the edges of the triangles
 *    whose swept boxes meet its swept box grown by its cloth's thickness + margin,
 *    of another body or (self) of its own that shares no vertex and is >= 2 *
 *    thickness apart at rest, if the closest points of the two edges are within the
 *    larger thickness + margin at x or at p; the direction between them at x is
 *    kept. Two border edges make one contact. Interior edges likewise, where either
 *    body has self contact (within it, and against the bodies it collides with),
 *    each edge's at most RBC_CC_MAX_EE_PER_EDGE. After the vertex contacts.
 * The contacts are sorted by vertex (body, index) and then partner (body, index),
 * vertex-triangle contacts first. Returns RBC_OK or RBC_ERR_OUT_OF_MEMORY (then the
 * list is empty and the object still valid). Buffers grow geometrically and are kept,
 * so a steady scene stops allocating. Cost: O(n + triangles + contacts + hash
 * entries), the vertex and interior edge contacts split over the threads
 * (rbc_clothcontact_detect_mt), the border edges' on one; a box that spans more than 512 hash cells (a particle
 * moving far in one substep) is tested by brute force against everything. */
int32_t rbc_clothcontact_detect(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count,
                                float margin);

/* rbc_clothcontact_detect on nth threads: every thread tid in [0, nth) calls it with
 * the same arguments, and sync(sync_ctx) must be a barrier of those threads (NULL
 * for one thread). Thread 0 builds the boxes and hashes, each thread finds the
 * contacts of its share of the vertices, thread 0 joins the lists and adds the edge
 * contacts: the list is the single thread's, bit for bit. Every thread gets the
 * result. */
int32_t rbc_clothcontact_detect_mt(rbc_clothcontact *cc, rbc_contact_body *bodies,
                                   uint32_t count, float margin, uint32_t tid, uint32_t nth,
                                   void (*sync)(void *), void *sync_ctx);

/* One Gauss-Seidel pass over the contacts in list order, mass-weighted (pinned =
 * infinite mass). Vertex-triangle: while the vertex lies over the triangle (its
 * closest point on the triangle is within thickness of its projection on the plane),
 * the vertex and the corners move along the normal (corners by the barycentric
 * weights of the closest point) until the vertex is on its side at plane distance >=
 * thickness. Beside the triangle, on its side, it is kept >= thickness from the
 * closest point; beside it on the other side it is put back to the plane if its
 * motion crossed this triangle (RBC_CONTACT_CROSSED: a fast vertex can end far from
 * the triangle it went through, and only this contact knows), and left alone if not
 * (it went around the edge, or it is a neighbouring triangle's business). Against a
 * sliver (RBC_CC_SLIVER: at x, RBC_CONTACT_THIN, or now) it is kept >= thickness from
 * the closest point, on whichever side it is.
 * Vertex-vertex: apart until >= thickness_a + thickness_b. Edge-edge: the closest
 * points of the two edges (their ends moved by their weights along the edges) apart
 * until >= the larger thickness, back along the direction at x if they crossed it
 * (the edge went around the border). No pull when separated. bodies and count must be those
 * given to detect (else nothing happens). Returns the largest violation found before
 * the pass (m). */
float rbc_clothcontact_project(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count);
/* The same pass on nth threads (all call it; sync is a barrier of the nth): the
 * list is ordered by colors whose contacts share no particle, so each color large
 * enough is split over the threads, and thread 0 projects the rest after them. The
 * result is bitwise the serial pass's for any thread count. No barrier at the end:
 * the caller's. */
void rbc_clothcontact_project_mt(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count,
                                 uint32_t tid, uint32_t nth, void (*sync)(void *),
                                 void *sync_ctx);

/* The largest violation project would find now, moving nothing (m): for tests and
 * stats. */
float rbc_clothcontact_violation(const rbc_clothcontact *cc, const rbc_contact_body *bodies,
                                 uint32_t count);

/* Coulomb friction after the solve (Macklin et al. 2014): for each
 * contact that was active (dn > 0), the relative tangential displacement over the
 * substep (p - x of the vertex minus that of the triangle point, tangent to the last
 * correction's direction) is removed if it is below mu * dn, else shortened by
 * mu * dn; mu = max of the two bodies' coefficients. Edge-edge contacts have none. dn is the largest correction of
 * one pass rather than their sum: the global solve between passes puts back much of
 * what the previous pass removed, so a sum would count one penetration once per
 * iteration. */
void rbc_clothcontact_friction(rbc_clothcontact *cc, rbc_contact_body *bodies, uint32_t count);

/* The fail-safe, after friction (the last change to the iterate in a substep): every
 * edge of a colliding body that crosses, at p, a triangle it may collide with (another
 * body's, or its own not sharing a vertex) puts its five vertices into an impact zone
 * (Bridson, Fedkiw and Anderson 2002; Harmon et al. 2008, "Robust treatment of
 * simultaneous collisions"): zones sharing a vertex merge, and a zone moves rigidly
 * from x by the mass-weighted mean of its vertices' motion over the substep, in
 * rounds until none crosses. x had no crossing that counts and a common translation keeps the
 * zone's pairs as at x, so crossings are only ever with what is outside a zone, and
 * each round grows a zone or stops one: a zone with a pinned vertex, or one found
 * crossing again after a round in which it neither gained a vertex nor merged, goes
 * back to x (pinned vertices stay where their pins put them). A pair that crossed at
 * x already (a tangle older than the substep, which no zone motion undoes) is not a
 * hit. The contact solve is not exact and four layers bent over a sphere
 * still end some substeps with an edge through another layer; a zone keeps its mean
 * velocity and loses its motion relative to it for one substep. (Sending every
 * vertex back to x instead stopped them while their neighbours moved on: in the
 * funnel's frames 38-42, a largest strain of 0.75-1.8 against 0.38-0.75 with no
 * fail-safe.) Static: a crossing that starts and ends within one substep
 * is the swept detection's business. Each round tests against the state it started
 * from, then moves what it found.
 *
 * On nth threads, called by every thread tid in [0, nth) with sync a barrier of them
 * (as rbc_clothcontact_detect_mt; nth = 1 and sync NULL: one thread): in each round
 * every thread tests
 * its share of the edges and triangles against the state the round started from,
 * then thread 0 moves the zones of every crossing found, in thread order, so the
 * result is the same for any thread count. *frozen (every thread): the vertices put
 * into zones. Returns RBC_OK, or RBC_ERR_OUT_OF_MEMORY (the crossings may remain). */
int32_t rbc_clothcontact_failsafe_mt(rbc_clothcontact *cc, rbc_contact_body *bodies,
                                     uint32_t count, uint32_t tid, uint32_t nth,
                                     void (*sync)(void *), void *sync_ctx, uint32_t *frozen);

uint32_t rbc_clothcontact_count(const rbc_clothcontact *cc);
/* Vertices whose vertex-triangle contacts the last detect cut to RBC_CC_MAX_PER_VERTEX. */
uint32_t rbc_clothcontact_capped(const rbc_clothcontact *cc);
/* The contacts of the last detect (valid until the next detect or destroy). */
const rbc_contact *rbc_clothcontact_list(const rbc_clothcontact *cc);
/* Bytes held (the object and every buffer at its capacity). */
size_t rbc_clothcontact_bytes(const rbc_clothcontact *cc);
#endif
