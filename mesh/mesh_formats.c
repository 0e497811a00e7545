/* mesh_formats.c - strict pre-checks of mesh files, before OpenMesh reads them
 * (see mesh_internal.h and the top of mesh_openmesh.cpp).
 *
 * OpenMesh 9.0's readers are permissive in ways that matter: a truncated or
 * malformed line is skipped or read as stale values, "nan" in a text file
 * silently stops its iostream, a PLY header without end_header loops forever,
 * a truncated binary STL is taken for ASCII, an out-of-range OBJ index writes
 * out of bounds. So every count, index and coordinate is validated here, and
 * OpenMesh only ever sees input it handles correctly. Each check mirrors what
 * the OpenMesh reader will do with the same bytes.
 */
#include "mesh_internal.h"

#include <ctype.h>
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

rr_status mesh__fail(rr_error *err, rr_status code, const char *path, const char *fmt, ...)
{
    char msg[RR_ERROR_MSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return rr_error_set(err, code, "%s: %s", path, msg);
}

void mesh__expect_free(mesh__expect *ex)
{
    free(ex->text);
    ex->text = NULL;
}

/* ---- text scanning ---- */

int mesh__eq(mesh__sv a, const char *s) { return a.n == strlen(s) && memcmp(a.p, s, a.n) == 0; }

static int mesh__ieq(mesh__sv a, const char *s)
{
    if (a.n != strlen(s))
        return 0;
    for (size_t i = 0; i < a.n; i++)
        if (tolower((unsigned char)a.p[i]) != tolower((unsigned char)s[i]))
            return 0;
    return 1;
}

int mesh__space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v'; }

mesh__sv mesh__trim(mesh__sv s)
{
    while (s.n && mesh__space(s.p[0]))
        s.p++, s.n--;
    while (s.n && mesh__space(s.p[s.n - 1]))
        s.n--;
    return s;
}

/* Pops the next whitespace-separated token of *s into *t. */
int mesh__token(mesh__sv *s, mesh__sv *t)
{
    size_t i = 0, j;
    while (i < s->n && mesh__space(s->p[i]))
        i++;
    for (j = i; j < s->n && !mesh__space(s->p[j]);)
        j++;
    t->p = s->p + i;
    t->n = j - i;
    s->p += j;
    s->n -= j;
    return t->n != 0;
}

int mesh__line(mesh__lines *L, mesh__sv *line)
{
    if (L->p >= L->end)
        return 0;
    const char *e = memchr(L->p, '\n', (size_t)(L->end - L->p));
    if (!e)
        e = L->end;
    line->p = L->p;
    line->n = (size_t)(e - L->p);
    L->p = e < L->end ? e + 1 : L->end;
    L->no++;
    return 1;
}

/* A decimal number as iostreams (and so OpenMesh) read it. nan/inf parse, so
 * that the caller can name them; hex floats do not (iostreams would stop at
 * the 'x' and OpenMesh read a different number than strtod). */
int mesh__number(mesh__sv t, double *v)
{
    char buf[64];
    if (t.n == 0 || t.n >= sizeof buf)
        return 0;
    memcpy(buf, t.p, t.n);
    buf[t.n] = '\0';
    const char *body = buf + (buf[0] == '+' || buf[0] == '-');
    int special = strncasecmp(body, "nan", 3) == 0 || strncasecmp(body, "inf", 3) == 0;
    for (size_t i = 0; i < t.n && !special; i++)
        if (!isdigit((unsigned char)buf[i]) && !strchr("+-.eE", buf[i]))
            return 0;
    char *e;
    *v = strtod(buf, &e);
    return e == buf + t.n;
}

int mesh__integer(mesh__sv t, long long *v)
{
    char buf[32];
    if (t.n == 0 || t.n >= sizeof buf)
        return 0;
    for (size_t i = 0; i < t.n; i++)
        if (!isdigit((unsigned char)t.p[i]) && !(i == 0 && (t.p[i] == '-' || t.p[i] == '+')))
            return 0;
    memcpy(buf, t.p, t.n);
    buf[t.n] = '\0';
    errno = 0;
    char *e;
    *v = strtoll(buf, &e, 10);
    return errno == 0 && e == buf + t.n;
}

/* OpenMesh stores points as float: a finite double beyond FLT_MAX would come
 * back infinite, so it is refused by name here. */
const char *mesh__bad_coord(double v)
{
    if (!isfinite(v))
        return "a non-finite coordinate";
    if (fabs(v) > FLT_MAX)
        return "a coordinate beyond single precision";
    return NULL;
}

/* File text quoted in a message: printable, one line, at most 40 bytes. */
const char *mesh__q(mesh__sv t, char out[48])
{
    size_t n = t.n < 40 ? t.n : 40;
    for (size_t i = 0; i < n; i++)
        out[i] = isprint((unsigned char)t.p[i]) ? t.p[i] : '?';
    strcpy(out + n, t.n > 40 ? "..." : "");
    return out;
}

/* Text formats never contain NUL bytes: one means binary garbage (and would
 * cut OpenMesh's line parsing short). */
int mesh__is_text(const char *buf, size_t n) { return memchr(buf, '\0', n) == NULL; }

/* Reads up to 3 numbers of a vertex-like line into v; returns how many. */
static int mesh__coords(mesh__sv *rest, double v[3])
{
    mesh__sv t;
    for (int k = 0; k < 3; k++)
        if (!mesh__token(rest, &t) || !mesh__number(t, &v[k]))
            return k;
    return 3;
}

/* The first three numbers of line as OpenMesh's iostreams read them into
 * floats (strtof rounds the decimal text once, as they do). */
static void mesh__probe(mesh__sv line, float out[3])
{
    mesh__sv t;
    char buf[64];
    for (int k = 0; k < 3; k++) {
        mesh__token(&line, &t);
        size_t n = t.n < sizeof buf - 1 ? t.n : sizeof buf - 1;
        memcpy(buf, t.p, n);
        buf[n] = '\0';
        out[k] = strtof(buf, NULL);
    }
}

/* ---- OBJ ---- */

/* One face corner: i, i/t, i//n or i/t/n. OpenMesh reads the parts with an
 * unchecked int, so anything else is refused. */
static rr_status mesh__obj_corner(const char *path, size_t line, mesh__sv t, long long nv, long long nn, rr_error *err)
{
    mesh__sv part[3];
    int np = 0;
    char q[48];
    for (mesh__sv rest = t;; rest.p++, rest.n--) {
        const char *slash = memchr(rest.p, '/', rest.n);
        if (np == 3)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: bad face corner '%s'", line, mesh__q(t, q));
        part[np].p = rest.p;
        part[np].n = slash ? (size_t)(slash - rest.p) : rest.n;
        np++;
        if (!slash)
            break;
        rest.n -= (size_t)(slash - rest.p);
        rest.p = slash;
    }
    const long long count[3] = {nv, -1, nn};
    for (int k = 0; k < np; k++) {
        long long idx;
        if (k == 1 && part[k].n == 0 && np == 3)
            continue; /* i//n */
        if (!mesh__integer(part[k], &idx) || idx == 0)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: bad face corner '%s'", line, mesh__q(t, q));
        if (count[k] >= 0 && (idx > count[k] || -idx > count[k]))
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face refers to %s %lld, but only %lld are defined before it",
                              line, k == 0 ? "vertex" : "normal", idx, count[k]);
    }
    return RR_OK;
}

