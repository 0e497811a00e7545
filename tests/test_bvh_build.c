/* test_bvh_build.c - white-box tests of the BVH build (raytrace/rt_bvh.c,
 * rt_bvh_binary.c): the same tree for any thread count, bytes included; the
 * binary builder's leaves of one packet, and its large nodes of few items
 * split by SAH. (The walks and box tests: test_bvh.c.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "rr_rng.h"
#include "rt.h"
#include "rt_wide.h" /* private header of raytrace/ */
#include "test_bvh_util.h"
#include "test_scenes.h"

/* The build runs subtrees of >= 65536 items as OpenMP tasks (rt_bvh.c): 1, 2
 * and 3 threads must give the same nodes and packets, bytes included. A
 * sphere of 300 x 400 (about 240k triangles, 4 levels of tasks), with double
 * vertices (RT_REF_DBL lanes) and after rounding them to floats. */
static void bvh_build_threads_same_tree(void **state)
{
    (void)state;
    char *json = uv_sphere_scene(300, 400, "\"auto\"");
    scene *s = NULL;
    assert_int_equal(scene_load_string(json, "uv-sphere", "", NULL, &s, NULL), RR_OK);
    free(json);
    assert_true(s->ntris > 4 * 65536 / 2);
    int before = omp_get_max_threads();
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1)
            verts_to_float(s);
        rt_accel *a[3] = {NULL, NULL, NULL};
        for (int t = 0; t < 3; t++) {
            omp_set_num_threads(t + 1);
            assert_int_equal(rt_accel_build(s, &a[t], NULL), RR_OK);
        }
        omp_set_num_threads(before);
        size_t nb = a[0]->nwnodes * rt__wnode_bytes(a[0]->width);
        for (int t = 1; t < 3; t++) {
            assert_int_equal(a[t]->nwnodes, a[0]->nwnodes);
            assert_int_equal(a[t]->npks, a[0]->npks);
            assert_int_equal(a[t]->ndverts, a[0]->ndverts);
            assert_memory_equal(a[t]->wnodes, a[0]->wnodes, nb);
            assert_memory_equal(a[t]->pks, a[0]->pks, a[0]->npks * sizeof(rt_pk));
            if (a[0]->ndverts)
                assert_memory_equal(a[t]->dverts, a[0]->dverts, a[0]->ndverts * 9 * sizeof(double));
        }
        assert_true(pass == 1 ? a[0]->ndverts == 0 : a[0]->ndverts > s->ntris / 2);
        for (int t = 0; t < 3; t++)
            rt_accel_destroy(a[t]);
    }
    scene_destroy(s);
}

/* Items under binary node i (a leaf's count, an inner node's two subtrees);
 * *leaves / *small_inner count the leaves and the inner nodes of at most 4
 * items, and seen[] each item's leaves. */
static size_t binary_items(const rt_node *nodes, size_t i, const rt_bref *refs, unsigned char *seen, size_t *leaves,
                           size_t *small_inner)
{
    const rt_node *nd = &nodes[i];
    if (nd->count) {
        assert_true(nd->count <= 8);
        for (size_t k = nd->index; k < nd->index + nd->count; k++)
            seen[rt__bref_item(&refs[k])]++;
        (*leaves)++;
        return nd->count;
    }
    size_t m = binary_items(nodes, i + 1, refs, seen, leaves, small_inner) +
               binary_items(nodes, nd->index, refs, seen, leaves, small_inner);
    *small_inner += m <= 4;
    return m;
}

/* rt__bvh_build_binary's leaf_items: with RT_PK (the scene BVH's packets),
 * no inner node holds that few items; with 1 (the solids' mesh leaves) SAH
 * alone decides and splits such nodes (many of them in a cloud of small
 * boxes). Every item in exactly one leaf either way. */
static void bvh_binary_leaf_items(void **state)
{
    (void)state;
    enum { N = 20000 };
    rt_bref *refs = malloc(N * sizeof *refs);
    unsigned char *seen = malloc(N);
    assert_non_null(refs);
    assert_non_null(seen);
    for (int pass = 0; pass < 2; pass++) {
        size_t leaf_items = pass == 0 ? RT_PK : 1;
        rr_rng rng = rr_rng_make(11, 0);
        for (uint32_t k = 0; k < N; k++) {
            rr_vec3 c = rr_v3(rr_rng_uniform(&rng), rr_rng_uniform(&rng), rr_rng_uniform(&rng));
            rr_vec3 h = rr_v3(0.002, 0.002, 0.002);
            rt__bref_set(&refs[k], rr_v3_sub(c, h), rr_v3_add(c, h), k);
        }
        rt_node *nodes = NULL;
        size_t nn = 0, leaves = 0, small_inner = 0;
        assert_int_equal(rt__bvh_build_binary(refs, N, leaf_items, 1, &nodes, &nn), 0);
        memset(seen, 0, N);
        assert_int_equal(binary_items(nodes, 0, refs, seen, &leaves, &small_inner), N);
        for (size_t k = 0; k < N; k++)
            assert_int_equal(seen[k], 1);
        assert_int_equal(nn, 2 * leaves - 1);
        print_message("leaf_items %zu: %zu leaves, %zu inner nodes of <= 4 items\n", leaf_items, leaves, small_inner);
        if (pass == 0)
            assert_int_equal(small_inner, 0);
        else
            assert_true(small_inner > N / 20);
        free(nodes);
    }
    free(refs);
    free(seen);
}

/* Walls in a leaf of the binary tree (items n + 2 w and n + 2 w + 1 are
 * wall w's two triangles): a leaf that holds two walls counts in *mixed. */
