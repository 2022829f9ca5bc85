//! [`Ordering::Optimised`](crate::session::Ordering::Optimised): one region's points in the
//! order of least move time that keeps the ascending-z rule.
//!
//! The rule ([`Rule`]): no point's *low* — the lowest table height its approach needs, its
//! contact or below it where its via pose's tip lies lower (which depends on the sides its
//! joints approach from, so on its place in the run) — lies more than `window` mm below the
//! contact of any earlier point of the region. The paper's layers are one way to keep it; the
//! window lets any order inside it. The metric is [`MoveTime`] (arm and table move together,
//! the slower counts), not a distance.
//!
//! A greedy start — from the lowest point, always the quickest to reach of those that keep the
//! rule and leave no contact more than `strand` below (room for the via poses still to come) —
//! then Or-opt (a run of up to three points moved elsewhere) and 2-opt (a stretch reversed)
//! passes, each change kept only when it shortens the path and keeps the rule, until a pass
//! finds nothing or the pass limit is hit. Deterministic: no random draws.

use crate::session::speeds::MoveTime;

/// One point: joints and table (or marker) position.
type Point = (Vec<f64>, [f64; 3]);

/// A point with its lows, one per approach pattern (mm, each at most its contact z).
#[derive(Debug, Clone)]
pub(crate) struct Item {
    pub point: Point,
    pub lows: Vec<f64>,
}

impl Item {
    fn z(&self) -> f64 {
        self.point.1[2]
    }

    fn low_at(&self, slot: usize) -> f64 {
        let n = self.lows.len().max(1);
        self.lows
            .get(slot % n)
            .copied()
            .unwrap_or(self.z())
            .min(self.z())
    }
}

/// The ascending-z rule of a region's run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rule<'a> {
    /// How far a low may lie below the running top of the contacts (mm).
    pub window_mm: f64,
    /// How far a contact may lie below the running top when placed by the greedy start (mm):
    /// less than the window, leaving room for a via pose's lower tip.
    pub strand_mm: f64,
    /// The approach pattern of each place in the run (an index into [`Item::lows`]).
    pub slots: &'a [usize],
}

impl Rule<'_> {
    fn slot(&self, pos: usize) -> usize {
        self.slots.get(pos).copied().unwrap_or(0)
    }
}

/// How far (places) an Or-opt move or a 2-opt reversal reaches: the rule keeps a point near
/// its place in z, so farther changes almost never keep it.
const REACH: usize = 24;
/// Improvement passes at most (each is O(n · REACH)).
const MAX_PASSES: usize = 12;
/// Smaller gains (s) are rounding.
const GAIN_S: f64 = 1e-9;
/// Rounding of heights (mm).
const EPS_MM: f64 = 1e-9;

/// True when the points, as (contact z, low) in order, keep the rule: each low at least the
/// running top of the contacts before it minus `window`.
fn keeps_window(z_low: impl IntoIterator<Item = (f64, f64)>, window: f64) -> bool {
    let mut top = f64::NEG_INFINITY;
    for (z, low) in z_low {
        if low < top - window - EPS_MM {
            return false;
        }
        top = top.max(z);
    }
    true
}

/// Orders `items` by least move time under `rule` (see the module docs).
pub(crate) fn optimised(items: Vec<Item>, rule: &Rule<'_>, metric: &MoveTime) -> Vec<Point> {
    let mut seq = greedy(items, rule, metric);
    let cost = |a: &Item, b: &Item| metric.between(&a.point.0, &a.point.1, &b.point.0, &b.point.1);
    for _ in 0..MAX_PASSES {
        let moved = or_opt_pass(&mut seq, rule, &cost);
        let reversed = two_opt_pass(&mut seq, rule, &cost);
        if !moved && !reversed {
            break;
        }
    }
    seq.into_iter().map(|i| i.point).collect()
}