static rr_status mesh__check_obj(const char *path, const char *buf, size_t n, mesh__expect *ex, rr_error *err)
{
    if (!mesh__is_text(buf, n))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OBJ file (binary data)");
    mesh__lines L = {buf, buf + n, 0};
    mesh__sv line, key, t;
    long long nv = 0, nn = 0, nf = 0;
    while (mesh__line(&L, &line)) {
        line = mesh__trim(line);
        if (line.n == 0 || line.p[0] == '#' || !mesh__token(&line, &key))
            continue;
        double v[3];
        if (mesh__eq(key, "v") || mesh__eq(key, "vn")) {
            int normal = mesh__eq(key, "vn");
            const char *what = normal ? "normal" : "vertex";
            if (mesh__coords(&line, v) != 3)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: %s needs three numbers (truncated?)", L.no, what);
            for (int k = 0; k < 3; k++) {
                const char *why = mesh__bad_coord(v[k]);
                if (why)
                    return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: %s %lld has %s", L.no, what,
                                      normal ? nn : nv, why);
            }
            *(normal ? &nn : &nv) += 1;
        } else if (mesh__eq(key, "vt")) {
            /* OpenMesh aborts the whole read on a "vt" it cannot parse. */
            if (mesh__coords(&line, v) < 2)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: texture coordinate needs two numbers", L.no);
        } else if (mesh__eq(key, "f")) {
            int corners = 0;
            for (; mesh__token(&line, &t) && t.p[0] != '#'; corners++) {
                rr_status st = mesh__obj_corner(path, L.no, t, nv, nn, err);
                if (st)
                    return st;
            }
            if (corners < 3)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face has fewer than 3 vertices (truncated?)", L.no);
            nf++;
        }
    }
    if (nf == 0)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    ex->nverts = nv; /* faces: OpenMesh drops repeated corners, which can drop a face */
    return RR_OK;
}

/* ---- OFF ---- */

