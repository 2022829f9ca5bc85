//! [`Ordering::Optimised`](crate::session::Ordering::Optimised): one region's points in the
//! order of least move time that keeps the ascending-z rule.
//!
//! The rule: no point's *low* — the lowest table height its approach may need, its contact
//! or below it where a via pose's tip lies lower — lies more than `window` mm below the contact
//! of any earlier point of the region (the paper's layers are one way to keep it; the window
//! lets any order inside it). The metric is [`MoveTime`] (arm and table move together, the
//! slower counts), not a distance.
//!
//! A greedy start — from the lowest point, always the quickest to reach of the points the rule
//! allows next (those that leave no point behind) — then Or-opt (a run of up to three
//! points moved elsewhere) and 2-opt (a stretch reversed) passes, each change kept only when it
//! shortens the path and keeps the rule, until a pass finds nothing or the pass limit is hit.
//! Deterministic: no random draws, ties resolved by position.

use crate::session::plan::MoveTime;

/// One point: joints and table (or marker) position.
type Point = (Vec<f64>, [f64; 3]);
/// A point with its low (mm).
type Low = (Point, f64);

/// How far (positions) an Or-opt move or a 2-opt reversal reaches: the rule keeps a point near
/// its place in z, so farther changes almost never keep it.
const REACH: usize = 24;
/// Improvement passes at most (each is O(n · REACH)).
const MAX_PASSES: usize = 12;
/// Smaller gains (s) are rounding.
const GAIN_S: f64 = 1e-9;

/// True when the points, as (contact z, low) in order, keep the rule: each low at least the
/// running top of the contacts before it minus `window`.
pub fn keeps_window(z_low: impl IntoIterator<Item = (f64, f64)>, window: f64) -> bool {
    let mut top = f64::NEG_INFINITY;
    for (z, low) in z_low {
        if low < top - window - 1e-9 {
            return false;
        }
        top = top.max(z);
    }
    true
}

/// Orders `pts` by least move time within the z window (see the module docs); `low` gives
/// each point's low.
pub(crate) fn optimised(
    pts: Vec<Point>,
    window: f64,
    metric: &MoveTime,
    low: &dyn Fn(&Point) -> f64,
) -> Vec<Point> {
    let window = window.max(0.0);
    let pts: Vec<Low> = pts
        .into_iter()
        .map(|p| {
            let l = low(&p).min(p.1[2]);
            (p, l)
        })
        .collect();
    let mut seq = greedy(pts, window, metric);
    let cost = |a: &Low, b: &Low| metric.between(&a.0 .0, &a.0 .1, &b.0 .0, &b.0 .1);
    for _ in 0..MAX_PASSES {
        let moved = or_opt_pass(&mut seq, window, &cost);
        let reversed = two_opt_pass(&mut seq, window, &cost);
        if !moved && !reversed {
            break;
        }
    }
    seq.into_iter().map(|(p, _)| p).collect()
}

/// Which of `left` the rule allows next: those whose contact lies within the window above
/// the low of every other point left (none is then left behind).
fn allowed(left: &[Low], window: f64) -> Vec<usize> {
    // The two lowest lows: each candidate is held against the lowest of the others.
    let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
    let mut at = usize::MAX;
    for (k, p) in left.iter().enumerate() {
        if p.1 < a {
            (b, a, at) = (a, p.1, k);
        } else if p.1 < b {
            b = p.1;
        }
    }
    let ok: Vec<usize> = (0..left.len())
        .filter(|&k| left[k].0 .1[2] <= if k == at { b } else { a } + window + 1e-9)
        .collect();
    if ok.is_empty() {
        // Cannot happen for a window ≥ 0 (the lowest contact is always allowed); stay safe.
        let lowest = (0..left.len())
            .min_by(|&x, &y| left[x].0 .1[2].total_cmp(&left[y].0 .1[2]))
            .unwrap_or(0);
        vec![lowest]
    } else {
        ok
    }
}

