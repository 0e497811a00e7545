/* mesh.c - the pure C half of the mesh module (see mesh.h): building and
 * freeing triangle meshes, triangle areas, the topology report, and turning
 * the loader's polygon soup (mesh_internal.h) into triangles.
 *
 * Everything that scales with the mesh is sort-based, O(n log n): meshes can
 * have millions of triangles, so nothing here compares all pairs of anything.
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Ear clipping costs about k^2 point-in-ear tests for a k-corner polygon
 * (k ear tests of k points each), more when many corners are tried before an
 * ear is found; past this many tests for one polygon (about 0.1 s) what is
 * left of it is fanned, so that no polygon can make loading run away (a
 * 3,458-corner face was ear-clipped in 0.05 s; pathological shapes of any
 * size stop at the budget). */
#define MESH__EAR_TESTS_MAX (1u << 26)

/* ---- allocation ---- */

static void *mesh__malloc_array(size_t n, size_t size)
{
    if (size != 0 && n > SIZE_MAX / size)
        return NULL;
    /* malloc(0) may return NULL, which would look like a failure. */
    return malloc(n != 0 && size != 0 ? n * size : 1);
}

static mesh_tri *mesh__alloc(size_t nverts, size_t ntris, int with_normals)
{
    if (nverts > SIZE_MAX / 3 || ntris > SIZE_MAX / 3)
        return NULL;
    mesh_tri *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    m->nverts = nverts;
    m->ntris = ntris;
    m->pos = mesh__malloc_array(3 * nverts, sizeof *m->pos);
    m->tris = mesh__malloc_array(3 * ntris, sizeof *m->tris);
    if (with_normals)
        m->normals = mesh__malloc_array(3 * nverts, sizeof *m->normals);
    if (!m->pos || !m->tris || (with_normals && !m->normals)) {
        mesh_destroy(m);
        return NULL;
    }
    return m;
}

void mesh_destroy(mesh_tri *m)
{
    if (!m)
        return;
    free(m->pos);
    free(m->normals);
    free(m->tris);
    free(m);
}

/* Index of the first vertex with a non-finite coordinate, or n if none. */
static size_t mesh__first_nonfinite(const double *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[3 * i]) || !isfinite(v[3 * i + 1]) || !isfinite(v[3 * i + 2]))
            return i;
    return n;
}

/* Normalises n normals in place. Returns 0, or 1 with *bad set to the first
 * zero-length normal (nothing sensible to scale it to). Callers check
 * finiteness first. */
static int mesh__normalize(double *nrm, size_t n, size_t *bad)
{
    for (size_t i = 0; i < n; i++) {
        double *v = nrm + 3 * i;
        double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (!(len > 0.0) || !isfinite(len)) {
            *bad = i;
            return 1;
        }
        v[0] /= len;
        v[1] /= len;
        v[2] /= len;
    }
    return 0;
}

rr_status mesh_from_arrays(const double *pos, size_t nverts, const uint32_t *tris, size_t ntris,
                           const double *normals, mesh_tri **out, rr_error *err)
{
    if (!out || (nverts && !pos) || (ntris && !tris))
        return rr_error_set(err, RR_ERR_INVALID, "mesh_from_arrays: NULL array");
    if (nverts > (size_t)UINT32_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "mesh has %zu vertices, more than 32-bit indices allow", nverts);
    size_t bad = mesh__first_nonfinite(pos, nverts);
    if (bad < nverts)
        return rr_error_set(err, RR_ERR_INVALID, "vertex %zu has a non-finite coordinate", bad);
    for (size_t i = 0; i < 3 * ntris; i++)
        if (tris[i] >= nverts)
            return rr_error_set(err, RR_ERR_INVALID, "triangle %zu refers to vertex %u, but the mesh has %zu vertices",
                                i / 3, (unsigned)tris[i], nverts);
    if (normals) {
        bad = mesh__first_nonfinite(normals, nverts);
        if (bad < nverts)
            return rr_error_set(err, RR_ERR_INVALID, "normal %zu has a non-finite component", bad);
    }
    mesh_tri *m = mesh__alloc(nverts, ntris, normals != NULL);
    if (!m)
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory for a mesh of %zu vertices and %zu triangles", nverts,
                            ntris);
    if (nverts)
        memcpy(m->pos, pos, 3 * nverts * sizeof *pos);
    if (ntris)
        memcpy(m->tris, tris, 3 * ntris * sizeof *tris);
    if (normals) {
        memcpy(m->normals, normals, 3 * nverts * sizeof *normals);
        if (mesh__normalize(m->normals, nverts, &bad)) {
            mesh_destroy(m);
            return rr_error_set(err, RR_ERR_INVALID, "normal %zu has zero length", bad);
        }
    }
    *out = m;
    return RR_OK;
}

