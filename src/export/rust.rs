//! The Rust writer of a [`BoardImage`]: `const` items a Rust firmware `include!`s, the same
//! frame for every kind (the generated-by line, the set's header items, the section tables)
//! and the kind's own items between.

use std::fmt::Write as _;

use super::image::{BoardImage, SetTiming};

/// The comment under the generated-by line, per kind.
const F32_INTRO: &str = "\
// The board's compensator: u_hat = cascade(GAIN * y), each section [b0, b1, b2, a1, a2]
// with y = b0 x + b1 x[k-1] + b2 x[k-2] - a1 y[k-1] - a2 y[k-2]. The values are the f32
// coefficients the board runs, widened exactly to f64. Build the compensator with
// `unlag::board::compensator::CascadeCoefficients::<f32, SECTION_COUNT>::new(GAIN, &SECTIONS)`.
";
const NONLINEAR_INTRO: &str = "\
// Nonlinear damping: add `NonlinearDampingCoefficients::<f32, NONLINEAR_SECTION_COUNT>::new(
// NONLINEAR_GAIN, NONLINEAR_LOWPASS_GAIN, &NONLINEAR_SECTIONS)`'s output, fed the same
// probe sample, to the cascade's output.
";
const FIXED_INTRO: &str = "\
// The board's fixed-point compensator: input codes are Q1.31 of FULL_SCALE, outputs
// Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT. Build it with
// `unlag::board::fixed::FixedCascade::<SECTION_COUNT>::new(&SECTIONS)`.
";
const DIRECT_INTRO: &str = "\
// The board's direct-form fixed-point compensator: input codes are Q1.31 of FULL_SCALE,
// outputs Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT. Build it with
// `unlag::board::fixed::direct::DirectCascade::<SECTION_COUNT>::new(&SECTIONS)`.
";
const BANK_INTRO: &str = "\
// One compensator per gas temperature: u_hat = cascade(GAINS[i] * y), sections [b0, b1, b2, a1, a2]
// as in `unlag::board::compensator::CascadeCoefficients`, f32 values widened exactly to f64. Build
// `unlag::board::compensator::TemperatureBank::<f32, SET_COUNT, SECTION_COUNT>::new(
//     &TEMPERATURES_K, &GAINS, &SECTIONS, HYSTERESIS_K, WARM_UP_SAMPLES)`, run a channel with `process` and give it
// each temperature reading with `set_temperature` (nearest set, hysteresis, bumpless handover).
";

/// The doc line of the sample rate (every kind).
const SAMPLE_RATE: &str =
    "/// Sample rate in Hz the coefficients belong to.\npub const SAMPLE_RATE_HZ: f64";

/// An array literal with one row per line: `[`, `    row,` each, `]`.
fn array(rows: impl IntoIterator<Item = String>) -> String {
    let mut a = String::from("[\n");
    for row in rows {
        let _ = writeln!(a, "    {row},");
    }
    a.push(']');
    a
}

/// `[b0, b1, b2, a1, a2]` of an `f32` section, widened exactly to `f64`.
fn f32_row(section: &[f32; 5]) -> String {
    format!("[{}]", list(section, |c| format!("{:?}", f64::from(*c))))
}

/// `values` as a comma-separated list.
fn list<T>(values: impl IntoIterator<Item = T>, each: impl Fn(T) -> String) -> String {
    values.into_iter().map(each).collect::<Vec<_>>().join(", ")
}

/// The sample rate, delay and latency of one set.
fn timing(s: &mut String, t: &SetTiming) {
    let _ = write!(
        s,
        "{SAMPLE_RATE} = {:?};\n\
         /// The probe model's delay in samples.\npub const DELAY_SAMPLES: u32 = {};\n\
         /// Latency of the reconstruction behind the true pressure, in samples.\n\
         pub const LATENCY_SAMPLES: f64 = {:?};\n",
        t.sample_rate_hz, t.delay_samples, t.latency_samples
    );
}

/// A fixed-point set: its timing, scale and count, and its sections as struct literals of
/// type `ty`, each with the fields `fields` gives.
fn fixed<S>(
    s: &mut String,
    t: &SetTiming,
    (full_scale, output_exponent): (f64, i32),
    ty: &str,
    sections: &[S],
    fields: impl Fn(&S) -> String,
) {
    timing(s, t);
    let _ = writeln!(
        s,
        "/// ADC full scale in the probe's units: the input code 2^31.\n\
         pub const FULL_SCALE: f64 = {full_scale:?};\n\
         /// The output is Q1.31 of FULL_SCALE * 2^OUTPUT_EXPONENT.\n\
         pub const OUTPUT_EXPONENT: i32 = {output_exponent};\n\
         /// Number of sections.\npub const SECTION_COUNT: usize = {};\n\
         /// The sections.\npub const SECTIONS: [{ty}; SECTION_COUNT] = {};",
        sections.len(),
        array(sections.iter().map(|f| format!("{ty} {{ {} }}", fields(f))))
    );
}

