/* rt_bvh_avx512.c - the walk of 16-wide BVH nodes with the AVX-512 box test
 * (rt__walk16, rt__occl16; the code is rt_wide.h's, as rt__walk4 in
 * rt_traverse.c and rt__walk8 in rt_bvh_avx2.c).
 *
 * The only file compiled for AVX-512F in a dispatching build (RADRAY_SIMD=AUTO
 * with a compiler that can build it: CMake adds -mavx2 -mavx512f to this
 * file alone, and -ffp-contract=off so that the triangle test is not fused
 * into multiply-adds and gives the bits of the other widths); rt_accel_build
 * picks 16-wide nodes only on a CPU with AVX-512F (rt__bvh_width_default).
 * Nothing here may be called otherwise. Elsewhere this file is empty. */
#include "rt_internal.h"

#if RT_HAVE_W16
#define RT_W 16
#define RT_WALK rt__walk16
#define RT_OCCL rt__occl16
#define RT_WALKN rt__walkn16
#define RT_OCCLN rt__occln16
#define RT_BOXTEST rt__box16_test
#include "rt_wide.h"

#else
typedef int rt__bvh_avx512_unused; /* ISO C wants a declaration in every file */
#endif
