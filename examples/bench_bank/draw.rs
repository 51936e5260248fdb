//! Drawing the bank's cases: a seeded generator and the distributions of every parameter.
//!
//! Kinds and families are dealt round-robin (so every kind meets every family); everything
//! else is drawn: the generator (Bergh-Tijdeman physics or a lumped model), the probe's
//! dynamics or geometry, the effect's size, the noise, the step and the validation test.

use super::case::{
    Case, Effect, Family, Generator, Geometry, Kind, Test, FAMILIES, KINDS, REFERENCE_K,
};
use unlag::physics::{find_modes, gas::Gas, lumped, HoleCavity, POISEUILLE_INERTANCE};

/// A tiny deterministic generator (SplitMix64) with uniform, log-uniform and Gaussian draws.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Log-uniform in `[lo, hi)`.
    pub fn log_range(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.uniform()).exp()
    }

    /// A whole number in `lo..=hi`.
    pub fn int(&mut self, lo: usize, hi: usize) -> usize {
        lo + (self.next_u64() % (hi - lo + 1) as u64) as usize
    }

    /// +1 or -1 with equal odds.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Standard normal (Box-Muller).
    pub fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}
/// Slowest decay rate [1/s] of a mode.
fn slowest_rate(f_hz: f64, zeta: f64) -> f64 {
    let w = 2.0 * std::f64::consts::PI * f_hz;
    if zeta < 1.0 {
        zeta * w
    } else {
        w * (zeta - (zeta * zeta - 1.0).sqrt())
    }
}

/// A physical geometry of `family` whose lumped prediction falls in the family's ranges,
/// drawn by rejection; `(geometry, f_hz, zeta)`.
fn draw_geometry(rng: &mut Rng, family: Family) -> (Geometry, f64, f64) {
    let gas = Gas::air(REFERENCE_K, 101_325.0);
    loop {
        let (geometry, f_range, z_range) = match family {
            Family::Pneumatic => (
                Geometry::Tube {
                    length_m: rng.log_range(0.2, 3.0),
                    radius_m: rng.log_range(0.25e-3, 1.0e-3),
                    volume_m3: rng.log_range(5e-9, 2000e-9),
                },
                (20.0, 150.0),
                (0.1, 1.5),
            ),
            Family::Flush => (
                Geometry::Hole {
                    length_m: rng.log_range(0.2e-3, 2e-3),
                    diameter_m: rng.log_range(0.3e-3, 1.0e-3),
                    volume_m3: rng.log_range(0.05e-9, 3e-9),
                },
                (30e3, 120e3),
                (0.0, 1.0),
            ),
            Family::Capillary => (
                Geometry::Tube {
                    length_m: rng.log_range(1.0, 5.0),
                    radius_m: rng.log_range(0.1e-3, 0.4e-3),
                    volume_m3: rng.log_range(20e-9, 1000e-9),
                },
                (5.0, 80.0),
                (1.5, 5.0),
            ),
        };
        let (f, z) = match geometry {
            Geometry::Hole {
                length_m,
                diameter_m,
                volume_m3,
            } => {
                // The closed form to draw by; the exact first mode (its Poiseuille damping
                // is far too low) to report and to size the record.
                let h = HoleCavity::flush(length_m, diameter_m, volume_m3);
                if !(f_range.0..=f_range.1).contains(&h.helmholtz_frequency_hz(&gas)) {
                    continue;
                }
                match find_modes(&geometry.line(&gas), &gas, 1) {
                    Ok(m) if !m.modes.is_empty() => {
                        (m.modes[0].natural_frequency_hz, m.modes[0].damping)
                    }
                    _ => continue,
                }
            }
            Geometry::Tube { .. } => match lumped(&geometry.line(&gas), &gas, POISEUILLE_INERTANCE)
            {
                Ok(l) => (l.natural_frequency_hz, l.damping),
                Err(_) => continue,
            },
        };
        if (f_range.0..=f_range.1).contains(&f) && (z_range.0..=z_range.1).contains(&z) {
            return (geometry, f, z);
        }
    }
}

/// Two levels `(from, to)` in `[lo, hi]` steps (times `step`), `|to - from|` in
/// `[min, max]` steps, rising or falling as `rising` says.
fn levels(
    rng: &mut Rng,
    step: f64,
    (lo, hi): (f64, f64),
    (min, max): (f64, f64),
    rising: bool,
) -> (f64, f64) {
    let size = rng.range(min, max.min(hi - lo));
    let start = rng.range(lo, hi - size);
    let (a, b) = (start, start + size);
    if rising {
        (a * step, b * step)
    } else {
        (b * step, a * step)
    }
}

