/* obj_vertices.h -- an OBJ file's "v" list in file order, with its element indices
 * checked (obj_vertices.c). */
#ifndef RBC_IMPORTER_OBJ_VERTICES_H
#define RBC_IMPORTER_OBJ_VERTICES_H
#include "file_vertices.h"

/* 1: the path ends in `ext` (lower case, with its dot), in any case: how assimp
 * picks OBJ, OFF and glTF. */
int rbc_path_has_ext(const char *path, const char *ext);
/* 1 read, 0 not an OBJ path, -1 unreadable (err), -2 an index of a face, line or
 * point element is out of range or malformed (err names the line and element). */
int rbc_obj_file_vertices(const char *path, rbc_file_vertices *out, char *err, size_t errcap);
#endif