static rr_vec3 mesh__vert(const mesh_tri *m, uint32_t v)
{
    const double *p = m->pos + 3 * (size_t)v;
    return rr_v3(p[0], p[1], p[2]);
}

static rr_vec3 mesh__tri_cross(const mesh_tri *m, size_t i)
{
    const uint32_t *t = m->tris + 3 * i;
    rr_vec3 a = mesh__vert(m, t[0]);
    return rr_v3_cross(rr_v3_sub(mesh__vert(m, t[1]), a), rr_v3_sub(mesh__vert(m, t[2]), a));
}

double mesh_tri_area(const mesh_tri *m, size_t i)
{
    RR_CHECK(m != NULL && i < m->ntris);
    return 0.5 * rr_v3_len(mesh__tri_cross(m, i));
}

/* ---- topology report ---- */

typedef struct mesh__wvert {
    double p[3];
    uint32_t idx;
} mesh__wvert;

/* Total order on doubles for sorting: NaN (which mesh_from_arrays rejects, but
 * a caller may build a mesh_tri by hand) sorts last instead of breaking qsort's
 * contract. -0.0 == 0.0, so they weld, as they should. */
static int mesh__cmp_double(double a, double b)
{
    if (a < b)
        return -1;
    if (a > b)
        return 1;
    return (isnan(a) != 0) - (isnan(b) != 0);
}

static int mesh__cmp_pos(const double *a, const double *b)
{
    for (int k = 0; k < 3; k++) {
        int c = mesh__cmp_double(a[k], b[k]);
        if (c)
            return c;
    }
    return 0;
}

static int mesh__cmp_wvert(const void *pa, const void *pb)
{
    const mesh__wvert *a = pa, *b = pb;
    int c = mesh__cmp_pos(a->p, b->p);
    if (c)
        return c;
    /* Ties by index, so that each position's representative is its lowest
     * index and the result does not depend on qsort's stability. */
    return (a->idx > b->idx) - (a->idx < b->idx);
}

/* weld[v] = lowest index of a vertex at exactly v's position. */
static uint32_t *mesh__weld(const mesh_tri *m)
{
    mesh__wvert *w = mesh__malloc_array(m->nverts, sizeof *w);
    uint32_t *weld = mesh__malloc_array(m->nverts, sizeof *weld);
    if (!w || !weld) {
        free(w);
        free(weld);
        return NULL;
    }
    for (size_t i = 0; i < m->nverts; i++) {
        memcpy(w[i].p, m->pos + 3 * i, sizeof w[i].p);
        w[i].idx = (uint32_t)i;
    }
    qsort(w, m->nverts, sizeof *w, mesh__cmp_wvert);
    uint32_t rep = 0;
    for (size_t i = 0; i < m->nverts; i++) {
        if (i == 0 || mesh__cmp_pos(w[i].p, w[i - 1].p) != 0)
            rep = w[i].idx;
        weld[w[i].idx] = rep;
    }
    free(w);
    return weld;
}

/* One vertex of the result of mesh_weld: a welded position seen by faces
 * whose normals are within the crease angle of n. */
typedef struct mesh__wcand {
    double n[3];
    uint32_t idx, next; /* new index; next candidate at the same position */
} mesh__wcand;

/* Index of the candidate at position rep whose normal is within cos_max of
 * n (a zero n, a degenerate face, takes the first), a new one if none. */
static uint32_t mesh__wfind(uint32_t *head, mesh__wcand *cand, size_t *ncand, uint32_t rep, const double *n,
                            double cos_max)
{
    int zero = n[0] == 0 && n[1] == 0 && n[2] == 0;
    for (uint32_t c = head[rep]; c != UINT32_MAX; c = cand[c].next)
        if (zero || cand[c].n[0] * n[0] + cand[c].n[1] * n[1] + cand[c].n[2] * n[2] >= cos_max)
            return c;
    uint32_t c = (uint32_t)(*ncand)++;
    memcpy(cand[c].n, n, sizeof cand[c].n);
    cand[c].idx = c;
    cand[c].next = head[rep];
    head[rep] = c;
    return c;
}