/// The effect of `kind` with its size, for a line of `f_hz` at `fs`.
fn draw_effect(
    rng: &mut Rng,
    kind: Kind,
    family: Family,
    generator: &Generator,
    f_hz: f64,
    fs: f64,
) -> Effect {
    let slow = family.slow_scale();
    match kind {
        Kind::None => Effect::None,
        Kind::Leak => Effect::Leak {
            corner_hz: slow * rng.log_range(0.5, 5.0),
            dc_gain: rng.range(0.9, 0.98),
        },
        Kind::Drift => Effect::Drift {
            per_s: slow * rng.sign() * rng.range(0.01, 0.1),
        },
        Kind::Offset => Effect::Offset {
            fraction: rng.sign() * rng.range(0.005, 0.05),
        },
        Kind::ColouredNoise => Effect::ColouredNoise {
            rho: rng.range(0.8, 0.99),
            ratio: rng.range(2.0, 10.0),
        },
        Kind::Mode => {
            let second_stage = match (&generator, family) {
                (Generator::Physics { .. }, Family::Flush) => Some((
                    rng.log_range(0.3e-3, 2e-3),
                    rng.log_range(0.1e-3, 0.3e-3),
                    rng.log_range(0.05e-9, 1e-9),
                )),
                (Generator::Physics { .. }, _) => Some((
                    rng.log_range(0.02, 0.3),
                    rng.log_range(0.2e-3, 0.6e-3),
                    rng.log_range(5e-9, 200e-9),
                )),
                _ => None,
            };
            Effect::Mode {
                f_hz: (f_hz * rng.range(2.0, 5.0)).min(0.3 * fs),
                zeta: rng.log_range(0.05, 0.3),
                second_stage,
            }
        }
        Kind::SensorResonance => Effect::SensorResonance {
            f_hz: rng.range(0.15, 0.4) * fs,
            zeta: rng.range(0.03, 0.1),
        },
        Kind::NonlinearDamping => Effect::NonlinearDamping {
            ratio: rng.log_range(0.3, 3.0),
        },
        Kind::Temperature => Effect::Temperature {
            kelvin: REFERENCE_K + rng.sign() * rng.range(30.0, 70.0),
        },
    }
}

/// The validation test: another facility or step, at least `seconds` long (a wake: four
/// tunnel periods).
fn draw_validation(
    rng: &mut Rng,
    family: Family,
    kind: Kind,
    fs: f64,
    step_pa: f64,
    seconds: f64,
) -> Test {
    use unlag::physics::Excitation as E;
    let n_for = |seconds: f64| (seconds * fs).ceil().clamp(2000.0, 20_000.0) as usize;
    // The validation test: another facility or step. Its levels stay well inside the
    // ADC range, closer with a ringing diaphragm.
    let sensor = kind == Kind::SensorResonance;
    let span = if sensor { (0.1, 1.0) } else { (-0.2, 1.3) };
    let sizes = if sensor { (0.3, 0.6) } else { (0.3, 1.4) };
    let val_kind = rng.int(0, 3);
    let (val, val_name) = match val_kind {
        0 => {
            let rising = rng.uniform() < 0.5;
            let (from, to) = levels(rng, step_pa, span, sizes, rising);
            ((E::shock_tube(to - from), from), "step")
        }
        1 => {
            let (from, to) = levels(rng, step_pa, span, sizes, false);
            ((E::balloon(from - to), to), "balloon")
        }
        2 => {
            let (from, to) = levels(rng, step_pa, span, sizes, true);
            let chamber_hz = match family {
                Family::Flush => rng.log_range(5e3, 50e3),
                _ => rng.range(0.02, 0.1) * fs,
            };
            (
                (
                    E::Valve {
                        amplitude_pa: to - from,
                        opening_s: 200e-6,
                        chamber_hz,
                        chamber_fraction: rng.range(0.0, 0.15),
                    },
                    from,
                ),
                "valve",
            )
        }
        _ => {
            let (wake_hz, tunnel_hz) = match family {
                Family::Pneumatic => (rng.range(10.0, 40.0), rng.range(2.0, 8.0)),
                Family::Flush => (rng.range(3e3, 15e3), rng.range(300.0, 1500.0)),
                Family::Capillary => (rng.range(3.0, 15.0), rng.range(1.0, 4.0)),
            };
            let depth = step_pa
                * if sensor {
                    rng.range(0.3, 0.5)
                } else {
                    rng.range(0.3, 0.7)
                };
            (
                (
                    E::CascadeWake {
                        wake_depth_pa: depth,
                        wake_hz,
                        wake_width: rng.range(0.05, 0.15),
                        tunnel_amplitude_pa: depth * rng.range(0.05, 0.25),
                        tunnel_hz,
                    },
                    step_pa * rng.range(0.7, 1.0),
                ),
                "wake",
            )
        }
    };
    let n_val = match val_name {
        "wake" => {
            let tunnel = match val.0 {
                E::CascadeWake { tunnel_hz, .. } => tunnel_hz,
                _ => 1.0,
            };
            n_for(seconds.max(4.0 / tunnel))
        }
        _ => n_for(seconds),
    };
    Test {
        excitation: val.0,
        base_pa: val.1,
        event_s: rng.range(0.1, 0.2) * n_val as f64 / fs,
        n: n_val,
        name: val_name,
    }
}

