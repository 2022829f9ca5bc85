//! Self-contained HTML reports (inline CSS and SVG, no network) of `rigcal identify`,
//! `rigcal calibrate` and `rigcal diagnose`: what was fitted from, the parameters with σ and
//! their correlations (|ρ| > 0.9 flagged), κ, residuals before and after, outliers with their
//! rows, held-out figures, each diagnosed effect with its evidence plot, the division's regions.

use super::svg::{bars, scatter, Series};
use crate::diagnosis::plots::ResidualSeries;
use crate::diagnosis::report::Report;
use crate::identification::{Identification, ResidualStats};
use crate::model::{ModelBody, ModelFile};
use rigcal_core::kinematics::Robot;
use std::fmt::Write as _;

/// Correlations above this (in magnitude) are flagged: the two parameters are nearly
/// interchangeable on these poses.
pub const CORRELATION_WARNING: f64 = 0.9;

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}\
th{background:#f3f3f3}td.name,th.name{text-align:left}.warn{background:#FBE3C8}\
section{margin-bottom:2em}.note{color:#8a4b00}svg{max-width:100%;height:auto}";

/// An HTML document under construction.
#[derive(Debug, Default)]
pub struct Html {
    body: String,
    title: String,
}

/// Text escaped for HTML.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

impl Html {
    /// A document with a title.
    pub fn new(title: &str) -> Self {
        Self {
            body: String::new(),
            title: title.into(),
        }
    }

    /// Opens a `<section id=…>` with a heading.
    pub fn section(&mut self, id: &str, heading: &str) {
        if !self.body.is_empty() {
            self.body.push_str("</section>\n");
        }
        let _ = writeln!(self.body, "<section id=\"{id}\"><h2>{}</h2>", esc(heading));
    }

    /// A paragraph of text.
    pub fn p(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", esc(text));
    }

    /// A warning paragraph.
    pub fn warn(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p class=\"note warn\">⚠ {}</p>", esc(text));
    }

    /// A table: header cells, rows of cells (the first cell of each row is a name), and per row
    /// whether to flag it.
    pub fn table(&mut self, id: &str, header: &[&str], rows: &[(Vec<String>, bool)]) {
        let _ = write!(self.body, "<table id=\"{id}\"><thead><tr>");
        for (k, h) in header.iter().enumerate() {
            let class = if k == 0 { " class=\"name\"" } else { "" };
            let _ = write!(self.body, "<th{class}>{}</th>", esc(h));
        }
        self.body.push_str("</tr></thead><tbody>\n");
        for (cells, flag) in rows {
            let class = if *flag { " class=\"warn\"" } else { "" };
            let _ = write!(self.body, "<tr{class}>");
            for (k, c) in cells.iter().enumerate() {
                let class = if k == 0 { " class=\"name\"" } else { "" };
                let _ = write!(self.body, "<td{class}>{}</td>", esc(c));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</tbody></table>\n");
    }

    /// Inline SVG (as written by [`super::svg`]).
    pub fn svg(&mut self, svg: &str) {
        let _ = writeln!(self.body, "<figure>{svg}</figure>");
    }

    /// The whole document.
    pub fn finish(mut self) -> String {
        if !self.body.is_empty() {
            self.body.push_str("</section>\n");
        }
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{t}</title><style>{CSS}</style></head><body><h1>{t}</h1>\n{}<footer><p>rigcal {}</p></footer></body></html>\n",
            self.body,
            env!("CARGO_PKG_VERSION"),
            t = esc(&self.title),
        )
    }
}

fn f4(v: f64) -> String {
    super::svg::tick(v)
}

fn stats_row(name: &str, s: &ResidualStats) -> (Vec<String>, bool) {
    (
        vec![
            name.into(),
            s.n.to_string(),
            format!("{:.4}", s.rms_mm),
            format!("{:.4}", s.mean_mm),
            format!("{:.4}", s.max_mm),
        ],
        false,
    )
}

const STATS_HEADER: [&str; 5] = ["", "points", "RMS (mm)", "mean (mm)", "max (mm)"];

/// What the report was made from.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    /// The rig's name.
    pub rig: &'a str,
    /// The rig file.
    pub rig_path: &'a str,
    /// The recording.
    pub recording: &'a str,
    /// Rows in the recording.
    pub rows: usize,
}

impl<'a> Source<'a> {
    /// A report on `rows` rows of the recording at `recording`, read with `rig` from the rig
    /// file at `rig_path` (a path that is not UTF-8 reads `(rig file)` or `(recording)`).
    pub fn of(
        rig: &'a rigcal_core::rig::Rig,
        rig_path: &'a std::path::Path,
        recording: &'a std::path::Path,
        rows: usize,
    ) -> Self {
        Source {
            rig: &rig.name,
            rig_path: rig_path.to_str().unwrap_or("(rig file)"),
            recording: recording.to_str().unwrap_or("(recording)"),
            rows,
        }
    }
}

fn source_section(h: &mut Html, s: &Source<'_>) {
    h.section("source", "Fitted from");
    h.table(
        "source-table",
        &["", "value"],
        &[
            (
                vec!["rig".into(), format!("{} ({})", s.rig, s.rig_path)],
                false,
            ),
            (vec!["recording".into(), s.recording.into()], false),
            (vec!["rows".into(), s.rows.to_string()], false),
        ],
    );
}

/// The HTML report of an identification.
pub fn identification_report(source: &Source<'_>, id: &Identification) -> String {
    let mut h = Html::new(&format!("rigcal identify: {}", source.rig));
    source_section(&mut h, source);
    let layout = id.chain.layout();
    let fit = &id.fit;
    h.section("parameters", "Parameters");
    let names: Vec<String> = fit
        .free
        .iter()
        .map(|&i| layout.name(layout.ids()[i]))
        .collect();
    let rows: Vec<_> = fit
        .free
        .iter()
        .zip(&fit.sigma)
        .zip(&names)
        .map(|((&i, &sd), n)| {
            let k = layout.ids()[i].kind;
            (
                vec![
                    n.clone(),
                    format!("{:+.5}", k.to_file_units(fit.params.get(i))),
                    format!("{:.5}", k.to_file_units(sd)),
                    k.unit().into(),
                ],
                false,
            )
        })
        .collect();
    h.table(
        "parameter-table",
        &["parameter", "value", "σ", "unit"],
        &rows,
    );
    h.p(&format!(
        "κ (eq. 4, column-scaled condition): {:.1}; σ̂ per coordinate {:.4} mm; {} iterations.",
        fit.kappa, fit.sigma0_mm, fit.iterations
    ));
    correlation_section(&mut h, &names, &fit.covariance);
    h.section("residuals", "Residuals before and after");
    h.table(
        "residual-table",
        &STATS_HEADER,
        &[
            stats_row("before (nominal)", &fit.before),
            stats_row("after (fitted)", &fit.after),
        ],
    );
    let series: Vec<Series> = ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(a, n)| Series {
            name: format!("residual {n}"),
            points: fit
                .residuals
                .iter()
                .enumerate()
                .map(|(i, r)| (i as f64, r[a]))
                .collect(),
        })
        .collect();
    h.svg(&scatter(
        "residual after the fit, by measurement (binned mean ± 2 s.e.)",
        "measurement",
        "residual (mm)",
        &series,
        true,
    ));
    outlier_section(&mut h, &id.outliers, id.outlier_warning.as_deref());
    h.section("heldout", "Held-out recordings");
    if id.heldout.is_empty() {
        h.p("No held-out recording was given (--heldout).");
    }
    let mut rows = Vec::new();
    for r in &id.heldout {
        rows.push(stats_row(&format!("{} nominal", r.name), &r.nominal));
        rows.push(stats_row(&format!("{} fitted", r.name), &r.fitted));
    }
    h.table("heldout-table", &STATS_HEADER, &rows);
    if !id.heldout.is_empty() {
        h.svg(&bars(
            "held-out RMS",
            "RMS (mm)",
            &id.heldout
                .iter()
                .map(|r| r.name.clone())
                .collect::<Vec<_>>(),
            &[
                (
                    "nominal".into(),
                    id.heldout.iter().map(|r| r.nominal.rms_mm).collect(),
                ),
                (
                    "fitted".into(),
                    id.heldout.iter().map(|r| r.fitted.rms_mm).collect(),
                ),
            ],
        ));
    }
    h.finish()
}

