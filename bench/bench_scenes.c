/* bench_scenes.c - the procedural benchmark scenes and ray sets shared by
 * radray-bench and radray-bench-embree (see bench_scenes.h, bench/README.md).
 * Moved unchanged from bench_rays.c. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench_scenes.h"

const char *bench_prog = "radray-bench";

/* ---------------------------------------------------------------- helpers */

double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of n values (sorts them in place). */
double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void *xmalloc(size_t n)
{
    void *p = malloc(n ? n : 1);
    if (!p) {
        fprintf(stderr, "%s: out of memory (%zu bytes)\n", bench_prog, n);
        exit(1);
    }
    return p;
}

/* ---------------------------------------------------------- geometry build */

/* A growing triangle soup: float positions (what the PLY stores), int indices. */

static uint32_t soup_vert(soup *m, double x, double y, double z)
{
    if (m->nverts == m->vcap) {
        m->vcap = m->vcap ? 2 * m->vcap : 4096;
        float *p = realloc(m->pos, 3 * m->vcap * sizeof *p);
        if (!p) {
            fprintf(stderr, "%s: out of memory\n", bench_prog);
            exit(1);
        }
        m->pos = p;
    }
    m->pos[3 * m->nverts + 0] = (float)x;
    m->pos[3 * m->nverts + 1] = (float)y;
    m->pos[3 * m->nverts + 2] = (float)z;
    return (uint32_t)m->nverts++;
}

/* Counter-clockwise seen from the front. */
static void soup_tri(soup *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (m->ntris == m->tcap) {
        m->tcap = m->tcap ? 2 * m->tcap : 4096;
        int32_t *p = realloc(m->idx, 3 * m->tcap * sizeof *p);
        if (!p) {
            fprintf(stderr, "%s: out of memory\n", bench_prog);
            exit(1);
        }
        m->idx = p;
    }
    m->idx[3 * m->ntris + 0] = (int32_t)a;
    m->idx[3 * m->ntris + 1] = (int32_t)b;
    m->idx[3 * m->ntris + 2] = (int32_t)c;
    m->ntris++;
}

void soup_free(soup *m)
{
    free(m->pos);
    free(m->idx);
}

/* Sinusoidal displacement of a unit sphere: radius factor at polar angle th
 * (0 at +y) and azimuth ph. The polar frequencies are integers, so the factor
 * is exactly 1 at both poles and the surface closes; the azimuthal ones are
 * integers, so it is periodic in ph. */
typedef struct displace {
    double amp[2];
    int kth[2], kph[2];
    double phase[2];
} displace;

static double displace_factor(const displace *d, double th, double ph)
{
    double f = 1.0;
    for (int i = 0; i < 2; i++)
        f += d->amp[i] * sin(d->kth[i] * th) * cos(d->kph[i] * ph + d->phase[i]);
    return f;
}

/* A displaced UV sphere: nu segments around, nv bands from pole to pole;
 * 2 + nu*(nv-1) vertices and 2*nu*(nv-1) triangles, outward-facing, closed. */
static void add_uv_sphere(soup *m, rr_vec3 c, double radius, const displace *d, int nu, int nv)
{
    uint32_t north = soup_vert(m, c.x, c.y + radius, c.z);
    uint32_t first = (uint32_t)m->nverts;
    for (int i = 1; i < nv; i++) {
        double th = RR_PI * i / nv;
        for (int j = 0; j < nu; j++) {
            double ph = 2.0 * RR_PI * j / nu;
            double r = radius * displace_factor(d, th, ph);
            soup_vert(m, c.x + r * sin(th) * cos(ph), c.y + r * cos(th), c.z + r * sin(th) * sin(ph));
        }
    }
    uint32_t south = soup_vert(m, c.x, c.y - radius, c.z);
#define RING(i, j) (first + (uint32_t)((i) - 1) * (uint32_t)nu + (uint32_t)((j) % nu))
    for (int j = 0; j < nu; j++)
        soup_tri(m, north, RING(1, j + 1), RING(1, j));
    for (int i = 1; i < nv - 1; i++)
        for (int j = 0; j < nu; j++) {
            uint32_t a = RING(i, j), b = RING(i, j + 1), cc = RING(i + 1, j), dd = RING(i + 1, j + 1);
            soup_tri(m, a, b, dd);
            soup_tri(m, a, dd, cc);
        }
    for (int j = 0; j < nu; j++)
        soup_tri(m, south, RING(nv - 1, j), RING(nv - 1, j + 1));
#undef RING
}

