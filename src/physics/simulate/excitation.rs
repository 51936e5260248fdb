//! The excitations of real facilities (shock tube, burst balloon, fast valve, wind-tunnel
//! wake, ...) as pressure histories evaluated analytically at any time, and each facility's
//! default settings ([`Excitation::of_facility`]).

use crate::error::{Error, Parameter, Result};

/// A facility, for [`Excitation::of_facility`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Facility {
    /// [`Excitation::ShockTube`].
    ShockTube,
    /// [`Excitation::Balloon`].
    Balloon,
    /// [`Excitation::Valve`].
    Valve,
    /// [`Excitation::CascadeWake`].
    CascadeWake,
}

/// Rise time of a shock tube unless given \[s\].
pub const SHOCK_RISE_S: f64 = 1e-6;
/// Fall time of a burst balloon unless given \[s\].
pub const BALLOON_FALL_S: f64 = 700e-6;
/// Opening time of a fast valve unless given \[s\].
pub const VALVE_OPENING_S: f64 = 200e-6;
/// Chamber oscillation of a valve unless given: frequency \[Hz\] (VKI report) and fraction of
/// the step [-] (none).
pub const VALVE_CHAMBER: (f64, f64) = (850.0, 0.0);
/// Tunnel oscillation amplitude of a cascade traverse unless given, as a fraction of the wake
/// depth [-].
pub const TUNNEL_FRACTION: f64 = 0.05;

/// The settings of a facility's excitation; those left `None` take the facility's default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FacilitySettings {
    /// Step size, initial over-pressure or wake depth \[Pa\].
    pub amplitude_pa: f64,
    /// Rise (shock, valve) or fall (balloon) time \[s\]; default [`SHOCK_RISE_S`],
    /// [`BALLOON_FALL_S`], [`VALVE_OPENING_S`].
    pub rise_s: Option<f64>,
    /// Valve chamber oscillation (frequency \[Hz\], fraction of the step); default
    /// [`VALVE_CHAMBER`].
    pub chamber: Option<(f64, f64)>,
    /// Wake passing frequency \[Hz\].
    pub wake_hz: f64,
    /// Wake width as a fraction of the pitch [-].
    pub wake_width: f64,
    /// Tunnel oscillation amplitude \[Pa\]; default [`TUNNEL_FRACTION`] of the amplitude.
    pub tunnel_amplitude_pa: Option<f64>,
    /// Tunnel oscillation frequency \[Hz\].
    pub tunnel_hz: f64,
}

/// The pressure history of a facility at the measuring point, as a deviation \[Pa\] from the
/// level before the event; `t` is the time since the event \[s\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Excitation {
    /// A shock-tube step: rises by `amplitude_pa` in `rise_s` (raised cosine), the shock's
    /// passage over the probe face.
    ShockTube {
        /// Step size \[Pa\].
        amplitude_pa: f64,
        /// Rise time \[s\] (microseconds for a shock).
        rise_s: f64,
    },
    /// A burst balloon: the pressure starts `amplitude_pa` above the final level and falls to
    /// it in `fall_s` (about 700 µs; raised cosine).
    Balloon {
        /// Initial over-pressure \[Pa\].
        amplitude_pa: f64,
        /// Fall time \[s\].
        fall_s: f64,
    },
    /// A fast-opening valve into a chamber: rises by `amplitude_pa` in `opening_s` (raised
    /// cosine), optionally with a decaying chamber oscillation.
    Valve {
        /// Step size \[Pa\].
        amplitude_pa: f64,
        /// Opening time \[s\].
        opening_s: f64,
        /// Chamber oscillation frequency \[Hz\] (VKI report 850 Hz).
        chamber_hz: f64,
        /// Chamber oscillation amplitude as a fraction of the step [-] (0: none).
        chamber_fraction: f64,
    },
    /// A traverse through the wakes of a cascade: from the event on, Gaussian pressure deficits
    /// of `wake_depth_pa` pass at `wake_hz` (width `wake_width` of the pitch, standard
    /// deviation), on top of a tunnel oscillation (`tunnel_amplitude_pa` at `tunnel_hz`,
    /// 20 Hz in the VKI tests) that runs all the time.
    CascadeWake {
        /// Depth of each wake \[Pa\].
        wake_depth_pa: f64,
        /// Wake passing frequency \[Hz\] (traverse speed / pitch).
        wake_hz: f64,
        /// Wake width as a fraction of the pitch [-].
        wake_width: f64,
        /// Amplitude of the tunnel oscillation \[Pa\].
        tunnel_amplitude_pa: f64,
        /// Frequency of the tunnel oscillation \[Hz\].
        tunnel_hz: f64,
    },
}

