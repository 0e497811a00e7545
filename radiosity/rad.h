/* rad.h - the radiosity pass: patches, form factors with visibility, solvers,
 * and the energy ledger.
 *
 * Units. The scene gives emitted *radiance* Le (what the ray tracer uses); the
 * radiosity pass works in *radiosity* (exitance, power per area) of Lambertian
 * patches: E = pi * Le emitted, B = E + rho * sum_j F_ij B_j, and a patch shows
 * radiance B / pi. Power is radiosity times area.
 *
 * Pipeline:
 *   rad_patches_build  scene triangles (and tessellated spheres) -> patches
 *   rad_ff_compute     sparse form factors F_ij with visibility (BVH rays)
 *   rad_solve          B per patch and channel (CHOLMOD, or Gauss-Seidel)
 *   rad_energy         where the emitted power went
 * or, with radiosity.method "hierarchical" (rad_hier.c, the default), elements
 * refined on demand under clusters and links in place of the three middle
 * steps (links by way of chains of planar mirrors too; a scene with a curved
 * mirror takes the flat method, with a warning); its leaves are a
 * rad_patches like the flat one (roots, qt below).
 *
 * Ownership: every *_build / *_compute allocates what it returns and has a
 * matching destroy (NULL is a no-op); outputs are untouched on failure.
 */
#ifndef RAD_H
#define RAD_H

#include <stddef.h>
#include <stdint.h>

#include "rr_core.h"
#include "rt.h"
#include "scene.h"

/* ---- patches ---- */

typedef struct rad_patch {
    uint32_t v[3];     /* corners: indices into rad_patches.verts, counter-clockwise */
    rr_vec3 normal;    /* unit, from the winding */
    rr_vec3 centroid;
    double area;       /* of the triangle (a sphere's or a solid's: its share of the true surface's area,
                          rad_patch.c); in a flat pass's solution, of its open part (rad_ff: buried parts) */
    rr_rgb rho;        /* diffuse reflectance of the material */
    double mirror;     /* mean mirror reflectance of the material: Monte Carlo form-factor
                          rays go on through it (extended form factors, rad_ff.c) */
    rr_rgb emission;   /* emitted radiosity E = pi * Le */
    uint32_t object;   /* scene object */
    uint32_t flat;     /* 1: the patch lies on the surface it stands for, so its points are their own
                          surface points (rad_patch_surface): a scene triangle's, and a solid's piece of
                          a mesh leaf's own triangle (rad_solid.c) */
    int64_t tri;       /* source scene triangle, or -1 for a tessellated sphere or solid */
} rad_patch;

/* Where a solid's patches lie: the cells of a grid over its box
 * (rad_solid.c). The patches whose centres are in cell c (x fastest; made in
 * it, for marching tetrahedra) are [cell_first[c], cell_first[c + 1]). */
typedef struct rad_solid_grid {
    rr_vec3 lo, cell;      /* grid origin and cell size per axis */
    uint32_t n[3];         /* cells per axis; 0 for objects that are not solids */
    uint32_t *cell_first;  /* n[0] n[1] n[2] + 1 entries, absolute patch indices */
} rad_solid_grid;

typedef struct rad_patches {
    rad_patch *p;
    size_t n;
    rr_vec3 *verts;    /* shared corners: patches of one object share their vertices, but not across creases */
    size_t nverts;
    /* Lookup from a scene triangle t to its patches: the triangle is split into
     * level[t]^2 similar sub-triangles, stored from first[t] on (see
     * rad_patch_locate). */
    uint32_t *tri_first;
    uint32_t *tri_level;
    size_t ntris;
    /* Tessellated spheres: object o's patches start at sphere_first[o]; a UV
     * grid of sphere_stacks x sphere_slices cells (2 triangles per cell). */
    uint32_t *sphere_first;
    uint32_t sphere_stacks, sphere_slices;
    /* Solids (CSG and quadric objects), per object (nsolid = the scene's object count). */
    rad_solid_grid *solid;
    size_t nsolid;
    /* Hierarchical patch sets (rad_hier.c): the patches above are the leaves
     * of a quadtree over each patch of roots (its four children: the corner
     * triangles at A, B, C, then the middle one); roots then answers the
     * lookups above. NULL for flat patch sets. A tree entry e is a leaf patch
     * (e & RAD_QT_LEAF, index e & ~RAD_QT_LEAF) or node e, whose four child
     * entries are qt[4e .. 4e+3]; root r's entry is root_qt[r]. Vertices past
     * roots->nverts are edge midpoints, made coarse to fine: vertex v's edge is
     * (mid[2 (v - roots->nverts)], mid[2 (v - roots->nverts) + 1]). */
    struct rad_patches *roots;
    uint32_t *qt;
    size_t nqt;
    uint32_t *root_qt;
    uint32_t *mid;
} rad_patches;

