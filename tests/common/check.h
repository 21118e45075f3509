/* check.h -- minimal assertion macros for rbcloth's C tests.
 * Each CHECK prints file:line and the failing expression (or the two numbers and
 * the tolerance) to stderr and counts a failure; a test's main returns
 * check_report(), which prints "N passed, M failed" and returns non-zero on failure.
 */
#ifndef RBC_TEST_CHECK_H
#define RBC_TEST_CHECK_H
#include <math.h>
#include <stdio.h>

static int check_passed_ = 0;
static int check_failed_ = 0;

#define CHECK(cond)                                                                 \
    do {                                                                            \
        if (cond) {                                                                 \
            check_passed_++;                                                        \
        } else {                                                                    \
            check_failed_++;                                                        \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                           \
    } while (0)

/* |a - b| <= tol, with the numbers printed on failure. */
#define CHECK_NEAR(a, b, tol)                                                       \
    do {                                                                            \
        double ca_ = (double)(a), cb_ = (double)(b), ct_ = (double)(tol);           \
        if (fabs(ca_ - cb_) <= ct_) {                                               \
            check_passed_++;                                                        \
        } else {                                                                    \
            check_failed_++;                                                        \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, %s = %.9g, |diff| = %.3g > %.3g\n", \
                    __FILE__, __LINE__, #a, ca_, #b, cb_, fabs(ca_ - cb_), ct_);     \
        }                                                                           \
    } while (0)

/* Integer / result-code equality, both values printed on failure. */
#define CHECK_EQ(a, b)                                                              \
    do {                                                                            \
        long long ca_ = (long long)(a), cb_ = (long long)(b);                       \
        if (ca_ == cb_) {                                                           \
            check_passed_++;                                                        \
        } else {                                                                    \
            check_failed_++;                                                        \
            fprintf(stderr, "%s:%d: CHECK_EQ failed: %s = %lld, %s = %lld\n",        \
                    __FILE__, __LINE__, #a, ca_, #b, cb_);                          \
        }                                                                           \
    } while (0)

static inline int check_report(const char *name) {
    printf("%s: %d passed, %d failed\n", name, check_passed_, check_failed_);
    return check_failed_ ? 1 : 0;
}
#endif
