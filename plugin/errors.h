/* errors.h -- the calling thread's last error message, and logging to a world's hook. */
#ifndef RBC_PLUGIN_ERRORS_H
#define RBC_PLUGIN_ERRORS_H
#include <stddef.h>

#include "rbcloth.h"

#define RBC_ERROR_CAP 1024

/* Set the thread's message (printf format) and return code. */
rbc_result rbc_set_error(rbc_result code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Set the thread's message as "rbc_mesh_import: <path>: <what>" and return code:
 * every refusal of a mesh import, in the plugin (import.c) and in the import helper
 * (importer/convert.c). The sweep groups refusals by <what>'s first clause, so each
 * clause starts with a fixed phrase and details follow a ':'. */
rbc_result rbc_import_error(const char *path, rbc_result code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* The thread's message buffer, for code that formats into it directly. */
char *rbc_error_buffer(void);
/* Fill a host's def: check struct_size against the released size and copy that
 * many bytes of `defaults` (shared by the *_def_init functions). */
rbc_result rbc_def_init_common(void *def, uint32_t struct_size, const void *defaults,
                               size_t released_size, size_t old_size, const char *fn,
                               const char *what);
#endif
