/* file_vertices.h -- a mesh file's own vertex lists, in the file's own order.
 *
 * assimp's OBJ, FBX and Collada loaders emit one vertex per face corner, and
 * JoinIdenticalVertices merges them back in first-use order, so the vertex order of
 * an imported mesh is not the file's. DCC tools (Blender) create a mesh's vertices in
 * the file's order: FBX Geometry `Vertices` (control points), Collada
 * <mesh><vertices><input semantic="POSITION"> -> <source><float_array>. These
 * readers return those raw position lists so that each file vertex can be mapped to
 * the imported vertex at the same raw position (docs/design/file-vertex-order.md).
 *
 * Self-contained: no assimp. FBX binary (any version; zlib for compressed arrays)
 * and ASCII (FBX 7 `Vertices: *N { a: ... }`, FBX 6.1 `Vertices: x,y,z,...`);
 * Collada through libxml2 with network access and entity substitution off.
 * Never print, never crash, never read out of bounds, on any input. */
#ifndef RBC_IMPORTER_FILE_VERTICES_H
#define RBC_IMPORTER_FILE_VERTICES_H
#include <stddef.h>
#include <stdint.h>

typedef struct rbc_file_vertices {
    uint32_t count;       /* vertices of all the file's position lists, in file order */
    double *xyz;          /* [3 count] coordinates exactly as the file stores them: no node
                             transform, no unit, no axis conversion */
    uint32_t list_count;  /* position lists (FBX Geometry objects of type Mesh, Collada
                             <mesh>es), file order */
    uint32_t *list_start; /* [list_count + 1] first vertex of each list, then count */
    char **list_name;     /* [list_count] the Geometry's / <geometry>'s name (UTF-8,
                             malloc'd; "" if none) */
    double unit_metres;   /* metres per file unit as the file declares it (FBX
                             GlobalSettings UnitScaleFactor is centimetres per unit, so
                             /100; Collada <asset><unit meter="..."/>); 0 = the file
                             declares none */
    int up_axis;          /* the file's declared up axis: 0 x, 1 y, 2 z, -1 none (FBX
                             UpAxis, Collada <up_axis>) */
} rbc_file_vertices;

/* Frees the arrays of *v and zeroes it. NULL and a zeroed struct are fine. */
void rbc_file_vertices_free(rbc_file_vertices *v);

/* Return 1 read (out filled, arrays malloc'd), 0 not this format (out zeroed; nothing
 * to say), -1 this format but unreadable (out zeroed; a one-line reason in err, e.g.
 * "FBX: node Objects/Geometry 'Plane': Vertices array truncated at byte 1234").
 * err may be NULL when errcap is 0. */
int rbc_fbx_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap);
int rbc_dae_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap);

/* Shared by the two readers (file_vertices_fbx.c defines them). */
typedef struct rbc_fv_builder {
    double *xyz;
    size_t n, cap;          /* doubles */
    uint32_t *start;        /* list starts (vertex indices) */
    char **name;
    size_t lists, lists_cap;
} rbc_fv_builder;
int rbc_fv_begin_list(rbc_fv_builder *b, const char *name, size_t name_len);
int rbc_fv_reserve(rbc_fv_builder *b, size_t more_doubles);
void rbc_fv_builder_free(rbc_fv_builder *b);
/* Moves b into out (1), or fails on a vertex count over UINT32_MAX (0). */
int rbc_fv_finish(rbc_fv_builder *b, rbc_file_vertices *out);
/* Reads a whole file into a malloc'd buffer with a NUL after it; 0 and errno on failure. */
int rbc_fv_read_file(const char *path, unsigned char **data, size_t *size);
#endif
