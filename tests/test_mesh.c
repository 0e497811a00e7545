/* test_mesh.c - mesh module: loading every format through OpenMesh, the
 * topology report, and refusing bad files cleanly.
 *
 * Text samples live in tests/data/meshes; binary files (PLY, STL) and every
 * broken file are written at run time into a temporary folder, so that what
 * each test feeds the loader is visible right here. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "mesh.h"

#define DATA RR_TEST_DATA "/meshes/"

/* The unit cube: 8 corners, 12 triangles wound counter-clockwise from outside. */
static const double cube_v[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                    {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
static const uint32_t cube_t[12][3] = {{0, 3, 2}, {0, 2, 1}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                                       {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};

static char tmpdir[256];
static mesh_tri *const UNTOUCHED = (mesh_tri *)&tmpdir; /* sentinel: never freed */

/* ---- helpers ---- */

static const char *tmp_path(const char *name)
{
    static char buf[8][512];
    static int next;
    char *p = buf[next++ % 8];
    snprintf(p, 512, "%s/%s", tmpdir, name);
    return p;
}

static const char *write_tmp(const char *name, const void *data, size_t n)
{
    const char *p = tmp_path(name);
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
    return p;
}

static unsigned char *read_whole(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc((size_t)len + 1);
    assert_non_null(buf);
    assert_int_equal(fread(buf, 1, (size_t)len, f), (size_t)len);
    fclose(f);
    buf[len] = '\0'; /* samples are searched with strstr */
    *n = (size_t)len;
    return buf;
}

/* Growable byte buffer for building binary files. */
typedef struct bytes {
    unsigned char d[8192];
    size_t n;
} bytes;

/* First occurrence of the text s in b (binary data may hold NUL bytes). */
static unsigned char *find(bytes *b, const char *s)
{
    size_t n = strlen(s);
    for (size_t i = 0; i + n <= b->n; i++)
        if (memcmp(b->d + i, s, n) == 0)
            return b->d + i;
    fail_msg("'%s' not found", s);
    return NULL;
}

static void put(bytes *b, const void *p, size_t n)
{
    assert_true(b->n + n <= sizeof b->d);
    memcpy(b->d + b->n, p, n);
    b->n += n;
}
static void put_str(bytes *b, const char *s) { put(b, s, strlen(s)); }
static void put_u32(bytes *b, uint32_t u, int big)
{
    unsigned char c[4];
    for (int i = 0; i < 4; i++)
        c[big ? 3 - i : i] = (unsigned char)(u >> (8 * i));
    put(b, c, 4);
}
static void put_f32(bytes *b, float f, int big)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(b, u, big);
}

/* Binary PLY of the cube (float x y z, optionally nx ny nz), triangles. */
static void cube_ply(bytes *b, int big, int normals, int nan_vertex)
{
    b->n = 0;
    put_str(b, big ? "ply\nformat binary_big_endian 1.0\n" : "ply\nformat binary_little_endian 1.0\n");
    put_str(b, "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n");
    if (normals)
        put_str(b, "property float nx\nproperty float ny\nproperty float nz\n");
    put_str(b, "element face 12\nproperty list uchar int vertex_indices\nend_header\n");
    for (int v = 0; v < 8; v++) {
        for (int k = 0; k < 3; k++)
            put_f32(b, v == nan_vertex && k == 1 ? NAN : (float)cube_v[v][k], big);
        for (int k = 0; k < 3 * normals; k++)
            put_f32(b, (float)(cube_v[v][k] - 0.5), big);
    }
    for (int t = 0; t < 12; t++) {
        unsigned char three = 3;
        put(b, &three, 1);
        for (int k = 0; k < 3; k++)
            put_u32(b, cube_t[t][k], big);
    }
}

/* Binary STL of the cube (always little endian). */
static void cube_stl(bytes *b, int nan_tri)
{
    b->n = 0;
    char header[80];
    memset(header, ' ', sizeof header);
    memcpy(header, "solid but binary", 16); /* legal, and a classic trap */
    put(b, header, 80);
    put_u32(b, 12, 0);
    for (int t = 0; t < 12; t++) {
        for (int k = 0; k < 3; k++)
            put_f32(b, 0.0f, 0);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                put_f32(b, t == nan_tri && c == 2 ? INFINITY : (float)cube_v[cube_t[t][c]][k], 0);
        put(b, "\0\0", 2);
    }
}

static mesh_tri *load_ok(const char *path)
{
    mesh_tri *m = NULL;
    rr_error err = {0};
    rr_status st = mesh_load(path, &m, &err);
    if (st != RR_OK)
        fail_msg("loading %s: %s", path, err.msg);
    assert_non_null(m);
    for (size_t i = 0; i < 3 * m->ntris; i++)
        assert_true(m->tris[i] < m->nverts);
    return m;
}

static void expect_closed(const mesh_tri *m, size_t nverts, size_t ntris)
{
    mesh_report r;
    assert_int_equal(mesh_analyze(m, &r, NULL), RR_OK);
    assert_int_equal(m->nverts, nverts);
    assert_int_equal(m->ntris, ntris);
    assert_int_equal(r.boundary_edges, 0);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.misoriented_edges, 0);
    assert_int_equal(r.degenerate_tris, 0);
    assert_true(r.watertight);
    assert_true(r.consistently_oriented);
}

/* The loader must fail, name the file, and leave *out alone. */
static rr_error expect_fail(const char *path)
{
    mesh_tri *m = UNTOUCHED;
    rr_error err = {0};
    rr_status st = mesh_load(path, &m, &err);
    if (st == RR_OK)
        fail_msg("%s loaded but should not have", path);
    assert_ptr_equal(m, UNTOUCHED);
    assert_int_equal(err.code, st);
    assert_true(strncmp(err.msg, path, strlen(path)) == 0);
    assert_null(strchr(err.msg, '\n'));
    return err;
}

static void expect_fail_with(const char *path, const char *words)
{
    rr_error err = expect_fail(path);
    if (!strstr(err.msg, words))
        fail_msg("'%s' does not mention '%s'", err.msg, words);
}

/* ---- loading, one test per format ---- */

static void test_obj_quads_triangulated(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(DATA "cube_quads.obj");
    expect_closed(m, 8, 12);
    assert_null(m->normals);
    double area = 0;
    for (size_t i = 0; i < m->ntris; i++)
        area += mesh_tri_area(m, i);
    assert_true(fabs(area - 6.0) < 1e-12);
    mesh_destroy(m);
}

static void test_obj_normals(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(DATA "tetra_normals.obj");
    expect_closed(m, 4, 4);
    assert_non_null(m->normals);
    for (size_t v = 0; v < 4; v++) {
        const double *n = m->normals + 3 * v;
        assert_true(fabs(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0) < 1e-6);
        /* each normal points away from the centroid (0.25, 0.25, 0.25) */
        const double *p = m->pos + 3 * v;
        assert_true(n[0] * (p[0] - 0.25) + n[1] * (p[1] - 0.25) + n[2] * (p[2] - 0.25) > 0);
    }
    mesh_destroy(m);
}

static void test_ply_ascii(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(DATA "cube_ascii.ply");
    expect_closed(m, 8, 12);
    assert_null(m->normals);
    mesh_destroy(m);
}

static void test_ply_binary(void **state)
{
    (void)state;
    bytes b;
    for (int big = 0; big <= 1; big++) {
        cube_ply(&b, big, 0, -1);
        mesh_tri *m = load_ok(write_tmp(big ? "be.ply" : "le.ply", b.d, b.n));
        expect_closed(m, 8, 12);
        assert_null(m->normals);
        for (int v = 0; v < 8; v++)
            for (int k = 0; k < 3; k++)
                assert_true(m->pos[3 * v + k] == cube_v[v][k]);
        mesh_destroy(m);
    }
    cube_ply(&b, 0, 1, -1);
    mesh_tri *m = load_ok(write_tmp("normals.ply", b.d, b.n));
    expect_closed(m, 8, 12);
    assert_non_null(m->normals);
    for (int k = 0; k < 3; k++) /* (0.5, 0.5, 0.5) normalised */
        assert_true(fabs(m->normals[3 * 6 + k] - 1.0 / sqrt(3.0)) < 1e-6);
    mesh_destroy(m);
}

static void test_off(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(DATA "cube.off");
    expect_closed(m, 8, 12);
    mesh_destroy(m);
}

static void test_stl_ascii(void **state)
{
    (void)state;
    /* STL repeats each corner per triangle; OpenMesh merges equal positions. */
    mesh_tri *m = load_ok(DATA "cube_ascii.stl");
    expect_closed(m, 8, 12);
    mesh_destroy(m);
}

static void test_stl_binary(void **state)
{
    (void)state;
    bytes b;
    cube_stl(&b, -1);
    mesh_tri *m = load_ok(write_tmp("cube.stl", b.d, b.n));
    expect_closed(m, 8, 12);
    assert_null(m->normals);
    mesh_destroy(m);
}

static void test_extension_case_insensitive(void **state)
{
    (void)state;
    size_t n;
    unsigned char *d = read_whole(DATA "cube_quads.obj", &n);
    mesh_tri *m = load_ok(write_tmp("CUBE.Obj", d, n));
    expect_closed(m, 8, 12);
    mesh_destroy(m);
    free(d);
}

static void test_concave_polygon_ear_clipped(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(DATA "concave_u.obj");
    assert_int_equal(m->ntris, 6);
    double area = 0;
    for (size_t i = 0; i < m->ntris; i++) {
        const uint32_t *t = m->tris + 3 * i;
        const double *a = m->pos + 3 * t[0], *b = m->pos + 3 * t[1], *c = m->pos + 3 * t[2];
        double z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert_true(z > 0); /* same winding as the polygon, none folded over */
        area += 0.5 * z;
    }
    assert_true(fabs(area - 5.0) < 1e-12); /* 3x2 minus the 1x1 notch */
    mesh_report r;
    assert_int_equal(mesh_analyze(m, &r, NULL), RR_OK);
    assert_int_equal(r.boundary_edges, 8);
    assert_int_equal(r.misoriented_edges, 0);
    mesh_destroy(m);
}

/* A 3,458-corner star (every other corner pulled in: half of them reflex),
 * in one OBJ face: ear-clipped whole (it used to be fanned past 1,024
 * corners, and a fan of a non-convex polygon folds triangles over each
 * other: the areas then add up to more than the polygon's), quickly (before
 * the cap it was cubic: over 300 s). */
static void test_huge_nonconvex_polygon(void **state)
{
    (void)state;
    enum { K = 3458 };
    size_t cap = (size_t)K * 96 + 16; /* a vertex line is at most 2 + 2 * 25 + 3 characters */
    char *text = malloc(cap);
    assert_non_null(text);
    size_t n = 0;
    double shoelace, px[K], py[K];
    for (int i = 0; i < K; i++) {
        double a = 2.0 * RR_PI * i / K, r = i % 2 ? 0.6 + 0.3 * ((i * 7919) % 101) / 101.0 : 1.0;
        px[i] = r * cos(a);
        py[i] = r * sin(a);
        n += (size_t)snprintf(text + n, cap - n, "v %.17g %.17g 0\n", px[i], py[i]);
    }
    n += (size_t)snprintf(text + n, cap - n, "f");
    for (int i = 0; i < K; i++) {
        n += (size_t)snprintf(text + n, cap - n, " %d", i + 1);
    }
    snprintf(text + n, cap - n, "\n");
    mesh_tri *m = load_ok(write_tmp("star.obj", text, strlen(text)));
    free(text);
    assert_int_equal(m->ntris, K - 2);
    double area = 0;
    for (size_t i = 0; i < m->ntris; i++) {
        const uint32_t *t = m->tris + 3 * i;
        const double *a = m->pos + 3 * t[0], *b = m->pos + 3 * t[1], *c = m->pos + 3 * t[2];
        double z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert_true(z > 0); /* none folded over */
        area += 0.5 * z;
    }
    /* The polygon's own area from the vertices as loaded (OpenMesh reads
     * floats), by the shoelace formula. */
    shoelace = 0;
    for (int i = 0; i < K; i++) {
        const double *a = m->pos + 3 * i, *b = m->pos + 3 * ((i + 1) % K);
        shoelace += 0.5 * (a[0] * b[1] - b[0] * a[1]);
    }
    if (!(fabs(area - shoelace) < 1e-9 * shoelace))
        fail_msg("triangles cover %.12g, the polygon is %.12g", area, shoelace);
    mesh_destroy(m);
}

/* ---- topology report (meshes built from arrays) ---- */

static mesh_tri *from_arrays(const double *pos, size_t nv, const uint32_t *tris, size_t nt)
{
    mesh_tri *m = NULL;
    rr_error err = {0};
    if (mesh_from_arrays(pos, nv, tris, nt, NULL, &m, &err) != RR_OK)
        fail_msg("mesh_from_arrays: %s", err.msg);
    return m;
}

static mesh_report analyze(const mesh_tri *m)
{
    mesh_report r;
    rr_error err = {0};
    assert_int_equal(mesh_analyze(m, &r, &err), RR_OK);
    return r;
}

static void test_open_quad(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t tris[] = {0, 1, 2, 0, 2, 3};
    mesh_tri *m = from_arrays(pos, 4, tris, 2);
    mesh_report r = analyze(m);
    assert_int_equal(r.boundary_edges, 4);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.misoriented_edges, 0);
    assert_false(r.watertight);
    assert_true(r.consistently_oriented);
    assert_true(fabs(mesh_tri_area(m, 0) - 0.5) < 1e-15);
    mesh_destroy(m);
}

