/* bench_import.c - load time of whole model files (radray-bench-import).
 *
 *   radray-bench-import [--repeat N] [--nodes N] [--unique] [--format glb|obj] [--keep]
 *
 * Writes one model twice into a fresh temporary folder, as a binary glTF
 * (big.glb) and as Wavefront OBJ + MTL (big.obj, big.mtl), with a tiny scene
 * file for each (a camera and one {"type": "model"} object), then times
 * scene_load of each scene N times (default 3) and, apart, imp_load of the
 * model file alone (the importer without the scene side: welding, topology
 * report, transforms into the scene's arrays).
 *
 * The model (default 1,000,000 triangles, bench/README.md):
 *   10 meshes, each a displaced UV sphere of 100 x 51 segments (10,000
 *   triangles, 5,002 shared vertices, per-vertex normals), and a root node
 *   "grid" with 100 child nodes on a 10 x 10 grid, each placing one of the
 *   meshes (node k uses mesh k mod 10) with its own translation, rotation
 *   about Y and uniform scale; 4 materials (mesh m uses material m mod 4).
 *   glTF: indexed TRIANGLES, UNSIGNED_INT indices, float POSITION (with min
 *   and max) and NORMAL, one bufferView per accessor, as exporters write it.
 *   OBJ: the same 100 placed meshes flattened into world space ("o",
 *   "usemtl", v, vn and "f a//a b//b c//c" per node), materials in big.mtl.
 *   --unique: the glb gets one mesh per node instead (each node's copy of
 *   its sphere stored again), as a file without instancing.
 *
 * Each format runs in a child process (fork), so its peak RSS (wait4's
 * ru_maxrss) is its own and not the other format's; the parent frees the
 * generated geometry before forking. Files are read from the page cache
 * (they were just written).
 *
 * Not a ctest test: timings belong in a benchmark, never in unit tests.
 */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench_scenes.h"
#include "imp.h"
#include "rr_core.h"
#include "scene.h"

#ifndef RADRAY_BUILD_TYPE
#define RADRAY_BUILD_TYPE "unknown"
#endif

#define BI_MESHES 10
#define BI_NU 100 /* segments around: 2 + NU (NV - 1) vertices, 2 NU (NV - 1) triangles */
#define BI_NV 51
#define BI_MATERIALS 4
#define BI_MAX_REPEAT 100

/* ------------------------------------------------------------ the model */

typedef struct bi_mesh {
    float *pos, *nrm; /* 3 per vertex */
    uint32_t *idx;    /* 3 per triangle */
    size_t nverts, ntris;
    float lo[3], hi[3];
} bi_mesh;

typedef struct bi_node {
    uint32_t mesh;
    double t[3], angle, scale; /* world = t + scale * R_y(angle) p */
} bi_node;

static const struct {
    const char *name;
    double rgb[3], metallic, roughness;
} k_mat[BI_MATERIALS] = {
    {"clay", {0.80, 0.45, 0.30}, 0.0, 0.9},
    {"leaf", {0.25, 0.60, 0.20}, 0.0, 0.6},
    {"porcelain", {0.90, 0.90, 0.85}, 0.0, 0.2},
    {"steel", {0.60, 0.60, 0.65}, 1.0, 0.35},
};

/* A displaced UV sphere of radius 1 (the displacement differs per mesh m);
 * counter-clockwise seen from outside; normals: area-weighted face normals. */
