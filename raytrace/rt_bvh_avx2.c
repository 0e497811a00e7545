/* rt_bvh_avx2.c - the walk of 8-wide BVH nodes with the AVX2 box test
 * (rt__walk8; the code is rt_wide.h's, as rt__walk4 in rt_traverse.c).
 *
 * The only file compiled for AVX2 in a dispatching build (RADRAY_SIMD=AUTO,
 * RT_SIMD 3: CMake adds -mavx2 to this file alone), so a default binary still
 * runs on any x86-64; rt_accel_build picks 8-wide nodes only on a CPU with
 * AVX2 (rt__bvh_width_default). Nothing here may be called otherwise. With
 * RADRAY_SIMD=AVX2 the whole library is compiled for AVX2 and this file is
 * the default walk; with SSE or OFF it is empty. */
#include "rt_internal.h"

#if RT_HAVE_W8
#define RT_W 8
#define RT_WALK rt__walk8
#define RT_OCCL rt__occl8
#define RT_WALKN rt__walkn8
#define RT_OCCLN rt__occln8
#define RT_BOXTEST rt__box8_test
#include "rt_wide.h"
#else
typedef int rt__bvh_avx2_unused; /* ISO C wants a declaration in every file */
#endif
