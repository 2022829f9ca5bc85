//! The recursive workspace division algorithm (seed 000 section 4.2) and measurement-location
//! selection (section 4.1).
//!
//! Step 1: the whole workspace is one region. Step 2: choose measurement locations (measurable,
//! κ of eq. (4) small) and identify the region's CEPs. Step 3: test them at random points with
//! compensation. Step 4: a region that misses the demanded accuracy splits into two equal halves,
//! worst first, until every region passes, the region cap is reached, or a region is too small
//! (or too ill-conditioned) to identify.
//!
//! *Planning* mode asks a [`Measurer`] (the simulated world, or the rig) for each measurement;
//! a half keeps the measurements of its parent that fall in it and adds new ones up to the
//! per-region count. Test points are measured at the compensated command: the error is
//! measured − target. *Offline* mode works from a recording: a region uses the points that fall
//! in it, every fifth held out to test (prediction error), all of them in its final fit.

use super::confidence::{self, TestError};
use super::design;
use super::select::{self, Selection};
use super::space::{Bounds, DivisionSpace, Space, SpaceError};
use super::tree::{expand, RegionNode, RegionTest, RegionTree};
use crate::compensation::{compensate_from, CompensationOptions};
use crate::identification::{fit, FitOptions, FitResult, Observation, Prior};
use nalgebra::{DMatrix, DVector};
use rand::rngs::ChaCha8Rng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rigcal_core::kinematics::{ErrorParams, Robot};
use rigcal_core::rig::Rig;

/// Something that measures the arm: the simulated world or the rig.
pub trait Measurer {
    /// A measurement with the arm sent to `q`: the joints actually commanded (a controller
    /// rounds them to its resolution) and the measured point (world, mm); `Ok(None)` when this
    /// measurement failed (no contact, out of reach of the instrument) and the division may go
    /// on without it; `Err` when the measurer cannot go on at all (a rig fault that stopped
    /// the session): the division stops at once and returns it.
    fn measure(&mut self, q: &[f64]) -> Result<Option<Observation>, MeasureError>;

    /// Measurements at every location of one batch — a region's measurement locations, or its
    /// test points — with the answers in the order asked. The default measures them one at a
    /// time in that order; a session orders the batch for its rig (z-ascending, then x-y) and
    /// measures it as one sequence. A stopped measurer stops the whole batch.
    fn measure_batch(&mut self, qs: &[Vec<f64>]) -> Result<Vec<Option<Observation>>, MeasureError> {
        qs.iter().map(|q| self.measure(q)).collect()
    }
}

/// Rounds of replacements for the locations of a region's batch that turned out not
/// measurable (skipped after their attempts, or refused); each round selects new locations in
/// the same region with κ re-checked against what was measured.
pub const REPLACEMENT_ROUNDS: usize = 3;

/// A measurer that cannot go on (e.g. the session's rig stopped on a fault); the cause is kept
/// as the error's source, so a caller can downcast it to its own type.
#[derive(Debug, thiserror::Error)]
#[error("measuring stopped: {source}")]
pub struct MeasureError {
    /// The cause (e.g. a [`SessionError`](rigcal_devices::session::SessionError)).
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync>,
}

impl MeasureError {
    /// Wraps the measurer's own error.
    pub fn new(source: impl std::error::Error + Send + Sync + 'static) -> Self {
        MeasureError {
            source: Box::new(source),
        }
    }
}

