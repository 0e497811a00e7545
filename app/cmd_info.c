/* cmd_info.c - `radray info SCENE`: what a scene holds. */
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "app.h"
#include "scene.h"

static const char info_usage[] =
    "usage: radray info SCENE [--set KEY=VALUE]...\n"
    "\n"
    "Loads SCENE, validates it, and prints its camera, materials, lights, objects\n"
    "(triangle counts, back-face culling, watertightness of each mesh) and bounds.\n"
    "\n"
    "options:\n"
    "      --set KEY=VALUE  override a scene value by its JSON path (repeatable)\n"
    "  -h, --help           show this help\n"
    "\n"
    "Exit codes: 0 ok, 2 usage error or bad input.\n";

static const char *kind_name(scene_object_kind k)
{
    switch (k) {
    case SCENE_OBJ_MESH: return "mesh";
    case SCENE_OBJ_TRIANGLES: return "triangles";
    case SCENE_OBJ_QUAD: return "quad";
    case SCENE_OBJ_BOX: return "box";
    case SCENE_OBJ_SPHERE: return "sphere";
    case SCENE_OBJ_CSG: return "solid";
    }
    return "?";
}

/* "closed (csg difference, 3 leaves: 1 sphere, 2 box)" or "closed (quadric cylinder)". */
static void print_solid(const scene *s, const scene_object *o)
{
    static const char *const ops[] = {"leaf", "union", "intersection", "difference"};
    static const char *const solids[] = {"sphere", "quadric", "box", "mesh"};
    static const char *const shapes[] = {"general", "ellipsoid", "cylinder", "cone", "paraboloid", "hyperboloid"};
    const scene_csg_node *root = &s->csg[o->csg_root];
    if (root->op == SCENE_CSG_LEAF) {
        printf("closed (%s", solids[root->solid & 3]);
        if (root->solid == SCENE_SOLID_QUADRIC && (unsigned)root->shape < 6)
            printf(" %s", shapes[root->shape]);
        printf(")");
        return;
    }
    /* The object's nodes are contiguous and end at its root. */
    size_t nleaves = 0, count[4] = {0, 0, 0, 0};
    for (size_t i = 0; i <= o->csg_root; i++)
        if (s->csg[i].object == (uint32_t)(o - s->objects) && s->csg[i].op == SCENE_CSG_LEAF) {
            nleaves++;
            count[s->csg[i].solid & 3]++;
        }
    printf("closed (csg %s, %zu leaves:", ops[root->op & 3], nleaves);
    const char *sep = " ";
    for (int k = 0; k < 4; k++)
        if (count[k]) {
            printf("%s%zu %s", sep, count[k], solids[k]);
            sep = ", ";
        }
    printf(")");
}

static void print_topology(const scene *s, const scene_object *o)
{
    const mesh_report *r = &o->report;
    if (o->kind == SCENE_OBJ_SPHERE) {
        printf("closed (analytic)");
        return;
    }
    if (o->kind == SCENE_OBJ_CSG) {
        print_solid(s, o);
        return;
    }
    if (r->watertight)
        printf("watertight");
    else
        printf("open: %zu boundary edge(s), %zu non-manifold edge(s)", r->boundary_edges, r->nonmanifold_edges);
    if (!r->consistently_oriented)
        printf(", %zu misoriented edge(s)", r->misoriented_edges);
    if (o->dropped_degenerate)
        printf(", %zu zero-area triangle(s) dropped", o->dropped_degenerate);
}


/* The "model" objects: what each file brought, and every material whose
 * mapping approximated or dropped something, grouped by what. */
static void print_models(const scene *s)
{
    if (s->nmodels == 0)
        return;
    printf("models     %zu\n", s->nmodels);
    for (size_t i = 0; i < s->nmodels; i++) {
        const scene_model *md = &s->models[i];
        printf("  %-16s %s, %zu object(s), %zu triangle(s), %zu material(s), %zu light(s)  [%s]\n", md->name,
               md->format, md->object_count, md->triangles, md->material_count, md->light_count, md->source);
        if (md->dropped_prims || md->dropped_lights || md->dropped_cameras)
            printf("    dropped: %zu point/line primitive(s), %zu spot light(s), %zu camera(s) (not rendered)\n",
                   md->dropped_prims, md->dropped_lights, md->dropped_cameras);
        for (unsigned b = 0; b < IMP_NOTE_BITS; b++) {
            int any = 0;
            for (size_t m = md->material_first; m < md->material_first + md->material_count; m++) {
                const scene_material *x = &s->materials[m];
                if (x->overridden || !(x->notes & (1u << b)))
                    continue;
                printf(any ? ", %s" : "    %s: %s", any ? x->name : imp_note_text(1u << b), x->name);
                any = 1;
            }
            if (any)
                printf("\n");
        }
        int any = 0;
        for (size_t m = md->material_first; m < md->material_first + md->material_count; m++)
            if (s->materials[m].overridden) {
                printf(any ? ", %s" : "    replaced by the scene's \"materials\": %s", s->materials[m].name);
                any = 1;
            }
        if (any)
            printf("\n");
    }
}

