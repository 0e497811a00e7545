/* rad_solid.c - patches on solids (CSG trees and quadrics).
 *
 * A solid's surface is pieced together from its leaves' surfaces, and only
 * the parts that lie on the final solid count. Clipping every leaf surface
 * against every other exactly would need a case analysis per pair of leaf
 * kinds; instead each leaf's own surface is split on a grid of its
 * parameters (a mesh's triangles, a box's or clip box's faces, a sphere,
 * an ellipsoid, a surface of revolution: rad_solid_own.c) and each piece
 * is kept or dropped by the ray tracer's
 * own boundary test at sample points on it, pieces that straddle a seam
 * split again down to an eighth of a cell. The patches are then the true
 * surface's pieces: flat ones exactly (mesh triangles, faces: rad_patch.flat),
 * curved ones as chords, and no sharp edge is cut off.
 *
 * A solid with a general quadric leaf (no parametric form here) is
 * tessellated from its inside test alone, by marching tetrahedra, as all
 * solids were before 2026-12-06:
 *
 *  - a grid over the solid's bounding box (cells about the patch edge limit
 *    across), the inside test rt_csg_contains at every grid point;
 *  - every cell split into the 6 tetrahedra of the Kuhn triangulation (all
 *    share the cell's main diagonal), which is conforming across cells, so
 *    the surface comes out closed with shared vertices (no T-vertices; the
 *    vertex radiosity interpolates continuously);
 *  - a tetrahedron whose corners disagree gives one or two triangles, with
 *    their corners on the tetrahedron's edges, placed on the surface by
 *    bisection of the inside test (to 2^-30 of the edge), oriented from the
 *    inside corners to the outside ones;
 *  - mesh leaves still get their own triangles (the marching triangles on
 *    them dropped).
 * What marching gives up: features smaller than a cell may be missed, and
 * sharp edges of the solid (where two leaf surfaces meet) are cut off by a
 * chamfer about a cell wide (a pedestal a cell high was mostly chamfer).
 *
 * Either way the chords have less area than the surface the rays meet, so
 * each leaf's true area on the solid is measured (group_areas, by Crofton's
 * formula) and its curved pieces scaled to it (area_scales; rad_patch.c
 * applies the scale).
 *
 * Patches are sorted by the cell of a grid over the solid's box, so the
 * patches near a point are found through the grid (rad_patch_locate). A
 * patch takes the material of the leaf it is a piece of (a marching
 * triangle: of the leaf surface under its centre, found along its normal
 * by rad_patch_surface).
 */
#include <stdlib.h>
#include <string.h>

#include "rad_solid_internal.h"

#define SOLID_CELLS_MAX 160 /* per axis */
#define SOLID_CELLS_MIN 6
#define SOLID_BISECT 30


/* Cells per axis and their size for object obj's solid under limits o. The
 * box is padded by a fraction of a cell so that flat faces of the solid (a
 * box leaf, a clip plane) do not lie exactly on grid planes. */
static int solid_grid(const scene *s, uint32_t obj, const rad_patch_opts *o, rr_vec3 *lo, rr_vec3 *cell, uint32_t n[3])
{
    const scene_csg_node *root = &s->csg[s->objects[obj].csg_root];
    rr_vec3 blo = root->bbox_lo, bhi = root->bbox_hi;
    if (!(blo.x <= bhi.x && blo.y <= bhi.y && blo.z <= bhi.z))
        return 0;
    /* Marching tetrahedra make about 9 triangles per cell face of surface
     * (measured: 42,888 patches for 13.25 units of area on cells of 0.053),
     * so cells of 3 sqrt(max_area) give about the patch count the area limit
     * asks for; the edge limit caps the cell, but a triangle's edges may
     * reach a cell diagonal: for solids both limits are targets, not bounds. */
    double h = fmin(o->max_edge, 3.0 * sqrt(o->max_area));
    double e[3] = {bhi.x - blo.x, bhi.y - blo.y, bhi.z - blo.z};
    double emax = fmax(e[0], fmax(e[1], e[2]));
    if (!(emax > 0))
        return 0;
    double l[3], c[3];
    for (int k = 0; k < 3; k++) {
        double m = ceil(e[k] / h) + 1.0;
        m = fmin(fmax(m, SOLID_CELLS_MIN), SOLID_CELLS_MAX);
        n[k] = (uint32_t)m;
        /* Pad by 0.37 of a cell on each side (an odd fraction, so no grid
         * plane meets a face at a round coordinate). */
        double ek = fmax(e[k], 1e-9 * emax);
        c[k] = ek / (m - 0.74);
        l[k] = (k == 0 ? blo.x : (k == 1 ? blo.y : blo.z)) - 0.37 * c[k];
    }
    *lo = rr_v3(l[0], l[1], l[2]);
    *cell = rr_v3(c[0], c[1], c[2]);
    return 1;
}

