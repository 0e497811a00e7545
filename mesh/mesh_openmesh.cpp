/* mesh_openmesh.cpp - mesh_load: the only C++ in radray, a shim over OpenMesh's
 * readers (see mesh.h for the contract, mesh_internal.h for the hand-over).
 *
 * How a file is read:
 *  1. The file is read into memory once (core's rr_file_read_all): OpenMesh
 *     then parses these same bytes from a memory stream, so what was checked
 *     is what gets read.
 *  2. A strict pre-check per format (mesh__check_*). OpenMesh 9.0's readers are
 *     permissive in ways that matter here: a truncated or malformed line is
 *     skipped or read as stale values, "nan" in a text file silently stops the
 *     iostream, a PLY header without end_header loops forever, a truncated
 *     binary STL is taken for ASCII, an out-of-range OBJ index writes out of
 *     bounds. So every count, index and coordinate is validated here first,
 *     and OpenMesh only ever sees input it handles correctly.
 *  3. OpenMesh reads into a PolyMesh through mesh__recorder, an ImporterT that
 *     also records each polygon exactly as the reader passed it. That matters
 *     because ImporterT on its own drops faces with a repeated vertex and, for
 *     a face that would make the halfedge structure non-manifold (a third face
 *     on an edge, or a face reversing a neighbour's orientation), adds it on
 *     fresh copies of its vertices: the recorded polygons keep the file's own
 *     indexing, so mesh_analyze sees the real topology and degenerate faces
 *     are kept, as mesh.h promises.
 *  4. The recorded soup goes to mesh__from_soup (mesh.c) for the final checks
 *     and triangulation.
 * No exception leaves this file: mesh_load catches everything.
 */
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>

#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <string_view>
#include <vector>

#include <sys/stat.h>

extern "C" {
#include "mesh_internal.h"
}

