//! Dense output: filling pixels without an estimate, and the edge-aware smoothing that follows.
//!
//! Filling follows Hirschmüller (2008): each hole looks along 8 directions for the nearest valid
//! disparity. An occluded pixel belongs to the background, which in a rectified pair lies beside
//! the occluding object on the same row, so it takes the smaller of its two row neighbours (the
//! second-smallest of all 8 when the row has none); a mismatched pixel takes the median of the 8.
//!
//! Smoothing is the thesis' cascaded convolution (§3.2.1, Fig. 3.6) made edge-aware: passes of a
//! 3-tap binomial kernel `[1 2 1]/4` whose taps spread 1, 2, 4, … pixels apart (the "à trous" form of a
//! Gaussian pyramid), where each neighbour's weight is
//! - its confidence (holes that were filled count little),
//! - low on Canny edges of the image (the thesis' Canny-based confidence map: disparities right on
//!   an object boundary are the least reliable),
//! - `exp(−|ΔI| / σ_I)` for the grey-level difference to the centre pixel, and
//! - zero when its disparity differs from the centre's by more than a jump threshold,
//!
//! so no pass averages across an object boundary.

use rayon::prelude::*;

use super::refine::PixelState;
use super::simd::GreyExponentials;
use crate::image::Raster;

/// Disparity difference between a hole's two row neighbours above which the hole is taken to sit
/// at a depth step, pixels.
const OCCLUSION_STEP: f32 = 2.0;

/// Fills every NaN of `disparity` in place (see the module documentation). Returns the number of
/// pixels filled. An image without a single estimate becomes 0 everywhere.
pub fn fill_holes(disparity: &mut Raster<f32>, state: &[PixelState]) -> usize {
    let (w, h) = (disparity.width(), disparity.height());
    let holes = indices_where(disparity.pixels(), w, |v| v.is_nan());
    if holes.is_empty() {
        return 0;
    }
    if holes.len() == w * h {
        disparity.pixels_mut().fill(0.0);
        return holes.len();
    }
    // Each hole's nearest valid value in the 8 directions, from two sweeps over the rows run in
    // parallel: downwards for the directions that look up (and along the row), upwards for
    // those that look down.
    let src = disparity.pixels();
    let (looking_up, looking_down) = rayon::join(
        || sweep_rows(src, w, &holes, Vertical::Up),
        || sweep_rows(src, w, &holes, Vertical::Down),
    );
    let values: Vec<f32> = holes
        .par_iter()
        .zip(looking_up.par_iter().zip(&looking_down))
        .map(|(&p, (up, down))| {
            let c = [up[0], up[1], up[2], up[3], up[4], down[0], down[1], down[2]];
            let (sorted, len) = sort8(c);
            let v = &sorted[..len];
            // An occlusion lies beside a nearer object on its row: the smaller of the two row
            // neighbours is the background. A mismatch between row neighbours at different depths
            // is treated the same way (holes at depth steps are mostly occlusions the L/R check
            // could not prove); elsewhere a mismatch takes the median of the 8 directions.
            let (left, right) = (c[1], c[0]);
            let row_step =
                !(left.is_nan() || right.is_nan()) && (left - right).abs() > OCCLUSION_STEP;
            match (v.len(), state[p]) {
                (0, _) => f32::NAN,
                (_, PixelState::Occluded) if !(left.is_nan() && right.is_nan()) => left.min(right),
                _ if row_step => left.min(right),
                (1, _) => v[0],
                (_, PixelState::Occluded) => v[1],
                (n, _) => v[n / 2],
            }
        })
        .collect();
    let out = disparity.pixels_mut();
    for (&p, &v) in holes.iter().zip(&values) {
        out[p] = v;
    }
    // Pixels no direction reached (possible only in odd layouts) take the row's nearest value.
    if values.iter().any(|v| v.is_nan()) {
        let fallback = out
            .iter()
            .copied()
            .filter(|v| !v.is_nan())
            .fold(f32::INFINITY, f32::min);
        for v in out.iter_mut().filter(|v| v.is_nan()) {
            *v = fallback;
        }
    }
    holes.len()
}

/// The values of `c` that are not NaN in ascending order, then infinities, and how many are not
/// NaN: Knuth's sorting network for eight values (19 comparators in 6 layers, TAOCP vol. 3,
/// §5.3.4) rather than a general sort per hole, whose branches took most of the filling's time.
fn sort8(c: [f32; 8]) -> ([f32; 8], usize) {
    let len = c.iter().filter(|v| !v.is_nan()).count();
    let mut v = c.map(|x| if x.is_nan() { f32::INFINITY } else { x });
    // No NaN is left, so a plain comparison orders each pair (`f32::min` would test for NaN).
    let mut order = |i: usize, j: usize| {
        let (a, b) = (v[i], v[j]);
        let swap = b < a;
        v[i] = if swap { b } else { a };
        v[j] = if swap { a } else { b };
    };
    order(0, 2);
    order(1, 3);
    order(4, 6);
    order(5, 7);
    order(0, 4);
    order(1, 5);
    order(2, 6);
    order(3, 7);
    order(0, 1);
    order(2, 3);
    order(4, 5);
    order(6, 7);
    order(2, 4);
    order(3, 5);
    order(1, 4);
    order(3, 6);
    order(1, 2);
    order(3, 4);
    order(5, 6);
    (v, len)
}

