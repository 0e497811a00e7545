/* test_image.c - image module: EXR (OpenEXR core) and PNG (libpng) files.
 *
 * Round trips check what a reader gets back (bit-exact for float EXR, within
 * half precision for half EXR, expected sRGB codes computed here from the
 * IEC 61966-2-1 formula for PNG). The failure tests check the atomic-write
 * promise: an error leaves no temporary file and never damages a good file
 * already at the destination.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <dirent.h>
#include <float.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "img.h"

static char g_dir[64];

static const char *tpath(const char *name)
{
    static char buf[8][512];
    static int next;
    char *p = buf[next++ % 8];
    snprintf(p, 512, "%s/%s", g_dir, name);
    return p;
}

/* Number of temporary files (".tmp-" in the name) left in the test folder. */
static int count_tmp(void)
{
    DIR *d = opendir(g_dir);
    assert_non_null(d);
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".tmp-"))
            n++;
    closedir(d);
    return n;
}

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

/* Deterministic pseudo-random floats for incompressible test images. */
static uint32_t g_lcg = 12345u;
static float noise01(void)
{
    g_lcg = g_lcg * 1664525u + 1013904223u;
    return (float)(g_lcg >> 8) / 16777216.0f;
}

/* A w x h image of base, base + 0.25, ... (base < 0: noise in [0, 1)). */
static rr_image make_image(int w, int h, float base)
{
    rr_image img = {0};
    assert_int_equal(rr_image_init(&img, w, h, NULL), RR_OK);
    for (size_t i = 0; i < 3 * (size_t)w * (size_t)h; i++)
        img.px[i] = base < 0.0f ? noise01() : base + 0.25f * (float)i;
    return img;
}

/* --------------------------------------------------------------------- EXR */

/* 13 x 37: odd sizes, and more rows than one 16-line ZIP chunk, so the last
 * chunk is partial. Float is stored bit for bit, extremes included. */
static void exr_float_round_trip(void **state)
{
    (void)state;
    rr_image img = make_image(13, 37, 100.0f);
    const float special[] = {FLT_MAX, -FLT_MAX, FLT_MIN, 1e-45f /* denormal */, -0.0f, 1e30f, -1e-30f,
                             (float)INFINITY, -(float)INFINITY, NAN, 3.14159265f, -123456.789f};
    memcpy(img.px, special, sizeof special);
    /* Different channels differ, and the last pixel is set too (row order). */
    img.px[3 * 13 * 37 - 1] = 42.5f;
    const char *p = tpath("float.exr");
    rr_error err;
    assert_int_equal(img_write_exr(p, &img, NULL, 0, IMG_FLOAT, &err), RR_OK);
    assert_int_equal(count_tmp(), 0);

    rr_image back = {0};
    assert_int_equal(img_read_exr(p, NULL, &back, &err), RR_OK);
    assert_int_equal(back.width, 13);
    assert_int_equal(back.height, 37);
    assert_memory_equal(back.px, img.px, sizeof(float) * 3 * 13 * 37);
    rr_image_free(&back);
    /* "" means the main layer too. */
    assert_int_equal(img_read_exr(p, "", &back, &err), RR_OK);
    assert_memory_equal(back.px, img.px, sizeof(float) * 3 * 13 * 37);
    rr_image_free(&back);
    rr_image_free(&img);
}

static int within_half(float got, float want)
{
    /* Round to nearest: relative error at most 2^-11 (plus float noise). */
    return fabs((double)got - (double)want) <= fabs((double)want) * (1.0 / 2048.0) * (1.0 + 1e-6);
}