/// `∫_{-∞}^{t}` of [`raised_cosine`] \[s\].
fn raised_cosine_integral(t: f64, duration: f64) -> f64 {
    if t <= 0.0 {
        0.0
    } else if t >= duration {
        t - 0.5 * duration
    } else {
        0.5 * t
            - duration / (2.0 * core::f64::consts::PI)
                * (core::f64::consts::PI * t / duration).sin()
    }
}

/// Mean of [`raised_cosine`] over `[t − w/2, t + w/2]`.
fn raised_cosine_average(t: f64, w: f64, duration: f64) -> f64 {
    if t + 0.5 * w <= 0.0 {
        return 0.0;
    }
    if t - 0.5 * w >= duration {
        return 1.0;
    }
    (raised_cosine_integral(t + 0.5 * w, duration) - raised_cosine_integral(t - 0.5 * w, duration))
        / w
}

/// Mean of a smooth `f` over `[t − w/2, t + w/2]` by the 8-point midpoint rule.
fn midpoint_average(f: impl Fn(f64) -> f64, t: f64, w: f64) -> f64 {
    (0..8)
        .map(|j| f(t + w * ((f64::from(j) + 0.5) / 8.0 - 0.5)))
        .sum::<f64>()
        / 8.0
}

fn raised_cosine(t: f64, duration: f64) -> f64 {
    if t <= 0.0 {
        0.0
    } else if t >= duration {
        1.0
    } else {
        0.5 * (1.0 - (core::f64::consts::PI * t / duration).cos())
    }
}

impl Excitation {
    /// The excitation of `facility` with `settings`, defaults filled in, checked.
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a rise time that is not finite and positive; the errors
    /// of [`Excitation::validate`].
    pub fn of_facility(facility: Facility, settings: &FacilitySettings) -> Result<Self> {
        let a = settings.amplitude_pa;
        let rise = match settings.rise_s {
            Some(r) if r.is_finite() && r > 0.0 => Some(r),
            Some(r) => {
                return Err(Error::InvalidParameter {
                    parameter: Parameter::RiseTime,
                    message: format!("{r} must be finite and positive"),
                })
            }
            None => None,
        };
        let e = match facility {
            Facility::ShockTube => Self::ShockTube {
                amplitude_pa: a,
                rise_s: rise.unwrap_or(SHOCK_RISE_S),
            },
            Facility::Balloon => Self::Balloon {
                amplitude_pa: a,
                fall_s: rise.unwrap_or(BALLOON_FALL_S),
            },
            Facility::Valve => {
                let (chamber_hz, chamber_fraction) = settings.chamber.unwrap_or(VALVE_CHAMBER);
                Self::Valve {
                    amplitude_pa: a,
                    opening_s: rise.unwrap_or(VALVE_OPENING_S),
                    chamber_hz,
                    chamber_fraction,
                }
            }
            Facility::CascadeWake => Self::CascadeWake {
                wake_depth_pa: a,
                wake_hz: settings.wake_hz,
                wake_width: settings.wake_width,
                tunnel_amplitude_pa: settings.tunnel_amplitude_pa.unwrap_or(TUNNEL_FRACTION * a),
                tunnel_hz: settings.tunnel_hz,
            },
        };
        e.validate()?;
        Ok(e)
    }

    /// A shock-tube step of `amplitude_pa` with a 1 µs rise.
    #[must_use]
    pub fn shock_tube(amplitude_pa: f64) -> Self {
        Self::ShockTube {
            amplitude_pa,
            rise_s: 1e-6,
        }
    }

    /// A burst balloon of `amplitude_pa` falling in 700 µs.
    #[must_use]
    pub fn balloon(amplitude_pa: f64) -> Self {
        Self::Balloon {
            amplitude_pa,
            fall_s: 700e-6,
        }
    }

    /// A fast valve of `amplitude_pa` opening in 200 µs, no chamber oscillation.
    #[must_use]
    pub fn valve(amplitude_pa: f64) -> Self {
        Self::Valve {
            amplitude_pa,
            opening_s: 200e-6,
            chamber_hz: 850.0,
            chamber_fraction: 0.0,
        }
    }

    /// Cascade wakes of `wake_depth_pa` at 50 Hz (width 0.1 pitch) with a 20 Hz tunnel
    /// oscillation of 5 % of the wake depth.
    #[must_use]
    pub fn cascade_wake(wake_depth_pa: f64) -> Self {
        Self::CascadeWake {
            wake_depth_pa,
            wake_hz: 50.0,
            wake_width: 0.1,
            tunnel_amplitude_pa: 0.05 * wake_depth_pa,
            tunnel_hz: 20.0,
        }
    }

