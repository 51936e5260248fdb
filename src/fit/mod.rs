//! Fitting a probe model to step tests: step and delay, order, coefficients.
//!
//! This module owns the identification loop of the paper (section 2.2), made robust to noise:
//!
//! 1. [`step`]: locate the step in the reference and the noise level of each channel.
//! 2. Delay: for each candidate `d`, fit a model and measure its *simulation* error; the delay
//!    is the largest `d` whose loss is the lowest (within the loss's statistical spread). A
//!    threshold on the raw probe signal reads the delay late, because a second-order line
//!    starts as `t^2`; the loss over delays does not. The table of losses is the evidence and
//!    is stored in the model file. A long range of delays (a slow probe sampled fast) is
//!    searched coarse to fine.
//! 3. Coefficients, by [`Method`]: output error (default), Steiglitz-McBride, or the paper's
//!    direct least squares ([`arx`]).
//! 4. Order: fixed, or chosen automatically from held-out tests (the other files given), or,
//!    with one test only, by the Bayesian information criterion. The table is returned.
//!
//! Signals are fitted as deviations from their pre-step levels, which matches a model that
//! starts in equilibrium.

pub mod analysis;
pub mod arx;
pub mod calibration;
pub mod continuous;
pub mod covariance;
mod delay;
mod error;
pub mod model;
pub mod noise;
pub mod oe;
pub mod selection;
pub mod step;
pub(crate) mod uncertainty;

pub use calibration::{CALIBRATED_SIGMAS, CALIBRATION_MAX_STD};
pub use error::{ContinuousError, FitError};
pub use model::{Method, Model, NoiseOrigin, TestRole};
use selection::{choose, judge_order, order_selection, OrderFit};
pub use selection::{OrderRule, OrderSelection, UnknownOrderSelection};

use crate::error::{Error, Result};
use crate::fit::model::{DelayRow, FitReport, OrderRow};
use arx::Data;

/// How to choose the order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Try `1..=max` and choose.
    Auto {
        /// Largest order tried.
        max: usize,
    },
    /// Use this order.
    Fixed(usize),
}

impl Default for Order {
    fn default() -> Self {
        Self::Auto { max: 6 }
    }
}

/// Fit options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Options {
    /// Identification method.
    pub method: Method,
    /// Order choice.
    pub order: Order,
    /// A known delay in samples (skips the delay search).
    pub delay: Option<usize>,
}

/// One test's signals for fitting.
#[derive(Debug, Clone, Copy)]
pub struct Test<'a> {
    /// Name for messages (the file).
    pub name: &'a str,
    /// Reference.
    pub u: &'a [f64],
    /// Probe output.
    pub y: &'a [f64],
}

/// What a fit returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Fitted {
    /// The model.
    pub model: Model,
    /// How it was found (tables included).
    pub report: FitReport,
    /// Simulation error on the estimation test.
    pub nrmse_estimation: f64,
    /// Simulation error on each validation test, in the order given.
    pub nrmse_validation: Vec<f64>,
}

/// Normalised simulation error of `model` on a test: `RMS(y - y_model) / range(y)`, with the
/// model started in equilibrium with the reference's resting level, or from the state that
/// best explains the test where it does not start at rest ([`Model::simulate_matched`]).
#[must_use]
pub fn nrmse(model: &Model, u: &[f64], y: &[f64]) -> f64 {
    let ym = model.simulate_matched(u, y);
    nrmse_of(y, &ym)
}

/// `RMS(y - y_model) / range(y)`.
#[must_use]
pub fn nrmse_of(y: &[f64], ym: &[f64]) -> f64 {
    nrmse_of_error(y, y.iter().zip(ym).map(|(a, b)| a - b))
}

/// `RMS(error) / range(y)`: an error sequence (a simulation's, a one-step predictor's) over
/// the range of the signal it belongs to.
#[must_use]
pub fn nrmse_of_error(y: &[f64], error: impl IntoIterator<Item = f64>) -> f64 {
    let (sum, n) = error
        .into_iter()
        .fold((0.0, 0usize), |(s, n), e| (s + e * e, n + 1));
    if n == 0 {
        return f64::NAN;
    }
    (sum / n as f64).sqrt() / range(y)
}

/// `max(x) - min(x)`: what an NRMSE and a floor are over (`-inf` for no samples).
#[must_use]
pub(crate) fn range(x: &[f64]) -> f64 {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    hi - lo
}