namespace {

using sv = std::string_view;

enum mesh__format { MESH__OBJ, MESH__PLY, MESH__OFF, MESH__STL };

/* What the pre-check learned and OpenMesh's result must agree with; -1 when
 * the format does not tell (OBJ face count, STL after OpenMesh's welding). */
struct mesh__expect {
    long long nverts = -1, nfaces = -1;
    bool binary = false; /* binary STL: OpenMesh's stream reader needs to be told */
    /* Binary PLY, OFF: the first and last vertex as the pre-check read them,
     * to catch OpenMesh reading from a shifted offset (PLY) or with stale
     * header flags (its OFF reader keeps them between files). */
    bool probe = false;
    float first[3], last[3];
    /* OFF: the file rewritten the way OpenMesh's reader needs it (see
     * mesh__check_off); empty when OpenMesh reads the file's own bytes. */
    std::string text;
};

/* "path: reason", as every error of mesh_load reads. */
#if defined(__GNUC__)
__attribute__((format(printf, 4, 5)))
#endif
rr_status mesh__fail(rr_error *err, rr_status code, const char *path, const char *fmt, ...)
{
    char msg[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return rr_error_set(err, code, "%s: %s", path, msg);
}

/* ---- text scanning helpers ---- */

struct mesh__lines {
    const char *p, *end;
    size_t no = 0; /* 1-based number of the line last returned */
    bool next(sv &line)
    {
        if (p >= end)
            return false;
        const char *e = static_cast<const char *>(memchr(p, '\n', size_t(end - p)));
        if (!e)
            e = end;
        line = sv(p, size_t(e - p));
        p = e < end ? e + 1 : end;
        no++;
        return true;
    }
};

bool mesh__space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

sv mesh__trim(sv s)
{
    while (!s.empty() && mesh__space(s.front()))
        s.remove_prefix(1);
    while (!s.empty() && mesh__space(s.back()))
        s.remove_suffix(1);
    return s;
}

/* Pops the next whitespace-separated token of s into t. */
bool mesh__token(sv &s, sv &t)
{
    size_t i = 0;
    while (i < s.size() && mesh__space(s[i]))
        i++;
    size_t j = i;
    while (j < s.size() && !mesh__space(s[j]))
        j++;
    t = s.substr(i, j - i);
    s.remove_prefix(j);
    return !t.empty();
}

bool mesh__ieq(sv a, const char *b)
{
    size_t n = strlen(b);
    if (a.size() != n)
        return false;
    for (size_t i = 0; i < n; i++)
        if (tolower((unsigned char)a[i]) != tolower((unsigned char)b[i]))
            return false;
    return true;
}

/* A decimal number as iostreams (and so OpenMesh) read it. nan/inf parse, so
 * that the caller can name them; hex floats do not (iostreams would stop at
 * the 'x' and OpenMesh read a different number than strtod). */
bool mesh__number(sv t, double &v)
{
    char buf[64];
    if (t.empty() || t.size() >= sizeof buf)
        return false;
    sv body = (t[0] == '+' || t[0] == '-') ? t.substr(1) : t;
    bool special = mesh__ieq(body.substr(0, 3), "nan") || mesh__ieq(body.substr(0, 3), "inf");
    for (char c : t)
        if (!special && !isdigit((unsigned char)c) && !strchr("+-.eE", c))
            return false;
    memcpy(buf, t.data(), t.size());
    buf[t.size()] = '\0';
    char *e;
    v = strtod(buf, &e);
    return e == buf + t.size();
}

bool mesh__integer(sv t, long long &v)
{
    char buf[32];
    if (t.empty() || t.size() >= sizeof buf)
        return false;
    for (size_t i = 0; i < t.size(); i++)
        if (!isdigit((unsigned char)t[i]) && !(i == 0 && (t[i] == '-' || t[i] == '+')))
            return false;
    memcpy(buf, t.data(), t.size());
    buf[t.size()] = '\0';
    errno = 0;
    char *e;
    v = strtoll(buf, &e, 10);
    return errno == 0 && e == buf + t.size();
}

/* OpenMesh stores points read from text as float: a finite double beyond
 * FLT_MAX would come back infinite, so it is refused by name here. */
const char *mesh__bad_coord(double v)
{
    if (!std::isfinite(v))
        return "a non-finite coordinate";
    if (std::fabs(v) > FLT_MAX)
        return "a coordinate beyond single precision";
    return nullptr;
}

/* File text quoted in a message: printable, one line, at most 40 bytes. */
std::string mesh__q(sv t)
{
    std::string q;
    for (size_t i = 0; i < t.size() && i < 40; i++)
        q += isprint((unsigned char)t[i]) ? t[i] : '?';
    if (t.size() > 40)
        q += "...";
    return q;
}

/* Text formats never contain NUL bytes: one means binary garbage (and would cut
 * OpenMesh's line parsing short). */
bool mesh__is_text(const char *buf, size_t n) { return memchr(buf, '\0', n) == nullptr; }

/* Reads up to 3 coordinates of a vertex-like line into v; returns how many. */
int mesh__coords(sv &rest, double v[3])
{
    sv t;
    for (int k = 0; k < 3; k++)
        if (!mesh__token(rest, t) || !mesh__number(t, v[k]))
            return k;
    return 3;
}

/* The first three numbers of line as OpenMesh's iostreams read them into
 * floats (strtof rounds the decimal text once, as they do). */
void mesh__probe(sv line, float out[3])
{
    sv t;
    char buf[64];
    for (int k = 0; k < 3; k++) {
        mesh__token(line, t);
        size_t n = t.size() < sizeof buf - 1 ? t.size() : sizeof buf - 1;
        memcpy(buf, t.data(), n);
        buf[n] = '\0';
        out[k] = strtof(buf, nullptr);
    }
}

/* ---- OBJ ---- */

rr_status mesh__check_obj(const char *path, const char *buf, size_t n, mesh__expect &ex, rr_error *err)
{
    if (!mesh__is_text(buf, n))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OBJ file (binary data)");
    mesh__lines L{buf, buf + n};
    sv line, key, t;
    long long nv = 0, nn = 0, nf = 0;
    while (L.next(line)) {
        line = mesh__trim(line);
        if (line.empty() || line[0] == '#' || !mesh__token(line, key))
            continue;
        double v[3];
        if (key == "v" || key == "vn") {
            bool normal = key == "vn";
            if (mesh__coords(line, v) != 3)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: %s needs three numbers (truncated?)", L.no,
                                  normal ? "normal" : "vertex");
            for (double c : v)
                if (const char *why = mesh__bad_coord(c))
                    return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: %s %lld has %s", L.no,
                                      normal ? "normal" : "vertex", normal ? nn : nv, why);
            (normal ? nn : nv)++;
        } else if (key == "vt") {
            /* OpenMesh aborts the whole read on a "vt" it cannot parse. */
            if (mesh__coords(line, v) < 2)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: texture coordinate needs two numbers", L.no);
        } else if (key == "f") {
            int corners = 0;
            while (mesh__token(line, t) && t[0] != '#') {
                /* i, i/t, i//n or i/t/n; OpenMesh reads the parts with an
                 * unchecked int, so anything else is refused here. */
                sv part[3];
                int np = 0;
                for (size_t s = 0;; np++) {
                    size_t slash = t.find('/', s);
                    if (np == 3)
                        return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: bad face corner '%s'", L.no,
                                          mesh__q(t).c_str());
                    part[np] = t.substr(s, slash == sv::npos ? sv::npos : slash - s);
                    if (slash == sv::npos) {
                        np++;
                        break;
                    }
                    s = slash + 1;
                }
                long long idx[3] = {0, 0, 0}, count[3] = {nv, -1, nn};
                for (int k = 0; k < np; k++) {
                    if (k == 1 && part[k].empty() && np == 3)
                        continue; /* i//n */
                    if (!mesh__integer(part[k], idx[k]) || idx[k] == 0)
                        return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: bad face corner '%s'", L.no,
                                          mesh__q(t).c_str());
                    if (count[k] >= 0 && (idx[k] > count[k] || -idx[k] > count[k]))
                        return mesh__fail(err, RR_ERR_PARSE, path,
                                          "line %zu: face refers to %s %lld, but only %lld are defined before it", L.no,
                                          k == 0 ? "vertex" : "normal", idx[k], count[k]);
                }
                corners++;
            }
            if (corners < 3)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face has fewer than 3 vertices (truncated?)", L.no);
            nf++;
        }
    }
    if (nf == 0)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    ex.nverts = nv;
    return RR_OK;
}

