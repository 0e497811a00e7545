/* scene_path.c - "camera_path": a walkthrough's key frames (eye, target,
 * fov), and the view of any frame between them.
 *
 * Eye and target follow a cubic Hermite spline through the keys whose
 * tangents are the Catmull-Rom ones scaled to the frame spacing (smooth at
 * every key, passing through each, no overshoot beyond what the keys
 * imply); fov is linear between keys. Frames before the first key or after
 * the last hold that key. The up vector is the camera's (notes/scene-format.md).
 */
#include <math.h>
#include <string.h>

#include "scene_internal.h"

static const char *const k_path[] = {"frames", "keys", "up", NULL};
static const char *const k_key[] = {"frame", "eye", "target", "fov", NULL};

static rr_status parse_key(const sp_ctx *c, const cJSON *v, const char *path, int frames, scene_key *k)
{
    rr_status st = sp_check_object(c, v, path, k_key);
    double f = 0;
    if (st != RR_OK || (st = sp_int(c, v, path, "frame", SP_REQUIRED, 1, frames, &f)) != RR_OK ||
        (st = sp_vec3(c, v, path, "eye", SP_REQUIRED, &k->eye)) != RR_OK ||
        (st = sp_vec3(c, v, path, "target", SP_REQUIRED, &k->target)) != RR_OK ||
        (st = sp_number_range(c, v, path, "fov", SP_REQUIRED, 1e-6, 179.999, &k->fov)) != RR_OK)
        return st;
    k->frame = f;
    if (!(rr_v3_len(rr_v3_sub(k->target, k->eye)) > 0))
        return sp_fail(c, RR_ERR_INVALID, path, "eye and target are the same point");
    return RR_OK;
}

rr_status sp_parse_camera_path(const sp_ctx *c, const cJSON *root, scene *s)
{
    const cJSON *p = sp_get(root, "camera_path");
    if (!p)
        return RR_OK;
    rr_status st = sp_check_object(c, p, "camera_path", k_path);
    double frames = 0;
    if (st != RR_OK || (st = sp_int(c, p, "camera_path", "frames", SP_REQUIRED, 1, 999999, &frames)) != RR_OK)
        return st;
    s->path_up = s->camera.lookat ? s->camera.up : s->view.U;
    if ((st = sp_vec3(c, p, "camera_path", "up", SP_OPTIONAL, &s->path_up)) != RR_OK)
        return st;
    const cJSON *keys = sp_get(p, "keys");
    if (!keys)
        return sp_missing(c, "camera_path", "keys", "an array of key frames");
    if ((st = sp_array(c, keys, "camera_path.keys", 0, "an array of key frames")) != RR_OK)
        return st;
    size_t n = (size_t)cJSON_GetArraySize(keys);
    if (!(s->path_keys = calloc(n, sizeof *s->path_keys)))
        return sp_fail(c, RR_ERR_NOMEM, "camera_path", "out of memory");
    size_t i = 0;
    for (const cJSON *it = keys->child; it; it = it->next, i++) {
        char kp[SP_PATH_MAX];
        sp_idx(kp, "camera_path.keys", i);
        if ((st = parse_key(c, it, kp, (int)frames, &s->path_keys[i])) != RR_OK)
            return st;
        if (i > 0 && !(s->path_keys[i].frame > s->path_keys[i - 1].frame))
            return sp_fail(c, RR_ERR_INVALID, kp, "frame %g does not come after the key before it (%g)",
                           s->path_keys[i].frame, s->path_keys[i - 1].frame);
        s->npath = i + 1;
    }
    s->path_frames = (int)frames;
    return RR_OK;
}

/* Hermite through keys: value of component get(k) at frame f. */
static rr_vec3 spline(const scene_key *k, size_t n, double f, int target)
{
#define P(i) (target ? k[i].target : k[i].eye)
    if (n == 1 || f <= k[0].frame)
        return P(0);
    if (f >= k[n - 1].frame)
        return P(n - 1);
    size_t i = 0;
    while (f > k[i + 1].frame)
        i++;
    double h = k[i + 1].frame - k[i].frame, t = (f - k[i].frame) / h;
    /* Catmull-Rom tangents per frame (one-sided at the ends), times h */
    size_t a = i > 0 ? i - 1 : i, b = i + 2 < n ? i + 2 : i + 1;
    rr_vec3 m0 = rr_v3_scale(rr_v3_sub(P(i + 1), P(a)), h / (k[i + 1].frame - k[a].frame));
    rr_vec3 m1 = rr_v3_scale(rr_v3_sub(P(b), P(i)), h / (k[b].frame - k[i].frame));
    double t2 = t * t, t3 = t2 * t;
    double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + t, h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    return rr_v3_add(rr_v3_add(rr_v3_scale(P(i), h00), rr_v3_scale(m0, h10)),
                     rr_v3_add(rr_v3_scale(P(i + 1), h01), rr_v3_scale(m1, h11)));
#undef P
}

rr_status scene_path_view(const scene *s, int frame, rr_view *out, rr_error *err)
{
    if (s->npath == 0)
        return rr_error_set(err, RR_ERR_INVALID, "%s: the scene has no camera_path", s->path);
    if (frame < 1 || frame > s->path_frames)
        return rr_error_set(err, RR_ERR_INVALID, "%s: frame %d is outside camera_path's 1..%d", s->path, frame,
                            s->path_frames);
    const scene_key *k = s->path_keys;
    size_t n = s->npath;
    double f = frame, fov = k[0].fov;
    if (f >= k[n - 1].frame) {
        fov = k[n - 1].fov;
    } else if (f > k[0].frame) {
        size_t i = 0;
        while (f > k[i + 1].frame)
            i++;
        double t = (f - k[i].frame) / (k[i + 1].frame - k[i].frame);
        fov = k[i].fov + t * (k[i + 1].fov - k[i].fov);
    }
    rr_status st = rr_view_lookat(spline(k, n, f, 0), spline(k, n, f, 1), s->path_up, fov, s->view.width,
                                  s->view.height, out, err);
    if (st != RR_OK)
        return rr_error_prefix(err, "%s: camera_path, frame %d", s->path, frame);
    return RR_OK;
}
