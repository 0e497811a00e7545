/* rad_patch.c - patches for the radiosity pass.
 *
 * Every triangle of an object is split into level^2 similar sub-triangles on
 * the grid P(i, j) = A + (i/n)(B - A) + (j/n)(C - A). One level per object
 * means two triangles that share an edge split it at the same points, and the
 * grid points are shared through a map keyed by (edge, step): no T-vertices,
 * so radiosity interpolated to vertices is continuous across the object.
 * Spheres become a UV grid (one-triangle caps at the poles). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "rad_patch_internal.h"

/* ---- the shared-vertex map: (a, b, k) -> vertex index ---- */

static uint64_t edge_hash(uint32_t a, uint32_t b, uint32_t k)
{
    return ((((uint64_t)a << 32) | b) * 0x9e3779b97f4a7c15ULL ^ ((uint64_t)k * 0xc2b2ae3d27d4eb4fULL)) | 1;
}

int rad__edge_map_init(rad__edge_map *m, size_t n)
{
    memset(m, 0, sizeof *m);
    m->cap = 16;
    while (m->cap < 2 * n + 16)
        m->cap *= 2;
    m->key = calloc(m->cap, sizeof *m->key);
    m->abk = malloc(m->cap * sizeof *m->abk);
    m->val = malloc(m->cap * sizeof *m->val);
    if (!m->key || !m->abk || !m->val) {
        rad__edge_map_free(m);
        return -1;
    }
    return 0;
}

void rad__edge_map_free(rad__edge_map *m)
{
    free(m->key);
    free(m->abk);
    free(m->val);
    memset(m, 0, sizeof *m);
}

static void edge_put(rad__edge_map *m, uint64_t h, const uint32_t abk[3], uint32_t val)
{
    size_t mask = m->cap - 1;
    size_t i = (size_t)(h >> 17) & mask;
    while (m->key[i])
        i = (i + 1) & mask;
    m->key[i] = h;
    memcpy(m->abk[i], abk, sizeof m->abk[i]);
    m->val[i] = val;
    m->count++;
}

uint32_t rad__edge_get(rad__edge_map *m, uint32_t a, uint32_t b, uint32_t k, uint32_t val)
{
    uint64_t h = edge_hash(a, b, k);
    size_t mask = m->cap - 1;
    for (size_t i = (size_t)(h >> 17) & mask; m->key[i]; i = (i + 1) & mask)
        if (m->key[i] == h && m->abk[i][0] == a && m->abk[i][1] == b && m->abk[i][2] == k)
            return m->val[i];
    if (2 * (m->count + 1) > m->cap) { /* keep the load under 1/2 */
        rad__edge_map old = *m;
        m->cap = old.cap * 2;
        m->count = 0;
        m->key = calloc(m->cap, sizeof *m->key);
        m->abk = malloc(m->cap * sizeof *m->abk);
        m->val = malloc(m->cap * sizeof *m->val);
        if (!m->key || !m->abk || !m->val) {
            rad__edge_map_free(m);
            *m = old;
            return UINT32_MAX;
        }
        for (size_t i = 0; i < old.cap; i++)
            if (old.key[i])
                edge_put(m, old.key[i], old.abk[i], old.val[i]);
        rad__edge_map_free(&old);
    }
    const uint32_t abk[3] = {a, b, k};
    edge_put(m, h, abk, val);
    return val;
}

uint32_t rad__edge_find(const rad__edge_map *m, uint32_t a, uint32_t b, uint32_t k)
{
    uint64_t h = edge_hash(a, b, k);
    size_t mask = m->cap - 1;
    for (size_t i = (size_t)(h >> 17) & mask; m->key[i]; i = (i + 1) & mask)
        if (m->key[i] == h && m->abk[i][0] == a && m->abk[i][1] == b && m->abk[i][2] == k)
            return m->val[i];
    return UINT32_MAX;
}

/* ---- building ---- */

static double tri_area(rr_vec3 a, rr_vec3 b, rr_vec3 c) { return 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(b, a), rr_v3_sub(c, a))); }

static uint32_t level_for(double area, double longest, const rad_patch_opts *o)
{
    double n1 = ceil(sqrt(area / o->max_area)), n2 = ceil(longest / o->max_edge);
    double n = fmax(1.0, fmax(n1, n2));
    return n > 65535.0 ? 65535u : (uint32_t)n;
}

static void fill_patch(rad_patches *P, size_t k, uint32_t a, uint32_t b, uint32_t c, const scene_material *m,
                       uint32_t obj, int64_t tri)
{
    rad_patch *p = &P->p[k];
    p->v[0] = a;
    p->v[1] = b;
    p->v[2] = c;
    rr_vec3 A = P->verts[a], B = P->verts[b], C = P->verts[c];
    rr_vec3 n = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
    p->area = 0.5 * rr_v3_len(n);
    p->normal = rr_v3_norm(n);
    p->centroid = rr_v3_scale(rr_v3_add(rr_v3_add(A, B), C), 1.0 / 3.0);
    p->rho = m->diffuse;
    p->mirror = rr_rgb_mean(m->mirror);
    p->emission = rr_rgb_scale(m->emission, RR_PI);
    p->object = obj;
    p->flat = tri >= 0;
    p->tri = tri;
}

