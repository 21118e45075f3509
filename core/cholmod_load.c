/* cholmod_load.c -- dlopen CHOLMOD on first use (see cholmod_load.h). */
#define _GNU_SOURCE /* RTLD_DEFAULT */
#include "cholmod_load.h"
#include "cholmod_alloc.h"
#include "report.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../abi/rbcloth.h"

/* The pointer types of rbc_cholmod_api are the header's: a CHOLMOD header whose
 * prototypes differ fails to compile here. (_Generic does not evaluate its
 * operand: nothing is linked.) */
#define SAME_TYPE(field, fn) \
    _Static_assert(_Generic(&fn, __typeof__(((rbc_cholmod_api *)0)->field): 1, default: 0), \
                   #fn " is not declared as rbc_cholmod_api." #field " expects")
SAME_TYPE(start, cholmod_start);
SAME_TYPE(finish, cholmod_finish);
SAME_TYPE(allocate_sparse, cholmod_allocate_sparse);
SAME_TYPE(free_sparse, cholmod_free_sparse);
SAME_TYPE(analyze, cholmod_analyze);
SAME_TYPE(factorize, cholmod_factorize);
SAME_TYPE(free_factor, cholmod_free_factor);
SAME_TYPE(free_work, cholmod_free_work);

static pthread_once_t load_once = PTHREAD_ONCE_INIT;
static void *handle;
static rbc_cholmod_api api;
static int loaded;
static char why[512];

static void *sym(const char *name, const char *file) {
    dlerror();
    void *p = dlsym(handle, name);
    if (!p && !why[0]) {
        const char *e = dlerror();
        snprintf(why, sizeof why, "%s has no %s (%s)", file, name, e ? e : "NULL");
    }
    return p;
}

static void load(void) {
    const char *file = getenv("RBC_CHOLMOD_LIBRARY");
    if (!file || !file[0]) file = RBC_CHOLMOD_SONAME;
    /* RTLD_LOCAL: CHOLMOD's symbols stay out of the host's global scope. */
    handle = dlopen(file, RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
        const char *e = dlerror();
        snprintf(why, sizeof why, "%s could not be loaded: %s", file, e ? e : "dlopen failed");
        return;
    }
    /* The types direct.c uses are CHOLMOD 3's (cholmod_common, cholmod_factor):
     * another major would be read with the wrong layout. */
    int (*version)(int[3]) = (int (*)(int[3]))sym("cholmod_version", file);
    int v[3] = {0, 0, 0};
    if (version) version(v);
    if (version && v[0] != CHOLMOD_MAIN_VERSION)
        snprintf(why, sizeof why, "%s is CHOLMOD %d.%d.%d; this build needs CHOLMOD %d", file,
                 v[0], v[1], v[2], CHOLMOD_MAIN_VERSION);
    api.start = (int (*)(cholmod_common *))sym("cholmod_start", file);
    api.finish = (int (*)(cholmod_common *))sym("cholmod_finish", file);
    api.allocate_sparse =
        (cholmod_sparse * (*)(size_t, size_t, size_t, int, int, int, int, cholmod_common *))
            sym("cholmod_allocate_sparse", file);
    api.free_sparse = (int (*)(cholmod_sparse **, cholmod_common *))sym("cholmod_free_sparse", file);
    api.analyze = (cholmod_factor * (*)(cholmod_sparse *, cholmod_common *))sym("cholmod_analyze", file);
    api.factorize =
        (int (*)(cholmod_sparse *, cholmod_factor *, cholmod_common *))sym("cholmod_factorize", file);
    api.free_factor = (int (*)(cholmod_factor **, cholmod_common *))sym("cholmod_free_factor", file);
    api.free_work = (int (*)(cholmod_common *))sym("cholmod_free_work", file);
    /* A data symbol of libsuitesparseconfig, which libcholmod needs. The copy
     * CHOLMOD uses is the one its relocations were bound to: the global scope's
     * first (a host executable that uses SuiteSparse_config holds its own copy of
     * it, a copy relocation), else the one in the handle's dependencies. */
    api.config = (struct SuiteSparse_config_struct *)dlsym(RTLD_DEFAULT, "SuiteSparse_config");
    if (!api.config) api.config = (struct SuiteSparse_config_struct *)sym("SuiteSparse_config", file);
    if (why[0]) {
        dlclose(handle);
        handle = NULL;
        memset(&api, 0, sizeof api);
        return;
    }
    rbc_cholmod_alloc_install(api.config);
    loaded = 1;
}

const rbc_cholmod_api *rbc_cholmod_get(char *err, size_t errlen) {
    pthread_once(&load_once, load);
    if (loaded) return &api;
    rbc_fail(err, errlen, RBC_ERR_BACKEND_UNAVAILABLE,
             "RBC_SOLVER_DIRECT needs CHOLMOD 3 (%s, Debian's libcholmod3): %s",
             RBC_CHOLMOD_SONAME, why);
    return NULL;
}

/* When the plugin is unloaded (a host's dlclose; or at exit): SuiteSparse's
 * allocator first (cholmod_alloc.c's wrappers live in this library), then CHOLMOD,
 * unless a world's CHOLMOD block is still alive (a host that unloads before
 * destroying its worlds): CHOLMOD then stays mapped, as before this file existed. */
__attribute__((destructor)) static void unload(void) {
    if (!loaded) return;
    if (!rbc_cholmod_alloc_release(api.config)) return;
    dlclose(handle);
    handle = NULL;
    loaded = 0;
}
