//! The C writer of a [`BoardImage`]: a header for C firmware, the same frame for every kind
//! (the generated-by comment, the include guard, the `#define`s of the set, the arrays) and the
//! kind's own declarations between.
//!
//! A single set's header ends with a reference implementation of the board's kernel for its
//! number format, in C99 with `stdint.h` only: a state struct `unlag_state`, `unlag_reset()`,
//! `unlag_init()` (the equilibrium start) and the per-sample `unlag_process()`, bit for bit
//! what [`crate::board::compensator::CascadeCoefficients::process`],
//! [`crate::board::fixed::FixedCascade::process`] or [`crate::board::fixed::direct::DirectCascade::process`]
//! computes (`host-tests/c_reference.rs` compiles it and checks). The C is kept as C, in
//! `src/export/c/*.h`, and pasted in after the tables it reads.

use std::fmt::Write as _;

use super::bank::BoardBank;
use super::image::{BoardCoefficients, BoardImage, SetTiming};

/// The comment under the generated-by line, per kind (it closes the comment).
const F32_INTRO: &[&str] = &[
    " * The board's compensator: u_hat = cascade(unlag_gain * y), each section",
    " * {b0, b1, b2, a1, a2} with y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2].",
    " * CMSIS-DSP's arm_biquad_cascade_df1_f32 / _df2T_f32 take {b0, b1, b2, -a1, -a2}",
    " * (the opposite sign of a1, a2) and apply no input gain: scale the input, or b of",
    " * the first section, by unlag_gain. Or run the reference implementation at the end of",
    " * this header, the board's arithmetic bit for bit: unlag_state, unlag_init() (start in",
    " * equilibrium) or unlag_reset(), then unlag_process() per sample. */",
];
const FIXED_INTRO: &[&str] = &[
    " * Normal-form sections, per sample and section (u the section input, x its states):",
    " *   x1' = trunc((a11 x1 + a12 x2 + b1 u) >> 30)   x2' = trunc((a21 x1 + a22 x2 + b2 u) >> 30)",
    " *   y   = round((c1 x1 + c2 x2 + d u) >> shift)   in 64-bit accumulators, saturated to int32;",
    " * see unlag::board::fixed for the exact arithmetic. Input: Q1.31 of UNLAG_FULL_SCALE; output:",
    " * Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. The reference implementation at the",
    " * end of this header is that arithmetic bit for bit: unlag_state, unlag_init() (start in",
    " * equilibrium) or unlag_reset(), unlag_process() per sample, unlag_take_overflow(). */",
];
const DIRECT_INTRO: &[&str] = &[
    " * Direct-form-I sections with first-order error feedback, per sample and section (x the",
    " * section input, y its output, e the residual carried, all int32, 64-bit accumulator):",
    " *   acc = e + b0 x0 + b1 x1 + b2 x2 + na1 y1 + na2 y2      (na = -a: the NEGATED denominator)",
    " *   y = acc >> 30 (floor; high word saturated to 30 bits), e = acc & (2^30 - 1);",
    " * see unlag::board::fixed::direct for the exact arithmetic. Input: Q1.31 of UNLAG_FULL_SCALE;",
    " * output: Q1.31 of UNLAG_FULL_SCALE * 2^UNLAG_OUTPUT_EXPONENT. The reference implementation",
    " * at the end of this header is that arithmetic bit for bit: unlag_state, unlag_init() (start",
    " * in equilibrium) or unlag_reset(), unlag_process() per sample, unlag_take_overflow(). */",
];
const BANK_INTRO: &[&str] = &[
    " * One compensator per gas temperature: u_hat = cascade(unlag_bank_gains[i] * y), each section",
    " *   y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]   (crate's sign convention;",
    " * CMSIS-DSP's biquads want a1, a2 negated). Pick the set with unlag_bank_select() on each",
    " * temperature reading; on a change, start the new set's states at its equilibrium for the last",
    " * input, run it beside the old set (whose output you keep) for UNLAG_BANK_WARM_UP_SAMPLES",
    " * samples, then switch to it: no step (see unlag::board::compensator::bank). */",
];

