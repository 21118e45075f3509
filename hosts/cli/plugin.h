/* plugin.h -- finding and loading librbcloth with dlopen, and checking its ABI. */
#ifndef RBC_CLI_PLUGIN_H
#define RBC_CLI_PLUGIN_H

#include <stddef.h>

#include "rbcloth.h"

typedef struct cli_plugin {
    void *handle;
    /// The function table of ABI major 1, checked: major, size, every entry set.
    const rbc_api_v1 *api;
    /// The file that was loaded (absolute when it could be resolved).
    char path[4096];
    /// How it was found: "RBC_PLUGIN", "next to the executable" or "library search path".
    const char *found_by;
} cli_plugin;

/// Load the plugin: $RBC_PLUGIN if set and not empty, else ../lib/librbcloth.so
/// relative to this executable (/proc/self/exe) if that file exists, else
/// "librbcloth.so" from the library search path. Resolves only rbc_get_api.
/// Returns 0, or -1 with a message in err.
int cli_plugin_open(cli_plugin *out, char *err, size_t err_size);

/// Unload the plugin. Safe on a zeroed or failed cli_plugin.
void cli_plugin_close(cli_plugin *plugin);

#endif
