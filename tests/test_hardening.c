/* test_hardening.c - the renderer under hostile conditions: interrupted
 * renders (the rt_render flag, and Ctrl-C on the command line writing
 * OUT.partial.exr), memory limits refused before any work, NaN/Inf kept out
 * of the output, and images that do not depend on the scene's scale. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "ig.h"
#include "img.h"
#include "rad.h"
#include "rr_core.h"
#include "rt.h"
#include "scene.h"
#include "test_cli_run.h"

static char g_dir[64];
static char g_out[8192]; /* captured stdout + stderr of the last run */


static void path_in(char *buf, size_t n, const char *name) { snprintf(buf, n, "%s/%s", g_dir, name); }

static int exists(const char *name)
{
    char path[256];
    struct stat st;
    path_in(path, sizeof path, name);
    return stat(path, &st) == 0;
}

/* Starts radray with args (NULL-terminated), output to log.txt. */
static pid_t start(const char *const *args)
{
    char log[128];
    path_in(log, sizeof log, "log.txt");
    return test_cli_start(log, args);
}

static int finish(pid_t pid)
{
    char log[128];
    path_in(log, sizeof log, "log.txt");
    return test_cli_finish(pid, log, g_out, sizeof g_out);
}

/* 1 once the process catches signal sig (its handler is installed): the
 * SigCgt mask of /proc/PID/status, bit sig - 1. */
static int catches(pid_t pid, int sig)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    int yes = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "SigCgt:", 7)) {
            unsigned long long mask = strtoull(line + 7, NULL, 16);
            yes = (mask >> (sig - 1)) & 1u;
        }
    fclose(f);
    return yes;
}

/* 1 when pid has ended (a zombie waiting for finish, or gone): /proc says so. */
static int exited(pid_t pid)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return 1;
    int gone = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "State:", 6))
            gone = strchr(line, 'Z') != NULL;
    fclose(f);
    return gone;
}

