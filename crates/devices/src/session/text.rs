//! What `rigcal plan` and `rigcal session` print about a plan and a session, and the file of
//! the candidates a plan dropped: the texts live here, beside the figures they render, so that
//! the command line only prints them.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::session::compare::{saving_pct, PlannedVariant};
use crate::session::plan::{Ordering, Plan, PlanError, RigTimeEstimate, REFERENCE_REGION};
use crate::session::procedure::ContactProcedure;
use crate::session::report::SessionReport;
use rigcal_core::kinematics::Robot;
use rigcal_core::rig::{Rig, Unmeasurable};

/// The rig time the paper gives per point (s), which the estimate is set beside.
const PAPER_S_PER_POINT: f64 = 5.0;

impl RigTimeEstimate {
    /// One line on the estimate: the total, motion and contact, and the paper's ~5 s a point
    /// beside it.
    pub fn text(&self) -> String {
        format!(
            "estimated rig time {:.0} s ({:.2} h) for {} points{}: {:.0} s motion, {:.0} s contact; the paper's ~5 s per point would be {:.0} s",
            self.total_s,
            self.total_s / 3600.0,
            self.points - self.registration_points,
            if self.registration_points > 0 {
                format!(" and {} registration poses", self.registration_points)
            } else {
                String::new()
            },
            self.motion_s,
            self.contact_s,
            PAPER_S_PER_POINT * self.points as f64
        )
    }

