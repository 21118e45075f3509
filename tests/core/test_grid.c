/* The grid fast path (core/grid.c):
 *  - detection: a lattice in host order is found (any nx x ny, two columns included);
 *    shear springs (4 colors), a shuffled vertex order, a torus and an irregular mesh
 *    are not, and take the CSR path;
 *  - the fused local step + right-hand side equals rbc_k_local + rbc_k_rhs to float
 *    rounding of the different summation order;
 *  - whole steps (integrate, local, 11 RBGS or SOR iterations) agree with the CSR path
 *    to a bound derived from that rounding, with pins, for 1 and 2 threads, and the
 *    fast path's result does not depend on the thread count (bitwise);
 *  - the temporally blocked wavefront equals plain red-black iterations bitwise;
 *  - the ELLPACK sweep of other meshes agrees with the CSR rows in the same way, and
 *    its shared body run one lane at a time (a device thread's share) gives the
 *    chunked sweep's result bitwise;
 *  - the lattice Jacobi (plain and Chebyshev) and serial Gauss-Seidel give the CSR
 *    rows' result bitwise (same sums in the same order), in whole steps with pins,
 *    1 and 2 threads, odd and even sides, uniform and non-uniform stiffness;
 *  - a lattice with an edge that is no spring (a notch) is not treated as uniform:
 *    the broadcast stiffness would add the missing spring.
 */
#include <math.h>
#include <string.h>

#include "check.h"
#include "ell.h"
#include "global.h"
#include "lattice.h"
#include "kernels/pd_kernels.h"
#include "meshes.h"
#include "solver.h"

static rbc_cloth_state *make(rbc_solver *s, const test_mesh *m, const uint32_t *pins,
                             uint32_t npins, float shear) {
    rbc_mesh_input in = mesh_input(m, pins, npins);
    in.shear_stiffness = shear;
    rbc_cloth_state *c = NULL;
    char err[256];
    CHECK_EQ(rbc_solver_create_cloth(s, &in, 0.0f, &c, err, sizeof err), RBC_OK);
    CHECK_EQ(rbc_solver_add_cloth(s, c), RBC_OK);
    return c;
}

static void test_detection(void) {
    rbc_allocator a = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &a, 1), RBC_OK);
    const uint32_t sizes[][2] = {{100, 100}, {7, 3}, {2, 2}, {2, 60}, {3, 50}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; ++k) {
        test_mesh m = mesh_grid(sizes[k][0], sizes[k][1], 0.01f);
        rbc_cloth_state *c = make(&s, &m, NULL, 0, 0.0f);
        CHECK(c->lattice != NULL);
        if (c->lattice) {
            CHECK_EQ(c->lattice->nx, sizes[k][0]);
            CHECK_EQ(c->lattice->ny, sizes[k][1]);
        }
        mesh_free(&m);
    }
    test_mesh m = mesh_grid(20, 20, 0.01f);
    rbc_cloth_state *c = make(&s, &m, NULL, 0, 500.0f); /* shear: 4 colors */
    CHECK(c->lattice == NULL);
    /* The same grid with its vertices renumbered: no lattice in host order. */
    test_mesh sh = mesh_grid(20, 20, 0.01f);
    uint32_t perm[400];
    for (uint32_t v = 0; v < 400; ++v) perm[v] = (v * 7u + 3u) % 400u; /* 7 and 400 coprime */
    for (uint32_t v = 0; v < 400; ++v)
        for (int ax = 0; ax < 3; ++ax) sh.pos[3 * perm[v] + ax] = m.pos[3 * v + ax];
    for (uint32_t q = 0; q < 4 * sh.nq; ++q) sh.quads[q] = perm[m.quads[q]];
    c = make(&s, &sh, NULL, 0, 0.0f);
    CHECK(c->lattice == NULL);
    test_mesh tor = mesh_torus(12, 10);
    c = make(&s, &tor, NULL, 0, 0.0f);
    CHECK(c->lattice == NULL);
    test_mesh tri = mesh_split_triangles(10);
    c = make(&s, &tri, NULL, 0, 0.0f);
    CHECK(c->lattice == NULL);
    mesh_free(&m);
    mesh_free(&sh);
    mesh_free(&tor);
    mesh_free(&tri);
    rbc_solver_fini(&s);
}

/* A state with some stretch and sag, and y a Verlet-like target near it. */
static void perturb(rbc_cloth_state *c) {
    const rbc_topology *t = &c->topo;
    for (uint32_t i = 0; i < t->n; ++i) {
        float x = t->rest_x[i], z = t->rest_z[i];
        c->x[0][i] = c->q[0][i] = 1.2f * x;
        c->x[1][i] = c->q[1][i] = -0.3f * x * z + 0.02f * sinf(40.0f * x);
        c->x[2][i] = c->q[2][i] = 1.1f * z;
    }
}

