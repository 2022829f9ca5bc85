//! Hand-written inline SVG for the HTML reports: scatter plots with a binned mean and its band,
//! and bar charts, in the Okabe–Ito colour-blind-safe palette, legends outside the data, tick
//! labels without "-0".

use std::fmt::Write as _;

/// The Okabe–Ito palette (black first), as `#rrggbb`.
pub const OKABE_ITO: [&str; 8] = [
    "#000000", "#E69F00", "#56B4E9", "#009E73", "#F0E442", "#0072B2", "#D55E00", "#CC79A7",
];

/// The series colours: Okabe–Ito without black and yellow (too light on white), then those.
pub const SERIES: [&str; 8] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442",
];

const W: f64 = 720.0;
const H: f64 = 360.0;
const LEFT: f64 = 70.0;
const RIGHT: f64 = 160.0;
const TOP: f64 = 34.0;
const BOTTOM: f64 = 48.0;

/// One named series of points.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
}

/// A tick label: at most 4 significant decimals, never "-0".
pub fn tick(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    match s {
        "-0" | "" => "0".into(),
        _ => s.into(),
    }
}

/// "Nice" ticks covering [lo, hi].
pub fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let span = (hi - lo).abs().max(1e-12);
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| span / s <= 6.0)
        .unwrap_or(10.0 * mag);
    let mut t = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while t <= hi + step * 1e-9 {
        // Snap values that are zero but for rounding.
        out.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        t += step;
    }
    out
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

struct Frame {
    x: (f64, f64),
    y: (f64, f64),
}

impl Frame {
    fn px(&self, x: f64) -> f64 {
        LEFT + (x - self.x.0) / (self.x.1 - self.x.0) * (W - LEFT - RIGHT)
    }
    fn py(&self, y: f64) -> f64 {
        H - BOTTOM - (y - self.y.0) / (self.y.1 - self.y.0) * (H - TOP - BOTTOM)
    }
}

fn range(vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = vals
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return (0.0, 1.0);
    }
    if hi - lo < 1e-12 {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = (hi - lo) * 0.04;
    (lo - pad, hi + pad)
}

fn axes(s: &mut String, f: &Frame, title: &str, xlabel: &str, ylabel: &str) {
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}" width="{W}" height="{H}" role="img"><title>{t}</title><rect width="{W}" height="{H}" fill="white"/><text x="{cx}" y="20" text-anchor="middle" font-size="15">{t}</text>"#,
        t = esc(title),
        cx = W / 2.0
    );
    let (x0, x1, y0, y1) = (LEFT, W - RIGHT, TOP, H - BOTTOM);
    let _ = write!(
        s,
        r##"<rect x="{x0}" y="{y0}" width="{}" height="{}" fill="none" stroke="#444"/>"##,
        x1 - x0,
        y1 - y0
    );
    for t in ticks(f.x.0, f.x.1) {
        let x = f.px(t);
        let _ = write!(
            s,
            r##"<line x1="{x:.1}" y1="{y1}" x2="{x:.1}" y2="{}" stroke="#444"/><text class="tick" x="{x:.1}" y="{}" text-anchor="middle" font-size="11">{}</text>"##,
            y1 + 4.0,
            y1 + 16.0,
            tick(t)
        );
    }
    for t in ticks(f.y.0, f.y.1) {
        let y = f.py(t);
        let _ = write!(
            s,
            r##"<line x1="{}" y1="{y:.1}" x2="{x0}" y2="{y:.1}" stroke="#444"/><line x1="{x0}" y1="{y:.1}" x2="{x1}" y2="{y:.1}" stroke="#eee"/><text class="tick" x="{}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
            x0 - 4.0,
            x0 - 6.0,
            y + 4.0,
            tick(t)
        );
    }
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle" font-size="12">{}</text><text transform="translate(16 {}) rotate(-90)" text-anchor="middle" font-size="12">{}</text>"#,
        (x0 + x1) / 2.0,
        H - 10.0,
        esc(xlabel),
        (y0 + y1) / 2.0,
        esc(ylabel)
    );
}

