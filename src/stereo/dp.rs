//! The thesis' scanline dynamic programming (Algorithms 1–2, after the MathWorks stereo demo it
//! follows): every row is solved on its own. Going from the right end of the row to the left, each
//! pixel's cost for disparity `d` becomes its block cost plus the cheapest continuation, where the
//! disparity may change by at most 3 pixels from one pixel to the next at `penalty` per pixel of
//! change; back-tracking from the cheapest start then reads off the disparities.
//!
//! Its confidence is the one-path form of eq. 3.5: how much worse the chosen disparity's cost is
//! than the best cost at that pixel.

use rayon::prelude::*;

use super::cost::CostRows;
use super::options::Subpixel;
use super::refine::subpixel_offset;
use super::refine::PixelState;
use crate::image::Raster;

/// Largest disparity change between neighbouring pixels (the thesis' 7-way minimum).
pub const MAX_STEP: usize = 3;

/// Disparity (no NaN) and confidence of every pixel of the left view, `k` disparities from 0.
pub fn scanline_dp(
    cost: &dyn CostRows,
    k: usize,
    penalty: f32,
    subpixel: Subpixel,
) -> (Raster<f32>, Raster<f32>) {
    let (w, h) = (cost.width(), cost.height());
    let mut disparity = vec![0f32; w * h];
    let mut confidence = vec![0f32; w * h];
    let unit = (penalty * 4.0).max(1.0);
    disparity
        .par_chunks_mut(w)
        .zip(confidence.par_chunks_mut(w))
        .enumerate()
        .for_each_init(
            || (vec![0u8; w * k], vec![0f32; w * k], vec![0u8; w * k]),
            |(costs, cp, choice), (y, (disp, conf))| {
                cost.row(y, None, k, costs);
                let last = (w - 1) * k;
                for d in 0..k {
                    cp[last + d] = costs[last + d] as f32;
                }
                for j in (0..w - 1).rev() {
                    let (head, tail) = cp.split_at_mut((j + 1) * k);
                    let next = &tail[..k];
                    let here = &mut head[j * k..];
                    for d in 0..k {
                        let lo = d.saturating_sub(MAX_STEP);
                        let hi = (d + MAX_STEP).min(k - 1);
                        let (mut best, mut arg) = (f32::INFINITY, d);
                        for (e, &n) in next.iter().enumerate().take(hi + 1).skip(lo) {
                            let v = n + penalty * e.abs_diff(d) as f32;
                            if v < best {
                                best = v;
                                arg = e;
                            }
                        }
                        here[d] = costs[j * k + d] as f32 + best;
                        choice[j * k + d] = (arg as isize - d as isize + MAX_STEP as isize) as u8;
                    }
                }
                let row = |j: usize| &cp[j * k..(j + 1) * k];
                let argmin =
                    |v: &[f32]| (0..v.len()).fold(0, |b, i| if v[i] < v[b] { i } else { b });
                let mut d = argmin(row(0));
                for j in 0..w {
                    if j > 0 {
                        let step = choice[(j - 1) * k + d] as isize - MAX_STEP as isize;
                        d = (d as isize + step).clamp(0, k as isize - 1) as usize;
                    }
                    let c = row(j);
                    let off = if d > 0 && d + 1 < k {
                        subpixel_offset(subpixel, c[d - 1], c[d], c[d + 1])
                    } else {
                        0.0
                    };
                    disp[j] = d as f32 + off;
                    let best = c[argmin(c)];
                    conf[j] = 1.0 / (1.0 + (c[d] - best).max(0.0) / unit);
                }
            },
        );
    (
        Raster::from_vec(w, h, disparity),
        Raster::from_vec(w, h, confidence),
    )
}

/// L/R check of two DP results: `right` is the disparity of the right view (pixel xr sees left
/// pixel xr + d). Pixels that fail become NaN with their reason in `state`.
pub fn cross_check(
    left: &mut Raster<f32>,
    right: &Raster<f32>,
    tolerance: u32,
    state: &mut [PixelState],
) {
    let w = left.width();
    for (y, row) in left.pixels_mut().chunks_mut(w).enumerate() {
        for (x, d) in row.iter_mut().enumerate() {
            let di = d.round() as isize;
            let xr = x as isize - di;
            let p = y * w + x;
            if xr < 0 {
                state[p] = PixelState::Occluded;
            } else {
                let dr = right.get(xr as usize, y).round() as isize;
                if dr.abs_diff(di) > tolerance as usize {
                    state[p] = if dr > di {
                        PixelState::Occluded
                    } else {
                        PixelState::Mismatch
                    };
                }
            }
            if state[p] != PixelState::Valid {
                *d = f32::NAN;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Steps {
        w: usize,
    }
    impl CostRows for Steps {
        fn width(&self) -> usize {
            self.w
        }
        fn height(&self) -> usize {
            2
        }
        fn row(&self, _y: usize, _b: Option<&[u16]>, k: usize, out: &mut [u8]) {
            for x in 0..self.w {
                // Truth: 2 on the left half, 8 on the right; pixel 3 has a misleading cost.
                let want = if x == 3 {
                    9
                } else if x < self.w / 2 {
                    2
                } else {
                    8
                };
                for d in 0..k {
                    out[x * k + d] = (d.abs_diff(want) * 10).min(255) as u8;
                }
            }
        }
    }

    #[test]
    fn dp_follows_the_costs_and_smooths_an_outlier() {
        let (d, c) = scanline_dp(&Steps { w: 30 }, 12, 4.0, Subpixel::None);
        for x in 0..30 {
            let want = if x < 15 { 2.0 } else { 8.0 };
            if x == 3 {
                // One pixel cannot jump by 7 and back (steps of at most 3): it stays near 2.
                assert!(*d.get(x, 0) <= 5.0);
                continue;
            }
            // The step of 6 takes two pixels to climb (at most 3 a pixel).
            if !(14..=16).contains(&x) {
                assert_eq!(*d.get(x, 0), want, "x = {x}");
            }
            assert!((0.0..=1.0).contains(c.get(x, 0)));
        }
    }
}