/* Sphere grid: stacks S (theta from the +z pole), slices L = 2S (phi). */
static size_t sphere_patch_count(uint32_t S) { return (size_t)2 * S * (2 * S) - 2 * (size_t)(2 * S); }

static rr_vec3 sphere_point(const scene_object *o, uint32_t S, uint32_t i, uint32_t j)
{
    double th = RR_PI * i / S, ph = 2.0 * RR_PI * j / (2.0 * S);
    return rr_v3_add(o->center, rr_v3(o->radius * sin(th) * cos(ph), o->radius * sin(th) * sin(ph), o->radius * cos(th)));
}

/* One subdivision level per object: the smallest that brings every triangle
 * of the object under both limits (olevel: nobjects entries, zeroed). */
static void object_levels(const scene *s, const rad_patch_opts *o, uint32_t *olevel)
{
    for (size_t t = 0; t < s->ntris; t++) {
        const scene_tri *tr = &s->tris[t];
        rr_vec3 A = s->verts[tr->v[0]], B = s->verts[tr->v[1]], C = s->verts[tr->v[2]];
        double longest = fmax(rr_v3_len(rr_v3_sub(B, A)), fmax(rr_v3_len(rr_v3_sub(C, B)), rr_v3_len(rr_v3_sub(A, C))));
        uint32_t l = level_for(tri_area(A, B, C), longest, o);
        if (l > olevel[tr->object])
            olevel[tr->object] = l;
    }
}

/* Stacks of every sphere's UV grid (one for all, from the largest radius), 0
 * without spheres. The largest cells are at the equator: pi r / S on each
 * side, so a triangle has area (pi r / S)^2 / 2 and a diagonal sqrt(2) pi r /
 * S (chords are shorter still). */
static uint32_t sphere_stacks(const scene *s, const rad_patch_opts *o)
{
    double rmax = 0;
    for (size_t i = 0; i < s->nobjects; i++)
        if (rt_prim_kind_of(s, (uint32_t)i) == RT_PRIM_SPHERE)
            rmax = fmax(rmax, s->objects[i].radius);
    if (!(rmax > 0))
        return 0;
    double need = fmax(4.0, fmax(RR_PI * rmax / sqrt(2.0 * o->max_area), sqrt(2.0) * RR_PI * rmax / o->max_edge));
    return need > 4096 ? 4096u : (uint32_t)ceil(need);
}

size_t rad_patches_level_outliers(const scene *s, const rad_patch_opts *o, const rr_warn_sink *warn)
{
    uint32_t *olevel = calloc(s->nobjects ? s->nobjects : 1, sizeof *olevel);
    if (!olevel)
        return 0;
    object_levels(s, o, olevel);
    size_t warned = 0;
    for (size_t ob = 0; ob < s->nobjects; ob++) {
        const scene_object *obj = &s->objects[ob];
        uint32_t L = olevel[ob];
        if (L < 4 || obj->tri_count < 100)
            continue;
        /* The triangles that need more than a quarter of the object's level,
         * and the longest of them. */
        size_t few = 0, worst = obj->tri_first;
        uint32_t rest = 1;
        for (size_t t = obj->tri_first; t < obj->tri_first + obj->tri_count; t++) {
            const scene_tri *tr = &s->tris[t];
            rr_vec3 A = s->verts[tr->v[0]], B = s->verts[tr->v[1]], C = s->verts[tr->v[2]];
            double longest =
                fmax(rr_v3_len(rr_v3_sub(B, A)), fmax(rr_v3_len(rr_v3_sub(C, B)), rr_v3_len(rr_v3_sub(A, C))));
            uint32_t l = level_for(tri_area(A, B, C), longest, o);
            if (4 * l > L) {
                few++;
                if (l == L)
                    worst = t;
            } else if (l > rest) {
                rest = l;
            }
        }
        if (few * 100 > obj->tri_count || few > 8)
            continue; /* the object is large all over, not one outlier */
        double n = (double)obj->tri_count;
        rr_warn(warn,
                "%s: radiosity: %zu of the %zu triangles of '%s' (e.g. triangle %zu of the scene) need subdivision "
                "level %u, which every triangle of the object gets (one level per object): %.0f patches where "
                "level %u would make %.0f. If they are modelling errors (faces across the object), fix them; "
                "else put them in an object of their own",
                s->path, few, obj->tri_count, obj->name, worst, L, n * L * L, rest, n * rest * rest);
        warned++;
    }
    free(olevel);
    return warned;
}

static void free_solid_meshes(rad__solid_mesh *sm, size_t n)
{
    if (!sm)
        return;
    for (size_t i = 0; i < n; i++)
        rad__solid_mesh_free(&sm[i]);
    free(sm);
}

/* What rad_patches_build carries from one kind of primitive to the next:
 * patches and vertices are appended in the order triangles, spheres, solids. */
typedef struct build_ctx {
    const scene *s;
    const rad_patch_opts *o;
    rad_patch_opts oc;    /* o with the curved surfaces' limits (spheres, solids) */
    rad_patches *P;
    uint32_t *olevel;     /* subdivision level per object (triangles) */
    uint32_t S;           /* sphere stacks */
    rad__solid_mesh *sm;  /* per object: the tessellated solid (CSG objects) */
    size_t nv, np;        /* vertices and patches written so far */
} build_ctx;