#define RAD_QT_LEAF 0x80000000u

typedef struct rad_patch_opts {
    double max_area;   /* > 0 */
    double max_edge;   /* > 0 */
    /* The BVH over the scene, for the solids' inside tests (mesh leaves);
     * NULL tests every mesh triangle (slow for big meshes, same result). */
    const rt_accel *accel;
    /* The same limits for curved surfaces (spheres, solids), whose patches
     * are flat facets of them: <= 0, max_area and max_edge. The hierarchical
     * method's roots are coarser than patches on flat surfaces only. */
    double curved_max_area, curved_max_edge;
} rad_patch_opts;

/* Subdivides every triangle of every object into level^2 similar triangles,
 * with one level per object (the smallest that brings every triangle of the
 * object under both limits), so edges shared inside an object are split the
 * same way on both sides: no T-vertices. Patches on both sides of an edge
 * share its vertices unless the edge is a crease (its triangles meet at more
 * than RAD_CREASE_DEG, a box's edges): Gouraud means are then taken on each
 * side apart, as the radiosity there differs. Spheres are tessellated into a UV grid
 * fine enough for the same limits. Solids (CSG trees, quadrics) are pieced
 * from their leaves' own surfaces (mesh triangles, faces, parametric grids),
 * each piece kept where it lies on the final solid (rad_solid.c; marching
 * tetrahedra for a solid with a general quadric leaf); each patch has its
 * leaf's material. A sphere's and a solid's curved patch areas are scaled
 * to the true surface's area (the sphere's 4 pi r^2; a solid leaf's by
 * Crofton's formula), which their chords fall short of. Fails
 * (RR_ERR_LIMIT) beyond 2^31 patches. */
rr_status rad_patches_build(const scene *s, const rad_patch_opts *o, rad_patches **out, rr_error *err);
#define RAD_CREASE_DEG 45.0
void rad_patches_destroy(rad_patches *P);

/* The patch that contains point p (on the surface) of a hit reported by the
 * ray tracer (scene triangle tri >= 0, or sphere / solid object obj when
 * tri < 0). For a solid, the patch nearest to p; UINT32_MAX when the solid
 * has no patches (too thin for its grid). */
uint32_t rad_patch_locate(const rad_patches *P, const scene *s, int64_t tri, uint32_t obj, rr_vec3 p);

/* The surface point a ray from (or to) point x of patch k starts (ends) at,
 * and the unit normal there on the patch's front side: x itself for patches
 * of triangles; facets of spheres and solids are chords of curved surfaces,
 * so x is moved onto the analytic surface (radially for spheres, along the
 * facet normal for solids). a may be NULL (see rad_patch_opts.accel). */
void rad_patch_surface(const rad_patches *P, const scene *s, const rt_accel *a, uint32_t k, rr_vec3 x, rr_vec3 *xs,
                       rr_vec3 *ns);

/* About how many patches solid object obj gets under limits o (for memory
 * estimates before building): its leaves' pieces at the limits, each
 * counted where its sample points lie on the final solid, rims by rule
 * (within 25 % of the count made: test_radiosity); the marching tetrahedra's
 * rule for a solid with a general quadric leaf. Queries the solids through
 * o->accel (NULL: every mesh triangle per query). */
double rad_solid_patch_estimate(const scene *s, uint32_t obj, const rad_patch_opts *o);
/* The patch count rad_patches_build makes under limits o, by its own level
 * rules (exact for triangles and spheres; solids by rad_solid_patch_estimate,
 * through the solids' own BVHs, built for it when o->accel is NULL), without
 * building the patches. */
