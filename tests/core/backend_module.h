/* backend_module.h -- the backend tests' way to a backend module (the CUDA module or
 * the stand-in): dlopen it, find its entry point, and probe it once.
 *
 * Returns -1 when the module opened (its entry point in *out), else the exit status
 * the test should end with: 77 (CTest's skip) when the backend is unavailable here,
 * 1 when the module is broken or RBC_REQUIRE_CUDA=1 forbids the skip. On a machine
 * that has a GPU a skip would hide a driver too old for the module's runtime:
 * tests/cuda/device_check.sh sets RBC_REQUIRE_CUDA=1. */
#ifndef RBC_TEST_BACKEND_MODULE_H
#define RBC_TEST_BACKEND_MODULE_H
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backend.h"
#include "rbcloth.h"

static inline int backend_module_open(const char *path, rbc_backend_open_fn **out) {
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        fprintf(stderr, "FAIL: the backend module %s does not load: %s\n", path, dlerror());
        return 1;
    }
    rbc_backend_open_fn *fn = (rbc_backend_open_fn *)dlsym(h, RBC_BACKEND_OPEN_SYMBOL);
    if (!fn) {
        fprintf(stderr, "FAIL: %s has no %s\n", path, RBC_BACKEND_OPEN_SYMBOL);
        return 1;
    }
    rbc_backend_handle probe;
    char why[512];
    int32_t rc = fn(RBC_BACKEND_INTERFACE, &probe, why, sizeof why);
    if (rc == RBC_ERR_BACKEND_UNAVAILABLE) {
        const char *req = getenv("RBC_REQUIRE_CUDA");
        if (req && !strcmp(req, "1")) {
            fprintf(stderr, "FAIL: RBC_REQUIRE_CUDA=1 and the CUDA backend is unavailable: %s\n",
                    why);
            return 1;
        }
        printf("SKIP: the CUDA backend is unavailable here (%s); parity not run\n", why);
        return 77;
    }
    if (rc != RBC_OK) {
        fprintf(stderr, "FAIL: %s does not open (%d): %s\n", path, (int)rc, why);
        return 1;
    }
    fprintf(stderr, "  backend: %s\n", probe.ops->describe(probe.be));
    probe.ops->close(probe.be);
    *out = fn;
    return -1;
}
#endif