rr_status mesh_weld(mesh_tri *m, double crease_deg, rr_error *err)
{
    if (m->ntris > UINT32_MAX / 3)
        return rr_error_set(err, RR_ERR_LIMIT, "mesh_weld: too many triangles (%zu)", m->ntris);
    uint32_t *weld = mesh__weld(m), *head = mesh__malloc_array(m->nverts, sizeof *head);
    uint32_t *src = mesh__malloc_array(3 * m->ntris, sizeof *src); /* new vertex -> old vertex */
    mesh__wcand *cand = mesh__malloc_array(3 * m->ntris, sizeof *cand);
    mesh_tri *out = NULL;
    rr_status st = RR_OK;
    if (!weld || !head || !src || !cand) {
        st = rr_error_set(err, RR_ERR_NOMEM, "out of memory welding %zu vertices", m->nverts);
        goto done;
    }
    for (size_t v = 0; v < m->nverts; v++)
        head[v] = UINT32_MAX;
    double cos_max = cos(crease_deg * (RR_PI / 180.0));
    size_t ncand = 0;
    for (size_t t = 0; t < m->ntris; t++) {
        rr_vec3 c = mesh__tri_cross(m, t);
        double len = rr_v3_len(c), n[3] = {0, 0, 0};
        if (len > 0)
            n[0] = c.x / len, n[1] = c.y / len, n[2] = c.z / len;
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->tris[3 * t + k];
            size_t before = ncand;
            uint32_t w = mesh__wfind(head, cand, &ncand, weld[v], n, cos_max);
            if (ncand != before)
                src[w] = v;
            m->tris[3 * t + k] = w;
        }
    }
    out = mesh__alloc(ncand, 0, m->normals != NULL);
    if (!out) {
        st = rr_error_set(err, RR_ERR_NOMEM, "out of memory welding %zu vertices", m->nverts);
        goto done;
    }
    for (size_t w = 0; w < ncand; w++) {
        memcpy(out->pos + 3 * w, m->pos + 3 * (size_t)src[w], 3 * sizeof *out->pos);
        if (m->normals)
            memcpy(out->normals + 3 * w, m->normals + 3 * (size_t)src[w], 3 * sizeof *out->normals);
    }
    free(m->pos);
    free(m->normals);
    m->pos = out->pos, m->normals = out->normals, m->nverts = ncand;
    free(out->tris);
    free(out);
done:
    free(weld);
    free(head);
    free(src);
    free(cand);
    return st;
}

/* One directed use of an undirected edge {lo, hi}: key = lo << 32 | hi. */
typedef struct mesh__edge {
    uint64_t key;
    uint32_t forward; /* 1 when the triangle walks lo -> hi */
} mesh__edge;

static int mesh__cmp_edge(const void *pa, const void *pb)
{
    const mesh__edge *a = pa, *b = pb;
    return (a->key > b->key) - (a->key < b->key);
}

