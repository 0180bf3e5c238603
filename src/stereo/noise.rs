//! How noisy a pair is, in the units that matter to SGM: the matching cost of the pair's own
//! matches. Image noise flips census bits between the two views, so true matches cost more, closer
//! to what two unrelated pixels cost, and the data term's contrast between right and wrong shrinks
//! against the smoothness penalties. [`penalty_scale`] restores the balance the penalties were
//! chosen for on clean pairs.

use rayon::prelude::*;

use super::cost::CostRows;
use crate::image::Raster;

/// Census cost (0–255 scale) of two unrelated pixels: half of the bits differ.
pub const UNRELATED_CENSUS_COST: f32 = 127.5;

/// The median cost of a clean pair's matches that the penalties are chosen for (census, 0–255
/// scale), above that of every clean photograph measured: at the half-size level's disparities,
/// 36–49 on the 8 Middlebury 2014 pairs and 24–45 on the 26 Middlebury 2005–2006 pairs, against
/// 73–78 on the built-in `room` and `clutter` scenes rendered at 128 samples per pixel and 102 on
/// `window` at 1024, whose views carry about 10 % noise (docs/stereo-eval.md, stop 25).
pub const CLEAN_MATCH_COST: f32 = 60.0;

/// Largest factor [`penalty_scale`] applies.
pub const MAX_PENALTY_SCALE: f32 = 8.0;

/// Every how many rows and columns [`match_cost_floor`] samples a pixel.
const SAMPLE_STEP: usize = 4;

/// The median cost of the pair's matches: `cost` at each sampled pixel's disparity from the
/// half-size level (`coarse`, half the size of `cost`'s images, disparities in its own pixels),
/// rounded; `None` when no sampled pixel has one inside the right view.
pub fn match_cost_floor(cost: &dyn CostRows, coarse: &Raster<f32>) -> Option<f32> {
    let (w, h) = (cost.width(), cost.height());
    let (cw, ch) = (coarse.width(), coarse.height());
    if cw == 0 || ch == 0 {
        return None;
    }
    let mut costs: Vec<u8> = (0..h)
        .into_par_iter()
        .step_by(SAMPLE_STEP)
        .flat_map_iter(|y| {
            let cy = (y / 2).min(ch - 1);
            // Disparities that leave the right view (or are missing) are not sampled.
            let (bases, usable): (Vec<u16>, Vec<bool>) = (0..w)
                .map(|x| {
                    let d = 2.0 * *coarse.get((x / 2).min(cw - 1), cy);
                    if d.is_finite() && d >= 0.0 && d.round() <= (x as f32).min(u16::MAX as f32) {
                        (d.round() as u16, true)
                    } else {
                        (0, false)
                    }
                })
                .unzip();
            let mut row = vec![0u8; w];
            cost.row(y, Some(&bases), 1, &mut row);
            row.into_iter()
                .zip(usable)
                .step_by(SAMPLE_STEP)
                .filter_map(|(c, ok)| ok.then_some(c))
                .collect::<Vec<_>>()
        })
        .collect();
    if costs.is_empty() {
        return None;
    }
    let mid = costs.len() / 2;
    Some(*costs.select_nth_unstable(mid).1 as f32)
}

/// The factor for P1 and P2 given the median cost of the pair's matches (census, 0–255 scale):
/// how much the gap between an unrelated pixel's cost and a match's has shrunk against a clean
/// pair's, `(UNRELATED − CLEAN) / (UNRELATED − floor)`, between 1 and [`MAX_PENALTY_SCALE`].
pub fn penalty_scale(floor: f32) -> f32 {
    let gap = (UNRELATED_CENSUS_COST - floor).max(0.0);
    let clean_gap = UNRELATED_CENSUS_COST - CLEAN_MATCH_COST;
    if gap * MAX_PENALTY_SCALE <= clean_gap {
        MAX_PENALTY_SCALE
    } else {
        (clean_gap / gap).clamp(1.0, MAX_PENALTY_SCALE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_is_one_for_clean_pairs_and_grows_to_its_cap_as_matches_turn_random() {
        assert_eq!(penalty_scale(0.0), 1.0);
        assert_eq!(penalty_scale(CLEAN_MATCH_COST), 1.0);
        let mut last = 1.0;
        for floor in [70.0, 90.0, 110.0, 120.0] {
            let s = penalty_scale(floor);
            assert!(s > last && s <= MAX_PENALTY_SCALE, "{floor}: {s}");
            last = s;
        }
        // (127.5 − 60) / (127.5 − 102) for the `window` scene's floor.
        assert!((penalty_scale(102.0) - 67.5 / 25.5).abs() < 1e-5);
        for floor in [127.5, 200.0, 255.0, f32::INFINITY] {
            assert_eq!(penalty_scale(floor), MAX_PENALTY_SCALE, "{floor}");
        }
    }
}
