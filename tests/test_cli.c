/* test_cli.c - the radray command line as a user meets it: help, exit codes,
 * one-line errors naming the file and the cause, no output file on failure,
 * a real render read back, and thread-count independence. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "img.h"
#include "scene.h"
#include "test_cli_run.h"
#include "rr_core.h"

static char g_dir[64];
static char g_out[8192]; /* captured stdout + stderr of the last run */

/* Runs radray with args (NULL-terminated); returns its exit code and leaves
 * its combined output in g_out (truncated). */
static int run(const char *const *args)
{
    char log[128];
    snprintf(log, sizeof log, "%s/log.txt", g_dir);
    return test_cli_run(log, args, g_out, sizeof g_out);
}

static void write_file(const char *name, const void *data, size_t n)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    fclose(f);
}

static int exists(const char *name)
{
    char path[256];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    return stat(path, &st) == 0;
}

static const char *k_head =
    "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],"
    "\"U\":[0,1,0],\"s\":0.25,\"w\":%s,\"h\":%s},"
    "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]},\"glow\":{\"diffuse\":[0.5,0.5,0.5],\"emission\":[2,2,2]}},"
    "\"objects\":[%s]}";

static const char *k_quad =
    "{\"type\":\"quad\",\"material\":\"a\",\"vertices\":[[-3,-3,-1],[3,-3,-1],[3,3,-1],[-3,3,-1]]}";

/* Writes scene NAME with camera w and objects, returns its path. */
static const char *scene_file(const char *name, const char *w, const char *objects)
{
    static char path[256];
    char text[4096];
    snprintf(text, sizeof text, k_head, w, w, objects); /* square: w = h */
    write_file(name, text, strlen(text));
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    return path;
}

/* Expects: exit 2, one line naming `name`, containing `cause`, and no output. */
static void expect_bad(const char *const *args, const char *name, const char *cause)
{
    int rc = run(args);
    if (rc != 2 || !strstr(g_out, name) || !strstr(g_out, cause))
        fail_msg("expected exit 2 naming '%s' with '%s'; got %d: %s", name, cause, rc, g_out);
    char *nl = strchr(g_out, '\n');
    assert_true(nl == NULL || nl[1] == '\0' || strstr(g_out, "warning")); /* one line */
    assert_false(exists("bad.exr"));
    assert_false(exists("bad.png"));
}

static char g_bad_out[256];

static void help_and_usage(void **state)
{
    (void)state;
    const char *a1[] = {"--help", NULL};
    assert_int_equal(run(a1), 0);
    assert_non_null(strstr(g_out, "render"));
    assert_non_null(strstr(g_out, "info"));
    const char *a2[] = {"render", "--help", NULL};
    assert_int_equal(run(a2), 0);
    assert_non_null(strstr(g_out, "--spp"));
    const char *a3[] = {"info", "--help", NULL};
    assert_int_equal(run(a3), 0);
    const char *a4[] = {"frobnicate", NULL};
    assert_int_equal(run(a4), 2);
    const char *a5[] = {"render", "--bogus", "x.json", NULL};
    assert_int_equal(run(a5), 2);
    assert_non_null(strstr(g_out, "--bogus"));
    const char *a6[] = {"render", NULL};
    assert_int_equal(run(a6), 2);
    const char *a7[] = {"render", "x.json", "--width", "-3", NULL};
    assert_int_equal(run(a7), 2);
}