/* max |a - b| over the positions of two cloths built from the same mesh. */
static double max_diff(const rbc_cloth_state *a, const rbc_cloth_state *b) {
    double d = 0.0;
    for (int ax = 0; ax < 3; ++ax)
        for (uint32_t i = 0; i < a->topo.n; ++i) d = fmax(d, fabs((double)a->x[ax][i] - b->x[ax][i]));
    return d;
}

/* Two solvers alike, each with the same cloth: c[0] keeps its fast path (lattice or
 * ELL), c[1] is made to take the CSR rows by the caller. */
typedef struct twins {
    rbc_allocator al;
    rbc_solver s[2];
    rbc_cloth_state *c[2];
} twins;

static void twins_init(twins *t, uint32_t threads) {
    t->al = rbc_allocator_default();
    for (int k = 0; k < 2; ++k) CHECK_EQ(rbc_solver_init(&t->s[k], &t->al, threads), RBC_OK);
}

/* Both solvers: kind, and no energy guard (the paths are compared, not the guard). */
static void twins_settings(twins *t, rbc_solver_kind kind) {
    rbc_solver_settings st = t->s[0].settings;
    st.kind = kind;
    st.energy_guard = RBC_ENERGY_GUARD_OFF;
    for (int k = 0; k < 2; ++k) CHECK_EQ(rbc_solver_set_settings(&t->s[k], &st), RBC_OK);
}

static void twins_cloths(twins *t, const test_mesh *m, const uint32_t *pins, uint32_t npins) {
    for (int k = 0; k < 2; ++k) t->c[k] = make(&t->s[k], m, pins, npins, 0.0f);
}

/* Steps both `frames` times at 2 ms: the largest max_diff of the two cloths after a
 * frame. */
static double twins_worst(twins *t, int frames) {
    char err[256];
    double worst = 0.0;
    for (int f = 0; f < frames; ++f) {
        CHECK_EQ(rbc_solver_step(&t->s[0], 0.002f, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_step(&t->s[1], 0.002f, err, sizeof err), RBC_OK);
        worst = fmax(worst, max_diff(t->c[0], t->c[1]));
    }
    return worst;
}

static void twins_fini(twins *t) {
    rbc_solver_fini(&t->s[0]);
    rbc_solver_fini(&t->s[1]);
}

/* The scene of test_steps_grid and test_lattice_solver in tw (of `threads` threads):
 * an nx x ny grid 1 m wide (*m), two corners and an interior particle pinned (an edge
 * one when a side is 2; pins), the solvers set to kind after the cloths are made. */
static void twins_pinned_grid(twins *tw, uint32_t threads, rbc_solver_kind kind, uint32_t nx,
                              uint32_t ny, test_mesh *m, uint32_t pins[3]) {
    twins_init(tw, threads);
    *m = mesh_grid(nx, ny, 1.0f / (float)(nx - 1));
    pins[0] = 0;
    pins[1] = nx - 1;
    pins[2] = nx * (ny / 2) + nx / 2;
    twins_cloths(tw, m, pins, 3);
    twins_settings(tw, kind);
}

/* The pins of c have not moved from their rest positions. */
static void check_pins_at_rest(const rbc_cloth_state *c, const uint32_t *pins, int npins) {
    const rbc_topology *t = &c->topo;
    for (int p = 0; p < npins; ++p) {
        uint32_t i = t->to_internal[pins[p]];
        CHECK(c->x[0][i] == t->rest_x[i] && c->x[1][i] == t->rest_y[i] &&
              c->x[2][i] == t->rest_z[i]);
    }
}

static void test_rhs(void) {
    rbc_allocator al = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &al, 1), RBC_OK);
    test_mesh m = mesh_grid(33, 17, 1.0f / 32.0f);
    rbc_cloth_state *c = make(&s, &m, NULL, 0, 0.0f);
    CHECK(c->lattice != NULL);
    perturb(c);
    const rbc_topology *t = &c->topo;
    for (uint32_t i = 0; i < t->n; ++i) {
        c->w[i] = 25.0f; /* 1e-4 kg / (2 ms)^2 */
        for (int ax = 0; ax < 3; ++ax) {
            c->p[ax][i] = c->x[ax][i];
            c->y[ax][i] = c->x[ax][i] + 0.001f;
        }
    }
    /* Two particles on top of each other: the rest-direction fallback. */
    for (int ax = 0; ax < 3; ++ax) c->p[ax][t->to_internal[40]] = c->p[ax][t->to_internal[41]];
    for (uint32_t k = 0; k < t->ns; ++k)
        rbc_k_local(k, t->sa, t->sb, t->rest_len, t->ux, t->uy, t->uz, t->he_a, t->he_b, c->p[0],
                    c->p[1], c->p[2], c->dx, c->dy, c->dz);
    rbc_global_rhs(c, 0, 1);
    float *ref[3];
    for (int ax = 0; ax < 3; ++ax) {
        ref[ax] = malloc(sizeof(float) * t->n);
        memcpy(ref[ax], ax == 0 ? c->bx : ax == 1 ? c->by : c->bz, sizeof(float) * t->n);
    }
    rbc_lattice_rhs(c->lattice, c, 0, 1);
    /* Same terms (w y and s d_j, each computed by the same float operations), summed
     * in another order: the sums differ by at most 5 roundings of their largest
     * partial sum, bounded by w |y| + sum s L. */
    double worst = 0.0;
    for (int ax = 0; ax < 3; ++ax) {
        const float *b = ax == 0 ? c->bx : ax == 1 ? c->by : c->bz;
        for (uint32_t i = 0; i < t->n; ++i) {
            double scale = fabs(c->w[i] * (double)c->y[ax][i]) + t->ksum[i] * (1.0 / 32.0);
            double d = fabs((double)b[i] - ref[ax][i]) / (scale * 5.0 * ldexp(1.0, -24));
            if (d > worst) worst = d;
        }
    }
    printf("grid rhs vs CSR rhs: worst difference %.3g of the bound\n", worst);
    CHECK(worst <= 1.0);
    for (int ax = 0; ax < 3; ++ax) free(ref[ax]);
    mesh_free(&m);
    rbc_solver_fini(&s);
}

