/* report.h -- small helpers every core module shares: formatting an error message
 * into the caller's buffer, and the static split of a range among threads. */
#ifndef RBC_CORE_REPORT_H
#define RBC_CORE_REPORT_H
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "format_attr.h"

/* Write the message into err (if any) and return code. */
static inline int32_t rbc_fail(char *err, size_t errlen, int32_t code, const char *fmt, ...)
    RBC_PRINTF(4, 5);
static inline int32_t rbc_fail(char *err, size_t errlen, int32_t code, const char *fmt, ...) {
    if (err && errlen) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err, errlen, fmt, ap);
        va_end(ap);
    }
    return code;
}

/* [begin, end) of `count` items for thread tid of n: contiguous, static, so the same
 * thread owns the same particles in every phase (and results do not depend on n). */
static inline void rbc_split(uint32_t count, uint32_t tid, uint32_t n, uint32_t *begin,
                             uint32_t *end) {
    *begin = (uint32_t)((uint64_t)count * tid / n);
    *end = (uint32_t)((uint64_t)count * (tid + 1) / n);
}
#endif
