//! The variable D-H parameter model: division → CEPs per region → learner → model file.
//!
//! A recording in an instrument's own frame (a free measurement frame: a tracker) is
//! registered into the rig's world frame first ([`registered`]).

mod registered;

pub use registered::RegionParams;

use super::{
    check_scenario_rig, design_basis, Calibrated, CalibrationError, CalibrationOptions,
    DivisionFigures, Figures, LearnerFigures, Source, UnmeasurableFigures,
};
use rigcal_core::rig::Rig;
use rigcal_model::division::{
    divide, Bounds, DivisionOptions, DivisionReport, DivisionSpace, MeasureError, Measurer, Mode,
};
use rigcal_model::identification::Observation;
use rigcal_model::learners::{self, Learner};
use rigcal_model::model::{
    cep_scale, entries, summary, DivisionSummary, ModelBody, ModelFile, Provenance,
};
use rigcal_sim::world::{Scenario, World};
use std::time::Instant;

/// A simulated world as a division's measurer: each call is the next measurement, taken
/// `step_s` after the previous one, with the world's motion history (backlash, drift).
pub struct WorldMeasurer {
    /// The truth world.
    pub world: World,
    /// Measurements made.
    pub seq: u64,
    /// Simulated time of the last measurement (s).
    pub t_s: f64,
    /// Time per measurement (s).
    pub step_s: f64,
}

impl WorldMeasurer {
    /// A fresh world of `scenario`, measuring at the scenario's pace.
    pub fn of(scenario: &Scenario) -> Self {
        Self {
            world: scenario.world(),
            seq: 0,
            t_s: 0.0,
            step_s: scenario.measurement.seconds_per_point,
        }
    }
}

impl Measurer for WorldMeasurer {
    fn measure(&mut self, q: &[f64]) -> Result<Option<Observation>, MeasureError> {
        self.seq += 1;
        self.t_s += self.step_s;
        let p = self.world.measure_at(q, self.t_s, self.seq, 0).position;
        Ok(p.map(|p| Observation { q: q.to_vec(), p }))
    }
}

