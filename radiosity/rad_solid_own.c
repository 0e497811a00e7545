/* rad_solid_own.c - a solid's patches from its leaves' own surfaces
 * (rad__solid_own_triangles, called by rad_solid.c; rad_solid_internal.h).
 *
 * A mesh leaf's detail (a scanned model's ears and creases) is finer than
 * the cells, and the marching triangles miss it (scenes/bunny-csg.json's
 * bunny: 28 % of its area at the automatic patch size); and every sharp
 * edge costs them a chamfer a cell wide (a pedestal a cell high is mostly
 * chamfer). But the final surface is made of pieces of the leaves' own
 * surfaces: those are the patches. Each leaf surface is a parametric
 * piece (psurf): a mesh triangle, a face of a box or of a
 * quadric's clip box, a sphere, an ellipsoid, or a surface of revolution
 * about the local y axis (the named quadrics but the ellipsoid); it is split
 * on a grid to the patch limits (shared vertices), then each piece is kept,
 * dropped, or (where another leaf's surface crosses it: a bite's rim) split
 * in four again, in its parameters, down to an eighth of a cell: a piece is
 * on the final surface where the boundary crosses the line along the leaf's
 * normal through the sample point (on the leaf's true surface) right there,
 * and is this leaf's (rt_solid_spans; the end's flip turns it when the leaf
 * is subtracted). Pieces are sampled at the centres of their four children;
 * the rim is then within an eighth of a cell. General quadrics have no
 * parametric form here: a solid with one is tessellated by marching
 * tetrahedra, with its mesh leaves' own triangles. */
#include <stdlib.h>
#include <string.h>

#include "rad_solid_internal.h"

/* A mesh leaf's triangle is split L x L to meet the patch limits (as a
 * scene triangle is, rad_patch.c), L at most 1024. */
uint32_t rad__solid_mesh_level(rr_vec3 A, rr_vec3 B, rr_vec3 C, const rad_patch_opts *o)
{
    double area = 0.5 * rr_v3_len(rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A)));
    double longest = fmax(rr_v3_len(rr_v3_sub(B, A)), fmax(rr_v3_len(rr_v3_sub(C, B)), rr_v3_len(rr_v3_sub(A, C))));
    double n1 = ceil(sqrt(area / o->max_area)), n2 = ceil(longest / o->max_edge);
    return (uint32_t)fmin(1024.0, fmax(1.0, fmax(n1, n2)));
}



typedef enum ps_kind { PS_TRI, PS_FACE, PS_SPHERE, PS_ELLIPSOID, PS_REV } ps_kind;

typedef struct psurf {
    ps_kind kind;
    const scene_csg_node *nd;
    int32_t surface;  /* rt_span_end.surface: the face, -1 the body */
    rr_vec3 A, B, C;  /* PS_TRI: the triangle (u along AB, v along AC) */
    rr_vec3 n;        /* PS_TRI: its outward normal */
    int axis, side;   /* PS_FACE: the face x[axis] = lo or hi (side 0 / 1) of nd->clip_lo..hi */
    double qa, qb, qc; /* PS_REV: r^2(y) = qa y^2 + qb y + qc over y in clip_lo.y..hi.y */
} psurf;

static int ps_flat(const psurf *f) { return f->kind == PS_TRI || f->kind == PS_FACE; }
static int ps_wraps(const psurf *f) { return f->kind == PS_SPHERE || f->kind == PS_ELLIPSOID || f->kind == PS_REV; }

/* The world point at parameters (u, v) in [0, 1]^2 (PS_TRI: barycentric,
 * u + v <= 1). */