static rad_patch_opts curved_opts(const rad_patch_opts *o)
{
    rad_patch_opts c = *o;
    if (o->curved_max_area > 0)
        c.max_area = o->curved_max_area;
    if (o->curved_max_edge > 0)
        c.max_edge = o->curved_max_edge;
    return c;
}

/* ---- per kind: how many patches, and the patches ---- */

static rr_status tri_count(build_ctx *c, uint32_t t, double *npatch, double *nvert, rr_error *err)
{
    (void)err;
    double l = c->olevel[c->s->tris[t].object];
    *npatch += l * l;
    *nvert += (l + 1) * (l + 2) / 2; /* upper bound before sharing */
    return RR_OK;
}

static rr_status sphere_count(build_ctx *c, uint32_t i, double *npatch, double *nvert, rr_error *err)
{
    (void)i;
    (void)err;
    *npatch += (double)sphere_patch_count(c->S);
    *nvert += (double)(c->S - 1) * (2.0 * c->S) + 2;
    return RR_OK;
}

/* Solids are tessellated here: their counts are known only then. */
static rr_status solid_count(build_ctx *c, uint32_t i, double *npatch, double *nvert, rr_error *err)
{
    rr_status st = rad__solid_tessellate(c->s, c->o->accel, i, &c->oc, &c->sm[i], err);
    if (st != RR_OK)
        return st;
    *npatch += (double)c->sm[i].ntris;
    *nvert += (double)c->sm[i].nverts;
    return RR_OK;
}

static double tri_estimate(const build_ctx *c, uint32_t t)
{
    return (double)c->olevel[c->s->tris[t].object] * (double)c->olevel[c->s->tris[t].object];
}

static double sphere_estimate(const build_ctx *c, uint32_t i)
{
    (void)i;
    return (double)sphere_patch_count(c->S);
}

static double solid_estimate(const build_ctx *c, uint32_t i) { return rad_solid_patch_estimate(c->s, i, &c->oc); }

/* P's arrays for npatch patches and nvert vertices; 0, or -1 when out of memory. */
static int allocate(build_ctx *c, size_t npatch, size_t nvert)
{
    const scene *s = c->s;
    rad_patches *P = c->P;
    P->n = npatch;
    P->ntris = s->ntris;
    P->p = calloc(P->n ? P->n : 1, sizeof *P->p);
    P->verts = malloc((nvert ? nvert : 1) * sizeof *P->verts);
    P->tri_first = malloc((s->ntris ? s->ntris : 1) * sizeof *P->tri_first);
    P->tri_level = malloc((s->ntris ? s->ntris : 1) * sizeof *P->tri_level);
    P->sphere_first = malloc((s->nobjects ? s->nobjects : 1) * sizeof *P->sphere_first);
    P->solid = calloc(s->nobjects ? s->nobjects : 1, sizeof *P->solid);
    P->nsolid = P->solid ? s->nobjects : 0;
    return P->p && P->verts && P->tri_first && P->tri_level && P->sphere_first && P->solid ? 0 : -1;
}

/* Grid point (i, j) of a triangle at level n (i along AB, j along AC): the
 * index of its vertex, shared with the neighbours through the corner table
 * (keyed by the corner's smoothing group, cg[3]: corners of one scene vertex
 * across smooth edges) and the edge map (points on an edge, keyed by the
 * groups of its ends); UINT32_MAX when out of memory. */
static uint32_t grid_vertex(build_ctx *c, const uint32_t vid[3], const uint32_t cg[3], uint32_t n, uint32_t i,
                            uint32_t j, uint32_t *corner, rad__edge_map *em)
{
    const scene *s = c->s;
    rad_patches *P = c->P;
    int corner_id = (i == 0 && j == 0) ? 0 : (i == n ? 1 : (j == n ? 2 : -1));
    if (corner_id >= 0) {
        uint32_t g = cg[corner_id];
        if (corner[g] == UINT32_MAX) {
            corner[g] = (uint32_t)c->nv;
            P->verts[c->nv++] = s->verts[vid[corner_id]];
        }
        return corner[g];
    }
    rr_vec3 A = s->verts[vid[0]], B = s->verts[vid[1]], C = s->verts[vid[2]];
    rr_vec3 p = rr_v3_add(A, rr_v3_add(rr_v3_scale(rr_v3_sub(B, A), (double)i / n),
                                       rr_v3_scale(rr_v3_sub(C, A), (double)j / n)));
    /* On an edge: identify it by its two ends' groups and the step counted
     * from the end with the smaller scene vertex, which both triangles
     * across a smooth edge agree on. */
    int ka, kb;
    uint32_t step;
    if (j == 0) { /* AB, step i from A */
        ka = 0, kb = 1, step = i;
    } else if (i == 0) { /* AC, step j from A */
        ka = 0, kb = 2, step = j;
    } else if (i + j == n) { /* BC, step j from B */
        ka = 1, kb = 2, step = j;
    } else {
        P->verts[c->nv] = p;
        return (uint32_t)c->nv++;
    }
    if (vid[ka] > vid[kb]) {
        int tmp = ka;
        ka = kb;
        kb = tmp;
        step = n - step;
    }
    uint32_t got = rad__edge_get(em, cg[ka], cg[kb], step, (uint32_t)c->nv);
    if (got != UINT32_MAX && got == c->nv)
        P->verts[c->nv++] = p;
    return got;
}