/// Runs the division, trains the learner and builds the model file.
pub(super) fn calibrate(
    rig: &Rig,
    source: Source<'_>,
    opts: &CalibrationOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Calibrated, CalibrationError> {
    opts.check()?;
    // Offline in an instrument's frame: the division runs on the registered points of a rig
    // whose frame is fixed, and the frame is put back into the model at the end.
    match source {
        Source::Offline {
            observations,
            label,
        } if registered::needs_registration(rig) && !observations.is_empty() => {
            let r =
                registered::Registration::of(rig, observations, opts.space, opts.region_params)?;
            let source = Source::Offline {
                observations: &r.observations,
                label,
            };
            calibrate_on(rig, &r.rig, source, Some(&r), opts, progress)
        }
        source => calibrate_on(rig, rig, source, None, opts, progress),
    }
}

/// [`calibrate`] on `rig` (the caller's, or the registered one of `registration`), the model
/// file written for `model_rig` (the caller's).
fn calibrate_on(
    model_rig: &Rig,
    rig: &Rig,
    source: Source<'_>,
    registration: Option<&registered::Registration>,
    opts: &CalibrationOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Calibrated, CalibrationError> {
    let mode_name = source.mode_name();
    let basis = match registration {
        Some(r) => r.region_basis(&design_basis(rig, opts)),
        None => design_basis(rig, opts),
    };
    let mut division = DivisionOptions {
        space: opts.space,
        accuracy_mm: opts.accuracy_mm,
        max_regions: opts.region_cap(),
        per_region: opts.per_region,
        test_points: opts.test_points,
        selection: opts.selection,
        reuse_parent: opts.reuse_parent,
        seed: opts.seed,
        learner_tolerance: opts.learner_tolerance_in_use(),
        confidence_z: opts.confidence_z,
        test_plan: opts.test_plan,
        split_order: opts.split_order,
        map_prior: opts.map_prior,
        // A registered recording is divided over its own extent, and a half it holds too few
        // points of is a region without measurements (its neighbours' CEPs, the learner
        // generalises), not the end of its parent's split: a recording covers its box unevenly.
        bounds: registration.map(|r| r.bounds),
        unmeasurable_halves: opts.unmeasurable_halves || registration.is_some(),
        ..DivisionOptions::default()
    };
    let t0 = Instant::now();
    let unmeasurable = match opts.unmeasurable_at {
        Some(at) => Some(unmeasurable_region(
            rig, &basis, &source, &division, opts, at,
        )?),
        None => None,
    };
    division.unmeasurable = unmeasurable.as_ref().map(|u| u.bounds);
    let mut world;
    let (mode, label) = match source {
        Source::Offline {
            observations,
            label,
        } => {
            if observations.is_empty() {
                return Err(CalibrationError::NoMeasurements { label });
            }
            (Mode::Offline(observations), label)
        }
        Source::Scenario(sc) => {
            check_scenario_rig(rig, sc)?;
            world = WorldMeasurer::of(sc);
            (
                Mode::Planning(&mut world),
                format!("scenario {}", sc.path.display()),
            )
        }
        Source::Measurer { measurer, label } => (Mode::Planning(measurer), label),
    };
    let report = divide(rig, &basis, mode, &division, progress)?;
    let unmeasurable = unmeasurable.map(|u| u.after(&report));
    let division_time = t0.elapsed();
    let t1 = Instant::now();
    let scale = cep_scale(rig, &basis);
    let init: Vec<f64> = basis
        .iter()
        .map(|&i| report.conventional.params.get(i))
        .collect();
    let measured = learners::Measured {
        robot: &rig.chain,
        space: &report.space,
        basis: &basis,
        conventional: &report.conventional.params,
        observations: &report.observations,
    };
    let learner = learners::train(
        opts.learner,
        &opts.learner_settings,
        &report.tree,
        &init,
        &scale,
        Some(&measured),
    );
    let mut figures = figures(&report, opts, mode_name);
    figures.unmeasurable = unmeasurable.map(Box::new);
    figures.learner = learner.as_ref().map(learner_figures);
    figures.division_time = division_time;
    figures.learner_time = t1.elapsed();
    let region = figures.unmeasurable.as_ref().map(|u| u.bounds);
    let mut model = model_file(model_rig, report, learner, opts, mode_name, label, region);
    if let Some(r) = registration {
        r.restore(&mut model);
        let note = r.text(opts.space);
        model.fitted_from.notes = Some(match model.fitted_from.notes.take() {
            Some(n) => format!("{n}; {note}"),
            None => note,
        });
    }
    Ok(Calibrated {
        model,
        figures: Figures::Division(figures),
    })
}

/// `model` (a variable D-H model of `rig`) with its learner replaced by one of `kind` trained on
/// the same region tree from the same conventional start: seed 000's FCMAC-against-CMAC
/// comparison on one division, no new measurement. `LearnerKind::None` drops the learner. A
/// model file keeps no measurements, so an FCMAC here learns the CEPs only (the paper's
/// training), whatever `settings.training` asks.
pub fn with_learner(
    model: &ModelFile,
    rig: &Rig,
    kind: learners::LearnerKind,
    settings: &learners::LearnerSettings,
) -> Result<ModelFile, CalibrationError> {
    settings.check()?;
    let ModelBody::Variable {
        conventional, tree, ..
    } = &model.model
    else {
        return Err(CalibrationError::NotVariable);
    };
    let path = std::path::Path::new("<model>");
    let layout = rigcal_core::kinematics::Robot::layout(&rig.chain);
    let basis = tree
        .basis
        .iter()
        .map(|n| layout.find(n).and_then(|id| layout.index_of(id)))
        .collect::<Option<Vec<usize>>>()
        .ok_or(CalibrationError::NotVariable)?;
    let start = rigcal_model::model::params_from_entries(rig, conventional, path)?;
    let init: Vec<f64> = basis.iter().map(|&i| start.get(i)).collect();
    let trained = learners::train(kind, settings, tree, &init, &cep_scale(rig, &basis), None);
    let mut out = model.clone();
    if let ModelBody::Variable { learner: l, .. } = &mut out.model {
        *l = trained;
    }
    Ok(out)
}

/// The model file of a division and its learner.
fn model_file(
    rig: &Rig,
    report: DivisionReport,
    learner: Option<Learner>,
    opts: &CalibrationOptions,
    mode_name: &str,
    label: String,
    unmeasurable: Option<Bounds>,
) -> ModelFile {
    let division = DivisionSummary {
        accuracy_mm: opts.accuracy_mm,
        max_regions: opts.region_cap(),
        per_region: opts.per_region,
        regions: report.tree.leaf_count(),
        measurements: report.observations.len(),
        test_measurements: report.test_measurements,
        mode: mode_name.into(),
        design_poses: opts.design_poses,
        learner_tolerance: opts.learner_tolerance_in_use(),
        unmeasurable,
    };
    ModelFile::new(
        rig,
        Provenance {
            recording: Some(label),
            measurements: report.observations.len(),
            notes: Some(format!(
                "{mode_name} division in {:?} space, {:?} selection, seed {}",
                opts.space, opts.selection, opts.seed
            )),
        },
        ModelBody::Variable {
            conventional: entries(rig, &report.conventional),
            fit: summary(&report.conventional),
            division,
            tree: report.tree,
            learner,
        },
    )
}

/// The division's figures (the learner's and the times are filled in by the caller).
fn figures(r: &DivisionReport, opts: &CalibrationOptions, mode: &str) -> DivisionFigures {
    let leaves = r.tree.root.leaves();
    let passing = leaves
        .iter()
        .filter(|l| l.test.is_some_and(|t| t.verdict_mm() <= opts.accuracy_mm))
        .count();
    let mut kappas: Vec<f64> = leaves
        .iter()
        .map(|l| l.kappa)
        .filter(|k| k.is_finite())
        .collect();
    kappas.sort_by(f64::total_cmp);
    let kappa = kappas.last().map(|&max| (kappas[kappas.len() / 2], max));
    let unsplit = leaves
        .iter()
        .filter_map(|l| Some((l.id.clone(), l.note.clone()?)))
        .take(5)
        .collect();
    DivisionFigures {
        mode: mode.into(),
        space: opts.space,
        accuracy_mm: opts.accuracy_mm,
        per_region: opts.per_region,
        selection: opts.selection,
        max_regions: opts.region_cap(),
        regions: leaves.len(),
        passing,
        measurements: r.observations.len(),
        test_measurements: r.test_measurements,
        kappa,
        unsplit,
        conventional_mm: (r.conventional.after.rms_mm, r.conventional.after.max_mm),
        unmeasurable: None,
        learner: None,
        learner_tolerance: opts.learner_tolerance_in_use(),
        division_time: Default::default(),
        learner_time: Default::default(),
    }
}

fn learner_figures(l: &Learner) -> LearnerFigures {
    match l {
        Learner::Fcmac(f) => LearnerFigures::Fcmac {
            sensors: f.config.cells,
            c: f.config.c,
            cells: f.cell_count(),
            report: f.report,
            positions: f.positions,
        },
        Learner::Cmac(c) => LearnerFigures::Cmac {
            layers: c.config.layers,
            cells: c.config.cells,
            report: c.report,
        },
    }
}

/// The unmeasurable region of a Fig. 8 calibration: the region of the division containing
/// `at` (file units) at the depth asked for, or, without one, at the depth of the leaf that
/// contains it in the same division made without it (a first division whose measurements are
/// all dropped: only its shape is kept).
fn unmeasurable_region(
    rig: &Rig,
    basis: &[usize],
    source: &Source<'_>,
    division: &DivisionOptions,
    opts: &CalibrationOptions,
    at: [f64; 3],
) -> Result<UnmeasurableFigures, CalibrationError> {
    let x = division_point(opts.space, at);
    // The box divided: a registered recording's own extent, else the rig's workspace.
    let full = match division.bounds {
        Some(b) => b,
        None => {
            DivisionSpace::new(rig, opts.space)
                .map_err(rigcal_model::division::DivisionError::from)?
                .full
        }
    };
    if !full.holds(&x) {
        return Err(CalibrationError::Option {
            option: "--unmeasurable-at",
            reason: "lies outside the division space".into(),
        });
    }
    let depth = match opts.unmeasurable_depth {
        Some(d) => d,
        None => depth_of_leaf_at(rig, basis, source, division, &x)?,
    };
    let (bounds, region) = Bounds::region_at(&full, &x, depth);
    if depth == 0 || bounds.min_fraction(&full) < division.min_fraction {
        return Err(CalibrationError::Option {
            option: "--unmeasurable-depth",
            reason: format!(
                "{depth}: the region must be a part of the workspace (depth at least 1) that the division can reach (no narrower than 1/{:.0} of it)",
                1.0 / division.min_fraction
            ),
        });
    }
    Ok(UnmeasurableFigures {
        at,
        region,
        depth,
        bounds,
        borrowed_from: None,
    })
}

/// The depth of the leaf containing `x` in the division of `source` made with `division`.
fn depth_of_leaf_at(
    rig: &Rig,
    basis: &[usize],
    source: &Source<'_>,
    division: &DivisionOptions,
    x: &[f64; 3],
) -> Result<usize, CalibrationError> {
    let mut world;
    let mode = match source {
        Source::Offline { observations, .. } => Mode::Offline(observations),
        Source::Scenario(sc) => {
            world = WorldMeasurer::of(sc);
            Mode::Planning(&mut world)
        }
        Source::Measurer { .. } => {
            return Err(CalibrationError::Option {
                option: "--unmeasurable-at",
                reason: "through a measurer (a session) needs --unmeasurable-depth: finding the region's depth would measure the whole division twice".into(),
            })
        }
    };
    let first = divide(rig, basis, mode, division, |_, _| {})?;
    Ok(first.tree.root.leaf_at(x, &first.tree.full).id.len() - 1)
}

impl UnmeasurableFigures {
    /// The figures once the division is made: the neighbours the region borrowed from.
    fn after(mut self, report: &DivisionReport) -> Self {
        self.borrowed_from = report
            .tree
            .unmeasurable()
            .into_iter()
            .find(|l| l.id == self.region)
            .and_then(|l| l.borrowed_from.clone());
        self
    }

    /// What `rigcal calibrate` prints about it.
    pub fn text(&self) -> String {
        let [a, b, c] = self.at;
        match &self.borrowed_from {
            Some(ids) => format!(
                "region {} (depth {}, containing {a},{b},{c}) could not be measured: no measurement was taken inside it and none of its points reached any fit; without a learner it takes the mean CEPs of its {} neighbours ({})",
                self.region,
                self.depth,
                ids.len(),
                ids.join(" ")
            ),
            None => format!(
                "region {} (depth {}, containing {a},{b},{c}) could not be measured: no measurement inside it; the division did not reach it as a region of its own (region cap), so it lies in a larger region fitted around it",
                self.region, self.depth
            ),
        }
    }
}

/// A division-space point from file units (deg for angles, mm for R).
fn division_point(space: rigcal_model::division::Space, p: [f64; 3]) -> [f64; 3] {
    match space {
        rigcal_model::division::Space::Joint => p.map(f64::to_radians),
        rigcal_model::division::Space::Cartesian => [p[0], p[1].to_radians(), p[2].to_radians()],
    }
}

impl DivisionFigures {
    /// The figures as `rigcal calibrate` prints them.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        if let Some(u) = &self.unmeasurable {
            let _ = writeln!(s, "{}", u.text());
        }
        let _ = writeln!(
            s,
            "{} division in {:?} space, demanded accuracy {} mm, {} per region ({:?} selection) (paper: {})",
            self.mode,
            self.space,
            self.accuracy_mm,
            self.per_region,
            self.selection,
            self.space.paper_figures()
        );
        let _ = writeln!(
            s,
            "  regions {} (cap {}), {} meet the accuracy on their test points; {} identification measurements, {} test measurements; {:.2} s",
            self.regions,
            self.max_regions,
            self.passing,
            self.measurements,
            self.test_measurements,
            self.division_time.as_secs_f64()
        );
        if let Some((median, max)) = self.kappa {
            let _ = writeln!(
                s,
                "  κ (eq. 4) per region: median {median:.3e}, max {max:.3e}"
            );
        }
        for (id, note) in &self.unsplit {
            let _ = writeln!(s, "  region {id} not split further: {note}");
        }
        let _ = writeln!(
            s,
            "  conventional fit on the same data: RMS {:.4} mm, max {:.4} mm",
            self.conventional_mm.0, self.conventional_mm.1
        );
        let _ = writeln!(s, "{}", self.learner_line());
        s
    }

    fn learner_line(&self) -> String {
        let t = self.learner_time.as_secs_f64();
        let tolerance = if self.learner_tolerance > 0.0 {
            format!(
                " (learner tolerance {} × the demand: {:.3} mm RMS)",
                self.learner_tolerance,
                self.learner_tolerance * self.accuracy_mm
            )
        } else {
            String::new()
        };
        let training = |r: &Option<learners::TrainReport>| {
            let text = r.map_or_else(|| "not trained".to_string(), |r| r.text());
            format!("on the CEPs{tolerance}: {text}")
        };
        match &self.learner {
            Some(LearnerFigures::Fcmac {
                sensors,
                c,
                cells,
                report,
                positions,
            }) => format!(
                "  FCMAC: {sensors:?} sensors, c = {c:?}, {cells} association cells; {}{}; {t:.2} s",
                training(report),
                positions.map_or_else(String::new, |p| format!("; then {}", p.text()))
            ),
            Some(LearnerFigures::Cmac {
                layers,
                cells,
                report,
            }) => format!(
                "  CMAC: {layers} layers of {cells:?} cells; {}; {t:.2} s",
                training(report)
            ),
            None => "  no learner: compensation uses each region's CEPs".to_string(),
        }
    }
}