double rad_patches_estimate(const scene *s, const rad_patch_opts *o);
/* Warns about every object whose level is set by a few outlying triangles
 * (at most 8, and under 1 %, needing more than a quarter of the level the
 * object gets): the patch count grows with the square of the level. Returns
 * the count of objects named. */
size_t rad_patches_level_outliers(const scene *s, const rad_patch_opts *o, const rr_warn_sink *warn);

/* Barycentric coordinates of p in patch k (for interpolation). */
void rad_patch_barycentric(const rad_patches *P, uint32_t k, rr_vec3 p, double b[3]);

/* ---- form factors ---- */

/* Sparse rows (CSR): F_ij for j in col[rowptr[i] .. rowptr[i+1]), zero entries
 * (back-facing, coplanar, occluded) not stored.
 *
 * Buried parts: where another surface lies within a hair in front of a patch
 * (a mirror or a lamp panel mounted on a wall, a box standing on the floor),
 * the part of the patch under it can neither be seen nor lit. A Monte Carlo
 * ray whose first hit is the back of a surface closer than RAD_FF_BURY times
 * the patch's size started there: it is not counted, row i is the open part's
 * (hits / open rays), and open[i] = open rays / rays. The pass then uses
 * A_i open_i as the patch's area (reciprocity, solve, ledger, display), so
 * the dark underside does not pull the visible part's radiosity down (a wall
 * strip around a mirror was -10 %, rad_pass.c). A thin gap counts as a
 * cover: a ray that starts under the front of a surface that does not emit,
 * less than RAD_FF_BURY times the patch's size above its tangent plane, in
 * a slot about that wide on every side (a fixture hanging 3 mm under the
 * ceiling; the patch itself does not emit). Quadrature rows: open = 1.
 * The hierarchical method probes its elements by the same rule (rad_hier.c,
 * buried parts) and gives its leaves their open areas likewise. */
typedef struct rad_ff {
    size_t n;
    size_t *rowptr; /* n + 1 */
    uint32_t *col;
    double *val;
    double *open;   /* n: the open fraction of each patch's area, in [0, 1] */
} rad_ff;

/* Burial distance, relative to the patch's size sqrt(A_i) (rad_ff.c). */
#define RAD_FF_BURY 0.1

typedef enum rad_ff_method {
    RAD_FF_MONTE_CARLO = 0, /* cosine-weighted rays from each patch: F_ij = hits on j / rays */
    RAD_FF_QUADRATURE = 1   /* exact point-to-polygon factor at sample points x visibility rays */
} rad_ff_method;

typedef struct rad_ff_opts {
    rad_ff_method method;
    int samples;       /* Monte Carlo: rays per patch; quadrature: points per patch */
    uint64_t seed;     /* (the hierarchical method reads it in its estimate only: its tree is the
                          same for every seed) */
    int threads;       /* rows in parallel; 0 = OpenMP default (the result does not depend on it) */
    int raw;           /* 1: keep the estimates as computed (for tests of reciprocity);
                          0 (default): make them reciprocal, F_ij := A_j (F_ij + F_ji) / (A_i + A_j),
                          so the solved system conserves energy exactly, and (Monte Carlo) rebalance
                          the rows, A_i F_ij := s_i s_j A_i F_ij, so that each effective row sum is
                          the raw row's again (rad_ff.c, "Row sums") */
    int mirror_depth;  /* Monte Carlo: reflections a form-factor ray follows off mirrors
                          (extended form factors; 0 = mirrors end rays like any surface) */
    /* When set, receives the rays the form factors traced (all threads). */
    rt_ray_counts *rays;
    /* Progress: rows done of all, called from one thread at a time (NULL: none). */
    void (*progress)(void *user, size_t done, size_t total);
    void *progress_user;
    /* Interrupt (a SIGINT handler's flag): when it points to a non-zero value,
     * no further row starts and rad_ff_compute returns RR_ERR_INTERRUPTED. */
    const volatile sig_atomic_t *interrupt;
    /* Several processes (NULL: this one alone): rows come from dist's work
     * list, then every rank receives every row (gather), so that each ends
     * with the same matrix, bytes included. */
    rr_dist *dist;
} rad_ff_opts;