/* Appends to the growable ex->text. */
static int mesh__append(mesh__expect *ex, size_t *cap, const char *p, size_t n)
{
    if (ex->text_len + n + 1 > *cap) {
        size_t want = 2 * (*cap + n + 1);
        char *t = realloc(ex->text, want);
        if (!t)
            return 0;
        ex->text = t;
        *cap = want;
    }
    memcpy(ex->text + ex->text_len, p, n);
    ex->text_len += n;
    ex->text[ex->text_len] = '\0';
    return 1;
}

/* Next line with content, skipping blank lines and comments. */
static int mesh__content(mesh__lines *L, mesh__sv *out)
{
    while (mesh__line(L, out)) {
        *out = mesh__trim(*out);
        if (out->n && out->p[0] != '#')
            return 1;
    }
    return 0;
}

static rr_status mesh__check_off(const char *path, const char *buf, size_t n, mesh__expect *ex, rr_error *err)
{
    if (!mesh__is_text(buf, n))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file (binary data)");
    mesh__lines L = {buf, buf + n, 0};
    mesh__sv line, t;
    char q[48];
    if (!mesh__content(&L, &line) || !mesh__token(&line, &t))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file");
    /* [ST][C][N]OFF: what each vertex line carries besides its point. */
    mesh__sv kw = t;
    int normals = 0;
    if (kw.n >= 2 && kw.p[0] == 'S' && kw.p[1] == 'T')
        kw.p += 2, kw.n -= 2;
    if (kw.n && kw.p[0] == 'C')
        kw.p++, kw.n--;
    if (kw.n && kw.p[0] == 'N')
        kw.p++, kw.n--, normals = 1;
    if (!mesh__eq(kw, "OFF"))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file (header '%s')", mesh__q(t, q));
    long long cnt[3];
    for (int k = 0; k < 3; k++) {
        while (!mesh__token(&line, &t))
            if (!mesh__content(&L, &line))
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file: no vertex and face counts (truncated?)");
        if (k == 0 && mesh__eq(t, "BINARY"))
            /* OpenMesh's binary OFF reader trusts every count and reads past
             * the end; there is no way to vouch for its result. */
            return mesh__fail(err, RR_ERR_PARSE, path, "binary OFF is not supported (convert it to ASCII OFF or PLY)");
        if (!mesh__integer(t, &cnt[k]) || cnt[k] < 0 || cnt[k] > (long long)UINT32_MAX)
            return mesh__fail(err, RR_ERR_PARSE, path, "not a valid OFF file: bad count '%s'", mesh__q(t, q));
    }
    const long long nv = cnt[0], nf = cnt[1];
    /* OpenMesh wants the keyword alone on the first line, reads every value
     * with >> (a comment or a trailing word derails all that follows), guesses
     * colours from the number of words, and in stream mode ignores the
     * header's N flag. So it gets a canonical copy: "OFF", the counts, and per
     * line only the point or the face's indices. (NOFF normals are checked but
     * not returned.) */
    size_t cap = 0;
    char head[64];
    int hn = snprintf(head, sizeof head, "OFF\n%lld %lld 0\n", nv, nf);
    if (!mesh__append(ex, &cap, head, (size_t)hn))
        return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
    for (long long i = 0; i < nv; i++) {
        double v[3];
        if (!mesh__content(&L, &line))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid OFF file: it ends after %lld of its %lld vertices (truncated?)", i, nv);
        mesh__sv rest = line;
        if (mesh__coords(&rest, v) != 3)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: vertex %lld needs three numbers", L.no, i);
        for (int k = 0; k < 3; k++) {
            const char *why = mesh__bad_coord(v[k]);
            if (why)
                return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: vertex %lld has %s", L.no, i, why);
        }
        if (!mesh__append(ex, &cap, line.p, (size_t)(rest.p - line.p)) || !mesh__append(ex, &cap, "\n", 1))
            return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
        if (normals && mesh__coords(&rest, v) != 3)
            return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: vertex %lld needs a normal", L.no, i);
        if (i == 0 || i == nv - 1)
            mesh__probe(line, i == 0 ? ex->first : ex->last);
    }
    for (long long f = 0; f < nf; f++) {
        long long k, idx;
        if (!mesh__content(&L, &line))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid OFF file: it ends after %lld of its %lld faces (truncated?)", f, nf);
        const char *start = line.p;
        if (!mesh__token(&line, &t) || !mesh__integer(t, &k) || k < 3 || k > nv)
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "line %zu: face %lld needs a vertex count from 3 to the number of vertices", L.no, f);
        for (long long j = 0; j < k; j++) {
            if (!mesh__token(&line, &t) || !mesh__integer(t, &idx))
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face %lld has fewer than %lld vertices (truncated?)",
                                  L.no, f, k);
            if (idx < 0 || idx >= nv)
                return mesh__fail(err, RR_ERR_PARSE, path, "line %zu: face %lld refers to vertex %lld, but the file has %lld",
                                  L.no, f, idx, nv);
        }
        if (!mesh__append(ex, &cap, start, (size_t)(line.p - start)) || !mesh__append(ex, &cap, "\n", 1))
            return mesh__fail(err, RR_ERR_NOMEM, path, "out of memory");
    }
    if (nf == 0)
        return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
    ex->nverts = nv;
    ex->nfaces = nf;
    ex->probe = nv > 0; /* OpenMesh's OFF reader keeps header flags between files */
    return RR_OK;
}

