//! The bench's probes: six families drawn over ranges from a seed, each simulated either as a
//! lumped model (bench_bank's state equations) or as a Bergh-Tijdeman line of the physics
//! module, with what the runs need to know of its time scales.

use std::f64::consts::PI;

use super::case::{Geometry, REFERENCE_K};
use super::draw::Rng;
use super::simulate::Stage;
use unlag::physics::{
    find_modes, gas::Gas, lumped, CavityThermal, Element, Line, Volume, POISEUILLE_INERTANCE,
};

/// Square of the first zero of `J0`: the slowest thermal mode of a cylinder is
/// `j01^2 alpha / r^2`.
const J01_SQUARED: f64 = 2.404_825_557_695_773 * 2.404_825_557_695_773;

/// The probe families, dealt round-robin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Overdamped capillaries (damping 1.5 and more) at 2-10 kHz.
    Capillary,
    /// Pneumatic lines (tube into a transducer volume) at 5-20 kHz.
    Pneumatic,
    /// Two tubes in series (a probe tip and its tubing), with or without a junction volume.
    Series,
    /// A flush or recessed hole into a sensor cavity, sampled at 1-2 MHz.
    Hole,
    /// A tube into a cavity whose gas exchanges heat with the wall: a slow thermal creep.
    ThermalCreep,
    /// A leak: a slow pole-zero pair (lumped) or a conductance to ambient at the volume.
    Leak,
}

/// Every family, in report order.
pub const FAMILIES: [Family; 6] = [
    Family::Capillary,
    Family::Pneumatic,
    Family::Series,
    Family::Hole,
    Family::ThermalCreep,
    Family::Leak,
];

impl Family {
    /// Name in the report and the CSV.
    pub fn name(self) -> &'static str {
        match self {
            Self::Capillary => "capillary",
            Self::Pneumatic => "pneumatic",
            Self::Series => "series",
            Self::Hole => "hole",
            Self::ThermalCreep => "thermal-creep",
            Self::Leak => "leak",
        }
    }
}

/// How a probe is simulated.
#[derive(Debug, Clone)]
pub enum Dynamics {
    /// Lumped stages in cascade with a whole-sample delay (RK4 on the state equations).
    Lumped {
        /// The stages, first a mode.
        stages: Vec<Stage>,
        /// Delay in samples at the probe's rate.
        delay: usize,
    },
    /// A Bergh-Tijdeman line (its impulse response by the physics module).
    Physics {
        /// The line, from the measuring point to the closed end.
        line: Line,
    },
}

/// One drawn probe.
#[derive(Debug, Clone)]
pub struct Probe {
    /// Number, also the folder `probe-NNN`.
    pub id: usize,
    /// Family.
    pub family: Family,
    /// How it is simulated.
    pub dynamics: Dynamics,
    /// Its parameters in words (report and CSV).
    pub text: String,
    /// Sample rate [Hz].
    pub fs: f64,
    /// First mode's natural frequency [Hz] (lumped: drawn; physics: the lumped approximation
    /// of a tube, the exact first mode of a hole or a series line).
    pub f_hz: f64,
    /// First mode's damping.
    pub zeta: f64,
    /// The probe's -3 dB band [Hz], from the first mode.
    pub band_hz: f64,
    /// Low-frequency lag of the probe behind the pressure [s] (delay plus `2 zeta / omega`).
    pub lag_s: f64,
    /// Slowest time constant of the probe [s] (a mode's decay, a creep, a leak).
    pub slowest_s: f64,
    /// Size of the calibration step [Pa] (the unit of every level and of the noise).
    pub step_pa: f64,
    /// White noise of the reference channel, fraction of the step.
    pub noise_u: f64,
    /// White noise of the probe channel, fraction of the step.
    pub noise_y: f64,
    /// Seed of this probe's runs.
    pub seed: u64,
}