/// Where the measurements come from.
pub enum Mode<'a> {
    /// The division asks for measurements where it needs them.
    Planning(&'a mut dyn Measurer),
    /// The division uses the points of a recording that fall in each region.
    Offline(&'a [Observation]),
}

/// Settings of the division; defaults are the paper's. Seventeen fields, flat on purpose: each is
/// one independent knob of the procedure (demand, caps, designs, priors, tests) that callers set
/// by name with `..Default::default()`; grouping them would only add a level to every call.
#[derive(Debug, Clone)]
pub struct DivisionOptions {
    /// Joint or Cartesian (spherical) division.
    pub space: Space,
    /// Demanded accuracy after compensation (mm).
    pub accuracy_mm: f64,
    /// Most regions (leaves).
    pub max_regions: usize,
    /// Measurements per region.
    pub per_region: usize,
    /// Test points per region (planning mode): its corners, its centre, then a Halton set
    /// ([`super::design`]).
    pub test_points: usize,
    /// A region whose measurement locations cannot bring κ below this is not split.
    pub kappa_max: f64,
    /// A region narrower than this fraction of the workspace in any dimension is not split.
    pub min_fraction: f64,
    /// Candidate locations sampled per region for the κ selection.
    pub candidates: usize,
    /// Exchange steps of the κ selection.
    pub exchange_steps: usize,
    /// How a region's measurement locations are chosen: κ of eq. (4) (the paper's) or
    /// D-optimality (det of MᵀM).
    pub selection: Selection,
    /// Planning mode: a half keeps its parent's measurements that fall in it and measures only
    /// the missing ones (true, the default); false measures every region afresh (each fit uses
    /// only the measurements taken for its own region), for comparison.
    pub reuse_parent: bool,
    /// Prior σ of a region's CEPs around its parent's: lengths (mm) and angles (rad).
    pub prior_sigma: (f64, f64),
    /// Measurement noise assumed for weighting the prior (mm).
    pub noise_mm: f64,
    /// Seed of every random choice.
    pub seed: u64,
    /// A box of the division space that cannot be measured (seed 000 Fig. 8): no measurement
    /// location or test point is chosen in it, no recorded point in it is used (offline), the
    /// regions around it split until it is a region of its own, and that region takes the mean
    /// CEPs of its neighbours. Give a region of the division ([`Bounds::region_at`]).
    pub unmeasurable: Option<Bounds>,
    /// A half of a split region that the rig cannot measure enough of (table travel, the pin
    /// rule) becomes a region without measurements of its own — its neighbours' mean CEPs,
    /// the learner generalises there — instead of stopping its parent's split (seed 000
    /// section 7's rig).
    pub unmeasurable_halves: bool,
    /// Planning mode: a region is accepted when the upper confidence bound of its largest
    /// error ([`super::confidence`]) at this many posterior standard deviations meets the
    /// demand, not only its test points' maximum; 0 accepts on the maximum (the paper's rule).
    pub confidence_z: f64,
    /// The CEPs a learner is trained on ([`RegionNode::learner_cep`]): how far, as a fraction
    /// of the demanded accuracy (RMS over a region's measurements), the predicted points may
    /// move when the part of a region's CEP deviation from its parent's that its measurements
    /// cannot see is put back to the parent's; 0 trains the learner on the regions'
    /// least-squares CEPs as they are.
    pub learner_tolerance: f64,
    /// Planning mode: how a region's test is measured ([`TestPlan`]); the default measures
    /// every test point of every region afresh in one batch (the paper's).
    pub test_plan: TestPlan,
    /// The box divided, when not the rig's workspace (its major joints' limits, or its
    /// `[workspace]` bounds): offline, a recording's extent, so a 6-DOF arm with ±360° limits
    /// is not divided over the empty space its recording never reached.
    pub bounds: Option<Bounds>,
    /// Which failing region splits next ([`SplitOrder`]); it matters once the region cap
    /// stops the division with regions still above the demand.
    pub split_order: SplitOrder,
    /// Planning mode: a half whose own measurements cannot separate its CEPs (κ above
    /// [`Self::kappa_max`]) is still identified, its unseen directions held at its parent's
    /// CEPs by the prior, and judged by its test like any other; false stops its parent's split
    /// there (the paper's "too small to identify").
    pub prior_holds_unseen: bool,
    /// A half's CEPs are a MAP estimate around its parent's (the prior of
    /// [`Self::prior_sigma`]; true, rigcal's) or the paper's plain least squares (false, which
    /// also turns [`Self::prior_holds_unseen`] off: nothing holds what a half cannot see).
    pub map_prior: bool,
}

/// Which failing leaf the division splits next.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SplitOrder {
    /// The leaf with the largest test verdict (the paper's "worst first").
    Worst,
    /// The leaf with the largest excess over the demand times its share of the workspace's
    /// volume: at a region cap, the regions left above the demand are the smallest part of the
    /// workspace, not large regions barely above it beside small ones far above it, which
    /// further halving helps little (docs/seeds.md: at Fig. 7's cap of 130 the tuning path's
    /// worst points lay in regions of 1/64–1/128 of the workspace left at 0.12–0.13 mm).
    ExcessVolume,
    /// Between the two: the excess over the demand times the region's size (the cube root of
    /// its volume share), which is how likely a path, a line, is to cross it. The default,
    /// chosen on the tuning set (docs/seeds.md: section 6's claims at ≥ 19 of 20 tuning seeds,
    /// 16 of 22 against 14 worst first and 15 excess × volume); section 7's preset keeps worst
    /// first, chosen there the same way.
    #[default]
    ExcessSize,
}

/// How a region's test points are measured (planning mode): the levers that cut a rig's test
/// measurements (seed 000 section 7's hours) without weakening what a region is accepted on.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TestPlan {
    /// Sequential testing: measure this many test points first and stop the test as soon as
    /// one of them misses the demand (the region fails whatever the rest would show); the
    /// rest follow only for a region still in the running. 0 measures every test point in
    /// one batch.
    pub first_stage: usize,
    /// Evidence from earlier tests: every test measurement of an enclosing region (none of
    /// them ever part of a fit) counts, predicted by this region's CEPs, as one of this
    /// region's test points, and its design locations near one are not measured again.
    pub reuse: bool,
    /// Once the division is made, every measured leaf's CEPs are fitted again on its
    /// identification and its test measurements together (its test, already judged, keeps
    /// the figures of the CEPs it judged): more data for the final model at no measurement's
    /// cost.
    pub refit: bool,
}

/// Design locations this close (unit-cube coordinates, every axis) to an earlier test
/// measurement are taken as tested ([`TestPlan::reuse`]): a quarter of the 3 × 3 × 3 grid's
/// spacing, so a half's grid points on its parent's grid are not measured twice.
const COVERED: f64 = 0.125;

impl Default for DivisionOptions {
    fn default() -> Self {
        Self {
            space: Space::Joint,
            accuracy_mm: 0.1,
            max_regions: 110,
            per_region: 20,
            test_points: 27,
            kappa_max: 1e10,
            min_fraction: 1.0 / 64.0,
            candidates: 60,
            exchange_steps: 60,
            selection: Selection::Kappa,
            reuse_parent: true,
            prior_sigma: (0.5, 0.1f64.to_radians()),
            noise_mm: 0.02,
            seed: 1,
            unmeasurable: None,
            unmeasurable_halves: false,
            confidence_z: CONFIDENCE_Z,
            learner_tolerance: 0.0,
            test_plan: TestPlan::default(),
            bounds: None,
            split_order: SplitOrder::default(),
            prior_holds_unseen: true,
            map_prior: true,
        }
    }
}

