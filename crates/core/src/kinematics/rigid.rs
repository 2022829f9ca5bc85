//! The two building blocks of a chain's evaluation, below both the chain ([`super::chain`]) and
//! its multiplied-out form ([`super::compiled`]): the elementary motion an error parameter
//! carries (a rotation about, or a translation along, one local axis) and the rigid transform
//! as rotation matrix + translation ([`Rt`]), on which an elementary rotation touches two
//! columns of the matrix and a translation three numbers.
//!
//! Units: mm and rad.

use nalgebra::{Isometry3, Matrix3, Vector3};

/// An elementary motion about or along local axis k (0 = x, 1 = y, 2 = z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Motion {
    Rot(usize),
    Trans(usize),
}

/// A rigid transform as rotation matrix and translation: x ↦ r·x + t.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Rt {
    pub(super) r: Matrix3<f64>,
    pub(super) t: Vector3<f64>,
}

impl Rt {
    pub(super) const IDENTITY: Rt = Rt {
        r: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        t: Vector3::new(0.0, 0.0, 0.0),
    };

    pub(super) fn from_isometry(p: &Isometry3<f64>) -> Rt {
        Rt {
            r: *p.rotation.to_rotation_matrix().matrix(),
            t: p.translation.vector,
        }
    }

    /// self · other.
    pub(super) fn then(&self, other: &Rt) -> Rt {
        // Column by column (each a combination of self's columns): cheaper than the generic
        // matrix product for 3 × 3.
        let (c0, c1, c2) = (self.r.column(0), self.r.column(1), self.r.column(2));
        let o = &other.r;
        let col = |j: usize| c0 * o[(0, j)] + c1 * o[(1, j)] + c2 * o[(2, j)];
        let t = &other.t;
        Rt {
            r: Matrix3::from_columns(&[col(0), col(1), col(2)]),
            t: self.t + c0 * t.x + c1 * t.y + c2 * t.z,
        }
    }

    /// self ← self · Rot_k(angle), given sin and cos of the angle: two columns change.
    pub(super) fn rotate_local(&mut self, k: usize, s: f64, c: f64) {
        let (i, j) = match k {
            0 => (1, 2),
            1 => (2, 0),
            _ => (0, 1),
        };
        let ci = self.r.column(i).into_owned();
        let cj = self.r.column(j).into_owned();
        self.r.set_column(i, &(ci * c + cj * s));
        self.r.set_column(j, &(cj * c - ci * s));
    }

    /// self ← self · Trans_k(v).
    pub(super) fn translate_local(&mut self, k: usize, v: f64) {
        self.t += self.r.column(k) * v;
    }

    /// self ← self · motion(v).
    pub(super) fn apply_motion(&mut self, m: Motion, v: f64) {
        match m {
            Motion::Rot(k) => {
                if v != 0.0 {
                    let (s, c) = v.sin_cos();
                    self.rotate_local(k, s, c);
                }
            }
            Motion::Trans(k) => self.translate_local(k, v),
        }
    }
}