/* Form factors between all patches, visibility by the BVH a (built over s).
 * Deterministic for a seed whatever the thread count. */
rr_status rad_ff_compute(const scene *s, const rt_accel *a, const rad_patches *P, const rad_ff_opts *o, rad_ff **out,
                         rr_error *err);
void rad_ff_destroy(rad_ff *F);

/* The exact form factor from a differential area at p with unit normal n to
 * the polygon poly[0..nv) (Lambert's contour integral, Nusselt's analogue):
 *   F = 1/(2 pi) sum_k  angle_k * (n . unit(r_k x r_k+1)),
 * with r_k = poly[k] - p. The polygon's side facing p is what counts; a
 * polygon behind the tangent plane of p must be clipped by the caller. */
double rad_ff_point_polygon(rr_vec3 p, rr_vec3 n, const rr_vec3 *poly, int nv);
/* The same sum as a vector, turned towards the polygon (the irradiance
 * vector of a unit-radiosity polygon at p): the factor for a normal n is
 * n . v wherever the polygon lies in front of p's plane for n. */
rr_vec3 rad_ff_point_polygon_vec(rr_vec3 p, const rr_vec3 *poly, int nv);

/* ---- solving ---- */

typedef enum rad_solver { RAD_SOLVER_AUTO = 0, RAD_SOLVER_DIRECT = 1, RAD_SOLVER_ITERATIVE = 2 } rad_solver;

/* The solvers' tolerance where neither the options nor the scene's
 * radiosity.tolerance set one. The flat method's Gauss-Seidel stops at a
 * relative residual of 1e-9. The hierarchical method's Jacobi sweeps stop
 * when a sweep changes no leaf by more than 1e-6 of the largest B, and the
 * power that the change carries (over the leaves, area x the largest
 * channel) is under 10 x 1e-6 of the emitted power (rad_hier_solve.c): its
 * Monte Carlo visibility leaves errors near 1e-3, but the energy checks look
 * at 1e-4 of the balance, and the largest B is often a lamp's, whose room
 * then moves by more (a room under one black lamp balanced to 1.1e-4 by the
 * first test alone). The 11 sweeps from 1e-6 to 1e-9 were 4 % of
 * room.json's pass. */
#define RAD_FLAT_TOLERANCE 1e-9
#define RAD_HIER_TOLERANCE 1e-6
#define RAD_HIER_POWER_SHARE 10.0 /* the power test's share of the emitted power, in tolerances */

typedef struct rad_solve_opts {
    rad_solver solver;
    double tolerance;     /* iterative: stop when max relative residual < tolerance (<= 0: the method's default) */
    int max_iterations;
    int allow_rho_ge_1;   /* for tests only: accept reflectance >= 1 */
    size_t auto_direct_max; /* auto picks direct up to this many patches (0 = default) */
    /* Checked before every Gauss-Seidel sweep (a fraction of a second on 100k
     * patches): non-zero stops the solve with RR_ERR_INTERRUPTED. The direct
     * solver (at most a few thousand patches by default) is not interrupted. */
    const volatile sig_atomic_t *interrupt;
} rad_solve_opts;

typedef struct rad_solve_stats {
    rad_solver used;      /* what auto picked */
    int iterations;
    double residual;      /* final max relative residual, all channels */
    double tolerance;     /* the tolerance an iterative solve stopped at (0: a direct solve) */
    double *history;      /* residual after each iteration (iterative), malloc'd; free() it */
    int nhistory;
    double seconds;
} rad_solve_stats;

/* Solves B = E + rho F B for every patch and channel into B[0..n). Fails with
 * RR_ERR_INVALID when a reflectance is >= 1 (unless allowed) or no patch emits. */
rr_status rad_solve(const rad_patches *P, const rad_ff *F, const rad_solve_opts *o, rr_rgb *B, rad_solve_stats *stats,
                    rr_error *err);

/* ---- energy ledger ---- */