static void test_nonmanifold_edge(void **state)
{
    (void)state;
    /* Three triangles on the edge 0-1 (a "book" with three pages). */
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1};
    const uint32_t tris[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    mesh_tri *m = from_arrays(pos, 5, tris, 3);
    mesh_report r = analyze(m);
    assert_int_equal(r.nonmanifold_edges, 1);
    assert_int_equal(r.boundary_edges, 6);
    assert_false(r.watertight);
    mesh_destroy(m);
}

static void test_misoriented(void **state)
{
    (void)state;
    /* Both triangles walk 0 -> 1: one of them is flipped. */
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0};
    const uint32_t tris[] = {0, 1, 2, 0, 1, 3};
    mesh_tri *m = from_arrays(pos, 4, tris, 2);
    mesh_report r = analyze(m);
    assert_int_equal(r.misoriented_edges, 1);
    assert_int_equal(r.boundary_edges, 4);
    assert_false(r.consistently_oriented);
    mesh_destroy(m);

    /* A closed cube with one triangle flipped: still watertight, not oriented. */
    uint32_t t[12][3];
    memcpy(t, cube_t, sizeof t);
    uint32_t s = t[5][1];
    t[5][1] = t[5][2];
    t[5][2] = s;
    m = from_arrays(&cube_v[0][0], 8, &t[0][0], 12);
    r = analyze(m);
    assert_true(r.watertight);
    assert_int_equal(r.misoriented_edges, 3);
    assert_false(r.consistently_oriented);
    mesh_destroy(m);
}

