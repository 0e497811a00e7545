/* rr_file.h - atomic output files and small path helpers (part of core).
 *
 * Every output radray writes goes through rr_atomic_*: the data goes to a
 * temporary file in the destination folder, and only a complete, flushed file
 * is renamed over the destination. A failure at any point removes the
 * temporary and leaves a previous good file untouched.
 */
#ifndef RR_FILE_H
#define RR_FILE_H

#include <stdio.h>

#include "rr_error.h"

typedef struct rr_atomic {
    char final_path[4096];
    char tmp_path[4096];
    FILE *fp; /* open for writing while the file is in progress */
} rr_atomic;

/* Creates the temporary file next to path (same folder, so rename is atomic).
 * Fails with RR_ERR_IO and a message naming path when the folder is missing
 * or not writable. */
rr_status rr_atomic_begin(rr_atomic *a, const char *path, rr_error *err);
/* Flushes, closes and renames over the destination. On failure the temporary
 * is removed. */
rr_status rr_atomic_commit(rr_atomic *a, rr_error *err);
/* Closes and removes the temporary (safe to call after a failed commit or twice). */
void rr_atomic_abort(rr_atomic *a);

/* Temporary path for libraries that open files by name themselves (OpenEXR,
 * libpng through FILE* is preferred): fills tmp with a unique name in the folder
 * of path, creates it empty, and returns RR_OK. Rename with rr_file_replace. */
rr_status rr_file_tmpname(const char *path, char *tmp, size_t tmp_size, rr_error *err);
/* rename(tmp, path), removing tmp on failure. */
rr_status rr_file_replace(const char *tmp, const char *path, rr_error *err);

/* Creates every missing folder of the parent of path (like mkdir -p dirname). */
rr_status rr_file_make_parent_dirs(const char *path, rr_error *err);

/* dir/rel when rel is relative, rel itself when absolute. dir may be "" (cwd). */
rr_status rr_path_join(const char *dir, const char *rel, char *out, size_t out_size, rr_error *err);
/* Folder part of path ("." when there is none). */
void rr_path_dirname(const char *path, char *out, size_t out_size);

/* RR_OK when path is a regular file; else RR_ERR_IO naming what it is (a
 * folder, a FIFO, a device). Check before opening an input: opening a FIFO
 * blocks until a writer comes. */
rr_status rr_file_check_regular(const char *path, rr_error *err);
/* Reads a whole regular file (rr_file_check_regular first) into a
 * NUL-terminated malloc'd buffer; *size excludes the NUL. */
rr_status rr_file_read_all(const char *path, char **data, size_t *size, rr_error *err);

#endif