typedef struct rad_energy_row {
    char name[SCENE_NAME_MAX]; /* object name, light name, or "total" */
    int64_t object;    /* scene object, or -1 */
    int64_t light;     /* scene light, or -1 */
    double area;
    rr_rgb emitted;    /* surfaces: sum A_i E_i of their own emission; lights: their power (rt_light_power) */
    rr_rgb incident;   /* sum A_i (H_i + H0_i), H_i = sum_j F_ij B_j, H0_i the first shot (power arriving) */
    rr_rgb reflected;  /* rho * incident (diffusely) */
    rr_rgb mirrored;   /* rho_mirror * incident (reflected on by mirrors: it arrives again elsewhere) */
    rr_rgb absorbed;   /* (1 - rho - rho_mirror) * incident */
    rr_rgb escaped;    /* surfaces: sum B_i A_i (1 - sum_j F_ij (1 - rho_mirror_j)), what leaves them and
                          lands on no patch's front; lights: power - what lands on patch fronts */
} rad_energy_row;

/* One row per object that has patches, then a "total" row (rows[*nrows-1]).
 * In the total, emitted = absorbed + escaped up to the solver tolerance.
 * Without a solution, patch emission counts as emitted (no lights). *rows is
 * one malloc'd array that the caller owns and frees with free(); on failure
 * *rows is NULL (when rows and nrows are given). */
rr_status rad_energy(const scene *s, const rad_patches *P, const rad_ff *F, const rr_rgb *B, rad_energy_row **rows,
                     size_t *nrows, rr_error *err);
/* The ledger of a solution (needs its form factors: not one read from a
 * cache): rows per object with patches, then one per scene light (point and
 * directional lights as themselves: emitted = their power; their light
 * enters the patches as the first shot H0), then "total". Ownership as for
 * rad_energy: the caller frees *rows with free(). */
struct rad_solution;
rr_status rad_energy_solution(const struct rad_solution *sol, rad_energy_row **rows, size_t *nrows, rr_error *err);

/* ---- the radiosity ledger against the light tracer's (rt_particles_trace) ----
 *
 * Per object (and light) row, the mean over R, G, B of three columns
 * (emitted, incident, absorbed) and, for the total, of the escaped power
 * (the particles' escaped + back + lost: the radiosity ledger cannot tell
 * them apart). A comparison is checked when either ledger's value exceeds
 * min_share of the emitted power; it passes when
 *     |radiosity - particles| <= sigmas * SE + allowance * max(|radiosity|, |particles|),
 * SE the particles' standard error (mean of the channels' SEs). The
 * allowance is the discretisation error the radiosity pass is allowed
 * (piecewise-constant patches, form-factor noise); notes/energy.md. */
typedef struct rad_energy_cmp {
    char name[SCENE_NAME_MAX]; /* the row's name */
    int64_t object, light;     /* as in rad_energy_row (-1, -1: the total) */
    int column;                /* RT_LEDGER_EMITTED, _INCIDENT, _ABSORBED, or -1: escaped (total only) */
    double rad, part, se;      /* radiosity value, particle value and its standard error */
    double z;                  /* |rad - part| / se (INFINITY when se is 0 and they differ) */
    int checked, pass;
} rad_energy_cmp;

typedef struct rad_energy_check_opts {
    double sigmas;     /* <= 0: 4 */
    double allowance;  /* < 0: 0.01 */
    double min_share;  /* <= 0: 0.001 */
} rad_energy_check_opts;

/* Compares rows (rad_energy_solution) with the particle ledger g (of the
 * same scene). *out: the comparisons (free()), *failures: how many checked
 * ones fail. */
rr_status rad_energy_compare(const rad_energy_row *rows, size_t nrows, const rt_particle_ledger *g,
                             const rad_energy_check_opts *o, rad_energy_cmp **out, size_t *n, size_t *failures,
                             rr_error *err);

/* ---- the whole pass ---- */

/* The pass's method: hierarchical radiosity with clustering (rad_hier.c), or
 * the flat matrix of form factors between uniform patches (rad_ff.c). */
typedef enum rad_method { RAD_METHOD_FLAT = 0, RAD_METHOD_HIERARCHICAL = 1 } rad_method;

