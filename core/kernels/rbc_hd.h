/* rbc_hd.h -- marks per-element bodies shared by the CPU and CUDA backends
 * (pbrt-v4's PBRT_CPU_GPU idea): __host__ __device__ under nvcc, static inline in C.
 * Bodies use only the C/C++ common subset over plain arrays. */
#ifndef RBC_HD_H
#define RBC_HD_H
#include <stdint.h>
#include <string.h>

#if defined(__CUDACC__)
#define RBC_HD static __host__ __device__ __forceinline__
#define RBC_RESTRICT __restrict__ /* C++ has no restrict; nvcc spells it so */
#else
#define RBC_HD static inline
#define RBC_RESTRICT restrict
#endif

/* A body that must be inlined into each of its caller's target clones (simd.h), so
 * that each clone vectorizes it for its own target: left to its heuristics, GCC calls
 * one baseline copy from all three (ell.c's chunk ran at SSE2 width so). */
#if defined(__CUDACC__)
#define RBC_HD_INLINE RBC_HD
#elif defined(__GNUC__) || defined(__clang__)
#define RBC_HD_INLINE static inline __attribute__((always_inline))
#elif defined(_MSC_VER)
#define RBC_HD_INLINE static __forceinline
#else
#define RBC_HD_INLINE static inline
#endif

/* pin ? old : v without a branch (bitwise, so the compiler vectorizes the loop; on a
 * device the same select). */
RBC_HD float rbc_keep_if(uint8_t pin, float old, float v) {
    uint32_t bo, bv, mk = 0u - (uint32_t)(pin != 0);
    memcpy(&bo, &old, 4);
    memcpy(&bv, &v, 4);
    uint32_t r = (bo & mk) | (bv & ~mk);
    float out;
    memcpy(&out, &r, 4);
    return out;
}
#endif
