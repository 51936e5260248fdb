//! `unlag simulate-test` and the physical probe on the command line: the description
//! ([`SystemArgs`]: lines, recessed hole, cavity, gas, leak, diaphragm, minor losses) that
//! `unlag predict` shares, and the simulated step test written as a CSV (`t,u,y`, readable by
//! `unlag fit`). The physics lives in [`crate::physics`]; `predict` is [`super::predict`].

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde_json::json;

use crate::error::{Error, Result};
use crate::physics::helmholtz::EndKind;
use crate::physics::sensor::{Butterworth, Diaphragm};
use crate::physics::simulate::{
    simulate, Acquisition, Adc, Excitation, Facility, FacilitySettings, Probe, Quantisation,
    SimulatedTest,
};
use crate::physics::system::{ProbeSpec, ProbeSystem};

/// How the end of a recessed hole meets the space beyond it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EndArg {
    /// Flush with a wall: end correction 0.85 r (Rayleigh).
    Flanged,
    /// A free pipe end: 0.61 r (Levine & Schwinger).
    Unflanged,
    /// No end correction.
    None,
}

/// The physical probe, shared by `simulate-test` and `predict`. Lengths and diameters in m,
/// volumes in m^3, temperature in K, pressures in Pa.
#[derive(Debug, Clone, Args)]
pub struct SystemArgs {
    /// A tube LENGTH,DIAMETER in m; repeat for tubes in series, from the measuring point on.
    #[arg(long = "line", value_name = "L,D")]
    pub lines: Vec<String>,
    /// Volume at the closed end (transducer volume or sensor cavity) in m^3.
    #[arg(long, value_name = "M3")]
    pub volume: f64,
    /// A recessed hole LENGTH,DIAMETER in m in front of everything else (a Bergh-Tijdeman tube
    /// with end-correction inertances at both ends); `--volume` is its cavity.
    #[arg(long, value_name = "L,D")]
    pub hole: Option<String>,
    /// End corrections of the hole (both ends).
    #[arg(long, value_enum, default_value_t = EndArg::Flanged)]
    pub hole_end: EndArg,
    /// Mean gas temperature in K (speed of sound, Sutherland viscosity).
    #[arg(long, default_value_t = 293.15, value_name = "K")]
    pub temperature: f64,
    /// Mean absolute pressure in the line in Pa.
    #[arg(long, default_value_t = 101_325.0, value_name = "PA")]
    pub pressure: f64,
    /// Diaphragm compliance sigma of the end volume (dV/V = sigma dp/p_s; acts as extra volume).
    #[arg(long, default_value_t = 0.0, value_name = "SIGMA")]
    pub sigma: f64,
    /// Polytropic constant k of the gas in the end volume (1.4 isentropic, 1.0 isothermal).
    #[arg(long, default_value_t = 1.4, value_name = "K")]
    pub cavity_k: f64,
    /// Radius of a cylindrical end cavity whose gas relaxes thermally (replaces --cavity-k).
    #[arg(long, value_name = "M")]
    pub cavity_radius: Option<f64>,
    /// Leak conductance of the end volume to the reference pressure in m^3/(s Pa).
    #[arg(long, default_value_t = 0.0, value_name = "G")]
    pub leak: f64,
    /// Quadratic (minor/orifice) loss coefficient K per stroke (entry 0.5 + exit 1.0 = 1.5),
    /// linearised for the step amplitude `--amplitude`.
    #[arg(long, value_name = "K")]
    pub minor_loss: Option<f64>,
    /// Step amplitude in Pa (the excitation's size; sets the minor-loss damping).
    #[arg(long, default_value_t = 1000.0, value_name = "PA")]
    pub amplitude: f64,
    /// Transducer diaphragm resonance FN,ZETA (Hz, -), e.g. 250e3,0.03.
    #[arg(long, value_name = "FN,ZETA")]
    pub diaphragm: Option<String>,
}

