/* rbc_hd.h -- marks per-element bodies shared by the CPU and CUDA backends
 * (pbrt-v4's PBRT_CPU_GPU idea): __host__ __device__ under nvcc, static inline in C.
 * Bodies use only the C/C++ common subset over plain arrays. */
#ifndef RBC_HD_H
#define RBC_HD_H
#if defined(__CUDACC__)
#define RBC_HD static __host__ __device__ __forceinline__
#else
#define RBC_HD static inline
#endif
#endif
