//! How a fit chose its model order: the rule and its numbers, and the words that name them.
//!
//! [`OrderSelection`] is stored in the fit's report ([`crate::fit::model::FitReport`]) and
//! written as its words, in the model file and in JSON alike; reading takes the same words
//! back:
//!
//! - `fixed`: the order was given;
//! - `auto 1..=MAX: smallest order within 5 % of the best mean held-out nrmse`;
//! - `auto 1..=MAX: lowest BIC on the estimation test`;
//! - `auto 1..=MAX: RULE on the first N samples from just before the step, the chosen order
//!   refined on the whole record` (a long record), `RULE` being `smallest order within 5 % of
//!   the best mean held-out nrmse` or `lowest BIC`.

use serde::{Deserialize, Serialize};

use super::arx::Data;
use super::model::{DelayRow, Method, Model};
use super::{nrmse, oe, prediction_loss, FitError, Order, Test, SELECTION_WINDOW};
use crate::error::Result;

/// What an automatic order choice compared the orders by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrderRule {
    /// The smallest order whose mean held-out nrmse is within 5 % of the best.
    HeldOut,
    /// The lowest Bayesian information criterion on the estimation test.
    Bic,
}

impl OrderRule {
    /// Both rules.
    pub const ALL: [Self; 2] = [Self::HeldOut, Self::Bic];

    /// The rule's words, as they stand before a window's (`lowest BIC`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::HeldOut => "smallest order within 5 % of the best mean held-out nrmse",
            Self::Bic => "lowest BIC",
        }
    }

    /// The rule's words when the orders were compared on the whole record (`lowest BIC on the
    /// estimation test`).
    #[must_use]
    pub const fn whole(self) -> &'static str {
        match self {
            Self::HeldOut => "smallest order within 5 % of the best mean held-out nrmse",
            Self::Bic => "lowest BIC on the estimation test",
        }
    }
}

/// How the order was chosen.
///
/// ```
/// use unlag::fit::{OrderRule, OrderSelection};
///
/// let s = OrderSelection::Auto { max: 6, rule: OrderRule::Bic, window: None };
/// assert_eq!(s.to_string(), "auto 1..=6: lowest BIC on the estimation test");
/// assert_eq!(s.to_string().parse::<OrderSelection>(), Ok(s));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrderSelection {
    /// The order was given.
    Fixed,
    /// Orders `1..=max` were tried and one chosen by `rule`.
    Auto {
        /// The largest order tried.
        max: usize,
        /// What the orders were compared by.
        rule: OrderRule,
        /// On a long record: the orders were compared on this many samples from just before
        /// the step, and the chosen one refined on the whole record.
        window: Option<usize>,
    },
}

impl OrderSelection {
    /// The rule an automatic choice used; `None` for a given order.
    #[must_use]
    pub const fn rule(self) -> Option<OrderRule> {
        match self {
            Self::Fixed => None,
            Self::Auto { rule, .. } => Some(rule),
        }
    }
}

/// Words that name no order selection: what reading an `order_selection` fails with.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown order selection '{0}'")]
pub struct UnknownOrderSelection(pub String);

/// What starts an automatic choice's words, before the largest order.
const AUTO: &str = "auto 1..=";

/// What stands between the rule and a window's length.
const ON_THE_FIRST: &str = " on the first ";

/// What follows a window's length.
const WINDOW_TAIL: &str =
    " samples from just before the step, the chosen order refined on the whole record";

impl core::fmt::Display for OrderSelection {
    /// Its words, padded as the formatter asks.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let text = match *self {
            Self::Fixed => "fixed".to_string(),
            Self::Auto {
                max,
                rule,
                window: Some(n),
            } => format!("{AUTO}{max}: {}{ON_THE_FIRST}{n}{WINDOW_TAIL}", rule.name()),
            Self::Auto {
                max,
                rule,
                window: None,
            } => format!("{AUTO}{max}: {}", rule.whole()),
        };
        f.pad(&text)
    }
}

impl core::str::FromStr for OrderSelection {
    type Err = UnknownOrderSelection;

    /// Reads the words [`OrderSelection`]'s `Display` writes.
    fn from_str(s: &str) -> core::result::Result<Self, Self::Err> {
        let unknown = || UnknownOrderSelection(s.to_string());
        if s == "fixed" {
            return Ok(Self::Fixed);
        }
        let (max, rest) = s
            .strip_prefix(AUTO)
            .and_then(|r| r.split_once(": "))
            .ok_or_else(unknown)?;
        let max: usize = max.parse().map_err(|_| unknown())?;
        if let Some(rule) = OrderRule::ALL.into_iter().find(|r| r.whole() == rest) {
            return Ok(Self::Auto {
                max,
                rule,
                window: None,
            });
        }
        let (rule, n) = rest
            .strip_suffix(WINDOW_TAIL)
            .and_then(|r| r.rsplit_once(ON_THE_FIRST))
            .ok_or_else(unknown)?;
        let rule = OrderRule::ALL
            .into_iter()
            .find(|r| r.name() == rule)
            .ok_or_else(unknown)?;
        let n: usize = n.parse().map_err(|_| unknown())?;
        Ok(Self::Auto {
            max,
            rule,
            window: Some(n),
        })
    }
}