static void exr_half_round_trip(void **state)
{
    (void)state;
    rr_image img = make_image(21, 19, 0.0f);
    for (size_t i = 0; i < 3 * 21 * 19; i++) {
        /* Normal half range [2^-14, 65504], both signs. */
        double mag = pow(2.0, -14.0 + 29.9 * noise01());
        img.px[i] = (float)((i % 2) ? -mag : mag);
    }
    /* Exact rounding cases: 1 + 2^-11 is halfway between 1 and 1 + 2^-10
     * (ties to even gives 1); 1 + 3 * 2^-12 rounds up; 65504 is the largest
     * half; 2^-24 the smallest subnormal; beyond 65520 is infinity. */
    const float special[] = {1.0f + 0x1p-11f, 1.0f + 0x1.8p-11f, 65504.0f, 0x1p-24f, 0.0f, -2.0f, 1e6f};
    const float expect[] = {1.0f, 1.0f + 0x1p-10f, 65504.0f, 0x1p-24f, 0.0f, -2.0f, (float)INFINITY};
    memcpy(img.px, special, sizeof special);
    const char *p = tpath("half.exr");
    rr_error err;
    assert_int_equal(img_write_exr(p, &img, NULL, 0, IMG_HALF, &err), RR_OK);
    rr_image back = {0};
    assert_int_equal(img_read_exr(p, NULL, &back, &err), RR_OK);
    assert_int_equal(back.width, 21);
    assert_int_equal(back.height, 19);
    for (size_t i = 0; i < sizeof expect / sizeof expect[0]; i++)
        assert_true(back.px[i] == expect[i]);
    for (size_t i = sizeof special / sizeof special[0]; i < 3 * 21 * 19; i++)
        if (!within_half(back.px[i], img.px[i]))
            fail_msg("value %zu: wrote %.9g, read %.9g", i, (double)img.px[i], (double)back.px[i]);
    rr_image_free(&back);
    rr_image_free(&img);
    assert_int_equal(count_tmp(), 0);
}

static void exr_layers_round_trip(void **state)
{
    (void)state;
    rr_image rgb = make_image(9, 17, 1.0f);
    rr_image diffuse = make_image(9, 17, 1000.0f);
    rr_image albedo = make_image(9, 17, 0.5f);
    /* Given out of alphabetical order: the file sorts channels, the reader
     * must still match them by name. */
    img_layer layers[2] = {{"diffuse", &diffuse}, {"albedo-2", &albedo}};
    const char *p = tpath("layers.exr");
    rr_error err;
    for (int t = 0; t < 2; t++) {
        img_pixel_type type = t ? IMG_HALF : IMG_FLOAT;
        assert_int_equal(img_write_exr(p, &rgb, layers, 2, type, &err), RR_OK);
        const rr_image *want[3] = {&rgb, &diffuse, &albedo};
        const char *names[3] = {NULL, "diffuse", "albedo-2"};
        for (int k = 0; k < 3; k++) {
            rr_image back = {0};
            assert_int_equal(img_read_exr(p, names[k], &back, &err), RR_OK);
            assert_int_equal(back.width, 9);
            assert_int_equal(back.height, 17);
            for (size_t i = 0; i < 3 * 9 * 17; i++) {
                float w = want[k]->px[i], g = back.px[i];
                if (type == IMG_FLOAT ? g != w : !within_half(g, w))
                    fail_msg("layer %s value %zu: wrote %.9g, read %.9g", names[k] ? names[k] : "(main)", i,
                             (double)w, (double)g);
            }
            rr_image_free(&back);
        }
        char found[4][64];
        int count = -1;
        assert_int_equal(img_exr_layers(p, found, 4, &count, &err), RR_OK);
        assert_int_equal(count, 2);
        assert_string_equal(found[0], "albedo-2");
        assert_string_equal(found[1], "diffuse");
        /* max limits what is stored. */
        assert_int_equal(img_exr_layers(p, found, 1, &count, &err), RR_OK);
        assert_int_equal(count, 1);
        assert_string_equal(found[0], "albedo-2");
    }
    /* A file without extra layers lists none. */
    assert_int_equal(img_write_exr(p, &rgb, NULL, 0, IMG_FLOAT, &err), RR_OK);
    char found[1][64];
    int count = -1;
    assert_int_equal(img_exr_layers(p, found, 1, &count, &err), RR_OK);
    assert_int_equal(count, 0);
    /* Names over 31 bytes need the EXR "long names" flag. */
    const char *name = "a_layer_name_that_is_longer_than_31_bytes-0123456789";
    img_layer long_layer = {name, &albedo};
    assert_int_equal(img_write_exr(p, &rgb, &long_layer, 1, IMG_FLOAT, &err), RR_OK);
    rr_image back = {0};
    assert_int_equal(img_read_exr(p, name, &back, &err), RR_OK);
    assert_memory_equal(back.px, albedo.px, sizeof(float) * 3 * 9 * 17);
    rr_image_free(&back);
    assert_int_equal(img_exr_layers(p, found, 1, &count, &err), RR_OK);
    assert_int_equal(count, 1);
    assert_string_equal(found[0], name);
    rr_image_free(&rgb);
    rr_image_free(&diffuse);
    rr_image_free(&albedo);
    assert_int_equal(count_tmp(), 0);
}

