/* test_scenes.h - scene snippets shared by the test files (header-only). */
#ifndef TEST_SCENES_H
#define TEST_SCENES_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <math.h>

#include "rr_file.h"
#include "rr_rng.h"
#include "scene.h"

/* Appends to json (at len, capacity cap) six quads "{...}" forming the faces of
 * [-1,1]^3 with material mat, wound so that their normals point inwards (the
 * inside of a closed room: a furnace). Comma-separated, no brackets. Returns
 * the new length. */
static inline size_t test_inward_cube(char *json, size_t cap, size_t len, const char *mat)
{
    for (int axis = 0; axis < 3; axis++)
        for (int sgn = -1; sgn <= 1; sgn += 2) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            double q[4][3], cu[4] = {-1, 1, 1, -1}, cv[4] = {-1, -1, 1, 1};
            for (int k = 0; k < 4; k++) {
                q[k][axis] = sgn;
                q[k][u] = cu[k];
                q[k][v] = cv[k];
            }
            /* (u, v) counter-clockwise has normal +axis; inward is -sgn. */
            int order[4] = {0, sgn > 0 ? 3 : 1, 2, sgn > 0 ? 1 : 3};
            len += (size_t)snprintf(json + len, cap - len, "%s{\"type\":\"quad\",\"material\":\"%s\",\"vertices\":[",
                                    axis || sgn > 0 ? "," : "", mat);
            for (int k = 0; k < 4; k++)
                len += (size_t)snprintf(json + len, cap - len, "%s[%g,%g,%g]", k ? "," : "", q[order[k]][0],
                                        q[order[k]][1], q[order[k]][2]);
            len += (size_t)snprintf(json + len, cap - len, "]}");
        }
    return len;
}

/* Loads the first ```json block after the line `heading` of
 * notes/scene-format.md (mesh paths relative to tests/data/scenes), so that
 * the documentation's examples are tested. Fails the test when it does not
 * load. Include after cmocka.h. */
static inline scene *test_doc_scene(const char *heading, const char *name)
{
    char *doc = NULL;
    rr_error err;
    if (rr_file_read_all(RR_SOURCE_DIR "/notes/scene-format.md", &doc, NULL, &err) != RR_OK)
        fail_msg("%s", err.msg);
    const char *h = strstr(doc, heading);
    const char *start = h ? strstr(h, "```json\n") : NULL;
    const char *end = start ? strstr(start + 8, "```") : NULL;
    if (!end)
        fail_msg("notes/scene-format.md: no json block after '%s'", heading);
    start += 8;
    size_t len = (size_t)(end - start);
    char *json = malloc(len + 1);
    if (!json)
        fail_msg("out of memory");
    memcpy(json, start, len);
    json[len] = 0;
    scene *s = NULL;
    rr_status st = scene_load_string(json, name, RR_TEST_DATA "/scenes", NULL, &s, &err);
    free(json);
    free(doc);
    if (st != RR_OK)
        fail_msg("the example under '%s' does not load: %s", heading, err.msg);
    return s;
}

/* Loads scenes/<rel> of the source tree with the n --set style overrides
 * over; fails the test when it does not load. Include after cmocka.h. */
static inline scene *test_shipped_scene(const char *rel, const char *const *over, size_t n)
{
    char path[512];
    snprintf(path, sizeof path, "%s/scenes/%s", RR_SOURCE_DIR, rel);
    scene_load_opts lo;
    memset(&lo, 0, sizeof lo);
    lo.overrides = over;
    lo.noverrides = n;
    scene *s = NULL;
    rr_error err;
    if (scene_load(path, &lo, &s, &err) != RR_OK)
        fail_msg("%s", err.msg);
    return s;
}