impl BoardImage {
    /// Rust source: `const` items to `include!` in a firmware module, for
    /// [`crate::board::compensator::CascadeCoefficients::new`] (with
    /// [`crate::board::compensator::NonlinearDampingCoefficients::new`] for the correction),
    /// [`crate::board::fixed::FixedCascade::new`], [`crate::board::fixed::direct::DirectCascade::new`] or
    /// [`crate::board::compensator::TemperatureBank::new`]. `source` names the model file.
    #[must_use]
    pub fn to_rust(&self, source: &str) -> String {
        let (flags, intro) = match self {
            Self::F32(_) => ("", F32_INTRO),
            Self::Fixed(_) => (" --number-format fixed", FIXED_INTRO),
            Self::Direct(_) => (" --number-format fixed --fixed-form direct", DIRECT_INTRO),
            Self::Bank(_) => (" --temperatures", BANK_INTRO),
        };
        let mut s = String::new();
        let _ = write!(
            s,
            "// Generated by `unlag export --format rust{flags}` from {source} (unlag {}). Do not edit.\n{intro}",
            env!("CARGO_PKG_VERSION")
        );
        let t = self.timing();
        match self {
            Self::F32(c) => {
                timing(&mut s, &t);
                let _ = writeln!(
                    s,
                    "/// Number of second-order sections.\npub const SECTION_COUNT: usize = {};\n\
                     /// Input gain of the cascade.\npub const GAIN: f64 = {:?};\n\
                     /// Sections `[b0, b1, b2, a1, a2]`.\n\
                     pub const SECTIONS: [[f64; 5]; SECTION_COUNT] = {};",
                    c.sections.len(),
                    f64::from(c.gain),
                    array(c.sections.iter().map(f32_row))
                );
                if let Some(n) = &c.nonlinear {
                    let _ = writeln!(
                        s,
                        "{NONLINEAR_INTRO}\
                         /// Nonlinear-damping correction: gain per squared sample difference.\n\
                         pub const NONLINEAR_GAIN: f64 = {:?};\n\
                         /// Input gain of the correction's low-pass.\n\
                         pub const NONLINEAR_LOWPASS_GAIN: f64 = {:?};\n\
                         /// Sections of the correction's low-pass.\n\
                         pub const NONLINEAR_SECTION_COUNT: usize = {};\n\
                         /// The correction's low-pass sections `[b0, b1, b2, a1, a2]`.\n\
                         pub const NONLINEAR_SECTIONS: [[f64; 5]; NONLINEAR_SECTION_COUNT] = {};",
                        f64::from(n.gain),
                        f64::from(n.lowpass_gain),
                        n.lowpass.len(),
                        array(n.lowpass.iter().map(f32_row))
                    );
                }
            }
            Self::Fixed(c) => {
                let scale = (c.full_scale, c.output_exponent);
                fixed(
                    &mut s,
                    &t,
                    scale,
                    "unlag::board::fixed::FixedSection",
                    &c.sections,
                    |f| {
                        format!(
                            "a: {:?}, b: {:?}, c: {:?}, d: {}, shift: {}",
                            f.a, f.b, f.c, f.d, f.shift
                        )
                    },
                );
            }
            Self::Direct(c) => {
                let scale = (c.full_scale, c.output_exponent);
                let ty = "unlag::board::fixed::direct::DirectSection";
                fixed(&mut s, &t, scale, ty, &c.sections, |f| {
                    format!("b: {:?}, neg_a: {:?}", f.b, f.neg_a)
                });
            }
            Self::Bank(b) => {
                let sets = b.temperatures_k.iter().zip(&b.sets).map(|(t, set)| {
                    let rows: String = set
                        .sections
                        .iter()
                        .map(|sec| format!("        {},\n", f32_row(sec)))
                        .collect();
                    format!("// {t} K\n    [\n{rows}    ]")
                });
                let _ = writeln!(
                    s,
                    "{SAMPLE_RATE} = {:?};\n\
                     /// Number of sets (temperatures).\npub const SET_COUNT: usize = {};\n\
                     /// Second-order sections per set (the same in every set).\n\
                     pub const SECTION_COUNT: usize = {};\n\
                     /// Gas temperature of each set (K), ascending.\n\
                     pub const TEMPERATURES_K: [f64; SET_COUNT] = [{}];\n\
                     /// Hysteresis of the selection (K): half the step.\n\
                     pub const HYSTERESIS_K: f64 = {:?};\n\
                     /// Samples a new set warms up beside the old one before it takes over.\n\
                     pub const WARM_UP_SAMPLES: u32 = {};\n\
                     /// The probe model's delay at each temperature (samples).\n\
                     pub const DELAY_SAMPLES: [u32; SET_COUNT] = [{}];\n\
                     /// Latency of each set's reconstruction behind the true pressure (samples).\n\
                     pub const LATENCY_SAMPLES: [f64; SET_COUNT] = [{}];\n\
                     /// Input gain of each set's cascade.\n\
                     pub const GAINS: [f64; SET_COUNT] = [{}];\n\
                     /// Each set's sections `[b0, b1, b2, a1, a2]`.\n\
                     pub const SECTIONS: [[[f64; 5]; SECTION_COUNT]; SET_COUNT] = {};",
                    t.sample_rate_hz,
                    b.sets.len(),
                    b.section_count(),
                    list(&b.temperatures_k, |t| format!("{t:?}")),
                    b.hysteresis_k,
                    b.warm_up_samples,
                    list(&b.sets, |c| c.delay_samples.to_string()),
                    list(&b.sets, |c| format!("{:?}", c.latency_samples)),
                    list(&b.sets, |c| format!("{:?}", f64::from(c.gain))),
                    array(sets)
                );
            }
        }
        s
    }
}
