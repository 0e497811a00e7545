/* rt_internal.h - private to raytrace/: BVH layout and the shared kernels. */
#ifndef RT_INTERNAL_H
#define RT_INTERNAL_H

#include "rt.h"

/* Build depth limit of the binary build tree. The wide tree is no deeper, and
 * each wide level pushes at most RT_WIDE - 1 entries, so this bounds the
 * traversal stack (RT_STACK_SIZE). */
#define RT_BVH_STACK 64

/* A primitive: its kind and its index in the scene (triangle index, or object
 * index for spheres and solids). */
typedef struct rt_prim {
    uint32_t kind;
    uint32_t index;
} rt_prim;

/* 32 bytes: what the binary builder reads of an item (a primitive of the
 * scene BVH, or a mesh-leaf triangle): its box as floats rounded outward,
 * lo[3] = 0 and hi[3] = the item's number (bits of a uint32_t; set and read
 * with rt__bref_set / rt__bref_item). Four floats per corner: a box union is
 * two SIMD operations. */
typedef struct rt_bref {
    float lo[4], hi[4];
} rt_bref;
void rt__bref_set(rt_bref *r, rr_vec3 lo, rr_vec3 hi, uint32_t item);
/* rt__bref_set of a triangle's box from its three vertices (SSE2 where the
 * build has it: the same box values, a zero's sign aside). */
void rt__bref_tri(rt_bref *r, const rr_vec3 *a, const rr_vec3 *b, const rr_vec3 *c, uint32_t item);
uint32_t rt__bref_item(const rt_bref *r);

/* 32 bytes: a node of the binary build tree (rt_bvh.c builds it, then collapses
 * it into rt_wnode; it is not kept). Inner node (count == 0): left child is the
 * next node, right child is nodes[index]; leaf: refs[index .. index + count). */
typedef struct rt_node {
    float lo[3], hi[3];
    uint32_t index;
    uint16_t count;
    uint16_t axis;
} rt_node;

/* ---- the wide BVH the queries walk ----
 *
 * W children per node (W = 4, 8 or 16, chosen per accel at build time: see
 * rt_accel.width), their boxes stored SoA as floats rounded outward (so a box
 * still contains its primitives exactly): b[2k] = lower bounds on axis k,
 * b[2k+1] = upper bounds, one lane per child. An unused lane has the empty box
 * lo = +inf, hi = -inf, which every ray misses (no NaN arises from it, see
 * rt_wide.h). 128 bytes (two cache lines) for 4 wide, 256 for 8, 448 for 16.
 *
 * child[i]: an inner node's index in wnodes, or RT_LEAF | the index of the
 * leaf's first packet (rt_pk); a leaf runs to the packet flagged
 * RT_REF_LAST.
 *
 * Widths by RT_SIMD (set by CMake from RADRAY_SIMD):
 *   0 (OFF) / 1 (SSE)  4 wide only (scalar / SSE2 box test)
 *   2 (AVX2, or AUTO when the compiler targets AVX2)  8 wide, AVX2 everywhere
 *   3 (AUTO otherwise: runtime dispatch)  4 wide SSE2, plus 8 wide AVX2 in
 *     rt_bvh_avx2.c (the only file compiled for AVX2), used when the CPU has
 *     AVX2, and (RT_HAVE_AVX512: the compiler can build it) 16 wide AVX-512
 *     in rt_bvh_avx512.c, used when the CPU has AVX-512F
 *     (__builtin_cpu_supports at rt_accel_build)
 * In builds with the wider paths, RADRAY_BVH_WIDTH=4 or 8 in the environment
 * makes rt_accel_build use that width (tests and benchmarks). */
#if defined(RT_SIMD) && RT_SIMD >= 2
#define RT_HAVE_W8 1
#define RT_WIDE 8 /* the widest node of this build (bench/bench_rays.c prints it) */
#else
#define RT_HAVE_W8 0
#define RT_WIDE 4
#endif
#if RT_HAVE_W8 && RT_SIMD == 3 && defined(RT_HAVE_AVX512)
#define RT_HAVE_W16 1
#undef RT_WIDE
#define RT_WIDE 16
#define RT_WIDE_MAX 16
#else
#define RT_HAVE_W16 0
#define RT_WIDE_MAX 8
#endif
#define RT_LEAF 0x80000000u
#define RT_EMPTY 0xffffffffu
#define RT_STACK_SIZE ((RT_WIDE_MAX - 1) * RT_BVH_STACK + 1)

