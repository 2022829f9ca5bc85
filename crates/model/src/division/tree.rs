//! The region tree of the variable D-H model and its use as an [`ErrorModel`].
//! CEP values are stored in internal units (mm, rad), in the order of `basis`.

use super::space::{Bounds, DivisionSpace, Space};
use rigcal_core::kinematics::{ErrorModel, ErrorParams};
use serde::{Deserialize, Serialize};

/// Test of a region's CEPs: position error after compensation (or prediction) at test points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RegionTest {
    /// Test points.
    pub n: usize,
    /// Largest error (mm).
    pub max_mm: f64,
    /// RMS error (mm).
    pub rms_mm: f64,
    /// Upper confidence bound of the region's largest error from its test points
    /// ([`super::confidence`]); absent in models made before it (and offline, where the
    /// held-out points are too few to fit it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bound_mm: Option<f64>,
}

impl RegionTest {
    /// What the region is judged on: its confidence bound where it has one, else its largest
    /// test error (the paper's rule).
    pub fn verdict_mm(&self) -> f64 {
        self.bound_mm.unwrap_or(self.max_mm).max(self.max_mm)
    }
}

/// A region: a box, its CEPs, and its halves once split.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionNode {
    /// Path from the root: `r`, `r0`, `r01`, …
    pub id: String,
    /// The box.
    pub bounds: Bounds,
    /// CEPs (internal units, basis order); None for a region without usable measurements.
    pub cep: Option<Vec<f64>>,
    /// κ of eq. (4) of the region's identification; infinite (`null` in a file) for a region
    /// never identified.
    #[serde(
        serialize_with = "infinite_is_null",
        deserialize_with = "null_is_infinite"
    )]
    pub kappa: f64,
    /// Measurements used.
    pub measurements: usize,
    /// Test outcome.
    pub test: Option<RegionTest>,
    /// Why the region was not split further, when it missed the accuracy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// For a region that could not be measured (seed 000 Fig. 8): the neighbouring regions
    /// whose CEPs it takes the mean of. No measurement lies inside it, and learners are not
    /// trained on it: they generalise there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub borrowed_from: Option<Vec<String>>,
    /// The CEPs a learner is trained on here: the region's CEPs with the part of their
    /// deviation from its parent's that its own measurements cannot see put back to the
    /// parent's ([`DivisionOptions::learner_tolerance`](super::DivisionOptions)); None: the
    /// CEPs themselves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learner_cep: Option<Vec<f64>>,
    /// The two halves, once split.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub children: Vec<RegionNode>,
}

/// JSON has no infinity: an infinite κ (a region never identified) is written as `null` on
/// purpose, so a check for non-finite numbers in a model file does not take it for a broken fit.
fn infinite_is_null<S: serde::Serializer>(kappa: &f64, s: S) -> Result<S::Ok, S::Error> {
    if kappa.is_finite() {
        s.serialize_some(kappa)
    } else {
        s.serialize_none()
    }
}

/// JSON has no infinity: serde_json writes it as `null`, read back here as infinite.
fn null_is_infinite<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

impl RegionNode {
    /// A region with no CEPs yet.
    pub fn unidentified(id: String, bounds: Bounds) -> Self {
        Self {
            id,
            bounds,
            cep: None,
            kappa: f64::INFINITY,
            measurements: 0,
            test: None,
            note: None,
            borrowed_from: None,
            learner_cep: None,
            children: Vec::new(),
        }
    }

    /// True for a leaf.
    pub fn is_leaf(&self) -> bool {
        self.children.is_empty()
    }

    /// True for a region whose CEPs were identified from its own measurements.
    pub fn is_measured(&self) -> bool {
        self.cep.is_some() && self.borrowed_from.is_none()
    }

    /// The leaves below (or this node).
    pub fn leaves(&self) -> Vec<&RegionNode> {
        if self.is_leaf() {
            vec![self]
        } else {
            self.children.iter().flat_map(|c| c.leaves()).collect()
        }
    }

    /// Every node, depth first.
    pub fn nodes(&self) -> Vec<&RegionNode> {
        let mut v = vec![self];
        for c in &self.children {
            v.extend(c.nodes());
        }
        v
    }

    /// The deepest node containing `x` that has CEPs.
    pub fn lookup(&self, x: &[f64; 3], full: &Bounds) -> Option<&RegionNode> {
        let own = self.cep.as_ref().map(|_| self);
        for c in &self.children {
            if c.bounds.contains(x, full) {
                return c.lookup(x, full).or(own);
            }
        }
        own
    }

    /// The leaf containing `x` (whether or not it has CEPs).
    pub fn leaf_at(&self, x: &[f64; 3], full: &Bounds) -> &RegionNode {
        for c in &self.children {
            if c.bounds.contains(x, full) {
                return c.leaf_at(x, full);
            }
        }
        self
    }
}

/// A division: the space, the basis the CEPs are given in, and the tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionTree {
    /// Joint or Cartesian.
    pub space: Space,
    /// The whole workspace.
    pub full: Bounds,
    /// Parameter names of the CEP vector.
    pub basis: Vec<String>,
    /// The root region (the whole workspace).
    pub root: RegionNode,
}

impl RegionTree {
    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.root.leaves().len()
    }

    /// The leaves that could not be measured (seed 000 Fig. 8).
    pub fn unmeasurable(&self) -> Vec<&RegionNode> {
        self.root
            .leaves()
            .into_iter()
            .filter(|l| l.borrowed_from.is_some())
            .collect()
    }
}

/// A region tree as an error model: the CEPs of the region a pose falls in.
pub struct RegionModel {
    tree: RegionTree,
    space: DivisionSpace,
    basis: Vec<usize>,
    n_params: usize,
}

impl RegionModel {
    /// Joins a tree with its division space; `basis` are layout indices of the CEP vector and
    /// `n_params` the layout's length.
    pub fn new(tree: RegionTree, space: DivisionSpace, basis: Vec<usize>, n_params: usize) -> Self {
        Self {
            tree,
            space,
            basis,
            n_params,
        }
    }

    /// The tree.
    pub fn tree(&self) -> &RegionTree {
        &self.tree
    }

    /// The division space.
    pub fn space(&self) -> &DivisionSpace {
        &self.space
    }

    /// Expands a CEP vector into full error parameters.
    pub fn expand(&self, cep: &[f64]) -> ErrorParams {
        expand(&self.basis, self.n_params, cep)
    }
}

/// Expands basis values into a full parameter vector of length `n`.
pub fn expand(basis: &[usize], n: usize, cep: &[f64]) -> ErrorParams {
    let mut e = ErrorParams::from_vector(nalgebra::DVector::zeros(n));
    for (&i, &v) in basis.iter().zip(cep) {
        e.set(i, v);
    }
    e
}

impl ErrorModel for RegionModel {
    fn params_at(&self, q: &[f64]) -> ErrorParams {
        let x = self.space.coords(q);
        match self
            .tree
            .root
            .lookup(&x, &self.tree.full)
            .and_then(|n| n.cep.as_ref())
        {
            Some(cep) => self.expand(cep),
            None => ErrorParams::from_vector(nalgebra::DVector::zeros(self.n_params)),
        }
    }
}