/* An axis-aligned box whose 12 triangles face inwards (a room seen from inside). */
static void add_room(soup *m, rr_vec3 lo, rr_vec3 hi)
{
    uint32_t v[8];
    for (int k = 0; k < 8; k++)
        v[k] = soup_vert(m, k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
    /* Each face as a quad counter-clockwise seen from inside. */
    static const int q[6][4] = {
        {0, 1, 3, 2}, /* z = lo: normal +z */
        {4, 6, 7, 5}, /* z = hi: normal -z */
        {0, 4, 5, 1}, /* y = lo (floor): normal +y */
        {2, 3, 7, 6}, /* y = hi (ceiling): normal -y */
        {0, 2, 6, 4}, /* x = lo: normal +x */
        {1, 5, 7, 3}, /* x = hi: normal -x */
    };
    for (int f = 0; f < 6; f++) {
        soup_tri(m, v[q[f][0]], v[q[f][1]], v[q[f][2]]);
        soup_tri(m, v[q[f][0]], v[q[f][2]], v[q[f][3]]);
    }
}

/* ------------------------------------------------------------- the scenes */


/* room-100k: a closed 20 x 8 x 20 room (12 inward-facing triangles) holding a
 * 5 x 4 grid of displaced UV spheres, 80 x 33 segments (5120 triangles) each,
 * radius 1.0-1.4 and displacement drawn from stream i of the seed: 102,412
 * triangles. Camera inside the room near one wall looking down at the grid. */
void make_room(bench_scene *b, uint64_t seed)
{
    b->name = "room-100k";
    b->recipe = "room 20x8x20 (12 tris) + 5x4 displaced UV spheres 80x33 (5120 tris each)";
    add_room(&b->mesh, rr_v3(-10, 0, -10), rr_v3(10, 8, 10));
    for (int gz = 0; gz < 4; gz++)
        for (int gx = 0; gx < 5; gx++) {
            rr_rng rng = rr_rng_make(seed, (uint64_t)(gz * 5 + gx));
            double radius = 1.0 + 0.4 * rr_rng_uniform(&rng);
            displace d;
            d.amp[0] = 0.06 + 0.04 * rr_rng_uniform(&rng);
            d.amp[1] = 0.02 * rr_rng_uniform(&rng);
            d.kth[0] = 2 + (int)rr_rng_below(&rng, 6);
            d.kph[0] = 2 + (int)rr_rng_below(&rng, 8);
            d.kth[1] = 8 + (int)rr_rng_below(&rng, 8);
            d.kph[1] = 8 + (int)rr_rng_below(&rng, 8);
            d.phase[0] = 2.0 * RR_PI * rr_rng_uniform(&rng);
            d.phase[1] = 2.0 * RR_PI * rr_rng_uniform(&rng);
            rr_vec3 c = rr_v3(-7.0 + 3.5 * gx, radius + 0.3, -6.0 + 4.0 * gz);
            add_uv_sphere(&b->mesh, c, radius, &d, 80, 33);
        }
    b->eye = rr_v3(0, 5.5, 9.5);
    b->target = rr_v3(0, 1, -1);
    b->fov = 70.0;
    b->light = rr_v3(0.5, 7.5, 0.25);
}

/* mesh-1m: one displaced UV sphere of radius 1, 1000 x 501 segments:
 * 1,000,000 triangles (500,002 vertices). Camera outside, the sphere covers
 * about 60 % of the image. */
void make_mesh1m(bench_scene *b, uint64_t seed)
{
    b->name = "mesh-1m";
    b->recipe = "one displaced UV sphere 1000x501 (1,000,000 tris), seen from outside";
    rr_rng rng = rr_rng_make(seed, 1000);
    displace d;
    d.amp[0] = 0.08;
    d.amp[1] = 0.02;
    d.kth[0] = 6;
    d.kph[0] = 7;
    d.kth[1] = 40;
    d.kph[1] = 45;
    d.phase[0] = 2.0 * RR_PI * rr_rng_uniform(&rng);
    d.phase[1] = 2.0 * RR_PI * rr_rng_uniform(&rng);
    add_uv_sphere(&b->mesh, rr_v3(0, 0, 0), 1.0, &d, 1000, 501);
    b->eye = rr_v3(0.0, 0.8, 3.2);
    b->target = rr_v3(0, 0, 0);
    b->fov = 40.0;
    b->light = rr_v3(3, 4, 4);
}

/* ---- bunny-1m: the scanned Stanford bunny, Loop-subdivided ---- */

typedef struct loop_edge {
    uint64_t key; /* lo << 32 | hi */
    uint32_t mid; /* its new vertex */
} loop_edge;

static int cmp_edge_key(const void *a, const void *b)
{
    uint64_t x = ((const loop_edge *)a)->key, y = ((const loop_edge *)b)->key;
    return (x > y) - (x < y);
}

static uint64_t edge_key(uint32_t a, uint32_t b) { return a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a; }

/* The edge {a, b} in the sorted, unique edge array e[0..n). */
static const loop_edge *find_edge(const loop_edge *e, size_t n, uint32_t a, uint32_t b)
{
    loop_edge k = {edge_key(a, b), 0};
    return bsearch(&k, e, n, sizeof *e, cmp_edge_key);
}

/* One level of Loop subdivision of a closed, manifold mesh (pos: 3 doubles
 * per vertex): every triangle becomes four; new edge points are 3/8 of the
 * edge's ends plus 1/8 of the two opposite corners, old vertices move to
 * (1 - n beta) v + beta sum(neighbours) with Warren's beta (3/16 for valence
 * 3, else 3/(8n)). */
static void loop_subdivide(double **pos, size_t *nv, uint32_t **tri, size_t *nt)
{
    size_t n_e = 3 * *nt, nu = 0;
    loop_edge *e = xmalloc(n_e * sizeof *e);
    for (size_t t = 0; t < *nt; t++)
        for (int k = 0; k < 3; k++)
            e[3 * t + k] = (loop_edge){edge_key((*tri)[3 * t + k], (*tri)[3 * t + (k + 1) % 3]), 0};
    qsort(e, n_e, sizeof *e, cmp_edge_key);
    for (size_t i = 0; i < n_e; i++)
        if (nu == 0 || e[i].key != e[nu - 1].key)
            e[nu++] = e[i];
    size_t nv2 = *nv + nu;
    double *p2 = xmalloc(3 * nv2 * sizeof *p2), *sum = xmalloc(3 * *nv * sizeof *sum);
    int *val = xmalloc(*nv * sizeof *val);
    memset(sum, 0, 3 * *nv * sizeof *sum);
    memset(val, 0, *nv * sizeof *val);
    for (size_t i = 0; i < nu; i++) { /* edge points, and each vertex's ring */
        uint32_t a = (uint32_t)(e[i].key >> 32), b = (uint32_t)e[i].key;
        e[i].mid = (uint32_t)(*nv + i);
        for (int c = 0; c < 3; c++)
            p2[3 * e[i].mid + c] = 0.375 * ((*pos)[3 * a + c] + (*pos)[3 * b + c]);
        for (int c = 0; c < 3; c++) {
            sum[3 * a + c] += (*pos)[3 * b + c];
            sum[3 * b + c] += (*pos)[3 * a + c];
        }
        val[a]++, val[b]++;
    }
    /* the opposite corners: every triangle adds 1/8 of its third corner to each of its edges */
    for (size_t t = 0; t < *nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = (*tri)[3 * t + k], b = (*tri)[3 * t + (k + 1) % 3], c = (*tri)[3 * t + (k + 2) % 3];
            const loop_edge *x = find_edge(e, nu, a, b);
            for (int j = 0; j < 3; j++)
                p2[3 * x->mid + j] += 0.125 * (*pos)[3 * c + j];
        }
    for (size_t v = 0; v < *nv; v++) {
        int n = val[v];
        double beta = n == 3 ? 3.0 / 16.0 : 3.0 / (8.0 * n);
        for (int c = 0; c < 3; c++)
            p2[3 * v + c] = (1 - n * beta) * (*pos)[3 * v + c] + beta * sum[3 * v + c];
    }
    uint32_t *t2 = xmalloc(12 * *nt * sizeof *t2);
    for (size_t t = 0; t < *nt; t++) {
        const uint32_t *T = *tri + 3 * t;
        uint32_t m0 = find_edge(e, nu, T[0], T[1])->mid, m1 = find_edge(e, nu, T[1], T[2])->mid,
                 m2 = find_edge(e, nu, T[2], T[0])->mid;
        uint32_t q[12] = {T[0], m0, m2, m0, T[1], m1, m2, m1, T[2], m0, m1, m2};
        memcpy(t2 + 12 * t, q, sizeof q);
    }
    free(e), free(sum), free(val), free(*pos), free(*tri);
    *pos = p2, *nv = nv2, *tri = t2, *nt *= 4;
}

/* bunny-1m: scenes/meshes/bunny.ply (3,674 triangles, watertight), four
 * levels of Loop subdivision: 940,544 triangles of the same smooth shape.
 * Camera in front, a point light above. */
void make_bunny1m(bench_scene *b, const char *ply)
{
    b->name = "bunny-1m";
    b->recipe = "the Stanford bunny (scanned, 3,674 tris), 4 levels of Loop subdivision (940,544 tris)";
    mesh_tri *m = NULL;
    rr_error err;
    if (mesh_load(ply, &m, &err) != RR_OK) {
        fprintf(stderr, "%s: %s\n", bench_prog, err.msg);
        exit(1);
    }
    size_t nv = m->nverts, nt = m->ntris;
    double *pos = xmalloc(3 * nv * sizeof *pos);
    uint32_t *tri = xmalloc(3 * nt * sizeof *tri);
    memcpy(pos, m->pos, 3 * nv * sizeof *pos);
    memcpy(tri, m->tris, 3 * nt * sizeof *tri);
    mesh_destroy(m);
    for (int level = 0; level < 4; level++)
        loop_subdivide(&pos, &nv, &tri, &nt);
    for (size_t v = 0; v < nv; v++)
        soup_vert(&b->mesh, pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]);
    for (size_t t = 0; t < nt; t++)
        soup_tri(&b->mesh, tri[3 * t], tri[3 * t + 1], tri[3 * t + 2]);
    free(pos);
    free(tri);
    b->eye = rr_v3(0.0, 6.0, 22.0); /* the bunny spans x, z in +-5, y in 0..9.7 */
    b->target = rr_v3(0, 4.5, 0);
    b->fov = 35.0;
    b->light = rr_v3(8, 20, 14);
}