static void make_mesh(bi_mesh *b, int m)
{
    const int nu = BI_NU, nv = BI_NV;
    b->nverts = 2 + (size_t)nu * (size_t)(nv - 1);
    b->ntris = 2 * (size_t)nu * (size_t)(nv - 1);
    b->pos = xmalloc(3 * b->nverts * sizeof *b->pos);
    b->nrm = xmalloc(3 * b->nverts * sizeof *b->nrm);
    b->idx = xmalloc(3 * b->ntris * sizeof *b->idx);
    /* Gentle bumps: at least 9 segments per wavelength, and tapered by
     * sin^2(theta) towards the poles, so that the surface is smooth (faces
     * meet at a few degrees: an OBJ's corners all weld again). */
    double a0 = 0.04 + 0.008 * m, a1 = 0.01;
    int kt0 = 2 + m % 4, kp0 = 2 + m % 5, kt1 = 6 + m / 2, kp1 = 7 + m / 2;
    double ph0 = 0.37 * m, ph1 = 1.3 + 0.21 * m;
    size_t v = 0;
    float *p = b->pos;
#define PUT(x, y, z) (p[3 * v] = (float)(x), p[3 * v + 1] = (float)(y), p[3 * v + 2] = (float)(z), v++)
    PUT(0, 1, 0); /* north pole: every displacement term is 0 there */
    for (int i = 1; i < nv; i++) {
        double th = RR_PI * i / nv;
        for (int j = 0; j < nu; j++) {
            double ph = 2.0 * RR_PI * j / nu;
            double taper = sin(th) * sin(th);
            double r = 1.0 + taper * (a0 * sin(kt0 * th) * cos(kp0 * ph + ph0) + a1 * sin(kt1 * th) * cos(kp1 * ph + ph1));
            PUT(r * sin(th) * cos(ph), r * cos(th), r * sin(th) * sin(ph));
        }
    }
    PUT(0, -1, 0);
#undef PUT
    const uint32_t north = 0, south = (uint32_t)(b->nverts - 1);
    uint32_t *t = b->idx;
#define RING(i, j) (1u + (uint32_t)((i) - 1) * (uint32_t)nu + (uint32_t)((j) % nu))
#define TRI(a, b_, c) (t[0] = (a), t[1] = (b_), t[2] = (c), t += 3)
    for (int j = 0; j < nu; j++)
        TRI(north, RING(1, j + 1), RING(1, j));
    for (int i = 1; i < nv - 1; i++)
        for (int j = 0; j < nu; j++) {
            uint32_t a = RING(i, j), bb = RING(i, j + 1), c = RING(i + 1, j), d = RING(i + 1, j + 1);
            TRI(a, bb, d);
            TRI(a, d, c);
        }
    for (int j = 0; j < nu; j++)
        TRI(south, RING(nv - 1, j), RING(nv - 1, j + 1));
#undef TRI
#undef RING
    double *acc = calloc(3 * b->nverts, sizeof *acc);
    if (!acc) {
        fprintf(stderr, "%s: out of memory\n", bench_prog);
        exit(1);
    }
    for (size_t f = 0; f < b->ntris; f++) {
        const uint32_t *q = b->idx + 3 * f;
        double e1[3], e2[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = (double)p[3 * q[1] + k] - p[3 * q[0] + k];
            e2[k] = (double)p[3 * q[2] + k] - p[3 * q[0] + k];
        }
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                acc[3 * q[c] + k] += n[k];
    }
    for (int k = 0; k < 3; k++)
        b->lo[k] = INFINITY, b->hi[k] = -INFINITY;
    for (size_t i = 0; i < b->nverts; i++) {
        double l = sqrt(acc[3 * i] * acc[3 * i] + acc[3 * i + 1] * acc[3 * i + 1] + acc[3 * i + 2] * acc[3 * i + 2]);
        for (int k = 0; k < 3; k++) {
            b->nrm[3 * i + k] = (float)(acc[3 * i + k] / l);
            b->lo[k] = fminf(b->lo[k], p[3 * i + k]);
            b->hi[k] = fmaxf(b->hi[k], p[3 * i + k]);
        }
    }
    free(acc);
}

static void mesh_free_bi(bi_mesh *b)
{
    free(b->pos);
    free(b->nrm);
    free(b->idx);
}

