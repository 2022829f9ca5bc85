//! Conventional calibration as `rigcal identify` runs it: the text of an identification (its
//! outliers, the parameter table, the fit, the held-out errors), training on several sessions
//! each in its own frame, and the model file it writes; what a rig can identify
//! (`rigcal observability`), the table-to-world registration (`rigcal register`), and named
//! effects checked on held-out sessions (`rigcal diagnose --heldout-session`).

use rigcal_core::kinematics::{ParamLayout, Robot};
use rigcal_core::recording::Recording;
use rigcal_core::rig::Rig;
use rigcal_model::diagnosis::sessions::{
    fit_sessions, heldout_sessions, physics_heldout, without_rows, PerSession, SessionError,
};
use rigcal_model::diagnosis::Report;
use rigcal_model::identification::outliers::Outlier;
use rigcal_model::identification::registration::Registration;
use rigcal_model::identification::{
    analyse, candidate_order, identifiability, joint_label, random_poses, FitResult, HeldOut,
    Identification, Level,
};
use rigcal_model::model::effects::{fit_recording_effects, EffectError, EffectSpec, ModelEffect};
use rigcal_model::model::{ModelFile, Provenance};
use std::fmt::Write as _;
use std::path::Path;

/// An identification as `rigcal identify` prints it: the outliers, the parameter table, the
/// fit summary and the held-out errors (its outlier warning is the caller's to show).
pub fn identification_text(id: &Identification) -> String {
    let mut s = outliers_text(&id.outliers);
    s.push_str(&parameter_table(id.chain.layout(), &id.fit));
    s.push_str(&fit_summary_text(&id.fit));
    for h in &id.heldout {
        let _ = writeln!(
            s,
            "held-out {} ({} points): nominal kinematics RMS {:.4} mm, max {:.4} mm → fitted RMS {:.4} mm, max {:.4} mm",
            h.name, h.points, h.nominal.rms_mm, h.nominal.max_mm, h.fitted.rms_mm, h.fitted.max_mm
        );
    }
    s
}

/// The outliers removed from a fit (or that there were none).
fn outliers_text(outliers: &[Outlier]) -> String {
    if outliers.is_empty() {
        return "outliers: none\n".into();
    }
    let mut s = String::new();
    for o in outliers {
        let line = o.line.map(|l| format!(", line {l}")).unwrap_or_default();
        let _ = writeln!(
            s,
            "outlier removed from the fit: seq {}{line}, {:.4} mm off ({:.1} σ; residual x {:.4}, y {:.4}, z {:.4} mm)",
            o.seq, o.size_mm, o.sigmas, o.residual_mm[0], o.residual_mm[1], o.residual_mm[2]
        );
    }
    s
}

/// κ and the residual statistics of a fit.
pub fn fit_summary_text(r: &FitResult) -> String {
    format!(
        "κ (eq. 4): {:.1}   σ̂ per coordinate: {:.4} mm   iterations: {}\nresidual before: RMS {:.4} mm, mean {:.4} mm, max {:.4} mm\nresidual after:  RMS {:.4} mm, mean {:.4} mm, max {:.4} mm  (x {:.4}, y {:.4}, z {:.4})\n",
        r.kappa,
        r.sigma0_mm,
        r.iterations,
        r.before.rms_mm,
        r.before.mean_mm,
        r.before.max_mm,
        r.after.rms_mm,
        r.after.mean_mm,
        r.after.max_mm,
        r.after.axis_rms_mm[0],
        r.after.axis_rms_mm[1],
        r.after.axis_rms_mm[2]
    )
}

/// The fitted parameters with their σ, in file units.
fn parameter_table(layout: &ParamLayout, fit: &FitResult) -> String {
    let mut s = format!("  {:<10} {:>11} {:>10}\n", "parameter", "value", "σ");
    for (k, &i) in fit.free.iter().enumerate() {
        let id = layout.ids()[i];
        let _ = writeln!(
            s,
            "  {:<10} {:>+11.5} {:>10.5} {}",
            layout.symbol(id),
            id.kind.to_file_units(fit.params.get(i)),
            id.kind.to_file_units(fit.sigma[k]),
            id.kind.unit()
        );
    }
    s.push_str(
        &rigcal_model::identification::identifiability::undetermined_text(
            layout,
            &fit.undetermined,
            |i| layout.symbol(layout.ids()[i]),
        ),
    );
    s
}