/// Correlations from a covariance matrix (zero variances give zero).
pub fn correlations(cov: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let n = cov.nrows();
    nalgebra::DMatrix::from_fn(n, n, |i, j| {
        let d = (cov[(i, i)] * cov[(j, j)]).sqrt();
        if d > 0.0 {
            cov[(i, j)] / d
        } else {
            0.0
        }
    })
}

fn correlation_section(h: &mut Html, names: &[String], cov: &nalgebra::DMatrix<f64>) {
    h.section("correlations", "Correlation matrix");
    if cov.nrows() != names.len() {
        h.p("No covariance available.");
        return;
    }
    let rho = correlations(cov);
    let mut pairs = Vec::new();
    let rows: Vec<_> = (0..names.len())
        .map(|i| {
            let mut cells = vec![names[i].clone()];
            let mut flag = false;
            for j in 0..names.len() {
                cells.push(format!("{:.2}", rho[(i, j)]));
                if i < j && rho[(i, j)].abs() > CORRELATION_WARNING {
                    flag = true;
                    pairs.push(format!(
                        "{} ~ {} (ρ = {:.3})",
                        names[i],
                        names[j],
                        rho[(i, j)]
                    ));
                }
            }
            (cells, flag)
        })
        .collect();
    for p in &pairs {
        h.warn(&format!("strongly correlated: {p}"));
    }
    let mut header: Vec<&str> = vec![""];
    header.extend(names.iter().map(String::as_str));
    h.table("correlation-table", &header, &rows);
}