typedef struct rt_wnode4 {
    _Alignas(64) float b[6][4];
    uint32_t child[4];
    uint32_t pad[4];
} rt_wnode4;
typedef struct rt_wnode8 {
    _Alignas(64) float b[6][8];
    uint32_t child[8];
    uint32_t pad[8];
} rt_wnode8;
typedef struct rt_wnode16 {
    _Alignas(64) float b[6][16];
    uint32_t child[16];
} rt_wnode16;
_Static_assert(sizeof(rt_wnode4) == 128 && sizeof(rt_wnode8) == 256 && sizeof(rt_wnode16) == 448,
               "wide nodes: whole cache lines (aligned_alloc needs a multiple of 64)");
/* Bytes of one node of a width (4, 8 or 16). */
static inline size_t rt__wnode_bytes(int width)
{
    return width == 16 ? sizeof(rt_wnode16) : width == 8 ? sizeof(rt_wnode8) : sizeof(rt_wnode4);
}
/* The widest node of this build (sizes printed by the benchmark). */
#if RT_HAVE_W16
typedef rt_wnode16 rt_wnode;
#elif RT_HAVE_W8
typedef rt_wnode8 rt_wnode;
#else
typedef rt_wnode4 rt_wnode;
#endif

/* A leaf packet: up to RT_PK primitives of one leaf, in leaf order, SoA, so
 * that one float test over the packet (rt__pk_cand, rt_kernel.h) rejects the
 * triangles the ray clearly misses and only the rest go to the exact double
 * test. A leaf is one packet or more in a row, the last flagged RT_REF_LAST
 * (in its lane 0).
 *
 * v[3c + k][i]: lane i's vertex c (A, B, C), axis k. For a triangle whose
 * vertices are floats exactly (RT_REF_FAST: meshes from PLY, OBJ, STL) these
 * are the vertices themselves, and the exact test converts them back to the
 * same doubles, so results are those of the double vertices bit for bit.
 * Otherwise (RT_REF_DBL: scenes written in decimals, such as the Cornell box)
 * they are the vertices rounded to nearest float, for the float test only,
 * and the exact test reads the double copy at rt_accel.dverts[9 (RT_PK pk +
 * i) ..] (one slot per lane of every packet; dverts exists only when some
 * triangle needs it). Lanes of spheres and solids (RT_REF_PRIM) hold NaN
 * vertices, which the float test never rejects, and go through
 * rt__prim_hit. Unused lanes have ref 0.
 *
 * ref[i] = primitive index << RT_REF_SHIFT | the lane's bits: the scene
 * triangle index (FAST, DBL) or the object index (PRIM). Object and material
 * come from scene->tris at hit time. 160 bytes: 40 per triangle in a full
 * packet; primitives below 2^28 (rt__accel_build_width checks). */
#define RT_PK 4
#define RT_REF_LANE 0x3u /* the lane's kind: */
#define RT_REF_FAST 0x1u /*   triangle, v exact */
#define RT_REF_DBL 0x2u  /*   triangle, double copy in dverts */
#define RT_REF_PRIM 0x3u /*   sphere or solid (rt_prim_kind_of its object) */
#define RT_REF_CULL 0x4u /* triangle of an object that culls back faces */
#define RT_REF_LAST 0x8u /* in lane 0: the last packet of its leaf */
#define RT_REF_SHIFT 4
#define RT_REF_MAX (1u << (32 - RT_REF_SHIFT)) /* primitives per BVH, at most */
typedef struct rt_pk {
    _Alignas(16) float v[9][RT_PK];
    uint32_t ref[RT_PK];
} rt_pk;
_Static_assert(sizeof(rt_pk) == 160, "leaf packets: 160 bytes, 16-byte aligned rows");

struct rt_accel {
    const scene *scene;
    void *wnodes; /* rt_wnode4, rt_wnode8 or rt_wnode16 by width, 64-byte aligned; wnodes[0] is the root;
                     NULL when the scene has no primitives */
    size_t nwnodes;
    int width;  /* 4, 8 or 16: the node layout and the walk (rt__walk4 / 8 / 16) */
    rt_pk *pks; /* leaf packets (64-byte aligned) */
    size_t npks;
    size_t nprims;  /* primitives in the packets */
    double *dverts; /* 9 per packet lane (x, y, z of A, B, C) when some lane is RT_REF_DBL, else NULL */
    size_t ndverts; /* lanes in dverts: RT_PK npks, or 0 */
    /* The largest |coordinate| of any vertex in the packets, rounded up (the
     * float test's error bound, rt__pk_cand). */
    float vmax;
    struct rt_solid_accel *solids; /* per-mesh-leaf BVHs of the scene's solids (rt_solid.c); NULL if none */
};

