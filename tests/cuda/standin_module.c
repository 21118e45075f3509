/* standin_module.c -- a stand-in for the CUDA module with the CPU backend behind the
 * module's entry point, for machines without a GPU. Loaded by the plugin through
 * $RBC_CUDA_MODULE, it lets the plugin's whole device path (world creation with
 * RBC_BACKEND_CUDA, the refusals, the step through the seam, readback, stats, the
 * bench's --backend cuda) run on every machine. It proves the plugin's wiring, not
 * the GPU: the kernels' loops are the CPU backend's (core/cpu/backend_cpu.c). */
#include <stdio.h>

#include "backend.h"
#include "rbcloth.h"

__attribute__((visibility("default"))) int32_t
rbc_cuda_backend_open(uint32_t interface_version, rbc_backend_handle *out, char *why,
                      size_t whylen) {
    if (interface_version != RBC_BACKEND_INTERFACE) {
        snprintf(why, whylen, "the stand-in module is for backend interface %u, not %u",
                 (unsigned)RBC_BACKEND_INTERFACE, (unsigned)interface_version);
        return RBC_ERR_BACKEND_UNAVAILABLE;
    }
    return rbc_backend_cpu_open(out);
}
