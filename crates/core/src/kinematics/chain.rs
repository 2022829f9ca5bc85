//! The serial chain: N joints, revolute or prismatic, between a fixed base and a fixed tool,
//! seen through a measurement frame and ending at a marker point. See the module docs of
//! [`crate::kinematics`] for the convention.

use super::ik::{solve_position_ik, IkOptions};
use super::joint::{JointKind, JointSpec};
use super::params::{ErrorParams, ParamId, ParamKind, ParamLayout, TransformId};
use super::pose::{newton_inverse, KinematicsError, NEWTON_ITERATIONS, NEWTON_TOLERANCE};
use super::rigid::{Motion, Rt};
use super::Robot;
use nalgebra::{DMatrix, Isometry3, Translation3, UnitQuaternion, Vector3};

/// Five-parameter link values (radians, millimetres).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LinkParams {
    /// Rotation about z (rad); a revolute joint adds its value here.
    pub theta: f64,
    /// Translation along z (mm); a prismatic joint adds its value here.
    pub d: f64,
    /// Translation along x (mm).
    pub a: f64,
    /// Rotation about x (rad).
    pub alpha: f64,
    /// Rotation about y (rad), used between parallel joints (Hayati).
    pub beta: f64,
}

/// A fixed transform (base or tool): five parameters, or a pose.
#[derive(Debug, Clone, PartialEq)]
pub enum Transform {
    /// Rz(θ)·Tz(d)·Tx(a)·Rx(α)·Ry(β); error kinds θ d a α β.
    FivePar(LinkParams),
    /// A pose; error kinds x y z rz ry rx applied after it.
    Pose(Isometry3<f64>),
}

/// One elementary motion of the chain, carrying error parameter `param` (its layout index,
/// which is also its position in the element list).
#[derive(Debug, Clone)]
pub(super) struct Elem {
    pub(super) prefix: Option<Isometry3<f64>>,
    pub(super) motion: Motion,
    pub(super) nominal: f64,
    pub(super) param: usize,
    pub(super) joint: Option<usize>,
}

/// World-frame axis and origin of every elementary motion, and the measured point.
struct Walk {
    axes: Vec<(Vector3<f64>, Vector3<f64>)>,
    point: Vector3<f64>,
}

/// A serial chain with its error-parameter layout. Immutable once built.
#[derive(Debug, Clone)]
pub struct SerialChain {
    joints: Vec<JointSpec>,
    frame: Isometry3<f64>,
    base: Transform,
    links: Vec<LinkParams>,
    tool: Transform,
    marker: Vector3<f64>,
    layout: ParamLayout,
    elems: Vec<Elem>,
}

