/* The lattice sweep without GCC's vector extension (core/lattice.c, RBC_NO_VECTOR_EXT:
 * the path MSVC's cl takes) against the build's own, on uniform grids:
 *  - each color sweep, started from the same positions, gives every particle the
 *    same position to the rounding of the two summation orders (bound below), plain
 *    and SOR, 11 iterations from a stretched state, with a pin;
 *  - the fallback's wavefront equals the fallback's plain red-black sweeps bitwise,
 *    as the vector build's does (core_grid).
 * tests/core/CMakeLists.txt compiles lattice.c a second time with RBC_NO_VECTOR_EXT
 * and its functions renamed rbc_novec_lattice_*, linked beside rbc_core's.
 *
 * The bound. A free particle of a uniform row (stiffness k, own old position o,
 * neighbours x_1..x_4 of the other color, b and r = inv_denom) is, with the vector
 * extension, g_v = (b + k ((x_1 + x_2) + (x_3 + x_4))) r, and in the fallback
 * (row_axis_uniform, edge_particle) g_s = (b + k x_1 + k x_2 + k x_3 + k x_4) r (a
 * missing neighbour reads 0 in both). Both are the same exact value; each float
 * operation rounds by at most u = 2^-24 relative, so with A = r (|b| + k sum |x_j|)
 * the recursive-summation bound gives |g_v - g| <= 5u A and |g_s - g| <= 6u A to first
 * order (g_v: 3 additions, the product by k, the addition of b, the product by r;
 * g_s: 4 products, 4 additions, the product by r), hence |g_v - g_s| <= 11u A, taken
 * as 12u A for the second-order terms. A <= r (|b| + ksum M), M the largest |position|
 * of the sweep's input, since sum k |x_j| <= ksum M. SOR, p = o + w (g - o), evaluated
 * the same way by both: w |g_v - g_s| plus, for each, the rounding of g - o, of the
 * product and of the sum, at most 3u (|o| + w (|g| + |o|)) each. With -ffp-contract
 * off (ISO C mode, CMAKE_C_EXTENSIONS OFF) nothing is fused; a fused multiply-add
 * would only drop roundings. Pinned rows take the same scalar path in both builds
 * and must match bitwise, which the bound includes. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "lattice.h"
#include "meshes.h"
#include "solver.h"

void rbc_novec_lattice_sweep(const rbc_lattice *g, struct rbc_cloth_state *c, uint32_t color,
                             float omega, uint32_t tid, uint32_t nt);
void rbc_novec_lattice_wavefront(const rbc_lattice *g, struct rbc_cloth_state *c,
                                 uint32_t iterations, float omega, volatile uint32_t *progress,
                                 size_t stride, uint32_t tid, uint32_t nt);

static const double U = 0x1p-24;

static void copy3(float *const dst[3], float *const src[3], uint32_t n) {
    for (int a = 0; a < 3; ++a) memcpy(dst[a], src[a], sizeof(float) * n);
}

static void test_grid(uint32_t nx, uint32_t ny) {
    rbc_allocator al = rbc_allocator_default();
    rbc_solver s;
    CHECK_EQ(rbc_solver_init(&s, &al, 1), RBC_OK);
    test_mesh m = mesh_grid(nx, ny, 0.02f);
    uint32_t pins[1] = {nx - 1}; /* row 0 takes the scalar path in both */
    rbc_mesh_input in = mesh_input(&m, pins, 1);
    rbc_cloth_state *c = NULL;
    char err[256];
    CHECK_EQ(rbc_solver_create_cloth(&s, &in, 0.0f, &c, err, sizeof err), RBC_OK);
    CHECK_EQ(rbc_solver_add_cloth(&s, c), RBC_OK);
    CHECK(c->lattice != NULL && c->lattice->k_uniform != 0.0f);
    if (!c->lattice || c->lattice->k_uniform == 0.0f) goto done;
    const rbc_topology *t = &c->topo;
    const uint32_t n = t->n;
    /* Stretched and sagging, as core_grid's tests start; y = x. */
    for (uint32_t i = 0; i < n; ++i) {
        float x = t->rest_x[i], z = t->rest_z[i];
        c->p[0][i] = c->y[0][i] = c->x[0][i] = 1.2f * x;
        c->p[1][i] = c->y[1][i] = c->x[1][i] = -0.3f * x * z + 0.02f * sinf(40.0f * x);
        c->p[2][i] = c->y[2][i] = c->x[2][i] = 1.1f * z;
        c->w[i] = 25.0f;
        c->inv_denom[i] = 1.0f / (25.0f + t->ksum[i]);
    }
    rbc_lattice_rhs(c->lattice, c, 0, 1);
    const float *B[3] = {c->bx, c->by, c->bz};
    float *start[3], *in3[3], *vec[3];
    for (int a = 0; a < 3; ++a) {
        start[a] = malloc(sizeof(float) * n);
        in3[a] = malloc(sizeof(float) * n);
        vec[a] = malloc(sizeof(float) * n);
    }
    copy3(start, c->p, n);
    const float omegas[2] = {0.0f, 1.7f};
    for (int o = 0; o < 2; ++o) {
        const double w = omegas[o];
        double worst = 0.0; /* largest |difference| / bound */
        uint32_t differ = 0, over = 0;
        copy3(c->p, start, n);
        for (int it = 0; it < 11; ++it)
            for (uint32_t col = 0; col < 2; ++col) {
                copy3(in3, c->p, n);
                double M = 0.0;
                for (int a = 0; a < 3; ++a)
                    for (uint32_t i = 0; i < n; ++i) M = fmax(M, fabs(in3[a][i]));
                rbc_lattice_sweep(c->lattice, c, col, omegas[o], 0, 1);
                copy3(vec, c->p, n);
                copy3(c->p, in3, n);
                rbc_novec_lattice_sweep(c->lattice, c, col, omegas[o], 0, 1);
                for (int a = 0; a < 3; ++a)
                    for (uint32_t i = 0; i < n; ++i) {
                        const double ov = in3[a][i], gv = vec[a][i], gs = c->p[a][i];
                        double A = c->inv_denom[i] * (fabs(B[a][i]) + t->ksum[i] * M);
                        double bound = 12.0 * U * A;
                        if (w != 0.0) {
                            /* |g| <= A; the update's own roundings, twice. */
                            bound = w * bound + 6.0 * U * (fabs(ov) + w * (A + fabs(ov)));
                        }
                        double d = fabs(gv - gs);
                        if (d != 0.0) ++differ;
                        if (d > bound) ++over;
                        if (bound > 0.0) worst = fmax(worst, d / bound);
                        else if (d > 0.0) worst = INFINITY;
                    }
                /* Go on from the vector build's positions (the next sweep's input). */
                copy3(c->p, vec, n);
            }
        CHECK_EQ(over, 0);
        printf("# %ux%u omega %.1f: %u of %u coordinates differ over 22 sweeps, the largest "
               "difference %.3f of its bound\n",
               nx, ny, w, differ, 22u * 3u * n, worst);
        /* The fallback's own wavefront: bitwise its plain sweeps. */
        copy3(c->p, start, n);
        for (int it = 0; it < 11; ++it)
            for (uint32_t col = 0; col < 2; ++col)
                rbc_novec_lattice_sweep(c->lattice, c, col, omegas[o], 0, 1);
        copy3(vec, c->p, n);
        copy3(c->p, start, n);
        uint32_t progress[16] = {0};
        rbc_novec_lattice_wavefront(c->lattice, c, 11, omegas[o], progress, 16, 0, 1);
        int same = 1;
        for (int a = 0; a < 3; ++a) same &= memcmp(vec[a], c->p[a], sizeof(float) * n) == 0;
        CHECK(same);
    }
    for (int a = 0; a < 3; ++a) {
        free(start[a]);
        free(in3[a]);
        free(vec[a]);
    }
done:
    mesh_free(&m);
    rbc_solver_fini(&s);
}

int main(void) {
    /* Odd and even widths (rows of both parities, counts not multiples of 8), and 16
     * columns: rows of exactly 8 of a color, the vector loop's smallest. */
    test_grid(41, 30);
    test_grid(40, 31);
    test_grid(16, 9);
    return check_report("core_lattice_fallback");
}
