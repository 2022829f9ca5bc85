//! The registry: every effect kind with its entry (its scenario parser and its
//! diagnosis candidates). It imports each effect file; the effect files import only the
//! interfaces (`kind`, `truth`, `entry`, `candidate`, `term`), never the registry.

use super::candidate::{Candidate, Index};
use super::entry::{EntryError, KindEntry, Masses, ParseCtx};
use super::kind::EffectKind;
use super::truth::Effect;
use super::{
    backlash, compliance, discrepancy, drift, registration_offset, table_scale, table_squareness,
    transmission, trig_joint,
};
use std::sync::Arc;

/// The entry of `kind`: one line per kind.
fn entry(kind: EffectKind) -> &'static dyn KindEntry {
    match kind {
        EffectKind::TrigJointErrors => &trig_joint::Entry,
        EffectKind::JointCompliance => &compliance::Entry,
        EffectKind::Backlash => &backlash::Entry,
        EffectKind::TransmissionError => &transmission::Entry,
        EffectKind::ThermalDrift => &drift::Entry,
        EffectKind::TableScale => &table_scale::Entry,
        EffectKind::TableSquareness => &table_squareness::Entry,
        EffectKind::RegistrationOffset => &registration_offset::Entry,
        EffectKind::Discrepancy => &discrepancy::Entry,
    }
}

/// Every kind's name, for error messages.
fn known() -> String {
    EffectKind::ALL
        .iter()
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Parses one `[[effects]]` entry of a scenario by its `kind`.
pub fn parse_effect(
    ctx: &ParseCtx<'_>,
    table: &toml::Table,
) -> Result<Arc<dyn Effect>, EntryError> {
    let Some(kind) = table.get("kind") else {
        return Err(ctx.invalid(".kind", format!("missing; one of {}", known())));
    };
    let Some(kind) = kind.as_str() else {
        return Err(ctx.invalid(".kind", "must be a string"));
    };
    match EffectKind::from_name(kind) {
        Some(k) => entry(k).parse(ctx, table),
        None => Err(ctx.invalid(
            ".kind",
            format!("unknown effect kind `{kind}`; known: {}", known()),
        )),
    }
}

/// The diagnosis's candidate library for `dof` joints: every kind on every joint, then every
/// kind on every axis and pair of axes, in registry order. Compliance uses the rig's link
/// `masses` where they are given, the generic unit-mass model elsewhere.
pub fn candidates(dof: usize, masses: &Masses) -> Vec<Box<dyn Candidate>> {
    let mut v: Vec<Box<dyn Candidate>> = Vec::new();
    for j in 0..dof {
        for k in EffectKind::ALL {
            v.extend(entry(*k).candidates(Index::Joint(j), masses));
        }
    }
    for k in EffectKind::ALL {
        for a in 0..3 {
            v.extend(entry(*k).candidates(Index::Axis(a), masses));
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            v.extend(entry(*k).candidates(Index::Axes(a, b), masses));
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_library_lists_every_named_kind_in_a_fixed_order() {
        // Per joint: compliance, backlash, four transmission orders, drift; then drift on each
        // axis, table scale on each axis, table squareness on each pair.
        let lib = candidates(2, &None);
        let labels: Vec<String> = lib.iter().map(|c| c.label()).collect();
        let mut want = Vec::new();
        for j in 1..=2 {
            want.push(format!("joint_compliance on joint {j}"));
            want.push(format!("backlash on joint {j}"));
            for n in 1..=transmission::MAX_ORDER {
                want.push(format!("transmission_error (order {n}) on joint {j}"));
            }
            want.push(format!("thermal_drift on joint {j}"));
        }
        for a in ["x", "y", "z"] {
            want.push(format!("thermal_drift on axis {a}"));
        }
        for a in ["x", "y", "z"] {
            want.push(format!("table_scale on axis {a}"));
        }
        for p in ["x–y", "x–z", "y–z"] {
            want.push(format!("table_squareness on axes {p}"));
        }
        assert_eq!(labels, want);
    }

    #[test]
    fn every_kind_has_an_entry_that_reports_its_own_kind() {
        for k in EffectKind::ALL {
            for on in [Index::Joint(0), Index::Axis(0), Index::Axes(0, 1)] {
                for c in entry(*k).candidates(on, &None) {
                    assert_eq!(c.kind(), *k);
                    assert_eq!(c.index(), on);
                }
            }
        }
    }
}