/* Whole steps: one cloth on the fast path, one identical cloth with its grid
 * removed (the CSR path). Grids of even and odd widths, rows shorter and longer than
 * a vector of 8, and a pin in the middle of a row besides the two corners: the sweep
 * takes its whole-row vector loop, its split path (pins, the first and last rows) and
 * short rows. */
static void test_steps_grid(rbc_solver_kind kind, uint32_t threads, uint32_t nx, uint32_t ny) {
    twins tw;
    test_mesh m;
    uint32_t pins[3];
    twins_pinned_grid(&tw, threads, kind, nx, ny, &m, pins);
    CHECK(tw.c[0]->lattice != NULL);
    rbc_lattice_free(tw.c[1]->lattice, &tw.al);
    tw.c[1]->lattice = NULL;
    double worst = twins_worst(&tw, 5);
    /* Each Gauss-Seidel update differs by the rounding of a 5-term sum (at most 5
     * roundings of |p| ~ 1 m: 3e-7 m) and of b; updates contract earlier differences
     * (rho < 1), so 5 frames of 11 iterations of 2 colors add at most
     * 5 * 11 * 2 * 5 * 2^-24 m = 3.3e-5 m. The pins must not have moved. */
    printf("%s, %u thread(s), %ux%u: fast path vs CSR path, worst |dp| over 5 frames %.3g m\n",
           kind == RBC_SOLVER_RBGS ? "rbgs" : "rbgs_sor", threads, nx, ny, worst);
    CHECK(worst <= 5.0 * 11 * 2 * 5 * ldexp(1.0, -24));
    check_pins_at_rest(tw.c[0], pins, 3);
    mesh_free(&m);
    twins_fini(&tw);
}

static void test_steps(rbc_solver_kind kind, uint32_t threads) {
    static const uint32_t shapes[][2] = {{64, 48}, {41, 30}, {33, 17}, {17, 12}, {9, 20}};
    for (size_t k = 0; k < sizeof shapes / sizeof shapes[0]; ++k)
        test_steps_grid(kind, threads, shapes[k][0], shapes[k][1]);
}

/* The ELLPACK sweep (meshes without lattice structure) against the CSR rows: the same
 * updates summed in another order (b first, then the slots in the same order), so
 * the same bound as the lattice path; and bitwise equal for 1 and 2 threads. */
static void test_ell(void) {
    test_mesh m = mesh_split_triangles(24);
    float *res[2];
    for (uint32_t nt = 1; nt <= 2; ++nt) {
        twins tw;
        twins_init(&tw, nt);
        twins_settings(&tw, RBC_SOLVER_RBGS); /* the default */
        uint32_t pins[2] = {0, 1};
        twins_cloths(&tw, &m, pins, 2);
        rbc_cloth_state *fast = tw.c[0];
        CHECK(fast->lattice == NULL && fast->ell != NULL);
        rbc_ell_free(tw.c[1]->ell, &tw.al);
        tw.c[1]->ell = NULL;
        double worst = twins_worst(&tw, 5);
        printf("ell, %u thread(s): ELL vs CSR, worst |dp| over 5 frames %.3g m\n", nt, worst);
        CHECK(worst <= 5.0 * 11 * 2 * 8 * ldexp(1.0, -24)); /* up to 8 terms per sum */
        res[nt - 1] = malloc(sizeof(float) * 3 * fast->topo.n);
        rbc_cloth_state_read(fast, res[nt - 1]);
        if (nt == 2) CHECK(memcmp(res[0], res[1], sizeof(float) * 3 * fast->topo.n) == 0);
        twins_fini(&tw);
    }
    free(res[0]);
    free(res[1]);
    mesh_free(&m);
}

