/* diagnose.c - warnings that name the cause of light that goes nowhere
 * (notes/energy.md, "Diagnostics"): an emitter inside a closed object whose
 * faces point outwards, and (from the light tracer's ledger) light that ends
 * on back faces. Printed by render, info, compare and energy. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "app.h"

#define MAX_EMITTER_POINTS 256
#define MAX_TESTS 50000000.0 /* triangle tests of the enclosure check */

/* Six times the signed volume of a closed triangle object: > 0 when its faces
 * point outwards. */
static double signed_volume6(const scene *s, const scene_object *o)
{
    double v = 0.0;
    for (size_t t = o->tri_first; t < o->tri_first + o->tri_count; t++) {
        rr_vec3 A = s->verts[s->tris[t].v[0]], B = s->verts[s->tris[t].v[1]], C = s->verts[s->tris[t].v[2]];
        v += rr_v3_dot(A, rr_v3_cross(B, C));
    }
    return v;
}

typedef struct emitter_point {
    rr_vec3 p;
    uint32_t object; /* UINT32_MAX for a scene light */
    const char *name;
} emitter_point;

/* Points that stand for the emitters: light positions, emissive triangles'
 * centroids, emissive spheres' centres (at most MAX_EMITTER_POINTS). */
static size_t emitter_points(const scene *s, emitter_point *e)
{
    size_t n = 0;
    for (size_t i = 0; i < s->nlights && n < MAX_EMITTER_POINTS; i++)
        if (s->lights[i].type == SCENE_LIGHT_POINT)
            e[n++] = (emitter_point){s->lights[i].position, UINT32_MAX, s->lights[i].name};
    for (size_t i = 0; i < s->nemissive && n < MAX_EMITTER_POINTS; i++) {
        const scene_tri *t = &s->tris[s->emissive_tris[i]];
        rr_vec3 c = rr_v3_scale(rr_v3_add(rr_v3_add(s->verts[t->v[0]], s->verts[t->v[1]]), s->verts[t->v[2]]), 1.0 / 3);
        e[n++] = (emitter_point){c, t->object, s->objects[t->object].name};
    }
    /* Spheres and solids that emit: the centre of their light sphere. */
    for (size_t o = 0; o < s->nobjects && n < MAX_EMITTER_POINTS; o++) {
        rt_prim_kind k = rt_prim_kind_of(s, (uint32_t)o);
        rr_vec3 c;
        double r;
        if (k != RT_PRIM_TRIANGLE && rt_prims[k].emission(s, (uint32_t)o) > 0 &&
            rt_prims[k].light_sphere(s, (uint32_t)o, rt_scene_scale(s), &c, &r))
            e[n++] = (emitter_point){c, (uint32_t)o, s->objects[o].name};
    }
    return n;
}

size_t app_diagnose_scene(const scene *s)
{
    emitter_point e[MAX_EMITTER_POINTS];
    size_t ne = emitter_points(s, e), warned = 0;
    rr_warn_sink w = app_warn_sink();
    int ambient = 0;
    for (size_t m = 0; m < s->nmaterials; m++)
        ambient |= s->materials[m].ambient > 0 && rr_rgb_max(s->materials[m].diffuse) > 0;
    ambient &= rr_rgb_max(s->settings.ambient) > 0; /* the lecture's a * A * rho, Whitted mode only */
    if (!rt_scene_emits(s) && !(rr_rgb_max(s->settings.background) > 0)) {
        rr_warn(&w,
                "%s: nothing emits light (no lights, no emissive material on any surface) and the background is "
                "black: every mode renders a black image%s. Add a light, or an \"emission\" to a material",
                s->path, ambient ? " except for the lecture's ambient term (--mode whitted)" : "");
        warned++;
    }
    for (size_t o = 0; o < s->nobjects && ne > 0; o++) {
        const scene_object *ob = &s->objects[o];
        int triangles = rt_prim_kind_of(s, (uint32_t)o) == RT_PRIM_TRIANGLE;
        if (!triangles || !scene_object_closed(s, (uint32_t)o) || (double)ob->tri_count * (double)ne > MAX_TESTS ||
            !(signed_volume6(s, ob) > 0.0))
            continue; /* only closed triangle objects can face the wrong way (solids face out by definition) */
        for (size_t k = 0; k < ne; k++) {
            if (e[k].object == o || !rt_object_encloses(s, (uint32_t)o, e[k].p))
                continue;
            rr_warn(&w,
                    "%s: '%s' is closed and its faces point outwards, but the emitter '%s' is inside it: seen from "
                    "inside it shows only back faces, which %s (the radiosity pass finds no form factors to it). If "
                    "it is a room, set \"flip\": true on '%s' so that its faces point inwards",
                    s->path, ob->name, e[k].name,
                    ob->cull_backfaces ? "are culled, so light passes out through its walls"
                                       : "are one-sided, so light ends on them",
                    ob->name);
            warned++;
            break;
        }
    }
    return warned;
}

size_t app_diagnose_ledger(const scene *s, const rt_particle_ledger *g, double share)
{
    double emitted = 0.0;
    for (size_t r = 0; r < g->nobjects + g->nlights; r++)
        emitted += rr_rgb_mean(g->row[r].c[RT_LEDGER_EMITTED]);
    size_t warned = 0;
    rr_warn_sink w = app_warn_sink();
    for (size_t o = 0; o < g->nobjects && emitted > 0.0; o++) {
        double back = rr_rgb_mean(g->row[o].c[RT_LEDGER_BACK]) / emitted;
        if (!(back > share))
            continue;
        rr_warn(&w,
                "%s: %.1f %% of the emitted power arrives at the back faces of '%s' and ends there (surfaces are "
                "one-sided in the radiosity pass): its front faces point away from the light. Set \"flip\": true "
                "on it if it is seen from the other side, or reverse its winding",
                s->path, 100.0 * back, s->objects[o].name);
        warned++;
    }
    return warned;
}

size_t app_diagnose_light(const scene *s, const rt_accel *a)
{
    if (!rt_scene_emits(s))
        return 0;
    rt_lights *L = NULL;
    if (rt_lights_build(s, a, 0, &L, NULL) != RR_OK)
        return 0;
    rt_particle_opts o = {0};
    o.particles = APP_DIAGNOSE_PARTICLES;
    o.batches = 4;
    o.seed = s->settings.seed;
    o.threads = s->settings.threads;
    rt_particle_ledger g;
    size_t n = 0;
    if (rt_lights_emitter_count(L) > 0 && rt_particles_trace(s, a, L, &o, &g, NULL) == RR_OK) {
        n = app_diagnose_ledger(s, &g, 0.01);
        rt_particle_ledger_free(&g);
    }
    rt_lights_destroy(L);
    return n;
}