static void test_degenerate(void **state)
{
    (void)state;
    /* Vertex 3 duplicates vertex 1's position: triangle (0,1,3) repeats a
     * vertex once welded; (0,1,4) is collinear; (0,1,2) is fine. */
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 2, 0, 0};
    const uint32_t tris[] = {0, 1, 2, 0, 1, 3, 0, 1, 4, 2, 2, 1};
    mesh_tri *m = from_arrays(pos, 5, tris, 4);
    mesh_report r = analyze(m);
    assert_int_equal(r.degenerate_tris, 3);
    assert_true(mesh_tri_area(m, 2) == 0.0);
    mesh_destroy(m);
}

static void test_weld_triangle_soup(void **state)
{
    (void)state;
    /* The cube with every triangle on its own three vertices, as STL stores
     * it: welding by position must still find it closed. */
    double pos[36 * 3];
    uint32_t tris[36];
    for (int t = 0; t < 12; t++)
        for (int c = 0; c < 3; c++) {
            memcpy(pos + 3 * (3 * t + c), cube_v[cube_t[t][c]], 3 * sizeof(double));
            tris[3 * t + c] = (uint32_t)(3 * t + c);
        }
    mesh_tri *m = from_arrays(pos, 36, tris, 12);
    mesh_report r = analyze(m);
    assert_true(r.watertight);
    assert_true(r.consistently_oriented);
    assert_int_equal(r.degenerate_tris, 0);
    mesh_destroy(m);
}

