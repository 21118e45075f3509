/* cholmod_load.h -- CHOLMOD, loaded when the first direct-solver cloth needs it.
 *
 * The plugin an engine loads depends on libc, libm and pthreads only (issue 20):
 * CHOLMOD and its closure (SuiteSparse's config, AMD, COLAMD, CAMD, CCOLAMD,
 * LAPACK, BLAS, libgomp, libgfortran: 13 libraries on bookworm) are mapped only
 * by a host that asks for RBC_SOLVER_DIRECT. The first call dlopens
 * libcholmod.so.3 (the SONAME of SuiteSparse 5's CHOLMOD 3, whose types
 * suitesparse/cholmod.h describes; $RBC_CHOLMOD_LIBRARY names another file of
 * that ABI), checks that it reports CHOLMOD 3, and resolves the eight functions
 * direct.c calls and SuiteSparse_config (cholmod_alloc.c's allocator hooks). Once
 * per process (pthread_once); the result, loaded or not, is kept. The library
 * is closed when the plugin is unloaded, after cholmod_alloc.c has put
 * SuiteSparse's allocator back (see rbc_cholmod_alloc_release).
 *
 * Built only with RBC_WITH_CHOLMOD (CMake option, default ON on Linux).
 */
#ifndef RBC_CORE_CHOLMOD_LOAD_H
#define RBC_CORE_CHOLMOD_LOAD_H
#include <stddef.h>
#include <suitesparse/cholmod.h>

/* The file dlopened when $RBC_CHOLMOD_LIBRARY is unset or empty. */
#define RBC_CHOLMOD_SONAME "libcholmod.so.3"

typedef struct rbc_cholmod_api {
    int (*start)(cholmod_common *);
    int (*finish)(cholmod_common *);
    cholmod_sparse *(*allocate_sparse)(size_t, size_t, size_t, int, int, int, int,
                                       cholmod_common *);
    int (*free_sparse)(cholmod_sparse **, cholmod_common *);
    cholmod_factor *(*analyze)(cholmod_sparse *, cholmod_common *);
    int (*factorize)(cholmod_sparse *, cholmod_factor *, cholmod_common *);
    int (*free_factor)(cholmod_factor **, cholmod_common *);
    int (*free_work)(cholmod_common *);
    struct SuiteSparse_config_struct *config; /* the process's SuiteSparse_config */
} rbc_cholmod_api;

/* CHOLMOD's functions, loading it on the first call; NULL if it cannot be loaded,
 * with the reason in err (which file, dlerror's words, or the version it reports).
 * Thread-safe. */
const rbc_cholmod_api *rbc_cholmod_get(char *err, size_t errlen);
#endif
