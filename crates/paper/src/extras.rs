//! What seed 000 reports and the demo did not measure (issue 32, points 5 and 6), measured
//! over seeds on the models a seed sweep ([`crate::seeds`]) leaves in each seed's directory:
//!
//! - **CMAC and FCMAC on equal training**: the demo's CMAC learns the regions' CEPs only while
//!   its FCMAC also learns the measured positions; here both learn the same CEP patterns of
//!   the Fig. 6 division (the paper's (A5) for the FCMAC, the LMS rule for the CMAC). The CMAC
//!   has no position training, so "both on CEPs and positions" cannot be run.
//! - **Ten paths** (the paper's "consistently good performance for different simulated
//!   paths"): the Fig. 6 and Fig. 7 models along ten straight joint-space lines drawn by a
//!   fixed rule ([`ten_joint_paths`]) before any of them was evaluated; with a section 7
//!   sweep, its model along ten Cartesian lines ([`ten_rig_paths`]) measured by the rig.
//! - **The 3 % noise run**: [`noise_sigma_mm`](crate::paper_regime::noise_sigma_mm) turns the paper's "about 3 % of the total
//!   error" into the simulated instrument's σ ([`crate::demo::DemoOptions::noise_share`]).
//! - **The rig's CEP plots** (Fig. 10 e–g): [`rig_cep_plot`](crate::sec7::rig_cep_plot).
//!
//! Units: mm and degrees in every file and table; radians inside.

use crate::demo::{DemoError, DemoOptions};
use crate::preset::Preset;
use crate::seeds::ClaimRow;
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rigcal_calibration::{self as calibration, CalibrationError, PathFigures};
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::Rig;
use rigcal_model::division::{Bounds, DivisionError, DivisionSpace, Space};
use rigcal_model::learners::{FcmacTraining, LearnerKind};
use rigcal_model::model::ModelFile;
use rigcal_model::report::{joint_path, PathSpec};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The paper's scenario and instrument, as the demo's section 6 uses them.
const PAPER_RIG: &str = "rigs/rv-m2-ideal.toml";
const PAPER_SCENARIO: &str = "sim/paper-fig6.toml";

/// The seed of the ten paths' draw: fixed before any path was evaluated (the number).
pub const TEN_PATHS_SEED: u64 = 32;
/// Paths drawn.
pub const TEN_PATHS: usize = 10;
/// Points per path, as the paper's figures.
pub const PATH_POINTS: usize = 101;
/// Each end of a path lies this fraction of the joint range inside every joint limit.
const JOINT_INSET: f64 = 0.1;
/// Every point lies this fraction of the Cartesian division's range inside its box, so the
/// Fig. 7 model (a Cartesian division) covers the path too.
const CARTESIAN_INSET: f64 = 0.02;
/// The shortest path (joint-space length over q1, q2, q3, deg): the paper's Fig. 6 path spans
/// about 60°.
const MIN_LENGTH_DEG: f64 = 60.0;
/// Draws before the rule gives up.
const MAX_DRAWS: usize = 100_000;

/// Why the ten paths could not be drawn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PathsError {
    /// The rig does not move three joints.
    #[error("the ten paths need a rig moving three joints (q1, q2, q3); {0} moves {1}")]
    NotThreeJoints(String, usize),
    /// The rule found fewer paths than asked within its draws.
    #[error(
        "only {found} of {wanted} paths found in {MAX_DRAWS} draws inside the measurable workspace"
    )]
    TooFew {
        /// Paths found.
        found: usize,
        /// Paths asked for.
        wanted: usize,
    },
    /// The division spaces of the rig.
    #[error(transparent)]
    Space(#[from] DivisionError),
}