double rad_solid_patch_estimate(const scene *s, uint32_t obj, const rad_patch_opts *o)
{
    rr_vec3 lo, cell;
    uint32_t n[3];
    if (!solid_grid(s, obj, o, &lo, &cell, n))
        return 0;
    /* Every leaf with its own pieces: those counted (rad_solid_own.c). */
    double own = rad__solid_own_estimate(s, o->accel, obj, fmin(cell.x, fmin(cell.y, cell.z)), o);
    if (own >= 0.0)
        return own;
    /* Marching tetrahedra: the surface crosses at most about (area of the box faces) / (cell
     * face) cells, with about 9 triangles per cell face of surface. */
    double a = (double)n[0] * n[1] + (double)n[1] * n[2] + (double)n[2] * n[0];
    double est = 2.0 * 9.0 * a;
    /* Mesh leaves add their own triangles, each split to the limits
     * (rad_solid_own.c), and twice as many again for the rims' splits. */
    for (uint32_t l = 0; l < s->ncsg; l++) {
        const scene_csg_node *nd = &s->csg[l];
        if (nd->object != obj || nd->op != SCENE_CSG_LEAF || nd->solid != SCENE_SOLID_MESH)
            continue;
        for (size_t t = nd->tri_first; t < nd->tri_first + nd->tri_count; t++) {
            const uint32_t *v = s->csg_tris[t];
            rr_vec3 A = s->csg_verts[v[0]], B = s->csg_verts[v[1]], C = s->csg_verts[v[2]];
            double L = rad__solid_mesh_level(A, B, C, o);
            est += 3.0 * L * L;
        }
    }
    return est;
}

/* Kuhn triangulation: the 6 monotone paths from corner 0 to corner 7 (bit 0:
 * +x, bit 1: +y, bit 2: +z). Faces between cells are split along the same
 * diagonal from both sides. */
static const int k_tets[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7}, {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};


static uint32_t gid(const rad__tess *T, uint32_t i, uint32_t j, uint32_t k)
{
    return i + (T->n[0] + 1) * (j + (T->n[1] + 1) * k);
}

static rr_vec3 gpos(const rad__tess *T, uint32_t id)
{
    uint32_t nx = T->n[0] + 1, ny = T->n[1] + 1;
    uint32_t i = id % nx, j = (id / nx) % ny, k = id / (nx * ny);
    return rr_v3(T->lo.x + i * T->cell.x, T->lo.y + j * T->cell.y, T->lo.z + k * T->cell.z);
}

int rad__solid_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t c = *cap ? *cap : 256;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, c * elem);
    if (!q)
        return -1;
    *p = q;
    *cap = c;
    return 0;
}

/* The surface point on grid edge (a inside, b outside): bisection. */
static rr_vec3 edge_point(const rad__tess *T, uint32_t a, uint32_t b)
{
    rr_vec3 pin = gpos(T, a), pout = gpos(T, b);
    for (int it = 0; it < SOLID_BISECT; it++) {
        rr_vec3 m = rr_v3_scale(rr_v3_add(pin, pout), 0.5);
        if (rt_csg_contains(T->s, T->a, T->root, m))
            pin = m;
        else
            pout = m;
    }
    return rr_v3_scale(rr_v3_add(pin, pout), 0.5);
}

