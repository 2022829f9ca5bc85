//! Writing a scenario file: an updated twin ([`crate::twin::learn`]) as TOML, through the
//! serializer, so what is written is what [`Scenario::parse`] reads.
//!
//! The old file's keys are kept (description, seed, measurement settings and its `[[effects]]`
//! tables as written, so effects drawn from the seed draw the same); the rig path is made
//! relative to the new file; `[geometric]` becomes explicit values of every non-zero parameter
//! (mm, degrees) — a random draw would not reproduce a fitted geometry; new effects are appended.
//! What the serializer cannot carry (comments: a flagged discrepancy) is appended as text.

use super::scenario::{Scenario, ScenarioError};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;
use std::path::{Component, Path, PathBuf};

/// A term of an updated scenario, as the world writes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum EffectKind {
    /// Lost motion of a joint (0-based); coefficient b (rad or mm).
    Backlash(usize),
    /// Harmonic `order` of a joint's cyclic error; coefficients A cos φ, A sin φ (rad).
    Transmission(usize, u32),
    /// Gravity compliance of a joint with the rig's link masses; coefficient rad/(N·m).
    Compliance(usize),
    /// Warm-up drift of a joint; coefficient A (rad or mm).
    DriftJoint(usize),
    /// Warm-up drift of the tip along an axis; coefficient A (mm).
    DriftAxis(usize),
}

/// An effect to append: its `[[effects]]` table and a one-line summary.
#[derive(Debug, Clone, PartialEq)]
pub struct NewEffect {
    /// The table, `kind` first.
    pub table: toml::Table,
    /// "lost_motion_deg = 0.04980".
    pub summary: String,
}

/// A TOML float rounded to seven significant digits.
pub(crate) fn float(v: f64) -> toml::Value {
    // Seven significant digits: well under the noise, and readable.
    let rounded: f64 = format!("{v:.7e}").parse().unwrap_or(v);
    toml::Value::Float(rounded)
}