rr_status mesh_analyze(const mesh_tri *m, mesh_report *rep, rr_error *err)
{
    if (!m || !rep)
        return rr_error_set(err, RR_ERR_INVALID, "mesh_analyze: NULL argument");
    memset(rep, 0, sizeof *rep);
    if (m->ntris > SIZE_MAX / 3)
        return rr_error_set(err, RR_ERR_LIMIT, "mesh has too many triangles to analyse");
    /* A mesh_tri may be built by hand: check indices before using them. */
    for (size_t i = 0; i < 3 * m->ntris; i++)
        if (m->tris[i] >= m->nverts)
            return rr_error_set(err, RR_ERR_INVALID, "triangle %zu refers to vertex %u, but the mesh has %zu vertices",
                                i / 3, (unsigned)m->tris[i], m->nverts);
    uint32_t *weld = mesh__weld(m);
    mesh__edge *edges = mesh__malloc_array(3 * m->ntris, sizeof *edges);
    if (!weld || !edges) {
        free(weld);
        free(edges);
        return rr_error_set(err, RR_ERR_NOMEM, "out of memory analysing a mesh of %zu triangles", m->ntris);
    }
    size_t nedges = 0;
    for (size_t i = 0; i < m->ntris; i++) {
        const uint32_t *t = m->tris + 3 * i;
        uint32_t v[3] = {weld[t[0]], weld[t[1]], weld[t[2]]};
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) {
            /* A repeated vertex has no surface and its "edges" would include a
             * loop and a doubled edge: count it and keep it out of the edges. */
            rep->degenerate_tris++;
            continue;
        }
        rr_vec3 c = mesh__tri_cross(m, i);
        if (c.x == 0.0 && c.y == 0.0 && c.z == 0.0)
            rep->degenerate_tris++; /* collinear: still part of the surface's connectivity */
        for (int k = 0; k < 3; k++) {
            uint32_t a = v[k], b = v[(k + 1) % 3];
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            edges[nedges].key = (uint64_t)lo << 32 | hi;
            edges[nedges].forward = a < b;
            nedges++;
        }
    }
    free(weld);
    qsort(edges, nedges, sizeof *edges, mesh__cmp_edge);
    for (size_t i = 0; i < nedges;) {
        size_t j = i, fwd = 0;
        while (j < nedges && edges[j].key == edges[i].key)
            fwd += edges[j++].forward;
        size_t uses = j - i;
        if (uses == 1)
            rep->boundary_edges++;
        else if (uses >= 3)
            rep->nonmanifold_edges++;
        else if (fwd != 1)
            rep->misoriented_edges++; /* both uses walk the same way */
        i = j;
    }
    free(edges);
    rep->watertight = rep->boundary_edges == 0 && rep->nonmanifold_edges == 0;
    rep->consistently_oriented = rep->misoriented_edges == 0;
    return RR_OK;
}

/* ---- polygon soup -> triangles ---- */