/* The vertex on grid edge (a, b), one per edge whichever tetrahedron asks. */
static int edge_vertex(rad__tess *T, uint32_t a, uint32_t b, uint32_t *out)
{
    uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
    uint32_t v = (uint32_t)T->out->nverts;
    uint32_t got = rad__edge_get(&T->map, lo, hi, 0, v);
    if (got == UINT32_MAX)
        return -1;
    if (got == v) {
        if (rad__solid_grow((void **)&T->out->verts, &T->cap_v, T->out->nverts + 1, sizeof *T->out->verts))
            return -1;
        rr_vec3 p = T->inside[a] ? edge_point(T, a, b) : edge_point(T, b, a);
        T->out->verts[T->out->nverts++] = p;
        /* Whose surface the vertex is on: the boundary crossing the grid
         * edge there. */
        if (rad__solid_grow((void **)&T->vgroup, &T->cap_g, T->out->nverts, sizeof *T->vgroup))
            return -1;
        rr_vec3 A = gpos(T, a), d = rr_v3_sub(gpos(T, b), A);
        double t = rr_v3_dot(rr_v3_sub(p, A), d) / rr_v3_len2(d);
        rt_span_end e;
        T->vgroup[v] = VG_NONE;
        if (rad__solid_nearest_end(T->s, T->a, T->s->csg[T->root].object, rr_v3_madd(A, d, t), d, 1.0, &e)) {
            if (T->s->csg[e.leaf].solid == SCENE_SOLID_MESH)
                T->vgroup[v] = VG_MESH;
            else
                T->vgroup[v] = T->slot[e.leaf] != UINT32_MAX ? T->slot[e.leaf] : VG_NONE;
        }
    }
    *out = got;
    return 0;
}

/* Appends triangle (a, b, c), turned so that its normal points away from
 * `inward` (a point on the inside side); zero-area triangles (two corners at
 * the same surface point) are left out. */
static int emit(rad__tess *T, uint32_t a, uint32_t b, uint32_t c, rr_vec3 inward)
{
    rr_vec3 A = T->out->verts[a], B = T->out->verts[b], C = T->out->verts[c];
    rr_vec3 n = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
    double h2 = rr_v3_len2(T->cell);
    if (!(rr_v3_len(n) > 1e-12 * h2))
        return 0;
    rr_vec3 ctr = rr_v3_scale(rr_v3_add(rr_v3_add(A, B), C), 1.0 / 3.0);
    if (rr_v3_dot(n, rr_v3_sub(ctr, inward)) < 0) {
        uint32_t t = b;
        b = c;
        c = t;
    }
    if (rad__solid_grow((void **)&T->out->tris, &T->cap_t, T->out->ntris + 1, sizeof *T->out->tris))
        return -1;
    uint32_t *t = T->out->tris[T->out->ntris++];
    t[0] = a;
    t[1] = b;
    t[2] = c;
    return 0;
}

static int march_tet(rad__tess *T, const uint32_t g[4])
{
    uint32_t in[4], out[4];
    int nin = 0, nout = 0;
    rr_vec3 cin = rr_v3(0, 0, 0);
    for (int k = 0; k < 4; k++) {
        if (T->inside[g[k]]) {
            in[nin++] = g[k];
            cin = rr_v3_add(cin, gpos(T, g[k]));
        } else {
            out[nout++] = g[k];
        }
    }
    if (nin == 0 || nout == 0)
        return 0;
    cin = rr_v3_scale(cin, 1.0 / nin);
    uint32_t v[4];
    if (nin == 1 || nout == 1) {
        /* One corner alone on its side: the triangle across its three edges. */
        uint32_t lone = nin == 1 ? in[0] : out[0];
        const uint32_t *others = nin == 1 ? out : in;
        for (int k = 0; k < 3; k++)
            if (edge_vertex(T, lone, others[k], &v[k]))
                return -1;
        return emit(T, v[0], v[1], v[2], cin);
    }
    /* Two and two: a quadrilateral in0-out0, in0-out1, in1-out1, in1-out0
     * (consecutive corners share a tetrahedron face), split along a diagonal. */
    if (edge_vertex(T, in[0], out[0], &v[0]) || edge_vertex(T, in[0], out[1], &v[1]) ||
        edge_vertex(T, in[1], out[1], &v[2]) || edge_vertex(T, in[1], out[0], &v[3]))
        return -1;
    if (emit(T, v[0], v[1], v[2], cin) || emit(T, v[0], v[2], v[3], cin))
        return -1;
    return 0;
}

