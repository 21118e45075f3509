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

/* rbc_keep_if: kernels/rbc_hd.h (the device bodies use it too). */
#include "kernels/rbc_hd.h"
#endif
