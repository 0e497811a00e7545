/* test_examples.c - the example scenes that reproduce the lecture's
 * comparisons load and show what their descriptions promise:
 *
 *  - scenes/sphere-to-board.json: the white board under the red sphere turns
 *    red in the hybrid (radiosity indirect layer) and with secondary rays, and
 *    stays untinted in Whitted mode (no indirect layer, a grey ambient term);
 *  - scenes/board-to-sphere.json: the underside of the white sphere turns
 *    green over the green board, the same way;
 *  - scenes/csg.json: the three solids (lens, bitten sphere, drilled mesh)
 *    load as CSG trees and take part in the radiosity pass: the floor next to
 *    the red bitten sphere turns red in the hybrid as with secondary rays;
 *  - scenes/room.json: a mirror, a glossy material, lights, inward-facing
 *    walls, and at least 100,000 radiosity patches at its own settings (only
 *    the patches are built here: solving the room takes tens of seconds).
 *
 * Small and quick: 61 px wide, coarser patches and fewer form-factor rays
 * than the scene files ask for (the tint is a ratio of colours, not a value
 * that needs the fine solution). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ig.h"
#include "rad.h"

static scene *load_scene(const char *file)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/%s", RR_SOURCE_DIR, file);
    scene *s = NULL;
    rr_error err;
    if (scene_load(path, NULL, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

static int find_object(const scene *s, const char *name)
{
    for (size_t i = 0; i < s->nobjects; i++)
        if (strcmp(s->objects[i].name, name) == 0)
            return (int)i;
    fail_msg("%s: no object '%s'", s->path, name);
    return -1;
}

/* Renders of one small view in the three modes that matter here. */
typedef struct renders {
    scene *s;
    rt_accel *a;
    ig_session ses; /* its sol: the radiosity pass shared by the renders */
    rad_solution *sol;
    rr_view v;
    rt_film hybrid, whitted, secondary;
} renders;

static void render_all(renders *r, const char *file)
{
    memset(r, 0, sizeof *r);
    r->s = load_scene(file);
    assert_int_equal(rr_view_resize(&r->s->view, 61, &r->v, NULL), RR_OK);
    r->s->view = r->v;
    assert_int_equal(rt_accel_build(r->s, &r->a, NULL), RR_OK);

    /* Coarser than the file's patches (which are sized for the full image). */
    ig_session_init(&r->ses, r->s, r->a);
    r->ses.pass.patch.max_area = 0.02;
    r->ses.pass.ff.samples = 1024;
    r->ses.pass.ff.seed = 1;
    rr_error err;
    if (ig_session_field(&r->ses, &err) != RR_OK)
        fail_msg("%s", err.msg);
    r->sol = r->ses.sol;

    int w = r->v.width, h = r->v.height;
    assert_int_equal(rt_film_init(&r->hybrid, w, h, NULL), RR_OK);
    assert_int_equal(rt_film_init(&r->whitted, w, h, NULL), RR_OK);
    assert_int_equal(rt_film_init(&r->secondary, w, h, NULL), RR_OK);
    r->s->settings.spp = 4;
    r->s->settings.seed = 3;
    r->s->settings.max_depth = 5;
    r->s->settings.light_samples = 4;
    r->s->settings.threads = 2;
    assert_int_equal(ig_render(&r->ses, ig_find("hybrid"), NULL, &r->hybrid, NULL, NULL), RR_OK);
    assert_int_equal(ig_render(&r->ses, ig_find("whitted"), NULL, &r->whitted, NULL, NULL), RR_OK);
    r->s->settings.spp = 64;
    assert_int_equal(ig_render(&r->ses, ig_find("secondary"), NULL, &r->secondary, NULL, NULL), RR_OK);
}

static void free_all(renders *r)
{
    rt_film_free(&r->hybrid);
    rt_film_free(&r->whitted);
    rt_film_free(&r->secondary);
    ig_session_free(&r->ses);
    rt_accel_destroy(r->a);
    scene_destroy(r->s);
}

/* The object a pixel sees when its centre and its four edge midpoints all hit
 * the same object (pixel samples stay inside the pixel with the box filter),
 * else -1; *hit gets the centre's hit. */