/* The ELL update one lane at a time (rbc_k_ell_one, what a device thread runs) gives
 * the CPU's chunked sweep bitwise: each particle's sum is taken in the same slot
 * order either way. Both colors in turn, plain and SOR, on a shuffled mesh (its
 * chunks of mixed degree have padding slots) after a step has set b and the
 * denominators, from positions moved off that step's result. */
static void test_ell_lanes(void) {
    test_mesh g = mesh_split_triangles(40);
    test_mesh m = mesh_shuffled(&g, 5, 0);
    rbc_allocator al = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &al, 1), RBC_OK);
    uint32_t pins[2] = {0, 1};
    rbc_cloth_state *c = make(&s, &m, pins, 2, 0.0f);
    CHECK(c->lattice == NULL && c->ell != NULL);
    char err[256];
    CHECK_EQ(rbc_solver_step(&s, 0.002f, err, sizeof err), RBC_OK);
    const rbc_ell *e = c->ell;
    const rbc_topology *t = &c->topo;
    const size_t bytes = sizeof(float) * t->n;
    float *start[3], *sweep[3];
    for (int a = 0; a < 3; ++a) {
        start[a] = malloc(bytes);
        sweep[a] = malloc(bytes);
        for (uint32_t i = 0; i < t->n; ++i)
            c->p[a][i] = start[a][i] = c->x[a][i] + 0.01f * sinf(7.0f * (float)i + (float)a);
    }
    const float omegas[2] = {0.0f, 1.37f};
    for (int w = 0; w < 2; ++w) {
        for (int a = 0; a < 3; ++a) memcpy(c->p[a], start[a], bytes);
        for (uint32_t col = 0; col < e->ncolors; ++col) rbc_ell_sweep(e, c, col, omegas[w], 0, 1);
        for (int a = 0; a < 3; ++a) {
            memcpy(sweep[a], c->p[a], bytes);
            memcpy(c->p[a], start[a], bytes);
        }
        for (uint32_t col = 0; col < e->ncolors; ++col) {
            const uint32_t f = t->color_start[col], count = t->color_start[col + 1] - f;
            const uint32_t ch = e->chunk_start[col];
            for (uint32_t k = 0; k < count; ++k)
                rbc_k_ell_one(k, count, e->width + ch, e->offset + ch, e->nbr, e->k, c->p[0],
                              c->p[1], c->p[2], c->bx + f, c->by + f, c->bz + f,
                              c->inv_denom + f, c->pinned + f, c->p[0] + f, c->p[1] + f,
                              c->p[2] + f, omegas[w]);
        }
        int moved = 0;
        for (int a = 0; a < 3; ++a) {
            CHECK(memcmp(sweep[a], c->p[a], bytes) == 0);
            moved |= memcmp(sweep[a], start[a], bytes) != 0;
        }
        CHECK(moved);
        /* The packed sweep (ell.h): the same sums from the xyzw copy, shared out as 2
         * threads would; each color's last chunk is not a multiple of 8 long, so both
         * the 8-lane body and the one-lane tail run. p4 must come out as the copy of
         * p the next color's sweep reads. */
        for (int a = 0; a < 3; ++a) memcpy(c->p[a], start[a], bytes);
        rbc_ell_pack(c->ell, c, 0, 2);
        rbc_ell_pack(c->ell, c, 1, 2);
        for (uint32_t col = 0; col < e->ncolors; ++col)
            for (uint32_t th = 0; th < 2; ++th) rbc_ell_sweep_packed(c->ell, c, col, omegas[w], th, 2);
        for (int a = 0; a < 3; ++a) {
            CHECK(memcmp(sweep[a], c->p[a], bytes) == 0);
            for (uint32_t i = 0; i < t->n; ++i) CHECK(memcmp(&e->p4[4 * (size_t)i + a], &sweep[a][i], 4) == 0);
        }
    }
    printf("ell lanes: %u particles, %u colors: one lane at a time == the chunked sweep "
           "== the packed sweep\n",
           t->n, e->ncolors);
    for (int a = 0; a < 3; ++a) {
        free(start[a]);
        free(sweep[a]);
    }
    rbc_solver_fini(&s);
    mesh_free(&g);
    mesh_free(&m);
}