/* ---- OFF (ASCII; OpenMesh's binary OFF layout is not checkable, see below) ---- */

rr_status mesh__check_off(const char *path, const char *buf, size_t n, mesh__expect &ex, rr_error *err)
{
    if (!mesh__is_text(buf, n))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file (binary data)");
    mesh__lines L{buf, buf + n};
    sv line, t;
    /* Next line with content, skipping blank lines and comments. */
    auto content = [&](sv &out) {
        while (L.next(out)) {
            out = mesh__trim(out);
            if (!out.empty() && out[0] != '#')
                return true;
        }
        return false;
    };
    if (!content(line) || !mesh__token(line, t))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file");
    /* [ST][C][N]OFF: what each vertex line carries besides its point. */
    sv kw = t;
    bool normals = false;
    if (kw.substr(0, 2) == "ST")
        kw.remove_prefix(2);
    if (!kw.empty() && kw[0] == 'C')
        kw.remove_prefix(1);
    if (!kw.empty() && kw[0] == 'N') {
        normals = true;
        kw.remove_prefix(1);
    }
    if (kw != "OFF")
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file (header '%s')", mesh__q(t).c_str());
    long long cnt[3];
    for (int k = 0; k < 3; k++) {
        while (!mesh__token(line, t))
            if (!content(line))
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file: no vertex and face counts (truncated?)");
        if (k == 0 && t == "BINARY")
            /* OpenMesh's binary OFF reader trusts every count and reads past
             * the end; there is no way to vouch for its result. */
            return mesh__fail(err, RR_ERR_PARSE, path, "binary OFF is not supported (convert it to ASCII OFF or PLY)");
        if (!mesh__integer(t, cnt[k]) || cnt[k] < 0 || cnt[k] > (long long)UINT32_MAX)
            return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file: bad count '%s'",
                              mesh__q(t).c_str());
    }
    const long long nv = cnt[0], nf = cnt[1];
    /* OpenMesh wants the keyword alone on the first line, reads every value
     * with >> (a comment or a trailing word derails all that follows) and
     * reads colours and texture coordinates by guesswork. So OpenMesh gets a
     * canonical copy: the keyword, the counts, and per line only the values
     * radray uses (point, normal; face indices). */
    std::string &o = ex.text;
    o.reserve(n);
    o += "OFF\n";
    o += std::to_string(nv) + " " + std::to_string(nf) + " 0\n";
    for (long long i = 0; i < nv; i++) {
        double v[3];
        if (!content(line))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid OFF file: it ends after %lld of its %lld vertices (truncated?)", i, nv);
        sv rest = line;
        if (mesh__coords(rest, v) != 3)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: vertex %lld needs three numbers", L.no, i);
        for (double c : v)
            if (const char *why = mesh__bad_coord(c))
                return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: vertex %lld has %s", L.no, i, why);
        o.append(line.data(), size_t(rest.data() - line.data())).push_back('\n');
        if (normals && mesh__coords(rest, v) != 3)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: vertex %lld needs a normal", L.no, i);
        if (i == 0 || i == nv - 1)
            mesh__probe(line, i == 0 ? ex.first : ex.last);
    }
    ex.probe = nv > 0;
    for (long long f = 0; f < nf; f++) {
        long long k, idx;
        if (!content(line))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid OFF file: it ends after %lld of its %lld faces (truncated?)", f, nf);
        const char *face_start = line.data();
        if (!mesh__token(line, t) || !mesh__integer(t, k) || k < 3 || k > nv)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face %lld needs a vertex count from 3 to the number of vertices", L.no, f);
        for (long long j = 0; j < k; j++) {
            if (!mesh__token(line, t) || !mesh__integer(t, idx))
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face %lld has fewer than %lld vertices (truncated?)",
                                  L.no, f, k);
            if (idx < 0 || idx >= nv)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face %lld refers to vertex %lld, but the file has %lld",
                                  L.no, f, idx, nv);
        }
        o.append(face_start, size_t(line.data() - face_start)).push_back('\n');
    }
    if (nf == 0)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    ex.nverts = nv;
    ex.nfaces = nf;
    return RR_OK;
}

/* ---- STL ---- */

