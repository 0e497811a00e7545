/* test_mpi.c - `mpirun -np N radray render ...` (built with -DRADRAY_MPI=ON;
 * registered with ctest only then): the job behaves like one process.
 *
 *  - the same EXR bytes as one process (--reproducible: no timings in the
 *    header) in hybrid, secondary and radiosity modes, for 2 and 3 ranks;
 *  - the radiosity cache an MPI run writes is the one process's, byte for
 *    byte, and a render from it is the same;
 *  - a walkthrough (--frames) over 2 ranks gives the one process's frames;
 *  - bad input: exit code 2, the message printed once, no output;
 *  - a rank killed mid-render ends the job within seconds with a non-zero
 *    exit code, and no OUT is written.
 *
 * The ranks run oversubscribed on this machine's cores (--oversubscribe);
 * as root, Open MPI needs OMPI_ALLOW_RUN_AS_ROOT(_CONFIRM), set here.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "rr_core.h"

static char g_dir[64];

static int setup(void **state)
{
    (void)state;
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    /* containers often forbid the cross-memory attach of Open MPI's shared-
     * memory transport; copying through the shared segment always works */
    setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 0);
    snprintf(g_dir, sizeof g_dir, "/tmp/radray-mpi-XXXXXX");
    return mkdtemp(g_dir) ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* Runs `[mpirun -np ranks] radray render args` (ranks 0: no mpirun), output
 * in g_dir/log; the exit code. */