fn legend(s: &mut String, names: &[&str]) {
    for (k, n) in names.iter().enumerate() {
        let y = TOP + 14.0 + 18.0 * k as f64;
        let x = W - RIGHT + 14.0;
        let _ = write!(
            s,
            r#"<rect x="{x}" y="{}" width="12" height="12" fill="{}"/><text x="{}" y="{y}" font-size="12">{}</text>"#,
            y - 10.0,
            SERIES[k % SERIES.len()],
            x + 18.0,
            esc(n)
        );
    }
}

/// The mean and its standard error in `bins` equal bins of x (bins with fewer than 2 points
/// left out): (bin centre, mean, standard error).
pub fn binned_mean(points: &[(f64, f64)], bins: usize) -> Vec<(f64, f64, f64)> {
    let (lo, hi) = range(points.iter().map(|p| p.0));
    let w = (hi - lo) / bins as f64;
    (0..bins)
        .filter_map(|b| {
            let a = lo + w * b as f64;
            let ys: Vec<f64> = points
                .iter()
                .filter(|p| p.0 >= a && (p.0 < a + w || b + 1 == bins))
                .map(|p| p.1)
                .collect();
            if ys.len() < 2 {
                return None;
            }
            let n = ys.len() as f64;
            let m = ys.iter().sum::<f64>() / n;
            let var = ys.iter().map(|y| (y - m).powi(2)).sum::<f64>() / (n - 1.0);
            Some((a + w / 2.0, m, (var / n).sqrt()))
        })
        .collect()
}

/// A scatter plot of the series, each with its binned mean (line) and ±2 standard errors
/// (band) when `binned`.
pub fn scatter(title: &str, xlabel: &str, ylabel: &str, series: &[Series], binned: bool) -> String {
    let f = Frame {
        x: range(series.iter().flat_map(|s| s.points.iter().map(|p| p.0))),
        y: range(series.iter().flat_map(|s| s.points.iter().map(|p| p.1))),
    };
    let mut s = String::new();
    axes(&mut s, &f, title, xlabel, ylabel);
    for (k, ser) in series.iter().enumerate() {
        let c = SERIES[k % SERIES.len()];
        for &(x, y) in &ser.points {
            if x.is_finite() && y.is_finite() {
                let _ = write!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="2" fill="{c}" fill-opacity="0.45"/>"#,
                    f.px(x),
                    f.py(y)
                );
            }
        }
        if binned {
            let b = binned_mean(&ser.points, 12);
            if b.len() >= 2 {
                let upper: Vec<String> = b
                    .iter()
                    .map(|(x, m, e)| format!("{:.1},{:.1}", f.px(*x), f.py(m + 2.0 * e)))
                    .collect();
                let lower: Vec<String> = b
                    .iter()
                    .rev()
                    .map(|(x, m, e)| format!("{:.1},{:.1}", f.px(*x), f.py(m - 2.0 * e)))
                    .collect();
                let _ = write!(
                    s,
                    r#"<polygon class="band" points="{} {}" fill="{c}" fill-opacity="0.18"/>"#,
                    upper.join(" "),
                    lower.join(" ")
                );
                let line: Vec<String> = b
                    .iter()
                    .map(|(x, m, _)| format!("{:.1},{:.1}", f.px(*x), f.py(*m)))
                    .collect();
                let _ = write!(
                    s,
                    r#"<polyline class="binned-mean" points="{}" fill="none" stroke="{c}" stroke-width="2.5"/>"#,
                    line.join(" ")
                );
            }
        }
    }
    let names: Vec<&str> = series.iter().map(|s| s.name.as_str()).collect();
    legend(&mut s, &names);
    s.push_str("</svg>");
    s
}