/* The area of object obj's solid surface, as the ray tracer meets it, by
 * the Cauchy-Crofton formula: the area is 1 / pi times the integral, over
 * line directions u on a hemisphere and over the plane across u, of the
 * number of times the line crosses the surface. The lines run through an
 * AREA_GRID x AREA_GRID grid over a square of side 2R across the bounding
 * sphere (centre c, radius R: lines outside it miss the solid), for
 * AREA_DIRS directions spread evenly over the hemisphere (spherical
 * Fibonacci points: z uniform, phi by the golden angle), each direction's
 * grid shifted by a fraction of a cell (the R2 sequence) so that no two
 * directions sample the same lines: area = 8 R^2 mean(crossings).
 * Directions matter more than lines per direction (a lens, whose projection
 * changes fast with u: 64 x 64^2 lines +0.30 %, 1024 x 16^2 +0.02 %, the
 * same count; scenes/csg.json's solids within 0.1 % of their converged
 * values), 0.01-0.1 s a solid on 2 cores. Deterministic: the directions in
 * parallel, summed in order. */
enum { AREA_DIRS = 1024, AREA_GRID = 16 };

/* The true area of each group of surfaces of the solid (rad__tess.slot), into
 * area[0 .. T->ngroups); mesh leaves' crossings are not counted (their
 * parts are their own triangles, below). Integer counts summed per thread,
 * so the result does not depend on the thread count. 0 when the solid's box
 * is empty or not finite (the triangles then keep their area). */
static int group_areas(const rad__tess *T, double *area)
{
    const scene *s = T->s;
    const scene_csg_node *root = &s->csg[T->root];
    uint32_t obj = root->object, ng = T->ngroups;
    rr_vec3 lo = root->bbox_lo, hi = root->bbox_hi;
    rr_vec3 c = rr_v3_scale(rr_v3_add(lo, hi), 0.5);
    double R = 0.5 * rr_v3_len(rr_v3_sub(hi, lo)) * (1.0 + 1e-6);
    if (!(R > 0) || !isfinite(R) || ng == 0)
        return 0;
    long *cross = calloc(ng, sizeof *cross);
    if (!cross)
        return -1;
    int bad = 0;
#pragma omp parallel
    {
        long *mine = calloc(ng, sizeof *mine);
        if (!mine) {
#pragma omp atomic write
            bad = 1;
        }
#pragma omp for schedule(dynamic, 16)
        for (int i = 0; i < AREA_DIRS; i++) {
            if (!mine)
                continue;
            double z = (i + 0.5) / AREA_DIRS, r = sqrt(1.0 - z * z), ph = 2.399963229728653 * i;
            rr_vec3 u = rr_v3(r * cos(ph), r * sin(ph), z);
            rr_vec3 e1 = rr_v3_norm(rr_v3_cross(u, fabs(u.x) < 0.9 ? rr_v3(1, 0, 0) : rr_v3(0, 1, 0)));
            rr_vec3 e2 = rr_v3_cross(u, e1);
            double fx = fmod(0.7548776662466927 * (i + 1), 1.0), fy = fmod(0.5698402909980532 * (i + 1), 1.0);
            for (int j = 0; j < AREA_GRID; j++)
                for (int k = 0; k < AREA_GRID; k++) {
                    double px = (2.0 * (j + fx) / AREA_GRID - 1.0) * R, py = (2.0 * (k + fy) / AREA_GRID - 1.0) * R;
                    rr_ray ray = {rr_v3_add(c, rr_v3_add(rr_v3_scale(e1, px), rr_v3_scale(e2, py))), u};
                    rt_spans sp;
                    rt_solid_spans(s, T->a, obj, ray, -2.0 * R, 2.0 * R, &sp);
                    for (int q = 0; q < sp.n; q++) {
                        const rt_span_end *e[2] = {&sp.s[q].in, &sp.s[q].out};
                        for (int w = 0; w < 2; w++) {
                            uint32_t l = e[w]->leaf;
                            if (e[w]->t > -2.0 * R && e[w]->t < 2.0 * R && T->slot[l] != UINT32_MAX)
                                mine[T->slot[l]]++;
                        }
                    }
                }
        }
        if (mine) {
#pragma omp critical(rad_solid_area)
            for (uint32_t g = 0; g < ng; g++)
                cross[g] += mine[g];
        }
        free(mine);
    }
    for (uint32_t g = 0; g < ng; g++)
        area[g] = 8.0 * R * R * (double)cross[g] / ((double)AREA_DIRS * AREA_GRID * AREA_GRID);
    free(cross);
    return bad ? -1 : 1;
}