/* Twice the signed area of 2D triangle (a, b, c). */
static double mesh__orient2(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Ear clipping state for one polygon: its vertices projected to 2D (uv,
 * oriented so that the polygon winds counter-clockwise) and a circular doubly
 * linked list of the corners not yet clipped. */
typedef struct mesh__poly {
    const uint32_t *idx;
    size_t k;
    double *uv;
    size_t *prev, *next;
} mesh__poly;

/* Projects the polygon onto the coordinate plane most parallel to it (the one
 * across the largest component of its Newell normal). Returns 0 when the
 * polygon has no area at all, in which case there is nothing to clip. */
static int mesh__project(const double *pos, mesh__poly *p)
{
    double n[3] = {0, 0, 0};
    for (size_t i = 0; i < p->k; i++) {
        const double *a = pos + 3 * (size_t)p->idx[i], *b = pos + 3 * (size_t)p->idx[(i + 1) % p->k];
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    int ax = fabs(n[0]) >= fabs(n[1]) && fabs(n[0]) >= fabs(n[2]) ? 0 : (fabs(n[1]) >= fabs(n[2]) ? 1 : 2);
    if (!(fabs(n[ax]) > 0.0))
        return 0;
    /* Cyclic (u, v) = (ax+1, ax+2) keeps a polygon whose normal points along
     * +ax counter-clockwise; flip v otherwise. */
    int u = (ax + 1) % 3, v = (ax + 2) % 3;
    double flip = n[ax] > 0 ? 1.0 : -1.0;
    for (size_t i = 0; i < p->k; i++) {
        const double *a = pos + 3 * (size_t)p->idx[i];
        p->uv[2 * i] = a[u];
        p->uv[2 * i + 1] = flip * a[v];
    }
    return 1;
}

/* Whether corner b (between a and c) is an ear; *tests counts the points tried. */
static int mesh__is_ear(const mesh__poly *p, size_t a, size_t b, size_t c, size_t *tests)
{
    const double *pa = p->uv + 2 * a, *pb = p->uv + 2 * b, *pc = p->uv + 2 * c;
    if (!(mesh__orient2(pa, pb, pc) > 0.0))
        return 0; /* reflex or flat corner */
    for (size_t i = p->next[c]; i != a; i = p->next[i]) {
        ++*tests;
        const double *q = p->uv + 2 * i;
        /* A corner repeated at the same position (polygons touching
         * themselves) does not block the ear. */
        if ((q[0] == pa[0] && q[1] == pa[1]) || (q[0] == pb[0] && q[1] == pb[1]) || (q[0] == pc[0] && q[1] == pc[1]))
            continue;
        if (mesh__orient2(pa, pb, q) >= 0.0 && mesh__orient2(pb, pc, q) >= 0.0 && mesh__orient2(pc, pa, q) >= 0.0)
            return 0;
    }
    return 1;
}

static uint32_t *mesh__emit(uint32_t *t, const mesh__poly *p, size_t a, size_t b, size_t c)
{
    t[0] = p->idx[a];
    t[1] = p->idx[b];
    t[2] = p->idx[c];
    return t + 3;
}

/* Writes the k - 2 triangles of polygon p to t, keeping its winding. Starting
 * at corner 1 makes a convex polygon come out as the fan (0,1,2), (0,2,3)...,
 * the same split OpenMesh itself would make. */
static uint32_t *mesh__triangulate(const double *pos, mesh__poly *p, uint32_t *t)
{
    size_t k = p->k;
    for (size_t i = 0; i < k; i++) {
        p->prev[i] = (i + k - 1) % k;
        p->next[i] = (i + 1) % k;
    }
    size_t left = k, cur = 1, misses = 0, tests = 0;
    int clip = k > 3 && mesh__project(pos, p);
    while (clip && left > 3 && tests < MESH__EAR_TESTS_MAX) {
        size_t a = p->prev[cur], c = p->next[cur];
        if (mesh__is_ear(p, a, cur, c, &tests)) {
            t = mesh__emit(t, p, a, cur, c);
            p->next[a] = c;
            p->prev[c] = a;
            left--;
            cur = c;
            misses = 0;
        } else if (++misses > left) {
            break; /* self-intersecting or flat: no ear left, fan the rest */
        } else {
            cur = c;
        }
    }
    /* Fan over what remains (all of it when not clipping). */
    size_t first = p->prev[cur];
    for (size_t i = p->next[first]; p->next[i] != first; i = p->next[i])
        t = mesh__emit(t, p, first, i, p->next[i]);
    return t;
}

rr_status mesh__from_soup(const char *path, const mesh__soup *s, mesh_tri **out, rr_error *err)
{
    if (s->nfaces == 0)
        return rr_error_set(err, RR_ERR_INVALID, "%s: no triangles", path);
    if (s->nverts > (size_t)UINT32_MAX)
        return rr_error_set(err, RR_ERR_LIMIT, "%s: %zu vertices, more than 32-bit indices allow", path, s->nverts);
    size_t bad = mesh__first_nonfinite(s->pos, s->nverts);
    if (bad < s->nverts)
        return rr_error_set(err, RR_ERR_INVALID, "%s: vertex %zu has a non-finite coordinate", path, bad);
    if (s->normals) {
        bad = mesh__first_nonfinite(s->normals, s->nverts);
        if (bad < s->nverts)
            return rr_error_set(err, RR_ERR_INVALID, "%s: vertex %zu has a non-finite normal", path, bad);
    }
    size_t ntris = 0, kmax = 0;
    for (size_t f = 0; f < s->nfaces; f++) {
        size_t k = s->start[f + 1] - s->start[f];
        RR_CHECK(k >= 3);
        ntris += k - 2;
        kmax = k > kmax ? k : kmax;
    }
    mesh_tri *m = mesh__alloc(s->nverts, ntris, s->normals != NULL);
    mesh__poly p = {0};
    p.uv = mesh__malloc_array(2 * kmax, sizeof *p.uv);
    p.prev = mesh__malloc_array(kmax, sizeof *p.prev);
    p.next = mesh__malloc_array(kmax, sizeof *p.next);
    rr_status st = RR_OK;
    if (!m || !p.uv || !p.prev || !p.next) {
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory for %zu vertices and %zu triangles", path, s->nverts,
                          ntris);
        goto done;
    }
    memcpy(m->pos, s->pos, 3 * s->nverts * sizeof *m->pos);
    if (s->normals) {
        memcpy(m->normals, s->normals, 3 * s->nverts * sizeof *m->normals);
        if (mesh__normalize(m->normals, s->nverts, &bad)) {
            /* Some files write (0,0,0) for "no normal": then the file's normals
             * cannot be trusted as a whole, and face normals are the fallback. */
            free(m->normals);
            m->normals = NULL;
        }
    }
    uint32_t *t = m->tris;
    for (size_t f = 0; f < s->nfaces; f++) {
        p.idx = s->idx + s->start[f];
        p.k = s->start[f + 1] - s->start[f];
        t = mesh__triangulate(s->pos, &p, t);
    }
    RR_CHECK(t == m->tris + 3 * ntris);
    *out = m;
    m = NULL;
done:
    mesh_destroy(m);
    free(p.uv);
    free(p.prev);
    free(p.next);
    return st;
}
