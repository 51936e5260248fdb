/* ---- Reference implementation: integer helpers of the fixed-point kernels ------------------
 *
 * C99 with stdint.h only, and no undefined or implementation-defined behaviour: no shift of a
 * negative value (C leaves >> of one to the implementation and << undefined), no signed
 * overflow, no conversion of an out-of-range value to a narrower signed type. */

/* floor(v / 2^n) for 0 <= n <= 63: what an arithmetic right shift gives, without shifting a
 * negative value (for v < 0, ~(uint64_t)v is -v - 1). Compilers emit one shift. */
static inline int64_t unlag_asr64(int64_t v, uint32_t n)
{
    if (v >= 0) {
        return (int64_t)((uint64_t)v >> n);
    }
    return -(int64_t)(~(uint64_t)v >> n) - 1;
}

/* v saturated to int32_t; *overflow set when it did not fit. */
static inline int32_t unlag_saturate32(int64_t v, int *overflow)
{
    if (v > INT32_MAX) {
        *overflow = 1;
        return INT32_MAX;
    }
    if (v < INT32_MIN) {
        *overflow = 1;
        return INT32_MIN;
    }
    return (int32_t)v;
}

/* x rounded to the nearest integer, halves away from zero, saturated to int32_t, NaN to 0:
 * Rust's `libm::round(x) as i32`. The fraction x - trunc(x) is exact. */
static inline int32_t unlag_round_to_i32(double x)
{
    int64_t t;
    double f;
    if (x != x) {
        return 0;
    }
    if (x >= 2147483647.5) {
        return INT32_MAX;
    }
    if (x <= -2147483648.5) {
        return INT32_MIN;
    }
    t = (int64_t)x;
    f = x - (double)t;
    if (f >= 0.5) {
        t += 1;
    } else if (f <= -0.5) {
        t -= 1;
    }
    return (int32_t)t;
}

/* The largest integer not above x, saturated to int32_t, NaN to 0: Rust's
 * `libm::floor(x) as i32`. */
static inline int32_t unlag_floor_to_i32(double x)
{
    int64_t t;
    if (x != x) {
        return 0;
    }
    if (x >= 2147483648.0) {
        return INT32_MAX;
    }
    if (x < -2147483648.0) {
        return INT32_MIN;
    }
    t = (int64_t)x;
    if ((double)t > x) {
        t -= 1;
    }
    return (int32_t)t;
}