typedef struct rad_hier_opts {
    double tolerance;  /* a link stays when the power it carries, times the receiver's reflectance,
                          is under tolerance x the scene's emitted power; <= 0: from the scene */
    double min_area;   /* elements are not split below this area; <= 0: from the scene / automatic */
    double relative;   /* > 0: the receiver-first splits (partly visible, uneven, unevenly exposed or
                          occluded) also where a link may carry this share of its receiver's own power,
                          and leaves at contacts below min_area for the uneven test, down to a
                          sixteenth of it (radiosity.relative_tolerance; rad_hier.c, "Light near
                          occluders"); <= 0: from the scene, whose default 0 is off */
    size_t max_links;  /* the most links: past it the tolerance is raised 4x at a time (with a
                          warning); RR_ERR_INVALID where the cluster links that admissibility
                          needs do not fit; 0: from the scene */
    double max_bytes;  /* the same bound on the pass's own arrays (links, elements, clusters and
                          the leaves' patch set, as rad__hier_bytes counts them): the app
                          gives it what --max-memory leaves after the film and the BVH; <= 0: none.
                          Not in the cache key: a solution that it coarsened is not cached */
} rad_hier_opts;

typedef struct rad_pass_opts {
    rad_method method;      /* used when !use_scene_choices */
    rad_hier_opts hier;
    rad_patch_opts patch;   /* <= 0 fields: from the scene's "radiosity" block / automatic */
    rad_ff_opts ff;         /* samples <= 0: from the scene */
    rad_solve_opts solve;   /* tolerance <= 0: from the scene */
    int use_scene_choices;  /* 1: ff.method and solve.solver come from the scene */
    rr_warn_sink warn;      /* what the pass cannot carry (mirrors with quadrature form factors) */
} rad_pass_opts;

typedef struct rad_solution {
    rt_field field;      /* how the ray tracer reads it (rad_solution_field) */
    const scene *scene;  /* the scene it was computed for (not owned) */
    rad_patches *P;
    rad_ff *F;
    rr_rgb *B;           /* per patch radiosity */
    rr_rgb *vertex_B;    /* per patch vertex: area-weighted mean of the patches around it
                          * (the hierarchical method: then back-projected, RAD_HIND_SWEEPS) */
    rr_rgb *emitted;     /* per patch: pi Le of its material (the patches' emission minus the first shot below) */
    rr_rgb *first_shot;  /* per patch: irradiance from point and directional lights (shadowed) */
    rr_rgb *light_landed; /* per scene light: its power that ends on patch fronts, sum (1 - m_k) A_k H0_k */
    rr_rgb *vertex_Hind; /* per vertex: indirect irradiance, sum_j F_ij (B_j - emitted_j), area-weighted and
                          * back-projected (RAD_HIND_SWEEPS) */
    rad_solve_stats stats;
    /* hierarchical: seconds_ff is the refinement's (linking, the estimate,
     * the output), seconds_solve the Jacobi sweeps of every round */
    double seconds_patches, seconds_ff, seconds_solve;
    size_t nnz;          /* stored form factors (hierarchical: links) */
    rt_ray_counts ff_rays; /* rays the form factors traced (hierarchical: the refinement's, all but the output's
                              first shots); 0 when read from a cache */
    /* Hierarchical solutions (P->roots set): per leaf, the irradiance gathered
     * from other surfaces (H, without the first shot) and the effective row sum
     * (the share of what leaves it that lands on surfaces, times 1 - their
     * mirror reflectance, counted through the links it sends by: rad_hier_solve.c,
     * column_sums), for the ledger in place of F; NULL when read from a cache. */
    rr_rgb *hier_H;
    rr_rgb *hier_fsum;
    size_t links;        /* hierarchical: links of the final hierarchy */
    size_t receiving_clusters; /* hierarchical: the receiving leaf clusters that took links as one (the
                                  highest; radiosity.receiving_clusters); 0 when there were none */
    size_t elements;     /* hierarchical: elements and clusters made */
    int refine_rounds;
    int memory_bound;    /* hierarchical: rad_hier_opts.max_bytes coarsened it (not cached, as the key
                            does not hold the limit) */
    double pass_bytes;   /* hierarchical: rad__hier_bytes at the output (what the pass held at its peak) */
    /* hierarchical: wall seconds by stage, all rounds together (0 when read
     * from a cache): setup (roots, clusters, lights), link (the first walk
     * and the later rounds' relinking), settle (the new links' geometry and
     * shadow rays), regeo (the kept cluster links' geometry again), estimate
     * (the last draw of visibility), solve (every round's Jacobi sweeps, as
     * seconds_solve), output (leaves, display, first shots) */
    struct {
        double setup, link, settle, regeo, estimate, solve, output;
    } hier_seconds;
} rad_solution;