static void test_large_grid(void **state)
{
    (void)state;
    /* 512 x 512 quads = 524288 triangles: an open sheet with 4 * 512
     * boundary edges. Quadratic code would not finish in time. */
    enum { N = 512 };
    size_t nv = (N + 1) * (N + 1), nt = 2 * (size_t)N * N;
    double *pos = malloc(3 * nv * sizeof *pos);
    uint32_t *tris = malloc(3 * nt * sizeof *tris);
    assert_non_null(pos);
    assert_non_null(tris);
    for (size_t y = 0; y <= N; y++)
        for (size_t x = 0; x <= N; x++) {
            double *p = pos + 3 * (y * (N + 1) + x);
            p[0] = (double)x;
            p[1] = (double)y;
            p[2] = 0;
        }
    uint32_t *t = tris;
    for (uint32_t y = 0; y < N; y++)
        for (uint32_t x = 0; x < N; x++) {
            uint32_t a = y * (N + 1) + x, b = a + 1, c = a + N + 2, d = a + N + 1;
            uint32_t q[6] = {a, b, c, a, c, d};
            memcpy(t, q, sizeof q);
            t += 6;
        }
    mesh_tri *m = from_arrays(pos, nv, tris, nt);
    mesh_report r = analyze(m);
    assert_int_equal(r.boundary_edges, 4 * N);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.misoriented_edges, 0);
    mesh_destroy(m);
    free(pos);
    free(tris);
}