/// Why the extras stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExtrasError {
    /// The ten paths.
    #[error(transparent)]
    Paths(#[from] PathsError),
    /// A model file a seed of the sweep should have left, or its evaluation.
    #[error(transparent)]
    Demo(#[from] DemoError),
}

impl From<CalibrationError> for ExtrasError {
    fn from(e: CalibrationError) -> Self {
        Self::Demo(e.into())
    }
}

impl From<rigcal_model::model::ModelError> for ExtrasError {
    fn from(e: rigcal_model::model::ModelError) -> Self {
        Self::Demo(e.into())
    }
}

impl From<rigcal_core::rig::RigError> for ExtrasError {
    fn from(e: rigcal_core::rig::RigError) -> Self {
        Self::Demo(e.into())
    }
}

/// The box `b` shrunk by `f` of its range on every side.
fn inset(b: &Bounds, f: f64) -> Bounds {
    Bounds {
        lo: std::array::from_fn(|k| b.lo[k] + f * (b.hi[k] - b.lo[k])),
        hi: std::array::from_fn(|k| b.hi[k] - f * (b.hi[k] - b.lo[k])),
    }
}

/// The paths a rule found, when it found all [`TEN_PATHS`].
fn all_ten<P>(paths: Vec<P>) -> Result<Vec<P>, PathsError> {
    if paths.len() < TEN_PATHS {
        return Err(PathsError::TooFew {
            found: paths.len(),
            wanted: TEN_PATHS,
        });
    }
    Ok(paths)
}

/// Ten straight joint-space lines of [`PATH_POINTS`] points for section 6's models, by a rule
/// fixed before any was evaluated: ends (q1, q2, q3) drawn uniformly inside the joint-space
/// division's box inset by 10 % of each range (ChaCha8, seed [`TEN_PATHS_SEED`]); a line is
/// kept when it is at least 60° long, every point is measurable on `rig` and lies inside the
/// Cartesian division's box inset by 2 %. Named "path k: (q1, q2, q3) → (…) deg".
pub fn ten_joint_paths(rig: &Rig) -> Result<Vec<PathSpec>, PathsError> {
    let moving = rig.moving_joints();
    if moving.len() != 3 {
        return Err(PathsError::NotThreeJoints(rig.name.clone(), moving.len()));
    }
    let joint = DivisionSpace::new(rig, Space::Joint).map_err(DivisionError::from)?;
    let cartesian = DivisionSpace::new(rig, Space::Cartesian).map_err(DivisionError::from)?;
    let ends_box = inset(&joint.full, JOINT_INSET);
    let cartesian_box = inset(&cartesian.full, CARTESIAN_INSET);
    let to_file = |j: usize, v: f64| rig.chain.joints()[moving[j]].kind.to_file_units(v);
    let mut rng = ChaCha8Rng::seed_from_u64(TEN_PATHS_SEED);
    let mut paths = Vec::with_capacity(TEN_PATHS);
    for _ in 0..MAX_DRAWS {
        if paths.len() == TEN_PATHS {
            break;
        }
        let mut draw = || -> [f64; 3] {
            std::array::from_fn(|k| {
                to_file(
                    k,
                    ends_box.lo[k] + rng.random_range(0.0..1.0) * (ends_box.hi[k] - ends_box.lo[k]),
                )
            })
        };
        let (a, b) = (draw(), draw());
        let length: f64 = (0..3).map(|k| (b[k] - a[k]).powi(2)).sum::<f64>().sqrt();
        if length < MIN_LENGTH_DEG {
            continue;
        }
        let name = format!(
            "path {}: ({:.0}, {:.0}, {:.0}) → ({:.0}, {:.0}, {:.0}) deg",
            paths.len() + 1,
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2]
        );
        let path = joint_path(rig, &name, &a, &b, PATH_POINTS);
        let inside = path.points.iter().all(|q| {
            rig.measurable(q).is_ok()
                && joint.full.holds(&joint.coords(q))
                && cartesian_box.holds(&cartesian.coords(q))
        });
        if inside {
            paths.push(path);
        }
    }
    all_ten(paths)
}

/// Which extra measurements a sweep adds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Extras {
    /// CMAC and FCMAC both trained on the Fig. 6 division's CEPs only.
    pub equal_training: bool,
    /// The Fig. 6 and Fig. 7 models along [`ten_joint_paths`] (section 6), or section 7's
    /// model along [`ten_rig_paths`] measured by the rig (`rig`).
    pub ten_paths: bool,
    /// The sweep ran section 7: the ten paths are the rig's.
    pub rig: bool,
}

/// One model's figures along one of the ten paths at one seed.
#[derive(Debug, Clone, PartialEq)]
pub struct PathRow {
    /// The seed.
    pub seed: u64,
    /// `Fig. 6` or `Fig. 7` (section 6's models, the simulated arm's true error) or `rig`
    /// (section 7's, measured by the rig through its own command path).
    pub figure: &'static str,
    /// 1..=10.
    pub path: usize,
    /// `conventional`, `regions`, `fcmac`.
    pub method: String,
    /// Mean error along the path (mm).
    pub mean_mm: f64,
    /// Largest error along the path (mm).
    pub max_mm: f64,
    /// The claim's limit on `max_mm` (mm): the demand for the regions and the FCMAC, the
    /// paper's bound for conventional calibration (twice the demand in section 6, 1.2 mm on
    /// the rig).
    pub limit_mm: f64,
}

