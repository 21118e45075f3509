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
#include <stdlib.h>
#include <string.h>

extern "C" {
#include "../../abi/rbcloth.h"
#include "../backend.h"
#include "../energy.h" /* RBC_ENERGY_BLOCK, the blocks' layout */
#include "../strain.h" /* RBC_STRAIN_BLOCK */
}
#include "../kernels/measure_kernels.h"
#include "../kernels/collide_kernels.h"
#include "../kernels/pd_kernels.h"

namespace {

struct cuda_backend {
    int device;
    cudaStream_t stream;
    /* CUDA graphs (backend.h's step_begin/step_end): whether they are used
     * ($RBC_CUDA_GRAPHS=0 turns them off, to compare), a capture under way, and the
     * executable graph of the last recorded step, updated in place while the next
     * step's launches have the same shape (only their arguments differ). */
    int graphs, capturing;
    cudaGraphExec_t exec;
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

/* The residual's sums: each thread its particle's terms, a warp's sum by shuffles,
 * one atomicAdd per warp (double atomics: sm_60 and later). The order differs from
 * the CPU's, so the sums agree to rounding; they only decide when to stop. */
__global__ void residual_kernel(rbc_dcloth c, rbc_kargs a) {
    const uint32_t t = blockIdx.x * blockDim.x + threadIdx.x;
    double r = 0.0, bb = 0.0;
    if (t < a.count && !c.pinned[a.first + t])
        rbc_k_residual(a.first + t, c.adj_start, c.adj_nbr, c.adj_k, c.b[0], c.b[1], c.b[2],
                       c.inv_denom, c.p[0], c.p[1], c.p[2], c.pinned, &r, &bb);
    for (int off = 16; off > 0; off >>= 1) {
        r += __shfl_down_sync(0xFFFFFFFFu, r, off);
        bb += __shfl_down_sync(0xFFFFFFFFu, bb, off);
    }
    if ((threadIdx.x & 31u) == 0) {
        atomicAdd(&c.sums[0], r);
        atomicAdd(&c.sums[1], bb);
    }
}

/* The block sums of the strain and the energy: one thread per block, in order, as
 * energy.h and strain.h define the blocks (a few hundred threads at 1M particles;
 * these run once or twice a step, and a tree sum would order them otherwise). */
__global__ void block_kernel(rbc_kernel k, rbc_dcloth c, rbc_kargs a) {
    const uint32_t blk = a.first + blockIdx.x * blockDim.x + threadIdx.x;
    if (blk >= a.first + a.count) return;
    if (k == RBC_KERNEL_STRAIN) {
        uint32_t s0 = blk * RBC_STRAIN_BLOCK, s1 = s0 + RBC_STRAIN_BLOCK;
        if (s1 > c.ns) s1 = c.ns;
        double sum = 0.0;
        float n = 0.0f;
        for (uint32_t s = s0; s < s1; ++s) {
            uint32_t i = c.sa[s], j = c.sb[s];
            float L = c.rest[s];
            int live = L > 0.0f; /* torn cloths are not on a backend */
            float r = rbc_k_rel_strain_f(a.pos[0][i] - a.pos[0][j], a.pos[1][i] - a.pos[1][j],
                                         a.pos[2][i] - a.pos[2][j], L, live);
            sum += (double)(r * r);
            n += live ? 1.0f : 0.0f;
        }
        c.strain_blk[2 * (size_t)blk] = sum;
        c.strain_blk[2 * (size_t)blk + 1] = n;
        return;
    }
    /* RBC_KERNEL_ENERGY */
    uint32_t i0 = blk * RBC_ENERGY_BLOCK, i1 = i0 + RBC_ENERGY_BLOCK;
    if (i1 > c.n) i1 = c.n;
    double ke = 0.0, ug = 0.0, mag = 0.0, md = 0.0, wsum = 0.0;
    uint32_t xbits = 0;
    for (uint32_t i = i0; i < i1; ++i) {
        uint32_t bm = __float_as_uint(a.pos[0][i]) & 0x7FFFFFFFu;
        uint32_t by = __float_as_uint(a.pos[1][i]) & 0x7FFFFFFFu;
        uint32_t bz = __float_as_uint(a.pos[2][i]) & 0x7FFFFFFFu;
        bm = bm > by ? bm : by;
        bm = bm > bz ? bm : bz;
        xbits = xbits > bm ? xbits : bm;
        rbc_k_energy_terms(i, a.pos[0], a.pos[1], a.pos[2], a.prev[0], a.prev[1], a.prev[2], c.w,
                           c.mass, c.pinned, a.g[0], a.g[1], a.g[2], &ke, &ug, &mag, &md, &wsum);
    }
    const double gn = sqrt((double)a.g[0] * a.g[0] + (double)a.g[1] * a.g[1] +
                           (double)a.g[2] * a.g[2]);
    double *o = c.e_blk + (size_t)RBC_EPB * blk;
    o[RBC_E_KE] = 0.5 * ke;
    o[RBC_E_UG] = ug;
    o[RBC_E_MAG] = mag * gn;
    o[RBC_E_WSUM] = wsum;
    o[RBC_E_MD] = md;
    o[RBC_E_XMAX] = __uint_as_float(xbits);
}

/* The pins' work over the springs at pins, one thread in order (a few per pin). */
__global__ void pin_work_kernel(rbc_dcloth c, rbc_kargs a) {
    double w = 0.0;
    for (uint32_t m = 0; m < c.pin_spring_count; ++m) {
        uint32_t k = c.pin_springs[m];
        w += rbc_k_spring_energy_at(k, c.sa, c.sb, c.rest, c.stiff, c.pinned, a.prev[0],
                                    a.prev[1], a.prev[2], a.pos[0], a.pos[1], a.pos[2]) -
             rbc_k_spring_energy_at(k, c.sa, c.sb, c.rest, c.stiff, c.pinned, a.prev[0],
                                    a.prev[1], a.prev[2], a.prev[0], a.prev[1], a.prev[2]);
    }
    c.sums[2] += w;
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

/* The schedule never copies or waits within a recorded step (backend.h); one that did
 * would read or write state the graph has not run yet. */
int32_t in_capture(cuda_backend *b, const char *what) {
    snprintf(b->err, sizeof b->err, "%s inside a recorded step (a schedule bug)", what);
    return RBC_ERR_INVALID_ARGUMENT;
}

int32_t cu_upload(void *be, void *dst, const void *src, size_t bytes) {
    cuda_backend *b = (cuda_backend *)be;
    if (b->capturing) return in_capture(b, "upload");
    if (!bytes) return RBC_OK;
    /* From pageable host memory: the call returns once the source was staged, so
     * the host may reuse it at once. */
    cudaError_t e = cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaMemcpyAsync (upload)");
}

int32_t cu_download(void *be, void *dst, const void *src, size_t bytes) {
    cuda_backend *b = (cuda_backend *)be;
    if (b->capturing) return in_capture(b, "readback");
    if (!bytes) return RBC_OK;
    cudaError_t e = cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, b->stream);
    if (e == cudaSuccess) e = cudaStreamSynchronize(b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaMemcpyAsync (readback)");
}

int32_t cu_launch(void *be, rbc_kernel k, const rbc_kargs *a) {
    cuda_backend *b = (cuda_backend *)be;
    if (!a->count) return RBC_OK;
    const unsigned blocks = (a->count + kBlock - 1) / kBlock;
    if (k == RBC_KERNEL_RESIDUAL)
        residual_kernel<<<blocks, kBlock, 0, b->stream>>>(*a->c, *a);
    else if (k == RBC_KERNEL_STRAIN || k == RBC_KERNEL_ENERGY)
        block_kernel<<<(a->count + 63) / 64, 64, 0, b->stream>>>(k, *a->c, *a);
    else if (k == RBC_KERNEL_PIN_WORK)
        pin_work_kernel<<<1, 1, 0, b->stream>>>(*a->c, *a);
    else
        stage_kernel<<<blocks, kBlock, 0, b->stream>>>(k, *a->c, *a);
    cudaError_t e = cudaGetLastError();
    return e == cudaSuccess ? RBC_OK : fail(b, e, "kernel launch");
}

int32_t cu_sync(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    if (b->capturing) return in_capture(b, "sync");
    cudaError_t e = cudaStreamSynchronize(b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaStreamSynchronize");
}

/* A step's launches are captured into a graph rather than run (thread-local mode:
 * other threads' CUDA calls, other worlds', are not affected). */
int32_t cu_step_begin(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    if (!b->graphs) return RBC_OK;
    cudaError_t e = cudaStreamBeginCapture(b->stream, cudaStreamCaptureModeThreadLocal);
    if (e != cudaSuccess) return fail(b, e, "cudaStreamBeginCapture");
    b->capturing = 1;
    return RBC_OK;
}

/* The captured step as one graph launch: the last step's executable graph updated
 * with the new arguments when the shape is the same (the usual case: the same
 * substeps, iterations and pins), instantiated anew otherwise. */
int32_t cu_step_end(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    if (!b->capturing) return RBC_OK;
    b->capturing = 0;
    cudaGraph_t g = NULL;
    cudaError_t e = cudaStreamEndCapture(b->stream, &g);
    if (e != cudaSuccess) {
        if (g) cudaGraphDestroy(g);
        return fail(b, e, "cudaStreamEndCapture");
    }
    if (b->exec) {
        cudaGraphExecUpdateResultInfo info;
        if (cudaGraphExecUpdate(b->exec, g, &info) != cudaSuccess) {
            (void)cudaGetLastError(); /* a shape change is not an error: rebuild */
            cudaGraphExecDestroy(b->exec);
            b->exec = NULL;
        }
    }
    if (!b->exec) e = cudaGraphInstantiate(&b->exec, g, 0);
    cudaGraphDestroy(g);
    if (e != cudaSuccess) {
        b->exec = NULL;
        return fail(b, e, "cudaGraphInstantiate");
    }
    e = cudaGraphLaunch(b->exec, b->stream);
    return e == cudaSuccess ? RBC_OK : fail(b, e, "cudaGraphLaunch");
}

const char *cu_last_error(void *be) { return ((cuda_backend *)be)->err; }

const char *cu_describe(void *be) { return ((cuda_backend *)be)->desc; }

void cu_close(void *be) {
    cuda_backend *b = (cuda_backend *)be;
    if (b->exec) cudaGraphExecDestroy(b->exec);
    cudaStreamDestroy(b->stream);
    free(b);
}

const rbc_backend_ops cuda_ops = {
    "cuda",   cu_alloc,      cu_release,  cu_upload, cu_download, cu_launch,
    cu_sync,  cu_last_error, cu_describe, cu_close,  cu_step_begin, cu_step_end,
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
    const char *gr = getenv("RBC_CUDA_GRAPHS");
    b->graphs = !(gr && !strcmp(gr, "0"));
    snprintf(b->desc, sizeof b->desc, "%.255s (sm_%d%d, %.1f GiB)", prop.name, prop.major, prop.minor,
             (double)prop.totalGlobalMem / (1024.0 * 1024.0 * 1024.0));
    out->ops = &cuda_ops;
    out->be = b;
    return RBC_OK;
}