    /// Checks every parameter is finite and durations positive.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`].
    pub fn validate(&self) -> Result<()> {
        let (values, durations): (Vec<f64>, Vec<f64>) = match *self {
            Self::ShockTube {
                amplitude_pa,
                rise_s,
            } => (vec![amplitude_pa], vec![rise_s]),
            Self::Balloon {
                amplitude_pa,
                fall_s,
            } => (vec![amplitude_pa], vec![fall_s]),
            Self::Valve {
                amplitude_pa,
                opening_s,
                chamber_hz,
                chamber_fraction,
            } => (
                vec![amplitude_pa, chamber_fraction],
                vec![opening_s, chamber_hz],
            ),
            Self::CascadeWake {
                wake_depth_pa,
                wake_hz,
                wake_width,
                tunnel_amplitude_pa,
                tunnel_hz,
            } => (
                vec![wake_depth_pa, tunnel_amplitude_pa],
                vec![wake_hz, wake_width, tunnel_hz],
            ),
        };
        if values.iter().any(|v| !v.is_finite())
            || durations.iter().any(|v| !(v.is_finite() && *v > 0.0))
        {
            return Err(Error::InvalidArgument {
                what: "excitation",
                message: format!(
                    "{self:?}: amplitudes must be finite, times and frequencies positive"
                ),
            });
        }
        Ok(())
    }

    /// The mean pressure deviation \[Pa\] over `[t − w/2, t + w/2]` (`t` after the event, `w`
    /// \[s\] a sample interval). The simulation samples the excitation this way, so a step
    /// that falls inside an internal sample interval is placed at its exact time (to second
    /// order in the interval), not rounded to a sample: the ramps are integrated in closed form,
    /// the smooth parts by the midpoint rule.
    #[must_use]
    pub fn cell_average(&self, t: f64, w: f64) -> f64 {
        match *self {
            Self::ShockTube {
                amplitude_pa,
                rise_s,
            } => amplitude_pa * raised_cosine_average(t, w, rise_s),
            Self::Balloon {
                amplitude_pa,
                fall_s,
            } => amplitude_pa * (1.0 - raised_cosine_average(t, w, fall_s)),
            Self::Valve {
                amplitude_pa,
                opening_s,
                chamber_fraction,
                ..
            } => {
                let ramp = amplitude_pa * raised_cosine_average(t, w, opening_s);
                if chamber_fraction == 0.0 {
                    ramp
                } else {
                    let no_chamber = Self::Valve {
                        amplitude_pa,
                        opening_s,
                        chamber_hz: 1.0,
                        chamber_fraction: 0.0,
                    };
                    ramp + midpoint_average(|x| self.value(x) - no_chamber.value(x), t, w)
                }
            }
            Self::CascadeWake { .. } => midpoint_average(|x| self.value(x), t, w),
        }
    }

    /// The pressure deviation \[Pa\] at time `t` \[s\] after the event.
    #[must_use]
    pub fn value(&self, t: f64) -> f64 {
        match *self {
            Self::ShockTube {
                amplitude_pa,
                rise_s,
            } => amplitude_pa * raised_cosine(t, rise_s),
            Self::Balloon {
                amplitude_pa,
                fall_s,
            } => amplitude_pa * (1.0 - raised_cosine(t, fall_s)),
            Self::Valve {
                amplitude_pa,
                opening_s,
                chamber_hz,
                chamber_fraction,
            } => {
                let mut v = raised_cosine(t, opening_s);
                if t > 0.0 && chamber_fraction != 0.0 {
                    let w = 2.0 * core::f64::consts::PI * chamber_hz;
                    // Decays over about five periods.
                    v += chamber_fraction
                        * raised_cosine(t, opening_s)
                        * (w * t).sin()
                        * (-t * chamber_hz / 5.0).exp();
                }
                amplitude_pa * v
            }
            Self::CascadeWake {
                wake_depth_pa,
                wake_hz,
                wake_width,
                tunnel_amplitude_pa,
                tunnel_hz,
            } => {
                let tunnel =
                    tunnel_amplitude_pa * (2.0 * core::f64::consts::PI * tunnel_hz * t).sin();
                if t <= 0.0 {
                    return tunnel;
                }
                // Phase within the pitch, the wake centred half a pitch after the event.
                let x = (t * wake_hz).fract() - 0.5;
                let g = (-0.5 * (x / wake_width).powi(2)).exp();
                // Enter the first wake smoothly (the probe starts outside the wakes).
                let ramp = raised_cosine(t * wake_hz, 0.5);
                tunnel - wake_depth_pa * g * ramp
            }
        }
    }
}
