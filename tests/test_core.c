/* test_core.c - core: the lecture's view, RNG streams, errors, atomic files, film. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include "rr_core.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static void assert_v3(rr_vec3 a, double x, double y, double z)
{
    assert_near(a.x, x, 1e-12);
    assert_near(a.y, y, 1e-12);
    assert_near(a.z, z, 1e-12);
}

/* E=(0,0,5), O=(0,0,4), U=(0,1,0), s=0.5, w=2, h=1: VO=(0,0,-1), so by hand
 * I = VO x U = (1,0,0), J = I x VO = (0,1,0); a 5 x 3 image. */
static void view_lecture_axis_aligned(void **state)
{
    (void)state;
    rr_view v;
    rr_error err;
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 5), rr_v3(0, 0, 4), rr_v3(0, 1, 0), 0.5, 2, 1, &v, &err), RR_OK);
    assert_int_equal(v.width, 5);
    assert_int_equal(v.height, 3);
    assert_v3(v.I, 1, 0, 0);
    assert_v3(v.J, 0, 1, 0);
    /* Centre pixel (col w, row h) is O itself: x = y = 0. */
    assert_v3(rr_view_screen_point(&v, 2, 1, 0, 0), 0, 0, 4);
    /* Top-left pixel: x = -w = -2, y = +h = 1: P = O - 2s I + s J. */
    assert_v3(rr_view_screen_point(&v, 0, 0, 0, 0), -1, 0.5, 4);
    /* Bottom-right: x = 2, y = -1. */
    assert_v3(rr_view_screen_point(&v, 4, 2, 0, 0), 1, -0.5, 4);
    /* Primary ray: origin E, direction EP, so t = 1 reaches the screen. */
    rr_ray r = rr_view_ray(&v, 0, 0, 0, 0);
    assert_v3(r.o, 0, 0, 5);
    assert_v3(r.d, -1, 0.5, -1);
    assert_v3(rr_ray_at(r, 1.0), -1, 0.5, 4);
    /* Sub-pixel offsets move by s per pixel along I and J. */
    assert_v3(rr_view_screen_point(&v, 2, 1, 0.5, -0.5), 0.25, -0.25, 4);
}

/* E=(1,2,3), O=(2,2,3), U=(0,0,1), s=2, w=h=1: VO=(1,0,0), I=(0,-1,0), J=(0,0,1).
 * Top-left: O + 2(-1)I + 2(1)J = (2,4,5). */
static void view_lecture_general(void **state)
{
    (void)state;
    rr_view v;
    assert_int_equal(rr_view_lecture(rr_v3(1, 2, 3), rr_v3(2, 2, 3), rr_v3(0, 0, 1), 2.0, 1, 1, &v, NULL), RR_OK);
    assert_v3(v.I, 0, -1, 0);
    assert_v3(v.J, 0, 0, 1);
    assert_v3(rr_view_screen_point(&v, 0, 0, 0, 0), 2, 4, 5);
    assert_v3(rr_view_screen_point(&v, 2, 2, 0, 0), 2, 0, 1);
    assert_v3(rr_view_ray(&v, 1, 1, 0, 0).d, 1, 0, 0);
}

/* U need be neither unit nor perpendicular to VO: J is rebuilt from I x VO. */
static void view_up_not_perpendicular(void **state)
{
    (void)state;
    rr_view v;
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -3), rr_v3(0, 5, 5), 1.0, 0, 0, &v, NULL), RR_OK);
    assert_v3(v.I, 1, 0, 0);
    assert_v3(v.J, 0, 1, 0);
    assert_int_equal(v.width, 1);
    assert_int_equal(v.height, 1);
}

static void view_errors(void **state)
{
    (void)state;
    rr_view v;
    memset(&v, 0x5a, sizeof v);
    rr_view before = v;
    rr_error err;
    /* U parallel (and anti-parallel) to the view direction. */
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 0, 2), 1, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_non_null(strstr(err.msg, "parallel"));
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 0, 1), 1, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lecture(rr_v3(1, 1, 1), rr_v3(1, 1, 1), rr_v3(0, 1, 0), 1, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 0, 0), 1, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 1, 0), 0, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lecture(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 1, 0), 1, -1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lecture(rr_v3(NAN, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 1, 0), 1, 1, 1, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lookat(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 1, 0), 180, 4, 4, &v, &err),
                     RR_ERR_INVALID);
    assert_int_equal(rr_view_lookat(rr_v3(0, 0, 0), rr_v3(0, 0, -1), rr_v3(0, 1, 0), 60, 0, 4, &v, &err),
                     RR_ERR_INVALID);
    /* Output untouched on failure. */
    assert_memory_equal(&v, &before, sizeof v);
}