/* Node k of a side x side grid, 3 units apart, centred on the origin. */
static bi_node make_node(int k, int side)
{
    bi_node n;
    n.mesh = (uint32_t)(k % BI_MESHES);
    n.t[0] = 3.0 * (k % side) - 1.5 * (side - 1);
    n.t[1] = 1.2;
    n.t[2] = 3.0 * (k / side) - 1.5 * (side - 1);
    n.angle = 0.7 * k;
    n.scale = 0.8 + 0.04 * (k % 11);
    return n;
}

/* ------------------------------------------------------ a growing string */

typedef struct sbuf {
    char *s;
    size_t n, cap;
} sbuf;

#if defined(__GNUC__)
__attribute__((format(printf, 2, 3)))
#endif
static void sb_printf(sbuf *b, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        size_t room = b->cap - b->n;
        int w = vsnprintf(b->s ? b->s + b->n : NULL, room, fmt, ap);
        va_end(ap);
        if (w < 0) {
            fprintf(stderr, "%s: formatting failed\n", bench_prog);
            exit(1);
        }
        if ((size_t)w < room) {
            b->n += (size_t)w;
            return;
        }
        size_t cap = b->cap ? 2 * b->cap : 4096;
        while (cap - b->n <= (size_t)w)
            cap *= 2;
        char *s = realloc(b->s, cap);
        if (!s) {
            fprintf(stderr, "%s: out of memory\n", bench_prog);
            exit(1);
        }
        b->s = s, b->cap = cap;
    }
}

/* ------------------------------------------------------------ the files */

static void put_u32(FILE *f, uint32_t v, int *ok)
{
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16), (unsigned char)(v >> 24)};
    *ok &= fwrite(b, 1, 4, f) == 4;
}

/* Binary glTF 2.0: header, JSON chunk (padded with spaces), BIN chunk.
 * unique: one glTF mesh per node (the data stored nnodes times, as in a file
 * without instancing); else the BI_MESHES meshes once, shared by the nodes. */