int rad__solid_nearest_end(const scene *s, const rt_accel *a, uint32_t obj, rr_vec3 x, rr_vec3 n, double r,
                           rt_span_end *end)
{
    rt_spans sp;
    rr_ray ray = {x, n};
    rt_solid_spans(s, a, obj, ray, -r, r, &sp);
    double bt = INFINITY;
    const rt_span_end *be = NULL;
    for (int k = 0; k < sp.n; k++) {
        const rt_span_end *e[2] = {&sp.s[k].in, &sp.s[k].out};
        for (int q = 0; q < 2; q++)
            if (e[q]->t > -r && e[q]->t < r && fabs(e[q]->t) < fabs(bt)) {
                bt = e[q]->t;
                be = e[q];
            }
    }
    if (!be)
        return 0;
    *end = *be;
    return 1;
}

/* Each triangle's group: the one most of its corners lie on (the first
 * corner's of the most, in a tie), not counting corners on mesh leaves or
 * not found, with VG_SEAM when a corner is on a mesh leaf; VG_MESH when
 * none is on a group but one is on a mesh leaf, VG_NONE when none is
 * on either. NULL when out of memory. */
static uint32_t *tri_groups(const rad__tess *T)
{
    const rad__solid_mesh *out = T->out;
    uint32_t *g = malloc((out->ntris + 1) * sizeof *g);
    if (!g)
        return NULL;
    for (size_t q = 0; q < out->ntris; q++) {
        uint32_t v[3], best = VG_NONE;
        int nmesh = 0, most = 0;
        for (int k = 0; k < 3; k++) {
            v[k] = T->vgroup[out->tris[q][k]];
            nmesh += v[k] == VG_MESH;
        }
        for (int k = 0; k < 3; k++) {
            if (v[k] >= VG_MESH)
                continue;
            int n = (v[0] == v[k]) + (v[1] == v[k]) + (v[2] == v[k]);
            if (n > most) {
                most = n;
                best = v[k];
            }
        }
        g[q] = nmesh == 3 || (nmesh > 0 && best == VG_NONE) ? VG_MESH : (nmesh > 0 ? best | VG_SEAM : best);
    }
    return g;
}

/* Each triangle's area scale (out->scale) and whether it is a mesh leaf's
 * own (out->own, only for solids with mesh leaves). The marching triangles
 * are chords of the curved faces with the sharp edges cut off, so they have
 * less area than the surface the rays meet, and not in the same proportion
 * on every leaf: each leaf's triangles are scaled to its true area
 * (group_areas), the triangles of no leaf (and the area of leaves that got
 * none) shared out in proportion over all. A mesh leaf's own triangles are
 * its true surface (scale 1). 0, or -1 when out of memory.
 * Per leaf, not per face: a chamfer across a sharp edge between two faces
 * of one leaf (a cylinder's cap and side) counts for the face most of its
 * corners lie on, and its light is the edge's, not that face's: scaling
 * each face to its own truth moved a cylinder pedestal's (on a floor, lit
 * from above) taken-in power from +2.4 % to +11.7 % of the light
 * tracer's. Between leaves the chamfers are fewer, and a small leaf's (a
 * bite out of a mesh) would otherwise be scaled with the rest: +10 %. */
