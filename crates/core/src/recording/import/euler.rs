//! Euler-angle conventions of imported orientations, as the user names them: intrinsic
//! (rotating axes) or extrinsic (fixed axes), and the axis order. `intrinsic-xyz` is scipy's
//! `'XYZ'` (R = Rx(a)·Ry(b)·Rz(c)); `extrinsic-xyz` is scipy's `'xyz'` and URDF's rpy
//! (R = Rz(c)·Ry(b)·Rx(a)).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// An Euler-angle convention.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EulerConvention {
    /// Rotating axes (each rotation about the axes the previous ones turned).
    pub intrinsic: bool,
    /// Axis of the first, second and third angle as written (0 = x, 1 = y, 2 = z).
    pub axes: [usize; 3],
}

/// Why a convention could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{text}` is not an Euler convention: write intrinsic-ORDER or extrinsic-ORDER with ORDER three of x, y, z, no axis twice in a row (intrinsic-xyz is scipy's 'XYZ', extrinsic-xyz is scipy's 'xyz' and URDF's rpy)")]
pub struct BadConvention {
    /// What was given.
    pub text: String,
}

impl std::str::FromStr for EulerConvention {
    type Err = BadConvention;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || BadConvention {
            text: s.to_string(),
        };
        let lower = s.trim().to_ascii_lowercase();
        let (kind, order) = lower.split_once(['-', '_', ' ']).ok_or_else(bad)?;
        let intrinsic = match kind {
            "intrinsic" => true,
            "extrinsic" => false,
            _ => return Err(bad()),
        };
        let axes: Vec<usize> = order
            .bytes()
            .map(|b| match b {
                b'x' => Some(0),
                b'y' => Some(1),
                b'z' => Some(2),
                _ => None,
            })
            .collect::<Option<_>>()
            .ok_or_else(bad)?;
        let axes: [usize; 3] = axes.try_into().map_err(|_| bad())?;
        if axes[0] == axes[1] || axes[1] == axes[2] {
            return Err(bad());
        }
        Ok(EulerConvention { intrinsic, axes })
    }
}

impl std::fmt::Display for EulerConvention {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let order: String = self.axes.iter().map(|&a| ['x', 'y', 'z'][a]).collect();
        let kind = if self.intrinsic {
            "intrinsic"
        } else {
            "extrinsic"
        };
        write!(f, "{kind}-{order}")
    }
}

fn axis(k: usize) -> Vector3<f64> {
    let mut v = Vector3::zeros();
    v[k] = 1.0;
    v
}

impl EulerConvention {
    /// The same rotation as intrinsic angles about `axes` (an extrinsic sequence is the
    /// intrinsic one in reverse order): (axes, the index of each angle as written).
    fn as_intrinsic(&self) -> ([usize; 3], [usize; 3]) {
        if self.intrinsic {
            (self.axes, [0, 1, 2])
        } else {
            ([self.axes[2], self.axes[1], self.axes[0]], [2, 1, 0])
        }
    }

    /// The rotation for angles (rad) in the order written.
    pub fn rotation(&self, angles: [f64; 3]) -> UnitQuaternion<f64> {
        let (axes, which) = self.as_intrinsic();
        let r = |k: usize| {
            Rotation3::from_axis_angle(
                &nalgebra::Unit::new_unchecked(axis(axes[k])),
                angles[which[k]],
            )
        };
        UnitQuaternion::from_rotation_matrix(&(r(0) * r(1) * r(2)))
    }

    /// The standard deviation (rad) of a small rotation of the frame about its own x, y and z
    /// axes, from standard deviations (rad) of the angles (in the order written), taken as
    /// independent: first order, σ_k = √Σ_j (J_kj σ_j)² with J the map from angle rates to the
    /// frame's own angular velocity at `angles`.
    pub fn body_sigma(&self, angles: [f64; 3], sigma: [f64; 3]) -> Vector3<f64> {
        let (axes, which) = self.as_intrinsic();
        let r = |k: usize| {
            Rotation3::from_axis_angle(
                &nalgebra::Unit::new_unchecked(axis(axes[k])),
                angles[which[k]],
            )
        };
        // R = R1 R2 R3: ω_body = (R2 R3)ᵀ e1 ȧ1 + R3ᵀ e2 ȧ2 + e3 ȧ3.
        let c1 = (r(1) * r(2)).inverse() * axis(axes[0]);
        let c2 = r(2).inverse() * axis(axes[1]);
        let c3 = axis(axes[2]);
        let j = Matrix3::from_columns(&[c1, c2, c3]);
        let s = Vector3::new(sigma[which[0]], sigma[which[1]], sigma[which[2]]);
        Vector3::from_fn(|k, _| {
            (0..3)
                .map(|m| (j[(k, m)] * s[m]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn names_read_and_print() {
        let c: EulerConvention = "Intrinsic-XYZ".parse().unwrap();
        assert_eq!(c.to_string(), "intrinsic-xyz");
        assert!("intrinsic-xxz".parse::<EulerConvention>().is_err());
        assert!("xyz".parse::<EulerConvention>().is_err());
        assert!("extrinsic-zyz".parse::<EulerConvention>().is_ok());
    }

    #[test]
    fn extrinsic_xyz_is_urdf_rpy_and_intrinsic_zyx() {
        let a = [0.3, -1.1, 2.6];
        let ext: EulerConvention = "extrinsic-xyz".parse().unwrap();
        let rpy = UnitQuaternion::from_euler_angles(a[0], a[1], a[2]);
        assert!(ext.rotation(a).angle_to(&rpy) < 1e-12);
        let zyx: EulerConvention = "intrinsic-zyx".parse().unwrap();
        assert!(zyx.rotation([a[2], a[1], a[0]]).angle_to(&rpy) < 1e-12);
        let xyz: EulerConvention = "intrinsic-xyz".parse().unwrap();
        let by_hand = UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), a[0])
            * UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), a[1])
            * UnitQuaternion::from_axis_angle(&nalgebra::Vector3::z_axis(), a[2]);
        assert!(xyz.rotation(a).angle_to(&by_hand) < 1e-12);
    }

    #[test]
    fn body_sigma_follows_the_axes() {
        let xyz: EulerConvention = "intrinsic-xyz".parse().unwrap();
        // At zero every angle turns about its own body axis.
        let s = xyz.body_sigma([0.0; 3], [1.0, 2.0, 3.0]);
        assert!((s - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        // With the last angle at 90° about z, the first angle's x turns into the body's −y.
        let s = xyz.body_sigma([0.0, 0.0, FRAC_PI_2], [1.0, 0.0, 0.0]);
        assert!((s - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-12, "{s}");
        // Numerically: a small change of each angle against the Jacobian's column.
        let a = [0.4, -0.9, 1.7];
        let ext: EulerConvention = "extrinsic-zyx".parse().unwrap();
        for k in 0..3 {
            let mut b = a;
            b[k] += 1e-7;
            let d = ext.rotation(a).inverse() * ext.rotation(b);
            let w = d.scaled_axis() / 1e-7;
            let mut sig = [0.0; 3];
            sig[k] = 1.0;
            let s = ext.body_sigma(a, sig);
            assert!((s - w.abs()).norm() < 1e-6, "{k}: {s} vs {w}");
        }
    }
}