static int write_glb(const char *path, const bi_mesh *me, const bi_node *nodes, int nnodes, int unique)
{
    const int ng = unique ? nnodes : BI_MESHES;
#define SRC(g) (unique ? (int)nodes[g].mesh : (g)) /* glTF mesh g holds me[SRC(g)] */
    sbuf j = {NULL, 0, 0};
    sb_printf(&j, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"radray-bench-import\"},\"scene\":0,"
                  "\"scenes\":[{\"name\":\"bench\",\"nodes\":[0]}],\"nodes\":[{\"name\":\"grid\",\"children\":[");
    for (int k = 0; k < nnodes; k++)
        sb_printf(&j, "%s%d", k ? "," : "", k + 1);
    sb_printf(&j, "]}");
    for (int k = 0; k < nnodes; k++) {
        const bi_node *n = &nodes[k];
        sb_printf(&j,
                  ",{\"name\":\"node_%d\",\"mesh\":%u,\"translation\":[%.9g,%.9g,%.9g],"
                  "\"rotation\":[0,%.9g,0,%.9g],\"scale\":[%.9g,%.9g,%.9g]}",
                  k, unique ? (unsigned)k : n->mesh, n->t[0], n->t[1], n->t[2], sin(0.5 * n->angle), cos(0.5 * n->angle), n->scale, n->scale,
                  n->scale);
    }
    sb_printf(&j, "],\"meshes\":[");
    for (int m = 0; m < ng; m++)
        sb_printf(&j,
                  "%s{\"name\":\"sphere_%d\",\"primitives\":[{\"attributes\":{\"POSITION\":%d,\"NORMAL\":%d},"
                  "\"indices\":%d,\"material\":%d,\"mode\":4}]}",
                  m ? "," : "", m, 3 * m, 3 * m + 1, 3 * m + 2, SRC(m) % BI_MATERIALS);
    sb_printf(&j, "],\"materials\":[");
    for (int i = 0; i < BI_MATERIALS; i++)
        sb_printf(&j,
                  "%s{\"name\":\"%s\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[%g,%g,%g,1],"
                  "\"metallicFactor\":%g,\"roughnessFactor\":%g}}",
                  i ? "," : "", k_mat[i].name, k_mat[i].rgb[0], k_mat[i].rgb[1], k_mat[i].rgb[2], k_mat[i].metallic,
                  k_mat[i].roughness);
    /* BIN layout per mesh: positions, normals, indices (all 4-byte aligned). */
    sb_printf(&j, "],\"accessors\":[");
    size_t off = 0;
    sbuf views = {NULL, 0, 0};
    for (int m = 0; m < ng; m++) {
        const bi_mesh *b = &me[SRC(m)];
        size_t vb = 12 * b->nverts, ib = 12 * b->ntris;
        sb_printf(&j,
                  "%s{\"bufferView\":%d,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\","
                  "\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]},"
                  "{\"bufferView\":%d,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\"},"
                  "{\"bufferView\":%d,\"componentType\":5125,\"count\":%zu,\"type\":\"SCALAR\"}",
                  m ? "," : "", 3 * m, b->nverts, b->lo[0], b->lo[1], b->lo[2], b->hi[0], b->hi[1], b->hi[2], 3 * m + 1,
                  b->nverts, 3 * m + 2, 3 * b->ntris);
        sb_printf(&views,
                  "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},"
                  "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34962},"
                  "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34963}",
                  m ? "," : "", off, vb, off + vb, vb, off + 2 * vb, ib);
        off += 2 * vb + ib;
    }
    sb_printf(&j, "],\"bufferViews\":[%s],\"buffers\":[{\"byteLength\":%zu}]}", views.s, off);
    free(views.s);
    while (j.n % 4)
        sb_printf(&j, " ");

    FILE *f = fopen(path, "wb");
    if (!f) {
        free(j.s);
        return -1;
    }
    int ok = 1;
    size_t total = 12 + 8 + j.n + 8 + off;
    if (total > UINT32_MAX)
        ok = 0;
    put_u32(f, 0x46546C67u, &ok); /* "glTF" */
    put_u32(f, 2, &ok);
    put_u32(f, (uint32_t)total, &ok);
    put_u32(f, (uint32_t)j.n, &ok);
    put_u32(f, 0x4E4F534Au, &ok); /* "JSON" */
    ok &= fwrite(j.s, 1, j.n, f) == j.n;
    put_u32(f, (uint32_t)off, &ok);
    put_u32(f, 0x004E4942u, &ok); /* "BIN\0" */
    /* The host is little-endian (checked in main): floats and indices as they are. */
    for (int m = 0; m < ng && ok; m++) {
        const bi_mesh *b = &me[SRC(m)];
        ok &= fwrite(b->pos, sizeof(float), 3 * b->nverts, f) == 3 * b->nverts;
        ok &= fwrite(b->nrm, sizeof(float), 3 * b->nverts, f) == 3 * b->nverts;
        ok &= fwrite(b->idx, sizeof(uint32_t), 3 * b->ntris, f) == 3 * b->ntris;
    }
    ok &= fclose(f) == 0;
    free(j.s);
    return ok ? 0 : -1;
#undef SRC
}

static int write_mtl(const char *path)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    fprintf(f, "# radray-bench-import\n");
    for (int i = 0; i < BI_MATERIALS; i++) {
        double ks = k_mat[i].metallic > 0 ? 0.5 : 0.04;
        fprintf(f, "\nnewmtl %s\nKa 0 0 0\nKd %.4f %.4f %.4f\nKs %.4f %.4f %.4f\nNs %.1f\nd 1\nillum 2\n",
                k_mat[i].name, k_mat[i].rgb[0], k_mat[i].rgb[1], k_mat[i].rgb[2], ks, ks, ks,
                2.0 / (k_mat[i].roughness * k_mat[i].roughness));
    }
    return fclose(f) == 0 ? 0 : -1;
}