/* Look-at with a 90 degree vertical fov: the screen at distance 1 spans
 * [-1, 1] vertically, so the top edge of the image is at 45 degrees. */
static void view_lookat(void **state)
{
    (void)state;
    rr_view v;
    assert_int_equal(rr_view_lookat(rr_v3(0, 0, 0), rr_v3(0, 0, -10), rr_v3(0, 1, 0), 90.0, 4, 2, &v, NULL), RR_OK);
    assert_int_equal(v.width, 4);
    assert_int_equal(v.height, 2);
    assert_near(v.s, 1.0, 1e-12);
    assert_v3(v.O, 0, 0, -1);
    /* Even sizes: pixel centres at half-integers; the top edge of row 0 is y = 1. */
    assert_v3(rr_view_screen_point(&v, 0, 0, -0.5, 0.5), -2, 1, -1);
    assert_v3(rr_view_screen_point(&v, 3, 1, 0.5, -0.5), 2, -1, -1);
    /* Resize keeps the screen extent. */
    rr_view r;
    assert_int_equal(rr_view_resize(&v, 8, &r, NULL), RR_OK);
    assert_int_equal(r.height, 4);
    assert_v3(rr_view_screen_point(&r, 0, 0, -0.5, 0.5), -2, 1, -1);
}

static void rng_streams(void **state)
{
    (void)state;
    rr_rng a = rr_rng_make(42, 7), b = rr_rng_make(42, 7), c = rr_rng_make(42, 8), d = rr_rng_make(43, 7);
    int same_c = 0, same_d = 0;
    for (int i = 0; i < 1000; i++) {
        uint32_t x = rr_rng_u32(&a);
        assert_int_equal(x, rr_rng_u32(&b));
        same_c += x == rr_rng_u32(&c);
        same_d += x == rr_rng_u32(&d);
    }
    assert_true(same_c < 3);
    assert_true(same_d < 3);
    /* Known first output of PCG32's reference (seed 42, stream 54) is not
     * what we use (we hash seeds); check statistics instead: mean of 1e5
     * uniforms is 0.5 within 5 standard errors (1/sqrt(12 n)). */
    rr_rng r = rr_rng_make(1, 2);
    double sum = 0;
    int n = 100000;
    for (int i = 0; i < n; i++) {
        double u = rr_rng_uniform(&r);
        assert_true(u >= 0.0 && u < 1.0);
        sum += u;
    }
    assert_near(sum / n, 0.5, 5.0 / sqrt(12.0 * n));
    int counts[7] = {0};
    for (int i = 0; i < 70000; i++) {
        uint32_t k = rr_rng_below(&r, 7);
        assert_true(k < 7);
        counts[k]++;
    }
    for (int k = 0; k < 7; k++)
        assert_near(counts[k], 10000, 500); /* 5 sigma of a binomial(70000, 1/7) */
}

static void error_messages(void **state)
{
    (void)state;
    rr_error err;
    assert_int_equal(rr_error_set(&err, RR_ERR_IO, "%s: cannot open", "a.json"), RR_ERR_IO);
    assert_string_equal(err.msg, "a.json: cannot open");
    rr_error_prefix(&err, "scene %d", 3);
    assert_string_equal(err.msg, "scene 3: a.json: cannot open");
    assert_int_equal(err.code, RR_ERR_IO);
    assert_int_equal(rr_error_set(NULL, RR_ERR_PARSE, "ignored"), RR_ERR_PARSE);
    /* An over-long prefix is cut, never overflows. */
    char big[3000];
    memset(big, 'x', sizeof big - 1);
    big[sizeof big - 1] = '\0';
    rr_error_prefix(&err, "%s", big);
    assert_true(strlen(err.msg) < RR_ERROR_MSG_MAX);
    rr_error_clear(&err);
    assert_int_equal(err.code, RR_OK);
    assert_string_equal(rr_status_name(RR_ERR_LIMIT), "resource limit");
}

static char g_dir[64];