impl SerialChain {
    /// Builds a chain. `links[i]` belongs to `joints[i]`; `frame` is the nominal measurement
    /// frame (identity for measurements in world coordinates), `marker` the nominal measured
    /// point in the tool frame.
    ///
    /// # Panics
    /// When `links` and `joints` differ in length (a programming error; the rig file validation
    /// reports it to users first).
    pub fn new(
        joints: Vec<JointSpec>,
        base: Transform,
        links: Vec<LinkParams>,
        tool: Transform,
        frame: Isometry3<f64>,
        marker: Vector3<f64>,
    ) -> Self {
        assert_eq!(joints.len(), links.len(), "one link per joint");
        let mut ids = Vec::new();
        let mut elems = Vec::new();
        let push = |ids: &mut Vec<ParamId>,
                    elems: &mut Vec<Elem>,
                    prefix: Option<Isometry3<f64>>,
                    transform: TransformId,
                    kind: ParamKind,
                    nominal: f64,
                    joint: Option<usize>| {
            ids.push(ParamId { transform, kind });
            elems.push(Elem {
                prefix,
                motion: motion_of(kind),
                nominal,
                param: ids.len() - 1,
                joint,
            });
        };
        let pose_kinds = [
            ParamKind::X,
            ParamKind::Y,
            ParamKind::Z,
            ParamKind::Rz,
            ParamKind::Ry,
            ParamKind::Rx,
        ];
        for (k, kind) in pose_kinds.iter().enumerate() {
            let prefix = (k == 0).then_some(frame);
            push(
                &mut ids,
                &mut elems,
                prefix,
                TransformId::Frame,
                *kind,
                0.0,
                None,
            );
        }
        let push_fixed =
            |ids: &mut Vec<ParamId>, elems: &mut Vec<Elem>, t: &Transform, id: TransformId| match t
            {
                Transform::FivePar(p) => {
                    for (kind, v) in five_par_values(p) {
                        push(ids, elems, None, id, kind, v, None);
                    }
                }
                Transform::Pose(pose) => {
                    for (k, kind) in pose_kinds.iter().enumerate() {
                        let prefix = (k == 0).then_some(*pose);
                        push(ids, elems, prefix, id, *kind, 0.0, None);
                    }
                }
            };
        push_fixed(&mut ids, &mut elems, &base, TransformId::Base);
        for (i, (link, joint)) in links.iter().zip(&joints).enumerate() {
            for (kind, v) in five_par_values(link) {
                let moves = match joint.kind {
                    JointKind::Revolute => kind == ParamKind::Theta,
                    JointKind::Prismatic => kind == ParamKind::D,
                };
                let j = moves.then_some(i);
                ids.push(ParamId {
                    transform: TransformId::Link(i + 1),
                    kind,
                });
                elems.push(Elem {
                    prefix: None,
                    motion: motion_of(kind),
                    nominal: v,
                    param: ids.len() - 1,
                    joint: j,
                });
            }
        }
        push_fixed(&mut ids, &mut elems, &tool, TransformId::Tool);
        for (k, kind) in [ParamKind::X, ParamKind::Y, ParamKind::Z]
            .iter()
            .enumerate()
        {
            ids.push(ParamId {
                transform: TransformId::Marker,
                kind: *kind,
            });
            elems.push(Elem {
                prefix: None,
                motion: Motion::Trans(k),
                nominal: marker[k],
                param: ids.len() - 1,
                joint: None,
            });
        }
        let layout = ParamLayout::new(ids, joints.len());
        Self {
            joints,
            frame,
            base,
            links,
            tool,
            marker,
            layout,
            elems,
        }
    }

    /// The elementary motions in chain order (element i carries layout parameter i).
    pub(super) fn elems(&self) -> &[Elem] {
        &self.elems
    }

    /// The nominal measurement frame.
    pub fn frame(&self) -> &Isometry3<f64> {
        &self.frame
    }

    /// The base transform.
    pub fn base(&self) -> &Transform {
        &self.base
    }

    /// The link parameters, one per joint.
    pub fn links(&self) -> &[LinkParams] {
        &self.links
    }

    /// The tool transform.
    pub fn tool(&self) -> &Transform {
        &self.tool
    }

    /// The same chain seen through another nominal measurement frame.
    pub fn with_frame(&self, frame: Isometry3<f64>) -> Self {
        Self::new(
            self.joints.clone(),
            self.base.clone(),
            self.links.clone(),
            self.tool.clone(),
            frame,
            self.marker,
        )
    }