static void test_from_arrays_rejects(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const double bad[] = {0, 0, 0, 1, NAN, 0, 0, 1, 0};
    const double zero_n[] = {0, 0, 1, 0, 0, 0, 0, 0, 1};
    const uint32_t ok[] = {0, 1, 2}, oob[] = {0, 1, 3};
    mesh_tri *m = UNTOUCHED;
    rr_error err = {0};
    assert_int_not_equal(mesh_from_arrays(pos, 3, oob, 1, NULL, &m, &err), RR_OK);
    assert_non_null(strstr(err.msg, "vertex 3"));
    assert_int_not_equal(mesh_from_arrays(bad, 3, ok, 1, NULL, &m, &err), RR_OK);
    assert_non_null(strstr(err.msg, "vertex 1 has a non-finite coordinate"));
    assert_int_not_equal(mesh_from_arrays(pos, 3, ok, 1, zero_n, &m, &err), RR_OK);
    assert_ptr_equal(m, UNTOUCHED);
    /* normals are copied and normalised */
    const double n[] = {0, 0, 2, 0, 0, 3, 0, 0, 0.5};
    assert_int_equal(mesh_from_arrays(pos, 3, ok, 1, n, &m, &err), RR_OK);
    for (int v = 0; v < 3; v++)
        assert_true(m->normals[3 * v + 2] == 1.0);
    mesh_destroy(m);
}

static void test_destroy_null(void **state)
{
    (void)state;
    mesh_destroy(NULL);
    mesh_report r;
    assert_int_not_equal(mesh_analyze(NULL, &r, NULL), RR_OK);
}

/* ---- files that must be refused ---- */

static const char *const exts[] = {"obj", "ply", "off", "stl"};

