//! Pass 7: solver settings and outputs. Resolves the integrator, the Baumgarte parameters, the
//! time span (from `end_time` or from `periods` of the drives' common period) and the divergence
//! guards; then what to record; then the effects the model simulates.

use super::ctx::{Ctx, positive};
use crate::clearance::Geometry;
use crate::error::Result;
use crate::model::{
    Bits, Body, Drive, Effects, Joint, Model, Outputs, ROUNDED_QUANTITIES, Settings,
};
use crate::ode::Accuracy;
use crate::scene::{OutputSpec, SignificantBits, SolverSpec};

/// The `[solver]` settings of a scene with these drives.
pub(crate) fn settings(sv: &SolverSpec, drives: &[Drive], cx: &Ctx) -> Result<Settings> {
    // A fixed-step method needs its step; the adaptive ones share their settings and checks.
    let max_step = sv.max_step.unwrap_or(f64::INFINITY);
    let method = sv.integrator.method(sv.step, sv.rtol, sv.atol, max_step);
    match method.accuracy() {
        Accuracy::Fixed { step } => {
            if step <= 0.0 {
                return Err(cx.err("solver.step", format!("must be positive, got {step} s")));
            }
        }
        Accuracy::Adaptive {
            rtol,
            atol,
            max_step,
        } => {
            if rtol <= 0.0 {
                return Err(cx.err("solver.rtol", "must be positive"));
            }
            if atol <= 0.0 {
                return Err(cx.err("solver.atol", "must be positive"));
            }
            if max_step <= 0.0 {
                return Err(cx.err("solver.max_step", "must be positive"));
            }
        }
    }
    if sv.baumgarte_alpha < 0.0 {
        return Err(cx.err("solver.baumgarte_alpha", "must not be negative"));
    }
    if sv.baumgarte_beta < 0.0 {
        return Err(cx.err("solver.baumgarte_beta", "must not be negative"));
    }
    let period = period(drives, cx)?;
    let end_time = end_time(sv, period, cx)?;
    // A step so small that the run could never finish is a mistake, not a setting.
    let span = end_time - sv.start_time;
    let (step_field, step) = match method.accuracy() {
        Accuracy::Fixed { step } => ("solver.step", step),
        Accuracy::Adaptive { max_step, .. } => ("solver.max_step", max_step),
    };
    if span / step > 1e12 {
        return Err(cx.err(
            step_field,
            format!(
                "{step:e} s over a span of {span} s means at least {:.3e} steps; at most 1e12 are allowed",
                span / step
            ),
        ));
    }
    let max_penetration = match sv.max_penetration {
        None => None,
        Some(v) => Some(positive(Some(v), "solver.max_penetration".into(), "", cx)?),
    };
    let max_drift = match sv.max_constraint_drift {
        None => 0.1,
        Some(v) => positive(Some(v), "solver.max_constraint_drift".into(), "", cx)?,
    };
    Ok(Settings {
        method,
        alpha: sv.baumgarte_alpha,
        beta: sv.baumgarte_beta,
        start_time: sv.start_time,
        end_time,
        period,
        max_penetration,
        max_drift,
        onset_events: sv.onset_events,
        end_events: sv.end_events,
        friction_events: sv.friction_events,
    })
}

/// The period the periodic drives share, if any; periods that differ are an error.
fn period(drives: &[Drive], cx: &Ctx) -> Result<Option<f64>> {
    let mut period = None;
    for (i, d) in drives.iter().enumerate() {
        if let Some(p) = d.period() {
            match period {
                None => period = Some(p),
                Some(q) if ((p - q) / q).abs() > 1e-9 => {
                    return Err(cx.err(
                        format!("drives[{i}].profile"),
                        format!("period {p} s differs from the other drives' period {q} s"),
                    ));
                }
                _ => {}
            }
        }
    }
    Ok(period)
}

/// The end time: `end_time`, or `periods` drive periods after the start.
fn end_time(sv: &SolverSpec, period: Option<f64>, cx: &Ctx) -> Result<f64> {
    let end_time = match (sv.end_time, sv.periods) {
        (Some(_), Some(_)) => {
            return Err(cx.err("solver.periods", "give end_time or periods, not both"));
        }
        (Some(t), None) => t,
        (None, Some(n)) => {
            let Some(p) = period else {
                return Err(cx.err(
                    "solver.periods",
                    "no drive has a period; give end_time instead",
                ));
            };
            if n <= 0.0 {
                return Err(cx.err("solver.periods", "must be positive"));
            }
            sv.start_time + n * p
        }
        (None, None) => {
            return Err(cx.err("solver.end_time", "give end_time or periods"));
        }
    };
    if end_time <= sv.start_time {
        return Err(cx.err(
            "solver.end_time",
            format!("must be after start_time = {} s", sv.start_time),
        ));
    }
    Ok(end_time)
}

