//! A serial chain evaluated at fixed error parameters, for the loops that evaluate one
//! parameter set at thousands of poses (identification, the identifiability analysis,
//! compensation).
//!
//! Between two moving joints every elementary motion is constant once the error parameters are
//! fixed, so [`ChainAt`] multiplies them out once: a pose then costs one rigid product and one
//! elementary joint motion per joint, with no allocation. The error-parameter Jacobian columns
//! keep, for each elementary motion, its axis and origin in the frame where its segment starts
//! (the frame just after the joint before it), so a column costs a cross product and a rotation.
//! The results equal [`Robot::position`](super::Robot::position) and
//! [`Robot::position_and_param_jacobian`](super::Robot::position_and_param_jacobian) up to
//! rounding (the products are associated differently).
//!
//! Frames are rotation matrix + translation ([`Rt`](super::rigid::Rt)): an elementary rotation
//! about a local axis touches two columns of the matrix, a translation three numbers.

use super::chain::SerialChain;
use super::params::ErrorParams;
use super::rigid::{Motion, Rt};
use super::Robot;
use nalgebra::Vector3;

/// Segments kept on the stack while a pose is evaluated; longer chains use the heap.
const STACK_SEGMENTS: usize = 10;

/// One moving joint: the constant transform from the frame after the previous joint up to this
/// joint's motion (its nominal value and error included), then the motion by the joint value.
#[derive(Debug, Clone)]
struct JointStep {
    joint: usize,
    offset: Rt,
    motion: Motion,
}

/// Where an error parameter's elementary motion sits: in segment `segment` (the frame after
/// `segment` joints), with its axis `a` and origin `b` in that frame.
#[derive(Debug, Clone, Copy)]
struct ColumnGeometry {
    segment: usize,
    rotation: bool,
    a: Vector3<f64>,
    b: Vector3<f64>,
}

/// A [`SerialChain`] at fixed error parameters: positions and Jacobian columns at any joint
/// values, without allocating (see the module docs).
#[derive(Debug, Clone)]
pub struct ChainAt {
    steps: Vec<JointStep>,
    /// The measured point in the frame after the last joint.
    tail: Vector3<f64>,
    /// Per layout index.
    columns: Vec<ColumnGeometry>,
    /// Layout index of each joint's own motion (θ of a revolute joint, d of a prismatic one).
    joint_params: Vec<usize>,
}

impl SerialChain {
    /// The chain at error parameters `e`, multiplied out for fast evaluation at many poses.
    pub fn at(&self, e: &ErrorParams) -> ChainAt {
        let mut steps = Vec::new();
        let mut columns = Vec::with_capacity(self.elems().len());
        let mut joint_params = vec![usize::MAX; self.joints().len()];
        let mut partial = Rt::IDENTITY;
        for el in self.elems() {
            if let Some(p) = &el.prefix {
                partial = partial.then(&Rt::from_isometry(p));
            }
            let value = el.nominal + e.get(el.param);
            let axis_k = match el.motion {
                Motion::Rot(k) | Motion::Trans(k) => k,
            };
            partial.apply_motion(el.motion, value);
            if let Some(j) = el.joint {
                steps.push(JointStep {
                    joint: j,
                    offset: partial,
                    motion: el.motion,
                });
                joint_params[j] = el.param;
                partial = Rt::IDENTITY;
            }
            columns.push(ColumnGeometry {
                segment: steps.len(),
                rotation: matches!(el.motion, Motion::Rot(_)),
                a: partial.r.column(axis_k).into_owned(),
                b: partial.t,
            });
        }
        ChainAt {
            steps,
            tail: partial.t,
            columns,
            joint_params,
        }
    }
}

impl ChainAt {
    /// Number of error parameters (the chain's layout length).
    pub fn params(&self) -> usize {
        self.columns.len()
    }

    /// The measured point (mm) at joint values `q`.
    pub fn position(&self, q: &[f64]) -> Vector3<f64> {
        self.point(q, None)
    }

    /// [`ChainAt::position`] with `trig[j]` = [sin q_j, cos q_j] given ([`joint_trig`]), for a
    /// pose evaluated at many parameter sets.
    pub fn position_trig(&self, q: &[f64], trig: &[[f64; 2]]) -> Vector3<f64> {
        self.point(q, Some(trig))
    }