/// The default of [`DivisionOptions::confidence_z`]. Chosen on data no reported figure uses
/// (docs/seeds.md: section 6 at seeds 101–120 along paths the figures do not use): z = 1
/// against 2, the one whose regions hold the demand along those paths at more seeds (100
/// passes of 120 against 89; at the region caps a stricter bound leaves more regions unresolved).
/// Accepted regions are held to the demand plus 10 % along the path (tests/division.rs).
pub const CONFIDENCE_Z: f64 = 1.0;

/// Why a division could not be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DivisionError {
    /// The division space does not fit the rig.
    #[error(transparent)]
    Space(#[from] SpaceError),
    /// The measurer stopped (planning mode): the division stopped with it.
    #[error(transparent)]
    Measurement(#[from] MeasureError),
    /// The whole workspace could not be identified.
    #[error(
        "the whole workspace could not be identified from {measurements} measurements: {reason}"
    )]
    Root {
        /// Measurements available.
        measurements: usize,
        /// Why.
        reason: String,
    },
}

/// What a division produced.
pub struct DivisionReport {
    /// The region tree.
    pub tree: RegionTree,
    /// The division space.
    pub space: DivisionSpace,
    /// Conventional calibration on the same identification measurements.
    pub conventional: FitResult,
    /// Identification measurements used.
    pub observations: Vec<Observation>,
    /// Test measurements made (planning mode).
    pub test_measurements: usize,
}

/// A measurement of the division: the observation, its division-space coordinates and the
/// region it was measured for (empty offline).
struct Datum {
    obs: Observation,
    x: [f64; 3],
    region: String,
}

/// A test measurement: the command, the measured point and the division-space coordinates of
/// its target ([`TestPlan::reuse`]).
struct TestDatum {
    obs: Observation,
    x: [f64; 3],
}

/// Why a region was not split: a reason for its note, or a measurer that stopped.
enum SplitError {
    Cannot(String),
    Measure(MeasureError),
}

struct Ctx<'a, 'm> {
    rig: &'a Rig,
    space: DivisionSpace,
    basis: &'a [usize],
    opts: &'a DivisionOptions,
    mode: Mode<'m>,
    data: Vec<Datum>,
    tests: Vec<TestDatum>,
    rng: ChaCha8Rng,
    tests_made: usize,
    n_params: usize,
}