/// The `[output]` selection, resolved to indices into the compiled lists.
pub(crate) fn outputs(
    out: &OutputSpec,
    settings: &Settings,
    bodies: &[Body],
    joints: &[Joint],
    drives: &[Drive],
    cx: &Ctx,
) -> Result<Outputs> {
    let span = settings.end_time - settings.start_time;
    let interval = out.interval.unwrap_or(span / 1000.0);
    if interval <= 0.0 {
        return Err(cx.err("output.interval", "must be positive"));
    }
    // Each sample holds O(100) numbers per body; beyond 1e8 samples the recording cannot fit
    // in memory, so refuse early instead of failing an allocation mid-run.
    let n_samples = span / interval;
    if n_samples > 1e8 {
        return Err(cx.err(
            "output.interval",
            format!("{interval} s over a span of {span} s gives {n_samples:.3e} samples; at most 1e8 are recorded"),
        ));
    }
    let bits = significant_bits(cx, out.significant_bits.as_ref())?;
    let pick = |sel: &Option<Vec<String>>, field: &str, all: &[&str]| -> Result<Vec<usize>> {
        match sel {
            None => Ok((0..all.len()).collect()),
            Some(v) => v
                .iter()
                .enumerate()
                .map(|(k, n)| {
                    all.iter().position(|x| x == n).ok_or_else(|| {
                        cx.err(
                            format!("output.{field}[{k}]"),
                            format!("unknown name '{n}'"),
                        )
                    })
                })
                .collect(),
        }
    };
    let bnames: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
    let jnames: Vec<&str> = joints.iter().map(|b| b.name.as_str()).collect();
    let dnames: Vec<&str> = drives.iter().map(|b| b.name.as_str()).collect();
    Ok(Outputs {
        interval,
        bodies: pick(&out.bodies, "bodies", &bnames)?,
        joints: pick(&out.joints, "joints", &jnames)?,
        drives: pick(&out.drives, "drives", &dnames)?,
        accelerations: out.accelerations,
        diagnostics: out.diagnostics,
        energy: out.diagnostics && out.energy,
        significant_bits: bits,
    })
}

/// `output.significant_bits` checked: every count between 1 and 52, every quantity one of
/// [`ROUNDED_QUANTITIES`]. 52 bits keep every bit: nothing is rounded or marked.
fn significant_bits(cx: &Ctx<'_>, spec: Option<&SignificantBits>) -> Result<Bits> {
    let count = |field: String, b: i64| -> Result<Option<u32>> {
        match u32::try_from(b) {
            Ok(b @ 1..=52) => Ok(Some(b).filter(|&b| b < 52)),
            _ => Err(cx.err(
                field,
                format!("{b} is not between 1 and 52 (the mantissa bits of a double)"),
            )),
        }
    };
    let field = "output.significant_bits";
    match spec {
        None => Ok(Bits::default()),
        Some(SignificantBits::All(b)) => Ok(Bits {
            default: count(field.into(), *b)?,
            by_quantity: Vec::new(),
        }),
        Some(SignificantBits::ByQuantity(by)) => {
            let mut bits = Bits::default();
            for (q, &b) in by {
                let n = count(format!("{field}.{q}"), b)?;
                if q == "default" {
                    bits.default = n;
                } else if ROUNDED_QUANTITIES.contains(&q.as_str()) {
                    bits.by_quantity.push((q.clone(), n));
                } else {
                    let why = match q.as_str() {
                        "contact_state" | "time" | "final_state" => {
                            " (flags, sample times and the final state are never rounded)"
                        }
                        _ => "",
                    };
                    return Err(cx.err(
                        format!("{field}.{q}"),
                        format!(
                            "'{q}' is not a recorded quantity{why}; one of default, {}",
                            ROUNDED_QUANTITIES.join(", ")
                        ),
                    ));
                }
            }
            Ok(bits)
        }
    }
}

/// The effects the compiled model `m` simulates; the right-hand side skips the others.
pub(crate) fn effects(m: &Model) -> Effects {
    Effects {
        gravity: m.gravity.is_some_and(|g| g.norm() > 0.0),
        springs: !m.springs.is_empty(),
        loads: !m.loads.is_empty(),
        constraints: m.n_rows > 0,
        drives: !m.drives.is_empty(),
        clearance: !m.clearances.is_empty(),
        friction: m.clearances.iter().any(|c| !c.friction.is_none()),
        axial_contact: m.clearances.iter().any(|c| {
            matches!(
                c.geometry,
                Geometry::Revolute {
                    journal_length: Some(_),
                    ..
                }
            )
        }),
        lubrication: m.clearances.iter().any(|c| c.film.is_some()),
    }
}
