//! Fixtures shared by the unit tests: deterministic noise (no crate and no OS entropy), a
//! second-order probe, and a bare model file.

/// `n` samples of unit-variance noise, close enough to Gaussian (the sum of 12 uniforms less
/// 6) from an LCG seeded with `seed`.
pub(crate) fn gaussian(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            (0..12)
                .map(|_| {
                    s = s
                        .wrapping_mul(6_364_136_223_846_793_005)
                        .wrapping_add(1_442_695_040_888_963_407);
                    (s >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        })
        .collect()
}

/// `x` with [`gaussian`] noise of standard deviation `sd` (draw `seed`) added.
pub(crate) fn with_noise(x: &[f64], sd: f64, seed: u64) -> Vec<f64> {
    x.iter()
        .zip(gaussian(x.len(), seed))
        .map(|(v, n)| v + sd * n)
        .collect()
}

/// A second-order probe: natural frequency `f` Hz, damping `zeta`, sampled at `fs` behind
/// `delay` samples, unit DC gain; with its continuous pole `s` (upper half-plane).
pub(crate) fn second_order(
    f: f64,
    zeta: f64,
    fs: f64,
    delay: usize,
) -> (crate::fit::model::Model, crate::poly::Complex) {
    let w = 2.0 * std::f64::consts::PI * f;
    let s = crate::poly::Complex::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt());
    let z = (s / fs).exp();
    let a = vec![-2.0 * z.re, z.norm_sqr()];
    let g = 1.0 + a[0] + a[1];
    let model = crate::fit::model::Model {
        fs,
        delay,
        a,
        b: vec![0.0, 0.6 * g, 0.4 * g],
    };
    (model, s)
}

/// An overdamped probe (a capillary): real corners `f_slow` and `f_fast` Hz, sampled at `fs`
/// behind `delay` samples, unit DC gain, the numerator of [`second_order`].
pub(crate) fn overdamped(
    f_slow: f64,
    f_fast: f64,
    fs: f64,
    delay: usize,
) -> crate::fit::model::Model {
    let z = |f: f64| (-2.0 * std::f64::consts::PI * f / fs).exp();
    let a = vec![-(z(f_slow) + z(f_fast)), z(f_slow) * z(f_fast)];
    let g = 1.0 + a[0] + a[1];
    crate::fit::model::Model {
        fs,
        delay,
        a,
        b: vec![0.0, 0.6 * g, 0.4 * g],
    }
}

/// A wake traverse at `fs`: a tunnel's oscillation at `tunnel_hz` (a tenth of the level) and
/// three wakes, 0.5, 0.3 and 0.2 deep, `lead + n` samples: the first `lead` are what came
/// before a record that starts in the middle of it, and the wakes are counted from there.
pub(crate) fn traverse(fs: f64, tunnel_hz: f64, lead: usize, n: usize) -> Vec<f64> {
    (0..lead + n)
        .map(|k| {
            let t = k as f64 / fs;
            1.0 + 0.1 * (2.0 * std::f64::consts::PI * tunnel_hz * t).sin()
                - 0.5 * (-((t - 0.08) / 0.02).powi(2)).exp()
                - 0.3 * (-((t - 0.35) / 0.01).powi(2)).exp()
                - 0.2 * (-((t - 0.5) / 0.01).powi(2)).exp()
        })
        .collect()
}

/// Two steps from rest, of 1000 and of 150, 1500 samples at 2 kHz, through a resonant probe
/// with a quadratic loss that takes half the big step off the input at its peak rate:
/// `(the probe's linear part, the big step, the small one, the loss)`.
pub(crate) fn two_step_sizes() -> (crate::fit::model::Model, Vec<f64>, Vec<f64>, f64) {
    let truth = crate::fit::model::Model {
        fs: 2000.0,
        delay: 2,
        a: vec![-1.8, 0.85],
        b: vec![0.03, 0.02],
    };
    let step = |size: f64| -> Vec<f64> {
        (0..1500)
            .map(|k| if k < 100 { 0.0 } else { size })
            .collect()
    };
    let (big, small) = (step(1000.0), step(150.0));
    let q = crate::effects::quadratic_rate(&truth.simulate(&big), truth.fs);
    let gain = 0.5 * 1000.0 / q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    (truth, big, small, gain)
}

/// The model file of `model` alone: no fit, sources, compensator, effects, history or probe.
pub(crate) fn model_file(model: crate::fit::model::Model) -> crate::file::ModelFile {
    crate::file::ModelFile {
        format_version: crate::file::FORMAT_VERSION,
        model,
        fit: None,
        sources: Vec::new(),
        inverse: None,
        effects: Vec::new(),
        history: Vec::new(),
        probe: None,
        board: Default::default(),
    }
}

/// The mean of `estimates`, their spread (the sample standard deviation), and the spread
/// over the mean of the deviations `stated` for them: about 1 when those are right.
pub(crate) fn spread_over_stated(estimates: &[f64], stated: &[f64]) -> (f64, f64, f64) {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let m = mean(estimates);
    let spread = (estimates.iter().map(|x| (x - m).powi(2)).sum::<f64>()
        / (estimates.len() - 1) as f64)
        .sqrt();
    (m, spread, spread / mean(stated))
}

/// The evidence of a capillary's probe (8 kHz, corners 4 and 60 Hz) after a step at sample
/// `onset` of `n`, with white noise on the probe and `extra` (of the time in seconds) added to
/// its output: what the diagnosis reads of a residual of that shape.
pub(crate) fn capillary_evidence(
    n: usize,
    onset: usize,
    extra: impl Fn(f64) -> f64,
) -> crate::evidence::TestEvidence {
    let fs = 8000.0;
    let model = overdamped(4.0, 60.0, fs, 3);
    let u: Vec<f64> = (0..n)
        .map(|k| if k < onset { 0.0 } else { 1000.0 })
        .collect();
    let clean = model.simulate(&u);
    let y: Vec<f64> = with_noise(&clean, 0.5, 7)
        .iter()
        .enumerate()
        .map(|(k, v)| v + extra(k as f64 / fs))
        .collect();
    crate::evidence::TestEvidence::measure(
        "t",
        crate::fit::TestRole::Validation,
        &model,
        (&u, &y),
        &clean,
    )
}
