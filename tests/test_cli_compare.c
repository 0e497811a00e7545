/* test_cli_compare.c - `radray compare` as a user meets it: a figure of the
 * four modes of the Cornell box with its per-object table, the lecture's
 * layer panels, PDF and SVG output, one-line errors naming a bad mode or
 * layer, and no file where the output cannot be written. Small images and
 * sample counts keep it quick. */
#define _XOPEN_SOURCE 700 /* nftw, to remove the temporary folder */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <ftw.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "img.h"
#include "test_cli_run.h"
#include "rr_core.h"

static char g_dir[64];
static char g_out[16384]; /* captured stdout + stderr of the last run */

/* Runs radray with args (NULL-terminated); returns its exit code and leaves
 * its combined output in g_out (truncated). */
static int run(const char *const *args)
{
    char log[128];
    snprintf(log, sizeof log, "%s/log.txt", g_dir);
    return test_cli_run(log, args, g_out, sizeof g_out);
}

static const char *path_in(const char *name)
{
    static char p[4][256];
    static int i;
    i = (i + 1) % 4;
    snprintf(p[i], sizeof p[i], "%s/%s", g_dir, name);
    return p[i];
}

static const char *scene(const char *name)
{
    static char p[256];
    snprintf(p, sizeof p, "%s/scenes/%s", RR_SOURCE_DIR, name);
    return p;
}

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Expects exit 2 with one line of error that contains every string of want. */
static void expect_usage(const char *const *args, const char *const *want)
{
    int rc = run(args);
    if (rc != 2)
        fail_msg("expected exit 2, got %d: %s", rc, g_out);
    for (int i = 0; want[i]; i++)
        if (!strstr(g_out, want[i]))
            fail_msg("expected '%s' in: %s", want[i], g_out);
    char *nl = strchr(g_out, '\n');
    assert_true(nl == NULL || nl[1] == '\0');
}

static void help(void **state)
{
    (void)state;
    const char *a[] = {"--help", NULL};
    assert_int_equal(run(a), 0);
    assert_non_null(strstr(g_out, "compare"));
    const char *b[] = {"help", "compare", NULL};
    assert_int_equal(run(b), 0);
    assert_non_null(strstr(g_out, "--modes"));
    assert_non_null(strstr(g_out, "--layers"));
    assert_non_null(strstr(g_out, "--secondary-spp"));
}

/* All four modes of the Cornell box: the figure is larger than a panel (it
 * holds four of them, a difference row and the table), and the table names
 * the walls with the reference marked. */
static void cornell_modes(void **state)
{
    (void)state;
    const char *fig = path_in("sub/dir/cornell.png"); /* folders are made as render makes them */
    const char *a[] = {"compare", scene("cornell.json"), "--width", "21", "--spp", "1", "--secondary-spp", "4",
                       "--set", "radiosity.patch_area=4000", "-o", fig, NULL};
    int rc = run(a);
    if (rc != 0)
        fail_msg("exit %d: %s", rc, g_out);
    static const char *const want[] = {"floor", "back_wall", "left_wall", "right_wall", "whitted", "secondary",
                                       "radiosity", "hybrid", "(ref)", "(all pixels)", "cornell.png", NULL};
    for (int i = 0; want[i]; i++)
        if (!strstr(g_out, want[i]))
            fail_msg("expected '%s' in: %s", want[i], g_out);
    unsigned char *rgb = NULL;
    int w = 0, h = 0;
    assert_int_equal(img_read_png(fig, &rgb, &w, &h, NULL), RR_OK);
    assert_true(w > 4 * 21 && h > 2 * 21);
    /* Not a blank page: the renders and the text are there. */
    long dark = 0;
    for (long i = 0; i < 3L * w * h; i++)
        dark += rgb[i] < 64;
    assert_true(dark > 4 * 21 * 21);
    free(rgb);
    /* The table's secondary column is the reference: the left wall row gives
     * each mode's value and its relative difference. */
    const char *line = strstr(g_out, "\nleft_wall");
    assert_non_null(line);
    long px = 0;
    double v[4] = {0};
    assert_int_equal(sscanf(line, " left_wall %ld %lf (%*[^)]) %lf (ref)", &px, &v[0], &v[1]), 3);
    assert_true(px > 4 && v[0] >= 0 && v[1] > 0);
}

