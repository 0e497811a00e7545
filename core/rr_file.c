/* rr_file.c - atomic output files and path helpers. */
#include "rr_file.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

void rr_path_dirname(const char *path, char *out, size_t out_size)
{
    const char *slash = strrchr(path, '/');
    if (!slash) {
        snprintf(out, out_size, ".");
    } else if (slash == path) {
        snprintf(out, out_size, "/");
    } else {
        size_t n = (size_t)(slash - path);
        if (n >= out_size)
            n = out_size - 1;
        memcpy(out, path, n);
        out[n] = '\0';
    }
}

rr_status rr_path_join(const char *dir, const char *rel, char *out, size_t out_size, rr_error *err)
{
    int n;
    if (rel[0] == '/' || !dir || dir[0] == '\0')
        n = snprintf(out, out_size, "%s", rel);
    else
        n = snprintf(out, out_size, "%s/%s", dir, rel);
    if (n < 0 || (size_t)n >= out_size)
        return rr_error_set(err, RR_ERR_INVALID, "path too long: %s/%s", dir ? dir : "", rel);
    return RR_OK;
}

rr_status rr_file_tmpname(const char *path, char *tmp, size_t tmp_size, rr_error *err)
{
    char dir[4096];
    rr_path_dirname(path, dir, sizeof dir);
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    /* Hidden name in the same folder, so the final rename never crosses file systems. */
    int n = snprintf(tmp, tmp_size, "%s/.%s.tmp-XXXXXX", dir, base);
    if (n < 0 || (size_t)n >= tmp_size)
        return rr_error_set(err, RR_ERR_INVALID, "%s: path too long", path);
    int fd = mkstemp(tmp);
    if (fd < 0) {
        struct stat st;
        if (stat(dir, &st) != 0)
            return rr_error_set(err, RR_ERR_IO, "%s: cannot write: folder '%s' does not exist", path, dir);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write in folder '%s': %s", path, dir, strerror(errno));
    }
    /* mkstemp creates 0600; outputs are ordinary files, so give them the mode
     * fopen would have (0666 less the umask) before they are renamed into place. */
    mode_t mask = umask(0);
    umask(mask);
    if (fchmod(fd, 0666 & ~mask) != 0) {
        int e = errno;
        close(fd);
        remove(tmp);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot set the mode of '%s': %s", path, tmp, strerror(e));
    }
    close(fd);
    return RR_OK;
}

rr_status rr_file_replace(const char *tmp, const char *path, rr_error *err)
{
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        remove(tmp);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write: it is a folder", path);
    }
    if (rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot replace: %s", path, strerror(e));
    }
    return RR_OK;
}

rr_status rr_atomic_begin(rr_atomic *a, const char *path, rr_error *err)
{
    memset(a, 0, sizeof *a);
    if (strlen(path) >= sizeof a->final_path)
        return rr_error_set(err, RR_ERR_INVALID, "%s: path too long", path);
    rr_status st = rr_file_tmpname(path, a->tmp_path, sizeof a->tmp_path, err);
    if (st != RR_OK)
        return st;
    snprintf(a->final_path, sizeof a->final_path, "%s", path);
    a->fp = fopen(a->tmp_path, "wb");
    if (!a->fp) {
        int e = errno;
        remove(a->tmp_path);
        a->tmp_path[0] = '\0';
        return rr_error_set(err, RR_ERR_IO, "%s: cannot write: %s", path, strerror(e));
    }
    return RR_OK;
}

rr_status rr_atomic_commit(rr_atomic *a, rr_error *err)
{
    if (!a->fp)
        return rr_error_set(err, RR_ERR_INTERNAL, "%s: file is not open", a->final_path);
    int bad = fflush(a->fp) != 0 || ferror(a->fp);
    if (!bad)
        bad = fsync(fileno(a->fp)) != 0 && errno != EINVAL;
    int e = errno;
    if (fclose(a->fp) != 0 && !bad) {
        bad = 1;
        e = errno;
    }
    a->fp = NULL;
    if (bad) {
        remove(a->tmp_path);
        a->tmp_path[0] = '\0';
        return rr_error_set(err, RR_ERR_IO, "%s: write failed: %s", a->final_path, strerror(e));
    }
    rr_status st = rr_file_replace(a->tmp_path, a->final_path, err);
    a->tmp_path[0] = '\0';
    return st;
}

void rr_atomic_abort(rr_atomic *a)
{
    if (a->fp) {
        fclose(a->fp);
        a->fp = NULL;
    }
    if (a->tmp_path[0]) {
        remove(a->tmp_path);
        a->tmp_path[0] = '\0';
    }
}

rr_status rr_file_make_parent_dirs(const char *path, rr_error *err)
{
    char dir[4096];
    rr_path_dirname(path, dir, sizeof dir);
    size_t n = strlen(dir);
    for (size_t i = 1; i <= n; i++) {
        if (dir[i] == '/' || dir[i] == '\0') {
            char c = dir[i];
            dir[i] = '\0';
            struct stat st;
            if (stat(dir, &st) != 0) {
                if (mkdir(dir, 0777) != 0 && errno != EEXIST)
                    return rr_error_set(err, RR_ERR_IO, "%s: cannot create folder '%s': %s", path, dir,
                                        strerror(errno));
            } else if (!S_ISDIR(st.st_mode)) {
                return rr_error_set(err, RR_ERR_IO, "%s: '%s' is not a folder", path, dir);
            }
            dir[i] = c;
        }
    }
    return RR_OK;
}

rr_status rr_file_check_regular(const char *path, rr_error *err)
{
    struct stat st;
    if (stat(path, &st) != 0)
        return rr_error_set(err, RR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return rr_error_set(err, RR_ERR_IO, "%s: cannot read: not a regular file (%s)", path,
                            S_ISDIR(st.st_mode)    ? "a folder"
                            : S_ISFIFO(st.st_mode) ? "a FIFO: reading it would wait for a writer"
                                                   : "a device or socket");
    return RR_OK;
}

rr_status rr_file_read_all(const char *path, char **data, size_t *size, rr_error *err)
{
    /* Before opening: opening a FIFO blocks, and /dev/zero never ends. */
    rr_status reg = rr_file_check_regular(path, err);
    if (reg != RR_OK)
        return reg;
    FILE *f = fopen(path, "rb");
    if (!f)
        return rr_error_set(err, RR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || S_ISDIR(st.st_mode)) {
        fclose(f);
        return rr_error_set(err, RR_ERR_IO, "%s: cannot read: not a regular file", path);
    }
    size_t cap = st.st_size > 0 ? (size_t)st.st_size + 1 : 4096, len = 0;
    char *buf = malloc(cap);
    if (!buf) {
        fclose(f);
        return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading the file", path);
    }
    for (;;) {
        if (len + 1 >= cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                fclose(f);
                return rr_error_set(err, RR_ERR_NOMEM, "%s: out of memory reading the file", path);
            }
            buf = nb;
            cap *= 2;
        }
        size_t got = fread(buf + len, 1, cap - 1 - len, f);
        len += got;
        if (got == 0)
            break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        free(buf);
        return rr_error_set(err, RR_ERR_IO, "%s: read error", path);
    }
    buf[len] = '\0';
    *data = buf;
    if (size)
        *size = len;
    return RR_OK;
}
