//! `rigcal plan`: the measurement points of a session, in order, with a rig-time estimate.
//!
//! Infeasible candidates are dropped with their reason: a summary by reason is printed and every
//! one is listed in `<out>.dropped.csv`. Files: degrees and mm.

use anyhow::{Context, Result};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use rigcal_devices::session::{
    compare, plan, saving_pct, write_plan, ContactProcedure, Ordering, Plan, PlanOptions,
    PlannedVariant, RigTimeEstimate,
};
use rigcal_sim::world::Scenario;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Arguments of `rigcal plan`.
#[derive(Debug, clap::Args)]
#[command(mut_args(super::help_of("rig", "The rig file")))]
#[command(mut_args(super::help_of("out", "Where to write the plan (CSV)")))]
pub struct Args {
    #[command(flatten)]
    rig: super::RigArg,
    /// A scenario (sim/*.toml) whose seed to use.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Measurement points wanted (drift-reference re-measurements come on top).
    #[arg(long)]
    points: usize,
    /// Regions of the workspace (rounded up to a power of two).
    #[arg(long, default_value_t = 8)]
    regions: usize,
    /// Re-measure the drift-reference pose every N points (0: never); in the optimised order
    /// as often, each time within N/5 points of that where the detour is least.
    #[arg(long, default_value_t = 50)]
    reference_every: usize,
    /// Seed of the random points (default: the scenario's, else 1).
    #[arg(long)]
    seed: Option<u64>,
    /// Order within a region: `optimised` (least move time within the ascending-z window) or
    /// the paper's `z-then-xy` (2 mm z layers, then x, then y); `nearest-neighbour` orders x-y
    /// layers greedily. The other order of the same points is estimated beside it.
    #[arg(long, default_value = "optimised")]
    order: Ordering,
    /// Contact procedure on the table rig: `rigcal` (two-phase final approach, moves
    /// overlapped) or `baseline` (the paper-style procedure: one move after another, a single
    /// slow final approach). The paper's order with the baseline procedure (the reference
    /// savings are counted against), with rigcal's, and the optimised order with rigcal's are
    /// estimated beside the chosen one.
    #[arg(long, default_value = "rigcal")]
    procedure: ContactProcedure,
    #[command(flatten)]
    out: super::OutArg,
}

/// The plan options of a command line.
pub(crate) fn options(
    points: usize,
    regions: usize,
    reference_every: usize,
    seed: u64,
) -> PlanOptions {
    PlanOptions {
        points,
        regions,
        reference_every,
        seed,
        ..PlanOptions::default()
    }
}

/// Prints the dropped candidates by reason and writes them all beside `out`.
pub(crate) fn report_dropped(rig: &Rig, p: &Plan, out: &Path) -> Result<()> {
    let mut by: BTreeMap<String, usize> = BTreeMap::new();
    for d in &p.dropped {
        let key = match &d.reason {
            rigcal_core::rig::Unmeasurable::JointLimit { .. } => "joint limit".to_string(),
            rigcal_core::rig::Unmeasurable::PinAngle { .. } => "pin angle to the panel".to_string(),
            rigcal_core::rig::Unmeasurable::TableTravel { axis, .. } => {
                format!("table {axis} travel")
            }
        };
        *by.entry(key).or_default() += 1;
    }
    let path = out.with_extension("dropped.csv");
    let mut s = String::from("candidate");
    for (i, j) in rig.chain.joints().iter().enumerate() {
        s.push_str(&format!(",{}", j.kind.column(i + 1)));
    }
    s.push_str(",reason\n");
    for (k, d) in p.dropped.iter().enumerate() {
        s.push_str(&format!("{}", k + 1));
        for (spec, v) in rig.chain.joints().iter().zip(&d.q) {
            s.push_str(&format!(",{:.3}", spec.kind.to_file_units(*v)));
        }
        s.push_str(&format!(
            ",\"{}\"\n",
            d.reason.to_string().replace('"', "'")
        ));
    }
    std::fs::write(&path, s).with_context(|| format!("writing {}", path.display()))?;
    println!(
        "dropped {} infeasible candidates (every one with its reason in {}):",
        p.dropped.len(),
        path.display()
    );
    for (reason, n) in by {
        println!("  {n:>7}  {reason}");
    }
    Ok(())
}

/// One line on the estimate.
pub(crate) fn describe(e: &RigTimeEstimate) -> String {
    format!(
        "estimated rig time {:.0} s ({:.2} h) for {} points{}: {:.0} s motion, {:.0} s contact; the paper's ~5 s per point would be {:.0} s",
        e.total_s,
        e.total_s / 3600.0,
        e.points - e.registration_points,
        if e.registration_points > 0 {
            format!(" and {} registration poses", e.registration_points)
        } else {
            String::new()
        },
        e.motion_s,
        e.contact_s,
        5.0 * e.points as f64
    )
}

/// The estimate's breakdown, one part a line.
pub(crate) fn breakdown(e: &RigTimeEstimate) -> String {
    e.breakdown
        .parts()
        .iter()
        .map(|(name, s)| {
            format!(
                "  {name:<18} {s:>8.0} s  {:>3.0} %",
                100.0 * s / e.total_s.max(1e-9)
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The same points in the compared orders and procedures, one a line, each with its saving
/// against the first (the paper's order with the baseline procedure); `chosen` marked.
pub(crate) fn comparison(
    variants: &[PlannedVariant],
    chosen: (Ordering, ContactProcedure),
) -> String {
    let reference = variants.first().map_or(0.0, |v| v.estimate.total_s);
    let mut lines = vec![
        "rig time of the same points; each one's saving against the first, the paper's order and contact procedure:"
            .to_string(),
    ];
    for (k, v) in variants.iter().enumerate() {
        let saving = if k == 0 {
            "reference".to_string()
        } else {
            format!("saves {:.1} %", saving_pct(v.estimate.total_s, reference))
        };
        let mark = if (v.order, v.procedure) == chosen {
            "  (this plan)"
        } else {
            ""
        };
        lines.push(format!(
            "  {:<38} {:>7.0} s ({:.2} h)  {saving}{mark}",
            v.label(),
            v.estimate.total_s,
            v.estimate.total_s / 3600.0
        ));
    }
    lines.join("\n")
}

pub fn run(a: Args) -> Result<()> {
    let rig = a.rig.load()?;
    let out = &a.out.out;
    let seed = match (&a.seed, &a.scenario) {
        (Some(s), _) => *s,
        (None, Some(path)) => Scenario::load(path, None)?.seed,
        (None, None) => 1,
    };
    let opts = PlanOptions {
        order: a.order,
        ..options(a.points, a.regions, a.reference_every, seed)
    };
    let p = plan(&rig, &opts)?;
    report_dropped(&rig, &p, out)?;
    write_plan(out, &rig, &p.points)?;
    let chosen = (a.order, a.procedure);
    let variants = compare(&rig, &opts, chosen, &[])?;
    let e = variants
        .iter()
        .find(|v| (v.order, v.procedure) == chosen)
        .map(|v| v.estimate)
        .context("the chosen order and procedure among the compared")?;
    println!(
        "planned {} points ({} drift references) → {}",
        p.points.len(),
        p.points
            .iter()
            .filter(|x| x.region == rigcal_devices::session::plan::REFERENCE_REGION)
            .count(),
        out.display()
    );
    println!(
        "{} ({} order, {} procedure)",
        describe(&e),
        a.order.name(),
        a.procedure.name()
    );
    println!("{}", breakdown(&e));
    println!("{}", comparison(&variants, chosen));
    Ok(())
}