float mesh__le_float(const unsigned char *p)
{
    uint32_t u = uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

rr_status mesh__check_stl(const char *path, const char *buf, size_t n, mesh__expect &ex, rr_error *err)
{
    const unsigned char *u = reinterpret_cast<const unsigned char *>(buf);
    /* OpenMesh's own test: binary exactly when the size matches the count in
     * the header (a binary header may well start with "solid"). */
    if (n >= 84) {
        uint64_t ntri = uint64_t(u[80]) | uint64_t(u[81]) << 8 | uint64_t(u[82]) << 16 | uint64_t(u[83]) << 24;
        if (84 + 50 * ntri == n) {
            for (uint64_t i = 0; i < ntri; i++)
                for (int k = 3; k < 12; k++)
                    if (const char *why = mesh__bad_coord(mesh__le_float(u + 84 + 50 * i + 4 * k)))
                        return mesh__fail(err, RR_ERR_INVALID, path, "triangle %llu has %s", (unsigned long long)i, why);
            if (ntri == 0)
                return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
            ex.binary = true;
            return RR_OK;
        }
        if (!mesh__is_text(buf, n))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid binary STL file: its header announces %llu triangles (%llu bytes) but the "
                              "file has %zu bytes (truncated?)",
                              (unsigned long long)ntri, (unsigned long long)(84 + 50 * ntri), n);
    }
    mesh__lines L{buf, buf + n};
    sv line, key;
    bool started = false, ended = false;
    size_t tris = 0;
    while (L.next(line)) {
        /* OpenMesh takes any line containing "outer" as the start of a facet
         * and reads the next three lines as its vertices, whatever they say. */
        bool outer = line.find("outer") != sv::npos || line.find("OUTER") != sv::npos;
        line = mesh__trim(line);
        if (line.empty())
            continue;
        if (!mesh__token(line, key))
            continue;
        if (!started) {
            if (!mesh__ieq(key, "solid"))
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid STL file (neither ASCII nor binary)");
            started = true;
            continue;
        }
        ended = mesh__ieq(key, "endsolid");
        if (!outer)
            continue;
        for (int k = 0; k < 3; k++) {
            double v[3];
            sv vl, vk;
            if (!L.next(vl) || (vl = mesh__trim(vl), !mesh__token(vl, vk)) || !mesh__ieq(vk, "vertex") ||
                mesh__coords(vl, v) != 3)
                return mesh__fail(err, RR_ERR_PARSE, path,
                                  "line %zu: expected three 'vertex x y z' lines after 'outer loop' (truncated?)", L.no);
            for (double c : v)
                if (const char *why = mesh__bad_coord(c))
                    return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: vertex has %s", L.no, why);
        }
        tris++;
    }
    if (!started)
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid STL file");
    if (!ended)
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid ASCII STL file: no final 'endsolid' (truncated?)");
    if (tris == 0)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    return RR_OK;
}

/* ---- PLY ---- */

enum mesh__ply_type { PLY_BAD, PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64 };

mesh__ply_type mesh__ply_type_of(sv s)
{
    static const struct {
        const char *name;
        mesh__ply_type type;
    } names[] = {{"char", PLY_I8},    {"int8", PLY_I8},     {"uchar", PLY_U8},   {"uint8", PLY_U8},
                 {"short", PLY_I16},  {"int16", PLY_I16},   {"ushort", PLY_U16}, {"uint16", PLY_U16},
                 {"int", PLY_I32},    {"int32", PLY_I32},   {"uint", PLY_U32},   {"uint32", PLY_U32},
                 {"float", PLY_F32},  {"float32", PLY_F32}, {"double", PLY_F64}, {"float64", PLY_F64}};
    for (const auto &e : names)
        if (s == e.name)
            return e.type;
    return PLY_BAD;
}