/* Binary little-endian PLY: float x y z, faces as "list uchar int". */
int write_ply(const char *path, const soup *m)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    fprintf(f,
            "ply\nformat binary_little_endian 1.0\nelement vertex %zu\nproperty float x\nproperty float y\n"
            "property float z\nelement face %zu\nproperty list uchar int vertex_indices\nend_header\n",
            m->nverts, m->ntris);
    int ok = 1;
    /* The host is little-endian (x86-64/aarch64); checked in main. */
    ok &= fwrite(m->pos, sizeof(float), 3 * m->nverts, f) == 3 * m->nverts;
    unsigned char rec[13];
    rec[0] = 3;
    for (size_t i = 0; i < m->ntris && ok; i++) {
        memcpy(rec + 1, m->idx + 3 * i, 12);
        ok &= fwrite(rec, 1, sizeof rec, f) == sizeof rec;
    }
    ok &= fclose(f) == 0;
    return ok ? 0 : -1;
}

/* ------------------------------------------------------------------- rays */


/* Cosine-weighted direction around unit n (Duff et al. 2017 orthonormal basis). */
rr_vec3 cosine_dir(rr_vec3 n, double u1, double u2)
{
    double sign = copysign(1.0, n.z);
    double a = -1.0 / (sign + n.z);
    double b = n.x * n.y * a;
    rr_vec3 t = rr_v3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    rr_vec3 bt = rr_v3(b, sign + n.y * n.y * a, -n.y);
    double r = sqrt(u1), phi = 2.0 * RR_PI * u2;
    double x = r * cos(phi), y = r * sin(phi), z = sqrt(fmax(0.0, 1.0 - u1));
    return rr_v3_add(rr_v3_add(rr_v3_scale(t, x), rr_v3_scale(bt, y)), rr_v3_scale(n, z));
}

