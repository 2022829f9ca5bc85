//! `rigcal plan`: the measurement points of a session, in order, with a rig-time estimate;
//! infeasible candidates dropped with their reason ([`rigcal_devices::session::Plan::write_dropped`]).

use anyhow::{Context, Result};
use rigcal_devices::session::{
    compare, comparison_text, plan, write_plan, ContactProcedure, Ordering, PlanOptions,
    MAX_PLAN_POINTS,
};
use rigcal_sim::world::Scenario;
use std::path::PathBuf;

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
    /// Measurement points wanted, 1 to 1000000 (drift-reference re-measurements come on top).
    #[arg(long, value_parser = point_count)]
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

/// Parses a count of points or poses (`--points`, `--random`): 1 to [`MAX_PLAN_POINTS`]. Checked
/// as the flag is read, so a zero count is refused instead of "finishing" with nothing, and a
/// huge one before any work or allocation.
pub fn point_count(s: &str) -> Result<usize, String> {
    let n: usize = s.trim().parse().map_err(|_| {
        format!("`{s}` is not a whole number; give a count from 1 to {MAX_PLAN_POINTS}")
    })?;
    match n {
        0 => Err(format!("0 points: give a count from 1 to {MAX_PLAN_POINTS}")),
        n if n > MAX_PLAN_POINTS => Err(format!(
            "{n} is above the maximum of {MAX_PLAN_POINTS}; split a larger campaign into several sessions"
        )),
        n => Ok(n),
    }
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
        points: a.points,
        regions: a.regions,
        reference_every: a.reference_every,
        seed,
        order: a.order,
        ..PlanOptions::default()
    };
    let p = plan(&rig, &opts)?;
    print!("{}", p.write_dropped(&rig, out)?);
    write_plan(out, &rig, &p.points)?;
    let chosen = (a.order, a.procedure);
    let variants = compare(&rig, &opts, chosen, &[])?;
    let e = variants
        .iter()
        .find(|v| (v.order, v.procedure) == chosen)
        .map(|v| v.estimate)
        .context("the chosen order and procedure among the compared")?;
    println!("{}", p.written_text(out));
    println!(
        "{} ({} order, {} procedure)",
        e.text(),
        a.order.name(),
        a.procedure.name()
    );
    println!("{}", e.breakdown_text());
    println!("{}", comparison_text(&variants, chosen));
    Ok(())
}