impl NewEffect {
    /// The effect of `kind` with fitted coefficients `c` (internal units) and, for a drift,
    /// time constant `tau_s`; an error says why it cannot be written (a negative lost motion
    /// or compliance is not that physics).
    pub fn of(rig: &Rig, kind: EffectKind, c: &[f64], tau_s: f64) -> Result<NewEffect, String> {
        let joints = rig.chain.joints();
        let mut t = toml::Table::new();
        let file = |j: usize, v: f64| joints.get(j).map_or(v, |s| s.kind.to_file_units(v));
        let summary = match kind {
            EffectKind::Backlash(j) => {
                let b = file(j, c[0]);
                if b < 0.0 {
                    return Err(format!(
                        "the fitted lost motion is negative ({b:.5}): the joint overshoots, which backlash is not"
                    ));
                }
                t.insert("kind".into(), "backlash".into());
                t.insert("joint".into(), toml::Value::Integer(j as i64 + 1));
                t.insert("lost_motion_deg".into(), float(b));
                format!("lost_motion_deg = {b:.5}")
            }
            EffectKind::Transmission(j, order) => {
                let a = c[0].hypot(c[1]).to_degrees();
                let phase = c[1].atan2(c[0]).to_degrees();
                let mut h = toml::Table::new();
                h.insert("order".into(), toml::Value::Integer(i64::from(order)));
                h.insert("amplitude_deg".into(), float(a));
                h.insert("phase_deg".into(), float(phase));
                t.insert("kind".into(), "transmission_error".into());
                t.insert("joint".into(), toml::Value::Integer(j as i64 + 1));
                t.insert(
                    "harmonics".into(),
                    toml::Value::Array(vec![toml::Value::Table(h)]),
                );
                format!("order {order}, amplitude_deg = {a:.5}, phase_deg = {phase:.1}")
            }
            EffectKind::Compliance(j) => {
                let per_nm = c[0].to_degrees();
                if per_nm <= 0.0 {
                    return Err(format!(
                        "the fitted compliance is not positive ({per_nm:.6} deg/(N·m))"
                    ));
                }
                let masses: Vec<toml::Value> = rig
                    .link_masses
                    .iter()
                    .enumerate()
                    .filter_map(|(k, m)| {
                        let m = (*m)?;
                        (m.kg > 0.0).then(|| {
                            let mut mt = toml::Table::new();
                            mt.insert("link".into(), toml::Value::Integer(k as i64 + 1));
                            mt.insert("kg".into(), float(m.kg));
                            mt.insert(
                                "at_mm".into(),
                                toml::Value::Array(m.com_mm.iter().map(|v| float(*v)).collect()),
                            );
                            toml::Value::Table(mt)
                        })
                    })
                    .collect();
                let mut jt = toml::Table::new();
                jt.insert("joint".into(), toml::Value::Integer(j as i64 + 1));
                jt.insert("deg_per_nm".into(), float(per_nm));
                t.insert("kind".into(), "joint_compliance".into());
                t.insert("masses".into(), toml::Value::Array(masses));
                t.insert(
                    "joints".into(),
                    toml::Value::Array(vec![toml::Value::Table(jt)]),
                );
                format!("deg_per_nm = {per_nm:.6} (the rig's link masses)")
            }
            EffectKind::DriftJoint(j) => {
                let a = file(j, c[0]);
                t.insert("kind".into(), "thermal_drift".into());
                t.insert("joint".into(), toml::Value::Integer(j as i64 + 1));
                t.insert("amplitude_deg".into(), float(a));
                t.insert("tau_s".into(), float(tau_s));
                format!("amplitude_deg = {a:.5}, tau_s = {tau_s:.0}")
            }
            EffectKind::DriftAxis(ax) => {
                let name = ["x", "y", "z"]
                    .get(ax)
                    .ok_or_else(|| "no such axis".to_string())?;
                t.insert("kind".into(), "thermal_drift".into());
                t.insert("axis".into(), (*name).into());
                t.insert("amplitude_mm".into(), float(c[0]));
                t.insert("tau_s".into(), float(tau_s));
                format!("amplitude_mm = {:.5}, tau_s = {tau_s:.0}", c[0])
            }
        };
        Ok(NewEffect { table: t, summary })
    }
}

/// The text of `scenario` (read from `source`) updated with the geometry `truth` and the new
/// `effects`, to be written at `out`.
pub fn scenario_text(
    scenario: &Scenario,
    source: &str,
    out: &Path,
    truth: &ErrorParams,
    effects: &[NewEffect],
) -> Result<String, ScenarioError> {
    let parse_error = |message: String| ScenarioError::Parse {
        path: scenario.path.clone(),
        message,
    };
    let mut doc: toml::Table = toml::from_str(source).map_err(|e| parse_error(e.to_string()))?;
    let out_dir = out.parent().unwrap_or_else(|| Path::new(""));
    let rig = relative_to(out_dir, &scenario.rig_path);
    doc.insert("rig".into(), rig.display().to_string().into());
    let description = format!(
        "{} (updated twin: fitted geometry and named effects)",
        scenario.description
    );
    doc.insert("description".into(), description.trim_start().into());
    doc.insert("seed".into(), toml::Value::Integer(scenario.seed as i64));
    let layout = scenario.rig.chain.layout();
    let mut values = toml::Table::new();
    for (i, id) in layout.ids().iter().enumerate() {
        let v = truth.get(i);
        if v != 0.0 {
            values.insert(layout.name(*id), float(id.kind.to_file_units(v)));
        }
    }
    let mut geometric = toml::Table::new();
    geometric.insert("values".into(), toml::Value::Table(values));
    doc.insert("geometric".into(), toml::Value::Table(geometric));
    let mut all = match doc.remove("effects") {
        Some(toml::Value::Array(a)) => a,
        _ => Vec::new(),
    };
    all.extend(effects.iter().map(|e| toml::Value::Table(e.table.clone())));
    if !all.is_empty() {
        doc.insert("effects".into(), toml::Value::Array(all));
    }
    let body = toml::to_string(&doc).map_err(|e| parse_error(e.to_string()))?;
    Ok(format!(
        "# Written by rigcal {} (`diagnose --write-scenario`): the scenario {} updated from a\n# recording; see the description.\n{body}",
        env!("CARGO_PKG_VERSION"),
        scenario.path.display()
    ))
}