static int area_scales(rad__tess *T, const uint32_t *tgroup)
{
    rad__solid_mesh *out = T->out;
    uint32_t ng = T->ngroups;
    size_t nt = out->ntris;
    double *truth = calloc(ng + 1, sizeof *truth), *mt = calloc(ng + 1, sizeof *mt), *flat = calloc(ng + 1, sizeof *flat);
    out->scale = malloc((nt + 1) * sizeof *out->scale);
    out->own = T->meshes || T->all_own ? malloc(nt + 1) : NULL;
    int got = truth && mt && flat ? group_areas(T, truth) : -1;
    if (got < 0 || !out->scale || ((T->meshes || T->all_own) && !out->own)) {
        free(truth);
        free(mt);
        free(flat);
        return -1;
    }
    /* Per triangle: a flat own piece (a mesh leaf's, VG_MESH, or a face's)
     * keeps its area; the others are scaled by their group. */
    for (size_t q = 0; q < nt; q++) {
        rr_vec3 A = out->verts[out->tris[q][0]], B = out->verts[out->tris[q][1]], C = out->verts[out->tris[q][2]];
        double a = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
        uint32_t g = tgroup[q];
        if (g < ng)
            mt[g] += a;
        else if (g != VG_MESH && g != VG_NONE && (g & VG_FACE))
            flat[g & ~VG_FACE] += a;
        out->scale[q] = a; /* (the area, for now) */
    }
    /* What each group's scaled triangles stand for: its true area less its
     * flat faces' pieces (a box leaf: nothing, up to the measure's noise).
     * Groups measured and tessellated are scaled to it; the rest keep their
     * area, and all of it is then scaled by f, to give the groups that got
     * no triangles their area too. */
    double covered = 0.0, rest = 0.0, total = 0.0;
    for (uint32_t g = 0; g < ng; g++) {
        truth[g] -= flat[g];
        if (!(truth[g] > 1e-3 * (truth[g] + flat[g])))
            truth[g] = 0.0;
        total += truth[g];
        if (got > 0 && truth[g] > 0 && mt[g] > 0)
            covered += truth[g];
    }
    for (size_t q = 0; q < nt; q++) {
        uint32_t g = tgroup[q];
        if (g == VG_NONE || (g < ng && !(got > 0 && truth[g] > 0 && mt[g] > 0)))
            rest += out->scale[q];
    }
    double f = got > 0 && covered + rest > 0 ? (total + rest) / (covered + rest) : 1.0;
    for (size_t q = 0; q < nt; q++) {
        uint32_t g = tgroup[q];
        int own = g == VG_MESH || (g != VG_NONE && g >= ng && (g & VG_FACE));
        if (out->own)
            out->own[q] = (unsigned char)own;
        if (own)
            out->scale[q] = 1.0;
        else if (g < ng && got > 0 && truth[g] > 0 && mt[g] > 0)
            out->scale[q] = truth[g] / mt[g] * f;
        else
            out->scale[q] = got > 0 ? f : 1.0;
    }
    free(truth);
    free(mt);
    free(flat);
    return 0;
}

