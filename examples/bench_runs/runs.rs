//! A probe's step test and its runs unlike it: what the pressure does in each (drawn from
//! the probe's time scales), the probe simulated on it with the input resolved finer than
//! a sample, and the two channels as recorded (white noise, a 16-bit ADC whose range the
//! experimenter sets for that run).

use std::f64::consts::PI;

use num_complex::Complex64;

use super::draw::Rng;
use super::probe::{gas, Dynamics, Probe};
use super::simulate::StateSpace;
use unlag::physics::fft::{convolve, fft_in_place};
use unlag::physics::simulate::{impulse_response, Adc};
use unlag::physics::Excitation;

/// What a record is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunKind {
    /// The calibration step the model is fitted on.
    StepTest,
    /// A mean with band-limited Gaussian fluctuations.
    Turbulence,
    /// A traverse through a cascade's wakes.
    Wake,
    /// A shock tube's incident shock and, a few time scales later, its reflection.
    ReflectedShock,
    /// A step of another size and sign than the calibration's.
    Step,
}

/// The runs of every probe, in report order (the step test is not one).
pub const RUN_KINDS: [RunKind; 4] = [
    RunKind::Turbulence,
    RunKind::Wake,
    RunKind::ReflectedShock,
    RunKind::Step,
];

impl RunKind {
    /// Name in the report, the CSV and the file names.
    pub fn name(self) -> &'static str {
        match self {
            Self::StepTest => "step-test",
            Self::Turbulence => "turbulence",
            Self::Wake => "wake",
            Self::ReflectedShock => "reflected-shock",
            Self::Step => "step",
        }
    }
}

/// The true pressure of a run.
#[derive(Debug, Clone, PartialEq)]
pub enum Pressure {
    /// A base level plus facility events, each `(excitation, time of the event [s])`.
    Events {
        /// Level before the first event [Pa].
        base_pa: f64,
        /// The events.
        events: Vec<(Excitation, f64)>,
    },
    /// A mean plus Gaussian fluctuations of spectrum
    /// `S(f) = (1 + (f/corner)^2)^(-7/6)` (von Karman's, the inertial range's `f^(-7/3)` of
    /// pressure), rolled off by a raised cosine from `0.7 limit` to `limit`.
    Turbulence {
        /// Mean [Pa].
        mean_pa: f64,
        /// RMS of the fluctuations [Pa].
        rms_pa: f64,
        /// Corner of the spectrum [Hz].
        corner_hz: f64,
        /// Band limit [Hz].
        limit_hz: f64,
        /// Seed of the fluctuations.
        seed: u64,
    },
}

impl Pressure {
    /// `count` values at `rate` from time `t0` [s], each the mean over its interval
    /// (fluctuations: band-limited, their samples are their means).
    pub fn sample(&self, rate: f64, t0: f64, count: usize) -> Result<Vec<f64>, String> {
        match self {
            Self::Events { base_pa, events } => Ok((0..count)
                .map(|i| {
                    let t = t0 + i as f64 / rate;
                    base_pa
                        + events
                            .iter()
                            .map(|(e, at)| e.cell_average(t - at, 1.0 / rate))
                            .sum::<f64>()
                })
                .collect()),
            Self::Turbulence {
                mean_pa,
                rms_pa,
                corner_hz,
                limit_hz,
                seed,
            } => {
                let x = fluctuations(rate, count, *corner_hz, *limit_hz, *seed)?;
                Ok(x.iter().map(|v| mean_pa + rms_pa * v).collect())
            }
        }
    }
}

/// Unit-RMS Gaussian fluctuations of [`Pressure::Turbulence`]'s spectrum, `count` samples
/// at `rate`, by random phases and Rayleigh amplitudes on an FFT grid.
fn fluctuations(
    rate: f64,
    count: usize,
    corner_hz: f64,
    limit_hz: f64,
    seed: u64,
) -> Result<Vec<f64>, String> {
    let n = count.max(2).next_power_of_two();
    let mut rng = Rng::new(seed);
    let taper_from = 0.7 * limit_hz;
    let amplitude = |f: f64| {
        let taper = if f <= taper_from {
            1.0
        } else if f >= limit_hz {
            0.0
        } else {
            0.5 * (1.0 + (PI * (f - taper_from) / (limit_hz - taper_from)).cos())
        };
        (1.0 + (f / corner_hz).powi(2)).powf(-7.0 / 12.0) * taper
    };
    let mut spec = vec![Complex64::new(0.0, 0.0); n];
    for k in 1..n / 2 {
        let a = amplitude(k as f64 * rate / n as f64);
        let c = Complex64::new(a * rng.gauss(), a * rng.gauss());
        spec[k] = c;
        spec[n - k] = c.conj();
    }
    fft_in_place(&mut spec, true).map_err(|e| e.to_string())?;
    let x: Vec<f64> = spec.iter().take(count).map(|c| c.re).collect();
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    if rms.is_nan() || rms <= 0.0 {
        return Err("turbulence: no fluctuation below the band limit".into());
    }
    Ok(x.iter().map(|v| v / rms).collect())
}

