/* imp_obj.c - Wavefront .obj: the material libraries read and checked here,
 * line by line, the geometry read by Assimp (imp_assimp.c).
 *
 * Assimp 5.2 reads .mtl files leniently: a missing library falls back to
 * another file, an unknown statement or a number it cannot read is skipped,
 * a usemtl without a material becomes a new grey one. Each of those is a
 * scene that renders wrong without a word, so radray reads the .mtl files
 * itself (every statement known, every number checked, every usemtl
 * resolved) and takes the materials from here by name; Assimp supplies only
 * the triangles and which material each group uses.
 */
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "imp_internal.h"

/* One newmtl block as written. */
typedef struct mtl_entry {
    char name[IMP_NAME_MAX];
    char file[4096]; /* the .mtl it is in, and the line of its newmtl */
    size_t line;
    int has_kd;
    rr_rgb kd, ks, ke;
    double ns, d, tr;
    int illum;            /* -1: not given */
    char map_kd[4096];    /* resolved path, "" when none */
    int other_maps;       /* map_Ks, bump, norm, ... */
} mtl_entry;

typedef struct imp__mtl {
    mtl_entry *e;
    size_t n, cap;
} imp__mtl;

/* Statements of the .mtl format (Wavefront's, plus the PBR extension's)
 * that radray knows; anything else in a file is an error. */
static const char *const k_known[] = {
    "newmtl", "Ka", "Kd", "Ks", "Ke", "Tf", "Ns", "Ni", "d", "Tr", "illum", "sharpness", "Pr", "Pm", "Ps", "Pc",
    "Pcr", "aniso", "anisor", "map_Ka", "map_Kd", "map_Ks", "map_Ke", "map_Ns", "map_d", "map_Tr", "map_bump",
    "map_Bump", "bump", "disp", "decal", "refl", "norm", "map_Pr", "map_Pm", "map_Ps", "map_refl", "map_Disp", NULL};

typedef struct mtl_reader {
    const char *file;
    size_t line;
    mtl_entry *cur;
    rr_error *err;
} mtl_reader;

static rr_status bad(const mtl_reader *r, const char *fmt, const char *a, const char *b)
{
    char what[512];
    snprintf(what, sizeof what, fmt, a, b);
    if (r->cur)
        return rr_error_set(r->err, RR_ERR_INVALID, "%s:%zu: material '%s': %s", r->file, r->line, r->cur->name, what);
    return rr_error_set(r->err, RR_ERR_INVALID, "%s:%zu: %s", r->file, r->line, what);
}

/* Splits s in place into at most max tokens; returns the count. */
static int tokens(char *s, char **tok, int max)
{
    int n = 0;
    while (*s) {
        while (*s && isspace((unsigned char)*s))
            s++;
        if (!*s)
            break;
        if (n == max)
            return max + 1;
        tok[n++] = s;
        while (*s && !isspace((unsigned char)*s))
            s++;
        if (*s)
            *s++ = '\0';
    }
    return n;
}

/* s without leading and trailing white space (cut in place). */
static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    for (char *e = s + strlen(s); e > s && isspace((unsigned char)e[-1]);)
        *--e = '\0';
    return s;
}

/* Cuts the next line off *cur (NULL at the end): lines end at \n, \r\n,
 * a lone \r or \f, as Assimp's OBJ and MTL readers end them, so that both
 * see the same lines (a statement after a lone \r is not hidden in a
 * comment from one of them). */
static char *next_line(char **cur)
{
    char *line = *cur;
    if (!line)
        return NULL;
    char *e = line + strcspn(line, "\n\r\f");
    if (!*e) {
        *cur = NULL;
    } else {
        *cur = e + 1 + (e[0] == '\r' && e[1] == '\n');
        *e = '\0';
    }
    return line;
}

/* A text file of radray's readers: NUL bytes are refused (Assimp reads past
 * them where a C string stops). */
static rr_status read_text(const char *path, char **text, size_t *size, rr_error *err)
{
    rr_status st = rr_file_read_all(path, text, size, err);
    if (st != RR_OK)
        return st;
    size_t len = strlen(*text);
    if (len != *size) {
        free(*text);
        *text = NULL;
        return rr_error_set(err, RR_ERR_PARSE, "%s: the file contains a NUL byte at offset %zu (not a text file?)",
                            path, len);
    }
    return RR_OK;
}