/// Which way a hole looks for its nearest valid values in [`sweep_rows`].
#[derive(Clone, Copy, PartialEq)]
enum Vertical {
    /// Left and right along the row, up, up-left and up-right (rows visited top to bottom).
    Up,
    /// Down, down-left and down-right (rows visited bottom to top).
    Down,
}

/// For each hole (`holes`: the pixel indices of the NaNs of `src`, ascending), the nearest valid
/// value met walking from it in each direction of `looking`, NaN where the walk leaves the image
/// first: `Up` gives [right, left, up, up-left, up-right]; `Down` gives [down, down-left,
/// down-right, NaN, NaN].
///
/// Each row is a few passes without branches (a hole's value is the carried one): whether a
/// pixel is a hole is as good as random where the L/R check rejected scattered pixels, and a
/// branch on it cost more than the rest of the work.
fn sweep_rows(src: &[f32], w: usize, holes: &[usize], looking: Vertical) -> Vec<[f32; 5]> {
    let h = src.len() / w;
    let mut out = vec![[f32::NAN; 5]; holes.len()];
    // carry[j][x]: the nearest valid value walking from (x, the row before) in diagonal
    // direction j (0 straight, 1 towards smaller x, 2 towards larger x), itself included.
    let mut carry = [vec![f32::NAN; w], vec![f32::NAN; w], vec![f32::NAN; w]];
    let mut next = carry.clone();
    let row_holes = |y: usize| {
        let start = holes.partition_point(|&p| p < y * w);
        let end = holes.partition_point(|&p| p < (y + 1) * w);
        start..end
    };
    for yi in 0..h {
        let y = if looking == Vertical::Up {
            yi
        } else {
            h - 1 - yi
        };
        let row = &src[y * w..(y + 1) * w];
        let pick = |v: f32, carried: f32| if v.is_nan() { carried } else { v };
        for (n, (&v, &c)) in next[0].iter_mut().zip(row.iter().zip(&carry[0])) {
            *n = pick(v, c);
        }
        next[1][0] = pick(row[0], f32::NAN);
        for (n, (&v, &c)) in next[1][1..].iter_mut().zip(row[1..].iter().zip(&carry[1])) {
            *n = pick(v, c);
        }
        for (n, (&v, &c)) in next[2].iter_mut().zip(row.iter().zip(&carry[2][1..])) {
            *n = pick(v, c);
        }
        next[2][w - 1] = pick(row[w - 1], f32::NAN);
        let range = row_holes(y);
        let xs = &holes[range.clone()];
        let found = &mut out[range];
        for (c, &p) in found.iter_mut().zip(xs) {
            let x = p - y * w;
            // At a hole, `next` holds what was carried to it: its nearest valid values along the
            // three directions through the rows already swept.
            *c = if looking == Vertical::Up {
                [f32::NAN, f32::NAN, next[0][x], next[1][x], next[2][x]]
            } else {
                [next[0][x], next[1][x], next[2][x], f32::NAN, f32::NAN]
            };
        }
        if looking == Vertical::Up {
            // Along the row, a hole's nearest valid values are the pixels just outside its run
            // of holes: found from the holes alone, not by scanning the row.
            let mut left = f32::NAN;
            let mut previous = usize::MAX;
            for (c, &p) in found.iter_mut().zip(xs) {
                let x = p - y * w;
                if x == 0 {
                    left = f32::NAN;
                } else if previous != x - 1 {
                    left = row[x - 1];
                }
                c[1] = left;
                previous = x;
            }
            let mut right = f32::NAN;
            let mut following = usize::MAX;
            for (c, &p) in found.iter_mut().zip(xs).rev() {
                let x = p - y * w;
                if x + 1 == w {
                    right = f32::NAN;
                } else if following != x + 1 {
                    right = row[x + 1];
                }
                c[0] = right;
                following = x;
            }
        }
        std::mem::swap(&mut carry, &mut next);
    }
    out
}

