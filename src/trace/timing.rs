//! A record's sample rate: given, or from its time column, which must increase uniformly
//! (within [`MAX_JITTER`]) at a plausible rate. The one check of the whole record's time that
//! [`Trace::read`](super::Trace::read) and the streamed first pass
//! ([`stream::scan`](super::stream::scan)) both make, from the same running figures.

use std::path::Path;

use super::rows::Layout;
use super::{
    time_unit, Columns, Result, TraceError, MAX_JITTER, MAX_SAMPLE_RATE_HZ, MIN_PLAUSIBLE_RATE_HZ,
};

/// The time column, as messages name it.
pub(super) struct TimeColumn {
    /// 1-based field position.
    pub(super) column: usize,
    /// Its name, quoted and cut ([`echo`](super::echo)).
    pub(super) name: String,
    /// Its unit's symbol.
    pub(super) unit: &'static str,
}

/// Whether a time step jitters by more than [`MAX_JITTER`] around the `nominal` step.
pub(super) fn jitters(step: f64, nominal: f64) -> bool {
    (step - nominal).abs() / nominal > MAX_JITTER
}

/// The running figures of a record's rows that its sample rate is checked from: how many rows,
/// the second's line, and the time column's first and last value, its extreme steps and the
/// first step that does not increase.
#[derive(Debug, Clone)]
pub(super) struct Steps {
    rows: usize,
    second_line: u64,
    first: Option<f64>,
    last: Option<f64>,
    min_step: f64,
    max_step: f64,
    /// Line, previous and value of the first time that does not increase.
    not_increasing: Option<(u64, f64, f64)>,
}

impl Default for Steps {
    fn default() -> Self {
        Self {
            rows: 0,
            second_line: 0,
            first: None,
            last: None,
            min_step: f64::INFINITY,
            max_step: f64::NEG_INFINITY,
            not_increasing: None,
        }
    }
}

impl Steps {
    /// One row: its time, when the time column is read, and its line.
    pub(super) fn push(&mut self, t: Option<f64>, line: u64) {
        if let Some(t) = t {
            if let Some(a) = self.last {
                if t <= a && self.not_increasing.is_none() {
                    self.not_increasing = Some((line, a, t));
                }
                let step = t - a;
                self.min_step = self.min_step.min(step);
                self.max_step = self.max_step.max(step);
            }
            self.first.get_or_insert(t);
            self.last = Some(t);
        }
        if self.rows == 1 {
            self.second_line = line;
        }
        self.rows += 1;
    }

    /// Rows seen.
    pub(super) fn rows(&self) -> usize {
        self.rows
    }

    /// Whether a step jitters around `nominal`: the extreme steps do.
    pub(super) fn any_jitters(&self, nominal: f64) -> bool {
        jitters(self.min_step, nominal) || jitters(self.max_step, nominal)
    }

    /// The record's sample rate, checked, once all its rows are pushed: an error when it has
    /// no rows; when the time column (with `layout` and `columns`) has one row, does not
    /// increase, jitters, or gives a rate too low for seconds (without a unit in its name);
    /// and when the rate is above [`MAX_SAMPLE_RATE_HZ`]. `first_jitter` gives the line and
    /// step of the first step that jitters around the nominal step it is given, or `None`
    /// when none does.
    ///
    /// # Errors
    /// [`TraceError::Empty`], [`TraceError::TooShort`], [`TraceError::TimeNotIncreasing`],
    /// [`TraceError::NonUniformTime`], [`TraceError::ImplausibleTime`],
    /// [`TraceError::NoSampleRate`], [`TraceError::Malformed`], and what `first_jitter` gives.
    pub(super) fn sample_rate(
        &self,
        path: &Path,
        columns: &Columns,
        layout: &Layout,
        first_jitter: impl FnOnce(f64) -> Result<Option<(u64, f64)>>,
    ) -> Result<f64> {
        let n = self.rows;
        if n == 0 {
            return Err(TraceError::Empty {
                path: path.to_path_buf(),
                line: 2,
                what: "a header and no data rows",
            });
        }
        let sample_rate_hz = match (columns.sample_rate_hz, layout.t_idx, self.first, self.last) {
            (Some(fs), _, _, _) => fs,
            (None, Some(ti), Some(first), Some(last)) => {
                let unit = time_unit(&columns.time);
                let (symbol, seconds) = unit.unwrap_or(("s", 1.0));
                let time = TimeColumn {
                    column: ti + 1,
                    name: layout.name_of(ti),
                    unit: symbol,
                };
                if n < 2 {
                    return Err(TraceError::TooShort {
                        path: path.to_path_buf(),
                        samples: n,
                    });
                }
                if let Some((line, previous, value)) = self.not_increasing {
                    return Err(TraceError::TimeNotIncreasing {
                        path: path.to_path_buf(),
                        line,
                        column: time.column,
                        name: time.name,
                        previous,
                        value,
                    });
                }
                let nominal = (last - first) / (n - 1) as f64;
                if let Some((line, step)) = first_jitter(nominal)? {
                    return Err(TraceError::NonUniformTime {
                        path: path.to_path_buf(),
                        line,
                        column: time.column,
                        name: time.name,
                        step,
                        nominal,
                        percent: (step - nominal).abs() / nominal * 100.0,
                        unit: time.unit,
                    });
                }
                let per_unit = 1.0 / nominal;
                let rate = per_unit / seconds;
                if unit.is_none() && rate < MIN_PLAUSIBLE_RATE_HZ {
                    return Err(TraceError::ImplausibleTime {
                        path: path.to_path_buf(),
                        line: self.second_line,
                        column: time.column,
                        name: time.name,
                        step: 1.0 / per_unit,
                        rate_hz: rate,
                        min: MIN_PLAUSIBLE_RATE_HZ,
                    });
                }
                rate
            }
            _ => {
                return Err(TraceError::NoSampleRate {
                    path: path.to_path_buf(),
                })
            }
        };
        if sample_rate_hz.is_nan() || sample_rate_hz > MAX_SAMPLE_RATE_HZ {
            return Err(TraceError::Malformed {
                path: path.to_path_buf(),
                line: 3,
                message: format!(
                    "the time column's step gives a sample rate of {sample_rate_hz:e} Hz, above \
                     the {:e} Hz a model may carry: is the time in seconds?",
                    MAX_SAMPLE_RATE_HZ
                ),
            });
        }
        Ok(sample_rate_hz)
    }
}
