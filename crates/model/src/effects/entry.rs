//! The scenario entry interface: an effect's `[[effects]]` table in a scenario file, read into its
//! truth and written from fitted coefficients, and the registry entry each effect file provides.
//!
//! Files give degrees and millimetres, unknown keys are rejected, and every error names the key
//! (a TOML path such as `effects[2].joint`); the scenario reader adds the file.

use super::candidate::{Candidate, Index};
use super::truth::Effect;
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rigcal_core::kinematics::{ErrorParams, SerialChain};
use rigcal_core::rig::{Instrument, LinkMass};
use serde::de::DeserializeOwned;
use std::sync::Arc;

/// A value of a scenario file that is out of range or inconsistent.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{key}`: {reason}")]
pub struct EntryError {
    /// The key, as a TOML path.
    pub key: String,
    /// What is wrong and what is expected.
    pub reason: String,
}

/// What a parser needs: where it is (for errors), the chain and truth it acts on, the seed.
#[derive(Debug, Clone, Copy)]
pub struct ParseCtx<'a> {
    /// The key of this effect, e.g. `effects[2]`.
    pub key: &'a str,
    /// The chain.
    pub chain: &'a SerialChain,
    /// The true geometric errors (parsed before the effects).
    pub truth: &'a ErrorParams,
    /// The rig's instrument.
    pub instrument: &'a Instrument,
    /// The scenario seed (for effects drawn at random).
    pub seed: u64,
    /// Position of the effect in the list (to draw independent random numbers).
    pub index: usize,
}

impl ParseCtx<'_> {
    /// An error at `self.key` + `sub` (`sub` empty or `.name`).
    pub fn invalid(&self, sub: &str, reason: impl Into<String>) -> EntryError {
        EntryError {
            key: format!("{}{}", self.key, sub),
            reason: reason.into(),
        }
    }

    /// Deserialises the effect's table (without `kind`) into its raw form.
    pub fn raw<T: DeserializeOwned>(&self, table: &toml::Table) -> Result<T, EntryError> {
        let mut t = table.clone();
        t.remove("kind");
        toml::Value::Table(t)
            .try_into()
            .map_err(|e: toml::de::Error| self.invalid("", e.message().to_string()))
    }

    /// A 1-based joint number from the file, checked against the chain, as a 0-based index.
    pub fn joint(&self, sub: &str, joint: i64) -> Result<usize, EntryError> {
        let n = self.chain.links().len() as i64;
        if joint < 1 || joint > n {
            return Err(self.invalid(sub, format!("joint {joint} is out of range 1..{n}")));
        }
        Ok((joint - 1) as usize)
    }

    /// A finite number.
    pub fn finite(&self, sub: &str, v: f64) -> Result<f64, EntryError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(sub, "must be a finite number"))
        }
    }

    /// A number ≥ 0.
    pub fn non_negative(&self, sub: &str, v: f64) -> Result<f64, EntryError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(sub, format!("must be zero or positive (got {v})")))
        }
    }

    /// A number > 0.
    pub fn positive(&self, sub: &str, v: f64) -> Result<f64, EntryError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(sub, format!("must be positive (got {v})")))
        }
    }

    /// Fails unless the rig measures with the table and panel.
    pub fn require_table(&self) -> Result<(), EntryError> {
        match self.instrument {
            Instrument::TablePanel(_) => Ok(()),
            _ => Err(self.invalid(
                ".kind",
                "a table effect needs a rig with instrument kind = \"table_panel\"",
            )),
        }
    }

    /// An axis name `x`, `y` or `z` at `sub` to its index.
    pub fn axis(&self, sub: &str, name: &str) -> Result<usize, EntryError> {
        match name {
            "x" => Ok(0),
            "y" => Ok(1),
            "z" => Ok(2),
            other => Err(self.invalid(sub, format!("`{other}` is not an axis (x, y or z)"))),
        }
    }

    /// The generator of this effect's random draws (see [`setup_rng`]).
    pub fn rng(&self) -> ChaCha8Rng {
        setup_rng(self.seed, self.index)
    }
}

/// The generator for drawing a scenario's truth (random geometric errors, random coefficients of
/// effect `index`): a function of the seed and the index only, separate from measurement draws.
pub fn setup_rng(seed: u64, index: usize) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&(index as u64).to_le_bytes());
    key[16..].copy_from_slice(b"rigcal-scenario!");
    ChaCha8Rng::from_seed(key)
}

/// A scenario entry written from fitted coefficients: its `[[effects]]` table and a one-line
/// summary.
#[derive(Debug, Clone, PartialEq)]
pub struct NewEffect {
    /// The table, `kind` first.
    pub table: toml::Table,
    /// "lost_motion_deg = 0.04980".
    pub summary: String,
}

/// A TOML float rounded to seven significant digits.
pub fn float(v: f64) -> toml::Value {
    // Seven significant digits: well under the noise, and readable.
    let rounded: f64 = format!("{v:.7e}").parse().unwrap_or(v);
    toml::Value::Float(rounded)
}

/// A 1-based joint number for a file, from a 0-based index.
pub(crate) fn one_based(j: usize) -> toml::Value {
    toml::Value::Integer(j as i64 + 1)
}

/// The rig's link masses, shared by the candidates that need them.
pub type Masses = Option<Arc<Vec<Option<LinkMass>>>>;

/// What the registry knows of one kind: each effect file implements it once.
pub(crate) trait KindEntry: Sync {
    /// Parses a scenario's `[[effects]]` table of this kind into its truth.
    fn parse(&self, ctx: &ParseCtx<'_>, table: &toml::Table)
        -> Result<Arc<dyn Effect>, EntryError>;

    /// The diagnosis's candidates of this kind on `on` (a joint, an axis or a pair of axes);
    /// none by default (the kind is simulated, never named).
    fn candidates(&self, _on: Index, _masses: &Masses) -> Vec<Box<dyn Candidate>> {
        Vec::new()
    }
}
