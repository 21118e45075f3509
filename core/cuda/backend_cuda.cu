/* backend_cuda.cu -- the CUDA backend of the seam (core/backend.h), built as a module
 * beside the plugin (librbcloth_cuda.so) that the plugin loads when a world asks for
 * RBC_BACKEND_CUDA. The CUDA runtime is linked statically, so the module needs only
 * the driver (libcuda.so.1), which the runtime itself loads: on a machine with no
 * driver or no device, opening fails with RBC_ERR_BACKEND_UNAVAILABLE and says why.
 *
 * Every kernel is a thin __global__ wrapper: one thread per element calling the same
 * per-element body the CPU backend loops over (kernels/pd_kernels.h). The module is
 * compiled with -fmad=false (no contraction into FMA), IEEE division and square
 * root, so each body rounds as the CPU's does (docs/design/backends.md).
 *
 * NOT YET RUN ON A GPU: no device was available where this was written; it compiles
 * for sm_80 and sm_90 and its no-device path is tested. */
#include <cuda_runtime.h>
#include <stdio.h>
#include <string.h>

extern "C" {
#include "../../abi/rbcloth.h"
#include "../backend.h"
}
#include "../kernels/collide_kernels.h"
#include "../kernels/pd_kernels.h"

namespace {

struct cuda_backend {
    int device;
    cudaStream_t stream;
    char err[256];
    char desc[320]; /* the device name (up to 256) and its figures */
};

const unsigned kBlock = 256;

/* The lowest index + 1 into *slot (0 = none), as the CPU backend's loop finds it. */
__device__ void keep_lowest(int32_t *slot, int32_t v) {
    int32_t old = *(volatile int32_t *)slot;
    while (old == 0 || v < old) {
        int32_t prev = atomicCAS(slot, old, v);
        if (prev == old) break;
        old = prev;
    }
}

/* One kernel for every stage: the switch is uniform across a launch (k is a kernel
 * argument), so it costs a branch per thread, and every stage is one wrapper. */
__global__ void stage_kernel(rbc_kernel k, rbc_dcloth c, rbc_kargs a) {
    const uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= a.count) return;
    const uint32_t i = a.first + t;
    switch (k) {
    case RBC_KERNEL_PREDICT:
        rbc_k_predict(i, c.x[0], c.x[1], c.x[2], c.q[0], c.q[1], c.q[2], c.y[0], c.y[1], c.y[2],
                      c.p[0], c.p[1], c.p[2], a.keep, a.g_h2[0], a.g_h2[1], a.g_h2[2]);
        break;
    case RBC_KERNEL_PINS:
        rbc_k_pin(i, c.pin_idx, c.pin_start, c.pin_target, a.f, a.last, c.p[0], c.p[1], c.p[2]);
        break;
    case RBC_KERNEL_LOCAL:
        rbc_k_local(i, c.sa, c.sb, c.rest, c.ux, c.uy, c.uz, c.he_a, c.he_b, c.p[0], c.p[1],
                    c.p[2], c.d[0], c.d[1], c.d[2]);
        break;
    case RBC_KERNEL_RHS:
        rbc_k_rhs(i, c.adj_start, c.adj_k, c.d[0], c.d[1], c.d[2], c.w, c.y[0], c.y[1], c.y[2],
                  c.b[0], c.b[1], c.b[2]);
        break;
    case RBC_KERNEL_GS:
        rbc_k_gs(i, a.variant, a.omega, c.adj_start, c.adj_nbr, c.adj_k, c.b[0], c.b[1], c.b[2],
                 c.inv_denom, c.pinned, c.p[0], c.p[1], c.p[2], c.alt[0], c.alt[1], c.alt[2]);
        break;
    case RBC_KERNEL_JACOBI:
        rbc_k_jacobi(i, a.variant, a.omega, c.adj_start, c.adj_nbr, c.adj_k, c.b[0], c.b[1],
                     c.b[2], c.inv_denom, c.pinned, a.src[0], a.src[1], a.src[2], a.dst[0],
                     a.dst[1], a.dst[2], c.prev[0], c.prev[1], c.prev[2]);
        break;
    case RBC_KERNEL_CHEB_BLEND:
        for (int ax = 0; ax < 3; ++ax)
            rbc_k_cheb_blend(i, a.omega, c.pinned, c.p[ax], c.prev[ax], c.alt[ax]);
        break;
    case RBC_KERNEL_COPY:
        for (int ax = 0; ax < 3; ++ax) a.dst[ax][i] = a.src[ax][i];
        break;
    case RBC_KERNEL_CHECK:
        if (!rbc_k_finite(i, c.p[0], c.p[1], c.p[2])) keep_lowest(&c.bad[0], (int32_t)i + 1);
        break;
    case RBC_KERNEL_SPRINGS:
        if (!rbc_k_spring_ok(i, c.sa, c.sb, c.rest, a.stretch, a.floor_len, c.p[0], c.p[1],
                             c.p[2]))
            keep_lowest(&c.bad[1], (int32_t)i + 1);
        break;
    case RBC_KERNEL_COLLIDE_FRAMES:
        rbc_kc_frames(i, c.cols, a.f0, a.f);
        break;
    case RBC_KERNEL_COLLIDE_DETECT: {
        uint32_t m = rbc_kc_detect(i, c.cols, c.ncols, c.x, c.p, c.pinned, a.thick, a.mu,
                                   a.margin, 1.0f / a.h, c.n, c.slots, c.ct, c.ncon);
        if (m > c.slots) keep_lowest(&c.bad[2], (int32_t)i + 1);
        if (a.last && m) atomicAdd(&c.bad[3], (int32_t)m); /* integers: any order */
        break;
    }
    case RBC_KERNEL_COLLIDE_PROJECT:
        rbc_kc_project_particle(i, c.n, c.slots, c.ncon, c.ct, c.x, a.dst, a.h);
        break;
    case RBC_KERNEL_COLLIDE_NORMAL:
        rbc_kc_normal_particle(i, c.n, c.slots, c.ncon, c.ct, c.adj_start, c.adj_nbr, c.adj_k,
                               c.mass, c.ksum, c.b, c.p, a.h);
        break;
    case RBC_KERNEL_COLLIDE_FINISH:
        rbc_kc_finish_particle(i, c.n, c.slots, c.ncon, c.ct, c.mass, c.x, c.p, a.h);
        break;
    case RBC_KERNEL_COLLIDE_POST:
        rbc_kc_post_particle(i, c.cols, c.ncols, c.x, c.y, c.p, c.pinned, a.thick, a.margin);
        break;
    default: break;
    }
}