/* The placed meshes in world space, one "o" per node, as an exporter
 * flattens a scene (Blender: 6 decimals for v, 4 for vn). */
static int write_obj(const char *path, const char *mtl_name, const bi_mesh *me, const bi_node *nodes, int nnodes)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    static char buf[1 << 20];
    setvbuf(f, buf, _IOFBF, sizeof buf);
    int ok = fprintf(f, "# radray-bench-import\nmtllib %s\n", mtl_name) > 0;
    size_t base = 1;
    for (int k = 0; k < nnodes && ok; k++) {
        const bi_node *n = &nodes[k];
        const bi_mesh *b = &me[n->mesh];
        double c = cos(n->angle), s = sin(n->angle);
        fprintf(f, "o node_%d\n", k);
        for (size_t i = 0; i < b->nverts; i++) {
            const float *p = b->pos + 3 * i;
            fprintf(f, "v %.6f %.6f %.6f\n", n->t[0] + n->scale * (c * p[0] + s * p[2]), n->t[1] + n->scale * p[1],
                    n->t[2] + n->scale * (-s * p[0] + c * p[2]));
        }
        for (size_t i = 0; i < b->nverts; i++) {
            const float *q = b->nrm + 3 * i;
            fprintf(f, "vn %.4f %.4f %.4f\n", c * q[0] + s * q[2], (double)q[1], -s * q[0] + c * q[2]);
        }
        fprintf(f, "usemtl %s\ns 1\n", k_mat[n->mesh % BI_MATERIALS].name);
        for (size_t t = 0; t < b->ntris; t++) {
            const uint32_t *q = b->idx + 3 * t;
            size_t x = base + q[0], y = base + q[1], z = base + q[2];
            fprintf(f, "f %zu//%zu %zu//%zu %zu//%zu\n", x, x, y, y, z, z);
        }
        base += b->nverts;
        ok = !ferror(f);
    }
    ok &= fclose(f) == 0;
    return ok ? 0 : -1;
}

static int write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    int ok = fputs(text, f) >= 0;
    ok &= fclose(f) == 0;
    return ok ? 0 : -1;
}

/* --------------------------------------------------------------- timing */

typedef struct bi_result {
    int ok;
    char msg[RR_ERROR_MSG_MAX];
    double t_scene[BI_MAX_REPEAT], t_imp[BI_MAX_REPEAT];
    size_t ntris, nverts, nobjects, nmaterials, imp_tris, imp_meshes, warnings;
    char first_warning[256];
} bi_result;

static void count_warning(void *user, const char *msg)
{
    bi_result *r = user;
    if (r->warnings++ == 0)
        snprintf(r->first_warning, sizeof r->first_warning, "%s", msg);
}

/* In the child: N x scene_load, then N x imp_load of the model alone. */
static void measure(const char *scene_path, const char *model_path, int repeat, bi_result *r)
{
    memset(r, 0, sizeof *r);
    scene_load_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.warn.fn = count_warning;
    opts.warn.user = r;
    rr_error err;
    for (int i = 0; i < repeat; i++) {
        scene *s = NULL;
        size_t w0 = r->warnings;
        double t0 = now_s();
        if (scene_load(scene_path, &opts, &s, &err) != RR_OK) {
            snprintf(r->msg, sizeof r->msg, "%s", err.msg);
            return;
        }
        r->t_scene[i] = now_s() - t0;
        r->ntris = s->ntris, r->nverts = s->nverts, r->nobjects = s->nobjects, r->nmaterials = s->nmaterials;
        if (i > 0)
            r->warnings = w0; /* count one load's warnings */
        scene_destroy(s);
    }
    for (int i = 0; i < repeat; i++) {
        imp_model *m = NULL;
        double t0 = now_s();
        if (imp_load(model_path, &m, &err) != RR_OK) {
            snprintf(r->msg, sizeof r->msg, "%s", err.msg);
            return;
        }
        r->t_imp[i] = now_s() - t0;
        r->imp_tris = imp_triangles(m), r->imp_meshes = m->nmeshes;
        imp_destroy(m);
    }
    r->ok = 1;
}