/// Draws `count` cases from `seed`.
pub fn draw(seed: u64, count: usize) -> Vec<Case> {
    use unlag::physics::Excitation as E;
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|id| {
            let kind = KINDS[id % KINDS.len()];
            let family = FAMILIES[(id / KINDS.len()) % FAMILIES.len()];
            let physics = kind != Kind::NonlinearDamping && rng.uniform() < 0.35;
            let fs = match family {
                Family::Pneumatic => rng.range(5e3, 10e3).round(),
                Family::Flush => 1e6,
                Family::Capillary => rng.range(2e3, 10e3).round(),
            };
            let (generator, f_hz, zeta) = if physics {
                let (geometry, f, z) = draw_geometry(&mut rng, family);
                (Generator::Physics { geometry }, f, z)
            } else {
                let (f, z, d) = match family {
                    Family::Pneumatic => (
                        rng.log_range(20.0, 150.0),
                        rng.log_range(0.1, 1.5),
                        rng.int(0, 40),
                    ),
                    Family::Flush => (
                        rng.log_range(30e3, 120e3),
                        rng.log_range(0.05, 0.4),
                        rng.int(0, 8),
                    ),
                    Family::Capillary => (
                        rng.log_range(5.0, 60.0),
                        rng.log_range(1.5, 5.0),
                        rng.int(0, 30),
                    ),
                };
                (
                    Generator::Lumped {
                        f_hz: f,
                        zeta: z,
                        delay: d,
                    },
                    f,
                    z,
                )
            };
            let effect = draw_effect(&mut rng, kind, family, &generator, f_hz, fs);
            // Record length: eight time constants of the slowest dynamics, 2 000 to 20 000.
            let mut rate = slowest_rate(f_hz, zeta);
            if let Effect::Leak { corner_hz, .. } = effect {
                rate = rate.min(2.0 * std::f64::consts::PI * corner_hz);
            }
            let n_for = |seconds: f64| (seconds * fs).ceil().clamp(2000.0, 20_000.0) as usize;
            let n_est = n_for(8.0 / rate / 0.8);
            let step_pa = rng.log_range(1e3, 2e4);
            let noise_u = rng.range(0.001, 0.005);
            let noise_y = rng.range(0.001, 0.005);
            let est_exc = if family != Family::Flush && rng.uniform() < 0.3 {
                E::valve(step_pa)
            } else {
                E::shock_tube(step_pa)
            };
            let est = Test {
                excitation: est_exc,
                base_pa: 0.0,
                event_s: rng.range(0.1, 0.2) * n_est as f64 / fs,
                n: n_est,
                name: "step",
            };
            let val = draw_validation(&mut rng, family, kind, fs, step_pa, 8.0 / rate / 0.8);
            Case {
                id,
                family,
                kind,
                effect,
                generator,
                f_hz,
                zeta,
                fs,
                step_pa,
                noise_u,
                noise_y,
                est,
                val,
                seed: rng.next_u64(),
            }
        })
        .collect()
}

/// Another run of `test`'s kind, as a user records several: the same facility, its sizes
/// and frequencies drawn again within +-20 % (levels only smaller, so that the run stays in
/// the ADC range the bank's tests set), and its own event time.
pub fn sibling(test: &Test, rng: &mut Rng) -> Test {
    use unlag::physics::Excitation as E;
    let size = rng.range(0.8, 1.0);
    let mut spread = || rng.range(0.8, 1.2);
    let excitation = match test.excitation {
        E::ShockTube {
            amplitude_pa,
            rise_s,
        } => E::ShockTube {
            amplitude_pa: amplitude_pa * size,
            rise_s,
        },
        E::Balloon {
            amplitude_pa,
            fall_s,
        } => E::Balloon {
            amplitude_pa: amplitude_pa * size,
            fall_s: fall_s * spread(),
        },
        E::Valve {
            amplitude_pa,
            opening_s,
            chamber_hz,
            chamber_fraction,
        } => E::Valve {
            amplitude_pa: amplitude_pa * size,
            opening_s: opening_s * spread(),
            chamber_hz: chamber_hz * spread(),
            chamber_fraction: chamber_fraction * spread(),
        },
        E::CascadeWake {
            wake_depth_pa,
            wake_hz,
            wake_width,
            tunnel_amplitude_pa,
            tunnel_hz,
        } => E::CascadeWake {
            wake_depth_pa: wake_depth_pa * size,
            wake_hz: wake_hz * spread(),
            wake_width: wake_width * spread(),
            tunnel_amplitude_pa: tunnel_amplitude_pa * size,
            tunnel_hz: tunnel_hz * spread(),
        },
    };
    Test {
        excitation,
        event_s: test.event_s * rng.range(0.8, 1.2),
        ..*test
    }
}