static rr_vec3 ps_point(const psurf *f, double u, double v)
{
    const scene_csg_node *n = f->nd;
    rr_vec3 l;
    double th = 2.0 * RR_PI * u;
    switch (f->kind) {
    case PS_TRI:
        return rr_v3_add(f->A, rr_v3_add(rr_v3_scale(rr_v3_sub(f->B, f->A), u), rr_v3_scale(rr_v3_sub(f->C, f->A), v)));
    case PS_FACE: {
        double c[3], lo[3] = {n->clip_lo.x, n->clip_lo.y, n->clip_lo.z}, hi[3] = {n->clip_hi.x, n->clip_hi.y, n->clip_hi.z};
        int a1 = (f->axis + 1) % 3, a2 = (f->axis + 2) % 3;
        c[f->axis] = f->side ? hi[f->axis] : lo[f->axis];
        c[a1] = lo[a1] + (hi[a1] - lo[a1]) * u;
        c[a2] = lo[a2] + (hi[a2] - lo[a2]) * v;
        l = rr_v3(c[0], c[1], c[2]);
        break;
    }
    case PS_SPHERE: {
        double ph = RR_PI * v;
        l = rr_v3_madd(n->center, rr_v3(sin(ph) * cos(th), cos(ph), sin(ph) * sin(th)), n->radius);
        break;
    }
    case PS_ELLIPSOID: {
        double ph = RR_PI * v;
        l = rr_v3(sin(ph) * cos(th) / sqrt(n->q[0][0]), cos(ph) / sqrt(n->q[1][1]), sin(ph) * sin(th) / sqrt(n->q[2][2]));
        break;
    }
    default: { /* PS_REV */
        double y = n->clip_lo.y + (n->clip_hi.y - n->clip_lo.y) * v;
        double r = sqrt(fmax(0.0, (f->qa * y + f->qb) * y + f->qc));
        l = rr_v3(r * cos(th), y, r * sin(th));
        break;
    }
    }
    return rr_xform_point(&n->to_world, l);
}

/* The leaf's outward unit normal at x, the point at (u, v). */
static rr_vec3 ps_normal(const psurf *f, const scene *s, rr_vec3 x)
{
    if (f->kind == PS_TRI)
        return f->n;
    return rt_csg_leaf_normal(s, (uint32_t)(f->nd - s->csg), f->surface, x);
}

/* World length of the curve t -> ps_point at (t, v) (along u) or (u, t). */
static double ps_length(const psurf *f, int along_u, double w)
{
    double len = 0.0;
    rr_vec3 p = along_u ? ps_point(f, 0.0, w) : ps_point(f, w, 0.0);
    for (int k = 1; k <= 64; k++) {
        rr_vec3 q = along_u ? ps_point(f, k / 64.0, w) : ps_point(f, w, k / 64.0);
        len += rr_v3_len(rr_v3_sub(q, p));
        p = q;
    }
    return len;
}

typedef struct mtess {
    const scene *s;
    const rt_accel *a;
    uint32_t obj, leaf;
    const psurf *f;  /* the surface being split */
    double eps;      /* "right there": a millionth of a cell */
    double min_edge; /* no rim splits below this */
    rad__edge_map vm; /* (v, v, 0): a mesh vertex; (a, b, n << 11 | k): point k / n of mesh edge a-b (n <= 1024,
                         lowest terms); (a, b, ~0): the midpoint of pieces' corners a, b */
    rad__edge_map gm; /* (i, j, 1): grid point (i, j) of the surface being split */
    rad__solid_mesh *out;
    size_t *cap_v, *cap_t;
    uint32_t *grp;   /* per triangle: its group (rad__tess); VG_MESH for flat own pieces */
    size_t cap_o;
    uint32_t *leafs; /* per triangle: the leaf it lies on (UINT32_MAX: a marching triangle) */
    size_t cap_l;
    uint32_t slot;   /* the leaf's group */
} mtess;

static int add_vert(mtess *M, rr_vec3 p, uint32_t *id)
{
    if (rad__solid_grow((void **)&M->out->verts, M->cap_v, M->out->nverts + 1, sizeof *M->out->verts))
        return -1;
    M->out->verts[M->out->nverts] = p;
    *id = (uint32_t)M->out->nverts++;
    return 0;
}

/* Vertex for key (a, b, k) of map m, made at p when new. */
static int keyed_vert(mtess *M, rad__edge_map *m, uint32_t a, uint32_t b, uint32_t k, rr_vec3 p, uint32_t *id)
{
    uint32_t v = (uint32_t)M->out->nverts;
    uint32_t got = rad__edge_get(m, a, b, k, v);
    if (got == UINT32_MAX)
        return -1;
    if (got == v && add_vert(M, p, &got))
        return -1;
    *id = got;
    return 0;
}

/* +1: the point x on the leaf with outward normal n lies on the final
 * surface facing n, -1 facing -n (a subtracted leaf), 0: not on it. */
static int on_surface(const mtess *M, rr_vec3 x, rr_vec3 n)
{
    rt_span_end e;
    if (!rad__solid_nearest_end(M->s, M->a, M->obj, x, n, M->eps, &e) || e.leaf != M->leaf)
        return 0;
    return e.flip ? -1 : 1;
}

/* Appends piece (a, b, c), turned to face `out` (the final surface's
 * outward normal at its centre). */