/// Parses `A,B` into two finite numbers.
fn pair(text: &str, what: &'static str, form: &str) -> Result<(f64, f64)> {
    let bad = || Error::InvalidArgument {
        what,
        message: format!("expected {form}, got '{text}'"),
    };
    let mut it = text.split(',').map(|x| x.trim().parse::<f64>());
    match (it.next(), it.next(), it.next()) {
        (Some(Ok(a)), Some(Ok(b)), None) if a.is_finite() && b.is_finite() => Ok((a, b)),
        _ => Err(bad()),
    }
}

impl SystemArgs {
    /// The probe described, its arguments parsed; the library checks and assembles it.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] for a pair that is not two numbers; the library's checks.
    pub fn build(&self) -> Result<ProbeSystem> {
        let hole = match &self.hole {
            Some(h) => Some(pair(h, "--hole", "LENGTH,DIAMETER in m")?),
            None => None,
        };
        let tubes = self
            .lines
            .iter()
            .map(|text| pair(text, "--line", "LENGTH,DIAMETER in m"))
            .collect::<Result<Vec<_>>>()?;
        let diaphragm = match &self.diaphragm {
            Some(text) => {
                let (f, z) = pair(text, "--diaphragm", "FN,ZETA (Hz, -)")?;
                Some(Diaphragm {
                    natural_frequency_hz: f,
                    damping: z,
                })
            }
            None => None,
        };
        ProbeSpec {
            tubes,
            volume_m3: self.volume,
            hole,
            hole_end: match self.hole_end {
                EndArg::Flanged => EndKind::Flanged,
                EndArg::Unflanged => EndKind::Unflanged,
                EndArg::None => EndKind::None,
            },
            temperature_k: self.temperature,
            pressure_pa: self.pressure,
            sigma: self.sigma,
            cavity_k: self.cavity_k,
            cavity_radius_m: self.cavity_radius,
            leak_m3_per_s_pa: self.leak,
            minor_loss_k: self.minor_loss,
            step_amplitude_pa: self.amplitude,
            diaphragm,
        }
        .build()
    }
}

/// Excitation kind on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExcitationArg {
    /// Shock-tube step: rises by --amplitude in --rise (default 1 us).
    Shock,
    /// Burst balloon: falls by --amplitude in --rise (default 700 us).
    Balloon,
    /// Fast-opening valve: rises by --amplitude in --rise (default 200 us), optional --chamber.
    Valve,
    /// Traverse through cascade wakes of depth --amplitude at --wake-hz, with a tunnel
    /// oscillation at --tunnel-hz.
    Wake,
}

