//! A robot at fixed error parameters, the evaluation under every fit and analysis of
//! identification ([`super::fit`], [`super::identifiability`]): a serial chain multiplied out
//! once ([`ChainAt`]), any other robot through its [`Robot`] methods.
//!
//! Units: mm and rad.

use nalgebra::Vector3;
use rigcal_core::kinematics::{ChainAt, ErrorParams, Robot};

/// A robot at fixed error parameters: a serial chain multiplied out ([`ChainAt`]), any other
/// robot through its [`Robot`] methods.
pub(crate) enum Kinematics<'a> {
    /// A serial chain, allocation-free.
    Chain(ChainAt),
    /// Any robot.
    Generic(&'a dyn Robot, ErrorParams),
}

impl<'a> Kinematics<'a> {
    /// `robot` at parameters `e`.
    pub(crate) fn at(robot: &'a dyn Robot, e: &ErrorParams) -> Self {
        match robot.as_serial_chain() {
            Some(chain) => Kinematics::Chain(chain.at(e)),
            None => Kinematics::Generic(robot, e.clone()),
        }
    }

    /// The measured point at joint values `q`.
    pub(crate) fn position(&self, q: &[f64]) -> Vector3<f64> {
        match self {
            Kinematics::Chain(c) => c.position(q),
            Kinematics::Generic(r, e) => r.position(q, e),
        }
    }

    /// [`Kinematics::position`] with the joints' sines and cosines when known.
    pub(crate) fn position_trig(&self, q: &[f64], trig: Option<&[[f64; 2]]>) -> Vector3<f64> {
        match (self, trig) {
            (Kinematics::Chain(c), Some(t)) => c.position_trig(q, t),
            _ => self.position(q),
        }
    }

    /// [`Kinematics::position_and_columns`] with the joints' sines and cosines when known.
    pub(crate) fn position_and_columns_trig(
        &self,
        q: &[f64],
        trig: Option<&[[f64; 2]]>,
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        match (self, trig) {
            (Kinematics::Chain(c), Some(t)) => c.position_and_columns_trig(q, t, columns, out),
            _ => self.position_and_columns(q, columns, out),
        }
    }

    /// The measured point and the Jacobian columns of the layout indices `columns` in `out`.
    pub(crate) fn position_and_columns(
        &self,
        q: &[f64],
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        match self {
            Kinematics::Chain(c) => c.position_and_columns(q, columns, out),
            Kinematics::Generic(r, e) => {
                let (p, m) = r.position_and_param_jacobian(q, e);
                for (o, &i) in out.iter_mut().zip(columns) {
                    *o = m.fixed_view::<3, 1>(0, i).into_owned();
                }
                p
            }
        }
    }
}