/// Canny edges of a grey image (Sobel gradient, non-maximum suppression, hysteresis with
/// thresholds `low`, `high` in grey levels per pixel). `true` = edge.
pub fn canny(image: &Raster<u8>, low: f32, high: f32) -> Vec<bool> {
    let (w, h) = (image.width(), image.height());
    let mut mag = vec![0f32; w * h];
    let mut dir = vec![0u8; w * h];
    mag.par_chunks_mut(w)
        .zip(dir.par_chunks_mut(w))
        .enumerate()
        .for_each_init(
            || [vec![0f32; w + 2], vec![0f32; w + 2], vec![0f32; w + 2]],
            |[up, mid, down], (y, (mag, dir))| {
                // The three rows as f32 with one replicated pixel on each side (borders
                // replicate), read through `columns` so that the Sobel loop vectorises.
                let pad = |out: &mut [f32], yy: usize| {
                    let row = image.row(yy);
                    out[0] = row[0] as f32;
                    for (o, &v) in out[1..=w].iter_mut().zip(row) {
                        *o = v as f32;
                    }
                    out[w + 1] = row[w - 1] as f32;
                };
                pad(up, y.saturating_sub(1));
                pad(mid, y);
                pad(down, (y + 1).min(h - 1));
                let [up_left, up_centre, up_right] = columns(up);
                let [left, _, right] = columns(mid);
                let [down_left, down_centre, down_right] = columns(down);
                let (mag, dir) = (&mut mag[..w], &mut dir[..w]);
                for x in 0..w {
                    let gx = (up_right[x] + 2.0 * right[x] + down_right[x])
                        - (up_left[x] + 2.0 * left[x] + down_left[x]);
                    let gy = (down_left[x] + 2.0 * down_centre[x] + down_right[x])
                        - (up_left[x] + 2.0 * up_centre[x] + up_right[x]);
                    mag[x] = (gx * gx + gy * gy).sqrt() / 4.0;
                    // Quantise the gradient direction to 0°, 45°, 90°, 135° (tan 22.5° ≈
                    // 0.4142): 0 when nearly horizontal, else 2 when nearly vertical, else 1 or 3
                    // by the diagonal, as arithmetic rather than branches.
                    let (ax, ay) = (gx.abs(), gy.abs());
                    let along_x = (ay <= 0.4142 * ax) as u8;
                    let along_y = (ax <= 0.4142 * ay) as u8;
                    let rising = ((gx > 0.0) == (gy > 0.0)) as u8;
                    dir[x] = (1 - along_x) * (2 * along_y + (1 - along_y) * (3 - 2 * rising));
                }
            },
        );
    // Non-maximum suppression: each pixel against its two neighbours along the gradient, read
    // from three rows padded with a zero on each side (outside the image counts as 0). All four
    // directions' neighbours are read and one pair picked without a branch: the direction is as
    // good as random from pixel to pixel, and a branch on it cost more than the comparisons.
    let zeros = vec![0f32; w];
    let mut strong = vec![0u8; w * h]; // 0 none, 1 weak, 2 strong
    strong.par_chunks_mut(w).enumerate().for_each_init(
        || [vec![0f32; w + 2], vec![0f32; w + 2], vec![0f32; w + 2]],
        |[up, mid, down], (y, strong)| {
            let row = |yy: Option<usize>| {
                yy.filter(|&yy| yy < h)
                    .map_or(&zeros[..], |yy| &mag[yy * w..(yy + 1) * w])
            };
            up[1..=w].copy_from_slice(row(y.checked_sub(1)));
            mid[1..=w].copy_from_slice(row(Some(y)));
            down[1..=w].copy_from_slice(row(Some(y + 1)));
            let dirs = &dir[y * w..(y + 1) * w];
            let [left, centre, right] = columns(mid);
            let [up_left, up_centre, up_right] = columns(up);
            let [down_left, down_centre, down_right] = columns(down);
            let strong = &mut strong[..w];
            for x in 0..w {
                // The neighbours ahead and behind along directions 0 (x), 1 (diagonal ↘), 2 (y)
                // and 3 (diagonal ↙). Exactly one of the four terms is not 0 (magnitudes are
                // finite): a select the compiler vectorises.
                let d = dirs[x];
                let one = |k: u8| (d == k) as u8 as f32;
                let pick = |along_x: f32, diagonal: f32, along_y: f32, anti_diagonal: f32| {
                    along_x * one(0) + diagonal * one(1) + along_y * one(2) + anti_diagonal * one(3)
                };
                let ahead = pick(right[x], down_right[x], down_centre[x], down_left[x]);
                let behind = pick(left[x], up_left[x], up_centre[x], up_right[x]);
                let v = centre[x];
                let kept = (v >= ahead) & (v >= behind) & (v >= low);
                strong[x] = kept as u8 * (1 + (v >= high) as u8);
            }
        },
    );
    // Hysteresis: weak edges connected to strong ones survive; a weak pixel reached becomes
    // strong, so `strong` also marks what has been taken.
    let mut stack = indices_where(&strong, w, |&s| s == 2);
    while let Some(p) = stack.pop() {
        let (x, y) = (p % w, p / w);
        for qy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
            for qx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                let q = qy * w + qx;
                if strong[q] == 1 {
                    strong[q] = 2;
                    stack.push(q);
                }
            }
        }
    }
    strong.par_iter().map(|&s| s == 2).collect()
}

/// A row padded with one value on each side, as three slices of the row's width: each pixel's
/// left neighbour, itself and its right neighbour at the same index. Loops over slices of one
/// known length have no bounds checks, so the compiler vectorises them.
fn columns(padded: &[f32]) -> [&[f32]; 3] {
    let w = padded.len() - 2;
    [&padded[..w], &padded[1..=w], &padded[2..]]
}

/// The row-major indices (`y · w + x`) of the values that `keep`, ascending, with the rows
/// scanned on all threads.
fn indices_where<T: Sync>(values: &[T], w: usize, keep: impl Fn(&T) -> bool + Sync) -> Vec<usize> {
    values
        .par_chunks(w)
        .enumerate()
        .flat_map_iter(|(y, row)| {
            let keep = &keep;
            row.iter()
                .enumerate()
                .filter(move |(_, v)| keep(v))
                .map(move |(x, _)| y * w + x)
        })
        .collect()
}

