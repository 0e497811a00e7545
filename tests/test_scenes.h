/* test_scenes.h - scene snippets shared by the test files (header-only). */
#ifndef TEST_SCENES_H
#define TEST_SCENES_H

#include <stdio.h>

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

#endif