static int pixel_object(const renders *r, int x, int y, rt_hit *hit)
{
    if (!rt_accel_closest(r->a, rr_view_ray(&r->v, x, y, 0, 0), 0, INFINITY, hit))
        return -1;
    for (int d = 0; d < 4; d++) {
        double dx = d < 2 ? (d ? -0.5 : 0.5) : 0, dy = d >= 2 ? (d == 3 ? -0.5 : 0.5) : 0;
        rt_hit h2;
        if (!rt_accel_closest(r->a, rr_view_ray(&r->v, x, y, dx, dy), 0, INFINITY, &h2) || h2.object != hit->object)
            return -1;
    }
    return (int)hit->object;
}

/* Sums of a layer over the pixels selected by mask (1 = in the region). */
static rr_rgb region_sum(const rr_image *img, const unsigned char *mask)
{
    rr_rgb sum = rr_rgb_make(0, 0, 0);
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            if (mask[(size_t)y * (size_t)img->width + (size_t)x])
                sum = rr_rgb_add(sum, rr_image_get(img, x, y));
    return sum;
}

/* The tint checks shared by both scenes: in the region, the hybrid's and the
 * secondary rays' indirect layers have channel `hue` over channel `other` by
 * more than `ratio`; Whitted mode has no indirect layer at all and an
 * untinted ambient layer (grey ambient light on a grey surface). */
static void check_tint(const renders *r, const unsigned char *mask, int hue, int other, double ratio,
                       const char *what)
{
    rr_rgb hy = region_sum(&r->hybrid.layer[RT_LAYER_INDIRECT], mask);
    rr_rgb se = region_sum(&r->secondary.layer[RT_LAYER_INDIRECT], mask);
    rr_rgb wa = region_sum(&r->whitted.layer[RT_LAYER_AMBIENT], mask);
    double hc[3] = {hy.r, hy.g, hy.b}, sc[3] = {se.r, se.g, se.b}, ac[3] = {wa.r, wa.g, wa.b};
    if (!(hc[other] > 0 && hc[hue] > ratio * hc[other]))
        fail_msg("%s: hybrid indirect %g %g %g, want channel %d > %g x channel %d", what, hy.r, hy.g, hy.b, hue, ratio,
                 other);
    if (!(sc[other] > 0 && sc[hue] > ratio * sc[other]))
        fail_msg("%s: secondary indirect %g %g %g, want channel %d > %g x channel %d", what, se.r, se.g, se.b, hue,
                 ratio, other);
    print_message("%s: indirect channel %d / channel %d: hybrid %.1f, secondary %.1f; hybrid / secondary %.3f\n",
                  what, hue, other, hc[hue] / hc[other], sc[hue] / sc[other], hc[hue] / sc[hue]);
    /* The hybrid's indirect light is the secondary rays' up to the coarse
     * patches used here (measured 0.91 and 0.94). */
    if (!(hc[hue] > 0.75 * sc[hue] && hc[hue] < 1.25 * sc[hue]))
        fail_msg("%s: hybrid indirect %g vs secondary %g", what, hc[hue], sc[hue]);
    /* Whitted: nothing in the indirect layer anywhere. */
    for (int y = 0; y < r->whitted.layer[RT_LAYER_INDIRECT].height; y++)
        for (int x = 0; x < r->whitted.layer[RT_LAYER_INDIRECT].width; x++) {
            rr_rgb c = rr_image_get(&r->whitted.layer[RT_LAYER_INDIRECT], x, y);
            if (c.r != 0 || c.g != 0 || c.b != 0)
                fail_msg("%s: whitted indirect layer not 0 at (%d, %d)", what, x, y);
        }
    /* The ambient term is there and carries no tint from the neighbour. */
    assert_true(ac[hue] > 0);
    if (!(fabs(ac[hue] - ac[other]) <= 1e-6 * ac[hue]))
        fail_msg("%s: whitted ambient %g %g %g is tinted", what, wa.r, wa.g, wa.b);
}

/* The board right under the red sphere: pixels that see only the board (see
 * pixel_object), with the centre within 0.6 of the point below the sphere's centre. */
