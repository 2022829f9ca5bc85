//! What a session continues from: the files and settings a resume must be given again, noted
//! when the session starts (`[resume_check]` in its `session.toml`) and compared, field by
//! field, before a resume opens any device.
//!
//! Files are compared by content (a 64-bit FNV-1a hash of their bytes, written
//! `fnv1a64:<hex>`): the same rig file under another path is the same rig, and a rig file
//! edited in place is not. The hash finds accidental edits and mix-ups, not forgeries.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::session::procedure::ContactProcedure;
use rigcal_core::recording::SessionInfo;

/// The key of the check in `session.toml`.
pub const RESUME_CHECK_KEY: &str = "resume_check";

/// What a session continues from (see the module docs).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ResumeCheck {
    /// The rig file's content.
    pub rig_hash: String,
    /// The scenario file's content (a dry run; none on the rig).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario_hash: Option<String>,
    /// The content of the rig file the scenario refers to (a dry run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario_rig_hash: Option<String>,
    /// The simulated world's seed (the scenario's, or `--sim-seed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scenario_seed: Option<u64>,
    /// The session's seed (`--seed`: plan and registration poses).
    pub seed: u64,
    /// The contact procedure.
    pub procedure: ContactProcedure,
    /// Poses of the registration step.
    pub registration_points: usize,
    /// The content of the session's `plan.csv` as the session wrote it.
    pub plan_hash: String,
}

impl ResumeCheck {
    /// The check `info` (a `session.toml`) holds: none for a session begun before checks were
    /// recorded; an error when the table is there but unreadable.
    pub fn of(info: &SessionInfo) -> Result<Option<ResumeCheck>, String> {
        let Some(value) = info.extra.get(RESUME_CHECK_KEY) else {
            return Ok(None);
        };
        value
            .clone()
            .try_into()
            .map(Some)
            .map_err(|e: toml::de::Error| format!("[{RESUME_CHECK_KEY}]: {e}"))
    }

    /// `info` holding this check.
    pub fn put_into(&self, info: &mut SessionInfo) {
        if let Ok(value) = toml::Value::try_from(self) {
            info.extra.insert(RESUME_CHECK_KEY.to_string(), value);
        }
    }

    /// What differs between the session's check (`self`) and `given`, one line each, naming
    /// the option or file to give again; `contact` compares the procedure (it matters on the
    /// table rig only).
    pub fn differences(&self, given: &ResumeCheck, contact: bool) -> Vec<String> {
        let mut out = Vec::new();
        if self.rig_hash != given.rig_hash {
            out.push("--rig: the rig file's content is not the one the session began with".into());
        }
        match (&self.scenario_hash, &given.scenario_hash) {
            (Some(_), None) => out.push(
                "--sim: the session began as a dry run on a scenario, now none is given".into(),
            ),
            (None, Some(_)) => out.push(
                "--sim: the session began on the rig's devices, now a scenario is given".into(),
            ),
            (Some(a), Some(b)) if a != b => out.push(
                "--sim: the scenario file's content is not the one the session began with".into(),
            ),
            _ => {}
        }
        if self.scenario_rig_hash != given.scenario_rig_hash
            && self.scenario_hash.is_some() == given.scenario_hash.is_some()
        {
            out.push(
                "--sim: the rig file the scenario refers to has changed since the session began"
                    .into(),
            );
        }
        if self.scenario_seed != given.scenario_seed {
            out.push(format!(
                "--sim-seed: the simulated world's seed was {}, now {}",
                shown(self.scenario_seed),
                shown(given.scenario_seed)
            ));
        }
        if self.seed != given.seed {
            out.push(format!("--seed: was {}, now {}", self.seed, given.seed));
        }
        if contact && self.procedure != given.procedure {
            out.push(format!(
                "--procedure: was {}, now {}",
                self.procedure, given.procedure
            ));
        }
        if self.registration_points != given.registration_points {
            out.push(format!(
                "--registration-points: was {}, now {}",
                self.registration_points, given.registration_points
            ));
        }
        if self.plan_hash != given.plan_hash {
            out.push(
                "plan.csv: edited since the session began (its content differs from the plan the session wrote)".into(),
            );
        }
        out
    }
}

fn shown(seed: Option<u64>) -> String {
    seed.map_or("none (no scenario)".to_string(), |s| s.to_string())
}

/// The content hash of `bytes` (`fnv1a64:<16 hex digits>`).
pub fn content_hash(bytes: &[u8]) -> String {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let h = bytes
        .iter()
        .fold(OFFSET, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME));
    format!("fnv1a64:{h:016x}")
}

/// The content hash of the file at `path`.
pub fn file_hash(path: &Path) -> std::io::Result<String> {
    std::fs::read(path).map(|b| content_hash(&b))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn check() -> ResumeCheck {
        ResumeCheck {
            rig_hash: content_hash(b"rig"),
            scenario_hash: Some(content_hash(b"scenario")),
            scenario_rig_hash: Some(content_hash(b"rig")),
            scenario_seed: Some(7),
            seed: 7,
            procedure: ContactProcedure::Rigcal,
            registration_points: 12,
            plan_hash: content_hash(b"plan"),
        }
    }

    #[test]
    fn the_hash_is_fnv1a() {
        assert_eq!(content_hash(b""), "fnv1a64:cbf29ce484222325");
        assert_eq!(content_hash(b"a"), "fnv1a64:af63dc4c8601ec8c");
    }

    #[test]
    fn the_check_survives_session_toml_and_names_each_difference() {
        let mut info = SessionInfo::default();
        check().put_into(&mut info);
        let text = toml::to_string_pretty(&info).unwrap();
        let back: SessionInfo = toml::from_str(&text).unwrap();
        assert_eq!(ResumeCheck::of(&back).unwrap(), Some(check()));
        assert!(check().differences(&check(), true).is_empty());
        let mut other = check();
        other.scenario_seed = Some(8);
        other.plan_hash = content_hash(b"edited");
        other.procedure = ContactProcedure::Baseline;
        let d = check().differences(&other, true);
        assert_eq!(d.len(), 3, "{d:?}");
        assert!(d[0].contains("--sim-seed") && d[0].contains("was 7, now 8"));
        assert!(check().differences(&other, false).len() == 2);
    }
}
