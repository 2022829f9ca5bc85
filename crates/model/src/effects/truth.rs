//! The truth interface: what an effect does to a simulated arm and instrument. One trait with
//! three hooks; the simulated world (`rigcal_sim::world`) calls them, nothing in this crate does.
//!
//! An effect perturbs the truth in one or more of three places:
//! - **joint space**: the actual joint angles differ from the commanded ones
//!   ([`Effect::joint_offsets`], given the commanded joints, the time and the approach
//!   directions);
//! - **the pin tip**: a Cartesian displacement of the true tip in the world frame
//!   ([`Effect::tip_offset`], e.g. thermal growth along an axis, or a fitted discrepancy that
//!   varies with the position);
//! - **the table**: the map from table readings to true world positions
//!   ([`Effect::distort_table`]).
//!
//! Units: radians and millimetres inside.

use super::kind::EffectKind;
use nalgebra::{Isometry3, Matrix3, Vector3};
use rigcal_core::kinematics::{ErrorParams, SerialChain};
use std::fmt;

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
    /// Per joint: +1 or −1, the sign of its last non-zero change including this command; 0
    /// while it has not moved (the world's motion history).
    pub direction: &'a [i8],
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

/// A piece of non-geometric physics in a simulated world. Every hook defaults to "no effect".
pub trait Effect: fmt::Debug + Send + Sync {
    /// Its kind, the name scenario files and diagnosis reports use.
    fn kind(&self) -> EffectKind;

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
