//! Seed 000's simulations as the demo runs them, each figure beside the paper's: the division
//! behind each of Figs. 6–8, the errors along its path, the error inside Fig. 8's unmeasurable
//! region and the CEP jumps of regions, FCMAC and CMAC. Data (serialised into the demo's
//! `summary.json`) and the text of its `summary.txt`.

use crate::preset::SEED_000;
use rigcal_calibration::path_figures::{MethodFigures, PathFigures};
use rigcal_core::kinematics::Robot;
use rigcal_model::division::{Selection, Space};
use rigcal_model::model::{ModelBody, ModelFile};
use serde::Serialize;
use std::fmt::Write as _;

/// Which of the paper's simulations a run reproduces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PaperFigure {
    /// Fig. 6: joint-space division, the joint path.
    #[serde(rename = "Fig. 6")]
    Fig6,
    /// Fig. 7: Cartesian (spherical) division, the spherical path.
    #[serde(rename = "Fig. 7")]
    Fig7,
    /// Fig. 8: Fig. 6 with one region on the path unmeasurable.
    #[serde(rename = "Fig. 8")]
    Fig8,
}

impl PaperFigure {
    /// The figure's name.
    pub fn name(self) -> &'static str {
        match self {
            PaperFigure::Fig6 => "Fig. 6",
            PaperFigure::Fig7 => "Fig. 7",
            PaperFigure::Fig8 => "Fig. 8",
        }
    }

    /// What the paper reports for a method along this figure's path (seed 000 section 6).
    fn paper_says(self, method: &str) -> &'static str {
        match (self, method) {
            (PaperFigure::Fig6 | PaperFigure::Fig8, "uncalibrated") => "0.4–1.2",
            (PaperFigure::Fig6, "conventional") => "below 0.2",
            (PaperFigure::Fig6, "regions" | "fcmac") => "below 0.1",
            (PaperFigure::Fig7, _) => "similar to Fig. 6",
            (PaperFigure::Fig8, "regions" | "fcmac") => "satisfactory",
            _ => "not given",
        }
    }
}

/// One division of the paper's regime and the errors along its figure's path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FigureRun {
    /// The figure.
    pub figure: PaperFigure,
    /// The division's space.
    pub division: Space,
    /// How measurement locations were chosen.
    pub selection: Selection,
    /// Measurements asked for per region.
    pub per_region: usize,
    /// Regions made (leaves).
    pub regions: usize,
    /// Identification measurements used (each location once: a half's reused parent points
    /// are not counted again).
    pub measurements: usize,
    /// Test measurements made (counted apart from the identification measurements).
    pub test_measurements: usize,
    /// The figure's path (and, for Fig. 8, inside the unmeasurable region).
    pub path: PathFigures,
}

impl FigureRun {
    /// The run of `figure` from its model file (made with `selection`) and the figures along its
    /// path; None for a model that is not a division.
    pub fn of(
        figure: PaperFigure,
        selection: Selection,
        model: &ModelFile,
        path: PathFigures,
    ) -> Option<Self> {
        let ModelBody::Variable { division, tree, .. } = &model.model else {
            return None;
        };
        Some(Self {
            figure,
            division: tree.space,
            selection,
            per_region: division.per_region,
            regions: division.regions,
            measurements: division.measurements,
            test_measurements: division.test_measurements,
            path,
        })
    }