/// What the extras measured over a sweep's seeds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExtrasTable {
    /// Per-seed claims (equal training, the ten paths' spread), as the sweep's own rows.
    pub rows: Vec<ClaimRow>,
    /// Every (seed, figure, path, method) of the ten paths.
    pub paths: Vec<PathRow>,
    /// The ten paths' names, in order.
    pub path_names: Vec<String>,
}

/// The extras at every seed of a finished sweep, from the model files each seed left in
/// `demo.out/seed-N` (the sweep's `demo` options: the same learner settings).
pub fn measure(
    demo: &DemoOptions,
    seeds: &[u64],
    extras: Extras,
) -> Result<ExtrasTable, ExtrasError> {
    let rig = Rig::load(Path::new(PAPER_RIG))?;
    let paths = if extras.ten_paths && !extras.rig {
        ten_joint_paths(&rig)?
    } else {
        Vec::new()
    };
    let rig_paths = if extras.ten_paths && extras.rig {
        ten_rig_paths(&Rig::load(Path::new(REAL_RIG))?)?
    } else {
        Vec::new()
    };
    let mut table = ExtrasTable {
        path_names: paths.iter().map(|p| p.name.clone()).collect(),
        ..Default::default()
    };
    for (k, ends) in rig_paths.iter().enumerate() {
        table.path_names.push(rig_path_name(k + 1, ends));
    }
    for &seed in seeds {
        let dir = demo.out.join(format!("seed-{seed}"));
        let mut claims: Vec<(String, Option<f64>, f64)> = Vec::new();
        if extras.equal_training {
            claims.extend(equal_training(&dir, &demo.preset, demo)?);
        }
        if extras.ten_paths {
            let rows = if extras.rig {
                rig_path_rows(&dir, seed, &rig_paths, &demo.preset)?
            } else {
                ten_path_rows(&dir, seed, &paths, demo.preset.accuracy_mm)?
            };
            claims.extend(spread_claims(&rows));
            table.paths.extend(rows);
        }
        for (claim, limit, value) in claims {
            match table.rows.iter_mut().find(|r| r.claim == claim) {
                Some(r) => r.values.push((seed, value)),
                None => table.rows.push(ClaimRow {
                    claim,
                    limit,
                    values: vec![(seed, value)],
                }),
            }
        }
    }
    Ok(table)
}

/// The largest error (mm) of `method` along a path's figures; NaN when absent.
fn max_of(f: &PathFigures, method: &str) -> f64 {
    f.method(method).map_or(f64::NAN, |m| m.max_mm)
}

/// CMAC and FCMAC on the same CEP patterns of the Fig. 6 division in `dir`: their errors along
/// the Fig. 6 path and the FCMAC's largest CEP jump over the CMAC's (the paper's smoothness
/// claim with the training made equal).
fn equal_training(
    dir: &Path,
    preset: &Preset,
    demo: &DemoOptions,
) -> Result<Vec<(String, Option<f64>, f64)>, ExtrasError> {
    let file = dir.join("paper-fig6-model.json");
    let model = ModelFile::load(&file)?;
    let rig = model.rig.clone();
    let mut settings = preset.calibration(Space::Joint).learner_settings;
    settings.training = FcmacTraining::Ceps;
    settings.init = demo.fcmac_init;
    let path = calibration::fig6_path(&rig, PATH_POINTS);
    let mut figures = Vec::new();
    for (kind, name) in [(LearnerKind::Fcmac, "fcmac"), (LearnerKind::Cmac, "cmac")] {
        let trained = calibration::with_learner(&model.file, &rig, kind, &settings)?;
        let out = dir.join(format!("paper-fig6-equal-{name}-model.json"));
        trained.save(&out)?;
        let (mut f, _) = calibration::evaluate_files(
            &out,
            Path::new(PAPER_SCENARIO),
            std::slice::from_ref(&path),
            &preset.traced_ceps(),
            None,
        )?;
        let f = f.pop().ok_or(DemoError::NoDivision("no path evaluated"))?;
        figures.push((name, f));
    }
    let [(_, fcmac), (_, cmac)] = &figures[..] else {
        return Err(DemoError::NoDivision("equal training: two learners expected").into());
    };
    let demand = preset.accuracy_mm;
    let jump = |f: &PathFigures, m: &str| f.method(m).map(|x| x.largest_cep_jump.clone());
    let worst_ratio = match (jump(fcmac, "fcmac"), jump(cmac, "cmac")) {
        (Some(a), Some(b)) => a
            .iter()
            .map(|(k, v)| v / b.get(k).copied().unwrap_or(f64::NAN))
            .fold(f64::NEG_INFINITY, f64::max),
        _ => f64::NAN,
    };
    Ok(vec![
        (
            "equal training (CEPs only): Fig. 6 FCMAC, path max (mm)".into(),
            Some(demand),
            max_of(fcmac, "fcmac"),
        ),
        (
            "equal training (CEPs only): Fig. 6 CMAC, path max (mm)".into(),
            Some(demand),
            max_of(cmac, "cmac"),
        ),
        (
            "equal training (CEPs only): Fig. 6 CEP jumps FCMAC ÷ CMAC, worst of the four traced"
                .into(),
            Some(1.0),
            worst_ratio,
        ),
    ])
}

