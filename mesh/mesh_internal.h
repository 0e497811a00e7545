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

/* ---- file pre-checks (mesh_formats.c, mesh_ply.c) ---- */

typedef enum mesh__format { MESH__OBJ, MESH__PLY, MESH__OFF, MESH__STL } mesh__format;

/* What a pre-check learned, for the shim to hand OpenMesh and to hold
 * OpenMesh's result against. Zero-initialise, then mesh__expect_free. */
typedef struct mesh__expect {
    long long nverts, nfaces; /* -1: the format does not say (OBJ faces, STL) */
    int binary;               /* binary STL: OpenMesh's stream reader must be told */
    /* The first and last vertex as the check read them (binary PLY, OFF), to
     * catch OpenMesh reading from a shifted offset or with stale flags. */
    int probe;
    float first[3], last[3];
    /* OFF only: the file rewritten the way OpenMesh's reader needs it;
     * NULL when OpenMesh reads the file's own bytes. */
    char *text;
    size_t text_len;
} mesh__expect;

/* Validates buf (the whole file) as format fmt, filling *ex. Errors are
 * prefixed with path. */
rr_status mesh__check(const char *path, mesh__format fmt, const char *buf, size_t n, mesh__expect *ex, rr_error *err);
void mesh__expect_free(mesh__expect *ex);

/* rr_error_set with "path: " in front, as every mesh_load message reads. */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
rr_status mesh__fail(rr_error *err, rr_status code, const char *path, const char *fmt, ...);

/* Text scanning shared by the checks: slices of the file (never
 * NUL-terminated), whitespace tokens, numbers parsed as iostreams would. */
typedef struct mesh__sv {
    const char *p;
    size_t n;
} mesh__sv;

typedef struct mesh__lines {
    const char *p, *end;
    size_t no; /* 1-based number of the line last returned */
} mesh__lines;

int mesh__eq(mesh__sv a, const char *s);
int mesh__space(char c);
mesh__sv mesh__trim(mesh__sv s);
int mesh__token(mesh__sv *s, mesh__sv *t);     /* pops the next token of *s */
int mesh__line(mesh__lines *L, mesh__sv *line); /* next line, without its '\n' */
int mesh__number(mesh__sv t, double *v);        /* decimal, nan and inf; no hex */
int mesh__integer(mesh__sv t, long long *v);
const char *mesh__bad_coord(double v);          /* why v cannot be a coordinate, or NULL */
const char *mesh__q(mesh__sv t, char out[48]);  /* printable quote for a message */
int mesh__is_text(const char *buf, size_t n);

rr_status mesh__check_ply(const char *path, const char *buf, size_t n, mesh__expect *ex, rr_error *err);

#ifdef __cplusplus
}
#endif

#endif