/* Patches, form factors, solve, vertex radiosity: everything the display and
 * the hybrid need. a must be built over s.
 *
 * Point and directional lights enter as a first shot: each patch's direct
 * irradiance H0 from them and from their images in planar mirrors (the light
 * interface, rt.h; shadow rays from 4 points of the patch) is reflected once,
 * rho * H0, and that is added to the patch's emission before solving (so the
 * ledger counts it as emitted by the patch). Mirrors: Monte Carlo form
 * factors are extended through them (ff.mirror_depth, default
 * render.max_depth). */
rr_status rad_pass_run(const scene *s, const rt_accel *a, const rad_pass_opts *o, rad_solution **out, rr_error *err);
void rad_solution_destroy(rad_solution *sol);

/* rad_pass_run through a cache file (cache_path NULL: no cache). A missing
 * file is made after the pass; an existing one is used when it was made for
 * the same scene and settings (*from_cache = 1; F is then NULL), and refused
 * with RR_ERR_INVALID when not. Over several ranks (o->ff.dist) only rank 0
 * writes the file. */
rr_status rad_pass_run_cached(const scene *s, const rt_accel *a, const rad_pass_opts *o, const char *cache_path,
                              int *from_cache, rad_solution **out, rr_error *err);

/* The patch limits the pass uses for s given o (resolving the automatic ones). */
rad_patch_opts rad_pass_patch_limits(const scene *s, const rad_pass_opts *o);
/* Bytes the pass needs at its peak for s given o (patches and their arrays,
 * and unless cached, the form factors: the raw rows copied into one matrix,
 * then its transpose and the reciprocal matrix over their union beside it);
 * *patches gets the patch count. Within 20 % of the measured peak on
 * scenes/room.json and the Cornell box at 108,854 patches (notes/hardening.md).
 * The hierarchical method: the least it needs (its roots as elements,
 * clusters and leaves, no links; a cache: the leaves, about the flat patch
 * count); how far it refines is not known before it runs, and it keeps
 * itself under rad_hier_opts.max_bytes instead (notes/radiosity.md). */
double rad_pass_memory_estimate(const scene *s, const rad_pass_opts *o, int cached, double *patches);

/* Radiance B/pi at a ray-tracer hit, interpolated from the vertex radiosity
 * across the patch (Gouraud). */
rr_rgb rad_radiance_at(const rad_solution *sol, const scene *s, const rt_hit *h);

/* The hybrid's indirect diffuse radiance at a hit on a surface of reflectance
 * rho: (rho / pi) times the indirect irradiance interpolated across the patch.
 * Indirect = everything that arrives after at least one diffuse reflection, so
 * the ray tracer's direct light (all lights, shadow rays) is not counted twice.
 * Its vertex values are the area-weighted means of the patches around each
 * vertex, then RAD_HIND_SWEEPS sweeps of back-projection, which bring the
 * interpolated irradiance's mean over each patch towards the patch's own: plain
 * means flatten a peak at a surface's edge (irradiance rises into a concave
 * corner), and a cubby's back came out 3.5 % dark (notes/radiosity.md). The
 * radiosity display (vertex_B) takes the same sweeps in the hierarchical
 * method: plain means brighten every concave edge where B falls towards it
 * (Cornell's display, block p90 5.6 -> 3.5 %). The flat method's display keeps
 * the plain means: its patches' noise dominates there, and sweeps amplify it. */
#define RAD_HIND_SWEEPS 2
rr_rgb rad_indirect_at(const rad_solution *sol, const scene *s, const rt_hit *h, rr_rgb rho);

/* The one way the solution reaches the ray tracer (rt_render_opts.field):
 * radiance = rad_radiance_at, indirect = rad_indirect_at, on the solution's
 * scene. sol (and its scene) must outlive the renders that use it. */
const rt_field *rad_solution_field(const rad_solution *sol);

#endif