/// Training on `train`, each session in its own measurement frame (the marker shared), then
/// the sessions of `held` with `per` refitted on each: the identification (in the first
/// session's frame) and the text `rigcal identify` prints for it.
pub fn identify_sessions(
    rig: &Rig,
    train: &[HeldOut],
    held: &[HeldOut],
    level: Level,
    per: PerSession,
) -> Result<(Identification, String), SessionError> {
    let trained = fit_sessions(rig, train, level)?;
    let mut s = String::new();
    for t in &trained.sessions {
        let n = t.recording.observations().len();
        let _ = writeln!(s, "training session {}: {n} measurements used", t.name);
        s.push_str(&outliers_text(&t.outliers));
    }
    s.push_str(&parameter_table(trained.chain.layout(), &trained.fit));
    s.push_str(&fit_summary_text(&trained.fit));
    let _ = writeln!(
        s,
        "training RMS {:.4} mm over {} points, each session in its own frame ({} alternation round(s))",
        trained.training.rms_mm, trained.training.n, trained.rounds
    );
    let _ = writeln!(s, "held-out sessions: {}", per.describe());
    for h in heldout_sessions(rig, &trained.chain, &trained.fit, held, per)? {
        for o in &h.outliers {
            let _ = writeln!(
                s,
                "held-out session {}: bad row seq {} left out ({:.4} mm off the full model, {:.1} σ)",
                h.name, o.seq, o.size_mm, o.sigmas
            );
        }
        let _ = writeln!(
            s,
            "held-out session {} ({} points): nominal kinematics RMS {:.4} mm → fitted RMS {:.4} mm, max {:.4} mm (through the training frame, nothing refitted: {:.4} mm)",
            h.name, h.points, h.nominal_refit.rms_mm, h.refit.rms_mm, h.refit.max_mm, h.frozen.rms_mm
        );
    }
    let id = Identification {
        chain: trained.chain,
        fit: trained.fit,
        outliers: trained
            .sessions
            .into_iter()
            .flat_map(|s| s.outliers)
            .collect(),
        outlier_warning: None,
        heldout: Vec::new(),
    };
    Ok((id, s))
}

/// The effects named by `words` (`backlash:J`, `transmission_error:J:ORDER`,
/// `joint_compliance:J`) fitted on `rec` beside the geometry of `id`: the identification with
/// the joint fit, the effects, and the text `rigcal identify --effects` prints for them.
pub fn identify_effects(
    rig: &Rig,
    rec: &Recording,
    id: Identification,
    words: &[String],
) -> Result<(Identification, Vec<ModelEffect>, String), EffectError> {
    let specs = words
        .iter()
        .map(|w| EffectSpec::parse(w, rig.chain.joints().len()))
        .collect::<Result<Vec<_>, _>>()?;
    let fitted = fit_recording_effects(rig, rec, &id, &specs)?;
    let mut s = String::from("fitted with the effects, beside the geometry:\n");
    for e in &fitted.effects {
        let _ = writeln!(s, "  {}", e.text());
    }
    s.push_str(&fit_summary_text(&fitted.fit));
    let id = Identification {
        fit: fitted.fit,
        ..id
    };
    Ok((id, fitted.effects, s))
}

/// The model file of an identification of the recording at `recording`: the fit, its outliers
/// and any outlier warning, and `effects` fitted beside the geometry.
pub fn model_file(
    rig: &Rig,
    id: &Identification,
    recording: &Path,
    effects: &[ModelEffect],
) -> ModelFile {
    let mut file = ModelFile::constant(
        rig,
        &id.fit,
        Provenance {
            recording: Some(recording.display().to_string()),
            measurements: id.fit.after.n,
            notes: id.outlier_warning.clone(),
        },
    );
    file.outliers = id.outliers.clone();
    file.effects = effects.to_vec();
    file
}

