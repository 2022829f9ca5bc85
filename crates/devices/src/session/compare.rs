//! The rig-time comparison `rigcal plan` prints: the same points in the paper's order with the
//! paper-style procedure (the reference to compare with), in the paper's order with rigcal's
//! procedure, and in the optimised order with rigcal's procedure.

use crate::session::plan::{
    estimate, plan, ContactSettings, Ordering, PlanError, PlanOptions, PlannedPoint,
    RigTimeEstimate,
};
use crate::session::procedure::ContactProcedure;
use crate::session::speeds::RigSpeeds;
use rigcal_core::rig::Rig;

/// The (order, procedure) pairs `rigcal plan` compares, the reference (the paper's order and procedure) first.
pub const COMPARED: [(Ordering, ContactProcedure); 3] = [
    (Ordering::ZThenXY, ContactProcedure::Baseline),
    (Ordering::ZThenXY, ContactProcedure::Rigcal),
    (Ordering::Optimised, ContactProcedure::Rigcal),
];

/// One order and procedure of a plan's points, with its rig-time estimate.
#[derive(Debug, Clone)]
pub struct PlannedVariant {
    /// The order within each region.
    pub order: Ordering,
    /// The contact procedure.
    pub procedure: ContactProcedure,
    /// The points in that order (without the registration poses).
    pub points: Vec<PlannedPoint>,
    /// The estimate, the registration poses given included.
    pub estimate: RigTimeEstimate,
}

impl PlannedVariant {
    /// `optimised order, rigcal procedure`.
    pub fn label(&self) -> String {
        format!(
            "{} order, {} procedure",
            self.order.name(),
            self.procedure.name()
        )
    }
}

/// Plans `opts` in `order` on `rig` and estimates it with `procedure`, the `registration`
/// poses measured first (none for `rigcal plan`, the session's for a dry-run comparison).
pub fn plan_variant(
    rig: &Rig,
    opts: &PlanOptions,
    order: Ordering,
    procedure: ContactProcedure,
    registration: &[PlannedPoint],
) -> Result<PlannedVariant, PlanError> {
    let points = plan(rig, &PlanOptions { order, ..*opts })?.points;
    let estimate = estimate(
        rig,
        &[registration, &points].concat(),
        &RigSpeeds::of(rig),
        &ContactSettings::for_procedure(rig, procedure),
    );
    Ok(PlannedVariant {
        order,
        procedure,
        points,
        estimate,
    })
}

/// How much less `t_s` is than `reference_s` (%).
pub fn saving_pct(t_s: f64, reference_s: f64) -> f64 {
    100.0 * (1.0 - t_s / reference_s.max(1e-9))
}

/// The variants `rigcal plan` compares: the [`COMPARED`] pairs, and `chosen` after them when
/// it is not one of them; each planned from `opts` and estimated with `registration` first.
pub fn compare(
    rig: &Rig,
    opts: &PlanOptions,
    chosen: (Ordering, ContactProcedure),
    registration: &[PlannedPoint],
) -> Result<Vec<PlannedVariant>, PlanError> {
    let mut pairs = COMPARED.to_vec();
    if !pairs.contains(&chosen) {
        pairs.push(chosen);
    }
    pairs
        .into_iter()
        .map(|(order, procedure)| plan_variant(rig, opts, order, procedure, registration))
        .collect()
}
