//! Section 6's claims as distributions over seeds (`rigcal demo --seeds 1-20`): the demo's first
//! step ([`demo::paper_regime`]) at each seed, and per claim the pass rate, the median and the
//! worst value. The README quotes the rates and medians; seed 1 is an example.
//!
//! Seeds run on worker threads (one per core asked for), each with its own simulated world and
//! its own output directory, so a seed's figures do not depend on the others or on the number
//! of threads. Nothing here prints: each finished seed is told to the caller's callback.

use crate::demo::{self, DemoError, DemoOptions, PathSet};
use crate::paper_regime::{FigureRun, PaperFigure, PaperRegimeSummary};
use crate::preset::SEED_000;
use crate::sec7::Sec7Report;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// What a sweep runs.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepOptions {
    /// The demo's settings; `out` is the sweep's directory (each seed writes into `seed-N`
    /// there) and `seed` is ignored.
    pub demo: DemoOptions,
    /// The seeds, in the order the table lists them.
    pub seeds: Vec<u64>,
    /// Worker threads (at least 1).
    pub threads: usize,
    /// The paper's paths (the reported figures) or the tuning set (docs/seeds.md).
    pub paths: PathSet,
    /// Section 6 (the demo's first step) or section 7 (the rig experiment).
    pub part: SweepPart,
}

/// Which part of the demo a sweep runs at each seed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum SweepPart {
    /// Section 6: Figs. 6–8, half the measurements, the CEP jumps ([`demo::paper_regime`]).
    Section6,
    /// Section 7: the rig experiment through the rig's own command path
    /// ([`demo::rig_experiment`]).
    Section7,
}

/// How a sweep is getting on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SweepEvent {
    /// A seed finished after `wall_s` seconds; `done` of `total` seeds are finished.
    Finished {
        /// The seed.
        seed: u64,
        /// Seeds finished so far.
        done: usize,
        /// Seeds in the sweep.
        total: usize,
        /// Its wall time (s).
        wall_s: f64,
    },
}

/// One claim of section 6: a value per seed that must stay at or below `limit` (None: a figure
/// reported without a pass mark, such as the region count).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClaimRow {
    /// What is claimed, with the unit of the values.
    pub claim: String,
    /// The largest value that passes.
    pub limit: Option<f64>,
    /// (seed, value), in the sweep's seed order.
    pub values: Vec<(u64, f64)>,
}

impl ClaimRow {
    /// Seeds whose value passes.
    pub fn passes(&self) -> usize {
        match self.limit {
            Some(l) => self.values.iter().filter(|(_, v)| *v <= l).count(),
            None => self.values.len(),
        }
    }

    /// The seeds that fail.
    pub fn failing_seeds(&self) -> Vec<u64> {
        match self.limit {
            Some(l) => self
                .values
                .iter()
                .filter(|(_, v)| *v > l || v.is_nan())
                .map(|(s, _)| *s)
                .collect(),
            None => Vec::new(),
        }
    }

    /// The median value (the mean of the middle two for an even count).
    pub fn median(&self) -> f64 {
        let mut v: Vec<f64> = self.values.iter().map(|(_, v)| *v).collect();
        v.sort_by(f64::total_cmp);
        match v.len() {
            0 => f64::NAN,
            n if n % 2 == 1 => v[n / 2],
            n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        }
    }

    /// The worst value: the largest (every limited claim is "at most").
    pub fn worst(&self) -> f64 {
        self.values
            .iter()
            .map(|(_, v)| *v)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The smallest value.
    pub fn best(&self) -> f64 {
        self.values
            .iter()
            .map(|(_, v)| *v)
            .fold(f64::INFINITY, f64::min)
    }
}

/// A finished sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SeedTable {
    /// The seeds.
    pub seeds: Vec<u64>,
    /// Which paths.
    pub paths: PathSet,
    /// Which part of the demo.
    pub part: SweepPart,
    /// Wall time of the whole sweep (s).
    pub wall_s: f64,
    /// Threads it ran on.
    pub threads: usize,
    /// Per claim, every seed's value.
    pub rows: Vec<ClaimRow>,
}

