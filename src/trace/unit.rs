//! The units a trace's columns are in, read from their names (time: `t_ms`; pressure:
//! `p_kPa`, `u [Pa]`), and the one rounding policy for values printed for a person to read.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// The unit a column's name ends with: the text in its last brackets (`t[ms]`, `p (kPa)`) or
/// after its last `_`, space, `-`, `/` or `.` (`t_ms`, `p_kPa`).
fn token(name: &str) -> Option<&str> {
    let name = name.trim();
    let bracketed = |open: char, close: char| {
        name.strip_suffix(close)
            .and_then(|s| s.rsplit_once(open))
            .map(|(_, unit)| unit)
    };
    bracketed('[', ']')
        .or_else(|| bracketed('(', ')'))
        .or_else(|| {
            name.rsplit_once(['_', ' ', '-', '/', '.'])
                .map(|(_, unit)| unit)
        })
        .map(str::trim)
}

/// A time column's unit, from its name (`t_ms`, `time_us`, `t[ms]`, `t (µs)`, `time_s`): its
/// symbol and its length in seconds; `None` when the name carries no unit.
#[must_use]
pub fn time_unit(name: &str) -> Option<(&'static str, f64)> {
    match token(name)?.to_lowercase().as_str() {
        "s" | "sec" | "secs" | "seconds" => Some(("s", 1.0)),
        "ms" | "msec" => Some(("ms", 1e-3)),
        "us" | "µs" | "μs" | "usec" => Some(("µs", 1e-6)),
        "ns" | "nsec" => Some(("ns", 1e-9)),
        _ => None,
    }
}

/// The unit a trace's pressures are in: the reference's and the probe's (they are calibrated
/// alike), the ADC's range and every pressure the CLI prints. Only for reading: the
/// computation is the same in any unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PressureUnit {
    /// Pascal.
    Pa,
    /// Hectopascal.
    #[serde(rename = "hPa")]
    HPa,
    /// Kilopascal.
    #[serde(rename = "kPa")]
    KPa,
    /// Megapascal.
    MPa,
    /// Millibar.
    #[serde(rename = "mbar")]
    Mbar,
    /// Bar.
    #[serde(rename = "bar")]
    Bar,
    /// Pound-force per square inch.
    #[serde(rename = "psi")]
    Psi,
    /// Millimetre of mercury (torr).
    #[serde(rename = "mmHg")]
    MmHg,
    /// Volt: a transducer's output not yet calibrated into a pressure.
    V,
    /// Millivolt.
    #[serde(rename = "mV")]
    MV,
}

impl PressureUnit {
    /// Every unit, in the order `--help` lists them.
    pub const ALL: [Self; 10] = [
        Self::Pa,
        Self::HPa,
        Self::KPa,
        Self::MPa,
        Self::Mbar,
        Self::Bar,
        Self::Psi,
        Self::MmHg,
        Self::V,
        Self::MV,
    ];

    /// Its symbol, as the file and the command line spell it.
    #[must_use]
    pub fn symbol(self) -> &'static str {
        match self {
            Self::Pa => "Pa",
            Self::HPa => "hPa",
            Self::KPa => "kPa",
            Self::MPa => "MPa",
            Self::Mbar => "mbar",
            Self::Bar => "bar",
            Self::Psi => "psi",
            Self::MmHg => "mmHg",
            Self::V => "V",
            Self::MV => "mV",
        }
    }

    /// A value in this unit as the SI unit it is a decimal multiple of and that multiple
    /// (`2.5 kPa` is `2500 Pa`), so that it can be printed with the prefix that suits it;
    /// `None` for a unit that is no decimal multiple of an SI unit (psi, mmHg, bar: printed
    /// as they are).
    #[must_use]
    pub fn si(self) -> Option<(&'static str, f64)> {
        match self {
            Self::Pa => Some(("Pa", 1.0)),
            Self::HPa => Some(("Pa", 1e2)),
            Self::KPa => Some(("Pa", 1e3)),
            Self::MPa => Some(("Pa", 1e6)),
            Self::V => Some(("V", 1.0)),
            Self::MV => Some(("V", 1e-3)),
            Self::Mbar | Self::Bar | Self::Psi | Self::MmHg => None,
        }
    }

    /// The unit a column's name ends with (`p_kPa`, `u [Pa]`, `y (psi)`); `None` when it
    /// names none.
    #[must_use]
    pub fn of_column(name: &str) -> Option<Self> {
        token(name)?.parse().ok()
    }
}

impl fmt::Display for PressureUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.symbol())
    }
}

impl FromStr for PressureUnit {
    type Err = String;