/// Arguments of `unlag simulate-test`.
#[derive(Debug, Args)]
pub struct SimulateTestArgs {
    /// The probe.
    #[command(flatten)]
    pub system: SystemArgs,
    /// Sample rate of the acquisition in Hz.
    #[arg(long, value_name = "HZ")]
    pub fs: f64,
    /// Record length in s.
    #[arg(long, default_value_t = 0.1, value_name = "S")]
    pub duration: f64,
    /// Time of the event (step) in the record in s (default: 10 % of the record); need not
    /// fall on a sample.
    #[arg(long, value_name = "S")]
    pub event_at: Option<f64>,
    /// The facility.
    #[arg(long, value_enum)]
    pub excitation: ExcitationArg,
    /// Rise (shock, valve) or fall (balloon) time in s.
    #[arg(long, value_name = "S")]
    pub rise: Option<f64>,
    /// Valve chamber oscillation HZ,FRACTION (fraction of the step).
    #[arg(long, value_name = "HZ,FRACTION")]
    pub chamber: Option<String>,
    /// Wake passing frequency in Hz (traverse speed / pitch).
    #[arg(long, default_value_t = 50.0, value_name = "HZ")]
    pub wake_hz: f64,
    /// Wake width as a fraction of the pitch.
    #[arg(long, default_value_t = 0.1, value_name = "FRACTION")]
    pub wake_width: f64,
    /// Tunnel oscillation frequency in Hz.
    #[arg(long, default_value_t = 20.0, value_name = "HZ")]
    pub tunnel_hz: f64,
    /// Tunnel oscillation amplitude in Pa (default 5 % of --amplitude).
    #[arg(long, value_name = "PA")]
    pub tunnel_amplitude: Option<f64>,
    /// White noise on the probe channel, standard deviation in Pa.
    #[arg(long, default_value_t = 0.0, value_name = "PA")]
    pub noise: f64,
    /// White noise on the reference channel, standard deviation in Pa.
    #[arg(long, default_value_t = 0.0, value_name = "PA")]
    pub reference_noise: f64,
    /// ADC resolution in bits (both channels).
    #[arg(long, value_name = "BITS")]
    pub adc_bits: Option<u32>,
    /// ADC range MIN,MAX in Pa (default: the signals' range plus 10 % each side).
    #[arg(long, value_name = "MIN,MAX")]
    pub adc_range: Option<String>,
    /// Extra delay of the probe channel in s (timing skew; any fraction of a sample).
    #[arg(long, default_value_t = 0.0, value_name = "S")]
    pub skew: f64,
    /// Reference transducer resonance FN,ZETA (Hz, -); default: an ideal reference.
    #[arg(long, value_name = "FN,ZETA")]
    pub reference_sensor: Option<String>,
    /// Analog anti-alias filter HZ,ORDER (Butterworth) on both channels.
    #[arg(long, value_name = "HZ,ORDER")]
    pub anti_alias: Option<String>,
    /// Internal simulation rate as a multiple of --fs.
    #[arg(long, default_value_t = 32, value_name = "N")]
    pub oversample: usize,
    /// Seed of the noise generator.
    #[arg(long, default_value_t = 1, value_name = "N")]
    pub seed: u64,
    /// Static gain error of the probe channel (0.02 = +2 %).
    #[arg(long, default_value_t = 0.0, value_name = "E")]
    pub gain_error: f64,
    /// Mains hum on the probe channel PA,HZ.
    #[arg(long, value_name = "PA,HZ")]
    pub hum: Option<String>,
    /// Zero drift of the probe channel after the event in Pa/s.
    #[arg(long, default_value_t = 0.0, value_name = "PA/S")]
    pub drift: f64,
    /// Output CSV (columns t, u = reference, y = probe, in Pa relative to the level before
    /// the event's start).
    #[arg(short = 'o', long = "output", value_name = "FILE.csv")]
    pub output: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

fn excitation_of(args: &SimulateTestArgs) -> Result<Excitation> {
    let chamber = match &args.chamber {
        Some(c) => Some(pair(c, "--chamber", "HZ,FRACTION")?),
        None => None,
    };
    let facility = match args.excitation {
        ExcitationArg::Shock => Facility::ShockTube,
        ExcitationArg::Balloon => Facility::Balloon,
        ExcitationArg::Valve => Facility::Valve,
        ExcitationArg::Wake => Facility::CascadeWake,
    };
    Excitation::of_facility(
        facility,
        &FacilitySettings {
            amplitude_pa: args.system.amplitude,
            rise_s: args.rise,
            chamber,
            wake_hz: args.wake_hz,
            wake_width: args.wake_width,
            tunnel_amplitude_pa: args.tunnel_amplitude,
            tunnel_hz: args.tunnel_hz,
        },
    )
}

/// Runs `unlag simulate-test`.
///
/// # Errors
/// Invalid arguments, numerical failures of the simulation, the output file.
pub fn run_simulate_test(args: &SimulateTestArgs) -> Result<()> {
    let (test, sys, adc) = simulated_test(args, &mut |line| crate::errln!("{line}"))?;
    crate::file::write_atomically_with(&args.output, |out| Ok(test.write_csv(out)?))?;
    print_simulated(args, &sys, &test, adc);
    Ok(())
}

/// The step test `unlag simulate-test` writes (before it is written), the probe simulated and
/// the ADC applied; `note` is given each line the command prints on stderr where the
/// simulation fell short of what was asked (as it is found: before the ADC is applied).
///
/// # Errors
/// Invalid arguments, numerical failures of the simulation.
pub fn simulated_test(
    args: &SimulateTestArgs,
    note: &mut dyn FnMut(String),
) -> Result<(SimulatedTest, ProbeSystem, Option<Adc>)> {
    let sys = args.system.build()?;
    let excitation = excitation_of(args)?;
    let anti_alias = anti_alias_of(args)?;
    let reference_sensor = reference_sensor_of(args)?;
    let probe = Probe {
        line: sys.line.clone(),
        gas: sys.gas,
        diaphragm: sys.diaphragm,
        anti_alias,
        skew_s: args.skew,
    };
    let acquisition = acquisition_of(args, reference_sensor)?;
    let mut test = simulate(&probe, &excitation, &acquisition)?;
    simulation_limits(&test, &probe, &acquisition, note);
    let adc = quantise_as_asked(args, &mut test)?;
    Ok((test, sys, adc))
}

/// The `--anti-alias HZ,ORDER` filter, its order a whole number the filter accepts.
fn anti_alias_of(args: &SimulateTestArgs) -> Result<Option<Butterworth>> {
    Ok(match &args.anti_alias {
        Some(text) => {
            let (f, n) = pair(text, "--anti-alias", "HZ,ORDER")?;
            // A whole number is parsed here; its range is the filter's.
            let refused = || Error::InvalidArgument {
                what: "--anti-alias",
                message: format!(
                    "order {n} must be a whole number 1..={}",
                    Butterworth::MAX_ORDER
                ),
            };
            if n.fract() != 0.0 || !(0.0..=f64::from(u32::MAX)).contains(&n) {
                return Err(refused());
            }
            let filter = Butterworth {
                corner_hz: f,
                order: n as u32,
            };
            filter.check_order().map_err(|_| refused())?;
            Some(filter)
        }
        None => None,
    })
}

/// The `--reference-sensor FN,ZETA` resonance of the reference transducer.
fn reference_sensor_of(args: &SimulateTestArgs) -> Result<Option<Diaphragm>> {
    Ok(match &args.reference_sensor {
        Some(text) => {
            let (f, z) = pair(text, "--reference-sensor", "FN,ZETA (Hz, -)")?;
            Some(Diaphragm {
                natural_frequency_hz: f,
                damping: z,
            })
        }
        None => None,
    })
}

/// The acquisition: rate, record, event time, noise, reference sensor, gain error, hum and drift.
fn acquisition_of(
    args: &SimulateTestArgs,
    reference_sensor: Option<Diaphragm>,
) -> Result<Acquisition> {
    let (hum_pa, hum_hz) = match &args.hum {
        Some(text) => pair(text, "--hum", "PA,HZ")?,
        None => Acquisition::NO_HUM,
    };
    Ok(Acquisition {
        sample_rate_hz: args.fs,
        duration_s: args.duration,
        event_time_s: args
            .event_at
            .unwrap_or_else(|| Acquisition::default_event_time_s(args.duration)),
        oversample: args.oversample,
        probe_noise_pa: args.noise,
        reference_noise_pa: args.reference_noise,
        adc: None,
        reference_sensor,
        seed: args.seed,
        probe_gain_error: args.gain_error,
        hum_pa,
        hum_hz,
        drift_pa_per_s: args.drift,
    })
}

/// Notes (for stderr) where the simulation fell short of what was asked: a reduced rate, a
/// resonance above the band.
fn simulation_limits(
    test: &SimulatedTest,
    probe: &Probe,
    acquisition: &Acquisition,
    note: &mut dyn FnMut(String),
) {
    if let Some(r) = test.reduced_rate(acquisition) {
        note(format!(
            "note: the response outlasts the longest FFT at {}x oversampling (a slow real pole); simulated at {:.0}x ({:.0} Hz), content above {:.0} Hz tapered off",
            r.asked,
            r.achieved,
            r.rate_hz,
            r.taper_start_hz
        ));
    }
    if let Some(r) = test.resonance_above_band(probe) {
        note(format!(
            "warning: the diaphragm resonance at {} Hz is above the simulated band (taper from {:.0} Hz) and is filtered out: raise --oversample to see it",
            r.natural_frequency_hz, r.taper_start_hz
        ));
    }
}

/// The ADC asked for (`--adc-bits`, `--adc-range`), applied after the simulation as its range may come from the signals.
fn quantise_as_asked(args: &SimulateTestArgs, test: &mut SimulatedTest) -> Result<Option<Adc>> {
    Ok(match args.adc_bits {
        Some(bits) => Some(test.quantise(match &args.adc_range {
            Some(text) => {
                let (min_pa, max_pa) = pair(text, "--adc-range", "MIN,MAX in Pa")?;
                Quantisation::Fixed(Adc {
                    bits,
                    min_pa,
                    max_pa,
                })
            }
            None => Quantisation::FromSignals { bits },
        })?),
        None => {
            if args.adc_range.is_some() {
                return Err(Error::InvalidArgument {
                    what: "--adc-range",
                    message: "needs --adc-bits".into(),
                });
            }
            None
        }
    })
}

/// The simulated test's summary, as JSON or as text.
fn print_simulated(
    args: &SimulateTestArgs,
    sys: &ProbeSystem,
    test: &SimulatedTest,
    adc: Option<Adc>,
) {
    let ir = &test.impulse;
    if args.json {
        let v = json!({
            "output": args.output.display().to_string(),
            "samples": test.t.len(),
            "sample_rate_hz": args.fs,
            "front_delay_s": sys.line.front_delay_s(&sys.gas),
            "dc_gain": sys.line.dc_gain(&sys.gas),
            "minor_loss_resistance_pa_s_per_m3": sys.minor_loss_resistance,
            "adc_lsb_pa": adc.map(|a| a.lsb_pa()),
            "method": {
                "internal_rate_hz": ir.rate_hz,
                "fft_length": ir.fft_length,
                "impulse_response_s": ir.taps.len() as f64 / ir.rate_hz,
                "tail_energy": ir.tail_energy,
                "noncausal_energy": ir.noncausal_energy,
                "taper_start_hz": ir.taper_start_hz,
            },
        });
        crate::outln!("{v}");
        return;
    }
    crate::outln!(
        "simulated {} samples at {} Hz ({:?}); front delay {:.6} s, DC gain {:.6}",
        test.t.len(),
        args.fs,
        args.excitation,
        sys.line.front_delay_s(&sys.gas),
        sys.line.dc_gain(&sys.gas)
    );
    if let Some(r) = sys.minor_loss_resistance {
        crate::outln!(
            "  minor losses linearised for {} Pa: R_eq = {r:.4e} Pa s/m^3",
            args.system.amplitude
        );
    }
    crate::outln!(
        "  method: impulse response by tapered inverse FFT at {:.0} Hz, length {} ({:.4} s), tail energy {:.1e} (wrap-around bound), non-causal taper energy {:.1e}, taper from {:.0} Hz",
        ir.rate_hz,
        ir.fft_length,
        ir.taps.len() as f64 / ir.rate_hz,
        ir.tail_energy,
        ir.noncausal_energy,
        ir.taper_start_hz
    );
    if let Some(a) = adc {
        crate::outln!(
            "  ADC {} bits over [{}, {}] Pa, LSB {:.4e} Pa",
            a.bits,
            a.min_pa,
            a.max_pa,
            a.lsb_pa()
        );
    }
    crate::outln!("wrote {}", args.output.display());
}