/// Settings of [`smooth`].
#[derive(Debug, Clone, Copy)]
pub struct SmoothOptions {
    /// Number of cascaded passes (tap spacing 1, 2, 4, …).
    pub passes: u32,
    /// Grey-level scale of the image-difference weight; at least [`MIN_SIGMA_INTENSITY`] (a
    /// smaller value is taken as that).
    pub sigma_intensity: f32,
    /// Neighbours whose disparity differs by more than this (pixels) do not contribute.
    pub max_jump: f32,
    /// Weight of pixels on Canny edges (the rest weigh 1).
    pub edge_weight: f32,
}

/// Smallest grey-level scale of the smoothing's image-difference weight. The weight
/// `e^(−|ΔI|/σ)` is computed as the smaller of two products of `e^(±I/σ)` per pixel, which stay
/// within `f32`'s normal range only for σ above about 2.9; with σ = 4 the weight of a neighbour
/// 1 grey level away is already 0.78, so nothing finer is lost.
pub const MIN_SIGMA_INTENSITY: f32 = 4.0;

/// Edge-aware cascaded smoothing of a dense disparity map (see the module documentation).
pub fn smooth(
    disparity: &mut Raster<f32>,
    confidence: &Raster<f32>,
    guide: &Raster<u8>,
    opts: &SmoothOptions,
) {
    let (w, h) = (disparity.width(), disparity.height());
    if opts.passes == 0 || w == 0 || h == 0 {
        return;
    }
    let edges = canny(guide, 10.0, 30.0);
    // The grey-level weight of a neighbour as products of per-pixel factors (GreyExponentials),
    // instead of an exponential per neighbour and pass. Each neighbour's reliability (its
    // confidence, less on edges) is folded into its two factors.
    let sigma = if opts.sigma_intensity >= MIN_SIGMA_INTENSITY {
        opts.sigma_intensity
    } else {
        MIN_SIGMA_INTENSITY
    };
    let GreyExponentials {
        rise: rise_of,
        fall: fall_of,
    } = GreyExponentials::new(sigma);
    let (reliable_rise, reliable_fall): (Vec<f32>, Vec<f32>) = confidence
        .pixels()
        .par_iter()
        .zip(edges.par_iter())
        .zip(guide.pixels().par_iter())
        .map(|((&c, &e), &g)| {
            let reliability = c.max(0.02) * if e { opts.edge_weight } else { 1.0 };
            (
                reliability * rise_of[g as usize],
                reliability * fall_of[g as usize],
            )
        })
        .unzip();
    let taps = [0.25f32, 0.5, 0.25];
    let mut src = disparity.pixels().to_vec();
    let mut dst = vec![0f32; w * h];
    for pass in 0..opts.passes {
        let spacing = 1isize << pass.min(10);
        let prev = &src;
        dst.par_chunks_mut(w).enumerate().for_each_init(
            || (vec![0f32; w], vec![0f32; w], vec![0f32; w], vec![0f32; w]),
            |(sum, weight, rise, fall), (y, out)| {
                for ((r, f), &g) in rise.iter_mut().zip(fall.iter_mut()).zip(guide.row(y)) {
                    *r = rise_of[g as usize];
                    *f = fall_of[g as usize];
                }
                let row = PassRow {
                    y,
                    w,
                    h,
                    spacing: spacing as usize,
                    centre: &prev[y * w..(y + 1) * w],
                    centre_rise: rise,
                    centre_fall: fall,
                    prev,
                    reliable_rise: &reliable_rise,
                    reliable_fall: &reliable_fall,
                    weights: taps,
                    max_jump: opts.max_jump,
                };
                // Where all nine taps lie inside the image, they are summed in one loop (in the
                // order of `add_taps`, so the result is the same to the bit), and only the
                // border pixels go tap by tap.
                let interior = row.interior();
                if !interior.is_empty() {
                    smooth_interior_fast(&row, interior.start, interior.end, out);
                }
                let borders = if interior.is_empty() {
                    [0..w, 0..0]
                } else {
                    [0..interior.start, interior.end..w]
                };
                for border in borders.into_iter().filter(|b| !b.is_empty()) {
                    let (sum, weight) = (&mut sum[border.clone()], &mut weight[border.clone()]);
                    sum.fill(0.0);
                    weight.fill(0.0);
                    add_taps(&row, border.start, sum, weight);
                    let out = &mut out[border.clone()];
                    for (((o, &s), &wt), &dp) in out
                        .iter_mut()
                        .zip(&*sum)
                        .zip(&*weight)
                        .zip(&row.centre[border])
                    {
                        *o = if wt > 1e-12 { s / wt } else { dp };
                    }
                }
            },
        );
        std::mem::swap(&mut src, &mut dst);
    }
    disparity.pixels_mut().copy_from_slice(&src);
}

