//! Writing a scenario file: an updated twin ([`crate::twin::learn`](mod@crate::twin::learn)) as
//! TOML, through the serializer, so what is written is what [`Scenario::parse`] reads.
//!
//! The old file's keys are kept (description, seed, measurement settings and its `[[effects]]`
//! tables as written, so effects drawn from the seed draw the same); the rig path is made
//! relative to the new file; `[geometric]` becomes explicit values of every non-zero parameter
//! (mm, degrees) — a random draw would not reproduce a fitted geometry; new effects are appended.
//! What the serializer cannot carry (comments: a flagged discrepancy) is appended as text. Each
//! new effect's table is written by its own file in [`rigcal_model::effects`]
//! (`scenario_entry`).

use super::scenario::{Scenario, ScenarioError};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_model::effects::{float, NewEffect};
use std::path::{Component, Path, PathBuf};

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
    use rigcal_model::effects::{backlash, EffectKind};

    #[test]
    fn relative_paths_climb_to_the_common_directory() {
        let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
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
        let b = backlash::scenario_entry(&sc.rig.chain, 1, 3e-4).unwrap();
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
        assert_eq!(back.effects.last().unwrap().kind(), EffectKind::Backlash);
        assert!(backlash::scenario_entry(&sc.rig.chain, 1, -3e-4).is_err());
    }
}