static int number(const char *s, double *out)
{
    char *end;
    *out = strtod(s, &end);
    return end != s && *end == '\0' && isfinite(*out);
}

/* "Kd r [g b]": one number is grey. lo/hi bound each channel. */
static rr_status colour(const mtl_reader *r, char **tok, int n, double hi, rr_rgb *out)
{
    double v[3];
    if (n == 2 || n == 4) {
        for (int k = 0; k + 1 < n; k++)
            if (!number(tok[k + 1], &v[k]))
                return bad(r, "%s: '%s' is not a finite number", tok[0], tok[k + 1]);
        if (n == 2)
            v[1] = v[2] = v[0];
    } else if (n > 1 && (strcmp(tok[1], "spectral") == 0 || strcmp(tok[1], "xyz") == 0)) {
        return bad(r, "%s %s: only RGB colours are supported", tok[0], tok[1]);
    } else {
        return bad(r, "%s: expected 1 or 3 numbers%s", tok[0], "");
    }
    for (int k = 0; k < 3; k++)
        if (v[k] < 0 || v[k] > hi) {
            char lim[64];
            snprintf(lim, sizeof lim, hi > 1e300 ? ">= 0" : "in [0, %g]", hi);
            return bad(r, "%s: each channel must be %s", tok[0], lim);
        }
    *out = rr_rgb_make(v[0], v[1], v[2]);
    return RR_OK;
}

static rr_status scalar(const mtl_reader *r, char **tok, int n, double lo, double hi, double *out)
{
    if (n != 2 || !number(tok[1], out))
        return bad(r, "%s: expected one finite number%s", tok[0], "");
    if (*out < lo || *out > hi) {
        char lim[64];
        snprintf(lim, sizeof lim, hi > 1e300 ? ">= %g" : "in [%g, %g]", lo, hi);
        char msg[96];
        snprintf(msg, sizeof msg, "%%s: %s (got %%s)", lim);
        return bad(r, msg, tok[0], tok[1]);
    }
    return RR_OK;
}

/* name: the rest of the newmtl line, trimmed (names may hold spaces, as
 * usemtl's do). */
static rr_status new_material(mtl_reader *r, imp__mtl *lib, const char *name)
{
    r->cur = NULL;
    if (!*name)
        return bad(r, "newmtl without a name%s%s", "", "");
    if (strlen(name) >= IMP_NAME_MAX)
        return bad(r, "newmtl '%.40s...': the name is longer than %s bytes", name, "63");
    for (size_t i = 0; i < lib->n; i++)
        if (strcmp(lib->e[i].name, name) == 0)
            return bad(r, "material '%s' is defined twice (first in %.400s)", name, lib->e[i].file);
    if (lib->n == lib->cap) {
        size_t cap = lib->cap ? 2 * lib->cap : 16;
        mtl_entry *e = realloc(lib->e, cap * sizeof *e);
        if (!e)
            return rr_error_set(r->err, RR_ERR_NOMEM, "%s: out of memory", r->file);
        lib->e = e, lib->cap = cap;
    }
    mtl_entry *e = &lib->e[lib->n++];
    memset(e, 0, sizeof *e);
    imp__name(e->name, name, "material", lib->n - 1);
    snprintf(e->file, sizeof e->file, "%s", r->file);
    e->line = r->line;
    e->kd = rr_rgb_make(0.5, 0.5, 0.5);
    e->d = 1;
    e->illum = -1;
    r->cur = e;
    return RR_OK;
}

