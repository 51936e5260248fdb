//! `unlag predict`: a physical probe's exact first modes, front delay and lumped
//! approximation, printed or as JSON, and their comparison with a fitted model file.

use std::path::PathBuf;

use clap::Args;
use serde_json::{json, Value};

use super::physics::SystemArgs;
use crate::error::{Error, Result};
use crate::file::ModelFile;
use crate::physics::system::ProbeSystem;
use crate::physics::{
    check_mode_count, predict_and_compare, Comparison, PredictRequest, Predicted, Prediction,
};

/// Arguments of `unlag predict`.
#[derive(Debug, Args)]
pub struct PredictArgs {
    /// The probe.
    #[command(flatten)]
    pub system: SystemArgs,
    /// Number of exact modes to report.
    #[arg(long, default_value_t = 3, value_name = "N")]
    pub modes: usize,
    /// A fitted model file to compare with the prediction.
    #[arg(long, value_name = "MODEL.toml")]
    pub model: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The prediction as `unlag predict --json` prints it, with the comparison when a model was
/// given.
///
/// # Errors
/// [`Error::Serialise`] when the comparison cannot be written as JSON.
pub fn prediction_json(
    sys: &ProbeSystem,
    p: &Prediction,
    comparison: Option<&Comparison>,
) -> Result<Value> {
    let mut v = json!({
        "modes": p.modes.iter().map(|m| json!({
            "natural_frequency_hz": m.natural_frequency_hz,
            "damping": m.damping,
            "damped_frequency_hz": m.damped_frequency_hz(),
            "overdamped": m.overdamped,
        })).collect::<Vec<_>>(),
        "real_poles_rad_s": p.real_poles_rad_s,
        "real_poles_searched_to_rad_s": p.real_search_limit_rad_s,
        "delay_s": p.delay_s,
        "lumped": p.lumped.map(|l| json!({
            "natural_frequency_hz": l.natural_frequency_hz,
            "damping": l.damping,
            "womersley": l.womersley,
            "valid": l.womersley < crate::physics::compare::LUMPED_WOMERSLEY_LIMIT,
        })),
        "dc_gain": p.dc_gain,
        "gas": {
            "temperature_k": sys.gas.temperature_k,
            "pressure_pa": sys.gas.pressure_pa,
            "speed_of_sound_m_s": sys.gas.speed_of_sound(),
            "kinematic_viscosity_m2_s": sys.gas.kinematic_viscosity(),
        },
        "helmholtz": sys.hole.map(|h| json!({
            "frequency_hz": h.helmholtz_frequency_hz(&sys.gas),
            "poiseuille_damping": h.poiseuille_damping(&sys.gas),
            "effective_length_m": h.effective_length_m(),
            "neck_volume_ratio": h.neck_volume_ratio(),
        })),
        "diaphragm": sys.diaphragm.map(|d| json!({
            "natural_frequency_hz": d.natural_frequency_hz,
            "damping": d.damping,
        })),
        "minor_loss_resistance_pa_s_per_m3": sys.minor_loss_resistance,
    });
    if let Some(c) = comparison {
        v["comparison"] = serde_json::to_value(c).map_err(|e| Error::Serialise {
            what: "JSON output",
            message: e.to_string(),
        })?;
    }
    Ok(v)
}

/// Runs `unlag predict`.
///
/// # Errors
/// Invalid arguments, a mode search that finds nothing, an unreadable model file.
pub fn run_predict(args: &PredictArgs) -> Result<()> {
    // A wrong count is told before the probe is built or the model file read.
    check_mode_count(args.modes).map_err(Error::from)?;
    let sys = args.system.build()?;
    let file = args.model.as_deref().map(ModelFile::load).transpose()?;
    let Predicted {
        prediction: p,
        comparison,
    } = predict_and_compare(&PredictRequest {
        line: &sys.line,
        gas: &sys.gas,
        modes: args.modes,
        model: file.as_ref().map(|f| &f.model),
    })?;
    if args.json {
        crate::outln!("{}", prediction_json(&sys, &p, comparison.as_ref())?);
        return Ok(());
    }
    print_prediction(args, &sys, &p);
    if let Some(c) = &comparison {
        print_comparison(c);
    }
    Ok(())
}

/// The prediction as text: the gas, the exact modes and real poles, the front delay, the lumped approximation and the probe's parts.
fn print_prediction(args: &PredictArgs, sys: &ProbeSystem, p: &Prediction) {
    let g = &sys.gas;
    crate::outln!(
        "air at {:.2} K, {:.0} Pa: speed of sound {:.2} m/s, kinematic viscosity {:.4e} m^2/s",
        g.temperature_k,
        g.pressure_pa,
        g.speed_of_sound(),
        g.kinematic_viscosity()
    );
    crate::outln!("exact modes (Bergh-Tijdeman poles):");
    for (i, m) in p.modes.iter().enumerate() {
        crate::outln!(
            "  {}: natural frequency {:10.3} Hz, damping {:.4}{}",
            i + 1,
            m.natural_frequency_hz,
            m.damping,
            if m.overdamped {
                " (overdamped: equivalent pair of the two slowest real poles)"
            } else {
                ""
            }
        );
    }
    if !p.real_poles_rad_s.is_empty() {
        let text: Vec<String> = p
            .real_poles_rad_s
            .iter()
            .map(|s| format!("{s:.2} rad/s (time constant {:.1} ms)", -1e3 / s))
            .collect();
        crate::outln!("real poles (slow creeps): {}", text.join(", "));
    }
    crate::outln!(
        "  (real poles searched from 0 to {:.1} rad/s; one beyond is not found)",
        p.real_search_limit_rad_s
    );
    crate::outln!("front delay sum(L)/a: {:.6} s", p.delay_s);
    match &p.lumped {
        Some(l) => crate::outln!(
            "lumped approximation: natural frequency {:.3} Hz, damping {:.4}, Womersley {:.2} ({})",
            l.natural_frequency_hz,
            l.damping,
            l.womersley,
            if p.lumped_valid() {
                "within its validity, Wo < 2"
            } else {
                "outside its validity, Wo >= 2: it under-predicts damping"
            }
        ),
        None => crate::outln!("lumped approximation: none (no second-order dynamics)"),
    }
    crate::outln!("DC gain {:.6}", p.dc_gain);
    if let Some(h) = &sys.hole {
        crate::outln!(
            "hole-cavity closed form: Helmholtz {:.1} Hz, Poiseuille damping {:.4}, L_eff {:.4e} m, neck/cavity volume {:.2}{}",
            h.helmholtz_frequency_hz(g),
            h.poiseuille_damping(g),
            h.effective_length_m(),
            h.neck_volume_ratio(),
            if h.neck_too_large_for_closed_form() {
                " (too large for the closed form: trust the exact modes)"
            } else {
                ""
            }
        );
    }
    if let Some(d) = &sys.diaphragm {
        crate::outln!(
            "diaphragm: natural frequency {:.1} Hz, damping {:.4}",
            d.natural_frequency_hz,
            d.damping
        );
    }
    if let Some(r) = sys.minor_loss_resistance {
        crate::outln!(
            "minor losses linearised for {} Pa: R_eq = {r:.4e} Pa s/m^3 (included above)",
            args.system.amplitude
        );
    }
}

/// The fitted model against the prediction: the ratios and differences, and what disagrees.
fn print_comparison(c: &Comparison) {
    crate::outln!(
        "fitted model against the prediction: natural frequency ratio {:.4} ({:.3} / {:.3} Hz), damping ratio {:.4} ({:.4} / {:.4}), delay difference {:+.6} s ({:.6} - {:.6} s), DC gain ratio {:.5}",
        c.natural_frequency_ratio,
        c.fitted.natural_frequency_hz,
        c.predicted.natural_frequency_hz,
        c.damping_ratio,
        c.fitted.damping,
        c.predicted.damping,
        c.delay_difference_s,
        c.fitted_delay_s,
        c.predicted_delay_s,
        c.dc_gain_ratio
    );
    if c.findings.is_empty() {
        crate::outln!("  agrees within 5 % in frequency, 15 % in damping, one sample in delay");
    }
    for f in &c.findings {
        crate::outln!("  {f}");
    }
}