impl Serialize for OrderSelection {
    fn serialize<S: serde::Serializer>(&self, s: S) -> core::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for OrderSelection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> core::result::Result<Self, D::Error> {
        let s = std::borrow::Cow::<'de, str>::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// Parsimony: the smallest usable order whose held-out error is within 5 % of the best
/// (`best_crit`); with BIC, whose criterion already penalises parameters, the best.
pub(super) fn choose<'a>(
    usable: &[&'a OrderFit],
    best_crit: f64,
    held_out: bool,
    name: &str,
) -> Result<&'a OrderFit> {
    usable
        .iter()
        .find(|c| {
            if held_out {
                c.criterion <= best_crit * 1.05
            } else {
                c.criterion <= best_crit
            }
        })
        .copied()
        .ok_or_else(|| FitError::OrderSelectionFailed { test: name.into() }.into())
}

/// How the order was chosen, for the report.
pub(super) fn order_selection(order: Order, held_out: bool, windowed: bool) -> OrderSelection {
    match order {
        Order::Fixed(_) => OrderSelection::Fixed,
        Order::Auto { max } => OrderSelection::Auto {
            max,
            rule: if held_out {
                OrderRule::HeldOut
            } else {
                OrderRule::Bic
            },
            window: windowed.then_some(SELECTION_WINDOW),
        },
    }
}

/// One order's fit, judged: its errors on the whole records and its selection criterion.
#[derive(Debug, Clone)]
pub(super) struct OrderFit {
    pub(super) order: usize,
    pub(super) model: Model,
    pub(super) rows: Vec<DelayRow>,
    pub(super) est: f64,
    pub(super) val: Vec<f64>,
    pub(super) criterion: f64,
    pub(super) stable: bool,
}

/// Order `m`'s fit judged on the whole records, one order at a time (the threads of the
/// search only touch the window, so they add little memory): its errors, stability and
/// criterion, the mean held-out error, or without held-out tests BIC on the simulation
/// residual (with a noise model, Box-Jenkins, on the one-step-ahead prediction error, the
/// noise model's parameters counted).
pub(super) fn judge_order(
    m: usize,
    model: Model,
    rows: Vec<DelayRow>,
    data: &[Data<'_>; 1],
    estimation: &Test<'_>,
    validation: &[Test<'_>],
    method: Method,
) -> OrderFit {
    let stable = model.check_stable("fit").is_ok();
    let est = nrmse(&model, estimation.u, estimation.y);
    let val: Vec<f64> = validation.iter().map(|t| nrmse(&model, t.u, t.y)).collect();
    let criterion = if val.is_empty() {
        let n = data[0].y.len() as f64;
        let (rss, extra) = if method == Method::Bj {
            prediction_loss(data, &model)
        } else {
            (oe::loss(data, (&model.a, &model.b), model.delay), 0)
        };
        n * (rss.max(1e-300) / n).ln() + (2 * m + 2 + extra) as f64 * n.ln()
    } else {
        val.iter().sum::<f64>() / val.len() as f64
    };
    OrderFit {
        order: m,
        model,
        rows,
        est,
        val,
        criterion,
        stable,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every selection with the words the fit wrote for it as a string.
    fn cases() -> Vec<(OrderSelection, &'static str)> {
        let auto = |max, rule, window| OrderSelection::Auto { max, rule, window };
        vec![
            (OrderSelection::Fixed, "fixed"),
            (
                auto(6, OrderRule::HeldOut, None),
                "auto 1..=6: smallest order within 5 % of the best mean held-out nrmse",
            ),
            (
                auto(4, OrderRule::Bic, None),
                "auto 1..=4: lowest BIC on the estimation test",
            ),
            (
                auto(6, OrderRule::HeldOut, Some(50_000)),
                "auto 1..=6: smallest order within 5 % of the best mean held-out nrmse on the \
                 first 50000 samples from just before the step, the chosen order refined on the \
                 whole record",
            ),
            (
                auto(12, OrderRule::Bic, Some(50_000)),
                "auto 1..=12: lowest BIC on the first 50000 samples from just before the step, \
                 the chosen order refined on the whole record",
            ),
        ]
    }

    #[test]
    fn the_words_are_the_fits_and_read_back() {
        for (s, text) in cases() {
            assert_eq!(s.to_string(), text);
            assert_eq!(text.parse::<OrderSelection>(), Ok(s), "{text}");
        }
    }

    #[test]
    fn serde_gives_and_takes_the_words() {
        #[derive(Serialize, Deserialize, PartialEq, Debug)]
        struct Row {
            order_selection: OrderSelection,
        }
        for (s, text) in cases() {
            let json = serde_json::to_string(&s).unwrap();
            assert_eq!(json, serde_json::to_string(text).unwrap());
            assert_eq!(serde_json::from_str::<OrderSelection>(&json).unwrap(), s);
            let row = Row { order_selection: s };
            let toml_text = toml::to_string(&row).unwrap();
            assert_eq!(toml_text, format!("order_selection = \"{text}\"\n"));
            assert_eq!(toml::from_str::<Row>(&toml_text).unwrap(), row);
        }
    }

    #[test]
    fn other_words_are_refused() {
        for text in [
            "",
            "auto",
            "auto 1..=x: lowest BIC",
            "auto 1..=6: lowest BIC",
            "auto 1..=6: lowest AIC on the estimation test",
            "auto 1..=6: lowest BIC on the first many samples from just before the step, the \
             chosen order refined on the whole record",
            "given",
        ] {
            assert_eq!(
                text.parse::<OrderSelection>(),
                Err(UnknownOrderSelection(text.to_string()))
            );
        }
    }

    #[test]
    fn only_an_automatic_choice_has_a_rule() {
        assert_eq!(OrderSelection::Fixed.rule(), None);
        for (s, _) in cases().into_iter().skip(1) {
            assert!(s.rule().is_some());
        }
    }
}