impl SeedTable {
    /// The table as Markdown: per claim the pass rate, the median, the worst value and the
    /// failing seeds.
    pub fn text(&self) -> String {
        let mut s = format!(
            "{} over {} seeds ({}), {:?} paths, {:.0} s wall on {} thread(s)\n\n| claim | limit | passes | median | worst | failing seeds |\n|---|---|---|---|---|---|\n",
            match self.part {
                SweepPart::Section6 => "Section 6",
                SweepPart::Section7 => "Section 7",
            },
            self.seeds.len(),
            seed_range(&self.seeds),
            self.paths,
            self.wall_s,
            self.threads
        );
        for r in &self.rows {
            let (limit, passes, worst) = match r.limit {
                Some(l) => (
                    format!("≤ {l}"),
                    format!("{}/{}", r.passes(), r.values.len()),
                    trim(r.worst()),
                ),
                None => (
                    "—".into(),
                    "—".into(),
                    format!("{}–{}", trim(r.best()), trim(r.worst())),
                ),
            };
            let failing: Vec<String> = r.failing_seeds().iter().map(u64::to_string).collect();
            let _ = writeln!(
                s,
                "| {} | {limit} | {passes} | {} | {worst} | {} |",
                r.claim,
                trim(r.median()),
                failing.join(" ")
            );
        }
        s
    }

    /// Every seed's values as CSV: one row per seed, one column per claim.
    pub fn csv(&self) -> String {
        let mut s = String::from("seed");
        for r in &self.rows {
            let _ = write!(s, ",\"{}\"", r.claim.replace('"', "'"));
        }
        s.push('\n');
        for seed in &self.seeds {
            let _ = write!(s, "{seed}");
            for r in &self.rows {
                let v = r.values.iter().find(|(s, _)| s == seed);
                let _ = write!(s, ",{}", v.map_or(f64::NAN, |v| v.1));
            }
            s.push('\n');
        }
        s
    }
}

/// A value with four significant decimals, or an integer as an integer.
fn trim(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e9 {
        format!("{v:.0}")
    } else {
        format!("{v:.4}")
    }
}

/// "1–20" for a run of consecutive seeds, else the list.
fn seed_range(seeds: &[u64]) -> String {
    let consecutive = seeds.windows(2).all(|w| w[1] == w[0] + 1);
    match (seeds.first(), seeds.last()) {
        (Some(a), Some(b)) if consecutive && seeds.len() > 2 => format!("seeds {a}–{b}"),
        _ => format!(
            "seeds {}",
            seeds
                .iter()
                .map(u64::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Runs section 6 at every seed of `opts` and gathers its claims; `progress` hears of each
/// finished seed (from the worker threads). A seed that fails stops the sweep with its error.
pub fn sweep(
    opts: &SweepOptions,
    progress: &(dyn Fn(SweepEvent) + Sync),
) -> Result<SeedTable, DemoError> {
    let started = Instant::now();
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<SeedResult>>> =
        Mutex::new(opts.seeds.iter().map(|_| None).collect());
    let threads = opts.threads.clamp(1, opts.seeds.len().max(1));
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                let Some(&seed) = opts.seeds.get(i) else {
                    break;
                };
                let t0 = Instant::now();
                let r = run_seed(opts, seed);
                let failed = r.is_err();
                if let Ok(mut all) = results.lock() {
                    all[i] = Some(r);
                }
                let n = done.fetch_add(1, Ordering::SeqCst) + 1;
                progress(SweepEvent::Finished {
                    seed,
                    done: n,
                    total: opts.seeds.len(),
                    wall_s: t0.elapsed().as_secs_f64(),
                });
                if failed {
                    // The sweep fails anyway: leave the other seeds unstarted.
                    next.store(opts.seeds.len(), Ordering::SeqCst);
                }
            });
        }
    });
    let results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    let mut summaries = Vec::with_capacity(opts.seeds.len());
    for (r, &seed) in results.into_iter().zip(&opts.seeds) {
        match r {
            Some(Ok(s)) => summaries.push((seed, s)),
            Some(Err(e)) => {
                return Err(DemoError::Seed {
                    seed,
                    source: Box::new(e),
                })
            }
            None => {}
        }
    }
    Ok(SeedTable {
        seeds: opts.seeds.clone(),
        paths: opts.paths,
        part: opts.part,
        wall_s: started.elapsed().as_secs_f64(),
        threads,
        rows: rows(&summaries),
    })
}