static uint32_t group_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

static void group_union(uint32_t *parent, uint32_t a, uint32_t b)
{
    a = group_find(parent, a);
    b = group_find(parent, b);
    if (a != b)
        parent[a > b ? a : b] = a < b ? a : b; /* the smaller root: the same groups in any order */
}

static rr_vec3 tri_normal(const scene *s, const scene_tri *t)
{
    rr_vec3 A = s->verts[t->v[0]];
    return rr_v3_norm(rr_v3_cross(rr_v3_sub(s->verts[t->v[1]], A), rr_v3_sub(s->verts[t->v[2]], A)));
}

/* Smoothing groups of the triangles' corners (parent[3 t + k], roots after
 * group_find): corners of one scene vertex are joined across every edge whose
 * two triangles (of one object) meet at less than RAD_CREASE_DEG. Patch
 * vertices are shared within a group only, so the vertex means that Gouraud
 * interpolates do not mix faces across a crease (a box's edge: the top lit,
 * the side in shadow). 0, or -1 when out of memory. */
static int smoothing_groups(const scene *s, uint32_t *parent)
{
    for (size_t i = 0; i < 3 * s->ntris; i++)
        parent[i] = (uint32_t)i;
    rad__edge_map first; /* scene edge -> the first corner (3 t + k) that starts it */
    if (rad__edge_map_init(&first, 3 * s->ntris) != 0)
        return -1;
    const double smooth_cos = cos(RAD_CREASE_DEG * RR_PI / 180.0);
    for (size_t t = 0; t < s->ntris; t++) {
        const scene_tri *tr = &s->tris[t];
        for (int k = 0; k < 3; k++) {
            uint32_t a = tr->v[k], b = tr->v[(k + 1) % 3];
            uint32_t me = (uint32_t)(3 * t + (size_t)k);
            uint32_t other = rad__edge_get(&first, a < b ? a : b, a < b ? b : a, 0, me);
            if (other == UINT32_MAX) {
                rad__edge_map_free(&first);
                return -1;
            }
            if (other == me)
                continue;
            const scene_tri *to = &s->tris[other / 3];
            if (to->object != tr->object || rr_v3_dot(tri_normal(s, tr), tri_normal(s, to)) < smooth_cos)
                continue;
            /* The other triangle's corners at a and at b. */
            uint32_t ko = other % 3, o_a = UINT32_MAX, o_b = UINT32_MAX;
            for (uint32_t q = 0; q < 3; q++) {
                uint32_t v = to->v[(ko + q) % 3];
                uint32_t id = (other / 3) * 3 + (ko + q) % 3;
                if (v == a)
                    o_a = id;
                else if (v == b)
                    o_b = id;
            }
            if (o_a == UINT32_MAX || o_b == UINT32_MAX)
                continue; /* a degenerate triangle */
            group_union(parent, me, o_a);
            group_union(parent, (uint32_t)(3 * t + (size_t)(k + 1) % 3), o_b);
        }
    }
    rad__edge_map_free(&first);
    for (size_t i = 0; i < 3 * s->ntris; i++)
        parent[i] = group_find(parent, (uint32_t)i);
    return 0;
}

/* Every scene triangle split into n^2 patches on a regular grid, n its
 * object's level; vertices on shared edges are shared. 0, or -1 when out of
 * memory. */
static int tessellate_triangles(build_ctx *c)
{
    const scene *s = c->s;
    rad_patches *P = c->P;
    /* Per corner group (3 ntris corner ids, the group's root): its patch vertex. */
    uint32_t *corner = malloc((s->ntris ? 3 * s->ntris : 1) * sizeof *corner);
    uint32_t *group = malloc((s->ntris ? 3 * s->ntris : 1) * sizeof *group);
    /* Edge points: at most 3 (l - 1) per triangle; the map is twice that. */
    size_t edge_pts = 0;
    for (size_t t = 0; t < s->ntris; t++)
        edge_pts += 3 * (size_t)(c->olevel[s->tris[t].object] - 1);
    rad__edge_map em;
    int em_ok = rad__edge_map_init(&em, edge_pts) == 0;
    uint32_t lmax = 1;
    for (size_t i = 0; i < s->nobjects; i++)
        lmax = c->olevel[i] > lmax ? c->olevel[i] : lmax;
    uint32_t *grid = malloc((size_t)(lmax + 1) * (lmax + 1) * sizeof *grid);
    int ok = corner && group && em_ok && grid && smoothing_groups(s, group) == 0;
    for (size_t i = 0; ok && i < 3 * s->ntris; i++)
        corner[i] = UINT32_MAX;
    for (size_t t = 0; ok && t < s->ntris; t++) {
        const scene_tri *tr = &s->tris[t];
        uint32_t n = c->olevel[tr->object];
        for (uint32_t j = 0; ok && j <= n; j++)
            for (uint32_t i = 0; ok && i + j <= n; i++)
                ok = (grid[i + j * (n + 1)] = grid_vertex(c, tr->v, group + 3 * t, n, i, j, corner, &em)) !=
                     UINT32_MAX;
        P->tri_first[t] = (uint32_t)c->np;
        P->tri_level[t] = n;
        const scene_material *m = &s->materials[tr->material];
        for (uint32_t j = 0; ok && j < n; j++)
            for (uint32_t i = 0; i + j < n; i++) {
                uint32_t g00 = grid[i + j * (n + 1)], g10 = grid[i + 1 + j * (n + 1)], g01 = grid[i + (j + 1) * (n + 1)];
                fill_patch(P, c->np++, g00, g10, g01, m, tr->object, (int64_t)t);
                if (i + j + 1 < n) {
                    uint32_t g11 = grid[i + 1 + (j + 1) * (n + 1)];
                    fill_patch(P, c->np++, g10, g11, g01, m, tr->object, (int64_t)t);
                }
            }
    }
    free(grid);
    free(corner);
    free(group);
    if (em_ok)
        rad__edge_map_free(&em);
    return ok ? 0 : -1;
}