    /// The measured point and the Jacobian columns of the layout indices `columns` (mm per
    /// internal unit), written to `out[k]` for `columns[k]`.
    ///
    /// # Panics
    /// When `out` is shorter than `columns` or an index is outside the layout.
    pub fn position_and_columns(
        &self,
        q: &[f64],
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        self.point_and_columns(q, None, columns, out)
    }

    /// [`ChainAt::position_and_columns`] with the joints' sines and cosines given.
    pub fn position_and_columns_trig(
        &self,
        q: &[f64],
        trig: &[[f64; 2]],
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        self.point_and_columns(q, Some(trig), columns, out)
    }

    /// The frame after step `s` from the frame `t` after the step before.
    fn advance(&self, s: usize, t: &Rt, q: &[f64], trig: Option<&[[f64; 2]]>) -> Rt {
        let step = &self.steps[s];
        let mut next = if s == 0 {
            step.offset
        } else {
            t.then(&step.offset)
        };
        let v = q[step.joint];
        match (step.motion, trig) {
            (Motion::Rot(k), Some(trig)) => {
                let [sin, cos] = trig[step.joint];
                next.rotate_local(k, sin, cos);
            }
            (m, _) => next.apply_motion(m, v),
        }
        next
    }

    fn point(&self, q: &[f64], trig: Option<&[[f64; 2]]>) -> Vector3<f64> {
        let mut t = Rt::IDENTITY;
        for s in 0..self.steps.len() {
            t = self.advance(s, &t, q, trig);
        }
        t.t + t.r * self.tail
    }

    fn point_and_columns(
        &self,
        q: &[f64],
        trig: Option<&[[f64; 2]]>,
        columns: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        let n = self.steps.len() + 1;
        let mut stack = [Rt::IDENTITY; STACK_SEGMENTS];
        let mut heap = Vec::new();
        let frames: &mut [Rt] = if n <= STACK_SEGMENTS {
            &mut stack[..n]
        } else {
            heap.resize(n, Rt::IDENTITY);
            &mut heap
        };
        let mut t = Rt::IDENTITY;
        for s in 0..self.steps.len() {
            t = self.advance(s, &t, q, trig);
            frames[s + 1] = t;
        }
        let p = t.t + t.r * self.tail;
        // The measured point in each segment's frame, for the rotation columns.
        let mut local_stack = [Vector3::zeros(); STACK_SEGMENTS];
        let mut local_heap = Vec::new();
        let local: &mut [Vector3<f64>] = if n <= STACK_SEGMENTS {
            &mut local_stack[..n]
        } else {
            local_heap.resize(n, Vector3::zeros());
            &mut local_heap
        };
        for (l, f) in local.iter_mut().zip(frames.iter()) {
            *l = f.r.tr_mul(&(p - f.t));
        }
        for (o, &i) in out.iter_mut().zip(columns) {
            let g = &self.columns[i];
            let f = &frames[g.segment];
            *o = if g.rotation {
                f.r * g.a.cross(&(local[g.segment] - g.b))
            } else {
                f.r * g.a
            };
        }
        p
    }

    /// The measured point and the joint Jacobian's columns of the joints `joints` (0-based),
    /// written to `out[k]` for `joints[k]`.
    pub fn position_and_joint_columns(
        &self,
        q: &[f64],
        joints: &[usize],
        out: &mut [Vector3<f64>],
    ) -> Vector3<f64> {
        let mut cols = [0usize; STACK_SEGMENTS];
        if joints.len() > STACK_SEGMENTS {
            let cols: Vec<usize> = joints.iter().map(|&j| self.joint_params[j]).collect();
            return self.position_and_columns(q, &cols, out);
        }
        for (c, &j) in cols.iter_mut().zip(joints) {
            *c = self.joint_params[j];
        }
        self.position_and_columns(q, &cols[..joints.len()], out)
    }
}