/* Runs measure() in a child; *maxrss_kib is the child's peak RSS. */
static int run_child(const char *scene_path, const char *model_path, int repeat, bi_result *r, long *maxrss_kib)
{
    int fd[2];
    if (pipe(fd)) {
        perror("pipe");
        return -1;
    }
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) {
        perror("fork");
        return -1;
    }
    if (pid == 0) {
        close(fd[0]);
        bi_result *x = xmalloc(sizeof *x);
        measure(scene_path, model_path, repeat, x);
        const char *p = (const char *)x;
        size_t left = sizeof *x;
        while (left) {
            ssize_t w = write(fd[1], p, left);
            if (w <= 0)
                _exit(3);
            p += w, left -= (size_t)w;
        }
        _exit(0);
    }
    close(fd[1]);
    char *p = (char *)r;
    size_t got = 0;
    while (got < sizeof *r) {
        ssize_t n = read(fd[0], p + got, sizeof *r - got);
        if (n <= 0)
            break;
        got += (size_t)n;
    }
    close(fd[0]);
    int status;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    if (wait4(pid, &status, 0, &ru) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0 || got != sizeof *r) {
        fprintf(stderr, "%s: the measuring process for %s failed (status %d)\n", bench_prog, model_path, status);
        return -1;
    }
    *maxrss_kib = ru.ru_maxrss;
    return 0;
}

static long self_maxrss_kib(void)
{
    struct rusage ru;
    return getrusage(RUSAGE_SELF, &ru) == 0 ? ru.ru_maxrss : -1;
}

static double file_mib(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (double)st.st_size / (1024.0 * 1024.0) : 0.0;
}

/* ------------------------------------------------------------------ main */

static void usage(FILE *f)
{
    fprintf(f, "usage: radray-bench-import [--repeat N] [--nodes N] [--unique] [--format glb|obj] [--keep]\n"
               "  --repeat N     loads per format (default 3, at most %d)\n"
               "  --nodes N      placed meshes (default 100: 1,000,000 triangles; 10 for a quick profile)\n"
               "  --unique       glb: one mesh per node (no instancing: the BIN chunk holds every triangle)\n"
               "  --format F     only glb or only obj\n"
               "  --keep         leave the temporary folder (prints its name)\n",
            BI_MAX_REPEAT);
}

static long parse_int(const char *s, long lo, long hi)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    return end == s || *end || errno || v < lo || v > hi ? -1 : v;
}

int main(int argc, char **argv)
{
    bench_prog = "radray-bench-import";
    int repeat = 3, nnodes = 100, keep = 0, unique = 0;
    const char *only = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--repeat") && i + 1 < argc) {
            long v = parse_int(argv[++i], 1, BI_MAX_REPEAT);
            if (v < 0) {
                fprintf(stderr, "%s: bad --repeat '%s' (1..%d)\n", bench_prog, argv[i], BI_MAX_REPEAT);
                return 2;
            }
            repeat = (int)v;
        } else if (!strcmp(argv[i], "--nodes") && i + 1 < argc) {
            long v = parse_int(argv[++i], 1, 10000);
            if (v < 0) {
                fprintf(stderr, "%s: bad --nodes '%s' (1..10000)\n", bench_prog, argv[i]);
                return 2;
            }
            nnodes = (int)v;
        } else if (!strcmp(argv[i], "--format") && i + 1 < argc) {
            only = argv[++i];
            if (strcmp(only, "glb") && strcmp(only, "obj")) {
                fprintf(stderr, "%s: unknown format '%s' (glb or obj)\n", bench_prog, only);
                return 2;
            }
        } else if (!strcmp(argv[i], "--unique")) {
            unique = 1;
        } else if (!strcmp(argv[i], "--keep")) {
            keep = 1;
        } else if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            usage(stdout);
            return 0;
        } else {
            usage(stderr);
            return 2;
        }
    }
    const uint16_t probe = 1;
    if (*(const unsigned char *)&probe != 1) {
        fprintf(stderr, "%s: the glb writer assumes a little-endian host\n", bench_prog);
        return 1;
    }

    char cpu[256];
    cpu_model(cpu, sizeof cpu);
    printf("radray-bench-import: load time of a model file (scene_load of a scene with one \"model\" object)\n");
    printf("machine: %ld online CPUs (nproc), CPU \"%s\"\n", sysconf(_SC_NPROCESSORS_ONLN), cpu);