int app_cmd_info(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"set", required_argument, NULL, 's'}, {"help", no_argument, NULL, 'h'}, {NULL, 0, NULL, 0}};
    const char *sets[256];
    size_t nsets = 0;
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":h", longopts, NULL)) != -1) {
        if (c == 'h') {
            fputs(info_usage, stdout);
            return APP_EXIT_OK;
        } else if (c == 's' && nsets < 256) {
            sets[nsets++] = optarg;
        } else if (c == ':') {
            app_error("option '%s' needs a value (try 'radray info --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        } else {
            app_error("unknown option '%s' (try 'radray info --help')", argv[optind - 1]);
            return APP_EXIT_USAGE;
        }
    }
    if (optind != argc - 1) {
        app_error("info: expected one SCENE (try 'radray info --help')");
        return APP_EXIT_USAGE;
    }
    rr_error err;
    scene_load_opts lo = {0};
    lo.overrides = sets;
    lo.noverrides = nsets;
    lo.warn = app_warn_sink();
    scene *s = NULL;
    if (app_scene_load(argv[optind], &lo, &s, &err) != RR_OK) {
        app_error("%s", err.msg);
        return APP_EXIT_USAGE;
    }
    app_diagnose_scene(s);
    rt_accel *a = NULL;
    if (rt_accel_build(s, &a, NULL) == RR_OK) /* for the light check only: info needs no BVH otherwise */
        app_diagnose_light(s, a);
    rt_accel_destroy(a);
    const rr_view *v = &s->view;
    printf("scene      %s (%s)\n", s->name, s->path);
    const scene_camera *cam = &s->camera;
    if (cam->lookat) /* the keys of the file (and of --set camera.eye=...) first */
        printf("camera     lookat: eye (%g, %g, %g)  target (%g, %g, %g)  up (%g, %g, %g)  fov %g\n"
               "           as the lecture's view: E (%g, %g, %g)  O (%g, %g, %g)  U (%g, %g, %g)  s %g\n",
               cam->eye.x, cam->eye.y, cam->eye.z, cam->target.x, cam->target.y, cam->target.z, cam->up.x, cam->up.y,
               cam->up.z, cam->fov, v->E.x, v->E.y, v->E.z, v->O.x, v->O.y, v->O.z, v->U.x, v->U.y, v->U.z, v->s);
    else
        printf("camera     lecture: E (%g, %g, %g)  O (%g, %g, %g)  U (%g, %g, %g)  s %g\n", v->E.x, v->E.y, v->E.z,
               v->O.x, v->O.y, v->O.z, v->U.x, v->U.y, v->U.z, v->s);
    printf("           I (%.4f, %.4f, %.4f)  J (%.4f, %.4f, %.4f)  %d x %d pixels\n", v->I.x, v->I.y, v->I.z, v->J.x,
           v->J.y, v->J.z, v->width, v->height);
    printf("render     %d spp, seed %llu, max depth %d, %d light sample(s)\n", s->settings.spp,
           (unsigned long long)s->settings.seed, s->settings.max_depth, s->settings.light_samples);
    printf("materials  %zu\n", s->nmaterials);
    for (size_t i = 0; i < s->nmaterials; i++) {
        const scene_material *m = &s->materials[i];
        printf("  %-16s diffuse (%.3f, %.3f, %.3f)", m->name, m->diffuse.r, m->diffuse.g, m->diffuse.b);
        if (rr_rgb_max(m->emission) > 0)
            printf("  emission (%g, %g, %g)", m->emission.r, m->emission.g, m->emission.b);
        if (rr_rgb_max(m->mirror) > 0)
            printf("  mirror (%g, %g, %g)", m->mirror.r, m->mirror.g, m->mirror.b);
        if (rr_rgb_max(m->specular) > 0)
            printf("  specular (%g, %g, %g) k %g", m->specular.r, m->specular.g, m->specular.b, m->k);
        printf("\n");
    }
    print_models(s);
    size_t ndir = 0, npoint = 0;
    for (size_t i = 0; i < s->nlights; i++)
        *(s->lights[i].type == SCENE_LIGHT_DIRECTIONAL ? &ndir : &npoint) += 1;
    printf("lights     %zu directional, %zu point, %zu emissive triangle(s) (area lights)\n", ndir, npoint,
           s->nemissive);
    printf("objects    %zu (%zu triangles, %zu vertices)\n", s->nobjects, s->ntris, s->nverts);
    for (size_t i = 0; i < s->nobjects; i++) {
        const scene_object *o = &s->objects[i];
        printf("  %-16s %-9s %7zu tri  material %-10s cull %-3s  ", o->name, kind_name(o->kind), o->tri_count,
               s->materials[o->material].name, o->cull_backfaces ? "yes" : "no");
        print_topology(s, o);
        if (o->source[0] && o->model == SCENE_NONE) /* a model's file is in "models" */
            printf("  [%s]", o->source);
        printf("\n");
    }
    printf("bounds     (%g, %g, %g) - (%g, %g, %g)\n", s->bbox_min.x, s->bbox_min.y, s->bbox_min.z, s->bbox_max.x,
           s->bbox_max.y, s->bbox_max.z);
    scene_destroy(s);
    return APP_EXIT_OK;
}