static int emit_own(mtess *M, uint32_t a, uint32_t b, uint32_t c, rr_vec3 out)
{
    rr_vec3 A = M->out->verts[a], B = M->out->verts[b], C = M->out->verts[c];
    rr_vec3 cn = rr_v3_cross(rr_v3_sub(B, A), rr_v3_sub(C, A));
    if (!(rr_v3_len2(cn) > 0))
        return 0; /* at a pole or an apex */
    if (rad__solid_grow((void **)&M->out->tris, M->cap_t, M->out->ntris + 1, sizeof *M->out->tris) ||
        rad__solid_grow((void **)&M->grp, &M->cap_o, M->out->ntris + 1, sizeof *M->grp) ||
        rad__solid_grow((void **)&M->leafs, &M->cap_l, M->out->ntris + 1, sizeof *M->leafs))
        return -1;
    int keep = rr_v3_dot(cn, out) >= 0;
    uint32_t *t = M->out->tris[M->out->ntris];
    t[0] = a;
    t[1] = keep ? b : c;
    t[2] = keep ? c : b;
    M->grp[M->out->ntris] = ps_flat(M->f) ? (M->f->kind == PS_TRI ? VG_MESH : (M->slot | VG_FACE)) : M->slot;
    M->leafs[M->out->ntris++] = M->leaf;
    return 0;
}

static double tri_longest(rr_vec3 A, rr_vec3 B, rr_vec3 C)
{
    return fmax(rr_v3_len(rr_v3_sub(B, A)), fmax(rr_v3_len(rr_v3_sub(C, B)), rr_v3_len(rr_v3_sub(A, C))));
}

/* The piece with corners at parameters pa, pb, pc sampled at the centres of
 * the four children of its split at the edge midpoints: side[k] as
 * on_surface there, *centre_n the leaf's normal at the middle child's;
 * whether all four agree. */
static int piece_sides(const mtess *M, const double pa[2], const double pb[2], const double pc[2], int side[4],
                       rr_vec3 *centre_n)
{
    static const double w[4][3] = {{4, 1, 1}, {1, 4, 1}, {1, 1, 4}, {2, 2, 2}};
    int agree = 1;
    for (int k = 0; k < 4; k++) {
        double u = (w[k][0] * pa[0] + w[k][1] * pb[0] + w[k][2] * pc[0]) / 6.0;
        double v = (w[k][0] * pa[1] + w[k][1] * pb[1] + w[k][2] * pc[1]) / 6.0;
        rr_vec3 x = ps_point(M->f, u, v), n = ps_normal(M->f, M->s, x);
        side[k] = on_surface(M, x, n);
        agree &= side[k] == side[0];
        if (k == 3)
            *centre_n = n;
    }
    return agree;
}

/* Piece (a, b, c) of the surface, its corners at parameters pa, pb, pc. */
static int own_piece(mtess *M, uint32_t a, uint32_t b, uint32_t c, const double pa[2], const double pb[2],
                     const double pc[2])
{
    int side[4];
    rr_vec3 centre_n;
    int agree = piece_sides(M, pa, pb, pc, side, &centre_n);
    double longest = tri_longest(M->out->verts[a], M->out->verts[b], M->out->verts[c]);
    if (agree || longest < 2.0 * M->min_edge) {
        int sd = side[3] ? side[3] : (side[0] ? side[0] : (side[1] ? side[1] : side[2]));
        if (!agree) {
            int kept = (side[0] != 0) + (side[1] != 0) + (side[2] != 0) + (side[3] != 0);
            if (kept < 2)
                return 0; /* mostly off the surface */
        }
        return sd ? emit_own(M, a, b, c, rr_v3_scale(centre_n, sd)) : 0;
    }
    double pab[2] = {0.5 * (pa[0] + pb[0]), 0.5 * (pa[1] + pb[1])};
    double pbc[2] = {0.5 * (pb[0] + pc[0]), 0.5 * (pb[1] + pc[1])};
    double pca[2] = {0.5 * (pc[0] + pa[0]), 0.5 * (pc[1] + pa[1])};
    uint32_t ab, bc, ca;
    if (keyed_vert(M, &M->vm, a < b ? a : b, a < b ? b : a, UINT32_MAX, ps_point(M->f, pab[0], pab[1]), &ab) ||
        keyed_vert(M, &M->vm, b < c ? b : c, b < c ? c : b, UINT32_MAX, ps_point(M->f, pbc[0], pbc[1]), &bc) ||
        keyed_vert(M, &M->vm, c < a ? c : a, c < a ? a : c, UINT32_MAX, ps_point(M->f, pca[0], pca[1]), &ca))
        return -1;
    if (own_piece(M, a, ab, ca, pa, pab, pca) || own_piece(M, ab, b, bc, pab, pb, pbc) ||
        own_piece(M, ca, bc, c, pca, pbc, pc) || own_piece(M, ab, bc, ca, pab, pbc, pca))
        return -1;
    return 0;
}