static void test_missing_and_empty(void **state)
{
    (void)state;
    char name[64];
    for (int i = 0; i < 4; i++) {
        snprintf(name, sizeof name, "missing.%s", exts[i]);
        expect_fail_with(tmp_path(name), "file does not exist");
        snprintf(name, sizeof name, "empty.%s", exts[i]);
        expect_fail_with(write_tmp(name, "", 0), "empty file");
    }
    expect_fail_with(tmpdir, "unknown mesh format"); /* a folder has no extension */
    mkdir(tmp_path("folder.obj"), 0700);
    expect_fail_with(tmp_path("folder.obj"), "not a regular file");
}

static void test_unknown_extension(void **state)
{
    (void)state;
    expect_fail_with(write_tmp("cube.xyz", "v 0 0 0\n", 8), "unknown mesh format '.xyz'");
    expect_fail_with(write_tmp("noext", "v 0 0 0\n", 8), "unknown mesh format");
    expect_fail_with(write_tmp("cube.obj.bak", "v 0 0 0\n", 8), "unknown mesh format");
}

/* The samples the refusal tests start from: name and bytes. */
typedef struct sample {
    const char *name; /* with the extension the loader dispatches on */
    unsigned char *d;
    size_t n;
    int counted;      /* the format announces its size: every cut is detectable */
    size_t complete;  /* a cut at least this long still holds all the data */
} sample;

static int load_samples(sample *s)
{
    static const char *const text[] = {"cube_quads.obj", "cube_ascii.ply", "cube.off", "cube_ascii.stl"};
    int k = 0;
    for (int i = 0; i < 4; i++, k++) {
        char path[512];
        snprintf(path, sizeof path, DATA "%s", text[i]);
        s[k].name = text[i];
        s[k].d = read_whole(path, &s[k].n);
        s[k].counted = i != 0; /* OBJ has no counts: a cut between lines is a smaller valid file */
        s[k].complete = s[k].n - 1;
        char *end = strstr((char *)s[k].d, "endsolid");
        if (end) /* "endsolid" names the solid again: cutting that name loses nothing */
            s[k].complete = (size_t)((unsigned char *)end - s[k].d) + 8;
    }
    bytes b;
    cube_ply(&b, 0, 1, -1);
    s[k] = (sample){"cube_bin.ply", malloc(b.n), b.n, 1, b.n};
    memcpy(s[k++].d, b.d, b.n);
    cube_stl(&b, -1);
    s[k] = (sample){"cube_bin.stl", malloc(b.n), b.n, 1, b.n};
    memcpy(s[k++].d, b.d, b.n);
    return k;
}

static void free_samples(sample *s, int n)
{
    for (int i = 0; i < n; i++)
        free(s[i].d);
}

static void test_truncated(void **state)
{
    (void)state;
    sample s[6];
    int ns = load_samples(s);
    char name[64];
    for (int i = 0; i < ns; i++) {
        /* Cut inside the last record: every format notices that one. */
        snprintf(name, sizeof name, "cut_%s", s[i].name);
        expect_fail_with(write_tmp(name, s[i].d, s[i].complete - 5), "truncated");
        /* Every other cut must fail cleanly, or (OBJ only) load a valid mesh. */
        for (size_t n = 1; n + 1 < s[i].n; n++) {
            const char *p = write_tmp(name, s[i].d, n);
            mesh_tri *m = UNTOUCHED;
            rr_error err = {0};
            if (mesh_load(p, &m, &err) == RR_OK) {
                if (s[i].counted && n < s[i].complete)
                    fail_msg("%s cut to %zu bytes loaded", s[i].name, n);
                for (size_t t = 0; t < 3 * m->ntris; t++)
                    assert_true(m->tris[t] < m->nverts);
                mesh_destroy(m);
            } else {
                assert_ptr_equal(m, UNTOUCHED);
                assert_true(strncmp(err.msg, p, strlen(p)) == 0);
            }
        }
    }
    free_samples(s, ns);
}

/* Deterministic pseudo-random bytes (the test must not depend on a seed). */
static uint32_t lcg(uint32_t *x)
{
    *x = *x * 1664525u + 1013904223u;
    return *x >> 8;
}

