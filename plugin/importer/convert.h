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
    /* The file's own vertices (info.file_vertex_count of them, in the file's order):
     * the mesh vertex each follows (UINT32_MAX: none), the placement whose
     * transform brought it there and its rest position in the file's coordinates. */
    uint32_t nf;
    uint32_t *file_map;  /* [nf] */
    uint32_t *file_inst; /* [nf] index into inst_inv, UINT32_MAX with no mesh vertex */
    float *file_rest;    /* [3nf] */
    /* Per placement, the inverse of "node transforms, then scale": mesh coordinates
     * back to the file's, rows 1..3 of a 4x4 affine matrix. */
    uint32_t ninst;
    double *inst_inv;    /* [12 ninst] */
    /* The file's faces, for rbc_mesh_write_file_obj: corners index assimp's vertices
     * of the placements taken (one per position, UV and normal), each with its file
     * vertex, mesh vertex, UV and normal (flags: 1 UV, 2 normal). */
    uint32_t ncv;
    uint32_t *cv_file;   /* [ncv] UINT32_MAX: none */
    uint32_t *cv_mesh;   /* [ncv] UINT32_MAX: none */
    float *cv_uv;        /* [2ncv] */
    float *cv_nrm;       /* [3ncv] file coordinates */
    uint8_t *cv_flags;   /* [ncv] */
    uint32_t nfc, nfcorner;
    uint32_t *fc_start;  /* [nfc + 1] into fc_corner */
    uint32_t *fc_corner; /* [fc_start[nfc]] corner vertices */
    uint32_t *fc_inst;   /* [nfc] placement (its "g" group) */
    char (*inst_name)[64]; /* [ninst] */
    rbc_mesh_info info;
} rbc_mesh;

/* Read `path` as `def` says (already checked by the plugin: check_def) into *out
 * (arrays malloc'd; free with rbc_import_mesh_free). On failure the message is in
 * rbc_error_buffer(), as "rbc_mesh_import: <path>: <what>", and nothing is kept. */
rbc_result rbc_import_convert(const char *path, const rbc_mesh_import_def *def, rbc_mesh *out);
/* What travels from the import helper to the plugin (importer/wire.h): the counts,
 * then every array in this order, its size from the counts. */
#define RBC_MESH_COUNTS 10
#define RBC_MESH_ARRAYS 19
typedef struct rbc_mesh_array {
    void **p;
    size_t bytes;
} rbc_mesh_array;

static inline void rbc_mesh_get_counts(const rbc_mesh *m, uint32_t c[RBC_MESH_COUNTS]) {
    const uint32_t v[RBC_MESH_COUNTS] = {m->n,    m->nq,    m->ns,  m->np,  m->nlt,
                                         m->nf,   m->ninst, m->ncv, m->nfc, m->nfcorner};
    memcpy(c, v, sizeof v);
}

static inline void rbc_mesh_set_counts(rbc_mesh *m, const uint32_t c[RBC_MESH_COUNTS]) {
    m->n = c[0], m->nq = c[1], m->ns = c[2], m->np = c[3], m->nlt = c[4];
    m->nf = c[5], m->ninst = c[6], m->ncv = c[7], m->nfc = c[8], m->nfcorner = c[9];
}

/* The arrays of m with their sizes for counts c (each count below 2^28, so no
 * size overflows). */
static inline void rbc_mesh_arrays(rbc_mesh *m, const uint32_t c[RBC_MESH_COUNTS],
                                   rbc_mesh_array a[RBC_MESH_ARRAYS]) {
    const size_t u = sizeof(uint32_t), f = sizeof(float);
    const rbc_mesh_array v[RBC_MESH_ARRAYS] = {
        {(void **)&m->pos, 3 * f * c[0]},          {(void **)&m->quads, 4 * u * c[1]},
        {(void **)&m->springs, 2 * u * c[2]},      {(void **)&m->pins, u * c[3]},
        {(void **)&m->ltris, 3 * u * c[4]},        {(void **)&m->file_map, u * c[5]},
        {(void **)&m->file_inst, u * c[5]},        {(void **)&m->file_rest, 3 * f * c[5]},
        {(void **)&m->inst_inv, 12 * sizeof(double) * c[6]},
        {(void **)&m->cv_file, u * c[7]},          {(void **)&m->cv_mesh, u * c[7]},
        {(void **)&m->cv_uv, 2 * f * c[7]},        {(void **)&m->cv_nrm, 3 * f * c[7]},
        {(void **)&m->cv_flags, c[7]},             {(void **)&m->fc_start, u * ((size_t)c[8] + 1)},
        {(void **)&m->fc_corner, u * c[9]},        {(void **)&m->fc_inst, u * c[8]},
        {(void **)&m->inst_name, 64 * (size_t)c[6]}, {NULL, 0}};
    memcpy(a, v, sizeof v);
}

/* Free the arrays (not m itself) and zero them. */
static inline void rbc_import_mesh_free(rbc_mesh *m) {
    free(m->pos);
    free(m->quads);
    free(m->springs);
    free(m->ltris);
    free(m->pins);
    free(m->file_map);
    free(m->file_inst);
    free(m->file_rest);
    free(m->inst_inv);
    free(m->cv_file);
    free(m->cv_mesh);
    free(m->cv_uv);
    free(m->cv_nrm);
    free(m->cv_flags);
    free(m->fc_start);
    free(m->fc_corner);
    free(m->fc_inst);
    free(m->inst_name);
    memset(m, 0, sizeof *m);
}
#endif
