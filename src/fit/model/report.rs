//! The fit's report: where a model came from ([`Source`]), how it was identified
//! ([`Method`], [`FitReport`] with its order and delay tables) and how well its parameters are
//! known ([`Uncertainty`]).

use serde::{Deserialize, Serialize};

use crate::fit::OrderSelection;

/// Where a model came from: one trace file and its role.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// File name as given on the command line.
    pub file: String,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    /// What the test was used for, written `estimation` or `validation`.
    pub role: TestRole,
    /// Simulation error on this trace: RMS(y - y_model) / range(y).
    pub nrmse: f64,
    /// Noise floor of the probe channel on this trace: RMS noise / range(y).
    pub noise_floor: f64,
    /// With a noise model, the floor of the error [`Self::nrmse`] then is (the one-step-ahead
    /// prediction error): both channels' noise's innovation over range(y).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction_floor: Option<PredictionFloor>,
}

/// The floor of a one-step-ahead prediction error on a test: the part of both channels' noise
/// (the probe's, and the reference's through the model) that no predictor removes
/// ([`crate::fit::noise::both_channels_innovation`]), over the test's range, read from the quiet
/// segment before a step; a test without one (a traverse) takes it from another test of the
/// same sensors that has one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PredictionFloor {
    /// RMS innovation / range(y).
    pub value: f64,
    /// The test whose quiet segment it was read from.
    pub from: String,
}

impl PredictionFloor {
    /// Where it comes from, in words: `the innovation of both channels' noise through the
    /// model, from est.csv's quiet segment`.
    #[must_use]
    pub fn origin(&self) -> String {
        format!(
            "the innovation of both channels' noise through the model, from {}'s quiet segment",
            self.from
        )
    }
}

/// For a unit enum `$ty` with `ALL` and a name per variant (`$ty::$name`): `from_name`, its
/// inverse; written by its name (`From<$ty> for &str`, which serde uses); read from its name
/// (`TryFrom<String>`), another name refused with the names there are, `$what` saying what was
/// asked for.
macro_rules! named {
    ($ty:ident, $name:ident, $what:literal) => {
        impl $ty {
            /// The value a name stands for (the inverse of its name).
            #[must_use]
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.into_iter().find(|v| v.$name() == name)
            }
        }

        impl From<$ty> for &'static str {
            fn from(v: $ty) -> Self {
                v.$name()
            }
        }

        impl TryFrom<String> for $ty {
            type Error = String;

            fn try_from(name: String) -> std::result::Result<Self, String> {
                Self::from_name(&name).ok_or_else(|| {
                    let names: Vec<&str> = Self::ALL.into_iter().map(Self::$name).collect();
                    format!(
                        concat!("unknown ", $what, " `{}`: one of {}"),
                        name,
                        names.join(", ")
                    )
                })
            }
        }
    };
}

/// What a step test is to a fit: the first file given is the estimation test, the model
/// fitted on it; any others are validation tests, held out to choose the order and judge it.
/// Stored and printed by its name ([`TestRole::as_str`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "&'static str", try_from = "String")]
pub enum TestRole {
    /// The test the model is fitted on.
    Estimation,
    /// A held-out test.
    Validation,
}

impl TestRole {
    /// Both roles, in the order their names are listed.
    pub const ALL: [Self; 2] = [Self::Estimation, Self::Validation];

    /// The role of the `i`-th test given (from 0): the first is the estimation test.
    #[must_use]
    pub fn of_index(i: usize) -> Self {
        if i == 0 {
            Self::Estimation
        } else {
            Self::Validation
        }
    }

    /// Name used in files, JSON and printed tables.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Estimation => "estimation",
            Self::Validation => "validation",
        }
    }
}

impl std::fmt::Display for TestRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // `pad`, not `write_str`: printed tables align the role with `{:<11}`.
        f.pad(self.as_str())
    }
}

named!(TestRole, as_str, "test role");

/// Identification method; stored in the model file's fit report and given on the command
/// line by its name ([`Method::name`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(into = "&'static str", try_from = "String")]
pub enum Method {
    /// Output error (simulation error) by Levenberg-Marquardt from Steiglitz-McBride: unbiased
    /// under white measurement noise.
    Oe,
    /// Box-Jenkins with an autoregressive noise model: output error, then alternately an AR
    /// model `D` of what the dynamics leave and an output-error refit of the dynamics on the
    /// data whitened by `D` (the one-step-ahead prediction error). For coloured probe noise,
    /// which plain output error partly takes for dynamics; for white residuals exactly output
    /// error. The default.
    #[default]
    Bj,
    /// Steiglitz-McBride iterations only.
    Sm,
    /// The paper's direct least squares on the ARX equation (eq. 5). Biased by measurement
    /// noise; kept for comparison with the paper.
    Arx,
}

impl Method {
    /// Every method, in the order their names are listed.
    pub const ALL: [Self; 4] = [Self::Oe, Self::Bj, Self::Sm, Self::Arx];