static int radray(int ranks, const char *args)
{
    char cmd[4096];
    if (ranks > 0)
        snprintf(cmd, sizeof cmd, "'%s' --oversubscribe -np %d '%s' render %s > '%s/log' 2>&1", RR_MPIEXEC, ranks,
                 RR_RADRAY_BIN, args, g_dir);
    else
        snprintf(cmd, sizeof cmd, "'%s' render %s > '%s/log' 2>&1", RR_RADRAY_BIN, args, g_dir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

static char *slurp(const char *name)
{
    char path[256];
    snprintf(path, sizeof path, "%s/%s", g_dir, name);
    char *data = NULL;
    size_t n = 0;
    if (rr_file_read_all(path, &data, &n, NULL) != RR_OK)
        return NULL;
    return data;
}

static void same_bytes(const char *a, const char *b)
{
    char pa[256], pb[256];
    snprintf(pa, sizeof pa, "%s/%s", g_dir, a);
    snprintf(pb, sizeof pb, "%s/%s", g_dir, b);
    char *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    assert_int_equal(rr_file_read_all(pa, &x, &nx, NULL), RR_OK);
    assert_int_equal(rr_file_read_all(pb, &y, &ny, NULL), RR_OK);
    if (nx != ny || memcmp(x, y, nx) != 0)
        fail_msg("%s and %s differ (%zu and %zu bytes)", a, b, nx, ny);
    free(x);
    free(y);
}

static const char *cornell(void)
{
    static char path[1024];
    snprintf(path, sizeof path, "'%s/scenes/cornell.json' --width 40 --spp 4 --reproducible -q", RR_SOURCE_DIR);
    return path;
}

static void same_bytes_every_mode(void **state)
{
    (void)state;
    const char *modes[] = {"hybrid", "secondary", "radiosity"};
    for (int m = 0; m < 3; m++) {
        char args[2048];
        snprintf(args, sizeof args, "%s --mode %s -o '%s/one-%s.exr'", cornell(), modes[m], g_dir, modes[m]);
        assert_int_equal(radray(0, args), 0);
        for (int ranks = 2; ranks <= 3; ranks++) {
            snprintf(args, sizeof args, "%s --mode %s -o '%s/np%d-%s.exr'", cornell(), modes[m], g_dir, ranks,
                     modes[m]);
            int rc = radray(ranks, args);
            if (rc != 0)
                fail_msg("mpirun -np %d: exit %d: %s", ranks, rc, slurp("log"));
            char a[64], b[64];
            snprintf(a, sizeof a, "one-%s.exr", modes[m]);
            snprintf(b, sizeof b, "np%d-%s.exr", ranks, modes[m]);
            same_bytes(a, b);
        }
    }
}

static void cache_made_by_ranks(void **state)
{
    (void)state;
    char args[2048];
    snprintf(args, sizeof args, "%s --radiosity-cache '%s/one.cache' -o '%s/c1.exr'", cornell(), g_dir, g_dir);
    assert_int_equal(radray(0, args), 0);
    snprintf(args, sizeof args, "%s --radiosity-cache '%s/mpi.cache' -o '%s/c2.exr'", cornell(), g_dir, g_dir);
    assert_int_equal(radray(3, args), 0);
    same_bytes("one.cache", "mpi.cache");
    same_bytes("c1.exr", "c2.exr");
    /* one process rendering from the ranks' cache */
    snprintf(args, sizeof args, "%s --radiosity-cache '%s/mpi.cache' -o '%s/c3.exr'", cornell(), g_dir, g_dir);
    assert_int_equal(radray(0, args), 0);
    same_bytes("c1.exr", "c3.exr");
}

static const char *k_walk =
    "{\"format\": \"radray-scene/1\", \"camera\": {\"type\": \"lookat\", \"eye\": [0, 1, 3], \"target\": [0, 1, 0], "
    "\"up\": [0, 1, 0], \"fov\": 60, \"width\": 24, \"height\": 16}, \"camera_path\": {\"frames\": 6, \"keys\": ["
    "{\"frame\": 1, \"eye\": [0, 1, 3], \"target\": [0, 1, 0], \"fov\": 60}, "
    "{\"frame\": 6, \"eye\": [1, 1.5, 2], \"target\": [0, 0.5, 0], \"fov\": 45}]}, "
    "\"materials\": {\"w\": {\"diffuse\": 0.7}, \"l\": {\"emission\": 5}}, \"objects\": ["
    "{\"type\": \"box\", \"material\": \"w\", \"min\": [-2, 0, -2], \"max\": [2, 3, 4], \"flip\": true}, "
    "{\"type\": \"box\", \"material\": \"w\", \"min\": [-0.4, 0, -0.4], \"max\": [0.4, 0.8, 0.4]}, "
    "{\"type\": \"quad\", \"material\": \"l\", \"vertices\": [[-0.5, 2.99, -0.5], [0.5, 2.99, -0.5], "
    "[0.5, 2.99, 0.5], [-0.5, 2.99, 0.5]]}]}";

static void walkthrough_over_ranks(void **state)
{
    (void)state;
    char path[256], args[2048];
    snprintf(path, sizeof path, "%s/walk.json", g_dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(k_walk, f);
    fclose(f);
    snprintf(args, sizeof args, "'%s' --frames 1..6 --spp 2 --reproducible -q -o '%s/a/w.exr'", path, g_dir);
    assert_int_equal(radray(0, args), 0);
    snprintf(args, sizeof args, "'%s' --frames 1..6 --spp 2 --reproducible -q -o '%s/b/w.exr'", path, g_dir);
    assert_int_equal(radray(2, args), 0);
    for (int k = 1; k <= 6; k++) {
        char a[64], b[64];
        snprintf(a, sizeof a, "a/w.%04d.exr", k);
        snprintf(b, sizeof b, "b/w.%04d.exr", k);
        same_bytes(a, b);
    }
    /* the frames differ from each other: the camera moves */
    char pa[256], pb[256], *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    snprintf(pa, sizeof pa, "%s/a/w.0001.exr", g_dir);
    snprintf(pb, sizeof pb, "%s/a/w.0006.exr", g_dir);
    assert_int_equal(rr_file_read_all(pa, &x, &nx, NULL), RR_OK);
    assert_int_equal(rr_file_read_all(pb, &y, &ny, NULL), RR_OK);
    assert_true(nx != ny || memcmp(x, y, nx) != 0);
    free(x);
    free(y);
}

static void bad_input_once(void **state)
{
    (void)state;
    char path[256], args[1024];
    snprintf(path, sizeof path, "%s/bad.json", g_dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs("{\"format\": \"radray-scene/1\"}", f);
    fclose(f);
    snprintf(args, sizeof args, "'%s' -o '%s/bad.exr'", path, g_dir);
    assert_int_equal(radray(3, args), 2);
    char *log = slurp("log");
    assert_non_null(log);
    int n = 0;
    for (const char *p = log; (p = strstr(p, "camera: missing")); p++)
        n++;
    if (n != 1)
        fail_msg("the message should be printed once, got %d times:\n%s", n, log);
    free(log);
    struct stat st;
    char out[256];
    snprintf(out, sizeof out, "%s/bad.exr", g_dir);
    assert_int_not_equal(stat(out, &st), 0);
    /* only render runs on several ranks: the others say so, once */
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "'%s' --oversubscribe -np 2 '%s' info '%s/scenes/cornell.json' > '%s/log' 2>&1",
             RR_MPIEXEC, RR_RADRAY_BIN, RR_SOURCE_DIR, g_dir);
    int rc = system(cmd);
    assert_true(WIFEXITED(rc) && WEXITSTATUS(rc) == 2);
    log = slurp("log");
    assert_non_null(log);
    const char *hit = strstr(log, "only 'render' runs on several MPI ranks");
    assert_non_null(hit);
    assert_null(strstr(hit + 1, "only 'render' runs on several MPI ranks"));
    free(log);
}

/* Kills the newest radray process (a rank) once the job has run a while. */
static void killed_rank_ends_job(void **state)
{
    (void)state;
    char args[2048], out[256];
    snprintf(out, sizeof out, "%s/k.exr", g_dir);
    snprintf(args, sizeof args, "'%s/scenes/cornell.json' --width 120 --spp 4096 --mode secondary -q -o '%s'",
             RR_SOURCE_DIR, out);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0)
        _exit(radray(2, args));
    struct timespec ts = {2, 0};
    nanosleep(&ts, NULL);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "pkill -9 -n -f '^%s render .*/k.exr'", RR_RADRAY_BIN);
    assert_int_equal(system(cmd), 0);
    double t0 = rr_now_seconds();
    int st = 0;
    waitpid(pid, &st, 0);
    double waited = rr_now_seconds() - t0;
    printf("job ended %.2f s after the kill, exit %d\n", waited, WIFEXITED(st) ? WEXITSTATUS(st) : -1);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) != 0);
    assert_true(waited < 10);
    struct stat sb;
    assert_int_not_equal(stat(out, &sb), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(same_bytes_every_mode), cmocka_unit_test(cache_made_by_ranks),
        cmocka_unit_test(walkthrough_over_ranks), cmocka_unit_test(bad_input_once),
        cmocka_unit_test(killed_rank_ends_job),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