static void exr_missing_layer(void **state)
{
    (void)state;
    rr_image rgb = make_image(4, 3, 0.0f);
    rr_image a = make_image(4, 3, 1.0f);
    img_layer layers[2] = {{"normal", &a}, {"depth", &a}};
    const char *p = tpath("missing.exr");
    rr_error err;
    assert_int_equal(img_write_exr(p, &rgb, layers, 2, IMG_HALF, &err), RR_OK);
    rr_image out = {.width = -7, .height = -7, .px = NULL};
    assert_int_not_equal(img_read_exr(p, "specular", &out, &err), RR_OK);
    assert_int_equal(err.code, RR_ERR_INVALID);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    assert_non_null(strstr(err.msg, "specular"));
    assert_non_null(strstr(err.msg, "normal"));
    assert_non_null(strstr(err.msg, "depth"));
    assert_int_equal(out.width, -7); /* untouched */
    assert_null(out.px);
    /* A layer name is matched whole: "norm" is not "normal". */
    assert_int_not_equal(img_read_exr(p, "norm", &out, &err), RR_OK);
    /* Without layers, the message says there are none. */
    assert_int_equal(img_write_exr(p, &rgb, NULL, 0, IMG_HALF, &err), RR_OK);
    assert_int_equal(img_read_exr(p, "normal", &out, &err), RR_ERR_INVALID);
    assert_non_null(strstr(err.msg, "no extra layers"));
    rr_image_free(&rgb);
    rr_image_free(&a);
}

/* The read fails cleanly; when the header itself is broken, listing the
 * layers (which reads only the header) fails too. */
static void expect_read_error(const char *p, int header_broken)
{
    rr_image out = {0};
    rr_error err;
    rr_status st = img_read_exr(p, NULL, &out, &err);
    if (st == RR_OK)
        fail_msg("%s: read should fail", p);
    assert_null(out.px);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    char names[2][64];
    int count = 0;
    if (header_broken)
        assert_int_not_equal(img_exr_layers(p, names, 2, &count, &err), RR_OK);
}

static void exr_bad_files(void **state)
{
    (void)state;
    expect_read_error(tpath("does-not-exist.exr"), 1);
    rr_error err;
    rr_image out = {0};
    assert_int_equal(img_read_exr(tpath("does-not-exist.exr"), NULL, &out, &err), RR_ERR_IO);
    expect_read_error(g_dir, 1); /* a folder */

    const char *text = "this is a text file, certainly not an OpenEXR image\n";
    const char *pt = tpath("text.exr");
    write_bytes(pt, text, strlen(text));
    expect_read_error(pt, 1);
    write_bytes(pt, "", 0);
    expect_read_error(pt, 1);

    /* Every truncation of a good file fails cleanly (header, offset table
     * or pixel data cut short). */
    rr_image img = make_image(40, 40, -1.0f);
    const char *good = tpath("good.exr");
    assert_int_equal(img_write_exr(good, &img, NULL, 0, IMG_FLOAT, &err), RR_OK);
    char *data = NULL;
    size_t size = 0;
    assert_int_equal(rr_file_read_all(good, &data, &size, NULL), RR_OK);
    const char *pc = tpath("cut.exr");
    /* The header of this file is ~330 bytes. */
    const size_t cuts[] = {4, 8, 100, 300, size / 2, size - 16, size - 1};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        write_bytes(pc, data, cuts[i]);
        expect_read_error(pc, cuts[i] <= 300);
    }
    free(data);
    rr_image_free(&img);
}

