/* mesh_internal.h - what the C++ loader shim hands to the C side of the mesh module.
 *
 * The shim (mesh_openmesh.cpp) lets OpenMesh parse a file and records the
 * polygons exactly as the reader produced them (a "soup"). Everything after
 * that - checking coordinates, normalising normals, triangulating polygons,
 * building the mesh_tri - is plain C here, so that the only C++ in radray stays
 * a thin layer over the library.
 *
 * Not a public header: only mesh.c and mesh_openmesh.cpp include it.
 */
#ifndef MESH_INTERNAL_H
#define MESH_INTERNAL_H

#include "mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Polygons as read from a file. Polygon f uses idx[start[f] .. start[f+1]-1]
 * (start has nfaces + 1 entries), every index already checked < nverts. */
typedef struct mesh__soup {
    const double *pos;     /* 3 * nverts */
    const double *normals; /* 3 * nverts, or NULL when the file has none */
    size_t nverts;
    const size_t *start;   /* nfaces + 1 */
    const uint32_t *idx;
    size_t nfaces;
} mesh__soup;

/* Validates the soup (finite coordinates, at least one polygon) and
 * triangulates it into a new mesh_tri. Errors are prefixed with path. Normals
 * that are zero-length anywhere are dropped as a whole (the renderer then
 * falls back to face normals); non-finite ones are an error. */
rr_status mesh__from_soup(const char *path, const mesh__soup *soup, mesh_tri **out, rr_error *err);

#ifdef __cplusplus
}
#endif

#endif
