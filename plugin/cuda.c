/* cuda.c -- load the CUDA backend module (core/cuda/, librbcloth_cuda.so) beside the
 * plugin on first use. The plugin itself links no CUDA library, so it loads on any
 * machine; the module links the CUDA runtime statically and needs only the driver.
 * Windows builds have no module (core/cuda/CMakeLists.txt). */
#define _GNU_SOURCE /* dladdr */
#include "cuda.h"

#include <stdio.h>
#include <string.h>

#include "rbcloth.h"

#if defined(_WIN32)
int32_t rbc_plugin_cuda_open(rbc_backend_handle *out, char *why, size_t whylen) {
    (void)out;
    snprintf(why, whylen, "Windows builds of librbcloth have no CUDA backend yet");
    return RBC_ERR_BACKEND_UNAVAILABLE;
}
#else
#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdlib.h>

#define MODULE_NAME "librbcloth_cuda.so"

static pthread_once_t load_once = PTHREAD_ONCE_INIT;
static rbc_backend_open_fn *open_fn;
static char load_why[PATH_MAX + 512];

static void load(void) {
    char path[PATH_MAX];
    const char *env = getenv("RBC_CUDA_MODULE");
    if (env && *env) {
        snprintf(path, sizeof path, "%s", env);
    } else {
        Dl_info dl;
        char lib[PATH_MAX];
        if (!dladdr((void *)&rbc_plugin_cuda_open, &dl) || !dl.dli_fname ||
            !realpath(dl.dli_fname, lib)) {
            snprintf(load_why, sizeof load_why,
                     "the library's own folder is unknown; set $RBC_CUDA_MODULE to %s",
                     MODULE_NAME);
            return;
        }
        char *slash = strrchr(lib, '/');
        if (slash) *slash = '\0';
        snprintf(path, sizeof path, "%.*s/%s", (int)(sizeof path - sizeof MODULE_NAME - 2), lib,
                 MODULE_NAME);
    }
    /* RTLD_LOCAL: the CUDA runtime's symbols stay out of the host's scope. */
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *e = dlerror();
        snprintf(load_why, sizeof load_why,
                 "the CUDA module could not be loaded (%s): this build may have been made "
                 "without nvcc",
                 e ? e : path);
        return;
    }
    open_fn = (rbc_backend_open_fn *)dlsym(h, RBC_BACKEND_OPEN_SYMBOL);
    if (!open_fn) {
        snprintf(load_why, sizeof load_why, "%s has no %s", path, RBC_BACKEND_OPEN_SYMBOL);
        dlclose(h);
    }
    /* Kept loaded for the process's life: worlds hold its function tables. */
}

int32_t rbc_plugin_cuda_open(rbc_backend_handle *out, char *why, size_t whylen) {
    pthread_once(&load_once, load);
    if (!open_fn) {
        snprintf(why, whylen, "%s", load_why);
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    return open_fn(RBC_BACKEND_INTERFACE, out, why, whylen);
}
#endif