/// The comment before the nonlinear-damping correction's declarations (its continuation
/// lines start with `*`, unindented, as they always have).
const NONLINEAR_INTRO: &str = "
/* Nonlinear damping: with d = y[k] - y[k-1], add
* cascade(unlag_nonlinear_gain * unlag_nonlinear_lowpass_gain * |d| d) through the
* sections below to the compensator's output for the same sample
* (unlag_nonlinear_process() at the end of this header). */
";

/// The reference implementations pasted after the tables (C99, `stdint.h` only), kept as C
/// files: the `f32` cascade, its nonlinear-damping correction, the integer helpers of both
/// fixed-point forms, the normal form and the direct form.
const F32_KERNEL: &str = include_str!("c/f32.h");
const NONLINEAR_KERNEL: &str = include_str!("c/nonlinear.h");
const INT_HELPERS: &str = include_str!("c/int.h");
const FIXED_KERNEL: &str = include_str!("c/fixed.h");
const DIRECT_KERNEL: &str = include_str!("c/direct.h");

/// The bank's selection function, the board's rule in C.
const BANK_SELECT: &str = "\
/* The set to use at temp_k for a channel on set current: current while temp_k stays within its
 * midpoints widened by half the hysteresis, else the nearest set (the ends outside the table).
 * A NaN reading keeps current. */
static inline uint32_t unlag_bank_select(uint32_t current, float temp_k)
{
    const float half = 0.5f * UNLAG_BANK_HYSTERESIS_K;
    uint32_t i, nearest = 0u;
    if (current >= UNLAG_BANK_SET_COUNT) current = UNLAG_BANK_SET_COUNT - 1u;
    if (temp_k != temp_k) return current;
    if ((current == 0u || temp_k >= 0.5f * (unlag_bank_temperatures_k[current - 1u] + unlag_bank_temperatures_k[current]) - half) &&
        (current + 1u >= UNLAG_BANK_SET_COUNT || temp_k <= 0.5f * (unlag_bank_temperatures_k[current] + unlag_bank_temperatures_k[current + 1u]) + half))
        return current;
    for (i = 0u; i + 1u < UNLAG_BANK_SET_COUNT; i++)
        if (temp_k > 0.5f * (unlag_bank_temperatures_k[i] + unlag_bank_temperatures_k[i + 1u])) nearest = i + 1u;
    return nearest;
}
";

/// `declaration = {`, `    row,` each, `};`.
fn array(s: &mut String, declaration: &str, rows: impl IntoIterator<Item = String>) {
    let _ = writeln!(s, "{declaration} = {{");
    for row in rows {
        let _ = writeln!(s, "    {row},");
    }
    s.push_str("};\n");
}

/// `{x, y, ...}`, each value as `each` writes it.
fn braced<T>(values: impl IntoIterator<Item = T>, each: impl Fn(T) -> String) -> String {
    let v: Vec<String> = values.into_iter().map(each).collect();
    format!("{{{}}}", v.join(", "))
}

/// `{x, y, ...}` of `float`s, exactly the board's `f32` values.
fn floats(values: impl IntoIterator<Item = f32>) -> String {
    braced(values, |x| format!("{x:?}f"))
}

/// An `int32_t` (`i32::MIN` as `INT32_MIN`, which C cannot write as a literal).
fn int(x: &i32) -> String {
    if *x == i32::MIN {
        "INT32_MIN".to_string()
    } else {
        x.to_string()
    }
}