/// From the lowest allowed point, the quickest to reach of those the rule allows next.
fn greedy(mut left: Vec<Low>, window: f64, metric: &MoveTime) -> Vec<Low> {
    let mut out: Vec<Low> = Vec::with_capacity(left.len());
    while !left.is_empty() {
        let ok = allowed(&left, window);
        let k = match out.last() {
            None => ok
                .iter()
                .copied()
                .min_by(|&x, &y| left[x].0 .1[2].total_cmp(&left[y].0 .1[2])),
            Some(from) => ok.iter().copied().min_by(|&x, &y| {
                let cx = metric.between(&from.0 .0, &from.0 .1, &left[x].0 .0, &left[x].0 .1);
                let cy = metric.between(&from.0 .0, &from.0 .1, &left[y].0 .0, &left[y].0 .1);
                cx.total_cmp(&cy)
            }),
        }
        .unwrap_or(0);
        out.push(left.swap_remove(k));
    }
    out
}

/// `top[k]`: the highest contact z of `seq[..k]` (−∞ for none).
fn running_tops(seq: &[Low]) -> Vec<f64> {
    let mut top = Vec::with_capacity(seq.len() + 1);
    top.push(f64::NEG_INFINITY);
    for p in seq {
        let last = *top.last().expect("starts with one");
        top.push(f64::max(last, p.0 .1[2]));
    }
    top
}

/// Whether the points `order` (indices into `seq`) keep the rule after a running top `top`.
/// A change confined to a stretch leaves the running top after it as it was, so checking the
/// stretch alone suffices.
fn stretch_keeps(seq: &[Low], order: impl Iterator<Item = usize>, top: f64, window: f64) -> bool {
    let stretch = order.map(|k| (seq[k].0 .1[2], seq[k].1));
    keeps_window(std::iter::once((top, f64::INFINITY)).chain(stretch), window)
}

/// One Or-opt pass: each run of 1–3 points tried at every place within [`REACH`]; true when
/// anything moved.
fn or_opt_pass(seq: &mut Vec<Low>, window: f64, cost: &impl Fn(&Low, &Low) -> f64) -> bool {
    let mut improved = false;
    let mut tops = running_tops(seq);
    for len in 1..=3usize {
        let mut i = 0;
        while i + len <= seq.len() {
            if let Some(to) = best_insertion(seq, &tops, i, len, window, cost) {
                let run: Vec<Low> = seq.drain(i..i + len).collect();
                let at = if to > i { to - len } else { to };
                seq.splice(at..at, run);
                tops = running_tops(seq);
                improved = true;
            }
            i += 1;
        }
    }
    improved
}

/// Where moving `seq[i..i+len]` (inserted before the point now at `to`) gains the most and
/// keeps the rule, if anywhere.
fn best_insertion(
    seq: &[Low],
    tops: &[f64],
    i: usize,
    len: usize,
    window: f64,
    cost: &impl Fn(&Low, &Low) -> f64,
) -> Option<usize> {
    let n = seq.len();
    let j = i + len - 1;
    let c = |a: usize, b: usize| cost(&seq[a], &seq[b]);
    // Taking the run out.
    let mut removed = 0.0;
    if i > 0 {
        removed += c(i - 1, i);
    }
    if j + 1 < n {
        removed += c(j, j + 1);
    }
    if i > 0 && j + 1 < n {
        removed -= c(i - 1, j + 1);
    }
    let lo = i.saturating_sub(REACH);
    let hi = (j + 1 + REACH).min(n);
    let mut best: Option<(f64, usize)> = None;
    // Insert between `to - 1` and `to` (positions in the original sequence, outside the run).
    for to in lo..=hi {
        if to >= i && to <= j + 1 {
            continue;
        }
        let mut added = 0.0;
        if to > 0 {
            added += c(to - 1, i);
        }
        if to < n {
            added += c(j, to);
        }
        if to > 0 && to < n {
            added -= c(to - 1, to);
        }
        let gain = removed - added;
        if gain > GAIN_S
            && best.is_none_or(|(g, _)| gain > g)
            && moved_keeps(seq, tops, i, len, to, window)
        {
            best = Some((gain, to));
        }
    }
    best.map(|(_, to)| to)
}

/// Whether the sequence with `seq[i..i+len]` moved before `to` keeps the rule.
fn moved_keeps(seq: &[Low], tops: &[f64], i: usize, len: usize, to: usize, window: f64) -> bool {
    let run = i..i + len;
    if to < i {
        stretch_keeps(seq, run.chain(to..i), tops[to], window)
    } else {
        stretch_keeps(seq, (i + len..to).chain(run), tops[i], window)
    }
}