static void sphere_to_board(void **state)
{
    (void)state;
    renders r;
    render_all(&r, "sphere-to-board.json");
    const scene *s = r.s;
    int board = find_object(s, "board"), ball = find_object(s, "sphere");
    const scene_material *red = &s->materials[s->objects[ball].material];
    const scene_material *white = &s->materials[s->objects[board].material];
    assert_true(red->diffuse.r > 8 * red->diffuse.g);
    assert_true(white->diffuse.r == white->diffuse.g && white->diffuse.g == white->diffuse.b);
    rr_vec3 below = s->objects[ball].center;
    below.y = s->verts[s->tris[s->objects[board].tri_first].v[0]].y;

    int w = r.v.width, h = r.v.height, n = 0;
    unsigned char mask[61 * 61];
    assert_true((size_t)w * (size_t)h <= sizeof mask);
    memset(mask, 0, sizeof mask);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            rt_hit hit;
            if (pixel_object(&r, x, y, &hit) == board && rr_v3_len(rr_v3_sub(hit.point, below)) < 0.6) {
                mask[(size_t)y * (size_t)w + (size_t)x] = 1;
                n++;
            }
        }
    if (n < 20)
        fail_msg("only %d board pixels under the sphere", n);
    check_tint(&r, mask, 0, 1, 4.0, "board under the red sphere");

    /* The tint is no trace: the red light reflected onto the board there is a
     * visible part of the image (the board sees only the sphere and the lamp,
     * which reflects nothing: diffuse 0). */
    rr_rgb under = region_sum(&r.hybrid.layer[RT_LAYER_INDIRECT], mask);
    rr_rgb all = region_sum(&r.hybrid.beauty, mask);
    print_message("board under the red sphere: %d pixels, indirect red %.3f of the image's red\n", n, under.r / all.r);
    assert_true(under.r > 0.1 * all.r);
    free_all(&r);
}

/* The sphere's underside over the green board: pixels that see only the
 * sphere, with the centre's normal pointing down. */
static void board_to_sphere(void **state)
{
    (void)state;
    renders r;
    render_all(&r, "board-to-sphere.json");
    const scene *s = r.s;
    int board = find_object(s, "board"), ball = find_object(s, "sphere");
    const scene_material *green = &s->materials[s->objects[board].material];
    const scene_material *white = &s->materials[s->objects[ball].material];
    assert_true(green->diffuse.g > 8 * green->diffuse.r);
    assert_true(white->diffuse.r == white->diffuse.g && white->diffuse.g == white->diffuse.b);

    int w = r.v.width, h = r.v.height, n = 0;
    unsigned char mask[61 * 61];
    assert_true((size_t)w * (size_t)h <= sizeof mask);
    memset(mask, 0, sizeof mask);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            rt_hit hit;
            if (pixel_object(&r, x, y, &hit) == ball && hit.normal.y < -0.3) {
                mask[(size_t)y * (size_t)w + (size_t)x] = 1;
                n++;
            }
        }
    if (n < 20)
        fail_msg("only %d pixels on the sphere's underside", n);
    print_message("underside of the white sphere: %d pixels\n", n);
    check_tint(&r, mask, 1, 0, 4.0, "underside of the white sphere");
    /* The underside gets no direct light (the lamp is above the sphere). */
    rr_rgb direct = region_sum(&r.hybrid.layer[RT_LAYER_DIFFUSE], mask);
    rr_rgb ind = region_sum(&r.hybrid.layer[RT_LAYER_INDIRECT], mask);
    assert_true(direct.g < 0.1 * ind.g);
    free_all(&r);
}

/* The room: what its description promises, checked on the loaded scene and on
 * the radiosity patches at the file's own limits (not solved here). */
static void room(void **state)
{
    (void)state;
    scene *s = load_scene("room.json");
    int mirrors = 0, glossy = 0;
    for (size_t i = 0; i < s->nmaterials; i++) {
        const scene_material *m = &s->materials[i];
        if (m->mirror.r >= 0.8 && m->mirror.g >= 0.8 && m->mirror.b >= 0.8 && m->diffuse.r == 0 && m->diffuse.g == 0 &&
            m->diffuse.b == 0)
            mirrors++;
        if (m->specular.r > 0.2 && m->k > 10 && m->mirror.r == 0)
            glossy++;
    }
    assert_true(mirrors >= 1);
    assert_true(glossy >= 1);
    assert_true(s->nemissive >= 4); /* ceiling lamp and window: two quads */
    /* Objects that use the mirror and glossy materials exist. */
    int used_mirror = 0, used_glossy = 0;
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_material *m = &s->materials[s->objects[i].material];
        used_mirror |= m->mirror.r >= 0.8;
        used_glossy |= m->specular.r > 0.2 && m->mirror.r == 0;
    }
    assert_true(used_mirror && used_glossy);

    /* The room's quads face into the room: their normals point towards the
     * middle of the room's bounding box. */
    static const char *const walls[] = {"floor", "ceiling", "back_wall", "front_wall", "left_wall", "right_wall"};
    rr_vec3 mid = rr_v3_scale(rr_v3_add(s->bbox_min, s->bbox_max), 0.5);
    for (size_t k = 0; k < sizeof walls / sizeof walls[0]; k++) {
        const scene_object *o = &s->objects[find_object(s, walls[k])];
        assert_int_equal(o->tri_count, 2);
        for (size_t t = o->tri_first; t < o->tri_first + o->tri_count; t++) {
            const scene_tri *tr = &s->tris[t];
            rr_vec3 c = rr_v3_scale(rr_v3_add(rr_v3_add(s->verts[tr->v[0]], s->verts[tr->v[1]]), s->verts[tr->v[2]]),
                                    1.0 / 3.0);
            if (!(rr_v3_dot(scene_tri_normal(s, t), rr_v3_sub(mid, c)) > 0))
                fail_msg("%s faces out of the room", walls[k]);
        }
    }

    /* At least 100,000 patches at the file's radiosity settings; and not so
     * many more that the default render stops being a one-minute job. */
    assert_true(s->radiosity.patch_area > 0);
    rad_patch_opts po = rad_pass_patch_limits(s, NULL);
    assert_true(po.max_area == s->radiosity.patch_area);
    rad_patches *P = NULL;
    rr_error err;
    if (rad_patches_build(s, &po, &P, &err) != RR_OK)
        fail_msg("%s", err.msg);
    if (!(P->n >= 100000 && P->n <= 200000))
        fail_msg("room: %zu radiosity patches, want 100,000 .. 200,000", P->n);
    rad_patches_destroy(P);
    scene_destroy(s);
}