/// The Fig. 6 and Fig. 7 models of `dir` along `paths`: one row per figure, path and method.
fn ten_path_rows(
    dir: &Path,
    seed: u64,
    paths: &[PathSpec],
    demand_mm: f64,
) -> Result<Vec<PathRow>, ExtrasError> {
    let mut rows = Vec::new();
    for (figure, file) in [
        ("Fig. 6", "paper-fig6-model.json"),
        ("Fig. 7", "paper-fig7-model.json"),
    ] {
        let (figures, _) = calibration::evaluate_files(
            &dir.join(file),
            Path::new(PAPER_SCENARIO),
            paths,
            &[],
            None,
        )?;
        for (k, f) in figures.iter().enumerate() {
            for m in f.methods.iter().filter(|m| m.method != "uncalibrated") {
                rows.push(PathRow {
                    seed,
                    figure,
                    path: k + 1,
                    method: m.method.clone(),
                    mean_mm: m.mean_mm,
                    max_mm: m.max_mm,
                    limit_mm: if m.method == "conventional" {
                        2.0 * demand_mm
                    } else {
                        demand_mm
                    },
                });
            }
        }
    }
    Ok(rows)
}

/// One seed's spread over the ten paths, per figure and method: the range of the path
/// maxima (worst path's max − best path's, mm) and their ratio (the paper: the proposed
/// scheme "more homogeneous" than the conventional one); the claim compares the ranges,
/// since a ratio blows up where a method's best path is near zero.
fn spread_claims(rows: &[PathRow]) -> Vec<(String, Option<f64>, f64)> {
    let extremes = |figure: &str, method: &str| {
        let v: Vec<f64> = rows
            .iter()
            .filter(|r| r.figure == figure && r.method == method)
            .map(|r| r.max_mm)
            .collect();
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        (lo, hi)
    };
    let range = |figure: &str, method: &str| {
        let (lo, hi) = extremes(figure, method);
        hi - lo
    };
    let mut figures: Vec<&str> = rows.iter().map(|r| r.figure).collect();
    figures.dedup();
    let mut c = Vec::new();
    for figure in figures {
        for method in ["conventional", "regions", "fcmac"] {
            let (lo, hi) = extremes(figure, method);
            c.push((
                format!("ten paths, {figure} {method}: worst − best path max (mm)"),
                None,
                hi - lo,
            ));
            c.push((
                format!("ten paths, {figure} {method}: worst ÷ best path max"),
                None,
                hi / lo,
            ));
        }
        c.push((
            format!("ten paths, {figure}: FCMAC range ÷ conventional range of the path maxima"),
            Some(1.0),
            range(figure, "fcmac") / range(figure, "conventional"),
        ));
    }
    c
}

/// The median of `v` (the mean of the middle two for an even count); NaN when empty.
fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