impl Probe {
    /// `lumped` or `physics`.
    pub fn generator(&self) -> &'static str {
        match self.dynamics {
            Dynamics::Lumped { .. } => "lumped",
            Dynamics::Physics { .. } => "physics",
        }
    }
}

/// The gas of every test.
pub fn gas() -> Gas {
    Gas::air(REFERENCE_K, 101_325.0)
}

/// -3 dB band of `w^2 / (s^2 + 2 zeta w s + w^2)` [Hz].
pub fn band_of(f_hz: f64, zeta: f64) -> f64 {
    let c = 1.0 - 2.0 * zeta * zeta;
    f_hz * (c + (c * c + 1.0).sqrt()).sqrt()
}

/// Slowest decay time [s] of a mode.
fn decay_s(f_hz: f64, zeta: f64) -> f64 {
    let w = 2.0 * PI * f_hz;
    let rate = if zeta < 1.0 {
        zeta * w
    } else {
        w * (zeta - (zeta * zeta - 1.0).sqrt())
    };
    1.0 / rate
}

/// What the physics module says of a line: `(f_hz, zeta, lag_s, slowest creep [s])`. The
/// first mode from the lumped approximation (`exact = false`, tubes) or from the exact
/// poles (`exact = true`, holes and series lines); the lag is the lumped `a1` plus the front
/// delay; the creep is the slowest real pole, 0 without one.
fn physics_scales(
    line: &Line,
    gas: &Gas,
    exact: bool,
    accept: impl Fn(f64, f64) -> bool,
) -> Option<(f64, f64, f64, f64)> {
    let l = lumped(line, gas, POISEUILLE_INERTANCE).ok()?;
    // The exact poles cost a search: a tube out of range by its lumped mode needs none.
    if !exact && !accept(l.natural_frequency_hz, l.damping) {
        return None;
    }
    let modes = find_modes(line, gas, 1).ok();
    let (f, z) = if exact {
        let m = modes.as_ref()?.modes.first()?;
        (m.natural_frequency_hz, m.damping)
    } else {
        (l.natural_frequency_hz, l.damping)
    };
    let front = modes.as_ref().map_or(0.0, |m| m.delay_s);
    let creep = modes
        .as_ref()
        .and_then(|m| m.real_poles_rad_s.first())
        .map_or(0.0, |s| 1.0 / s.abs());
    accept(f, z).then_some((f, z, l.a1_s + front, creep))
}

/// The end volume of `line` (its last element) changed by `change`.
fn with_end_volume(mut line: Line, change: impl FnOnce(&mut Volume)) -> Line {
    if let Some(Element::Volume(v)) = line.elements.last_mut() {
        change(v);
    }
    line
}

