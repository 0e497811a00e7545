/* mesh.h - triangle meshes loaded through OpenMesh, and their topology report.
 *
 * The loader is a thin C++ shim over OpenMesh (mesh_openmesh.cpp: the only C++
 * in radray). It reads OBJ, PLY (ASCII and binary), OFF and STL (ASCII and
 * binary), triangulates polygons, and hands back a plain C triangle mesh. No
 * C++ exception crosses into C: every failure (missing file, empty, truncated,
 * garbage, non-finite coordinates, out of memory) comes back as an rr_status
 * with a one-line message that starts with the file name.
 *
 * Ownership: mesh_load allocates *out; mesh_destroy frees it (NULL is a no-op).
 * On failure *out is left untouched.
 */
#ifndef MESH_H
#define MESH_H

#include <stddef.h>
#include <stdint.h>

#include "rr_core.h"

typedef struct mesh_tri {
    size_t nverts;
    double *pos;     /* 3 * nverts */
    double *normals; /* 3 * nverts, unit length, or NULL when the file has none */
    size_t ntris;
    uint32_t *tris;  /* 3 * ntris vertex indices, counter-clockwise = front */
} mesh_tri;

/* Topology of a triangle mesh. Vertices are welded by exact position first
 * (STL has no shared vertices, and OBJ/PLY files often duplicate seams), so the
 * report speaks of the surface, not of the file's indexing. */
typedef struct mesh_report {
    size_t boundary_edges;     /* edges used by exactly one triangle */
    size_t nonmanifold_edges;  /* edges used by three or more triangles */
    size_t misoriented_edges;  /* edges used twice in the same direction */
    size_t degenerate_tris;    /* zero area (repeated or collinear vertices) */
    int watertight;            /* no boundary and no non-manifold edges */
    int consistently_oriented; /* no misoriented edges */
} mesh_report;

/* Loads the file at path; the format is chosen by extension (case-insensitive:
 * .obj .ply .off .stl). Polygons are triangulated. Degenerate triangles are
 * kept (mesh_report counts them; the scene decides what to do).
 *
 * Details worth knowing (OpenMesh 9.0 underneath, see mesh_openmesh.cpp):
 *  - Polygons are ear-clipped in their best-fit plane, keeping their winding
 *    (a fan for self-intersecting ones, and for what is left of a polygon once
 *    2^26 point-in-ear tests have been spent on it, which bounds the work for
 *    any size; ordinary polygons of thousands of corners are clipped).
 *  - Vertex order and numbering follow the file, counting from 0 (error
 *    messages too), except STL, whose reader merges equal positions and drops
 *    triangles that collapse. OBJ's reader drops repeated corners of a face.
 *  - Coordinates pass through single precision (OpenMesh reads into floats);
 *    values beyond FLT_MAX, nan and inf are errors naming the vertex.
 *  - normals: OBJ vn and PLY nx/ny/nz, when every vertex a face uses has one;
 *    normalised; NULL as a whole if any is zero-length. OFF normals are not
 *    returned.
 *  - Refused as unsupported rather than misread: binary OFF; PLY list
 *    properties other than the face's vertex_indices (first in the face),
 *    integer-typed coordinates, and binary PLY with a comment or blank line
 *    right before end_header.
 *  - Calls are serialised by a lock (OpenMesh's readers keep state), and
 *    OpenMesh's own log output and std::cerr are silenced during a read. */
rr_status mesh_load(const char *path, mesh_tri **out, rr_error *err);

/* Builds a mesh from arrays (copies them). normals may be NULL. */
rr_status mesh_from_arrays(const double *pos, size_t nverts, const uint32_t *tris, size_t ntris,
                           const double *normals, mesh_tri **out, rr_error *err);

void mesh_destroy(mesh_tri *m);

/* Fills *rep for m (pure C, no allocation failure is silent: returns
 * RR_ERR_NOMEM). */
rr_status mesh_analyze(const mesh_tri *m, mesh_report *rep, rr_error *err);

/* Re-indexes m's vertices so that corners at exactly the same position
 * share one vertex when their faces meet at less than crease_deg (normals
 * within that angle of the first face to claim the vertex; faces in order):
 * the smooth parts of a surface share vertices, creases do not. For readers
 * that hand back every corner as its own vertex (Assimp's OBJ reader): the
 * radiosity display averages over shared vertices only. Vertex normals
 * follow the first corner of each new vertex. Triangles keep their order
 * and winding. */
rr_status mesh_weld(mesh_tri *m, double crease_deg, rr_error *err);

/* Area of triangle i (half the cross product length). */
double mesh_tri_area(const mesh_tri *m, size_t i);

#endif
