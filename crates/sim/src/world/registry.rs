//! The effect registry: every effect kind a scenario may name, with its parser.
//!
//! It imports each effect file; the effects import only the interface in [`super::effect`], so
//! adding an effect is one new file plus one line in [`REGISTRY`].

use super::effect::{Effect, ParseCtx};
use super::scenario::ScenarioError;
use super::{backlash, compliance, discrepancy, drift, table, transmission, trig_joint};
use std::sync::Arc;

/// Parses one effect's table.
pub type ParseFn = fn(&ParseCtx<'_>, &toml::Table) -> Result<Arc<dyn Effect>, ScenarioError>;

/// Every effect kind a scenario may name, with its parser.
pub const REGISTRY: &[(&str, ParseFn)] = &[
    ("trig_joint_errors", trig_joint::parse),
    ("joint_compliance", compliance::parse),
    ("backlash", backlash::parse),
    ("transmission_error", transmission::parse),
    ("thermal_drift", drift::parse),
    ("table_scale", table::parse_scale),
    ("table_squareness", table::parse_squareness),
    ("registration_offset", table::parse_registration_offset),
    ("discrepancy", discrepancy::parse),
];

/// Parses one `[[effects]]` entry by its `kind`.
pub fn parse_effect(
    ctx: &ParseCtx<'_>,
    table: &toml::Table,
) -> Result<Arc<dyn Effect>, ScenarioError> {
    let kinds: Vec<&str> = REGISTRY.iter().map(|(k, _)| *k).collect();
    let Some(kind) = table.get("kind") else {
        return Err(ctx.invalid(".kind", format!("missing; one of {}", kinds.join(", "))));
    };
    let Some(kind) = kind.as_str() else {
        return Err(ctx.invalid(".kind", "must be a string"));
    };
    match REGISTRY.iter().find(|(k, _)| *k == kind) {
        Some((_, parse)) => parse(ctx, table),
        None => Err(ctx.invalid(
            ".kind",
            format!("unknown effect kind `{kind}`; known: {}", kinds.join(", ")),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::Scenario;
    use std::collections::BTreeSet;
    use std::path::Path;

    fn parse_error(effect: &str) -> String {
        let text = format!("seed = 1\nrig = \"../rigs/rv-m2-ideal.toml\"\n[[effects]]\n{effect}");
        match Scenario::parse(
            &text,
            Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../sim/registry-test.toml"
            )),
            None,
        ) {
            Ok(_) => panic!("`{effect}` parsed"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn every_kind_is_registered_once_under_its_effects_own_name() {
        let keys: Vec<&str> = REGISTRY.iter().map(|(k, _)| *k).collect();
        let unique: BTreeSet<&str> = keys.iter().copied().collect();
        assert_eq!(unique.len(), keys.len(), "duplicate kinds in {keys:?}");
        // The shipped scenarios name every kind between them: each parses to an effect that
        // reports the name it was registered under.
        let mut seen = BTreeSet::new();
        for file in [
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/rig-realistic.toml"),
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../sim/paper-sim.toml"),
        ] {
            let sc = Scenario::load(Path::new(file), None).expect("shipped scenario");
            for e in &sc.effects {
                assert!(unique.contains(e.kind()), "{} is not registered", e.kind());
                seen.insert(e.kind());
            }
        }
        // A fitted discrepancy is written by the twin, never shipped: its own tests parse it.
        seen.insert("discrepancy");
        assert_eq!(seen, unique);
    }

    #[test]
    fn a_missing_or_unknown_kind_lists_the_known_ones() {
        let missing = parse_error("joint = 1\n");
        assert!(missing.contains("effects[0].kind"), "{missing}");
        assert!(
            missing.contains(&format!("missing; one of {}", REGISTRY[0].0)),
            "{missing}"
        );
        let not_string = parse_error("kind = 3\n");
        assert!(not_string.contains("must be a string"), "{not_string}");
        let unknown = parse_error("kind = \"gear_wobble\"\n");
        for (k, _) in REGISTRY {
            assert!(unknown.contains(k), "{unknown}");
        }
    }
}