/* Every analytic sphere as S stacks x 2S slices of facets (rings between
 * the poles), their areas scaled to the true sphere's. */
/* Patches [first, end) of one curved object (a sphere's facets, a solid's
 * triangles) scaled so that their areas sum to area, the true surface's:
 * each patch stands for its share of it, so that what it emits and takes in
 * agrees with the rays, which meet the true surface. Left as they are when
 * area is not positive (not measured). */
static void scale_to_area(rad_patches *P, size_t first, size_t end, double area)
{
    double facets = 0.0;
    for (size_t k = first; k < end; k++)
        facets += P->p[k].area;
    double scale = facets > 0 && area > 0 ? area / facets : 1.0;
    for (size_t k = first; k < end; k++)
        P->p[k].area *= scale;
}

static int tessellate_spheres(build_ctx *c)
{
    const scene *s = c->s;
    rad_patches *P = c->P;
    uint32_t S = c->S, L = 2 * S;
    P->sphere_stacks = S;
    P->sphere_slices = L;
    for (size_t oi = 0; oi < s->nobjects; oi++) {
        const scene_object *ob = &s->objects[oi];
        P->sphere_first[oi] = UINT32_MAX;
        if (rt_prim_kind_of(s, (uint32_t)oi) != RT_PRIM_SPHERE)
            continue;
        /* Vertices: north pole, rings 1..S-1, south pole. */
        uint32_t base = (uint32_t)c->nv;
        P->verts[c->nv++] = sphere_point(ob, S, 0, 0);
        for (uint32_t i = 1; i < S; i++)
            for (uint32_t j = 0; j < L; j++)
                P->verts[c->nv++] = sphere_point(ob, S, i, j);
        P->verts[c->nv++] = sphere_point(ob, S, S, 0);
        uint32_t south = (uint32_t)c->nv - 1;
#define RV(i, j) ((i) == 0 ? base : ((i) == S ? south : base + 1 + ((i)-1) * L + ((j) % L)))
        P->sphere_first[oi] = (uint32_t)c->np;
        const scene_material *m = &s->materials[ob->material];
        for (uint32_t i = 0; i < S; i++)
            for (uint32_t j = 0; j < L; j++) {
                uint32_t a = RV(i, j), b = RV(i + 1, j), cc = RV(i + 1, j + 1), d = RV(i, j + 1);
                if (i < S - 1)
                    fill_patch(P, c->np++, a, b, cc, m, (uint32_t)oi, -1);
                if (i > 0)
                    fill_patch(P, c->np++, a, cc, d, m, (uint32_t)oi, -1);
            }
#undef RV
        /* The facets are chords of the sphere the ray tracer (and the
         * form-factor rays) meet, and have less area in all than it. */
        scale_to_area(P, P->sphere_first[oi], c->np, 4.0 * RR_PI * ob->radius * ob->radius);
    }
    return 0;
}

/* Every solid's tessellation (count_patches made it) moved into P, each
 * patch with the material of the leaf surface under its centre. */