    /// Name used in files and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Oe => "oe",
            Self::Bj => "bj",
            Self::Sm => "sm",
            Self::Arx => "arx",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

named!(Method, name, "fit method");

/// How the model was fitted, and how well.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitReport {
    /// The identification method, stored by its name: `bj` (Box-Jenkins, the default), `oe`
    /// (output error), `sm` (Steiglitz-McBride) or `arx` (the paper's direct least squares).
    pub method: Method,
    /// How the order was chosen, stored as its words (`fixed`, `auto 1..=6: lowest BIC on the
    /// estimation test`, ...).
    pub order_selection: OrderSelection,
    /// Order-selection table: one row per order tried.
    #[serde(default)]
    pub orders: Vec<OrderRow>,
    /// How the delay was chosen.
    pub delay_selection: String,
    /// Delay evidence: simulation loss (normalised RMS) for each candidate delay.
    #[serde(default)]
    pub delay_candidates: Vec<DelayRow>,
    /// Step onset in the estimation reference, in samples from the start.
    pub step_onset: usize,
    /// What the fit decided beyond the tables (a slow pole-zero pair read as a drift).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// How sure the fit is of what it found (one standard deviation), when it could say.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<Uncertainty>,
    /// The DC gain the data gave, when the fit took it as 1 because it could not tell it from
    /// 1 (within [`crate::fit::CALIBRATED_SIGMAS`] of its standard deviation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_from: Option<f64>,
}

/// One standard deviation of what a fit found: the sandwich covariance of the estimate, the
/// residual counted as what both channels' noise leaves (the probe's, and the reference's
/// through the model), with a noise model on the whitened data, carried to the model's
/// features. It covers the noise, not the model's structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Uncertainty {
    /// The DC gain's standard deviation.
    pub dc_gain_std: f64,
    /// Each resonance, lowest natural frequency first.
    #[serde(default)]
    pub resonances: Vec<ResonanceUncertainty>,
    /// Whether the residual was whitened by a noise model first.
    pub noise_model: bool,
    /// Where the noise it counts was read (absent in a file written before this was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_from: Option<NoiseOrigin>,
}

/// `value`, `between` and `std`, the deviation to two significant digits and the value to
/// the same decimal place, as the GUM quotes a result (`112.631 +/- 0.031`); `value` alone to
/// four decimals when the deviation is zero or not a number.
#[must_use]
pub fn quoted(value: f64, std: f64, between: &str) -> String {
    match decimals(std) {
        Some(d) => format!("{value:.d$}{between}{std:.d$}"),
        None => format!("{value:.4}"),
    }
}

/// The decimal places that give `std` two significant digits (none for a zero or non-finite
/// deviation).
fn decimals(std: f64) -> Option<usize> {
    (std.is_finite() && std > 0.0).then(|| (1.0 - std.log10().floor()).clamp(0.0, 12.0) as usize)
}

/// A deviation alone, to two significant digits.
#[must_use]
pub fn two_digits(std: f64) -> String {
    match decimals(std) {
        Some(d) => format!("{std:.d$}"),
        None => format!("{std}"),
    }
}

/// Where the noise a stated uncertainty counts was read, the surest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseOrigin {
    /// Each test's quiet segment before its step, both channels: the probe's noise and the
    /// reference's, which passes through the model into the residual.
    QuietSegment,
    /// A test without a quiet segment (a traverse) took both channels' noise from the quiet
    /// segment of a test fitted with it: the same sensors.
    Borrowed,
    /// No quiet segment to read: the residual's own colour (its AR model), and beside it the
    /// reference's noise from its highest frequencies through the model, which errs wide.
    ResidualColour,
}

impl Uncertainty {
    /// One line: `DC gain +/- 0.00012; 113.33 +/- 0.21 Hz, damping 0.2506 +/- 0.0010` (each
    /// deviation to two significant digits, [`quoted`]).
    #[must_use]
    pub fn summary(&self) -> String {
        let modes: String = self
            .resonances
            .iter()
            .map(|q| {
                format!(
                    "; {} Hz, damping {}",
                    quoted(q.natural_frequency_hz, q.natural_frequency_std_hz, " +/- "),
                    quoted(q.damping, q.damping_std, " +/- ")
                )
            })
            .collect();
        format!("DC gain +/- {}{modes}", two_digits(self.dc_gain_std))
    }

    /// How the noise was counted, in words: where it was read, and whether a noise model
    /// whitened the residual first.
    #[must_use]
    pub fn noise_text(&self) -> String {
        let read = match self.noise_from {
            Some(NoiseOrigin::QuietSegment) => "both channels' noise read before the step",
            Some(NoiseOrigin::Borrowed) => {
                "both channels' noise read before the step, a test without a quiet segment \
                 taking it from one fitted with it"
            }
            Some(NoiseOrigin::ResidualColour) => {
                "the residual's own colour and the reference's high-frequency noise through \
                 the model (no quiet segment before a step; errs wide)"
            }
            None => "the residual",
        };
        if self.noise_model {
            format!("{read}, whitened by the noise model")
        } else {
            read.to_string()
        }
    }
}

/// A resonance's natural frequency and damping with their standard deviations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResonanceUncertainty {
    /// Natural frequency, Hz.
    pub natural_frequency_hz: f64,
    /// Its standard deviation, Hz.
    pub natural_frequency_std_hz: f64,
    /// Damping ratio.
    pub damping: f64,
    /// Its standard deviation.
    pub damping_std: f64,
}

/// One row of the order-selection table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderRow {
    /// Order.
    pub order: usize,
    /// Delay found for this order.
    pub delay: usize,
    /// Simulation error on the estimation data.
    pub nrmse_estimation: f64,
    /// The criterion compared: held-out error, or BIC with one trace.
    pub criterion: f64,
    /// Whether the model is stable.
    pub stable: bool,
}

/// One candidate delay and its loss.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DelayRow {
    /// Delay in samples.
    pub delay: usize,
    /// Simulation error (normalised RMS) with this delay.
    pub nrmse: f64,
}
