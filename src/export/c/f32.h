/* ---- Reference implementation: the f32 cascade --------------------------------------------
 *
 * unlag::board::compensator::CascadeCoefficients::<f32, UNLAG_SECTION_COUNT>::process in C99 (stdint.h
 * only: no libm, no allocation), bit for bit, on a target where float is IEEE single
 * precision evaluated as float (FLT_EVAL_METHOD 0: any FPU or soft-float library; not the
 * x87) and a * b + c is not fused into one rounding. Build with -ffp-contract=off: GCC fuses
 * by default in its GNU modes, and a Cortex-M4F or M7 has a fused multiply-add (the board's
 * own kernels round each product, as this code does). Clang is told so below.
 *
 *     unlag_state s;
 *     unlag_init(&s, first_reading);          (or unlag_reset(&s): all states zero)
 *     for each sample: u_hat = unlag_process(&s, y);
 *
 * One unlag_state per channel; the coefficients are the tables above, shared by every channel.
 * The input gain unlag_gain is folded into the first section's b0, b1, b2, as the board does:
 * a product of two floats is exact in double, so it rounds to the same float in float
 * arithmetic (and the compiler folds these products of constants). Each section, in the
 * crate's sign convention (a1, a2 as in 1 + a1 z^-1 + a2 z^-2), runs in transposed direct
 * form II, in this order:
 *
 *     y  = s1 + b0 x
 *     s1 = (s2 + b1 x) - a1 y
 *     s2 = b2 x - a2 y
 */

#if defined(__clang__)
#define UNLAG_NO_FMA _Pragma("STDC FP_CONTRACT OFF")
#else
#define UNLAG_NO_FMA
#endif

/* The states s1, s2 of each section, for one channel. */
typedef struct {
    float s1[UNLAG_SECTION_COUNT];
    float s2[UNLAG_SECTION_COUNT];
} unlag_state;

/* Every state zero (Rust: CascadeState::default()). */
static inline void unlag_reset(unlag_state *state)
{
    uint32_t i;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        state->s1[i] = 0.0f;
        state->s2[i] = 0.0f;
    }
}

/* The state after the constant input x0 forever: a probe that already reads a steady
 * pressure starts with no transient (Rust: CascadeCoefficients::equilibrium). Each section's
 * DC gain is formed in double and rounded once to float, as the board does when it builds
 * the coefficients; the rest is float. */
static inline void unlag_init(unlag_state *state, float x0)
{
    UNLAG_NO_FMA
    float v = x0;
    uint32_t i;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        const float *c = unlag_sections[i];
        const float g = (i == 0u) ? unlag_gain : 1.0f;
        const double gd = (double)g;
        const float dc = (float)(gd * ((double)c[0] + (double)c[1] + (double)c[2]) /
                                 (1.0 + (double)c[3] + (double)c[4]));
        const float b0 = g * c[0], b2 = g * c[2], a2 = c[4];
        const float y = dc * v;
        state->s1[i] = y - b0 * v;
        state->s2[i] = b2 * v - a2 * y;
        v = y;
    }
}

/* One probe sample x through the cascade: the reconstructed pressure, UNLAG_LATENCY_SAMPLES
 * samples late (Rust: CascadeCoefficients::process). 5 multiplies per section. */
static inline float unlag_process(unlag_state *state, float x)
{
    UNLAG_NO_FMA
    float v = x;
    uint32_t i;
    for (i = 0u; i < UNLAG_SECTION_COUNT; i++) {
        const float *c = unlag_sections[i];
        const float g = (i == 0u) ? unlag_gain : 1.0f;
        const float b0 = g * c[0], b1 = g * c[1], b2 = g * c[2], a1 = c[3], a2 = c[4];
        const float y = state->s1[i] + b0 * v;
        state->s1[i] = state->s2[i] + b1 * v - a1 * y;
        state->s2[i] = b2 * v - a2 * y;
        v = y;
    }
    return v;
}