    /// World pose of the frame before joint `j`'s motion (0-based), i.e. the frame in which the
    /// joint's axis is local z. With `j == dof()` it is the tool frame (before the marker).
    pub fn frame_before_joint(&self, q: &[f64], e: &ErrorParams, j: usize) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for el in &self.elems {
            if el.joint == Some(j) {
                return t;
            }
            if self.layout.ids()[el.param].transform == TransformId::Marker {
                return t;
            }
            t = self.apply(t, el, q, e);
        }
        t
    }

    /// [`Self::frame_before_joint`] for every joint `0..=n` (n joints; index n is the frame
    /// past the last joint, before the marker) in one pass along the chain: the same products
    /// in the same order, so each equals `frame_before_joint(q, e, j)` exactly, at the cost of
    /// one pose instead of n.
    pub fn frames_before_joints(&self, q: &[f64], e: &ErrorParams) -> Vec<Isometry3<f64>> {
        let n = self.joints.len();
        let mut frames: Vec<Option<Isometry3<f64>>> = vec![None; n + 1];
        let mut t = Isometry3::identity();
        for el in &self.elems {
            if self.layout.ids()[el.param].transform == TransformId::Marker {
                break;
            }
            if let Some(j) = el.joint {
                if j <= n && frames[j].is_none() {
                    frames[j] = Some(t);
                }
            }
            t = self.apply(t, el, q, e);
        }
        frames.into_iter().map(|f| f.unwrap_or(t)).collect()
    }

    /// The measurement frame F with its error parameters applied (maps world to instrument).
    pub fn frame_pose(&self, e: &ErrorParams) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for el in &self.elems {
            if self.layout.ids()[el.param].transform != TransformId::Frame {
                break;
            }
            t = self.apply(t, el, &[], e);
        }
        t
    }

    /// World pose of the tool frame (the marker's frame), measured frame F included.
    pub fn tool_pose(&self, q: &[f64], e: &ErrorParams) -> Isometry3<f64> {
        self.frame_before_joint(q, e, usize::MAX)
    }

    /// The measured point, the tool frame's rotation and their Jacobian with respect to every
    /// error parameter, all in the measurement frame (as [`Robot::position`] and
    /// [`SerialChain::tool_pose`]): rows 0–2 of the 6 × L matrix are the point's columns (mm per
    /// unit), rows 3–5 the tool frame's angular change per unit of the parameter (the axis of
    /// a rotation parameter in the measurement frame, zero for a translation; rad per unit), so
    /// R(e + δ·eᵢ) ≈ exp([ωᵢ·δ]×)·R(e). Orientation measurements (a 6-DoF probe) fit with it.
    pub fn pose_and_param_jacobian(
        &self,
        q: &[f64],
        e: &ErrorParams,
    ) -> (Vector3<f64>, UnitQuaternion<f64>, DMatrix<f64>) {
        let w = self.walk(q, e, true);
        let rotation = self.tool_pose(q, e).rotation;
        let mut m = DMatrix::zeros(6, self.layout.len());
        for (el, axis) in self.elems.iter().zip(&w.axes) {
            let c = self.column(el, axis, &w.point);
            m.fixed_view_mut::<3, 1>(0, el.param).copy_from(&c);
            if let Motion::Rot(_) = el.motion {
                m.fixed_view_mut::<3, 1>(3, el.param).copy_from(&axis.0);
            }
        }
        (w.point, rotation, m)
    }

    fn apply(&self, t: Isometry3<f64>, el: &Elem, q: &[f64], e: &ErrorParams) -> Isometry3<f64> {
        let mut t = match el.prefix {
            Some(p) => t * p,
            None => t,
        };
        let mut v = el.nominal + e.get(el.param);
        if let Some(j) = el.joint {
            v += q[j];
        }
        t *= elementary(el.motion, v);
        t
    }

    fn walk(&self, q: &[f64], e: &ErrorParams, need_axes: bool) -> Walk {
        debug_assert_eq!(q.len(), self.joints.len());
        let mut t = Rt::IDENTITY;
        let mut axes = Vec::with_capacity(if need_axes { self.elems.len() } else { 0 });
        for el in &self.elems {
            if let Some(p) = &el.prefix {
                t = t.then(&Rt::from_isometry(p));
            }
            let mut v = el.nominal + e.get(el.param);
            if let Some(j) = el.joint {
                v += q[j];
            }
            t.apply_motion(el.motion, v);
            if need_axes {
                let k = match el.motion {
                    Motion::Rot(k) | Motion::Trans(k) => k,
                };
                axes.push((t.r.column(k).into_owned(), t.t));
            }
        }
        Walk { axes, point: t.t }
    }

    fn column(
        &self,
        el: &Elem,
        axis: &(Vector3<f64>, Vector3<f64>),
        p: &Vector3<f64>,
    ) -> Vector3<f64> {
        let (w, o) = axis;
        match el.motion {
            Motion::Rot(_) => w.cross(&(p - o)),
            Motion::Trans(_) => *w,
        }
    }
}