/// Divides the workspace of `rig`, identifying the CEPs of `basis` (layout indices) per region.
pub fn divide(
    rig: &Rig,
    basis: &[usize],
    mode: Mode<'_>,
    opts: &DivisionOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<DivisionReport, DivisionError> {
    let mut space = DivisionSpace::new(rig, opts.space)?;
    if let Some(b) = opts.bounds {
        space.full = b;
    }
    let full = space.full;
    let mut ctx = Ctx {
        rig,
        space,
        basis,
        opts,
        data: Vec::new(),
        tests: Vec::new(),
        rng: ChaCha8Rng::seed_from_u64(opts.seed),
        tests_made: 0,
        n_params: rig.chain.layout().len(),
        mode,
    };
    if let Mode::Offline(obs) = &ctx.mode {
        let obs = obs.to_vec();
        ctx.data = obs
            .into_iter()
            .map(|obs| {
                let x = ctx.space.coords(&obs.q);
                Datum {
                    obs,
                    x,
                    region: String::new(),
                }
            })
            .filter(|d| !ctx.excluded(&d.x))
            .collect();
    }
    let mut root = RegionNode::unidentified("r".into(), full);
    ctx.populate("r", &root.bounds, ctx.opts.per_region.max(3 * basis.len()))?;
    match ctx.identify("r", &root.bounds, None) {
        Ok((cep, kappa, n)) => {
            root.cep = Some(cep);
            root.kappa = kappa;
            root.measurements = n;
        }
        Err(reason) => {
            return Err(DivisionError::Root {
                measurements: ctx.data.len(),
                reason,
            })
        }
    }
    root.test = ctx.test(&root)?;
    let mut leaves = 1;
    progress(leaves, opts.max_regions);
    while leaves < opts.max_regions {
        let Some(path) = next_to_split(&root, opts) else {
            break;
        };
        let node = node_at_mut(&mut root, &path);
        match ctx.split(node) {
            Ok(children) => {
                node.children = children;
                leaves += 1;
                progress(leaves, opts.max_regions);
            }
            Err(SplitError::Cannot(reason)) => node.note = Some(reason),
            Err(SplitError::Measure(e)) => return Err(e.into()),
        }
    }
    for leaf in leaves_mut(&mut root) {
        if leaf.note.is_none() && leaf.test.is_some_and(|t| t.verdict_mm() > opts.accuracy_mm) {
            leaf.note = Some(format!("region cap of {} reached", opts.max_regions));
        }
    }
    if ctx.opts.test_plan.refit && matches!(ctx.mode, Mode::Planning(_)) {
        if let Some(cep) = root.cep.clone() {
            ctx.refit_leaves(&mut root, &cep);
        }
    }
    borrow_neighbour_ceps(&mut root);
    if let Some(cep) = root.cep.clone() {
        ctx.set_learner_ceps(&mut root, &cep);
        root.learner_cep = Some(cep);
    }
    let all: Vec<Observation> = ctx.data.iter().map(|d| d.obs.clone()).collect();
    let conventional = fit(
        &rig.chain,
        &all,
        &ErrorParams::zeros(rig.chain.layout()),
        basis,
        &FitOptions::default(),
    )
    .map_err(|e| DivisionError::Root {
        measurements: all.len(),
        reason: e.to_string(),
    })?;
    let layout = rig.chain.layout();
    Ok(DivisionReport {
        tree: RegionTree {
            space: opts.space,
            full,
            basis: basis
                .iter()
                .map(|&i| layout.name(layout.ids()[i]))
                .collect(),
            root,
        },
        space: ctx.space,
        conventional,
        observations: all,
        test_measurements: ctx.tests_made,
    })
}

/// How many design points a region's test may try, per test point wanted, where the rig's reach
/// cuts regions ([`DivisionOptions::unmeasurable_halves`]).
const TEST_TOP_UP: usize = 8;

/// The leaf to split next: one that holds the unmeasurable box as a part (its test could not
/// look there, so it cannot be accepted until the box is a region of its own), else the failing
/// leaf first in [`DivisionOptions::split_order`].
fn next_to_split(root: &RegionNode, opts: &DivisionOptions) -> Option<Vec<usize>> {
    let accuracy = opts.accuracy_mm;
    let unmeasurable = opts.unmeasurable.as_ref();
    let full = root.bounds;
    fn walk(
        n: &RegionNode,
        path: &mut Vec<usize>,
        judge: &dyn Fn(&RegionNode) -> Option<f64>,
        best: &mut Option<(f64, Vec<usize>)>,
    ) {
        if n.is_leaf() {
            if let Some(e) = judge(n) {
                if best.as_ref().is_none_or(|(b, _)| e > *b) {
                    *best = Some((e, path.clone()));
                }
            }
            return;
        }
        for (i, c) in n.children.iter().enumerate() {
            path.push(i);
            walk(c, path, judge, best);
            path.pop();
        }
    }
    let judge = |n: &RegionNode| -> Option<f64> {
        if n.note.is_some() {
            return None;
        }
        if unmeasurable.is_some_and(|u| n.bounds.encloses(u) && n.bounds != *u) {
            return Some(f64::INFINITY);
        }
        let verdict = n.test.map(|t| t.verdict_mm()).filter(|&e| e > accuracy)?;
        Some(match opts.split_order {
            SplitOrder::Worst => verdict,
            SplitOrder::ExcessVolume => (verdict - accuracy) * n.bounds.volume_share(&full),
            SplitOrder::ExcessSize => (verdict - accuracy) * n.bounds.volume_share(&full).cbrt(),
        })
    };
    let mut best = None;
    walk(root, &mut Vec::new(), &judge, &mut best);
    best.map(|(_, p)| p)
}

/// Gives every unmeasurable leaf the mean CEPs of the measured leaves that share a face with
/// it (seed 000 section 6: "average CEPs derived from CEPs for neighbouring local regions").
fn borrow_neighbour_ceps(root: &mut RegionNode) {
    let measured: Vec<(String, Bounds, Vec<f64>)> = root
        .leaves()
        .into_iter()
        .filter(|l| l.is_measured())
        .filter_map(|l| Some((l.id.clone(), l.bounds, l.cep.clone()?)))
        .collect();
    for leaf in leaves_mut(root) {
        if leaf.borrowed_from.is_none() {
            continue;
        }
        let near: Vec<&(String, Bounds, Vec<f64>)> = measured
            .iter()
            .filter(|(_, b, _)| b.shares_face(&leaf.bounds))
            .collect();
        let Some(first) = near.first() else {
            continue;
        };
        let mut mean = vec![0.0; first.2.len()];
        for (_, _, cep) in &near {
            for (m, v) in mean.iter_mut().zip(cep) {
                *m += v / near.len() as f64;
            }
        }
        leaf.cep = Some(mean);
        leaf.borrowed_from = Some(near.iter().map(|(id, _, _)| id.clone()).collect());
    }
}

fn node_at_mut<'n>(root: &'n mut RegionNode, path: &[usize]) -> &'n mut RegionNode {
    let mut n = root;
    for &i in path {
        n = &mut n.children[i];
    }
    n
}

fn leaves_mut(n: &mut RegionNode) -> Vec<&mut RegionNode> {
    if n.children.is_empty() {
        vec![n]
    } else {
        n.children.iter_mut().flat_map(leaves_mut).collect()
    }
}

impl Ctx<'_, '_> {
    /// True for a point of the unmeasurable box.
    fn excluded(&self, x: &[f64; 3]) -> bool {
        self.opts.unmeasurable.is_some_and(|u| u.holds(x))
    }

    /// [`DivisionSpace::pose_at`], never inside the unmeasurable box.
    fn pose_at(&mut self, b: &Bounds, x: &[f64; 3], seed: Option<&[f64]>) -> Option<Vec<f64>> {
        let q = self.space.pose_at(b, x, &mut self.rng, seed)?;
        (!self.excluded(&self.space.coords(&q))).then_some(q)
    }

    /// [`DivisionSpace::sample`], never inside the unmeasurable box.
    fn sample(&mut self, b: &Bounds, tries: usize, seed: Option<&[f64]>) -> Option<Vec<f64>> {
        (0..tries).find_map(|_| {
            let q = self.space.sample(b, &mut self.rng, 1, seed)?;
            (!self.excluded(&self.space.coords(&q))).then_some(q)
        })
    }

