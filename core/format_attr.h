/* format_attr.h -- RBC_PRINTF(f, a): GCC's check of a printf-like function's format
 * (argument f) against its arguments (from a). On mingw-w64 plain `printf` names the
 * MSVC runtime's printf, which has no %zu; the library's messages are formatted by
 * mingw's own C99 printf (__USE_MINGW_ANSI_STDIO, which _POSIX_C_SOURCE turns on),
 * which GCC knows as gnu_printf. Other compilers (MSVC) get no check. */
#ifndef RBC_CORE_FORMAT_ATTR_H
#define RBC_CORE_FORMAT_ATTR_H
#if defined(__MINGW32__)
#include <stdio.h>
#if !__USE_MINGW_ANSI_STDIO
#error "mingw-w64 without __USE_MINGW_ANSI_STDIO: the messages' %zu would be garbled"
#endif
#define RBC_PRINTF(f, a) __attribute__((format(gnu_printf, f, a)))
#elif defined(__GNUC__)
#define RBC_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define RBC_PRINTF(f, a)
#endif
#endif
