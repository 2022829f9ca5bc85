//! The effect interface: one trait with three hooks and the context a parser gets.
//!
//! An effect perturbs the truth in one or more of three places:
//! - **joint space**: the actual joint angles differ from the commanded ones
//!   ([`Effect::joint_offsets`], given the commanded joints, the time and the motion history);
//! - **the pin tip**: a Cartesian displacement of the true tip in the world frame
//!   ([`Effect::tip_offset`], e.g. thermal growth along an axis, or a fitted discrepancy that
//!   varies with the position);
//! - **the table**: the map from table readings to true world positions ([`Effect::distort_table`]).
//!
//! Adding an effect means one new file with a type implementing [`Effect`] and a `parse`
//! function, plus one line in the registry ([`super::registry::REGISTRY`]), which knows every
//! effect; no effect knows the registry.
//!
//! Units: radians and millimetres inside; scenario files give degrees and millimetres.

use super::scenario::ScenarioError;
use super::MotionHistory;
use nalgebra::{Isometry3, Matrix3, Vector3};
use rigcal_core::kinematics::{ErrorParams, SerialChain};
use rigcal_core::rig::Instrument;
use serde::de::DeserializeOwned;
use std::fmt;
use std::path::PathBuf;

/// What a joint-space effect sees when the arm is commanded somewhere.
#[derive(Debug, Clone, Copy)]
pub struct JointContext<'a> {
    /// The chain, nominal values.
    pub chain: &'a SerialChain,
    /// The true geometric error parameters.
    pub truth: &'a ErrorParams,
    /// The commanded joint values (rad or mm).
    pub commanded: &'a [f64],
    /// Seconds since the session started.
    pub t_s: f64,
    /// The motion history, already updated with this command.
    pub history: &'a MotionHistory,
}

/// The table's truth: world position of the panel centre for a table reading r is
/// `registration · (axes · r)`. Nominal: `axes` = identity, `registration` = the rig's
/// `table_to_world_mm` translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableMap {
    /// True table-frame position per unit of reading along each axis (columns = axes).
    pub axes: Matrix3<f64>,
    /// True table-to-world transform.
    pub registration: Isometry3<f64>,
}

impl TableMap {
    /// The nominal map: perfect axes, the nominal translation (mm).
    pub fn nominal(table_to_world_mm: Vector3<f64>) -> Self {
        Self {
            axes: Matrix3::identity(),
            registration: Isometry3::translation(
                table_to_world_mm.x,
                table_to_world_mm.y,
                table_to_world_mm.z,
            ),
        }
    }

    /// World position (mm) of the panel centre when the table reads `reading` (mm).
    pub fn world(&self, reading: &Vector3<f64>) -> Vector3<f64> {
        (self.registration * nalgebra::Point3::from(self.axes * reading)).coords
    }

    /// The table reading whose z puts the panel surface at world height `z_world`, with x and y
    /// at `xy` (the table's z arm rises until it touches the pin).
    pub fn reading_at_height(&self, xy: [f64; 2], z_world: f64) -> Vector3<f64> {
        let m = self.registration.rotation.to_rotation_matrix().matrix() * self.axes;
        let tz = self.registration.translation.vector.z;
        // z_world = m[2,0]·x + m[2,1]·y + m[2,2]·z + tz, linear in the unknown z.
        let z = (z_world - tz - m[(2, 0)] * xy[0] - m[(2, 1)] * xy[1]) / m[(2, 2)];
        Vector3::new(xy[0], xy[1], z)
    }
}

/// A piece of non-geometric physics. Every hook defaults to "no effect".
pub trait Effect: fmt::Debug + Send + Sync {
    /// The name used in scenario files and diagnosis reports (`backlash`, …).
    fn kind(&self) -> &'static str;

