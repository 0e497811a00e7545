/* test_scene_util.h - helpers shared by the scene tests (header-only):
 * scenes from parts, warning capture, load-or-fail and expect-failure. */
#ifndef TEST_SCENE_UTIL_H
#define TEST_SCENE_UTIL_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "scene.h"

#define assert_near(a, b, tol) assert_true(fabs((double)(a) - (double)(b)) <= (tol))

static inline void assert_v3(rr_vec3 a, double x, double y, double z)
{
    if (!(fabs(a.x - x) <= 1e-9 && fabs(a.y - y) <= 1e-9 && fabs(a.z - z) <= 1e-9))
        fail_msg("got (%.12g, %.12g, %.12g), expected (%.12g, %.12g, %.12g)", a.x, a.y, a.z, x, y, z);
}

static inline void assert_rgb(rr_rgb a, double r, double g, double b)
{
    assert_v3(rr_v3(a.r, a.g, a.b), r, g, b);
}

/* A scene from parts; NULL parts take a small valid default, "" leaves an
 * optional part out. */
#define CAM "{\"type\":\"lecture\",\"E\":[0,0,5],\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.5,\"w\":2,\"h\":1}"
#define MATS                                                                                                 \
    "{\"white\":{},\"red\":{\"diffuse\":[0.8,0.1,0.1]},\"green\":{\"diffuse\":[0.1,0.8,0.1]},"              \
    "\"chrome\":{\"mirror\":0.9},\"lamp\":{\"emission\":[4,3,2]}}"
#define QUAD(mat) "{\"type\":\"quad\",\"material\":\"" mat "\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"
#define OBJS "[" QUAD("white") "}]"

static inline char *make_scene(const char *cam, const char *mats, const char *lights, const char *objs, const char *render)
{
    static char buf[16384];
    snprintf(buf, sizeof buf, "{\"format\":\"radray-scene/1\",\"camera\":%s,\"materials\":%s%s%s,\"objects\":%s%s%s}",
             cam ? cam : CAM, mats ? mats : MATS, lights && lights[0] ? ",\"lights\":" : "", lights ? lights : "",
             objs ? objs : OBJS, render && render[0] ? ",\"render\":" : "", render ? render : "");
    return buf;
}

/* Warnings land here. */
typedef struct warn_log {
    int count;
    char last[RR_ERROR_MSG_MAX];
} warn_log;

static inline void warn_fn(void *user, const char *msg)
{
    warn_log *w = user;
    w->count++;
    snprintf(w->last, sizeof w->last, "%s", msg);
}

static inline scene *load_ok(const char *json, const scene_load_opts *opts)
{
    scene *s = NULL;
    rr_error err = {0};
    rr_status st = scene_load_string(json, "t.json", RR_TEST_DATA "/scenes", opts, &s, &err);
    if (st != RR_OK)
        fail_msg("scene_load_string failed: %s\n%s", err.msg, json);
    assert_non_null(s);
    return s;
}

/* Loads json expecting failure with code and a message that contains want
 * (and starts with the file name). *out must stay untouched. */
static inline void expect_fail_opts(const char *json, const scene_load_opts *opts, const char *base_dir, rr_status code,
                             const char *want)
{
    scene *sentinel = (scene *)(uintptr_t)0x1234;
    scene *s = sentinel;
    rr_error err = {0};
    rr_status st = scene_load_string(json, "bad.json", base_dir, opts, &s, &err);
    if (st == RR_OK) {
        scene_destroy(s);
        fail_msg("expected failure containing \"%s\", but it loaded:\n%s", want, json);
    }
    assert_ptr_equal(s, sentinel);
    if (!strstr(err.msg, want))
        fail_msg("message \"%s\"\n  does not contain \"%s\"", err.msg, want);
    if (strncmp(err.msg, "bad.json", 8) != 0 && strncmp(err.msg, "--set '", 7) != 0)
        fail_msg("message \"%s\" does not start with the file name", err.msg);
    if (st != code)
        fail_msg("status %s, expected %s (message: %s)", rr_status_name(st), rr_status_name(code), err.msg);
}

static inline void expect_fail(const char *json, rr_status code, const char *want)
{
    expect_fail_opts(json, NULL, "", code, want);
}

#endif