/* The lecture's shading panels: the layers of one render, no difference
 * row; the ambient layer is filled (it comes from the Whitted render). */
static void phong_layers(void **state)
{
    (void)state;
    const char *fig = path_in("layers.png");
    const char *a[] = {"compare", scene("phong-spheres.json"), "--layers", "ambient,diffuse,specular",
                       "--width", "41", "--spp", "1", "-o", fig, NULL};
    int rc = run(a);
    if (rc != 0)
        fail_msg("exit %d: %s", rc, g_out);
    assert_non_null(strstr(g_out, "ambient"));
    assert_non_null(strstr(g_out, "specular"));
    assert_null(strstr(g_out, "(ref)"));
    const char *line = strstr(g_out, "\nboard");
    assert_non_null(line);
    long px = 0;
    double amb = 0, dif = 0, spec = -1;
    assert_int_equal(sscanf(line, " board %ld %lf %lf %lf", &px, &amb, &dif, &spec), 4);
    assert_true(amb > 0 && dif > amb && spec >= 0);
    unsigned char *rgb = NULL;
    int w = 0, h = 0;
    assert_int_equal(img_read_png(fig, &rgb, &w, &h, NULL), RR_OK);
    assert_true(w > 3 * 41 && h > 21);
    free(rgb);
}

static void vector_outputs(void **state)
{
    (void)state;
    static const char *const names[] = {"fig.pdf", "fig.svg"};
    for (int i = 0; i < 2; i++) {
        const char *fig = path_in(names[i]);
        const char *a[] = {"compare", scene("cornell.json"), "--modes", "whitted,hybrid", "--width", "11",
                           "--spp", "1", "--set", "radiosity.patch_area=4000", "-q", "-o", fig, NULL};
        int rc = run(a);
        if (rc != 0)
            fail_msg("exit %d: %s", rc, g_out);
        assert_string_equal(g_out, ""); /* -q */
        char *data = NULL;
        size_t n = 0;
        assert_int_equal(rr_file_read_all(fig, &data, &n, NULL), RR_OK);
        if (i == 0)
            assert_memory_equal(data, "%PDF", 4);
        else
            assert_true(!strncmp(data, "<?xml", 5) || !strncmp(data, "<svg", 4));
        free(data);
    }
}

static void bad_input(void **state)
{
    (void)state;
    const char *fig = path_in("bad.png");
    const char *a[] = {"compare", scene("cornell.json"), "--modes", "whitted,raytraced", "-o", fig, NULL};
    static const char *const wa[] = {"raytraced", "whitted", "secondary", "radiosity", "hybrid", NULL};
    expect_usage(a, wa);
    const char *b[] = {"compare", scene("cornell.json"), "--layers", "ambient,shiny", "-o", fig, NULL};
    static const char *const wb[] = {"shiny", "diffuse", "beauty", NULL};
    expect_usage(b, wb);
    const char *c[] = {"compare", scene("cornell.json"), "--modes", "whitted,hybrid", "--reference", "secondary",
                       "-o", fig, NULL};
    static const char *const wc[] = {"--reference", "secondary", NULL};
    expect_usage(c, wc);
    const char *d[] = {"compare", scene("cornell.json"), "-o", path_in("fig.jpg"), NULL};
    static const char *const wd[] = {"fig.jpg", ".png", NULL};
    expect_usage(d, wd);
    const char *e[] = {"compare", NULL};
    static const char *const we[] = {"SCENE", NULL};
    expect_usage(e, we);
    assert_false(exists(fig));
}

/* The number after "key": in the row of panel `panel`, region "(all pixels)". */
static double stats_value(const char *json, const char *panel, const char *key)
{
    char want[96];
    snprintf(want, sizeof want, "{\"panel\": \"%s\", \"region\": \"(all pixels)\"", panel);
    const char *row = strstr(json, want);
    assert_non_null(row);
    char k[64];
    snprintf(k, sizeof k, "\"%s\": ", key);
    const char *v = strstr(row, k);
    assert_non_null(v);
    return strtod(v + strlen(k), NULL);
}

/* compare --reference FILE.exr (an image from any renderer; here from
 * `render`): a render of the same settings scores relMSE 0 and SSIM 1
 * against it, another mode's relMSE, MARE and bias are what this test
 * computes itself from the two EXRs, and a second run reuses the radiosity
 * cache. */
