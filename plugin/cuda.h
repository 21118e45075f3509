/* cuda.h -- the CUDA backend module, loaded on first use (cuda.c). */
#ifndef RBC_PLUGIN_CUDA_H
#define RBC_PLUGIN_CUDA_H
#include <stddef.h>
#include <stdint.h>

#include "backend.h"

/* A CUDA backend for one world: RBC_OK and *out filled, or
 * RBC_ERR_BACKEND_UNAVAILABLE with why (the module is missing, no driver, no
 * device) and *out untouched. The module is loaded once, from the plugin's own
 * folder ($RBC_CUDA_MODULE names another file). */
int32_t rbc_plugin_cuda_open(rbc_backend_handle *out, char *why, size_t whylen);
#endif