/// One row `y` of a smoothing pass: the centre row's values and the whole image's, the tap
/// weights (per row and per column of the 3×3 taps) and their spacing.
struct PassRow<'a> {
    y: usize,
    w: usize,
    h: usize,
    spacing: usize,
    /// The row's disparities from the previous pass.
    centre: &'a [f32],
    /// `e^(I/σ)` and `e^(−I/σ)` of the row's grey levels.
    centre_rise: &'a [f32],
    centre_fall: &'a [f32],
    /// The whole previous pass.
    prev: &'a [f32],
    /// `e^(±I/σ)` of every pixel times its reliability.
    reliable_rise: &'a [f32],
    reliable_fall: &'a [f32],
    weights: [f32; 3],
    max_jump: f32,
}

impl PassRow<'_> {
    /// The row's pixels whose nine taps all lie inside the image (empty on the first and last
    /// `spacing` rows).
    fn interior(&self) -> std::ops::Range<usize> {
        let s = self.spacing;
        if self.y >= s && self.y + s < self.h {
            s..self.w.saturating_sub(s)
        } else {
            0..0
        }
    }
}

/// Adds the nine taps of the pixels `from..from + sum.len()` of a row tap by tap, each over the
/// pixels it has inside the image.
fn add_taps(row: &PassRow<'_>, from: usize, sum: &mut [f32], weight: &mut [f32]) {
    let PassRow { y, w, h, .. } = *row;
    let spacing = row.spacing as isize;
    let to = from + sum.len();
    // Tap by tap over the run: no bounds logic in the inner loop.
    for (j, ty) in row.weights.iter().enumerate() {
        let qy = y as isize + (j as isize - 1) * spacing;
        if qy < 0 || qy >= h as isize {
            continue;
        }
        let image_row = qy as usize * w..(qy as usize + 1) * w;
        let (drow, rrow, frow) = (
            &row.prev[image_row.clone()],
            &row.reliable_rise[image_row.clone()],
            &row.reliable_fall[image_row],
        );
        for (i, tx) in row.weights.iter().enumerate() {
            let dx = (i as isize - 1) * spacing;
            // The run's pixels whose neighbour at dx lies inside the row; none on a row
            // narrower than the tap's spacing.
            let lo = ((-dx).max(0) as usize).max(from);
            let hi = ((w as isize - dx.max(0)).max(0) as usize).min(to);
            if lo >= hi {
                continue;
            }
            let q0 = (lo as isize + dx) as usize;
            let n = hi - lo;
            let tap = Tap {
                centre: &row.centre[lo..hi],
                centre_rise: &row.centre_rise[lo..hi],
                centre_fall: &row.centre_fall[lo..hi],
                disparity: &drow[q0..q0 + n],
                reliable_rise: &rrow[q0..q0 + n],
                reliable_fall: &frow[q0..q0 + n],
                weight: tx * ty,
                max_jump: row.max_jump,
            };
            add_tap_fast(
                &tap,
                &mut sum[lo - from..hi - from],
                &mut weight[lo - from..hi - from],
            );
        }
    }
}