/* Origin nudged off the surface to the side the new ray leaves towards, as the
 * renderer does (raytrace/rt_render.c offset_origin). */
rr_vec3 offset_origin(rr_vec3 p, rr_vec3 n, rr_vec3 dir, double extent)
{
    double m = fmax(fabs(p.x), fmax(fabs(p.y), fabs(p.z)));
    double eps = 1e-9 * (m + extent);
    return rr_v3_madd(p, n, rr_v3_dot(n, dir) >= 0.0 ? eps : -eps);
}

void cpu_model(char *out, size_t size)
{
    snprintf(out, size, "unknown");
    FILE *f = fopen("/proc/cpuinfo", "r");
    if (!f)
        return;
    char line[512];
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "model name", 10) == 0) {
            const char *c = strchr(line, ':');
            if (c) {
                c++;
                while (*c == ' ' || *c == '\t')
                    c++;
                snprintf(out, size, "%s", c);
                out[strcspn(out, "\n")] = '\0';
            }
            break;
        }
    }
    fclose(f);
}

scene *bench_load_scene(bench_scene *b, int res, const char *tmpdir, double *t_write_out, double *t_load_out)
{
    char path[4096], json[4096];
    /* Generate and write (untimed in the table; reported for information). */
    double t0 = now_s();
    int pn = snprintf(path, sizeof path, "%s/%s.ply", tmpdir, b->name);
    if (pn < 0 || (size_t)pn >= sizeof path || write_ply(path, &b->mesh)) {
        fprintf(stderr, "%s: cannot write %s\n", bench_prog, path);
        exit(1);
    }
    double t_write = now_s() - t0;
    snprintf(json, sizeof json,
             "{\"format\":\"radray-scene/1\",\"name\":\"%s\","
             "\"camera\":{\"type\":\"lookat\",\"eye\":[%.17g,%.17g,%.17g],\"target\":[%.17g,%.17g,%.17g],"
             "\"up\":[0,1,0],\"fov\":%.17g,\"width\":%d,\"height\":%d},"
             "\"materials\":{\"grey\":{\"diffuse\":[0.5,0.5,0.5]}},"
             "\"lights\":[{\"type\":\"point\",\"position\":[%.17g,%.17g,%.17g],\"intensity\":[1,1,1]}],"
             "\"objects\":[{\"name\":\"geometry\",\"type\":\"mesh\",\"file\":\"%s.ply\",\"material\":\"grey\"}]}",
             b->name, b->eye.x, b->eye.y, b->eye.z, b->target.x, b->target.y, b->target.z, b->fov, res, res,
             b->light.x, b->light.y, b->light.z, b->name);

    scene *s = NULL;
    rr_error err;
    t0 = now_s();
    if (scene_load_string(json, b->name, tmpdir, NULL, &s, &err) != RR_OK) {
        fprintf(stderr, "%s: %s\n", bench_prog, err.msg);
        exit(1);
    }
    double t_load = now_s() - t0;
    unlink(path);
    soup_free(&b->mesh);
    *t_write_out = t_write;
    *t_load_out = t_load;
    return s;
}