static void exr_write_missing_folder(void **state)
{
    (void)state;
    rr_image img = make_image(2, 2, 0.0f);
    const char *p = tpath("no-such-folder/out.exr");
    rr_error err;
    assert_int_equal(img_write_exr(p, &img, NULL, 0, IMG_FLOAT, &err), RR_ERR_IO);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    assert_false(exists(tpath("no-such-folder")));
    assert_int_equal(count_tmp(), 0);
    /* The destination is an existing folder: nothing replaces it. */
    assert_int_equal(img_write_exr(g_dir, &img, NULL, 0, IMG_FLOAT, &err), RR_ERR_IO);
    assert_int_equal(count_tmp(), 0);
    rr_image_free(&img);
}

/* Writes img (as float EXR, or PNG) with the process file-size limit
 * lowered, so that writing more than limit bytes to any file fails with
 * EFBIG: a real I/O error in the middle of a write. */
static rr_status write_limited(rlim_t limit, int png, const char *path, const rr_image *img, rr_error *err)
{
    struct rlimit old, low;
    assert_int_equal(getrlimit(RLIMIT_FSIZE, &old), 0);
    void (*prev)(int) = signal(SIGXFSZ, SIG_IGN); /* EFBIG instead of a signal */
    low = old;
    low.rlim_cur = limit;
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &low), 0);
    rr_status st = png ? img_write_png(path, img, 0.0, err) : img_write_exr(path, img, NULL, 0, IMG_FLOAT, err);
    assert_int_equal(setrlimit(RLIMIT_FSIZE, &old), 0);
    signal(SIGXFSZ, prev);
    return st;
}

static void assert_same_file(const char *path, const char *data, size_t size)
{
    char *now = NULL;
    size_t now_size = 0;
    assert_int_equal(rr_file_read_all(path, &now, &now_size, NULL), RR_OK);
    assert_int_equal(now_size, size);
    assert_memory_equal(now, data, size);
    free(now);
}

static void exr_failed_write_keeps_old_file(void **state)
{
    (void)state;
    rr_image good = make_image(5, 6, 2.0f);
    const char *p = tpath("keep.exr");
    rr_error err;
    assert_int_equal(img_write_exr(p, &good, NULL, 0, IMG_FLOAT, &err), RR_OK);
    char *data = NULL;
    size_t size = 0;
    assert_int_equal(rr_file_read_all(p, &data, &size, NULL), RR_OK);

    /* Rejected arguments. */
    rr_image empty = {0};
    assert_int_not_equal(img_write_exr(p, &empty, NULL, 0, IMG_FLOAT, &err), RR_OK);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    rr_image small = make_image(2, 2, 0.0f);
    img_layer bad_size = {"x", &small};
    assert_int_equal(img_write_exr(p, &good, &bad_size, 1, IMG_FLOAT, &err), RR_ERR_INVALID);
    img_layer bad_name = {"a.b", &good};
    assert_int_equal(img_write_exr(p, &good, &bad_name, 1, IMG_FLOAT, &err), RR_ERR_INVALID);
    img_layer twice[2] = {{"same", &good}, {"same", &good}};
    assert_int_equal(img_write_exr(p, &good, twice, 2, IMG_FLOAT, &err), RR_ERR_INVALID);
    assert_int_equal(img_write_exr(p, &good, NULL, 0, (img_pixel_type)7, &err), RR_ERR_INVALID);
    assert_same_file(p, data, size);

    /* An I/O error half way through: 300 x 200 noise is ~700 KB of floats. */
    rr_image big = make_image(300, 200, -1.0f);
    assert_int_equal(write_limited(64 * 1024, 0, p, &big, &err), RR_ERR_IO);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    assert_same_file(p, data, size);
    assert_int_equal(count_tmp(), 0);

    rr_image back = {0};
    assert_int_equal(img_read_exr(p, NULL, &back, &err), RR_OK);
    assert_memory_equal(back.px, good.px, sizeof(float) * 3 * 5 * 6);
    rr_image_free(&back);
    free(data);
    rr_image_free(&big);
    rr_image_free(&small);
    rr_image_free(&good);
}