    /// The measurements region `id` (box `b`) may use: those in its box, or, when regions are
    /// measured afresh ([`DivisionOptions::reuse_parent`] false, planning mode), only those
    /// taken for it.
    fn in_box(&self, id: &str, b: &Bounds) -> Vec<&Observation> {
        let own_only = !self.opts.reuse_parent && matches!(self.mode, Mode::Planning(_));
        self.data
            .iter()
            .filter(|d| b.contains(&d.x, &self.space.full))
            .filter(|d| !own_only || d.region == id)
            .map(|d| &d.obs)
            .collect()
    }

    /// Planning mode: adds measurements in `b` until it holds `target` of them, a batch at a
    /// time: the κ-selected locations as one batch, then (for the ones that could not be
    /// measured) replacements selected against what was measured, up to
    /// [`REPLACEMENT_ROUNDS`]. A region still short is left so: its fit says why.
    fn populate(&mut self, id: &str, b: &Bounds, target: usize) -> Result<(), MeasureError> {
        let Mode::Planning(_) = self.mode else {
            return Ok(());
        };
        let mut existing: Vec<Vec<f64>> = self
            .in_box(id, b)
            .into_iter()
            .map(|o| o.q.clone())
            .collect();
        for _ in 0..=REPLACEMENT_ROUNDS {
            if existing.len() >= target {
                break;
            }
            let chosen = self.select(id, b, &existing, target - existing.len());
            if chosen.is_empty() {
                break;
            }
            for obs in self.measure_batch(&chosen)?.into_iter().flatten() {
                let x = self.space.coords(&obs.q);
                existing.push(obs.q.clone());
                self.data.push(Datum {
                    obs,
                    x,
                    region: id.to_string(),
                });
            }
        }
        Ok(())
    }

    /// One batch through the planning-mode measurer (none offline).
    fn measure_batch(&mut self, qs: &[Vec<f64>]) -> Result<Vec<Option<Observation>>, MeasureError> {
        match &mut self.mode {
            Mode::Planning(m) => m.measure_batch(qs),
            Mode::Offline(_) => Ok(vec![None; qs.len()]),
        }
    }

    /// Measurement-location selection: `n` measurable poses in `b` that, with `existing`, make
    /// the region's identification well conditioned, by the rule of
    /// [`DivisionOptions::selection`] ([`select`]).
    fn select(&mut self, id: &str, b: &Bounds, existing: &[Vec<f64>], n: usize) -> Vec<Vec<f64>> {
        let mut pool = self.candidate_pool(id, b, self.opts.candidates.max(n));
        if pool.len() <= n {
            return pool;
        }
        pool.shuffle(&mut self.rng);
        let fixed: Vec<DMatrix<f64>> = existing.iter().map(|q| self.block(q)).collect();
        let blocks: Vec<DMatrix<f64>> = pool.iter().map(|q| self.block(q)).collect();
        let chosen = select::choose(
            self.opts.selection,
            &fixed,
            &blocks,
            n,
            self.opts.exchange_steps,
            &mut self.rng,
        );
        chosen.into_iter().map(|i| pool[i].clone()).collect()
    }

    /// The rows of [M] a measurement at `q` adds: the position Jacobian of the CEPs.
    fn block(&self, q: &[f64]) -> DMatrix<f64> {
        let e = ErrorParams::zeros(self.rig.chain.layout());
        let (_, j) = self.rig.chain.position_and_param_jacobian(q, &e);
        DMatrix::from_fn(3, self.basis.len(), |r, c| j[(r, self.basis[c])])
    }

    /// Measurable candidate locations in `b`: the box's corners, then a Halton set from a
    /// random offset ([`design::candidate_design`]); a location that cannot be measured is
    /// replaced by one drawn at random.
    fn candidate_pool(&mut self, id: &str, b: &Bounds, n: usize) -> Vec<Vec<f64>> {
        let offset = self.rng.random_range(0..1u64 << 20);
        let seed = self.box_seed(id, b);
        let seed = seed.as_deref();
        let mut pool = Vec::with_capacity(n);
        for u in design::candidate_design(n, offset) {
            let q = self
                .pose_at(b, &b.at_unit(&u), seed)
                .or_else(|| self.sample(b, 3, seed));
            pool.extend(q);
        }
        pool
    }

    /// A pose of box `b` for the inverse kinematics of Cartesian locations to start from: a
    /// measurement already in it, else the pose of its centre (None in joint space, which
    /// needs none).
    fn box_seed(&mut self, id: &str, b: &Bounds) -> Option<Vec<f64>> {
        if self.space.space == Space::Joint {
            return None;
        }
        if let Some(o) = self.in_box(id, b).first() {
            return Some(o.q.clone());
        }
        self.pose_at(b, &b.centre(), None)
    }

    /// The prior σ of each CEP (basis order): lengths (mm) and angles (rad).
    fn prior_sigmas(&self) -> Vec<f64> {
        let layout = self.rig.chain.layout();
        self.basis
            .iter()
            .map(|&i| {
                if layout.ids()[i].kind.is_angle() {
                    self.opts.prior_sigma.1
                } else {
                    self.opts.prior_sigma.0
                }
            })
            .collect()
    }