/* One statement of the current material. */
static rr_status statement(mtl_reader *r, char **tok, int n, const char *dir)
{
    mtl_entry *e = r->cur;
    const char *k = tok[0];
    if (strcmp(k, "Kd") == 0)
        return e->has_kd = 1, colour(r, tok, n, 1, &e->kd);
    if (strcmp(k, "Ks") == 0)
        return colour(r, tok, n, INFINITY, &e->ks);
    if (strcmp(k, "Ke") == 0)
        return colour(r, tok, n, INFINITY, &e->ke);
    if (strcmp(k, "Ka") == 0 || strcmp(k, "Tf") == 0) {
        rr_rgb ignored;
        return colour(r, tok, n, INFINITY, &ignored);
    }
    if (strcmp(k, "Ns") == 0)
        return scalar(r, tok, n, 0, INFINITY, &e->ns);
    if (strcmp(k, "d") == 0) /* "d -halo 0.5" is the halo form */
        return scalar(r, n == 3 && strcmp(tok[1], "-halo") == 0 ? tok + 1 : tok, n == 3 ? 2 : n, 0, 1, &e->d);
    if (strcmp(k, "Tr") == 0)
        return scalar(r, tok, n, 0, 1, &e->tr);
    if (strcmp(k, "illum") == 0) {
        double v;
        rr_status st = scalar(r, tok, n, 0, 10, &v);
        if (st == RR_OK && v != floor(v))
            return bad(r, "illum: expected an integer 0..10 (got %s)%s", tok[1], "");
        e->illum = (int)v;
        return st;
    }
    if (strncmp(k, "map_", 4) == 0 || strcmp(k, "bump") == 0 || strcmp(k, "disp") == 0 ||
        strcmp(k, "decal") == 0 || strcmp(k, "refl") == 0 || strcmp(k, "norm") == 0) {
        if (n < 2)
            return bad(r, "%s without a file name%s", k, "");
        if (strcmp(k, "map_Kd") != 0) {
            e->other_maps = 1;
            return RR_OK;
        }
        /* Options (-s 1 1 1, -clamp on, ...) come first; the file is last. */
        rr_error jerr;
        if (rr_path_join(dir, tok[n - 1], e->map_kd, sizeof e->map_kd, &jerr) != RR_OK)
            return bad(r, "map_Kd: %.480s%s", jerr.msg, "");
        return RR_OK;
    }
    double v; /* Ni, sharpness and the PBR numbers: read, checked, not used */
    if (strcmp(k, "Ni") == 0 || strcmp(k, "sharpness") == 0 || strcmp(k, "Pr") == 0 || strcmp(k, "Pm") == 0 ||
        strcmp(k, "Ps") == 0 || strcmp(k, "Pc") == 0 || strcmp(k, "Pcr") == 0 || strcmp(k, "aniso") == 0 ||
        strcmp(k, "anisor") == 0)
        return scalar(r, tok, n, 0, INFINITY, &v);
    return RR_OK;
}

static int known(const char *k)
{
    for (int i = 0; k_known[i]; i++)
        if (strcmp(k_known[i], k) == 0)
            return 1;
    return 0;
}

static rr_status read_mtl(const char *path, imp__mtl *lib, rr_error *err)
{
    char *text = NULL, dir[4096];
    size_t size = 0;
    rr_status st = read_text(path, &text, &size, err);
    if (st != RR_OK)
        return st;
    rr_path_dirname(path, dir, sizeof dir);
    mtl_reader r = {path, 0, NULL, err};
    char *cur = text, *line;
    while (st == RR_OK && (line = next_line(&cur))) {
        r.line++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *name = trim(line);
        if (strncmp(name, "newmtl", 6) == 0 && (isspace((unsigned char)name[6]) || !name[6])) {
            st = new_material(&r, lib, trim(name + 6));
            continue;
        }
        char *tok[32];
        int n = tokens(line, tok, 30);
        if (n == 0)
            continue;
        if (!known(tok[0]))
            st = bad(&r, "unknown statement '%.40s'%s", tok[0], r.cur ? "" : " (before any newmtl)");
        else if (!r.cur)
            st = bad(&r, "'%s' before any newmtl%s", tok[0], "");
        else
            st = statement(&r, tok, n > 30 ? 30 : n, dir);
    }
    free(text);
    return st;
}

/* The .obj's mtllib and usemtl lines: every library must exist and read
 * cleanly, every usemtl must name one of their materials. text is cut
 * into lines; in assimp_text (a copy of it) every mtllib line becomes a
 * comment, so that Assimp never reads a material library (radray's
 * materials replace its by name; its .mtl reader has crashed on input
 * radray refuses). */