static void external_reference_and_stats(void **state)
{
    (void)state;
    /* path_in rotates four buffers: keep copies. */
    char ref[256], wh[256], cache[256], fig[256], stats[256], csv[256], fig2[256], junk[256], none[256], txt[256];
    snprintf(ref, sizeof ref, "%s", path_in("ref.exr"));
    snprintf(wh, sizeof wh, "%s", path_in("wh.exr"));
    snprintf(cache, sizeof cache, "%s", path_in("c.cache"));
    snprintf(fig, sizeof fig, "%s", path_in("ext.png"));
    snprintf(stats, sizeof stats, "%s", path_in("s.json"));
    snprintf(csv, sizeof csv, "%s", path_in("s.csv"));
    snprintf(fig2, sizeof fig2, "%s", path_in("never.png"));
    snprintf(junk, sizeof junk, "%s", path_in("junk.exr"));
    snprintf(none, sizeof none, "%s", path_in("none.exr"));
    snprintf(txt, sizeof txt, "%s", path_in("s.txt"));
    const char *r1[] = {"render", scene("cornell.json"), "--width", "24", "--spp", "2", "-q", "-o", ref, NULL};
    assert_int_equal(run(r1), 0);
    const char *r2[] = {"render", scene("cornell.json"), "--width", "24", "--spp", "2", "--mode", "whitted", "-q",
                        "-o", wh, NULL};
    assert_int_equal(run(r2), 0);
    const char *a[] = {"compare", scene("cornell.json"), "--width", "24", "--spp", "2", "--modes", "hybrid,whitted",
                       "--reference", ref, "--stats", stats, "--radiosity-cache", cache, "-o", fig, NULL};
    assert_int_equal(run(a), 0);
    assert_true(exists(fig) && exists(stats) && exists(cache));
    char *json = NULL;
    size_t n = 0;
    assert_int_equal(rr_file_read_all(stats, &json, &n, NULL), RR_OK);
    assert_true(stats_value(json, "hybrid", "relmse") == 0.0);
    assert_true(stats_value(json, "hybrid", "ssim") == 1.0);
    rr_image x = {0}, r = {0};
    assert_int_equal(img_read_exr(wh, NULL, &x, NULL), RR_OK);
    assert_int_equal(img_read_exr(ref, NULL, &r, NULL), RR_OK);
    double rel = 0, mare = 0, bias = 0;
    size_t m = 3 * (size_t)x.width * (size_t)x.height;
    for (size_t k = 0; k < m; k++) {
        double d = (double)x.px[k] - (double)r.px[k], b = r.px[k];
        rel += d * d / (b * b + 0.01);
        mare += fabs(d) / (fabs(b) + 0.01);
        bias += d / (fabs(b) + 0.01);
    }
    rel /= (double)m;
    mare /= (double)m;
    bias /= (double)m;
    assert_true(rel > 0.01);
    assert_true(fabs(stats_value(json, "whitted", "relmse") - rel) <= 1e-6 * rel);
    assert_true(fabs(stats_value(json, "whitted", "mare") - mare) <= 1e-6 * mare);
    assert_true(fabs(stats_value(json, "whitted", "bias") - bias) <= 1e-6 * fabs(bias));
    assert_true(stats_value(json, "whitted", "ssim") < 1.0);
    assert_non_null(strstr(json, "\"region\": \"back_wall\""));
    free(json);
    rr_image_free(&x);
    rr_image_free(&r);
    /* Again, as CSV, from the cache. */
    const char *b[] = {"compare", scene("cornell.json"), "--width", "24", "--spp", "2", "--modes", "hybrid",
                       "--reference", ref, "--stats", csv, "--radiosity-cache", cache, "-o", fig, NULL};
    assert_int_equal(run(b), 0);
    assert_non_null(strstr(g_out, "solution read from"));
    char *text = NULL;
    assert_int_equal(rr_file_read_all(csv, &text, &n, NULL), RR_OK);
    assert_true(!strncmp(text, "panel,region,pixels,relmse,relmse_se,mare,mare_se,bias,bias_se,ssim\nhybrid,(all pixels),576,0,", 92));
    free(text);
    /* The convergence plot: relMSE at 1 and 2 spp for each mode, by time. */
    char conv[256];
    snprintf(conv, sizeof conv, "%s", path_in("conv.svg"));
    const char *cv[] = {"compare", scene("cornell.json"), "--width", "24", "--spp", "2", "--modes", "hybrid,whitted",
                        "--spp-of", "whitted=4", "--reference", ref, "--radiosity-cache", cache, "--convergence", conv,
                        "-o", fig, NULL};
    assert_int_equal(run(cv), 0);
    assert_true(exists(conv));
    assert_non_null(strstr(g_out, "convergence against reference"));
    const char *l1 = strstr(g_out, "  hybrid            1 "), *l2 = strstr(g_out, "  whitted           4 ");
    assert_non_null(l1);
    assert_non_null(l2); /* --spp-of whitted=4: its series goes on to 4 spp */
    assert_null(strstr(g_out, "  hybrid            4 "));
    /* At 2 spp the hybrid is the reference itself: relMSE 0. */
    const char *l3 = strstr(g_out, "  hybrid            2 ");
    assert_non_null(l3);
    double secs = -1, rel2 = -1;
    assert_int_equal(sscanf(l3, " hybrid 2 %lf %lf", &secs, &rel2), 2);
    assert_true(rel2 == 0.0 && secs > 0.0);
    /* Bad references: another size, not an EXR, a missing file; a stats file
     * of another kind. Exit 2, nothing written. */
    const char *c[] = {"compare", scene("cornell.json"), "--width", "30", "--reference", ref, "-o", fig2, NULL};
    static const char *const wc[] = {"ref.exr", "24 x 24", "30 x 30", NULL};
    expect_usage(c, wc);
    FILE *f = fopen(junk, "wb");
    assert_non_null(f);
    fputs("not an EXR at all", f);
    fclose(f);
    const char *d[] = {"compare", scene("cornell.json"), "--reference", junk, "-o", fig2, NULL};
    static const char *const wd[] = {"--reference", "junk.exr", NULL};
    expect_usage(d, wd);
    const char *e[] = {"compare", scene("cornell.json"), "--reference", none, "-o", fig2, NULL};
    static const char *const we[] = {"--reference", "none.exr", NULL};
    expect_usage(e, we);
    const char *g[] = {"compare", scene("cornell.json"), "--stats", txt, "-o", fig2, NULL};
    static const char *const wg[] = {"--stats", ".json", ".csv", NULL};
    expect_usage(g, wg);
    const char *h[] = {"compare", scene("cornell.json"), "--reference", ref, "--stats", ref, "-o", fig2, NULL};
    static const char *const wh2[] = {"--stats", NULL};
    expect_usage(h, wh2);
    const char *so[] = {"compare", scene("cornell.json"), "--spp-of", "raytraced=4", "-o", fig2, NULL};
    static const char *const wso[] = {"--spp-of", "raytraced=4", "hybrid", NULL};
    expect_usage(so, wso);
    const char *k[] = {"compare", scene("cornell.json"), "--convergence", path_in("c.jpg"), "-o", fig2, NULL};
    static const char *const wk[] = {"--convergence", ".png", ".svg", NULL};
    expect_usage(k, wk);
    assert_false(exists(fig2));
}

static void unwritable_output(void **state)
{
    (void)state;
    /* A folder that cannot be made: its parent is a file. */
    FILE *f = fopen(path_in("afile"), "w");
    assert_non_null(f);
    fclose(f);
    const char *fig = path_in("afile/sub/fig.png");
    const char *a[] = {"compare", scene("cornell.json"), "--width", "11", "-o", fig, NULL};
    static const char *const want[] = {"afile", NULL};
    expect_usage(a, want);
    assert_false(exists(fig));
}

static int setup(void **state)
{
    (void)state;
    strcpy(g_dir, "/tmp/rr_cmp_XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
    (void)st;
    (void)flag;
    (void)ftw;
    return remove(path);
}

/* The temporary folder goes, figures and all: nothing to clean by hand. */
static int teardown(void **state)
{
    (void)state;
    return nftw(g_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(help),           cmocka_unit_test(cornell_modes), cmocka_unit_test(phong_layers),
        cmocka_unit_test(vector_outputs), cmocka_unit_test(bad_input),     cmocka_unit_test(unwritable_output),
        cmocka_unit_test(external_reference_and_stats),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