/* The floor next to the red bitten sphere of scenes/csg.json: pixels that see
 * only the floor, within 0.75 of the point under the sphere's centre. Its
 * indirect light is tinted red in the hybrid (the solid is tessellated for the
 * radiosity pass) as with secondary rays, by about as much. */
static void csg_bleeds(void **state)
{
    (void)state;
    renders r;
    render_all(&r, "csg.json");
    const scene *s = r.s;
    int floor_ = find_object(s, "floor"), ball = find_object(s, "bitten sphere");
    int lens = find_object(s, "lens"), pebble = find_object(s, "drilled pebble");
    assert_int_equal(s->objects[ball].kind, SCENE_OBJ_CSG);
    assert_int_equal(s->objects[lens].kind, SCENE_OBJ_CSG);
    assert_int_equal(s->objects[pebble].kind, SCENE_OBJ_CSG);
    assert_int_equal(s->csg[s->objects[lens].csg_root].op, SCENE_CSG_INTERSECTION);
    assert_int_equal(s->csg[s->objects[ball].csg_root].op, SCENE_CSG_DIFFERENCE);
    assert_int_equal(s->csg[s->objects[pebble].csg_root].op, SCENE_CSG_DIFFERENCE);
    /* Every solid got patches. */
    size_t np[3] = {0, 0, 0};
    for (size_t k = 0; k < r.sol->P->n; k++) {
        uint32_t o = r.sol->P->p[k].object;
        np[0] += o == (uint32_t)lens, np[1] += o == (uint32_t)ball, np[2] += o == (uint32_t)pebble;
    }
    assert_true(np[0] > 50 && np[1] > 50 && np[2] > 50);
    rr_vec3 c = s->csg[s->objects[ball].csg_root].bbox_lo;
    rr_vec3 hi = s->csg[s->objects[ball].csg_root].bbox_hi;
    rr_vec3 below = rr_v3(0.5 * (c.x + hi.x), 0, 0.5 * (c.z + hi.z));
    int w = r.v.width, h = r.v.height, n = 0;
    unsigned char mask[61 * 61];
    assert_true((size_t)w * (size_t)h <= sizeof mask);
    memset(mask, 0, sizeof mask);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            rt_hit hit, nb;
            if (pixel_object(&r, x, y, &hit) != floor_ || rr_v3_len(rr_v3_sub(hit.point, below)) >= 0.75)
                continue;
            /* Away from the solid's silhouette: the pixel's neighbours see the
             * floor too (a pixel's samples reach its corners). */
            int clear = 1;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++)
                    clear &= x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h &&
                             pixel_object(&r, x + dx, y + dy, &nb) == floor_;
            if (clear) {
                mask[(size_t)y * (size_t)w + (size_t)x] = 1;
                n++;
            }
        }
    if (n < 10)
        fail_msg("only %d floor pixels next to the bitten sphere", n);
    check_tint(&r, mask, 0, 1, 1.2, "floor next to the red bitten sphere");
    free_all(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sphere_to_board),
        cmocka_unit_test(board_to_sphere),
        cmocka_unit_test(csg_bleeds),
        cmocka_unit_test(room),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