static rr_status scan_obj(const char *path, char *text, char *assimp_text, imp__mtl *lib, rr_error *err)
{
    char dir[4096];
    size_t lineno = 0;
    rr_status st = RR_OK;
    rr_path_dirname(path, dir, sizeof dir);
    int libs = 0;
    char *cur = text, *line;
    while (st == RR_OK && (line = next_line(&cur))) {
        lineno++;
        char *p = line;
        while (*p == ' ' || *p == '\t')
            p++;
        int is_lib = strncmp(p, "mtllib", 6) == 0 && (isspace((unsigned char)p[6]) || !p[6]);
        int is_use = strncmp(p, "usemtl", 6) == 0 && (isspace((unsigned char)p[6]) || !p[6]);
        if (!is_lib && !is_use)
            continue;
        char *name = trim(p + 6);
        if (is_lib) {
            char file[4096];
            libs++;
            assimp_text[p - text] = '#';
            if ((st = rr_path_join(dir, name, file, sizeof file, err)) == RR_OK &&
                (st = rr_file_check_regular(file, err)) != RR_OK)
                st = rr_error_set(err, RR_ERR_IO, "%s:%zu: mtllib '%s': the material library is missing (%s)", path,
                                  lineno, name, file);
            if (st == RR_OK)
                st = read_mtl(file, lib, err);
            continue;
        }
        size_t i = 0;
        while (i < lib->n && strcmp(lib->e[i].name, name) != 0)
            i++;
        if (i == lib->n)
            st = rr_error_set(err, RR_ERR_INVALID, "%s:%zu: usemtl '%s': no such material in %s", path, lineno, name,
                              libs ? "the material libraries (mtllib) read so far" : "the file (it has no mtllib)");
    }
    return st;
}

/* The MTL mapping (notes/import.md): illum 3..9 reflect (the mirror is Ks),
 * so does a Ks whose Ns is 1000 or more (exporters write a polished surface
 * so); illum 2 and no illum are Phong (Ks, Ns); illum 0 and 1 have no
 * highlight. */
static void map_entry(const mtl_entry *e, imp_material *x)
{
    imp__name(x->name, e->name, "material", 0);
    x->diffuse = e->kd;
    x->emission = e->ke;
    x->k = 1;
    if (e->map_kd[0])
        imp__texture_mean(e->map_kd, x);
    if (e->other_maps)
        x->notes |= IMP_NOTE_TEXTURE_DROP;
    int ill = e->illum;
    int reflects = (ill >= 3 && ill <= 9) || (rr_rgb_max(e->ks) > 0 && e->ns >= 1000);
    if (reflects) {
        x->mirror = rr_rgb_make(fmin(e->ks.r, 1), fmin(e->ks.g, 1), fmin(e->ks.b, 1));
        double *d[3] = {&x->diffuse.r, &x->diffuse.g, &x->diffuse.b};
        double m[3] = {x->mirror.r, x->mirror.g, x->mirror.b};
        for (int k = 0; k < 3; k++)
            if (*d[k] + m[k] > 1) {
                *d[k] = 1 - m[k];
                x->notes |= IMP_NOTE_CLAMPED;
            }
    } else if (ill == 2 || ill < 0) {
        x->specular = e->ks;
        x->k = e->ns;
    }
    if (ill == 0)
        x->notes |= IMP_NOTE_UNLIT;
    if (e->d < 1 || e->tr > 0 || ill == 4 || ill == 6 || ill == 7 || ill == 9)
        x->notes |= IMP_NOTE_TRANSPARENT;
}

int imp__mtl_material(const imp__mtl *mtl, const char *name, imp_material *out)
{
    for (size_t i = 0; i < mtl->n; i++)
        if (strcmp(mtl->e[i].name, name) == 0) {
            memset(out, 0, sizeof *out);
            map_entry(&mtl->e[i], out);
            return 1;
        }
    return 0;
}

rr_status imp__load_obj(const char *path, imp_model *m, rr_error *err)
{
    imp__mtl lib = {NULL, 0, 0};
    char *text = NULL, *copy = NULL;
    size_t size = 0;
    rr_status st = read_text(path, &text, &size, err);
    if (st == RR_OK && !(copy = malloc(size + 1)))
        st = rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory", path);
    if (st == RR_OK) {
        memcpy(copy, text, size + 1);
        st = scan_obj(path, text, copy, &lib, err);
    }
    free(text);
    if (st == RR_OK)
        st = imp__load_assimp(path, copy, size, &lib, m, err);
    free(copy);
    free(lib.e);
    return st;
}