/* Per-ray constants of the watertight test (Woop et al. 2013, rt_kernel.h),
 * the solids' mesh-leaf crossings (rt_solid_mesh.c) and the slab tests
 * (rt_wide.h): every query prepares its ray once, with rt__ray_prepare, or
 * (the walks) its two halves from rt_kernel.h, rt__ray_prepare_box and
 * rt__ray_prepare_tri (the packet walks: at a ray's first leaf). */
typedef struct rt_ray_pre {
    rr_ray ray;
    int kx, ky, kz;
    double Sx, Sy, Sz;
    double ok[3]; /* the origin's coordinates kx, ky, kz */
    double inv[3];
    int neg[3]; /* the sign bit of d (so -0 counts as negative, like 1/-0 = -inf) */
    /* Float slab test: the origin rounded towards the near planes (org_near)
     * and towards the far planes (org_far), 1/d rounded to float, and which
     * row of rt_wnode.b holds each axis's near planes (2k + neg[k]). */
    float org_near[4], org_far[4], inv_f[4]; /* [3]: unused (SSE stores) */
    int near_row[3];
    /* 1 when the float test is not safe for this ray (coordinates beyond
     * 1e30, direction components outside [1e-30, 1e30], tmin < 0): the
     * double test is used instead. */
    int box_double;
    /* RT_REF_CULL: back faces of objects that cull them are culled; 0 in a
     * two-sided query (rt_accel_closest_two_sided), which sees them all. */
    uint32_t cull_mask;
} rt_ray_pre;

void rt__ray_prepare(rr_ray ray, rt_ray_pre *p);

/* Watertight ray/triangle test. Returns 1 with *t and *front (1 when the ray
 * meets the counter-clockwise side) for a hit with tmin < t < tmax. cull:
 * reject back faces. */
int rt__tri_hit(const rt_ray_pre *p, rr_vec3 A, rr_vec3 B, rr_vec3 C, int cull, double tmin, double tmax, double *t,
                int *front);

/* ---- the one BVH builder (rt_bvh_binary.c) ----
 * A binary tree over refs[0..n) (n >= 1) by binned SAH, leaves of at most
 * 8 items (deeper than RT_BVH_STACK - 2: a leaf); a node of at most
 * leaf_items items is a leaf whatever SAH says, unless its box has more than
 * 1/256 of the root's area (RT_BIG_NODE; the scene BVH: RT_PK, one
 * packet; the solids' mesh leaves: 1, SAH alone decides), in one array in
 * depth-first order (left child next, right child at index), float bounds
 * that contain the refs' boxes; refs are reordered into leaf order (the
 * caller maps rt__bref_item back to its items). The scene BVH collapses it
 * into wide nodes; the solids' mesh leaves walk it as it is
 * (rt_solid_mesh.c). *nodes: NULL on entry, then malloc'd (the caller
 * frees it); or storage for 2 n - 1 nodes that the caller owns (the scene
 * BVH's, whose leaf packets later go into the same pages, rt_bvh.c). 0, or
 * -1 when out of memory.
 * Built by `threads` threads (0: OpenMP's default): the nodes of >= 65536
 * items as tasks, the subtrees below them by a parallel loop: the same
 * nodes for any count, bytes included. */
int rt__bvh_build_binary(rt_bref *refs, size_t n, size_t leaf_items, int threads, rt_node **nodes, size_t *nnodes);
/* Nodes of at least this many items are split as OpenMP tasks, each
 * subtree in slots of its own in the one node array, which is then
 * compacted into the order of the serial build (node, left subtree, right
 * subtree): the same splits, the same node array, bytes included, for any
 * thread count. The subtrees below it are built (and the collapse's costs
 * computed) by a parallel loop, one thread each, largest first: as nested
 * tasks libgomp ran them on one thread. */
#define RT_BUILD_TASK_MIN 65536

/* ---- the BVH by width (rt_bvh.c, rt_traverse.c, rt_bvh_avx2.c) ---- */