/* Builds a scene JSON string with a random triangle soup and a few spheres. */
static inline char *random_scene(rr_rng *rng, int ntri, int nsph)
{
    size_t cap = (size_t)ntri * 3 * 80 + (size_t)nsph * 200 + 4096, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                            "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                            "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                            "{\"type\":\"triangles\",\"material\":\"a\",\"vertices\":[");
    for (int i = 0; i < 3 * ntri; i++)
        len += (size_t)snprintf(buf + len, cap - len, "%s[%.17g,%.17g,%.17g]", i ? "," : "",
                                2 * rr_rng_uniform(rng) - 1, 2 * rr_rng_uniform(rng) - 1,
                                2 * rr_rng_uniform(rng) - 1);
    len += (size_t)snprintf(buf + len, cap - len, "],\"indices\":[");
    for (int i = 0; i < ntri; i++)
        len += (size_t)snprintf(buf + len, cap - len, "%s[%d,%d,%d]", i ? "," : "", 3 * i, 3 * i + 1, 3 * i + 2);
    len += (size_t)snprintf(buf + len, cap - len, "]}");
    for (int i = 0; i < nsph; i++)
        len += (size_t)snprintf(buf + len, cap - len,
                                ",{\"type\":\"sphere\",\"material\":\"a\",\"center\":[%.17g,%.17g,%.17g],"
                                "\"radius\":%.17g}",
                                2 * rr_rng_uniform(rng) - 1, 2 * rr_rng_uniform(rng) - 1,
                                2 * rr_rng_uniform(rng) - 1, 0.05 + 0.2 * rr_rng_uniform(rng));
    snprintf(buf + len, cap - len, "]}");
    return buf;
}

static inline rr_vec3 random_point(rr_rng *rng, double r)
{
    return rr_v3(r * (2 * rr_rng_uniform(rng) - 1), r * (2 * rr_rng_uniform(rng) - 1),
                 r * (2 * rr_rng_uniform(rng) - 1));
}

/* A closed UV sphere of radius 1 as a "triangles" object: stacks x slices
 * quads, poles as fans; 2 * slices * (stacks - 1) triangles, outward facing. */
static inline char *uv_sphere_scene(int stacks, int slices, const char *cull)
{
    size_t nv = (size_t)(stacks - 1) * slices + 2, nt = 2 * (size_t)slices * (stacks - 1);
    size_t cap = nv * 64 + nt * 24 + 1024, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len,
                            "{\"format\":\"radray-scene/1\",\"camera\":{\"type\":\"lecture\",\"E\":[0,0,5],"
                            "\"O\":[0,0,4],\"U\":[0,1,0],\"s\":0.1,\"w\":2,\"h\":2},"
                            "\"materials\":{\"a\":{\"diffuse\":[0.5,0.5,0.5]}},\"objects\":["
                            "{\"type\":\"triangles\",\"material\":\"a\",\"cull\":%s,\"vertices\":[[0,0,1],[0,0,-1]",
                            cull);
    for (int i = 1; i < stacks; i++)
        for (int j = 0; j < slices; j++) {
            double th = RR_PI * i / stacks, ph = 2 * RR_PI * j / slices;
            len += (size_t)snprintf(buf + len, cap - len, ",[%.17g,%.17g,%.17g]", sin(th) * cos(ph),
                                    sin(th) * sin(ph), cos(th));
        }
    len += (size_t)snprintf(buf + len, cap - len, "],\"indices\":[");
    const char *sep = "";
#define RING(i, j) (2 + ((i) - 1) * slices + ((j) % slices))
    for (int j = 0; j < slices; j++) {
        len += (size_t)snprintf(buf + len, cap - len, "%s[0,%d,%d]", sep, RING(1, j), RING(1, j + 1));
        sep = ",";
        len += (size_t)snprintf(buf + len, cap - len, ",[1,%d,%d]", RING(stacks - 1, j + 1), RING(stacks - 1, j));
    }
    for (int i = 1; i < stacks - 1; i++)
        for (int j = 0; j < slices; j++)
            len += (size_t)snprintf(buf + len, cap - len, ",[%d,%d,%d],[%d,%d,%d]", RING(i, j), RING(i + 1, j),
                                    RING(i + 1, j + 1), RING(i, j), RING(i + 1, j + 1), RING(i, j + 1));
#undef RING
    snprintf(buf + len, cap - len, "]}]}");
    return buf;
}

static inline rr_vec3 random_unit(rr_rng *rng)
{
    double z = 2 * rr_rng_uniform(rng) - 1, ph = 2 * RR_PI * rr_rng_uniform(rng), r = sqrt(fmax(0.0, 1 - z * z));
    return rr_v3(r * cos(ph), r * sin(ph), z);
}

#endif
