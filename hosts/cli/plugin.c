/* plugin.c -- finding and loading librbcloth with dlopen, and checking its ABI. */
#define _GNU_SOURCE /* dladdr: report which file was actually loaded */
#include "plugin.h"

#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PLUGIN_FILE "librbcloth.so"

/* "<dir of /proc/self/exe>/../lib/librbcloth.so" into out, or 0 if unknown. */
static int path_next_to_executable(char *out, size_t size) {
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return 0;
    exe[n] = '\0';
    char *slash = strrchr(exe, '/');
    if (!slash)
        return 0;
    *slash = '\0';
    int written = snprintf(out, size, "%s/../lib/%s", exe, PLUGIN_FILE);
    return written > 0 && (size_t)written < size;
}

/* Every entry of the table this host calls must be present. */
static const char *missing_entry(const rbc_api_v1 *api) {
#define RBC_REQUIRE_ENTRY(field) \
    if (!api->field)             \
        return #field;
    RBC_REQUIRE_ENTRY(abi_version_fn)
    RBC_REQUIRE_ENTRY(version_string)
    RBC_REQUIRE_ENTRY(result_string)
    RBC_REQUIRE_ENTRY(last_error)
    RBC_REQUIRE_ENTRY(world_def_init)
    RBC_REQUIRE_ENTRY(cloth_def_init)
    RBC_REQUIRE_ENTRY(collider_def_init)
    RBC_REQUIRE_ENTRY(cache_def_init)
    RBC_REQUIRE_ENTRY(world_create)
    RBC_REQUIRE_ENTRY(world_destroy)
    RBC_REQUIRE_ENTRY(world_step)
    RBC_REQUIRE_ENTRY(world_set_iterations)
    RBC_REQUIRE_ENTRY(world_set_gravity)
    RBC_REQUIRE_ENTRY(world_get_stats)
    RBC_REQUIRE_ENTRY(world_set_collision_callback)
    RBC_REQUIRE_ENTRY(cloth_create)
    RBC_REQUIRE_ENTRY(cloth_destroy)
    RBC_REQUIRE_ENTRY(cloth_get_vertex_count)
    RBC_REQUIRE_ENTRY(cloth_get_topology)
    RBC_REQUIRE_ENTRY(cloth_read_positions)
    RBC_REQUIRE_ENTRY(cloth_set_pin)
    RBC_REQUIRE_ENTRY(collider_create)
    RBC_REQUIRE_ENTRY(collider_set_transform)
    RBC_REQUIRE_ENTRY(collider_destroy)
    RBC_REQUIRE_ENTRY(write_obj)
    RBC_REQUIRE_ENTRY(cache_create)
    RBC_REQUIRE_ENTRY(cache_write_frame)
    RBC_REQUIRE_ENTRY(cache_finish)
    RBC_REQUIRE_ENTRY(cache_destroy)
#undef RBC_REQUIRE_ENTRY
    return NULL;
}

int cli_plugin_open(cli_plugin *out, char *err, size_t err_size) {
    memset(out, 0, sizeof *out);
    char candidate[PATH_MAX];
    const char *env = getenv("RBC_PLUGIN");
    if (env && env[0]) {
        if (strlen(env) >= sizeof candidate) {
            snprintf(err, err_size, "RBC_PLUGIN is longer than %zu characters", sizeof candidate - 1);
            return -1;
        }
        memcpy(candidate, env, strlen(env) + 1);
        out->found_by = "RBC_PLUGIN";
    } else if (path_next_to_executable(candidate, sizeof candidate) &&
               access(candidate, F_OK) == 0) {
        out->found_by = "next to the executable";
    } else {
        snprintf(candidate, sizeof candidate, "%s", PLUGIN_FILE);
        out->found_by = "library search path";
    }

    dlerror();
    void *handle = dlopen(candidate, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char *why = dlerror();
        snprintf(err, err_size, "cannot load the plugin %s (%s): %s%s", candidate, out->found_by,
                 why ? why : "unknown dlopen error",
                 env && env[0] ? "" : "; set RBC_PLUGIN to the path of librbcloth.so");
        return -1;
    }

    /* POSIX guarantees that a function address survives the trip through void *. */
    dlerror();
    void *symbol = dlsym(handle, "rbc_get_api");
    const char *why = dlerror();
    if (!symbol || why) {
        snprintf(err, err_size, "%s is not an rbcloth plugin: no rbc_get_api (%s)", candidate,
                 why ? why : "symbol is NULL");
        dlclose(handle);
        return -1;
    }

    /* Report the file the loader picked (it may differ from a bare name). */
    Dl_info info;
    char resolved[PATH_MAX];
    const char *loaded = candidate;
    if (dladdr(symbol, &info) && info.dli_fname && info.dli_fname[0])
        loaded = info.dli_fname;
    if (realpath(loaded, resolved))
        loaded = resolved;
    snprintf(out->path, sizeof out->path, "%s", loaded);

    rbc_get_api_fn get_api = (rbc_get_api_fn)symbol;
    const rbc_api_v1 *api = get_api(RBC_ABI_VERSION_MAJOR);
    const char *missing = NULL;
    if (!api) {
        snprintf(err, err_size, "%s does not implement ABI major %d (rbc_get_api returned NULL)",
                 out->path, RBC_ABI_VERSION_MAJOR);
    } else if (api->abi_version >> 16 != RBC_ABI_VERSION_MAJOR) {
        snprintf(err, err_size, "%s reports ABI %u.%u for major %d: incompatible", out->path,
                 api->abi_version >> 16, api->abi_version & 0xFFFFu, RBC_ABI_VERSION_MAJOR);
        api = NULL;
    } else if (api->struct_size < sizeof(rbc_api_v1)) {
        /* Entries are only appended: a smaller table lacks functions this host calls. */
        snprintf(err, err_size,
                 "%s has a function table of %u bytes, older than this host's (%zu bytes, ABI "
                 "%d.%d)",
                 out->path, api->struct_size, sizeof(rbc_api_v1), RBC_ABI_VERSION_MAJOR,
                 RBC_ABI_VERSION_MINOR);
        api = NULL;
    } else if ((missing = missing_entry(api)) != NULL) {
        snprintf(err, err_size, "%s has no %s in its function table", out->path, missing);
        api = NULL;
    }
    if (!api) {
        dlclose(handle);
        return -1;
    }
    out->handle = handle;
    out->api = api;
    return 0;
}

void cli_plugin_close(cli_plugin *plugin) {
    if (plugin && plugin->handle)
        dlclose(plugin->handle);
    if (plugin) {
        plugin->handle = NULL;
        plugin->api = NULL;
    }
}