static void bad_scenes(void **state)
{
    (void)state;
    /* Missing scene file. */
    const char *a[] = {"render", "/nonexistent/scene.json", "-o", g_bad_out, NULL};
    expect_bad(a, "/nonexistent/scene.json", "");
    /* Invalid JSON: line and column. */
    write_file("broken.json", "{\n  \"format\": \"radray-scene/1\",\n  \"camera\": [1,,\n}", 48);
    char p[256];
    snprintf(p, sizeof p, "%s/broken.json", g_dir);
    const char *b[] = {"render", p, "-o", g_bad_out, NULL};
    expect_bad(b, "broken.json", ":3:");
    /* Unknown key, wrong type. */
    const char *c[] = {"render", scene_file("unknown.json", "4", "{\"type\":\"quad\",\"material\":\"a\",\"colour\":1,"
                                                                  "\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}"),
                       "-o", g_bad_out, NULL};
    expect_bad(c, "unknown.json", "objects[0]");
    assert_non_null(strstr(g_out, "colour"));
    const char *d[] = {"render", scene_file("type.json", "\"four\"", k_quad), "-o", g_bad_out, NULL};
    expect_bad(d, "type.json", "camera.w");
    /* NaN / infinite coordinates. */
    const char *e[] = {"render", scene_file("inf.json", "4", "{\"type\":\"quad\",\"material\":\"a\","
                                                             "\"vertices\":[[0,0,0],[1e999,0,0],[1,1,0],[0,1,0]]}"),
                       "-o", g_bad_out, NULL};
    expect_bad(e, "inf.json", "objects[0]");
    /* Negative resolution, and one that cannot fit in memory. */
    const char *f[] = {"render", scene_file("neg.json", "-5", k_quad), "-o", g_bad_out, NULL};
    expect_bad(f, "neg.json", "camera");
    const char *g[] = {"render", scene_file("huge.json", "1000000", k_quad), "-o", g_bad_out, NULL};
    expect_bad(g, "huge.json", "camera");
}

