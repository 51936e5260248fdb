/* ---- Reference implementation: the nonlinear-damping correction ---------------------------
 *
 * unlag::board::compensator::NonlinearDampingCoefficients::<f32, UNLAG_NONLINEAR_SECTION_COUNT>
 * in C99, bit for bit under the same conditions as unlag_process above. Add its output to
 * unlag_process's for the same probe sample:
 *
 *     unlag_nonlinear_state n;
 *     unlag_nonlinear_init(&n, first_reading);
 *     for each sample: u_hat = unlag_process(&s, y) + unlag_nonlinear_process(&n, y);
 *
 * The low-pass runs like the cascade above, with its input gain
 * unlag_nonlinear_gain * unlag_nonlinear_lowpass_gain (exact in double) folded into its first
 * section's b0, b1, b2 in double and rounded once to float, as the board does (constant
 * expressions: the compiler folds them). */

/* The previous probe sample and the low-pass's states s1, s2, for one channel. */
typedef struct {
    float previous;
    float s1[UNLAG_NONLINEAR_SECTION_COUNT];
    float s2[UNLAG_NONLINEAR_SECTION_COUNT];
} unlag_nonlinear_state;

/* Coefficient k (0..4: b0, b1, b2, a1, a2) of low-pass section i, the input gain folded into
 * the first section's numerator. */
static inline float unlag_nonlinear_coefficient(uint32_t i, uint32_t k)
{
    UNLAG_NO_FMA
    const double g = (double)unlag_nonlinear_gain * (double)unlag_nonlinear_lowpass_gain;
    const float c = unlag_nonlinear_sections[i][k];
    return (i == 0u && k < 3u) ? (float)(g * (double)c) : c;
}

/* The state after the constant probe signal y0 forever: no correction, no transient (Rust:
 * NonlinearDampingCoefficients::equilibrium). */
static inline void unlag_nonlinear_init(unlag_nonlinear_state *state, float y0)
{
    UNLAG_NO_FMA
    float v = 0.0f;
    uint32_t i;
    state->previous = y0;
    for (i = 0u; i < UNLAG_NONLINEAR_SECTION_COUNT; i++) {
        const float *c = unlag_nonlinear_sections[i];
        const double g = (i == 0u)
            ? (double)unlag_nonlinear_gain * (double)unlag_nonlinear_lowpass_gain
            : 1.0;
        const float dc = (float)(g * ((double)c[0] + (double)c[1] + (double)c[2]) /
                                 (1.0 + (double)c[3] + (double)c[4]));
        const float b0 = unlag_nonlinear_coefficient(i, 0u);
        const float b2 = unlag_nonlinear_coefficient(i, 2u);
        const float a2 = c[4];
        const float y = dc * v;
        state->s1[i] = y - b0 * v;
        state->s2[i] = b2 * v - a2 * y;
        v = y;
    }
}

/* The correction for the probe sample y: the low-pass of |d| d, d = y - (previous y) (Rust:
 * NonlinearDampingCoefficients::process). */
static inline float unlag_nonlinear_process(unlag_nonlinear_state *state, float y)
{
    UNLAG_NO_FMA
    const float d = y - state->previous;
    const float magnitude = (d < 0.0f) ? 0.0f - d : d;
    float v = magnitude * d;
    uint32_t i;
    state->previous = y;
    for (i = 0u; i < UNLAG_NONLINEAR_SECTION_COUNT; i++) {
        const float b0 = unlag_nonlinear_coefficient(i, 0u);
        const float b1 = unlag_nonlinear_coefficient(i, 1u);
        const float b2 = unlag_nonlinear_coefficient(i, 2u);
        const float a1 = unlag_nonlinear_sections[i][3], a2 = unlag_nonlinear_sections[i][4];
        const float out = state->s1[i] + b0 * v;
        state->s1[i] = state->s2[i] + b1 * v - a1 * out;
        state->s2[i] = b2 * v - a2 * out;
        v = out;
    }
    return v;
}