/// The flagged discrepancy as TOML comments: structure the library does not explain; when
/// `simulated`, the `discrepancy` effect above is its fitted smooth term, which the world
/// simulates but which is no physics.
pub fn discrepancy_comment(
    description: &[String],
    simulated: bool,
    heldout_rms_mm: f64,
    floor_mm: f64,
) -> String {
    let how = if simulated {
        "# The recording shows structure no library effect explains; the twin claims no library\n\
         # effect for it. The `discrepancy` effect above (kind = \"discrepancy\") is a smooth fit of\n\
         # it in the shapes the diagnosis located, so the world reproduces the recording; it\n\
         # describes a residual and explains nothing. What the diagnosis located:\n"
    } else {
        "# The recording shows structure no library effect explains; the twin does not claim\n\
         # one for it and the world above does not reproduce it. What the diagnosis located:\n"
    };
    let mut s = format!(
        "\n# ---- discrepancy: FLAGGED, NOT PHYSICS FROM THE LIBRARY{} ----\n{how}",
        if simulated { "" } else { ", NOT SIMULATED" }
    );
    for d in description {
        for line in d.lines() {
            s.push_str("#   ");
            s.push_str(line);
            s.push('\n');
        }
    }
    s.push_str(&format!(
        "# Held-out RMS the updated twin leaves: {heldout_rms_mm:.4} mm (noise floor {floor_mm:.4} mm).\n"
    ));
    s
}

/// `to` as a path relative to the directory `from` when both resolve, else `to` absolute.
fn relative_to(from: &Path, to: &Path) -> PathBuf {
    let abs = |p: &Path| -> Option<PathBuf> {
        let base = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        std::fs::canonicalize(base).ok()
    };
    let (Some(from), Some(to)) = (abs(from), abs(to)) else {
        return to.to_path_buf();
    };
    let f: Vec<Component> = from.components().collect();
    let t: Vec<Component> = to.components().collect();
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in common..f.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_climb_to_the_common_directory() {
        let here = std::env::current_dir().unwrap();
        let r = relative_to(&here.join("sim"), &here.join("rigs/rv-m2-ideal.toml"));
        assert_eq!(r, PathBuf::from("../rigs/rv-m2-ideal.toml"));
    }

    #[test]
    fn a_written_scenario_reads_back_with_its_geometry_and_effects() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../sim/paper-sim.toml"
        ));
        let source = std::fs::read_to_string(path).unwrap();
        let sc = Scenario::parse(&source, path, None).unwrap();
        let mut truth = sc.truth.clone();
        truth.set(0, truth.get(0) + 1e-4);
        let b = NewEffect::of(&sc.rig, EffectKind::Backlash(1), &[3e-4], 0.0).unwrap();
        let text = scenario_text(
            &sc,
            &source,
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/out.toml")),
            &truth,
            &[b],
        )
        .unwrap();
        let back = Scenario::parse(
            &text,
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/out.toml")),
            None,
        )
        .unwrap();
        for i in 0..truth.len() {
            assert!((back.truth.get(i) - truth.get(i)).abs() < 1e-9, "{i}");
        }
        assert_eq!(back.effects.len(), sc.effects.len() + 1);
        assert_eq!(back.effects.last().unwrap().kind(), "backlash");
        assert!(NewEffect::of(&sc.rig, EffectKind::Backlash(1), &[-3e-4], 0.0).is_err());
    }
}