/* CPU time pid has used, in clock ticks (utime + stime of /proc/PID/stat); -1 when gone. */
static long cpu_ticks(pid_t pid)
{
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    const char *p = strrchr(buf, ')'); /* the command name may hold spaces */
    if (!p)
        return -1;
    long utime = 0, stime = 0;
    /* after ")": state ppid pgrp session tty tpgid flags minflt cminflt majflt cmajflt utime stime */
    if (sscanf(p + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %ld %ld", &utime, &stime) != 2)
        return -1;
    return utime + stime;
}

/* ---- a small scene at any scale ---- */

/* Floor, a box on it, an area light above, a point light; all lengths times
 * k, the point light's intensity times k^2 (so irradiance is unchanged). */
static scene *scaled_scene(double k, const char *mode_extra, const char *method, const char *ff)
{
    char json[4096];
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\","
             "\"camera\":{\"type\":\"lookat\",\"eye\":[%.17g,%.17g,%.17g],\"target\":[0,%.17g,0],\"up\":[0,1,0],"
             "\"fov\":45,\"width\":41,\"height\":31},"
             "\"materials\":{\"white\":{\"diffuse\":[0.7,0.7,0.7],\"ambient\":1,\"specular\":[0.2,0.2,0.2],\"k\":20},"
             "\"red\":{\"diffuse\":[0.7,0.2,0.1],\"ambient\":1},"
             "\"glow\":{\"diffuse\":[0.5,0.5,0.5],\"emission\":[5,5,5]}},"
             "\"lights\":[{\"type\":\"point\",\"position\":[%.17g,%.17g,%.17g],\"intensity\":[%.17g,%.17g,%.17g]}],"
             "\"objects\":["
             "{\"type\":\"quad\",\"material\":\"white\",\"vertices\":[[%.17g,0,%.17g],[%.17g,0,%.17g],[%.17g,0,%.17g],"
             "[%.17g,0,%.17g]]},"
             "{\"type\":\"box\",\"material\":\"red\",\"min\":[%.17g,0,%.17g],\"max\":[%.17g,%.17g,%.17g]},"
             "{\"type\":\"quad\",\"material\":\"glow\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
             "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}],"
             "\"render\":{\"ambient\":[0.05,0.05,0.05],\"threads\":2,\"light_samples\":4%s},"
             "\"radiosity\":{\"ff_samples\":64,\"method\":\"%s\",\"form_factors\":\"%s\"}}",
             0.0, 2.0 * k, 6.0 * k, 0.5 * k,                                  /* camera */
             -1.5 * k, 2.5 * k, 1.0 * k, 3.0 * k * k, 2.5 * k * k, 2.0 * k * k, /* point light */
             -3 * k, -3 * k, -3 * k, 3 * k, 3 * k, 3 * k, 3 * k, -3 * k,        /* floor, facing up */
             -0.6 * k, -0.6 * k, 0.6 * k, 1.2 * k, 0.6 * k,                     /* box */
             -0.5 * k, 3 * k, -0.5 * k, 0.5 * k, 3 * k, -0.5 * k, 0.5 * k, 3 * k, 0.5 * k, -0.5 * k, 3 * k,
             0.5 * k, /* light, facing down */
             mode_extra, method, ff);
    scene *s = NULL;
    rr_error err;
    rr_status st = scene_load_string(json, "scaled", "", NULL, &s, &err);
    if (st != RR_OK)
        fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(st, RR_OK);
    return s;
}

static void render_scene(scene *s, const char *mode, rt_film *film)
{
    rr_error err;
    rt_accel *a = NULL;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    assert_int_equal(rt_film_init(film, s->view.width, s->view.height, &err), RR_OK);
    s->settings.spp = 1;
    s->settings.threads = 2;
    s->settings.max_depth = 5;
    s->settings.seed = 0;
    ig_session ses;
    ig_session_init(&ses, s, a);
    assert_int_equal(ig_render(&ses, ig_find(mode), NULL, film, NULL, &err), RR_OK);
    ig_session_free(&ses);
    rt_accel_destroy(a);
}

/* ---- interrupt ---- */

static void interrupt_flag_preset(void **state)
{
    (void)state;
    scene *s = scaled_scene(1.0, ",\"spp\":64", "flat", "montecarlo");
    rr_error err;
    rt_accel *a = NULL;
    rt_film film;
    assert_int_equal(rt_accel_build(s, &a, &err), RR_OK);
    assert_int_equal(rt_film_init(&film, s->view.width, s->view.height, &err), RR_OK);
    volatile sig_atomic_t stop = 1;
    rt_render_opts o;
    memset(&o, 0, sizeof o);
    o.spp = 4096;
    o.light_samples = 16;
    o.indirect = RT_INDIRECT_SECONDARY;
    o.interrupt = &stop;
    /* Interrupted before the first pixel: every pixel stays black (below). */
    assert_int_equal(rt_render(s, a, &o, &film, &err), RR_ERR_INTERRUPTED);
    assert_non_null(strstr(err.msg, "interrupted"));
    for (int y = 0; y < film.beauty.height; y++)
        for (int x = 0; x < film.beauty.width; x++)
            assert_true(rr_image_at(&film.beauty, x, y)[0] == 0.0f);
    /* Not set: renders normally. */
    stop = 0;
    o.spp = 1;
    o.indirect = RT_INDIRECT_AMBIENT;
    assert_int_equal(rt_render(s, a, &o, &film, &err), RR_OK);
    rt_film_free(&film);
    rt_accel_destroy(a);
    scene_destroy(s);
}

/* 1 when g_dir holds a hidden temporary (".NAME.tmp-XXXXXX"). */
static int temporaries_left(void)
{
    char cmd[256];
    snprintf(cmd, sizeof cmd, "ls -a %s | grep -q '^\\..*\\.tmp-'", g_dir);
    return system(cmd) == 0;
}

/* SIGINT and SIGTERM stop a render the same way: the finished tiles in
 * OUT.partial.exr, nothing at OUT, no temporary left, exit 128 + signal.
 * Waits for the handlers (a condition), not for a time. At spp 2^24 (the
 * largest a scene may ask for) one pixel takes minutes: the render must stop
 * within a pixel, not after it. */
static void signal_writes_partial(int sig, const char *spp)
{
    char out[256], scene_path[512];
    path_in(out, sizeof out, "slow.partial.exr");
    remove(out);
    path_in(out, sizeof out, "slow.exr");
    remove(out);
    /* A closed box seen from inside: every pixel's samples hit walls (the
     * Cornell box's corner pixels see nothing and are quick at any spp). */
    snprintf(scene_path, sizeof scene_path, "%s/scenes/energy/furnace-05.json", RR_TEST_DATA);
    const char *args[] = {"render", scene_path, "--mode", "secondary", "--spp", spp, "--set", "render.light_samples=4096",
                          "-q", "-o", out, NULL};
    pid_t pid = start(args);
    assert_true(pid > 0);
    while ((!catches(pid, SIGINT) || !catches(pid, SIGTERM)) && !exited(pid))
        usleep(10000);
    /* Into the pixels: half a second of CPU after the handlers (the set-up
     * before the first pixel takes milliseconds). */
    long t0 = cpu_ticks(pid);
    while (!exited(pid) && cpu_ticks(pid) >= 0 && cpu_ticks(pid) < t0 + sysconf(_SC_CLK_TCK) / 2)
        usleep(10000);
    kill(pid, sig);
    /* It stops within 256 samples (milliseconds); a render that finished its
     * pixels first would take hours at these settings. 60 s is no timing
     * test, only a bound on a hang. */
    for (int i = 0; i < 6000 && !exited(pid); i++)
        usleep(10000);
    if (!exited(pid)) {
        kill(pid, SIGKILL);
        finish(pid);
        fail_msg("the render did not stop within 60 s of the signal");
    }
    int rc = finish(pid);
    assert_int_equal(rc, 128 + sig);
    assert_true(exists("slow.partial.exr"));
    assert_false(exists("slow.exr"));
    assert_false(exists("slow.png"));
    assert_false(temporaries_left());
    assert_non_null(strstr(g_out, "slow.partial.exr"));
    assert_non_null(strstr(g_out, "interrupted"));
}

static void cli_sigint_writes_partial(void **state)
{
    (void)state;
    signal_writes_partial(SIGINT, "65536");
}

static void cli_sigterm_writes_partial(void **state)
{
    (void)state;
    signal_writes_partial(SIGTERM, "16777216");
}

/* Ctrl-C during the radiosity pass stops its form factors (not the pass's
 * end, as before): the message says so, exit 130, the partial image black. */
static void cli_sigint_stops_radiosity_pass(void **state)
{
    (void)state;
    char out[256], scene_path[512];
    path_in(out, sizeof out, "pass.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *args[] = {"render", scene_path, "--patch-area", "100", "--width", "8", "-q", "-o", out, NULL};
    pid_t pid = start(args);
    while (!catches(pid, SIGINT) && !exited(pid))
        usleep(1000);
    kill(pid, SIGINT);
    assert_int_equal(finish(pid), 130);
    assert_non_null(strstr(g_out, "radiosity pass interrupted"));
    assert_true(exists("pass.partial.exr"));
    assert_false(exists("pass.exr"));
    /* compare the same way: exit 130 and no figure. */
    char fig[256];
    path_in(fig, sizeof fig, "pass-compare.png");
    const char *cargs[] = {"compare", scene_path, "--set", "radiosity.patch_area=100", "--width", "8", "-q", "-o", fig,
                           NULL};
    pid = start(cargs);
    while (!catches(pid, SIGINT) && !exited(pid))
        usleep(1000);
    kill(pid, SIGINT);
    assert_int_equal(finish(pid), 130);
    assert_false(exists("pass-compare.png"));
}

/* ---- outputs ---- */

/* An output that names an input or another output is refused before any
 * work, and a refused render creates no folder. */
static void cli_outputs_never_overwrite_inputs(void **state)
{
    (void)state;
    char scene_path[512], copy[256], before[65536];
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    path_in(copy, sizeof copy, "cornell.json");
    char *text = NULL;
    size_t n = 0;
    assert_int_equal(rr_file_read_all(scene_path, &text, &n, NULL), RR_OK);
    assert_true(n < sizeof before);
    memcpy(before, text, n);
    FILE *f = fopen(copy, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, n, f), n);
    fclose(f);
    free(text);
    char out[256], out2[256], png[256];
    path_in(out, sizeof out, "o.exr");
    path_in(png, sizeof png, "sub/../o.exr");
    const char *a[] = {"render", copy, "--width", "8", "--png", copy, "-o", out, NULL};
    assert_int_equal(finish(start(a)), 2);
    assert_non_null(strstr(g_out, "input"));
    const char *p[] = {"render", copy, "--width", "8", "--plot", copy, "--mode", "radiosity", "-o", out, NULL};
    assert_int_equal(finish(start(p)), 2);
    const char *c[] = {"render", copy, "--width", "8", "--radiosity-cache", out, "-o", out, NULL};
    assert_int_equal(finish(start(c)), 2);
    assert_int_equal(rr_file_read_all(copy, &text, &n, NULL), RR_OK);
    assert_memory_equal(text, before, n);
    free(text);
    const char *d[] = {"render", copy, "--width", "8", "-o", out, "--png", png, NULL};
    assert_int_equal(finish(start(d)), 2);
    assert_non_null(strstr(g_out, "the same file as -o"));
    assert_false(exists("o.exr"));
    assert_false(exists("sub"));
    /* Refused after the output check (memory): no folder made either. */
    path_in(out2, sizeof out2, "made/later/x.exr");
    const char *e[] = {"render", copy, "--width", "8", "--max-memory", "1K", "-o", out2, NULL};
    assert_int_equal(finish(start(e)), 2);
    assert_false(exists("made"));
    const char *g[] = {"render", copy, "--width", "8", "-q", "-o", out2, NULL};
    assert_int_equal(finish(start(g)), 0);
    assert_true(exists("made/later/x.exr") && exists("made/later/x.png"));
    assert_false(temporaries_left());
}

/* The disk fills between the two writes of one commit: the EXR's temporary
 * is written, the PNG's (on a tiny, nearly full tmpfs) cannot be. Neither of
 * the old pair may be replaced, and no temporary may be left. Needs root (to
 * mount the tmpfs); skipped otherwise. */
static void cli_disk_full_between_writes(void **state)
{
    (void)state;
    char mnt[256], png[320], exr[256], filler[320], scene_path[512];
    if (geteuid() != 0) {
        print_message("  skipped: mounting a tmpfs needs root\n");
        skip();
    }
    path_in(mnt, sizeof mnt, "full");
    assert_int_equal(mkdir(mnt, 0755), 0);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "mount -t tmpfs -o size=64k tmpfs %s 2>/dev/null", mnt);
    if (system(cmd) != 0) {
        rmdir(mnt);
        print_message("  skipped: cannot mount a tmpfs here\n");
        skip();
    }
    snprintf(png, sizeof png, "%s/o.png", mnt);
    path_in(exr, sizeof exr, "o.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    /* The old pair, small (8 px wide). */
    const char *a[] = {"render", scene_path, "--width", "8", "--mode", "whitted", "-q", "-o", exr, "--png", png,
                       NULL};
    assert_int_equal(finish(start(a)), 0);
    char *old_exr = NULL, *old_png = NULL, *now = NULL;
    size_t n_exr = 0, n_png = 0, n = 0;
    assert_int_equal(rr_file_read_all(exr, &old_exr, &n_exr, NULL), RR_OK);
    assert_int_equal(rr_file_read_all(png, &old_png, &n_png, NULL), RR_OK);
    /* Fill the tmpfs up to the last few hundred bytes. */
    snprintf(filler, sizeof filler, "%s/filler", mnt);
    snprintf(cmd, sizeof cmd, "dd if=/dev/zero of=%s bs=1k count=200 2>/dev/null; true", filler);
    assert_int_equal(system(cmd), 0);
    /* A bigger render: its PNG does not fit. */
    const char *b[] = {"render", scene_path, "--width", "64", "--mode", "whitted", "-q", "-o", exr, "--png", png,
                       NULL};
    int rc = finish(start(b));
    snprintf(cmd, sizeof cmd, "ls -a %s | grep -q '^\\..*\\.tmp-'", mnt);
    int temp_on_tmpfs = system(cmd) == 0;
    assert_int_equal(rr_file_read_all(exr, &now, &n, NULL), RR_OK);
    int exr_same = n == n_exr && memcmp(now, old_exr, n) == 0;
    free(now);
    assert_int_equal(rr_file_read_all(png, &now, &n, NULL), RR_OK);
    int png_same = n == n_png && memcmp(now, old_png, n) == 0;
    free(now);
    free(old_exr);
    free(old_png);
    snprintf(cmd, sizeof cmd, "umount %s", mnt);
    assert_int_equal(system(cmd), 0);
    rmdir(mnt);
    if (rc != 1 || !strstr(g_out, "o.png"))
        fail_msg("expected exit 1 naming the PNG; got %d: %s", rc, g_out);
    assert_true(exr_same);
    assert_true(png_same);
    assert_false(temp_on_tmpfs);
    assert_false(temporaries_left());
    remove(exr);
}

/* Two renders to one output at once (a dark and a bright version of one
 * scene): whichever commits last, its EXR and its PNG are the pair left
 * there, never the EXR of one beside the PNG of the other. */
static void cli_concurrent_renders_leave_one_pair(void **state)
{
    (void)state;
    char scene_path[512], out[256], png[256], la[128], lb[128];
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    path_in(out, sizeof out, "race.exr");
    path_in(png, sizeof png, "race.png");
    path_in(la, sizeof la, "race-a.txt");
    path_in(lb, sizeof lb, "race-b.txt");
    /* 300 pixels wide: writing takes long enough for the old code's window
     * (EXR renamed, PNG still being written) to be hit in 8 of 12 runs. */
    const char *dark[] = {"render", scene_path, "--mode", "whitted", "--width", "300", "--spp", "1", "--exposure", "-3",
                          "--set", "materials.light.emission=[1,1,1]", "-q", "-o", out, NULL};
    const char *bright[] = {"render", scene_path, "--mode", "whitted", "--width", "300", "--spp", "1", "--set",
                            "materials.light.emission=[40,40,40]", "-q", "-o", out, NULL};
    for (int run = 0; run < 12; run++) {
        pid_t a = test_cli_start(la, dark), b = test_cli_start(lb, bright);
        assert_int_equal(test_cli_finish(a, la, g_out, sizeof g_out), 0);
        assert_int_equal(test_cli_finish(b, lb, g_out, sizeof g_out), 0);
        rr_image im = {0};
        unsigned char *rgb = NULL;
        int w = 0, h = 0;
        assert_int_equal(img_read_exr(out, NULL, &im, NULL), RR_OK);
        assert_int_equal(img_read_png(png, &rgb, &w, &h, NULL), RR_OK);
        double e = 0.0, p = 0.0;
        for (int y = 0; y < im.height; y++)
            for (int x = 0; x < im.width; x++)
                e += rr_rgb_mean(rr_image_get(&im, x, y));
        for (int k = 0; k < 3 * w * h; k++)
            p += rgb[k];
        e /= (double)im.width * im.height;
        p /= 3.0 * w * h;
        /* Measured alone: EXR means 0.007 (dark) and 0.296 (bright), PNG
         * means 1.7 and 69.8 (of 255): the two must tell the same story. */
        int exr_bright = e > 0.05, png_bright = p > 30.0;
        if (exr_bright != png_bright)
            fail_msg("run %d: EXR mean %.3g (%s render) beside PNG mean %.1f (%s render)", run, e,
                     exr_bright ? "bright" : "dark", p, png_bright ? "bright" : "dark");
        rr_image_free(&im);
        free(rgb);
    }
}

/* ---- the radiosity cache ---- */

/* A cache is refused, naming the part of its key that differs, for every
 * input the solution depends on (the key audit; the flat method's here,
 * the hierarchical one's settings in test_hier); a damaged payload is
 * refused by its checksum; a FIFO (cache or scene) or a device is refused at
 * once instead of blocking. */
static void cli_cache_key_and_checksum(void **state)
{
    (void)state;
    char scene_path[512], cache[256], out[256];
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    path_in(cache, sizeof cache, "k.rcache");
    path_in(out, sizeof out, "k.exr");
    const char *a[] = {"render", scene_path, "--width", "8", "--patch-area", "8000", "--radiosity-cache", cache,
                       "--set", "radiosity.method=flat", "-q", "-o", out, NULL};
    assert_int_equal(finish(start(a)), 0);
    static const char *const flips[][2] = {
        {"objects[0].vertices=[[552.8,1,0],[0,0,0],[0,0,559.2],[549.6,0,559.2]]", "geometry"},
        {"objects[0].cull=true", "back-face culling"},
        {"materials.white.diffuse=0.5", "materials"},
        {"lights=[{\"type\":\"point\",\"position\":[278,500,278],\"intensity\":1000}]", "lights"},
        {"radiosity.patch_area=6000", "patch limits"},
        {"radiosity.ff_samples=256", "form-factor settings"},
        {"render.seed=9", "form-factor settings"},
        {"render.max_depth=3", "render.max_depth"},
        {"radiosity.solver=direct", "solver settings"},
    };
    for (size_t i = 0; i < sizeof flips / sizeof *flips; i++) {
        const char *b[] = {"render", scene_path, "--width", "8", "--patch-area", "8000", "--radiosity-cache", cache,
                           "--set", "radiosity.method=flat", "--set", flips[i][0], "-q", "-o", out, NULL};
        if (i == 4)
            b[5] = "6000"; /* --patch-area wins over the scene's value */
        int rc = finish(start(b));
        if (rc != 2 || !strstr(g_out, "made with different") || !strstr(g_out, flips[i][1]))
            fail_msg("--set %s: exit %d: %s", flips[i][0], rc, g_out);
    }
    /* Every payload value doubled (a damaged copy): the checksum refuses it. */
    char *data = NULL;
    size_t n = 0;
    assert_int_equal(rr_file_read_all(cache, &data, &n, NULL), RR_OK);
    size_t header = 8 + 4 + 4 + 8 * 8 + 8 + 8 + 8;
    assert_true(n > header && (n - header) % sizeof(double) == 0);
    for (size_t k = header; k + sizeof(double) <= n; k += sizeof(double)) {
        double v;
        memcpy(&v, data + k, sizeof v);
        v *= 2.0;
        memcpy(data + k, &v, sizeof v);
    }
    FILE *f = fopen(cache, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    fclose(f);
    free(data);
    assert_int_equal(finish(start(a)), 2);
    assert_non_null(strstr(g_out, "damaged"));
    /* FIFOs and devices: refused, not waited on. */
    char fifo[256];
    path_in(fifo, sizeof fifo, "fifo");
    assert_int_equal(mkfifo(fifo, 0600), 0);
    const char *c[] = {"render", scene_path, "--width", "8", "--radiosity-cache", fifo, "-q", "-o", out, NULL};
    assert_int_equal(finish(start(c)), 2);
    assert_non_null(strstr(g_out, "FIFO"));
    const char *d[] = {"render", fifo, "-q", "-o", out, NULL};
    assert_int_equal(finish(start(d)), 2);
    assert_non_null(strstr(g_out, "FIFO"));
    const char *e[] = {"render", "/dev/zero", "-q", "-o", out, NULL};
    assert_int_equal(finish(start(e)), 2);
    assert_non_null(strstr(g_out, "not a regular file"));
    remove(fifo);
}

/* ---- memory limits ---- */

static void cli_refuses_huge_resolution(void **state)
{
    (void)state;
    char out[256], scene_path[512];
    path_in(out, sizeof out, "huge.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *args[] = {"render", scene_path, "--width", "2000000", "-o", out, NULL};
    int rc = finish(start(args));
    assert_int_equal(rc, 2);
    assert_non_null(strstr(g_out, "2000000 x 2000000"));
    assert_non_null(strstr(g_out, "--max-memory"));
    assert_false(exists("huge.exr"));
    /* The same with a limit given, at load (the scene's own resolution). */
    const char *args2[] = {"render", scene_path, "--max-memory", "1M", "-o", out, NULL};
    assert_int_equal(finish(start(args2)), 2);
    assert_non_null(strstr(g_out, "over the limit of 1.0 MiB"));
    const char *args3[] = {"render", scene_path, "--max-memory", "lots", "-o", out, NULL};
    assert_int_equal(finish(start(args3)), 2);
    assert_non_null(strstr(g_out, "--max-memory"));
}

/* The flat method knows its patches before it runs, and refuses a patch
 * area that would pass --max-memory before any work (the hierarchical
 * method, the default, bounds itself while it refines:
 * cli_bounds_the_hierarchical_pass). */
static void cli_refuses_tiny_patches(void **state)
{
    (void)state;
    char out[256], scene_path[512];
    path_in(out, sizeof out, "tiny.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *args[] = {"render",       scene_path, "--patch-area", "0.5", "--max-memory", "4G", "--set",
                          "radiosity.method=flat", "-o", out, NULL};
    int rc = finish(start(args));
    assert_int_equal(rc, 2);
    assert_non_null(strstr(g_out, "radiosity: 4,080,596 patches need about"));
    assert_non_null(strstr(g_out, "over the limit of 4.0 GiB (--max-memory); raise --patch-area"));
    assert_false(exists("tiny.exr"));
    /* energy runs the same pass and checks the same way. */
    const char *args2[] = {"energy", scene_path, "--patch-area", "0.5", "--max-memory", "4G",
                           "--set", "radiosity.method=flat", NULL};
    assert_int_equal(finish(start(args2)), 2);
    assert_non_null(strstr(g_out, "raise --patch-area"));
    /* Whitted runs no radiosity pass: the same patch area is no obstacle. */
    const char *args3[] = {"render",       scene_path, "--patch-area", "0.5", "--max-memory", "4G", "--mode",
                           "whitted",      "--width",  "21",           "-q",  "-o",           out,  NULL};
    assert_int_equal(finish(start(args3)), 0);
    assert_true(exists("tiny.exr"));
}

/* The hierarchical pass cannot know its links before it runs: --max-memory
 * bounds it while it refines. Under what its coarsest refinement needs: exit
 * 2 naming the option, and no output. Under what the settings ask (Cornell's
 * pass holds 13.8 MiB): a coarser solution with a warning, and an image. */
static void cli_bounds_the_hierarchical_pass(void **state)
{
    (void)state;
    char out[256], scene_path[512];
    path_in(out, sizeof out, "hier.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/cornell.json", RR_SOURCE_DIR);
    const char *args[] = {"render", scene_path, "--set", "radiosity.method=hierarchical", "--max-memory", "1M",
                          "--width", "8", "--spp", "1", "-q", "-o", out, NULL};
    assert_int_equal(finish(start(args)), 2);
    assert_non_null(strstr(g_out, "even at its coarsest; raise --max-memory"));
    assert_false(exists("hier.exr"));
    const char *args2[] = {"render", scene_path, "--set", "radiosity.method=hierarchical", "--max-memory", "6M",
                           "--width", "8", "--spp", "1", "-q", "-o", out, NULL};
    assert_int_equal(finish(start(args2)), 0);
    assert_non_null(strstr(g_out, "what --max-memory leaves the pass"));
    assert_true(exists("hier.exr"));
}

/* The mutated copy of scenes/csg.json that ran past 20 s (issue #20): its
 * pebble scaled by -2.5 instead of 0.45, a mirrored pebble through the
 * walls, whose CSG leaf makes ~40-60k patches and 17 M form factors (69 s).
 * Long work, not a loop: the pass counts it, and a --max-memory below it
 * refuses the render before any work (the flat method's count; --set
 * replaces the whole transform). */
static void cli_bounds_the_csg_mutant(void **state)
{
    (void)state;
    char out[256], scene_path[512];
    path_in(out, sizeof out, "mutant.exr");
    snprintf(scene_path, sizeof scene_path, "%s/scenes/csg.json", RR_SOURCE_DIR);
    char *text = NULL;
    size_t n = 0;
    assert_int_equal(rr_file_read_all(scene_path, &text, &n, NULL), RR_OK);
    char *at = strstr(text, "{\"scale\": 0.45}");
    assert_non_null(at);
    memcpy(at, "{\"scale\": -2.5}", strlen("{\"scale\": -2.5}"));
    char copy[256];
    path_in(copy, sizeof copy, "meshes");
    snprintf(scene_path, sizeof scene_path, "ln -sfn %s/scenes/meshes %s", RR_SOURCE_DIR, copy);
    assert_int_equal(system(scene_path), 0); /* the scene's mesh paths are relative to it */
    path_in(copy, sizeof copy, "mutant.json");
    FILE *f = fopen(copy, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, n, f), n);
    fclose(f);
    free(text);
    const char *args[] = {"render", copy, "--width", "24", "--spp", "1", "--max-memory", "300M",
                          "--set", "radiosity.method=flat", "-o", out, NULL};
    assert_int_equal(finish(start(args)), 2);
    assert_non_null(strstr(g_out, "patches need about"));
    assert_non_null(strstr(g_out, "form factors"));
    assert_false(exists("mutant.exr"));
}

/* ---- NaN / Inf ---- */

static void scrub_nonfinite(void **state)
{
    (void)state;
    rt_film f;
    rr_error err;
    assert_int_equal(rt_film_init(&f, 5, 4, &err), RR_OK);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 5; x++)
            rr_image_set(&f.beauty, x, y, rr_rgb_make(1, 2, 3));
    rr_image_at(&f.beauty, 1, 2)[1] = NAN;
    rr_image_at(&f.layer[RT_LAYER_DIFFUSE], 3, 0)[2] = INFINITY;
    rr_image_at(&f.beauty, 3, 0)[2] = INFINITY;
    rr_image_at(&f.layer[RT_LAYER_INDIRECT], 4, 3)[0] = -INFINITY;
    int xs[2] = {-1, -1}, ys[2] = {-1, -1};
    assert_int_equal(rt_film_scrub_nonfinite(&f, 2, xs, ys), 3);
    assert_int_equal(xs[0], 3); /* row-major order */
    assert_int_equal(ys[0], 0);
    assert_int_equal(xs[1], 1);
    assert_int_equal(ys[1], 2);
    for (int c = 0; c < 3; c++) {
        assert_true(rr_image_at(&f.beauty, 1, 2)[c] == 0.0f);
        assert_true(rr_image_at(&f.beauty, 3, 0)[c] == 0.0f);
        assert_true(rr_image_at(&f.layer[RT_LAYER_DIFFUSE], 3, 0)[c] == 0.0f);
        assert_true(rr_image_at(&f.layer[RT_LAYER_INDIRECT], 4, 3)[c] == 0.0f);
    }
    assert_true(rr_image_at(&f.beauty, 0, 0)[0] == 1.0f); /* the rest untouched */
    assert_true(rr_image_at(&f.beauty, 4, 3)[2] == 3.0f);
    assert_int_equal(rt_film_scrub_nonfinite(&f, 0, NULL, NULL), 0); /* clean now */
    rt_film_free(&f);
}

/* ---- scale invariance ---- */

static void compare_scales(const char *mode, const char *method, const char *ff, double tol)
{
    static const double scales[] = {1e-3, 1e4};
    rt_film ref;
    scene *s = scaled_scene(1.0, "", method, ff);
    render_scene(s, mode, &ref);
    scene_destroy(s);
    double mean = 0;
    int w = ref.beauty.width, h = ref.beauty.height;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            mean += rr_rgb_mean(rr_image_get(&ref.beauty, x, y));
    mean /= (double)w * h;
    assert_true(mean > 1e-3);
    for (int i = 0; i < 2; i++) {
        rt_film f;
        s = scaled_scene(scales[i], "", method, ff);
        render_scene(s, mode, &f);
        scene_destroy(s);
        double worst = 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                for (int c = 0; c < 3; c++)
                    worst = fmax(worst, fabs((double)rr_image_at(&f.beauty, x, y)[c] -
                                             (double)rr_image_at(&ref.beauty, x, y)[c]));
        if (worst > tol * mean)
            fprintf(stderr, "scale %g, %s (%s, %s): max |diff| %g, mean %g\n", scales[i], mode, method, ff, worst, mean);
        assert_true(worst <= tol * mean);
        rt_film_free(&f);
    }
    rt_film_free(&ref);
}

static void scale_invariance_whitted(void **state)
{
    (void)state;
    compare_scales("whitted", "flat", "quadrature", 1e-4);
}

/* Quadrature form factors are continuous in the geometry: as tight as
 * Whitted. Monte Carlo ones count ray hits, and a ray grazing a patch edge can
 * land on the other patch once the coordinates round differently (seen: one
 * such flip moves a few pixels by 0.6% of the mean), hence the looser bound;
 * scales by powers of two, which round nothing, give identical images. The
 * hierarchical method's oracle refines a link or not by a threshold, and
 * at 1e-3 (coordinates no longer exact in binary, as they are at 1e4) 131
 * of its 102,839 links refine differently over the same leaves: the worst
 * pixel moves by 2.0 % of the mean (the image's relative RMS 3.6e-4); at
 * 1e4, 2.5e-5. */
static void scale_invariance_hybrid(void **state)
{
    (void)state;
    compare_scales("hybrid", "flat", "quadrature", 1e-4);
    compare_scales("hybrid", "flat", "montecarlo", 2e-2);
    compare_scales("hybrid", "hierarchical", "montecarlo", 3e-2);
}

static int setup(void **state)
{
    (void)state;
    snprintf(g_dir, sizeof g_dir, "/tmp/radray-hardening-XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

/* Removes the test folder with everything the tests left in it (a
 * folder of our own under /tmp, made by mkdtemp). */
static int teardown(void **state)
{
    (void)state;
    char cmd[128];
    if (strncmp(g_dir, "/tmp/radray-hardening-", 22) != 0)
        return 0;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(interrupt_flag_preset),       cmocka_unit_test(cli_sigint_writes_partial),
        cmocka_unit_test(cli_sigterm_writes_partial),  cmocka_unit_test(cli_sigint_stops_radiosity_pass),
        cmocka_unit_test(cli_outputs_never_overwrite_inputs), cmocka_unit_test(cli_disk_full_between_writes),
        cmocka_unit_test(cli_cache_key_and_checksum), cmocka_unit_test(cli_concurrent_renders_leave_one_pair),
        cmocka_unit_test(cli_refuses_huge_resolution), cmocka_unit_test(cli_refuses_tiny_patches),
        cmocka_unit_test(cli_bounds_the_hierarchical_pass),
        cmocka_unit_test(cli_bounds_the_csg_mutant),
        cmocka_unit_test(scrub_nonfinite),             cmocka_unit_test(scale_invariance_whitted),
        cmocka_unit_test(scale_invariance_hybrid),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