/* A mesh whose host order is scattered (an irregular mesh with its vertices
 * shuffled) is placed in memory for the sweeps (topology.c, ell.c):
 *  - spatially: Morton order within each color, so the mean distance between a
 *    spring's two ends (their ranks within their colors) is within the library's
 *    own test for a scattered order (4 sqrt(n) + 16) plus what the grouping below
 *    may move each end (less than 1024 ranks), where the shuffled input is not;
 *  - by degree within windows of 1024 particles of a color (non-decreasing), so
 *    the sliced ELLPACK chunks pad little: its slot count equals the sum over chunks
 *    of the chunk's largest degree times its length, recomputed here;
 *  - springs in the memory order of their lower host vertex (the local step walks
 *    the particles in order);
 *  - and the ELL sweep still equals the CSR rows bitwise over whole steps. */
static uint32_t color_of(const rbc_topology *t, uint32_t i) {
    uint32_t c = 0;
    while (c + 1 < t->ncolors && i >= t->color_start[c + 1]) ++c;
    return c;
}

static void test_scattered_order(void) {
    test_mesh g = mesh_split_triangles(64);
    test_mesh m = mesh_shuffled(&g, 11, 0);
    twins tw;
    twins_init(&tw, 1);
    twins_settings(&tw, RBC_SOLVER_RBGS); /* the default */
    uint32_t pins[2] = {0, 1};
    twins_cloths(&tw, &m, pins, 2);
    rbc_cloth_state *c = tw.c[0];
    const rbc_topology *t = &c->topo;
    CHECK(c->lattice == NULL && c->ell != NULL);
    double host = 0.0, mem = 0.0;
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t a = t->to_host[t->sa[k]], b = t->to_host[t->sb[k]];
        host += a > b ? a - b : b - a;
        /* Its two ends are of different colors: compare their ranks in their colors. */
        double ra = t->sa[k] - t->color_start[color_of(t, t->sa[k])];
        double rb = t->sb[k] - t->color_start[color_of(t, t->sb[k])];
        mem += fabs(ra - rb);
    }
    host /= t->ns;
    mem /= t->ns;
    const double limit = 4.0 * sqrt((double)t->n) + 16.0 + 2.0 * 1024;
    printf("scattered mesh, %u particles: mean spring span %.0f in host order, %.1f in memory "
           "(limit %.0f)\n", t->n, host, mem, limit);
    CHECK(host > limit); /* the input really is scattered */
    CHECK(mem <= limit);
    uint32_t unsorted = 0;
    for (uint32_t col = 0; col < t->ncolors; ++col)
        for (uint32_t i = t->color_start[col]; i + 1 < t->color_start[col + 1]; ++i) {
            if ((i + 1 - t->color_start[col]) % 1024 == 0) continue; /* a new window */
            unsorted += t->adj_start[i + 1] - t->adj_start[i] > t->adj_start[i + 2] - t->adj_start[i + 1];
        }
    CHECK_EQ(unsorted, 0);
    uint32_t order_breaks = 0, prev = 0;
    for (uint32_t k = 0; k < t->ns; ++k) {
        uint32_t lo = t->to_host[t->sa[k]] < t->to_host[t->sb[k]] ? t->sa[k] : t->sb[k];
        order_breaks += k > 0 && lo < prev;
        prev = lo;
    }
    CHECK_EQ(order_breaks, 0);
    size_t slots = 0;
    for (uint32_t col = 0; col < t->ncolors; ++col)
        for (uint32_t f = t->color_start[col]; f < t->color_start[col + 1]; f += RBC_ELL_CHUNK) {
            uint32_t end = f + RBC_ELL_CHUNK < t->color_start[col + 1] ? f + RBC_ELL_CHUNK
                                                                       : t->color_start[col + 1];
            uint32_t w = 0;
            for (uint32_t i = f; i < end; ++i)
                if (t->adj_start[i + 1] - t->adj_start[i] > w) w = t->adj_start[i + 1] - t->adj_start[i];
            slots += (size_t)w * (end - f);
        }
    printf("scattered mesh: %zu ELL slots for %u spring ends\n", c->ell->slots, 2 * t->ns);
    CHECK_EQ(c->ell->slots, slots);
    rbc_ell_free(tw.c[1]->ell, &tw.al);
    tw.c[1]->ell = NULL;
    twins_worst(&tw, 5);
    CHECK(max_diff(c, tw.c[1]) == 0.0); /* after the last frame */
    twins_fini(&tw);
    mesh_free(&g);
    mesh_free(&m);
}

/* The temporally blocked wavefront does exactly the updates of K plain red-then-black
 * iterations with the same inputs: bitwise the same positions, plain and SOR, on a
 * grid with odd and even row lengths. */