impl Robot for SerialChain {
    fn joints(&self) -> &[JointSpec] {
        &self.joints
    }

    fn as_serial_chain(&self) -> Option<&SerialChain> {
        Some(self)
    }

    /// A local Newton step from the guess first (it keeps the branch), then the global search
    /// of [`solve_position_ik`] seeded with the guess, nominal chain, no joint held.
    fn inverse(&self, s: &[f64], guess: &[f64]) -> Result<Vec<f64>, KinematicsError> {
        if let Ok(q) = newton_inverse(self, s, guess, NEWTON_TOLERANCE, NEWTON_ITERATIONS) {
            return Ok(q);
        }
        let target = Vector3::new(s[0], s[1], s[2]);
        let held = vec![None; self.joints.len()];
        solve_position_ik(
            self,
            &ErrorParams::zeros(&self.layout),
            &target,
            &held,
            Some(guess),
            &IkOptions::default(),
        )
        .map_err(|e| KinematicsError::Unreachable {
            pose: s.to_vec(),
            reason: e.to_string(),
        })
    }

    /// The nominal joint Jacobian (analytic).
    fn pose_jacobian(&self, q: &[f64]) -> Result<DMatrix<f64>, KinematicsError> {
        Ok(self.joint_jacobian(q, &ErrorParams::zeros(&self.layout)))
    }

    fn layout(&self) -> &ParamLayout {
        &self.layout
    }

    fn position(&self, q: &[f64], e: &ErrorParams) -> Vector3<f64> {
        self.walk(q, e, false).point
    }

    fn position_and_param_jacobian(
        &self,
        q: &[f64],
        e: &ErrorParams,
    ) -> (Vector3<f64>, DMatrix<f64>) {
        let w = self.walk(q, e, true);
        let mut m = DMatrix::zeros(3, self.layout.len());
        for (el, axis) in self.elems.iter().zip(&w.axes) {
            let c = self.column(el, axis, &w.point);
            m.fixed_view_mut::<3, 1>(0, el.param).copy_from(&c);
        }
        (w.point, m)
    }

    fn joint_jacobian(&self, q: &[f64], e: &ErrorParams) -> DMatrix<f64> {
        let w = self.walk(q, e, true);
        let mut m = DMatrix::zeros(3, self.joints.len());
        for (el, axis) in self.elems.iter().zip(&w.axes) {
            if let Some(j) = el.joint {
                let c = self.column(el, axis, &w.point);
                m.fixed_view_mut::<3, 1>(0, j).copy_from(&c);
            }
        }
        m
    }
}

fn five_par_values(p: &LinkParams) -> [(ParamKind, f64); 5] {
    [
        (ParamKind::Theta, p.theta),
        (ParamKind::D, p.d),
        (ParamKind::A, p.a),
        (ParamKind::Alpha, p.alpha),
        (ParamKind::Beta, p.beta),
    ]
}

fn motion_of(kind: ParamKind) -> Motion {
    match kind {
        ParamKind::Theta | ParamKind::Rz => Motion::Rot(2),
        ParamKind::Alpha | ParamKind::Rx => Motion::Rot(0),
        ParamKind::Beta | ParamKind::Ry => Motion::Rot(1),
        ParamKind::D | ParamKind::Z => Motion::Trans(2),
        ParamKind::A | ParamKind::X => Motion::Trans(0),
        ParamKind::Y => Motion::Trans(1),
    }
}

fn unit(k: usize) -> Vector3<f64> {
    let mut u = Vector3::zeros();
    u[k] = 1.0;
    u
}

fn elementary(m: Motion, v: f64) -> Isometry3<f64> {
    match m {
        Motion::Rot(k) => Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_unchecked(unit(k)), v),
        ),
        Motion::Trans(k) => {
            Isometry3::from_parts(Translation3::from(unit(k) * v), UnitQuaternion::identity())
        }
    }
}