    /// The symbol, as [`PressureUnit::symbol`] spells it (`torr` for mmHg; case matters only
    /// where it tells units apart: `mPa` is not `MPa`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let text = text.trim();
        if let Some(u) = Self::ALL.iter().find(|u| u.symbol() == text) {
            return Ok(*u);
        }
        match text.to_lowercase().as_str() {
            "pa" => Ok(Self::Pa),
            "hpa" => Ok(Self::HPa),
            "kpa" => Ok(Self::KPa),
            "mbar" => Ok(Self::Mbar),
            "bar" => Ok(Self::Bar),
            "psi" => Ok(Self::Psi),
            "mmhg" | "torr" => Ok(Self::MmHg),
            "v" => Ok(Self::V),
            _ => Err(format!(
                "'{}' is not a pressure unit unlag knows ({})",
                text.chars()
                    .take(super::ECHO_CHARS)
                    .collect::<String>()
                    .escape_debug(),
                Self::ALL.map(Self::symbol).join(", ")
            )),
        }
    }
}

/// The one rounding policy of what the CLI prints for a person: four significant digits,
/// trailing zeros dropped (`6562`, `0.3203`, `1.373e-9`), in scientific notation below 1e-3
/// and from 1e6 on. The CLI's `--json` keeps every value in full.
#[must_use]
pub fn significant(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        return "0".into();
    }
    if !a.is_finite() {
        return if v.is_nan() {
            "NaN".into()
        } else {
            format!("{v}")
        };
    }
    if !(1e-3..1e6).contains(&a) {
        let text = format!("{v:.3e}");
        return match text.split_once('e') {
            Some((m, e)) => format!("{}e{e}", trim(m)),
            None => text,
        };
    }
    // Decimals that leave four significant digits (rounding may carry to one more digit:
    // 9999.5 prints 10000).
    let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
    trim(&format!("{v:.decimals$}")).to_string()
}

/// `text` without the zeros after its decimal point's last significant digit.
fn trim(text: &str) -> &str {
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.')
    } else {
        text
    }
}

/// A quantity of an SI unit (`symbol`) with the prefix that suits it, four significant digits
/// ([`significant`]): `1.328 MHz`, `112 Hz`, `6.562 kPa`, `850 mPa`.
#[must_use]
pub fn si(v: f64, symbol: &str) -> String {
    let a = v.abs();
    let (scale, prefix) = match a {
        a if a == 0.0 || !a.is_finite() => (1.0, ""),
        a if a >= 1e9 => (1e-9, "G"),
        a if a >= 1e6 => (1e-6, "M"),
        a if a >= 1e3 => (1e-3, "k"),
        a if a >= 1.0 => (1.0, ""),
        a if a >= 1e-3 => (1e3, "m"),
        a if a >= 1e-6 => (1e6, "µ"),
        _ => (1e9, "n"),
    };
    format!("{} {prefix}{symbol}", significant(v * scale))
}

/// A pressure (or a transducer's voltage) in the traces' `unit`, for a person to read: a
/// decimal multiple of Pa or V with the prefix that suits it (`6.562 kPa`), another unit as it
/// is (`14.7 psi`), four significant digits; without a unit, the number alone.
#[must_use]
pub fn pressure(v: f64, unit: Option<PressureUnit>) -> String {
    match unit {
        None => significant(v),
        Some(u) => match u.si() {
            Some((symbol, multiple)) => si(v * multiple, symbol),
            None => format!("{} {u}", significant(v)),
        },
    }
}

/// A frequency for a person to read ([`si`] of Hz).
#[must_use]
pub fn hz(v: f64) -> String {
    si(v, "Hz")
}

/// A time for a person to read: four significant digits in the unit that suits it (`2.1 ms`,
/// `37.5 µs`, `1.25 s`), not `0.002100000 s`; never above seconds.
#[must_use]
pub fn duration(seconds: f64) -> String {
    if seconds.abs() >= 1.0 {
        return format!("{} s", significant(seconds));
    }
    si(seconds, "s")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_are_read_from_column_names() {
        for (name, unit) in [
            ("p_kPa", Some(PressureUnit::KPa)),
            ("u [Pa]", Some(PressureUnit::Pa)),
            ("y (psi)", Some(PressureUnit::Psi)),
            ("p_MPa", Some(PressureUnit::MPa)),
            ("probe_mV", Some(PressureUnit::MV)),
            ("u_torr", Some(PressureUnit::MmHg)),
            ("u", None),
            ("probe_mpa", None),
            ("probe_signal", None),
        ] {
            assert_eq!(PressureUnit::of_column(name), unit, "{name}");
        }
        assert_eq!(time_unit("t_ms"), Some(("ms", 1e-3)));
        assert_eq!(time_unit("u_kPa"), None);
    }

    #[test]
    fn every_unit_reads_back_from_its_symbol_and_its_file_name() {
        for u in PressureUnit::ALL {
            assert_eq!(u.symbol().parse::<PressureUnit>(), Ok(u));
            let toml = toml::to_string(&std::collections::BTreeMap::from([("unit", u)])).unwrap();
            assert_eq!(toml.trim(), format!("unit = \"{}\"", u.symbol()));
        }
        let e = "furlong".parse::<PressureUnit>().unwrap_err();
        assert!(e.contains("'furlong'") && e.contains("kPa, MPa"), "{e}");
    }
}