static void test_wavefront(void) {
    rbc_allocator al = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &al, 1), RBC_OK);
    const uint32_t dims[][2] = {{41, 30}, {40, 31}, {2, 9}};
    for (size_t d = 0; d < 3; ++d) {
        test_mesh m = mesh_grid(dims[d][0], dims[d][1], 0.02f);
        uint32_t pins[1] = {dims[d][0] - 1};
        rbc_cloth_state *c = make(&s, &m, pins, 1, 0.0f);
        CHECK(c->lattice != NULL);
        perturb(c);
        const rbc_topology *t = &c->topo;
        for (uint32_t i = 0; i < t->n; ++i) {
            c->w[i] = 25.0f;
            c->inv_denom[i] = 1.0f / (25.0f + t->ksum[i]);
            for (int ax = 0; ax < 3; ++ax) c->p[ax][i] = c->y[ax][i] = c->x[ax][i];
        }
        rbc_lattice_rhs(c->lattice, c, 0, 1);
        float *start[3], *plain[3];
        for (int ax = 0; ax < 3; ++ax) {
            start[ax] = malloc(sizeof(float) * t->n);
            plain[ax] = malloc(sizeof(float) * t->n);
            memcpy(start[ax], c->p[ax], sizeof(float) * t->n);
        }
        const float omegas[2] = {0.0f, 1.7f};
        for (int o = 0; o < 2; ++o) {
            for (int ax = 0; ax < 3; ++ax) memcpy(c->p[ax], start[ax], sizeof(float) * t->n);
            for (int it = 0; it < 11; ++it)
                for (uint32_t col = 0; col < 2; ++col) rbc_lattice_sweep(c->lattice, c, col, omegas[o], 0, 1);
            for (int ax = 0; ax < 3; ++ax) memcpy(plain[ax], c->p[ax], sizeof(float) * t->n);
            for (int ax = 0; ax < 3; ++ax) memcpy(c->p[ax], start[ax], sizeof(float) * t->n);
            uint32_t progress[16] = {0};
            rbc_lattice_wavefront(c->lattice, c, 11, omegas[o], progress, 16, 0, 1);
            int same = 1;
            for (int ax = 0; ax < 3; ++ax)
                same &= memcmp(plain[ax], c->p[ax], sizeof(float) * t->n) == 0;
            CHECK(same);
        }
        for (int ax = 0; ax < 3; ++ax) {
            free(start[ax]);
            free(plain[ax]);
        }
        mesh_free(&m);
    }
    rbc_solver_fini(&s);
}

/* The fast path's positions with 1 and 2 threads: bitwise equal. */
static void test_threads(void) {
    rbc_allocator al = rbc_allocator_default();
    float *res[3];
    /* 2 and 3 threads split the wavefront's 22 color sweeps inside an iteration. */
    for (uint32_t nt = 1; nt <= 3; ++nt) {
        rbc_solver s;
        CHECK_EQ(rbc_solver_init(&s, &al, nt), RBC_OK);
        test_mesh m = mesh_grid(101, 37, 0.01f); /* odd width: rows of both parities */
        uint32_t pins[2] = {0, 100};
        rbc_cloth_state *c = make(&s, &m, pins, 2, 0.0f);
        CHECK(c->lattice != NULL);
        char err[256];
        for (int f = 0; f < 20; ++f) CHECK_EQ(rbc_solver_step(&s, 0.002f, err, sizeof err), RBC_OK);
        res[nt - 1] = malloc(sizeof(float) * 3 * c->topo.n);
        rbc_cloth_state_read(c, res[nt - 1]);
        if (nt > 1) CHECK(memcmp(res[0], res[nt - 1], sizeof(float) * 3 * c->topo.n) == 0);
        mesh_free(&m);
        rbc_solver_fini(&s);
    }
    for (int k = 0; k < 3; ++k) free(res[k]);
}

/* Per-spring stiffness k (1 + 0.5 sin(1.7 k)) N/m for every spring, in the topology
 * (stiff, the CSR rows, ksum) and in the lattice (rebuilt from it): the same cloth
 * for the CSR and the lattice paths, with no uniform stiffness to broadcast. */
static void vary_stiffness(rbc_cloth_state *c, const rbc_allocator *al) {
    rbc_topology *t = &c->topo;
    memset(t->ksum, 0, sizeof(float) * t->n);
    for (uint32_t k = 0; k < t->ns; ++k) {
        float sk = t->stiff[k] * (1.0f + 0.5f * sinf(1.7f * (float)k));
        t->stiff[k] = t->adj_k[t->he_a[k]] = t->adj_k[t->he_b[k]] = sk;
        t->ksum[t->sa[k]] += sk;
        t->ksum[t->sb[k]] += sk;
    }
    rbc_lattice_free(c->lattice, al);
    c->lattice = NULL;
    CHECK_EQ(rbc_lattice_detect(t, al, &c->lattice), 1);
}