/// The places of `left` the greedy start may take next at place `pos` after the running top
/// `top`: contacts within `strand` of every other contact left, lows within the window; where
/// none keeps its low there (a via pose far below), those with the highest low.
fn allowed(left: &[Item], top: f64, pos: usize, rule: &Rule<'_>) -> Vec<usize> {
    // The two lowest contacts: each candidate is held against the lowest of the others.
    let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
    let mut at = usize::MAX;
    for (k, p) in left.iter().enumerate() {
        if p.z() < a {
            (b, a, at) = (a, p.z(), k);
        } else if p.z() < b {
            b = p.z();
        }
    }
    let unstranding: Vec<usize> = (0..left.len())
        .filter(|&k| left[k].z() <= if k == at { b } else { a } + rule.strand_mm + EPS_MM)
        .collect();
    let slot = rule.slot(pos);
    let keeping: Vec<usize> = unstranding
        .iter()
        .copied()
        .filter(|&k| left[k].low_at(slot) >= top - rule.window_mm - EPS_MM)
        .collect();
    if !keeping.is_empty() {
        return keeping;
    }
    let best = unstranding
        .iter()
        .map(|&k| left[k].low_at(slot))
        .fold(f64::NEG_INFINITY, f64::max);
    let mut out: Vec<usize> = unstranding
        .into_iter()
        .filter(|&k| left[k].low_at(slot) >= best - EPS_MM)
        .collect();
    if out.is_empty() && at < left.len() {
        out.push(at);
    }
    out
}

/// From the lowest allowed point, the quickest to reach of those the rule allows next.
fn greedy(mut left: Vec<Item>, rule: &Rule<'_>, metric: &MoveTime) -> Vec<Item> {
    let mut out: Vec<Item> = Vec::with_capacity(left.len());
    let mut top = f64::NEG_INFINITY;
    while !left.is_empty() {
        let ok = allowed(&left, top, out.len(), rule);
        let k = match out.last() {
            None => ok
                .iter()
                .copied()
                .min_by(|&x, &y| left[x].z().total_cmp(&left[y].z())),
            Some(from) => ok.iter().copied().min_by(|&x, &y| {
                let (f, px, py) = (&from.point, &left[x].point, &left[y].point);
                let cx = metric.between(&f.0, &f.1, &px.0, &px.1);
                let cy = metric.between(&f.0, &f.1, &py.0, &py.1);
                cx.total_cmp(&cy)
            }),
        }
        .unwrap_or(0);
        let item = left.swap_remove(k);
        top = top.max(item.z());
        out.push(item);
    }
    out
}

/// `top[k]`: the highest contact z of `seq[..k]` (−∞ for none).
fn running_tops(seq: &[Item]) -> Vec<f64> {
    let mut top = Vec::with_capacity(seq.len() + 1);
    top.push(f64::NEG_INFINITY);
    for p in seq {
        let last = *top.last().expect("starts with one");
        top.push(f64::max(last, p.z()));
    }
    top
}

/// Whether the points `order` (indices into `seq`), placed from place `first` on after the
/// running top `top`, keep the rule. A change confined to a stretch leaves the running top
/// after it as it was, so checking the stretch alone suffices.
fn stretch_keeps(
    seq: &[Item],
    order: impl Iterator<Item = usize>,
    first: usize,
    top: f64,
    rule: &Rule<'_>,
) -> bool {
    let stretch = order
        .enumerate()
        .map(|(n, k)| (seq[k].z(), seq[k].low_at(rule.slot(first + n))));
    keeps_window(
        std::iter::once((top, f64::INFINITY)).chain(stretch),
        rule.window_mm,
    )
}