/// Which error parameters position measurements at `poses` random poses (drawn with `seed`)
/// can identify for `rig`, and why not the rest, as `rigcal observability` prints it; with
/// `all_joints` the rig's held joints move too.
pub fn observability_text(rig: &Rig, poses: usize, seed: u64, all_joints: bool) -> String {
    use rand::SeedableRng;
    let held = if all_joints {
        vec![None; rig.chain.dof()]
    } else {
        rig.held().to_vec()
    };
    let joints = rig.chain.joints();
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let design = random_poses(joints, &held, poses, &mut rng);
    let cands = candidate_order(rig);
    let result = analyse(&rig.chain, &design, &cands);
    let layout = rig.chain.layout();
    let moving: Vec<&str> = joints
        .iter()
        .zip(&held)
        .filter(|(_, h)| h.is_none())
        .map(|(j, _)| j.name.as_str())
        .collect();
    let held_list: Vec<String> = joints
        .iter()
        .zip(&held)
        .filter_map(|(j, h)| h.map(|v| format!("{} = {}", j.name, joint_label(j, v))))
        .collect();
    let mut s = format!(
        "rig {} ({}): {} joints, {} error parameters\nmoving: {}",
        rig.name,
        rig.robot_name,
        joints.len(),
        layout.len(),
        moving.join(" ")
    );
    if !held_list.is_empty() {
        let _ = write!(s, "; held: {}", held_list.join(", "));
    }
    let _ = writeln!(
        s,
        "\nmeasurement frame: {:?}, marker: {:?} (fixed ones are not candidates)",
        rig.calibration.measurement_frame, rig.calibration.marker
    );
    if !rig.calibration.basis_priority.is_empty() {
        s.push_str("basis preference from the rig file: the rank is computed; the preference only picks among equivalent bases\n");
    }
    s.push_str(&identifiability::report(layout, &result, cands.len()));
    s
}

/// The geometry and the named effects of `report` fitted on `rec` (its outliers left out),
/// checked on the sessions of `held` with `per` refitted on each, geometry only and with the
/// effects: the text `rigcal diagnose --heldout-session` prints.
pub fn physics_sessions_text(
    rig: &Rig,
    rec: &Recording,
    report: &Report,
    held: &[HeldOut],
    per: PerSession,
) -> Result<String, SessionError> {
    let training = without_rows(rec, report.outliers.iter().map(|o| o.seq));
    let ph = physics_heldout(rig, &training, &report.effects, held, per)?;
    let effects = if ph.effects.is_empty() {
        "none".to_string()
    } else {
        ph.effects.join(", ")
    };
    let mut s = format!(
        "held-out sessions ({}); effects: {effects}\n  training RMS {:.4} mm geometry only, {:.4} mm with the effects\n",
        per.describe(),
        ph.training_geometry,
        ph.training_physics
    );
    for (name, g, p) in &ph.heldout {
        let _ = writeln!(
            s,
            "  held-out session {name}: mean / RMS / max {:.4} / {:.4} / {:.4} mm geometry only, {:.4} / {:.4} / {:.4} mm with the effects",
            g.mean_mm, g.rms_mm, g.max_mm, p.mean_mm, p.rms_mm, p.max_mm
        );
    }
    Ok(s)
}

/// What `rigcal diagnose --model` says of the model file it writes: the named effects `left`
/// out of it, then those in it.
pub fn named_effects_text(file: &ModelFile, left: &[String]) -> String {
    let mut s = String::new();
    for l in left {
        let _ = writeln!(s, "not in the model: {l}");
    }
    for e in &file.effects {
        let _ = writeln!(s, "in the model: {}", e.text());
    }
    s
}

/// A registration as `rigcal register` prints it: the transform with its σ, and the residual.
pub fn registration_text(reg: &Registration) -> String {
    let info = reg.info();
    let (t, rpy, sd) = (info.translation_mm, info.rpy_deg, &reg.sigma);
    format!(
        "registration from {} points (nominal kinematics): world = R · table + t\n  t   = ({:+.4}, {:+.4}, {:+.4}) mm   σ ({:.4}, {:.4}, {:.4}) mm\n  rpy = ({:+.5}, {:+.5}, {:+.5}) deg\n  residual: RMS {:.4} mm, max {:.4} mm (what the nominal kinematics cannot explain; identification absorbs it)\n",
        reg.n,
        t[0],
        t[1],
        t[2],
        sd[0],
        sd[1],
        sd[2],
        rpy[0],
        rpy[1],
        rpy[2],
        reg.stats.rms_mm,
        reg.stats.max_mm
    )
}
