#include "errors.h"

#include <stdarg.h>
#include <stdio.h>

/* MSVC's cl: __declspec(thread), which every version has, where _Thread_local in C
 * mode is recent (a DLL's __declspec(thread) works under LoadLibrary since Vista). */
#if defined(_MSC_VER) && !defined(__clang__)
static __declspec(thread) char g_error[RBC_ERROR_CAP];
#else
static _Thread_local char g_error[RBC_ERROR_CAP];
#endif

char *rbc_error_buffer(void) { return g_error; }

rbc_result rbc_set_error(rbc_result code, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(g_error, sizeof g_error, fmt, ap);
    va_end(ap);
    return code;
}

rbc_result rbc_import_error(const char *path, rbc_result code, const char *fmt, ...) {
    int k = snprintf(g_error, sizeof g_error, "rbc_mesh_import: %s: ", path);
    if (k < 0 || k >= (int)sizeof g_error) return code;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(g_error + k, sizeof g_error - (size_t)k, fmt, ap);
    va_end(ap);
    return code;
}

RBC_API const char *RBC_CALL rbc_last_error(void) { return g_error; }

RBC_API const char *RBC_CALL rbc_result_string(rbc_result result) {
    switch (result) {
    case RBC_OK: return "RBC_OK";
    case RBC_ERR_INVALID_ARGUMENT: return "RBC_ERR_INVALID_ARGUMENT";
    case RBC_ERR_OUT_OF_MEMORY: return "RBC_ERR_OUT_OF_MEMORY";
    case RBC_ERR_UNSUPPORTED: return "RBC_ERR_UNSUPPORTED";
    case RBC_ERR_BACKEND_UNAVAILABLE: return "RBC_ERR_BACKEND_UNAVAILABLE";
    case RBC_ERR_BAD_MESH: return "RBC_ERR_BAD_MESH";
    case RBC_ERR_IO: return "RBC_ERR_IO";
    case RBC_ERR_UNSTABLE: return "RBC_ERR_UNSTABLE";
    case RBC_ERR_STALE_HANDLE: return "RBC_ERR_STALE_HANDLE";
    case RBC_ERR_CALLBACK: return "RBC_ERR_CALLBACK";
    case RBC_ERR_CAPACITY: return "RBC_ERR_CAPACITY";
    case RBC_ERR_BUSY: return "RBC_ERR_BUSY";
    default: return "unknown result";
    }
}