static void bad_meshes(void **state)
{
    (void)state;
    static const char *cases[][2] = {
        {"missing.obj", NULL}, {"empty.obj", ""}, {"trunc.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"},
        {"garbage.stl", "(binary, below)"},
        {"nan.off", "OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        static const char garbage[] = "\x01\x02\x03\xff\xfe garbage \x00\x7f\x80 binary junk";
        if (i == 3)
            write_file(cases[i][0], garbage, sizeof garbage);
        else if (cases[i][1])
            write_file(cases[i][0], cases[i][1], strlen(cases[i][1]));
        char obj[256];
        snprintf(obj, sizeof obj, "{\"type\":\"mesh\",\"material\":\"a\",\"file\":\"%s\"}", cases[i][0]);
        const char *a[] = {"render", scene_file("mesh.json", "4", obj), "-o", g_bad_out, NULL};
        expect_bad(a, cases[i][0], "objects[0]");
    }
}

static void unwritable_output(void **state)
{
    (void)state;
    const char *sc = scene_file("ok.json", "4", k_quad);
    /* A folder that cannot be created (its parent is a file). */
    write_file("afile", "x", 1);
    char out[256];
    snprintf(out, sizeof out, "%s/afile/sub/bad.exr", g_dir);
    const char *a[] = {"render", sc, "-o", out, NULL};
    expect_bad(a, "afile", "");
    /* Neither .exr nor .png (-o FILE.png is the preview, the EXR beside it). */
    const char *b[] = {"render", sc, "-o", "x.jpg", NULL};
    assert_int_equal(run(b), 2);
    assert_non_null(strstr(g_out, "x.jpg"));
}

static void zero_area_warning(void **state)
{
    (void)state;
    char objs[512];
    snprintf(objs, sizeof objs,
             "%s,{\"type\":\"triangles\",\"material\":\"a\",\"vertices\":[[0,0,0],[1,0,0],[2,0,0],[0,1,0]],"
             "\"indices\":[[0,1,2],[0,1,3]]}",
             k_quad);
    char out[256];
    snprintf(out, sizeof out, "%s/zero.exr", g_dir);
    const char *a[] = {"render", scene_file("zero.json", "4", objs), "-o", out, NULL};
    assert_int_equal(run(a), 0);
    assert_non_null(strstr(g_out, "warning"));
    assert_non_null(strstr(g_out, "zero-area"));
    assert_true(exists("zero.exr"));
}

static void render_reads_back_and_is_thread_independent(void **state)
{
    (void)state;
    char objs[512];
    snprintf(objs, sizeof objs,
             "%s,{\"type\":\"sphere\",\"material\":\"glow\",\"center\":[0,0,0],\"radius\":0.5}", k_quad);
    const char *sc = scene_file("good.json", "4", objs);
    char o1[256], o2[256], png[256];
    snprintf(o1, sizeof o1, "%s/t1.exr", g_dir);
    snprintf(o2, sizeof o2, "%s/t2.exr", g_dir);
    snprintf(png, sizeof png, "%s/t1.png", g_dir);
    const char *a[] = {"render", sc, "-o", o1, "--threads", "1", "--spp", "4", NULL};
    assert_int_equal(run(a), 0);
    assert_non_null(strstr(g_out, "t1.exr"));
    const char *b[] = {"render", sc, "-o", o2, "--threads", "2", "--spp", "4", "--no-png", NULL};
    assert_int_equal(run(b), 0);
    rr_image i1 = {0}, i2 = {0};
    assert_int_equal(img_read_exr(o1, NULL, &i1, NULL), RR_OK);
    assert_int_equal(img_read_exr(o2, NULL, &i2, NULL), RR_OK);
    assert_int_equal(i1.width, 9);
    assert_int_equal(i1.height, 9);
    assert_memory_equal(i1.px, i2.px, sizeof(float) * 3 * 81);
    /* Centre: partly the emissive sphere (radiance 2). The main image is the
     * sum of the layers, and all of them are in the file. */
    assert_true(rr_image_get(&i1, 4, 4).r > 0.2);
    char names[16][64];
    int nl = 0;
    assert_int_equal(img_exr_layers(o1, names, 16, &nl, NULL), RR_OK);
    assert_int_equal(nl, 7);
    double sum = 0;
    for (int l = 0; l < nl; l++) {
        rr_image li = {0};
        assert_int_equal(img_read_exr(o1, names[l], &li, NULL), RR_OK);
        sum += rr_image_get(&li, 4, 4).g;
        rr_image_free(&li);
    }
    assert_true(fabs(sum - rr_image_get(&i1, 4, 4).g) < 1e-5);
    unsigned char *rgb8 = NULL;
    int w = 0, h = 0;
    assert_int_equal(img_read_png(png, &rgb8, &w, &h, NULL), RR_OK);
    assert_int_equal(w, 9);
    /* The preview is the EXR through the sRGB curve (checked by value in test_image). */
    for (int i = 0; i < 81 * 3; i++) {
        double lin = fmin(1.0, fmax(0.0, i1.px[i]));
        assert_int_equal(rgb8[i], (int)lround(255.0 * img_srgb_encode(lin)));
    }
    free(rgb8);
    rr_image_free(&i1);
    rr_image_free(&i2);
    /* --width rescales, info describes. */
    const char *c[] = {"render", sc, "-o", o1, "--width", "17", "-q", NULL};
    assert_int_equal(run(c), 0);
    assert_string_equal(g_out, "");
    assert_int_equal(img_read_exr(o1, NULL, &i1, NULL), RR_OK);
    assert_int_equal(i1.width, 17);
    assert_int_equal(i1.height, 17);
    rr_image_free(&i1);
    const char *d[] = {"info", sc, NULL};
    assert_int_equal(run(d), 0);
    assert_non_null(strstr(g_out, "sphere"));
}

/* --mode names a row of the integrator table; --indirect K picks the
 * ray-traced row with that term, whatever --mode says: the same image. */
static void modes_and_indirect(void **state)
{
    (void)state;
    char objs[512];
    snprintf(objs, sizeof objs,
             "%s,{\"type\":\"sphere\",\"material\":\"glow\",\"center\":[0,0,0],\"radius\":0.5}", k_quad);
    const char *sc = scene_file("modes.json", "4", objs);
    static const char *const pairs[][2] = {
        {"direct", "none"}, {"whitted", "ambient"}, {"secondary", "secondary"}, {"hybrid", "radiosity"}};
    for (int i = 0; i < 4; i++) {
        char o1[256], o2[256];
        snprintf(o1, sizeof o1, "%s/m1.exr", g_dir);
        snprintf(o2, sizeof o2, "%s/m2.exr", g_dir);
        const char *a[] = {"render", sc, "-o", o1, "--no-png", "--spp", "2", "--mode", pairs[i][0], NULL};
        assert_int_equal(run(a), 0);
        char want[64];
        snprintf(want, sizeof want, "mode %s,", pairs[i][0]);
        assert_non_null(strstr(g_out, want));
        const char *b[] = {"render", sc, "-o", o2, "--no-png", "--spp", "2", "--mode", "radiosity", "--indirect",
                           pairs[i][1], "-q", NULL};
        assert_int_equal(run(b), 0);
        rr_image i1 = {0}, i2 = {0};
        assert_int_equal(img_read_exr(o1, NULL, &i1, NULL), RR_OK);
        assert_int_equal(img_read_exr(o2, NULL, &i2, NULL), RR_OK);
        assert_memory_equal(i1.px, i2.px, sizeof(float) * 3 * (size_t)i1.width * (size_t)i1.height);
        rr_image_free(&i1);
        rr_image_free(&i2);
    }
    /* The direct mode has no interreflection: its indirect layer is zero. */
    char od[256];
    snprintf(od, sizeof od, "%s/d.exr", g_dir);
    const char *d[] = {"render", sc, "-o", od, "--no-png", "--mode", "direct", "-q", NULL};
    assert_int_equal(run(d), 0);
    rr_image ind = {0};
    assert_int_equal(img_read_exr(od, "indirect", &ind, NULL), RR_OK);
    for (int k = 0; k < 3 * ind.width * ind.height; k++)
        assert_true(ind.px[k] == 0.0f);
    rr_image_free(&ind);
    const char *e[] = {"render", sc, "--indirect", "bounce", NULL};
    assert_int_equal(run(e), 2);
    assert_non_null(strstr(g_out, "--indirect"));
    const char *f[] = {"render", sc, "--mode", "path", NULL};
    assert_int_equal(run(f), 2);
    assert_non_null(strstr(g_out, "whitted, secondary, radiosity, hybrid or direct"));
}

/* Small things a new user meets: -o FILE.png, an option's bad value blamed
 * on the command line (not the scene file), info showing a lookat camera in
 * the keys --set takes, a scene that nothing lights. */
static void user_details(void **state)
{
    (void)state;
    char png[256], exr[256], room[512];
    snprintf(png, sizeof png, "%s/pp.png", g_dir);
    snprintf(exr, sizeof exr, "%s/pp.exr", g_dir);
    char sc[256];
    snprintf(sc, sizeof sc, "%s", scene_file("details.json", "4", k_quad)); /* scene_file reuses its buffer */
    const char *a[] = {"render", sc, "-o", png, "--mode", "whitted", "-q", NULL};
    assert_int_equal(run(a), 0);
    assert_true(exists("pp.png") && exists("pp.exr"));
    const char *b[] = {"render", sc, "--spp", "0", "-o", exr, NULL};
    assert_int_equal(run(b), 2);
    assert_non_null(strstr(g_out, "the command line (render.spp=0"));
    assert_null(strstr(g_out, "details.json"));
    const char *c[] = {"render", sc, "--set", "materials.a.diffuse=[2,0,0]", "-o", exr, NULL};
    assert_int_equal(run(c), 2);
    assert_non_null(strstr(g_out, "the command line (materials.a.diffuse=[2,0,0]"));
    /* A bad value in the file itself is still the file's. */
    const char *bad = scene_file("details-bad.json", "1.5", k_quad);
    const char *d[] = {"render", bad, "-o", exr, NULL};
    assert_int_equal(run(d), 2);
    assert_non_null(strstr(g_out, "details-bad.json: camera"));
    snprintf(room, sizeof room, "%s/scenes/room.json", RR_SOURCE_DIR);
    const char *e[] = {"info", room, NULL};
    assert_int_equal(run(e), 0);
    assert_non_null(strstr(g_out, "camera     lookat: eye (3.1, 1.6, 5.35)  target (2.3, 1.05, 1.2)"));
    const char *f[] = {"info", room, "--set", "camera.eye=[3,1.6,5]", NULL};
    assert_int_equal(run(f), 0);
    assert_non_null(strstr(g_out, "eye (3, 1.6, 5)"));
    /* --max-memory judges the film that is rendered: the Cornell box's 255 x
     * 255 film (6 MiB) is over 2M, its --width 8 film is not. */
    char cornell[512];
    snprintf(cornell, sizeof cornell, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *m1[] = {"render", cornell, "--mode", "whitted", "--max-memory", "2M", "-o", exr, NULL};
    assert_int_equal(run(m1), 2);
    assert_non_null(strstr(g_out, "255 x 255"));
    const char *m2[] = {"render", cornell, "--mode", "whitted", "--max-memory", "2M", "--width", "8", "-q", "-o",
                        exr, NULL};
    assert_int_equal(run(m2), 0);
    /* Nothing emits (k_quad is grey, no lights): warned, still exit 0. */
    const char *g[] = {"render", sc, "-o", exr, "-q", NULL};
    assert_int_equal(run(g), 0);
    assert_non_null(strstr(g_out, "nothing emits light"));
}

/* --aov and the EXR's header: on the quad of k_quad (z = -1, facing +z,
 * diffuse 0.5) seen from E = (0, 0, 5), albedo is the reflectance, the
 * normal unit and facing the eye, depth the distance to the plane along the
 * pixel's ray (6 through the centre), object_id the quad's index; the corners
 * miss the quad. The header says what made the image. */
static void aovs_and_metadata(void **state)
{
    (void)state;
    char sc[256], out[256];
    snprintf(sc, sizeof sc, "%s", scene_file("aov.json", "4", k_quad));
    snprintf(out, sizeof out, "%s/aov.exr", g_dir);
    const char *a[] = {"render", sc, "-o", out, "--aov", "albedo,normal,depth,object_id", "--spp", "3", "-q", NULL};
    assert_int_equal(run(a), 0);
    rr_image alb = {0}, nrm = {0}, dep = {0}, oid = {0};
    assert_int_equal(img_read_exr(out, "albedo", &alb, NULL), RR_OK);
    assert_int_equal(img_read_exr(out, "normal", &nrm, NULL), RR_OK);
    assert_int_equal(img_read_exr(out, "depth", &dep, NULL), RR_OK);
    assert_int_equal(img_read_exr(out, "object_id", &oid, NULL), RR_OK);
    int w = alb.width, hits = 0, misses = 0;
    assert_true(fabs(rr_image_get(&dep, w / 2, w / 2).r - 6.0) < 1e-5);
    /* Every pixel's depth is the distance from E along its centre ray to the
     * plane z = -1, where that meets the quad ([-3, 3]^2). */
    scene *s = NULL;
    assert_int_equal(scene_load(sc, NULL, &s, NULL), RR_OK);
    for (int y = 0; y < w; y++)
        for (int x = 0; x < w; x++) {
            rr_ray r = rr_view_ray(&s->view, x, y, 0.0, 0.0);
            double t = (-1.0 - r.o.z) / r.d.z;
            rr_vec3 p = rr_ray_at(r, t);
            double want = fabs(p.x) < 3 - 1e-9 && fabs(p.y) < 3 - 1e-9 ? t * rr_v3_len(r.d) : 0.0;
            if (fabs(fabs(p.x) - 3) < 1e-9 || fabs(fabs(p.y) - 3) < 1e-9)
                continue; /* on the quad's edge */
            assert_true(fabs(rr_image_get(&dep, x, y).r - want) <= 1e-5 * (1.0 + want));
        }
    scene_destroy(s);
    for (int y = 0; y < w; y++)
        for (int x = 0; x < w; x++) {
            rr_rgb id = rr_image_get(&oid, x, y), d = rr_image_get(&dep, x, y), n = rr_image_get(&nrm, x, y);
            if (id.r < 0) {
                misses++;
                assert_true(d.r == 0.0 && rr_image_get(&alb, x, y).g == 0.0);
                continue;
            }
            hits++;
            assert_true(id.r == 0.0 && id.g == 0.0);
            assert_true(fabs(rr_image_get(&alb, x, y).g - 0.5) < 1e-6);
            assert_true(fabs(n.r * n.r + n.g * n.g + n.b * n.b - 1.0) < 1e-5);
            assert_true(n.b > 0.999); /* the quad faces +z, towards E */
            assert_true(d.r >= 6.0 - 1e-5 && d.r < 6.0 * 1.5); /* at least the plane's distance */
        }
    assert_true(hits > 0 && misses > 0);
    rr_image_free(&alb);
    rr_image_free(&nrm);
    rr_image_free(&dep);
    rr_image_free(&oid);
    char v[512];
    assert_int_equal(img_read_exr_attr(out, "radray:mode", v, sizeof v, NULL), RR_OK);
    assert_string_equal(v, "hybrid");
    assert_int_equal(img_read_exr_attr(out, "radray:spp", v, sizeof v, NULL), RR_OK);
    assert_string_equal(v, "3");
    assert_int_equal(img_read_exr_attr(out, "radray:scene_hash", v, sizeof v, NULL), RR_OK);
    assert_true(!strncmp(v, "fnv1a64:", 8) && strlen(v) == 24);
    assert_int_equal(img_read_exr_attr(out, "radray:camera", v, sizeof v, NULL), RR_OK);
    assert_non_null(strstr(v, "E (0, 0, 5)"));
    assert_int_equal(img_read_exr_attr(out, "radray:version", v, sizeof v, NULL), RR_OK);
    assert_int_equal(img_read_exr_attr(out, "radray:nothing", v, sizeof v, NULL), RR_ERR_INVALID);
    /* --stats: with no lights and no mirrors, Whitted traces exactly one ray
     * per sample (9 x 9 pixels, 3 spp) and no visibility rays; secondary rays
     * trace the same rays whatever the thread count. */
    char st[256], *text = NULL;
    size_t len = 0;
    snprintf(st, sizeof st, "%s/st.json", g_dir);
    const char *c[] = {"render", sc, "-o", out, "--mode", "whitted", "--spp", "3", "--stats", st, "-q", NULL};
    assert_int_equal(run(c), 0);
    assert_int_equal(rr_file_read_all(st, &text, &len, NULL), RR_OK);
    assert_non_null(strstr(text, "\"rays_closest\": 243, \"rays_any_hit\": 0,"));
    assert_non_null(strstr(text, "\"mode\": \"whitted\""));
    free(text);
    char objs[512], counts[2][128];
    snprintf(objs, sizeof objs,
             "%s,{\"type\":\"sphere\",\"material\":\"glow\",\"center\":[0,0,0],\"radius\":0.5}", k_quad);
    char lit[256];
    snprintf(lit, sizeof lit, "%s", scene_file("lit.json", "4", objs));
    for (int t = 0; t < 2; t++) {
        const char *d[] = {"render", lit, "-o", out, "--mode", "secondary", "--spp", "4", "--threads", t ? "2" : "1",
                           "--stats", st, "-q", NULL};
        assert_int_equal(run(d), 0);
        assert_int_equal(rr_file_read_all(st, &text, &len, NULL), RR_OK);
        const char *r = strstr(text, "\"rays_closest\"");
        assert_non_null(r);
        snprintf(counts[t], sizeof counts[t], "%.*s", (int)(strstr(r, "\"seconds_render\"") - r), r);
        free(text);
    }
    assert_string_equal(counts[0], counts[1]);
    assert_null(strstr(counts[0], "\"rays_closest\": 0,"));
    /* The radiosity pass traces one Monte Carlo ray per form-factor sample:
     * patches x ff_samples (512 by default; no mirror to extend them), the
     * flat method's. */
    const char *e[] = {"render", lit, "-o", out, "--stats", st, "--set", "radiosity.method=flat", "-q", NULL};
    assert_int_equal(run(e), 0);
    assert_int_equal(rr_file_read_all(st, &text, &len, NULL), RR_OK);
    const char *pa = strstr(text, "\"patches\": "), *fr = strstr(text, "\"form_factor_rays\": ");
    assert_non_null(pa);
    assert_non_null(fr);
    long long patches = atoll(pa + strlen("\"patches\": ")), rays = atoll(fr + strlen("\"form_factor_rays\": "));
    free(text);
    assert_true(patches > 100);
    assert_int_equal(rays, patches * 512);
    /* The hierarchical pass counts its rays too (links' shadow rays, burial
     * probes, closedness, first shots; it printed 0 before), the same for
     * any thread count, and reports its links. */
    long long hrays[2];
    for (int t = 0; t < 2; t++) {
        const char *h[] = {"render", lit, "-o", out, "--stats", st, "-q", "--threads", t ? "2" : "1",
                           "--set", "radiosity.method=hierarchical", NULL};
        assert_int_equal(run(h), 0);
        assert_int_equal(rr_file_read_all(st, &text, &len, NULL), RR_OK);
        const char *hr = strstr(text, "\"form_factor_rays\": "), *hl = strstr(text, "\"hierarchical_links\": ");
        assert_non_null(hr);
        assert_non_null(hl);
        hrays[t] = atoll(hr + strlen("\"form_factor_rays\": "));
        assert_true(atoll(hl + strlen("\"hierarchical_links\": ")) > 0);
        /* its stages' seconds account for the pass: none negative, their
         * sum no more than the pass's and all but what lies outside the
         * hierarchical solver (the BVH's lights, the solution's arrays) */
        const char *stage[] = {"setup", "link", "settle", "regeo", "estimate", "solve", "output"};
        const char *sr = strstr(text, "\"seconds_radiosity\": "), *hs = strstr(text, "\"hierarchical_seconds\"");
        assert_non_null(sr);
        assert_non_null(hs);
        double pass = atof(sr + strlen("\"seconds_radiosity\": ")), sum = 0.0;
        for (size_t k = 0; k < sizeof stage / sizeof *stage; k++) {
            char key[32];
            snprintf(key, sizeof key, "\"%s\": ", stage[k]);
            const char *v = strstr(hs, key);
            assert_non_null(v);
            double x = atof(v + strlen(key));
            assert_true(x >= 0.0);
            sum += x;
        }
        assert_true(sum <= pass * 1.0001 + 1e-5);
        assert_true(sum >= 0.5 * pass);
        free(text);
    }
    assert_true(hrays[0] > 0);
    assert_true(hrays[0] == hrays[1]);
    /* An unknown AOV: exit 2 naming it, nothing written. */
    char bad[256];
    snprintf(bad, sizeof bad, "%s/bad.exr", g_dir);
    const char *b[] = {"render", sc, "-o", bad, "--aov", "albedo,motion", NULL};
    expect_bad(b, "motion", "--aov");
}

/* radray energy: the ledger balances on the Cornell box, in text and JSON;
 * scenes the radiosity pass cannot take are bad input (exit 2). */
static void energy_ledger(void **state)
{
    (void)state;
    char cornell[512];
    snprintf(cornell, sizeof cornell, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *a[] = {"energy", cornell, "--patch-area", "2000", NULL};
    assert_int_equal(run(a), 0);
    assert_non_null(strstr(g_out, "holds"));
    assert_non_null(strstr(g_out, "left_wall"));
    const char *b[] = {"energy",       cornell, "--json", "--solver", "direct", "--set", "radiosity.method=flat",
                       "--patch-area", "4000",  NULL};
    assert_int_equal(run(b), 0);
    assert_non_null(strstr(g_out, "\"balanced\": true"));
    assert_non_null(strstr(g_out, "\"solver\": \"direct\""));
    /* Reflectance 1: no physical solution. */
    char objs[512];
    snprintf(objs, sizeof objs,
             "{\"type\":\"quad\",\"material\":\"glow\",\"vertices\":[[-3,-3,-1],[3,-3,-1],[3,3,-1],[-3,3,-1]]},"
             "{\"type\":\"box\",\"material\":\"a\",\"min\":[-1,-1,-0.5],\"max\":[1,1,0]}");
    const char *sc = scene_file("rho1.json", "4", objs);
    const char *c[] = {"energy", sc, "--set", "materials.a.diffuse=1", NULL};
    assert_int_equal(run(c), 2);
    assert_non_null(strstr(g_out, "reflectance >= 1"));
    /* Nothing emits. */
    const char *d[] = {"energy", scene_file("dark.json", "4", k_quad), NULL};
    assert_int_equal(run(d), 2);
    assert_non_null(strstr(g_out, "emits"));
    assert_null(strstr(g_out, "radiosity: radiosity")); /* the pass's prefix, once */
    const char *e[] = {"render", sc, "--mode", "radiosty", NULL};
    assert_int_equal(run(e), 2);
    assert_non_null(strstr(g_out, "--mode"));
    /* Radiosity display with a convergence plot: the flat method's
     * Gauss-Seidel sweeps, then the hierarchical method's Jacobi sweeps (the
     * default), where --solver changes nothing and says so. */
    char out[256], plot[256];
    snprintf(out, sizeof out, "%s/rad.exr", g_dir);
    snprintf(plot, sizeof plot, "%s/conv.svg", g_dir);
    const char *f[] = {"render", cornell, "--mode", "radiosity", "--width", "21", "--patch-area", "4000",
                       "--solver", "iterative", "--set", "radiosity.method=flat", "--plot", plot, "-o", out, NULL};
    assert_int_equal(run(f), 0);
    assert_true(exists("rad.exr") && exists("conv.svg"));
    assert_null(strstr(g_out, "applies to the flat radiosity method"));
    assert_int_equal(remove(plot), 0);
    const char *g[] = {"render", cornell, "--mode", "radiosity", "--width", "21", "--solver", "iterative",
                       "--plot",  plot,    "-o",     out,         NULL};
    assert_int_equal(run(g), 0);
    assert_true(exists("conv.svg"));
    assert_non_null(strstr(g_out, "radiosity.solver applies to the flat radiosity method"));
    rr_image im = {0};
    assert_int_equal(img_read_exr(out, "radiosity", &im, NULL), RR_OK);
    assert_true(rr_image_get(&im, 10, 10).r > 0.0);
    rr_image_free(&im);
}

/* --radiosity-cache: made on the first render, reused by another view (same
 * image for the same view), refused for other settings or another scene. */
static void radiosity_cache(void **state)
{
    (void)state;
    char cornell[512], cache[256], o1[256], o2[256], o3[256];
    snprintf(cornell, sizeof cornell, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    snprintf(cache, sizeof cache, "%s/cornell.rcache", g_dir);
    snprintf(o1, sizeof o1, "%s/k1.exr", g_dir);
    snprintf(o2, sizeof o2, "%s/k2.exr", g_dir);
    snprintf(o3, sizeof o3, "%s/k3.exr", g_dir);
    const char *a[] = {"render", cornell, "--width", "21", "--patch-area", "4000", "--radiosity-cache", cache,
                       "-o", o1, "--no-png", NULL};
    assert_int_equal(run(a), 0);
    assert_true(exists("cornell.rcache"));
    const char *b[] = {"render", cornell, "--width", "21", "--patch-area", "4000", "--radiosity-cache", cache,
                       "-o", o2, "--no-png", NULL};
    assert_int_equal(run(b), 0);
    assert_non_null(strstr(g_out, "read from"));
    rr_image i1 = {0}, i2 = {0};
    assert_int_equal(img_read_exr(o1, NULL, &i1, NULL), RR_OK);
    assert_int_equal(img_read_exr(o2, NULL, &i2, NULL), RR_OK);
    assert_memory_equal(i1.px, i2.px, sizeof(float) * 3 * (size_t)i1.width * (size_t)i1.height);
    rr_image_free(&i1);
    rr_image_free(&i2);
    /* Another view of the same room may use it. */
    const char *c[] = {"render", cornell, "--width", "15", "--patch-area", "4000", "--radiosity-cache", cache,
                       "-o", o3, "--no-png", "--set", "camera.E=[278,273,-700]", NULL};
    assert_int_equal(run(c), 0);
    /* Other settings, or another scene: refused, exit 2, no output. */
    const char *d[] = {"render", cornell, "--width", "21", "--patch-area", "3000", "--radiosity-cache", cache,
                       "-o", g_bad_out, NULL};
    expect_bad(d, "cornell.rcache", "different");
    const char *e[] = {"render", cornell, "--width", "21", "--patch-area", "4000", "--radiosity-cache", cache,
                       "--set", "materials.white.diffuse=0.5", "-o", g_bad_out, NULL};
    expect_bad(e, "cornell.rcache", "different");
}

static int setup(void **state)
{
    (void)state;
    strcpy(g_dir, "/tmp/rr_cli_XXXXXX");
    if (!mkdtemp(g_dir))
        return -1;
    snprintf(g_bad_out, sizeof g_bad_out, "%s/bad.exr", g_dir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(help_and_usage),
        cmocka_unit_test(bad_scenes),
        cmocka_unit_test(bad_meshes),
        cmocka_unit_test(unwritable_output),
        cmocka_unit_test(zero_area_warning),
        cmocka_unit_test(render_reads_back_and_is_thread_independent),
        cmocka_unit_test(modes_and_indirect),
        cmocka_unit_test(user_details),
        cmocka_unit_test(aovs_and_metadata),
        cmocka_unit_test(energy_ledger),
        cmocka_unit_test(radiosity_cache),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