/// One record to make: its kind, its pressure, its length and its words.
#[derive(Debug, Clone)]
pub struct Run {
    /// Kind.
    pub kind: RunKind,
    /// The true pressure.
    pub pressure: Pressure,
    /// Samples.
    pub n: usize,
    /// Its parameters in words.
    pub text: String,
}

/// Samples for `seconds` at the probe's rate, 4 000 to 20 000 (2 000 for a short step test).
fn samples(probe: &Probe, seconds: f64, min: usize) -> usize {
    (seconds * probe.fs).ceil().clamp(min as f64, 20_000.0) as usize
}

/// The record's length for the probe's slowest dynamics: eight time constants after an
/// event at a fifth of the record.
fn settled_samples(probe: &Probe, min: usize) -> usize {
    samples(probe, 8.0 * probe.slowest_s / 0.8, min)
}

/// The calibration step test: a shock-tube step of the probe's step size from 0.
pub fn step_test(probe: &Probe, rng: &mut Rng) -> Run {
    let n = settled_samples(probe, 2000);
    let at = rng.range(0.1, 0.2) * n as f64 / probe.fs;
    Run {
        kind: RunKind::StepTest,
        pressure: Pressure::Events {
            base_pa: 0.0,
            events: vec![(Excitation::shock_tube(probe.step_pa), at)],
        },
        n,
        text: format!("step 0 -> {:.0} Pa", probe.step_pa),
    }
}

/// The probe's runs unlike its step test, one of each kind, drawn from its time scales.
pub fn draw_runs(probe: &Probe, rng: &mut Rng) -> Vec<Run> {
    let s = probe.step_pa;
    let band = probe.band_hz;
    // The probe's time scale: its band's time constant.
    let tau = 1.0 / (2.0 * PI * band);
    let settled = settled_samples(probe, 4000);
    let event_at = |rng: &mut Rng, n: usize| rng.range(0.15, 0.25) * n as f64 / probe.fs;
    RUN_KINDS
        .iter()
        .map(|&kind| match kind {
            RunKind::Turbulence => {
                let mean_pa = s * rng.range(-0.5, 1.5);
                let rms_pa = s * rng.log_range(0.03, 0.15);
                let corner_hz = band * rng.log_range(0.1, 1.0);
                let limit_hz = (band * rng.log_range(1.5, 5.0)).min(0.45 * probe.fs);
                let n = samples(probe, (200.0 / corner_hz).max(8.0 * probe.slowest_s), 4000);
                Run {
                    kind,
                    pressure: Pressure::Turbulence {
                        mean_pa,
                        rms_pa,
                        corner_hz,
                        limit_hz,
                        seed: rng.next_u64(),
                    },
                    n,
                    text: format!(
                        "mean {mean_pa:.0} Pa, rms {rms_pa:.0} Pa, corner {corner_hz:.4e} Hz, limit {limit_hz:.4e} Hz"
                    ),
                }
            }
            RunKind::Wake => {
                let depth = s * rng.range(0.3, 0.8);
                // At least six wakes and two tunnel periods after the event in the longest
                // record (20 000 samples): a slow probe sees its wakes closer to its band.
                let longest_s = 20_000.0 / probe.fs;
                let wake_hz = (band * rng.log_range(0.05, 0.4)).max(6.0 / (0.75 * longest_s));
                let tunnel_hz = (wake_hz * rng.range(0.05, 0.2)).max(2.0 / (0.75 * longest_s));
                let n = samples(
                    probe,
                    (8.0 / wake_hz).max(2.0 / tunnel_hz).max(8.0 * probe.slowest_s) / 0.75,
                    4000,
                );
                let wake = Excitation::CascadeWake {
                    wake_depth_pa: depth,
                    wake_hz,
                    wake_width: rng.range(0.05, 0.15),
                    tunnel_amplitude_pa: depth * rng.range(0.05, 0.25),
                    tunnel_hz,
                };
                let base_pa = s * rng.range(0.5, 1.2);
                Run {
                    kind,
                    pressure: Pressure::Events {
                        base_pa,
                        events: vec![(wake, event_at(rng, n))],
                    },
                    n,
                    text: format!(
                        "base {base_pa:.0} Pa, wakes {depth:.0} Pa at {wake_hz:.4e} Hz, tunnel {tunnel_hz:.4e} Hz"
                    ),
                }
            }
            RunKind::ReflectedShock => {
                let incident = s * rng.range(0.5, 1.0);
                let reflected = incident * rng.range(1.0, 1.6);
                let after_s = tau * rng.log_range(2.0, 10.0);
                let at = event_at(rng, settled);
                Run {
                    kind,
                    pressure: Pressure::Events {
                        base_pa: 0.0,
                        events: vec![
                            (Excitation::shock_tube(incident), at),
                            (Excitation::shock_tube(reflected), at + after_s),
                        ],
                    },
                    n: settled,
                    text: format!(
                        "incident {incident:.0} Pa, reflected +{reflected:.0} Pa ({:.2}x) after {:.3e} s",
                        (incident + reflected) / incident,
                        after_s
                    ),
                }
            }
            RunKind::Step | RunKind::StepTest => {
                let size = s * rng.sign() * rng.range(0.3, 2.0);
                let base_pa = s * rng.range(-0.5, 0.5);
                Run {
                    kind,
                    pressure: Pressure::Events {
                        base_pa,
                        events: vec![(Excitation::shock_tube(size), event_at(rng, settled))],
                    },
                    n: settled,
                    text: format!(
                        "step {base_pa:.0} -> {:.0} Pa ({:+.2} steps)",
                        base_pa + size,
                        size / s
                    ),
                }
            }
        })
        .collect()
}