/* Whole steps of Jacobi, Jacobi + Chebyshev or serial Gauss-Seidel: one cloth on the
 * lattice path, one identical cloth whose lattice serves the local step and b only
 * (csr_order cleared: rbc_global_jacobi and rbc_global_gs_serial take the CSR rows).
 * The lattice path adds the same terms in the same order, so the positions must be
 * equal bitwise, and the same for 1 and 2 threads (ref: the 1-thread result, or NULL
 * to record it). */
static int test_lattice_solver(rbc_solver_kind kind, uint32_t nx, uint32_t ny, int vary,
                               uint32_t threads, float **ref) {
    twins tw;
    test_mesh m;
    uint32_t pins[3];
    twins_pinned_grid(&tw, threads, kind, nx, ny, &m, pins);
    rbc_cloth_state *fast = tw.c[0], *csr = tw.c[1];
    if (vary) {
        vary_stiffness(fast, &tw.al);
        vary_stiffness(csr, &tw.al);
    }
    CHECK(fast->lattice != NULL && csr->lattice != NULL);
    if (!fast->lattice || !csr->lattice) return 0;
    CHECK(fast->lattice->csr_order == 1);
    CHECK(vary ? fast->lattice->k_uniform == 0.0f : fast->lattice->k_uniform == 1000.0f);
    csr->lattice->csr_order = 0;
    char err[256];
    int same = 1;
    for (int f = 0; f < 5; ++f) {
        CHECK_EQ(rbc_solver_step(&tw.s[0], 0.002f, err, sizeof err), RBC_OK);
        CHECK_EQ(rbc_solver_step(&tw.s[1], 0.002f, err, sizeof err), RBC_OK);
        for (int ax = 0; ax < 3; ++ax)
            same &= memcmp(fast->x[ax], csr->x[ax], sizeof(float) * fast->topo.n) == 0;
    }
    if (!same)
        fprintf(stderr, "solver %d, %ux%u%s, %u thread(s): the lattice path differs from the "
                        "CSR path\n",
                (int)kind, nx, ny, vary ? " (varied stiffness)" : "", threads);
    CHECK(same);
    float *res = malloc(sizeof(float) * 3 * fast->topo.n);
    rbc_cloth_state_read(fast, res);
    if (*ref) {
        CHECK(memcmp(*ref, res, sizeof(float) * 3 * fast->topo.n) == 0);
        free(res);
    } else {
        *ref = res;
    }
    check_pins_at_rest(fast, pins, 3);
    mesh_free(&m);
    twins_fini(&tw);
    return same;
}

static void test_lattice_solvers(void) {
    const rbc_solver_kind kinds[3] = {RBC_SOLVER_JACOBI, RBC_SOLVER_JACOBI_CHEBYSHEV,
                                      RBC_SOLVER_GAUSS_SEIDEL};
    /* odd x even, even x odd, odd x odd, even x even, two columns, two rows */
    const uint32_t dims[][2] = {{41, 30}, {40, 31}, {33, 17}, {64, 48}, {2, 9}, {9, 2}};
    const char *names[3] = {"jacobi", "jacobi_chebyshev", "gauss_seidel"};
    for (int k = 0; k < 3; ++k) {
        int runs = 0, equal = 0;
        for (size_t d = 0; d < sizeof dims / sizeof dims[0]; ++d)
            for (int vary = 0; vary < 2; ++vary) {
                float *ref = NULL;
                for (uint32_t nt = 1; nt <= 2; ++nt, ++runs)
                    equal += test_lattice_solver(kinds[k], dims[d][0], dims[d][1], vary, nt, &ref);
                free(ref);
            }
        printf("%s: lattice path bitwise equal to the CSR path in %d of %d runs (6 grids, "
               "uniform and varied stiffness, 1 and 2 threads, 5 frames each)\n",
               names[k], equal, runs);
    }
}

/* Signed zeros: with p_y and b_y all -0 (a flat cloth at y = -0 with no load), every
 * CSR sum in y is -0. The lattice Jacobi's rows beyond the edges must add nothing
 * (s * (-0) = -0 does; a row of +0 would make the edge rows' sums +0), and the serial
 * sweep must leave the missing terms out: bitwise the CSR rows' results. */
