/* ---- Reference implementation: the fixed-point cascade in normal form ---------------------
 *
 * unlag::board::fixed::FixedCascade::<UNLAG_SECTION_COUNT>::process in C99 (stdint.h only: no libm,
 * no allocation, no undefined behaviour), bit for bit: integer arithmetic is exact. Only
 * unlag_init uses floating point (double, as the board's equilibrium does); it matches the
 * board where double is IEEE double evaluated as double and not fused (-ffp-contract=off).
 *
 *     unlag_state s;
 *     unlag_init(&s, first_code);             (or unlag_reset(&s): all states zero)
 *     for each ADC code: out = unlag_process(&s, code);
 *     if (unlag_take_overflow(&s)) { a state or output saturated since the last check }
 *
 * Codes in: Q1.31 of UNLAG_FULL_SCALE (the reading divided by UNLAG_FULL_SCALE, times 2^31);
 * codes out: Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. Per section, u its input,
 * x1, x2 its states, all int32_t, accumulators int64_t:
 *
 *     x1' = trunc((a11 x1 + a12 x2 + b1 u) / 2^30)       towards zero, saturated
 *     x2' = trunc((a21 x1 + a22 x2 + b2 u) / 2^30)       towards zero, saturated
 *     y   = round((c1 x1  + c2 x2  + d u)  / 2^shift)    to nearest, halves up, saturated
 *
 * The export checked every coefficient to be at most 2^30 in magnitude and 1 <= shift <= 62,
 * so no accumulator can overflow for any input; the host's scaling keeps states and outputs
 * inside int32_t for every input, and should one leave it anyway it saturates and sets the
 * overflow flag. */

/* The states x1, x2 of each section, and the overflow flag, for one channel. */
typedef struct {
    int32_t x[UNLAG_SECTION_COUNT][2];
    int overflow; /* nonzero once a state or output saturated, until taken */
} unlag_state;

/* Every state zero, the flag clear (Rust: FixedState::default()). */
static inline void unlag_reset(unlag_state *state)
{
    uint32_t i;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        state->x[i][0] = 0;
        state->x[i][1] = 0;
    }
    state->overflow = 0;
}

/* The state after the constant input code forever, computed in double from the integer
 * coefficients and rounded (Rust: FixedCascade::equilibrium): a probe that already reads a
 * steady pressure starts with no transient. */
static inline void unlag_init(unlag_state *state, int32_t input)
{
    const double q = 1.0 / 1073741824.0; /* 2^-30 */
    double v = (double)input;
    uint32_t i, k;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        const int32_t *s = unlag_fixed_sections[i];
        const double a11 = (double)s[0] * q, a12 = (double)s[1] * q;
        const double a21 = (double)s[2] * q, a22 = (double)s[3] * q;
        const double b1 = (double)s[4] * q, b2 = (double)s[5] * q;
        /* (I - A) x = b v; det(I - A) > 0 for the accepted (stable) forms. */
        const double m11 = 1.0 - a11, m12 = -a12, m21 = -a21, m22 = 1.0 - a22;
        const double det = m11 * m22 - m12 * m21;
        const double r1 = b1 * v, r2 = b2 * v;
        const double x1 = (r1 * m22 - m12 * r2) / det;
        const double x2 = (m11 * r2 - m21 * r1) / det;
        double scale = 1.0, y;
        for (k = 0u; k < (uint32_t)s[9]; k++) {
            scale *= 0.5; /* 2^-shift, exactly */
        }
        y = ((double)s[6] * x1 + (double)s[7] * x2 + (double)s[8] * v) * scale;
        state->x[i][0] = unlag_round_to_i32(x1);
        state->x[i][1] = unlag_round_to_i32(x2);
        v = (double)unlag_round_to_i32(y);
    }
    state->overflow = 0;
}

/* acc / 2^bits rounded towards zero (magnitude truncation: no limit cycles), saturated. */
static inline int32_t unlag_fixed_truncate(int64_t acc, uint32_t bits, int *overflow)
{
    if (acc < 0) {
        /* 0 - (uint64_t)acc is |acc|, well defined for every acc. */
        return unlag_saturate32(-(int64_t)(((uint64_t)0 - (uint64_t)acc) >> bits), overflow);
    }
    return unlag_saturate32((int64_t)((uint64_t)acc >> bits), overflow);
}

/* acc / 2^bits rounded to nearest, halves up, saturated: floor((floor(acc / 2^(bits-1)) + 1) / 2),
 * which is floor((acc + 2^(bits-1)) / 2^bits) with no addition that could overflow. */
static inline int32_t unlag_fixed_round(int64_t acc, uint32_t bits, int *overflow)
{
    return unlag_saturate32(unlag_asr64(unlag_asr64(acc, bits - 1u) + 1, 1u), overflow);
}

/* One ADC code through the cascade: the reconstructed reference, UNLAG_LATENCY_SAMPLES
 * samples late (Rust: FixedCascade::process). */
static inline int32_t unlag_process(unlag_state *state, int32_t input)
{
    int32_t v = input;
    int overflow = 0;
    uint32_t i;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        /* {a11, a12, a21, a22, b1, b2, c1, c2, d, shift} */
        const int32_t *s = unlag_fixed_sections[i];
        const int64_t x1 = state->x[i][0], x2 = state->x[i][1], u = v;
        const int64_t acc1 = s[0] * x1 + s[1] * x2 + s[4] * u;
        const int64_t acc2 = s[2] * x1 + s[3] * x2 + s[5] * u;
        const int64_t acc3 = s[6] * x1 + s[7] * x2 + s[8] * u;
        state->x[i][0] = unlag_fixed_truncate(acc1, 30u, &overflow);
        state->x[i][1] = unlag_fixed_truncate(acc2, 30u, &overflow);
        v = unlag_fixed_round(acc3, (uint32_t)s[9], &overflow);
    }
    state->overflow |= overflow;
    return v;
}

/* Nonzero when a state or output saturated since the flag was last taken
 * (Rust: FixedState::overflowed). */
static inline int unlag_overflowed(const unlag_state *state)
{
    return state->overflow;
}

/* Reads and clears the overflow flag (Rust: FixedState::take_overflow). */
static inline int unlag_take_overflow(unlag_state *state)
{
    const int overflow = state->overflow;
    state->overflow = 0;
    return overflow;
}
