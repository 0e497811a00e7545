/* mesh_ply.c - strict pre-check of PLY files (ASCII and binary) before
 * OpenMesh reads them; see mesh_formats.c for why.
 *
 * The header is parsed the way OpenMesh's reader will parse it, and the body
 * is walked value by value (binary bytes or ASCII tokens) up to the end of the
 * face element, where OpenMesh stops: counts, vertex coordinates and face
 * indices are all checked, so truncation and garbage are caught here.
 */
#include <float.h>
#include <math.h>
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

typedef enum mesh__ply_type { PLY_BAD, PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64 } mesh__ply_type;

static mesh__ply_type mesh__ply_type_of(mesh__sv s)
{
    static const struct {
        const char *name;
        mesh__ply_type type;
    } names[] = {{"char", PLY_I8},    {"int8", PLY_I8},     {"uchar", PLY_U8},   {"uint8", PLY_U8},
                 {"short", PLY_I16},  {"int16", PLY_I16},   {"ushort", PLY_U16}, {"uint16", PLY_U16},
                 {"int", PLY_I32},    {"int32", PLY_I32},   {"uint", PLY_U32},   {"uint32", PLY_U32},
                 {"float", PLY_F32},  {"float32", PLY_F32}, {"double", PLY_F64}, {"float64", PLY_F64}};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (mesh__eq(s, names[i].name))
            return names[i].type;
    return PLY_BAD;
}