size_t mesh__ply_size(mesh__ply_type t)
{
    static const size_t sizes[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
    return sizes[t];
}

/* Decodes one binary scalar. */
double mesh__ply_get(const unsigned char *p, mesh__ply_type t, bool big)
{
    const uint16_t one = 1;
    bool swap = big == (*reinterpret_cast<const unsigned char *>(&one) == 1);
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

struct mesh__ply_prop {
    sv name;
    mesh__ply_type type;
    mesh__ply_type count_type; /* PLY_BAD for a scalar */
    int coord;                 /* 0..2 for vertex x, y, z, else -1 */
};

struct mesh__ply_elem {
    sv name;
    unsigned long long count;
    std::vector<mesh__ply_prop> props;
};

/* Walks the PLY body value by value (binary bytes or ASCII tokens), checking
 * the vertex coordinates and the face indices. Stops after the face element,
 * as OpenMesh does. */
struct mesh__ply_walk {
    const char *path;
    bool ascii, big;
    const unsigned char *p, *end; /* binary */
    sv text;                      /* ascii */
    const char *elem;
    unsigned long long rec, count;
    rr_error *err;

    rr_status truncated()
    {
        return mesh__fail(err, RR_ERR_PARSE, path,
                          "not a valid %s PLY file: it ends inside element '%s' (record %llu of %llu) (truncated?)",
                          ascii ? "ASCII" : "binary", elem, rec, count);
    }
    /* Next value as a double; integer types are checked to be integral. */
    rr_status value(mesh__ply_type t, double &v)
    {
        if (!ascii) {
            size_t n = mesh__ply_size(t);
            if (size_t(end - p) < n)
                return truncated();
            v = mesh__ply_get(p, t, big);
            p += n;
            return RR_OK;
        }
        sv tok;
        if (!mesh__token(text, tok))
            return truncated();
        long long i;
        bool ok = t == PLY_F32 || t == PLY_F64 ? mesh__number(tok, v) : mesh__integer(tok, i);
        if (!ok)
            return mesh__fail(err, RR_ERR_PARSE, path, "not a valid ASCII PLY file: '%s' in element '%s' (record %llu)",
                              mesh__q(tok).c_str(), elem, rec);
        if (t != PLY_F32 && t != PLY_F64)
            v = double(i);
        return RR_OK;
    }
};

rr_status mesh__check_ply(const char *path, const char *buf, size_t n, mesh__expect &ex, rr_error *err)
{
    mesh__lines L{buf, buf + n};
    sv line, key, t;
    if (!L.next(line) || mesh__trim(line) != "ply")
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file (no 'ply' magic)");
    if (sv(buf, n).find("end_header") == sv::npos)
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: no end_header (truncated?)");
    int format = -1; /* 0 ascii, 1 little endian, 2 big endian */
    std::vector<mesh__ply_elem> elems;
    bool header_done = false, prev_comment = false;
    while (!header_done && L.next(line)) {
        sv raw = line;
        bool after_gap = prev_comment;
        if (!mesh__token(line, key)) {
            prev_comment = true; /* a blank line misleads OpenMesh the same way */
            continue;
        }
        prev_comment = key == "comment";
        if (key == "comment")
            continue;
        /* OpenMesh reads the rest of the header token by token (and loops
         * forever once a token fails to parse), so every line must have
         * exactly the tokens it expects. */
        sv tok[6];
        size_t ntok = 0;
        while (ntok < 6 && mesh__token(line, tok[ntok]))
            ntok++;
        const sv a = tok[0], b = tok[1], c = tok[2], d = tok[3];
        double version;
        if (format < 0 && (key != "format" || ntok != 2 || !mesh__number(b, version)))
            return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: no 'format' line after 'ply'");
        if (key == "obj_info") {
            /* OpenMesh takes each word of it for a keyword. */
            for (size_t i = 0; i < ntok; i++)
                if (tok[i] == "comment" || tok[i] == "element" || tok[i] == "property" || tok[i] == "end_header")
                    return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: obj_info mentions '%s'", L.no,
                                      mesh__q(tok[i]).c_str());
            continue;
        }
        if ((key == "element" && ntok != 2) || (key == "property" && ntok != (a == "list" ? 4u : 2u)) ||
            (key == "end_header" && ntok != 0))
            return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: malformed '%s' line", L.no,
                              mesh__q(key).c_str());
        if (key == "format") {
            if (format >= 0)
                return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: second 'format' line", L.no);
            format = a == "ascii" ? 0 : a == "binary_little_endian" ? 1 : a == "binary_big_endian" ? 2 : -1;
            if (format < 0)
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: unknown format '%s'", mesh__q(a).c_str());
        } else if (key == "element") {
            long long cnt;
            if (!mesh__integer(b, cnt) || cnt < 0 || cnt > (long long)UINT32_MAX)
                return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: bad element count", L.no);
            elems.push_back({a, (unsigned long long)cnt, {}});
        } else if (key == "property" && !elems.empty()) {
            mesh__ply_elem &e = elems.back();
            bool list = a == "list";
            mesh__ply_prop p{list ? d : b, mesh__ply_type_of(list ? c : a), list ? mesh__ply_type_of(b) : PLY_BAD, -1};
            if (p.type == PLY_BAD || p.name.empty() || (list && p.count_type == PLY_BAD))
                return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: bad property", L.no);
            if (e.name == "vertex" && !list && p.name.size() == 1 && p.name[0] >= 'x' && p.name[0] <= 'z')
                p.coord = p.name[0] - 'x';
            /* OpenMesh skips any other list by the size of one scalar, which
             * would shift every following value, and expects the face's
             * indices first; it reads list counts of these types only. */
            if (list && (e.name != "face" || !e.props.empty() ||
                         (p.name != "vertex_indices" && p.name != "vertex_index")))
                return mesh__fail(err, RR_ERR_PARSE, path, "list property '%s' of element '%s' is not supported",
                                  mesh__q(p.name).c_str(), mesh__q(e.name).c_str());
            if (list && ((p.count_type != PLY_U8 && p.count_type != PLY_U16 && p.count_type != PLY_I32) ||
                         p.type == PLY_F32 || p.type == PLY_F64))
                return mesh__fail(err, RR_ERR_PARSE, path, "face index list of type '%s %s' is not supported",
                                  mesh__q(b).c_str(), mesh__q(c).c_str());
            if (p.coord >= 0 && p.type != PLY_F32 && p.type != PLY_F64)
                /* OpenMesh converts only float and double properties to
                 * coordinates. */
                return mesh__fail(err, RR_ERR_PARSE, path,
                                  "vertex coordinates of type '%s' are not supported (only float or double)",
                                  mesh__q(a).c_str());
            e.props.push_back(p);
        } else if (key == "end_header") {
            /* OpenMesh finds the binary data by assuming "end_header" stands
             * alone on its line. */
            if (mesh__trim(raw) != "end_header")
                return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: text after end_header", L.no);
            /* In binary files OpenMesh finds the data 12 bytes (14 with CRLF)
             * after the end of the last header token it read: a comment, a
             * blank line or trailing blanks just before end_header throw it
             * off by a few bytes, and it then reads shifted values. */
            const char *e = raw.data();
            size_t eol = e > buf && e[-1] == '\n' ? (e - 1 > buf && e[-2] == '\r' ? 2 : 1) : 0;
            if (format > 0 && (eol == 0 || after_gap || e - eol <= buf || mesh__space(e[-1 - (long)eol])))
                return mesh__fail(err, RR_ERR_PARSE, path,
                                  "header line %zu: OpenMesh cannot find the binary data after a comment, blank line or "
                                  "trailing blank just before end_header",
                                  L.no);
            header_done = true;
        } else {
            return mesh__fail(err, RR_ERR_PARSE, path, "header line %zu: unexpected '%s'", L.no,
                              mesh__q(key).c_str());
        }
    }
    if (!header_done || format < 0)
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file: incomplete header (truncated?)");
    const mesh__ply_elem *vert = nullptr, *face = nullptr;
    for (const auto &e : elems) {
        if (e.count > 0 && e.props.empty())
            return mesh__fail(err, RR_ERR_PARSE, path, "element '%s' has no properties", mesh__q(e.name).c_str());
        if (e.name == "vertex" && !vert)
            vert = &e;
        if (e.name == "face" && !face)
            face = &e;
    }
    int has[3] = {0, 0, 0};
    if (vert)
        for (const auto &p : vert->props)
            if (p.coord >= 0)
                has[p.coord]++;
    if (!vert || has[0] != 1 || has[1] != 1 || has[2] != 1)
        return mesh__fail(err, RR_ERR_PARSE, path, "PLY file without a vertex element with x, y and z");
    if (!face || face->count == 0 || face->props.empty() || face->props[0].count_type == PLY_BAD)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    if (!mesh__is_text(buf, size_t(L.p - buf)) || (format == 0 && !mesh__is_text(L.p, size_t(L.end - L.p))))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid PLY file (binary data in text)");

    mesh__ply_walk w{path, format == 0, format == 2, reinterpret_cast<const unsigned char *>(L.p),
                     reinterpret_cast<const unsigned char *>(L.end), sv(L.p, size_t(L.end - L.p)), "", 0, 0, err};
    for (const auto &e : elems) {
        std::string name(e.name);
        w.elem = name.c_str();
        w.count = e.count;
        for (w.rec = 0; w.rec < e.count; w.rec++) {
            for (const auto &p : e.props) {
                double v;
                if (p.count_type == PLY_BAD) {
                    if (rr_status st = w.value(p.type, v))
                        return st;
                    if (p.coord >= 0 && &e == vert) {
                        if (const char *why = mesh__bad_coord(v))
                            return mesh__fail(err, RR_ERR_INVALID, path, "vertex %llu has %s", w.rec, why);
                        if (w.rec == 0)
                            ex.first[p.coord] = float(v);
                        ex.last[p.coord] = float(v);
                    }
                    continue;
                }
                double k;
                if (rr_status st = w.value(p.count_type, k))
                    return st;
                if (k < 3)
                    return mesh__fail(err, RR_ERR_PARSE, path, "face %llu has %g vertices, fewer than 3", w.rec, k);
                for (double j = 0; j < k; j++) {
                    if (rr_status st = w.value(p.type, v))
                        return st;
                    if (v < 0 || v >= double(vert->count))
                        return mesh__fail(err, RR_ERR_PARSE, path, "face %llu refers to vertex %.0f, but the file has %llu",
                                          w.rec, v, vert->count);
                }
            }
        }
        if (&e == face)
            break;
    }
    ex.nverts = (long long)vert->count;
    ex.nfaces = (long long)face->count;
    ex.probe = format > 0 && vert->count > 0; /* text: iostream and strtod may round differently */
    return RR_OK;
}

