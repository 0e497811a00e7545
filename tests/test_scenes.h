/* test_scenes.h - scene snippets shared by the test files (header-only). */
#ifndef TEST_SCENES_H
#define TEST_SCENES_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rr_file.h"
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

#endif