/// The `#define`s of one set's sample rate, delay and latency.
fn timing(s: &mut String, t: &SetTiming) {
    let _ = write!(
        s,
        "#define UNLAG_SAMPLE_RATE_HZ {:?} /* Hz */\n\
         #define UNLAG_DELAY_SAMPLES {}u /* model delay, samples */\n\
         #define UNLAG_LATENCY_SAMPLES {:?} /* reconstruction latency, samples */\n",
        t.sample_rate_hz, t.delay_samples, t.latency_samples
    );
}

/// A fixed-point set: timing, scale and count `#define`s, then the `int32_t` table
/// `unlag_{name}_sections` of `columns` values per section, described by `layout`.
fn fixed(
    s: &mut String,
    t: &SetTiming,
    (full_scale, output_exponent): (f64, i32),
    (name, columns, layout): (&str, usize, &str),
    rows: Vec<String>,
) {
    timing(s, t);
    let _ = writeln!(
        s,
        "#define UNLAG_FULL_SCALE {full_scale:?} /* input code 2^31 */\n\
         #define UNLAG_OUTPUT_EXPONENT {output_exponent}\n\
         #define UNLAG_SECTION_COUNT {}u\n\n\
         /* {layout} */",
        rows.len()
    );
    let declaration =
        format!("static const int32_t unlag_{name}_sections[UNLAG_SECTION_COUNT][{columns}]");
    array(s, &declaration, rows);
}

impl BoardImage {
    /// A C header: `#define`s and `static const` arrays (`float` for `f32`, `int32_t` for
    /// fixed point), then for one set the reference implementation of the board's kernel
    /// (`unlag_state`, `unlag_reset()`, `unlag_init()`, `unlag_process()`; see the module
    /// docs), and for a bank the selection function `unlag_bank_select()` with the board's
    /// rule. `source` names the model file.
    #[must_use]
    pub fn to_c(&self, source: &str) -> String {
        let (flags, intro, guard) = match self {
            Self::F32(_) => ("", F32_INTRO, "UNLAG_COEFFICIENTS_H"),
            Self::Fixed(_) => (
                " --number-format fixed",
                FIXED_INTRO,
                "UNLAG_FIXED_COEFFICIENTS_H",
            ),
            Self::Direct(_) => (
                " --number-format fixed --fixed-form direct",
                DIRECT_INTRO,
                "UNLAG_DIRECT_COEFFICIENTS_H",
            ),
            Self::Bank(_) => (" --temperatures", BANK_INTRO, "UNLAG_BANK_H"),
        };
        let mut s = String::new();
        let _ = writeln!(
            s,
            "/* Generated by `unlag export --format c{flags}` from {source} (unlag {}). Do not edit.\n\
             {}\n\
             #ifndef {guard}\n#define {guard}\n",
            env!("CARGO_PKG_VERSION"),
            intro.join("\n")
        );
        s.push_str("#include <stdint.h>\n\n");
        let t = self.timing();
        match self {
            Self::F32(c) => f32_body(&mut s, c, &t),
            Self::Fixed(c) => {
                let rows = c.sections.iter().map(|f| {
                    let shift = i32::from(f.shift);
                    braced(
                        f.a.iter().chain(&f.b).chain(&f.c).chain([&f.d, &shift]),
                        int,
                    )
                });
                let layout = "{a11, a12, a21, a22, b1, b2, c1, c2, d, shift} per section";
                let scale = (c.full_scale, c.output_exponent);
                fixed(&mut s, &t, scale, ("fixed", 10, layout), rows.collect());
                let _ = write!(s, "\n{INT_HELPERS}\n{FIXED_KERNEL}");
            }
            Self::Direct(c) => {
                let rows = c
                    .sections
                    .iter()
                    .map(|f| braced(f.b.iter().chain(&f.neg_a), int));
                let layout = "{b0, b1, b2, -a1, -a2} per section, Q2.30";
                let scale = (c.full_scale, c.output_exponent);
                fixed(&mut s, &t, scale, ("direct", 5, layout), rows.collect());
                let _ = write!(s, "\n{INT_HELPERS}\n{DIRECT_KERNEL}");
            }
            Self::Bank(b) => bank_body(&mut s, b, &t),
        }
        let _ = write!(s, "\n#endif /* {guard} */\n");
        s
    }
}

