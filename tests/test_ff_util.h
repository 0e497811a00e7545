/* test_ff_util.h - closed forms shared by the form-factor tests
 * (test_formfactor.c, test_visibility.c), included after cmocka.h. */
#ifndef TEST_FF_UTIL_H
#define TEST_FF_UTIL_H

#include <math.h>

#include "rr_math.h"

/* a within tol of b, or the test fails saying both (after cmocka.h) */
#define assert_near(a, b, tol)                                                                                    \
    do {                                                                                                          \
        double a_ = (double)(a), b_ = (double)(b), t_ = (double)(tol);                                            \
        if (!(fabs(a_ - b_) <= t_))                                                                               \
            fail_msg("%s = %.9g, expected %s = %.9g within %.3g (off by %.3g)", #a, a_, #b, b_, t_, fabs(a_ - b_)); \
    } while (0)

/* A plane element under a corner of a parallel a x b rectangle at distance c
 * (Howell's catalogue, "plane element to plane parallel rectangle; normal to
 * element passes through corner of rectangle"). */
static inline double corner_parallel(double a, double b, double c)
{
    double A = a / c, B = b / c;
    return (A / sqrt(1 + A * A) * atan(B / sqrt(1 + A * A)) + B / sqrt(1 + B * B) * atan(A / sqrt(1 + B * B))) /
           (2 * RR_PI);
}

#endif