/* --------------------------------------------------------------------- PNG */

/* The IEC 61966-2-1 encoding, written out independently of the module. */
static int srgb_byte(double linear)
{
    if (isnan(linear) || linear <= 0.0)
        return 0;
    if (linear >= 1.0)
        return 255;
    double s = linear <= 0.0031308 ? 12.92 * linear : 1.055 * pow(linear, 1.0 / 2.4) - 0.055;
    return (int)floor(s * 255.0 + 0.5);
}

static void png_srgb_curve(void **state)
{
    (void)state;
    assert_true(img_srgb_encode(0.0) == 0.0);
    assert_true(img_srgb_encode(1.0) == 1.0);
    assert_true(fabs(img_srgb_encode(0.5) - 0.735356983052449) < 1e-12);
    assert_true(fabs(img_srgb_encode(0.0031308) - 0.040449936) < 1e-9);
    assert_true(fabs(img_srgb_encode(0.001) - 0.01292) < 1e-12);
    /* Out of range and NaN are clamped. */
    assert_true(img_srgb_encode(-1.0) == 0.0);
    assert_true(img_srgb_encode(7.0) == 1.0);
    assert_true(img_srgb_encode(NAN) == 0.0);
    /* Monotonic, and the two pieces meet at the threshold. */
    double prev = -1.0;
    for (int i = 0; i <= 10000; i++) {
        double v = img_srgb_encode(i / 10000.0);
        assert_true(v > prev);
        prev = v;
    }
    assert_true(fabs(img_srgb_encode(0.0031308 + 1e-12) - img_srgb_encode(0.0031308)) < 1e-6);
}

static void png_known_values(void **state)
{
    (void)state;
    const float lin[] = {0.0f, 1.0f, 0.5f, 0.18f, 0.0031308f, 0.001f, 0.0001f, 0.9999f,
                         2.0f, -1.0f, NAN, (float)INFINITY, -(float)INFINITY, 0.2140f, 0.7f};
    const int n = (int)(sizeof lin / sizeof lin[0]); /* 15 values = 5 RGB pixels */
    rr_image img = {0};
    assert_int_equal(rr_image_init(&img, 5, 2, NULL), RR_OK);
    memcpy(img.px, lin, sizeof lin);
    /* Second row: the first one reversed, to check row order. */
    for (int i = 0; i < n; i++)
        img.px[n + i] = lin[n - 1 - i];
    const char *p = tpath("known.png");
    rr_error err;
    assert_int_equal(img_write_png(p, &img, 0.0, &err), RR_OK);
    assert_int_equal(count_tmp(), 0);
    unsigned char *rgb8 = NULL;
    int w = 0, h = 0;
    assert_int_equal(img_read_png(p, &rgb8, &w, &h, &err), RR_OK);
    assert_int_equal(w, 5);
    assert_int_equal(h, 2);
    /* Literal anchors, then the formula for everything. */
    assert_int_equal(rgb8[0], 0);
    assert_int_equal(rgb8[1], 255);
    assert_int_equal(rgb8[2], 188); /* 0.5 -> 0.7354 * 255 = 187.5 */
    assert_int_equal(rgb8[3], 118); /* 18% grey */
    assert_int_equal(rgb8[4], 10);  /* 0.0031308 * 12.92 * 255 = 10.3 */
    assert_int_equal(rgb8[8], 255); /* 2.0 clamped */
    assert_int_equal(rgb8[9], 0);   /* negative */
    assert_int_equal(rgb8[10], 0);  /* NaN */
    assert_int_equal(rgb8[11], 255);
    assert_int_equal(rgb8[12], 0);
    for (int i = 0; i < n; i++) {
        assert_int_equal(rgb8[i], srgb_byte(lin[i]));
        assert_int_equal(rgb8[n + i], srgb_byte(lin[n - 1 - i]));
    }
    free(rgb8);
    rr_image_free(&img);
}