/// Writes [sin q_j, cos q_j] of every joint value to `out` (for
/// [`ChainAt::position_trig`] and [`ChainAt::position_and_columns_trig`]; prismatic joints'
/// entries are not read).
pub fn joint_trig(q: &[f64], out: &mut [[f64; 2]]) {
    for (o, v) in out.iter_mut().zip(q) {
        let (s, c) = v.sin_cos();
        *o = [s, c];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{JointKind, JointSpec, LinkParams, Robot, Transform};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// A chain with a prismatic joint, a pose base and tool and a non-trivial frame.
    fn chain() -> SerialChain {
        let j = |name: &str, kind| JointSpec {
            name: name.into(),
            kind,
            min: -3.0,
            max: 3.0,
        };
        let link = |theta, d, a, alpha, beta| LinkParams {
            theta,
            d,
            a,
            alpha,
            beta,
        };
        SerialChain::new(
            vec![
                j("J1", JointKind::Revolute),
                j("J2", JointKind::Prismatic),
                j("J3", JointKind::Revolute),
            ],
            Transform::Pose(Isometry3::from_parts(
                Translation3::new(10.0, -20.0, 300.0),
                UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
            )),
            vec![
                link(0.1, 50.0, 120.0, -1.2, 0.0),
                link(0.0, 10.0, 250.0, 0.3, 0.02),
                link(-0.4, 0.0, 200.0, 1.5, -0.01),
            ],
            Transform::FivePar(link(0.2, 5.0, 170.0, 0.1, 0.05)),
            Isometry3::from_parts(
                Translation3::new(-3.0, 4.0, 5.0),
                UnitQuaternion::from_euler_angles(0.01, 0.02, -0.03),
            ),
            Vector3::new(1.0, 2.0, 3.0),
        )
    }

    fn params(c: &SerialChain) -> ErrorParams {
        let mut e = ErrorParams::zeros(c.layout());
        for i in 0..e.len() {
            e.set(i, 0.01 * ((i * 7 % 11) as f64 - 5.0));
        }
        e
    }

    #[test]
    fn positions_and_columns_equal_the_elementwise_walk() {
        let c = chain();
        let e = params(&c);
        let at = c.at(&e);
        let all: Vec<usize> = (0..c.layout().len()).collect();
        let mut cols = vec![Vector3::zeros(); all.len()];
        for q in [[0.0, 0.0, 0.0], [0.7, 33.0, -1.1], [-2.5, -12.0, 2.9]] {
            let (p, m) = c.position_and_param_jacobian(&q, &e);
            assert!((at.position(&q) - p).norm() < 1e-9);
            let p2 = at.position_and_columns(&q, &all, &mut cols);
            assert!((p2 - p).norm() < 1e-9);
            for (k, col) in cols.iter().enumerate() {
                assert!((col - m.column(k)).norm() < 1e-9, "column {k}");
            }
            let mut trig = [[0.0; 2]; 3];
            joint_trig(&q, &mut trig);
            assert!((at.position_trig(&q, &trig) - p).norm() < 1e-9);
            let p3 = at.position_and_columns_trig(&q, &trig, &all, &mut cols);
            assert!((p3 - p).norm() < 1e-9);
            for (k, col) in cols.iter().enumerate() {
                assert!((col - m.column(k)).norm() < 1e-9, "column {k} (trig)");
            }
            let jj = c.joint_jacobian(&q, &e);
            let mut jc = vec![Vector3::zeros(); 3];
            at.position_and_joint_columns(&q, &[0, 1, 2], &mut jc);
            for (k, col) in jc.iter().enumerate() {
                assert!((col - jj.column(k)).norm() < 1e-9, "joint {k}");
            }
        }
    }

    #[test]
    fn columns_are_derivatives() {
        // Central differences of the position in each parameter, independent of the geometry.
        let c = chain();
        let e = params(&c);
        let q = [0.4, 20.0, -0.8];
        let all: Vec<usize> = (0..c.layout().len()).collect();
        let mut cols = vec![Vector3::zeros(); all.len()];
        c.at(&e).position_and_columns(&q, &all, &mut cols);
        for (i, col) in cols.iter().enumerate() {
            let h = 1e-6;
            let mut ep = e.clone();
            let mut em = e.clone();
            ep.set(i, e.get(i) + h);
            em.set(i, e.get(i) - h);
            let d = (c.at(&ep).position(&q) - c.at(&em).position(&q)) / (2.0 * h);
            assert!((d - col).norm() < 1e-5 * (1.0 + col.norm()), "param {i}");
        }
    }
}