/// One Or-opt pass: each run of 1–3 points tried at every place within [`REACH`]; true when
/// anything moved.
fn or_opt_pass(seq: &mut Vec<Item>, rule: &Rule<'_>, cost: &impl Fn(&Item, &Item) -> f64) -> bool {
    let mut improved = false;
    let mut tops = running_tops(seq);
    for len in 1..=3usize {
        let mut i = 0;
        while i + len <= seq.len() {
            if let Some(to) = best_insertion(seq, &tops, i, len, rule, cost) {
                let run: Vec<Item> = seq.drain(i..i + len).collect();
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
    seq: &[Item],
    tops: &[f64],
    i: usize,
    len: usize,
    rule: &Rule<'_>,
    cost: &impl Fn(&Item, &Item) -> f64,
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
    // Insert between `to - 1` and `to` (places in the sequence as it is, outside the run).
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
            && moved_keeps(seq, tops, i, len, to, rule)
        {
            best = Some((gain, to));
        }
    }
    best.map(|(_, to)| to)
}

/// Whether the sequence with `seq[i..i+len]` moved before `to` keeps the rule.
fn moved_keeps(
    seq: &[Item],
    tops: &[f64],
    i: usize,
    len: usize,
    to: usize,
    rule: &Rule<'_>,
) -> bool {
    let run = i..i + len;
    if to < i {
        stretch_keeps(seq, run.chain(to..i), to, tops[to], rule)
    } else {
        stretch_keeps(seq, (i + len..to).chain(run), i, tops[i], rule)
    }
}

/// One 2-opt pass: each stretch of up to [`REACH`] points tried reversed; true when anything
/// changed.
fn two_opt_pass(seq: &mut [Item], rule: &Rule<'_>, cost: &impl Fn(&Item, &Item) -> f64) -> bool {
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
            if before - after > GAIN_S && stretch_keeps(seq, (i..=j).rev(), i, tops[i], rule) {
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

    fn item(x: f64, z: f64, low: f64) -> Item {
        Item {
            point: (vec![], [x, 0.0, z]),
            lows: vec![low],
        }
    }

    fn rule(window: f64, strand: f64) -> Rule<'static> {
        Rule {
            window_mm: window,
            strand_mm: strand,
            slots: &[],
        }
    }

    fn xs(out: &[Point]) -> Vec<f64> {
        out.iter().map(|p| p.1[0]).collect()
    }

    #[test]
    fn inside_one_window_the_order_follows_the_shortest_path() {
        // Four points at one height on a line, given shuffled: the optimised order walks the
        // line (3 × 100 mm) instead of zig-zagging.
        let m = MoveTime::table_only();
        let items = [0.0, 300.0, 100.0, 200.0]
            .map(|x| item(x, 0.0, 0.0))
            .to_vec();
        assert_eq!(
            xs(&optimised(items, &rule(1.0, 1.0), &m)),
            vec![0.0, 100.0, 200.0, 300.0]
        );
    }

    #[test]
    fn the_window_is_kept_even_when_a_lower_point_would_be_quicker() {
        // The point at x = 10 is 5 mm lower than the one at x = 200: with a 2 mm window it must
        // come first, however far the detour.
        let m = MoveTime::table_only();
        let items = vec![
            item(0.0, 5.0, 5.0),
            item(10.0, 0.0, 0.0),
            item(200.0, 10.0, 10.0),
        ];
        let out = optimised(items, &rule(2.0, 2.0), &m);
        assert!(keeps_window(out.iter().map(|p| (p.1[2], p.1[2])), 2.0));
        assert_eq!(xs(&out), vec![10.0, 0.0, 200.0]);
    }

    #[test]
    fn the_profile_time_matches_a_trapezoid_by_hand() {
        let m = MoveTime::table_only();
        // 100 mm/s, 500 mm/s² both ways: 2 × 10 mm of ramps in 2 × 0.2 s; 120 mm: 0.4 + 1.0 s.
        assert!((m.axis_s(120.0) - 1.4).abs() < 1e-9);
        // Triangular below 20 mm: 2 · sqrt(d / a).
        assert!((m.axis_s(5.0) - 2.0 * (5.0_f64 / 500.0).sqrt()).abs() < 1e-9);
    }
}