static void png_exposure(void **state)
{
    (void)state;
    rr_image img = {0};
    assert_int_equal(rr_image_init(&img, 2, 1, NULL), RR_OK);
    const float lin[6] = {0.25f, 0.6f, 0.1f, 1.0f, 0.05f, 0.003f};
    memcpy(img.px, lin, sizeof lin);
    const char *p = tpath("exposure.png");
    rr_error err;
    unsigned char *rgb8 = NULL;
    int w = 0, h = 0;
    /* +1 stop doubles before encoding: 0.25 -> 0.5 -> 188; 0.6 -> 1.2 clamps. */
    assert_int_equal(img_write_png(p, &img, 1.0, &err), RR_OK);
    assert_int_equal(img_read_png(p, &rgb8, &w, &h, &err), RR_OK);
    assert_int_equal(rgb8[0], 188);
    assert_int_equal(rgb8[1], 255);
    for (int i = 0; i < 6; i++)
        assert_int_equal(rgb8[i], srgb_byte(2.0 * lin[i]));
    free(rgb8);
    /* -1 stop halves: 1.0 -> 0.5 -> 188. */
    assert_int_equal(img_write_png(p, &img, -1.0, &err), RR_OK);
    assert_int_equal(img_read_png(p, &rgb8, &w, &h, &err), RR_OK);
    assert_int_equal(rgb8[3], 188);
    for (int i = 0; i < 6; i++)
        assert_int_equal(rgb8[i], srgb_byte(0.5 * lin[i]));
    free(rgb8);
    /* Fractional exposure: 2^0.5. */
    assert_int_equal(img_write_png(p, &img, 0.5, &err), RR_OK);
    assert_int_equal(img_read_png(p, &rgb8, &w, &h, &err), RR_OK);
    for (int i = 0; i < 6; i++)
        assert_int_equal(rgb8[i], srgb_byte(sqrt(2.0) * lin[i]));
    free(rgb8);
    assert_int_not_equal(img_write_png(p, &img, INFINITY, &err), RR_OK);
    rr_image_free(&img);
    assert_int_equal(count_tmp(), 0);
}

/* Hand-made PNGs (zlib + CRC computed offline) in the colour types that
 * img_read_png converts to 8-bit RGB. */