static void test_garbage(void **state)
{
    (void)state;
    uint32_t seed = 12345;
    unsigned char buf[600];
    char name[64];
    for (int e = 0; e < 4; e++)
        for (int i = 0; i < 25; i++) {
            size_t n = 1 + lcg(&seed) % sizeof buf;
            for (size_t k = 0; k < n; k++)
                buf[k] = (unsigned char)lcg(&seed);
            snprintf(name, sizeof name, "garbage%d.%s", i, exts[e]);
            expect_fail(write_tmp(name, buf, n));
        }
    /* A valid header followed by garbage, too short to hold the data. */
    bytes b;
    cube_ply(&b, 0, 0, -1);
    size_t header = (size_t)(find(&b, "end_header\n") - b.d) + 11;
    for (int i = 0; i < 25; i++) {
        size_t n = header + lcg(&seed) % (b.n - header);
        for (size_t k = header; k < n; k++)
            b.d[k] = (unsigned char)lcg(&seed);
        expect_fail(write_tmp("header_garbage.ply", b.d, n));
    }
    const char solid[] = "solid x\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\n";
    memcpy(buf, solid, sizeof solid - 1);
    for (size_t k = sizeof solid - 1; k < 200; k++)
        buf[k] = (unsigned char)lcg(&seed);
    expect_fail(write_tmp("solid_garbage.stl", buf, 200));
}

/* Random byte flips in valid files: anything may happen except a crash, a
 * hang, an invalid mesh or a message that does not name the file. */
static void test_mutations(void **state)
{
    (void)state;
    sample s[6];
    int ns = load_samples(s);
    uint32_t seed = 777;
    char name[64];
    for (int i = 0; i < ns; i++)
        for (int r = 0; r < 60; r++) {
            unsigned char *d = malloc(s[i].n);
            memcpy(d, s[i].d, s[i].n);
            int flips = 1 + (int)(lcg(&seed) % 4);
            for (int f = 0; f < flips; f++)
                d[lcg(&seed) % s[i].n] = (unsigned char)lcg(&seed);
            snprintf(name, sizeof name, "mut_%s", s[i].name);
            const char *p = write_tmp(name, d, s[i].n);
            mesh_tri *m = UNTOUCHED;
            rr_error err = {0};
            if (mesh_load(p, &m, &err) == RR_OK) {
                for (size_t t = 0; t < 3 * m->ntris; t++)
                    assert_true(m->tris[t] < m->nverts);
                mesh_report rep;
                assert_int_equal(mesh_analyze(m, &rep, NULL), RR_OK);
                mesh_destroy(m);
            } else {
                assert_ptr_equal(m, UNTOUCHED);
                assert_true(strncmp(err.msg, p, strlen(p)) == 0);
            }
            free(d);
        }
    free_samples(s, ns);
}

static const char *write_text(const char *name, const char *text) { return write_tmp(name, text, strlen(text)); }

#define PLY_TRI_HEADER                                                                                          \
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"          \
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"

static void test_non_finite(void **state)
{
    (void)state;
    expect_fail_with(write_text("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"),
                     "vertex 1 has a non-finite coordinate");
    expect_fail_with(write_text("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1e999\nf 1 2 3\n"),
                     "vertex 2 has a non-finite coordinate");
    expect_fail_with(write_text("huge.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1e300\nf 1 2 3\n"),
                     "vertex 2 has a coordinate beyond single precision");
    expect_fail_with(write_text("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 NaN 0\n3 0 1 2\n"),
                     "vertex 2 has a non-finite coordinate");
    expect_fail_with(write_text("nan.ply", PLY_TRI_HEADER "0 0 0\n1 0 0\n0 1 -inf\n3 0 1 2\n"),
                     "vertex 2 has a non-finite coordinate");
    expect_fail_with(write_text("nan.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex nan 0 0\n"
                                           "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n"),
                     "non-finite coordinate");
    bytes b;
    cube_ply(&b, 1, 0, 5);
    expect_fail_with(write_tmp("nan_bin.ply", b.d, b.n), "vertex 5 has a non-finite coordinate");
    cube_stl(&b, 7);
    expect_fail_with(write_tmp("inf_bin.stl", b.d, b.n), "triangle 7 has a non-finite coordinate");
}