/// Noise floor of the probe channel: noise RMS / range(y), the noise as
/// [`step::channel_noise`] measures it (the quiet segment ending at `quiet`, from
/// [`step::quiet_until`] of the reference, else the highest frequencies).
#[must_use]
pub fn noise_floor(y: &[f64], quiet: usize) -> f64 {
    // Before the step when that segment is quiet, else from the highest frequencies (a
    // traverse has no quiet segment: its "pre-step" part is signal).
    let (sigma, _) = step::channel_noise(y, quiet);
    sigma / range(y)
}

/// Deviations of a test from its pre-step levels.
struct Prepared {
    u: Vec<f64>,
    y: Vec<f64>,
    onset: usize,
}

fn prepare(test: &Test<'_>) -> Result<Prepared> {
    if test.u.len() != test.y.len() {
        return Err(Error::Mismatch {
            path: test.name.into(),
            message: format!(
                "reference has {} samples, probe {}",
                test.u.len(),
                test.y.len()
            ),
        });
    }
    let s = step::find_step(test.u).map_err(|reason| Error::NoStep {
        path: test.name.into(),
        column: 0,
        name: "u".into(),
        reason,
    })?;
    let y0 = if s.onset > 0 {
        step::mean_std(&test.y[..s.onset]).0
    } else {
        test.y[0]
    };
    Ok(Prepared {
        u: test.u.iter().map(|v| v - s.before).collect(),
        y: test.y.iter().map(|v| v - y0).collect(),
        onset: s.onset,
    })
}

/// Samples the order choice looks at in a long record (from just before the step).
pub const SELECTION_WINDOW: usize = 50_000;

/// Iterations of the refinement on the whole record: it starts from the window's fit, and
/// on a long record an ill-conditioned model creeps on by statistically negligible steps.
const REFINE_ITERATIONS: usize = 20;

/// Samples kept before the step in the order choice's window.
const WINDOW_LEAD: usize = 200;

/// The order choice's window, when the record is longer than it.
fn selection_window(p: &Prepared) -> Option<std::ops::Range<usize>> {
    let start = p.onset.saturating_sub(WINDOW_LEAD);
    let end = start + SELECTION_WINDOW;
    (end < p.y.len()).then_some(start..end)
}