rr_status rad__solid_tessellate(const scene *s, const rt_accel *a, uint32_t obj, const rad_patch_opts *o,
                                rad__solid_mesh *out, rr_error *err)
{
    memset(out, 0, sizeof *out);
    rad__tess T;
    memset(&T, 0, sizeof T);
    T.s = s;
    T.a = a;
    T.root = s->objects[obj].csg_root;
    T.out = out;
    if (!solid_grid(s, obj, o, &T.lo, &T.cell, T.n))
        return RR_OK; /* empty solid: no patches */
    uint32_t *tgroup = NULL;
    T.slot = malloc((s->ncsg + 1) * sizeof *T.slot);
    if (!T.slot)
        goto nomem;
    T.all_own = 1;
    for (uint32_t l = 0; l < s->ncsg; l++) {
        T.slot[l] = UINT32_MAX;
        if (s->csg[l].object != obj || s->csg[l].op != SCENE_CSG_LEAF)
            continue;
        if (s->csg[l].solid == SCENE_SOLID_MESH)
            T.meshes = 1;
        else
            T.slot[l] = T.ngroups++;
        T.all_own &= rad__solid_leaf_parametric(&s->csg[l]);
    }
    if (getenv("RADRAY_SOLID_MARCH")) /* (for comparisons: notes/csg.md) */
        T.all_own = 0;
    out->grid.lo = T.lo;
    out->grid.cell = T.cell;
    memcpy(out->grid.n, T.n, sizeof T.n);
    size_t npts = (size_t)(T.n[0] + 1) * (T.n[1] + 1) * (T.n[2] + 1);
    size_t ncells = (size_t)T.n[0] * T.n[1] * T.n[2];
    out->grid.cell_first = calloc(ncells + 1, sizeof *out->grid.cell_first);
    if (!out->grid.cell_first)
        goto nomem;
    if (T.all_own) {
        /* Nothing to march: the leaves' own surfaces are all of it. */
        tgroup = malloc(sizeof *tgroup);
        if (!tgroup || rad__solid_own_triangles(&T, o, &tgroup) || area_scales(&T, tgroup))
            goto nomem_late;
        free(tgroup);
        free(T.slot);
        return RR_OK;
    }
    T.inside = malloc(npts);
    if (!T.inside || rad__edge_map_init(&T.map, 4 * (size_t)(T.n[0] + T.n[1] + T.n[2]) * 64))
        goto nomem;
    /* The inside test at every grid point: independent, so in parallel. */
#pragma omp parallel for schedule(dynamic, 1)
    for (long k = 0; k <= (long)T.n[2]; k++)
        for (uint32_t j = 0; j <= T.n[1]; j++)
            for (uint32_t i = 0; i <= T.n[0]; i++) {
                uint32_t id = gid(&T, i, j, (uint32_t)k);
                T.inside[id] = (unsigned char)rt_csg_contains(s, a, T.root, gpos(&T, id));
            }
    size_t c = 0;
    for (uint32_t k = 0; k < T.n[2]; k++)
        for (uint32_t j = 0; j < T.n[1]; j++)
            for (uint32_t i = 0; i < T.n[0]; i++, c++) {
                out->grid.cell_first[c] = (uint32_t)out->ntris;
                uint32_t corner[8];
                for (int q = 0; q < 8; q++)
                    corner[q] = gid(&T, i + (q & 1), j + ((q >> 1) & 1), k + ((q >> 2) & 1));
                for (int t = 0; t < 6; t++) {
                    uint32_t g[4] = {corner[k_tets[t][0]], corner[k_tets[t][1]], corner[k_tets[t][2]],
                                     corner[k_tets[t][3]]};
                    if (march_tet(&T, g))
                        goto nomem;
                }
                if (out->ntris > (size_t)1 << 31)
                    goto toomany;
            }
    out->grid.cell_first[ncells] = (uint32_t)out->ntris;
    free(T.inside);
    T.inside = NULL;
    rad__edge_map_free(&T.map);
    tgroup = tri_groups(&T);
    if (!tgroup || (T.meshes && rad__solid_own_triangles(&T, o, &tgroup)) || area_scales(&T, tgroup))
        goto nomem_late;
    free(tgroup);
    free(T.vgroup);
    free(T.slot);
    return RR_OK;
nomem_late:
    free(tgroup);
    free(T.vgroup);
    free(T.slot);
    rad__solid_mesh_free(out);
    return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory tessellating solid '%s'", s->path,
                        s->objects[obj].name);
toomany:
    free(T.vgroup);
    free(T.slot);
    free(T.inside);
    rad__edge_map_free(&T.map);
    rad__solid_mesh_free(out);
    return rr_error_set(err, RR_ERR_LIMIT, "%s: radiosity: solid '%s' would need more than 2^31 patches", s->path,
                        s->objects[obj].name);
nomem:
    free(T.vgroup);
    free(T.slot);
    free(T.inside);
    rad__edge_map_free(&T.map);
    rad__solid_mesh_free(out);
    return rr_error_set(err, RR_ERR_NOMEM, "%s: radiosity: out of memory tessellating solid '%s'", s->path,
                        s->objects[obj].name);
}

void rad__solid_mesh_free(rad__solid_mesh *m)
{
    free(m->verts);
    free(m->tris);
    free(m->grid.cell_first);
    free(m->own);
    free(m->scale);
    free(m->leaf);
    memset(m, 0, sizeof *m);
}

/* ---- lookups ---- */

/* Squared distance from p to triangle abc (Ericson, Real-Time Collision
 * Detection 5.1.5: the closest point by Voronoi regions). */
static double tri_dist2(rr_vec3 p, rr_vec3 a, rr_vec3 b, rr_vec3 c)
{
    rr_vec3 ab = rr_v3_sub(b, a), ac = rr_v3_sub(c, a), ap = rr_v3_sub(p, a);
    double d1 = rr_v3_dot(ab, ap), d2 = rr_v3_dot(ac, ap);
    rr_vec3 q;
    if (d1 <= 0 && d2 <= 0) {
        q = a;
    } else {
        rr_vec3 bp = rr_v3_sub(p, b);
        double d3 = rr_v3_dot(ab, bp), d4 = rr_v3_dot(ac, bp);
        rr_vec3 cp = rr_v3_sub(p, c);
        double d5 = rr_v3_dot(ab, cp), d6 = rr_v3_dot(ac, cp);
        double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3)
            q = b;
        else if (d6 >= 0 && d5 <= d6)
            q = c;
        else if (vc <= 0 && d1 >= 0 && d3 <= 0)
            q = rr_v3_madd(a, ab, d1 / (d1 - d3));
        else if (vb <= 0 && d2 >= 0 && d6 <= 0)
            q = rr_v3_madd(a, ac, d2 / (d2 - d6));
        else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
            q = rr_v3_madd(b, rr_v3_sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)));
        else {
            double den = 1.0 / (va + vb + vc);
            q = rr_v3_add(a, rr_v3_add(rr_v3_scale(ab, vb * den), rr_v3_scale(ac, vc * den)));
        }
    }
    return rr_v3_len2(rr_v3_sub(p, q));
}

