/* ---- Reference implementation: the fixed-point cascade in direct form ---------------------
 *
 * unlag::board::fixed::direct::DirectCascade::<UNLAG_SECTION_COUNT>::process in C99 (stdint.h only:
 * no libm, no allocation, no undefined behaviour), bit for bit: integer arithmetic is exact.
 * Only unlag_init uses floating point (double, as the board's equilibrium does); it matches
 * the board where double is IEEE double evaluated as double and not fused
 * (-ffp-contract=off).
 *
 *     unlag_state s;
 *     unlag_init(&s, first_code);             (or unlag_reset(&s): all states zero)
 *     for each ADC code: out = unlag_process(&s, code);
 *     if (unlag_take_overflow(&s)) { a section's output saturated since the last check }
 *
 * Codes in: Q1.31 of UNLAG_FULL_SCALE (the reading divided by UNLAG_FULL_SCALE, times 2^31);
 * codes out: Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. Per section, x its input
 * (the previous section's output, or the code), y its output, e the residual it carries, all
 * int32_t, coefficients Q2.30 with the NEGATED denominator na = -a:
 *
 *     acc = e + b0 x[n] + b1 x[n-1] + b2 x[n-2] + na1 y[n-1] + na2 y[n-2]     (int64_t, exact)
 *     y[n] = floor(acc / 2^30), the high word of acc saturated to 30 bits (within 3 codes of
 *            INT32_MIN and INT32_MAX; that sets the overflow flag)
 *     e    = acc mod 2^30 (0 <= e < 2^30: first-order error feedback)
 *
 * A section's output history is the next section's input history. The export checked that
 * each section's five coefficient magnitudes sum to less than 2^32, so no accumulator can
 * overflow for any input; the host's scaling keeps every output inside int32_t. */

/* The last two input codes, per section y[n-1], y[n-2] and e, and the overflow flag, for
 * one channel. */
typedef struct {
    int32_t x[2];                       /* x[n-1], x[n-2] */
    int32_t s[UNLAG_SECTION_COUNT][3];  /* y[n-1], y[n-2], e */
    int overflow; /* nonzero once an output saturated, until taken */
} unlag_state;

/* Every state and residual zero, the flag clear (Rust: DirectState::default()). */
static inline void unlag_reset(unlag_state *state)
{
    uint32_t i;
    state->x[0] = 0;
    state->x[1] = 0;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        state->s[i][0] = 0;
        state->s[i][1] = 0;
        state->s[i][2] = 0;
    }
    state->overflow = 0;
}

/* The state after the constant input code forever, computed in double from the integer
 * coefficients and rounded down; the residuals start at 0 (Rust: DirectCascade::equilibrium). */
static inline void unlag_init(unlag_state *state, int32_t input)
{
    const double one = 1073741824.0; /* 2^30 */
    double v = (double)input;
    uint32_t i;
    state->x[0] = input;
    state->x[1] = input;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        /* {b0, b1, b2, -a1, -a2} */
        const int32_t *c = unlag_direct_sections[i];
        /* DC gain B(1) / A(1); A(1) > 0 for an accepted (stable) section. */
        const double y = v * ((double)c[0] + (double)c[1] + (double)c[2]) /
                         (one - (double)c[3] - (double)c[4]);
        const int32_t yi = unlag_floor_to_i32(y);
        state->s[i][0] = yi;
        state->s[i][1] = yi;
        state->s[i][2] = 0;
        v = (double)yi;
    }
    state->overflow = 0;
}

/* One ADC code through the cascade: the reconstructed reference, UNLAG_LATENCY_SAMPLES
 * samples late (Rust: DirectCascade::process). */
static inline int32_t unlag_process(unlag_state *state, int32_t input)
{
    int32_t v0 = input, v1 = state->x[0], v2 = state->x[1];
    int overflow = 0;
    uint32_t i;
    state->x[1] = state->x[0];
    state->x[0] = input;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        /* {b0, b1, b2, -a1, -a2} */
        const int32_t *c = unlag_direct_sections[i];
        const int32_t y1 = state->s[i][0], y2 = state->s[i][1];
        int64_t acc = state->s[i][2];
        int32_t hi, sat, y;
        uint32_t lo;
        acc += (int64_t)c[0] * v0;
        acc += (int64_t)c[1] * v1;
        acc += (int64_t)c[2] * v2;
        acc += (int64_t)c[3] * y1;
        acc += (int64_t)c[4] * y2;
        /* The two words of acc; the high one saturated to 30 bits (one SSAT on the board). */
        hi = (int32_t)unlag_asr64(acc, 32u);
        lo = (uint32_t)((uint64_t)acc & 0xFFFFFFFFu);
        sat = hi < -(INT32_C(1) << 29) ? -(INT32_C(1) << 29)
            : hi > (INT32_C(1) << 29) - 1 ? (INT32_C(1) << 29) - 1
            : hi;
        if (sat != hi) {
            overflow = 1;
        }
        y = sat * 4 + (int32_t)(lo >> 30); /* floor(acc / 2^30) when not saturated */
        state->s[i][0] = y;
        state->s[i][1] = y1;
        state->s[i][2] = (int32_t)(lo & 0x3FFFFFFFu);
        v0 = y;
        v1 = y1;
        v2 = y2;
    }
    state->overflow |= overflow;
    return v0;
}

/* Nonzero when an output saturated since the flag was last taken
 * (Rust: DirectState::overflowed). */
static inline int unlag_overflowed(const unlag_state *state)
{
    return state->overflow;
}

/* Reads and clears the overflow flag (Rust: DirectState::take_overflow). */
static inline int unlag_take_overflow(unlag_state *state)
{
    const int overflow = state->overflow;
    state->overflow = 0;
    return overflow;
}