/// A physical line of `family` drawn by rejection until its first mode lies in the family's
/// ranges (`f` in Hz within `f_range` and below `fs / 8`, damping in `z_range`); with its words and
/// `(f, zeta, lag, slowest)`.
fn draw_line(rng: &mut Rng, family: Family, fs: f64) -> (Line, String, [f64; 4]) {
    let gas = gas();
    for _ in 0..10_000 {
        let (line, text, f_range, z_range, exact, extra_s) = match family {
            Family::Capillary | Family::Pneumatic | Family::Leak => {
                let (l, r, v) = if family == Family::Capillary {
                    (
                        rng.log_range(1.0, 5.0),
                        rng.log_range(0.1e-3, 0.4e-3),
                        rng.log_range(20e-9, 1000e-9),
                    )
                } else {
                    (
                        rng.log_range(0.2, 3.0),
                        rng.log_range(0.25e-3, 1.0e-3),
                        rng.log_range(5e-9, 2000e-9),
                    )
                };
                let g = Geometry::Tube {
                    length_m: l,
                    radius_m: r,
                    volume_m3: v,
                };
                let (mut line, mut text) = (g.line(&gas), g.describe());
                if family == Family::Leak {
                    // A conductance to ambient at the volume: static gain 1/(1 + R G).
                    let dc_gain = rng.range(0.9, 0.98);
                    let conductance = (1.0 / dc_gain - 1.0) / line.dc_resistance(&gas);
                    line = with_end_volume(line, |v| v.leak_m3_per_s_pa = conductance);
                    text.push_str(&format!(", leak to dc gain {dc_gain:.3}"));
                }
                let (f, z) = if family == Family::Capillary {
                    ((2.0, 100.0), (1.5, 8.0))
                } else {
                    ((15.0, 300.0), (0.05, 1.5))
                };
                (line, text, f, z, false, 0.0)
            }
            Family::Series => {
                let (l1, r1) = (rng.log_range(0.05, 0.5), rng.log_range(0.2e-3, 0.6e-3));
                let (l2, r2) = (rng.log_range(0.2, 2.0), rng.log_range(0.4e-3, 1.2e-3));
                let junction = (rng.uniform() < 0.5).then(|| rng.log_range(5e-9, 100e-9));
                let end = rng.log_range(20e-9, 1000e-9);
                let mut line = Line::new().tube(l1, r1);
                if let Some(v) = junction {
                    line = line.volume(v);
                }
                let line = line.tube(l2, r2).volume(end);
                let text = format!(
                    "tube {l1:.3} m x {:.2} mm dia{}, then {l2:.3} m x {:.2} mm dia, {:.1} mm3",
                    2e3 * r1,
                    junction.map_or(String::new(), |v| format!(", junction {:.1} mm3", 1e9 * v)),
                    2e3 * r2,
                    1e9 * end
                );
                (line, text, (10.0, 400.0), (0.02, 3.0), true, 0.0)
            }
            Family::Hole => {
                let g = Geometry::Hole {
                    length_m: rng.log_range(0.2e-3, 2e-3),
                    diameter_m: rng.log_range(0.3e-3, 1.0e-3),
                    volume_m3: rng.log_range(0.05e-9, 3e-9),
                };
                (
                    g.line(&gas),
                    g.describe(),
                    (20e3, 200e3),
                    (0.0, 1.0),
                    true,
                    0.0,
                )
            }
            Family::ThermalCreep => {
                let (l, r) = (rng.log_range(0.1, 1.5), rng.log_range(0.3e-3, 1.0e-3));
                let volume = rng.log_range(100e-9, 2000e-9);
                // A cylinder of length `aspect` diameters: V = 2 pi aspect r^3.
                let aspect = rng.log_range(1.0, 4.0);
                let radius_m = (volume / (2.0 * PI * aspect)).cbrt();
                let line = with_end_volume(Line::new().tube(l, r).volume(volume), |v| {
                    v.thermal = CavityThermal::Relaxing { radius_m };
                });
                let alpha = gas.kinematic_viscosity() / gas.prandtl;
                let thermal_s = radius_m * radius_m / (J01_SQUARED * alpha);
                let text = format!(
                    "tube {l:.3} m x {:.2} mm dia, cavity {:.0} mm3 of radius {:.2} mm relaxing in {:.1} ms",
                    2e3 * r,
                    1e9 * volume,
                    1e3 * radius_m,
                    1e3 * thermal_s
                );
                (line, text, (15.0, 400.0), (0.05, 1.5), false, thermal_s)
            }
        };
        let accept = |f: f64, z: f64| {
            (f_range.0..=f_range.1).contains(&f)
                && f < fs / 8.0
                && (z_range.0..=z_range.1).contains(&z)
        };
        if let Some((f, z, lag, creep)) = physics_scales(&line, &gas, exact, accept) {
            let slowest = decay_s(f, z).max(creep).max(extra_s);
            return (line, text, [f, z, lag, slowest]);
        }
    }
    // The ranges above always admit lines; a seed that found none keeps the last family
    // default rather than looping for ever.
    let line = Line::new().tube(0.5, 0.5e-3).volume(300e-9);
    let (f, z, lag, _) =
        physics_scales(&line, &gas, false, |_, _| true).unwrap_or((100.0, 0.3, 0.0, 0.0));
    (line, "fallback tube".into(), [f, z, lag, decay_s(f, z)])
}