    /// Adds this effect's joint errors (rad or mm) to `dq`, actual = commanded + dq.
    fn joint_offsets(&self, _ctx: &JointContext<'_>, _dq: &mut [f64]) {}

    /// Displacement (mm, world) of the true pin tip at time `t_s`, the tip being at `tip` (mm,
    /// world) before any such displacement.
    fn tip_offset(&self, _t_s: f64, _tip: &Vector3<f64>) -> Vector3<f64> {
        Vector3::zeros()
    }

    /// Applies this effect to the table's truth.
    fn distort_table(&self, _map: &mut TableMap) {}
}

/// What a parser needs: where it is (for errors), the chain and truth it acts on, the seed.
#[derive(Debug, Clone, Copy)]
pub struct ParseCtx<'a> {
    /// The scenario file.
    pub path: &'a std::path::Path,
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
    pub fn invalid(&self, sub: &str, reason: impl Into<String>) -> ScenarioError {
        ScenarioError::Invalid {
            path: PathBuf::from(self.path),
            key: format!("{}{}", self.key, sub),
            reason: reason.into(),
        }
    }

    /// Deserialises the effect's table (without `kind`) into its raw form.
    pub fn raw<T: DeserializeOwned>(&self, table: &toml::Table) -> Result<T, ScenarioError> {
        let mut t = table.clone();
        t.remove("kind");
        toml::Value::Table(t)
            .try_into()
            .map_err(|e: toml::de::Error| self.invalid("", e.message().to_string()))
    }

    /// A 1-based joint number from the file, checked against the chain, as a 0-based index.
    pub fn joint(&self, sub: &str, joint: i64) -> Result<usize, ScenarioError> {
        let n = self.chain.links().len() as i64;
        if joint < 1 || joint > n {
            return Err(self.invalid(sub, format!("joint {joint} is out of range 1..{n}")));
        }
        Ok((joint - 1) as usize)
    }

    /// A finite number.
    pub fn finite(&self, sub: &str, v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(sub, "must be a finite number"))
        }
    }

    /// A number ≥ 0.
    pub fn non_negative(&self, sub: &str, v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(sub, format!("must be zero or positive (got {v})")))
        }
    }

    /// A number > 0.
    pub fn positive(&self, sub: &str, v: f64) -> Result<f64, ScenarioError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(self.invalid(sub, format!("must be positive (got {v})")))
        }
    }

    /// Fails unless the rig measures with the table and panel.
    pub fn require_table(&self) -> Result<(), ScenarioError> {
        match self.instrument {
            Instrument::TablePanel(_) => Ok(()),
            _ => Err(self.invalid(
                ".kind",
                "a table effect needs a rig with instrument kind = \"table_panel\"",
            )),
        }
    }
}

/// An axis name `x`, `y` or `z` to its index.
pub fn axis_index(ctx: &ParseCtx<'_>, sub: &str, name: &str) -> Result<usize, ScenarioError> {
    match name {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => Err(ctx.invalid(sub, format!("`{other}` is not an axis (x, y or z)"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    #[test]
    fn contact_height_inverts_the_table_map() {
        // A tilted, sheared, scaled table: the solved reading puts the panel at the asked height.
        let mut map = TableMap::nominal(Vector3::new(-400.0, 170.0, -50.0));
        map.axes[(0, 1)] = 1e-3;
        map.axes[(2, 2)] = 1.0 / 1.0002;
        map.registration = Isometry3::from_parts(
            map.registration.translation,
            UnitQuaternion::from_euler_angles(1e-3, -2e-3, 0.01),
        );
        let r = map.reading_at_height([310.0, 120.0], 123.0);
        assert_eq!((r.x, r.y), (310.0, 120.0));
        assert!((map.world(&r).z - 123.0).abs() < 1e-10);
        // Nominal: world z = reading z − 50.
        let n = TableMap::nominal(Vector3::new(-400.0, 170.0, -50.0));
        assert!((n.reading_at_height([0.0, 0.0], 100.0).z - 150.0).abs() < 1e-12);
    }
}