static int tessellate_solids(build_ctx *c)
{
    const scene *s = c->s;
    rad_patches *P = c->P;
    for (size_t oi = 0; oi < s->nobjects; oi++) {
        if (rt_prim_kind_of(s, (uint32_t)oi) != RT_PRIM_SOLID)
            continue;
        rad__solid_mesh *m = &c->sm[oi];
        uint32_t vbase = (uint32_t)c->nv, pbase = (uint32_t)c->np;
        if (m->nverts) /* (an empty solid has no vertex array) */
            memcpy(P->verts + c->nv, m->verts, m->nverts * sizeof *m->verts);
        c->nv += m->nverts;
        /* The grid moves into P, with absolute patch indices. */
        P->solid[oi] = m->grid;
        m->grid.cell_first = NULL;
        if (P->solid[oi].n[0]) {
            size_t ncells = (size_t)P->solid[oi].n[0] * P->solid[oi].n[1] * P->solid[oi].n[2];
            for (size_t k = 0; k <= ncells; k++)
                P->solid[oi].cell_first[k] += pbase;
        }
        for (size_t t = 0; t < m->ntris; t++) {
            size_t np = c->np++;
            fill_patch(P, np, vbase + m->tris[t][0], vbase + m->tris[t][1], vbase + m->tris[t][2],
                       &s->materials[s->objects[oi].material], (uint32_t)oi, -1);
            P->p[np].flat = m->own && m->own[t];
            /* A curved piece is a chord (a marching triangle also cuts sharp
             * edges off: rad_solid.c), with less area than the surface the
             * rays meet (scenes/csg.json's lens 4.4 % less under marching;
             * the energy check found it 5 % short of the light tracer): each
             * stands for its share of its leaf's true area (flat pieces: 1). */
            P->p[np].area *= m->scale[t];
            rr_vec3 xs, ns;
            uint32_t leaf = m->leaf ? m->leaf[t] : UINT32_MAX;
            if (leaf != UINT32_MAX || rad__solid_surface(P, s, c->o->accel, (uint32_t)oi, P->p[np].centroid,
                                                         P->p[np].normal, &xs, &ns, &leaf)) {
                const scene_material *lm = &s->materials[s->csg[leaf].material];
                P->p[np].rho = lm->diffuse;
                P->p[np].mirror = rr_rgb_mean(lm->mirror);
                P->p[np].emission = rr_rgb_scale(lm->emission, RR_PI);
            }
        }
    }
    return 0;
}

static uint32_t tri_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p);
static uint32_t sphere_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p);
static uint32_t solid_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p);
static void tri_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x, rr_vec3 *xs,
                        rr_vec3 *ns);
static void sphere_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x,
                           rr_vec3 *xs, rr_vec3 *ns);
static void solid_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x,
                          rr_vec3 *xs, rr_vec3 *ns);

/* The radiosity pass's half of the primitive table (rt.h, rt_prims: the
 * other half), by rt_prim_kind. The kinds are tessellated in this order. */
typedef struct patch_kind {
    /* Adds primitive i's patches (and an upper bound of its vertices). */
    rr_status (*count)(build_ctx *c, uint32_t i, double *npatch, double *nvert, rr_error *err);
    /* Primitive i's patches, estimated without building anything. */
    double (*estimate)(const build_ctx *c, uint32_t i);
    /* Appends the patches of every primitive of the kind; 0, or -1 when out of memory. */
    int (*tessellate)(build_ctx *c);
    /* The patch under point p of a hit on triangle tri / object obj (rad_patch_locate). */
    uint32_t (*locate)(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p);
    /* x on patch k moved onto the true surface (rad_patch_surface). */
    void (*surface)(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x, rr_vec3 *xs,
                    rr_vec3 *ns);
} patch_kind;

static const patch_kind k_patch_kinds[RT_PRIM_KINDS] = {
    [RT_PRIM_TRIANGLE] = {tri_count, tri_estimate, tessellate_triangles, tri_locate, tri_surface},
    [RT_PRIM_SPHERE] = {sphere_count, sphere_estimate, tessellate_spheres, sphere_locate, sphere_surface},
    [RT_PRIM_SOLID] = {solid_count, solid_estimate, tessellate_solids, solid_locate, solid_surface},
};

/* Every primitive's count (triangles, then the per-object ones in object
 * order), limited to 2^31 patches. */
static rr_status count_patches(build_ctx *c, double *npatch, double *nvert, rr_error *err)
{
    const scene *s = c->s;
    *npatch = *nvert = 0;
    rr_status st = RR_OK;
    for (size_t t = 0; t < s->ntris && st == RR_OK; t++)
        st = k_patch_kinds[RT_PRIM_TRIANGLE].count(c, (uint32_t)t, npatch, nvert, err);
    for (size_t i = 0; i < s->nobjects && st == RR_OK; i++) {
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)i);
        if (k != RT_PRIM_TRIANGLE)
            st = k_patch_kinds[k].count(c, (uint32_t)i, npatch, nvert, err);
    }
    if (st != RR_OK)
        return st;
    if (*npatch > (double)(1u << 31) || *nvert > (double)(1u << 31))
        return rr_error_set(err, RR_ERR_LIMIT,
                            "%s: radiosity: the patch limits would make %.3g patches (more than 2^31); "
                            "raise the patch area/edge limits",
                            s->path, *npatch);
    return RR_OK;
}

double rad_patches_estimate(const scene *s, const rad_patch_opts *o)
{
    build_ctx c;
    memset(&c, 0, sizeof c);
    c.s = s;
    c.o = o;
    c.olevel = calloc(s->nobjects ? s->nobjects : 1, sizeof *c.olevel);
    if (!c.olevel)
        return 0.0;
    object_levels(s, o, c.olevel);
    c.oc = curved_opts(o);
    c.S = sphere_stacks(s, &c.oc);
    /* The solids' estimate asks where their leaves' pieces lie: without the
     * mesh leaves' BVHs each query walks every mesh triangle (csg.json's
     * estimate took 5.9 s so). */
    rt_accel *sa = NULL;
    if (!o->accel && s->ncsg_tris > 0 && rt_accel_build_solids(s, &sa, NULL) == RR_OK)
        c.oc.accel = sa;
    double n = 0;
    for (size_t t = 0; t < s->ntris; t++)
        n += k_patch_kinds[RT_PRIM_TRIANGLE].estimate(&c, (uint32_t)t);
    for (size_t i = 0; i < s->nobjects; i++) {
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)i);
        if (k != RT_PRIM_TRIANGLE)
            n += k_patch_kinds[k].estimate(&c, (uint32_t)i);
    }
    rt_accel_destroy(sa);
    free(c.olevel);
    return n;
}