static int make_tmpdir(void **state)
{
    (void)state;
    strcpy(g_dir, "/tmp/rr_core_XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int count_tmp_files(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        n += strstr(e->d_name, ".tmp-") != NULL;
    closedir(d);
    return n;
}

static void atomic_files(void **state)
{
    (void)state;
    char path[128], *data;
    rr_error err;
    rr_atomic a;
    snprintf(path, sizeof path, "%s/out.txt", g_dir);
    assert_int_equal(rr_atomic_begin(&a, path, &err), RR_OK);
    fputs("good", a.fp);
    assert_int_equal(rr_atomic_commit(&a, &err), RR_OK);
    assert_int_equal(rr_file_read_all(path, &data, NULL, &err), RR_OK);
    assert_string_equal(data, "good");
    free(data);
    /* A second write that is abandoned half way leaves the good file alone. */
    assert_int_equal(rr_atomic_begin(&a, path, &err), RR_OK);
    fputs("half", a.fp);
    rr_atomic_abort(&a);
    rr_atomic_abort(&a); /* twice is harmless */
    assert_int_equal(rr_file_read_all(path, &data, NULL, &err), RR_OK);
    assert_string_equal(data, "good");
    free(data);
    assert_int_equal(count_tmp_files(g_dir), 0);
    /* A missing folder is reported by name. */
    char bad[160];
    snprintf(bad, sizeof bad, "%s/missing/out.txt", g_dir);
    assert_int_equal(rr_atomic_begin(&a, bad, &err), RR_ERR_IO);
    assert_non_null(strstr(err.msg, "does not exist"));
    /* ... and can be created. */
    assert_int_equal(rr_file_make_parent_dirs(bad, &err), RR_OK);
    assert_int_equal(rr_atomic_begin(&a, bad, &err), RR_OK);
    assert_int_equal(rr_atomic_commit(&a, &err), RR_OK);
    struct stat st;
    assert_int_equal(stat(bad, &st), 0);
    /* A missing file to read names the file. */
    assert_int_equal(rr_file_read_all("/nonexistent/x.json", &data, NULL, &err), RR_ERR_IO);
    assert_non_null(strstr(err.msg, "/nonexistent/x.json"));
}

static void paths(void **state)
{
    (void)state;
    char out[64];
    rr_path_dirname("scenes/a.json", out, sizeof out);
    assert_string_equal(out, "scenes");
    rr_path_dirname("a.json", out, sizeof out);
    assert_string_equal(out, ".");
    rr_path_dirname("/a.json", out, sizeof out);
    assert_string_equal(out, "/");
    assert_int_equal(rr_path_join("scenes", "m/x.obj", out, sizeof out, NULL), RR_OK);
    assert_string_equal(out, "scenes/m/x.obj");
    assert_int_equal(rr_path_join("scenes", "/abs/x.obj", out, sizeof out, NULL), RR_OK);
    assert_string_equal(out, "/abs/x.obj");
    assert_int_equal(rr_path_join("", "x.obj", out, sizeof out, NULL), RR_OK);
    assert_string_equal(out, "x.obj");
    char tiny[4];
    assert_int_equal(rr_path_join("abc", "def", tiny, sizeof tiny, NULL), RR_ERR_INVALID);
}

static void image_film(void **state)
{
    (void)state;
    rr_image img = {0};
    rr_error err;
    assert_int_equal(rr_image_init(&img, 3, 2, &err), RR_OK);
    rr_image_set(&img, 2, 1, rr_rgb_make(1, 2, 3));
    rr_rgb c = rr_image_get(&img, 2, 1);
    assert_near(c.g, 2, 0);
    assert_near(img.px[3 * 5 + 2], 3, 0);
    assert_near(rr_image_get(&img, 0, 0).r, 0, 0);
    rr_image_free(&img);
    rr_image_free(&img);
    assert_null(img.px);
    assert_int_equal(rr_image_init(&img, -1, 5, &err), RR_ERR_INVALID);
    assert_int_equal(rr_image_bytes(1L << 40, 1L << 40), 0);
    assert_int_equal(rr_image_bytes(4, 2), 4 * 2 * 12);
}

static void xforms(void **state)
{
    (void)state;
    rr_xform a = rr_xform_identity(), b = rr_xform_identity();
    a.m[0][0] = 2;
    a.t = rr_v3(1, 0, 0);
    b.t = rr_v3(0, 3, 0);
    rr_xform ab = rr_xform_compose(&a, &b); /* a(b(p)) */
    assert_v3(rr_xform_point(&ab, rr_v3(1, 1, 1)), 3, 4, 1);
    assert_near(rr_xform_det(&ab), 2, 1e-15);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(view_lecture_axis_aligned), cmocka_unit_test(view_lecture_general),
        cmocka_unit_test(view_up_not_perpendicular), cmocka_unit_test(view_errors),
        cmocka_unit_test(view_lookat),               cmocka_unit_test(rng_streams),
        cmocka_unit_test(error_messages),            cmocka_unit_test(atomic_files),
        cmocka_unit_test(paths),                     cmocka_unit_test(image_film),
        cmocka_unit_test(xforms),
    };
    return cmocka_run_group_tests(tests, make_tmpdir, NULL);
}