fn outlier_section(
    h: &mut Html,
    outliers: &[crate::identification::outliers::Outlier],
    warning: Option<&str>,
) {
    h.section("outliers", "Outliers");
    if let Some(w) = warning {
        h.warn(w);
    }
    if outliers.is_empty() {
        h.p("None removed.");
    }
    let rows: Vec<_> = outliers
        .iter()
        .map(|o| {
            (
                vec![
                    o.seq.to_string(),
                    o.line.map(|l| l.to_string()).unwrap_or_default(),
                    format!("{:.4}", o.size_mm),
                    format!("{:.1}", o.sigmas),
                    format!(
                        "{:.4} {:.4} {:.4}",
                        o.residual_mm[0], o.residual_mm[1], o.residual_mm[2]
                    ),
                ],
                true,
            )
        })
        .collect();
    h.table(
        "outlier-table",
        &["seq", "line", "size (mm)", "σ", "residual x y z (mm)"],
        &rows,
    );
}

fn residual_plot(title: &str, s: &ResidualSeries) -> String {
    let series: Vec<Series> = ["x", "y", "z"]
        .iter()
        .enumerate()
        .map(|(a, n)| Series {
            name: format!("residual {n}"),
            points: s
                .x
                .iter()
                .zip(&s.residual)
                .map(|(x, r)| (*x, r[a]))
                .collect(),
        })
        .collect();
    scatter(title, &s.label, "residual (mm)", &series, true)
}

/// The HTML report of a diagnosis, with the residual series for the evidence plots.
pub fn diagnosis_report(source: &Source<'_>, r: &Report, residuals: &[ResidualSeries]) -> String {
    let mut h = Html::new(&format!("rigcal diagnose: {}", source.rig));
    source_section(&mut h, source);
    h.section("mismatch", "Mismatch after the geometric fit");
    let m = &r.mismatch;
    h.p(&format!(
        "{}: RMS {:.4} mm against a noise floor of {:.4} mm ({}).",
        if m.significant {
            "significant"
        } else {
            "not significant"
        },
        m.rms_mm,
        m.noise_floor_mm,
        m.noise_source
    ));
    h.section("residuals", "Residuals before and after");
    h.table(
        "residual-table",
        &["", "RMS (mm)"],
        &[
            (
                vec![
                    "geometric fit".into(),
                    format!("{:.4}", r.fit.before_rms_mm),
                ],
                false,
            ),
            (
                vec![
                    "with the named effects".into(),
                    format!("{:.4}", r.fit.after_rms_mm),
                ],
                false,
            ),
        ],
    );
    h.section("effects", "Diagnosed effects");
    if r.effects.is_empty() {
        h.p("No effect named.");
    }
    let rows: Vec<_> = r
        .effects
        .iter()
        .map(|e| {
            (
                vec![
                    e.kind.to_string(),
                    e.joint.map(|j| j.to_string()).unwrap_or_default(),
                    format!("{:.4}", e.size_mm),
                    format!("{:.4}", e.size_sigma_mm),
                    format!("{:.3}", e.visible_fraction),
                    format!("{:.2e}", e.p_value),
                ],
                false,
            )
        })
        .collect();
    h.table(
        "effect-table",
        &["effect", "joint", "size (mm)", "σ (mm)", "visible", "p"],
        &rows,
    );
    for (k, e) in r.effects.iter().enumerate() {
        let _ = write!(h.body, "<div class=\"effect\" id=\"effect-{k}\">");
        h.p(&e.explanation);
        let evidence = residuals
            .iter()
            .find(|s| s.joint.is_some() && s.joint == e.joint)
            .or_else(|| residuals.first());
        if let Some(s) = evidence {
            h.svg(&residual_plot(
                &format!("evidence for {}: residual vs {}", e.kind, s.label),
                s,
            ));
        }
        h.body.push_str("</div>\n");
    }
    if r.unexplained {
        h.warn("A significant structured residual remains that no candidate explains.");
    }
    outlier_section(&mut h, &r.outliers, None);
    h.section("heldout", "Held-out figures");
    h.table(
        "heldout-table",
        &["", "RMS (mm)"],
        &[
            (
                vec![
                    "geometric".into(),
                    r.fit.heldout_before_rms_mm.map(f4).unwrap_or_default(),
                ],
                false,
            ),
            (
                vec![
                    "with the named effects".into(),
                    r.fit.heldout_after_rms_mm.map(f4).unwrap_or_default(),
                ],
                false,
            ),
        ],
    );
    h.p(&format!("held out: {}", r.fit.heldout));
    h.section("plots", "Residuals of the geometric fit");
    for s in residuals {
        h.svg(&residual_plot(&format!("residual vs {}", s.label), s));
    }
    for n in &r.notes {
        h.p(n);
    }
    h.finish()
}