/// One 2-opt pass: each stretch of up to [`REACH`] points tried reversed; true when anything
/// changed.
fn two_opt_pass(seq: &mut [Low], window: f64, cost: &impl Fn(&Low, &Low) -> f64) -> bool {
    let n = seq.len();
    let mut improved = false;
    let mut tops = running_tops(seq);
    for i in 0..n {
        for j in i + 1..(i + REACH).min(n) {
            let mut before = 0.0;
            let mut after = 0.0;
            if i > 0 {
                before += cost(&seq[i - 1], &seq[i]);
                after += cost(&seq[i - 1], &seq[j]);
            }
            if j + 1 < n {
                before += cost(&seq[j], &seq[j + 1]);
                after += cost(&seq[i], &seq[j + 1]);
            }
            if before - after > GAIN_S && stretch_keeps(seq, (i..=j).rev(), tops[i], window) {
                seq[i..=j].reverse();
                tops = running_tops(seq);
                improved = true;
            }
        }
    }
    improved
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(x: f64, y: f64, z: f64) -> Point {
        (vec![], [x, y, z])
    }

    #[test]
    fn inside_one_window_the_order_follows_the_shortest_path() {
        // Four points at one height on a line, given shuffled: the optimised order walks the
        // line (3 × 100 mm) instead of zig-zagging.
        let m = MoveTime::table_only();
        let pts = vec![pt(0.0, 0.0, 0.0), pt(300.0, 0.0, 0.0), pt(100.0, 0.0, 0.0), pt(200.0, 0.0, 0.0)];
        let out = optimised(pts, 1.0, &m, &|p| p.1[2]);
        let xs: Vec<f64> = out.iter().map(|p| p.1[0]).collect();
        assert_eq!(xs, vec![0.0, 100.0, 200.0, 300.0]);
    }

    #[test]
    fn the_window_is_kept_even_when_a_lower_point_would_be_quicker() {
        // The point at x = 10 is 5 mm lower than the one at x = 200: with a 2 mm window it must
        // come first, however far the detour.
        let m = MoveTime::table_only();
        let pts = vec![pt(0.0, 0.0, 5.0), pt(10.0, 0.0, 0.0), pt(200.0, 0.0, 10.0)];
        let mut sorted = pts.clone();
        sorted.sort_by(|a, b| a.1[2].total_cmp(&b.1[2]));
        let out = optimised(sorted, 2.0, &m, &|p| p.1[2]);
        assert!(keeps_window(out.iter().map(|p| (p.1[2], p.1[2])), 2.0));
        assert_eq!(out[0].1[0], 10.0);
    }

    #[test]
    fn a_low_via_pose_brings_its_point_forward() {
        // Same heights within the window, but the far point's via pose needs the table 3 mm
        // lower: with a 2 mm window it must come before the 2 mm higher one.
        let m = MoveTime::table_only();
        let pts = vec![pt(0.0, 0.0, 0.0), pt(10.0, 0.0, 2.0), pt(300.0, 0.0, 1.0)];
        let low = |p: &Point| if p.1[0] > 100.0 { p.1[2] - 3.0 } else { p.1[2] };
        let out = optimised(pts, 2.0, &m, &low);
        let xs: Vec<f64> = out.iter().map(|p| p.1[0]).collect();
        assert!(keeps_window(out.iter().map(|p| (p.1[2], low(p))), 2.0), "{xs:?}");
        assert_eq!(xs, vec![0.0, 300.0, 10.0]);
    }

    #[test]
    fn the_profile_time_matches_a_trapezoid_by_hand() {
        let m = MoveTime::table_only();
        // 100 mm/s, 500 mm/s² both ways: 20 mm of ramps, 0.2 s of them; 120 mm: 0.2 + 1.0 s.
        assert!((m.axis_s(120.0) - 1.2).abs() < 1e-9);
        // Triangular below 20 mm: 2 · sqrt(d / a).
        assert!((m.axis_s(5.0) - 2.0 * (5.0_f64 / 500.0).sqrt()).abs() < 1e-9);
    }
}