/// The sweep's part at one seed, into `seed-N` of the sweep's directory, telling nothing: its
/// claims.
fn run_seed(opts: &SweepOptions, seed: u64) -> Result<Vec<Claim>, DemoError> {
    let o = DemoOptions {
        out: opts.demo.out.join(format!("seed-{seed}")),
        seed,
        ..opts.demo.clone()
    };
    Ok(match opts.part {
        SweepPart::Section6 => claims(&demo::paper_regime(&o, opts.paths, &mut |_| {})?),
        SweepPart::Section7 => sec7_claims(&demo::rig_experiment(&o, opts.paths)?),
    })
}

/// One claim's value at one seed.
type Claim = (String, Option<f64>, f64);

/// What one seed of a sweep gave: its claims, or why it failed.
type SeedResult = Result<Vec<Claim>, DemoError>;

/// The claims' rows from every seed's claims (in the order of the first seed).
fn rows(summaries: &[(u64, Vec<Claim>)]) -> Vec<ClaimRow> {
    let mut rows: Vec<ClaimRow> = Vec::new();
    for (seed, s) in summaries {
        for (claim, limit, value) in s.iter().cloned() {
            match rows.iter_mut().find(|r| r.claim == claim) {
                Some(r) => r.values.push((*seed, value)),
                None => rows.push(ClaimRow {
                    claim,
                    limit,
                    values: vec![(*seed, value)],
                }),
            }
        }
    }
    rows
}

/// The largest error (mm) of `method` along a run's path; NaN when the run has none.
fn max_of(run: &FigureRun, method: &str) -> f64 {
    run.path.method(method).map_or(f64::NAN, |m| m.max_mm)
}