static const char k_png_gray8[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x03\x00\x00\x00\x02\x08"
    "\x00\x00\x00\x00\xb8\x1f\x39\xc6\x00\x00\x00\x10\x49\x44\x41\x54\x78\xda\x63\x60\x68\xf8\xcf\xc0\xc8"
    "\xc4\x0c\x00\x08\x0d\x01\x86\xe5\x48\x5e\x35\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
static const char k_png_palette[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x02\x00\x00\x00\x02\x08"
    "\x03\x00\x00\x00\x45\x68\xfd\x16\x00\x00\x00\x09\x50\x4c\x54\x45\xff\x00\x00\x00\xff\x00\x0a\x14\x1e"
    "\xd9\x7e\x4d\xe7\x00\x00\x00\x0e\x49\x44\x41\x54\x78\xda\x63\x60\x60\x64\x60\x62\x00\x00\x00\x0e\x00"
    "\x04\xdb\xe0\x32\x8e\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
static const char k_png_rgba[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x02\x00\x00\x00\x01\x08"
    "\x06\x00\x00\x00\xf4\x22\x7f\x8a\x00\x00\x00\x11\x49\x44\x41\x54\x78\xda\x63\xe0\x12\x91\x63\xd0\x30"
    "\xb2\xf9\x0f\x00\x04\x46\x01\xd2\x4a\x0d\x15\x0a\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
static const char k_png_gray_alpha16[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x01\x00\x00\x00\x01\x10"
    "\x04\x00\x00\x00\xe5\x8c\xd0\x41\x00\x00\x00\x0d\x49\x44\x41\x54\x78\xda\x63\x68\x68\x10\x32\x01\x00"
    "\x03\xdd\x01\x47\x16\x6a\x11\x95\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
static const char k_png_rgb16[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x02\x00\x00\x00\x01\x10"
    "\x02\x00\x00\x00\x2b\xd0\x34\x9e\x00\x00\x00\x15\x49\x44\x41\x54\x78\xda\x63\xf8\xff\x9f\x81\x81\x91"
    "\xb1\xbe\xbe\xa1\xe1\xdf\x3f\x00\x22\xf4\x05\xfb\xec\x60\xb3\x7c\x00\x00\x00\x00\x49\x45\x4e\x44\xae"
    "\x42\x60\x82";
static const char k_png_gray1[] =
    "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x08\x00\x00\x00\x01\x01"
    "\x00\x00\x00\x00\xcb\x7b\xd2\xee\x00\x00\x00\x0a\x49\x44\x41\x54\x78\xda\x63\xd8\x00\x00\x00\xb2\x00"
    "\xb1\xf8\x82\x92\xa7\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";

static void expect_png(const char *data, size_t n, int ew, int eh, const unsigned char *expect)
{
    const char *p = tpath("fixture.png");
    write_bytes(p, data, n);
    unsigned char *rgb8 = NULL;
    int w = 0, h = 0;
    rr_error err;
    if (img_read_png(p, &rgb8, &w, &h, &err) != RR_OK)
        fail_msg("%s", err.msg);
    assert_int_equal(w, ew);
    assert_int_equal(h, eh);
    assert_memory_equal(rgb8, expect, 3 * (size_t)ew * (size_t)eh);
    free(rgb8);
}

static void png_read_formats(void **state)
{
    (void)state;
    const unsigned char gray8[] = {0, 0, 0, 128, 128, 128, 255, 255, 255, 1, 1, 1, 2, 2, 2, 3, 3, 3};
    expect_png(k_png_gray8, sizeof k_png_gray8 - 1, 3, 2, gray8);
    const unsigned char pal[] = {255, 0, 0, 0, 255, 0, 10, 20, 30, 255, 0, 0};
    expect_png(k_png_palette, sizeof k_png_palette - 1, 2, 2, pal);
    const unsigned char rgba[] = {10, 20, 30, 40, 50, 60}; /* alpha dropped, colour kept */
    expect_png(k_png_rgba, sizeof k_png_rgba - 1, 2, 1, rgba);
    const unsigned char ga16[] = {128, 128, 128};
    expect_png(k_png_gray_alpha16, sizeof k_png_gray_alpha16 - 1, 1, 1, ga16);
    const unsigned char rgb16[] = {255, 0, 1, 127, 128, 254};
    expect_png(k_png_rgb16, sizeof k_png_rgb16 - 1, 2, 1, rgb16);
    const unsigned char g1[] = {255, 255, 255, 0, 0, 0, 255, 255, 255, 255, 255, 255,
                                0,   0,   0,   0, 0, 0, 0,   0,   0,   0,   0,   0};
    expect_png(k_png_gray1, sizeof k_png_gray1 - 1, 8, 1, g1);
}

static void png_bad_files(void **state)
{
    (void)state;
    unsigned char *rgb8 = NULL;
    int w = 0, h = 0;
    rr_error err;
    const char *missing = tpath("missing.png");
    assert_int_equal(img_read_png(missing, &rgb8, &w, &h, &err), RR_ERR_IO);
    assert_true(strncmp(err.msg, missing, strlen(missing)) == 0);
    const char *pt = tpath("text.png");
    write_bytes(pt, "definitely not a PNG file", 25);
    assert_int_equal(img_read_png(pt, &rgb8, &w, &h, &err), RR_ERR_PARSE);
    assert_true(strncmp(err.msg, pt, strlen(pt)) == 0);
    assert_null(rgb8);

    /* Truncated and corrupted versions of a real file fail without a crash
     * (the ASan build also checks for leaks on these libpng error paths). */
    rr_image img = make_image(30, 20, -1.0f);
    const char *good = tpath("good.png");
    assert_int_equal(img_write_png(good, &img, 0.0, &err), RR_OK);
    char *data = NULL;
    size_t size = 0;
    assert_int_equal(rr_file_read_all(good, &data, &size, NULL), RR_OK);
    const char *pc = tpath("cut.png");
    const size_t cuts[] = {4, 8, 20, 40, size / 2, size - 13};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        write_bytes(pc, data, cuts[i]);
        if (img_read_png(pc, &rgb8, &w, &h, &err) == RR_OK)
            fail_msg("truncated to %zu bytes: read should fail", cuts[i]);
        assert_true(strncmp(err.msg, pc, strlen(pc)) == 0);
        assert_null(rgb8);
    }
    /* Flip a byte inside the image data: the CRC check rejects it. */
    data[size / 2] ^= 0x5a;
    write_bytes(pc, data, size);
    assert_int_not_equal(img_read_png(pc, &rgb8, &w, &h, &err), RR_OK);
    assert_null(rgb8);
    free(data);
    rr_image_free(&img);
}

static void png_failed_write_keeps_old_file(void **state)
{
    (void)state;
    rr_image good = make_image(4, 4, 0.0f);
    for (size_t i = 0; i < 3 * 16; i++)
        good.px[i] = (float)i / 48.0f;
    const char *p = tpath("keep.png");
    rr_error err;
    assert_int_equal(img_write_png(p, &good, 0.0, &err), RR_OK);
    char *data = NULL;
    size_t size = 0;
    assert_int_equal(rr_file_read_all(p, &data, &size, NULL), RR_OK);

    rr_image empty = {0};
    assert_int_not_equal(img_write_png(p, &empty, 0.0, &err), RR_OK);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    assert_same_file(p, data, size);

    rr_image big = make_image(400, 300, -1.0f);
    assert_int_equal(write_limited(32 * 1024, 1, p, &big, &err), RR_ERR_IO);
    assert_true(strncmp(err.msg, p, strlen(p)) == 0);
    assert_same_file(p, data, size);
    assert_int_equal(count_tmp(), 0);

    const char *nodir = tpath("no-such-folder/out.png");
    assert_int_equal(img_write_png(nodir, &good, 0.0, &err), RR_ERR_IO);
    assert_true(strncmp(err.msg, nodir, strlen(nodir)) == 0);
    assert_false(exists(tpath("no-such-folder")));
    assert_int_equal(count_tmp(), 0);
    free(data);
    rr_image_free(&big);
    rr_image_free(&good);
}

/* ------------------------------------------------------------------ driver */

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/rr_image_XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    DIR *d = opendir(g_dir);
    if (!d)
        return -1;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
            continue;
        char p[600];
        snprintf(p, sizeof p, "%s/%s", g_dir, e->d_name);
        remove(p);
    }
    closedir(d);
    return rmdir(g_dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(exr_float_round_trip),
        cmocka_unit_test(exr_half_round_trip),
        cmocka_unit_test(exr_layers_round_trip),
        cmocka_unit_test(exr_missing_layer),
        cmocka_unit_test(exr_bad_files),
        cmocka_unit_test(exr_write_missing_folder),
        cmocka_unit_test(exr_failed_write_keeps_old_file),
        cmocka_unit_test(png_srgb_curve),
        cmocka_unit_test(png_known_values),
        cmocka_unit_test(png_exposure),
        cmocka_unit_test(png_read_formats),
        cmocka_unit_test(png_bad_files),
        cmocka_unit_test(png_failed_write_keeps_old_file),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