#if defined(__VERSION__)
    printf("build: %s, compiler %s\n", RADRAY_BUILD_TYPE, __VERSION__);
#else
    printf("build: %s\n", RADRAY_BUILD_TYPE);
#endif

    const char *tmp = getenv("TMPDIR");
    char dir[4096];
    int tn = snprintf(dir, sizeof dir, "%s/radray-bench-import-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (tn < 0 || (size_t)tn >= sizeof dir - 64 || !mkdtemp(dir)) {
        fprintf(stderr, "%s: cannot create a temporary folder %s: %s\n", bench_prog, dir, strerror(errno));
        return 1;
    }
    char p_glb[4160], p_obj[4160], p_mtl[4160], p_sglb[4160], p_sobj[4160];
    snprintf(p_glb, sizeof p_glb, "%s/big.glb", dir);
    snprintf(p_obj, sizeof p_obj, "%s/big.obj", dir);
    snprintf(p_mtl, sizeof p_mtl, "%s/big.mtl", dir);
    snprintf(p_sglb, sizeof p_sglb, "%s/big-glb.json", dir);
    snprintf(p_sobj, sizeof p_sobj, "%s/big-obj.json", dir);

    /* Generate and write. */
    double t0 = now_s();
    bi_mesh me[BI_MESHES];
    for (int m = 0; m < BI_MESHES; m++)
        make_mesh(&me[m], m);
    int side = (int)ceil(sqrt((double)nnodes));
    bi_node *nodes = xmalloc((size_t)nnodes * sizeof *nodes);
    size_t tris = 0, verts = 0;
    for (int k = 0; k < nnodes; k++) {
        nodes[k] = make_node(k, side);
        tris += me[nodes[k].mesh].ntris;
        verts += me[nodes[k].mesh].nverts;
    }
    double t_gen = now_s() - t0;
    int do_glb = !only || !strcmp(only, "glb"), do_obj = !only || !strcmp(only, "obj");
    double t_wglb = 0, t_wobj = 0;
    char scene_json[1024];
    const char *scene_fmt = "{\"format\": \"radray-scene/1\", \"name\": \"bench-import-%s\",\n"
                            " \"camera\": {\"type\": \"lookat\", \"eye\": [0, %g, %g], \"target\": [0, 0, 0],"
                            " \"up\": [0, 1, 0], \"fov\": 50, \"width\": 64, \"height\": 64},\n"
                            " \"objects\": [{\"type\": \"model\", \"file\": \"big.%s\"}]}\n";
    double reach = 2.0 * side + 5.0;
    int werr = 0;
    if (do_glb) {
        t0 = now_s();
        werr |= write_glb(p_glb, me, nodes, nnodes, unique);
        t_wglb = now_s() - t0;
        snprintf(scene_json, sizeof scene_json, scene_fmt, "glb", reach, reach, "glb");
        werr |= write_text(p_sglb, scene_json);
    }
    if (do_obj) {
        t0 = now_s();
        werr |= write_mtl(p_mtl) | write_obj(p_obj, "big.mtl", me, nodes, nnodes);
        t_wobj = now_s() - t0;
        snprintf(scene_json, sizeof scene_json, scene_fmt, "obj", reach, reach, "obj");
        werr |= write_text(p_sobj, scene_json);
    }
    for (int m = 0; m < BI_MESHES; m++)
        mesh_free_bi(&me[m]);
    free(nodes);
    if (werr) {
        fprintf(stderr, "%s: cannot write the model files into %s: %s\n", bench_prog, dir, strerror(errno));
        return 1;
    }
    printf("model: %d meshes of %d triangles (displaced UV spheres %dx%d), %d nodes on a %dx%d grid, %d materials:"
           " %zu triangles, %zu vertices placed%s\n",
           BI_MESHES, 2 * BI_NU * (BI_NV - 1), BI_NU, BI_NV, nnodes, side, side, BI_MATERIALS, tris, verts,
           unique ? "; glb: --unique, one mesh per node" : "");
    printf("files: %s; generated in %.2f s", dir, t_gen);
    if (do_glb)
        printf(", big.glb %.1f MiB written in %.2f s", file_mib(p_glb), t_wglb);
    if (do_obj)
        printf(", big.obj %.1f MiB + big.mtl written in %.2f s", file_mib(p_obj), t_wobj);
    printf("\n");
    long base_rss = self_maxrss_kib();
    printf("loads: %d per format, each format in its own process (peak RSS of that process; %.1f MiB at the fork)\n\n",
           repeat, base_rss / 1024.0);

    printf("%-6s %10s %9s %17s %10s %11s %13s %9s\n", "format", "triangles", "load s", "min-max s", "Mtris/s",
           "imp_load s", "scene side s", "peak RSS");
    int fail = 0;
    for (int f = 0; f < 2; f++) {
        if ((f == 0 && !do_glb) || (f == 1 && !do_obj))
            continue;
        const char *name = f == 0 ? "glb" : "obj";
        bi_result *r = xmalloc(sizeof *r);
        long rss = 0;
        if (run_child(f == 0 ? p_sglb : p_sobj, f == 0 ? p_glb : p_obj, repeat, r, &rss)) {
            fail = 1;
            free(r);
            continue;
        }
        if (!r->ok) {
            fprintf(stderr, "%s: %s: %s\n", bench_prog, name, r->msg);
            fail = 1;
            free(r);
            continue;
        }
        double lo = r->t_scene[0], hi = r->t_scene[0];
        for (int i = 1; i < repeat; i++)
            lo = fmin(lo, r->t_scene[i]), hi = fmax(hi, r->t_scene[i]);
        double med = median(r->t_scene, repeat), imed = median(r->t_imp, repeat);
        char range[64];
        snprintf(range, sizeof range, "%.3f-%.3f", lo, hi);
        printf("%-6s %10zu %9.3f %17s %10.3f %11.3f %13.3f %5.0f MiB\n", name, r->ntris, med, range,
               (double)r->ntris / med * 1e-6, imed, med - imed, rss / 1024.0);
        printf("       scene: %zu objects, %zu materials, %zu vertices (after welding); imp_load: %zu meshes, %zu "
               "triangles; %zu warning%s%s%s\n",
               r->nobjects, r->nmaterials, r->nverts, r->imp_meshes, r->imp_tris, r->warnings,
               r->warnings == 1 ? "" : "s", r->warnings ? ", first: " : "", r->warnings ? r->first_warning : "");
        fflush(stdout);
        free(r);
    }
    printf("\nload s: scene_load of the scene file, median of %d (min-max: fastest and slowest); Mtris/s: scene "
           "triangles / median;\nimp_load s: the importer alone (median of %d); scene side s: the difference.\n",
           repeat, repeat);

    if (keep) {
        printf("kept %s\n", dir);
    } else {
        unlink(p_glb), unlink(p_obj), unlink(p_mtl), unlink(p_sglb), unlink(p_sobj);
        if (rmdir(dir))
            fprintf(stderr, "%s: cannot remove %s: %s\n", bench_prog, dir, strerror(errno));
    }
    return fail;
}
