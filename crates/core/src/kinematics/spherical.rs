//! Spherical workspace coordinates (seed 000, Fig. 4c; conventions §5).
//!
//! Centred on the first joint's frame origin, with the polar axis along the first joint's axis:
//! R is the distance (mm), azimuth the angle about the first joint's axis measured in that
//! joint's frame before it moves (so azimuth = q1 for any point of the arm), and elevation the
//! angle above the plane normal to that axis, positive towards world +z (radians inside).
//! For the RV-M2 this is R = |p − (0, −80, 400)|, azimuth = atan2(x, y + 80) and
//! elevation = atan2(z − 400, ρ).

use super::{ErrorParams, Robot, SerialChain};
use nalgebra::{Isometry3, Point3, Vector3};

/// A point in spherical workspace coordinates (mm, rad, rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spherical {
    /// Distance from the centre (mm).
    pub r: f64,
    /// Angle about the first joint's axis (rad).
    pub azimuth: f64,
    /// Angle above the plane normal to that axis (rad).
    pub elevation: f64,
}

/// The frame in which spherical coordinates are taken.
#[derive(Debug, Clone)]
pub struct SphericalFrame {
    centre: Isometry3<f64>,
    up_sign: f64,
}

impl SphericalFrame {
    /// The spherical frame of a chain: its first joint's frame, in world coordinates (the
    /// measurement frame is left out).
    pub fn of(chain: &SerialChain) -> Self {
        let world = chain.with_frame(Isometry3::identity());
        let zero = vec![0.0; world.dof()];
        let centre = world.frame_before_joint(&zero, &ErrorParams::zeros(world.layout()), 0);
        let axis_z = (centre.rotation * Vector3::z()).z;
        Self {
            centre,
            up_sign: if axis_z >= 0.0 { 1.0 } else { -1.0 },
        }
    }

    /// The centre (world, mm).
    pub fn origin(&self) -> Vector3<f64> {
        self.centre.translation.vector
    }

    /// World point (mm) to spherical coordinates.
    pub fn to_spherical(&self, p: &Vector3<f64>) -> Spherical {
        let l = self.centre.inverse_transform_point(&Point3::from(*p));
        let rho = l.x.hypot(l.y);
        Spherical {
            r: l.coords.norm(),
            azimuth: l.y.atan2(l.x),
            elevation: (self.up_sign * l.z).atan2(rho),
        }
    }

    /// Spherical coordinates to a world point (mm).
    pub fn to_world(&self, s: &Spherical) -> Vector3<f64> {
        let rho = s.r * s.elevation.cos();
        let l = Point3::new(
            rho * s.azimuth.cos(),
            rho * s.azimuth.sin(),
            self.up_sign * s.r * s.elevation.sin(),
        );
        (self.centre * l).coords
    }
}