/// The f32 cascade's header body: its timing, gain and sections, the nonlinear damping's
/// correction when the model has one, and the reference kernels.
fn f32_body(s: &mut String, c: &BoardCoefficients, t: &SetTiming) {
    timing(s, t);
    let _ = writeln!(
        s,
        "#define UNLAG_SECTION_COUNT {}u\n\n\
         static const float unlag_gain = {:?}f;",
        c.sections.len(),
        c.gain
    );
    let sections = c.sections.iter().map(|sec| floats(*sec));
    array(
        s,
        "static const float unlag_sections[UNLAG_SECTION_COUNT][5]",
        sections,
    );
    if let Some(n) = &c.nonlinear {
        let _ = writeln!(
            s,
            "{NONLINEAR_INTRO}\
             #define UNLAG_NONLINEAR_SECTION_COUNT {}u\n\
             static const float unlag_nonlinear_gain = {:?}f;\n\
             static const float unlag_nonlinear_lowpass_gain = {:?}f;",
            n.lowpass.len(),
            n.gain,
            n.lowpass_gain
        );
        array(
            s,
            "static const float unlag_nonlinear_sections[UNLAG_NONLINEAR_SECTION_COUNT][5]",
            n.lowpass.iter().map(|sec| floats(*sec)),
        );
    }
    let _ = write!(s, "\n{F32_KERNEL}");
    // A design's low-pass has at least one section (C has no empty array).
    if c.nonlinear.as_ref().is_some_and(|n| !n.lowpass.is_empty()) {
        let _ = write!(s, "\n{NONLINEAR_KERNEL}");
    }
}

/// The temperature bank's header body: its sets by temperature and the selection code.
fn bank_body(s: &mut String, b: &BoardBank, t: &SetTiming) {
    let _ = writeln!(
        s,
        "#define UNLAG_BANK_SAMPLE_RATE_HZ {:?} /* Hz */\n\
         #define UNLAG_BANK_SET_COUNT {}u\n\
         #define UNLAG_BANK_SECTION_COUNT {}u\n\
         #define UNLAG_BANK_HYSTERESIS_K {:?}f /* K: half the step */\n\
         #define UNLAG_BANK_WARM_UP_SAMPLES {}u\n\n\
         static const float unlag_bank_temperatures_k[UNLAG_BANK_SET_COUNT] = {};\n\
         static const uint32_t unlag_bank_delay_samples[UNLAG_BANK_SET_COUNT] = {};\n\
         static const float unlag_bank_gains[UNLAG_BANK_SET_COUNT] = {};\n\
         /* {{b0, b1, b2, a1, a2}} per section, per set */",
        t.sample_rate_hz,
        b.sets.len(),
        b.section_count(),
        narrow(b.hysteresis_k),
        b.warm_up_samples,
        floats(b.temperatures_k.iter().map(|t| narrow(*t))),
        braced(&b.sets, |c| format!("{}u", c.delay_samples)),
        floats(b.sets.iter().map(|c| c.gain)),
    );
    let sets = b.temperatures_k.iter().zip(&b.sets).map(|(t, set)| {
        let rows: String = set
            .sections
            .iter()
            .map(|sec| format!("        {},\n", floats(*sec)))
            .collect();
        format!("{{ /* {t} K */\n{rows}    }}")
    });
    array(
        s,
        "static const float unlag_bank_sections[UNLAG_BANK_SET_COUNT][UNLAG_BANK_SECTION_COUNT][5]",
        sets,
    );
    let _ = write!(s, "\n{BANK_SELECT}");
}

#[allow(clippy::cast_possible_truncation)]
fn narrow(x: f64) -> f32 {
    x as f32
}