int32_t fail(cuda_backend *b, cudaError_t e, const char *what) {
    snprintf(b->err, sizeof b->err, "%s: %s (%s)", what, cudaGetErrorString(e),
             cudaGetErrorName(e));
    return e == cudaErrorMemoryAllocation ? RBC_ERR_OUT_OF_MEMORY : RBC_ERR_BACKEND_UNAVAILABLE;
}

void *cu_alloc(void *be, size_t bytes) {
    cuda_backend *b = (cuda_backend *)be;
    void *p = NULL;
    cudaError_t e = cudaMalloc(&p, bytes);
    if (e != cudaSuccess) {
        fail(b, e, "cudaMalloc");
        return NULL;
    }
    /* The backend's memory starts zeroed, as the CPU backend's calloc. */
    e = cudaMemsetAsync(p, 0, bytes, b->stream);
    if (e != cudaSuccess) {
        fail(b, e, "cudaMemsetAsync");
        cudaFree(p);
        return NULL;
    }
    return p;
}

void cu_release(void *be, void *ptr) {
    (void)be;
    cudaFree(ptr);
}

int32_t cu_upload(void *be, void *dst, const void *src, size_t bytes) {
    cuda_backend *b = (cuda_backend *)be;
    if (!bytes) return RBC_OK;
    /* From pageable host memory: the call returns once the source was staged, so
     * the host may reuse it at once. */
    cudaError_t e = cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaMemcpyAsync (upload)");
}