    /// The estimate's breakdown, one part a line (s and share of the total), no final newline.
    pub fn breakdown_text(&self) -> String {
        self.breakdown
            .parts()
            .iter()
            .map(|(name, s)| {
                format!(
                    "  {name:<18} {s:>8.0} s  {:>3.0} %",
                    100.0 * s / self.total_s.max(1e-9)
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// The same points in the compared orders and procedures, one a line, each with its saving
/// against the first (the paper's order with the baseline procedure); `chosen` marked. No final
/// newline.
pub fn comparison_text(
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

impl Plan {
    /// Where [`Plan::write_dropped`] writes the dropped candidates of a plan written to
    /// `plan_path`: beside it, `<plan>.dropped.csv`.
    pub fn dropped_path(plan_path: &Path) -> PathBuf {
        plan_path.with_extension("dropped.csv")
    }

    /// The dropped candidates as CSV: `candidate,q1_deg..qN_deg,reason` (degrees or mm, three
    /// decimals; the reason quoted).
    pub fn dropped_csv(&self, rig: &Rig) -> String {
        let mut s = String::from("candidate");
        for (i, j) in rig.chain.joints().iter().enumerate() {
            let _ = write!(s, ",{}", j.kind.column(i + 1));
        }
        s.push_str(",reason\n");
        for (k, d) in self.dropped.iter().enumerate() {
            let _ = write!(s, "{}", k + 1);
            for (spec, v) in rig.chain.joints().iter().zip(&d.q) {
                let _ = write!(s, ",{:.3}", spec.kind.to_file_units(*v));
            }
            let _ = writeln!(s, ",\"{}\"", d.reason.to_string().replace('"', "'"));
        }
        s
    }

    /// The line `rigcal plan` prints once the plan is written to `plan_path`: its points and
    /// how many of them re-measure the drift reference.
    pub fn written_text(&self, plan_path: &Path) -> String {
        let references = self.points.iter().filter(|x| x.region == REFERENCE_REGION);
        format!(
            "planned {} points ({} drift references) → {}",
            self.points.len(),
            references.count(),
            plan_path.display()
        )
    }

    /// Writes every dropped candidate with its reason beside `plan_path`
    /// ([`Plan::dropped_path`]) and returns the summary to print: the count and where, then the
    /// count by reason, a line each.
    pub fn write_dropped(&self, rig: &Rig, plan_path: &Path) -> Result<String, PlanError> {
        let mut by: BTreeMap<String, usize> = BTreeMap::new();
        for d in &self.dropped {
            *by.entry(reason_kind(&d.reason)).or_default() += 1;
        }
        let path = Plan::dropped_path(plan_path);
        std::fs::write(&path, self.dropped_csv(rig)).map_err(|source| PlanError::Write {
            path: path.clone(),
            source,
        })?;
        let mut s = format!(
            "dropped {} infeasible candidates (every one with its reason in {}):\n",
            self.dropped.len(),
            path.display()
        );
        for (reason, n) in by {
            let _ = writeln!(s, "  {n:>7}  {reason}");
        }
        Ok(s)
    }
}

/// The kind of reason a candidate was dropped for, as the summary counts them.
fn reason_kind(reason: &Unmeasurable) -> String {
    match reason {
        Unmeasurable::JointLimit { .. } => "joint limit".to_string(),
        Unmeasurable::PinAngle { .. } => "pin angle to the panel".to_string(),
        Unmeasurable::TableTravel { axis, .. } => format!("table {axis} travel"),
    }
}

impl SessionReport {
    /// What `rigcal session` prints at the end of the session in `dir`: the counts, the skipped
    /// points and cleared faults, the registration and the rig time (`virtual_clock` for a dry
    /// run, whose rig time is what the rig would have taken); every line ends in a newline.
    pub fn text(&self, dir: &Path, virtual_clock: bool) -> String {
        let mut s = format!(
            "session {}: {} points, {} measured{}, {} skipped, {} via rows, {} retries, {} faults cleared, {} extra passes\n",
            dir.display(),
            self.points,
            self.ok,
            match self.resumed_at {
                Some(k) if k >= self.points => " (already finished: nothing left to measure)".to_string(),
                Some(k) => format!(" (this run, resumed at point {})", k + 1),
                None => String::new(),
            },
            self.skipped.len(),
            self.via,
            self.retries,
            self.faults_cleared.len(),
            self.extra_passes
        );
        for (p, why) in &self.skipped {
            let _ = writeln!(s, "  point {p} skipped: {why}");
        }
        for f in &self.faults_cleared {
            let _ = writeln!(s, "  cleared: {f}");
        }
        if let Some(rms) = self.registration_rms_mm {
            let _ = writeln!(s, "registration RMS {rms:.3} mm (written to session.toml)");
        }
        let _ = writeln!(
            s,
            "rig time {:.0} s ({:.2} h){}; wall time {:.2} s",
            self.rig_time_s,
            self.rig_time_s / 3600.0,
            if virtual_clock {
                " on the virtual clock: what the rig would have taken"
            } else {
                ""
            },
            self.wall.as_secs_f64()
        );
        s
    }

    /// The estimate `estimated_s` set beside the rig time the session took (one line, no final
    /// newline).
    pub fn beside_estimate_text(&self, estimated_s: f64) -> String {
        format!(
            "estimated {:.0} s beside it ({:+.1} %)",
            estimated_s,
            100.0 * (estimated_s / self.rig_time_s.max(1e-9) - 1.0)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::plan::TimeBreakdown;

    #[test]
    fn the_estimate_line_names_the_registration_poses_and_the_papers_rate() {
        let e = RigTimeEstimate {
            total_s: 3600.0,
            motion_s: 1600.0,
            contact_s: 2000.0,
            points: 112,
            registration_points: 12,
            breakdown: TimeBreakdown::default(),
        };
        assert_eq!(
            e.text(),
            "estimated rig time 3600 s (1.00 h) for 100 points and 12 registration poses: 1600 s motion, 2000 s contact; the paper's ~5 s per point would be 560 s"
        );
    }

    #[test]
    fn a_resumed_finished_session_says_nothing_was_left() {
        let r = SessionReport {
            points: 10,
            ok: 10,
            resumed_at: Some(10),
            rig_time_s: 100.0,
            ..Default::default()
        };
        let text = r.text(Path::new("s"), true);
        assert!(
            text.starts_with("session s: 10 points, 10 measured (already finished: nothing left to measure), 0 skipped"),
            "{text}"
        );
        assert_eq!(
            r.beside_estimate_text(110.0),
            "estimated 110 s beside it (+10.0 %)"
        );
    }
}
