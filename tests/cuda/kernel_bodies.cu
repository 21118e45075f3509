/* kernel_bodies.cu -- a build check, never launched: the bodies of kernels/ that the
 * CUDA module does not call yet (the CPU's ELL chunk update and the lattice's row
 * bodies), each in a __global__ wrapper of the kind a device path would launch,
 * compiled for the module's architectures with its flags (no FMA contraction,
 * warnings as errors). A __host__ __device__ body that nothing instantiates for the
 * device is only parsed; this makes nvcc generate its device code, so a body that
 * stops compiling there fails the build. */
#include "../../core/kernels/ell_kernels.h"
#include "../../core/kernels/lattice_kernels.h"

/* One thread per particle of a color (one lane of its chunk): rbc_k_ell_one. width
 * and offset at the color's first chunk, p whole, the color's particles from first. */
__global__ void rbc_check_ell_color(uint32_t count, uint32_t first, const uint32_t *width,
                                    const size_t *offset, const uint32_t *nbr, const float *k,
                                    float *px, float *py, float *pz, const float *bx,
                                    const float *by, const float *bz, const float *inv,
                                    const uint8_t *pin, float omega) {
    const uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= count) return;
    rbc_k_ell_one(t, count, width, offset, nbr, k, px, py, pz, bx + first, by + first,
                  bz + first, inv + first, pin + first, px + first, py + first, pz + first,
                  omega);
}

/* The lattice's row bodies (kernels/lattice_kernels.h), one thread per particle of a
 * run (count 1 at its offset): which picks the body. The vector row
 * (rbc_k_lat_row_free) is the CPU's alone and is not compiled here. */
struct rbc_check_rows {
    float *p[3], *o[3], *q[3];
    const float *l[3], *r[3], *d[3], *u[3], *b[3], *y[3];
    const float *inv, *kl, *kr, *kd, *ku, *ll, *lr, *ld, *lu, *w;
    const uint8_t *pin;
    rbc_k_lat_gs_arrays gs;
    rbc_k_lat_jacobi_arrays jac;
    int *bad;
};

__global__ void rbc_check_lattice_rows(rbc_check_rows a, uint32_t count, int which, float omega,
                                       float kuni) {
    const uint32_t m = blockIdx.x * blockDim.x + threadIdx.x;
    if (m >= count) return;
    switch (which) {
    case 0:
        rbc_k_lat_row(1, a.p[0] + m, a.p[1] + m, a.p[2] + m, a.l[0] + m, a.l[1] + m, a.l[2] + m,
                      a.r[0] + m, a.r[1] + m, a.r[2] + m, a.d[0] + m, a.d[1] + m, a.d[2] + m,
                      a.u[0] + m, a.u[1] + m, a.u[2] + m, a.kl + m, a.kr + m, a.kd + m, a.ku + m,
                      a.b[0] + m, a.b[1] + m, a.b[2] + m, a.inv + m, a.pin + m, omega, kuni);
        break;
    case 1:
        for (int x = 0; x < 3; ++x)
            rbc_k_lat_row_axis(1, a.p[x] + m, a.l[x] + m, a.r[x] + m, a.d[x] + m, a.u[x] + m,
                               a.b[x] + m, a.inv + m, a.pin + m, omega, kuni);
        break;
    case 2:
        rbc_k_lat_edge(&a.gs, m, m, kuni, kuni, kuni, a.d, a.u, m, omega);
        break;
    case 3:
        for (int x = 0; x < 3; ++x)
            rbc_k_lat_jacobi_row(1, a.o[x] + m, a.q[x] + m, a.p[x] + m, a.l[x] + m, a.r[x] + m,
                                 a.d[x] + m, a.u[x] + m, a.b[x] + m, a.inv + m, a.pin + m,
                                 a.kl + m, a.kr + m, a.kd + m, a.ku + m, kuni, omega, kuni == 0.0f,
                                 omega != 0.0f);
        break;
    case 4:
        rbc_k_lat_jacobi_edge(&a.jac, a.p, a.o, m, m, m, m, m, 1, 1, 0, 1, omega != 0.0f, omega);
        break;
    default:
        if (rbc_k_lat_rhs_row(1, a.p[0] + m, a.p[1] + m, a.p[2] + m, a.l[0] + m, a.l[1] + m,
                              a.l[2] + m, a.r[0] + m, a.r[1] + m, a.r[2] + m, a.d[0] + m,
                              a.d[1] + m, a.d[2] + m, a.u[0] + m, a.u[1] + m, a.u[2] + m,
                              a.kl + m, a.kr + m, a.kd + m, a.ku + m, a.ll + m, a.lr + m,
                              a.ld + m, a.lu + m, a.w + m, a.y[0] + m, a.y[1] + m, a.y[2] + m,
                              a.o[0] + m, a.o[1] + m, a.o[2] + m, kuni))
            *a.bad = 1;
        break;
    }
}