uint32_t rad__solid_locate(const rad_patches *P, uint32_t obj, rr_vec3 p)
{
    const rad_solid_grid *g = &P->solid[obj];
    if (!g->n[0] || g->cell_first[(size_t)g->n[0] * g->n[1] * g->n[2]] == g->cell_first[0])
        return UINT32_MAX;
    double f[3] = {(p.x - g->lo.x) / g->cell.x, (p.y - g->lo.y) / g->cell.y, (p.z - g->lo.z) / g->cell.z};
    long c[3];
    for (int k = 0; k < 3; k++) {
        double x = floor(f[k]);
        c[k] = x < 0 ? 0 : (x >= g->n[k] ? (long)g->n[k] - 1 : (long)x);
    }
    /* The surface lies within a cell of its tessellation: the neighbouring
     * cells hold the nearest patch; widen the search only if they are empty. */
    uint32_t best = UINT32_MAX;
    double bd = INFINITY;
    for (long r = 1; r <= 4 && best == UINT32_MAX; r *= 2)
        for (long dk = -r; dk <= r; dk++)
            for (long dj = -r; dj <= r; dj++)
                for (long di = -r; di <= r; di++) {
                    long i = c[0] + di, j = c[1] + dj, k = c[2] + dk;
                    if (i < 0 || j < 0 || k < 0 || i >= (long)g->n[0] || j >= (long)g->n[1] || k >= (long)g->n[2])
                        continue;
                    size_t cell = (size_t)i + g->n[0] * ((size_t)j + g->n[1] * (size_t)k);
                    for (uint32_t q = g->cell_first[cell]; q < g->cell_first[cell + 1]; q++) {
                        const rad_patch *t = &P->p[q];
                        double d = tri_dist2(p, P->verts[t->v[0]], P->verts[t->v[1]], P->verts[t->v[2]]);
                        if (d < bd) {
                            bd = d;
                            best = q;
                        }
                    }
                }
    if (best == UINT32_MAX) {
        /* Far from every patch (a feature the grid missed): the nearest by brute force. */
        for (uint32_t q = g->cell_first[0]; q < g->cell_first[(size_t)g->n[0] * g->n[1] * g->n[2]]; q++) {
            double d = rr_v3_len2(rr_v3_sub(p, P->p[q].centroid));
            if (d < bd) {
                bd = d;
                best = q;
            }
        }
    }
    return best;
}

int rad__solid_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t obj, rr_vec3 x, rr_vec3 n,
                       rr_vec3 *xs, rr_vec3 *ns, uint32_t *leaf)
{
    const rad_solid_grid *g = &P->solid[obj];
    /* The facet is within about a cell of the surface: look both ways along
     * its normal, two cell diagonals far, for the nearest boundary. */
    double r = 2.0 * rr_v3_len(g->cell);
    rt_span_end end;
    if (!rad__solid_nearest_end(s, a, obj, x, n, r, &end)) {
        *xs = x;
        *ns = n;
        return 0;
    }
    const rt_span_end *be = &end;
    *xs = rr_v3_madd(x, n, be->t);
    rr_vec3 m = rt_csg_leaf_normal(s, be->leaf, be->surface, *xs);
    if (be->flip)
        m = rr_v3_neg(m);
    /* The facet's side is the front (it faces out of the solid, as m does);
     * near a chamfered edge the two can disagree by more than 90 degrees,
     * and the facet's own normal is then the better guess. */
    *ns = rr_v3_dot(m, n) > 0 ? m : n;
    if (leaf)
        *leaf = be->leaf;
    return 1;
}