/// The chosen model refined on the whole record from its fit on the window: the iterative
/// methods start from it, the least-squares ones are refitted.
fn refine(whole: &[Data<'_>], model: &Model, method: Method) -> Result<(Vec<f64>, Vec<f64>)> {
    let (d, m) = (model.delay, model.a.len());
    match method {
        Method::Arx | Method::Sm => fit_at(whole, m, d, method),
        // The window's Box-Jenkins fit is a good start for the whole record's.
        Method::Bj => box_jenkins(whole, (model.a.clone(), model.b.clone()), d, true),
        Method::Oe => {
            let (b, short) = unpadded(&model.b);
            let (a, b) = oe::output_error_from(
                whole,
                (model.a.clone(), b),
                d,
                REFINE_ITERATIONS,
                oe::WARM_DAMPING,
            )?;
            Ok((a, padded(b, short)))
        }
    }
}

/// Rounds of the Box-Jenkins alternation (noise model, then dynamics on whitened data).
const BJ_ROUNDS: usize = 4;

/// Box-Jenkins refinement of `init`: alternately the AR noise model of the simulation
/// residual and an output-error refit on the data whitened by it. `D (y - G u) = D y - G (D u)`
/// for causal filters from rest, so the refit is an ordinary output-error fit of `(D u, D y)`.
/// A numerator whose last coefficient is exactly zero (the short numerator) stays short.
/// `warm`: `init` is the optimum of nearby data, so the first step tried is undamped.
fn box_jenkins(
    sets: &[Data<'_>],
    init: (Vec<f64>, Vec<f64>),
    d: usize,
    warm: bool,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (b, short) = unpadded(&init.1);
    let mut current = (init.0, b);
    let mut previous_ar: Vec<f64> = Vec::new();
    for _ in 0..BJ_ROUNDS {
        let ar = residual_noise(sets, (&current.0, &current.1), d).0;
        if ar.is_empty() {
            break;
        }
        let settled = ar.len() == previous_ar.len()
            && ar
                .iter()
                .zip(&previous_ar)
                .all(|(x, y)| (x - y).abs() < 1e-3);
        let white = whitened(sets, &ar);
        let wsets: Vec<Data<'_>> = white.iter().map(|(u, y)| Data { u, y }).collect();
        // `warm`: `init` is an optimum of nearby data (the window's), and so is each round's
        // start.
        let damping = if warm {
            oe::WARM_DAMPING
        } else {
            oe::FRESH_DAMPING
        };
        current = oe::output_error_from(&wsets, current, d, 60, damping)?;
        if settled {
            break;
        }
        previous_ar = ar;
    }
    Ok((current.0, padded(current.1, short)))
}

/// A numerator without the zero that pads the short numerator (`m` coefficients stored as
/// `m + 1`), and whether it was there; [`padded`] puts it back.
pub(crate) fn unpadded(b: &[f64]) -> (Vec<f64>, bool) {
    let short = b.len() > 1 && b.last() == Some(&0.0);
    let kept = if short { &b[..b.len() - 1] } else { b };
    (kept.to_vec(), short)
}

/// `b` with the short numerator's padding zero back when `short`.
pub(crate) fn padded(mut b: Vec<f64>, short: bool) -> Vec<f64> {
    if short {
        b.push(0.0);
    }
    b
}

/// The AR noise model of the simulation residuals at `(a, b)`, and the residuals.
fn residual_noise(
    sets: &[Data<'_>],
    (a, b): (&[f64], &[f64]),
    d: usize,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let residual = residuals(sets, (a, b), d);
    (
        noise::fit(&residual.concat(), noise::MAX_NOISE_ORDER).ar,
        residual,
    )
}

/// Each data set's `(D u, D y)` under the noise model `ar`.
fn whitened(sets: &[Data<'_>], ar: &[f64]) -> Vec<(Vec<f64>, Vec<f64>)> {
    sets.iter()
        .map(|s| (noise::whiten(ar, s.u), noise::whiten(ar, s.y)))
        .collect()
}

/// The simulation residual `y - q^-d B/A u` of each data set.
fn residuals(sets: &[Data<'_>], (a, b): (&[f64], &[f64]), d: usize) -> Vec<Vec<f64>> {
    sets.iter()
        .map(|s| {
            let yh = crate::fit::model::filter(b, a, d, s.u);
            s.y.iter().zip(&yh).map(|(y, h)| y - h).collect()
        })
        .collect()
}

/// The sum of squared one-step-ahead prediction errors of `model` under the AR noise model of
/// its simulation residual, and that noise model's number of parameters.
fn prediction_loss(sets: &[Data<'_>], model: &Model) -> (f64, usize) {
    let (ar, residual) = residual_noise(sets, (&model.a, &model.b), model.delay);
    let rss = residual
        .iter()
        .map(|v| noise::whiten(&ar, v).iter().map(|e| e * e).sum::<f64>())
        .sum();
    (rss, ar.len())
}

/// Fits one order at one delay with the chosen method.
fn fit_at(sets: &[Data<'_>], m: usize, d: usize, method: Method) -> Result<(Vec<f64>, Vec<f64>)> {
    match method {
        Method::Arx => arx::fit(sets, m, d),
        Method::Sm => oe::steiglitz_mcbride(sets, m, d, 20),
        Method::Bj => {
            let init = fit_at(sets, m, d, Method::Oe)?;
            box_jenkins(sets, init, d, false)
        }
        Method::Oe => {
            // Two numerators: the paper's m + 1 coefficients, and m. A probe sampled through a
            // hold has exactly m coefficients after its delay; the extra one then only fits
            // noise, and tends to put a zero far outside the unit circle, which costs the
            // inverse. Keep m + 1 only when it lowers the simulation error by more than the
            // BIC penalty of one parameter.
            let full = {
                let init = oe::steiglitz_mcbride(sets, m, d, 20)?;
                oe::output_error(sets, init, d, 60)?
            };
            let Ok(init) = oe::steiglitz_mcbride_nb(sets, m, m, d, 20) else {
                return Ok(full);
            };
            let Ok(short) = oe::output_error(sets, init, d, 60) else {
                return Ok(full);
            };
            let n: usize = sets.iter().map(|s| s.y.len()).sum();
            let l_full = oe::loss(sets, (&full.0, &full.1), d);
            let l_short = oe::loss(sets, (&short.0, &short.1), d);
            let n = n as f64;
            if l_short.is_finite() && l_short <= l_full * (1.0 + n.ln() / n) {
                let (a, mut b) = short;
                b.push(0.0);
                Ok((a, b))
            } else {
                Ok(full)
            }
        }
    }
}

/// `f` of each item, in the items' order, on up to as many threads as the machine has cores
/// (each item on one thread; the results do not depend on which).
pub(crate) fn in_parallel<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let slots: Vec<std::sync::Mutex<Option<R>>> =
        items.iter().map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                // The last items first (the fit's highest orders, which take longest).
                while let Some(i) = items
                    .len()
                    .checked_sub(1 + next.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
                {
                    let Some(item) = items.get(i) else { break };
                    let r = f(item);
                    if let Some(slot) = slots.get(i) {
                        if let Ok(mut s) = slot.lock() {
                            *s = Some(r);
                        }
                    }
                }
            });
        }
    });
    slots
        .into_iter()
        .filter_map(|s| s.into_inner().ok().flatten())
        .collect()
}

/// Fits a model to the estimation test; validation tests are held out (used for the order
/// choice and reported). A DC gain the fit cannot tell from 1 is then taken as 1
/// ([`calibration::calibrate_fitted`]); [`fit_as_found`] keeps it.
///
/// # Errors
/// [`Error::NoStep`] when the reference has no step, [`Error::TooShort`] when the test is too
/// short for the order and delay, [`Error::UnstableModel`] when the chosen fit is unstable,
/// [`FitError`] when the data do not determine a model.
pub fn fit(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    sample_rate_hz: f64,
    options: &Options,
) -> Result<Fitted> {
    let mut fitted = fit_as_found(estimation, validation, sample_rate_hz, options)?;
    calibration::calibrate_fitted(&mut fitted, estimation, validation);
    Ok(fitted)
}

/// [`fit`] without the calibration: the DC gain is the one the data give, even where it
/// cannot be told from 1. For a model whose physics sets the static gain below 1 (a leak).
///
/// # Errors
/// As [`fit`].
pub fn fit_as_found(
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    sample_rate_hz: f64,
    options: &Options,
) -> Result<Fitted> {
    let p = prepare(estimation)?;
    let whole = [Data { u: &p.u, y: &p.y }];
    // A long record: the orders are compared on a window from just before the step, and the
    // chosen one is refined on the whole record from there.
    let window = selection_window(&p);
    let data = match &window {
        Some(r) => [Data {
            u: &p.u[r.clone()],
            y: &p.y[r.clone()],
        }],
        None => whole,
    };
    let (candidates, first_error) =
        fit_orders(&p, &data, estimation, validation, sample_rate_hz, options)?;
    let held_out = !validation.is_empty();
    let table: Vec<OrderRow> = candidates
        .iter()
        .map(|c| OrderRow {
            order: c.order,
            delay: c.model.delay,
            nrmse_estimation: c.est,
            criterion: c.criterion,
            stable: c.stable,
        })
        .collect();
    let usable: Vec<&OrderFit> = candidates
        .iter()
        .filter(|c| c.stable && c.criterion.is_finite())
        .collect();
    let Some(best_crit) = usable.iter().map(|c| c.criterion).reduce(f64::min) else {
        return Err(no_usable_order(&p, estimation, &candidates, first_error));
    };
    let chosen = choose(&usable, best_crit, held_out, estimation.name)?;
    let OrderFit {
        order: m,
        mut model,
        rows,
        mut est,
        mut val,
        ..
    } = chosen.clone();
    if window.is_some() {
        let refined = refine(&whole, &model, options.method)?;
        let candidate = Model {
            a: refined.0,
            b: refined.1,
            ..model.clone()
        };
        if candidate.check_stable("fit").is_ok() {
            model = candidate;
            est = nrmse(&model, estimation.u, estimation.y);
            val = validation.iter().map(|t| nrmse(&model, t.u, t.y)).collect();
        }
    }
    let report = FitReport {
        method: options.method,
        order_selection: order_selection(options.order, held_out, window.is_some()),
        orders: table,
        delay_selection: if options.delay.is_some() {
            "given".into()
        } else {
            delay::selection(m, &rows)
        },
        delay_candidates: rows,
        step_onset: p.onset,
        notes: Vec::new(),
        uncertainty: uncertainty::uncertainty(
            &whole,
            &model,
            options.method,
            uncertainty::levels(&p.u, &p.y, p.onset).or_borrowed(validation),
        ),
        calibrated_from: None,
    };
    Ok(Fitted {
        model,
        report,
        nrmse_estimation: est,
        nrmse_validation: val,
    })
}

/// Each order the options allow fitted on `data` (the selection window of `p`) and judged:
/// the fits in order, and the first error of an order that failed alone.
///
/// # Errors
/// An error that ends the whole fit ([`fit_order`]).
fn fit_orders(
    p: &Prepared,
    data: &[Data<'_>; 1],
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    sample_rate_hz: f64,
    options: &Options,
) -> Result<(Vec<OrderFit>, Option<Error>)> {
    let orders: Vec<usize> = match options.order {
        Order::Fixed(m) => vec![m],
        Order::Auto { max } => (1..=max.max(1)).collect(),
    };
    // Each order's delay search and fit are independent: they run on the cores there are,
    // and are taken in order, so the choice is the same as one after the other.
    let results = in_parallel(&orders, |&m| {
        fit_order(
            p,
            data,
            m,
            orders.len() == 1,
            estimation.name,
            sample_rate_hz,
            options,
        )
    });
    let mut candidates = Vec::new();
    let mut first_error = None;
    for result in results {
        match result {
            Ok((m, model, rows)) => {
                candidates.push(judge_order(
                    m,
                    model,
                    rows,
                    data,
                    estimation,
                    validation,
                    options.method,
                ));
            }
            Err((e, true)) => return Err(e),
            Err((e, false)) => {
                first_error.get_or_insert(e);
            }
        }
    }
    Ok((candidates, first_error))
}

/// The delay search and the fit at order `m` on `data` (the selection window), with the
/// delay's candidates; an error with `true` ends the whole fit (an order out of range, a
/// failed search, a record too short for an order given), with `false` only this order.
fn fit_order(
    p: &Prepared,
    data: &[Data<'_>; 1],
    m: usize,
    alone: bool,
    name: &str,
    sample_rate_hz: f64,
    options: &Options,
) -> std::result::Result<(usize, Model, Vec<DelayRow>), (Error, bool)> {
    if m == 0 || m > crate::fit::model::MAX_ORDER {
        return Err((
            Error::InvalidParameter {
                parameter: crate::error::Parameter::Order,
                message: format!(
                    "the order must be 1..={}, not {m}",
                    crate::fit::model::MAX_ORDER
                ),
            },
            true,
        ));
    }
    let (d, rows) = match options.delay {
        Some(d) => (d, Vec::new()),
        None => delay::search(&p.u, &p.y, p.onset, m, alone).map_err(|e| (e, true))?,
    };
    let needed = 2 * (2 * m + 1) + m + d + 1;
    if p.y.len() < needed {
        let e = Error::TooShort {
            path: name.into(),
            samples: p.y.len(),
            order: m,
            delay: d,
            needed,
        };
        return Err((e, matches!(options.order, Order::Fixed(_))));
    }
    let (a, b) = fit_at(data, m, d, options.method).map_err(|e| (e, false))?;
    let model = Model {
        fs: sample_rate_hz,
        delay: d,
        a,
        b,
    };
    Ok((m, model, rows))
}

/// Why no order could be chosen: the first candidate's instability, with what the record held
/// of the response (an unstable fit of a probe, a passive and stable system, most often saw
/// too little of it after the step); else the first order's error, or no usable order.
fn no_usable_order(
    p: &Prepared,
    estimation: &Test<'_>,
    candidates: &[OrderFit],
    first_error: Option<Error>,
) -> Error {
    if let Some(c) = candidates.first() {
        let after = p.y.len().saturating_sub(p.onset);
        if let Err(e) = c.model.check_stable(estimation.name) {
            return match e {
                Error::UnstableModel {
                    context,
                    pole,
                    radius,
                    ..
                } => Error::UnstableModel {
                    context,
                    pole,
                    radius,
                    note: format!(
                        "; the record ends {after} samples ({} s) after the step: a probe is \
                         stable, so an unstable fit most often means the record holds too little \
                         of its response; record until the probe has settled",
                        crate::error::number(after as f64 / c.model.fs)
                    ),
                },
                e => e,
            };
        }
    }
    first_error.unwrap_or_else(|| {
        FitError::NoUsableOrder {
            test: estimation.name.into(),
        }
        .into()
    })
}

/// Whether a held-out error went from `before` to `after` by a rise of more than
/// [`ERROR_RISE_NOTED`]: the change made the model worse on data it was not fitted to.
#[must_use]
pub fn error_rose(before: f64, after: f64) -> bool {
    after > before * (1.0 + ERROR_RISE_NOTED)
}

/// A held-out error that rises by more than this share has risen ([`error_rose`]): a refit of
/// the same model on the same data moves it by far less.
pub const ERROR_RISE_NOTED: f64 = 0.01;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_parallel_keeps_the_items_order() {
        let items: Vec<usize> = (0..37).collect();
        let out = in_parallel(&items, |&i| {
            // Uneven work, so that the threads finish out of order.
            let spin: u64 = (0..(37 - i) * 1000).map(|k| k as u64 % 7).sum();
            (i * i, spin)
        });
        assert_eq!(out.len(), items.len());
        for (i, (sq, _)) in out.iter().enumerate() {
            assert_eq!(*sq, i * i);
        }
        assert!(in_parallel(&[] as &[usize], |&i| i).is_empty());
    }
}
