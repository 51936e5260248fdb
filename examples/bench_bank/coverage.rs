//! The stated uncertainty against the drawn truth: on the cases with no hidden effect, how
//! many of the plain fit's estimates (`loop.toml`, `[fit.uncertainty]`) lie within 3 of their
//! stated standard deviations of what was drawn.

use std::fmt::Write as _;
use std::path::Path;

use unlag::file::ModelFile;

use super::case::{Case, Generator, Kind};
use super::modelling_loop::LoopOutcome;

/// An estimate and its stated standard deviation.
pub type Estimate = (f64, f64);

/// What the plain fit stated.
#[derive(Debug, Clone, Copy)]
pub struct Stated {
    /// The DC gain the data gave (before a gain within noise of 1 is taken as 1).
    pub dc_gain: Estimate,
    /// The lowest resonance's natural frequency [Hz] and damping, where the fit has one.
    pub resonance: Option<(Estimate, Estimate)>,
}

/// Reads the statement of the model file `path`; `None` when it has none.
pub fn read(path: &Path) -> Option<Stated> {
    let file = ModelFile::load(path).ok()?;
    let fit = file.fit.as_ref()?;
    let u = fit.uncertainty.as_ref()?;
    let dc = fit.calibrated_from.unwrap_or_else(|| file.model.dc_gain());
    Some(Stated {
        dc_gain: (dc, u.dc_gain_std),
        resonance: u.resonances.first().map(|r| {
            (
                (r.natural_frequency_hz, r.natural_frequency_std_hz),
                (r.damping, r.damping_std),
            )
        }),
    })
}

/// The deviations of the estimates from the truth in units of the stated ones, sorted.
fn zs(pairs: impl Iterator<Item = (Estimate, f64)>) -> Vec<f64> {
    let mut z: Vec<f64> = pairs
        .filter(|((_, s), _)| *s > 0.0)
        .map(|((e, s), truth)| ((e - truth) / s).abs())
        .collect();
    z.sort_by(f64::total_cmp);
    z
}

/// One row: how many within 3, RMS of the deviations, worst.
fn row(what: &str, cases: usize, z: &[f64]) -> String {
    let within = z.iter().filter(|z| **z <= 3.0).count();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len().max(1) as f64).sqrt();
    format!(
        "| {what} | {cases} | {within}/{} | {rms:.2} | {} |",
        z.len(),
        z.last().map_or("-".into(), |w| format!("{w:.2}"))
    )
}

/// The table, under its heading.
pub fn report(rows: &[(Case, LoopOutcome)]) -> String {
    let plain: Vec<(&Case, Stated)> = rows
        .iter()
        .filter(|(c, _)| c.kind == Kind::None)
        .filter_map(|(c, o)| Some((c, o.stated?)))
        .collect();
    // The drawn resonance is the truth only for the lumped generator (a physics tube's is
    // the lumped approximation of its first mode), and only an underdamped one has it.
    let resonant: Vec<(&Case, (Estimate, Estimate))> = plain
        .iter()
        .filter(|(c, _)| matches!(c.generator, Generator::Lumped { zeta, .. } if zeta < 1.0))
        .filter_map(|(c, s)| Some((*c, s.resonance?)))
        .collect();
    let n_resonant = rows
        .iter()
        .filter(|(c, _)| {
            c.kind == Kind::None
                && matches!(c.generator, Generator::Lumped { zeta, .. } if zeta < 1.0)
        })
        .count();
    let frequency = zs(resonant.iter().map(|(c, (f, _))| (*f, c.f_hz)));
    let damping = zs(resonant.iter().map(|(c, (_, z))| (*z, c.zeta)));
    let dc = zs(plain.iter().map(|(_, s)| (s.dc_gain, 1.0)));
    let mut r = String::new();
    let _ = writeln!(r, "\n## The stated uncertainty against the drawn truth\n");
    let _ = writeln!(r, "The plain fit of each case with no hidden effect (`unlag fit --order 2 est.csv`, its `[fit.uncertainty]`) against what was drawn: the deviation of each estimate from the truth in units of its stated standard deviation. The frequency and damping are judged on the lumped generator's underdamped probes (a physics tube's drawn resonance is an approximation, not its truth); the DC gain, 1 in every probe, on all of them, as the data gave it before a gain within noise of 1 is taken as 1. A Gaussian estimate with a right deviation puts 99.7 % within 3, and the RMS near 1.\n");
    let _ = writeln!(
        r,
        "| quantity | cases | within 3 stated deviations | RMS of the deviations | worst |"
    );
    let _ = writeln!(r, "|---|---|---|---|---|");
    let _ = writeln!(r, "{}", row("natural frequency", n_resonant, &frequency));
    let _ = writeln!(r, "{}", row("damping", n_resonant, &damping));
    let _ = writeln!(
        r,
        "{}",
        row(
            "DC gain",
            rows.iter().filter(|(c, _)| c.kind == Kind::None).count(),
            &dc
        )
    );
    r
}