rr_status rad_patches_build(const scene *s, const rad_patch_opts *o, rad_patches **out, rr_error *err)
{
    if (!(o->max_area > 0) || !(o->max_edge > 0) || !isfinite(o->max_area) || !isfinite(o->max_edge))
        return rr_error_set(err, RR_ERR_INVALID, "%s: radiosity: patch area and edge limits must be > 0 (got %g, %g)",
                            s->path, o->max_area, o->max_edge);
    build_ctx c;
    memset(&c, 0, sizeof c);
    c.s = s;
    c.o = o;
    c.P = calloc(1, sizeof *c.P);
    c.olevel = calloc(s->nobjects ? s->nobjects : 1, sizeof *c.olevel);
    c.sm = calloc(s->nobjects ? s->nobjects : 1, sizeof *c.sm);
    rr_status st = RR_ERR_NOMEM;
    double npatch = 0, nvert = 0;
    if (c.P && c.olevel && c.sm) {
        object_levels(s, o, c.olevel);
        c.oc = curved_opts(o);
        c.S = sphere_stacks(s, &c.oc);
        st = count_patches(&c, &npatch, &nvert, err);
    }
    if (st == RR_OK && allocate(&c, (size_t)npatch, (size_t)nvert) != 0)
        st = RR_ERR_NOMEM;
    for (int k = 0; k < RT_PRIM_KINDS && st == RR_OK; k++)
        if (k_patch_kinds[k].tessellate(&c) != 0)
            st = RR_ERR_NOMEM;
    if (st == RR_OK) {
        RR_CHECK(c.np == c.P->n);
        c.P->nverts = c.nv;
        *out = c.P;
        c.P = NULL;
    }
    if (c.sm)
        free_solid_meshes(c.sm, s->nobjects);
    free(c.olevel);
    rad_patches_destroy(c.P);
    if (st == RR_ERR_NOMEM)
        return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory building patches", s->path);
    return st;
}

void rad_patches_destroy(rad_patches *P)
{
    if (!P)
        return;
    free(P->p);
    free(P->verts);
    free(P->tri_first);
    free(P->tri_level);
    free(P->sphere_first);
    if (P->solid)
        for (size_t i = 0; i < P->nsolid; i++)
            free(P->solid[i].cell_first);
    free(P->solid);
    rad_patches_destroy(P->roots);
    free(P->qt);
    free(P->root_qt);
    free(P->mid);
    free(P);
}

/* ---- lookups ---- */

/* (u, v): p = A + u (B - A) + v (C - A), by least squares in the plane. */
static void plane_coords(rr_vec3 A, rr_vec3 B, rr_vec3 C, rr_vec3 p, double *u, double *v)
{
    rr_vec3 e1 = rr_v3_sub(B, A), e2 = rr_v3_sub(C, A), d = rr_v3_sub(p, A);
    double a11 = rr_v3_dot(e1, e1), a12 = rr_v3_dot(e1, e2), a22 = rr_v3_dot(e2, e2);
    double b1 = rr_v3_dot(e1, d), b2 = rr_v3_dot(e2, d);
    double det = a11 * a22 - a12 * a12;
    if (!(fabs(det) > 0)) {
        *u = *v = 0;
        return;
    }
    *u = (b1 * a22 - b2 * a12) / det;
    *v = (a11 * b2 - a12 * b1) / det;
}

static uint32_t tri_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p)
{
    (void)obj;
    const scene_tri *tr = &s->tris[tri];
    double u, v;
    plane_coords(s->verts[tr->v[0]], s->verts[tr->v[1]], s->verts[tr->v[2]], p, &u, &v);
    uint32_t n = P->tri_level[tri];
    double x = fmin(fmax(u * n, 0.0), (double)n), y = fmin(fmax(v * n, 0.0), (double)n);
    uint32_t j = y >= n ? n - 1 : (uint32_t)y;
    uint32_t i = x >= n ? n - 1 : (uint32_t)x;
    if (i + j > n - 1)
        i = n - 1 - j;
    double fx = x - i, fy = y - j;
    int down = fx + fy > 1.0 && i + j + 1 < n;
    /* Rows before j hold (2(n - j') - 1) patches each: j (2n - j) in all. */
    uint32_t idx = j * (2 * n - j) + 2 * i + (uint32_t)down;
    return P->tri_first[tri] + idx;
}

static uint32_t solid_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p)
{
    (void)s;
    (void)tri;
    return rad__solid_locate(P, obj, p);
}