/* Lattice point (i, j) of triangle (va, vb, vc) split L x L (i along a->b,
 * j along a->c): corners and edge points shared with the neighbours. */
static int lattice_vert(mtess *M, const uint32_t v[3], uint32_t L, uint32_t i, uint32_t j, uint32_t *id)
{
    const rr_vec3 *W = M->s->csg_verts;
    uint32_t k0 = L - i - j; /* weight of a */
    rr_vec3 p = rr_v3_scale(rr_v3_add(rr_v3_add(rr_v3_scale(W[v[0]], k0), rr_v3_scale(W[v[1]], i)),
                                      rr_v3_scale(W[v[2]], j)),
                            1.0 / L);
    if (i == L)
        return keyed_vert(M, &M->vm, v[1], v[1], 0, W[v[1]], id);
    if (j == L)
        return keyed_vert(M, &M->vm, v[2], v[2], 0, W[v[2]], id);
    if (k0 == L)
        return keyed_vert(M, &M->vm, v[0], v[0], 0, W[v[0]], id);
    /* On an edge: keyed by its ends (lower index first) and the step from the lower. */
    uint32_t e0, e1, step;
    if (j == 0) {
        e0 = v[0], e1 = v[1], step = i;
    } else if (i == 0) {
        e0 = v[0], e1 = v[2], step = j;
    } else if (k0 == 0) {
        e0 = v[1], e1 = v[2], step = j;
    } else {
        return add_vert(M, p, id);
    }
    if (e0 > e1) {
        uint32_t t = e0;
        e0 = e1;
        e1 = t;
        step = L - step;
    }
    /* The same point from either side of the edge: recomputed from its ends,
     * and keyed by its fraction of the edge in lowest terms (the triangles on
     * either side may be split to different levels; a point only one of them
     * has is a T-junction there). */
    p = rr_v3_scale(rr_v3_add(rr_v3_scale(W[e0], L - step), rr_v3_scale(W[e1], step)), 1.0 / L);
    uint32_t g = L, r = step;
    while (r) {
        uint32_t t = g % r;
        g = r;
        r = t;
    }
    return keyed_vert(M, &M->vm, e0, e1, (L / g) << 11 | (step / g), p, id);
}

/* Triangle t of mesh leaf nd as a surface; 0 when it has no area. */
static int mesh_surface(const scene *s, const scene_csg_node *nd, size_t t, psurf *f)
{
    const uint32_t *v = s->csg_tris[t];
    *f = (psurf){.kind = PS_TRI, .nd = nd, .surface = (int32_t)t};
    f->A = s->csg_verts[v[0]], f->B = s->csg_verts[v[1]], f->C = s->csg_verts[v[2]];
    rr_vec3 nn = rr_v3_cross(rr_v3_sub(f->B, f->A), rr_v3_sub(f->C, f->A));
    if (!(rr_v3_len2(nn) > 0))
        return 0;
    f->n = rr_v3_norm(nn);
    return 1;
}

static int tessellate_mesh_leaf(mtess *M, const rad_patch_opts *o)
{
    const scene *s = M->s;
    const scene_csg_node *nd = &s->csg[M->leaf];
    for (size_t t = nd->tri_first; t < nd->tri_first + nd->tri_count; t++) {
        const uint32_t *v = s->csg_tris[t];
        psurf f;
        if (!mesh_surface(s, nd, t, &f))
            continue;
        M->f = &f;
        uint32_t L = rad__solid_mesh_level(f.A, f.B, f.C, o);
        for (uint32_t i = 0; i < L; i++)
            for (uint32_t j = 0; i + j < L; j++) {
                uint32_t p0, p1, p2;
                double q0[2] = {(double)i / L, (double)j / L}, q1[2] = {(double)(i + 1) / L, (double)j / L},
                       q2[2] = {(double)i / L, (double)(j + 1) / L};
                if (lattice_vert(M, v, L, i, j, &p0) || lattice_vert(M, v, L, i + 1, j, &p1) ||
                    lattice_vert(M, v, L, i, j + 1, &p2) || own_piece(M, p0, p1, p2, q0, q1, q2))
                    return -1;
                if (i + j + 1 < L) {
                    uint32_t p3;
                    double q3[2] = {(double)(i + 1) / L, (double)(j + 1) / L};
                    if (lattice_vert(M, v, L, i + 1, j + 1, &p3) || own_piece(M, p1, p3, p2, q1, q3, q2))
                        return -1;
                }
            }
    }
    return 0;
}