void bench_make_rays(const scene *s, const rt_accel *a, const bench_scene *b, uint64_t seed, ray_set *prim_out,
                     ray_set *diff_out, ray_set *shad_out)
{
    rr_view view = s->view;
    size_t n = (size_t)view.width * (size_t)view.height;
    ray_set prim = {xmalloc(n * sizeof(rr_ray)), n, INFINITY, view.width, view.height, NULL};
    for (size_t i = 0; i < n; i++)
        prim.rays[i] = rr_view_ray(&view, (int)(i % (size_t)view.width), (int)(i / (size_t)view.width), 0.0, 0.0);
    rr_vec3 *hp = xmalloc(n * sizeof *hp), *hn = xmalloc(n * sizeof *hn);
    unsigned char *hit = xmalloc(n);
    const long ln = (long)n;
#pragma omp parallel for schedule(dynamic, 1024)
    for (long i = 0; i < ln; i++) {
        rt_hit h;
        hit[i] = (unsigned char)rt_accel_closest(a, prim.rays[i], 0.0, INFINITY, &h);
        if (hit[i]) {
            hp[i] = h.point;
            hn[i] = h.normal;
        }
    }
    rr_vec3 ext = rr_v3_sub(s->bbox_max, s->bbox_min);
    double extent = fmax(ext.x, fmax(ext.y, ext.z));
    ray_set diff = {xmalloc(n * sizeof(rr_ray)), 0, INFINITY, view.width, view.height, xmalloc(n * sizeof(uint32_t))};
    ray_set shad = {xmalloc(n * sizeof(rr_ray)), 0, 1.0 - 1e-7, view.width, view.height,
                    xmalloc(n * sizeof(uint32_t))};
    for (size_t i = 0; i < n; i++) {
        if (!hit[i])
            continue;
        rr_rng rng = rr_rng_make(seed, i);
        double u1 = rr_rng_uniform(&rng), u2 = rr_rng_uniform(&rng);
        rr_vec3 d = cosine_dir(hn[i], u1, u2);
        rr_ray r = {offset_origin(hp[i], hn[i], d, extent), d};
        diff.pix[diff.n] = (uint32_t)i;
        diff.rays[diff.n++] = r;
        /* To the light, from the hits that face it (the renderer skips the
         * others): unnormalised direction, t = 1 at the light. */
        /* A square light (light_size > 0): a uniform point of it, from the
         * pixel's stream after the diffuse ray's draws. */
        rr_vec3 lp = b->light;
        if (b->light_size > 0.0) {
            double side = b->light_size * extent, u3 = rr_rng_uniform(&rng), u4 = rr_rng_uniform(&rng);
            lp = rr_v3_add(lp, rr_v3(side * (u3 - 0.5), 0.0, side * (u4 - 0.5)));
        }
        rr_vec3 to_light = rr_v3_sub(lp, hp[i]);
        if (rr_v3_dot(hn[i], to_light) <= 0.0)
            continue;
        rr_vec3 org = offset_origin(hp[i], hn[i], to_light, extent);
        rr_ray sr = {org, rr_v3_sub(lp, org)};
        shad.pix[shad.n] = (uint32_t)i;
        shad.rays[shad.n++] = sr;
    }
    free(hp);
    free(hn);
    free(hit);

    *prim_out = prim;
    *diff_out = diff;
    *shad_out = shad;
}

