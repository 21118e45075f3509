/* kernel_bodies.cu -- a build check, never launched: the bodies of kernels/ that the
 * CUDA module does not call yet (the CPU's ELL chunk update), each in the __global__
 * wrapper that a device path would launch, compiled for the module's architectures
 * with its flags (no FMA contraction, warnings as errors). A __host__ __device__
 * body that nothing instantiates for the device is only parsed; this makes nvcc
 * generate its device code, so a body that stops compiling there fails the build. */
#include "../../core/kernels/ell_kernels.h"

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
