/* output.c - what a command writes, checked before any work and committed
 * at the end (notes/hardening.md, "Outputs"):
 *  - no output may name an input (the scene, its mesh files, the radiosity
 *    cache) or another output: refused before any work, nothing created;
 *  - folders are created only when the files are written;
 *  - the EXR and its PNG preview are one commit: both are written to hidden
 *    temporaries first, then renamed into place while holding a lock on the
 *    folder, so both or neither replace the old pair, and two renders to one
 *    output leave one render's pair. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app.h"
#include "img.h"

/* Absolute, normalised name of a path that may not exist yet: the real path
 * of its longest existing prefix, then the rest as given. */
static void canonical(const char *path, char *out, size_t n)
{
    char dir[4096], tail[4096] = "", t[8200], real[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    struct stat st;
    while (stat(dir, &st) != 0) {
        char *slash = strrchr(dir, '/');
        snprintf(t, sizeof t, "%s%s%s", slash ? slash + 1 : dir, tail[0] ? "/" : "", tail);
        snprintf(tail, sizeof tail, "%.4095s", t);
        if (!slash || slash == dir) {
            snprintf(dir, sizeof dir, "%s", slash ? "/" : ".");
            break;
        }
        *slash = '\0';
    }
    if (!realpath(dir, real))
        snprintf(real, sizeof real, "%s", dir);
    /* The part that does not exist has no links: "." and ".." resolve by name. */
    snprintf(out, n, "%s", strcmp(real, "/") ? real : "");
    size_t len = strlen(out);
    for (char *part = strtok(tail, "/"); part; part = strtok(NULL, "/")) {
        if (!strcmp(part, "."))
            continue;
        if (!strcmp(part, "..")) {
            while (len > 0 && out[len - 1] != '/')
                len--;
            if (len > 0)
                len--;
            out[len] = '\0';
            continue;
        }
        len += (size_t)snprintf(out + len, n - len, "/%s", part);
        if (len >= n)
            len = n - 1;
    }
}

int app_same_file(const char *a, const char *b)
{
    struct stat sa, sb;
    int ea = stat(a, &sa) == 0, eb = stat(b, &sb) == 0;
    if (ea && eb)
        return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    if (ea != eb)
        return 0;
    char ca[8192], cb[8192];
    canonical(a, ca, sizeof ca);
    canonical(b, cb, sizeof cb);
    return strcmp(ca, cb) == 0;
}

int app_check_writable(const char *path)
{
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        app_error("%s: cannot write: it is a folder", path);
        return -1;
    }
    /* The nearest folder that exists must be one we can create files in. */
    char dir[4096];
    rr_path_dirname(path, dir, sizeof dir);
    while (stat(dir, &st) != 0) {
        char up[4096];
        rr_path_dirname(dir, up, sizeof up);
        if (!strcmp(up, dir))
            break;
        snprintf(dir, sizeof dir, "%s", up);
    }
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        app_error("%s: cannot write: '%s' is not a folder", path, dir);
        return -1;
    }
    if (access(dir, W_OK | X_OK) != 0) {
        app_error("%s: cannot write in folder '%s': %s", path, dir, strerror(errno));
        return -1;
    }
    return 0;
}

size_t app_scene_inputs(const scene *s, const char **ins, size_t cap)
{
    size_t n = 0;
    if (n < cap)
        ins[n++] = s->path;
    for (size_t o = 0; o < s->nobjects && n < cap; o++) {
        if (!s->objects[o].source[0])
            continue;
        int seen = 0;
        for (size_t k = 1; k < n && !seen; k++)
            seen = !strcmp(ins[k], s->objects[o].source);
        if (!seen)
            ins[n++] = s->objects[o].source;
    }
    return n;
}

int app_check_outputs(const char *const *outs, const char *const *what, size_t nout, const char *const *ins,
                      size_t nin)
{
    for (size_t i = 0; i < nout; i++) {
        if (!outs[i])
            continue;
        for (size_t k = 0; k < nin; k++)
            if (ins[k] && app_same_file(outs[i], ins[k])) {
                app_error("%s %s: that is an input of this command (%s): refusing to overwrite it", what[i], outs[i],
                          ins[k]);
                return -1;
            }
        for (size_t j = 0; j < i; j++)
            if (outs[j] && app_same_file(outs[i], outs[j])) {
                app_error("%s %s: the same file as %s %s: give each output its own name", what[i], outs[i], what[j],
                          outs[j]);
                return -1;
            }
        if (app_check_writable(outs[i]))
            return -1;
    }
    return 0;
}

/* Renames tmp[i] onto path[i] for every i, holding an exclusive lock on the
 * first path's folder (so that concurrent commits to one output do not
 * interleave). */
static rr_status commit_all(char tmp[][4096], const char *const *path, int n, rr_error *err)
{
    char dir[4096];
    rr_path_dirname(path[0], dir, sizeof dir);
    int fd = open(dir, O_RDONLY | O_DIRECTORY);
    if (fd >= 0)
        while (flock(fd, LOCK_EX) != 0 && errno == EINTR) {
        }
    rr_status st = RR_OK;
    for (int i = 0; i < n; i++) {
        if (st == RR_OK)
            st = rr_file_replace(tmp[i], path[i], err);
        else
            remove(tmp[i]);
        tmp[i][0] = '\0';
    }
    if (fd >= 0) {
        flock(fd, LOCK_UN);
        close(fd);
    }
    return st;
}

rr_status app_write_film(const char *exr, const char *png, const rt_film *film, int half, double exposure,
                         const app_exr_extra *extra, rr_error *err)
{
    img_layer layers[RT_LAYER_COUNT + RT_AOV_COUNT];
    int nl = 0;
    for (int i = 0; i < RT_LAYER_COUNT; i++) {
        layers[nl].name = rt_layer_name(i);
        layers[nl++].image = &film->layer[i];
    }
    for (int i = 0; extra && i < extra->nlayers && nl < RT_LAYER_COUNT + RT_AOV_COUNT; i++)
        layers[nl++] = extra->layers[i];
    const char *path[2] = {exr, png};
    char tmp[2][4096] = {"", ""};
    int n = png ? 2 : 1;
    rr_status st = RR_OK;
    /* Missing folders are made now, when the files are written, never earlier. */
    for (int i = 0; i < n && st == RR_OK; i++)
        if ((st = rr_file_make_parent_dirs(path[i], err)) == RR_OK)
            st = rr_file_tmpname(path[i], tmp[i], sizeof tmp[i], err);
    int failed = st == RR_OK ? -1 : 0;
    if (st == RR_OK && (st = img_write_exr_attrs(tmp[0], &film->beauty, layers, nl, half ? IMG_HALF : IMG_FLOAT,
                                                 extra ? extra->attrs : NULL, extra ? extra->nattrs : 0, err)) != RR_OK)
        failed = 0;
    if (st == RR_OK && png && (st = img_write_png(tmp[1], &film->beauty, exposure, err)) != RR_OK)
        failed = 1;
    if (st != RR_OK) {
        /* Nothing replaced: the old pair stays. The message names the temporary. */
        for (int i = 0; i < n; i++)
            if (tmp[i][0])
                remove(tmp[i]);
        if (failed >= 0)
            rr_error_prefix(err, "%s", path[failed]);
        return st;
    }
    return commit_all(tmp, path, n, err);
}