/* Grid point (i, j) of surface f split nu x nv: shared around a wrapping
 * surface's seam and at its poles. */
static int grid_vert(mtess *M, const psurf *f, uint32_t nu, uint32_t nv, uint32_t i, uint32_t j, uint32_t *id)
{
    uint32_t ki = ps_wraps(f) ? i % nu : i;
    if ((f->kind == PS_SPHERE || f->kind == PS_ELLIPSOID) && (j == 0 || j == nv))
        ki = 0; /* a pole */
    return keyed_vert(M, &M->gm, ki, j, 1, ps_point(f, (double)ki / nu, (double)j / nv), id);
}

/* The nu x nv grid that splits surface f to the limits; 0 for a degenerate
 * face. */
static int surface_grid(const psurf *f, const rad_patch_opts *o, uint32_t *nu, uint32_t *nv)
{
    double e = fmin(o->max_edge, sqrt(2.0 * o->max_area));
    double lu = fmax(ps_length(f, 1, 0.0), fmax(ps_length(f, 1, 0.5), ps_length(f, 1, 1.0)));
    double lv = fmax(ps_length(f, 0, 0.0), fmax(ps_length(f, 0, 0.5), ps_length(f, 0, 0.25)));
    if (!(lu > 0) || !(lv > 0))
        return 0;
    uint32_t minu = ps_wraps(f) ? 12 : 1, minv = f->kind == PS_SPHERE || f->kind == PS_ELLIPSOID ? 6 : 1;
    *nu = (uint32_t)fmin(1024.0, fmax((double)minu, ceil(lu / e)));
    *nv = (uint32_t)fmin(1024.0, fmax((double)minv, ceil(lv / e)));
    return 1;
}

/* One parametric surface of the leaf on an nu x nv grid to the limits. */
static int tessellate_surface(mtess *M, const psurf *f, const rad_patch_opts *o)
{
    uint32_t nu, nv;
    if (!surface_grid(f, o, &nu, &nv))
        return 0; /* a degenerate face */
    M->f = f;
    rad__edge_map_free(&M->gm);
    if (rad__edge_map_init(&M->gm, 4 * ((size_t)nu + 1) * ((size_t)nv + 1)))
        return -1;
    for (uint32_t j = 0; j < nv; j++)
        for (uint32_t i = 0; i < nu; i++) {
            uint32_t p00, p10, p01, p11;
            double q00[2] = {(double)i / nu, (double)j / nv}, q10[2] = {(double)(i + 1) / nu, (double)j / nv},
                   q01[2] = {(double)i / nu, (double)(j + 1) / nv}, q11[2] = {(double)(i + 1) / nu, (double)(j + 1) / nv};
            if (grid_vert(M, f, nu, nv, i, j, &p00) || grid_vert(M, f, nu, nv, i + 1, j, &p10) ||
                grid_vert(M, f, nu, nv, i, j + 1, &p01) || grid_vert(M, f, nu, nv, i + 1, j + 1, &p11))
                return -1;
            if (own_piece(M, p00, p10, p11, q00, q10, q11) || own_piece(M, p00, p11, p01, q00, q11, q01))
                return -1;
        }
    return 0;
}

/* Whether leaf l has a parametric form here (a general quadric has not). */
int rad__solid_leaf_parametric(const scene_csg_node *nd)
{
    if (nd->solid == SCENE_SOLID_QUADRIC)
        return nd->shape != SCENE_QUADRIC_GENERAL;
    return nd->solid == SCENE_SOLID_SPHERE || nd->solid == SCENE_SOLID_BOX || nd->solid == SCENE_SOLID_MESH;
}