/// The HTML report of a model file (`rigcal calibrate`): the conventional parameters, the fit,
/// the division's regions.
pub fn model_report(source: &Source<'_>, file: &ModelFile) -> String {
    let mut h = Html::new(&format!("rigcal calibrate: {}", source.rig));
    source_section(&mut h, source);
    let (params, fit) = match &file.model {
        ModelBody::Constant { parameters, fit }
        | ModelBody::Variable {
            conventional: parameters,
            fit,
            ..
        } => (parameters.as_slice(), Some(fit)),
        _ => (&[][..], None),
    };
    h.section("parameters", "Parameters (conventional fit)");
    let rows: Vec<_> = params
        .iter()
        .map(|p| {
            (
                vec![
                    p.name.clone(),
                    format!("{:+.5}", p.value),
                    p.sigma.map(|s| format!("{s:.5}")).unwrap_or_default(),
                    p.unit.clone(),
                ],
                false,
            )
        })
        .collect();
    h.table(
        "parameter-table",
        &["parameter", "value", "σ", "unit"],
        &rows,
    );
    if let Some(c) = &file.covariance {
        correlation_section(&mut h, &c.names, &c.matrix());
    }
    if let Some(f) = fit {
        h.p(&format!(
            "κ (eq. 4): {:.1}; σ̂ per coordinate {:.4} mm.",
            f.kappa_eq4, f.sigma0_mm
        ));
        h.section("residuals", "Residuals before and after");
        h.table(
            "residual-table",
            &STATS_HEADER,
            &[stats_row("before", &f.before), stats_row("after", &f.after)],
        );
    }
    outlier_section(&mut h, &file.outliers, None);
    if let ModelBody::Variable { division, tree, .. } = &file.model {
        h.section("regions", "The division's regions");
        h.p(&format!(
            "{} regions for {:.3} mm demanded accuracy ({} mode, {} measurements, {} per region).",
            division.regions,
            division.accuracy_mm,
            division.mode,
            division.measurements,
            division.per_region
        ));
        let rows: Vec<_> = tree
            .root
            .leaves()
            .iter()
            .map(|l| {
                let cep = l
                    .cep
                    .as_ref()
                    .map(|c| {
                        c.iter()
                            .map(|v| format!("{v:.4}"))
                            .collect::<Vec<_>>()
                            .join(" ")
                    })
                    .unwrap_or_else(|| "—".into());
                let test = l
                    .test
                    .map(|t| format!("{:.4} / {:.4}", t.rms_mm, t.max_mm))
                    .unwrap_or_default();
                (
                    vec![
                        l.id.clone(),
                        format!("{:.2?} – {:.2?}", l.bounds.lo, l.bounds.hi),
                        l.measurements.to_string(),
                        format!("{:.1}", l.kappa),
                        test,
                        cep,
                    ],
                    l.cep.is_none(),
                )
            })
            .collect();
        h.table(
            "region-table",
            &[
                "region",
                "bounds",
                "measurements",
                "κ",
                "test RMS / max (mm)",
                "CEPs (internal units)",
            ],
            &rows,
        );
    }
    h.finish()
}
