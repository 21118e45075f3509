/* simd.h -- run-time dispatch for the vectorized loops: GCC builds a function once
 * per listed target and picks the clone the CPU supports when the library is loaded
 * (an ifunc), so one librbcloth.so uses AVX2 (or AVX-512) where present and SSE2
 * elsewhere. Results may differ between clones in the last bits (the lane split of
 * reassociated sums), never between thread counts. Only on Linux: a clone is picked
 * by an ifunc, which PE (Windows DLLs) and other loaders lack, so there the loops
 * are built once, for the baseline target. */
#ifndef RBC_CORE_SIMD_H
#define RBC_CORE_SIMD_H
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define RBC_VECTOR_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define RBC_VECTOR_CLONES
#endif

#include <stdint.h>
#include <string.h>

/* pin ? old : v without a branch (bitwise, so the compiler vectorizes the loop). */
static inline float rbc_keep_if(uint8_t pin, float old, float v) {
    uint32_t bo, bv, mk = 0u - (uint32_t)(pin != 0);
    memcpy(&bo, &old, 4);
    memcpy(&bv, &v, 4);
    uint32_t r = (bo & mk) | (bv & ~mk);
    float out;
    memcpy(&out, &r, 4);
    return out;
}
#endif