    fn text(&self) -> String {
        let paper_regions = SEED_000.region_cap(self.division);
        let paper_measurements = paper_regions * SEED_000.per_region;
        let mut s = format!(
            "  {}: {:?}-space division, {:?} selection, {} per region: {} regions, {} identification + {} test measurements (paper {paper_regions} regions, {paper_measurements} identification); {}, mean / max mm\n    ",
            self.figure.name(),
            self.division,
            self.selection,
            self.per_region,
            self.regions,
            self.measurements,
            self.test_measurements,
            self.path.path
        );
        for m in &self.path.methods {
            let _ = write!(
                s,
                "  {} {:.4} / {:.4} (paper {})",
                m.method,
                m.mean_mm,
                m.max_mm,
                self.figure.paper_says(&m.method)
            );
        }
        s.push('\n');
        if let Some(inside) = &self.path.inside_unmeasurable {
            let region = inside
                .region
                .as_deref()
                .unwrap_or("(not a region of its own)");
            let _ = write!(
                s,
                "    inside the unmeasurable region {region} ({} points; regions = its neighbours' mean CEPs):",
                inside.points.len()
            );
            for m in inside.methods.iter().filter(|m| m.method != "uncalibrated") {
                let _ = write!(s, "  {} {:.4} / {:.4}", m.method, m.mean_mm, m.max_mm);
            }
            s.push_str(" (paper: satisfactory with and without the FCMAC)\n");
        }
        s
    }
}

/// The paper's regime as the demo ran it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperRegimeSummary {
    /// The scenario file.
    pub scenario: String,
    /// Non-geometric share on the Fig. 6 path (conventions §3).
    pub non_geometric_share: f64,
    /// Demanded accuracy (mm).
    pub accuracy_mm: f64,
    /// Measurements per region.
    pub per_region: usize,
    /// Figs. 6, 7 and 8.
    pub runs: Vec<FigureRun>,
    /// Figs. 6 and 7 again at about half the paper's measurements (D-optimal locations, fewer
    /// per region; issue [4/5] item 3).
    pub half_budget: Vec<FigureRun>,
    /// Largest CEP jumps along the Fig. 6 path: regions, FCMAC and CMAC on one division.
    pub cep_jumps: Vec<MethodFigures>,
}

impl PaperRegimeSummary {
    /// The lines of the demo's `summary.txt`.
    pub fn text(&self) -> String {
        let mut s = format!(
            "paper regime: {} on the ideal instrument, {} mm demanded, {} measurements per region; true position error of the simulated arm\n  non-geometric share on the Fig. 6 path {:.1} % (paper 8–10 %)\n",
            self.scenario,
            self.accuracy_mm,
            self.per_region,
            100.0 * self.non_geometric_share
        );
        for run in &self.runs {
            s.push_str(&run.text());
        }
        if !self.half_budget.is_empty() {
            s.push_str("  half the measurements: the same divisions with D-optimal locations and fewer per region (a half keeps its parent's points; tests counted apart)
");
        }
        for run in &self.half_budget {
            s.push_str(&run.text());
        }
        if !self.cep_jumps.is_empty() {
            s.push_str("  largest CEP jump between neighbouring points of the Fig. 6 path (paper: the FCMAC smooth, regions and CMAC abrupt at region boundaries)\n   ");
            for m in &self.cep_jumps {
                let jumps: Vec<String> = m
                    .largest_cep_jump
                    .iter()
                    .map(|(k, v)| format!("{k} {v:.4}"))
                    .collect();
                let _ = write!(s, "  {}: {}", m.method, jumps.join(", "));
                s.push(';');
            }
            s.pop();
            s.push('\n');
        }
        s
    }
}

/// Mean length of a 3-D isotropic Gaussian vector of σ 1 per coordinate: √(8/π) (the mean of
/// the Maxwell distribution).
const MEAN_NORM_PER_SIGMA: f64 = 1.595_769_121_605_731;

/// σ per coordinate (mm) of Gaussian measurement noise whose mean length is `share` of the
/// mean uncalibrated error of `sc` along the Fig. 6 path (101 points): the paper's "random
/// measurement errors (about 3 % of the total error)" read as `share` = 0.03, the way
/// `sim/paper-sim-noise.toml` reads it (0.016 mm there).
pub fn noise_sigma_mm(sc: &rigcal_sim::world::Scenario, share: f64) -> f64 {
    let dof = sc.rig.chain.dof();
    let total = sc
        .world()
        .error_split(&rigcal_sim::world::fig6_path(101, dof))
        .mean_total();
    share * total / MEAN_NORM_PER_SIGMA
}