static void big_node_leaves(const rt_node *nodes, size_t i, const rt_bref *refs, uint32_t n, int *mixed)
{
    const rt_node *nd = &nodes[i];
    if (nd->count) {
        unsigned walls = 0;
        for (size_t k = nd->index; k < nd->index + nd->count; k++) {
            uint32_t it = rt__bref_item(&refs[k]);
            if (it >= n)
                walls |= 1u << ((it - n) / 2);
        }
        *mixed += walls != 0 && (walls & (walls - 1)) != 0;
        return;
    }
    big_node_leaves(nodes, i + 1, refs, n, mixed);
    big_node_leaves(nodes, nd->index, refs, n, mixed);
}

/* A node of RT_PK items or fewer whose box is large against the root's is
 * split as SAH says (RT_BIG_NODE): the six walls of a room (two triangles
 * each, as large as the room) around a cloud of small items end in leaves
 * of one wall each, not in leaves whose box is most of the room, which
 * nearly every ray inside the room would enter. With leaf_items 1 SAH
 * splits them too. */
static void bvh_binary_big_nodes_split(void **state)
{
    (void)state;
    enum { N = 2000 };
    rt_bref *refs = malloc((N + 12) * sizeof *refs);
    assert_non_null(refs);
    for (int pass = 0; pass < 2; pass++) {
        rr_rng rng = rr_rng_make(12, 0);
        for (uint32_t k = 0; k < N; k++) {
            rr_vec3 c = rr_v3(0.3 + 0.4 * rr_rng_uniform(&rng), 0.3 * rr_rng_uniform(&rng),
                              0.3 + 0.4 * rr_rng_uniform(&rng));
            rr_vec3 h = rr_v3(0.001, 0.001, 0.001);
            rt__bref_set(&refs[k], rr_v3_sub(c, h), rr_v3_add(c, h), k);
        }
        /* The walls of the room [0, 2] x [0, 1] x [0, 2]: x = 0, x = 2, y = 0, y = 1, z = 0, z = 2. */
        for (uint32_t w = 0; w < 6; w++) {
            int axis = (int)w / 2;
            double at = (w & 1) ? (axis == 1 ? 1.0 : 2.0) : 0.0;
            double lo[3] = {0, 0, 0}, hi[3] = {2, 1, 2};
            lo[axis] = hi[axis] = at;
            for (uint32_t k = 0; k < 2; k++)
                rt__bref_set(&refs[N + 2 * w + k], rr_v3(lo[0], lo[1], lo[2]), rr_v3(hi[0], hi[1], hi[2]),
                             N + 2 * w + k);
        }
        rt_node *nodes = NULL;
        size_t nn = 0;
        assert_int_equal(rt__bvh_build_binary(refs, N + 12, pass == 0 ? RT_PK : 1, 1, &nodes, &nn), 0);
        int mixed = 0;
        big_node_leaves(nodes, 0, refs, N, &mixed);
        assert_int_equal(mixed, 0);
        free(nodes);
    }
    free(refs);
}

/* rt__bref_tri (the build's triangle boxes, SSE2 where the build has it)
 * against rt__bref_set of the vertices' min and max (the scalar reference,
 * rt__f_up and rt__f_down): the same box values and item for coordinates of
 * every magnitude and sign, floats exactly and between floats; and every
 * box holds its vertices (in double) with corners at most one float step
 * outside them. */
static void bref_tri_matches_set(void **state)
{
    (void)state;
    rr_rng g = rr_rng_make(17, 3);
    const double scales[] = {1.0, 1e-30, 1e-42, 3e5, 1e30, 1e38};
    for (int k = 0; k < 60000; k++) {
        rr_vec3 v[3];
        double sc = scales[k % 6];
        for (int c = 0; c < 3; c++) {
            double x[3];
            for (int a = 0; a < 3; a++) {
                double u = 2.0 * rr_rng_uniform(&g) - 1.0;
                /* a third exact floats, some zeros, the rest doubles */
                int how = (int)(rr_rng_u32(&g) % 7);
                x[a] = how == 0 ? 0.0 : how == 1 ? -0.0 : how < 4 ? (double)(float)(u * sc) : u * sc;
            }
            v[c] = rr_v3(x[0], x[1], x[2]);
        }
        uint32_t item = rr_rng_u32(&g) % RT_REF_MAX;
        rt_bref fast, ref;
        rt__bref_tri(&fast, &v[0], &v[1], &v[2], item);
        rr_vec3 lo = rr_v3_min(rr_v3_min(v[0], v[1]), v[2]), hi = rr_v3_max(rr_v3_max(v[0], v[1]), v[2]);
        rt__bref_set(&ref, lo, hi, item);
        double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
        for (int a = 0; a < 3; a++) {
            assert_true(fast.lo[a] == ref.lo[a]);
            assert_true(fast.hi[a] == ref.hi[a]);
            assert_true((double)fast.lo[a] <= l[a] && (double)fast.hi[a] >= h[a]);
            assert_true(nextafterf(fast.lo[a], INFINITY) > l[a] || (double)fast.lo[a] == l[a]);
            assert_true(nextafterf(fast.hi[a], -INFINITY) < h[a] || (double)fast.hi[a] == h[a]);
        }
        assert_true(fast.lo[3] == 0.0f);
        assert_int_equal(rt__bref_item(&fast), item);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(bvh_build_threads_same_tree),
        cmocka_unit_test(bvh_binary_leaf_items),
        cmocka_unit_test(bvh_binary_big_nodes_split),
        cmocka_unit_test(bref_tri_matches_set),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