static uint32_t sphere_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p)
{
    (void)tri;
    const scene_object *o = &s->objects[obj];
    uint32_t S = P->sphere_stacks, L = P->sphere_slices;
    rr_vec3 d = rr_v3_scale(rr_v3_sub(p, o->center), 1.0 / o->radius);
    double th = acos(fmin(1.0, fmax(-1.0, d.z))), ph = atan2(d.y, d.x);
    if (ph < 0)
        ph += 2.0 * RR_PI;
    double y = th / RR_PI * S, x = ph / (2.0 * RR_PI) * L;
    uint32_t i = y >= S ? S - 1 : (uint32_t)y, j = x >= L ? L - 1 : (uint32_t)x;
    double fy = y - i, fx = x - j;
    /* Row 0 and row S-1 hold one triangle per cell, the others two (abc, acd). */
    uint32_t first = P->sphere_first[obj];
    if (i == 0)
        return first + j;
    uint32_t row = L + (i - 1) * 2 * L;
    if (i == S - 1)
        return first + row + j;
    (void)fx;
    (void)fy;
    /* The diagonal a-c projects radially onto the great circle through a and
     * c, so the side of that circle's plane is exact where the (theta, phi)
     * diagonal is not. */
    const rad_patch *q = &P->p[first + row + 2 * j];
    rr_vec3 a = rr_v3_sub(P->verts[q->v[0]], o->center), c = rr_v3_sub(P->verts[q->v[2]], o->center);
    rr_vec3 b = rr_v3_sub(P->verts[q->v[1]], o->center);
    double side_p = rr_v3_dot(rr_v3_cross(a, c), rr_v3_sub(p, o->center));
    double side_b = rr_v3_dot(rr_v3_cross(a, c), b);
    return first + row + 2 * j + ((side_p > 0) == (side_b > 0) ? 0u : 1u);
}

/* The leaf of a hierarchical patch set under p: its root patch, then down the
 * quadtree by barycentrics (b[] of the node's corners A, B, C). A corner child
 * takes the points with b >= 1/2 at its corner, the middle child the rest;
 * each step maps b to the child's corners (rad.h, rad_patches.qt). */
static uint32_t hier_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p)
{
    const rad_patches *R = P->roots;
    rt_prim_kind kind = tri >= 0 ? RT_PRIM_TRIANGLE : rt_prim_kind_of(s, obj);
    uint32_t r = k_patch_kinds[kind].locate(R, s, tri, obj, p);
    if (r >= R->n)
        return UINT32_MAX;
    double b[3];
    rad_patch_barycentric(R, r, p, b);
    uint32_t e = P->root_qt[r];
    while (!(e & RAD_QT_LEAF)) {
        int c = 3;
        double best = 0.5;
        for (int k = 0; k < 3; k++)
            if (b[k] >= best) {
                best = b[k];
                c = k;
            }
        if (c < 3) {
            for (int k = 0; k < 3; k++)
                b[k] = k == c ? 2.0 * b[k] - 1.0 : 2.0 * b[k];
        } else {
            /* The middle child's corners are the midpoints bc, ca, ab. */
            for (int k = 0; k < 3; k++)
                b[k] = 1.0 - 2.0 * b[k];
        }
        e = P->qt[4 * (size_t)e + (size_t)c];
    }
    return e & ~RAD_QT_LEAF;
}

uint32_t rad_patch_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p)
{
    if (P->roots)
        return hier_locate(P, s, tri, obj, p);
    rt_prim_kind k = tri >= 0 ? RT_PRIM_TRIANGLE : rt_prim_kind_of(s, obj);
    return k_patch_kinds[k].locate(P, s, tri, obj, p);
}

void rad_patch_barycentric(const rad_patches *P, uint32_t k, rr_vec3 p, double b[3])
{
    const rad_patch *q = &P->p[k];
    double u, v;
    plane_coords(P->verts[q->v[0]], P->verts[q->v[1]], P->verts[q->v[2]], p, &u, &v);
    b[0] = 1.0 - u - v;
    b[1] = u;
    b[2] = v;
}

static void tri_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x, rr_vec3 *xs,
                        rr_vec3 *ns)
{
    (void)s;
    (void)a;
    *xs = x;
    *ns = P->p[k].normal;
}

static void solid_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x,
                          rr_vec3 *xs, rr_vec3 *ns)
{
    const rad_patch *q = &P->p[k];
    rad__solid_surface(P, s, a, q->object, x, q->normal, xs, ns, NULL);
}

static void sphere_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x,
                           rr_vec3 *xs, rr_vec3 *ns)
{
    (void)a;
    const rad_patch *q = &P->p[k];
    const scene_object *o = &s->objects[q->object];
    rr_vec3 d = rr_v3_norm(rr_v3_sub(x, o->center));
    *xs = rr_v3_madd(o->center, d, o->radius);
    *ns = rr_v3_dot(d, q->normal) >= 0.0 ? d : rr_v3_neg(d);
}

void rad_patch_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x, rr_vec3 *xs,
                       rr_vec3 *ns)
{
    const rad_patch *q = &P->p[k];
    rt_prim_kind kind = q->flat ? RT_PRIM_TRIANGLE : rt_prim_kind_of(s, q->object);
    k_patch_kinds[kind].surface(P, s, a, k, x, xs, ns);
}