/* ---- STL ---- */

static float mesh__le_float(const unsigned char *p)
{
    uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static rr_status mesh__check_stl(const char *path, const char *buf, size_t n, mesh__expect *ex, rr_error *err)
{
    const unsigned char *u = (const unsigned char *)buf;
    /* OpenMesh's own test: binary exactly when the size matches the count in
     * the header (a binary header may well start with "solid"). */
    if (n >= 84) {
        uint64_t ntri = (uint64_t)u[80] | (uint64_t)u[81] << 8 | (uint64_t)u[82] << 16 | (uint64_t)u[83] << 24;
        if (84 + 50 * ntri == n) {
            for (uint64_t i = 0; i < ntri; i++)
                for (int k = 3; k < 12; k++) {
                    const char *why = mesh__bad_coord(mesh__le_float(u + 84 + 50 * i + 4 * k));
                    if (why)
                        return mesh__fail(err, RR_ERR_INVALID, path, "triangle %llu has %s", (unsigned long long)i, why);
                }
            if (ntri == 0)
                return mesh__fail(err, RR_ERR_INVALID, path, "no triangles");
            ex->binary = 1;
            return RR_OK;
        }
        if (!mesh__is_text(buf, n))
            return mesh__fail(err, RR_ERR_PARSE, path,
                              "not a valid binary STL file: its header announces %llu triangles (%llu bytes) but the "
                              "file has %zu bytes (truncated?)",
                              (unsigned long long)ntri, (unsigned long long)(84 + 50 * ntri), n);
    }
    if (!mesh__is_text(buf, n))
        return mesh__fail(err, RR_ERR_PARSE, path, "not a valid STL file (neither ASCII nor binary)");
    mesh__lines L = {buf, buf + n, 0};
    mesh__sv line, key;
    int started = 0, ended = 0;
    size_t tris = 0;
    while (mesh__line(&L, &line)) {
        /* OpenMesh takes any line containing "outer" as the start of a facet
         * and reads the next three lines as its vertices, whatever they say. */
        int outer = 0;
        for (size_t i = 0; i + 5 <= line.n && !outer; i++)
            outer = memcmp(line.p + i, "outer", 5) == 0 || memcmp(line.p + i, "OUTER", 5) == 0;
        line = mesh__trim(line);
        if (!mesh__token(&line, &key))
            continue;
        if (!started) {
            if (!mesh__ieq(key, "solid"))
                return mesh__fail(err, RR_ERR_PARSE, path, "not a valid STL file (neither ASCII nor binary)");
            started = 1;
            continue;
        }
        ended = mesh__ieq(key, "endsolid");
        if (!outer)
            continue;
        for (int k = 0; k < 3; k++) {
            double v[3];
            mesh__sv vl, vk;
            if (!mesh__line(&L, &vl) || (vl = mesh__trim(vl), !mesh__token(&vl, &vk)) || !mesh__ieq(vk, "vertex") ||
                mesh__coords(&vl, v) != 3)
                return mesh__fail(err, RR_ERR_PARSE, path,
                                  "line %zu: expected three 'vertex x y z' lines after 'outer loop' (truncated?)", L.no);
            for (int c = 0; c < 3; c++) {
                const char *why = mesh__bad_coord(v[c]);
                if (why)
                    return mesh__fail(err, RR_ERR_INVALID, path, "line %zu: vertex has %s", L.no, why);
            }
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

rr_status mesh__check(const char *path, mesh__format fmt, const char *buf, size_t n, mesh__expect *ex, rr_error *err)
{
    ex->nverts = ex->nfaces = -1;
    switch (fmt) {
    case MESH__OBJ: return mesh__check_obj(path, buf, n, ex, err);
    case MESH__OFF: return mesh__check_off(path, buf, n, ex, err);
    case MESH__STL: return mesh__check_stl(path, buf, n, ex, err);
    case MESH__PLY: return mesh__check_ply(path, buf, n, ex, err);
    }
    return mesh__fail(err, RR_ERR_INTERNAL, path, "unknown format");
}