/* ---- OpenMesh ---- */

struct mesh__traits : public OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
typedef OpenMesh::PolyMesh_ArrayKernelT<mesh__traits> mesh__poly;
typedef OpenMesh::IO::ImporterT<mesh__poly> mesh__importer;

/* ImporterT that also records what the reader hands it (see the top of the
 * file for why). Vertices are recorded by handle in the order the reader
 * added them, which leaves out the copies ImporterT makes for non-manifold
 * faces. Normals are kept here rather than in the mesh so that a bad handle
 * from a reader cannot write out of bounds. */
class mesh__recorder : public mesh__importer {
public:
    explicit mesh__recorder(mesh__poly &m) : mesh__importer(m), mesh_(m) {}

    std::vector<int> verts;         /* reader's vertices, as handle indices */
    std::vector<size_t> start{0};   /* polygon f is idx[start[f] .. start[f+1]) */
    std::vector<int> idx;           /* handle indices */
    std::vector<double> normals;    /* 3 per handle index */
    std::vector<unsigned char> has_normal;
    size_t short_faces = 0;         /* fewer than 3 corners: not a polygon */

    using mesh__importer::add_face;
    using mesh__importer::set_normal;

    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3f &p) override { return note(mesh__importer::add_vertex(p)); }
    OpenMesh::VertexHandle add_vertex(const OpenMesh::Vec3d &p) override { return note(mesh__importer::add_vertex(p)); }
    OpenMesh::VertexHandle add_vertex() override { return note(mesh__importer::add_vertex()); }

    OpenMesh::FaceHandle add_face(const VHandles &vs) override
    {
        if (vs.size() < 3) {
            short_faces++;
        } else {
            for (const auto &v : vs)
                idx.push_back(v.idx());
            start.push_back(idx.size());
        }
        return mesh__importer::add_face(vs);
    }

    void set_normal(OpenMesh::VertexHandle vh, const OpenMesh::Vec3f &n) override { keep(vh, n[0], n[1], n[2]); }
    void set_normal(OpenMesh::VertexHandle vh, const OpenMesh::Vec3d &n) override { keep(vh, n[0], n[1], n[2]); }