    fn prior(&self, parent: &[f64]) -> Prior {
        let weight = self
            .prior_sigmas()
            .iter()
            .map(|sigma| self.opts.noise_mm / sigma)
            .collect();
        Prior {
            mean: expand(self.basis, self.n_params, parent),
            weight,
        }
    }

    /// Identifies the CEPs of box `b` (offline: leaving every fifth point out when `hold_out`).
    fn fit_box(
        &self,
        id: &str,
        b: &Bounds,
        parent: Option<&[f64]>,
        hold_out: bool,
    ) -> Result<(Vec<f64>, f64, usize), String> {
        let obs: Vec<Observation> = self
            .in_box(id, b)
            .into_iter()
            .enumerate()
            .filter(|(k, _)| !(hold_out && k % 5 == 4))
            .map(|(_, o)| o.clone())
            .collect();
        let min_points = self.min_points();
        if obs.len() < min_points {
            return Err(format!(
                "only {} measurable points in the region ({} needed)",
                obs.len(),
                min_points
            ));
        }
        let mut fo = FitOptions::default();
        let start = match parent {
            Some(p) => {
                if self.opts.map_prior {
                    fo.prior = Some(self.prior(p));
                }
                expand(self.basis, self.n_params, p)
            }
            None => ErrorParams::zeros(self.rig.chain.layout()),
        };
        let r = fit(&self.rig.chain, &obs, &start, self.basis, &fo).map_err(|e| e.to_string())?;
        let held_by_prior = self.opts.prior_holds_unseen
            && self.opts.map_prior
            && parent.is_some()
            && matches!(self.mode, Mode::Planning(_));
        if r.kappa > self.opts.kappa_max && !held_by_prior {
            return Err(format!(
                "κ = {:.2e} exceeds {:.0e}: the region is too small to identify its CEPs",
                r.kappa, self.opts.kappa_max
            ));
        }
        let cep = self.basis.iter().map(|&i| r.params.get(i)).collect();
        // A rank-deficient data Jacobian (κ infinite, a half held by the prior) is recorded as
        // the largest finite κ: model files hold finite numbers only.
        Ok((cep, r.kappa.min(f64::MAX), obs.len()))
    }

    /// Sets [`RegionNode::learner_cep`] below `node` (whose own learner CEPs are `reference`),
    /// top-down: each measured region's CEPs with the part of their deviation from its parent's
    /// learner CEPs that its own measurements cannot see put back to the parent's.
    fn set_learner_ceps(&self, node: &mut RegionNode, reference: &[f64]) {
        for child in &mut node.children {
            let Some(cep) = child.cep.clone() else {
                continue;
            };
            let seen = if child.is_measured() {
                let obs: Vec<Observation> = self
                    .in_box(&child.id, &child.bounds)
                    .into_iter()
                    .cloned()
                    .collect();
                self.seen_part(&obs, &cep, reference)
            } else {
                cep
            };
            self.set_learner_ceps(child, &seen);
            child.learner_cep = Some(seen);
        }
    }