/// The noise-free `(pressure, probe)` of `run` at the probe's rate: the pressure resolved
/// `over` times finer than a sample and from before the record (the probe's response to
/// what came before has decayed by its first sample), each channel's sample the fine value
/// at its instant.
pub fn clean(probe: &Probe, run: &Run) -> Result<(Vec<f64>, Vec<f64>), String> {
    let fs = probe.fs;
    let (fine_p, fine_y, pre, over) = match &probe.dynamics {
        Dynamics::Lumped { stages, delay } => {
            let over = 4;
            let rate = fs * over as f64;
            let pre = ((6.0 * probe.slowest_s * rate).ceil() as usize).min(run.n * over);
            let p = run
                .pressure
                .sample(rate, -(pre as f64) / rate, pre + run.n * over)?;
            let y = StateSpace::cascade(stages).simulate(&p, delay * over, rate);
            (p, y, pre, over)
        }
        Dynamics::Physics { line } => {
            let response = unlag::physics::Probe::new(line.clone(), gas());
            let h = |s| response.response(s);
            // The finest rate whose impulse response decays within the longest transform.
            let (ir, over) = [16, 8, 4, 2]
                .iter()
                .find_map(|&over| {
                    impulse_response(&h, fs * over as f64, 0)
                        .ok()
                        .map(|ir| (ir, over))
                })
                .ok_or("physics: the impulse response does not decay")?;
            let rate = fs * over as f64;
            let pre = ir.taps.len();
            let p = run
                .pressure
                .sample(rate, -(pre as f64) / rate, pre + run.n * over)?;
            let p0 = p.first().copied().unwrap_or(0.0);
            let dc = h(Complex64::new(0.0, 0.0)).re;
            let dp: Vec<f64> = p.iter().map(|v| v - p0).collect();
            let y = convolve(&ir.taps, &dp, p.len()).map_err(|e| e.to_string())?;
            let y = y.iter().map(|v| v + dc * p0).collect();
            (p, y, pre, over)
        }
    };
    let pick = |x: &[f64]| -> Vec<f64> { x.iter().skip(pre).step_by(over).copied().collect() };
    Ok((pick(&fine_p), pick(&fine_y)))
}

/// A record as the experimenter has it, with the truth kept for scoring.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// The true pressure.
    pub truth: Vec<f64>,
    /// The probe without noise or ADC.
    pub probe_clean: Vec<f64>,
    /// The recorded reference.
    pub u: Vec<f64>,
    /// The recorded probe.
    pub y: Vec<f64>,
    /// The ADC of both channels.
    pub adc: Adc,
    /// Samples of either channel at the ADC's rails.
    pub clipped: usize,
}

