//! Measurement space analysis (seed 000 section 4): measurement-location selection and the
//! recursive workspace division of the variable D-H parameter model.
//!
//! # Conventions
//! A region is a box in a three-dimensional *division space*: the major joints (the first three
//! moving joints, rad) or spherical workspace coordinates (R mm, azimuth rad, elevation rad,
//! [`rigcal_core::kinematics::SphericalFrame`]) of the nominal position of a pose. A region splits into
//! two equal halves across its widest dimension, widths measured as fractions of that dimension's
//! full range; ties go to the first dimension (conventions §5). At the region cap the region with
//! the worst test error splits first.
//!
//! Each region's calibrated error parameters (CEPs) are the identifiable basis of the rig,
//! fitted from the measurements that fall in the region with a weak prior towards its parent's
//! CEPs. That prior is weak (σ 0.5 mm, 0.1°): in a small region (κ up to 1e10) the CEPs still
//! wander along directions that move its predicted points by micrometres. The region model
//! keeps them (they cancel inside the region); a learner can instead be trained on
//! [`RegionNode::learner_cep`], where what a region's measurements cannot see is put back to
//! its parent's ([`DivisionOptions::learner_tolerance`]).

pub mod confidence;
pub mod design;
mod planner;
pub mod select;
mod space;
mod tree;

pub use planner::{
    divide, DivisionError, DivisionOptions, DivisionReport, MeasureError, Measurer, Mode,
    SplitOrder, TestPlan, CONFIDENCE_Z,
};
pub use select::Selection;
pub use space::{Bounds, DivisionSpace, Space};
pub use tree::{expand as tree_expand, RegionModel, RegionNode, RegionTest, RegionTree};