    /// `cep` with the part of its deviation from `reference` that the measurements `obs` cannot
    /// see put back to `reference`: a small region is ill-conditioned (κ up to 1e10), and its
    /// least-squares CEPs wander along directions that move its predicted points by
    /// micrometres — values that cancel inside the region but not in a learner that blends
    /// neighbours. Directions of the position Jacobian at `obs` (columns scaled by the prior σ
    /// so lengths and angles compare) are dropped, weakest first, while the predicted points
    /// move by at most [`DivisionOptions::learner_tolerance`] × the demanded accuracy, RMS.
    fn seen_part(&self, obs: &[Observation], cep: &[f64], reference: &[f64]) -> Vec<f64> {
        let tol = self.opts.learner_tolerance * self.opts.accuracy_mm;
        if tol <= 0.0 || obs.is_empty() {
            return cep.to_vec();
        }
        let unit = self.prior_sigmas();
        let k = self.basis.len();
        let mut j = DMatrix::zeros(3 * obs.len(), k);
        for (n, o) in obs.iter().enumerate() {
            let b = self.block(&o.q);
            for c in 0..k {
                for r in 0..3 {
                    j[(3 * n + r, c)] = b[(r, c)] * unit[c];
                }
            }
        }
        let d = DVector::from_fn(k, |c, _| (cep[c] - reference[c]) / unit[c]);
        let svd = j.svd(false, true);
        let Some(v_t) = svd.v_t else {
            return cep.to_vec();
        };
        let mut weakest_first: Vec<usize> = (0..svd.singular_values.len()).collect();
        weakest_first.sort_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]));
        let budget = tol * tol * obs.len() as f64;
        let mut moved = 0.0;
        let mut kept = d.clone();
        for i in weakest_first {
            let v = v_t.row(i).transpose();
            let c = v.dot(&d);
            // Dropping this direction moves the predicted points by s·c (the columns of U
            // are orthonormal), and the moves of different directions add in squares.
            let cost = (svd.singular_values[i] * c).powi(2);
            if moved + cost > budget {
                break;
            }
            moved += cost;
            kept -= v * c;
        }
        (0..k).map(|c| reference[c] + kept[c] * unit[c]).collect()
    }

    /// Measurements a region needs for its fit.
    fn min_points(&self) -> usize {
        (self.basis.len() / 3 + 1).max(self.opts.per_region / 2)
    }

    fn identify(
        &self,
        id: &str,
        b: &Bounds,
        parent: Option<&[f64]>,
    ) -> Result<(Vec<f64>, f64, usize), String> {
        self.fit_box(id, b, parent, false)
    }

    /// Tests a region's CEPs: planning mode measures the arm at compensated commands for random
    /// targets in the region; offline mode predicts the held-out points of a fit without them.
    fn test(&mut self, node: &RegionNode) -> Result<Option<RegionTest>, MeasureError> {
        let Some(cep) = node.cep.as_ref() else {
            return Ok(None);
        };
        let (errors, bound_mm) = match self.mode {
            Mode::Planning(_) => {
                let tested = self.planning_test(&node.id, &node.bounds, cep)?;
                let bound = confidence::upper_bound(&tested, self.opts.confidence_z);
                (tested.iter().map(|t| t.error.norm()).collect(), Some(bound))
            }
            Mode::Offline(_) => (self.offline_test(&node.id, &node.bounds, cep), None),
        };
        if errors.is_empty() {
            return Ok(None);
        }
        let n = errors.len();
        Ok(Some(RegionTest {
            n,
            max_mm: errors.iter().copied().fold(0.0, f64::max),
            rms_mm: (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt(),
            bound_mm,
        }))
    }

    /// A region's test errors (measured − target, mm, with their unit-cube locations): the
    /// earlier tests inside it when [`TestPlan::reuse`], then its test design measured in
    /// stages ([`TestPlan::first_stage`]), skipping locations already tested, until the count
    /// is reached or a stage shows an error above the demand.
    fn planning_test(
        &mut self,
        id: &str,
        b: &Bounds,
        cep: &[f64],
    ) -> Result<Vec<TestError>, MeasureError> {
        let model = expand(self.basis, self.n_params, cep);
        let plan = self.opts.test_plan;
        let mut tested = if plan.reuse {
            self.earlier_tests(b, &model)
        } else {
            Vec::new()
        };
        let want = self.opts.test_points;
        // Where the rig's reach cuts a region, the locations it cannot measure are replaced by
        // further design points, so the part it can measure — where a measured path runs — is
        // judged on the full count, not on the few grid points that happen to fall inside it.
        let drawn = if self.opts.unmeasurable_halves {
            want * TEST_TOP_UP
        } else {
            want
        };
        let design = design::test_design(drawn);
        let mut next = 0;
        let stages = match plan.first_stage {
            n if n > 0 && n < want => vec![n, want],
            _ => vec![want],
        };
        let last = stages.len() - 1;
        for (k, &count) in stages.iter().enumerate() {
            if tested.len() < count {
                let new = self.measure_tests(
                    id,
                    b,
                    &model,
                    &design,
                    &mut next,
                    count - tested.len(),
                    &tested,
                )?;
                tested.extend(new);
            }
            let misses = tested
                .iter()
                .any(|t| t.error.norm() > self.opts.accuracy_mm);
            if k < last && misses {
                break;
            }
        }
        Ok(tested)
    }

    /// The earlier test measurements whose targets lie in `b` (faces closed), as this region's
    /// test errors under `model`: measured minus what `model` predicts at the command, which
    /// is exactly a compensated test's measured − target.
    fn earlier_tests(&self, b: &Bounds, model: &ErrorParams) -> Vec<TestError> {
        self.tests
            .iter()
            .filter(|t| b.holds(&t.x))
            .map(|t| TestError {
                u: std::array::from_fn(|k| {
                    let w = b.hi[k] - b.lo[k];
                    if w > 0.0 {
                        ((t.x[k] - b.lo[k]) / w).clamp(0.0, 1.0)
                    } else {
                        0.5
                    }
                }),
                error: t.obs.p - self.rig.chain.position(&t.obs.q, model),
            })
            .collect()
    }

    /// Up to `n` new test measurements of region `id` at the next locations of `design` (from
    /// `*next` on) that no test in `tested` covers ([`COVERED`]), as one batch.
    #[allow(clippy::too_many_arguments)]
    fn measure_tests(
        &mut self,
        id: &str,
        b: &Bounds,
        model: &ErrorParams,
        design: &[[f64; 3]],
        next: &mut usize,
        n: usize,
        tested: &[TestError],
    ) -> Result<Vec<TestError>, MeasureError> {
        let covered = |u: &[f64; 3]| {
            tested
                .iter()
                .any(|t| (0..3).all(|k| (t.u[k] - u[k]).abs() <= COVERED))
        };
        let mut commands = Vec::new();
        let mut targets = Vec::new();
        let mut units = Vec::new();
        while commands.len() < n && *next < design.len() {
            let u = design[*next];
            *next += 1;
            if covered(&u) {
                continue;
            }
            let Some((target, command, at)) = self.test_command(id, b, &u, model) else {
                continue;
            };
            commands.push(command);
            targets.push(target);
            units.push(at);
        }
        self.tests_made += commands.len();
        let measured = self.measure_batch(&commands)?;
        let mut out = Vec::new();
        for (o, (target, u)) in measured.into_iter().zip(targets.into_iter().zip(units)) {
            let Some(o) = o else { continue };
            out.push(TestError {
                u,
                error: o.p - target,
            });
            self.tests.push(TestDatum {
                x: b.at_unit(&u),
                obs: o,
            });
        }
        Ok(out)
    }

    /// The target at test location `u` (unit-cube coordinates of `b`) and the command that
    /// compensates it with `model`; a location whose pose cannot be measured or whose
    /// compensated command leaves the joint limits (at the workspace's faces) moves towards the
    /// centre until it can.
    fn test_command(
        &mut self,
        id: &str,
        b: &Bounds,
        u: &[f64; 3],
        model: &ErrorParams,
    ) -> Option<(nalgebra::Vector3<f64>, Vec<f64>, [f64; 3])> {
        let nominal = ErrorParams::zeros(self.rig.chain.layout());
        let opts = CompensationOptions::default();
        let seed = self.box_seed(id, b);
        for f in [1.0, 0.9, 0.75, 0.5] {
            let at = design::towards_centre(u, f);
            let x = b.at_unit(&at);
            let Some(q) = self.pose_at(b, &x, seed.as_deref()) else {
                continue;
            };
            let target = self.rig.chain.position(&q, &nominal);
            if let Ok(c) =
                compensate_from(&self.rig.chain, model, &target, self.rig.held(), q, &opts)
            {
                return Some((target, c.command, at));
            }
        }
        None
    }

    fn offline_test(&self, id: &str, b: &Bounds, cep: &[f64]) -> Vec<f64> {
        let held: Vec<&Observation> = self
            .in_box(id, b)
            .into_iter()
            .enumerate()
            .filter(|(k, _)| k % 5 == 4)
            .map(|(_, o)| o)
            .collect();
        let fitted = self
            .fit_box(id, b, Some(cep), true)
            .map(|(c, _, _)| c)
            .unwrap_or_else(|_| cep.to_vec());
        let model = expand(self.basis, self.n_params, &fitted);
        held.iter()
            .map(|o| (o.p - self.rig.chain.position(&o.q, &model)).norm())
            .collect()
    }

    /// Fits every measured leaf below `node` again on its identification and test
    /// measurements together, with the prior of its parent's CEPs (`parent`, as identified)
    /// ([`TestPlan::refit`]); a leaf whose fit fails keeps its CEPs.
    fn refit_leaves(&self, node: &mut RegionNode, parent: &[f64]) {
        if node.children.is_empty() {
            if !node.is_measured() {
                return;
            }
            let full = self.space.full;
            let mut obs: Vec<Observation> = self
                .in_box(&node.id, &node.bounds)
                .into_iter()
                .cloned()
                .collect();
            obs.extend(
                self.tests
                    .iter()
                    .filter(|t| node.bounds.contains(&t.x, &full))
                    .map(|t| t.obs.clone()),
            );
            let fo = FitOptions {
                prior: self.opts.map_prior.then(|| self.prior(parent)),
                ..FitOptions::default()
            };
            let start = expand(self.basis, self.n_params, parent);
            if let Ok(r) = fit(&self.rig.chain, &obs, &start, self.basis, &fo) {
                if r.kappa <= self.opts.kappa_max {
                    node.cep = Some(self.basis.iter().map(|&i| r.params.get(i)).collect());
                    node.measurements = obs.len();
                }
            }
            return;
        }
        let own = node.cep.clone().unwrap_or_else(|| parent.to_vec());
        for child in &mut node.children {
            self.refit_leaves(child, &own);
        }
    }

    /// Splits a region into two halves with their CEPs and tests, or says why it cannot.
    fn split(&mut self, node: &RegionNode) -> Result<Vec<RegionNode>, SplitError> {
        let full = self.space.full;
        if node.bounds.min_fraction(&full) * 0.5 < self.opts.min_fraction {
            return Err(SplitError::Cannot(format!(
                "narrower than 1/{:.0} of the workspace",
                1.0 / self.opts.min_fraction
            )));
        }
        let dim = node.bounds.widest(&full);
        let (a, b) = node.bounds.halves(dim);
        let parent = node.cep.clone();
        let mut children = Vec::new();
        for (k, bounds) in [a, b].into_iter().enumerate() {
            let mut child = RegionNode::unidentified(format!("{}{k}", node.id), bounds);
            if self.opts.unmeasurable.is_some_and(|u| u.encloses(&bounds)) {
                child.note = Some("unmeasurable: no measurement inside it".into());
                child.borrowed_from = Some(Vec::new());
                children.push(child);
                continue;
            }
            self.populate(&child.id, &bounds, self.opts.per_region)
                .map_err(SplitError::Measure)?;
            let (cep, kappa, n) = match self.identify(&child.id, &bounds, parent.as_deref()) {
                Ok(fit) => fit,
                // The rig cannot measure enough of this half (table travel, the pin rule): it
                // becomes a region without measurements of its own, as on the paper's rig
                // (seed 000 section 7): its neighbours' mean CEPs, the learner generalises there.
                Err(reason)
                    if self.opts.unmeasurable_halves
                        && self.in_box(&child.id, &bounds).len() < self.min_points() =>
                {
                    child.note = Some(format!("unmeasurable: {reason}"));
                    child.borrowed_from = Some(Vec::new());
                    children.push(child);
                    continue;
                }
                Err(reason) => return Err(SplitError::Cannot(reason)),
            };
            child.cep = Some(cep);
            child.kappa = kappa;
            child.measurements = n;
            child.test = self.test(&child).map_err(SplitError::Measure)?;
            children.push(child);
        }
        if children.iter().all(|c| c.borrowed_from.is_some()) && self.opts.unmeasurable.is_none() {
            return Err(SplitError::Cannot(
                "neither half holds enough measurable points".into(),
            ));
        }
        Ok(children)
    }
}