/* All of leaf M->leaf's surfaces. */
static int tessellate_leaf(mtess *M, const rad_patch_opts *o)
{
    const scene_csg_node *nd = &M->s->csg[M->leaf];
    if (nd->solid == SCENE_SOLID_MESH)
        return tessellate_mesh_leaf(M, o);
    psurf f = {.nd = nd, .surface = -1};
    if (nd->solid == SCENE_SOLID_SPHERE) {
        f.kind = PS_SPHERE;
        return tessellate_surface(M, &f, o);
    }
    if (nd->solid == SCENE_SOLID_QUADRIC) {
        if (nd->shape == SCENE_QUADRIC_ELLIPSOID) {
            f.kind = PS_ELLIPSOID;
        } else {
            /* x^2 + z^2 + q11 y^2 + 2 q13 y + q33 = 0 (scene_csg.c's named shapes) */
            f.kind = PS_REV;
            f.qa = -nd->q[1][1];
            f.qb = -2.0 * nd->q[1][3];
            f.qc = -nd->q[3][3];
        }
        if (tessellate_surface(M, &f, o))
            return -1;
    }
    /* The faces of a box, or of a quadric's clip box (mostly off the
     * surface; only where the quadric is cut, a cap). */
    for (int k = 0; k < 6; k++) {
        psurf g = {.kind = PS_FACE, .nd = nd, .surface = k, .axis = k / 2, .side = k & 1};
        if (tessellate_surface(M, &g, o))
            return -1;
    }
    return 0;
}

/* ---- the count without the pieces (rad__solid_own_estimate) ---- */

/* What own_piece makes of piece (pa, pb, pc), about: where its four sample
 * points agree, itself or nothing; where they do not (a rim crosses it),
 * own_piece splits it in four for d levels, down to an eighth of a cell,
 * and a rim crosses about 2^k of the pieces k levels down, of which about
 * half are kept: 2^d (against the pieces made, test_radiosity's random
 * solids: -6 .. +19 %; 1.5 x 2^d gave +0 .. +65 %, a fixed 3 per rim piece
 * -47 .. 0 %). */
static double count_piece(const mtess *M, const double pa[2], const double pb[2], const double pc[2])
{
    int side[4];
    rr_vec3 centre_n;
    if (piece_sides(M, pa, pb, pc, side, &centre_n))
        return side[0] != 0;
    double longest = tri_longest(ps_point(M->f, pa[0], pa[1]), ps_point(M->f, pb[0], pb[1]), ps_point(M->f, pc[0], pc[1]));
    double d = 0.0;
    for (; longest >= 2.0 * M->min_edge && d < 16; longest *= 0.5)
        d++;
    return exp2(d);
}

/* Surface f on its grid to the limits (as tessellate_surface splits it). */
static double count_surface(mtess *M, const psurf *f, const rad_patch_opts *o)
{
    uint32_t nu, nv;
    if (!surface_grid(f, o, &nu, &nv))
        return 0.0;
    M->f = f;
    double n = 0.0;
    for (uint32_t j = 0; j < nv; j++)
        for (uint32_t i = 0; i < nu; i++) {
            double q00[2] = {(double)i / nu, (double)j / nv}, q10[2] = {(double)(i + 1) / nu, (double)j / nv},
                   q01[2] = {(double)i / nu, (double)(j + 1) / nv}, q11[2] = {(double)(i + 1) / nu, (double)(j + 1) / nv};
            n += count_piece(M, q00, q10, q11) + count_piece(M, q00, q11, q01);
        }
    return n;
}

/* A mesh leaf's triangles split L x L to the limits (as tessellate_mesh_leaf
 * splits them): a triangle whose sample points agree counts all L^2 pieces or
 * none, one that a rim crosses piece by piece. */
static double count_mesh_leaf(mtess *M, const rad_patch_opts *o)
{
    const scene *s = M->s;
    const scene_csg_node *nd = &s->csg[M->leaf];
    double n = 0.0;
    for (size_t t = nd->tri_first; t < nd->tri_first + nd->tri_count; t++) {
        psurf f;
        if (!mesh_surface(s, nd, t, &f))
            continue;
        M->f = &f;
        uint32_t L = rad__solid_mesh_level(f.A, f.B, f.C, o);
        const double a[2] = {0, 0}, b[2] = {1, 0}, c[2] = {0, 1};
        double whole = count_piece(M, a, b, c);
        if (whole <= 1.0 || L == 1) { /* all on, all off, or a rim across one piece */
            n += whole <= 1.0 ? whole * L * L : whole;
            continue;
        }
        for (uint32_t i = 0; i < L; i++)
            for (uint32_t j = 0; i + j < L; j++) {
                double q0[2] = {(double)i / L, (double)j / L}, q1[2] = {(double)(i + 1) / L, (double)j / L},
                       q2[2] = {(double)i / L, (double)(j + 1) / L}, q3[2] = {(double)(i + 1) / L, (double)(j + 1) / L};
                n += count_piece(M, q0, q1, q2);
                if (i + j + 1 < L)
                    n += count_piece(M, q1, q3, q2);
            }
    }
    return n;
}

