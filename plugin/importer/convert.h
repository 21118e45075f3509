/* convert.h -- a mesh file read with assimp and turned into a cloth mesh (positions,
 * quads, springs, pins, leftover triangles and the report). This is the part of
 * rbc_mesh_import that runs in the import helper (rbcloth-import), never in the
 * host's process: assimp can crash, abort, hang or allocate without bound on a
 * crafted file (docs/design/import.md, "Isolation"). */
#ifndef RBC_IMPORTER_CONVERT_H
#define RBC_IMPORTER_CONVERT_H
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rbcloth.h"

/* Vertices or faces beyond this are refused (indices stay far from UINT32_MAX even
 * after n-gon fans and 2x-4x edge arrays). The plugin refuses an answer beyond it. */
#define RBC_IMPORT_MAX_ELEMENTS (1u << 28)

typedef struct rbc_mesh {
    uint32_t id;       /* the registry's handle (set by the plugin) */
    uint32_t n, nq, ns, np;
    float *pos;        /* [3n] */
    uint32_t *quads;   /* [4nq] */
    uint32_t *springs; /* [2ns] */
    uint32_t *pins;    /* [np] ascending */
    uint32_t nlt;      /* triangles left unpaired */
    uint32_t *ltris;   /* [3nlt] (rbc_mesh_get_triangles) */
    rbc_mesh_info info;
} rbc_mesh;

/* Read `path` as `def` says (already checked by the plugin: check_def) into *out
 * (arrays malloc'd; free with rbc_import_mesh_free). On failure the message is in
 * rbc_error_buffer(), as "rbc_mesh_import: <path>: <what>", and nothing is kept. */
rbc_result rbc_import_convert(const char *path, const rbc_mesh_import_def *def, rbc_mesh *out);
/* Free the arrays (not m itself) and zero them. */
static inline void rbc_import_mesh_free(rbc_mesh *m) {
    free(m->pos);
    free(m->quads);
    free(m->springs);
    free(m->ltris);
    free(m->pins);
    memset(m, 0, sizeof *m);
}
#endif