static void test_negative_zero(void) {
    rbc_allocator al = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &al, 1), RBC_OK);
    rbc_solver_settings st = s.settings;
    st.kind = RBC_SOLVER_JACOBI_CHEBYSHEV; /* allocates alt and prev */
    CHECK_EQ(rbc_solver_set_settings(&s, &st), RBC_OK);
    test_mesh m = mesh_grid(9, 6, 0.1f);
    uint32_t pins[1] = {4};
    rbc_cloth_state *c = make(&s, &m, pins, 1, 0.0f);
    CHECK(c->lattice != NULL && c->lattice->csr_order == 1);
    if (!c->lattice) return;
    const rbc_topology *t = &c->topo;
    const uint32_t n = t->n;
    for (uint32_t i = 0; i < n; ++i) {
        c->inv_denom[i] = 1.0f / (25.0f + t->ksum[i]);
        c->bx[i] = 25.0f * t->rest_x[i];
        c->by[i] = -0.0f;
        c->bz[i] = 25.0f * t->rest_z[i];
    }
    /* [path][result][axis]: path 0 the CSR rows, 1 the lattice; results: Jacobi,
     * Jacobi + Chebyshev (prev = p), serial Gauss-Seidel. */
    float *out[2][3][3];
    for (int path = 0; path < 2; ++path) {
        c->lattice->csr_order = (uint32_t)path;
        for (int r = 0; r < 3; ++r) {
            for (int ax = 0; ax < 3; ++ax)
                for (uint32_t i = 0; i < n; ++i) {
                    c->p[ax][i] = ax == 0 ? t->rest_x[i] : ax == 1 ? -0.0f : t->rest_z[i];
                    c->prev[ax][i] = 0.9f * c->p[ax][i];
                }
            if (r < 2) rbc_global_jacobi(c, c->p, c->alt, r, 1.3f, 0, 1);
            else rbc_global_gs_serial(c);
            for (int ax = 0; ax < 3; ++ax) {
                out[path][r][ax] = malloc(sizeof(float) * n);
                memcpy(out[path][r][ax], r < 2 ? c->alt[ax] : c->p[ax], sizeof(float) * n);
            }
        }
    }
    int same = 1, negative = 1;
    for (int r = 0; r < 3; ++r)
        for (int ax = 0; ax < 3; ++ax)
            same &= memcmp(out[0][r][ax], out[1][r][ax], sizeof(float) * n) == 0;
    for (uint32_t i = 0; i < n; ++i) /* CSR's y: -0 (Chebyshev's: +0 = 1.3 (-0 - -0) + -0) */
        negative &= signbit(out[0][0][1][i]) && signbit(out[0][2][1][i]) &&
                    out[0][0][1][i] == 0.0f && out[0][2][1][i] == 0.0f;
    printf("signed zeros: lattice Jacobi, Chebyshev and serial Gauss-Seidel %s the CSR rows "
           "(whose Jacobi and Gauss-Seidel y are all -0: %s)\n",
           same ? "bitwise equal to" : "DIFFER from", negative ? "yes" : "no");
    CHECK(same);
    CHECK(negative);
    for (int p = 0; p < 2; ++p)
        for (int r = 0; r < 3; ++r)
            for (int ax = 0; ax < 3; ++ax) free(out[p][r][ax]);
    mesh_free(&m);
    rbc_solver_fini(&s);
}

/* A lattice with a notch: the bottom edge of the fourth quad of row 0 is no spring
 * (its quad removed). Still a lattice, but not every edge a spring: no uniform
 * stiffness (the broadcast would add the missing spring to the sweep's sum) and no
 * CSR-order path. RBGS on it agrees with the CSR path to test_steps' bound. */
static void test_notch(void) {
    twins tw;
    twins_init(&tw, 1);
    twins_settings(&tw, RBC_SOLVER_RBGS); /* the default */
    test_mesh m = mesh_grid(30, 20, 1.0f / 29.0f);
    memcpy(m.quads + 4 * 3, m.quads + 4 * (m.nq - 1), 4 * sizeof(uint32_t)); /* quad (3, 0) */
    m.nq--;
    uint32_t pins[2] = {0, 29};
    twins_cloths(&tw, &m, pins, 2);
    const rbc_cloth_state *fast = tw.c[0];
    CHECK(fast->lattice != NULL);
    if (!fast->lattice) return;
    CHECK(fast->lattice->k_uniform == 0.0f && fast->lattice->csr_order == 0);
    rbc_lattice_free(tw.c[1]->lattice, &tw.al);
    tw.c[1]->lattice = NULL;
    double worst = twins_worst(&tw, 5);
    printf("notched lattice, rbgs: fast path vs CSR path, worst |dp| over 5 frames %.3g m\n",
           worst);
    CHECK(worst <= 5.0 * 11 * 2 * 5 * ldexp(1.0, -24));
    mesh_free(&m);
    twins_fini(&tw);
}

int main(void) {
    test_detection();
    test_rhs();
    test_steps(RBC_SOLVER_RBGS, 1);
    test_steps(RBC_SOLVER_RBGS, 2);
    test_steps(RBC_SOLVER_RBGS_SOR, 2);
    test_threads();
    test_ell();
    test_ell_lanes();
    test_scattered_order();
    test_wavefront();
    test_lattice_solvers();
    test_negative_zero();
    test_notch();
    return check_report("core_grid");
}