double rad__solid_own_estimate(const scene *s, const rt_accel *a, uint32_t obj, double hmin, const rad_patch_opts *o)
{
    mtess M;
    memset(&M, 0, sizeof M);
    M.s = s;
    M.a = a;
    M.obj = obj;
    M.eps = 1e-6 * hmin;
    M.min_edge = hmin / 8.0;
    double n = 0.0;
    for (uint32_t l = 0; l < s->ncsg; l++) {
        const scene_csg_node *nd = &s->csg[l];
        if (nd->object != obj || nd->op != SCENE_CSG_LEAF)
            continue;
        if (!rad__solid_leaf_parametric(nd))
            return -1.0;
        M.leaf = l;
        if (nd->solid == SCENE_SOLID_MESH) {
            n += count_mesh_leaf(&M, o);
            continue;
        }
        psurf f = {.nd = nd, .surface = -1};
        if (nd->solid == SCENE_SOLID_SPHERE || nd->solid == SCENE_SOLID_QUADRIC) {
            f.kind = nd->solid == SCENE_SOLID_SPHERE ? PS_SPHERE : nd->shape == SCENE_QUADRIC_ELLIPSOID ? PS_ELLIPSOID : PS_REV;
            f.qa = -nd->q[1][1];
            f.qb = -2.0 * nd->q[1][3];
            f.qc = -nd->q[3][3];
            n += count_surface(&M, &f, o);
            if (nd->solid == SCENE_SOLID_SPHERE)
                continue;
        }
        for (int k = 0; k < 6; k++) {
            psurf g = {.kind = PS_FACE, .nd = nd, .surface = k, .axis = k / 2, .side = k & 1};
            n += count_surface(&M, &g, o);
        }
    }
    return n;
}

/* rad_solid_internal.h. The marching triangles' groups in *tgroup are
 * replaced; VG_MESH marks a mesh leaf's own piece, group | VG_FACE a face's. */