/// What the demo claims in section 6, as values at one seed: the accuracy of each figure's
/// models along its path (the paper's "below 0.1 mm", "below 0.2" for conventional), the
/// FCMAC against conventional calibration and inside Fig. 8's unmeasurable region against the
/// neighbours' mean CEPs, half the paper's measurements, and the FCMAC's CEPs smoother than the
/// CMAC's; region counts and the unmeasurable region's size as figures without a pass mark.
pub fn claims(s: &PaperRegimeSummary) -> Vec<Claim> {
    let demand = s.accuracy_mm;
    let mut c: Vec<Claim> = Vec::new();
    for run in &s.runs {
        let f = run.figure.name();
        c.push((format!("{f} regions (leaves)"), None, run.regions as f64));
        c.push((
            format!("{f} regions, path max (mm)"),
            Some(demand),
            max_of(run, "regions"),
        ));
        c.push((
            format!("{f} FCMAC, path max (mm)"),
            Some(demand),
            max_of(run, "fcmac"),
        ));
        c.push((
            format!("{f} conventional, path max (mm)"),
            Some(2.0 * demand),
            max_of(run, "conventional"),
        ));
        c.push((
            format!("{f} FCMAC max ÷ conventional max"),
            Some(1.0),
            max_of(run, "fcmac") / max_of(run, "conventional"),
        ));
        if run.figure == PaperFigure::Fig8 {
            // A seed without the region on its path fails the claims inside it (NaN).
            let inside = run.path.inside_unmeasurable.as_ref();
            let of = |m: &str| {
                inside
                    .and_then(|i| i.methods.iter().find(|x| x.method == m))
                    .map_or(f64::NAN, |x| x.max_mm)
            };
            let depth = inside
                .and_then(|i| i.region.as_deref())
                .map(|r| r.len() - 1);
            c.push((
                format!("{f} unmeasurable region, share of the workspace (%)"),
                None,
                depth.map_or(f64::NAN, |d| 100.0 * 0.5f64.powi(d as i32)),
            ));
            c.push((
                format!("{f} inside it: regions (neighbours' mean), max (mm)"),
                Some(demand),
                of("regions"),
            ));
            c.push((
                format!("{f} inside it: FCMAC max (mm)"),
                Some(demand),
                of("fcmac"),
            ));
            c.push((
                format!("{f} inside it: FCMAC max ÷ neighbours' mean max"),
                Some(1.0),
                of("fcmac") / of("regions"),
            ));
        }
    }
    for run in &s.half_budget {
        let f = format!("{} at {} per region", run.figure.name(), run.per_region);
        let paper = SEED_000.region_cap(run.division) * SEED_000.per_region;
        c.push((
            format!("{f}: measurements ÷ the paper's {paper}"),
            Some(0.5),
            run.measurements as f64 / paper as f64,
        ));
        c.push((
            format!("{f}: regions, path max (mm)"),
            Some(demand),
            max_of(run, "regions"),
        ));
        c.push((
            format!("{f}: FCMAC, path max (mm)"),
            Some(demand),
            max_of(run, "fcmac"),
        ));
    }
    let jumps = |m: &str| s.cep_jumps.iter().find(|j| j.method == m);
    if let (Some(fcmac), Some(cmac)) = (jumps("fcmac"), jumps("cmac")) {
        let worst = fcmac
            .largest_cep_jump
            .iter()
            .map(|(k, v)| v / cmac.largest_cep_jump.get(k).copied().unwrap_or(f64::NAN))
            .fold(f64::NEG_INFINITY, f64::max);
        c.push((
            "Fig. 6 CEP jumps: FCMAC ÷ CMAC, worst of the four traced".into(),
            Some(1.0),
            worst,
        ));
    }
    c
}

/// The rig hours section 7 may take: the paper's "a couple of hours", as issue 32 reads it.
pub const SEC7_HOURS: f64 = 2.5;

/// What the demo claims in section 7, as values at one seed (docs/seeds.md): through the rig's
/// own command path, the FCMAC and the regions below the demanded 0.5 mm, conventional
/// calibration below the paper's 1.2 mm, and the whole experiment (the division session and
/// the path through that command path) within [`SEC7_HOURS`] of rig time; regions and
/// measurements as figures without a pass mark.
pub fn sec7_claims(r: &Sec7Report) -> Vec<Claim> {
    let (ident, tests) = r.measurements();
    let demand = r.summary().accuracy_mm;
    let own = r.runs.first();
    let max_of = |m: &str| {
        own.and_then(|run| run.result(m))
            .map_or(f64::NAN, |x| x.errors.iter().copied().fold(0.0, f64::max))
    };
    let command = own.map_or("-", |run| run.command());
    vec![
        (
            "regions (leaves; paper 85)".into(),
            None,
            r.regions() as f64,
        ),
        ("identification measurements".into(), None, ident as f64),
        ("test measurements".into(), None, tests as f64),
        (
            "rig hours, division session".into(),
            None,
            r.division.report.rig_time_s / 3600.0,
        ),
        (
            format!("rig hours, division and the path through {command}"),
            Some(SEC7_HOURS),
            r.rig_time_s() / 3600.0,
        ),
        (
            format!("uncalibrated through {command}, max (mm)"),
            None,
            max_of("uncalibrated"),
        ),
        (
            format!("conventional through {command}, max (mm)"),
            Some(1.2),
            max_of("conventional"),
        ),
        (
            format!("regions through {command}, max (mm)"),
            Some(demand),
            max_of("regions"),
        ),
        (
            format!("FCMAC through {command}, max (mm)"),
            Some(demand),
            max_of("fcmac"),
        ),
    ]
}

/// The directory a sweep writes into by default.
pub fn default_out() -> PathBuf {
    PathBuf::from("out/seeds")
}