crate::avx2_variant!(fn smooth_interior_fast<'a, 'b>(row: &'b PassRow<'a>, from: usize, to: usize, out: &'b mut [f32]) => smooth_interior);

/// The smoothed values of pixels `from..to` of the row's interior ([`PassRow::interior`]) into
/// `out`, in one pass: the same sums as [`add_taps`], in the same order.
#[inline(always)]
fn smooth_interior(row: &PassRow<'_>, from: usize, to: usize, out: &mut [f32]) {
    let (n, s, w) = (to - from, row.spacing, row.w);
    let centre = &row.centre[from..to];
    let rise_p = &row.centre_rise[from..to];
    let fall_p = &row.centre_fall[from..to];
    let out = &mut out[from..to];
    // Tap (j, i) reads row y + (j − 1)·spacing at an offset of (i − 1)·spacing: each of its
    // three inputs as a slice of the run's length, so that the loop has no bounds checks.
    let inputs: [[[&[f32]; 3]; 3]; 3] = [0, 1, 2].map(|j| {
        let start = (row.y + j * s - s) * w + from;
        [0, 1, 2].map(|i| {
            let at = start + i * s - s;
            [row.prev, row.reliable_rise, row.reliable_fall].map(|v| &v[at..at + n])
        })
    });
    for x in 0..n {
        let dp = centre[x];
        let (rp, fp) = (rise_p[x], fall_p[x]);
        let (mut sum, mut weight) = (0f32, 0f32);
        for (taps_of_row, ty) in inputs.iter().zip(row.weights) {
            for (tap, tx) in taps_of_row.iter().zip(row.weights) {
                let (dq, rq, fq) = (tap[0][x], tap[1][x], tap[2][x]);
                let near = ((dq - dp).abs() <= row.max_jump) as u32 as f32;
                let wq = near * (tx * ty) * (rq * fp).min(fq * rp);
                sum += wq * dq;
                weight += wq;
            }
        }
        out[x] = if weight > 1e-12 { sum / weight } else { dp };
    }
}

/// One tap of a smoothing pass over a run of pixels: the centres' values and the neighbours'.
struct Tap<'a> {
    centre: &'a [f32],
    /// `e^(I/σ)` and `e^(−I/σ)` of the centres' grey levels.
    centre_rise: &'a [f32],
    centre_fall: &'a [f32],
    disparity: &'a [f32],
    /// The same of the neighbours' grey levels, times their reliability.
    reliable_rise: &'a [f32],
    reliable_fall: &'a [f32],
    weight: f32,
    max_jump: f32,
}

crate::avx2_variant!(fn add_tap_fast<'a, 'b>(tap: &'b Tap<'a>, sum: &'b mut [f32], weight: &'b mut [f32]) => add_tap);

/// Adds the tap's weighted neighbours into `sum` and their weights into `weight`.
#[inline(always)]
fn add_tap(tap: &Tap<'_>, sum: &mut [f32], weight: &mut [f32]) {
    for (((((((s, wt), &dp), &rise_p), &fall_p), &dq), &rise_q), &fall_q) in sum
        .iter_mut()
        .zip(weight.iter_mut())
        .zip(tap.centre)
        .zip(tap.centre_rise)
        .zip(tap.centre_fall)
        .zip(tap.disparity)
        .zip(tap.reliable_rise)
        .zip(tap.reliable_fall)
    {
        // Branch-free: a neighbour across a disparity jump weighs 0.
        let near = ((dq - dp).abs() <= tap.max_jump) as u32 as f32;
        let wq = near * tap.weight * (rise_q * fall_p).min(fall_q * rise_p);
        *s += wq * dq;
        *wt += wq;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sorting_network_sorts_every_input() {
        // Zero–one principle: a comparator network that sorts every sequence of zeros and ones
        // sorts every sequence.
        for bits in 0u32..256 {
            let c: [f32; 8] = std::array::from_fn(|i| (bits >> i & 1) as f32);
            let (v, len) = sort8(c);
            assert_eq!(len, 8);
            assert!(v.windows(2).all(|p| p[0] <= p[1]), "{c:?} gave {v:?}");
        }
        // With holes (NaN): the values first, ascending, as a general sort gives them.
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0x5017);
        for _ in 0..2000 {
            let c: [f32; 8] = std::array::from_fn(|_| match rng.below(10) {
                0..=2 => f32::NAN,
                r => r as f32,
            });
            let mut plain: Vec<f32> = c.iter().copied().filter(|v| !v.is_nan()).collect();
            plain.sort_by(f32::total_cmp);
            let (v, len) = sort8(c);
            assert_eq!(&v[..len], &plain[..], "{c:?}");
            assert!(v[len..].iter().all(|&x| x == f32::INFINITY));
        }
    }

    #[test]
    fn occlusions_take_the_background_and_mismatches_the_median() {
        // Background 10 on the left, foreground 40 on the right, a hole between them.
        let mut d = Raster::from_fn(12, 5, |x, _| match x {
            0..=4 => 10.0,
            5..=6 => f32::NAN,
            _ => 40.0,
        });
        let st = vec![PixelState::Occluded; 60];
        assert_eq!(fill_holes(&mut d, &st), 10);
        assert!(d.pixels().iter().all(|v| v.is_finite()));
        assert_eq!(*d.get(5, 2), 10.0);
        assert_eq!(*d.get(6, 2), 10.0);
        // A lone mismatched pixel inside a plane takes the plane's value.
        let mut d = Raster::filled(7, 7, 3.0f32);
        *d.get_mut(3, 3) = f32::NAN;
        fill_holes(&mut d, &[PixelState::Mismatch; 49]);
        assert_eq!(*d.get(3, 3), 3.0);
        // Nothing valid at all: zeros, never NaN.
        let mut d = Raster::filled(4, 4, f32::NAN);
        fill_holes(&mut d, &[PixelState::Mismatch; 16]);
        assert!(d.pixels().iter().all(|&v| v == 0.0));
    }

    #[test]
    fn sweeps_find_the_nearest_valid_value_in_every_direction() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0xf111);
        for (w, h, hole_percent) in [
            (1, 1, 100),
            (1, 7, 50),
            (9, 1, 50),
            (13, 11, 30),
            (31, 17, 90),
        ] {
            let src: Vec<f32> = (0..w * h)
                .map(|_| {
                    let r = rng.next_u64();
                    if r % 100 < hole_percent {
                        f32::NAN
                    } else {
                        (r >> 32) as f32
                    }
                })
                .collect();
            let hole_list: Vec<usize> = (0..w * h).filter(|&p| src[p].is_nan()).collect();
            let up = sweep_rows(&src, w, &hole_list, Vertical::Up);
            let down = sweep_rows(&src, w, &hole_list, Vertical::Down);
            // Walking from (x, y) by (dx, dy) one pixel at a time.
            let walk = |x: usize, y: usize, dx: isize, dy: isize| {
                let (mut x, mut y) = (x as isize, y as isize);
                loop {
                    x += dx;
                    y += dy;
                    if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
                        return f32::NAN;
                    }
                    let v = src[y as usize * w + x as usize];
                    if !v.is_nan() {
                        return v;
                    }
                }
            };
            let holes = (0..w * h).filter(|&p| src[p].is_nan());
            for (i, p) in holes.enumerate() {
                let (x, y) = (p % w, p / w);
                let want_up = [
                    walk(x, y, 1, 0),
                    walk(x, y, -1, 0),
                    walk(x, y, 0, -1),
                    walk(x, y, -1, -1),
                    walk(x, y, 1, -1),
                ];
                let want_down = [walk(x, y, 0, 1), walk(x, y, -1, 1), walk(x, y, 1, 1)];
                let same = |a: f32, b: f32| a == b || a.is_nan() && b.is_nan();
                for (j, &want) in want_up.iter().enumerate() {
                    assert!(
                        same(up[i][j], want),
                        "{w}×{h}, hole ({x}, {y}), up {j}: {} vs {want}",
                        up[i][j]
                    );
                }
                for (j, &want) in want_down.iter().enumerate() {
                    assert!(
                        same(down[i][j], want),
                        "{w}×{h}, hole ({x}, {y}), down {j}: {} vs {want}",
                        down[i][j]
                    );
                }
            }
        }
    }

    #[test]
    fn canny_finds_a_step_and_nothing_on_flat_ground() {
        let img = Raster::from_fn(20, 10, |x, _| if x < 10 { 20u8 } else { 200 });
        let e = canny(&img, 10.0, 30.0);
        for y in 0..10 {
            assert!(e[y * 20 + 9] || e[y * 20 + 10], "row {y}");
            assert!(!e[y * 20 + 3] && !e[y * 20 + 16]);
        }
        assert!(canny(&Raster::filled(8, 8, 77u8), 10.0, 30.0)
            .iter()
            .all(|e| !e));
    }

    /// [`canny`] written plainly: Sobel with replicated borders, the direction by its angle,
    /// suppression against the two neighbours along it (0 outside the image), and hysteresis as
    /// a flood from the strong pixels.
    fn canny_plainly(image: &Raster<u8>, low: f32, high: f32) -> Vec<bool> {
        let (w, h) = (image.width() as isize, image.height() as isize);
        let at = |x: isize, y: isize| {
            *image.get(x.clamp(0, w - 1) as usize, y.clamp(0, h - 1) as usize) as f32
        };
        let mut mag = vec![0f32; (w * h) as usize];
        let mut step = vec![(0isize, 0isize); (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let gx = (at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1))
                    - (at(x - 1, y - 1) + 2.0 * at(x - 1, y) + at(x - 1, y + 1));
                let gy = (at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1))
                    - (at(x - 1, y - 1) + 2.0 * at(x, y - 1) + at(x + 1, y - 1));
                let p = (y * w + x) as usize;
                mag[p] = (gx * gx + gy * gy).sqrt() / 4.0;
                let (ax, ay) = (gx.abs(), gy.abs());
                step[p] = if ay <= 0.4142 * ax {
                    (1, 0)
                } else if ax <= 0.4142 * ay {
                    (0, 1)
                } else if (gx > 0.0) == (gy > 0.0) {
                    (1, 1)
                } else {
                    (-1, 1)
                };
            }
        }
        let m = |x: isize, y: isize| {
            if x < 0 || y < 0 || x >= w || y >= h {
                0.0
            } else {
                mag[(y * w + x) as usize]
            }
        };
        let mut level = vec![0u8; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) as usize;
                let (dx, dy) = step[p];
                let v = mag[p];
                if v >= m(x + dx, y + dy) && v >= m(x - dx, y - dy) && v >= low {
                    level[p] = if v >= high { 2 } else { 1 };
                }
            }
        }
        let mut edge: Vec<bool> = level.iter().map(|&l| l == 2).collect();
        let mut stack: Vec<isize> = (0..w * h).filter(|&p| edge[p as usize]).collect();
        while let Some(p) = stack.pop() {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (qx, qy) = (p % w + dx, p / w + dy);
                    let q = qy * w + qx;
                    if qx >= 0
                        && qy >= 0
                        && qx < w
                        && qy < h
                        && !edge[q as usize]
                        && level[q as usize] == 1
                    {
                        edge[q as usize] = true;
                        stack.push(q);
                    }
                }
            }
        }
        edge
    }

    #[test]
    fn canny_matches_the_plain_definition_in_every_direction() {
        use crate::mesh::surfaces::XorShift;
        let mut rng = XorShift(0xca77);
        // Rings (edges in every direction, weak ones joined to strong ones) under noise, and
        // images one pixel wide or high.
        for (w, h) in [(41, 29), (1, 9), (9, 1), (2, 2)] {
            let image = Raster::from_fn(w, h, |x, y| {
                let (dx, dy) = (x as f32 - 20.0, y as f32 - 14.0);
                let ring = ((dx * dx + dy * dy).sqrt() / 4.0) as u32 % 3;
                (40 + ring * 50 + rng.below(25) as u32) as u8
            });
            let fast = canny(&image, 10.0, 30.0);
            assert_eq!(fast, canny_plainly(&image, 10.0, 30.0), "{w}x{h}");
            if w > 2 {
                assert!(fast.iter().any(|&e| e) && !fast.iter().all(|&e| e));
            }
        }
    }

    /// [`smooth`] written plainly: every neighbour of every pixel, its weight with `exp`.
    fn smooth_plainly(
        disparity: &Raster<f32>,
        confidence: &Raster<f32>,
        guide: &Raster<u8>,
        opts: &SmoothOptions,
    ) -> Raster<f32> {
        let (w, h) = (disparity.width(), disparity.height());
        let edges = canny(guide, 10.0, 30.0);
        let sigma = opts.sigma_intensity.max(MIN_SIGMA_INTENSITY);
        let mut d = disparity.clone();
        for pass in 0..opts.passes {
            let spacing = 1isize << pass;
            let prev = d.clone();
            for y in 0..h as isize {
                for x in 0..w as isize {
                    let dp = *prev.get(x as usize, y as usize);
                    let ip = *guide.get(x as usize, y as usize) as f32;
                    let (mut sum, mut total) = (0.0f32, 0.0f32);
                    for (j, ty) in [0.25f32, 0.5, 0.25].iter().enumerate() {
                        for (i, tx) in [0.25f32, 0.5, 0.25].iter().enumerate() {
                            let qx = x + (i as isize - 1) * spacing;
                            let qy = y + (j as isize - 1) * spacing;
                            if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                                continue;
                            }
                            let (qx, qy) = (qx as usize, qy as usize);
                            let dq = *prev.get(qx, qy);
                            if (dq - dp).abs() > opts.max_jump {
                                continue;
                            }
                            let edge = if edges[qy * w + qx] {
                                opts.edge_weight
                            } else {
                                1.0
                            };
                            let reliability = confidence.get(qx, qy).max(0.02) * edge;
                            let similarity =
                                (-(*guide.get(qx, qy) as f32 - ip).abs() / sigma).exp();
                            let weight = tx * ty * reliability * similarity;
                            sum += weight * dq;
                            total += weight;
                        }
                    }
                    *d.get_mut(x as usize, y as usize) =
                        if total > 1e-12 { sum / total } else { dp };
                }
            }
        }
        d
    }

    #[test]
    fn smoothing_matches_the_plain_weighted_average() {
        // Ramps, a step, texture, edges and low confidence; σ from well above the floor to
        // below it (taken as the floor by both). Sizes where every pass has pixels with all
        // their neighbours inside, and sizes where some passes have none.
        for (w, h) in [(37, 23), (7, 5), (1, 9), (9, 1)] {
            smoothing_matches_the_plain_weighted_average_at(w, h);
        }
    }

    fn smoothing_matches_the_plain_weighted_average_at(w: usize, h: usize) {
        let guide = Raster::from_fn(w, h, |x, y| {
            let base = if x < 18 { 40 } else { 200 };
            (base + (x * 13 + y * 7) % 23) as u8
        });
        let disparity = Raster::from_fn(w, h, |x, y| {
            let plane = if x < 18 { 10.0 } else { 25.0 };
            plane + 0.05 * y as f32 + (((x * 31 + y * 17) % 11) as f32 - 5.0) * 0.1
        });
        let confidence = Raster::from_fn(w, h, |x, y| ((x + 2 * y) % 5) as f32 / 4.0);
        for (sigma, passes) in [(12.0, 3), (5.0, 2), (1.0, 1)] {
            let opts = SmoothOptions {
                passes,
                sigma_intensity: sigma,
                max_jump: 1.5,
                edge_weight: 0.2,
            };
            // An empty map stays empty.
            let mut empty = Raster::filled(0, 4, 0.0f32);
            let no_confidence = empty.clone();
            smooth(
                &mut empty,
                &no_confidence,
                &Raster::filled(0, 4, 0u8),
                &opts,
            );
            assert_eq!(empty.width(), 0);
            let want = smooth_plainly(&disparity, &confidence, &guide, &opts);
            let mut got = disparity.clone();
            smooth(&mut got, &confidence, &guide, &opts);
            for (p, (g, e)) in got.pixels().iter().zip(want.pixels()).enumerate() {
                assert!(
                    (g - e).abs() <= 1e-4,
                    "{w}x{h}, σ {sigma}, pixel ({}, {}): {g} vs {e}",
                    p % w,
                    p / w
                );
            }
        }
    }

    #[test]
    fn smoothing_reduces_noise_but_keeps_a_step_sharp() {
        let (w, h) = (40, 20);
        let noise = |x: usize, y: usize| (((x * 7919 + y * 104729) % 97) as f32 / 97.0 - 0.5) * 0.4;
        let truth = |x: usize| if x < 20 { 10.0 } else { 30.0 };
        let mut d = Raster::from_fn(w, h, |x, y| truth(x) + noise(x, y));
        let guide = Raster::from_fn(w, h, |x, _| if x < 20 { 50u8 } else { 180 });
        let conf = Raster::filled(w, h, 1.0f32);
        let opts = SmoothOptions {
            passes: 3,
            sigma_intensity: 10.0,
            max_jump: 2.0,
            edge_weight: 0.1,
        };
        let err = |d: &Raster<f32>| {
            (0..w * h)
                .map(|p| (d.pixels()[p] - truth(p % w)).abs())
                .sum::<f32>()
                / (w * h) as f32
        };
        let before = err(&d);
        smooth(&mut d, &conf, &guide, &opts);
        assert!(err(&d) < before * 0.6, "{} vs {before}", err(&d));
        for y in 0..h {
            assert!((*d.get(19, y) - 10.0).abs() < 0.5 && (*d.get(20, y) - 30.0).abs() < 0.5);
        }
    }
}