int32_t cu_download(void *be, void *dst, const void *src, size_t bytes) {
    cuda_backend *b = (cuda_backend *)be;
    if (!bytes) return RBC_OK;
    cudaError_t e = cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, b->stream);
    if (e == cudaSuccess) e = cudaStreamSynchronize(b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaMemcpyAsync (readback)");
}

int32_t cu_launch(void *be, rbc_kernel k, const rbc_kargs *a) {
    cuda_backend *b = (cuda_backend *)be;
    if (!a->count) return RBC_OK;
    const unsigned blocks = (a->count + kBlock - 1) / kBlock;
    stage_kernel<<<blocks, kBlock, 0, b->stream>>>(k, *a->c, *a);
    cudaError_t e = cudaGetLastError();
    return e == cudaSuccess ? RBC_OK : fail(b, e, "kernel launch");
}

int32_t cu_sync(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    cudaError_t e = cudaStreamSynchronize(b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaStreamSynchronize");
}

const char *cu_last_error(void *be) { return ((cuda_backend *)be)->err; }

const char *cu_describe(void *be) { return ((cuda_backend *)be)->desc; }

void cu_close(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    cudaStreamDestroy(b->stream);
    free(b);
}

const rbc_backend_ops cuda_ops = {
    "cuda",   cu_alloc,      cu_release,  cu_upload, cu_download, cu_launch,
    cu_sync,  cu_last_error, cu_describe, cu_close,
};

} // namespace

extern "C" __attribute__((visibility("default"))) int32_t
rbc_cuda_backend_open(uint32_t interface_version, rbc_backend_handle *out, char *why,
                      size_t whylen) {
    if (interface_version != RBC_BACKEND_INTERFACE) {
        snprintf(why, whylen,
                 "the CUDA module was built for backend interface %u, the library asks for %u "
                 "(install the module built with this library)",
                 (unsigned)RBC_BACKEND_INTERFACE, (unsigned)interface_version);
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    int count = 0;
    cudaError_t e = cudaGetDeviceCount(&count);
    if (e != cudaSuccess || count == 0) {
        /* No driver at all reads as an "insufficient" one to the runtime. */
        snprintf(why, whylen,
                 "no CUDA device (no NVIDIA driver, one older than this CUDA %d.%d runtime "
                 "needs, or no GPU): cudaGetDeviceCount says %s (%s)",
                 CUDART_VERSION / 1000, (CUDART_VERSION % 1000) / 10,
                 e == cudaSuccess ? "0 devices" : cudaGetErrorString(e),
                 e == cudaSuccess ? "cudaSuccess" : cudaGetErrorName(e));
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    cudaDeviceProp prop;
    memset(&prop, 0, sizeof prop);
    if ((e = cudaGetDeviceProperties(&prop, 0)) != cudaSuccess || (e = cudaSetDevice(0)) != cudaSuccess) {
        snprintf(why, whylen, "CUDA device 0: %s (%s)", cudaGetErrorString(e), cudaGetErrorName(e));
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    cuda_backend *b = (cuda_backend *)calloc(1, sizeof *b);
    if (!b) {
        snprintf(why, whylen, "out of host memory");
        return RBC_ERR_OUT_OF_MEMORY;
    }
    b->device = 0;
    /* A stream of the world's own: worlds on other threads do not wait for it. */
    if ((e = cudaStreamCreateWithFlags(&b->stream, cudaStreamNonBlocking)) != cudaSuccess) {
        snprintf(why, whylen, "cudaStreamCreate: %s (%s)", cudaGetErrorString(e), cudaGetErrorName(e));
        free(b);
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    snprintf(b->err, sizeof b->err, "no error");
    snprintf(b->desc, sizeof b->desc, "%.255s (sm_%d%d, %.1f GiB)", prop.name, prop.major, prop.minor,
             (double)prop.totalGlobalMem / (1024.0 * 1024.0 * 1024.0));
    out->ops = &cuda_ops;
    out->be = b;
    return RBC_OK;
}