/// A lumped probe of `family`: its stages, delay, words and `(f, zeta, lag, slowest)`.
fn draw_lumped(rng: &mut Rng, family: Family, fs: f64) -> (Vec<Stage>, usize, String, [f64; 4]) {
    let (f, z, delay) = match family {
        Family::Capillary => (
            rng.log_range(5.0, 60.0),
            rng.log_range(1.5, 5.0),
            rng.int(0, 30),
        ),
        Family::Hole => (
            rng.log_range(30e3, 120e3),
            rng.log_range(0.05, 0.4),
            rng.int(0, 8),
        ),
        _ => (
            rng.log_range(20.0, 150.0),
            rng.log_range(0.1, 1.5),
            rng.int(0, 40),
        ),
    };
    let mut stages = vec![Stage::Mode {
        f_hz: f,
        zeta: z,
        quad: 0.0,
    }];
    let mut text = format!("lumped {f:.1} Hz, damping {z:.3}, delay {delay}");
    let mut slowest = decay_s(f, z);
    match family {
        Family::Series => {
            let (f2, z2) = (
                (f * rng.range(2.0, 5.0)).min(0.3 * fs),
                rng.log_range(0.05, 0.3),
            );
            stages.push(Stage::Mode {
                f_hz: f2,
                zeta: z2,
                quad: 0.0,
            });
            text.push_str(&format!(", second mode {f2:.1} Hz, damping {z2:.3}"));
        }
        Family::Leak => {
            let (corner_hz, dc_gain) = (rng.log_range(0.5, 5.0), rng.range(0.9, 0.98));
            stages.push(Stage::Leak { corner_hz, dc_gain });
            text.push_str(&format!(
                ", leak corner {corner_hz:.2} Hz to dc gain {dc_gain:.3}"
            ));
            slowest = slowest.max(1.0 / (2.0 * PI * corner_hz * dc_gain));
        }
        _ => {}
    }
    let lag = delay as f64 / fs + 2.0 * z / (2.0 * PI * f);
    (stages, delay, text, [f, z, lag, slowest])
}

/// Draws `count` probes from `seed`: families round-robin, everything else drawn.
pub fn draw(seed: u64, count: usize) -> Vec<Probe> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|id| {
            let family = FAMILIES[id % FAMILIES.len()];
            let fs = match family {
                Family::Capillary => rng.range(2e3, 10e3),
                Family::Hole => rng.range(1e6, 2e6),
                Family::Leak => rng.range(2e3, 8e3),
                _ => rng.range(5e3, 20e3),
            };
            // Whole hertz below 100 kHz, whole kHz above: rates a DAQ offers.
            let fs = if fs > 1e5 {
                (fs / 1e3).round() * 1e3
            } else {
                fs.round()
            };
            let physics = family == Family::ThermalCreep || rng.uniform() < 0.5;
            let (dynamics, text, [f_hz, zeta, lag_s, slowest_s]) = if physics {
                let (line, text, scales) = draw_line(&mut rng, family, fs);
                (Dynamics::Physics { line }, text, scales)
            } else {
                let (stages, delay, text, scales) = draw_lumped(&mut rng, family, fs);
                (Dynamics::Lumped { stages, delay }, text, scales)
            };
            Probe {
                id,
                family,
                dynamics,
                text,
                fs,
                f_hz,
                zeta,
                band_hz: band_of(f_hz, zeta),
                lag_s,
                slowest_s,
                step_pa: rng.log_range(1e3, 2e4),
                noise_u: rng.range(0.001, 0.005),
                noise_y: rng.range(0.001, 0.005),
                seed: rng.next_u64(),
            }
        })
        .collect()
}
