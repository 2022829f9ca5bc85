//! Where in a region to measure and test, as unit-cube coordinates (each in 0..=1) of its box.
//!
//! A region's CEPs are one constant set for a whole box, so their error is largest where the fit
//! extrapolates: at the corners. Random test points in three dimensions rarely land there (20
//! uniform points leave every corner's eighth of the box empty with probability 0.88^20 ≈ 8 %,
//! and the corner itself far more often), so a region could pass its test and still miss the
//! demand at its corners, where paths cross from one region to the next. The test design is
//! therefore a 3 × 3 × 3 grid — the eight corners (pulled in by [`CORNER_INSET`], so a
//! compensated command stays inside the joint limits), the edges' midpoints, the faces' centres
//! and the centre — then a Halton low-discrepancy sequence that spreads
//! the remaining points evenly; the measurement candidates start with the same corners, so the
//! κ selection can choose the extremes a well-conditioned design wants.

/// How far the corners are pulled in, as a fraction of each width.
pub const CORNER_INSET: f64 = 0.01;

/// First Halton index of the test design (index 0 is the origin, a corner already).
const TEST_HALTON_START: u64 = 1;

/// First Halton index of measurement candidates: far from the test design's indices, so test
/// points are not measurement locations.
const CANDIDATE_HALTON_START: u64 = 4096;

/// The radical inverse of `index` in `base`: the `index`-th element of van der Corput's
/// sequence.
pub fn radical_inverse(mut index: u64, base: u64) -> f64 {
    let mut result = 0.0;
    let mut f = 1.0 / base as f64;
    while index > 0 {
        result += f * (index % base) as f64;
        index /= base;
        f /= base as f64;
    }
    result
}

/// The `index`-th point of the three-dimensional Halton sequence (bases 2, 3, 5).
pub fn halton(index: u64) -> [f64; 3] {
    [
        radical_inverse(index, 2),
        radical_inverse(index, 3),
        radical_inverse(index, 5),
    ]
}

/// The eight corners of the unit cube, pulled in by [`CORNER_INSET`].
pub fn corners() -> [[f64; 3]; 8] {
    std::array::from_fn(|c| {
        std::array::from_fn(|d| {
            if (c >> d) & 1 == 1 {
                1.0 - CORNER_INSET
            } else {
                CORNER_INSET
            }
        })
    })
}

/// `n` test locations: the 27 points of a 3 × 3 × 3 grid — corners first, then the edges'
/// midpoints, the faces' centres and the centre — then Halton points (fewer than 27: the first
/// `n` of the grid, in that order).
pub fn test_design(n: usize) -> Vec<[f64; 3]> {
    let mut grid: Vec<[f64; 3]> = Vec::with_capacity(27);
    let level = [CORNER_INSET, 0.5, 1.0 - CORNER_INSET];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                grid.push([level[i], level[j], level[k]]);
            }
        }
    }
    // Corners (no coordinate at 0.5) first, the centre (all three) last.
    grid.sort_by_key(|u| u.iter().filter(|&&v| v == 0.5).count());
    grid.extend((TEST_HALTON_START..).map(halton).take(n.saturating_sub(27)));
    grid.truncate(n);
    grid
}

/// `n` candidate measurement locations: the corners, then Halton points from `offset` on (a
/// region's own offset, so neighbouring regions do not repeat one pattern).
pub fn candidate_design(n: usize, offset: u64) -> Vec<[f64; 3]> {
    let mut v: Vec<[f64; 3]> = corners().to_vec();
    v.extend(
        (CANDIDATE_HALTON_START + offset..)
            .map(halton)
            .take(n.saturating_sub(8)),
    );
    v.truncate(n);
    v
}

/// `u` moved towards the centre by `factor` (1: unchanged, 0: the centre), for a design point
/// that cannot be reached.
pub fn towards_centre(u: &[f64; 3], factor: f64) -> [f64; 3] {
    u.map(|v| 0.5 + factor * (v - 0.5))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn van_der_corput_by_hand() {
        assert_eq!(radical_inverse(1, 2), 0.5);
        assert_eq!(radical_inverse(6, 2), 0.375); // 110₂ → 0.011₂
        assert!((radical_inverse(5, 3) - 7.0 / 9.0).abs() < 1e-15); // 12₃ → 0.21₃
    }

    #[test]
    fn the_test_design_is_the_3x3x3_grid_corners_first_then_halton_points() {
        let d = test_design(40);
        assert_eq!(d.len(), 40);
        for c in 0..8 {
            let corner: [f64; 3] = std::array::from_fn(|k| ((c >> k) & 1) as f64);
            assert!(d[..8]
                .iter()
                .any(|u| (0..3).all(|k| (u[k] - corner[k]).abs() <= CORNER_INSET + 1e-12)));
        }
        // 12 edge midpoints (one coordinate at 0.5), 6 face centres (two), the centre last.
        let halves = |u: &[f64; 3]| u.iter().filter(|&&v| v == 0.5).count();
        assert!(d[8..20].iter().all(|u| halves(u) == 1));
        assert!(d[20..26].iter().all(|u| halves(u) == 2));
        assert_eq!(d[26], [0.5; 3]);
        // Halton points fill the octants evenly: the 13 after the grid touch at least 7.
        let octants: std::collections::HashSet<[bool; 3]> =
            d[27..].iter().map(|u| u.map(|v| v >= 0.5)).collect();
        assert!(octants.len() >= 7, "{octants:?}");
        assert_eq!(d[27], halton(1));
        assert_eq!(test_design(5).len(), 5);
    }

    #[test]
    fn test_points_are_not_candidate_locations() {
        let t = test_design(40);
        let c = candidate_design(200, 17);
        for u in &t[27..] {
            assert!(c.iter().all(|v| v != u));
        }
    }
}