static void test_bad_indices_and_no_faces(void **state)
{
    (void)state;
    expect_fail_with(write_text("idx.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"), "vertex 9");
    expect_fail_with(write_text("idx0.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"), "bad face corner '0'");
    expect_fail_with(write_text("idx.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"), "vertex 3");
    expect_fail_with(write_text("idx.ply", PLY_TRI_HEADER "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"), "vertex 7");
    expect_fail_with(write_text("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"), "no triangles");
    expect_fail_with(write_text("points.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n"), "no triangles");
    expect_fail_with(write_text("nofaces.stl", "solid t\nendsolid t\n"), "no triangles");
    /* OpenMesh would read this binary PLY from the wrong offset. */
    bytes b;
    cube_ply(&b, 0, 0, -1);
    unsigned char *e = find(&b, "end_header");
    bytes c = {.n = 0};
    put(&c, b.d, (size_t)(e - b.d));
    put_str(&c, "comment here\n");
    put(&c, e, b.n - (size_t)(e - b.d));
    expect_fail_with(write_tmp("comment.ply", c.d, c.n), "end_header");
}

/* Faces OpenMesh's importer would rebuild on copied vertices (a third face on
 * an edge, a flipped neighbour) must reach the report as they are in the file. */
static void test_loaded_topology_kept(void **state)
{
    (void)state;
    mesh_tri *m = load_ok(write_text("book.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                                 "f 1 2 3\nf 2 1 4\nf 1 2 5\n"));
    assert_int_equal(m->nverts, 5);
    mesh_report r = analyze(m);
    assert_int_equal(r.nonmanifold_edges, 1);
    mesh_destroy(m);
    m = load_ok(write_text("flip.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                       "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                                       "end_header\n0 0 0\n1 0 0\n0 1 0\n0 -1 0\n3 0 1 2\n3 0 1 3\n"));
    assert_int_equal(m->nverts, 4);
    r = analyze(m);
    assert_int_equal(r.misoriented_edges, 1);
    mesh_destroy(m);
    /* A face repeating a vertex is kept (and reported), not dropped. */
    m = load_ok(write_text("rep.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 0 1\n"));
    assert_int_equal(m->ntris, 2);
    r = analyze(m);
    assert_int_equal(r.degenerate_tris, 1);
    mesh_destroy(m);
}

/* ---- fixture ---- */

static int setup(void **state)
{
    (void)state;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/radray_test_mesh_XXXXXX");
    return mkdtemp(tmpdir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    return system(cmd) == 0 ? 0 : -1;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_obj_quads_triangulated),
        cmocka_unit_test(test_obj_normals),
        cmocka_unit_test(test_ply_ascii),
        cmocka_unit_test(test_ply_binary),
        cmocka_unit_test(test_off),
        cmocka_unit_test(test_stl_ascii),
        cmocka_unit_test(test_stl_binary),
        cmocka_unit_test(test_extension_case_insensitive),
        cmocka_unit_test(test_concave_polygon_ear_clipped),
        cmocka_unit_test(test_huge_nonconvex_polygon),
        cmocka_unit_test(test_open_quad),
        cmocka_unit_test(test_nonmanifold_edge),
        cmocka_unit_test(test_misoriented),
        cmocka_unit_test(test_degenerate),
        cmocka_unit_test(test_weld_triangle_soup),
        cmocka_unit_test(test_large_grid),
        cmocka_unit_test(test_from_arrays_rejects),
        cmocka_unit_test(test_destroy_null),
        cmocka_unit_test(test_missing_and_empty),
        cmocka_unit_test(test_unknown_extension),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_garbage),
        cmocka_unit_test(test_mutations),
        cmocka_unit_test(test_non_finite),
        cmocka_unit_test(test_bad_indices_and_no_faces),
        cmocka_unit_test(test_loaded_topology_kept),
    };
    /* A reader stuck in a loop must fail the test, not hang the suite. */
    alarm(300);
    return cmocka_run_group_tests(tests, setup, teardown);
}