private:
    mesh__poly &mesh_;

    OpenMesh::VertexHandle note(OpenMesh::VertexHandle vh)
    {
        verts.push_back(vh.idx());
        return vh;
    }
    void keep(OpenMesh::VertexHandle vh, double x, double y, double z)
    {
        if (!vh.is_valid() || size_t(vh.idx()) >= mesh_.n_vertices())
            return;
        size_t i = size_t(vh.idx());
        if (has_normal.size() <= i) {
            has_normal.resize(mesh_.n_vertices(), 0);
            normals.resize(3 * mesh_.n_vertices(), 0.0);
        }
        normals[3 * i] = x;
        normals[3 * i + 1] = y;
        normals[3 * i + 2] = z;
        has_normal[i] = 1;
    }
};

/* A read-only seekable stream over the file's bytes (OpenMesh's OBJ reader
 * rewinds for its second pass; the PLY reader seeks to its binary data). */
class mesh__membuf : public std::streambuf {
public:
    mesh__membuf(const char *p, size_t n)
    {
        char *b = const_cast<char *>(p); /* only ever read: no put area */
        setg(b, b, b + n);
    }

protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        char *base = dir == std::ios_base::beg ? eback() : dir == std::ios_base::cur ? gptr() : egptr();
        if (off < eback() - base || off > egptr() - base)
            return pos_type(off_type(-1));
        setg(eback(), base + off, egptr());
        return pos_type(gptr() - eback());
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

class mesh__nullbuf : public std::streambuf {
protected:
    int_type overflow(int_type c) override { return traits_type::not_eof(c); }
};

/* OpenMesh reports through its omerr/omlog streams and, in places, straight to
 * std::cerr; radray reports through rr_error, so both are silenced while a
 * file is read and restored afterwards. The lock also serialises use of
 * OpenMesh's reader singletons, whose state is not thread-safe. */
std::mutex mesh__lock;

class mesh__quiet {
public:
    mesh__quiet() : guard_(mesh__lock)
    {
        err_on_ = ::omerr().is_enabled();
        log_on_ = ::omlog().is_enabled();
        ::omerr().disable();
        ::omlog().disable();
        cerr_ = std::cerr.rdbuf(&null_);
    }
    ~mesh__quiet()
    {
        /* Flushing while disabled drops any half-written message. */
        ::omerr().flush();
        ::omlog().flush();
        if (err_on_)
            ::omerr().enable();
        if (log_on_)
            ::omlog().enable();
        std::cerr.rdbuf(cerr_);
    }
    mesh__quiet(const mesh__quiet &) = delete;
    mesh__quiet &operator=(const mesh__quiet &) = delete;

private:
    std::lock_guard<std::mutex> guard_;
    mesh__nullbuf null_;
    std::streambuf *cerr_;
    bool err_on_, log_on_;
};

const char *mesh__ext_name(mesh__format f)
{
    static const char *names[] = {".obj", ".ply", ".off", ".stl"};
    return names[f];
}

rr_status mesh__load(const char *path, mesh_tri **out, rr_error *err)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash + 1 : path, '.');
    mesh__format fmt;
    if (dot && mesh__ieq(dot, ".obj"))
        fmt = MESH__OBJ;
    else if (dot && mesh__ieq(dot, ".ply"))
        fmt = MESH__PLY;
    else if (dot && mesh__ieq(dot, ".off"))
        fmt = MESH__OFF;
    else if (dot && mesh__ieq(dot, ".stl"))
        fmt = MESH__STL;
    else
        return mesh__fail(err, RR_ERR_INVALID, path, "unknown mesh format '%s' (expected .obj, .ply, .off or .stl)",
                          dot ? dot : "");

    struct stat st;
    if (stat(path, &st) != 0)
        return errno == ENOENT ? mesh__fail(err, RR_ERR_IO, path, "file does not exist")
                               : mesh__fail(err, RR_ERR_IO, path, "cannot open: %s", strerror(errno));
    if (!S_ISREG(st.st_mode)) /* a FIFO would block, a folder is no mesh */
        return mesh__fail(err, RR_ERR_IO, path, "not a regular file");
    char *raw = nullptr;
    size_t n = 0;
    if (rr_status s = rr_file_read_all(path, &raw, &n, err))
        return s;
    std::unique_ptr<char, void (*)(void *)> data(raw, free);
    if (n == 0)
        return mesh__fail(err, RR_ERR_IO, path, "empty file");

    mesh__expect ex;
    rr_status s = fmt == MESH__OBJ   ? mesh__check_obj(path, raw, n, ex, err)
                  : fmt == MESH__PLY ? mesh__check_ply(path, raw, n, ex, err)
                  : fmt == MESH__OFF ? mesh__check_off(path, raw, n, ex, err)
                                     : mesh__check_stl(path, raw, n, ex, err);
    if (s)
        return s;

    mesh__poly mesh;
    mesh__recorder rec(mesh);
    OpenMesh::IO::Options opt = OpenMesh::IO::Options::VertexNormal;
    if (ex.binary)
        opt += OpenMesh::IO::Options::Binary;
    bool ok;
    {
        mesh__quiet quiet;
        mesh__membuf mb(ex.text.empty() ? raw : ex.text.data(), ex.text.empty() ? n : ex.text.size());
        std::istream in(&mb);
        ok = OpenMesh::IO::IOManager().read(in, mesh__ext_name(fmt), rec, opt);
    }
    if (!ok)
        return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh could not read this %s file", mesh__ext_name(fmt) + 1);
    size_t nfaces = rec.start.size() - 1;
    if ((ex.nverts >= 0 && rec.verts.size() != size_t(ex.nverts)) ||
        (ex.nfaces >= 0 && nfaces + rec.short_faces != size_t(ex.nfaces)))
        return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh read %zu vertices and %zu faces, the file has %lld and %lld",
                          rec.verts.size(), nfaces, ex.nverts, ex.nfaces);

    /* Handle index -> position in the reader's vertex order. */
    const size_t nh = mesh.n_vertices();
    std::vector<uint32_t> remap(nh, UINT32_MAX);
    std::vector<double> pos(3 * rec.verts.size());
    for (size_t i = 0; i < rec.verts.size(); i++) {
        OpenMesh::VertexHandle vh(rec.verts[i]);
        if (!vh.is_valid() || size_t(rec.verts[i]) >= nh)
            return mesh__fail(err, RR_ERR_INTERNAL, path, "OpenMesh returned an invalid vertex handle");
        remap[size_t(rec.verts[i])] = uint32_t(i);
        const mesh__poly::Point &p = mesh.point(vh);
        pos[3 * i] = p[0];
        pos[3 * i + 1] = p[1];
        pos[3 * i + 2] = p[2];
    }
    if (ex.probe) {
        const double *a = &pos[0], *b = &pos[pos.size() - 3];
        for (int k = 0; k < 3; k++)
            if (float(a[k]) != ex.first[k] || float(b[k]) != ex.last[k])
                return mesh__fail(err, RR_ERR_PARSE, path, "OpenMesh misread the vertex data of this PLY file");
    }
    std::vector<uint32_t> idx(rec.idx.size());
    std::vector<unsigned char> used(rec.verts.size(), 0);
    for (size_t i = 0; i < rec.idx.size(); i++) {
        int h = rec.idx[i];
        if (h < 0 || size_t(h) >= nh || remap[size_t(h)] == UINT32_MAX)
            return mesh__fail(err, RR_ERR_PARSE, path, "a face refers to a vertex that does not exist");
        idx[i] = remap[size_t(h)];
        used[idx[i]] = 1;
    }

    /* Normals only when the file has them for every vertex a face uses. */
    std::vector<double> nrm;
    if (opt.vertex_has_normal() && !rec.has_normal.empty()) {
        nrm.assign(3 * rec.verts.size(), 0.0);
        for (size_t i = 0; i < rec.verts.size() && !nrm.empty(); i++) {
            size_t h = size_t(rec.verts[i]);
            if (h < rec.has_normal.size() && rec.has_normal[h]) {
                memcpy(&nrm[3 * i], &rec.normals[3 * h], 3 * sizeof(double));
            } else if (used[i]) {
                nrm.clear();
            } else {
                nrm[3 * i + 2] = 1.0; /* no triangle uses it: any unit vector will do */
            }
        }
    }

    mesh__soup soup;
    soup.pos = pos.data();
    soup.normals = nrm.empty() ? nullptr : nrm.data();
    soup.nverts = rec.verts.size();
    soup.start = rec.start.data();
    soup.idx = idx.data();
    soup.nfaces = nfaces;
    return mesh__from_soup(path, &soup, out, err);
}

} // namespace

extern "C" rr_status mesh_load(const char *path, mesh_tri **out, rr_error *err)
{
    if (!path || !out)
        return rr_error_set(err, RR_ERR_INVALID, "mesh_load: NULL argument");
    try {
        return mesh__load(path, out, err);
    } catch (const std::bad_alloc &) {
        return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
    } catch (const std::exception &e) {
        return mesh__fail(err, RR_ERR_INTERNAL, path, "mesh reader failed: %s", e.what());
    } catch (...) {
        return mesh__fail(err, RR_ERR_INTERNAL, path, "mesh reader failed");
    }
}