static size_t mesh__ply_size(mesh__ply_type t)
{
    static const size_t sizes[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
    return sizes[t];
}

/* Decodes one binary scalar stored with the given byte order. */
static double mesh__ply_get(const unsigned char *p, mesh__ply_type t, int big)
{
    const uint16_t one = 1;
    int swap = big == (*(const unsigned char *)&one == 1);
    unsigned char b[8];
    size_t n = mesh__ply_size(t);
    for (size_t i = 0; i < n; i++)
        b[i] = swap ? p[n - 1 - i] : p[i];
    int8_t i8; uint8_t u8; int16_t i16; uint16_t u16; int32_t i32; uint32_t u32; float f; double d;
    switch (t) {
    case PLY_I8: memcpy(&i8, b, 1); return i8;
    case PLY_U8: memcpy(&u8, b, 1); return u8;
    case PLY_I16: memcpy(&i16, b, 2); return i16;
    case PLY_U16: memcpy(&u16, b, 2); return u16;
    case PLY_I32: memcpy(&i32, b, 4); return i32;
    case PLY_U32: memcpy(&u32, b, 4); return u32;
    case PLY_F32: memcpy(&f, b, 4); return f;
    case PLY_F64: memcpy(&d, b, 8); return d;
    case PLY_BAD: break;
    }
    return 0.0;
}

typedef struct mesh__ply_prop {
    mesh__sv name;
    mesh__ply_type type;
    mesh__ply_type count_type; /* PLY_BAD for a scalar */
    int coord;                 /* 0..2 for vertex x, y, z, else -1 */
} mesh__ply_prop;

typedef struct mesh__ply_elem {
    mesh__sv name;
    unsigned long long count;
    size_t first, nprops; /* its properties in the header's prop array */
} mesh__ply_elem;

typedef struct mesh__ply_header {
    int format; /* 0 ascii, 1 little endian, 2 big endian */
    mesh__ply_elem *elems;
    size_t nelems;
    mesh__ply_prop *props;
    size_t nprops;
    const char *body;
} mesh__ply_header;

/* Walks the body value by value. */
typedef struct mesh__ply_walk {
    const char *path;
    int ascii, big;
    const unsigned char *p, *end; /* binary */
    mesh__sv text;                /* ascii */
    char elem[48];
    unsigned long long rec, count;
    rr_error *err;
} mesh__ply_walk;

static rr_status mesh__ply_value(mesh__ply_walk *w, mesh__ply_type t, double *v)
{
    if (!w->ascii) {
        size_t n = mesh__ply_size(t);
        if ((size_t)(w->end - w->p) < n)
            return mesh__fail(w->err, RR_ERR_PARSE, w->path,
                              "not a valid binary PLY file: it ends inside element '%s' (record %llu of %llu) (truncated?)",
                              w->elem, w->rec, w->count);
        *v = mesh__ply_get(w->p, t, w->big);
        w->p += n;
        return RR_OK;
    }
    mesh__sv tok;
    long long i;
    char q[48];
    if (!mesh__token(&w->text, &tok))
        return mesh__fail(w->err, RR_ERR_PARSE, w->path,
                          "not a valid ASCII PLY file: it ends inside element '%s' (record %llu of %llu) (truncated?)",
                          w->elem, w->rec, w->count);
    int real = t == PLY_F32 || t == PLY_F64;
    if (real ? !mesh__number(tok, v) : !mesh__integer(tok, &i))
        return mesh__fail(w->err, RR_ERR_PARSE, w->path, "not a valid ASCII PLY file: '%s' in element '%s' (record %llu)",
                          mesh__q(tok, q), w->elem, w->rec);
    if (!real)
        *v = (double)i;
    return RR_OK;
}

/* One "property" line of element e. */
static rr_status mesh__ply_property(const char *path, size_t line, mesh__ply_header *h, const mesh__sv *tok, size_t ntok,
                                    rr_error *err)
{
    mesh__ply_elem *e = &h->elems[h->nelems - 1];
    int list = mesh__eq(tok[0], "list");
    char q[48], q2[48];
    if (ntok != (list ? 4u : 2u))
        return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: malformed 'property' line", line);
    mesh__ply_prop p = {list ? tok[3] : tok[1], mesh__ply_type_of(list ? tok[2] : tok[0]),
                        list ? mesh__ply_type_of(tok[1]) : PLY_BAD, -1};
    if (p.type == PLY_BAD || (list && p.count_type == PLY_BAD))
        return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: bad property", line);
    if (mesh__eq(e->name, "vertex") && !list && p.name.n == 1 && p.name.p[0] >= 'x' && p.name.p[0] <= 'z')
        p.coord = p.name.p[0] - 'x';
    /* OpenMesh skips any other list by the size of one scalar, which would
     * shift every following value, expects the face's indices first, and
     * reads list counts of these types only. */
    if (list && (!mesh__eq(e->name, "face") || e->nprops != 0 ||
                 (!mesh__eq(p.name, "vertex_indices") && !mesh__eq(p.name, "vertex_index"))))
        return mesh__fail(err, RR_ERR_PARSE, path, "list property '%s' of element '%s' is not supported",
                          mesh__q(p.name, q), mesh__q(e->name, q2));
    if (list && ((p.count_type != PLY_U8 && p.count_type != PLY_U16 && p.count_type != PLY_I32) || p.type == PLY_F32 ||
                 p.type == PLY_F64))
        return mesh__fail(err, RR_ERR_PARSE, path, "face index list of type '%s %s' is not supported",
                          mesh__q(tok[1], q), mesh__q(tok[2], q2));
    if (p.coord >= 0 && p.type != PLY_F32 && p.type != PLY_F64) /* OpenMesh converts no other type */
        return mesh__fail(err, RR_ERR_PARSE, path, "vertex coordinates of type '%s' are not supported (only float or double)",
                          mesh__q(tok[0], q));
    mesh__ply_prop *np = realloc(h->props, (h->nprops + 1) * sizeof *np);
    if (!np)
        return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
    h->props = np;
    h->props[h->nprops++] = p;
    e->nprops++;
    return RR_OK;
}

static rr_status mesh__ply_header_parse(const char *path, const char *buf, size_t n, mesh__ply_header *h, rr_error *err)
{
    mesh__lines L = {buf, buf + n, 0};
    mesh__sv line, key, tok[6];
    char q[48];
    if (!mesh__line(&L, &line) || !mesh__eq(mesh__trim(line), "ply"))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file (no 'ply' magic)");
    int gap = 0; /* the line before was a comment or blank */
    while (mesh__line(&L, &line)) {
        mesh__sv raw = line;
        int after_gap = gap;
        if (!mesh__token(&line, &key)) {
            gap = 1;
            continue;
        }
        gap = mesh__eq(key, "comment");
        if (gap)
            continue;
        /* OpenMesh reads the rest of the header token by token (and loops
         * forever once a token fails to parse), so every line must have
         * exactly the tokens it expects. */
        size_t ntok = 0;
        while (ntok < 6 && mesh__token(&line, &tok[ntok]))
            ntok++;
        double version;
        if (h->format < 0) {
            if (!mesh__eq(key, "format") || ntok != 2 || !mesh__number(tok[1], &version))
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: no 'format' line after 'ply'");
            /* OpenMesh reads the version as a float and loops forever when
             * that fails: nan, inf and out-of-float-range values (found by
             * fuzzing, tests/fuzz/findings/). */
            if (!isfinite(version) || fabs(version) > FLT_MAX)
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: format version '%s' is not a number",
                                  mesh__q(tok[1], q));
            h->format = mesh__eq(tok[0], "ascii")                  ? 0
                        : mesh__eq(tok[0], "binary_little_endian") ? 1
                        : mesh__eq(tok[0], "binary_big_endian")    ? 2
                                                                   : -1;
            if (h->format < 0)
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: unknown format '%s'", mesh__q(tok[0], q));
        } else if (mesh__eq(key, "obj_info")) {
            /* OpenMesh takes each word of it for a keyword. */
            for (size_t i = 0; i < ntok; i++)
                if (mesh__eq(tok[i], "comment") || mesh__eq(tok[i], "element") || mesh__eq(tok[i], "property") ||
                    mesh__eq(tok[i], "end_header") || mesh__eq(tok[i], "format"))
                    return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: obj_info mentions '%s'", L.no,
                                      mesh__q(tok[i], q));
        } else if (mesh__eq(key, "element")) {
            long long cnt;
            if (ntok != 2 || !mesh__integer(tok[1], &cnt) || cnt < 0 || cnt > (long long)UINT32_MAX)
                return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: malformed 'element' line", L.no);
            mesh__ply_elem *ne = realloc(h->elems, (h->nelems + 1) * sizeof *ne);
            if (!ne)
                return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
            h->elems = ne;
            h->elems[h->nelems++] = (mesh__ply_elem){tok[0], (unsigned long long)cnt, h->nprops, 0};
        } else if (mesh__eq(key, "property") && h->nelems) {
            rr_status st = mesh__ply_property(path, L.no, h, tok, ntok, err);
            if (st)
                return st;
        } else if (mesh__eq(key, "end_header") && ntok == 0 && mesh__eq(mesh__trim(raw), "end_header")) {
            /* In binary files OpenMesh finds the data 12 bytes (14 with CRLF)
             * after the end of the last header token it read: a comment, a
             * blank line or trailing blanks just before end_header throw it
             * off by a few bytes, and it then reads shifted values. */
            const char *e = raw.p;
            size_t eol = e > buf && e[-1] == '\n' ? (e - 1 > buf && e[-2] == '\r' ? 2 : 1) : 0;
            if (h->format > 0 && (eol == 0 || after_gap || e - eol <= buf || mesh__space(e[-1 - (long)eol])))
                return mesh__fail(err, RR_ERR_PARSE, path,
                                  "header line %zu: OpenMesh cannot find the binary data after a comment, blank line or "
                                  "trailing blank just before end_header",
                                  L.no);
            h->body = L.p;
            return RR_OK;
        } else {
            return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: unexpected '%s'", L.no, mesh__q(key, q));
        }
    }
    return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: no end_header (truncated?)");
}