/* The width rt_accel_build uses: the widest that this build and the CPU
 * have (16: AVX-512F, 8: AVX2, else 4), or RADRAY_BVH_WIDTH (4 or 8) when set
 * and available. */
int rt__bvh_width_default(void);
/* 1 when width (4, 8 or 16) can be built and walked on this build and CPU. */
int rt__bvh_width_ok(int width);
/* rt_accel_build with a given width (0 = rt__bvh_width_default()); a width
 * that rt__bvh_width_ok rejects is RR_ERR_INVALID. For tests. */
rr_status rt__accel_build_width(const scene *s, int width, rt_accel **out, rr_error *err);
/* The walks of one width; any != 0 returns at the first hit (hit unused). */
#define RT_WALK_ANY 1        /* return at the first hit (no hit record) */
#define RT_WALK_TWO_SIDED 2  /* cull no back faces (rt_accel_closest_two_sided) */
/* Two-sided walks: how far (relative) beyond a front-face hit a back face of
 * a culling object still counts as first (flush faces, rt_wide.h). */
#define RT_TIE_REL 1e-9
int rt__walk4(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int mode);
/* The packet walks of one width (rt_accel_closest_n): nr <= RT_PACKET_MAX rays
 * together, each with rt__walkN's answer (mode 0), bit for bit (rt_packet.h). */
int rt__walkn4(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, rt_hit *hits,
               unsigned char *found);
/* The any-hit walks of one width (rt_accel_occluded): the same answer as
 * rt__walkN with any != 0, without ordering the children (rt_wide.h). */
int rt__occl4(const rt_accel *a, rr_ray ray, double tmin, double tmax);
/* The packet any-hit walks (rt_accel_occluded_n): nr <= RT_PACKET_MAX rays,
 * occ[r] = rt__occlN's answer for ray r (rt_packet_occl.h). */
int rt__occln4(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, unsigned char *occ);
#if RT_HAVE_W8
int rt__walk8(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int mode);
int rt__occl8(const rt_accel *a, rr_ray ray, double tmin, double tmax);
int rt__walkn8(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, rt_hit *hits,
               unsigned char *found);
int rt__occln8(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, unsigned char *occ);
unsigned rt__box8_test(const void *node, rr_ray ray, double tmin, double tmax, float *dist, int *fast);
#endif
#if RT_HAVE_W16
int rt__walk16(const rt_accel *a, rr_ray ray, double tmin, double tmax, rt_hit *hit, int mode);
int rt__occl16(const rt_accel *a, rr_ray ray, double tmin, double tmax);
int rt__walkn16(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, rt_hit *hits,
                unsigned char *found);
int rt__occln16(const rt_accel *a, const rr_ray *rays, int nr, double tmin, double tmax, unsigned char *occ);
unsigned rt__box16_test(const void *node, rr_ray ray, double tmin, double tmax, float *dist, int *fast);
#endif

/* ---- rt_solid.c: acceleration for the solids' mesh leaves ---- */
rr_status rt__solids_build(const scene *s, struct rt_solid_accel **out, rr_error *err);
void rt__solids_destroy(struct rt_solid_accel *sa); /* NULL is a no-op */
size_t rt__solids_bytes(const struct rt_solid_accel *sa); /* 0 for NULL */

/* ---- rt_prim.c: the primitive table as the BVH reads it (rt.h: rt_prims) ---- */

/* How many primitives the scene has: its triangles (primitives 0 ..
 * ntris - 1, triangle i the i-th), then one per sphere or solid object,
 * which rt__prim_others lists in object order (out has rt__prim_count -
 * ntris entries). */
size_t rt__prim_count(const scene *s);
void rt__prim_others(const scene *s, rt_prim *out);
/* World-space bounds of one primitive (containing it exactly). */
void rt__prim_bounds(const scene *s, rt_prim p, rr_vec3 *lo, rr_vec3 *hi);
/* Intersects one primitive; on a hit with tmin < t < *tmax fills hit (when not
 * NULL; hit->point is left to the caller) and lowers *tmax. */
int rt__prim_hit(const rt_accel *a, rt_prim pr, const rt_ray_pre *p, double tmin, double *tmax, rt_hit *hit);
/* rt_solid_closest with the culling given (cull: the object's, or 0 in a
 * two-sided query); obj must be a solid (SCENE_OBJ_CSG). */
int rt__solid_closest(const scene *s, const rt_accel *a, uint32_t obj, rr_ray ray, double tmin, double tmax, int cull,
                      rt_hit *hit);

#endif