impl ExtrasTable {
    /// The ten paths pooled over paths × seeds, per figure and method (pass rate at each
    /// row's limit, median, worst, the failing seed:path pairs), then per path conventional
    /// calibration's and the FCMAC's median and worst over seeds; then the per-seed rows.
    /// Markdown.
    pub fn text(&self) -> String {
        let mut s = String::new();
        if !self.paths.is_empty() {
            let seeds = {
                let mut v: Vec<u64> = self.paths.iter().map(|r| r.seed).collect();
                v.dedup();
                v.len()
            };
            let mut figures: Vec<&str> = self.paths.iter().map(|r| r.figure).collect();
            figures.dedup();
            let _ = writeln!(
                s,
                "Ten paths × {seeds} seeds, path max (mm):\n\n| model | limit | passes | median | worst | failing seed:path |\n|---|---|---|---|---|---|"
            );
            for figure in &figures {
                for method in ["conventional", "regions", "fcmac"] {
                    let rows: Vec<&PathRow> = self
                        .paths
                        .iter()
                        .filter(|r| r.figure == *figure && r.method == method)
                        .collect();
                    let Some(limit) = rows.first().map(|r| r.limit_mm) else {
                        continue;
                    };
                    let v: Vec<f64> = rows.iter().map(|r| r.max_mm).collect();
                    let passes = v.iter().filter(|x| **x <= limit).count();
                    let failing: Vec<String> = rows
                        .iter()
                        .filter(|r| r.max_mm > limit || r.max_mm.is_nan())
                        .map(|r| format!("{}:{}", r.seed, r.path))
                        .collect();
                    let _ = writeln!(
                        s,
                        "| {figure} {method} | ≤ {limit} | {passes}/{} | {:.4} | {:.4} | {} |",
                        v.len(),
                        median(&v),
                        v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                        failing.join(" ")
                    );
                }
            }
            let mut header = String::from("| path |");
            let mut rule = String::from("|---|");
            for figure in &figures {
                let _ = write!(header, " {figure} conventional | {figure} FCMAC |");
                rule.push_str("---|---|");
            }
            let _ = writeln!(
                s,
                "\nPer path, max (mm) over seeds, median / worst:\n\n{header}\n{rule}"
            );
            for (k, name) in self.path_names.iter().enumerate() {
                let cell = |figure: &str, method: &str| {
                    let v: Vec<f64> = self
                        .paths
                        .iter()
                        .filter(|r| r.path == k + 1 && r.figure == figure && r.method == method)
                        .map(|r| r.max_mm)
                        .collect();
                    format!(
                        "{:.4} / {:.4}",
                        median(&v),
                        v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                    )
                };
                let _ = write!(s, "| {name} |");
                for figure in &figures {
                    let _ = write!(
                        s,
                        " {} | {} |",
                        cell(figure, "conventional"),
                        cell(figure, "fcmac")
                    );
                }
                s.push('\n');
            }
            s.push('\n');
        }
        if !self.rows.is_empty() {
            s.push_str("| claim | limit | passes | median | worst | failing seeds |\n|---|---|---|---|---|---|\n");
            for r in &self.rows {
                let (limit, passes, worst) = match r.limit {
                    Some(l) => (
                        format!("≤ {l}"),
                        format!("{}/{}", r.passes(), r.values.len()),
                        format!("{:.4}", r.worst()),
                    ),
                    None => (
                        "—".into(),
                        "—".into(),
                        format!("{:.4}–{:.4}", r.best(), r.worst()),
                    ),
                };
                let failing: Vec<String> = r.failing_seeds().iter().map(u64::to_string).collect();
                let _ = writeln!(
                    s,
                    "| {} | {limit} | {passes} | {:.4} | {worst} | {} |",
                    r.claim,
                    r.median(),
                    failing.join(" ")
                );
            }
        }
        s
    }

    /// The ten paths' rows as CSV (seed, figure, path, method, mean and max in mm).
    pub fn paths_csv(&self) -> String {
        let mut s = String::from("seed,figure,path,method,mean_mm,max_mm\n");
        for r in &self.paths {
            let _ = writeln!(
                s,
                "{},{},{},{},{:.6},{:.6}",
                r.seed, r.figure, r.path, r.method, r.mean_mm, r.max_mm
            );
        }
        s
    }
}

/// The rig experiment's files, as the demo's section 7 uses them.
const REAL_RIG: &str = "rigs/rv-m2.toml";
const REAL_SCENARIO: &str = "sim/rig-sec7.toml";