/* Walks element e's records; checks coordinates (vertex) and indices (face). */
static rr_status mesh__ply_walk_elem(mesh__ply_walk *w, const mesh__ply_header *h, const mesh__ply_elem *e,
                                     const mesh__ply_elem *vert, mesh__expect *ex)
{
    snprintf(w->elem, sizeof w->elem, "%.*s", (int)(e->name.n < 40 ? e->name.n : 40), e->name.p);
    w->count = e->count;
    rr_status st;
    for (w->rec = 0; w->rec < e->count; w->rec++) {
        for (size_t i = 0; i < e->nprops; i++) {
            const mesh__ply_prop *p = &h->props[e->first + i];
            double v, k;
            if (p->count_type == PLY_BAD) {
                if ((st = mesh__ply_value(w, p->type, &v)))
                    return st;
                if (p->coord >= 0 && e == vert) {
                    const char *why = mesh__bad_coord(v);
                    if (why)
                        return mesh__fail(w->err, RR_ERR_INVALID, w->path, "vertex %llu has %s", w->rec, why);
                    if (w->rec == 0)
                        ex->first[p->coord] = (float)v;
                    ex->last[p->coord] = (float)v;
                }
                continue;
            }
            if ((st = mesh__ply_value(w, p->count_type, &k)))
                return st;
            if (k < 3)
                return mesh__fail(w->err, RR_ERR_PARSE, w->path, "face %llu has %g vertices, fewer than 3", w->rec, k);
            for (double j = 0; j < k; j++) {
                if ((st = mesh__ply_value(w, p->type, &v)))
                    return st;
                if (v < 0 || v >= (double)vert->count)
                    return mesh__fail(w->err, RR_ERR_PARSE, w->path, "face %llu refers to vertex %.0f, but the file has %llu",
                                      w->rec, v, vert->count);
            }
        }
    }
    return RR_OK;
}