/// Grouped bars (one group per label, one bar per series value), y from zero.
pub fn bars(title: &str, ylabel: &str, groups: &[String], series: &[(String, Vec<f64>)]) -> String {
    let ymax = series
        .iter()
        .flat_map(|s| s.1.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let f = Frame {
        x: (0.0, groups.len().max(1) as f64),
        y: (0.0, if ymax > 0.0 { ymax * 1.1 } else { 1.0 }),
    };
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {W} {H}" width="{W}" height="{H}" role="img"><title>{t}</title><rect width="{W}" height="{H}" fill="white"/><text x="{cx}" y="20" text-anchor="middle" font-size="15">{t}</text>"#,
        t = esc(title),
        cx = W / 2.0
    );
    for t in ticks(f.y.0, f.y.1) {
        let y = f.py(t);
        let _ = write!(
            s,
            r##"<line x1="{LEFT}" y1="{y:.1}" x2="{}" y2="{y:.1}" stroke="#eee"/><text class="tick" x="{}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"##,
            W - RIGHT,
            LEFT - 6.0,
            y + 4.0,
            tick(t)
        );
    }
    let _ = write!(
        s,
        r#"<text transform="translate(16 {}) rotate(-90)" text-anchor="middle" font-size="12">{}</text>"#,
        (TOP + H - BOTTOM) / 2.0,
        esc(ylabel)
    );
    let n = series.len().max(1) as f64;
    for (g, label) in groups.iter().enumerate() {
        for (k, (_, vals)) in series.iter().enumerate() {
            let v = vals.get(g).copied().unwrap_or(0.0);
            if !v.is_finite() {
                continue;
            }
            let x0 = f.px(g as f64 + 0.1 + 0.8 * k as f64 / n);
            let x1 = f.px(g as f64 + 0.1 + 0.8 * (k as f64 + 1.0) / n);
            let _ = write!(
                s,
                r#"<rect x="{x0:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{}"/>"#,
                f.py(v),
                x1 - x0,
                f.py(0.0) - f.py(v),
                SERIES[k % SERIES.len()]
            );
        }
        let _ = write!(
            s,
            r#"<text x="{:.1}" y="{}" text-anchor="middle" font-size="11">{}</text>"#,
            f.px(g as f64 + 0.5),
            H - BOTTOM + 16.0,
            esc(label)
        );
    }
    let names: Vec<&str> = series.iter().map(|s| s.0.as_str()).collect();
    legend(&mut s, &names);
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_never_read_minus_zero() {
        for (lo, hi) in [(-0.3, 0.3), (-1e-3, 2e-3), (-5.0, 0.0)] {
            for t in ticks(lo, hi) {
                assert_ne!(tick(t), "-0", "{lo}..{hi}");
            }
        }
        assert_eq!(tick(-0.0), "0");
        assert_eq!(tick(-0.00001), "0");
        assert_eq!(tick(2.5), "2.5");
    }

    #[test]
    fn the_binned_mean_follows_a_structure_in_the_points() {
        let pts: Vec<(f64, f64)> = (0..600)
            .map(|i| {
                let x = i as f64 / 600.0;
                (x, 2.0 * x + if i % 2 == 0 { 0.1 } else { -0.1 })
            })
            .collect();
        let b = binned_mean(&pts, 10);
        assert_eq!(b.len(), 10);
        // Each bin holds 60 points: ±0.1 alternating plus the slope across the bin's width
        // (2 × 0.1 / √12), so its standard error is √(0.01 + 0.0033) / √60 ≈ 0.015.
        // The axis is padded by 4 % each side, so the two end bins are only partly filled and
        // their mean is not at their centre: the inner bins are checked against the line.
        for (k, &(x, m, e)) in b.iter().enumerate() {
            if k > 0 && k + 1 < b.len() {
                assert!((m - 2.0 * x).abs() < 0.02, "{x} {m}");
            }
            assert!((0.010..0.020).contains(&e), "{x} {e}");
        }
    }
}