/// The box the rig's ten paths' ends are drawn in (world mm): around the preset's path and
/// the tuning line, wider than the table's reach so the measurability check decides.
pub const RIG_BOX_MM: [[f64; 3]; 2] = [[-400.0, 250.0, 0.0], [400.0, 700.0, 600.0]];
/// The shortest rig path (mm); the paper's is 809 mm long.
const RIG_MIN_LENGTH_MM: f64 = 400.0;
/// Draws before the rig rule gives up (each tried point is an inverse kinematics).
const RIG_MAX_DRAWS: usize = 5_000;

/// "path k: (x, y, z) → (x, y, z) mm".
fn rig_path_name(k: usize, ends: &[[f64; 3]; 2]) -> String {
    let [a, b] = ends;
    format!(
        "path {k}: ({:.0}, {:.0}, {:.0}) → ({:.0}, {:.0}, {:.0}) mm",
        a[0], a[1], a[2], b[0], b[1], b[2]
    )
}

/// Ten straight Cartesian lines for section 7, by a rule fixed before any was measured: ends
/// drawn uniformly in [`RIG_BOX_MM`] (ChaCha8, seed [`TEN_PATHS_SEED`]); a line is kept when
/// it is at least 400 mm long and every one of its [`PATH_POINTS`] points has a nominal joint
/// solution the rig can measure (table reach, the 15° pin rule: [`crate::sec7::cartesian_line`]).
pub fn ten_rig_paths(rig: &Rig) -> Result<Vec<[[f64; 3]; 2]>, PathsError> {
    let [lo, hi] = RIG_BOX_MM;
    let mut rng = ChaCha8Rng::seed_from_u64(TEN_PATHS_SEED);
    let mut paths = Vec::with_capacity(TEN_PATHS);
    for _ in 0..RIG_MAX_DRAWS {
        if paths.len() == TEN_PATHS {
            break;
        }
        let mut draw = || -> [f64; 3] {
            std::array::from_fn(|k| lo[k] + rng.random_range(0.0..1.0) * (hi[k] - lo[k]))
        };
        let ends = [draw(), draw()];
        let length: f64 = (0..3)
            .map(|k| (ends[1][k] - ends[0][k]).powi(2))
            .sum::<f64>()
            .sqrt();
        if length >= RIG_MIN_LENGTH_MM
            && crate::sec7::cartesian_line(rig, ends, PATH_POINTS).is_ok()
        {
            paths.push(ends);
        }
    }
    all_ten(paths)
}

/// Section 7's model of the sweep's seed directory `dir` along each of `paths`, measured by
/// the rig through its own command path (each path a session of its own in `dir/rig/ten-paths/k`).
fn rig_path_rows(
    dir: &Path,
    seed: u64,
    paths: &[[[f64; 3]; 2]],
    preset: &Preset,
) -> Result<Vec<PathRow>, ExtrasError> {
    let out = dir.join("rig");
    let files = crate::sec7::Sec7Files {
        rig: Path::new(REAL_RIG),
        scenario: Path::new(REAL_SCENARIO),
        out: &out,
    };
    let mut rows = Vec::new();
    for (k, ends) in paths.iter().enumerate() {
        let here = out.join("ten-paths").join(format!("{}", k + 1));
        if here.exists() {
            std::fs::remove_dir_all(&here).map_err(|source| DemoError::Io {
                doing: "removing",
                path: here.clone(),
                source,
            })?;
        }
        let run = crate::sec7::measure_another_path(files, *ends, PATH_POINTS, &here)
            .map_err(DemoError::from)?;
        for r in run.results.iter().filter(|r| r.model != "uncalibrated") {
            let finite: Vec<f64> = r.errors.iter().copied().filter(|e| e.is_finite()).collect();
            rows.push(PathRow {
                seed,
                figure: "rig",
                path: k + 1,
                method: r.model.clone(),
                mean_mm: finite.iter().sum::<f64>() / finite.len().max(1) as f64,
                max_mm: finite.iter().copied().fold(0.0, f64::max),
                limit_mm: if r.model == "conventional" {
                    RIG_CONVENTIONAL_MM
                } else {
                    preset.section7.accuracy_mm
                },
            });
        }
    }
    Ok(rows)
}

/// The paper's bound on conventional calibration along the rig's path (section 7: "less than
/// 1.2 mm").
const RIG_CONVENTIONAL_MM: f64 = 1.2;

/// Where a sweep's extras are written in the sweep's directory: `extras.md` (the tables)
/// and `ten-paths.csv` (every row of the ten paths).
pub fn files(out: &Path) -> [PathBuf; 2] {
    [out.join("extras.md"), out.join("ten-paths.csv")]
}