static rr_status mesh__ply_body(const char *path, const char *buf, size_t n, mesh__ply_header *h, mesh__expect *ex,
                                rr_error *err)
{
    const mesh__ply_elem *vert = NULL, *face = NULL;
    int has[3] = {0, 0, 0};
    for (size_t i = 0; i < h->nelems; i++) {
        const mesh__ply_elem *e = &h->elems[i];
        char q[48];
        if (e->count > 0 && e->nprops == 0) /* nothing to read, yet the loop would run count times */
            return mesh__fail(err, RR_ERR_PARSE, path, "element '%s' has no properties", mesh__q(e->name, q));
        if (mesh__eq(e->name, "vertex") && !vert)
            vert = e;
        if (mesh__eq(e->name, "face") && !face)
            face = e;
    }
    for (size_t i = 0; vert && i < vert->nprops; i++)
        if (h->props[vert->first + i].coord >= 0)
            has[h->props[vert->first + i].coord]++;
    if (!vert || has[0] != 1 || has[1] != 1 || has[2] != 1)
        return mesh__fail(err, RR_ERR_PARSE, path, "PLY file without a vertex element with x, y and z");
    if (!face || face->count == 0 || face->nprops == 0 || h->props[face->first].count_type == PLY_BAD)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    const char *end = buf + n;
    if (!mesh__is_text(buf, (size_t)(h->body - buf)) || (h->format == 0 && !mesh__is_text(h->body, (size_t)(end - h->body))))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file (binary data in text)");
    mesh__ply_walk w = {path, h->format == 0, h->format == 2, (const unsigned char *)h->body, (const unsigned char *)end,
                        {h->body, (size_t)(end - h->body)}, "", 0, 0, err};
    for (size_t i = 0; i < h->nelems; i++) {
        rr_status st = mesh__ply_walk_elem(&w, h, &h->elems[i], vert, ex);
        if (st)
            return st;
        if (&h->elems[i] == face)
            break; /* OpenMesh stops here too */
    }
    ex->nverts = (long long)vert->count;
    ex->nfaces = (long long)face->count;
    ex->probe = h->format > 0 && vert->count > 0; /* text: iostream and strtod may round differently */
    return RR_OK;
}

rr_status mesh__check_ply(const char *path, const char *buf, size_t n, mesh__expect *ex, rr_error *err)
{
    /* Without end_header OpenMesh's header loop never ends: say "truncated"
     * rather than complain about whatever the cut left. */
    int found = 0;
    for (size_t i = 0; i + 10 <= n && !found; i++)
        found = buf[i] == 'e' && memcmp(buf + i, "end_header", 10) == 0;
    if (!found)
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: no end_header (truncated?)");
    mesh__ply_header h = {-1, NULL, 0, NULL, 0, NULL};
    rr_status st = mesh__ply_header_parse(path, buf, n, &h, err);
    if (!st)
        st = mesh__ply_body(path, buf, n, &h, ex, err);
    free(h.elems);
    free(h.props);
    return st;
}
