/* sd_math.h -- the runtime's real arithmetic in either precision (private to the runtime).
 *
 * sd_real (sd_layout.h) is double in the reference build and float with -DSD_SINGLE. Every real
 * constant is written SD_R(...) and every libm call through the macros below, so the reference
 * build performs exactly the operations it did with plain doubles (bit-exact with Python), and
 * the single-precision build performs no double operation at all: on a Cortex-M4F
 * (fpv4-sp-d16) every real operation of a tick is a hardware single-precision instruction or a
 * float libm call (tests/test_m4_runtime.py disassembles the tick path and checks that no
 * double-precision helper is reachable from sd_renderer_step).
 *
 * Tolerances that exist to absorb rounding are scaled to the precision (SD_TOL_*): a relative
 * tolerance of 1e-12 is meaningful in double and rounds away in float.
 */
#ifndef SD_MATH_H
#define SD_MATH_H

#include <float.h>
#include <math.h>
#include "sd_layout.h"

#define SD_R(x) ((sd_real)(x))
#define SD_PI SD_R(3.141592653589793)

#ifdef SD_SINGLE
#define SD_SQRT sqrtf
#define SD_EXP expf
#define SD_POW powf
#define SD_LOG logf
#define SD_SIN sinf
#define SD_COS cosf
#define SD_ATAN2 atan2f
#define SD_ACOS acosf
#define SD_FMOD fmodf
#define SD_FLOOR floorf
#define SD_CEIL ceilf
#define SD_FABS fabsf
#define SD_COPYSIGN copysignf
#define SD_EPS FLT_EPSILON            /* 2^-23: twice the unit roundoff */
#define SD_TINY FLT_MIN
/* rounding tolerances of the single-precision build (2^-23 = 1.2e-7 per operation) */
#define SD_TOL_BREAK SD_R(1e-6)       /* stick force beyond mu_s N by more than rounding */
#define SD_TOL_ADMIT SD_R(1e-5)       /* re-stick admissible if |f| <= (1 - this) mu_s N */
#define SD_TOL_TOUCH SD_R(1e-4)       /* stricter for tangent touches */
#define SD_TOL_GRAZE SD_R(1e-5)       /* relative velocity counted as a touch, per m/s of |V| + |v0| */
#define SD_TOL_PHASE SD_R(1e-6)       /* an acceleration zero this close to a period boundary, rad */
#define SD_POLISH_ABS SD_R(1e-12)     /* Newton stopping rule of the re-stick polish: |step| <= abs + rel t */
#define SD_POLISH_REL (4.0f * FLT_EPSILON)
#define SD_TOL_ROOT SD_R(1.25e-8)      /* series end of a re-stick root: omitted term / root time (0.1 ulp) */
#else
#define SD_SQRT sqrt
#define SD_EXP exp
#define SD_POW pow
#define SD_LOG log
#define SD_SIN sin
#define SD_COS cos
#define SD_ATAN2 atan2
#define SD_ACOS acos
#define SD_FMOD fmod
#define SD_FLOOR floor
#define SD_CEIL ceil
#define SD_FABS fabs
#define SD_COPYSIGN copysign
#define SD_EPS DBL_EPSILON
#define SD_TINY 1e-300
/* the reference build (double) */
#define SD_TOL_BREAK 1e-12
#define SD_TOL_ADMIT 1e-9
#define SD_TOL_TOUCH 1e-6
#define SD_TOL_GRAZE 1e-12
#define SD_TOL_PHASE 1e-9
#define SD_POLISH_ABS 1e-16
#define SD_POLISH_REL 1e-15
#define SD_TOL_ROOT 2.5e-17
#endif

#endif
