/* errors.h -- the calling thread's last error message, and logging to a world's hook. */
#ifndef RBC_PLUGIN_ERRORS_H
#define RBC_PLUGIN_ERRORS_H
#include <stddef.h>

#include "format_attr.h"

#include "rbcloth.h"

#define RBC_ERROR_CAP 1024

/* Set the thread's message (printf format) and return code. */
rbc_result rbc_set_error(rbc_result code, const char *fmt, ...)
    RBC_PRINTF(2, 3);
/* Set the thread's message as "rbc_mesh_import: <path>: <what>" and return code:
 * every refusal of a mesh import, in the plugin (import.c) and in the import helper
 * (importer/convert.c). The sweep groups refusals by <what>'s first clause, so each
 * clause starts with a fixed phrase and details follow a ':'. */
rbc_result rbc_import_error(const char *path, rbc_result code, const char *fmt, ...)
    RBC_PRINTF(3, 4);
/* The thread's message buffer, for code that formats into it directly. */
char *rbc_error_buffer(void);
/* The struct_size values a struct of the ABI accepts: its size in this library
 * (size[0]), then every older released one, newest first (the RBC_*_SIZE_V1_n
 * macros). One table per struct (defs.c), so that every check and every message
 * agree on them. */
typedef struct rbc_struct_sizes {
    const char *name; /* "rbc_world_def" */
    uint32_t count;
    uint32_t size[8];
} rbc_struct_sizes;
extern const rbc_struct_sizes rbc_sizes_world_def, rbc_sizes_cloth_def, rbc_sizes_collider_def,
    rbc_sizes_solver_def, rbc_sizes_cache_def, rbc_sizes_import_def, rbc_sizes_mesh_info,
    rbc_sizes_world_stats;
int rbc_size_known(const rbc_struct_sizes *s, uint32_t size);
/* "FN: WHERE->struct_size is N, which matches no released version of NAME (this
 * library accepts A, its own, and the older sizes B, C, ...)" into buf. */
void rbc_size_message(const rbc_struct_sizes *s, uint32_t size, const char *fn,
                      const char *where, char *buf, size_t cap);
/* That message as the thread's error; RBC_ERR_INVALID_ARGUMENT. */
rbc_result rbc_size_refused(const rbc_struct_sizes *s, uint32_t size, const char *fn,
                            const char *where);
/* Fill a host's def: check struct_size against the sizes s accepts and copy that
 * many bytes of `defaults` (shared by the *_def_init functions). */
rbc_result rbc_def_init_common(void *def, uint32_t struct_size, const void *defaults,
                               const rbc_struct_sizes *s, const char *fn);
#endif