int rad__solid_own_triangles(rad__tess *T, const rad_patch_opts *o, uint32_t **tgroup)
{
    const scene *s = T->s;
    rad__solid_mesh *out = T->out;
    uint32_t obj = s->csg[T->root].object;
    size_t ncells = (size_t)T->n[0] * T->n[1] * T->n[2], nmarch = out->ntris;
    double hmin = fmin(T->cell.x, fmin(T->cell.y, T->cell.z));
    /* Each marching triangle's cell; those on mesh leaves are dropped (cell
     * = ncells): the leaves' own triangles stand there. So are the chamfers
     * across a seam between a mesh leaf and another (VG_SEAM), which are
     * neither surface and lie where the light is the mesh's (a bite's rim,
     * on the lit back of a bunny), unless the other leaf has no triangle
     * of its own (a bite a cell wide): then they stand for it. */
    uint32_t *tcell = malloc((nmarch + 1) * sizeof *tcell);
    size_t *inner = calloc(T->ngroups + 1, sizeof *inner);
    if (!tcell || !inner) {
        free(tcell);
        free(inner);
        return -1;
    }
    uint32_t *tg = *tgroup;
    for (size_t q = 0; q < nmarch; q++)
        if (tg[q] < T->ngroups)
            inner[tg[q]]++;
    for (size_t c = 0; c < ncells; c++)
        for (uint32_t q = out->grid.cell_first[c]; q < out->grid.cell_first[c + 1]; q++) {
            int seam = tg[q] != VG_MESH && tg[q] != VG_NONE && (tg[q] & VG_SEAM);
            if (seam)
                tg[q] &= ~VG_SEAM;
            int drop = tg[q] == VG_MESH || (seam && inner[tg[q]] > 0);
            tcell[q] = drop ? (uint32_t)ncells : (uint32_t)c;
        }
    free(inner);
    mtess M;
    memset(&M, 0, sizeof M);
    M.s = s;
    M.a = T->a;
    M.obj = obj;
    M.eps = 1e-6 * hmin;
    M.min_edge = hmin / 8.0;
    M.out = out;
    M.cap_v = &T->cap_v;
    M.cap_t = &T->cap_t;
    int bad = rad__solid_grow((void **)&M.grp, &M.cap_o, nmarch + 1, sizeof *M.grp) ||
              rad__solid_grow((void **)&M.leafs, &M.cap_l, nmarch + 1, sizeof *M.leafs);
    for (size_t q = 0; q < nmarch && !bad; q++) {
        M.grp[q] = (*tgroup)[q];
        M.leafs[q] = UINT32_MAX;
    }
    int vm = !bad && !rad__edge_map_init(&M.vm, 1024), gm = vm && !rad__edge_map_init(&M.gm, 16);
    bad = bad || !gm;
    /* Every leaf when the marching tetrahedra made nothing, else the mesh leaves. */
    for (uint32_t l = 0; l < s->ncsg && !bad; l++)
        if (s->csg[l].object == obj && s->csg[l].op == SCENE_CSG_LEAF &&
            (T->all_own || s->csg[l].solid == SCENE_SOLID_MESH)) {
            M.leaf = l;
            M.slot = T->slot[l];
            bad = tessellate_leaf(&M, o) != 0;
        }
    if (vm)
        rad__edge_map_free(&M.vm);
    if (gm)
        rad__edge_map_free(&M.gm);
    size_t nt = out->ntris;
    uint32_t *cell = bad ? NULL : malloc((nt + 1) * sizeof *cell);
    uint32_t(*tris)[3] = bad ? NULL : malloc((nt + 1) * sizeof *tris);
    uint32_t *grp = bad ? NULL : malloc((nt + 1) * sizeof *grp);
    uint32_t *leafs = bad ? NULL : malloc((nt + 1) * sizeof *leafs);
    uint32_t *first = bad ? NULL : calloc(ncells + 2, sizeof *first);
    if (bad || !cell || !tris || !grp || !leafs || !first) {
        free(tcell);
        free(M.grp);
        free(M.leafs);
        free(leafs);
        free(cell);
        free(tris);
        free(grp);
        free(first);
        return -1;
    }
    /* The leaves' triangles go to the cell of their centre. */
    for (size_t q = 0; q < nt; q++) {
        if (q < nmarch) {
            cell[q] = tcell[q];
            continue;
        }
        const uint32_t *t = out->tris[q];
        rr_vec3 x = rr_v3_scale(rr_v3_add(rr_v3_add(out->verts[t[0]], out->verts[t[1]]), out->verts[t[2]]), 1.0 / 3.0);
        double f[3] = {(x.x - T->lo.x) / T->cell.x, (x.y - T->lo.y) / T->cell.y, (x.z - T->lo.z) / T->cell.z};
        long ci[3];
        for (int k = 0; k < 3; k++) {
            double fl = floor(f[k]);
            ci[k] = !(fl >= 0) ? 0 : (fl >= T->n[k] ? (long)T->n[k] - 1 : (long)fl);
        }
        cell[q] = (uint32_t)((size_t)ci[0] + T->n[0] * ((size_t)ci[1] + T->n[1] * (size_t)ci[2]));
    }
    /* Stable counting sort by cell; the dropped (cell ncells) fall off the end. */
    for (size_t q = 0; q < nt; q++)
        first[cell[q] + 1]++;
    for (size_t c = 0; c <= ncells; c++)
        first[c + 1] += first[c];
    for (size_t q = 0; q < nt; q++) {
        uint32_t k = first[cell[q]]++;
        memcpy(tris[k], out->tris[q], sizeof tris[k]);
        grp[k] = M.grp[q];
        leafs[k] = M.leafs[q];
    }
    /* first[c] is now the end of cell c: shift back into starts. */
    for (size_t c = ncells; c > 0; c--)
        out->grid.cell_first[c] = first[c - 1];
    out->grid.cell_first[0] = 0;
    free(out->tris);
    out->tris = tris;
    out->ntris = out->grid.cell_first[ncells];
    T->cap_t = nt + 1;
    free(tcell);
    free(M.grp);
    free(M.leafs);
    free(cell);
    free(first);
    free(*tgroup);
    *tgroup = grp;
    out->leaf = leafs;
    /* The dropped triangles' vertices go too (every vertex is a corner). */
    uint32_t *map = malloc((out->nverts + 1) * sizeof *map);
    if (!map)
        return -1;
    memset(map, 0xff, (out->nverts + 1) * sizeof *map);
    /* (in the vertices' order, so that none is overwritten before it moves) */
    for (size_t q = 0; q < out->ntris; q++)
        for (int k = 0; k < 3; k++)
            map[out->tris[q][k]] = 0;
    uint32_t nv = 0;
    for (size_t v = 0; v < out->nverts; v++)
        if (map[v] == 0) {
            out->verts[nv] = out->verts[v];
            map[v] = nv++;
        }
    for (size_t q = 0; q < out->ntris; q++)
        for (int k = 0; k < 3; k++)
            out->tris[q][k] = map[out->tris[q][k]];
    out->nverts = nv;
    free(map);
    return 0;
}