/// `run` recorded from `probe`: white noise on both channels, then a 16-bit ADC over the
/// run's extremes (both channels, noise included) with a drawn margin of 5-25 % of their
/// span on either side, as an experimenter sets it after a trial run.
pub fn record(probe: &Probe, run: &Run, rng: &mut Rng) -> Result<Recorded, String> {
    let (truth, probe_clean) = clean(probe, run)?;
    let (su, sy) = (probe.noise_u * probe.step_pa, probe.noise_y * probe.step_pa);
    let mut u: Vec<f64> = truth.iter().map(|v| v + su * rng.gauss()).collect();
    let mut y: Vec<f64> = probe_clean.iter().map(|v| v + sy * rng.gauss()).collect();
    let (lo, hi) = u
        .iter()
        .chain(&y)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let margin = rng.range(0.05, 0.25) * (hi - lo);
    let adc = Adc {
        bits: 16,
        min_pa: lo - margin,
        max_pa: hi + margin,
    };
    let mut clipped = 0;
    for v in u.iter_mut().chain(y.iter_mut()) {
        clipped += usize::from(*v <= adc.min_pa || *v >= adc.max_pa);
        *v = adc.quantise(*v);
    }
    Ok(Recorded {
        truth,
        probe_clean,
        u,
        y,
        adc,
        clipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::probe::{Family, Probe};
    use crate::simulate::Stage;
    use unlag::physics::{simulate, Acquisition, Line};

    fn probe(dynamics: Dynamics) -> Probe {
        Probe {
            id: 0,
            family: Family::Pneumatic,
            dynamics,
            text: String::new(),
            fs: 10_000.0,
            f_hz: 100.0,
            zeta: 0.3,
            band_hz: 150.0,
            lag_s: 1e-3,
            slowest_s: 0.01,
            step_pa: 1000.0,
            noise_u: 0.0,
            noise_y: 0.0,
            seed: 1,
        }
    }

    fn step(n: usize, at: f64) -> Run {
        Run {
            kind: RunKind::Step,
            pressure: Pressure::Events {
                base_pa: 0.0,
                events: vec![(Excitation::shock_tube(1000.0), at)],
            },
            n,
            text: String::new(),
        }
    }

    #[test]
    fn a_physical_step_is_the_physics_modules_own() {
        let line = Line::new().tube(0.5, 0.75e-3).volume(300e-9);
        let p = probe(Dynamics::Physics { line: line.clone() });
        let (truth, y) = clean(&p, &step(2000, 0.02)).unwrap();
        let mut acq = Acquisition::new(p.fs, 0.2);
        acq.event_time_s = 0.02;
        acq.oversample = 16;
        let sim = simulate(
            &unlag::physics::Probe::new(line, gas()),
            &Excitation::shock_tube(1000.0),
            &acq,
        )
        .unwrap();
        let worst = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&y, &sim.probe_clean) < 1e-6 * 1000.0);
        // (The sample times differ in rounding: 1e-9 Pa at the step.)
        assert!(worst(&truth, &sim.excitation) < 1e-6);
    }

    #[test]
    fn a_lumped_step_settles_at_its_gain_and_lags_by_its_delay() {
        let p = probe(Dynamics::Lumped {
            stages: vec![Stage::Mode {
                f_hz: 100.0,
                zeta: 0.5,
                quad: 0.0,
            }],
            delay: 5,
        });
        let at = 0.0201;
        let (truth, y) = clean(&p, &step(2000, at)).unwrap();
        let first = (at * p.fs).ceil() as usize;
        assert_eq!(truth[first - 1], 0.0);
        assert_eq!(truth[first + 1], 1000.0);
        // Nothing before the step reaches the probe, plus its delay.
        assert!(y[..first + 5].iter().all(|v| v.abs() < 1e-9));
        assert!(y[first + 6] > 0.0);
        assert!((y[1999] - 1000.0).abs() < 1e-6);
    }

    #[test]
    fn turbulence_has_its_rms_and_nothing_above_its_band_limit() {
        let rate = 1000.0;
        let x = fluctuations(rate, 4096, 20.0, 100.0, 3).unwrap();
        let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
        assert!((rms - 1.0).abs() < 1e-12);
        let mut spec: Vec<Complex64> = x.iter().map(|v| Complex64::new(*v, 0.0)).collect();
        fft_in_place(&mut spec, false).unwrap();
        let power = |from_hz: f64, to_hz: f64| -> f64 {
            spec.iter()
                .enumerate()
                .take(2048)
                .filter(|(k, _)| {
                    let f = *k as f64 * rate / 4096.0;
                    f >= from_hz && f < to_hz
                })
                .map(|(_, c)| c.norm_sqr())
                .sum()
        };
        assert!(power(100.0, 500.0) < 1e-20 * power(0.0, 100.0));
        // The spectrum falls beyond its corner: less power per hertz at 60-70 Hz than at 1-11.
        assert!(power(60.0, 70.0) < 0.5 * power(1.0, 11.0));
    }
}