tile_order bench_tile_order(const ray_set *rs, int tile)
{
    const size_t w = (size_t)rs->width, h = (size_t)rs->height, tw = (w + (size_t)tile - 1) / (size_t)tile;
    tile_order t;
    t.ntiles = tw * ((h + (size_t)tile - 1) / (size_t)tile);
    t.idx = xmalloc((rs->n ? rs->n : 1) * sizeof *t.idx);
    t.start = xmalloc((t.ntiles + 1) * sizeof *t.start);
    /* A counting sort by tile, stable: the rays come in pixel order, so
     * each tile's rays stay in scanline order. */
    for (size_t k = 0; k <= t.ntiles; k++)
        t.start[k] = 0;
    for (size_t i = 0; i < rs->n; i++) {
        size_t p = rs->pix ? rs->pix[i] : i;
        if (p >= w * h) {
            fprintf(stderr, "%s: ray %zu of a set is not in the %zux%zu image\n", bench_prog, i, w, h);
            exit(1);
        }
        t.start[(p / w / (size_t)tile) * tw + (p % w) / (size_t)tile + 1]++;
    }
    for (size_t k = 0; k < t.ntiles; k++)
        t.start[k + 1] += t.start[k];
    size_t *fill = xmalloc((t.ntiles + 1) * sizeof *fill);
    memcpy(fill, t.start, (t.ntiles + 1) * sizeof *fill);
    for (size_t i = 0; i < rs->n; i++) {
        size_t p = rs->pix ? rs->pix[i] : i;
        t.idx[fill[(p / w / (size_t)tile) * tw + (p % w) / (size_t)tile]++] = (uint32_t)i;
    }
    free(fill);
    return t;
}

void bench_tile_order_free(tile_order *t)
{
    free(t->idx);
    free(t->start);
}

void ray_set_free(ray_set *rs)
{
    free(rs->rays);
    free(rs->pix);
}
